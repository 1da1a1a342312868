//! Complete Verilog-2005 RTL for the blocks generated in full: the treelet count table
//! ([`count_table_verilog`]), the treelet queue table ([`queue_table_verilog`]) and the treelet
//! controller ([`controller_verilog`]), synthesizable; and the RT unit's control
//! ([`rt_unit_verilog`], with the toy datapath [`toy_datapath_verilog`]), co-simulated and
//! lint-clean but not yet synthesizable in reasonable time (its module documentation).
//!
//! Each module is built from the Rust block's [`vtq_hdl::Block::describe`]: the module name,
//! the header comment and the port list come from g1's emitter ([`crate::verilog`]), and every
//! width and size the body uses is looked up in the description (ports, registers, memories
//! and parameters by name), so the RTL cannot drift from the Rust block; a description that
//! lacks an item the body needs is a [`GenError::InvalidDesc`].
//!
//! Conventions shared by the bodies (and [`crate::cosim`]'s timing convention):
//! - every register of the description is `<name>_q` with its next value `<name>_d`, computed
//!   by combinational `always @*` blocks; one clocked block loads all of them, and synchronous
//!   active-high `rst` loads the values of the Rust `Block::reset()`;
//! - outputs are `assign`ed from the registers and this cycle's inputs (like `Block::eval`);
//! - memories are `reg [W-1:0] name [0:D-1]` with synchronous writes; latency-1 (SRAM) reads
//!   go through a registered read-data word; flip-flop arrays are reset like the Rust model.

mod controller;
mod count_table;
mod queue_table;
mod replay;
mod rt_unit;
mod treelet_wiring;

pub use controller::controller_verilog;
pub use count_table::count_table_verilog;
pub use queue_table::queue_table_verilog;
pub use replay::{rt_unit_replay_verilog, treelet_rt_unit_replay_verilog, REPLAY_INSTANCE};
pub use rt_unit::{
    datapath_blackbox_verilog, rt_unit_verilog, toy_datapath_verilog, CHILD_BITS, CHILD_COUNT_BITS,
    DATAPATH_PORTS,
};
pub use treelet_wiring::{instances, treelet_wiring_desc, treelet_wiring_verilog};

use crate::emit::{one_line, range, VerilogWriter};
use crate::error::GenError;
use crate::verilog::{emit_header, emit_ports, validate_desc};
use vtq_hdl::controller::{ControllerFeatures, TreeletController};
use vtq_hdl::count_table::CountTable;
use vtq_hdl::queue_table::QueueTable;
use vtq_hdl::{Block, BlockDesc, Dir, HwConfig, MemDesc};

/// The complete RTL of every block generated in full for `cfg`: both tables and the treelet
/// controller with `features`, as `(module name, Verilog text)` pairs (count table, queue
/// table, controller); write each to `<module name>.v`.
pub fn rtl_modules(
    cfg: &HwConfig,
    features: ControllerFeatures,
) -> Result<Vec<(String, String)>, GenError> {
    let mut out = table_modules(cfg)?;
    let name = TreeletController::new(cfg.clone(), features)?
        .describe()
        .name;
    out.push((name, controller_verilog(cfg, features)?));
    Ok(out)
}

/// The complete RTL of both tables for `cfg`, as `(module name, Verilog text)` pairs (count
/// table first); write each to `<module name>.v`.
pub fn table_modules(cfg: &HwConfig) -> Result<Vec<(String, String)>, GenError> {
    let count = CountTable::new(cfg)?.describe().name;
    let queue = QueueTable::new(cfg)?.describe().name;
    Ok(vec![
        (count, count_table_verilog(cfg)?),
        (queue, queue_table_verilog(cfg)?),
    ])
}

/// Looks up the sizes a body needs in a block description, failing with a message that names
/// the missing or inconsistent item.
struct DescInfo<'a> {
    desc: &'a BlockDesc,
}

impl<'a> DescInfo<'a> {
    fn new(desc: &'a BlockDesc) -> Result<Self, GenError> {
        validate_desc(desc)?;
        Ok(DescInfo { desc })
    }

    fn bad(&self, reason: String) -> GenError {
        GenError::InvalidDesc {
            block: self.desc.name.clone(),
            reason,
        }
    }

    /// Width of port `name`, which must have direction `dir`.
    fn port(&self, name: &str, dir: Dir) -> Result<u32, GenError> {
        match self.desc.port(name) {
            Some(p) if p.dir == dir => Ok(p.width),
            Some(p) => Err(self.bad(format!(
                "port `{name}` is {:?}, the RTL needs {dir:?}",
                p.dir
            ))),
            None => Err(self.bad(format!("the RTL needs a port `{name}`"))),
        }
    }

