//! The treelet controller (paper sections 4.2-4.5, Figure 8): the state machine that decides
//! when warps leave the initial ray-stationary phase, which treelet queue is dispatched next,
//! when the next treelet is preloaded, when the RT unit falls back to ray-stationary traversal
//! of grouped underpopulated queues, and when a warp is repacked.
//!
//! It reads per-cycle summaries and events from the RT unit and the status of the treelet count
//! table and treelet queue table, and drives one operation per table per cycle plus commands to
//! the RT unit. Two FSMs: `mode` ([`Mode`]: initial / treelet stationary / final ray stationary /
//! done) and `seq` ([`Seq`]: the queue-table sequence in progress).
//!
//! ## Protocol (what the integrator must honour)
//! - Table ops fire in the cycle they are driven: the controller drives a count-table op only
//!   when `ct_ready` is high and a queue-table op only when `qt_ready` is high, and assumes the
//!   op is then accepted. So `qt_ready` and the count-table status (`ct_ready`, `ct_max_*`,
//!   `ct_occupancy`, `ct_above_threshold`) and `qt_free_entries`/`qt_spilled` must describe the
//!   tables' registers in *this* cycle (evaluate them with a `Nop` to peek: `eval` is pure).
//!   The count table only refuses an Add that misses a full table while its minimum is stale,
//!   so drive `ct_ready` with `!(occupancy == entries && !min.valid)` from its registers.
//! - The answers (`qt_done`, `qt_pop_*`, `ct_evict_*`) are the tables' outputs of the
//!   *previous* cycle: the queue table may finish an op in the cycle it is presented, and the
//!   controller only looks for `qt_done` from the cycle after it issued `Pop`/`PopAny`/`Refill`.
//!   Only one such request is outstanding. `qt_pop_count == 0` means the queue was empty.
//! - The count table mirrors the queue table: `Add{t, 1}` for every inserted ray and
//!   `Remove{t, n}` (n <= warp_size) for rays popped from a resident treelet's queue, never more
//!   than the controller knows the table holds for `t` (it tracks a resident treelet's count
//!   from the moment it claims it as the table's maximum). An empty pop of a resident queue (its
//!   rays are spilled) removes the whole remaining count, a warp's worth per cycle, so the table
//!   stops offering it; claims wait while such a remove is pending. Entries popped by `PopAny` may belong
//!   to treelets the table evicted, so they are not removed: after the treelet phase the count
//!   table is no longer consulted, and completion is judged on the controller's exact
//!   `queued_rays`. Counts on the `ct_max_count` wire are encoded `count - 1` (12 bits for 4096
//!   rays, [`HwConfig::count_bits`]); `ct_n` carries the op's true `n`.
//! - An enqueue request is taken when `enq_valid && enq_ready`. After `terminate` (or when a
//!   treelet warp ends) the RT unit sends one enqueue per ray, then `warp_done` for the slot.
//! - The treelet phase ends only when nothing can refill the queues: no resident treelet, no
//!   treelet warp or terminated warp still sending rays (`warp_done` not yet seen), no
//!   initial-phase warp in the warp buffer (`initial_warps`), no enqueue pending.
//! - `reserve_valid/slot` names a warp-buffer slot the controller owns this cycle: the RT unit
//!   must not give it to an SM warp and, for a repacked warp, must not report it done until a
//!   fill with `fill_last` arrives.
//! - Initial reports, active-ray reports and `warp_done` are never back-pressured; the
//!   controller acts on an active-ray report only when idle, so the RT unit repeats them.

use crate::bits::{bits_for, clog2, fits};
use crate::block::{Block, Signal, Signals};
use crate::config::{ConfigError, HwConfig};
use crate::describe::{port, reg, BlockDesc, Dir, FsmDesc};
use crate::mode::{
    drained, largest_queue_underpopulated, next_mode, queue_underpopulated, treelet_phase_over,
    warp_diverged, DrainStatus, Mode, ModeEvents, TreeletPhaseStatus,
};
use crate::warp_repacking::{lanes_to_refill, should_repack, split_refill};
use serde::Serialize;

/// Width of every statistics counter register.
pub const STAT_BITS: u32 = 48;

/// Feature switches that select the paper's design variants (section 6): naive queues,
/// grouping underpopulated queues, preloading. Warp repacking is switched by
/// [`HwConfig::repack_threshold`] (0 = off); it only acts in the final ray-stationary phase, so
/// it needs grouping.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct ControllerFeatures {
    /// Group underpopulated queues into ray-stationary warps (section 4.4). Off is the naive
    /// design: every queue, however small, is processed treelet-stationary, one warp per entry.
    pub group_underpopulated: bool,
    /// Preload the next treelet and its rays' records while the current one drains (section 4.3).
    pub preload: bool,
}

impl ControllerFeatures {
    /// The naive treelet queues of Figure 12: no grouping, preloading on.
    pub const NAIVE: ControllerFeatures = ControllerFeatures {
        group_underpopulated: false,
        preload: true,
    };
    /// The full design (grouping and preloading; repacking per the configuration).
    pub const FULL: ControllerFeatures = ControllerFeatures {
        group_underpopulated: true,
        preload: true,
    };
}

impl Default for ControllerFeatures {
    fn default() -> Self {
        ControllerFeatures::FULL
    }
}

/// Bit widths of the controller's fields, derived once from [`HwConfig`]; every port and
/// register bundle carries a copy so it can describe itself as signals.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct ControllerWidths {
    /// Threads (lanes) per warp.
    pub warp_size: u32,
    /// Slots in the RT unit's warp buffer.
    pub warp_slots: u32,
    /// Entries of the resident-treelet list.
    pub resident_entries: u32,
    /// Treelet address bits (19 by default).
    pub treelet: u32,
    /// Ray id bits (12 by default).
    pub ray: u32,
    /// Count-table count bits, encoded count - 1 (12 by default).
    pub count: u32,
    /// Bits of a lane index (5 for 32 lanes); also holds the spare-buffer fill (< warp_size).
    pub lane: u32,
    /// Bits of a number of lanes 0..=warp_size (6 for 32).
    pub lanes: u32,
    /// Bits of a warp-buffer slot index.
    pub slot: u32,
    /// Bits of a resident-list index.
    pub resident_index: u32,
    /// Bits of a ray total 0..=max_rays (13 for 4096).
    pub ray_total: u32,
    /// Bits of a number of warps 0..=warp_slots.
    pub warps: u32,
    /// Bits of the queue table's free-entry count 0..=queue_table_entries.
    pub queue_free: u32,
    /// Bits of a number of count-table entries 0..=count_table_entries.
    pub count_entries: u32,
}

impl ControllerWidths {
    /// The widths for a configuration.
    pub fn new(cfg: &HwConfig) -> Self {
        ControllerWidths {
            warp_size: cfg.warp_size,
            warp_slots: cfg.warp_buffer_size,
            resident_entries: cfg.max_resident_treelets,
            treelet: cfg.treelet_addr_bits(),
            ray: cfg.ray_id_bits(),
            count: cfg.count_bits(),
            lane: cfg.lane_bits(),
            lanes: bits_for(cfg.warp_size as u64),
            slot: clog2(cfg.warp_buffer_size as u64),
            resident_index: clog2(cfg.max_resident_treelets as u64),
            ray_total: bits_for(cfg.max_rays as u64),
            warps: bits_for(cfg.warp_buffer_size as u64),
            queue_free: bits_for(cfg.queue_table_entries as u64),
            count_entries: bits_for(cfg.count_table_entries as u64),
        }
    }
}

/// A count-table operation (one per cycle), as driven on `ct_op`/`ct_treelet`/`ct_n`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum CtOp {
    /// No operation (code 0).
    #[default]
    Nop,
    /// Add `rays` rays to `treelet`'s count (code 1).
    Add {
        /// Treelet address.
        treelet: u32,
        /// Rays added (1..=warp_size).
        rays: u32,
    },
    /// Remove `rays` rays from `treelet`'s count (code 2).
    Remove {
        /// Treelet address.
        treelet: u32,
        /// Rays removed (1..=warp_size).
        rays: u32,
    },
}

