//! The analytical tier's timing model of each design (docs/accuracy.md), from the functional
//! trace and a functional cache model; no fitted constants, every number comes from the
//! configuration.
//!
//! **Caches.** Each SM has an LRU L1 and all share an LRU L2 of the configured shapes, filled
//! by the fetch stream in the order the design issues it (SMs interleaved trip by trip); a fetch
//! costs `l1_latency` on an L1 hit, `+ l2_latency` on an L2 hit, `+ dram_latency` from DRAM
//! (bandwidth and queueing are not modelled).
//!
//! **Baseline.** The RT unit holds one warp (Table 1): a trip of a warp takes the longer of its
//! issue time (one 32 B request per cycle; lanes fetching the same node at the same step merge)
//! and its slowest lane's chain of fetch latencies and test delays. An SM's time is the sum of
//! its trips; the GPU's the slowest SM's.
//!
//! **Treelet prefetching.** The baseline, plus: at each step of a trip, when one treelet holds
//! `mode.prefetch_threshold` of the lanes' next nodes and was not prefetched in the last four
//! prefetches, all its sectors are put in the L1 (in idle request cycles, so at no issue cost).
//!
//! **Treelet queues.** Per SM the rays in flight (`hw.max_rays` with ray virtualization, else
//! the CTA slots' threads) of one bounce level are queued by the treelet they need next; while
//! the largest queue holds at least `hw.underpopulation_threshold` rays it is processed in warps
//! of `warp_size` rays (each ray's fetches inside the treelet; the treelet's nodes stay in the
//! L1 across its warps), and each ray moves to the queue of its next treelet, costing a 32 B ray
//! record load and store request. The rays left (underpopulated queues) then finish
//! ray-stationary in warps formed from the queues; with warp repacking below `r` active rays
//! (`hw.repack_threshold`) a warp keeps on average `(r + warp_size) / 2` lanes busy, so the
//! phase takes the longer of its requests and its total lane latency over that many lanes;
//! without repacking, as baseline trips. Without grouping (`mode.grouping = false`) every queue
//! is processed treelet-stationary however small.

use std::collections::BTreeMap;

use crate::config::{ModeKind, SimConfig};
use crate::memory::{SectorCache, SectorState};

use super::trace::{FrameTrace, Node, Trip};

/// What the model gives for one design.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Timing {
    /// Estimated cycles.
    pub cycles: f64,
    /// BVH L1 miss rate of the functional cache model.
    pub bvh_l1_miss_rate: f64,
    /// SIMT efficiency the model implies (busy lane cycles over warp cycles x warp size).
    pub simt_efficiency: f64,
}

/// The caches of the GPU, functionally (no timing).
struct Caches {
    l1: Vec<SectorCache>,
    l2: SectorCache,
    l1_ways: u32,
    l2_ways: u32,
    line_shift: u32,
    sector_shift: u32,
    /// Latency of an L1 hit, an L2 hit and a DRAM access.
    latency: [u64; 3],
    accesses: u64,
    misses: u64,
}

impl Caches {
    fn new(cfg: &SimConfig, sms: usize) -> Caches {
        let m = &cfg.memory;
        let (l1, l2, dram) = (
            u64::from(m.l1_latency),
            u64::from(m.l2_latency),
            u64::from(m.dram_latency),
        );
        Caches {
            l1: (0..sms)
                .map(|_| SectorCache::new(m.l1_geometry()))
                .collect(),
            l2: SectorCache::new(m.l2_geometry()),
            l1_ways: m.l1_geometry().ways,
            l2_ways: m.l2_geometry().ways,
            line_shift: m.line_bytes.trailing_zeros(),
            sector_shift: m.sector_bytes.trailing_zeros(),
            latency: [l1, l1 + l2, l1 + l2 + dram],
            accesses: 0,
            misses: 0,
        }
    }

    /// Puts the sector of `addr` in `cache` (LRU), returning whether it was there.
    fn touch(cache: &mut SectorCache, ways: u32, line: u64, sector: u32) -> bool {
        if let Some(slot) = cache.lookup(line) {
            if cache.sector_state(slot, sector, 0) == SectorState::Ready {
                cache.touch(slot);
                return true;
            }
        }
        if let Ok(slot) = cache.find_slot(line, 0, 0..ways) {
            cache.install(slot, line, sector, 0);
        }
        false
    }

