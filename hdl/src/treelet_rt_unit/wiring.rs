//! The treelet RT unit's wiring kernel over its registers ([`GlueRegs`], in `glue.rs`), written
//! as three stages in dependency order — the controller's inputs from registers
//! ([`controller_inputs`]), the children's inputs from the controller's outputs
//! ([`children_inputs`]), the block's outputs and next registers from the children's outputs
//! ([`after_children`]). [`kernel`] chains them for [`crate::compose::settle`] (the block's
//! `eval`); `fast_path.rs` runs them once with the children stepped in place.

use super::glue::{Build, Event, GlueFault, GlueRegs, SlotUse};
use super::{
    ChildInputs, ChildOutputs, FinishedRay, ParkedRay, RayLoad, TreeletCounts, TreeletRequest,
    TreeletRtUnit, TreeletRtUnitInputs, TreeletRtUnitOutputs, TreeletRtUnitRegs,
};
use crate::block::{Block, Moore};
use crate::bounded::BoundedVec;
use crate::config::HwConfig;
use crate::controller::{
    ActiveReport, ControllerInputs, ControllerOutputs, ControllerRegs, EnqueueRequest, FillCommand,
    FillKind, InitReport,
};
use crate::count_table::{CountOp, CountTableIn, CountTableOut, CountTableRegs, CountTableStatus};
use crate::mode::Mode;
use crate::queue_table::{QueueOp, QueueTableIn, QueueTableOut, QueueTableRegs, QueueTableStatus};
use crate::rt_unit::{
    IssueTarget, LaneWrite, NodeDatapath, RayOutcome, RayRecord, RtUnitInputs, RtUnitOutputs,
    RtUnitStatus, TraversalOrder, WarpDone, WarpIssue, CHUNK_BYTES,
};

/// The children's register-only output ports, read by the kernel before the children's inputs
/// are known: the RT unit's status ports, the tables' status and the controller's mode.
pub(super) struct Peeks<'a> {
    rt: &'a RtUnitStatus,
    ct: CountTableStatus,
    /// The queue table's status.
    pub(super) qt: QueueTableStatus,
    /// The controller's mode register.
    pub(super) mode: Mode,
    /// SM warps are admitted in treelet-stationary mode (a controller feature).
    admit_ts: bool,
}

impl<'a> Peeks<'a> {
    /// Whether SM warps are admitted in mode `mode` ([`admitting`]).
    pub(super) fn admits(&self, mode: Mode) -> bool {
        admits_in(mode, self.admit_ts)
    }

    /// The peeks from the children's register-only outputs ([`Moore`]): the RT unit's status
    /// ports `rt`, the count table's and queue table's status and the controller's mode
    /// register.
    pub(super) fn new<D: NodeDatapath>(
        u: &TreeletRtUnit<D>,
        rt: &'a RtUnitStatus,
        ct: CountTableStatus,
        qt: QueueTableStatus,
        mode: Mode,
    ) -> Self {
        Peeks {
            rt,
            ct,
            qt,
            mode,
            admit_ts: u.ctl.features().admit_in_treelet_stationary,
        }
    }

    /// The peeks as the children's output ports carry them (the RT unit's status ports `rt`):
    /// what the block's definition and the wiring's RTL read.
    pub(super) fn from_ports<D: NodeDatapath>(
        u: &TreeletRtUnit<D>,
        rt: &'a RtUnitStatus,
        ctl: &ControllerOutputs,
        ct: &CountTableOut,
        qt: &QueueTableOut,
    ) -> Self {
        Peeks::new(u, rt, ct.status(), qt.status(), ctl.mode_reg)
    }

    /// The peeks of the children's registers with the RT unit's status ports `rt` (of its
    /// registers): the children's [`Moore::status`], for the fast path, which steps them in
    /// dependency order.
    pub(super) fn of<D: NodeDatapath>(
        u: &TreeletRtUnit<D>,
        rt: &'a RtUnitStatus,
        ctl: &ControllerRegs,
        ct: &CountTableRegs,
        qt: &QueueTableRegs,
    ) -> Self {
        Peeks::new(
            u,
            rt,
            u.ct.status(ct, &(), ()),
            u.qt.status(qt, &(), ()),
            u.ctl.status(ctl, &(), ()),
        )
    }
}

