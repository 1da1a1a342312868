//! The treelet RT unit (paper section 4.2, Figure 8): the RT unit with the treelet controller,
//! the treelet count table and the treelet queue table beside it, composed as one block
//! ([`crate::compose`]): four children and a wiring kernel ([`wiring`]) with a few registers of
//! its own ([`GlueRegs`]).
//!
//! What the block leaves to its environment, through its ports ([`TreeletRtUnitInputs`],
//! [`TreeletRtUnitOutputs`]): the SM's warps (offered with their rays, accepted with the ray ids
//! the block gives them; finished rays come back with their hits), the memory (node chunks and
//! stack fills for the RT unit; ray-record stores when an SM warp enters and loads when a warp is
//! formed from the queues, answered with the record; the queue table's spill FIFO), the ray-record
//! store (records of rays stopped at a treelet boundary, kept until a fill loads them) and the
//! treelet preloads (prefetches into the L1).
//!
//! # One cycle (the wiring, in dependency order)
//! 1. Ray records that arrived (at most one per record port, `hw.record_bytes_per_cycle / 32`)
//!    are written into the fills being built, each into the lane it will be issued to.
//! 2. The controller's inputs come from registers only: the count table's and queue table's
//!    status ([`Moore::status`]),
//!    their answers of the previous cycle (registered here), the RT unit's status ports
//!    ([`crate::rt_unit::RtUnitStatus`], register-only outputs: per slot its warp's order, hold,
//!    lane summary and inactive lanes; they give the free slot, whether the unit is idle, the
//!    initial-phase warp with the most distinct next treelets, ties to the lowest slot, and, for
//!    repacking, the final-phase warp with the fewest busy lanes, skipping warps that complete
//!    this cycle; nothing else of the RT unit's registers is read), the first pending event (an
//!    enqueue or a warp done) and whether the SM offers a warp (its waiting warps count as
//!    initial-phase warps and keep `launch_done` low). A controller that is `done` restarts when
//!    the SM offers a warp (its `restart` port): each wave of rays goes through the phases again.
//! 3. The controller's ops go to the tables; their answers are registered for the next cycle; a
//!    spilled queue-table entry goes to the spill FIFO, and the table's refill request is answered
//!    from the FIFO's head.
//! 4. Its commands go to the RT unit: `terminate` to `stop`, `repack` to `repack`, a `fill` loads
//!    the records of its rays, a fill that is complete with every record in is issued into its
//!    reserved slot (an append for a repack); otherwise an SM warp may take a slot nobody owns
//!    when enough ray ids are free (not in the final ray-stationary phase, which finishes the
//!    rays it grouped before new rays are fetched, section 4.4): its rays get the lowest free ids
//!    and their 32 B records are stored.
//! 5. The RT unit steps; a warp it completes is unpacked: finished rays leave with their hits
//!    (each at its lane's position) and free their ids, rays stopped at a boundary leave their
//!    records to the store (at their lanes) and are queued for enqueueing (one per cycle), then
//!    the slot's `warp_done`.
//!
//! # Definition and fast path
//! [`Block::eval`] is the definition: the kernel ([`wiring`]) settled with the children's pure
//! `eval`s ([`crate::compose::settle`]). [`Cached::step_cached`] evaluates the same kernel
//! stages once in dependency order, in place, with the RT unit's lane cache and a dry run of
//! the controller kept in a [`TreeletRtUnitCache`] by its owner: a cycle in which the dry run
//! found the controller idle counts only in its mode, a dry run whose controller neither
//! stepped nor sees new inputs reuses the last one's verdict (a pure function of the same
//! registers and inputs), tables with nothing to do are not stepped, and the controller's and
//! RT unit's input bundles and the outputs ([`Cached::step_cached_into`]) are filled in
//! place. Tests check the fast path against `eval`. [`Skip::idle_cycles`](crate::block::Skip::idle_cycles) and
//! [`Skip::skip`](crate::block::Skip::skip) let a simulator jump over cycles in which nothing but counters and
//! delays change.
//!
//! # Statistics
//! No statistics registers: each cycle's events leave on [`TreeletRtUnitOutputs::counts`]
//! ([`TreeletCounts`]), and [`Skip::skip`](crate::block::Skip::skip) returns those of skipped cycles.
//!
//! # Files
//! `ports` (the port bundles and widths), `glue` (the wiring's registers, declared once),
//! `wiring` (the kernel's stages), `wiring_ports` (the kernel on its own, from its ports, as
//! its RTL module sees it), `fast_path` (the stages once, children stepped in place),
//! `probe` (the probe that checks the fast path against the definition), this file (the block,
//! its cache, idle skipping).

