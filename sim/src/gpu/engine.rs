//! The cycle loop. Each cycle, in this order: time-series samples due, shader timers (warps
//! become ready to trace or end; CTAs retire or, with ray virtualization, start suspending),
//! CTA dispatch to free slots (CTAs ready to resume first, then new ones), memory responses into
//! the RT units' return queues (CTA-state loads to their SMs: a CTA whose state is back shades
//! the hits its warps received while suspended), one step of every RT unit (issue, responses,
//! completion) with its memory request to the L1, and one CTA-state access per SM. SMs are
//! visited in index order, so runs are deterministic.
//!
//! Idle cycles are skipped in SST's declocking style, per SM: after visiting an SM the engine
//! records the next cycle that SM has work (its shader timers [`Sm::next_timer`], a warp it can
//! offer its RT unit, [`RtPort::next_event`], which uses the RT unit's exact `idle_cycles`,
//! [`CtaStatePort::next_event`], its next memory response
//! [`MemorySystem::next_response`], room for the CTA dispatch), jumps to the earliest such
//! cycle over all SMs, and there visits only the SMs whose wake cycle has come (all of them
//! when the CTA dispatch ran). This is exact because an SM's wake cycle changes only when the
//! SM itself is visited or the dispatch gives it a CTA: its memory responses come from its own
//! accesses, and visiting it earlier would do nothing (each of its components reports no work
//! before that cycle). Within a visited SM, an RT unit with nothing to do is not stepped
//! either; it catches up its warp-cycle statistics and delay counters with `skip` when next
//! stepped (and at the end). With `sim.lockstep` every SM is visited and every RT unit stepped
//! every cycle; results are identical (tested).

use std::time::Instant;

use glam::Vec3;
use vtq_hdl::rt_unit::{TraversalOrder, CHUNK_BYTES};

use crate::bvh::HwBvh;
use crate::config::{ModeKind, SimConfig};
use crate::geometry::{Hit, Ray};
use crate::gpu::cta_scheduler::CtaScheduler;
use crate::gpu::error::SimError;
use crate::gpu::prefetch::Prefetcher;
use crate::gpu::rt::{QueueObserver, QueueSetup, RtPort, TracedWarp};
use crate::gpu::shader::{PathThread, ShaderTiming, ThreadStep};
use crate::gpu::sm::Sm;
use crate::gpu::stats::{PhaseStats, Phases, QueueTotals, RtTotals, Sample, SimStats};
use crate::gpu::virtualization::{CtaStatePort, StateSend};
use crate::gpu::watchdog::Watchdog;
use crate::memory::{AccessClass, MemorySystem, Response};
use crate::scene::Scene;
use crate::workload::camera::CameraFrame;
use crate::workload::pathtracer::RenderSettings;

/// Bytes of one hit record.
const HIT_RECORD_BYTES: u64 = 32;

/// Alignment of the hit-record region after the BVH image.
const HIT_RECORD_ALIGN: u64 = 4096;

/// Options of a simulation that are not part of the configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SimOptions {
    /// Record every traced ray with its closest hit ([`SimOutput::ray_log`]), for tests.
    pub record_rays: bool,
    /// Queues mode: record the input ports of SM `.0`'s treelet count and queue tables for the
    /// first `.1` cycles ([`SimOutput::table_log`]), to replay real traffic against their RTL.
    pub record_tables: Option<(usize, usize)>,
}

/// One traced ray and the closest hit the RT unit found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TracedRay {
    /// Pixel of the thread that traced it.
    pub pixel: u32,
    /// The ray.
    pub ray: Ray,
    /// Its closest hit (`None`: a miss).
    pub hit: Option<Hit>,
}

