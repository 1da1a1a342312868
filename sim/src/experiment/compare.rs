//! Several designs on one scene and workload (`vtq compare`): one BVH per distinct build
//! shared by the designs that use it, every design simulated in full detail ([`simulate_all`],
//! designs concurrently) or estimated by the sampled tier on shared profiles
//! ([`estimate_all`]), what their results say against a reference design ([`Comparison`]: its
//! speedups and energy ratios, whether the images are identical), and every design again
//! under DRAM-latency perturbation ([`perturb_all`]). [`super::compare_report`] makes
//! their tables and JSON; the command layer prints them.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use anyhow::{bail, Context};
use glam::Vec3;

use crate::estimate::sample::{simulate_sampled, Profile, SampledStats};
use crate::experiment::perturb::{perturbations, perturbed, speedups, Spread};
use crate::model::bvh::{BvhParams, HwBvh};
use crate::model::designs::{self, Design};
use crate::model::gpu::{simulate, SimOptions, SimStats};
use crate::model::scene::Scene;

/// The design whose cycles the speedups divide, when it is compared.
pub const BASELINE: &str = "baseline";

/// The reference of `designs`' speedups and energy ratios: the baseline if it is among them,
/// else the first.
pub fn reference(designs: &[Design]) -> usize {
    designs
        .iter()
        .position(|d| d.label == BASELINE)
        .unwrap_or(0)
}

/// The designs of `vtq compare`: each of `specs` resolved with `overrides` applied
/// ([`designs::resolve`]), stepping every cycle if `lockstep`, and with `sample` (a `--sample`
/// value) applied to and validated against each one's configuration. An error if `specs` is
/// empty, a design does not resolve, two designs simulate different workloads, or the sample
/// does not suit a design.
pub fn resolve_designs(
    specs: &[String],
    overrides: &[String],
    lockstep: bool,
    sample: Option<&str>,
) -> anyhow::Result<Vec<Design>> {
    let designs = specs
        .iter()
        .map(|spec| designs::resolve(spec, overrides))
        .collect::<anyhow::Result<Vec<Design>>>()?;
    let Some(first) = designs.first() else {
        bail!("--designs is empty");
    };
    let settings = first.config.render_settings();
    if let Some(other) = designs
        .iter()
        .find(|d| d.config.render_settings() != settings)
    {
        bail!(
            "designs '{}' and '{}' simulate different workloads ({:?} vs {:?}): set the \
             workload with --set or --width/--height/--spp/--bounces",
            first.label,
            other.label,
            settings,
            other.config.render_settings()
        );
    }
    let mut designs: Vec<Design> = designs
        .into_iter()
        .map(|mut d| {
            d.config.sim.lockstep |= lockstep;
            d
        })
        .collect();
    if let Some(spec) = sample {
        for d in &mut designs {
            d.config
                .sample
                .apply_spec(spec)
                .map_err(anyhow::Error::msg)?;
            d.config
                .sample
                .validate(&d.config)
                .with_context(|| format!("design '{}'", d.label))?;
        }
    }
    Ok(designs)
}

/// One BVH per distinct build parameters of `designs` (built by `build`, in design order of
/// first use) and, per design, the index of its BVH.
pub fn shared_bvhs(
    designs: &[Design],
    mut build: impl FnMut(&BvhParams) -> anyhow::Result<HwBvh>,
) -> anyhow::Result<(Vec<HwBvh>, Vec<usize>)> {
    let mut bvhs: Vec<HwBvh> = Vec::new();
    let mut of = Vec::with_capacity(designs.len());
    for d in designs {
        let params = d.config.bvh_params();
        let k = match bvhs.iter().position(|b| *b.params() == params) {
            Some(k) => k,
            None => {
                bvhs.push(build(&params)?);
                bvhs.len() - 1
            }
        };
        of.push(k);
    }
    Ok((bvhs, of))
}

/// What one design's full-detail simulation gave.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Statistics and image, or why the simulation failed.
    pub result: Result<(SimStats, Vec<Vec3>), String>,
    /// Wall-clock seconds of the whole `simulate` call (setup included).
    pub wall_seconds: f64,
}

