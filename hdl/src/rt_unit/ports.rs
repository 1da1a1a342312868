//! The RT unit's port bundles, declared once with [`crate::bundle!`] (both in one declaration:
//! its description lists each request's ports beside their answer), and the widths of its
//! fields.
//!
//! Per-lane fields of a bus port appear in traces as `<port>_<lane>`, the 256-bit data buses as
//! `<port>_<k>` 64-bit words (`k` = 0 for the lowest bytes). Ray words, hits and stack contents
//! are bulk data: described, not traced.

use super::bundles::{
    BoundaryEvent, ErrorRecord, IssueTarget, LaneWrite, MemRequest, MemResponse, RayOutcome,
    RayRecord, RequestKind, RtStats, SlotSummary, TraversalOrder, WarpDone, WarpIssue,
};
use super::event_ports::{RtCountPorts, RtCountWidths, RtErrorPorts, RtErrorWidths};
use super::node::{Hit, NodeEntry, CHUNK_BYTES, RAY_WORDS};
use crate::bits::{bits_for, BitPacker};

/// Bits of a memory data chunk (32 B).
pub(super) const DATA_BITS: u32 = CHUNK_BYTES * 8;
/// Bits of a hit: t, hit id and two attributes.
pub(crate) const HIT_BITS: u32 = 4 * 32;
/// Bits of a request's size field (bytes, always 32).
const SIZE_BITS: u32 = 6;
/// Bits of the ray words (origin, direction, tmin, tmax).
const WORD_BITS: u32 = RAY_WORDS as u32 * 32;

/// Widths of the fields of the port bundles, fixed by the configuration; they let a bundle list
/// its signals with the same names and widths every cycle.
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
    /// Bits of a stack's spilled-chunk count.
    pub spilled: u32,
    /// Entries of a lane's on-chip stack (`stack_depth`).
    pub stack_depth: u32,
    /// Bits of an on-chip stack's depth (0..=stack_depth).
    pub stack_pointer: u32,
    /// Entries per stack a ray record carries in and out (`record_stack_entries`).
    pub record_stack: u32,
    /// Bits of a record's stack depth (0..=record_stack).
    pub record_pointer: u32,
}

impl Widths {
    /// Bits of a stack entry (a node reference).
    pub fn entry(&self) -> u32 {
        NodeEntry::bits(self.address)
    }

    /// The widths of the error ports ([`RtErrorPorts`]).
    pub fn errors(&self) -> RtErrorWidths {
        RtErrorWidths {
            slot: self.slot,
            lane: self.lane,
            ray_id: self.ray_id,
        }
    }

    /// The widths of the statistics-event ports ([`RtCountPorts`]): each lane count as wide as
    /// its largest value.
    pub fn counts(&self) -> RtCountWidths {
        RtCountWidths {
            warps: bits_for(self.slots as u64),
            lanes: bits_for(self.warp_size as u64 * self.slots as u64),
            warp_lanes: bits_for(self.warp_size as u64),
        }
    }
}

