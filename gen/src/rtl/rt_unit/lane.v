// ---------------------------------------------------------------------------------------------
// rt_unit_lane: the next state of one lane of the RT unit's warp buffer (one instance per lane,
// holding the lane's registers and its two stacks and node buffer). The lane runs the stages of
// RtUnit::update on its own state, told by the slot-level logic what concerns it:
//   A  completion (its slot completes), the hit-record store sent, the request merged into
//      the scheduler's fetch, its own spill or fill as the leader, the delay countdown;
//   B  the response popped: a stack fill it expects or a chunk of its node (then the
//      intersection test's inputs);
//   T  the test's result written back (closest hit, children pushed, status, boundary);
//   C  the controller's commands: a warp issued into its slot, a stop, a repack.
// Each stage is its own always block on the values the previous one produced (`<field>_a`,
// `_b`, `_t`, `_d`), so no signal's logic loops through the slot-level logic.
// Each stack keeps its bottom K entries in a window of flip-flops, the rest in a ring of SKB
// SRAM banks (rt_unit_stack_bank: one read and one write port, read latency 1) from ring
// position `base`, and a copy of its top while that lies in the ring (vtq_hdl's StackLayout).
// A pop reads the new top from the ring and a spill the entries sliding into the window; the
// read data replaces them in the next cycle (`pending`), before any stage reads them.
// ---------------------------------------------------------------------------------------------
/* verilator lint_off DECLFILENAME */
module rt_unit_lane (
    clk, rst,
${LANE_PORT_NAMES}
    two, stopped, complete, store_sel, merge, lead_node, lead, lead_me,
    pop_fill_here, pop_node_here, pop_leader, pop_address, pop_data, fill_expect,
    dp_child_count, dp_children, dp_hit_valid, dp_hit,
    load, write_here, wake, issue_active, issue_ray_id, issue_ray_words, issue_occlusion, issue_hit_valid, issue_hit,
    issue_cur_treelet, issue_cur_sp, issue_other_sp, issue_cur_spilled, issue_other_spilled,
    issue_cur_stack, issue_other_stack, stop_here, repack_here,
    busy, act, act_index, next_valid, next_treelet,
    done_active, done_parked, done_cur_stack, done_other_stack, spill_data,
    fx_ray, fx_stack, fx_index, fill_ok, node_match, node_chunk, dp_node, tested, test_kind,
    new_hit, err_child, err_value, err_limit, boundary_valid,
    boundary_treelet, status_tested, released
);
/* verilator lint_on DECLFILENAME */
/* verilator lint_off UNUSEDPARAM */
${PARAMS}
${COMMON}
/* verilator lint_on UNUSEDPARAM */

