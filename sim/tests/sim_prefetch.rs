//! End-to-end tests of the `prefetch` design (the treelet prefetcher of Chou et al., MICRO 2023)
//! on small images of the built-in scenes with 1-2 SMs and 4 KB L1s holding two 2 KB treelets,
//! so prefetching matters: closest hits and the image equal the functional tracer's bit for
//! bit, skipping idle cycles changes nothing, runs repeat exactly, and the prefetcher issues
//! prefetches that change the timing but not the rays.

mod common;

use common::{
    check_against_functional, check_deterministic, check_same_results, check_skip_matches_lockstep,
    run, setup, small_config,
};

/// In prefetch mode every ray's closest hit equals `traversal::trace`'s, every pixel traced
/// the functional renderer's rays in order, the image is bit-identical, and the prefetcher
/// both fetched sectors and saw some of them used by demand loads.
fn check_prefetch(name: &str, sms: u32, side: u32) {
    let out = check_against_functional(name, &small_config("prefetch", sms, side, &[]));
    let s = &out.stats;
    assert_eq!(s.mode, "prefetch");
    assert!(s.active_units.iter().any(|u| u == "prefetcher"));
    assert!(s.prefetches_issued > 0, "{name}: no prefetch issued");
    assert!(s.prefetches_used > 0, "{name}: no prefetch used");
    assert!(s.prefetches_used + s.prefetches_unused_evicted <= s.prefetches_issued);
    assert_eq!(s.prefetches_issued, s.memory.prefetch.issued);
    // Prefetches stay out of the demand counters: every RT-unit node load is one L1 lookup.
    assert_eq!(s.rt.load_requests, s.bvh_l1_accesses);
}

#[test]
fn wknd_hits_and_image_equal_the_functional_tracer() {
    check_prefetch("wknd", 2, 32);
}

#[test]
fn cornell_hits_and_image_equal_the_functional_tracer() {
    check_prefetch("cornell", 1, 32);
}

/// Skipping idle cycles gives the same statistics and time series as stepping every cycle
/// while prefetches are queued.
#[test]
fn skipping_idle_cycles_matches_lockstep() {
    let (skip, _) = check_skip_matches_lockstep(&small_config("prefetch", 2, 32, &[]));
    assert!(skip.stats.prefetches_issued > 0);
}

/// Two runs of one configuration give identical statistics, images and ray logs.
#[test]
fn runs_are_deterministic() {
    check_deterministic(&small_config("prefetch", 4, 16, &["bounces=2"]));
}

/// The prefetcher changes the timing (cycles, L1 behaviour) but not what is traced: the same
/// rays with the same hits and the same image as the baseline, which issues no prefetch.
#[test]
fn prefetching_changes_timing_not_results() {
    let base_cfg = small_config("baseline", 1, 32, &[]);
    let pf_cfg = small_config("prefetch", 1, 32, &[]);
    let (scene, bvh) = setup("wknd", &base_cfg);
    let base = run(&scene, &bvh, &base_cfg);
    let pf = run(&scene, &bvh, &pf_cfg);
    assert_eq!(base.stats.prefetches_issued, 0);
    assert!(!base.stats.active_units.iter().any(|u| u == "prefetcher"));
    assert!(pf.stats.prefetches_issued > 0);
    assert_ne!(
        base.stats.cycles, pf.stats.cycles,
        "prefetching had no effect"
    );
    check_same_results(&base, &pf);
}