/// The kernel: `(inputs, registers, children's outputs) -> (children's inputs, (outputs, next
/// wiring registers))`, the three stages chained.
pub(super) fn kernel<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    glue: &GlueRegs,
    peeks: &Peeks,
    inputs: &TreeletRtUnitInputs,
    q: &ChildOutputs,
) -> (ChildInputs, (TreeletRtUnitOutputs, GlueRegs)) {
    let mut g = glue.clone();
    let mut out = empty_outputs(u);
    let arrived = place_records(&u.cfg, &mut g, peeks.rt, &inputs.ray_records);
    out.sm_ready = sm_ready_in(u, &g, peeks.mode, peeks.rt);
    let (ctl_in, restart) = controller_inputs(u, &g, peeks, inputs.sm_warp.is_some());
    out.counts.restarts += u64::from(restart);
    out.counts.ctl.observe(&ctl_in, &q.ctl);
    let mut rt_in = u.rt.idle_inputs();
    let (ct_in, qt_in) = children_inputs(
        u,
        &mut g,
        peeks,
        inputs,
        restart,
        &ctl_in,
        Some(&q.ctl),
        arrived,
        &mut out,
        &mut rt_in,
    );
    after_children(u, &mut g, Some(&q.ct), Some(&q.qt), &q.rt, &mut out);
    let d = ChildInputs {
        ctl: ctl_in,
        ct: ct_in,
        qt: qt_in,
        rt: rt_in,
    };
    (d, (out, g))
}

/// Outputs with nothing happening.
pub(super) fn empty_outputs<D: NodeDatapath>(u: &TreeletRtUnit<D>) -> TreeletRtUnitOutputs {
    TreeletRtUnitOutputs {
        widths: u.widths,
        sm_ready: false,
        resp_free: 0,
        sm_accepted: None,
        requests: Vec::new(),
        finished: Vec::new(),
        parked: Vec::new(),
        preload: None,
        spill_push: None,
        spill_pop: false,
        errors: 0,
        first_error: None,
        fault: None,
        counts: TreeletCounts::default(),
    }
}

/// Resets `out` to [`empty_outputs`] keeping its lists' storage, so a step that writes into a
/// bundle it is given allocates nothing for them.
pub(super) fn reset_outputs<D: NodeDatapath>(u: &TreeletRtUnit<D>, out: &mut TreeletRtUnitOutputs) {
    out.widths = u.widths;
    out.sm_ready = false;
    out.resp_free = 0;
    out.sm_accepted = None;
    out.requests.clear();
    out.finished.clear();
    out.parked.clear();
    out.preload = None;
    out.spill_push = None;
    out.spill_pop = false;
    out.errors = 0;
    out.first_error = None;
    out.fault = None;
    out.counts = TreeletCounts::default();
}

