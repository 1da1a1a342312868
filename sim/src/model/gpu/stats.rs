//! [`SimStats`]: what one simulation measured, written as JSON (every key is documented in
//! docs/stats.md), and its time series ([`Sample`]), which `vtq sim` writes as CSV beside the
//! JSON (the command layer's `cli::time_series`).

use serde::{Deserialize, Serialize};
use vtq_hdl::rt_unit::RtStats;
use vtq_hdl::treelet_rt_unit::TreeletCounts;

use crate::model::bvh::BvhStats;
use crate::model::energy::EnergyReport;
use crate::model::gpu::rt::warp_costs::WarpCostStats;
use crate::model::memory::MemStats;

/// Keys of [`SimStats`] that depend on the host or on the engine's stepping mode rather than on
/// the simulated machine; runs of one configuration agree on every other key.
pub const HOST_DEPENDENT_KEYS: [&str; 3] =
    ["sim_wall_seconds", "simulated_rays_per_second", "sm_visits"];

/// Cycles, intersection tests and RT-unit warp cycles of one traversal phase (paper section
/// 6.4).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct PhaseStats {
    /// Cycles spent in the phase.
    pub cycles: u64,
    /// Intersection tests (node tests of every kind) made in the phase.
    pub intersection_tests: u64,
    /// RT-unit warp cycles (cycles x resident warps) in the phase, summed over the SMs.
    pub warp_cycles: u64,
    /// Sum over those warp cycles of traversing rays.
    pub active_thread_cycles: u64,
    /// SIMT efficiency in the phase: `active_thread_cycles / (warp_cycles x warp_size)` (0
    /// with no warp cycles).
    pub simt_efficiency: f64,
    /// Where the lanes of those warp cycles were.
    pub lanes: LaneCycles,
}

/// The lanes of RT-unit warp cycles by what they held, summed over warp cycles and lanes:
/// `warp_cycles x warp_size` = active (`active_thread_cycles`) + `finished` + `parked` +
/// `empty`. What keeps SIMT efficiency below 1 (docs/fidelity.md, issue 23).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct LaneCycles {
    /// Active lanes waiting for a node in flight (counted active: the paper's "threads
    /// traversing" include them).
    pub memory_wait: u64,
    /// Lanes whose ray has finished while the warp still holds the slot for its other lanes.
    pub finished: u64,
    /// Lanes parked at a treelet boundary, waiting for the warp to leave the treelet.
    pub parked: u64,
    /// Lanes holding no ray (a warp issued with fewer rays, or lanes a repack left empty).
    pub empty: u64,
}

vtq_hdl::counters! {
    /// RT-unit warp cycles and what their lanes held, summed over cycles (and SMs): the counters
    /// of one phase, or of a whole run, that [`WarpLanes::phase`] turns into [`PhaseStats`].
    #[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
    pub struct WarpLanes {
        /// Warp cycles (cycles x resident warps).
        pub warp_cycles: u64,
        /// Traversing lanes summed over them.
        pub active: u64,
        /// Of those, lanes waiting for a node in flight.
        pub waiting: u64,
        /// Lanes whose ray had finished.
        pub done: u64,
        /// Lanes parked at a treelet boundary.
        pub parked: u64,
    }
}

impl WarpLanes {
    /// The lane counters of the RT unit's statistics increments `s`.
    pub fn of(s: &RtStats) -> WarpLanes {
        WarpLanes {
            warp_cycles: s.warp_cycles,
            active: s.active_thread_cycles,
            waiting: s.waiting_lane_cycles,
            done: s.done_lane_cycles,
            parked: s.parked_lane_cycles,
        }
    }

    /// The statistics of a phase of `cycles` cycles and `intersection_tests` tests whose warp
    /// cycles (of `warp_size` lanes) these are.
    pub fn phase(&self, cycles: u64, intersection_tests: u64, warp_size: u32) -> PhaseStats {
        let lanes = self.warp_cycles * warp_size as u64;
        PhaseStats {
            cycles,
            intersection_tests,
            warp_cycles: self.warp_cycles,
            active_thread_cycles: self.active,
            simt_efficiency: if lanes == 0 {
                0.0
            } else {
                self.active as f64 / lanes as f64
            },
            lanes: LaneCycles {
                memory_wait: self.waiting,
                finished: self.done,
                parked: self.parked,
                empty: lanes.saturating_sub(self.active + self.done + self.parked),
            },
        }
    }
}

/// The three traversal phases of treelet queues (paper section 3.2). The baseline has only
/// ray-stationary traversal, so everything counts there.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Phases {
    /// Initial ray-stationary phase, before the switch to treelet-stationary mode.
    pub initial: PhaseStats,
    /// Treelet-stationary mode.
    pub treelet_stationary: PhaseStats,
    /// Final ray-stationary phase (and all of the baseline).
    pub ray_stationary: PhaseStats,
}

