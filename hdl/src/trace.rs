//! Cycle traces of blocks as VCD files (readable in GTKWave), and reading them back.
//!
//! A trace holds, every cycle, groups of flattened [`Signals`], each group under a scope path
//! (parts separated by `.`, e.g. `treelet_rt_unit.ctl.regs`), all below one top module that also
//! holds a `clk` wire. A block's cycle is a [`BlockCycle`]: its inputs and outputs and its
//! registers as the block lists them ([`Block::reg_signals`], as they are at the start of the
//! cycle, before the clock edge), in scopes `inputs`, `outputs` and `regs`.
//!
//! - [`Tracer`] records one block in memory: one module named after the block with the scopes
//!   `inputs`, `outputs` and `regs`.
//! - [`VcdStream`] writes the scopes of any number of blocks straight to a writer as the cycles
//!   come (a window of a simulation may hold many cycles of many signals).
//!
//! Cycle `t` occupies times `[10 t, 10 t + 10)` ns, with `clk` high from `10 t` and low from
//! `10 t + 5`; a trace may start at any cycle (its first timestamp), and a final timestamp
//! `10 (last + 1)` marks the end of its last cycle. A value is written only when it changes (the
//! VCD holds it until then). [`read_vcd`] turns such a file back into per-cycle values keyed by
//! `scope.signal` name.

use crate::block::{Block, Signal, Signals};
use std::collections::BTreeMap;
use std::fmt;
use std::io::{self, BufRead, Write};
use std::path::Path;
use vcd::{Command, IdCode, ScopeItem, TimescaleUnit, Value};

/// Nanoseconds per clock cycle in written traces.
pub const CYCLE_NS: u64 = 10;

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

/// The signals of one scope in one cycle: the scope's path (parts separated by `.`) and its
/// signals.
pub type ScopedSignals = (String, Vec<Signal>);

/// One cycle of a block as a trace shows it: the inputs presented, the outputs driven and the
/// registers at the start of the cycle (before the clock edge).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct BlockCycle {
    /// The input ports' signals.
    pub inputs: Vec<Signal>,
    /// The output ports' signals.
    pub outputs: Vec<Signal>,
    /// The registers' signals ([`Block::reg_signals`]) at the start of the cycle.
    pub regs: Vec<Signal>,
}

impl BlockCycle {
    /// The cycle of a block given its port bundles and its registers' signals.
    pub fn new(inputs: &impl Signals, outputs: &impl Signals, regs: Vec<Signal>) -> Self {
        BlockCycle {
            inputs: inputs.signals(),
            outputs: outputs.signals(),
            regs,
        }
    }

    /// The three groups as scopes `<prefix>.inputs`, `<prefix>.outputs` and `<prefix>.regs`
    /// (`inputs`, `outputs` and `regs` with an empty prefix), appended to `scopes`.
    pub fn push_scopes(self, prefix: &str, scopes: &mut Vec<ScopedSignals>) {
        let path = |group: &str| {
            if prefix.is_empty() {
                group.to_string()
            } else {
                format!("{prefix}.{group}")
            }
        };
        scopes.push((path("inputs"), self.inputs));
        scopes.push((path("outputs"), self.outputs));
        scopes.push((path("regs"), self.regs));
    }
}

/// The signal layout of a trace, fixed by its first cycle.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
struct Layout {
    /// Scope paths, in file order.
    scopes: Vec<String>,
    /// (scope index, name, width) of every signal, in recording order.
    signals: Vec<(usize, String, u32)>,
}

impl Layout {
    /// The layout of `cycle`.
    fn of(cycle: &[ScopedSignals]) -> Self {
        Layout {
            scopes: cycle.iter().map(|(p, _)| p.clone()).collect(),
            signals: cycle
                .iter()
                .enumerate()
                .flat_map(|(i, (_, sigs))| sigs.iter().map(move |s| (i, s.name.clone(), s.width)))
                .collect(),
        }
    }

