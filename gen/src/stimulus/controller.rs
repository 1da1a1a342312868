//! Seeded random stimulus for the treelet controller, played by a reactive environment that
//! honours the controller's protocol (the top of `hdl/src/controller/mod.rs`).
//!
//! The environment wires the controller to the real Rust treelet count table and treelet queue
//! table as the treelet RT unit does (their status from their registers this cycle, their
//! answers registered for the next cycle, spilled rays kept in a FIFO and handed back 0–3
//! cycles after each refill request), and models the RT unit around them: waves of SM warps
//! admitted into free warp-buffer slots in the initial and treelet-stationary modes, each with
//! rays that cross 1–3 treelet boundaries; divergence reports for initial-phase warps (a
//! terminated warp sends one enqueue per ray, then `warp_done`); treelet warps that send their
//! rays on to random treelets (or finish them) after a few cycles; grouped ray-stationary warps
//! that build from fills and lose rays one by one; active-ray reports that trigger repacks; and
//! a new wave with `restart` some cycles after the controller is done. Every input bundle is
//! validated before it is used. The same configuration, features, length and seed always give
//! the same inputs.

use super::Rng;
use crate::error::GenError;
use serde::Serialize;
use std::collections::VecDeque;
use vtq_hdl::controller::ControllerFeatures;
use vtq_hdl::controller::{
    ActiveReport, ControllerInputs, ControllerOutputs, ControllerRegs, ControllerStats,
    EnqueueRequest, FillKind, InitReport, Seq, TreeletController,
};
use vtq_hdl::count_table::{CountOp, CountTable, CountTableRegs};
use vtq_hdl::mode::Mode;
use vtq_hdl::queue_table::{PopResult, QueueOp, QueueTable, QueueTableRegs};
use vtq_hdl::{Block, HwConfig, Moore};

/// What a controller stimulus stream exercised, counted on the Rust controller's registers,
/// inputs and outputs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct ControllerCoverage {
    /// Cycles simulated.
    pub cycles: u64,
    /// Cycles per mode (the `mode` output), in [`Mode::ALL`] order.
    pub mode_cycles: [u64; 4],
    /// Cycles per sequencer state (the `seq` register), in [`Seq::ALL`] order.
    pub seq_cycles: [u64; 4],
    /// Mode transitions initial → treelet stationary.
    pub to_treelet: u64,
    /// Mode transitions treelet stationary → final ray stationary.
    pub to_final: u64,
    /// Mode transitions to done.
    pub to_done: u64,
    /// Restarts of a done controller (new waves).
    pub restarts: u64,
    /// The controller's own statistics, as the simulator's observer counts them from the same
    /// ports (terminations, enqueues, claims, preloads, treelet and grouped warps, repacks,
    /// repack-starved cycles, evictions): counted once, by [`ControllerStats::observe`].
    pub stats: ControllerStats,
    /// Enqueue requests held back (`enq_valid` without `enq_ready`).
    pub enqueues_held: u64,
    /// Treelet warps dispatched by `Pop` of a resident treelet.
    pub resident_pops: u64,
    /// Entries popped by `PopAny` (naive untracked queues and grouped warps).
    pub pop_any: u64,
    /// Pops answered with an empty entry.
    pub empty_pops: u64,
    /// Fills given from the spare buffer.
    pub spare_fills: u64,
    /// Fills that close a slot without rays.
    pub empty_closes: u64,
    /// `Refill` ops issued.
    pub refills: u64,
    /// Count-table `Remove` ops issued.
    pub removes: u64,
    /// Count-table `Clear` ops issued (a wave ended with counts left in the table).
    pub clears: u64,
    /// Evictions of a resident treelet.
    pub resident_evictions: u64,
    /// Cycles with a count-table op refused for `ct_ready` low while an op was wanted.
    pub ct_not_ready: u64,
    /// The largest number of resident treelets at once.
    pub max_resident: u64,
}

