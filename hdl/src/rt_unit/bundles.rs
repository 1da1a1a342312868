//! The RT unit's port bundles (inputs, outputs) and register bundle, with the per-ray records
//! that enter and leave the warp buffer.

use super::node::{Hit, NodeEntry, RayWords, CHUNK_BYTES, MAX_NODE_CHUNKS};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// Sticky error flags of the RT unit (the `errors` register and output). A set flag means the
/// environment broke the block's protocol or the datapath returned something the hardware cannot
/// hold; the offending item was dropped, so results after it are not trustworthy.
pub mod errors {
    /// A warp was issued while `issue_ready` was low (the warp was dropped).
    pub const ISSUE_WHILE_FULL: u8 = 1 << 0;
    /// An issued warp failed [`super::super::RtUnit::check_issue`] (the warp was dropped).
    pub const BAD_ISSUE: u8 = 1 << 1;
    /// More responses arrived than the response FIFO had room for, or than it has ports.
    pub const FIFO_OVERFLOW: u8 = 1 << 2;
    /// A response matched no node in flight (wrong tag, address or duplicate chunk).
    pub const UNMATCHED_RESPONSE: u8 = 1 << 3;
    /// A push exceeded `stack_depth` (the child was dropped).
    pub const STACK_OVERFLOW: u8 = 1 << 4;
    /// The datapath returned a child that is misaligned, of a bad size or outside the address
    /// space (the child was dropped).
    pub const BAD_CHILD: u8 = 1 << 5;
    /// A treelet-controller command named a slot it cannot act on: an issue into a slot that is
    /// not free, an append to a slot that is not held or has too few inactive lanes, a stop or
    /// repack of an empty slot (the command was dropped).
    pub const BAD_COMMAND: u8 = 1 << 6;
    /// Width of the error register.
    pub const BITS: u32 = 7;
}

/// Which traversal order a warp uses (set per warp at issue, held in its slot).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum TraversalOrder {
    /// Single stack: every child goes on the current stack (baseline ray-stationary order).
    #[default]
    RayStationary,
    /// Two-stack treelet order; at a treelet boundary the ray reports the treelet it needs next
    /// and continues into it (the initial traversal phase).
    TreeletContinue,
    /// Two-stack treelet order; at a treelet boundary the ray reports the treelet it needs next
    /// and stops (a treelet warp in treelet-stationary mode).
    TreeletStop,
}

impl TraversalOrder {
    /// Every order in encoding order.
    pub const ALL: [TraversalOrder; 3] = [
        TraversalOrder::RayStationary,
        TraversalOrder::TreeletContinue,
        TraversalOrder::TreeletStop,
    ];

    /// Width of the encoded order.
    pub const BITS: u32 = 2;

    /// Encoding (index in [`TraversalOrder::ALL`]).
    pub fn code(self) -> u64 {
        match self {
            TraversalOrder::RayStationary => 0,
            TraversalOrder::TreeletContinue => 1,
            TraversalOrder::TreeletStop => 2,
        }
    }

    /// Whether the order keeps a separate other-treelet stack.
    pub fn two_stack(self) -> bool {
        self != TraversalOrder::RayStationary
    }
}

/// A ray's complete traversal state: loaded into a warp-buffer lane at issue and handed back
/// when the warp completes (so a ray stopped at a treelet boundary can resume in another warp).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct RayRecord {
    /// Ray id (below `max_rays`).
    pub ray_id: u32,
    /// Origin, direction, tmin, tmax as f32 bit patterns.
    pub words: RayWords,
    /// Closest hit so far.
    pub hit: Option<Hit>,
    /// Treelet (address >> log2(treelet_bytes)) the current stack belongs to.
    pub current_treelet: u64,
    /// Current-treelet stack, bottom first (the last entry is popped next).
    pub current_stack: Vec<NodeEntry>,
    /// Other-treelet stack, bottom first; when the current stack is empty its top is popped and
    /// its treelet becomes the current treelet.
    pub other_stack: Vec<NodeEntry>,
}

