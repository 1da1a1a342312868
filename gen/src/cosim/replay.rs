//! The RT unit replayed on a real run's traffic: the intersection datapath's answers become
//! testbench inputs ([`RtUnitReplay`]).
//!
//! The RT unit's RTL leaves the box/triangle datapath outside its control (`rt_datapath`, one
//! instance per lane), and a real scene's datapath (the simulator's BVH decoder and tests) has
//! no Verilog. So a replay first runs the Rust RT unit with the real datapath over the recorded
//! inputs and keeps every test it ran in each cycle — the ray, its closest hit so far, the node
//! and the result, with the lane it served ([`datapath_tables`]). The co-simulated block
//! ([`RtUnitReplay`]) is the same RT unit whose datapath answers from the cycle's table, one
//! entry per lane, which arrives on three extra input ports (`dp_valid`, `dp_key`,
//! `dp_result`, [`ReplayInputs`]); on the Verilog side the module `rt_unit_replay` carries the
//! same ports around `rt_unit`, and the replay `rt_datapath` instance of lane `l`
//! ([`crate::rtl::rt_unit_replay_verilog`]) answers from entry `l` when its key is the test's.
//! Every output and status port of the RT unit is compared every cycle, as in the random
//! co-simulation; what the replay does not check is the node bytes the RTL hands its datapath
//! (not part of the key), which the random co-simulation's toy datapath checks.

use super::rt_unit::{RtUnitAllOutputs, RtUnitWithStatus};
use super::waveform::{nested_registers, RegSignal};
use crate::compose::WIRING_INSTANCE;
use crate::error::GenError;
use crate::rtl::{instances, treelet_wiring_desc, CHILD_BITS, CHILD_COUNT_BITS, REPLAY_INSTANCE};
use std::cell::{Cell, RefCell};
use std::rc::Rc;
use vtq_hdl::bits::BitPacker;
use vtq_hdl::bundle::push_words;
use vtq_hdl::rt_unit::{
    Hit, NodeDatapath, NodeEntry, RayWords, RtUnit, RtUnitInputs, RtUnitParams, RtUnitRegs,
    TestResult, RAY_WORDS,
};
use vtq_hdl::treelet_rt_unit::{
    TreeletRtUnit, TreeletRtUnitInputs, TreeletRtUnitOutputs, TreeletRtUnitParams,
    TreeletRtUnitRegs,
};
use vtq_hdl::{Block, BlockDesc, Dir, HwConfig, PortDesc, Signal, Signals};

/// One test the datapath ran: the lane it served, its inputs (the key) and its result.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DatapathCall {
    /// The lane of the warp buffer whose test it was (the datapath instance's index).
    pub lane: u32,
    /// The ray's original words.
    pub ray: RayWords,
    /// Its closest hit so far.
    pub best: Option<Hit>,
    /// The node tested.
    pub node: NodeEntry,
    /// What the datapath decided.
    pub result: TestResult,
}

impl DatapathCall {
    /// Whether this call's key is `(ray, best, node)`.
    fn answers(&self, ray: &RayWords, best: Option<&Hit>, node: &NodeEntry) -> bool {
        self.ray == *ray && self.best.as_ref() == best && self.node == *node
    }
}

/// A datapath that keeps every test of the one it wraps in `calls`.
struct Recording<D> {
    inner: D,
    calls: Rc<RefCell<Vec<DatapathCall>>>,
}

impl<D: NodeDatapath> NodeDatapath for Recording<D> {
    fn test(
        &self,
        ray: &RayWords,
        best: Option<&Hit>,
        node: &NodeEntry,
        data: &[u8],
    ) -> TestResult {
        let result = self.inner.test(ray, best, node, data);
        self.calls.borrow_mut().push(DatapathCall {
            lane: 0,
            ray: *ray,
            best: best.copied(),
            node: *node,
            result: result.clone(),
        });
        result
    }
}