/// Simulates every design of `runs` (each with its BVH), `jobs` at a time on `threads` threads
/// each, advancing `bars[i]` (if any) for design `i`; outcomes in design order. A simulation
/// that fails or panics is an outcome with its error, not an error of the whole.
pub fn simulate_all(
    scene: &Scene,
    runs: &[(&Design, &HwBvh)],
    jobs: usize,
    threads: usize,
    bars: &[Option<indicatif::ProgressBar>],
) -> Vec<Outcome> {
    let next = AtomicUsize::new(0);
    let slots: Vec<Mutex<Option<Outcome>>> = runs.iter().map(|_| Mutex::new(None)).collect();
    let worker = || loop {
        let i = next.fetch_add(1, Ordering::Relaxed);
        let Some((design, bvh)) = runs.get(i) else {
            return;
        };
        let bar = bars.get(i).and_then(Option::as_ref);
        let start = Instant::now();
        let options = SimOptions {
            threads,
            ..SimOptions::default()
        };
        let result = simulate(scene, bvh, &design.config, options, bar)
            .map(|out| (out.stats, out.image))
            .map_err(|e| e.to_string());
        if let Some(bar) = bar {
            match &result {
                Ok(_) => bar.finish_with_message("done"),
                Err(_) => bar.abandon_with_message("failed"),
            }
        }
        let outcome = Outcome {
            result,
            wall_seconds: start.elapsed().as_secs_f64(),
        };
        if let Ok(mut slot) = slots[i].lock() {
            *slot = Some(outcome);
        }
    };
    std::thread::scope(|s| {
        for _ in 0..jobs.min(runs.len()) {
            s.spawn(worker);
        }
    });
    // A simulation that panicked left its slot empty (the panic message is on stderr).
    slots
        .into_iter()
        .map(|slot| {
            slot.into_inner().ok().flatten().unwrap_or(Outcome {
                result: Err("the simulation panicked (a simulator bug)".into()),
                wall_seconds: 0.0,
            })
        })
        .collect()
}

/// Full-detail outcomes of designs against the reference design's.
#[derive(Debug)]
pub struct Comparison<'a> {
    /// The designs, in table order.
    pub designs: &'a [Design],
    /// Their outcomes, in the same order.
    pub outcomes: &'a [Outcome],
    /// The index of the reference design ([`reference`]).
    pub reference: usize,
}

impl Comparison<'_> {
    /// The reference's statistics, if it ran.
    fn reference_stats(&self) -> Option<&SimStats> {
        let outcome = self.outcomes.get(self.reference)?;
        outcome.result.as_ref().ok().map(|(s, _)| s)
    }

    /// The speedup of a design with statistics `stats`: the reference's cycles over its.
    pub fn speedup(&self, stats: &SimStats) -> Option<f64> {
        let r = self.reference_stats()?.cycles;
        (stats.cycles > 0).then(|| r as f64 / stats.cycles as f64)
    }

    /// The energy of a design with statistics `stats` over the reference's (docs/energy.md).
    pub fn energy_ratio(&self, stats: &SimStats) -> Option<f64> {
        let r = self.reference_stats()?.energy.total_mj;
        (r > 0.0).then(|| stats.energy.total_mj / r)
    }

    /// The designs that produced an image, with it.
    pub fn images(&self) -> Vec<(&Design, &[Vec3])> {
        (self.designs.iter().zip(self.outcomes))
            .filter_map(|(d, o)| o.result.as_ref().ok().map(|(_, i)| (d, i.as_slice())))
            .collect()
    }

    /// How each image differs from the first design's that produced one, a sentence per design
    /// whose image differs (images `width` pixels wide); empty when all are identical.
    pub fn image_mismatches(&self, width: u32) -> Vec<String> {
        let ran = self.images();
        let Some(((first, first_image), rest)) = ran.split_first() else {
            return Vec::new();
        };
        let w = width.max(1) as usize;
        rest.iter()
            .filter_map(|(design, image)| {
                let (pixel, count) = image_difference(first_image, image)?;
                Some(format!(
                    "{} differs from {} in {count} of {} pixels (first at x={}, y={})",
                    design.label,
                    first.label,
                    first_image.len().max(image.len()),
                    pixel % w,
                    pixel / w
                ))
            })
            .collect()
    }
}

/// Percentages of the three traversal phases' cycles (initial, treelet-stationary,
/// ray-stationary), or `-` when no phase counted a cycle.
pub fn phase_split(stats: &SimStats) -> String {
    let p = &stats.phases;
    let cycles = [
        p.initial.cycles,
        p.treelet_stationary.cycles,
        p.ray_stationary.cycles,
    ];
    let total: u64 = cycles.iter().sum();
    if total == 0 {
        return "-".into();
    }
    let pct = cycles.map(|c| format!("{:.1}", 100.0 * c as f64 / total as f64));
    pct.join("/")
}

