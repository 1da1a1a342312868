//! The treelet RT unit's wiring: its registers ([`GlueRegs`]) and its kernel, written as three
//! stages in dependency order — the controller's inputs from registers
//! ([`controller_inputs`]), the children's inputs from the controller's outputs
//! ([`children_inputs`]), the block's outputs and next registers from the children's outputs
//! ([`after_children`]). [`kernel`] chains them for [`crate::compose::settle`] (the block's
//! `eval`); [`step_in_place`] runs them once with the children stepped in place (the fast path).

use std::fmt;

use super::{
    probe, FinishedRay, RayLoad, TreeletCounts, TreeletRequest, TreeletRtUnit, TreeletRtUnitCache,
    TreeletRtUnitInputs, TreeletRtUnitOutputs, TreeletRtUnitRegs, TreeletRtUnitWidths,
};
use crate::bits::bits_for;
use crate::block::Block;
use crate::bounded::{BoundedDeque, BoundedVec};
use crate::config::HwConfig;
use crate::controller::{
    ActiveReport, ControllerInputs, ControllerOutputs, ControllerRegs, EnqueueRequest, FillCommand,
    FillKind, InitReport,
};
use crate::count_table::{CountOp, CountTableIn, CountTableOut, CountTableRegs, CountTableStatus};
use crate::mode::Mode;
use crate::queue_table::{
    PopResult, QueueOp, QueueTableIn, QueueTableOut, QueueTableRegs, QueueTableStatus,
};
use crate::registers::RegTable;
use crate::rt_unit::{
    IssueTarget, NodeDatapath, RayOutcome, RayRecord, RtCache, RtUnitInputs, RtUnitOutputs,
    RtUnitRegs, RtUnitStatus, TraversalOrder, WarpDone, WarpIssue, CHUNK_BYTES,
};

/// Who owns a warp-buffer slot, as the wiring sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlotUse {
    /// Free for an SM warp or a controller fill (code 0).
    Free,
    /// An SM warp in its initial traversal phase, possibly terminated (code 1).
    Initial,
    /// A warp the controller filled (treelet or grouped), building or traversing (code 2).
    Controller,
    /// Its warp completed; enqueues and `warp_done` still to deliver (code 3).
    Closing,
}

impl SlotUse {
    /// The encoding.
    fn code(self) -> u64 {
        match self {
            SlotUse::Free => 0,
            SlotUse::Initial => 1,
            SlotUse::Controller => 2,
            SlotUse::Closing => 3,
        }
    }
}

/// A fill the controller is giving to a slot: its rays, and their records as they arrive.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Build {
    /// What the fill builds.
    pub kind: FillKind,
    /// Ray ids, in the order they are placed in the slot's lanes (at most `warp_size`).
    pub rays: BoundedVec<u32>,
    /// The loaded record of each ray (`None` until it arrives; at most `warp_size`).
    pub records: BoundedVec<Option<RayRecord>>,
    /// Records not yet arrived.
    pub loading: u32,
    /// The controller closed the fill.
    pub last: bool,
}

/// Something the RT unit reports to the controller after a warp completes, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    /// A ray stopped at a treelet boundary: insert it into that treelet's queue.
    Enqueue {
        /// Ray id.
        ray: u32,
        /// The treelet it needs next.
        treelet: u32,
    },
    /// The slot's warp has sent all its rays.
    WarpDone(u32),
}

/// An inconsistency the wiring found (a modelling bug, reported rather than giving wrong
/// numbers).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum GlueFault {
    /// A ray left the RT unit with an id that is not in use.
    UnknownRay(u32),
    /// A table raised its error output for an op.
    TableError(&'static str),
    /// A fill could not place all of its rays.
    Unplaced {
        /// The slot.
        slot: u32,
        /// Rays placed.
        placed: usize,
        /// Rays of the fill.
        rays: usize,
    },
    /// A ray record arrived for a fill that did not ask for it.
    UnexpectedRecord {
        /// The slot named.
        slot: u32,
        /// The ray.
        ray: u32,
    },
    /// A register array of the wiring was full (its depth is too small for the protocol).
    Full {
        /// The array.
        what: &'static str,
        /// Its depth.
        depth: usize,
    },
}

