//! End-to-end tests of the workloads beyond the path tracer (`[workload]` `kind`): ambient
//! occlusion's occlusion rays and next-event estimation's shadow rays go through every design's RT unit with the terminate-on-first-hit
//! flag; each design's image equals the functional renderer's bit for bit (so the designs'
//! images are identical), each occlusion ray's answer is whether its closest-hit twin hits,
//! the treelet queues park and resume occlusion rays, skipping idle cycles changes nothing, and
//! bad workload keys are clear errors; a ray file (CSV or binary) written from a render replays
//! ray by ray, in file order, in every design; a hybrid frame traces the path tracer's rays
//! but its primary rays, with the path tracer's image, threads with nothing to trace included.

mod common;

use common::{
    check_against_functional, check_skip_matches_lockstep, small_config, small_vtq, strip,
};
use vtq_sim::model::bvh::HwBvh;
use vtq_sim::model::config::SimConfig;
use vtq_sim::model::gpu::SimOutput;
use vtq_sim::model::scene::load::load_scene;
use vtq_sim::model::workload::kind::TraceRay;
use vtq_sim::model::workload::pathtracer::render;
use vtq_sim::model::workload::ray_file::write_ray_file;

const AO: &[&str] = &["workload.kind=ao", "workload.ao_rays=3"];

/// Checks an AO run traced occlusion rays and counted them.
fn check_ao(out: &SimOutput, what: &str) {
    let s = &out.stats;
    assert!(s.occlusion_rays > 0, "{what}: occlusion rays traced");
    assert!(s.occlusion_rays < s.rays, "{what}: primary rays too");
    let logged = out.ray_log.iter().filter(|r| r.occlusion).count() as u64;
    assert_eq!(logged, s.occlusion_rays, "{what}: occlusion rays counted");
    let hit = out
        .ray_log
        .iter()
        .filter(|r| r.occlusion && r.hit.is_some());
    assert!(hit.count() > 0, "{what}: some occlusion ray is occluded");
}

#[test]
fn ao_images_equal_the_functional_renderer_in_every_design() {
    let mut images = Vec::new();
    for (mode, scene, side) in [
        ("baseline", "wknd", 24),
        ("prefetch", "wknd", 24),
        ("baseline", "cornell", 16),
    ] {
        let out = check_against_functional(scene, &small_config(mode, 2, side, AO));
        check_ao(&out, mode);
        if scene == "wknd" {
            images.push(out.image);
        }
    }
    let out = check_against_functional("wknd", &small_vtq(2, 24, AO));
    check_ao(&out, "vtq");
    let q = &out.stats.queues.counts;
    assert!(q.ctl.terminated_warps > 0 && q.ctl.enqueued_rays > 0);
    assert_eq!(q.ray_loads, q.ctl.enqueued_rays);
    images.push(out.image);
    assert!(images.windows(2).all(|w| w[0] == w[1]));
}

#[test]
fn path_nee_images_equal_the_functional_renderer_in_every_design() {
    // cornell's light is an emitting quad, so every diffuse hit sends a shadow ray.
    let nee = &["workload.kind=path-nee"];
    let base = check_against_functional("cornell", &small_config("baseline", 2, 16, nee));
    check_ao(&base, "path-nee baseline");
    let vtq = check_against_functional("cornell", &small_vtq(2, 16, nee));
    check_ao(&vtq, "path-nee vtq");
    assert_eq!(base.image, vtq.image);
    // The paths are the path tracer's, the shadow rays come on top.
    let path = check_against_functional("cornell", &small_config("baseline", 2, 16, &[]));
    assert_eq!(base.stats.rays - base.stats.occlusion_rays, path.stats.rays);
    // wknd has no emitting triangle: its light is the sky, and the shadow rays sample it.
    let wknd = check_against_functional("wknd", &small_vtq(2, 16, nee));
    check_ao(&wknd, "path-nee wknd");
    let plain = check_against_functional("wknd", &small_config("baseline", 2, 16, &[]));
    assert_eq!(
        wknd.stats.rays - wknd.stats.occlusion_rays,
        plain.stats.rays
    );
}

