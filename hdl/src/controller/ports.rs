//! The treelet controller's port bundles, each declared once with [`crate::bundle!`]: its
//! inputs (events and reports from the RT unit, the tables' status and last cycle's answers)
//! and its outputs (commands to the RT unit, one op per table, the events its statistics
//! observer counts).

use super::{ActiveReport, ControllerWidths, EnqueueRequest, FillCommand, FillKind, InitReport};
use crate::bits::fits;
use crate::count_table::{CountOp, CountTableStatus};
use crate::mode::Mode;
use crate::queue_table::{PopResult, QueueOp, QueueTableStatus};
use crate::Signals;

crate::bundle! {
    /// The controller's input ports for one cycle.
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub struct ControllerInputs (In, w: ControllerWidths, this) {
        /// The SM will send no more warps to the RT unit.
        pub launch_done: bool,
        /// The RT unit's warp buffer is empty and it has no events pending.
        pub rt_idle: bool,
        /// The warp buffer holds warps still in their initial phase.
        pub initial_warps: bool,
        /// A free warp-buffer slot the controller may fill, if any.
        pub wb_free_slot: Option<u32>,
        /// Initial-phase divergence report.
        pub init_report: Option<InitReport>,
        /// Enqueue request.
        pub enqueue: Option<EnqueueRequest>,
        /// Warp-buffer slot whose warp finished (its treelet, or traversal) this cycle.
        pub warp_done: Option<u32>,
        /// Active-ray report for repacking.
        pub active_report: Option<ActiveReport>,
        /// The count table's status this cycle (its register-only outputs,
        /// [`Moore::status`](crate::block::Moore::status)).
        pub ct: CountTableStatus,
        /// Treelet the count table evicted last cycle (its answer of the previous cycle).
        pub ct_evict: Option<u32>,
        /// The queue table's status this cycle ([`Moore::status`](crate::block::Moore::status)).
        pub qt: QueueTableStatus,
        /// The outstanding `Pop`/`PopAny`/`Refill` completed last cycle (the table's answer of
        /// the previous cycle, with the popped entry; empty for `Refill`).
        pub qt_done: Option<PopResult>,
        /// Start again from the reset state this cycle if the controller is `done` (a new wave
        /// of rays arrives).
        pub restart: bool,
    }
    ports {
        /// The SM will send no more warps to the RT unit.
        sig launch_done (1) = this.launch_done as u64;
        /// The RT unit's warp buffer is empty and no events are pending.
        sig rt_idle (1) = this.rt_idle as u64;
        /// The warp buffer holds warps still in their initial phase (they may yet fill the queues).
        sig initial_warps (1) = this.initial_warps as u64;
        /// A warp-buffer slot is free for the controller.
        sig wb_free_valid (1) = this.wb_free_slot.is_some() as u64;
        /// That free slot.
        sig wb_free_slot (w.slot) = this.wb_free_slot.unwrap_or(0) as u64;
        /// Divergence report of a warp in its initial ray-stationary phase.
        sig init_valid (1) = this.init_report.is_some() as u64;
        /// Its warp-buffer slot.
        sig init_slot (w.slot) = this.init_report.map_or(0, |r| r.slot) as u64;
        /// Its active rays.
        sig init_active (w.lanes) = this.init_report.map_or(0, |r| r.active) as u64;
        /// Distinct treelets those rays need next.
        sig init_distinct (w.lanes) = this.init_report.map_or(0, |r| r.distinct) as u64;
        /// A ray reached a treelet boundary and must be enqueued.
        sig enq_valid (1) = this.enqueue.is_some() as u64;
        /// Its ray id.
        sig enq_ray (w.ray) = this.enqueue.map_or(0, |e| e.ray) as u64;
        /// The treelet it needs next.
        sig enq_treelet (w.treelet) = this.enqueue.map_or(0, |e| e.treelet) as u64;
        /// A warp finished its treelet or its traversal; its slot is free.
        sig warp_done_valid (1) = this.warp_done.is_some() as u64;
        /// Its warp-buffer slot.
        sig warp_done_slot (w.slot) = this.warp_done.unwrap_or(0) as u64;
        /// Active-ray report of a warp (for repacking, section 4.5).
        sig active_valid (1) = this.active_report.is_some() as u64;
        /// Its warp-buffer slot.
        sig active_slot (w.slot) = this.active_report.map_or(0, |r| r.slot) as u64;
        /// Its active rays.
        sig active_count (w.lanes) = this.active_report.map_or(0, |r| r.active) as u64;
        /// The treelet count table accepts any op this cycle (from its registers).
        sig ct_ready (1) = this.ct.ready as u64;
        /// The count table's max pointer is current and the table is not empty.
        sig ct_max_valid (1) = this.ct.max.is_some() as u64;
        /// The treelet with the largest queue.
        sig ct_max_treelet (w.treelet) = this.ct.max.map_or(0, |m| m.treelet) as u64;
        /// Rays in that queue, minus one.
        sig ct_max_count (w.count) = this.ct.max.map_or(0, |m| m.count.saturating_sub(1)) as u64;
        /// Valid count-table entries.
        sig ct_occupancy (w.count_entries) = this.ct.occupancy as u64;
        /// Count-table entries with at least underpopulation_threshold rays (judges underpopulation while the max pointer is stale).
        sig ct_above_threshold (w.count_entries) = this.ct.above_threshold as u64;
        /// The count table evicted an entry (previous cycle's answer).
        sig ct_evict_valid (1) = this.ct_evict.is_some() as u64;
        /// The evicted treelet.
        sig ct_evict_treelet (w.treelet) = this.ct_evict.unwrap_or(0) as u64;
        /// The treelet queue table accepts an op this cycle.
        sig qt_ready (1) = this.qt.ready as u64;
        /// The outstanding pop/pop_any/refill completed.
        sig qt_done (1) = this.qt_done.is_some() as u64;
        /// Rays in the popped entry (0: the queue was empty).
        sig qt_pop_count (w.lanes) = this.qt_done.as_ref().map_or(0, |p| p.rays.len()) as u64;
        /// Treelet of the popped entry.
        sig qt_pop_treelet (w.treelet) = this.qt_done.as_ref().map_or(0, |p| p.treelet) as u64;
        /// Ray ids of the popped entry; lane i in bits [i*ray_id_bits +: ray_id_bits] (traced as qt_pop_rays_<i>).
        lanes qt_pop_rays (w.ray, w.warp_size) = |i: usize| {
            this.qt_done.as_ref().and_then(|p| p.rays.get(i)).copied().unwrap_or(0) as u64
        };
        /// Free queue-table entries.
        sig qt_free_entries (w.queue_free) = this.qt.free_entries as u64;
        /// Rays spilled to memory and not yet refilled.
        sig qt_spilled (w.ray_total) = this.qt.spilled as u64;
        /// In mode done, start again from the reset state this cycle (a new wave of rays).
        sig restart (1) = this.restart as u64;
    }
}

