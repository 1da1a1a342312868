//! Every command that writes files checks its outputs before the work: given a path it cannot
//! write (here one under a regular file, which fails for root too), it exits non-zero within a
//! moment with one `error:` line naming the path, before loading a scene, simulating or
//! fuzzing, and leaves no file behind.

mod common;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// A fresh scratch folder holding a regular file `plain`, under which nothing can be created.
fn scratch(test: &str) -> (PathBuf, PathBuf) {
    let dir = common::fresh_dir(&format!("outputs-{test}"));
    let plain = dir.join("plain");
    std::fs::write(&plain, b"not a folder").unwrap();
    (dir, plain)
}

/// The most a failed output check may take (it runs before any scene is loaded; generous for
/// a loaded 2-core machine running a debug binary).
const QUICK: Duration = Duration::from_secs(10);

/// Runs `vtq args` in `cwd` and asserts a quick failure with one error line naming `bad`,
/// and no sign of work on stdout (`work` are lines the work would print).
fn assert_fails_before_work(cwd: &Path, args: &[&str], bad: &Path, work: &[&str]) {
    let start = Instant::now();
    let (ok, stdout, stderr) = common::vtq_cli(cwd, args);
    let took = start.elapsed();
    assert!(!ok, "{args:?} succeeded: {stdout}{stderr}");
    assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{args:?}: {stderr}");
    assert!(
        errors[0].contains(&bad.display().to_string()),
        "{args:?}: the error does not name {}: {}",
        bad.display(),
        errors[0]
    );
    for needle in ["scene ", "bvh:"].iter().chain(work) {
        assert!(
            !stdout.lines().any(|l| l.starts_with(needle)),
            "{args:?} did work before failing ('{needle}'): {stdout}"
        );
    }
    assert!(took < QUICK, "{args:?} took {took:?} to fail");
}

