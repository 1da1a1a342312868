//! Tests of the RT unit control block with a toy datapath and a fixed-latency memory.

use std::collections::BTreeMap;
use vtq_hdl::bits::fits;
use vtq_hdl::bounded::BoundedVec;
use vtq_hdl::rt_unit::StatusSelect;
use vtq_hdl::rt_unit::{
    errors, spill_area, unpack_spill_chunk, BoundaryEvent, ErrorKind, Hit, IssueTarget, Lane,
    LaneStatus, LaneWrite, MemRequest, MemResponse, NodeEntry, NodeKind, RayOutcome, RayRecord,
    RequestKind, RtCache, RtStats, RtUnit, RtUnitError, RtUnitInputs, RtUnitOutputs, RtUnitParams,
    RtUnitRegs, SlotSummary, Split, TraversalOrder, WarpDone, WarpIssue, CHUNK_BYTES,
};
use vtq_hdl::splitmix::SplitMix64;
use vtq_hdl::{Block, Cached, HwConfig, Moore, Signals, Skip};

mod common;
use common::{node, words, ToyDatapath, Tree, ALL};

/// Default test latencies (Vulkan-Sim's treelet-prefetching configuration): internal node and
/// triangle leaf / hit.
const L_INTERNAL: u64 = 4;
const L_TRIANGLE: u64 = 4;

/// Memory returning each load's chunk `latency` cycles after the request (plus a per-address
/// extra delay), never before `hold_until`, as many per cycle as the RT unit accepts.
struct Memory {
    tree: Tree,
    latency: u64,
    extra: BTreeMap<u64, u64>,
    hold_until: u64,
    pending: Vec<(u64, MemResponse)>,
    log: Vec<(u64, MemRequest)>,
}

impl Memory {
    fn new(tree: Tree, latency: u64) -> Self {
        Memory {
            tree,
            latency,
            extra: BTreeMap::new(),
            hold_until: 0,
            pending: Vec::new(),
            log: Vec::new(),
        }
    }

    fn deliver(&mut self, cycle: u64, max: usize) -> Vec<MemResponse> {
        if cycle < self.hold_until {
            return Vec::new();
        }
        // `pending` is in request order; take the due ones oldest first.
        let mut out = Vec::new();
        let mut i = 0;
        while i < self.pending.len() && out.len() < max {
            if self.pending[i].0 <= cycle {
                out.push(self.pending.remove(i).1);
            } else {
                i += 1;
            }
        }
        out
    }

    fn accept(&mut self, cycle: u64, req: Option<MemRequest>) {
        let Some(req) = req else { return };
        self.log.push((cycle, req));
        if req.kind == RequestKind::StackSpill {
            self.tree.chunks.insert(req.address, req.data);
        }
        if !req.is_store() {
            let due = cycle + self.latency + self.extra.get(&req.address).copied().unwrap_or(0);
            let data = self
                .tree
                .chunks
                .get(&req.address)
                .copied()
                .unwrap_or([0; 32]);
            self.pending.push((
                due,
                MemResponse {
                    address: req.address,
                    tag: req.tag,
                    data,
                },
            ));
        }
    }

    /// (cycle, address, is_store) of every request.
    fn requests(&self) -> Vec<(u64, u64, bool)> {
        self.log
            .iter()
            .map(|(c, r)| (*c, r.address, r.is_store()))
            .collect()
    }
}

/// The RT unit, its registers and its memory, stepped cycle by cycle.
struct Sim {
    unit: RtUnit<ToyDatapath>,
    regs: RtUnitRegs,
    cache: RtCache,
    stats: RtStats,
    mem: Memory,
    cycle: u64,
    use_eval: bool,
    done: Vec<(u64, WarpDone)>,
    events: Vec<(u64, BoundaryEvent)>,
    outputs: Vec<RtUnitOutputs>,
    max_fifo: usize,
}

impl Sim {
    fn new(cfg: HwConfig, params: RtUnitParams, mem: Memory) -> Self {
        let unit = RtUnit::new(cfg, params, ToyDatapath).unwrap();
        let regs = unit.reset();
        Sim {
            cache: unit.cache(&regs),
            unit,
            stats: RtStats::default(),
            regs,
            mem,
            cycle: 0,
            use_eval: false,
            done: Vec::new(),
            events: Vec::new(),
            outputs: Vec::new(),
            max_fifo: 0,
        }
    }

    /// Entries of its other stack a parked lane keeps (`record_stack_entries`).
    fn keep(&self) -> usize {
        self.unit.config().record_stack_entries as usize
    }

    fn step(&mut self, issue: Option<WarpIssue>) {
        self.step_with(|inputs| inputs.issue = issue);
    }

    /// One cycle with idle inputs changed by `set` (responses are added here).
    fn step_with(&mut self, set: impl FnOnce(&mut vtq_hdl::rt_unit::RtUnitInputs)) {
        let mut inputs = self.unit.idle_inputs();
        set(&mut inputs);
        let max = self
            .unit
            .status(&self.regs, &self.cache, StatusSelect::Scalars)
            .resp_free
            .min(self.unit.params().resp_ports);
        inputs.responses = self.mem.deliver(self.cycle, max as usize);
        let status = self
            .unit
            .status(&self.regs, &self.cache, StatusSelect::Scalars);
        let out = if self.use_eval {
            let (out, next) = self.unit.eval(&self.regs, &inputs);
            self.regs = next;
            self.cache = self.unit.cache(&self.regs);
            out
        } else {
            // The fast path must give exactly what the definition gives.
            let (expected, next) = self.unit.eval(&self.regs, &inputs);
            let out = self
                .unit
                .step_cached(&mut self.regs, &mut self.cache, &inputs);
            assert_eq!(out, expected, "step_cached outputs, cycle {}", self.cycle);
            assert_eq!(
                self.regs, next,
                "step_cached registers, cycle {}",
                self.cycle
            );
            out
        };
        assert_eq!(
            (status.issue_ready, status.resp_free),
            (out.issue_ready, out.resp_free),
            "Moore status and the outputs' register-only ports, cycle {}",
            self.cycle
        );
        self.stats.add(&out.counts);
        self.max_fifo = self.max_fifo.max(self.regs.fifo.len());
        self.mem.accept(self.cycle, out.request);
        if let Some(d) = &out.done {
            self.done.push((self.cycle, d.clone()));
        }
        self.events
            .extend(out.boundary.iter().map(|e| (self.cycle, *e)));
        self.outputs.push(out);
        self.cycle += 1;
    }

    /// Issues `warps` one per cycle from cycle 0 and runs until all have completed.
    fn run(&mut self, warps: Vec<WarpIssue>) {
        let n = self.done.len() + warps.len();
        for w in warps {
            assert!(
                self.unit
                    .status(&self.regs, &self.cache, StatusSelect::Scalars)
                    .issue_ready
            );
            self.step(Some(w));
        }
        while self.done.len() < n {
            assert!(self.cycle < 50_000, "warps did not complete");
            self.step(None);
        }
        assert_eq!(self.regs.errors, 0, "protocol errors");
    }
}

/// A small configuration: 4-lane warps, 2 warp slots, 16-bit addresses, 256 B treelets.
fn small() -> HwConfig {
    HwConfig {
        max_rays: 16,
        warp_size: 4,
        address_bits: 16,
        treelet_bytes: 256,
        underpopulation_threshold: 8,
        repack_threshold: 2,
        divergence_threshold: 2,
        warp_buffer_size: 2,
        stack_depth: 16,
        ..HwConfig::default()
    }
}

/// A warp of `lanes` (`None` inactive) padded to `warp_size` lanes.
fn warp(order: TraversalOrder, warp_size: u32, lanes: Vec<Option<RayRecord>>) -> WarpIssue {
    let mut lanes = lanes;
    lanes.resize(warp_size as usize, None);
    WarpIssue {
        order,
        lanes,
        ..WarpIssue::default()
    }
}

fn ray(id: u32, select: u32, root: NodeEntry) -> Option<RayRecord> {
    Some(RayRecord::new(id, words(select), root))
}

