//! RTL of the treelet count table (`vtq_hdl::count_table::CountTable`, paper sections 4.2, 4.4
//! and 6.5): the entry array in flip-flops with a CAM match of the op's treelet and a priority
//! encoder for the first free entry, the registered max/min pointers with their incremental
//! update rules, and the scan engine that recomputes them `scan_width` entries per cycle.

use super::{emit_full_module, emit_registers, emit_text, fill, lit, zext, DescInfo};
use crate::error::GenError;
use crate::verilog::state_param;
use vtq_hdl::count_table::{CountTable, CountTableWidths};
use vtq_hdl::{bits_for, Block, Dir, HwConfig};

/// Complete Verilog-2005 for the treelet count table of `cfg` (module `treelet_count_table`,
/// default scan width), cycle-exact with the Rust block.
pub fn count_table_verilog(cfg: &HwConfig) -> Result<String, GenError> {
    let block = CountTable::new(cfg)?;
    let desc = block.describe();
    let info = DescInfo::new(&desc)?;
    let derived = block.widths();

    // Sizes, all read from the description (and checked against each other).
    let tw = info.port("op_treelet", Dir::In)?;
    let nw = info.port("op_n", Dir::In)?;
    let cnt = info.port("max_count", Dir::Out)?;
    let ew = info.port("occupancy", Dir::Out)?;
    let iw = info.reg("scan_pos")?;
    let cw = info.reg("max_count_m1")?;
    let mem = info.mem(
        "entries",
        &[("valid", 1), ("treelet", tw), ("count_m1", cw)],
        0,
    )?;
    let n = mem.depth as u64;
    let s = info.param("scan_width")?;
    let warp = info.param("warp_size")?;
    let max_rays = info.param("max_rays")?;
    let thr = info.param("underpopulation_threshold")?;
    let op_kind = info.port("op_kind", Dir::In)?;
    let state = desc
        .fsms
        .iter()
        .find(|f| f.name == "state" && f.states == ["IDLE", "SCAN"])
        .ok_or_else(|| info.bad("the RTL needs the FSM `state` with states IDLE, SCAN".into()))?;
    let expected = CountTableWidths {
        treelet: tw,
        n: nw,
        count: cnt,
        count_m1: cw,
        index: iw,
        entries: ew,
    };
    if expected != derived
        || cnt != cw + 1
        || op_kind != 2
        || ew != bits_for(n)
        || s == 0
        || s > n
        || warp > max_rays
        || 1u64 << cw != max_rays
    {
        return Err(info.bad(format!(
            "sizes are inconsistent: {expected:?} from the description, {derived:?} from the \
             block, {n} entries, scan width {s}, warp {warp}, max_rays {max_rays}"
        )));
    }
    let w = 1 + tw + cw;
    let groups = n.div_ceil(s);
    // The underpopulation threshold test `count - 1 + 1 >= threshold` on a stored count.
    let above = |x: &str| {
        if thr <= 1 {
            "1'b1".to_string()
        } else {
            format!("({x} >= {})", lit(cw, thr - 1))
        }
    };
    // The reset values of both pointers' registers with `prefix` (`max`, `run_min`, ...).
    let zeros = ["1'b0".to_string(), lit(iw, 0), lit(tw, 0), lit(cw, 0)];
    let reset = |prefix: &str, indent: usize| {
        both(|p| ptr_assign(&reg_ptr(&format!("{prefix}{p}"), "d"), &zeros, indent))
    };
    let mut vars: Vec<(&str, String)> = vec![
        ("N", n.to_string()),
        ("N_EW", lit(ew, n)),
        ("NM1", (n - 1).to_string()),
        ("W", w.to_string()),
        ("WM1", (w - 1).to_string()),
        ("VB", (w - 1).to_string()),
        ("DM1", (w - 2).to_string()),
        ("ZERO_N_BITS", lit(n as u32, 0)),
        ("TH", (w - 2).to_string()),
        ("TL", cw.to_string()),
        ("TWM1", (tw - 1).to_string()),
        ("CWM1", (cw - 1).to_string()),
        ("CNTM1", (cnt - 1).to_string()),
        ("IW", iw.to_string()),
        ("IWM1", (iw - 1).to_string()),
        ("S", s.to_string()),
        ("G", groups.to_string()),
        ("THR", thr.to_string()),
        ("ZERO_W", lit(w, 0)),
        ("ZERO_IDX", lit(iw, 0)),
        ("ZERO_IDX1", lit(iw + 1, 0)),
        ("ZERO_TW", lit(tw, 0)),
        ("ZERO_CW", lit(cw, 0)),
        ("ZERO_CNT", lit(cnt, 0)),
        ("ZERO_EW", lit(ew, 0)),
        ("ONE_CNT", lit(cnt, 1)),
        ("ZERO_N", lit(nw, 0)),
        ("L_WARP", lit(nw, warp)),
        ("L_MAXR", lit(cnt, max_rays)),
        ("L_S1", lit(iw + 1, s)),
        ("L_N1", lit(iw + 1, n)),
        ("OP_N_X", zext("op_n", nw, cnt)),
        ("OCC_INC", zext("occ_inc", 1, ew)),
        ("OCC_DEC", zext("occ_dec", 1, ew)),
        ("NEW_ABOVE", zext("new_above", 1, ew)),
        ("OLD_ABOVE", zext("old_above", 1, ew)),
        ("ABOVE_HIT", above("hit_cm1")),
        ("ABOVE_ADD", above("add_sum[${CWM1}:0]")),
        ("ABOVE_NEW", above("n_m1[${CWM1}:0]")),
        ("ABOVE_MIN", above("min_count_m1_q")),
        ("ABOVE_REM", above("rem_cm1")),
        ("RUN_RESET_12", reset("run_", 12)),
        ("RUN_RESET_8", reset("run_", 8)),
        ("PTR_RESET_8", reset("", 8)),
        ("IDLE", state_param(state, "IDLE")),
        ("SCAN", state_param(state, "SCAN")),
    ];
    vars.extend(pointer_pieces());
    // Two passes: the ABOVE_* values and the pointer pieces contain placeholders themselves.
    let body = fill(&fill(BODY, &vars), &vars);
    let note = format!(
        "Full RTL (not a skeleton), cycle-exact with vtq_hdl::count_table::CountTable: every \
         output equals Block::eval in every cycle (co-simulated by gen/tests/table_rtl.rs). \
         Scan read port k only ever reads entries k, k + {s}, k + {}, ... because the scan \
         position starts at 0 and advances by the scan width ({s}), so each port is a \
         {groups}-input multiplexer.",
        2 * s
    );
    Ok(emit_full_module(&desc, &note, |wr| {
        emit_text(wr, &fill(CONSTANTS, &vars));
        emit_registers(wr, &desc, &[]);
        emit_text(wr, &body);
    }))
}

