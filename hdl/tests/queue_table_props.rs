//! State-machine property test of the treelet queue table against a slot-level reference model.
//!
//! The reference keeps `entries` slots of `(treelet, rays, allocation sequence number)` and a
//! spill FIFO, with no hashing or chains: Insert appends to the newest entry of the treelet when
//! it is not full, else takes the lowest free slot, else spills to the FIFO's back; Pop removes
//! the treelet's newest entry; PopAny the lowest-index entry; Refill takes the FIFO's front and
//! inserts it again. The test bench plays the memory system: it stores spilled rays in its own
//! FIFO and answers refill requests after a random latency. After every operation the table's
//! memories must equal the reference slots, its chains must be acyclic with every valid entry
//! reachable from its bucket exactly once, and no ray may be lost or duplicated.

use proptest::prelude::*;
use proptest::sample::Index;
use proptest_state_machine::{prop_state_machine, ReferenceStateMachine, StateMachineTest};
use std::collections::{BTreeSet, VecDeque};
use vtq_hdl::queue_table::{QueueOp, QueueTable, QueueTableIn, QueueTableOut, QueueTableRegs};
use vtq_hdl::{Block, HwConfig, Moore};

#[derive(Debug, Clone)]
struct Params {
    cfg: HwConfig,
    buckets: u32,
    /// Treelet addresses the ops draw from.
    treelets: Vec<u64>,
}

#[derive(Debug, Clone, PartialEq, Eq)]
struct Entry {
    treelet: u64,
    rays: Vec<u32>,
    seq: u64,
}

/// Expected results of one op.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
struct Expect {
    pop: Option<(u64, Vec<u32>)>,
    count: u32,
    spill: Option<(u64, u32)>,
    refill_req: bool,
}

#[derive(Debug, Clone)]
struct RefState {
    p: Params,
    slots: Vec<Option<Entry>>,
    spill: VecDeque<(u64, u32)>,
    /// Ray ids not in the table or the spill store (available for Insert).
    free_ids: BTreeSet<u32>,
    seq: u64,
    /// Ops applied in `init_test` before the generated transitions.
    prefill: Vec<QueueOp>,
    /// The last transition's op with its ray id resolved, and its expected results.
    op: QueueOp,
    last: Expect,
}

#[derive(Debug, Clone)]
enum OpGen {
    Insert { treelet: Index, ray: Index },
    Pop { treelet: Index },
    PopAny,
    Count { treelet: Index },
    Refill,
}

#[derive(Debug, Clone)]
struct Step {
    op: OpGen,
    /// Nop cycles after the op.
    idle: u32,
    /// Cycles from a refill request to the answer.
    latency: u32,
    /// Presented (and to be ignored) while the table is busy.
    busy_op: OpGen,
}

impl RefState {
    fn resolve(&self, g: &OpGen) -> QueueOp {
        let t = |i: &Index| *i.get(&self.p.treelets);
        match g {
            OpGen::Insert { treelet, ray } => QueueOp::Insert {
                treelet: t(treelet),
                ray: *ray.get(&self.free_ids.iter().copied().collect::<Vec<_>>()),
            },
            OpGen::Pop { treelet } => QueueOp::Pop {
                treelet: t(treelet),
            },
            OpGen::PopAny => QueueOp::PopAny,
            OpGen::Count { treelet } => QueueOp::Count {
                treelet: t(treelet),
            },
            OpGen::Refill => QueueOp::Refill,
        }
    }

    fn insert(&mut self, treelet: u64, ray: u32, e: &mut Expect) {
        let warp = self.p.cfg.warp_size as usize;
        let newest = self
            .slots
            .iter_mut()
            .flatten()
            .filter(|x| x.treelet == treelet)
            .max_by_key(|x| x.seq);
        match newest {
            Some(x) if x.rays.len() < warp => x.rays.push(ray),
            _ => match self.slots.iter().position(|s| s.is_none()) {
                Some(f) => {
                    self.seq += 1;
                    self.slots[f] = Some(Entry {
                        treelet,
                        rays: vec![ray],
                        seq: self.seq,
                    });
                }
                None => {
                    self.spill.push_back((treelet, ray));
                    e.spill = Some((treelet, ray));
                }
            },
        }
    }

