//! The waveforms of a co-simulation run (`CosimOptions::vcd`): the testbench's scopes that
//! mirror the Rust trace's, and the Rust block's own waveform of the same run
//! ([`write_rust_vcd`]), its cycles numbered so that both put cycle `k` at the same time.

use super::{SignalInfo, Trace, RESET_CYCLES};
use crate::emit::range;
use crate::error::GenError;
use serde::Serialize;
use std::collections::HashMap;
use std::fmt::Write as _;
use vtq_hdl::{Block, Signal};

/// A register signal of the Rust block and the RTL register that holds it: `<rtl>_q`, or for
/// register `i` of a bank of `count` registers (the Rust signal `<rtl>_<i>`) the bits
/// `[i*width +: width]` of the packed `<rtl>_q` (the convention of [`crate::rtl`]); a bank of
/// bits is traced in 64-bit words, word `k` the bits `[64k +: 64]`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct RegSignal {
    /// The Rust signal's name.
    pub name: String,
    /// Width in bits.
    pub width: u32,
    /// The description's register (the RTL's `<rtl>_q`).
    pub rtl: String,
    /// The signal's least significant bit in a bank's packed vector; `None` for a single
    /// register.
    pub lsb: Option<u32>,
    /// Where the RTL register lies below the testbench's instance of the module: `""` for the
    /// module's own registers, else instance names each followed by `.` (a child's in a
    /// replay wrapper or a composite, e.g. `u_dut.rt.`).
    pub path: String,
}

impl RegSignal {
    /// The RTL bits holding it, seen from the testbench: `dut.<path><rtl>_q`, or its slice.
    pub fn source(&self) -> String {
        match self.lsb {
            None => format!("dut.{}{}_q", self.path, self.rtl),
            Some(lsb) => format!("dut.{}{}_q[{lsb} +: {}]", self.path, self.rtl, self.width),
        }
    }
}

/// The register signals of `regs` that are registers of `desc`: single registers by name and
/// width, bank members as `<bank>_<i>` (words of a bank of bits as `<bank>_<k>`), a grid's
/// members as `<bank>_<row>_<col>` (member `row * cols + col` of the bank, `cols` the most
/// columns `regs` names).
pub(super) fn desc_registers(desc: &vtq_hdl::BlockDesc, regs: &[Signal]) -> Vec<RegSignal> {
    // Grid members `<bank>_<row>_<col>`: each bank's column count, the largest column plus one.
    let mut grid_cols: HashMap<&str, u32> = HashMap::new();
    for t in regs {
        let Some((rest, c)) = t.name.rsplit_once('_') else {
            continue;
        };
        let (Some((b, _)), Ok(c)) = (rest.rsplit_once('_'), c.parse::<u32>()) else {
            continue;
        };
        let cols = grid_cols.entry(b).or_insert(0);
        *cols = (*cols).max(c + 1);
    }
    let grid = |s: &Signal| -> Option<(String, Option<u32>)> {
        let (rest, col) = s.name.rsplit_once('_')?;
        let (bank, row) = rest.rsplit_once('_')?;
        let (row, col): (u32, u32) = (row.parse().ok()?, col.parse().ok()?);
        let r = desc.registers.iter().find(|r| r.name == bank)?;
        let cols = *grid_cols.get(bank)?;
        let k = row * cols + col;
        (s.width == r.width && r.count % cols == 0 && k < r.count)
            .then(|| (bank.to_string(), Some(k * r.width)))
    };
    let place = |s: &Signal| -> Option<(String, Option<u32>)> {
        let single = desc
            .registers
            .iter()
            .any(|r| r.name == s.name && r.count == 1 && r.width == s.width);
        if single {
            return Some((s.name.clone(), None));
        }
        let (bank, i) = s.name.rsplit_once('_')?;
        let i: u32 = i.parse().ok()?;
        let r = desc.registers.iter().find(|r| r.name == bank)?;
        // A bank of bits is traced as 64-bit words `<bank>_<k>` (word 0 is min(64, count) bits
        // wide); any other bank one signal per member.
        let bits = r.width == 1
            && regs
                .iter()
                .any(|t| t.name == format!("{bank}_0") && t.width == r.count.min(64));
        let lsb = if bits { i * 64 } else { i * r.width };
        let fits = if bits {
            s.width == (r.count - lsb.min(r.count)).min(64)
        } else {
            s.width == r.width && i < r.count
        };
        (fits && s.width > 0).then(|| (bank.to_string(), Some(lsb)))
    };
    regs.iter()
        .filter_map(|s| {
            place(s).or_else(|| grid(s)).map(|(rtl, lsb)| RegSignal {
                name: s.name.clone(),
                width: s.width,
                rtl,
                lsb,
                path: String::new(),
            })
        })
        .collect()
}

