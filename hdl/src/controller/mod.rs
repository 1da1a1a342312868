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
//! The composed block [`crate::treelet_rt_unit::TreeletRtUnit`] wires it to the RT unit and the
//! two tables; the protocol below is what that wiring honours.
//!
//! Files: [`ports`] (its port bundles), [`regs`] (its registers), `next_state` (the sequencer's
//! next-state logic beside `eval` here) and `desc` (its description).
//!
//! ## Protocol (what the integrator must honour)
//! - Table ops fire in the cycle they are driven: the controller drives a count-table op only
//!   when `ct_ready` is high (but `Clear`, which the table always accepts) and a queue-table op
//!   only when `qt_ready` is high, and assumes the op is then accepted. So the tables' status
//!   inputs (`ct_ready`, `ct_max_*`, `ct_occupancy`,
//!   `ct_above_threshold`, `qt_ready`, `qt_free_entries`, `qt_spilled`) are the tables'
//!   register-only outputs in *this* cycle ([`Moore::status`](crate::block::Moore::status),
//!   [`Moore::status`](crate::block::Moore::status)); the count table's `ready_any` is low only
//!   while it is full and its minimum is stale, the one case in which it refuses an Add.
//! - The ops are the tables' own input types ([`CountOp`], [`QueueOp`]).
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
//!   `queued_rays`. In the cycle the controller finds every ray traced (it enters mode done) it
//!   drives `Clear` if the table still holds counts, so no count outlives its wave of rays
//!   (under ray virtualization the controller restarts for every wave). Counts on the
//!   `ct_max_count` wire are encoded `count - 1` (12 bits for 4096 rays,
//!   [`HwConfig::count_bits`]); `ct_n` carries the op's true `n`.
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
//! - `restart` in mode done starts the controller from its reset state in that cycle (a new
//!   wave of rays); it is ignored in other modes.
//!
//! ## Statistics
//! The controller has no statistics registers: [`ControllerStats::observe`] counts them from its
//! ports (cycles per mode, terminations, enqueues, claims, preloads, dispatched, grouped and
//! repacked warps, evictions), as an observer beside the block.

mod desc;
mod next_state;
pub mod ports;
pub mod regs;

pub use ports::{ControllerInputs, ControllerOutputs, PortError};
pub use regs::{ControllerRegs, FillState, ResidentEntry, SlotState};

use crate::bits::{bits_for, clog2};
use crate::block::{Block, Signal};
use crate::config::{ConfigError, HwConfig};
use crate::count_table::CountOp;
use crate::describe::BlockDesc;
use crate::mode::{
    drained, largest_queue_underpopulated, next_mode, treelet_phase_over, warp_diverged,
    DrainStatus, Mode, ModeEvents, TreeletPhaseStatus,
};
use crate::queue_table::QueueOp;
use serde::Serialize;

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
    /// Admit the SM's warps into the RT unit in treelet-stationary mode too (they start their
    /// initial phase beside the treelet warps, sharing the warp buffer). Off: SM warps wait
    /// while the controller is treelet stationary, as they do in the final ray-stationary
    /// phase; an experiment on what the treelet-stationary phase processes (docs/fidelity.md,
    /// Figure 15), not a design of the paper's.
    pub admit_in_treelet_stationary: bool,
}

