//! RTL of the RT unit's control (`vtq_hdl::rt_unit::RtUnit`, paper section 2.2, Figure 3;
//! section 4.2, Figure 8): the warp buffer with per-ray traversal state and two stacks with
//! spill and fill, the memory scheduler with request merging, the response FIFO, the
//! intersection-delay countdown, warp completion, the treelet controller's commands (issue into
//! a slot, append, stop, repack) and the register-only status ports.
//!
//! The module is split the way the hardware is: one `rt_unit_lane` per lane of the warp buffer
//! holds that lane's registers and stacks and computes their next state (`rt_unit`
//! reads the description's lane registers through wires `lane_<field>_q`), and `rt_unit` holds
//! the slot-level logic between them. The lane runs the stages of `RtUnit::update` on its own
//! state — completion, its request merged or its spill or fill as the scheduler's leader, the
//! delay countdown, the popped response (a fill or a chunk of its node), the test's result
//! written back, the warp issue, stop and repack — each stage an always block of its own. The
//! slot level decides what concerns each lane from start-of-cycle state (a completing warp's
//! lanes are quiescent, so completion does not change what the scheduler sees): which warp
//! completes, which store or which leader's request goes out, which lanes a response is for;
//! it raises the errors in `RtUnit::update`'s order, runs the response FIFO and decodes the
//! controller's commands. Between the lanes' stages sits the intersection datapath, one
//! `rt_datapath` instance per lane index, fed by that lane of the popped response's slot,
//! outside the RT unit's control (a black box with the interface of [`DATAPATH_PORTS`]): the
//! Rust block calls its `NodeDatapath` at the same point of the cycle. [`toy_datapath_verilog`]
//! is the Verilog of the toy node format the co-simulation uses on both sides
//! (`vtq_gen::stimulus::rt_unit::ToyDatapath`).
//!
//! Each lane's two stacks are stored as a chip would (`vtq_hdl::rt_unit::StackLayout`): the
//! bottom entries in a window of flip-flops, the rest in a ring of SRAM banks
//! (`rt_unit_stack_bank`, one read and one write port, read latency 1, kept by Yosys as memory
//! macros), the top copied in a register while it lies in the ring. The node buffer is four
//! SRAM banks at the slot level (`rt_unit_node_bank`, chunk c of a node in bank c, one word per
//! slot and leader lane, read one cycle ahead at the next popped response's leader); the
//! response FIFO is a flip-flop array.
//! The module lints clean, co-simulates with 0 mismatches (`gen/tests/rt_unit_rtl.rs`) and
//! synthesizes under Yosys (a first, single-always-block version of the same logic did not: its loops over
//! slots and lanes unrolled into multiplexer chains Yosys could not finish in 20 minutes).

use super::{emit_full_module, emit_text, emit_vector_registers, fill, lit, DescInfo};
use crate::emit::VerilogWriter;
use crate::error::GenError;
use vtq_hdl::rt_unit::{spill_area, NoDatapath, RtUnit, RtUnitParams};
use vtq_hdl::{bits_for, clog2, Block, BlockDesc, Dir, HwConfig};

/// The template of the module body (`${NAME}` placeholders, see [`rt_unit_verilog`]).
const BODY: &str = include_str!("rt_unit/body.v");

/// The template of the lane module `rt_unit_lane` (same placeholders).
const LANE: &str = include_str!("rt_unit/lane.v");

/// The constants and functions both modules use.
const COMMON: &str = include_str!("rt_unit/common.v");

/// Bits of a child on the datapath interface: `{address[63:0], kind[2:0], chunks[7:0]}` (the
/// raw `NodeEntry` the datapath returns, checked by the RT unit).
pub const CHILD_BITS: u32 = 75;

/// Bits of the datapath's child count (saturating).
pub const CHILD_COUNT_BITS: u32 = 8;