#[test]
fn the_path_workload_is_the_default_and_traces_no_occlusion_ray() {
    let out = check_against_functional("cornell", &small_config("baseline", 1, 12, &[]));
    assert_eq!(out.stats.occlusion_rays, 0);
    assert!(out.ray_log.iter().all(|r| !r.occlusion));
}

#[test]
fn ao_skipping_idle_cycles_matches_lockstep() {
    let (skip, _) = check_skip_matches_lockstep(&small_vtq(2, 16, AO));
    check_ao(&skip, "vtq skip");
    let (skip, lock) = check_skip_matches_lockstep(&small_config("baseline", 2, 16, AO));
    assert_eq!(strip(&skip), strip(&lock));
}

const HYBRID: &[&str] = &["workload.kind=hybrid"];

#[test]
fn a_hybrid_frame_traces_the_path_tracers_rays_but_its_primaries_with_the_same_image() {
    // wknd's sky and cornell's light end paths at their primary hit: those pixels' threads
    // trace nothing (with 2 spp, some trace one sample only).
    for (scene, spp) in [("wknd", "spp=2"), ("cornell", "spp=1")] {
        let extra: Vec<&str> = HYBRID.iter().copied().chain([spp]).collect();
        let (scene_data, bvh) = common::setup(scene, &small_config("baseline", 2, 16, &extra));
        let settings = small_config("baseline", 2, 16, &extra).render_settings();
        let hybrid = render(&scene_data, &bvh, &settings, None).unwrap();
        let mut path_settings = settings.clone();
        path_settings.kind = Default::default();
        let path = render(&scene_data, &bvh, &path_settings, None).unwrap();
        assert_eq!(hybrid.image, path.image, "{scene}: the path tracer's image");
        let primaries = (settings.pixels() as u32 * settings.spp) as usize;
        assert_eq!(hybrid.rays.len(), path.rays.len() - primaries, "{scene}");
        let idle = (0..settings.pixels())
            .filter(|&p| hybrid.pixel_rays(p).is_empty())
            .count();
        assert!(idle > 0, "{scene}: some thread traces nothing");
        // Each pixel's traced rays are its path rays less each sample's first.
        for p in 0..settings.pixels() {
            let (traced, all) = (hybrid.pixel_rays(p), path.pixel_rays(p));
            assert_eq!(
                traced.len() + settings.spp as usize,
                all.len(),
                "{scene} {p}"
            );
            if settings.spp == 1 {
                assert_eq!(traced, &all[1..], "{scene}: rays of pixel {p}");
            }
        }
        let mut images = Vec::new();
        for cfg in [
            small_config("baseline", 2, 16, &extra),
            small_config("prefetch", 2, 16, &extra),
            small_vtq(2, 16, &extra),
        ] {
            let out = check_against_functional(scene, &cfg);
            assert_eq!(out.stats.rays, hybrid.rays.len() as u64);
            assert_eq!(out.stats.occlusion_rays, 0);
            images.push(out.image);
        }
        assert!(images.windows(2).all(|w| w[0] == w[1]), "{scene}");
    }
}

#[test]
fn hybrid_skipping_idle_cycles_matches_lockstep() {
    let (skip, lock) = check_skip_matches_lockstep(&small_vtq(2, 16, HYBRID));
    assert_eq!(strip(&skip), strip(&lock));
    let (skip, lock) = check_skip_matches_lockstep(&small_config("baseline", 2, 16, HYBRID));
    assert_eq!(strip(&skip), strip(&lock));
}

