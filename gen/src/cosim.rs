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

use crate::emit::{is_identifier, range};
use crate::error::GenError;
use crate::tools::{create_dir, run, write_file};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::PathBuf;
use vtq_hdl::{Block, Dir, Signal, Signals};

mod jobs;
mod replay;
mod rt_unit;
mod waveform;
mod wiring;

pub use jobs::{random_jobs, replay_jobs, Blocks, Job, Recorded, RustVcd};
pub use replay::{
    datapath_tables, tests_and_hits, DatapathCall, ReplayInputs, RtUnitReplay, TreeletRtUnitReplay,
    REPLAY_MODULE, TREELET_REPLAY_MODULE,
};
pub use rt_unit::{RtUnitAllOutputs, RtUnitWithStatus};
pub use wiring::{wiring_ports, TreeletWiring};

use waveform::{declares, desc_registers, vcd_scopes};
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

/// Name and width of one traced signal.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct SignalInfo {
    /// Signal (port) name.
    pub name: String,
    /// Width in bits.
    pub width: u32,
}

/// The Rust block's inputs and outputs over a run, one row per cycle.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Trace {
    /// Verilog module name of the block.
    pub module: String,
    /// Input signals, in the order of the input bundle.
    pub inputs: Vec<SignalInfo>,
    /// Output signals, in the order of the output bundle.
    pub outputs: Vec<SignalInfo>,
    /// The module's ports in the order of the block description, each with the signals it is
    /// made of.
    pub ports: Vec<PortConn>,
    /// The Rust block's register signals ([`Block::reg_signals`]) that are registers of the
    /// block description, with where the RTL holds them, each cycle's start value recorded:
    /// the testbench compares them every cycle and the waveform of [`CosimOptions::vcd`]
    /// shows them under the same names. A replay block has none of its own: its replayed
    /// block's are [`RtUnitReplay::registers`] and [`TreeletRtUnitReplay::registers`]
    /// ([`record_with_registers`]).
    pub registers: Vec<RegSignal>,
    /// Per cycle, the signals whose value differs from the cycle before (at cycle 0, from
    /// zero) as `(index, value)`, the index counting the inputs, the outputs, then the
    /// registers (their values at the cycle's start): most of a
    /// block's wide ports (ray records, stacks) are zero or unchanged most cycles, so a long
    /// run of a large configuration stays small.
    changes: Vec<(u32, u64)>,
    /// Where each cycle's changes start in `changes`.
    starts: Vec<usize>,
}

impl Trace {
    /// Cycles recorded.
    pub fn cycles(&self) -> usize {
        self.starts.len()
    }

    /// Every cycle's values in order: the inputs (in [`Trace::inputs`] order) then the outputs
    /// (in [`Trace::outputs`] order).
    pub fn rows(&self) -> impl Iterator<Item = Vec<u64>> + '_ {
        let mut row = vec![0u64; self.inputs.len() + self.outputs.len()];
        (0..self.cycles()).map(move |c| {
            for &(i, v) in self.cycle_changes(c) {
                if let Some(x) = row.get_mut(i as usize) {
                    *x = v;
                }
            }
            row.clone()
        })
    }

    /// The index that ends a cycle in the vectors: one past the last signal's (inputs,
    /// outputs, registers).
    fn end_of_cycle(&self) -> usize {
        self.inputs.len() + self.outputs.len() + self.registers.len()
    }

    /// The changes of cycle `c` (see [`Trace::changes`]).
    fn cycle_changes(&self, c: usize) -> &[(u32, u64)] {
        let end = self
            .starts
            .get(c + 1)
            .copied()
            .unwrap_or(self.changes.len());
        &self.changes[self.starts[c]..end]
    }

    /// Appends a cycle whose values are `values` (inputs, outputs, registers); `last` holds
    /// the previous cycle's and becomes this one's.
    fn push_cycle(&mut self, last: &mut [u64], values: impl Iterator<Item = u64>) {
        self.starts.push(self.changes.len());
        for (i, (old, v)) in last.iter_mut().zip(values).enumerate() {
            if *old != v {
                *old = v;
                self.changes.push((i as u32, v));
            }
        }
    }
}