#[test]
fn single_ray_three_node_path_completes_on_the_derived_cycle() {
    // Root A (internal, 64 B) -> B (internal, 64 B) -> C (triangle leaf, 32 B, hit).
    let (a, b, c) = (
        node(0x100, NodeKind::Internal, 64),
        node(0x200, NodeKind::Internal, 64),
        node(0x300, NodeKind::TriangleLeaf, 32),
    );
    let mut tree = Tree::default();
    tree.add(a, false, &[(b, ALL)])
        .add(b, false, &[(c, ALL)])
        .add(c, true, &[]);
    const M: u64 = 10;
    let params = RtUnitParams {
        hit_record_base: 0x8000,
        ..RtUnitParams::default()
    };
    let mut sim = Sim::new(HwConfig::default(), params, Memory::new(tree, M));
    sim.run(vec![warp(
        TraversalOrder::RayStationary,
        32,
        vec![ray(7, 0, a)],
    )]);
    // Derivation (M = memory latency: a request in cycle t returns at the input in t + M,
    // enters the FIFO at the end of that cycle and is popped in t + M + 1; a test of latency L
    // popped in cycle p allows the next request in p + L + 1):
    //   issue cycle 0 -> A chunk 0 requested in 1, chunk 1 in 2 (remaining chunks first);
    //   A's chunks popped in 2 + M and 3 + M; internal test: B requested in 3 + M + 5 = 8 + M,
    //   B + 32 in 9 + M; B's last chunk popped in 10 + 2M; C requested in 15 + 2M;
    //   C popped in 16 + 3M: hit -> delay 4, store pending, ray done;
    //   the store issues in 17 + 3M; the delay reaches 0 at the start of 21 + 3M, so the warp
    //   completes in 21 + 3M = 51.
    let expected = vec![
        (1, 0x100, false),
        (2, 0x120, false),
        (8 + M, 0x200, false),
        (9 + M, 0x220, false),
        (15 + 2 * M, 0x300, false),
        (17 + 3 * M, 0x8000 + 7 * 32, true),
    ];
    assert_eq!(sim.mem.requests(), expected);
    assert_eq!(sim.done.len(), 1);
    let (cycle, done) = &sim.done[0];
    assert_eq!(*cycle, 21 + 3 * M);
    assert_eq!(*cycle, 51);
    let (rec, outcome) = done.lanes[0].as_ref().unwrap();
    assert_eq!(*outcome, RayOutcome::Finished);
    assert_eq!(rec.ray_id, 7);
    assert_eq!(rec.hit.unwrap().hit_id, 0x300);
    assert_eq!(rec.hit.unwrap().t, 0.5f32.to_bits());
    assert_eq!(rec.words, words(0), "the ray keeps its original words");
    assert!(done.lanes[1..].iter().all(Option::is_none));
    // The store carries the hit record: t, hit id, attributes, ray id.
    let store = sim.mem.log.last().unwrap().1;
    assert_eq!(&store.data[0..4], &0.5f32.to_bits().to_le_bytes());
    assert_eq!(&store.data[4..8], &0x300u32.to_le_bytes());
    assert_eq!(&store.data[16..20], &7u32.to_le_bytes());
    let st = &sim.stats;
    assert_eq!(st.load_requests, 5);
    assert_eq!(st.stores, 1);
    assert_eq!(st.tests[NodeKind::Internal.code() as usize], 2);
    assert_eq!(st.tests[NodeKind::TriangleLeaf.code() as usize], 1);
    assert_eq!(st.triangle_hits, 1);
    assert_eq!(st.warps, 1);
}

#[test]
fn sixty_four_byte_nodes_take_two_consecutive_requests() {
    let (a, b) = (
        node(0x100, NodeKind::Internal, 64),
        node(0x200, NodeKind::Internal, 64),
    );
    let mut tree = Tree::default();
    tree.add(a, false, &[]).add(b, false, &[]);
    let mut sim = Sim::new(small(), RtUnitParams::default(), Memory::new(tree, 20));
    sim.run(vec![
        warp(TraversalOrder::RayStationary, 4, vec![ray(0, 0, a)]),
        warp(TraversalOrder::RayStationary, 4, vec![ray(1, 0, b)]),
    ]);
    // Warp 1 is ready in cycle 2, but A's second chunk goes first.
    let reqs = sim.mem.requests();
    assert_eq!(
        reqs,
        vec![
            (1, 0x100, false),
            (2, 0x120, false),
            (3, 0x200, false),
            (4, 0x220, false)
        ]
    );
    let tags: Vec<u32> = sim.mem.log.iter().map(|(_, r)| r.tag).collect();
    // tag = slot << lane_bits | lane with 2 lane bits.
    assert_eq!(tags, vec![0, 0, 4, 4]);
    // At most one request per cycle over the whole run.
    for pair in reqs.windows(2) {
        assert!(pair[0].0 < pair[1].0);
    }
}

/// A lane ready to fetch `root`.
fn ready_lane(id: u32, root: NodeEntry) -> Lane {
    Lane {
        status: LaneStatus::Traversing,
        ray: RayRecord::new(id, words(0), root),
        ..Lane::default()
    }
}

/// A finished lane whose hit record still has to be stored.
fn storing_lane(id: u32) -> Lane {
    let mut ray = RayRecord::new(id, words(0), node(0, NodeKind::Internal, 32));
    ray.other_stack.clear();
    ray.hit = Some(Hit::default());
    Lane {
        status: LaneStatus::Done,
        ray,
        store_pending: true,
        ..Lane::default()
    }
}

#[test]
fn scheduler_priority_chunks_then_stores_then_oldest_warp() {
    let unit = RtUnit::new(
        small(),
        RtUnitParams {
            hit_record_base: 0x4000,
            ..RtUnitParams::default()
        },
        ToyDatapath,
    )
    .unwrap();
    let mut regs = unit.reset();
    let (r0, r1, r2) = (
        node(0x400, NodeKind::Internal, 32),
        node(0x500, NodeKind::Internal, 64),
        node(0x600, NodeKind::Internal, 32),
    );
    // Slot 1 is the older warp.
    regs.age = vtq_hdl::bounded::BoundedVec::with(regs.age.capacity(), [1, 0]).unwrap();
    regs.slots[0].valid = true;
    regs.slots[0].lanes[0] = ready_lane(0, r0);
    regs.slots[0].lanes[2] = storing_lane(2);
    regs.slots[1].valid = true;
    regs.slots[1].lanes[0] = ready_lane(4, r1);
    regs.slots[1].lanes[1] = ready_lane(5, r1);
    regs.slots[1].lanes[2] = ready_lane(6, r2);
    regs.slots[1].lanes[3] = storing_lane(7);
    // A 64 B node of slot 0 lane 1 has its second chunk left.
    let pending = node(0x700, NodeKind::Internal, 64);
    regs.split = Some(Split {
        tag: 1,
        node: pending,
        next_chunk: 1,
    });
    let idle = unit.idle_inputs();
    let mut reqs = Vec::new();
    let mut stats = RtStats::default();
    for _ in 0..8 {
        let out = unit.step(&mut regs, &idle);
        stats.add(&out.counts);
        reqs.push(out.request.map(|r| (r.address, r.is_store(), r.tag)));
    }
    assert_eq!(
        reqs,
        vec![
            Some((0x720, false, 1)),                   // remaining chunk first
            Some((0x4000 + 7 * 32, true, 1 << 2 | 3)), // store of the oldest warp
            Some((0x4000 + 2 * 32, true, 2)),          // then the younger warp's store
            Some((0x500, false, 1 << 2)),              // oldest warp, lanes 0 and 1 merged
            Some((0x520, false, 1 << 2)),              // its second chunk
            Some((0x600, false, 1 << 2 | 2)),          // oldest warp is still not stalled
            Some((0x400, false, 0)),                   // then the younger warp
            None,
        ]
    );
    let lanes = &regs.slots[1].lanes;
    assert_eq!(lanes[0].in_flight.unwrap().leader, 0);
    assert_eq!(lanes[1].in_flight.unwrap().leader, 0);
    assert_eq!(lanes[1].in_flight.unwrap().node, r1);
    assert_eq!(stats.merged, 1);
    assert_eq!(stats.load_requests, 5);
    assert_eq!(stats.stores, 2);
}

#[test]
fn identical_requests_merge_within_a_warp_not_across_warps() {
    let r = node(0x100, NodeKind::Internal, 64);
    let other = node(0x180, NodeKind::Internal, 64);
    let mut tree = Tree::default();
    tree.add(r, false, &[]).add(other, false, &[]);
    let mut sim = Sim::new(small(), RtUnitParams::default(), Memory::new(tree, 15));
    sim.run(vec![
        warp(
            TraversalOrder::RayStationary,
            4,
            vec![ray(0, 0, r), ray(1, 0, other), ray(2, 0, r), ray(3, 0, r)],
        ),
        warp(
            TraversalOrder::RayStationary,
            4,
            vec![None, ray(4, 0, r), ray(5, 0, r)],
        ),
    ]);
    let loads: Vec<(u64, u32)> = sim
        .mem
        .log
        .iter()
        .map(|(_, q)| (q.address, q.tag))
        .collect();
    assert_eq!(
        loads,
        vec![
            (0x100, 0),
            (0x120, 0),
            (0x180, 1),
            (0x1a0, 1),
            (0x100, 4 | 1),
            (0x120, 4 | 1)
        ]
    );
    assert_eq!(sim.stats.merged, 3);
    assert_eq!(sim.stats.tests[NodeKind::Internal.code() as usize], 6);
    let finished: usize = sim
        .done
        .iter()
        .flat_map(|(_, d)| d.lanes.iter().flatten())
        .filter(|(_, o)| *o == RayOutcome::Finished)
        .count();
    assert_eq!(finished, 6);
}

#[test]
fn next_fetch_waits_for_every_chunk_and_the_test_latency() {
    for internal in [4u32, 9] {
        let a = node(0x100, NodeKind::Internal, 64);
        let c = node(0x300, NodeKind::TriangleLeaf, 32);
        let mut tree = Tree::default();
        tree.add(a, false, &[(c, ALL)]).add(c, false, &[]);
        let mut mem = Memory::new(tree, 3);
        mem.extra.insert(0x120, 17);
        let mut params = RtUnitParams::default();
        params.latencies.internal = internal;
        let mut sim = Sim::new(small(), params, mem);
        sim.step(Some(warp(
            TraversalOrder::RayStationary,
            4,
            vec![ray(0, 0, a)],
        )));
        // A + 0 requested in 1, returns in 4, popped in 5; A + 32 requested in 2, returns in
        // 2 + 3 + 17 = 22, popped in 23.
        for _ in 1..6 {
            sim.step(None);
        }
        let lane = &sim.regs.slots[0].lanes[0];
        assert_eq!(lane.in_flight.unwrap().returned, 0b01, "chunk 0 only");
        while sim.done.is_empty() {
            sim.step(None);
        }
        let c_request = 23 + internal as u64 + 1;
        assert_eq!(
            sim.mem.requests(),
            vec![
                (1, 0x100, false),
                (2, 0x120, false),
                (c_request, 0x300, false)
            ]
        );
    }
}

