//! Cycle-by-cycle tests of the treelet controller alone, its inputs driven by the test and its
//! table ops answered by small reference models of the tables: each mode transition and the
//! cycle it happens on, dispatch of the largest queue, preloading, grouping vs the naive design,
//! warp repacking, completion, widths and the block description. The controller wired to the
//! real tables and RT unit is tested end to end in `treelet_rt_unit.rs` (the composed block).

mod common;

use common::assert_signals_fit;
use std::collections::{BTreeMap, BTreeSet, VecDeque};
use vtq_hdl::bounded::BoundedVec;
use vtq_hdl::controller::{
    ActiveReport, ControllerFeatures, ControllerInputs, ControllerOutputs, ControllerRegs,
    ControllerStats, EnqueueRequest, FillKind, InitReport, Seq, TreeletController,
};
use vtq_hdl::count_table::{CountOp, QueueCount};
use vtq_hdl::mode::Mode;
use vtq_hdl::queue_table::{PopResult, QueueOp};
use vtq_hdl::{Block, Dir, HwConfig, Moore, Signals};

const A: u32 = 0x1_2345;
const B: u32 = 0x0_0B0B;
const C: u32 = 0x0_0C0C;
const D: u32 = 0x0_0D0D;

/// Reference count table: exact counts, a current max pointer (ties to the lower treelet).
/// Removing more rays than held panics, so it checks that the controller mirrors counts.
#[derive(Default)]
struct RefCountTable {
    counts: BTreeMap<u32, u32>,
}

impl RefCountTable {
    fn max(&self) -> Option<QueueCount> {
        self.counts
            .iter()
            .max_by_key(|&(&t, &c)| (c, std::cmp::Reverse(t)))
            .map(|(&treelet, &count)| QueueCount { treelet, count })
    }

    fn apply(&mut self, op: CountOp, warp_size: u32) {
        match op {
            CountOp::Nop => {}
            CountOp::Clear => self.counts.clear(),
            CountOp::Add { treelet, n: rays } => {
                let treelet = treelet as u32;
                assert!((1..=warp_size).contains(&rays));
                *self.counts.entry(treelet).or_default() += rays;
            }
            CountOp::Remove { treelet, n: rays } => {
                let treelet = treelet as u32;
                assert!((1..=warp_size).contains(&rays));
                let c = self
                    .counts
                    .get_mut(&treelet)
                    .expect("remove of untracked treelet");
                assert!(*c >= rays, "remove {rays} from {treelet:#x} holding {c}");
                *c -= rays;
                if *c == 0 {
                    self.counts.remove(&treelet);
                }
            }
        }
    }
}

/// Reference queue table: entries of up to a warp of rays per treelet; a pop is answered on the
/// controller's inputs `latency` cycles after it is issued (the table's output one cycle
/// earlier), and the table is busy until then.
struct RefQueueTable {
    warp_size: usize,
    latency: u32,
    queues: BTreeMap<u32, VecDeque<Vec<u32>>>,
    busy: Option<(u32, PopResult)>,
    answer: Option<PopResult>,
}

impl RefQueueTable {
    fn new(warp_size: u32, latency: u32) -> Self {
        RefQueueTable {
            warp_size: warp_size as usize,
            latency,
            queues: BTreeMap::new(),
            busy: None,
            answer: None,
        }
    }

    fn rays(&self) -> usize {
        self.queues.values().flatten().map(Vec::len).sum()
    }

    /// Advances one cycle with the controller's op (driven only while ready).
    fn apply(&mut self, op: QueueOp) {
        self.answer = None;
        if let Some((left, res)) = self.busy.take() {
            assert_eq!(op, QueueOp::Nop, "op driven while the queue table is busy");
            if left <= 1 {
                self.answer = Some(res);
            } else {
                self.busy = Some((left - 1, res));
            }
            return;
        }
        let lanes = self.warp_size;
        let pop = |q: &mut VecDeque<Vec<u32>>, t: u32| PopResult {
            treelet: t,
            rays: BoundedVec::with(lanes, q.pop_front().unwrap_or_default()).expect("a warp"),
        };
        let result = match op {
            QueueOp::Nop | QueueOp::Count { .. } => return,
            QueueOp::Insert { treelet, ray } => {
                let treelet = treelet as u32;
                let q = self.queues.entry(treelet).or_default();
                match q.back_mut() {
                    Some(e) if e.len() < self.warp_size => e.push(ray),
                    _ => q.push_back(vec![ray]),
                }
                return;
            }
            QueueOp::Pop { treelet } => {
                let treelet = treelet as u32;
                pop(self.queues.entry(treelet).or_default(), treelet)
            }
            QueueOp::PopAny => match self.queues.iter_mut().find(|(_, q)| !q.is_empty()) {
                Some((&t, q)) => pop(q, t),
                None => PopResult::default(),
            },
            // Nothing is ever spilled here: a refill is answered empty, as by a table whose
            // spill count is 0.
            QueueOp::Refill => PopResult::default(),
        };
        self.queues.retain(|_, q| !q.is_empty());
        self.busy = Some((self.latency - 1, result));
        if self.latency == 1 {
            self.answer = self.busy.take().map(|(_, r)| r);
        }
    }
}