/// The result of a simulation.
#[derive(Debug, Clone, PartialEq)]
pub struct SimOutput {
    /// Statistics.
    pub stats: SimStats,
    /// Linear radiance per pixel, row-major, as [`crate::workload::pathtracer::render`] gives.
    pub image: Vec<Vec3>,
    /// Samples whose radiance was NaN or infinite (written black).
    pub nonfinite_samples: u64,
    /// The time series (every `sim.sample_interval` cycles).
    pub time_series: Vec<Sample>,
    /// Every traced ray in completion order (only with [`SimOptions::record_rays`]).
    pub ray_log: Vec<TracedRay>,
    /// The recorded table inputs (only with [`SimOptions::record_tables`] in queues mode).
    pub table_log: Option<vtq_hdl::treelet_rt_unit::TableLog>,
}

/// The whole simulated GPU.
struct Gpu<'a> {
    scene: &'a Scene,
    cfg: &'a SimConfig,
    settings: RenderSettings,
    frame: CameraFrame,
    timing: ShaderTiming,
    options: SimOptions,
    scheduler: CtaScheduler,
    sms: Vec<Sm>,
    rts: Vec<RtPort<'a>>,
    /// Each SM's CTA-state traffic (ray virtualization; idle without it).
    states: Vec<CtaStatePort>,
    /// CTA-state load responses of the SM being visited (reused buffer).
    state_loads: Vec<Response>,
    mem: MemorySystem,
    /// Per SM: the next cycle it has work (it is visited when this cycle has come).
    wake: Vec<u64>,
    /// The SMs visited in the current cycle, in index order (reused buffer).
    awake: Vec<usize>,
    watchdog: Watchdog,
    image: Vec<Vec3>,
    nonfinite: u64,
    ray_log: Vec<TracedRay>,
    rays_hit: u64,
    time_series: Vec<Sample>,
    next_sample: u64,
    last_sample_loads: (u64, u64),
    pixels_done: u64,
    stepped: u64,
}

/// Checks that the configuration asks for what this build simulates and fits the BVH.
fn check_setup(bvh: &HwBvh, cfg: &SimConfig) -> Result<(), SimError> {
    if *bvh.params() != cfg.bvh_params() {
        return Err(SimError::Setup(format!(
            "the BVH was built with {:?} but the configuration asks for {:?}",
            bvh.params(),
            cfg.bvh_params()
        )));
    }
    let ids = cfg.hw.warp_buffer_size as u64 * cfg.hw.warp_size as u64;
    if ids > cfg.hw.max_rays as u64 {
        return Err(SimError::Setup(format!(
            "hw.warp_buffer_size x hw.warp_size = {ids} rays exceed hw.max_rays = {} (ray ids \
             name warp-buffer lanes)",
            cfg.hw.max_rays
        )));
    }
    Ok(())
}

