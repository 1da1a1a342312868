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
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use anyhow::{bail, Context};
use clap::Args;
use glam::Vec3;

use crate::cli::cmd::energy::print_comparison as print_energy_comparison;
use crate::cli::cmd::options::{build_bvh, load_scene, parse_threads, CacheArgs, SampleArg};
use crate::cli::output::{check_file, write_or_keep};
use crate::estimate::sample::{paired_speedup, simulate_sampled, Profile};
use crate::experiment::perturb::{perturbations, perturbed, speedups, Spread};
use crate::model::bvh::HwBvh;
use crate::model::designs::{self, Design};
use crate::model::energy::EnergyReport;
use crate::model::gpu::{simulate, SimOptions, SimStats};
use crate::model::scene::Scene;

/// The design whose cycles the speedups divide, when it is among `--designs`.
const BASELINE: &str = "baseline";

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

/// What one design's simulation gave.
struct Outcome {
    /// Statistics and image, or why the simulation failed.
    result: Result<(SimStats, Vec<Vec3>), String>,
    /// Wall-clock seconds of the whole `simulate` call (setup included).
    wall_seconds: f64,
}

/// Simulates every design (each with its BVH), `jobs` at a time on `threads` threads each;
/// outcomes in design order.
fn simulate_all(
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
        let start = Instant::now();
        let result = simulate(
            scene,
            bvh,
            &design.config,
            SimOptions {
                threads,
                ..SimOptions::default()
            },
            bars[i].as_ref(),
        )
        .map(|out| (out.stats, out.image))
        .map_err(|e| e.to_string());
        if let Some(bar) = &bars[i] {
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

/// Percentages of the three traversal phases' cycles (initial, treelet-stationary,
/// ray-stationary), or `-` when no phase counted a cycle.
fn phase_split(stats: &SimStats) -> String {
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
fn image_difference(a: &[Vec3], b: &[Vec3]) -> Option<(usize, usize)> {
    let bits = |c: &Vec3| c.to_array().map(f32::to_bits);
    let mut differing = (0..a.len().max(b.len()))
        .filter(|&i| a.get(i).map(bits) != b.get(i).map(bits))
        .peekable();
    let first = *differing.peek()?;
    Some((first, differing.count()))
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
    // One BVH per distinct build parameters, shared by every design that uses them.
    let mut bvhs: Vec<HwBvh> = Vec::new();
    let mut bvh_of = Vec::with_capacity(designs.len());
    for d in &designs {
        let params = d.config.bvh_params();
        let k = match bvhs.iter().position(|b| *b.params() == params) {
            Some(k) => k,
            None => {
                bvhs.push(build_bvh(&scene, &params, &args.cache)?);
                bvhs.len() - 1
            }
        };
        bvh_of.push(k);
    }
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

    // Speedups divide the baseline's cycles when it is compared, else the first design's.
    let reference = designs
        .iter()
        .position(|d| d.label == BASELINE)
        .unwrap_or(0);
    let reference_cycles = match &outcomes[reference].result {
        Ok((stats, _)) => Some(stats.cycles),
        Err(_) => None,
    };
    let speedup = |stats: &SimStats| {
        reference_cycles
            .filter(|_| stats.cycles > 0)
            .map(|r| r as f64 / stats.cycles as f64)
    };

    // Energy relative to the reference design's (docs/energy.md).
    let reference_mj = outcomes[reference]
        .result
        .as_ref()
        .ok()
        .map(|(s, _)| s.energy.total_mj);
    let energy = |s: &SimStats| {
        reference_mj
            .filter(|&e| e > 0.0)
            .map(|e| s.energy.total_mj / e)
    };
    let label_width = label_width(&designs);
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
    for (design, outcome) in designs.iter().zip(&outcomes) {
        match &outcome.result {
            Ok((stats, _)) => println!(
                "{:<label_width$}  {:>12}  {:>8}  {:>7}  {:>11.3}  {:>9.3}  {:>23}  {:>8.2}",
                design.label,
                stats.cycles,
                speedup(stats).map_or_else(|| "-".into(), |s| format!("{s:.2}")),
                energy(stats).map_or_else(|| "-".into(), |e| format!("{e:.3}")),
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
    println!(
        "speedup = {} cycles / design cycles; energy = design energy / {}'s (below); phases: \
         initial / treelet-stationary / ray-stationary share of traversal-phase cycles",
        designs[reference].label, designs[reference].label
    );
    let energy_rows: Vec<Option<(&str, &EnergyReport)>> = designs
        .iter()
        .zip(&outcomes)
        .map(|(d, o)| {
            o.result
                .as_ref()
                .ok()
                .map(|(s, _)| (d.label.as_str(), &s.energy))
        })
        .collect();
    print_energy_comparison(&energy_rows, reference, label_width);

    let perturbed = if args.perturb > 0 {
        perturbed_table(args, &scene, &runs, jobs, reference, &outcomes, label_width)?
    } else {
        Vec::new()
    };

    let ran: Vec<(&Design, &[Vec3])> = designs
        .iter()
        .zip(&outcomes)
        .filter_map(|(d, o)| {
            o.result
                .as_ref()
                .ok()
                .map(|(_, image)| (d, image.as_slice()))
        })
        .collect();
    let mut mismatches = Vec::new();
    if let Some(((first, first_image), rest)) = ran.split_first() {
        for (design, image) in rest {
            if let Some((pixel, count)) = image_difference(first_image, image) {
                let w = settings.width as usize;
                mismatches.push(format!(
                    "{} differs from {} in {count} of {} pixels (first at x={}, y={})",
                    design.label,
                    first.label,
                    settings.pixels(),
                    pixel % w,
                    pixel / w
                ));
            }
        }
    }
    match (ran.len(), mismatches.is_empty()) {
        (0, _) => println!("images: no design produced an image"),
        (1, _) => println!(
            "images: only {} produced an image, nothing to compare",
            ran[0].0.label
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
        let entries: Vec<serde_json::Value> = designs
            .iter()
            .zip(&outcomes)
            .enumerate()
            .map(|(i, (d, o))| match &o.result {
                Ok((stats, _)) => serde_json::json!({
                    "design": d.label,
                    "source": d.source,
                    "speedup": speedup(stats),
                    "energy_ratio": energy(stats),
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
        let doc = serde_json::json!({
            "scene": scene.name,
            "speedup_reference": designs[reference].label,
            "images_identical": ran.len() >= 2 && mismatches.is_empty(),
            "designs": entries,
        });
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

/// One design under perturbation: its cycles and speedups over the unperturbed run and the
/// perturbed ones (JSON `perturbed` of `vtq compare --perturb`).
#[derive(Debug, Clone, serde::Serialize)]
struct Perturbed {
    /// DRAM latency offsets of the runs after the first (cycles).
    offsets: Vec<i64>,
    /// Cycles, unperturbed first.
    cycles: Vec<f64>,
    /// Speedups over the reference design's run with the same offset (empty for the reference
    /// itself).
    speedups: Vec<f64>,
}

/// `vtq compare --perturb`: every design again with the DRAM latency moved by a cycle or two;
/// prints each design's mean and range of cycles and speedups over its runs (design column
/// `label_width` wide, as the main table's) and returns them per design (an error if a
/// perturbed run fails).
fn perturbed_table(
    args: &CompareArgs,
    scene: &Scene,
    runs: &[(&Design, &HwBvh)],
    jobs: usize,
    reference: usize,
    outcomes: &[Outcome],
    label_width: usize,
) -> anyhow::Result<Vec<Perturbed>> {
    let offsets = perturbations(args.perturb);
    if outcomes.iter().any(|o| o.result.is_err()) {
        println!("under perturbation: not run (a design failed above)");
        return Ok(Vec::new());
    }
    let designs: Vec<(Design, &HwBvh)> = offsets
        .iter()
        .flat_map(|&o| runs.iter().map(move |&(d, bvh)| (d, bvh, o)))
        .map(|(d, bvh, o)| {
            let config = perturbed(&d.config, o)
                .map_err(anyhow::Error::msg)
                .with_context(|| format!("design '{}'", d.label))?;
            Ok((
                Design {
                    config,
                    ..d.clone()
                },
                bvh,
            ))
        })
        .collect::<anyhow::Result<_>>()?;
    let all: Vec<(&Design, &HwBvh)> = designs.iter().map(|(d, b)| (d, *b)).collect();
    let bars: Vec<_> = all.iter().map(|_| None).collect();
    let more = simulate_all(scene, &all, jobs, args.threads, &bars);
    let n = runs.len();
    let mut cycles: Vec<Vec<f64>> = vec![Vec::new(); n];
    for (k, o) in outcomes.iter().chain(&more).enumerate() {
        match &o.result {
            Ok((stats, _)) => cycles[k % n].push(stats.cycles as f64),
            Err(e) => bail!(
                "design '{}' failed with the DRAM latency moved by {} cycles: {e}",
                runs[k % n].0.label,
                k.checked_sub(n).map_or(0, |j| offsets[j / n])
            ),
        }
    }
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
    let mut out = Vec::with_capacity(n);
    let mut unresolved = Vec::new();
    for (i, (design, _)) in runs.iter().enumerate() {
        let c = Spread::of(&cycles[i]).expect("every design has its runs");
        let s = if i == reference {
            Vec::new()
        } else {
            speedups(&cycles[reference], &cycles[i])
        };
        let (mean, range) = match Spread::of(&s) {
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
            c.mean,
            format!("{:.0}-{:.0} ({:.1}%)", c.min, c.max, 100.0 * c.relative()),
            mean,
            range
        );
        out.push(Perturbed {
            offsets: offsets.clone(),
            cycles: cycles[i].clone(),
            speedups: s,
        });
    }
    if unresolved.is_empty() {
        println!(
            "every design is faster or slower than {} in every run",
            runs[reference].0.label
        );
    } else {
        println!(
            "not resolved at this frame size: {} is faster than {} in some runs and slower in \
             others (try a larger frame)",
            unresolved.join(", "),
            runs[reference].0.label
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
    let reference = designs
        .iter()
        .position(|d| d.label == BASELINE)
        .unwrap_or(0);
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
