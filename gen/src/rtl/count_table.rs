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
    // The reset values of a pointer's four registers (`max`, `run_min`, ...), one per line.
    let reset = |ptrs: &[&str], indent: usize| {
        ptrs.iter()
            .flat_map(|p| {
                [
                    format!("{p}_valid_d = 1'b0;"),
                    format!("{p}_idx_d = {};", lit(iw, 0)),
                    format!("{p}_treelet_d = {};", lit(tw, 0)),
                    format!("{p}_count_m1_d = {};", lit(cw, 0)),
                ]
            })
            .map(|l| format!("{:indent$}{l}", ""))
            .collect::<Vec<_>>()
            .join("\n")
    };
    let vars: Vec<(&str, String)> = vec![
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
        ("RUN_RESET_12", reset(&["run_max", "run_min"], 12)),
        ("RUN_RESET_8", reset(&["run_max", "run_min"], 8)),
        ("PTR_RESET_8", reset(&["max", "min"], 8)),
        ("IDLE", state_param(state, "IDLE")),
        ("SCAN", state_param(state, "SCAN")),
    ];
    // Two passes: the ABOVE_* values contain placeholders themselves.
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
reg          pmax_valid;
reg [${IWM1}:0]  pmax_idx;
reg [${TWM1}:0] pmax_treelet;
reg [${CWM1}:0] pmax_cm1;
reg          pmin_valid;
reg [${IWM1}:0]  pmin_idx;
reg [${TWM1}:0] pmin_treelet;
reg [${CWM1}:0] pmin_cm1;
always @* begin : p_published
    pmax_valid = max_valid_q;
    pmax_idx = max_idx_q;
    pmax_treelet = max_treelet_q;
    pmax_cm1 = max_count_m1_q;
    if (max_valid_q || !scanning) begin
        if (chg_up && (beats_max(max_valid_q, max_idx_q, max_count_m1_q, chg_idx, chg_cm1)
                       || (chg_idx == max_idx_q))) begin
            pmax_valid = 1'b1;
            pmax_idx = chg_idx;
            pmax_treelet = op_treelet;
            pmax_cm1 = chg_cm1;
        end else if (chg_max_stale && max_valid_q && (chg_idx == max_idx_q)) begin
            pmax_valid = 1'b0;
        end
    end
    pmin_valid = min_valid_q;
    pmin_idx = min_idx_q;
    pmin_treelet = min_treelet_q;
    pmin_cm1 = min_count_m1_q;
    if (min_valid_q || !scanning) begin
        if (chg_down && (beats_min(min_valid_q, min_idx_q, min_count_m1_q, chg_idx, chg_cm1)
                         || (chg_idx == min_idx_q))) begin
            pmin_valid = 1'b1;
            pmin_idx = chg_idx;
            pmin_treelet = op_treelet;
            pmin_cm1 = chg_cm1;
        end else if (chg_min_stale && min_valid_q && (chg_idx == min_idx_q)) begin
            pmin_valid = 1'b0;
        end
    end
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
reg          wmax_valid;
reg [${IWM1}:0]  wmax_idx;
reg [${TWM1}:0] wmax_treelet;
reg [${CWM1}:0] wmax_cm1;
reg          wmin_valid;
reg [${IWM1}:0]  wmin_idx;
reg [${TWM1}:0] wmin_treelet;
reg [${CWM1}:0] wmin_cm1;
always @* begin : p_scan
    integer k;
    reg [${WM1}:0] word;
    reg [${IWM1}:0] idx;
    wmax_valid = run_max_valid_q;
    wmax_idx = run_max_idx_q;
    wmax_treelet = run_max_treelet_q;
    wmax_cm1 = run_max_count_m1_q;
    wmin_valid = run_min_valid_q;
    wmin_idx = run_min_idx_q;
    wmin_treelet = run_min_treelet_q;
    wmin_cm1 = run_min_count_m1_q;
    for (k = 0; k < ${S}; k = k + 1) begin
        word = scan_words[k*${W} +: ${W}];
        idx = scan_pos_q + k[${IWM1}:0];
        if (word[${VB}]) begin
            if (beats_max(wmax_valid, wmax_idx, wmax_cm1, idx, word[${CWM1}:0])) begin
                wmax_valid = 1'b1;
                wmax_idx = idx;
                wmax_treelet = word[${TH}:${TL}];
                wmax_cm1 = word[${CWM1}:0];
            end
            if (beats_min(wmin_valid, wmin_idx, wmin_cm1, idx, word[${CWM1}:0])) begin
                wmin_valid = 1'b1;
                wmin_idx = idx;
                wmin_treelet = word[${TH}:${TL}];
                wmin_cm1 = word[${CWM1}:0];
            end
        end
    end
