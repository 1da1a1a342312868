//! RTL of the hash-chained treelet queue table (`vtq_hdl::queue_table::QueueTable`, paper
//! section 4.2, Figure 9): bucket heads in flip-flops, entry metadata and ray ids in SRAMs with
//! registered read data (latency 1), per-entry valid bits with priority encoders for the first
//! free and first valid entry, and the FSM that walks a chain one metadata word per cycle.

use super::{emit_full_module, emit_registers, emit_text, fill, lit, zext, DescInfo};
use crate::emit::VerilogWriter;
use crate::error::GenError;
use crate::verilog::state_param;
use vtq_hdl::queue_table::QueueTable;
use vtq_hdl::{bits_for, clog2, Block, Dir, HwConfig};

/// FSM states of the queue table, in encoding order (as `QueueState`).
const STATES: [&str; 5] = ["IDLE", "WALK", "ANY_META", "POP_RAYS", "REFILL_WAIT"];

/// Complete Verilog-2005 for the treelet queue table of `cfg` (module `treelet_queue_table`,
/// the default number of buckets), cycle-exact with the Rust block.
pub fn queue_table_verilog(cfg: &HwConfig) -> Result<String, GenError> {
    let block = QueueTable::new(cfg)?;
    let desc = block.describe();
    let info = DescInfo::new(&desc)?;
    let derived = block.widths();

    let tw = info.port("op_treelet", Dir::In)?;
    let rw = info.port("op_ray", Dir::In)?;
    let pc = info.port("pop_count", Dir::Out)?;
    let tot = info.port("count_result", Dir::Out)?;
    let sp = info.port("spilled", Dir::Out)?;
    let en = info.port("free_entries", Dir::Out)?;
    let op_kind = info.port("op_kind", Dir::In)?;
    let iw = info.reg("cur")?;
    let cm = info.reg("prev_count_m1")?;
    let lanes = info.param("warp_size")?;
    let buckets = info.param("buckets")?;
    let bw = clog2(buckets);
    let heads = info.mem("heads", &[("valid", 1), ("idx", iw)], 0)?;
    let meta = info.mem(
        "meta",
        &[
            ("treelet", tw),
            ("count_m1", cm),
            ("next_valid", 1),
            ("next", iw),
        ],
        1,
    )?;
    let ray_names: Vec<String> = (0..lanes).rev().map(|i| format!("ray_{i}")).collect();
    let ray_fields: Vec<(&str, u32)> = ray_names.iter().map(|n| (n.as_str(), rw)).collect();
    let rays = info.mem("rays", &ray_fields, 1)?;
    let e = meta.depth as u64;
    for i in 0..lanes {
        if info.port(&format!("pop_ray_{i}"), Dir::Out)? != rw {
            return Err(info.bad(format!("port pop_ray_{i} is not {rw} bits wide")));
        }
    }
    match desc.registers.iter().find(|r| r.name == "valid") {
        Some(r) if r.width == 1 && r.count as u64 == e => {}
        _ => {
            return Err(info.bad(format!(
                "the RTL needs a bank `valid` of {e} one-bit registers"
            )))
        }
    }
    let state = desc
        .fsms
        .iter()
        .find(|f| f.name == "state" && f.states == STATES && f.width == 3)
        .ok_or_else(|| {
            info.bad(format!(
                "the RTL needs the 3-bit FSM `state` with states {STATES:?}"
            ))
        })?;
    let consistent = derived.treelet == tw
        && derived.ray == rw
        && derived.lanes as u64 == lanes
        && derived.count_m1 == cm
        && derived.pop_count == pc
        && derived.total == tot
        && derived.spilled == sp
        && derived.index == iw
        && derived.entries == en
        && derived.bucket == bw
        && heads.depth as u64 == buckets
        && rays.depth as u64 == e
        && op_kind == 3
        && lanes.is_power_of_two()
        && 1u64 << cm == lanes
        && pc == cm + 1
        && buckets.is_power_of_two()
        && en == bits_for(e)
        && tot > cm
        && info.reg("walk_op")? == 2;
    if !consistent {
        return Err(info.bad(format!(
            "sizes are inconsistent: description {tw}/{rw}/{cm}/{pc}/{tot}/{sp}/{iw}/{en}/{bw} \
             (treelet/ray/count_m1/pop_count/total/spilled/index/entries/bucket bits), block \
             {derived:?}, {e} entries, {buckets} buckets, {lanes} lanes"
        )));
    }
    let mw = tw + cm + 1 + iw;
    let st = |s: &str| state_param(state, s);
    let vars: Vec<(&str, String)> = vec![
        ("E", e.to_string()),
        ("EM1", (e - 1).to_string()),
        ("B", buckets.to_string()),
        ("BM1", (buckets - 1).to_string()),
        ("BWM1", (bw - 1).to_string()),
        ("IW", iw.to_string()),
        ("IWM1", (iw - 1).to_string()),
        ("TWM1", (tw - 1).to_string()),
        ("RW", rw.to_string()),
        ("RWM1", (rw - 1).to_string()),
        ("CMM1", (cm - 1).to_string()),
        ("MWM1", (mw - 1).to_string()),
        ("M_TL", (iw + cm + 1).to_string()),
        ("M_CH", (iw + cm).to_string()),
        ("M_CL", (iw + 1).to_string()),
        ("L", lanes.to_string()),
        ("RAYSWM1", (lanes * rw as u64 - 1).to_string()),
        ("PCM1", (pc - 1).to_string()),
        ("TOTM1", (tot - 1).to_string()),
        ("ENM1", (en - 1).to_string()),
        ("ZERO_IDX", lit(iw, 0)),
        ("ZERO_B", lit(bw, 0)),
        ("ZERO_HW", lit(iw + 1, 0)),
        ("ZERO_BBITS", lit(buckets as u32, 0)),
        ("ZERO_MW", lit(mw, 0)),
        ("ZERO_RAYS", lit(lanes as u32 * rw, 0)),
        ("ZERO_TW", lit(tw, 0)),
        ("ZERO_RW", lit(rw, 0)),
        ("ZERO_CM", lit(cm, 0)),
        ("ONE_CM", lit(cm, 1)),
        ("FULL_CM", lit(cm, lanes - 1)),
        ("ZERO_TOT", lit(tot, 0)),
        ("ZERO_PC", lit(pc, 0)),
        ("ONE_PC", lit(pc, 1)),
        ("ZERO_EN", lit(en, 0)),
        ("ONE_EN", lit(en, 1)),
        ("ZERO_SP", lit(sp, 0)),
        ("M_COUNT_TOT", zext("m_count_m1", cm, tot)),
        ("ONE_TOT", lit(tot, 1)),
        ("SPILL_TAKE", zext("spill_take", 1, sp)),
        ("SPILL_PUT", zext("spill_put", 1, sp)),
        ("HASH", hash_expr("t", tw, bw)),
        ("IDLE", st("IDLE")),
        ("WALK", st("WALK")),
        ("ANY_META", st("ANY_META")),
        ("POP_RAYS", st("POP_RAYS")),
        ("REFILL_WAIT", st("REFILL_WAIT")),
    ];
    let note = format!(
        "Full RTL (not a skeleton), cycle-exact with vtq_hdl::queue_table::QueueTable: every \
         output equals Block::eval in every cycle (co-simulated by gen/tests/table_rtl.rs). The \
         meta and rays SRAMs are not reset (the Rust model resets them to zero, but no word is \
         read into an output before it is written: only valid entries are read, and pop_ray \
         lanes at or beyond pop_count are forced to zero); the bucket heads, valid bits and the \
         SRAM read-data registers are reset like the Rust model. {buckets} buckets, hash = XOR \
         of the {tw}-bit treelet address in {bw}-bit groups from the LSB."
    );
    Ok(emit_full_module(&desc, &note, |wr| {
        emit_text(wr, &fill(CONSTANTS, &vars));
        emit_registers(wr, &desc, &[("free_count", lit(en, e))]);
        emit_text(wr, &fill(BODY, &vars));
        emit_pop_rays(wr, lanes as u32, rw, cm);
    }))
}