/// Stage 0: ray records that arrived (at most the record ports, all for one slot: more, or
/// another slot's, is a fault and those are not taken) find their fill's entries and the lanes
/// they are issued to ([`Build::filled`]); returned as the cycle's lane write, which goes to
/// the RT unit on the issue bus (or with the fill's issue, if the fill completes this cycle).
/// `rt` is the RT unit's status ports (a repack's records go to the held warp's inactive
/// lanes).
pub(super) fn place_records(
    cfg: &HwConfig,
    g: &mut GlueRegs,
    rt: &RtUnitStatus,
    records: &[RayLoad],
) -> Option<LaneWrite> {
    let ports = cfg.record_ports();
    if records.len() > ports as usize {
        g.set_fault(GlueFault::Full {
            what: "ray-record ports",
            depth: ports as usize,
        });
    }
    let mut write: Option<LaneWrite> = None;
    for load in records.iter().take(ports as usize) {
        let s = load.slot as usize;
        if load.slot != records[0].slot {
            g.set_fault(GlueFault::MixedRecords {
                first: records[0].slot,
                other: load.slot,
            });
            continue;
        }
        // The fill's entry waiting for this ray.
        let found = g.builds.get_mut(s).and_then(Option::as_mut).and_then(|b| {
            let mut waiting = b.rays.iter().zip(b.arrived.iter());
            let k = waiting.position(|(&r, &arrived)| r == load.ray && !arrived)?;
            Some((b, k))
        });
        let Some((build, k)) = found else {
            g.set_fault(GlueFault::UnexpectedRecord {
                slot: load.slot,
                ray: load.ray,
            });
            continue;
        };
        build.arrived.as_mut_slice()[k] = true;
        build.loading = build.loading.saturating_sub(1);
        let lanes = cfg.warp_size as usize;
        let lane = match build.kind {
            FillKind::Repack => {
                let inactive = rt.slot(s).map_or(0, |v| v.inactive);
                (0..lanes).find(|&l| (inactive & !build.filled) >> l & 1 == 1)
            }
            FillKind::Treelet | FillKind::Grouped => Some(k),
        };
        match lane {
            // The fill knows the ray's id: the record's own is not on the ports.
            Some(l) => {
                build.filled |= 1 << l;
                let w = write.get_or_insert_with(|| LaneWrite {
                    slot: load.slot,
                    lanes: vec![None; lanes],
                });
                w.lanes[l] = Some(RayRecord {
                    ray_id: load.ray,
                    ..load.record.clone()
                });
            }
            None => {
                let placed = build.filled.count_ones() as usize;
                let rays = build.rays.len();
                g.set_fault(GlueFault::Unplaced {
                    slot: load.slot,
                    placed,
                    rays,
                });
            }
        }
    }
    write
}

/// Whether the controller's reports this cycle read the RT unit's distinct-treelet counts
/// (`status_distinct`): in the modes that terminate divergent warps, the mode after a restart
/// if the SM `offering` a warp restarts a `done` controller.
pub(super) fn reads_distinct<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    ctl: &ControllerRegs,
    offering: bool,
) -> bool {
    u.ctl
        .status(ctl, &(), ())
        .restarted_if(offering)
        .terminates_divergent_warps()
}

/// Whether SM warps are admitted in controller mode `mode`: not in the final ray-stationary
/// phase, which traverses the rays it grouped "until all of them have finished traversal
/// completely before fetching new rays to process" (section 4.4), nor in the
/// treelet-stationary mode when the controller's features keep them out of it.
pub(super) fn admitting<D: NodeDatapath>(u: &TreeletRtUnit<D>, mode: Mode) -> bool {
    admits_in(mode, u.ctl.features().admit_in_treelet_stationary)
}

/// [`admitting`] with the treelet-stationary switch `admit_ts`.
fn admits_in(mode: Mode, admit_ts: bool) -> bool {
    match mode {
        Mode::FinalRayStationary => false,
        Mode::TreeletStationary => admit_ts,
        Mode::Initial | Mode::Done => true,
    }
}

/// The `sm_ready` output ([`super::TreeletRtUnitStatus::sm_ready`]) from the wiring's registers `g` (its slots and free ids; the records
/// that arrive in a cycle change neither), the controller's mode and the RT unit's status.
pub(super) fn sm_ready_in<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    g: &GlueRegs,
    mode: Mode,
    rt: &RtUnitStatus,
) -> bool {
    admitting(u, mode) && g.ids.available() >= u.cfg.warp_size && free_slot(g, rt, None).is_some()
}

/// The lowest slot the wiring has not given out and whose RT-unit slot holds no warp, other
/// than `reserved`.
fn free_slot(g: &GlueRegs, rt: &RtUnitStatus, reserved: Option<u32>) -> Option<u32> {
    (0..g.uses.len() as u32).find(|&s| {
        g.uses[s as usize] == SlotUse::Free && rt.slot(s as usize).is_none() && reserved != Some(s)
    })
}

/// Whether the wiring has work in the next cycle whatever the children do: events to report or
/// a complete fill to issue.
pub(super) fn glue_busy(g: &GlueRegs) -> bool {
    !g.events.is_empty() || g.builds.iter().flatten().any(|b| b.last && b.loading == 0)
}

