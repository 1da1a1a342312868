//! The paper's figures computed from stored runs: each a chart (SVG and PNG, the paper's
//! published values as dashed reference lines where it gives numbers) and the table of the
//! numbers drawn. Speedups are baseline cycles / design cycles on the same scene; means are
//! geometric for speedups and arithmetic for rates, shares and SIMT efficiencies, over the
//! scenes that are not built-ins (docs/fidelity.md).

use std::path::Path;

use serde_json::Value as Json;

mod locality;
mod phases;
mod speedups;

pub use locality::{figure1, figure11, figure5};
pub use phases::{figure14, figure15};
pub(super) use phases::{phase_split, treelet_order_share};
pub use speedups::{figure10, figure12, figure13, figure16};

use super::{is_builtin, Results};
use crate::estimate::sample::Estimate;
use crate::experiment::plot::{write_bars, BarSeries, Bars, Reference};

/// The baseline GPU's configuration file.
pub(super) const BASELINE: &str = "configs/designs/baseline/config.toml";
/// Treelet prefetching.
pub(super) const PREFETCH: &str = "configs/designs/prefetch/config.toml";
/// The full design (repacking below 22 active rays).
pub(super) const VTQ: &str = "configs/designs/vtq/config.toml";
/// Treelet queues without grouping or repacking (also the permanent treelet-stationary mode of
/// Figure 11).
const NAIVE: &str = "configs/designs/queues-naive/config.toml";
/// Grouping of underpopulated queues, no repacking.
const GROUPING: &str = "configs/designs/queues-grouping/config.toml";
/// Grouping and repacking below 16 active rays.
const REPACK16: &str = "configs/designs/queues-repack16/config.toml";

/// The axis range of a rate drawn as a fraction (SIMT efficiency).
const RATE: (f64, f64) = (0.0, 1.0);
/// The axis range of a rate or share drawn in percent.
const RATE_PERCENT: (f64, f64) = (0.0, 100.0);

/// A table of numbers: a header and rows of cells.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Table {
    /// Column names.
    pub header: Vec<String>,
    /// Rows of cells.
    pub rows: Vec<Vec<String>>,
}

/// One figure of the page.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Short name, the stem of its image files (`fig10`, `fig11-lands`...).
    pub id: String,
    /// Heading.
    pub title: String,
    /// What it shows and what the paper reports.
    pub caption: String,
    /// Image stems relative to the output folder (each has a `.svg` and a `.png`).
    pub images: Vec<String>,
    /// The numbers drawn.
    pub table: Table,
}

/// A number read from statistics by JSON pointer.
pub(super) fn num(stats: &Json, pointer: &str) -> Option<f64> {
    stats.pointer(pointer).and_then(Json::as_f64)
}

/// Geometric mean of the present values (`None` if none is).
fn geo_mean(values: &[Option<f64>]) -> Option<f64> {
    let v: Vec<f64> = values
        .iter()
        .flatten()
        .copied()
        .filter(|x| *x > 0.0)
        .collect();
    (!v.is_empty()).then(|| (v.iter().map(|x| x.ln()).sum::<f64>() / v.len() as f64).exp())
}