    /// Checks that cycle number `n`'s signals `cycle` follow the layout and fit their widths,
    /// and puts their values in `values`.
    fn values(
        &self,
        n: usize,
        cycle: &[ScopedSignals],
        values: &mut Vec<u64>,
    ) -> Result<(), TraceError> {
        values.clear();
        let layout = |detail: String| TraceError::Layout { cycle: n, detail };
        if cycle.len() != self.scopes.len() {
            return Err(layout(format!(
                "{} scopes now, {} in the first cycle",
                cycle.len(),
                self.scopes.len()
            )));
        }
        let mut expected = self.signals.iter();
        for (i, (path, sigs)) in cycle.iter().enumerate() {
            if *path != self.scopes[i] {
                return Err(layout(format!(
                    "scope {path} where the first cycle had {}",
                    self.scopes[i]
                )));
            }
            for s in sigs {
                match expected.next() {
                    Some((si, name, width)) if *si == i && *name == s.name && *width == s.width => {
                    }
                    _ => {
                        return Err(layout(format!(
                            "signal {path}.{} ({} bits) is not the first cycle's",
                            s.name, s.width
                        )))
                    }
                }
                if s.width == 0 || s.width > 64 || (s.width < 64 && s.value >> s.width != 0) {
                    return Err(TraceError::Width {
                        cycle: n,
                        name: s.name.clone(),
                        value: s.value,
                        width: s.width,
                    });
                }
                values.push(s.value);
            }
        }
        if values.len() != self.signals.len() {
            return Err(layout(format!(
                "{} signals now, {} in the first cycle",
                values.len(),
                self.signals.len()
            )));
        }
        Ok(())
    }
}

/// The VCD text of a trace being written: the header, then one cycle at a time.
struct Body<W: Write> {
    v: vcd::Writer<W>,
    clk: IdCode,
    /// Id code and width of every signal of the layout.
    ids: Vec<(IdCode, u32)>,
    /// The last cycle's values (none before the first cycle).
    prev: Option<Vec<u64>>,
    /// The next cycle to write.
    cycle: u64,
}

impl<W: Write> Body<W> {
    /// Writes the header: `top` with `clk` and the layout's scopes, an optional comment; the
    /// first cycle will be `first_cycle`.
    fn start(
        w: W,
        top: &str,
        comment: Option<&str>,
        layout: &Layout,
        first_cycle: u64,
    ) -> io::Result<Self> {
        let mut v = vcd::Writer::new(w);
        v.version(concat!("vtq-hdl ", env!("CARGO_PKG_VERSION")))?;
        if let Some(c) = comment {
            v.comment(c)?;
        }
        v.timescale(1, TimescaleUnit::NS)?;
        v.add_module(top)?;
        let clk = v.add_wire(1, "clk")?;
        let mut ids = vec![(clk, 1); layout.signals.len()];
        let mut open: Vec<&str> = Vec::new();
        for (i, path) in layout.scopes.iter().enumerate() {
            let parts: Vec<&str> = path.split('.').collect();
            let common = open.iter().zip(&parts).take_while(|(a, b)| a == b).count();
            while open.len() > common {
                v.upscope()?;
                open.pop();
            }
            for part in &parts[common..] {
                v.add_module(part)?;
                open.push(part);
            }
            for (k, (si, name, width)) in layout.signals.iter().enumerate() {
                if *si == i {
                    ids[k] = (v.add_wire(*width, name)?, *width);
                }
            }
        }
        for _ in open {
            v.upscope()?;
        }
        v.upscope()?;
        v.enddefinitions()?;
        Ok(Body {
            v,
            clk,
            ids,
            prev: None,
            cycle: first_cycle,
        })
    }

