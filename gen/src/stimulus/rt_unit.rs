//! Seeded random stimulus for the RT unit's control ([`RtUnit`]), played by a reactive
//! environment: a toy BVH in a memory model, a toy intersection datapath ([`ToyDatapath`],
//! specified byte for byte so that a Verilog twin can be written from it), and a treelet
//! controller that issues, stops, repacks and refills warps, and writes rays into lanes ahead of
//! their warp's issue (a free slot it reserves, or the inactive lanes of a held one) the way
//! the treelet wiring writes a fill's records as they arrive.
//!
//! The environment steps its own copy of the Rust block and reads its registers like a test
//! bench peeking at the design: it issues warps only into slots that are free (`issue_ready`,
//! or a free slot named by number), stops only two-stack warps that do not complete this cycle,
//! repacks a warp now and then and appends rays into the lanes the repack left inactive, and
//! keeps every resident ray id unique. Memory answers each node load and stack fill 1–12 cycles
//! later, out of order, with at most as many responses per cycle as the response FIFO accepts
//! (sometimes one more than `resp_free`, which the FIFO's pop makes room for; a response the
//! FIFO drops is sent again). Rays come fresh from a root, with a previous hit, already finished,
//! or in the middle of a traversal with stack chunks already spilled; rays parked at a treelet
//! boundary go back to a pool and are issued again in treelet warps.
//!
//! After the first [`QUIET_CYCLES`] cycles the environment also breaks the protocol, rarely,
//! to raise each of the block's sticky errors (counted per cycle in [`RtUnitCoverage`]): a
//! warp issued while the buffer is full, a malformed warp, a slot command naming a slot it
//! cannot act on, an append into a lane that holds a ray, a lane write the unit must refuse or
//! an issue naming a lane never written, one response more than the FIFO has
//! room for, a response matching nothing or a duplicate node chunk, rays of the ray class 7
//! (`ray[0] & 7`), the only ones that visit the tree's bad children. In the last sixteenth of
//! a stream of at least 2000 cycles one ray is issued with its spill area already full and a
//! full on-chip stack, so its next fetch raises `SpillAreaFull`: the scheduler then retries
//! that spill every cycle and makes no other request, so the stream ends with the unit
//! stalled. The same configuration, parameters, length and seed always give the same inputs.

use super::Rng;
use crate::error::GenError;
use std::collections::HashMap;
use vtq_hdl::bounded::BoundedVec;
use vtq_hdl::rt_unit::{
    occupied, pack_spill_chunk, spill_area, Hit, IssueTarget, LaneStatus, LaneWrite, MemResponse,
    NodeEntry, RayOutcome, RayRecord, RayWords, RequestKind, RtUnit, RtUnitInputs, RtUnitParams,
    RtUnitRegs, StackLayout, StackSel, TraversalOrder, WarpIssue, CHUNK_BYTES,
    STACK_ENTRIES_PER_CHUNK,
};
use vtq_hdl::{Block, HwConfig};

mod coverage;
mod toy;

pub use coverage::{RtUnitCoverage, ALL_ERRORS};
use toy::{build_tree, Memory, Tree};
pub use toy::{toy_node_bytes, ToyChild, ToyDatapath, TOY_MAGIC};

/// Cycles at the start of a stream in which the environment breaks no rule.
pub const QUIET_CYCLES: u64 = 500;

/// The configuration the RT unit's stimulus is tested with, for co-simulation tests to reuse:
/// 4-lane warps, 3 warp-buffer slots, 4-entry stacks, 16 rays, a 16-bit address space with
/// 128 B treelets, nodes of at most 3 children, a 4-entry response FIFO with 2 ports and 4 spill
/// chunks per stack.
pub fn small_config() -> (HwConfig, RtUnitParams) {
    let cfg = HwConfig {
        warp_size: 4,
        warp_buffer_size: 3,
        stack_depth: 4,
        max_rays: 16,
        address_bits: 16,
        treelet_bytes: 128,
        count_table_entries: 16,
        queue_table_entries: 8,
        underpopulation_threshold: 8,
        repack_threshold: 2,
        divergence_threshold: 2,
        ..HwConfig::default()
    };
    let params = RtUnitParams {
        max_children: 3,
        resp_fifo_depth: 4,
        resp_ports: 2,
        stack_spill_chunks: 4,
        ..RtUnitParams::default()
    };
    (cfg, params)
}

/// The protocol breaks the environment injects, in this order: a warp issued while no slot is
/// free, a warp issued into a taken or missing slot, an append to a slot not held, a stop and
/// a repack of an empty or missing slot (the repack is ignored, not an error), a malformed
/// warp, an append into a lane of the held slot that holds a ray, and a lane write into a slot
/// holding a warp that is not held (or an issue naming a lane never written).
const FAULTS: u64 = 8;

/// A free slot the environment reserved and is writing rays into before it issues the warp.
#[derive(Debug, Clone, Copy)]
struct Staged {
    /// The slot.
    slot: u32,
    /// The warp's order.
    order: TraversalOrder,
    /// Lanes written so far.
    written: u64,
    /// Writes still to send before the issue.
    left: u32,
}

