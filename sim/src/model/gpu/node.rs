//! One SM of the simulated GPU as the engine steps it ([`SmNode`]): its CTA and warp slots
//! ([`Sm`]), its RT unit ([`RtPort`]), its CTA-state port and its L1 ([`L1Port`]), with what it
//! produces for the whole run (pixels, statistics, time-series contributions).
//!
//! A node visits its own cycles in order: at each cycle it has work (its *wake* cycle, or
//! every cycle in lockstep) it runs, in the order of the serial cycle loop: time-series samples
//! due, shader timers (warps become ready to trace or end; CTAs retire or start suspending),
//! CTAs ready to resume into free slots, memory responses into the RT unit and CTA-state loads
//! (a CTA whose state is back shades the hits its warps received while suspended), one step of
//! the RT unit with its memory request to the L1, one CTA-state access, and its next wake
//! cycle. Between synchronisation points a node needs nothing from the other SMs: L2 results
//! come back one L2 round trip after acceptance at the earliest ([`crate::model::memory::l1`]). It
//! stops early ([`Halt`]) where it needs the engine: when it could take a new CTA from the CTA
//! scheduler, and, once it is idle for good, before each remaining visit (only the engine
//! knows whether the run has ended by then).

use glam::Vec3;

use crate::model::bvh::HwBvh;
use crate::model::config::SimConfig;
use crate::model::gpu::error::SimError;
use crate::model::gpu::l2_partitions::PartitionJobs;
use crate::model::gpu::output::TracedRay;
use crate::model::gpu::rt::{RtPort, TracedWarp};
use crate::model::gpu::shader::{FinishedPixel, PathThread, ShaderTiming, ThreadStep};
use crate::model::gpu::sm::{CtaRef, Resumed, Sm};
use crate::model::gpu::virtualization::{CtaStatePort, StateSend};
use crate::model::memory::{L1Port, Response};
use crate::model::scene::Scene;
use crate::model::workload::camera::CameraFrame;
use crate::model::workload::kind::{Sampler, TraceRay, Workload};
use crate::model::workload::pathtracer::RenderSettings;

/// Phase of a cycle in which the RT unit's port offers its memory request.
pub const PHASE_RT: u8 = 0;

/// Phase of a cycle in which the CTA-state port offers its access (after every RT unit's).
pub const PHASE_STATE: u8 = 1;

/// What every node reads and nobody writes during a run.
#[derive(Debug, Clone)]
pub struct Ctx<'a> {
    /// The scene (materials for shading).
    pub scene: &'a Scene,
    /// The configuration.
    pub cfg: &'a SimConfig,
    /// The workload's image size and limits.
    pub settings: RenderSettings,
    /// The camera.
    pub frame: CameraFrame,
    /// The workload resolved for the scene (which rays each sample traces).
    pub workload: Workload,
    /// The BVH as the functional tracer that gives a hybrid frame's primary hits (untimed, as
    /// a rasterizer's G-buffer).
    pub raster: &'a HwBvh,
    /// Shader timing.
    pub timing: ShaderTiming,
    /// Record every traced ray.
    pub record_rays: bool,
    /// Time the node's visits ([`SmNode::stretches`]) for the parallelism report.
    pub profile: bool,
}

impl Ctx<'_> {
    /// What the raygen threads start and answer their samples with.
    pub fn sampler(&self) -> Sampler<'_> {
        Sampler {
            scene: self.scene,
            workload: &self.workload,
            frame: &self.frame,
            settings: &self.settings,
            raster: self.raster,
        }
    }
}

/// Adds a finished pixel to a node's pixels and non-finite sample count.
fn record_pixel((pixels, nonfinite): (&mut Vec<(u32, Vec3)>, &mut u64), done: FinishedPixel) {
    pixels.push((done.pixel, done.color));
    *nonfinite += done.nonfinite;
}

/// Why a node stopped for the coordinator ([`crate::model::gpu::coordinator`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HaltKind {
    /// It has room for a new CTA and CTAs are pending: the CTA scheduler hands them out (its
    /// visit of the cycle is half done: samples, timers and resumes ran).
    Dispatch,
    /// It is idle for good and has work at this cycle (a prefetch, a late response): the visit
    /// happens only if the run has not ended before this cycle.
    Drain,
}

/// Where and why a node stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Halt {
    /// The cycle of the visit.
    pub cycle: u64,
    /// Why.
    pub kind: HaltKind,
}

