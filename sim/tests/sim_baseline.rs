//! End-to-end tests of the cycle-exact GPU simulator in the baseline design, on small images of
//! the built-in scenes with 1-2 SMs and small caches: closest hits and the image equal the
//! functional tracer's bit for bit, skipping idle cycles changes nothing, runs repeat exactly,
//! and the watchdog stops a run that makes no progress.

use vtq_sim::bvh::HwBvh;
use vtq_sim::config::SimConfig;
use vtq_sim::geometry::Hit;
use vtq_sim::gpu::stats::comparable_json;
use vtq_sim::gpu::{simulate, SimError, SimOptions, SimOutput};
use vtq_sim::scene::load::load_scene;
use vtq_sim::scene::Scene;
use vtq_sim::traversal::{trace, Order};
use vtq_sim::workload::pathtracer::render;

/// A small GPU: `sms` SMs, a `side` x `side` image, 4 KB L1s, 16 KB L2, 2 KB treelets.
fn small_config(sms: u32, side: u32, extra: &[&str]) -> SimConfig {
    let mut sets: Vec<String> = [
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

/// Every ray's closest hit equals `traversal::trace`'s, every pixel traced exactly the rays of
/// the functional renderer in the same order, and the image is bit-identical.
fn check_against_functional(name: &str, sms: u32, side: u32) {
    let cfg = small_config(sms, side, &[]);
    let (scene, bvh) = setup(name, &cfg);
    let out = run(&scene, &bvh, &cfg);
    let reference = render(&scene, &bvh, &cfg.render_settings(), None).unwrap();

    assert_eq!(out.ray_log.len(), reference.rays.len(), "{name}: ray count");
    assert_eq!(out.stats.rays, reference.rays.len() as u64);
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
    let bits = |img: &[glam::Vec3]| -> Vec<[u32; 3]> {
        img.iter().map(|c| c.to_array().map(f32::to_bits)).collect()
    };
    assert_eq!(bits(&out.image), bits(&reference.image), "{name}: image");
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
}

#[test]
fn wknd_hits_and_image_equal_the_functional_tracer() {
    check_against_functional("wknd", 2, 32);
}

#[test]
fn cornell_hits_and_image_equal_the_functional_tracer() {
    check_against_functional("cornell", 1, 32);
}

/// Skipping idle cycles gives the same statistics and time series as stepping every cycle.
#[test]
fn skipping_idle_cycles_matches_lockstep() {
    let cfg = small_config(2, 32, &[]);
    let (scene, bvh) = setup("wknd", &cfg);
    let skip = run(&scene, &bvh, &cfg);
    let mut lock_cfg = cfg.clone();
    lock_cfg.sim.lockstep = true;
    let lock = run(&scene, &bvh, &lock_cfg);
    let strip = |o: &SimOutput| {
        let mut v = comparable_json(&o.stats);
        v.as_object_mut().unwrap().remove("config");
        v
    };
    assert_eq!(strip(&skip), strip(&lock));
    assert_eq!(skip.time_series, lock.time_series);
    assert!(!skip.time_series.is_empty());
    assert_eq!(lock.stats.stepped_cycles, lock.stats.cycles);
    assert!(
        skip.stats.stepped_cycles < skip.stats.cycles,
        "idle cycles were skipped"
    );
}

/// Two runs of one configuration give identical statistics, images and ray logs.
#[test]
fn runs_are_deterministic() {
    let cfg = small_config(2, 8, &["bounces=2"]);
    let (scene, bvh) = setup("cornell", &cfg);
    let a = run(&scene, &bvh, &cfg);
    let b = run(&scene, &bvh, &cfg);
    assert_eq!(comparable_json(&a.stats), comparable_json(&b.stats));
    assert_eq!(a.ray_log, b.ray_log);
    assert_eq!(a.image, b.image);
}

/// With one MSHR, one-cycle latencies and a DRAM moving one byte per cycle, every miss keeps
/// the RT unit waiting ~32 cycles with nothing issuing: a watchdog of 8 cycles stops the run
/// with a state dump of every component.
#[test]
fn watchdog_stops_a_run_without_progress() {
    let cfg = small_config(
        2,
        8,
        &[
            "memory.l1_latency=1",
            "memory.l2_latency=1",
            "memory.dram_latency=1",
            "memory.dram_bytes_per_cycle=1",
            "memory.l1_mshrs=1",
            "sim.watchdog_cycles=8",
        ],
    );
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

/// Designs this build does not simulate are refused with a clear error.
#[test]
fn other_modes_are_not_implemented_yet() {
    let cfg = small_config(1, 8, &["mode.kind=queues", "hw.repack_threshold=0"]);
    let (scene, bvh) = setup("cornell", &cfg);
    let err = simulate(&scene, &bvh, &cfg, SimOptions::default(), None).unwrap_err();
    assert!(matches!(err, SimError::NotImplemented(_)), "{err}");
    assert!(err.to_string().contains("mode.kind = \"queues\""), "{err}");
}
