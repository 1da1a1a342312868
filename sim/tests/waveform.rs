//! Waveforms of a simulation window (`vtq sim --vcd`): the VCD of one SM's RT unit hardware
//! parses back with one value per cycle of the window for every declared signal, shows each
//! block in its own scope, shows the treelet controller changing modes, and is the same whether
//! the engine skipped idle cycles or stepped every one (lockstep); the statistics do not change;
//! bad windows are clear errors; GTKWave's `vcd2fst` converts it.

mod common;

use std::io::BufReader;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::process::Command;

use common::{check_identical, setup, small_config, small_vtq};
use vtq_gen::tools::{or_skip, run as run_tool};
use vtq_hdl::mode::Mode;
use vtq_hdl::trace::{read_vcd, VcdTrace};
use vtq_sim::model::config::SimConfig;
use vtq_sim::model::gpu::rt::waveform::parse_cycles;
use vtq_sim::model::gpu::{simulate, SimError, SimOptions, SimOutput, VcdWindow};

/// A fresh temporary folder for one test.
fn temp_dir(test: &str) -> PathBuf {
    common::fresh_dir(&format!("waveform-{test}"))
}

/// Simulates `scene` with `cfg`, writing the waveform of SM `sm` over `cycles` to `path` if
/// given (rays recorded, for comparisons).
fn sim(
    scene: &str,
    cfg: &SimConfig,
    vcd: Option<(&Path, usize, Range<u64>)>,
) -> Result<SimOutput, SimError> {
    sim_threads(scene, cfg, vcd, 1)
}

/// [`sim`] on `threads` threads.
fn sim_threads(
    scene: &str,
    cfg: &SimConfig,
    vcd: Option<(&Path, usize, Range<u64>)>,
    threads: usize,
) -> Result<SimOutput, SimError> {
    let (scene, bvh) = setup(scene, cfg);
    let options = SimOptions {
        record_rays: true,
        threads,
        vcd: vcd.map(|(path, sm, cycles)| VcdWindow {
            path: path.to_path_buf(),
            sm,
            cycles,
        }),
        ..SimOptions::default()
    };
    simulate(&scene, &bvh, cfg, options, None)
}

fn read(path: &Path) -> VcdTrace {
    read_vcd(BufReader::new(std::fs::File::open(path).unwrap())).unwrap()
}

/// The trace holds every cycle of `window`, every row holds a value of every declared signal,
/// and each block prefix has signals in its `inputs`, `outputs` and `regs` scopes.
fn check_complete(trace: &VcdTrace, window: &Range<u64>, blocks: &[&str]) {
    assert_eq!(trace.start, window.start, "first cycle");
    assert_eq!(trace.cycles() as u64, window.end - window.start, "cycles");
    assert!(trace
        .values
        .iter()
        .all(|row| row.len() == trace.signals.len()));
    for block in blocks {
        for group in ["inputs", "outputs", "regs"] {
            let scope = format!("{block}.{group}.");
            assert!(
                trace.signals.iter().any(|(n, _)| n.starts_with(&scope)),
                "no signal in scope {scope}"
            );
        }
    }
    assert_eq!(
        trace.signals[0],
        ("clk".to_string(), 1),
        "the clock is declared first"
    );
}

/// The distinct values of `signal` over the trace, in order of first appearance.
fn distinct(trace: &VcdTrace, signal: &str) -> Vec<u64> {
    let i = trace
        .signals
        .iter()
        .position(|(n, _)| n == signal)
        .unwrap_or_else(|| panic!("no signal {signal}"));
    let mut seen = Vec::new();
    for row in &trace.values {
        if !seen.contains(&row[i]) {
            seen.push(row[i]);
        }
    }
    seen
}

/// Full VTQ on one SM of an 8x8 cornell box, with thresholds low enough for the small image
/// to reach the treelet-stationary and final ray-stationary phases in its first wave of rays.
fn vtq_config() -> SimConfig {
    small_vtq(1, 8, &[])
}

