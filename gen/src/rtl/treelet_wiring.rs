//! RTL of the treelet RT unit's wiring (`vtq_hdl::treelet_rt_unit`'s kernel, module
//! `treelet_rt_unit_wiring`): the slot owners, the fills of ray records, the event FIFO to the
//! controller, the tables' registered answers, the free ray ids and the first fault, between the
//! composite's ports and its children's (see [`crate::compose`] for the module's ports).
//!
//! The body follows the Rust kernel's stages in dependency order, each an always block of its
//! own: arriving records join their fills (`p_place`); the controller's inputs come from
//! registers and the children's register-only ports (`p_reports` and the assigns after it: the
//! RT unit's status ports, the tables' `accepts`/`ready`/`refill_waiting`, the controller's
//! `mode_reg`); the children's inputs follow from the controller's outputs (`p_children`: the
//! event taken, a fill's rays, the issue of a complete fill or the admission of an SM warp with
//! ray ids popped from the free-id stack (its banks' read data or bypasses) and fresh ids; the ray-record requests in
//! `p_requests`); the RT unit's released and completed lanes are unpacked (`p_unpack`) and the
//! finished rays' ids pushed on the free-id stack (`p_id_writes`, one
//! `treelet_rt_unit_wiring_id_bank` SRAM per bank); `p_next` gives the next registers.
//!
//! Records (2,806 bits at the defaults) only move through one-hot crossbars: the always blocks
//! compute selects from ids, ranks and counts, and one `treelet_rt_unit_wiring_pick` instance
//! per destination (fill entry, issued lane; the parked rays' enqueues, ids and treelets only)
//! moves the data; parked and finished rays leave at their lanes' positions, uncompacted. No
//! wide vector is indexed by a computed position, which is what keeps Yosys' front end and
//! synthesis tractable (the first body, written with running indices into the records, was
//! killed for memory at the defaults), and hierarchical synthesis builds each crossbar once.
//!
//! Every width comes from the wiring's description (its ports and registers) and is checked
//! against the block's; ray ids on the RT unit's lanes are unique (the wiring gives them out),
//! which the RTL relies on.

use super::{emit_full_module, emit_registers_as, emit_text, fill, lit, vector_range, DescInfo};
use crate::compose::{wiring_desc, Instance};
use crate::emit::VerilogWriter;
use crate::error::GenError;
use vtq_hdl::rt_unit::NodeDatapath;
use vtq_hdl::treelet_rt_unit::TreeletRtUnit;
use vtq_hdl::{bits_for, clog2, Block, BlockDesc, Dir};

/// The template of the module body (`${NAME}` placeholders).
const BODY: &str = include_str!("treelet_wiring/body.v");

/// The children of `unit` as instances (name and description), in the order of its
/// registers: `rt`, `ctl`, `ct`, `qt`.
pub fn instances<D: NodeDatapath>(unit: &TreeletRtUnit<D>) -> Vec<Instance> {
    unit.children()
        .into_iter()
        .map(|(name, desc)| Instance {
            name: name.to_string(),
            desc,
        })
        .collect()
}

/// The wiring module's description for `unit` ([`wiring_desc`] of its description and
/// children).
pub fn treelet_wiring_desc<D: NodeDatapath>(unit: &TreeletRtUnit<D>) -> BlockDesc {
    wiring_desc(&unit.describe(), &instances(unit))
}

