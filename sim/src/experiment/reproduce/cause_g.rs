//! docs/fidelity.md's cause G: where VTQ's gain comes from, and when the treelet-stationary
//! phase pays. Two figures drawn from the experiment files `dev-mechanisms` (a factorial over
//! ray virtualization, treelet-stationary processing, grouping and repacking) and
//! `dev-treelet-map` (VTQ against VTQ with the treelet-stationary phase skipped, one machine
//! parameter at a time). Their points are read from the built-in copies of the files, so each
//! point is defined once.

use std::path::Path;

use super::figures::{cell, num, paper, Figure, Table};
use super::{file_safe, Results, EXPERIMENT_FILES};
use crate::experiment::plot::{write_bars, BarSeries, Bars};
use crate::experiment::sweep::spec::override_text;
use crate::experiment::sweep::SweepSpec;

/// The base configuration of both experiment files' points (the points spell out the design).
const BASE: &str = "configs/designs/baseline/config.toml";

/// The factorial's cells in the order of `dev-mechanisms`'s points: the mechanisms each has
/// (V ray virtualization, T treelet-stationary processing, G grouping, R repacking).
const CELLS: [&str; 10] = [
    "baseline",
    "V",
    "T",
    "TG",
    "G",
    "VT",
    "VTG",
    "VG",
    "VTGR (VTQ)",
    "VGR (T skipped)",
];

/// The keys that make a `dev-treelet-map` point VTQ or its skip variant (left out of the
/// point's label).
const DESIGN_KEYS: [&str; 6] = [
    "mode.kind",
    "mode.virtualization",
    "mode.grouping",
    "mode.preload",
    "hw.repack_threshold",
    "hw.underpopulation_threshold",
];

/// A point's overrides: (key, `key=value`).
type Sets = Vec<(String, String)>;

/// The points of built-in experiment file `name`, each as its `key=value` overrides.
fn points(name: &str) -> anyhow::Result<Vec<Sets>> {
    let (_, text) = EXPERIMENT_FILES
        .iter()
        .find(|(n, _)| *n == name)
        .ok_or_else(|| anyhow::anyhow!("no built-in experiment file {name}"))?;
    let spec = SweepSpec::from_toml(text)?;
    Ok(spec
        .points
        .iter()
        .map(|p| {
            p.iter()
                .map(|(k, v)| (k.clone(), override_text(k, v)))
                .collect()
        })
        .collect())
}

/// The cycles of `scene` run with the overrides `sets` on the base configuration.
fn cycles(r: &Results, scene: &str, sets: &[(String, String)]) -> Option<f64> {
    let sets: Vec<&str> = sets.iter().map(|(_, s)| s.as_str()).collect();
    num(&r.stats(scene, BASE, &sets)?, "/cycles")
}

/// The scenes (with their labels) for which `first` has a stored run.
fn scenes_with<'r>(r: &'r Results, first: &[(String, String)]) -> (Vec<&'r str>, Vec<String>) {
    r.scenes()
        .into_iter()
        .zip(r.labels())
        .filter(|(s, _)| cycles(r, s, first).is_some())
        .unzip()
}

/// A bar chart `id` under `out/figures` and the table of its values.
fn chart(out: &Path, id: &str, bars: &Bars) -> anyhow::Result<(String, Table)> {
    let stem = format!("figures/{}", file_safe(id));
    write_bars(&out.join(&stem), bars)?;
    let table = Table {
        header: std::iter::once("".to_string())
            .chain(bars.series.iter().map(|s| s.name.clone()))
            .collect(),
        rows: bars
            .categories
            .iter()
            .enumerate()
            .map(|(i, c)| {
                std::iter::once(c.clone())
                    .chain(
                        bars.series
                            .iter()
                            .map(|s| cell(s.values.get(i).copied().flatten(), 3)),
                    )
                    .collect()
            })
            .collect(),
    };
    Ok((stem, table))
}