/// A controller with its registers, the cycle count and reference models of both tables.
struct Harness {
    ctl: TreeletController,
    regs: ControllerRegs,
    /// Its statistics, counted from its ports.
    stats: ControllerStats,
    cycle: u64,
    ct: RefCountTable,
    qt: RefQueueTable,
}

impl Harness {
    fn new(cfg: HwConfig, features: ControllerFeatures) -> Self {
        let ctl = TreeletController::new(cfg, features).expect("valid config");
        let regs = ctl.reset();
        let qt = RefQueueTable::new(ctl.config().warp_size, 1);
        Harness {
            ctl,
            regs,
            stats: ControllerStats::default(),
            cycle: 0,
            ct: RefCountTable::default(),
            qt,
        }
    }

    /// Inputs with the tables' current status (last cycle's queue-table answer) and nothing
    /// else happening.
    fn quiet(&self) -> ControllerInputs {
        let cfg = self.ctl.config();
        let mut i = self.ctl.idle_inputs();
        i.ct.ready = true;
        i.ct.max = self.ct.max();
        i.ct.occupancy = self.ct.counts.len() as u32;
        i.ct.above_threshold = self
            .ct
            .counts
            .values()
            .filter(|&&c| c >= cfg.underpopulation_threshold)
            .count() as u32;
        i.qt.ready = self.qt.busy.is_none();
        i.qt_done = self.qt.answer.clone();
        i.qt.free_entries = cfg.queue_table_entries;
        i
    }

    /// One clock: checks the inputs, steps the controller (checking `step` equals `eval` and
    /// every signal fits its width) and applies its table ops to the reference tables.
    fn step(&mut self, inputs: &ControllerInputs) -> ControllerOutputs {
        inputs.validate().expect("inputs in range");
        let (expect_out, expect_regs) = self.ctl.eval(&self.regs, inputs);
        let mode_reg = self.ctl.status(&self.regs, &(), ());
        let out = self.ctl.step(&mut self.regs, inputs);
        assert_eq!(mode_reg, out.mode_reg, "Moore status and the mode_reg port");
        assert_eq!(
            mode_reg.restarted_if(inputs.restart),
            out.mode,
            "the mode port"
        );
        assert_eq!(out, expect_out);
        assert_eq!(self.regs, expect_regs);
        assert_signals_fit(
            out.signals()
                .iter()
                .chain(self.ctl.reg_signals(&self.regs).iter()),
            "",
        );
        if !matches!(out.ct_op, CountOp::Nop | CountOp::Clear) {
            assert!(inputs.ct.ready, "count-table op while not ready");
        }
        if out.qt_op != QueueOp::Nop {
            assert!(inputs.qt.ready, "queue-table op while not ready");
        }
        self.ct.apply(out.ct_op, self.ctl.config().warp_size);
        self.qt.apply(out.qt_op);
        self.stats.observe(inputs, &out);
        self.cycle += 1;
        out
    }

    /// Queues rays while still in the initial phase (no claims happen there), presenting each
    /// request until it is taken: `(treelet, first ray id, rays)`.
    fn populate(&mut self, queues: &[(u32, u32, u32)]) {
        for &(treelet, first, rays) in queues {
            for ray in first..first + rays {
                loop {
                    let mut i = self.quiet();
                    i.enqueue = Some(EnqueueRequest { ray, treelet });
                    let o = self.step(&i);
                    assert_eq!(o.mode, Mode::Initial);
                    if o.enq_ready {
                        break;
                    }
                }
            }
        }
        assert_eq!(self.regs.queued_rays as usize, self.qt.rays());
    }

