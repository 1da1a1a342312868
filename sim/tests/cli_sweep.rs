//! End-to-end tests of `vtq sweep`: a sweep killed mid-way and run again gives the table of an
//! uninterrupted sweep and skips every finished run; a point that fails validation is recorded
//! and does not stop the others; shards together equal the whole sweep; bad definitions fail
//! before anything runs. Tiny images of the built-in scenes.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

mod sweep_grid;
use sweep_grid::sweep_args;

/// A fresh temporary folder for one test.
fn temp_dir(test: &str) -> PathBuf {
    common::fresh_dir(&format!("cli-sweep-{test}"))
}

/// The workspace's configs/designs/vtq/config.toml.
fn vtq_toml() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../configs/designs/vtq/config.toml")
        .display()
        .to_string()
}

/// A `vtq` command in `dir`.
fn vtq(dir: &Path) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_vtq"));
    cmd.current_dir(dir);
    cmd
}

/// Runs `vtq args` in `dir`.
fn run(dir: &Path, args: &[String]) -> Output {
    vtq(dir).args(args).output().expect("the vtq binary runs")
}

/// stdout and stderr of a run, for messages.
fn text(out: &Output) -> String {
    format!(
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// Collects `results` (relative to `dir`) and returns the CSV text.
fn collect(dir: &Path, results: &str, extra: &[&str]) -> String {
    let out_file = format!("{results}.csv");
    let mut args = vec!["sweep", "--collect", results, "--out", &out_file];
    args.extend_from_slice(extra);
    let args: Vec<String> = args.into_iter().map(String::from).collect();
    let out = run(dir, &args);
    assert!(out.status.success(), "{}", text(&out));
    std::fs::read_to_string(dir.join(&out_file)).unwrap()
}

/// The result files in `dir/runs` and their contents.
fn result_files(results: &Path) -> BTreeMap<String, Vec<u8>> {
    let Ok(entries) = std::fs::read_dir(results.join("runs")) else {
        return BTreeMap::new();
    };
    entries
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            // A result file is renamed into place whole, so it is never partial.
            (name, std::fs::read(&p).unwrap())
        })
        .collect()
}

