//! The `queues` mode's treelet hardware beside one SM's RT unit (paper sections 3.2 and 4.2-4.5,
//! Figure 8): the `vtq-hdl` treelet controller, treelet count table and treelet queue table,
//! stepped once per cycle and wired to the RT unit as the controller's protocol requires
//! (`vtq_hdl::controller` module documentation), plus what the paper leaves to the environment:
//! the ray store, ray ids, ray-data traffic and the queue table's spill FIFO.
//!
//! # Wiring, per cycle
//! 1. Inputs are derived from the registers at the start of the cycle: the count-table status
//!    from its registers (`max`, `occupancy`, `above`, ready unless a full table's minimum is
//!    stale), the queue-table status from its registers, and last cycle's answers (`qt_done`
//!    with the popped entry, the count table's eviction). RT-unit reports come from
//!    [`RtUnit::slot_summary`]: the initial-phase warp with the most distinct next treelets
//!    (ties: lowest slot) and, for repacking, the warp with the fewest busy lanes, skipping
//!    warps that complete this cycle. Both choices depend on registers only, so skipping idle
//!    cycles cannot change them.
//! 2. The controller is evaluated; its table ops are applied to the tables (a table with no op
//!    and no work in progress is not stepped: its registers would not change). After every
//!    step a dry run evaluates the controller on the new registers: if it would do nothing,
//!    the engine may skip cycles (a count-table scan's `Nop` cycles are stepped on catching
//!    up), and the next step reuses the dry run's inputs and, when they still hold, does not
//!    evaluate the controller again (debug builds check both against a real evaluation).
//! 3. Its commands go to the RT unit: `terminate` → the unit's `stop`, `repack` → `repack`,
//!    `fill` → ray-data loads, then (when every ray of the fill has arrived and the fill is
//!    complete) one warp issue into the reserved slot (or an append, for a repack), `preload`
//!    → the treelet's sectors are prefetched into the L1.
//! 4. An SM warp may take a slot nobody owns (not reserved this cycle, no fill building in it,
//!    its last warp's `warp_done` delivered) when the issue port is free and enough ray ids are
//!    free — except in the final ray-stationary phase, which finishes the rays it grouped
//!    before new rays are fetched (section 4.4). The SM's waiting warps count as initial-phase
//!    warps for the controller (`initial_warps`): they will populate the queues, so the treelet
//!    phase does not end while they wait; `launch_done` is low while one is offered and
//!    admitted.
//! 5. After the RT unit's step, its completed warp is unpacked: finished rays go back to their SM
//!    warps, rays stopped at a boundary are kept in the ray store and queued for enqueueing
//!    (one per cycle, taken on `enq_ready`), followed by the slot's `warp_done`.
//!
//! # Modelling decisions (the paper does not fix them)
//! - Ray ids are this SM's `hw.max_rays` ray-record slots, allocated lowest first when a warp
//!   issues and freed when its ray finishes. A warp waits while too few are free.
//! - Ray data: issuing a warp stores each ray's 32 B record (class `RayRecord`, L1 bypass, paper
//!   4.2 ❶); forming a treelet, grouped or repack warp loads 32 B per ray. The traversal stacks
//!   travel with the record without extra traffic (the paper counts only the 32 B record).
//! - Spilled queue-table entries wait in a FIFO in memory whose traffic is not modelled.
//! - A preload prefetches the treelet's nodes into the L1 (one sector per cycle in which the
//!   RT unit sends no demand request); the rays' records are loaded when their warp forms, not
//!   preloaded.
//! - When the controller is `done` (everything drained) and the SM offers a new warp, the
//!   controller restarts from the initial phase (its statistics are kept): each wave of rays
//!   (e.g. a bounce) goes through the phases again.

use std::collections::{BTreeSet, VecDeque};

use vtq_hdl::controller::{
    ActiveReport, ControllerInputs, ControllerOutputs, ControllerRegs, ControllerStats,
    CountEntry as CtlCountEntry, CountTableStatus, CtOp, EnqueueRequest, FillKind, InitReport,
    PopResult, QtOp, QueueTableStatus, TreeletController,
};
use vtq_hdl::count_table::{CountOp, CountTable, CountTableRegs};
use vtq_hdl::mode::Mode;
use vtq_hdl::queue_table::{QueueOp, QueueState, QueueTable, QueueTableRegs};
use vtq_hdl::rt_unit::{
    IssueTarget, LaneStatus, NodeDatapath, RayOutcome, RayRecord, RtCache, RtStats, RtUnit,
    RtUnitOutputs, RtUnitRegs, TraversalOrder, WarpDone, WarpIssue, CHUNK_BYTES,
};
use vtq_hdl::{Block, ConfigError, HwConfig};

