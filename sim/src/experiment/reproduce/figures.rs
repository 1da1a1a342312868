//! The paper's figures computed from stored runs: each a chart (SVG and PNG, the paper's
//! published values as dashed reference lines where it gives numbers) and the table of the
//! numbers drawn. Speedups are baseline cycles / design cycles on the same scene; means are
//! geometric for speedups and arithmetic for rates, shares and SIMT efficiencies, over the
//! scenes that are not built-ins (docs/fidelity.md).

use std::path::Path;

use serde_json::Value as Json;

use super::{file_safe, is_builtin, Results};
use crate::estimate::figure5::Figure5Row;
use crate::estimate::sample::stored::stored_estimate;
use crate::estimate::sample::Estimate;
use crate::experiment::plot::{
    write_bars, write_lines, write_scatter, BarSeries, Bars, Line, Lines, Point, Reference,
    Scatter, Series,
};

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

/// Figure 1: the baseline's BVH L1 miss rate and RT-unit SIMT efficiency per scene.
pub fn figure1(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let scenes = r.scenes();
    let how = Mean::Arithmetic;
    let cats = categories(&r.labels(), how);
    let miss = estimate_series(
        "measured by vtq",
        &scenes,
        per_scene_estimates(r, &scenes, BASELINE, "bvh_l1_miss_rate"),
        how,
        100.0,
    );
    let simt = estimate_series(
        "measured by vtq",
        &scenes,
        per_scene_estimates(r, &scenes, BASELINE, "simt_efficiency"),
        how,
        1.0,
    );
    let a = bars(
        out,
        "fig01a",
        &Bars {
            title: "Figure 1a: baseline BVH L1 miss rate".into(),
            y_label: "BVH L1 miss rate (%)".into(),
            categories: cats.clone(),
            series: vec![miss.clone()],
            references: vec![
                paper("paper: mean 58%", 58.0),
                paper("paper: max 70%", 70.0),
            ],
            stacked: false,
            y_range: Some(RATE_PERCENT),
        },
    )?;
    let b = bars(
        out,
        "fig01b",
        &Bars {
            title: "Figure 1b: baseline RT-unit SIMT efficiency".into(),
            y_label: "SIMT efficiency".into(),
            categories: cats.clone(),
            series: vec![simt.clone()],
            references: vec![paper("paper: mean 0.37", 0.37)],
            stacked: false,
            y_range: Some(RATE),
        },
    )?;
    let mut table = series_table("scene", &cats, &[miss], |v| {
        v.map_or_else(|| "-".to_string(), |x| format!("{x:.1}%"))
    });
    table.header[1] = "BVH L1 miss rate".into();
    append_columns(&mut table, "SIMT efficiency", &cats, &[simt]);
    table.header[2] = "SIMT efficiency".into();
    Ok(Figure {
        id: "fig01".into(),
        title: "Figure 1: the baseline's BVH L1 miss rate and SIMT efficiency".into(),
        caption: "BVH accesses of the RT unit missing in the L1, and the RT unit's SIMT \
                  efficiency (active lanes / warp size), in the baseline GPU. The paper \
                  (Vulkan-Sim, all of LumiBench): 58% mean and 70% max miss rate, 0.37 SIMT \
                  efficiency."
            .into(),
        images: vec![a, b],
        table,
    })
}

/// Figure 5: the paper's analytical model of treelet reuse (`vtq figure5`): the potential
/// speedup of treelets against the number of concurrent rays, per scene, from `rows`.
pub fn figure5(rows: &[(String, Vec<Figure5Row>)], out: &Path) -> anyhow::Result<Figure> {
    let series = rows
        .iter()
        .map(|(scene, rows)| Series {
            name: scene.clone(),
            points: rows
                .iter()
                .map(|r| Point {
                    x: r.concurrent_rays as f64,
                    y: r.speedup,
                    label: scene.clone(),
                    interval: None,
                })
                .collect(),
        })
        .collect();
    let stem = "figures/fig05".to_string();
    write_scatter(
        &out.join(&stem),
        &Scatter {
            title: "Figure 5: potential speedup of treelets against concurrent rays (model)".into(),
            x_label: "concurrent rays".into(),
            y_label: "potential speedup (model)".into(),
            x_log: true,
            y_log: true,
            joined: true,
            series,
        },
    )?;
    let sizes: Vec<u64> = rows
        .first()
        .map(|(_, r)| r.iter().map(|x| x.concurrent_rays).collect())
        .unwrap_or_default();
    let mut header = vec!["scene".to_string()];
    header.extend(sizes.iter().map(|c| format!("{c} rays")));
    Ok(Figure {
        id: "fig05".into(),
        title: "Figure 5: treelet reuse against concurrent rays (analytical model)".into(),
        caption: "The paper's Figure 5 model computed from vtq's functional node-fetch traces \
                  (`vtq figure5`, docs/fidelity.md): every node fetch a miss of equal latency, \
                  the baseline costing every ray's fetches, treelet queues processing rays in \
                  batches of the given size and fetching each treelet a batch touches once. \
                  The paper: 3 to 4x for most scenes at high concurrency, WKND and SHIP far \
                  more."
            .into(),
        images: vec![stem],
        table: Table {
            header,
            rows: rows
                .iter()
                .map(|(scene, rows)| {
                    std::iter::once(scene.clone())
                        .chain(rows.iter().map(|r| format!("{:.2}", r.speedup)))
                        .collect()
                })
                .collect(),
        },
    })
}

