//! The RT unit's register-only outputs (its status ports, read by the treelet wiring before
//! the cycle's inputs are known) and summaries of its registers for the simulator and debugging.

use super::{
    LaneStatus, NodeDatapath, RtCache, RtUnit, RtUnitRegs, RtUnitStatus, SlotStatus, TraversalOrder,
};

impl<D: NodeDatapath> RtUnit<D> {
    /// The register-only output ports for these registers (and their lane cache `cache`); the
    /// distinct next treelets (`status_distinct`) are counted only with `distinct` (0
    /// otherwise): the treelet wiring reads them only in modes that terminate divergent warps,
    /// and counting them is the costly part.
    pub fn status(&self, regs: &RtUnitRegs, cache: &RtCache, distinct: bool) -> RtUnitStatus {
        let mut status = RtUnitStatus {
            widths: self.widths,
            slots: Vec::new(),
        };
        self.status_into(regs, cache, distinct, &mut status);
        status
    }

    /// [`RtUnit::status`] written into `status` (its slot list reused: the fast path keeps
    /// one bundle).
    pub fn status_into(
        &self,
        regs: &RtUnitRegs,
        cache: &RtCache,
        distinct: bool,
        status: &mut RtUnitStatus,
    ) {
        status.widths = self.widths;
        status.slots.clear();
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

    /// Rays traversing in the warp buffer.
    pub fn traversing_rays(&self, regs: &RtUnitRegs, cache: &RtCache) -> u64 {
        regs.slots
            .iter()
            .zip(&cache.masks)
            .filter(|(s, _)| s.valid)
            .map(|(_, m)| u64::from(m.traversing.count_ones()))
            .sum()
    }

    /// Per warp-buffer slot, the rays traversing in it (`None` for a slot holding no warp): a
    /// register-only output, for observers that follow each warp (e.g. SIMT efficiency averaged
    /// per warp).
    pub fn slot_lanes<'a>(
        &self,
        regs: &'a RtUnitRegs,
        cache: &'a RtCache,
    ) -> impl Iterator<Item = Option<u32>> + 'a {
        regs.slots
            .iter()
            .zip(&cache.masks)
            .map(|(s, m)| s.valid.then(|| m.traversing.count_ones()))
    }

    /// A one-line summary of the registers, for a watchdog's dump.
    pub fn debug_state(&self, regs: &RtUnitRegs, cache: &RtCache) -> String {
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
