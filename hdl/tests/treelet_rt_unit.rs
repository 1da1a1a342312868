//! The composed treelet RT unit (RT unit + treelet controller + count table + queue table and
//! their wiring) run end to end against an environment of its own ports only: an SM offering
//! warps of rays, a memory with per-request latencies, the ray-record store and the queue
//! table's spill FIFO. Every cycle the fast path (`step_cached`, and `skip` over idle cycles)
//! is checked against the definition (`eval`, the wiring settled with the children's pure
//! `eval`s); every ray must come back exactly once with its hit, through all of the
//! controller's phases, in every design variant.

use std::collections::{BTreeMap, VecDeque};
use vtq_hdl::controller::ControllerFeatures;
use vtq_hdl::mode::Mode;
use vtq_hdl::rt_unit::NodeDatapath;
use vtq_hdl::rt_unit::{
    MemResponse, NodeEntry, NodeKind, RayRecord, RequestKind, RtUnitParams, CHUNK_BYTES,
};
use vtq_hdl::splitmix::SplitMix64;
use vtq_hdl::treelet_rt_unit::{
    ProbeCycle, RayLoad, TreeletCounts, TreeletRequest, TreeletRtUnit, TreeletRtUnitInputs,
    TreeletRtUnitOutputs, TreeletRtUnitParams, TreeletRtUnitRegs,
};
use vtq_hdl::{Block, Cached, HwConfig, Moore, Signal, Signals, Skip};

mod common;
use common::{assert_signals_fit, node, words, ToyDatapath, Tree, ALL};

/// Ray classes (the toy datapath's child masks select on the ray's class, 0..8).
const CLASSES: u32 = 8;

/// A BVH over eleven 256 B treelets: the root (treelet 0) has one child in each of treelets
/// 1..=7, each class of rays visiting two of them; each of those holds a hit leaf and, for odd
/// classes, leads on into one of treelets 8..=10, each with a hit leaf of its own. Every ray
/// crosses one to four treelet boundaries and ends with a hit.
fn forest() -> (Tree, NodeEntry) {
    let root = node(0x000, NodeKind::Internal, 64);
    let mut tree = Tree::default();
    let deep: Vec<NodeEntry> = (0..3)
        .map(|k| node(0x100 * (8 + k), NodeKind::Internal, 64))
        .collect();
    for &d in &deep {
        let leaf = node(d.address + 0x40, NodeKind::TriangleLeaf, 32);
        tree.add(d, false, &[(leaf, ALL)]).add(leaf, true, &[]);
    }
    let mut children = Vec::new();
    for t in 1..=7u64 {
        let x = node(0x100 * t, NodeKind::Internal, 64);
        let leaf = node(x.address + 0x40, NodeKind::TriangleLeaf, 32);
        let odd = 0b1010_1010;
        tree.add(x, false, &[(leaf, ALL), (deep[t as usize % 3], odd)])
            .add(leaf, true, &[]);
        // Class c visits treelets 1 + c % 7 and 1 + (c + 3) % 7.
        let mask = (0..CLASSES as u64)
            .filter(|c| 1 + c % 7 == t || 1 + (c + 3) % 7 == t)
            .fold(0u8, |m, c| m | 1 << c);
        children.push((x, mask));
    }
    tree.add(root, false, &children);
    (tree, root)
}

/// A small treelet RT unit: 4-lane warps, 16-bit addresses, 256 B treelets, tables of four
/// entries (so the queue table spills and the count table evicts).
fn small() -> HwConfig {
    HwConfig {
        max_rays: 32,
        warp_size: 4,
        address_bits: 16,
        treelet_bytes: 256,
        count_table_entries: 4,
        queue_table_entries: 4,
        underpopulation_threshold: 3,
        repack_threshold: 2,
        divergence_threshold: 2,
        warp_buffer_size: 2,
        max_resident_treelets: 2,
        preload_threshold_warps: 1,
        stack_depth: 8,
        record_stack_entries: 2,
        record_bytes_per_cycle: 32,
    }
}

/// Everything outside the treelet RT unit: the SM's rays, the memory (node chunks, stack spill
/// chunks, ray records in flight) and the spill FIFO.
struct Env {
    tree: Tree,
    root: NodeEntry,
    rng: SplitMix64,
    /// Rays still to offer (their classes), a warp at a time.
    to_offer: VecDeque<u32>,
    /// Responses in flight: (due cycle, response).
    responses: Vec<(u64, MemResponse)>,
    /// Ray-record loads in flight: (due cycle, slot, ray id).
    loads: Vec<(u64, u32, u32)>,
    /// Records of rays parked at a treelet boundary, by ray id.
    store: BTreeMap<u32, RayRecord>,
    spill_fifo: VecDeque<(u64, u32)>,
    /// Per SM ray (by offer order) the class it was given and how often it finished.
    classes: Vec<u32>,
    finished: Vec<u32>,
    /// Ray id -> SM ray, while in flight.
    owner: BTreeMap<u32, usize>,
}

