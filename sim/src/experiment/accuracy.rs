//! The accuracy benchmark (`vtq accuracy`, docs/accuracy.md): for each scene and design, full
//! detail against the sampled tier at several settings — wall time,
//! speed-up over full detail, error of cycles, error of each design's speedup over the baseline,
//! and whether the 95% interval held the full-detail value — with the mean and worst case per
//! setting, a CSV of the rows and a plot of run time against error.
//!
//! With perturbations ([`Plan::perturbations`]) full detail also runs with the DRAM latency
//! moved by a few cycles, a change far below any real GPU's variation: how far the reference
//! itself moves says how much of an estimate's error is the reference's own sensitivity (which
//! SM gets the heaviest CTAs is decided by cycle-level timing) rather than the estimator's
//! bias, and each estimate is also compared with the mean of those runs ([`Reference`]).

use std::time::Instant;

use serde::Serialize;

use crate::estimate::sample::{
    paired_speedup, simulate_sampled, Estimate, Method, Profile, SampleConfig,
};
use crate::experiment::perturb::{perturbed, speedups, Spread};
use crate::experiment::plot::{Point, Scatter, Series};
use crate::model::bvh::HwBvh;
use crate::model::config::SimConfig;
use crate::model::gpu::{simulate, SimError, SimOptions};
use crate::model::scene::Scene;

/// The tier of a row.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum Tier {
    /// Full detail (the reference).
    Full,
    /// The sampled tier at `FRACTIONxREPLICATES`.
    Sampled(String),
}

impl Tier {
    /// Its name in tables and plots.
    pub fn name(&self) -> String {
        match self {
            Tier::Full => "full".into(),
            Tier::Sampled(s) => format!("sampled {s}"),
        }
    }
}

/// One design on one scene at one tier.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Row {
    /// Scene.
    pub scene: String,
    /// Design label.
    pub design: String,
    /// Tier.
    pub tier: Tier,
    /// How the sampled tier chose its CTAs (`None` for full detail).
    pub method: Option<Method>,
    /// Stripe sampling was tried first and found the dispatch not static (the estimate is
    /// stratified; [`crate::estimate::sample::SampledStats::stripes_dynamic`]).
    pub stripes_dynamic: bool,
    /// Wall-clock seconds (the sampled tier's include the functional profile).
    pub wall: f64,
    /// Full detail's wall over this one's.
    pub time_speedup: f64,
    /// Full detail's wall over this one's when the scene's designs share the functional
    /// profile, as `vtq compare --sample` runs them: the sampled tier's wall with its profile's
    /// time divided among the designs (full detail: [`Row::time_speedup`]).
    pub time_speedup_shared: f64,
    /// Cycles (estimate).
    pub cycles: f64,
    /// Half-width of the 95% interval of the cycles (sampled tier).
    pub cycles_half_width: Option<f64>,
    /// Relative error of the cycles against full detail.
    pub cycles_error: f64,
    /// Whether the interval held full detail's cycles (`None` without an interval).
    pub cycles_covered: Option<bool>,
    /// Speedup over the baseline (estimate; `None` for the baseline itself).
    pub speedup: Option<f64>,
    /// Half-width of its 95% interval.
    pub speedup_half_width: Option<f64>,
    /// Its relative error against full detail's speedup.
    pub speedup_error: Option<f64>,
    /// Whether the interval held full detail's speedup.
    pub speedup_covered: Option<bool>,
    /// Full detail under the plan's perturbations (`None` without them).
    pub reference: Option<Reference>,
}

/// Full detail under small perturbations of the DRAM latency: how far the reference moves, and
/// a row's error against the mean of its runs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Reference {
    /// Full detail's cycles, unperturbed first, then one per perturbation.
    pub cycles: Vec<f64>,
    /// Their mean.
    pub mean: f64,
    /// (max - min) / mean of `cycles`: the reference's own spread.
    pub spread: f64,
    /// The row's cycles against `mean` (relative error).
    pub cycles_error: f64,
    /// The row's speedup over the baseline against the mean of full detail's speedups, one per
    /// run (each design's run over the baseline's with the same perturbation); `None` for the
    /// baseline.
    pub speedup_error: Option<f64>,
    /// Whether the row's interval of cycles holds `mean` (`None` without an interval).
    pub cycles_covered: Option<bool>,
    /// Whether the row's interval of its speedup holds the mean of full detail's speedups.
    pub speedup_covered: Option<bool>,
}

