//! RTL of the treelet controller (`vtq_hdl::controller::TreeletController`, paper sections
//! 4.2-4.5, Figure 8): the mode and sequencer FSMs, the resident-treelet list with its parallel
//! comparators and age-order pick, the per-slot bookkeeping, the fill sequence with its lane
//! shifter and spare buffer, and the pending count-table remove.
//!
//! The next-state logic is one combinational block that follows `TreeletController::next_into`
//! step by step (eviction, warp done, termination, pending remove, the sequencer, retirement,
//! mode transitions), each step reading the next-register values the earlier ones wrote, as the
//! Rust code does with its `n` bundle; the outputs are driven from the same block. A `restart`
//! in mode done selects the reset values (all zero) of every register for the cycle: the
//! `e_<register>` wires are the registers the cycle's logic works on.

use super::{
    emit_full_module, emit_text, emit_vector_registers, fill, lit, reg_bits, vector_range, zext,
    DescInfo,
};
use crate::emit::range;
use crate::error::GenError;
use crate::verilog::state_param;
use vtq_hdl::controller::{ControllerFeatures, ControllerWidths, TreeletController};
use vtq_hdl::{bits_for, Block, BlockDesc, Dir, HwConfig};

mod templates;

use templates::{CONSTANTS, NEXT_BODY, NEXT_HEAD, RESIDENT};

/// Looks up bank `name` (or single register, `count` 1) of the description: `(width, count)`.
fn bank(info: &DescInfo, desc: &BlockDesc, name: &str) -> Result<(u32, u32), GenError> {
    desc.registers
        .iter()
        .find(|r| r.name == name)
        .map(|r| (r.width, r.count))
        .ok_or_else(|| info.bad(format!("the RTL needs a register `{name}`")))
}