#[test]
fn simt_efficiency_counts_traversing_lanes_per_warp_cycle() {
    // Lane 0: root X is a leaf; lane 1: root Y (internal) -> Z (leaf); lanes 2, 3 inactive.
    let (x, y, z) = (
        node(0x100, NodeKind::TriangleLeaf, 32),
        node(0x200, NodeKind::Internal, 32),
        node(0x300, NodeKind::TriangleLeaf, 32),
    );
    let mut tree = Tree::default();
    tree.add(x, false, &[])
        .add(y, false, &[(z, ALL)])
        .add(z, false, &[]);
    const M: u64 = 5;
    let mut sim = Sim::new(small(), RtUnitParams::default(), Memory::new(tree, M));
    sim.run(vec![warp(
        TraversalOrder::RayStationary,
        4,
        vec![ray(0, 0, x), ray(1, 0, y)],
    )]);
    // X requested in 1, popped in 2 + M: lane 0 traverses in cycles 1..=2+M.
    // Y requested in 2, popped in 3 + M; Z requested in 3 + M + L_INTERNAL + 1, popped
    // M + 1 cycles later: lane 1 traverses in cycles 1..=last_pop.
    let last_pop = 3 + M + L_INTERNAL + 1 + M + 1;
    let lane0 = 2 + M;
    // The warp is valid from cycle 1 until it completes when lane 1's delay ends.
    let completion = last_pop + L_TRIANGLE + 1;
    assert_eq!(sim.done[0].0, completion);
    let st = &sim.stats;
    assert_eq!(st.warp_cycles, completion);
    assert_eq!(st.active_thread_cycles, lane0 + last_pop);
    let eff = st.simt_efficiency(4);
    assert!((eff - (lane0 + last_pop) as f64 / (4 * completion) as f64).abs() < 1e-12);
    assert!(eff < 0.5, "two of four lanes at most");
}

/// Tree for the treelet-order tests (treelets are 256 B: treelet = address >> 8).
/// R (0x000, treelet 0) has children c1 (0x100, treelet 1, leaf) then c2 (0x040, treelet 0);
/// c2 has child c3 (0x200, treelet 2, leaf).
fn treelet_tree() -> (Tree, [NodeEntry; 4]) {
    let r = node(0x000, NodeKind::Internal, 32);
    let c1 = node(0x100, NodeKind::TriangleLeaf, 32);
    let c2 = node(0x040, NodeKind::Internal, 32);
    let c3 = node(0x200, NodeKind::TriangleLeaf, 32);
    let mut tree = Tree::default();
    tree.add(r, false, &[(c1, ALL), (c2, ALL)])
        .add(c2, false, &[(c3, ALL)])
        .add(c1, false, &[])
        .add(c3, false, &[]);
    (tree, [r, c1, c2, c3])
}

fn addresses(sim: &Sim) -> Vec<u64> {
    sim.mem.log.iter().map(|(_, r)| r.address).collect()
}

#[test]
fn two_stack_order_puts_other_treelets_on_the_other_stack() {
    let (tree, [r, c1, c2, _]) = treelet_tree();
    let mut sim = Sim::new(small(), RtUnitParams::default(), Memory::new(tree, 4));
    sim.step(Some(warp(
        TraversalOrder::TreeletContinue,
        4,
        vec![ray(3, 0, r)],
    )));
    // R is requested in 1 and popped in 6.
    while sim.cycle < 7 {
        sim.step(None);
    }
    let rec = &sim.regs.slots[0].lanes[0].ray;
    assert_eq!(rec.current_treelet, 0);
    assert_eq!(*rec.current_stack, [c2]);
    assert_eq!(*rec.other_stack, [c1]);
    while sim.done.is_empty() {
        sim.step(None);
    }
    // c2 (same treelet) before c1 though c1 comes first in visit order; after c2 the current
    // stack is empty: boundary, the most recent other-stack entry c3 (treelet 2) is next; after
    // c3 another boundary to treelet 1.
    assert_eq!(addresses(&sim), vec![0x000, 0x040, 0x200, 0x100]);
    let events: Vec<(u32, u64)> = sim
        .events
        .iter()
        .map(|(_, e)| (e.ray_id, e.treelet))
        .collect();
    assert_eq!(events, vec![(3, 2), (3, 1)]);
    let (rec, outcome) = sim.done[0].1.lanes[0].clone().unwrap();
    assert_eq!(outcome, RayOutcome::Finished);
    assert_eq!(rec.current_treelet, 1);
}

#[test]
fn treelet_stop_parks_the_ray_and_it_resumes_in_a_new_warp() {
    let (tree, [r, c1, _, c3]) = treelet_tree();
    // Records carry one entry per stack: the parked ray spills the rest.
    let cfg = HwConfig {
        record_stack_entries: 1,
        ..small()
    };
    let mut sim = Sim::new(cfg, RtUnitParams::default(), Memory::new(tree, 4));
    sim.run(vec![warp(
        TraversalOrder::TreeletStop,
        4,
        vec![ray(3, 0, r)],
    )]);
    // Parked, the ray spills its other stack but the top (c1) before its warp completes.
    let spill = sim.mem.log[2].1;
    assert_eq!(spill.kind, RequestKind::StackSpill);
    assert_eq!(addresses(&sim), vec![0x000, 0x040, spill.address]);
    let (rec, outcome) = sim.done[0].1.lanes[0].clone().unwrap();
    assert_eq!(outcome, RayOutcome::AtBoundary { treelet: 2 });
    assert_eq!(sim.events.len(), 1);
    assert_eq!(sim.events[0].1.treelet, 2);
    assert!(rec.current_stack.is_empty());
    assert_eq!(*rec.other_stack, [c3]);
    assert_eq!(rec.other_spilled, 1);
    // Resume the ray in a treelet warp: it switches to treelet 2, tests c3 and stops again.
    let mut lanes = vec![None; 4];
    lanes[2] = Some(rec);
    sim.run(vec![WarpIssue {
        order: TraversalOrder::TreeletStop,
        lanes,
        ..WarpIssue::default()
    }]);
    // After c3 the other stack is empty on chip: c1's chunk is loaded back, then the boundary.
    assert_eq!(
        addresses(&sim),
        vec![0x000, 0x040, spill.address, 0x200, spill.address]
    );
    assert_eq!(sim.mem.log[4].1.kind, RequestKind::StackFill);
    let (rec, outcome) = sim.done[1].1.lanes[2].clone().unwrap();
    assert_eq!(outcome, RayOutcome::AtBoundary { treelet: 1 });
    assert_eq!(rec.current_treelet, 2);
    assert_eq!(*rec.other_stack, [c1]);
    assert_eq!(rec.other_spilled, 0);
    assert_eq!(sim.events.last().unwrap().1.lane, 2);
}

#[test]
fn ray_stationary_order_uses_one_stack_and_reports_no_boundaries() {
    let (tree, [r, ..]) = treelet_tree();
    let mut sim = Sim::new(small(), RtUnitParams::default(), Memory::new(tree, 4));
    sim.run(vec![warp(
        TraversalOrder::RayStationary,
        4,
        vec![ray(3, 0, r)],
    )]);
    assert_eq!(addresses(&sim), vec![0x000, 0x100, 0x040, 0x200]);
    assert!(sim.events.is_empty());
}

/// Four rays with distinct 64 B roots, each with a leaf child chosen per ray by mask.
fn burst_setup(use_eval: bool) -> Sim {
    let mut tree = Tree::default();
    let leaf = |i: u64| node(0x800 + 0x40 * i, NodeKind::TriangleLeaf, 32);
    let mut rays = Vec::new();
    for i in 0..4u64 {
        let root = node(0x100 * (i + 1), NodeKind::Internal, 64);
        // Ray i visits leaf i only (mask bit i), and leaf i is hit.
        let children: Vec<(NodeEntry, u8)> = (0..4).map(|j| (leaf(j), 1u8 << j)).collect();
        tree.add(root, false, &children);
        tree.add(leaf(i), true, &[]);
        rays.push(ray(i as u32, i as u32, root));
    }
    let mut mem = Memory::new(tree, 2);
    mem.hold_until = 20;
    let params = RtUnitParams {
        resp_fifo_depth: 4,
        resp_ports: 2,
        hit_record_base: 0x4000,
        ..RtUnitParams::default()
    };
    let mut sim = Sim::new(small(), params, mem);
    sim.use_eval = use_eval;
    sim.run(vec![warp(TraversalOrder::RayStationary, 4, rays)]);
    sim
}

#[test]
fn response_fifo_loses_nothing_when_it_fills() {
    let sim = burst_setup(false);
    // Eight chunks are held back until cycle 20, then arrive two per cycle (as many as
    // `resp_free` at the start of the cycle allows) while one is popped per cycle: after a cycle
    // the FIFO holds at most depth - 1 = 3 entries (the popped one made room during the cycle).
    assert_eq!(sim.max_fifo, 3);
    let lanes = &sim.done[0].1.lanes;
    for (i, lane) in lanes.iter().enumerate() {
        let (rec, outcome) = lane.as_ref().unwrap();
        assert_eq!(*outcome, RayOutcome::Finished);
        assert_eq!(rec.hit.unwrap().hit_id, 0x800 + 0x40 * i as u32);
    }
    assert_eq!(sim.stats.tests[NodeKind::Internal.code() as usize], 4);
    assert_eq!(sim.stats.triangle_hits, 4);
    assert_eq!(sim.stats.stores, 4);
}

