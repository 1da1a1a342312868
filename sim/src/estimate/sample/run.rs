//! Running the sampled tier: each replicate simulates the scale model
//! ([`SampleConfig::scale_model`](super::SampleConfig::scale_model)) in full detail on its own
//! stratified sample of CTAs ([`super::strata`]); the replicates' results are extrapolated to the
//! whole frame and combined into estimates with 95% intervals ([`SampledStats`]).
//!
//! Extrapolation: the scale model gives each simulated SM the share of CTAs, L2 capacity and
//! DRAM bandwidth a full-GPU SM has, so its cycle count estimates the full GPU's. A replicate's
//! cycles are carried to the whole frame by the dispatch model's makespan ratio
//! ([`super::dispatch`]), with each CTA's cost from the profile as the design's RT unit pays it
//! (`dispatch_cost`: its warps' lockstep fetches, or every fetch under treelet queues). Rates
//! (BVH L1 miss rate, SIMT efficiency, phase shares) are taken as measured; DRAM bytes scale by
//! the inverse of the sample's share of the frame's fetches.
//!
//! Where the design's SMs hold every CTA at once and `sample.stripes` is on, the replicates run
//! whole stripes instead ([`super::stripes`]): a replicate's cycles are those of its slowest
//! stripe, which SM ran it in the full GPU too, and the estimate of the frame's cycles is the
//! slowest replicate, with the validated bound `sample.stripe_bound` as its interval.

use std::borrow::Cow;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use serde::Serialize;

use super::dispatch::{held_at_once, holds_every_cta, makespan_ratio, resident_ctas};
use super::estimate::Estimate;
use super::profile::{total_work, CtaWork, Profile, LINE_BYTES};
use super::strata::stratified_sample;
use super::stripes::stripe_samples;
use crate::model::bvh::HwBvh;
use crate::model::config::{Cluster, SimConfig};
use crate::model::gpu::sm::CtaSpan;
use crate::model::gpu::{simulate, SimError, SimOptions, SimStats};
use crate::model::memory::GhostReads;
use crate::model::scene::Scene;
use crate::model::splitmix::SplitMix64;

/// One replicate: its sample and the scale model's statistics.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Replicate {
    /// CTAs simulated.
    pub ctas: usize,
    /// The sample's node fetches over its share of the frame's (1: exactly its share).
    pub work_share: f64,
    /// The stripes it ran, with stripe sampling (empty for a stratified sample).
    pub stripes: Vec<u32>,
    /// Cycles extrapolated to the whole frame (stratified: the scale model's times the
    /// dispatch model's makespan ratio; stripes: the scale model's, its slowest stripe's).
    pub cycles: f64,
    /// Stripe sampling: a scale-model SM ran CTAs of more than one stripe, i.e. CTAs finished
    /// before every CTA was dispatched and the dispatch gave later ones to whichever SM had
    /// room, so the stripes were not fixed (false for stratified samples).
    pub stripes_mixed: bool,
    /// The scale model's statistics.
    pub stats: SimStats,
}