impl fmt::Display for GlueFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GlueFault::UnknownRay(id) => {
                write!(f, "ray id {id} left the RT unit but is not in use")
            }
            GlueFault::TableError(what) => write!(f, "{what}"),
            GlueFault::Unplaced { slot, placed, rays } => write!(
                f,
                "a fill of slot {slot} placed {placed} of its {rays} rays"
            ),
            GlueFault::UnexpectedRecord { slot, ray } => {
                write!(
                    f,
                    "a record of ray {ray} arrived for slot {slot}, which did not ask for it"
                )
            }
            GlueFault::Full { what, depth } => {
                write!(f, "the wiring's {what} ({depth} entries) overflowed")
            }
        }
    }
}

/// The ray-record slots of an SM (`max_rays` ray ids) as a bitmap of free ids; the lowest free
/// id is given first (a priority encoder).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IdPool {
    free: Box<[u64]>,
    count: u32,
}

impl IdPool {
    /// Every id below `n` free.
    fn new(n: u32) -> Self {
        let mut free = vec![u64::MAX; (n as usize).div_ceil(64)];
        if !n.is_multiple_of(64) {
            *free.last_mut().expect("at least one word") = (1u64 << (n % 64)) - 1;
        }
        IdPool {
            free: free.into(),
            count: n,
        }
    }

    /// Free ids.
    pub fn len(&self) -> u32 {
        self.count
    }

    /// Whether no id is free.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Whether `id` is in use.
    fn in_use(&self, id: u32) -> bool {
        self.free
            .get(id as usize / 64)
            .is_some_and(|w| w >> (id % 64) & 1 == 0)
    }

    /// Takes the lowest free id.
    fn take(&mut self) -> Option<u32> {
        let (i, w) = self.free.iter_mut().enumerate().find(|(_, w)| **w != 0)?;
        let bit = w.trailing_zeros();
        *w &= !(1 << bit);
        self.count -= 1;
        Some(i as u32 * 64 + bit)
    }

    /// Frees `id`.
    fn give(&mut self, id: u32) {
        if let Some(w) = self.free.get_mut(id as usize / 64) {
            if *w >> (id % 64) & 1 == 0 {
                *w |= 1 << (id % 64);
                self.count += 1;
            }
        }
    }
}

/// The wiring's registers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GlueRegs {
    /// Who owns each warp-buffer slot (`warp_buffer_size` entries).
    pub uses: Box<[SlotUse]>,
    /// The fill being built in each slot (`warp_buffer_size` entries).
    pub builds: Box<[Option<Build>]>,
    /// Events for the controller, oldest first: a FIFO of depth
    /// [`event_depth`]` = warp_buffer_size x (warp_size + 1)` (one enqueue per ray and one warp
    /// done per slot).
    pub events: BoundedDeque<Event>,
    /// The count table's eviction of the previous cycle.
    pub ct_evict: Option<u32>,
    /// The queue table's answer of the previous cycle.
    pub qt_done: Option<PopResult>,
    /// Free ray ids.
    pub ids: IdPool,
    /// The first inconsistency found (sticky).
    pub fault: Option<GlueFault>,
}

impl GlueRegs {
    /// The registers after reset.
    pub fn reset(cfg: &HwConfig) -> Self {
        let slots = cfg.warp_buffer_size as usize;
        GlueRegs {
            uses: vec![SlotUse::Free; slots].into(),
            builds: vec![None; slots].into(),
            events: BoundedDeque::new(event_depth(cfg)),
            ct_evict: None,
            qt_done: None,
            ids: IdPool::new(cfg.max_rays),
            fault: None,
        }
    }

    /// Records an inconsistency (the first one is kept).
    fn set_fault(&mut self, fault: GlueFault) {
        self.fault.get_or_insert(fault);
    }

    /// Appends an event for the controller (a fault if the FIFO is full).
    fn push_event(&mut self, event: Event) {
        if let Err(full) = self.events.push_back(event) {
            self.set_fault(GlueFault::Full {
                what: "event FIFO",
                depth: full.capacity,
            });
        }
    }
}