#[test]
fn step_in_place_matches_eval() {
    let a = burst_setup(false);
    let b = burst_setup(true);
    assert_eq!(a.outputs, b.outputs);
    assert_eq!(a.regs, b.regs);
}

#[test]
fn protocol_violations_raise_sticky_errors() {
    let unit = RtUnit::new(small(), RtUnitParams::default(), ToyDatapath).unwrap();
    let mut regs = unit.reset();
    let r = node(0x100, NodeKind::Internal, 32);
    let mut inp = unit.idle_inputs();
    // A response nobody waits for.
    inp.responses = vec![MemResponse {
        address: 0x100,
        tag: 0,
        data: [0; 32],
    }];
    unit.step(&mut regs, &inp);
    let out = unit.step(&mut regs, &unit.idle_inputs());
    assert_eq!(out.errors, errors::UNMATCHED_RESPONSE);
    // Fill both slots, then issue a third warp.
    let mut inp = unit.idle_inputs();
    inp.issue = Some(warp(TraversalOrder::RayStationary, 4, vec![ray(0, 0, r)]));
    unit.step(&mut regs, &inp);
    unit.step(&mut regs, &inp);
    assert!(
        !unit
            .status(&regs, &unit.cache(&regs), StatusSelect::Scalars)
            .issue_ready
    );
    let out = unit.step(&mut regs, &inp);
    assert!(!out.issue_ready);
    let out = unit.step(&mut regs, &unit.idle_inputs());
    assert_ne!(out.errors & errors::ISSUE_WHILE_FULL, 0);
    // More responses than ports.
    let mut inp = unit.idle_inputs();
    inp.responses = vec![
        MemResponse {
            address: 0,
            tag: 0,
            data: [0; 32]
        };
        3
    ];
    unit.step(&mut regs, &inp);
    assert_ne!(regs.errors & errors::FIFO_OVERFLOW, 0);
    // A malformed warp is dropped.
    let mut regs = unit.reset();
    let mut inp = unit.idle_inputs();
    inp.issue = Some(WarpIssue {
        order: TraversalOrder::RayStationary,
        lanes: vec![ray(0, 0, r)],
        ..WarpIssue::default()
    });
    unit.step(&mut regs, &inp);
    assert_eq!(regs.errors, errors::BAD_ISSUE);
    assert!(regs.slots.iter().all(|s| !s.valid));
}

/// A lane write of `lanes` into `slot` (padded to 4 lanes).
fn lane_write(slot: u32, lanes: Vec<Option<RayRecord>>) -> LaneWrite {
    let mut lanes = lanes;
    lanes.resize(4, None);
    LaneWrite { slot, lanes }
}

#[test]
fn written_lanes_wait_inactive_and_enter_with_their_warps_issue() {
    let unit = RtUnit::new(small(), RtUnitParams::default(), ToyDatapath).unwrap();
    let r = node(0x100, NodeKind::Internal, 32);
    let mut regs = unit.reset();
    // Rays 1 and 2 written into lanes 0 and 2 of the free slot 1, over two cycles.
    let mut inp = unit.idle_inputs();
    inp.write = Some(lane_write(1, vec![ray(1, 0, r)]));
    unit.step(&mut regs, &inp);
    inp.write = Some(lane_write(1, vec![None, None, ray(2, 0, r)]));
    let out = unit.step(&mut regs, &inp);
    assert_eq!(out.errors, 0);
    assert!(!regs.slots[1].valid, "a written slot holds no warp yet");
    let lanes = &regs.slots[1].lanes;
    assert!(lanes[0].written && lanes[2].written && !lanes[1].written);
    assert!(lanes.iter().all(|l| l.status == LaneStatus::Inactive));
    assert_eq!(
        unit.status(&regs, &unit.cache(&regs), StatusSelect::Slots)
            .slots[1],
        None
    );
    // The issue: lanes 0 and 2 from their written records, lane 3 from the bus, while the bus
    // also writes lane 1 of slot 0 (another slot, another lane).
    let mut issue = warp(
        TraversalOrder::TreeletStop,
        4,
        vec![None, None, None, ray(3, 0, r)],
    );
    issue.target = IssueTarget::Slot(1);
    issue.written = 0b0101;
    inp.issue = Some(issue);
    inp.write = Some(lane_write(0, vec![None, ray(4, 0, r)]));
    let out = unit.step(&mut regs, &inp);
    assert_eq!(out.errors, 0, "{:?}", out.first_error);
    let ids = |s: usize, l: usize| {
        (
            regs.slots[s].lanes[l].status,
            regs.slots[s].lanes[l].ray.ray_id,
        )
    };
    assert!(regs.slots[1].valid);
    assert_eq!(ids(1, 0), (LaneStatus::Traversing, 1));
    assert_eq!(ids(1, 1).0, LaneStatus::Inactive);
    assert_eq!(ids(1, 2), (LaneStatus::Traversing, 2));
    assert_eq!(ids(1, 3), (LaneStatus::Traversing, 3));
    assert!(regs.slots[1].lanes.iter().all(|l| !l.written));
    assert!(regs.slots[0].lanes[1].written && !regs.slots[0].valid);

    // Refused, each a bad command naming the slot, nothing written: a write into the slot
    // holding a warp that is not held; a write on a bus lane the issue uses; an issue naming a
    // lane never written.
    let written = |regs: &RtUnitRegs| -> Vec<bool> {
        (regs.slots.iter())
            .flat_map(|s| s.lanes.iter().map(|l| l.written))
            .collect()
    };
    let refused = |inp: &RtUnitInputs, slot: u32| {
        let mut after = regs.clone();
        let out = unit.step(&mut after, inp);
        assert_eq!(out.errors, errors::BAD_COMMAND);
        assert_eq!(out.first_error.map(|e| e.slot), Some(slot));
        written(&regs) == written(&after) && regs.slots[0].valid == after.slots[0].valid
    };
    let mut inp = unit.idle_inputs();
    inp.write = Some(lane_write(1, vec![None, ray(5, 0, r)]));
    assert!(refused(&inp, 1));
    let mut inp = unit.idle_inputs();
    let mut issue = warp(TraversalOrder::TreeletStop, 4, vec![ray(6, 0, r)]);
    issue.target = IssueTarget::Slot(0);
    issue.written = 0b0010;
    inp.issue = Some(issue);
    inp.write = Some(lane_write(0, vec![ray(7, 0, r)]));
    let mut regs2 = regs.clone();
    let out = unit.step(&mut regs2, &inp);
    assert_eq!(out.errors, errors::BAD_COMMAND, "the write is refused");
    assert!(regs2.slots[0].valid, "the issue goes ahead");
    let mut inp = unit.idle_inputs();
    let mut issue = warp(TraversalOrder::TreeletStop, 4, vec![]);
    issue.target = IssueTarget::Slot(0);
    issue.written = 0b0001;
    inp.issue = Some(issue);
    assert!(refused(&inp, 0));
}

#[test]
fn bad_parameters_and_issues_are_rejected_with_reasons() {
    let bad = |p: RtUnitParams| RtUnit::new(small(), p, ToyDatapath).unwrap_err();
    let e = bad(RtUnitParams {
        resp_fifo_depth: 0,
        ..RtUnitParams::default()
    });
    assert!(matches!(
        e,
        RtUnitError::BadParam {
            name: "resp_fifo_depth",
            ..
        }
    ));
    let mut p = RtUnitParams::default();
    p.latencies.header = 0;
    assert!(bad(p).to_string().contains("header latency"));
    let e = bad(RtUnitParams {
        hit_record_base: 0xFFE0,
        ..RtUnitParams::default()
    });
    assert!(matches!(
        e,
        RtUnitError::BadParam {
            name: "hit_record_base",
            ..
        }
    ));
    let cfg = HwConfig {
        warp_buffer_size: 0,
        ..small()
    };
    assert!(matches!(
        RtUnit::new(cfg, RtUnitParams::default(), ToyDatapath),
        Err(RtUnitError::Config(_))
    ));
    assert!(NodeEntry::new(0x10, NodeKind::Internal, 64).is_err());
    assert!(NodeEntry::new(0x40, NodeKind::Internal, 48).is_err());
    assert!(NodeEntry::new(0x40, NodeKind::InstanceLeaf, 160).is_err());

    let unit = RtUnit::new(small(), RtUnitParams::default(), ToyDatapath).unwrap();
    let r = node(0x100, NodeKind::Internal, 32);
    let e = unit
        .check_issue(&warp(TraversalOrder::RayStationary, 4, vec![ray(16, 0, r)]))
        .unwrap_err();
    assert!(e.to_string().contains("max_rays"), "{e}");
    let mut deep = RayRecord::new(1, words(0), r);
    deep.other_stack = BoundedVec::with(17, vec![r; 17]).unwrap();
    let e = unit
        .check_issue(&warp(
            TraversalOrder::RayStationary,
            4,
            vec![None, Some(deep)],
        ))
        .unwrap_err();
    assert!(matches!(e, RtUnitError::BadIssue { lane: 1, .. }), "{e}");
    let outside = NodeEntry {
        address: 0xFFE0,
        kind: NodeKind::Internal,
        chunks: 2,
    };
    assert!(unit.check_node(&outside).is_err());
    assert_eq!(CHUNK_BYTES, 32);
}