    /// Width of the single register `name`.
    fn reg(&self, name: &str) -> Result<u32, GenError> {
        match self.desc.registers.iter().find(|r| r.name == name) {
            Some(r) if r.count == 1 => Ok(r.width),
            Some(r) => Err(self.bad(format!(
                "register `{name}` is a bank of {}, the RTL needs one register",
                r.count
            ))),
            None => Err(self.bad(format!("the RTL needs a register `{name}`"))),
        }
    }

    /// Width of each register of the register or bank `name`.
    fn bank(&self, name: &str) -> Result<u32, GenError> {
        self.desc
            .registers
            .iter()
            .find(|r| r.name == name)
            .map(|r| r.width)
            .ok_or_else(|| self.bad(format!("the RTL needs a register `{name}`")))
    }

    /// Configuration parameter `name`.
    fn param(&self, name: &str) -> Result<u64, GenError> {
        self.desc
            .params
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| *v)
            .ok_or_else(|| self.bad(format!("the RTL needs the parameter `{name}`")))
    }

    /// Memory `name` with its fields checked against `fields` (name, width), most significant
    /// first, and its read latency against `latency`.
    fn mem(&self, name: &str, fields: &[(&str, u32)], latency: u32) -> Result<&MemDesc, GenError> {
        let m = self
            .desc
            .memories
            .iter()
            .find(|m| m.name == name)
            .ok_or_else(|| self.bad(format!("the RTL needs a memory `{name}`")))?;
        let got: Vec<(&str, u32)> = m.fields.iter().map(|(n, w)| (n.as_str(), *w)).collect();
        if got != fields {
            return Err(self.bad(format!(
                "memory `{name}` has fields {got:?}, the RTL expects {fields:?}"
            )));
        }
        if m.read_latency != latency {
            return Err(self.bad(format!(
                "memory `{name}` has read latency {}, the RTL expects {latency}",
                m.read_latency
            )));
        }
        Ok(m)
    }
}

/// Zero of `width` bits: a sized literal, or a replication past 64 bits (simulators limit the
/// width of a literal).
fn zero(width: u32) -> String {
    if width > 64 {
        // Replications of at most 8192 bits (Verilator's linter flags longer ones).
        let mut parts = vec!["{8192{1'b0}}".to_string(); (width / 8192) as usize];
        if !width.is_multiple_of(8192) {
            parts.push(format!("{{{}{{1'b0}}}}", width % 8192));
        }
        format!("{{{}}}", parts.join(", "))
    } else {
        lit(width, 0)
    }
}

/// A sized decimal literal.
fn lit(width: u32, value: u64) -> String {
    format!("{width}'d{value}")
}

/// `expr` (of `from` bits) zero-extended to `to` bits.
fn zext(expr: &str, from: u32, to: u32) -> String {
    debug_assert!(to >= from, "zext from {from} to {to} bits");
    if to <= from {
        expr.to_string()
    } else {
        format!("{{{}'d0, {expr}}}", to - from)
    }
}

/// Replaces every `${NAME}` in `template` by its value from `vars`. The templates are written
/// in this crate, so an unknown name is a bug the lint tests catch (it is left in place and is
/// not valid Verilog).
fn fill(template: &str, vars: &[(&str, String)]) -> String {
    let mut out = String::with_capacity(template.len() + template.len() / 4);
    let mut rest = template;
    while let Some(start) = rest.find("${") {
        out.push_str(&rest[..start]);
        let after = &rest[start + 2..];
        match after.find('}') {
            Some(end) => {
                let key = &after[..end];
                match vars.iter().find(|(k, _)| *k == key) {
                    Some((_, v)) => out.push_str(v),
                    None => {
                        debug_assert!(false, "template variable `{key}` has no value");
                        out.push_str(&rest[start..start + 3 + end]);
                    }
                }
                rest = &after[end + 1..];
            }
            None => {
                out.push_str(&rest[start..]);
                rest = "";
            }
        }
    }
    out.push_str(rest);
    out
}

/// Bits of register (or bank) `r` as one packed vector: a bank of `count` registers of `width`
/// bits holds register i in bits `[i*width +: width]`.
fn reg_bits(r: &vtq_hdl::RegDesc) -> u32 {
    r.count * r.width
}

/// The register declarations (`<name>_q` and `<name>_d` for every register of the
/// description; a bank of registers becomes a packed vector, register i in bits
/// `[i*width +: width]`) and the clocked block
/// that loads them, with `reset` giving the reset value of each register that does not reset
/// to zero.
fn emit_registers(w: &mut VerilogWriter, desc: &BlockDesc, reset: &[(&str, String)]) {
    emit_registers_as(w, desc, reset, range);
}

/// [`emit_registers`] with every register declared as a vector, `[0:0]` for one bit too (so
/// the body may index a bank of one register of one bit).
fn emit_vector_registers(w: &mut VerilogWriter, desc: &BlockDesc) {
    emit_registers_as(w, desc, &[], vector_range);
}

/// `[W-1:0] ` for every width, `[0:0] ` for one bit.
fn vector_range(width: u32) -> String {
    format!("[{}:0] ", width.max(1) - 1)
}

