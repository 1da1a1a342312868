${PARAMS}

// Slot owners (slot_use) and the codes of the other fields.
localparam [1:0] U_FREE = 2'd0;
localparam [1:0] U_INITIAL = 2'd1;
localparam [1:0] U_CONTROLLER = 2'd2;
localparam [1:0] U_CLOSING = 2'd3;
localparam [1:0] M_INITIAL = 2'd0;
localparam [1:0] M_TREELET = 2'd1;
localparam [1:0] M_FINAL = 2'd2;
localparam [1:0] M_DONE = 2'd3;
localparam [1:0] K_TREELET = 2'd0;
localparam [1:0] K_GROUPED = 2'd1;
localparam [1:0] K_REPACK = 2'd2;
localparam [1:0] O_RAY_STATIONARY = 2'd0;
localparam [1:0] O_CONTINUE = 2'd1;
localparam [1:0] O_STOP = 2'd2;
// A ray record as the wiring keeps it: {other_stack, cur_stack, other_spilled, cur_spilled,
// other_sp, cur_sp, cur_treelet, hit, hit_valid, occlusion, ray_words, ray id} (ray id
// lowest); each
// field's offset:
${RECORD_OFFSETS}
// An event: {warp done, ray id (or the slot), treelet}.
localparam EW = 1 + RB + TW;
${REGISTERS}