#[test]
fn queues_window_shows_every_block_every_cycle_and_the_controller_changing_modes() {
    let dir = temp_dir("queues");
    let cfg = vtq_config();
    let plain = sim("cornell", &cfg, None).unwrap();
    // The first wave of rays: initial phase, treelet stationary, final ray stationary, done.
    let window = 50..7050;
    assert!(
        window.end <= plain.stats.cycles,
        "the window is inside the run"
    );
    let (skip_vcd, lock_vcd) = (dir.join("skip.vcd"), dir.join("lock.vcd"));
    let rec = sim("cornell", &cfg, Some((&skip_vcd, 0, window.clone()))).unwrap();
    check_identical(&plain, &rec, "with and without --vcd");
    assert_eq!(
        plain.stats.sm_visits, rec.stats.sm_visits,
        "the engine ran alike"
    );
    let summary = rec.waveform.as_ref().expect("a waveform was written");
    assert_eq!(
        (&summary.path, summary.sm, &summary.cycles),
        (&skip_vcd, 0, &window)
    );
    assert!(
        summary.idle_steps > 0,
        "the window holds cycles the engine skipped"
    );

    let trace = read(&skip_vcd);
    let blocks = [
        "treelet_rt_unit",
        "treelet_rt_unit.rt",
        "treelet_rt_unit.ctl",
        "treelet_rt_unit.ct",
        "treelet_rt_unit.qt",
    ];
    check_complete(&trace, &window, &blocks);
    let modes = distinct(&trace, "treelet_rt_unit.ctl.regs.mode");
    for m in [
        Mode::Initial,
        Mode::TreeletStationary,
        Mode::FinalRayStationary,
    ] {
        assert!(
            modes.contains(&m.encoding()),
            "mode {} not seen in {window:?}: {modes:?}",
            m.name()
        );
    }
    // The controller's mode output follows its register; the RT unit requested memory.
    assert_eq!(
        distinct(&trace, "treelet_rt_unit.ctl.outputs.mode").len(),
        modes.len()
    );
    assert!(distinct(&trace, "treelet_rt_unit.rt.outputs.req_valid").contains(&1));

    // Stepping every cycle (lockstep) gives the same waveform: the skipped cycles were recorded
    // exactly as the blocks see them.
    let mut lock_cfg = cfg.clone();
    lock_cfg.sim.lockstep = true;
    let lock = sim("cornell", &lock_cfg, Some((&lock_vcd, 0, window.clone()))).unwrap();
    assert_eq!(
        lock.waveform.unwrap().idle_steps,
        0,
        "lockstep skips nothing"
    );
    let lock_trace = read(&lock_vcd);
    assert_eq!(lock_trace.signals, trace.signals);
    assert!(
        lock_trace.values == trace.values,
        "the lockstep waveform differs"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn baseline_window_of_the_second_sm_records_the_rt_unit() {
    let dir = temp_dir("baseline");
    let cfg = small_config("baseline", 2, 16, &[]);
    let plain = sim("wknd", &cfg, None).unwrap();
    let window = 1000..2500;
    let path = dir.join("base.vcd");
    // On three threads: the SM's node may move between them while it records.
    let rec = sim_threads("wknd", &cfg, Some((&path, 1, window.clone())), 3).unwrap();
    check_identical(&plain, &rec, "with and without --vcd");
    let trace = read(&path);
    check_complete(&trace, &window, &["rt_unit"]);
    let changing_regs = trace
        .signals
        .iter()
        .filter(|(n, _)| n.starts_with("rt_unit.regs.") && distinct(&trace, n).len() > 1)
        .count();
    assert!(changing_regs > 0, "no register changed in the window");
    assert!(distinct(&trace, "rt_unit.outputs.req_valid").contains(&1));
    assert!(distinct(&trace, "rt_unit.inputs.resp0_valid").contains(&1));

    let mut lock_cfg = cfg.clone();
    lock_cfg.sim.lockstep = true;
    let lock_path = dir.join("lock.vcd");
    sim("wknd", &lock_cfg, Some((&lock_path, 1, window))).unwrap();
    assert!(
        read(&lock_path).values == trace.values,
        "the lockstep waveform differs"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_windows_are_clear_errors_and_leave_no_file() {
    let dir = temp_dir("errors");
    let cfg = small_config("baseline", 1, 8, &[]);
    let path = dir.join("w.vcd");
    let cycles = sim("cornell", &cfg, None).unwrap().stats.cycles;
    let err = sim("cornell", &cfg, Some((&path, 0, cycles - 10..cycles + 10))).unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, SimError::Waveform(_)), "{msg}");
    assert!(
        msg.contains("past the end of the run") && msg.contains(&format!("{cycles} cycles")),
        "{msg}"
    );
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        0,
        "no VCD and no temporary file is left"
    );
    // The window may end exactly at the end of the run.
    let out = sim("cornell", &cfg, Some((&path, 0, cycles - 10..cycles))).unwrap();
    assert_eq!(read(&path).cycles(), 10);
    assert_eq!(out.waveform.unwrap().cycles, cycles - 10..cycles);

    let err = sim("cornell", &cfg, Some((&path, 1, 0..10))).unwrap_err();
    assert!(err.to_string().contains("gpu.sms = 1"), "{err}");
    let err = sim("cornell", &cfg, Some((&path, 0, 10..10))).unwrap_err();
    assert!(err.to_string().contains("1 to 1000000 cycles"), "{err}");

    assert_eq!(parse_cycles("400000..402000"), Ok(400000..402000));
    assert_eq!(parse_cycles("1_000..2_000"), Ok(1000..2000));
    for (spec, why) in [
        ("400000", "expected A..B"),
        ("5..3", "start must be below its end"),
        ("7..7", "start must be below its end"),
        ("x..3", "start 'x' is not a cycle number"),
        ("1..-3", "end '-3' is not a cycle number"),
        ("0..1000001", "at most 1000000"),
    ] {
        let e = parse_cycles(spec).unwrap_err();
        assert!(e.contains(why) && e.contains(spec), "{spec}: {e}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `vtq sim --vcd` from the command line: the file and its summary line; one-line errors.
#[test]
fn cli_writes_the_waveform_and_rejects_bad_options() {
    let dir = temp_dir("cli");
    let vtq = |extra: &[&str]| {
        let config = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../configs/designs/vtq/config.toml"
        );
        let mut args = vec![
            "sim",
            "--scene",
            "cornell",
            "--config",
            config,
            "--set",
            "width=8",
            "--set",
            "height=8",
            "--set",
            "gpu.sms=2",
        ];
        args.extend(extra);
        Command::new(env!("CARGO_BIN_EXE_vtq"))
            .args(&args)
            .current_dir(&dir)
            .output()
            .unwrap()
    };
    let out = vtq(&[
        "--out",
        "s.json",
        "--vcd",
        "w.vcd",
        "--vcd-sm",
        "1",
        "--vcd-cycles",
        "100..600",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("wrote w.vcd (the RT unit of SM 1 over cycles 100..600"),
        "{stdout}"
    );
    assert_eq!(read(&dir.join("w.vcd")).cycles(), 500);
    let one_line_error = |extra: &[&str], needle: &str| {
        let out = vtq(extra);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
        assert_eq!(errors.len(), 1, "{stderr}");
        assert!(errors[0].contains(needle), "'{needle}' not in {stderr}");
    };
    let base = ["--out", "e.json", "--vcd", "e.vcd"];
    let with = |extra: &[&'static str]| [&base[..], extra].concat();
    one_line_error(
        &with(&["--vcd-cycles", "9..3"]),
        "start must be below its end",
    );
    one_line_error(
        &with(&["--vcd-cycles", "0..100", "--vcd-sm", "2"]),
        "gpu.sms = 2",
    );
    one_line_error(
        &with(&["--vcd-cycles", "0..100", "--sample", "1/2"]),
        "cannot be combined with --sample",
    );
    one_line_error(
        &with(&["--vcd-cycles", "999999000..999999100"]),
        "past the end of the run",
    );
    assert!(!dir.join("e.vcd").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// GTKWave's `vcd2fst` converts the waveform, and `fst2vcd` gives back the same values (skips
/// with a message when GTKWave is not installed, unless `CI` is set).
#[test]
fn gtkwave_converts_the_waveform() {
    let dir = temp_dir("gtkwave");
    let path = dir.join("w.vcd");
    let window = 4000..5000;
    sim("cornell", &vtq_config(), Some((&path, 0, window.clone()))).unwrap();
    let Some(_) = or_skip(run_tool("vcd2fst", &["w.vcd", "w.fst"], &dir, false)).unwrap() else {
        std::fs::remove_dir_all(&dir).unwrap();
        return;
    };
    let fst = std::fs::metadata(dir.join("w.fst")).expect("vcd2fst wrote w.fst");
    assert!(fst.len() > 0);
    let (back, _) = run_tool("fst2vcd", &["w.fst"], &dir, false).expect("fst2vcd runs");
    let converted = read_vcd(back.stdout.as_bytes()).expect("fst2vcd's VCD parses");
    let original = read(&path);
    assert_eq!(converted.signals, original.signals);
    assert_eq!(converted.start, window.start);
    assert!(
        converted.values == original.values,
        "GTKWave reads other values"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