impl Env {
    fn new(rays: u32, seed: u64) -> Self {
        let (tree, root) = forest();
        Env {
            tree,
            root,
            rng: SplitMix64::new(seed),
            to_offer: (0..rays).map(|r| (r * 5 + r / 3) % CLASSES).collect(),
            responses: Vec::new(),
            loads: Vec::new(),
            store: BTreeMap::new(),
            spill_fifo: VecDeque::new(),
            classes: Vec::new(),
            finished: Vec::new(),
            owner: BTreeMap::new(),
        }
    }

    /// The warp the SM offers this cycle, if rays are left and the unit is ready.
    fn offer(&self, ready: bool, warp_size: usize) -> Option<Vec<Option<RayRecord>>> {
        if !ready || self.to_offer.is_empty() {
            return None;
        }
        let lanes = self
            .to_offer
            .iter()
            .take(warp_size)
            .map(|&class| Some(RayRecord::new(0, words(class), self.root)))
            .collect();
        Some(lanes)
    }

    /// This cycle's inputs (with `offer`): due responses (at most `resp_max`) and ray records
    /// (at most `record_max`, oldest first).
    fn inputs(
        &mut self,
        now: u64,
        idle: TreeletRtUnitInputs,
        offer: Option<Vec<Option<RayRecord>>>,
        resp_max: usize,
        record_max: usize,
    ) -> TreeletRtUnitInputs {
        let mut responses = Vec::new();
        self.responses.retain(|&(due, r)| {
            let take = due <= now && responses.len() < resp_max;
            if take {
                responses.push(r);
            }
            !take
        });
        let mut ray_records = Vec::new();
        let store = &mut self.store;
        // The records of a cycle are for one slot (the RT unit writes one slot a cycle): the
        // first due record's.
        let first = self.loads.iter().find(|l| l.0 <= now).map(|l| l.1);
        self.loads.retain(|&(due, slot, ray)| {
            if due > now || ray_records.len() == record_max || Some(slot) != first {
                return true;
            }
            let record = store.remove(&ray).expect("a load of a parked ray");
            ray_records.push(RayLoad { slot, ray, record });
            false
        });
        TreeletRtUnitInputs {
            sm_warp: offer,
            responses,
            ray_records,
            spill_head: self.spill_fifo.front().copied(),
            ..idle
        }
    }

    /// Whether cycle `now` has nothing for the unit (no response or record due).
    fn quiet(&self, now: u64) -> bool {
        self.responses.iter().all(|r| r.0 > now) && self.loads.iter().all(|l| l.0 > now)
    }

    /// The first cycle after `now` at which something arrives.
    fn next_arrival(&self) -> u64 {
        let r = self.responses.iter().map(|r| r.0);
        r.chain(self.loads.iter().map(|l| l.0))
            .min()
            .unwrap_or(u64::MAX)
    }

    /// Takes in the unit's outputs of cycle `now`.
    fn absorb(&mut self, now: u64, out: &TreeletRtUnitOutputs, offered: usize) {
        assert_eq!(
            out.errors, 0,
            "RT unit errors at cycle {now}: {:?}",
            out.first_error
        );
        assert!(
            out.fault.is_none(),
            "wiring fault at cycle {now}: {:?}",
            out.fault
        );
        if let Some(ids) = &out.sm_accepted {
            for id in ids.iter().take(offered) {
                let class = self.to_offer.pop_front().expect("an offered ray");
                let id = id.expect("an offered ray gets an id");
                self.owner.insert(id, self.classes.len());
                self.classes.push(class);
                self.finished.push(0);
            }
        }
        for f in &out.finished {
            let sm_ray = self
                .owner
                .remove(&f.ray)
                .expect("a finished ray is in flight");
            self.finished[sm_ray] += 1;
            assert!(f.hit.is_some(), "every ray of the forest ends with a hit");
        }
        for r in out.parked.iter().map(|p| &p.record) {
            assert!(self.store.insert(r.ray_id, r.clone()).is_none());
        }
        if let Some(e) = out.spill_push {
            self.spill_fifo.push_back(e);
        }
        if out.spill_pop {
            self.spill_fifo
                .pop_front()
                .expect("a pop of the spill FIFO");
        }
        for r in &out.requests {
            let due = now + 3 + self.rng.below_exact(10);
            match *r {
                TreeletRequest::RayLoad { slot, ray, .. } => self.loads.push((due, slot, ray)),
                TreeletRequest::RayStore { .. } => {}
                TreeletRequest::Rt(req) => {
                    if req.kind == RequestKind::StackSpill {
                        self.tree.chunks.insert(req.address, req.data);
                    }
                    if !req.is_store() {
                        let data = self.tree.chunks.get(&req.address).copied();
                        let data = data.unwrap_or([0; CHUNK_BYTES as usize]);
                        let response = MemResponse {
                            address: req.address,
                            tag: req.tag,
                            data,
                        };
                        self.responses.push((due, response));
                    }
                }
            }
        }
    }
}