impl RayRecord {
    /// A fresh ray starting at `root`: the root sits on the other stack, so the first fetch makes
    /// the root's treelet the current treelet.
    pub fn new(ray_id: u32, words: RayWords, root: NodeEntry) -> Self {
        RayRecord {
            ray_id,
            words,
            hit: None,
            current_treelet: 0,
            current_stack: Vec::new(),
            other_stack: vec![root],
        }
    }

    /// The node the ray visits next (top of the current stack, else top of the other stack).
    #[inline]
    pub fn next_node(&self) -> Option<NodeEntry> {
        self.current_stack
            .last()
            .or(self.other_stack.last())
            .copied()
    }

    /// Whether both stacks are empty (traversal finished).
    #[inline]
    pub fn finished(&self) -> bool {
        self.current_stack.is_empty() && self.other_stack.is_empty()
    }
}

/// A warp handed to the RT unit (`traceRayEXT()` from the raygen shader, or a treelet / repacked
/// warp from the treelet controller).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct WarpIssue {
    /// Traversal order of the warp (ignored by an append).
    pub order: TraversalOrder,
    /// One entry per lane (`warp_size` of them); `None` is an inactive lane. For an append,
    /// `Some` lanes must be inactive lanes of the held slot.
    pub lanes: Vec<Option<RayRecord>>,
    /// Where the rays go.
    pub target: IssueTarget,
}

/// Where an issued warp's rays go (`issue_target`, `issue_slot`, `issue_last`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum IssueTarget {
    /// A new warp in the lowest free slot (a warp from the SM; code 0).
    #[default]
    AnyFree,
    /// A new warp in this free slot (a treelet or grouped warp the treelet controller reserved
    /// the slot for; code 1).
    Slot(u32),
    /// Rays appended into inactive lanes of this held slot (a repack fill; code 2); `last`
    /// releases the hold, so the warp may complete again.
    Append {
        /// The held slot.
        slot: u32,
        /// The fill is complete.
        last: bool,
    },
}

impl IssueTarget {
    /// Width of the target code.
    pub const BITS: u32 = 2;

    /// The `issue_target` code.
    pub fn code(self) -> u64 {
        match self {
            IssueTarget::AnyFree => 0,
            IssueTarget::Slot(_) => 1,
            IssueTarget::Append { .. } => 2,
        }
    }

    /// The slot named on `issue_slot` (0 for `AnyFree`).
    pub fn slot(self) -> u32 {
        match self {
            IssueTarget::AnyFree => 0,
            IssueTarget::Slot(s) | IssueTarget::Append { slot: s, .. } => s,
        }
    }
}

/// One 32 B memory request of the RT unit (to the L1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemRequest {
    /// Byte address (32 B aligned).
    pub address: u64,
    /// A store of a hit record (no response follows) rather than a node load.
    pub is_store: bool,
    /// Requesting warp slot and lane, `slot << lane_bits | lane`; a load's response must carry it
    /// back.
    pub tag: u32,
    /// Store data (the hit record); zero for loads.
    pub data: [u8; CHUNK_BYTES as usize],
}

/// One 32 B chunk returned by memory for a load.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemResponse {
    /// Byte address of the chunk.
    pub address: u64,
    /// Tag of the request it answers.
    pub tag: u32,
    /// The chunk's bytes.
    pub data: [u8; CHUNK_BYTES as usize],
}

/// How a ray left the RT unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RayOutcome {
    /// Both stacks are empty: traversal is complete.
    Finished,
    /// Stopped at a treelet boundary ([`TraversalOrder::TreeletStop`]); needs this treelet next.
    AtBoundary {
        /// Treelet (address >> log2(treelet_bytes)) of the node the ray visits next.
        treelet: u64,
    },
}

/// A completed warp leaving the RT unit.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WarpDone {
    /// Warp-buffer slot it occupied.
    pub slot: u32,
    /// Per lane the ray's final state and how it left; `None` for inactive lanes.
    pub lanes: Vec<Option<(RayRecord, RayOutcome)>>,
}