input  wire           clk;
input  wire           rst;
// The lane's registers (`_q`, the description's ones also outputs) and their next values (`_d`).
${LANE_PORT_DECLS}
// The slot's warp: two stacks (treelet orders), stopped (treelet-stationary order).
input  wire           two;
input  wire           stopped;
// Stage 2: the slot's warp completes this cycle.
input  wire           complete;
// Stage 3: this lane's hit-record store is the request sent; the slot's leader fetches
// `lead_node` (lane `lead`) and every ready lane of the slot whose next node it is merges;
// this lane is the scheduler's leader (its spill or fill is the request).
input  wire           store_sel;
input  wire           merge;
input  wire [E-1:0]   lead_node;
input  wire [LB-1:0]  lead;
input  wire           lead_me;
// Stage 5: the popped response is a stack fill for this lane (it is the tag's lane), or a
// chunk for the lanes of its slot led by `pop_leader`; the fill's expected address.
input  wire           pop_fill_here;
input  wire           pop_node_here;
input  wire [LB-1:0]  pop_leader;
input  wire [AB-1:0]  pop_address;
input  wire [255:0]   pop_data;
input  wire [AB-1:0]  fill_expect;
// The intersection datapath's result for this lane's test.
input  wire [CW-1:0]  dp_child_count;
input  wire [R*CHW-1:0] dp_children;
input  wire           dp_hit_valid;
input  wire [127:0]   dp_hit;
// Stage 7: a warp issued into this lane or a record written into it (`load`), this lane's slice of the issue bus; a stop
// and a repack of the lane's slot.
input  wire           load;
input  wire           write_here;   // the load is a lane write: the lane stays inactive, written
input  wire           wake;         // the issue enters the lane's written record
input  wire           issue_active;
input  wire [RB-1:0]  issue_ray_id;
input  wire [255:0]   issue_ray_words;
input  wire           issue_occlusion;
input  wire           issue_hit_valid;
input  wire [127:0]   issue_hit;
input  wire [TW-1:0]  issue_cur_treelet;
input  wire [RSPW-1:0] issue_cur_sp;
input  wire [RSPW-1:0] issue_other_sp;
input  wire [SCW-1:0] issue_cur_spilled;
input  wire [SCW-1:0] issue_other_spilled;
input  wire [RD*E-1:0] issue_cur_stack;
input  wire [RD*E-1:0] issue_other_stack;
input  wire           stop_here;
input  wire           repack_here;
// Start-of-cycle views: busy (not quiescent), the lane's request {action, stack, spill count,
// node} and the spilled chunks of that stack, its next node's treelet when traversing.
output reg            busy;
output reg  [E+5:0]   act;
output reg  [SCW-1:0] act_index;
output reg            next_valid;
output reg  [TW-1:0]  next_treelet;
// Stage 2 and 3 results (zero unless they concern this lane): the completed ray's flags and
// its stacks' valid entries; the spill's data; the fill's expected address's terms.
output reg            done_active;
output reg            done_parked;
output reg  [RD*E-1:0] done_cur_stack;
output reg  [RD*E-1:0] done_other_stack;
output reg  [255:0]   spill_data;
output reg  [RB-1:0]  fx_ray;
output reg            fx_stack;
output reg  [SCW-1:0] fx_index;
// Stage 5 results: the fill matched, the chunk matched and its index in the node (zero unless
// it matched: the slot level writes it into the node buffer), the node the datapath tests (zero
// unless it completed this cycle). The slot level gives the datapath the node's bytes from the
// node buffer and the ray and its closest hit from the lane's registers (stages 1-5 do not
// change them).
output reg            fill_ok;
output reg            node_match;
output reg  [1:0]     node_chunk;
output reg  [E-1:0]   dp_node;
// Test write-back: tested (node kind), a new closest triangle hit, the lane's first bad-child
// error (value, limit), a treelet boundary, the status after the test.
output reg            tested;
output reg  [2:0]     test_kind;
output reg            new_hit;
output reg            err_child;
output reg  [63:0]    err_value;
output reg  [63:0]    err_limit;
output reg            boundary_valid;
output reg  [TW-1:0]  boundary_treelet;
output reg  [1:0]     status_tested;
// Stage 7: the repack released the lane's finished ray.
output reg            released;

// The values after each stage.
${LANE_STAGE_DECLS}
reg [1:0] a_act;      // fields of `act`
reg       a_stack;
reg [2:0] a_k;
reg [E-1:0] a_node;
reg       fill_event; // a fill brought a boundary's top back
reg [TW-1:0] fill_treelet;
reg       test_now;   // the node completed: test it

// The stacks' rings: each bank's write and read this cycle (written by the test's children,
// read after a pop or a spill) and its read data (the word read in the previous cycle).
// (Without a ring, SK = 0, nothing reads the requests.)
/* verilator lint_off UNUSEDSIGNAL */
reg  [SKB-1:0]     cur_we, other_we;
reg  [SKB*SAW-1:0] cur_waddr, other_waddr;
reg  [SKB*E-1:0]   cur_wdata, other_wdata;
reg  [SKB*SAW-1:0] cur_raddr, other_raddr;
/* verilator lint_on UNUSEDSIGNAL */
wire [SKB*E-1:0]   cur_rdata, other_rdata;
// The start-of-cycle windows and tops with the read data in place of their pending entries.
reg  [K*E-1:0]     cur_win_r, other_win_r;
reg  [E-1:0]       cur_top_r, other_top_r;

