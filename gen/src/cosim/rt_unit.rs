//! The RT unit as co-simulation sees it: its cycle's outputs and its register-only status
//! ports together, one module's outputs ([`RtUnitWithStatus`]).

use vtq_hdl::rt_unit::{
    NodeDatapath, RtUnit, RtUnitInputs, RtUnitOutputs, RtUnitRegs, RtUnitStatus, StatusSelect,
};
use vtq_hdl::{Block, BlockDesc, Cached, Moore, Signal, Signals};

/// An RT unit whose outputs include its status ports, as the Verilog module `rt_unit` drives
/// them every cycle (the distinct next treelets always counted, for treelet-continue warps):
/// the Rust block's outputs alone lack the register-only ports, which the simulator reads
/// separately ([`RtUnit::status`]).
#[derive(Debug, Clone)]
pub struct RtUnitWithStatus<D>(pub RtUnit<D>);

/// One cycle's outputs of [`RtUnitWithStatus`].
#[derive(Debug, Clone)]
pub struct RtUnitAllOutputs {
    /// The cycle's outputs.
    pub out: RtUnitOutputs,
    /// The register-only status ports.
    pub status: RtUnitStatus,
}

impl Signals for RtUnitAllOutputs {
    fn signals(&self) -> Vec<Signal> {
        let mut s = self.out.signals();
        s.extend(self.status.signals());
        s
    }

    fn bulk_signals(&self) -> Vec<Signal> {
        let mut s = self.out.bulk_signals();
        s.extend(self.status.bulk_signals());
        s
    }
}

impl<D: NodeDatapath> Block for RtUnitWithStatus<D> {
    type Inputs = RtUnitInputs;
    type Outputs = RtUnitAllOutputs;
    type Regs = RtUnitRegs;

    fn reset(&self) -> RtUnitRegs {
        self.0.reset()
    }

    fn idle_inputs(&self) -> RtUnitInputs {
        self.0.idle_inputs()
    }

    fn next_into(
        &self,
        regs: &RtUnitRegs,
        inputs: &RtUnitInputs,
        next: &mut RtUnitRegs,
    ) -> RtUnitAllOutputs {
        let status = self
            .0
            .status(regs, &self.0.cache(regs), StatusSelect::Distinct);
        RtUnitAllOutputs {
            out: self.0.next_into(regs, inputs, next),
            status,
        }
    }

    fn reg_signals(&self, regs: &RtUnitRegs) -> Vec<Signal> {
        self.0.reg_signals(regs)
    }

    fn describe(&self) -> BlockDesc {
        self.0.describe()
    }
}