/// The bucket hash of `t`: XOR of its `bw`-bit groups from the LSB, the top group zero-extended
/// (as `vtq_hdl::queue_table::bucket_hash`).
fn hash_expr(t: &str, tw: u32, bw: u32) -> String {
    let mut groups = Vec::new();
    let mut lo = 0;
    while lo < tw {
        let hi = (lo + bw).min(tw) - 1;
        let sel = if hi == lo {
            format!("{t}[{lo}]")
        } else {
            format!("{t}[{hi}:{lo}]")
        };
        groups.push(zext(&sel, hi - lo + 1, bw));
        lo += bw;
    }
    groups.join(" ^ ")
}

/// One `assign` per popped-ray port: lane k of the read data while the popped entry's rays are
/// on the outputs and k < pop_count, else zero.
fn emit_pop_rays(w: &mut VerilogWriter, lanes: u32, rw: u32, cm: u32) {
    w.comment("Popped ray ids in insertion order; lanes at or beyond pop_count are zero.");
    for k in 0..lanes {
        let cond = if k == 0 {
            "st_pop_rays".to_string()
        } else {
            format!("st_pop_rays && (pop_count_m1_q >= {})", lit(cm, k as u64))
        };
        w.line(format!(
            "assign pop_ray_{k} = ({cond}) ? rays_rdata[{}:{}] : {};",
            k * rw + rw - 1,
            k * rw,
            lit(rw, 0)
        ));
    }
}