impl CtOp {
    /// Width of the op code.
    pub const BITS: u32 = 2;

    /// The op code on `ct_op`.
    pub fn code(&self) -> u64 {
        match self {
            CtOp::Nop => 0,
            CtOp::Add { .. } => 1,
            CtOp::Remove { .. } => 2,
        }
    }

    /// `(treelet, n)` as driven on the wires (zeros for `Nop`).
    fn wire_fields(&self) -> (u64, u64) {
        match *self {
            CtOp::Nop => (0, 0),
            CtOp::Add { treelet, rays } | CtOp::Remove { treelet, rays } => {
                (treelet as u64, rays as u64)
            }
        }
    }
}

/// A queue-table operation (one per cycle), as driven on `qt_op`/`qt_treelet`/`qt_ray`.
/// Code 4 is the table's `Count{treelet}` query, which the controller never issues.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum QtOp {
    /// No operation (code 0).
    #[default]
    Nop,
    /// Append `ray` to `treelet`'s queue (code 1).
    Insert {
        /// Treelet address.
        treelet: u32,
        /// Ray id.
        ray: u32,
    },
    /// Pop one entry (up to a warp of rays) of `treelet`'s queue (code 2).
    Pop {
        /// Treelet address.
        treelet: u32,
    },
    /// Pop the first entry of any queue, in table order (code 3).
    PopAny,
    /// Bring spilled entries back from memory into free table entries (code 5).
    Refill,
}

impl QtOp {
    /// Width of the op code.
    pub const BITS: u32 = 3;

    /// The op code on `qt_op`.
    pub fn code(&self) -> u64 {
        match self {
            QtOp::Nop => 0,
            QtOp::Insert { .. } => 1,
            QtOp::Pop { .. } => 2,
            QtOp::PopAny => 3,
            QtOp::Refill => 5,
        }
    }

    /// `(treelet, ray)` as driven on the wires (zeros where unused).
    fn wire_fields(&self) -> (u64, u64) {
        match *self {
            QtOp::Insert { treelet, ray } => (treelet as u64, ray as u64),
            QtOp::Pop { treelet } => (treelet as u64, 0),
            QtOp::Nop | QtOp::PopAny | QtOp::Refill => (0, 0),
        }
    }
}

/// What a fill sequence is building in its warp-buffer slot (`fill_kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum FillKind {
    /// A treelet warp: one queue entry of the treelet being processed (code 0).
    #[default]
    Treelet = 0,
    /// A ray-stationary warp grouped from underpopulated queues (code 1).
    Grouped = 1,
    /// Idle lanes of a repacked warp (code 2).
    Repack = 2,
}

impl FillKind {
    /// Width of the kind code.
    pub const BITS: u32 = 2;
}

/// The queue-table sequencer FSM (`seq`; the discriminant is the state encoding).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum Seq {
    /// No sequence: the controller may claim, dispatch, start a fill, enqueue or refill.
    #[default]
    Idle = 0,
    /// A `Pop`/`PopAny` is outstanding; waiting for `qt_done`.
    PopWait = 1,
    /// Filling a slot in the final phase: give spare rays or pop another entry.
    FillNext = 2,
    /// A `Refill` is outstanding; waiting for `qt_done`.
    RefillWait = 3,
}

impl Seq {
    /// Every state in encoding order.
    pub const ALL: [Seq; 4] = [Seq::Idle, Seq::PopWait, Seq::FillNext, Seq::RefillWait];
    /// Width of the state register.
    pub const BITS: u32 = 2;

    /// The state name used in block descriptions.
    pub fn name(self) -> &'static str {
        match self {
            Seq::Idle => "idle",
            Seq::PopWait => "pop_wait",
            Seq::FillNext => "fill_next",
            Seq::RefillWait => "refill_wait",
        }
    }
}

/// "Warp `slot`, still in its initial phase, has `active` active rays needing `distinct`
/// distinct treelets next."
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct InitReport {
    /// Warp-buffer slot.
    pub slot: u32,
    /// Active rays (0..=warp_size).
    pub active: u32,
    /// Distinct treelets those rays need next (0..=active).
    pub distinct: u32,
}

/// "Ray `ray` reached a treelet boundary and needs treelet `treelet` next": enqueue it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct EnqueueRequest {
    /// Ray id.
    pub ray: u32,
    /// Treelet address the ray needs next.
    pub treelet: u32,
}

/// "Warp `slot` has `active` active rays" (for repacking).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct ActiveReport {
    /// Warp-buffer slot.
    pub slot: u32,
    /// Active rays (0..=warp_size).
    pub active: u32,
}

/// A treelet and its queued ray count, as reported by the count table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct CountEntry {
    /// Treelet address.
    pub treelet: u32,
    /// Rays queued (1..=max_rays; on the wire as count - 1).
    pub count: u32,
}

/// Status of the treelet count table this cycle.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize)]
pub struct CountTableStatus {
    /// The table accepts an op this cycle.
    pub ready: bool,
    /// The largest tracked treelet queue, if the table's max pointer is current (it is stale
    /// while the table rescans after the largest entry shrank, and absent when empty).
    pub max: Option<CountEntry>,
    /// Valid table entries.
    pub occupancy: u32,
    /// Entries holding at least `underpopulation_threshold` rays.
    pub above_threshold: u32,
    /// Treelet the table evicted last cycle (its rays go ray-stationary later).
    pub evict: Option<u32>,
}

/// The answer to a `Pop`/`PopAny` (the popped entry).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize)]
pub struct PopResult {
    /// Treelet address of the popped entry.
    pub treelet: u32,
    /// Ray ids of the entry (at most warp_size; empty when the queue was empty).
    pub rays: Vec<u32>,
}

/// Status of the treelet queue table this cycle.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize)]
pub struct QueueTableStatus {
    /// The table accepts an op this cycle.
    pub ready: bool,
    /// The outstanding `Pop`/`PopAny`/`Refill` completed this cycle (with the popped entry;
    /// empty for `Refill`).
    pub done: Option<PopResult>,
    /// Free table entries.
    pub free_entries: u32,
    /// Rays spilled to memory and not yet refilled.
    pub spilled: u32,
}

/// The controller's input ports for one cycle.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ControllerInputs {
    /// Widths of the fields (for [`Signals`]).
    pub widths: ControllerWidths,
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
    /// Count-table status.
    pub ct: CountTableStatus,
    /// Queue-table status.
    pub qt: QueueTableStatus,
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
            qt: QueueTableStatus::default(),
        }
    }

    /// Checks that every value fits its port and that slot indices, lane counts and ray counts
    /// are in range. The controller ignores events naming a slot that does not exist.
    pub fn validate(&self) -> Result<(), PortError> {
        let w = &self.widths;
        let check = |port: &'static str, value: u64, limit: u64| {
            if value <= limit {
                Ok(())
            } else {
                Err(PortError { port, value, limit })
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
                    port: "ct_max_count",
                    value: 0,
                    limit: 1 << w.count,
                });
            }
        }
        if let Some(p) = &self.qt.done {
            check("qt_pop_count", p.rays.len() as u64, lanes)?;
        }
        for s in self.signals() {
            if !fits(s.value, s.width) {
                return Err(PortError {
                    port: port_name(&s.name),
                    value: s.value,
                    limit: (1u64 << s.width) - 1,
                });
            }
        }
        Ok(())
    }
}

/// The static port name for a signal name (signals of packed ports carry a `_<lane>` suffix).
fn port_name(signal: &str) -> &'static str {
    INPUT_PORT_NAMES
        .iter()
        .copied()
        .find(|p| {
            signal == *p
                || signal
                    .strip_prefix(p)
                    .and_then(|rest| rest.strip_prefix('_'))
                    .is_some_and(|lane| lane.bytes().all(|b| b.is_ascii_digit()))
        })
        .unwrap_or("unknown")
}