/// Time-series contribution of one node at one sample cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct NodeSample {
    /// BVH demand loads of this SM's L1 so far.
    pub bvh_l1_loads: u64,
    /// ... that missed.
    pub bvh_l1_misses: u64,
    /// Rays traversing in its RT unit.
    pub active_rays: u64,
    /// L1 prefetches (treelet preloads and prefetcher requests) accepted so far.
    pub prefetches: u64,
    /// ... that missed the L1 and fetched their sector.
    pub prefetch_misses: u64,
    /// RT-unit warp cycles before the sample's boundary.
    pub warp_cycles: u64,
    /// Traversing lanes summed over them.
    pub active_thread_cycles: u64,
}

/// One SM with its RT unit, CTA-state port and L1, and what it produced.
#[derive(Debug)]
pub struct SmNode<'a> {
    /// SM index.
    pub index: usize,
    /// CTA and warp slots.
    pub sm: Sm,
    /// The RT unit with its memory queues.
    pub rt: RtPort<'a>,
    /// Ray virtualization's CTA-state traffic.
    pub states: CtaStatePort,
    /// The SM's L1 side of the memory hierarchy.
    pub mem: L1Port,
    /// CTA-state load responses of the visit (reused buffer).
    state_loads: Vec<Response>,
    /// The next cycle with work (`u64::MAX`: none) if nothing but its own visits changes it.
    pub wake: u64,
    /// The next cycle to visit (its wake cycle; in lockstep every cycle).
    pub next: u64,
    /// Where it stopped for the coordinator, if it did.
    pub halt: Option<Halt>,
    /// The cycle of the visit after which it held no CTA (resident or suspended), while it
    /// holds none.
    pub idle_since: Option<u64>,
    /// The first error, with its cycle.
    pub error: Option<(u64, SimError)>,
    /// Visits made.
    pub visits: u64,
    /// The last cycle with progress (a ray completed, a request or CTA-state access accepted).
    pub last_progress: u64,
    /// Finished pixels and their radiance.
    pub pixels: Vec<(u32, Vec3)>,
    /// Samples whose radiance was not finite.
    pub nonfinite: u64,
    /// Rays that hit something.
    pub rays_hit: u64,
    /// Occlusion rays shaded.
    pub occlusion_rays: u64,
    /// Traced rays with their order key (cycle, phase, SM, sequence), with
    /// [`Ctx::record_rays`].
    pub ray_log: Vec<((u64, u8, usize, u64), TracedRay)>,
    /// Its time-series contributions, one per sample cycle so far.
    pub samples: Vec<NodeSample>,
    /// With [`Ctx::profile`]: per stretch of visits the engine ran, its first cycle, the cycle
    /// it reached and its CPU time in nanoseconds.
    pub stretches: Vec<(u64, u64, u64)>,
    /// The number of its next L2 operation to post to the memory partitions.
    pub posted: u64,
}

impl<'a> SmNode<'a> {
    /// SM `index` with its parts.
    pub fn new(index: usize, sm: Sm, rt: RtPort<'a>, states: CtaStatePort, mem: L1Port) -> Self {
        SmNode {
            index,
            sm,
            rt,
            states,
            mem,
            state_loads: Vec::new(),
            wake: 0,
            next: 0,
            halt: None,
            idle_since: Some(0),
            error: None,
            visits: 0,
            last_progress: 0,
            pixels: Vec::new(),
            nonfinite: 0,
            rays_hit: 0,
            occlusion_rays: 0,
            ray_log: Vec::new(),
            samples: Vec::new(),
            stretches: Vec::new(),
            posted: 0,
        }
    }

    /// Records a pixel whose samples have all ended (its thread's last trace shaded, or, for a
    /// thread that traces nothing, its CTA launched).
    pub fn finish_pixel(&mut self, done: FinishedPixel) {
        record_pixel((&mut self.pixels, &mut self.nonfinite), done);
    }

    /// Whether the node is idle for good: it holds no CTA and none is pending.
    fn retired(&self, pending: bool) -> bool {
        !pending && self.idle_since.is_some()
    }

