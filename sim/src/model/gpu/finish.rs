//! The end of a run: the statistics ([`SimStats`]), image, time series and ray log of the
//! whole GPU, summed over its SM nodes and the L2.

use glam::Vec3;
use vtq_hdl::rt_unit::RtStats;

use crate::model::bvh::HwBvh;
use crate::model::config::SimConfig;
use crate::model::energy::EnergyReport;
use crate::model::gpu::node::{Ctx, NodeSample, SmNode};
use crate::model::gpu::output::{SimOutput, TracedRay};
use crate::model::gpu::rt::warp_costs::{WarpCostStats, WarpCosts};
use crate::model::gpu::rt::QueueObserver;
use crate::model::gpu::stats::VirtTiming;
use crate::model::gpu::stats::{Phases, QueueStats, Sample, SimStats, TailStats, WarpLanes};
use crate::model::memory::{AccessClass, MemStats};

/// What [`finish`] needs of a run that ended.
pub struct Finished<'r, 'a> {
    /// The run's shared context.
    pub ctx: &'r Ctx<'a>,
    /// The SM nodes, by index.
    pub nodes: &'r [SmNode<'a>],
    /// The L2 and DRAM counters.
    pub l2_stats: MemStats,
    /// Cycles the run took.
    pub cycles: u64,
    /// Wall-clock seconds of the simulation loop.
    pub wall: f64,
    /// The configuration as TOML.
    pub config: String,
    /// The BVH.
    pub bvh: &'r HwBvh,
    /// Chunks of each ray stack's spill area.
    pub stack_spill_chunks: u32,
}

/// The statistics, image, time series and ray log of a run that ended after `cycles` cycles
/// (`wall` seconds), from its nodes and the L2 (`config`: the configuration as TOML).
pub fn finish(run: Finished<'_, '_>) -> SimOutput {
    let Finished {
        ctx,
        nodes,
        l2_stats,
        cycles,
        wall,
        config,
        bvh,
        stack_spill_chunks,
    } = run;
    let cfg = ctx.cfg;
    let (rt, mem) = summed_counters(nodes, l2_stats);
    let warp_simt = warp_simt_totals(nodes);
    let rays_issued: u64 = nodes.iter().map(|n| n.rt.rays_issued()).sum();
    let rays_completed: u64 = nodes.iter().map(|n| n.rt.rays_completed()).sum();
    let l2_misses = AccessClass::ALL
        .iter()
        .map(|&c| mem.class(c).l2_misses)
        .sum();
    let warp_size = cfg.hw.warp_size;
    let simt = ratio(rt.active_thread_cycles, rt.warp_cycles * warp_size as u64);
    let queues: Vec<&QueueObserver> = nodes.iter().filter_map(|n| n.rt.queue_stats()).collect();
    let phases = phases(&rt, &queues, cycles, warp_size);
    let image = image(ctx, nodes);
    let time_series = time_series(cfg.sim.sample_interval, cycles, nodes);
    let interval = cfg.sim.sample_interval;
    let deciles = miss_rate_deciles(interval, cycles, nodes, false);
    let deciles_preloads = miss_rate_deciles(interval, cycles, nodes, true);
    let simt_deciles = simt_deciles(cfg, cycles, nodes);
    let tail = tail_stats(ctx, cycles, nodes);
    let virt = virt_timing(nodes);
    let ray_log = ray_log(nodes);
    let stats = SimStats {
        scene: ctx.scene.name.clone(),
        mode: cfg.mode.kind.name().to_string(),
        cycles,
        rays: rays_completed,
        rays_issued,
        rays_completed,
        rays_hit: nodes.iter().map(|n| n.rays_hit).sum(),
        occlusion_rays: nodes.iter().map(|n| n.occlusion_rays).sum(),
        ctas: nodes.iter().map(|n| n.sm.done.len() as u64).sum(),
        simt_efficiency: simt,
        simt_efficiency_per_warp: per_warp_simt(warp_simt),
        rt_warps: warp_simt.1,
        simt_efficiency_deciles: simt_deciles,
        bvh_l1_accesses: mem.bvh.l1_loads,
        bvh_l1_misses: mem.bvh.l1_misses,
        bvh_l1_merges: mem.bvh.l1_merges,
        bvh_l1_miss_rate: ratio(mem.bvh.l1_misses, mem.bvh.l1_loads),
        bvh_l1_miss_rate_deciles: deciles,
        bvh_l1_miss_rate_deciles_with_prefetches: deciles_preloads,
        bvh_l1_miss_rate_with_prefetches: ratio(
            mem.bvh.l1_misses + mem.prefetch.issued,
            mem.bvh.l1_loads + mem.prefetch.requests,
        ),
        l2_misses,
        dram_bytes: mem.dram.read_bytes + mem.dram.write_bytes,
        phases,
        tail,
        max_queues: queues.iter().map(|q| q.max_queues).max().unwrap_or(0),
        max_queues_above_threshold: queues
            .iter()
            .map(|q| q.max_queues_above_threshold)
            .max()
            .unwrap_or(0),
        count_table_evictions: queues.iter().map(|q| q.counts.ctl.evictions).sum(),
        queue_table_spills: queues.iter().map(|q| q.counts.spills).sum(),
        cta_suspends: nodes.iter().map(|n| n.sm.suspends).sum(),
        cta_resumes: nodes.iter().map(|n| n.sm.resumes).sum(),
        virtualization: virt,
        sm_finish_cycles: nodes
            .iter()
            .map(|n| n.idle_since.map_or(cycles, |c| c + 1))
            .collect(),
        max_rays_in_flight: nodes.iter().map(|n| n.sm.max_in_flight).max().unwrap_or(0),
        stack_spill_chunks: stack_spill_chunks as u64,
        rt,
        warp_costs: (!queues.is_empty()).then(|| warp_costs(nodes, warp_size)),
        max_access_queue: nodes.iter().map(|n| n.rt.max_queue()).max().unwrap_or(0),
        queues: queue_stats(&queues, nodes),
        prefetcher_treelets: nodes
            .iter()
            .filter_map(|n| n.rt.prefetcher())
            .map(|p| p.treelets_queued)
            .sum(),
        prefetches_issued: mem.prefetch.issued,
        prefetches_used: mem.prefetch.used,
        prefetches_unused_evicted: mem.prefetch.evicted_unused,
        memory: mem,
        time_series_samples: time_series.len() as u64,
        active_units: active_units(cfg, bvh),
        bvh: bvh.stats(),
        energy: EnergyReport::default(),
        config,
        sm_visits: nodes.iter().map(|n| n.visits).sum(),
        sim_wall_seconds: wall,
        simulated_rays_per_second: rays_completed as f64 / wall.max(1e-9),
    };
    SimOutput {
        stats,
        image,
        nonfinite_samples: nodes.iter().map(|n| n.nonfinite).sum(),
        time_series,
        ray_log,
        table_log: None,
        waveform: None,
        parallelism: None,
        cta_spans: nodes.iter().map(|n| n.sm.done.clone()).collect(),
    }
}

