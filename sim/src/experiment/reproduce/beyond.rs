//! Figures beyond the paper: design questions the paper's blocks invite, answered with the same
//! runs and charts as its figures. Each has its experiment file in `configs/experiments/`
//! (`ext-*.toml`) and its reading in docs/fidelity.md.

use std::path::Path;

use super::cause_g::points;
use super::figures::{
    cell, paper, phase_split, speedup_bars, treelet_order_share, Figure, Table, BASELINE, PREFETCH,
    VTQ,
};
use super::Results;
use crate::experiment::plot::{write_lines, Line, Lines, Reference};

/// VTQ with treelet prefetching in its ray-stationary phases (design `vtq-prefetch`).
const VTQ_PREFETCH: &str = "configs/designs/vtq-prefetch/config.toml";
/// VTQ with treelet prefetching in every phase.
const VTQ_PREFETCH_ALL: &str = "configs/designs/vtq-prefetch-all/config.toml";

/// VTQ with treelet prefetching: speedups over the baseline of prefetching alone, VTQ alone and
/// VTQ with the prefetcher watching its rays in the ray-stationary phases or in all.
pub fn vtq_prefetch(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let (img, table) = speedup_bars(
        r,
        out,
        "ext-vtq-prefetch",
        "VTQ with treelet prefetching: speedup over the baseline",
        &[
            ("treelet prefetching", PREFETCH),
            ("VTQ", VTQ),
            ("VTQ + prefetching (ray-stationary phases)", VTQ_PREFETCH),
            ("VTQ + prefetching (all phases)", VTQ_PREFETCH_ALL),
        ],
        vec![paper("baseline", 1.0)],
    )?;
    Ok(Figure {
        id: "ext-vtq-prefetch".into(),
        title: "Beyond the paper: VTQ with treelet prefetching".into(),
        caption: "Speedup over the baseline of treelet prefetching alone (MICRO 2023), VTQ alone, \
                  and VTQ with the same prefetcher beside its treelet RT unit, watching the rays \
                  in the initial and final ray-stationary phases only or in every phase \
                  (`mode.treelet_prefetch`; the prefetcher also serves VTQ's treelet preloads). \
                  The paper does not evaluate this combination."
            .into(),
        images: vec![img],
        table,
    })
}

/// The experiment file of the workload predictions.
const PREDICTIONS: &str = "ext-workload-predictions";

/// One workload point of [`PREDICTIONS`]: the workload key it varies and its value.
#[derive(Debug, Clone)]
struct WorkloadPoint {
    /// `spp`, `bounces` or `kind`.
    key: String,
    /// Its value (a count, or the kind's name).
    value: String,
    /// The override that selects it (`workload.spp=2`).
    set: String,
}

impl WorkloadPoint {
    /// The experiment file's points in its order, each one `workload.*` override.
    fn all() -> anyhow::Result<Vec<WorkloadPoint>> {
        points(PREDICTIONS)?
            .into_iter()
            .map(|sets| {
                let [(key, set)] = sets.as_slice() else {
                    anyhow::bail!("{PREDICTIONS}: a point sets {} keys, not one", sets.len());
                };
                let key = key
                    .strip_prefix("workload.")
                    .ok_or_else(|| anyhow::anyhow!("{PREDICTIONS}: {key} is not a workload key"))?;
                let value = set.rsplit('=').next().unwrap_or_default().trim_matches('"');
                Ok(WorkloadPoint {
                    key: key.to_string(),
                    value: value.to_string(),
                    set: set.clone(),
                })
            })
            .collect()
    }
}

/// One line chart of the predictions: its file name part, its y axis, the value it draws and
/// its reference lines.
type Chart = (
    &'static str,
    &'static str,
    fn(&PointResult) -> Option<f64>,
    Vec<Reference>,
);

/// What one scene gives at one workload point: VTQ's treelet-stationary share of its
/// intersection tests and the speedups over the baseline of VTQ and of prefetching.
struct PointResult {
    treelet_share: Option<f64>,
    /// The share of VTQ's tests made by treelet-stop warps (treelet and terminated initial
    /// warps): Figure 15's other reading.
    order_share: Option<f64>,
    vtq: Option<f64>,
    prefetch: Option<f64>,
}

/// [`PointResult`] of `scene` at `p`, `None` when a run is missing.
fn point_result(r: &Results, scene: &str, p: &WorkloadPoint) -> Option<PointResult> {
    let sets: &[&str] = &[&p.set];
    let stats = r.stats(scene, VTQ, sets)?;
    let speedup = |design| {
        r.speedup(scene, (BASELINE, sets), (design, sets))
            .map(|e| e.value)
    };
    Some(PointResult {
        treelet_share: phase_split(&stats, "intersection_tests").map(|split| split[1]),
        order_share: treelet_order_share(&stats),
        vtq: speedup(VTQ),
        prefetch: speedup(PREFETCH),
    })
}