/// The environment around the RT unit.
struct Env {
    rng: Rng,
    block: RtUnit<ToyDatapath>,
    regs: RtUnitRegs,
    tree: Tree,
    mem: Memory,
    /// Lanes per warp, entries per on-chip stack, stack entries a record carries, spill chunks
    /// per stack, ray ids.
    ws: usize,
    depth: usize,
    record: usize,
    chunks: u32,
    rays: u32,
    /// Responses to send, each with the first cycle it may be sent in; the last node chunk
    /// sent.
    pending: Vec<(u64, MemResponse)>,
    last_load: Option<MemResponse>,
    /// Ray ids not in use, and rays parked at a treelet boundary (their ids in use).
    free_ids: Vec<u32>,
    pool: Vec<RayRecord>,
    /// The slot a repack holds, with the appends still to send, and its lanes written ahead of
    /// the next append (which names them all).
    held: Option<(u32, u32)>,
    held_written: u64,
    /// A free slot being written ahead of its issue.
    staged: Option<Staged>,
    /// A fault ([`FAULTS`]) waiting for a cycle it applies in; a FIFO overflow likewise.
    fault: Option<u64>,
    overflow: bool,
    /// The cycle from which the spill-overflow ray is issued (until it is).
    finale: Option<u64>,
    cycle: u64,
    cov: RtUnitCoverage,
}

impl Env {
    fn new(
        cfg: &HwConfig,
        params: &RtUnitParams,
        cycles: u64,
        seed: u64,
    ) -> Result<Self, GenError> {
        let block = RtUnit::new(cfg.clone(), params.clone(), ToyDatapath)?;
        let mut rng = Rng::new(seed);
        let mut mem = HashMap::new();
        let tree = build_tree(&mut rng, cfg, params, &mut mem)?;
        Ok(Env {
            rng,
            regs: block.reset(),
            block,
            tree,
            mem,
            ws: cfg.warp_size as usize,
            depth: cfg.stack_depth as usize,
            record: cfg.record_stack_entries as usize,
            chunks: params.stack_spill_chunks,
            rays: cfg.max_rays,
            pending: Vec::new(),
            last_load: None,
            free_ids: (0..cfg.max_rays).rev().collect(),
            pool: Vec::new(),
            held: None,
            held_written: 0,
            staged: None,
            fault: None,
            overflow: false,
            finale: (cycles >= 2000).then(|| cycles - cycles / 16),
            cycle: 0,
            cov: RtUnitCoverage::default(),
        })
    }

    /// Uniform in `0..n` (n > 0).
    fn idx(&mut self, n: usize) -> usize {
        self.rng.below(n as u64) as usize
    }

    /// A random element of `v`.
    fn pick<T: Copy>(&mut self, v: &[T]) -> Option<T> {
        (!v.is_empty()).then(|| v[self.idx(v.len())])
    }

    /// `k` distinct random elements of `v`.
    fn subset(&mut self, mut v: Vec<usize>, k: usize) -> Vec<usize> {
        for i in 0..k.min(v.len()) {
            let j = i + self.idx(v.len() - i);
            v.swap(i, j);
        }
        v.truncate(k);
        v
    }

    /// The slots whose `valid` register is `valid`.
    fn slots(&self, valid: bool) -> Vec<u32> {
        let n = self.regs.slots.len() as u32;
        (0..n)
            .filter(|&s| self.regs.slots[s as usize].valid == valid)
            .collect()
    }

    /// Half the time a slot number the ports carry but the warp buffer lacks (if there is
    /// one), else a random one of `slots`.
    fn bad_slot(&mut self, slots: &[u32]) -> Option<u32> {
        let (have, named) = (
            self.regs.slots.len() as u64,
            1u64 << self.block.widths().slot,
        );
        match have < named && self.rng.chance(50) {
            true => Some((have + self.rng.below(named - have)) as u32),
            false => self.pick(slots),
        }
    }

    /// A random node of the tree (`leaf`: one without children).
    fn node(&mut self, leaf: bool) -> NodeEntry {
        let v = if leaf {
            &self.tree.leaves
        } else {
            &self.tree.nodes
        };
        v[self.rng.below(v.len() as u64) as usize]
    }

    /// An on-chip stack of `k` random leaves, with a random node on top unless `leaves`.
    fn stack(&mut self, k: usize, leaves: bool) -> BoundedVec<NodeEntry> {
        let nodes: Vec<NodeEntry> = (0..k).map(|j| self.node(leaves || j + 1 < k)).collect();
        BoundedVec::with(k.max(self.depth), nodes).unwrap_or_default()
    }

