//! Verilog-2005 modules from block self-descriptions ([`BlockDesc`]).
//!
//! [`emit_module`] writes, for any block: a header comment (the block's purpose, the
//! configuration parameters that shaped it, its timing, its storage and the port timing
//! convention), `clk` and `rst` plus every port one per line with its width and the port's
//! documentation, the registers and memories with their widths, depths and field layouts, and
//! each state machine's state encodings as `localparam`s. Blocks whose full RTL is not generated
//! get a skeleton body that is lint-clean under `verilator --lint-only -Wall` and synthesizes
//! without latches: every output is driven with zero, every register and state register is
//! reset (to zero, which is also every state machine's first state) and otherwise holds, and
//! only the intentionally unused signals (the inputs, and the storage the skeleton does not
//! read) are wrapped in `verilator lint_off` pragmas.
//!
//! A register with the name and width of an output port is a registered output: it is declared
//! in the port list as `output reg` and driven by the register directly. Register banks
//! (`count > 1`) are arrays marked `(* mem2reg *)` (flip-flops, not RAM); memories are
//! `reg [W-1:0] name [0:D-1]` with their field layout, ports and read latency in a comment.
//!
//! Timing convention (shared with [`crate::cosim`]): all registers update on the rising edge of
//! `clk`; `rst` is synchronous and active high; outputs are combinational functions of the
//! registers and this cycle's inputs, as returned by the Rust `Block::eval`.

use crate::emit::{dec, is_identifier, one_line, range, screaming_snake, VerilogWriter};
use crate::error::GenError;
use crate::tools::{create_dir, write_file};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use vtq_hdl::{BlockDesc, Dir, FsmDesc};

/// Widest port, register or memory word the generator accepts: 2^20 bits (co-simulation
/// further needs every traced signal to fit a `u64`).
///
/// IEEE 1364-2005 only guarantees vectors of up to 65,536 bits, and the RT
/// unit's per-warp stack ports at the default configuration are wider (32 lanes x 128 entries x
/// 37 bits = 151,552 bits). The tools vtq uses accept wider vectors: Verilator 5.006
/// (`--lint-only -Wall`), Icarus Verilog 11 and Yosys 0.23 (generic `synth`, no latches) were
/// checked on 75,776-bit and 151,552-bit ports; `gen/tests/hdl_blocks.rs` lints and
/// synthesizes the RT unit skeleton at the default configuration.
pub const MAX_WIDTH: u32 = 1 << 20;

/// Names every generated module reserves for itself.
const RESERVED: &[&str] = &["clk", "rst", "unused_inputs"];

