//! `vtq energy`: the energy model (docs/energy.md) evaluated on stored statistics, with no
//! rerun: every run under each coefficient set, relative to the first run (the baseline), and
//! with `--vary` each coefficient halved and doubled. Also the energy table `vtq compare`
//! prints.

use std::path::PathBuf;

use anyhow::{bail, Context};
use clap::Args;

use crate::model::config::{CoefficientSet, SimConfig};
use crate::model::energy::{stats_config, Coefficients, EnergyReport, Relative, Term};

/// Options of `vtq energy`.
#[derive(Debug, Args)]
pub struct EnergyArgs {
    /// Statistics JSON files: `vtq sim --out` files, `vtq compare --json` files (every design
    /// in them) or sweep result files (`DIR/runs/*.json`). A compare file's designs are
    /// reported together, relative to its first (the baseline where it was compared); the other
    /// files together, relative to the first of them.
    #[arg(required = true, value_name = "STATS.json")]
    pub stats: Vec<PathBuf>,
    /// A coefficient set (`accelwattch-ptx`, `accelwattch-sass`, `physical`) or `all`.
    #[arg(long, default_value = "all", value_name = "NAME|all")]
    pub coefficients: String,
    /// Also evaluate with each coefficient halved and doubled, printing each run's energy
    /// relative to the first run's under each variation.
    #[arg(long)]
    pub vary: bool,
}

/// One run read from a file: its label, statistics and configuration.
struct Run {
    /// File stem, or the design's label in a compare file.
    label: String,
    /// The statistics JSON.
    stats: serde_json::Value,
    /// The configuration the statistics recorded.
    cfg: SimConfig,
}

/// The runs of one statistics file (one, or every design of a `vtq compare --json` file), and
/// whether they are a compare file's (a group of their own).
fn read_runs(path: &PathBuf) -> anyhow::Result<(Vec<Run>, bool)> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let json: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{} is not JSON", path.display()))?;
    let stem = path.file_stem().map_or_else(
        || path.display().to_string(),
        |s| s.to_string_lossy().into(),
    );
    let mut found: Vec<(String, serde_json::Value)> = Vec::new();
    let is_compare = json.get("designs").is_some();
    if let Some(designs) = json.get("designs").and_then(|d| d.as_array()) {
        for d in designs {
            let label = d.get("design").and_then(|l| l.as_str()).unwrap_or("?");
            if let Some(stats) = d.get("stats") {
                found.push((label.to_string(), stats.clone()));
            }
        }
    } else if let Some(stats) = json.pointer("/result/stats") {
        found.push((stem, stats.clone()));
    } else if json.get("cycles").is_some() {
        found.push((stem, json));
    }
    if found.is_empty() {
        bail!(
            "{}: no statistics (expected a `vtq sim --out` file, a `vtq compare --json` file \
             or a sweep result file)",
            path.display()
        );
    }
    let runs = found
        .into_iter()
        .map(|(label, stats)| {
            let cfg = stats_config(&stats)
                .map_err(anyhow::Error::msg)
                .with_context(|| format!("{} ({label})", path.display()))?;
            Ok(Run { label, stats, cfg })
        })
        .collect::<anyhow::Result<Vec<Run>>>()?;
    Ok((runs, is_compare))
}

/// Run `vtq energy`.
pub fn run(args: &EnergyArgs) -> anyhow::Result<()> {
    let sets: Vec<CoefficientSet> = if args.coefficients == "all" {
        CoefficientSet::ALL.to_vec()
    } else {
        vec![CoefficientSet::from_name(&args.coefficients).map_err(anyhow::Error::msg)?]
    };
    // Groups of runs reported together: each compare file's, and the other files'.
    let mut groups: Vec<(String, Vec<Run>)> = Vec::new();
    let mut singles: Vec<Run> = Vec::new();
    for path in &args.stats {
        match read_runs(path)? {
            (runs, true) => groups.push((path.display().to_string(), runs)),
            (runs, false) => singles.extend(runs),
        }
    }
    if !singles.is_empty() {
        groups.insert(0, (String::new(), singles));
    }
    let width = groups
        .iter()
        .flat_map(|(_, runs)| runs.iter().map(|r| r.label.len()))
        .max()
        .unwrap_or(0)
        .max(6);
    for set in sets {
        for (name, runs) in &groups {
            let reports = evaluate_all(runs, set, None)?;
            let from = if name.is_empty() {
                String::new()
            } else {
                format!(", {name}")
            };
            println!("coefficients {set}{from} (docs/energy.md):");
            let rows: Vec<(&str, &EnergyReport)> = runs
                .iter()
                .map(|r| r.label.as_str())
                .zip(reports.iter())
                .collect();
            print_table(&rows, width);
            print_components(&rows, width);
            if args.vary {
                print_variations(runs, set, width)?;
            }
            println!();
        }
    }
    Ok(())
}

