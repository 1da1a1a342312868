//! The RT unit's port bundles (inputs, outputs) and register bundle, with the per-ray records
//! that enter and leave the warp buffer.
//!
//! `records` holds the per-ray records; this file the error flags, the warp-buffer lanes and
//! slots, the statistics counters and the register bundle with its simulation cache.

mod records;

pub use records::{
    occupied, BoundaryEvent, IssueTarget, LaneWrite, MemRequest, MemResponse, RayOutcome,
    RayRecord, RequestKind, StackSel, TraversalOrder, WarpDone, WarpIssue,
};

use super::node::{NodeEntry, CHUNK_BYTES, MAX_NODE_CHUNKS};
use crate::bounded::{BoundedDeque, BoundedVec};
use serde::Serialize;

/// Sticky error flags of the RT unit (the `errors` register and output). A set flag means the
/// environment broke the block's protocol, the datapath returned something the hardware cannot
/// hold, or a ray outgrew its stack spill area; the offending item was dropped, so results
/// after it are not trustworthy. The first error's details are captured in
/// [`RtUnitRegs::first_error`] ([`ErrorRecord`]).
pub mod errors {
    /// A warp was issued while `issue_ready` was low (the warp was dropped).
    pub const ISSUE_WHILE_FULL: u8 = 1 << 0;
    /// An issued warp failed [`super::super::RtUnit::check_issue`] (the warp was dropped).
    pub const BAD_ISSUE: u8 = 1 << 1;
    /// More responses arrived than the response FIFO had room for, or than it has ports.
    pub const FIFO_OVERFLOW: u8 = 1 << 2;
    /// A response matched no node or stack fill in flight (wrong tag, address or duplicate
    /// chunk).
    pub const UNMATCHED_RESPONSE: u8 = 1 << 3;
    /// A ray's stack needed more spilled 32 B chunks than its spill area holds
    /// (`RtUnitParams::stack_spill_chunks`; the spill was not made).
    pub const SPILL_AREA_FULL: u8 = 1 << 4;
    /// The datapath returned a child that is misaligned, of a bad size or outside the address
    /// space, or more children than `RtUnitParams::max_children` (the child was dropped).
    pub const BAD_CHILD: u8 = 1 << 5;
    /// A treelet-controller command named a slot it cannot act on: an issue into a slot that is
    /// not free, an append to a slot that is not held or has too few inactive lanes, a stop or
    /// repack of an empty slot (the command was dropped).
    pub const BAD_COMMAND: u8 = 1 << 6;
    /// Width of the error register.
    pub const BITS: u32 = 7;
}

/// What went wrong, for the first-error capture register ([`ErrorRecord`]); each kind is one
/// flag of [`errors`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    /// [`errors::ISSUE_WHILE_FULL`].
    IssueWhileFull,
    /// [`errors::BAD_ISSUE`].
    BadIssue,
    /// [`errors::FIFO_OVERFLOW`].
    FifoOverflow,
    /// [`errors::UNMATCHED_RESPONSE`].
    UnmatchedResponse,
    /// [`errors::SPILL_AREA_FULL`].
    SpillAreaFull,
    /// [`errors::BAD_CHILD`].
    BadChild,
    /// [`errors::BAD_COMMAND`].
    BadCommand,
}

impl ErrorKind {
    /// The kind's flag in [`errors`] (its bit index is the kind's encoding).
    pub fn flag(self) -> u8 {
        match self {
            ErrorKind::IssueWhileFull => errors::ISSUE_WHILE_FULL,
            ErrorKind::BadIssue => errors::BAD_ISSUE,
            ErrorKind::FifoOverflow => errors::FIFO_OVERFLOW,
            ErrorKind::UnmatchedResponse => errors::UNMATCHED_RESPONSE,
            ErrorKind::SpillAreaFull => errors::SPILL_AREA_FULL,
            ErrorKind::BadChild => errors::BAD_CHILD,
            ErrorKind::BadCommand => errors::BAD_COMMAND,
        }
    }

