//! The treelet RT unit's fast path ([`step_in_place`]): the kernel's stages of [`super::wiring`]
//! run once, in dependency order, with the children stepped in place — the RT unit with its
//! lane cache, tables with nothing to do not at all, and a controller that a dry run of its
//! next state found idle only counted in its mode. [`super::TreeletRtUnit`]'s `eval` (the
//! definition, settled by [`crate::compose::settle`]) is what it must equal; tests and
//! debug-build checks compare the two.

use super::wiring::{
    admitting, after_children, children_inputs, controller_inputs, controller_inputs_into,
    place_records, reads_distinct, reset_outputs, set_offering, sm_ready_in, Peeks,
};
use super::{
    probe, TreeletRtUnit, TreeletRtUnitCache, TreeletRtUnitInputs, TreeletRtUnitOutputs,
    TreeletRtUnitRegs,
};
use crate::block::{Block, Cached, Moore, Skip};
use crate::controller::{ControllerInputs, ControllerOutputs, ControllerRegs};
use crate::count_table::CountOp;
use crate::mode::Mode;
use crate::queue_table::QueueOp;
use crate::rt_unit::{NodeDatapath, StatusSelect};

/// Whether a controller cycle did anything: an output other than its mode, or a register
/// change (`regs` before, `next` after).
fn acts(out: &ControllerOutputs, next: &ControllerRegs, regs: &ControllerRegs) -> bool {
    out.ct_op != CountOp::Nop
        || out.qt_op != QueueOp::Nop
        || out.fill.is_some()
        || out.terminate.is_some()
        || out.repack.is_some()
        || out.preload.is_some()
        || out.reserve.is_some()
        || out.enq_ready
        || out.claim
        || next != regs
}

/// The fast path: the kernel's stages once, in dependency order, with the children stepped in
/// place (the RT unit with its lane cache, tables with nothing to do not at all, a controller
/// the last dry run found idle only counted in its mode).
pub(super) fn step_in_place<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    regs: &mut TreeletRtUnitRegs,
    cache: &mut TreeletRtUnitCache,
    inputs: &TreeletRtUnitInputs,
    out: &mut TreeletRtUnitOutputs,
) {
    debug_assert!(
        cache.rt.consistent(&regs.rt),
        "stale RT-unit cache: it must follow every change of the registers"
    );
    reset_outputs(u, out);
    let TreeletRtUnitRegs {
        rt,
        ctl,
        ct,
        qt,
        glue: g,
    } = regs;
    // The probe's registers, as they are at the start of the cycle.
    let probe_regs = cache
        .probe
        .then(|| probe::start_regs(u, (rt, ctl, ct, qt), u.glue_signals(g)));
    super::log_treelet(&mut cache.tables, inputs);
    let offering = inputs.sm_warp.is_some();
    // The RT unit's status ports: computed by the dry run at the end of the last step unless
    // cycles were skipped since or the mode that reads the distinct-treelet counts differs.
    let distinct = reads_distinct(u, ctl, offering);
    if cache.rt_status_current == Some(distinct) {
        debug_assert_eq!(
            cache.rt_status,
            u.rt.status(rt, &cache.rt, StatusSelect::slots(distinct)),
            "stale RT-unit status ports"
        );
    } else {
        u.rt.status_into(
            rt,
            &cache.rt,
            StatusSelect::slots(distinct),
            &mut cache.rt_status,
        );
    }
    cache.rt_status_current = None;
    let arrived = place_records(&u.cfg, g, &cache.rt_status, &inputs.ray_records);
    let peeks = Peeks::of(u, &cache.rt_status, ctl, ct, qt);
    out.sm_ready = sm_ready_in(u, g, peeks.mode, &cache.rt_status);
    let restart = peeks.mode == Mode::Done && offering;
    // The dry run of the last step computed the controller's inputs from these registers,
    // unless cycles were skipped since (they change the RT unit's delays) or it restarts.
    // Its bundle lives in the cache and is filled in place.
    let reused = cache.dry_valid && !restart;
    cache.dry_valid = false;
    let ctl_in = &mut **cache
        .dry
        .get_or_insert_with(|| Box::new(u.ctl.idle_inputs()));
    if reused {
        set_offering(g, peeks.admits(peeks.mode), ctl_in, offering);
        debug_assert_eq!(
            *ctl_in,
            controller_inputs(u, g, &peeks, offering).0,
            "stale cached controller inputs"
        );
    } else {
        controller_inputs_into(g, &peeks, offering, ctl_in);
    }
    let ctl_in: &ControllerInputs = ctl_in;
    super::log_controller(&mut cache.tables, ctl_in);
    let mode = if restart { Mode::Initial } else { peeks.mode };
    let idle = reused && cache.idle && !(offering && admitting(u, mode));
    let ctl_out = if idle {
        debug_assert!(
            {
                let (o, n) = u.ctl.eval(ctl, ctl_in);
                !acts(&o, &n, ctl)
            },
            "the controller was not idle"
        );
        out.counts.ctl.count_cycles(mode, 1);
        // The controller's `repack_starved` output as the dry run found it: the same
        // registers, and inputs that differ at most in the SM's offer, which the active-lane
        // report it depends on does not read.
        debug_assert_eq!(
            cache.repack_starved,
            u.ctl.eval(ctl, ctl_in).0.repack_starved,
            "stale repack verdict"
        );
        out.counts.ctl.repack_starved_cycles += u64::from(cache.repack_starved);
        None
    } else {
        // The next-state function into the scratch registers, then the clock edge (a swap):
        // `eval` without copying the registers' storage.
        let scratch = cache.scratch.get_or_insert_with(|| Box::new(ctl.clone()));
        let o = u.ctl.next_into(ctl, ctl_in, scratch);
        std::mem::swap(ctl, &mut **scratch);
        out.counts.ctl.observe(ctl_in, &o);
        Some(o)
    };
    out.counts.restarts += u64::from(restart);
    // The RT unit's input bundle lives in the cache so its storage is reused every cycle.
    let rt_in = cache.rt_inputs.get_or_insert_with(|| u.rt.idle_inputs());
    let (ct_in, qt_in) = children_inputs(
        u,
        g,
        &peeks,
        inputs,
        restart,
        ctl_in,
        ctl_out.as_ref(),
        arrived,
        out,
        rt_in,
    );
    let qt_busy = !peeks.qt.ready;
    super::log_tables(&mut cache.tables, &ct_in, &qt_in);
    super::log_rt_unit(&mut cache.tables, rt_in);
    // Tables with no op and nothing in progress are not stepped: their registers would not
    // change and their outputs would carry nothing.
    let ct_out = (ct_in.op != CountOp::Nop || !u.ct.gated(ct, &())).then(|| u.ct.step(ct, &ct_in));
    let qt_out =
        (qt_in.op != QueueOp::Nop || qt_in.refill_valid || qt_busy).then(|| u.qt.step(qt, &qt_in));
    let rt_out = u.rt.step_cached(rt, &mut cache.rt, rt_in);
    after_children(u, g, ct_out.as_ref(), qt_out.as_ref(), &rt_out, out);
    if let Some(start) = probe_regs {
        let ins = (ctl_in, &ct_in, &qt_in, &*rt_in);
        let outs = (ctl_out.as_ref(), ct_out.as_ref(), qt_out.as_ref(), &rt_out);
        cache.probed = Some(probe::cycle(u, (ctl, ct, qt), start, ins, outs));
    }
    dry_run(u, regs, cache, idle);
}