/// Sets the controller inputs that depend on whether the SM offers a warp: its waiting warps
/// count as initial-phase warps and keep `launch_done` low while SM warps are admitted.
/// `admits`: SM warps are admitted in the controller's mode ([`admitting`]).
pub(super) fn set_offering(g: &GlueRegs, admits: bool, inp: &mut ControllerInputs, offering: bool) {
    let waiting = offering && admits;
    inp.launch_done = !waiting;
    inp.initial_warps = g.uses.contains(&SlotUse::Initial) || waiting;
    inp.restart = offering;
}

/// Stage 1: the controller's inputs, from registers only, and whether it restarts (a
/// controller that is `done` restarts when the SM offers a warp).
pub(super) fn controller_inputs<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    g: &GlueRegs,
    p: &Peeks,
    offering: bool,
) -> (ControllerInputs, bool) {
    let mut inp = u.ctl.idle_inputs();
    let restart = controller_inputs_into(g, p, offering, &mut inp);
    (inp, restart)
}

/// The controller's active-lane report in mode `mode`: in the final ray-stationary phase, the
/// warp with the fewest lanes a repack cannot release (`status_busy`) among those that neither
/// complete this cycle, are held, are being built nor stop at treelet boundaries.
pub(super) fn active_report(g: &GlueRegs, p: &Peeks, mode: Mode) -> Option<ActiveReport> {
    if mode != Mode::FinalRayStationary {
        return None;
    }
    let mut best: Option<ActiveReport> = None;
    for s in 0..g.uses.len() {
        let Some(view) = p.rt.slot(s) else {
            continue;
        };
        let sum = &view.summary;
        // A warp that completes this cycle (quiescent, not held), one held by a repack, one
        // being built or one stopping at treelet boundaries is not reported.
        if sum.quiescent
            || view.held
            || g.builds[s].is_some()
            || view.order == TraversalOrder::TreeletStop
        {
            continue;
        }
        let r = ActiveReport {
            slot: s as u32,
            active: sum.busy,
        };
        if best.is_none_or(|b| r.active < b.active) {
            best = Some(r);
        }
    }
    best
}

/// [`controller_inputs`] written into `inp` (every field but the widths, so its old contents do
/// not matter if it came from this controller's `idle_inputs`):
/// the fast path keeps one bundle and fills it in place. Returns whether the controller
/// restarts.
pub(super) fn controller_inputs_into(
    g: &GlueRegs,
    p: &Peeks,
    offering: bool,
    inp: &mut ControllerInputs,
) -> bool {
    let restart = p.mode == Mode::Done && offering;
    let mode = if restart { Mode::Initial } else { p.mode };
    set_offering(g, p.admits(mode), inp, offering);
    inp.rt_idle = p.rt.is_empty() && g.builds.iter().all(Option::is_none) && g.events.is_empty();
    inp.wb_free_slot = free_slot(g, p.rt, None);
    let mut best_init: Option<InitReport> = None;
    for (s, use_) in g.uses.iter().enumerate() {
        let slot = s as u32;
        let Some(view) = p.rt.slot(s) else {
            continue;
        };
        let initial = *use_ == SlotUse::Initial
            && view.order != TraversalOrder::TreeletStop
            && mode.terminates_divergent_warps();
        // The RT unit counts distinct next treelets for warps in treelet-continue order, which
        // an initial-phase warp not stopped keeps; they matter only to an initial report.
        let mut sum = view.summary;
        if !initial {
            sum.distinct_next_treelets = 0;
        }
        if sum.quiescent && !view.held {
            continue; // completes this cycle
        }
        if initial {
            let r = InitReport {
                slot,
                active: sum.traversing,
                distinct: sum.distinct_next_treelets,
            };
            if best_init.is_none_or(|b| r.distinct > b.distinct) {
                best_init = Some(r);
            }
        }
    }
    inp.init_report = best_init;
    inp.active_report = active_report(g, p, mode);
    inp.warp_done = None;
    inp.enqueue = None;
    match g.events.front() {
        Some(Event::WarpDone(s)) => inp.warp_done = Some(*s),
        Some(&Event::Enqueue { ray, treelet }) => {
            inp.enqueue = Some(EnqueueRequest { ray, treelet })
        }
        None => {}
    }
    inp.ct = p.ct;
    inp.ct_evict = g.ct_evict;
    inp.qt = p.qt;
    inp.qt_done.clone_from(&g.qt_done);
    restart
}