    fn locate(&self, addr: u64) -> (u64, u32) {
        let line = addr >> self.line_shift;
        let sector = ((addr & ((1 << self.line_shift) - 1)) >> self.sector_shift) as u32;
        (line, sector)
    }

    /// A demand access of SM `sm` to the 32 B chunk at `addr`: its latency.
    fn access(&mut self, sm: usize, addr: u64) -> u64 {
        let (line, sector) = self.locate(addr);
        self.accesses += 1;
        if Self::touch(&mut self.l1[sm], self.l1_ways, line, sector) {
            return self.latency[0];
        }
        self.misses += 1;
        if Self::touch(&mut self.l2, self.l2_ways, line, sector) {
            self.latency[1]
        } else {
            self.latency[2]
        }
    }

    /// A node's fetch: every chunk accessed, latency of the slowest.
    fn fetch(&mut self, sm: usize, node: &Node) -> u64 {
        (0..u64::from(node.chunks))
            .map(|c| self.access(sm, u64::from(node.addr) + 32 * c))
            .max()
            .unwrap_or(0)
    }

    /// A prefetch of every sector of `[base, base + bytes)` into SM `sm`'s L1 (and the L2).
    fn prefetch(&mut self, sm: usize, base: u64, bytes: u64) {
        for addr in (base..base + bytes).step_by(32) {
            let (line, sector) = self.locate(addr);
            Self::touch(&mut self.l1[sm], self.l1_ways, line, sector);
            Self::touch(&mut self.l2, self.l2_ways, line, sector);
        }
    }
}

/// Time and busy lane cycles of work run as one warp whose lanes hold `segments` (each a
/// sequence of nodes), fetched step by step: the longer of the issue time (requests after
/// merging identical nodes at the same step) and the slowest lane's latency chain. `before`
/// runs at each step with the lanes' next nodes (the prefetcher).
fn warp_time(
    caches: &mut Caches,
    sm: usize,
    segments: &[&[Node]],
    mut before: impl FnMut(&mut Caches, &[&Node]),
) -> (u64, u64) {
    let steps = segments.iter().map(|s| s.len()).max().unwrap_or(0);
    let mut lane_time = vec![0u64; segments.len()];
    let mut requests = 0u64;
    let mut next: Vec<&Node> = Vec::with_capacity(segments.len());
    // Nodes fetched at this step and their latency: lanes asking for the same node merge into
    // one request (as the RT unit merges a warp's identical requests).
    let mut seen: Vec<(u32, u64)> = Vec::with_capacity(segments.len());
    for j in 0..steps {
        next.clear();
        next.extend(segments.iter().filter_map(|s| s.get(j)));
        before(caches, &next);
        seen.clear();
        for (lane, seg) in segments.iter().enumerate() {
            let Some(node) = seg.get(j) else { continue };
            let latency = match seen.iter().find(|(a, _)| *a == node.addr) {
                Some(&(_, latency)) => latency,
                None => {
                    requests += u64::from(node.chunks);
                    let latency = caches.fetch(sm, node);
                    seen.push((node.addr, latency));
                    latency
                }
            };
            lane_time[lane] += latency + u64::from(node.delay);
        }
    }
    let busy: u64 = lane_time.iter().sum();
    let time = lane_time.iter().copied().max().unwrap_or(0).max(requests);
    (time, busy)
}