use crate::geometry::Hit;
use crate::gpu::datapath::hit_from_hw;
use crate::memory::{AccessClass, MemRequest};

/// Whether a controller cycle did anything: an output other than its mode, or a register
/// change other than the cycle counters (`regs` before, `next` after).
fn acts(out: &ControllerOutputs, next: &ControllerRegs, regs: &ControllerRegs) -> bool {
    out.ct_op != CtOp::Nop
        || out.qt_op != QtOp::Nop
        || out.fill.is_some()
        || out.terminate.is_some()
        || out.repack.is_some()
        || out.preload.is_some()
        || out.reserve.is_some()
        || out.enq_ready
        || !same_but_statistics(next, regs)
}

/// Whether two controller register sets are equal except for the statistics counters (the
/// pattern is exhaustive, so a new register cannot be forgotten).
fn same_but_statistics(a: &ControllerRegs, b: &ControllerRegs) -> bool {
    let ControllerRegs {
        widths,
        mode,
        seq,
        queued_rays,
        res,
        res_head,
        res_tail,
        slots,
        fill,
        spare_rays,
        spare_count,
        pending_remove,
        stats: _,
    } = a;
    *widths == b.widths
        && *mode == b.mode
        && *seq == b.seq
        && *queued_rays == b.queued_rays
        && *res == b.res
        && *res_head == b.res_head
        && *res_tail == b.res_tail
        && *slots == b.slots
        && *fill == b.fill
        && *spare_rays == b.spare_rays
        && *spare_count == b.spare_count
        && *pending_remove == b.pending_remove
}

/// Tag bit marking a ray-data load's response (the low bits are the warp-buffer slot).
const RAY_LOAD_TAG: u64 = 1 << 48;

/// Who owns a warp-buffer slot, as the glue sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SlotUse {
    /// Free for an SM warp or a controller fill.
    Free,
    /// An SM warp in its initial traversal phase (possibly terminated).
    Initial,
    /// A warp the controller filled (treelet or grouped), building or traversing.
    Controller,
    /// Its warp completed; enqueues and `warp_done` still to deliver.
    Closing,
}

/// A fill the controller is giving to a slot: rays whose records are being loaded.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Build {
    kind: FillKind,
    rays: Vec<u32>,
    /// Ray-data loads not yet returned.
    loading: u32,
    /// The controller closed the fill.
    last: bool,
}

/// A ray that left its SM warp: its record (while queued) and where its result goes.
#[derive(Debug, Clone, PartialEq)]
struct StoredRay {
    /// SM warp handle and lane.
    owner: (usize, u32),
    /// The record while the ray waits in a queue (`None` while it is in the warp buffer).
    record: Option<RayRecord>,
}

/// Something the RT unit reports to the controller after a warp completes, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Event {
    /// A ray stopped at a treelet boundary: insert it into that treelet's queue.
    Enqueue { ray: u32, treelet: u32 },
    /// The slot's warp has sent all its rays.
    WarpDone(u32),
}

/// A ray that finished traversal: its SM warp, lane and closest hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FinishedRay {
    /// SM warp handle.
    pub warp: usize,
    /// Lane in that warp.
    pub lane: u32,
    /// Closest hit (`None`: miss).
    pub hit: Option<Hit>,
}

/// What the glue wants the RT unit to do this cycle (filled by [`TreeletQueues::before_step`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Commands {
    /// A warp issue from a completed fill.
    pub issue: Option<WarpIssue>,
    /// Terminate this slot's warp (`stop`).
    pub stop: Option<u32>,
    /// Repack this slot's warp.
    pub repack: Option<u32>,
    /// Treelet to preload into the L1.
    pub preload: Option<u32>,
    /// A slot an SM warp may take this cycle (with enough free ray ids), if any.
    pub sm_slot: Option<u32>,
}

