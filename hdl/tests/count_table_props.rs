//! State-machine property test of the treelet count table against a slot-level reference model.
//!
//! The reference keeps `entries` slots of `(treelet, count)`: Add hits add, misses take the
//! lowest free slot, and a miss on a full table evicts the smallest slot (lowest index on ties)
//! unless the new treelet is not larger, in which case the new treelet itself is reported
//! evicted. Every cycle the block's registered outputs are checked against the reference state
//! of that cycle; after every operation the whole entry array must equal the reference slots.

use proptest::prelude::*;
use proptest_state_machine::{prop_state_machine, ReferenceStateMachine, StateMachineTest};
use vtq_hdl::count_table::{CountOp, CountTable, CountTableOut, CountTableRegs};
use vtq_hdl::{Block, HwConfig, Moore, Skip};

/// Parameters of one test case.
#[derive(Debug, Clone)]
struct Params {
    cfg: HwConfig,
    scan_width: u32,
    /// Pool of treelet addresses the ops draw from.
    pool: u64,
}

/// Reference state: the slots, plus the expected result of the last op.
#[derive(Debug, Clone)]
struct RefState {
    p: Params,
    slots: Vec<Option<(u64, u32)>>,
    /// Ops applied in `init_test` before the generated transitions (fills big tables).
    prefill: Vec<CountOp>,
    last: Expect,
}

/// Expected outputs of an accepted op.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct Expect {
    error: bool,
    evict: Option<(u64, u32)>,
}

/// Present the op until accepted, then `idle` Nop cycles.
#[derive(Debug, Clone)]
struct Step {
    op: CountOp,
    idle: u32,
}

fn argmax(slots: &[Option<(u64, u32)>]) -> Option<(usize, u64, u32)> {
    let mut best: Option<(usize, u64, u32)> = None;
    for (i, s) in slots.iter().enumerate() {
        if let Some((t, c)) = *s {
            if best.is_none_or(|b| c > b.2) {
                best = Some((i, t, c));
            }
        }
    }
    best
}

fn argmin(slots: &[Option<(u64, u32)>]) -> Option<(usize, u64, u32)> {
    let mut best: Option<(usize, u64, u32)> = None;
    for (i, s) in slots.iter().enumerate() {
        if let Some((t, c)) = *s {
            if best.is_none_or(|b| c < b.2) {
                best = Some((i, t, c));
            }
        }
    }
    best
}

/// The reference semantics of one op.
fn ref_apply(p: &Params, slots: &mut [Option<(u64, u32)>], op: CountOp) -> Expect {
    let warp = p.cfg.warp_size;
    let hit =
        |slots: &[Option<(u64, u32)>], t| slots.iter().position(|s| s.is_some_and(|s| s.0 == t));
    match op {
        CountOp::Nop => Expect::default(),
        CountOp::Clear => {
            slots.fill(None);
            Expect::default()
        }
        CountOp::Add { treelet, n } => {
            if n == 0 || n > warp {
                return Expect {
                    error: true,
                    evict: None,
                };
            }
            if let Some(i) = hit(slots, treelet) {
                let c = slots[i].unwrap().1;
                if c + n > p.cfg.max_rays {
                    return Expect {
                        error: true,
                        evict: None,
                    };
                }
                slots[i] = Some((treelet, c + n));
                return Expect::default();
            }
            if let Some(f) = slots.iter().position(|s| s.is_none()) {
                slots[f] = Some((treelet, n));
                return Expect::default();
            }
            let (i, t, c) = argmin(slots).expect("a full table has a minimum");
            if n <= c {
                Expect {
                    error: false,
                    evict: Some((treelet, n)),
                }
            } else {
                slots[i] = Some((treelet, n));
                Expect {
                    error: false,
                    evict: Some((t, c)),
                }
            }
        }
        CountOp::Remove { treelet, n } => match hit(slots, treelet) {
            Some(i) if n > 0 && n <= warp => {
                let c = slots[i].unwrap().1;
                if n > c {
                    Expect {
                        error: true,
                        evict: None,
                    }
                } else {
                    slots[i] = (n < c).then_some((treelet, c - n));
                    Expect::default()
                }
            }
            _ => Expect {
                error: true,
                evict: None,
            },
        },
    }
}