    /// The kind's encoding on the `error_kind` port (bit index of its flag).
    pub fn code(self) -> u64 {
        self.flag().trailing_zeros() as u64
    }

    /// What happened, in words.
    pub fn describe(self) -> &'static str {
        match self {
            ErrorKind::IssueWhileFull => "a warp was issued while the warp buffer was full",
            ErrorKind::BadIssue => "an issued warp does not fit the warp buffer",
            ErrorKind::FifoOverflow => "more responses arrived than the response FIFO could take",
            ErrorKind::UnmatchedResponse => "a memory response matched no request in flight",
            ErrorKind::SpillAreaFull => "a traversal stack outgrew its spill area in memory",
            ErrorKind::BadChild => {
                "the intersection datapath returned a child the RT unit cannot hold"
            }
            ErrorKind::BadCommand => "a treelet-controller command named a slot it cannot act on",
        }
    }
}

/// The first error the RT unit raised (a capture register, like a machine-check log): what,
/// where, and the value against the limit it broke. Fields that do not apply are 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ErrorRecord {
    /// What went wrong.
    pub kind: ErrorKind,
    /// Warp-buffer slot concerned.
    pub slot: u32,
    /// Lane concerned.
    pub lane: u32,
    /// Ray id of that lane (0 when no ray is concerned).
    pub ray_id: u32,
    /// The value that was needed or seen (e.g. spilled chunks needed, children returned,
    /// responses offered, an address).
    pub value: u64,
    /// The limit it broke (e.g. `stack_spill_chunks`, `max_children`, free FIFO entries).
    pub limit: u64,
}

/// Traversal status of a warp-buffer lane (the lane state machine).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum LaneStatus {
    /// No ray in this lane.
    #[default]
    Inactive,
    /// The ray is traversing (fetching, testing or waiting to fetch).
    Traversing,
    /// Both stacks are empty.
    Done,
    /// Stopped at a treelet boundary (treelet-stop order).
    Parked,
}

impl LaneStatus {
    /// State names in encoding order.
    pub const NAMES: [&'static str; 4] = ["inactive", "traversing", "done", "parked"];

    /// Encoding (index in [`LaneStatus::NAMES`]).
    pub fn code(self) -> u64 {
        match self {
            LaneStatus::Inactive => 0,
            LaneStatus::Traversing => 1,
            LaneStatus::Done => 2,
            LaneStatus::Parked => 3,
        }
    }
}

/// The node a lane is fetching.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct InFlight {
    /// The node.
    pub node: NodeEntry,
    /// Lane whose request (tag) fetches it; merged lanes share the leader's responses.
    pub leader: u32,
    /// Bit `k` set when chunk `k` has returned.
    pub returned: u8,
}

/// One warp-buffer lane (ray buffer entry).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Lane {
    /// Lane state.
    pub status: LaneStatus,
    /// The ray's record (geometry, hit, stacks, current treelet).
    pub ray: RayRecord,
    /// The node in flight, if any.
    pub in_flight: Option<InFlight>,
    /// The stack whose spilled chunk is being loaded back (a stack fill in flight), if any.
    pub filling: Option<StackSel>,
    /// Chunks of the node in flight returned so far.
    pub chunks: [[u8; CHUNK_BYTES as usize]; MAX_NODE_CHUNKS],
    /// Intersection-delay countdown; the next fetch waits until it is 0.
    pub delay: u32,
    /// A hit record is waiting to be stored.
    pub store_pending: bool,
    /// The lane holds a ray record written ahead of its warp's issue ([`LaneWrite`]); it is
    /// inactive until the issue activates it.
    pub written: bool,
}

impl Lane {
    /// The lane holds nothing: inactive, no written record (where an append or a lane write may
    /// put a ray).
    #[inline]
    pub fn empty(&self) -> bool {
        self.status == LaneStatus::Inactive && !self.written
    }