/// Complete Verilog-2005 for the treelet RT unit's wiring (module `treelet_rt_unit_wiring`),
/// cycle-exact with the Rust kernel (see the module documentation).
pub fn treelet_wiring_verilog<D: NodeDatapath>(
    unit: &TreeletRtUnit<D>,
) -> Result<String, GenError> {
    let desc = treelet_wiring_desc(unit);
    let info = DescInfo::new(&desc)?;
    let cfg = unit.config();
    let params = unit.params();
    let n = info.param("warp_size")? as u32;
    let s = info.param("warp_buffer_size")? as u32;
    let mr = info.param("max_rays")? as u32;
    let ray_base = info.param("ray_base")?;
    let sb = info.port("rt_issue_slot", Dir::Out)?;
    let rb = info.port("sm_ray_id", Dir::Out)? / n;
    let k = info.port("ray_record_id", Dir::In)? / rb;
    let rcw = info.port("ray_count", Dir::In)?;
    let tw = info.port("spill_head_treelet", Dir::In)?;
    let ab = info.port("mem_req_address", Dir::Out)?;
    let spw = info.port("sm_cur_sp", Dir::In)? / n;
    let scw = info.port("sm_cur_spilled", Dir::In)? / n;
    let de = info.port("sm_cur_stack", Dir::In)? / n;
    let d = cfg.record_stack_entries;
    let e = de / d;
    let cw = info.port("ctl_fill_count", Dir::In)?;
    let lw = info.port("finished_count", Dir::Out)?;
    let cmw = info.port("ctl_ct_max_count", Dir::Out)?;
    let ctcw = info.port("ct_max_count", Dir::In)?;
    let fcw = info.reg("id_count")?;
    let ids_mem = info.mem("free_ids", &[("ray", rb)], 1)?;
    let idb = ids_mem.banks;
    let idbw = clog2(idb as u64);
    let idwd = ids_mem.depth;
    let idaw = clog2(idwd as u64).max(1);
    let bypass = desc
        .registers
        .iter()
        .find(|r| r.name == "id_bypass")
        .ok_or_else(|| info.bad("the RTL needs a register bank `id_bypass`".into()))?;
    let evw = info.reg("event_count")?;
    let events = desc
        .registers
        .iter()
        .find(|r| r.name == "events")
        .ok_or_else(|| info.bad("the RTL needs a register bank `events`".into()))?;
    let evd = events.count;
    // A ray record on the bus: {other_stack, cur_stack, other_spilled, cur_spilled, other_sp,
    // cur_sp, cur_treelet, hit, hit_valid, occlusion, ray_words, ray id}.
    let rec = rb + 256 + 1 + 1 + 128 + tw + 2 * spw + 2 * scw + 2 * de;
    let qdw = desc
        .registers
        .iter()
        .find(|r| r.name == "last_qt_done")
        .map_or(0, |r| r.width);
    let tsh = clog2(cfg.treelet_bytes as u64);
    let consistent = info.port("rt_issue_ray_id", Dir::Out)? == n * rb
        && qdw == 1 + tw + cw + n * rb
        && events.width == 1 + rb + tw
        && cw == bits_for(n as u64)
        && info.port("rt_status_traversing", Dir::In)? == s * cw
        && info.port("ctl_init_active", Dir::Out)? == cw
        && fcw == bits_for(mr as u64)
        && bypass.width == rb + 1
        && bypass.count == idb
        && idb.is_power_of_two()
        && idb >= 2
        && idb * idwd == mr
        && idb == (2 * n).min(mr)
        && lw >= cw
        && ctcw >= cmw
        && ab >= rb + 5
        && rb >= sb
        && k >= 1
        && k <= n
        && d * e == de
        && tsh + 5 + tw <= e;
    if !consistent {
        return Err(info.bad(format!(
            "sizes are inconsistent: record {rec}, ray {rb}, treelet {tw}, lanes {cw}, \
             stack {de} bits from the description"
        )));
    }
    let params_text = [
        format!("localparam N = {n};        // lanes per warp"),
        format!("localparam S = {s};        // warp-buffer slots"),
        format!("localparam SB = {sb};      // slot index bits"),
        format!("localparam RB = {rb};      // ray id bits"),
        format!("localparam K = {k};        // record ports (records written a cycle)"),
        format!("localparam RCW = {rcw};    // bits of the returning-record count"),
        format!("localparam TW = {tw};      // treelet number bits"),
        format!("localparam AB = {ab};      // address bits"),
        format!("localparam MR = {mr};      // ray ids (max_rays)"),
        format!("localparam IDB = {idb};    // banks of the free-id stack"),
        format!("localparam IDBW = {idbw};  // bank index bits"),
        format!("localparam IDWD = {idwd};  // words per bank"),
        format!("localparam IDAW = {idaw};  // bank address bits (at least 1)"),
        format!("localparam D = {d};        // stack entries a ray record carries (record_stack_entries)"),
        format!("localparam E = {e};        // stack entry: {{address, kind, chunks - 1}}"),
        format!("localparam DE = {de};      // bits of a stack"),
        format!("localparam SPW = {spw};    // a record's stack pointer bits"),
        format!("localparam SCW = {scw};    // spilled-chunk count bits"),
        format!("localparam TSH = {tsh};    // log2(treelet_bytes)"),
        format!("localparam CW = {cw};      // a warp's lane count bits"),
        format!("localparam LW = {lw};      // two warps' lane count bits"),
        format!("localparam CMW = {cmw};    // the controller's count-table count bits"),
        format!("localparam CTCW = {ctcw};  // the count table's count bits"),
        format!("localparam FCW = {fcw};    // free-id count bits"),
        format!("localparam EVD = {evd};    // event FIFO entries"),
        format!("localparam EVW = {evw};    // event count bits"),
        format!("localparam REC = {rec};    // a ray record on the bus"),
        format!("localparam QDW = {qdw};    // the queue table's registered answer"),
        format!(
            "localparam ADMIT_TS = {}; // SM warps admitted in the treelet-stationary mode",
            u8::from(params.features.admit_in_treelet_stationary)
        ),
        format!("localparam [AB-1:0] RAY_BASE = {};", lit(ab, ray_base)),
        format!("localparam [CW-1:0] ONE_CW = {};", lit(cw, 1)),
    ]
    .join("\n");
    let mut regs = VerilogWriter::new();
    emit_registers_as(&mut regs, &desc, &[], vector_range);
    let pop_rays = (0..n)
        .rev()
        .map(|i| format!("qt_pop_ray_{i}"))
        .collect::<Vec<_>>()
        .join(", ");
    let zext = |expr: &str, from: u32, to: u32| {
        if to > from {
            format!("{{{}'d0, {expr}}}", to - from)
        } else {
            expr.to_string()
        }
    };
    let mut responses = Vec::new();
    for k in 0.. {
        if desc.port(&format!("resp{k}_valid")).is_none() {
            break;
        }
        for f in ["valid", "address", "tag", "data"] {
            responses.push(format!("assign rt_resp{k}_{f} = resp{k}_{f};"));
        }
    }
    // The RT unit's request, errors, FIFO room and statistics events leave unchanged.
    let mut pass = vec![
        "assign resp_free = rt_resp_free;".to_string(),
        "assign mem_req_valid = rt_req_valid;".to_string(),
        "assign mem_req_address = rt_req_address;".to_string(),
        "assign mem_req_kind = rt_req_kind;".to_string(),
        "assign mem_req_tag = rt_req_tag;".to_string(),
        "assign mem_req_data = rt_req_data;".to_string(),
    ];
    for p in &desc.ports {
        let child = if p.name == "errors" || p.name.starts_with("error_") {
            Some(format!("rt_{}", p.name))
        } else {
            p.name
                .strip_prefix("count_rt_")
                .map(|rest| format!("rt_count_{rest}"))
        };
        if let Some(child) = child {
            let from = info.port(&child, Dir::In)?;
            pass.push(format!(
                "assign {} = {};",
                p.name,
                zext(&child, from, p.width)
            ));
        }
    }
    let mut text = fill(
        BODY,
        &[
            ("PARAMS", params_text),
            ("REGISTERS", regs.finish()),
            ("QT_POP_RAYS", format!("{{{pop_rays}}}")),
            ("RESPONSES", responses.join("\n")),
            ("NLOADS_LW", zext("nloads", cw, lw)),
            ("NEED_LW", zext("need", cw, lw)),
            ("PASS_THROUGH", pass.join("\n")),
            ("UNUSED", String::new()),
            ("ID_WADDR", bank_address("wpos", rb, idbw)),
            ("ID_RADDR", bank_address("rpos", rb, idbw)),
            ("RECORD_OFFSETS", record_offsets()),
            ("ARRIVED_WIRES", port_vectors("ray_record", "rr", "K")),
            ("PACK_ARRIVED", pack_record("rr", "rr_id[gl*RB +: RB]")),
            ("PACK_SM", pack_record("sm", "admit_ids[gl*RB +: RB]")),
            (
                "PACK_DONE",
                pack_record("rt_done", "rt_done_ray_id[gl*RB +: RB]"),
            ),
            ("UNPACK_ISSUE", unpack_record("rt_issue", "issue_rec")),
            ("UNPACK_PARKED", unpack_record("parked", "park_rec")),
        ],
    );
    // Inputs the wiring does not read (or reads in part) are gathered for the linter.
    let unused: Vec<String> = desc
        .ports
        .iter()
        .filter(|p| p.dir == Dir::In && !mentions(&text, &p.name))
        .map(|p| p.name.clone())
        .collect();
    if !unused.is_empty() {
        text.push_str(&format!(
            "\n// Inputs the wiring does not read.\n/* verilator lint_off UNUSEDSIGNAL */\n\
             wire unused_inputs = &{{1'b0, {}}};\n/* verilator lint_on UNUSEDSIGNAL */\n",
            unused.join(", ")
        ));
    }
    let note = "Complete RTL of the wiring kernel, cycle-exact with vtq_hdl's treelet RT unit \
                (co-simulated from the ports of real runs): slot owners, fills of ray records, \
                the event FIFO, the tables' registered answers, free ray ids.";
    let mut out = emit_full_module(&desc, note, |w| emit_text(w, &text));
    out.push_str(PICK);
    Ok(out)
}

