//! The text and JSON of `vtq compare`: the heading of a run, the full-detail table (cycles,
//! speedup, energy ratio, BVH L1 miss rate, SIMT efficiency, phase split, wall time), the table
//! under DRAM-latency perturbation ([`PerturbedReport`]), whether the images are identical
//! ([`ImageCheck`]), the sampled tier's table of estimates ([`SampledComparison`]) and the
//! `--json` documents. The runs themselves are [`crate::experiment::compare`]'s; the command
//! prints what these functions return.

use std::fmt;

use crate::estimate::sample::{
    paired_speedup, Estimate, Method, SampledStats, STRIPES_DYNAMIC_NOTE, STRIPE_CAUTION,
    STRIPE_NOTE,
};
use crate::experiment::compare::{
    estimate_all, perturb_all, phase_split, reference, Comparison, Estimated, Perturbed,
};
use crate::model::bvh::HwBvh;
use crate::model::config::sample_points;
use crate::model::designs::Design;
use crate::model::energy::EnergyReport;
use crate::model::scene::Scene;

/// Width of the design column of the tables: the longest label, at least the header's.
pub fn label_width(designs: &[Design]) -> usize {
    designs
        .iter()
        .map(|d| d.label.len())
        .max()
        .unwrap_or(0)
        .max("design".len())
}

/// The line that opens a full-detail comparison (no newline): how many designs on which scene
/// and workload, and how many simulated at once with `jobs`. `designs` must not be empty.
pub fn heading(scene: &Scene, designs: &[Design], jobs: usize) -> String {
    let settings = designs[0].config.render_settings();
    format!(
        "compare: {} designs on scene {}, {}x{}, {} spp, {} bounces, {} at a time",
        designs.len(),
        scene.name,
        settings.width,
        settings.height,
        settings.spp,
        settings.bounces,
        jobs.min(designs.len())
    )
}

/// The full-detail table of `c`: a header, a row per design (or its error) with the design
/// column `label_width` wide, and the legend; every line ends in a newline.
pub fn table(c: &Comparison<'_>, label_width: usize) -> String {
    let mut out = format!(
        "{:<label_width$}  {:>12}  {:>8}  {:>7}  {:>11}  {:>9}  {:>23}  {:>8}\n",
        "design",
        "cycles",
        "speedup",
        "energy",
        "BVH L1 miss",
        "SIMT eff.",
        "phases % init/TS/RS",
        "wall s"
    );
    for (design, outcome) in c.designs.iter().zip(c.outcomes) {
        out += &match &outcome.result {
            Ok((stats, _)) => format!(
                "{:<label_width$}  {:>12}  {:>8}  {:>7}  {:>11.3}  {:>9.3}  {:>23}  {:>8.2}\n",
                design.label,
                stats.cycles,
                c.speedup(stats)
                    .map_or_else(|| "-".into(), |s| format!("{s:.2}")),
                c.energy_ratio(stats)
                    .map_or_else(|| "-".into(), |e| format!("{e:.3}")),
                stats.bvh_l1_miss_rate,
                stats.simt_efficiency,
                phase_split(stats),
                outcome.wall_seconds
            ),
            Err(e) => format!("{:<label_width$}  error: {e}\n", design.label),
        };
    }
    let reference = &c.designs[c.reference].label;
    out += &format!(
        "speedup = {reference} cycles / design cycles; energy = design energy / {reference}'s \
         (below); phases: initial / treelet-stationary / ray-stationary share of traversal-phase \
         cycles\n"
    );
    out
}

/// Each design's label and energy report, `None` for a design that failed: the rows of the
/// energy comparison printed under [`table`].
pub fn energy_rows<'a>(c: &Comparison<'a>) -> Vec<Option<(&'a str, &'a EnergyReport)>> {
    c.designs
        .iter()
        .zip(c.outcomes)
        .map(|(d, o)| {
            o.result
                .as_ref()
                .ok()
                .map(|(s, _)| (d.label.as_str(), &s.energy))
        })
        .collect()
}

