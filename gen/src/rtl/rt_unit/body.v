// ---- Sizes and constants of this configuration -------------------------------------------------
/* verilator lint_off UNUSEDPARAM */
${PARAMS}
${COMMON}
/* verilator lint_on UNUSEDPARAM */
// ---- The response FIFO, in flip-flops (the description's memory) --------------------------------
reg [FD*FEW-1:0] resp_fifo_q;     // entry i: {address, tag, data} in bits [i*FEW +: FEW]
reg [FD*FEW-1:0] resp_fifo_d;
always @(posedge clk) begin : p_storage
    integer i;
    if (rst) begin
        for (i = 0; i < FD; i = i + 1) resp_fifo_q[i*FEW +: FEW] <= {FEW{1'b0}};
    end else begin
        resp_fifo_q <= resp_fifo_d;
    end
end

// ---- The lanes ----------------------------------------------------------------------------------
// One rt_unit_lane per lane of the warp buffer holds that lane's registers (the description's
// `lane_<field>`, lane L's in bits [L*W +: W] of `lane_<field>_q`; its stacks' SRAM rings
// inside) and computes their next state from the slot-level decisions below; its other
// results come back as `l_<name>`, lane L's in bits [L*W +: W].
/* verilator lint_off UNUSEDSIGNAL */
${LANE_STATE}
/* verilator lint_on UNUSEDSIGNAL */
wire [NL-1:0] l_busy;
wire [NL*(E+6)-1:0] l_act;
wire [NL*SCW-1:0] l_act_index;
wire [NL-1:0] l_next_valid;
wire [NL*TW-1:0] l_next_treelet;
wire [NL-1:0] l_done_active;
wire [NL-1:0] l_done_parked;
wire [NL*RD*E-1:0] l_done_cur_stack;
wire [NL*RD*E-1:0] l_done_other_stack;
wire [NL*256-1:0] l_spill_data;
wire [NL*RB-1:0] l_fx_ray;
wire [NL-1:0] l_fx_stack;
wire [NL*SCW-1:0] l_fx_index;
wire [NL-1:0] l_fill_ok;
wire [NL-1:0] l_node_match;
wire [NL*E-1:0] l_dp_node;
wire [NL*2-1:0] l_node_chunk;
wire [NL-1:0] l_tested;
wire [NL*3-1:0] l_test_kind;
wire [NL-1:0] l_new_hit;
wire [NL-1:0] l_err_child;
wire [NL*64-1:0] l_err_value;
wire [NL*64-1:0] l_err_limit;
wire [NL-1:0] l_boundary_valid;
wire [NL*TW-1:0] l_boundary_treelet;
wire [NL*2-1:0] l_status_tested;
wire [NL-1:0] l_released;

// Slot-level decisions for the lanes.
reg [S-1:0] slot_two;             // the slot's warp keeps two stacks (treelet orders)
reg [S-1:0] slot_stopped;         // ... and is stopped (treelet-stationary)
reg [S-1:0] complete;             // stage 2: the slot's warp completes
reg [NL-1:0] store_sel;           // stage 3: the lane's hit-record store is sent
reg [S-1:0] merge;                // the slot's leader fetches lead_node; its ready lanes merge
reg [E-1:0] lead_node;
reg [LB-1:0] lead;
reg [NL-1:0] lead_me;             // the scheduler's leader lane
reg pop_fill;                     // stage 5: the popped response is a stack fill for a valid slot
reg pop_node;                     // ... or a node chunk for a valid slot
reg [SB-1:0] pop_slot;
reg [LB-1:0] pop_leader;
reg [AB-1:0] pop_address;
reg [255:0] pop_data;
reg [NL-1:0] pop_fill_lane;       // the fill's lane
reg [S-1:0] pop_node_slot;        // the chunk's slot
reg [AB-1:0] fill_expect;         // the fill's expected address
reg [NL-1:0] load;                // stage 7: the issue or the lane write loads the lane from the bus
reg [NL-1:0] write_here;          // ... the lane write (the lane stays inactive, written)
reg [NL-1:0] wake;                // ... the issue enters the lane's written record
// Per lane: it holds nothing (inactive, no written record), where an append or a lane write may
// put a ray.
wire [NL-1:0] lane_empty;
reg [S-1:0] stop_here;
reg [S-1:0] repack_here;

// The intersection datapath, one per lane index, tests the node of that lane of the popped
// response's slot (a black box outside the RT unit's control).
reg [N*256-1:0] dp_ray;
reg [N-1:0] dp_best_valid;
reg [N*128-1:0] dp_best;
reg [N*E-1:0] dp_node;
reg [N*1024-1:0] dp_data;
wire [N*CW-1:0] dp_child_count;
wire [N*R*CHW-1:0] dp_children;
wire [N-1:0] dp_hit_valid;
wire [N*128-1:0] dp_hit;
genvar gl, gs;
generate
    for (gs = 0; gs < NL; gs = gs + 1) begin : g_empty
        assign lane_empty[gs] = l_status_tested[gs*2 +: 2] == ST_INACTIVE && !lane_written_q[gs];
    end
endgenerate
generate
    for (gl = 0; gl < N; gl = gl + 1) begin : g_datapath
        rt_datapath #(.AB(AB), .E(E), .R(R), .LANE(gl)) u_datapath (
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
    for (gs = 0; gs < S; gs = gs + 1) begin : g_slot
        for (gl = 0; gl < N; gl = gl + 1) begin : g_lane
            localparam L = gs * N + gl;
            rt_unit_lane u_lane (
                .clk(clk),
                .rst(rst),
${LANE_CONNECT}
                .two(slot_two[gs]),
                .stopped(slot_stopped[gs]),
                .complete(complete[gs]),
                .store_sel(store_sel[L]),
                .merge(merge[gs]),
                .lead_node(lead_node),
                .lead(lead),
                .lead_me(lead_me[L]),
                .pop_fill_here(pop_fill_lane[L]),
                .pop_node_here(pop_node_slot[gs]),
                .pop_leader(pop_leader),
                .pop_address(pop_address),
                .pop_data(pop_data),
                .fill_expect(fill_expect),
                .dp_child_count(dp_child_count[gl*CW +: CW]),
                .dp_children(dp_children[gl*R*CHW +: R*CHW]),
                .dp_hit_valid(dp_hit_valid[gl]),
                .dp_hit(dp_hit[gl*128 +: 128]),
                .load(load[L]),
                .write_here(write_here[L]),
                .wake(wake[L]),
                .issue_active(issue_active[gl]),
                .issue_ray_id(issue_ray_id[gl*RB +: RB]),
                .issue_ray_words(issue_ray_words[gl*256 +: 256]),
                .issue_occlusion(issue_occlusion[gl]),
                .issue_hit_valid(issue_hit_valid[gl]),
                .issue_hit(issue_hit[gl*128 +: 128]),
                .issue_cur_treelet(issue_cur_treelet[gl*TW +: TW]),
                .issue_cur_sp(issue_cur_sp[gl*RSPW +: RSPW]),
                .issue_other_sp(issue_other_sp[gl*RSPW +: RSPW]),
                .issue_cur_spilled(issue_cur_spilled[gl*SCW +: SCW]),
                .issue_other_spilled(issue_other_spilled[gl*SCW +: SCW]),
                .issue_cur_stack(issue_cur_stack[gl*RD*E +: RD*E]),
                .issue_other_stack(issue_other_stack[gl*RD*E +: RD*E]),
                .stop_here(stop_here[gs]),
                .repack_here(repack_here[gs]),
                .busy(l_busy[L]),
                .act(l_act[L*(E+6) +: E+6]),
                .act_index(l_act_index[L*SCW +: SCW]),
                .next_valid(l_next_valid[L]),
                .next_treelet(l_next_treelet[L*TW +: TW]),
                .done_active(l_done_active[L]),
                .done_parked(l_done_parked[L]),
                .done_cur_stack(l_done_cur_stack[L*RD*E +: RD*E]),
                .done_other_stack(l_done_other_stack[L*RD*E +: RD*E]),
                .spill_data(l_spill_data[L*256 +: 256]),
                .fx_ray(l_fx_ray[L*RB +: RB]),
                .fx_stack(l_fx_stack[L]),
                .fx_index(l_fx_index[L*SCW +: SCW]),
                .fill_ok(l_fill_ok[L]),
                .node_match(l_node_match[L]),
                .node_chunk(l_node_chunk[L*2 +: 2]),
                .dp_node(l_dp_node[L*E +: E]),
                .tested(l_tested[L]),
                .test_kind(l_test_kind[L*3 +: 3]),
                .new_hit(l_new_hit[L]),
                .err_child(l_err_child[L]),
                .err_value(l_err_value[L*64 +: 64]),
                .err_limit(l_err_limit[L*64 +: 64]),
                .boundary_valid(l_boundary_valid[L]),
                .boundary_treelet(l_boundary_treelet[L*TW +: TW]),
                .status_tested(l_status_tested[L*2 +: 2]),
                .released(l_released[L])
            );
        end
    end
endgenerate

// ---- Stages 1-5, slot level ---------------------------------------------------------------------
// Every decision here reads start-of-cycle state: a completing warp's lanes are quiescent (no
// request, no store), so the scheduler's choices do not depend on the completion before them.
reg [S-1:0] free_mask;            // slots free at the start of the cycle
reg [FCW-1:0] o_resp_free;
reg o_done_valid;
reg [SB-1:0] o_done_slot;
reg o_req_valid;
reg [AB-1:0] o_req_address;
reg [1:0] o_req_kind;
reg [TGW-1:0] o_req_tag;
reg [255:0] store_data;           // a hit-record store's data (a spill's comes from its lane)
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
// Slot-level registers after the front stages.
reg [S-1:0] slot_valid_f;
reg [S*SB-1:0] age_order_f;
reg [SCNT-1:0] age_count_f;
reg split_valid_f;
reg [TGW-1:0] split_tag_f;
reg [E-1:0] split_node_f;
reg [1:0] split_chunk_f;
reg [FPW-1:0] fifo_head_f;
reg [FCW-1:0] fifo_count_f;
reg [6:0] errors_f;
reg [FE_W-1:0] first_error_f;

always @* begin : p_front
    integer s, l, k, j;
    reg found;
    reg stop_scan;
    reg [SB-1:0] sk;
    reg [E+5:0] la;
    reg [1:0] act;
    reg act_stack;
    reg [E-1:0] act_node;
    reg [SCW-1:0] sp_idx;
    reg [RB-1:0] ray;
    reg [CMW-1:0] served;
    reg [1:0] st;
    reg [FEW-1:0] entry;
    reg [TGW-1:0] r_tag;
    /* verilator lint_off UNUSEDSIGNAL */
    reg [63:0] w;  // a hit record's offset (its top bits are 0)
    /* verilator lint_on UNUSEDSIGNAL */
    found = 1'b0;
    stop_scan = 1'b0;
    sk = {SB{1'b0}};
    la = {(E+6){1'b0}};
    sp_idx = {SCW{1'b0}};
    ray = {RB{1'b0}};
    served = {CMW{1'b0}};
    entry = {FEW{1'b0}};
    r_tag = {TGW{1'b0}};
    w = 64'd0;
    free_mask = ~slot_valid_q;
    o_resp_free = FD_W - fifo_count_q;
    for (s = 0; s < S; s = s + 1) begin
        slot_two[s] = slot_order_q[s*2 +: 2] != ORD_RAY;
        slot_stopped[s] = slot_order_q[s*2 +: 2] == ORD_STOP;
    end
    slot_valid_f = slot_valid_q;
    age_order_f = age_order_q;
    age_count_f = age_count_q;
    split_valid_f = split_valid_q;
    split_tag_f = split_tag_q;
    split_node_f = split_node_q;
    split_chunk_f = split_chunk_q;
    fifo_head_f = fifo_head_q;
    fifo_count_f = fifo_count_q;
    errors_f = errors_q;
    first_error_f = first_error_q;

    // 1. Statistics. (Counts here and below add each term's condition, a tree of adders,
    // not a branch per term, a chain of multiplexed increments.)
    o_count_warps = {CWW{1'b0}};
    o_count_active = {CAW{1'b0}};
    o_count_waiting = {CAW{1'b0}};
    o_count_done_lanes = {CAW{1'b0}};
    o_count_parked_lanes = {CAW{1'b0}};
    st = 2'd0;
    for (s = 0; s < S; s = s + 1) begin
        if (slot_valid_q[s]) begin
            o_count_warps = o_count_warps + ONE_CWW;
            for (l = 0; l < N; l = l + 1) begin
                st = lane_status_q[(s*N+l)*2 +: 2];
                o_count_active = o_count_active + {{(CAW-1){1'b0}}, st == ST_TRAVERSING};
                o_count_waiting = o_count_waiting + {{(CAW-1){1'b0}}, st == ST_TRAVERSING
                    && (lane_node_valid_q[s*N+l] || lane_filling_q[(s*N+l)*2 +: 2] != 2'd0)};
                o_count_done_lanes = o_count_done_lanes + {{(CAW-1){1'b0}}, st == ST_DONE};
                o_count_parked_lanes = o_count_parked_lanes + {{(CAW-1){1'b0}}, st == ST_PARKED};
            end
        end
    end

    // 2. Completion: the oldest warp, not held, whose lanes are all quiescent.
    complete = {S{1'b0}};
    o_done_valid = 1'b0;
    o_done_slot = {SB{1'b0}};
    o_count_warp_done = 1'b0;
    for (k = 0; k < S; k = k + 1) begin
        if (!found && k < {{(32-SCNT){1'b0}}, age_count_q}) begin
            sk = age_order_q[k*SB +: SB];
            for (s = 0; s < S; s = s + 1) begin
                if (sk == s[SB-1:0] && !slot_held_q[s] && l_busy[s*N +: N] == {N{1'b0}}) begin
                    found = 1'b1;
                    complete[s] = 1'b1;
                    o_done_valid = 1'b1;
                    o_done_slot = sk;
                    o_count_warp_done = 1'b1;
                    slot_valid_f[s] = 1'b0;
                    for (j = k; j < S - 1; j = j + 1)
                        age_order_f[j*SB +: SB] = age_order_f[(j+1)*SB +: SB];
                    age_order_f[(S-1)*SB +: SB] = {SB{1'b0}};
                    age_count_f = age_count_f - ONE_SCNT;
                end
            end
        end
    end

    // 3. The memory scheduler: at most one 32 B request.
    store_sel = {NL{1'b0}};
    merge = {S{1'b0}};
    lead_node = {E{1'b0}};
    lead = {LB{1'b0}};
    lead_me = {NL{1'b0}};
    act = ACT_NONE;
    act_stack = 1'b0;
    act_node = {E{1'b0}};
    o_req_valid = 1'b0;
    o_req_address = {AB{1'b0}};
    o_req_kind = RQ_LOAD;
    o_req_tag = {TGW{1'b0}};
    store_data = 256'd0;
    o_count_request = 1'b0;
    o_count_store = 1'b0;
    o_count_spill = 1'b0;
    o_count_fill = 1'b0;
    o_count_merged = {CMW{1'b0}};
    if (split_valid_q) begin
        // The next chunk of the node being requested.
        o_req_valid = 1'b1;
        o_req_address = split_node_q[E-1:5] + {{(AB-7){1'b0}}, split_chunk_q, 5'd0};
        o_req_tag = split_tag_q;
        o_count_request = 1'b1;
        if ({1'b0, split_chunk_q} + 3'd1 < {1'b0, split_node_q[1:0]} + 3'd1) begin
            split_chunk_f = split_chunk_q + 2'd1;
        end else begin
            split_valid_f = 1'b0;
            split_tag_f = {TGW{1'b0}};
            split_node_f = {E{1'b0}};
            split_chunk_f = 2'd0;
        end
    end else begin
        // A hit-record store: oldest warp, lowest lane.
        found = 1'b0;
        for (k = 0; k < S; k = k + 1) begin
            if (!found && k < {{(32-SCNT){1'b0}}, age_count_q}) begin
                sk = age_order_q[k*SB +: SB];
                for (s = 0; s < S; s = s + 1) begin
                    for (l = 0; l < N; l = l + 1) begin
                        if (!found && sk == s[SB-1:0] && lane_store_pending_q[s*N+l]) begin
                            found = 1'b1;
                            store_sel[s*N+l] = 1'b1;
                            o_req_valid = 1'b1;
                            o_req_kind = RQ_STORE;
                            o_req_tag = {sk, l[LB-1:0]};
                            w = {{(59-RB){1'b0}}, lane_ray_id_q[(s*N+l)*RB +: RB], 5'd0};
                            o_req_address = HB_AB + w[AB-1:0];
                            store_data = {96'd0, {(32-RB){1'b0}}, lane_ray_id_q[(s*N+l)*RB +: RB],
                                lane_hit_q[(s*N+l)*128+96 +: 32], lane_hit_q[(s*N+l)*128+64 +: 32],
                                lane_hit_q[(s*N+l)*128+32 +: 32], lane_hit_q[(s*N+l)*128 +: 32]};
                            o_count_store = 1'b1;
                        end
                    end
                end
            end
        end
        // Else the lowest ready lane (the leader) of the oldest warp with a ready lane.
        stop_scan = found;
        for (k = 0; k < S; k = k + 1) begin
            if (!stop_scan && k < {{(32-SCNT){1'b0}}, age_count_q}) begin
                sk = age_order_q[k*SB +: SB];
                for (s = 0; s < S; s = s + 1) begin
                    if (!stop_scan && sk == s[SB-1:0]) begin
                        for (l = 0; l < N; l = l + 1) begin
                            la = l_act[(s*N+l)*(E+6) +: E+6];
                            if (!stop_scan && la[E+5:E+4] != ACT_NONE) begin
                                stop_scan = 1'b1;
                                lead = l[LB-1:0];
                                lead_me[s*N+l] = 1'b1;
                                act = la[E+5:E+4];
                                act_stack = la[E+3];
                                act_node = la[E-1:0];
                                sp_idx = l_act_index[(s*N+l)*SCW +: SCW];
                                ray = lane_ray_id_q[(s*N+l)*RB +: RB];
                            end
                        end
                        if (stop_scan && act == ACT_FETCH) begin
                            // Every ready lane whose next request is the same node merges.
                            merge[s] = 1'b1;
                            lead_node = act_node;
                            served = {CMW{1'b0}};
                            for (l = 0; l < N; l = l + 1) begin
                                la = l_act[(s*N+l)*(E+6) +: E+6];
                                served = served
                                    + {{(CMW-1){1'b0}}, la[E+5:E+4] == ACT_FETCH && la[E-1:0] == act_node};
                            end
                            o_count_merged = served - ONE_CMW;
                            if (act_node[1:0] != 2'd0) begin
                                split_valid_f = 1'b1;
                                split_tag_f = {sk, lead};
                                split_node_f = act_node;
                                split_chunk_f = 2'd1;
                            end
                            o_req_valid = 1'b1;
                            o_req_kind = RQ_LOAD;
                            o_req_tag = {sk, lead};
                            o_req_address = act_node[E-1:5];
                            o_count_request = 1'b1;
                        end
                        if (stop_scan && act == ACT_SPILL) begin
                            if (sp_idx >= SPC_W) begin
                                {errors_f, first_error_f} = raised(errors_f, first_error_f, E_SPILL_FULL, sk, lead, ray,
                                        {{(64-SCW){1'b0}}, sp_idx} + 64'd1, SPC64);
                            end else begin
                                o_req_valid = 1'b1;
                                o_req_kind = RQ_SPILL;
                                o_req_tag = {sk, lead};
                                o_req_address = spill_address(ray, act_stack, sp_idx);
                                o_count_spill = 1'b1;
                            end
                        end
                        if (stop_scan && act == ACT_FILL) begin
                            o_req_valid = 1'b1;
                            o_req_kind = RQ_FILL;
                            o_req_tag = {sk, lead};
                            o_req_address = spill_address(ray, act_stack, sp_idx - ONE_SCW);
                            o_count_fill = 1'b1;
                        end
                    end
                end
            end
        end
    end

    // 5. The head of the response FIFO is popped and delivered.
    pop_fill = 1'b0;
    pop_node = 1'b0;
    pop_slot = {SB{1'b0}};
    pop_leader = {LB{1'b0}};
    pop_address = {AB{1'b0}};
    pop_data = 256'd0;
    pop_fill_lane = {NL{1'b0}};
    pop_node_slot = {S{1'b0}};
    if (fifo_count_q != {FCW{1'b0}}) begin
        for (j = 0; j < FD; j = j + 1)
            if (fifo_head_q == j[FPW-1:0]) entry = resp_fifo_q[j*FEW +: FEW];
        fifo_head_f = (fifo_head_q == FD_LAST) ? {FPW{1'b0}} : fifo_head_q + ONE_FPW;
        fifo_count_f = fifo_count_q - ONE_FCW;
        {pop_address, r_tag, pop_data} = entry;
        pop_slot = r_tag[TGW-1:LB];
        pop_leader = r_tag[LB-1:0];
        found = 1'b0;  // the tag names a valid slot
        for (s = 0; s < S; s = s + 1)
            if (pop_slot == s[SB-1:0] && slot_valid_f[s]) found = 1'b1;
        if (!found) begin
            {errors_f, first_error_f} = raised(errors_f, first_error_f, E_UNMATCHED, pop_slot, pop_leader, {RB{1'b0}}, {{(64-AB){1'b0}}, pop_address}, 64'd0);
        end else if ({1'b0, pop_address} >= SPILL_LO && {1'b0, pop_address} < SPILL_HI) begin
            // A stack fill for the tag's lane.
            pop_fill = 1'b1;
            for (s = 0; s < S; s = s + 1)
                for (l = 0; l < N; l = l + 1)
                    pop_fill_lane[s*N+l] = pop_slot == s[SB-1:0] && pop_leader == l[LB-1:0];
        end else begin
            // A node chunk for the lanes of the tag's slot whose request it answers.
            pop_node = 1'b1;
            for (s = 0; s < S; s = s + 1) pop_node_slot[s] = pop_slot == s[SB-1:0];
        end
    end
end

// The fill's expected address, from its lane's state after stage 3 (zero from every other lane).
always @* begin : p_fill
    integer L;
    reg [RB-1:0] ray;
    reg stk;
    reg [SCW-1:0] index;
    ray = {RB{1'b0}};
    stk = 1'b0;
    index = {SCW{1'b0}};
    for (L = 0; L < NL; L = L + 1) begin
        ray = ray | l_fx_ray[L*RB +: RB];
        stk = stk | l_fx_stack[L];
        index = index | l_fx_index[L*SCW +: SCW];
    end
    fill_expect = spill_address(ray, stk, index);
end

// ---- The node buffer ---------------------------------------------------------------------------
// Four SRAM banks (rt_unit_node_bank: one read and one write port, read latency 1), bank c
// holding chunk c of a node, one word per slot and leader lane: the lanes a fetch merged share
// its chunks, and the chunks a cycle pops all belong to one leader. A popped chunk some lane
// takes is written at its leader's word. Every bank reads, one cycle ahead, the word of the
// response the FIFO pops next (its head after this cycle), so when a node's last chunk pops,
// its earlier chunks are there: from the read data, from last cycle's write (a read does not
// see the write of its own cycle), or the chunk popping now.
reg nb_we;                        // a popped chunk is written ...
reg [1:0] nb_chunk;               // ... into this bank
reg [NAW-1:0] nb_index;           // ... at the popped response's word
reg [NAW-1:0] nb_raddr;           // the word of the response popped next cycle
reg [3:0] nb_we_c;
wire [4*256-1:0] nb_rdata;
reg [1023:0] node_data;           // the popped response's node: its four chunks
generate
    genvar gc;
    for (gc = 0; gc < 4; gc = gc + 1) begin : g_node_buffer
        rt_unit_node_bank u_bank (
            .clk(clk), .we(nb_we_c[gc]), .waddr(nb_index), .wdata(pop_data),
            .raddr(nb_raddr), .rdata(nb_rdata[gc*256 +: 256])
        );
    end
endgenerate
// The node buffer's word of slot `slot`'s leader lane `leader`.
function [NAW-1:0] node_index;
    input [SB-1:0] slot;
    input [LB-1:0] leader;
    /* verilator lint_off UNUSEDSIGNAL */
    reg [31:0] x;
    /* verilator lint_on UNUSEDSIGNAL */
    begin
        x = {{(32-SB){1'b0}}, slot} * N + {{(32-LB){1'b0}}, leader};
        node_index = x[NAW-1:0];
    end
endfunction
always @* begin : p_node_buffer
    integer L, c;
    reg [TGW-1:0] next_tag;
    nb_we = pop_node && l_node_match != {NL{1'b0}};
    nb_chunk = 2'd0;
    for (L = 0; L < NL; L = L + 1) nb_chunk = nb_chunk | l_node_chunk[L*2 +: 2];
    nb_index = node_index(pop_slot, pop_leader);
    for (c = 0; c < 4; c = c + 1) begin
        nb_we_c[c] = nb_we && nb_chunk == c[1:0];
        if (nb_we_c[c]) node_data[c*256 +: 256] = pop_data;
        else if (node_write_valid_q && node_write_chunk_q == c[1:0] && node_write_index_q == nb_index)
            node_data[c*256 +: 256] = node_write_data_q;
        else node_data[c*256 +: 256] = nb_rdata[c*256 +: 256];
    end
    node_write_valid_d = nb_we;
    node_write_chunk_d = nb_chunk;
    node_write_index_d = nb_index;
    node_write_data_d = pop_data;
    next_tag = {TGW{1'b0}};
    for (c = 0; c < FD; c = c + 1)
        if (fifo_head_d == c[FPW-1:0]) next_tag = resp_fifo_d[c*FEW + 256 +: TGW];
    nb_raddr = node_index(next_tag[TGW-1:LB], next_tag[LB-1:0]);
end

// The datapath's inputs for lane l of the popped response's slot: the node it tests (zero unless
// it completed this cycle), the node's bytes from the node buffer (the same for every lane: the
// chunks a cycle pops belong to one leader's node), the ray and its closest hit from the lane's
// registers (slot 0's unless the response is another slot's). A datapath whose node is zero
// tests nothing: the lane does not take its result.
always @* begin : p_datapath
    integer s, l;
    dp_node = {N*E{1'b0}};
    for (l = 0; l < N; l = l + 1) begin  // wide vectors lane by lane
        dp_data[l*1024 +: 1024] = node_data;
        dp_ray[l*256 +: 256] = lane_ray_words_q[l*256 +: 256];
        dp_best_valid[l] = lane_hit_valid_q[l];
        dp_best[l*128 +: 128] = lane_hit_q[l*128 +: 128];
    end
    for (s = 0; s < S; s = s + 1) begin
        for (l = 0; l < N; l = l + 1) begin
            if (s != 0 && pop_slot == s[SB-1:0]) begin
                dp_ray[l*256 +: 256] = lane_ray_words_q[(s*N+l)*256 +: 256];
                dp_best_valid[l] = lane_hit_valid_q[s*N+l];
                dp_best[l*128 +: 128] = lane_hit_q[(s*N+l)*128 +: 128];
            end
            dp_node[l*E +: E] = dp_node[l*E +: E] | l_dp_node[(s*N+l)*E +: E];
        end
    end
end

// The completed warp's lanes (stage 2) and the request's data (a store's, or the leader's spill).
reg [N-1:0] o_done_active;
reg [N-1:0] o_done_parked;
reg [N*RB-1:0] o_done_ray_id;
reg [N*256-1:0] o_done_ray_words;
reg [N-1:0] o_done_occlusion;
reg [N-1:0] o_done_hit_valid;
reg [N*128-1:0] o_done_hit;
reg [N*TW-1:0] o_done_cur_treelet;
reg [N*RSPW-1:0] o_done_cur_sp;
reg [N*RSPW-1:0] o_done_other_sp;
reg [N*SCW-1:0] o_done_cur_spilled;
reg [N*SCW-1:0] o_done_other_spilled;
reg [N*RD*E-1:0] o_done_cur_stack;
reg [N*RD*E-1:0] o_done_other_stack;
reg [255:0] o_req_data;
always @* begin : p_done
    integer s, l, L;
    o_done_active = {N{1'b0}};
    o_done_parked = {N{1'b0}};
    o_done_ray_id = {N*RB{1'b0}};
    o_done_occlusion = {N{1'b0}};
    o_done_hit_valid = {N{1'b0}};
    o_done_cur_treelet = {N*TW{1'b0}};
    o_done_cur_sp = {N*RSPW{1'b0}};
    o_done_other_sp = {N*RSPW{1'b0}};
    o_done_cur_spilled = {N*SCW{1'b0}};
    o_done_other_spilled = {N*SCW{1'b0}};
    for (l = 0; l < N; l = l + 1) begin  // wide vectors lane by lane
        o_done_ray_words[l*256 +: 256] = 256'd0;
        o_done_hit[l*128 +: 128] = 128'd0;
        o_done_cur_stack[l*RD*E +: RD*E] = {RD*E{1'b0}};
        o_done_other_stack[l*RD*E +: RD*E] = {RD*E{1'b0}};
    end
    for (s = 0; s < S; s = s + 1) begin
        for (l = 0; l < N; l = l + 1) begin
            if (l_done_active[s*N+l]) begin
                o_done_active[l] = 1'b1;
                o_done_parked[l] = l_done_parked[s*N+l];
                o_done_ray_id[l*RB +: RB] = lane_ray_id_q[(s*N+l)*RB +: RB];
                o_done_ray_words[l*256 +: 256] = lane_ray_words_q[(s*N+l)*256 +: 256];
                o_done_occlusion[l] = lane_occlusion_q[s*N+l];
                o_done_hit_valid[l] = lane_hit_valid_q[s*N+l];
                o_done_hit[l*128 +: 128] = lane_hit_q[(s*N+l)*128 +: 128];
                o_done_cur_treelet[l*TW +: TW] = lane_cur_treelet_q[(s*N+l)*TW +: TW];
                // A completing lane holds at most RD entries per stack.
                o_done_cur_sp[l*RSPW +: RSPW] = lane_cur_sp_q[(s*N+l)*SPW +: RSPW];
                o_done_other_sp[l*RSPW +: RSPW] = lane_other_sp_q[(s*N+l)*SPW +: RSPW];
                o_done_cur_spilled[l*SCW +: SCW] = lane_cur_spilled_q[(s*N+l)*SCW +: SCW];
                o_done_other_spilled[l*SCW +: SCW] = lane_other_spilled_q[(s*N+l)*SCW +: SCW];
                o_done_cur_stack[l*RD*E +: RD*E] = l_done_cur_stack[(s*N+l)*RD*E +: RD*E];
                o_done_other_stack[l*RD*E +: RD*E] = l_done_other_stack[(s*N+l)*RD*E +: RD*E];
            end
        end
    end
    o_req_data = store_data;
    for (L = 0; L < NL; L = L + 1) o_req_data = o_req_data | l_spill_data[L*256 +: 256];
end

// ---- Stages 5 (test write-back), 6 and 7, slot level --------------------------------------------
reg [N-1:0] o_boundary_valid;
reg [SB-1:0] o_boundary_slot;
reg [N*RB-1:0] o_boundary_ray_id;
reg [N*TW-1:0] o_boundary_treelet;
reg o_released_valid;
reg [SB-1:0] o_released_slot;
reg [6*CTW-1:0] o_tests;        // tests per node kind, kind k in bits [k*CTW +: CTW]
reg [CTW-1:0] o_count_tests_treelet_order;
reg [CTW-1:0] o_count_hits;

always @* begin : p_back
    integer s, l, k, j;
    reg [7:0] nvalid;
    reg [15:0] lim;
    reg bad;
    reg any_bad;
    reg [LB-1:0] bad_lane;
    reg [RB-1:0] bad_ray;
    reg [SB-1:0] target;
    reg ok;
    reg issued;           // the issue acted on slot `target`
    reg wok;              // the lane write is accepted
    reg [N-1:0] bus;      // bus lanes carrying a record (the issue's, then the write's)
    reg [SPW-1:0] csp;
    reg [SPW-1:0] osp;
    /* verilator lint_off UNUSEDSIGNAL */
    reg [E-1:0] ent;  // an issued stack entry (its kind is not checked)
    /* verilator lint_on UNUSEDSIGNAL */
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
    ent = {E{1'b0}};
    slot_valid_d = slot_valid_f;
    slot_order_d = slot_order_q;
    slot_held_d = slot_held_q;
    age_order_d = age_order_f;
    age_count_d = age_count_f;
    split_valid_d = split_valid_f;
    split_tag_d = split_tag_f;
    split_node_d = split_node_f;
    split_chunk_d = split_chunk_f;
    fifo_head_d = fifo_head_f;
    fifo_tail_d = fifo_tail_q;
    fifo_count_d = fifo_count_f;
    errors_d = errors_f;
    first_error_d = first_error_f;
    resp_fifo_d = resp_fifo_q;
    load = {NL{1'b0}};
    write_here = {NL{1'b0}};
    wake = {NL{1'b0}};
    issued = 1'b0;
    wok = 1'b0;
    stop_here = {S{1'b0}};
    repack_here = {S{1'b0}};
    o_boundary_valid = {N{1'b0}};
    o_boundary_slot = {SB{1'b0}};
    o_boundary_ray_id = {N*RB{1'b0}};
    o_boundary_treelet = {N*TW{1'b0}};
    o_released_valid = 1'b0;
    o_released_slot = {SB{1'b0}};
    o_tests = {6*CTW{1'b0}};
    o_count_tests_treelet_order = {CTW{1'b0}};
    o_count_hits = {CTW{1'b0}};

    // 5. (continued) A fill no lane expected; then boundaries and the tests' results, lane by lane.
    if (pop_fill && l_fill_ok == {NL{1'b0}})
        {errors_d, first_error_d} = raised(errors_d, first_error_d, E_UNMATCHED, pop_slot, pop_leader, {RB{1'b0}}, {{(64-AB){1'b0}}, pop_address}, 64'd0);
    for (s = 0; s < S; s = s + 1) begin
        for (l = 0; l < N; l = l + 1) begin
            if (l_boundary_valid[s*N+l]) begin
                o_boundary_valid[l] = 1'b1;
                o_boundary_slot = pop_slot;
                o_boundary_ray_id[l*RB +: RB] = lane_ray_id_q[(s*N+l)*RB +: RB];
                o_boundary_treelet[l*TW +: TW] = l_boundary_treelet[(s*N+l)*TW +: TW];
            end
            for (k = 0; k < 6; k = k + 1)
                o_tests[k*CTW +: CTW] = o_tests[k*CTW +: CTW]
                    + {{(CTW-1){1'b0}}, l_tested[s*N+l] && l_test_kind[(s*N+l)*3 +: 3] == k[2:0]};
            o_count_tests_treelet_order = o_count_tests_treelet_order
                + {{(CTW-1){1'b0}}, l_tested[s*N+l] && slot_stopped[s]};
            o_count_hits = o_count_hits + {{(CTW-1){1'b0}}, l_new_hit[s*N+l]};
            if (l_err_child[s*N+l])
                {errors_d, first_error_d} = raised(errors_d, first_error_d, E_BAD_CHILD, pop_slot, l[LB-1:0], lane_ray_id_q[(s*N+l)*RB +: RB],
                        l_err_value[(s*N+l)*64 +: 64], l_err_limit[(s*N+l)*64 +: 64]);
        end
    end
    if (pop_node && l_node_match == {NL{1'b0}})
        {errors_d, first_error_d} = raised(errors_d, first_error_d, E_UNMATCHED, pop_slot, pop_leader, {RB{1'b0}}, {{(64-AB){1'b0}}, pop_address}, 64'd0);

    // 6. This cycle's responses enter the FIFO.
    nvalid = 8'd0;
    ${COUNT_RESP}
    lim = {{(16-FCW){1'b0}}, o_resp_free};
    if (lim > {8'd0, RP_8}) lim = {8'd0, RP_8};
    ${PUSH_RESP}

    // 7. Warp issue and lane write (they share the issue bus: a bad record on it drops both),
    // then the treelet controller's stop and repack.
    bus = (issue_valid ? issue_active : {N{1'b0}}) | (write_valid ? write_mask : {N{1'b0}});
    if (issue_valid || write_valid) begin
        any_bad = 1'b0;
        bad_lane = {LB{1'b0}};
        bad_ray = {RB{1'b0}};
        for (l = 0; l < N; l = l + 1) begin
            bad = 1'b0;
            csp = {SPW{1'b0}};
            csp[RSPW-1:0] = issue_cur_sp[l*RSPW +: RSPW];
            osp = {SPW{1'b0}};
            osp[RSPW-1:0] = issue_other_sp[l*RSPW +: RSPW];
            if (issue_cur_spilled[l*SCW +: SCW] > SPC_W || issue_other_spilled[l*SCW +: SCW] > SPC_W
                || csp > RD_SPW || osp > RD_SPW)
                bad = 1'b1;
            for (j = 0; j < RD; j = j + 1) begin
                ent = issue_cur_stack[(l*RD+j)*E +: E];
                if (j[SPW-1:0] < csp && bad_node({{(64-AB){1'b0}}, ent[E-1:5]}, {6'd0, ent[1:0]} + 8'd1))
                    bad = 1'b1;
                ent = issue_other_stack[(l*RD+j)*E +: E];
                if (j[SPW-1:0] < osp && bad_node({{(64-AB){1'b0}}, ent[E-1:5]}, {6'd0, ent[1:0]} + 8'd1))
                    bad = 1'b1;
            end
            if (bus[l] && bad && !any_bad) begin
                any_bad = 1'b1;
                bad_lane = l[LB-1:0];
                bad_ray = issue_ray_id[l*RB +: RB];
            end
        end
        if (any_bad) begin
            {errors_d, first_error_d} = raised(errors_d, first_error_d, E_BAD_ISSUE, {SB{1'b0}}, bad_lane, bad_ray, 64'd0, 64'd0);
        end else if (issue_valid) begin
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
                for (s = 0; s < S; s = s + 1)
                    if (issue_slot == s[SB-1:0] && slot_valid_d[s] && slot_held_d[s]
                        && (issue_active & ~lane_empty[s*N +: N]) == {N{1'b0}})
                        ok = 1'b1;
                target = issue_slot;
                if (!ok) {errors_d, first_error_d} = raised(errors_d, first_error_d, E_BAD_COMMAND, issue_slot, {LB{1'b0}}, {RB{1'b0}}, 64'd2, 64'd0);
            end else begin
                {errors_d, first_error_d} = raised(errors_d, first_error_d, E_BAD_COMMAND, issue_slot, {LB{1'b0}}, {RB{1'b0}}, 64'd3, 64'd0);
            end
            // The lanes named written hold written records, and none also takes one from the bus.
            if (ok) begin
                if ((issue_written & issue_active) != {N{1'b0}}) ok = 1'b0;
                for (s = 0; s < S; s = s + 1)
                    for (l = 0; l < N; l = l + 1)
                        if (target == s[SB-1:0] && issue_written[l] && !lane_written_q[s*N+l])
                            ok = 1'b0;
                if (!ok) {errors_d, first_error_d} = raised(errors_d, first_error_d, E_BAD_COMMAND, issue_slot, {LB{1'b0}}, {RB{1'b0}}, {62'd0, issue_target}, 64'd0);
            end
            if (ok) begin
                issued = 1'b1;
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
                            load[s*N+l] = issue_active[l] || (issue_target != 2'd2 && !issue_written[l]);
                            wake[s*N+l] = issue_written[l];
                        end
                    end
                end
            end
        end
        // The lane write: into a free slot or a held one other than the issue's, its lanes empty
        // and inactive, none carrying an issued ray on the bus.
        if (!any_bad && write_valid) begin
            wok = !(issue_valid && (issue_active & write_mask) != {N{1'b0}})
                && !(issued && target == write_slot);
            ok = 1'b0;
            for (s = 0; s < S; s = s + 1)
                if (write_slot == s[SB-1:0] && (!slot_valid_d[s] || slot_held_d[s])
                    && (write_mask & ~lane_empty[s*N +: N]) == {N{1'b0}})
                    ok = 1'b1;
            wok = wok && ok;
            if (!wok) {errors_d, first_error_d} = raised(errors_d, first_error_d, E_BAD_COMMAND, write_slot, {LB{1'b0}}, {RB{1'b0}}, 64'd4, 64'd0);
            for (s = 0; s < S; s = s + 1)
                for (l = 0; l < N; l = l + 1)
                    if (wok && write_slot == s[SB-1:0] && write_mask[l]) begin
                        load[s*N+l] = 1'b1;
                        write_here[s*N+l] = 1'b1;
                    end
        end
    end
    if (stop_valid) begin
        ok = 1'b0;
        for (s = 0; s < S; s = s + 1) begin
            if (stop_slot == s[SB-1:0] && slot_valid_d[s]) begin
                ok = 1'b1;
                slot_order_d[s*2 +: 2] = ORD_STOP;
                stop_here[s] = 1'b1;
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
                repack_here[s] = 1'b1;
            end
        end
    end
end

// The lanes the repack released (lane l of the repacked slot), with their rays' ids and hits
// (quiescent lanes: their registers are what the repack takes).
reg [N-1:0] o_released_mask;
reg [N*RB-1:0] o_released_ray_id;
reg [N-1:0] o_released_hit_valid;
reg [N*128-1:0] o_released_hit;
always @* begin : p_released
    integer s, l;
    o_released_mask = {N{1'b0}};
    o_released_ray_id = {N*RB{1'b0}};
    o_released_hit_valid = {N{1'b0}};
    for (l = 0; l < N; l = l + 1) o_released_hit[l*128 +: 128] = 128'd0;
    for (s = 0; s < S; s = s + 1)
        for (l = 0; l < N; l = l + 1)
            if (l_released[s*N+l]) begin
                o_released_mask[l] = 1'b1;
                o_released_ray_id[l*RB +: RB] = lane_ray_id_q[(s*N+l)*RB +: RB];
                o_released_hit_valid[l] = lane_hit_valid_q[s*N+l];
                o_released_hit[l*128 +: 128] = lane_hit_q[(s*N+l)*128 +: 128];
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
    reg seen;
    reg [1:0] st;
    trav = {SNW{1'b0}};
    kept = {SNW{1'b0}};
    ndist = {SNW{1'b0}};
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
            for (l = 0; l < N; l = l + 1) begin
                st = lane_status_q[(s*N+l)*2 +: 2];
                trav = trav + {{(SNW-1){1'b0}}, st == ST_TRAVERSING};
                kept = kept + {{(SNW-1){1'b0}}, st == ST_TRAVERSING || st == ST_PARKED
                    || (st == ST_DONE && l_busy[s*N+l])};
                if (st == ST_INACTIVE) o_status_inactive[s*N + l] = 1'b1;
            end
            if (slot_order_q[s*2 +: 2] == 2'd1) begin
                for (l = 0; l < N; l = l + 1) begin
                    seen = 1'b0;
                    for (m = 0; m < l; m = m + 1)
                        if (l_next_valid[s*N+m]
                            && l_next_treelet[(s*N+m)*TW +: TW] == l_next_treelet[(s*N+l)*TW +: TW])
                            seen = 1'b1;
                    ndist = ndist + {{(SNW-1){1'b0}}, l_next_valid[s*N+l] && !seen};
                end
            end
            o_status_traversing[s*SNW +: SNW] = trav;
            o_status_busy[s*SNW +: SNW] = kept;
            o_status_distinct[s*SNW +: SNW] = ndist;
            o_status_quiescent[s] = l_busy[s*N +: N] == {N{1'b0}};
        end
    end
end

// ---- Outputs ------------------------------------------------------------------------------------
${OUTPUTS}