/// The interface of the intersection datapath (`rt_datapath`, one instance per lane), as
/// `(port, direction, width, meaning)`; `E` is a stack entry's width, `R` `max_children`. Its
/// parameters are `AB` (address bits), `E`, `R` and `LANE`, the lane index the instance
/// serves.
pub const DATAPATH_PORTS: [(&str, &str, &str, &str); 9] = [
    (
        "ray",
        "input",
        "256",
        "the ray's words: origin, direction, tmin, tmax (f32 bits, word 0 lowest)",
    ),
    (
        "best_valid",
        "input",
        "1",
        "the ray has a closest hit so far",
    ),
    (
        "best",
        "input",
        "128",
        "that hit: {attribs[1], attribs[0], hit id, t}",
    ),
    (
        "node",
        "input",
        "E",
        "the node tested: {address, kind, chunks - 1}",
    ),
    (
        "data",
        "input",
        "1024",
        "the node's bytes, byte b in bits [8b +: 8] (chunks beyond the node undefined)",
    ),
    (
        "child_count",
        "output",
        "8",
        "children to visit (saturating at 255; more than R is an error)",
    ),
    (
        "children",
        "output",
        "R*75",
        "child c in bits [c*75 +: 75]: {address[63:0], kind, chunks}, visit order",
    ),
    ("hit_valid", "output", "1", "a candidate hit"),
    (
        "hit",
        "output",
        "128",
        "the candidate: {attribs[1], attribs[0], hit id, t}",
    ),
];

