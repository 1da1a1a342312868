//! The generated RTL of the treelet controller against the Rust block: cycle-by-cycle
//! co-simulation (Icarus Verilog, and Verilator on a shorter stream) of the reactive random
//! environment of [`vtq_gen::stimulus::controller`] (the real Rust tables and a model of the RT
//! unit around the controller), at a small configuration (full and naive designs) and the
//! paper's; broken RTL lines that the co-simulation must catch; `verilator --lint-only -Wall`
//! and Yosys synthesis without latches or warnings.

mod common;

use common::{cosim_timed, lints_clean, small, synthesize_small, write_verilog};
use std::path::{Path, PathBuf};
use vtq_gen::cosim::{record, CosimResult, Simulator, Trace};
use vtq_gen::rtl::{controller_verilog, rtl_modules};
use vtq_gen::stimulus::controller::controller_inputs;
use vtq_hdl::controller::{ControllerFeatures, TreeletController};
use vtq_hdl::{Block, HwConfig};

/// Cycles of every Icarus co-simulation.
const ICARUS_CYCLES: usize = 8_000;
/// Cycles of the Verilator co-simulation.
const VERILATOR_CYCLES: usize = 3_000;

/// No preloading and no repacking (the RTL's constant-folded branches).
const NO_PRELOAD: ControllerFeatures = ControllerFeatures {
    preload: false,
    ..ControllerFeatures::FULL
};

fn work_dir(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("vtq-gen-controller-rtl-{name}"))
}

/// Co-simulates `trace` against `source`; `None` when the simulator is not installed.
fn cosim(trace: &Trace, source: &Path, sim: Simulator, tag: &str) -> Option<CosimResult> {
    let work = work_dir(&format!("{tag}-{sim:?}"));
    cosim_timed(trace, &[source.to_path_buf()], sim, work, tag)
}

/// The stimulus of `cfg` and `features`, recorded on the Rust block, and the RTL's file.
fn setup(
    tag: &str,
    cfg: &HwConfig,
    features: ControllerFeatures,
    cycles: usize,
    seed: u64,
) -> (Trace, PathBuf) {
    let (ctl, inputs, cov) = controller_inputs(cfg, features, cycles, seed).unwrap();
    eprintln!("controller ({tag}): {cov}");
    let naive = !features.group_underpopulated;
    if tag.starts_with("small") {
        // The stream reaches every mode and sequencer state and every action, many times.
        cov.covers_everything(if naive { 1 } else { 5 }, features)
            .unwrap_or_else(|e| panic!("{tag}: {e}"));
        // Preloading makes a second treelet resident behind the current one.
        let resident = if features.preload { 2 } else { 1 };
        assert!(
            cov.to_done >= 1 && cov.max_resident >= resident,
            "{tag}: {cov}"
        );
    }
    let trace = record(&ctl, inputs).unwrap();
    let text = controller_verilog(cfg, features).unwrap();
    let file = write_verilog(&work_dir(tag), &ctl.describe().name, &text);
    (trace, file)
}

#[test]
fn controller_matches_rust_cycle_by_cycle() {
    for (tag, cfg, features, seed) in [
        ("small", small(), ControllerFeatures::FULL, 1),
        ("small-naive", small(), ControllerFeatures::NAIVE, 2),
        ("small-no-preload", small(), NO_PRELOAD, 3),
        ("default", HwConfig::default(), ControllerFeatures::FULL, 4),
    ] {
        let (trace, file) = setup(tag, &cfg, features, ICARUS_CYCLES, seed);
        let Some(r) = cosim(&trace, &file, Simulator::Icarus, tag) else {
            return;
        };
        assert!(r.passed(), "{tag}:\n{r}");
    }
}

/// The same kind of stream, shorter, under Verilator (two-state, its own scheduling).
#[test]
fn controller_matches_rust_under_verilator() {
    let (trace, file) = setup(
        "small",
        &small(),
        ControllerFeatures::FULL,
        VERILATOR_CYCLES,
        5,
    );
    if let Some(r) = cosim(&trace, &file, Simulator::Verilator, "small") {
        assert!(r.passed(), "{r}");
    }
}