/// The sampled tier's estimates for one design, each with its 95% interval.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SampledStats {
    /// Scene.
    pub scene: String,
    /// Design (`mode.kind`).
    pub mode: String,
    /// Fraction of the GPU and of the frame each replicate simulated.
    pub fraction: f64,
    /// SMs of the scale model.
    pub scale_sms: u32,
    /// Replicates.
    pub replicates: u32,
    /// Seed of the samples.
    pub seed: u64,
    /// CTAs per unit of the stratified samples, one size or one per replicate in turn
    /// (`sample.cluster`; stripe sampling does not use it).
    pub cluster: Cluster,
    /// Whether every CTA of the frame is resident on its SM at once in this design (its SMs'
    /// resident CTAs, [`resident_ctas`], cover the frame): each SM then runs a fixed stripe of
    /// CTAs, the run ends with the slowest stripe, and a stratified sample, which mixes the
    /// stripes, cannot see which one that is. The intervals cover the sampling noise only and
    /// have missed full detail most often in this case (docs/accuracy.md).
    pub every_cta_resident: bool,
    /// How the replicates sampled the frame: `strata` (stratified CTA samples) or `stripes`
    /// (whole stripes, where every CTA is resident and `sample.stripes` is on).
    pub method: Method,
    /// The part of the interval of cycles that bounds the method's bias, relative to the
    /// estimate: `sample.tail_bound / waves` for strata (added to the Student-t half-width),
    /// `sample.stripe_bound` for stripes (the whole half-width).
    pub bias_bound: f64,
    /// Rays of the whole frame, from the functional profile: exact, unless
    /// `rays_estimated`.
    pub rays: u64,
    /// The profile traced one warp in `sample.profile_stride` of the frame's, so `rays` is an
    /// estimate (exact for the CTAs the replicates ran, scaled from the traced warps for the
    /// others).
    pub rays_estimated: bool,
    /// Cycles of the whole frame.
    pub cycles: Estimate,
    /// BVH L1 miss rate.
    pub bvh_l1_miss_rate: Estimate,
    /// SIMT efficiency.
    pub simt_efficiency: Estimate,
    /// Shares of cycles in the initial, treelet-stationary and final ray-stationary phases.
    pub phase_shares: [Estimate; 3],
    /// DRAM bytes read and written.
    pub dram_bytes: Estimate,
    /// Wall-clock seconds of the functional profile.
    pub profile_seconds: f64,
    /// Wall-clock seconds of the replicates' simulations.
    pub sim_seconds: f64,
    /// Stripe sampling was tried first and its scale model's dispatch mixed the stripes
    /// ([`Replicate::stripes_mixed`]), so the stripes are not the GPU's fixed SM workloads and
    /// the estimate is the stratified one (`method` says `strata`; `sim_seconds` includes the
    /// stripes' run).
    pub stripes_dynamic: bool,
    /// The replicates.
    pub replicate_runs: Vec<Replicate>,
}

/// How a sampled run chose its replicates' CTAs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Stratified CTA samples carried to the frame by the dispatch model; Student-t intervals.
    Strata,
    /// The whole stripes predicted slowest; the slowest replicate, with the validated bound.
    Stripes,
}

/// [`SampledStats::bias_bound`] of `cfg.sample` on `profile`'s frame by `method`.
fn bias_bound(cfg: &SimConfig, profile: &Profile, method: Method) -> f64 {
    match method {
        Method::Stripes => cfg.sample.stripe_bound,
        Method::Strata => {
            let held = held_at_once(cfg).max(1);
            let waves = (profile.ctas.len() as f64 / held as f64).max(1.0);
            cfg.sample.tail_bound / waves
        }
    }
}

/// Whether `cfg`'s design holds every CTA of `profile`'s frame at once.
pub fn every_cta_resident(cfg: &SimConfig, profile: &Profile) -> bool {
    holds_every_cta(cfg, profile.ctas.len())
}

/// The method `cfg.sample` uses on `profile`'s frame: stripes where every CTA is resident, the
/// profile has the stripes and `sample.stripes` is on, below the whole GPU; else strata.
pub fn method(cfg: &SimConfig, profile: &Profile) -> Method {
    let stripes = cfg.sample.stripes
        && cfg.sample.fraction < 1.0
        && profile.stripes.len() == cfg.gpu.sms as usize
        && every_cta_resident(cfg, profile);
    if stripes {
        Method::Stripes
    } else {
        Method::Strata
    }
}

impl SampledStats {
    /// The replicates' extrapolated cycles.
    pub fn replicate_cycles(&self) -> Vec<f64> {
        self.replicate_runs.iter().map(|r| r.cycles).collect()
    }
}

/// `cfg` with stripe sampling's replicates made one: their stripes (each replicate's
/// [`SampleConfig::scale_sms`](crate::model::config::SampleConfig::scale_sms), one below one
/// SM) in one replicate, if that is a scale model (a whole number of SMs dividing the GPU's);
/// else `None` (the replicates run apart).
fn stripes_together(cfg: &SimConfig) -> Option<SimConfig> {
    let sms = cfg.gpu.sms;
    let stripes = cfg.sample.scale_sms(sms)? * cfg.sample.replicates;
    let mut c = cfg.clone();
    c.sample.fraction = f64::from(stripes) / f64::from(sms);
    c.sample.replicates = 1;
    (stripes <= sms && c.sample.scale_sms(sms) == Some(stripes)).then_some(c)
}