/// Every input port name, in [`Signals`] order.
const INPUT_PORT_NAMES: [&str; 32] = [
    "launch_done",
    "rt_idle",
    "initial_warps",
    "wb_free_valid",
    "wb_free_slot",
    "init_valid",
    "init_slot",
    "init_active",
    "init_distinct",
    "enq_valid",
    "enq_ray",
    "enq_treelet",
    "warp_done_valid",
    "warp_done_slot",
    "active_valid",
    "active_slot",
    "active_count",
    "ct_ready",
    "ct_max_valid",
    "ct_max_treelet",
    "ct_max_count",
    "ct_occupancy",
    "ct_above_threshold",
    "ct_evict_valid",
    "ct_evict_treelet",
    "qt_ready",
    "qt_done",
    "qt_pop_count",
    "qt_pop_treelet",
    "qt_pop_rays",
    "qt_free_entries",
    "qt_spilled",
];

/// An input value is out of range for its port.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("treelet controller input {port} = {value} is out of range (at most {limit})")]
pub struct PortError {
    /// The port.
    pub port: &'static str,
    /// The value driven on it.
    pub value: u64,
    /// The largest legal value.
    pub limit: u64,
}

/// Rays given to a warp-buffer slot this cycle (`fill_*`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct FillCommand {
    /// What is being built in the slot.
    pub kind: FillKind,
    /// Warp-buffer slot.
    pub slot: u32,
    /// Treelet of a treelet warp (0 for ray-stationary fills).
    pub treelet: u32,
    /// First rays of a new warp in this slot (never set for a repack).
    pub first: bool,
    /// The slot is complete: the warp may start (or resume, after a repack).
    pub last: bool,
    /// Ray ids appended into the slot's free lanes (at most warp_size; may be empty with `last`).
    pub rays: Vec<u32>,
}

/// The controller's output ports for one cycle.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ControllerOutputs {
    /// Widths of the fields (for [`Signals`]).
    pub widths: ControllerWidths,
    /// Current traversal mode.
    pub mode: Mode,
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
    /// Count-table op.
    pub ct_op: CtOp,
    /// Queue-table op.
    pub qt_op: QtOp,
    /// Resident treelets, oldest (the one being processed) first.
    pub resident: Vec<u32>,
}

/// One entry of the resident-treelet list.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct ResidentEntry {
    /// The entry holds a treelet.
    pub valid: bool,
    /// Treelet address.
    pub treelet: u32,
    /// Rays waiting in its queue as the count table counts them: the table's maximum when it
    /// was claimed, plus later enqueues, minus pops; 0 once the table evicted it.
    pub count: u32,
    /// Its treelet warps still traversing.
    pub warps: u32,
}

/// What the controller knows about one warp-buffer slot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct SlotState {
    /// The slot holds an initial-phase warp the controller terminated, still sending its rays
    /// to the queues (until its `warp_done`).
    pub terminated: bool,
    /// The slot holds a treelet warp the controller dispatched.
    pub treelet_warp: bool,
    /// The resident entry that warp belongs to (`None` for a naive untracked-queue warp).
    pub resident: Option<u32>,
}

/// The fill sequence in progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct FillState {
    /// What is being built.
    pub kind: FillKind,
    /// Target warp-buffer slot.
    pub slot: u32,
    /// Resident entry popped from (treelet warps of a resident treelet).
    pub resident: Option<u32>,
    /// Lanes still to fill.
    pub need: u32,
    /// Rays were already given to the slot (or it is a repack, opened by the repack command).
    pub started: bool,
}

/// Per-mode statistics counters (all [`STAT_BITS`] wide, saturating).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct ControllerStats {
    /// Cycles spent in the initial phase.
    pub cycles_initial: u64,
    /// Cycles spent treelet-stationary.
    pub cycles_treelet: u64,
    /// Cycles spent in the final ray-stationary phase.
    pub cycles_final: u64,
    /// Initial-phase warps terminated into the queues.
    pub terminated_warps: u64,
    /// Active rays of those warps.
    pub terminated_rays: u64,
    /// Rays inserted into the queues.
    pub enqueued_rays: u64,
    /// Treelets claimed from the count table (made resident).
    pub claims: u64,
    /// Preloads issued.
    pub preloads: u64,
    /// Treelet warps dispatched.
    pub treelet_warps: u64,
    /// Ray-stationary warps grouped from underpopulated queues.
    pub grouped_warps: u64,
    /// Warps repacked.
    pub repacks: u64,
    /// Count-table evictions seen.
    pub evictions: u64,
}

impl ControllerStats {
    fn fields(&self) -> [(&'static str, u64); 12] {
        [
            ("stat_cycles_initial", self.cycles_initial),
            ("stat_cycles_treelet", self.cycles_treelet),
            ("stat_cycles_final", self.cycles_final),
            ("stat_terminated_warps", self.terminated_warps),
            ("stat_terminated_rays", self.terminated_rays),
            ("stat_enqueued_rays", self.enqueued_rays),
            ("stat_claims", self.claims),
            ("stat_preloads", self.preloads),
            ("stat_treelet_warps", self.treelet_warps),
            ("stat_grouped_warps", self.grouped_warps),
            ("stat_repacks", self.repacks),
            ("stat_evictions", self.evictions),
        ]
    }
}

/// Saturating increment of a statistics counter.
fn bump(counter: &mut u64, by: u64) {
    *counter = counter.saturating_add(by).min((1u64 << STAT_BITS) - 1);
}

/// Every register of the controller.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ControllerRegs {
    /// Widths of the fields (for [`Signals`]).
    pub widths: ControllerWidths,
    /// Traversal mode FSM.
    pub mode: Mode,
    /// Queue-table sequencer FSM.
    pub seq: Seq,
    /// Rays in the queue table (exact: +1 per insert, -n per pop).
    pub queued_rays: u32,
    /// Resident-treelet list, a circular buffer allocated at `res_tail`.
    pub res: Vec<ResidentEntry>,
    /// Oldest valid resident entry (the current treelet).
    pub res_head: u32,
    /// Next entry to allocate.
    pub res_tail: u32,
    /// Per warp-buffer slot bookkeeping.
    pub slots: Vec<SlotState>,
    /// Fill sequence in progress (meaningful outside `Seq::Idle`).
    pub fill: FillState,
    /// Spare buffer: rays popped in the final phase that did not fit the warp being filled
    /// (fixed bank of warp_size - 1 ids; the first `spare_count` are valid).
    pub spare_rays: Vec<u32>,
    /// Valid spare rays.
    pub spare_count: u32,
    /// A count-table `Remove` still to issue for a popped untracked entry: (treelet, rays).
    pub pending_remove: Option<(u32, u32)>,
    /// Statistics counters.
    pub stats: ControllerStats,
}

impl ControllerRegs {
    /// Resident entry indices in age order (oldest first).
    fn resident_order(&self) -> impl Iterator<Item = usize> + '_ {
        let n = self.res.len();
        (0..n)
            .map(move |k| (self.res_head as usize + k) % n)
            .filter(move |&i| self.res[i].valid)
    }

    /// Number of valid resident entries.
    fn resident_count(&self) -> u32 {
        self.res.iter().filter(|e| e.valid).count() as u32
    }

    /// The resident entry holding `treelet`, if any.
    fn resident_of(&self, treelet: u32) -> Option<usize> {
        self.res
            .iter()
            .position(|e| e.valid && e.treelet == treelet)
    }
}

/// The treelet controller block.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TreeletController {
    cfg: HwConfig,
    features: ControllerFeatures,
    widths: ControllerWidths,
}

