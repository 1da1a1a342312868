//! docs/fidelity.md's commands: every experiment of `configs/experiments/` is a sweep file whose
//! points all validate, and `vtq figure5` prints the Figure 5 model (checked on a tiny image).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use vtq_sim::experiment::sweep::SweepSpec;

/// The workspace root (configs/ lives there).
fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the sim crate is in the workspace")
        .to_path_buf()
}

/// Every experiment expands from the workspace root (where docs/fidelity.md's commands run)
/// into points whose configurations validate: no run of a documented experiment fails on its
/// configuration.
#[test]
fn every_experiment_expands_into_valid_points() {
    let root = workspace_root();
    std::env::set_current_dir(&root).expect("cd to the workspace root");
    let dir = root.join("configs/experiments");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("configs/experiments exists")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 10, "{} experiments", files.len());
    for file in &files {
        let rel = file.strip_prefix(&root).expect("inside the root");
        let spec = SweepSpec::from_file(rel).unwrap_or_else(|e| panic!("{}: {e:#}", rel.display()));
        let points = spec
            .points()
            .unwrap_or_else(|e| panic!("{}: {e:#}", rel.display()));
        assert!(!points.is_empty(), "{}", rel.display());
        for p in &points {
            p.config
                .validate()
                .unwrap_or_else(|e| panic!("{}: {}: {e}", rel.display(), p.label));
        }
    }
}

/// `vtq figure5` on a 16 x 16 cornell image: batch sizes that are multiples of each other can
/// only share more treelets, one batch of every ray fetches each treelet once, and the JSON has
/// one row per batch size.
#[test]
fn figure5_prints_the_model_and_writes_json() {
    let dir = common::fresh_dir("figure5");
    let json = dir.join("f5.json");
    let out = Command::new(env!("CARGO_BIN_EXE_vtq"))
        .arg("figure5")
        .args(common::TINY_CORNELL)
        .args([
            "--set",
            "hw.treelet_bytes=512",
            "--rays",
            "1,32,1024,1000000",
            "--no-cache",
            "--json",
        ])
        .arg(&json)
        .output()
        .expect("vtq runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("concurrent rays") && text.contains("speedup"),
        "{text}"
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 4);
    let fetches: Vec<u64> = rows
        .iter()
        .map(|r| r["treelet_fetches"].as_u64().unwrap())
        .collect();
    assert!(fetches.windows(2).all(|w| w[1] <= w[0]), "{fetches:?}");
    let baseline = rows[0]["baseline_fetches"].as_u64().unwrap();
    assert!(rows
        .iter()
        .all(|r| r["baseline_fetches"].as_u64() == Some(baseline)));
    // One batch of every ray: each treelet it touches once, no more than the BVH has.
    let all = &rows[3];
    assert_eq!(all["batches"].as_u64(), Some(1));
    assert!(all["unique_treelets"].as_u64().unwrap() <= v["treelets"].as_u64().unwrap());
    assert!(all["speedup"].as_f64().unwrap() > rows[0]["speedup"].as_f64().unwrap());
    // A batch of zero rays is an error that says so.
    let bad = Command::new(env!("CARGO_BIN_EXE_vtq"))
        .args(["figure5", "--scene", "cornell", "--rays", "0"])
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("at least 1"));
    let _ = std::fs::remove_dir_all(&dir);
}