/// Checks that `desc` can be emitted: legal and unique identifiers, widths 1..=64, non-empty
/// memories and banks, and state machines whose states fit their register width and whose
/// state names give unique `localparam`s.
pub fn validate_desc(desc: &BlockDesc) -> Result<(), GenError> {
    let bad = |reason: String| GenError::InvalidDesc {
        block: desc.name.clone(),
        reason,
    };
    if !is_identifier(&desc.name) {
        return Err(bad(format!(
            "module name `{}` is not a legal Verilog identifier",
            desc.name
        )));
    }
    let mut names: BTreeSet<String> = RESERVED.iter().map(|s| s.to_string()).collect();
    let mut claim = |kind: &str, name: &str, width: u32| -> Result<(), GenError> {
        if !is_identifier(name) {
            return Err(bad(format!(
                "{kind} name `{name}` is not a legal Verilog identifier"
            )));
        }
        if !names.insert(name.to_string()) {
            return Err(bad(format!(
                "{kind} name `{name}` is used twice (or collides with clk/rst)"
            )));
        }
        if width == 0 || width > MAX_WIDTH {
            return Err(bad(format!(
                "{kind} `{name}` has width {width}; widths must be 1..={MAX_WIDTH}"
            )));
        }
        Ok(())
    };
    if !desc.ports.iter().any(|p| p.dir == Dir::Out) {
        return Err(bad("the block has no output port".to_string()));
    }
    for p in &desc.ports {
        claim("port", &p.name, p.width)?;
    }
    for r in &desc.registers {
        match desc.port(&r.name) {
            // A register that drives the output port of the same name (a registered output).
            Some(p) if p.dir == Dir::Out && p.width == r.width && r.count == 1 => {}
            Some(_) => {
                return Err(bad(format!(
                    "register `{}` has the name of a port but is not a registered output of \
                     the same width",
                    r.name
                )))
            }
            None => claim("register", &r.name, r.width)?,
        }
        if r.count == 0 {
            return Err(bad(format!("register bank `{}` has count 0", r.name)));
        }
    }
    for m in &desc.memories {
        claim("memory", &m.name, m.width)?;
        if m.depth == 0 {
            return Err(bad(format!("memory `{}` has depth 0", m.name)));
        }
        let field_bits: u32 = m.fields.iter().map(|(_, w)| *w).sum();
        if !m.fields.is_empty() && field_bits != m.width {
            return Err(bad(format!(
                "memory `{}`: fields add up to {field_bits} bits but a word has {}",
                m.name, m.width
            )));
        }
    }
    for f in &desc.fsms {
        // The state register may be a bank: one copy of the machine per lane, say.
        match desc.registers.iter().find(|r| r.name == f.name) {
            Some(r) if r.width != f.width => {
                return Err(bad(format!(
                    "state machine `{}` is also listed as a register with a different width",
                    f.name
                )))
            }
            Some(_) => {}
            None => claim("state register", &f.name, f.width)?,
        }
        if f.states.is_empty() {
            return Err(bad(format!("state machine `{}` has no states", f.name)));
        }
        if f.width < 64 && f.states.len() as u64 > 1u64 << f.width {
            return Err(bad(format!(
                "state machine `{}` has {} states, more than {} bits encode",
                f.name,
                f.states.len(),
                f.width
            )));
        }
    }
    let mut params = BTreeSet::new();
    for f in &desc.fsms {
        for s in &f.states {
            let p = state_param(f, s);
            if !is_identifier(&p) || !params.insert(p.clone()) {
                return Err(bad(format!(
                    "state `{s}` of `{}` gives the localparam `{p}`, which is illegal or repeated",
                    f.name
                )));
            }
        }
    }
    Ok(())
}

/// Whether output port `name` is driven directly by the register of the same name.
fn is_registered_output(desc: &BlockDesc, name: &str) -> bool {
    desc.registers.iter().any(|r| r.name == name)
}

/// The `localparam` name of state `state` of `fsm` (`MODE_RAY_STATIONARY`).
pub fn state_param(fsm: &FsmDesc, state: &str) -> String {
    format!("{}_{}", screaming_snake(&fsm.name), screaming_snake(state))
}

/// A complete Verilog module for `desc` with a skeleton body (see the module documentation).
pub fn emit_module(desc: &BlockDesc) -> Result<String, GenError> {
    validate_desc(desc)?;
    let mut w = VerilogWriter::new();
    emit_header(&mut w, desc);
    emit_port_list(&mut w, desc);
    w.indent();
    emit_skeleton_body(&mut w, desc);
    w.dedent();
    w.line("endmodule");
    Ok(w.finish())
}

/// Writes [`emit_module`]'s text for `desc` to `<dir>/<module name>.v` (creating `dir`) and
/// returns the file's path; the file is named after the module, as Verilator's -Wall expects.
pub fn write_module(dir: &Path, desc: &BlockDesc) -> Result<PathBuf, GenError> {
    let text = emit_module(desc)?;
    create_dir(dir)?;
    let path = dir.join(format!("{}.v", desc.name));
    write_file(&path, &text)?;
    Ok(path)
}

