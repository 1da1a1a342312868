//! The statistics JSON against its documentation and its readers: every key `vtq sim` writes
//! (top level, `rt`, `queues`, each phase) is in docs/stats.md, every `rt` key it documents is
//! written, and every headline column `vtq sweep --collect` reads (`sweep::collect::DIRECT`) is
//! a statistic `vtq sim` writes, in every design.

mod common;

use std::collections::BTreeSet;
use std::path::Path;

use common::{setup, small_config, small_vtq};
use vtq_sim::experiment::sweep::collect::DIRECT;
use vtq_sim::model::gpu::{simulate, SimOptions};

/// The keys docs/stats.md's table under the heading `heading` documents: every `` `name` `` in
/// the first cell of its rows.
fn documented(heading: &str) -> BTreeSet<String> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/stats.md");
    let text = std::fs::read_to_string(&path).expect("docs/stats.md");
    let mut keys = BTreeSet::new();
    let mut inside = false;
    for line in text.lines() {
        if let Some(h) = line.strip_prefix("## ") {
            inside = h.trim() == heading;
            continue;
        }
        let Some(row) = line.strip_prefix('|').filter(|_| inside) else {
            continue;
        };
        let first = row.split('|').next().unwrap_or("");
        keys.extend(first.split('`').skip(1).step_by(2).map(str::to_string));
    }
    assert!(!keys.is_empty(), "no table under '## {heading}'");
    keys
}

/// The keys of a JSON object.
fn keys(v: &serde_json::Value) -> BTreeSet<String> {
    v.as_object().expect("an object").keys().cloned().collect()
}

#[test]
fn every_statistic_is_documented_and_every_collected_column_exists() {
    let top = documented("Top-level keys");
    let rt = documented("`rt`");
    let phases_doc =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/stats.md"))
            .unwrap();
    for cfg in [
        small_config("baseline", 2, 16, &[]),
        small_config("prefetch", 2, 16, &[]),
        small_vtq(2, 16, &[]),
    ] {
        let (scene, bvh) = setup("wknd", &cfg);
        let out = simulate(&scene, &bvh, &cfg, SimOptions::default(), None).unwrap();
        let json = serde_json::to_value(&out.stats).unwrap();
        let mode = &cfg.mode.kind;
        let missing: Vec<_> = keys(&json).difference(&top).cloned().collect();
        assert!(
            missing.is_empty(),
            "{mode}: undocumented top-level keys {missing:?}"
        );
        let missing: Vec<_> = keys(&json["rt"]).difference(&rt).cloned().collect();
        assert!(
            missing.is_empty(),
            "{mode}: undocumented rt keys {missing:?}"
        );
        let stale: Vec<_> = rt.difference(&keys(&json["rt"])).cloned().collect();
        assert!(
            stale.is_empty(),
            "{mode}: docs/stats.md documents rt keys vtq sim does not write: {stale:?}"
        );
        // The `queues` object's keys (the treelet RT units' counters, declared once in
        // vtq-hdl) are listed in the `queues` row's text.
        let queues_row = phases_doc
            .lines()
            .find(|l| l.starts_with("| `queues` |"))
            .expect("a `queues` row in docs/stats.md");
        for key in keys(&json["queues"]) {
            assert!(
                queues_row.contains(&format!("`{key}`")),
                "{mode}: queues key {key} undocumented"
            );
        }
        // Each phase's keys are listed in the `phases` row's text.
        for key in keys(&json["phases"]["ray_stationary"]) {
            assert!(
                phases_doc.contains(&format!("`{key}`")) || phases_doc.contains(&format!("{key},")),
                "{mode}: phase key {key} undocumented"
            );
        }
        for (column, pointer) in DIRECT {
            assert!(
                json.pointer(pointer).is_some(),
                "{mode}: the collected column {column} reads {pointer}, which vtq sim does not write"
            );
        }
    }
}
