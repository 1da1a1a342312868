//! `vtq sweep --sample` and `vtq reproduce --sample`: the sampled tier where users run many
//! simulations. Estimates are stored apart from full detail's results of the same points, the
//! collected table gets a tier column and each estimate's 95% interval, a sampled sweep resumes
//! like an exact one, stored speedups pair replicates as `vtq compare --sample` does, and the
//! reproduction draws its figures with error bars and says on the page that they are estimates.

mod common;

use std::path::{Path, PathBuf};

use common::vtq_ok_in as vtq;
use vtq_sim::estimate::sample::stored::{is_sampled, stored_estimate, stored_speedup};

/// A fresh scratch folder.
fn scratch(name: &str) -> PathBuf {
    common::fresh_dir(&format!("sampled-{name}"))
}

/// Cornell at 64x64 with stratified samples (no stripes: their speedups pair replicates), as
/// `vtq` options.
const CORNELL_64: [&str; 8] = [
    "--scene",
    "cornell",
    "--set",
    "width=64",
    "--set",
    "height=64",
    "--set",
    "sample.stripes=false",
];

/// The stored result files of `results`.
fn result_files(results: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(results.join("runs"))
        .map(|d| d.map(|e| e.unwrap().path()).collect())
        .unwrap_or_default();
    files.retain(|p| p.extension().is_some_and(|x| x == "json"));
    files.sort();
    files
}

/// The statistics of a stored result file.
fn stats(path: &Path) -> serde_json::Value {
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    record["result"]["stats"].clone()
}

/// The sweep of two designs of [`CORNELL_64`] into `results`, sampled at `sample` or exact.
fn sweep(dir: &Path, results: &str, sample: Option<&str>) -> String {
    let mut args = vec!["sweep", "--config", "baseline", "--config", "vtq"];
    args.extend(CORNELL_64);
    args.extend(["--results", results, "--jobs", "2"]);
    if let Some(s) = sample {
        args.extend(["--sample", s]);
    }
    vtq(dir, &args)
}

