//! The section 6.5 tables of `vtq reproduce`: the treelet queues VTQ tracked at once per
//! scene, and the storage and area of the tables from the area model.

use vtq_gen::AreaReport;

use super::figures::{cell, num, Table, VTQ};
use super::Results;

/// Section 6.5: the treelet queues tracked at once, against the tables' sizes.
pub fn section65(r: &Results) -> Table {
    let scenes = r.scenes();
    let mut rows: Vec<Vec<String>> = scenes
        .iter()
        .zip(r.labels())
        .map(|(s, name)| {
            let stats = r.stats(s, VTQ, &[]);
            let get = |p: &str| cell(stats.as_ref().and_then(|x| num(x, p)), 0);
            vec![
                name,
                get("/max_queues"),
                get("/max_queues_above_threshold"),
                get("/count_table_evictions"),
            ]
        })
        .collect();
    rows.push(vec![
        "paper (max over LumiBench)".into(),
        "549".into(),
        "13".into(),
        "-".into(),
    ]);
    Table {
        header: vec![
            "scene".into(),
            "most treelet queues at once".into(),
            "most above the threshold".into(),
            "count-table evictions".into(),
        ],
        rows,
    }
}

/// Section 6.5: the area report's structures as a table.
pub fn area_table(report: &AreaReport) -> Table {
    let mut header = vec![
        "structure".to_string(),
        "where".into(),
        "entries".into(),
        "bits / entry".into(),
        "size".into(),
        "paper".into(),
    ];
    if let Some(s) = report.structures.first() {
        for a in &s.area {
            header.push(format!("SRAM {} nm (mm²)", a.feature_nm));
        }
    }
    Table {
        header,
        rows: report
            .structures
            .iter()
            .map(|s| {
                let mut row = vec![
                    s.name.clone(),
                    s.location.clone(),
                    s.entries.to_string(),
                    s.entry_bits.to_string(),
                    s.size.clone(),
                    s.paper.clone().unwrap_or_else(|| "-".into()),
                ];
                row.extend(s.area.iter().map(|a| format!("{:.4}", a.sram_mm2)));
                row
            })
            .collect(),
    }
}