/// Runs the RT unit of `cfg` and `params` with `datapath` over `inputs` from reset and returns
/// each cycle's datapath tests, in the order it ran them, each with its lane: the lane whose
/// node in flight, ray words and closest hit are the test's, in the slot of the response
/// popped (the head of the response FIFO, else the cycle's first response) if it holds one.
/// Fails if a test matches no lane, or two tests one lane.
pub fn datapath_tables<D: NodeDatapath>(
    cfg: &HwConfig,
    params: &RtUnitParams,
    datapath: D,
    inputs: &[RtUnitInputs],
) -> Result<Vec<Vec<DatapathCall>>, GenError> {
    let calls = Rc::new(RefCell::new(Vec::new()));
    let unit = RtUnit::new(
        cfg.clone(),
        params.clone(),
        Recording {
            inner: datapath,
            calls: calls.clone(),
        },
    )?;
    let lane_bits = unit.widths().lane;
    let mut regs = unit.reset();
    let mut tables = Vec::with_capacity(inputs.len());
    for (cycle, i) in inputs.iter().enumerate() {
        let popped = regs
            .fifo
            .front()
            .or(i.responses.first())
            .map(|r| (r.tag >> lane_bits) as usize);
        let before = regs.clone();
        unit.step(&mut regs, i);
        let mut cycle_calls = std::mem::take(&mut *calls.borrow_mut());
        let mut taken = 0u64;
        for call in &mut cycle_calls {
            let lane = lane_of(&before, popped, call, taken).ok_or_else(|| GenError::Cosim {
                block: "rt_unit".into(),
                reason: format!(
                    "cycle {cycle}: a datapath test of node {:#x} matches no lane's node in \
                     flight, or a lane tested twice",
                    call.node.address
                ),
            })?;
            taken |= 1 << lane;
            call.lane = lane;
        }
        tables.push(cycle_calls);
    }
    Ok(tables)
}

/// How many datapath tests `tables` ([`datapath_tables`]) hold, and how many of them hit.
pub fn tests_and_hits(tables: &[Vec<DatapathCall>]) -> (usize, usize) {
    let calls = tables.iter().flatten();
    let hits = calls.clone().filter(|c| c.result.hit.is_some()).count();
    (tables.iter().map(Vec::len).sum(), hits)
}

/// The lane (not in `taken`) whose node in flight, ray words and closest hit are `call`'s,
/// looked for in slot `popped` first.
fn lane_of(
    regs: &RtUnitRegs,
    popped: Option<usize>,
    call: &DatapathCall,
    taken: u64,
) -> Option<u32> {
    let order = popped
        .into_iter()
        .chain((0..regs.slots.len()).filter(|&s| Some(s) != popped));
    for s in order {
        let Some(slot) = regs.slots.get(s).filter(|w| w.valid) else {
            continue;
        };
        let found = slot.lanes.iter().enumerate().position(|(l, lane)| {
            taken >> l & 1 == 0
                && lane.in_flight.is_some_and(|f| f.node == call.node)
                && lane.ray.words == call.ray
                && lane.ray.hit == call.best
        });
        if let Some(l) = found {
            return Some(l as u32);
        }
    }
    None
}

/// The datapath of [`RtUnitReplay`]: answers each test from the current cycle's table (a test
/// not in it finds nothing and is counted).
#[derive(Debug, Clone, Default)]
struct TableDatapath(Rc<Table>);

/// The table of [`TableDatapath`], shared with the block that fills it each cycle.
#[derive(Debug, Default)]
struct Table {
    calls: RefCell<Vec<DatapathCall>>,
    misses: Cell<u64>,
}

impl NodeDatapath for TableDatapath {
    fn test(&self, ray: &RayWords, best: Option<&Hit>, node: &NodeEntry, _: &[u8]) -> TestResult {
        let calls = self.0.calls.borrow();
        match calls.iter().find(|c| c.answers(ray, best, node)) {
            Some(c) => c.result.clone(),
            None => {
                self.0.misses.set(self.0.misses.get() + 1);
                TestResult::default()
            }
        }
    }
}

/// One cycle's inputs of a replay ([`RtUnitReplay`], [`TreeletRtUnitReplay`]): the replayed
/// block's (`I`), and the table its RT unit's datapath answers from: `table[l]` is lane `l`'s
/// test, valid this cycle when bit `l` of `valid` is set (an invalid entry's contents are
/// whatever the cycle before left, so that a long replay's vectors hold only the entries that
/// change).
#[derive(Debug, Clone)]
pub struct ReplayInputs<I = RtUnitInputs> {
    /// The replayed block's inputs.
    pub block: I,
    /// The table's entries (one per lane).
    pub table: Vec<Option<DatapathCall>>,
    /// Which entries are this cycle's tests.
    pub valid: u64,
    /// Bits of a stack entry (a node reference).
    entry_bits: u32,
    /// Children per result (`max_children`).
    max_children: u32,
}

