//! Property tests of the hardware BVH: layout and treelet invariants, conservative
//! quantization, both traversal orders against a brute-force closest-hit search, and the cache.

mod common;

use std::collections::BTreeSet;
use std::path::PathBuf;

use glam::Vec3;
use proptest::prelude::*;
use vtq_sim::model::bvh::layout::{decode_sphere, decode_triangle, InternalView};
use vtq_sim::model::bvh::{
    build_cached, sphere_bounds, sphere_is_usable, triangle_bounds, triangle_is_usable, BvhParams,
    CacheOutcome, HwBvh, NodeKind, TreeletFormation,
};
use vtq_sim::model::intersect::{ray_sphere, ray_triangle, RayPrecomp};
use vtq_sim::model::traversal::{
    trace, trace_occlusion, trace_occlusion_with_fetches, trace_with_fetches, Order, TraversalState,
};
use vtq_sim::{Hit, Ray, Scene, Sphere};

use common::meshes::{icosphere, mesh_scene};

/// Closest hit over every usable primitive with the same routines and tie rule as traversal.
fn brute_force(scene: &Scene, ray: &Ray) -> Option<Hit> {
    if !ray.is_valid() {
        return None;
    }
    let pre = RayPrecomp::new(ray);
    let mut best: Option<Hit> = None;
    let mut offer = |h: Hit| {
        if best.is_none_or(|b| h.t < b.t || (h.t == b.t && h.prim < b.prim)) {
            best = Some(h);
        }
    };
    for i in 0..scene.triangles.len() {
        let v = scene.triangle(i);
        if !triangle_is_usable(v) {
            continue;
        }
        if let Some((t, u, w)) = ray_triangle(&pre, v, ray.tmin, ray.tmax) {
            offer(Hit {
                t,
                prim: i as u32,
                u,
                v: w,
            });
        }
    }
    for (i, s) in scene.spheres.iter().enumerate() {
        if !sphere_is_usable(s) {
            continue;
        }
        if let Some(t) = ray_sphere(ray, s.center, s.radius, ray.tmin, ray.tmax) {
            offer(Hit {
                t,
                prim: (scene.triangles.len() + i) as u32,
                u: 0.0,
                v: 0.0,
            });
        }
    }
    best
}

/// Exact bounds of the subtree at `addr`, computed from the leaves' geometry.
fn exact_box(bvh: &HwBvh, addr: u32, kind: NodeKind) -> (Vec3, Vec3) {
    let bytes = bvh.node_bytes(addr).expect("node address");
    match kind {
        NodeKind::TriangleLeaf => triangle_bounds(decode_triangle(bytes).0),
        NodeKind::ProceduralLeaf => {
            let (c, r, _) = decode_sphere(bytes);
            sphere_bounds(c, r)
        }
        NodeKind::Internal => {
            let view = InternalView::new(bytes).expect("internal node");
            let mut lo = Vec3::INFINITY;
            let mut hi = Vec3::NEG_INFINITY;
            for (caddr, ckind, _) in children(&view, addr) {
                let (a, b) = exact_box(bvh, caddr, ckind);
                lo = lo.min(a);
                hi = hi.max(b);
            }
            (lo, hi)
        }
        NodeKind::Header => panic!("the header has no box"),
    }
}

/// (address, kind, slot) of every child of an internal node.
fn children(view: &InternalView, addr: u32) -> Vec<(u32, NodeKind, usize)> {
    let mut out = Vec::new();
    let mut a = view.child_base(addr);
    for i in 0..view.child_count() {
        let k = view.child_kind(i).expect("child kind");
        out.push((a, k, i));
        a += view.child_size(k);
    }
    out
}

/// The nodes where a ray may enter a treelet slot: the header, and every node whose parent lies
/// in another slot.
fn entry_points(bvh: &HwBvh) -> BTreeSet<u32> {
    let mut out = BTreeSet::from([0]);
    for n in bvh.nodes().iter().filter(|n| n.kind == NodeKind::Internal) {
        let view =
            InternalView::new(bvh.node_bytes(n.addr).expect("node bytes")).expect("internal");
        for (c, _, _) in children(&view, n.addr) {
            if bvh.treelet_of(c) != n.treelet {
                out.insert(c);
            }
        }
    }
    out
}

