//! The cycle loop. The GPU is a set of SM nodes ([`SmNode`]: an SM with its RT unit, CTA-state
//! port and L1) around what they share: the CTA scheduler and the L2 with DRAM.
//!
//! # Windows
//! An SM affects another only through the L2 and the CTA scheduler. Every access reaches the L2
//! `l1_latency` cycles after its SM accepted it, in acceptance order, and no L2 result is needed
//! before one L2 round trip (`l1_latency + l2_latency`, 226 cycles by Table 1) after its
//! acceptance ([`crate::memory::l1`]). So the engine runs time in *windows* of at most one
//! round trip: within a window every node visits its own cycles independently — on any of
//! `threads` threads — while its L2 operations wait; at the end of the window the operations of
//! all nodes go to the L2's memory partitions ([`crate::gpu::l2_partitions`]), which apply them
//! at the start of the next window's first round, side by side, each in a fixed order (cycle,
//! phase, SM, sequence: [`crate::memory::L2Op::key`]) — exactly the order in which one loop
//! visiting every SM each cycle would have applied them, as partitions share no state — and the
//! nodes settle their results before they go on. The next window starts at the earliest cycle
//! any node has work (idle stretches are skipped whole), or where this one ended if a node
//! waits for an L2 result of it.
//!
//! Within a window a node stops ([`crate::gpu::node::Halt`]) where it needs the engine: when it
//! could take a new CTA (the scheduler hands CTAs out round-robin over the SMs with room in the
//! same cycle, so the engine serves such stops in cycle order once every node has reached that
//! cycle), and, once it holds no CTA and none is pending, before each further visit (made only
//! if the run has not ended by then: it ends after the cycle in which the last SM fell idle).
//!
//! Within a node, idle cycles are skipped in SST's declocking style: after a visit the node
//! records the next cycle it has work (its shader timers, a warp it can offer its RT unit,
//! [`RtPort::next_event`], which uses the RT unit's exact `idle_cycles`,
//! [`CtaStatePort::next_event`], its next memory response, room for a CTA), and an RT unit with
//! nothing to do is not stepped; it catches up its warp-cycle statistics and delay counters with
//! `skip` when next stepped (and at the end). With `sim.lockstep` every node visits every cycle
//! and steps its RT unit every cycle; results are identical (tested), as they are for every
//! number of threads (tested). A waveform ([`SimOptions::vcd`]) changes none of this: inside its
//! window the recorded RT unit steps the cycles it would have skipped one by one
//! ([`crate::gpu::rt::waveform`]).

use std::sync::Mutex;
use std::time::Instant;

use crossbeam_utils::CachePadded;

use glam::Vec3;
use vtq_hdl::rt_unit::{TraversalOrder, CHUNK_BYTES};

use crate::bvh::HwBvh;
use crate::config::{ModeKind, SimConfig};
use crate::geometry::{Hit, Ray};
use crate::gpu::cta_scheduler::CtaScheduler;
use crate::gpu::error::SimError;
use crate::gpu::finish::{finish, Finished};
use crate::gpu::l2_partitions::PartitionJobs;
use crate::gpu::node::{Ctx, HaltKind, SmNode};
use crate::gpu::parallelism::{clock_reads, ParallelProfile, RoundKind, Serial, Stopwatch};
use crate::gpu::prefetch::Prefetcher;
use crate::gpu::queued_stacks::QueuedStacks;
use crate::gpu::rt::waveform::{VcdWindow, Waveform, WaveformSummary, MAX_WINDOW_CYCLES};
use crate::gpu::rt::{QueueSetup, RtPort};
use crate::gpu::shader::{PathThread, ShaderTiming};
use crate::gpu::sm::{RayBudget, Sm};
use crate::gpu::stats::{Sample, SimStats};
use crate::gpu::virtualization::CtaStatePort;
use crate::gpu::watchdog::Watchdog;
use crate::gpu::workers::{lock, Unit, Workers};
use crate::memory::{L1Port, MemorySystem};
use crate::scene::Scene;
use crate::workload::camera::CameraFrame;

/// Bytes of one hit record.
const HIT_RECORD_BYTES: u64 = 32;

/// Alignment of the hit-record region after the BVH image.
const HIT_RECORD_ALIGN: u64 = 4096;