/// Statistics of the treelet hardware of one SM.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct QueueStats {
    /// Most treelet queues tracked by the count table at once.
    pub max_queues: u64,
    /// Most of them holding at least `hw.underpopulation_threshold` rays at once.
    pub max_queues_above_threshold: u64,
    /// Queue-table inserts that spilled to memory.
    pub spills: u64,
    /// Spilled rays brought back.
    pub refills: u64,
    /// Ray-data loads (32 B each) for treelet, grouped and repack warps.
    pub ray_loads: u64,
    /// Ray-data stores (32 B each) when SM warps issue.
    pub ray_stores: u64,
    /// Controller restarts from `done` when a warp arrives (a unit with nothing launched is
    /// drained, so the first warp of a run restarts it too).
    pub restarts: u64,
    /// Intersection tests per phase: initial, treelet stationary, final ray stationary.
    pub tests: [u64; 3],
}

/// One SM's treelet controller, count table, queue table and ray store.
#[derive(Debug, Clone)]
pub struct TreeletQueues {
    warp_size: u32,
    max_rays: u32,
    ray_base: u64,
    ctl: TreeletController,
    ctl_regs: ControllerRegs,
    ct: CountTable,
    ct_regs: CountTableRegs,
    qt: QueueTable,
    qt_regs: QueueTableRegs,
    /// Count-table eviction of the previous cycle.
    ct_evict: Option<u32>,
    /// Queue-table answer (`done`) of the previous cycle.
    qt_done: Option<PopResult>,
    /// Spilled rays, oldest first.
    spilled: VecDeque<(u64, u32)>,
    rays: Vec<Option<StoredRay>>,
    free_ids: BTreeSet<u32>,
    events: VecDeque<Event>,
    uses: Vec<SlotUse>,
    builds: Vec<Option<Build>>,
    /// The controller would act next cycle even if nothing else changed.
    awake: bool,
    /// Cycle the count table publishes its pointers after the running scan (`u64::MAX`: none).
    ct_wake: u64,
    /// The controller inputs the last dry run computed (valid for the next cycle if no cycle
    /// is skipped in between).
    cached: Option<ControllerInputs>,
    /// The last dry run found the controller idle with `cached` (no output, registers
    /// unchanged but for the cycle counters).
    idle: bool,
    /// RT-unit intersection tests already attributed to a phase.
    tests_seen: u64,
    /// First inconsistency found (reported as an error by the caller).
    fault: Option<String>,
    /// Statistics.
    pub stats: QueueStats,
}

impl TreeletQueues {
    /// The treelet hardware of one SM for `cfg` with `features`; ray records of this SM start at
    /// byte `ray_base` (32 B per ray id).
    pub fn new(
        cfg: &HwConfig,
        features: vtq_hdl::controller::ControllerFeatures,
        ray_base: u64,
    ) -> Result<Self, ConfigError> {
        let ctl = TreeletController::new(cfg.clone(), features)?;
        let ct = CountTable::new(cfg)?;
        let qt = QueueTable::new(cfg)?;
        let slots = cfg.warp_buffer_size as usize;
        Ok(TreeletQueues {
            warp_size: cfg.warp_size,
            max_rays: cfg.max_rays,
            ray_base,
            ctl_regs: ctl.reset(),
            ct_regs: ct.reset(),
            qt_regs: qt.reset(),
            ctl,
            ct,
            qt,
            ct_evict: None,
            qt_done: None,
            spilled: VecDeque::new(),
            rays: vec![None; cfg.max_rays as usize],
            free_ids: (0..cfg.max_rays).collect(),
            events: VecDeque::new(),
            uses: vec![SlotUse::Free; slots],
            builds: vec![None; slots],
            // After reset the controller acts at once (an idle unit with nothing launched is
            // drained and goes to `done`), so the first cycle is evaluated.
            awake: true,
            ct_wake: u64::MAX,
            cached: None,
            idle: false,
            tests_seen: 0,
            fault: None,
            stats: QueueStats::default(),
        })
    }

    /// The controller's statistics counters.
    pub fn controller_stats(&self) -> &ControllerStats {
        &self.ctl_regs.stats
    }

    /// Ray ids in use (rays this SM's RT unit holds, queues or still has to return).
    fn rays_in_flight(&self) -> u32 {
        self.max_rays - self.free_ids.len() as u32
    }

