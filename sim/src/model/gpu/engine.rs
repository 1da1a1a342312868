//! The cycle loop. The GPU is a set of SM nodes ([`SmNode`]: an SM with its RT unit, CTA-state
//! port and L1) around what they share: the CTA scheduler and the L2 with DRAM.
//!
//! # Bounded lag
//! An SM affects another only through the L2 and the CTA scheduler, and no L2 result is needed
//! before one L2 round trip (`l1_latency + l2_latency`, 226 cycles by Table 1) after its access
//! was accepted ([`crate::model::memory::l1`]). So every node visits its own cycles independently, on
//! any of `threads` threads, up to one round trip past its oldest L2 operation whose result it
//! does not have yet; the L2's memory partitions ([`crate::model::gpu::l2_partitions`]) apply the
//! operations accepted before the cycle every node has reached, side by side, each in a fixed
//! order (cycle, phase, SM, sequence: [`crate::model::memory::L2Op::key`]) — exactly the order in which
//! one loop visiting every SM each cycle would have applied them — and the CTA scheduler serves
//! the nodes' halts ([`crate::model::gpu::node::Halt`]) in cycle order: a node halts when it could
//! take a new CTA (CTAs go out round-robin over the SMs with room in the same cycle, served once
//! every node has reached that cycle) and, once it holds no CTA and none is pending, before each
//! further visit (made only if the run has not ended by then: it ends after the cycle in which
//! the last SM fell idle). There is no barrier: [`crate::model::gpu::coordinator`] says who waits for
//! what.
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
//! ([`crate::model::gpu::rt::waveform`]).

use std::time::Instant;

use vtq_hdl::rt_unit::{TraversalOrder, CHUNK_BYTES};

use crate::model::bvh::HwBvh;
use crate::model::config::SimConfig;
use crate::model::energy::EnergyReport;
use crate::model::gpu::coordinator;
use crate::model::gpu::cta_scheduler::CtaScheduler;
use crate::model::gpu::error::SimError;
use crate::model::gpu::finish::{finish, Finished};
use crate::model::gpu::l2_partitions::PartitionJobs;
use crate::model::gpu::node::{Ctx, SmNode};
use crate::model::gpu::output::SimOutput;
use crate::model::gpu::prefetch::Prefetcher;
use crate::model::gpu::queued_stacks::QueuedStacks;
use crate::model::gpu::rt::waveform::{VcdWindow, Waveform, MAX_WINDOW_CYCLES};
use crate::model::gpu::rt::{QueueSetup, RtPort};
use crate::model::gpu::shader::ShaderTiming;
use crate::model::gpu::sm::{RayBudget, Sm};
use crate::model::gpu::virtualization::CtaStatePort;
use crate::model::memory::{L1Port, MemorySystem};
use crate::model::scene::Scene;
use crate::model::workload::camera::CameraFrame;
use crate::model::workload::kind::Workload;
use crate::model::workload::pathtracer::RenderSettings;

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
    /// ([`crate::model::gpu::rt::waveform`]); the results do not change.
    pub vcd: Option<VcdWindow>,
    /// Time the nodes', memory partitions' and coordinator's work for the parallelism report
    /// ([`SimOutput::parallelism`]; meant for one-thread runs); the results do not change.
    pub profile: bool,
    /// BVH sectors (byte addresses) present in the L2 before the run (the sampled tier's scale
    /// models, `sample.warm_l2`; [`crate::model::memory::L2Side::warm`]).
    pub l2_warm: Option<Vec<u64>>,
    /// The BVH reads of the SMs a scale model leaves out, replayed into its L2 as it runs (the
    /// sampled tier's scale models, `sample.ghost_l2_footprint`;
    /// [`crate::model::memory::L2Side::ghosts`]).
    pub l2_ghosts: Option<std::sync::Arc<crate::model::memory::GhostReads>>,
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
        .map_err(crate::model::workload::pathtracer::RenderError::from)?;
    let config_toml = cfg
        .to_toml()
        .map_err(|e| SimError::Setup(format!("cannot write the configuration: {e}")))?;
    let nsms = cfg.gpu.sms as usize;
    let warps_per_cta = cfg.warps_per_cta() as usize;
    let cta_slots = cta_slots(cfg, warps_per_cta)?;
    let scheduler = cta_scheduler(&settings, cfg, &options)?;
    let map = AddressMap::new(cfg, bvh, nsms, scheduler.total())?;
    let (ports, mut l2) = MemorySystem::new(&cfg.memory, nsms)?.into_parts();
    let mut nodes = Vec::with_capacity(nsms);
    for (sm, port) in ports.into_iter().enumerate() {
        nodes.push(build_node(
            cfg,
            bvh,
            &options,
            &map,
            (cta_slots, warps_per_cta),
            sm,
            port,
        )?);
    }
    if let Some((sm, _)) = options.record_tables {
        if sm >= nsms {
            return Err(SimError::Setup(format!(
                "cannot record the tables of SM {sm}: the GPU has gpu.sms = {nsms}"
            )));
        }
    }
    if let Some(w) = &options.vcd {
        attach_waveform(&mut nodes, w, scene, cfg)?;
    }
    let ctx = Ctx {
        scene,
        cfg,
        workload: Workload::new(&settings, scene),
        raster: bvh,
        settings,
        frame,
        timing: ShaderTiming::new(&cfg.gpu),
        record_rays: options.record_rays,
        profile: options.profile,
    };
    let start = Instant::now();
    if let Some(sectors) = &options.l2_warm {
        l2.warm(sectors);
    }
    if let Some(reads) = &options.l2_ghosts {
        l2.ghosts(reads);
    }
    let l2 = PartitionJobs::new(l2, nsms);
    let outcome = coordinator::run(&ctx, &l2, nodes, scheduler, options.threads, progress);
    let (cycles, mut nodes) = (outcome.cycles, outcome.nodes);
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
        stack_spill_chunks: map.spill.chunks,
    });
    // The energy model observes the finished statistics.
    let json = serde_json::to_value(&out.stats).map_err(|e| SimError::Energy(e.to_string()))?;
    out.stats.energy = EnergyReport::of_stats(&json, cfg).map_err(SimError::Energy)?;
    out.table_log = table_log;
    out.waveform = waveform;
    out.parallelism = outcome.profile;
    Ok(out)
}