impl ControllerFeatures {
    /// The naive treelet queues of Figure 12: no grouping, preloading on.
    pub const NAIVE: ControllerFeatures = ControllerFeatures {
        group_underpopulated: false,
        preload: true,
        admit_in_treelet_stationary: true,
    };
    /// The full design (grouping and preloading; repacking per the configuration).
    pub const FULL: ControllerFeatures = ControllerFeatures {
        group_underpopulated: true,
        preload: true,
        admit_in_treelet_stationary: true,
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

crate::counters! {
    /// The controller's statistics, counted by an observer beside the block from its ports (not
    /// registers of the block). The simulator's statistics report them summed over its SMs: the
    /// counters the `queues` object of docs/stats.md lists under these names; the rest are
    /// reported elsewhere (`serde(skip)`, each says where).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
    pub struct ControllerStats {
        /// Cycles spent in the initial phase (reported as `phases.initial.cycles`).
        #[serde(skip)]
        pub cycles_initial: u64,
        /// Cycles spent treelet-stationary (`phases.treelet_stationary.cycles`).
        #[serde(skip)]
        pub cycles_treelet: u64,
        /// Cycles spent in the final ray-stationary phase (`phases.ray_stationary.cycles`).
        #[serde(skip)]
        pub cycles_final: u64,
        /// Initial-phase warps terminated into the queues (they diverged).
        pub terminated_warps: u64,
        /// Active rays of those warps (not in the statistics JSON: `enqueued_rays` counts
        /// every ray inserted).
        #[serde(skip)]
        pub terminated_rays: u64,
        /// Rays inserted into the treelet queues.
        pub enqueued_rays: u64,
        /// Treelets made resident (claimed from the count table).
        pub claims: u64,
        /// Treelets preloaded behind the current one.
        pub preloads: u64,
        /// Treelet warps dispatched (one queue entry each, treelet-stationary).
        pub treelet_warps: u64,
        /// Ray-stationary warps grouped from underpopulated queues.
        pub grouped_warps: u64,
        /// Warps repacked.
        pub repacks: u64,
        /// Cycles in which a repack was withheld for want of rays
        /// ([`crate::warp_repacking::withheld_for_want_of_rays`]): in the final ray-stationary
        /// phase a warp was below the repack threshold while the queues and the spare buffer
        /// were empty (the pool drained, as at the end of each bounce).
        pub repack_starved_cycles: u64,
        /// Count-table evictions seen (reported as `count_table_evictions`).
        #[serde(skip)]
        pub evictions: u64,
    }
}

/// Widths of the controller's statistics-event ports ([`ControllerCountPorts`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ControllerCountWidths {
    /// Bits of a number of a warp's lanes (0..=warp_size).
    pub lanes: u32,
}

crate::bundle! {
    /// The controller's statistics events of one cycle as ports: [`ControllerStats`] as its
    /// observer counts them (the treelet RT unit's outputs carry them).
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub struct ControllerCountPorts (Out, w: ControllerCountWidths, this) {
        /// The cycle's increments.
        pub counts: ControllerStats,
    }
    ports {
        /// a cycle in the initial phase.
        sig initial (1) = this.counts.cycles_initial;
        /// a cycle treelet-stationary.
        sig treelet (1) = this.counts.cycles_treelet;
        /// a cycle in the final ray-stationary phase.
        sig final (1) = this.counts.cycles_final;
        /// an initial-phase warp was terminated into the queues.
        sig terminated_warps (1) = this.counts.terminated_warps;
        /// the terminated warp's active rays.
        sig terminated_rays (w.lanes) = this.counts.terminated_rays;
        /// a ray was inserted into the treelet queues.
        sig enqueued (1) = this.counts.enqueued_rays;
        /// a treelet was made resident.
        sig claim (1) = this.counts.claims;
        /// a treelet was preloaded.
        sig preload (1) = this.counts.preloads;
        /// a treelet warp was dispatched.
        sig treelet_warp (1) = this.counts.treelet_warps;
        /// a grouped ray-stationary warp was started.
        sig grouped_warp (1) = this.counts.grouped_warps;
        /// a warp was repacked.
        sig repack (1) = this.counts.repacks;
        /// a repack was withheld for want of rays.
        sig repack_starved (1) = this.counts.repack_starved_cycles;
        /// the count table evicted a treelet.
        sig eviction (1) = this.counts.evictions;
    }
}

impl ControllerStats {
    /// Counts one evaluated cycle from the controller's inputs and outputs.
    pub fn observe(&mut self, inputs: &ControllerInputs, out: &ControllerOutputs) {
        self.count_cycles(out.mode, 1);
        self.evictions += u64::from(inputs.ct_evict.is_some());
        if out.terminate.is_some() {
            self.terminated_warps += 1;
            self.terminated_rays += inputs.init_report.map_or(0, |r| r.active as u64);
        }
        self.enqueued_rays += u64::from(out.enq_ready);
        self.claims += u64::from(out.claim);
        self.preloads += u64::from(out.preload.is_some());
        self.repacks += u64::from(out.repack.is_some());
        self.repack_starved_cycles += u64::from(out.repack_starved);
        if let Some(f) = &out.fill {
            self.treelet_warps += u64::from(f.kind == FillKind::Treelet);
            self.grouped_warps += u64::from(f.kind == FillKind::Grouped && f.first);
        }
    }

