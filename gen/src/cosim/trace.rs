//! The Rust block's side of a co-simulation: its recorded run ([`Trace`]: each cycle's changed
//! input, output and register signals) and how the traced signals connect to the module's
//! ports ([`PortConn`]).

use super::waveform::desc_registers;
use super::RegSignal;
use crate::emit::is_identifier;
use crate::error::GenError;
use serde::Serialize;
use vtq_hdl::{Block, Dir, Signal, Signals};

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
    pub(super) fn end_of_cycle(&self) -> usize {
        self.inputs.len() + self.outputs.len() + self.registers.len()
    }

    /// The changes of cycle `c` (see [`Trace::changes`]).
    pub(super) fn cycle_changes(&self, c: usize) -> &[(u32, u64)] {
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
