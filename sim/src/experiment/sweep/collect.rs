//! The tidy table of a sweep (`vtq sweep --collect`): one row per run, one column per swept
//! configuration key (every key whose value differs between the rows) and per headline
//! statistic, plus the run's status, error and key; rows in a fixed order (scene, then the
//! swept values, then key), so the same results always give the same table, byte for byte.

use std::cmp::Ordering;
use std::path::Path;

use anyhow::Context;
use serde_json::Value as Json;
use toml::{Table, Value};

use super::key::Tier;
use super::record::RunRecord;
use super::spec::{leaves, value_text};
use crate::estimate::sample::stored::{stored_estimate, ESTIMATED};
use crate::model::energy::{stats_config, Components, EnergyReport};

/// A run's status in the table when a sweep point has no result file yet (its job was killed,
/// cancelled or has not run).
pub const MISSING: &str = "missing";

/// Headline statistics read directly from the statistics JSON: (column, JSON pointer). A test
/// (`sim/tests/stats_docs.rs`) checks that every pointer reads a statistic `vtq sim` writes.
pub const DIRECT: [(&str, &str); 34] = [
    ("cycles", "/cycles"),
    ("rays", "/rays"),
    ("rays_hit", "/rays_hit"),
    ("simt_efficiency", "/simt_efficiency"),
    ("bvh_l1_accesses", "/bvh_l1_accesses"),
    ("bvh_l1_misses", "/bvh_l1_misses"),
    ("bvh_l1_miss_rate", "/bvh_l1_miss_rate"),
    (
        "bvh_l1_miss_rate_with_prefetches",
        "/bvh_l1_miss_rate_with_prefetches",
    ),
    ("l2_misses", "/l2_misses"),
    ("dram_bytes", "/dram_bytes"),
    ("max_queues", "/max_queues"),
    ("max_queues_above_threshold", "/max_queues_above_threshold"),
    ("count_table_evictions", "/count_table_evictions"),
    ("queue_table_spills", "/queue_table_spills"),
    ("cta_suspends", "/cta_suspends"),
    ("cta_save_cycles", "/virtualization/save_cycles"),
    (
        "cta_resume_wait_cycles",
        "/virtualization/resume_wait_cycles",
    ),
    ("cta_restore_cycles", "/virtualization/restore_cycles"),
    ("cta_state_accesses", "/memory/cta_state/l1_bypasses"),
    ("dram_queue_cycles", "/memory/dram/queue_cycles"),
    ("dram_write_queue_cycles", "/memory/dram/write_queue_cycles"),
    ("bvh_dram_reads", "/memory/bvh/dram_reads"),
    ("bvh_dram_queue_cycles", "/memory/bvh/dram_queue_cycles"),
    ("max_rays_in_flight", "/max_rays_in_flight"),
    ("treelet_warps", "/queues/treelet_warps"),
    ("grouped_warps", "/queues/grouped_warps"),
    ("repacks", "/queues/repacks"),
    ("repack_starved_cycles", "/queues/repack_starved_cycles"),
    ("stack_spills", "/rt/stack_spills"),
    ("ray_stack_accesses", "/memory/ray_stack/l1_bypasses"),
    ("bvh_bytes", "/bvh/bvh_bytes"),
    ("treelets", "/bvh/treelets"),
    ("prefetches_issued", "/prefetches_issued"),
    ("prefetches_used", "/prefetches_used"),
];

/// The three traversal phases, whose shares of the phase cycles are columns `<phase>_share`
/// and whose shares of the intersection tests are columns `<phase>_test_share`.
const PHASES: [&str; 3] = ["initial", "treelet_stationary", "ray_stationary"];

/// Deciles of the run whose BVH L1 miss rates are columns `miss_rate_d<1..=10>` (and, with
/// prefetches counted, `miss_rate_pf_d<1..=10>`).
const DECILES: usize = 10;

