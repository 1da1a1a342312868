//! docs/fidelity.md's cause G: where VTQ's gain comes from, and when the treelet-stationary
//! phase pays. Two figures drawn from the experiment files `dev-mechanisms` (a factorial over
//! ray virtualization, treelet-stationary processing, grouping and repacking) and
//! `dev-treelet-map` (VTQ against VTQ with the treelet-stationary phase skipped, one machine
//! parameter at a time). Their points are read from the built-in copies of the files, so each
//! point is defined once.

use std::path::Path;

use super::figures::{bars, cell, estimate_bars, num, paper, series_table, Figure, Table};
use super::{Results, EXPERIMENT_FILES};
use crate::estimate::sample::Estimate;
use crate::experiment::plot::{BarSeries, Bars};
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
pub(super) type Sets = Vec<(String, String)>;

/// The points of built-in experiment file `name`, each as its `key=value` overrides.
pub(super) fn points(name: &str) -> anyhow::Result<Vec<Sets>> {
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

/// The speedup of `scene` run with the overrides `design` over the same scene with `reference`
/// (cycles of `reference` over cycles of `design`), exact or, from sampled runs, an estimate
/// with its 95% interval.
fn ratio(
    r: &Results,
    scene: &str,
    reference: &[(String, String)],
    design: &[(String, String)],
) -> Option<Estimate> {
    fn strs(sets: &[(String, String)]) -> Vec<&str> {
        sets.iter().map(|(_, s)| s.as_str()).collect()
    }
    let (a, b) = (strs(reference), strs(design));
    r.speedup(scene, (BASE, &a), (BASE, &b))
}

/// An estimate's table cell: three decimals, and its 95% interval in brackets if it has one.
fn estimate_cell(e: Option<Estimate>) -> String {
    match e.and_then(|e| e.interval().map(|i| (e.value, i))) {
        Some((v, (lo, hi))) => format!("{v:.3} [{lo:.3}, {hi:.3}]"),
        None => cell(e.map(|e| e.value), 3),
    }
}

/// The scenes (with their labels) that have a stored run of every point of `points`.
fn scenes_with<'r>(r: &'r Results, points: &[Sets]) -> (Vec<&'r str>, Vec<String>) {
    r.scenes()
        .into_iter()
        .zip(r.labels())
        .filter(|(s, _)| points.iter().all(|p| cycles(r, s, p).is_some()))
        .unzip()
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
    let (scenes, labels) = scenes_with(r, &pts);
    anyhow::ensure!(
        !scenes.is_empty(),
        "no scene has every run of the factorial"
    );
    let series: Vec<BarSeries> = CELLS[1..]
        .iter()
        .zip(&pts[1..])
        .map(|(name, sets)| {
            let values: Vec<_> = scenes.iter().map(|s| ratio(r, s, &pts[0], sets)).collect();
            estimate_bars(name, &values, 1.0)
        })
        .collect();
    let table = series_table("scene", &labels, &series, |v| cell(v, 3));
    let img = bars(
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

/// The map's groups of machine parameters, each drawn as a chart of its own (the title suffix
/// and the keys whose points it holds); a point that sets several keys is a corner, drawn with
/// the rays-in-flight group.
const MAP_GROUPS: [(&str, &[&str]); 3] = [
    (
        "caches",
        &["memory.l1_bytes", "memory.l2_bytes", "memory.l1_mshrs"],
    ),
    (
        "latency and bandwidth",
        &[
            "memory.dram_latency",
            "memory.dram_bytes_per_cycle",
            "memory.l2_latency",
        ],
    ),
    (
        "rays in flight, treelets, warp slots",
        &["hw.max_rays", "hw.treelet_bytes", "hw.warp_buffer_size"],
    ),
];

/// A map point's overrides beyond the design's keys.
fn machine(sets: &Sets) -> Vec<&(String, String)> {
    sets.iter()
        .filter(|(k, _)| !DESIGN_KEYS.contains(&k.as_str()))
        .collect()
}

/// A byte count in K or M.
fn bytes(v: &str) -> String {
    match v.parse::<u64>() {
        Ok(b) if b >= 1 << 20 && b % (1 << 20) == 0 => format!("{}M", b >> 20),
        Ok(b) if b >= 1 << 10 && b % (1 << 10) == 0 => format!("{}K", b >> 10),
        _ => v.to_string(),
    }
}

/// A map point's short label for a chart's axis (`L1 32K`, `DRAM 508`); the figure's table
/// gives its full overrides.
fn short_label(sets: &Sets, corner: &mut u32) -> String {
    let own = machine(sets);
    match own.as_slice() {
        [] => "Table 1".to_string(),
        [(k, text)] => {
            let v = text.split_once('=').map_or("", |(_, v)| v);
            match k.as_str() {
                "memory.l1_bytes" => format!("L1 {}", bytes(v)),
                "memory.l2_bytes" => format!("L2 {}", bytes(v)),
                "memory.l1_mshrs" => format!("MSHR {v}"),
                "memory.dram_latency" => format!("DRAM {v}"),
                "memory.dram_bytes_per_cycle" => format!("{v} B/cy"),
                "memory.l2_latency" => format!("L2 {v}cy"),
                "hw.max_rays" => format!("rays {v}"),
                "hw.treelet_bytes" => format!("treelet {}", bytes(v)),
                "hw.warp_buffer_size" => format!("{v} slots"),
                _ => text.clone(),
            }
        }
        _ if own.iter().any(|(k, _)| k == "hw.treelet_bytes") && own.len() == 2 => {
            let v = |key: &str| {
                own.iter()
                    .find(|(k, _)| k == key)
                    .and_then(|(_, t)| t.split_once('='))
                    .map_or(String::new(), |(_, v)| bytes(v))
            };
            format!("treelet {}", v("hw.treelet_bytes"))
        }
        _ => {
            *corner += 1;
            format!("corner {corner}")
        }
    }
}

/// The group of [`MAP_GROUPS`] a map point belongs to (`None`: Table 1's point, in every
/// group).
fn group_of(sets: &Sets) -> Option<usize> {
    let own = machine(sets);
    let first = own.first()?;
    if own.len() > 1 && !own.iter().any(|(k, _)| k == "hw.treelet_bytes") {
        return Some(MAP_GROUPS.len() - 1);
    }
    let key = if own.len() > 1 {
        "hw.treelet_bytes"
    } else {
        first.0.as_str()
    };
    MAP_GROUPS
        .iter()
        .position(|(_, keys)| keys.contains(&key))
        .or(Some(MAP_GROUPS.len() - 1))
}

/// The map: per machine parameter, VTQ's cycles over the skip variant's, per scene that has
/// every point, in three charts (caches; latency and bandwidth; rays in flight, treelets and
/// warp slots, with the corners).
pub fn treelet_map(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let pts = points("dev-treelet-map")?;
    anyhow::ensure!(
        !pts.is_empty() && pts.len() % 2 == 0,
        "dev-treelet-map must list its points in pairs (VTQ, T skipped)"
    );
    let pairs: Vec<(&Sets, &Sets)> = pts.chunks(2).map(|p| (&p[0], &p[1])).collect();
    let (scenes, names) = scenes_with(r, &pts);
    anyhow::ensure!(!scenes.is_empty(), "no scene has every run of the map");
    // VTQ's cycles over the skip variant's: the skip variant's speedup over VTQ.
    let ratio = |s: &str, (v, k): &(&Sets, &Sets)| ratio(r, s, v, k);
    let mut corner = 0;
    let shorts: Vec<String> = pairs
        .iter()
        .map(|(v, _)| short_label(v, &mut corner))
        .collect();
    let mut images = Vec::new();
    for (g, (title, _)) in MAP_GROUPS.iter().enumerate() {
        let members: Vec<usize> = (0..pairs.len())
            .filter(|&i| group_of(pairs[i].0).is_none_or(|x| x == g))
            .collect();
        let series = scenes
            .iter()
            .zip(&names)
            .map(|(s, name)| {
                let values: Vec<_> = members.iter().map(|&i| ratio(s, &pairs[i])).collect();
                estimate_bars(name, &values, 1.0)
            })
            .collect();
        let img = bars(
            out,
            &format!("cause-g-map-{}", g + 1),
            &Bars {
                title: format!("VTQ / VTQ with the treelet-stationary phase skipped: {title}"),
                y_label: "cycles ratio (below 1: the phase pays)".into(),
                categories: members.iter().map(|&i| shorts[i].clone()).collect(),
                series,
                references: vec![
                    paper("equal", 1.0),
                    paper("the phase saves 1.5x", 1.0 / 1.5),
                ],
                stacked: false,
                y_range: Some((0.0, 1.2)),
            },
        )?;
        images.push(img);
    }
    let table = Table {
        header: ["point", "overrides"]
            .into_iter()
            .map(String::from)
            .chain(names.iter().cloned())
            .collect(),
        rows: pairs
            .iter()
            .zip(&shorts)
            .map(|(pair, short)| {
                [short.clone(), map_label(pair.0)]
                    .into_iter()
                    .chain(scenes.iter().map(|s| estimate_cell(ratio(s, pair))))
                    .collect()
            })
            .collect(),
    };
    Ok(Figure {
        id: "cause-g-map".into(),
        title: "Cause G: when the treelet-stationary phase pays".into(),
        caption: "VTQ's cycles over those of VTQ with its treelet-stationary phase skipped \
                  (`dev-treelet-map`), one machine parameter changed at a time from Table 1's \
                  (cycles and bytes per cycle as labelled; the table gives each point's \
                  overrides), and two corners that combine the settings most favourable to \
                  treelet reuse. Below the dashed line at 0.67 the phase would save at least \
                  1.5x; the paper reports skipping it costs 4-6x the baseline's cycles. \
                  docs/fidelity.md, cause G."
            .into(),
        images,
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
        let mut corner = 0;
        let shorts: Vec<String> = map
            .chunks(2)
            .map(|p| short_label(&p[0], &mut corner))
            .collect();
        assert_eq!(shorts[1], "L1 32K");
        assert!(shorts.contains(&"L2 4M".to_string()), "{shorts:?}");
        assert!(shorts.contains(&"corner 2".to_string()), "{shorts:?}");
        // Every point but Table 1's belongs to one group, and every group has points.
        for g in 0..MAP_GROUPS.len() {
            assert!(map.chunks(2).any(|p| group_of(&p[0]) == Some(g)));
        }
        assert_eq!(group_of(&map[0]), None);
    }
}
