//! Cycle traces of blocks as VCD files (readable in GTKWave), and reading them back.
//!
//! A [`Tracer`] records, every cycle, the flattened [`Signals`] of a block's inputs and outputs
//! and its registers as the block lists them ([`Block::reg_signals`], as they are at the start of
//! the cycle, before the clock edge). The VCD
//! has one module named after the block with scopes `inputs`, `outputs` and `regs`, plus a `clk`
//! wire: cycle `t` occupies times `[10 t, 10 t + 10)` ns, with `clk` high from `10 t` and low
//! from `10 t + 5`, and a final timestamp `10 N` marks the end of `N` cycles.
//! [`read_vcd`] turns such a file back into per-cycle values keyed by `scope.signal` name.

use crate::block::{Block, Signal, Signals};
use std::collections::BTreeMap;
use std::io::{self, BufRead, Write};
use std::path::Path;
use vcd::{Command, IdCode, ScopeItem, TimescaleUnit, Value};

/// Nanoseconds per clock cycle in written traces.
pub const CYCLE_NS: u64 = 10;

/// Scope names of the three signal groups, in file order.
const GROUPS: [&str; 3] = ["inputs", "outputs", "regs"];

/// A trace could not be recorded, written or read.
#[derive(Debug, thiserror::Error)]
pub enum TraceError {
    /// A cycle's signals differ in names or widths from the first cycle's.
    #[error("cycle {cycle}: signal layout changed ({detail})")]
    Layout {
        /// Cycle being recorded.
        cycle: usize,
        /// What differs.
        detail: String,
    },
    /// A signal's value does not fit its width.
    #[error("cycle {cycle}: signal {name} value {value} does not fit in {width} bits")]
    Width {
        /// Cycle being recorded.
        cycle: usize,
        /// Signal name.
        name: String,
        /// Value.
        value: u64,
        /// Declared width.
        width: u32,
    },
    /// Writing the VCD failed.
    #[error("writing VCD: {0}")]
    Write(#[source] io::Error),
    /// Reading or parsing the VCD failed.
    #[error("reading VCD: {0}")]
    Read(#[source] io::Error),
    /// The VCD is well-formed but not a trace this module can interpret.
    #[error("VCD content: {0}")]
    Content(String),
}

/// Records per-cycle signal values of one block and writes them as VCD.
#[derive(Debug, Clone)]
pub struct Tracer {
    module: String,
    /// (group index, name, width) of every signal, fixed by the first recorded cycle.
    layout: Vec<(usize, String, u32)>,
    cycles: Vec<Vec<u64>>,
}

impl Tracer {
    /// An empty trace of the block named `module` (a legal Verilog identifier).
    pub fn new(module: &str) -> Self {
        Tracer {
            module: module.to_string(),
            layout: Vec::new(),
            cycles: Vec::new(),
        }
    }

    /// Number of recorded cycles.
    pub fn cycles(&self) -> usize {
        self.cycles.len()
    }

    /// Records one cycle: the inputs presented, the outputs driven and the registers' signals at
    /// the start of the cycle.
    pub fn record(
        &mut self,
        inputs: &impl Signals,
        outputs: &impl Signals,
        regs: Vec<Signal>,
    ) -> Result<(), TraceError> {
        let cycle = self.cycles.len();
        let groups: [Vec<Signal>; 3] = [inputs.signals(), outputs.signals(), regs];
        let flat: Vec<(usize, Signal)> = groups
            .into_iter()
            .enumerate()
            .flat_map(|(g, sigs)| sigs.into_iter().map(move |s| (g, s)))
            .collect();
        if cycle == 0 {
            self.layout = flat
                .iter()
                .map(|(g, s)| (*g, s.name.clone(), s.width))
                .collect();
        } else if flat.len() != self.layout.len()
            || flat
                .iter()
                .zip(&self.layout)
                .any(|((g, s), (lg, ln, lw))| g != lg || &s.name != ln || s.width != *lw)
        {
            return Err(TraceError::Layout {
                cycle,
                detail: format!(
                    "{} signals now, {} in cycle 0, or a name/width differs",
                    flat.len(),
                    self.layout.len()
                ),
            });
        }
        let mut values = Vec::with_capacity(flat.len());
        for (_, s) in flat {
            if s.width == 0 || (s.width < 64 && s.value >> s.width != 0) || s.width > 64 {
                return Err(TraceError::Width {
                    cycle,
                    name: s.name,
                    value: s.value,
                    width: s.width,
                });
            }
            values.push(s.value);
        }
        self.cycles.push(values);
        Ok(())
    }

    /// One clock cycle of `block`: evaluates it, records inputs, outputs and the registers
    /// before the edge, updates the registers and returns the outputs.
    pub fn step<B: Block>(
        &mut self,
        block: &B,
        regs: &mut B::Regs,
        inputs: &B::Inputs,
    ) -> Result<B::Outputs, TraceError> {
        let (out, next) = block.eval(regs, inputs);
        self.record(inputs, &out, block.reg_signals(regs))?;
        *regs = next;
        Ok(out)
    }

    /// Writes the trace as VCD.
    pub fn write_vcd(&self, w: impl Write) -> Result<(), TraceError> {
        self.write_inner(w).map_err(TraceError::Write)
    }

    /// Writes the trace as a VCD file at `path`.
    pub fn write_vcd_file(&self, path: &Path) -> Result<(), TraceError> {
        let f = std::fs::File::create(path).map_err(|e| {
            TraceError::Write(io::Error::new(
                e.kind(),
                format!("creating {}: {e}", path.display()),
            ))
        })?;
        self.write_vcd(io::BufWriter::new(f))
    }

    fn write_inner(&self, w: impl Write) -> io::Result<()> {
        let mut v = vcd::Writer::new(w);
        v.timescale(1, TimescaleUnit::NS)?;
        v.add_module(&self.module)?;
        let clk = v.add_wire(1, "clk")?;
        let mut ids = Vec::with_capacity(self.layout.len());
        for (g, group) in GROUPS.iter().enumerate() {
            v.add_module(group)?;
            for (lg, name, width) in &self.layout {
                if *lg == g {
                    ids.push((v.add_wire(*width, name)?, *width));
                }
            }
            v.upscope()?;
        }
        v.upscope()?;
        v.enddefinitions()?;
        // `ids` follows group order; the layout is already grouped (inputs, outputs, regs).
        let mut prev: Option<&Vec<u64>> = None;
        for (t, values) in self.cycles.iter().enumerate() {
            v.timestamp(t as u64 * CYCLE_NS)?;
            v.change_scalar(clk, Value::V1)?;
            for (i, (&(id, width), &value)) in ids.iter().zip(values).enumerate() {
                if prev.is_some_and(|p| p[i] == value) {
                    continue;
                }
                change(&mut v, id, width, value)?;
            }
            v.timestamp(t as u64 * CYCLE_NS + CYCLE_NS / 2)?;
            v.change_scalar(clk, Value::V0)?;
            prev = Some(values);
        }
        v.timestamp(self.cycles.len() as u64 * CYCLE_NS)?;
        v.flush()
    }
}

fn change<W: Write>(v: &mut vcd::Writer<W>, id: IdCode, width: u32, value: u64) -> io::Result<()> {
    if width == 1 {
        v.change_scalar(id, value & 1 == 1)
    } else {
        v.change_vector(
            id,
            (0..width).rev().map(|b| Value::from((value >> b) & 1 == 1)),
        )
    }
}

/// Per-cycle signal values read back from a VCD trace.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VcdTrace {
    /// Signal names (`scope.name`, e.g. `outputs.ready`, and `clk`) with widths, in file order.
    pub signals: Vec<(String, u32)>,
    /// `values[cycle][i]` is signal `i`'s value during `cycle`.
    pub values: Vec<Vec<u64>>,
}

impl VcdTrace {
    /// Number of cycles.
    pub fn cycles(&self) -> usize {
        self.values.len()
    }