/// The baseline's (or, with a prefetcher, treelet prefetching's) trips of a set of SMs, with
/// the prefetcher's policy `prefetch` (threshold, treelet size) if any.
fn ray_stationary(
    cfg: &SimConfig,
    trace: &FrameTrace,
    bvh_treelets: &[(u64, u64)],
    prefetch: Option<f64>,
) -> Timing {
    let sms = cfg.gpu.sms as usize;
    let mut caches = Caches::new(cfg, sms);
    let slots = (cfg.gpu.max_ctas_per_sm as usize)
        .min(cfg.gpu.max_warps_per_sm as usize / cfg.warps_per_cta().max(1) as usize)
        .max(1);
    // Per SM, its trips in issue order: resident CTAs in groups of `slots`, bounce level by
    // bounce level, warp by warp.
    let per_sm: Vec<Vec<&Trip>> = (0..sms)
        .map(|sm| trace.sm_levels(sm, sms, slots).concat())
        .collect();
    let mut time = vec![0u64; sms];
    let (mut busy, mut warp_cycles) = (0u64, 0u64);
    let mut history: Vec<Vec<u32>> = vec![Vec::new(); sms];
    let longest = per_sm.iter().map(Vec::len).max().unwrap_or(0);
    let warp_size = u64::from(cfg.gpu.warp_size);
    for k in 0..longest {
        for sm in 0..sms {
            let Some(trip) = per_sm[sm].get(k) else {
                continue;
            };
            let segments: Vec<&[Node]> = trip.rays.iter().map(Vec::as_slice).collect();
            let hist = &mut history[sm];
            let (t, b) = warp_time(&mut caches, sm, &segments, |caches, next| {
                let Some(threshold) = prefetch else { return };
                let mut counts: Vec<(u32, u32)> = Vec::new();
                for n in next {
                    match counts.iter_mut().find(|(t, _)| *t == n.treelet) {
                        Some(c) => c.1 += 1,
                        None => counts.push((n.treelet, 1)),
                    }
                }
                let Some(&(treelet, count)) = counts
                    .iter()
                    .max_by_key(|&&(t, c)| (c, std::cmp::Reverse(t)))
                else {
                    return;
                };
                if (count as f64) < threshold * next.len() as f64 || hist.contains(&treelet) {
                    return;
                }
                hist.push(treelet);
                if hist.len() > 4 {
                    hist.remove(0);
                }
                if let Some(&(base, bytes)) = bvh_treelets.get(treelet as usize) {
                    caches.prefetch(sm, base, bytes);
                }
            });
            time[sm] += t;
            busy += b;
            warp_cycles += t * warp_size;
        }
    }
    timing(&caches, &time, busy, warp_cycles)
}

/// The model's result from per-SM times and the lane counts.
fn timing(caches: &Caches, time: &[u64], busy: u64, lane_cycles: u64) -> Timing {
    Timing {
        cycles: time.iter().copied().max().unwrap_or(0) as f64,
        bvh_l1_miss_rate: ratio(caches.misses, caches.accesses),
        simt_efficiency: ratio(busy, lane_cycles).min(1.0),
    }
}

/// `a / b`, 0 when `b` is 0.
fn ratio(a: u64, b: u64) -> f64 {
    if b == 0 {
        0.0
    } else {
        a as f64 / b as f64
    }
}

/// A ray in the treelet queues: its nodes and how far it got.
struct Queued<'t> {
    nodes: &'t [Node],
    at: usize,
}

impl Queued<'_> {
    /// The treelet of its next node (`None`: done).
    fn treelet(&self) -> Option<u32> {
        self.nodes.get(self.at).map(|n| n.treelet)
    }

    /// Its nodes from `at` while they stay in the current treelet, advancing past them.
    fn segment(&mut self) -> &[Node] {
        let start = self.at;
        let Some(t) = self.treelet() else {
            return &[];
        };
        while self.nodes.get(self.at).is_some_and(|n| n.treelet == t) {
            self.at += 1;
        }
        &self.nodes[start..self.at]
    }
}

/// The remaining nodes of the rays `warp` (indices into `queued`), each ray now run to its end.
fn take_rests<'t>(queued: &mut [Queued<'t>], warp: &[usize]) -> Vec<&'t [Node]> {
    warp.iter()
        .map(|&i| {
            let q = &mut queued[i];
            let start = q.at;
            q.at = q.nodes.len();
            &q.nodes[start..]
        })
        .collect()
}

/// The treelet-queue design (see the module documentation).
fn treelet_queues(cfg: &SimConfig, trace: &FrameTrace) -> Timing {
    let sms = cfg.gpu.sms as usize;
    let mut caches = Caches::new(cfg, sms);
    let warp_size = cfg.gpu.warp_size as usize;
    let threads = cfg.gpu.threads_per_cta.max(1) as usize;
    let in_flight = if cfg.mode.virtualization {
        cfg.hw.max_rays as usize
    } else {
        let slots = (cfg.gpu.max_ctas_per_sm as usize)
            .min(cfg.gpu.max_warps_per_sm as usize / cfg.warps_per_cta().max(1) as usize);
        slots.max(1) * threads
    };
    let batch_ctas = (in_flight / threads).max(1);
    let threshold = if cfg.mode.grouping {
        cfg.hw.underpopulation_threshold as usize
    } else {
        0
    };
    let repack = cfg.hw.repack_threshold as usize;
    let mut time = vec![0u64; sms];
    let (mut busy, mut lane_cycles) = (0u64, 0u64);
    // Batches of each SM, then bounce levels, SMs interleaved batch by batch.
    let batches: Vec<Vec<Vec<&[Node]>>> = (0..sms)
        .map(|sm| {
            trace
                .sm_levels(sm, sms, batch_ctas)
                .into_iter()
                .map(|level| {
                    level
                        .iter()
                        .flat_map(|t| t.rays.iter().map(Vec::as_slice))
                        .collect()
                })
                .collect()
        })
        .collect();
    let longest = batches.iter().map(Vec::len).max().unwrap_or(0);
    for k in 0..longest {
        for sm in 0..sms {
            let Some(rays) = batches[sm].get(k) else {
                continue;
            };
            let (t, b, l) = queue_batch(&mut caches, sm, rays, warp_size, threshold, repack);
            time[sm] += t;
            busy += b;
            lane_cycles += l;
        }
    }
    timing(&caches, &time, busy, lane_cycles)
}