/// The share of the frame's CTAs a replicate of `cfg.sample` runs by `method`: `fraction` for
/// stratified samples, its stripes' share (one of `gpu.sms` per scale-model SM) for stripes.
fn frame_share(cfg: &SimConfig, method: Method) -> f64 {
    match method {
        Method::Strata => cfg.sample.fraction,
        Method::Stripes => {
            let sms = cfg.gpu.sms.max(1);
            f64::from(cfg.sample.scale_sms(sms).unwrap_or(1)) / f64::from(sms)
        }
    }
}

/// The BVH sectors (byte addresses, ascending) that a scale model of `scale_sms` of the GPU's
/// `sms` SMs finds in its L2 before the run (`sample.warm_l2`): each line of the frame's
/// footprint is dealt by a hash to one of the `sms` SMs, and the lines dealt to the SMs the
/// model leaves out are present, as they are for an SM of the full GPU that reaches a line
/// another SM fetched first. None for the whole GPU.
fn warm_sectors(profile: &Profile, scale_sms: usize, sms: usize) -> Vec<u64> {
    let mut out = Vec::new();
    for (w, &word) in profile.frame_lines.iter().enumerate() {
        let mut bits = word;
        while bits != 0 {
            let line = w as u64 * 64 + u64::from(bits.trailing_zeros());
            bits &= bits - 1;
            if SplitMix64::new(line).next_u64() % sms as u64 >= scale_sms as u64 {
                out.push(line * u64::from(LINE_BYTES));
            }
        }
    }
    out
}

/// The BVH reads at the L2 of the stripes (an SM's CTAs `c mod sms = s`) the scale model
/// leaves out (`sample.ghost_l2_footprint`): every stripe but `simulated`'s, each the profile's L1-missing
/// reads of its CTAs in order.
fn ghost_streams(profile: &Profile, sms: usize, simulated: &[u32]) -> Vec<Vec<u32>> {
    (0..sms)
        .filter(|s| !simulated.contains(&(*s as u32)))
        .map(|s| {
            profile
                .cta_streams
                .iter()
                .skip(s)
                .step_by(sms)
                .flatten()
                .copied()
                .collect::<Vec<u32>>()
        })
        .filter(|stream| !stream.is_empty())
        .collect()
}

/// What CTA `work` costs an SM of `cfg`'s design in the dispatch model: an RT unit that keeps
/// a warp until its slowest ray is done (the baseline's, prefetching's) pays its warps'
/// lockstep fetches ([`CtaWork::warp_fetches`]); the treelet RT unit, whose rays leave their
/// warps for the treelets' queues and are repacked, pays every fetch once.
fn dispatch_cost(cfg: &SimConfig, work: &CtaWork) -> f64 {
    if cfg.mode.treelet_queues() {
        work.fetches as f64
    } else {
        work.warp_fetches as f64
    }
}

/// The CTA samples of `cfg.sample`'s replicates for a frame with `profile`, by
/// [`method`]; an error when stripe sampling needs more stripes than the GPU has.
pub fn samples(cfg: &SimConfig, profile: &Profile) -> Result<Vec<Vec<u32>>, String> {
    let s = &cfg.sample;
    if method(cfg, profile) == Method::Stripes {
        let k = s.scale_sms(cfg.gpu.sms).unwrap_or(1) as usize;
        return stripe_samples(
            &profile.stripes,
            profile.ctas.len(),
            k,
            s.replicates as usize,
        );
    }
    let costs: Vec<u64> = profile.ctas.iter().map(|c| c.fetches).collect();
    Ok((0..s.replicates)
        .map(|r| {
            let cluster = s.cluster.for_replicate(r) as usize;
            stratified_sample(&costs, s.fraction, s.seed, r, cluster)
        })
        .collect())
}

