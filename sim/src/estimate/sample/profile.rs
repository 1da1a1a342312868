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
//!
//! With `sample.profile_stride` the profile traces part of the frame's warps and estimates
//! the rest: within each CTA up to its warps, beyond that only some CTAs (a diagonal pattern
//! over the tiles), each other CTA taking the mean work of its traced neighbours.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use crate::model::bvh::HwBvh;
use crate::model::config::SimConfig;
use crate::model::gpu::cta_scheduler::CtaScheduler;
use crate::model::scene::Scene;
use crate::model::traversal::{trace_occlusion_with_fetches, trace_with_fetches, Fetch, Order};
use crate::model::workload::camera::CameraFrame;
use crate::model::workload::kind::{Sampler, Workload};
use crate::model::workload::pathtracer::{RenderError, RenderSettings};

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

impl CtaWork {
    /// The work traced times `scale` (rounded), the estimate of a CTA's work from the part of
    /// its warps the profile traced ([`Profile::new`] with `sample.profile_stride` above 1).
    fn scaled(self, scale: f64) -> CtaWork {
        if scale == 1.0 {
            return self;
        }
        let s = |v: u64| (v as f64 * scale).round() as u64;
        CtaWork {
            rays: s(self.rays),
            fetches: s(self.fetches),
            warp_fetches: s(self.warp_fetches),
        }
    }
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
    /// Per CTA, when the frame's footprint is at most `sample.ghost_l2_footprint` L2s: the
    /// 32 B BVH sectors (byte address / 32) its rays read, in order, that miss an L1 filter
    /// private to the CTA (the GPU's L1 capacity and line size, 8-way LRU) — the reads its SM
    /// sends the L2 (empty otherwise); with `sample.profile_stride` above 1, those of its traced
    /// warps.
    pub cta_streams: Vec<Vec<u32>>,
    /// Bytes of the frame's footprint (its distinct 32 B BVH lines), with `sample.warm_l2` or
    /// `sample.ghost_l2_footprint` (0 otherwise).
    pub footprint_bytes: u64,
    /// `sample.profile_stride`: 1 when every warp was traced and [`Profile::ctas`] is exact,
    /// else each CTA's work is estimated from one warp in this many.
    pub stride: u32,
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

/// The 32 B lines (byte address / 32) node fetch `f` reads, in order.
fn lines_of(f: &Fetch) -> std::ops::RangeInclusive<u32> {
    f.addr / LINE_BYTES..=(f.addr + f.bytes.max(1) - 1) / LINE_BYTES
}

/// Sets the bits of `bits` (one per 32 B line of the BVH's address space) of every line the
/// fetches `fetches` touch.
fn mark_lines(bits: &[AtomicU64], fetches: &[Fetch]) {
    for f in fetches {
        for line in lines_of(f) {
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

/// Ways of [`L1Filter`]'s sets.
const FILTER_WAYS: usize = 8;

/// The L1 a CTA's reads pass before the L2, as the ghost streams see it: the GPU's L1 capacity
/// and line size in sets of [`FILTER_WAYS`] lines (LRU), sectors filled at once. An
/// approximation of the SM's L1 (which its CTAs share and the RT unit's warps interleave in),
/// good enough to say which lines an SM reads at the L2.
struct L1Filter {
    /// Per way: line + 1 (0: empty), its sectors' valid bits, its last use.
    ways: Vec<(u64, u32, u64)>,
    sets: u64,
    line_bytes: u64,
    now: u64,
}

impl L1Filter {
    fn new(l1_bytes: u32, line_bytes: u32) -> Self {
        let lines = (l1_bytes / line_bytes).max(1) as usize;
        let sets = lines.div_ceil(FILTER_WAYS).max(1);
        L1Filter {
            ways: vec![(0, 0, 0); sets * FILTER_WAYS],
            sets: sets as u64,
            line_bytes: u64::from(line_bytes),
            now: 0,
        }
    }

    /// Appends to `out` the 32 B sectors (byte address / 32) of `fetches` that miss, filling
    /// them.
    fn misses(&mut self, fetches: &[Fetch], out: &mut Vec<u32>) {
        for f in fetches {
            for sector_index in lines_of(f) {
                let addr = u64::from(sector_index) * u64::from(LINE_BYTES);
                let line = addr / self.line_bytes;
                let bit = 1u32 << ((addr % self.line_bytes) / u64::from(LINE_BYTES));
                self.now += 1;
                let set = (line % self.sets) as usize * FILTER_WAYS;
                let ways = &mut self.ways[set..set + FILTER_WAYS];
                if let Some(way) = ways.iter_mut().find(|w| w.0 == line + 1) {
                    way.2 = self.now;
                    if way.1 & bit == 0 {
                        way.1 |= bit;
                        out.push(sector_index);
                    }
                    continue;
                }
                let victim = ways.iter_mut().min_by_key(|w| w.2).expect("a set has ways");
                *victim = (line + 1, bit, self.now);
                out.push(sector_index);
            }
        }
    }
}

/// The frame as the profile traces it: each CTA's threads' paths, ray by ray.
struct Frame<'a> {
    scene: &'a Scene,
    bvh: &'a HwBvh,
    camera: CameraFrame,
    settings: RenderSettings,
    workload: Workload,
    scheduler: CtaScheduler,
}

impl<'a> Frame<'a> {
    fn new(scene: &'a Scene, bvh: &'a HwBvh, cfg: &SimConfig) -> Result<Self, RenderError> {
        let settings = cfg.render_settings();
        settings.validate()?;
        Ok(Frame {
            scene,
            bvh,
            camera: CameraFrame::new(&scene.camera, settings.width, settings.height)?,
            scheduler: CtaScheduler::new(settings.width, settings.height, cfg.gpu.threads_per_cta),
            workload: Workload::new(&settings, scene),
            settings,
        })
    }

    /// Traces CTA `cta`'s rays in thread order, each thread's in path order, calling
    /// `on_ray(thread, fetches)` with each ray's node fetches (`fetches` is scratch). Of its
    /// `n` warps of `warp` threads it traces those `w` with `w mod stride = cta mod min(stride,
    /// n)`, at least one (all with `stride` 1). Returns its threads and the factor that scales
    /// the traced warps' work to the CTA's (its warps over those traced; 1 with `stride` 1).
    fn trace_cta(
        &self,
        cta: u32,
        (warp, stride): (usize, usize),
        fetches: &mut Vec<Fetch>,
        mut on_ray: impl FnMut(usize, &[Fetch]),
    ) -> (usize, f64) {
        let pixels = self.scheduler.pixels(cta);
        let threads = pixels.len();
        let (warp, stride) = (warp.max(1), stride.max(1));
        let warps = threads.div_ceil(warp);
        let phase = cta as usize % stride.min(warps).max(1);
        let traced = (0..warps).filter(|w| w % stride == phase).count();
        let scale = if traced == 0 {
            0.0
        } else {
            warps as f64 / traced as f64
        };
        let sampler = Sampler {
            scene: self.scene,
            workload: &self.workload,
            frame: &self.camera,
            settings: &self.settings,
            raster: self.bvh,
        };
        for (thread, pixel) in pixels.into_iter().enumerate() {
            if (thread / warp) % stride != phase {
                continue;
            }
            let Some(pixel) = pixel else { continue };
            for sample in 0..self.settings.spp {
                let (mut path, mut next) = sampler.start(pixel, sample);
                while let Some(traced) = next {
                    fetches.clear();
                    let (ray, order) = (&traced.ray, Order::Hardware);
                    let hit = if traced.occlusion {
                        trace_occlusion_with_fetches(self.bvh, ray, order, fetches)
                    } else {
                        trace_with_fetches(self.bvh, ray, order, fetches)
                    };
                    on_ray(thread, fetches);
                    next = sampler.answer(&mut path, hit);
                }
            }
        }
        (threads, scale)
    }

    /// CTA `cta`'s work as [`Frame::trace_cta`] traces it with `(warp, stride)`, scaled to the
    /// whole CTA, calling `also(fetches)` with each traced ray's fetches (`scratch`: fetches
    /// and per-thread fetch counts).
    fn cta_work(
        &self,
        cta: u32,
        (warp, stride): (usize, usize),
        (fetches, traces): &mut (Vec<Fetch>, Vec<Vec<u32>>),
        mut also: impl FnMut(&[Fetch]),
    ) -> CtaWork {
        let mut work = CtaWork::default();
        // Per thread, the fetches of each of its rays in order.
        traces.iter_mut().for_each(Vec::clear);
        let (threads, scale) = self.trace_cta(cta, (warp, stride), fetches, |thread, fetches| {
            work.rays += 1;
            work.fetches += fetches.len() as u64;
            if traces.len() <= thread {
                traces.resize_with(thread + 1, Vec::new);
            }
            traces[thread].push(fetches.len() as u32);
            also(fetches);
        });
        traces.resize_with(threads, Vec::new);
        work.warp_fetches = lockstep_fetches(&traces[..threads], warp);
        work.scaled(scale)
    }
}

/// The frame's CTAs per CTA the profile traces, with `sample.profile_stride` `stride` on
/// `cfg`'s CTAs: one warp in `stride` is traced, within each CTA up to its warps, and beyond
/// them in one CTA of every `stride / warps` (rounded down; 1: every CTA).
fn cta_stride(stride: usize, cfg: &SimConfig) -> usize {
    let warp = cfg.gpu.warp_size.max(1) as usize;
    let warps = (cfg.gpu.threads_per_cta.max(1) as usize).div_ceil(warp);
    (stride / warps).max(1)
}

/// Which CTAs the profile traces, one in `cta_stride` of them: those whose tile's column plus
/// row is a multiple of it, a diagonal pattern that leaves every other CTA with traced
/// neighbours (for 2: a checkerboard).
fn traced_ctas(scheduler: &CtaScheduler, cta_stride: usize) -> Vec<bool> {
    (0..scheduler.total())
        .map(|cta| {
            let (x, y) = scheduler.tile(cta);
            (x as usize + y as usize).is_multiple_of(cta_stride)
        })
        .collect()
}

/// Fills in the work of the CTAs the profile did not trace (`traced[c]` false): the mean of
/// the traced CTAs among its eight neighbouring tiles, else of the nearest traced CTA in CTA
/// order (the earlier on a tie).
fn estimate_untraced(ctas: &mut [CtaWork], traced: &[bool], scheduler: &CtaScheduler) {
    if traced.iter().all(|&t| t) || !traced.iter().any(|&t| t) {
        return;
    }
    let estimates: Vec<(usize, CtaWork)> = (0..ctas.len())
        .filter(|&c| !traced[c])
        .map(|c| {
            let (x, y) = scheduler.tile(c as u32);
            let (x, y) = (i64::from(x), i64::from(y));
            let around: Vec<u32> = (-1..=1)
                .flat_map(|dy| (-1..=1).map(move |dx| (dx, dy)))
                .filter_map(|(dx, dy)| scheduler.cta_at(x + dx, y + dy))
                .filter(|&n| traced[n as usize])
                .collect();
            let around = if around.is_empty() {
                let nearest = (1..ctas.len())
                    .flat_map(|d| [c.checked_sub(d), Some(c + d)])
                    .flatten()
                    .find(|&n| n < ctas.len() && traced[n])
                    .expect("some CTA is traced");
                vec![nearest as u32]
            } else {
                around
            };
            let sum = total_work(ctas, Some(&around));
            let k = around.len() as f64;
            let mean = |v: u64| (v as f64 / k).round() as u64;
            let work = CtaWork {
                rays: mean(sum.rays),
                fetches: mean(sum.fetches),
                warp_fetches: mean(sum.warp_fetches),
            };
            (c, work)
        })
        .collect();
    for (c, work) in estimates {
        ctas[c] = work;
    }
}

impl Profile {
    /// What a profile made with `cfg` depends on, as text: two configurations with the same
    /// key give the same profile. The BVH build, the image, the GPU's shape, the memory sizes,
    /// `hw.max_rays` (whether the frame can be held at once, [`stripes_possible`]) and the
    /// `[sample]` keys it reads (`profile_stride`, `warm_l2`, `ghost_l2_footprint`) — not the
    /// rest of the design or the sample's size, so the designs of a scene and the settings of
    /// a benchmark share one profile.
    pub fn key(cfg: &SimConfig) -> String {
        let s = &cfg.sample;
        format!(
            "{:?}|{:?}|{:?}|{:?}|{}|{}|{}|{}",
            cfg.bvh_params(),
            cfg.workload,
            cfg.gpu,
            cfg.memory,
            cfg.hw.max_rays,
            s.profile_stride,
            s.warm_l2,
            s.ghost_l2_footprint
        )
    }

    /// Profiles `cfg`'s workload on `scene` (whose BVH is `bvh`) on all rayon threads. Where
    /// the frame's footprint is within `sample.ghost_l2_footprint`, it also records the CTAs'
    /// L2 streams ([`Profile::cta_streams`]): in the one pass when the BVH's whole address
    /// space is within the limit, else in a second pass once the footprint is known. With
    /// `sample.profile_stride` `m` above 1 the first pass traces one warp in `m` of each CTA
    /// and estimates the CTA's work from them; with `m` beyond a CTA's `n` warps, one warp of
    /// one CTA in `m / n` ([`traced_ctas`]), the others' work estimated from their traced
    /// neighbours ([`estimate_untraced`]). The footprints and streams then hold the traced
    /// warps' lines and reads only.
    pub fn new(scene: &Scene, bvh: &HwBvh, cfg: &SimConfig) -> Result<Profile, RenderError> {
        let start = Instant::now();
        let frame = Frame::new(scene, bvh, cfg)?;
        let total = frame.scheduler.total();
        let with_stripes = stripes_possible(cfg, total as usize);
        let sms = cfg.gpu.sms.max(1) as usize;
        let warp = cfg.gpu.warp_size.max(1) as usize;
        let ghost_limit = cfg.sample.ghost_l2_footprint;
        // Footprints: one bit per 32 B line of the BVH's address space (a slot of
        // `treelet_bytes` per treelet, the header's included), set by every fetch of a stripe's
        // CTAs (per stripe) or of the frame's (for `sample.warm_l2` and `ghost_l2_footprint`).
        let words = {
            let space = (bvh.treelets().len() as u64 + 2) * u64::from(bvh.params().treelet_bytes);
            (space as usize).div_ceil(LINE_BYTES as usize * 64)
        };
        let with_frame = cfg.sample.warm_l2 || ghost_limit > 0.0;
        let limit_bytes = ghost_limit * f64::from(cfg.memory.l2_bytes);
        // A BVH no larger than the limit has a small enough footprint: its streams are
        // recorded in the first pass, otherwise in a second one once the footprint is known.
        let streams_now =
            ghost_limit > 0.0 && (words * 64 * LINE_BYTES as usize) as f64 <= limit_bytes;
        // With a stride the streams hold the traced warps' reads only (the scale models replay
        // them at the full rate, so each stands for the reads of the warps left out).
        let stride = cfg.sample.profile_stride.max(1) as usize;
        let l1_bytes = cfg.memory.l1_bytes;
        let line_bytes = cfg.memory.line_bytes;
        let frame_bits: Vec<AtomicU64> = (0..if with_frame { words } else { 0 })
            .map(|_| AtomicU64::new(0))
            .collect();
        let footprints: Vec<Vec<AtomicU64>> = (0..if with_stripes { sms } else { 0 })
            .map(|_| (0..words).map(|_| AtomicU64::new(0)).collect())
            .collect();
        let traced = traced_ctas(&frame.scheduler, cta_stride(stride, cfg));
        let (mut ctas, first_streams) = (0..total)
            .into_par_iter()
            .map_init(
                || (Vec::new(), Vec::new()),
                |scratch, cta| {
                    if !traced[cta as usize] {
                        return (CtaWork::default(), Vec::new());
                    }
                    let mut l1 = streams_now.then(|| L1Filter::new(l1_bytes, line_bytes));
                    let mut stream = Vec::new();
                    let footprint = footprints.get(cta as usize % sms);
                    let work = frame.cta_work(cta, (warp, stride), scratch, |fetches| {
                        if let Some(bits) = footprint {
                            mark_lines(bits, fetches);
                        }
                        if !frame_bits.is_empty() {
                            mark_lines(&frame_bits, fetches);
                        }
                        if let Some(l1) = &mut l1 {
                            l1.misses(fetches, &mut stream);
                        }
                    });
                    (work, stream)
                },
            )
            .unzip::<_, _, Vec<CtaWork>, Vec<Vec<u32>>>();
        estimate_untraced(&mut ctas, &traced, &frame.scheduler);
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
        let frame_lines: Vec<u64> = frame_bits
            .iter()
            .map(|w| w.load(Ordering::Relaxed))
            .collect();
        let footprint_bytes = frame_lines
            .iter()
            .map(|w| u64::from(w.count_ones()))
            .sum::<u64>()
            * u64::from(LINE_BYTES);
        let cta_streams = if streams_now {
            first_streams
        } else if ghost_limit > 0.0 && footprint_bytes as f64 <= limit_bytes {
            (0..total)
                .into_par_iter()
                .map_init(Vec::new, |fetches, cta| {
                    let mut stream = Vec::new();
                    if !traced[cta as usize] {
                        return stream;
                    }
                    let mut l1 = L1Filter::new(l1_bytes, line_bytes);
                    frame.trace_cta(cta, (warp, stride), fetches, |_, fetches| {
                        l1.misses(fetches, &mut stream)
                    });
                    stream
                })
                .collect()
        } else {
            Vec::new()
        };
        Ok(Profile {
            ctas,
            stripes,
            seconds: start.elapsed().as_secs_f64(),
            frame_lines: if cfg.sample.warm_l2 {
                frame_lines
            } else {
                Vec::new()
            },
            footprint_bytes,
            cta_streams,
            stride: stride as u32,
        })
    }

    /// [`Profile::ctas`] with the CTAs `exact` traced in full (every warp): the exact work of
    /// the CTAs a sample simulates where the profile estimated it (`stride` above 1).
    pub fn with_exact(
        &self,
        scene: &Scene,
        bvh: &HwBvh,
        cfg: &SimConfig,
        exact: &[u32],
    ) -> Result<Vec<CtaWork>, RenderError> {
        let mut ctas = self.ctas.clone();
        if self.stride <= 1 {
            return Ok(ctas);
        }
        let frame = Frame::new(scene, bvh, cfg)?;
        let warp = cfg.gpu.warp_size.max(1) as usize;
        let traced: Vec<(u32, CtaWork)> = exact
            .par_iter()
            .map_init(
                || (Vec::new(), Vec::new()),
                |scratch, &cta| (cta, frame.cta_work(cta, (warp, 1), scratch, |_| {})),
            )
            .collect();
        for (cta, work) in traced {
            if let Some(slot) = ctas.get_mut(cta as usize) {
                *slot = work;
            }
        }
        Ok(ctas)
    }

    /// Total work of the CTAs `subset` (all of them with `None`).
    pub fn work(&self, subset: Option<&[u32]>) -> CtaWork {
        total_work(&self.ctas, subset)
    }
}

/// Total work of the CTAs `subset` of `ctas` (all of them with `None`).
pub fn total_work(ctas: &[CtaWork], subset: Option<&[u32]>) -> CtaWork {
    let add = |a: CtaWork, b: &CtaWork| CtaWork {
        rays: a.rays + b.rays,
        fetches: a.fetches + b.fetches,
        warp_fetches: a.warp_fetches + b.warp_fetches,
    };
    match subset {
        None => ctas.iter().fold(CtaWork::default(), add),
        Some(s) => s
            .iter()
            .map(|&c| &ctas[c as usize])
            .fold(CtaWork::default(), add),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The L1 filter passes each sector's first read and none after while its line stays; a
    /// node spanning sectors reads each; a set's least recently used line leaves for a new one.
    #[test]
    fn the_l1_filter_passes_first_reads_of_sectors() {
        let fetch = |addr: u32, bytes: u32| Fetch {
            addr,
            bytes,
            kind: crate::model::traversal::NodeKind::Internal,
            treelet: 0,
        };
        // 2 sets of 8 ways of 128 B lines.
        let mut l1 = L1Filter::new(16 * 128, 128);
        let mut out = Vec::new();
        l1.misses(&[fetch(0, 64), fetch(32, 32), fetch(96, 32)], &mut out);
        assert_eq!(out, [0, 1, 3]);
        out.clear();
        // Eight more lines of set 0 (even lines): line 0 is the least recently used.
        let fetches: Vec<Fetch> = (1..=8).map(|k| fetch(k * 256, 32)).collect();
        l1.misses(&fetches, &mut out);
        assert_eq!(out.len(), 8);
        out.clear();
        l1.misses(&[fetch(0, 32), fetch(8 * 256, 32)], &mut out);
        assert_eq!(out, [0], "line 0 was evicted, line 8 stayed");
    }

    /// Beyond the warps of a CTA the profile traces one CTA in `cta_stride` in a diagonal
    /// pattern; an untraced CTA's work is the mean of its traced neighbouring tiles, else the
    /// nearest traced CTA's in CTA order (the earlier on a tie).
    #[test]
    fn untraced_ctas_take_their_traced_neighbours_mean() {
        let work = |rays: u64| CtaWork {
            rays,
            fetches: 10 * rays,
            warp_fetches: 3 * rays,
        };
        // 64 threads in 8x8 tiles: a 24x16 image is 3 x 2 tiles.
        let s = CtaScheduler::new(24, 16, 64);
        assert_eq!(s.total(), 6);
        assert_eq!(
            cta_stride(2, &crate::model::config::SimConfig::default()),
            1
        );
        assert_eq!(
            cta_stride(4, &crate::model::config::SimConfig::default()),
            2
        );
        let traced = traced_ctas(&s, 2);
        assert_eq!(traced, [true, false, true, false, true, false]);
        let mut ctas = vec![work(10), work(0), work(30), work(0), work(50), work(0)];
        estimate_untraced(&mut ctas, &traced, &s);
        // CTA 1 (1, 0): traced neighbours 0, 2 and 4 (below); CTA 3 (0, 1): 0 and 4; CTA 5
        // (2, 1): 2 and 4.
        assert_eq!(ctas[1], work(30));
        assert_eq!(ctas[3], work(30));
        assert_eq!(ctas[5], work(40));
        // One row of eight tiles, every sixth traced: CTA 3 has no traced neighbour and takes
        // CTA 0's (as near as CTA 6, and earlier).
        let s = CtaScheduler::new(64, 8, 64);
        let traced = traced_ctas(&s, 6);
        assert_eq!(traced.iter().filter(|&&t| t).count(), 2);
        let mut ctas: Vec<CtaWork> = (0..8)
            .map(|c| work(if c % 6 == 0 { c + 1 } else { 0 }))
            .collect();
        estimate_untraced(&mut ctas, &traced, &s);
        assert_eq!(ctas[1], work(1));
        assert_eq!(ctas[3], work(1));
        assert_eq!(ctas[4], work(7));
        assert_eq!(ctas[7], work(7));
    }

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