/// After a step: whether the controller, evaluated on the new registers with no SM warp
/// offered, would act (so the next cycle may not be skipped), keeping its inputs for the next
/// step. A count-table scan does not wake it: while the scan runs the controller's inputs do
/// not change (the pointers stay stale); the scan's `Nop` cycles are stepped by `skip` and its
/// end bounds `idle_cycles`. `was_idle`: the step left the controller's registers unchanged
/// and it is idle on the inputs in `cache.dry` (the step's); if the new inputs equal them, it
/// is still idle and is not evaluated again.
fn dry_run<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    regs: &TreeletRtUnitRegs,
    cache: &mut TreeletRtUnitCache,
    was_idle: bool,
) {
    cache.idle = false;
    cache.dry_valid = false;
    refresh_rt_status(u, regs, cache);
    let g = &regs.glue;
    if !u.qt.status(&regs.qt, &(), ()).ready
        || g.qt_done.is_some()
        || g.ct_evict.is_some()
        || !g.events.is_empty()
    {
        cache.awake = true;
        return;
    }
    let peeks = Peeks::of(u, &cache.rt_status, &regs.ctl, &regs.ct, &regs.qt);
    let new = cache
        .dry_spare
        .get_or_insert_with(|| Box::new(u.ctl.idle_inputs()));
    controller_inputs_into(g, &peeks, false, new);
    if was_idle && cache.dry.as_ref() == Some(new) {
        debug_assert!(
            {
                let (o, n) = u.ctl.eval(&regs.ctl, new);
                !acts(&o, &n, &regs.ctl)
            },
            "an idle controller with unchanged registers and inputs acts"
        );
        cache.dry_valid = true;
        cache.idle = true;
        cache.awake = false;
        return;
    }
    std::mem::swap(&mut cache.dry, &mut cache.dry_spare);
    let inp = cache.dry.as_deref().expect("filled above");
    let scratch = cache
        .scratch
        .get_or_insert_with(|| Box::new(regs.ctl.clone()));
    let o = u.ctl.next_into(&regs.ctl, inp, scratch);
    let acts = acts(&o, scratch, &regs.ctl);
    cache.repack_starved = o.repack_starved;
    cache.dry_valid = true;
    cache.idle = !acts;
    cache.awake = acts;
}

/// Computes the RT unit's status ports of the current registers into the cache, with the
/// distinct-treelet counts if the controller reads them with no SM warp offered; they stay
/// current until the registers change.
pub(super) fn refresh_rt_status<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    regs: &TreeletRtUnitRegs,
    cache: &mut TreeletRtUnitCache,
) {
    let distinct = reads_distinct(u, &regs.ctl, false);
    u.rt.status_into(
        &regs.rt,
        &cache.rt,
        StatusSelect::slots(distinct),
        &mut cache.rt_status,
    );
    cache.rt_status_current = Some(distinct);
}