    /// A ray with id `id`: mostly fresh at a random root; sometimes with a previous hit,
    /// already finished, or in the middle of a traversal (a few nodes on both stacks, up to
    /// half the spill area of each spilled). Its spilled chunks are not stored yet
    /// ([`Env::store_spills`]). The ray class 7 (bad children) only after the quiet start.
    fn ray(&mut self, id: u32) -> RayRecord {
        let mut words: RayWords = std::array::from_fn(|_| self.rng.below(1 << 32) as u32);
        if self.cycle >= QUIET_CYCLES && self.rng.chance(12) {
            words[0] |= 7;
        } else if words[0] & 7 == 7 {
            words[0] ^= 1;
        }
        let root = self.idx(self.tree.roots.len());
        let mut ray = RayRecord::new(id, words, self.tree.roots[root]);
        // One ray in four is an occlusion ray (from its words: the stream of draws is kept).
        ray.occlusion = words[1] & 3 == 0;
        match self.rng.below(50) {
            0 => ray.other_stack = BoundedVec::new(self.depth),
            1..=10 => {
                let node = self.node(false);
                ray.current_treelet = self.block.treelet_of(node.address);
                let spare = self.chunks as u64 / 2;
                if spare > 0 && self.rng.chance(50) {
                    ray.current_spilled = self.rng.below(spare + 1) as u32;
                    ray.other_spilled = self.rng.below(spare + 1) as u32;
                }
                let leaves = ray.current_spilled + ray.other_spilled > 0;
                let most = self.record.min(3) + 1;
                let (a, b) = (self.idx(most), self.idx(most));
                ray.current_stack = self.stack(a, leaves);
                ray.other_stack = self.stack(b, leaves);
            }
            _ => {}
        }
        if self.rng.chance(10) {
            let mut w = || self.rng.below(1 << 32) as u32;
            let (t, hit_id, attribs) = (w(), w(), [w(), w()]);
            ray.hit = Some(Hit { t, hit_id, attribs });
        }
        ray
    }

    /// Stores the chunks `ray` has spilled, 1–4 leaves each, where the RT unit reads them.
    fn store_spills(&mut self, ray: &RayRecord) {
        let base = spill_area(self.block.config(), self.block.params()).0;
        for stack in [StackSel::Current, StackSel::Other] {
            for k in 0..ray.spilled(stack) as u64 {
                let n = 1 + self.idx(STACK_ENTRIES_PER_CHUNK.min(self.depth));
                let entries: Vec<NodeEntry> = (0..n).map(|_| self.node(true)).collect();
                let area = ray.ray_id as u64 * 2 + stack.code();
                let address = base + (area * self.chunks as u64 + k) * CHUNK_BYTES as u64;
                self.mem.insert(address, pack_spill_chunk(&entries));
            }
        }
    }

    /// A new ray with a free id, its spilled chunks stored.
    fn new_ray(&mut self) -> Option<RayRecord> {
        let i = (!self.free_ids.is_empty()).then(|| self.idx(self.free_ids.len()))?;
        let id = self.free_ids.swap_remove(i);
        let ray = self.ray(id);
        self.store_spills(&ray);
        Some(ray)
    }

    /// Lanes `lanes` of a warp of order `order` filled: with parked rays from the pool
    /// (two-stack orders only) or new rays (none when no id is free).
    fn fill(&mut self, order: TraversalOrder, lanes: Vec<usize>) -> Vec<Option<RayRecord>> {
        let mut out = vec![None; self.ws];
        for l in lanes {
            out[l] = if order.two_stack() && !self.pool.is_empty() && self.rng.chance(60) {
                let i = self.idx(self.pool.len());
                Some(self.pool.swap_remove(i))
            } else {
                self.new_ray()
            };
        }
        out
    }

    /// A warp of random rays with any ids, for a fault (never loaded).
    fn throwaway(&mut self, target: IssueTarget) -> WarpIssue {
        let lanes = (0..self.ws)
            .map(|_| {
                let id = self.rng.below(self.rays as u64) as u32;
                self.rng.chance(60).then(|| self.ray(id))
            })
            .collect();
        let order = TraversalOrder::ALL[self.idx(3)];
        WarpIssue {
            order,
            lanes,
            target,
            written: 0,
        }
    }

