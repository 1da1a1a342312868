//! End-to-end tests of `vtq compare` (designs side by side on the cycle-exact simulator) and
//! `vtq bench --sim` (simulator speed against the functional path tracer), on tiny images of
//! the built-in `wknd` scene.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;
use vtq_sim::model::gpu::HOST_DEPENDENT_KEYS;

/// A fresh temporary folder for one test.
fn temp_dir(test: &str) -> PathBuf {
    common::fresh_dir(&format!("cli-compare-{test}"))
}

/// The workspace root (configs/ lives there).
fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Runs `vtq` from `dir` (so the built-in configurations must not need the working directory).
fn vtq_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vtq"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the vtq binary runs")
}

/// The options of a tiny wknd workload without the BVH cache.
const TINY: [&str; 7] = [
    "--scene",
    "wknd",
    "--set",
    "width=32",
    "--set",
    "height=32",
    "--no-cache",
];

/// Assert the command failed with exit code 1 and exactly one `error: ...` line (the last)
/// mentioning `needle`.
fn assert_one_line_error(out: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "panic: {stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "stderr: {stderr}");
    assert_eq!(stderr.trim_end().lines().last(), Some(errors[0]));
    assert!(
        errors[0].contains(needle),
        "'{needle}' not in: {}",
        errors[0]
    );
}

/// Runs `vtq compare` in `dir` on the tiny workload with `extra` options, writing `--json json`;
/// checks it succeeded and returns its stdout and the JSON document.
fn compare_ok(dir: &Path, extra: &[&str], json: &Path) -> (String, Value) {
    let mut args = vec!["compare"];
    args.extend_from_slice(extra);
    args.extend(TINY);
    args.extend(["--json", json.to_str().unwrap()]);
    let out = vtq_in(dir, &args);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "stdout: {stdout}\nstderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let doc = serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
    (stdout, doc)
}

/// The table row of `design`, split into columns.
fn row<'a>(stdout: &'a str, design: &str) -> Vec<&'a str> {
    let line = stdout
        .lines()
        .find(|l| l.split_whitespace().next() == Some(design))
        .unwrap_or_else(|| panic!("no row for {design} in:\n{stdout}"));
    line.split_whitespace().collect()
}

/// A design's statistics from the `--json` file, without the host-dependent keys.
fn comparable(entry: &Value) -> Value {
    let mut stats = entry["stats"].clone();
    let map = stats.as_object_mut().expect("stats is an object");
    for k in HOST_DEPENDENT_KEYS {
        assert!(map.remove(k).is_some(), "stats lack {k}");
    }
    stats
}

