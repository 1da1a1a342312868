`define RT_ACTION lane_action(a_lane_status[(s*N+l)*2 +: 2], a_lane_node_valid[(s*N+l)], a_lane_filling[(s*N+l)*2 +: 2], a_lane_delay[(s*N+l)*DW +: DW], a_lane_cur_sp[(s*N+l)*SPW +: SPW], a_lane_other_sp[(s*N+l)*SPW +: SPW], a_lane_cur_spilled[(s*N+l)*SCW +: SCW], a_lane_other_spilled[(s*N+l)*SCW +: SCW], a_cur_stack[(s*N+l)*D*E +: D*E], a_other_stack[(s*N+l)*D*E +: D*E], two)
// ---- Sizes and constants of this configuration -------------------------------------------------
${PARAMS}
localparam D4 = (D < 4) ? D : 4;     // entries of a spill chunk that fit a stack
localparam [1:0] ST_INACTIVE = 2'd0;  // lane_status encodings
localparam [1:0] ST_TRAVERSING = 2'd1;
localparam [1:0] ST_DONE = 2'd2;
localparam [1:0] ST_PARKED = 2'd3;
localparam [1:0] ORD_RAY = 2'd0;      // slot_order encodings
localparam [1:0] ORD_STOP = 2'd2;
localparam [1:0] ACT_NONE = 2'd0;     // a ready lane's request
localparam [1:0] ACT_FETCH = 2'd1;
localparam [1:0] ACT_SPILL = 2'd2;
localparam [1:0] ACT_FILL = 2'd3;
localparam [2:0] K_TRIANGLE = 3'd4;   // node kind of a triangle leaf
// Error kinds (bit index of the flag in `errors`).
localparam [2:0] E_ISSUE_FULL = 3'd0;
localparam [2:0] E_BAD_ISSUE = 3'd1;
localparam [2:0] E_FIFO = 3'd2;
localparam [2:0] E_UNMATCHED = 3'd3;
localparam [2:0] E_SPILL_FULL = 3'd4;
localparam [2:0] E_BAD_CHILD = 3'd5;
localparam [2:0] E_BAD_COMMAND = 3'd6;
// Request kinds.
localparam [1:0] RQ_LOAD = 2'd0;
localparam [1:0] RQ_STORE = 2'd1;
localparam [1:0] RQ_SPILL = 2'd2;
localparam [1:0] RQ_FILL = 2'd3;
// first_error fields, most significant first: valid, kind, slot, lane, ray id, value, limit.
localparam FE_W = 1 + 3 + SB + LB + RB + 128;

// ---- Storage held in flip-flops (the description's memories) -----------------------------------
reg [NL*D*E-1:0] cur_stack_q;     // lane L's entry j in bits [(L*D+j)*E +: E], bottom first
reg [NL*D*E-1:0] cur_stack_d;
reg [NL*D*E-1:0] other_stack_q;
reg [NL*D*E-1:0] other_stack_d;
reg [NL*4*256-1:0] node_buffer_q; // lane L's chunk k in bits [(L*4+k)*256 +: 256]
reg [NL*4*256-1:0] node_buffer_d;
reg [FD*FEW-1:0] resp_fifo_q;     // entry i: {address, tag, data} in bits [i*FEW +: FEW]
reg [FD*FEW-1:0] resp_fifo_d;
always @(posedge clk) begin : p_storage
    integer L;
    if (rst) begin
        for (L = 0; L < NL*D; L = L + 1) begin
            cur_stack_q[L*E +: E] <= {E{1'b0}};
            other_stack_q[L*E +: E] <= {E{1'b0}};
        end
        for (L = 0; L < NL*4; L = L + 1) node_buffer_q[L*256 +: 256] <= 256'd0;
        for (L = 0; L < FD; L = L + 1) resp_fifo_q[L*FEW +: FEW] <= {FEW{1'b0}};
    end else begin
        cur_stack_q <= cur_stack_d;
        other_stack_q <= other_stack_d;
        node_buffer_q <= node_buffer_d;
        resp_fifo_q <= resp_fifo_d;
    end
end

// ---- Helpers ------------------------------------------------------------------------------------
// Byte address of chunk `index` of stack `stack` of ray `ray`'s spill area (the area fits the
// address space, so AB bits hold every term).
function [AB-1:0] spill_address;
    input [RB-1:0] ray;
    input stack;
    input [SCW-1:0] index;
    /* verilator lint_off UNUSEDSIGNAL */
    reg [AB-1:0] a;  // the chunk's index in the area (its top 5 bits are 0)
    /* verilator lint_on UNUSEDSIGNAL */
    begin
        a = {{(AB-RB-1){1'b0}}, ray, stack} * SPC_AB + {{(AB-SCW){1'b0}}, index};
        spill_address = SBASE_AB + {a[AB-6:0], 5'd0};
    end
endfunction

// Whether a node reference cannot be held: 1..=4 chunks, 32 B aligned, inside the address space.
function bad_node;
    input [63:0] address;
    input [7:0] chunks;
    reg [AB:0] end_byte;
    begin
        end_byte = {1'b0, address[AB-1:0]} + {{(AB-12){1'b0}}, chunks, 5'd0};
        bad_node = chunks == 8'd0 || chunks > 8'd4 || address[4:0] != 5'd0
            || address[63:AB] != {(64-AB){1'b0}} || end_byte > SPACE_W;
    end
endfunction

// f32 a < b (IEEE: false when either is NaN, -0 == +0).
function f32_lt;
    input [31:0] a;
    input [31:0] b;
    reg nan;
    reg zeros;
    begin
        nan = (a[30:23] == 8'hff && a[22:0] != 23'd0) || (b[30:23] == 8'hff && b[22:0] != 23'd0);
        zeros = a[30:0] == 31'd0 && b[30:0] == 31'd0;
        if (nan || zeros) f32_lt = 1'b0;
        else if (a[31] != b[31]) f32_lt = a[31];
        else if (a[31]) f32_lt = a[30:0] > b[30:0];
        else f32_lt = a[30:0] < b[30:0];
    end
endfunction

// f32 a == b (IEEE).
function f32_eq;
    input [31:0] a;
    input [31:0] b;
    reg nan;
    begin
        nan = (a[30:23] == 8'hff && a[22:0] != 23'd0) || (b[30:23] == 8'hff && b[22:0] != 23'd0);
        f32_eq = !nan && (a == b || (a[30:0] == 31'd0 && b[30:0] == 31'd0));
    end
endfunction

// Test latency of a node kind (triangle leaf: `hit` selects the hit latency).
function [DW-1:0] latency;
    input [2:0] kind;
    input hit;
    begin
        case (kind)
            3'd0: latency = LAT_HEADER;
            3'd1: latency = LAT_INTERNAL;
            3'd2: latency = LAT_INSTANCE;
            3'd3: latency = LAT_PRIMITIVE;
            3'd4: latency = hit ? LAT_TRI_HIT : LAT_TRI;
            3'd5: latency = LAT_PROCEDURAL;
            default: latency = {DW{1'b0}};
        endcase
    end
endfunction

// A lane's request this cycle: {action, stack (0 current, 1 other), spill count, node}; none
// unless the lane is ready (traversing, nothing in flight, no delay, an entry left).
function [E+5:0] lane_action;
    input [1:0] st;
    input nv;
    input [1:0] fl;
    input [DW-1:0] dl;
    input [SPW-1:0] csp;
    input [SPW-1:0] osp;
    input [SCW-1:0] csl;
    input [SCW-1:0] osl;
    input [D*E-1:0] cs;
    input [D*E-1:0] os;
    input two;
    reg [1:0] a;
    reg stk;
    reg [2:0] kk;
    reg [E-1:0] nd;
    reg pop_other;
    reg [15:0] after;
    integer j;
    begin
        a = ACT_NONE;
        stk = 1'b0;
        kk = 3'd0;
        nd = {E{1'b0}};
        pop_other = 1'b0;
        if (st == ST_TRAVERSING && !nv && fl == 2'd0 && dl == {DW{1'b0}}) begin
            if (csp != {SPW{1'b0}}) begin
                a = ACT_FETCH;
                for (j = 0; j < D; j = j + 1)
                    if (csp == j[SPW-1:0] + ONE_SPW) nd = cs[j*E +: E];
            end else if (csl != {SCW{1'b0}}) begin
                a = ACT_FILL;
            end else if (osp != {SPW{1'b0}}) begin
                a = ACT_FETCH;
                pop_other = 1'b1;
                for (j = 0; j < D; j = j + 1)
                    if (osp == j[SPW-1:0] + ONE_SPW) nd = os[j*E +: E];
            end else if (osl != {SCW{1'b0}}) begin
                a = ACT_FILL;
                stk = 1'b1;
            end
            // After the pop, every stack that may receive children needs room for R of them.
            if (a == ACT_FETCH) begin
                after = {{(16-SPW){1'b0}}, csp} - {15'd0, !pop_other};
                if (after + R16 > D16) begin
                    a = ACT_SPILL;
                    kk = after > 16'd4 ? 3'd4 : after[2:0];
                end else if (two) begin
                    after = {{(16-SPW){1'b0}}, osp} - {15'd0, pop_other};
                    if (after + R16 > D16) begin
                        a = ACT_SPILL;
                        stk = 1'b1;
                        kk = after > 16'd4 ? 3'd4 : after[2:0];
                    end
                end
            end
        end
        lane_action = {a, stk, kk, nd};
    end
endfunction

// ---- Working state ------------------------------------------------------------------------------
// p_front runs stages 1-5 of the cycle (statistics, completion, the memory scheduler, the delay
// countdown, the response pop up to the datapath's inputs) on `a_<register>`, copies of the
// registers; p_back takes them over as `<register>_d` and runs the rest (test write-back, the
// response push, warp issue, stop, repack). Each stage reads the values the earlier ones wrote,
// like RtUnit::update on its copy of the registers.
${WORKING_DECLS}
reg [NL*D*E-1:0] a_cur_stack;
reg [NL*D*E-1:0] a_other_stack;
reg [NL*4*256-1:0] a_node_buffer;
reg [FD*FEW-1:0] a_resp_fifo;

// Front-end results for the back end and the outputs.
reg [S-1:0] free_mask;            // slots free at the start of the cycle
reg [FCW-1:0] o_resp_free;
reg o_done_valid;
reg [SB-1:0] o_done_slot;
reg [N-1:0] o_done_active;
reg [N-1:0] o_done_parked;
reg [N*RB-1:0] o_done_ray_id;
reg [N*256-1:0] o_done_ray_words;
reg [N-1:0] o_done_hit_valid;
reg [N*128-1:0] o_done_hit;
reg [N*TW-1:0] o_done_cur_treelet;
reg [N*SPW-1:0] o_done_cur_sp;
reg [N*SPW-1:0] o_done_other_sp;
reg [N*SCW-1:0] o_done_cur_spilled;
reg [N*SCW-1:0] o_done_other_spilled;
reg [N*D*E-1:0] o_done_cur_stack;
reg [N*D*E-1:0] o_done_other_stack;
reg o_req_valid;
reg [AB-1:0] o_req_address;
reg [1:0] o_req_kind;
reg [TGW-1:0] o_req_tag;
reg [255:0] o_req_data;
reg [CWW-1:0] o_count_warps;
reg [CAW-1:0] o_count_active;
reg [CAW-1:0] o_count_waiting;
reg [CAW-1:0] o_count_done_lanes;
reg [CAW-1:0] o_count_parked_lanes;
reg o_count_request;
reg o_count_store;
reg o_count_spill;
reg o_count_fill;
reg o_count_warp_done;
reg [CMW-1:0] o_count_merged;
reg pop_valid;                    // a response was popped
reg [SB-1:0] pop_slot;
reg [LB-1:0] pop_leader;
reg pop_node;                     // ... and it is a node chunk for a valid slot (else handled)
reg [AB-1:0] pop_address;
reg [N-1:0] test_now;             // lanes of pop_slot whose node completed: run the test
reg node_matched;                 // the node chunk matched a lane
reg [N-1:0] fill_event;           // a fill brought a boundary's top back (lane of pop_slot)
reg [N*TW-1:0] fill_treelet;
// Datapath inputs, per lane of pop_slot.
reg [N*256-1:0] dp_ray;
reg [N-1:0] dp_best_valid;
reg [N*128-1:0] dp_best;
reg [N*E-1:0] dp_node;
reg [N*1024-1:0] dp_data;
// Datapath outputs, per lane.
wire [N*CW-1:0] dp_child_count;
wire [N*R*CHW-1:0] dp_children;
wire [N-1:0] dp_hit_valid;
wire [N*128-1:0] dp_hit;

// The error registers {errors, first_error} after raising error `kind` (its flag set; the first
// error captured with its slot, lane, ray id, value and limit).
function [7+FE_W-1:0] raised;
    input [6:0] flags;
    input [FE_W-1:0] first;
    input [2:0] kind;
    input [SB-1:0] slot;
    input [LB-1:0] lane;
    input [RB-1:0] ray;
    input [63:0] value;
    input [63:0] limit;
    begin
        raised = {flags | (7'd1 << kind),
                  first[FE_W-1] ? first : {1'b1, kind, slot, lane, ray, value, limit}};
    end
endfunction

// The intersection datapath, one per lane (a black box outside the RT unit's control).
genvar gl;
generate
    for (gl = 0; gl < N; gl = gl + 1) begin : g_datapath
        rt_datapath #(.AB(AB), .E(E), .R(R)) u_datapath (
            .ray(dp_ray[gl*256 +: 256]),
            .best_valid(dp_best_valid[gl]),
            .best(dp_best[gl*128 +: 128]),
            .node(dp_node[gl*E +: E]),
            .data(dp_data[gl*1024 +: 1024]),
            .child_count(dp_child_count[gl*CW +: CW]),
            .children(dp_children[gl*R*CHW +: R*CHW]),
            .hit_valid(dp_hit_valid[gl]),
            .hit(dp_hit[gl*128 +: 128])
        );
    end
endgenerate

// ---- Stages 1-5 ---------------------------------------------------------------------------------
always @* begin : p_front
    integer s, l, k, j, L, sh;
    reg found;
    reg [SB-1:0] sk;
    reg [LB-1:0] lead;
    reg [SPW-1:0] csp;
    reg [SPW-1:0] osp;
    reg [SCW-1:0] csl;
    reg [1:0] act;
    reg act_stack;
    reg [2:0] act_k;
    reg [E-1:0] act_node;
    reg [1:0] lact;
    reg lact_stack;
    reg [2:0] lact_k;
    reg [E-1:0] lact_node;
    reg two;
    reg busy;
    reg [CMW-1:0] served;
    reg [SCW-1:0] sp_idx;
    reg [FEW-1:0] entry;
    reg [AB-1:0] r_addr;
    reg [TGW-1:0] r_tag;
    reg [255:0] r_data;
    reg [AB:0] offset;
    reg [AB-1:0] naddr;
    reg [2:0] nchunks;
    reg [3:0] full;
    reg [2:0] cnt;
    reg [63:0] w;
    reg stop_scan;
    reg addr_needed;
    reg [RB-1:0] addr_ray;
    reg [SCW-1:0] addr_index;
    reg [AB-1:0] fill_expect;
    addr_needed = 1'b0;
    addr_ray = {RB{1'b0}};
    addr_index = {SCW{1'b0}};
    fill_expect = {AB{1'b0}};
    found = 1'b0;
    sk = {SB{1'b0}};
    lead = {LB{1'b0}};
    csp = {SPW{1'b0}};
    osp = {SPW{1'b0}};
    csl = {SCW{1'b0}};
    act = ACT_NONE;
    act_stack = 1'b0;
    act_k = 3'd0;
    act_node = {E{1'b0}};
    lact = ACT_NONE;
    lact_stack = 1'b0;
    lact_k = 3'd0;
    lact_node = {E{1'b0}};
    two = 1'b0;
    busy = 1'b0;
    served = {CMW{1'b0}};
    sp_idx = {SCW{1'b0}};
    entry = {FEW{1'b0}};
    r_addr = {AB{1'b0}};
    r_tag = {TGW{1'b0}};
    r_data = 256'd0;
    offset = {(AB+1){1'b0}};
    naddr = {AB{1'b0}};
    nchunks = 3'd0;
    full = 4'd0;
    cnt = 3'd0;
    w = 64'd0;
    stop_scan = 1'b0;
    o_req_valid = 1'b0;
    o_req_address = {AB{1'b0}};
    o_req_kind = RQ_LOAD;
    o_req_tag = {TGW{1'b0}};
    o_req_data = 256'd0;
    o_count_request = 1'b0;
    o_count_store = 1'b0;
    o_count_spill = 1'b0;
    o_count_fill = 1'b0;
    o_count_merged = {CMW{1'b0}};
    pop_valid = 1'b0;
    pop_slot = {SB{1'b0}};
    pop_leader = {LB{1'b0}};
    pop_node = 1'b0;
    pop_address = {AB{1'b0}};
    test_now = {N{1'b0}};
    node_matched = 1'b0;
    fill_event = {N{1'b0}};
    fill_treelet = {N*TW{1'b0}};
    dp_best_valid = {N{1'b0}};
    dp_best = {N*128{1'b0}};
    dp_node = {N*E{1'b0}};
    // Wide vectors lane by lane.
    for (l = 0; l < N; l = l + 1) begin
        dp_ray[l*256 +: 256] = 256'd0;
        dp_data[l*1024 +: 1024] = 1024'd0;
        o_done_ray_words[l*256 +: 256] = 256'd0;
        for (j = 0; j < D; j = j + 1) begin
            o_done_cur_stack[(l*D+j)*E +: E] = {E{1'b0}};
            o_done_other_stack[(l*D+j)*E +: E] = {E{1'b0}};
        end
    end
${WORKING_COPIES}
    a_cur_stack = cur_stack_q;
    a_other_stack = other_stack_q;
    a_node_buffer = node_buffer_q;
    a_resp_fifo = resp_fifo_q;
    free_mask = ~slot_valid_q;
    o_resp_free = FD_W - fifo_count_q;

    // 1. Statistics (start-of-cycle registers).
    o_count_warps = {CWW{1'b0}};
    o_count_active = {CAW{1'b0}};
    o_count_waiting = {CAW{1'b0}};
    o_count_done_lanes = {CAW{1'b0}};
    o_count_parked_lanes = {CAW{1'b0}};
    for (s = 0; s < S; s = s + 1) begin
        if (slot_valid_q[s]) begin
            o_count_warps = o_count_warps + ONE_CWW;
            for (l = 0; l < N; l = l + 1) begin
                if (lane_status_q[(s*N+l)*2 +: 2] == ST_TRAVERSING) begin
                    o_count_active = o_count_active + ONE_CAW;
                    if (lane_node_valid_q[(s*N+l)] || lane_filling_q[(s*N+l)*2 +: 2] != 2'd0)
                        o_count_waiting = o_count_waiting + ONE_CAW;
                end
                if (lane_status_q[(s*N+l)*2 +: 2] == ST_DONE)
                    o_count_done_lanes = o_count_done_lanes + ONE_CAW;
                if (lane_status_q[(s*N+l)*2 +: 2] == ST_PARKED)
                    o_count_parked_lanes = o_count_parked_lanes + ONE_CAW;
            end
        end
    end

    // 2. Completion: the oldest warp, not held, whose lanes are all quiescent.
    o_done_valid = 1'b0;
    o_done_slot = {SB{1'b0}};
    o_done_active = {N{1'b0}};
    o_done_parked = {N{1'b0}};
    o_done_ray_id = {N*RB{1'b0}};
    o_done_hit_valid = {N{1'b0}};
    o_done_hit = {N*128{1'b0}};
    o_done_cur_treelet = {N*TW{1'b0}};
    o_done_cur_sp = {N*SPW{1'b0}};
    o_done_other_sp = {N*SPW{1'b0}};
    o_done_cur_spilled = {N*SCW{1'b0}};
    o_done_other_spilled = {N*SCW{1'b0}};
    o_count_warp_done = 1'b0;
    found = 1'b0;
    for (k = 0; k < S; k = k + 1) begin
        if (!found && k < {{(32-SCNT){1'b0}}, a_age_count}) begin
            sk = a_age_order[k*SB +: SB];
            for (s = 0; s < S; s = s + 1) begin
                if (sk == s[SB-1:0] && !a_slot_held[s]) begin
                    busy = 1'b0;
                    for (l = 0; l < N; l = l + 1) begin
                        if (a_lane_status[(s*N+l)*2 +: 2] == ST_TRAVERSING || a_lane_node_valid[(s*N+l)]
                            || a_lane_filling[(s*N+l)*2 +: 2] != 2'd0
                            || a_lane_delay[(s*N+l)*DW +: DW] != {DW{1'b0}} || a_lane_store_pending[(s*N+l)])
                            busy = 1'b1;
                    end
                    if (!busy) begin
                        found = 1'b1;
                        o_done_valid = 1'b1;
                        o_done_slot = sk;
                        o_count_warp_done = 1'b1;
                        a_slot_valid[s] = 1'b0;
                        for (l = 0; l < N; l = l + 1) begin
                            csp = a_lane_cur_sp[(s*N+l)*SPW +: SPW];
                            osp = a_lane_other_sp[(s*N+l)*SPW +: SPW];
                            csl = a_lane_cur_spilled[(s*N+l)*SCW +: SCW];
                            // A parked lane is reported with the treelet of its next node.
                            if (a_lane_status[(s*N+l)*2 +: 2] == ST_DONE
                                || (a_lane_status[(s*N+l)*2 +: 2] == ST_PARKED
                                    && (csp != {SPW{1'b0}}
                                        || (csl == {SCW{1'b0}} && osp != {SPW{1'b0}})))) begin
                                o_done_active[l] = 1'b1;
                                o_done_parked[l] = a_lane_status[(s*N+l)*2 +: 2] == ST_PARKED;
                                o_done_ray_id[l*RB +: RB] = a_lane_ray_id[(s*N+l)*RB +: RB];
                                o_done_ray_words[l*256 +: 256] = a_lane_ray_words[(s*N+l)*256 +: 256];
                                o_done_hit_valid[l] = a_lane_hit_valid[(s*N+l)];
                                o_done_hit[l*128 +: 128] = a_lane_hit[(s*N+l)*128 +: 128];
                                o_done_cur_treelet[l*TW +: TW] = a_lane_cur_treelet[(s*N+l)*TW +: TW];
                                o_done_cur_sp[l*SPW +: SPW] = csp;
                                o_done_other_sp[l*SPW +: SPW] = osp;
                                o_done_cur_spilled[l*SCW +: SCW] = csl;
                                o_done_other_spilled[l*SCW +: SCW] = a_lane_other_spilled[(s*N+l)*SCW +: SCW];
                                for (j = 0; j < D; j = j + 1) begin
                                    if (j < {{(32-SPW){1'b0}}, csp})
                                        o_done_cur_stack[(l*D+j)*E +: E] = a_cur_stack[((s*N+l)*D+j)*E +: E];
                                    if (j < {{(32-SPW){1'b0}}, osp})
                                        o_done_other_stack[(l*D+j)*E +: E] = a_other_stack[((s*N+l)*D+j)*E +: E];
                                end
                                // The ray leaves the lane.
                                a_lane_status[(s*N+l)*2 +: 2] = ST_INACTIVE;
                                a_lane_ray_id[(s*N+l)*RB +: RB] = {RB{1'b0}};
                                a_lane_ray_words[(s*N+l)*256 +: 256] = 256'd0;
                                a_lane_hit_valid[(s*N+l)] = 1'b0;
                                a_lane_hit[(s*N+l)*128 +: 128] = 128'd0;
                                a_lane_cur_treelet[(s*N+l)*TW +: TW] = {TW{1'b0}};
                                a_lane_cur_sp[(s*N+l)*SPW +: SPW] = {SPW{1'b0}};
                                a_lane_other_sp[(s*N+l)*SPW +: SPW] = {SPW{1'b0}};
                                a_lane_cur_spilled[(s*N+l)*SCW +: SCW] = {SCW{1'b0}};
                                a_lane_other_spilled[(s*N+l)*SCW +: SCW] = {SCW{1'b0}};
                            end
                        end
                        // Remove the slot from the age order.
                        for (j = k; j < S - 1; j = j + 1)
                            a_age_order[j*SB +: SB] = a_age_order[(j+1)*SB +: SB];
                        a_age_order[(S-1)*SB +: SB] = {SB{1'b0}};
                        a_age_count = a_age_count - ONE_SCNT;
                    end
                end
            end
        end
    end

    // 3. The memory scheduler: at most one 32 B request.
    o_req_valid = 1'b0;
    o_req_address = {AB{1'b0}};
    o_req_kind = RQ_LOAD;
    o_req_tag = {TGW{1'b0}};
    o_req_data = 256'd0;
    o_count_request = 1'b0;
    o_count_store = 1'b0;
    o_count_spill = 1'b0;
    o_count_fill = 1'b0;
    o_count_merged = {CMW{1'b0}};
    if (a_split_valid) begin
        // The next chunk of the node being requested.
        o_req_valid = 1'b1;
        o_req_address = a_split_node[E-1:5] + {{(AB-7){1'b0}}, a_split_chunk, 5'd0};
        o_req_tag = a_split_tag;
        o_count_request = 1'b1;
        if ({1'b0, a_split_chunk} + 3'd1 < {1'b0, a_split_node[1:0]} + 3'd1) begin
            a_split_chunk = a_split_chunk + 2'd1;
        end else begin
            a_split_valid = 1'b0;
            a_split_tag = {TGW{1'b0}};
            a_split_node = {E{1'b0}};
            a_split_chunk = 2'd0;
        end
    end else begin
        // A hit-record store: oldest warp, lowest lane.
        found = 1'b0;
        for (k = 0; k < S; k = k + 1) begin
            if (!found && k < {{(32-SCNT){1'b0}}, a_age_count}) begin
                sk = a_age_order[k*SB +: SB];
                for (s = 0; s < S; s = s + 1) begin
                    for (l = 0; l < N; l = l + 1) begin
                        if (!found && sk == s[SB-1:0] && a_lane_store_pending[(s*N+l)]) begin
                            found = 1'b1;
                            a_lane_store_pending[(s*N+l)] = 1'b0;
                            o_req_valid = 1'b1;
                            o_req_kind = RQ_STORE;
                            o_req_tag = {sk, l[LB-1:0]};
                            w = {{(59-RB){1'b0}}, a_lane_ray_id[(s*N+l)*RB +: RB], 5'd0};
                            o_req_address = HB_AB + w[AB-1:0];
                            o_req_data = {96'd0, {(32-RB){1'b0}}, a_lane_ray_id[(s*N+l)*RB +: RB],
                                a_lane_hit[(s*N+l)*128+96 +: 32], a_lane_hit[(s*N+l)*128+64 +: 32],
                                a_lane_hit[(s*N+l)*128+32 +: 32], a_lane_hit[(s*N+l)*128 +: 32]};
                            o_count_store = 1'b1;
                        end
                    end
                end
            end
        end
        // Else the lowest ready lane of the oldest warp with a ready lane.
        stop_scan = found;
        for (k = 0; k < S; k = k + 1) begin
            if (!stop_scan && k < {{(32-SCNT){1'b0}}, a_age_count}) begin
                sk = a_age_order[k*SB +: SB];
                for (s = 0; s < S; s = s + 1) begin
                    if (!stop_scan && sk == s[SB-1:0]) begin
                        two = a_slot_order[s*2 +: 2] != ORD_RAY;
                        // The leader: the lowest ready lane, and its action.
                        found = 1'b0;
                        lead = {LB{1'b0}};
                        act = ACT_NONE;
                        act_stack = 1'b0;
                        act_k = 3'd0;
                        act_node = {E{1'b0}};
                        for (l = 0; l < N; l = l + 1) begin
                            {lact, lact_stack, lact_k, lact_node} = `RT_ACTION;
                            if (!found && lact != ACT_NONE) begin
                                found = 1'b1;
                                lead = l[LB-1:0];
                                act = lact;
                                act_stack = lact_stack;
                                act_k = lact_k;
                                act_node = lact_node;
                            end
                        end
                        if (found) stop_scan = 1'b1;
                        if (found && act == ACT_FETCH) begin
                            // Fetch act_node for every ready lane whose next request is the same.
                            served = {CMW{1'b0}};
                            for (l = 0; l < N; l = l + 1) begin
                                {lact, lact_stack, lact_k, lact_node} = `RT_ACTION;
                                if (lact == ACT_FETCH && lact_node == act_node) begin
                                    if (a_lane_cur_sp[(s*N+l)*SPW +: SPW] != {SPW{1'b0}}) begin
                                        a_lane_cur_sp[(s*N+l)*SPW +: SPW] = a_lane_cur_sp[(s*N+l)*SPW +: SPW] - ONE_SPW;
                                    end else begin
                                        a_lane_other_sp[(s*N+l)*SPW +: SPW] = a_lane_other_sp[(s*N+l)*SPW +: SPW] - ONE_SPW;
                                        a_lane_cur_treelet[(s*N+l)*TW +: TW] = act_node[E-1:TSH+5];
                                    end
                                    a_lane_node_valid[(s*N+l)] = 1'b1;
                                    a_lane_node[(s*N+l)*E +: E] = act_node;
                                    a_lane_node_leader[(s*N+l)*LB +: LB] = lead;
                                    a_lane_chunks_returned[(s*N+l)*4 +: 4] = 4'd0;
                                    served = served + ONE_CMW;
                                end
                            end
                            o_count_merged = served - ONE_CMW;
                            if (act_node[1:0] != 2'd0) begin
                                a_split_valid = 1'b1;
                                a_split_tag = {sk, lead};
                                a_split_node = act_node;
                                a_split_chunk = 2'd1;
                            end
                            o_req_valid = 1'b1;
                            o_req_kind = RQ_LOAD;
                            o_req_tag = {sk, lead};
                            o_req_address = act_node[E-1:5];
                            o_count_request = 1'b1;
                        end
                        for (l = 0; l < N; l = l + 1) begin
                            if (found && l[LB-1:0] == lead && act == ACT_SPILL) begin
                                sp_idx = act_stack ? a_lane_other_spilled[(s*N+l)*SCW +: SCW]
                                                   : a_lane_cur_spilled[(s*N+l)*SCW +: SCW];
                                if (sp_idx >= SPC_W) begin
                                    {a_errors, a_first_error} = raised(a_errors, a_first_error, E_SPILL_FULL, sk, lead, a_lane_ray_id[(s*N+l)*RB +: RB],
                                            {{(64-SCW){1'b0}}, sp_idx} + 64'd1, SPC64);
                                end else begin
                                    // Store the act_k oldest entries; the rest move down.
                                    for (j = 0; j < D4; j = j + 1) begin
                                        if (j < {29'd0, act_k}) begin
                                            w = {1'b1, {(63-E){1'b0}},
                                                 act_stack ? a_other_stack[((s*N+l)*D+j)*E +: E]
                                                           : a_cur_stack[((s*N+l)*D+j)*E +: E]};
                                            o_req_data[j*64 +: 64] = w;
                                        end
                                    end
                                    for (sh = 1; sh <= 4; sh = sh + 1) begin
                                        if ({29'd0, act_k} == sh) begin
                                            for (j = 0; j + sh < D; j = j + 1) begin
                                                if (act_stack)
                                                    a_other_stack[((s*N+l)*D+j)*E +: E] = a_other_stack[((s*N+l)*D+j+sh)*E +: E];
                                                else
                                                    a_cur_stack[((s*N+l)*D+j)*E +: E] = a_cur_stack[((s*N+l)*D+j+sh)*E +: E];
                                            end
                                        end
                                    end
                                    if (act_stack) begin
                                        a_lane_other_sp[(s*N+l)*SPW +: SPW] = a_lane_other_sp[(s*N+l)*SPW +: SPW] - {{(SPW-3){1'b0}}, act_k};
                                        a_lane_other_spilled[(s*N+l)*SCW +: SCW] = sp_idx + ONE_SCW;
                                    end else begin
                                        a_lane_cur_sp[(s*N+l)*SPW +: SPW] = a_lane_cur_sp[(s*N+l)*SPW +: SPW] - {{(SPW-3){1'b0}}, act_k};
                                        a_lane_cur_spilled[(s*N+l)*SCW +: SCW] = sp_idx + ONE_SCW;
                                    end
                                    o_req_valid = 1'b1;
                                    o_req_kind = RQ_SPILL;
                                    o_req_tag = {sk, lead};
                                    addr_ray = a_lane_ray_id[(s*N+l)*RB +: RB];
                                    addr_index = sp_idx;
                                    addr_needed = 1'b1;
                                    o_count_spill = 1'b1;
                                end
                            end
                            if (found && l[LB-1:0] == lead && act == ACT_FILL) begin
                                sp_idx = act_stack ? a_lane_other_spilled[(s*N+l)*SCW +: SCW]
                                                   : a_lane_cur_spilled[(s*N+l)*SCW +: SCW];
                                a_lane_filling[(s*N+l)*2 +: 2] = act_stack ? 2'd2 : 2'd1;
                                o_req_valid = 1'b1;
                                o_req_kind = RQ_FILL;
                                o_req_tag = {sk, lead};
                                addr_ray = a_lane_ray_id[(s*N+l)*RB +: RB];
                                addr_index = sp_idx - ONE_SCW;
                                addr_needed = 1'b1;
                                o_count_fill = 1'b1;
                            end
                        end
                    end
                end
            end
        end
    end

    if (addr_needed) o_req_address = spill_address(addr_ray, act_stack, addr_index);

    // 4. Every intersection delay counts down.
    for (L = 0; L < NL; L = L + 1) begin
        if (a_lane_delay[L*DW +: DW] != {DW{1'b0}})
            a_lane_delay[L*DW +: DW] = a_lane_delay[L*DW +: DW] - ONE_DW;
    end

    // 5. The head of the response FIFO is popped and delivered.
    if (a_fifo_count != {FCW{1'b0}}) begin
        entry = {FEW{1'b0}};
        for (j = 0; j < FD; j = j + 1)
            if (a_fifo_head == j[FPW-1:0]) entry = a_resp_fifo[j*FEW +: FEW];
        a_fifo_head = (a_fifo_head == FD_LAST) ? {FPW{1'b0}} : a_fifo_head + ONE_FPW;
        a_fifo_count = a_fifo_count - ONE_FCW;
        {r_addr, r_tag, r_data} = entry;
        pop_valid = 1'b1;
        pop_slot = r_tag[TGW-1:LB];
        pop_leader = r_tag[LB-1:0];
        pop_address = r_addr;
        found = 1'b0;  // the tag names a valid slot
        for (s = 0; s < S; s = s + 1)
            if (pop_slot == s[SB-1:0] && a_slot_valid[s]) found = 1'b1;
        if (!found) begin
            {a_errors, a_first_error} = raised(a_errors, a_first_error, E_UNMATCHED, pop_slot, pop_leader, {RB{1'b0}}, {{(64-AB){1'b0}}, r_addr}, 64'd0);
        end else if ({1'b0, r_addr} >= SPILL_LO && {1'b0, r_addr} < SPILL_HI) begin
            // A stack fill for the leader lane: the address it expects.
            for (s = 0; s < S; s = s + 1) begin
                for (l = 0; l < N; l = l + 1) begin
                    if (pop_slot == s[SB-1:0] && pop_leader == l[LB-1:0]) begin
                        addr_ray = a_lane_ray_id[(s*N+l)*RB +: RB];
                        act_stack = a_lane_filling[(s*N+l)*2 +: 2] == 2'd2;
                        addr_index = (act_stack ? a_lane_other_spilled[(s*N+l)*SCW +: SCW]
                                                : a_lane_cur_spilled[(s*N+l)*SCW +: SCW]) - ONE_SCW;
                    end
                end
            end
            fill_expect = spill_address(addr_ray, act_stack, addr_index);
            found = 1'b0;  // matched
            for (s = 0; s < S; s = s + 1) begin
                for (l = 0; l < N; l = l + 1) begin
                    if (pop_slot == s[SB-1:0] && pop_leader == l[LB-1:0]
                        && a_lane_filling[(s*N+l)*2 +: 2] != 2'd0) begin
                        two = a_slot_order[s*2 +: 2] != ORD_RAY;
                        act_stack = a_lane_filling[(s*N+l)*2 +: 2] == 2'd2;
                        sp_idx = act_stack ? a_lane_other_spilled[(s*N+l)*SCW +: SCW]
                                           : a_lane_cur_spilled[(s*N+l)*SCW +: SCW];
                        // Entries: the leading valid 64-bit slots (defined kinds).
                        cnt = 3'd0;
                        stop_scan = 1'b0;
                        for (j = 0; j < 4; j = j + 1) begin
                            w = r_data[j*64 +: 64];
                            if (!stop_scan && w[63] && w[4:2] < 3'd6) cnt = cnt + 3'd1;
                            else stop_scan = 1'b1;
                        end
                        if (sp_idx != {SCW{1'b0}}
                            && r_addr == fill_expect
                            && (act_stack ? a_lane_other_sp[(s*N+l)*SPW +: SPW] : a_lane_cur_sp[(s*N+l)*SPW +: SPW]) == {SPW{1'b0}}
                            && cnt != 3'd0 && {29'd0, cnt} <= D) begin
                            found = 1'b1;
                            for (j = 0; j < D4; j = j + 1) begin
                                if (j < {29'd0, cnt}) begin
                                    if (act_stack) a_other_stack[((s*N+l)*D+j)*E +: E] = r_data[j*64 +: E];
                                    else a_cur_stack[((s*N+l)*D+j)*E +: E] = r_data[j*64 +: E];
                                end
                            end
                            if (act_stack) begin
                                a_lane_other_sp[(s*N+l)*SPW +: SPW] = {{(SPW-3){1'b0}}, cnt};
                                a_lane_other_spilled[(s*N+l)*SCW +: SCW] = sp_idx - ONE_SCW;
                            end else begin
                                a_lane_cur_sp[(s*N+l)*SPW +: SPW] = {{(SPW-3){1'b0}}, cnt};
                                a_lane_cur_spilled[(s*N+l)*SCW +: SCW] = sp_idx - ONE_SCW;
                            end
                            a_lane_filling[(s*N+l)*2 +: 2] = 2'd0;
                            if (act_stack && two && a_lane_cur_sp[(s*N+l)*SPW +: SPW] == {SPW{1'b0}}
                                && a_lane_cur_spilled[(s*N+l)*SCW +: SCW] == {SCW{1'b0}}) begin
                                if (a_slot_order[s*2 +: 2] == ORD_STOP) a_lane_status[(s*N+l)*2 +: 2] = ST_PARKED;
                                fill_event[l] = 1'b1;
                                for (j = 0; j < 4; j = j + 1)
                                    if (j + 1 == {29'd0, cnt})
                                        fill_treelet[l*TW +: TW] = r_data[j*64 + TSH + 5 +: TW];
                            end
                        end
                    end
                end
            end
            if (!found)
                {a_errors, a_first_error} = raised(a_errors, a_first_error, E_UNMATCHED, pop_slot, pop_leader, {RB{1'b0}}, {{(64-AB){1'b0}}, r_addr}, 64'd0);
        end else begin
            // A node chunk for the lanes whose request it answers.
            pop_node = 1'b1;
            for (s = 0; s < S; s = s + 1) begin
                if (pop_slot == s[SB-1:0]) begin
                    for (l = 0; l < N; l = l + 1) begin
                        naddr = a_lane_node[(s*N+l)*E+5 +: AB];
                        nchunks = {1'b0, a_lane_node[(s*N+l)*E +: 2]} + 3'd1;
                        offset = {1'b0, r_addr} - {1'b0, naddr};
                        full = (4'd1 << nchunks) - 4'd1;
                        if (a_lane_node_valid[(s*N+l)] && a_lane_node_leader[(s*N+l)*LB +: LB] == pop_leader
                            && r_addr >= naddr && offset[4:0] == 5'd0
                            && offset[AB:5] < {{(AB-7){1'b0}}, nchunks}
                            && !a_lane_chunks_returned[(s*N+l)*4 + {30'd0, offset[6:5]}]) begin
                            node_matched = 1'b1;
                            for (j = 0; j < 4; j = j + 1) begin
                                if (offset[6:5] == j[1:0]) begin
                                    a_lane_chunks_returned[(s*N+l)*4 + j] = 1'b1;
                                    a_node_buffer[((s*N+l)*4 + j)*256 +: 256] = r_data;
                                end
                            end
                            if (a_lane_chunks_returned[(s*N+l)*4 +: 4] == full) begin
                                a_lane_node_valid[(s*N+l)] = 1'b0;
                                test_now[l] = 1'b1;
                                dp_ray[l*256 +: 256] = a_lane_ray_words[(s*N+l)*256 +: 256];
                                dp_best_valid[l] = a_lane_hit_valid[(s*N+l)];
                                dp_best[l*128 +: 128] = a_lane_hit[(s*N+l)*128 +: 128];
                                dp_node[l*E +: E] = a_lane_node[(s*N+l)*E +: E];
                                dp_data[l*1024 +: 1024] = a_node_buffer[(s*N+l)*1024 +: 1024];
                            end
                        end
                    end
                end
            end
        end
    end
end

// ---- Stages 5 (test write-back), 6 and 7 --------------------------------------------------------
reg [N-1:0] o_boundary_valid;
reg [SB-1:0] o_boundary_slot;
reg [N*RB-1:0] o_boundary_ray_id;
reg [N*TW-1:0] o_boundary_treelet;
reg o_released_valid;
reg [SB-1:0] o_released_slot;
reg [N-1:0] o_released_mask;
reg [6*CTW-1:0] o_tests;        // tests per node kind, kind k in bits [k*CTW +: CTW]
reg [CTW-1:0] o_count_tests_treelet_order;
reg [CTW-1:0] o_count_hits;


always @* begin : p_back
    integer s, l, k, j, c;
    reg [CW-1:0] nch;
    reg [CHW-1:0] child;
    reg [63:0] caddr;
    reg [2:0] ckind;
    reg [7:0] cchunks;
    reg accepted;
    reg two;
    reg [2:0] kind;
    reg [127:0] h;
    reg [63:0] b;
    reg finished;
    reg [7:0] nvalid;
    reg [15:0] lim;
    reg bad;
    reg any_bad;
    reg [LB-1:0] bad_lane;
    reg [RB-1:0] bad_ray;
    reg [SB-1:0] target;
    reg ok;
    reg [SPW-1:0] csp;
    reg [SPW-1:0] osp;
    reg [SCW-1:0] csl;
    reg [SCW-1:0] osl;
    reg [E-1:0] ent;
    nch = {CW{1'b0}};
    child = {CHW{1'b0}};
    caddr = 64'd0;
    ckind = 3'd0;
    cchunks = 8'd0;
    accepted = 1'b0;
    two = 1'b0;
    kind = 3'd0;
    h = 128'd0;
    b = 64'd0;
    finished = 1'b0;
    nvalid = 8'd0;
    lim = 16'd0;
    bad = 1'b0;
    any_bad = 1'b0;
    bad_lane = {LB{1'b0}};
    bad_ray = {RB{1'b0}};
    target = {SB{1'b0}};
    ok = 1'b0;
    csp = {SPW{1'b0}};
    osp = {SPW{1'b0}};
    csl = {SCW{1'b0}};
    osl = {SCW{1'b0}};
    ent = {E{1'b0}};
${BACK_COPIES}
    cur_stack_d = a_cur_stack;
    other_stack_d = a_other_stack;
    node_buffer_d = a_node_buffer;
    resp_fifo_d = a_resp_fifo;
    o_boundary_valid = {N{1'b0}};
    o_boundary_slot = {SB{1'b0}};
    o_boundary_ray_id = {N*RB{1'b0}};
    o_boundary_treelet = {N*TW{1'b0}};
    o_released_valid = 1'b0;
    o_released_slot = {SB{1'b0}};
    o_released_mask = {N{1'b0}};
    o_tests = {6*CTW{1'b0}};
    o_count_tests_treelet_order = {CTW{1'b0}};
    o_count_hits = {CTW{1'b0}};

    // 5. (continued) Fill boundaries, then the tests of the lanes whose node completed.
    for (s = 0; s < S; s = s + 1) begin
        if (pop_valid && pop_slot == s[SB-1:0]) begin
            two = slot_order_d[s*2 +: 2] != ORD_RAY;
            for (l = 0; l < N; l = l + 1) begin
                if (fill_event[l]) begin
                    o_boundary_valid[l] = 1'b1;
                    o_boundary_slot = pop_slot;
                    o_boundary_ray_id[l*RB +: RB] = lane_ray_id_d[(s*N+l)*RB +: RB];
                    o_boundary_treelet[l*TW +: TW] = fill_treelet[l*TW +: TW];
                end
                if (test_now[l]) begin
                    kind = lane_node_d[(s*N+l)*E+2 +: 3];
                    for (k = 0; k < 6; k = k + 1)
                        if (kind == k[2:0]) o_tests[k*CTW +: CTW] = o_tests[k*CTW +: CTW] + ONE_CTW;
                    if (slot_order_d[s*2 +: 2] == ORD_STOP)
                        o_count_tests_treelet_order = o_count_tests_treelet_order + ONE_CTW;
                    h = dp_hit[l*128 +: 128];
                    b = lane_hit_d[(s*N+l)*128 +: 64];
                    accepted = dp_hit_valid[l] && (!lane_hit_valid_d[(s*N+l)] || f32_lt(h[31:0], b[31:0])
                        || (f32_eq(h[31:0], b[31:0]) && h[63:32] < b[63:32]));
                    if (accepted) begin
                        lane_hit_d[(s*N+l)*128 +: 128] = h;
                        lane_hit_valid_d[(s*N+l)] = 1'b1;
                        lane_store_pending_d[(s*N+l)] = 1'b1;
                        if (kind == K_TRIANGLE) o_count_hits = o_count_hits + ONE_CTW;
                    end
                    lane_delay_d[(s*N+l)*DW +: DW] = latency(kind, accepted);
                    nch = dp_child_count[l*CW +: CW];
                    if (nch > R_CW)
                        {errors_d, first_error_d} = raised(errors_d, first_error_d, E_BAD_CHILD, pop_slot, l[LB-1:0], lane_ray_id_d[(s*N+l)*RB +: RB],
                                {{(64-CW){1'b0}}, nch}, R64);
                    // Children pushed last first, so the first in visit order ends on top.
                    for (c = R - 1; c >= 0; c = c - 1) begin
                        if (c < {{(32-CW){1'b0}}, nch}) begin
                            child = dp_children[(l*R+c)*CHW +: CHW];
                            caddr = child[CHW-1:11];
                            ckind = child[10:8];
                            cchunks = child[7:0];
                            if (bad_node(caddr, cchunks)) begin
                                {errors_d, first_error_d} = raised(errors_d, first_error_d, E_BAD_CHILD, pop_slot, l[LB-1:0], lane_ray_id_d[(s*N+l)*RB +: RB],
                                        caddr, SPACE64);
                            end else begin
                                ent = {caddr[AB-1:0], ckind, cchunks[1:0] - 2'd1};
                                if (!two || caddr[AB-1:TSH] == lane_cur_treelet_d[(s*N+l)*TW +: TW]) begin
                                    csp = lane_cur_sp_d[(s*N+l)*SPW +: SPW];
                                    if (csp < D_SPW) begin
                                        for (j = 0; j < D; j = j + 1)
                                            if (csp == j[SPW-1:0]) cur_stack_d[((s*N+l)*D+j)*E +: E] = ent;
                                        lane_cur_sp_d[(s*N+l)*SPW +: SPW] = csp + ONE_SPW;
                                    end
                                end else begin
                                    osp = lane_other_sp_d[(s*N+l)*SPW +: SPW];
                                    if (osp < D_SPW) begin
                                        for (j = 0; j < D; j = j + 1)
                                            if (osp == j[SPW-1:0]) other_stack_d[((s*N+l)*D+j)*E +: E] = ent;
                                        lane_other_sp_d[(s*N+l)*SPW +: SPW] = osp + ONE_SPW;
                                    end
                                end
                            end
                        end
                    end
                    csp = lane_cur_sp_d[(s*N+l)*SPW +: SPW];
                    osp = lane_other_sp_d[(s*N+l)*SPW +: SPW];
                    csl = lane_cur_spilled_d[(s*N+l)*SCW +: SCW];
                    osl = lane_other_spilled_d[(s*N+l)*SCW +: SCW];
                    finished = csp == {SPW{1'b0}} && csl == {SCW{1'b0}} && osp == {SPW{1'b0}}
                        && osl == {SCW{1'b0}};
                    if (finished) begin
                        lane_status_d[(s*N+l)*2 +: 2] = ST_DONE;
                    end else if (two && csp == {SPW{1'b0}} && csl == {SCW{1'b0}} && osp != {SPW{1'b0}}) begin
                        // A treelet boundary: report the treelet of the other stack's top.
                        if (slot_order_d[s*2 +: 2] == ORD_STOP) lane_status_d[(s*N+l)*2 +: 2] = ST_PARKED;
                        o_boundary_valid[l] = 1'b1;
                        o_boundary_slot = pop_slot;
                        o_boundary_ray_id[l*RB +: RB] = lane_ray_id_d[(s*N+l)*RB +: RB];
                        for (j = 0; j < D; j = j + 1)
                            if (osp == j[SPW-1:0] + ONE_SPW)
                                o_boundary_treelet[l*TW +: TW] = other_stack_d[((s*N+l)*D+j)*E + TSH + 5 +: TW];
                    end
                end
            end
        end
    end
    if (pop_node && !node_matched)
        {errors_d, first_error_d} = raised(errors_d, first_error_d, E_UNMATCHED, pop_slot, pop_leader, {RB{1'b0}}, {{(64-AB){1'b0}}, pop_address}, 64'd0);

    // 6. This cycle's responses enter the FIFO.
    nvalid = 8'd0;
    ${COUNT_RESP}
    lim = {{(16-FCW){1'b0}}, o_resp_free};
    if (lim > {8'd0, RP_8}) lim = {8'd0, RP_8};
    ${PUSH_RESP}

    // 7. Warp issue, then the treelet controller's stop and repack.
    if (issue_valid) begin
        any_bad = 1'b0;
        bad_lane = {LB{1'b0}};
        bad_ray = {RB{1'b0}};
        for (l = 0; l < N; l = l + 1) begin
            bad = 1'b0;
            csp = issue_cur_sp[l*SPW +: SPW];
            osp = issue_other_sp[l*SPW +: SPW];
            if (issue_cur_spilled[l*SCW +: SCW] > SPC_W || issue_other_spilled[l*SCW +: SCW] > SPC_W
                || csp > D_SPW || osp > D_SPW)
                bad = 1'b1;
            for (j = 0; j < D; j = j + 1) begin
                ent = issue_cur_stack[(l*D+j)*E +: E];
                if (j[SPW-1:0] < csp && bad_node({{(64-AB){1'b0}}, ent[E-1:5]}, {6'd0, ent[1:0]} + 8'd1))
                    bad = 1'b1;
                ent = issue_other_stack[(l*D+j)*E +: E];
                if (j[SPW-1:0] < osp && bad_node({{(64-AB){1'b0}}, ent[E-1:5]}, {6'd0, ent[1:0]} + 8'd1))
                    bad = 1'b1;
            end
            if (issue_active[l] && bad && !any_bad) begin
                any_bad = 1'b1;
                bad_lane = l[LB-1:0];
                bad_ray = issue_ray_id[l*RB +: RB];
            end
        end
        if (any_bad) begin
            {errors_d, first_error_d} = raised(errors_d, first_error_d, E_BAD_ISSUE, {SB{1'b0}}, bad_lane, bad_ray, 64'd0, 64'd0);
        end else begin
            target = {SB{1'b0}};
            ok = 1'b0;
            if (issue_target == 2'd0) begin
                for (s = S - 1; s >= 0; s = s - 1)
                    if (free_mask[s]) begin
                        ok = 1'b1;
                        target = s[SB-1:0];
                    end
                if (!ok) {errors_d, first_error_d} = raised(errors_d, first_error_d, E_ISSUE_FULL, {SB{1'b0}}, {LB{1'b0}}, {RB{1'b0}}, S_PLUS1_64, S_64);
            end else if (issue_target == 2'd1) begin
                for (s = 0; s < S; s = s + 1)
                    if (issue_slot == s[SB-1:0] && free_mask[s]) ok = 1'b1;
                target = issue_slot;
                if (!ok) {errors_d, first_error_d} = raised(errors_d, first_error_d, E_BAD_COMMAND, issue_slot, {LB{1'b0}}, {RB{1'b0}}, 64'd1, 64'd0);
            end else if (issue_target == 2'd2) begin
                for (s = 0; s < S; s = s + 1) begin
                    if (issue_slot == s[SB-1:0] && slot_valid_d[s] && slot_held_d[s]) begin
                        ok = 1'b1;
                        for (l = 0; l < N; l = l + 1)
                            if (issue_active[l] && lane_status_d[(s*N+l)*2 +: 2] != ST_INACTIVE)
                                ok = 1'b0;
                    end
                end
                target = issue_slot;
                if (!ok) {errors_d, first_error_d} = raised(errors_d, first_error_d, E_BAD_COMMAND, issue_slot, {LB{1'b0}}, {RB{1'b0}}, 64'd2, 64'd0);
            end else begin
                {errors_d, first_error_d} = raised(errors_d, first_error_d, E_BAD_COMMAND, issue_slot, {LB{1'b0}}, {RB{1'b0}}, 64'd3, 64'd0);
            end
            if (ok) begin
                for (s = 0; s < S; s = s + 1) begin
                    if (target == s[SB-1:0]) begin
                        if (issue_target != 2'd2) begin
                            slot_valid_d[s] = 1'b1;
                            slot_held_d[s] = 1'b0;
                            slot_order_d[s*2 +: 2] = issue_order;
                            for (k = 0; k < S; k = k + 1)
                                if (age_count_d == k[SCNT-1:0]) age_order_d[k*SB +: SB] = target;
                            age_count_d = age_count_d + ONE_SCNT;
                        end else if (issue_last) begin
                            slot_held_d[s] = 1'b0;
                        end
                        for (l = 0; l < N; l = l + 1) begin
                            if (issue_active[l] || issue_target != 2'd2) begin
                                csp = issue_cur_sp[l*SPW +: SPW];
                                osp = issue_other_sp[l*SPW +: SPW];
                                csl = issue_cur_spilled[l*SCW +: SCW];
                                osl = issue_other_spilled[l*SCW +: SCW];
                                finished = csp == {SPW{1'b0}} && csl == {SCW{1'b0}}
                                    && osp == {SPW{1'b0}} && osl == {SCW{1'b0}};
                                lane_status_d[(s*N+l)*2 +: 2] = !issue_active[l] ? ST_INACTIVE
                                    : finished ? ST_DONE : ST_TRAVERSING;
                                lane_ray_id_d[(s*N+l)*RB +: RB] = issue_ray_id[l*RB +: RB];
                                lane_ray_words_d[(s*N+l)*256 +: 256] = issue_ray_words[l*256 +: 256];
                                lane_hit_valid_d[(s*N+l)] = issue_hit_valid[l];
                                lane_hit_d[(s*N+l)*128 +: 128] = issue_hit[l*128 +: 128];
                                lane_cur_treelet_d[(s*N+l)*TW +: TW] = issue_cur_treelet[l*TW +: TW];
                                lane_cur_sp_d[(s*N+l)*SPW +: SPW] = csp;
                                lane_other_sp_d[(s*N+l)*SPW +: SPW] = osp;
                                lane_cur_spilled_d[(s*N+l)*SCW +: SCW] = csl;
                                lane_other_spilled_d[(s*N+l)*SCW +: SCW] = osl;
                                cur_stack_d[(s*N+l)*D*E +: D*E] = issue_cur_stack[l*D*E +: D*E];
                                other_stack_d[(s*N+l)*D*E +: D*E] = issue_other_stack[l*D*E +: D*E];
                                lane_filling_d[(s*N+l)*2 +: 2] = 2'd0;
                                lane_node_valid_d[(s*N+l)] = 1'b0;
                                lane_node_d[(s*N+l)*E +: E] = {E{1'b0}};
                                lane_node_leader_d[(s*N+l)*LB +: LB] = {LB{1'b0}};
                                lane_chunks_returned_d[(s*N+l)*4 +: 4] = 4'd0;
                                lane_delay_d[(s*N+l)*DW +: DW] = {DW{1'b0}};
                                lane_store_pending_d[(s*N+l)] = 1'b0;
                            end
                        end
                    end
                end
            end
        end
    end
    if (stop_valid) begin
        ok = 1'b0;
        for (s = 0; s < S; s = s + 1) begin
            if (stop_slot == s[SB-1:0] && slot_valid_d[s]) begin
                ok = 1'b1;
                slot_order_d[s*2 +: 2] = ORD_STOP;
                for (l = 0; l < N; l = l + 1) begin
                    if (lane_status_d[(s*N+l)*2 +: 2] == ST_TRAVERSING && !lane_node_valid_d[(s*N+l)]
                        && lane_filling_d[(s*N+l)*2 +: 2] == 2'd0
                        && lane_cur_sp_d[(s*N+l)*SPW +: SPW] == {SPW{1'b0}}
                        && lane_cur_spilled_d[(s*N+l)*SCW +: SCW] == {SCW{1'b0}}
                        && lane_other_sp_d[(s*N+l)*SPW +: SPW] != {SPW{1'b0}})
                        lane_status_d[(s*N+l)*2 +: 2] = ST_PARKED;
                end
            end
        end
        if (!ok) {errors_d, first_error_d} = raised(errors_d, first_error_d, E_BAD_COMMAND, stop_slot, {LB{1'b0}}, {RB{1'b0}}, 64'd0, 64'd0);
    end
    if (repack_valid) begin
        for (s = 0; s < S; s = s + 1) begin
            if (repack_slot == s[SB-1:0] && slot_valid_d[s]) begin
                slot_held_d[s] = 1'b1;
                o_released_valid = 1'b1;
                o_released_slot = repack_slot;
                for (l = 0; l < N; l = l + 1) begin
                    if (lane_status_d[(s*N+l)*2 +: 2] == ST_DONE && !lane_node_valid_d[(s*N+l)]
                        && lane_filling_d[(s*N+l)*2 +: 2] == 2'd0
                        && lane_delay_d[(s*N+l)*DW +: DW] == {DW{1'b0}} && !lane_store_pending_d[(s*N+l)]) begin
                        o_released_mask[l] = 1'b1;
                        lane_status_d[(s*N+l)*2 +: 2] = ST_INACTIVE;
                        lane_ray_id_d[(s*N+l)*RB +: RB] = {RB{1'b0}};
                        lane_ray_words_d[(s*N+l)*256 +: 256] = 256'd0;
                        lane_hit_valid_d[(s*N+l)] = 1'b0;
                        lane_hit_d[(s*N+l)*128 +: 128] = 128'd0;
                        lane_cur_treelet_d[(s*N+l)*TW +: TW] = {TW{1'b0}};
                        lane_cur_sp_d[(s*N+l)*SPW +: SPW] = {SPW{1'b0}};
                        lane_other_sp_d[(s*N+l)*SPW +: SPW] = {SPW{1'b0}};
                        lane_cur_spilled_d[(s*N+l)*SCW +: SCW] = {SCW{1'b0}};
                        lane_other_spilled_d[(s*N+l)*SCW +: SCW] = {SCW{1'b0}};
                    end
                end
            end
        end
    end
end

// ---- Register-only status ports -----------------------------------------------------------------
reg [S-1:0] o_status_valid;
reg [S-1:0] o_status_held;
reg [S-1:0] o_status_quiescent;
reg [S*2-1:0] o_status_order;
reg [S*SNW-1:0] o_status_traversing;
reg [S*SNW-1:0] o_status_busy;
reg [S*SNW-1:0] o_status_distinct;
reg [S*N-1:0] o_status_inactive;
always @* begin : p_status
    integer s, l, m;
    reg [SNW-1:0] trav;
    reg [SNW-1:0] kept;
    reg [SNW-1:0] ndist;
    reg [N-1:0] has;
    reg [N*TW-1:0] nxt;
    reg busy;
    reg any_busy;
    reg seen;
    reg [1:0] st;
    trav = {SNW{1'b0}};
    kept = {SNW{1'b0}};
    ndist = {SNW{1'b0}};
    has = {N{1'b0}};
    nxt = {N*TW{1'b0}};
    busy = 1'b0;
    any_busy = 1'b0;
    seen = 1'b0;
    st = ST_INACTIVE;
    o_status_valid = {S{1'b0}};
    o_status_held = {S{1'b0}};
    o_status_quiescent = {S{1'b0}};
    o_status_order = {S*2{1'b0}};
    o_status_traversing = {S*SNW{1'b0}};
    o_status_busy = {S*SNW{1'b0}};
    o_status_distinct = {S*SNW{1'b0}};
    o_status_inactive = {S*N{1'b0}};
    for (s = 0; s < S; s = s + 1) begin
        if (slot_valid_q[s]) begin
            o_status_valid[s] = 1'b1;
            o_status_held[s] = slot_held_q[s];
            o_status_order[s*2 +: 2] = slot_order_q[s*2 +: 2];
            trav = {SNW{1'b0}};
            kept = {SNW{1'b0}};
            ndist = {SNW{1'b0}};
            any_busy = 1'b0;
            has = {N{1'b0}};
            nxt = {N*TW{1'b0}};
            for (l = 0; l < N; l = l + 1) begin
                st = lane_status_q[(s*N+l)*2 +: 2];
                busy = st == ST_TRAVERSING || lane_node_valid_q[(s*N+l)] || lane_filling_q[(s*N+l)*2 +: 2] != 2'd0
                    || lane_delay_q[(s*N+l)*DW +: DW] != {DW{1'b0}} || lane_store_pending_q[(s*N+l)];
                if (busy) any_busy = 1'b1;
                if (st == ST_TRAVERSING) trav = trav + ONE_SNW;
                if (st == ST_TRAVERSING || st == ST_PARKED || (st == ST_DONE && busy))
                    kept = kept + ONE_SNW;
                if (st == ST_INACTIVE) o_status_inactive[s*N + l] = 1'b1;
                // The traversing lane's next node, if on chip.
                if (st == ST_TRAVERSING) begin
                    for (m = 0; m < D; m = m + 1) begin
                        if (lane_cur_sp_q[(s*N+l)*SPW +: SPW] == m[SPW-1:0] + ONE_SPW) begin
                            has[l] = 1'b1;
                            nxt[l*TW +: TW] = cur_stack_q[(((s*N+l)*D+m)*E) + TSH + 5 +: TW];
                        end
                        if (lane_cur_sp_q[(s*N+l)*SPW +: SPW] == {SPW{1'b0}}
                            && lane_cur_spilled_q[(s*N+l)*SCW +: SCW] == {SCW{1'b0}}
                            && lane_other_sp_q[(s*N+l)*SPW +: SPW] == m[SPW-1:0] + ONE_SPW) begin
                            has[l] = 1'b1;
                            nxt[l*TW +: TW] = other_stack_q[(((s*N+l)*D+m)*E) + TSH + 5 +: TW];
                        end
                    end
                end
            end
            if (slot_order_q[s*2 +: 2] == 2'd1) begin
                for (l = 0; l < N; l = l + 1) begin
                    seen = 1'b0;
                    for (m = 0; m < l; m = m + 1)
                        if (has[m] && nxt[m*TW +: TW] == nxt[l*TW +: TW]) seen = 1'b1;
                    if (has[l] && !seen) ndist = ndist + ONE_SNW;
                end
            end
            o_status_traversing[s*SNW +: SNW] = trav;
            o_status_busy[s*SNW +: SNW] = kept;
            o_status_distinct[s*SNW +: SNW] = ndist;
            o_status_quiescent[s] = !any_busy;
        end
    end
end

// ---- Outputs ------------------------------------------------------------------------------------
${OUTPUTS}
`undef RT_ACTION