    /// Injects fault `f` ([`FAULTS`]) into `inp` if it applies this cycle.
    fn inject(&mut self, f: u64, inp: &mut RtUnitInputs) -> Option<()> {
        let (free, taken) = (self.slots(false), self.slots(true));
        match f {
            0 if free.is_empty() => inp.issue = Some(self.throwaway(IssueTarget::AnyFree)),
            0 => return None,
            1 => {
                let s = self.bad_slot(&taken)?;
                inp.issue = Some(self.throwaway(IssueTarget::Slot(s)));
            }
            2 | 6 => {
                // To a slot not held, or (fault 6) into a lane of the held slot that holds a ray.
                let slots = &self.regs.slots;
                let held = self.held.map(|(s, _)| s as usize);
                let busy: Vec<usize> = held.map_or(Vec::new(), |s| {
                    let lanes = slots[s].lanes.iter().enumerate();
                    (lanes.filter(|(_, l)| l.status != LaneStatus::Inactive))
                        .map(|(l, _)| l)
                        .collect()
                });
                let unheld: Vec<u32> = (0..slots.len() as u32)
                    .filter(|&s| !slots[s as usize].held)
                    .collect();
                let lane = if f == 6 {
                    Some(self.pick(&busy)?)
                } else {
                    None
                };
                let slot = match (held, lane) {
                    (Some(s), Some(_)) => s as u32,
                    _ => self.pick(&unheld)?,
                };
                let last = self.rng.chance(50);
                let mut warp = self.throwaway(IssueTarget::Append { slot, last });
                if let Some(l) = lane {
                    warp.lanes[l] = Some(self.ray(0));
                }
                inp.issue = Some(warp);
            }
            7 => {
                let lanes = (0..self.ws).map(|_| self.rng.chance(50).then(|| self.ray(0)));
                let lanes: Vec<_> = lanes.collect();
                let unheld: Vec<u32> = (taken.iter().copied())
                    .filter(|&s| !self.regs.slots[s as usize].held)
                    .collect();
                let staged = self.staged.map(|st| st.slot);
                let unstaged: Vec<u32> = (free.iter().copied())
                    .filter(|&s| Some(s) != staged)
                    .collect();
                if self.rng.chance(50) {
                    // A write into a warp's lanes.
                    let slot = self.pick(&unheld)?;
                    inp.write = Some(LaneWrite { slot, lanes });
                } else {
                    // An issue naming lanes never written.
                    let slot = self.pick(&unstaged)?;
                    let mut warp = self.throwaway(IssueTarget::Slot(slot));
                    warp.lanes = vec![None; self.ws];
                    warp.written = 1 << self.idx(self.ws);
                    inp.issue = Some(warp);
                }
            }
            3 => inp.stop = Some(self.bad_slot(&free)?),
            4 => inp.repack = Some(self.bad_slot(&free)?),
            _ => {
                // A malformed warp.
                let mut warp = self.throwaway(IssueTarget::AnyFree);
                let w = self.block.widths();
                let mut ray = self.ray(0);
                match self.rng.below(3) {
                    0 if (self.record + 1) >> w.record_pointer == 0 => {
                        ray.current_stack = self.stack(self.record + 1, false);
                    }
                    1 if (self.chunks + 1) >> w.spilled == 0 => ray.other_spilled = self.chunks + 1,
                    _ => {
                        let n = self.node(false);
                        let bad = NodeEntry {
                            address: n.address + 8,
                            ..n
                        };
                        ray.other_stack = BoundedVec::with(self.depth, [bad]).ok()?;
                    }
                }
                let l = self.idx(self.ws);
                warp.lanes[l] = Some(ray);
                inp.issue = Some(warp);
            }
        }
        Some(())
    }

    /// The SM's and the treelet controller's commands in a cycle without a fault.
    fn commands(&mut self, inp: &mut RtUnitInputs) {
        let free = self.slots(false);
        let finale = self.finale.is_some_and(|c| self.cycle >= c);
        if finale && self.staged.is_none() && !free.is_empty() && !self.free_ids.is_empty() {
            // A current stack full on chip and in memory: the next fetch must spill, and can't.
            self.finale = None;
            let mut lanes = vec![None; self.ws];
            let id = self.free_ids.pop().unwrap_or(0);
            let mut ray = self.ray(id);
            // (Full on chip only where a record carries a whole stack.)
            ray.current_stack = self.stack(self.record, true);
            ray.current_spilled = self.chunks;
            self.store_spills(&ray);
            lanes[0] = Some(ray);
            let (order, target) = (TraversalOrder::RayStationary, IssueTarget::AnyFree);
            inp.issue = Some(WarpIssue {
                order,
                lanes,
                target,
                written: 0,
            });
        } else if let Some((slot, left)) = self.held.filter(|_| self.rng.chance(35)) {
            let s = &self.regs.slots[slot as usize];
            let order = s.order;
            let inactive: Vec<usize> = (0..self.ws).filter(|&l| s.lanes[l].empty()).collect();
            let empty = inactive.is_empty() || self.rng.chance(10);
            let k = if empty {
                0
            } else {
                1 + self.idx(inactive.len())
            };
            let lanes = self.subset(inactive, k);
            let lanes = self.fill(order, lanes);
            if !empty && self.rng.chance(40) {
                // Written ahead of the next append.
                self.held_written |= occupied(&lanes);
                inp.write = Some(LaneWrite { slot, lanes });
            } else {
                let last = empty || left <= 1;
                self.held = (!last).then_some((slot, left - 1));
                let written = std::mem::take(&mut self.held_written);
                let target = IssueTarget::Append { slot, last };
                inp.issue = Some(WarpIssue {
                    order,
                    lanes,
                    target,
                    written,
                });
            }
        } else if let Some(st) = self.staged.filter(|_| self.rng.chance(40)) {
            self.staged_step(st, inp);
        } else if !free.is_empty() && self.rng.chance(85) {
            let order = TraversalOrder::ALL[self.idx(3)];
            let staged = self.staged.map(|st| st.slot);
            let unstaged: Vec<u32> = free
                .iter()
                .copied()
                .filter(|&s| Some(s) != staged)
                .collect();
            // The lowest free slot, where AnyFree goes, must not be the one being written.
            let target = match self.pick(&unstaged) {
                Some(s) if self.rng.chance(20) || staged == free.first().copied() => {
                    Some(IssueTarget::Slot(s))
                }
                Some(_) => Some(IssueTarget::AnyFree),
                None => None,
            };
            if let Some(target) = target {
                if self.staged.is_none() && unstaged.len() > 1 && self.rng.chance(15) {
                    // Reserve a free slot (not where this warp goes) and start writing it.
                    let slot = match target {
                        IssueTarget::Slot(s) => unstaged.iter().copied().find(|&x| x != s),
                        _ => unstaged.iter().copied().rfind(|&x| x != free[0]),
                    };
                    if let Some(slot) = slot {
                        let order = TraversalOrder::ALL[self.idx(3)];
                        let left = 1 + self.rng.below(3) as u32;
                        let (written, left) = (0, left);
                        self.staged = Some(Staged {
                            slot,
                            order,
                            written,
                            left,
                        });
                    }
                }
                let k = 1 + self.idx(self.ws);
                let lanes = self.subset((0..self.ws).collect(), k);
                let lanes = self.fill(order, lanes);
                inp.issue = Some(WarpIssue {
                    order,
                    lanes,
                    target,
                    written: 0,
                });
                if let Some(st) = self.staged.filter(|st| st.left > 0 && self.rng.chance(50)) {
                    // A write beside the issue, on the bus lanes it leaves free.
                    let used = inp.issue.as_ref().map_or(0, |i| occupied(&i.lanes));
                    self.stage_write(st, !used, inp);
                }
            }
        }
        if self.rng.chance(3) {
            // Never a ray-stationary warp, nor one that completes (freeing its slot) first.
            let slots = &self.regs.slots;
            let completing = (self.regs.age.iter().copied()).find(|&s| {
                !slots[s as usize].held
                    && slots[s as usize]
                        .lanes
                        .iter()
                        .all(|l| l.quiescent(self.record))
            });
            let stoppable: Vec<u32> = (self.slots(true).into_iter())
                .filter(|&s| slots[s as usize].order != TraversalOrder::RayStationary)
                .filter(|&s| Some(s) != completing)
                .collect();
            inp.stop = self.pick(&stoppable);
        }
        if self.held.is_none() && self.rng.below(200) == 0 {
            inp.repack = self.pick(&self.slots(true));
        }
    }