fn small_cfg(entries: u32, warp: u32, max_rays: u32, threshold: u32) -> HwConfig {
    HwConfig {
        count_table_entries: entries,
        warp_size: warp,
        max_rays,
        underpopulation_threshold: threshold,
        repack_threshold: 2,
        divergence_threshold: 2,
        ..HwConfig::default()
    }
}

fn params() -> BoxedStrategy<(Params, Vec<CountOp>)> {
    let small = (
        2u32..=10,
        0u32..4,
        prop_oneof![Just(4u32), Just(8)],
        prop_oneof![Just(32u32), Just(64)],
        1u32..=20,
    )
        .prop_map(|(entries, w, warp, max_rays, threshold)| {
            let p = Params {
                cfg: small_cfg(entries, warp, max_rays, threshold),
                scan_width: (w % entries) + 1,
                pool: entries as u64 + 4,
            };
            (p, Vec::new())
        });
    // The paper's table (600 entries, scan width 8), filled to 590..=600 distinct treelets.
    let big = (590u64..=600, any::<u64>()).prop_map(|(fill, salt)| {
        let cfg = HwConfig::default();
        let prefill = (0..fill)
            .map(|t| CountOp::Add {
                treelet: t,
                n: 1 + ((t ^ salt) % 32) as u32,
            })
            .collect();
        (
            Params {
                cfg,
                scan_width: 8,
                pool: 610,
            },
            prefill,
        )
    });
    prop_oneof![49 => small, 1 => big].boxed()
}

struct CountRef;

impl ReferenceStateMachine for CountRef {
    type State = RefState;
    type Transition = Step;

    fn init_state() -> BoxedStrategy<RefState> {
        params()
            .prop_map(|(p, prefill)| {
                let mut slots = vec![None; p.cfg.count_table_entries as usize];
                for &op in &prefill {
                    ref_apply(&p, &mut slots, op);
                }
                RefState {
                    p,
                    slots,
                    prefill,
                    last: Expect::default(),
                }
            })
            .boxed()
    }

    fn transitions(s: &RefState) -> BoxedStrategy<Step> {
        let warp = s.p.cfg.warp_size;
        let pool = s.p.pool;
        let scan = s.p.cfg.count_table_entries.div_ceil(s.p.scan_width);
        let idle = prop_oneof![4 => 0u32..3, 1 => Just(scan + 1)];
        let held: Vec<(u64, u32)> = s.slots.iter().flatten().copied().collect();
        let add = (
            0..pool,
            prop_oneof![10 => 1..=warp, 1 => Just(0u32), 1 => Just(warp + 1)],
        )
            .prop_map(|(treelet, n)| CountOp::Add { treelet, n });
        let any_remove =
            (0..pool, 0..=warp + 1).prop_map(|(treelet, n)| CountOp::Remove { treelet, n });
        let op = if held.is_empty() {
            prop_oneof![4 => add, 1 => any_remove].boxed()
        } else {
            let remove_held =
                (proptest::sample::select(held), 0u32..100).prop_map(move |((treelet, c), r)| {
                    // Mostly a valid amount, sometimes the whole count, sometimes one too many.
                    let n = match r {
                        0..=59 => 1 + r % c.min(warp),
                        60..=89 => c.min(warp),
                        _ => c + 1,
                    };
                    CountOp::Remove { treelet, n }
                });
            prop_oneof![
                5 => add,
                4 => remove_held,
                1 => any_remove,
                1 => Just(CountOp::Clear)
            ]
            .boxed()
        };
        (op, idle).prop_map(|(op, idle)| Step { op, idle }).boxed()
    }

    fn apply(mut s: RefState, t: &Step) -> RefState {
        let op = t.op;
        s.last = ref_apply(&s.p, &mut s.slots, op);
        s
    }
}