/// One row before the columns are chosen.
#[derive(Debug, Clone)]
pub struct Row {
    /// The scene's name.
    pub scene: String,
    /// The vtq version of the result (a column only when the rows differ).
    pub vtq_version: String,
    /// The effective configuration, flattened to dotted keys, sorted.
    pub config: Vec<(String, Value)>,
    /// `ok`, `failed` or [`MISSING`].
    pub status: String,
    /// The error of a failed run.
    pub error: String,
    /// The statistics of a run that finished.
    pub stats: Option<Json>,
    /// The tier it ran (or would run) in.
    pub tier: Tier,
    /// The run's key.
    pub key: String,
}

/// A configuration's TOML as sorted dotted keys and values.
pub fn flat_config(toml_text: &str) -> anyhow::Result<Vec<(String, Value)>> {
    let table: Table = toml_text.parse().context("the configuration is not TOML")?;
    let mut out = leaves(&table);
    out.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(out)
}

impl Row {
    /// The row of a stored run.
    pub fn from_record(record: &RunRecord) -> anyhow::Result<Row> {
        Ok(Row {
            scene: record.scene.clone(),
            vtq_version: record.vtq_version.clone(),
            config: flat_config(&record.config)
                .with_context(|| format!("result {}", record.key))?,
            status: record.status.name().to_string(),
            error: record.error.clone().unwrap_or_default(),
            stats: record.stats().cloned(),
            tier: record.tier,
            key: record.key.clone(),
        })
    }

    /// The row of a sweep point with no result.
    pub fn missing(
        scene: &str,
        vtq_version: &str,
        (config_toml, tier): (&str, Tier),
        key: &str,
    ) -> anyhow::Result<Row> {
        Ok(Row {
            scene: scene.to_string(),
            vtq_version: vtq_version.to_string(),
            config: flat_config(config_toml)?,
            status: MISSING.to_string(),
            error: String::new(),
            stats: None,
            tier,
            key: key.to_string(),
        })
    }

    /// The value of configuration key `key`.
    fn value(&self, key: &str) -> Option<&Value> {
        self.config
            .binary_search_by(|(k, _)| k.as_str().cmp(key))
            .ok()
            .map(|i| &self.config[i].1)
    }
}

/// Orders two configuration values: numbers by value, then booleans, then strings, then
/// anything else by its TOML text; a missing value first.
fn compare_values(a: Option<&Value>, b: Option<&Value>) -> Ordering {
    let rank = |v: &Value| match v {
        Value::Integer(_) | Value::Float(_) => 0,
        Value::Boolean(_) => 1,
        Value::String(_) => 2,
        _ => 3,
    };
    let number = |v: &Value| match v {
        Value::Integer(i) => Some(*i as f64),
        Value::Float(f) => Some(*f),
        _ => None,
    };
    match (a, b) {
        (None, None) => Ordering::Equal,
        (None, Some(_)) => Ordering::Less,
        (Some(_), None) => Ordering::Greater,
        (Some(a), Some(b)) => rank(a).cmp(&rank(b)).then_with(|| match (a, b) {
            (Value::Boolean(x), Value::Boolean(y)) => x.cmp(y),
            (Value::String(x), Value::String(y)) => x.cmp(y),
            _ => match (number(a), number(b)) {
                (Some(x), Some(y)) => x.total_cmp(&y),
                _ => a.to_string().cmp(&b.to_string()),
            },
        }),
    }
}

/// A JSON scalar as a cell (empty for null or absent).
fn json_cell(v: Option<&Json>) -> String {
    match v {
        None | Some(Json::Null) => String::new(),
        Some(Json::String(s)) => s.clone(),
        Some(other) => other.to_string(),
    }
}

/// The headline statistic columns' names, in order.
fn stat_columns() -> Vec<String> {
    let mut names: Vec<String> = DIRECT.iter().map(|(n, _)| n.to_string()).collect();
    names.push("treelet_fill".into());
    names.push("sm_finish_min".into());
    names.push("sm_finish_mean".into());
    names.push("intersection_tests".into());
    names.extend(PHASES.iter().map(|p| format!("{p}_share")));
    names.extend(PHASES.iter().map(|p| format!("{p}_test_share")));
    names.extend((1..=DECILES).map(|d| format!("miss_rate_d{d}")));
    names.extend((1..=DECILES).map(|d| format!("miss_rate_pf_d{d}")));
    names.extend(ENERGY.iter().map(|n| n.to_string()));
    names.extend(
        Components::default()
            .named()
            .iter()
            .map(|(c, _)| format!("energy_{c}_mj")),
    );
    names
}

