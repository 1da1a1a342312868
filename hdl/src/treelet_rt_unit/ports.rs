//! The treelet RT unit's port bundles, each declared once with [`crate::bundle!`], and its
//! description.

use super::TreeletRtUnit;
use crate::bits::{bits_for, clog2};
use crate::config::HwConfig;
use crate::controller::ControllerStats;
use crate::describe::BlockDesc;
use crate::rt_unit::{
    ErrorRecord, Hit, MemRequest, MemResponse, NodeDatapath, NodeEntry, RayRecord, RequestKind,
    RtStats, Widths, RAY_WORDS,
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
    /// Bits of a whole ray record (ray id, words, hit, current treelet, both stacks and their
    /// pointers and spilled-chunk counts).
    pub record: u32,
    /// Response ports of the RT unit.
    pub resp_ports: u32,
    /// Bits of an RT-unit request tag.
    pub tag: u32,
}

impl TreeletRtUnitWidths {
    /// The widths for `cfg`, with the RT unit's `rt`.
    pub fn new(cfg: &HwConfig, rt: Widths) -> Self {
        let sp = bits_for(cfg.stack_depth as u64);
        let entry = NodeEntry::bits(cfg.address_bits);
        let record = rt.ray_id
            + RAY_WORDS as u32 * 32
            + 1
            + 4 * 32
            + rt.treelet
            + 2 * sp
            + 2 * rt.spilled
            + 2 * cfg.stack_depth * entry;
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

/// A ray that finished traversal: its id and closest hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FinishedRay {
    /// Ray id (free again).
    pub ray: u32,
    /// Closest hit (`None`: a miss).
    pub hit: Option<Hit>,
}

crate::counters! {
    /// One cycle's statistics events of a treelet RT unit (increments; an observer sums them).
    /// The observer attributes the RT unit's tests to the controller's mode after the cycle and
    /// keeps the largest number of queues from the block's register-only outputs
    /// ([`super::TreeletRtUnit::mode`], [`super::TreeletRtUnit::queues`]). The simulator's
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
        /// Ray records loaded this cycle.
        pub ray_records: Vec<RayLoad>,
        /// The head of the queue table's spill FIFO in memory, `(treelet, ray)`, if any.
        pub spill_head: Option<(u64, u32)>,
    }
    ports {
        /// The SM offers a warp.
        sig sm_valid (1) = this.sm_warp.is_some() as u64;
        /// Per lane: the offered warp's lane holds a ray.
        sig sm_active (w.warp_size) = this.sm_warp.as_ref().map_or(0, |l| {
            l.iter().enumerate().fold(0, |m, (i, r)| m | (u64::from(r.is_some()) << i))
        });
        /// Per lane: the offered rays' records (words, root on the stacks).
        bulk sm_rays (w.warp_size * w.record);
        /// Per response port: a 32 B chunk returns (node chunk or stack fill).
        lanes resp_valid (1, w.resp_ports) = |i: usize| (i < this.responses.len()) as u64;
        /// Per response port: its byte address.
        lanes resp_address (w.address, w.resp_ports) = |i: usize| this.responses.get(i).map_or(0, |r| r.address);
        /// Per response port: its request tag.
        lanes resp_tag (w.tag, w.resp_ports) = |i: usize| this.responses.get(i).map_or(0, |r| r.tag as u64);
        /// Per response port: its 256 bits.
        bulk resp_data (256 * w.resp_ports);
        /// Ray records returning this cycle (up to a warp's worth).
        sig ray_count (w.lanes) = this.ray_records.len() as u64;
        /// The returning records with their slots and ray ids.
        bulk ray_records (w.warp_size * (w.slot + w.ray + w.record));
        /// The spill FIFO is not empty.
        sig spill_head_valid (1) = this.spill_head.is_some() as u64;
        /// Treelet of its oldest ray.
        sig spill_head_treelet (w.treelet) = this.spill_head.map_or(0, |h| h.0);
        /// Its oldest ray.
        sig spill_head_ray (w.ray) = this.spill_head.map_or(0, |h| h.1 as u64);
    }
}

