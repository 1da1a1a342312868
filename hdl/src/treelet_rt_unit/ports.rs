//! The treelet RT unit's port bundles, each declared once with [`crate::bundle!`], and its
//! description.

use super::TreeletRtUnit;
use crate::bits::{bits_for, clog2, BitPacker};
use crate::config::HwConfig;
use crate::controller::{ControllerCountPorts, ControllerCountWidths, ControllerStats};
use crate::describe::{block_params, BlockDesc};
use crate::rt_unit::{
    data_word, ray_state, ray_state_words, ErrorRecord, Hit, MemRequest, MemResponse, NodeDatapath,
    NodeEntry, RayRecord, RequestKind, RtCountPorts, RtCountWidths, RtErrorPorts, RtStats, Widths,
    HIT_BITS, RAY_WORDS,
};
use serde::Serialize;

/// Widths of the treelet RT unit's fields, derived from the configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TreeletRtUnitWidths {
    /// Lanes per warp.
    pub warp_size: u32,
    /// Bits of a ray id.
    pub ray: u32,
    /// Bits of a treelet number.
    pub treelet: u32,
    /// Bits of a byte address.
    pub address: u32,
    /// Bits of a warp-buffer slot index.
    pub slot: u32,
    /// Bits of a count of lanes of all warp-buffer slots (0..=slots x warp_size).
    pub lanes: u32,
    /// Bits of a whole ray record (ray id, words, occlusion flag, hit, current treelet, both
    /// stacks and their pointers and spilled-chunk counts).
    pub record: u32,
    /// Response ports of the RT unit.
    pub resp_ports: u32,
    /// Bits of an RT-unit request tag.
    pub tag: u32,
    /// Bits of a count of a warp's lanes (0..=warp_size).
    pub warp_lanes: u32,
    /// Ray records the fills take per cycle (`record_bytes_per_cycle / 32`, the wiring's
    /// record write ports).
    pub record_ports: u32,
    /// The RT unit's widths.
    pub rt: Widths,
}

impl TreeletRtUnitWidths {
    /// The widths for `cfg`, with the RT unit's `rt`.
    pub fn new(cfg: &HwConfig, rt: Widths) -> Self {
        let sp = rt.record_pointer;
        let entry = NodeEntry::bits(cfg.address_bits);
        let record = rt.ray_id
            + RAY_WORDS as u32 * 32
            + 1
            + 1
            + 4 * 32
            + rt.treelet
            + 2 * sp
            + 2 * rt.spilled
            + 2 * rt.record_stack * entry;
        TreeletRtUnitWidths {
            warp_size: cfg.warp_size,
            ray: rt.ray_id,
            treelet: rt.treelet,
            address: cfg.address_bits,
            slot: clog2(cfg.warp_buffer_size as u64),
            lanes: bits_for(cfg.warp_size as u64 * cfg.warp_buffer_size as u64 * 2),
            record,
            resp_ports: rt.resp_ports,
            tag: rt.tag,
            warp_lanes: bits_for(cfg.warp_size as u64),
            record_ports: cfg.record_ports(),
            rt,
        }
    }

    /// The RT unit's widths with one lane per record port: the returning records' ports carry
    /// a ray's state as a warp's lanes do.
    fn record_port_lanes(&self) -> Widths {
        Widths {
            warp_size: self.record_ports,
            ..self.rt
        }
    }
}

/// A ray record loaded for a fill (the answer to a [`TreeletRequest::RayLoad`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RayLoad {
    /// The warp-buffer slot whose fill asked for it.
    pub slot: u32,
    /// Its ray id.
    pub ray: u32,
    /// The record, as the ray left the RT unit at its treelet boundary.
    pub record: RayRecord,
}

/// A memory request of the treelet RT unit, in issue order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TreeletRequest {
    /// Load ray `ray`'s 32 B record at `address` for the fill of slot `slot` (L1 bypass; answer
    /// on `ray_records`).
    RayLoad {
        /// Warp-buffer slot of the fill.
        slot: u32,
        /// Ray id.
        ray: u32,
        /// Byte address of the record.
        address: u64,
    },
    /// Store ray `ray`'s 32 B record at `address` (an SM warp's ray entering; L1 bypass).
    RayStore {
        /// Ray id.
        ray: u32,
        /// Byte address of the record.
        address: u64,
    },
    /// The RT unit's request (node chunk, hit record, stack spill or fill).
    Rt(MemRequest),
}