/// Checks every structural invariant of a built BVH against its scene.
fn check_layout(scene: &Scene, bvh: &HwBvh) -> Result<(), TestCaseError> {
    let p = *bvh.params();
    let stats = bvh.stats();
    // Every node lies in exactly one treelet: the slot its address names, inside the used bytes.
    let mut per_treelet = vec![(0u32, 0u32); bvh.treelets().len()];
    for n in bvh.nodes() {
        prop_assert_eq!(n.treelet, n.addr / p.treelet_bytes);
        prop_assert_eq!(n.treelet, bvh.treelet_of(n.addr));
        prop_assert_eq!(n.addr % 64, 0);
        let t = bvh.treelets()[n.treelet as usize];
        prop_assert!(n.addr >= t.base && n.addr + n.bytes <= t.base + t.bytes);
        per_treelet[n.treelet as usize].0 += n.bytes;
        per_treelet[n.treelet as usize].1 += 1;
    }
    for (i, t) in bvh.treelets().iter().enumerate() {
        prop_assert!(
            t.bytes <= p.treelet_bytes,
            "treelet {i} holds {} bytes",
            t.bytes
        );
        prop_assert_eq!(t.base, i as u32 * p.treelet_bytes);
        prop_assert_eq!((t.bytes, t.nodes), per_treelet[i]);
    }
    let used: u64 = bvh.treelets().iter().map(|t| t.bytes as u64).sum();
    prop_assert_eq!(used, stats.bvh_bytes);
    let fill = used as f64 / (bvh.treelets().len() as f64 * p.treelet_bytes as f64);
    prop_assert!((stats.treelet_fill - fill).abs() < 1e-12);
    prop_assert_eq!(
        bvh.nodes().len() as u32,
        1 + stats.internal_nodes + stats.leaves()
    );
    prop_assert_eq!(bvh.nodes()[0].kind, NodeKind::Header);

    // Quantized child boxes contain the exact child boxes; primitives appear exactly once.
    let mut prims = Vec::new();
    for n in bvh.nodes() {
        let bytes = bvh.node_bytes(n.addr).expect("node bytes");
        match n.kind {
            NodeKind::Internal => {
                let view = InternalView::new(bytes).expect("internal");
                prop_assert!(view.child_count() >= 1 && view.child_count() <= p.width as usize);
                for (caddr, ckind, slot) in children(&view, n.addr) {
                    prop_assert_eq!(bvh.node(caddr).map(|c| c.kind), Some(ckind));
                    let (qlo, qhi) = view.child_box(slot);
                    let (lo, hi) = exact_box(bvh, caddr, ckind);
                    prop_assert!(
                        qlo.cmple(lo).all() && qhi.cmpge(hi).all(),
                        "child {slot} of {:#x}: decoded {qlo}..{qhi} misses exact {lo}..{hi}",
                        n.addr
                    );
                }
            }
            NodeKind::TriangleLeaf => prims.push(decode_triangle(bytes).1),
            NodeKind::ProceduralLeaf => prims.push(decode_sphere(bytes).2),
            NodeKind::Header => {}
        }
    }
    prims.sort_unstable();
    let expected: Vec<u32> = (0..scene.triangles.len())
        .filter(|&i| triangle_is_usable(scene.triangle(i)))
        .map(|i| i as u32)
        .chain(
            scene
                .spheres
                .iter()
                .enumerate()
                .filter(|(_, s)| sphere_is_usable(s))
                .map(|(i, _)| (scene.triangles.len() + i) as u32),
        )
        .collect();
    prop_assert_eq!(
        stats.excluded_prims as usize,
        scene.prim_count() - expected.len()
    );
    prop_assert_eq!(prims, expected);
    prop_assert_eq!(bvh.has_procedural(), stats.procedural_leaves > 0);
    Ok(())
}