#[test]
fn compare_baseline_and_prefetch() {
    let dir = temp_dir("two");
    let json = dir.join("cmp.json");
    let (stdout, doc) = compare_ok(&dir, &["--designs", "baseline,prefetch"], &json);

    let header = stdout
        .lines()
        .find(|l| l.starts_with("design"))
        .expect("a table header");
    for column in [
        "cycles",
        "speedup",
        "energy",
        "BVH L1 miss",
        "SIMT eff.",
        "phases",
        "wall s",
    ] {
        assert!(header.contains(column), "header lacks {column}: {header}");
    }
    let base = row(&stdout, "baseline");
    let pre = row(&stdout, "prefetch");
    // design, cycles, speedup, energy, miss rate, SIMT efficiency, phase split, wall seconds.
    assert_eq!(base.len(), 8, "{base:?}");
    assert_eq!(pre.len(), 8, "{pre:?}");
    assert_eq!(base[2], "1.00", "the baseline's speedup over itself");
    assert_eq!(base[3], "1.000", "the baseline's energy over itself");
    // The baseline has only ray-stationary traversal (docs/stats.md).
    assert_eq!(base[6], "0.0/0.0/100.0");
    assert!(
        stdout.contains("images: identical"),
        "no identical-image line in:\n{stdout}"
    );

    assert_eq!(doc["scene"], "wknd");
    assert_eq!(doc["images_identical"], true);
    let designs = doc["designs"].as_array().expect("a designs array");
    let names: Vec<&str> = designs
        .iter()
        .map(|d| d["design"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["baseline", "prefetch"]);
    let (b, p) = (&designs[0]["stats"], &designs[1]["stats"]);
    assert_eq!(b["mode"], "baseline");
    assert_eq!(p["mode"], "prefetch");
    // Same workload: the same rays, and every pixel traced at least one.
    assert_eq!(b["rays"], p["rays"]);
    assert!(b["rays"].as_u64().unwrap() >= 32 * 32);
    // The table shows the JSON's numbers; the speedup is baseline cycles / prefetch cycles.
    let (bc, pc) = (b["cycles"].as_u64().unwrap(), p["cycles"].as_u64().unwrap());
    assert_eq!(base[1], bc.to_string());
    assert_eq!(pre[1], pc.to_string());
    assert_eq!(pre[2], format!("{:.2}", bc as f64 / pc as f64));
    assert_eq!(designs[0]["speedup"].as_f64(), Some(1.0));
    // The energy column is prefetch's energy over the baseline's (docs/energy.md), and an
    // energy table follows with the identity's terms.
    let energy = |s: &Value| s["energy"]["total_mj"].as_f64().unwrap();
    assert_eq!(pre[3], format!("{:.3}", energy(p) / energy(b)));
    assert_eq!(
        designs[1]["energy_ratio"].as_f64(),
        Some(energy(p) / energy(b))
    );
    assert!(
        stdout.contains("energy, coefficients accelwattch-ptx"),
        "{stdout}"
    );
    assert!(stdout.contains("fT+(1-f)D"), "{stdout}");
    assert_eq!(
        pre[5],
        format!("{:.3}", p["simt_efficiency"].as_f64().unwrap())
    );
    assert!(p["prefetches_issued"].as_u64().unwrap() > 0);
    assert_eq!(b["prefetches_issued"], 0);
}

#[test]
fn config_file_design_matches_the_built_in_on_any_thread_count() {
    let dir = temp_dir("path");
    let json = dir.join("cmp.json");
    let file = workspace_root().join("configs/designs/prefetch/config.toml");
    let designs = format!("prefetch,{}", file.display());
    for jobs in ["1", "2"] {
        let (stdout, doc) = compare_ok(&dir, &["--designs", &designs, "--jobs", jobs], &json);
        // Without the baseline, speedups are over the first design.
        assert_eq!(row(&stdout, "prefetch")[2], "1.00");
        let designs = doc["designs"].as_array().unwrap();
        assert_eq!(designs.len(), 2);
        assert_eq!(designs[1]["source"], file.display().to_string());
        assert_eq!(
            comparable(&designs[0]),
            comparable(&designs[1]),
            "the built-in prefetch design and its file simulate identically (--jobs {jobs})"
        );
    }
}

/// Asserts `vtq compare --scene <scene> --designs <designs>`, then `extra`, run in `dir`, fails
/// with one error line mentioning `needle` ([`assert_one_line_error`]).
fn assert_compare_fails(dir: &Path, scene: &str, designs: &str, extra: &[&str], needle: &str) {
    let mut args = vec!["compare", "--scene", scene, "--designs", designs];
    args.extend(extra);
    assert_one_line_error(&vtq_in(dir, &args), needle);
}

#[test]
fn compare_errors_are_one_line() {
    let dir = temp_dir("errors");
    assert_compare_fails(
        &dir,
        "wknd",
        "baseline,fastest",
        &[],
        "unknown design 'fastest'",
    );
    assert_compare_fails(&dir, "no-such-scene", "baseline", &[], "no-such-scene");
    assert_compare_fails(&dir, "wknd", "missing.toml", &[], "missing.toml");

    // A design whose file sets another image cannot be compared pixel for pixel.
    let small = dir.join("small.toml");
    std::fs::write(&small, "[workload]\nwidth = 8\nheight = 8\n").unwrap();
    let designs = format!("baseline,{}", small.display());
    assert_compare_fails(
        &dir,
        "wknd",
        &designs,
        &["--no-cache"],
        "different workloads",
    );
}

#[test]
fn bench_sim_prints_the_ratios() {
    let dir = temp_dir("bench");
    let out = vtq_in(
        &dir,
        &[
            "bench",
            "--sim",
            "--scene",
            "wknd",
            "--width",
            "16",
            "--height",
            "16",
            "--threads",
            "1,3",
        ],
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "stdout: {stdout}\nstderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    for field in [
        "rays:",
        "render wall:",
        "sim, 1 thread(s):",
        "sim, 3 thread(s):",
        "simulated rays/s",
        "slowdown",
        "the first count",
        "every thread count gave identical statistics",
        ">= 100,000 simulated rays/s",
        "< 10x",
    ] {
        assert!(stdout.contains(field), "no '{field}' in:\n{stdout}");
    }
    // Each target line ends in a verdict.
    let verdicts = stdout
        .lines()
        .filter(|l| l.starts_with("target"))
        .filter(|l| l.ends_with("pass") || l.ends_with("FAIL"))
        .count();
    assert_eq!(verdicts, 2, "two target verdicts in:\n{stdout}");
    // The simulated image is the functional tracer's.
    assert!(stdout.contains("image: identical"), "{stdout}");
}

#[test]
fn bench_config_options_need_sim() {
    let dir = temp_dir("bench-err");
    let out = vtq_in(&dir, &["bench", "--scene", "wknd", "--set", "gpu.sms=2"]);
    assert_one_line_error(&out, "--sim");
}

/// The default designs (baseline, prefetch, VTQ) all run, render the identical image and the VTQ
/// row reports its treelet phases.
#[test]
fn default_designs_include_vtq() {
    let dir = temp_dir("vtq");
    let json = dir.join("all.json");
    let (stdout, doc) = compare_ok(&dir, &[], &json);
    for design in ["baseline", "prefetch", "vtq"] {
        row(&stdout, design);
    }
    assert!(stdout.contains("images: identical"), "{stdout}");
    let vtq = &doc["designs"][2];
    assert_eq!(vtq["design"], "vtq");
    assert_eq!(vtq["stats"]["mode"], "queues");
    assert!(vtq["stats"]["cta_suspends"].as_u64().unwrap() > 0);
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--config NAME` is the built-in design even where a file of that name sits in the working
/// directory (the `vtq` binary beside its user), as `--designs NAME` is; `./NAME` is the file.
#[test]
fn a_design_name_is_the_built_in_whatever_the_working_directory_holds() {
    let dir = temp_dir("shadow");
    let clean = vtq_in(&dir, &["area", "--config", "vtq"]);
    assert!(clean.status.success(), "{clean:?}");
    std::fs::write(dir.join("vtq"), [0xff_u8, 0xfe, 0x00, 0x7f]).unwrap();
    let shadowed = vtq_in(&dir, &["area", "--config", "vtq"]);
    assert!(shadowed.status.success(), "{shadowed:?}");
    assert_eq!(shadowed.stdout, clean.stdout);
    let file = vtq_in(&dir, &["area", "--config", "./vtq"]);
    assert_one_line_error(&file, "cannot read config file ./vtq");
}

/// `vtq designs` lists the registry from any folder, names what each design puts beside the
/// SMs and what it changes, and refuses an unknown design with the choices.
#[test]
fn designs_lists_the_registry_and_refuses_unknown_names() {
    let dir = temp_dir("designs");
    let out = vtq_in(&dir, &["designs"]);
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8_lossy(&out.stdout);
    for name in ["baseline", "prefetch", "vtq", "vtq-prefetch"] {
        assert!(
            text.contains(&format!("\n{name}: ")) || text.starts_with(&format!("{name}: ")),
            "{text}"
        );
    }
    assert!(text.contains("mode.kind = \"queues\""), "{text}");
    assert!(text.contains("treelet_controller"), "{text}");
    let file = workspace_root().join("configs/designs/queues-repack16/config.toml");
    let out = vtq_in(&dir, &["designs", "--design", file.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("hw.repack_threshold = 16"), "{text}");
    // A design folder's file is named after its folder and carries the design's summary.
    assert!(text.starts_with("queues-repack16: ablation"), "{text}");
    let out = vtq_in(&dir, &["designs", "--design", "fastest"]);
    assert_one_line_error(&out, "unknown design 'fastest'");
    // --doc adds the design's documentation, its folder's README.md.
    let out = vtq_in(&dir, &["designs", "--design", "vtq", "--doc"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("    # vtq: Virtualized Treelet Queues"),
        "{text}"
    );
    // `vtq sim --config` takes a design's name from any folder, and simulates it as its file.
    let mut stats = Vec::new();
    for config in [
        "vtq".to_string(),
        workspace_root()
            .join("configs/designs/vtq/config.toml")
            .display()
            .to_string(),
    ] {
        let json = dir.join("sim.json");
        let mut args = vec!["sim", "--config", &config, "--out", json.to_str().unwrap()];
        args.extend(common::TINY_CORNELL);
        let out = vtq_in(&dir, &args);
        assert!(out.status.success(), "{out:?}");
        let mut doc: Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        for key in HOST_DEPENDENT_KEYS {
            doc.as_object_mut().unwrap().remove(key);
        }
        assert_eq!(
            doc["config"]
                .as_str()
                .map(|c| c.contains("kind = \"queues\"")),
            Some(true)
        );
        stats.push(doc);
    }
    assert_eq!(stats[0], stats[1]);
    let json = dir.join("none.json");
    let out = vtq_in(
        &dir,
        &[
            "sim",
            "--scene",
            "cornell",
            "--config",
            "fastest",
            "--out",
            json.to_str().unwrap(),
        ],
    );
    assert_one_line_error(&out, "not a built-in design's name");
}

/// `--perturb 2` runs every design again with the DRAM latency one cycle up and one down: the
/// JSON's `perturbed` holds the unperturbed cycles first (the table's), the perturbed runs
/// equal `vtq compare` with `memory.dram_latency` set so, and the speedups pair runs by offset.
#[test]
fn compare_under_perturbation() {
    let dir = temp_dir("perturb");
    let json = dir.join("cmp.json");
    let (stdout, doc) = compare_ok(
        &dir,
        &["--designs", "baseline,prefetch", "--perturb", "2"],
        &json,
    );
    assert!(
        stdout.contains("under perturbation: 3 runs per design"),
        "{stdout}"
    );
    let entries = doc["designs"].as_array().unwrap();
    let cycles = |i: usize| -> Vec<f64> {
        entries[i]["perturbed"]["cycles"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c.as_f64().unwrap())
            .collect()
    };
    let (base, pre) = (cycles(0), cycles(1));
    assert_eq!(base.len(), 3);
    assert_eq!(base[0], entries[0]["stats"]["cycles"].as_f64().unwrap());
    assert_eq!(
        entries[0]["perturbed"]["offsets"],
        serde_json::json!([1, -1])
    );
    // The run one cycle up is `vtq compare` with that latency.
    let latency = vtq_sim::model::config::SimConfig::default()
        .memory
        .dram_latency
        + 1;
    let up = dir.join("up.json");
    let (_, up_doc) = compare_ok(
        &dir,
        &[
            "--designs",
            "baseline,prefetch",
            "--set",
            &format!("memory.dram_latency={latency}"),
        ],
        &up,
    );
    for (i, runs) in [&base, &pre].into_iter().enumerate() {
        let c = up_doc["designs"][i]["stats"]["cycles"].as_f64().unwrap();
        assert_eq!(runs[1], c, "design {i}");
    }
    let speedups: Vec<f64> = entries[1]["perturbed"]["speedups"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_f64().unwrap())
        .collect();
    for k in 0..3 {
        assert!((speedups[k] - base[k] / pre[k]).abs() < 1e-12);
    }
    assert!(entries[0]["perturbed"]["speedups"]
        .as_array()
        .unwrap()
        .is_empty());
    // Full detail only: with the sampled tier it is an error.
    let out = vtq_in(
        &dir,
        &[
            "compare",
            "--sample",
            "1/2x2",
            "--perturb",
            "2",
            "--scene",
            "wknd",
        ],
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--perturb"));
}