/// Complete Verilog-2005 for the RT unit's control for `cfg` and `params` (module `rt_unit`),
/// cycle-exact with the Rust block; it instantiates `rt_datapath` (see the module
/// documentation), which must be supplied beside it (e.g. [`toy_datapath_verilog`]).
pub fn rt_unit_verilog(cfg: &HwConfig, params: &RtUnitParams) -> Result<String, GenError> {
    let block = RtUnit::new(cfg.clone(), params.clone(), NoDatapath)?;
    let desc = block.describe();
    let info = DescInfo::new(&desc)?;
    let w = block.widths();
    let n = info.param("warp_size")? as u32;
    let s = info.param("warp_buffer_size")? as u32;
    let d = info.param("stack_depth")? as u32;
    let rd = info.param("record_stack_entries")? as u32;
    let k = info.param("stack_window")? as u32;
    let sk = info.param("stack_banks")? as u32;
    let swd = info.param("stack_bank_words")? as u32;
    let ab = info.param("address_bits")? as u32;
    let treelet_bytes = info.param("treelet_bytes")?;
    let fd = info.param("resp_fifo_depth")? as u32;
    let rp = info.param("resp_ports")? as u32;
    let r = info.param("max_children")? as u32;
    let spc = info.param("stack_spill_chunks")?;
    let hb = info.param("hit_record_base")?;
    let tsh = clog2(treelet_bytes);
    let e = ab + 5;
    let (spill_lo, spill_hi) = spill_area(cfg, params);
    // Every width the body uses, from the description, checked against the block's widths.
    let rb = info.port("issue_ray_id", Dir::In)? / n;
    let lb = info.port("error_lane", Dir::Out)?;
    let sb = info.port("done_slot", Dir::Out)?;
    let tw = info.port("boundary_treelet", Dir::Out)? / n;
    let rspw = info.port("issue_cur_sp", Dir::In)? / n;
    let spw = info.bank("lane_cur_sp")?;
    let scw = info.port("issue_cur_spilled", Dir::In)? / n;
    let dw = info.bank("lane_delay")?;
    let fcw = info.reg("fifo_count")?;
    let spb = info.bank("lane_cur_base")?;
    let fpw = info.reg("fifo_head")?;
    let naw = info.reg("node_write_index")?;
    let node_buffer = info.mem("node_buffer", &[("data", 256)], 1)?;
    let scnt = info.reg("age_count")?;
    let tgw = info.port("req_tag", Dir::Out)?;
    let cww = info.port("count_warps", Dir::Out)?;
    let caw = info.port("count_active", Dir::Out)?;
    let cmw = info.port("count_merged", Dir::Out)?;
    let ctw = info.port("count_tests_header", Dir::Out)?;
    let snw = info.port("status_traversing", Dir::Out)? / s;
    let consistent = lb == w.lane
        && rb == w.ray_id
        && sb == w.slot
        && tw == w.treelet
        && tw == ab - tsh
        && spw == w.stack_pointer
        && rspw == w.record_pointer
        && rd == w.record_stack
        && rd <= d
        && k >= rd
        && k >= d.min(4)
        && k <= d
        && (sk == 0 || (sk.is_power_of_two() && sk >= r && sk >= 4))
        && k + sk * swd >= d
        && spb == clog2((sk * swd).max(2) as u64)
        && scw == w.spilled
        && dw == w.delay
        && fcw == w.fifo_count
        && tgw == sb + lb
        && fpw == clog2(fd as u64)
        && naw == clog2((n * s) as u64).max(1)
        && node_buffer.banks == 4
        && node_buffer.depth == n * s
        && (node_buffer.read_ports, node_buffer.write_ports) == (1, 1)
        && scnt == bits_for(s as u64)
        && e == w.entry()
        && info.port("issue_cur_stack", Dir::In)? == n * rd * e
        && info.port("resp0_data", Dir::In)? == 256
        && e <= 63
        && rp <= 8;
    if !consistent {
        return Err(info.bad(format!(
            "sizes are inconsistent: {w:?} from the block; lane {lb}, ray {rb}, slot {sb}, \
             treelet {tw}, stack pointer {spw}, record stack pointer {rspw}, spilled {scw}, delay {dw} bits from the description"
        )));
    }
    if block
        .reg_signals(&block.reset())
        .iter()
        .any(|x| x.value != 0)
    {
        return Err(info.bad("a register does not reset to 0, the RTL expects it".into()));
    }
    let l = &params.latencies;
    let few = ab + tgw + 256;
    // The datapath latencies, as delay-wide constants `LAT_<name>`.
    let latencies = [
        ("HEADER", l.header),
        ("INTERNAL", l.internal),
        ("INSTANCE", l.instance_leaf),
        ("PRIMITIVE", l.primitive_descriptor),
        ("TRI", l.triangle_leaf),
        ("TRI_HIT", l.triangle_hit),
        ("PROCEDURAL", l.procedural),
    ];
    // Counters' increments: a constant 1 `ONE_<name>` of width `<name>` each.
    let ones = [
        ("CWW", cww),
        ("CMW", cmw),
        ("SPW", spw),
        ("SCW", scw),
        ("DW", dw),
        ("FCW", fcw),
        ("FPW", fpw),
        ("SCNT", scnt),
    ];
    let params_text = [
        format!("localparam N = {n};        // lanes per warp"),
        format!("localparam S = {s};        // warp-buffer slots"),
        format!(
            "localparam NL = {};       // lanes of the warp buffer (lane L = slot * N + lane)",
            n * s
        ),
        format!("localparam D = {d};        // on-chip entries per stack"),
        format!("localparam RD = {rd};      // stack entries a ray record carries (record_stack_entries)"),
        format!("localparam RSPW = {rspw};  // bits of a record's stack depth"),
        format!("localparam K = {k};        // a stack's bottom entries in flip-flops (its window)"),
        format!("localparam SK = {sk};      // SRAM banks of a stack's ring (0: none)"),
        format!("localparam SKB = {};      // SK, at least 1 (vector widths)", sk.max(1)),
        format!(
            "localparam SBW = {};      // bank index bits",
            clog2(sk.max(2) as u64)
        ),
        format!("localparam SWD = {};      // words per bank", swd.max(1)),
        format!(
            "localparam SAW = {};      // word address bits",
            clog2(swd.max(2) as u64)
        ),
        format!("localparam SPB = {spb};    // ring position bits"),
        format!("localparam NAW = {naw};    // node-buffer word address bits (slot, leader lane)"),
        format!("localparam AB = {ab};      // address bits"),
        format!("localparam E = {e};        // stack entry: {{address, kind, chunks - 1}}"),
        format!("localparam TSH = {tsh};    // log2(treelet_bytes)"),
        format!("localparam TW = {tw};      // treelet number bits"),
        format!("localparam LB = {lb};      // lane index bits"),
        format!("localparam SB = {sb};      // slot index bits"),
        format!("localparam TGW = {tgw};    // request tag bits (slot, lane)"),
        format!("localparam RB = {rb};      // ray id bits"),
        format!("localparam SPW = {spw};    // stack pointer bits"),
        format!("localparam SCW = {scw};    // spilled-chunk count bits"),
        format!("localparam DW = {dw};      // intersection-delay bits"),
        format!("localparam FD = {fd};      // response-FIFO entries"),
        format!("localparam FPW = {fpw};    // response-FIFO pointer bits"),
        format!("localparam FCW = {fcw};    // response-FIFO count bits"),
        format!("localparam FEW = {few};    // response-FIFO entry: {{address, tag, data}}"),
        format!("localparam R = {r};        // most children of a node (max_children)"),
        format!("localparam CW = {CHILD_COUNT_BITS};  // datapath child count bits"),
        format!("localparam CHW = {CHILD_BITS};       // datapath child bits"),
        format!("localparam SCNT = {scnt};  // age_count bits"),
        format!("localparam SNW = {snw};    // per-slot lane count bits of the status ports"),
        format!("localparam CWW = {cww};"),
        format!("localparam CAW = {caw};"),
        format!("localparam CMW = {cmw};"),
        format!("localparam CTW = {ctw};"),
        format!(
            "localparam [AB-1:0] SBASE_AB = {}; // stack spill area",
            lit(ab, spill_lo)
        ),
        format!("localparam [AB-1:0] SPC_AB = {};", lit(ab, spc)),
        format!(
            "localparam [AB-1:0] HB_AB = {}; // hit_record_base",
            lit(ab, hb)
        ),
        format!("localparam [AB:0] SPILL_LO = {};", lit(ab + 1, spill_lo)),
        format!("localparam [AB:0] SPILL_HI = {};", lit(ab + 1, spill_hi)),
        format!(
            "localparam [63:0] SPC64 = {}; // stack_spill_chunks",
            lit(64, spc)
        ),
        format!("localparam [SCW-1:0] SPC_W = {};", lit(scw, spc)),
        format!(
            "localparam [63:0] SPACE64 = {}; // bytes of the address space",
            lit(64, 1u64 << ab)
        ),
        format!("localparam [63:0] S_64 = {};", lit(64, s as u64)),
        format!("localparam [63:0] S_PLUS1_64 = {};", lit(64, s as u64 + 1)),
        format!("localparam [63:0] R64 = {};", lit(64, r as u64)),
        format!("localparam [15:0] R16 = {};", lit(16, r as u64)),
        format!("localparam [15:0] D16 = {};", lit(16, d as u64)),
        format!("localparam [SPW-1:0] D_SPW = {};", lit(spw, d as u64)),
        format!("localparam [SPW-1:0] RD_SPW = {};", lit(spw, rd as u64)),
        format!("localparam [SPW-1:0] K_SPW = {};", lit(spw, k as u64)),
        format!(
            "localparam [CW-1:0] R_CW = {};",
            lit(CHILD_COUNT_BITS, r as u64)
        ),
        format!("localparam [FCW-1:0] FD_W = {};", lit(fcw, fd as u64)),
        format!(
            "localparam [FPW-1:0] FD_LAST = {};",
            lit(fpw, fd as u64 - 1)
        ),
        format!("localparam [7:0] RP_8 = {};", lit(8, rp as u64)),
    ]
    .into_iter()
    .chain(latencies.map(|(name, cycles)| {
        format!("localparam [DW-1:0] LAT_{name} = {};", lit(dw, cycles as u64))
    }))
    .chain(ones.map(|(name, bits)| {
        format!("localparam [{name}-1:0] ONE_{name} = {};", lit(bits, 1))
    }))
    .collect::<Vec<_>>()
    .join("\n");
    let lane_text = lane_pieces(
        &desc,
        &info,
        n * s,
        &[lb, rb, tw, spw, scw, dw, e, k * e, spb, k + 1],
    )?;
    let mut count_resp = String::new();
    let mut push_resp = String::new();
    for k in 0..rp {
        count_resp.push_str(&format!("if (resp{k}_valid) nvalid = nvalid + 8'd1;\n    "));
        push_resp.push_str(&format!(
            "if (resp{k}_valid) begin\n        \
                 if (fifo_count_d < FD_W) begin\n            \
                     for (j = 0; j < FD; j = j + 1)\n                \
                         if (fifo_tail_d == j[FPW-1:0]) resp_fifo_d[j*FEW +: FEW] = {{resp{k}_address, resp{k}_tag, resp{k}_data}};\n            \
                     fifo_tail_d = (fifo_tail_d == FD_LAST) ? {{FPW{{1'b0}}}} : fifo_tail_d + ONE_FPW;\n            \
                     fifo_count_d = fifo_count_d + ONE_FCW;\n        \
                 end else begin\n            \
                     {{errors_d, first_error_d}} = raised(errors_d, first_error_d, E_FIFO, {{SB{{1'b0}}}}, {{LB{{1'b0}}}}, {{RB{{1'b0}}}}, {{56'd0, nvalid}}, {{48'd0, lim}});\n        \
                 end\n    \
             end\n    "
        ));
    }
    let outputs = output_assigns(&desc, &info)?;
    let mut vars: Vec<(&str, String)> = vec![
        ("BANK_E", e.to_string()),
        ("BANK_DEPTH", swd.max(1).to_string()),
        ("BANK_AW", clog2(swd.max(2) as u64).to_string()),
        ("NODE_DEPTH", (n * s).to_string()),
        ("NODE_AW", naw.to_string()),
        ("PARAMS", params_text),
        ("COMMON", COMMON.to_string()),
        ("COUNT_RESP", count_resp),
        ("PUSH_RESP", push_resp),
        ("OUTPUTS", outputs),
    ];
    vars.extend(lane_text);
    let text = fill(BODY, &vars);
    let lane = fill(LANE, &vars);
    let note =
        "Full RTL (not a skeleton), cycle-exact with vtq_hdl::rt_unit::RtUnit: every output \
                equals Block::eval in every cycle (co-simulated by gen/tests/rt_unit_rtl.rs on a \
                reactive random environment with the toy datapath). One rt_unit_lane per lane of the \
                warp buffer holds the lane's registers and runs RtUnit::update's stages on them; \
                this module holds the slot-level logic; the intersection datapath is the \
                rt_datapath module (one per lane index), outside the control.";
    let mut out = emit_full_module(&desc, note, |wr| {
        // The lanes' registers live in their lane modules.
        let mut slot_level = desc.clone();
        slot_level
            .registers
            .retain(|r| !r.name.starts_with("lane_"));
        emit_vector_registers(wr, &slot_level);
        emit_text(wr, &text);
    });
    let mut wr = VerilogWriter::new();
    emit_text(&mut wr, &lane);
    out.push('\n');
    out.push_str(&wr.finish());
    Ok(out)
}

