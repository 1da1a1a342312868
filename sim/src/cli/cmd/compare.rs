//! `vtq compare`: simulate one scene and workload on several designs (by default the baseline,
//! treelet prefetching and Virtualized Treelet Queues) with the cycle-exact GPU model and print
//! one table: cycles, speedup over the baseline, BVH L1 miss rate, SIMT efficiency, the phase
//! split and wall time, plus whether every design produced the identical image.
//!
//! The built-in designs ([`crate::model::designs`]: the paper's three and VTQ with treelet
//! prefetching) are embedded in the binary, so the command works from any directory; other
//! configuration files are named by path. Designs run concurrently (`--jobs`), each simulation
//! on `--threads` threads (1 by default); every statistic except wall time is deterministic and
//! independent of both. The runs are [`crate::experiment::compare`]'s, the tables and JSON
//! [`crate::experiment::compare_report`]'s: this module parses, calls them and prints.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::Args;

use crate::cli::cmd::energy::print_comparison as print_energy_comparison;
use crate::cli::cmd::options::{build_bvh, load_scene, parse_threads, CacheArgs, SampleArg};
use crate::cli::output::{check_file, write_or_keep};
use crate::experiment::compare::{
    reference, resolve_designs, shared_bvhs, simulate_all, Comparison,
};
use crate::experiment::compare_report::{self as report, ImageCheck};
use crate::model::bvh::HwBvh;
use crate::model::designs::Design;
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
    let point = args.sample.point.as_deref();
    let designs = resolve_designs(&args.designs, &args.overrides(), args.lockstep, point)?;
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
    let prepared = Prepared {
        scene: &scene,
        designs: &designs,
        runs: &runs,
        jobs,
    };
    if point.is_some() {
        compare_sampled(args, &prepared)
    } else {
        compare_full(args, &prepared)
    }
}

/// What both kinds of comparison start from: the scene, the designs, each design with its
/// BVH, and how many runs go at once.
#[derive(Clone, Copy)]
struct Prepared<'a> {
    scene: &'a Scene,
    designs: &'a [Design],
    runs: &'a [(&'a Design, &'a HwBvh)],
    jobs: usize,
}

/// `vtq compare` in full detail: every design simulated (`jobs` at a time), the table, the
/// energy comparison, with `--perturb` the runs under perturbation, and whether the images
/// are identical.
fn compare_full(args: &CompareArgs, prepared: &Prepared) -> anyhow::Result<()> {
    let Prepared {
        scene,
        designs,
        runs,
        jobs,
    } = *prepared;
    let settings = designs[0].config.render_settings();
    println!("{}", report::heading(scene, designs, jobs));
    let bars = progress_bars(designs, settings.pixels() as u64);
    let outcomes = simulate_all(scene, runs, jobs, args.threads, &bars);
    for bar in bars.iter().flatten() {
        bar.finish_and_clear();
    }
    // Speedups and energy divide the baseline's when it is compared, else the first design's.
    let comparison = Comparison {
        designs,
        outcomes: &outcomes,
        reference: reference(designs),
    };
    let width = report::label_width(designs);
    print!("{}", report::table(&comparison, width));
    let energy_rows = report::energy_rows(&comparison);
    print_energy_comparison(&energy_rows, comparison.reference, width);

    let mut perturbed = Vec::new();
    if args.perturb > 0 {
        let threads = (jobs, args.threads);
        let out = report::perturb_report(scene, runs, threads, &comparison, args.perturb, width)?;
        print!("{out}");
        perturbed = out.into_runs();
    }
    let images = ImageCheck::of(&comparison, (settings.width, settings.height));
    println!("{images}");

    let mut problems = Vec::new();
    if let Some(path) = &args.json {
        let doc = report::comparison_json(scene, &comparison, &perturbed, images.identical());
        let text = serde_json::to_string_pretty(&doc).context("serializing the statistics")?;
        problems.extend(write_json(path, &(text + "\n")));
    }
    problems.extend(report::problems(&comparison, &images));
    if !problems.is_empty() {
        bail!("{}", problems.join("; "));
    }
    Ok(())
}

/// `vtq compare --sample`: every design estimated by the sampled tier on the same CTA samples
/// (replicates `jobs` at a time), speedups paired per replicate.
fn compare_sampled(args: &CompareArgs, p: &Prepared) -> anyhow::Result<()> {
    println!("{}", report::sampled_heading(p.scene, p.designs));
    let point = args.sample.point.as_deref();
    let sampled = report::estimate_compared(p.scene, p.designs, p.runs, p.jobs, point)?;
    print!("{sampled}");
    let failed = report::failed_summary(&sampled.failures(), p.designs.len());
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&sampled.json(p.scene))
            .context("serializing the estimates")?;
        if let Some(e) = write_json(path, &(text + "\n")) {
            if failed.is_none() {
                bail!("{e}");
            }
            eprintln!("error: {e}");
        }
    }
    if let Some(failed) = failed {
        bail!("{failed}");
    }
    Ok(())
}