impl ControllerCoverage {
    /// Every mode and every sequencer state was reached, and every action happened at least
    /// `n` times: terminations, enqueues, claims, preloads, resident pops, pop_any, empty pops,
    /// grouped warps, repacks, cycles with a repack withheld for want of rays, spare fills,
    /// refills, removes, clears, evictions and restarts. The design variant decides which
    /// apply: without grouping (the naive design) there is no final ray-stationary phase (nor
    /// its fill sequence, grouped warps, repacks and spare fills, nor the clears of the counts
    /// they leave), and without preloading no preloads. An error lists what was not covered.
    pub fn covers_everything(&self, n: u64, features: ControllerFeatures) -> Result<(), String> {
        let naive = !features.group_underpopulated;
        let mut missing = Vec::new();
        for (m, c) in Mode::ALL.iter().zip(self.mode_cycles) {
            if c == 0 && !(naive && *m == Mode::FinalRayStationary) {
                missing.push(format!("mode {}", m.name()));
            }
        }
        for (s, c) in Seq::ALL.iter().zip(self.seq_cycles) {
            if c == 0 && !(naive && *s == Seq::FillNext) {
                missing.push(format!("seq {}", s.name()));
            }
        }
        let mut actions = vec![
            ("terminations", self.stats.terminated_warps),
            ("enqueues", self.stats.enqueued_rays),
            ("claims", self.stats.claims),
            ("resident pops", self.resident_pops),
            ("pop_any", self.pop_any),
            ("empty pops", self.empty_pops),
            ("refills", self.refills),
            ("removes", self.removes),
            ("evictions", self.stats.evictions),
            ("restarts", self.restarts),
        ];
        if features.preload {
            actions.push(("preloads", self.stats.preloads));
        }
        if !naive {
            actions.extend([
                ("grouped warps", self.stats.grouped_warps),
                ("repacks", self.stats.repacks),
                ("repack-starved cycles", self.stats.repack_starved_cycles),
                ("spare fills", self.spare_fills),
                ("clears", self.clears),
            ]);
        }
        missing.extend(super::counters_below(actions, n));
        super::coverage_verdict(&missing, self)
    }
}

impl std::fmt::Display for ControllerCoverage {
    /// Cycles per mode and per sequencer state, then the nonzero action counters.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let modes: Vec<String> = Mode::ALL
            .iter()
            .zip(self.mode_cycles)
            .map(|(m, c)| format!("{} {c}", m.name()))
            .collect();
        let seqs: Vec<String> = Seq::ALL
            .iter()
            .zip(self.seq_cycles)
            .map(|(s, c)| format!("{} {c}", s.name()))
            .collect();
        write!(
            f,
            "{} cycles; modes: {}; seq: {}",
            self.cycles,
            modes.join(", "),
            seqs.join(", ")
        )?;
        let fields = [
            ("initial->treelet", self.to_treelet),
            ("treelet->final", self.to_final),
            ("->done", self.to_done),
            ("restarts", self.restarts),
            ("terminations", self.stats.terminated_warps),
            ("enqueues", self.stats.enqueued_rays),
            ("enqueues held", self.enqueues_held),
            ("claims", self.stats.claims),
            ("preloads", self.stats.preloads),
            ("resident pops", self.resident_pops),
            ("pop_any", self.pop_any),
            ("empty pops", self.empty_pops),
            ("treelet warps", self.stats.treelet_warps),
            ("grouped warps", self.stats.grouped_warps),
            ("repacks", self.stats.repacks),
            ("repack-starved cycles", self.stats.repack_starved_cycles),
            ("spare fills", self.spare_fills),
            ("empty closes", self.empty_closes),
            ("refills", self.refills),
            ("removes", self.removes),
            ("clears", self.clears),
            ("evictions", self.stats.evictions),
            ("resident evictions", self.resident_evictions),
            ("max resident", self.max_resident),
        ];
        let text: Vec<String> = fields
            .iter()
            .filter(|(_, v)| *v != 0)
            .map(|(name, v)| format!("{name} {v}"))
            .collect();
        write!(f, "; {}", text.join(", "))
    }
}