/// Simulates `cfg.sample`'s replicates of `cfg`'s workload on `scene` (BVH `bvh`, functional
/// profile `profile`), `threads` replicates at a time (each single-threaded), and estimates the
/// whole frame's statistics. With `sample.fraction = 1` and one replicate it is full detail:
/// the replicate's statistics are exactly `vtq sim`'s.
pub fn simulate_sampled(
    scene: &Scene,
    bvh: &HwBvh,
    cfg: &SimConfig,
    profile: &Profile,
    threads: usize,
) -> Result<SampledStats, SimError> {
    cfg.sample
        .validate(cfg)
        .map_err(|e| SimError::Setup(e.to_string()))?;
    let method = method(cfg, profile);
    let samples = samples(cfg, profile).map_err(SimError::Setup)?;
    let asked = cfg;
    // Stripe sampling runs every replicate's stripes together, sharing one L2 as they do in
    // the full GPU, where they make a scale model (their SMs divide the GPU's).
    let together = (method == Method::Stripes)
        .then(|| stripes_together(cfg))
        .flatten();
    let (cfg, samples) = match &together {
        Some(c) => {
            let mut all: Vec<u32> = samples.concat();
            all.sort_unstable();
            (c, vec![all])
        }
        None => (cfg, samples),
    };
    let model = cfg.sample.scale_model(cfg);
    // Each CTA's work: the profile's, with the stratified samples' CTAs traced in full where
    // the profile estimated it (`sample.profile_stride`), so that the dispatch model carries
    // the samples by their exact work.
    let ctas_work: Cow<[CtaWork]> = if method == Method::Strata && profile.stride > 1 {
        let mut sampled: Vec<u32> = samples.concat();
        sampled.sort_unstable();
        sampled.dedup();
        Cow::Owned(profile.with_exact(scene, bvh, cfg, &sampled)?)
    } else {
        Cow::Borrowed(&profile.ctas)
    };
    let total = total_work(&ctas_work, None);
    let full_work: Vec<f64> = ctas_work.iter().map(|c| dispatch_cost(cfg, c)).collect();
    let sms = cfg.gpu.sms as usize;
    let scale_sms = model.gpu.sms as usize;
    let resident = resident_ctas(cfg);
    let warm = cfg
        .sample
        .warm_l2
        .then(|| warm_sectors(profile, scale_sms, sms));
    // The left-out SMs' BVH reads (`sample.ghost_l2_footprint`) for a model simulating the
    // stripes `simulated`, with how many follow each of its BVH reads.
    let ghosts_of = |simulated: &[u32]| {
        if profile.cta_streams.is_empty() || scale_sms >= sms {
            return None;
        }
        let streams = ghost_streams(profile, sms, simulated);
        let per_read = ((sms - scale_sms) / scale_sms) as u32;
        (!streams.is_empty()).then(|| Arc::new(GhostReads::new(&model.memory, &streams, per_read)))
    };
    // Stratified samples mix the stripes: the left-out SMs are the last `sms - k`, the same
    // for every replicate.
    let strata_ghosts = (method == Method::Strata)
        .then(|| ghosts_of(&(0..scale_sms as u32).collect::<Vec<_>>()))
        .flatten();
    let start = Instant::now();
    let next = AtomicUsize::new(0);
    let slots: Vec<Mutex<Option<Result<Replicate, SimError>>>> =
        samples.iter().map(|_| Mutex::new(None)).collect();
    let worker = || loop {
        let r = next.fetch_add(1, Ordering::Relaxed);
        let Some(ctas) = samples.get(r) else {
            return;
        };
        let work = total_work(&ctas_work, Some(ctas));
        let expected = total.fetches as f64 * frame_share(cfg, method);
        let work_share = if expected > 0.0 {
            work.fetches as f64 / expected
        } else {
            1.0
        };
        let ghosts = match method {
            Method::Strata => strata_ghosts.clone(),
            Method::Stripes => ghosts_of(&ctas.iter().map(|&c| c % sms as u32).collect::<Vec<_>>()),
        };
        let options = SimOptions {
            l2_warm: warm.clone(),
            l2_ghosts: ghosts,
            ctas: (ctas.len() < profile.ctas.len()).then(|| ctas.clone()),
            // Threads left over by fewer replicates simulate a replicate's SMs (the same
            // results for any count).
            threads: (threads / samples.len()).max(1),
            ..SimOptions::default()
        };
        let sample_work: Vec<f64> = ctas
            .iter()
            .map(|&c| dispatch_cost(cfg, &ctas_work[c as usize]))
            .collect();
        // A stripe's SM runs the same CTAs in the full GPU: its cycles need no carrying.
        let (dispatch, stripes) = match method {
            Method::Strata => (
                makespan_ratio(&full_work, sms, &sample_work, scale_sms, resident),
                Vec::new(),
            ),
            Method::Stripes => {
                let mut chosen: Vec<u32> = ctas.iter().map(|&c| c % sms as u32).collect();
                chosen.sort_unstable();
                chosen.dedup();
                (1.0, chosen)
            }
        };
        let result = simulate(scene, bvh, &model, options, None).map(|out| Replicate {
            ctas: ctas.len(),
            work_share,
            stripes,
            cycles: out.stats.cycles as f64 * dispatch,
            stripes_mixed: method == Method::Stripes && mixes_stripes(&out.cta_spans, sms),
            stats: out.stats,
        });
        *slots[r].lock().unwrap_or_else(|e| e.into_inner()) = Some(result);
    };
    std::thread::scope(|scope| {
        for _ in 1..threads.clamp(1, samples.len().max(1)) {
            scope.spawn(worker);
        }
        worker();
    });
    let mut runs = Vec::with_capacity(slots.len());
    for slot in slots {
        let result = slot
            .into_inner()
            .unwrap_or_else(|e| e.into_inner())
            .expect("every replicate ran");
        runs.push(result?);
    }
    let sim_seconds = start.elapsed().as_secs_f64();
    if runs.iter().any(|r| r.stripes_mixed) {
        // The stripes were not fixed: the stratified method, which does not assume they are.
        let mut strata = asked.clone();
        strata.sample.stripes = false;
        let mut s = simulate_sampled(scene, bvh, &strata, profile, threads)?;
        s.stripes_dynamic = true;
        s.sim_seconds += sim_seconds;
        return Ok(s);
    }
    Ok(combine(cfg, profile, total.rays, method, runs, sim_seconds))
}