    /// Terminates the divergent initial warp in slot 0: from the next cycle the controller is
    /// treelet-stationary, and slot 0 must be reported done.
    fn enter_treelet_mode(&mut self) {
        let mut i = self.quiet();
        i.init_report = Some(InitReport {
            slot: 0,
            active: 32,
            distinct: 32,
        });
        assert_eq!(self.step(&i).terminate, Some(0));
    }
}

#[test]
fn initial_to_treelet_stationary_on_the_divergent_cycle_set_by_config() {
    for threshold in [4u32, 8] {
        let cfg = HwConfig {
            divergence_threshold: threshold,
            ..HwConfig::default()
        };
        let mut h = Harness::new(cfg, ControllerFeatures::FULL);
        // Cycle k reports a warp whose rays need k + 1 distinct treelets next.
        for k in 0..=threshold + 1 {
            let mut i = h.quiet();
            i.init_report = Some(InitReport {
                slot: 0,
                active: 32,
                distinct: k + 1,
            });
            let o = h.step(&i);
            let diverged = k + 1 > threshold;
            assert_eq!(
                o.terminate.is_some(),
                diverged,
                "threshold {threshold} cycle {k}"
            );
            let expect = if k <= threshold {
                Mode::Initial
            } else {
                Mode::TreeletStationary
            };
            assert_eq!(o.mode, expect, "threshold {threshold} cycle {k}");
        }
        assert_eq!(h.stats.terminated_warps, 2);
        assert_eq!(h.stats.terminated_rays, 64);
        assert_eq!(h.stats.cycles_initial, threshold as u64 + 1);
    }
}

#[test]
fn claims_and_dispatches_the_largest_queue() {
    let mut h = Harness::new(HwConfig::default(), ControllerFeatures::FULL);
    h.populate(&[(B, 0, 150), (A, 1000, 200), (C, 2000, 10)]);
    assert_eq!(h.regs.queued_rays, 360);
    h.enter_treelet_mode();
    // +1: the terminated warp is done; the largest queue (A, 200 rays) becomes resident.
    let mut i = h.quiet();
    i.warp_done = Some(0);
    let o = h.step(&i);
    assert_eq!(o.mode, Mode::TreeletStationary);
    assert_eq!(
        (o.qt_op, o.ct_op, o.preload),
        (QueueOp::Nop, CountOp::Nop, None)
    );
    assert!(o.resident.is_empty());
    // +2: pop A's first entry for the free slot, which the controller reserves.
    let mut i = h.quiet();
    i.wb_free_slot = Some(0);
    let o = h.step(&i);
    assert_eq!(o.qt_op, QueueOp::Pop { treelet: A as u64 });
    assert_eq!((o.reserve, o.resident.clone()), (Some(0), vec![A]));
    // +3: the entry arrives and becomes a treelet warp for A.
    let o = h.step(&h.quiet());
    assert_eq!(o.reserve, Some(0));
    let fill = o.fill.expect("treelet warp dispatched");
    assert_eq!(fill.kind, FillKind::Treelet);
    assert_eq!(
        (fill.slot, fill.treelet, fill.first, fill.last),
        (0, A, true, true)
    );
    assert_eq!(fill.rays, (1000..1032).collect::<Vec<_>>());
    // +4: the count table learns that 32 rays left A's queue.
    let o = h.step(&h.quiet());
    assert_eq!(
        o.ct_op,
        CountOp::Remove {
            treelet: A as u64,
            n: 32
        }
    );
    assert_eq!(h.ct.counts[&A], 168);
    assert_eq!(h.regs.queued_rays, 328);
    assert_eq!(h.stats.treelet_warps, 1);
}

/// Runs one slot: `running` counts down the cycles of the warp in slot 0; at 0 the warp is
/// reported done, and a free slot is offered when nothing runs.
fn slot0(i: &mut ControllerInputs, running: &mut Option<u32>) -> bool {
    match *running {
        Some(0) => {
            i.warp_done = Some(0);
            *running = None;
            true
        }
        Some(n) => {
            *running = Some(n - 1);
            false
        }
        None => {
            i.wb_free_slot = Some(0);
            false
        }
    }
}