/// The energy columns before the components' (`energy_<component>_mj`): the run's energy under
/// its `energy.coefficients`, computed from its counters (so results stored before the energy
/// model get them too; docs/energy.md).
const ENERGY: [&str; 7] = [
    "energy_coefficients",
    "energy_mj",
    "energy_power_w",
    "energy_nj_per_ray",
    "energy_edp_j_s",
    "energy_time_share",
    "energy_virtualization_share",
];

/// The energy cells of one statistics JSON ([`ENERGY`], then the components), empty when the
/// statistics cannot be evaluated.
fn energy_cells(stats: &Json) -> Vec<String> {
    let report = stats_config(stats).and_then(|cfg| EnergyReport::of_stats(stats, &cfg));
    match report {
        Ok(r) => [
            r.coefficients.clone(),
            r.total_mj.to_string(),
            r.average_power_w.to_string(),
            r.nj_per_ray.to_string(),
            r.edp_j_s.to_string(),
            r.time_share.to_string(),
            r.virtualization_share.to_string(),
        ]
        .into_iter()
        .chain(r.components.named().iter().map(|(_, v)| v.to_string()))
        .collect(),
        Err(_) => vec![String::new(); ENERGY.len() + Components::default().named().len()],
    }
}

/// The shares of `field` over the three phases, as cells (empty when absent or all zero).
fn phase_shares(stats: &Json, field: &str) -> Vec<String> {
    let values: Vec<Option<u64>> = PHASES
        .iter()
        .map(|p| stats.pointer(&format!("/phases/{p}/{field}"))?.as_u64())
        .collect();
    let total: u64 = values.iter().flatten().sum();
    values
        .into_iter()
        .map(|v| match v {
            Some(v) if total > 0 => (v as f64 / total as f64).to_string(),
            _ => String::new(),
        })
        .collect()
}

/// The headline statistic cells of one statistics JSON, in [`stat_columns`] order.
fn stat_cells(stats: &Json) -> Vec<String> {
    let mut cells: Vec<String> = DIRECT
        .iter()
        .map(|(_, pointer)| json_cell(stats.pointer(pointer)))
        .collect();
    let tests = stats
        .pointer("/rt/tests")
        .and_then(Json::as_object)
        .map(|t| t.values().filter_map(Json::as_u64).sum::<u64>());
    cells.push(json_cell(stats.pointer("/bvh/treelet_fill")));
    let finish: Vec<u64> = stats
        .pointer("/sm_finish_cycles")
        .and_then(Json::as_array)
        .map(|v| v.iter().filter_map(Json::as_u64).collect())
        .unwrap_or_default();
    if finish.is_empty() {
        cells.extend([String::new(), String::new()]);
    } else {
        let min = finish.iter().min().copied().unwrap_or(0);
        let mean = finish.iter().sum::<u64>() as f64 / finish.len() as f64;
        cells.extend([min.to_string(), mean.to_string()]);
    }
    cells.push(tests.map_or_else(String::new, |t| t.to_string()));
    match PHASES.map(|p| stored_estimate(stats, &format!("{p}_share"))) {
        [Some(a), Some(b), Some(c)] => cells.extend([a, b, c].map(|e| e.value.to_string())),
        _ => cells.extend(phase_shares(stats, "cycles")),
    }
    cells.extend(phase_shares(stats, "intersection_tests"));
    for key in [
        "/bvh_l1_miss_rate_deciles",
        "/bvh_l1_miss_rate_deciles_with_prefetches",
    ] {
        let deciles = stats.pointer(key).and_then(Json::as_array);
        for d in 0..DECILES {
            cells.push(json_cell(deciles.and_then(|v| v.get(d))));
        }
    }
    cells.extend(energy_cells(stats));
    cells
}

/// A table: a header and rows of cells.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CollectedTable {
    /// Column names.
    pub header: Vec<String>,
    /// Cells, one row per run.
    pub rows: Vec<Vec<String>>,
}