/// The factorial: each cell's speedup over the baseline per scene.
pub fn mechanisms(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let pts = points("dev-mechanisms")?;
    anyhow::ensure!(
        pts.len() == CELLS.len(),
        "dev-mechanisms has {} points, the figure names {}",
        pts.len(),
        CELLS.len()
    );
    let (scenes, labels) = scenes_with(r, &pts[0]);
    anyhow::ensure!(
        !scenes.is_empty(),
        "no scene has the factorial's baseline run"
    );
    let series = CELLS[1..]
        .iter()
        .zip(&pts[1..])
        .map(|(name, sets)| BarSeries {
            name: name.to_string(),
            values: scenes
                .iter()
                .map(|s| Some(cycles(r, s, &pts[0])? / cycles(r, s, sets)?))
                .collect(),
        })
        .collect();
    let (img, table) = chart(
        out,
        "cause-g-mechanisms",
        &Bars {
            title: "VTQ's mechanisms: speedup over the baseline".into(),
            y_label: "speedup (baseline cycles / cycles)".into(),
            categories: labels,
            series,
            references: vec![
                paper("paper: VTQ mean 1.95", 1.95),
                paper("paper: T skipped, 4x the cycles", 0.25),
                paper("paper: T skipped, 6x the cycles", 1.0 / 6.0),
            ],
            stacked: false,
            y_range: None,
        },
    )?;
    Ok(Figure {
        id: "cause-g-mechanisms".into(),
        title: "Cause G: which mechanism carries VTQ's gain".into(),
        caption: "A factorial over VTQ's four mechanisms (`dev-mechanisms`): V ray \
                  virtualization, T treelet-stationary processing, G grouping underpopulated \
                  queues into ray-stationary warps, R warp repacking (below 22 active rays; it \
                  needs G and V). Without T every queue is underpopulated (threshold 4096), so \
                  diverged rays go straight to grouped warps. The paper: VTQ 1.95x; skipping \
                  the treelet-stationary phase, 4-6x the baseline's cycles (section 6.4). \
                  docs/fidelity.md, cause G."
            .into(),
        images: vec![img],
        table,
    })
}

/// The label of a `dev-treelet-map` point: its overrides beyond the design's keys.
fn map_label(sets: &[(String, String)]) -> String {
    let own: Vec<&str> = sets
        .iter()
        .filter(|(k, _)| !DESIGN_KEYS.contains(&k.as_str()))
        .map(|(_, s)| s.as_str())
        .collect();
    if own.is_empty() {
        "Table 1".to_string()
    } else {
        own.join(", ")
    }
}

/// The map: per machine parameter, VTQ's cycles over the skip variant's, per scene.
pub fn treelet_map(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let pts = points("dev-treelet-map")?;
    anyhow::ensure!(
        !pts.is_empty() && pts.len() % 2 == 0,
        "dev-treelet-map must list its points in pairs (VTQ, T skipped)"
    );
    let pairs: Vec<(&Sets, &Sets)> = pts.chunks(2).map(|p| (&p[0], &p[1])).collect();
    let (scenes, labels) = scenes_with(r, pairs[0].0);
    anyhow::ensure!(!scenes.is_empty(), "no scene has the map's runs");
    let categories: Vec<String> = pairs.iter().map(|(v, _)| map_label(v)).collect();
    let series = scenes
        .iter()
        .zip(labels)
        .map(|(s, label)| BarSeries {
            name: label,
            values: pairs
                .iter()
                .map(|(v, k)| Some(cycles(r, s, v)? / cycles(r, s, k)?))
                .collect(),
        })
        .collect();
    let (img, table) = chart(
        out,
        "cause-g-map",
        &Bars {
            title: "VTQ's cycles over VTQ's with the treelet-stationary phase skipped".into(),
            y_label: "cycles ratio (below 1: the phase pays)".into(),
            categories,
            series,
            references: vec![
                paper("equal", 1.0),
                paper("the phase saves 1.5x", 1.0 / 1.5),
            ],
            stacked: false,
            y_range: None,
        },
    )?;
    Ok(Figure {
        id: "cause-g-map".into(),
        title: "Cause G: when the treelet-stationary phase pays".into(),
        caption: "VTQ's cycles over those of VTQ with its treelet-stationary phase skipped \
                  (`dev-treelet-map`), one machine parameter changed at a time from Table 1's, \
                  and two corners that combine the settings most favourable to treelet reuse. \
                  Below the dashed line at 0.67 the phase would save at least 1.5x; the paper \
                  reports skipping it costs 4-6x the baseline's cycles. docs/fidelity.md, \
                  cause G."
            .into(),
        images: vec![img],
        table,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_experiment_files_match_the_figures() {
        let cells = points("dev-mechanisms").unwrap();
        assert_eq!(cells.len(), CELLS.len());
        let map = points("dev-treelet-map").unwrap();
        assert_eq!(map.len() % 2, 0);
        for pair in map.chunks(2) {
            // Each pair differs only in the underpopulation threshold (the skip variant's).
            let strip = |p: &Sets| -> Sets {
                p.iter()
                    .filter(|(k, _)| k != "hw.underpopulation_threshold")
                    .cloned()
                    .collect()
            };
            assert_eq!(strip(&pair[0]), strip(&pair[1]));
            assert!(pair[1]
                .iter()
                .any(|(k, _)| k == "hw.underpopulation_threshold"));
        }
        assert_eq!(map_label(&map[0]), "Table 1");
        assert_eq!(map_label(&map[2]), "memory.l1_bytes=32768");
    }
}