/// Figure 10: speedups of treelet prefetching and VTQ over the baseline.
pub fn figure10(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let (img, table) = speedup_bars(
        r,
        out,
        "fig10",
        "Figure 10: speedup over the baseline",
        &[("treelet prefetching", PREFETCH), ("VTQ", VTQ)],
        vec![
            paper("baseline", 1.0),
            paper("paper: VTQ mean 1.95", 1.95),
            paper("paper: VTQ max 2.55", 2.55),
            paper("paper: prefetching 1.95 / 1.43", 1.95 / 1.43),
        ],
    )?;
    Ok(Figure {
        id: "fig10".into(),
        title: "Figure 10: VTQ and treelet prefetching against the baseline".into(),
        caption: "Speedup of treelet prefetching (MICRO 2023) and of Virtualized Treelet Queues \
                  (4096 rays per SM, grouping, repacking below 22) over the baseline GPU. The \
                  paper: VTQ +95% on average and up to 2.55x, every scene faster, 43% faster \
                  than prefetching (so prefetching about 1.36x)."
            .into(),
        images: vec![img],
        table,
    })
}

/// Figure 11: the BVH L1 miss rate over the run (tenths), baseline against the permanent
/// treelet-stationary mode, one chart per scene.
pub fn figure11(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let scenes = r.scenes();
    let mut images = Vec::new();
    let mut rows = Vec::new();
    let deciles = |s: &Option<Json>, key: &str| -> Option<Vec<f64>> {
        let v = s.as_ref()?.pointer(key)?.as_array()?;
        Some(v.iter().filter_map(Json::as_f64).collect())
    };
    for (scene, name) in scenes.iter().zip(r.labels()) {
        let base = r.stats(scene, BASELINE, &[]);
        let ts = r.stats(scene, NAIVE, &[]);
        let lines: Vec<(String, Option<Vec<f64>>)> = vec![
            (
                "baseline".into(),
                deciles(&base, "/bvh_l1_miss_rate_deciles"),
            ),
            (
                "treelet-stationary".into(),
                deciles(&ts, "/bvh_l1_miss_rate_deciles"),
            ),
            (
                "treelet-stationary, preloads counted".into(),
                deciles(&ts, "/bvh_l1_miss_rate_deciles_with_prefetches"),
            ),
        ];
        for (run, values) in &lines {
            let mut row = vec![name.clone(), run.clone()];
            row.extend((0..10).map(|d| pct(values.as_ref().and_then(|v| v.get(d).copied()))));
            rows.push(row);
        }
        let chart = Lines {
            title: format!("Figure 11: BVH L1 miss rate over the run, {name}"),
            x_label: "progress through the run (% of cycles)".into(),
            y_label: "BVH L1 miss rate (%)".into(),
            lines: lines
                .into_iter()
                .filter_map(|(run, v)| {
                    Some(Line {
                        name: run,
                        points: v?
                            .iter()
                            .enumerate()
                            .map(|(d, m)| (10.0 * d as f64 + 5.0, 100.0 * m))
                            .collect(),
                    })
                })
                .collect(),
            references: vec![
                paper("paper (LANDS): treelet-stationary early 9%", 9.0),
                paper("paper: treelet-stationary late 75-80%", 77.5),
                paper("paper: baseline plateau 60%", 60.0),
            ],
            x_range: Some(RATE_PERCENT),
            y_range: Some(RATE_PERCENT),
        };
        let stem = format!("figures/fig11-{}", file_safe(&name));
        write_lines(&out.join(&stem), &chart)?;
        images.push(stem);
    }
    let mut header = vec!["scene".to_string(), "run".to_string()];
    header.extend((1..=10).map(|d| format!("d{d}")));
    Ok(Figure {
        id: "fig11".into(),
        title: "Figure 11: BVH L1 miss rate over time, baseline against treelet-stationary mode"
            .into(),
        caption: "The BVH L1 miss rate in each tenth of the run: the baseline, and treelet queues \
                  kept in treelet-stationary mode (no grouping, no repacking), counting demand \
                  loads only, and counting the treelet preloads as accesses too. The paper \
                  (LANDS): treelet-stationary as low as 9% early, plateauing at 75-80% late; \
                  the baseline plateaus at about 60%."
            .into(),
        images,
        table: Table { header, rows },
    })
}