    /// One step of the staged slot `st`: a write of some lanes not written yet, or, when the
    /// writes are sent, the warp's issue naming the written lanes (with rays on the bus in some
    /// others: the last records written and issued in one cycle).
    fn staged_step(&mut self, st: Staged, inp: &mut RtUnitInputs) {
        if st.left > 0 {
            self.stage_write(st, u64::MAX, inp);
            return;
        }
        self.staged = None;
        let rest: Vec<usize> = (0..self.ws).filter(|&l| st.written >> l & 1 == 0).collect();
        let k = self.idx(rest.len() + 1);
        let lanes = self.subset(rest, k);
        let lanes = self.fill(st.order, lanes);
        inp.issue = Some(WarpIssue {
            order: st.order,
            lanes,
            target: IssueTarget::Slot(st.slot),
            written: st.written,
        });
    }

    /// A write of some of the staged slot's unwritten lanes among `free` (bus lanes), with new
    /// rays; counts one of its writes down.
    fn stage_write(&mut self, st: Staged, free: u64, inp: &mut RtUnitInputs) {
        let open: Vec<usize> = (0..self.ws)
            .filter(|&l| (free & !st.written) >> l & 1 == 1)
            .collect();
        let k = if open.is_empty() {
            0
        } else {
            1 + self.idx(open.len())
        };
        let lanes = self.subset(open, k);
        let lanes = self.fill(st.order, lanes);
        let mask = occupied(&lanes);
        self.staged = Some(Staged {
            written: st.written | mask,
            left: st.left - 1,
            ..st
        });
        if mask != 0 {
            inp.write = Some(LaneWrite {
                slot: st.slot,
                lanes,
            });
        }
    }

    /// A response to no request: a copy of the last node chunk sent (a duplicate, which
    /// matches only a later load of that chunk by the same lane, whose own response then
    /// matches nothing or a later one), or under a random tag a hit-record address (never a
    /// node) with random data, or a spill-area address with no stack entries (never a fill).
    fn junk(&mut self) -> MemResponse {
        if let Some(dup) = self.last_load.filter(|_| self.rng.chance(30)) {
            return dup;
        }
        let (base, end) = spill_area(self.block.config(), self.block.params());
        let tag = self.rng.below(1 << self.block.widths().tag) as u32;
        if self.rng.chance(50) {
            let records = self.block.params().hit_record_base;
            let address = records + 32 * self.rng.below(self.rays as u64);
            let data = std::array::from_fn(|_| self.rng.below(256) as u8);
            MemResponse { address, tag, data }
        } else {
            let address = base + 32 * self.rng.below((end - base) / 32);
            MemResponse {
                address,
                tag,
                data: [0; 32],
            }
        }
    }