/// Depth of the wiring's event FIFO: one enqueue per ray and one warp done per warp-buffer
/// slot (`warp_buffer_size x (warp_size + 1)`).
pub fn event_depth(cfg: &HwConfig) -> usize {
    cfg.warp_buffer_size as usize * (cfg.warp_size as usize + 1)
}

/// The wiring's registers for `cfg` and widths `w`: their descriptions and trace signals,
/// declared once. Traced: the slots' owners, whether each slot has a fill and its records still
/// loading, and the event FIFO's and the id pool's occupancies; the fills' rays and records,
/// the events, the tables' registered answers and the free-id bitmap are described only.
pub(super) fn registers(cfg: &HwConfig, w: &TreeletRtUnitWidths) -> RegTable<'static, GlueRegs> {
    let slots = cfg.warp_buffer_size;
    let lanes = bits_for(cfg.warp_size as u64);
    let events = event_depth(cfg) as u32;
    let mut t = RegTable::new();
    t.bank(
        "slot_use",
        2,
        slots,
        "per slot: free / initial-phase SM warp / controller fill / closing",
        |g: &GlueRegs, i| g.uses[i].code(),
    )
    .bank(
        "build_valid",
        1,
        slots,
        "per slot: a fill is being built",
        |g, i| g.builds[i].is_some() as u64,
    )
    .untraced(
        "build_kind",
        FillKind::BITS,
        slots,
        "per slot: what the fill builds",
    )
    .untraced(
        "build_rays",
        w.ray,
        slots * cfg.warp_size,
        "per slot: the fill's ray ids",
    )
    .untraced(
        "build_records",
        w.record,
        slots * cfg.warp_size,
        "per slot: the fill's loaded ray records",
    )
    .untraced("build_count", lanes, slots, "per slot: the fill's rays")
    .bank(
        "build_loading",
        lanes,
        slots,
        "per slot: records not yet arrived",
        |g, i| g.builds[i].as_ref().map_or(0, |b| b.loading as u64),
    )
    .untraced("build_last", 1, slots, "per slot: the fill is closed")
    .untraced(
        "events",
        1 + w.ray + w.treelet,
        events,
        "events for the controller (FIFO): enqueue (ray, treelet) or warp done (slot)",
    )
    .one(
        "event_count",
        bits_for(events as u64),
        "valid entries of the event FIFO",
        |g| g.events.len() as u64,
    )
    .untraced(
        "last_ct_evict",
        1 + w.treelet,
        1,
        "the count table's eviction of the previous cycle",
    )
    .untraced(
        "last_qt_done",
        1 + w.treelet + lanes + w.ray * cfg.warp_size,
        1,
        "the queue table's answer of the previous cycle",
    )
    .untraced("free_ids", 1, cfg.max_rays, "free ray ids (lowest first)")
    .one(
        "free_count",
        bits_for(cfg.max_rays as u64),
        "free ray ids (the bitmap's population count)",
        |g| g.ids.len() as u64,
    )
    .untraced("fault", 1, 1, "an inconsistency was found (sticky)");
    t
}

/// The children's register-only output ports, read by the kernel before the children's inputs
/// are known: the RT unit's status ports, the tables' status and the controller's mode.
pub(super) struct Peeks<'a> {
    rt: &'a RtUnitStatus,
    ct: CountTableStatus,
    qt: QueueTableStatus,
    /// The controller's mode register.
    mode: Mode,
    /// SM warps are admitted in treelet-stationary mode (a controller feature).
    admit_ts: bool,
}

impl<'a> Peeks<'a> {
    /// Whether SM warps are admitted in mode `mode` ([`admitting`]).
    fn admits(&self, mode: Mode) -> bool {
        admits_in(mode, self.admit_ts)
    }

    /// The peeks with the RT unit's status ports `rt` and the other children's registers.
    pub(super) fn new<D: NodeDatapath>(
        u: &TreeletRtUnit<D>,
        rt: &'a RtUnitStatus,
        ctl: &ControllerRegs,
        ct: &CountTableRegs,
        qt: &QueueTableRegs,
    ) -> Self {
        Peeks {
            rt,
            ct: u.ct.status(ct),
            qt: u.qt.status(qt),
            mode: u.ctl.mode(ctl, false),
            admit_ts: u.ctl.features().admit_in_treelet_stationary,
        }
    }