/// Stage 2: from the controller's outputs (`None`: it did nothing but wait this cycle), the
/// tables' inputs (returned) and the RT unit's (written into `rt_in`, whatever it held, so a
/// caller may reuse its storage); fills start loading their records, a complete fill is
/// issued, the records that `arrived` this cycle are written into their lanes (with the
/// issue, if they complete it), or else (the bus is free) an offered SM warp may enter.
#[allow(clippy::too_many_arguments)]
pub(super) fn children_inputs<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    g: &mut GlueRegs,
    p: &Peeks,
    inputs: &TreeletRtUnitInputs,
    restart: bool,
    ctl_in: &ControllerInputs,
    ctl_out: Option<&ControllerOutputs>,
    mut arrived: Option<LaneWrite>,
    out: &mut TreeletRtUnitOutputs,
    rt_in: &mut RtUnitInputs,
) -> (CountTableIn, QueueTableIn) {
    let mode = if restart { Mode::Initial } else { p.mode };
    if ctl_in.warp_done.is_some() || ctl_out.is_some_and(|o| o.enq_ready) {
        if let Some(Event::WarpDone(s)) = g.events.pop_front() {
            g.uses[s as usize] = SlotUse::Free;
        }
    }
    let ct_in = CountTableIn {
        op: ctl_out.map_or(CountOp::Nop, |o| o.ct_op),
        ..u.ct.idle_inputs()
    };
    let qt_op = ctl_out.map_or(QueueOp::Nop, |o| o.qt_op);
    let qt_in = match inputs.spill_head {
        Some((t, r)) if p.qt.refill_waiting => {
            out.spill_pop = true;
            out.counts.refills += 1;
            QueueTableIn {
                refill_valid: true,
                refill_treelet: t,
                refill_ray: r,
                ..u.qt.idle_inputs()
            }
        }
        _ => QueueTableIn {
            op: qt_op,
            ..u.qt.idle_inputs()
        },
    };
    out.preload = ctl_out.and_then(|o| o.preload);
    if let Some(fill) = ctl_out.and_then(|o| o.fill.as_ref()) {
        start_fill(u, g, fill, out);
    }
    rt_in.responses.clear();
    rt_in.responses.extend_from_slice(&inputs.responses);
    rt_in.stop = ctl_out.and_then(|o| o.terminate);
    rt_in.repack = ctl_out.and_then(|o| o.repack);
    rt_in.issue = finished_build(u, g, p, &mut arrived);
    rt_in.write = arrived;
    let reserve = ctl_out.and_then(|o| o.reserve);
    if rt_in.issue.is_none() && rt_in.write.is_none() && admitting(u, mode) {
        let slot = free_slot(g, p.rt, reserve);
        if let (Some(slot), Some(lanes)) = (slot, inputs.sm_warp.as_ref()) {
            rt_in.issue = admit(u, g, slot, lanes, out);
        }
    }
    (ct_in, qt_in)
}