mod fast_path;
mod glue;
mod ports;
mod probe;
mod skip;
mod status;
mod wiring;
mod wiring_ports;

pub use glue::{Build, Event, GlueFault, GlueRegs, IdPool, SlotUse};
pub use ports::{
    FinishedRay, ParkedRay, RayLoad, TreeletCounts, TreeletRequest, TreeletRtUnitInputs,
    TreeletRtUnitOutputs, TreeletRtUnitWidths,
};
pub use probe::ProbeCycle;
pub use status::TreeletRtUnitStatus;
pub use wiring_ports::{WiringInputs, WiringOutputs};

use crate::block::{Block, Cached, Moore, Signal};
use crate::config::HwConfig;
use crate::controller::{
    ControllerFeatures, ControllerInputs, ControllerOutputs, ControllerRegs, TreeletController,
};
use crate::count_table::{CountTable, CountTableIn, CountTableOut, CountTableRegs};
use crate::describe::BlockDesc;
use crate::queue_table::{QueueTable, QueueTableIn, QueueTableOut, QueueTableRegs};
use crate::rt_unit::{
    NodeDatapath, RtCache, RtUnit, RtUnitError, RtUnitInputs, RtUnitOutputs, RtUnitParams,
    RtUnitRegs, StatusSelect,
};

/// Parameters of a treelet RT unit beyond the hardware configuration.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TreeletRtUnitParams {
    /// The RT unit's parameters (latencies, FIFO, hit records, stack spill area).
    pub rt: RtUnitParams,
    /// The controller's feature switches (the paper's design variants).
    pub features: ControllerFeatures,
    /// Byte address of ray id 0's 32 B ray record; ray `r`'s is at `ray_base + 32 r`.
    pub ray_base: u64,
}

/// The treelet RT unit block, generic over the RT unit's intersection datapath `D`.
#[derive(Debug, Clone)]
pub struct TreeletRtUnit<D> {
    cfg: HwConfig,
    rt: RtUnit<D>,
    ctl: TreeletController,
    ct: CountTable,
    qt: QueueTable,
    ray_base: u64,
    widths: TreeletRtUnitWidths,
}

crate::composite! {
    /// The treelet RT unit's registers: its children's and the wiring's.
    pub struct TreeletRtUnitRegs;
    child_inputs ChildInputs;
    child_outputs ChildOutputs;
    child_regs ChildRegs;
    parent TreeletRtUnit<D: NodeDatapath>;
    children {
        /// The RT unit's.
        rt: RtUnit<D> => (RtUnitRegs, RtUnitInputs, RtUnitOutputs),
        /// The treelet controller's.
        ctl: TreeletController => (ControllerRegs, ControllerInputs, ControllerOutputs),
        /// The treelet count table's.
        ct: CountTable => (CountTableRegs, CountTableIn, CountTableOut),
        /// The treelet queue table's.
        qt: QueueTable => (QueueTableRegs, QueueTableIn, QueueTableOut),
    }
    /// The wiring's.
    glue glue: GlueRegs;
}