/// The CTAs an SM holds at once: as many as `gpu.max_ctas_per_sm` allows and its
/// `gpu.max_warps_per_sm` fit CTAs of `warps_per_cta` warps; an error if not even one fits.
fn cta_slots(cfg: &SimConfig, warps_per_cta: usize) -> Result<usize, SimError> {
    let cta_slots = (cfg.gpu.max_ctas_per_sm as usize)
        .min(cfg.gpu.max_warps_per_sm as usize / warps_per_cta.max(1));
    if cta_slots == 0 {
        return Err(SimError::Setup(format!(
            "a CTA of {warps_per_cta} warps does not fit gpu.max_warps_per_sm = {}",
            cfg.gpu.max_warps_per_sm
        )));
    }
    Ok(cta_slots)
}

/// The CTA scheduler of the image of `settings`, limited to `options.ctas` (checked: sorted,
/// distinct and within the image) when given.
fn cta_scheduler(
    settings: &RenderSettings,
    cfg: &SimConfig,
    options: &SimOptions,
) -> Result<CtaScheduler, SimError> {
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
    Ok(scheduler)
}

/// Where the simulated memory's regions lie after the BVH image: hit records, then (queues
/// mode) ray records, then suspended CTAs' state, then (queued stacks' traffic) queued rays'
/// stacks, then the traversal stacks' spill areas.
struct AddressMap {
    /// First byte of SM 0's hit records.
    records: u64,
    /// Bytes of one SM's hit records (and of its ray records).
    per_sm: u64,
    /// First byte of the suspended CTAs' state.
    state_base: u64,
    /// First byte of SM 0's queued rays' stacks.
    queued_stacks_base: u64,
    /// Bytes of one SM's queued rays' stacks (0 without `rt.queued_stack_traffic`).
    queued_stacks_bytes: u64,
    /// The traversal stacks' spill areas.
    spill: SpillLayout,
}

