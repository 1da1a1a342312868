//! The per-ray records that enter and leave the warp buffer: a ray's traversal state and
//! order, the warps and lane writes issued into the unit, its memory requests and responses,
//! and the warps and treelet boundaries it reports.

use crate::bounded::BoundedVec;
use crate::rt_unit::node::{Hit, NodeEntry, RayWords, CHUNK_BYTES};
use serde::{Deserialize, Serialize};

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

/// Which of a ray's two traversal stacks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum StackSel {
    /// The current-treelet stack (the only stack of the ray-stationary order).
    Current,
    /// The other-treelet stack.
    Other,
}

impl StackSel {
    /// Encoding: 0 current, 1 other (also the stack's index in its ray's spill area).
    pub fn code(self) -> u64 {
        match self {
            StackSel::Current => 0,
            StackSel::Other => 1,
        }
    }

    /// The stack's name in messages.
    pub fn name(self) -> &'static str {
        match self {
            StackSel::Current => "current-treelet",
            StackSel::Other => "other-treelet",
        }
    }
}

/// A ray's complete traversal state: loaded into a warp-buffer lane at issue and handed back
/// when the warp completes (so a ray stopped at a treelet boundary can resume in another warp).
///
/// Each stack is split between the lane's on-chip stack (at most `stack_depth` entries, its
/// top) and 32 B chunks of older entries spilled to the ray's spill area in memory (the chunks
/// stay there while the ray waits outside the RT unit; their number travels with the record).
/// The on-chip parts are bounded lists: in a warp-buffer lane their depth is `stack_depth` (a
/// record issued to the RT unit is loaded into stacks of that depth).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RayRecord {
    /// Ray id (below `max_rays`).
    pub ray_id: u32,
    /// Origin, direction, tmin, tmax as f32 bit patterns.
    pub words: RayWords,
    /// An occlusion ray: traversal ends at the first hit the RT unit accepts, in every traversal
    /// order (Vulkan's `gl_RayFlagsTerminateOnFirstHitEXT`; the ray's answer is hit or miss).
    pub occlusion: bool,
    /// Closest hit so far.
    pub hit: Option<Hit>,
    /// Treelet (address >> log2(treelet_bytes)) the current stack belongs to.
    pub current_treelet: u64,
    /// On-chip part of the current-treelet stack, bottom first (the last entry is popped next).
    pub current_stack: BoundedVec<NodeEntry>,
    /// On-chip part of the other-treelet stack, bottom first; when the current stack is empty
    /// its top is popped and its treelet becomes the current treelet.
    pub other_stack: BoundedVec<NodeEntry>,
    /// Chunks of the current-treelet stack spilled to memory (entries below `current_stack`).
    pub current_spilled: u32,
    /// Chunks of the other-treelet stack spilled to memory (entries below `other_stack`).
    pub other_spilled: u32,
}

impl RayRecord {
    /// A fresh ray starting at `root`: the root sits on the other stack, so the first fetch makes
    /// the root's treelet the current treelet.
    pub fn new(ray_id: u32, words: RayWords, root: NodeEntry) -> Self {
        RayRecord {
            ray_id,
            words,
            occlusion: false,
            hit: None,
            current_treelet: 0,
            current_stack: BoundedVec::new(0),
            other_stack: BoundedVec::with(1, [root]).unwrap_or_default(),
            current_spilled: 0,
            other_spilled: 0,
        }
    }

    /// The node the ray visits next if it is on chip (top of the current stack, else, with no
    /// current-stack entries spilled either, top of the other stack); `None` when the ray is
    /// finished or its next entry waits in memory.
    #[inline]
    pub fn next_node(&self) -> Option<NodeEntry> {
        match self.current_stack.last() {
            Some(n) => Some(*n),
            None if self.current_spilled > 0 => None,
            None => self.other_stack.last().copied(),
        }
    }

    /// Whether the current-treelet stack is empty, spilled part included.
    #[inline]
    pub fn current_empty(&self) -> bool {
        self.current_stack.is_empty() && self.current_spilled == 0
    }

    /// Whether both stacks are empty, spilled parts included (traversal finished).
    #[inline]
    pub fn finished(&self) -> bool {
        self.current_empty() && self.other_stack.is_empty() && self.other_spilled == 0
    }