/// Complete Verilog-2005 for the treelet controller of `cfg` with `features` (module
/// `treelet_controller`), cycle-exact with the Rust block.
pub fn controller_verilog(
    cfg: &HwConfig,
    features: ControllerFeatures,
) -> Result<String, GenError> {
    let block = TreeletController::new(cfg.clone(), features)?;
    let desc = block.describe();
    let info = DescInfo::new(&desc)?;

    // Every width and size from the description, checked against the block's own widths.
    let tw = info.port("ct_max_treelet", Dir::In)?;
    let rw = info.port("enq_ray", Dir::In)?;
    let cw = info.port("ct_max_count", Dir::In)?;
    let lnw = info.port("init_distinct", Dir::In)?;
    let sw = info.port("wb_free_slot", Dir::In)?;
    let qfw = info.port("qt_free_entries", Dir::In)?;
    let cew = info.port("ct_occupancy", Dir::In)?;
    let spw_in = info.port("qt_spilled", Dir::In)?;
    let ctop = info.port("ct_op", Dir::Out)?;
    let qtop = info.port("qt_op", Dir::Out)?;
    let kindw = info.port("fill_kind", Dir::Out)?;
    let lw = info.reg("spare_count")?;
    let riw = info.reg("res_head")?;
    let rtw = info.reg("queued_rays")?;
    let (ww, nr) = bank(&info, &desc, "res_warps")?;
    let (_, ns) = bank(&info, &desc, "slot_terminated")?;
    let (_, spare) = bank(&info, &desc, "spare_rays")?;
    let ws = info.param("warp_size")?;
    let max_rays = info.param("max_rays")?;
    let div = info.param("divergence_threshold")?;
    let upop = info.param("underpopulation_threshold")?;
    let repack = info.param("repack_threshold")?;
    let preload_warps = info.param("preload_threshold_warps")?;
    let group = info.param("group_underpopulated")? != 0;
    let preload = info.param("preload")? != 0;
    let expected = ControllerWidths {
        warp_size: ws as u32,
        warp_slots: ns,
        resident_entries: nr,
        treelet: tw,
        ray: rw,
        count: cw,
        lane: lw,
        lanes: lnw,
        slot: sw,
        resident_index: riw,
        ray_total: rtw,
        warps: ww,
        queue_free: qfw,
        count_entries: cew,
    };
    let derived = block.widths();
    let wsrw = ws as u32 * rw;
    if expected != derived
        || rtw != cw + 1
        || spw_in != rtw
        || spare as u64 != ws - 1
        || info.port("fill_rays", Dir::Out)? != wsrw
        || info.port("qt_pop_rays", Dir::In)? != wsrw
        || info.port("resident_treelet", Dir::Out)? != nr * tw
        || 1u64 << cw != max_rays
    {
        return Err(info.bad(format!(
            "sizes are inconsistent: {expected:?} from the description, {derived:?} from the \
             block, max_rays {max_rays}, {spare} spare lanes"
        )));
    }
    // Every register resets to zero (the reset mode and sequencer states are encoded 0), which
    // is what the `e_<register>` multiplexers select on a restart.
    if let Some(s) = block
        .reg_signals(&block.reset())
        .into_iter()
        .find(|s| s.value != 0)
    {
        return Err(info.bad(format!(
            "register `{}` resets to {}, the RTL expects 0",
            s.name, s.value
        )));
    }
    let fsm = |name: &str, states: &[&str]| {
        desc.fsms
            .iter()
            .find(|f| f.name == name && f.states == states)
            .ok_or_else(|| {
                info.bad(format!(
                    "the RTL needs the FSM `{name}` with states {states:?}"
                ))
            })
    };
    let mode_fsm = fsm(
        "mode",
        &[
            "initial",
            "treelet_stationary",
            "final_ray_stationary",
            "done",
        ],
    )?;
    let seq_fsm = fsm("seq", &["idle", "pop_wait", "fill_next", "refill_wait"])?;

    let shw = bits_for(wsrw as u64);
    let slot_ok = |sig: &str| {
        if ns as u64 == 1u64 << sw {
            "1'b1".to_string()
        } else {
            format!("({sig} < {})", lit(sw, ns as u64))
        }
    };
    // The preload threshold on a resident count: a limit no count reaches is always "low".
    let limit = preload_warps * ws;
    let cur_low = if limit == 0 {
        "1'b0".to_string()
    } else if limit > (1u64 << rtw) - 1 {
        "1'b1".to_string()
    } else {
        format!("(cnt < {})", lit(rtw, limit))
    };
    let max_under = if upop == 0 {
        "1'b0".to_string()
    } else {
        format!("(max_count < {})", lit(rtw, upop))
    };
    let repack_ok = if repack == 0 {
        "1'b0".to_string()
    } else {
        format!(
            "active_valid && {} && (active_count != {}) && (active_count < {})",
            slot_ok("active_slot"),
            lit(lnw, 0),
            lit(lnw, repack)
        )
    };
    // What TreeletController::repack_withheld says: repack_ok's threshold test on the report,
    // in the final phase, with no rays to refill from (the report's slot is not checked).
    let repack_starved = if repack == 0 {
        "1'b0".to_string()
    } else {
        format!(
            "(e_mode == {}) && !rays_waiting && active_valid && (active_count != {}) \
             && (active_count < {})",
            state_param(mode_fsm, "final_ray_stationary"),
            lit(lnw, 0),
            lit(lnw, repack)
        )
    };
    let sh = |x: &str| format!("({} * {})", zext(x, lnw, shw), lit(shw, rw as u64));
    let bool_lit = |b: bool| if b { "1'b1" } else { "1'b0" }.to_string();
    let vars: Vec<(&str, String)> = vec![
        ("WS", ws.to_string()),
        ("NS", ns.to_string()),
        ("NR", nr.to_string()),
        ("TW", tw.to_string()),
        ("RW", rw.to_string()),
        ("RTW", rtw.to_string()),
        ("RIW", riw.to_string()),
        ("WW", ww.to_string()),
        ("SW", sw.to_string()),
        ("LNW", lnw.to_string()),
        ("TW1", (tw - 1).to_string()),
        ("RTW1", (rtw - 1).to_string()),
        ("RIW1", (riw - 1).to_string()),
        ("SW1", (sw - 1).to_string()),
        ("LW1", (lw - 1).to_string()),
        ("LNW1", (lnw - 1).to_string()),
        ("SHW1", (shw - 1).to_string()),
        ("WSRW1", (wsrw - 1).to_string()),
        ("SPW1", (spare * rw - 1).to_string()),
        ("RCW1", (bits_for(nr as u64) - 1).to_string()),
        ("NR_WIDE", lit(riw + 1, nr as u64)),
        ("NR_M1", lit(riw, nr as u64 - 1)),
        ("WS_LNW", lit(lnw, ws)),
        ("WS_RTW", lit(rtw, ws)),
        ("MAXR", lit(rtw, max_rays)),
        ("DIV", lit(lnw, div)),
        ("Z_TW", lit(tw, 0)),
        ("Z_RW", lit(rw, 0)),
        ("Z_RTW", lit(rtw, 0)),
        ("Z_RIW", lit(riw, 0)),
        ("Z_WW", lit(ww, 0)),
        ("Z_SW", lit(sw, 0)),
        ("Z_LNW", lit(lnw, 0)),
        ("Z_QF", lit(qfw, 0)),
        ("Z_SP", lit(rtw, 0)),
        ("Z_CE", lit(cew, 0)),
        ("Z_RCW", lit(bits_for(nr as u64), 0)),
        ("Z_LW", lit(lw, 0)),
        ("Z_SH", lit(shw, 0)),
        ("Z_WSRW", "{${WSRW_ZERO}}".to_string()),
        ("WSRW_ZERO", format!("{wsrw}{{1'b0}}")),
        ("ONES", format!("{{{wsrw}{{1'b1}}}}")),
        ("ONE_RTW", lit(rtw, 1)),
        ("ONE_WW", lit(ww, 1)),
        ("ONE_RIW", lit(riw, 1)),
        ("ONE_RCW", lit(bits_for(nr as u64), 1)),
        ("ONE_LNW", lit(lnw, 1)),
        ("CTW1", (ctop - 1).to_string()),
        ("QTW1", (qtop - 1).to_string()),
        ("KW1", (kindw - 1).to_string()),
        ("CT_ADD", lit(ctop, 1)),
        ("CT_REMOVE", lit(ctop, 2)),
        ("CT_CLEAR", lit(ctop, 3)),
        ("CT_NOP", lit(ctop, 0)),
        ("QT_NOP", lit(qtop, 0)),
        ("QT_INSERT", lit(qtop, 1)),
        ("QT_POP", lit(qtop, 2)),
        ("QT_POP_ANY", lit(qtop, 3)),
        ("QT_REFILL", lit(qtop, 5)),
        ("K_TREELET", lit(kindw, 0)),
        ("K_GROUPED", lit(kindw, 1)),
        ("K_REPACK", lit(kindw, 2)),
        ("M_INITIAL", state_param(mode_fsm, "initial")),
        ("M_TS", state_param(mode_fsm, "treelet_stationary")),
        ("M_FINAL", state_param(mode_fsm, "final_ray_stationary")),
        ("M_DONE", state_param(mode_fsm, "done")),
        ("S_IDLE", state_param(seq_fsm, "idle")),
        ("S_POP_WAIT", state_param(seq_fsm, "pop_wait")),
        ("S_FILL_NEXT", state_param(seq_fsm, "fill_next")),
        ("S_REFILL_WAIT", state_param(seq_fsm, "refill_wait")),
        ("GROUP", bool_lit(group)),
        ("PRELOAD", bool_lit(preload)),
        ("CUR_LOW", cur_low),
        ("MAX_UNDER", max_under),
        ("REPACK_OK", repack_ok),
        ("REPACK_STARVED", repack_starved),
        ("WD_OK", slot_ok("warp_done_slot")),
        ("INIT_OK", slot_ok("init_slot")),
        ("FREE_OK", slot_ok("wb_free_slot")),
        ("POPPED_RTW", zext("popped", lnw, rtw)),
        ("SPARE_LNW", zext("e_spare_count", lw, lnw)),
        ("SH_POPPED", sh("popped")),
        ("SH_TAKE", sh("take")),
        ("SH_LEFT", sh("left_n")),
        (
            "MAX_COUNT",
            format!("{{1'b0, ct_max_count}} + {}", lit(rtw, 1)),
        ),
        ("ZERO_SPARE", lit(spare * rw, 0)),
        ("FREE_DONE_SLOT", set_slot("warp_done_slot", FREE_SLOT, 8)),
        (
            "TAKE_FILL_SLOT",
            set_slot(
                "e_fill_slot",
                ["1'b0", "1'b1", "e_fill_res_valid", "e_fill_res"],
                20,
            ),
        ),
        ("FREE_FILL_SLOT", set_slot("e_fill_slot", FREE_SLOT, 12)),
    ];
    // Two passes: some values contain placeholders themselves.
    let text = |t: &str| fill(&fill(t, &vars), &vars);
    let note = format!(
        "Full RTL (not a skeleton), cycle-exact with vtq_hdl::controller::TreeletController \
         (group_underpopulated = {group}, preload = {preload}): every output equals Block::eval \
         in every cycle (co-simulated by gen/tests/controller_rtl.rs on a reactive random \
         environment, and by `vtq cosim --block controller --scene ...` on a real run's \
         traffic). The next-state logic follows TreeletController::next_into step by step."
    );
    Ok(emit_full_module(&desc, &note, |wr| {
        emit_text(wr, &text(CONSTANTS));
        emit_vector_registers(wr, &desc);
        emit_text(wr, &effective_registers(&desc));
        emit_text(wr, &text(RESIDENT));
        emit_text(wr, &output_regs(&desc));
        emit_text(wr, &text(NEXT_HEAD));
        emit_text(wr, &next_defaults(&desc));
        emit_text(wr, &text(NEXT_BODY));
        emit_text(wr, &output_assigns(&desc));
    }))
}