    /// This cycle's responses: due ones in random order, as many as the FIFO takes (`resp_free`,
    /// or one more when the FIFO pops this cycle); rarely junk, or one more than the FIFO
    /// takes. Returns which are junk.
    fn responses(&mut self, inp: &mut RtUnitInputs) -> Vec<bool> {
        let late = self.cycle >= QUIET_CYCLES;
        let free = self.block.resp_free(&self.regs) as usize;
        let room = free + usize::from(!self.regs.fifo.is_empty());
        let ports = self.block.params().resp_ports as usize;
        self.overflow |= late && self.rng.below(400) == 0;
        let overflow = self.overflow && room < ports;
        self.overflow &= !overflow;
        let limit = match (overflow, room > free && self.rng.chance(50)) {
            (true, _) => room + 1,
            (false, more) => ports.min(if more { room } else { free }),
        };
        let mut junk = Vec::new();
        if late && limit > 0 && self.rng.below(500) == 0 {
            inp.responses.push(self.junk());
            junk.push(true);
        }
        let now = self.cycle;
        let mut due: Vec<usize> = (0..self.pending.len())
            .filter(|&i| self.pending[i].0 <= now)
            .collect();
        let mut chosen = Vec::new();
        while junk.len() + chosen.len() < limit && !due.is_empty() {
            let i = self.idx(due.len());
            chosen.push(due.swap_remove(i));
        }
        let spill = spill_area(self.block.config(), self.block.params());
        for &i in &chosen {
            let r = self.pending[i].1;
            if !(spill.0..spill.1).contains(&r.address) {
                self.last_load = Some(r);
            }
            inp.responses.push(r);
            junk.push(false);
        }
        chosen.sort_unstable();
        for &i in chosen.iter().rev() {
            self.pending.swap_remove(i);
        }
        while overflow && junk.len() < limit {
            inp.responses.push(self.junk());
            junk.push(true);
        }
        junk
    }

    /// One cycle: returns its inputs.
    fn cycle(&mut self) -> RtUnitInputs {
        let mut inp = self.block.idle_inputs();
        if self.cycle >= QUIET_CYCLES && self.fault.is_none() && self.rng.below(250) == 0 {
            self.fault = Some(self.rng.below(FAULTS));
        }
        if self
            .fault
            .is_some_and(|f| self.inject(f, &mut inp).is_some())
        {
            self.fault = None;
        } else {
            self.commands(&mut inp);
        }
        let junk = self.responses(&mut inp);
        self.step(&inp, &junk);
        inp
    }