/// A simulation cache of a treelet RT unit's registers, not hardware, owned beside the
/// registers by whoever steps the block with [`Cached::step_cached`]: the RT unit's lane
/// cache, and the controller's inputs and idleness found by a dry run at the end of the last
/// step (valid for the next step if no cycle is skipped in between). It can also keep a probe
/// of the tables' input ports ([`TreeletRtUnitCache::record_tables`]) and a probe of the
/// children's ports and registers ([`TreeletRtUnitCache::probe`]).
#[derive(Debug, Clone, PartialEq)]
pub struct TreeletRtUnitCache {
    rt: RtCache,
    /// The RT unit's status ports (register-only outputs) of the current registers while
    /// `rt_status_current`; kept for their storage otherwise.
    rt_status: crate::rt_unit::RtUnitStatus,
    /// `Some(distinct)`: `rt_status` is that of the current registers, with the distinct
    /// next treelets counted if `distinct` (set by the dry run at the end of a step and by a
    /// skip that ends a delay, cleared by a step's start).
    rt_status_current: Option<bool>,
    /// The controller inputs of the last dry run (meaningful while `dry_valid`; kept for its
    /// storage otherwise).
    dry: Option<Box<ControllerInputs>>,
    /// The storage the next dry run fills before it compares it with `dry` (swapped with it).
    dry_spare: Option<Box<ControllerInputs>>,
    /// `dry` holds the inputs the last dry run computed from the current registers.
    dry_valid: bool,
    /// The dry run found the controller idle with `dry` (no output, registers unchanged).
    idle: bool,
    /// The controller's `repack_starved` output in the last dry run (meaningful while
    /// `dry_valid`): the verdict of every cycle the controller idles through with `dry`.
    repack_starved: bool,
    /// The controller would act in the next cycle even if nothing else changed.
    awake: bool,
    /// The tables' inputs of every cycle so far, while recording.
    tables: Option<TableLog>,
    /// Storage the controller's next registers are computed into (its contents mean nothing
    /// between steps), so a step allocates nothing.
    scratch: Option<Box<ControllerRegs>>,
    /// The RT unit's input bundle of the last step, kept for its storage (its contents mean
    /// nothing between steps).
    rt_inputs: Option<crate::rt_unit::RtUnitInputs>,
    /// Each step keeps its cycle's [`ProbeCycle`] in `probed`.
    probe: bool,
    /// The last step's cycle, while probing.
    probed: Option<ProbeCycle>,
}

/// The treelet count table's and queue table's input ports, cycle by cycle (a `Nop` in every
/// cycle a table was not stepped or skipped): real traffic to replay against their RTL. It
/// starts at the first cycle in which either table gets an op: until then both get only `Nop`s
/// from reset, which leave them in their reset state, so a replay from reset is exact. Beside
/// them, the treelet controller's input ports from reset (its registers change without table
/// ops, so its log starts at the first cycle), the RT unit's input ports from reset, to replay
/// the RT unit with the same datapath, and the whole block's input ports from reset with its
/// parameters, to replay the block.
#[derive(Debug, Clone, PartialEq)]
pub struct TableLog {
    /// Cycles to record at most.
    pub limit: usize,
    /// The cycle of the first recorded input.
    pub first_cycle: u64,
    /// Cycles seen before the first op (not recorded).
    pub skipped: u64,
    /// The count table's inputs.
    pub count: Vec<CountTableIn>,
    /// The queue table's inputs.
    pub queue: Vec<QueueTableIn>,
    /// The treelet controller's inputs of the first `limit` cycles from reset, every cycle (a
    /// skipped idle cycle has the inputs the wiring gives the controller with no SM warp
    /// offered, those of the cycle the skip starts in).
    pub controller: Vec<ControllerInputs>,
    /// The RT unit's inputs of the first `limit` cycles from reset, every cycle (a skipped idle
    /// cycle has idle inputs: a skip is exactly that many idle steps).
    pub rt_unit: Vec<RtUnitInputs>,
    /// The treelet RT unit's own inputs of the first `limit` cycles from reset, every cycle (a
    /// skipped idle cycle has idle inputs): what replays the whole block.
    pub treelet: Vec<TreeletRtUnitInputs>,
    /// The treelet RT unit's parameters (the RT unit's latencies, response FIFO, hit records
    /// and stack spill area; the controller's features; the ray-record base).
    pub params: TreeletRtUnitParams,
}

impl TreeletRtUnitCache {
    /// The cache around the RT unit's cache `rt` (nothing known about the controller yet: the
    /// next step evaluates it); [`Cached::cache`] builds it for registers.
    fn with_rt(rt: RtCache) -> Self {
        TreeletRtUnitCache {
            rt,
            rt_status: crate::rt_unit::RtUnitStatus {
                widths: Default::default(),
                slots: Vec::new(),
                issue_ready: false,
                resp_free: 0,
            },
            rt_status_current: None,
            dry: None,
            dry_spare: None,
            dry_valid: false,
            idle: false,
            repack_starved: false,
            awake: true,
            tables: None,
            scratch: None,
            rt_inputs: None,
            probe: false,
            probed: None,
        }
    }