/// The interval columns of a table with sampled runs: `<estimate>_lo` and `<estimate>_hi`, the
/// 95% interval of each [`ESTIMATED`] value (empty for full detail's exact rows and for an
/// estimate from one replicate).
fn interval_columns() -> Vec<String> {
    ESTIMATED
        .iter()
        .flat_map(|e| [format!("{e}_lo"), format!("{e}_hi")])
        .collect()
}

/// The interval cells of one statistics JSON, in [`interval_columns`] order.
fn interval_cells(stats: Option<&Json>) -> Vec<String> {
    ESTIMATED
        .iter()
        .flat_map(|name| {
            match stats
                .and_then(|s| stored_estimate(s, name))
                .and_then(|e| e.interval())
            {
                Some((lo, hi)) => [lo.to_string(), hi.to_string()],
                None => [String::new(), String::new()],
            }
        })
        .collect()
}

/// The table of `rows`: columns `scene`, `vtq_version` (when the rows differ in it), every
/// configuration key whose value differs between the rows (sorted), `status`, `tier` (when
/// a row is sampled), the headline statistics (a sampled row's estimates), the 95% intervals
/// of the estimates ([`interval_columns`], when a row is sampled), `error` and `key`; rows
/// sorted by scene, the swept values, the tier and key.
pub fn table(mut rows: Vec<Row>) -> CollectedTable {
    let sampled = rows.iter().any(|r| r.tier == Tier::Sampled);
    let mut keys: Vec<&str> = rows
        .iter()
        .flat_map(|r| r.config.iter().map(|(k, _)| k.as_str()))
        .collect();
    keys.sort_unstable();
    keys.dedup();
    let swept: Vec<String> = keys
        .into_iter()
        .filter(|k| {
            let first = rows.first().and_then(|r| r.value(k));
            rows.iter().any(|r| r.value(k) != first)
        })
        .map(str::to_string)
        .collect();
    let versions_differ = rows
        .windows(2)
        .any(|w| w[0].vtq_version != w[1].vtq_version);
    rows.sort_by(|a, b| {
        a.scene
            .cmp(&b.scene)
            .then_with(|| {
                swept
                    .iter()
                    .map(|k| compare_values(a.value(k), b.value(k)))
                    .find(|o| o.is_ne())
                    .unwrap_or(Ordering::Equal)
            })
            .then_with(|| a.vtq_version.cmp(&b.vtq_version))
            .then_with(|| a.tier.name().cmp(b.tier.name()))
            .then_with(|| a.key.cmp(&b.key))
    });
    let mut header = vec!["scene".to_string()];
    if versions_differ {
        header.push("vtq_version".into());
    }
    header.extend(swept.iter().cloned());
    header.push("status".into());
    if sampled {
        header.push("tier".into());
    }
    let stats_columns = stat_columns();
    header.extend(stats_columns.iter().cloned());
    if sampled {
        header.extend(interval_columns());
    }
    header.push("error".into());
    header.push("key".into());
    let cells = rows
        .iter()
        .map(|r| {
            let mut row = vec![r.scene.clone()];
            if versions_differ {
                row.push(r.vtq_version.clone());
            }
            row.extend(
                swept
                    .iter()
                    .map(|k| r.value(k).map(value_text).unwrap_or_default()),
            );
            row.push(r.status.clone());
            if sampled {
                row.push(r.tier.name().to_string());
            }
            match &r.stats {
                Some(stats) => row.extend(stat_cells(stats)),
                None => row.extend(stats_columns.iter().map(|_| String::new())),
            }
            if sampled {
                row.extend(interval_cells(r.stats.as_ref()));
            }
            row.push(r.error.clone());
            row.push(r.key.clone());
            row
        })
        .collect();
    CollectedTable {
        header,
        rows: cells,
    }
}

impl CollectedTable {
    /// The table as CSV text (RFC 4180 quoting where a cell needs it).
    pub fn to_csv(&self) -> anyhow::Result<String> {
        let mut w = csv::Writer::from_writer(Vec::new());
        w.write_record(&self.header)?;
        for row in &self.rows {
            w.write_record(row)?;
        }
        let bytes = w.into_inner().context("writing the CSV")?;
        String::from_utf8(bytes).context("the CSV is not UTF-8")
    }

