//! `vtq compare`: simulate one scene and workload on several designs (by default the baseline,
//! treelet prefetching and Virtualized Treelet Queues) with the cycle-exact GPU model and print
//! one table: cycles, speedup over the baseline, BVH L1 miss rate, SIMT efficiency, the phase
//! split and wall time, plus whether every design produced the identical image.
//!
//! The built-in designs ([`crate::model::designs`]: the paper's three and VTQ with treelet
//! prefetching) are embedded in the binary, so the command works from any directory; other
//! configuration files are named by path. Designs run concurrently (`--jobs`), each simulation on `--threads` threads (1 by
//! default); every statistic except wall time is deterministic and independent of both.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::Args;

use crate::cli::cmd::energy::print_comparison as print_energy_comparison;
use crate::cli::cmd::options::{build_bvh, load_scene, parse_threads, CacheArgs, SampleArg};
use crate::cli::output::{check_file, write_or_keep};
use crate::estimate::sample::paired_speedup;
use crate::experiment::compare::{
    estimate_all, perturb_all, phase_split, reference, shared_bvhs, simulate_all, Comparison,
    Perturbed,
};
use crate::model::bvh::HwBvh;
use crate::model::designs::{self, Design};
use crate::model::energy::EnergyReport;
use crate::model::scene::Scene;

/// Options of `vtq compare`.
#[derive(Debug, Args)]
pub struct CompareArgs {
    /// Scene: a built-in name (`wknd`, `cornell`, `city:N` e.g. `city:250k`), a folder under
    /// ../shared/scenes, a scene folder path or a `.obj` file (see `vtq scenes`).
    #[arg(long)]
    pub scene: String,
    /// Designs to simulate, in table order: built-in names (`baseline`, `prefetch`, `vtq`,
    /// `vtq-prefetch`: the configs/ files of those names) or paths of configuration files
    /// (TOML, docs/config.md).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "baseline,prefetch,vtq",
        value_name = "DESIGN,..."
    )]
    pub designs: Vec<String>,
    /// Override one configuration key in every design, e.g. `--set gpu.sms=4` or
    /// `--set width=64` (repeatable; applied after the design's file).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Image width in pixels (same as `--set width=N`; applied after the --set overrides).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels (same as `--set height=N`).
    #[arg(long)]
    pub height: Option<u32>,
    /// Samples per pixel (same as `--set spp=N`).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Maximum secondary rays per path (same as `--set bounces=N`).
    #[arg(long)]
    pub bounces: Option<u32>,
    /// Write every design's statistics (docs/stats.md) to this JSON file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Simulate up to this many designs at once [default: the available cores].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub jobs: Option<u32>,
    /// Threads simulating each design's SMs (results are identical for every count).
    #[arg(long, default_value_t = 1, value_parser = parse_threads)]
    pub threads: usize,
    /// Step every cycle instead of skipping idle ones (verification; same results).
    #[arg(long)]
    pub lockstep: bool,
    /// The sampled tier instead of full detail (`--sample [POINT]`).
    #[command(flatten)]
    pub sample: SampleArg,
    /// Also run every design N more times with the DRAM latency moved by +1, -1, +2, -2, ...
    /// cycles and print each design's mean and range of cycles and of its speedup over those
    /// runs: whether a difference between designs is larger than the reference's own
    /// sensitivity (docs/accuracy.md, "How far the reference moves"). Full detail only.
    #[arg(long, default_value_t = 0, value_name = "N", conflicts_with = "sample")]
    pub perturb: usize,
    /// The BVH build cache.
    #[command(flatten)]
    pub cache: CacheArgs,
}

impl CompareArgs {
    /// The overrides applied to every design: `--set`, then the image options.
    fn overrides(&self) -> Vec<String> {
        let mut sets = self.set.clone();
        for (key, value) in [
            ("width", self.width),
            ("height", self.height),
            ("spp", self.spp),
            ("bounces", self.bounces),
        ] {
            if let Some(v) = value {
                sets.push(format!("workload.{key}={v}"));
            }
        }
        sets
    }
}

/// Width of the design column of the tables: the longest label, at least the header's.
fn label_width(designs: &[Design]) -> usize {
    designs
        .iter()
        .map(|d| d.label.len())
        .max()
        .unwrap_or(0)
        .max("design".len())
}