/// [`emit_registers`] declaring each register with `range_of(bits)`.
fn emit_registers_as(
    w: &mut VerilogWriter,
    desc: &BlockDesc,
    reset: &[(&str, String)],
    range_of: fn(u32) -> String,
) {
    w.line("");
    w.comment(
        "Registers of the block description: `<name>_q` holds the register, `<name>_d` is its \
         next value, computed combinationally below.",
    );
    for r in &desc.registers {
        let width = reg_bits(r);
        let doc = match (r.count, r.width) {
            (1, _) => r.doc.clone(),
            (_, 1) => format!("{} (bit i = register i)", r.doc),
            (_, w) => format!("{} (register i in bits [i*{w} +: {w}])", r.doc),
        };
        w.line(format!(
            "reg {}{}_q; // {}",
            range_of(width),
            r.name,
            one_line(&doc)
        ));
        w.line(format!("reg {}{}_d;", range_of(width), r.name));
    }
    w.line("");
    w.line("always @(posedge clk) begin : p_registers");
    w.indent();
    w.line("if (rst) begin");
    w.indent();
    for r in &desc.registers {
        let width = reg_bits(r);
        let value = reset
            .iter()
            .find(|(n, _)| *n == r.name)
            .map(|(_, v)| v.clone())
            .unwrap_or_else(|| zero(width));
        w.line(format!("{}_q <= {value};", r.name));
    }
    w.dedent();
    w.line("end else begin");
    w.indent();
    for r in &desc.registers {
        w.line(format!("{0}_q <= {0}_d;", r.name));
    }
    w.dedent();
    w.line("end");
    w.dedent();
    w.line("end");
}

/// A complete module: g1's header and port list (every output a wire), then `body`, which
/// receives the writer at one level of indentation.
fn emit_full_module(desc: &BlockDesc, note: &str, body: impl FnOnce(&mut VerilogWriter)) -> String {
    let mut w = VerilogWriter::new();
    emit_header(&mut w, desc);
    w.comment(note);
    w.line(format!("// {}", "-".repeat(93)));
    emit_ports(&mut w, desc, false);
    w.indent();
    body(&mut w);
    w.dedent();
    w.line("endmodule");
    w.finish()
}

/// Appends a multi-line template (already filled) at the writer's indentation, with the
/// declarations tidied: single spaces in the code, and the trailing comments of consecutive
/// declarations aligned.
fn emit_text(w: &mut VerilogWriter, text: &str) {
    let lines: Vec<&str> = text.lines().collect();
    let mut i = 0;
    while i < lines.len() {
        let Some(first) = split_declaration(lines[i]) else {
            w.line(lines[i]);
            i += 1;
            continue;
        };
        let mut run = vec![first];
        while let Some(d) = lines.get(i + run.len()).and_then(|l| split_declaration(l)) {
            run.push(d);
        }
        let width = run
            .iter()
            .filter(|d| d.2.is_some())
            .map(|d| d.1.len())
            .max()
            .unwrap_or(0);
        for (indent, code, comment) in &run {
            match comment {
                Some(c) => w.line(format!("{indent}{code:width$} {c}")),
                None => w.line(format!("{indent}{code}")),
            }
        }
        i += run.len();
    }
}

/// A one-line `reg`/`wire` declaration as (indentation, code with single spaces, comment).
fn split_declaration(line: &str) -> Option<(String, String, Option<String>)> {
    let text = line.trim_start();
    if !(text.starts_with("reg ") || text.starts_with("wire ")) || !text.contains(';') {
        return None;
    }
    let indent = line[..line.len() - text.len()].to_string();
    let (code, comment) = match text.find("//") {
        Some(i) => (&text[..i], Some(text[i..].trim_end().to_string())),
        None => (text, None),
    };
    let code = code.split_whitespace().collect::<Vec<_>>().join(" ");
    Some((indent, code, comment))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fill_replaces_known_names() {
        let v = [("A", "1".to_string()), ("BB", "x".to_string())];
        assert_eq!(fill("a${A}b${BB}${A}", &v), "a1bx1");
        assert_eq!(fill("{no} $ {x}", &v), "{no} $ {x}");
    }

    #[test]
    fn declarations_are_tidied() {
        let mut w = VerilogWriter::new();
        emit_text(
            &mut w,
            "reg   a;   // first\nwire [3:0]  bb = c; // second\nassign x = y;  // kept\n",
        );
        assert_eq!(
            w.finish(),
            "reg a;             // first\nwire [3:0] bb = c; // second\nassign x = y;  // kept\n"
        );
    }

    #[test]
    fn zext_pads_only_when_needed() {
        assert_eq!(zext("a", 3, 3), "a");
        assert_eq!(zext("a", 3, 5), "{2'd0, a}");
        assert_eq!(lit(4, 9), "4'd9");
    }
}
