//! The treelet RT unit's probe ([`super::TreeletRtUnitCache::probe`]): what each child saw in
//! a cycle of the fast path, kept out of its code (cold, never inlined), so the fast path costs
//! nothing extra when nobody probes.

use super::TreeletRtUnit;
use crate::block::{Block, Signal};
use crate::controller::{ControllerInputs, ControllerOutputs, ControllerRegs};
use crate::count_table::{CountTableIn, CountTableOut, CountTableRegs};
use crate::queue_table::{QueueTableIn, QueueTableOut, QueueTableRegs};
use crate::rt_unit::{NodeDatapath, RtUnitInputs, RtUnitOutputs, RtUnitRegs};
use crate::trace::BlockCycle;

/// One cycle of a treelet RT unit's insides as a probe sees them
/// ([`TreeletRtUnitCache::probe`](super::TreeletRtUnitCache::probe)):
/// the wiring's registers and each child's ports and registers, exactly as the child saw them in
/// the cycle (a child the fast path did not evaluate, having nothing to do, is evaluated for the
/// probe: its outputs are what the hardware drives).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ProbeCycle {
    /// The wiring's registers at the start of the cycle.
    pub glue: Vec<Signal>,
    /// Each child's cycle with its instance name: `rt`, `ctl`, `ct`, `qt`, as in
    /// [`TreeletRtUnit::children`].
    pub children: Vec<(&'static str, BlockCycle)>,
}

/// The probe's registers at the start of a cycle: the children's (`rt`, `ctl`, `ct`, `qt`) and
/// the wiring's, `glue`, as the wiring describes them (kept out of the fast path's code; the
/// probe knows nothing of the wiring's registers).
#[cold]
#[inline(never)]
pub(super) fn start_regs<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    (rt, ctl, ct, qt): (
        &RtUnitRegs,
        &ControllerRegs,
        &CountTableRegs,
        &QueueTableRegs,
    ),
    glue: Vec<Signal>,
) -> [Vec<Signal>; 5] {
    [
        u.rt.reg_signals(rt),
        u.ctl.reg_signals(ctl),
        u.ct.reg_signals(ct),
        u.qt.reg_signals(qt),
        glue,
    ]
}

/// The probe's cycle from its starting registers `start` ([`start_regs`]), the children's
/// inputs and their outputs (`None` for a child the fast path did not evaluate: it kept its
/// registers `(ctl, ct, qt)`, so it is evaluated here for its outputs).
#[cold]
#[inline(never)]
pub(super) fn cycle<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    (ctl, ct, qt): (&ControllerRegs, &CountTableRegs, &QueueTableRegs),
    start: [Vec<Signal>; 5],
    (ctl_in, ct_in, qt_in, rt_in): (
        &ControllerInputs,
        &CountTableIn,
        &QueueTableIn,
        &RtUnitInputs,
    ),
    (ctl_o, ct_o, qt_o, rt_o): (
        Option<&ControllerOutputs>,
        Option<&CountTableOut>,
        Option<&QueueTableOut>,
        &RtUnitOutputs,
    ),
) -> ProbeCycle {
    let [rt_r, ctl_r, ct_r, qt_r, glue] = start;
    let ctl_o = ctl_o.cloned().unwrap_or_else(|| u.ctl.eval(ctl, ctl_in).0);
    let ct_o = ct_o.cloned().unwrap_or_else(|| u.ct.eval(ct, ct_in).0);
    let qt_o = qt_o.cloned().unwrap_or_else(|| u.qt.eval(qt, qt_in).0);
    ProbeCycle {
        glue,
        children: vec![
            ("rt", BlockCycle::new(rt_in, rt_o, rt_r)),
            ("ctl", BlockCycle::new(ctl_in, &ctl_o, ctl_r)),
            ("ct", BlockCycle::new(ct_in, &ct_o, ct_r)),
            ("qt", BlockCycle::new(qt_in, &qt_o, qt_r)),
        ],
    }
}
