//! Verilog of a composed block (a [`vtq_hdl::compose`] block such as the treelet RT unit): a
//! top module with the composite's ports that instantiates every child and one wiring module,
//! and the wiring module itself.
//!
//! The wiring module ([`wiring_desc`]) carries the composite's ports, one port per port of
//! every child in the other direction (a child's input is a wiring output and the other way
//! round), named `<instance>_<port>`, and the composite's own registers: it is the kernel.
//! Its body is generated for each composite ([`crate::rtl::treelet_wiring_verilog`] for the
//! treelet RT unit).
//! The top ([`emit_top`]) declares one net per child port and connects each child and the
//! wiring to them by name, so the child modules (complete RTL where there is some) plug in
//! unchanged.

use crate::emit::{range, VerilogWriter};
use crate::error::GenError;
use crate::verilog::{emit_header, validate_desc};
use vtq_hdl::{BlockDesc, Dir, PortDesc};

/// The instance name of the wiring module in a composite's module.
pub const WIRING_INSTANCE: &str = "wiring";

/// One child of a composite: its instance name and description.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Instance {
    /// Instance name (a Verilog identifier; prefixes the child's nets).
    pub name: String,
    /// The child's description (its module name is `desc.name`).
    pub desc: BlockDesc,
}

/// Name of the wiring module of composite `top`.
pub fn wiring_name(top: &BlockDesc) -> String {
    format!("{}_wiring", top.name)
}

/// The net connecting port `port` of instance `inst`.
fn net(inst: &str, port: &str) -> String {
    format!("{inst}_{port}")
}

/// The wiring module's description (see the module documentation).
pub fn wiring_desc(top: &BlockDesc, children: &[Instance]) -> BlockDesc {
    let mut ports = top.ports.clone();
    for c in children {
        for p in &c.desc.ports {
            ports.push(PortDesc {
                name: net(&c.name, &p.name),
                dir: match p.dir {
                    Dir::In => Dir::Out,
                    Dir::Out => Dir::In,
                },
                width: p.width,
                doc: format!("{} {}: {}", c.name, p.name, p.doc),
            });
        }
    }
    BlockDesc {
        name: wiring_name(top),
        doc: format!(
            "The wiring kernel of {}: maps the composite's inputs, its own registers and its \
             children's outputs to the composite's outputs and its children's inputs.",
            top.name
        ),
        params: top.params.clone(),
        ports,
        registers: top.registers.clone(),
        memories: top.memories.clone(),
        fsms: top.fsms.clone(),
        timing: top.timing.clone(),
    }
}

/// The top module of composite `top` with `children` (see the module documentation).
pub fn emit_top(top: &BlockDesc, children: &[Instance]) -> Result<String, GenError> {
    let wiring = wiring_desc(top, children);
    validate_desc(&wiring)?;
    let top_ports = BlockDesc {
        registers: vec![],
        memories: vec![],
        fsms: vec![],
        ..top.clone()
    };
    validate_desc(&top_ports)?;
    let mut w = VerilogWriter::new();
    emit_header(&mut w, &top_ports);
    emit_module_start(&mut w, &top.name, &top.ports);
    w.indent();
    for c in children {
        w.line("");
        w.comment(&format!("Nets of {} ({}).", c.name, c.desc.name));
        for p in &c.desc.ports {
            w.line(format!("wire {}{};", range(p.width), net(&c.name, &p.name)));
        }
    }
    for c in children {
        w.line("");
        w.line(format!("{} {} (", c.desc.name, c.name));
        w.indent();
        let mut conns = vec![".clk(clk)".to_string(), ".rst(rst)".to_string()];
        conns.extend(
            c.desc
                .ports
                .iter()
                .map(|p| format!(".{}({})", p.name, net(&c.name, &p.name))),
        );
        emit_connections(&mut w, &conns);
        w.dedent();
        w.line(");");
    }
    w.line("");
    w.line(format!("{} {WIRING_INSTANCE} (", wiring.name));
    w.indent();
    let mut conns = vec![".clk(clk)".to_string(), ".rst(rst)".to_string()];
    conns.extend(top.ports.iter().map(|p| format!(".{0}({0})", p.name)));
    for c in children {
        conns.extend(c.desc.ports.iter().map(|p| {
            let n = net(&c.name, &p.name);
            format!(".{n}({n})")
        }));
    }
    emit_connections(&mut w, &conns);
    w.dedent();
    w.line(");");
    w.dedent();
    w.line("endmodule");
    Ok(w.finish())
}

/// `module <name> (` with `clk`, `rst` and `ports`, one a line, up to the closing `);`.
pub(crate) fn emit_module_start(w: &mut VerilogWriter, name: &str, ports: &[PortDesc]) {
    w.line(format!("module {name} ("));
    w.indent();
    w.line("input  wire clk,");
    w.line("input  wire rst,");
    let last = ports.len().saturating_sub(1);
    for (i, p) in ports.iter().enumerate() {
        let dir = match p.dir {
            Dir::In => "input  wire",
            Dir::Out => "output wire",
        };
        let comma = if i == last { "" } else { "," };
        w.line(format!("{dir} {}{}{comma}", range(p.width), p.name));
    }
    w.dedent();
    w.line(");");
}

/// Port connections, one a line, comma-separated.
pub(crate) fn emit_connections(w: &mut VerilogWriter, conns: &[String]) {
    let last = conns.len().saturating_sub(1);
    for (i, c) in conns.iter().enumerate() {
        w.line(if i == last {
            c.clone()
        } else {
            format!("{c},")
        });
    }
}

/// The composite's top module and its wiring module (`wiring`, its Verilog), as `(module
/// name, Verilog)` pairs; the children's modules are generated on their own.
pub fn composite_modules(
    top: &BlockDesc,
    children: &[Instance],
    wiring: String,
) -> Result<Vec<(String, String)>, GenError> {
    Ok(vec![
        (top.name.clone(), emit_top(top, children)?),
        (wiring_name(top), wiring),
    ])
}
