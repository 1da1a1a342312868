//! The RT unit's register-only outputs (its status ports, read by the treelet wiring before
//! the cycle's inputs are known) and summaries of its registers for the simulator and debugging.

use crate::block::{Moore, Skip};

use super::{
    LaneStatus, NodeDatapath, RtCache, RtUnit, RtUnitRegs, RtUnitStatus, SlotStatus, StatusSelect,
    TraversalOrder,
};

/// The status ports (`status_*`: per slot its warp's order, hold, lane summary and inactive
/// lanes) and the `issue_ready` and `resp_free` ports, as selected ([`StatusSelect`]).
impl<D: NodeDatapath> Moore for RtUnit<D> {
    type Status = RtUnitStatus;
    type Select = StatusSelect;

    fn status(&self, regs: &RtUnitRegs, cache: &RtCache, select: StatusSelect) -> RtUnitStatus {
        let mut status = RtUnitStatus {
            widths: self.widths,
            slots: Vec::new(),
            issue_ready: false,
            resp_free: 0,
        };
        self.status_into(regs, cache, select, &mut status);
        status
    }

    /// [`Moore::status`] writing into `status`: its slot list reused (the fast path keeps one
    /// bundle).
    fn status_into(
        &self,
        regs: &RtUnitRegs,
        cache: &RtCache,
        select: StatusSelect,
        status: &mut RtUnitStatus,
    ) {
        status.widths = self.widths;
        status.issue_ready = regs.slots.iter().any(|s| !s.valid);
        status.resp_free = self.params.resp_fifo_depth - regs.fifo.len() as u32;
        status.slots.clear();
        if select == StatusSelect::Scalars {
            return;
        }
        let distinct = select == StatusSelect::Distinct;
        status
            .slots
            .extend(regs.slots.iter().enumerate().map(|(k, s)| {
                let distinct = distinct && s.order == TraversalOrder::TreeletContinue;
                let summary = self.slot_summary(regs, cache, k as u32, distinct)?;
                let m = &cache.masks[k];
                let lanes = if s.lanes.len() >= 64 {
                    u64::MAX
                } else {
                    (1u64 << s.lanes.len()) - 1
                };
                Some(SlotStatus {
                    order: s.order,
                    held: s.held,
                    summary,
                    inactive: lanes & !(m.traversing | m.done | m.parked),
                })
            }));
    }
}

impl<D: NodeDatapath> RtUnit<D> {
    /// A one-line summary of the registers (with their cache), for a watchdog's dump
    /// ([`crate::block::Block::debug_state`]).
    pub(super) fn summary(&self, regs: &RtUnitRegs, cache: &RtCache) -> String {
        let slots: Vec<String> = regs
            .slots
            .iter()
            .enumerate()
            .filter(|(_, s)| s.valid)
            .map(|(i, s)| {
                let count = |st| s.lanes.iter().filter(|l| l.status == st).count();
                format!(
                    "slot {i}: {} traversing, {} done, {} in flight, {} delayed, {} stores pending",
                    count(LaneStatus::Traversing),
                    count(LaneStatus::Done),
                    s.lanes
                        .iter()
                        .filter(|l| l.in_flight.is_some() || l.filling.is_some())
                        .count(),
                    s.lanes.iter().filter(|l| l.delay > 0).count(),
                    s.lanes.iter().filter(|l| l.store_pending).count()
                )
            })
            .collect();
        format!(
            "RT unit: fifo {}, split {:?}, errors {:#x}, idle for {}; {}",
            regs.fifo.len(),
            regs.split,
            regs.errors,
            self.idle_cycles(regs, cache),
            if slots.is_empty() {
                "no warps".to_string()
            } else {
                slots.join("; ")
            }
        )
    }
}