/// A complete `fanout`-ary tree of 64 B internal nodes `depth` levels deep over 32 B triangle
/// leaves (a hit at every leaf, t = 0.5, so the smallest leaf address wins), laid out breadth
/// first from 0x100, 64 B apart (so 256 B treelets hold four nodes). Returns the tree and its
/// root.
fn deep_tree(fanout: usize, depth: u32) -> (Tree, NodeEntry) {
    let mut tree = Tree::default();
    let mut level = vec![0x100u64];
    let mut next = 0x100 + 64;
    let mut levels = vec![];
    for _ in 0..depth {
        let mut below = Vec::new();
        for _ in 0..level.len() * fanout {
            below.push(next);
            next += 64;
        }
        levels.push(level);
        level = below;
    }
    let leaf_addrs = level;
    for &a in &leaf_addrs {
        tree.add(node(a, NodeKind::TriangleLeaf, 32), true, &[]);
    }
    let mut children = leaf_addrs;
    for (d, addrs) in levels.iter().enumerate().rev() {
        let child = |c: u64| {
            if d + 1 == levels.len() {
                node(c, NodeKind::TriangleLeaf, 32)
            } else {
                node(c, NodeKind::Internal, 64)
            }
        };
        for (i, &a) in addrs.iter().enumerate() {
            let kids: Vec<(NodeEntry, u8)> = children[i * fanout..(i + 1) * fanout]
                .iter()
                .map(|&c| (child(c), ALL))
                .collect();
            tree.add(node(a, NodeKind::Internal, 64), false, &kids);
        }
        children = addrs.clone();
    }
    (tree, node(0x100, NodeKind::Internal, 64))
}

/// The unit of the deep-tree tests: 64 rays, 20-bit addresses, `stack_depth` on-chip stack
/// entries, hit records at 0x8_0000, four children a node and `spill_chunks` spill chunks a
/// stack.
fn deep_config(stack_depth: u32, spill_chunks: u32) -> (HwConfig, RtUnitParams) {
    let cfg = HwConfig {
        max_rays: 64,
        address_bits: 20,
        stack_depth,
        ..small()
    };
    let params = RtUnitParams {
        hit_record_base: 0x8_0000,
        max_children: 4,
        stack_spill_chunks: spill_chunks,
        ..RtUnitParams::default()
    };
    (cfg, params)
}

/// Runs one warp of `rays` rays (ids 0.., lanes 0..) through a deep tree in `order` on a unit
/// with `stack_depth` on-chip entries; under the treelet-stop order parked rays are issued
/// again (as a treelet controller would) until every ray finished. Returns each ray's final
/// record, the unit's statistics registers and every request.
fn run_deep(
    order: TraversalOrder,
    stack_depth: u32,
    spill_chunks: u32,
) -> (Vec<RayRecord>, vtq_hdl::rt_unit::RtStats, Vec<MemRequest>) {
    let (tree, root) = deep_tree(4, 4);
    let (cfg, params) = deep_config(stack_depth, spill_chunks);
    let mut sim = Sim::new(cfg, params, Memory::new(tree, 7));
    let mut finished = BTreeMap::new();
    let mut pending: Vec<RayRecord> = (0..4).map(|i| RayRecord::new(i, words(0), root)).collect();
    while !pending.is_empty() {
        let lanes = pending.drain(..).map(Some).collect();
        let before = sim.done.len();
        sim.run(vec![warp(order, 4, lanes)]);
        for (_, done) in &sim.done[before..] {
            for (rec, outcome) in done.lanes.iter().flatten() {
                match outcome {
                    RayOutcome::Finished => {
                        finished.insert(rec.ray_id, rec.clone());
                    }
                    RayOutcome::AtBoundary { .. } => pending.push(rec.clone()),
                }
            }
        }
        assert_eq!(sim.regs.errors, 0, "{:?}", sim.regs.first_error);
    }
    let reqs = sim.mem.log.iter().map(|(_, r)| *r).collect();
    (finished.into_values().collect(), sim.stats, reqs)
}

/// Per ray id, the node addresses it fetched, in order (first chunks only).
fn fetch_order(reqs: &[MemRequest]) -> Vec<u64> {
    reqs.iter()
        .filter(|r| r.kind == RequestKind::NodeLoad)
        .map(|r| r.address)
        .collect()
}

#[test]
fn a_short_stack_spills_and_fills_without_changing_the_traversal() {
    for order in TraversalOrder::ALL {
        // At most 1 + 3 x 4 = 13 entries: a 64-entry stack never spills.
        let (deep_recs, deep_stats, deep_reqs) = run_deep(order, 64, 16);
        // (Parked rays spill whatever the depth.)
        if order != TraversalOrder::TreeletStop {
            assert_eq!(deep_stats.stack_spills, 0, "{order:?}");
        }
        let (recs, stats, reqs) = run_deep(order, 6, 16);
        assert!(
            stats.stack_spills > 0,
            "{order:?}: the 6-entry stack must spill"
        );
        assert_eq!(
            stats.stack_fills, stats.stack_spills,
            "{order:?}: every chunk returns"
        );
        assert_eq!(recs.len(), 4);
        assert_eq!(recs, deep_recs, "{order:?}: same hits and final state");
        assert_eq!(stats.tests, deep_stats.tests, "{order:?}: same tests");
        // Lanes desynchronize, so fetches merge differently; the nodes fetched are the same.
        let mut a = fetch_order(&reqs);
        let mut b = fetch_order(&deep_reqs);
        for v in [&mut a, &mut b] {
            v.sort_unstable();
            v.dedup();
        }
        assert_eq!(a, b, "{order:?}: same nodes fetched");
        // Spills and fills stay inside the spill area, one 32 B chunk each.
        let (cfg, params) = deep_config(6, 16);
        let (lo, hi) = spill_area(&cfg, &params);
        for r in reqs.iter().filter(|r| r.kind != RequestKind::NodeLoad) {
            if r.kind == RequestKind::HitStore {
                continue;
            }
            assert!(
                (lo..hi).contains(&r.address) && r.address % 32 == 0,
                "{r:?}"
            );
        }
        for r in reqs.iter().filter(|r| r.kind == RequestKind::StackSpill) {
            let entries = unpack_spill_chunk(&r.data);
            assert!((1..=4).contains(&entries.len()), "{entries:?}");
        }
    }
}

#[test]
fn spill_addresses_follow_the_ray_and_stack() {
    let (_, _, reqs) = run_deep(TraversalOrder::RayStationary, 6, 16);
    let (cfg, params) = deep_config(6, 16);
    let (base, _) = spill_area(&cfg, &params);
    // The first spill is ray (lane) 0's current stack, chunk 0; its fill reads it back.
    let first = reqs
        .iter()
        .find(|r| r.kind == RequestKind::StackSpill)
        .unwrap();
    let lane = first.tag & 3;
    assert_eq!(first.address, base + (lane as u64 * 2) * 16 * 32);
    assert!(reqs
        .iter()
        .any(|r| r.kind == RequestKind::StackFill && r.address == first.address));
}

#[test]
fn a_full_spill_area_is_an_error_naming_the_ray_and_the_limit() {
    let (tree, root) = deep_tree(4, 5);
    let (cfg, params) = deep_config(4, 1);
    let mut sim = Sim::new(cfg, params, Memory::new(tree, 3));
    sim.step(Some(warp(
        TraversalOrder::RayStationary,
        4,
        vec![None, ray(9, 0, root)],
    )));
    while sim.regs.errors == 0 {
        assert!(sim.cycle < 5_000, "no error raised");
        sim.step(None);
    }
    assert_eq!(sim.regs.errors, errors::SPILL_AREA_FULL);
    let e = sim.regs.first_error.expect("captured");
    assert_eq!(e.kind, ErrorKind::SpillAreaFull);
    assert_eq!((e.lane, e.ray_id, e.value, e.limit), (1, 9, 2, 1));
    assert_eq!(sim.outputs.last().unwrap().first_error, Some(e));
}

#[test]
fn max_children_must_fit_the_stack() {
    let cfg = HwConfig {
        stack_depth: 4,
        ..small()
    };
    let e = RtUnit::new(cfg, RtUnitParams::default(), ToyDatapath).unwrap_err();
    assert!(
        matches!(
            e,
            RtUnitError::BadParam {
                name: "max_children",
                ..
            }
        ),
        "{e}"
    );
}

/// The port or register a trace signal belongs to: numeric `_<n>` suffixes removed.
fn base_name(name: &str) -> &str {
    let mut s = name;
    while let Some((head, tail)) = s.rsplit_once('_') {
        if !tail.is_empty() && tail.chars().all(|c| c.is_ascii_digit()) {
            s = head;
        } else {
            break;
        }
    }
    s
}

#[test]
fn signals_are_stable_fit_their_widths_and_name_described_items() {
    let sim = burst_setup(false);
    let desc = sim.unit.describe();
    let idle = &sim.outputs[sim.outputs.len() - 1];
    let busy = sim.outputs.iter().find(|o| o.request.is_some()).unwrap();
    let shape = |sigs: Vec<vtq_hdl::Signal>| -> Vec<(String, u32)> {
        sigs.into_iter().map(|s| (s.name, s.width)).collect()
    };
    assert_eq!(shape(idle.signals()), shape(busy.signals()));
    let mut inputs = sim.unit.idle_inputs();
    let empty = shape(inputs.signals());
    inputs.issue = Some(warp(
        TraversalOrder::TreeletStop,
        4,
        vec![None, ray(1, 0, node(0, NodeKind::Internal, 32))],
    ));
    assert_eq!(empty, shape(inputs.signals()));
    let all = [
        inputs.signals(),
        busy.signals(),
        sim.unit.reg_signals(&sim.regs),
    ]
    .concat();
    for s in all {
        assert!(fits(s.value, s.width), "{} overflows", s.name);
        let base = base_name(&s.name);
        let known = desc.port(base).is_some() || desc.registers.iter().any(|r| r.name == base);
        assert!(known, "{} ({base}) is not described", s.name);
    }
}