/// What the environment's RT unit holds in one warp-buffer slot.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Slot {
    /// Free for an SM warp or a controller fill.
    Free,
    /// An SM warp in its initial ray-stationary phase; it finishes when `timer` runs out.
    Initial { rays: Vec<u32>, timer: u32 },
    /// A warp whose events (enqueues, then `warp_done`) are queued; free once `warp_done` is
    /// taken.
    Draining,
    /// A treelet warp traversing its treelet until `timer` runs out.
    Treelet { rays: Vec<u32>, timer: u32 },
    /// A grouped warp (or a repacked one) receiving fills.
    Building { rays: Vec<u32> },
    /// A ray-stationary warp whose rays finish one by one.
    Traversing { rays: Vec<u32> },
}

/// An event of the RT unit for the controller, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Event {
    Enqueue(EnqueueRequest),
    WarpDone(u32),
}

/// The environment around the controller.
struct Env {
    rng: Rng,
    ws: u32,
    ctl: TreeletController,
    regs: ControllerRegs,
    ct: CountTable,
    ct_regs: CountTableRegs,
    qt: QueueTable,
    qt_regs: QueueTableRegs,
    /// The tables' answers of the previous cycle.
    ct_evict: Option<u32>,
    qt_done: Option<PopResult>,
    /// Spilled rays, oldest first, and the cycles until the head answers a refill request.
    spill: VecDeque<(u64, u32)>,
    refill_delay: u32,
    slots: Vec<Slot>,
    events: VecDeque<Event>,
    /// Ray ids not in use, and the treelet boundaries each ray still crosses.
    free_ids: Vec<u32>,
    hops: Vec<u32>,
    treelets: Vec<u32>,
    /// SM warps of the current wave still to admit, and cycles to wait before the next wave.
    wave_left: u32,
    next_wave: u32,
    cov: ControllerCoverage,
}

impl Env {
    fn new(cfg: &HwConfig, features: ControllerFeatures, seed: u64) -> Result<Self, GenError> {
        let ctl = TreeletController::new(cfg.clone(), features)?;
        let ct = CountTable::new(cfg)?;
        let qt = QueueTable::new(cfg)?;
        let mut rng = Rng::new(seed);
        let bits = ctl.widths().treelet;
        // A few treelets, so queues grow past the thresholds; a few more keep the count table
        // evicting.
        let n = 3 + cfg.count_table_entries.min(8) as usize;
        let treelets: Vec<u32> = (0..n)
            .map(|i| {
                if i % 3 == 0 {
                    i as u32
                } else {
                    rng.below(1 << bits.min(31)) as u32
                }
            })
            .collect();
        Ok(Env {
            ws: cfg.warp_size,
            regs: ctl.reset(),
            ct_regs: ct.reset(),
            qt_regs: qt.reset(),
            ctl,
            ct,
            qt,
            ct_evict: None,
            qt_done: None,
            spill: VecDeque::new(),
            refill_delay: 0,
            slots: vec![Slot::Free; cfg.warp_buffer_size as usize],
            events: VecDeque::new(),
            free_ids: (0..cfg.max_rays).rev().collect(),
            hops: vec![0; cfg.max_rays as usize],
            treelets,
            wave_left: 0,
            next_wave: 0,
            rng,
            cov: ControllerCoverage::default(),
        })
    }

    /// A treelet for an enqueued ray: the first few are popular, so their queues grow.
    fn treelet(&mut self) -> u32 {
        let n = self.treelets.len() as u64;
        let i = if self.rng.chance(60) {
            self.rng.below(n.min(3))
        } else {
            self.rng.below(n)
        };
        self.treelets[i as usize]
    }