/// The max/min pointer logic of [`BODY`], written once for both pointers: the published,
/// window and result variables' declarations and updates, and the next registers (its values
/// contain placeholders of [`count_table_verilog`]'s own).
fn pointer_pieces() -> Vec<(&'static str, String)> {
    let var = |v: &str, p: &str| var_ptr(&format!("{v}{p}"));
    let reg = |r: &str, p: &str, s: &str| reg_ptr(&format!("{r}{p}"), s);
    // A valid entry of the scan window: `word` at index `idx`.
    let word = ["1'b1", "idx", "word[${TH}:${TL}]", "word[${CWM1}:0]"].map(String::from);
    let published = |p: &str| {
        let (src, dst) = (reg("", p, "q"), var("p", p));
        [
            ptr_assign(&dst, &src, 4),
            format!("    if ({} || !scanning) begin", src[0]),
            fold_change(p, &src, &dst, &dst[0]),
            "    end".to_string(),
        ]
        .join("\n")
    };
    let step = |p: &str| {
        let w = var("w", p);
        [
            format!(
                "            if ({}) begin",
                beats(p, &w, &word[1], &word[3])
            ),
            ptr_assign(&w, &word, 16),
            "            end".to_string(),
        ]
        .join("\n")
    };
    let hold = |p: &str| ptr_assign(&reg("", p, "d"), &var("p", p), 4);
    let run_hold = |p: &str| ptr_assign(&reg("run_", p, "d"), &reg("run_", p, "q"), 4);
    vec![
        ("PUBLISHED_DECLS", both(|p| ptr_decls(&format!("p{p}"), 0))),
        ("PUBLISHED", both(published)),
        ("WINDOW_DECLS", both(|p| ptr_decls(&format!("w{p}"), 0))),
        (
            "WINDOW_START",
            both(|p| ptr_assign(&var("w", p), &reg("run_", p, "q"), 4)),
        ),
        ("WINDOW_STEP", both(step)),
        ("RESULT_DECLS", both(|p| ptr_decls(&format!("r{p}"), 4))),
        (
            "RESULT_START",
            both(|p| ptr_assign(&var("r", p), &var("w", p), 4)),
        ),
        (
            "RESULT_FOLD",
            both(|p| fold_change(p, &var("w", p), &var("r", p), "intact")),
        ),
        ("NEXT_HOLD", format!("{}\n{}", both(hold), both(run_hold))),
        (
            "NEXT_WINDOW",
            both(|p| ptr_assign(&reg("run_", p, "d"), &var("r", p), 12)),
        ),
        (
            "PUBLISH",
            both(|p| ptr_assign(&reg("", p, "d"), &var("r", p), 16)),
        ),
    ]
}

