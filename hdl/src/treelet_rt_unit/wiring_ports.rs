//! The wiring kernel on its own, as its RTL module sees it ([`WiringInputs`] ->
//! [`WiringOutputs`] over the wiring's registers): the block's inputs and every child's output
//! ports in, the block's outputs and every child's input ports out. The children's ports are
//! named `<instance>_<port>` (the RT unit's status ports included, as `rt_status_*`), the
//! names of the wiring module's ports in `vtq verilog`.
//!
//! [`TreeletRtUnit::eval_wiring`] runs one cycle of the definition and returns the wiring's
//! ports as they settled; [`TreeletRtUnit::wiring_eval`] evaluates the wiring from those ports
//! alone (the children's register-only outputs stand for their registers). Tests check the two
//! agree every cycle, so the wiring reads nothing of its children but their ports; the
//! co-simulation of the wiring's RTL replays the same ports.

use super::glue::GlueRegs;
use super::wiring::{self, Peeks};
use super::TreeletRtUnitRegs;
use super::{ChildOutputs, TreeletRtUnit, TreeletRtUnitInputs, TreeletRtUnitOutputs};
use crate::block::{Cached, Moore, Signal, Signals};
use crate::controller::{ControllerInputs, ControllerOutputs};
use crate::count_table::{CountTableIn, CountTableOut};
use crate::queue_table::{QueueTableIn, QueueTableOut};
use crate::rt_unit::{NodeDatapath, RtUnitInputs, RtUnitOutputs, RtUnitStatus, StatusSelect};

/// The wiring's input ports for one cycle: the block's inputs and the children's outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct WiringInputs {
    /// The treelet RT unit's inputs.
    pub top: TreeletRtUnitInputs,
    /// The RT unit's outputs (`rt_*`).
    pub rt: RtUnitOutputs,
    /// The RT unit's register-only status ports (`rt_status_*`), distinct treelets always
    /// counted, as its RTL drives them.
    pub rt_status: RtUnitStatus,
    /// The controller's outputs (`ctl_*`).
    pub ctl: ControllerOutputs,
    /// The count table's outputs (`ct_*`).
    pub ct: CountTableOut,
    /// The queue table's outputs (`qt_*`).
    pub qt: QueueTableOut,
}

/// The wiring's output ports for one cycle: the block's outputs and the children's inputs.
#[derive(Debug, Clone, PartialEq)]
pub struct WiringOutputs {
    /// The treelet RT unit's outputs.
    pub top: TreeletRtUnitOutputs,
    /// The RT unit's inputs (`rt_*`).
    pub rt: RtUnitInputs,
    /// The controller's inputs (`ctl_*`).
    pub ctl: ControllerInputs,
    /// The count table's inputs (`ct_*`).
    pub ct: CountTableIn,
    /// The queue table's inputs (`qt_*`).
    pub qt: QueueTableIn,
}

/// A port bundle made of parts, each part's signals named `<prefix>_<name>` (a part with
/// prefix `""` keeps its names).
type Parts<'a> = [(&'static str, &'a dyn Signals)];

/// The signals of `parts` taken by `get` (a bundle's [`Signals::signals`] or
/// [`Signals::bulk_signals`]), each with its part's prefix.
fn joined(parts: &Parts, get: fn(&dyn Signals) -> Vec<Signal>) -> Vec<Signal> {
    parts
        .iter()
        .flat_map(|&(prefix, part)| {
            get(part).into_iter().map(move |s| match prefix {
                "" => s,
                _ => Signal {
                    name: format!("{prefix}_{}", s.name),
                    ..s
                },
            })
        })
        .collect()
}

impl WiringInputs {
    /// The ports in the wiring module's order: the block's inputs, then each child's outputs.
    fn parts(&self) -> [(&'static str, &dyn Signals); 6] {
        [
            ("", &self.top),
            ("rt", &self.rt),
            ("rt", &self.rt_status),
            ("ctl", &self.ctl),
            ("ct", &self.ct),
            ("qt", &self.qt),
        ]
    }
}

impl Signals for WiringInputs {
    fn signals(&self) -> Vec<Signal> {
        joined(&self.parts(), |p| p.signals())
    }