/// State, op and walk encodings, and the hash function.
const CONSTANTS: &str = r#"
// FSM states (QueueState).
localparam [2:0] ${IDLE}        = 3'd0; // waiting for an op (ready)
localparam [2:0] ${WALK}        = 3'd1; // walking a chain, one meta word per cycle
localparam [2:0] ${ANY_META}    = 3'd2; // PopAny: reading the chosen entry's treelet
localparam [2:0] ${POP_RAYS}    = 3'd3; // Pop/PopAny: the popped entry's rays are on the outputs
localparam [2:0] ${REFILL_WAIT} = 3'd4; // Refill: waiting for the spill store's answer
// op_kind encodings.
localparam [2:0] OP_INSERT  = 3'd1;
localparam [2:0] OP_POP     = 3'd2;
localparam [2:0] OP_POP_ANY = 3'd3;
localparam [2:0] OP_COUNT   = 3'd4;
localparam [2:0] OP_REFILL  = 3'd5;
// Which op a chain walk serves (WalkOp).
localparam [1:0] WALK_INSERT  = 2'd0; // find the treelet's first entry to append to
localparam [1:0] WALK_POP     = 2'd1; // find and unlink the treelet's first entry
localparam [1:0] WALK_COUNT   = 2'd2; // sum the treelet's entries
localparam [1:0] WALK_POP_ANY = 2'd3; // find and unlink entry `target`

// Hash bucket of a treelet: XOR of the treelet address in ${B}-bucket-index-wide groups from
// the LSB (chaining resolves collisions).
function [${BWM1}:0] bucket_of(input [${TWM1}:0] t);
    bucket_of = ${HASH};
endfunction"#;

/// Storage, search, the FSM and the scalar outputs (after the register declarations).
const BODY: &str = r#"
// ---------------------------------------------------------------------------------------------
// Storage of the treelet queue table.
// ---------------------------------------------------------------------------------------------
// Chain head per hash bucket {valid, idx}: ${B} words in flip-flops (combinational read). The
// valid fields are heads_valid, reset to empty chains like the Rust model; the idx fields are
// `heads`, not reset (an invalid head's idx only ever reaches the next field of a chain end,
// which no logic follows).
reg [${BM1}:0] heads_valid;
(* mem2reg *) reg [${IWM1}:0] heads [0:${BM1}];
reg          heads_we;
reg [${BWM1}:0]  heads_waddr;
reg [${IW}:0]  heads_wdata;   // {valid, idx}
always @(posedge clk) begin : p_heads
    if (rst) begin
        heads_valid <= ${ZERO_BBITS};
    end else if (heads_we) begin
        heads_valid[heads_waddr] <= heads_wdata[${IW}];
        heads[heads_waddr] <= heads_wdata[${IWM1}:0];
    end