    fn take(&mut self, i: Option<usize>, e: &mut Expect) {
        if let Some(i) = i {
            let x = self.slots[i].take().unwrap();
            self.free_ids.extend(&x.rays);
            e.pop = Some((x.treelet, x.rays));
        }
    }

    fn apply_op(&mut self, op: QueueOp) -> Expect {
        let mut e = Expect::default();
        match op {
            QueueOp::Nop => {}
            QueueOp::Insert { treelet, ray } => {
                assert!(self.free_ids.remove(&ray), "ray {ray} reused");
                self.insert(treelet, ray, &mut e);
            }
            QueueOp::Pop { treelet } => {
                let i = (0..self.slots.len())
                    .filter(|&i| self.slots[i].as_ref().is_some_and(|x| x.treelet == treelet))
                    .max_by_key(|&i| self.slots[i].as_ref().unwrap().seq);
                self.take(i, &mut e);
            }
            QueueOp::PopAny => {
                let i = self.slots.iter().position(|s| s.is_some());
                self.take(i, &mut e);
            }
            QueueOp::Count { treelet } => {
                e.count = self
                    .slots
                    .iter()
                    .flatten()
                    .filter(|x| x.treelet == treelet)
                    .map(|x| x.rays.len() as u32)
                    .sum();
            }
            QueueOp::Refill => {
                if let Some((t, r)) = self.spill.pop_front() {
                    e.refill_req = true;
                    self.insert(t, r, &mut e);
                }
            }
        }
        e
    }
}

fn small_cfg(entries: u32, warp: u32, max_rays: u32) -> HwConfig {
    HwConfig {
        queue_table_entries: entries,
        warp_size: warp,
        max_rays,
        repack_threshold: 2,
        divergence_threshold: 2,
        underpopulation_threshold: 8,
        ..HwConfig::default()
    }
}

fn init() -> BoxedStrategy<RefState> {
    let addr = 0u64..(1 << 19);
    let small = (
        2u32..=10,
        prop_oneof![Just(2u32), Just(4), Just(8)],
        prop_oneof![Just(32u32), Just(64)],
        prop_oneof![Just(2u32), Just(4)],
        proptest::collection::vec(prop_oneof![0u64..8, addr.clone()], 2..8),
    )
        .prop_map(|(entries, warp, max_rays, buckets, treelets)| {
            (
                Params {
                    cfg: small_cfg(entries, warp, max_rays),
                    buckets,
                    treelets,
                },
                0usize,
            )
        });
    // The paper's table (128 entries, 128 buckets, 32 rays per entry) with enough distinct
    // treelets inserted first to fill it and spill.
    let big = (proptest::collection::vec(addr, 140..=160), 120usize..=150).prop_map(
        |(treelets, fill)| {
            (
                Params {
                    cfg: HwConfig::default(),
                    buckets: 128,
                    treelets,
                },
                fill,
            )
        },
    );
    prop_oneof![49 => small, 1 => big]
        .prop_map(|(p, fill)| {
            let mut s = RefState {
                slots: vec![None; p.cfg.queue_table_entries as usize],
                spill: VecDeque::new(),
                free_ids: (0..p.cfg.max_rays).collect(),
                seq: 0,
                prefill: Vec::new(),
                op: QueueOp::Nop,
                last: Expect::default(),
                p,
            };
            for k in 0..fill {
                let op = QueueOp::Insert {
                    treelet: s.p.treelets[k % s.p.treelets.len()],
                    ray: k as u32,
                };
                s.apply_op(op);
                s.prefill.push(op);
            }
            s
        })
        .boxed()
}

