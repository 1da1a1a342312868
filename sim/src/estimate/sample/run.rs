//! Running the sampled tier: each replicate simulates the scale model
//! ([`SampleConfig::scale_model`](super::SampleConfig::scale_model)) in full detail on its own
//! stratified sample of CTAs ([`super::strata`]); the replicates' results are extrapolated to the
//! whole frame and combined into estimates with 95% intervals ([`SampledStats`]).
//!
//! Extrapolation: the scale model gives each simulated SM the share of CTAs, L2 capacity and
//! DRAM bandwidth a full-GPU SM has, so its cycle count estimates the full GPU's. A replicate's
//! sample may hold a little more or less work than its share of the frame; its cycles are scaled
//! by the ratio of the share of the frame's node fetches it should hold to the fetches it holds
//! (both known from the functional profile), a ratio estimator that removes most of the
//! sampling noise. Rates (BVH L1 miss rate, SIMT efficiency, phase shares) are taken as
//! measured; DRAM bytes scale by the inverse of the sample's share of the frame's fetches.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use serde::Serialize;

use super::dispatch::{makespan_ratio, resident_ctas};
use super::estimate::Estimate;
use super::profile::Profile;
use super::strata::stratified_sample;
use crate::model::bvh::HwBvh;
use crate::model::config::SimConfig;
use crate::model::gpu::{simulate, SimError, SimOptions, SimStats};
use crate::model::scene::Scene;

/// One replicate: its sample and the scale model's statistics.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Replicate {
    /// CTAs simulated.
    pub ctas: usize,
    /// The sample's node fetches over its share of the frame's (1: exactly its share).
    pub work_share: f64,
    /// Cycles extrapolated to the whole frame (the scale model's, divided by `work_share`).
    pub cycles: f64,
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
    /// Whether every CTA of the frame is resident on its SM at once in this design (its SMs'
    /// resident CTAs, [`resident_ctas`], cover the frame): each SM then runs a fixed stripe of
    /// CTAs, the run ends with the slowest stripe, and a stratified sample, which mixes the
    /// stripes, cannot see which one that is. The intervals cover the sampling noise only and
    /// have missed full detail most often in this case (docs/accuracy.md).
    pub every_cta_resident: bool,
    /// Rays of the whole frame (exact, from the functional profile).
    pub rays: u64,
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
    /// The replicates.
    pub replicate_runs: Vec<Replicate>,
}

impl SampledStats {
    /// The replicates' extrapolated cycles.
    pub fn replicate_cycles(&self) -> Vec<f64> {
        self.replicate_runs.iter().map(|r| r.cycles).collect()
    }
}

/// The CTA samples of `cfg.sample`'s replicates for a frame with `profile`.
pub fn samples(cfg: &SimConfig, profile: &Profile) -> Vec<Vec<u32>> {
    let costs: Vec<u64> = profile.ctas.iter().map(|c| c.fetches).collect();
    let s = &cfg.sample;
    (0..s.replicates)
        .map(|r| stratified_sample(&costs, s.fraction, s.seed, r))
        .collect()
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
    let model = cfg.sample.scale_model(cfg);
    let samples = samples(cfg, profile);
    let total = profile.work(None);
    let full_work: Vec<f64> = profile.ctas.iter().map(|c| c.fetches as f64).collect();
    let sms = cfg.gpu.sms as usize;
    let scale_sms = model.gpu.sms as usize;
    let resident = resident_ctas(cfg);
    let start = Instant::now();
    let next = AtomicUsize::new(0);
    let slots: Vec<Mutex<Option<Result<Replicate, SimError>>>> =
        samples.iter().map(|_| Mutex::new(None)).collect();
    let worker = || loop {
        let r = next.fetch_add(1, Ordering::Relaxed);
        let Some(ctas) = samples.get(r) else {
            return;
        };
        let work = profile.work(Some(ctas));
        let expected = total.fetches as f64 * cfg.sample.fraction;
        let work_share = if expected > 0.0 {
            work.fetches as f64 / expected
        } else {
            1.0
        };
        let options = SimOptions {
            ctas: (ctas.len() < profile.ctas.len()).then(|| ctas.clone()),
            ..SimOptions::default()
        };
        let sample_work: Vec<f64> = ctas
            .iter()
            .map(|&c| profile.ctas[c as usize].fetches as f64)
            .collect();
        let dispatch = makespan_ratio(&full_work, sms, &sample_work, scale_sms, resident);
        let result = simulate(scene, bvh, &model, options, None).map(|out| Replicate {
            ctas: ctas.len(),
            work_share,
            cycles: out.stats.cycles as f64 * dispatch,
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
    Ok(combine(cfg, profile, runs, sim_seconds))
}

/// The estimates from the replicates `runs`.
fn combine(
    cfg: &SimConfig,
    profile: &Profile,
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
    SampledStats {
        scene: first.scene.clone(),
        mode: first.mode.clone(),
        fraction: cfg.sample.fraction,
        scale_sms: cfg.sample.scale_sms(cfg.gpu.sms).unwrap_or(1),
        replicates: cfg.sample.replicates,
        seed: cfg.sample.seed,
        every_cta_resident: resident_ctas(cfg) * cfg.gpu.sms as usize >= profile.ctas.len(),
        rays: profile.work(None).rays,
        cycles: each(&|r| r.cycles),
        bvh_l1_miss_rate: each(&|r| r.stats.bvh_l1_miss_rate),
        simt_efficiency: each(&|r| r.stats.simt_efficiency),
        phase_shares: [
            each(&|r| share(r, r.stats.phases.initial.cycles)),
            each(&|r| share(r, r.stats.phases.treelet_stationary.cycles)),
            each(&|r| share(r, r.stats.phases.ray_stationary.cycles)),
        ],
        dram_bytes: each(&|r| r.stats.dram_bytes as f64 / (cfg.sample.fraction * r.work_share)),
        profile_seconds: profile.seconds,
        sim_seconds,
        replicate_runs: runs,
    }
}

/// The speedup of `design` over `baseline` (sampled with the same settings and seed, so each
/// replicate ran the same CTAs on both): per replicate the ratio of their extrapolated cycles
/// (each design's own dispatch model: their CTAs in flight differ), combined into an estimate
/// with its interval (the pairing cancels most of the sampling noise).
pub fn paired_speedup(baseline: &SampledStats, design: &SampledStats) -> Estimate {
    let ratios: Vec<f64> = baseline
        .replicate_runs
        .iter()
        .zip(&design.replicate_runs)
        .map(|(b, d)| b.cycles / d.cycles.max(1.0))
        .collect();
    Estimate::of(&ratios)
}