/// The failed designs of `c`, a line each: `label: error`.
pub fn failures(c: &Comparison<'_>) -> Vec<String> {
    (c.designs.iter().zip(c.outcomes))
        .filter_map(|(d, o)| o.result.as_ref().err().map(|e| format!("{}: {e}", d.label)))
        .collect()
}

/// The sentence that ends a comparison in which some of `designs` designs failed (`failures`
/// as [`failures`] gives them); `None` when none did.
pub fn failed_summary(failures: &[String], designs: usize) -> Option<String> {
    (!failures.is_empty()).then(|| {
        format!(
            "{} of {designs} designs failed: {}",
            failures.len(),
            failures.join("; ")
        )
    })
}

/// Whether the designs of a full-detail comparison produced the identical image.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageCheck {
    /// How many designs produced an image.
    pub ran: usize,
    /// The label of the first design that produced one.
    pub first: Option<String>,
    /// How each image differs from the first's ([`Comparison::image_mismatches`]).
    pub mismatches: Vec<String>,
    /// The image's width and height in pixels.
    pub size: (u32, u32),
}

impl ImageCheck {
    /// The check of `c`'s images, `size` (width, height) pixels.
    pub fn of(c: &Comparison<'_>, size: (u32, u32)) -> ImageCheck {
        let images = c.images();
        ImageCheck {
            ran: images.len(),
            first: images.first().map(|(d, _)| d.label.clone()),
            mismatches: c.image_mismatches(size.0),
            size,
        }
    }

    /// Whether at least two designs produced an image and all are identical.
    pub fn identical(&self) -> bool {
        self.ran >= 2 && self.mismatches.is_empty()
    }
}

/// The `images: ...` line (no newline).
impl fmt::Display for ImageCheck {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (width, height) = self.size;
        match (self.ran, self.mismatches.is_empty()) {
            (0, _) => write!(f, "images: no design produced an image"),
            (1, _) => write!(
                f,
                "images: only {} produced an image, nothing to compare",
                self.first.as_deref().unwrap_or_default()
            ),
            (n, true) => write!(
                f,
                "images: identical: all {n} designs that ran produced the same {width}x{height} \
                 image, pixel for pixel"
            ),
            (_, false) => write!(f, "images: DIFFERENT: {}", self.mismatches.join("; ")),
        }
    }
}

/// What makes a full-detail comparison fail, a sentence each: images that differ, designs that
/// failed.
pub fn problems(c: &Comparison<'_>, images: &ImageCheck) -> Vec<String> {
    let mut problems = Vec::new();
    if !images.mismatches.is_empty() {
        problems.push(format!(
            "the designs' images differ (they must be identical): {}",
            images.mismatches.join("; ")
        ));
    }
    problems.extend(failed_summary(&failures(c), c.designs.len()));
    problems
}

/// The JSON document of `vtq compare --json` in full detail: per design its statistics,
/// speedup, energy ratio, wall time and runs under perturbation (`perturbed`, per design; empty
/// without `--perturb`), or its error.
pub fn comparison_json(
    scene: &Scene,
    c: &Comparison<'_>,
    perturbed: &[Perturbed],
    images_identical: bool,
) -> serde_json::Value {
    let entries: Vec<serde_json::Value> = (c.designs.iter().zip(c.outcomes))
        .enumerate()
        .map(|(i, (d, o))| match &o.result {
            Ok((stats, _)) => serde_json::json!({
                "design": d.label,
                "source": d.source,
                "speedup": c.speedup(stats),
                "energy_ratio": c.energy_ratio(stats),
                "wall_seconds": o.wall_seconds,
                "stats": stats,
                "perturbed": perturbed.get(i),
            }),
            Err(e) => serde_json::json!({
                "design": d.label,
                "source": d.source,
                "error": e,
            }),
        })
        .collect();
    serde_json::json!({
        "scene": scene.name,
        "speedup_reference": c.designs[c.reference].label,
        "images_identical": images_identical,
        "designs": entries,
    })
}