/// A field of a lane's state: its name in `rt_unit_lane`, the description's register holding
/// every lane's, its width as a Verilog expression, and the index of its width in
/// the widths [`lane_pieces`] checks (`None`: a fixed width).
const LANE_FIELDS: [(&str, &str, &str, Option<usize>); 27] = [
    ("status", "lane_status", "2", None),
    ("ray_id", "lane_ray_id", "RB", Some(1)),
    ("ray_words", "lane_ray_words", "256", None),
    ("occlusion", "lane_occlusion", "1", None),
    ("hit_valid", "lane_hit_valid", "1", None),
    ("hit", "lane_hit", "128", None),
    ("cur_treelet", "lane_cur_treelet", "TW", Some(2)),
    ("cur_sp", "lane_cur_sp", "SPW", Some(3)),
    ("other_sp", "lane_other_sp", "SPW", Some(3)),
    ("cur_spilled", "lane_cur_spilled", "SCW", Some(4)),
    ("other_spilled", "lane_other_spilled", "SCW", Some(4)),
    ("filling", "lane_filling", "2", None),
    ("node_valid", "lane_node_valid", "1", None),
    ("node", "lane_node", "E", Some(6)),
    ("node_leader", "lane_node_leader", "LB", Some(0)),
    ("chunks_returned", "lane_chunks_returned", "4", None),
    ("delay", "lane_delay", "DW", Some(5)),
    ("store_pending", "lane_store_pending", "1", None),
    ("written", "lane_written", "1", None),
    ("cur_win", "lane_cur_window", "K*E", Some(7)),
    ("cur_top", "lane_cur_top", "E", Some(6)),
    ("cur_base", "lane_cur_base", "SPB", Some(8)),
    ("cur_pend", "lane_cur_pending", "K+1", Some(9)),
    ("other_win", "lane_other_window", "K*E", Some(7)),
    ("other_top", "lane_other_top", "E", Some(6)),
    ("other_base", "lane_other_base", "SPB", Some(8)),
    ("other_pend", "lane_other_pending", "K+1", Some(9)),
];