/// A ray reached a treelet boundary: its current stack emptied and its next node lies in
/// another treelet (reported to the treelet controller).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoundaryEvent {
    /// Warp-buffer slot of the ray.
    pub slot: u32,
    /// Lane of the ray.
    pub lane: u32,
    /// Ray id.
    pub ray_id: u32,
    /// Treelet the ray needs next.
    pub treelet: u64,
}

/// Widths of the fields of the port and register bundles, fixed by the configuration; they let a
/// bundle list its signals with the same names and widths every cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Widths {
    /// Lanes per warp.
    pub warp_size: u32,
    /// Warp-buffer slots.
    pub slots: u32,
    /// Response ports (responses accepted per cycle).
    pub resp_ports: u32,
    /// Bits of a ray id.
    pub ray_id: u32,
    /// Bits of a byte address.
    pub address: u32,
    /// Bits of a treelet number.
    pub treelet: u32,
    /// Bits of a lane index.
    pub lane: u32,
    /// Bits of a slot index.
    pub slot: u32,
    /// Bits of a request tag (slot and lane).
    pub tag: u32,
    /// Bits of the response-FIFO occupancy and free count.
    pub fifo_count: u32,
    /// Bits of an intersection-delay counter.
    pub delay: u32,
}

/// The RT unit's inputs for one cycle. Build an idle bundle with
/// [`super::RtUnit::idle_inputs`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RtUnitInputs {
    /// Field widths (constant).
    pub widths: Widths,
    /// A warp to load into a free slot (only when `issue_ready`).
    pub issue: Option<WarpIssue>,
    /// Responses from memory this cycle, at most `resp_ports` and at most `resp_free`.
    pub responses: Vec<MemResponse>,
    /// Terminate this slot's warp into the treelet queues (treelet controller `terminate`): its
    /// order becomes [`TraversalOrder::TreeletStop`], so each ray stops at its next treelet
    /// boundary; a ray already between treelets (current stack empty, nothing in flight)
    /// parks at once.
    pub stop: Option<u32>,
    /// Repack this slot's warp (treelet controller `repack`): its finished, quiescent lanes are
    /// released on [`RtUnitOutputs::released`] and the slot is held (it does not complete) until
    /// an [`IssueTarget::Append`] with `last` arrives.
    pub repack: Option<u32>,
}

/// The RT unit's outputs for one cycle.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RtUnitOutputs {
    /// Field widths (constant).
    pub widths: Widths,
    /// A warp slot is free: a warp may be issued this cycle (depends on registers only).
    pub issue_ready: bool,
    /// Free response-FIFO entries at the start of the cycle (depends on registers only).
    pub resp_free: u32,
    /// The one 32 B memory request of this cycle.
    pub request: Option<MemRequest>,
    /// The one warp completing this cycle.
    pub done: Option<WarpDone>,
    /// Rays that reached a treelet boundary this cycle (all from the slot whose response was
    /// popped).
    pub boundary: Vec<BoundaryEvent>,
    /// Finished lanes released by this cycle's repack (slot and per-lane final records; their
    /// hit records are already stored), freeing the lanes for the repack fill.
    pub released: Option<WarpDone>,
    /// Sticky error flags ([`errors`]), including any raised this cycle.
    pub errors: u8,
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
    /// Chunks of the node in flight returned so far.
    pub chunks: [[u8; CHUNK_BYTES as usize]; MAX_NODE_CHUNKS],
    /// Intersection-delay countdown; the next fetch waits until it is 0.
    pub delay: u32,
    /// A hit record is waiting to be stored.
    pub store_pending: bool,
}

impl Lane {
    /// The lane may request its next node: traversing, nothing in flight, delay 0, a node
    /// left on a stack.
    #[inline]
    pub fn ready(&self) -> bool {
        self.status == LaneStatus::Traversing
            && self.in_flight.is_none()
            && self.delay == 0
            && self.ray.next_node().is_some()
    }