/// `vtq compare --perturb`: each design's mean and range of cycles and of its speedup over its
/// runs with the DRAM latency moved by a cycle or two ([`perturb_all`]).
#[derive(Debug, Clone)]
pub struct PerturbedReport {
    /// The designs' labels, in table order.
    pub labels: Vec<String>,
    /// The index of the reference design (its speedups are empty).
    pub reference: usize,
    /// Width of the design column (as the main table's, [`label_width`]).
    pub label_width: usize,
    /// Per design, its runs; `None` when they were not run because a design failed.
    pub runs: Option<Vec<Perturbed>>,
}

/// Runs every design of `runs` `n` more times under perturbation ([`perturb_all`]; `jobs` at
/// a time on `threads` threads each) beside the unperturbed outcomes of `c`, unless a design
/// of `c` failed; the report with the design column `label_width` wide. An error if a
/// perturbed run fails.
pub fn perturb_report(
    scene: &Scene,
    runs: &[(&Design, &HwBvh)],
    (jobs, threads): (usize, usize),
    c: &Comparison<'_>,
    n: usize,
    label_width: usize,
) -> anyhow::Result<PerturbedReport> {
    let failed = c.outcomes.iter().any(|o| o.result.is_err());
    let runs_out = if failed {
        None
    } else {
        Some(perturb_all(
            scene,
            runs,
            (jobs, threads),
            c.reference,
            c.outcomes,
            n,
        )?)
    };
    Ok(PerturbedReport {
        labels: runs.iter().map(|(d, _)| d.label.clone()).collect(),
        reference: c.reference,
        label_width,
        runs: runs_out,
    })
}

impl PerturbedReport {
    /// The designs whose speedup is above 1 in some runs and below in others.
    pub fn unresolved(&self) -> Vec<&str> {
        let runs = self.runs.as_deref().unwrap_or_default();
        (self.labels.iter().zip(runs))
            .filter(|(_, p)| {
                p.speedup_spread()
                    .is_some_and(|x| x.min < 1.0 && x.max > 1.0)
            })
            .map(|(l, _)| l.as_str())
            .collect()
    }

    /// The runs per design for the JSON document (empty when not run).
    pub fn into_runs(self) -> Vec<Perturbed> {
        self.runs.unwrap_or_default()
    }
}

/// The report's text, every line ending in a newline: a line saying it was not run, or a blank
/// line, the runs' offsets, the table and whether every design's speedup kept its side of 1.
impl fmt::Display for PerturbedReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let Some(runs) = &self.runs else {
            return writeln!(f, "under perturbation: not run (a design failed above)");
        };
        let width = self.label_width;
        let offsets = runs.first().map(|p| p.offsets.clone()).unwrap_or_default();
        writeln!(f)?;
        writeln!(
            f,
            "under perturbation: {} runs per design, the DRAM latency moved by {:+?} cycles",
            offsets.len() + 1,
            offsets
        )?;
        writeln!(
            f,
            "{:<width$}  {:>12}  {:>25}  {:>8}  {:>17}",
            "design", "cycles mean", "cycles range", "speedup", "speedup range"
        )?;
        for (label, p) in self.labels.iter().zip(runs) {
            let cycles = p.cycle_spread();
            let (mean, range) = match p.speedup_spread() {
                Some(x) => (
                    format!("{:.2}", x.mean),
                    format!("{:.2}-{:.2}", x.min, x.max),
                ),
                None => ("-".into(), "-".into()),
            };
            writeln!(
                f,
                "{:<width$}  {:>12.0}  {:>25}  {:>8}  {:>17}",
                label,
                cycles.mean,
                format!(
                    "{:.0}-{:.0} ({:.1}%)",
                    cycles.min,
                    cycles.max,
                    100.0 * cycles.relative()
                ),
                mean,
                range
            )?;
        }
        let reference = &self.labels[self.reference];
        let unresolved = self.unresolved();
        if unresolved.is_empty() {
            writeln!(
                f,
                "every design is faster or slower than {reference} in every run"
            )
        } else {
            writeln!(
                f,
                "not resolved at this frame size: {} is faster than {reference} in some runs and \
                 slower in others (try a larger frame)",
                unresolved.join(", "),
            )
        }
    }
}