/// The number after `word` in `line`.
fn number_after(line: &str, word: &str) -> usize {
    let rest = &line[line
        .find(word)
        .unwrap_or_else(|| panic!("no `{word}` in {line}"))
        + word.len()..];
    rest.trim_start()
        .split(|c: char| !c.is_ascii_digit())
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

#[test]
fn a_killed_sweep_resumes_to_the_uninterrupted_table() {
    let dir = temp_dir("resume");
    // The uninterrupted sweep, two at a time.
    let whole = run(&dir, &sweep_args(&dir, "whole", &["--jobs", "2"]));
    assert!(whole.status.success(), "{}", text(&whole));
    assert_eq!(result_files(&dir.join("whole")).len(), 12);
    let expected = collect(&dir, "whole", &[]);
    assert_eq!(expected.lines().count(), 13, "{expected}");
    let header: Vec<&str> = expected.lines().next().unwrap().split(',').collect();
    assert_eq!(
        header[..4],
        ["scene", "gpu.sms", "hw.repack_threshold", "status"]
    );
    for column in [
        "cycles",
        "rays",
        "bvh_l1_miss_rate",
        "simt_efficiency",
        "treelet_stationary_share",
        "dram_bytes",
        "max_queues",
        "cta_suspends",
        "energy_mj",
        "energy_time_share",
        "energy_virtualization_mj",
        "error",
        "key",
    ] {
        assert!(header.contains(&column), "no {column} in {header:?}");
    }
    // The energy columns are computed from the stored counters: a positive energy per run.
    let energy = header.iter().position(|c| *c == "energy_mj").unwrap();
    for row in expected.lines().skip(1) {
        let cells: Vec<&str> = row.split(',').collect();
        let mj: f64 = cells[energy].parse().unwrap_or(0.0);
        assert!(mj > 0.0, "energy_mj {} in {row}", cells[energy]);
    }

    // The same sweep, one at a time, killed once a few results exist.
    let mut child = vtq(&dir)
        .args(sweep_args(&dir, "killed", &["--jobs", "1"]))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while result_files(&dir.join("killed")).len() < 3 {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the sweep ended before it could be killed"
        );
        assert!(start.elapsed() < Duration::from_secs(120), "no results");
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let before = result_files(&dir.join("killed"));
    let finished = before.len();
    eprintln!("killed after {finished} of 12 runs");
    assert!(
        (3..12).contains(&finished),
        "{finished} of 12 runs finished before the kill: not mid-way"
    );

    // The rerun skips every finished run, runs the rest and leaves the finished files alone.
    let rerun = run(&dir, &sweep_args(&dir, "killed", &["--jobs", "2"]));
    assert!(rerun.status.success(), "{}", text(&rerun));
    let stdout = String::from_utf8_lossy(&rerun.stdout);
    let plan = stdout.lines().find(|l| l.contains("already done")).unwrap();
    assert_eq!(number_after(plan, "12 points;"), finished, "{plan}");
    let summary = stdout.lines().find(|l| l.contains("sweep: ran")).unwrap();
    assert_eq!(number_after(summary, "ran"), 12 - finished, "{summary}");
    assert_eq!(number_after(summary, "skipped"), finished, "{summary}");
    assert_eq!(
        stdout.lines().filter(|l| l.contains("] ")).count(),
        12 - finished,
        "one line per run:\n{stdout}"
    );
    let after = result_files(&dir.join("killed"));
    for (name, bytes) in &before {
        assert_eq!(after.get(name), Some(bytes), "{name} was rewritten");
    }
    assert_eq!(after.len(), 12);
    assert_eq!(collect(&dir, "killed", &[]), expected);

    // Once complete, a rerun runs nothing.
    let again = run(&dir, &sweep_args(&dir, "killed", &[]));
    let stdout = String::from_utf8_lossy(&again.stdout);
    assert!(
        stdout.contains("sweep: ran 0 (0 ok, 0 failed), skipped 12 (12 done"),
        "{stdout}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A 2-point cornell sweep (design `vtq`, 16x16) whose second repack threshold fails validation.
fn failing_sweep(extra: &[&str]) -> Vec<String> {
    let mut args: Vec<String> = [
        "sweep",
        "--scene",
        "cornell",
        "--config",
        &vtq_toml(),
        "--set",
        "width=16",
        "--set",
        "height=16",
        "--grid",
        "hw.repack_threshold=16,99",
        "--results",
        "res",
        "--no-cache",
    ]
    .map(String::from)
    .to_vec();
    args.extend(extra.iter().map(|s| s.to_string()));
    args
}

#[test]
fn a_failed_point_is_recorded_and_the_others_run() {
    let dir = temp_dir("failure");
    let out = run(&dir, &failing_sweep(&[]));
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("error: 1 of 2 points failed (cornell hw.repack_threshold=99)"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    let files = result_files(&dir.join("res"));
    assert_eq!(files.len(), 2);
    let records: Vec<serde_json::Value> = files
        .values()
        .map(|b| serde_json::from_slice(b).unwrap())
        .collect();
    let failed = records.iter().find(|r| r["status"] == "failed").unwrap();
    let error = failed["error"].as_str().unwrap();
    assert!(
        error.contains("hw.repack_threshold = 99"),
        "the error names the key: {error}"
    );
    assert!(failed.get("result").is_none());
    let ok = records.iter().find(|r| r["status"] == "ok").unwrap();
    assert!(ok["result"]["stats"]["cycles"].as_u64().unwrap() > 0);

    let table = collect(&dir, "res", &[]);
    let rows: Vec<&str> = table.lines().collect();
    assert_eq!(rows.len(), 3, "{table}");
    assert!(rows[1].starts_with("cornell,16,ok,"), "{table}");
    assert!(rows[2].starts_with("cornell,99,failed,,"), "{table}");
    assert!(rows[2].contains("hw.repack_threshold = 99"), "{table}");

    // A failure is final: the rerun skips it (and still reports it) ...
    let out = run(&dir, &failing_sweep(&[]));
    assert_eq!(out.status.code(), Some(1));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("ran 0 (0 ok, 0 failed), skipped 2 (1 done, 1 failed earlier)"),
        "{stdout}"
    );
    // ... unless asked to retry it.
    let out = run(&dir, &failing_sweep(&["--retry-failed"]));
    assert_eq!(out.status.code(), Some(1));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("ran 1 (0 ok, 1 failed), skipped 1 (1 done, 0 failed earlier)"),
        "{stdout}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn shards_of_a_sweep_file_add_up_to_the_whole() {
    let dir = temp_dir("shards");
    std::fs::write(
        dir.join("study.toml"),
        "scenes = ['cornell']\nset = ['width=16', 'height=16']\n\
         [grid]\ngpu.sms = [1, 2]\nbounces = [0, 1]\n\
         [[points]]\nmode.kind = 'prefetch'\n",
    )
    .unwrap();
    let spec = |extra: &[&str]| -> Vec<String> {
        let mut a = vec!["sweep", "--spec", "study.toml", "--no-cache"];
        a.extend_from_slice(extra);
        a.into_iter().map(String::from).collect()
    };
    let out = run(&dir, &spec(&["--results", "whole"]));
    assert!(out.status.success(), "{}", text(&out));
    let expected = collect(&dir, "whole", &[]);
    assert_eq!(expected.lines().count(), 6, "5 points:\n{expected}");

    // One shard alone: the sweep's table shows the other points as missing.
    let out = run(&dir, &spec(&["--results", "sharded", "--shard", "1/3"]));
    assert!(out.status.success(), "{}", text(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("5 points, shard 1/3: 2 of them"),
        "{stdout}"
    );
    assert_eq!(result_files(&dir.join("sharded")).len(), 2);
    let partial = collect(&dir, "sharded", &["--spec", "study.toml"]);
    assert_eq!(partial.matches(",missing,").count(), 3, "{partial}");
    for shard in ["0/3", "2/3"] {
        let out = run(&dir, &spec(&["--results", "sharded", "--shard", shard]));
        assert!(out.status.success(), "{}", text(&out));
    }
    assert_eq!(collect(&dir, "sharded", &[]), expected);
    assert_eq!(
        collect(&dir, "sharded", &["--spec", "study.toml"]),
        expected
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_sweeps_fail_before_running() {
    let dir = temp_dir("bad");
    let cases: [(&[&str], &str); 5] = [
        (
            &[
                "--scene",
                "cornell",
                "--grid",
                "hw.no_such=1,2",
                "--results",
                "r",
            ],
            "unknown key `hw.no_such`",
        ),
        (
            &["--scene", "cornell", "--grid", "gpu.sms", "--results", "r"],
            "--grid `gpu.sms`: expected key=v1,v2",
        ),
        (&["--scene", "cornell"], "--results DIR is required"),
        (&["--results", "r"], "the sweep has no scenes"),
        (
            &["--scene", "no-such-scene", "--results", "r"],
            "unknown scene 'no-such-scene'",
        ),
    ];
    for (args, needle) in cases {
        let mut all = vec!["sweep".to_string()];
        all.extend(args.iter().map(|s| s.to_string()));
        let out = run(&dir, &all);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {}", text(&out));
        let last = stderr.trim_end().lines().last().unwrap_or("");
        assert!(
            last.starts_with("error:") && last.contains(needle),
            "{args:?}: `{needle}` not in {last}"
        );
        assert!(!dir.join("r").exists(), "{args:?} ran something");
    }
    // A partial definition (a grid without scenes) is an error, not silently ignored.
    let out = run(
        &dir,
        &["sweep", "--collect", "r", "--grid", "gpu.sms=1,2"].map(String::from),
    );
    assert_eq!(out.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("the sweep has no scenes"),
        "{}",
        text(&out)
    );
    let out = run(
        &dir,
        &["sweep".into(), "--collect".into(), "nothing".into()],
    );
    assert_eq!(out.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("nothing holds no results"),
        "{}",
        text(&out)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// From a folder without the project's files (a cluster node with only the binary), a sweep
/// names the project's designs by name or by their files and its experiment files by name:
/// vtq's built-in copies, the same runs (by their keys) as the files' in a checkout.
#[test]
fn designs_and_experiments_run_from_anywhere_by_name() {
    let dir = temp_dir("anywhere");
    let tiny = ["--set", "width=8", "--set", "height=8"];
    let args = |extra: &[&str]| -> Vec<String> {
        extra.iter().chain(&tiny).map(|s| s.to_string()).collect()
    };
    // Two designs on wknd into results folder r1.
    let sweep_two = |vtq: &str, naive: &str| {
        let designs = ["--config", vtq, "--config", naive];
        let head = ["sweep", "--scene", "wknd", "--results", "r1"];
        run(&dir, &args(&[&head[..], &designs[..]].concat()))
    };
    let by_name = sweep_two("vtq", "configs/designs/queues-naive/config.toml");
    assert!(by_name.status.success(), "{}", text(&by_name));
    assert!(
        text(&by_name).contains("ran 2 (2 ok, 0 failed)"),
        "{}",
        text(&by_name)
    );
    // The same two designs from the checkout's files are the same runs: nothing runs again.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let naive = root
        .join("configs/designs/queues-naive/config.toml")
        .display()
        .to_string();
    let from_files = sweep_two(&vtq_toml(), &naive);
    assert!(text(&from_files).contains("ran 0"), "{}", text(&from_files));
    // An experiment file by name: read (its first point, the baseline's file, names the bad
    // override before anything runs); an unknown design or experiment is a one-line error.
    let fig10 = run(
        &dir,
        &args(&[
            "sweep",
            "--spec",
            "fig10-speedup",
            "--set",
            "nosuch=1",
            "--results",
            "r2",
        ]),
    );
    assert!(!fig10.status.success());
    assert!(
        text(&fig10).contains("sweep point wknd baseline: --set `nosuch=1`: unknown key"),
        "{}",
        text(&fig10)
    );
    assert!(!dir.join("r2").exists());
    for (flag, name, says) in [
        (
            "--config",
            "fastest",
            "not a built-in design's name or file",
        ),
        ("--spec", "fig99", "cannot read sweep file fig99"),
    ] {
        let out = run(
            &dir,
            &args(&["sweep", "--scene", "wknd", flag, name, "--results", "r3"]),
        );
        assert!(!out.status.success());
        assert!(text(&out).contains(says), "{}", text(&out));
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