/// Traces `ray` in both orders and checks hits, fetch lists and the stepwise API; `entries` are
/// the BVH's [`entry_points`].
fn check_ray(
    scene: &Scene,
    bvh: &HwBvh,
    entries: &BTreeSet<u32>,
    ray: &Ray,
) -> Result<(), TestCaseError> {
    let reference = brute_force(scene, ray);
    let tb = bvh.params().treelet_bytes;
    for order in [Order::RayStationary, Order::Treelet] {
        let mut fetches = Vec::new();
        let hit = trace_with_fetches(bvh, ray, order, &mut fetches);
        prop_assert_eq!(
            hit,
            reference,
            "{:?} differs from brute force for {:?}",
            order,
            ray
        );
        prop_assert_eq!(trace(bvh, ray, order), reference);
        if ray.is_valid() {
            prop_assert_eq!(fetches[0].addr, 0);
            prop_assert_eq!(fetches[0].kind, NodeKind::Header);
            prop_assert_eq!(fetches[0].bytes, 64);
        } else {
            prop_assert!(fetches.is_empty());
        }
        for f in &fetches {
            let node = bvh.node(f.addr).expect("fetch of a real node");
            prop_assert_eq!(
                (node.kind, node.bytes, node.treelet),
                (f.kind, f.bytes, f.treelet)
            );
            prop_assert_eq!(f.treelet, f.addr / tb);
        }
        if order == Order::Treelet {
            // No node is fetched twice, and the ray enters a slot only at an entry point (the
            // header, or a node whose parent lies in another slot). A breadth-first treelet is
            // one subtree, so it is entered at most once; a packed slot holds several, and is
            // entered at most once per subtree (sim/src/model/bvh/treelet.rs).
            let mut fetched = BTreeSet::new();
            let mut seen = BTreeSet::new();
            let mut last = None;
            for f in &fetches {
                prop_assert!(fetched.insert(f.addr), "node {} fetched twice", f.addr);
                if last != Some(f.treelet) {
                    prop_assert!(
                        entries.contains(&f.addr),
                        "treelet {} entered at node {}, not an entry point",
                        f.treelet,
                        f.addr
                    );
                    let again = !seen.insert(f.treelet);
                    prop_assert!(
                        !(again && bvh.params().formation == TreeletFormation::BreadthFirst),
                        "breadth-first treelet {} re-entered",
                        f.treelet
                    );
                    last = Some(f.treelet);
                }
            }
        }
        // The stepwise API produces the same fetches and hit.
        let mut state = TraversalState::new(bvh, ray, order);
        let mut steps = Vec::new();
        let mut prev_treelet = state.current_treelet();
        while let Some(f) = state.next_fetch() {
            prop_assert_eq!(state.next_treelet(), Some(f.treelet));
            prop_assert_eq!(state.at_treelet_boundary(), prev_treelet != Some(f.treelet));
            steps.push(f);
            let out = state.visit(bvh);
            let tests = out.box_tests + out.triangle_tests + out.sphere_tests;
            match f.kind {
                NodeKind::Header => prop_assert_eq!(tests, 0),
                NodeKind::Internal => prop_assert_eq!(out.box_tests, tests),
                NodeKind::TriangleLeaf => prop_assert_eq!(out.triangle_tests, 1),
                NodeKind::ProceduralLeaf => prop_assert_eq!(out.sphere_tests, 1),
            }
            prev_treelet = Some(f.treelet);
            prop_assert!(state.is_done() || state.current_treelet() == Some(f.treelet));
        }
        prop_assert!(state.is_done() && state.current_treelet().is_none());
        prop_assert_eq!(state.hit(), reference);
        prop_assert_eq!(&steps, &fetches);
    }
    for order in [Order::RayStationary, Order::Treelet, Order::Hardware] {
        check_occlusion(bvh, ray, order)?;
    }
    Ok(())
}

/// An occlusion ray in `order` hits exactly when the closest-hit ray does, and stops at the
/// closest-hit traversal's first recorded hit: its fetches are a prefix of its twin's, its hit
/// is the first one the twin recorded, and the stepwise API agrees.
fn check_occlusion(bvh: &HwBvh, ray: &Ray, order: Order) -> Result<(), TestCaseError> {
    let mut closest = TraversalState::new(bvh, ray, order);
    let (mut twin, mut first) = (Vec::new(), None);
    while let Some(f) = closest.next_fetch() {
        twin.push(f);
        if closest.visit(bvh).hit_recorded && first.is_none() {
            first = Some((closest.hit(), twin.len()));
        }
    }
    let mut fetches = Vec::new();
    let hit = trace_occlusion_with_fetches(bvh, ray, order, &mut fetches);
    prop_assert_eq!(
        hit.is_some(),
        closest.hit().is_some(),
        "{:?} {:?}",
        order,
        ray
    );
    prop_assert_eq!(trace_occlusion(bvh, ray, order), hit);
    prop_assert!(twin.starts_with(&fetches), "{:?}: not a prefix", order);
    match first {
        Some((h, n)) => prop_assert_eq!((hit, fetches.len()), (h, n)),
        None => prop_assert_eq!(fetches.len(), twin.len()),
    }
    let mut state = TraversalState::occlusion(bvh, ray, order);
    let mut steps = Vec::new();
    while let Some(f) = state.next_fetch() {
        steps.push(f);
        state.visit(bvh);
    }
    prop_assert!(state.is_done() && state.current_treelet().is_none());
    prop_assert_eq!(state.hit(), hit);
    prop_assert_eq!(steps, fetches);
    Ok(())
}