crate::bundle! {
    /// The treelet RT unit's outputs for one cycle.
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub struct TreeletRtUnitOutputs (Out, w: TreeletRtUnitWidths, this) {
        /// The offered SM warp was accepted: the ray id given to each lane's ray.
        pub sm_accepted: Option<Vec<Option<u32>>>,
        /// Memory requests of the cycle, in issue order.
        pub requests: Vec<TreeletRequest>,
        /// Rays that finished traversal.
        pub finished: Vec<FinishedRay>,
        /// Records of rays that stopped at a treelet boundary, for the ray-record store (their
        /// 32 B record was stored when they entered; the traversal stacks travel with it).
        pub parked: Vec<RayRecord>,
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
        /// The offered SM warp is accepted this cycle.
        sig sm_accept (1) = this.sm_accepted.is_some() as u64;
        /// Per lane: the ray id given to the accepted warp's ray.
        lanes sm_ray_id (w.ray, w.warp_size) = |i: usize| {
            this.sm_accepted.as_ref().and_then(|l| l.get(i).copied().flatten()).unwrap_or(0) as u64
        };
        /// Ray-record loads issued this cycle.
        sig ray_load_count (w.lanes) = this.requests.iter().filter(|r| matches!(r, TreeletRequest::RayLoad { .. })).count() as u64;
        /// Ray-record stores issued this cycle.
        sig ray_store_count (w.lanes) = this.requests.iter().filter(|r| matches!(r, TreeletRequest::RayStore { .. })).count() as u64;
        /// Their ray ids and addresses, in issue order (up to two warps' worth).
        bulk ray_requests (2 * w.warp_size * (w.ray + w.address));
        /// The RT unit requests a 32 B access.
        sig mem_req_valid (1) = this.rt_request().is_some() as u64;
        /// Its byte address.
        sig mem_req_address (w.address) = this.rt_request().map_or(0, |r| r.address);
        /// 0 node-chunk load, 1 hit-record store, 2 stack spill, 3 stack fill.
        sig mem_req_kind (RequestKind::BITS) = this.rt_request().map_or(0, |r| r.kind.code());
        /// Its tag.
        sig mem_req_tag (w.tag) = this.rt_request().map_or(0, |r| r.tag as u64);
        /// Store data.
        bulk mem_req_data (256);
        /// Rays finishing this cycle.
        sig finished_count (w.lanes) = this.finished.len() as u64;
        /// Their ray ids and closest hits (up to two warps' worth: a repack's released lanes and a completed warp).
        bulk finished (2 * w.warp_size * (w.ray + 1 + 4 * 32));
        /// Rays parked at a treelet boundary this cycle.
        sig parked_count (w.lanes) = this.parked.len() as u64;
        /// Their records, for the ray-record store (up to a warp's worth).
        bulk parked (w.warp_size * w.record);
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
        /// The RT unit's sticky error flags.
        sig errors (crate::rt_unit::errors::BITS) = this.errors as u64;
        /// The wiring found an inconsistency (sticky).
        sig fault (1) = this.fault.is_some() as u64;
        /// The cycle's statistics events (the RT unit's and the controller's event ports, spills, refills, ray-record traffic, restarts, tests per phase).
        bulk counts (64);
    }
}

impl TreeletRtUnitOutputs {
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
        params: vec![
            ("warp_size".into(), u.cfg.warp_size as u64),
            ("warp_buffer_size".into(), u.cfg.warp_buffer_size as u64),
            ("max_rays".into(), u.cfg.max_rays as u64),
            ("ray_base".into(), u.ray_base),
        ],
        ports,
        registers: super::glue::registers(&u.cfg, w).descs(),
        memories: vec![],
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
