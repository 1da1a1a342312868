//! Figure 17 and section 6.6's energy numbers (docs/energy.md): the energy of VTQ with and
//! without ray virtualization's state traffic relative to the baseline, stacked by component,
//! from the stored runs of Figures 10 and 16 (no run of its own), evaluated by the energy model
//! under each coefficient set.

use std::path::Path;

use serde_json::Value as Json;

use super::figures::{
    bars, categories, cell, paper, with_mean, Figure, Mean, Table, BASELINE, VTQ,
};
use super::Results;
use crate::experiment::plot::{BarSeries, Bars};
use crate::model::config::CoefficientSet;
use crate::model::energy::{stats_config, Coefficients, EnergyReport};

/// The override of Figure 16's run of VTQ without state traffic.
const NO_TRAFFIC: &str = "virtualization.state_traffic=false";

/// The paper's VTQ energy relative to the baseline (60% saved).
const PAPER_VTQ: f64 = 0.40;

/// The paper's virtualization share of VTQ's energy.
const PAPER_VIRTUALIZATION: f64 = 0.11;

/// The energy of stored statistics under `set` (`None` when absent or unreadable).
fn energy(stats: Option<Json>, set: CoefficientSet) -> Option<EnergyReport> {
    let stats = stats?;
    let cfg = stats_config(&stats).ok()?;
    EnergyReport::of_stats_with(&stats, &cfg, &Coefficients::of(set, &cfg)).ok()
}

/// Per scene: the baseline's, VTQ's and VTQ-without-state-traffic's energy under `set`.
type Triple = (
    Option<EnergyReport>,
    Option<EnergyReport>,
    Option<EnergyReport>,
);

/// The three runs' energy per scene under `set`.
fn triples(r: &Results, set: CoefficientSet) -> Vec<Triple> {
    r.scenes()
        .iter()
        .map(|s| {
            (
                energy(r.stats(s, BASELINE, &[]), set),
                energy(r.stats(s, VTQ, &[]), set),
                energy(r.stats(s, VTQ, &[NO_TRAFFIC]), set),
            )
        })
        .collect()
}

/// `design`'s energy over `base`'s.
fn ratio(design: &Option<EnergyReport>, base: &Option<EnergyReport>) -> Option<f64> {
    let (d, b) = (design.as_ref()?, base.as_ref()?);
    (b.total_mj > 0.0).then(|| d.total_mj / b.total_mj)
}