/// Figure 12: naive treelet queues and grouping of underpopulated queues.
pub fn figure12(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let (img, table) = speedup_bars(
        r,
        out,
        "fig12",
        "Figure 12: grouping underpopulated treelet queues",
        &[
            ("naive treelet queues", NAIVE),
            ("grouping underpopulated queues", GROUPING),
        ],
        vec![
            paper("baseline", 1.0),
            paper("paper: grouping 0.95", 0.95),
            paper("paper: naive 0.95 / 8", 0.95 / 8.0),
        ],
    )?;
    Ok(Figure {
        id: "fig12".into(),
        title: "Figure 12: grouping underpopulated treelet queues".into(),
        caption: "Speedup over the baseline of naive treelet queues and of grouping \
                  underpopulated queues into ray-stationary warps (threshold 128 rays, no \
                  repacking). The paper: grouping is 8x faster than naive and still 5% slower \
                  than the baseline."
            .into(),
        images: vec![img],
        table,
    })
}

/// Figure 13: warp repacking's speedups (a) and SIMT efficiencies (b).
pub fn figure13(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let scenes = r.scenes();
    let designs = [
        ("no repacking", GROUPING),
        ("repack below 16", REPACK16),
        ("repack below 22 (VTQ)", VTQ),
    ];
    let (a, mut table) = speedup_bars(
        r,
        out,
        "fig13a",
        "Figure 13a: warp repacking, speedup",
        &designs,
        vec![
            paper("paper: no repacking 0.95", 0.95),
            paper("paper: below 16 1.84", 1.84),
            paper("paper: below 22 1.95", 1.95),
        ],
    )?;
    let m = Mean::Arithmetic;
    let cats_m = categories(&r.labels(), m);
    let simt: Vec<BarSeries> = std::iter::once(("baseline", BASELINE))
        .chain(designs)
        .map(|(name, cfg)| {
            let values = per_scene_estimates(r, &scenes, cfg, "simt_efficiency");
            estimate_series(name, &scenes, values, m, 1.0)
        })
        .collect();
    let b = bars(
        out,
        "fig13b",
        &Bars {
            title: "Figure 13b: warp repacking, SIMT efficiency".into(),
            y_label: "RT-unit SIMT efficiency".into(),
            categories: cats_m.clone(),
            series: simt.clone(),
            references: vec![
                paper("paper: baseline 0.37", 0.37),
                paper("paper: no repacking 0.33", 0.33),
                paper("paper: below 22 0.82", 0.82),
            ],
            stacked: false,
            y_range: Some(RATE),
        },
    )?;
    append_columns(&mut table, "SIMT", &cats_m, &simt);
    // Beside vtq's per-cycle measure, the per-warp mean the paper's simulator lineage reports
    // (docs/fidelity.md, "SIMT efficiency averaged per warp").
    let per_warp: Vec<BarSeries> = std::iter::once(("baseline", BASELINE))
        .chain(designs)
        .map(|(name, cfg)| BarSeries {
            intervals: Vec::new(),
            name: name.to_string(),
            values: with_mean(
                &scenes,
                per_scene(r, &scenes, cfg, "/simt_efficiency_per_warp"),
                m,
            ),
        })
        .collect();
    append_columns(&mut table, "SIMT per warp", &cats_m, &per_warp);
    // How much of the final phase a warp below the threshold waited with no ray to refill it
    // (docs/fidelity.md, "Repacks withheld for want of rays").
    let starved: Vec<BarSeries> = designs[1..]
        .iter()
        .map(|&(name, cfg)| BarSeries {
            intervals: Vec::new(),
            name: name.to_string(),
            values: with_mean(
                &scenes,
                scenes
                    .iter()
                    .map(|s| starved_share(&r.stats(s, cfg, &[])?))
                    .collect(),
                m,
            ),
        })
        .collect();
    append_columns(&mut table, "pool empty", &cats_m, &starved);
    Ok(Figure {
        id: "fig13".into(),
        title: "Figure 13: warp repacking".into(),
        caption: "Speedup over the baseline (a) and RT-unit SIMT efficiency (b) of grouped \
                  treelet queues without repacking and repacking warps with fewer than 16 or 22 \
                  active rays (speedups: geometric means; SIMT: arithmetic). The paper: 0.95x, \
                  1.84x, 1.95x; SIMT 0.37 (baseline), 0.33 without repacking, 0.82 at 22. The \
                  table also gives SIMT efficiency averaged per RT-unit warp, as the paper's \
                  simulator lineage averages it, and the share of the final ray-stationary \
                  phase in which a warp below the threshold waited with the queues empty \
                  (`queues.repack_starved_cycles` per SM over the phase's cycles; \
                  docs/fidelity.md)."
            .into(),
        images: vec![a, b],
        table,
    })
}