/// A max/min pointer's four fields as the body names them: valid, index, treelet, count - 1.
type Ptr = [String; 4];

/// The pointer registers `name` (`max`, `run_min`, ...) with suffix `suffix` (`q` or `d`).
fn reg_ptr(name: &str, suffix: &str) -> Ptr {
    ["valid", "idx", "treelet", "count_m1"].map(|f| format!("{name}_{f}_{suffix}"))
}

/// The pointer variables `name` (`pmax`, `wmin`, ...).
fn var_ptr(name: &str) -> Ptr {
    ["valid", "idx", "treelet", "cm1"].map(|f| format!("{name}_{f}"))
}

/// `piece` of the maximum, then of the minimum pointer (`piece` gets `max` or `min`), on
/// lines of their own.
fn both(piece: impl Fn(&str) -> String) -> String {
    ["max", "min"].map(piece).join("\n")
}

/// The declarations of the pointer variables `name`, at `indent` spaces.
fn ptr_decls(name: &str, indent: usize) -> String {
    let v = var_ptr(name);
    let ranges = ["", "[${IWM1}:0] ", "[${TWM1}:0] ", "[${CWM1}:0] "];
    (0..4)
        .map(|i| format!("{:indent$}reg {}{};", "", ranges[i], v[i]))
        .collect::<Vec<_>>()
        .join("\n")
}