/// Runs treelet warps of A (200 rays; B holds 150) through one warp slot, each warp taking two
/// cycles. Returns (A's queued rays, A's warps dispatched) when B is preloaded, or `None` when
/// B's first warp comes without a preload.
fn preload_point(preload_threshold_warps: u32, features: ControllerFeatures) -> Option<(u32, u32)> {
    let cfg = HwConfig {
        preload_threshold_warps,
        ..HwConfig::default()
    };
    let mut h = Harness::new(cfg, features);
    h.populate(&[(A, 0, 200), (B, 1000, 150)]);
    h.enter_treelet_mode();
    let mut running = Some(0); // the terminated warp
    let mut fills = 0;
    let mut last_fill_cycle = 0;
    for _ in 0..200 {
        let mut i = h.quiet();
        slot0(&mut i, &mut running);
        let cycle = h.cycle;
        let o = h.step(&i);
        if let Some(f) = &o.fill {
            if f.treelet == B {
                return None;
            }
            fills += 1;
            last_fill_cycle = cycle;
            running = Some(1);
        }
        if let Some(t) = o.preload {
            assert_eq!(t, B);
            assert_eq!(o.resident, vec![A], "B becomes resident behind A");
            // The fill's cycle pops the rays; the next cycle tells the count table they left
            // A's queue; the claim waits for that, so the preload comes one cycle later.
            assert_eq!(
                cycle,
                last_fill_cycle + 2,
                "preload once the table has the remove"
            );
            let a = h.regs.res.iter().find(|e| e.treelet == A).unwrap().count;
            return Some((a, fills));
        }
    }
    panic!("neither a preload nor a warp of B");
}

#[test]
fn preload_issued_when_the_current_queue_falls_under_the_threshold() {
    // 2 warps = 64 rays: A goes 200 -> 168 -> 136 -> 104 -> 72 -> 40 at the fifth warp.
    assert_eq!(preload_point(2, ControllerFeatures::FULL), Some((40, 5)));
    // 3 warps = 96 rays: the preload moves one warp earlier (72 < 96).
    assert_eq!(preload_point(3, ControllerFeatures::FULL), Some((72, 4)));
    // Preloading off: B is claimed only after A has drained.
    let off = ControllerFeatures {
        preload: false,
        ..ControllerFeatures::FULL
    };
    assert_eq!(preload_point(2, off), None);
}

/// Queues A (`a` rays), C (40) and D (20), then runs A's treelet warps to completion through
/// slot 0. Returns the harness and the cycle of A's last `warp_done`.
fn drain_a(cfg: HwConfig, features: ControllerFeatures, a: u32) -> (Harness, u64) {
    let mut h = Harness::new(cfg, features);
    h.populate(&[(A, 0, a), (C, 1000, 40), (D, 2000, 20)]);
    h.enter_treelet_mode();
    let mut running = Some(0);
    let mut a_left = a;
    for _ in 0..100 {
        let mut i = h.quiet();
        let finished = slot0(&mut i, &mut running) && a_left == 0;
        let cycle = h.cycle;
        let o = h.step(&i);
        assert_eq!(o.mode, Mode::TreeletStationary);
        if let Some(f) = &o.fill {
            assert_eq!(f.treelet, A);
            a_left -= f.rays.len() as u32;
            running = Some(1);
        }
        if finished {
            return (h, cycle);
        }
    }
    panic!("A did not drain");
}

#[test]
fn grouping_switches_to_final_ray_stationary_two_cycles_after_the_last_treelet_warp() {
    let (mut h, done_cycle) = drain_a(HwConfig::default(), ControllerFeatures::FULL, 130);
    // done_cycle: the last warp of A finishes and A retires; +1: the controller sees no
    // resident treelet, no warp feeding the queues and a largest queue (C, 40) under 128
    // rays; +2: final ray-stationary phase.
    assert_eq!(h.ct.max().map(|m| (m.treelet, m.count)), Some((C, 40)));
    let mut seen = Vec::new();
    for _ in 0..2 {
        let cycle = h.cycle;
        let o = h.step(&h.quiet());
        seen.push((cycle, o.mode));
        assert_eq!(o.preload, None);
    }
    assert_eq!(
        seen,
        vec![
            (done_cycle + 1, Mode::TreeletStationary),
            (done_cycle + 2, Mode::FinalRayStationary)
        ]
    );
}