impl ControllerInputs {
    /// Inputs with nothing happening: no events, tables not ready, nothing launched yet.
    pub fn idle(widths: ControllerWidths) -> Self {
        ControllerInputs {
            widths,
            launch_done: false,
            rt_idle: false,
            initial_warps: false,
            wb_free_slot: None,
            init_report: None,
            enqueue: None,
            warp_done: None,
            active_report: None,
            ct: CountTableStatus::default(),
            ct_evict: None,
            qt: QueueTableStatus::default(),
            qt_done: None,
            restart: false,
        }
    }

    /// Checks that every value fits its port and that slot indices, lane counts and ray counts
    /// are in range. The controller ignores events naming a slot that does not exist.
    pub fn validate(&self) -> Result<(), PortError> {
        let w = &self.widths;
        let check = |port: &str, value: u64, limit: u64| {
            if value <= limit {
                Ok(())
            } else {
                Err(PortError {
                    port: port.to_string(),
                    value,
                    limit,
                })
            }
        };
        let slot_max = w.warp_slots as u64 - 1;
        let lanes = w.warp_size as u64;
        if let Some(s) = self.wb_free_slot {
            check("wb_free_slot", s as u64, slot_max)?;
        }
        if let Some(r) = self.init_report {
            check("init_slot", r.slot as u64, slot_max)?;
            check("init_active", r.active as u64, lanes)?;
            check("init_distinct", r.distinct as u64, r.active as u64)?;
        }
        if let Some(s) = self.warp_done {
            check("warp_done_slot", s as u64, slot_max)?;
        }
        if let Some(r) = self.active_report {
            check("active_slot", r.slot as u64, slot_max)?;
            check("active_count", r.active as u64, lanes)?;
        }
        if let Some(m) = self.ct.max {
            // Counts travel as count - 1: 0 rays cannot be encoded, 2^count_bits is the largest.
            check("ct_max_count", m.count as u64, 1 << w.count)?;
            if m.count == 0 {
                return Err(PortError {
                    port: "ct_max_count".into(),
                    value: 0,
                    limit: 1 << w.count,
                });
            }
        }
        if let Some(p) = &self.qt_done {
            check("qt_pop_count", p.rays.len() as u64, lanes)?;
        }
        let ports = ControllerInputs::ports(w);
        for s in self.signals() {
            if !fits(s.value, s.width) {
                // Packed ports' signals carry a `_<lane>` suffix.
                let port = ports
                    .iter()
                    .map(|p| p.name.as_str())
                    .find(|p| {
                        s.name == *p
                            || s.name
                                .strip_prefix(p)
                                .and_then(|rest| rest.strip_prefix('_'))
                                .is_some_and(|lane| lane.bytes().all(|b| b.is_ascii_digit()))
                    })
                    .unwrap_or("unknown");
                return Err(PortError {
                    port: port.to_string(),
                    value: s.value,
                    limit: (1u64 << s.width) - 1,
                });
            }
        }
        Ok(())
    }
}

