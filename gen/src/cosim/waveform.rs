//! The waveforms of a co-simulation run (`CosimOptions::vcd`): the testbench's scopes that
//! mirror the Rust trace's, and the Rust block's own waveform of the same run
//! ([`write_rust_vcd`]), its cycles numbered so that both put cycle `k` at the same time.

use super::{RegSignal, SignalInfo, Trace, RESET_CYCLES};
use crate::emit::range;
use crate::error::GenError;
use std::fmt::Write as _;
use vtq_hdl::Block;

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
        .map(|r| {
            let source = match r.lsb {
                None => format!("dut.{}_q", r.rtl),
                Some(lsb) => format!("dut.{}_q[{lsb} +: {}]", r.rtl, r.width),
            };
            (r.name.clone(), r.width, source)
        })
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

/// `text` declares `name` as a `reg` (a line `reg [..] name;`, a comment may follow).
pub(super) fn declares(text: &str, name: &str) -> bool {
    text.lines().any(|l| {
        let l = l.trim_start();
        l.starts_with("reg ")
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
