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
use vtq_hdl::rt_unit::{
    IssueTarget, LaneStatus, MemResponse, RayOutcome, RayRecord, RequestKind, RtUnit, RtUnitInputs,
    RtUnitParams, RtUnitRegs, StackLayout, StackSel, TraversalOrder,
};
use vtq_hdl::{Block, HwConfig};

mod commands;
mod coverage;
mod rays;
mod responses;
mod toy;

use commands::FAULTS;
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
    use vtq_hdl::rt_unit::{ErrorKind, Hit, NodeDatapath, NodeEntry, NodeKind, TestResult};
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