    /// The lane is parked with more than `keep` (`hw.record_stack_entries`) entries of its
    /// other stack on chip: it spills the oldest to its spill area before its warp may
    /// complete, so a record leaving the RT unit carries at most `keep` entries per stack.
    #[inline]
    pub fn park_spilling(&self, keep: usize) -> bool {
        self.status == LaneStatus::Parked && self.ray.other_stack.len() > keep
    }

    /// The lane may make its next request (a node fetch, a stack spill or a stack fill):
    /// traversing (or parked and spilling down to `keep` entries), nothing in flight, delay 0,
    /// an entry left on a stack.
    #[inline]
    pub fn ready(&self, keep: usize) -> bool {
        (self.status == LaneStatus::Traversing || self.park_spilling(keep))
            && self.in_flight.is_none()
            && self.filling.is_none()
            && self.delay == 0
            && !self.ray.finished()
    }

    /// Nothing of the lane is outstanding (its warp may complete as far as the lane goes; a
    /// parked lane has at most `keep` entries of its other stack on chip).
    #[inline]
    pub fn quiescent(&self, keep: usize) -> bool {
        self.status != LaneStatus::Traversing
            && !self.park_spilling(keep)
            && self.in_flight.is_none()
            && self.filling.is_none()
            && self.delay == 0
            && !self.store_pending
    }
}

/// One warp-buffer slot.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct WarpSlot {
    /// The slot holds a warp.
    pub valid: bool,
    /// The warp's traversal order.
    pub order: TraversalOrder,
    /// Held by a repack: the warp does not complete until the repack fill's last append.
    pub held: bool,
    /// `warp_size` lanes.
    pub lanes: Box<[Lane]>,
}

/// Per-lane predicates of one slot's lanes as bit masks (bit `l` for lane `l`; `warp_size` is
/// at most 64), and the leader of each lane's node in flight. A simulation cache, not hardware state: it is a pure function of the lanes
/// ([`LaneMasks::of`]), kept up to date by every write to a lane so that the per-cycle
/// decisions (completion, scheduling, delay countdown, response delivery, idle cycles) need not
/// scan all lanes. It is not described and not traced.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct LaneMasks {
    /// `status == Traversing`.
    pub traversing: u64,
    /// `status == Done`.
    pub done: u64,
    /// `status == Parked`.
    pub parked: u64,
    /// [`Lane::park_spilling`] with [`keep`](Self::keep).
    pub park_spilling: u64,
    /// Entries of the other stack a parked lane keeps on chip (`hw.record_stack_entries`).
    pub keep: usize,
    /// `store_pending`.
    pub store: u64,
    /// `delay > 0`.
    pub delayed: u64,
    /// `in_flight.is_some() || filling.is_some()`.
    pub in_flight: u64,
    /// The ray has a next node (`!ray.finished()`).
    pub has_next: u64,
    /// Per lane the low 8 bits of `in_flight.leader` (0 with nothing in flight), so response
    /// delivery reads the lanes of one request only instead of every lane with a node in flight.
    pub leader: [u8; 64],
}

impl Default for LaneMasks {
    fn default() -> Self {
        LaneMasks {
            traversing: 0,
            done: 0,
            parked: 0,
            park_spilling: 0,
            keep: 0,
            store: 0,
            delayed: 0,
            in_flight: 0,
            has_next: 0,
            leader: [0; 64],
        }
    }
}

impl LaneMasks {
    /// The masks of `lanes`, whose parked lanes keep `keep` entries of their other stack.
    pub fn of(lanes: &[Lane], keep: usize) -> Self {
        let mut m = LaneMasks {
            keep,
            ..LaneMasks::default()
        };
        for (l, lane) in lanes.iter().enumerate() {
            m.set(l, lane);
        }
        m
    }

