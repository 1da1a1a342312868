//! End-to-end tests of the `queues` design (dynamic treelet queues, paper sections 3.2 and 4)
//! in each of the paper's variants — naive queues, +grouping, +repacking, full VTQ with ray
//! virtualization — on small images of the built-in scenes: closest hits and the image equal the
//! functional tracer's bit for bit, no ray is lost when the tables overflow, skipping idle
//! cycles changes nothing and runs repeat exactly.

mod common;

use common::{
    check_against_functional, check_deterministic, check_skip_matches_lockstep, small_config,
};
use vtq_sim::model::gpu::SimOutput;

/// The overrides of each variant (the configs/ files' switches).
const NAIVE: &[&str] = &[
    "mode.virtualization=true",
    "mode.grouping=false",
    "mode.preload=true",
    "hw.repack_threshold=0",
];
const GROUPING: &[&str] = &[
    "mode.virtualization=true",
    "mode.grouping=true",
    "mode.preload=true",
    "hw.repack_threshold=0",
];
const REPACK16: &[&str] = &[
    "mode.virtualization=true",
    "mode.grouping=true",
    "mode.preload=true",
    "hw.repack_threshold=16",
];
const VTQ: &[&str] = &[
    "mode.virtualization=true",
    "mode.grouping=true",
    "mode.preload=true",
    "hw.repack_threshold=22",
];
/// Queues without ray virtualization (repacking needs it, so it is off).
const NO_VIRT: &[&str] = &[
    "mode.virtualization=false",
    "mode.grouping=true",
    "mode.preload=false",
    "hw.repack_threshold=0",
];

/// A small queues-mode configuration: `variant` switches, treelet phase reachable (a low
/// divergence and underpopulation threshold for the small images), then `extra`.
fn cfg(variant: &[&str], sms: u32, side: u32, extra: &[&str]) -> vtq_sim::model::config::SimConfig {
    let mut sets: Vec<&str> = variant.to_vec();
    sets.extend([
        "hw.divergence_threshold=2",
        "hw.underpopulation_threshold=8",
    ]);
    sets.extend(extra);
    small_config("queues", sms, side, &sets)
}

/// Checks shared by every queues run: the treelet hardware was used and reported.
fn check_queue_stats(out: &SimOutput) {
    let s = &out.stats;
    assert_eq!(s.mode, "queues");
    for unit in [
        "treelet_controller",
        "treelet_count_table",
        "treelet_queue_table",
    ] {
        assert!(s.active_units.iter().any(|u| u == unit), "{unit} listed");
    }
    assert!(
        s.phases.treelet_stationary.intersection_tests > 0,
        "rays were traversed treelet-stationary: {:?}",
        s.phases
    );
    assert!(s.max_queues > 0);
    let tests = s.phases.initial.intersection_tests
        + s.phases.treelet_stationary.intersection_tests
        + s.phases.ray_stationary.intersection_tests;
    assert_eq!(
        tests,
        s.rt.total_tests(),
        "every test is attributed to a phase"
    );
    let phases = [
        &s.phases.initial,
        &s.phases.treelet_stationary,
        &s.phases.ray_stationary,
    ];
    assert_eq!(
        phases.iter().map(|p| p.warp_cycles).sum::<u64>(),
        s.rt.warp_cycles,
        "every warp cycle is attributed to a phase"
    );
    assert_eq!(
        phases.iter().map(|p| p.active_thread_cycles).sum::<u64>(),
        s.rt.active_thread_cycles,
        "every active thread cycle is attributed to a phase"
    );
    assert!(s.phases.treelet_stationary.warp_cycles > 0);
    for p in phases {
        assert!((0.0..=1.0).contains(&p.simt_efficiency), "{p:?}");
        // Every lane of every warp cycle is active, finished, parked or empty.
        let l = &p.lanes;
        assert_eq!(
            p.active_thread_cycles + l.finished + l.parked + l.empty,
            p.warp_cycles * 32,
            "{p:?}"
        );
        assert!(l.memory_wait <= p.active_thread_cycles, "{p:?}");
    }
    // Treelet-stationary warps park their lanes at the treelet's boundary.
    assert!(s.phases.treelet_stationary.lanes.parked > 0);
    assert_eq!(
        phases.iter().map(|p| p.lanes.parked).sum::<u64>(),
        s.rt.parked_lane_cycles
    );
    // Every ray an SM issued stored its record once; every ray that entered a queue left it
    // again and had its record loaded once.
    let q = &s.queues.counts;
    assert_eq!(q.ray_stores, s.rays_issued);
    assert!(q.ctl.terminated_warps > 0 && q.ctl.enqueued_rays > 0);
    assert_eq!(q.ray_loads, q.ctl.enqueued_rays);
    assert_eq!(s.memory.ray_record.l1_bypasses, q.ray_loads + q.ray_stores);
    assert!(q.restarts >= 1);
}

