//! End-to-end tests of ray virtualization (paper sections 3.1, 4.1) in the `baseline` and
//! `prefetch` designs, on small images with one SM, so more CTAs exist than CTA slots and CTAs
//! are suspended and resumed: closest hits and the image equal the functional tracer's bit for
//! bit, every suspended CTA is resumed, the CTA-state traffic is exactly the saved state, the
//! ray budget `hw.max_rays` holds (and binds when small), skipping idle cycles changes nothing,
//! runs repeat exactly, and without virtualization nothing of it happens.

mod common;

use common::{
    check_against_functional, check_deterministic, check_same_results, check_skip_matches_lockstep,
    run, setup, small_config, STARVED_MEMORY,
};
use vtq_sim::model::config::SimConfig;
use vtq_sim::model::gpu::{simulate, SimError, SimOptions, SimOutput};

/// `mode` with ray virtualization on one SM, a `side` x `side` image, then `extra`.
fn virt_config(mode: &str, side: u32, extra: &[&str]) -> SimConfig {
    let mut sets = vec!["mode.virtualization=true"];
    sets.extend_from_slice(extra);
    small_config(mode, 1, side, &sets)
}

/// CTA slots x threads: the most rays an SM can have in flight without virtualization.
fn slot_rays(cfg: &SimConfig) -> u64 {
    cfg.gpu.max_ctas_per_sm as u64 * cfg.gpu.threads_per_cta as u64
}

/// The checks every virtualized run must pass: suspends and resumes balance, the CTA-state
/// class moved the saved state of every suspend and resume (32 B accesses bypassing the L1, the
/// last one of each CTA shorter), and the ray budget held.
fn check_virtualized(cfg: &SimConfig, out: &SimOutput) {
    let s = &out.stats;
    assert!(s.cta_suspends > 0, "no CTA was suspended");
    assert_eq!(s.cta_suspends, s.cta_resumes, "every suspended CTA resumes");
    assert!(s.active_units.iter().any(|u| u == "virtualization"));
    let per_cta = cfg.cta_state_bytes().div_ceil(32);
    let state = &s.memory.cta_state;
    assert_eq!(
        state.l1_bypasses,
        (s.cta_suspends + s.cta_resumes) * per_cta,
        "CTA-state accesses"
    );
    assert_eq!(state.l2_accesses, state.l1_bypasses);
    assert_eq!(
        (state.l1_loads, state.l1_stores),
        (0, 0),
        "state bypasses the L1"
    );
    assert!(s.max_rays_in_flight <= cfg.hw.max_rays as u64);
    assert_eq!(s.rays_issued, s.rays_completed);
}

#[test]
fn baseline_wknd_hits_and_image_equal_the_functional_tracer() {
    let cfg = virt_config("baseline", 48, &[]);
    let out = check_against_functional("wknd", &cfg);
    check_virtualized(&cfg, &out);
    // 36 CTAs share one SM of 16 slots: suspending lets more rays be in flight than the
    // slots' threads.
    assert!(out.stats.max_rays_in_flight > slot_rays(&cfg));
}

#[test]
fn prefetch_wknd_hits_and_image_equal_the_functional_tracer() {
    let cfg = virt_config("prefetch", 48, &[]);
    let out = check_against_functional("wknd", &cfg);
    check_virtualized(&cfg, &out);
    assert!(out.stats.prefetches_issued > 0);
    assert!(out.stats.active_units.iter().any(|u| u == "prefetcher"));
}

#[test]
fn baseline_cornell_with_bounces_hits_and_image_equal_the_functional_tracer() {
    // Triangles, three bounces: CTAs suspend again after later bounces.
    let cfg = virt_config("baseline", 32, &[]);
    let out = check_against_functional("cornell", &cfg);
    check_virtualized(&cfg, &out);
    assert!(
        out.stats.cta_suspends > out.stats.ctas,
        "CTAs suspend more than once"
    );
}