    /// Writes the table as CSV to `path` (atomically).
    pub fn write_csv(&self, path: &Path) -> anyhow::Result<()> {
        crate::model::atomic_file::write_atomic(path, self.to_csv()?.as_bytes())
            .map_err(anyhow::Error::msg)
    }

    /// How many rows have each status, as `N ok, N failed, N missing` (only the non-zero
    /// ones).
    pub fn status_summary(&self) -> String {
        let Some(col) = self.header.iter().position(|h| h == "status") else {
            return String::new();
        };
        let mut parts = Vec::new();
        for status in ["ok", "failed", MISSING] {
            let n = self.rows.iter().filter(|r| r[col] == status).count();
            if n > 0 {
                parts.push(format!("{n} {status}"));
            }
        }
        parts.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(scene: &str, config: &str, status: &str, stats: Option<Json>) -> Row {
        Row {
            scene: scene.into(),
            vtq_version: "1".into(),
            config: flat_config(config).unwrap(),
            status: status.into(),
            error: if status == "failed" {
                "bad, \"very\" bad".into()
            } else {
                String::new()
            },
            stats,
            tier: Tier::Full,
            key: format!("k-{scene}-{}", config.len()),
        }
    }

    #[test]
    fn swept_keys_are_the_varying_ones_and_rows_sort_by_value() {
        let stats = serde_json::json!({
            "cycles": 100, "simt_efficiency": 0.5, "rt": {"tests": {"a": 3, "b": 4}},
            "phases": {"initial": {"cycles": 1, "intersection_tests": 2},
                       "treelet_stationary": {"cycles": 3, "intersection_tests": 6},
                       "ray_stationary": {"cycles": 0, "intersection_tests": 0}},
            "queues": {"repacks": 7},
            "bvh": {"bvh_bytes": 4096, "treelet_fill": 0.5},
            "virtualization": {"restore_cycles": 11},
            "sm_finish_cycles": [90, 100, 95, 99],
            "bvh_l1_miss_rate_deciles": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]
        });
        let rows = vec![
            row("wknd", "[hw]\nx = 128\ny = 1\n", "ok", Some(stats.clone())),
            row("wknd", "[hw]\nx = 64\ny = 1\n", "failed", None),
            row("cornell", "[hw]\nx = 128\ny = 1\n", MISSING, None),
        ];
        let t = table(rows);
        let col = |name: &str| t.header.iter().position(|h| h == name).unwrap();
        assert_eq!(&t.header[..3], ["scene", "hw.x", "status"]);
        assert!(!t.header.contains(&"hw.y".to_string()));
        let cells: Vec<(&str, &str)> = t
            .rows
            .iter()
            .map(|r| (r[0].as_str(), r[1].as_str()))
            .collect();
        // 64 sorts before 128 (numbers by value, not as text).
        assert_eq!(cells, [("cornell", "128"), ("wknd", "64"), ("wknd", "128")]);
        let ok = &t.rows[2];
        assert_eq!(ok[col("cycles")], "100");
        assert_eq!(ok[col("repacks")], "7");
        assert_eq!(ok[col("intersection_tests")], "7");
        assert_eq!(ok[col("initial_share")], "0.25");
        assert_eq!(ok[col("ray_stationary_share")], "0");
        assert_eq!(ok[col("treelet_stationary_test_share")], "0.75");
        assert_eq!(ok[col("bvh_bytes")], "4096");
        assert_eq!(ok[col("treelet_fill")], "0.5");
        assert_eq!(ok[col("cta_restore_cycles")], "11");
        assert_eq!(ok[col("sm_finish_min")], "90");
        assert_eq!(ok[col("sm_finish_mean")], "96");
        assert_eq!(ok[col("miss_rate_d1")], "0.1");
        assert_eq!(ok[col("miss_rate_d10")], "1.0");
        assert_eq!(ok[col("rays")], "");
        assert_eq!(t.rows[0][col("status")], MISSING);
        assert_eq!(t.status_summary(), "1 ok, 1 failed, 1 missing");
        let csv = t.to_csv().unwrap();
        assert!(csv.contains("\"bad, \"\"very\"\" bad\""), "{csv}");
        assert_eq!(csv.lines().count(), 4);
    }
}
