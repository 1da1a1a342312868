//! Co-simulation: a Rust [`Block`] and its Verilog, cycle by cycle.
//!
//! [`record`] runs the Rust block from reset over a sequence of inputs and keeps, per cycle,
//! the flattened input and output [`vtq_hdl::Signals`]. [`write_testbench`] turns the trace into
//! a self-checking Verilog-2005 testbench that reads the vectors (each cycle's changed signals)
//! from a file with `$fscanf`, and [`run_cosim`] runs it with Icarus Verilog or Verilator and
//! parses the verdict.
//!
//! # Timing convention
//!
//! The Verilog module has ports `clk`, `rst` and one port per signal, named and sized like the
//! signals of the Rust port bundles. Every register updates on the rising edge of `clk`; `rst`
//! is synchronous and active high. The testbench:
//!
//! 1. holds `rst` high with all inputs zero for two rising edges, then drops it while `clk` is
//!    low: the registers now hold `Block::reset()`;
//! 2. for each cycle `k`, with `clk` low: applies the inputs of cycle `k`, waits 1 ns for the
//!    combinational logic to settle, and compares every output with the outputs that
//!    `Block::eval(regs_k, inputs_k)` returned (`!==`, so an `x` or `z` is a mismatch), and
//!    every register of [`Trace::registers`] the RTL declares with the Rust block's `regs_k`
//!    (a register whose RTL value has an `x` bit, storage the RTL does not reset, is not
//!    compared that cycle); then raises `clk` (the registers take `eval`'s next values) and
//!    lowers it again.
//!
//! So outputs are this cycle's combinational function of the registers and this cycle's inputs
//! (Mealy outputs, exactly `eval`'s first result); a registered output simply does not depend
//! on the inputs. The testbench prints every mismatch up to [`CosimOptions::max_reported`]
//! (`cosim: MISMATCH cycle C signal S expected E got G`) and always a final
//! `cosim: N cycles compared, M mismatches` line, where M counts (cycle, signal) pairs.

use crate::error::GenError;
use crate::tools::{create_dir, run, write_file};
use serde::Serialize;
use std::path::PathBuf;
use vtq_hdl::Block;

mod jobs;
mod replay;
mod rt_unit;
mod testbench;
mod trace;
mod waveform;
mod wiring;

pub use jobs::{random_jobs, replay_jobs, Blocks, Job, Recorded, RustVcd};
pub use replay::{
    datapath_tables, tests_and_hits, DatapathCall, ReplayInputs, RtUnitReplay, TreeletRtUnitReplay,
    REPLAY_MODULE, TREELET_REPLAY_MODULE,
};
pub use rt_unit::{RtUnitAllOutputs, RtUnitWithStatus};
pub use testbench::{vectors, write_testbench, write_testbench_with};
pub use trace::{record, record_with_registers, PortConn, SignalInfo, Trace};
pub use wiring::{wiring_ports, TreeletWiring};

use waveform::declares;
pub use waveform::{write_rust_vcd, RegSignal};

/// Name of the generated testbench module.
pub const TESTBENCH_TOP: &str = "cosim_tb";
/// File the vectors are written to (inside the work directory).
pub const VECTORS_FILE: &str = "cosim_vectors.hex";
/// File the testbench is written to (inside the work directory).
pub const TESTBENCH_FILE: &str = "cosim_tb.v";
/// File the RTL simulation's waveform is dumped to with [`CosimOptions::vcd`] (inside the work
/// directory).
pub const RTL_VCD_FILE: &str = "rtl.vcd";
/// File name [`write_rust_vcd`]'s callers use for the Rust block's waveform of the same run.
pub const RUST_VCD_FILE: &str = "rust.vcd";
/// Clock cycles of reset before cycle 0: cycle `k` of a run occupies `[10 (k + 2), 10 (k + 3))`
/// ns in the testbench, and [`write_rust_vcd`] numbers its cycles from here so both waveforms
/// put cycle `k` at the same time.
pub const RESET_CYCLES: u64 = 2;

/// Which simulator runs the testbench.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Simulator {
    /// Icarus Verilog (`iverilog -g2005` + `vvp`): quick to start, good for short runs.
    Icarus,
    /// Verilator (`--binary --timing`): slow to compile, fast to run.
    Verilator,
}