#[test]
fn describe_widths_follow_the_config() {
    let cfg = HwConfig::default();
    let unit = RtUnit::new(cfg.clone(), RtUnitParams::default(), ToyDatapath).unwrap();
    let d = unit.describe();
    assert_eq!(d.port("req_address").unwrap().width, 32);
    assert_eq!(d.port("req_tag").unwrap().width, 1 + 5);
    assert_eq!(d.port("issue_ray_id").unwrap().width, 32 * 12);
    assert_eq!(d.port("resp1_data").unwrap().width, 256);
    assert!(d.port("resp2_data").is_none());
    let stack = d.memories.iter().find(|m| m.name == "cur_stack").unwrap();
    // Above each lane's 4-entry window, a ring of 8 SRAM banks of 4 words (28 entries).
    assert_eq!((stack.banks, stack.depth), (32 * 8, 4));
    assert_eq!(
        (stack.read_ports, stack.write_ports, stack.read_latency),
        (1, 1, 1)
    );
    assert_eq!(stack.width, 32 + 3 + 2);
    let window = d
        .registers
        .iter()
        .find(|r| r.name == "lane_cur_window")
        .unwrap();
    assert_eq!(window.width, 4 * (32 + 3 + 2));
    let small_unit = RtUnit::new(small(), RtUnitParams::default(), ToyDatapath).unwrap();
    let s = small_unit.describe();
    assert_eq!(s.port("req_tag").unwrap().width, 1 + 2);
    assert!(s.storage_bits() < d.storage_bits());
}

#[test]
fn describe_snapshot_default() {
    let unit = RtUnit::new(HwConfig::default(), RtUnitParams::default(), ToyDatapath).unwrap();
    insta::assert_yaml_snapshot!("rt_unit_default", unit.describe());
}

#[test]
fn describe_snapshot_small() {
    let unit = RtUnit::new(small(), RtUnitParams::default(), ToyDatapath).unwrap();
    insta::assert_yaml_snapshot!("rt_unit_small", unit.describe());
}

/// A ray that hits two leaves with the same t: the first visited (larger id) is kept until the
/// second (smaller id) replaces it; a later tie with a larger id does not.
#[test]
fn ties_in_t_go_to_the_smaller_hit_id() {
    let mut tree = Tree::default();
    let root = node(0x100, NodeKind::Internal, 64);
    let leaves = [0x300u64, 0x200, 0x280].map(|a| node(a, NodeKind::TriangleLeaf, 32));
    tree.add(root, false, &leaves.map(|l| (l, ALL)));
    for l in leaves {
        tree.add(l, true, &[]);
    }
    let params = RtUnitParams {
        hit_record_base: 0x8000,
        ..RtUnitParams::default()
    };
    let mut sim = Sim::new(small(), params, Memory::new(tree, 3));
    sim.run(vec![warp(
        TraversalOrder::RayStationary,
        4,
        vec![ray(0, 0, root), None, None, None],
    )]);
    let (rec, _) = sim.done[0].1.lanes[0].as_ref().unwrap();
    assert_eq!(rec.hit.unwrap().hit_id, 0x200);
    // Hits 0x300 then 0x200 were stored; 0x280 ties with a larger id and is dropped.
    assert_eq!(sim.stats.triangle_hits, 2);
    assert_eq!(sim.stats.stores, 2);
}

/// `skip(n)` equals `n` idle steps whenever `n <= idle_cycles`, and idle steps really are idle:
/// checked at every cycle of runs with several warps, stores, merges and memory latencies.
#[test]
fn skip_equals_idle_steps() {
    for latency in [1u64, 7, 40] {
        let mut tree = Tree::default();
        let root = node(0x100, NodeKind::Internal, 64);
        let inner = node(0x200, NodeKind::Internal, 64);
        let leaf = |a: u64| node(a, NodeKind::TriangleLeaf, 32);
        let mut children: Vec<(NodeEntry, u8)> = (0..4u64)
            .map(|j| (leaf(0x800 + 0x40 * j), 1u8 << j))
            .collect();
        children.push((inner, 0b0101));
        tree.add(root, false, &children);
        tree.add(inner, false, &[(leaf(0x900), ALL)]);
        for a in [0x800, 0x840, 0x880, 0x8c0, 0x900] {
            tree.add(leaf(a), true, &[]);
        }
        let mut sim = Sim::new(
            small(),
            RtUnitParams {
                hit_record_base: 0x8000,
                ..RtUnitParams::default()
            },
            Memory::new(tree, latency),
        );
        let warps: Vec<WarpIssue> = (0..3u32)
            .map(|w| {
                let lanes = (0..4u32)
                    .map(|l| ray(4 * w + l, l, root))
                    .collect::<Vec<_>>();
                warp(TraversalOrder::TreeletContinue, 4, lanes)
            })
            .collect();
        let mut checked_nonzero = 0;
        let mut pending: Vec<WarpIssue> = warps.into_iter().rev().collect();
        while !pending.is_empty() || sim.regs.slots.iter().any(|s| s.valid) {
            let idle = sim.unit.idle_cycles(&sim.regs, &sim.cache);
            let n = idle.min(25);
            let mut stepped = sim.regs.clone();
            let mut stepped_counts = RtStats::default();
            for _ in 0..n {
                let out = sim.unit.step(&mut stepped, &sim.unit.idle_inputs());
                assert!(out.request.is_none() && out.done.is_none() && out.boundary.is_empty());
                assert_eq!(stepped.fifo.len(), sim.regs.fifo.len());
                stepped_counts.add(&out.counts);
            }
            let mut skipped = sim.regs.clone();
            let mut skipped_cache = sim.cache.clone();
            let counts = sim.unit.skip(&mut skipped, &mut skipped_cache, n);
            assert_eq!(skipped, stepped, "cycle {} skip {n}", sim.cycle);
            assert_eq!(counts, stepped_counts, "cycle {} skip {n}", sim.cycle);
            assert!(skipped_cache.consistent(&skipped));
            checked_nonzero += usize::from(n > 0);
            let issue = if sim
                .unit
                .status(&sim.regs, &sim.cache, StatusSelect::Scalars)
                .issue_ready
            {
                pending.pop()
            } else {
                None
            };
            sim.step(issue);
            assert!(sim.cycle < 10_000, "warps did not complete");
        }
        assert_eq!(sim.regs.errors, 0);
        assert!(checked_nonzero > 0, "no idle period was exercised");
    }
}

/// A two-treelet path for the treelet controller's commands: A (0x000) and B (0x040) in
/// treelet 0, the hit leaf C (0x100) in treelet 1 (256 B treelets).
fn two_treelet_tree() -> (Tree, NodeEntry, NodeEntry) {
    let (a, b, c) = (
        node(0x000, NodeKind::Internal, 64),
        node(0x040, NodeKind::Internal, 64),
        node(0x100, NodeKind::TriangleLeaf, 32),
    );
    let mut tree = Tree::default();
    tree.add(a, false, &[(b, ALL)])
        .add(b, false, &[(c, ALL)])
        .add(c, true, &[]);
    (tree, a, c)
}

#[test]
fn stop_makes_a_continuing_warp_park_at_its_next_treelet_boundary() {
    for stop in [false, true] {
        let (tree, a, c) = two_treelet_tree();
        let mut sim = Sim::new(small(), RtUnitParams::default(), Memory::new(tree, 5));
        let w = warp(TraversalOrder::TreeletContinue, 4, vec![ray(3, 0, a)]);
        sim.step(Some(w));
        sim.step(None); // the first fetch: the ray is inside treelet 0 now
        if stop {
            sim.step_with(|i| i.stop = Some(0));
            assert_eq!(sim.regs.slots[0].order, TraversalOrder::TreeletStop);
        }
        while sim.done.is_empty() {
            assert!(sim.cycle < 1000);
            sim.step(None);
        }
        assert_eq!(sim.regs.errors, 0);
        let (rec, outcome) = sim.done[0].1.lanes[0].clone().unwrap();
        if stop {
            assert_eq!(outcome, RayOutcome::AtBoundary { treelet: 1 });
            assert_eq!(*rec.other_stack, [c], "C waits on the other-treelet stack");
            assert!(rec.hit.is_none());
        } else {
            assert_eq!(outcome, RayOutcome::Finished);
            assert_eq!(rec.hit.unwrap().hit_id, 0x100);
        }
    }
}

#[test]
fn issue_into_a_reserved_slot_and_bad_commands_raise_an_error() {
    let (tree, a, _) = two_treelet_tree();
    let mut sim = Sim::new(small(), RtUnitParams::default(), Memory::new(tree, 5));
    let mut w = warp(TraversalOrder::RayStationary, 4, vec![ray(1, 0, a)]);
    w.target = IssueTarget::Slot(1);
    sim.step(Some(w.clone()));
    assert!(sim.regs.slots[1].valid && !sim.regs.slots[0].valid);
    assert_eq!(sim.regs.errors, 0);
    // Slot 1 is taken: a second issue there is refused and flagged.
    sim.step(Some(w));
    assert_ne!(sim.regs.errors & errors::BAD_COMMAND, 0);
    for bad in [
        |i: &mut vtq_hdl::rt_unit::RtUnitInputs| i.stop = Some(0),
        |i: &mut vtq_hdl::rt_unit::RtUnitInputs| {
            let mut w = warp(
                TraversalOrder::RayStationary,
                4,
                vec![None, ray(2, 0, node(0, NodeKind::Internal, 64))],
            );
            w.target = IssueTarget::Append {
                slot: 1,
                last: true,
            };
            i.issue = Some(w);
        },
    ] {
        let (tree, a, _) = two_treelet_tree();
        let mut sim = Sim::new(small(), RtUnitParams::default(), Memory::new(tree, 5));
        let mut w = warp(TraversalOrder::RayStationary, 4, vec![ray(1, 0, a)]);
        w.target = IssueTarget::Slot(1);
        sim.step(Some(w));
        sim.step_with(bad); // stop of an empty slot; append to a slot that is not held
        assert_ne!(sim.regs.errors & errors::BAD_COMMAND, 0);
    }
}