struct CountSut {
    table: CountTable,
    regs: CountTableRegs,
    /// The same table through the definition, `next_into`, into a scratch bundle that holds
    /// the registers of two cycles before (what it holds must not matter).
    shadow: CountTableRegs,
    scratch: CountTableRegs,
    /// Reference slots before the current transition.
    slots: Vec<Option<(u64, u32)>>,
}

/// Registered outputs must describe `slots` (the state at the start of the cycle).
fn check_registered(p: &Params, o: &CountTableOut, slots: &[Option<(u64, u32)>]) {
    let occupancy = slots.iter().flatten().count() as u32;
    let above = slots
        .iter()
        .flatten()
        .filter(|s| s.1 >= p.cfg.underpopulation_threshold)
        .count() as u32;
    assert_eq!(o.occupancy, occupancy, "occupancy");
    assert_eq!(o.above_threshold, above, "above_threshold");
    if o.max_valid {
        let (_, t, c) = argmax(slots).expect("max_valid on an empty table");
        assert_eq!(
            (o.max_treelet, o.max_count),
            (t, c),
            "reported max is not the largest"
        );
    } else {
        assert_eq!((o.max_treelet, o.max_count), (0, 0), "max fields not gated");
    }
}

fn check_contents(regs: &CountTableRegs, slots: &[Option<(u64, u32)>]) {
    let got: Vec<Option<(u64, u32)>> = regs
        .entries
        .words()
        .iter()
        .map(|e| e.valid.then_some((e.treelet, e.count_m1 + 1)))
        .collect();
    assert_eq!(got, slots, "entry array differs from the reference");
}

impl CountSut {
    /// One clock edge with `op` presented, in place and through `next_into` (which must agree).
    fn clock(&mut self, op: CountOp) -> CountTableOut {
        let input = self.table.input(op);
        // The register-only outputs from the registers alone, and a `Nop` cycle as a skip.
        let status = self.table.status(&self.regs, &(), ());
        let idle = self.table.idle_cycles(&self.regs, &());
        let mut skipped = self.regs.clone();
        let o = self.table.step(&mut self.regs, &input);
        assert_eq!(
            status,
            o.status(),
            "Moore status and the outputs' register-only ports"
        );
        if op == CountOp::Nop {
            if idle == u64::MAX {
                assert_eq!(skipped, self.regs, "a gated table changed in a Nop cycle");
            } else {
                self.table.skip(&mut skipped, &mut (), 1);
                assert_eq!(skipped, self.regs, "a skipped cycle and a Nop step differ");
            }
        }
        let d = self
            .table
            .next_into(&self.shadow, &input, &mut self.scratch);
        std::mem::swap(&mut self.shadow, &mut self.scratch);
        assert_eq!(o, d, "in-place step and next_into: outputs");
        assert_eq!(
            self.regs, self.shadow,
            "in-place step and next_into: registers"
        );
        o
    }

    /// Presents `op` until accepted; returns the accepting cycle's outputs.
    fn present(&mut self, p: &Params, op: CountOp, check: bool) -> CountTableOut {
        let limit = self.table.scan_cycles() + 2;
        for _ in 0..=limit {
            let o = self.clock(op);
            if check {
                check_registered(p, &o, &self.slots);
            }
            if o.ready {
                return o;
            }
            // Only an Add of a new treelet into a full table may stall.
            let full = self.slots.iter().all(|s| s.is_some());
            match op {
                CountOp::Add { treelet, n } => assert!(
                    full && n >= 1
                        && n <= p.cfg.warp_size
                        && !self.slots.iter().flatten().any(|s| s.0 == treelet),
                    "stalled on {op:?}"
                ),
                _ => panic!("stalled on {op:?}"),
            }
        }
        panic!("{op:?} not accepted within {limit} cycles");
    }
}

impl StateMachineTest for CountSut {
    type SystemUnderTest = Self;
    type Reference = CountRef;