/// Where and how to run a co-simulation.
#[derive(Debug, Clone)]
pub struct CosimOptions {
    /// Simulator to use.
    pub simulator: Simulator,
    /// Directory for the testbench, vectors and simulator files (created if missing).
    pub work_dir: PathBuf,
    /// Mismatches printed individually (all are counted).
    pub max_reported: u32,
    /// Dump the RTL simulation's waveform to [`RTL_VCD_FILE`] in the work directory: the ports
    /// in scopes `inputs` and `outputs` and the registers the Rust trace names the same in scope
    /// `regs` (as [`vtq_hdl::trace`] names them), plus the DUT's own signals in scope `dut`.
    pub vcd: bool,
}

impl CosimOptions {
    /// Icarus Verilog in `work_dir`, reporting the first 10 mismatches.
    pub fn icarus(work_dir: impl Into<PathBuf>) -> Self {
        CosimOptions {
            simulator: Simulator::Icarus,
            work_dir: work_dir.into(),
            max_reported: 10,
            vcd: false,
        }
    }
}

/// One output that differed from the Rust model.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Mismatch {
    /// Cycle after reset (0-based).
    pub cycle: u64,
    /// Output signal name.
    pub signal: String,
    /// What the Rust block drove (hex).
    pub expected: String,
    /// What the Verilog drove (hex; may contain `x` or `z`).
    pub got: String,
}

/// The verdict of a co-simulation run.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct CosimResult {
    /// Simulator that ran it.
    pub simulator: Simulator,
    /// Cycles compared.
    pub cycles: u64,
    /// (cycle, signal) pairs that differed, outputs and registers.
    pub mismatches: u64,
    /// The first mismatches, in cycle order.
    pub reported: Vec<Mismatch>,
}

impl CosimResult {
    /// Every output matched in every cycle.
    pub fn passed(&self) -> bool {
        self.mismatches == 0
    }
}

impl std::fmt::Display for CosimResult {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "cosim ({:?}): {} cycles compared, {} mismatches",
            self.simulator, self.cycles, self.mismatches
        )?;
        for m in &self.reported {
            writeln!(
                f,
                "  cycle {} signal {}: expected {} got {}",
                m.cycle, m.signal, m.expected, m.got
            )?;
        }
        Ok(())
    }
}

/// Writes the testbench and vectors for `trace` into `opts.work_dir`, simulates them with the
/// DUT `sources` (comparing the outputs and the registers of `trace.registers` the sources
/// declare), and parses the verdict.
pub fn run_cosim(
    trace: &Trace,
    sources: &[PathBuf],
    opts: &CosimOptions,
) -> Result<CosimResult, GenError> {
    if trace.cycles() == 0 || trace.outputs.is_empty() {
        return Err(GenError::Cosim {
            block: trace.module.clone(),
            reason: "the trace has no cycles or no outputs to compare".to_string(),
        });
    }
    let dir = &opts.work_dir;
    create_dir(dir)?;
    let dir = std::fs::canonicalize(dir)
        .map_err(|e| GenError::io(format!("resolving {}", dir.display()), e))?;
    write_file(&dir.join(VECTORS_FILE), &vectors(trace))?;
    let mut files = vec![TESTBENCH_FILE.to_string()];
    let mut texts = String::new();
    for s in sources {
        let abs = std::fs::canonicalize(s)
            .map_err(|e| GenError::io(format!("finding Verilog source {}", s.display()), e))?;
        texts += &std::fs::read_to_string(&abs)
            .map_err(|e| GenError::io(format!("reading {}", abs.display()), e))?;
        files.push(abs.display().to_string());
    }
    // Only the registers the RTL declares as `<name>_q` (a hierarchical reference to a missing
    // one would not compile).
    let checked: Vec<usize> = (0..trace.registers.len())
        .filter(|&k| declares(&texts, &format!("{}_q", trace.registers[k].rtl)))
        .collect();
    let tb = write_testbench_with(trace, opts.max_reported, &checked, opts.vcd);
    write_file(&dir.join(TESTBENCH_FILE), &tb)?;
    let files: Vec<&str> = files.iter().map(String::as_str).collect();
    let output = match opts.simulator {
        Simulator::Icarus => {
            let mut args = vec!["-g2005", "-o", "cosim.vvp", "-s", TESTBENCH_TOP];
            args.extend(&files);
            run("iverilog", &args, &dir, false)?;
            run("vvp", &["-n", "cosim.vvp"], &dir, false)?.0.stdout
        }
        Simulator::Verilator => {
            let mut args = vec![
                "--binary",
                "-j",
                "2",
                "--timescale",
                "1ns/1ps",
                "-Wno-fatal",
                "-Wno-lint",
                "-Wno-style",
                "--top-module",
                TESTBENCH_TOP,
                "-o",
                "cosim",
            ];
            if opts.vcd {
                args.push("--trace");
            }
            args.extend(&files);
            run("verilator", &args, &dir, false)?;
            run("./obj_dir/cosim", &[], &dir, false)?.0.stdout
        }
    };
    parse_result(&output, opts.simulator, &trace.module)
}