/// A free-id bank's word address from stack position vector `pos` (its bits above the bank
/// index; `1'b0` when each bank holds one word).
fn bank_address(pos: &str, rb: u32, idbw: u32) -> String {
    if rb > idbw {
        format!("{pos}[IDBW +: IDAW]")
    } else {
        "1'b0".to_string()
    }
}

/// A ray record's fields as the wiring keeps it, highest first, above its ray id (bits
/// `[0 +: RB]`): `(field, width, offset)`, the field as the ports name it
/// (`<prefix>_<field>`), its width and the localparam of its offset in the record. One list
/// for every place a record is packed from or unpacked into a lane's ports.
const RECORD_FIELDS: [(&str, &str, &str); 11] = [
    ("other_stack", "DE", "F_OST"),
    ("cur_stack", "DE", "F_CST"),
    ("other_spilled", "SCW", "F_OSC"),
    ("cur_spilled", "SCW", "F_CSC"),
    ("other_sp", "SPW", "F_OSP"),
    ("cur_sp", "SPW", "F_CSP"),
    ("cur_treelet", "TW", "F_CT"),
    ("hit", "128", "F_HIT"),
    ("hit_valid", "1", "F_HV"),
    ("occlusion", "1", "F_OCC"),
    ("ray_words", "256", "F_WORDS"),
];