/// What a run saw.
struct Outcome {
    counts: TreeletCounts,
    modes: Vec<Mode>,
    cycles: u64,
    skipped: u64,
}

/// Runs `rays` rays through a treelet RT unit of `cfg` with `features`: a reference copy steps
/// with `eval` every cycle; the fast copy steps with `step_cached` (odd cycles) or
/// `step_cached_into` an output bundle kept across cycles, as a simulator does (even cycles),
/// and skips the cycles its `idle_cycles` allows when nothing arrives, and must match the
/// reference throughout. With
/// `probe`, the fast copy is probed ([`TreeletRtUnitCache::probe`]) and every step's probe is
/// checked against the reference ([`check_probe`]).
fn run(cfg: HwConfig, features: ControllerFeatures, rays: u32, seed: u64, probe: bool) -> Outcome {
    let params = TreeletRtUnitParams {
        rt: RtUnitParams {
            hit_record_base: 0x8000,
            stack_spill_chunks: 4,
            ..RtUnitParams::default()
        },
        features,
        ray_base: 0x9000,
    };
    let u = TreeletRtUnit::new(cfg.clone(), params, ToyDatapath).expect("valid unit");
    let mut reference: TreeletRtUnitRegs = u.reset();
    let mut fast = reference.clone();
    let mut cache = u.cache(&fast);
    cache.probe(probe);
    let mut env = Env::new(rays, seed);
    let mut counts = TreeletCounts::default();
    let mut modes = vec![mode_of(&u, &reference)];
    let resp_ports = u.rt_unit().params().resp_ports;
    let (mut now, mut skipped) = (0u64, 0u64);
    let mut kept = u.empty_outputs();
    while env.finished.len() < rays as usize
        || !env.owner.is_empty()
        || u.status(&fast, &cache, false).mode != Mode::Done
    {
        assert!(
            now < 200_000,
            "no end after {now} cycles: {}",
            u.debug_state(&fast)
        );
        let offer = env.offer(
            u.status(&fast, &cache, true).sm_ready,
            cfg.warp_size as usize,
        );
        // Cycles with nothing arriving and nothing offered may be skipped by the fast copy.
        let idle = u.idle_cycles(&fast, &cache);
        if offer.is_none() && env.quiet(now) && idle > 0 {
            let n = idle.min(env.next_arrival() - now).min(1000);
            let got = u.skip(&mut fast, &mut cache, n);
            let mut want = TreeletCounts::default();
            for _ in 0..n {
                let inputs = env.inputs(now, u.idle_inputs(), None, 0, 0);
                let (out, next) = u.eval(&reference, &inputs);
                assert_eq!(
                    out.requests.len() + out.finished.len() + out.parked.len(),
                    0,
                    "a skipped cycle did something (cycle {now}, skip {n} of {idle})"
                );
                want.add(&out.counts);
                reference = next;
                now += 1;
            }
            assert_eq!(got, want, "skip({n}) counts, up to cycle {now}");
            assert_eq!(cache.take_probe(), None, "a skip leaves no probe");
            assert_eq!(fast, reference, "registers after skip({n}), cycle {now}");
            counts.add(&got);
            skipped += n;
            continue;
        }
        let offered = offer.as_ref().map_or(0, |o| o.len());
        let resp_max = u.status(&fast, &cache, false).resp_free.min(resp_ports) as usize;
        let ready = u.status(&fast, &cache, true).sm_ready;
        let record_max = cfg.record_ports() as usize;
        let inputs = env.inputs(now, u.idle_inputs(), offer, resp_max, record_max);
        let (want, next, wiring_in, wiring_out) = u.eval_wiring(&reference, &inputs);
        // The wiring alone, from its ports (the children's register-only outputs standing for
        // their registers), is the wiring of the definition.
        let (alone, glue) = u.wiring_eval(&reference.glue, &wiring_in);
        assert_eq!(alone, wiring_out, "the wiring from its ports, cycle {now}");
        assert_eq!(
            glue, next.glue,
            "the wiring's registers from its ports, cycle {now}"
        );
        // The register-only outputs on the ports are what the environment read before the cycle.
        assert_eq!(
            (want.sm_ready, want.resp_free),
            (ready, u.status(&fast, &cache, false).resp_free)
        );
        ports_fit(&inputs, &want, now);
        let out = if now % 2 == 0 {
            u.step_cached_into(&mut fast, &mut cache, &inputs, &mut kept);
            kept.clone()
        } else {
            u.step_cached(&mut fast, &mut cache, &inputs)
        };
        assert_eq!(out, want, "step_cached outputs, cycle {now}");
        assert_eq!(fast, next, "step_cached registers, cycle {now}");
        match cache.take_probe() {
            Some(p) => check_probe(&u, &reference, &inputs, &out, &p, now),
            None => assert!(!probe, "no probe of cycle {now}"),
        }
        reference = next;
        counts.add(&out.counts);
        env.absorb(now, &out, offered);
        if modes.last() != Some(&u.status(&fast, &cache, false).mode) {
            modes.push(u.status(&fast, &cache, false).mode);
        }
        now += 1;
    }
    assert!(
        env.finished.iter().all(|&f| f == 1),
        "rays not traced exactly once: {:?}",
        env.finished
    );
    assert!(env.spill_fifo.is_empty() && env.store.is_empty());
    assert_eq!((fast.ctl.queued_rays, fast.ctl.spare_count), (0, 0));
    assert_eq!(counts.spills, counts.refills, "every spilled ray came back");
    Outcome {
        counts,
        modes,
        cycles: now,
        skipped,
    }
}