#[test]
fn underpopulation_threshold_from_config_keeps_c_treelet_stationary() {
    // With the threshold at 40, C (40 rays) is not underpopulated: it was preloaded behind A
    // and is dispatched next instead of switching to the final phase.
    let cfg = HwConfig {
        underpopulation_threshold: 40,
        ..HwConfig::default()
    };
    let (mut h, _) = drain_a(cfg, ControllerFeatures::FULL, 130);
    assert_eq!(h.stats.preloads, 1);
    for _ in 0..4 {
        let mut i = h.quiet();
        i.wb_free_slot = Some(0);
        let o = h.step(&i);
        assert_eq!(o.mode, Mode::TreeletStationary);
        if o.qt_op != QueueOp::Nop {
            assert_eq!(o.qt_op, QueueOp::Pop { treelet: C as u64 });
            return;
        }
    }
    panic!("C was not dispatched");
}

#[test]
fn naive_design_stays_treelet_stationary_one_warp_per_queue_entry() {
    let (mut h, _) = drain_a(HwConfig::default(), ControllerFeatures::NAIVE, 130);
    let mut warps = Vec::new();
    let mut running = None;
    for _ in 0..60 {
        let mut i = h.quiet();
        slot0(&mut i, &mut running);
        i.launch_done = true;
        i.rt_idle = running.is_none() && i.warp_done.is_none();
        let o = h.step(&i);
        assert_ne!(o.mode, Mode::FinalRayStationary);
        if let Some(f) = &o.fill {
            assert_eq!(f.kind, FillKind::Treelet);
            warps.push((f.treelet, f.rays.len()));
            running = Some(1);
        }
        if o.mode == Mode::Done {
            break;
        }
    }
    // C (the larger queue) first, then D, each however small: one warp per entry.
    assert_eq!(warps, vec![(C, 32), (C, 8), (D, 20)]);
    assert_eq!(h.regs.mode, Mode::Done);
    assert_eq!(h.regs.queued_rays, 0);
    assert_eq!(h.stats.cycles_final, 0);
}

/// Brings the controller to the final ray-stationary phase with C (40 rays) and D (20) queued
/// and slot 0 busy with a ray-stationary warp.
fn final_phase(cfg: HwConfig) -> Harness {
    let mut h = Harness::new(cfg, ControllerFeatures::FULL);
    h.populate(&[(C, 1000, 40), (D, 2000, 20)]);
    h.enter_treelet_mode();
    let mut i = h.quiet();
    i.warp_done = Some(0);
    // The terminated warp is done; the next cycle sees nothing worth a treelet.
    let modes = [
        h.step(&i).mode,
        h.step(&h.quiet()).mode,
        h.step(&h.quiet()).mode,
    ];
    assert_eq!(
        modes,
        [
            Mode::TreeletStationary,
            Mode::TreeletStationary,
            Mode::FinalRayStationary
        ]
    );
    h
}

/// Reports `active` rays for slot 0 (no free slot) and returns whether a repack started.
fn repack_starts(h: &mut Harness, active: u32) -> bool {
    let mut i = h.quiet();
    i.active_report = Some(ActiveReport { slot: 0, active });
    let o = h.step(&i);
    assert_eq!(o.repack.is_some(), o.reserve.is_some());
    o.repack == Some(0)
}

#[test]
fn repacks_a_warp_with_21_active_rays_at_threshold_22_but_not_22() {
    let mut h = final_phase(HwConfig::default());
    assert!(!repack_starts(&mut h, 22));
    assert!(!repack_starts(&mut h, 32));
    assert!(repack_starts(&mut h, 21));
    assert_eq!(h.stats.repacks, 1);
    // +1: pop any queue entry; +2: it arrives (C's first 32 rays). The 11 idle lanes take
    // 11 rays, the other 21 wait in the spare buffer for the next warp.
    let o = h.step(&h.quiet());
    assert_eq!((o.qt_op, o.reserve), (QueueOp::PopAny, Some(0)));
    let o = h.step(&h.quiet());
    let fill = o.fill.expect("repack filled");
    assert_eq!(fill.kind, FillKind::Repack);
    assert_eq!((fill.slot, fill.first, fill.last), (0, false, true));
    assert_eq!(fill.rays, (1000..1011).collect::<Vec<_>>());
    assert_eq!(h.regs.spare_count, 21);
    assert_eq!(h.regs.queued_rays, 28);
}