    /// Whether SM warps are admitted in the controller's current mode: not in the final
    /// ray-stationary phase, which traverses the rays it grouped "until all of them have
    /// finished traversal completely before fetching new rays to process" (section 4.4).
    fn admitting(&self) -> bool {
        self.ctl_regs.mode != Mode::FinalRayStationary
    }

    /// Whether an SM warp could enter now: SM warps are admitted in this mode, a slot nobody
    /// owns is free and a warp's worth of ray ids is free (the controller may still reserve the
    /// slot this cycle).
    pub fn sm_may_issue(&self, regs: &RtUnitRegs) -> bool {
        self.admitting()
            && self.free_ids.len() >= self.warp_size as usize
            && self
                .uses
                .iter()
                .zip(&regs.slots)
                .any(|(u, s)| *u == SlotUse::Free && !s.valid)
    }

    /// Whether the glue has work next cycle even if no other component changes.
    pub fn busy(&self) -> bool {
        self.awake
            || !self.events.is_empty()
            || self
                .builds
                .iter()
                .flatten()
                .any(|b| b.last && b.loading == 0)
    }

    /// The cycle the count table publishes its pointers after a scan (the controller may act
    /// then), or `u64::MAX`.
    pub fn wake(&self) -> u64 {
        self.ct_wake
    }

    /// Advances `n` skipped idle cycles, as `n` steps with unchanged inputs would (the glue
    /// was not [`busy`](Self::busy)): the controller's phase counters, and the count table's
    /// scan (`Nop` cycles).
    pub fn skip(&mut self, n: u64) {
        if n > 0 {
            self.cached = None;
        }
        let mut left = n;
        while left > 0 && self.ct.busy(&self.ct_regs) {
            self.ct
                .step(&mut self.ct_regs, &self.ct.input(CountOp::Nop));
            left -= 1;
        }
        self.count_cycles(n);
    }

    /// Counts `n` cycles in which the controller did nothing in its mode's cycle counter, as
    /// its `eval` would.
    fn count_cycles(&mut self, n: u64) {
        let s = &mut self.ctl_regs.stats;
        let c = match self.ctl_regs.mode {
            Mode::Initial => &mut s.cycles_initial,
            Mode::TreeletStationary => &mut s.cycles_treelet,
            Mode::FinalRayStationary => &mut s.cycles_final,
            Mode::Done => return,
        };
        *c = c
            .saturating_add(n)
            .min((1u64 << vtq_hdl::controller::STAT_BITS) - 1);
    }

    /// The 32 B record address of ray `id`.
    fn ray_addr(&self, id: u32) -> u64 {
        self.ray_base + id as u64 * CHUNK_BYTES as u64
    }

    /// The count table's status from its registers.
    fn ct_status(&self) -> CountTableStatus {
        let r = &self.ct_regs;
        let entries = r.entries.depth() as u32;
        let max = r.max.valid.then_some(CtlCountEntry {
            treelet: r.max.treelet as u32,
            count: r.max.count_m1 + 1,
        });
        CountTableStatus {
            ready: r.occupancy != entries || r.min.valid,
            max,
            occupancy: r.occupancy,
            above_threshold: r.above,
            evict: self.ct_evict,
        }
    }