#[test]
fn sampled_sweeps_store_estimates_apart_and_resume() {
    let dir = scratch("sweep");
    let results = dir.join("results");
    sweep(&dir, "results", None);
    assert_eq!(result_files(&results).len(), 2);
    let log = sweep(&dir, "results", Some("1/4x2"));
    assert!(log.contains("ok (sampled, 95% intervals)"), "{log}");
    assert!(
        !log.contains("note:"),
        "an explicit fraction has no notes: {log}"
    );
    // Two exact and two sampled results of the same points: different store entries.
    let files = result_files(&results);
    assert_eq!(files.len(), 4);
    let sampled: Vec<&PathBuf> = files.iter().filter(|f| is_sampled(&stats(f))).collect();
    assert_eq!(sampled.len(), 2);
    for f in &sampled {
        let s = stats(f);
        let cycles = stored_estimate(&s, "cycles").unwrap();
        let (lo, hi) = cycles.interval().expect("two replicates give an interval");
        assert!(lo < cycles.value && cycles.value < hi, "{s}");
        assert_eq!(s["cycles"].as_f64(), Some(cycles.value));
    }

    // Rerun: nothing to do. A lost sampled result is run again, alone.
    let again = sweep(&dir, "results", Some("1/4x2"));
    assert!(
        again.contains("ran 0 (0 ok, 0 failed), skipped 2"),
        "{again}"
    );
    std::fs::remove_file(sampled[0]).unwrap();
    let again = sweep(&dir, "results", Some("1/4x2"));
    assert!(
        again.contains("1 already done") && again.contains("ran 1 (1 ok, 0 failed)"),
        "{again}"
    );
    assert_eq!(result_files(&results).len(), 4);

    // The table of everything stored: a tier column and each estimate's interval, empty for
    // the exact rows.
    vtq(
        &dir,
        &["sweep", "--collect", "results", "--out", "table.csv"],
    );
    let csv = std::fs::read_to_string(dir.join("table.csv")).unwrap();
    let mut reader = csv::Reader::from_reader(csv.as_bytes());
    let header: Vec<String> = reader.headers().unwrap().iter().map(String::from).collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("no {name} in {header:?}"))
    };
    let (tier, cycles, lo, hi) = (
        col("tier"),
        col("cycles"),
        col("cycles_lo"),
        col("cycles_hi"),
    );
    col("simt_efficiency_lo");
    col("treelet_stationary_share_hi");
    let rows: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 4);
    for row in &rows {
        match &row[tier] {
            "sampled" => {
                let v: f64 = row[cycles].parse().unwrap();
                let (l, h): (f64, f64) = (row[lo].parse().unwrap(), row[hi].parse().unwrap());
                assert!(l < v && v < h, "{row:?}");
            }
            "full" => assert!(row[lo].is_empty() && row[hi].is_empty(), "{row:?}"),
            other => panic!("tier {other}"),
        }
    }

    // A named point below the frame it was measured at: the note, once for both points.
    let named = sweep(&dir, "named", Some("default"));
    let notes: Vec<&str> = named.lines().filter(|l| l.starts_with("note:")).collect();
    assert_eq!(notes.len(), 1, "{named}");
    assert!(
        notes[0].contains("measured at 1024x1024") && notes[0].contains("this frame is 64x64"),
        "{named}"
    );

    // The stored estimates pair replicates into the speedup `vtq compare --sample` prints.
    let mut args = vec!["compare", "--designs", "baseline,vtq"];
    args.extend(CORNELL_64);
    args.extend(["--sample", "1/4x2", "--json", "compare.json"]);
    let compare = vtq(&dir, &args);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("compare.json")).unwrap())
            .unwrap_or_else(|e| panic!("{e}: {compare}"));
    let printed = &json["designs"][1]["speedup"];
    // The sampled result of the design whose `mode.kind` is `kind`.
    let by_kind = |kind: &str| {
        result_files(&results)
            .iter()
            .map(|f| {
                let text = std::fs::read_to_string(f).unwrap();
                serde_json::from_str::<serde_json::Value>(&text).unwrap()
            })
            .find(|r| {
                is_sampled(&r["result"]["stats"])
                    && r["config"]
                        .as_str()
                        .unwrap()
                        .contains(&format!("kind = \"{kind}\""))
            })
            .map(|r| r["result"]["stats"].clone())
            .unwrap()
    };
    let speedup = stored_speedup(&by_kind("baseline"), &by_kind("queues")).unwrap();
    assert!(
        (speedup.value - printed["value"].as_f64().unwrap()).abs() < 1e-12,
        "stored {speedup:?}, compare {printed}"
    );
    assert!(
        (speedup.half_width.unwrap() - printed["half_width"].as_f64().unwrap()).abs() < 1e-12,
        "stored {speedup:?}, compare {printed}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_sampled_reproduction_draws_estimates_with_error_bars() {
    let dir = scratch("reproduce");
    let out = dir.join("page");
    let mut args = vec!["reproduce", "--out", out.to_str().unwrap(), "--jobs", "2"];
    args.extend(CORNELL_64);
    args.extend(["--sample", "1/4x2"]);
    let log = vtq(&dir, &args);
    assert!(log.contains("ok (sampled, 95% intervals)"), "{log}");
    let md = std::fs::read_to_string(out.join("index.md")).unwrap();
    assert!(md.contains("Estimates, not full detail: every run"), "{md}");
    assert!(
        md.contains("--sample 1/4x2"),
        "the rerun command samples too: {md}"
    );
    // Speedups carry their intervals in the tables (the scene's row; the mean has none).
    for table in ["fig10", "fig12", "fig13", "fig16", "cause-g-mechanisms"] {
        let csv = std::fs::read_to_string(out.join(format!("tables/{table}.csv"))).unwrap();
        let scene_row = csv.lines().nth(1).unwrap();
        assert!(
            scene_row.starts_with("cornell,") && scene_row.contains(" ["),
            "{table}: {csv}"
        );
    }
    // Figures of statistics the tier does not estimate are left out, saying why, and the
    // command still succeeds.
    for (id, needs) in [
        ("fig11", "tenth of the run"),
        ("fig15", "intersection tests"),
        ("fig17", "energy"),
        ("ext-workload-share-spp", "intersection tests"),
    ] {
        assert!(!out.join(format!("figures/{id}.svg")).exists(), "{id}");
        assert!(md.contains(needs), "{id}: {md}");
    }
    assert!(out.join("figures/fig10.svg").exists());
    // Nothing runs again, and full detail of the same points is other entries.
    let again = vtq(&dir, &args);
    assert!(again.contains("ran 0"), "{again}");
    std::fs::remove_dir_all(&dir).unwrap();
}