/// The line that opens a sampled comparison (no newline): how many designs on which scene,
/// and the first design's sampling (replicates, SMs, fraction, seed). `designs` must not be
/// empty.
pub fn sampled_heading(scene: &Scene, designs: &[Design]) -> String {
    let first = &designs[0].config;
    let s = &first.sample;
    format!(
        "compare (sampled): {} designs on scene {}, each estimated from {} replicates of {} SM(s) \
         on stratified 1/{:.0} samples of the frame (seed {}; whole stripes where every CTA is \
         resident); estimates with 95% intervals",
        designs.len(),
        scene.name,
        s.replicates,
        s.scale_sms(first.gpu.sms).unwrap_or(1),
        1.0 / s.fraction,
        s.seed
    )
}

/// `vtq compare --sample`: every design's sampled-tier estimate and its speedup over the
/// reference's, paired per replicate.
#[derive(Debug, Clone)]
pub struct SampledComparison<'a> {
    /// The designs, in table order.
    pub designs: &'a [Design],
    /// Their estimates and wall seconds, in the same order ([`estimate_all`]).
    pub results: Vec<Estimated>,
    /// The index of the reference design ([`reference`]).
    pub reference: usize,
    /// The `--sample` value, for the notes of a named operating point.
    pub point: Option<String>,
}

/// Estimates every design of `runs` (the designs of `designs` in order, each with its BVH) by
/// the sampled tier, replicates `jobs` at a time ([`estimate_all`]); `point` is the `--sample`
/// value. An error if a scene's profile fails; a design's failure is in its result.
pub fn estimate_compared<'a>(
    scene: &Scene,
    designs: &'a [Design],
    runs: &[(&Design, &HwBvh)],
    jobs: usize,
    point: Option<&str>,
) -> anyhow::Result<SampledComparison<'a>> {
    Ok(SampledComparison {
        designs,
        results: estimate_all(scene, runs, jobs)?,
        reference: reference(designs),
        point: point.map(str::to_string),
    })
}

impl SampledComparison<'_> {
    /// The speedup of design `i` over the reference, paired per replicate (`None` if either
    /// failed).
    pub fn speedup(&self, i: usize) -> Option<Estimate> {
        let base = self.results[self.reference].0.as_ref().ok()?;
        let est = self.results[i].0.as_ref().ok()?;
        Some(paired_speedup(base, est))
    }

    /// The failed designs, a line each: `label: error`.
    pub fn failures(&self) -> Vec<String> {
        (self.designs.iter().zip(&self.results))
            .filter_map(|(d, (r, _))| r.as_ref().err().map(|e| format!("{}: {e}", d.label)))
            .collect()
    }

    /// The labels of the designs whose estimate satisfies `keep`.
    fn labels(&self, keep: impl Fn(&SampledStats) -> bool) -> Vec<&str> {
        (self.designs.iter().zip(&self.results))
            .filter(|(_, (r, _))| r.as_ref().is_ok_and(&keep))
            .map(|(d, _)| d.label.as_str())
            .collect()
    }

    /// The notes under the table, a line each: stripe sampling, stratified samples where
    /// stripes were dynamic, the caution where every CTA is resident, the operating point's.
    fn notes(&self) -> Vec<String> {
        let mut lines = Vec::new();
        let by_stripes = self.labels(|e| e.method == Method::Stripes);
        if !by_stripes.is_empty() {
            lines.push(format!(
                "stripe sampling ({}): {STRIPE_NOTE}",
                by_stripes.join(", ")
            ));
        }
        let dynamic = self.labels(|e| e.stripes_dynamic);
        if !dynamic.is_empty() {
            lines.push(format!(
                "stratified ({}): {STRIPES_DYNAMIC_NOTE}",
                dynamic.join(", ")
            ));
        }
        let cautioned = self
            .labels(|e| e.every_cta_resident && !e.stripes_dynamic && e.method == Method::Strata);
        if !cautioned.is_empty() {
            lines.push(format!(
                "caution ({}): {STRIPE_CAUTION}",
                cautioned.join(", ")
            ));
        }
        let first = &self.designs[0].config;
        for note in sample_points::notes(self.point.as_deref(), first) {
            lines.push(format!("note: {note}"));
        }
        lines
    }

    /// The JSON document of `vtq compare --sample --json`: per design its estimates, speedup
    /// and wall time, or its error.
    pub fn json(&self, scene: &Scene) -> serde_json::Value {
        let entries: Vec<serde_json::Value> = (self.designs.iter().zip(&self.results))
            .enumerate()
            .map(|(i, (design, (result, wall)))| match result {
                Ok(est) => serde_json::json!({
                    "design": design.label,
                    "source": design.source,
                    "estimate": true,
                    "speedup": self.speedup(i),
                    "wall_seconds": wall,
                    "sampled": est,
                }),
                Err(e) => serde_json::json!({
                    "design": design.label,
                    "source": design.source,
                    "error": e,
                }),
            })
            .collect();
        serde_json::json!({
            "scene": scene.name,
            "speedup_reference": self.designs[self.reference].label,
            "sampled": true,
            "designs": entries,
        })
    }
}