    /// Visits the node's cycles before `end` and before its L1 port's horizon (CTAs `pending`
    /// at the CTA scheduler), first finishing the visit it halted in if the engine let it go
    /// on; stops at a halt, an error or the bound. (Time-series samples are recorded at the
    /// next visit or at the end: nothing they count changes in between.)
    pub fn run(&mut self, ctx: &Ctx, end: u64, pending: bool) {
        if let Some(halt) = self.halt.take() {
            let done = match halt.kind {
                HaltKind::Dispatch => self.back(ctx, halt.cycle, pending),
                HaltKind::Drain => self.visit(ctx, halt.cycle, pending, true),
            };
            if !done {
                return;
            }
        }
        while self.error.is_none() && self.halt.is_none() && self.next < end.min(self.mem.horizon())
        {
            let t = self.next;
            if !self.visit(ctx, t, pending, false) {
                return;
            }
        }
    }

    /// One visit at cycle `t`; false when it halted or failed. A node idle for good halts
    /// before the visit unless `drain_ok` (the engine knows the run goes on past `t`).
    fn visit(&mut self, ctx: &Ctx, t: u64, pending: bool, drain_ok: bool) -> bool {
        if self.retired(pending) && !drain_ok {
            self.halt = Some(Halt {
                cycle: t,
                kind: HaltKind::Drain,
            });
            return false;
        }
        self.visits += 1;
        self.record_samples(ctx.cfg, t);
        for cta in self.sm.run_timers(t) {
            self.suspend(ctx, cta, t);
        }
        for r in self.sm.resume(t) {
            match r {
                Resumed::Load(cta) => self.states.restore(cta),
                Resumed::Loading(_) => {}
                Resumed::Run(warps) => {
                    for done in warps {
                        self.shade(ctx, t, 0, done);
                    }
                }
            }
        }
        if pending && (self.sm.launchable() > 0 || self.sm.suspend_wanted(true)) {
            self.halt = Some(Halt {
                cycle: t,
                kind: HaltKind::Dispatch,
            });
            return false;
        }
        self.back(ctx, t, pending)
    }

    /// CTA `cta` starts suspending at cycle `t`: its state is queued for storing, or, without
    /// state traffic, it leaves its slot at once.
    fn suspend(&mut self, ctx: &Ctx, cta: CtaRef, t: u64) {
        if ctx.cfg.virtualization.state_traffic {
            self.states.save(cta);
        } else {
            self.sm.state_saved(cta.id, t);
        }
    }

    /// The rest of the visit at cycle `t` after the CTA dispatch (`pending` is exact here):
    /// CTAs suspended for wanted slots, responses, the RT unit, the CTA-state port, the next
    /// wake cycle. False when it failed.
    fn back(&mut self, ctx: &Ctx, t: u64, pending: bool) -> bool {
        for cta in self.sm.suspend_on_demand(pending, t) {
            self.suspend(ctx, cta, t);
        }
        self.rt
            .collect_responses(t, &mut self.mem, &mut self.state_loads);
        self.resume_loaded(ctx, t);
        if let Err(e) = self.step_rt(ctx, t) {
            self.error = Some((t, e));
            return false;
        }
        match self.states.send(t, PHASE_STATE, &mut self.mem) {
            Ok(StateSend::Idle) => {}
            Ok(StateSend::Accepted) => self.last_progress = t,
            Ok(StateSend::Saved(id)) => {
                self.last_progress = t;
                self.sm.state_saved(id, t);
            }
            Err(e) => {
                self.error = Some((t, e));
                return false;
            }
        }
        for cta in self.sm.take_to_load() {
            self.states.restore(cta);
        }
        self.wake = self.wake_cycle(t, pending);
        debug_assert!(
            self.wake <= t + 1 || self.quiet(self.wake - 1, pending),
            "SM {} has work before its wake cycle {} (after cycle {t})",
            self.index,
            self.wake
        );
        self.idle_since = match self.idle_since {
            Some(c) if self.sm.is_idle() => Some(c),
            _ if self.sm.is_idle() => Some(t),
            _ => None,
        };
        self.next = if ctx.cfg.sim.lockstep && !self.retired(pending) {
            t + 1
        } else {
            self.wake
        };
        true
    }