crate::bundle! {
    /// The RT unit's inputs for one cycle. Build an idle bundle with
    /// [`super::RtUnit::idle_inputs`].
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub struct RtUnitInputs (In, w: Widths, this) {
        /// A warp to load into a free slot (only when `issue_ready`).
        pub issue: Option<WarpIssue>,
        /// Ray records to write into inactive lanes ahead of their warp's issue, on the issue
        /// bus's lanes the issue leaves free.
        pub write: Option<LaneWrite>,
        /// Responses from memory this cycle, at most `resp_ports` and at most `resp_free`.
        pub responses: Vec<MemResponse>,
        /// Terminate this slot's warp into the treelet queues (treelet controller `terminate`):
        /// its order becomes [`TraversalOrder::TreeletStop`], so each ray stops at its next
        /// treelet boundary; a ray already between treelets (current stack empty, nothing in
        /// flight) parks at once.
        pub stop: Option<u32>,
        /// Repack this slot's warp (treelet controller `repack`): its finished, quiescent lanes
        /// are released on [`RtUnitOutputs::released`] and the slot is held (it does not
        /// complete) until an [`IssueTarget::Append`] with `last` arrives.
        pub repack: Option<u32>,
    }
    /// The RT unit's outputs for one cycle.
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub struct RtUnitOutputs (Out, w: Widths, this) {
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
        /// Finished lanes released by this cycle's repack (slot and per-lane final records;
        /// their hit records are already stored), freeing the lanes for the repack fill.
        pub released: Option<WarpDone>,
        /// Sticky error flags ([`errors`](super::errors)), including any raised this cycle.
        pub errors: u8,
        /// The first error raised so far, with its details (sticky, like `errors`).
        pub first_error: Option<ErrorRecord>,
        /// This cycle's events for the statistics counters outside the block (warp cycles,
        /// active lanes, requests, tests...): one cycle's increments, summed by whoever keeps
        /// the statistics ([`RtStats::add`]).
        pub counts: RtStats,
    }
    ports {
        /// a warp is issued to the warp buffer this cycle
        In sig issue_valid (1) = this.issue.is_some() as u64;
        /// a warp-buffer slot is free (registers only)
        Out sig issue_ready (1) = this.issue_ready as u64;
        /// traversal order: 0 ray-stationary single stack, 1 treelet two-stack continuing across boundaries, 2 treelet two-stack stopping at a boundary
        In sig issue_order (TraversalOrder::BITS) = this.issue.as_ref().map_or(0, |i| i.order.code());
        /// 0 a new warp in the lowest free slot, 1 a new warp in issue_slot (reserved by the treelet controller), 2 append the active lanes into inactive lanes of held slot issue_slot (repack fill)
        In sig issue_target (IssueTarget::BITS) = this.issue.as_ref().map_or(0, |i| i.target.code());
        /// slot of issue_target 1 and 2
        In sig issue_slot (w.slot) = this.issue.as_ref().map_or(0, |i| i.target.slot() as u64);
        /// with issue_target 2: the repack fill is complete, release the hold
        In sig issue_last (1) = this.issue.as_ref().is_some_and(|i| {
            matches!(i.target, IssueTarget::Append { last: true, .. })
        }) as u64;
        /// treelet controller terminate: stop_slot's rays stop at their next treelet boundary (order becomes treelet-stop)
        In sig stop_valid (1) = this.stop.is_some() as u64;
        /// the terminated slot
        In sig stop_slot (w.slot) = this.stop.unwrap_or(0) as u64;
        /// treelet controller repack: release repack_slot's finished lanes and hold the slot until a fill with issue_last
        In sig repack_valid (1) = this.repack.is_some() as u64;
        /// the repacked slot
        In sig repack_slot (w.slot) = this.repack.unwrap_or(0) as u64;
        /// per lane: the lane holds a ray from the bus
        In sig issue_active (w.warp_size) = mask(w.warp_size, |i| this.issue_lane(i).is_some());
        /// per lane: the lane enters with the record written into it before (not from the bus)
        In sig issue_written (w.warp_size) = this.issue.as_ref().map_or(0, |i| i.written) & mask(w.warp_size, |_| true);
        /// ray records are written into lanes of write_slot ahead of their warp's issue, from the bus lanes in write_mask
        In sig write_valid (1) = this.write.is_some() as u64;
        /// the slot written (free, or held by a repack)
        In sig write_slot (w.slot) = this.write.as_ref().map_or(0, |x| x.slot as u64);
        /// per lane: the lane takes the record on its bus lane and stays inactive until issued
        In sig write_mask (w.warp_size) = mask(w.warp_size, |i| this.write_lane(i).is_some());
        /// per lane: ray id (the bus: the issued lane's ray, else the written lane's)
        In lanes issue_ray_id (w.ray_id, w.warp_size) = |i: usize| {
            this.bus_lane(i).map_or(0, |r| r.ray_id as u64)
        };
        /// per lane: the rest of the ray state on the bus (words, hit, current treelet, both on-chip stacks and their pointers and spilled-chunk counts)
        In bulks issue (ray_state(w)) = |f: usize| ray_state_words(w, f, |i| this.bus_lane(i));
        /// a 32 B memory request is issued (at most one per cycle)
        Out sig req_valid (1) = this.request.is_some() as u64;
        /// byte address of the request (32 B aligned)
        Out sig req_address (w.address) = this.request.map_or(0, |r| r.address);
        /// request size in bytes (always 32; a 64 B node takes two requests)
        Out sig req_size (SIZE_BITS) = this.request.map_or(0, |_| CHUNK_BYTES as u64);
        /// 0 node-chunk load, 1 hit-record store (no response), 2 stack spill store (no response), 3 stack fill load
        Out sig req_kind (RequestKind::BITS) = this.request.map_or(0, |r| r.kind.code());
        /// requesting slot and lane (slot << lane_bits | lane), returned with the response
        Out sig req_tag (w.tag) = this.request.map_or(0, |r| r.tag as u64);
        /// store data: hit record (t, hit id, two attributes, ray id) or up to four spilled stack entries (64-bit slots, valid bit 63, bottom first)
        Out lanes req_data (64, 4) = |k: usize| {
            data_word(this.request.as_ref().filter(|r| r.is_store()).map(|r| &r.data), k)
        };
        /// free response-FIFO entries (registers only); memory delivers no more than this
        Out sig resp_free (w.fifo_count) = this.resp_free as u64;
        In group resp (k < w.resp_ports) {
            /// a 32 B chunk returns from memory on this response port
            sig valid (1) = (k < this.responses.len()) as u64;
            /// byte address of the returned chunk
            sig address (w.address) = this.responses.get(k).map_or(0, |r| r.address);
            /// tag of the request the chunk answers
            sig tag (w.tag) = this.responses.get(k).map_or(0, |r| r.tag as u64);
            /// the chunk's 256 bits
            lanes data (64, 4) = |j: usize| data_word(this.responses.get(k).map(|r| &r.data), j);
        }
        /// a warp completes this cycle (at most one)
        Out sig done_valid (1) = this.done.is_some() as u64;
        /// warp-buffer slot of the completed warp
        Out sig done_slot (w.slot) = this.done.as_ref().map_or(0, |d| d.slot as u64);
        /// per lane: the ray stopped at a treelet boundary rather than finishing
        Out sig done_parked (w.warp_size) = mask(w.warp_size, |i| {
            this.done_lane(i).is_some_and(|(_, o)| *o != RayOutcome::Finished)
        });
        /// per lane: the lane holds a ray
        Out sig done_active (w.warp_size) = mask(w.warp_size, |i| this.done_lane(i).is_some());
        /// per lane: ray id
        Out lanes done_ray_id (w.ray_id, w.warp_size) = |i: usize| {
            this.done_lane(i).map_or(0, |(r, _)| r.ray_id as u64)
        };
        /// per lane: the rest of the ray state written back at completion
        Out bulks done (ray_state(w)) = |f: usize| {
            ray_state_words(w, f, |i| this.done_lane(i).map(|(r, _)| r))
        };
        /// per lane: the ray reached a treelet boundary this cycle
        Out sig boundary_valid (w.warp_size) = mask(w.warp_size, |i| this.boundary_at(i).is_some());
        /// slot of the rays reaching a boundary (the slot whose response was popped)
        Out sig boundary_slot (w.slot) = this.boundary.first().map_or(0, |e| e.slot as u64);
        /// per lane: ray id
        Out lanes boundary_ray_id (w.ray_id, w.warp_size) = |i: usize| {
            this.boundary_at(i).map_or(0, |e| e.ray_id as u64)
        };
        /// per lane: treelet the ray needs next
        Out lanes boundary_treelet (w.treelet, w.warp_size) = |i: usize| {
            this.boundary_at(i).map_or(0, |e| e.treelet)
        };
        /// a repack released finished lanes this cycle (their hit records are already stored)
        Out sig released_valid (1) = this.released.is_some() as u64;
        /// slot of the released lanes
        Out sig released_slot (w.slot) = this.released.as_ref().map_or(0, |d| d.slot as u64);
        /// per lane: released
        Out sig released_mask (w.warp_size) = mask(w.warp_size, |i| {
            this.released.as_ref().is_some_and(|d| d.lanes.get(i).is_some_and(Option::is_some))
        });
        /// per lane: the released ray's id
        Out lanes released_ray_id (w.ray_id, w.warp_size) = |i: usize| {
            this.released_lane(i).map_or(0, |r| r.ray_id as u64)
        };
        /// per lane: the released ray has a hit
        Out sig released_hit_valid (w.warp_size) = mask(w.warp_size, |i| {
            this.released_lane(i).is_some_and(|r| r.hit.is_some())
        });
        /// per lane: the released ray's closest hit
        Out bulks released ([("hit", w.warp_size * HIT_BITS, "per lane: the released ray's closest hit t, hit id, two attributes (t lowest)")]) = |_f: usize| {
            let mut p = BitPacker::new();
            for i in 0..w.warp_size as usize {
                Hit::pack(this.released_lane(i).and_then(|r| r.hit.as_ref()), &mut p);
            }
            p.into_words()
        };
        Out nest (w.errors()) = RtErrorPorts { errors: this.errors, first_error: this.first_error };
        Out nest count (w.counts()) = RtCountPorts { counts: this.counts };
    }
}

