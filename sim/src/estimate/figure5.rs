//! The paper's Figure 5 analytical model (section 2.4): the potential speedup of treelets over
//! the baseline as the number of concurrent rays grows, computed from functional node-fetch
//! traces (`vtq figure5`).
//!
//! Every BVH access is taken to be a miss that costs the memory latency, for both designs:
//!
//! - **baseline**: cycles = nodes fetched by all rays x latency (each ray fetches its own);
//! - **treelet queues**: rays are processed in batches of `C` concurrent rays, and a batch
//!   fetches each treelet its rays visit once: cycles = sum over batches of the nodes of the
//!   unique treelets the batch visits x latency.
//!
//! The speedup is the ratio (the latency cancels). The paper's text multiplies the unique
//! treelets by "the number of nodes in a treelet"; [`Figure5Row`] gives both readings: each
//! treelet's own node count (`speedup`), and every treelet counted as full
//! (`treelet_bytes / 64` nodes, `speedup_full_treelets`), which differ by the treelet fill.
//!
//! Rays are batched in issue order: wave by wave (all primary rays, then all first bounces,
//! ...; a path that ended has no ray in later waves), each wave in CTA order (pixel tiles as the
//! CTA scheduler hands them out) and pixel order within a tile. Traces use the treelet
//! traversal order of the baseline RT unit (paper section 5).

use rayon::prelude::*;
use serde::Serialize;

use crate::model::bvh::HwBvh;
use crate::model::geometry::Ray;
use crate::model::gpu::cta_scheduler::CtaScheduler;
use crate::model::traversal::{trace_with_fetches, Order};
use crate::model::workload::pathtracer::Render;

/// Bytes of the unit the full-treelet reading counts a treelet in (one 64 B node).
const NODE_BYTES: u64 = 64;

/// What the model needs of one ray: its node fetches and the treelets they touch.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RayTrace {
    /// Nodes fetched (the header included).
    pub fetches: u64,
    /// The distinct treelets of those fetches, ascending.
    pub treelets: Vec<u32>,
}

/// One row of the model: a batch size and the two designs' cycle counts in units of the
/// memory latency.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Figure5Row {
    /// Concurrent rays per batch.
    pub concurrent_rays: u64,
    /// Batches.
    pub batches: u64,
    /// Baseline: nodes fetched by all rays.
    pub baseline_fetches: u64,
    /// Treelet queues: sum over batches of the unique treelets' node counts.
    pub treelet_fetches: u64,
    /// `baseline_fetches / treelet_fetches`.
    pub speedup: f64,
    /// Sum over batches of the unique treelets (each fetched once per batch).
    pub unique_treelets: u64,
    /// `baseline_fetches / (unique_treelets x treelet_bytes / 64)`: every treelet counted as
    /// full.
    pub speedup_full_treelets: f64,
}

/// The rays of `render` in issue order (module documentation): wave by wave, each in CTA order
/// for CTAs of `threads_per_cta` threads.
pub fn issue_order(render: &Render, threads_per_cta: u32) -> Vec<Ray> {
    let sched = CtaScheduler::new(render.width, render.height, threads_per_cta);
    let pixels: Vec<u32> = (0..sched.total())
        .flat_map(|cta| sched.pixels(cta).into_iter().flatten())
        .collect();
    let waves = pixels
        .iter()
        .map(|&p| render.pixel_rays(p as usize).len())
        .max()
        .unwrap_or(0);
    let mut out = Vec::with_capacity(render.rays.len());
    for wave in 0..waves {
        for &p in &pixels {
            if let Some(r) = render.pixel_rays(p as usize).get(wave) {
                out.push(*r);
            }
        }
    }
    out
}

/// The traces of `rays` through `bvh` in the treelet order (in parallel; in ray order).
pub fn traces(bvh: &HwBvh, rays: &[Ray]) -> Vec<RayTrace> {
    rays.par_iter()
        .map_init(Vec::new, |fetches, ray| {
            fetches.clear();
            trace_with_fetches(bvh, ray, Order::Treelet, fetches);
            let mut treelets: Vec<u32> = fetches.iter().map(|f| f.treelet).collect();
            treelets.sort_unstable();
            treelets.dedup();
            RayTrace {
                fetches: fetches.len() as u64,
                treelets,
            }
        })
        .collect()
}