/// A share as a percentage cell with one decimal, `-` when missing.
fn percent(v: Option<f64>) -> String {
    v.map_or_else(|| "-".into(), |s| format!("{:.1}%", 100.0 * s))
}

/// The paper's workload predictions: how the treelet-stationary share of VTQ's tests and its
/// speedups move with samples per pixel and bounces, and what they are for the other workload
/// kinds (the table's `kind` rows), per scene with every point stored.
pub fn workload_predictions(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let points = WorkloadPoint::all()?;
    let mut scenes: Vec<(String, Vec<PointResult>)> = Vec::new();
    for (scene, label) in r.scenes().into_iter().zip(r.labels()) {
        let results: Option<Vec<PointResult>> =
            points.iter().map(|p| point_result(r, scene, p)).collect();
        if let Some(results) = results {
            scenes.push((label, results));
        }
    }
    anyhow::ensure!(
        !scenes.is_empty(),
        "no scene has every run of {PREDICTIONS}"
    );
    let mut images = Vec::new();
    for (key, x_label) in [
        ("spp", "samples per pixel (3 bounces)"),
        ("bounces", "bounces (1 sample per pixel)"),
    ] {
        let charts: [Chart; 2] = [
            (
                "share",
                "treelet-stationary share of VTQ's tests (%)",
                |p| p.treelet_share.map(|s| 100.0 * s),
                vec![paper("paper, 1 spp, 3 bounces: mean 15%", 15.0)],
            ),
            (
                "speedup",
                "VTQ's speedup over the baseline",
                |p| p.vtq,
                vec![paper("baseline", 1.0)],
            ),
        ];
        for (what, y_label, value, references) in charts {
            let lines = scenes
                .iter()
                .map(|(label, results)| Line {
                    name: label.clone(),
                    points: points
                        .iter()
                        .zip(results)
                        .filter(|(p, _)| p.key == key)
                        .filter_map(|(p, res)| Some((p.value.parse().ok()?, value(res)?)))
                        .collect(),
                })
                .collect();
            let stem = format!("figures/ext-workload-{what}-{key}");
            write_lines(
                &out.join(&stem),
                &Lines {
                    title: format!("{y_label} against {key}"),
                    x_label: x_label.into(),
                    y_label: y_label.into(),
                    lines,
                    references,
                    x_range: None,
                    y_range: None,
                },
            )?;
            images.push(stem);
        }
    }
    let rows = scenes
        .iter()
        .flat_map(|(label, results)| {
            points.iter().zip(results).map(move |(p, res)| {
                let over_prefetch = res.vtq.zip(res.prefetch).map(|(v, f)| v / f);
                vec![
                    label.clone(),
                    format!("{} {}", p.key, p.value),
                    percent(res.treelet_share),
                    percent(res.order_share),
                    cell(res.vtq, 3),
                    cell(res.prefetch, 3),
                    cell(over_prefetch, 3),
                ]
            })
        })
        .collect();
    Ok(Figure {
        id: "ext-workload-predictions".into(),
        title: "Beyond the paper: its workload predictions".into(),
        caption: "The paper expects the treelet-stationary phase to process fewer of the \
                  intersection tests with more bounces (more divergent rays) and more of them \
                  with more samples per pixel. Per scene: the share of VTQ's tests done \
                  treelet-stationary and VTQ's speedup over the baseline, against samples per \
                  pixel (3 bounces) and against bounces (1 sample per pixel); the table adds \
                  the share of tests made by treelet-stop warps (Figure 15's reading by \
                  traversal order), prefetching's speedup and VTQ's over prefetching \
                  (docs/fidelity.md). The `kind` rows are the other workloads at 1 sample per \
                  pixel: `ao`, ambient occlusion (a primary ray, then occlusion rays); \
                  `path-nee`, the paths with a shadow ray at each diffuse hit; `hybrid`, the \
                  paths' secondary rays only (primary hits given, as by rasterization)."
            .into(),
        images,
        table: Table {
            header: [
                "scene",
                "workload",
                "treelet-stationary share of tests",
                "treelet-stop warps' share of tests (by traversal order)",
                "VTQ over baseline",
                "prefetching over baseline",
                "VTQ over prefetching",
            ]
            .map(String::from)
            .to_vec(),
            rows,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_predictions_points_come_from_their_experiment_file() {
        let points = WorkloadPoint::all().unwrap();
        let of = |key: &str| -> Vec<&str> {
            points
                .iter()
                .filter(|p| p.key == key)
                .map(|p| p.value.as_str())
                .collect()
        };
        assert_eq!(of("spp"), ["1", "2", "4", "8"]);
        assert_eq!(of("bounces"), ["1", "2", "3", "5"]);
        assert_eq!(of("kind"), ["ao", "path-nee", "hybrid"]);
        assert_eq!(points[1].set, "workload.spp=2");
    }
}