impl Reference {
    /// The reference of `cycles` (unperturbed first) for an estimate `estimate` and, for a
    /// design other than the baseline, its speedup `speedup` against the baseline's runs
    /// `baseline` (same perturbations, same order).
    fn of(cycles: &[f64], estimate: &Estimate, speedup: Option<(&Estimate, &[f64])>) -> Self {
        let runs = Spread::of(cycles).unwrap_or(Spread {
            mean: 0.0,
            min: 0.0,
            max: 0.0,
        });
        let mean = runs.mean;
        let speedup_mean = speedup.map(|(s, base)| {
            let m = Spread::of(&speedups(base, cycles)).map_or(0.0, |x| x.mean);
            (s, m)
        });
        Reference {
            cycles: cycles.to_vec(),
            mean,
            spread: runs.relative(),
            cycles_error: estimate.value / mean.max(1.0) - 1.0,
            speedup_error: speedup_mean.map(|(s, m)| s.value / m - 1.0),
            cycles_covered: estimate.half_width.map(|_| estimate.contains(mean)),
            speedup_covered: speedup_mean.and_then(|(s, m)| s.half_width.map(|_| s.contains(m))),
        }
    }
}

/// A design to benchmark: its label and configuration.
#[derive(Debug, Clone)]
pub struct Design {
    /// Label (the first design is the speedup reference).
    pub label: String,
    /// Configuration.
    pub config: SimConfig,
}

/// What a benchmark of one scene needs.
#[derive(Debug, Clone)]
pub struct Plan<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its BVH (every design must use its build parameters).
    pub bvh: &'a HwBvh,
    /// The designs, reference first.
    pub designs: &'a [Design],
    /// Sampled settings: named points (`default`, `fast`) or `FRACTIONxREPLICATES`.
    pub settings: &'a [String],
    /// Threads for full detail's SMs and the sampled tier's replicates.
    pub threads: usize,
    /// DRAM latency offsets (cycles) of the extra full-detail runs ([`Reference`]); empty: none.
    pub perturbations: &'a [i64],
}