/// Simulates the path-traced workload of `cfg.workload` on `scene` (whose BVH is `bvh`, built
/// with `cfg.bvh_params()`), advancing `progress` (if any) by finished pixels.
pub fn simulate(
    scene: &Scene,
    bvh: &HwBvh,
    cfg: &SimConfig,
    options: SimOptions,
    progress: Option<&indicatif::ProgressBar>,
) -> Result<SimOutput, SimError> {
    cfg.validate().map_err(|e| SimError::Setup(e.to_string()))?;
    check_setup(bvh, cfg)?;
    let settings = cfg.render_settings();
    settings.validate()?;
    let frame = CameraFrame::new(&scene.camera, settings.width, settings.height)
        .map_err(crate::workload::pathtracer::RenderError::from)?;
    let config_toml = cfg
        .to_toml()
        .map_err(|e| SimError::Setup(format!("cannot write the configuration: {e}")))?;
    let nsms = cfg.gpu.sms as usize;
    let warps_per_cta = cfg.warps_per_cta() as usize;
    let cta_slots = (cfg.gpu.max_ctas_per_sm as usize)
        .min(cfg.gpu.max_warps_per_sm as usize / warps_per_cta.max(1));
    if cta_slots == 0 {
        return Err(SimError::Setup(format!(
            "a CTA of {warps_per_cta} warps does not fit gpu.max_warps_per_sm = {}",
            cfg.gpu.max_warps_per_sm
        )));
    }
    let bvh_end = bvh.treelets().len() as u64 * bvh.params().treelet_bytes as u64;
    let records = bvh_end.div_ceil(HIT_RECORD_ALIGN) * HIT_RECORD_ALIGN;
    let per_sm = cfg.hw.max_rays as u64 * HIT_RECORD_BYTES;
    // Hit records, then (queues mode) ray records, then suspended CTAs' state, then the
    // traversal stacks' spill areas.
    let state_base = (records + 2 * nsms as u64 * per_sm).next_multiple_of(HIT_RECORD_ALIGN);
    let scheduler = CtaScheduler::new(settings.width, settings.height, cfg.gpu.threads_per_cta);
    let state_end = state_base
        + scheduler.total() as u64 * cfg.cta_state_bytes().next_multiple_of(CHUNK_BYTES as u64);
    let spill = SpillLayout::new(cfg, bvh, state_end.next_multiple_of(HIT_RECORD_ALIGN))?;
    let rts = (0..nsms)
        .map(|sm| {
            let params = cfg.rt_unit_params(
                records + sm as u64 * per_sm,
                Some(spill.base(sm)),
                spill.chunks,
            );
            let queues = (cfg.mode.kind == ModeKind::Queues).then(|| QueueSetup {
                features: cfg.controller_features(),
                ray_base: records + (nsms + sm) as u64 * per_sm,
            });
            let port = RtPort::new(
                &cfg.hw,
                params,
                bvh,
                TraversalOrder::TreeletContinue,
                queues,
            )
            .map_err(|source| SimError::Rt { sm, source })?;
            let prefetch = match cfg.mode.kind {
                ModeKind::Baseline => false,
                ModeKind::Prefetch => true,
                ModeKind::Queues => cfg.mode.preload,
            };
            Ok::<_, SimError>(if prefetch {
                port.with_prefetcher(Prefetcher::new(bvh, cfg.mode.prefetch_threshold))
            } else {
                port
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut rts = rts;
    if let Some((sm, cycles)) = options.record_tables {
        if !rts.get_mut(sm).is_some_and(|rt| rt.record_tables(cycles)) {
            return Err(SimError::Setup(format!(
                "cannot record the tables of SM {sm}: it needs mode.kind = \"queues\" and an SM \
                 below gpu.sms = {nsms}"
            )));
        }
    }
    let sm = |_| {
        let sm = Sm::new(cta_slots, warps_per_cta);
        if cfg.mode.virtualization {
            sm.with_virtualization(cfg.hw.max_rays as u64, cfg.gpu.threads_per_cta as u64)
        } else {
            sm
        }
    };
    let mut gpu = Gpu {
        scene,
        cfg,
        settings,
        frame,
        timing: ShaderTiming::new(&cfg.gpu),
        options,
        scheduler,
        sms: (0..nsms).map(sm).collect(),
        rts,
        states: (0..nsms)
            .map(|_| CtaStatePort::new(state_base, cfg.cta_state_bytes()))
            .collect(),
        state_loads: Vec::new(),
        mem: MemorySystem::new(&cfg.memory, nsms)?,
        wake: vec![0; nsms],
        awake: Vec::with_capacity(nsms),
        watchdog: Watchdog::new(cfg.sim.watchdog_cycles),
        image: vec![Vec3::ZERO; settings.pixels()],
        nonfinite: 0,
        ray_log: Vec::new(),
        rays_hit: 0,
        time_series: Vec::new(),
        next_sample: cfg.sim.sample_interval,
        last_sample_loads: (0, 0),
        pixels_done: 0,
        stepped: 0,
    };
    let start = Instant::now();
    let cycles = gpu.run(progress)?;
    let wall = start.elapsed().as_secs_f64();
    let table_log = options
        .record_tables
        .and_then(|(sm, _)| gpu.rts[sm].take_table_log());
    let mut out = gpu.finish(cycles, wall, config_toml, bvh, spill.chunks);
    out.table_log = table_log;
    Ok(out)
}

/// Where the RT units' traversal stacks spill: each SM's area holds `chunks` 32 B chunks for
/// each of the two stacks of each of its `hw.max_rays` ray ids, the areas one after another
/// from `start`.
#[derive(Debug, Clone, Copy)]
struct SpillLayout {
    /// First byte of SM 0's area.
    start: u64,
    /// Bytes of one SM's area.
    per_sm: u64,
    /// Chunks per ray stack.
    chunks: u32,
}

impl SpillLayout {
    /// Chunks per ray stack never need to exceed this: a chunk holds at least one entry, and a
    /// ray's stack holds at most (width - 1) x depth + 1 entries of its current treelet plus
    /// one per treelet root (only treelet roots go on the other stack, each at most once).
    fn needed(bvh: &HwBvh) -> u64 {
        let s = bvh.stats();
        (bvh.params().width as u64 - 1) * s.depth as u64 + 1 + s.treelets as u64
    }

    /// The layout after everything else (from `start`): as many chunks per ray stack as fit the
    /// `hw.address_bits` address space, but no more than [`SpillLayout::needed`] and 2^20.
    fn new(cfg: &SimConfig, bvh: &HwBvh, start: u64) -> Result<Self, SimError> {
        let stacks = cfg.gpu.sms as u64 * cfg.hw.max_rays as u64 * 2;
        let top = 1u64 << cfg.hw.address_bits;
        let room = top.saturating_sub(start) / (stacks * CHUNK_BYTES as u64);
        let chunks = Self::needed(bvh).min(1 << 20).min(room);
        if chunks == 0 {
            return Err(SimError::Setup(format!(
                "no room for the traversal stacks' spill areas: the BVH, records and CTA state \
                 end at byte {start} of the {}-bit address space; raise hw.address_bits",
                cfg.hw.address_bits
            )));
        }
        Ok(SpillLayout {
            start,
            per_sm: cfg.hw.max_rays as u64 * 2 * chunks * CHUNK_BYTES as u64,
            chunks: chunks as u32,
        })
    }

    /// First byte of SM `sm`'s area.
    fn base(&self, sm: usize) -> u64 {
        self.start + sm as u64 * self.per_sm
    }
}

impl Gpu<'_> {
    /// Runs to the end; returns the cycle count.
    fn run(&mut self, progress: Option<&indicatif::ProgressBar>) -> Result<u64, SimError> {
        let mut now = 0u64;
        loop {
            self.cycle(now)?;
            self.stepped += 1;
            if let Some(bar) = progress {
                bar.set_position(self.pixels_done);
            }
            if self.finished() {
                for rt in &mut self.rts {
                    rt.catch_up(now + 1);
                }
                return Ok(now + 1);
            }
            let next = if self.cfg.sim.lockstep {
                now + 1
            } else {
                self.next_event().unwrap_or(u64::MAX)
            };
            let next = next.min(self.watchdog.deadline());
            if self.watchdog.expired(next) {
                return Err(self.watchdog_error(next));
            }
            now = next;
        }
    }

    /// Whether every CTA has run and retired. (The SMs visited last are checked first: while
    /// CTAs run, one of them is usually busy.)
    fn finished(&self) -> bool {
        self.scheduler.pending() == 0
            && self.awake.iter().all(|&i| self.sms[i].is_idle())
            && self.sms.iter().all(Sm::is_idle)
    }

    /// One cycle: visits the SMs whose wake cycle has come (every SM in lockstep, or when the
    /// CTA dispatch runs), in index order, phase by phase, then records their next wake cycles.
    fn cycle(&mut self, now: u64) -> Result<(), SimError> {
        self.sample(now);
        let lockstep = self.cfg.sim.lockstep;
        // Which SMs are awake follows no pattern, so they are collected without a branch.
        let mut awake = std::mem::take(&mut self.awake);
        awake.resize(self.sms.len(), 0);
        let mut len = 0;
        for (i, &wake) in self.wake.iter().enumerate() {
            awake[len] = i;
            len += usize::from(lockstep || wake <= now);
        }
        awake.truncate(len);
        for &i in &awake {
            for cta in self.sms[i].run_timers(now) {
                self.states[i].save(cta);
            }
        }
        // An SM not visited could not dispatch after its last visit (its wake cycle would be
        // the next one), and nothing but a visit or the dispatch changes that.
        let pending = self.scheduler.pending() > 0;
        if awake.iter().any(|&i| self.sms[i].can_dispatch(pending)) {
            self.dispatch(now);
            // It may have launched or resumed a CTA on any SM.
            awake.clear();
            awake.extend(0..self.sms.len());
        }
        for &i in &awake {
            self.rts[i].collect_responses(now, i, &mut self.mem, &mut self.state_loads);
            self.resume_loaded(now, i);
        }
        for &i in &awake {
            self.step_rt(now, i, lockstep)?;
        }
        for &i in &awake {
            match self.states[i].send(now, i, &mut self.mem)? {
                StateSend::Idle => {}
                StateSend::Accepted => self.watchdog.progress(now),
                StateSend::Saved(id) => {
                    self.watchdog.progress(now);
                    self.sms[i].state_saved(id);
                }
            }
        }
        let pending = self.scheduler.pending() > 0;
        for &i in &awake {
            self.wake[i] = self.wake_cycle(now, i, pending);
        }
        debug_assert!(
            (0..self.sms.len())
                .all(|i| self.wake[i] <= now + 1 || self.quiet(self.wake[i] - 1, i, pending)),
            "after cycle {now}, an SM has work before its wake cycle"
        );
        self.awake = awake;
        Ok(())
    }

    /// SM `sm`'s RT unit in cycle `now`: offered the SM's first ready warp, stepped if it has
    /// work (always in `lockstep`), and its memory request offered to the L1.
    fn step_rt(&mut self, now: u64, sm: usize, lockstep: bool) -> Result<(), SimError> {
        let head = if self.rts[sm].issue_ready() {
            self.sms[sm].peek_ready()
        } else {
            None
        };
        if lockstep || self.rts[sm].busy_at(now, head.is_some()) {
            let rays: Vec<Option<Ray>> = head
                .and_then(|w| self.sms[sm].warp(w))
                .map(|w| {
                    w.threads
                        .iter()
                        .map(|t| t.as_ref().map(PathThread::ray))
                        .collect()
                })
                .unwrap_or_default();
            let out = self.rts[sm]
                .step(now, sm, head.map(|w| (w, rays.as_slice())))
                .map_err(|e| self.locate(sm, e))?;
            if out.accepted.is_some() {
                self.sms[sm].issue_ready();
            }
            if let Some(done) = out.done {
                self.watchdog.progress(now);
                if let Some(done) = self.sms[sm].traversal_done(done) {
                    self.shade(now, sm, done);
                }
            }
        }
        // Idle RT units are caught up lazily when next stepped.
        if self.rts[sm].send(now, sm, &mut self.mem)? {
            self.watchdog.progress(now);
        }
        Ok(())
    }

    /// Adds the pixel of the ray an RT-unit error of SM `sm` names (from its SM warp and lane).
    fn locate(&self, sm: usize, mut e: SimError) -> SimError {
        if let SimError::RtUnit { fault, .. } = &mut e {
            if let Some((w, l)) = fault.owner {
                let thread = self.sms[sm]
                    .warp(w)
                    .and_then(|warp| warp.threads.get(l as usize))
                    .and_then(|t| t.as_ref());
                let width = self.settings.width.max(1);
                fault.pixel = thread.map(|t| (t.pixel() % width, t.pixel() / width));
            }
        }
        e
    }

    /// Takes SM `sm`'s CTA-state load responses; a CTA whose state is back runs again and
    /// shades the traversals its warps completed while it was suspended.
    fn resume_loaded(&mut self, now: u64, sm: usize) {
        let mut loads = std::mem::take(&mut self.state_loads);
        for r in loads.drain(..) {
            if let Some(id) = self.states[sm].loaded(&r) {
                for done in self.sms[sm].state_restored(id) {
                    self.shade(now, sm, done);
                }
            }
        }
        self.state_loads = loads;
    }

    /// Resumes CTAs ready to resume (their state loads are queued), then hands pending CTAs to
    /// the slots left; new CTAs' warps trace after launch and raygen.
    fn dispatch(&mut self, now: u64) {
        for (sm, states) in self.sms.iter_mut().zip(&mut self.states) {
            for cta in sm.resume() {
                states.restore(cta);
            }
        }
        if self.scheduler.pending() == 0 {
            return;
        }
        let mut free: Vec<u32> = self.sms.iter().map(Sm::launchable).collect();
        let start = now + self.cfg.gpu.cta_launch_cycles as u64 + self.timing.raygen;
        let warp_size = self.cfg.gpu.warp_size as usize;
        for (sm, cta) in self.scheduler.dispatch(&mut free) {
            let pixels = self.scheduler.pixels(cta);
            let warps = pixels
                .chunks(warp_size)
                .map(|chunk| {
                    chunk
                        .iter()
                        .map(|p| p.map(|p| PathThread::new(&self.frame, &self.settings, p)))
                        .collect()
                })
                .collect();
            self.sms[sm].launch(cta, warps, start);
        }
    }

    /// Runs the hit / miss shaders of a traced warp (of a running CTA) and schedules its next
    /// trace or its end.
    fn shade(&mut self, now: u64, sm: usize, done: TracedWarp) {
        let Some(warp) = self.sms[sm].warp_mut(done.warp) else {
            return;
        };
        let (mut any_hit, mut any_miss, mut again) = (false, false, false);
        let mut finished = 0;
        for (thread, hit) in warp.threads.iter_mut().zip(&done.hits) {
            let (Some(t), Some(hit)) = (thread.as_mut(), hit) else {
                continue;
            };
            if self.options.record_rays {
                self.ray_log.push(TracedRay {
                    pixel: t.pixel(),
                    ray: t.ray(),
                    hit: *hit,
                });
            }
            any_hit |= hit.is_some();
            any_miss |= hit.is_none();
            self.rays_hit += u64::from(hit.is_some());
            match t.on_hit(self.scene, &self.frame, &self.settings, *hit) {
                ThreadStep::Trace => again = true,
                ThreadStep::Finished {
                    pixel,
                    color,
                    nonfinite,
                } => {
                    self.image[pixel as usize] = color;
                    self.nonfinite += nonfinite;
                    self.pixels_done += 1;
                    finished += 1;
                    *thread = None;
                }
            }
        }
        let until = now + self.timing.after_trace(any_hit, any_miss, again);
        self.sms[sm].start_shading(done.warp, until, !again, finished);
    }

    /// The next cycle with work for some SM (every SM's wake cycle is after the current one).
    fn next_event(&self) -> Option<u64> {
        self.wake.iter().copied().min().filter(|&c| c != u64::MAX)
    }

    /// The next cycle after `now` at which SM `sm` has work if nothing but its own visits
    /// changes it (`u64::MAX`: none): room for the CTA dispatch (with CTAs `pending` or ready
    /// to resume) or a warp it can offer its RT unit (the next cycle), a shader timer, a memory
    /// response, or work of its RT unit or CTA-state port.
    fn wake_cycle(&self, now: u64, sm: usize, pending: bool) -> u64 {
        let soon = now + 1;
        let (s, rt) = (&self.sms[sm], &self.rts[sm]);
        if s.can_dispatch(pending) || (s.peek_ready().is_some() && rt.issue_ready()) {
            return soon;
        }
        let mut wake = u64::MAX;
        if let Some(c) = s.next_timer() {
            wake = c;
        }
        if let Some(c) = self.mem.next_response(sm) {
            wake = wake.min(c);
        }
        wake = wake.max(soon);
        if let Some(c) = rt.next_event(now) {
            wake = wake.min(c);
        }
        if let Some(c) = self.states[sm].next_event(now) {
            wake = wake.min(c);
        }
        wake
    }

    /// Whether visiting SM `sm` in cycle `now` (`now > 0`; CTAs `pending`) would do nothing if
    /// nothing changes it meanwhile. Debug builds check after every cycle that each SM is quiet
    /// until its wake cycle (the components' answers only grow with `now`, so checking the
    /// cycle before it suffices).
    fn quiet(&self, now: u64, sm: usize, pending: bool) -> bool {
        let (s, rt) = (&self.sms[sm], &self.rts[sm]);
        let before = now.saturating_sub(1);
        s.next_timer().is_none_or(|c| c > now)
            && self.mem.next_response(sm).is_none_or(|c| c > now)
            && !s.can_dispatch(pending)
            && !(s.peek_ready().is_some() && rt.issue_ready())
            && !rt.busy_at(now, false)
            && rt.next_event(before).is_none_or(|c| c > now)
            && self.states[sm].next_event(before).is_none_or(|c| c > now)
    }

    /// Records the time-series samples due at the start of cycle `now`.
    fn sample(&mut self, now: u64) {
        let interval = self.cfg.sim.sample_interval;
        if interval == 0 {
            return;
        }
        while self.next_sample <= now {
            let bvh = self.mem.stats().bvh;
            let (loads, misses) = (
                bvh.l1_loads - self.last_sample_loads.0,
                bvh.l1_misses - self.last_sample_loads.1,
            );
            self.last_sample_loads = (bvh.l1_loads, bvh.l1_misses);
            self.time_series.push(Sample {
                cycle: self.next_sample,
                bvh_l1_accesses: loads,
                bvh_l1_misses: misses,
                bvh_l1_miss_rate: ratio(misses, loads),
                active_rays: self.rts.iter().map(RtPort::active_rays).sum(),
            });
            self.next_sample += interval;
        }
    }

    /// The watchdog's error with every component's state.
    fn watchdog_error(&self, cycle: u64) -> SimError {
        let mut dump = format!(
            "CTA scheduler: {} of {} CTAs not dispatched\n",
            self.scheduler.pending(),
            self.scheduler.total()
        );
        for (i, ((sm, rt), states)) in self.sms.iter().zip(&self.rts).zip(&self.states).enumerate()
        {
            dump += &format!("SM {i}: {}\n  {}\n", sm.debug_state(), rt.debug_state());
            if self.cfg.mode.virtualization {
                dump += &format!("  {}\n", states.debug_state());
            }
        }
        dump += &self.mem.debug_state(cycle);
        SimError::Watchdog {
            cycle,
            last_progress: self.watchdog.last_progress(),
            dump,
        }
    }

    /// The statistics and image of a finished run.
    fn finish(
        self,
        cycles: u64,
        wall: f64,
        config: String,
        bvh: &HwBvh,
        stack_spill_chunks: u32,
    ) -> SimOutput {
        let mut rt = RtTotals::default();
        for port in &self.rts {
            rt.add(port.hw_stats());
        }
        let mem = self.mem.stats();
        let rays_issued: u64 = self.rts.iter().map(|r| r.rays_issued).sum();
        let rays_completed: u64 = self.rts.iter().map(|r| r.rays_completed).sum();
        let l2_misses = AccessClass::ALL
            .iter()
            .map(|&c| mem.class(c).l2_misses)
            .sum();
        let mut units = vec![
            "cta_scheduler",
            "sm",
            "shader",
            "rt_unit",
            "rt_datapath.box",
        ];
        if bvh.header().triangle_leaves > 0 {
            units.push("rt_datapath.triangle");
        }
        if bvh.has_procedural() {
            units.push("rt_datapath.procedural");
        }
        match self.cfg.mode.kind {
            ModeKind::Baseline => {}
            ModeKind::Prefetch => units.push("prefetcher"),
            ModeKind::Queues => {
                units.extend([
                    "treelet_controller",
                    "treelet_count_table",
                    "treelet_queue_table",
                ]);
                if self.cfg.mode.preload {
                    units.push("treelet_preloader");
                }
            }
        }
        if self.cfg.mode.virtualization {
            units.push("virtualization");
        }
        units.extend(["memory.l1", "memory.l2", "memory.dram"]);
        let warp_size = self.cfg.hw.warp_size;
        let simt = ratio(rt.active_thread_cycles, rt.warp_cycles * warp_size as u64);
        let queues: Vec<&QueueObserver> = self.rts.iter().filter_map(RtPort::queue_stats).collect();
        let phases = if queues.is_empty() {
            Phases {
                ray_stationary: PhaseStats {
                    cycles,
                    intersection_tests: rt.total_tests(),
                },
                ..Phases::default()
            }
        } else {
            // Cycles: each SM's controller time per mode, averaged over the SMs.
            let n = queues.len() as u64;
            let phase = |f: &dyn Fn(&QueueObserver) -> (u64, u64)| {
                let (c, t) = queues
                    .iter()
                    .map(|q| f(q))
                    .fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
                PhaseStats {
                    cycles: c / n,
                    intersection_tests: t,
                }
            };
            Phases {
                initial: phase(&|q| (q.counts.ctl.cycles_initial, q.tests[0])),
                treelet_stationary: phase(&|q| (q.counts.ctl.cycles_treelet, q.tests[1])),
                ray_stationary: phase(&|q| (q.counts.ctl.cycles_final, q.tests[2])),
            }
        };
        let stats = SimStats {
            scene: self.scene.name.clone(),
            mode: self.cfg.mode.kind.name().to_string(),
            cycles,
            rays: rays_completed,
            rays_issued,
            rays_completed,
            rays_hit: self.rays_hit,
            ctas: self.sms.iter().map(|s| s.ctas_done).sum(),
            simt_efficiency: simt,
            bvh_l1_accesses: mem.bvh.l1_loads,
            bvh_l1_misses: mem.bvh.l1_misses,
            bvh_l1_merges: mem.bvh.l1_merges,
            bvh_l1_miss_rate: ratio(mem.bvh.l1_misses, mem.bvh.l1_loads),
            l2_misses,
            dram_bytes: mem.dram.read_bytes + mem.dram.write_bytes,
            phases,
            max_queues: queues.iter().map(|q| q.max_queues).max().unwrap_or(0),
            max_queues_above_threshold: queues
                .iter()
                .map(|q| q.max_queues_above_threshold)
                .max()
                .unwrap_or(0),
            count_table_evictions: queues.iter().map(|q| q.counts.ctl.evictions).sum(),
            queue_table_spills: queues.iter().map(|q| q.counts.spills).sum(),
            cta_suspends: self.sms.iter().map(|s| s.suspends).sum(),
            cta_resumes: self.sms.iter().map(|s| s.resumes).sum(),
            max_rays_in_flight: self.sms.iter().map(|s| s.max_in_flight).max().unwrap_or(0),
            stack_spill_chunks: stack_spill_chunks as u64,
            rt,
            max_access_queue: self.rts.iter().map(|r| r.max_queue).max().unwrap_or(0),
            queues: queues.iter().fold(QueueTotals::default(), |mut t, q| {
                t.add(&q.counts);
                t
            }),
            prefetches_issued: mem.prefetch.issued,
            prefetches_used: mem.prefetch.used,
            prefetches_unused_evicted: mem.prefetch.evicted_unused,
            memory: mem,
            time_series_samples: self.time_series.len() as u64,
            active_units: units.into_iter().map(String::from).collect(),
            config,
            stepped_cycles: self.stepped,
            sim_wall_seconds: wall,
            simulated_rays_per_second: rays_completed as f64 / wall.max(1e-9),
        };
        SimOutput {
            stats,
            image: self.image,
            nonfinite_samples: self.nonfinite,
            time_series: self.time_series,
            ray_log: self.ray_log,
            table_log: None,
        }
    }
}

/// `num / den`, 0 when `den` is 0.
fn ratio(num: u64, den: u64) -> f64 {
    if den == 0 {
        0.0
    } else {
        num as f64 / den as f64
    }
}
