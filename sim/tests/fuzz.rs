//! The parser fuzz harness: a short run over every parser (0 panics, 0 hangs, and cases both
//! accepted and rejected), determinism by seed, valid seeds, and the harness's own detection of
//! panics and true infinite loops, with the failing input saved. The long runs (100,000 cases
//! per parser) are `vtq fuzz` in a release build; figures in docs/fuzzing.md.

mod common;

use std::path::PathBuf;
use std::process::Command;
use std::sync::Arc;
use std::time::Duration;

use vtq_sim::cli::fuzz::mutate::Rng;
use vtq_sim::cli::fuzz::targets::{run, Outcome};
use vtq_sim::cli::fuzz::{fuzz_parser, fuzz_target, seeds, FuzzOptions, Parser};

/// A fresh temporary folder for one test.
fn temp_dir(test: &str) -> PathBuf {
    common::fresh_dir(&format!("fuzz-{test}"))
}

fn options(cases: u64, seed: u64) -> FuzzOptions {
    FuzzOptions {
        cases,
        seed,
        timeout: Duration::from_secs(5),
        save_dir: None,
        max_hangs: 1,
    }
}

#[test]
fn every_parser_survives_a_short_run() {
    // 500 cases per parser, 4,500 in all: about a second in the test profile.
    for parser in Parser::ALL {
        let report = fuzz_parser(parser, &options(500, 2024));
        assert_eq!(report.cases, 500, "{parser}");
        assert!(
            report.panics.is_empty() && report.hangs.is_empty(),
            "{parser}: panics {:?} hangs {:?}",
            report.panics,
            report.hangs
        );
        // Both outcomes occur: the mutations reach past the first check, and break inputs.
        assert!(
            report.accepted >= 20 && report.rejected >= 50,
            "{parser}: {} accepted, {} rejected",
            report.accepted,
            report.rejected
        );
    }
}

#[test]
fn runs_are_determined_by_the_seed() {
    let run = |seed| fuzz_parser(Parser::Obj, &options(300, seed));
    let (a, b, c) = (run(5), run(5), run(6));
    assert_eq!(
        (a.digest.as_str(), a.accepted, a.rejected),
        (b.digest.as_str(), b.accepted, b.rejected)
    );
    assert_ne!(a.digest, c.digest);
}

#[test]
fn every_seed_is_accepted_by_its_parser() {
    for parser in Parser::ALL {
        let seeds = seeds::seeds(parser, &mut Rng::new(99));
        assert!(seeds.len() >= 7, "{parser}: {} seeds", seeds.len());
        for (i, seed) in seeds.iter().enumerate() {
            assert_eq!(
                run(parser, seed),
                Outcome::Accepted,
                "{parser} seed {i}: {}",
                String::from_utf8_lossy(seed)
            );
        }
    }
}

#[test]
fn panics_and_true_infinite_loops_are_caught_and_saved() {
    let dir = temp_dir("harness");
    let target = Arc::new(|input: &[u8]| {
        let text = String::from_utf8_lossy(input);
        if text.contains("boom") {
            panic!("boom in the parser");
        }
        if text.contains("spin") {
            // Never returns (without burning a core while the other tests run).
            loop {
                std::thread::sleep(Duration::from_secs(1));
            }
        }
        Outcome::Rejected
    });
    let seeds = vec![
        b"boom".to_vec(),
        b"spin".to_vec(),
        b"fine".to_vec(),
        b"also fine".to_vec(),
    ];
    let options = FuzzOptions {
        cases: 400,
        seed: 1,
        timeout: Duration::from_millis(100),
        save_dir: Some(dir.clone()),
        max_hangs: 2,
    };
    let report = fuzz_target(Parser::Set, target.clone(), Some(seeds), &options);
    assert_eq!(report.hangs.len(), 2, "stops after max_hangs: {report:?}");
    assert!(report.cases < 400, "the run stopped at the second hang");
    assert!(!report.panics.is_empty());
    let panic = &report.panics[0];
    assert!(
        panic.message.contains("boom in the parser") && panic.message.contains("fuzz.rs"),
        "the message and its location: {}",
        panic.message
    );
    let saved = std::fs::read(panic.saved.as_ref().expect("saved")).unwrap();
    assert!(String::from_utf8_lossy(&saved).contains("boom"));
    let hang = &report.hangs[0];
    assert_eq!(hang.message, "hang (over 100 ms)");
    let saved = hang.saved.as_ref().expect("saved");
    assert!(saved
        .file_name()
        .unwrap()
        .to_str()
        .unwrap()
        .starts_with("set-hang-seed1-case"));
    assert!(String::from_utf8_lossy(&std::fs::read(saved).unwrap()).contains("spin"));
    assert!(report.rejected > 0, "cases after a hang still run");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_command_reports_every_parser_and_replays_an_input() {
    let dir = temp_dir("cli");
    let vtq = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_vtq"))
            .args(args)
            .current_dir(&dir)
            .output()
            .expect("vtq runs")
    };
    let out = vtq(&["fuzz", "--cases", "40", "--seed", "3"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    for parser in Parser::ALL {
        let row = stdout
            .lines()
            .find(|l| l.starts_with(&format!("{} ", parser.name())))
            .unwrap_or_else(|| panic!("no row for {parser}: {stdout}"));
        let cells: Vec<&str> = row.split_whitespace().collect();
        assert_eq!(
            (cells[1], cells[4], cells[5]),
            ("40", "0", "0"),
            "cases, panics, hangs: {row}"
        );
    }
    assert!(!dir.join("vtq-fuzz-failures").exists(), "nothing saved");

    let input = dir.join("ok.obj");
    std::fs::write(&input, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let out = vtq(&["fuzz", "--parser", "obj", "--replay", "ok.obj"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.contains("accepted"),
        "{stdout}"
    );
    let out = vtq(&["fuzz", "--parser", "rays-csv", "--replay", "ok.obj"]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("rejected with an error"));

    let out = vtq(&["fuzz", "--parser", "yaml"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("unknown parser 'yaml'"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