/// Runs `block` from reset over `inputs` and records every cycle's signals, and the start
/// values of its registers that are registers of its description. The signal lists must be
/// the same every cycle, every value must fit its width, and the signals must match the
/// block description's ports (same names, directions and widths, every port covered).
pub fn record<B: Block>(
    block: &B,
    inputs: impl IntoIterator<Item = B::Inputs>,
) -> Result<Trace, GenError> {
    let registers = desc_registers(&block.describe(), &block.reg_signals(&block.reset()));
    record_with_registers(block, inputs, registers)
}

/// [`record`] with the registers to record given: those of a block whose description has
/// none of its own, a replay wrapper's ([`RtUnitReplay::registers`]).
pub fn record_with_registers<B: Block>(
    block: &B,
    inputs: impl IntoIterator<Item = B::Inputs>,
    mut registers: Vec<RegSignal>,
) -> Result<Trace, GenError> {
    let desc = block.describe();
    let fail = |reason: String| GenError::Cosim {
        block: desc.name.clone(),
        reason,
    };
    let mut regs = block.reset();
    let mut trace: Option<Trace> = None;
    let mut last: Vec<u64> = Vec::new();
    // Where each recorded register lies in the block's register signals (the same list every
    // cycle).
    let place: Vec<usize> = {
        let names = block.reg_signals(&regs);
        registers
            .iter()
            .map(|r| {
                names
                    .iter()
                    .position(|s| s.name == r.name)
                    .ok_or_else(|| fail(format!("register `{}` is not a register signal", r.name)))
            })
            .collect::<Result<_, _>>()?
    };
    for (cycle, inp) in inputs.into_iter().enumerate() {
        let now: Vec<u64> = if place.is_empty() {
            Vec::new()
        } else {
            let sigs = block.reg_signals(&regs);
            place.iter().map(|&k| sigs[k].value).collect()
        };
        let (out, next) = block.eval(&regs, &inp);
        regs = next;
        let (mut ins, mut outs) = (inp.signals(), out.signals());
        ins.extend(inp.bulk_signals());
        outs.extend(out.bulk_signals());
        let t = match trace.as_mut() {
            Some(t) => t,
            None => trace.insert(Trace {
                module: desc.name.clone(),
                inputs: infos(&ins),
                outputs: infos(&outs),
                ports: Vec::new(),
                registers: std::mem::take(&mut registers),
                changes: Vec::new(),
                starts: Vec::new(),
            }),
        };
        for (kind, infos, sigs) in [("input", &t.inputs, &ins), ("output", &t.outputs, &outs)] {
            if sigs.len() != infos.len()
                || sigs
                    .iter()
                    .zip(infos.iter())
                    .any(|(s, i)| s.name != i.name || s.width != i.width)
            {
                return Err(fail(format!(
                    "the {kind} signals changed at cycle {cycle}: they must be the same list \
                     every cycle"
                )));
            }
            if let Some(s) = sigs
                .iter()
                .find(|s| s.width < 64 && s.value >> s.width != 0)
            {
                return Err(fail(format!(
                    "{kind} `{}` = {} does not fit its {} bits at cycle {cycle}",
                    s.name, s.value, s.width
                )));
            }
        }
        last.resize(ins.len() + outs.len() + now.len(), 0);
        let values = ins.iter().chain(outs.iter()).map(|s| s.value);
        t.push_cycle(&mut last, values.chain(now.iter().copied()));
    }
    let mut trace = trace.ok_or_else(|| fail("no input cycles to simulate".to_string()))?;
    for s in trace.inputs.iter().chain(trace.outputs.iter()) {
        if !is_identifier(&s.name) || s.name == "clk" || s.name == "rst" {
            return Err(fail(format!(
                "signal `{}` cannot be a Verilog port name",
                s.name
            )));
        }
    }
    trace.ports = connect_ports(&desc, &trace.inputs, &trace.outputs).map_err(fail)?;
    Ok(trace)
}