/// Runs every tier on one scene; rows in (design, tier) order.
pub fn benchmark(plan: &Plan) -> Result<Vec<Row>, SimError> {
    let scene = plan.scene;
    let first = &plan.designs[0].config;
    // The settings' `[sample]` sections (the setting's fraction and replicates, a named
    // point's profile stride and clusters, the design's other keys), and one functional
    // profile per distinct profile they ask for ([`Profile::key`]), made with the first design
    // and shared by all: setting `k` uses `profiles[of_setting[k]]`.
    let sample_of = |d: &SimConfig, spec: &str| -> Result<SampleConfig, SimError> {
        let defaults = SampleConfig::default();
        let mut s = SampleConfig {
            fraction: defaults.fraction,
            replicates: defaults.replicates,
            ..d.sample.clone()
        };
        s.apply_spec(spec).map_err(SimError::Setup)?;
        Ok(s)
    };
    let mut profiles: Vec<(String, Profile, f64)> = Vec::new();
    let mut of_setting = Vec::new();
    for spec in plan.settings {
        let mut cfg = first.clone();
        cfg.sample = sample_of(first, spec)?;
        let key = Profile::key(&cfg);
        let at = match profiles.iter().position(|(k, _, _)| *k == key) {
            Some(at) => at,
            None => {
                let start = Instant::now();
                let profile = Profile::new(scene, plan.bvh, &cfg)?;
                profiles.push((key, profile, start.elapsed().as_secs_f64()));
                profiles.len() - 1
            }
        };
        of_setting.push(at);
    }
    // Per design: (full cycles, full wall), per setting the sampled result.
    let mut full = Vec::new();
    let mut sampled = Vec::new();
    // Per design: full detail's cycles, unperturbed then perturbed.
    let mut references: Vec<Vec<f64>> = Vec::new();
    for d in plan.designs {
        let t = Instant::now();
        let options = SimOptions {
            threads: plan.threads,
            ..SimOptions::default()
        };
        let out = simulate(scene, plan.bvh, &d.config, options.clone(), None)?;
        full.push((out.stats.cycles as f64, t.elapsed().as_secs_f64()));
        let mut runs = vec![out.stats.cycles as f64];
        for &offset in plan.perturbations {
            let cfg = perturbed(&d.config, offset).map_err(SimError::Setup)?;
            runs.push(
                simulate(scene, plan.bvh, &cfg, options.clone(), None)?
                    .stats
                    .cycles as f64,
            );
        }
        references.push(runs);
        let mut per = Vec::new();
        for (k, spec) in plan.settings.iter().enumerate() {
            let mut cfg = d.config.clone();
            cfg.sample = sample_of(&d.config, spec)?;
            let t = Instant::now();
            let profile = &profiles[of_setting[k]].1;
            let s = simulate_sampled(scene, plan.bvh, &cfg, profile, plan.threads)?;
            per.push((s, t.elapsed().as_secs_f64()));
        }
        sampled.push(per);
    }
    let mut rows = Vec::new();
    let reference = full[0].0;
    for (i, d) in plan.designs.iter().enumerate() {
        let (cycles, wall) = full[i];
        let true_speedup = (i > 0).then(|| reference / cycles.max(1.0));
        // A row's wall: its own plus, for the sampled tier, its setting's profile's (whole, or
        // shared among the designs).
        let row = |tier: Tier,
                   method: Option<(Method, bool)>,
                   own: f64,
                   profile_wall: f64,
                   c: Estimate,
                   s: Option<Estimate>| {
            let shared = profile_wall / plan.designs.len().max(1) as f64;
            let (w, w_shared) = match tier {
                Tier::Full => (own, own),
                Tier::Sampled(_) => (own + profile_wall, own + shared),
            };
            let err = |e: f64, t: f64| e / t - 1.0;
            Row {
                scene: scene.name.clone(),
                design: d.label.clone(),
                tier,
                method: method.map(|m| m.0),
                stripes_dynamic: method.is_some_and(|m| m.1),
                wall: w,
                time_speedup: wall / w.max(1e-9),
                time_speedup_shared: wall / w_shared.max(1e-9),
                cycles: c.value,
                cycles_half_width: c.half_width,
                cycles_error: err(c.value, cycles),
                cycles_covered: c.half_width.map(|_| c.contains(cycles)),
                speedup: s.map(|s| s.value),
                speedup_half_width: s.and_then(|s| s.half_width),
                speedup_error: s.zip(true_speedup).map(|(s, t)| err(s.value, t)),
                speedup_covered: s
                    .zip(true_speedup)
                    .and_then(|(s, t)| s.half_width.map(|_| s.contains(t))),
                reference: (!plan.perturbations.is_empty()).then(|| {
                    let base = (i > 0).then_some(references[0].as_slice());
                    Reference::of(&references[i], &c, s.as_ref().zip(base))
                }),
            }
        };
        let exact = |v: f64| Estimate {
            value: v,
            half_width: None,
        };
        rows.push(row(
            Tier::Full,
            None,
            wall,
            0.0,
            exact(cycles),
            true_speedup.map(exact),
        ));
        for (k, spec) in plan.settings.iter().enumerate() {
            let (s, w) = &sampled[i][k];
            let speedup = (i > 0).then(|| paired_speedup(&sampled[0][k].0, s));
            rows.push(row(
                Tier::Sampled(spec.clone()),
                Some((s.method, s.stripes_dynamic)),
                *w,
                profiles[of_setting[k]].2,
                s.cycles,
                speedup,
            ));
        }
    }
    Ok(rows)
}

/// Mean and worst of `values` (0 for none).
fn mean_worst(values: &[f64]) -> (f64, f64) {
    if values.is_empty() {
        return (0.0, 0.0);
    }
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    (mean, values.iter().copied().fold(0.0, f64::max))
}