    /// Takes the L2 results the memory partitions left for it ([`PartitionJobs::results_for`])
    /// and settles its oldest operations that have them: the L1 port's placeholders, deferred
    /// stalls' retry cycles, and its next visit (new responses are queued now). Not while
    /// halted. Settling as soon as results arrive gives the same results as settling just
    /// before they are needed ([`crate::model::memory::l1`]).
    pub fn absorb(&mut self, l2: &PartitionJobs, lockstep: bool, pending: bool) {
        debug_assert!(self.halt.is_none(), "a halted node absorbs nothing");
        let before = self.mem.horizon();
        let mem = &mut self.mem;
        l2.results_for(self.index, |k, result| mem.set_result(k, result));
        if self.mem.settle() == 0 {
            return;
        }
        self.rt.settle_retries(&self.mem);
        // Every visit before `from` is done and the new responses are at or after it.
        let from = self.next.min(before);
        self.wake = self.wake_cycle(from.saturating_sub(1), pending);
        self.next = if lockstep && !self.retired(pending) {
            self.next
        } else {
            self.wake
        };
    }

    /// Records this node's time-series contribution at every sample cycle up to `t`: its state
    /// at the start of cycle `t` (nothing changed it since its last visit).
    fn record_samples(&mut self, cfg: &SimConfig, t: u64) {
        let interval = cfg.sim.sample_interval;
        if interval == 0 {
            return;
        }
        let due = t / interval;
        if self.samples.len() as u64 >= due {
            return;
        }
        let stats = self.mem.stats();
        let active_rays = self.rt.active_rays();
        // Every sample this visit records: the L1's counters do not change between visits;
        // the RT unit's warp cycles do (idle cycles it has not caught up yet), so each sample
        // takes them at its own boundary, as a lockstep run would.
        while (self.samples.len() as u64) < due {
            let boundary = (self.samples.len() as u64 + 1) * interval;
            let (warp_cycles, active_thread_cycles) = self.rt.warp_counters_until(boundary);
            self.samples.push(NodeSample {
                bvh_l1_loads: stats.bvh.l1_loads,
                bvh_l1_misses: stats.bvh.l1_misses,
                active_rays,
                prefetches: stats.prefetch.requests,
                prefetch_misses: stats.prefetch.issued,
                warp_cycles,
                active_thread_cycles,
            });
        }
    }

    /// Fills in the samples up to cycle `t` at the end of the run.
    pub fn finish_samples(&mut self, cfg: &SimConfig, t: u64) {
        self.record_samples(cfg, t);
    }

    /// The RT unit in cycle `now`: offered the SM's first ready warp, stepped if it has work
    /// (always in lockstep), and its memory request offered to the L1.
    fn step_rt(&mut self, ctx: &Ctx, now: u64) -> Result<(), SimError> {
        let head = if self.rt.issue_ready() {
            self.sm.peek_ready()
        } else {
            None
        };
        if ctx.cfg.sim.lockstep || self.rt.busy_at(now, head.is_some()) {
            let rays: Vec<Option<TraceRay>> = head
                .and_then(|w| self.sm.warp(w))
                .map(|w| {
                    w.threads
                        .iter()
                        .map(|t| t.as_ref().map(PathThread::trace_ray))
                        .collect()
                })
                .unwrap_or_default();
            let out = self
                .rt
                .step(now, self.index, head.map(|w| (w, rays.as_slice())))
                .map_err(|e| self.locate(ctx, e))?;
            if out.accepted.is_some() {
                self.sm.issue_ready();
            }
            if let Some(done) = out.done {
                self.last_progress = now;
                if let Some(done) = self.sm.traversal_done(done, now) {
                    self.shade(ctx, now, 1, done);
                }
            }
        }
        // Idle RT units are caught up lazily when next stepped.
        if self.rt.send(now, PHASE_RT, &mut self.mem)? {
            self.last_progress = now;
        }
        Ok(())
    }

    /// Adds the pixel of the ray an RT-unit error names (from its SM warp and lane).
    fn locate(&self, ctx: &Ctx, mut e: SimError) -> SimError {
        if let SimError::RtUnit { fault, .. } = &mut e {
            if let Some((w, l)) = fault.owner {
                let thread = self
                    .sm
                    .warp(w)
                    .and_then(|warp| warp.threads.get(l as usize))
                    .and_then(|t| t.as_ref());
                let width = ctx.settings.width.max(1);
                fault.pixel = thread.map(|t| (t.pixel() % width, t.pixel() / width));
            }
        }
        e
    }

