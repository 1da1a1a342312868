//! The generated RTL of the treelet count table and the treelet queue table against the Rust
//! blocks: cycle-by-cycle co-simulation of long random operation streams (Icarus Verilog, and
//! Verilator on a shorter stream), `verilator --lint-only -Wall` and Yosys synthesis without
//! latches or undriven wires, at the paper's configuration and a small one, plus snapshots of
//! the small configuration's Verilog.
//!
//! The stimulus comes from [`vtq_gen::stimulus`]: seeded random op streams played by a test
//! bench that steps its own copy of the Rust block, so it can react like the real environment
//! (it holds a count-table Add while `ready` is low, presents queue-table ops only when the
//! table is idle, stores spilled rays in a FIFO and answers each refill request after a random
//! latency with the oldest one, as `hdl/tests/queue_table_props.rs` does).

mod common;

use common::{cosim_timed, lints_clean, synthesize_small, write_verilog};
use std::path::{Path, PathBuf};
use vtq_gen::cosim::{record, Simulator};
use vtq_gen::rtl::{count_table_verilog, queue_table_verilog, table_modules};
use vtq_gen::stimulus::{count_table_inputs, queue_table_inputs};
use vtq_hdl::count_table::CountTable;
use vtq_hdl::queue_table::QueueTable;
use vtq_hdl::{Block, HwConfig};

/// Cycles of every Icarus co-simulation.
const ICARUS_CYCLES: usize = 100_000;
/// Cycles of the Verilator co-simulations.
const VERILATOR_CYCLES: usize = 20_000;

/// The small configuration: 20 count-table entries (3 scan windows, the last one partial),
/// 8 queue-table entries in 8 buckets, 4-ray warps, 64 rays.
fn small() -> HwConfig {
    HwConfig {
        count_table_entries: 20,
        queue_table_entries: 8,
        max_rays: 64,
        warp_size: 4,
        underpopulation_threshold: 5,
        repack_threshold: 2,
        divergence_threshold: 2,
        ..HwConfig::default()
    }
}

fn configs() -> [(&'static str, HwConfig); 2] {
    [("default", HwConfig::default()), ("small", small())]
}

fn work_dir(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("vtq-gen-table-rtl-{name}"))
}

/// Records `inputs` on the Rust `block`, writes `text`, its RTL, into `dir` and co-simulates
/// the two under `sim`, asserting zero mismatches; false when the simulator is not installed
/// (outside CI).
fn cosim<B: Block>(
    block: &B,
    inputs: impl IntoIterator<Item = B::Inputs>,
    text: &str,
    dir: &Path,
    sim: Simulator,
    tag: &str,
) -> bool {
    let trace = record(block, inputs).unwrap();
    let source = write_verilog(dir, &block.describe().name, text);
    let work = work_dir(&format!("{tag}-{sim:?}"));
    let Some(result) = cosim_timed(&trace, &[source], sim, work, tag) else {
        return false;
    };
    assert!(result.passed(), "{tag}:\n{result}");
    true
}

#[test]
fn count_table_matches_rust_cycle_by_cycle() {
    for (tag, cfg) in configs() {
        let (t, inputs, cov) = count_table_inputs(&cfg, ICARUS_CYCLES, 1).unwrap();
        eprintln!("count table ({tag}): {cov}");
        // The stream exercises every behaviour of the table.
        assert!(
            cov.scans_started > 100 && cov.scans_restarted > 10 && cov.scans_published > 100,
            "{tag}: {cov:?}"
        );
        assert!(
            cov.evictions > 100 && cov.stalls > 100 && cov.errors > 100 && cov.clears >= 2,
            "{tag}: {cov:?}"
        );
        let text = count_table_verilog(&cfg).unwrap();
        let tag = format!("count-{tag}");
        if !cosim(&t, inputs, &text, &work_dir(&tag), Simulator::Icarus, &tag) {
            return;
        }
    }
}

#[test]
fn generated_tables_lint_clean() {
    for (tag, cfg) in configs() {
        for (module, text) in table_modules(&cfg).unwrap() {
            assert!(
                !text.contains("${"),
                "{module} ({tag}): unfilled template variable"
            );
            let dir = work_dir(&format!("lint-{tag}"));
            let file = write_verilog(&dir, &module, &text);
            if !lints_clean(&[file], &module, &dir, &format!("{module} ({tag})")) {
                return;
            }
        }
    }
}