/// `dst = src;` for each field of a pointer (`src` may be any four expressions), one line each
/// at `indent` spaces.
fn ptr_assign(dst: &Ptr, src: &Ptr, indent: usize) -> String {
    dst.iter()
        .zip(src)
        .map(|(d, s)| format!("{:indent$}{d} = {s};", ""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The call of `beats_max` or `beats_min` (`p`): does entry `idx` with count - 1 `cm1` beat
/// pointer `ptr`.
fn beats(p: &str, ptr: &Ptr, idx: &str, cm1: &str) -> String {
    format!(
        "beats_{p}({}, {}, {}, {idx}, {cm1})",
        ptr[0], ptr[1], ptr[3]
    )
}

/// The published pointers' rule for this cycle's change on pointer `p` (`max` or `min`),
/// read from `src` and written to `dst`: the changed entry takes the pointer if it may move
/// it and beats it (or is its entry), else a change that stales the pointer's entry clears
/// `stale` (at 8 spaces, inside the `always` block's condition).
fn fold_change(p: &str, src: &Ptr, dst: &Ptr, stale: &str) -> String {
    let chg = if p == "max" { "chg_up" } else { "chg_down" };
    let change = ["1'b1", "chg_idx", "op_treelet", "chg_cm1"].map(String::from);
    let cond = format!("if ({chg} && (");
    let (valid, idx) = (&src[0], &src[1]);
    [
        format!("        {cond}{}", beats(p, src, "chg_idx", "chg_cm1")),
        format!("        {:1$}|| (chg_idx == {idx}))) begin", "", cond.len()),
        ptr_assign(dst, &change, 12),
        format!("        end else if (chg_{p}_stale && {valid} && (chg_idx == {idx})) begin"),
        format!("            {stale} = 1'b0;"),
        "        end".to_string(),
    ]
    .join("\n")
}

/// State and change encodings.
const CONSTANTS: &str = r#"
// FSM states: IDLE = both pointers current (or the table is empty), SCAN = the scan engine
// is recomputing them.
localparam ${IDLE} = 1'd0;
localparam ${SCAN} = 1'd1;
// How the op changed one entry this cycle; selects the pointer update rule.
localparam [2:0] CHG_NONE   = 3'd0; // no entry written
localparam [2:0] CHG_GROW   = 3'd1; // entry grew, or the smallest entry was replaced by a larger new treelet
localparam [2:0] CHG_SHRINK = 3'd2; // entry shrank and stays valid
localparam [2:0] CHG_FREE   = 3'd3; // entry freed (its count reached 0)
localparam [2:0] CHG_ALLOC  = 3'd4; // a free entry was allocated for a new treelet"#;

/// The datapath and control (after the register declarations).
const BODY: &str = r#"
// ---------------------------------------------------------------------------------------------
// The treelet count table entries: ${N} words {valid, treelet, count_m1} in flip-flops. A count
// c in 1..=max_rays is stored as c - 1. One write port (the op's entry), combinational reads
// (the op's entry and ${S} scan ports), two search ports (the CAM match of op_treelet and the
// first free entry). The valid fields are entries_valid, reset to 0 like the Rust model's
// reset() and cleared together by a Clear op; the {treelet, count_m1} fields are `entries`, not
// reset: no logic reads them while the entry is invalid, so the outputs are those of an
// all-zero reset.
// ---------------------------------------------------------------------------------------------
reg [${NM1}:0] entries_valid;                // valid field of every entry
(* mem2reg *) reg [${DM1}:0] entries [0:${NM1}]; // {treelet, count_m1} fields
reg          ent_we;    // write the op's entry at the clock edge
reg [${IWM1}:0]  ent_waddr; // ... this entry
reg [${WM1}:0] ent_wdata; // ... with this word {valid, treelet, count_m1}
wire         op_clear = (op_kind == 2'd3); // Clear: every valid bit, the scan and both pointers reset

always @(posedge clk) begin : p_entries
    if (rst || op_clear) begin
        entries_valid <= ${ZERO_N_BITS};
    end else if (ent_we) begin
        entries_valid[ent_waddr] <= ent_wdata[${VB}];
        entries[ent_waddr] <= ent_wdata[${DM1}:0];
    end
end

// (count - 1, index) orders before a valid pointer as the maximum: larger count, then the
// lower index; an invalid pointer is beaten by any entry.
function beats_max(input p_valid, input [${IWM1}:0] p_idx, input [${CWM1}:0] p_cm1,
                   input [${IWM1}:0] idx, input [${CWM1}:0] cm1);
    beats_max = !p_valid || (cm1 > p_cm1) || ((cm1 == p_cm1) && (idx < p_idx));
endfunction

// ... as the minimum: smaller count, then the lower index.
function beats_min(input p_valid, input [${IWM1}:0] p_idx, input [${CWM1}:0] p_cm1,
                   input [${IWM1}:0] idx, input [${CWM1}:0] cm1);
    beats_min = !p_valid || (cm1 < p_cm1) || ((cm1 == p_cm1) && (idx < p_idx));
endfunction

// ---- Parallel search: CAM match of op_treelet, and the free list -------------------------------
wire [${NM1}:0] ent_valid; // valid bit of every entry; its complement is the free list
wire [${NM1}:0] ent_match; // CAM match line: the entry is valid and holds op_treelet
genvar gi;
generate
    for (gi = 0; gi < ${N}; gi = gi + 1) begin : g_cam
        assign ent_valid[gi] = entries_valid[gi];
        assign ent_match[gi] = entries_valid[gi] && (entries[gi][${TH}:${TL}] == op_treelet);
    end
endgenerate

// Priority encoders, lowest index first: the op's entry and the first free entry.
reg          hit_found;
reg [${IWM1}:0]  hit_idx;
reg          free_found;
reg [${IWM1}:0]  free_idx;
always @* begin : p_search
    integer i;
    hit_found = 1'b0;
    hit_idx = ${ZERO_IDX};
    free_found = 1'b0;
    free_idx = ${ZERO_IDX};
    for (i = ${NM1}; i >= 0; i = i - 1) begin
        if (ent_match[i]) begin
            hit_found = 1'b1;
            hit_idx = i[${IWM1}:0];
        end
        if (!ent_valid[i]) begin
            free_found = 1'b1;
            free_idx = i[${IWM1}:0];
        end
    end
end

// ---- The op: Add or Remove n rays of op_treelet, or Clear, one per cycle, decided this cycle -----
wire         op_add = (op_kind == 2'd1);
wire         op_remove = (op_kind == 2'd2);
wire         n_bad = (op_n == ${ZERO_N}) || (op_n > ${L_WARP}); // n outside 1..=warp_size
wire [${CNTM1}:0] op_n_x = ${OP_N_X};                   // n at count width
wire [${CNTM1}:0] n_m1 = op_n_x - ${ONE_CNT};               // n - 1: a new entry's stored count
wire [${CWM1}:0] hit_cm1 = entries[hit_idx][${CWM1}:0];    // the op's entry: count - 1
wire [${CNTM1}:0] hit_count = {1'b0, hit_cm1} + ${ONE_CNT};  // ... its true count
wire [${CNTM1}:0] add_sum = {1'b0, hit_cm1} + op_n_x;     // count - 1 after adding n
wire         add_over = (add_sum >= ${L_MAXR});         // the Add would exceed max_rays
wire [${CWM1}:0] rem_cm1 = hit_cm1 - op_n_x[${CWM1}:0];    // count - 1 after removing n < count

reg          ready_o;         // low: an Add of a new treelet into a full table waits for the minimum
reg          error_o;         // invalid op, ignored
reg          evict_valid_o;   // an entry (or the new treelet itself) is evicted: ray-stationary later
reg [${TWM1}:0] evict_treelet_o;
reg [${CNTM1}:0] evict_count_o;
reg [2:0]    chg_kind;        // how the op changed an entry (CHG_*)
reg [${IWM1}:0]  chg_idx;         // ... which entry (its treelet is op_treelet)
reg [${CWM1}:0] chg_cm1;         // ... and its new count - 1
reg          occ_inc;         // an entry was allocated
reg          occ_dec;         // an entry was freed
reg          old_above;       // the changed entry was at or above the underpopulation threshold
reg          new_above;       // ... and is now

always @* begin : p_op
    ready_o = 1'b1;
    error_o = 1'b0;
    evict_valid_o = 1'b0;
    evict_treelet_o = ${ZERO_TW};
    evict_count_o = ${ZERO_CNT};
    ent_we = 1'b0;
    ent_waddr = ${ZERO_IDX};
    ent_wdata = ${ZERO_W};
    chg_kind = CHG_NONE;
    chg_idx = ${ZERO_IDX};
    chg_cm1 = ${ZERO_CW};
    occ_inc = 1'b0;
    occ_dec = 1'b0;
    old_above = 1'b0;
    new_above = 1'b0;
    if (op_add) begin
        if (n_bad) begin
            error_o = 1'b1;
        end else if (hit_found) begin
            // Hit: add to the entry, unless that exceeds max_rays.
            if (add_over) begin
                error_o = 1'b1;
            end else begin
                ent_we = 1'b1;
                ent_waddr = hit_idx;
                ent_wdata = {1'b1, op_treelet, add_sum[${CWM1}:0]};
                old_above = ${ABOVE_HIT};
                new_above = ${ABOVE_ADD};
                chg_kind = CHG_GROW;
                chg_idx = hit_idx;
                chg_cm1 = add_sum[${CWM1}:0];
            end
        end else if (free_found) begin
            // Miss: take the first free entry.
            ent_we = 1'b1;
            ent_waddr = free_idx;
            ent_wdata = {1'b1, op_treelet, n_m1[${CWM1}:0]};
            occ_inc = 1'b1;
            new_above = ${ABOVE_NEW};
            chg_kind = CHG_ALLOC;
            chg_idx = free_idx;
            chg_cm1 = n_m1[${CWM1}:0];
        end else if (!min_valid_q) begin
            // Full table and the minimum is stale: hold the op until the scan publishes it.
            ready_o = 1'b0;
        end else if (n_m1 <= {1'b0, min_count_m1_q}) begin
            // Full table, not larger than the smallest entry: the new treelet itself is evicted.
            evict_valid_o = 1'b1;
            evict_treelet_o = op_treelet;
            evict_count_o = op_n_x;
        end else begin
            // Full table: evict the smallest entry and put the new treelet in its place.
            evict_valid_o = 1'b1;
            evict_treelet_o = min_treelet_q;
            evict_count_o = {1'b0, min_count_m1_q} + ${ONE_CNT};
            ent_we = 1'b1;
            ent_waddr = min_idx_q;
            ent_wdata = {1'b1, op_treelet, n_m1[${CWM1}:0]};
            old_above = ${ABOVE_MIN};
            new_above = ${ABOVE_NEW};
            chg_kind = CHG_GROW;
            chg_idx = min_idx_q;
            chg_cm1 = n_m1[${CWM1}:0];
        end
    end else if (op_remove) begin
        if (!hit_found || n_bad || (op_n_x > hit_count)) begin
            // Unknown treelet, n out of range, or more rays than the entry holds.
            error_o = 1'b1;
        end else if (op_n_x == hit_count) begin
            // The count reaches 0: free the entry.
            ent_we = 1'b1;
            ent_waddr = hit_idx;
            ent_wdata = ${ZERO_W};
            occ_dec = 1'b1;
            old_above = ${ABOVE_HIT};
            chg_kind = CHG_FREE;
            chg_idx = hit_idx;
        end else begin
            ent_we = 1'b1;
            ent_waddr = hit_idx;
            ent_wdata = {1'b1, op_treelet, rem_cm1};
            old_above = ${ABOVE_HIT};
            new_above = ${ABOVE_REM};
            chg_kind = CHG_SHRINK;
            chg_idx = hit_idx;
            chg_cm1 = rem_cm1;
        end
    end
end

// ---- Published max/min pointers: incremental update rules ---------------------------------
wire scanning      = (state_q == ${SCAN});
wire chg_up        = (chg_kind == CHG_GROW) || (chg_kind == CHG_ALLOC);   // may raise the maximum
wire chg_down      = (chg_kind == CHG_SHRINK) || (chg_kind == CHG_ALLOC); // may lower the minimum
wire chg_max_stale = (chg_kind == CHG_SHRINK) || (chg_kind == CHG_FREE);  // stales a max naming the entry
wire chg_min_stale = (chg_kind == CHG_GROW) || (chg_kind == CHG_FREE);    // stales a min naming the entry

// The published pointers after this cycle's change (a stale pointer is left alone while a scan
// runs; with no scan and no pointer the table was empty and only an allocation applies).
${PUBLISHED_DECLS}
always @* begin : p_published
${PUBLISHED}
end

// ---- Scan engine: ${S} entries per cycle, entries scan_pos .. scan_pos + ${S} - 1 ------------------
// Read port k returns entry scan_pos + k (zero, i.e. invalid, past the last entry). scan_pos is
// always a multiple of ${S}, so port k selects among the ${G} entries k, k + ${S}, k + 2 x ${S}, ...
reg [${S}*${W}-1:0] scan_words;
always @* begin : p_scan_read
    integer g;
    integer k;
    scan_words = {${S}{${ZERO_W}}};
    for (g = 0; g < ${G}; g = g + 1) begin
        if ({1'b0, scan_pos_q} == g[${IW}:0] * ${L_S1}) begin
            for (k = 0; (k < ${S}) && (g * ${S} + k < ${N}); k = k + 1) begin
                scan_words[k*${W} +: ${W}] = {entries_valid[g*${S} + k], entries[g*${S} + k]};
            end
        end
    end
end

// The scan's running max/min after this cycle's window, in index order.
${WINDOW_DECLS}
always @* begin : p_scan
    integer k;
    reg [${WM1}:0] word;
    reg [${IWM1}:0] idx;
${WINDOW_START}
    for (k = 0; k < ${S}; k = k + 1) begin
        word = scan_words[k*${W} +: ${W}];
        idx = scan_pos_q + k[${IWM1}:0];
        if (word[${VB}]) begin
${WINDOW_STEP}
        end
    end
end

wire [${IW}:0] scan_next = {1'b0, scan_pos_q} + ${L_S1};        // one past this cycle's window
wire       scan_last = (scan_next >= ${L_N1});                // the window reaches the last entry
wire [${IW}:0] scan_end  = scan_last ? ${L_N1} : scan_next;      // end of the window (exclusive)
wire       chg_seen  = (chg_kind != CHG_NONE) && ({1'b0, chg_idx} < scan_end); // change behind the scan

// ---- Next state -------------------------------------------------------------------------------
always @* begin : p_next
${RESULT_DECLS}
    reg          intact;
    occupancy_d = occupancy_q + ${OCC_INC} - ${OCC_DEC};
    above_d = above_q + ${NEW_ABOVE} - ${OLD_ABOVE};
    // A change on an entry the scan has already passed is folded into its running result by
    // the published pointers' rules; when it stales the running result the scan restarts.
${RESULT_START}
    intact = 1'b1;
    if (chg_seen) begin
${RESULT_FOLD}
    end
    state_d = state_q;
    scan_pos_d = scan_pos_q;
${NEXT_HOLD}
    if (scanning) begin
        if (intact && !scan_last) begin
            // Next window.
            scan_pos_d = scan_next[${IWM1}:0];
${NEXT_WINDOW}
        end else begin
            // Restart from entry 0, or the last window: publish both pointers.
            if (intact) begin
                state_d = ${IDLE};
${PUBLISH}
            end
            scan_pos_d = ${ZERO_IDX};
${RUN_RESET_12}
        end
    end else if ((!pmax_valid || !pmin_valid) && (occupancy_d != ${ZERO_EW})) begin
        // A pointer went stale: start a scan from entry 0.
        state_d = ${SCAN};
        scan_pos_d = ${ZERO_IDX};
    end
    if (op_clear) begin
        // Clear: the registers' reset values.
        occupancy_d = ${ZERO_EW};
        above_d = ${ZERO_EW};
        state_d = ${IDLE};
        scan_pos_d = ${ZERO_IDX};
${PTR_RESET_8}
${RUN_RESET_8}
    end
end

// ---- Outputs ----------------------------------------------------------------------------------
assign ready = ready_o;
assign accepts = (occupancy_q != ${N_EW}) || min_valid_q;
assign error = error_o;
assign evict_valid = evict_valid_o;
assign evict_treelet = evict_treelet_o;
assign evict_count = evict_count_o;
assign max_valid = max_valid_q;
assign max_treelet = max_valid_q ? max_treelet_q : ${ZERO_TW};
assign max_count = max_valid_q ? ({1'b0, max_count_m1_q} + ${ONE_CNT}) : ${ZERO_CNT};
assign occupancy = occupancy_q;
assign above_threshold = above_q;"#;