/// Every run's report under `set`, with `vary` (a term and its factor) applied.
fn evaluate_all(
    runs: &[Run],
    set: CoefficientSet,
    vary: Option<(Term, f64)>,
) -> anyhow::Result<Vec<EnergyReport>> {
    runs.iter()
        .map(|r| {
            let mut c = Coefficients::of(set, &r.cfg);
            if let Some((term, factor)) = vary {
                c = c.scaled(term, factor);
            }
            EnergyReport::of_stats_with(&r.stats, &r.cfg, &c)
                .map_err(anyhow::Error::msg)
                .with_context(|| r.label.clone())
        })
        .collect()
}

/// Prints the energy table of `vtq compare`: the designs that ran (`None`: failed), the one at
/// `reference` first so the ratios divide its energy.
pub fn print_comparison(rows: &[Option<(&str, &EnergyReport)>], reference: usize, width: usize) {
    let order = std::iter::once(reference).chain((0..rows.len()).filter(|&i| i != reference));
    let ran: Vec<(&str, &EnergyReport)> = order
        .filter_map(|i| rows.get(i).copied().flatten())
        .collect();
    if let Some((_, first)) = ran.first() {
        println!(
            "energy, coefficients {} (docs/energy.md):",
            first.coefficients
        );
        print_table(&ran, width);
    }
}

/// Prints the energy table of `rows` (label, report), ratios against the first row.
pub fn print_table(rows: &[(&str, &EnergyReport)], width: usize) {
    println!(
        "{:<width$}  {:>10}  {:>7}  {:>8}  {:>7}  {:>6}  {:>6}  {:>6}  {:>8}  {:>9}",
        "design", "mJ/frame", "W", "nJ/ray", "E/base", "f", "T", "D", "fT+(1-f)D", "virt. %"
    );
    let Some((_, reference)) = rows.first() else {
        return;
    };
    for (label, r) in rows {
        let rel = Relative::of(r, reference);
        println!(
            "{:<width$}  {:>10.4}  {:>7.2}  {:>8.2}  {:>7.3}  {:>6.3}  {:>6.3}  {:>6.3}  {:>8.3}  \
             {:>9.1}",
            label,
            r.total_mj,
            r.average_power_w,
            r.nj_per_ray,
            rel.energy,
            rel.time_share,
            rel.time,
            rel.events,
            rel.identity,
            100.0 * r.virtualization_share
        );
    }
    println!(
        "E/base = energy / {}'s; f = {}'s time-proportional share; T = time ratio; D = event \
         energy ratio; virt. % = CTA-state traffic's share of the design's energy",
        rows[0].0, rows[0].0
    );
}

/// Prints each run's components as fractions of the first run's energy (Figure 17's stacks).
fn print_components(rows: &[(&str, &EnergyReport)], width: usize) {
    let Some((first, reference)) = rows.first() else {
        return;
    };
    let names = reference.components.named().map(|(n, _)| n);
    let mut header = format!("{:<width$}", "design");
    for n in names {
        header += &format!("  {n:>15}");
    }
    println!("{header}");
    for (label, r) in rows {
        let mut line = format!("{label:<width$}");
        for (_, v) in r.components.named() {
            let share = if reference.total_mj > 0.0 {
                v / reference.total_mj
            } else {
                0.0
            };
            line += &format!("  {share:>15.4}");
        }
        println!("{line}");
    }
    println!("components as fractions of {first}'s energy");
}

/// Prints, for each coefficient halved and doubled, every run's energy relative to the first.
fn print_variations(runs: &[Run], set: CoefficientSet, width: usize) -> anyhow::Result<()> {
    let base = evaluate_all(runs, set, None)?;
    let ratios = |reports: &[EnergyReport]| -> Vec<f64> {
        reports
            .iter()
            .map(|r| Relative::of(r, &reports[0]).energy)
            .collect()
    };
    println!(
        "sensitivity: E/{} with one coefficient x0.5 and x2",
        runs[0].label
    );
    let mut header = format!("{:<20}", "coefficient");
    for r in runs {
        header += &format!("  {:>w$}", r.label, w = width.max(15));
    }
    println!("{header}");
    let cell = |a: f64, b: f64| format!("{a:.3} / {b:.3}");
    let mut line = format!("{:<20}", "(as given)");
    for e in ratios(&base) {
        line += &format!("  {:>w$}", format!("{e:.3}"), w = width.max(15));
    }
    println!("{line}");
    for term in Term::ALL {
        if runs
            .iter()
            .all(|r| Coefficients::of(set, &r.cfg).get(term) == 0.0)
        {
            continue;
        }
        let half = ratios(&evaluate_all(runs, set, Some((term, 0.5)))?);
        let double = ratios(&evaluate_all(runs, set, Some((term, 2.0)))?);
        let mut line = format!("{:<20}", term.name());
        for (h, d) in half.iter().zip(&double) {
            line += &format!("  {:>w$}", cell(*h, *d), w = width.max(15));
        }
        println!("{line}");
    }
    println!("(cells: x0.5 / x2; coefficients that are 0 in this set are left out)");
    Ok(())
}
