//! The figures of the designs' speed: speedups of treelet prefetching and VTQ (Figure 10),
//! of treelet queues with and without grouping (Figure 12), of warp repacking with its SIMT
//! efficiencies (Figure 13), and the cost of ray virtualization (Figure 16).

use std::path::Path;

use serde_json::Value as Json;

use super::super::Results;
use super::{
    append_columns, bars, categories, estimate_series, num, paper, per_scene, per_scene_estimates,
    series_table, speedup_bars, with_mean, Figure, Mean, BASELINE, GROUPING, NAIVE, PREFETCH, RATE,
    REPACK16, VTQ,
};
use crate::estimate::sample::Estimate;
use crate::experiment::plot::{BarSeries, Bars};

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