/// A ray that finished traversal: its id and closest hit, at the position of the lane it left.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FinishedRay {
    /// Where it left: lane `l` of a repack's released lanes is position `l`, lane `l` of a
    /// completed warp is `warp_size + l` (the position on the `finished_*` ports).
    pub position: u32,
    /// Ray id (free again).
    pub ray: u32,
    /// Closest hit (`None`: a miss).
    pub hit: Option<Hit>,
}

/// A ray that stopped at a treelet boundary: the lane of the completed warp it left and its
/// record, for the ray-record store.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParkedRay {
    /// The completed warp's lane it left (the position on the `parked_*` ports).
    pub lane: u32,
    /// The record, as the ray left the RT unit.
    pub record: RayRecord,
}

crate::counters! {
    /// One cycle's statistics events of a treelet RT unit (increments; an observer sums them).
    /// The observer attributes the RT unit's tests to the controller's mode after the cycle and
    /// keeps the largest number of queues from the block's register-only outputs
    /// ([`super::TreeletRtUnitStatus::mode`], [`super::TreeletRtUnitStatus::queues`]). The simulator's
    /// statistics report their sum over the SMs as the `queues` object of docs/stats.md (with
    /// the controller's counters inline); the rest are reported elsewhere (`serde(skip)`).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
    pub struct TreeletCounts {
        /// The RT unit's (reported in the `rt` object with the other SMs' RT units).
        #[serde(skip)]
        pub rt: RtStats,
        /// The controller's.
        #[serde(flatten)]
        pub ctl: ControllerStats,
        /// Queue-table inserts that spilled to memory (reported as `queue_table_spills`).
        #[serde(skip)]
        pub spills: u64,
        /// Spilled rays brought back into the queue table.
        pub refills: u64,
        /// 32 B ray-record loads for treelet, grouped and repacked warps.
        pub ray_loads: u64,
        /// 32 B ray-record stores when SM warps issue their rays.
        pub ray_stores: u64,
        /// Controller restarts from `done` when new warps arrive (an idle controller is `done`,
        /// so the first warp of a run counts too; then one per wave of rays).
        pub restarts: u64,
    }
}

crate::bundle! {
    /// The treelet RT unit's inputs for one cycle.
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub struct TreeletRtUnitInputs (In, w: TreeletRtUnitWidths, this) {
        /// A warp the SM offers (only while `sm_ready`): per lane its ray (`None`: an idle lane);
        /// ray ids are given on acceptance.
        pub sm_warp: Option<Vec<Option<RayRecord>>>,
        /// Memory responses for the RT unit this cycle (at most its response ports and its
        /// free FIFO entries).
        pub responses: Vec<MemResponse>,
        /// Ray records loaded this cycle: at most `record_ports` (the wiring's record write
        /// ports; more is a fault).
        pub ray_records: Vec<RayLoad>,
        /// The head of the queue table's spill FIFO in memory, `(treelet, ray)`, if any.
        pub spill_head: Option<(u64, u32)>,
    }
    ports {
        /// The SM offers a warp.
        sig sm_valid (1) = this.sm_warp.is_some() as u64;
        /// Per lane: the offered warp's lane holds a ray.
        sig sm_active (w.warp_size) = mask(w.warp_size, |i| this.sm_lane(i).is_some());
        /// Per lane: the offered rays' state (words, hit, treelet, stacks with the root), as the RT unit's issue ports carry it.
        bulks sm (ray_state(&w.rt)) = |f: usize| ray_state_words(&w.rt, f, |i| this.sm_lane(i));
        group resp (k < w.resp_ports) {
            /// A 32 B chunk returns on this response port (node chunk or stack fill).
            sig valid (1) = (k < this.responses.len()) as u64;
            /// Its byte address.
            sig address (w.address) = this.responses.get(k).map_or(0, |r| r.address);
            /// The tag of the request it answers.
            sig tag (w.tag) = this.responses.get(k).map_or(0, |r| r.tag as u64);
            /// Its 256 bits.
            lanes data (64, 4) = |j: usize| data_word(this.responses.get(k).map(|r| &r.data), j);
        }
        /// Ray records returning this cycle (at most one per record port).
        sig ray_count (bits_for(w.record_ports as u64)) = this.ray_records.len() as u64;
        /// Per record port: the slot whose fill asked for its record.
        lanes ray_record_slot (w.slot, w.record_ports) = |i: usize| this.ray_records.get(i).map_or(0, |r| r.slot as u64);
        /// Per record port: the record's ray id.
        lanes ray_record_id (w.ray, w.record_ports) = |i: usize| this.ray_records.get(i).map_or(0, |r| r.ray as u64);
        /// Per record port: the ray's state as it left the RT unit at its treelet boundary.
        bulks ray_record (ray_state(&w.record_port_lanes())) = |f: usize| {
            ray_state_words(&w.record_port_lanes(), f, |i| this.ray_records.get(i).map(|r| &r.record))
        };
        /// The spill FIFO is not empty.
        sig spill_head_valid (1) = this.spill_head.is_some() as u64;
        /// Treelet of its oldest ray.
        sig spill_head_treelet (w.treelet) = this.spill_head.map_or(0, |h| h.0);
        /// Its oldest ray.
        sig spill_head_ray (w.ray) = this.spill_head.map_or(0, |h| h.1 as u64);
    }
}

