//! The figures of the traversal phases: VTQ's cycles (Figure 14) and intersection tests
//! (Figure 15) per phase, and the phase and traversal-order shares of one run's statistics
//! that other pages read too.

use std::path::Path;

use serde_json::Value as Json;

use super::super::Results;
use super::{
    bars, categories, num, paper, series_table, with_mean, Figure, Mean, Table, RATE_PERCENT, VTQ,
};
use crate::estimate::sample::stored::stored_estimate;
use crate::experiment::plot::{BarSeries, Bars, Reference};

/// The three phases' (initial, treelet-stationary, final ray-stationary) shares of `field`
/// (`cycles` or `intersection_tests`) in one run's statistics.
pub(in crate::experiment::reproduce) fn phase_split(stats: &Json, field: &str) -> Option<[f64; 3]> {
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
pub(in crate::experiment::reproduce) fn treelet_order_share(stats: &Json) -> Option<f64> {
    let tests: f64 = stats
        .pointer("/rt/tests")?
        .as_object()?
        .values()
        .filter_map(Json::as_f64)
        .sum();
    let order = num(stats, "/rt/treelet_order_tests")?;
    (tests > 0.0).then(|| order / tests)
}