    /// Takes the CTA-state load responses; a CTA whose state is back runs again and shades
    /// the traversals its warps completed while it was suspended.
    fn resume_loaded(&mut self, ctx: &Ctx, now: u64) {
        let mut loads = std::mem::take(&mut self.state_loads);
        for r in loads.drain(..) {
            if let Some(id) = self.states.loaded(&r) {
                for done in self.sm.state_restored(id, now) {
                    self.shade(ctx, now, 0, done);
                }
            }
        }
        self.state_loads = loads;
    }

    /// Runs the hit / miss shaders of a traced warp (of a running CTA) in phase `phase` of
    /// cycle `now` and schedules its next trace or its end.
    fn shade(&mut self, ctx: &Ctx, now: u64, phase: u8, done: TracedWarp) {
        let Some(warp) = self.sm.warp_mut(done.warp) else {
            return;
        };
        let (mut any_hit, mut any_miss, mut again) = (false, false, false);
        let mut finished = 0;
        let sampler = ctx.sampler();
        for (thread, hit) in warp.threads.iter_mut().zip(&done.hits) {
            let (Some(t), Some(hit)) = (thread.as_mut(), hit) else {
                continue;
            };
            if ctx.record_rays {
                let key = (now, phase, self.index, self.ray_log.len() as u64);
                self.ray_log.push((
                    key,
                    TracedRay {
                        pixel: t.pixel(),
                        ray: t.ray(),
                        occlusion: t.trace_ray().occlusion,
                        hit: *hit,
                    },
                ));
            }
            any_hit |= hit.is_some();
            any_miss |= hit.is_none();
            self.rays_hit += u64::from(hit.is_some());
            self.occlusion_rays += u64::from(t.trace_ray().occlusion);
            match t.on_hit(&sampler, *hit) {
                ThreadStep::Trace => again = true,
                ThreadStep::Finished(done) => {
                    // `self.finish_pixel`, with `self.sm` borrowed.
                    record_pixel((&mut self.pixels, &mut self.nonfinite), done);
                    finished += 1;
                    *thread = None;
                }
            }
        }
        let until = now + ctx.timing.after_trace(any_hit, any_miss, again);
        self.sm.start_shading(done.warp, until, !again, finished);
    }

    /// The next cycle after `now` at which the node has work if nothing but its own visits
    /// changes it (`u64::MAX`: none): room for a CTA (with CTAs `pending`) or one ready to
    /// resume, or a warp it can offer its RT unit (the next cycle), a shader timer, a memory
    /// response, or work of its RT unit or CTA-state port.
    fn wake_cycle(&self, now: u64, pending: bool) -> u64 {
        let soon = now + 1;
        let (s, rt) = (&self.sm, &self.rt);
        if s.can_dispatch(pending) || (s.peek_ready().is_some() && rt.issue_ready()) {
            return soon;
        }
        let mut wake = u64::MAX;
        if let Some(c) = s.next_timer() {
            wake = c;
        }
        if let Some(c) = self.mem.next_response() {
            wake = wake.min(c);
        }
        wake = wake.max(soon);
        if let Some(c) = rt.next_event(now) {
            wake = wake.min(c);
        }
        if let Some(c) = self.states.next_event(now) {
            wake = wake.min(c);
        }
        wake
    }

    /// Whether visiting the node in cycle `now` (`now > 0`) would do nothing if nothing changes
    /// it meanwhile (debug builds check it before every wake cycle; the components' answers only
    /// grow with `now`, so checking the cycle before it suffices).
    fn quiet(&self, now: u64, pending: bool) -> bool {
        let (s, rt) = (&self.sm, &self.rt);
        let before = now.saturating_sub(1);
        s.next_timer().is_none_or(|c| c > now)
            && self.mem.next_response().is_none_or(|c| c > now)
            && !s.can_dispatch(pending)
            && !(s.peek_ready().is_some() && rt.issue_ready())
            && !rt.busy_at(now, false)
            && rt.next_event(before).is_none_or(|c| c > now)
            && self.states.next_event(before).is_none_or(|c| c > now)
    }

    /// A summary of the node's state, for the watchdog.
    pub fn debug_state(&self, virtualization: bool, now: u64) -> String {
        let mut out = format!(
            "SM {}: {}\n  {}\n",
            self.index,
            self.sm.debug_state(),
            self.rt.debug_state()
        );
        if virtualization {
            out += &format!("  {}\n", self.states.debug_state());
        }
        out += &format!("  {}\n", self.mem.debug_state(now));
        out
    }
}
