//! `vtq accuracy`: run time against error. For each scene and design, full detail and the
//! sampled tier at several settings (docs/accuracy.md); prints the rows and the mean and worst
//! case per setting, writes them as CSV and JSON, and plots run time against
//! error (SVG and PNG).

use std::path::PathBuf;

use anyhow::{bail, Context};
use clap::Args;

use crate::cli::cmd::options::{build_bvh, load_scene, parse_threads, CacheArgs};
use crate::cli::output::{check_dir, write_or_keep, Failures};
use crate::experiment::accuracy::{
    benchmark, chart, csv, summarize, Design, Plan, Row, Summary, Tier,
};
use crate::experiment::perturb::perturbations;
use crate::experiment::plot::write_scatter;
use crate::model::designs;

/// Options of `vtq accuracy`.
#[derive(Debug, Args)]
pub struct AccuracyArgs {
    /// Scenes to benchmark (repeatable): built-in names, shared-scene folders or paths.
    #[arg(long, required = true)]
    pub scene: Vec<String>,
    /// Designs (as `vtq compare --designs`); the first is the speedup reference.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "baseline,prefetch,vtq",
        value_name = "DESIGN,..."
    )]
    pub designs: Vec<String>,
    /// Sampled-tier settings to measure: named points (`default`, `fast`; `vtq sim --help`
    /// lists them) or `FRACTIONxREPLICATES` with the `[sample]` section's other settings.
    #[arg(long, value_delimiter = ',', default_value = "default,fast")]
    pub settings: Vec<String>,
    /// Override one configuration key in every design (repeatable), e.g. `--set width=64`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Threads for full detail's SMs and the sampled tier's replicates (the same for both, so
    /// the time ratios compare like with like) [default: the available cores].
    #[arg(long, value_parser = parse_threads)]
    pub threads: Option<usize>,
    /// Also run full detail N more times with the DRAM latency moved by +1, -1, +2, -2, ...
    /// cycles, and report how far the reference itself moves (its spread) and each estimate's
    /// error against the mean of those runs (docs/accuracy.md, "How far the reference moves").
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub perturb: usize,
    /// Directory for `accuracy.csv`, `accuracy.json` and the plot `accuracy.{svg,png}`.
    #[arg(long, default_value = "accuracy")]
    pub out: PathBuf,
    /// The BVH build cache.
    #[command(flatten)]
    pub cache: CacheArgs,
}

/// Percent with one decimal, or `-`.
fn pct(v: Option<f64>) -> String {
    v.map_or_else(|| "-".into(), |v| format!("{:+.2}%", 100.0 * v))
}

/// `yes`/`no`, or `-`.
fn yes(v: Option<bool>) -> &'static str {
    match v {
        Some(true) => "yes",
        Some(false) => "NO",
        None => "-",
    }
}

/// Prints one scene's rows (with perturbations, also the reference's spread and the errors
/// against the mean of its runs).
fn print_rows(rows: &[Row]) {
    let perturbed = rows.iter().any(|r| r.reference.is_some());
    let extra = if perturbed {
        format!(" {:>8} {:>9} {:>9}", "spread", "err/mean", "spd/mean")
    } else {
        String::new()
    };
    println!(
        "{:<8} {:<10} {:<16} {:>8} {:>8} {:>14} {:>9} {:>4} {:>9} {:>4}{extra}",
        "scene", "design", "tier", "wall s", "x faster", "cycles", "err", "in95", "spd err", "in95"
    );
    for r in rows {
        let extra = r.reference.as_ref().map_or_else(String::new, |x| {
            format!(
                " {:>7.1}% {:>9} {:>9}",
                100.0 * x.spread,
                pct(Some(x.cycles_error)),
                pct(x.speedup_error)
            )
        });
        println!(
            "{:<8} {:<10} {:<16} {:>8.2} {:>8.1} {:>14.0} {:>9} {:>4} {:>9} {:>4}{extra}",
            r.scene,
            r.design,
            r.tier.name(),
            r.wall,
            r.time_speedup,
            r.cycles,
            pct(Some(r.cycles_error)),
            yes(r.cycles_covered),
            pct(r.speedup_error),
            yes(r.speedup_covered)
        );
    }
}