/// The RT units' hardware counters and the memory counters (the L2's `l2_stats` plus every
/// node's L1), summed in SM order.
fn summed_counters(nodes: &[SmNode<'_>], l2_stats: MemStats) -> (RtStats, MemStats) {
    let mut rt = RtStats::default();
    let mut mem = l2_stats;
    for node in nodes {
        rt.add(node.rt.hw_stats());
        mem.add(node.mem.stats());
    }
    (rt, mem)
}

/// The per-warp SIMT efficiencies summed over the RT units' completed warps, and the number of
/// those warps.
fn warp_simt_totals(nodes: &[SmNode<'_>]) -> (f64, u64) {
    // Summed in SM order: the same float sum for any thread count.
    nodes
        .iter()
        .map(|n| n.rt.warp_simt().totals())
        .fold((0.0, 0u64), |(s, w), (a, b)| (s + a, w + b))
}

/// The mean per-warp SIMT efficiency of `(sum, warps)` ([`warp_simt_totals`]); 0 without warps.
fn per_warp_simt(warp_simt: (f64, u64)) -> f64 {
    if warp_simt.1 == 0 {
        0.0
    } else {
        warp_simt.0 / warp_simt.1 as f64
    }
}

/// The rendered image: every node's finished pixels in place, the others black.
fn image(ctx: &Ctx<'_>, nodes: &[SmNode<'_>]) -> Vec<Vec3> {
    let mut image = vec![Vec3::ZERO; ctx.settings.pixels()];
    for node in nodes {
        for &(pixel, color) in &node.pixels {
            image[pixel as usize] = color;
        }
    }
    image
}

/// The SIMT efficiency of each tenth of the run's samples.
fn simt_deciles(cfg: &SimConfig, cycles: u64, nodes: &[SmNode<'_>]) -> Vec<f64> {
    ratio_deciles(cfg.sim.sample_interval, cycles, nodes, |s: &NodeSample| {
        (
            s.active_thread_cycles,
            s.warp_cycles * cfg.hw.warp_size as u64,
        )
    })
}

/// The CTA-state save, resume-wait and restore cycles, summed over the SMs.
fn virt_timing(nodes: &[SmNode<'_>]) -> VirtTiming {
    let mut virt = VirtTiming::default();
    for node in nodes {
        let t = node.sm.timing;
        virt.save_cycles += t.save_cycles;
        virt.resume_wait_cycles += t.resume_wait_cycles;
        virt.restore_cycles += t.restore_cycles;
    }
    virt
}

/// Every node's traced rays, in the order of their keys (cycle, phase, SM, sequence): the same
/// log for any thread count.
fn ray_log(nodes: &[SmNode<'_>]) -> Vec<TracedRay> {
    let mut log: Vec<_> = nodes
        .iter()
        .flat_map(|n| n.ray_log.iter().copied())
        .collect();
    log.sort_by_key(|&(key, _)| key);
    log.into_iter().map(|(_, ray)| ray).collect()
}

/// The completed warps' costs, summed in SM order over the RT units that track them.
fn warp_costs(nodes: &[SmNode<'_>], warp_size: u32) -> WarpCostStats {
    let mut costs = WarpCosts::default();
    for c in nodes.iter().filter_map(|n| n.rt.warp_costs()) {
        costs.add(&c);
    }
    costs.stats(warp_size)
}

/// The units a run used, for the energy model: the fixed ones, the datapath units the BVH
/// needs, the design's own and the memory levels.
fn active_units(cfg: &SimConfig, bvh: &HwBvh) -> Vec<String> {
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
    units.extend(cfg.mode.units());
    units.extend(["memory.l1", "memory.l2", "memory.dram"]);
    units.into_iter().map(String::from).collect()
}

/// The cycles, tests and lanes per controller phase: the whole run as ray-stationary without
/// treelet queues; else each SM's controller time per mode averaged over the SMs, tests and
/// warp cycles summed over them.
fn phases(rt: &RtStats, queues: &[&QueueObserver], cycles: u64, warp_size: u32) -> Phases {
    if queues.is_empty() {
        let all = WarpLanes {
            warp_cycles: rt.warp_cycles,
            active: rt.active_thread_cycles,
            waiting: rt.waiting_lane_cycles,
            done: rt.done_lane_cycles,
            parked: rt.parked_lane_cycles,
        };
        Phases {
            ray_stationary: all.phase(cycles, rt.total_tests(), warp_size),
            ..Phases::default()
        }
    } else {
        // Cycles: each SM's controller time per mode, averaged over the SMs; tests and warp
        // cycles: summed over the SMs.
        let n = queues.len() as u64;
        let phase = |i: usize, cycles: &dyn Fn(&QueueObserver) -> u64| {
            let sum = |f: &dyn Fn(&QueueObserver) -> u64| queues.iter().map(|q| f(q)).sum::<u64>();
            let mut lanes = WarpLanes::default();
            for q in queues {
                lanes.add(&q.lanes[i]);
            }
            lanes.phase(sum(cycles) / n, sum(&|q| q.tests[i]), warp_size)
        };
        Phases {
            initial: phase(0, &|q| q.counts.ctl.cycles_initial),
            treelet_stationary: phase(1, &|q| q.counts.ctl.cycles_treelet),
            ray_stationary: phase(2, &|q| q.counts.ctl.cycles_final),
        }
    }
}

/// The treelet-queue counters summed over the SMs' observers, with every node's queued stack
/// chunks.
fn queue_stats(queues: &[&QueueObserver], nodes: &[SmNode]) -> QueueStats {
    let mut t = QueueStats::default();
    for q in queues {
        t.counts.add(&q.counts);
    }
    for n in nodes {
        let (stores, loads) = n.rt.queued_stack_chunks();
        t.stack_stores += stores;
        t.stack_loads += loads;
    }
    t
}

/// The time series: at every multiple of `interval` before `cycles`, the BVH L1 accesses and
/// misses since the previous sample and the rays traversing, summed over the nodes.
fn time_series(interval: u64, cycles: u64, nodes: &[SmNode]) -> Vec<Sample> {
    if interval == 0 {
        return Vec::new();
    }
    let n = ((cycles - 1) / interval) as usize;
    let mut out = Vec::with_capacity(n);
    let (mut loads, mut misses) = (0u64, 0u64);
    for k in 0..n {
        let (l, m, active) = nodes.iter().fold((0, 0, 0), |(l, m, a), node| {
            let s = node.samples[k];
            (l + s.bvh_l1_loads, m + s.bvh_l1_misses, a + s.active_rays)
        });
        out.push(Sample {
            cycle: (k as u64 + 1) * interval,
            bvh_l1_accesses: l - loads,
            bvh_l1_misses: m - misses,
            bvh_l1_miss_rate: ratio(m - misses, l - loads),
            active_rays: active,
        });
        (loads, misses) = (l, m);
    }
    out
}

/// The BVH L1 miss rate in each tenth of a run of `cycles` cycles sampled every `interval`
/// cycles ([`ratio_deciles`]); `with_prefetches` counts L1 prefetches (treelet preloads) as accesses
/// and those that fetched a sector as misses. Empty without samples.
fn miss_rate_deciles(
    interval: u64,
    cycles: u64,
    nodes: &[SmNode],
    with_prefetches: bool,
) -> Vec<f64> {
    ratio_deciles(interval, cycles, nodes, |s| {
        if with_prefetches {
            (
                s.bvh_l1_misses + s.prefetch_misses,
                s.bvh_l1_loads + s.prefetches,
            )
        } else {
            (s.bvh_l1_misses, s.bvh_l1_loads)
        }
    })
}

/// A ratio of two counters in each tenth of a run of `cycles` cycles sampled every `interval`
/// cycles: `counters` gives a sample's (numerator, denominator) so far; decile `d` sums the
/// nodes' increments over the samples whose interval (the `interval` cycles before the sample's
/// cycle) starts in `[d x cycles / 10, (d + 1) x cycles / 10)`. Empty without samples.
fn ratio_deciles(
    interval: u64,
    cycles: u64,
    nodes: &[SmNode],
    counters: impl Fn(&NodeSample) -> (u64, u64),
) -> Vec<f64> {
    if interval == 0 {
        return Vec::new();
    }
    let n = ((cycles - 1) / interval) as usize;
    if n == 0 {
        return Vec::new();
    }
    let mut sums = [(0u64, 0u64); 10];
    let mut last = (0u64, 0u64);
    for k in 0..n {
        let (mut num, mut den) = (0, 0);
        for node in nodes {
            let (a, b) = counters(&node.samples[k]);
            num += a;
            den += b;
        }
        let start = k as u64 * interval;
        let d = ((start as u128 * 10 / cycles as u128) as usize).min(9);
        sums[d].0 += num - last.0;
        sums[d].1 += den - last.1;
        last = (num, den);
    }
    sums.iter().map(|&(m, a)| ratio(m, a)).collect()
}

/// The tail after the last CTA dispatch ([`TailStats`]): the RT units' warp counters at the
/// end of the run less their samples at the first sample boundary at or after it.
fn tail_stats(ctx: &Ctx, cycles: u64, nodes: &[SmNode]) -> TailStats {
    let cfg = ctx.cfg;
    let lead = cfg.gpu.cta_launch_cycles as u64 + ctx.timing.raygen;
    let last_dispatch = nodes
        .iter()
        .flat_map(|n| n.sm.done.iter())
        .map(|span| span.start.saturating_sub(lead))
        .max()
        .unwrap_or(0);
    let interval = cfg.sim.sample_interval;
    let from_cycle = if interval == 0 {
        cycles
    } else {
        (last_dispatch.div_ceil(interval) * interval).min(cycles)
    };
    let (mut warp_cycles, mut active) = (0, 0);
    if from_cycle < cycles {
        for node in nodes {
            let (w, a) = node.rt.warp_counters_until(cycles);
            // Sample `k` holds the counters of the cycles before `(k + 1) x interval`.
            let (w0, a0) = (from_cycle / interval)
                .checked_sub(1)
                .and_then(|k| node.samples.get(k as usize))
                .map_or((0, 0), |s| (s.warp_cycles, s.active_thread_cycles));
            warp_cycles += w.saturating_sub(w0);
            active += a.saturating_sub(a0);
        }
    }
    TailStats {
        last_dispatch,
        from_cycle,
        cycles: cycles - from_cycle,
        warp_cycles,
        active_thread_cycles: active,
        simt_efficiency: ratio(active, warp_cycles * cfg.hw.warp_size as u64),
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