/// The register-only state of one occupied warp-buffer slot, as the RT unit's status ports
/// carry it ([`RtUnitStatus`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SlotStatus {
    /// The warp's traversal order.
    pub order: TraversalOrder,
    /// Held by a repack.
    pub held: bool,
    /// Its lanes' summary; `distinct_next_treelets` is counted for a warp in
    /// [`TraversalOrder::TreeletContinue`] order only, and only when asked for (0 otherwise:
    /// [`StatusSelect::Distinct`]).
    pub summary: SlotSummary,
    /// Bit `l` set for each lane holding no ray (where a repack fill may append).
    pub inactive: u64,
}

crate::bundle! {
    /// The RT unit's register-only output ports ([`crate::block::Moore`]): what the warp
    /// buffer holds at the start of the cycle, before the cycle's inputs are known. The treelet
    /// RT unit's wiring reads these (free slot, idle, the controller's initial-phase and
    /// active-lane reports, where a repack fill appends) and nothing else of the unit's state.
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub struct RtUnitStatus (Out, w: Widths, this) {
        /// Per warp-buffer slot: its warp's status (`None`: the slot holds no warp); empty when
        /// not selected ([`StatusSelect::Scalars`]).
        pub slots: Vec<Option<SlotStatus>>,
        /// A slot is free: the `issue_ready` port (among the cycle's outputs,
        /// [`RtUnitOutputs::issue_ready`]).
        pub issue_ready: bool,
        /// Free response-FIFO entries: the `resp_free` port ([`RtUnitOutputs::resp_free`]).
        pub resp_free: u32,
    }
    ports {
        /// per slot: the slot holds a warp (registers only)
        sig status_valid (w.slots) = mask(w.slots, |s| this.slot(s).is_some());
        /// per slot: its warp is held by a repack (registers only)
        sig status_held (w.slots) = mask(w.slots, |s| this.slot(s).is_some_and(|x| x.held));
        /// per slot: every lane is quiescent, so the warp completes this cycle unless held (registers only)
        sig status_quiescent (w.slots) = mask(w.slots, |s| this.slot(s).is_some_and(|x| x.summary.quiescent));
        /// per slot: its warp's traversal order (registers only)
        lanes status_order (TraversalOrder::BITS, w.slots) = |s: usize| {
            this.slot(s).map_or(0, |x| x.order.code())
        };
        /// per slot: lanes traversing (registers only)
        lanes status_traversing (bits_for(w.warp_size as u64), w.slots) = |s: usize| {
            this.slot(s).map_or(0, |x| x.summary.traversing as u64)
        };
        /// per slot: lanes a repack cannot release yet (traversing, parked, or finished with a node, delay or store outstanding; registers only)
        lanes status_busy (bits_for(w.warp_size as u64), w.slots) = |s: usize| {
            this.slot(s).map_or(0, |x| x.summary.busy as u64)
        };
        /// per slot: distinct treelets of the traversing lanes' next nodes, for a warp in treelet-continue order (0 otherwise; registers only; the simulator evaluates it only in the controller modes that read it, initial and treelet-stationary)
        lanes status_distinct (bits_for(w.warp_size as u64), w.slots) = |s: usize| {
            this.slot(s).map_or(0, |x| x.summary.distinct_next_treelets as u64)
        };
        /// per slot, per lane: the lane holds no ray (registers only)
        lanes status_inactive (w.warp_size, w.slots) = |s: usize| {
            this.slot(s).map_or(0, |x| x.inactive)
        };
    }
}