/// How one port of the module is connected in the testbench: the traced signals it is made of,
/// most significant first. A plain port is one signal of its name and width; a packed port
/// (the `lanes` rows of [`vtq_hdl::bundle!`]: `width x count` bits, lane `i` in bits
/// `[i*width +: width]`) is traced as the signals `<port>_0` .. `<port>_<count-1>` and connected
/// as their concatenation, lane `count - 1` first; so is a bulk port, as its 64-bit words
/// ([`vtq_hdl::Signals::bulk_signals`], the last word possibly narrower).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct PortConn {
    /// Port name.
    pub name: String,
    /// An output port (an input otherwise).
    pub output: bool,
    /// The signals, most significant first.
    pub signals: Vec<String>,
}

/// Matches the traced signals with the description's ports: every port is one signal of its
/// name, direction and width, or the lanes `<port>_<i>` of a packed port; every signal belongs
/// to exactly one port.
fn connect_ports(
    desc: &vtq_hdl::BlockDesc,
    inputs: &[SignalInfo],
    outputs: &[SignalInfo],
) -> Result<Vec<PortConn>, String> {
    let mut used: std::collections::BTreeSet<(bool, &str)> = Default::default();
    let mut conns = Vec::new();
    for p in &desc.ports {
        let output = p.dir == Dir::Out;
        let (sigs, other) = if output {
            (outputs, inputs)
        } else {
            (inputs, outputs)
        };
        let found = sigs
            .iter()
            .find(|s| s.name == p.name)
            .map(|s| (s, output))
            .or_else(|| {
                other
                    .iter()
                    .find(|s| s.name == p.name)
                    .map(|s| (s, !output))
            });
        if let Some((s, s_output)) = found {
            if s_output != output || s.width != p.width {
                return Err(format!(
                    "signal `{}` ({}, {} bits) disagrees with its port ({:?}, {} bits)",
                    s.name,
                    if s_output { "Out" } else { "In" },
                    s.width,
                    p.dir,
                    p.width
                ));
            }
            used.insert((output, s.name.as_str()));
            conns.push(PortConn {
                name: p.name.clone(),
                output,
                signals: vec![s.name.clone()],
            });
            continue;
        }
        // A packed port: its lanes `<port>_0`, `<port>_1`, ... in order, of equal widths.
        let mut lanes: Vec<&SignalInfo> = Vec::new();
        while let Some(s) = sigs
            .iter()
            .find(|s| s.name == format!("{}_{}", p.name, lanes.len()))
        {
            lanes.push(s);
        }
        let bits: u64 = lanes.iter().map(|s| s.width as u64).sum();
        // Equal lanes; a bulk port's words are 64 bits but the last.
        let even = lanes.split_last().is_some_and(|(last, rest)| {
            rest.iter().all(|s| s.width == lanes[0].width) && last.width <= lanes[0].width
        });
        if lanes.is_empty() || !even || bits != p.width as u64 {
            return Err(format!(
                "port `{}` has no signal in the port bundles",
                p.name
            ));
        }
        for s in &lanes {
            used.insert((output, s.name.as_str()));
        }
        conns.push(PortConn {
            name: p.name.clone(),
            output,
            signals: lanes.iter().rev().map(|s| s.name.clone()).collect(),
        });
    }
    for (output, sigs) in [(false, inputs), (true, outputs)] {
        if let Some(s) = sigs
            .iter()
            .find(|s| !used.contains(&(output, s.name.as_str())))
        {
            return Err(format!(
                "signal `{}` is not a port of the block description",
                s.name
            ));
        }
    }
    Ok(conns)
}

fn infos(sigs: &[Signal]) -> Vec<SignalInfo> {
    sigs.iter()
        .map(|s| SignalInfo {
            name: s.name.clone(),
            width: s.width,
        })
        .collect()
}

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

/// The vectors file for `trace`: per cycle one line `<index> <value>` (hex) for each signal
/// whose value changed since the cycle before (at cycle 0, each nonzero one), the index
/// counting the inputs, the outputs, then the registers, and a line
/// `<inputs + outputs + registers> 0` ending the cycle.
pub fn vectors(trace: &Trace) -> String {
    let end = trace.end_of_cycle();
    let mut out = String::new();
    for c in 0..trace.cycles() {
        for &(i, v) in trace.cycle_changes(c) {
            let _ = writeln!(out, "{i:x} {v:x}");
        }
        let _ = writeln!(out, "{end:x} 0");
    }
    out
}