/// A free slot's bookkeeping: not terminated, no treelet warp, no resident entry.
const FREE_SLOT: [&str; 4] = ["1'b0", "1'b0", "1'b0", "${Z_RIW}"];

/// The next-state block's loop that sets slot `sel`'s bookkeeping registers (terminated,
/// treelet warp, resident entry valid, resident entry) to `values`, at `indent` spaces.
fn set_slot(sel: &str, values: [&str; 4], indent: usize) -> String {
    let regs = [
        "slot_terminated_d[k]",
        "slot_treelet_warp_d[k]",
        "slot_res_valid_d[k]",
        "slot_res_d[k*${RIW} +: ${RIW}]",
    ];
    let mut lines = vec![
        "for (k = 0; k < ${NS}; k = k + 1) begin".to_string(),
        format!("    if ({sel} == k[${{SW1}}:0]) begin"),
    ];
    lines.extend(
        regs.iter()
            .zip(values)
            .map(|(r, v)| format!("        {r} = {v};")),
    );
    lines.extend(["    end".to_string(), "end".to_string()]);
    lines
        .iter()
        .map(|l| format!("{:indent$}{l}", ""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The registers the cycle works on: the registers, or their reset values (all zero) when a
/// `done` controller restarts.
fn effective_registers(desc: &BlockDesc) -> String {
    let mut s = String::from(
        "\n// The registers this cycle's logic works on: the registers, or their reset values (all\n\
         // zero) when a done controller restarts this cycle (a new wave of rays).\n\
         wire restart_now = restart && (mode_q == MODE_DONE);\n",
    );
    for r in &desc.registers {
        let w = reg_bits(r);
        s.push_str(&format!(
            "wire {}e_{} = restart_now ? {} : {}_q;\n",
            vector_range(w),
            r.name,
            lit(w, 0),
            r.name
        ));
    }
    s
}

/// Output ports driven by the combinational block through `o_<port>` (the others: `mode`
/// and the resident list, which come from the effective registers, and `mode_reg`, the mode
/// register itself).
fn driven_outputs(desc: &BlockDesc) -> impl Iterator<Item = &vtq_hdl::PortDesc> {
    desc.ports.iter().filter(|p| {
        p.dir == Dir::Out
            && !matches!(
                p.name.as_str(),
                "mode" | "mode_reg" | "resident_valid" | "resident_treelet"
            )
    })
}

/// Declarations of the `o_<port>` variables.
fn output_regs(desc: &BlockDesc) -> String {
    let mut s = String::from("\n// Output values, computed by the next-state block.\n");
    for p in driven_outputs(desc) {
        s.push_str(&format!("reg {}o_{};\n", range(p.width), p.name));
    }
    s
}

/// The start of the next-state block: every next register is its effective value, every
/// output carries nothing.
fn next_defaults(desc: &BlockDesc) -> String {
    let mut s = String::from("    // Registers hold; outputs carry nothing.\n");
    for r in &desc.registers {
        s.push_str(&format!("    {0}_d = e_{0};\n", r.name));
    }
    for p in driven_outputs(desc) {
        s.push_str(&format!("    o_{} = {};\n", p.name, lit(p.width, 0)));
    }
    s
}

/// The output ports' assignments.
fn output_assigns(desc: &BlockDesc) -> String {
    let mut s = String::from("\n// Outputs.\n");
    for p in desc.ports.iter().filter(|p| p.dir == Dir::Out) {
        let src = match p.name.as_str() {
            "mode" => "e_mode".to_string(),
            "mode_reg" => "mode_q".to_string(),
            "resident_valid" => "ord_valid".to_string(),
            "resident_treelet" => "ord_treelet".to_string(),
            n => format!("o_{n}"),
        };
        s.push_str(&format!("assign {} = {src};\n", p.name));
    }
    s
}