/// Starts loading the records of a fill's rays.
fn start_fill<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    g: &mut GlueRegs,
    fill: &FillCommand,
    out: &mut TreeletRtUnitOutputs,
) {
    let s = fill.slot as usize;
    let lanes = u.cfg.warp_size as usize;
    let build = g.builds[s].get_or_insert_with(|| Build {
        kind: fill.kind,
        rays: BoundedVec::new(lanes),
        arrived: BoundedVec::new(lanes),
        filled: 0,
        loading: 0,
        last: false,
    });
    let mut full = None;
    for &ray in &fill.rays {
        match build
            .rays
            .push(ray)
            .and_then(|()| build.arrived.push(false))
        {
            Ok(()) => build.loading += 1,
            Err(f) => full = Some(f),
        }
    }
    build.last |= fill.last;
    if let Some(f) = full {
        g.set_fault(GlueFault::Full {
            what: "fill of a slot",
            depth: f.capacity,
        });
    }
    if fill.kind != FillKind::Repack {
        g.uses[s] = SlotUse::Controller;
    }
    for &ray in &fill.rays {
        out.requests.push(TreeletRequest::RayLoad {
            slot: fill.slot,
            ray,
            address: u.ray_base + ray as u64 * CHUNK_BYTES as u64,
        });
        out.counts.ray_loads += 1;
    }
}

/// The warp issue of the first fill whose rays have all arrived and which is complete: each
/// lane enters from the record written into it before, or from the bus if its record arrived
/// this cycle (taken out of `arrived`, the cycle's lane write, when it is for this slot).
fn finished_build<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    g: &mut GlueRegs,
    p: &Peeks,
    arrived: &mut Option<LaneWrite>,
) -> Option<WarpIssue> {
    let s = g
        .builds
        .iter()
        .position(|b| b.as_ref().is_some_and(|b| b.last && b.loading == 0))?;
    let build = g.builds[s].take()?;
    let slot = s as u32;
    let rays = build.rays.len();
    let (order, target) = match build.kind {
        FillKind::Treelet => (TraversalOrder::TreeletStop, IssueTarget::Slot(slot)),
        FillKind::Grouped => (TraversalOrder::TreeletContinue, IssueTarget::Slot(slot)),
        FillKind::Repack => (
            p.rt.slot(s)
                .map_or(TraversalOrder::RayStationary, |v| v.order),
            IssueTarget::Append { slot, last: true },
        ),
    };
    let on_bus = arrived.take_if(|w| w.slot == slot);
    let bus = on_bus.as_ref().map_or(0, LaneWrite::mask);
    let lanes = on_bus.map_or_else(|| vec![None; u.cfg.warp_size as usize], |w| w.lanes);
    let placed = build.filled.count_ones() as usize;
    if placed != rays {
        g.set_fault(GlueFault::Unplaced { slot, placed, rays });
    }
    Some(WarpIssue {
        order,
        lanes,
        target,
        written: build.filled & !bus,
    })
}

/// Takes an offered SM warp into `slot` if enough ray ids are available: gives its active
/// lanes, in order, ids from the free-id stack ([`super::IdPool`]), stores their records and
/// returns the warp issue.
fn admit<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    g: &mut GlueRegs,
    slot: u32,
    offered: &[Option<RayRecord>],
    out: &mut TreeletRtUnitOutputs,
) -> Option<WarpIssue> {
    let need = offered.iter().flatten().count() as u32;
    if g.ids.available() < need {
        return None;
    }
    let mut lanes: Vec<Option<RayRecord>> = offered.to_vec();
    lanes.resize(u.cfg.warp_size as usize, None);
    let mut ids = vec![None; lanes.len()];
    let mut given = g.ids.take(need);
    for (rec, id_out) in lanes.iter_mut().zip(&mut ids) {
        let Some(rec) = rec.as_mut() else { continue };
        let id = given.next()?;
        rec.ray_id = id;
        *id_out = Some(id);
        out.requests.push(TreeletRequest::RayStore {
            ray: id,
            address: u.ray_base + id as u64 * CHUNK_BYTES as u64,
        });
        out.counts.ray_stores += 1;
    }
    g.uses[slot as usize] = SlotUse::Initial;
    out.sm_accepted = Some(ids);
    Some(WarpIssue {
        order: TraversalOrder::TreeletContinue,
        lanes,
        target: IssueTarget::Slot(slot),
        written: 0,
    })
}