    /// The on-chip part of stack `s`.
    pub fn stack(&self, s: StackSel) -> &BoundedVec<NodeEntry> {
        match s {
            StackSel::Current => &self.current_stack,
            StackSel::Other => &self.other_stack,
        }
    }

    /// The on-chip part of stack `s`, writable.
    pub fn stack_mut(&mut self, s: StackSel) -> &mut BoundedVec<NodeEntry> {
        match s {
            StackSel::Current => &mut self.current_stack,
            StackSel::Other => &mut self.other_stack,
        }
    }

    /// Chunks of stack `s` spilled to memory.
    pub fn spilled(&self, s: StackSel) -> u32 {
        match s {
            StackSel::Current => self.current_spilled,
            StackSel::Other => self.other_spilled,
        }
    }

    /// Chunks of stack `s` spilled to memory, writable.
    pub fn spilled_mut(&mut self, s: StackSel) -> &mut u32 {
        match s {
            StackSel::Current => &mut self.current_spilled,
            StackSel::Other => &mut self.other_spilled,
        }
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
    /// Bit `l` set: lane `l` of the target slot already holds its ray, written there by an
    /// earlier [`LaneWrite`], and enters the warp from that record (its entry in `lanes` is
    /// `None`: it takes nothing from the issue bus).
    pub written: u64,
}

/// Ray records written into lanes of one slot ahead of the warp issue that activates them
/// (`write_valid`, `write_slot`, `write_mask`): a fill's records as they arrive from memory,
/// riding the issue bus in the lanes they are bound for. A written lane holds its record and
/// stays inactive until an issue names it in [`WarpIssue::written`]. The slot is free (a
/// treelet or grouped fill) or held by a repack (its inactive lanes); the bus is shared, so a
/// lane may not carry an issued ray and a written one in the same cycle, and a write may not
/// name the slot the cycle's issue loads.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct LaneWrite {
    /// The slot written.
    pub slot: u32,
    /// One entry per lane (`warp_size` of them): the record written there, `None` for a lane
    /// not written.
    pub lanes: Vec<Option<RayRecord>>,
}

impl LaneWrite {
    /// The lanes written, as a mask (bit `l` for lane `l`).
    pub fn mask(&self) -> u64 {
        occupied(&self.lanes)
    }
}

/// The lanes of `lanes` that carry a ray record, as a mask (bit `l` for lane `l`).
pub fn occupied(lanes: &[Option<RayRecord>]) -> u64 {
    (lanes.iter().enumerate()).fold(0, |m, (l, r)| m | (u64::from(r.is_some()) << l))
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

/// What a memory request of the RT unit does (`req_kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum RequestKind {
    /// Load one chunk of a BVH node (code 0).
    #[default]
    NodeLoad,
    /// Store a ray's 32 B hit record (code 1; no response).
    HitStore,
    /// Store 32 B of stack entries spilled from a lane's on-chip stack (code 2; no response).
    StackSpill,
    /// Load back the most recently spilled 32 B of a lane's stack (code 3).
    StackFill,
}

impl RequestKind {
    /// Width of the kind code.
    pub const BITS: u32 = 2;

    /// The `req_kind` code.
    pub fn code(self) -> u64 {
        match self {
            RequestKind::NodeLoad => 0,
            RequestKind::HitStore => 1,
            RequestKind::StackSpill => 2,
            RequestKind::StackFill => 3,
        }
    }

    /// Whether the request stores data (no response follows).
    pub fn is_store(self) -> bool {
        matches!(self, RequestKind::HitStore | RequestKind::StackSpill)
    }
}

/// One 32 B memory request of the RT unit (to the L1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemRequest {
    /// Byte address (32 B aligned).
    pub address: u64,
    /// What the request does.
    pub kind: RequestKind,
    /// Requesting warp slot and lane, `slot << lane_bits | lane`; a load's response must carry it
    /// back.
    pub tag: u32,
    /// Store data (a hit record or spilled stack entries); zero for loads.
    pub data: [u8; CHUNK_BYTES as usize],
}

impl MemRequest {
    /// Whether the request stores data (no response follows).
    pub fn is_store(&self) -> bool {
        self.kind.is_store()
    }
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