#[test]
fn full_vtq_hits_and_image_equal_the_functional_tracer() {
    let out = check_against_functional("wknd", &cfg(VTQ, 2, 32, &[]));
    check_queue_stats(&out);
    assert!(out.stats.cta_suspends > 0, "virtualization suspended CTAs");
    let out = check_against_functional("cornell", &cfg(VTQ, 1, 24, &[]));
    check_queue_stats(&out);
}

#[test]
fn naive_grouping_and_repack_variants_trace_every_ray_exactly() {
    for (name, variant) in [
        ("naive", NAIVE),
        ("grouping", GROUPING),
        ("repack16", REPACK16),
    ] {
        let out = check_against_functional("wknd", &cfg(variant, 1, 24, &[]));
        check_queue_stats(&out);
        let finals = out.stats.phases.ray_stationary.intersection_tests;
        let q = &out.stats.queues.counts.ctl;
        match name {
            "naive" => {
                assert_eq!(finals, 0, "naive queues never group underpopulated queues");
                assert_eq!((q.grouped_warps, q.repacks), (0, 0));
                assert!(q.treelet_warps > 0);
            }
            "grouping" => assert!(q.grouped_warps > 0 && q.repacks == 0, "{q:?}"),
            _ => assert!(q.grouped_warps > 0 && q.repacks > 0, "{q:?}"),
        }
    }
}

#[test]
fn queues_without_virtualization_trace_every_ray_exactly() {
    let out = check_against_functional("cornell", &cfg(NO_VIRT, 2, 24, &[]));
    check_queue_stats(&out);
    assert_eq!(out.stats.cta_suspends, 0);
}

/// Tiny tables: the queue table spills to memory and the count table evicts, and still every
/// ray is traced exactly once with the right hit.
#[test]
fn no_ray_is_lost_when_the_tables_overflow() {
    let tiny = ["hw.queue_table_entries=2", "hw.count_table_entries=2"];
    let out = check_against_functional("wknd", &cfg(VTQ, 1, 32, &tiny));
    check_queue_stats(&out);
    assert!(out.stats.queue_table_spills > 0, "the queue table spilled");
    assert!(
        out.stats.count_table_evictions > 0,
        "the count table evicted"
    );
    let out = check_against_functional("wknd", &cfg(NAIVE, 1, 32, &tiny));
    assert!(out.stats.queue_table_spills > 0);
}

/// The skip reading of section 6.4 (every queue underpopulated, so no queue is ever claimed)
/// under ray virtualization with a small ray budget: grouped warps take every ray with
/// `PopAny`, which removes no count, so the counts must be cleared when a wave ends. Before that
/// clear they outlived their rays and passed `hw.max_rays` within a few waves ("the count table
/// rejected an op", docs/fidelity.md cause G).
#[test]
fn counts_do_not_outlive_their_wave_of_rays() {
    let small_budget = [
        "hw.max_rays=64",
        "hw.underpopulation_threshold=64",
        "gpu.max_ctas_per_sm=1",
        "gpu.threads_per_cta=64",
    ];
    let out = check_against_functional("wknd", &cfg(VTQ, 1, 32, &small_budget));
    let q = &out.stats.queues.counts;
    assert!(q.restarts > 10, "many waves of rays: {}", q.restarts);
    assert!(q.ctl.grouped_warps > 0 && q.ctl.enqueued_rays > 0, "{q:?}");
    assert_eq!(q.ctl.treelet_warps, 0, "no queue reaches the threshold");
}

#[test]
fn skipping_idle_cycles_matches_lockstep() {
    for variant in [VTQ, NAIVE, NO_VIRT] {
        let (skip, _) = check_skip_matches_lockstep(&cfg(variant, 2, 24, &[]));
        check_queue_stats(&skip);
    }
}