fn vec3(range: f32) -> impl Strategy<Value = Vec3> {
    (-range..range, -range..range, -range..range).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

/// Triangles of assorted sizes, some degenerate (repeated or collinear vertices).
fn triangle() -> impl Strategy<Value = [Vec3; 3]> {
    (vec3(8.0), vec3(1.0), vec3(1.0), 0.05f32..4.0, 0u8..12).prop_map(|(c, a, b, s, kind)| {
        let (p, q) = (c + a * s, c + b * s);
        match kind {
            0 => [c, p, c],
            1 => [c, p, c + (p - c) * 2.0],
            _ => [c, p, q],
        }
    })
}

fn sphere() -> impl Strategy<Value = Sphere> {
    (vec3(8.0), 0.05f32..2.0).prop_map(|(center, radius)| Sphere {
        center,
        radius,
        material: 0,
    })
}

/// Random triangles (plus exact duplicates of the first few, so hits tie in `t` and the prim-id
/// tie rule decides) and spheres.
fn scene() -> impl Strategy<Value = Scene> {
    (
        prop::collection::vec(triangle(), 0..40),
        prop::collection::vec(sphere(), 0..5),
        0usize..4,
    )
        .prop_map(|(mut tris, spheres, dups)| {
            let copies: Vec<[Vec3; 3]> = tris.iter().take(dups).copied().collect();
            tris.extend(copies);
            let positions: Vec<Vec3> = tris.iter().flatten().copied().collect();
            let triangles = (0..tris.len() as u32)
                .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
                .collect();
            mesh_scene(positions, triangles, spheres)
        })
}

/// Width, treelet size (the smallest valid, 1 KB or the default 8 KB) and treelet formation.
fn params() -> impl Strategy<Value = BvhParams> {
    (2u32..=8, 0u8..3, any::<bool>()).prop_map(|(width, t, packed)| {
        let node = if width <= 6 { 64 } else { 128 };
        let min = (width * node).max(128).next_power_of_two();
        let treelet_bytes = [min, min.max(1024), 8192][t as usize];
        BvhParams {
            width,
            treelet_bytes,
            formation: if packed {
                TreeletFormation::Packed
            } else {
                TreeletFormation::BreadthFirst
            },
        }
    })
}

/// A ray spec: origin, free direction or a target (a vertex, centroid or sphere centre of a
/// primitive picked by index), and the interval kind.
fn ray_spec() -> impl Strategy<Value = (Vec3, Vec3, prop::sample::Index, u8, u8)> {
    (
        vec3(15.0),
        vec3(1.0),
        any::<prop::sample::Index>(),
        0u8..5,
        0u8..3,
    )
}

fn make_ray(
    scene: &Scene,
    (origin, dir, idx, aim, interval): (Vec3, Vec3, prop::sample::Index, u8, u8),
) -> Ray {
    let n = scene.prim_count();
    let dir = if aim > 0 && n > 0 {
        let i = idx.index(n);
        let target = match scene.sphere_of(i as u32) {
            Some(s) => s.center,
            None => {
                let v = scene.triangle(i);
                match aim {
                    1 => v[0],
                    2 => v[1],
                    3 => (v[0] + v[1]) * 0.5,
                    _ => (v[0] + v[1] + v[2]) / 3.0,
                }
            }
        };
        target - origin
    } else {
        dir
    };
    let (tmin, tmax) = match interval {
        0 => (0.0, f32::INFINITY),
        1 => (0.001, 10000.0),
        _ => (0.5, 0.9),
    };
    Ray {
        origin,
        dir,
        tmin,
        tmax,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn layout_and_treelet_invariants(scene in scene(), params in params()) {
        let bvh = HwBvh::build(&scene, &params).expect("build");
        check_layout(&scene, &bvh)?;
    }

    #[test]
    fn both_orders_match_brute_force(
        scene in scene(),
        params in params(),
        rays in prop::collection::vec(ray_spec(), 1..24),
    ) {
        let bvh = HwBvh::build(&scene, &params).expect("build");
        let entries = entry_points(&bvh);
        for spec in rays {
            check_ray(&scene, &bvh, &entries, &make_ray(&scene, spec))?;
        }
    }
}

/// A fixed scene with enough primitives for several treelet levels at every width.
fn fixed_scene() -> Scene {
    let (pos, tris) = icosphere(2);
    let mut positions = pos.clone();
    let mut triangles = tris.clone();
    // A second, shifted and scaled copy so that the tree has uneven structure.
    let base = positions.len() as u32;
    positions.extend(pos.iter().map(|p| *p * 0.5 + Vec3::new(2.5, 0.3, -0.7)));
    triangles.extend(tris.iter().map(|t| t.map(|i| i + base)));
    let spheres = (0..6)
        .map(|i| Sphere {
            center: Vec3::new(-3.0 + i as f32, 2.0, 0.5 * i as f32),
            radius: 0.3 + 0.1 * i as f32,
            material: 0,
        })
        .collect();
    mesh_scene(positions, triangles, spheres)
}

#[test]
fn every_width_builds_and_traces_like_brute_force() {
    let scene = fixed_scene();
    for width in 2..=8 {
        for treelet_bytes in [1024, 8192] {
            let params = BvhParams {
                width,
                treelet_bytes,
                ..BvhParams::default()
            };
            let bvh = HwBvh::build(&scene, &params).expect("build");
            check_layout(&scene, &bvh).expect("layout");
            assert!(
                bvh.stats().treelets > 1,
                "width {width}: expected several treelets"
            );
            let internal = bvh.stats().internal_nodes as usize;
            let leaves = scene.prim_count();
            // A binary tree has leaves - 1 internal nodes; collapsing to width >= 4 at least
            // halves that.
            assert!(internal < leaves);
            if width >= 4 {
                assert!(
                    2 * internal < leaves,
                    "width {width}: {internal} internal nodes"
                );
            }
            let entries = entry_points(&bvh);
            let mut hits = 0;
            for i in 0..200 {
                let a = i as f32 * 0.37;
                let origin = Vec3::new(6.0 * a.cos(), 4.0 * (a * 0.7).sin(), 6.0 * a.sin());
                let target = Vec3::new((a * 1.3).sin(), (a * 0.9).cos(), 0.5 * (a * 2.1).sin());
                let ray = Ray::new(origin, target - origin);
                check_ray(&scene, &bvh, &entries, &ray).expect("ray");
                hits += usize::from(trace(&bvh, &ray, Order::Treelet).is_some());
            }
            assert!(hits > 100, "width {width}: only {hits} of 200 rays hit");
        }
    }
}

#[test]
fn invalid_params_are_rejected_with_clear_errors() {
    let scene = fixed_scene();
    let cases = [
        (
            BvhParams {
                width: 1,
                treelet_bytes: 8192,
                ..BvhParams::default()
            },
            "width",
        ),
        (
            BvhParams {
                width: 9,
                treelet_bytes: 8192,
                ..BvhParams::default()
            },
            "width",
        ),
        (
            BvhParams {
                width: 6,
                treelet_bytes: 6000,
                ..BvhParams::default()
            },
            "power of two",
        ),
        (
            BvhParams {
                width: 8,
                treelet_bytes: 512,
                ..BvhParams::default()
            },
            "child group",
        ),
        (
            BvhParams {
                width: 2,
                treelet_bytes: 64,
                ..BvhParams::default()
            },
            "child group",
        ),
    ];
    for (params, needle) in cases {
        let err = HwBvh::build(&scene, &params)
            .expect_err("invalid params")
            .to_string();
        assert!(err.contains(needle), "{err:?} does not mention {needle:?}");
    }
    assert!(BvhParams::default().validate().is_ok());
    assert_eq!(BvhParams::default().width, 6);
    assert_eq!(BvhParams::default().treelet_bytes, 8192);
}

#[test]
fn out_of_range_triangle_index_and_huge_coordinates_are_errors() {
    let bad_index = mesh_scene(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 3]], vec![]);
    let err = HwBvh::build(&bad_index, &BvhParams::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("triangle 0") && err.contains("vertex 3"),
        "{err}"
    );
    let huge = mesh_scene(
        vec![Vec3::ZERO, Vec3::X, Vec3::splat(1e30)],
        vec![[0, 1, 2]],
        vec![],
    );
    let err = HwBvh::build(&huge, &BvhParams::default())
        .unwrap_err()
        .to_string();
    assert!(err.contains("triangle 0"), "{err}");
}

