//! The functional profile the sampled tier stratifies by: for every CTA of the frame, the rays
//! its threads trace and the BVH nodes those rays fetch — in all, and as its warps fetch them in
//! lockstep (each trace's longest ray) — from the functional path tracer (the same paths, hence
//! the same rays, the simulation traces) in the treelet traversal order the simulated RT units
//! use. One traversal per ray, CTAs in parallel.
//!
//! On frames small enough for a design with ray virtualization to hold every CTA at once, the
//! profile also sums each *stripe* — the CTAs `c` with `c mod gpu.sms = s`, which SM `s` runs
//! when every CTA is resident (the CTA scheduler's round-robin fill) — with its footprint: the
//! distinct 32 B lines of BVH nodes its rays fetch, the working set its SM's L1 must hold
//! ([`super::stripes`] samples stripes by it).

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use crate::model::bvh::HwBvh;
use crate::model::config::SimConfig;
use crate::model::gpu::cta_scheduler::CtaScheduler;
use crate::model::scene::Scene;
use crate::model::traversal::{trace_with_fetches, Fetch, Order};
use crate::model::workload::camera::CameraFrame;
use crate::model::workload::pathtracer::{PathState, RenderError};

/// The work of one CTA.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CtaWork {
    /// Rays its threads trace.
    pub rays: u64,
    /// BVH node fetches of those rays (treelet order, header included).
    pub fetches: u64,
    /// Its warps' fetches in lockstep: per warp and trace (a warp's `k`-th trace holds its
    /// threads' `k`-th rays), the most fetches of any of its rays, summed — what a warp costs
    /// an RT unit that keeps it until its slowest ray is done.
    pub warp_fetches: u64,
}

/// The work of one stripe: the CTAs `c` with `c mod gpu.sms = s`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StripeWork {
    /// Rays of its CTAs.
    pub rays: u64,
    /// BVH node fetches of those rays.
    pub fetches: u64,
    /// Distinct 32 B lines of BVH nodes those rays fetch (its footprint).
    pub lines: u64,
}

/// The work of every CTA of a frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    /// Per CTA, in CTA order (tiles row-major).
    pub ctas: Vec<CtaWork>,
    /// Per stripe `s` (the CTAs `c mod gpu.sms = s`), when the frame has at most as many CTAs
    /// as the GPU's SMs can hold at once under ray virtualization ([`stripes_possible`]); empty
    /// otherwise.
    pub stripes: Vec<StripeWork>,
    /// Wall-clock seconds the profile took.
    pub seconds: f64,
    /// The whole frame's footprint, one bit per 32 B line of the BVH's address space (bit `i`
    /// of word `w`: line `64 w + i`), with `sample.warm_l2` (empty otherwise).
    pub frame_lines: Vec<u64>,
}

/// Bytes of a BVH line in a footprint (the memory system's sector).
pub const LINE_BYTES: u32 = 32;

/// Whether a frame of `ctas` CTAs is small enough for `cfg`'s GPU to hold every CTA at once in
/// some design: a ray-virtualizing SM holds the most (its CTA slots, or as many as `hw.max_rays`
/// covers). The profile sums the stripes only then.
pub fn stripes_possible(cfg: &SimConfig, ctas: usize) -> bool {
    let mut virtualizing = cfg.clone();
    virtualizing.mode.virtualization = true;
    super::dispatch::holds_every_cta(&virtualizing, ctas)
}

/// The fetches of warps of `warp` threads tracing in lockstep: per warp, the sum over its
/// traces `k` of the most fetches of any of its threads' `k`-th rays (`traces[t]`: thread `t`'s
/// rays' fetches in order).
fn lockstep_fetches(traces: &[Vec<u32>], warp: usize) -> u64 {
    traces
        .chunks(warp)
        .map(|lanes| {
            let longest = lanes.iter().map(Vec::len).max().unwrap_or(0);
            (0..longest)
                .map(|k| {
                    let most = lanes.iter().filter_map(|t| t.get(k)).max();
                    u64::from(most.copied().unwrap_or(0))
                })
                .sum::<u64>()
        })
        .sum()
}

/// Sets the bits of `bits` (one per 32 B line of the BVH's address space) of every line the
/// fetches `fetches` touch.
fn mark_lines(bits: &[AtomicU64], fetches: &[Fetch]) {
    for f in fetches {
        let first = f.addr / LINE_BYTES;
        let last = (f.addr + f.bytes.max(1) - 1) / LINE_BYTES;
        for line in first..=last {
            // Every node lies inside the address space.
            let Some(word) = bits.get((line / 64) as usize) else {
                debug_assert!(false, "line {line} beyond the BVH");
                continue;
            };
            let bit = 1u64 << (line % 64);
            if word.load(Ordering::Relaxed) & bit == 0 {
                word.fetch_or(bit, Ordering::Relaxed);
            }
        }
    }
}