/// The index of the first pixel whose color differs bit for bit, and how many differ.
pub fn image_difference(a: &[Vec3], b: &[Vec3]) -> Option<(usize, usize)> {
    let bits = |c: &Vec3| c.to_array().map(f32::to_bits);
    let mut differing = (0..a.len().max(b.len()))
        .filter(|&i| a.get(i).map(bits) != b.get(i).map(bits))
        .peekable();
    let first = *differing.peek()?;
    Some((first, differing.count()))
}

/// One design under perturbation: its cycles and speedups over the unperturbed run and the
/// perturbed ones (JSON `perturbed` of `vtq compare --perturb`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct Perturbed {
    /// DRAM latency offsets of the runs after the first (cycles).
    pub offsets: Vec<i64>,
    /// Cycles, unperturbed first.
    pub cycles: Vec<f64>,
    /// Speedups over the reference design's run with the same offset (empty for the reference
    /// itself).
    pub speedups: Vec<f64>,
}

impl Perturbed {
    /// The spread of its cycles.
    pub fn cycle_spread(&self) -> Spread {
        Spread::of(&self.cycles).expect("every design has its unperturbed run")
    }

    /// The spread of its speedups (`None` for the reference).
    pub fn speedup_spread(&self) -> Option<Spread> {
        Spread::of(&self.speedups)
    }
}

/// Every design of `runs` again `n` times with the DRAM latency moved by +1, -1, +2, ...
/// cycles (`jobs` at a time on `threads` threads each), beside its unperturbed `outcomes`
/// (which must all have succeeded): per design, its cycles and its speedups over the
/// `reference` design's run with the same offset. An error if a perturbed run fails.
pub fn perturb_all(
    scene: &Scene,
    runs: &[(&Design, &HwBvh)],
    (jobs, threads): (usize, usize),
    reference: usize,
    outcomes: &[Outcome],
    n: usize,
) -> anyhow::Result<Vec<Perturbed>> {
    let offsets = perturbations(n);
    let designs: Vec<(Design, &HwBvh)> = offsets
        .iter()
        .flat_map(|&o| runs.iter().map(move |&(d, bvh)| (d, bvh, o)))
        .map(|(d, bvh, o)| {
            let config = perturbed(&d.config, o)
                .map_err(anyhow::Error::msg)
                .with_context(|| format!("design '{}'", d.label))?;
            let design = Design {
                config,
                ..d.clone()
            };
            Ok((design, bvh))
        })
        .collect::<anyhow::Result<_>>()?;
    let all: Vec<(&Design, &HwBvh)> = designs.iter().map(|(d, b)| (d, *b)).collect();
    let more = simulate_all(scene, &all, jobs, threads, &[]);
    let count = runs.len();
    let mut cycles: Vec<Vec<f64>> = vec![Vec::new(); count];
    for (k, o) in outcomes.iter().chain(&more).enumerate() {
        match &o.result {
            Ok((stats, _)) => cycles[k % count].push(stats.cycles as f64),
            Err(e) => bail!(
                "design '{}' failed with the DRAM latency moved by {} cycles: {e}",
                runs[k % count].0.label,
                k.checked_sub(count).map_or(0, |j| offsets[j / count])
            ),
        }
    }
    Ok((0..count)
        .map(|i| Perturbed {
            offsets: offsets.clone(),
            speedups: if i == reference {
                Vec::new()
            } else {
                speedups(&cycles[reference], &cycles[i])
            },
            cycles: cycles[i].clone(),
        })
        .collect())
}

/// One design's sampled-tier estimate and the seconds it took, or why it failed.
pub type Estimated = (Result<SampledStats, String>, f64);