    /// Steps the block on `inp` (whose responses are junk where `junk` says) and reacts to
    /// its outputs. The block is evaluated with its error registers cleared, so that its
    /// outputs show this cycle's errors only; the sticky registers are restored after.
    fn step(&mut self, inp: &RtUnitInputs, junk: &[bool]) {
        let now = self.cycle;
        let sticky = (self.regs.errors, self.regs.first_error.take());
        self.regs.errors = 0;
        let (out, mut next) = self.block.eval(&self.regs, inp);
        next.errors |= sticky.0;
        next.first_error = sticky.1.or(next.first_error);
        // Responses the FIFO dropped are sent again.
        let accepted = next.fifo.len() - self.regs.fifo.len().saturating_sub(1);
        for (r, _) in inp
            .responses
            .iter()
            .zip(junk)
            .skip(accepted)
            .filter(|(_, j)| !**j)
        {
            self.pending.push((now + 1, *r));
        }
        if let Some(req) = out.request {
            if matches!(req.kind, RequestKind::NodeLoad | RequestKind::StackFill) {
                let data = self.mem.get(&req.address).copied().unwrap_or([0; 32]);
                let (address, tag) = (req.address, req.tag);
                let due = now + 1 + self.rng.below(12);
                self.pending.push((due, MemResponse { address, tag, data }));
            } else if req.kind == RequestKind::StackSpill {
                self.mem.insert(req.address, req.data);
            }
        }
        let c = &mut self.cov;
        let left = out.done.iter().chain(&out.released);
        c.occlusion_hits += (left.flat_map(|d| d.lanes.iter().flatten()))
            .filter(|(ray, _)| ray.occlusion && ray.hit.is_some())
            .count() as u64;
        for (ray, outcome) in out.done.iter().flat_map(|d| d.lanes.iter().flatten()) {
            if *outcome == RayOutcome::Finished {
                self.free_ids.push(ray.ray_id);
            } else {
                c.parked += 1;
                self.pool.push(ray.clone());
            }
        }
        if let Some(rel) = &out.released {
            for (ray, _) in rel.lanes.iter().flatten() {
                self.free_ids.push(ray.ray_id);
                c.released += 1;
            }
            c.repacks += 1;
            self.held = Some((rel.slot, 1 + self.rng.below(3) as u32));
        }
        let (k, slots) = (&out.counts, &self.regs.slots);
        c.cycles += 1;
        c.node_loads += k.load_requests;
        c.split_loads += u64::from(self.regs.split.is_some());
        c.hit_stores += k.stores;
        c.stack_spills += k.stack_spills;
        c.stack_fills += k.stack_fills;
        c.merged += k.merged;
        c.tests += k.total_tests();
        c.triangle_hits += k.triangle_hits;
        c.boundaries += out.boundary.len() as u64;
        c.warps_done += k.warps;
        c.stops += u64::from(
            inp.stop
                .and_then(|s| slots.get(s as usize))
                .is_some_and(|s| s.valid),
        );
        if let Some(issue) = &inp.issue {
            if let IssueTarget::Append { slot, .. } = issue.target {
                let fits = slots.get(slot as usize).is_some_and(|s| {
                    let mut lanes = issue.lanes.iter().zip(s.lanes.iter());
                    s.valid
                        && s.held
                        && lanes.all(|(r, l)| r.is_none() || l.status == LaneStatus::Inactive)
                });
                c.appends += u64::from(fits && self.block.check_issue(issue).is_ok());
            } else if (0..slots.len()).any(|s| !slots[s].valid && next.slots[s].valid) {
                c.issued[issue.order.code() as usize] += 1;
                c.slot_issues += u64::from(matches!(issue.target, IssueTarget::Slot(_)));
            }
        }
        if let Some(w) = &inp.write {
            let s = w.slot as usize;
            let wrote = (0..self.ws).filter(|&l| {
                !slots.get(s).is_some_and(|x| x.lanes[l].written)
                    && next.slots.get(s).is_some_and(|x| x.lanes[l].written)
            });
            c.lane_writes += wrote.count() as u64;
        }
        if let Some(issue) = &inp.issue {
            let target = match issue.target {
                IssueTarget::AnyFree => None,
                t => Some(t.slot() as usize),
            };
            let woke = target.map_or(0, |s| {
                (0..self.ws)
                    .filter(|&l| {
                        issue.written >> l & 1 == 1
                            && slots.get(s).is_some_and(|x| x.lanes[l].written)
                            && next.slots.get(s).is_some_and(|x| {
                                !x.lanes[l].written && x.lanes[l].status != LaneStatus::Inactive
                            })
                    })
                    .count()
            });
            c.written_issues += u64::from(woke > 0);
        }
        c.fifo_full += u64::from(out.resp_free == 0);
        c.buffer_full += u64::from(!out.issue_ready);
        for (k, e) in c.errors.iter_mut().enumerate() {
            *e += u64::from(out.errors >> k & 1);
        }
        c.max_occupancy = c.max_occupancy.max(self.regs.age.len() as u64);
        let window = StackLayout::new(self.block.config(), self.block.params()).window as usize;
        let pairs = (self.regs.slots.iter().zip(next.slots.iter()))
            .flat_map(|(s, t)| s.lanes.iter().zip(t.lanes.iter()));
        for (a, b) in pairs {
            for sel in [StackSel::Current, StackSel::Other] {
                let (before, after) = (a.ray.stack(sel).len(), b.ray.stack(sel).len());
                let popped = a.in_flight.is_none() && b.in_flight.is_some();
                c.ring_pops += u64::from(popped && after + 1 == before && after > window);
            }
        }
        self.regs = next;
        self.cycle += 1;
    }
}

/// `cycles` cycles of RT-unit inputs from the reactive environment (see the module
/// documentation) for `cfg` and `params`, with the block they were played against (testing
/// nodes with [`ToyDatapath`]) and what they covered.
pub fn rt_unit_inputs(
    cfg: &HwConfig,
    params: &RtUnitParams,
    cycles: usize,
    seed: u64,
) -> Result<(RtUnit<ToyDatapath>, Vec<RtUnitInputs>, RtUnitCoverage), GenError> {
    let mut env = Env::new(cfg, params, cycles as u64, seed)?;
    let inputs = (0..cycles).map(|_| env.cycle()).collect();
    Ok((env.block, inputs, env.cov))
}

#[cfg(test)]
mod tests {
    use super::*;
    use vtq_hdl::rt_unit::{ErrorKind, NodeDatapath, NodeKind, TestResult};
    use vtq_hdl::Signals;

    #[test]
    fn same_seed_same_stream_other_seed_other_stream() {
        let (cfg, params) = small_config();
        let run = |seed| rt_unit_inputs(&cfg, &params, 3000, seed).unwrap();
        let ((_, a, ca), (_, b, cb), (_, c, _)) = (run(7), run(7), run(8));
        let signals = |v: &[RtUnitInputs]| v.iter().map(Signals::signals).collect::<Vec<_>>();
        assert_eq!(signals(&a), signals(&b));
        assert_ne!(signals(&c), signals(&b));
        assert_eq!((a, ca.cycles), (b, 3000));
        assert_eq!(ca, cb);
    }

    /// At the paper's sizes the stimulus drives stacks past their window: pops leave the top
    /// in the RTL's SRAM ring (a read the next cycle), which co-simulation then checks.
    #[test]
    fn default_config_pops_tops_out_of_the_ring() {
        let (_, _, cov) =
            rt_unit_inputs(&HwConfig::default(), &RtUnitParams::default(), 2000, 7).unwrap();
        println!("{cov}");
        assert!(cov.ring_pops >= 20, "{cov}");
    }