    /// The controller's inputs for this cycle.
    fn inputs<D: NodeDatapath>(
        &self,
        unit: &RtUnit<D>,
        (regs, cache): (&RtUnitRegs, &RtCache),
        offering: bool,
    ) -> ControllerInputs {
        let mut inp = self.ctl.idle_inputs();
        self.set_offering(&mut inp, offering);
        inp.rt_idle = regs.slots.iter().all(|s| !s.valid)
            && self.builds.iter().all(Option::is_none)
            && self.events.is_empty();
        inp.wb_free_slot = (0..self.uses.len() as u32)
            .find(|&s| self.uses[s as usize] == SlotUse::Free && !regs.slots[s as usize].valid);
        let mut best_init: Option<InitReport> = None;
        let mut best_active: Option<ActiveReport> = None;
        let mode = self.ctl_regs.mode;
        for (s, u) in self.uses.iter().enumerate() {
            let slot = s as u32;
            let initial = *u == SlotUse::Initial
                && regs.slots[s].order != TraversalOrder::TreeletStop
                && mode.terminates_divergent_warps();
            let Some(sum) = unit.slot_summary(regs, cache, slot, initial) else {
                continue;
            };
            if sum.quiescent && !regs.slots[s].held {
                continue; // completes this cycle
            }
            if initial {
                let r = InitReport {
                    slot,
                    active: sum.traversing,
                    distinct: sum.distinct_next_treelets,
                };
                if best_init.is_none_or(|b| r.distinct > b.distinct) {
                    best_init = Some(r);
                }
            }
            if mode == Mode::FinalRayStationary
                && !regs.slots[s].held
                && self.builds[s].is_none()
                && regs.slots[s].order != TraversalOrder::TreeletStop
            {
                let r = ActiveReport {
                    slot,
                    active: sum.busy,
                };
                if best_active.is_none_or(|b| r.active < b.active) {
                    best_active = Some(r);
                }
            }
        }
        inp.init_report = best_init;
        inp.active_report = best_active;
        match self.events.front() {
            Some(Event::WarpDone(s)) => inp.warp_done = Some(*s),
            Some(&Event::Enqueue { ray, treelet }) => {
                inp.enqueue = Some(EnqueueRequest { ray, treelet })
            }
            None => {}
        }
        inp.ct = self.ct_status();
        let q = &self.qt_regs.ctl;
        inp.qt = QueueTableStatus {
            ready: q.state == QueueState::Idle,
            done: self.qt_done.clone(),
            free_entries: q.free_count,
            spilled: q.spilled,
        };
        inp
    }

    /// Sets the inputs that depend on whether the SM offers a warp: the SM's waiting warps
    /// count as initial-phase warps and keep `launch_done` low while SM warps are admitted.
    fn set_offering(&self, inp: &mut ControllerInputs, offering: bool) {
        let waiting = offering && self.admitting();
        inp.launch_done = !waiting;
        inp.initial_warps = self.uses.contains(&SlotUse::Initial) || waiting;
    }

    /// Evaluates the controller and the tables for cycle `now`'s start-of-cycle RT-unit
    /// registers and returns the commands for the RT unit; ray-data loads go to `requests`.
    /// `offering`: the SM offers a warp this cycle.
    pub fn before_step<D: NodeDatapath>(
        &mut self,
        unit: &RtUnit<D>,
        (regs, cache, stats): (&RtUnitRegs, &RtCache, &RtStats),
        offering: bool,
        requests: &mut VecDeque<MemRequest>,
    ) -> Commands {
        self.attribute_tests(stats);
        let restarted = self.ctl_regs.mode == Mode::Done && offering;
        if restarted {
            let stats = self.ctl_regs.stats;
            self.ctl_regs = self.ctl.reset();
            self.ctl_regs.stats = stats;
            self.stats.restarts += 1;
        }
        // The dry run of the last step computed these inputs from the same registers unless
        // cycles were skipped since (they change the RT unit's delays) or the controller
        // restarted.
        let (inp, reused) = match self.cached.take() {
            Some(mut inp) if !restarted => {
                self.set_offering(&mut inp, offering);
                debug_assert_eq!(
                    inp,
                    self.inputs(unit, (regs, cache), offering),
                    "stale cached inputs"
                );
                (inp, true)
            }
            _ => (self.inputs(unit, (regs, cache), offering), false),
        };
        let admitting = self.admitting();
        // The dry run found the controller idle for exactly these inputs (no warp offered):
        // this cycle only counts in its mode's cycle counter (debug builds check it).
        let idle = reused && self.idle && !(offering && admitting);
        let out = if idle {
            debug_assert!(
                {
                    let (o, n) = self.ctl.eval(&self.ctl_regs, &inp);
                    !acts(&o, &n, &self.ctl_regs)
                },
                "the controller was not idle"
            );
            self.count_cycles(1);
            None
        } else {
            Some(self.ctl.step(&mut self.ctl_regs, &inp))
        };
        let out = out.as_ref();
        if inp.warp_done.is_some() || out.is_some_and(|o| o.enq_ready) {
            if let Some(Event::WarpDone(s)) = self.events.pop_front() {
                self.uses[s as usize] = SlotUse::Free;
            }
        }
        self.step_tables(
            out.map_or(CtOp::Nop, |o| o.ct_op),
            out.map_or(QtOp::Nop, |o| o.qt_op),
        );
        let mut cmd = Commands {
            stop: out.and_then(|o| o.terminate),
            repack: out.and_then(|o| o.repack),
            preload: out.and_then(|o| o.preload),
            ..Commands::default()
        };
        if let Some(fill) = out.and_then(|o| o.fill.as_ref()) {
            self.start_fill(fill, requests);
        }
        cmd.issue = self.finished_build(regs);
        let reserve = out.and_then(|o| o.reserve);
        if cmd.issue.is_none() && admitting {
            cmd.sm_slot = (0..self.uses.len() as u32).find(|&s| {
                self.uses[s as usize] == SlotUse::Free
                    && !regs.slots[s as usize].valid
                    && reserve != Some(s)
            });
        }
        cmd
    }