/// Whether a scale model's SMs ran CTAs of more than one stripe each (`spans`: per SM, its
/// CTAs; stripe of CTA `c`: `c mod sms`).
fn mixes_stripes(spans: &[Vec<CtaSpan>], sms: usize) -> bool {
    spans.iter().any(|sm| {
        sm.windows(2)
            .any(|w| w[0].cta % sms as u32 != w[1].cta % sms as u32)
    })
}

/// The estimates from the replicates `runs`.
fn combine(
    cfg: &SimConfig,
    profile: &Profile,
    rays: u64,
    method: Method,
    runs: Vec<Replicate>,
    sim_seconds: f64,
) -> SampledStats {
    let each = |f: &dyn Fn(&Replicate) -> f64| -> Estimate {
        Estimate::of(&runs.iter().map(f).collect::<Vec<f64>>())
    };
    let share = |r: &Replicate, c: u64| {
        if r.stats.cycles == 0 {
            0.0
        } else {
            c as f64 / r.stats.cycles as f64
        }
    };
    let first = &runs[0].stats;
    let bias_bound = bias_bound(cfg, profile, method);
    let cycles = match method {
        Method::Strata => {
            let e = each(&|r| r.cycles);
            Estimate {
                half_width: e.half_width.map(|h| h + bias_bound * e.value),
                ..e
            }
        }
        Method::Stripes => {
            let slowest = runs.iter().map(|r| r.cycles).fold(0.0, f64::max);
            Estimate {
                value: slowest,
                half_width: Some(slowest * bias_bound),
            }
        }
    };
    SampledStats {
        scene: first.scene.clone(),
        mode: first.mode.clone(),
        fraction: cfg.sample.fraction,
        scale_sms: cfg.sample.scale_sms(cfg.gpu.sms).unwrap_or(1),
        replicates: cfg.sample.replicates,
        seed: cfg.sample.seed,
        cluster: cfg.sample.cluster.clone(),
        every_cta_resident: every_cta_resident(cfg, profile),
        method,
        bias_bound,
        rays,
        rays_estimated: profile.stride > 1,
        cycles,
        bvh_l1_miss_rate: each(&|r| r.stats.bvh_l1_miss_rate),
        simt_efficiency: each(&|r| r.stats.simt_efficiency),
        phase_shares: [
            each(&|r| share(r, r.stats.phases.initial.cycles)),
            each(&|r| share(r, r.stats.phases.treelet_stationary.cycles)),
            each(&|r| share(r, r.stats.phases.ray_stationary.cycles)),
        ],
        dram_bytes: each(&|r| {
            r.stats.dram_bytes as f64 / (frame_share(cfg, method) * r.work_share)
        }),
        profile_seconds: profile.seconds,
        sim_seconds,
        stripes_dynamic: false,
        replicate_runs: runs,
    }
}