/// The header comment: purpose, configuration, timing, storage and conventions.
pub(crate) fn emit_header(w: &mut VerilogWriter, desc: &BlockDesc) {
    w.line(format!("// {}", "-".repeat(93)));
    w.comment(&format!(
        "{}: generated by vtq-gen from the block's self-description (vtq_hdl::BlockDesc).",
        desc.name
    ));
    w.line("//");
    w.comment(&desc.doc);
    if !desc.params.is_empty() {
        w.line("//");
        w.line("// Configuration:");
        let name_width = desc.params.iter().map(|(n, _)| n.len()).max().unwrap_or(0);
        for (name, value) in &desc.params {
            w.line(format!("//   {name:<name_width$} = {value}"));
        }
    }
    if !desc.timing.is_empty() {
        w.line("//");
        w.line("// Timing:");
        for t in &desc.timing {
            w.comment(&format!("  {}", one_line(t)));
        }
    }
    let (reg_bits, mem_bits) = (desc.register_bits(), desc.memory_bits());
    w.line("//");
    w.line(format!(
        "// Storage: {} bits ({reg_bits} in registers, {mem_bits} in memories).",
        desc.storage_bits()
    ));
    w.line("//");
    w.comment(
        "Conventions: registers update on the rising edge of clk; rst is synchronous and active \
         high; outputs are combinational functions of the registers and this cycle's inputs \
         (the Rust Block::eval).",
    );
    w.line(format!("// {}", "-".repeat(93)));
}

/// `module name (` ... `);` with clk, rst and every port, one per line with its comment.
fn emit_port_list(w: &mut VerilogWriter, desc: &BlockDesc) {
    emit_ports(w, desc, true);
}

/// [`emit_port_list`], with `registered_outputs` false declaring every output `output wire`
/// (for full RTL bodies that drive each output with an `assign`).
pub(crate) fn emit_ports(w: &mut VerilogWriter, desc: &BlockDesc, registered_outputs: bool) {
    let mut ports: Vec<(&str, String, &str, String)> = vec![
        (
            "input  wire",
            String::new(),
            "clk",
            "clock; every register updates on its rising edge".to_string(),
        ),
        (
            "input  wire",
            String::new(),
            "rst",
            "synchronous reset, active high".to_string(),
        ),
    ];
    for p in &desc.ports {
        let dir = match p.dir {
            Dir::In => "input  wire",
            Dir::Out if registered_outputs && is_registered_output(desc, &p.name) => "output reg ",
            Dir::Out => "output wire",
        };
        ports.push((dir, range(p.width), &p.name, one_line(&p.doc)));
    }
    let range_width = ports.iter().map(|p| p.1.len()).max().unwrap_or(0);
    let last = ports.len() - 1;
    let decls: Vec<String> = ports
        .iter()
        .enumerate()
        .map(|(i, (dir, r, name, _))| {
            let comma = if i == last { "" } else { "," };
            format!("{dir} {r:range_width$}{name}{comma}")
        })
        .collect();
    let decl_width = decls.iter().map(|d| d.len()).max().unwrap_or(0);
    w.line(format!("module {} (", desc.name));
    w.indent();
    for (decl, (_, _, _, doc)) in decls.iter().zip(&ports) {
        if doc.is_empty() {
            w.line(decl);
        } else {
            w.line(format!("{decl:decl_width$} // {doc}"));
        }
    }
    w.dedent();
    w.line(");");
}