/// With one CTA slot and a budget of two CTAs' threads (the smallest power of two above the
/// slot's 64, as `hw.max_rays` must be), the second CTA launches while the first is suspended,
/// a third cannot: both CTAs' rays are in flight before the RT unit (one warp at a time)
/// finishes the first warp, so the bound is reached and never passed.
#[test]
fn a_small_ray_budget_binds() {
    let cfg = virt_config(
        "baseline",
        32,
        &["gpu.max_ctas_per_sm=1", "hw.max_rays=128"],
    );
    assert_eq!(slot_rays(&cfg), 64);
    let out = check_against_functional("wknd", &cfg);
    check_virtualized(&cfg, &out);
    assert_eq!(out.stats.max_rays_in_flight, 128);
    // Without virtualization the single slot's threads are the bound.
    let mut off = cfg.clone();
    off.mode.virtualization = false;
    let (scene, bvh) = setup("wknd", &off);
    let base = run(&scene, &bvh, &off);
    assert_eq!(base.stats.max_rays_in_flight, 64);
}

#[test]
fn baseline_skipping_idle_cycles_matches_lockstep() {
    let (skip, _) = check_skip_matches_lockstep(&virt_config("baseline", 48, &[]));
    assert!(skip.stats.cta_suspends > 0);
}

#[test]
fn prefetch_skipping_idle_cycles_matches_lockstep() {
    let (skip, _) = check_skip_matches_lockstep(&virt_config("prefetch", 48, &[]));
    assert!(skip.stats.cta_suspends > 0);
}

/// Two runs of one configuration give identical statistics, images and ray logs.
#[test]
fn runs_are_deterministic() {
    let out = check_deterministic(&small_config(
        "prefetch",
        3,
        32,
        &["mode.virtualization=true", "bounces=2"],
    ));
    assert!(out.stats.cta_suspends > 0);
}

/// Virtualization changes the timing (cycles, memory traffic) but not what is traced; without
/// it no CTA is suspended, no CTA state moves, and no SM has more rays in flight than its CTA
/// slots' threads.
#[test]
fn virtualization_changes_timing_not_results() {
    let on_cfg = virt_config("baseline", 48, &[]);
    let off_cfg = small_config("baseline", 1, 48, &[]);
    let (scene, bvh) = setup("wknd", &off_cfg);
    let on = run(&scene, &bvh, &on_cfg);
    let off = run(&scene, &bvh, &off_cfg);
    let s = &off.stats;
    assert_eq!((s.cta_suspends, s.cta_resumes), (0, 0));
    assert_eq!(s.memory.cta_state, Default::default());
    assert!(!s.active_units.iter().any(|u| u == "virtualization"));
    assert!(s.max_rays_in_flight <= slot_rays(&off_cfg));
    assert!(s.max_rays_in_flight > 0);
    assert_ne!(
        on.stats.cycles, off.stats.cycles,
        "virtualization had no effect"
    );
    assert_eq!(on.stats.ctas, off.stats.ctas);
    check_same_results(&on, &off);
}

/// A run stopped by the watchdog while CTAs are suspended lists them and the CTA-state port:
/// warps trace right after launch, so the CTAs suspend at once, and with one MSHR and a DRAM
/// moving one byte per cycle the RT unit then waits longer than the watchdog allows.
#[test]
fn watchdog_dump_lists_suspended_ctas() {
    let cfg = virt_config(
        "baseline",
        16,
        &[
            "gpu.max_ctas_per_sm=1",
            "hw.max_rays=128",
            "gpu.cta_launch_cycles=0",
            "gpu.raygen_cycles=1",
        ]
        .into_iter()
        .chain(STARVED_MEMORY)
        .collect::<Vec<_>>(),
    );
    let (scene, bvh) = setup("wknd", &cfg);
    let err = simulate(&scene, &bvh, &cfg, SimOptions::default(), None).unwrap_err();
    let SimError::Watchdog { dump, .. } = &err else {
        panic!("expected a watchdog error, got {err}");
    };
    for part in ["virtualization: suspending", "CTA-state port", "RT unit"] {
        assert!(dump.contains(part), "dump lacks {part}: {dump}");
    }
    assert!(
        !dump.contains("suspending [], suspended []"),
        "no CTA listed as suspended: {dump}"
    );
}