    fn bulk_signals(&self) -> Vec<Signal> {
        joined(&self.parts(), |p| p.bulk_signals())
    }
}

impl WiringOutputs {
    /// The ports in the wiring module's order: the block's outputs, then each child's inputs.
    fn parts(&self) -> [(&'static str, &dyn Signals); 5] {
        [
            ("", &self.top),
            ("rt", &self.rt),
            ("ctl", &self.ctl),
            ("ct", &self.ct),
            ("qt", &self.qt),
        ]
    }
}

impl Signals for WiringOutputs {
    fn signals(&self) -> Vec<Signal> {
        joined(&self.parts(), |p| p.signals())
    }

    fn bulk_signals(&self) -> Vec<Signal> {
        joined(&self.parts(), |p| p.bulk_signals())
    }
}

impl<D: NodeDatapath> TreeletRtUnit<D> {
    /// One cycle of the definition ([`Block::eval`](crate::block::Block::eval)) with the wiring's ports as they settled:
    /// the block's outputs, its next registers, and the wiring's inputs and outputs.
    pub fn eval_wiring(
        &self,
        regs: &TreeletRtUnitRegs,
        inputs: &TreeletRtUnitInputs,
    ) -> (
        TreeletRtUnitOutputs,
        TreeletRtUnitRegs,
        WiringInputs,
        WiringOutputs,
    ) {
        let distinct = wiring::reads_distinct(self, &regs.ctl, inputs.sm_warp.is_some());
        let cache = self.rt.cache(&regs.rt);
        let status = self
            .rt
            .status(&regs.rt, &cache, StatusSelect::slots(distinct));
        let (d, (out, glue), q, children) = self
            .settle_children(regs, 8, |q| {
                let peeks = Peeks::from_ports(self, &status, &q.ctl, &q.ct, &q.qt);
                wiring::kernel(self, &regs.glue, &peeks, inputs, q)
            })
            .expect("the treelet RT unit's wiring has no combinational cycle");
        let ports_in = WiringInputs {
            top: inputs.clone(),
            rt: q.rt,
            rt_status: self.rt.status(&regs.rt, &cache, StatusSelect::Distinct),
            ctl: q.ctl,
            ct: q.ct,
            qt: q.qt,
        };
        let ports_out = WiringOutputs {
            top: out.clone(),
            rt: d.rt,
            ctl: d.ctl,
            ct: d.ct,
            qt: d.qt,
        };
        (out, children.with_glue(glue), ports_in, ports_out)
    }

    /// The wiring alone: its outputs and next registers from its registers `glue` and its input
    /// ports `ports` (nothing of the children but their ports).
    pub fn wiring_eval(&self, glue: &GlueRegs, ports: &WiringInputs) -> (WiringOutputs, GlueRegs) {
        let peeks = Peeks::from_ports(self, &ports.rt_status, &ports.ctl, &ports.ct, &ports.qt);
        let q = ChildOutputs {
            rt: ports.rt.clone(),
            ctl: ports.ctl.clone(),
            ct: ports.ct,
            qt: ports.qt.clone(),
        };
        let (d, (top, next)) = wiring::kernel(self, glue, &peeks, &ports.top, &q);
        let out = WiringOutputs {
            top,
            rt: d.rt,
            ctl: d.ctl,
            ct: d.ct,
            qt: d.qt,
        };
        (out, next)
    }

    /// The wiring's registers `g` as trace signals (unprefixed).
    pub fn wiring_reg_signals(&self, g: &GlueRegs) -> Vec<Signal> {
        self.glue_signals(g)
    }

    /// The wiring's registers after reset.
    pub fn wiring_reset(&self) -> GlueRegs {
        GlueRegs::reset(&self.cfg)
    }
}