    /// Events for the rays of a warp that leaves its treelet (or is terminated): each ray with
    /// boundaries left is enqueued, the others finish; then `warp_done`.
    fn drain(&mut self, slot: usize, rays: Vec<u32>, terminated: bool) {
        for r in rays {
            let h = &mut self.hops[r as usize];
            if *h > 0 || terminated {
                *h = h.saturating_sub(1);
                let treelet = self.treelet();
                self.events
                    .push_back(Event::Enqueue(EnqueueRequest { ray: r, treelet }));
            } else {
                self.free_ids.push(r);
            }
        }
        self.events.push_back(Event::WarpDone(slot as u32));
        self.slots[slot] = Slot::Draining;
    }

    /// A random slot matching `pred`, if any.
    fn pick(&mut self, pred: impl Fn(&Slot) -> bool) -> Option<usize> {
        let c: Vec<usize> = (0..self.slots.len())
            .filter(|&s| pred(&self.slots[s]))
            .collect();
        (!c.is_empty()).then(|| c[self.rng.below(c.len() as u64) as usize])
    }

    /// This cycle's inputs from the environment's state, `offering` whether the SM offers a
    /// warp: as in the treelet RT unit's wiring, a warp waiting to be admitted counts as an
    /// initial-phase warp and keeps `launch_done` low, and a `done` controller restarts.
    fn inputs(&mut self, offering: bool) -> ControllerInputs {
        let mut i = self.ctl.idle_inputs();
        let waiting =
            offering && admits(self.ctl.status(&self.regs, &(), ()).restarted_if(offering));
        i.restart = offering;
        i.launch_done = !waiting;
        i.rt_idle = self.events.is_empty() && self.slots.iter().all(|s| *s == Slot::Free);
        i.initial_warps = waiting || self.slots.iter().any(|s| matches!(s, Slot::Initial { .. }));
        if self.rng.chance(85) {
            i.wb_free_slot = self.pick(|s| *s == Slot::Free).map(|s| s as u32);
        }
        if self.rng.chance(50) {
            if let Some(s) = self.pick(|s| matches!(s, Slot::Initial { .. })) {
                if let Slot::Initial { rays, .. } = &self.slots[s] {
                    let active = rays.len() as u32;
                    let distinct = 1 + self.rng.below(active as u64) as u32;
                    i.init_report = Some(InitReport {
                        slot: s as u32,
                        active,
                        distinct,
                    });
                }
            }
        }
        match self.events.front() {
            Some(Event::Enqueue(e)) => i.enqueue = Some(*e),
            Some(Event::WarpDone(s)) => i.warp_done = Some(*s),
            None => {}
        }
        if self.rng.chance(60) {
            if let Some(s) = self.pick(|s| matches!(s, Slot::Traversing { .. })) {
                if let Slot::Traversing { rays } = &self.slots[s] {
                    i.active_report = Some(ActiveReport {
                        slot: s as u32,
                        active: rays.len() as u32,
                    });
                }
            }
        }
        i.ct = self.ct.status(&self.ct_regs, &(), ());
        i.ct_evict = self.ct_evict;
        i.qt = self.qt.status(&self.qt_regs, &(), ());
        i.qt_done = self.qt_done.clone();
        i
    }

    /// One cycle: returns its inputs.
    fn cycle(&mut self) -> Result<ControllerInputs, GenError> {
        // The SM offers warps in waves, with pauses between them.
        if self.wave_left == 0 {
            if self.next_wave == 0 {
                self.wave_left = 3 + self.rng.below(3 * self.slots.len() as u64 + 4) as u32;
                self.next_wave = 20 + self.rng.below(150) as u32;
            } else {
                self.next_wave -= 1;
            }
        }
        let offering = self.wave_left > 0 && self.rng.chance(80);
        let inputs = self.inputs(offering);
        inputs.validate().map_err(|e| GenError::Cosim {
            block: "treelet_controller".into(),
            reason: format!("the stimulus drove an invalid input: {e}"),
        })?;
        let before = self.regs.clone();
        let (out, next) = self.ctl.eval(&self.regs, &inputs);
        self.count(&before, &inputs, &out, &next);
        self.regs = next;
        self.tables(&out);
        self.rt_unit(&out, offering, inputs.warp_done.is_some());
        Ok(inputs)
    }