/// The speedup of `design` over `baseline` (sampled with the same settings and seed). Both
/// stratified, each replicate ran the same CTAs on both: per replicate the ratio of their
/// extrapolated cycles (each design's own dispatch model: their CTAs in flight differ),
/// combined into an estimate with its interval (the pairing cancels most of the sampling
/// noise) widened by both designs' bias bounds. Where either used stripes the replicates do
/// not pair: the ratio of the two estimates, its relative half-width the sum of theirs (no
/// interval if either has none). A design over itself (the same estimates) is exactly 1.
pub fn paired_speedup(baseline: &SampledStats, design: &SampledStats) -> Estimate {
    // A design over itself: exactly 1.
    if std::ptr::eq(baseline, design) {
        return Estimate {
            value: 1.0,
            half_width: baseline.cycles.half_width.map(|_| 0.0),
        };
    }
    let stripes = baseline.method == Method::Stripes || design.method == Method::Stripes;
    let cycles = |s: &SampledStats| {
        s.replicate_runs
            .iter()
            .map(|r| r.cycles)
            .collect::<Vec<_>>()
    };
    let (b, d) = (cycles(baseline), cycles(design));
    let paired = (!stripes).then_some((&b[..], &d[..], baseline.bias_bound + design.bias_bound));
    speedup_of(baseline.cycles, design.cycles, paired)
}

/// The speedup `baseline / design` of two estimates of cycles, with its 95% interval. With
/// `paired` (each replicate's cycles of the baseline and of the design, in replicate order,
/// and the sum of their bias bounds): the mean of the per-replicate ratios with Student's t
/// interval widened by the bounds. Without: the ratio of the estimates, its relative
/// half-width the sum of theirs (no interval if either has none). [`paired_speedup`] and
/// stored sampled runs ([`super::stored::stored_speedup`]) both combine this way.
pub fn speedup_of(
    baseline: Estimate,
    design: Estimate,
    paired: Option<(&[f64], &[f64], f64)>,
) -> Estimate {
    if let Some((b, d, bias)) = paired {
        let ratios: Vec<f64> = b.iter().zip(d).map(|(b, d)| b / d.max(1.0)).collect();
        // The replicates' spread, plus both designs' bias bounds (their biases need not cancel).
        let e = Estimate::of(&ratios);
        return Estimate {
            half_width: e.half_width.map(|h| h + e.value * bias),
            ..e
        };
    }
    let value = baseline.value / design.value.max(1.0);
    let relative = |e: Estimate| e.half_width.map(|h| h / e.value.max(1.0));
    Estimate {
        value,
        half_width: relative(baseline)
            .zip(relative(design))
            .map(|(rb, rd)| value * (rb + rd)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spans(ctas: &[u32]) -> Vec<CtaSpan> {
        ctas.iter()
            .map(|&cta| CtaSpan {
                cta,
                start: 0,
                end: 1,
            })
            .collect()
    }

    /// A scale-model SM that ran CTAs of two stripes mixes them; SMs each on one stripe (in
    /// any order of retirement) do not.
    #[test]
    fn mixed_stripes_are_seen_on_any_sm() {
        let fixed = vec![spans(&[3, 19, 35]), spans(&[20, 4])];
        assert!(!mixes_stripes(&fixed, 16));
        let mixed = vec![spans(&[3, 19]), spans(&[4, 35, 20])];
        assert!(mixes_stripes(&mixed, 16));
        assert!(!mixes_stripes(&[], 16));
    }
}