impl<I> ReplayInputs<I> {
    /// The `dp_key` bits of entry `call` (`None`: zeros), lowest first: the ray words (word
    /// `j` in `[32 j +: 32]`), the closest hit's valid bit, the hit (`{attribs[1], attribs[0],
    /// hit id, t}`, zero without one), the node (`NodeEntry::encode`).
    fn push_key(&self, p: &mut BitPacker, call: Option<&DatapathCall>) {
        for j in 0..RAY_WORDS {
            p.push(call.map_or(0, |c| c.ray[j] as u64), 32);
        }
        let best = call.and_then(|c| c.best);
        p.push(best.is_some() as u64, 1);
        Hit::pack(best.as_ref(), p);
        p.push(call.map_or(0, |c| c.node.encode()), self.entry_bits);
    }

    /// The `dp_result` bits of entry `call`, lowest first: the child count (saturating), the
    /// children (`max_children` of [`CHILD_BITS`], child `c` at `[c CHILD_BITS +: CHILD_BITS]`
    /// as `{address[63:0], kind, chunks}`), the hit's valid bit and the hit.
    fn push_result(&self, p: &mut BitPacker, call: Option<&DatapathCall>) {
        let r = call.map(|c| &c.result);
        // The datapath's child count saturates.
        let count = r.map_or(0, |r| r.children.len() as u64);
        p.push(count.min((1 << CHILD_COUNT_BITS) - 1), CHILD_COUNT_BITS);
        for k in 0..self.max_children as usize {
            let child = r.and_then(|r| r.children.get(k));
            p.push(child.map_or(0, |c| c.chunks as u64), 8);
            p.push(child.map_or(0, |c| c.kind.code()), 3);
            p.push(child.map_or(0, |c| c.address), 64);
        }
        let hit = r.and_then(|r| r.hit);
        p.push(hit.is_some() as u64, 1);
        Hit::pack(hit.as_ref(), p);
    }

    /// Bits of one `dp_key` entry.
    fn key_bits(&self) -> u32 {
        RAY_WORDS as u32 * 32 + 1 + 128 + self.entry_bits
    }

    /// Bits of one `dp_result` entry.
    fn result_bits(&self) -> u32 {
        CHILD_COUNT_BITS + self.max_children * CHILD_BITS + 1 + 128
    }
}

impl<I: Signals> Signals for ReplayInputs<I> {
    fn signals(&self) -> Vec<Signal> {
        let mut s = self.block.signals();
        s.push(Signal::new("dp_valid", self.table.len() as u32, self.valid));
        s
    }

    fn bulk_signals(&self) -> Vec<Signal> {
        let mut s = self.block.bulk_signals();
        let (mut keys, mut results) = (BitPacker::new(), BitPacker::new());
        for call in &self.table {
            self.push_key(&mut keys, call.as_ref());
            self.push_result(&mut results, call.as_ref());
        }
        let n = self.table.len() as u32;
        push_words(&mut s, "dp_key", n * self.key_bits(), keys.into_words());
        push_words(
            &mut s,
            "dp_result",
            n * self.result_bits(),
            results.into_words(),
        );
        s
    }
}

/// Implements [`Block`] for a replay wrapper `$replay` of the block in its field `unit` (inputs
/// `$inputs`, outputs `$outputs`, registers `$regs`), whose RT unit `|$s| $rt` reaches: the
/// block's registers and outputs, with each cycle's table loaded before the block's step, and
/// the block's description with the table's ports as module `$module` (about `$what`), with
/// no registers (they are the replayed block's, one level down).
macro_rules! replay_block {
    ($replay:ty, $inputs:ty => $outputs:ty, $regs:ty, $module:expr, $what:expr,
     |$s:ident| $rt:expr) => {
        impl Block for $replay {
            type Inputs = ReplayInputs<$inputs>;
            type Outputs = $outputs;
            type Regs = $regs;

            fn reset(&self) -> $regs {
                self.unit.reset()
            }

            fn idle_inputs(&self) -> ReplayInputs<$inputs> {
                let $s = self;
                let rt = $rt;
                idle_replay(self.unit.idle_inputs(), rt.config(), rt.params())
            }

            fn next_into(
                &self,
                regs: &$regs,
                inputs: &ReplayInputs<$inputs>,
                next: &mut $regs,
            ) -> $outputs {
                load_table(&self.table, inputs);
                self.unit.next_into(regs, &inputs.block, next)
            }

            fn reg_signals(&self, regs: &$regs) -> Vec<Signal> {
                self.unit.reg_signals(regs)
            }

            fn describe(&self) -> BlockDesc {
                replay_desc(self.unit.describe(), $module, $what, &self.idle_inputs())
            }
        }
    };
}