    /// Whether the controller, evaluated again with the registers it has now, would act (so
    /// the engine must not skip the next cycle). A count-table scan does not wake it: while the
    /// scan runs the controller's inputs do not change (the pointers stay stale), so the scan's
    /// `Nop` cycles are stepped in [`skip`](Self::skip) and the controller wakes when the
    /// pointers are published ([`wake`](Self::wake)).
    /// No SM warp is assumed offered: a cycle in which one is offered is evaluated anyway.
    fn dry_run<D: NodeDatapath>(
        &mut self,
        unit: &RtUnit<D>,
        regs: (&RtUnitRegs, &RtCache),
    ) -> bool {
        self.idle = false;
        if self.qt_regs.ctl.state != QueueState::Idle
            || self.qt_done.is_some()
            || self.ct_evict.is_some()
            || !self.events.is_empty()
        {
            return true;
        }
        let inp = self.inputs(unit, regs, false);
        let (out, next) = self.ctl.eval(&self.ctl_regs, &inp);
        self.cached = Some(inp);
        let acts = acts(&out, &next, &self.ctl_regs);
        self.idle = !acts;
        acts
    }

    /// Applies this cycle's table ops and keeps the tables' answers for the next cycle.
    fn step_tables(&mut self, ct_op: CtOp, qt_op: QtOp) {
        let ct_op = match ct_op {
            CtOp::Nop => CountOp::Nop,
            CtOp::Add { treelet, rays } => CountOp::Add {
                treelet: treelet as u64,
                n: rays,
            },
            CtOp::Remove { treelet, rays } => CountOp::Remove {
                treelet: treelet as u64,
                n: rays,
            },
        };
        self.ct_evict = None;
        if ct_op != CountOp::Nop || self.ct.busy(&self.ct_regs) {
            let o = self.ct.step(&mut self.ct_regs, &self.ct.input(ct_op));
            self.ct_evict = o.evict_valid.then_some(o.evict_treelet as u32);
            if o.error {
                self.set_fault(format!("the count table rejected {ct_op:?}"));
            }
        }
        self.stats.max_queues = self.stats.max_queues.max(self.ct_regs.occupancy as u64);
        self.stats.max_queues_above_threshold = self
            .stats
            .max_queues_above_threshold
            .max(self.ct_regs.above as u64);

        let qt_op = match qt_op {
            QtOp::Nop => QueueOp::Nop,
            QtOp::Insert { treelet, ray } => QueueOp::Insert {
                treelet: treelet as u64,
                ray,
            },
            QtOp::Pop { treelet } => QueueOp::Pop {
                treelet: treelet as u64,
            },
            QtOp::PopAny => QueueOp::PopAny,
            QtOp::Refill => QueueOp::Refill,
        };
        self.qt_done = None;
        let waiting = self.qt_regs.ctl.state == QueueState::RefillWait;
        if qt_op == QueueOp::Nop && self.qt_regs.ctl.state == QueueState::Idle {
            return;
        }
        let input = match self.spilled.front() {
            Some(&(t, r)) if waiting => self.qt.refill_answer(t, r),
            _ => self.qt.input(qt_op),
        };
        if waiting && self.spilled.pop_front().is_some() {
            self.stats.refills += 1;
        }
        let o = self.qt.step(&mut self.qt_regs, &input);
        if o.error {
            self.set_fault(format!("the queue table rejected {input:?}"));
        }
        if o.spill_valid {
            self.spilled.push_back((o.spill_treelet, o.spill_ray));
            self.stats.spills += 1;
        }
        if o.done {
            self.qt_done = Some(PopResult {
                treelet: o.pop_treelet as u32,
                rays: o.pop_rays[..o.pop_count as usize].to_vec(),
            });
        }
    }