    /// The tables take the controller's ops (or a refill answer) and register their answers.
    fn tables(&mut self, out: &ControllerOutputs) {
        let ct_out = self.ct.step(&mut self.ct_regs, &self.ct.input(out.ct_op));
        let waiting = self.qt.status(&self.qt_regs, &(), ()).refill_waiting;
        let qt_in = match self.spill.front() {
            Some(&(t, r)) if waiting && self.refill_delay == 0 => {
                self.spill.pop_front();
                self.qt.refill_answer(t, r)
            }
            _ => {
                if waiting {
                    self.refill_delay = self.refill_delay.saturating_sub(1);
                } else {
                    self.refill_delay = self.rng.below(4) as u32;
                }
                self.qt.input(out.qt_op)
            }
        };
        let qt_out = self.qt.step(&mut self.qt_regs, &qt_in);
        if qt_out.spill_valid {
            self.spill
                .push_back((qt_out.spill_treelet, qt_out.spill_ray));
        }
        self.ct_evict = ct_out.evict_valid.then_some(ct_out.evict_treelet as u32);
        self.qt_done = qt_out.popped();
    }

    /// The RT unit reacts to the controller's outputs and advances its warps.
    /// `offering`: the SM offers a warp; `warp_done`: the first event was a warp done.
    fn rt_unit(&mut self, out: &ControllerOutputs, offering: bool, warp_done: bool) {
        if warp_done || out.enq_ready {
            if let Some(Event::WarpDone(s)) = self.events.pop_front() {
                self.slots[s as usize] = Slot::Free;
            }
        }
        if let Some(s) = out.terminate {
            if let Slot::Initial { rays, .. } =
                std::mem::replace(&mut self.slots[s as usize], Slot::Free)
            {
                self.drain(s as usize, rays, true);
            }
        }
        if let Some(s) = out.repack {
            if let Slot::Traversing { rays } =
                std::mem::replace(&mut self.slots[s as usize], Slot::Free)
            {
                self.slots[s as usize] = Slot::Building { rays };
            }
        }
        if let Some(f) = &out.fill {
            let s = f.slot as usize;
            match f.kind {
                FillKind::Treelet => {
                    let timer = 1 + self.rng.below(8) as u32;
                    self.slots[s] = Slot::Treelet {
                        rays: f.rays.clone(),
                        timer,
                    };
                }
                FillKind::Grouped | FillKind::Repack => {
                    let mut rays = match std::mem::replace(&mut self.slots[s], Slot::Free) {
                        Slot::Building { rays } if !f.first => rays,
                        _ => Vec::new(),
                    };
                    rays.extend_from_slice(&f.rays);
                    self.slots[s] = if !f.last {
                        Slot::Building { rays }
                    } else if rays.is_empty() {
                        self.events.push_back(Event::WarpDone(s as u32));
                        Slot::Draining
                    } else {
                        Slot::Traversing { rays }
                    };
                }
            }
        }
        // An offered SM warp enters in the initial and treelet-stationary modes (the mode
        // output), into a free slot the controller does not own, when enough ray ids are free.
        if offering && admits(out.mode) {
            let reserved = out.reserve;
            let slot = self.pick(|s| *s == Slot::Free);
            if let Some(s) = slot.filter(|&s| reserved != Some(s as u32)) {
                let n = 1 + self.rng.below(self.ws as u64) as usize;
                if self.free_ids.len() >= n {
                    let rays: Vec<u32> = (0..n).filter_map(|_| self.free_ids.pop()).collect();
                    for &r in &rays {
                        self.hops[r as usize] = self.rng.below(3) as u32;
                    }
                    let timer = 4 + self.rng.below(20) as u32;
                    self.slots[s] = Slot::Initial { rays, timer };
                    self.wave_left -= 1;
                }
            }
        }
        // Warps advance.
        for s in 0..self.slots.len() {
            match &mut self.slots[s] {
                Slot::Initial { timer, .. } | Slot::Treelet { timer, .. } if *timer > 0 => {
                    *timer -= 1;
                }
                Slot::Initial { rays, .. } => {
                    // It finished ray-stationary: its rays are done.
                    let rays = std::mem::take(rays);
                    self.free_ids.extend(rays);
                    self.events.push_back(Event::WarpDone(s as u32));
                    self.slots[s] = Slot::Draining;
                }
                Slot::Treelet { rays, .. } => {
                    let rays = std::mem::take(rays);
                    self.drain(s, rays, false);
                }
                Slot::Traversing { rays } => {
                    if self.rng.chance(15) {
                        if let Some(r) = rays.pop() {
                            self.free_ids.push(r);
                        }
                        if rays.is_empty() {
                            self.events.push_back(Event::WarpDone(s as u32));
                            self.slots[s] = Slot::Draining;
                        }
                    }
                }
                Slot::Free | Slot::Draining | Slot::Building { .. } => {}
            }
        }
    }