/// Which of the RT unit's register-only outputs [`crate::block::Moore::status`] computes: a
/// simulator leaves out what no reader looks at in the cycle (hardware drives them all).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StatusSelect {
    /// `issue_ready` and `resp_free` only (no slot list).
    Scalars,
    /// And every slot's status, with the distinct next treelets left at 0.
    Slots,
    /// And the distinct next treelets of warps in treelet-continue order (the costly part:
    /// the treelet wiring reads them only in modes that terminate divergent warps).
    Distinct,
}

impl StatusSelect {
    /// Every slot's status, with the distinct next treelets if `distinct`.
    pub fn slots(distinct: bool) -> Self {
        if distinct {
            StatusSelect::Distinct
        } else {
            StatusSelect::Slots
        }
    }
}

impl RtUnitStatus {
    /// Slot `s`'s status, if it holds a warp.
    pub fn slot(&self, s: usize) -> Option<&SlotStatus> {
        self.slots.get(s)?.as_ref()
    }

    /// Whether the warp buffer holds no warp.
    pub fn is_empty(&self) -> bool {
        self.slots.iter().all(Option::is_none)
    }
}

impl RtUnitInputs {
    /// The ray issued into lane `i` from the bus, if any.
    fn issue_lane(&self, i: usize) -> Option<&RayRecord> {
        self.issue.as_ref()?.lanes.get(i)?.as_ref()
    }