    /// Counts `n` cycles in `mode` (cycles in which the controller did nothing but wait count
    /// in its mode).
    pub fn count_cycles(&mut self, mode: Mode, n: u64) {
        match mode {
            Mode::Initial => self.cycles_initial += n,
            Mode::TreeletStationary => self.cycles_treelet += n,
            Mode::FinalRayStationary => self.cycles_final += n,
            Mode::Done => {}
        }
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
    /// The mode after this cycle, judged on this cycle's registers and inputs (`divergent`:
    /// an initial-phase warp diverged).
    fn mode_after(
        &self,
        regs: &ControllerRegs,
        inputs: &ControllerInputs,
        divergent: bool,
    ) -> Mode {
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
        next_mode(
            regs.mode,
            &ModeEvents {
                divergent_warp: divergent,
                treelet_phase_over: phase_over,
                drained: all_drained,
            },
        )
    }

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

    /// Whether the queues or the spare buffer hold rays (registers only).
    pub fn rays_waiting(&self, regs: &ControllerRegs) -> bool {
        regs.queued_rays > 0 || regs.spare_count > 0
    }

    /// Whether, in a cycle starting with registers `regs` and inputs `inputs`, a repack is
    /// withheld for want of rays ([`crate::warp_repacking::withheld_for_want_of_rays`], on the
    /// active-lane report): the `repack_starved` output, what
    /// [`ControllerStats::repack_starved_cycles`] counts; callable without the rest of `eval`
    /// for cycles a simulator does not evaluate (nothing in the hardware reads it).
    pub fn repack_withheld(&self, regs: &ControllerRegs, inputs: &ControllerInputs) -> bool {
        inputs.active_report.is_some_and(|r| {
            crate::warp_repacking::withheld_for_want_of_rays(
                regs.mode,
                r.active,
                self.cfg.repack_threshold,
                self.rays_waiting(regs),
            )
        })
    }
}

crate::uncached!(TreeletController);

/// The `mode_reg` port: the mode register, from which a parent decides a restart
/// ([`Mode::restarted_if`] gives the `mode` port).
impl crate::block::Moore for TreeletController {
    type Status = Mode;
    type Select = ();

    fn status(&self, regs: &ControllerRegs, _: &(), _: ()) -> Mode {
        regs.mode
    }
}

impl Block for TreeletController {
    type Inputs = ControllerInputs;
    type Outputs = ControllerOutputs;
    type Regs = ControllerRegs;

    fn reset(&self) -> ControllerRegs {
        ControllerRegs {
            mode: Mode::Initial,
            seq: Seq::Idle,
            queued_rays: 0,
            res: vec![ResidentEntry::default(); self.cfg.max_resident_treelets as usize].into(),
            res_head: 0,
            res_tail: 0,
            slots: vec![SlotState::default(); self.cfg.warp_buffer_size as usize].into(),
            fill: FillState::default(),
            spare_rays: vec![0; self.cfg.warp_size as usize - 1].into(),
            spare_count: 0,
            pending_remove: None,
        }
    }

    /// Nothing happening this cycle.
    fn idle_inputs(&self) -> ControllerInputs {
        ControllerInputs::idle(self.widths)
    }