    /// Starts loading the records of a fill's rays.
    fn start_fill(
        &mut self,
        fill: &vtq_hdl::controller::FillCommand,
        requests: &mut VecDeque<MemRequest>,
    ) {
        let s = fill.slot as usize;
        let build = self.builds[s].get_or_insert_with(|| Build {
            kind: fill.kind,
            rays: Vec::new(),
            loading: 0,
            last: false,
        });
        build.rays.extend_from_slice(&fill.rays);
        build.loading += fill.rays.len() as u32;
        build.last |= fill.last;
        if fill.kind != FillKind::Repack {
            self.uses[s] = SlotUse::Controller;
        }
        for &ray in &fill.rays {
            let addr = self.ray_base + ray as u64 * CHUNK_BYTES as u64;
            requests.push_back(
                MemRequest::load(
                    addr,
                    CHUNK_BYTES,
                    AccessClass::RayRecord,
                    RAY_LOAD_TAG | s as u64,
                )
                .bypassing_l1(),
            );
            self.stats.ray_loads += 1;
        }
    }

    /// A ray-data load for the fill of slot `tag & !RAY_LOAD_TAG` returned.
    pub fn ray_loaded(&mut self, tag: u64) {
        let s = (tag & !RAY_LOAD_TAG) as usize;
        if let Some(b) = self.builds.get_mut(s).and_then(Option::as_mut) {
            b.loading = b.loading.saturating_sub(1);
        }
    }

    /// The warp issue of the first fill whose rays have all arrived and which is complete.
    fn finished_build(&mut self, regs: &RtUnitRegs) -> Option<WarpIssue> {
        let s = self
            .builds
            .iter()
            .position(|b| b.as_ref().is_some_and(|b| b.last && b.loading == 0))?;
        let build = self.builds[s].take()?;
        let slot = s as u32;
        let rays = build.rays.len();
        let mut lanes: Vec<Option<RayRecord>> = vec![None; self.warp_size as usize];
        let (order, target) = match build.kind {
            FillKind::Treelet => (TraversalOrder::TreeletStop, IssueTarget::Slot(slot)),
            FillKind::Grouped => (TraversalOrder::TreeletContinue, IssueTarget::Slot(slot)),
            FillKind::Repack => (
                regs.slots[s].order,
                IssueTarget::Append { slot, last: true },
            ),
        };
        let mut free = (0..self.warp_size as usize).filter(|&l| match build.kind {
            FillKind::Repack => regs.slots[s].lanes[l].status == LaneStatus::Inactive,
            _ => true,
        });
        let mut placed = 0;
        for ray in build.rays {
            let (Some(lane), Some(stored)) = (free.next(), self.rays[ray as usize].as_mut()) else {
                break;
            };
            lanes[lane] = stored.record.take();
            placed += usize::from(lanes[lane].is_some());
        }
        if placed != rays {
            self.set_fault(format!(
                "a {:?} fill of slot {slot} placed {placed} of its {rays} rays",
                build.kind
            ));
        }
        Some(WarpIssue {
            order,
            lanes,
            target,
        })
    }

    /// Takes SM warp `warp`'s rays (`records` per lane, ray ids not yet assigned) if enough ray
    /// ids are free: assigns ids, queues the ray-data stores and returns the warp issue.
    pub fn admit(
        &mut self,
        warp: usize,
        slot: u32,
        mut lanes: Vec<Option<RayRecord>>,
        requests: &mut VecDeque<MemRequest>,
    ) -> Option<WarpIssue> {
        let need = lanes.iter().flatten().count();
        if self.free_ids.len() < need {
            return None;
        }
        for (l, rec) in lanes.iter_mut().enumerate() {
            let Some(rec) = rec.as_mut() else { continue };
            let id = self.free_ids.pop_first()?;
            rec.ray_id = id;
            self.rays[id as usize] = Some(StoredRay {
                owner: (warp, l as u32),
                record: None,
            });
            requests.push_back(
                MemRequest::store(self.ray_addr(id), CHUNK_BYTES, AccessClass::RayRecord, 0)
                    .bypassing_l1(),
            );
            self.stats.ray_stores += 1;
        }
        self.uses[slot as usize] = SlotUse::Initial;
        Some(WarpIssue {
            order: TraversalOrder::TreeletContinue,
            lanes,
            target: IssueTarget::Slot(slot),
        })
    }