#[test]
fn bad_workload_keys_are_errors_naming_the_key() {
    for (set, key) in [
        ("workload.kind=whitted", "workload.kind"),
        ("workload.ao_rays=0", "workload.ao_rays"),
        ("workload.ao_rays=65", "workload.ao_rays"),
        ("workload.ao_radius=0", "workload.ao_radius"),
        ("workload.ao_radius=1.5", "workload.ao_radius"),
        ("workload.ao_radius=nan", "workload.ao_radius"),
        ("workload.kind=rays", "workload.rays_file"),
        (
            "workload.kind=hybrid\nworkload.bounces=0",
            "workload.bounces",
        ),
        (
            "workload.kind=rays\nworkload.rays_file=\"/nonexistent/rays.csv\"",
            "/nonexistent/rays.csv: No such file",
        ),
    ] {
        let sets: Vec<String> = set.lines().map(str::to_string).collect();
        let err = SimConfig::load(None, &sets).unwrap_err();
        assert!(err.to_string().contains(key), "{set}: {err}");
    }
}

/// The rays of a functional AO render of cornell (closest-hit and occlusion), written to
/// `dir` as CSV and binary ray files; returns the rays and the two paths.
fn ray_files(dir: &std::path::Path) -> (Vec<TraceRay>, [String; 2]) {
    let cfg = small_config("baseline", 1, 12, AO);
    let scene = load_scene("cornell").unwrap();
    let bvh = HwBvh::build(&scene, &cfg.bvh_params()).unwrap();
    let rays = render(&scene, &bvh, &cfg.render_settings(), None)
        .unwrap()
        .trace_rays();
    std::fs::create_dir_all(dir).unwrap();
    let paths = ["rays.csv", "rays.bin"].map(|f| dir.join(f).to_str().unwrap().to_string());
    for p in &paths {
        write_ray_file(std::path::Path::new(p), &rays).unwrap();
    }
    (rays, paths)
}

#[test]
fn a_ray_file_replays_in_file_order_in_every_design_from_csv_or_binary() {
    let dir = std::env::temp_dir().join(format!("vtq-rays-{}", std::process::id()));
    let (rays, [csv, bin]) = ray_files(&dir);
    assert!(rays.iter().any(|r| r.occlusion) && rays.iter().any(|r| !r.occlusion));
    let mut outs = Vec::new();
    for (mode, file) in [("baseline", &csv), ("prefetch", &bin), ("baseline", &bin)] {
        let sets = [
            "workload.kind=rays".to_string(),
            format!("workload.rays_file={file:?}"),
        ];
        let sets: Vec<&str> = sets.iter().map(String::as_str).collect();
        let cfg = small_config(mode, 2, 8, &sets);
        assert_eq!(
            (cfg.workload.width, cfg.workload.height),
            (rays.len() as u32, 1)
        );
        let out = check_against_functional("cornell", &cfg);
        assert_eq!(out.stats.rays, rays.len() as u64);
        let occlusion = rays.iter().filter(|r| r.occlusion).count() as u64;
        assert_eq!(out.stats.occlusion_rays, occlusion);
        // Each pixel traced its ray of the file, flag included.
        for r in &out.ray_log {
            let want = rays[r.pixel as usize];
            assert_eq!((r.ray, r.occlusion), (want.ray, want.occlusion));
        }
        outs.push(out);
    }
    let sets = [
        "workload.kind=rays".to_string(),
        format!("workload.rays_file={bin:?}"),
    ];
    let sets: Vec<&str> = sets.iter().map(String::as_str).collect();
    let out = check_against_functional("cornell", &small_vtq(2, 8, &sets));
    assert!(out.stats.queues.counts.ctl.enqueued_rays > 0);
    outs.push(out);
    assert!(outs.windows(2).all(|w| w[0].image == w[1].image));
    // The same rays from either form: the same run.
    assert_eq!(strip(&outs[0]), strip(&outs[2]));
    assert_eq!(outs[0].ray_log, outs[2].ray_log);
    let _ = std::fs::remove_dir_all(&dir);
}