/// The share of the final ray-stationary phase in which a repack was withheld for want of rays:
/// `queues.repack_starved_cycles` (summed over the SMs) per SM over the phase's cycles (averaged
/// over the SMs); `None` without a final phase.
fn starved_share(stats: &Json) -> Option<f64> {
    let sms = stats.pointer("/sm_finish_cycles")?.as_array()?.len() as f64;
    let phase = num(stats, "/phases/ray_stationary/cycles")?;
    let starved = num(stats, "/queues/repack_starved_cycles")?;
    (phase > 0.0 && sms > 0.0).then(|| starved / sms / phase)
}

/// The three phases' (initial, treelet-stationary, final ray-stationary) shares of `field`
/// (`cycles` or `intersection_tests`) in one run's statistics.
pub(super) fn phase_split(stats: &Json, field: &str) -> Option<[f64; 3]> {
    let mut values = [0.0; 3];
    for (v, p) in values
        .iter_mut()
        .zip(["initial", "treelet_stationary", "ray_stationary"])
    {
        // A sampled run estimates the shares of cycles, not the phases' counts.
        let estimated = (field == "cycles")
            .then(|| stored_estimate(stats, &format!("{p}_share")))
            .flatten();
        *v = match estimated {
            Some(e) => e.value,
            None => num(stats, &format!("/phases/{p}/{field}"))?,
        };
    }
    let total: f64 = values.iter().sum();
    (total > 0.0).then(|| values.map(|v| v / total))
}

/// The three phases' shares of `field` (`cycles` or `intersection_tests`) in VTQ, per scene.
fn phase_shares(r: &Results, scenes: &[&str], field: &str) -> [Vec<Option<f64>>; 3] {
    let mut out: [Vec<Option<f64>>; 3] = Default::default();
    for scene in scenes {
        let split = r
            .stats(scene, VTQ, &[])
            .and_then(|stats| phase_split(&stats, field));
        for (i, o) in out.iter_mut().enumerate() {
            o.push(split.map(|v| v[i]));
        }
    }
    out
}

/// The phase series of Figures 14 and 15, the treelet-stationary phase first (at the bottom of
/// the stacks, so Figure 15's paper values read against its top), then initial, then final
/// ray-stationary.
fn phase_series(scenes: &[&str], shares: [Vec<Option<f64>>; 3]) -> Vec<BarSeries> {
    let [initial, treelet, ray] = shares;
    [
        ("treelet-stationary", treelet),
        ("initial", initial),
        ("ray-stationary", ray),
    ]
    .into_iter()
    .map(|(name, v)| BarSeries {
        intervals: Vec::new(),
        name: name.to_string(),
        values: with_mean(scenes, v, Mean::Arithmetic)
            .into_iter()
            .map(|x| x.map(|y| 100.0 * y))
            .collect(),
    })
    .collect()
}

/// A stacked bar chart `id` of VTQ's shares of `field` (`cycles` or `intersection_tests`) per
/// traversal phase per scene, and its table.
fn phase_bars(
    r: &Results,
    out: &Path,
    id: &str,
    title: &str,
    y_label: &str,
    field: &str,
    references: Vec<Reference>,
) -> anyhow::Result<(String, Table)> {
    let scenes = r.scenes();
    let cats = categories(&r.labels(), Mean::Arithmetic);
    let series = phase_series(&scenes, phase_shares(r, &scenes, field));
    let img = bars(
        out,
        id,
        &Bars {
            title: title.into(),
            y_label: y_label.into(),
            categories: cats.clone(),
            series: series.clone(),
            references,
            stacked: true,
            y_range: Some(RATE_PERCENT),
        },
    )?;
    let table = series_table("scene", &cats, &series, |v| {
        v.map_or_else(|| "-".into(), |x| format!("{x:.1}%"))
    });
    Ok((img, table))
}