/// `s` of a path.
fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn sim_checks_out_image_and_vcd() {
    let (dir, plain) = scratch("sim");
    let bad = plain.join("stats.json");
    assert_fails_before_work(
        &dir,
        &["sim", "--scene", "wknd", "--out", s(&bad)],
        &bad,
        &["sim:"],
    );
    // The acceptance case: a folder that does not exist is not created.
    let missing = dir.join("no/such/dir/x.json");
    assert_fails_before_work(
        &dir,
        &["sim", "--scene", "wknd", "--out", s(&missing)],
        &missing,
        &["sim:"],
    );
    assert!(!dir.join("no").exists());
    let good = dir.join("stats.json");
    for extra in [
        vec!["--image", s(&bad)],
        vec!["--ctas", s(&bad)],
        vec!["--vcd", s(&bad), "--vcd-cycles", "0..10"],
        vec!["--sample", "1/2x2", "--image", s(&bad)],
    ] {
        let mut args = vec!["sim", "--scene", "wknd", "--out", s(&good)];
        args.extend(extra);
        assert_fails_before_work(&dir, &args, &bad, &["sim"]);
    }
    assert!(!good.exists(), "the check leaves no file behind");
    let names: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert_eq!(names.len(), 1, "only `plain` is left: {names:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn compare_checks_json() {
    let (dir, plain) = scratch("compare");
    let bad = plain.join("c.json");
    assert_fails_before_work(
        &dir,
        &["compare", "--scene", "wknd", "--json", s(&bad)],
        &bad,
        &["compare:"],
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn render_checks_out_and_rays_out() {
    let (dir, plain) = scratch("render");
    let bad = plain.join("img.png");
    assert_fails_before_work(
        &dir,
        &["render", "--scene", "wknd", "--out", s(&bad)],
        &bad,
        &["render:"],
    );
    let bad_rays = plain.join("rays.csv");
    assert_fails_before_work(
        &dir,
        &[
            "render",
            "--scene",
            "wknd",
            "--out",
            s(&dir.join("ok.png")),
            "--rays-out",
            s(&bad_rays),
        ],
        &bad_rays,
        &["render:"],
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn accuracy_checks_its_folder() {
    let (dir, plain) = scratch("accuracy");
    let bad = plain.join("acc");
    assert_fails_before_work(
        &dir,
        &["accuracy", "--scene", "wknd", "--out", s(&bad)],
        &bad,
        &[],
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn reproduce_checks_out_and_results() {
    let (dir, plain) = scratch("reproduce");
    let bad = plain.join("page");
    assert_fails_before_work(
        &dir,
        &["reproduce", "--scene", "wknd", "--out", s(&bad)],
        &bad,
        &["reproduce:"],
    );
    let bad_results = plain.join("results");
    assert_fails_before_work(
        &dir,
        &[
            "reproduce",
            "--scene",
            "wknd",
            "--out",
            s(&dir.join("page")),
            "--results",
            s(&bad_results),
        ],
        &bad_results,
        &["reproduce:"],
    );
    assert!(!dir.join("page").exists(), "the check creates no folder");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn sweep_checks_results_script_and_table() {
    let (dir, plain) = scratch("sweep");
    let bad = plain.join("results");
    assert_fails_before_work(
        &dir,
        &["sweep", "--scene", "wknd", "--results", s(&bad)],
        &bad,
        &["sweep:"],
    );
    let bad_script = plain.join("job.sh");
    assert_fails_before_work(
        &dir,
        &[
            "sweep",
            "--scene",
            "wknd",
            "--results",
            s(&dir.join("results")),
            "--slurm",
            s(&bad_script),
        ],
        &bad_script,
        &["sweep:"],
    );
    let bad_table = plain.join("table.csv");
    assert_fails_before_work(
        &dir,
        &[
            "sweep",
            "--collect",
            s(&dir.join("results")),
            "--out",
            s(&bad_table),
        ],
        &bad_table,
        &["collect:"],
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn verilog_checks_its_folder() {
    let (dir, plain) = scratch("verilog");
    let bad = plain.join("rtl");
    assert_fails_before_work(&dir, &["verilog", "--out", s(&bad)], &bad, &["wrote"]);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn fuzz_checks_its_save_folder() {
    let (dir, plain) = scratch("fuzz");
    let bad = plain.join("failures");
    assert_fails_before_work(
        &dir,
        &["fuzz", "--cases", "10", "--save-dir", s(&bad)],
        &bad,
        &["fuzz:"],
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn trace_and_figure5_check_their_files() {
    let (dir, plain) = scratch("trace");
    let bad = plain.join("hits.csv");
    assert_fails_before_work(
        &dir,
        &[
            "trace",
            "--scene",
            "wknd",
            "--rays",
            s(&dir.join("rays.csv")),
            "--out",
            s(&bad),
        ],
        &bad,
        &["trace:"],
    );
    let bad_json = plain.join("fig5.json");
    assert_fails_before_work(
        &dir,
        &["figure5", "--scene", "wknd", "--json", s(&bad_json)],
        &bad_json,
        &["figure5"],
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Runs `vtq args` in `cwd`; returns (success, stdout, stderr).
fn run(cwd: &Path, args: &[&str]) -> (bool, String, String) {
    common::vtq_cli(cwd, args)
}

#[test]
fn a_figure_that_cannot_be_drawn_leaves_the_results_and_the_rest() {
    let (dir, _) = scratch("figure");
    let out = dir.join("page");
    // A folder where Figure 10's SVG goes: that chart cannot be written.
    std::fs::create_dir_all(out.join("figures/fig10.svg/x")).unwrap();
    let args = [
        "reproduce",
        "--out",
        s(&out),
        "--scene",
        "wknd",
        "--set",
        "width=16",
        "--set",
        "height=16",
        "--jobs",
        "2",
    ];
    let (ok, stdout, stderr) = run(&dir, &args);
    assert!(!ok, "{stdout}{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let last = stderr.lines().last().unwrap_or_default();
    assert!(
        last.starts_with("error: 1 figure(s) not drawn (Figure 10") && last.contains("fig10.svg"),
        "{stderr}"
    );
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(
        html.contains("Not drawn: "),
        "the page says which figure is missing"
    );
    for stem in ["fig05", "fig12", "fig16"] {
        assert!(out.join(format!("figures/{stem}.png")).exists(), "{stem}");
    }
    assert!(std::fs::read_dir(out.join("results/runs")).unwrap().count() > 0);

    let acc = dir.join("acc");
    std::fs::create_dir_all(acc.join("accuracy.svg/x")).unwrap();
    let (ok, stdout, stderr) = run(
        &dir,
        &common::small_accuracy_args("wknd", Some("baseline"), s(&acc)),
    );
    assert!(!ok, "{stdout}{stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{stderr}");
    assert!(errors[0].contains("the plot was not drawn"), "{stderr}");
    assert!(acc.join("accuracy.csv").exists() && acc.join("accuracy.json").exists());
    let _ = std::fs::remove_dir_all(&dir);
}