/// The RT unit whose datapath answers from tables that arrive with its inputs (see the module
/// documentation); its outputs are [`RtUnitWithStatus`]'s.
/// A clone shares the table (each cycle's `next_into` loads it, so clones replay alike) and its
/// miss count.
#[derive(Debug, Clone)]
pub struct RtUnitReplay {
    unit: RtUnitWithStatus<TableDatapath>,
    table: Rc<Table>,
}

impl RtUnitReplay {
    /// The replay block of the RT unit of `cfg` and `params`.
    pub fn new(cfg: &HwConfig, params: &RtUnitParams) -> Result<Self, GenError> {
        let table = Rc::new(Table::default());
        let unit = RtUnit::new(cfg.clone(), params.clone(), TableDatapath(table.clone()))?;
        Ok(RtUnitReplay {
            unit: RtUnitWithStatus(unit),
            table,
        })
    }

    /// Tests the block's datapath found in no table so far (0 when the tables came from
    /// [`datapath_tables`] over the same inputs).
    pub fn misses(&self) -> u64 {
        self.table.misses.get()
    }

    /// The inputs of a replay: each cycle's RT-unit inputs with its tests (from
    /// [`datapath_tables`]) in their lanes' entries of a table of `warp_size` entries, the
    /// others left as the cycle before left them.
    pub fn inputs(
        &self,
        rt: Vec<RtUnitInputs>,
        tables: Vec<Vec<DatapathCall>>,
    ) -> Vec<ReplayInputs> {
        let idle = self.idle_inputs();
        with_tables(rt, tables, &idle)
    }

    /// The RT unit's registers where the replay wrapper's RTL holds them (its instance of
    /// `rt_unit`): what a co-simulation compares and shows in its waveform
    /// ([`crate::cosim::record_with_registers`]).
    pub fn registers(&self) -> Vec<RegSignal> {
        let regs = self.reg_signals(&self.reset());
        nested_registers(
            &self.unit.describe(),
            &format!("{REPLAY_INSTANCE}."),
            "",
            &regs,
        )
    }
}

/// Each cycle's inputs of the replayed block with its tests (from [`datapath_tables`]) in
/// their lanes' entries of a table shaped as `idle`'s, the other entries left as the cycle
/// before left them.
fn with_tables<I: Clone>(
    block: Vec<I>,
    tables: Vec<Vec<DatapathCall>>,
    idle: &ReplayInputs<I>,
) -> Vec<ReplayInputs<I>> {
    let mut table = idle.table.clone();
    block
        .into_iter()
        .zip(tables.into_iter().chain(std::iter::repeat_with(Vec::new)))
        .map(|(block, calls)| {
            let mut valid = 0u64;
            for call in calls {
                valid |= 1 << call.lane;
                let lane = call.lane as usize;
                table[lane] = Some(call);
            }
            ReplayInputs {
                block,
                table: table.clone(),
                valid,
                ..idle.clone()
            }
        })
        .collect()
}

/// An empty table for the RT unit of `cfg` and `params` around the replayed block's idle
/// inputs `block`.
fn idle_replay<I>(block: I, cfg: &HwConfig, params: &RtUnitParams) -> ReplayInputs<I> {
    ReplayInputs {
        block,
        table: vec![None; cfg.warp_size as usize],
        valid: 0,
        entry_bits: NodeEntry::bits(cfg.address_bits),
        max_children: params.max_children,
    }
}

/// Loads the cycle's valid entries of `inputs` into `table`.
fn load_table<I>(table: &Table, inputs: &ReplayInputs<I>) {
    *table.calls.borrow_mut() = inputs
        .table
        .iter()
        .enumerate()
        .filter(|(k, _)| inputs.valid >> k & 1 == 1)
        .filter_map(|(_, c)| c.clone())
        .collect();
}