/// Stage 3: the tables' answers are registered for the next cycle, a spilled entry goes to the
/// spill FIFO, and the RT unit's completed warp is unpacked: finished rays leave with their
/// hits and free their ids, rays stopped at a boundary leave their records to the store and are
/// queued for enqueueing, then the slot's `warp_done`.
/// A table that was not stepped (`None`: no op and nothing in progress) answers nothing.
pub(super) fn after_children<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    g: &mut GlueRegs,
    ct: Option<&CountTableOut>,
    qt: Option<&QueueTableOut>,
    rt: &RtUnitOutputs,
    out: &mut TreeletRtUnitOutputs,
) {
    g.ct_evict = ct.filter(|o| o.evict_valid).map(|o| o.evict_treelet as u32);
    if ct.is_some_and(|o| o.error) {
        g.set_fault(GlueFault::TableError("the count table rejected an op"));
    }
    if qt.is_some_and(|o| o.error) {
        g.set_fault(GlueFault::TableError("the queue table rejected an op"));
    }
    if let Some(o) = qt.filter(|o| o.spill_valid) {
        out.spill_push = Some((o.spill_treelet, o.spill_ray));
        out.counts.spills += 1;
    }
    g.qt_done = qt.and_then(QueueTableOut::popped);
    if let Some(req) = rt.request {
        out.requests.push(TreeletRequest::Rt(req));
    }
    out.counts.rt = rt.counts;
    out.resp_free = rt.resp_free;
    out.errors = rt.errors;
    out.first_error = rt.first_error;
    if rt.released.is_some() || rt.done.is_some() {
        let first = out.finished.len();
        if let Some(done) = &rt.released {
            unpack(u, g, done, 0, out);
        }
        if let Some(done) = &rt.done {
            unpack(u, g, done, u.cfg.warp_size, out);
            g.uses[done.slot as usize] = SlotUse::Closing;
            g.push_event(Event::WarpDone(done.slot));
        }
        // The finished rays' ids are pushed on the free-id stack, in position order.
        let back = &out.finished[first..];
        if let Err(in_use) = g.ids.give(back.iter().map(|f| f.ray)) {
            g.set_fault(GlueFault::IdsReturned {
                returned: back.len() as u32,
                in_use,
            });
        }
    }
    out.fault = g.fault.clone();
}

/// Returns finished rays (lane `l` at position `base + l`) and parks stopped ones. A parked
/// ray is queued for the treelet of its next node (the record's, as the RT unit's completion
/// ports carry it).
fn unpack<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    g: &mut GlueRegs,
    done: &WarpDone,
    base: u32,
    out: &mut TreeletRtUnitOutputs,
) {
    let lanes = done.lanes.iter().enumerate();
    for (lane, (rec, outcome)) in lanes.filter_map(|(l, x)| Some((l as u32, x.as_ref()?))) {
        let id = rec.ray_id;
        match *outcome {
            RayOutcome::Finished => {
                out.finished.push(FinishedRay {
                    position: base + lane,
                    ray: id,
                    hit: rec.hit,
                });
            }
            RayOutcome::AtBoundary { .. } => {
                let treelet = rec.next_node().map_or(0, |n| u.rt.treelet_of(n.address));
                out.parked.push(ParkedRay {
                    lane,
                    record: rec.clone(),
                });
                g.push_event(Event::Enqueue {
                    ray: id,
                    treelet: treelet as u32,
                });
            }
        }
    }
}

/// A summary of the registers for a watchdog's dump.
pub(super) fn debug_state<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    regs: &TreeletRtUnitRegs,
) -> String {
    let g = &regs.glue;
    format!(
        "{}\n  treelet controller: {}; queue table {}; count table {} entries; events {}; slots \
         {:?}; fills {:?}; {} ray ids in use",
        u.rt.debug_state(&regs.rt),
        u.ctl.debug_state(&regs.ctl),
        u.qt.debug_state(&regs.qt),
        u.ct.status(&regs.ct, &(), ()).occupancy,
        g.events.len(),
        g.uses,
        g.builds
            .iter()
            .map(|b| b
                .as_ref()
                .map(|b| (b.kind, b.rays.len(), b.loading, b.last)))
            .collect::<Vec<_>>(),
        g.ids.in_use()
    )
}

#[cfg(test)]
mod tests;