/// The tail of a run: from the last CTA dispatch to the end, when the SMs drain the rays in
/// flight with no new work coming (issue 23: where SIMT efficiency is lost).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct TailStats {
    /// Cycle of the last CTA dispatch (its warps' first trace less the CTA launch and raygen
    /// cycles).
    pub last_dispatch: u64,
    /// First cycle counted: the first `sim.sample_interval` boundary at or after
    /// `last_dispatch` (the RT units' counters are sampled there; `cycles` when there are no
    /// samples, so the tail then counts nothing).
    pub from_cycle: u64,
    /// Cycles from `from_cycle` to the end of the run.
    pub cycles: u64,
    /// RT-unit warp cycles in them, summed over the SMs.
    pub warp_cycles: u64,
    /// Traversing lanes summed over those warp cycles.
    pub active_thread_cycles: u64,
    /// `active_thread_cycles / (warp_cycles x hw.warp_size)` (0 without warp cycles).
    pub simt_efficiency: f64,
}

/// Treelet-controller and treelet-queue counters summed over all SMs: the treelet RT units'
/// own counters (their observers' sums, declared once in `vtq-hdl`) and the traffic of queued
/// rays' stacks, which the simulator models beside them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct QueueStats {
    /// The treelet RT units' counters, summed.
    #[serde(flatten)]
    pub counts: TreeletCounts,
    /// 32 B chunks of queued rays' stacks stored when they were parked
    /// (`rt.queued_stack_traffic`; 0 otherwise).
    pub stack_stores: u64,
    /// ... loaded back with their ray records (equal to `stack_stores` at the end).
    pub stack_loads: u64,
}

/// One point of the time series, taken at the start of cycle `cycle` and describing the
/// interval since the previous point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Cycle of the sample (a multiple of `sim.sample_interval`).
    pub cycle: u64,
    /// BVH demand loads the L1s saw in the interval.
    pub bvh_l1_accesses: u64,
    /// ... that missed.
    pub bvh_l1_misses: u64,
    /// Their miss rate (0 when there were no accesses).
    pub bvh_l1_miss_rate: f64,
    /// Rays traversing in the RT units at the sample.
    pub active_rays: u64,
}