impl TreeletRtUnitInputs {
    /// Lane `i` of the offered SM warp, if it holds a ray.
    fn sm_lane(&self, i: usize) -> Option<&RayRecord> {
        self.sm_warp.as_ref()?.get(i)?.as_ref()
    }
}

crate::bundle! {
    /// The treelet RT unit's outputs for one cycle.
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub struct TreeletRtUnitOutputs (Out, w: TreeletRtUnitWidths, this) {
        /// The SM may offer a warp (registers only: [`super::TreeletRtUnitStatus::sm_ready`]).
        pub sm_ready: bool,
        /// Free response-FIFO entries of the RT unit (registers only); memory delivers no more.
        pub resp_free: u32,
        /// The offered SM warp was accepted: the ray id given to each lane's ray.
        pub sm_accepted: Option<Vec<Option<u32>>>,
        /// Memory requests of the cycle, in issue order.
        pub requests: Vec<TreeletRequest>,
        /// Rays that finished traversal, in position order (each at the lane it left).
        pub finished: Vec<FinishedRay>,
        /// Rays that stopped at a treelet boundary, in lane order, with their records for the
        /// ray-record store (their 32 B record was stored when they entered; the traversal
        /// stacks travel with it).
        pub parked: Vec<ParkedRay>,
        /// Treelet to preload into the L1.
        pub preload: Option<u32>,
        /// A queue-table entry spills to the spill FIFO: `(treelet, ray)`.
        pub spill_push: Option<(u64, u32)>,
        /// The spill FIFO's head is taken (refilled into the queue table).
        pub spill_pop: bool,
        /// The RT unit's sticky error flags.
        pub errors: u8,
        /// The RT unit's first error, with its details.
        pub first_error: Option<ErrorRecord>,
        /// The wiring's first inconsistency (a ray it cannot place or account for).
        pub fault: Option<super::GlueFault>,
        /// The cycle's statistics events.
        pub counts: TreeletCounts,
    }
    ports {
        /// The SM may offer a warp (registers only).
        sig sm_ready (1) = this.sm_ready as u64;
        /// Free response-FIFO entries of the RT unit (registers only); memory delivers no more than this.
        sig resp_free (w.rt.fifo_count) = this.resp_free as u64;
        /// The offered SM warp is accepted this cycle.
        sig sm_accept (1) = this.sm_accepted.is_some() as u64;
        /// Per lane: the ray id given to the accepted warp's ray.
        lanes sm_ray_id (w.ray, w.warp_size) = |i: usize| {
            this.sm_accepted.as_ref().and_then(|l| l.get(i).copied().flatten()).unwrap_or(0) as u64
        };
        /// Ray-record loads issued this cycle.
        sig ray_load_count (w.lanes) = this.ray_requests().filter(|r| r.0).count() as u64;
        /// Ray-record stores issued this cycle.
        sig ray_store_count (w.lanes) = this.ray_requests().filter(|r| !r.0).count() as u64;
        /// Per ray-record request, in issue order (the loads, then the stores; up to two warps' worth): its ray id.
        lanes ray_request_id (w.ray, 2 * w.warp_size) = |i: usize| this.ray_requests().nth(i).map_or(0, |r| r.1 as u64);
        /// Per ray-record request: the record's byte address.
        lanes ray_request_address (w.address, 2 * w.warp_size) = |i: usize| this.ray_requests().nth(i).map_or(0, |r| r.2);
        /// The RT unit requests a 32 B access.
        sig mem_req_valid (1) = this.rt_request().is_some() as u64;
        /// Its byte address.
        sig mem_req_address (w.address) = this.rt_request().map_or(0, |r| r.address);
        /// 0 node-chunk load, 1 hit-record store, 2 stack spill, 3 stack fill.
        sig mem_req_kind (RequestKind::BITS) = this.rt_request().map_or(0, |r| r.kind.code());
        /// Its tag.
        sig mem_req_tag (w.tag) = this.rt_request().map_or(0, |r| r.tag as u64);
        /// Store data (hit record or spilled stack entries).
        lanes mem_req_data (64, 4) = |k: usize| {
            data_word(this.rt_request().filter(|r| r.is_store()).map(|r| &r.data), k)
        };
        /// Rays finishing this cycle.
        sig finished_count (w.lanes) = this.finished.len() as u64;
        /// Per position (a repack's released lanes, then a completed warp's; no compaction): a ray finishes there.
        lanes finished_valid (1, 2 * w.warp_size) = |i: usize| this.finished_at(i).is_some() as u64;
        /// Per position: the finishing ray's id.
        lanes finished_id (w.ray, 2 * w.warp_size) = |i: usize| this.finished_at(i).map_or(0, |f| f.ray as u64);
        /// Per position: the finishing ray has a hit.
        lanes finished_hit_valid (1, 2 * w.warp_size) = |i: usize| this.finished_at(i).is_some_and(|f| f.hit.is_some()) as u64;
        /// Per position: the finishing ray's closest hit.
        bulks finished ([("hit", 2 * w.warp_size * HIT_BITS, "per position: the finishing ray's closest hit t, hit id, two attributes (t lowest)")]) = |_f: usize| {
            hit_words(2 * w.warp_size as usize, |i| this.finished_at(i).and_then(|f| f.hit))
        };
        /// Rays parked at a treelet boundary this cycle.
        sig parked_count (w.lanes) = this.parked.len() as u64;
        /// Per lane of the completed warp (no compaction): its ray parks.
        sig parked_valid (w.warp_size) = mask(w.warp_size, |i| this.parked_at(i).is_some());
        /// Per lane: the parked ray's id.
        lanes parked_id (w.ray, w.warp_size) = |i: usize| this.parked_at(i).map_or(0, |r| r.ray_id as u64);
        /// Per lane: the parked ray's state, for the ray-record store.
        bulks parked (ray_state(&w.rt)) = |f: usize| ray_state_words(&w.rt, f, |i| this.parked_at(i));
        /// Preload a treelet into the L1 (section 4.3).
        sig preload_valid (1) = this.preload.is_some() as u64;
        /// The treelet.
        sig preload_treelet (w.treelet) = this.preload.unwrap_or(0) as u64;
        /// A queue-table entry spills to the spill FIFO.
        sig spill_push_valid (1) = this.spill_push.is_some() as u64;
        /// Its treelet.
        sig spill_push_treelet (w.treelet) = this.spill_push.map_or(0, |s| s.0);
        /// Its ray.
        sig spill_push_ray (w.ray) = this.spill_push.map_or(0, |s| s.1 as u64);
        /// The spill FIFO's head is taken.
        sig spill_pop (1) = this.spill_pop as u64;
        /// RT unit:
        nest (w.rt.errors()) = RtErrorPorts { errors: this.errors, first_error: this.first_error };
        /// The wiring found an inconsistency (sticky).
        sig fault (1) = this.fault.is_some() as u64;
        // The cycle's statistics events: the RT unit's event ports (its lane counts one bit
        // wider), the controller's events as its observer counts them, and the wiring's own.
        /// RT unit:
        nest count_rt (RtCountWidths { lanes: w.lanes, ..w.rt.counts() }) = RtCountPorts { counts: this.counts.rt };
        /// Controller:
        nest count_ctl (ControllerCountWidths { lanes: w.warp_lanes }) = ControllerCountPorts { counts: this.counts.ctl };
        /// A queue-table insert spilled to memory.
        sig count_spill (1) = this.counts.spills;
        /// A spilled ray was brought back into the queue table.
        sig count_refill (1) = this.counts.refills;
        /// Ray-record loads issued.
        sig count_ray_loads (w.lanes) = this.counts.ray_loads;
        /// Ray-record stores issued.
        sig count_ray_stores (w.lanes) = this.counts.ray_stores;
        /// The controller restarted from done.
        sig count_restart (1) = this.counts.restarts;
    }
}