/// An input value is out of range for its port.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("treelet controller input {port} = {value} is out of range (at most {limit})")]
pub struct PortError {
    /// The port.
    pub port: String,
    /// The value driven on it.
    pub value: u64,
    /// The largest legal value.
    pub limit: u64,
}

crate::bundle! {
    /// The controller's output ports for one cycle.
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub struct ControllerOutputs (Out, w: ControllerWidths, this) {
        /// Current traversal mode.
        pub mode: Mode,
        /// The mode register (registers only): `mode` before this cycle's restart, what the
        /// wiring decides the restart from.
        pub mode_reg: Mode,
        /// The enqueue request is taken this cycle.
        pub enq_ready: bool,
        /// Terminate this initial-phase warp: its rays go to the treelet queues.
        pub terminate: Option<u32>,
        /// Warp-buffer slot owned by the controller this cycle.
        pub reserve: Option<u32>,
        /// Repack this warp: keep its active rays and slot until a fill with `last`.
        pub repack: Option<u32>,
        /// Rays for a warp-buffer slot.
        pub fill: Option<FillCommand>,
        /// Preload this treelet into L1 and prefetch its queued rays' records.
        pub preload: Option<u32>,
        /// Count-table op (the count table's own input type).
        pub ct_op: CountOp,
        /// Queue-table op (the queue table's own input type).
        pub qt_op: QueueOp,
        /// Resident treelets, oldest (the one being processed) first.
        pub resident: Vec<u32>,
        /// A treelet was made resident (claimed from the count table) this cycle.
        pub claim: bool,
        /// A repack is withheld for want of rays this cycle
        /// ([`TreeletController::repack_withheld`](super::TreeletController::repack_withheld)).
        pub repack_starved: bool,
    }
    ports {
        /// Traversal mode: 0 initial, 1 treelet stationary, 2 final ray stationary, 3 done.
        sig mode (Mode::BITS) = this.mode.encoding();
        /// The mode register (registers only): mode before this cycle's restart.
        sig mode_reg (Mode::BITS) = this.mode_reg.encoding();
        /// The enqueue request is taken this cycle.
        sig enq_ready (1) = this.enq_ready as u64;
        /// Terminate an initial-phase warp: its rays go to the treelet queues.
        sig terminate_valid (1) = this.terminate.is_some() as u64;
        /// Its warp-buffer slot.
        sig terminate_slot (w.slot) = this.terminate.unwrap_or(0) as u64;
        /// The controller owns a warp-buffer slot this cycle.
        sig reserve_valid (1) = this.reserve.is_some() as u64;
        /// That slot (not for SM warps; a repacked warp holds it until fill_last).
        sig reserve_slot (w.slot) = this.reserve.unwrap_or(0) as u64;
        /// Repack a warp: keep its active rays, refill its idle lanes.
        sig repack_valid (1) = this.repack.is_some() as u64;
        /// Its warp-buffer slot.
        sig repack_slot (w.slot) = this.repack.unwrap_or(0) as u64;
        /// Rays for a warp-buffer slot (ray records are fetched into its lanes).
        sig fill_valid (1) = this.fill.is_some() as u64;
        /// 0 treelet warp, 1 grouped ray-stationary warp, 2 repack.
        sig fill_kind (FillKind::BITS) = this.fill.as_ref().map_or(0, |f| f.kind as u64);
        /// The slot.
        sig fill_slot (w.slot) = this.fill.as_ref().map_or(0, |f| f.slot) as u64;
        /// Treelet of a treelet warp.
        sig fill_treelet (w.treelet) = this.fill.as_ref().map_or(0, |f| f.treelet) as u64;
        /// First rays of a new warp in the slot.
        sig fill_first (1) = this.fill.as_ref().is_some_and(|f| f.first) as u64;
        /// The slot is complete: start (or resume) the warp.
        sig fill_last (1) = this.fill.as_ref().is_some_and(|f| f.last) as u64;
        /// Rays in this fill.
        sig fill_count (w.lanes) = this.fill.as_ref().map_or(0, |f| f.rays.len()) as u64;
        /// Ray ids, appended into free lanes in order; lane i in bits [i*ray_id_bits +: ray_id_bits] (traced as fill_rays_<i>).
        lanes fill_rays (w.ray, w.warp_size) = |i: usize| {
            this.fill.as_ref().and_then(|f| f.rays.get(i)).copied().unwrap_or(0) as u64
        };
        /// Preload a treelet into L1 and prefetch its queued rays' records (section 4.3).
        sig preload_valid (1) = this.preload.is_some() as u64;
        /// The treelet.
        sig preload_treelet (w.treelet) = this.preload.unwrap_or(0) as u64;
        /// Count-table op: 0 nop, 1 add, 2 remove.
        sig ct_op (CountOp::BITS) = this.ct_op.kind_code();
        /// Its treelet.
        sig ct_treelet (w.treelet) = this.ct_op.fields().0;
        /// Its ray count (1..=warp_size).
        sig ct_n (w.lanes) = this.ct_op.fields().1 as u64;
        /// Queue-table op: 0 nop, 1 insert, 2 pop, 3 pop_any, 4 count (unused), 5 refill.
        sig qt_op (QueueOp::BITS) = this.qt_op.kind_code();
        /// Its treelet (insert, pop).
        sig qt_treelet (w.treelet) = this.qt_op.fields().0;
        /// Its ray id (insert).
        sig qt_ray (w.ray) = this.qt_op.fields().1 as u64;
        /// Bit i: resident treelet i is valid, oldest (current) first (traced as resident_valid_<i>).
        lanes resident_valid (1, w.resident_entries) = |i: usize| (i < this.resident.len()) as u64;
        /// Resident treelet addresses, oldest first (traced as resident_treelet_<i>).
        lanes resident_treelet (w.treelet, w.resident_entries) = |i: usize| {
            this.resident.get(i).copied().unwrap_or(0) as u64
        };
        /// A treelet is made resident (claimed from the count table) this cycle (an event for the statistics observer).
        sig claim (1) = this.claim as u64;
        /// A repack is withheld for want of rays: in the final ray-stationary phase the reported warp is below the repack threshold but the queues and the spare buffer are empty (an event for the statistics observer).
        sig repack_starved (1) = this.repack_starved as u64;
    }
}