/// The generated parts of the lane module and of its instances: ports and registers, the values
/// after each stage, the copies between stages, the clocked block, the top's wires of the
/// lanes' registers and the instances' connections.
/// Checks that the description's per-lane registers are exactly the fields of [`LANE_FIELDS`],
/// `lanes` of them each, of the widths `widths` (lane, ray id,
/// treelet, stack pointer, spilled count, delay, entry, stack window, ring position, pending
/// bits).
fn lane_pieces(
    desc: &BlockDesc,
    info: &DescInfo,
    lanes: u32,
    widths: &[u32; 10],
) -> Result<Vec<(&'static str, String)>, GenError> {
    let lane_regs: Vec<&str> = desc
        .registers
        .iter()
        .filter(|r| r.name.starts_with("lane_"))
        .map(|r| r.name.as_str())
        .collect();
    let fields: Vec<&str> = LANE_FIELDS.iter().map(|f| f.1).collect();
    if lane_regs != fields {
        return Err(info.bad(format!(
            "the lane registers are {lane_regs:?}; the RTL's lane module holds {fields:?}"
        )));
    }
    let mut v: Vec<String> = vec![String::new(); 9];
    let [names, decls, stages, copy_a, copy_b, copy_t, copy_d, next, regs] = &mut v[..] else {
        unreachable!()
    };
    let mut connect = String::new();
    let mut reset = String::new();
    for (field, top, width, check) in LANE_FIELDS {
        if let (Some(i), Some(r)) = (check, desc.registers.iter().find(|r| r.name == top)) {
            if r.width != widths[i] || r.count != lanes {
                return Err(info.bad(format!(
                    "register `{top}` is {} x {} bits; the lane module expects {lanes} x {}",
                    r.count, r.width, widths[i]
                )));
            }
        }
        let range = format!("[{width}-1:0]");
        // The lane's registers are its outputs too (the slot level reads them).
        names.push_str(&format!("    {field}_q,\n"));
        decls.push_str(&format!("output reg  {range} {field}_q;\n"));
        next.push_str(&format!("wire [NL*({width})-1:0] {top}_q;\n"));
        connect.push_str(&format!(
            "                .{field}_q({top}_q[L*({width}) +: {width}]),\n"
        ));
        decls.push_str(&format!("reg {range} {field}_d;\n"));
        stages.push_str(&format!("reg {range} {field}_a, {field}_b, {field}_t;\n"));
        copy_a.push_str(&format!("    {field}_a = {field}_q;\n"));
        copy_b.push_str(&format!("    {field}_b = {field}_a;\n"));
        copy_t.push_str(&format!("    {field}_t = {field}_b;\n"));
        copy_d.push_str(&format!("    {field}_d = {field}_t;\n"));
        reset.push_str(&format!("        {field}_q <= {{({width}){{1'b0}}}};\n"));
        regs.push_str(&format!("        {field}_q <= {field}_d;\n"));
    }
    let registers = format!(
        "always @(posedge clk) begin : p_registers\n    if (rst) begin\n{reset}    end else \
         begin\n{regs}    end\nend"
    );
    Ok(vec![
        ("LANE_PORT_NAMES", v[0].clone()),
        ("LANE_PORT_DECLS", v[1].clone()),
        ("LANE_STAGE_DECLS", v[2].clone()),
        ("COPY_A", v[3].clone()),
        ("COPY_B", v[4].clone()),
        ("COPY_T", v[5].clone()),
        ("COPY_D", v[6].clone()),
        ("LANE_STATE", v[7].clone()),
        ("LANE_REGISTERS", registers),
        ("LANE_CONNECT", connect.trim_end().to_string()),
    ])
}