/// 64-bit words of `n` hits side by side, `{attribs[1], attribs[0], hit id, t}` (t lowest) each,
/// zero for `None`.
fn hit_words(n: usize, hit: impl Fn(usize) -> Option<Hit>) -> Vec<u64> {
    let mut p = BitPacker::new();
    for i in 0..n {
        Hit::pack(hit(i).as_ref(), &mut p);
    }
    p.into_words()
}

/// A mask of `n` lanes, bit `i` set where `on(i)`.
fn mask(n: u32, on: impl Fn(usize) -> bool) -> u64 {
    (0..n as usize).fold(0, |m, i| m | (u64::from(on(i)) << i))
}

impl TreeletRtUnitOutputs {
    /// The ray-record requests among this cycle's requests, in issue order, as `(load, ray,
    /// address)`.
    fn ray_requests(&self) -> impl Iterator<Item = (bool, u32, u64)> + '_ {
        self.requests.iter().filter_map(|r| match *r {
            TreeletRequest::RayLoad { ray, address, .. } => Some((true, ray, address)),
            TreeletRequest::RayStore { ray, address } => Some((false, ray, address)),
            TreeletRequest::Rt(_) => None,
        })
    }

    /// The ray finishing at position `i` of the `finished_*` ports, if any.
    fn finished_at(&self, i: usize) -> Option<&FinishedRay> {
        self.finished.iter().find(|f| f.position as usize == i)
    }

    /// The record of the ray parking from lane `i` of the completed warp, if any.
    fn parked_at(&self, i: usize) -> Option<&RayRecord> {
        let p = self.parked.iter().find(|p| p.lane as usize == i)?;
        Some(&p.record)
    }

    /// The RT unit's request among this cycle's requests, if any.
    pub fn rt_request(&self) -> Option<&MemRequest> {
        self.requests.iter().find_map(|r| match r {
            TreeletRequest::Rt(m) => Some(m),
            _ => None,
        })
    }
}