    /// Recomputes lane `l`'s bits from `lane`.
    #[inline]
    pub fn set(&mut self, l: usize, lane: &Lane) {
        let bit = 1u64 << l;
        let put = |mask: &mut u64, on: bool| *mask = (*mask & !bit) | (u64::from(on) << l);
        put(&mut self.traversing, lane.status == LaneStatus::Traversing);
        put(&mut self.done, lane.status == LaneStatus::Done);
        put(&mut self.parked, lane.status == LaneStatus::Parked);
        put(&mut self.park_spilling, lane.park_spilling(self.keep));
        put(&mut self.store, lane.store_pending);
        put(&mut self.delayed, lane.delay > 0);
        put(
            &mut self.in_flight,
            lane.in_flight.is_some() || lane.filling.is_some(),
        );
        put(&mut self.has_next, !lane.ray.finished());
        self.leader[l] = lane.in_flight.map_or(0, |f| f.leader as u8);
    }

    /// Lanes that are not [`Lane::quiescent`].
    #[inline]
    pub fn busy(&self) -> u64 {
        self.traversing | self.park_spilling | self.in_flight | self.delayed | self.store
    }

    /// Lanes that are [`Lane::ready`].
    #[inline]
    pub fn ready(&self) -> u64 {
        (self.traversing | self.park_spilling) & !self.in_flight & !self.delayed & self.has_next
    }
}

/// The set bits of `mask`, lowest first.
#[inline]
pub(super) fn bits(mut mask: u64) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let l = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            l
        })
    })
}

/// The remaining chunks of the node whose first chunk was requested (highest scheduler
/// priority).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Split {
    /// Request tag of the node.
    pub tag: u32,
    /// The node.
    pub node: NodeEntry,
    /// Chunk to request next.
    pub next_chunk: u8,
}

crate::counters! {
    /// Statistics counters of an RT unit. Not registers of the block: each cycle's increments
    /// leave it on [`super::RtUnitOutputs::counts`] (and [`Skip::skip`](crate::block::Skip::skip) returns those of
    /// skipped idle cycles), and an observer beside the block sums them with [`RtStats::add`].
    /// The simulator's statistics report the sum over its SMs as they are (the `rt` object of
    /// docs/stats.md, in this order and with these names).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
    pub struct RtStats {
        /// Warps completed (issued to and completed by the unit).
        pub warps: u64,
        /// Sum over cycles of valid warps (RT-unit warp cycles).
        pub warp_cycles: u64,
        /// Sum over cycles and valid warps of traversing lanes.
        pub active_thread_cycles: u64,
        /// Of the traversing lanes, those waiting for a node in flight (a load requested, its
        /// data not all back): memory waits inside `active_thread_cycles`.
        pub waiting_lane_cycles: u64,
        /// Sum over cycles and valid warps of lanes whose ray has finished (the warp still holds
        /// the slot for its other lanes).
        pub done_lane_cycles: u64,
        /// Sum over cycles and valid warps of lanes parked at a treelet boundary.
        pub parked_lane_cycles: u64,
        /// 32 B node-load requests issued.
        pub load_requests: u64,
        /// 32 B hit-record stores issued.
        pub stores: u64,
        /// 32 B stack spills (stores of stack entries to the ray's spill area).
        pub stack_spills: u64,
        /// 32 B stack fills (loads of spilled stack entries back onto the lane's stack).
        pub stack_fills: u64,
        /// Lanes served by another lane's request (merged within a warp).
        pub merged: u64,
        /// Node tests per kind, indexed by [`super::NodeKind::code`] (reported by kind name,
        /// kinds never tested left out).
        #[serde(serialize_with = "tests_by_kind")]
        pub tests: [u64; 6],
        /// Of those, tests by lanes of warps in [`TraversalOrder::TreeletStop`] order: treelet
        /// warps (filled from a treelet queue) and initial-phase warps the treelet controller
        /// terminated, finishing their current treelet (treelet-stationary traversal, counted by
        /// the warp's order rather than by the controller's mode).
        pub treelet_order_tests: u64,
        /// Triangle tests that reported a new closest hit (sphere hits are not counted here).
        pub triangle_hits: u64,
    }
}