fn op_gen() -> impl Strategy<Value = OpGen> {
    prop_oneof![
        8 => (any::<Index>(), any::<Index>()).prop_map(|(treelet, ray)| OpGen::Insert { treelet, ray }),
        3 => any::<Index>().prop_map(|treelet| OpGen::Pop { treelet }),
        1 => Just(OpGen::PopAny),
        2 => any::<Index>().prop_map(|treelet| OpGen::Count { treelet }),
        2 => Just(OpGen::Refill),
    ]
}

struct QueueRef;

impl ReferenceStateMachine for QueueRef {
    type State = RefState;
    type Transition = Step;

    fn init_state() -> BoxedStrategy<RefState> {
        init()
    }

    fn transitions(_: &RefState) -> BoxedStrategy<Step> {
        (
            op_gen(),
            prop_oneof![3 => Just(0u32), 1 => 1u32..3],
            1u32..4,
            op_gen(),
        )
            .prop_map(|(op, idle, latency, busy_op)| Step {
                op,
                idle,
                latency,
                busy_op,
            })
            .boxed()
    }

    fn preconditions(s: &RefState, t: &Step) -> bool {
        !matches!(t.op, OpGen::Insert { .. }) || !s.free_ids.is_empty()
    }

    fn apply(mut s: RefState, t: &Step) -> RefState {
        s.op = s.resolve(&t.op);
        s.last = s.apply_op(s.op);
        s
    }
}

struct QueueSut {
    table: QueueTable,
    regs: QueueTableRegs,
    /// The same table through the definition, `next_into`, into a scratch bundle that holds
    /// the registers of two cycles before (what it holds must not matter).
    shadow: QueueTableRegs,
    scratch: QueueTableRegs,
    /// The memory system's spill store.
    spill: VecDeque<(u64, u32)>,
    /// The statistics observer: the longest chain walk seen (the largest `walk_len`).
    max_chain: u32,
}

/// What the bench saw while one op ran.
struct Run {
    done: QueueTableOut,
    spills: Vec<(u64, u32)>,
    refill_reqs: u32,
}

impl QueueSut {
    /// One clock edge with `input`, in place and through `next_into` (which must agree).
    fn clock(&mut self, input: &QueueTableIn) -> QueueTableOut {
        let status = self.table.status(&self.regs, &(), ());
        let o = self.table.step(&mut self.regs, input);
        assert_eq!(
            status,
            o.status(),
            "Moore status and the outputs' register-only ports"
        );
        let d = self.table.next_into(&self.shadow, input, &mut self.scratch);
        std::mem::swap(&mut self.shadow, &mut self.scratch);
        assert_eq!(o, d, "in-place step and next_into: outputs");
        assert_eq!(
            self.regs, self.shadow,
            "in-place step and next_into: registers"
        );
        o
    }

    /// Presents `op` (which must be accepted at once), answers refill requests after `latency`
    /// cycles, presents `busy_op` while the table is busy, and runs until `done`.
    fn run(&mut self, op: QueueOp, busy_op: QueueOp, latency: u32) -> Run {
        let t = self.table.clone();
        let limit = 4 * self.regs.valid.len() as u32 + latency + 16;
        let mut answer: Option<(u32, u64, u32)> = None;
        let mut spills = Vec::new();
        let mut refill_reqs = 0;
        for cycle in 0..limit {
            let mut input: QueueTableIn = t.input(if cycle == 0 { op } else { busy_op });
            if let Some((at, tr, ray)) = answer {
                if at == cycle {
                    input = QueueTableIn {
                        refill_valid: true,
                        refill_treelet: tr,
                        refill_ray: ray,
                        ..input
                    };
                    answer = None;
                }
            }
            let o = self.clock(&input);
            self.max_chain = self.max_chain.max(o.walk_len);
            assert_eq!(o.ready, cycle == 0, "ready in cycle {cycle} of {op:?}");
            assert!(!o.error, "error in cycle {cycle} of {op:?}");
            if o.spill_valid {
                self.spill.push_back((o.spill_treelet, o.spill_ray));
                spills.push((o.spill_treelet, o.spill_ray));
            }
            if o.refill_req {
                refill_reqs += 1;
                let (tr, ray) = self
                    .spill
                    .pop_front()
                    .expect("refill request with an empty spill store");
                answer = Some((cycle + latency, tr, ray));
            }
            if o.done {
                assert!(answer.is_none(), "done before the refill answer");
                return Run {
                    done: o,
                    spills,
                    refill_reqs,
                };
            }
        }
        panic!("{op:?} not done within {limit} cycles");
    }