/// The skeleton: storage declarations, reset-and-hold registers, zero outputs.
fn emit_skeleton_body(w: &mut VerilogWriter, desc: &BlockDesc) {
    w.line("");
    w.comment(
        "Skeleton body: the block's full RTL is not generated yet. Outputs are driven with zero \
         and the state is reset and held, so the module lints and synthesizes cleanly and shows \
         the block's interface and storage.",
    );
    let fsm_regs: Vec<&FsmDesc> = desc
        .fsms
        .iter()
        .filter(|f| !desc.registers.iter().any(|r| r.name == f.name))
        .collect();
    let has_state = !desc.registers.is_empty() || !fsm_regs.is_empty();
    // Registers that are not also output ports (those are declared in the port list).
    let internal_regs: Vec<_> = desc
        .registers
        .iter()
        .filter(|r| desc.port(&r.name).is_none())
        .collect();

    if !desc.fsms.is_empty() {
        w.line("");
        w.line("// State encodings (the skeleton does not decode them).");
        w.line("/* verilator lint_off UNUSED */");
        for f in &desc.fsms {
            for (i, s) in f.states.iter().enumerate() {
                w.line(format!(
                    "localparam {}{} = {};",
                    range(f.width),
                    state_param(f, s),
                    dec(f.width, i as u64)
                ));
            }
        }
        w.line("/* verilator lint_on UNUSED */");
    }

    if !internal_regs.is_empty() || !fsm_regs.is_empty() || !desc.memories.is_empty() {
        w.line("");
        w.line("// Storage (not read by the skeleton).");
        w.line("/* verilator lint_off UNUSED */");
        for r in &internal_regs {
            w.comment(&r.doc);
            if r.count > 1 {
                // A bank of registers, not a RAM: tell Yosys so it does not warn.
                w.line(format!(
                    "(* mem2reg *) reg {}{} [0:{}];",
                    range(r.width),
                    r.name,
                    r.count - 1
                ));
            } else {
                w.line(format!("reg {}{};", range(r.width), r.name));
            }
        }
        for f in &fsm_regs {
            w.comment(&format!(
                "State register of the {} state machine ({} states).",
                f.name,
                f.states.len()
            ));
            w.line(format!("reg {}{};", range(f.width), f.name));
        }
        if !desc.memories.is_empty() {
            w.line("/* verilator lint_off UNDRIVEN */");
            for m in &desc.memories {
                w.comment(&m.doc);
                let fields = m
                    .fields
                    .iter()
                    .map(|(n, b)| format!("{n}:{b}"))
                    .collect::<Vec<_>>()
                    .join(" | ");
                let banks = if m.banks > 1 {
                    format!("{} banks of ", m.banks)
                } else {
                    String::new()
                };
                w.comment(&format!(
                    "{banks}{} words x {} bits, {}R/{}W, read latency {}{}{}.",
                    m.depth,
                    m.width,
                    m.read_ports,
                    m.write_ports,
                    m.read_latency,
                    if fields.is_empty() { "" } else { "; word = " },
                    fields
                ));
                w.line(format!(
                    "reg {}{} [0:{}];",
                    range(m.width),
                    m.name,
                    m.banks * m.depth - 1
                ));
            }
            w.line("/* verilator lint_on UNDRIVEN */");
        }
        w.line("/* verilator lint_on UNUSED */");
    }

    if has_state {
        w.line("");
        w.line("// Reset every register; hold otherwise.");
        w.line("always @(posedge clk) begin : p_state");
        w.indent();
        let needs_index = desc.registers.iter().any(|r| r.count > 1);
        if needs_index {
            w.line("integer i;");
        }
        w.line("if (rst) begin");
        w.indent();
        for r in &desc.registers {
            if r.count > 1 {
                w.line(format!(
                    "for (i = 0; i < {}; i = i + 1) {}[i] <= {};",
                    r.count,
                    r.name,
                    dec(r.width, 0)
                ));
            } else {
                w.line(format!("{} <= {};", r.name, dec(r.width, 0)));
            }
        }
        for f in &fsm_regs {
            w.line(format!("{} <= {};", f.name, state_param(f, &f.states[0])));
        }
        w.dedent();
        w.line("end");
        w.dedent();
        w.line("end");
    }

    // Without registers the skeleton does not use the clock and reset either.
    let mut inputs: Vec<&str> = if has_state {
        vec![]
    } else {
        vec!["clk", "rst"]
    };
    inputs.extend(
        desc.ports
            .iter()
            .filter(|p| p.dir == Dir::In)
            .map(|p| p.name.as_str()),
    );
    if !inputs.is_empty() {
        w.line("");
        w.line("// The skeleton does not use these inputs yet.");
        w.line("/* verilator lint_off UNUSED */");
        w.line(format!(
            "wire unused_inputs = &{{1'b0, {}, 1'b0}};",
            inputs.join(", ")
        ));
        w.line("/* verilator lint_on UNUSED */");
    }

    w.line("");
    w.line("// Outputs: zero until the block's RTL is generated (registered outputs are reset).");
    for p in desc
        .ports
        .iter()
        .filter(|p| p.dir == Dir::Out && !is_registered_output(desc, &p.name))
    {
        w.line(format!("assign {} = {};", p.name, dec(p.width, 0)));
    }
}