    /// Starts (`on`) or stops probing: while on, each [`Cached::step_cached`] keeps its
    /// cycle's children's ports and registers for [`TreeletRtUnitCache::take_probe`]. It changes
    /// no result; off (the default), it costs nothing.
    pub fn probe(&mut self, on: bool) {
        self.probe = on;
        self.probed = None;
    }

    /// The last step's [`ProbeCycle`], while probing (`None` after a [`Skip::skip`](crate::block::Skip::skip)).
    pub fn take_probe(&mut self) -> Option<ProbeCycle> {
        self.probed.take()
    }

    /// Starts recording the tables', the controller's, the RT unit's and the whole block's
    /// inputs of the next `cycles` cycles (from reset: start before the first step); `params`
    /// are the block's parameters ([`TreeletRtUnit::params`]), kept with the log.
    pub fn record_tables(&mut self, cycles: usize, params: TreeletRtUnitParams) {
        self.tables = Some(TableLog {
            limit: cycles,
            first_cycle: 0,
            skipped: 0,
            count: Vec::new(),
            queue: Vec::new(),
            controller: Vec::new(),
            rt_unit: Vec::new(),
            treelet: Vec::new(),
            params,
        });
    }

    /// The tables' inputs recorded so far.
    pub fn take_table_log(&mut self) -> Option<TableLog> {
        self.tables.take()
    }

    /// Records one cycle's table inputs.
    fn log_tables(&mut self, ct: &CountTableIn, qt: &QueueTableIn) {
        log_tables(&mut self.tables, ct, qt);
    }
}

/// Appends one cycle's controller inputs to `tables`, while recording (up to its limit).
fn log_controller(tables: &mut Option<TableLog>, inputs: &ControllerInputs) {
    if let Some(log) = tables.as_mut().filter(|l| l.controller.len() < l.limit) {
        log.controller.push(inputs.clone());
    }
}

/// Appends one cycle's inputs of the whole block to `tables`, while recording (up to its
/// limit).
fn log_treelet(tables: &mut Option<TableLog>, inputs: &TreeletRtUnitInputs) {
    if let Some(log) = tables.as_mut().filter(|l| l.treelet.len() < l.limit) {
        log.treelet.push(inputs.clone());
    }
}

/// Appends one cycle's RT-unit inputs to `tables`, while recording (up to its limit).
fn log_rt_unit(tables: &mut Option<TableLog>, inputs: &RtUnitInputs) {
    if let Some(log) = tables.as_mut().filter(|l| l.rt_unit.len() < l.limit) {
        log.rt_unit.push(inputs.clone());
    }
}

/// Appends one cycle's table inputs to `tables`, while recording.
fn log_tables(tables: &mut Option<TableLog>, ct: &CountTableIn, qt: &QueueTableIn) {
    let Some(log) = tables.as_mut() else {
        return;
    };
    let idle = ct.op == crate::count_table::CountOp::Nop
        && qt.op == crate::queue_table::QueueOp::Nop
        && !qt.refill_valid;
    if log.count.is_empty() && idle {
        log.skipped += 1;
        log.first_cycle = log.skipped;
        return;
    }
    if log.count.len() < log.limit {
        log.count.push(*ct);
        log.queue.push(*qt);
    }
}

impl<D: NodeDatapath> TreeletRtUnit<D> {
    /// The wiring's registers `g` as trace signals ([`glue::registers`]).
    fn glue_signals(&self, g: &GlueRegs) -> Vec<Signal> {
        glue::registers(&self.cfg, &self.widths).signals(g)
    }

    /// A treelet RT unit for `cfg` and `params` testing nodes with `datapath`; checks both.
    pub fn new(
        cfg: HwConfig,
        params: TreeletRtUnitParams,
        datapath: D,
    ) -> Result<Self, RtUnitError> {
        let rt = RtUnit::new(cfg.clone(), params.rt, datapath)?;
        let ctl = TreeletController::new(cfg.clone(), params.features)?;
        let ct = CountTable::new(&cfg)?;
        let qt = QueueTable::new(&cfg)?;
        let widths = TreeletRtUnitWidths::new(&cfg, rt.widths());
        Ok(TreeletRtUnit {
            cfg,
            rt,
            ctl,
            ct,
            qt,
            ray_base: params.ray_base,
            widths,
        })
    }

    /// The RT unit child (for its parameters and widths).
    pub fn rt_unit(&self) -> &RtUnit<D> {
        &self.rt
    }