    /// The ray written into lane `i`, if any.
    fn write_lane(&self, i: usize) -> Option<&RayRecord> {
        self.write.as_ref()?.lanes.get(i)?.as_ref()
    }

    /// What bus lane `i` carries: the issued ray, else the written one.
    fn bus_lane(&self, i: usize) -> Option<&RayRecord> {
        self.issue_lane(i).or_else(|| self.write_lane(i))
    }
}

impl RtUnitOutputs {
    /// The completed warp's lane `i`, if it held a ray.
    fn done_lane(&self, i: usize) -> Option<&(RayRecord, RayOutcome)> {
        self.done.as_ref()?.lanes.get(i)?.as_ref()
    }

    /// Lane `i`'s ray released by this cycle's repack, if any.
    fn released_lane(&self, i: usize) -> Option<&RayRecord> {
        self.released
            .as_ref()?
            .lanes
            .get(i)?
            .as_ref()
            .map(|(r, _)| r)
    }

    /// The boundary event of lane `i`, if any.
    fn boundary_at(&self, i: usize) -> Option<&BoundaryEvent> {
        self.boundary.iter().find(|e| e.lane as usize == i)
    }
}

/// The bulk fields of every lane's ray state, as `(field, width, doc)`: what the ray-state
/// ports carry beside the traced `active` and `ray_id` (loaded at issue, written back at
/// completion).
pub(crate) fn ray_state(w: &Widths) -> [(&'static str, u32, &'static str); 11] {
    let n = w.warp_size;
    let stack = n * w.record_stack * w.entry();
    [
        ("ray_words", n * WORD_BITS, "per lane: origin, direction, tmin, tmax (f32 bits)"),
        ("occlusion", n, "per lane: an occlusion ray (traversal ends at its first accepted hit)"),
        ("hit_valid", n, "per lane: the ray has a hit"),
        ("hit", n * HIT_BITS, "per lane: closest hit t, hit id, two attributes"),
        ("cur_treelet", n * w.treelet, "per lane: current treelet"),
        ("cur_sp", n * w.record_pointer, "per lane: current-treelet stack depth (at most record_stack_entries)"),
        ("other_sp", n * w.record_pointer, "per lane: other-treelet stack depth (at most record_stack_entries)"),
        ("cur_spilled", n * w.spilled, "per lane: current-treelet stack chunks in the spill area"),
        ("other_spilled", n * w.spilled, "per lane: other-treelet stack chunks in the spill area"),
        ("cur_stack", stack, "per lane: current-treelet stack entries, bottom first (parallel load of the ray state)"),
        ("other_stack", stack, "per lane: other-treelet stack entries, bottom first"),
    ]
}