    /// Writes the next cycle's `values` (only those that changed).
    fn cycle(&mut self, values: &[u64]) -> io::Result<()> {
        let t = self.cycle * CYCLE_NS;
        self.v.timestamp(t)?;
        self.v.change_scalar(self.clk, Value::V1)?;
        for (i, &value) in values.iter().enumerate() {
            if self.prev.as_ref().is_some_and(|p| p[i] == value) {
                continue;
            }
            let (id, width) = self.ids[i];
            if width == 1 {
                self.v.change_scalar(id, value & 1 == 1)?;
            } else {
                // Leading zeros are implied (IEEE 1364 18.2.1).
                writeln!(self.v.writer(), "b{value:b} {id}")?;
            }
        }
        self.v.timestamp(t + CYCLE_NS / 2)?;
        self.v.change_scalar(self.clk, Value::V0)?;
        match &mut self.prev {
            Some(p) => p.copy_from_slice(values),
            None => self.prev = Some(values.to_vec()),
        }
        self.cycle += 1;
        Ok(())
    }

    /// Marks the end of the last cycle and flushes.
    fn end(&mut self) -> io::Result<()> {
        self.v.timestamp(self.cycle * CYCLE_NS)?;
        self.v.flush()
    }
}

/// Records per-cycle signal values of one block in memory and writes them as VCD.
#[derive(Debug, Clone)]
pub struct Tracer {
    module: String,
    /// Fixed by the first recorded cycle.
    layout: Layout,
    cycles: Vec<Vec<u64>>,
}

impl Tracer {
    /// An empty trace of the block named `module` (a legal Verilog identifier).
    pub fn new(module: &str) -> Self {
        Tracer {
            module: module.to_string(),
            layout: Layout::default(),
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
        let mut scopes = Vec::with_capacity(3);
        BlockCycle::new(inputs, outputs, regs).push_scopes("", &mut scopes);
        let cycle = self.cycles.len();
        if cycle == 0 {
            self.layout = Layout::of(&scopes);
        }
        let mut values = Vec::with_capacity(self.layout.signals.len());
        self.layout.values(cycle, &scopes, &mut values)?;
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
        self.write_vcd(io::BufWriter::new(create(path)?))
    }

    fn write_inner(&self, w: impl Write) -> io::Result<()> {
        let mut body = Body::start(w, &self.module, None, &self.layout, 0)?;
        for values in &self.cycles {
            body.cycle(values)?;
        }
        body.end()
    }
}

/// Creates the file at `path` (an error naming it if that fails).
fn create(path: &Path) -> Result<std::fs::File, TraceError> {
    std::fs::File::create(path).map_err(|e| {
        TraceError::Write(io::Error::new(
            e.kind(),
            format!("creating {}: {e}", path.display()),
        ))
    })
}

/// Writes a trace of any number of scopes as VCD while the cycles come, holding only the last
/// cycle's values: the header when the first cycle is recorded (its scopes fix the layout), then
/// each cycle's changes; [`VcdStream::finish`] marks the end. Cycles are numbered from the
/// `first_cycle` given to [`VcdStream::new`] (its time is `10 first_cycle` ns).
pub struct VcdStream<W: Write> {
    top: String,
    comment: Option<String>,
    first_cycle: u64,
    /// The writer until the header is written.
    writer: Option<W>,
    body: Option<Body<W>>,
    layout: Layout,
    values: Vec<u64>,
    cycles: usize,
}

impl<W: Write> fmt::Debug for VcdStream<W> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("VcdStream")
            .field("top", &self.top)
            .field("first_cycle", &self.first_cycle)
            .field("cycles", &self.cycles)
            .field("signals", &self.layout.signals.len())
            .finish()
    }
}

impl<W: Write> VcdStream<W> {
    /// A trace with top module `top` (a legal Verilog identifier) written to `w`, its first
    /// cycle numbered `first_cycle`.
    pub fn new(w: W, top: &str, first_cycle: u64) -> Self {
        VcdStream {
            top: top.to_string(),
            comment: None,
            first_cycle,
            writer: Some(w),
            body: None,
            layout: Layout::default(),
            values: Vec::new(),
            cycles: 0,
        }
    }

    /// The same trace with a `$comment` in its header (what it shows, for a reader).
    pub fn with_comment(self, comment: &str) -> Self {
        VcdStream {
            comment: Some(comment.to_string()),
            ..self
        }
    }

    /// Number of recorded cycles.
    pub fn cycles(&self) -> usize {
        self.cycles
    }