    /// The peeks of `regs` with the RT unit's status ports `rt` (of `regs.rt`).
    pub(super) fn of<D: NodeDatapath>(
        u: &TreeletRtUnit<D>,
        regs: &TreeletRtUnitRegs,
        rt: &'a RtUnitStatus,
    ) -> Self {
        Peeks::new(u, rt, &regs.ctl, &regs.ct, &regs.qt)
    }
}

/// The children's inputs of one cycle.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct ChildInputs {
    ctl: ControllerInputs,
    ct: CountTableIn,
    qt: QueueTableIn,
    rt: RtUnitInputs,
}

impl ChildInputs {
    /// Inputs with nothing happening.
    pub(super) fn idle<D: NodeDatapath>(u: &TreeletRtUnit<D>) -> Self {
        ChildInputs {
            ctl: u.ctl.idle_inputs(),
            ct: u.ct.input(CountOp::Nop),
            qt: u.qt.input(QueueOp::Nop),
            rt: u.rt.idle_inputs(),
        }
    }
}

/// The children's outputs of one cycle.
pub(super) type ChildOutputs = (
    ControllerOutputs,
    CountTableOut,
    QueueTableOut,
    RtUnitOutputs,
);

/// The children's next registers.
pub(super) type ChildRegs = (RtUnitRegs, ControllerRegs, CountTableRegs, QueueTableRegs);

/// The children evaluated on `d` (pure): their outputs and next registers.
pub(super) fn eval_children<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    regs: &TreeletRtUnitRegs,
    d: &ChildInputs,
) -> (ChildOutputs, ChildRegs) {
    let (ctl_o, ctl_r) = u.ctl.eval(&regs.ctl, &d.ctl);
    let (ct_o, ct_r) = u.ct.eval(&regs.ct, &d.ct);
    let (qt_o, qt_r) = u.qt.eval(&regs.qt, &d.qt);
    let (rt_o, rt_r) = u.rt.eval(&regs.rt, &d.rt);
    ((ctl_o, ct_o, qt_o, rt_o), (rt_r, ctl_r, ct_r, qt_r))
}