/// A tier's summary over all scenes and designs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// Tier name.
    pub tier: String,
    /// Rows summarized.
    pub rows: usize,
    /// Mean speed-up over full detail (wall time).
    pub mean_time_speedup: f64,
    /// Smallest speed-up over full detail.
    pub min_time_speedup: f64,
    /// Mean speed-up over full detail with the profile shared by each scene's designs
    /// ([`Row::time_speedup_shared`]).
    pub mean_time_speedup_shared: f64,
    /// Mean |relative error| of cycles.
    pub mean_cycles_error: f64,
    /// Worst |relative error| of cycles.
    pub worst_cycles_error: f64,
    /// Mean |relative error| of speedups over the baseline.
    pub mean_speedup_error: f64,
    /// Worst |relative error| of speedups.
    pub worst_speedup_error: f64,
    /// Share of intervals (cycles and speedups) that held full detail's value (`None`: no
    /// intervals).
    pub coverage: Option<f64>,
    /// With perturbations: mean and worst |relative error| of cycles, then of speedups,
    /// against the mean of the perturbed full-detail runs ([`Reference`]).
    pub against_mean: Option<[f64; 4]>,
    /// With perturbations: the share of intervals (cycles and speedups) that held that mean
    /// (`None`: no intervals).
    pub coverage_of_mean: Option<f64>,
}

/// The summary of each tier of `rows` in order of first appearance — full detail's only with
/// perturbations (its error against the mean of its perturbed runs: the reference's own
/// sensitivity).
pub fn summarize(rows: &[Row]) -> Vec<Summary> {
    let mut tiers: Vec<String> = Vec::new();
    for r in rows {
        let t = r.tier.name();
        if (r.tier != Tier::Full || r.reference.is_some()) && !tiers.contains(&t) {
            tiers.push(t);
        }
    }
    tiers
        .into_iter()
        .map(|tier| {
            let of: Vec<&Row> = rows.iter().filter(|r| r.tier.name() == tier).collect();
            let cycles: Vec<f64> = of.iter().map(|r| r.cycles_error.abs()).collect();
            let speedups: Vec<f64> = of
                .iter()
                .filter_map(|r| r.speedup_error.map(f64::abs))
                .collect();
            let covered: Vec<bool> = of
                .iter()
                .flat_map(|r| [r.cycles_covered, r.speedup_covered])
                .flatten()
                .collect();
            let times: Vec<f64> = of.iter().map(|r| r.time_speedup).collect();
            let shared: f64 = of.iter().map(|r| r.time_speedup_shared).sum();
            let (mean_c, worst_c) = mean_worst(&cycles);
            let (mean_s, worst_s) = mean_worst(&speedups);
            let refs: Vec<&Reference> = of.iter().filter_map(|r| r.reference.as_ref()).collect();
            let against_mean = (!refs.is_empty()).then(|| {
                let c: Vec<f64> = refs.iter().map(|r| r.cycles_error.abs()).collect();
                let s: Vec<f64> = refs
                    .iter()
                    .filter_map(|r| r.speedup_error.map(f64::abs))
                    .collect();
                let ((mc, wc), (ms, ws)) = (mean_worst(&c), mean_worst(&s));
                [mc, wc, ms, ws]
            });
            let covered_mean: Vec<bool> = refs
                .iter()
                .flat_map(|r| [r.cycles_covered, r.speedup_covered])
                .flatten()
                .collect();
            Summary {
                tier,
                rows: of.len(),
                mean_time_speedup: times.iter().sum::<f64>() / times.len().max(1) as f64,
                min_time_speedup: times.iter().copied().fold(f64::INFINITY, f64::min),
                mean_time_speedup_shared: shared / times.len().max(1) as f64,
                mean_cycles_error: mean_c,
                worst_cycles_error: worst_c,
                mean_speedup_error: mean_s,
                worst_speedup_error: worst_s,
                coverage: (!covered.is_empty())
                    .then(|| covered.iter().filter(|&&c| c).count() as f64 / covered.len() as f64),
                against_mean,
                coverage_of_mean: (!covered_mean.is_empty()).then(|| {
                    covered_mean.iter().filter(|&&c| c).count() as f64 / covered_mean.len() as f64
                }),
            }
        })
        .collect()
}