// The ring position of stack entry j (j >= K; for j < K, where entry j's refill comes from):
// base + j - K, modulo the ring.
function [SPB-1:0] ring_pos;
    input [SPB-1:0] base;
    input [31:0] j;
    /* verilator lint_off UNUSEDSIGNAL */
    reg [31:0] p;
    /* verilator lint_on UNUSEDSIGNAL */
    begin
        p = {{(32-SPB){1'b0}}, base} + j - K;
        ring_pos = p[SPB-1:0];
    end
endfunction

// The bank and the word of ring position p.
function [SBW-1:0] bank_of;
    /* verilator lint_off UNUSEDSIGNAL */
    input [SPB-1:0] p;
    /* verilator lint_on UNUSEDSIGNAL */
    begin
        bank_of = p[SBW-1:0];
    end
endfunction
function [SAW-1:0] word_of;
    input [SPB-1:0] p;
    /* verilator lint_off UNUSEDSIGNAL */
    reg [31:0] w;
    /* verilator lint_on UNUSEDSIGNAL */
    begin
        w = {{(32-SPB){1'b0}}, p} >> SBW;
        word_of = w[SAW-1:0];
    end
endfunction

// Read addresses v with bank bank_of(p) addressing word_of(p): a decoder (an index into the
// vector would be a shifter with a 33-bit index computation).
function [SKB*SAW-1:0] with_raddr;
    input [SKB*SAW-1:0] v;
    input [SPB-1:0] p;
    integer b;
    begin
        with_raddr = v;
        for (b = 0; b < SKB; b = b + 1)
            if (bank_of(p) == b[SBW-1:0]) with_raddr[b*SAW +: SAW] = word_of(p);
    end
endfunction

// The top entry of a stack of sp entries (sp > 0): in the window, or the top register.
function [E-1:0] top_of;
    input [SPW-1:0] sp;
    input [K*E-1:0] win;
    input [E-1:0] top;
    integer j;
    begin
        top_of = top;
        for (j = 0; j < K; j = j + 1)
            if (sp == j[SPW-1:0] + ONE_SPW) top_of = win[j*E +: E];
    end
endfunction

always @* begin : p_resolve
    integer j;
    cur_win_r = cur_win_q;
    other_win_r = other_win_q;
    cur_top_r = cur_top_q;
    other_top_r = other_top_q;
    for (j = 0; j < K; j = j + 1) begin
        if (cur_pend_q[j])
            cur_win_r[j*E +: E] = cur_rdata[bank_of(ring_pos(cur_base_q, j))*E +: E];
        if (other_pend_q[j])
            other_win_r[j*E +: E] = other_rdata[bank_of(ring_pos(other_base_q, j))*E +: E];
    end
    if (cur_pend_q[K])
        cur_top_r = cur_rdata[bank_of(ring_pos(cur_base_q,
            {{(32-SPW){1'b0}}, cur_sp_q - ONE_SPW}))*E +: E];
    if (other_pend_q[K])
        other_top_r = other_rdata[bank_of(ring_pos(other_base_q,
            {{(32-SPW){1'b0}}, other_sp_q - ONE_SPW}))*E +: E];
end

generate
    genvar gb;
    for (gb = 0; gb < SK; gb = gb + 1) begin : g_ring
        rt_unit_stack_bank cur_bank (
            .clk(clk), .we(cur_we[gb]), .waddr(cur_waddr[gb*SAW +: SAW]),
            .wdata(cur_wdata[gb*E +: E]), .raddr(cur_raddr[gb*SAW +: SAW]),
            .rdata(cur_rdata[gb*E +: E]));
        rt_unit_stack_bank other_bank (
            .clk(clk), .we(other_we[gb]), .waddr(other_waddr[gb*SAW +: SAW]),
            .wdata(other_wdata[gb*E +: E]), .raddr(other_raddr[gb*SAW +: SAW]),
            .rdata(other_rdata[gb*E +: E]));
    end
    if (SK == 0) begin : g_no_ring
        assign cur_rdata = {SKB*E{1'b0}};
        assign other_rdata = {SKB*E{1'b0}};
    end
endgenerate

// A ray leaves the lane (its warp completes, or a repack releases it): the fields that held it,
// cleared (the node, delay and store fields are idle by then).
task leave;
    output [1:0] status;
    output [RB-1:0] ray_id;
    output [255:0] ray_words;
    output occlusion;
    output hit_valid;
    output [127:0] hit;
    output [TW-1:0] cur_treelet;
    output [SPW-1:0] cur_sp;
    output [SPW-1:0] other_sp;
    output [SCW-1:0] cur_spilled;
    output [SCW-1:0] other_spilled;
    begin
        status = ST_INACTIVE;
        ray_id = {RB{1'b0}};
        ray_words = 256'd0;
        occlusion = 1'b0;
        hit_valid = 1'b0;
        hit = 128'd0;
        cur_treelet = {TW{1'b0}};
        cur_sp = {SPW{1'b0}};
        other_sp = {SPW{1'b0}};
        cur_spilled = {SCW{1'b0}};
        other_spilled = {SCW{1'b0}};
    end
endtask

always @* begin : p_view
    /* verilator lint_off UNUSEDSIGNAL */
    reg [E-1:0] top;
    /* verilator lint_on UNUSEDSIGNAL */
    busy = status_q == ST_TRAVERSING || (status_q == ST_PARKED && other_sp_q > RD_SPW)
        || node_valid_q || filling_q != 2'd0
        || delay_q != {DW{1'b0}} || store_pending_q;
    act = lane_action(status_q, node_valid_q, filling_q, delay_q, cur_sp_q, other_sp_q,
                      cur_spilled_q, other_spilled_q, top_of(cur_sp_q, cur_win_r, cur_top_r),
                      top_of(other_sp_q, other_win_r, other_top_r), two);
    {a_act, a_stack, a_k, a_node} = act;
    act_index = a_stack ? other_spilled_q : cur_spilled_q;
    // The traversing lane's next node, if on chip.
    next_valid = 1'b0;
    next_treelet = {TW{1'b0}};
    top = {E{1'b0}};
    if (status_q == ST_TRAVERSING) begin
        if (cur_sp_q != {SPW{1'b0}}) begin
            next_valid = 1'b1;
            top = top_of(cur_sp_q, cur_win_r, cur_top_r);
        end else if (cur_spilled_q == {SCW{1'b0}} && other_sp_q != {SPW{1'b0}}) begin
            next_valid = 1'b1;
            top = top_of(other_sp_q, other_win_r, other_top_r);
        end
    end
    next_treelet = top[TSH + 5 +: TW];
end

// ---- A: completion, the scheduler's request, the delay countdown --------------------------------
always @* begin : p_a
    integer j, sh;
    reg [SPB-1:0] pos;
${COPY_A}
    // The read data in place of the pending entries; this cycle's reads.
    cur_win_a = cur_win_r;
    other_win_a = other_win_r;
    cur_top_a = cur_top_r;
    other_top_a = other_top_r;
    cur_pend_a = {(K+1){1'b0}};
    other_pend_a = {(K+1){1'b0}};
    cur_raddr = {SKB*SAW{1'b0}};
    other_raddr = {SKB*SAW{1'b0}};
    pos = {SPB{1'b0}};
    done_active = 1'b0;
    done_parked = 1'b0;
    done_cur_stack = {RD*E{1'b0}};
    done_other_stack = {RD*E{1'b0}};
    spill_data = 256'd0;
    // 2. Completion: a finished ray, or a parked one with a next node, leaves the lane.
    if (complete && (status_a == ST_DONE
        || (status_a == ST_PARKED && (cur_sp_a != {SPW{1'b0}}
            || (cur_spilled_a == {SCW{1'b0}} && other_sp_a != {SPW{1'b0}}))))) begin
        done_active = 1'b1;
        done_parked = status_a == ST_PARKED;
        // A completing lane holds at most RD entries per stack (parked lanes spilled the rest).
        for (j = 0; j < RD; j = j + 1) begin
            if (j < {{(32-SPW){1'b0}}, cur_sp_a}) done_cur_stack[j*E +: E] = cur_win_a[j*E +: E];
            if (j < {{(32-SPW){1'b0}}, other_sp_a}) done_other_stack[j*E +: E] = other_win_a[j*E +: E];
        end
        leave(status_a, ray_id_a, ray_words_a, occlusion_a, hit_valid_a, hit_a, cur_treelet_a,
              cur_sp_a, other_sp_a, cur_spilled_a, other_spilled_a);
    end
    // 3. The hit-record store sent, the fetch merged, the leader's spill or fill.
    if (store_sel) store_pending_a = 1'b0;
    if (merge && a_act == ACT_FETCH && a_node == lead_node) begin
        // The popped stack's new top, if it lies in the ring, is read for the next cycle.
        if (cur_sp_a != {SPW{1'b0}}) begin
            cur_sp_a = cur_sp_a - ONE_SPW;
            if (cur_sp_a > K_SPW) begin
                pos = ring_pos(cur_base_a, {{(32-SPW){1'b0}}, cur_sp_a - ONE_SPW});
                cur_raddr = with_raddr(cur_raddr, pos);
                cur_pend_a[K] = 1'b1;
            end
        end else begin
            other_sp_a = other_sp_a - ONE_SPW;
            cur_treelet_a = lead_node[E-1:TSH+5];
            if (other_sp_a > K_SPW) begin
                pos = ring_pos(other_base_a, {{(32-SPW){1'b0}}, other_sp_a - ONE_SPW});
                other_raddr = with_raddr(other_raddr, pos);
                other_pend_a[K] = 1'b1;
            end
        end
        node_valid_a = 1'b1;
        node_a = lead_node;
        node_leader_a = lead;
        chunks_returned_a = 4'd0;
    end
    if (lead_me && a_act == ACT_SPILL && act_index < SPC_W) begin
        // Store the a_k oldest entries; the rest of the window moves down, the ring's base up,
        // and the a_k entries above the window are read into its top for the next cycle.
        for (j = 0; j < D4; j = j + 1) begin
            if (j < {29'd0, a_k})
                spill_data[j*64 +: 64] = {1'b1, {(63-E){1'b0}},
                    a_stack ? other_win_a[j*E +: E] : cur_win_a[j*E +: E]};
        end
        for (sh = 1; sh <= 4; sh = sh + 1) begin
            if ({29'd0, a_k} == sh) begin
                for (j = 0; j + sh < K; j = j + 1) begin
                    if (a_stack) other_win_a[j*E +: E] = other_win_a[(j+sh)*E +: E];
                    else cur_win_a[j*E +: E] = cur_win_a[(j+sh)*E +: E];
                end
                if (SK != 0) begin
                    if (a_stack) other_base_a = other_base_a + sh[SPB-1:0];
                    else cur_base_a = cur_base_a + sh[SPB-1:0];
                    for (j = K - sh; j < K; j = j + 1) begin
                        if (a_stack) begin
                            pos = ring_pos(other_base_a, j);
                            other_raddr = with_raddr(other_raddr, pos);
                            other_pend_a[j] = 1'b1;
                        end else begin
                            pos = ring_pos(cur_base_a, j);
                            cur_raddr = with_raddr(cur_raddr, pos);
                            cur_pend_a[j] = 1'b1;
                        end
                    end
                end
            end
        end
        if (a_stack) begin
            other_sp_a = other_sp_a - {{(SPW-3){1'b0}}, a_k};
            other_spilled_a = act_index + ONE_SCW;
        end else begin
            cur_sp_a = cur_sp_a - {{(SPW-3){1'b0}}, a_k};
            cur_spilled_a = act_index + ONE_SCW;
        end
    end
    if (lead_me && a_act == ACT_FILL) filling_a = a_stack ? 2'd2 : 2'd1;
    // 4. The intersection delay counts down.
    if (delay_a != {DW{1'b0}}) delay_a = delay_a - ONE_DW;
    // The terms of a fill's expected address (the chunk below the stack's spilled count).
    fx_ray = {RB{1'b0}};
    fx_stack = 1'b0;
    fx_index = {SCW{1'b0}};
    if (pop_fill_here) begin
        fx_ray = ray_id_a;
        fx_stack = filling_a == 2'd2;
        fx_index = (fx_stack ? other_spilled_a : cur_spilled_a) - ONE_SCW;
    end
end

// ---- B: the popped response ---------------------------------------------------------------------
always @* begin : p_b
    integer j;
    reg stk;
    reg [SCW-1:0] sp_idx;
    reg [2:0] cnt;
    reg stop_scan;
    /* verilator lint_off UNUSEDSIGNAL */
    reg [63:0] w;  // a spilled entry's slot (valid bit and kind read)
    /* verilator lint_on UNUSEDSIGNAL */
    reg [AB-1:0] naddr;
    reg [2:0] nchunks;
    reg [AB:0] offset;
    reg [3:0] full;
    stk = 1'b0;
    sp_idx = {SCW{1'b0}};
    cnt = 3'd0;
    stop_scan = 1'b0;
    w = 64'd0;
${COPY_B}
    fill_ok = 1'b0;
    fill_event = 1'b0;
    fill_treelet = {TW{1'b0}};
    if (pop_fill_here && filling_b != 2'd0) begin
        stk = filling_b == 2'd2;
        sp_idx = stk ? other_spilled_b : cur_spilled_b;
        // Entries: the leading valid 64-bit slots (defined kinds).
        cnt = 3'd0;
        stop_scan = 1'b0;
        for (j = 0; j < 4; j = j + 1) begin
            w = pop_data[j*64 +: 64];
            if (!stop_scan && w[63] && w[4:2] < 3'd6) cnt = cnt + 3'd1;
            else stop_scan = 1'b1;
        end
        if (sp_idx != {SCW{1'b0}} && pop_address == fill_expect
            && (stk ? other_sp_b : cur_sp_b) == {SPW{1'b0}}
            && cnt != 3'd0 && {29'd0, cnt} <= D) begin
            fill_ok = 1'b1;
            for (j = 0; j < D4; j = j + 1) begin
                if (j < {29'd0, cnt}) begin
                    if (stk) other_win_b[j*E +: E] = pop_data[j*64 +: E];
                    else cur_win_b[j*E +: E] = pop_data[j*64 +: E];
                end
            end
            if (stk) begin
                other_sp_b = {{(SPW-3){1'b0}}, cnt};
                other_spilled_b = sp_idx - ONE_SCW;
            end else begin
                cur_sp_b = {{(SPW-3){1'b0}}, cnt};
                cur_spilled_b = sp_idx - ONE_SCW;
            end
            filling_b = 2'd0;
            if (stk && two && cur_sp_b == {SPW{1'b0}} && cur_spilled_b == {SCW{1'b0}}) begin
                if (stopped) status_b = ST_PARKED;
                fill_event = 1'b1;
                for (j = 0; j < 4; j = j + 1)
                    if (j + 1 == {29'd0, cnt}) fill_treelet = pop_data[j*64 + TSH + 5 +: TW];
            end
        end
    end
    // A node chunk: this lane's if it answers the lane's request. (Every condition is computed
    // first and each field written under one: nested conditions would multiplex the node
    // buffer once per level.)
    naddr = node_b[E-1:5];
    nchunks = {1'b0, node_b[1:0]} + 3'd1;
    offset = {1'b0, pop_address} - {1'b0, naddr};
    full = (4'd1 << nchunks) - 4'd1;
    node_match = pop_node_here && node_valid_b && node_leader_b == pop_leader
        && pop_address >= naddr && offset[4:0] == 5'd0
        && offset[AB:5] < {{(AB-7){1'b0}}, nchunks} && !chunks_returned_b[offset[6:5]];
    for (j = 0; j < 4; j = j + 1)
        if (node_match && offset[6:5] == j[1:0]) chunks_returned_b[j] = 1'b1;
    node_chunk = {2{node_match}} & offset[6:5];
    test_now = node_match && chunks_returned_b == full;
    if (test_now) node_valid_b = 1'b0;
    dp_node = {E{test_now}} & node_b;
end

// ---- T: the test's result written back ----------------------------------------------------------
always @* begin : p_t
    integer j, c;
    reg accepted;
    reg [127:0] h;
    reg [63:0] b;
    reg [CHW-1:0] child;
    reg [63:0] caddr;
    reg [2:0] ckind;
    reg [7:0] cchunks;
    /* verilator lint_off UNUSEDSIGNAL */
    reg [E-1:0] ent;  // the other stack's top at a boundary (its treelet read)
    /* verilator lint_on UNUSEDSIGNAL */
    reg finished;
    reg [SPB-1:0] pos;
    reg live, bad, at, cany, oany, at_cur, at_other;
    reg [E-1:0] cw, ow;
    reg [SPW-1:0] csp, osp;
    // Each child's push: made, to the other stack, its position, entry, ring bank and word.
    reg [R-1:0] push_ok, push_other, ring_push;
    reg [R*SPW-1:0] push_pos;
    reg [R*E-1:0] push_ent;
    reg [R*SBW-1:0] push_bank;
    reg [R*SAW-1:0] push_word;
    accepted = 1'b0;
    h = 128'd0;
    b = 64'd0;
    child = {CHW{1'b0}};
    caddr = 64'd0;
    ckind = 3'd0;
    cchunks = 8'd0;
    ent = {E{1'b0}};
    finished = 1'b0;
    pos = {SPB{1'b0}};
    live = 1'b0;
    bad = 1'b0;
    at = 1'b0;
    cany = 1'b0;
    oany = 1'b0;
    at_cur = 1'b0;
    at_other = 1'b0;
    cw = {E{1'b0}};
    ow = {E{1'b0}};
    push_ok = {R{1'b0}};
    push_other = {R{1'b0}};
    ring_push = {R{1'b0}};
    push_pos = {R*SPW{1'b0}};
    push_ent = {R*E{1'b0}};
    push_bank = {R*SBW{1'b0}};
    push_word = {R*SAW{1'b0}};
${COPY_T}
    csp = cur_sp_t;
    osp = other_sp_t;
    cur_we = {SKB{1'b0}};
    other_we = {SKB{1'b0}};
    cur_waddr = {SKB*SAW{1'b0}};
    other_waddr = {SKB*SAW{1'b0}};
    cur_wdata = {SKB*E{1'b0}};
    other_wdata = {SKB*E{1'b0}};
    tested = test_now;
    test_kind = 3'd0;
    new_hit = 1'b0;
    err_child = 1'b0;
    err_value = 64'd0;
    err_limit = 64'd0;
    boundary_valid = fill_event;
    boundary_treelet = fill_treelet;
    if (test_now) begin
        test_kind = node_t[2 +: 3];
        h = dp_hit;
        b = hit_t[63:0];
        accepted = dp_hit_valid && (!hit_valid_t || f32_lt(h[31:0], b[31:0])
            || (f32_eq(h[31:0], b[31:0]) && h[63:32] < b[63:32]));
        if (accepted) begin
            hit_t = h;
            hit_valid_t = 1'b1;
            store_pending_t = 1'b1;
            if (test_kind == K_TRIANGLE) new_hit = 1'b1;
        end
        delay_t = latency(test_kind, accepted);
        if (dp_child_count > R_CW) begin
            err_child = 1'b1;
            err_value = {{(64-CW){1'b0}}, dp_child_count};
            err_limit = R64;
        end
        // Children pushed last first, so the first in visit order ends on top. Each child's
        // push is decided first (its stack and position), then every window entry and ring
        // bank takes the one push aimed at it (positions are distinct): no entry is written
        // through a running position, which would unroll into multiplexer chains.
        for (c = R - 1; c >= 0; c = c - 1) begin
            child = dp_children[c*CHW +: CHW];
            caddr = child[CHW-1:11];
            ckind = child[10:8];
            cchunks = child[7:0];
            live = c < {{(32-CW){1'b0}}, dp_child_count};
            bad = live && bad_node(caddr, cchunks);
            if (bad && !err_child) begin
                err_value = caddr;
                err_limit = SPACE64;
            end
            err_child = err_child || bad;
            push_ent[c*E +: E] = {caddr[AB-1:0], ckind, cchunks[1:0] - 2'd1};
            push_other[c] = two && caddr[AB-1:TSH] != cur_treelet_t;
            if (live && !bad && !push_other[c] && csp < D_SPW) begin
                push_ok[c] = 1'b1;
                push_pos[c*SPW +: SPW] = csp;
                csp = csp + ONE_SPW;
            end
            if (live && !bad && push_other[c] && osp < D_SPW) begin
                push_ok[c] = 1'b1;
                push_pos[c*SPW +: SPW] = osp;
                osp = osp + ONE_SPW;
            end
        end
        for (j = 0; j < K; j = j + 1) begin
            cw = {E{1'b0}};
            ow = {E{1'b0}};
            cany = 1'b0;
            oany = 1'b0;
            for (c = 0; c < R; c = c + 1) begin
                at = push_ok[c] && push_pos[c*SPW +: SPW] == j[SPW-1:0];
                cw = cw | ({E{at && !push_other[c]}} & push_ent[c*E +: E]);
                ow = ow | ({E{at && push_other[c]}} & push_ent[c*E +: E]);
                cany = cany || (at && !push_other[c]);
                oany = oany || (at && push_other[c]);
            end
            if (cany) cur_win_t[j*E +: E] = cw;
            if (oany) other_win_t[j*E +: E] = ow;
        end
        // Into the ring: the bank of each push above the window; the last is the top's copy.
        for (c = R - 1; c >= 0; c = c - 1) begin
            ring_push[c] = push_ok[c] && push_pos[c*SPW +: SPW] >= K_SPW;
            pos = ring_pos(push_other[c] ? other_base_t : cur_base_t,
                           {{(32-SPW){1'b0}}, push_pos[c*SPW +: SPW]});
            push_bank[c*SBW +: SBW] = bank_of(pos);
            push_word[c*SAW +: SAW] = word_of(pos);
            if (ring_push[c] && !push_other[c]) begin
                cur_top_t = push_ent[c*E +: E];
                cur_pend_t[K] = 1'b0;
            end
            if (ring_push[c] && push_other[c]) begin
                other_top_t = push_ent[c*E +: E];
                other_pend_t[K] = 1'b0;
            end
        end
        // Each bank takes the push aimed at it, of either stack (both written unconditionally:
        // a branch on the push's stack would multiplex every bank's port once per child).
        for (j = 0; j < SK; j = j + 1) begin
            for (c = 0; c < R; c = c + 1) begin
                at = ring_push[c] && push_bank[c*SBW +: SBW] == j[SBW-1:0];
                at_other = at && push_other[c];
                at_cur = at && !push_other[c];
                other_we[j] = other_we[j] || at_other;
                other_waddr[j*SAW +: SAW] = other_waddr[j*SAW +: SAW]
                    | ({SAW{at_other}} & push_word[c*SAW +: SAW]);
                other_wdata[j*E +: E] = other_wdata[j*E +: E]
                    | ({E{at_other}} & push_ent[c*E +: E]);
                cur_we[j] = cur_we[j] || at_cur;
                cur_waddr[j*SAW +: SAW] = cur_waddr[j*SAW +: SAW]
                    | ({SAW{at_cur}} & push_word[c*SAW +: SAW]);
                cur_wdata[j*E +: E] = cur_wdata[j*E +: E] | ({E{at_cur}} & push_ent[c*E +: E]);
            end
        end
        cur_sp_t = csp;
        other_sp_t = osp;
        if (accepted && occlusion_t) begin
            // An occlusion ray's first accepted hit ends its traversal: both stacks dropped.
            cur_sp_t = {SPW{1'b0}};
            other_sp_t = {SPW{1'b0}};
            cur_spilled_t = {SCW{1'b0}};
            other_spilled_t = {SCW{1'b0}};
        end
        finished = cur_sp_t == {SPW{1'b0}} && cur_spilled_t == {SCW{1'b0}}
            && other_sp_t == {SPW{1'b0}} && other_spilled_t == {SCW{1'b0}};
        if (finished) begin
            status_t = ST_DONE;
        end else if (two && cur_sp_t == {SPW{1'b0}} && cur_spilled_t == {SCW{1'b0}}
                     && other_sp_t != {SPW{1'b0}}) begin
            // A treelet boundary: report the treelet of the other stack's top.
            if (stopped) status_t = ST_PARKED;
            boundary_valid = 1'b1;
            ent = top_of(other_sp_t, other_win_t, other_top_t);
            boundary_treelet = ent[TSH + 5 +: TW];
        end
    end
    status_tested = status_t;
end

// ---- C: the warp issue, the stop and the repack -------------------------------------------------
always @* begin : p_c
    reg finished;
    integer j;
    finished = 1'b0;
${COPY_D}
    released = 1'b0;
    if (load) begin
        finished = issue_cur_sp == {RSPW{1'b0}} && issue_cur_spilled == {SCW{1'b0}}
            && issue_other_sp == {RSPW{1'b0}} && issue_other_spilled == {SCW{1'b0}};
        status_d = !issue_active || write_here ? ST_INACTIVE : finished ? ST_DONE : ST_TRAVERSING;
        written_d = write_here;
        ray_id_d = issue_ray_id;
        ray_words_d = issue_ray_words;
        occlusion_d = issue_occlusion;
        hit_valid_d = issue_hit_valid;
        hit_d = issue_hit;
        cur_treelet_d = issue_cur_treelet;
        // A record's stacks (at most RD entries) fill the bottom of the lane's.
        cur_sp_d = {SPW{1'b0}};
        cur_sp_d[RSPW-1:0] = issue_cur_sp;
        other_sp_d = {SPW{1'b0}};
        other_sp_d[RSPW-1:0] = issue_other_sp;
        cur_spilled_d = issue_cur_spilled;
        other_spilled_d = issue_other_spilled;
        cur_win_d = {K*E{1'b0}};
        other_win_d = {K*E{1'b0}};
        for (j = 0; j < RD; j = j + 1) begin
            cur_win_d[j*E +: E] = issue_cur_stack[j*E +: E];
            other_win_d[j*E +: E] = issue_other_stack[j*E +: E];
        end
        cur_top_d = {E{1'b0}};
        other_top_d = {E{1'b0}};
        cur_base_d = {SPB{1'b0}};
        other_base_d = {SPB{1'b0}};
        cur_pend_d = {(K+1){1'b0}};
        other_pend_d = {(K+1){1'b0}};
        filling_d = 2'd0;
        node_valid_d = 1'b0;
        node_d = {E{1'b0}};
        node_leader_d = {LB{1'b0}};
        chunks_returned_d = 4'd0;
        delay_d = {DW{1'b0}};
        store_pending_d = 1'b0;
    end
    if (wake) begin
        finished = cur_sp_d == {SPW{1'b0}} && cur_spilled_d == {SCW{1'b0}}
            && other_sp_d == {SPW{1'b0}} && other_spilled_d == {SCW{1'b0}};
        status_d = finished ? ST_DONE : ST_TRAVERSING;
        written_d = 1'b0;
    end
    if (stop_here && status_d == ST_TRAVERSING && !node_valid_d && filling_d == 2'd0
        && cur_sp_d == {SPW{1'b0}} && cur_spilled_d == {SCW{1'b0}} && other_sp_d != {SPW{1'b0}})
        status_d = ST_PARKED;
    if (repack_here && status_d == ST_DONE && !node_valid_d && filling_d == 2'd0
        && delay_d == {DW{1'b0}} && !store_pending_d) begin
        released = 1'b1;
        leave(status_d, ray_id_d, ray_words_d, occlusion_d, hit_valid_d, hit_d, cur_treelet_d,
              cur_sp_d, other_sp_d, cur_spilled_d, other_spilled_d);
    end
end

${LANE_REGISTERS}
endmodule

// One bank of a lane's stack ring: an SRAM of ${BANK_DEPTH} entries of ${BANK_E} bits with one write port and
// one read port of read latency 1 (read-first); no reset (an entry is written before it is
// read). Its sizes are fixed in the module, not parameters (one module per configuration).
/* verilator lint_off DECLFILENAME */
module rt_unit_stack_bank (
    input wire clk,
    input wire we,
    input wire [${BANK_AW}-1:0] waddr,
    input wire [${BANK_E}-1:0] wdata,
    input wire [${BANK_AW}-1:0] raddr,
    output reg [${BANK_E}-1:0] rdata
);
/* verilator lint_on DECLFILENAME */
reg [${BANK_E}-1:0] mem [0:${BANK_DEPTH}-1];
always @(posedge clk) begin : p_bank
    if (we) mem[waddr] <= wdata;
    rdata <= mem[raddr];
end
endmodule

// One bank of the node buffer: an SRAM of ${NODE_DEPTH} chunks of 256 bits (one per slot and leader lane)
// with one write port and one read port of read latency 1 (read-first); no reset (a chunk is
// written before a test reads it).
/* verilator lint_off DECLFILENAME */
module rt_unit_node_bank (
    input wire clk,
    input wire we,
    input wire [${NODE_AW}-1:0] waddr,
    input wire [255:0] wdata,
    input wire [${NODE_AW}-1:0] raddr,
    output reg [255:0] rdata
);
/* verilator lint_on DECLFILENAME */
reg [255:0] mem [0:${NODE_DEPTH}-1];
always @(posedge clk) begin : p_bank
    if (we) mem[waddr] <= wdata;
    rdata <= mem[raddr];
end
endmodule