/// A column of a table per coefficient set: its name (after the set's) and its value from a
/// scene's [`Triple`].
type SetColumn = (&'static str, fn(&Triple) -> Option<f64>);

/// The header (`scene`, then each of `columns` under each coefficient set in turn) and the
/// columns' values per scene in `scenes` with their mean (`how`) after them.
fn set_columns(
    r: &Results,
    scenes: &[&str],
    how: Mean,
    columns: [SetColumn; 2],
) -> (Vec<String>, Vec<Vec<Option<f64>>>) {
    let mut header = vec!["scene".to_string()];
    let mut values = Vec::new();
    for set in CoefficientSet::ALL {
        let t = triples(r, set);
        for (name, value) in columns {
            header.push(format!("{set}: {name}"));
            values.push(with_mean(scenes, t.iter().map(value).collect(), how));
        }
    }
    (header, values)
}

/// Figure 17: energy relative to the baseline, stacked by component, under the paper's
/// accounting (AccelWattch PTX); the table adds the other coefficient sets' totals.
pub fn figure17(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let scenes = r.scenes();
    let labels = r.labels();
    let how = Mean::Arithmetic;
    let scene_cats = categories(&labels, how);
    let ptx = triples(r, CoefficientSet::AccelwattchPtx);
    // Categories: each scene (and the mean) twice, with and without state traffic; the second
    // bar of a pair is labelled `free` only, so the labels fit under the bars.
    let mut cats = Vec::new();
    for c in &scene_cats {
        cats.push(c.clone());
        cats.push("free".to_string());
    }
    let names: Vec<&str> = ptx
        .iter()
        .find_map(|(_, v, _)| v.as_ref())
        .map(|v| v.components.named().iter().map(|(n, _)| *n).collect())
        .unwrap_or_default();
    let mut series = Vec::new();
    for (k, name) in names.iter().enumerate() {
        let part = |design: &Option<EnergyReport>, base: &Option<EnergyReport>| {
            let (d, b) = (design.as_ref()?, base.as_ref()?);
            (b.total_mj > 0.0).then(|| d.components.named()[k].1 / b.total_mj)
        };
        let with = with_mean(
            &scenes,
            ptx.iter().map(|(b, v, _)| part(v, b)).collect(),
            how,
        );
        let without = with_mean(
            &scenes,
            ptx.iter().map(|(b, _, n)| part(n, b)).collect(),
            how,
        );
        let values = with
            .iter()
            .zip(&without)
            .flat_map(|(a, b)| [*a, *b])
            .collect();
        series.push(BarSeries {
            intervals: Vec::new(),
            name: name.replace('_', " "),
            values,
        });
    }
    let img = bars(
        out,
        "fig17",
        &Bars {
            title: "Figure 17: energy relative to the baseline (AccelWattch PTX)".into(),
            y_label: "energy / baseline energy".into(),
            categories: cats,
            series,
            references: vec![paper("paper: VTQ 0.40", PAPER_VTQ), paper("baseline", 1.0)],
            stacked: true,
            y_range: None,
        },
    )?;
    let (header, columns) = set_columns(
        r,
        &scenes,
        how,
        [
            ("VTQ", |(b, v, _)| ratio(v, b)),
            ("VTQ no-save", |(b, _, n)| ratio(n, b)),
        ],
    );
    let rows = scene_cats
        .iter()
        .enumerate()
        .map(|(i, c)| {
            std::iter::once(c.clone())
                .chain(columns.iter().map(|col| cell(col[i], 3)))
                .collect()
        })
        .chain(std::iter::once(
            std::iter::once("paper (mean)".to_string())
                .chain(std::iter::once(format!("{PAPER_VTQ:.2}")))
                .chain(std::iter::repeat_n("-".to_string(), columns.len() - 1))
                .collect(),
        ))
        .collect();
    Ok(Figure {
        id: "fig17".into(),
        title: "Figure 17: energy with and without ray virtualization".into(),
        caption: "Energy of VTQ, and of VTQ with suspends and resumes free \
                  (`virtualization.state_traffic = false`, Figure 16's run; the bar labelled \
                  `free` right of each scene's), relative to the baseline's on the same scene, \
                  stacked by component (time-proportional power, L1, L2 and interconnect, DRAM, \
                  RT tests, treelet tables, virtualization's CTA-state traffic) under the paper's accounting (AccelWattch's PTX fit; the \
                  energy model of docs/energy.md, an estimate). The table gives the totals under \
                  every coefficient set. The paper: VTQ uses 0.40 of the baseline's energy (60% \
                  saved), \"primarily from the reduced cycles\"."
            .into(),
        images: vec![img],
        table: Table { header, rows },
    })
}

/// Section 6.6: ray virtualization's share of VTQ's energy per scene under each coefficient
/// set, and the energy VTQ saves when its state moves for free.
pub fn section66(r: &Results) -> Table {
    let scenes = r.scenes();
    let how = Mean::Arithmetic;
    let cats = categories(&r.labels(), how);
    let (header, columns) = set_columns(
        r,
        &scenes,
        how,
        [
            ("CTA-state share", |(_, v, _)| {
                v.as_ref().map(|v| v.virtualization_share)
            }),
            ("1 - no-save / VTQ", |(_, v, n)| {
                ratio(n, v).map(|x| 1.0 - x)
            }),
        ],
    );
    let pct = |v: Option<f64>| v.map_or_else(|| "-".into(), |x| format!("{:.1}%", 100.0 * x));
    let mut rows: Vec<Vec<String>> = cats
        .iter()
        .enumerate()
        .map(|(i, c)| {
            std::iter::once(c.clone())
                .chain(columns.iter().map(|col| pct(col[i])))
                .collect()
        })
        .collect();
    rows.push(
        std::iter::once("paper".to_string())
            .chain(columns.iter().map(|_| pct(Some(PAPER_VIRTUALIZATION))))
            .collect(),
    );
    Table { header, rows }
}