/// Progress bars, one per design, on a terminal only.
fn progress_bars(designs: &[Design], pixels: u64) -> Vec<Option<indicatif::ProgressBar>> {
    if !std::io::stderr().is_terminal() {
        return designs.iter().map(|_| None).collect();
    }
    let multi = indicatif::MultiProgress::new();
    let width = designs.iter().map(|d| d.label.len()).max().unwrap_or(0);
    designs
        .iter()
        .map(|d| {
            let bar = multi.add(indicatif::ProgressBar::new(pixels));
            bar.set_style(
                indicatif::ProgressStyle::with_template(&format!(
                    "{{prefix:<{width}}} {{bar:40}} {{pos}}/{{len}} pixels {{elapsed}} {{msg}}"
                ))
                .expect("the progress template is valid"),
            );
            bar.set_prefix(d.label.clone());
            Some(bar)
        })
        .collect()
}

/// Writes the JSON text to `path` (or keeps it in a fallback file) and says so; the error, as
/// one line, when `path` could not be written.
fn write_json(path: &Path, text: &str) -> Option<String> {
    match write_or_keep(path, |p| std::fs::write(p, text)) {
        Ok(()) => {
            println!("wrote {}", path.display());
            None
        }
        Err(e) => Some(format!("{e:#}")),
    }
}