// The RT unit's per-slot status bits, as vectors.
wire [S-1:0] st_valid = rt_status_valid;
wire [S-1:0] st_held = rt_status_held;
wire [S-1:0] st_quiescent = rt_status_quiescent;
// Slots and counts as 32-bit indices.
wire [31:0] fill_slot32 = {{(32-SB){1'b0}}, ctl_fill_slot};
wire [31:0] fill_count32 = {{(32-CW){1'b0}}, ctl_fill_count};
wire [31:0] pop_count32 = {{(32-CW){1'b0}}, qt_pop_count};

// The queue table's popped rays, one port per lane.
wire [N*RB-1:0] qt_pop_rays = ${QT_POP_RAYS};

// SM warps are admitted in mode m (not in the final ray-stationary phase; in the
// treelet-stationary one only with the controller's feature).
function admits;
    input [1:0] m;
    begin
        admits = m == M_INITIAL || m == M_DONE || (m == M_TREELET && ADMIT_TS);
    end
endfunction

// ---- 0: ray records that arrived are written into the RT unit's lanes ------------------------
// A record on record port r (at most K a cycle, all for the slot of port 0's: the RT unit writes
// one slot a cycle) goes to the lane it will be issued to: entry k's lane k for a treelet or
// grouped fill; for a repack, the lowest inactive lane of the held warp not written yet (ports
// in order). It rides the RT unit's issue bus in that lane (a lane write, or with the fill's
// issue if the fill completes this cycle): each bus lane takes its record through a K-input
// crossbar (treelet_rt_unit_wiring_pick; a plain wire for one port). Each always block computes
// the selects from ids and counts, never indexes a record by a computed position.
genvar gl, gj;
// The records on the record ports, as the RT unit's bus carries them (the fill's ray id lowest).
${ARRIVED_WIRES}
wire [K*REC-1:0] arr_recs;
generate
    for (gl = 0; gl < K; gl = gl + 1) begin : g_arrived
        assign arr_recs[gl*REC +: REC] = ${PACK_ARRIVED};
    end
endgenerate
wire [SB-1:0] rr_slot0 = rr_slot[SB-1:0];
// place_sel[l*K + r]: bus lane l takes the record on port r (for lane l of slot rr_slot0).
reg [N*K-1:0] place_sel;
reg [N-1:0] wmask;
reg [S*N-1:0] arr_p;
reg [S*N-1:0] filled_p;
reg [S*CW-1:0] loading_p;
reg fault_place;
always @* begin : p_place
    integer r, e, s, k, l, ps, ek;
    reg m;
    reg taken;
    reg got;
    reg free;
    arr_p = build_arrived_q;
    filled_p = build_filled_q;
    loading_p = build_loading_q;
    place_sel = {N*K{1'b0}};
    wmask = {N{1'b0}};
    fault_place = {{(32-RCW){1'b0}}, ray_count} > K;
    for (r = 0; r < K; r = r + 1) begin
        ps = {{(32-SB){1'b0}}, rr_slot[r*SB +: SB]};
        // Another slot's record than port 0's is a fault and not taken.
        fault_place = fault_place || (r < ray_count && rr_slot[r*SB +: SB] != rr_slot0);
        // The fill entry waiting for this ray.
        taken = 1'b0;
        ek = 0;
        for (e = 0; e < S*N; e = e + 1) begin
            s = e / N;
            k = e % N;
            m = !taken && r < ray_count && build_valid_q[s] && !arr_p[e]
                && k < build_count_q[s*CW +: CW] && ps == s && rr_slot[r*SB +: SB] == rr_slot0
                && rr_id[r*RB +: RB] == build_rays_q[e*RB +: RB];
            arr_p[e] = arr_p[e] | m;
            if (m && loading_p[s*CW +: CW] != {CW{1'b0}})
                loading_p[s*CW +: CW] = loading_p[s*CW +: CW] - ONE_CW;
            ek = m ? k : ek;
            taken = taken | m;
        end
        fault_place = fault_place | (r < ray_count && rr_slot[r*SB +: SB] == rr_slot0 && !taken);
        // Its lane.
        got = 1'b0;
        for (e = 0; e < S*N; e = e + 1) begin
            s = e / N;
            l = e % N;
            free = build_kind_q[s*2 +: 2] == K_REPACK
                ? st_valid[s] && rt_status_inactive[e] && !filled_p[e] : l == ek;
            m = taken && !got && ps == s && free;
            place_sel[l*K + r] = place_sel[l*K + r] | m;
            wmask[l] = wmask[l] | m;
            filled_p[e] = filled_p[e] | m;
            got = got | m;
        end
        fault_place = fault_place | (taken && !got);
    end
end
// The records written this cycle, in their bus lanes (zero where none).
wire [N*REC-1:0] wrec;
generate
    for (gj = 0; gj < N; gj = gj + 1) begin : g_place
        treelet_rt_unit_wiring_pick #(.NI(K), .W(REC)) pick (
            .sel(place_sel[gj*K +: K]), .in(arr_recs), .out(wrec[gj*REC +: REC]));
    end
endgenerate
wire write_any = wmask != {N{1'b0}};

// ---- 1: the controller's inputs, from registers and register-only ports ----------------------
wire restart = ctl_mode_reg == M_DONE && sm_valid;
wire [1:0] mode = restart ? M_INITIAL : ctl_mode_reg;
wire mode_terminates = mode == M_INITIAL || mode == M_TREELET;
wire waiting = sm_valid && admits(mode);
wire [EW-1:0] head = events_q[EW-1:0];
wire head_valid = event_count_q != {EVW{1'b0}};
wire head_done = head_valid && head[EW-1];
reg any_initial;
reg free_valid;
reg [SB-1:0] free_slot;
reg init_valid;
reg [SB-1:0] init_slot;
reg [CW-1:0] init_active;
reg [CW-1:0] init_distinct;
reg active_valid;
reg [SB-1:0] active_slot;
reg [CW-1:0] active_count;
always @* begin : p_reports
    integer s;
    reg initial_warp;
    any_initial = 1'b0;
    free_valid = 1'b0;
    free_slot = {SB{1'b0}};
    init_valid = 1'b0;
    init_slot = {SB{1'b0}};
    init_active = {CW{1'b0}};
    init_distinct = {CW{1'b0}};
    active_valid = 1'b0;
    active_slot = {SB{1'b0}};
    active_count = {CW{1'b0}};
    for (s = S - 1; s >= 0; s = s - 1) begin
        if (slot_use_q[s*2 +: 2] == U_INITIAL) any_initial = 1'b1;
        if (slot_use_q[s*2 +: 2] == U_FREE && !st_valid[s]) begin
            free_valid = 1'b1;
            free_slot = s[SB-1:0];
        end
    end
    for (s = 0; s < S; s = s + 1) begin
        initial_warp = slot_use_q[s*2 +: 2] == U_INITIAL
            && rt_status_order[s*2 +: 2] != O_STOP && mode_terminates;
        // A warp that completes this cycle (quiescent, not held) is not reported.
        if (st_valid[s] && !(st_quiescent[s] && !st_held[s]) && initial_warp
            && (!init_valid || rt_status_distinct[s*CW +: CW] > init_distinct)) begin
            init_valid = 1'b1;
            init_slot = s[SB-1:0];
            init_active = rt_status_traversing[s*CW +: CW];
            init_distinct = rt_status_distinct[s*CW +: CW];
        end
        if (mode == M_FINAL && st_valid[s] && !st_quiescent[s] && !st_held[s]
            && !build_valid_q[s] && rt_status_order[s*2 +: 2] != O_STOP
            && (!active_valid || rt_status_busy[s*CW +: CW] < active_count)) begin
            active_valid = 1'b1;
            active_slot = s[SB-1:0];
            active_count = rt_status_busy[s*CW +: CW];
        end
    end
end

assign ctl_restart = sm_valid;
assign ctl_launch_done = !waiting;
assign ctl_initial_warps = any_initial || waiting;
assign ctl_rt_idle = rt_status_valid == {S{1'b0}} && build_valid_q == {S{1'b0}} && !head_valid;
assign ctl_wb_free_valid = free_valid;
assign ctl_wb_free_slot = free_slot;
assign ctl_init_valid = init_valid;
assign ctl_init_slot = init_slot;
assign ctl_init_active = init_active;
assign ctl_init_distinct = init_distinct;
assign ctl_active_valid = active_valid;
assign ctl_active_slot = active_slot;
assign ctl_active_count = active_count;
assign ctl_warp_done_valid = head_done;
assign ctl_warp_done_slot = head_done ? head[TW +: SB] : {SB{1'b0}};
assign ctl_enq_valid = head_valid && !head[EW-1];
assign ctl_enq_ray = ctl_enq_valid ? head[TW +: RB] : {RB{1'b0}};
assign ctl_enq_treelet = ctl_enq_valid ? head[TW-1:0] : {TW{1'b0}};
assign ctl_ct_ready = ct_accepts;
assign ctl_ct_max_valid = ct_max_valid;
assign ctl_ct_max_treelet = ct_max_treelet;
/* verilator lint_off UNUSEDSIGNAL */
wire [CTCW-1:0] ct_max_m1 = ct_max_count - {{(CTCW-1){1'b0}}, 1'b1};
/* verilator lint_on UNUSEDSIGNAL */
assign ctl_ct_max_count = ct_max_valid ? ct_max_m1[CMW-1:0] : {CMW{1'b0}};
assign ctl_ct_occupancy = ct_occupancy;
assign ctl_ct_above_threshold = ct_above_threshold;
assign ctl_ct_evict_valid = last_ct_evict_q[TW];
assign ctl_ct_evict_treelet = last_ct_evict_q[TW-1:0];
assign ctl_qt_ready = qt_ready;
assign ctl_qt_free_entries = qt_free_entries;
assign ctl_qt_spilled = qt_spilled;
assign ctl_qt_done = last_qt_done_q[QDW-1];
assign ctl_qt_pop_treelet = last_qt_done_q[CW + N*RB +: TW];
assign ctl_qt_pop_count = last_qt_done_q[N*RB +: CW];
assign ctl_qt_pop_rays = last_qt_done_q[N*RB-1:0];

// ---- 2: the children's inputs: events, fills, the issue of a complete fill or an SM warp -----
// The free-id stack (IDB SRAM banks of IDWD words, one read and one write port each; position
// p is word p >> IDBW of bank p % IDB): an admission pops the top ids (at most a warp's, id_top),
// then takes fresh ones (id_fresh_q up). A bank written in the previous cycle gives its bypass
// register, else its read data (every bank reads the position of the top IDB that it holds).
wire [IDB*RB-1:0] id_rdata;
reg [IDB*RB-1:0] id_top_data;
always @* begin : p_id_top
    integer b;
    for (b = 0; b < IDB; b = b + 1)
        id_top_data[b*RB +: RB] = id_bypass_q[b*(RB+1) + RB]
            ? id_bypass_q[b*(RB+1) +: RB] : id_rdata[b*RB +: RB];
end
wire [31:0] id_count32 = {{(32-FCW){1'b0}}, id_count_q};
wire [31:0] id_top = id_count32 < N ? id_count32 : N;
wire [31:0] id_fresh32 = {{(32-FCW){1'b0}}, id_fresh_q};
/* verilator lint_off UNUSEDSIGNAL */
wire [31:0] id_avail = id_top + MR - id_fresh32;
/* verilator lint_on UNUSEDSIGNAL */

reg pop;
reg [2*S-1:0] use_b;
reg [S-1:0] bv;
reg [2*S-1:0] bk;
reg [S*N*RB-1:0] brays;
reg [S*N-1:0] barr;
reg [S*N-1:0] bfill;
reg [S*CW-1:0] bcount;
reg [S*CW-1:0] bload;
reg [S-1:0] blast;
reg fault_fill;
reg issue_build;
reg [SB-1:0] issue_slot;
reg [1:0] issue_order;
reg [1:0] issue_target;
reg issue_last;
reg [N-1:0] build_active;     // the issued fill's lanes whose records arrive on the bus now
reg [N-1:0] build_written;    // ... and those written before
reg fault_unplaced;
reg admit;
reg [SB-1:0] admit_slot;
reg [CW-1:0] need;
reg [N*RB-1:0] admit_ids;
always @* begin : p_children
    integer s, k, l, c, n, placed, s2;
    /* verilator lint_off UNUSEDSIGNAL */
    reg [31:0] id_fresh;
    reg [31:0] id_pos;
    /* verilator lint_on UNUSEDSIGNAL */
    reg found;
    reg got;
    // The first event leaves when the controller takes it (a warp done always does).
    pop = head_done || (head_valid && ctl_enq_ready);
    use_b = slot_use_q;
    if (pop && head_done) use_b[head[TW +: SB]*2 +: 2] = U_FREE;
    // A fill starts loading its rays' records: its rays join the slot's, as many as fit.
    bv = build_valid_q;
    bk = build_kind_q;
    brays = build_rays_q;
    barr = arr_p;
    bfill = filled_p;
    bcount = build_count_q;
    bload = loading_p;
    blast = build_last_q;
    fault_fill = 1'b0;
    for (s = 0; s < S; s = s + 1) begin
        if (ctl_fill_valid && fill_slot32 == s) begin
            if (!bv[s]) begin
                bv[s] = 1'b1;
                bk[s*2 +: 2] = ctl_fill_kind;
                bcount[s*CW +: CW] = {CW{1'b0}};
                bfill[s*N +: N] = {N{1'b0}};
                bload[s*CW +: CW] = {CW{1'b0}};
                blast[s] = 1'b0;
            end
            c = {{(32-CW){1'b0}}, bcount[s*CW +: CW]};
            n = fill_count32 < N ? fill_count32 : N;
            if (n > N - c) begin
                fault_fill = 1'b1;
                n = N - c;
            end
            for (k = 0; k < N; k = k + 1) begin
                if (k >= c && k < c + n) begin
                    brays[(s*N + k)*RB +: RB] = ctl_fill_rays[(k - c)*RB +: RB];
                    barr[s*N + k] = 1'b0;
                end
            end
            bcount[s*CW +: CW] = bcount[s*CW +: CW] + n[CW-1:0];
            bload[s*CW +: CW] = bload[s*CW +: CW] + n[CW-1:0];
            blast[s] = blast[s] | ctl_fill_last;
            if (ctl_fill_kind != K_REPACK) use_b[s*2 +: 2] = U_CONTROLLER;
        end
    end
    // The first complete fill with every record in is issued.
    issue_build = 1'b0;
    issue_slot = {SB{1'b0}};
    for (s = S - 1; s >= 0; s = s - 1) begin
        if (bv[s] && blast[s] && bload[s*CW +: CW] == {CW{1'b0}}) begin
            issue_build = 1'b1;
            issue_slot = s[SB-1:0];
        end
    end
    issue_order = O_RAY_STATIONARY;
    issue_target = 2'd0;
    issue_last = 1'b0;
    build_active = {N{1'b0}};
    build_written = {N{1'b0}};
    fault_unplaced = 1'b0;
    admit = 1'b0;
    admit_slot = {SB{1'b0}};
    admit_ids = {N*RB{1'b0}};
    need = {CW{1'b0}};
    if (issue_build) begin
        s = {{(32-SB){1'b0}}, issue_slot};
        bv[s] = 1'b0;
        case (bk[s*2 +: 2])
            K_TREELET: begin issue_order = O_STOP; issue_target = 2'd1; end
            K_GROUPED: begin issue_order = O_CONTINUE; issue_target = 2'd1; end
            default: begin
                issue_order = st_valid[s] ? rt_status_order[s*2 +: 2] : O_RAY_STATIONARY;
                issue_target = 2'd2;
                issue_last = 1'b1;
            end
        endcase
    end else if (admits(mode) && sm_valid && !write_any) begin
        // An SM warp takes the lowest slot nobody owns (not the one the controller reserves)
        // if enough ray ids are free and the bus carries no lane write; its rays get the
        // lowest free ids.
        found = 1'b0;
        for (s = S - 1; s >= 0; s = s - 1) begin
            if (use_b[s*2 +: 2] == U_FREE && !st_valid[s]
                && !(ctl_reserve_valid && ctl_reserve_slot == s[SB-1:0])) begin
                found = 1'b1;
                admit_slot = s[SB-1:0];
            end
        end
        for (l = 0; l < N; l = l + 1) need = need + {{(CW-1){1'b0}}, sm_active[l]};
        if (found && {{(32-CW){1'b0}}, need} <= id_avail) begin
            admit = 1'b1;
            use_b[admit_slot*2 +: 2] = U_INITIAL;
            issue_order = O_CONTINUE;
            issue_target = 2'd1;
            issue_slot = admit_slot;
        end
    end
    // The issued fill's lanes enter from the records written into them, or from the bus if
    // theirs arrive now; its lanes are free for the slot's next fill.
    c = 0;
    placed = 0;
    for (s2 = 0; s2 < S; s2 = s2 + 1) begin
        got = issue_build && issue_slot == s2[SB-1:0];
        c = c | (got ? {{(32-CW){1'b0}}, bcount[s2*CW +: CW]} : 0);
        for (l = 0; l < N; l = l + 1) begin
            if (got && bfill[s2*N + l]) begin
                placed = placed + 1;
                if (wmask[l] && rr_slot0 == s2[SB-1:0]) build_active[l] = 1'b1;
                else build_written[l] = 1'b1;
            end
        end
        if (got) bfill[s2*N +: N] = {N{1'b0}};
    end
    fault_unplaced = issue_build && placed != c;
    // An admitted warp's active lanes take, in lane order, ids popped from the stack's top
    // (position count - 1 - k), then fresh ones.
    k = 0;
    for (l = 0; l < N; l = l + 1) begin
        id_pos = id_count32 - 1 - k;
        id_fresh = id_fresh32 + k - id_top;
        admit_ids[l*RB +: RB] = {RB{admit && sm_active[l]}}
            & (k < id_top ? id_top_data[id_pos[IDBW-1:0]*RB +: RB] : id_fresh[RB-1:0]);
        k = k + {31'd0, sm_active[l]};
    end
end

// The bus: an admitted SM warp's lanes with their new ray ids, else the records arriving this
// cycle in their lanes (a complete fill's issued, or another slot's written).
wire [N-1:0] admit_lanes = admit ? sm_active : {N{1'b0}};
wire [N-1:0] issue_active = build_active | admit_lanes;
wire [N*REC-1:0] issue_rec;
generate
    for (gl = 0; gl < N; gl = gl + 1) begin : g_issue
        assign issue_rec[gl*REC +: REC] = admit_lanes[gl] ? ${PACK_SM}
            : wrec[gl*REC +: REC];
    end
endgenerate
// The lane write: the records of this cycle unless they go with their fill's issue.
wire write_out = write_any && !(issue_build && issue_slot == rr_slot0);
assign rt_write_valid = write_out;
assign rt_write_slot = write_out ? rr_slot0 : {SB{1'b0}};
assign rt_write_mask = write_out ? wmask : {N{1'b0}};
assign rt_issue_written = build_written;

wire issue = issue_build || admit;
assign rt_issue_valid = issue;
assign rt_issue_order = issue ? issue_order : 2'd0;
assign rt_issue_target = issue ? issue_target : 2'd0;
assign rt_issue_slot = issue ? issue_slot : {SB{1'b0}};
assign rt_issue_last = issue_last;
assign rt_issue_active = issue_active;
generate
    for (gl = 0; gl < N; gl = gl + 1) begin : g_lanes
        assign rt_issue_ray_id[gl*RB +: RB] = issue_rec[gl*REC +: RB];
${UNPACK_ISSUE}
    end
endgenerate
assign rt_stop_valid = ctl_terminate_valid;
assign rt_stop_slot = ctl_terminate_slot;
assign rt_repack_valid = ctl_repack_valid;
assign rt_repack_slot = ctl_repack_slot;
${RESPONSES}
assign sm_accept = admit;
assign sm_ray_id = admit_ids;

// The tables: the controller's ops, or the spill FIFO's head answering a refill request.
wire refill = spill_head_valid && qt_refill_waiting;
assign spill_pop = refill;
assign qt_op_kind = refill ? 3'd0 : ctl_qt_op;
assign qt_op_treelet = refill ? {TW{1'b0}} : ctl_qt_treelet;
assign qt_op_ray = refill ? {RB{1'b0}} : ctl_qt_ray;
assign qt_refill_valid = refill;
assign qt_refill_treelet = refill ? spill_head_treelet : {TW{1'b0}};
assign qt_refill_ray = refill ? spill_head_ray : {RB{1'b0}};
assign ct_op_kind = ctl_ct_op;
assign ct_op_treelet = ctl_ct_treelet;
assign ct_op_n = ctl_ct_n;
assign preload_valid = ctl_preload_valid;
assign preload_treelet = ctl_preload_treelet;

// Ray-record requests: the fill's loads, then the admitted rays' stores.
reg [CW-1:0] nloads;
reg [2*N*RB-1:0] req_ids;
reg [2*N*AB-1:0] req_addrs;
always @* begin : p_requests
    integer i, l, c, k, j;
    nloads = ctl_fill_valid ? ctl_fill_count : {CW{1'b0}};
    req_ids = {2*N*RB{1'b0}};
    req_addrs = {2*N*AB{1'b0}};
    c = {{(32-CW){1'b0}}, nloads};
    if (c > N) c = N;
    for (i = 0; i < N; i = i + 1)
        if (i < c) req_ids[i*RB +: RB] = ctl_fill_rays[i*RB +: RB];
    // The admitted rays' stores follow the loads (ids of different lanes never share a place).
    k = 0;
    for (l = 0; l < N; l = l + 1) begin
        for (j = 0; j < 2*N; j = j + 1)
            req_ids[j*RB +: RB] = req_ids[j*RB +: RB]
                | ({RB{admit && sm_active[l] && j == c + k}} & admit_ids[l*RB +: RB]);
        k = k + {31'd0, admit && sm_active[l]};
    end
    c = c + k;
    for (i = 0; i < 2*N; i = i + 1)
        req_addrs[i*AB +: AB] = i < c
            ? RAY_BASE + {{(AB-RB-5){1'b0}}, req_ids[i*RB +: RB], 5'd0} : {AB{1'b0}};
end
assign ray_load_count = ${NLOADS_LW};
assign ray_store_count = admit ? ${NEED_LW} : {LW{1'b0}};
assign ray_request_id = req_ids;
assign ray_request_address = req_addrs;
assign count_ray_loads = ray_load_count;
assign count_ray_stores = ray_store_count;

// ---- 3: after the children: registered answers, spills, the unpacked warps -------------------
assign spill_push_valid = qt_spill_valid;
assign spill_push_treelet = qt_spill_valid ? qt_spill_treelet : {TW{1'b0}};
assign spill_push_ray = qt_spill_valid ? qt_spill_ray : {RB{1'b0}};
assign count_spill = qt_spill_valid;
assign count_refill = refill;
${PASS_THROUGH}

// The released lanes (finished), then the completed warp's lanes: finished rays leave with
// their hits at their position (released lane l at l, completed lane l at N + l) and free their
// ids; parked rays leave their records at their lane and queue an enqueue. Records are not
// compacted: only the enqueues' ray ids and treelets are, for the event FIFO.
// park_sel[p*N + l]: the p-th parked ray is the completed warp's lane l.
reg [LW-1:0] nfin;
reg [LW-1:0] npark;
reg [2*N-1:0] fin_valid;
reg [N-1:0] park_valid;
reg [N*N-1:0] park_sel;
always @* begin : p_unpack
    integer l, j;
    reg [LW-1:0] c;
    reg [LW-1:0] p;
    reg act;
    reg park;
    c = {LW{1'b0}};
    p = {LW{1'b0}};
    fin_valid = {2*N{1'b0}};
    park_valid = {N{1'b0}};
    park_sel = {N*N{1'b0}};
    for (l = 0; l < N; l = l + 1) begin
        act = rt_released_valid && rt_released_mask[l];
        fin_valid[l] = act;
        c = c + {{(LW-1){1'b0}}, fin_valid[l]};
    end
    for (l = 0; l < N; l = l + 1) begin
        act = rt_done_valid && rt_done_active[l];
        fin_valid[N + l] = act && !rt_done_parked[l];
        park = act && rt_done_parked[l];
        park_valid[l] = park;
        c = c + {{(LW-1){1'b0}}, fin_valid[N + l]};
        for (j = 0; j < N; j = j + 1)
            park_sel[j*N + l] = park && j == {{(32-LW){1'b0}}, p};
        p = p + {{(LW-1){1'b0}}, park};
    end
    nfin = c;
    npark = p;
end
// The treelet of a completed lane's next node: the current stack's top, or the other stack's
// when the current one is empty and nothing of it is spilled.
reg [N*TW-1:0] next_treelet;
always @* begin : p_next_treelet
    integer l, m;
    /* verilator lint_off UNUSEDSIGNAL */
    reg [31:0] m1;
    reg [E-1:0] top;
    /* verilator lint_on UNUSEDSIGNAL */
    m1 = 32'd0;
    for (l = 0; l < N; l = l + 1) begin
        top = {E{1'b0}};
        for (m = 0; m < D; m = m + 1) begin
            m1 = m + 1;
            if (rt_done_cur_sp[l*SPW +: SPW] == m1[SPW-1:0])
                top = rt_done_cur_stack[l*DE + m*E +: E];
            if (rt_done_cur_sp[l*SPW +: SPW] == {SPW{1'b0}}
                && rt_done_cur_spilled[l*SCW +: SCW] == {SCW{1'b0}}
                && rt_done_other_sp[l*SPW +: SPW] == m1[SPW-1:0])
                top = rt_done_other_stack[l*DE + m*E +: E];
        end
        next_treelet[l*TW +: TW] = top[TSH + 5 +: TW];
    end
end
// A finished item: {hit, hit valid, ray id}; a parked ray's enqueue: {next treelet, ray id}.
localparam FIN = RB + 129;
localparam ENQ = RB + TW;
wire [2*N*FIN-1:0] fin_items;
wire [2*N*RB-1:0] fin_id;
wire [N*ENQ-1:0] enq_items;
wire [N*ENQ-1:0] enq_out;
wire [N*RB-1:0] park_id;
wire [N*TW-1:0] park_treelet;
wire [N*REC-1:0] park_rec;
generate
    for (gl = 0; gl < N; gl = gl + 1) begin : g_items
        assign fin_items[gl*FIN +: FIN] = {rt_released_hit[gl*128 +: 128],
            rt_released_hit_valid[gl], rt_released_ray_id[gl*RB +: RB]};
        assign fin_items[(N + gl)*FIN +: FIN] = {rt_done_hit[gl*128 +: 128],
            rt_done_hit_valid[gl], rt_done_ray_id[gl*RB +: RB]};
        assign enq_items[gl*ENQ +: ENQ] = {next_treelet[gl*TW +: TW],
            rt_done_ray_id[gl*RB +: RB]};
        treelet_rt_unit_wiring_pick #(.NI(N), .W(ENQ)) pick_enq (
            .sel(park_sel[gl*N +: N]), .in(enq_items), .out(enq_out[gl*ENQ +: ENQ]));
        assign park_id[gl*RB +: RB] = enq_out[gl*ENQ +: RB];
        assign park_treelet[gl*TW +: TW] = enq_out[gl*ENQ + RB +: TW];
        assign park_rec[gl*REC +: REC] = park_valid[gl] ? ${PACK_DONE} : {REC{1'b0}};
        assign parked_id[gl*RB +: RB] = park_rec[gl*REC +: RB];
    end
    for (gj = 0; gj < 2*N; gj = gj + 1) begin : g_finished
        assign fin_id[gj*RB +: RB] = fin_valid[gj] ? fin_items[gj*FIN +: RB] : {RB{1'b0}};
        assign finished_hit_valid[gj] = fin_valid[gj] && fin_items[gj*FIN + RB];
        assign finished_hit[gj*128 +: 128] = fin_valid[gj]
            ? fin_items[gj*FIN + RB + 1 +: 128] : 128'd0;
    end
endgenerate
assign finished_count = nfin;
assign finished_valid = fin_valid;
assign finished_id = fin_id;
assign parked_count = npark;
assign parked_valid = park_valid;
generate
    for (gl = 0; gl < N; gl = gl + 1) begin : g_parked
${UNPACK_PARKED}
    end
endgenerate

// The free-id stack's banks. The finished rays' ids (position j, the k-th finished) are pushed
// after the ids popped, at position count - popped + k: one write per bank. Every bank reads the
// position of the top IDB (from this cycle's count) that it holds; with the bypasses of the
// banks written in this cycle, that covers the next cycle's top warp.
wire [31:0] need32 = {{(32-CW){1'b0}}, need};
wire [31:0] id_take = admit ? (need32 < id_top ? need32 : id_top) : 32'd0;
/* verilator lint_off UNUSEDSIGNAL */
wire [31:0] id_tail32 = id_count32 - id_take;
/* verilator lint_on UNUSEDSIGNAL */
wire [RB-1:0] id_tail = id_tail32[RB-1:0];
// Ids given back: all the finished rays', unless more than are in use (a fault: none).
wire [31:0] id_in_use = id_fresh32 + (admit ? need32 - id_take : 32'd0)
    - (id_count32 - id_take);
wire fault_ids = {{(32-LW){1'b0}}, nfin} > id_in_use;
reg [IDB-1:0] id_we;
reg [IDB*RB-1:0] id_wdata;
reg [IDB*RB-1:0] id_wpos;
// The ids are compacted (each valid one moves down by the count of empty positions before it,
// a bit of that count per stage: valid ones never collide, their order kept) and each
// IDB-long part rotated up by the tail (a bit of it per stage), so bank b takes the id of rank
// (b - tail) mod IDB (+ IDB for the next part): log-depth networks, not a select per id and
// bank (which unrolled into 2N x IDB multiplexers of two ids' width). A later part wins a bank.
always @* begin : p_id_writes
    integer j, s, b, m;
    reg [2*N*RB-1:0] cd, nd;
    reg [2*N-1:0] cv, nv;
    reg [2*N*LW-1:0] cz, nz;
    reg [LW-1:0] z;
    reg [IDB*RB-1:0] rd;
    reg [IDB-1:0] rv;
    /* verilator lint_off UNUSEDSIGNAL */
    reg [31:0] rank;  // (b - tail) mod IDB + m * IDB
    /* verilator lint_on UNUSEDSIGNAL */
    z = {LW{1'b0}};
    for (j = 0; j < 2*N; j = j + 1) begin
        cd[j*RB +: RB] = fin_id[j*RB +: RB];
        cv[j] = fin_valid[j] && !fault_ids;
        cz[j*LW +: LW] = z;
        z = z + {{(LW-1){1'b0}}, !fin_valid[j]};
    end
    for (s = 0; s < LW; s = s + 1) begin
        for (j = 0; j < 2*N; j = j + 1) begin
            nd[j*RB +: RB] = {RB{1'b0}};
            nv[j] = 1'b0;
            nz[j*LW +: LW] = {LW{1'b0}};
            if (cv[j] && !cz[j*LW + s]) begin
                nd[j*RB +: RB] = cd[j*RB +: RB];
                nv[j] = 1'b1;
                nz[j*LW +: LW] = cz[j*LW +: LW];
            end
            if (j + (1 << s) < 2*N) begin
                if (cv[j + (1 << s)] && cz[(j + (1 << s))*LW + s]) begin
                    nd[j*RB +: RB] = cd[(j + (1 << s))*RB +: RB];
                    nv[j] = 1'b1;
                    nz[j*LW +: LW] = cz[(j + (1 << s))*LW +: LW];
                end
            end
        end
        cd = nd;
        cv = nv;
        cz = nz;
    end
    id_we = {IDB{1'b0}};
    id_wdata = {IDB*RB{1'b0}};
    id_wpos = {IDB*RB{1'b0}};
    rank = 32'd0;
    for (m = 0; m < 2*N/IDB; m = m + 1) begin
        rd = cd[m*IDB*RB +: IDB*RB];
        rv = cv[m*IDB +: IDB];
        for (s = 0; s < IDBW; s = s + 1) begin
            if (id_tail[s]) begin
                rd = (rd << ((1 << s)*RB)) | (rd >> ((IDB - (1 << s))*RB));
                rv = (rv << (1 << s)) | (rv >> (IDB - (1 << s)));
            end
        end
        for (b = 0; b < IDB; b = b + 1) begin
            if (rv[b]) begin
                rank = ((b - {{(32-RB){1'b0}}, id_tail}) & (IDB - 1)) + m * IDB;
                id_we[b] = 1'b1;
                id_wdata[b*RB +: RB] = rd[b*RB +: RB];
                id_wpos[b*RB +: RB] = id_tail + rank[RB-1:0];
            end
        end
    end
end
generate
    for (gj = 0; gj < IDB; gj = gj + 1) begin : g_id_bank
        localparam integer BI = gj;
        localparam [IDBW-1:0] BK = BI[IDBW-1:0];
        // The position of the top IDB this bank holds: count - 1 - (count - 1 - bank) % IDB.
        wire [IDBW-1:0] off = id_count_q[IDBW-1:0] - {{(IDBW-1){1'b0}}, 1'b1} - BK;
        /* verilator lint_off UNUSEDSIGNAL */
        wire [31:0] rpos = id_count32 - 1 - {{(32-IDBW){1'b0}}, off};
        wire [RB-1:0] wpos = id_wpos[gj*RB +: RB];
        /* verilator lint_on UNUSEDSIGNAL */
        treelet_rt_unit_wiring_id_bank #(.RB(RB), .DEPTH(IDWD), .AW(IDAW)) bank (
            .clk(clk), .rst(rst), .we(id_we[gj]), .waddr(${ID_WADDR}), .wdata(id_wdata[gj*RB +: RB]),
            .raddr(${ID_RADDR}), .rdata(id_rdata[gj*RB +: RB]));
    end
endgenerate
// ---- Next registers ---------------------------------------------------------------------------
always @* begin : p_next
    integer i, c, l, j, n;
    reg [EVD*EW-1:0] ev;
    reg [EVD*EW-1:0] app;  // the appended events, then shifted to their places
    reg [EVD-1:0] appv;
    reg [31:0] cnt;
    reg full;
    c = 0;
    l = 0;
    fault_d = fault_q;
    slot_use_d = use_b;
    if (rt_done_valid) slot_use_d[rt_done_slot*2 +: 2] = U_CLOSING;
    build_valid_d = bv;
    build_kind_d = bk;
    build_rays_d = brays;
    build_arrived_d = barr;
    build_filled_d = bfill;
    build_count_d = bcount;
    build_loading_d = bload;
    build_last_d = blast;
    // Events: the head leaves, then the enqueues and the warp done are appended, as many as
    // fit (the FIFO full is a fault).
    ev = events_q;
    cnt = {{(32-EVW){1'b0}}, event_count_q};
    if (pop) begin
        ev = ev >> EW;
        cnt = cnt - 1;
    end
    n = {{(32-LW){1'b0}}, npark};
    // The appended events in order (the enqueues, then the warp done), shifted up to the
    // FIFO's tail a bit of the count per stage; those past the end do not fit.
    app = {EVD*EW{1'b0}};
    appv = {EVD{1'b0}};
    for (i = 0; i <= N && i < EVD; i = i + 1) begin
        if (i < N && i < n) begin
            app[i*EW +: EW] = {1'b0, park_id[(i < N ? i : 0)*RB +: RB],
                               park_treelet[(i < N ? i : 0)*TW +: TW]};
            appv[i] = 1'b1;
        end else if (i == n && rt_done_valid) begin
            app[i*EW +: EW] = {1'b1, {{(RB-SB){1'b0}}, rt_done_slot}, {TW{1'b0}}};
            appv[i] = 1'b1;
        end
    end
    for (j = 0; (1 << j) <= EVD; j = j + 1) begin
        if (cnt[j]) begin
            app = app << ((1 << j)*EW);
            appv = appv << (1 << j);
        end
    end
    for (j = 0; j < EVD; j = j + 1)
        if (appv[j]) ev[j*EW +: EW] = app[j*EW +: EW];
    cnt = cnt + n + (rt_done_valid ? 1 : 0);
    full = cnt > EVD;
    if (full) cnt = EVD;
    events_d = ev;
    event_count_d = cnt[EVW-1:0];
    last_ct_evict_d = ct_evict_valid ? {1'b1, ct_evict_treelet} : {(TW+1){1'b0}};
    last_qt_done_d = {QDW{1'b0}};
    if (qt_done) begin
        c = pop_count32 < N ? pop_count32 : N;
        last_qt_done_d[QDW-1] = 1'b1;
        last_qt_done_d[CW + N*RB +: TW] = qt_pop_treelet;
        last_qt_done_d[N*RB +: CW] = c[CW-1:0];
        for (l = 0; l < N; l = l + 1)
            if (l < c) last_qt_done_d[l*RB +: RB] = qt_pop_rays[l*RB +: RB];
    end
    // Ray ids: popped and fresh ids taken, the finished rays' pushed; each bank's bypass holds
    // what it was written.
    cnt = id_tail32;
    if (!fault_ids) cnt = cnt + {{(32-LW){1'b0}}, nfin};
    id_count_d = cnt[FCW-1:0];
    cnt = id_fresh32 + (admit ? need32 - id_take : 32'd0);
    id_fresh_d = cnt[FCW-1:0];
    for (i = 0; i < IDB; i = i + 1)
        id_bypass_d[i*(RB+1) +: RB+1] = {id_we[i], id_wdata[i*RB +: RB]};
    fault_d = fault_q || fault_place || fault_fill || fault_unplaced || fault_ids || full
        || ct_error || qt_error;
end
assign fault = fault_d;

// Register-only: an SM warp may be offered.
assign sm_ready = admits(ctl_mode_reg) && id_avail >= N && free_valid;

// The controller's events as its observer counts them, and the restart.
assign count_ctl_initial = ctl_mode == M_INITIAL;
assign count_ctl_treelet = ctl_mode == M_TREELET;
assign count_ctl_final = ctl_mode == M_FINAL;
assign count_ctl_terminated_warps = ctl_terminate_valid;
assign count_ctl_terminated_rays = ctl_terminate_valid ? init_active : {CW{1'b0}};
assign count_ctl_enqueued = ctl_enq_ready;
assign count_ctl_claim = ctl_claim;
assign count_ctl_preload = ctl_preload_valid;
assign count_ctl_treelet_warp = ctl_fill_valid && ctl_fill_kind == K_TREELET;
assign count_ctl_grouped_warp = ctl_fill_valid && ctl_fill_kind == K_GROUPED && ctl_fill_first;
assign count_ctl_repack = ctl_repack_valid;
assign count_ctl_repack_starved = ctl_repack_starved;
assign count_ctl_eviction = last_ct_evict_q[TW];
assign count_restart = restart;
${UNUSED}