#[test]
fn repack_threshold_16_and_off() {
    let cfg = HwConfig {
        repack_threshold: 16,
        ..HwConfig::default()
    };
    let mut h = final_phase(cfg);
    assert!(!repack_starts(&mut h, 21));
    assert!(!repack_starts(&mut h, 16));
    assert!(repack_starts(&mut h, 15));

    let cfg = HwConfig {
        repack_threshold: 0,
        ..HwConfig::default()
    };
    let mut h = final_phase(cfg);
    for active in [1, 15, 21, 31] {
        assert!(!repack_starts(&mut h, active));
    }
}

#[test]
fn groups_underpopulated_queues_into_full_warps_then_finishes() {
    let mut h = final_phase(HwConfig::default());
    let mut fills = Vec::new();
    let mut done_at = None;
    for _ in 0..40 {
        let mut i = h.quiet();
        i.wb_free_slot = Some(0);
        i.launch_done = true;
        i.rt_idle = true; // in this script the grouped warps finish at once
        let cycle = h.cycle;
        let o = h.step(&i);
        if let Some(f) = o.fill {
            fills.push((f.kind, f.first, f.last, f.rays.len()));
        }
        if o.mode == Mode::Done {
            done_at = Some(cycle);
            break;
        }
        // Grouped warps take C's and D's rays without removing their counts (PopAny).
        assert!(
            o.ct_op == CountOp::Nop || h.regs.mode == Mode::Done,
            "a count-table op before every ray is traced: {:?}",
            o.ct_op
        );
    }
    // The cycle that found every ray traced cleared the counts the grouped warps left.
    assert!(h.ct.counts.is_empty(), "stale counts: {:?}", h.ct.counts);
    // C's first entry (32) is one warp; C's other 8 and D's 20 are grouped into the second.
    assert_eq!(
        fills,
        vec![
            (FillKind::Grouped, true, true, 32),
            (FillKind::Grouped, true, false, 8),
            (FillKind::Grouped, false, true, 20),
        ]
    );
    assert_eq!(h.stats.grouped_warps, 2);
    assert_eq!((h.regs.queued_rays, h.regs.spare_count), (0, 0));
    assert!(done_at.is_some(), "Done once drained");
}

#[test]
fn stale_max_waits_and_spilled_rays_are_refilled_first() {
    let mut h = Harness::new(HwConfig::default(), ControllerFeatures::FULL);
    h.enter_treelet_mode();
    // The count table's max pointer is being rescanned (`max` absent, one entry left), with
    // `above` entries at or over the threshold and `spilled` rays in memory.
    let inputs = |h: &Harness, above: u32, spilled: u32| {
        let mut i = h.quiet();
        i.ct.max = None;
        i.ct.occupancy = 1;
        i.ct.above_threshold = above;
        i.qt.spilled = spilled;
        i.wb_free_slot = Some(0);
        i
    };
    let mut i = inputs(&h, 1, 0);
    i.warp_done = Some(0);
    h.step(&i);
    // One entry is above the threshold: the treelet phase is not over.
    for _ in 0..3 {
        assert_eq!(h.step(&inputs(&h, 1, 0)).mode, Mode::TreeletStationary);
    }
    // Spilled rays are refilled before anything else while the table has room.
    let o = h.step(&inputs(&h, 1, 2));
    assert_eq!(o.qt_op, QueueOp::Refill);
    assert_eq!(h.regs.seq, Seq::RefillWait);
    let o = h.step(&inputs(&h, 1, 1)); // the refill's answer arrives
    assert_eq!((o.qt_op, h.regs.seq), (QueueOp::Nop, Seq::Idle));
    let o = h.step(&inputs(&h, 1, 1));
    assert_eq!(o.qt_op, QueueOp::Refill);
    // All entries are under the threshold now and nothing feeds the queues: the refill is
    // answered, the next cycle (sequencer idle) judges the phase over, the one after is final.
    let modes: Vec<(Seq, Mode)> = (0..3)
        .map(|_| {
            let o = h.step(&inputs(&h, 0, 0));
            (h.regs.seq, o.mode)
        })
        .collect();
    assert_eq!(
        modes,
        [
            (Seq::Idle, Mode::TreeletStationary),
            (Seq::Idle, Mode::TreeletStationary),
            (Seq::Idle, Mode::FinalRayStationary)
        ]
    );
}