/// Run `vtq accuracy`.
pub fn run(args: &AccuracyArgs) -> anyhow::Result<()> {
    check_dir(&args.out)?;
    let designs = resolve_designs(args)?;
    let first = &designs[0];
    let threads = args
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let offsets = perturbations(args.perturb);
    let mut rows = Vec::new();
    for name in &args.scene {
        let scene = load_scene(name)?;
        let bvh = build_bvh(&scene, &first.config.bvh_params(), &args.cache)?;
        let plan = Plan {
            scene: &scene,
            bvh: &bvh,
            designs: &designs,
            settings: &args.settings,
            threads,
            perturbations: &offsets,
        };
        let scene_rows =
            benchmark(&plan).with_context(|| format!("benchmarking scene '{}'", scene.name))?;
        print_rows(&scene_rows);
        rows.extend(scene_rows);
    }
    let summary = summarize(&rows);
    print_summary(&summary, args.perturb, &offsets, threads);
    // The results first; a chart that cannot be drawn is reported without losing them, and
    // one file that cannot be written is kept in a fallback file.
    let mut failures = Failures::default();
    let mut wrote = Vec::new();
    let csv_path = args.out.join("accuracy.csv");
    let csv_text = csv(&rows);
    if failures.note(write_or_keep(&csv_path, |p| std::fs::write(p, &csv_text))) {
        wrote.push(csv_path.display().to_string());
    }
    let json_path = args.out.join("accuracy.json");
    let doc = serde_json::json!({ "threads": threads, "rows": rows, "summary": summary });
    let json_text = serde_json::to_string_pretty(&doc)? + "\n";
    if failures.note(write_or_keep(&json_path, |p| std::fs::write(p, &json_text))) {
        wrote.push(json_path.display().to_string());
    }
    match write_scatter(&args.out.join("accuracy"), &chart(&rows)) {
        Ok((svg, png)) => wrote.extend([svg.display().to_string(), png.display().to_string()]),
        Err(e) => {
            failures.note(Err(anyhow::Error::new(e).context("the plot was not drawn")));
        }
    }
    if !wrote.is_empty() {
        println!("wrote {}", wrote.join(", "));
    }
    failures.finish()
}

/// The designs of `--designs` with `--set`, checked: one BVH and workload for all, and every
/// `--settings` point valid for each.
fn resolve_designs(args: &AccuracyArgs) -> anyhow::Result<Vec<Design>> {
    let designs: Vec<Design> = args
        .designs
        .iter()
        .map(|spec| {
            designs::resolve(spec, &args.set).map(|d| Design {
                label: d.label,
                config: d.config,
            })
        })
        .collect::<anyhow::Result<_>>()?;
    let Some(first) = designs.first() else {
        bail!("--designs is empty");
    };
    for d in &designs {
        if d.config.bvh_params() != first.config.bvh_params()
            || d.config.render_settings() != first.config.render_settings()
        {
            bail!(
                "design '{}' has another BVH or workload than '{}': the benchmark compares \
                 designs on one BVH and workload",
                d.label,
                first.label
            );
        }
        for spec in &args.settings {
            let mut s = d.config.sample.clone();
            s.apply_spec(spec).map_err(anyhow::Error::msg)?;
            let mut cfg = d.config.clone();
            cfg.sample = s;
            cfg.sample
                .validate(&cfg)
                .with_context(|| format!("setting `{spec}` for design '{}'", d.label))?;
        }
    }
    Ok(designs)
}

/// Prints the summary table per tier, and with `perturb` runs the errors against the mean of
/// full detail's perturbed runs (DRAM latency `offsets`).
fn print_summary(summary: &[Summary], perturb: usize, offsets: &[i64], threads: usize) {
    println!();
    println!(
        "{:<16} {:>5} {:>10} {:>10} {:>10} {:>12} {:>12} {:>12} {:>12} {:>9}",
        "tier",
        "rows",
        "x faster",
        "min x",
        "x shared",
        "cyc err avg",
        "cyc err max",
        "spd err avg",
        "spd err max",
        "in 95%"
    );
    for s in summary.iter().filter(|s| s.tier != Tier::Full.name()) {
        println!(
            "{:<16} {:>5} {:>10.1} {:>10.1} {:>10.1} {:>11.2}% {:>11.2}% {:>11.2}% {:>11.2}% {:>9}",
            s.tier,
            s.rows,
            s.mean_time_speedup,
            s.min_time_speedup,
            s.mean_time_speedup_shared,
            100.0 * s.mean_cycles_error,
            100.0 * s.worst_cycles_error,
            100.0 * s.mean_speedup_error,
            100.0 * s.worst_speedup_error,
            s.coverage
                .map_or_else(|| "-".into(), |c| format!("{:.0}%", 100.0 * c))
        );
    }
    if perturb > 0 {
        println!();
        println!(
            "against the mean of full detail's {} runs (DRAM latency {:+?} cycles):",
            perturb + 1,
            offsets
        );
        println!(
            "{:<16} {:>12} {:>12} {:>12} {:>12} {:>9}",
            "tier", "cyc err avg", "cyc err max", "spd err avg", "spd err max", "in 95%"
        );
        for s in summary {
            if let Some([mc, wc, ms, ws]) = s.against_mean {
                println!(
                    "{:<16} {:>11.2}% {:>11.2}% {:>11.2}% {:>11.2}% {:>9}",
                    s.tier,
                    100.0 * mc,
                    100.0 * wc,
                    100.0 * ms,
                    100.0 * ws,
                    s.coverage_of_mean
                        .map_or_else(|| "-".into(), |c| format!("{:.0}%", 100.0 * c))
                );
            }
        }
        println!(
            "(the full row: the unperturbed run against that mean, the reference's own \
             sensitivity)"
        );
    }
    println!(
        "errors are relative to full detail on the same machine and threads ({threads}); \
         x faster = full detail's wall time / the tier's; x shared = the same with the \
         functional profile shared by the scene's designs, as `vtq compare --sample` runs them"
    );
}
