//! The section 6.5 table of `vtq reproduce` drawn from the stored runs: the treelet queues VTQ
//! tracked at once per scene (the storage and area of the tables, from the area model of
//! `vtq-gen`, is the command's: `area_table` in the `area` command).

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