/// [`RtStats::tests`] as a map from [`super::NodeKind::name`] to count, in name order, without
/// the kinds never tested.
fn tests_by_kind<S: serde::Serializer>(tests: &[u64; 6], s: S) -> Result<S::Ok, S::Error> {
    let by_name: std::collections::BTreeMap<&str, u64> = super::NodeKind::ALL
        .iter()
        .map(|k| (k.name(), tests[k.code() as usize]))
        .filter(|&(_, n)| n > 0)
        .collect();
    serde::Serialize::serialize(&by_name, s)
}

impl RtStats {
    /// Node tests of kind `kind`.
    pub fn tests_of(&self, kind: super::NodeKind) -> u64 {
        self.tests[kind.code() as usize]
    }

    /// Node tests of every kind.
    pub fn total_tests(&self) -> u64 {
        self.tests.iter().sum()
    }

    /// SIMT efficiency: active threads / `warp_size` per RT-unit warp cycle (0 with no cycles).
    pub fn simt_efficiency(&self, warp_size: u32) -> f64 {
        if self.warp_cycles == 0 {
            0.0
        } else {
            self.active_thread_cycles as f64 / (self.warp_cycles as f64 * warp_size as f64)
        }
    }
}

/// All registers of the RT unit's control.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RtUnitRegs {
    /// The warp buffer (`warp_buffer_size` slots).
    pub slots: Box<[WarpSlot]>,
    /// Valid slots, oldest first (the age order of the memory scheduler and of completion; at
    /// most `warp_buffer_size`).
    pub age: BoundedVec<u32>,
    /// The response FIFO (`resp_fifo_depth` entries).
    pub fifo: BoundedDeque<MemResponse>,
    /// Remaining chunks of the node being requested.
    pub split: Option<Split>,
    /// Sticky error flags ([`errors`]).
    pub errors: u8,
    /// The first error raised, with its details (capture register).
    pub first_error: Option<ErrorRecord>,
}

/// A simulation cache of an RT unit's registers, not hardware: per slot, its lanes'
/// predicates as bit masks (traversing, done, parked, store pending, delay above 0, request in
/// flight, entries left) and each in-flight lane's leader. It is a pure function of the
/// registers ([`RtCache::of`]); [`Cached::step_cached`](crate::block::Cached::step_cached) keeps it up to date so that
/// completion, scheduling, the delay countdown, response delivery, `idle_cycles` and
/// `slot_summary` touch only the lanes concerned instead of scanning them all. Whoever steps
/// the unit owns it beside the registers; [`crate::Block::eval`] builds a fresh one.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RtCache {
    pub(super) masks: Vec<LaneMasks>,
}

impl RtCache {
    /// The cache of `regs`, whose parked lanes keep `keep` entries of their other stack on
    /// chip (`hw.record_stack_entries`; [`Cached::cache`](crate::block::Cached::cache) passes the unit's).
    pub fn of(regs: &RtUnitRegs, keep: usize) -> Self {
        RtCache {
            masks: regs
                .slots
                .iter()
                .map(|s| LaneMasks::of(&s.lanes, keep))
                .collect(),
        }
    }

    /// Whether this cache equals a fresh computation from `regs` (debug builds check it at the
    /// start of every cached step).
    pub fn consistent(&self, regs: &RtUnitRegs) -> bool {
        let keep = self.masks.first().map_or(0, |m| m.keep);
        *self == RtCache::of(regs, keep)
    }
}

/// A combinational summary of one warp-buffer slot, as the treelet controller's reports need it
/// (initial-phase divergence reports, active-ray reports for repacking).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SlotSummary {
    /// Lanes still traversing.
    pub traversing: u32,
    /// Lanes a repack cannot release yet: traversing, or finished but with a node in flight, a
    /// delay or a hit-record store outstanding, or parked.
    pub busy: u32,
    /// Distinct treelets the traversing lanes visit next (the treelet of each one's next node).
    pub distinct_next_treelets: u32,
    /// Every lane is quiescent: the warp completes this cycle unless it is held.
    pub quiescent: bool,
}