#[test]
fn repack_releases_finished_lanes_holds_the_warp_and_an_append_refills_it() {
    // Lane 0 hits leaf L at once; lane 1 walks A -> B -> C (select bit 1 only reaches A's child).
    let (mut tree, a, _) = two_treelet_tree();
    let leaf = node(0x080, NodeKind::TriangleLeaf, 32);
    tree.add(leaf, true, &[]);
    let mut sim = Sim::new(small(), RtUnitParams::default(), Memory::new(tree, 5));
    sim.step(Some(warp(
        TraversalOrder::RayStationary,
        4,
        vec![ray(0, 0, leaf), ray(1, 0, a)],
    )));
    // Run until lane 0 is done and quiescent (its hit record stored).
    while !sim.regs.slots[0].lanes[0].quiescent(sim.keep()) {
        sim.step(None);
    }
    sim.step_with(|i| i.repack = Some(0));
    let released = sim.outputs.last().unwrap().released.clone().unwrap();
    assert_eq!(released.slot, 0);
    let (rec, outcome) = released.lanes[0].clone().unwrap();
    assert_eq!((rec.ray_id, outcome), (0, RayOutcome::Finished));
    assert_eq!(rec.hit.unwrap().hit_id, 0x080);
    assert!(
        released.lanes[1..].iter().all(Option::is_none),
        "lane 1 still traverses"
    );
    assert!(sim.regs.slots[0].held);
    assert_eq!(sim.regs.slots[0].lanes[0].status, LaneStatus::Inactive);
    // Lane 1 finishes, but the held warp does not complete.
    while sim.regs.slots[0].lanes[1].status == LaneStatus::Traversing
        || !sim.regs.slots[0].lanes[1].quiescent(sim.keep())
    {
        assert!(sim.cycle < 1000);
        sim.step(None);
    }
    for _ in 0..20 {
        sim.step(None);
    }
    assert!(sim.done.is_empty(), "a held warp does not complete");
    // The fill appends a new ray into lane 0 and releases the hold.
    let mut w = warp(TraversalOrder::RayStationary, 4, vec![ray(5, 0, leaf)]);
    w.target = IssueTarget::Append {
        slot: 0,
        last: true,
    };
    sim.step(Some(w));
    assert!(!sim.regs.slots[0].held);
    while sim.done.is_empty() {
        assert!(sim.cycle < 2000);
        sim.step(None);
    }
    assert_eq!(sim.regs.errors, 0);
    let done = &sim.done[0].1;
    let ids: Vec<u32> = done.lanes.iter().flatten().map(|(r, _)| r.ray_id).collect();
    assert_eq!(
        ids,
        vec![5, 1],
        "the appended ray and the long one complete together"
    );
    assert!(done
        .lanes
        .iter()
        .flatten()
        .all(|(_, o)| *o == RayOutcome::Finished));
}

/// `idle_cycles` as a scan of every lane (the definition the unit's lane summaries replace).
fn idle_cycles_by_scan(regs: &RtUnitRegs, keep: usize) -> u64 {
    if !regs.fifo.is_empty() || regs.split.is_some() {
        return 0;
    }
    let mut idle = u64::MAX;
    for &s in &regs.age {
        let slot = &regs.slots[s as usize];
        if !slot.held && slot.lanes.iter().all(|l| l.quiescent(keep)) {
            return 0;
        }
        for lane in &slot.lanes {
            if lane.store_pending || lane.ready(keep) {
                return 0;
            }
            if lane.delay > 0 {
                idle = idle.min(lane.delay as u64);
            }
        }
    }
    idle
}

/// `slot_summary` as a scan of every lane (the definition the unit's lane summaries replace).
fn slot_summary_by_scan(
    unit: &RtUnit<ToyDatapath>,
    regs: &RtUnitRegs,
    slot: u32,
    distinct: bool,
) -> Option<SlotSummary> {
    let s = regs.slots.get(slot as usize).filter(|s| s.valid)?;
    let keep = unit.config().record_stack_entries as usize;
    let mut treelets = Vec::new();
    let mut sum = SlotSummary {
        quiescent: s.lanes.iter().all(|l| l.quiescent(keep)),
        ..SlotSummary::default()
    };
    for lane in &s.lanes {
        let busy = match lane.status {
            LaneStatus::Inactive => false,
            LaneStatus::Done => !lane.quiescent(keep),
            LaneStatus::Traversing | LaneStatus::Parked => true,
        };
        sum.busy += u32::from(busy);
        if lane.status == LaneStatus::Traversing {
            sum.traversing += 1;
            if let Some(n) = lane.ray.next_node().filter(|_| distinct) {
                let t = unit.treelet_of(n.address);
                if !treelets.contains(&t) {
                    treelets.push(t);
                }
            }
        }
    }
    sum.distinct_next_treelets = treelets.len() as u32;
    Some(sum)
}

/// A random DAG of toy nodes, one per 128 B (two per 256 B treelet): node `i`'s children are
/// later nodes, so every path ends. Returns the tree and the nodes (node 0 is the root).
fn random_tree(rng: &mut SplitMix64, count: usize) -> (Tree, Vec<NodeEntry>) {
    // The root is a 128 B node with three children, so every ray does some work.
    let sizes: Vec<u32> = (0..count)
        .map(|i| {
            if i == 0 {
                128
            } else {
                32 * (1 + rng.below_exact(4) as u32)
            }
        })
        .collect();
    let mut nodes = Vec::new();
    let mut children = Vec::new();
    for (i, &bytes) in sizes.iter().enumerate() {
        let max = (((bytes - 5) / 8) as usize).min(3).min(count - 1 - i);
        let n = if i == 0 {
            max
        } else {
            rng.below_exact(max as u64 + 1) as usize
        };
        let picked: Vec<usize> = (0..n)
            .map(|_| i + 1 + rng.below_exact((count - 1 - i) as u64) as usize)
            .collect();
        let kind = if picked.is_empty() {
            NodeKind::TriangleLeaf
        } else {
            NodeKind::Internal
        };
        nodes.push(node(0x80 * i as u64, kind, bytes));
        children.push(picked);
    }
    let mut tree = Tree::default();
    for (i, picked) in children.iter().enumerate() {
        let kids: Vec<(NodeEntry, u8)> = picked
            .iter()
            .map(|&j| {
                // Every ray visits the root's children; bit 0 keeps some ray on every edge.
                let mask = if i == 0 {
                    ALL
                } else {
                    rng.next_u64() as u8 | 1
                };
                (nodes[j], mask)
            })
            .collect();
        tree.add(nodes[i], rng.below_exact(3) == 0, &kids);
    }
    (tree, nodes)
}

/// Checks every lane summary, slot summary and status port of `sim`'s registers against a scan
/// of the lanes; returns whether the unit is idle for a while (a finite idle horizon) and the
/// valid slots.
fn check_lane_summaries(sim: &Sim, cfg: &HwConfig, seed: u64) -> (bool, Vec<u32>) {
    let regs = &sim.regs;
    let idle_cycles = sim.unit.idle_cycles(regs, &sim.cache);
    assert_eq!(
        idle_cycles,
        idle_cycles_by_scan(regs, sim.keep()),
        "seed {seed} cycle {}",
        sim.cycle
    );
    for s in 0..cfg.warp_buffer_size + 1 {
        for distinct in [false, true] {
            assert_eq!(
                sim.unit.slot_summary(regs, &sim.cache, s, distinct),
                slot_summary_by_scan(&sim.unit, regs, s, distinct),
                "seed {seed} cycle {} slot {s}",
                sim.cycle
            );
        }
    }
    // The status ports: each slot's state and summary by their definition (distinct
    // next treelets for treelet-continue warps only), inactive lanes by scan.
    let count_distinct = sim.cycle.is_multiple_of(2);
    let status = sim
        .unit
        .status(regs, &sim.cache, StatusSelect::slots(count_distinct));
    assert_eq!(status.slots.len(), cfg.warp_buffer_size as usize);
    for (k, st) in status.slots.iter().enumerate() {
        let slot = &regs.slots[k];
        let want = slot.valid.then(|| {
            let distinct = count_distinct && slot.order == TraversalOrder::TreeletContinue;
            let inactive = slot
                .lanes
                .iter()
                .enumerate()
                .filter(|(_, l)| l.status == LaneStatus::Inactive)
                .fold(0u64, |m, (i, _)| m | 1 << i);
            (
                slot.order,
                slot.held,
                slot_summary_by_scan(&sim.unit, regs, k as u32, distinct),
                inactive,
            )
        });
        let got = st.map(|st| (st.order, st.held, Some(st.summary), st.inactive));
        assert_eq!(got, want, "seed {seed} cycle {} slot {k}", sim.cycle);
    }
    let valid: Vec<u32> = (0..cfg.warp_buffer_size)
        .filter(|&s| regs.slots[s as usize].valid)
        .collect();
    assert_eq!(status.is_empty(), valid.is_empty());
    (idle_cycles > 0 && idle_cycles < u64::MAX, valid)
}