    /// Nothing of the lane is outstanding (its warp may complete as far as the lane goes).
    #[inline]
    pub fn quiescent(&self) -> bool {
        self.status != LaneStatus::Traversing
            && self.in_flight.is_none()
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
    pub lanes: Vec<Lane>,
    /// Simulation cache, not a register: per-lane predicates of `lanes` as bit masks, always
    /// equal to `LaneMasks::of(&lanes)` (see [`RtUnitRegs::refresh_summaries`]).
    pub(super) masks: LaneMasks,
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
    /// `store_pending`.
    pub store: u64,
    /// `delay > 0`.
    pub delayed: u64,
    /// `in_flight.is_some()`.
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
            store: 0,
            delayed: 0,
            in_flight: 0,
            has_next: 0,
            leader: [0; 64],
        }
    }
}

impl LaneMasks {
    /// The masks of `lanes`.
    pub fn of(lanes: &[Lane]) -> Self {
        let mut m = LaneMasks::default();
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
        put(&mut self.store, lane.store_pending);
        put(&mut self.delayed, lane.delay > 0);
        put(&mut self.in_flight, lane.in_flight.is_some());
        put(&mut self.has_next, !lane.ray.finished());
        self.leader[l] = lane.in_flight.map_or(0, |f| f.leader as u8);
    }

    /// Lanes that are not [`Lane::quiescent`].
    #[inline]
    pub fn busy(&self) -> u64 {
        self.traversing | self.in_flight | self.delayed | self.store
    }

    /// Lanes that are [`Lane::ready`].
    #[inline]
    pub fn ready(&self) -> u64 {
        self.traversing & !self.in_flight & !self.delayed & self.has_next
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

/// Statistics registers.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize)]
pub struct RtStats {
    /// Sum over cycles and valid warps of traversing lanes.
    pub active_thread_cycles: u64,
    /// Sum over cycles of valid warps (RT-unit warp cycles).
    pub warp_cycles: u64,
    /// 32 B load requests issued.
    pub requests: u64,
    /// Hit-record stores issued.
    pub stores: u64,
    /// Lanes served by another lane's request (merged within a warp).
    pub merged: u64,
    /// Node tests per kind, indexed by [`super::NodeKind::code`].
    pub tests: [u64; 6],
    /// Triangle tests that reported a hit.
    pub hits: u64,
    /// Warps completed.
    pub warps_done: u64,
}

impl RtStats {
    /// Width of each statistics counter.
    pub const BITS: u32 = 48;

    /// SIMT efficiency: active threads / `warp_size` per RT-unit warp cycle (0 with no cycles).
    pub fn simt_efficiency(&self, warp_size: u32) -> f64 {
        if self.warp_cycles == 0 {
            0.0
        } else {
            self.active_thread_cycles as f64 / (self.warp_cycles as f64 * warp_size as f64)
        }
    }
}

/// All state of the RT unit's control.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RtUnitRegs {
    /// Field widths (constant, for traces).
    pub widths: Widths,
    /// The warp buffer.
    pub slots: Vec<WarpSlot>,
    /// Valid slots, oldest first (the age order of the memory scheduler and of completion).
    pub age: Vec<u32>,
    /// The response FIFO.
    pub fifo: VecDeque<MemResponse>,
    /// Remaining chunks of the node being requested.
    pub split: Option<Split>,
    /// Sticky error flags ([`errors`]).
    pub errors: u8,
    /// Statistics counters.
    pub stats: RtStats,
}

impl RtUnitRegs {
    /// Recomputes the simulation caches that summarize the lanes of each slot. The RT unit keeps
    /// them up to date itself; call this only after writing lane registers directly (for
    /// example when building a register state by hand in a test).
    pub fn refresh_summaries(&mut self) {
        for slot in &mut self.slots {
            slot.masks = LaneMasks::of(&slot.lanes);
        }
    }

    /// Whether every slot's cached lane summary equals a fresh computation from its lanes (the
    /// invariant [`refresh_summaries`](Self::refresh_summaries) restores).
    pub fn summaries_consistent(&self) -> bool {
        self.slots
            .iter()
            .all(|slot| slot.masks == LaneMasks::of(&slot.lanes))
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