/// The model for batches of `concurrent_rays` rays over `traces` (in issue order), with
/// `treelet_nodes[t]` the node count of treelet `t` and treelets of `treelet_bytes` bytes.
/// `concurrent_rays` must be positive.
pub fn row(
    traces: &[RayTrace],
    treelet_nodes: &[u32],
    treelet_bytes: u32,
    concurrent_rays: u64,
) -> Figure5Row {
    let baseline: u64 = traces.iter().map(|t| t.fetches).sum();
    let (mut treelet, mut unique, mut batches) = (0u64, 0u64, 0u64);
    let mut seen = vec![u64::MAX; treelet_nodes.len()];
    for (b, batch) in traces.chunks(concurrent_rays.max(1) as usize).enumerate() {
        batches += 1;
        for t in batch.iter().flat_map(|r| &r.treelets) {
            let i = *t as usize;
            if seen[i] != b as u64 {
                seen[i] = b as u64;
                unique += 1;
                treelet += treelet_nodes[i] as u64;
            }
        }
    }
    let full = unique * (treelet_bytes as u64 / NODE_BYTES);
    let ratio = |a: u64, b: u64| if b == 0 { 0.0 } else { a as f64 / b as f64 };
    Figure5Row {
        concurrent_rays,
        batches,
        baseline_fetches: baseline,
        treelet_fetches: treelet,
        speedup: ratio(baseline, treelet),
        unique_treelets: unique,
        speedup_full_treelets: ratio(baseline, full),
    }
}

/// The model over `bvh` for every batch size of `concurrent`, from the rays of `render`
/// (issued by CTAs of `threads_per_cta` threads).
pub fn model(
    bvh: &HwBvh,
    render: &Render,
    threads_per_cta: u32,
    concurrent: &[u64],
) -> Vec<Figure5Row> {
    let rays = issue_order(render, threads_per_cta);
    let traces = traces(bvh, &rays);
    let nodes: Vec<u32> = bvh.treelets().iter().map(|t| t.nodes).collect();
    let bytes = bvh.params().treelet_bytes;
    concurrent
        .iter()
        .map(|&c| row(&traces, &nodes, bytes, c))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(fetches: u64, treelets: &[u32]) -> RayTrace {
        RayTrace {
            fetches,
            treelets: treelets.to_vec(),
        }
    }

    #[test]
    fn batches_share_each_treelet_once() {
        // Treelets 0..3 of 4, 2, 8 nodes; slots of 8 nodes (512 B).
        let nodes = [4, 2, 8];
        let traces = [
            ray(5, &[0, 1]),
            ray(6, &[0, 2]),
            ray(3, &[0]),
            ray(9, &[1, 2]),
        ];
        // One ray per batch: every ray fetches its treelets whole.
        let r = row(&traces, &nodes, 512, 1);
        assert_eq!(r.baseline_fetches, 23);
        assert_eq!(r.batches, 4);
        assert_eq!(r.treelet_fetches, 6 + 12 + 4 + 10);
        assert_eq!(r.unique_treelets, 7);
        // Two rays per batch: {0,1,2} then {0,1,2}.
        let r = row(&traces, &nodes, 512, 2);
        assert_eq!(
            (r.batches, r.treelet_fetches, r.unique_treelets),
            (2, 28, 6)
        );
        // All at once: each treelet once.
        let r = row(&traces, &nodes, 512, 4);
        assert_eq!(
            (r.batches, r.treelet_fetches, r.unique_treelets),
            (1, 14, 3)
        );
        assert!((r.speedup - 23.0 / 14.0).abs() < 1e-12);
        assert!((r.speedup_full_treelets - 23.0 / 24.0).abs() < 1e-12);
    }
}