/// The rows as CSV with a header line.
pub fn csv(rows: &[Row]) -> String {
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v}"));
    let flag = |v: Option<bool>| v.map_or(String::new(), |v| v.to_string());
    let mut out = String::from(
        "scene,design,tier,method,wall_seconds,time_speedup,cycles,cycles_half_width,cycles_error,\
         cycles_covered,speedup,speedup_half_width,speedup_error,speedup_covered,reference_mean,\
         reference_spread,cycles_error_vs_mean,speedup_error_vs_mean,cycles_covered_mean,\
         speedup_covered_mean,time_speedup_shared\n",
    );
    for r in rows {
        let method = match (r.method, r.stripes_dynamic) {
            (None, _) => "",
            (Some(Method::Strata), false) => "strata",
            (Some(Method::Strata), true) => "strata (stripes dynamic)",
            (Some(Method::Stripes), _) => "stripes",
        };
        let reference = r.reference.as_ref();
        out += &format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            r.scene,
            r.design,
            r.tier.name(),
            method,
            r.wall,
            r.time_speedup,
            r.cycles,
            opt(r.cycles_half_width),
            r.cycles_error,
            flag(r.cycles_covered),
            opt(r.speedup),
            opt(r.speedup_half_width),
            opt(r.speedup_error),
            flag(r.speedup_covered),
            opt(reference.map(|x| x.mean)),
            opt(reference.map(|x| x.spread)),
            opt(reference.map(|x| x.cycles_error)),
            opt(reference.and_then(|x| x.speedup_error)),
            flag(reference.and_then(|x| x.cycles_covered)),
            flag(reference.and_then(|x| x.speedup_covered)),
            r.time_speedup_shared,
        );
    }
    out
}

/// The run-time-against-error chart of `rows`: log wall time on x, the signed error of cycles
/// in percent on y, with the sampled tier's 95% intervals as error bars, one series per tier,
/// one marker shape per scene. The error is against full detail's run (full detail at 0), or,
/// with perturbations, against the mean of its runs, full detail's own run plotted there with
/// the range of those runs as its bar.
pub fn chart(rows: &[Row]) -> Scatter {
    let against_mean = !rows.is_empty() && rows.iter().all(|r| r.reference.is_some());
    let mut series: Vec<Series> = Vec::new();
    for r in rows {
        let name = r.tier.name();
        let (y, interval) = match r.reference.as_ref().filter(|_| against_mean) {
            Some(x) => {
                let err = |c: f64| 100.0 * (c / x.mean.max(1.0) - 1.0);
                let interval = match r.cycles_half_width {
                    Some(hw) => Some((err(r.cycles - hw), err(r.cycles + hw))),
                    None => Spread::of(&x.cycles).map(|s| (err(s.min), err(s.max))),
                };
                (100.0 * x.cycles_error, interval)
            }
            None => (100.0 * r.cycles_error, error_interval(r)),
        };
        let point = Point {
            x: r.wall.max(1e-3),
            y,
            label: r.scene.clone(),
            interval,
        };
        match series.iter_mut().find(|s| s.name == name) {
            Some(s) => s.points.push(point),
            None => series.push(Series {
                name,
                points: vec![point],
            }),
        }
    }
    let y_label = if against_mean {
        "error vs full detail's mean (%, 95% interval)"
    } else {
        "error of cycles vs full detail (%, 95% interval)"
    };
    Scatter {
        title: "vtq accuracy: run time against error of cycles".into(),
        x_label: "wall time per design run (s)".into(),
        y_label: y_label.into(),
        x_log: true,
        y_log: false,
        joined: false,
        series,
    }
}