    /// Counts one cycle's coverage.
    fn count(
        &mut self,
        regs: &ControllerRegs,
        i: &ControllerInputs,
        out: &ControllerOutputs,
        next: &ControllerRegs,
    ) {
        let c = &mut self.cov;
        c.cycles += 1;
        c.mode_cycles[out.mode as usize] += 1;
        let seq = if i.restart && regs.mode == Mode::Done {
            Seq::Idle
        } else {
            regs.seq
        };
        c.seq_cycles[seq as usize] += 1;
        match (out.mode, next.mode) {
            (Mode::Initial, Mode::TreeletStationary) => c.to_treelet += 1,
            (Mode::TreeletStationary, Mode::FinalRayStationary) => c.to_final += 1,
            (m, Mode::Done) if m != Mode::Done => c.to_done += 1,
            _ => {}
        }
        c.restarts += u64::from(i.restart && regs.mode == Mode::Done);
        c.enqueues_held += u64::from(i.enqueue.is_some() && !out.enq_ready);
        c.resident_pops += u64::from(matches!(out.qt_op, QueueOp::Pop { .. }));
        c.pop_any += u64::from(out.qt_op == QueueOp::PopAny);
        if seq == Seq::PopWait {
            c.empty_pops += u64::from(i.qt_done.as_ref().is_some_and(|p| p.rays.is_empty()));
        }
        if let Some(f) = &out.fill {
            c.spare_fills += u64::from(seq == Seq::FillNext && !f.rays.is_empty());
            c.empty_closes += u64::from(f.rays.is_empty());
        }
        c.refills += u64::from(out.qt_op == QueueOp::Refill);
        c.removes += u64::from(matches!(out.ct_op, CountOp::Remove { .. }));
        c.clears += u64::from(out.ct_op == CountOp::Clear);
        c.ct_not_ready +=
            u64::from(!i.ct.ready && (i.enqueue.is_some() || regs.pending_remove.is_some()));
        if let Some(t) = i.ct_evict {
            c.resident_evictions += u64::from(out.resident.contains(&t));
        }
        c.stats.observe(i, out);
        c.max_resident = c.max_resident.max(out.resident.len() as u64);
    }
}

/// Whether SM warps are admitted in `mode` (the designs' `admit_in_treelet_stationary`).
fn admits(mode: Mode) -> bool {
    matches!(mode, Mode::Initial | Mode::TreeletStationary)
}

/// `cycles` cycles of controller inputs from the reactive environment (see the module
/// documentation), with the controller they were played against (for [`crate::cosim::record`])
/// and what they covered.
pub fn controller_inputs(
    cfg: &HwConfig,
    features: ControllerFeatures,
    cycles: usize,
    seed: u64,
) -> Result<(TreeletController, Vec<ControllerInputs>, ControllerCoverage), GenError> {
    let mut env = Env::new(cfg, features, seed)?;
    let mut inputs = Vec::with_capacity(cycles);
    for _ in 0..cycles {
        inputs.push(env.cycle()?);
    }
    Ok((env.ctl.clone(), inputs, env.cov))
}