/// The output ports' assignments.
fn output_assigns(desc: &BlockDesc, info: &DescInfo) -> Result<String, GenError> {
    let mut out = String::new();
    let lb = info.port("error_lane", Dir::Out)?;
    let rb = info.port("error_ray_id", Dir::Out)?;
    let sb = info.port("error_slot", Dir::Out)?;
    let kinds = [
        "header",
        "internal",
        "instance_leaf",
        "primitive_descriptor",
        "triangle_leaf",
        "procedural",
    ];
    for p in desc.ports.iter().filter(|p| p.dir == Dir::Out) {
        let name = p.name.as_str();
        let src = match name {
            "issue_ready" => "|free_mask".to_string(),
            "req_size" => "o_req_valid ? 6'd32 : 6'd0".to_string(),
            "errors" => "errors_d".to_string(),
            "error_valid" => "first_error_d[FE_W-1]".to_string(),
            "error_kind" => format!("first_error_d[{} +: 3]", 128 + rb + lb + sb),
            "error_slot" => format!("first_error_d[{} +: {sb}]", 128 + rb + lb),
            "error_lane" => format!("first_error_d[{} +: {lb}]", 128 + rb),
            "error_ray_id" => format!("first_error_d[128 +: {rb}]"),
            "error_value" => "first_error_d[64 +: 64]".to_string(),
            "error_limit" => "first_error_d[0 +: 64]".to_string(),
            "count_tests_treelet_order" | "count_hits" => format!("o_{name}"),
            n if n.starts_with("count_tests_") => {
                let kind = &n["count_tests_".len()..];
                let k = kinds
                    .iter()
                    .position(|x| *x == kind)
                    .ok_or_else(|| info.bad(format!("unknown test counter `{n}`")))?;
                format!("o_tests[{} +: CTW]", k as u32 * p.width)
            }
            n => format!("o_{n}"),
        };
        out.push_str(&format!("assign {name} = {src};\n"));
    }
    Ok(out)
}