    /// The next-state function, writing the next registers into `n`, whose storage is reused
    /// (it need not hold anything in particular): `eval` runs it on a fresh copy, a simulator
    /// on a scratch bundle it keeps, so a cycle allocates nothing.
    fn next_into(
        &self,
        regs: &ControllerRegs,
        inputs: &ControllerInputs,
        n: &mut ControllerRegs,
    ) -> ControllerOutputs {
        let mode_reg = regs.mode;
        // A restart in mode done starts this cycle from the reset state.
        let reset;
        let regs = if inputs.restart && regs.mode == Mode::Done {
            reset = self.reset();
            &reset
        } else {
            regs
        };
        n.copy_from(regs);
        let mut out = ControllerOutputs {
            widths: self.widths,
            mode: regs.mode,
            mode_reg,
            enq_ready: false,
            terminate: None,
            reserve: None,
            repack: None,
            fill: None,
            preload: None,
            ct_op: CountOp::Nop,
            qt_op: QueueOp::Nop,
            resident: regs.resident_order().map(|i| regs.res[i].treelet).collect(),
            claim: false,
            repack_starved: self.repack_withheld(regs, inputs),
        };
        let slots = self.widths.warp_slots;

        // An evicted resident treelet is no longer counted by the table: stop mirroring it (its
        // remaining rays are grouped ray-stationary later, section 6.5).
        if let Some(t) = inputs.ct_evict {
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
        }

        // A pending count-table Remove has the count-table port first, a warp of rays at a time.
        let mut ct_port_free = inputs.ct.ready;
        if let Some((treelet, rays)) = regs.pending_remove {
            if inputs.ct.ready {
                let chunk = rays.min(self.cfg.warp_size);
                out.ct_op = CountOp::Remove {
                    treelet: treelet as u64,
                    n: chunk,
                };
                n.pending_remove = (rays > chunk).then_some((treelet, rays - chunk));
            }
            ct_port_free = false;
        }

        match regs.seq {
            Seq::Idle => self.idle_step(regs, inputs, ct_port_free, n, &mut out),
            Seq::PopWait => {
                out.reserve = Some(regs.fill.slot);
                if let Some(pop) = &inputs.qt_done {
                    self.pop_done(regs, pop, n, &mut out);
                }
            }
            Seq::FillNext => self.fill_next(regs, inputs, n, &mut out),
            Seq::RefillWait => {
                if inputs.qt_done.is_some() {
                    n.seq = Seq::Idle;
                }
            }
        }

        retire_residents(n);

        n.mode = self.mode_after(regs, inputs, divergent.is_some());
        // Every ray is traced: the counts still in the table are of rays that grouped warps and
        // repacks took, so clear them before the next wave (no other op can be pending: the
        // sequence is settled and no enqueue waits).
        if n.mode == Mode::Done && regs.mode != Mode::Done && inputs.ct.occupancy > 0 {
            debug_assert_eq!(out.ct_op, CountOp::Nop, "a count-table op when drained");
            out.ct_op = CountOp::Clear;
        }
        out
    }
    fn reg_signals(&self, regs: &ControllerRegs) -> Vec<Signal> {
        regs::table(&self.widths).signals(regs)
    }

    fn describe(&self) -> BlockDesc {
        desc::describe(&self.cfg, self.features, &self.widths)
    }

    /// A one-line summary of the registers, for a watchdog's dump.
    fn debug_state(&self, regs: &ControllerRegs) -> String {
        format!(
            "mode {}, seq {:?}, queued rays {}, resident {:?}, spare {}",
            regs.mode.name(),
            regs.seq,
            regs.queued_rays,
            regs.res,
            regs.spare_count
        )
    }
}

/// Retires the resident treelets of `n` whose queue is empty and whose warps have all finished
/// (not the one a pop in flight fills), and moves the head past retired entries.
fn retire_residents(n: &mut ControllerRegs) {
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
}