/// Everything one simulation measured (see docs/stats.md for each key).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimStats {
    /// Scene name.
    pub scene: String,
    /// Simulated design (`baseline`, `prefetch` or `queues`).
    pub mode: String,
    /// Cycles until the last CTA retired.
    pub cycles: u64,
    /// Rays traced (every path's rays: primary and secondary).
    pub rays: u64,
    /// Rays issued to the RT units.
    pub rays_issued: u64,
    /// Rays whose traversal completed.
    pub rays_completed: u64,
    /// Rays that hit something.
    pub rays_hit: u64,
    /// Of the rays traced, occlusion rays (terminate on first hit; the `ao` workload's).
    pub occlusion_rays: u64,
    /// CTAs run.
    pub ctas: u64,
    /// RT-unit SIMT efficiency: traversing rays / warp size per RT-unit warp cycle.
    pub simt_efficiency: f64,
    /// RT-unit SIMT efficiency averaged per warp instead, as the paper's simulator lineage
    /// reports it ([`crate::model::gpu::warp_simt`]): the mean over RT-unit warps of each warp's
    /// traversing lane-cycles / (warp size x its cycles in the unit).
    pub simt_efficiency_per_warp: f64,
    /// RT-unit warps that mean is over (warp-buffer occupancies, cut at repacking fills).
    pub rt_warps: u64,
    /// `simt_efficiency` in each tenth of the run (from the `sim.sample_interval` samples, as
    /// `bvh_l1_miss_rate_deciles`; an RT unit's skipped idle cycles count in the sample its
    /// next visit records).
    pub simt_efficiency_deciles: Vec<f64>,
    /// BVH demand loads looked up in the L1s.
    pub bvh_l1_accesses: u64,
    /// ... that missed the L1 (a new sector fetch; merges with a pending fill are not misses).
    pub bvh_l1_misses: u64,
    /// ... that merged with a pending fill of the same sector.
    pub bvh_l1_merges: u64,
    /// `bvh_l1_misses / bvh_l1_accesses`.
    pub bvh_l1_miss_rate: f64,
    /// The BVH L1 miss rate in each tenth of the run (paper Figure 11's early and late miss
    /// rates), from the time series: decile `d` holds the samples whose interval starts in
    /// `[d x cycles / 10, (d + 1) x cycles / 10)`; 0 for a decile without BVH accesses; empty
    /// without a time series.
    pub bvh_l1_miss_rate_deciles: Vec<f64>,
    /// `bvh_l1_miss_rate` counting L1 prefetches (treelet preloads, prefetcher requests) as BVH
    /// accesses and those that fetched their sector as misses.
    pub bvh_l1_miss_rate_with_prefetches: f64,
    /// `bvh_l1_miss_rate_deciles` counting prefetches likewise.
    pub bvh_l1_miss_rate_deciles_with_prefetches: Vec<f64>,
    /// L2 misses of all classes.
    pub l2_misses: u64,
    /// Bytes moved to and from DRAM.
    pub dram_bytes: u64,
    /// Cycles and intersection tests per traversal phase.
    pub phases: Phases,
    /// The tail of the run after the last CTA was dispatched: its RT-unit warp cycles and
    /// SIMT efficiency.
    pub tail: TailStats,
    /// Most treelet queues at once (treelet-queue mode; 0 in the baseline).
    pub max_queues: u64,
    /// Most treelet queues above the underpopulation threshold at once (0 in the baseline).
    pub max_queues_above_threshold: u64,
    /// Treelet count table evictions (0 in the baseline).
    pub count_table_evictions: u64,
    /// Treelet queue table entries spilled to memory (0 in the baseline).
    pub queue_table_spills: u64,
    /// CTAs suspended by ray virtualization (0 in the baseline).
    pub cta_suspends: u64,
    /// Suspended CTAs resumed (0 in the baseline).
    pub cta_resumes: u64,
    /// Where suspended CTAs' time went, summed over the SMs (zeros without virtualization).
    pub virtualization: VirtTiming,
    /// Per SM, the cycle after which it held no CTA for good (its last CTA retired): how evenly
    /// the CTA scheduler spread the work. `cycles` is their maximum.
    pub sm_finish_cycles: Vec<u64>,
    /// Most rays in flight in one SM at once (issued or waiting to issue, traversal not
    /// completed, rays of suspended CTAs included); at most `hw.max_rays` with virtualization.
    pub max_rays_in_flight: u64,
    /// 32 B chunks each ray's traversal stack may spill to memory (the spill area the
    /// simulator's memory layout gives each of the two stacks of each ray id; see
    /// docs/stats.md).
    pub stack_spill_chunks: u64,
    /// RT-unit counters summed over the SMs.
    pub rt: RtStats,
    /// What each kind of RT-unit warp cost in each traversal phase, summed over the SMs
    /// (`queues` mode; `None`, written as `null`, otherwise).
    pub warp_costs: Option<WarpCostStats>,
    /// Treelet-controller and treelet-queue counters summed over the SMs (zeros outside
    /// `queues` mode).
    pub queues: QueueStats,
    /// Most requests waiting in one SM's memory access queue (back-pressure from the L1).
    pub max_access_queue: u64,
    /// Treelets the treelet prefetcher's popularity rule queued (the `prefetch` design, and
    /// `queues` with `mode.treelet_prefetch`; VTQ's preloads are `queues.preloads`).
    pub prefetcher_treelets: u64,
    /// L1 prefetches (the prefetcher's sectors and VTQ's treelet preloads) that missed the L1
    /// and fetched their sector (prefetches of sectors already in the L1 are dropped and not
    /// counted).
    pub prefetches_issued: u64,
    /// Prefetched sectors later used by a demand load.
    pub prefetches_used: u64,
    /// Prefetched sectors evicted from the L1 before any demand use.
    pub prefetches_unused_evicted: u64,
    /// Memory-system counters by class.
    pub memory: MemStats,
    /// Samples in the time series (written to the CSV file).
    pub time_series_samples: u64,
    /// The units modelled in this run.
    pub active_units: Vec<String>,
    /// The hardware BVH: node counts, bytes, treelets and their fill.
    pub bvh: BvhStats,
    /// The frame's energy under `energy.coefficients` (the energy model observes the other
    /// statistics; docs/energy.md).
    pub energy: EnergyReport,
    /// The effective configuration (TOML).
    pub config: String,
    /// (SM, cycle) pairs the engine evaluated (every cycle of every SM holding work in lockstep
    /// mode; far fewer when idle cycles are skipped). Engine dependent: see
    /// [`HOST_DEPENDENT_KEYS`].
    pub sm_visits: u64,
    /// Wall-clock seconds of the simulation loop. Host dependent.
    pub sim_wall_seconds: f64,
    /// `rays / sim_wall_seconds`. Host dependent.
    pub simulated_rays_per_second: f64,
}

/// The statistics as a JSON value without the [`HOST_DEPENDENT_KEYS`] (for comparing runs).
pub fn comparable_json(stats: &SimStats) -> serde_json::Value {
    let mut v = serde_json::to_value(stats).unwrap_or(serde_json::Value::Null);
    if let Some(map) = v.as_object_mut() {
        for k in HOST_DEPENDENT_KEYS {
            map.remove(k);
        }
    }
    v
}

/// Where the time of suspended CTAs went, summed over suspends and resumes (cycles).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct VirtTiming {
    /// From the start of a suspend to the CTA leaving its slot (its last state store accepted):
    /// the slot is held while the state is stored.
    pub save_cycles: u64,
    /// From a suspended CTA being ready to resume (all its rays traced) to its getting a slot.
    pub resume_wait_cycles: u64,
    /// From getting a slot to running again (its last state load back): the restore latency a
    /// resumed CTA waits for while holding its slot. 0 for a CTA whose state came back before
    /// it got a slot (`virtualization.restore = "on_ready"`).
    pub restore_cycles: u64,
}