/// VTQ with treelet prefetching (design `vtq-prefetch`): the prefetcher beside the
/// treelet RT unit watches its rays in the ray-stationary phases, or in all; every ray is still
/// traced exactly, skipping idle cycles equals lockstep, and the popularity rule queues treelets
/// (never without the switch).
#[test]
fn vtq_with_treelet_prefetching_traces_every_ray_exactly() {
    let alone = check_against_functional("wknd", &cfg(VTQ, 2, 32, &[]));
    assert_eq!(alone.stats.prefetcher_treelets, 0);
    for watch in ["ray_stationary", "all"] {
        let switch = format!("mode.treelet_prefetch={watch}");
        let out = check_against_functional("wknd", &cfg(VTQ, 2, 32, &[&switch]));
        check_queue_stats(&out);
        assert!(out.stats.active_units.iter().any(|u| u == "prefetcher"));
        assert!(
            out.stats.prefetcher_treelets > 0,
            "{watch}: nothing prefetched"
        );
        check_skip_matches_lockstep(&cfg(VTQ, 2, 24, &[&switch]));
    }
}

/// Two runs of one configuration give identical statistics, images and ray logs.
#[test]
fn runs_are_deterministic() {
    let out = check_deterministic(&cfg(VTQ, 4, 16, &["bounces=2"]));
    assert!(out.stats.queues.counts.ctl.enqueued_rays > 0);
}

/// A warp buffer of several slots: SM warps, treelet warps, grouped and repacked warps share
/// it (reserved slots, appends into held slots), and still every ray is traced exactly once.
#[test]
fn a_wider_warp_buffer_traces_every_ray_exactly() {
    let c = cfg(VTQ, 1, 32, &["hw.warp_buffer_size=4"]);
    let out = check_against_functional("wknd", &c);
    check_queue_stats(&out);
    let (skip, _) = check_skip_matches_lockstep(&cfg(NAIVE, 1, 24, &["hw.warp_buffer_size=2"]));
    check_queue_stats(&skip);
}

/// Cycles in which a repack waits for rays (`queues.repack_starved_cycles`: a warp below the
/// threshold in the final phase, the queues and spare buffer empty) are counted in skipped idle
/// cycles as in stepped ones, and never without repacking or without a final phase.
#[test]
fn repacks_withheld_for_want_of_rays_count_in_skipped_cycles_too() {
    let (skip, lock) = check_skip_matches_lockstep(&cfg(VTQ, 2, 24, &[]));
    let starved = skip.stats.queues.counts.ctl.repack_starved_cycles;
    assert!(starved > 0, "no repack waited for rays");
    assert_eq!(starved, lock.stats.queues.counts.ctl.repack_starved_cycles);
    // Not more cycles than the SMs spent in the final phase (`phases` cycles are per SM).
    assert!(starved <= 2 * skip.stats.phases.ray_stationary.cycles);
    for off in [
        cfg(VTQ, 2, 24, &["hw.repack_threshold=0"]),
        cfg(NAIVE, 2, 24, &[]),
    ] {
        let (out, _) = check_skip_matches_lockstep(&off);
        assert_eq!(out.stats.queues.counts.ctl.repack_starved_cycles, 0);
    }
}

/// The warp costs' BVH loads go to the phase and warp kind of the cycle in which the L1 accepts
/// them, whether that cycle was stepped or skipped: a load still queued at the L1 port when a
/// stepped cycle ends the initial phase counts in the treelet-stationary phase in lockstep, and
/// so it must when the idle cycles after that step are skipped. The treelet-prefetching design
/// on a generated 20,000-triangle city at 32 x 32 has such a load (on the small built-in scenes
/// no mode change leaves one queued).
#[test]
fn bvh_loads_accepted_in_skipped_cycles_count_in_the_phase_lockstep_gives_them() {
    let design = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../configs/designs/vtq-prefetch-all/config.toml");
    let sets: Vec<String> = ["width=32", "height=32"].map(String::from).into();
    let cfg = vtq_sim::model::config::SimConfig::load(Some(&design), &sets).expect("design");
    let scene = vtq_sim::model::scene::load::load_scene("city:20000").expect("generated city");
    let bvh = vtq_sim::model::bvh::HwBvh::build(&scene, &cfg.bvh_params()).expect("BVH builds");
    let (skip, _) = common::check_scene_skip_matches_lockstep(&scene, &bvh, &cfg);
    let phases = skip.stats.warp_costs.as_ref().expect("warp costs");
    assert!(phases.treelet_stationary.sm.bvh_l1_accesses > 0);
}