    fn init_test(s: &RefState) -> Self {
        let table = CountTable::with_scan_width(&s.p.cfg, s.p.scan_width).unwrap();
        let regs = table.reset();
        let mut sut = CountSut {
            table,
            shadow: regs.clone(),
            scratch: regs.clone(),
            regs,
            slots: vec![None; s.p.cfg.count_table_entries as usize],
        };
        for &op in &s.prefill {
            let o = sut.present(&s.p, op, false);
            let e = ref_apply(&s.p, &mut sut.slots, op);
            assert_eq!(
                (o.error, o.evict_valid),
                (e.error, e.evict.is_some()),
                "prefill {op:?}"
            );
        }
        check_contents(&sut.regs, &s.slots);
        sut
    }

    fn apply(mut sut: Self, s: &RefState, t: Step) -> Self {
        let Step { op, idle } = t;
        let o = sut.present(&s.p, op, true);
        assert_eq!(o.error, s.last.error, "error flag for {op:?}");
        let evict = o.evict_valid.then_some((o.evict_treelet, o.evict_count));
        assert_eq!(evict, s.last.evict, "eviction for {op:?}");
        if !o.evict_valid {
            assert_eq!(
                (o.evict_treelet, o.evict_count),
                (0, 0),
                "evict fields not gated"
            );
        }
        sut.slots = s.slots.clone();
        check_contents(&sut.regs, &s.slots);
        for _ in 0..idle {
            let o = sut.clock(CountOp::Nop);
            check_registered(&s.p, &o, &s.slots);
            assert!(!o.error && !o.evict_valid);
        }
        sut
    }

    fn check_invariants(sut: &Self, s: &RefState) {
        let r = &sut.regs;
        let nonempty = s.slots.iter().any(|x| x.is_some());
        // Out of a scan both pointers are current; when valid they are exact.
        for (what, ptr, expected) in [
            ("max", &r.ctl.max, argmax(&s.slots)),
            ("min", &r.ctl.min, argmin(&s.slots)),
        ] {
            if !r.ctl.scanning {
                assert_eq!(ptr.valid, nonempty, "{what} pointer valid outside a scan");
            }
            if ptr.valid {
                let (i, t, c) = expected.unwrap();
                assert_eq!(
                    (ptr.idx as usize, ptr.treelet, ptr.count_m1 + 1),
                    (i, t, c),
                    "{what} pointer"
                );
            }
        }
    }
}

prop_state_machine! {
    #![proptest_config(ProptestConfig { cases: 10_000, ..ProptestConfig::default() })]
    #[test]
    fn count_table_matches_reference(sequential 1..40 => CountSut);
}

#[test]
fn default_widths_in_description() {
    let d = CountTable::new(&HwConfig::default()).unwrap().describe();
    assert_eq!(d.port("op_treelet").unwrap().width, 19);
    assert_eq!(d.port("max_treelet").unwrap().width, 19);
    let m = &d.memories[0];
    assert_eq!((m.depth, m.width), (600, 32));
    assert_eq!(
        m.fields,
        vec![
            ("valid".to_string(), 1),
            ("treelet".to_string(), 19),
            ("count_m1".to_string(), 12)
        ]
    );
    assert_eq!(
        d.storage_bits() / 8 / 1024,
        2,
        "about the paper's 2.2 KB plus pointer registers"
    );
}

#[test]
fn widths_follow_config() {
    let cfg = HwConfig {
        max_rays: 8192,
        treelet_bytes: 16384,
        count_table_entries: 1024,
        ..HwConfig::default()
    };
    let d = CountTable::new(&cfg).unwrap().describe();
    assert_eq!(d.port("op_treelet").unwrap().width, 18);
    assert_eq!(
        d.port("max_count").unwrap().width,
        14,
        "true counts 0..=8192"
    );
    let m = &d.memories[0];
    assert_eq!(m.fields[2], ("count_m1".to_string(), 13));
    assert_eq!(m.depth, 1024);
    assert_eq!(d.port("occupancy").unwrap().width, 11);
}

#[test]
fn description_snapshot() {
    insta::assert_yaml_snapshot!(CountTable::new(&HwConfig::default()).unwrap().describe());
}