    /// Records and writes the next cycle: its scopes with their signals (the same scopes,
    /// names and widths every cycle).
    pub fn record(&mut self, cycle: &[ScopedSignals]) -> Result<(), TraceError> {
        if self.cycles == 0 {
            self.layout = Layout::of(cycle);
        }
        self.layout.values(self.cycles, cycle, &mut self.values)?;
        self.start_body()?;
        let body = self.body.as_mut().expect("the header is written");
        body.cycle(&self.values).map_err(TraceError::Write)?;
        self.cycles += 1;
        Ok(())
    }

    /// Writes the header if it is not yet written.
    fn start_body(&mut self) -> Result<(), TraceError> {
        if let Some(w) = self.writer.take() {
            let body = Body::start(
                w,
                &self.top,
                self.comment.as_deref(),
                &self.layout,
                self.first_cycle,
            )
            .map_err(TraceError::Write)?;
            self.body = Some(body);
        }
        Ok(())
    }

    /// Marks the end of the last cycle and flushes (a trace of no cycle holds only `clk`).
    pub fn finish(mut self) -> Result<(), TraceError> {
        self.start_body()?;
        let body = self.body.as_mut().expect("the header is written");
        body.end().map_err(TraceError::Write)
    }
}

/// Per-cycle signal values read back from a VCD trace.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VcdTrace {
    /// The first cycle (its first timestamp over [`CYCLE_NS`]).
    pub start: u64,
    /// Signal names (`scope.name`, e.g. `outputs.ready` or `rt.regs.fifo_count`, and `clk`) with
    /// widths, in file order.
    pub signals: Vec<(String, u32)>,
    /// `values[i][k]` is signal `k`'s value during cycle `start + i`.
    pub values: Vec<Vec<u64>>,
}

impl VcdTrace {
    /// Number of cycles.
    pub fn cycles(&self) -> usize {
        self.values.len()
    }

    /// The value of signal `name` (`scope.name`) in cycle `cycle` (counted like the trace's
    /// timestamps: from `start`), if both exist.
    pub fn value(&self, name: &str, cycle: usize) -> Option<u64> {
        let i = self.signals.iter().position(|(n, _)| n == name)?;
        let row = (cycle as u64).checked_sub(self.start)?;
        self.values.get(usize::try_from(row).ok()?).map(|v| v[i])
    }
}

/// Reads a VCD written by [`Tracer`] or [`VcdStream`] (one module, scopes nested below it, a
/// [`CYCLE_NS`] clock period) into per-cycle values: the first cycle is the first timestamp's,
/// cycle `t` holds the values as of time `CYCLE_NS * t` after that time's changes, and the last
/// cycle is the last one whose start precedes the final timestamp.
pub fn read_vcd(r: impl BufRead) -> Result<VcdTrace, TraceError> {
    let mut parser = vcd::Parser::new(r);
    let header = parser.parse_header().map_err(TraceError::Read)?;
    let mut signals = Vec::new();
    let mut by_code: BTreeMap<IdCode, Vec<usize>> = BTreeMap::new();
    let modules: Vec<_> = header
        .items
        .iter()
        .filter_map(|i| match i {
            ScopeItem::Scope(s) => Some(s),
            _ => None,
        })
        .collect();
    let [top] = modules.as_slice() else {
        return Err(TraceError::Content(format!(
            "expected exactly one top-level module, found {}",
            modules.len()
        )));
    };
    collect_vars(&top.items, "", &mut signals, &mut by_code)?;
    let mut current = vec![0u64; signals.len()];
    let mut values = Vec::new();
    let mut start = None;
    for cmd in parser {
        match cmd.map_err(TraceError::Read)? {
            Command::Timestamp(ts) => {
                let first = *start.get_or_insert(ts / CYCLE_NS);
                // Every cycle start before `ts` is now final: sample it.
                while (first + values.len() as u64) * CYCLE_NS < ts {
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
    Ok(VcdTrace {
        start: start.unwrap_or(0),
        signals,
        values,
    })
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