#[test]
fn queue_table_matches_rust_cycle_by_cycle() {
    for (tag, cfg) in configs() {
        let (t, inputs, cov) = queue_table_inputs(&cfg, ICARUS_CYCLES, 2).unwrap();
        eprintln!("queue table ({tag}): {cov}");
        assert!(
            cov.spills > 100
                && cov.refills > 100
                && cov.pops > 1000
                && cov.counts > 500
                && cov.errors > 100,
            "{tag}: {cov:?}"
        );
        assert!(
            cov.max_chain >= 3,
            "{tag}: chains too short to test the walk"
        );
        let text = queue_table_verilog(&cfg).unwrap();
        let tag = format!("queue-{tag}");
        if !cosim(&t, inputs, &text, &work_dir(&tag), Simulator::Icarus, &tag) {
            return;
        }
    }
}

/// The same kind of streams, shorter, under Verilator (two-state, its own scheduling).
#[test]
fn tables_match_rust_under_verilator() {
    for (tag, cfg) in configs() {
        let dir = work_dir(&format!("verilator-{tag}"));
        let (ct, inputs, _) = count_table_inputs(&cfg, VERILATOR_CYCLES, 3).unwrap();
        let text = count_table_verilog(&cfg).unwrap();
        if !cosim(
            &ct,
            inputs,
            &text,
            &dir,
            Simulator::Verilator,
            &format!("count-{tag}"),
        ) {
            return;
        }
        let (qt, inputs, _) = queue_table_inputs(&cfg, VERILATOR_CYCLES, 4).unwrap();
        let text = queue_table_verilog(&cfg).unwrap();
        cosim(
            &qt,
            inputs,
            &text,
            &dir,
            Simulator::Verilator,
            &format!("queue-{tag}"),
        );
    }
}

/// Yosys' generic synthesis of the small configuration: no latches, no undriven wires, no
/// warnings, and the flip-flops the storage needs (the default configuration takes minutes
/// and is measured separately; see docs/hardware.md).
#[test]
fn small_tables_synthesize_without_latches() {
    let cfg = small();
    for (module, text) in table_modules(&cfg).unwrap() {
        let Some(r) = synthesize_small(&work_dir(&format!("synth-{module}")), &module, &text)
        else {
            return;
        };
        // Every memory bit is a flip-flop (generic synthesis maps the SRAMs to flip-flops too);
        // Yosys may drop register bits that are constant (the scan position's low bits).
        let desc = if module.contains("count") {
            CountTable::new(&cfg).unwrap().describe()
        } else {
            QueueTable::new(&cfg).unwrap().describe()
        };
        let mem_bits: u64 = desc
            .memories
            .iter()
            .map(|m| (m.width * m.depth) as u64)
            .sum();
        assert!(
            r.flip_flops >= mem_bits,
            "{module}: {} < {mem_bits}",
            r.flip_flops
        );
    }
}

#[test]
fn small_table_snapshots() {
    let cfg = small();
    insta::assert_snapshot!("count_table_small", count_table_verilog(&cfg).unwrap());
    insta::assert_snapshot!("queue_table_small", queue_table_verilog(&cfg).unwrap());
}

#[test]
fn generated_modules_follow_the_configuration() {
    let modules = table_modules(&HwConfig::default()).unwrap();
    let names: Vec<&str> = modules.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["treelet_count_table", "treelet_queue_table"]);
    let (count, queue) = (&modules[0].1, &modules[1].1);
    // The paper's sizes: 600 x {valid, 19-bit treelet, 12-bit count - 1}; 128 x 32 ray ids.
    assert!(count.contains("reg [599:0] entries_valid;"));
    assert!(count.contains("reg [30:0] entries [0:599];"));
    assert!(queue.contains("reg [383:0] rays [0:127];"));
    assert!(queue.contains("t[6:0] ^ t[13:7] ^ {2'd0, t[18:14]}"));
    for text in [count, queue] {
        assert!(!text.contains("initial"), "no initial blocks in RTL");
        assert!(text.contains("always @(posedge clk)"));
    }
    // An invalid configuration is an error naming the offending key, not a panic.
    let bad = HwConfig {
        count_table_entries: 1,
        ..HwConfig::default()
    };
    let err = count_table_verilog(&bad).unwrap_err().to_string();
    assert!(err.contains("count_table_entries"), "{err}");
    let bad = HwConfig {
        warp_size: 3,
        ..HwConfig::default()
    };
    let err = queue_table_verilog(&bad).unwrap_err().to_string();
    assert!(err.contains("warp_size"), "{err}");
}