/// Options of a simulation that are not part of the configuration.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct SimOptions {
    /// Record every traced ray with its closest hit ([`SimOutput::ray_log`]), for tests.
    pub record_rays: bool,
    /// Queues mode: record the input ports of SM `.0`'s treelet count and queue tables for the
    /// first `.1` cycles ([`SimOutput::table_log`]), to replay real traffic against their RTL.
    pub record_tables: Option<(usize, usize)>,
    /// Threads simulating the SMs (0 or 1: the calling thread alone). Results are identical
    /// for every value.
    pub threads: usize,
    /// Dispatch only these CTAs (sorted, distinct; `None`: the whole image). The pixels of the
    /// other CTAs stay black and trace nothing (the sampled tier's scale models).
    pub ctas: Option<Vec<u32>>,
    /// Write the waveform of one SM's RT unit over a window of cycles as VCD
    /// ([`crate::gpu::rt::waveform`]); the results do not change.
    pub vcd: Option<VcdWindow>,
    /// Time the engine's rounds and serial sections for the parallelism report
    /// ([`SimOutput::parallelism`]; meant for one-thread runs); the results do not change.
    pub profile: bool,
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
    /// The waveform written (only with [`SimOptions::vcd`]).
    pub waveform: Option<WaveformSummary>,
    /// The parallelism report's timings (only with [`SimOptions::profile`]).
    pub parallelism: Option<ParallelProfile>,
    /// Per SM, the CTAs that ran there, in the order they retired.
    pub cta_spans: Vec<Vec<super::sm::CtaSpan>>,
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
    // Hit records, then (queues mode) ray records, then suspended CTAs' state, then (queued
    // stacks' traffic) queued rays' stacks, then the traversal stacks' spill areas.
    let state_base = (records + 2 * nsms as u64 * per_sm).next_multiple_of(HIT_RECORD_ALIGN);
    let mut scheduler = CtaScheduler::new(settings.width, settings.height, cfg.gpu.threads_per_cta);
    if let Some(ctas) = &options.ctas {
        let sorted = ctas.windows(2).all(|w| w[0] < w[1]);
        if !sorted || ctas.last().is_some_and(|&c| c >= scheduler.total()) {
            return Err(SimError::Setup(format!(
                "the CTA subset must be sorted, distinct and below the image's {} CTAs",
                scheduler.total()
            )));
        }
        scheduler = scheduler.with_subset(ctas.clone());
    }
    let state_end = state_base
        + scheduler.total() as u64 * cfg.cta_state_bytes().next_multiple_of(CHUNK_BYTES as u64);
    // Then, with `rt.queued_stack_traffic`, queued rays' stacks (one area per SM).
    let queued_stacks_base = state_end.next_multiple_of(HIT_RECORD_ALIGN);
    let queued_stacks_bytes = if cfg.rt.queued_stack_traffic {
        QueuedStacks::area_bytes(cfg.hw.max_rays, cfg.hw.stack_depth)
    } else {
        0
    };
    let spill_start = queued_stacks_base + nsms as u64 * queued_stacks_bytes;
    let spill = SpillLayout::new(cfg, bvh, spill_start.next_multiple_of(HIT_RECORD_ALIGN))?;
    let (ports, l2) = MemorySystem::new(&cfg.memory, nsms)?.into_parts();
    let mut nodes = Vec::with_capacity(nsms);
    for (sm, port) in ports.into_iter().enumerate() {
        let params = cfg.rt_unit_params(
            records + sm as u64 * per_sm,
            Some(spill.base(sm)),
            spill.chunks,
        );
        let queues = (cfg.mode.kind == ModeKind::Queues).then(|| QueueSetup {
            features: cfg.controller_features(),
            ray_base: records + (nsms + sm) as u64 * per_sm,
            stack_base: cfg
                .rt
                .queued_stack_traffic
                .then(|| queued_stacks_base + sm as u64 * queued_stacks_bytes),
        });
        let mut rt = RtPort::new(
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
        if prefetch {
            rt = rt.with_prefetcher(Prefetcher::new(bvh, cfg.mode.prefetch_threshold));
        }
        if let Some((record, cycles)) = options.record_tables {
            if record == sm && !rt.record_tables(cycles) {
                return Err(SimError::Setup(format!(
                    "cannot record the tables of SM {sm}: it needs mode.kind = \"queues\""
                )));
            }
        }
        let mut s = Sm::new(cta_slots, warps_per_cta);
        if cfg.mode.virtualization {
            s = s.with_virtualization(RayBudget {
                max_rays: cfg.hw.max_rays as u64,
                cta_threads: cfg.gpu.threads_per_cta as u64,
                policy: cfg.virtualization,
            });
        }
        let states = CtaStatePort::new(state_base, cfg.cta_state_bytes());
        nodes.push(SmNode::new(sm, s, rt, states, port));
    }
    if let Some((sm, _)) = options.record_tables {
        if sm >= nsms {
            return Err(SimError::Setup(format!(
                "cannot record the tables of SM {sm}: the GPU has gpu.sms = {nsms}"
            )));
        }
    }
    if let Some(w) = &options.vcd {
        let (a, b) = (w.cycles.start, w.cycles.end);
        if w.sm >= nsms {
            return Err(SimError::Waveform(format!(
                "SM {} does not exist: the GPU has gpu.sms = {nsms} (SMs 0..{})",
                w.sm,
                nsms - 1
            )));
        }
        if a >= b || b - a > MAX_WINDOW_CYCLES {
            return Err(SimError::Waveform(format!(
                "the window {a}..{b} must hold 1 to {MAX_WINDOW_CYCLES} cycles (end exclusive)"
            )));
        }
        let comment = format!(
            "vtq {}: the RT unit of SM {} (of {nsms}), scene {}, mode {}, cycles {a}..{b} (end \
             exclusive). Cycle c starts at time {} c ns (clk high in its first half); each \
             block's scope holds its inputs and outputs of the cycle and its registers at the \
             start of the cycle.",
            env!("CARGO_PKG_VERSION"),
            w.sm,
            scene.name,
            cfg.mode.kind.name(),
            vtq_hdl::trace::CYCLE_NS
        );
        nodes[w.sm]
            .rt
            .attach_waveform(Waveform::create(w, &comment)?);
    }
    let ctx = Ctx {
        scene,
        cfg,
        settings,
        frame,
        timing: ShaderTiming::new(&cfg.gpu),
        record_rays: options.record_rays,
        profile: options.profile,
    };
    let start = Instant::now();
    let l2 = PartitionJobs::new(l2, nsms);
    let slots: Vec<SummarySlot> = (0..nsms).map(|_| SummarySlot::default()).collect();
    let mut engine = Engine {
        ctx: &ctx,
        scheduler,
        l2: &l2,
        slots: &slots,
        summaries: nodes.iter().map(Summary::of).collect(),
        l2_unapplied: false,
        watchdog: Watchdog::new(cfg.sim.watchdog_cycles),
        progress,
        profile: options.profile.then(ParallelProfile::new),
    };
    let step = |unit: Unit<'_, SmNode>, round: &Round| step(&ctx, &l2, &slots, unit, round);
    let (cycles, mut nodes) = Workers::with(options.threads.max(1), l2.len(), nodes, step, |w| {
        engine.run(w)
    });
    // The last window's L2 operations count in the L2 and DRAM statistics, as every other
    // window's do (nobody settles their results).
    for p in 0..l2.len() {
        l2.apply(p, false);
    }
    let waveform_sm = options.vcd.as_ref().map(|w| w.sm);
    let cycles = match cycles {
        Ok(c) => c,
        Err(e) => {
            if let Some(w) = waveform_sm.and_then(|sm| nodes[sm].rt.take_waveform()) {
                w.abandon();
            }
            return Err(e);
        }
    };
    for node in &mut nodes {
        node.rt.catch_up(cycles);
        node.finish_samples(cfg, cycles - 1);
    }
    let waveform = match waveform_sm.and_then(|sm| nodes[sm].rt.take_waveform()) {
        Some(w) => Some(w.finish(cycles)?),
        None => None,
    };
    let wall = start.elapsed().as_secs_f64();
    let table_log = options
        .record_tables
        .and_then(|(sm, _)| nodes[sm].rt.take_table_log());
    let mut out = finish(Finished {
        ctx: &ctx,
        nodes: &nodes,
        l2_stats: l2.stats(),
        cycles,
        wall,
        config: config_toml,
        bvh,
        stack_spill_chunks: spill.chunks,
    });
    out.table_log = table_log;
    out.waveform = waveform;
    out.parallelism = engine.profile;
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
    /// one per treelet root (only treelet roots go on the other stack, each at most once). A
    /// packed slot holds several subtrees, so this counts slots where it should count their
    /// roots; chunks hold four entries each, so the bound keeps a factor of four in hand, and a
    /// stack that outgrows it stops the run with an RT-unit fault naming `stack_spill_chunks`.
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

/// The parameter of a round of node visits.
#[derive(Debug, Clone, Copy)]
struct Round {
    /// The end of the window (exclusive).
    end: u64,
    /// Whether CTAs are pending at the CTA scheduler.
    pending: bool,
    /// The first round of the window: nodes settle the last window and begin this one.
    begin: bool,
}

/// What the nodes share, and the loop over windows.
struct Engine<'r, 'a> {
    ctx: &'r Ctx<'a>,
    scheduler: CtaScheduler,
    l2: &'r PartitionJobs,
    /// The nodes' summary slots, written as their visits end.
    slots: &'r [SummarySlot],
    /// The nodes' summaries as of the last round each took part in.
    summaries: Vec<Summary>,
    /// The last window's L2 operations wait in the partitions, to be applied by the next
    /// window's first round.
    l2_unapplied: bool,
    watchdog: Watchdog,
    progress: Option<&'r indicatif::ProgressBar>,
    /// The parallelism report's timings, in a profiled run.
    profile: Option<ParallelProfile>,
}

/// The engine's view of the nodes between rounds.
type Nodes<'w, 'a, F> = Workers<'w, SmNode<'a>, Round, F>;

/// The function the workers run.
trait StepFn<'a>: for<'u> Fn(Unit<'u, SmNode<'a>>, &Round) + Sync {}
impl<'a, F: for<'u> Fn(Unit<'u, SmNode<'a>>, &Round) + Sync> StepFn<'a> for F {}

/// One unit of a round (run on any thread): a memory partition applying the last window's L2
/// operations (a pre-job), or a node's visits (which first takes its results of the last
/// window, all partitions being done, when the round begins a window).
fn step(
    ctx: &Ctx,
    l2: &PartitionJobs,
    summaries: &[SummarySlot],
    unit: Unit<'_, SmNode>,
    round: &Round,
) {
    match unit {
        Unit::Pre(p) => l2.apply(p, ctx.profile),
        Unit::Item(node) => {
            let watch = Stopwatch::start(ctx.profile);
            if round.begin {
                if !node.mem.ops().is_empty() {
                    let mem = &mut node.mem;
                    l2.results_for(node.index, |k, result| mem.set_result(k, result));
                }
                node.begin_window(ctx, round.end, round.pending);
            }
            node.run(ctx, round.end, round.pending);
            let ops = node.mem.ops();
            l2.post(node.index, node.posted, &ops[node.posted..]);
            node.posted = ops.len();
            let mut summary = Summary::of(node);
            summary.visit_ns = watch.ns();
            *lock(&summaries[node.index]) = summary;
        }
    }
}

/// What the engine reads of a node between rounds: the node writes it at the end of each of
/// its visits, into a slot of its own, so that the engine reads one cache line per node
/// instead of locking the node.
#[derive(Debug, Clone, Copy, Default)]
struct Summary {
    /// The cycle of its first error, if any.
    error: Option<u64>,
    /// Where and why it halted, if it did.
    halt: Option<(u64, HaltKind)>,
    /// Whether its SM holds no CTA.
    idle: bool,
    /// [`SmNode::idle_since`].
    idle_since: Option<u64>,
    /// [`SmNode::next`].
    next: u64,
    /// Whether it has L2 operations in the window.
    l2_ops: bool,
    /// Whether it waits for an L2 result of the window (an operation or a deferred stall).
    l2_wait: bool,
    /// Pixels it finished.
    pixels: usize,
    /// [`SmNode::last_progress`].
    last_progress: u64,
    /// Nanoseconds of its last visits (profiled runs).
    visit_ns: u64,
}

impl Summary {
    /// The summary of `node` as it is.
    fn of(node: &SmNode) -> Self {
        let l2_ops = !node.mem.ops().is_empty();
        Summary {
            error: node.error.as_ref().map(|(c, _)| *c),
            halt: node.halt.map(|h| (h.cycle, h.kind)),
            idle: node.sm.is_idle(),
            idle_since: node.idle_since,
            next: node.next,
            l2_ops,
            l2_wait: l2_ops || node.mem.has_deferred_stall(),
            pixels: node.pixels.len(),
            last_progress: node.last_progress,
            visit_ns: 0,
        }
    }
}

/// A node's [`Summary`] behind its own lock, on cache lines of its own.
type SummarySlot = CachePadded<Mutex<Summary>>;

impl<'a> Engine<'_, 'a> {
    /// Runs windows until the last SM falls idle with no CTA pending; returns the cycle count.
    fn run<F: StepFn<'a>>(&mut self, nodes: &mut Nodes<'_, 'a, F>) -> Result<u64, SimError> {
        let window = L1Port::round_trip(&self.ctx.cfg.memory);
        let reads_before = clock_reads();
        let total = Stopwatch::start(self.profile.is_some());
        let mut start = 0u64;
        loop {
            let end = start.saturating_add(window);
            let pending = self.scheduler.pending() > 0;
            if let Some(p) = &mut self.profile {
                p.window();
            }
            let pre = if self.l2_unapplied { self.l2.len() } else { 0 };
            self.l2_unapplied = false;
            self.visit_round(
                nodes,
                pre,
                |_| true,
                Round {
                    end,
                    pending,
                    begin: true,
                },
            );
            let ended = self.serve_halts(nodes, end)?;
            let next = self.end_window(end);
            if let Some(cycles) = ended {
                if let Some(p) = &mut self.profile {
                    p.set_total(total.ns(), reads_before);
                }
                return Ok(cycles);
            }
            let deadline = self.watchdog.deadline();
            if next >= deadline || end > deadline {
                return Err(self.watchdog_error(nodes, deadline));
            }
            start = next;
        }
    }

    /// Runs a round: the memory partitions `0..pre` apply their operations, then the nodes
    /// `choose` selects visit their cycles; in a profiled run, records the units' times.
    fn visit_round<F: StepFn<'a>>(
        &mut self,
        nodes: &mut Nodes<'_, 'a, F>,
        pre: usize,
        choose: impl Fn(usize) -> bool,
        round: Round,
    ) {
        let kind = if round.begin {
            RoundKind::Window
        } else {
            RoundKind::AfterHalt
        };
        let chosen: Vec<bool> = (0..nodes.len()).map(&choose).collect();
        nodes.round(pre, |i| chosen[i], round);
        for (i, _) in chosen.iter().enumerate().filter(|(_, &c)| c) {
            self.summaries[i] = *lock(&self.slots[i]);
        }
        if let Some(p) = &mut self.profile {
            let parts: Vec<u64> = (0..pre).map(|j| self.l2.apply_ns(j)).collect();
            p.round(RoundKind::L2, &parts);
            let times: Vec<u64> = (0..nodes.len())
                .filter(|&i| chosen[i])
                .map(|i| self.summaries[i].visit_ns)
                .collect();
            p.round(kind, &times);
        }
    }

    /// Serves the nodes' halts of the window ending at `end` in cycle order, letting the
    /// halted nodes go on after each, until every node has reached `end`. Returns the cycle
    /// count when the run has ended.
    fn serve_halts<F: StepFn<'a>>(
        &mut self,
        nodes: &mut Nodes<'_, 'a, F>,
        end: u64,
    ) -> Result<Option<u64>, SimError> {
        loop {
            let watch = Stopwatch::start(self.profile.is_some());
            // The first error in (cycle, SM) order among the nodes that ran.
            let mut first: Option<(u64, usize)> = None;
            for (i, s) in self.summaries.iter().enumerate() {
                if let Some(c) = s.error {
                    if first.is_none_or(|(fc, _)| c < fc) {
                        first = Some((c, i));
                    }
                }
            }
            if let Some((_, i)) = first {
                let (_, e) = nodes.item(i).error.take().expect("its summary has it");
                return Err(e);
            }
            let halts: Vec<Option<(u64, HaltKind)>> =
                self.summaries.iter().map(|s| s.halt).collect();
            let Some(t) = halts.iter().flatten().map(|h| h.0).min() else {
                let ended = self.ended();
                if let Some(p) = &mut self.profile {
                    p.serial(Serial::Halts, watch.ns());
                }
                return Ok(ended);
            };
            // Every node is at cycle t or later: serve the CTA dispatch of cycle t.
            let at = |i: usize, kind| halts[i] == Some((t, kind));
            let dispatch: Vec<usize> = (0..nodes.len())
                .filter(|&i| at(i, HaltKind::Dispatch))
                .collect();
            if !dispatch.is_empty() {
                self.dispatch(nodes, t, &dispatch);
            }
            let pending = self.scheduler.pending() > 0;
            // Visits of nodes idle for good happen only if the run goes on past cycle t: some
            // CTA is pending, or some SM holds CTAs or fell idle at t or later.
            let goes_on = pending
                || self
                    .summaries
                    .iter()
                    .any(|s| s.idle_since.is_none_or(|c| c >= t));
            let mut go = vec![false; nodes.len()];
            for i in 0..nodes.len() {
                if halts[i].is_none_or(|(c, _)| c != t) {
                    continue;
                }
                // A node served a dispatch may hold CTAs now (its summary predates it).
                let idle = if dispatch.contains(&i) {
                    nodes.item(i).sm.is_idle()
                } else {
                    self.summaries[i].idle
                } && !pending;
                if goes_on || !idle {
                    go[i] = true;
                } else {
                    // Beyond the end of the run: the visit never happens.
                    let mut n = nodes.item(i);
                    n.halt = None;
                    n.next = u64::MAX;
                    self.summaries[i].halt = None;
                    self.summaries[i].next = u64::MAX;
                }
            }
            if let Some(p) = &mut self.profile {
                p.serial(Serial::Halts, watch.ns());
            }
            self.visit_round(
                nodes,
                0,
                |i| go[i],
                Round {
                    end,
                    pending,
                    begin: false,
                },
            );
        }
    }

    /// When every node has reached the end of the window: the cycle count if the run has ended
    /// (no CTA pending and every SM idle: it ends after the cycle the last one fell idle).
    fn ended(&self) -> Option<u64> {
        if self.scheduler.pending() > 0 {
            return None;
        }
        let mut last = 0;
        for s in &self.summaries {
            last = last.max(s.idle_since?);
        }
        Some(last + 1)
    }

    /// Hands pending CTAs out at cycle `t` to the nodes halted for them (`halted`, in index
    /// order), round-robin over the SMs; new CTAs' warps trace after launch and raygen.
    fn dispatch<F>(&mut self, nodes: &Nodes<'_, 'a, F>, t: u64, halted: &[usize]) {
        let ctx = self.ctx;
        let mut free = vec![0; nodes.len()];
        for &i in halted {
            free[i] = nodes.item(i).sm.launchable();
        }
        let start = t + ctx.cfg.gpu.cta_launch_cycles as u64 + ctx.timing.raygen;
        let warp_size = ctx.cfg.gpu.warp_size as usize;
        for (sm, cta) in self.scheduler.dispatch(&mut free) {
            let pixels = self.scheduler.pixels(cta);
            let warps = pixels
                .chunks(warp_size)
                .map(|chunk| {
                    chunk
                        .iter()
                        .map(|p| p.map(|p| PathThread::new(&ctx.frame, &ctx.settings, p)))
                        .collect()
                })
                .collect();
            nodes.item(sm).sm.launch(cta, warps, start);
        }
    }

    /// Ends the window at `end`: notes whether the nodes posted L2 operations (the memory
    /// partitions then apply them in (cycle, phase, SM, sequence) order as the next window's
    /// first round begins, and the nodes take their results and settle), advances the progress
    /// bar and the watchdog, and returns the earliest cycle at which a node may have work: its
    /// next visit, or the window end if it waits for an L2 result of this window (never earlier
    /// than the end) or for a stall's retry cycle.
    fn end_window(&mut self, end: u64) -> u64 {
        let watch = Stopwatch::start(self.profile.is_some());
        let mut next = u64::MAX;
        let (mut pixels, mut progress) = (0, 0);
        for s in &self.summaries {
            self.l2_unapplied |= s.l2_ops;
            next = next.min(s.next);
            if s.l2_wait {
                next = end;
            }
            pixels += s.pixels;
            progress = progress.max(s.last_progress);
        }
        if let Some(bar) = self.progress {
            bar.set_position(pixels as u64);
        }
        self.watchdog.progress(progress);
        if let Some(p) = &mut self.profile {
            p.serial(Serial::WindowEnd, watch.ns());
        }
        next.max(end)
    }

    /// The watchdog's error at cycle `cycle` with every component's state.
    fn watchdog_error<F>(&self, nodes: &Nodes<'_, 'a, F>, cycle: u64) -> SimError {
        let mut dump = format!(
            "CTA scheduler: {} of {} CTAs not dispatched\n",
            self.scheduler.pending(),
            self.scheduler.total()
        );
        let virtualization = self.ctx.cfg.mode.virtualization;
        for i in 0..nodes.len() {
            dump += &nodes.item(i).debug_state(virtualization, cycle);
        }
        dump += &format!("memory: {}\n", self.l2.debug_state(cycle));
        SimError::Watchdog {
            cycle,
            last_progress: self.watchdog.last_progress(),
            dump,
        }
    }
}
