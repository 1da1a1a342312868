//! The treelet RT unit's register-only outputs ([`Moore`]): what a simulator reads of the block
//! between cycles (whether an SM warp may be offered, free response entries, the controller's
//! mode, the kind of warp traversing, the count table's occupancy), and its simulation cache
//! ([`Cached`]). Beside them, the observer taps ([`Taps`], and the kind of warp a fill builds):
//! what the simulator's observers and a treelet prefetcher watch, which are not ports.

use super::glue::{GlueRegs, SlotUse};
use super::{
    wiring, TreeletRtUnit, TreeletRtUnitCache, TreeletRtUnitInputs, TreeletRtUnitOutputs,
    TreeletRtUnitRegs, WarpKind,
};
use crate::block::{Cached, Moore, Taps};
use crate::controller::FillKind;
use crate::mode::Mode;
use crate::rt_unit::{NodeDatapath, RtUnitStatus, StatusSelect, TraversalOrder};

/// The treelet RT unit's register-only outputs, as [`Moore::status`] gives them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TreeletRtUnitStatus {
    /// The `sm_ready` port: an SM warp may be offered (SM warps are admitted in this mode, a
    /// slot nobody owns is free and a warp's worth of ray ids is free; the controller may still
    /// reserve the slot in the cycle). Computed only when selected (false otherwise).
    pub sm_ready: bool,
    /// The `resp_free` port: free entries of the RT unit's response FIFO (memory delivers no
    /// more than this, and no more than its response ports, per cycle).
    pub resp_free: u32,
    /// The controller's mode register (what an observer attributes the cycle's intersection
    /// tests to).
    pub mode: Mode,
    /// The kind of warp the lowest occupied warp-buffer slot holds (what an observer
    /// attributes a cycle's events to, docs/fidelity.md cause G); `None` when no slot holds a
    /// warp. With one warp-buffer slot (Table 1) this is the kind of the one warp traversing.
    pub warp_kind: Option<WarpKind>,
    /// The count table's occupancy (treelet queues).
    pub queues: u32,
    /// Its entries at or above the underpopulation threshold.
    pub queues_above_threshold: u32,
}

/// The RT unit's lane cache and the controller's dry run ([`TreeletRtUnitCache`]).
impl<D: NodeDatapath> Cached for TreeletRtUnit<D> {
    type Cache = TreeletRtUnitCache;

    /// The simulation cache of `regs` for stepping them in place.
    fn cache(&self, regs: &TreeletRtUnitRegs) -> TreeletRtUnitCache {
        TreeletRtUnitCache::with_rt(self.rt.cache(&regs.rt))
    }

    /// One cycle in place with `cache` kept up to date (the simulator's fast path): the same
    /// outputs and next registers as [`Block::eval`](crate::block::Block::eval). `cache` must belong to `regs` (debug builds
    /// check the RT unit's part).
    fn step_cached(
        &self,
        regs: &mut TreeletRtUnitRegs,
        cache: &mut TreeletRtUnitCache,
        inputs: &TreeletRtUnitInputs,
    ) -> TreeletRtUnitOutputs {
        let mut out = super::wiring::empty_outputs(self);
        super::fast_path::step_in_place(self, regs, cache, inputs, &mut out);
        out
    }

    /// Reuses the lists' storage of `out`.
    fn step_cached_into(
        &self,
        regs: &mut TreeletRtUnitRegs,
        cache: &mut TreeletRtUnitCache,
        inputs: &TreeletRtUnitInputs,
        out: &mut TreeletRtUnitOutputs,
    ) {
        super::fast_path::step_in_place(self, regs, cache, inputs, out);
    }
}

/// From the children's register-only outputs and the wiring's registers; the select is
/// whether to compute `sm_ready`.
impl<D: NodeDatapath> Moore for TreeletRtUnit<D> {
    type Status = TreeletRtUnitStatus;
    type Select = bool;

    fn status(
        &self,
        regs: &TreeletRtUnitRegs,
        cache: &TreeletRtUnitCache,
        sm_ready: bool,
    ) -> TreeletRtUnitStatus {
        // The RT unit's status ports: those the last step's dry run computed, while current.
        let fresh;
        let rt = match cache.rt_status_current {
            Some(distinct) => {
                debug_assert_eq!(
                    cache.rt_status,
                    self.rt
                        .status(&regs.rt, &cache.rt, StatusSelect::slots(distinct)),
                    "stale RT-unit status ports"
                );
                &cache.rt_status
            }
            None => {
                fresh = self.rt.status(&regs.rt, &cache.rt, StatusSelect::Slots);
                &fresh
            }
        };
        let mode = self.ctl.status(&regs.ctl, &(), ());
        let ct = self.ct.status(&regs.ct, &(), ());
        TreeletRtUnitStatus {
            sm_ready: sm_ready && wiring::sm_ready_in(self, &regs.glue, mode, rt),
            resp_free: rt.resp_free,
            mode,
            warp_kind: warp_kind(rt, &regs.glue),
            queues: ct.occupancy,
            queues_above_threshold: ct.above_threshold,
        }
    }
}

/// The kind of warp in the lowest occupied slot of the RT unit's status `rt`, by the wiring's
/// use of the slot `g.uses`.
fn warp_kind(rt: &RtUnitStatus, g: &GlueRegs) -> Option<WarpKind> {
    rt.slots
        .iter()
        .zip(g.uses.iter())
        .find_map(|(slot, use_)| slot.as_ref().map(|s| (s, use_)))
        .and_then(|(slot, use_)| match use_ {
            SlotUse::Initial => Some(WarpKind::Sm),
            SlotUse::Controller if slot.order == TraversalOrder::TreeletStop => {
                Some(WarpKind::Treelet)
            }
            SlotUse::Controller => Some(WarpKind::Grouped),
            SlotUse::Free | SlotUse::Closing => None,
        })
}

/// The RT unit's taps.
impl<D: NodeDatapath> Taps for TreeletRtUnit<D> {
    /// Per warp-buffer slot, the rays traversing in it (`None`: no warp); see
    /// [`crate::rt_unit::RtUnit::slot_lanes`].
    fn slot_lanes<'a>(
        &self,
        regs: &'a TreeletRtUnitRegs,
        cache: &'a TreeletRtUnitCache,
    ) -> impl Iterator<Item = Option<u32>> + 'a {
        self.rt.slot_lanes(&regs.rt, &cache.rt)
    }

    /// The next node address of every ray traversing in the warp buffer (what a treelet
    /// prefetcher beside the unit watches); see [`crate::rt_unit::RtUnit::next_addresses`].
    fn next_addresses<'a>(
        &self,
        regs: &'a TreeletRtUnitRegs,
        cache: &'a TreeletRtUnitCache,
    ) -> impl Iterator<Item = u64> + 'a {
        self.rt.next_addresses(&regs.rt, &cache.rt)
    }
}

/// An observer tap of the wiring: not a port, it changes no state.
impl<D: NodeDatapath> TreeletRtUnit<D> {
    /// The kind of warp the fill being built in warp-buffer slot `slot` makes (what an
    /// observer attributes the fill's ray-record loads to); `None` when the slot builds no
    /// fill. A repack's fill counts as grouped: repacking refills final-phase warps.
    pub fn fill_kind(&self, regs: &TreeletRtUnitRegs, slot: u32) -> Option<WarpKind> {
        let build = regs.glue.builds.get(slot as usize)?.as_ref()?;
        Some(match build.kind {
            FillKind::Treelet => WarpKind::Treelet,
            FillKind::Grouped | FillKind::Repack => WarpKind::Grouped,
        })
    }
}