end

wire [${IW}:0] scan_next = {1'b0, scan_pos_q} + ${L_S1};        // one past this cycle's window
wire       scan_last = (scan_next >= ${L_N1});                // the window reaches the last entry
wire [${IW}:0] scan_end  = scan_last ? ${L_N1} : scan_next;      // end of the window (exclusive)
wire       chg_seen  = (chg_kind != CHG_NONE) && ({1'b0, chg_idx} < scan_end); // change behind the scan

// ---- Next state -------------------------------------------------------------------------------
always @* begin : p_next
    reg          rmax_valid;
    reg [${IWM1}:0]  rmax_idx;
    reg [${TWM1}:0] rmax_treelet;
    reg [${CWM1}:0] rmax_cm1;
    reg          rmin_valid;
    reg [${IWM1}:0]  rmin_idx;
    reg [${TWM1}:0] rmin_treelet;
    reg [${CWM1}:0] rmin_cm1;
    reg          intact;
    occupancy_d = occupancy_q + ${OCC_INC} - ${OCC_DEC};
    above_d = above_q + ${NEW_ABOVE} - ${OLD_ABOVE};
    // A change on an entry the scan has already passed is folded into its running result by
    // the published pointers' rules; when it stales the running result the scan restarts.
    rmax_valid = wmax_valid;
    rmax_idx = wmax_idx;
    rmax_treelet = wmax_treelet;
    rmax_cm1 = wmax_cm1;
    rmin_valid = wmin_valid;
    rmin_idx = wmin_idx;
    rmin_treelet = wmin_treelet;
    rmin_cm1 = wmin_cm1;
    intact = 1'b1;
    if (chg_seen) begin
        if (chg_up && (beats_max(wmax_valid, wmax_idx, wmax_cm1, chg_idx, chg_cm1)
                       || (chg_idx == wmax_idx))) begin
            rmax_valid = 1'b1;
            rmax_idx = chg_idx;
            rmax_treelet = op_treelet;
            rmax_cm1 = chg_cm1;
        end else if (chg_max_stale && wmax_valid && (chg_idx == wmax_idx)) begin
            intact = 1'b0;
        end
        if (chg_down && (beats_min(wmin_valid, wmin_idx, wmin_cm1, chg_idx, chg_cm1)
                         || (chg_idx == wmin_idx))) begin
            rmin_valid = 1'b1;
            rmin_idx = chg_idx;
            rmin_treelet = op_treelet;
            rmin_cm1 = chg_cm1;
        end else if (chg_min_stale && wmin_valid && (chg_idx == wmin_idx)) begin
            intact = 1'b0;
        end
    end
    state_d = state_q;
    scan_pos_d = scan_pos_q;
    max_valid_d = pmax_valid;
    max_idx_d = pmax_idx;
    max_treelet_d = pmax_treelet;
    max_count_m1_d = pmax_cm1;
    min_valid_d = pmin_valid;
    min_idx_d = pmin_idx;
    min_treelet_d = pmin_treelet;
    min_count_m1_d = pmin_cm1;
    run_max_valid_d = run_max_valid_q;
    run_max_idx_d = run_max_idx_q;
    run_max_treelet_d = run_max_treelet_q;
    run_max_count_m1_d = run_max_count_m1_q;
    run_min_valid_d = run_min_valid_q;
    run_min_idx_d = run_min_idx_q;
    run_min_treelet_d = run_min_treelet_q;
    run_min_count_m1_d = run_min_count_m1_q;
    if (scanning) begin
        if (intact && !scan_last) begin
            // Next window.
            scan_pos_d = scan_next[${IWM1}:0];
            run_max_valid_d = rmax_valid;
            run_max_idx_d = rmax_idx;
            run_max_treelet_d = rmax_treelet;
            run_max_count_m1_d = rmax_cm1;
            run_min_valid_d = rmin_valid;
            run_min_idx_d = rmin_idx;
            run_min_treelet_d = rmin_treelet;
            run_min_count_m1_d = rmin_cm1;
        end else begin
            // Restart from entry 0, or the last window: publish both pointers.
            if (intact) begin
                state_d = ${IDLE};
                max_valid_d = rmax_valid;
                max_idx_d = rmax_idx;
                max_treelet_d = rmax_treelet;
                max_count_m1_d = rmax_cm1;
                min_valid_d = rmin_valid;
                min_idx_d = rmin_idx;
                min_treelet_d = rmin_treelet;
                min_count_m1_d = rmin_cm1;
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