    /// The hardware configuration.
    pub fn config(&self) -> &HwConfig {
        &self.cfg
    }

    /// The parameters the block was built with.
    pub fn params(&self) -> TreeletRtUnitParams {
        TreeletRtUnitParams {
            rt: self.rt.params().clone(),
            features: self.ctl.features(),
            ray_base: self.ray_base,
        }
    }

    /// An output bundle carrying nothing, for [`Cached::step_cached_into`] to
    /// write into.
    pub fn empty_outputs(&self) -> TreeletRtUnitOutputs {
        wiring::empty_outputs(self)
    }
}

/// The kinds of RT-unit warp of the treelet RT unit, as an observer tells them apart
/// ([`TreeletRtUnitStatus::warp_kind`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum WarpKind {
    /// A warp from the SM in its initial phase (ray-stationary in treelet order), also once the
    /// controller terminated it and it finishes its current treelet (the default: the first
    /// warps of a run are the SM's).
    #[default]
    Sm = 0,
    /// A treelet warp: one queue entry of the treelet being processed, traversing to the
    /// treelet's boundary (treelet-stationary).
    Treelet = 1,
    /// A warp grouped from underpopulated queues, traversing ray-stationary to completion, and
    /// the rays repacking appends to it.
    Grouped = 2,
}

impl WarpKind {
    /// Every kind, in index order.
    pub const ALL: [WarpKind; 3] = [WarpKind::Sm, WarpKind::Treelet, WarpKind::Grouped];

    /// The kind's index in [`WarpKind::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// The kind's name in statistics.
    pub fn name(self) -> &'static str {
        match self {
            WarpKind::Sm => "sm",
            WarpKind::Treelet => "treelet",
            WarpKind::Grouped => "grouped",
        }
    }
}

impl<D: NodeDatapath> Block for TreeletRtUnit<D> {
    type Inputs = TreeletRtUnitInputs;
    type Outputs = TreeletRtUnitOutputs;
    type Regs = TreeletRtUnitRegs;

    fn reset(&self) -> TreeletRtUnitRegs {
        self.children_reset(GlueRegs::reset(&self.cfg))
    }

    /// Nothing offered and nothing arriving.
    fn idle_inputs(&self) -> TreeletRtUnitInputs {
        TreeletRtUnitInputs {
            widths: self.widths,
            sm_warp: None,
            responses: Vec::new(),
            ray_records: Vec::new(),
            spill_head: None,
        }
    }

    /// The definition: the wiring kernel settled with the children's pure `eval`s (the
    /// settled children's registers replace `next`'s storage).
    fn next_into(
        &self,
        regs: &TreeletRtUnitRegs,
        inputs: &TreeletRtUnitInputs,
        next: &mut TreeletRtUnitRegs,
    ) -> TreeletRtUnitOutputs {
        // The RT unit's status ports (its register-only outputs, which its output bundle does
        // not carry); the other children's come with their settled outputs.
        let distinct = wiring::reads_distinct(self, &regs.ctl, inputs.sm_warp.is_some());
        let rt_status = self.rt.status(
            &regs.rt,
            &self.rt.cache(&regs.rt),
            StatusSelect::slots(distinct),
        );
        let settled = self.settle_children(regs, 8, |q| {
            let peeks = wiring::Peeks::from_ports(self, &rt_status, &q.ctl, &q.ct, &q.qt);
            wiring::kernel(self, &regs.glue, &peeks, inputs, q)
        });
        let (_, (out, glue), _, children) =
            settled.expect("the treelet RT unit's wiring has no combinational cycle");
        *next = children.with_glue(glue);
        out
    }

    /// The children's register signals (prefixed `rt_`, `ctl_`, `ct_`, `qt_`) and the wiring's
    /// (prefixed `glue_`).
    fn reg_signals(&self, regs: &TreeletRtUnitRegs) -> Vec<Signal> {
        self.children_reg_signals(regs, self.glue_signals(&regs.glue))
    }

    fn describe(&self) -> BlockDesc {
        ports::describe(self)
    }

    /// A one-paragraph summary of the registers, for a watchdog's dump.
    fn debug_state(&self, regs: &TreeletRtUnitRegs) -> String {
        wiring::debug_state(self, regs)
    }
}