    fn check_done(&self, r: &Run, op: QueueOp, e: &Expect) {
        let o = &r.done;
        let lanes = self.table.widths().lanes as usize;
        match &e.pop {
            Some((t, rays)) => {
                assert_eq!(
                    (o.pop_count as usize, o.pop_treelet),
                    (rays.len(), *t),
                    "popped entry of {op:?}"
                );
                assert_eq!(
                    &o.pop_rays[..rays.len()],
                    &rays[..],
                    "popped rays of {op:?}"
                );
            }
            None => assert_eq!(
                (o.pop_count, o.pop_treelet),
                (0, 0),
                "{op:?} popped nothing"
            ),
        }
        assert!(
            o.pop_rays[o.pop_count as usize..lanes]
                .iter()
                .all(|&x| x == 0),
            "lanes beyond pop_count"
        );
        assert_eq!(o.count_result, e.count, "count of {op:?}");
        assert_eq!(
            r.spills,
            e.spill.into_iter().collect::<Vec<_>>(),
            "spills of {op:?}"
        );
        assert_eq!(
            r.refill_reqs, e.refill_req as u32,
            "refill requests of {op:?}"
        );
    }
}

/// The memories hold exactly the reference slots, and the chains are sound.
fn check_structure(sut: &QueueSut, s: &RefState) {
    let r = &sut.regs;
    let t = &sut.table;
    let e = s.slots.len();
    // Walk every chain: acyclic, valid entries only, in the right bucket.
    let mut seen = vec![false; e];
    let mut longest = 0;
    for (b, h) in r.heads.words().iter().enumerate() {
        let mut cur = h.valid.then_some(h.idx as usize);
        let mut len = 0;
        let mut last_seq = u64::MAX;
        while let Some(i) = cur {
            assert!(!seen[i], "entry {i} reached twice (cycle or shared chain)");
            seen[i] = true;
            len += 1;
            assert!(r.valid[i], "chain of bucket {b} reaches free entry {i}");
            let m = r.meta.words()[i];
            assert_eq!(t.bucket(m.treelet), b, "entry {i} in the wrong bucket");
            let x = s.slots[i]
                .as_ref()
                .expect("valid entry the reference does not have");
            assert!(x.seq < last_seq, "chain not newest-first");
            last_seq = x.seq;
            cur = m.next_valid.then_some(m.next as usize);
        }
        longest = longest.max(len);
    }
    assert_eq!(
        *seen, *r.valid,
        "a valid entry is unreachable from its bucket"
    );
    for (i, slot) in s.slots.iter().enumerate() {
        assert_eq!(r.valid[i], slot.is_some(), "valid bit of entry {i}");
        if let Some(x) = slot {
            let m = r.meta.words()[i];
            let n = x.rays.len();
            assert_eq!(
                (m.treelet, m.count_m1 as usize + 1),
                (x.treelet, n),
                "entry {i} treelet/count"
            );
            assert_eq!(&r.rays.words()[i][..n], &x.rays[..], "entry {i} rays");
        }
    }
    let free = s.slots.iter().filter(|x| x.is_none()).count() as u32;
    assert_eq!(r.ctl.free_count, free, "free count");
    assert_eq!(r.ctl.spilled as usize, s.spill.len(), "spilled count");
    assert_eq!(sut.spill, s.spill, "spill store differs from the reference");
    assert!(
        sut.max_chain as usize <= e,
        "a chain walk beyond the table size"
    );
    // No ray lost or duplicated: table + spill store + unused ids = all ids, disjointly.
    let mut all: Vec<u32> = s
        .slots
        .iter()
        .flatten()
        .flat_map(|x| x.rays.iter().copied())
        .chain(sut.spill.iter().map(|x| x.1))
        .chain(s.free_ids.iter().copied())
        .collect();
    all.sort_unstable();
    assert_eq!(
        all,
        (0..s.p.cfg.max_rays).collect::<Vec<_>>(),
        "rays lost or duplicated"
    );
}

