//! The treelet RT unit's wiring as a block of its own ([`TreeletWiring`]): its ports are the
//! wiring module's (the composite's inputs and its children's outputs in, the composite's
//! outputs and its children's inputs out) and its registers the wiring's, so the wiring's RTL
//! co-simulates alone against ports recorded from a run of the whole block
//! ([`wiring_ports`]).

use crate::rtl::treelet_wiring_desc;
use vtq_hdl::rt_unit::NodeDatapath;
use vtq_hdl::treelet_rt_unit::{
    GlueRegs, TreeletRtUnit, TreeletRtUnitInputs, WiringInputs, WiringOutputs,
};
use vtq_hdl::{Block, BlockDesc, Signal};

/// The wiring of `unit` as a block: `eval` is [`TreeletRtUnit::wiring_eval`], the wiring from
/// its ports alone.
#[derive(Debug)]
pub struct TreeletWiring<'a, D> {
    unit: &'a TreeletRtUnit<D>,
    idle: WiringInputs,
}

impl<'a, D: NodeDatapath> TreeletWiring<'a, D> {
    /// The wiring of `unit`.
    pub fn new(unit: &'a TreeletRtUnit<D>) -> Self {
        let idle = unit.eval_wiring(&unit.reset(), &unit.idle_inputs()).2;
        TreeletWiring { unit, idle }
    }
}

/// The wiring's input ports in each cycle of `unit` run by its definition from reset over
/// `inputs` (what [`TreeletWiring`] replays).
pub fn wiring_ports<D: NodeDatapath>(
    unit: &TreeletRtUnit<D>,
    inputs: impl IntoIterator<Item = TreeletRtUnitInputs>,
) -> Vec<WiringInputs> {
    let mut regs = unit.reset();
    inputs
        .into_iter()
        .map(|inp| {
            let (_, next, ports, _) = unit.eval_wiring(&regs, &inp);
            regs = next;
            ports
        })
        .collect()
}

impl<D: NodeDatapath> Block for TreeletWiring<'_, D> {
    type Inputs = WiringInputs;
    type Outputs = WiringOutputs;
    type Regs = GlueRegs;

    fn reset(&self) -> GlueRegs {
        self.unit.wiring_reset()
    }

    fn idle_inputs(&self) -> WiringInputs {
        self.idle.clone()
    }

    fn next_into(
        &self,
        regs: &GlueRegs,
        inputs: &WiringInputs,
        next: &mut GlueRegs,
    ) -> WiringOutputs {
        let (out, glue) = self.unit.wiring_eval(regs, inputs);
        *next = glue;
        out
    }

    fn reg_signals(&self, regs: &GlueRegs) -> Vec<Signal> {
        self.unit.wiring_reg_signals(regs)
    }

    fn describe(&self) -> BlockDesc {
        treelet_wiring_desc(self.unit)
    }
}
