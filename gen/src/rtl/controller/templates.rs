//! The treelet controller's Verilog templates (`${NAME}` placeholders filled by
//! [`super::controller_verilog`]): encodings, the resident list and slot logic on the effective
//! registers with this cycle's conditions, and the next-state block that follows
//! `TreeletController::next_into` step by step.

/// Encodings.
pub(super) const CONSTANTS: &str = r#"
// State encodings of the mode and sequencer FSMs.
localparam [1:0] ${M_INITIAL} = 2'd0;
localparam [1:0] ${M_TS} = 2'd1;
localparam [1:0] ${M_FINAL} = 2'd2;
localparam [1:0] ${M_DONE} = 2'd3;
localparam [1:0] ${S_IDLE} = 2'd0;
localparam [1:0] ${S_POP_WAIT} = 2'd1;
localparam [1:0] ${S_FILL_NEXT} = 2'd2;
localparam [1:0] ${S_REFILL_WAIT} = 2'd3;
// Feature switches (the paper's design variants).
localparam GROUP = ${GROUP};   // group underpopulated queues (section 4.4)
localparam PRELOAD = ${PRELOAD}; // preload the next treelet (section 4.3)"#;

/// The resident list and the slots on the effective registers.
pub(super) const RESIDENT: &str = r#"
// ---- The resident list on the effective registers ----------------------------------------------
// Its age order (from res_head, valid entries only) drives the resident_* outputs and picks the
// current treelet (the oldest) and the oldest one with queued rays; three comparator rows find
// the entries holding ct_evict_treelet, enq_treelet and ct_max_treelet (lowest index first).
reg [${RCW1}:0] e_res_n;           // valid entries
reg [${NR}-1:0] ord_valid;         // resident_valid: the k-th oldest entry exists
reg [${NR}*${TW}-1:0] ord_treelet; // resident_treelet: the k-th oldest entry's treelet
reg        cur_low;            // the current queue is below the preload threshold (or none)
reg        disp_found;         // an entry has queued rays: dispatch a treelet warp of it
reg [${RIW1}:0] disp_idx;          // ... the oldest such entry
reg [${TW1}:0] disp_treelet;      // ... its treelet
reg        evict_hit;          // an entry holds ct_evict_treelet
reg [${RIW1}:0] evict_idx;
reg        enq_hit;            // an entry holds enq_treelet
reg [${RIW1}:0] enq_idx;
reg        max_hit;            // an entry holds ct_max_treelet
reg        tail_valid;         // the entry a claim would allocate is taken
always @* begin : p_resident
    integer k;
    integer j;
    reg [${RIW}:0] at;
    reg [${RCW1}:0] pos;
    reg [${RTW1}:0] cnt;
    reg [${TW1}:0] tv;
    reg vv;
    reg seen;
    e_res_n = ${Z_RCW};
    ord_valid = {${NR}{1'b0}};
    ord_treelet = {${NR}*${TW}{1'b0}};
    cur_low = 1'b1;
    disp_found = 1'b0;
    disp_idx = ${Z_RIW};
    disp_treelet = ${Z_TW};
    pos = ${Z_RCW};
    seen = 1'b0;
    for (k = 0; k < ${NR}; k = k + 1) begin
        if (e_res_valid[k]) e_res_n = e_res_n + ${ONE_RCW};
        at = {1'b0, e_res_head} + k[${RIW}:0];
        if (at >= ${NR_WIDE}) at = at - ${NR_WIDE};
        vv = 1'b0;
        cnt = ${Z_RTW};
        tv = ${Z_TW};
        for (j = 0; j < ${NR}; j = j + 1) begin
            if (at == j[${RIW}:0]) begin
                vv = e_res_valid[j];
                cnt = e_res_count[j*${RTW} +: ${RTW}];
                tv = e_res_treelet[j*${TW} +: ${TW}];
            end
        end
        if (vv) begin
            for (j = 0; j < ${NR}; j = j + 1) begin
                if (pos == j[${RCW1}:0]) begin
                    ord_valid[j] = 1'b1;
                    ord_treelet[j*${TW} +: ${TW}] = tv;
                end
            end
            if (!seen) cur_low = ${CUR_LOW};
            seen = 1'b1;
            if (!disp_found && (cnt != ${Z_RTW})) begin
                disp_found = 1'b1;
                disp_idx = at[${RIW1}:0];
                disp_treelet = tv;
            end
            pos = pos + ${ONE_RCW};
        end
    end
end
always @* begin : p_cam
    integer k;
    evict_hit = 1'b0;
    evict_idx = ${Z_RIW};
    enq_hit = 1'b0;
    enq_idx = ${Z_RIW};
    max_hit = 1'b0;
    tail_valid = 1'b0;
    for (k = ${NR} - 1; k >= 0; k = k - 1) begin
        if (e_res_tail == k[${RIW1}:0]) tail_valid = e_res_valid[k];
        if (e_res_valid[k] && (e_res_treelet[k*${TW} +: ${TW}] == ct_evict_treelet)) begin
            evict_hit = 1'b1;
            evict_idx = k[${RIW1}:0];
        end
        if (e_res_valid[k] && (e_res_treelet[k*${TW} +: ${TW}] == enq_treelet)) begin
            enq_hit = 1'b1;
            enq_idx = k[${RIW1}:0];
        end
        if (e_res_valid[k] && (e_res_treelet[k*${TW} +: ${TW}] == ct_max_treelet)) max_hit = 1'b1;
    end
end

// ---- Slots: the finished warp's bookkeeping, and the warps that may still fill the queues -------
reg        wd_releases;        // the finished warp is a treelet warp of a resident entry
reg [${RIW1}:0] wd_res;            // ... that entry
always @* begin : p_slots
    integer k;
    wd_releases = 1'b0;
    wd_res = ${Z_RIW};
    for (k = 0; k < ${NS}; k = k + 1) begin
        if (warp_done_slot == k[${SW1}:0]) begin
            wd_releases = e_slot_treelet_warp[k] && e_slot_res_valid[k];
            wd_res = e_slot_res[k*${RIW} +: ${RIW}];
        end
    end
end
wire feeding = |(e_slot_treelet_warp | e_slot_terminated); // treelet or terminated warps in flight

// ---- Conditions of this cycle ------------------------------------------------------------------
wire [${RTW1}:0] max_count = ${MAX_COUNT};        // the largest queue's true count
wire rays_waiting = (e_queued_rays != ${Z_RTW}) || (e_spare_count != ${Z_LW});
wire free_ok = wb_free_valid && ${FREE_OK};         // a free warp-buffer slot is offered
wire repack_ok = ${REPACK_OK};                     // the reported warp is below the repack threshold
wire refill_ok = qt_ready && (qt_spilled != ${Z_SP}) && (qt_free_entries != ${Z_QF});
// A naive design pops any entry once the count table tracks nothing.
wire naive_untracked = !GROUP && (e_res_n == ${Z_RCW}) && (ct_occupancy == ${Z_CE})
                       && (e_queued_rays != ${Z_RTW});
// The largest queue may be claimed (made resident).
wire claim_ok = (e_mode == ${M_TS}) && ct_max_valid && !e_prm_valid && !tail_valid && !max_hit
                && (!GROUP || !${MAX_UNDER}) && ((e_res_n == ${Z_RCW}) || (PRELOAD && cur_low));
wire largest_under = ct_max_valid ? ${MAX_UNDER}
                                  : ((ct_occupancy == ${Z_CE}) || (ct_above_threshold == ${Z_CE}));
wire settled = (e_seq == ${S_IDLE}) && !e_prm_valid;  // no table sequence in progress
wire divergent = init_valid && ${INIT_OK} && ((e_mode == ${M_INITIAL}) || (e_mode == ${M_TS}))
                 && (init_distinct > ${DIV});
wire phase_over = (e_mode == ${M_TS}) && settled && GROUP && largest_under
                  && (e_res_n == ${Z_RCW}) && !feeding && !initial_warps && !enq_valid;
wire drained = launch_done && rt_idle && (e_queued_rays == ${Z_RTW}) && (e_spare_count == ${Z_LW})
               && (e_res_n == ${Z_RCW}) && settled && !enq_valid;

// Inputs the controller does not read (init_active is for the statistics observer); active_*
// are not read when repacking is off.
/* verilator lint_off UNUSED */
wire unused_ok = &{1'b0, init_active, active_count, active_slot, active_valid, 1'b0};
/* verilator lint_on UNUSED */"#;

/// The next-state block's declarations and opening.
pub(super) const NEXT_HEAD: &str = r#"
// ---- Next state and outputs: TreeletController::next_into, step by step ------------------------
reg        ct_port_free;       // the count-table port is free for an enqueue's Add
reg [${LNW1}:0] popped;            // rays of the popped entry (at most warp_size)
reg [${LNW1}:0] take;              // rays given to the slot being filled
reg [${LNW1}:0] left_n;            // rays left for the spare buffer
reg [${LNW1}:0] need;              // lanes still to fill afterwards
reg        last;               // the fill closes the slot
reg [${RTW1}:0] chunk;             // rays of a pending remove issued this cycle
reg [${RTW1}:0] removed;           // rays a treelet pop removes from its resident count
reg [${RTW1}:0] cnt;               // that resident count
reg [${TW1}:0] ptreelet;          // the popped treelet warp's treelet
reg [${WSRW1}:0] wide;            // rays shifted down for the spare buffer
reg        ef_go;              // emit_fill: a fill sequence gives rays (or closes the slot)
reg        ef_last;
reg [${LNW1}:0] ef_count;
reg [${WSRW1}:0] ef_rays;
reg        found;
reg [${RIW}:0] at;
/* verilator lint_off UNUSED */
wire unused_wide = &{1'b0, wide, 1'b0};   // the spare buffer takes warp_size - 1 lanes of it
/* verilator lint_on UNUSED */
always @* begin : p_next
    integer k;
    integer j;"#;

/// The next-state block's body (after the defaults).
pub(super) const NEXT_BODY: &str = r#"    // A repack withheld for want of rays (an event for the statistics observer).
    o_repack_starved = ${REPACK_STARVED};
    ct_port_free = ct_ready;
    popped = ${Z_LNW};
    take = ${Z_LNW};
    left_n = ${Z_LNW};
    need = ${Z_LNW};
    last = 1'b0;
    chunk = ${Z_RTW};
    removed = ${Z_RTW};
    cnt = ${Z_RTW};
    ptreelet = ${Z_TW};
    wide = ${Z_WSRW};
    ef_go = 1'b0;
    ef_last = 1'b0;
    ef_count = ${Z_LNW};
    ef_rays = ${Z_WSRW};
    found = 1'b0;
    at = {1'b0, ${Z_RIW}};

    // An evicted resident treelet is no longer counted by the table: stop mirroring it.
    if (ct_evict_valid && evict_hit) begin
        for (k = 0; k < ${NR}; k = k + 1)
            if (evict_idx == k[${RIW1}:0]) res_count_d[k*${RTW} +: ${RTW}] = ${Z_RTW};
    end

    // A finished warp frees its slot; a treelet warp releases its resident treelet.
    if (warp_done_valid && ${WD_OK}) begin
        for (k = 0; k < ${NR}; k = k + 1)
            if (wd_releases && (wd_res == k[${RIW1}:0]) && (res_warps_d[k*${WW} +: ${WW}] != ${Z_WW}))
                res_warps_d[k*${WW} +: ${WW}] = res_warps_d[k*${WW} +: ${WW}] - ${ONE_WW};
${FREE_DONE_SLOT}
    end

    // Initial-phase warps that diverged are terminated into the queues.
    if (divergent) begin
        o_terminate_valid = 1'b1;
        o_terminate_slot = init_slot;
        for (k = 0; k < ${NS}; k = k + 1)
            if (init_slot == k[${SW1}:0]) slot_terminated_d[k] = 1'b1;
    end

    // A pending count-table Remove has the count-table port first, a warp of rays at a time.
    if (e_prm_valid) begin
        if (ct_ready) begin
            chunk = (e_prm_count > ${WS_RTW}) ? ${WS_RTW} : e_prm_count;
            o_ct_op = ${CT_REMOVE};
            o_ct_treelet = e_prm_treelet;
            o_ct_n = chunk[${LNW1}:0];
            if (e_prm_count > chunk) begin
                prm_count_d = e_prm_count - chunk;
            end else begin
                prm_valid_d = 1'b0;
                prm_treelet_d = ${Z_TW};
                prm_count_d = ${Z_RTW};
            end
        end
        ct_port_free = 1'b0;
    end

    // The sequencer.
    case (e_seq)
    ${S_IDLE}: begin
        // At most one action, by priority.
        if (refill_ok) begin
            // 1. Bring a spilled ray back while the table has room.
            o_qt_op = ${QT_REFILL};
            seq_d = ${S_REFILL_WAIT};
        end else if ((e_mode == ${M_TS}) && qt_ready && free_ok && (disp_found || naive_untracked)) begin
            // 2. Dispatch a treelet warp: pop the oldest resident with rays (naive: any entry).
            o_qt_op = disp_found ? ${QT_POP} : ${QT_POP_ANY};
            o_qt_treelet = disp_found ? disp_treelet : ${Z_TW};
            o_reserve_valid = 1'b1;
            o_reserve_slot = wb_free_slot;
            seq_d = ${S_POP_WAIT};
            fill_kind_d = ${K_TREELET};
            fill_slot_d = wb_free_slot;
            fill_res_valid_d = disp_found;
            fill_res_d = disp_found ? disp_idx : ${Z_RIW};
            fill_need_d = ${WS_LNW};
            fill_started_d = 1'b0;
        end else if (claim_ok) begin
            // 3. Claim the largest queue: current, or preloaded behind the current one.
            for (k = 0; k < ${NR}; k = k + 1) begin
                if (e_res_tail == k[${RIW1}:0]) begin
                    res_valid_d[k] = 1'b1;
                    res_treelet_d[k*${TW} +: ${TW}] = ct_max_treelet;
                    res_count_d[k*${RTW} +: ${RTW}] = max_count;
                    res_warps_d[k*${WW} +: ${WW}] = ${Z_WW};
                end
            end
            res_tail_d = (e_res_tail == ${NR_M1}) ? ${Z_RIW} : e_res_tail + ${ONE_RIW};
            o_claim = 1'b1;
            if (e_res_n != ${Z_RCW}) begin
                o_preload_valid = 1'b1;
                o_preload_treelet = ct_max_treelet;
            end
        end else if ((e_mode == ${M_FINAL}) && rays_waiting && free_ok) begin
            // 4a. Final phase: group underpopulated queues into a free slot.
            o_reserve_valid = 1'b1;
            o_reserve_slot = wb_free_slot;
            seq_d = ${S_FILL_NEXT};
            fill_kind_d = ${K_GROUPED};
            fill_slot_d = wb_free_slot;
            fill_res_valid_d = 1'b0;
            fill_res_d = ${Z_RIW};
            fill_need_d = ${WS_LNW};
            fill_started_d = 1'b0;
        end else if ((e_mode == ${M_FINAL}) && rays_waiting && repack_ok) begin
            // 4b. ... or repack a warp with few active rays.
            o_repack_valid = 1'b1;
            o_repack_slot = active_slot;
            o_reserve_valid = 1'b1;
            o_reserve_slot = active_slot;
            seq_d = ${S_FILL_NEXT};
            fill_kind_d = ${K_REPACK};
            fill_slot_d = active_slot;
            fill_res_valid_d = 1'b0;
            fill_res_d = ${Z_RIW};
            fill_need_d = ${WS_LNW} - active_count;
            fill_started_d = 1'b1;
        end else if (enq_valid && (e_mode != ${M_DONE}) && qt_ready && ct_port_free) begin
            // 5. Enqueue a ray: insert it and count it (mirrored in its resident entry).
            o_enq_ready = 1'b1;
            o_qt_op = ${QT_INSERT};
            o_qt_treelet = enq_treelet;
            o_qt_ray = enq_ray;
            o_ct_op = ${CT_ADD};
            o_ct_treelet = enq_treelet;
            o_ct_n = ${ONE_LNW};
            for (k = 0; k < ${NR}; k = k + 1) begin
                if (enq_hit && (enq_idx == k[${RIW1}:0])) begin
                    cnt = res_count_d[k*${RTW} +: ${RTW}];
                    res_count_d[k*${RTW} +: ${RTW}] = (cnt >= ${MAXR}) ? ${MAXR} : cnt + ${ONE_RTW};
                end
            end
            queued_rays_d = (e_queued_rays >= ${MAXR}) ? ${MAXR} : e_queued_rays + ${ONE_RTW};
        end
    end
    ${S_POP_WAIT}: begin
        o_reserve_valid = 1'b1;
        o_reserve_slot = e_fill_slot;
        if (qt_done) begin
            // The popped entry arrived: hand it to the slot being filled.
            popped = (qt_pop_count > ${WS_LNW}) ? ${WS_LNW} : qt_pop_count;
            queued_rays_d = (e_queued_rays > ${POPPED_RTW}) ? e_queued_rays - ${POPPED_RTW} : ${Z_RTW};
            if (e_fill_kind == ${K_TREELET}) begin
                seq_d = ${S_IDLE};
                ptreelet = qt_pop_treelet;
                // Keep the count table in step; an empty pop removes the whole count.
                for (k = 0; k < ${NR}; k = k + 1) begin
                    if (e_fill_res_valid && (e_fill_res == k[${RIW1}:0])) begin
                        cnt = res_count_d[k*${RTW} +: ${RTW}];
                        removed = (popped == ${Z_LNW}) ? cnt : ((${POPPED_RTW} < cnt) ? ${POPPED_RTW} : cnt);
                        res_count_d[k*${RTW} +: ${RTW}] = cnt - removed;
                        if (removed != ${Z_RTW}) begin
                            prm_valid_d = 1'b1;
                            prm_treelet_d = res_treelet_d[k*${TW} +: ${TW}];
                            prm_count_d = removed;
                        end
                        ptreelet = res_treelet_d[k*${TW} +: ${TW}];
                        if (popped != ${Z_LNW})
                            res_warps_d[k*${WW} +: ${WW}] = res_warps_d[k*${WW} +: ${WW}] + ${ONE_WW};
                    end
                end
                if (popped != ${Z_LNW}) begin
${TAKE_FILL_SLOT}
                    o_fill_valid = 1'b1;
                    o_fill_kind = ${K_TREELET};
                    o_fill_slot = e_fill_slot;
                    o_fill_treelet = ptreelet;
                    o_fill_first = 1'b1;
                    o_fill_last = 1'b1;
                    o_fill_count = popped;
                    o_fill_rays = qt_pop_rays & ~(${ONES} << ${SH_POPPED});
                end
            end else begin
                // Grouped warp or repack: take what fits, keep the rest in the spare buffer.
                take = (e_fill_need < popped) ? e_fill_need : popped;
                left_n = popped - take;
                wide = (qt_pop_rays >> ${SH_TAKE}) & ~(${ONES} << ${SH_LEFT});
                spare_rays_d = wide[${SPW1}:0];
                spare_count_d = left_n[${LW1}:0];
                need = e_fill_need - take;
                last = (need == ${Z_LNW}) || ((left_n == ${Z_LNW}) && (queued_rays_d == ${Z_RTW}));
                ef_go = 1'b1;
                ef_last = last;
                ef_count = take;
                ef_rays = qt_pop_rays & ~(${ONES} << ${SH_TAKE});
                fill_need_d = need;
                seq_d = last ? ${S_IDLE} : ${S_FILL_NEXT};
            end
        end
    end
    ${S_FILL_NEXT}: begin
        // Give spare rays, pop another entry, or close the slot.
        o_reserve_valid = 1'b1;
        o_reserve_slot = e_fill_slot;
        if (e_spare_count != ${Z_LW}) begin
            take = (e_fill_need < ${SPARE_LNW}) ? e_fill_need : ${SPARE_LNW};
            left_n = ${SPARE_LNW} - take;
            wide = ({${Z_RW}, e_spare_rays} >> ${SH_TAKE}) & ~(${ONES} << ${SH_LEFT});
            spare_rays_d = wide[${SPW1}:0];
            spare_count_d = left_n[${LW1}:0];
            need = e_fill_need - take;
            last = (need == ${Z_LNW}) || ((left_n == ${Z_LNW}) && (e_queued_rays == ${Z_RTW}));
            ef_go = 1'b1;
            ef_last = last;
            ef_count = take;
            ef_rays = {${Z_RW}, e_spare_rays} & ~(${ONES} << ${SH_TAKE});
            fill_need_d = need;
            if (last) seq_d = ${S_IDLE};
        end else if (e_queued_rays == ${Z_RTW}) begin
            ef_go = 1'b1;
            ef_last = 1'b1;
            seq_d = ${S_IDLE};
        end else if (refill_ok) begin
            // Spilled rays first; the sequence stays here (the refill's answer is ignored).
            o_qt_op = ${QT_REFILL};
        end else if (qt_ready) begin
            o_qt_op = ${QT_POP_ANY};
            seq_d = ${S_POP_WAIT};
        end
    end
    default: begin // ${S_REFILL_WAIT}
        if (qt_done) seq_d = ${S_IDLE};
    end
    endcase

    // emit_fill: give rays to the slot of a grouped warp or repack (or close it).
    if (ef_go && ((ef_count != ${Z_LNW}) || (e_fill_started && ef_last))) begin
        if ((e_fill_kind == ${K_GROUPED}) && !e_fill_started) begin
${FREE_FILL_SLOT}
        end
        o_fill_valid = 1'b1;
        o_fill_kind = e_fill_kind;
        o_fill_slot = e_fill_slot;
        o_fill_first = (e_fill_kind == ${K_GROUPED}) && !e_fill_started;
        o_fill_last = ef_last;
        o_fill_count = ef_count;
        o_fill_rays = ef_rays;
        fill_started_d = 1'b1;
    end

    // Retire resident treelets whose queue is empty and whose warps have all finished (not the
    // one a pop in flight belongs to).
    for (k = 0; k < ${NR}; k = k + 1) begin
        if (res_valid_d[k] && (res_count_d[k*${RTW} +: ${RTW}] == ${Z_RTW})
            && (res_warps_d[k*${WW} +: ${WW}] == ${Z_WW})
            && !((seq_d == ${S_POP_WAIT}) && fill_res_valid_d && (fill_res_d == k[${RIW1}:0]))) begin
            res_valid_d[k] = 1'b0;
            res_treelet_d[k*${TW} +: ${TW}] = ${Z_TW};
            res_count_d[k*${RTW} +: ${RTW}] = ${Z_RTW};
            res_warps_d[k*${WW} +: ${WW}] = ${Z_WW};
        end
    end
    // The head moves to the oldest valid entry (to the tail when the list is empty).
    if (res_valid_d == {${NR}{1'b0}}) begin
        res_head_d = res_tail_d;
    end else begin
        for (k = 0; k < ${NR}; k = k + 1) begin
            at = {1'b0, e_res_head} + k[${RIW}:0];
            if (at >= ${NR_WIDE}) at = at - ${NR_WIDE};
            for (j = 0; j < ${NR}; j = j + 1) begin
                if (!found && (at == j[${RIW}:0]) && res_valid_d[j]) begin
                    found = 1'b1;
                    res_head_d = j[${RIW1}:0];
                end
            end
        end
    end

    // Mode transitions, judged on this cycle's registers and inputs.
    if (e_mode != ${M_DONE}) begin
        if (drained) begin
            mode_d = ${M_DONE};
            // Every ray is traced: clear the counts grouped warps and repacks left behind.
            if (ct_occupancy != ${Z_CE}) o_ct_op = ${CT_CLEAR};
        end
        else if ((e_mode == ${M_INITIAL}) && divergent) mode_d = ${M_TS};
        else if ((e_mode == ${M_TS}) && phase_over) mode_d = ${M_FINAL};
    end
end"#;