/// Every design of `runs` estimated by the sampled tier (replicates `jobs` at a time), one
/// functional profile per BVH shared by the designs that use it, so every design's samples
/// are the same CTAs and their speedups pair per replicate.
pub fn estimate_all(
    scene: &Scene,
    runs: &[(&Design, &HwBvh)],
    jobs: usize,
) -> anyhow::Result<Vec<Estimated>> {
    let mut profiles: Vec<(*const HwBvh, Profile)> = Vec::new();
    let mut results = Vec::with_capacity(runs.len());
    for (design, bvh) in runs {
        let key: *const HwBvh = *bvh;
        if !profiles.iter().any(|(k, _)| *k == key) {
            let profile = Profile::new(scene, bvh, &design.config)
                .with_context(|| format!("profiling scene '{}'", scene.name))?;
            profiles.push((key, profile));
        }
        let profile = &profiles.iter().find(|(k, _)| *k == key).expect("added").1;
        let start = Instant::now();
        let result =
            simulate_sampled(scene, bvh, &design.config, profile, jobs).map_err(|e| e.to_string());
        results.push((result, start.elapsed().as_secs_f64()));
    }
    Ok(results)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::designs;
    use crate::model::scene::load::load_scene;

    #[test]
    fn image_difference_finds_the_first_and_counts() {
        let a = vec![Vec3::ZERO; 4];
        let mut b = a.clone();
        assert_eq!(image_difference(&a, &b), None);
        b[1] = Vec3::X;
        b[3] = Vec3::new(-0.0, 0.0, 0.0);
        assert_eq!(image_difference(&a, &b), Some((1, 2)));
        assert_eq!(image_difference(&a, &a[..3]), Some((3, 1)));
    }

    #[test]
    fn resolving_designs_applies_lockstep_and_the_sample_and_checks_them() {
        let specs = ["vtq".to_string(), "baseline".into()];
        let sets = ["width=8".to_string(), "height=8".into()];
        let designs = resolve_designs(&specs, &sets, true, Some("1/2x3")).unwrap();
        assert_eq!(designs.len(), 2);
        for d in &designs {
            assert!(d.config.sim.lockstep);
            assert_eq!(
                (d.config.sample.fraction, d.config.sample.replicates),
                (0.5, 3)
            );
            assert_eq!(d.config.workload.width, 8);
        }
        let plain = resolve_designs(&specs[..1], &sets, false, None).unwrap();
        assert!(!plain[0].config.sim.lockstep);
        let e = resolve_designs(&[], &sets, false, None).unwrap_err();
        assert_eq!(e.to_string(), "--designs is empty");
        let e = resolve_designs(&specs, &sets, false, Some("bogus")).unwrap_err();
        assert!(e.to_string().starts_with("--sample `bogus`"), "{e:#}");
    }

    /// Two designs on a tiny frame of cornell, the second with another treelet size.
    fn two_designs() -> Vec<Design> {
        let sets = ["width=8".to_string(), "height=8".into()];
        let base = designs::resolve("baseline", &sets).unwrap();
        let mut other = designs::resolve("vtq", &sets).unwrap();
        other.config.hw.treelet_bytes /= 2;
        vec![other, base]
    }

    #[test]
    fn designs_share_a_bvh_only_with_the_same_build_and_compare_against_the_baseline() {
        let designs = two_designs();
        assert_eq!(reference(&designs), 1, "the baseline, wherever it is");
        assert_eq!(reference(&designs[..1]), 0, "else the first");
        let scene = load_scene("cornell").unwrap();
        let mut built = 0;
        let mut build = |p: &BvhParams| {
            built += 1;
            Ok(HwBvh::build(&scene, p)?)
        };
        let twice = [designs[1].clone(), designs[1].clone()];
        let (bvhs, of) = shared_bvhs(&twice, &mut build).unwrap();
        assert_eq!((bvhs.len(), of), (1, vec![0, 0]));
        let (bvhs, of) = shared_bvhs(&designs, &mut build).unwrap();
        assert_eq!((bvhs.len(), of.clone(), built), (2, vec![0, 1], 3));

        let runs: Vec<(&Design, &HwBvh)> = designs
            .iter()
            .zip(&of)
            .map(|(d, &k)| (d, &bvhs[k]))
            .collect();
        let outcomes = simulate_all(&scene, &runs, 2, 1, &[]);
        let comparison = Comparison {
            designs: &designs,
            outcomes: &outcomes,
            reference: 1,
        };
        let stats = |i: usize| &outcomes[i].result.as_ref().unwrap().0;
        assert_eq!(comparison.speedup(stats(1)), Some(1.0));
        let s = comparison.speedup(stats(0)).unwrap();
        assert_eq!(s, stats(1).cycles as f64 / stats(0).cycles as f64);
        assert_eq!(comparison.energy_ratio(stats(1)), Some(1.0));
        assert!(
            comparison.image_mismatches(8).is_empty(),
            "one image in every design"
        );
        assert_eq!(comparison.images().len(), 2);
    }
}