/// Deliberately broken lines of the RTL: each must make the co-simulation fail.
#[test]
fn a_broken_rtl_line_is_caught() {
    let cfg = small();
    let features = ControllerFeatures::FULL;
    let (ctl, inputs, _) = controller_inputs(&cfg, features, ICARUS_CYCLES, 1).unwrap();
    let trace = record(&ctl, inputs).unwrap();
    let good = controller_verilog(&cfg, features).unwrap();
    let mutations = [
        // A grouped warp takes every popped ray instead of what fits.
        (
            "take = (e_fill_need < popped) ? e_fill_need : popped;",
            "take = popped;",
        ),
        // The resident list's tail wraps at a power of two instead of its 3 entries.
        (
            "res_tail_d = (e_res_tail == 2'd2) ? 2'd0 : e_res_tail + 2'd1;",
            "res_tail_d = e_res_tail + 2'd1;",
        ),
        // The divergence test is off by one.
        ("(init_distinct > 3'd1)", "(init_distinct >= 3'd1)"),
    ];
    for (i, (from, to)) in mutations.iter().enumerate() {
        assert_eq!(
            good.matches(from).count(),
            1,
            "mutation {i}: `{from}` not found once"
        );
        let bad = good.replacen(from, to, 1);
        let tag = format!("broken-{i}");
        let file = write_verilog(&work_dir(&tag), &ctl.describe().name, &bad);
        let Some(r) = cosim(&trace, &file, Simulator::Icarus, &tag) else {
            return;
        };
        assert!(r.mismatches > 0, "mutation {i} was not caught:\n{r}");
        assert!(!r.reported.is_empty(), "mutation {i}: no mismatch reported");
    }
}

#[test]
fn generated_controller_lints_clean() {
    for (tag, cfg, features) in [
        ("default", HwConfig::default(), ControllerFeatures::FULL),
        ("small", small(), ControllerFeatures::FULL),
        ("small-naive", small(), ControllerFeatures::NAIVE),
        (
            "no-repack",
            HwConfig {
                repack_threshold: 0,
                underpopulation_threshold: 0,
                preload_threshold_warps: 0,
                max_resident_treelets: 1,
                warp_buffer_size: 2,
                ..small()
            },
            NO_PRELOAD,
        ),
    ] {
        let module = TreeletController::new(cfg.clone(), features)
            .unwrap()
            .describe()
            .name;
        let text = controller_verilog(&cfg, features).unwrap();
        assert!(!text.contains("${"), "{tag}: unfilled template variable");
        assert!(
            !text.contains("initial begin"),
            "{tag}: no initial blocks in RTL"
        );
        let dir = work_dir(&format!("lint-{tag}"));
        let file = write_verilog(&dir, &module, &text);
        if !lints_clean(&[file], &module, &dir, tag) {
            return;
        }
    }
}

/// Yosys' generic synthesis of the small configuration: no latches, no undriven wires, no
/// warnings, and every register bit a flip-flop (but those Yosys finds constant).
#[test]
fn small_controller_synthesizes_without_latches() {
    let cfg = small();
    let ctl = TreeletController::new(cfg.clone(), ControllerFeatures::FULL).unwrap();
    let module = ctl.describe().name;
    let text = controller_verilog(&cfg, ControllerFeatures::FULL).unwrap();
    let Some(r) = synthesize_small(&work_dir("synth"), &module, &text) else {
        return;
    };
    // Yosys' fsm pass may re-encode the mode and sequencer FSMs one-hot.
    let desc = ctl.describe();
    let recoded: u64 = desc
        .fsms
        .iter()
        .map(|f| f.states.len() as u64 - f.width as u64)
        .sum();
    let bits = desc.register_bits();
    assert!(
        r.flip_flops > bits / 2 && r.flip_flops <= bits + recoded,
        "{} flip-flops for {bits} register bits",
        r.flip_flops
    );
}

#[test]
fn controller_rtl_follows_the_configuration() {
    let modules = rtl_modules(&HwConfig::default(), ControllerFeatures::FULL).unwrap();
    let names: Vec<&str> = modules.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "treelet_count_table",
            "treelet_queue_table",
            "treelet_controller"
        ]
    );
    let text = &modules[2].1;
    // The paper's sizes: 32 lanes of 12-bit ray ids, 2 resident treelets of 19 bits.
    assert!(text.contains("input  wire [383:0] qt_pop_rays"), "pop bus");
    assert!(
        text.contains("output wire [37:0]  resident_treelet"),
        "resident list"
    );
    assert!(text.contains("reg [371:0] spare_rays_q;"), "31 spare lanes");
    assert!(text.contains("localparam GROUP = 1'b1;"));
    let naive = controller_verilog(&HwConfig::default(), ControllerFeatures::NAIVE).unwrap();
    assert!(naive.contains("localparam GROUP = 1'b0;"));
    // An invalid configuration is an error naming the offending key, not a panic.
    let bad = HwConfig {
        max_resident_treelets: 0,
        ..HwConfig::default()
    };
    let err = controller_verilog(&bad, ControllerFeatures::FULL)
        .unwrap_err()
        .to_string();
    assert!(err.contains("max_resident_treelets"), "{err}");
}

#[test]
fn small_controller_snapshot() {
    insta::assert_snapshot!(
        "controller_small",
        controller_verilog(&small(), ControllerFeatures::FULL).unwrap()
    );
}