/// Verilog of `rt_datapath` for the toy node format of
/// `vtq_gen::stimulus::rt_unit::ToyDatapath` (a stand-in for the box/triangle datapath, used
/// to co-simulate and lint the RT unit's control): byte 0 child count, byte 1 hit flag, bytes
/// 2..4 the top half of the hit's t, 8-byte child records from byte 4 (address, kind, chunks,
/// ray mask), last byte 0xA5.
pub fn toy_datapath_verilog(address_bits: u32) -> String {
    let id = if address_bits >= 32 {
        "node[5 +: 32]".to_string()
    } else {
        format!("{{{}'d0, node[E-1:5]}}", 32 - address_bits)
    };
    TOY_DATAPATH.replace("${HIT_ID}", &id)
}

/// `rt_datapath`'s interface as a Yosys black box (`(* blackbox *)`, no body): the RT unit's
/// control is synthesized without the stand-in datapath, whose area is not the RT unit's.
pub fn datapath_blackbox_verilog() -> String {
    let header_end = TOY_DATAPATH
        .find(");\n")
        .expect("the toy datapath has a port list")
        + 3;
    let start = TOY_DATAPATH
        .find("module rt_datapath")
        .expect("the toy datapath's module");
    format!(
        "// The intersection datapath's interface only: a black box for synthesis.\n\
         (* blackbox *)\n{}endmodule\n",
        &TOY_DATAPATH[start..header_end]
    )
}