/// The 95% interval of a row's error of cycles in percent (`None` without an interval): the
/// interval of its cycles over full detail's cycles (the estimate over one plus its error).
fn error_interval(r: &Row) -> Option<(f64, f64)> {
    let full = r.cycles / (1.0 + r.cycles_error);
    let hw = r.cycles_half_width?;
    (full.is_finite() && full > 0.0).then(|| {
        let err = |c: f64| 100.0 * (c / full - 1.0);
        (err(r.cycles - hw), err(r.cycles + hw))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A row of `tier` on a scene whose full detail took 100 cycles: `cycles` with an interval
    /// of `half_width`, and full detail's perturbed runs `runs` if any.
    fn row(tier: Tier, cycles: f64, half_width: Option<f64>, runs: Option<&[f64]>) -> Row {
        let estimate = Estimate {
            value: cycles,
            half_width,
        };
        Row {
            scene: "WKND".into(),
            design: "baseline".into(),
            tier,
            method: None,
            stripes_dynamic: false,
            wall: 1.0,
            time_speedup: 1.0,
            time_speedup_shared: 1.0,
            cycles,
            cycles_half_width: half_width,
            cycles_error: cycles / 100.0 - 1.0,
            cycles_covered: half_width.map(|_| estimate.contains(100.0)),
            speedup: None,
            speedup_half_width: None,
            speedup_error: None,
            speedup_covered: None,
            reference: runs.map(|r| Reference::of(r, &estimate, None)),
        }
    }

    /// With perturbations the chart plots errors against the mean of full detail's runs, full
    /// detail's own run with the range of the runs as its bar.
    #[test]
    fn with_perturbations_the_chart_is_against_the_mean() {
        let runs: &[f64] = &[100.0, 120.0, 80.0];
        let rows = [
            row(Tier::Full, 100.0, None, Some(runs)),
            row(Tier::Sampled("1/16x2".into()), 110.0, Some(5.0), Some(runs)),
        ];
        let chart = chart(&rows);
        let points: Vec<&Point> = chart.series.iter().flat_map(|s| &s.points).collect();
        let close =
            |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9;
        assert!(points[0].y.abs() < 1e-9);
        assert!(close(points[0].interval.unwrap(), (-20.0, 20.0)));
        assert!((points[1].y - 10.0).abs() < 1e-9);
        assert!(close(points[1].interval.unwrap(), (5.0, 15.0)));
        assert!(chart.y_label.contains("mean"));
    }

    #[test]
    fn the_reference_is_the_mean_of_the_runs() {
        // Full detail 100 unperturbed, 120 and 80 perturbed; an estimate of 110.
        let est = |value: f64, half_width: Option<f64>| Estimate { value, half_width };
        let r = Reference::of(&[100.0, 120.0, 80.0], &est(110.0, Some(5.0)), None);
        assert!((r.mean - 100.0).abs() < 1e-9);
        assert!((r.spread - 0.4).abs() < 1e-9);
        assert!((r.cycles_error - 0.1).abs() < 1e-9);
        assert_eq!(r.speedup_error, None);
        // 110 +- 5 misses the mean of 100; 110 +- 15 holds it.
        assert_eq!(r.cycles_covered, Some(false));
        let wide = Reference::of(&[100.0, 120.0, 80.0], &est(110.0, Some(15.0)), None);
        assert_eq!(wide.cycles_covered, Some(true));
        // The baseline's runs pair with the design's, perturbation by perturbation: speedups
        // 2, 1.5 and 3 (mean 13/6); an estimate of 2 is 1 - 12/13 below it.
        let base = [200.0, 180.0, 240.0];
        let r = Reference::of(
            &[100.0, 120.0, 80.0],
            &est(110.0, None),
            Some((&est(2.0, Some(0.2)), &base)),
        );
        let err = r.speedup_error.unwrap();
        assert!((err - (12.0 / 13.0 - 1.0)).abs() < 1e-9, "{err}");
        assert_eq!((r.cycles_covered, r.speedup_covered), (None, Some(true)));
    }

    #[test]
    fn the_chart_draws_the_sampled_tiers_intervals() {
        let rows = [
            row(Tier::Full, 100.0, None, None),
            row(Tier::Sampled("1/16x4".into()), 110.0, Some(20.0), None),
            // One replicate: an estimate with no interval.
            row(Tier::Sampled("1/16x1".into()), 80.0, None, None),
        ];
        let chart = chart(&rows);
        let points: Vec<&Point> = chart.series.iter().flat_map(|s| &s.points).collect();
        assert_eq!(points[0].interval, None);
        let (lo, hi) = points[1].interval.expect("the sampled estimate's interval");
        assert!((points[1].y - 10.0).abs() < 1e-9);
        assert!(
            (lo + 10.0).abs() < 1e-9 && (hi - 30.0).abs() < 1e-9,
            "{lo} {hi}"
        );
        // The error is signed, so an interval shows whether it holds full detail (0).
        assert!((points[2].y + 20.0).abs() < 1e-9);
        // The axis holds the estimates; an interval reaching more than half their span beyond
        // them runs off it.
        let (_, y) = chart.axes();
        assert!(y.lo <= -20.0 && y.hi >= 10.0 && y.hi < 30.0, "{y:?}");
        let narrower = [
            rows[0].clone(),
            row(Tier::Sampled("1/16x4".into()), 110.0, Some(12.0), None),
            rows[2].clone(),
        ];
        let (_, y) = super::chart(&narrower).axes();
        assert!(y.lo <= -20.0 && y.hi >= 22.0, "{y:?}");
    }
}