/// Records `block` over `inputs` and co-simulates it against the Verilog `sources`.
pub fn cosim_block<B: Block>(
    block: &B,
    inputs: impl IntoIterator<Item = B::Inputs>,
    sources: &[PathBuf],
    opts: &CosimOptions,
) -> Result<CosimResult, GenError> {
    let trace = record(block, inputs)?;
    run_cosim(&trace, sources, opts)
}

/// A 64-bit hex value from the testbench without its leading zeros (`000a` -> `a`).
fn trim_hex(s: &str) -> String {
    let t = s.trim_start_matches('0');
    if t.is_empty() { "0" } else { t }.to_string()
}

/// Reads the testbench's `cosim:` lines.
fn parse_result(output: &str, simulator: Simulator, module: &str) -> Result<CosimResult, GenError> {
    let bad = |reason: String| GenError::Parse {
        tool: format!("{simulator:?} co-simulation of {module}"),
        reason,
    };
    let mut reported = Vec::new();
    let mut summary = None;
    for line in output.lines() {
        let Some(rest) = line.trim().strip_prefix("cosim: ") else {
            continue;
        };
        if let Some(m) = rest.strip_prefix("MISMATCH ") {
            let words: Vec<&str> = m.split_whitespace().collect();
            match words.as_slice() {
                ["cycle", c, "signal", s, "expected", e, "got", g] => reported.push(Mismatch {
                    cycle: c
                        .parse()
                        .map_err(|_| bad(format!("bad cycle in `{line}`")))?,
                    signal: s.to_string(),
                    expected: trim_hex(e),
                    got: trim_hex(g),
                }),
                _ => return Err(bad(format!("malformed mismatch line `{line}`"))),
            }
        } else {
            let words: Vec<&str> = rest.split_whitespace().collect();
            if let [n, "cycles", "compared,", m, "mismatches"] = words.as_slice() {
                let n: u64 = n
                    .parse()
                    .map_err(|_| bad(format!("bad count in `{line}`")))?;
                let m: u64 = m
                    .parse()
                    .map_err(|_| bad(format!("bad count in `{line}`")))?;
                summary = Some((n, m));
            }
        }
    }
    let (cycles, mismatches) = summary.ok_or_else(|| {
        bad(format!(
            "no `cosim: N cycles compared, M mismatches` line in:\n{output}"
        ))
    })?;
    Ok(CosimResult {
        simulator,
        cycles,
        mismatches,
        reported,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_results() {
        let out = "VCD info\ncosim: MISMATCH cycle 7 signal count expected 3 got 4\n\
                   cosim: 100 cycles compared, 2 mismatches\n";
        let r = parse_result(out, Simulator::Icarus, "m").unwrap();
        assert_eq!(r.cycles, 100);
        assert_eq!(r.mismatches, 2);
        assert_eq!(r.reported[0].cycle, 7);
        assert_eq!(r.reported[0].signal, "count");
        assert!(!r.passed());
        assert_eq!(trim_hex("000000000000000a"), "a");
        assert_eq!(trim_hex("0000"), "0");
        assert_eq!(trim_hex("00000000000000xx"), "xx");
        assert!(parse_result("nothing", Simulator::Icarus, "m").is_err());
    }
}