/// A replay block's description: the replayed block's `d` as module `name`, documented with
/// `what`, with the table's ports (for `idle`'s table) and no registers (they are the replayed
/// block's, one level down).
fn replay_desc<I>(mut d: BlockDesc, name: &str, what: &str, idle: &ReplayInputs<I>) -> BlockDesc {
    let n = idle.table.len() as u32;
    d.doc = format!(
        "{what} replayed on recorded traffic: {} with the table its datapath answers from as \
         input ports. {}",
        d.name, d.doc
    );
    d.name = name.into();
    d.registers.clear();
    d.memories.clear();
    d.fsms.clear();
    d.ports.extend([
        PortDesc {
            name: "dp_valid".into(),
            dir: Dir::In,
            width: n,
            doc: "per entry: the entry is one of this cycle's datapath tests".into(),
        },
        PortDesc {
            name: "dp_key".into(),
            dir: Dir::In,
            width: n * idle.key_bits(),
            doc: "per entry: the test's ray words, closest hit (valid bit and hit) and node".into(),
        },
        PortDesc {
            name: "dp_result".into(),
            dir: Dir::In,
            width: n * idle.result_bits(),
            doc: "per entry: the test's child count, children, hit valid bit and hit".into(),
        },
    ]);
    d
}

replay_block!(
    RtUnitReplay,
    RtUnitInputs => RtUnitAllOutputs,
    RtUnitRegs,
    REPLAY_MODULE,
    "The RT unit's control",
    |replay| &replay.unit.0
);

/// The Verilog module name of [`RtUnitReplay`].
pub const REPLAY_MODULE: &str = "rt_unit_replay";

/// The treelet RT unit (RT unit, controller, tables and wiring) whose RT unit's datapath
/// answers from tables that arrive with its inputs, as [`RtUnitReplay`] does for the RT unit
/// alone: the tables of [`datapath_tables`] over the RT unit's inputs recorded in the same run
/// (`TableLog::rt_unit`) serve the whole block's replay (`TableLog::treelet`), cycle for cycle.
/// A clone shares the table and its miss count, as [`RtUnitReplay`]'s does.
#[derive(Debug, Clone)]
pub struct TreeletRtUnitReplay {
    unit: TreeletRtUnit<TableDatapath>,
    table: Rc<Table>,
}

impl TreeletRtUnitReplay {
    /// The replay block of the treelet RT unit of `cfg` and `params`.
    pub fn new(cfg: &HwConfig, params: &TreeletRtUnitParams) -> Result<Self, GenError> {
        let table = Rc::new(Table::default());
        let unit = TreeletRtUnit::new(cfg.clone(), params.clone(), TableDatapath(table.clone()))?;
        Ok(TreeletRtUnitReplay { unit, table })
    }

    /// Tests the block's datapath found in no table so far (0 when the tables came from
    /// [`datapath_tables`] over the RT unit's inputs of the same run).
    pub fn misses(&self) -> u64 {
        self.table.misses.get()
    }

    /// The inputs of a replay: each cycle's treelet-RT-unit inputs with the RT unit's tests of
    /// that cycle in their lanes' entries (as [`RtUnitReplay::inputs`]).
    pub fn inputs(
        &self,
        block: Vec<TreeletRtUnitInputs>,
        tables: Vec<Vec<DatapathCall>>,
    ) -> Vec<ReplayInputs<TreeletRtUnitInputs>> {
        with_tables(block, tables, &self.idle_inputs())
    }

    /// The treelet RT unit's registers where the replay wrapper's RTL holds them: each child's
    /// (Rust signals `<child>_<register>`) in its instance of the composite, the wiring's
    /// (`glue_<register>`, the composite's field `glue`) in the wiring's instance: what a
    /// co-simulation compares and shows in its waveform
    /// ([`crate::cosim::record_with_registers`]).
    pub fn registers(&self) -> Vec<RegSignal> {
        let regs = self.reg_signals(&self.reset());
        let mut out: Vec<RegSignal> = instances(&self.unit)
            .iter()
            .flat_map(|c| {
                let path = format!("{REPLAY_INSTANCE}.{}.", c.name);
                nested_registers(&c.desc, &path, &format!("{}_", c.name), &regs)
            })
            .collect();
        out.extend(nested_registers(
            &treelet_wiring_desc(&self.unit),
            &format!("{REPLAY_INSTANCE}.{WIRING_INSTANCE}."),
            "glue_",
            &regs,
        ));
        out
    }
}

replay_block!(
    TreeletRtUnitReplay,
    TreeletRtUnitInputs => TreeletRtUnitOutputs,
    TreeletRtUnitRegs,
    TREELET_REPLAY_MODULE,
    "The treelet RT unit",
    |replay| replay.unit.rt_unit()
);

/// The Verilog module name of [`TreeletRtUnitReplay`].
pub const TREELET_REPLAY_MODULE: &str = "treelet_rt_unit_replay";