/// The localparams of [`RECORD_FIELDS`]' offsets, lowest first (the first above the ray id).
fn record_offsets() -> String {
    let mut below = "RB".to_string();
    RECORD_FIELDS
        .iter()
        .rev()
        .map(|(_, width, offset)| {
            let line = format!("localparam {offset} = {below};");
            below = format!("{offset} + {width}");
            line
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The record ports' fields `<port>_<field>` (and `<port>_id`, `<port>_slot`) as vectors
/// `<local>_<field>` of `lanes` entries: a port of one bit is a scalar, which cannot be
/// indexed.
fn port_vectors(port: &str, local: &str, lanes: &str) -> String {
    RECORD_FIELDS
        .iter()
        .map(|(field, width, _)| (*field, *width))
        .chain([("id", "RB"), ("slot", "SB")])
        .map(|(field, width)| {
            format!("wire [{lanes}*{width}-1:0] {local}_{field} = {port}_{field};")
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Lane `gl`'s slice of port `<prefix>_<field>` of `width` bits per lane.
fn lane_slice(prefix: &str, field: &str, width: &str) -> String {
    if width == "1" {
        format!("{prefix}_{field}[gl]")
    } else {
        format!("{prefix}_{field}[gl*{width} +: {width}]")
    }
}

/// Lane `gl`'s ray record packed from the lane's ports `<prefix>_<field>`, its ray id `id`.
fn pack_record(prefix: &str, id: &str) -> String {
    let mut parts: Vec<String> = RECORD_FIELDS
        .iter()
        .map(|(field, width, _)| lane_slice(prefix, field, width))
        .collect();
    parts.push(id.to_string());
    let lines: Vec<String> = parts.chunks(2).map(|pair| pair.join(", ")).collect();
    format!("{{\n            {}}}", lines.join(",\n            "))
}

/// Lane `gl`'s ports `<prefix>_<field>` (all but the ray id) driven from its record in
/// `records` (`REC` bits per lane).
fn unpack_record(prefix: &str, records: &str) -> String {
    RECORD_FIELDS
        .iter()
        .rev()
        .map(|(field, width, offset)| {
            let bits = if *width == "1" {
                format!("{records}[gl*REC + {offset}]")
            } else {
                format!("{records}[gl*REC + {offset} +: {width}]")
            };
            format!(
                "        assign {} = {bits};",
                lane_slice(prefix, field, width)
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The wiring's crossbar: one of `NI` inputs of `W` bits picked by a one-hot select (zero when
/// none is selected). Every record the wiring moves to a computed place goes through one
/// instance per destination, so synthesis builds each crossbar once per shape.
const PICK: &str = "
// One of NI W-bit inputs picked by a one-hot select (zero when none is): the wiring's record
// crossbars, one instance per destination.
/* verilator lint_off DECLFILENAME */
module treelet_rt_unit_wiring_pick #(
    parameter NI = 1,
    parameter W = 1
) (
    input wire [NI-1:0] sel,
    input wire [NI*W-1:0] in,
    output reg [W-1:0] out
);
always @* begin : p_pick
    integer i;
    out = {W{1'b0}};
    for (i = 0; i < NI; i = i + 1)
        out = out | (sel[i] ? in[i*W +: W] : {W{1'b0}});
end
endmodule

// One bank of the wiring's free-id stack: an SRAM of DEPTH ray ids with one write port and one
// read port of read latency 1, read-first (a read and a write of one word in a cycle read the
// old id); no reset (nothing is read before it is written).
module treelet_rt_unit_wiring_id_bank #(
    parameter RB = 1,
    parameter DEPTH = 1,
    parameter AW = 1
) (
    input wire clk,
    input wire rst,
    input wire we,
    input wire [AW-1:0] waddr,
    input wire [RB-1:0] wdata,
    input wire [AW-1:0] raddr,
    output reg [RB-1:0] rdata
);
reg [RB-1:0] mem [0:DEPTH-1];
always @(posedge clk) begin : p_bank
    if (!rst && we) mem[waddr] <= wdata;
    rdata <= mem[raddr];
end
endmodule
/* verilator lint_on DECLFILENAME */
";

/// Whether `text` mentions identifier `name` (not as part of a longer identifier).
fn mentions(text: &str, name: &str) -> bool {
    let ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
    text.match_indices(name).any(|(i, _)| {
        let before = text[..i].chars().next_back();
        let after = text[i + name.len()..].chars().next();
        !before.is_some_and(ident) && !after.is_some_and(ident)
    })
}