#[test]
fn lane_summaries_match_a_scan_of_the_lanes_every_cycle() {
    /// Rays issued per run (ids below `max_rays`).
    const RAYS: u32 = 128;
    // A deep stack (no spills) and a 4-entry one that spills and fills all the time.
    for (stack_depth, seed) in [64, 4]
        .into_iter()
        .flat_map(|d| (1..=4u64).map(move |s| (d, s)))
    {
        let cfg = HwConfig {
            max_rays: 128,
            warp_size: 8,
            warp_buffer_size: 3,
            stack_depth,
            ..small()
        };
        let params = RtUnitParams {
            max_children: 3,
            stack_spill_chunks: 4,
            ..RtUnitParams::default()
        };
        {
            let mut rng = SplitMix64::new(seed);
            let (tree, nodes) = random_tree(&mut rng, 24);
            let mut mem = Memory::new(tree, 3 + seed);
            for n in &nodes {
                mem.extra.insert(n.address, rng.below_exact(6));
            }
            let mut sim = Sim::new(cfg.clone(), params.clone(), mem);
            let mut next_ray = 0u32;
            let (mut stops, mut repacks, mut fills, mut idle) = (0, 0, 0, 0);
            // Held slots waiting for their (empty) repack fill, and the cycle it comes.
            let mut fill_due: Vec<(u64, u32)> = Vec::new();
            loop {
                let regs = &sim.regs;
                assert!(
                    sim.cache.consistent(regs),
                    "seed {seed} cycle {}",
                    sim.cycle
                );
                let (was_idle, valid) = check_lane_summaries(&sim, &cfg, seed);
                idle += u32::from(was_idle);
                if next_ray >= RAYS && valid.is_empty() {
                    break;
                }
                assert!(sim.cycle < 20_000, "seed {seed}: warps did not complete");
                let mut issue = None;
                if let Some(i) = fill_due.iter().position(|&(at, _)| at <= sim.cycle) {
                    let (_, slot) = fill_due.remove(i);
                    let mut w = warp(TraversalOrder::RayStationary, 8, Vec::new());
                    w.target = IssueTarget::Append { slot, last: true };
                    issue = Some(w);
                    fills += 1;
                } else if next_ray < RAYS
                    && sim
                        .unit
                        .status(regs, &sim.cache, StatusSelect::Scalars)
                        .issue_ready
                    && rng.below_exact(4) == 0
                {
                    let order = TraversalOrder::ALL[rng.below_exact(3) as usize];
                    let lanes = (0..8)
                        .map(|_| {
                            let id = next_ray;
                            next_ray += 1;
                            (rng.below_exact(5) != 0).then(|| {
                                RayRecord::new(id, words(rng.below_exact(8) as u32), nodes[0])
                            })
                        })
                        .collect();
                    issue = Some(warp(order, 8, lanes));
                }
                let mut stop = None;
                let mut repack = None;
                // Stop only a warp that cannot complete in this cycle (a stop of a slot that
                // empties in the same cycle is a protocol error).
                let busy: Vec<u32> = valid
                    .iter()
                    .copied()
                    .filter(|&s| {
                        sim.unit
                            .slot_summary(regs, &sim.cache, s, false)
                            .is_some_and(|m| !m.quiescent)
                    })
                    .collect();
                if !busy.is_empty() && rng.below_exact(150) == 0 {
                    stop = Some(busy[rng.below_exact(busy.len() as u64) as usize]);
                    stops += 1;
                }
                let unheld: Vec<u32> = valid
                    .iter()
                    .copied()
                    .filter(|&s| !regs.slots[s as usize].held)
                    .collect();
                if fill_due.is_empty() && !unheld.is_empty() && rng.below_exact(100) == 0 {
                    let s = unheld[rng.below_exact(unheld.len() as u64) as usize];
                    repack = Some(s);
                    fill_due.push((sim.cycle + 1 + rng.below_exact(30), s));
                    repacks += 1;
                }
                sim.step_with(|i| {
                    i.issue = issue;
                    i.stop = stop;
                    i.repack = repack;
                });
                // A repack of a slot that completed in the same cycle releases nothing and holds
                // nothing: its fill is not needed.
                if let Some(s) = repack {
                    if !sim.regs.slots[s as usize].valid {
                        fill_due.retain(|&(_, slot)| slot != s);
                    }
                }
            }
            assert_eq!(sim.regs.errors, 0, "seed {seed}");
            assert!(sim.stats.tests.iter().sum::<u64>() > 100, "seed {seed}");
            assert!(stops > 0 && repacks > 0 && fills > 0, "seed {seed}");
            assert!(idle > 0, "seed {seed}: no idle period was exercised");
            let spills = sim.stats.stack_spills;
            // Deep stacks spill only for parked rays (stopped warps).
            assert!(
                spills > 0 || stack_depth != 4,
                "seed {seed}: {spills} spills"
            );
        }
    }
}

/// What [`run_alone`] saw of one ray.
struct Alone {
    /// The final record.
    record: RayRecord,
    /// Tests the ray took.
    tests: u64,
    /// Its node fetches in order.
    fetches: Vec<u64>,
    /// The records it parked with.
    parked: Vec<RayRecord>,
    /// The first hit the RT unit accepted for it and the tests taken by then.
    first_hit: Option<(Hit, u64)>,
}

/// Runs `ray` alone in one-lane warps of `order` on a unit with `stack_depth` on-chip entries
/// until it finishes (under the treelet-stop order a parked ray is issued again, as a treelet
/// controller would).
fn run_alone(tree: Tree, ray: RayRecord, order: TraversalOrder, stack_depth: u32) -> Alone {
    let cfg = HwConfig {
        stack_depth,
        ..small()
    };
    let params = RtUnitParams {
        max_children: 3,
        stack_spill_chunks: 8,
        ..RtUnitParams::default()
    };
    let mut sim = Sim::new(cfg, params, Memory::new(tree, 3));
    let mut parked = Vec::new();
    let mut pending = Some(ray);
    let mut last = None;
    let mut first_hit = None;
    while let Some(r) = pending.take() {
        let before = sim.done.len();
        sim.step(Some(warp(order, 4, vec![Some(r)])));
        while sim.done.len() == before {
            assert!(sim.cycle < 50_000, "the ray did not finish");
            let lanes = sim.regs.slots.iter().flat_map(|s| s.lanes.iter());
            if let Some(h) = lanes.filter_map(|l| l.ray.hit).next() {
                first_hit.get_or_insert((h, sim.stats.total_tests()));
            }
            sim.step(None);
        }
        for (_, done) in &sim.done[before..] {
            for (rec, outcome) in done.lanes.iter().flatten() {
                match outcome {
                    RayOutcome::Finished => last = Some(rec.clone()),
                    RayOutcome::AtBoundary { .. } => {
                        parked.push(rec.clone());
                        pending = Some(rec.clone());
                    }
                }
            }
        }
        assert_eq!(sim.regs.errors, 0, "{:?}", sim.regs.first_error);
    }
    let reqs: Vec<MemRequest> = sim.mem.log.iter().map(|(_, r)| *r).collect();
    Alone {
        record: last.expect("the ray finished"),
        tests: sim.stats.total_tests(),
        fetches: fetch_order(&reqs),
        parked,
        first_hit,
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(96))]

    /// An occlusion ray (terminate on first hit) answers "the closest-hit ray hits something"
    /// in every traversal order, on random trees and rays, with on-chip stacks that spill or
    /// not; its node fetches are a prefix of its closest-hit twin's, so it never visits more
    /// nodes or runs more tests; and a parked occlusion ray never holds a hit (one that hit
    /// is finished, not queued again).
    #[test]
    fn an_occlusion_ray_answers_whether_its_closest_hit_twin_hits(
        seed in proptest::prelude::any::<u64>(),
        select in 0u32..8,
        order in 0usize..3,
        stack_depth in proptest::prop_oneof![proptest::strategy::Just(4u32), proptest::strategy::Just(16u32)],
    ) {
        let mut rng = SplitMix64::new(seed);
        let (tree, nodes) = random_tree(&mut rng, 24);
        let order = TraversalOrder::ALL[order];
        let closest = RayRecord::new(0, words(select), nodes[0]);
        let occlusion = RayRecord { occlusion: true, ..closest.clone() };
        let c = run_alone(tree.clone(), closest, order, stack_depth);
        let o = run_alone(tree, occlusion, order, stack_depth);
        proptest::prop_assert_eq!(o.record.hit.is_some(), c.record.hit.is_some(), "order {:?}", order);
        proptest::prop_assert!(o.tests <= c.tests, "{} tests > {}", o.tests, c.tests);
        proptest::prop_assert!(
            c.fetches.starts_with(&o.fetches),
            "fetches {:?} are not a prefix of {:?}", o.fetches, c.fetches
        );
        proptest::prop_assert!(o.parked.iter().all(|r| r.hit.is_none()));
        let r = &o.record;
        proptest::prop_assert!(r.current_stack.is_empty() && r.other_stack.is_empty());
        proptest::prop_assert_eq!((r.current_spilled, r.other_spilled), (0, 0));
        // It stops at the twin's first accepted hit, with the tests taken by then.
        proptest::prop_assert_eq!(o.record.hit.map(|h| (h, o.tests)), c.first_hit);
        if c.record.hit.is_none() {
            proptest::prop_assert_eq!(o.tests, c.tests);
        }
    }
}