/// Every port value of the cycle fits its port's width, traced signals and bulk words alike
/// (the bulk ones panic on a word that does not fit), and the counts ports carry the cycle's
/// statistics events: each one's value is its counter's increment.
fn ports_fit(inputs: &TreeletRtUnitInputs, out: &TreeletRtUnitOutputs, now: u64) {
    let signals: Vec<Signal> = [inputs.signals(), inputs.bulk_signals()]
        .into_iter()
        .chain([out.signals(), out.bulk_signals()])
        .flatten()
        .collect();
    assert_signals_fit(&signals, &format!("cycle {now}: "));
    let port = |name: &str| {
        signals
            .iter()
            .find(|s| s.name == name)
            .unwrap_or_else(|| panic!("no port {name}"))
            .value
    };
    let c = &out.counts;
    let pairs = [
        ("count_rt_active", c.rt.active_thread_cycles),
        ("count_rt_tests_triangle_leaf", c.rt.tests[4]),
        ("count_ctl_initial", c.ctl.cycles_initial),
        ("count_ctl_final", c.ctl.cycles_final),
        ("count_ctl_terminated_rays", c.ctl.terminated_rays),
        ("count_ctl_repack_starved", c.ctl.repack_starved_cycles),
        ("count_spill", c.spills),
        ("count_refill", c.refills),
        ("count_ray_loads", c.ray_loads),
        ("count_ray_stores", c.ray_stores),
        ("count_restart", c.restarts),
    ];
    for (name, count) in pairs {
        assert_eq!(port(name), count, "cycle {now}: port {name}");
    }
    assert_eq!(port("finished_count"), out.finished.len() as u64);
    for f in &out.finished {
        let i = f.position;
        assert_eq!(port(&format!("finished_valid_{i}")), 1);
        assert_eq!(port(&format!("finished_id_{i}")), f.ray as u64);
    }
    let valid = signals
        .iter()
        .filter(|s| s.name.starts_with("finished_valid_") && s.value == 1);
    assert_eq!(valid.count(), out.finished.len());
}

