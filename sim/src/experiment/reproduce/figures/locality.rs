//! The figures of the BVH's memory behaviour and of the reuse treelets offer: the baseline's
//! BVH L1 miss rate and SIMT efficiency (Figure 1), the analytical model of treelet reuse
//! (Figure 5) and the miss rate over a run, baseline against treelet-stationary (Figure 11).

use std::path::Path;

use serde_json::Value as Json;

use super::super::{file_safe, Results};
use super::{
    append_columns, bars, categories, estimate_series, paper, pct, per_scene_estimates,
    series_table, Figure, Mean, Table, BASELINE, NAIVE, RATE, RATE_PERCENT,
};
use crate::estimate::figure5::Figure5Row;
use crate::experiment::plot::{
    write_lines, write_scatter, Bars, Line, Lines, Point, Scatter, Series,
};

/// Figure 1: the baseline's BVH L1 miss rate and RT-unit SIMT efficiency per scene.
pub fn figure1(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let scenes = r.scenes();
    let how = Mean::Arithmetic;
    let cats = categories(&r.labels(), how);
    // The baseline's statistic `name` per scene, scaled by `scale`, with its mean.
    let measured = |name: &str, scale: f64| {
        let values = per_scene_estimates(r, &scenes, BASELINE, name);
        estimate_series("measured by vtq", &scenes, values, how, scale)
    };
    let miss = measured("bvh_l1_miss_rate", 100.0);
    let simt = measured("simt_efficiency", 1.0);
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