#[test]
fn an_empty_pop_of_a_resident_queue_removes_its_whole_count() {
    let mut h = Harness::new(HwConfig::default(), ControllerFeatures::NAIVE);
    h.populate(&[(A, 0, 100)]);
    h.enter_treelet_mode();
    let mut i = h.quiet();
    i.warp_done = Some(0);
    h.step(&i); // claim A (naive: any size)
    let mut i = h.quiet();
    i.wb_free_slot = Some(0);
    assert_eq!(h.step(&i).qt_op, QueueOp::Pop { treelet: A as u64 });
    // The table answers with nothing: A's rays are all spilled to memory.
    let mut i = h.quiet();
    i.qt_done = Some(PopResult {
        treelet: A,
        rays: BoundedVec::default(),
    });
    let o = h.step(&i);
    assert_eq!(o.fill, None);
    // A's whole count leaves the count table, a warp's worth per cycle, and A retires.
    let removes: Vec<CountOp> = (0..5).map(|_| h.step(&h.quiet()).ct_op).collect();
    let r = |n| CountOp::Remove {
        treelet: A as u64,
        n,
    };
    assert_eq!(removes, vec![r(32), r(32), r(32), r(4), CountOp::Nop]);
    assert!(h.ct.counts.is_empty());
    assert!(h.regs.res.iter().all(|e| !e.valid));
}

#[test]
fn done_only_when_everything_drained() {
    let mut h = Harness::new(HwConfig::default(), ControllerFeatures::FULL);
    let mut i = h.quiet();
    i.launch_done = true;
    assert_eq!(h.step(&i).mode, Mode::Initial); // RT unit still busy
    i.rt_idle = true;
    i.enqueue = Some(EnqueueRequest { ray: 7, treelet: A });
    let o = h.step(&i); // a ray is still arriving: it is queued, not done
    assert!(o.enq_ready);
    assert_eq!(o.mode, Mode::Initial);
    i.enqueue = None;
    assert_eq!(h.step(&i).mode, Mode::Initial, "one ray queued");
    assert_eq!(h.regs.queued_rays, 1);

    let mut h = Harness::new(HwConfig::default(), ControllerFeatures::FULL);
    let mut i = h.quiet();
    i.launch_done = true;
    i.rt_idle = true;
    assert_eq!(h.step(&i).mode, Mode::Initial);
    assert_eq!(h.step(&i).mode, Mode::Done, "Done the cycle after draining");
    assert_eq!(h.stats.cycles_initial, 1);
    // Done is absorbing and ignores events.
    i.init_report = Some(InitReport {
        slot: 0,
        active: 32,
        distinct: 32,
    });
    let o = h.step(&i);
    assert_eq!((o.mode, o.terminate), (Mode::Done, None));
}

#[test]
fn port_widths_follow_the_config() {
    let ctl = TreeletController::new(HwConfig::default(), ControllerFeatures::FULL).unwrap();
    let d = ctl.describe();
    let width = |name: &str| d.port(name).unwrap_or_else(|| panic!("port {name}")).width;
    for p in [
        "enq_treelet",
        "ct_max_treelet",
        "fill_treelet",
        "preload_treelet",
        "qt_treelet",
    ] {
        assert_eq!(width(p), 19, "{p}");
    }
    for p in ["enq_ray", "qt_ray", "ct_max_count"] {
        assert_eq!(width(p), 12, "{p}");
    }
    assert_eq!(width("fill_rays"), 32 * 12);
    assert_eq!(width("init_distinct"), 6);
    assert_eq!(width("wb_free_slot"), 1);
    assert_eq!(d.port("mode").unwrap().dir, Dir::Out);

    let cfg = HwConfig {
        max_rays: 8192,
        warp_buffer_size: 4,
        max_resident_treelets: 4,
        ..HwConfig::default()
    };
    let ctl = TreeletController::new(cfg, ControllerFeatures::FULL).unwrap();
    let d = ctl.describe();
    let width = |name: &str| d.port(name).unwrap().width;
    assert_eq!(width("enq_ray"), 13);
    assert_eq!(width("ct_max_count"), 13);
    assert_eq!(width("wb_free_slot"), 2);
    assert_eq!(width("resident_treelet"), 4 * 19);
}