impl Profile {
    /// Profiles `cfg`'s workload on `scene` (whose BVH is `bvh`) on all rayon threads.
    pub fn new(scene: &Scene, bvh: &HwBvh, cfg: &SimConfig) -> Result<Profile, RenderError> {
        let start = Instant::now();
        let settings = cfg.render_settings();
        settings.validate()?;
        let frame = CameraFrame::new(&scene.camera, settings.width, settings.height)?;
        let scheduler = CtaScheduler::new(settings.width, settings.height, cfg.gpu.threads_per_cta);
        let with_stripes = stripes_possible(cfg, scheduler.total() as usize);
        let sms = cfg.gpu.sms.max(1) as usize;
        let warp = cfg.gpu.warp_size.max(1) as usize;
        // Footprints: one bit per 32 B line of the BVH's address space (a slot of
        // `treelet_bytes` per treelet, the header's included), set by every fetch of a stripe's
        // CTAs (per stripe) or of the frame's (for `sample.warm_l2`).
        let words = {
            let space = (bvh.treelets().len() as u64 + 2) * u64::from(bvh.params().treelet_bytes);
            (space as usize).div_ceil(LINE_BYTES as usize * 64)
        };
        let frame_bits: Vec<AtomicU64> = (0..if cfg.sample.warm_l2 { words } else { 0 })
            .map(|_| AtomicU64::new(0))
            .collect();
        let footprints: Vec<Vec<AtomicU64>> = (0..if with_stripes { sms } else { 0 })
            .map(|_| (0..words).map(|_| AtomicU64::new(0)).collect())
            .collect();
        let ctas = (0..scheduler.total())
            .into_par_iter()
            .map_init(
                || (Vec::new(), Vec::new()),
                |(fetches, traces): &mut (Vec<_>, Vec<Vec<u32>>), cta| {
                    let mut work = CtaWork::default();
                    let footprint = footprints.get(cta as usize % sms);
                    let pixels = scheduler.pixels(cta);
                    // Per thread, the fetches of each of its rays in order.
                    traces.resize_with(pixels.len(), Vec::new);
                    traces.iter_mut().for_each(Vec::clear);
                    for (thread, pixel) in pixels.into_iter().enumerate() {
                        let Some(pixel) = pixel else { continue };
                        for sample in 0..settings.spp {
                            let (mut path, mut ray) =
                                PathState::new(&frame, &settings, pixel, sample);
                            loop {
                                fetches.clear();
                                let hit = trace_with_fetches(bvh, &ray, Order::Hardware, fetches);
                                work.rays += 1;
                                work.fetches += fetches.len() as u64;
                                traces[thread].push(fetches.len() as u32);
                                if let Some(bits) = footprint {
                                    mark_lines(bits, fetches);
                                }
                                if !frame_bits.is_empty() {
                                    mark_lines(&frame_bits, fetches);
                                }
                                match path.on_hit(scene, hit) {
                                    Some(next) => ray = next,
                                    None => break,
                                }
                            }
                        }
                    }
                    work.warp_fetches = lockstep_fetches(traces, warp);
                    work
                },
            )
            .collect::<Vec<CtaWork>>();
        let stripes = footprints
            .iter()
            .enumerate()
            .map(|(s, bits)| {
                let mut stripe = StripeWork {
                    lines: bits
                        .iter()
                        .map(|w| u64::from(w.load(Ordering::Relaxed).count_ones()))
                        .sum(),
                    ..StripeWork::default()
                };
                for work in ctas.iter().skip(s).step_by(sms) {
                    stripe.rays += work.rays;
                    stripe.fetches += work.fetches;
                }
                stripe
            })
            .collect();
        Ok(Profile {
            ctas,
            stripes,
            seconds: start.elapsed().as_secs_f64(),
            frame_lines: frame_bits
                .iter()
                .map(|w| w.load(Ordering::Relaxed))
                .collect(),
        })
    }

    /// Total work of the CTAs `subset` (all of them with `None`).
    pub fn work(&self, subset: Option<&[u32]>) -> CtaWork {
        let add = |a: CtaWork, b: &CtaWork| CtaWork {
            rays: a.rays + b.rays,
            fetches: a.fetches + b.fetches,
            warp_fetches: a.warp_fetches + b.warp_fetches,
        };
        match subset {
            None => self.ctas.iter().fold(CtaWork::default(), add),
            Some(s) => s
                .iter()
                .map(|&c| &self.ctas[c as usize])
                .fold(CtaWork::default(), add),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Warps of two threads: each trace costs its longest ray; a thread with fewer rays (its
    /// path ended) or none (off the frame) adds nothing to the traces after its last.
    #[test]
    fn lockstep_fetches_sum_each_traces_longest_ray() {
        let traces = vec![vec![3, 1], vec![5], vec![2, 4, 6], vec![]];
        // Warp 0: max(3, 5) + 1; warp 1: 2 + 4 + 6.
        assert_eq!(lockstep_fetches(&traces, 2), 6 + 12);
        // One warp of four: max(3, 5, 2) + max(1, 4) + 6.
        assert_eq!(lockstep_fetches(&traces, 4), 5 + 4 + 6);
        // Threads alone: every fetch.
        assert_eq!(lockstep_fetches(&traces, 1), 21);
        assert_eq!(lockstep_fetches(&[], 32), 0);
    }
}