end

// Entry metadata {treelet, count_m1, next_valid, next}: ${E}-word SRAM, 1R 1W, read latency 1
// (the word addressed in one cycle is in meta_rdata the next, and held while the port idles).
reg [${MWM1}:0] meta [0:${EM1}];
reg [${MWM1}:0] meta_rdata;
reg          meta_re;
reg [${IWM1}:0]  meta_raddr;
reg          meta_we;
reg [${IWM1}:0]  meta_waddr;
reg [${MWM1}:0] meta_wdata;
always @(posedge clk) begin : p_meta
    if (!rst && meta_we) meta[meta_waddr] <= meta_wdata;
end
always @(posedge clk) begin : p_meta_read
    if (rst) meta_rdata <= ${ZERO_MW};
    else if (meta_re) meta_rdata <= meta[meta_raddr];
end

// Entry ray ids, ${L} lanes of ${RW} bits (lane k = ray slot k): ${E}-word SRAM, 1R 1W with a
// write enable per lane (an insert writes one lane), read latency 1.
reg [${RAYSWM1}:0] rays [0:${EM1}];
reg [${RAYSWM1}:0] rays_rdata;
reg          rays_re;
reg [${IWM1}:0]  rays_raddr;
reg          rays_we;
reg [${IWM1}:0]  rays_waddr;
reg [${CMM1}:0]  rays_wlane;
reg [${RWM1}:0] rays_wdata;
always @(posedge clk) begin : p_rays
    integer k;
    for (k = 0; k < ${L}; k = k + 1) begin
        if (!rst && rays_we && (rays_wlane == k[${CMM1}:0])) rays[rays_waddr][k*${RW} +: ${RW}] <= rays_wdata;
    end
end
always @(posedge clk) begin : p_rays_read
    if (rst) rays_rdata <= ${ZERO_RAYS};
    else if (rays_re) rays_rdata <= rays[rays_raddr];
end

// ---- Free list: priority encoders over the valid bits (lowest index first) --------------------
reg          any_free;
reg [${IWM1}:0]  first_free;  // allocation takes the lowest free entry
reg          any_valid;
reg [${IWM1}:0]  first_valid; // PopAny takes the lowest valid entry
always @* begin : p_free_list
    integer i;
    any_free = 1'b0;
    first_free = ${ZERO_IDX};
    any_valid = 1'b0;
    first_valid = ${ZERO_IDX};
    for (i = ${EM1}; i >= 0; i = i - 1) begin
        if (!valid_q[i]) begin
            any_free = 1'b1;
            first_free = i[${IWM1}:0];
        end else begin
            any_valid = 1'b1;
            first_valid = i[${IWM1}:0];
        end
    end
end

// ---- The meta word on the read port, and the bucket head lookup --------------------------------
wire [${TWM1}:0] m_treelet = meta_rdata[${MWM1}:${M_TL}];
wire [${CMM1}:0]  m_count_m1 = meta_rdata[${M_CH}:${M_CL}];
wire         m_next_valid = meta_rdata[${IW}];
wire [${IWM1}:0]  m_next = meta_rdata[${IWM1}:0];
wire         m_full = (m_count_m1 == ${FULL_CM});     // the entry holds a full warp of rays
// The treelet whose bucket head is read this cycle: the op's (IDLE), the refilled ray's
// (REFILL_WAIT) or the PopAny entry's (ANY_META).
wire [${TWM1}:0] lookup_treelet = (state_q == ${ANY_META}) ? m_treelet :
                              (state_q == ${REFILL_WAIT}) ? refill_treelet : op_treelet;
wire [${BWM1}:0]  lookup_bucket = bucket_of(lookup_treelet);
wire         head_rd_valid = heads_valid[lookup_bucket];
wire [${IWM1}:0]  head_rd_idx = heads[lookup_bucket];
wire [${BWM1}:0]  key_bucket = bucket_of(key_treelet_q);   // bucket of the current op's treelet
// Walk step: does the entry on the read port match (its treelet, or PopAny's target entry)?
wire         matched = (walk_op_q == WALK_POP_ANY) ? (cur_q == target_q)
                                                   : (m_treelet == key_treelet_q);