/// A fresh, empty folder under the system temp dir for one test.
fn temp_dir(name: &str) -> PathBuf {
    common::fresh_dir(&format!("b2b-{name}"))
}

#[test]
fn cache_round_trip_and_corruption_recovery() {
    let scene = fixed_scene();
    let params = BvhParams {
        width: 4,
        treelet_bytes: 2048,
        ..BvhParams::default()
    };
    let dir = temp_dir("cache");
    let fresh = HwBvh::build(&scene, &params).expect("build").to_bytes();

    let (a, outcome) = build_cached(&scene, &params, Some(&dir)).expect("first");
    assert_eq!(outcome, CacheOutcome::Built);
    assert_eq!(a.to_bytes(), fresh);
    let (b, outcome) = build_cached(&scene, &params, Some(&dir)).expect("second");
    assert_eq!(outcome, CacheOutcome::Hit);
    assert_eq!(b.to_bytes(), fresh);

    let files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("list")
        .map(|e| e.expect("entry").path())
        .collect();
    assert_eq!(
        files.len(),
        1,
        "exactly one cache file, no temporaries: {files:?}"
    );
    let file = &files[0];
    assert_eq!(file.extension().and_then(|e| e.to_str()), Some("vtqbvh"));

    // A flipped bit in the image, a truncation and garbage are all detected and rebuilt.
    let good = std::fs::read(file).expect("read");
    let mut flipped = good.clone();
    flipped[good.len() / 2] ^= 0x10;
    let corruptions = [
        flipped,
        good[..good.len() - 7].to_vec(),
        b"garbage".to_vec(),
    ];
    for bad in corruptions {
        assert!(HwBvh::from_bytes(&bad).is_err());
        std::fs::write(file, &bad).expect("corrupt");
        let (c, outcome) = build_cached(&scene, &params, Some(&dir)).expect("rebuild");
        assert!(matches!(outcome, CacheOutcome::Rebuilt(_)), "{outcome:?}");
        assert_eq!(c.to_bytes(), fresh);
        assert_eq!(std::fs::read(file).expect("reread"), good);
    }

    // Different parameters use a different file.
    let other = BvhParams {
        width: 6,
        treelet_bytes: 2048,
        ..BvhParams::default()
    };
    let (_, outcome) = build_cached(&scene, &other, Some(&dir)).expect("other params");
    assert_eq!(outcome, CacheOutcome::Built);
    // So does another treelet formation, and it loads back as that formation.
    assert_eq!(params.formation, TreeletFormation::Packed);
    let bf = BvhParams {
        formation: TreeletFormation::BreadthFirst,
        ..params
    };
    let (p, outcome) = build_cached(&scene, &bf, Some(&dir)).expect("breadth-first");
    assert_eq!(outcome, CacheOutcome::Built);
    let (q, outcome) = build_cached(&scene, &bf, Some(&dir)).expect("breadth-first again");
    assert_eq!(outcome, CacheOutcome::Hit);
    assert_eq!((p.params(), q.to_bytes()), (&bf, p.to_bytes()));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn serialization_round_trip_preserves_traversal() {
    let scene = fixed_scene();
    let bvh = HwBvh::build(&scene, &BvhParams::default()).expect("build");
    let back = HwBvh::from_bytes(&bvh.to_bytes()).expect("load");
    assert_eq!(back.stats(), bvh.stats());
    assert_eq!(back.treelets(), bvh.treelets());
    assert_eq!(back.nodes(), bvh.nodes());
    let ray = Ray::new(Vec3::new(0.2, 0.1, 5.0), Vec3::new(0.0, 0.0, -1.0));
    assert_eq!(
        trace(&back, &ray, Order::RayStationary),
        trace(&bvh, &ray, Order::RayStationary)
    );
}