    #[test]
    fn small_config_covers_everything() {
        let (cfg, params) = small_config();
        cfg.validate().unwrap();
        let (block, inputs, cov) = rt_unit_inputs(&cfg, &params, 20_000, 1).unwrap();
        println!("{cov}");
        cov.covers_everything(5, ALL_ERRORS).unwrap();
        // Replayed: responses fit the ports, ray ids and treelets their fields, no
        // ray-stationary warp is stopped, resident ray ids are unique.
        let w = block.widths();
        let mut regs = block.reset();
        for i in &inputs {
            assert!(i.responses.len() <= params.resp_ports as usize);
            for ray in i.issue.iter().flat_map(|x| x.lanes.iter().flatten()) {
                assert!(ray.ray_id < cfg.max_rays && ray.current_treelet >> w.treelet == 0);
            }
            if let Some(slot) = i.stop.and_then(|s| regs.slots.get(s as usize)) {
                assert!(!slot.valid || slot.order != TraversalOrder::RayStationary);
            }
            block.step(&mut regs, i);
            let lanes = regs
                .slots
                .iter()
                .filter(|s| s.valid)
                .flat_map(|s| s.lanes.iter());
            let mut ids: Vec<u32> = (lanes.filter(|l| l.status != LaneStatus::Inactive))
                .map(|l| l.ray.ray_id)
                .collect();
            let resident = ids.len();
            ids.sort_unstable();
            ids.dedup();
            assert_eq!(ids.len(), resident);
        }
        assert_eq!(regs.errors, ALL_ERRORS);
    }

    #[test]
    fn the_start_is_clean_and_a_small_spill_area_fills() {
        let (cfg, mut params) = small_config();
        let (_, _, cov) = rt_unit_inputs(&cfg, &params, QUIET_CYCLES as usize, 3).unwrap();
        assert_eq!(cov.errors, [0; 7], "{cov}");
        // Too short for the final overflowing ray: the spill area overflows by itself, in
        // some streams (the unit then stalls).
        params.stack_spill_chunks = 1;
        let full = |seed| {
            let (_, _, cov) = rt_unit_inputs(&cfg, &params, 1999, seed).unwrap();
            cov.errors[ErrorKind::SpillAreaFull.code() as usize] > 0
        };
        assert!((1..=20).any(full));
    }

    #[test]
    fn bad_parameters_are_an_error() {
        let (cfg, mut params) = small_config();
        params.max_children = 5;
        let err = rt_unit_inputs(&cfg, &params, 10, 1)
            .unwrap_err()
            .to_string();
        assert!(err.contains("max_children"), "{err}");
    }

    #[test]
    fn toy_datapath_follows_its_format() {
        let node = |address, kind, chunks| NodeEntry {
            address,
            kind,
            chunks,
        };
        let records = [
            (0x100, 1, 1, 0b100),
            (0x140, 4, 2, 0b011),
            (0x1A0, 6, 1, 0xFF),
            (0x1C1, 5, 0, 0xFF),
            (0x200, 2, 4, 0b100),
            (0x300, 1, 1, 0xFF),
            (0x400, 1, 1, 0xFF),
            (0x500, 1, 1, 0xFF),
        ];
        let children: Vec<ToyChild> = (records.iter())
            .map(|&(address, kind, chunks, mask)| ToyChild {
                address,
                kind,
                chunks,
                mask,
            })
            .collect();
        let at = node(0x40, NodeKind::Internal, 2);
        let data = toy_node_bytes(2, Some(0xBF80), &children);
        assert_eq!((data.len(), data[0], data[63]), (64, 8, TOY_MAGIC));
        let test = |class: u32, data: &[u8], at| {
            ToyDatapath.test(&[0x1230 | class, 0, 0, 0, 0, 0, 0, 0], None, &at, data)
        };
        // Class 2: kind 6 skipped, the bad child kept, only the 7 records that fit read.
        let r = test(2, &data, at);
        let kept = [
            node(0x100, NodeKind::Internal, 1),
            node(0x1C1, NodeKind::Procedural, 0),
            node(0x200, NodeKind::InstanceLeaf, 4),
            node(0x300, NodeKind::Internal, 1),
            node(0x400, NodeKind::Internal, 1),
        ];
        assert_eq!(r.children, kept);
        let attribs = [0x1232, 0x40 ^ 0x5555_5555];
        let hit = Hit {
            t: 0xBF80_0000,
            hit_id: 0x40,
            attribs,
        };
        assert_eq!(r.hit, Some(hit));
        let r = test(1, &data, at);
        assert_eq!(
            r.children[..2],
            [node(0x140, NodeKind::TriangleLeaf, 2), kept[1]]
        );
        assert_eq!(r.children.len(), 4);
        // No hit flag and 3 records in one chunk; a wrong magic byte or size: nothing.
        let small = toy_node_bytes(1, None, &children);
        let r = test(2, &small, node(0, NodeKind::Internal, 1));
        assert_eq!((r.children, r.hit), (vec![kept[0]], None));
        let mut bad = data.clone();
        bad[63] = !TOY_MAGIC;
        assert_eq!(test(2, &bad, at), TestResult::default());
        assert_eq!(test(2, &data[..32], at), TestResult::default());
    }
}