/// The self-checking testbench for `trace` (see the module documentation for its timing),
/// comparing the outputs only.
pub fn write_testbench(trace: &Trace, max_reported: u32) -> String {
    write_testbench_with(trace, max_reported, &[], false)
}

/// The testbench of [`write_testbench`] that also compares the registers
/// `trace.registers[k]` for each `k` of `checked` (the DUT's `<rtl>_q` or a bank member's
/// bits of it, at `dut.<path>`; the RTL must declare them), a mismatch reported as signal
/// `regs.<name>`, and with `vcd` dumps the waveform to [`RTL_VCD_FILE`]: the ports under the
/// Rust trace's scopes and names (`inputs.<signal>`, `outputs.<signal>`; a packed port's lanes
/// one signal each), the checked registers as `regs.<name>`, and the DUT's own signals (scope
/// `dut`, one level).
pub fn write_testbench_with(
    trace: &Trace,
    max_reported: u32,
    checked: &[usize],
    vcd: bool,
) -> String {
    let registers: Vec<RegSignal> = checked
        .iter()
        .map(|&k| trace.registers[k].clone())
        .collect();
    let vcd = vcd.then_some(registers.as_slice());
    let n_in = trace.inputs.len();
    let n_out = trace.outputs.len();
    let end = trace.end_of_cycle();
    let mut v = String::new();
    let _ = writeln!(
        v,
        "// Self-checking co-simulation testbench for {}, generated by vtq-gen.",
        trace.module
    );
    let _ = writeln!(
        v,
        "// Vectors: {VECTORS_FILE}, per cycle the signals that changed (index, value) and an \
         end-of-cycle line (index {end})."
    );
    // 1 ns precision: every delay is whole nanoseconds, and the waveform's times are in ns.
    let _ = writeln!(v, "`timescale 1ns/1ns");
    let _ = writeln!(v, "module {TESTBENCH_TOP};");
    let _ = writeln!(v, "    localparam integer CYCLES = {};", trace.cycles());
    let _ = writeln!(v, "    localparam integer MAX_REPORTED = {max_reported};");
    let _ = writeln!(v, "    localparam integer END_OF_CYCLE = {end};");
    let _ = writeln!(v, "    reg clk = 1'b0;");
    let _ = writeln!(v, "    reg rst = 1'b1;");
    let _ = writeln!(v, "    integer fd;");
    let _ = writeln!(v, "    integer got_fields;");
    let _ = writeln!(v, "    reg [31:0] v_index;");
    let _ = writeln!(v, "    reg [63:0] v_value;");
    let _ = writeln!(v, "    integer cycle;");
    let _ = writeln!(v, "    integer mismatches;");
    for s in &trace.inputs {
        let _ = writeln!(v, "    reg  {}i_{};", range(s.width), s.name);
    }
    for s in &trace.outputs {
        let _ = writeln!(v, "    wire {}o_{};", range(s.width), s.name);
        let _ = writeln!(v, "    reg  {}e_{};", range(s.width), s.name);
    }
    // The checked registers: q_ the RTL's, x_ the Rust block's at the cycle's start.
    for r in &registers {
        let _ = writeln!(
            v,
            "    wire {}q_{} = {};",
            range(r.width),
            r.name,
            r.source()
        );
        let _ = writeln!(v, "    reg  {}x_{};", range(r.width), r.name);
    }
    let _ = writeln!(v);
    let _ = writeln!(v, "    {} dut (", trace.module);
    let mut conns = vec![
        "        .clk(clk)".to_string(),
        "        .rst(rst)".to_string(),
    ];
    conns.extend(trace.ports.iter().map(|p| {
        let prefix = if p.output { "o_" } else { "i_" };
        let sigs: Vec<String> = p.signals.iter().map(|s| format!("{prefix}{s}")).collect();
        match sigs.as_slice() {
            [one] => format!("        .{}({one})", p.name),
            _ => format!("        .{}({{{}}})", p.name, sigs.join(", ")),
        }
    }));
    let _ = writeln!(v, "{}", conns.join(",\n"));
    let _ = writeln!(v, "    );");
    let _ = writeln!(v);
    let _ = writeln!(v, "    task check(input integer c, input [8*64-1:0] name, input [63:0] expected, input [63:0] got);");
    let _ = writeln!(v, "        begin");
    let _ = writeln!(v, "            if (got !== expected) begin");
    let _ = writeln!(v, "                mismatches = mismatches + 1;");
    let _ = writeln!(v, "                if (mismatches <= MAX_REPORTED)");
    let _ = writeln!(v, "                    $display(\"cosim: MISMATCH cycle %0d signal %0s expected %h got %h\", c, name, expected, got);");
    let _ = writeln!(v, "            end");
    let _ = writeln!(v, "        end");
    let _ = writeln!(v, "    endtask");
    let _ = writeln!(v);
    // A register holding an x bit is storage the RTL does not reset: not compared.
    let _ = writeln!(v, "    task check_reg(input integer c, input [8*64-1:0] name, input [63:0] expected, input [63:0] got);");
    let _ = writeln!(v, "        begin");
    let _ = writeln!(
        v,
        "            if (^got !== 1'bx) check(c, name, expected, got);"
    );
    let _ = writeln!(v, "        end");
    let _ = writeln!(v, "    endtask");
    let _ = writeln!(v);
    // One cycle's changes: each sets an input, an expected output or an expected register.
    let _ = writeln!(v, "    task apply(input [31:0] index, input [63:0] value);");
    let _ = writeln!(v, "        begin");
    let _ = writeln!(v, "            case (index)");
    for (i, s) in trace.inputs.iter().enumerate() {
        let _ = writeln!(
            v,
            "                {i}: i_{} = value[{}:0];",
            s.name,
            s.width - 1
        );
    }
    for (j, s) in trace.outputs.iter().enumerate() {
        let _ = writeln!(
            v,
            "                {}: e_{} = value[{}:0];",
            n_in + j,
            s.name,
            s.width - 1
        );
    }
    for (&k, r) in checked.iter().zip(&registers) {
        let _ = writeln!(
            v,
            "                {}: x_{} = value[{}:0];",
            n_in + n_out + k,
            r.name,
            r.width - 1
        );
    }
    let _ = writeln!(v, "                default: ;");
    let _ = writeln!(v, "            endcase");
    let _ = writeln!(v, "        end");
    let _ = writeln!(v, "    endtask");
    let _ = writeln!(v);
    if let Some(registers) = vcd {
        v.push_str(&vcd_scopes(trace, registers));
        let _ = writeln!(v);
    }
    let _ = writeln!(v, "    initial begin");
    if let Some(registers) = vcd {
        let _ = writeln!(v, "        $dumpfile(\"{RTL_VCD_FILE}\");");
        let _ = writeln!(
            v,
            "        $dumpvars(0, {TESTBENCH_TOP}.clk, {TESTBENCH_TOP}.rst, {TESTBENCH_TOP}.cycle);"
        );
        for (scope, n) in [
            ("inputs", trace.inputs.len()),
            ("outputs", trace.outputs.len()),
            ("regs", registers.len()),
        ] {
            if n > 0 {
                let _ = writeln!(v, "        $dumpvars(1, {TESTBENCH_TOP}.{scope});");
            }
        }
        let _ = writeln!(v, "        $dumpvars(1, {TESTBENCH_TOP}.dut);");
    }
    let _ = writeln!(v, "        fd = $fopen(\"{VECTORS_FILE}\", \"r\");");
    let _ = writeln!(v, "        if (fd == 0) begin");
    let _ = writeln!(
        v,
        "            $display(\"cosim: cannot open {VECTORS_FILE}\");"
    );
    let _ = writeln!(v, "            $finish;");
    let _ = writeln!(v, "        end");
    let _ = writeln!(v, "        mismatches = 0;");
    for s in &trace.inputs {
        let _ = writeln!(v, "        i_{} = {}'d0;", s.name, s.width);
    }
    for s in &trace.outputs {
        let _ = writeln!(v, "        e_{} = {}'d0;", s.name, s.width);
    }
    for r in &registers {
        let _ = writeln!(v, "        x_{} = {}'d0;", r.name, r.width);
    }
    let _ = writeln!(
        v,
        "        // Reset: two rising edges with rst high, then rst low while clk is low."
    );
    let _ = writeln!(v, "        #5 clk = 1'b1; #5 clk = 1'b0;");
    let _ = writeln!(v, "        #5 clk = 1'b1; #5 clk = 1'b0;");
    let _ = writeln!(v, "        rst = 1'b0;");
    let _ = writeln!(
        v,
        "        for (cycle = 0; cycle < CYCLES; cycle = cycle + 1) begin"
    );
    let _ = writeln!(
        v,
        "            got_fields = $fscanf(fd, \"%h %h\\n\", v_index, v_value);"
    );
    let _ = writeln!(
        v,
        "            while (got_fields == 2 && v_index != END_OF_CYCLE) begin"
    );
    let _ = writeln!(v, "                apply(v_index, v_value);");
    let _ = writeln!(
        v,
        "                got_fields = $fscanf(fd, \"%h %h\\n\", v_index, v_value);"
    );
    let _ = writeln!(v, "            end");
    let _ = writeln!(v, "            if (got_fields != 2) begin");
    let _ = writeln!(
        v,
        "                $display(\"cosim: {VECTORS_FILE} ends before cycle %0d\", cycle);"
    );
    let _ = writeln!(v, "                $finish;");
    let _ = writeln!(v, "            end");
    let _ = writeln!(v, "            #1;");
    // One comparison of all outputs (and one of all registers) per cycle; the per-signal checks
    // (which count and report each mismatching signal) run only when it fails, which keeps long
    // runs fast.
    let outputs: Vec<(&str, u32)> = trace
        .outputs
        .iter()
        .map(|s| (s.name.as_str(), s.width))
        .collect();
    emit_compare(&mut v, &outputs, ("o_", "e_"), "check", "");
    let regs: Vec<(&str, u32)> = registers
        .iter()
        .map(|r| (r.name.as_str(), r.width))
        .collect();
    emit_compare(&mut v, &regs, ("q_", "x_"), "check_reg", "regs.");
    let _ = writeln!(v, "            #4 clk = 1'b1;");
    let _ = writeln!(v, "            #5 clk = 1'b0;");
    let _ = writeln!(v, "        end");
    let _ = writeln!(v, "        $fclose(fd);");
    let _ = writeln!(
        v,
        "        $display(\"cosim: %0d cycles compared, %0d mismatches\", CYCLES, mismatches);"
    );
    let _ = writeln!(v, "        $finish;");
    let _ = writeln!(v, "    end");
    let _ = writeln!(v, "endmodule");
    v
}