/// One batch of rays of SM `sm` through the treelet queues: (cycles, busy lane cycles, lane
/// cycles).
fn queue_batch(
    caches: &mut Caches,
    sm: usize,
    rays: &[&[Node]],
    warp_size: usize,
    threshold: usize,
    repack: usize,
) -> (u64, u64, u64) {
    let mut queued: Vec<Queued> = rays.iter().map(|n| Queued { nodes: n, at: 0 }).collect();
    let (mut time, mut busy, mut lanes) = (0u64, 0u64, 0u64);
    let ws = warp_size as u64;
    let mut queues: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
    for (i, q) in queued.iter().enumerate() {
        if let Some(t) = q.treelet() {
            queues.entry(t).or_default().push(i);
        }
    }
    // Treelet-stationary: the largest queue (ties: the lowest treelet) while it is populated
    // enough.
    loop {
        let Some((&treelet, members)) = queues
            .iter()
            .max_by_key(|(t, m)| (m.len(), std::cmp::Reverse(**t)))
        else {
            return (time, busy, lanes);
        };
        if members.len() < threshold.max(1) {
            break;
        }
        let members = queues.remove(&treelet).expect("found above");
        for warp in members.chunks(warp_size) {
            let mut segs: Vec<&[Node]> = Vec::with_capacity(warp.len());
            for &i in warp {
                let (nodes, at) = (queued[i].nodes, queued[i].at);
                let len = queued[i].segment().len();
                segs.push(&nodes[at..at + len]);
            }
            let (t, b) = warp_time(caches, sm, &segs, |_, _| {});
            // Ray records: a load when the warp forms, a store when each ray leaves.
            let records = 2 * warp.len() as u64;
            time += t + records;
            busy += b;
            lanes += (t + records) * ws;
        }
        for &i in &members {
            if let Some(t) = queued[i].treelet() {
                queues.entry(t).or_default().push(i);
            }
        }
    }
    // Ray-stationary for the rest, warps formed from the queues in treelet order.
    let rest: Vec<usize> = queues.into_values().flatten().collect();
    if repack > 0 {
        let mut requests = 0u64;
        let mut latency = 0u64;
        for warp in rest.chunks(warp_size) {
            let segs = take_rests(&mut queued, warp);
            requests += segs
                .iter()
                .map(|s| s.iter().map(|n| u64::from(n.chunks)).sum::<u64>())
                .sum::<u64>()
                + warp.len() as u64;
            let (_, b) = warp_time(caches, sm, &segs, |_, _| {});
            latency += b;
        }
        let active = ((repack + warp_size) as f64 / 2.0).max(1.0);
        let t = (latency as f64 / active).ceil().max(requests as f64) as u64;
        time += t;
        busy += latency;
        lanes += t * ws;
    } else {
        for warp in rest.chunks(warp_size) {
            let segs = take_rests(&mut queued, warp);
            let (t, b) = warp_time(caches, sm, &segs, |_, _| {});
            time += t + warp.len() as u64;
            busy += b;
            lanes += (t + warp.len() as u64) * ws;
        }
    }
    (time, busy, lanes)
}

/// The model's estimate for `cfg`'s design on the traced frame; `treelets` are the BVH's
/// treelets as (base address, bytes).
pub fn estimate(cfg: &SimConfig, trace: &FrameTrace, treelets: &[(u64, u64)]) -> Timing {
    match cfg.mode.kind {
        ModeKind::Baseline => ray_stationary(cfg, trace, treelets, None),
        ModeKind::Prefetch => {
            ray_stationary(cfg, trace, treelets, Some(cfg.mode.prefetch_threshold))
        }
        ModeKind::Queues => treelet_queues(cfg, trace),
    }
}