/// The kernel: `(inputs, registers, children's outputs) -> (children's inputs, (outputs, next
/// wiring registers))`, the three stages chained.
pub(super) fn kernel<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    regs: &TreeletRtUnitRegs,
    peeks: &Peeks,
    inputs: &TreeletRtUnitInputs,
    q: &ChildOutputs,
) -> (ChildInputs, (TreeletRtUnitOutputs, GlueRegs)) {
    let mut g = regs.glue.clone();
    let mut out = empty_outputs(u);
    place_records(&mut g, &inputs.ray_records);
    let (ctl_in, restart) = controller_inputs(u, &g, peeks, inputs.sm_warp.is_some());
    out.counts.restarts += u64::from(restart);
    out.counts.ctl.observe(&ctl_in, &q.0);
    out.counts.ctl.repack_starved_cycles += u64::from(u.ctl.repack_withheld(&regs.ctl, &ctl_in));
    let mut rt_in = u.rt.idle_inputs();
    let (ct_in, qt_in) = children_inputs(
        u,
        &mut g,
        peeks,
        inputs,
        restart,
        &ctl_in,
        Some(&q.0),
        &mut out,
        &mut rt_in,
    );
    after_children(&mut g, Some(&q.1), Some(&q.2), &q.3, &mut out);
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
fn reset_outputs<D: NodeDatapath>(u: &TreeletRtUnit<D>, out: &mut TreeletRtUnitOutputs) {
    out.widths = u.widths;
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

/// Stage 0: ray records that arrived join their fills.
fn place_records(g: &mut GlueRegs, records: &[RayLoad]) {
    for load in records {
        let placed = g
            .builds
            .get_mut(load.slot as usize)
            .and_then(Option::as_mut)
            .and_then(|b| {
                let k = b
                    .rays
                    .iter()
                    .zip(&b.records)
                    .position(|(&r, rec)| r == load.ray && rec.is_none())?;
                b.records.as_mut_slice()[k] = Some(load.record.clone());
                b.loading = b.loading.saturating_sub(1);
                Some(())
            });
        if placed.is_none() {
            g.set_fault(GlueFault::UnexpectedRecord {
                slot: load.slot,
                ray: load.ray,
            });
        }
    }
}

/// Whether the controller's reports this cycle read the RT unit's distinct-treelet counts
/// (`status_distinct`): in the modes that terminate divergent warps, the mode after a restart
/// if the SM `offering` a warp restarts a `done` controller.
pub(super) fn reads_distinct<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    ctl: &ControllerRegs,
    offering: bool,
) -> bool {
    u.ctl.mode(ctl, offering).terminates_divergent_warps()
}

/// Whether SM warps are admitted in controller mode `mode`: not in the final ray-stationary
/// phase, which traverses the rays it grouped "until all of them have finished traversal
/// completely before fetching new rays to process" (section 4.4), nor in the
/// treelet-stationary mode when the controller's features keep them out of it.
fn admitting<D: NodeDatapath>(u: &TreeletRtUnit<D>, mode: Mode) -> bool {
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

/// The `sm_ready` output (see [`TreeletRtUnit::sm_ready`]), with the RT unit's status ports
/// `rt`.
pub(super) fn sm_ready<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    regs: &TreeletRtUnitRegs,
    rt: &RtUnitStatus,
) -> bool {
    let g = &regs.glue;
    admitting(u, u.ctl.mode(&regs.ctl, false))
        && g.ids.len() >= u.cfg.warp_size
        && free_slot(g, rt, None).is_some()
}

/// The lowest slot the wiring has not given out and whose RT-unit slot holds no warp, other
/// than `reserved`.
fn free_slot(g: &GlueRegs, rt: &RtUnitStatus, reserved: Option<u32>) -> Option<u32> {
    (0..g.uses.len() as u32).find(|&s| {
        g.uses[s as usize] == SlotUse::Free && rt.slot(s as usize).is_none() && reserved != Some(s)
    })
}

/// Whether the wiring has work in the next cycle whatever the children do: events to report
/// or a complete fill to issue.
pub(super) fn glue_busy(g: &GlueRegs) -> bool {
    !g.events.is_empty() || g.builds.iter().flatten().any(|b| b.last && b.loading == 0)
}

/// Sets the controller inputs that depend on whether the SM offers a warp: its waiting warps
/// count as initial-phase warps and keep `launch_done` low while SM warps are admitted.
/// `admits`: SM warps are admitted in the controller's mode ([`admitting`]).
fn set_offering(g: &GlueRegs, admits: bool, inp: &mut ControllerInputs, offering: bool) {
    let waiting = offering && admits;
    inp.launch_done = !waiting;
    inp.initial_warps = g.uses.contains(&SlotUse::Initial) || waiting;
    inp.restart = offering;
}

/// Stage 1: the controller's inputs, from registers only, and whether it restarts (a
/// controller that is `done` restarts when the SM offers a warp).
fn controller_inputs<D: NodeDatapath>(
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
fn controller_inputs_into(
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
/// issued, or else an offered SM warp may enter.
#[allow(clippy::too_many_arguments)]
fn children_inputs<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    g: &mut GlueRegs,
    p: &Peeks,
    inputs: &TreeletRtUnitInputs,
    restart: bool,
    ctl_in: &ControllerInputs,
    ctl_out: Option<&ControllerOutputs>,
    out: &mut TreeletRtUnitOutputs,
    rt_in: &mut RtUnitInputs,
) -> (CountTableIn, QueueTableIn) {
    let mode = if restart { Mode::Initial } else { p.mode };
    if ctl_in.warp_done.is_some() || ctl_out.is_some_and(|o| o.enq_ready) {
        if let Some(Event::WarpDone(s)) = g.events.pop_front() {
            g.uses[s as usize] = SlotUse::Free;
        }
    }
    let ct_in = u.ct.input(ctl_out.map_or(CountOp::Nop, |o| o.ct_op));
    let qt_op = ctl_out.map_or(QueueOp::Nop, |o| o.qt_op);
    let qt_in = match inputs.spill_head {
        Some((t, r)) if p.qt.refill_waiting => {
            out.spill_pop = true;
            out.counts.refills += 1;
            u.qt.refill_answer(t, r)
        }
        _ => u.qt.input(qt_op),
    };
    out.preload = ctl_out.and_then(|o| o.preload);
    if let Some(fill) = ctl_out.and_then(|o| o.fill.as_ref()) {
        start_fill(u, g, fill, out);
    }
    rt_in.responses.clear();
    rt_in.responses.extend_from_slice(&inputs.responses);
    rt_in.stop = ctl_out.and_then(|o| o.terminate);
    rt_in.repack = ctl_out.and_then(|o| o.repack);
    rt_in.issue = finished_build(u, g, p);
    let reserve = ctl_out.and_then(|o| o.reserve);
    if rt_in.issue.is_none() && admitting(u, mode) {
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
        records: BoundedVec::new(lanes),
        loading: 0,
        last: false,
    });
    let mut full = None;
    for &ray in &fill.rays {
        match build.rays.push(ray).and_then(|()| build.records.push(None)) {
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

/// The warp issue of the first fill whose rays have all arrived and which is complete.
fn finished_build<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    g: &mut GlueRegs,
    p: &Peeks,
) -> Option<WarpIssue> {
    let s = g
        .builds
        .iter()
        .position(|b| b.as_ref().is_some_and(|b| b.last && b.loading == 0))?;
    let build = g.builds[s].take()?;
    let slot = s as u32;
    let rays = build.rays.len();
    let warp_size = u.cfg.warp_size as usize;
    let mut lanes: Vec<Option<RayRecord>> = vec![None; warp_size];
    let (order, target, free) = match build.kind {
        FillKind::Treelet => (
            TraversalOrder::TreeletStop,
            IssueTarget::Slot(slot),
            u64::MAX,
        ),
        FillKind::Grouped => (
            TraversalOrder::TreeletContinue,
            IssueTarget::Slot(slot),
            u64::MAX,
        ),
        FillKind::Repack => {
            let view = p.rt.slot(s);
            (
                view.map_or(TraversalOrder::RayStationary, |v| v.order),
                IssueTarget::Append { slot, last: true },
                view.map_or(0, |v| v.inactive),
            )
        }
    };
    let mut free_lanes = (0..warp_size).filter(|&l| free >> l & 1 == 1);
    let mut placed = 0;
    for record in build.records.into_vec() {
        let Some(lane) = free_lanes.next() else {
            break;
        };
        placed += usize::from(record.is_some());
        lanes[lane] = record;
    }
    if placed != rays {
        g.set_fault(GlueFault::Unplaced { slot, placed, rays });
    }
    Some(WarpIssue {
        order,
        lanes,
        target,
    })
}

/// Takes an offered SM warp into `slot` if enough ray ids are free: gives its rays the lowest
/// free ids, stores their records and returns the warp issue.
fn admit<D: NodeDatapath>(
    u: &TreeletRtUnit<D>,
    g: &mut GlueRegs,
    slot: u32,
    offered: &[Option<RayRecord>],
    out: &mut TreeletRtUnitOutputs,
) -> Option<WarpIssue> {
    let need = offered.iter().flatten().count();
    if (g.ids.len() as usize) < need {
        return None;
    }
    let mut lanes: Vec<Option<RayRecord>> = offered.to_vec();
    lanes.resize(u.cfg.warp_size as usize, None);
    let mut ids = vec![None; lanes.len()];
    for (rec, id_out) in lanes.iter_mut().zip(&mut ids) {
        let Some(rec) = rec.as_mut() else { continue };
        let id = g.ids.take()?;
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
    })
}

/// Stage 3: the tables' answers are registered for the next cycle, a spilled entry goes to the
/// spill FIFO, and the RT unit's completed warp is unpacked: finished rays leave with their
/// hits and free their ids, rays stopped at a boundary leave their records to the store and are
/// queued for enqueueing, then the slot's `warp_done`.
/// A table that was not stepped (`None`: no op and nothing in progress) answers nothing.
fn after_children(
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
    out.errors = rt.errors;
    out.first_error = rt.first_error;
    if let Some(done) = &rt.released {
        unpack(g, done, out);
    }
    if let Some(done) = &rt.done {
        unpack(g, done, out);
        g.uses[done.slot as usize] = SlotUse::Closing;
        g.push_event(Event::WarpDone(done.slot));
    }
    out.fault = g.fault.clone();
}

/// Returns finished rays and parks stopped ones.
fn unpack(g: &mut GlueRegs, done: &WarpDone, out: &mut TreeletRtUnitOutputs) {
    for (rec, outcome) in done.lanes.iter().flatten() {
        let id = rec.ray_id;
        if !g.ids.in_use(id) {
            g.set_fault(GlueFault::UnknownRay(id));
            continue;
        }
        match *outcome {
            RayOutcome::Finished => {
                out.finished.push(FinishedRay {
                    ray: id,
                    hit: rec.hit,
                });
                g.ids.give(id);
            }
            RayOutcome::AtBoundary { treelet } => {
                out.parked.push(rec.clone());
                g.push_event(Event::Enqueue {
                    ray: id,
                    treelet: treelet as u32,
                });
            }
        }
    }
}

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
    place_records(g, &inputs.ray_records);
    let offering = inputs.sm_warp.is_some();
    // The RT unit's status ports: computed by the dry run at the end of the last step unless
    // cycles were skipped since or the mode that reads the distinct-treelet counts differs.
    let distinct = reads_distinct(u, ctl, offering);
    if cache.rt_status_current == Some(distinct) {
        debug_assert_eq!(
            cache.rt_status,
            u.rt.status(rt, &cache.rt, distinct),
            "stale RT-unit status ports"
        );
    } else {
        u.rt.status_into(rt, &cache.rt, distinct, &mut cache.rt_status);
    }
    cache.rt_status_current = None;
    let peeks = Peeks::new(u, &cache.rt_status, ctl, ct, qt);
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
    let mode = if restart { Mode::Initial } else { peeks.mode };
    let idle = reused && cache.idle && !(offering && admitting(u, mode));
    out.counts.ctl.repack_starved_cycles += u64::from(u.ctl.repack_withheld(ctl, ctl_in));
    let ctl_out = if idle {
        debug_assert!(
            {
                let (o, n) = u.ctl.eval(ctl, ctl_in);
                !acts(&o, &n, ctl)
            },
            "the controller was not idle"
        );
        out.counts.ctl.count_cycles(mode, 1);
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
        out,
        rt_in,
    );
    let qt_busy = !peeks.qt.ready;
    super::log_tables(&mut cache.tables, &ct_in, &qt_in);
    // Tables with no op and nothing in progress are not stepped: their registers would not
    // change and their outputs would carry nothing.
    let ct_out = (ct_in.op != CountOp::Nop || u.ct.busy(ct)).then(|| u.ct.step(ct, &ct_in));
    let qt_out =
        (qt_in.op != QueueOp::Nop || qt_in.refill_valid || qt_busy).then(|| u.qt.step(qt, &qt_in));
    let rt_out = u.rt.step_cached(rt, &mut cache.rt, rt_in);
    after_children(g, ct_out.as_ref(), qt_out.as_ref(), &rt_out, out);
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
    let distinct = reads_distinct(u, &regs.ctl, false);
    u.rt.status_into(&regs.rt, &cache.rt, distinct, &mut cache.rt_status);
    cache.rt_status_current = Some(distinct);
    let g = &regs.glue;
    if !u.qt.status(&regs.qt).ready
        || g.qt_done.is_some()
        || g.ct_evict.is_some()
        || !g.events.is_empty()
    {
        cache.awake = true;
        return;
    }
    let peeks = Peeks::of(u, regs, &cache.rt_status);
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
    cache.dry_valid = true;
    cache.idle = !acts;
    cache.awake = acts;
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
        u.rt.debug_state(&regs.rt, &RtCache::of(&regs.rt)),
        u.ctl.debug_state(&regs.ctl),
        u.qt.debug_state(&regs.qt),
        u.ct.status(&regs.ct).occupancy,
        g.events.len(),
        g.uses,
        g.builds
            .iter()
            .map(|b| b
                .as_ref()
                .map(|b| (b.kind, b.rays.len(), b.loading, b.last)))
            .collect::<Vec<_>>(),
        u.cfg.max_rays - g.ids.len()
    )
}
