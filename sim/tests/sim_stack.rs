//! The RT unit's short on-chip traversal stacks (`hw.stack_depth`) spill to memory and fill
//! back on demand, so no scene overflows them: on a deep BVH built here with an 8-entry stack,
//! every design of `configs/designs/` spills and still returns the functional tracer's closest
//! hits and image, skipping idle cycles still equals lockstep, and a stack deep enough never to
//! spill gives the same statistics as a deeper one.

mod common;

use std::path::Path;

use common::{check_scene_against_functional, check_scene_skip_matches_lockstep, run, strip};
use glam::Vec3;
use vtq_sim::model::bvh::HwBvh;
use vtq_sim::model::config::SimConfig;
use vtq_sim::model::gpu::SimOutput;
use vtq_sim::{Material, Scene};

/// Nested open boxes around the camera: shell `k` is a cube of half-size `1.35^k` (five faces
/// of two triangles each, the -Z face open), `shells` of them, the two innermost emissive. A ray from the centre is inside every
/// shell's bounds, so its traversal goes down through the whole nest: a deep BVH with many
/// children hit at every level.
fn nested_shells(shells: u32) -> Scene {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    let mut tri_material = Vec::new();
    for k in 0..shells {
        let h = 1.35f32.powi(k as i32);
        let base = positions.len() as u32;
        for i in 0..8u32 {
            let pick = |bit: u32| if i & bit != 0 { h } else { -h };
            positions.push(Vec3::new(pick(1), pick(2), pick(4)));
        }
        let c = |i: u32| base + i;
        // Faces x-, x+, y-, y+, z+ (the z- face is open).
        for q in [
            [0, 2, 6, 4],
            [1, 5, 7, 3],
            [0, 4, 5, 1],
            [2, 3, 7, 6],
            [4, 6, 7, 5],
        ] {
            triangles.push([c(q[0]), c(q[1]), c(q[2])]);
            triangles.push([c(q[0]), c(q[2]), c(q[3])]);
            let m = if k < 2 { 2 } else { 1 };
            tri_material.extend([m, m]);
        }
    }
    Scene {
        name: "nested_shells".into(),
        positions,
        triangles,
        tri_material,
        spheres: Vec::new(),
        materials: vec![
            Material::DEFAULT,
            Material::Lambertian {
                albedo: Vec3::new(0.7, 0.6, 0.5),
            },
            Material::Light {
                emit: Vec3::splat(4.0),
            },
        ],
        camera: vtq_sim::model::scene::Camera {
            eye: Vec3::new(0.1, 0.2, -0.3),
            look_at: Vec3::new(0.3, 0.1, 1.0),
            up: Vec3::Y,
            fov_y_deg: 100.0,
        },
        sky: false,
    }
}

/// The configuration of design `name` (`configs/designs/<name>/config.toml`), on a small GPU
/// (2 SMs, `side` x `side` pixels, 2 KB treelets so the nest spans many treelets, small
/// caches; for the queue designs thresholds a small image reaches), then `extra`.
fn config(name: &str, side: u32, extra: &[&str]) -> SimConfig {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../configs/designs")
        .join(name)
        .join("config.toml");
    let mut sets: Vec<String> = [
        "gpu.sms=2".to_string(),
        format!("width={side}"),
        format!("height={side}"),
        "memory.l1_bytes=4096".into(),
        "memory.l2_bytes=16384".into(),
        "hw.treelet_bytes=2048".into(),
        "sim.sample_interval=500".into(),
    ]
    .into();
    if name.starts_with("queues") || name == "vtq" {
        sets.push("hw.divergence_threshold=2".into());
        sets.push("hw.underpopulation_threshold=8".into());
    }
    sets.extend(extra.iter().map(|s| s.to_string()));
    SimConfig::load(Some(&path), &sets).expect("valid test configuration")
}

/// Every design of `configs/designs/`, by name.
fn config_names() -> Vec<String> {
    vtq_sim::model::designs::BUILT_INS
        .iter()
        .map(|b| b.name.to_string())
        .collect()
}