/// Figure 14: VTQ's cycles per traversal phase.
pub fn figure14(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let (img, table) = phase_bars(
        r,
        out,
        "fig14",
        "Figure 14: VTQ's cycles per traversal phase",
        "share of cycles (%)",
        "cycles",
        vec![],
    )?;
    Ok(Figure {
        id: "fig14".into(),
        title: "Figure 14: cycle distribution of the traversal phases".into(),
        caption: "Share of VTQ's RT-unit cycles in the treelet-stationary phase (bottom), the \
                  initial phase and the final ray-stationary phase (top). The paper gives no \
                  numbers: for every scene a short initial phase, then mostly ray-stationary."
            .into(),
        images: vec![img],
        table,
    })
}

/// Figure 15: VTQ's intersection tests per traversal phase, and in the table also the share
/// made by warps in treelet-stop order (`rt.treelet_order_tests`).
pub fn figure15(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let (img, mut table) = phase_bars(
        r,
        out,
        "fig15",
        "Figure 15: VTQ's intersection tests per traversal phase",
        "share of intersection tests (%)",
        "intersection_tests",
        vec![
            paper("paper: treelet-stationary mean 15%", 15.0),
            paper("paper: treelet-stationary max 52%", 52.0),
        ],
    )?;
    let scenes = r.scenes();
    let by_order: Vec<Option<f64>> = scenes
        .iter()
        .map(|scene| treelet_order_share(&r.stats(scene, VTQ, &[])?))
        .collect();
    let by_order = with_mean(&scenes, by_order, Mean::Arithmetic);
    table
        .header
        .push("treelet-stop warps' tests (by traversal order)".into());
    for (row, v) in table.rows.iter_mut().zip(by_order) {
        row.push(v.map_or_else(|| "-".into(), |x| format!("{:.1}%", 100.0 * x)));
    }
    Ok(Figure {
        id: "fig15".into(),
        title: "Figure 15: intersection tests per traversal phase".into(),
        caption: "Share of VTQ's intersection tests done in each phase, stacked with the \
                  treelet-stationary part at the bottom so that the paper's values read against \
                  its top. The paper: the treelet-stationary phase processes 15% of the tests on \
                  average and up to 52%. The table's last column counts the tests by the warp's \
                  traversal order instead of the controller's mode: those of treelet warps and \
                  terminated initial warps (treelet-stop order), the other reading of the \
                  paper's \"ray traversal modes\" (docs/fidelity.md)."
            .into(),
        images: vec![img],
        table,
    })
}

/// The share of a run's node tests made by treelet-stop warps (treelet warps and terminated
/// initial warps): Figure 15 read by traversal order instead of controller mode.
pub(super) fn treelet_order_share(stats: &Json) -> Option<f64> {
    let tests: f64 = stats
        .pointer("/rt/tests")?
        .as_object()?
        .values()
        .filter_map(Json::as_f64)
        .sum();
    let order = num(stats, "/rt/treelet_order_tests")?;
    (tests > 0.0).then(|| order / tests)
}

/// Figure 16: the cost of ray virtualization in the full design.
pub fn figure16(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let scenes = r.scenes();
    let how = Mean::Arithmetic;
    let cats = categories(&r.labels(), how);
    // Extra cycles = (cycles with / cycles free) - 1: the free run's speedup over the run
    // with state traffic, less one.
    let overhead: Vec<Option<Estimate>> = scenes
        .iter()
        .map(|s| {
            let ratio = r.speedup(
                s,
                (VTQ, &[]),
                (VTQ, &["virtualization.state_traffic=false"]),
            )?;
            Some(Estimate {
                value: ratio.value - 1.0,
                ..ratio
            })
        })
        .collect();
    let series = vec![estimate_series(
        "measured by vtq",
        &scenes,
        overhead,
        how,
        100.0,
    )];
    let img = bars(
        out,
        "fig16",
        &Bars {
            title: "Figure 16: ray virtualization's overhead".into(),
            y_label: "extra cycles (%)".into(),
            categories: cats.clone(),
            series: series.clone(),
            references: vec![paper("paper: about 10%", 10.0)],
            stacked: false,
            y_range: None,
        },
    )?;
    Ok(Figure {
        id: "fig16".into(),
        title: "Figure 16: ray virtualization's performance overhead".into(),
        caption: "Extra cycles of VTQ when suspended CTAs' state is saved and restored through \
                  memory, against the same design with suspends free \
                  (`virtualization.state_traffic = false`). The paper: about 10% on average."
            .into(),
        images: vec![img],
        table: series_table("scene", &cats, &series, |v| {
            v.map_or_else(|| "-".into(), |x| format!("{x:+.1}%"))
        }),
    })
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