wire [${ENM1}:0]  walked_inc = walked_q + ${ONE_EN};
wire [${TOTM1}:0] acc_add = matched ? (acc_q + ${M_COUNT_TOT} + ${ONE_TOT}) : acc_q;
wire         st_pop_rays = (state_q == ${POP_RAYS});

// ---------------------------------------------------------------------------------------------
// The FSM: one op at a time, accepted in IDLE; done pulses with the results.
// ---------------------------------------------------------------------------------------------
reg          done_o;
reg          error_o;
reg [${TOTM1}:0] count_result_o;
reg          spill_valid_o;
reg [${TWM1}:0] spill_treelet_o;
reg [${RWM1}:0] spill_ray_o;
reg          refill_req_o;
reg [${ENM1}:0]  walk_len_o;
always @* begin : p_fsm
    reg          start_insert;     // begin an Insert (op or refill answer): read the bucket head
    reg [${TWM1}:0] ins_treelet;
    reg [${RWM1}:0] ins_ray;
    reg          walk_start;       // begin a chain walk at walk_first (its meta word arrives next)
    reg [1:0]    walk_kind;
    reg [${IWM1}:0]  walk_first;
    reg          advance;          // move the walk to the next entry of the chain
    reg          alloc;            // link a new entry at the chain head, or spill the ray
    reg [${TWM1}:0] alloc_treelet;
    reg [${RWM1}:0] alloc_ray;
    reg          alloc_next_valid; // the chain head the new entry links to
    reg [${IWM1}:0]  alloc_next;
    reg [${BWM1}:0]  alloc_bucket;
    reg          finish;           // the op is done this cycle
    reg          spill_take;       // a refill answer takes a ray back from the spill store
    reg          spill_put;        // a ray spills to memory
    // Hold every register, access no memory, drive no result.
    state_d = state_q;
    walk_op_d = walk_op_q;
    key_treelet_d = key_treelet_q;
    key_ray_d = key_ray_q;
    head_valid_d = head_valid_q;
    head_idx_d = head_idx_q;
    cur_d = cur_q;
    prev_valid_d = prev_valid_q;
    prev_d = prev_q;
    prev_treelet_d = prev_treelet_q;
    prev_count_m1_d = prev_count_m1_q;
    target_d = target_q;
    acc_d = acc_q;
    walked_d = walked_q;
    pop_count_m1_d = pop_count_m1_q;
    pop_treelet_d = pop_treelet_q;
    free_count_d = free_count_q;
    valid_d = valid_q;
    done_o = 1'b0;
    error_o = refill_valid && (state_q != ${REFILL_WAIT}); // unexpected refill answer: ignored
    count_result_o = ${ZERO_TOT};
    spill_valid_o = 1'b0;
    spill_treelet_o = ${ZERO_TW};
    spill_ray_o = ${ZERO_RW};
    refill_req_o = 1'b0;
    walk_len_o = ${ZERO_EN};
    heads_we = 1'b0;
    heads_waddr = ${ZERO_B};
    heads_wdata = ${ZERO_HW};
    meta_re = 1'b0;
    meta_raddr = ${ZERO_IDX};
    meta_we = 1'b0;
    meta_waddr = ${ZERO_IDX};
    meta_wdata = ${ZERO_MW};
    rays_re = 1'b0;
    rays_raddr = ${ZERO_IDX};
    rays_we = 1'b0;
    rays_waddr = ${ZERO_IDX};
    rays_wlane = ${ZERO_CM};
    rays_wdata = ${ZERO_RW};
    start_insert = 1'b0;
    ins_treelet = ${ZERO_TW};
    ins_ray = ${ZERO_RW};
    walk_start = 1'b0;
    walk_kind = WALK_INSERT;
    walk_first = ${ZERO_IDX};
    advance = 1'b0;
    alloc = 1'b0;
    alloc_treelet = ${ZERO_TW};
    alloc_ray = ${ZERO_RW};
    alloc_next_valid = 1'b0;
    alloc_next = ${ZERO_IDX};
    alloc_bucket = ${ZERO_B};
    finish = 1'b0;
    spill_take = 1'b0;
    spill_put = 1'b0;
    case (state_q)
        ${IDLE}: begin
            case (op_kind)
                OP_INSERT: begin
                    start_insert = 1'b1;
                    ins_treelet = op_treelet;
                    ins_ray = op_ray;
                end
                OP_POP, OP_COUNT: begin
                    key_treelet_d = op_treelet;
                    if (head_rd_valid) begin
                        walk_start = 1'b1;
                        walk_kind = (op_kind == OP_POP) ? WALK_POP : WALK_COUNT;
                        walk_first = head_rd_idx;
                    end else begin
                        finish = 1'b1; // empty bucket: nothing found, count 0
                    end
                end
                OP_POP_ANY: begin
                    if (any_valid) begin
                        // Read the lowest valid entry's treelet, then walk its chain to unlink it.
                        meta_re = 1'b1;
                        meta_raddr = first_valid;
                        target_d = first_valid;
                        state_d = ${ANY_META};
                    end else begin
                        finish = 1'b1;
                    end
                end
                OP_REFILL: begin
                    if (spilled_q == ${ZERO_SP}) begin
                        finish = 1'b1;
                    end else begin
                        refill_req_o = 1'b1;
                        state_d = ${REFILL_WAIT};
                    end
                end
                default: begin
                end
            endcase
        end
        ${WALK}: begin
            walked_d = walked_inc;
            walk_len_o = walked_inc;
            case (walk_op_q)
                WALK_INSERT: begin
                    if (matched && !m_full) begin
                        // Append the ray to the treelet's first entry (its only non-full one).
                        rays_we = 1'b1;
                        rays_waddr = cur_q;
                        rays_wlane = m_count_m1 + ${ONE_CM};
                        rays_wdata = key_ray_q;
                        meta_we = 1'b1;
                        meta_waddr = cur_q;
                        meta_wdata = {m_treelet, m_count_m1 + ${ONE_CM}, m_next_valid, m_next};
                        finish = 1'b1;
                    end else if (matched || !m_next_valid) begin
                        // The treelet's entries are full, or it has none: a new entry.
                        alloc = 1'b1;
                        alloc_treelet = key_treelet_q;
                        alloc_ray = key_ray_q;
                        alloc_next_valid = head_valid_q;
                        alloc_next = head_idx_q;
                        alloc_bucket = key_bucket;
                    end else begin
                        advance = 1'b1;
                    end
                end
                WALK_COUNT: begin
                    if (m_next_valid) begin
                        acc_d = acc_add;
                        advance = 1'b1;
                    end else begin
                        count_result_o = acc_add;
                        finish = 1'b1;
                    end
                end
                default: begin // WALK_POP, WALK_POP_ANY
                    if (matched) begin
                        // Unlink cur: the previous entry (or the bucket head) skips it.
                        if (prev_valid_q) begin
                            meta_we = 1'b1;
                            meta_waddr = prev_q;
                            meta_wdata = {prev_treelet_q, prev_count_m1_q, m_next_valid, m_next};
                        end else begin
                            heads_we = 1'b1;
                            heads_waddr = key_bucket;
                            heads_wdata = {m_next_valid, m_next};
                        end
                        valid_d[cur_q] = 1'b0;
                        free_count_d = free_count_q + ${ONE_EN};
                        rays_re = 1'b1;
                        rays_raddr = cur_q;
                        pop_count_m1_d = m_count_m1;
                        pop_treelet_d = m_treelet;
                        state_d = ${POP_RAYS};
                    end else if (m_next_valid) begin
                        advance = 1'b1;
                    end else begin
                        // End of the chain: Pop found nothing; PopAny's entry was missing.
                        error_o = (walk_op_q == WALK_POP_ANY);
                        finish = 1'b1;
                    end
                end
            endcase
        end
        ${ANY_META}: begin
            key_treelet_d = m_treelet;
            if (head_rd_valid) begin
                walk_start = 1'b1;
                walk_kind = WALK_POP_ANY;
                walk_first = head_rd_idx;
            end else begin
                error_o = 1'b1; // inconsistent table: the entry's bucket is empty
                finish = 1'b1;
            end
        end
        ${POP_RAYS}: begin
            finish = 1'b1; // pop_count, pop_treelet and pop_ray_* are driven below
        end
        ${REFILL_WAIT}: begin
            if (refill_valid) begin
                // The spill store's answer: insert the ray again (it may spill again).
                spill_take = 1'b1;
                start_insert = 1'b1;
                ins_treelet = refill_treelet;
                ins_ray = refill_ray;
            end
        end
        default: begin
        end
    endcase
    if (start_insert) begin
        key_treelet_d = ins_treelet;
        key_ray_d = ins_ray;
        head_valid_d = head_rd_valid;
        head_idx_d = head_rd_idx;
        if (head_rd_valid) begin
            walk_start = 1'b1;
            walk_kind = WALK_INSERT;
            walk_first = head_rd_idx;
        end else begin
            alloc = 1'b1; // empty bucket: allocate at once
            alloc_treelet = ins_treelet;
            alloc_ray = ins_ray;
            alloc_next_valid = head_rd_valid;
            alloc_next = head_rd_idx;
            alloc_bucket = lookup_bucket;
        end
    end
    if (advance) begin
        meta_re = 1'b1;
        meta_raddr = m_next;
        prev_valid_d = 1'b1;
        prev_d = cur_q;
        prev_treelet_d = m_treelet;
        prev_count_m1_d = m_count_m1;
        cur_d = m_next;
    end
    if (walk_start) begin
        meta_re = 1'b1;
        meta_raddr = walk_first;
        state_d = ${WALK};
        walk_op_d = walk_kind;
        cur_d = walk_first;
        prev_valid_d = 1'b0;
        walked_d = ${ZERO_EN};
        acc_d = ${ZERO_TOT};
    end
    if (alloc) begin
        if (any_free) begin
            // Link the lowest free entry at the head of the bucket's chain.
            meta_we = 1'b1;
            meta_waddr = first_free;
            meta_wdata = {alloc_treelet, ${ZERO_CM}, alloc_next_valid, alloc_next};
            rays_we = 1'b1;
            rays_waddr = first_free;
            rays_wlane = ${ZERO_CM};
            rays_wdata = alloc_ray;
            heads_we = 1'b1;
            heads_waddr = alloc_bucket;
            heads_wdata = {1'b1, first_free};
            valid_d[first_free] = 1'b1;
            free_count_d = free_count_q - ${ONE_EN};
        end else begin
            // No free entry: the ray spills to memory.
            spill_valid_o = 1'b1;
            spill_treelet_o = alloc_treelet;
            spill_ray_o = alloc_ray;
            spill_put = 1'b1;
        end
        finish = 1'b1;
    end
    if (finish) begin
        done_o = 1'b1;
        state_d = ${IDLE};
    end
    spilled_d = spilled_q - ${SPILL_TAKE} + ${SPILL_PUT};
end

// ---- Outputs ----------------------------------------------------------------------------------
assign ready = (state_q == ${IDLE});
assign done = done_o;
assign error = error_o;
assign pop_count = st_pop_rays ? ({1'b0, pop_count_m1_q} + ${ONE_PC}) : ${ZERO_PC};
assign pop_treelet = st_pop_rays ? pop_treelet_q : ${ZERO_TW};
assign count_result = count_result_o;
assign spill_valid = spill_valid_o;
assign spill_treelet = spill_treelet_o;
assign spill_ray = spill_ray_o;
assign refill_req = refill_req_o;
assign refill_waiting = (state_q == ${REFILL_WAIT});
assign free_entries = free_count_q;
assign spilled = spilled_q;
assign walk_len = walk_len_o;"#;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hash_groups_from_the_lsb() {
        assert_eq!(hash_expr("t", 19, 7), "t[6:0] ^ t[13:7] ^ {2'd0, t[18:14]}");
        assert_eq!(hash_expr("t", 5, 2), "t[1:0] ^ t[3:2] ^ {1'd0, t[4]}");
    }
}