    /// The value of signal `name` (`scope.name`) in `cycle`, if both exist.
    pub fn value(&self, name: &str, cycle: usize) -> Option<u64> {
        let i = self.signals.iter().position(|(n, _)| n == name)?;
        self.values.get(cycle).map(|v| v[i])
    }
}

/// Reads a VCD written by [`Tracer`] (one module, scopes nested below it, a [`CYCLE_NS`] clock
/// period) into per-cycle values: cycle `t` holds the values as of time `CYCLE_NS * t` after
/// that time's changes; the last cycle is the last one whose start precedes the final timestamp.
pub fn read_vcd(r: impl BufRead) -> Result<VcdTrace, TraceError> {
    let mut parser = vcd::Parser::new(r);
    let header = parser.parse_header().map_err(TraceError::Read)?;
    let mut signals = Vec::new();
    let mut by_code: BTreeMap<IdCode, Vec<usize>> = BTreeMap::new();
    let top = match header.items.as_slice() {
        [ScopeItem::Scope(s)] => s,
        _ => {
            return Err(TraceError::Content(
                "expected exactly one top-level module".into(),
            ))
        }
    };
    collect_vars(&top.items, "", &mut signals, &mut by_code)?;
    let mut current = vec![0u64; signals.len()];
    let mut values = Vec::new();
    for cmd in parser {
        match cmd.map_err(TraceError::Read)? {
            Command::Timestamp(ts) => {
                // Every cycle start before `ts` is now final: sample it.
                while (values.len() as u64) * CYCLE_NS < ts {
                    values.push(current.clone());
                }
            }
            Command::ChangeScalar(id, v) => set(&by_code, &mut current, id, &[v])?,
            Command::ChangeVector(id, v) => {
                let bits: Vec<Value> = v.iter().collect();
                set(&by_code, &mut current, id, &bits)?;
            }
            _ => {}
        }
    }
    Ok(VcdTrace { signals, values })
}

fn collect_vars(
    items: &[ScopeItem],
    prefix: &str,
    signals: &mut Vec<(String, u32)>,
    by_code: &mut BTreeMap<IdCode, Vec<usize>>,
) -> Result<(), TraceError> {
    for item in items {
        match item {
            ScopeItem::Var(var) => {
                if var.size == 0 || var.size > 64 {
                    return Err(TraceError::Content(format!(
                        "signal {} has width {} (1..=64 supported)",
                        var.reference, var.size
                    )));
                }
                by_code.entry(var.code).or_default().push(signals.len());
                signals.push((format!("{prefix}{}", var.reference), var.size));
            }
            ScopeItem::Scope(s) => {
                collect_vars(
                    &s.items,
                    &format!("{prefix}{}.", s.identifier),
                    signals,
                    by_code,
                )?;
            }
            _ => {}
        }
    }
    Ok(())
}

fn set(
    by_code: &BTreeMap<IdCode, Vec<usize>>,
    current: &mut [u64],
    id: IdCode,
    bits: &[Value],
) -> Result<(), TraceError> {
    let mut value = 0u64;
    for b in bits {
        value = (value << 1)
            | match b {
                Value::V0 => 0,
                Value::V1 => 1,
                Value::X | Value::Z => {
                    return Err(TraceError::Content(format!(
                        "signal {id} has an x/z bit; traces are two-valued"
                    )))
                }
            };
    }
    let slots = by_code
        .get(&id)
        .ok_or_else(|| TraceError::Content(format!("value change for undeclared code {id}")))?;
    for &i in slots {
        current[i] = value;
    }
    Ok(())
}