/// Arithmetic mean of the present values.
fn mean(values: &[Option<f64>]) -> Option<f64> {
    let v: Vec<f64> = values.iter().flatten().copied().collect();
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// A cell with `decimals` decimals, `-` for a missing value.
pub(super) fn cell(v: Option<f64>, decimals: usize) -> String {
    v.map_or_else(|| "-".to_string(), |x| format!("{x:.decimals$}"))
}

/// A percentage cell with one decimal.
fn pct(v: Option<f64>) -> String {
    v.map_or_else(|| "-".to_string(), |x| format!("{:.1}%", 100.0 * x))
}

/// How a per-scene series is averaged into its "mean" category.
#[derive(Debug, Clone, Copy)]
pub(super) enum Mean {
    /// Geometric (speedups, cycle ratios).
    Geometric,
    /// Arithmetic (rates, shares, efficiencies).
    Arithmetic,
}

/// Per-scene values plus their mean over the scenes that are not built-ins.
pub(super) fn with_mean(scenes: &[&str], values: Vec<Option<f64>>, how: Mean) -> Vec<Option<f64>> {
    let counted: Vec<Option<f64>> = scenes
        .iter()
        .zip(&values)
        .filter(|(s, _)| !is_builtin(s))
        .map(|(_, v)| *v)
        .collect();
    let counted = if counted.is_empty() {
        values.clone()
    } else {
        counted
    };
    let m = match how {
        Mean::Geometric => geo_mean(&counted),
        Mean::Arithmetic => mean(&counted),
    };
    values.into_iter().chain([m]).collect()
}

/// The categories of a per-scene chart: the scenes' names, then the mean.
pub(super) fn categories(names: &[String], how: Mean) -> Vec<String> {
    let name = match how {
        Mean::Geometric => "geo. mean",
        Mean::Arithmetic => "mean",
    };
    names.iter().cloned().chain([name.to_string()]).collect()
}

/// A reference line.
pub(super) fn paper(name: &str, value: f64) -> Reference {
    Reference {
        name: name.to_string(),
        value,
    }
}

/// Appends `series` to `table` as columns named `prefix: <series>` (three decimals), one row
/// per category of `cats` (the table's rows, in the same order).
fn append_columns(table: &mut Table, prefix: &str, cats: &[String], series: &[BarSeries]) {
    let extra = series_table("scene", cats, series, |v| cell(v, 3));
    for h in &extra.header[1..] {
        table.header.push(format!("{prefix}: {h}"));
    }
    for (row, more) in table.rows.iter_mut().zip(&extra.rows) {
        row.extend(more[1..].iter().cloned());
    }
}

/// A table with one row per category and one column per series (an estimate's cell followed
/// by its 95% interval in brackets).
pub(super) fn series_table(
    first: &str,
    cats: &[String],
    series: &[BarSeries],
    fmt: fn(Option<f64>) -> String,
) -> Table {
    Table {
        header: std::iter::once(first.to_string())
            .chain(series.iter().map(|s| s.name.clone()))
            .collect(),
        rows: cats
            .iter()
            .enumerate()
            .map(|(i, c)| {
                std::iter::once(c.clone())
                    .chain(series.iter().map(|s| {
                        let v = fmt(s.values.get(i).copied().flatten());
                        match s.intervals.get(i).copied().flatten() {
                            Some((lo, hi)) => format!("{v} [{}, {}]", fmt(Some(lo)), fmt(Some(hi))),
                            None => v,
                        }
                    }))
                    .collect()
            })
            .collect(),
    }
}

/// Writes a bar chart under `out/figures/<id>` and returns its image stem.
pub(super) fn bars(out: &Path, id: &str, chart: &Bars) -> anyhow::Result<String> {
    let stem = format!("figures/{id}");
    write_bars(&out.join(&stem), chart)?;
    Ok(stem)
}

/// Speedups of `design` over the baseline, per scene (estimates with their intervals from
/// sampled runs).
fn speedups(r: &Results, scenes: &[&str], design: &str, sets: &[&str]) -> Vec<Option<Estimate>> {
    scenes
        .iter()
        .map(|s| r.speedup(s, (BASELINE, &[]), (design, sets)))
        .collect()
}

/// A bar series `name` of estimates `values` scaled by `scale`: their values, and their 95%
/// intervals as error bars.
pub(super) fn estimate_bars(name: &str, values: &[Option<Estimate>], scale: f64) -> BarSeries {
    BarSeries {
        name: name.to_string(),
        values: values.iter().map(|e| e.map(|e| scale * e.value)).collect(),
        intervals: values
            .iter()
            .map(|e| {
                e.and_then(|e| e.interval())
                    .map(|(lo, hi)| (scale * lo, scale * hi))
            })
            .collect(),
    }
}

/// A bar series `name` of per-scene estimates `values` scaled by `scale` ([`estimate_bars`]),
/// with their mean (`how`, over the scenes that are not built-ins) as the last category, which
/// has no error bar.
pub(super) fn estimate_series(
    name: &str,
    scenes: &[&str],
    values: Vec<Option<Estimate>>,
    how: Mean,
    scale: f64,
) -> BarSeries {
    let mut series = estimate_bars(name, &values, scale);
    series.values = with_mean(scenes, series.values, how);
    series.intervals.push(None);
    series
}

/// A statistic of `design` per scene.
fn per_scene(r: &Results, scenes: &[&str], design: &str, pointer: &str) -> Vec<Option<f64>> {
    scenes
        .iter()
        .map(|s| num(&r.stats(s, design, &[])?, pointer))
        .collect()
}

/// Statistic `name` of `design` per scene as estimates (exact from full-detail runs).
fn per_scene_estimates(
    r: &Results,
    scenes: &[&str],
    design: &str,
    name: &str,
) -> Vec<Option<Estimate>> {
    scenes
        .iter()
        .map(|s| r.estimate(s, design, &[], name))
        .collect()
}

/// A bar chart `id` of the speedups over the baseline of `designs` (legend name, configuration
/// file) per scene with their geometric mean, and its table.
pub(super) fn speedup_bars(
    r: &Results,
    out: &Path,
    id: &str,
    title: &str,
    designs: &[(&str, &str)],
    references: Vec<Reference>,
) -> anyhow::Result<(String, Table)> {
    let scenes = r.scenes();
    let how = Mean::Geometric;
    let cats = categories(&r.labels(), how);
    let series: Vec<BarSeries> = designs
        .iter()
        .map(|(name, cfg)| estimate_series(name, &scenes, speedups(r, &scenes, cfg, &[]), how, 1.0))
        .collect();
    let img = bars(
        out,
        id,
        &Bars {
            title: title.into(),
            y_label: "speedup (baseline cycles / cycles)".into(),
            categories: cats.clone(),
            series: series.clone(),
            references,
            stacked: false,
            y_range: None,
        },
    )?;
    Ok((img, series_table("scene", &cats, &series, |v| cell(v, 2))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn means_leave_built_ins_out_and_skip_missing_values() {
        let scenes = ["wknd", "ship", "bunny"];
        let v = with_mean(
            &scenes,
            vec![Some(100.0), Some(1.0), Some(4.0)],
            Mean::Geometric,
        );
        assert_eq!(v[3], Some(2.0));
        let v = with_mean(&scenes, vec![Some(9.0), None, Some(4.0)], Mean::Arithmetic);
        assert_eq!(v[3], Some(4.0));
        // Only built-ins: they are the mean.
        let v = with_mean(
            &["wknd", "cornell"],
            vec![Some(1.0), Some(3.0)],
            Mean::Arithmetic,
        );
        assert_eq!(v[2], Some(2.0));
        assert_eq!(cell(None, 2), "-");
    }
}
