//! End-to-end tests of the cycle-exact GPU simulator in the baseline design, on small images of
//! the built-in scenes with 1-2 SMs and small caches: closest hits and the image equal the
//! functional tracer's bit for bit, skipping idle cycles changes nothing, runs repeat exactly,
//! and the watchdog stops a run that makes no progress.

mod common;

use common::{
    check_against_functional, check_deterministic, check_scene_skip_matches_lockstep,
    check_skip_matches_lockstep, setup, small_config, STARVED_MEMORY,
};
use std::collections::BTreeMap;

use vtq_hdl::rt_unit::NodeKind;
use vtq_sim::model::gpu::{simulate, SimError, SimOptions};
use vtq_sim::model::traversal::{trace_with_fetches, Order};

/// Hits and image equal the functional tracer's; the RT units' requests and stores all
/// reached the L1, and every 8x8 tile ran as one CTA.
fn check_baseline(name: &str, sms: u32, side: u32) {
    let out = check_against_functional(name, &small_config("baseline", sms, side, &[]));
    assert!(out.stats.cycles > 0 && out.stats.simt_efficiency > 0.0);
    assert!(out.stats.bvh_l1_accesses >= out.stats.bvh_l1_misses);
    assert!(out.stats.bvh_l1_misses > 0, "{name}: cold caches must miss");
    // Every node request of the RT units reached the L1, every hit-record store too.
    assert_eq!(out.stats.rt.load_requests, out.stats.bvh_l1_accesses);
    assert_eq!(out.stats.rt.stores, out.stats.memory.hit_record.l1_stores);
    assert_eq!(
        out.stats.ctas,
        4 * (side as u64 / 8) * (side as u64 / 8) / 4
    );
    // SIMT efficiency per warp: every warp carried at most 32 rays and every ray was in one,
    // and the mean of per-warp ratios is a ratio like the per-cycle one.
    let s = &out.stats;
    assert!(
        s.rt_warps >= s.rays_issued.div_ceil(32),
        "{} warps",
        s.rt_warps
    );
    assert!(s.rt_warps <= s.rays_issued, "{} warps", s.rt_warps);
    assert!(s.simt_efficiency_per_warp > 0.0 && s.simt_efficiency_per_warp <= 1.0);
    // Per tenth of the run: ten ratios, and where warps were resident the per-cycle measure.
    assert_eq!(s.simt_efficiency_deciles.len(), 10);
    assert!(s
        .simt_efficiency_deciles
        .iter()
        .all(|e| (0.0..=1.0).contains(e)));
    assert!(s.simt_efficiency_deciles.iter().any(|&e| e > 0.0));
}

#[test]
fn wknd_hits_and_image_equal_the_functional_tracer() {
    check_baseline("wknd", 2, 32);
}

#[test]
fn cornell_hits_and_image_equal_the_functional_tracer() {
    check_baseline("cornell", 1, 32);
}

/// The functional tracer's hardware order visits exactly the nodes the RT units test: over
/// every traced ray, its fetches per node kind sum to the simulation's test counts (so the
/// sampled tier's profile counts the simulated work).
#[test]
fn hardware_order_visits_the_rt_units_nodes() {
    for scene in ["wknd", "cornell"] {
        let cfg = small_config("baseline", 2, 24, &[]);
        let (s, bvh) = setup(scene, &cfg);
        let out = common::run(&s, &bvh, &cfg);
        let mut counts: BTreeMap<String, u64> = BTreeMap::new();
        let mut fetches = Vec::new();
        for r in &out.ray_log {
            fetches.clear();
            let hit = trace_with_fetches(&bvh, &r.ray, Order::Hardware, &mut fetches);
            assert_eq!(common::hit_bits(hit), common::hit_bits(r.hit));
            for f in &fetches {
                *counts.entry(format!("{:?}", f.kind)).or_default() += 1;
            }
        }
        let simulated = |k: &str| {
            let kind = NodeKind::ALL.into_iter().find(|n| n.name() == k);
            out.stats.rt.tests_of(kind.expect("a node kind"))
        };
        assert_eq!(
            counts.get("Header").copied().unwrap_or(0),
            simulated("header"),
            "{scene}"
        );
        assert_eq!(
            counts.get("Internal").copied().unwrap_or(0),
            simulated("internal"),
            "{scene}"
        );
        assert_eq!(
            counts.get("TriangleLeaf").copied().unwrap_or(0),
            simulated("triangle_leaf"),
            "{scene}"
        );
        assert_eq!(
            counts.get("ProceduralLeaf").copied().unwrap_or(0),
            simulated("procedural"),
            "{scene}"
        );
        assert!(out.stats.rt.total_tests() > 0);
    }
}

/// Skipping idle cycles gives the same statistics and time series as stepping every cycle.
#[test]
fn skipping_idle_cycles_matches_lockstep() {
    check_skip_matches_lockstep(&small_config("baseline", 2, 32, &[]));
}

/// Two runs of one configuration give identical statistics, images and ray logs.
#[test]
fn runs_are_deterministic() {
    check_deterministic(&small_config("baseline", 4, 16, &["bounces=2"]));
}

/// With an L2 round trip of 3 cycles (windows of 3 cycles), one MSHR and slow DRAM, L1 misses
/// stall on fills whose cycle is not known yet within a window (deferred retries) and merge with
/// them: every design still traces every ray exactly, equals lockstep and gives identical
/// results on any number of threads.
#[test]
fn short_round_trip_and_one_mshr_are_exact_on_any_thread_count() {
    let fast = [
        "memory.l1_latency=1",
        "memory.l2_latency=2",
        "memory.dram_latency=3",
        "memory.dram_bytes_per_cycle=4",
        "memory.l1_mshrs=1",
        "bounces=2",
    ];
    for mode in ["baseline", "prefetch"] {
        let cfg = small_config(mode, 4, 16, &fast);
        let out = check_against_functional("cornell", &cfg);
        assert!(
            out.stats.memory.mshr_stalls > 0,
            "{mode}: MSHR stalls happen"
        );
        check_deterministic(&cfg);
        let (scene, bvh) = setup("cornell", &cfg);
        check_scene_skip_matches_lockstep(&scene, &bvh, &cfg);
    }
}

/// With one MSHR, one-cycle latencies and a DRAM moving one byte per cycle, every miss keeps
/// the RT unit waiting ~32 cycles with nothing issuing: a watchdog of 8 cycles stops the run
/// with a state dump of every component.
#[test]
fn watchdog_stops_a_run_without_progress() {
    let cfg = small_config("baseline", 2, 8, &STARVED_MEMORY);
    let (scene, bvh) = setup("wknd", &cfg);
    let err = simulate(&scene, &bvh, &cfg, SimOptions::default(), None).unwrap_err();
    let SimError::Watchdog {
        cycle,
        last_progress,
        dump,
    } = &err
    else {
        panic!("expected a watchdog error, got {err}");
    };
    assert_eq!(*cycle, last_progress + 9);
    for part in ["CTA scheduler", "SM 0", "SM 1", "RT unit", "MSHRs", "DRAM"] {
        assert!(dump.contains(part), "dump lacks {part}: {dump}");
    }
}