/// A probe's cycle against the definition: the children's registers and the wiring's, as the
/// probe saw them at the start of the cycle, are the composed block's (`regs`, named `<child>_`
/// and `glue_` by [`Block::reg_signals`]); the RT unit child received the block's responses and
/// drove its request; the controller's inputs show whether the SM offered a warp, and its
/// outputs the mode register.
fn check_probe<D: vtq_hdl::rt_unit::NodeDatapath>(
    u: &TreeletRtUnit<D>,
    regs: &TreeletRtUnitRegs,
    inputs: &TreeletRtUnitInputs,
    out: &TreeletRtUnitOutputs,
    p: &ProbeCycle,
    now: u64,
) {
    let names: Vec<&str> = p.children.iter().map(|c| c.0).collect();
    assert_eq!(names, ["rt", "ctl", "ct", "qt"]);
    let prefixed = |prefix: &str, sigs: &[Signal]| {
        sigs.iter()
            .map(|s| Signal::new(format!("{prefix}_{}", s.name), s.width, s.value))
            .collect::<Vec<_>>()
    };
    let mut seen = Vec::new();
    for (name, c) in &p.children {
        seen.extend(prefixed(name, &c.regs));
    }
    seen.extend(prefixed("glue", &p.glue));
    assert_eq!(seen, u.reg_signals(regs), "probed registers, cycle {now}");
    let value = |group: &[Signal], name: &str| {
        group
            .iter()
            .find(|s| s.name == name)
            .unwrap_or_else(|| panic!("no signal {name}"))
            .value
    };
    let rt = &p.children[0].1;
    assert_eq!(
        value(&rt.inputs, "resp0_valid"),
        u64::from(!inputs.responses.is_empty()),
        "cycle {now}"
    );
    assert_eq!(
        value(&rt.outputs, "req_valid"),
        u64::from(out.rt_request().is_some()),
        "cycle {now}"
    );
    if let Some(r) = out.rt_request() {
        assert_eq!(value(&rt.outputs, "req_address"), r.address);
    }
    let ctl = &p.children[1].1;
    assert_eq!(
        value(&ctl.inputs, "restart"),
        u64::from(inputs.sm_warp.is_some()),
        "cycle {now}"
    );
    assert_eq!(
        value(&ctl.regs, "mode"),
        mode_of(u, regs).encoding(),
        "cycle {now}"
    );
    for (name, c) in &p.children {
        assert!(
            !c.inputs.is_empty() && !c.outputs.is_empty(),
            "{name} has ports"
        );
    }
}

#[test]
fn every_ray_is_traced_exactly_once_in_every_variant_and_the_fast_path_is_the_definition() {
    let wide = HwConfig {
        warp_buffer_size: 4,
        max_resident_treelets: 3,
        record_bytes_per_cycle: 128,
        ..small()
    };
    let no_repack = HwConfig {
        repack_threshold: 0,
        record_bytes_per_cycle: 64,
        ..small()
    };
    let no_preload = ControllerFeatures {
        preload: false,
        ..ControllerFeatures::FULL
    };
    // Some variants run probed: the probe changes nothing (the fast path still is the
    // definition) and sees what the children saw.
    let variants = [
        ("full", small(), ControllerFeatures::FULL, true),
        ("naive", small(), ControllerFeatures::NAIVE, true),
        ("no preload", small(), no_preload, false),
        ("no repack", no_repack, ControllerFeatures::FULL, false),
        ("4 warps", wide, ControllerFeatures::FULL, true),
    ];
    let mut spilled = false;
    for (name, cfg, features, probe) in variants {
        // Seed 1: a run in which every variant meets every behaviour asserted below (with some
        // response-latency draws, e.g. seeds 7 and 9 of SplitMix64, or two record ports instead
        // of four, the 4-warp variant never has a warp to repack, which is allowed hardware
        // behaviour, not a failure). Record ports: one (the default), two (no repack) and a
        // warp's worth (4 warps).
        let o = run(cfg.clone(), features, 96, 1, probe);
        let c = &o.counts;
        println!(
            "{name}: {} cycles ({} skipped), modes {:?}, {:?}",
            o.cycles, o.skipped, o.modes, c.ctl
        );
        assert!(
            o.modes.contains(&Mode::TreeletStationary),
            "{name}: {:?}",
            o.modes
        );
        assert!(c.ctl.treelet_warps > 0, "{name}: treelet warps");
        if features.group_underpopulated {
            assert!(
                o.modes.contains(&Mode::FinalRayStationary),
                "{name}: {:?}",
                o.modes
            );
            assert!(c.ctl.grouped_warps > 0, "{name}: grouped warps");
            assert_eq!(
                c.ctl.repacks > 0,
                cfg.repack_threshold > 0,
                "{name}: repacks"
            );
        } else {
            assert!(!o.modes.contains(&Mode::FinalRayStationary), "{name}");
        }
        assert_eq!(
            c.ray_stores, 96,
            "{name}: every SM ray's record is stored once"
        );
        assert!(o.skipped > 0, "{name}: no idle cycle was skipped");
        spilled |= c.spills > 0;
    }
    assert!(spilled, "the queue table never spilled");
}

/// The controller's mode register of `regs` (the block's register-only outputs, from a fresh
/// cache).
fn mode_of<D: NodeDatapath>(u: &TreeletRtUnit<D>, regs: &TreeletRtUnitRegs) -> Mode {
    u.status(regs, &u.cache(regs), false).mode
}