impl AddressMap {
    /// The regions for `cfg`, `bvh`, `nsms` SMs and an image of `ctas` CTAs; an error if the
    /// spill areas do not fit the address space.
    fn new(cfg: &SimConfig, bvh: &HwBvh, nsms: usize, ctas: u32) -> Result<Self, SimError> {
        let bvh_end = bvh.treelets().len() as u64 * bvh.params().treelet_bytes as u64;
        let records = bvh_end.div_ceil(HIT_RECORD_ALIGN) * HIT_RECORD_ALIGN;
        let per_sm = cfg.hw.max_rays as u64 * HIT_RECORD_BYTES;
        // Hit records, then (queues mode) ray records, then suspended CTAs' state, then (queued
        // stacks' traffic) queued rays' stacks, then the traversal stacks' spill areas.
        let state_base = (records + 2 * nsms as u64 * per_sm).next_multiple_of(HIT_RECORD_ALIGN);
        let state_end =
            state_base + ctas as u64 * cfg.cta_state_bytes().next_multiple_of(CHUNK_BYTES as u64);
        // Then, with `rt.queued_stack_traffic`, queued rays' stacks (one area per SM).
        let queued_stacks_base = state_end.next_multiple_of(HIT_RECORD_ALIGN);
        let queued_stacks_bytes = if cfg.rt.queued_stack_traffic {
            QueuedStacks::area_bytes(cfg.hw.max_rays, cfg.hw.stack_depth)
        } else {
            0
        };
        let spill_start = queued_stacks_base + nsms as u64 * queued_stacks_bytes;
        let spill = SpillLayout::new(cfg, bvh, spill_start.next_multiple_of(HIT_RECORD_ALIGN))?;
        Ok(AddressMap {
            records,
            per_sm,
            state_base,
            queued_stacks_base,
            queued_stacks_bytes,
            spill,
        })
    }
}

/// SM `sm`'s node: its RT unit (with its treelet queues, prefetcher and table recording as
/// configured), its SM of `cta` = (CTA slots, warps per CTA), its CTA-state port and its L1
/// `port`.
fn build_node<'a>(
    cfg: &SimConfig,
    bvh: &'a HwBvh,
    options: &SimOptions,
    map: &AddressMap,
    (cta_slots, warps_per_cta): (usize, usize),
    sm: usize,
    port: L1Port,
) -> Result<SmNode<'a>, SimError> {
    let nsms = cfg.gpu.sms as usize;
    let params = cfg.rt_unit_params(
        map.records + sm as u64 * map.per_sm,
        Some(map.spill.base(sm)),
        map.spill.chunks,
    );
    let queues = cfg.mode.treelet_queues().then(|| QueueSetup {
        features: cfg.controller_features(),
        prefetch: cfg.mode.treelet_prefetch,
        ray_base: map.records + (nsms + sm) as u64 * map.per_sm,
        stack_base: cfg
            .rt
            .queued_stack_traffic
            .then(|| map.queued_stacks_base + sm as u64 * map.queued_stacks_bytes),
        record_latency: (cfg.rt.ray_record_latency > 0).then_some(cfg.rt.ray_record_latency),
    });
    let mut rt = RtPort::new(
        &cfg.hw,
        params,
        bvh,
        TraversalOrder::TreeletContinue,
        queues,
    )
    .map_err(|source| SimError::Rt { sm, source })?;
    if cfg.mode.prefetcher() {
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
    let states = CtaStatePort::new(map.state_base, cfg.cta_state_bytes());
    Ok(SmNode::new(sm, s, rt, states, port))
}

/// Checks the waveform window `w` (an existing SM, 1 to [`MAX_WINDOW_CYCLES`] cycles) and
/// attaches its VCD writer to that SM's RT unit.
fn attach_waveform(
    nodes: &mut [SmNode<'_>],
    w: &VcdWindow,
    scene: &Scene,
    cfg: &SimConfig,
) -> Result<(), SimError> {
    let nsms = cfg.gpu.sms as usize;
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
    Ok(())
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