/// The table of estimates (a row per design, or its error), its legend and the notes; every
/// line ends in a newline.
impl fmt::Display for SampledComparison<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let width = label_width(self.designs);
        writeln!(
            f,
            "{:<width$}  {:>24}  {:>15}  {:>13}  {:>13}  {:>8}",
            "design", "cycles (est.)", "speedup (est.)", "BVH L1 miss", "SIMT eff.", "wall s"
        )?;
        for (i, (design, (result, wall))) in self.designs.iter().zip(&self.results).enumerate() {
            match result {
                Ok(est) => writeln!(
                    f,
                    "{:<width$}  {:>24}  {:>15}  {:>13}  {:>13}  {:>8.2}",
                    design.label,
                    est.cycles.display(0),
                    self.speedup(i).map_or_else(|| "-".into(), |s| s.display(3)),
                    est.bvh_l1_miss_rate.display(3),
                    est.simt_efficiency.display(3),
                    wall
                )?,
                Err(e) => writeln!(f, "{:<width$}  error: {e}", design.label)?,
            }
        }
        writeln!(
            f,
            "estimates (sampled tier, not full detail): value ± half-width of the 95% interval; \
             speedup = {} cycles / design cycles, paired per replicate (stratified samples)",
            self.designs[self.reference].label
        )?;
        for line in self.notes() {
            writeln!(f, "{line}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::compare::{resolve_designs, shared_bvhs, simulate_all, Outcome};
    use crate::model::scene::load::load_scene;

    /// `specs` resolved on a `size`-pixel square frame, with the sampled tier's `sample`.
    fn designs(specs: &[&str], size: u32, sample: Option<&str>) -> Vec<Design> {
        let specs: Vec<String> = specs.iter().map(|s| s.to_string()).collect();
        let sets = [
            format!("width={size}"),
            format!("height={size}"),
            "gpu.sms=4".into(),
        ];
        resolve_designs(&specs, &sets, false, sample).unwrap()
    }

    /// The designs of `labels` under perturbation, with `cycles` and `speedups` per design.
    fn perturbed_report(rows: &[(&str, Vec<f64>, Vec<f64>)]) -> PerturbedReport {
        PerturbedReport {
            labels: rows.iter().map(|(l, _, _)| l.to_string()).collect(),
            reference: 0,
            label_width: 8,
            runs: Some(
                rows.iter()
                    .map(|(_, cycles, speedups)| Perturbed {
                        offsets: vec![1, -1],
                        cycles: cycles.clone(),
                        speedups: speedups.clone(),
                    })
                    .collect(),
            ),
        }
    }

    #[test]
    fn the_perturbed_table_has_a_row_per_design_and_names_the_unresolved() {
        let report = perturbed_report(&[
            ("base", vec![100.0, 120.0, 80.0], vec![]),
            ("fast", vec![50.0, 60.0, 40.0], vec![2.0, 2.0, 2.0]),
            ("close", vec![95.0, 125.0, 80.0], vec![1.05, 0.96, 1.0]),
        ]);
        let text = report.to_string();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 1 + 1 + 1 + 3 + 1, "{text}");
        assert_eq!(lines[0], "", "a blank line first");
        assert_eq!(
            lines[1],
            "under perturbation: 3 runs per design, the DRAM latency moved by [+1, -1] cycles"
        );
        assert!(lines[2].starts_with("design     cycles mean"), "{text}");
        let base: Vec<&str> = lines[3].split_whitespace().collect();
        assert_eq!(base, ["base", "100", "80-120", "(40.0%)", "-", "-"]);
        let fast: Vec<&str> = lines[4].split_whitespace().collect();
        assert_eq!(
            fast,
            ["fast", "50", "40-60", "(40.0%)", "2.00", "2.00-2.00"]
        );
        assert_eq!(report.unresolved(), ["close"]);
        assert!(
            lines[6].starts_with("not resolved at this frame size: close is faster than base"),
            "{text}"
        );
        assert_eq!(report.clone().into_runs().len(), 3);

        let resolved = perturbed_report(&[
            ("base", vec![100.0], vec![]),
            ("fast", vec![50.0], vec![2.0]),
        ]);
        assert!(resolved.unresolved().is_empty());
        assert!(resolved
            .to_string()
            .ends_with("every design is faster or slower than base in every run\n"));

        let not_run = PerturbedReport {
            runs: None,
            ..resolved
        };
        assert_eq!(
            not_run.to_string(),
            "under perturbation: not run (a design failed above)\n"
        );
        assert!(not_run.into_runs().is_empty());
    }

    #[test]
    fn the_image_line_says_how_many_ran_and_whether_they_match() {
        let mut check = ImageCheck {
            ran: 3,
            first: Some("baseline".into()),
            mismatches: Vec::new(),
            size: (32, 16),
        };
        assert!(check.identical());
        assert_eq!(
            check.to_string(),
            "images: identical: all 3 designs that ran produced the same 32x16 image, pixel for \
             pixel"
        );
        check.mismatches = vec!["vtq differs".into(), "prefetch differs".into()];
        assert!(!check.identical());
        assert_eq!(
            check.to_string(),
            "images: DIFFERENT: vtq differs; prefetch differs"
        );
        check.ran = 1;
        assert!(!check.identical());
        assert_eq!(
            check.to_string(),
            "images: only baseline produced an image, nothing to compare"
        );
        check.ran = 0;
        assert_eq!(check.to_string(), "images: no design produced an image");
        assert_eq!(failed_summary(&[], 3), None);
        assert_eq!(
            failed_summary(&["a: x".into(), "b: y".into()], 3).as_deref(),
            Some("2 of 3 designs failed: a: x; b: y")
        );
    }

    #[test]
    fn failed_designs_are_error_rows_and_problems() {
        let designs = designs(&["vtq", "baseline"], 8, None);
        let outcomes = vec![
            Outcome {
                result: Err("out of memory".into()),
                wall_seconds: 0.0,
            };
            2
        ];
        let c = Comparison {
            designs: &designs,
            outcomes: &outcomes,
            reference: reference(&designs),
        };
        let text = table(&c, label_width(&designs));
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 4, "{text}");
        assert!(lines[0].starts_with("design  "), "{text}");
        assert_eq!(lines[1], "vtq       error: out of memory");
        assert!(lines[3].starts_with("speedup = baseline cycles"), "{text}");
        assert_eq!(energy_rows(&c), [None, None]);
        let images = ImageCheck::of(&c, (8, 8));
        assert_eq!((images.ran, images.identical()), (0, false));
        assert_eq!(
            problems(&c, &images),
            ["2 of 2 designs failed: vtq: out of memory; baseline: out of memory"]
        );
        let doc = comparison_json(&load_scene("cornell").unwrap(), &c, &[], false);
        assert_eq!(doc["speedup_reference"], "baseline");
        assert_eq!(doc["designs"][0]["error"], "out of memory");
    }

    #[test]
    fn the_full_table_shows_each_designs_cycles_and_speedup() {
        let scene = load_scene("cornell").unwrap();
        let designs = designs(&["baseline", "vtq"], 8, None);
        let (bvhs, of) = shared_bvhs(&designs, |p| Ok(HwBvh::build(&scene, p)?)).unwrap();
        let runs: Vec<(&Design, &HwBvh)> =
            designs.iter().zip(of).map(|(d, k)| (d, &bvhs[k])).collect();
        let outcomes = simulate_all(&scene, &runs, 2, 1, &[]);
        let c = Comparison {
            designs: &designs,
            outcomes: &outcomes,
            reference: 0,
        };
        assert!(heading(&scene, &designs, 4).ends_with("8x8, 1 spp, 3 bounces, 2 at a time"));
        let text = table(&c, label_width(&designs));
        assert_eq!(text.lines().count(), 1 + 2 + 1, "{text}");
        let row = |i: usize| -> Vec<&str> {
            text.lines()
                .nth(1 + i)
                .unwrap()
                .split_whitespace()
                .collect()
        };
        for i in 0..2 {
            let stats = &outcomes[i].result.as_ref().unwrap().0;
            assert_eq!(row(i)[0], designs[i].label);
            assert_eq!(row(i)[1], stats.cycles.to_string(), "{text}");
            assert_eq!(row(i)[6], phase_split(stats), "{text}");
        }
        assert_eq!(&row(0)[2..4], ["1.00", "1.000"], "{text}");
        assert!(failures(&c).is_empty());
        assert_eq!(energy_rows(&c).iter().flatten().count(), 2);
        let images = ImageCheck::of(&c, (8, 8));
        assert!(images.identical() && problems(&c, &images).is_empty());
        let json = comparison_json(&scene, &c, &[], true);
        assert_eq!(json["designs"][1]["design"], "vtq");
        assert!(json["designs"][0]["perturbed"].is_null());
    }

    #[test]
    fn the_sampled_table_pairs_speedups_against_the_reference() {
        let scene = load_scene("cornell").unwrap();
        let designs = designs(&["vtq", "baseline"], 16, Some("1/2x2"));
        let (bvhs, of) = shared_bvhs(&designs, |p| Ok(HwBvh::build(&scene, p)?)).unwrap();
        let runs: Vec<(&Design, &HwBvh)> =
            designs.iter().zip(of).map(|(d, k)| (d, &bvhs[k])).collect();
        assert!(sampled_heading(&scene, &designs)
            .starts_with("compare (sampled): 2 designs on scene cornell, each estimated from 2"));
        let mut sampled = estimate_compared(&scene, &designs, &runs, 2, Some("1/2x2")).unwrap();
        assert_eq!(sampled.reference, 1, "the baseline");
        let text = sampled.to_string();
        let lines: Vec<&str> = text.lines().collect();
        assert!(lines[0].starts_with("design   "), "{text}");
        assert!(lines[2].starts_with("baseline"), "{text}");
        assert!(
            lines[2].contains("1.000 ± 0.000"),
            "a design over itself: {text}"
        );
        assert!(lines[3].starts_with("estimates (sampled tier"), "{text}");
        let est = sampled.results[0].0.as_ref().unwrap().clone();
        assert!(lines[1].contains(&est.cycles.display(0)), "{text}");
        assert!(sampled.failures().is_empty());
        let json = sampled.json(&scene);
        assert_eq!(
            (json["sampled"].as_bool(), &json["speedup_reference"]),
            (Some(true), &serde_json::json!("baseline"))
        );
        assert_eq!(json["designs"][1]["speedup"]["value"], 1.0);

        // A failed reference: no speedups, an error row, a failure.
        sampled.results[1].0 = Err("no profile".into());
        assert_eq!(sampled.speedup(0), None);
        let text = sampled.to_string();
        assert!(text.contains("\nbaseline  error: no profile\n"), "{text}");
        assert_eq!(sampled.failures(), ["baseline: no profile"]);
        assert_eq!(sampled.json(&scene)["designs"][1]["error"], "no profile");
    }
}