#[test]
fn the_nest_is_deeper_than_a_short_stack() {
    let scene = nested_shells(40);
    let cfg = config("baseline", 8, &[]);
    let bvh = HwBvh::build(&scene, &cfg.bvh_params()).unwrap();
    let depth = bvh.stats().depth;
    assert!(depth >= 12, "BVH depth {depth}");
}

#[test]
fn every_design_spills_a_short_stack_and_keeps_exact_hits() {
    let scene = nested_shells(40);
    let names = config_names();
    // Every design, every variant of the paper's experiments (configs/experiments/ are sweep
    // specifications, not configurations).
    for design in ["baseline", "prefetch", "vtq"] {
        assert!(names.iter().any(|n| n == design), "{names:?}");
    }
    assert!(names.len() >= 8, "{names:?}");
    for name in &names {
        let cfg = config(name, 20, &["hw.stack_depth=8"]);
        let bvh = HwBvh::build(&scene, &cfg.bvh_params()).unwrap();
        let out = check_scene_against_functional(&scene, &bvh, &cfg);
        let rt = &out.stats.rt;
        assert!(
            rt.stack_spills > 0,
            "{name}: no spill with an 8-entry stack"
        );
        assert_eq!(
            rt.stack_fills, rt.stack_spills,
            "{name}: every spilled chunk comes back before its ray finishes"
        );
        let stack = &out.stats.memory.stack;
        assert_eq!(
            stack.l1_stores, rt.stack_spills,
            "{name}: spills are 32 B stores"
        );
        assert_eq!(
            stack.l1_loads, rt.stack_fills,
            "{name}: fills are 32 B loads through the L1"
        );
        check_scene_skip_matches_lockstep(&scene, &bvh, &cfg);
    }
}

#[test]
fn a_stack_that_never_spills_gives_the_same_statistics_as_a_deeper_one() {
    let scene = nested_shells(40);
    for name in config_names() {
        // Records carry whole stacks (`record_stack_entries` = the depth): parked rays keep
        // theirs, so nothing spills.
        let runs: Vec<SimOutput> = [128, 1024]
            .iter()
            .map(|d| {
                let depth = format!("hw.stack_depth={d}");
                let record = format!("hw.record_stack_entries={d}");
                let cfg = config(&name, 16, &[&depth, &record]);
                let bvh = HwBvh::build(&scene, &cfg.bvh_params()).unwrap();
                run(&scene, &bvh, &cfg)
            })
            .collect();
        assert_eq!(runs[0].stats.rt.stack_spills, 0, "{name}");
        assert_eq!(strip(&runs[0]), strip(&runs[1]), "{name}");
        assert_eq!(runs[0].time_series, runs[1].time_series, "{name}");
    }
}

#[test]
fn a_ray_outgrowing_its_spill_area_is_named_in_words() {
    let scene = nested_shells(40);
    // The smallest address space that holds the BVH, the records and at least one spill chunk
    // per ray stack: too small for this nest's stacks.
    for bits in 16..=24 {
        let cfg = config(
            "baseline",
            8,
            &[
                "hw.stack_depth=8",
                "hw.max_rays=128",
                &format!("hw.address_bits={bits}"),
            ],
        );
        let bvh = HwBvh::build(&scene, &cfg.bvh_params()).unwrap();
        let err = vtq_sim::model::gpu::simulate(&scene, &bvh, &cfg, Default::default(), None);
        match err {
            Err(vtq_sim::model::gpu::SimError::Setup(msg)) => {
                assert!(msg.contains("hw.address_bits"), "{msg}");
                continue;
            }
            Err(e) => {
                let msg = e.to_string();
                for needle in [
                    "RT unit of SM ",
                    "outgrew its spill area",
                    "ray ",
                    "SM warp ",
                    "lane ",
                    "pixel (",
                    "spilled 32 B chunks",
                    "but its spill area holds ",
                    &format!("hw.address_bits, now {bits}"),
                ] {
                    assert!(msg.contains(needle), "{needle:?} missing from: {msg}");
                }
                assert!(!msg.contains('\n'), "one line: {msg}");
                return;
            }
            Ok(out) => panic!(
                "{bits}-bit addresses: ran with {} spill chunks per stack",
                out.stats.stack_spill_chunks
            ),
        }
    }
    panic!("no address width between 16 and 24 bits held the setup");
}