    /// Unpacks the RT unit's outputs of this cycle: finished rays (returned), rays stopped at a
    /// boundary (queued for enqueueing) and the slot's `warp_done`; then decides, from the
    /// registers after the step (`regs`), whether the controller has work next cycle.
    /// `next` is the next cycle.
    pub fn after_step<D: NodeDatapath>(
        &mut self,
        unit: &RtUnit<D>,
        regs: (&RtUnitRegs, &RtCache),
        out: &RtUnitOutputs,
        next: u64,
        finished: &mut Vec<FinishedRay>,
    ) {
        if let Some(done) = &out.released {
            self.unpack(done, finished);
        }
        if let Some(done) = &out.done {
            self.unpack(done, finished);
            self.uses[done.slot as usize] = SlotUse::Closing;
            self.events.push_back(Event::WarpDone(done.slot));
        }
        self.awake = self.dry_run(unit, regs);
        self.ct_wake = self
            .ct
            .cycles_to_publish(&self.ct_regs)
            .map_or(u64::MAX, |k| next + k as u64);
    }

    /// SM warp and lane of the ray with id `ray_id`, if it is in flight.
    pub fn owner(&self, ray_id: u32) -> Option<(usize, u32)> {
        self.rays.get(ray_id as usize)?.as_ref().map(|r| r.owner)
    }

    /// The first inconsistency the glue found (a ray it cannot place or account for), if any.
    pub fn fault(&self) -> Option<&str> {
        self.fault.as_deref()
    }

    /// Records an inconsistency (the first one is kept).
    fn set_fault(&mut self, reason: String) {
        self.fault.get_or_insert(reason);
    }

    /// Returns finished rays and stores stopped ones.
    fn unpack(&mut self, done: &WarpDone, finished: &mut Vec<FinishedRay>) {
        for (rec, outcome) in done.lanes.iter().flatten() {
            let id = rec.ray_id;
            let Some(stored) = self.rays.get_mut(id as usize).and_then(Option::as_mut) else {
                self.set_fault(format!(
                    "ray id {id} left the RT unit but is not in the ray store"
                ));
                continue;
            };
            match *outcome {
                RayOutcome::Finished => {
                    finished.push(FinishedRay {
                        warp: stored.owner.0,
                        lane: stored.owner.1,
                        hit: rec.hit.as_ref().map(hit_from_hw),
                    });
                    self.rays[id as usize] = None;
                    self.free_ids.insert(id);
                }
                RayOutcome::AtBoundary { treelet } => {
                    stored.record = Some(rec.clone());
                    self.events.push_back(Event::Enqueue {
                        ray: id,
                        treelet: treelet as u32,
                    });
                }
            }
        }
    }

    /// Attributes the RT unit's intersection tests since the last call to the current phase.
    fn attribute_tests(&mut self, stats: &RtStats) {
        let total: u64 = stats.tests.iter().sum();
        let new = total - self.tests_seen;
        self.tests_seen = total;
        let phase = match self.ctl_regs.mode {
            Mode::Initial | Mode::Done => 0,
            Mode::TreeletStationary => 1,
            Mode::FinalRayStationary => 2,
        };
        self.stats.tests[phase] += new;
    }

    /// Attributes the tests of the last steps (call once at the end of the run).
    pub fn finish(&mut self, stats: &RtStats) {
        self.attribute_tests(stats);
    }

    /// A one-line summary for the watchdog.
    pub fn debug_state(&self) -> String {
        format!(
            "treelet controller: mode {}, seq {:?}, queued rays {}, resident {:?}, spare {}; \
             queue table {:?} ({} free, {} spilled); count table {} entries; events {}; slots \
             {:?}; fills {:?}; {} ray ids in use",
            self.ctl_regs.mode.name(),
            self.ctl_regs.seq,
            self.ctl_regs.queued_rays,
            self.ctl_regs.res,
            self.ctl_regs.spare_count,
            self.qt_regs.ctl.state,
            self.qt_regs.ctl.free_count,
            self.qt_regs.ctl.spilled,
            self.ct_regs.occupancy,
            self.events.len(),
            self.uses,
            self.builds,
            self.rays_in_flight()
        )
    }
}
