//! End-to-end tests of the `prefetch` design (the treelet prefetcher of Chou et al., MICRO 2023)
//! on small images of the built-in scenes with 1-2 SMs and 4 KB L1s holding two 2 KB treelets,
//! so prefetching matters: closest hits and the image equal the functional tracer's bit for
//! bit, skipping idle cycles changes nothing, runs repeat exactly, and the prefetcher issues
//! prefetches that change the timing but not the rays.

use vtq_sim::bvh::HwBvh;
use vtq_sim::config::SimConfig;
use vtq_sim::geometry::Hit;
use vtq_sim::gpu::stats::comparable_json;
use vtq_sim::gpu::{simulate, SimOptions, SimOutput};
use vtq_sim::scene::load::load_scene;
use vtq_sim::scene::Scene;
use vtq_sim::traversal::{trace, Order};
use vtq_sim::workload::pathtracer::render;

/// A small GPU in `mode` (`baseline` or `prefetch`): `sms` SMs, a `side` x `side` image, 4 KB
/// L1s, 16 KB L2, 2 KB treelets.
fn small_config(mode: &str, sms: u32, side: u32, extra: &[&str]) -> SimConfig {
    let mut sets: Vec<String> = [
        format!("mode.kind={mode}"),
        format!("gpu.sms={sms}"),
        format!("width={side}"),
        format!("height={side}"),
        "memory.l1_bytes=4096".into(),
        "memory.l2_bytes=16384".into(),
        "hw.treelet_bytes=2048".into(),
        "sim.sample_interval=500".into(),
    ]
    .into();
    sets.extend(extra.iter().map(|s| s.to_string()));
    SimConfig::load(None, &sets).expect("valid test configuration")
}

fn setup(name: &str, cfg: &SimConfig) -> (Scene, HwBvh) {
    let scene = load_scene(name).expect("built-in scene");
    let bvh = HwBvh::build(&scene, &cfg.bvh_params()).expect("BVH builds");
    (scene, bvh)
}

fn run(scene: &Scene, bvh: &HwBvh, cfg: &SimConfig) -> SimOutput {
    simulate(scene, bvh, cfg, SimOptions { record_rays: true }, None).expect("simulation runs")
}

fn hit_bits(h: Option<Hit>) -> Option<(u32, u32, u32, u32)> {
    h.map(|h| (h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()))
}

fn image_bits(img: &[glam::Vec3]) -> Vec<[u32; 3]> {
    img.iter().map(|c| c.to_array().map(f32::to_bits)).collect()
}

/// Statistics without host-dependent keys and the configuration text.
fn strip(o: &SimOutput) -> serde_json::Value {
    let mut v = comparable_json(&o.stats);
    v.as_object_mut().unwrap().remove("config");
    v
}

/// In prefetch mode every ray's closest hit equals `traversal::trace`'s, every pixel traced
/// the functional renderer's rays in order, the image is bit-identical, and the prefetcher
/// both fetched sectors and saw some of them used by demand loads.
fn check_against_functional(name: &str, sms: u32, side: u32) {
    let cfg = small_config("prefetch", sms, side, &[]);
    let (scene, bvh) = setup(name, &cfg);
    let out = run(&scene, &bvh, &cfg);
    let reference = render(&scene, &bvh, &cfg.render_settings(), None).unwrap();

    assert_eq!(out.ray_log.len(), reference.rays.len(), "{name}: ray count");
    assert_eq!(out.stats.rays_issued, out.stats.rays_completed);
    let mut per_pixel: Vec<Vec<_>> = vec![Vec::new(); reference.image.len()];
    for r in &out.ray_log {
        assert_eq!(
            hit_bits(r.hit),
            hit_bits(trace(&bvh, &r.ray, Order::RayStationary)),
            "{name}: closest hit of {:?}",
            r.ray
        );
        per_pixel[r.pixel as usize].push(r.ray);
    }
    for (p, rays) in per_pixel.iter().enumerate() {
        assert_eq!(
            rays.as_slice(),
            reference.pixel_rays(p),
            "{name}: rays of pixel {p}"
        );
    }
    assert_eq!(
        image_bits(&out.image),
        image_bits(&reference.image),
        "{name}: image"
    );
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
    check_against_functional("wknd", 2, 32);
}

#[test]
fn cornell_hits_and_image_equal_the_functional_tracer() {
    check_against_functional("cornell", 1, 32);
}

/// Skipping idle cycles gives the same statistics and time series as stepping every cycle
/// while prefetches are queued.
#[test]
fn skipping_idle_cycles_matches_lockstep() {
    let cfg = small_config("prefetch", 2, 32, &[]);
    let (scene, bvh) = setup("wknd", &cfg);
    let skip = run(&scene, &bvh, &cfg);
    let mut lock_cfg = cfg.clone();
    lock_cfg.sim.lockstep = true;
    let lock = run(&scene, &bvh, &lock_cfg);
    assert_eq!(strip(&skip), strip(&lock));
    assert_eq!(skip.time_series, lock.time_series);
    assert!(skip.stats.prefetches_issued > 0);
    assert!(
        skip.stats.stepped_cycles < skip.stats.cycles,
        "idle cycles were skipped"
    );
}

/// Two runs of one configuration give identical statistics, images and ray logs.
#[test]
fn runs_are_deterministic() {
    let cfg = small_config("prefetch", 2, 16, &["bounces=2"]);
    let (scene, bvh) = setup("cornell", &cfg);
    let a = run(&scene, &bvh, &cfg);
    let b = run(&scene, &bvh, &cfg);
    assert_eq!(comparable_json(&a.stats), comparable_json(&b.stats));
    assert_eq!(a.ray_log, b.ray_log);
    assert_eq!(a.image, b.image);
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
    assert_eq!(base.stats.rays, pf.stats.rays);
    assert_eq!(base.stats.rays_hit, pf.stats.rays_hit);
    assert_eq!(image_bits(&base.image), image_bits(&pf.image));
    let sorted = |o: &SimOutput| {
        let mut v: Vec<_> = o
            .ray_log
            .iter()
            .map(|r| (r.pixel, hit_bits(r.hit)))
            .collect();
        v.sort_unstable();
        v
    };
    assert_eq!(sorted(&base), sorted(&pf));
}
