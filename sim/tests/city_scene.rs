//! The generated `city:N` scene family: spec parsing and errors, exact triangle counts,
//! determinism, geometry quality and a BVH build.

use vtq_sim::model::bvh::{triangle_is_usable, BvhParams, HwBvh};
use vtq_sim::model::scene::builtin::builtin;
use vtq_sim::model::scene::city::{
    city, parse_spec, DEFAULT_TRIANGLES, MAX_TRIANGLES, MIN_TRIANGLES,
};
use vtq_sim::model::scene::load::load_scene;
use vtq_sim::model::scene::{Scene, SceneError};

/// Positions as bit patterns, for exact comparison.
fn position_bits(scene: &Scene) -> Vec<[u32; 3]> {
    scene
        .positions
        .iter()
        .map(|p| p.to_array().map(f32::to_bits))
        .collect()
}

#[test]
fn specs_parse_with_suffixes_and_case() {
    for (spec, n) in [
        ("city", DEFAULT_TRIANGLES),
        ("CITY", DEFAULT_TRIANGLES),
        ("city:1000", 1_000),
        ("city:250k", 250_000),
        ("City:250K", 250_000),
        ("city:4M", 4_000_000),
        ("city:4m", 4_000_000),
        ("city:64M", MAX_TRIANGLES),
        ("city:1k", MIN_TRIANGLES),
    ] {
        match parse_spec(spec) {
            Some(Ok(got)) => assert_eq!(got, n, "{spec}"),
            other => panic!("{spec}: {other:?}"),
        }
    }
    for not_city in ["cityscape", "cit", "wknd", "sponza", "ci", ""] {
        assert!(parse_spec(not_city).is_none(), "{not_city}");
    }
}

#[test]
fn bad_specs_are_one_line_errors_naming_the_spec() {
    for (spec, problem) in [
        ("city:", "no triangle budget"),
        ("city:0", "below the minimum"),
        ("city:999", "below the minimum"),
        ("city:abc", "not a triangle budget"),
        ("city:1.5M", "not a triangle budget"),
        ("city:k", "not a triangle budget"),
        ("city:-5", "not a triangle budget"),
        ("city:65M", "above the maximum"),
        ("city:99999999999", "above the maximum"),
        ("city:99999999999999999999999", "above the maximum"),
        ("city:99999999999999999M", "above the maximum"),
    ] {
        let err = match load_scene(spec) {
            Err(e @ SceneError::Parse { .. }) => e.to_string(),
            Err(other) => panic!("{spec}: wrong error kind {other:?}"),
            Ok(scene) => panic!("{spec}: loaded {}", scene.name),
        };
        assert!(err.contains(spec), "{spec}: {err}");
        assert!(err.contains(problem), "{spec}: {err}");
        assert!(!err.contains('\n'), "{spec}: {err}");
    }
}

#[test]
fn cities_have_exactly_their_budget_of_triangles() {
    for n in [1_000, 1_001, 9_999, 20_000, 33_333] {
        let scene = city(n);
        assert_eq!(scene.triangles.len(), n as usize, "city:{n}");
        assert_eq!(scene.tri_material.len(), n as usize);
        assert!(scene.spheres.is_empty() && scene.sky);
        scene.validate().expect("city validates");
    }
    let by_spec = builtin("city:20k").expect("a built-in").expect("loads");
    assert_eq!(by_spec.name, "city:20k");
    assert_eq!(by_spec.triangles.len(), 20_000);
}

#[test]
fn generation_is_deterministic() {
    let a = city(20_000);
    let b = load_scene("CITY:20K").expect("loads");
    assert_eq!(a.name, b.name);
    assert_eq!(position_bits(&a), position_bits(&b));
    assert_eq!(a.triangles, b.triangles);
    assert_eq!(a.tri_material, b.tri_material);
    assert_eq!(a.materials, b.materials);
    assert_eq!(a.camera, b.camera);
    // A different budget is a different city.
    assert_ne!(a.triangles.len(), city(20_002).triangles.len());
}

#[test]
fn no_degenerate_or_unused_geometry() {
    for n in [1_001, 20_000] {
        let scene = city(n);
        let degenerate = (0..scene.triangles.len())
            .filter(|&i| !triangle_is_usable(scene.triangle(i)))
            .count();
        assert_eq!(degenerate, 0, "city:{n}");
        let mut used = vec![false; scene.positions.len()];
        for t in &scene.triangles {
            for &v in t {
                used[v as usize] = true;
            }
        }
        assert!(used.iter().all(|&u| u), "city:{n} has unused vertices");
        // Vertices are shared: fewer vertices than triangle corners.
        assert!(scene.positions.len() < scene.triangles.len() * 3 / 2);
        // Several materials, some of them metal (glass).
        let metal = scene
            .tri_material
            .iter()
            .filter(|&&m| {
                matches!(
                    scene.materials[m as usize],
                    vtq_sim::model::scene::Material::Metal { .. }
                )
            })
            .count();
        assert!(metal > 0 && metal < scene.triangles.len() / 2, "{metal}");
    }
}

#[test]
fn a_mid_size_city_builds_a_treelet_bvh() {
    let scene = city(50_000);
    let bvh = HwBvh::build(&scene, &BvhParams::default()).expect("BVH builds");
    let stats = bvh.stats();
    assert_eq!(stats.triangle_leaves, 50_000);
    assert_eq!(stats.excluded_prims, 0);
    // Packed treelets (the default): hundreds of nearly full 8 KB slots.
    assert!(stats.treelets > 500, "{stats:?}");
    assert!(stats.treelet_fill > 0.8, "{stats:?}");
    assert!(stats.bvh_bytes > 4_000_000, "{stats:?}");
    // The camera looks at the city: its view direction points into the scene bounds.
    let (lo, hi) = scene.bounds().expect("bounds");
    let cam = scene.camera;
    assert!(cam.look_at.cmpge(lo).all() && cam.look_at.cmple(hi).all());
}

/// The BVH build runs on rayon's threads (`obvhs`'s parallel PLOC, Morton sort and reinsertion,
/// whose parallel paths start at 300-500 thousand primitives); its tree must not depend on how
/// many threads there are, or a BVH built on a 2-core machine would differ from one built on a
/// cluster node, and with it every cycle count.
#[test]
fn the_parallel_build_is_identical_on_any_number_of_threads() {
    let scene = city(600_000);
    let build = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool")
            .install(|| HwBvh::build(&scene, &BvhParams::default()).expect("BVH builds"))
            .to_bytes()
    };
    let one = build(1);
    for threads in [2, 3, 16] {
        assert!(build(threads) == one, "{threads} threads built another BVH");
    }
}