/// Run `vtq compare`.
pub fn run(args: &CompareArgs) -> anyhow::Result<()> {
    let overrides = args.overrides();
    let designs = args
        .designs
        .iter()
        .map(|spec| designs::resolve(spec, &overrides))
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
            d.config.sim.lockstep |= args.lockstep;
            d
        })
        .collect();
    if let Some(spec) = &args.sample.point {
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

    if let Some(path) = &args.json {
        check_file(path)?;
    }
    let scene = load_scene(&args.scene)?;
    let (bvhs, bvh_of) = shared_bvhs(&designs, |p| build_bvh(&scene, p, &args.cache))?;
    let runs: Vec<(&Design, &HwBvh)> = designs
        .iter()
        .zip(bvh_of)
        .map(|(d, k)| (d, &bvhs[k]))
        .collect();

    let jobs = match args.jobs {
        Some(n) => n as usize,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    if args.sample.point.is_some() {
        return compare_sampled(args, &scene, &designs, &runs, jobs);
    }
    println!(
        "compare: {} designs on scene {}, {}x{}, {} spp, {} bounces, {} at a time",
        designs.len(),
        scene.name,
        settings.width,
        settings.height,
        settings.spp,
        settings.bounces,
        jobs.min(designs.len())
    );
    let bars = progress_bars(&designs, settings.pixels() as u64);
    let outcomes = simulate_all(&scene, &runs, jobs, args.threads, &bars);
    for bar in bars.iter().flatten() {
        bar.finish_and_clear();
    }
    // Speedups and energy divide the baseline's when it is compared, else the first design's.
    let comparison = Comparison {
        designs: &designs,
        outcomes: &outcomes,
        reference: reference(&designs),
    };
    let label_width = label_width(&designs);
    let failures = print_table(&comparison, label_width);

    let perturbed = if args.perturb > 0 {
        perturbed_table(args, &scene, &runs, jobs, &comparison, label_width)?
    } else {
        Vec::new()
    };

    let ran = comparison.images().len();
    let mismatches = comparison.image_mismatches(settings.width);
    match (ran, mismatches.is_empty()) {
        (0, _) => println!("images: no design produced an image"),
        (1, _) => println!(
            "images: only {} produced an image, nothing to compare",
            comparison.images()[0].0.label
        ),
        (n, true) => println!(
            "images: identical: all {n} designs that ran produced the same {}x{} image, \
             pixel for pixel",
            settings.width, settings.height
        ),
        (_, false) => println!("images: DIFFERENT: {}", mismatches.join("; ")),
    }

    let mut json_error = None;
    if let Some(path) = &args.json {
        let images_identical = ran >= 2 && mismatches.is_empty();
        let doc = comparison_json(&scene, &comparison, &perturbed, images_identical);
        let text = serde_json::to_string_pretty(&doc).context("serializing the statistics")?;
        json_error = write_json(path, &(text + "\n"));
    }

    let mut problems: Vec<String> = json_error.into_iter().collect();
    if !mismatches.is_empty() {
        problems.push(format!(
            "the designs' images differ (they must be identical): {}",
            mismatches.join("; ")
        ));
    }
    if !failures.is_empty() {
        problems.push(format!(
            "{} of {} designs failed: {}",
            failures.len(),
            designs.len(),
            failures.join("; ")
        ));
    }
    if !problems.is_empty() {
        bail!("{}", problems.join("; "));
    }
    Ok(())
}

/// Prints the comparison's table (design column `label_width` wide), its legend and the
/// energy comparison; returns the failed designs' errors, a line each.
fn print_table(c: &Comparison<'_>, label_width: usize) -> Vec<String> {
    println!(
        "{:<label_width$}  {:>12}  {:>8}  {:>7}  {:>11}  {:>9}  {:>23}  {:>8}",
        "design",
        "cycles",
        "speedup",
        "energy",
        "BVH L1 miss",
        "SIMT eff.",
        "phases % init/TS/RS",
        "wall s"
    );
    let mut failures = Vec::new();
    for (design, outcome) in c.designs.iter().zip(c.outcomes) {
        match &outcome.result {
            Ok((stats, _)) => println!(
                "{:<label_width$}  {:>12}  {:>8}  {:>7}  {:>11.3}  {:>9.3}  {:>23}  {:>8.2}",
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
            Err(e) => {
                println!("{:<label_width$}  error: {e}", design.label);
                failures.push(format!("{}: {e}", design.label));
            }
        }
    }
    let reference = &c.designs[c.reference].label;
    println!(
        "speedup = {reference} cycles / design cycles; energy = design energy / {reference}'s \
         (below); phases: initial / treelet-stationary / ray-stationary share of traversal-phase \
         cycles"
    );
    let energy_rows: Vec<Option<(&str, &EnergyReport)>> = c
        .designs
        .iter()
        .zip(c.outcomes)
        .map(|(d, o)| {
            o.result
                .as_ref()
                .ok()
                .map(|(s, _)| (d.label.as_str(), &s.energy))
        })
        .collect();
    print_energy_comparison(&energy_rows, c.reference, label_width);
    failures
}

/// The JSON document of `vtq compare --json`.
fn comparison_json(
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

/// `vtq compare --perturb`: every design again with the DRAM latency moved by a cycle or two
/// ([`perturb_all`]); prints each design's mean and range of cycles and speedups over its runs
/// (design column `label_width` wide, as the main table's) and returns them per design (an
/// error if a perturbed run fails).
fn perturbed_table(
    args: &CompareArgs,
    scene: &Scene,
    runs: &[(&Design, &HwBvh)],
    jobs: usize,
    c: &Comparison<'_>,
    label_width: usize,
) -> anyhow::Result<Vec<Perturbed>> {
    if c.outcomes.iter().any(|o| o.result.is_err()) {
        println!("under perturbation: not run (a design failed above)");
        return Ok(Vec::new());
    }
    let (threads, reference) = (args.threads, c.reference);
    let out = perturb_all(
        scene,
        runs,
        (jobs, threads),
        reference,
        c.outcomes,
        args.perturb,
    )?;
    let offsets = out.first().map(|p| p.offsets.clone()).unwrap_or_default();
    println!();
    println!(
        "under perturbation: {} runs per design, the DRAM latency moved by {:+?} cycles",
        offsets.len() + 1,
        offsets
    );
    println!(
        "{:<label_width$}  {:>12}  {:>25}  {:>8}  {:>17}",
        "design", "cycles mean", "cycles range", "speedup", "speedup range"
    );
    let mut unresolved = Vec::new();
    for ((design, _), p) in runs.iter().zip(&out) {
        let cycles = p.cycle_spread();
        let (mean, range) = match p.speedup_spread() {
            Some(x) => {
                if x.min < 1.0 && x.max > 1.0 {
                    unresolved.push(design.label.clone());
                }
                (
                    format!("{:.2}", x.mean),
                    format!("{:.2}-{:.2}", x.min, x.max),
                )
            }
            None => ("-".into(), "-".into()),
        };
        println!(
            "{:<label_width$}  {:>12.0}  {:>25}  {:>8}  {:>17}",
            design.label,
            cycles.mean,
            format!(
                "{:.0}-{:.0} ({:.1}%)",
                cycles.min,
                cycles.max,
                100.0 * cycles.relative()
            ),
            mean,
            range
        );
    }
    let reference = &runs[reference].0.label;
    if unresolved.is_empty() {
        println!("every design is faster or slower than {reference} in every run");
    } else {
        println!(
            "not resolved at this frame size: {} is faster than {reference} in some runs and \
             slower in others (try a larger frame)",
            unresolved.join(", "),
        );
    }
    Ok(out)
}

/// `vtq compare --sample`: every design estimated by the sampled tier on the same CTA samples
/// (replicates `jobs` at a time), speedups paired per replicate.
fn compare_sampled(
    args: &CompareArgs,
    scene: &Scene,
    designs: &[Design],
    runs: &[(&Design, &HwBvh)],
    jobs: usize,
) -> anyhow::Result<()> {
    let first = &designs[0].config;
    let s = &first.sample;
    println!(
        "compare (sampled): {} designs on scene {}, each estimated from {} replicates of {} SM(s) \
         on stratified 1/{:.0} samples of the frame (seed {}; whole stripes where every CTA is \
         resident); estimates with 95% intervals",
        designs.len(),
        scene.name,
        s.replicates,
        s.scale_sms(first.gpu.sms).unwrap_or(1),
        1.0 / s.fraction,
        s.seed
    );
    let results = estimate_all(scene, runs, jobs)?;
    let reference = reference(designs);
    let width = label_width(designs);
    println!(
        "{:<width$}  {:>24}  {:>15}  {:>13}  {:>13}  {:>8}",
        "design", "cycles (est.)", "speedup (est.)", "BVH L1 miss", "SIMT eff.", "wall s"
    );
    let mut failures = Vec::new();
    let mut entries = Vec::new();
    for (design, (result, wall)) in designs.iter().zip(&results) {
        match result {
            Ok(est) => {
                let speedup = match &results[reference].0 {
                    Ok(base) => Some(paired_speedup(base, est)),
                    Err(_) => None,
                };
                println!(
                    "{:<width$}  {:>24}  {:>15}  {:>13}  {:>13}  {:>8.2}",
                    design.label,
                    est.cycles.display(0),
                    speedup.map_or_else(|| "-".into(), |s| s.display(3)),
                    est.bvh_l1_miss_rate.display(3),
                    est.simt_efficiency.display(3),
                    wall
                );
                entries.push(serde_json::json!({
                    "design": design.label,
                    "source": design.source,
                    "estimate": true,
                    "speedup": speedup,
                    "wall_seconds": wall,
                    "sampled": est,
                }));
            }
            Err(e) => {
                println!("{:<width$}  error: {e}", design.label);
                failures.push(format!("{}: {e}", design.label));
                entries.push(serde_json::json!({
                    "design": design.label,
                    "source": design.source,
                    "error": e,
                }));
            }
        }
    }
    println!(
        "estimates (sampled tier, not full detail): value ± half-width of the 95% interval; \
         speedup = {} cycles / design cycles, paired per replicate (stratified samples)",
        designs[reference].label
    );
    let labels = |keep: &dyn Fn(&crate::estimate::sample::SampledStats) -> bool| {
        designs
            .iter()
            .zip(&results)
            .filter(|(_, (r, _))| r.as_ref().is_ok_and(keep))
            .map(|(d, _)| d.label.as_str())
            .collect::<Vec<&str>>()
    };
    let by_stripes = labels(&|e| e.method == crate::estimate::sample::Method::Stripes);
    if !by_stripes.is_empty() {
        println!(
            "stripe sampling ({}): {}",
            by_stripes.join(", "),
            crate::estimate::sample::STRIPE_NOTE
        );
    }
    let dynamic = labels(&|e| e.stripes_dynamic);
    if !dynamic.is_empty() {
        println!(
            "stratified ({}): {}",
            dynamic.join(", "),
            crate::estimate::sample::STRIPES_DYNAMIC_NOTE
        );
    }
    let cautioned = labels(&|e| {
        e.every_cta_resident
            && !e.stripes_dynamic
            && e.method == crate::estimate::sample::Method::Strata
    });
    if !cautioned.is_empty() {
        println!(
            "caution ({}): {}",
            cautioned.join(", "),
            crate::estimate::sample::STRIPE_CAUTION
        );
    }
    for note in crate::model::config::sample_points::notes(args.sample.point.as_deref(), first) {
        println!("note: {note}");
    }
    if let Some(path) = &args.json {
        let doc = serde_json::json!({
            "scene": scene.name,
            "speedup_reference": designs[reference].label,
            "sampled": true,
            "designs": entries,
        });
        let text = serde_json::to_string_pretty(&doc).context("serializing the estimates")?;
        if let Some(e) = write_json(path, &(text + "\n")) {
            if failures.is_empty() {
                bail!("{e}");
            }
            eprintln!("error: {e}");
        }
    }
    if !failures.is_empty() {
        bail!(
            "{} of {} designs failed: {}",
            failures.len(),
            designs.len(),
            failures.join("; ")
        );
    }
    Ok(())
}