impl TreeletController {
    /// A controller for a configuration and a set of features; the configuration is validated.
    pub fn new(cfg: HwConfig, features: ControllerFeatures) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let widths = ControllerWidths::new(&cfg);
        Ok(TreeletController {
            cfg,
            features,
            widths,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &HwConfig {
        &self.cfg
    }

    /// The feature switches.
    pub fn features(&self) -> ControllerFeatures {
        self.features
    }

    /// The field widths.
    pub fn widths(&self) -> ControllerWidths {
        self.widths
    }

    /// Inputs with nothing happening this cycle.
    pub fn idle_inputs(&self) -> ControllerInputs {
        ControllerInputs::idle(self.widths)
    }

    /// Whether the oldest resident treelet's queue has fallen under the preload threshold
    /// (section 4.3: fewer than `preload_threshold_warps` warps of rays left).
    fn current_queue_low(&self, regs: &ControllerRegs) -> bool {
        let limit = self.cfg.preload_threshold_warps as u64 * self.cfg.warp_size as u64;
        regs.resident_order()
            .next()
            .is_none_or(|i| (regs.res[i].count as u64) < limit)
    }

    /// The count table's largest queue, if it may be claimed (made resident) this cycle: the
    /// table is not being updated by a pending remove, the treelet is not resident yet, it is not underpopulated (unless the design is naive), a resident entry
    /// is free, and either nothing is resident or preloading is on and the current queue is low.
    fn claimable(&self, regs: &ControllerRegs, inputs: &ControllerInputs) -> Option<CountEntry> {
        let max = inputs.ct.max?;
        let tail = regs.res_tail as usize;
        let ok = regs.mode == Mode::TreeletStationary
            && regs.pending_remove.is_none()
            && !regs.res[tail].valid
            && regs.resident_of(max.treelet).is_none()
            && (!self.features.group_underpopulated
                || !queue_underpopulated(max.count, self.cfg.underpopulation_threshold))
            && (regs.resident_count() == 0
                || (self.features.preload && self.current_queue_low(regs)));
        ok.then_some(max)
    }

    /// The sequencer's actions in `Seq::Idle`, in priority order; at most one per cycle.
    fn idle_step(
        &self,
        regs: &ControllerRegs,
        inputs: &ControllerInputs,
        ct_port_free: bool,
        n: &mut ControllerRegs,
        out: &mut ControllerOutputs,
    ) {
        let free_slot = inputs.wb_free_slot.filter(|&s| s < self.widths.warp_slots);
        let ts = regs.mode == Mode::TreeletStationary;
        let frs = regs.mode == Mode::FinalRayStationary;
        let rays_waiting = regs.queued_rays > 0 || regs.spare_count > 0;

        // 1. Bring a spilled ray back while the table has room, so pops find every ray.
        if inputs.qt.ready && inputs.qt.spilled > 0 && inputs.qt.free_entries > 0 {
            out.qt_op = QtOp::Refill;
            n.seq = Seq::RefillWait;
            return;
        }

        // 2. Dispatch a treelet warp: the oldest resident with queued rays, or (naive design)
        //    any entry once the count table tracks nothing.
        if ts && inputs.qt.ready {
            if let Some(slot) = free_slot {
                let resident = regs.resident_order().find(|&i| regs.res[i].count > 0);
                let naive_untracked = !self.features.group_underpopulated
                    && regs.resident_count() == 0
                    && inputs.ct.occupancy == 0
                    && regs.queued_rays > 0;
                if resident.is_some() || naive_untracked {
                    out.qt_op = match resident {
                        Some(i) => QtOp::Pop {
                            treelet: regs.res[i].treelet,
                        },
                        None => QtOp::PopAny,
                    };
                    out.reserve = Some(slot);
                    n.seq = Seq::PopWait;
                    n.fill = FillState {
                        kind: FillKind::Treelet,
                        slot,
                        resident: resident.map(|i| i as u32),
                        need: self.cfg.warp_size,
                        started: false,
                    };
                    return;
                }
            }
        }

        // 3. Claim the largest queue: it becomes current, or is preloaded behind the current one.
        if let Some(max) = self.claimable(regs, inputs) {
            let first = regs.resident_count() == 0;
            let tail = regs.res_tail as usize;
            n.res[tail] = ResidentEntry {
                valid: true,
                treelet: max.treelet,
                count: max.count,
                warps: 0,
            };
            n.res_tail = ((tail + 1) % n.res.len()) as u32;
            bump(&mut n.stats.claims, 1);
            if !first {
                out.preload = Some(max.treelet);
                bump(&mut n.stats.preloads, 1);
            }
            return;
        }

        // 4. Final phase: group underpopulated queues into a free slot, or repack a warp.
        if frs && rays_waiting {
            if let Some(slot) = free_slot {
                out.reserve = Some(slot);
                n.seq = Seq::FillNext;
                n.fill = FillState {
                    kind: FillKind::Grouped,
                    slot,
                    resident: None,
                    need: self.cfg.warp_size,
                    started: false,
                };
                return;
            }
            if let Some(r) = inputs.active_report {
                if r.slot < self.widths.warp_slots
                    && should_repack(regs.mode, r.active, self.cfg.repack_threshold, rays_waiting)
                {
                    out.repack = Some(r.slot);
                    out.reserve = Some(r.slot);
                    n.seq = Seq::FillNext;
                    n.fill = FillState {
                        kind: FillKind::Repack,
                        slot: r.slot,
                        resident: None,
                        need: lanes_to_refill(r.active, self.cfg.warp_size),
                        started: true,
                    };
                    bump(&mut n.stats.repacks, 1);
                    return;
                }
            }
        }

        // 5. Enqueue a ray at a treelet boundary: insert it and count it (a resident treelet's
        //    count is mirrored here).
        if let Some(e) = inputs.enqueue {
            if regs.mode != Mode::Done && inputs.qt.ready && ct_port_free {
                out.enq_ready = true;
                out.qt_op = QtOp::Insert {
                    treelet: e.treelet,
                    ray: e.ray,
                };
                out.ct_op = CtOp::Add {
                    treelet: e.treelet,
                    rays: 1,
                };
                if let Some(i) = regs.resident_of(e.treelet) {
                    n.res[i].count = (n.res[i].count + 1).min(self.cfg.max_rays);
                }
                n.queued_rays = (n.queued_rays + 1).min(self.cfg.max_rays);
                bump(&mut n.stats.enqueued_rays, 1);
            }
        }
    }

    /// `Seq::PopWait`: the popped entry arrived; hand it to the slot being filled.
    fn pop_done(
        &self,
        regs: &ControllerRegs,
        pop: &PopResult,
        n: &mut ControllerRegs,
        out: &mut ControllerOutputs,
    ) {
        let f = regs.fill;
        let popped = (pop.rays.len() as u32).min(self.cfg.warp_size);
        let rays = &pop.rays[..popped as usize];
        n.queued_rays = regs.queued_rays.saturating_sub(popped);
        out.reserve = Some(f.slot);
        if f.kind == FillKind::Treelet {
            n.seq = Seq::Idle;
            let treelet = match f.resident {
                Some(i) => {
                    // Keep the count table in step; an empty pop means the rest of the queue
                    // is spilled, so its whole count leaves the table (found again by PopAny).
                    let e = &mut n.res[i as usize];
                    let removed = if popped == 0 {
                        e.count
                    } else {
                        popped.min(e.count)
                    };
                    e.count -= removed;
                    if removed > 0 {
                        n.pending_remove = Some((e.treelet, removed));
                    }
                    e.treelet
                }
                None => pop.treelet,
            };
            if popped == 0 {
                return;
            }
            if let Some(i) = f.resident {
                n.res[i as usize].warps += 1;
            }
            n.slots[f.slot as usize] = SlotState {
                terminated: false,
                treelet_warp: true,
                resident: f.resident,
            };
            bump(&mut n.stats.treelet_warps, 1);
            out.fill = Some(FillCommand {
                kind: FillKind::Treelet,
                slot: f.slot,
                treelet,
                first: true,
                last: true,
                rays: rays.to_vec(),
            });
            return;
        }

        // Grouped warp or repack: take what fits, keep the rest in the spare buffer.
        let (take, left) = split_refill(f.need, popped);
        n.spare_rays[..left as usize].copy_from_slice(&rays[take as usize..]);
        n.spare_rays[left as usize..].fill(0);
        n.spare_count = left;
        let need = f.need - take;
        let last = need == 0 || (left == 0 && n.queued_rays == 0);
        self.emit_fill(&f, &rays[..take as usize], last, n, out);
        n.fill.need = need;
        n.seq = if last { Seq::Idle } else { Seq::FillNext };
    }

    /// Gives `rays` to the slot of fill sequence `f` (for grouped warps and repacks).
    fn emit_fill(
        &self,
        f: &FillState,
        rays: &[u32],
        last: bool,
        n: &mut ControllerRegs,
        out: &mut ControllerOutputs,
    ) {
        if rays.is_empty() && !(f.started && last) {
            return; // nothing to give and nothing to close
        }
        if f.kind == FillKind::Grouped && !f.started {
            bump(&mut n.stats.grouped_warps, 1);
            n.slots[f.slot as usize] = SlotState::default();
        }
        out.fill = Some(FillCommand {
            kind: f.kind,
            slot: f.slot,
            treelet: 0,
            first: f.kind == FillKind::Grouped && !f.started,
            last,
            rays: rays.to_vec(),
        });
        n.fill.started = true;
    }

    /// `Seq::FillNext`: give spare rays, pop another entry, or close the slot.
    fn fill_next(
        &self,
        regs: &ControllerRegs,
        inputs: &ControllerInputs,
        n: &mut ControllerRegs,
        out: &mut ControllerOutputs,
    ) {
        let f = regs.fill;
        out.reserve = Some(f.slot);
        if regs.spare_count > 0 {
            let (take, left) = split_refill(f.need, regs.spare_count);
            let (given, kept) = regs.spare_rays.split_at(take as usize);
            n.spare_rays[..left as usize].copy_from_slice(&kept[..left as usize]);
            n.spare_rays[left as usize..].fill(0);
            n.spare_count = left;
            let need = f.need - take;
            let last = need == 0 || (left == 0 && regs.queued_rays == 0);
            self.emit_fill(&f, given, last, n, out);
            n.fill.need = need;
            if last {
                n.seq = Seq::Idle;
            }
        } else if regs.queued_rays == 0 {
            self.emit_fill(&f, &[], true, n, out);
            n.seq = Seq::Idle;
        } else if inputs.qt.ready && inputs.qt.spilled > 0 && inputs.qt.free_entries > 0 {
            // Spilled rays first, as in `Seq::Idle`: without this a table emptied by pops
            // answers every PopAny with nothing while its rays wait in memory. The sequence
            // stays here; the next op waits for `qt_ready` (the refill's answer is ignored).
            out.qt_op = QtOp::Refill;
        } else if inputs.qt.ready {
            out.qt_op = QtOp::PopAny;
            n.seq = Seq::PopWait;
        }
    }
}

impl Block for TreeletController {
    type Inputs = ControllerInputs;
    type Outputs = ControllerOutputs;
    type Regs = ControllerRegs;

    fn reset(&self) -> ControllerRegs {
        ControllerRegs {
            widths: self.widths,
            mode: Mode::Initial,
            seq: Seq::Idle,
            queued_rays: 0,
            res: vec![ResidentEntry::default(); self.cfg.max_resident_treelets as usize],
            res_head: 0,
            res_tail: 0,
            slots: vec![SlotState::default(); self.cfg.warp_buffer_size as usize],
            fill: FillState::default(),
            spare_rays: vec![0; self.cfg.warp_size as usize - 1],
            spare_count: 0,
            pending_remove: None,
            stats: ControllerStats::default(),
        }
    }

    fn eval(
        &self,
        regs: &ControllerRegs,
        inputs: &ControllerInputs,
    ) -> (ControllerOutputs, ControllerRegs) {
        let mut n = regs.clone();
        let mut out = ControllerOutputs {
            widths: self.widths,
            mode: regs.mode,
            enq_ready: false,
            terminate: None,
            reserve: None,
            repack: None,
            fill: None,
            preload: None,
            ct_op: CtOp::Nop,
            qt_op: QtOp::Nop,
            resident: regs.resident_order().map(|i| regs.res[i].treelet).collect(),
        };
        let slots = self.widths.warp_slots;

        match regs.mode {
            Mode::Initial => bump(&mut n.stats.cycles_initial, 1),
            Mode::TreeletStationary => bump(&mut n.stats.cycles_treelet, 1),
            Mode::FinalRayStationary => bump(&mut n.stats.cycles_final, 1),
            Mode::Done => {}
        }
        // An evicted resident treelet is no longer counted by the table: stop mirroring it (its
        // remaining rays are grouped ray-stationary later, section 6.5).
        if let Some(t) = inputs.ct.evict {
            bump(&mut n.stats.evictions, 1);
            if let Some(i) = regs.resident_of(t) {
                n.res[i].count = 0;
            }
        }

        // A finished warp frees its slot; a treelet warp releases its resident treelet.
        if let Some(s) = inputs.warp_done.filter(|&s| s < slots) {
            let st = regs.slots[s as usize];
            if let Some(i) = st.resident.filter(|_| st.treelet_warp) {
                let e = &mut n.res[i as usize];
                e.warps = e.warps.saturating_sub(1);
            }
            n.slots[s as usize] = SlotState::default();
        }

        // Initial-phase warps that diverged are terminated into the queues (section 3.2 ❶).
        let divergent = inputs.init_report.filter(|r| {
            r.slot < slots
                && regs.mode.terminates_divergent_warps()
                && warp_diverged(r.distinct, self.cfg.divergence_threshold)
        });
        if let Some(r) = divergent {
            out.terminate = Some(r.slot);
            n.slots[r.slot as usize].terminated = true;
            bump(&mut n.stats.terminated_warps, 1);
            bump(&mut n.stats.terminated_rays, r.active as u64);
        }

        // A pending count-table Remove has the count-table port first, a warp of rays at a time.
        let mut ct_port_free = inputs.ct.ready;
        if let Some((treelet, rays)) = regs.pending_remove {
            if inputs.ct.ready {
                let chunk = rays.min(self.cfg.warp_size);
                out.ct_op = CtOp::Remove {
                    treelet,
                    rays: chunk,
                };
                n.pending_remove = (rays > chunk).then_some((treelet, rays - chunk));
            }
            ct_port_free = false;
        }

        match regs.seq {
            Seq::Idle => self.idle_step(regs, inputs, ct_port_free, &mut n, &mut out),
            Seq::PopWait => {
                out.reserve = Some(regs.fill.slot);
                if let Some(pop) = &inputs.qt.done {
                    self.pop_done(regs, pop, &mut n, &mut out);
                }
            }
            Seq::FillNext => self.fill_next(regs, inputs, &mut n, &mut out),
            Seq::RefillWait => {
                if inputs.qt.done.is_some() {
                    n.seq = Seq::Idle;
                }
            }
        }

        // Retire resident treelets whose queue is empty and whose warps have all finished.
        let popping = (n.seq == Seq::PopWait).then_some(n.fill.resident).flatten();
        for (i, e) in n.res.iter_mut().enumerate() {
            if e.valid && e.count == 0 && e.warps == 0 && popping != Some(i as u32) {
                *e = ResidentEntry::default();
            }
        }
        if n.resident_count() == 0 {
            n.res_head = n.res_tail;
        } else {
            while !n.res[n.res_head as usize].valid {
                n.res_head = (n.res_head + 1) % n.res.len() as u32;
            }
        }

        // Mode transitions, judged on this cycle's registers and inputs.
        let enqueue_pending = inputs.enqueue.is_some();
        let feeding = regs
            .slots
            .iter()
            .filter(|s| s.treelet_warp || s.terminated)
            .count() as u32;
        let settled = regs.seq == Seq::Idle && regs.pending_remove.is_none();
        let phase_over = regs.mode == Mode::TreeletStationary
            && settled
            && treelet_phase_over(
                &TreeletPhaseStatus {
                    largest_underpopulated: largest_queue_underpopulated(
                        inputs.ct.max.map(|m| m.count),
                        inputs.ct.occupancy,
                        inputs.ct.above_threshold,
                        self.cfg.underpopulation_threshold,
                    ),
                    resident_treelets: regs.resident_count(),
                    warps_feeding_queues: feeding,
                    initial_warps: inputs.initial_warps,
                    enqueue_pending,
                },
                self.features.group_underpopulated,
            );
        let all_drained = drained(&DrainStatus {
            launch_done: inputs.launch_done,
            rt_idle: inputs.rt_idle,
            queued_rays: regs.queued_rays,
            held_rays: regs.spare_count,
            resident_treelets: regs.resident_count(),
            sequence_busy: !settled,
            enqueue_pending,
        });
        n.mode = next_mode(
            regs.mode,
            &ModeEvents {
                divergent_warp: divergent.is_some(),
                treelet_phase_over: phase_over,
                drained: all_drained,
            },
        );
        (out, n)
    }
    fn describe(&self) -> BlockDesc {
        describe_controller(&self.cfg, self.features, &self.widths)
    }
}

/// The controller's [`BlockDesc`].
fn describe_controller(
    cfg: &HwConfig,
    features: ControllerFeatures,
    w: &ControllerWidths,
) -> BlockDesc {
    use Dir::{In, Out};
    let wr = w.warp_size * w.ray;
    let ports = vec![
        port("launch_done", In, 1, "The SM will send no more warps to the RT unit."),
        port("rt_idle", In, 1, "The RT unit's warp buffer is empty and no events are pending."),
        port(
            "initial_warps",
            In,
            1,
            "The warp buffer holds warps still in their initial phase (they may yet fill the queues).",
        ),
        port("wb_free_valid", In, 1, "A warp-buffer slot is free for the controller."),
        port("wb_free_slot", In, w.slot, "That free slot."),
        port("init_valid", In, 1, "Divergence report of a warp in its initial ray-stationary phase."),
        port("init_slot", In, w.slot, "Its warp-buffer slot."),
        port("init_active", In, w.lanes, "Its active rays."),
        port("init_distinct", In, w.lanes, "Distinct treelets those rays need next."),
        port("enq_valid", In, 1, "A ray reached a treelet boundary and must be enqueued."),
        port("enq_ray", In, w.ray, "Its ray id."),
        port("enq_treelet", In, w.treelet, "The treelet it needs next."),
        port("warp_done_valid", In, 1, "A warp finished its treelet or its traversal; its slot is free."),
        port("warp_done_slot", In, w.slot, "Its warp-buffer slot."),
        port("active_valid", In, 1, "Active-ray report of a warp (for repacking, section 4.5)."),
        port("active_slot", In, w.slot, "Its warp-buffer slot."),
        port("active_count", In, w.lanes, "Its active rays."),
        port("ct_ready", In, 1, "The treelet count table accepts an op this cycle."),
        port("ct_max_valid", In, 1, "The count table's max pointer is current and the table is not empty."),
        port("ct_max_treelet", In, w.treelet, "The treelet with the largest queue."),
        port("ct_max_count", In, w.count, "Rays in that queue, minus one."),
        port("ct_occupancy", In, w.count_entries, "Valid count-table entries."),
        port("ct_above_threshold", In, w.count_entries, "Count-table entries with at least underpopulation_threshold rays (judges underpopulation while the max pointer is stale)."),
        port("ct_evict_valid", In, 1, "The count table evicted an entry (previous cycle's answer)."),
        port("ct_evict_treelet", In, w.treelet, "The evicted treelet."),
        port("qt_ready", In, 1, "The treelet queue table accepts an op this cycle."),
        port("qt_done", In, 1, "The outstanding pop/pop_any/refill completed."),
        port("qt_pop_count", In, w.lanes, "Rays in the popped entry (0: the queue was empty)."),
        port("qt_pop_treelet", In, w.treelet, "Treelet of the popped entry."),
        port("qt_pop_rays", In, wr, "Ray ids of the popped entry; lane i in bits [i*ray_id_bits +: ray_id_bits] (traced as qt_pop_rays_<i>)."),
        port("qt_free_entries", In, w.queue_free, "Free queue-table entries."),
        port("qt_spilled", In, w.ray_total, "Rays spilled to memory and not yet refilled."),
        port("mode", Out, Mode::BITS, "Traversal mode: 0 initial, 1 treelet stationary, 2 final ray stationary, 3 done."),
        port("enq_ready", Out, 1, "The enqueue request is taken this cycle."),
        port("terminate_valid", Out, 1, "Terminate an initial-phase warp: its rays go to the treelet queues."),
        port("terminate_slot", Out, w.slot, "Its warp-buffer slot."),
        port("reserve_valid", Out, 1, "The controller owns a warp-buffer slot this cycle."),
        port("reserve_slot", Out, w.slot, "That slot (not for SM warps; a repacked warp holds it until fill_last)."),
        port("repack_valid", Out, 1, "Repack a warp: keep its active rays, refill its idle lanes."),
        port("repack_slot", Out, w.slot, "Its warp-buffer slot."),
        port("fill_valid", Out, 1, "Rays for a warp-buffer slot (ray records are fetched into its lanes)."),
        port("fill_kind", Out, FillKind::BITS, "0 treelet warp, 1 grouped ray-stationary warp, 2 repack."),
        port("fill_slot", Out, w.slot, "The slot."),
        port("fill_treelet", Out, w.treelet, "Treelet of a treelet warp."),
        port("fill_first", Out, 1, "First rays of a new warp in the slot."),
        port("fill_last", Out, 1, "The slot is complete: start (or resume) the warp."),
        port("fill_count", Out, w.lanes, "Rays in this fill."),
        port("fill_rays", Out, wr, "Ray ids, appended into free lanes in order; lane i in bits [i*ray_id_bits +: ray_id_bits] (traced as fill_rays_<i>)."),
        port("preload_valid", Out, 1, "Preload a treelet into L1 and prefetch its queued rays' records (section 4.3)."),
        port("preload_treelet", Out, w.treelet, "The treelet."),
        port("ct_op", Out, CtOp::BITS, "Count-table op: 0 nop, 1 add, 2 remove."),
        port("ct_treelet", Out, w.treelet, "Its treelet."),
        port("ct_n", Out, w.lanes, "Its ray count (1..=warp_size)."),
        port("qt_op", Out, QtOp::BITS, "Queue-table op: 0 nop, 1 insert, 2 pop, 3 pop_any, 4 count (unused), 5 refill."),
        port("qt_treelet", Out, w.treelet, "Its treelet (insert, pop)."),
        port("qt_ray", Out, w.ray, "Its ray id (insert)."),
        port("resident_valid", Out, w.resident_entries, "Bit i: resident treelet i is valid, oldest (current) first (traced as resident_valid_<i>)."),
        port("resident_treelet", Out, w.resident_entries * w.treelet, "Resident treelet addresses, oldest first (traced as resident_treelet_<i>)."),
    ];
    let n = w.resident_entries;
    let slots = w.warp_slots;
    let mut registers = vec![
        reg("mode", Mode::BITS, 1, "Traversal mode FSM."),
        reg("seq", Seq::BITS, 1, "Queue-table sequencer FSM."),
        reg(
            "queued_rays",
            w.ray_total,
            1,
            "Rays in the queue table (exact).",
        ),
        reg("res_valid", 1, n, "Resident list: entry valid."),
        reg(
            "res_treelet",
            w.treelet,
            n,
            "Resident list: treelet address.",
        ),
        reg(
            "res_count",
            w.ray_total,
            n,
            "Resident list: rays still queued for it.",
        ),
        reg(
            "res_warps",
            w.warps,
            n,
            "Resident list: its treelet warps in flight.",
        ),
        reg(
            "res_head",
            w.resident_index,
            1,
            "Oldest resident entry (current treelet).",
        ),
        reg(
            "res_tail",
            w.resident_index,
            1,
            "Next resident entry to allocate.",
        ),
        reg(
            "slot_terminated",
            1,
            slots,
            "Warp-buffer slot holds a terminated warp still sending its rays to the queues.",
        ),
        reg(
            "slot_treelet_warp",
            1,
            slots,
            "Warp-buffer slot holds a dispatched treelet warp.",
        ),
        reg(
            "slot_res_valid",
            1,
            slots,
            "That warp belongs to a resident entry.",
        ),
        reg("slot_res", w.resident_index, slots, "Which resident entry."),
        reg(
            "fill_kind",
            FillKind::BITS,
            1,
            "Fill sequence: what is being built.",
        ),
        reg("fill_slot", w.slot, 1, "Fill sequence: target slot."),
        reg(
            "fill_res_valid",
            1,
            1,
            "Fill sequence: popping a resident treelet.",
        ),
        reg(
            "fill_res",
            w.resident_index,
            1,
            "Fill sequence: which resident entry.",
        ),
        reg(
            "fill_need",
            w.lanes,
            1,
            "Fill sequence: lanes still to fill.",
        ),
        reg(
            "fill_started",
            1,
            1,
            "Fill sequence: the slot already received rays (or is a repack).",
        ),
        reg("spare_count", w.lane, 1, "Valid rays in the spare buffer."),
        reg(
            "spare_rays",
            w.ray,
            w.warp_size - 1,
            "Spare buffer: popped rays that did not fit the warp being filled.",
        ),
        reg("prm_valid", 1, 1, "A count-table remove is pending."),
        reg("prm_treelet", w.treelet, 1, "Its treelet."),
        reg(
            "prm_count",
            w.ray_total,
            1,
            "Rays still to remove (a warp's worth per cycle).",
        ),
    ];
    for (name, _) in ControllerStats::default().fields() {
        registers.push(reg(name, STAT_BITS, 1, stat_doc(name)));
    }
    let flag = |b: bool| b as u64;
    BlockDesc {
        name: "treelet_controller".to_string(),
        doc: "Treelet controller (sections 4.2-4.5): switches the RT unit between the initial \
              ray-stationary phase, treelet-stationary processing of the largest treelet queues \
              (with preloading of the next treelet) and the final ray-stationary phase that \
              groups underpopulated queues into warps and repacks warps with few active rays; \
              drives one treelet-count-table and one treelet-queue-table op per cycle."
            .to_string(),
        params: vec![
            ("warp_size".to_string(), cfg.warp_size as u64),
            ("max_rays".to_string(), cfg.max_rays as u64),
            ("warp_buffer_size".to_string(), cfg.warp_buffer_size as u64),
            ("max_resident_treelets".to_string(), cfg.max_resident_treelets as u64),
            ("count_table_entries".to_string(), cfg.count_table_entries as u64),
            ("queue_table_entries".to_string(), cfg.queue_table_entries as u64),
            ("treelet_addr_bits".to_string(), w.treelet as u64),
            ("ray_id_bits".to_string(), w.ray as u64),
            ("count_bits".to_string(), w.count as u64),
            ("lane_bits".to_string(), w.lane as u64),
            ("lane_count_bits".to_string(), w.lanes as u64),
            ("slot_bits".to_string(), w.slot as u64),
            ("divergence_threshold".to_string(), cfg.divergence_threshold as u64),
            ("underpopulation_threshold".to_string(), cfg.underpopulation_threshold as u64),
            ("repack_threshold".to_string(), cfg.repack_threshold as u64),
            ("preload_threshold_warps".to_string(), cfg.preload_threshold_warps as u64),
            ("group_underpopulated".to_string(), flag(features.group_underpopulated)),
            ("preload".to_string(), flag(features.preload)),
        ],
        ports,
        registers,
        memories: vec![],
        fsms: vec![
            FsmDesc {
                name: "mode".to_string(),
                states: Mode::ALL.iter().map(|m| m.name().to_string()).collect(),
                width: Mode::BITS,
            },
            FsmDesc {
                name: "seq".to_string(),
                states: Seq::ALL.iter().map(|s| s.name().to_string()).collect(),
                width: Seq::BITS,
            },
        ],
        timing: vec![
            "At most one count-table op and one queue-table op per cycle, each driven only in a cycle whose ready input is high (both readies must come from the tables' registers); all outputs are combinational from registers and this cycle's inputs.".to_string(),
            "Answers (qt_done with the popped entry, ct_evict_*) are the tables' outputs of the previous cycle; one pop / pop_any / refill is outstanding at a time (seq = pop_wait / refill_wait).".to_string(),
            "A pending count-table remove (prm_*) owns the count-table port first, issuing up to warp_size rays per cycle.".to_string(),
            "In seq = idle at most one action per cycle, by priority: refill a spilled ray, dispatch a treelet warp (pop), claim the largest queue (no table op; preload it if a treelet is already resident), start a grouped warp or a repack, enqueue one ray (insert plus count-table add).".to_string(),
            "Terminations of diverged initial-phase warps, warp-done bookkeeping, resident retirement and mode transitions happen every cycle in parallel with the sequencer.".to_string(),
            format!("The resident list ({n} entries) is searched in parallel: {n} comparators each on enq_treelet, ct_max_treelet and ct_evict_treelet, and a priority pick from res_head."),
            format!("A fill moves up to {} ray ids per cycle from the pop bus or the spare buffer through a lane shifter.", w.warp_size),
        ],
    }
}

/// The description of a statistics register.
fn stat_doc(name: &str) -> &'static str {
    match name {
        "stat_cycles_initial" => "Statistics: cycles in the initial phase.",
        "stat_cycles_treelet" => "Statistics: cycles treelet-stationary.",
        "stat_cycles_final" => "Statistics: cycles in the final ray-stationary phase.",
        "stat_terminated_warps" => "Statistics: initial-phase warps terminated into the queues.",
        "stat_terminated_rays" => "Statistics: active rays of terminated warps.",
        "stat_enqueued_rays" => "Statistics: rays inserted into the queues.",
        "stat_claims" => "Statistics: treelets made resident.",
        "stat_preloads" => "Statistics: preloads issued.",
        "stat_treelet_warps" => "Statistics: treelet warps dispatched.",
        "stat_grouped_warps" => {
            "Statistics: ray-stationary warps grouped from underpopulated queues."
        }
        "stat_repacks" => "Statistics: warps repacked.",
        _ => "Statistics: count-table evictions seen.",
    }
}

/// Appends `name_<i>` signals for a packed port or register bank of `count` lanes.
fn lanes(out: &mut Vec<Signal>, name: &str, width: u32, count: u32, value: impl Fn(usize) -> u64) {
    for i in 0..count as usize {
        out.push(Signal::new(format!("{name}_{i}"), width, value(i)));
    }
}

impl Signals for ControllerInputs {
    fn signals(&self) -> Vec<Signal> {
        let w = &self.widths;
        let b = |v: bool| v as u64;
        let init = self.init_report;
        let enq = self.enqueue;
        let act = self.active_report;
        let max = self.ct.max;
        let pop = self.qt.done.as_ref();
        let mut s = vec![
            Signal::new("launch_done", 1, b(self.launch_done)),
            Signal::new("rt_idle", 1, b(self.rt_idle)),
            Signal::new("initial_warps", 1, b(self.initial_warps)),
            Signal::new("wb_free_valid", 1, b(self.wb_free_slot.is_some())),
            Signal::new(
                "wb_free_slot",
                w.slot,
                self.wb_free_slot.unwrap_or(0) as u64,
            ),
            Signal::new("init_valid", 1, b(init.is_some())),
            Signal::new("init_slot", w.slot, init.map_or(0, |r| r.slot) as u64),
            Signal::new("init_active", w.lanes, init.map_or(0, |r| r.active) as u64),
            Signal::new(
                "init_distinct",
                w.lanes,
                init.map_or(0, |r| r.distinct) as u64,
            ),
            Signal::new("enq_valid", 1, b(enq.is_some())),
            Signal::new("enq_ray", w.ray, enq.map_or(0, |e| e.ray) as u64),
            Signal::new(
                "enq_treelet",
                w.treelet,
                enq.map_or(0, |e| e.treelet) as u64,
            ),
            Signal::new("warp_done_valid", 1, b(self.warp_done.is_some())),
            Signal::new("warp_done_slot", w.slot, self.warp_done.unwrap_or(0) as u64),
            Signal::new("active_valid", 1, b(act.is_some())),
            Signal::new("active_slot", w.slot, act.map_or(0, |r| r.slot) as u64),
            Signal::new("active_count", w.lanes, act.map_or(0, |r| r.active) as u64),
            Signal::new("ct_ready", 1, b(self.ct.ready)),
            Signal::new("ct_max_valid", 1, b(max.is_some())),
            Signal::new(
                "ct_max_treelet",
                w.treelet,
                max.map_or(0, |m| m.treelet) as u64,
            ),
            Signal::new(
                "ct_max_count",
                w.count,
                max.map_or(0, |m| m.count.saturating_sub(1)) as u64,
            ),
            Signal::new("ct_occupancy", w.count_entries, self.ct.occupancy as u64),
            Signal::new(
                "ct_above_threshold",
                w.count_entries,
                self.ct.above_threshold as u64,
            ),
            Signal::new("ct_evict_valid", 1, b(self.ct.evict.is_some())),
            Signal::new(
                "ct_evict_treelet",
                w.treelet,
                self.ct.evict.unwrap_or(0) as u64,
            ),
            Signal::new("qt_ready", 1, b(self.qt.ready)),
            Signal::new("qt_done", 1, b(pop.is_some())),
            Signal::new(
                "qt_pop_count",
                w.lanes,
                pop.map_or(0, |p| p.rays.len()) as u64,
            ),
            Signal::new(
                "qt_pop_treelet",
                w.treelet,
                pop.map_or(0, |p| p.treelet) as u64,
            ),
        ];
        lanes(&mut s, "qt_pop_rays", w.ray, w.warp_size, |i| {
            pop.and_then(|p| p.rays.get(i)).copied().unwrap_or(0) as u64
        });
        s.push(Signal::new(
            "qt_free_entries",
            w.queue_free,
            self.qt.free_entries as u64,
        ));
        s.push(Signal::new(
            "qt_spilled",
            w.ray_total,
            self.qt.spilled as u64,
        ));
        s
    }
}

impl Signals for ControllerOutputs {
    fn signals(&self) -> Vec<Signal> {
        let w = &self.widths;
        let b = |v: bool| v as u64;
        let fill = self.fill.as_ref();
        let (ct_treelet, ct_n) = self.ct_op.wire_fields();
        let (qt_treelet, qt_ray) = self.qt_op.wire_fields();
        let mut s = vec![
            Signal::new("mode", Mode::BITS, self.mode.encoding()),
            Signal::new("enq_ready", 1, b(self.enq_ready)),
            Signal::new("terminate_valid", 1, b(self.terminate.is_some())),
            Signal::new("terminate_slot", w.slot, self.terminate.unwrap_or(0) as u64),
            Signal::new("reserve_valid", 1, b(self.reserve.is_some())),
            Signal::new("reserve_slot", w.slot, self.reserve.unwrap_or(0) as u64),
            Signal::new("repack_valid", 1, b(self.repack.is_some())),
            Signal::new("repack_slot", w.slot, self.repack.unwrap_or(0) as u64),
            Signal::new("fill_valid", 1, b(fill.is_some())),
            Signal::new(
                "fill_kind",
                FillKind::BITS,
                fill.map_or(0, |f| f.kind as u64),
            ),
            Signal::new("fill_slot", w.slot, fill.map_or(0, |f| f.slot) as u64),
            Signal::new(
                "fill_treelet",
                w.treelet,
                fill.map_or(0, |f| f.treelet) as u64,
            ),
            Signal::new("fill_first", 1, fill.map_or(0, |f| b(f.first))),
            Signal::new("fill_last", 1, fill.map_or(0, |f| b(f.last))),
            Signal::new(
                "fill_count",
                w.lanes,
                fill.map_or(0, |f| f.rays.len()) as u64,
            ),
        ];
        lanes(&mut s, "fill_rays", w.ray, w.warp_size, |i| {
            fill.and_then(|f| f.rays.get(i)).copied().unwrap_or(0) as u64
        });
        s.extend([
            Signal::new("preload_valid", 1, b(self.preload.is_some())),
            Signal::new(
                "preload_treelet",
                w.treelet,
                self.preload.unwrap_or(0) as u64,
            ),
            Signal::new("ct_op", CtOp::BITS, self.ct_op.code()),
            Signal::new("ct_treelet", w.treelet, ct_treelet),
            Signal::new("ct_n", w.lanes, ct_n),
            Signal::new("qt_op", QtOp::BITS, self.qt_op.code()),
            Signal::new("qt_treelet", w.treelet, qt_treelet),
            Signal::new("qt_ray", w.ray, qt_ray),
        ]);
        lanes(&mut s, "resident_valid", 1, w.resident_entries, |i| {
            b(i < self.resident.len())
        });
        lanes(
            &mut s,
            "resident_treelet",
            w.treelet,
            w.resident_entries,
            |i| self.resident.get(i).copied().unwrap_or(0) as u64,
        );
        s
    }
}

impl Signals for ControllerRegs {
    fn signals(&self) -> Vec<Signal> {
        let w = &self.widths;
        let b = |v: bool| v as u64;
        let n = w.resident_entries;
        let slots = w.warp_slots;
        let prm = self.pending_remove;
        let mut s = vec![
            Signal::new("mode", Mode::BITS, self.mode.encoding()),
            Signal::new("seq", Seq::BITS, self.seq as u64),
            Signal::new("queued_rays", w.ray_total, self.queued_rays as u64),
        ];
        lanes(&mut s, "res_valid", 1, n, |i| b(self.res[i].valid));
        lanes(&mut s, "res_treelet", w.treelet, n, |i| {
            self.res[i].treelet as u64
        });
        lanes(&mut s, "res_count", w.ray_total, n, |i| {
            self.res[i].count as u64
        });
        lanes(&mut s, "res_warps", w.warps, n, |i| {
            self.res[i].warps as u64
        });
        s.push(Signal::new(
            "res_head",
            w.resident_index,
            self.res_head as u64,
        ));
        s.push(Signal::new(
            "res_tail",
            w.resident_index,
            self.res_tail as u64,
        ));
        lanes(&mut s, "slot_terminated", 1, slots, |i| {
            b(self.slots[i].terminated)
        });
        lanes(&mut s, "slot_treelet_warp", 1, slots, |i| {
            b(self.slots[i].treelet_warp)
        });
        lanes(&mut s, "slot_res_valid", 1, slots, |i| {
            b(self.slots[i].resident.is_some())
        });
        lanes(&mut s, "slot_res", w.resident_index, slots, |i| {
            self.slots[i].resident.unwrap_or(0) as u64
        });
        let f = &self.fill;
        s.extend([
            Signal::new("fill_kind", FillKind::BITS, f.kind as u64),
            Signal::new("fill_slot", w.slot, f.slot as u64),
            Signal::new("fill_res_valid", 1, b(f.resident.is_some())),
            Signal::new("fill_res", w.resident_index, f.resident.unwrap_or(0) as u64),
            Signal::new("fill_need", w.lanes, f.need as u64),
            Signal::new("fill_started", 1, b(f.started)),
            Signal::new("spare_count", w.lane, self.spare_count as u64),
        ]);
        lanes(&mut s, "spare_rays", w.ray, w.warp_size - 1, |i| {
            self.spare_rays[i] as u64
        });
        s.extend([
            Signal::new("prm_valid", 1, b(prm.is_some())),
            Signal::new("prm_treelet", w.treelet, prm.map_or(0, |p| p.0) as u64),
            Signal::new("prm_count", w.ray_total, prm.map_or(0, |p| p.1) as u64),
        ]);
        for (name, value) in self.stats.fields() {
            s.push(Signal::new(name, STAT_BITS, value));
        }
        s
    }
}