impl StateMachineTest for QueueSut {
    type SystemUnderTest = Self;
    type Reference = QueueRef;

    fn init_test(s: &RefState) -> Self {
        let table = QueueTable::with_buckets(&s.p.cfg, s.p.buckets).unwrap();
        let regs = table.reset();
        let mut sut = QueueSut {
            table,
            shadow: regs.clone(),
            scratch: regs.clone(),
            regs,
            spill: VecDeque::new(),
            max_chain: 0,
        };
        for &op in &s.prefill {
            sut.run(op, QueueOp::Nop, 1);
        }
        sut
    }

    fn apply(mut sut: Self, s: &RefState, t: Step) -> Self {
        let busy = s.resolve(&t.busy_op);
        let busy = match busy {
            // An id that may be in use: the table must ignore it anyway.
            QueueOp::Insert { treelet, .. } => QueueOp::Insert { treelet, ray: 1 },
            other => other,
        };
        let run = sut.run(s.op, busy, t.latency);
        sut.check_done(&run, s.op, &s.last);
        for _ in 0..t.idle {
            let nop = sut.table.input(QueueOp::Nop);
            let o = sut.clock(&nop);
            assert!(o.ready && !o.done && !o.spill_valid && !o.refill_req && !o.error);
            assert_eq!(o.walk_len, 0, "no walk step while idle");
        }
        sut
    }

    fn check_invariants(sut: &Self, s: &RefState) {
        check_structure(sut, s);
    }
}

prop_state_machine! {
    #![proptest_config(ProptestConfig { cases: 10_000, ..ProptestConfig::default() })]
    #[test]
    fn queue_table_matches_reference(sequential 1..40 => QueueSut);
}

#[test]
fn default_widths_in_description() {
    let d = QueueTable::new(&HwConfig::default()).unwrap().describe();
    assert_eq!(d.port("op_treelet").unwrap().width, 19);
    assert_eq!(d.port("op_ray").unwrap().width, 12);
    assert_eq!(d.port("pop_ray_31").unwrap().width, 12);
    assert!(d.port("pop_ray_32").is_none());
    let meta = d.memories.iter().find(|m| m.name == "meta").unwrap();
    assert_eq!(
        (meta.depth, meta.fields[0].1, meta.read_latency),
        (128, 19, 1)
    );
    let rays = d.memories.iter().find(|m| m.name == "rays").unwrap();
    assert_eq!((rays.depth, rays.width), (128, 32 * 12));
    // Paper: (19 + 32 x 12) bits x 128 entries; ours adds the count and link fields.
    assert_eq!(meta.width + rays.width, 19 + 5 + 1 + 7 + 384);
}

#[test]
fn widths_follow_config() {
    let cfg = HwConfig {
        max_rays: 8192,
        queue_table_entries: 256,
        ..HwConfig::default()
    };
    let d = QueueTable::new(&cfg).unwrap().describe();
    assert_eq!(d.port("op_ray").unwrap().width, 13);
    assert_eq!(d.port("free_entries").unwrap().width, 9);
    let meta = d.memories.iter().find(|m| m.name == "meta").unwrap();
    assert_eq!(meta.depth, 256);
    assert_eq!(meta.fields[3], ("next".to_string(), 8));
    let heads = d.memories.iter().find(|m| m.name == "heads").unwrap();
    assert_eq!(heads.depth, 256);
    let rays = d.memories.iter().find(|m| m.name == "rays").unwrap();
    assert_eq!(rays.width, 32 * 13);
}

#[test]
fn description_snapshot() {
    insta::assert_yaml_snapshot!(QueueTable::new(&HwConfig::default()).unwrap().describe());
}