/// The register signals of `regs` named `<prefix><name>` where `<name>` is a register of
/// `desc` (as [`desc_registers`] finds them), held by the instance of `desc` at `path` below
/// the testbench's instance (instance names each followed by `.`): a replayed block's, or a
/// composite's child's, whose Rust signals the composite prefixes with the child's name.
pub(super) fn nested_registers(
    desc: &vtq_hdl::BlockDesc,
    path: &str,
    prefix: &str,
    regs: &[Signal],
) -> Vec<RegSignal> {
    let own: Vec<Signal> = regs
        .iter()
        .filter_map(|s| {
            let name = s.name.strip_prefix(prefix)?;
            Some(Signal {
                name: name.to_string(),
                ..s.clone()
            })
        })
        .collect();
    desc_registers(desc, &own)
        .into_iter()
        .map(|r| RegSignal {
            name: format!("{prefix}{}", r.name),
            path: path.to_string(),
            ..r
        })
        .collect()
}

/// The waveform scopes of the testbench: named generate blocks of wires that mirror the Rust
/// trace's scopes.
pub(super) fn vcd_scopes(trace: &Trace, registers: &[RegSignal]) -> String {
    let mut v = String::new();
    let _ = writeln!(
        v,
        "    // Waveform scopes named like the Rust trace's (vtq_hdl::trace): inputs, outputs, regs."
    );
    let ports = |sigs: &[SignalInfo], prefix: &str| -> Vec<(String, u32, String)> {
        sigs.iter()
            .map(|s| (s.name.clone(), s.width, format!("{prefix}{}", s.name)))
            .collect()
    };
    let regs: Vec<(String, u32, String)> = registers
        .iter()
        .map(|r| (r.name.clone(), r.width, r.source()))
        .collect();
    let groups = [
        ("inputs", ports(&trace.inputs, "i_")),
        ("outputs", ports(&trace.outputs, "o_")),
        ("regs", regs),
    ];
    for (scope, sigs) in groups {
        if sigs.is_empty() {
            continue;
        }
        let _ = writeln!(v, "    generate if (1) begin : {scope}");
        for (name, width, source) in sigs {
            let _ = writeln!(v, "        wire {}{name} = {source};", range(width));
        }
        let _ = writeln!(v, "    end endgenerate");
    }
    v
}

/// `text` declares `name` as a `reg` or a `wire` (a line `reg [..] name;`, a comment may
/// follow): a module's register, or a bank a module keeps in child instances and reads back
/// through wires (the RT unit's lanes).
pub(super) fn declares(text: &str, name: &str) -> bool {
    text.lines().any(|l| {
        let l = l.trim_start();
        (l.starts_with("reg ") || l.starts_with("wire "))
            && l.split("//")
                .next()
                .unwrap_or("")
                .trim_end()
                .ends_with(&format!(" {name};"))
    })
}

/// Writes the Rust block's waveform of a run of `block` from reset over `inputs` to `path`
/// ([`vtq_hdl::trace`]'s scopes `inputs`, `outputs` and `regs` under the block's name), its
/// cycles numbered from [`RESET_CYCLES`] so that cycle `k` lies at the same time as in the RTL
/// waveform of [`CosimOptions::vcd`]. Returns the cycles written.
pub fn write_rust_vcd<B: Block>(
    block: &B,
    inputs: impl IntoIterator<Item = B::Inputs>,
    path: &std::path::Path,
) -> Result<u64, GenError> {
    let name = block.describe().name;
    let fail = |e: vtq_hdl::trace::TraceError| GenError::Cosim {
        block: name.clone(),
        reason: format!("writing {}: {e}", path.display()),
    };
    let file = std::fs::File::create(path)
        .map_err(|e| GenError::io(format!("creating {}", path.display()), e))?;
    let mut vcd =
        vtq_hdl::trace::VcdStream::new(std::io::BufWriter::new(file), &name, RESET_CYCLES)
            .with_comment("Rust block of a vtq cosim run: cycle k at 10 (k + 2) ns, as in rtl.vcd");
    let mut regs = block.reset();
    for inp in inputs {
        let (out, next) = block.eval(&regs, &inp);
        let mut scopes = Vec::with_capacity(3);
        vtq_hdl::trace::BlockCycle::new(&inp, &out, block.reg_signals(&regs))
            .push_scopes("", &mut scopes);
        vcd.record(&scopes).map_err(fail)?;
        regs = next;
    }
    let cycles = vcd.cycles() as u64;
    vcd.finish().map_err(fail)?;
    Ok(cycles)
}