/// Field `f` of [`ray_state`] for every lane as 64-bit words (lane `i` in bits
/// `[i*width +: width]`, zero for a lane without a ray): ray words `[j*32 +: 32]`, hit
/// `{attribs[1], attribs[0], hit id, t}` (t lowest), stacks entry `j` (bottom first) in
/// `[j*entry +: entry]` as [`NodeEntry::encode`], entries above the pointer zero.
pub(crate) fn ray_state_words<'a>(
    w: &Widths,
    f: usize,
    lane: impl Fn(usize) -> Option<&'a RayRecord>,
) -> Vec<u64> {
    let mut p = BitPacker::new();
    for i in 0..w.warp_size as usize {
        let r = lane(i);
        let hit = r.and_then(|r| r.hit);
        let stack = |p: &mut BitPacker, s: Option<&crate::bounded::BoundedVec<NodeEntry>>| {
            for j in 0..w.record_stack as usize {
                p.push(
                    s.and_then(|s| s.get(j)).map_or(0, NodeEntry::encode),
                    w.entry(),
                );
            }
        };
        match f {
            0 => {
                for j in 0..RAY_WORDS {
                    p.push(r.map_or(0, |r| r.words[j] as u64), 32);
                }
            }
            1 => {
                p.push(r.is_some_and(|r| r.occlusion) as u64, 1);
            }
            2 => {
                p.push(hit.is_some() as u64, 1);
            }
            3 => Hit::pack(hit.as_ref(), &mut p),
            4 => {
                p.push(r.map_or(0, |r| r.current_treelet), w.treelet);
            }
            5 => {
                p.push(
                    r.map_or(0, |r| r.current_stack.len() as u64),
                    w.record_pointer,
                );
            }
            6 => {
                p.push(
                    r.map_or(0, |r| r.other_stack.len() as u64),
                    w.record_pointer,
                );
            }
            7 => {
                p.push(r.map_or(0, |r| r.current_spilled as u64), w.spilled);
            }
            8 => {
                p.push(r.map_or(0, |r| r.other_spilled as u64), w.spilled);
            }
            9 => stack(&mut p, r.map(|r| &r.current_stack)),
            _ => stack(&mut p, r.map(|r| &r.other_stack)),
        }
    }
    p.into_words()
}

/// A mask of `n` lanes, bit `i` set where `on(i)`.
fn mask(n: u32, on: impl Fn(usize) -> bool) -> u64 {
    (0..n as usize).fold(0, |m, i| m | (u64::from(on(i)) << i))
}

/// 64-bit word `k` of a 32 B chunk (word 0 holds the lowest bytes; 0 without a chunk).
pub(crate) fn data_word(data: Option<&[u8; CHUNK_BYTES as usize]>, k: usize) -> u64 {
    data.map_or(0, |d| {
        let mut bytes = [0u8; 8];
        bytes.copy_from_slice(&d[8 * k..8 * k + 8]);
        u64::from_le_bytes(bytes)
    })
}