/// A cycle's comparison of `signals` (name, width) in the testbench: one `!==` of all the
/// `<got prefix><name>` against all the `<expected prefix><name>`, and when it fails a call of
/// `task` for each, reporting it as `<label><name>`; nothing for no signals.
fn emit_compare(
    v: &mut String,
    signals: &[(&str, u32)],
    (got, expected): (&str, &str),
    task: &str,
    label: &str,
) {
    if signals.is_empty() {
        return;
    }
    let all = |prefix: &str| {
        signals
            .iter()
            .map(|(name, _)| format!("{prefix}{name}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let _ = writeln!(
        v,
        "            if ({{{}}} !== {{{}}}) begin",
        all(got),
        all(expected)
    );
    for &(name, width) in signals {
        let _ = writeln!(
            v,
            "                {task}(cycle, \"{label}{name}\", {}, {});",
            pad64(&format!("{expected}{name}"), width),
            pad64(&format!("{got}{name}"), width)
        );
    }
    let _ = writeln!(v, "            end");
}

/// `expr` of `width` bits zero-extended to the check tasks' 64-bit arguments.
fn pad64(expr: &str, width: u32) -> String {
    if width >= 64 {
        expr.to_string()
    } else {
        format!("{{{}'d0, {expr}}}", 64 - width)
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