/// The treelet RT unit's description: its ports, the wiring's registers, its children.
pub(super) fn describe<D: NodeDatapath>(u: &TreeletRtUnit<D>) -> BlockDesc {
    let w = &u.widths;
    let mut ports = TreeletRtUnitInputs::ports(w);
    ports.extend(TreeletRtUnitOutputs::ports(w));
    let children = u.children();
    BlockDesc {
        name: "treelet_rt_unit".into(),
        doc: "Treelet RT unit (paper section 4.2, Figure 8): the RT unit with the treelet \
              controller, the treelet count table and the treelet queue table, and the wiring \
              between them (slot ownership, ray ids, fills of ray records, the event queue from \
              the RT unit to the controller, the tables' registered answers)."
            .into(),
        params: block_params!(u.cfg;
            warp_size, warp_buffer_size, max_rays,
            ray_base = u.ray_base,
        ),
        ports,
        registers: super::glue::registers(&u.cfg, w).descs(),
        memories: super::glue::memories(&u.cfg, w),
        fsms: vec![],
        timing: vec![format!(
            "children: {}; each cycle the controller's inputs come from registers only (the tables' status, their answers of the previous cycle, the RT unit's slot summaries, the first pending event), its ops and commands drive the tables and the RT unit in the same cycle",
            children
                .iter()
                .map(|(_, c)| c.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        )],
    }
}