/// The toy datapath's module.
const TOY_DATAPATH: &str = r#"// The intersection datapath interface of the RT unit, with the toy node format of the
// co-simulation (vtq_gen::stimulus::rt_unit::ToyDatapath) as its body: a stand-in for the
// box/triangle datapath, whose result the RT unit uses in the cycle the node's last chunk
// arrives and whose latency it counts itself.
/* verilator lint_off UNUSEDPARAM */
module rt_datapath #(
    parameter AB = 32,  // address bits (the toy format does not need them)
    parameter E = 37,   // stack entry bits: {address, kind, chunks - 1}
    parameter R = 8,    // children returned at most
    parameter LANE = 0  // the lane index this instance serves (the toy format does not need it)
) (
    /* verilator lint_off UNUSED */
    input  wire [255:0]    ray,         // origin, direction, tmin, tmax (f32 bits, word 0 lowest)
    input  wire            best_valid,  // the ray's closest hit so far (the toy ignores it)
    input  wire [127:0]    best,
    input  wire [E-1:0]    node,        // {address, kind, chunks - 1}
    input  wire [1023:0]   data,        // the node's bytes, byte b in bits [8b +: 8]
    /* verilator lint_on UNUSED */
    output reg  [7:0]      child_count, // children kept (more than R is the RT unit's error)
    output reg  [R*75-1:0] children,    // child c: {address[63:0], kind, chunks}
    output reg             hit_valid,   // a candidate hit
    output reg  [127:0]    hit          // {attribs[1], attribs[0], hit id, t}
);
    /* verilator lint_on UNUSEDPARAM */
    always @* begin : p_test
        integer i;
        integer j;
        reg [7:0] last;
        reg [7:0] cap;
        reg [7:0] sel;
        /* verilator lint_off UNUSED */
        reg [63:0] rec;  // a child record (its last byte is unused)
        /* verilator lint_on UNUSED */
        reg [31:0] id;
        case (node[1:0])
            2'd0: begin last = data[255:248]; cap = 8'd3; end
            2'd1: begin last = data[511:504]; cap = 8'd7; end
            2'd2: begin last = data[767:760]; cap = 8'd11; end
            default: begin last = data[1023:1016]; cap = 8'd15; end
        endcase
        sel = 8'd1 << ray[2:0];
        child_count = 8'd0;
        children = {R*75{1'b0}};
        hit_valid = 1'b0;
        hit = 128'd0;
        id = ${HIT_ID};
        if (last == 8'ha5) begin
            for (i = 0; i < 15; i = i + 1) begin
                rec = data[(4 + 8*i)*8 +: 64];
                if (i[7:0] < data[7:0] && i[7:0] < cap && (rec[55:48] & sel) != 8'd0
                    && rec[39:32] < 8'd6) begin
                    for (j = 0; j < R; j = j + 1)
                        if (child_count == j[7:0])
                            children[j*75 +: 75] = {32'd0, rec[31:0], rec[34:32], rec[47:40]};
                    child_count = child_count + 8'd1;
                end
            end
            if (data[15:8] != 8'd0) begin
                hit_valid = 1'b1;
                hit = {id ^ 32'h5555_5555, ray[31:0], id, data[31:16], 16'd0};
            end
        end
    end
endmodule
"#;