/// Names the signals cover: each signal is a port/register of its width (`total` gives the
/// full width of a name), or lane `<i>` of a packed port or register bank, all lanes present.
fn covered(sigs: &[vtq_hdl::Signal], total: impl Fn(&str) -> Option<u32>) -> BTreeSet<String> {
    let mut lane_bits: BTreeMap<String, u32> = BTreeMap::new();
    for s in sigs {
        match total(&s.name) {
            Some(w) => {
                assert_eq!(w, s.width, "{}", s.name);
                lane_bits.insert(s.name.clone(), w);
            }
            None => {
                let (base, lane) = s.name.rsplit_once('_').expect("lane suffix");
                lane.parse::<u32>().expect("lane index");
                assert!(total(base).is_some(), "{} is not described", s.name);
                *lane_bits.entry(base.to_string()).or_default() += s.width;
            }
        }
    }
    for (name, bits) in &lane_bits {
        assert_eq!(Some(*bits), total(name), "all lanes of {name}");
    }
    lane_bits.into_keys().collect()
}

#[test]
fn signals_match_the_description() {
    let cfg = HwConfig {
        warp_buffer_size: 2,
        ..HwConfig::default()
    };
    let ctl = TreeletController::new(cfg, ControllerFeatures::FULL).unwrap();
    let d = ctl.describe();
    let regs = ctl.reset();
    let (out, _) = ctl.eval(&regs, &ctl.idle_inputs());
    let port = |dir: Dir| {
        let d = &d;
        move |n: &str| {
            d.ports
                .iter()
                .find(|p| p.name == n && p.dir == dir)
                .map(|p| p.width)
        }
    };
    let ins = covered(&ctl.idle_inputs().signals(), port(Dir::In));
    let outs = covered(&out.signals(), port(Dir::Out));
    let regs_seen = covered(&ctl.reg_signals(&regs), |n: &str| {
        d.registers
            .iter()
            .find(|r| r.name == n)
            .map(|r| r.width * r.count)
    });
    assert_eq!(
        ins.len(),
        d.ports.iter().filter(|p| p.dir == Dir::In).count()
    );
    assert_eq!(
        outs.len(),
        d.ports.iter().filter(|p| p.dir == Dir::Out).count()
    );
    assert_eq!(regs_seen.len(), d.registers.len());
}

#[test]
fn bad_inputs_are_reported_not_panics() {
    let ctl = TreeletController::new(HwConfig::default(), ControllerFeatures::FULL).unwrap();
    let mut i = ctl.idle_inputs();
    i.warp_done = Some(3); // one warp slot by default
    let e = i.validate().unwrap_err();
    assert_eq!(e.port, "warp_done_slot");
    // The controller ignores the nonexistent slot instead of panicking.
    let (_, regs) = ctl.eval(&ctl.reset(), &i);
    assert_eq!(regs.slots.len(), 1);

    let mut i = ctl.idle_inputs();
    i.enqueue = Some(EnqueueRequest {
        ray: 4096,
        treelet: 0,
    });
    assert_eq!(i.validate().unwrap_err().port, "enq_ray");
    let bad = HwConfig {
        warp_buffer_size: 0,
        ..HwConfig::default()
    };
    assert_eq!(
        TreeletController::new(bad, ControllerFeatures::FULL)
            .unwrap_err()
            .key,
        "warp_buffer_size"
    );
}

#[test]
fn describe_snapshot() {
    let ctl = TreeletController::new(HwConfig::default(), ControllerFeatures::FULL).unwrap();
    insta::assert_yaml_snapshot!("treelet_controller_describe", ctl.describe());
}

/// While a repacked warp is being filled, spilled rays are refilled before the next pop (a
/// table emptied by pops would otherwise answer every `PopAny` with nothing while its rays wait
/// in memory), and the fill sequence continues afterwards.
#[test]
fn a_fill_refills_spilled_rays_before_popping() {
    let mut h = final_phase(HwConfig::default());
    assert!(repack_starts(&mut h, 21));
    let spilled = |h: &Harness, n: u32| {
        let mut i = h.quiet();
        i.qt.spilled = n;
        i
    };
    let o = h.step(&spilled(&h, 3));
    assert_eq!((o.qt_op, o.reserve), (QueueOp::Refill, Some(0)));
    assert_eq!(h.regs.seq, Seq::FillNext, "the fill sequence goes on");
    // A full table cannot take a refilled ray: pop instead.
    let mut i = spilled(&h, 3);
    i.qt.free_entries = 0;
    assert_eq!(h.step(&i).qt_op, QueueOp::PopAny);
    let o = h.step(&spilled(&h, 0));
    assert_eq!(o.fill.expect("filled").kind, FillKind::Repack);
}
