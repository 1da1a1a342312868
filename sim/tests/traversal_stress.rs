//! Traversal robustness: rays aimed exactly at the shared vertices and edge midpoints of a closed
//! mesh never slip through (at several offsets from the origin), NaN/inf rays are misses, and
//! degenerate triangles are never hit.

mod common;

use glam::Vec3;
use vtq_sim::model::bvh::{BvhParams, HwBvh};
use vtq_sim::model::traversal::{trace, trace_with_fetches, Order, TraversalState};
use vtq_sim::Ray;

use common::meshes::{icosphere, mesh_scene};

#[test]
fn rays_at_vertices_and_edge_midpoints_never_miss() {
    let (unit, tris) = icosphere(3);
    for offset in [0.0f32, 1e3, 1e5] {
        let center = Vec3::new(offset, -0.5 * offset, 0.7 * offset);
        let positions: Vec<Vec3> = unit.iter().map(|p| *p + center).collect();
        let scene = mesh_scene(positions.clone(), tris.clone(), vec![]);
        for width in [2, 6, 8] {
            let params = BvhParams {
                width,
                treelet_bytes: 2048,
                ..BvhParams::default()
            };
            let bvh = HwBvh::build(&scene, &params).expect("build");
            assert_eq!(bvh.stats().excluded_prims, 0);
            let mut targets: Vec<Vec3> = positions.clone();
            for t in &tris {
                for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                    if a < b {
                        targets.push((positions[a as usize] + positions[b as usize]) * 0.5);
                    }
                }
            }
            let mut misses = [0usize; 2];
            for target in &targets {
                let ray = Ray {
                    origin: center,
                    dir: *target - center,
                    tmin: 0.0,
                    tmax: f32::INFINITY,
                };
                let rs = trace(&bvh, &ray, Order::RayStationary);
                let tl = trace(&bvh, &ray, Order::Treelet);
                assert_eq!(rs, tl, "orders disagree for target {target}");
                misses[0] += usize::from(rs.is_none());
                misses[1] += usize::from(tl.is_none());
                if let Some(h) = rs {
                    // The hit lies at the target: t is 1 up to rounding of the sheared test.
                    assert!((h.t - 1.0).abs() < 1e-2, "t = {} at offset {offset}", h.t);
                }
            }
            assert_eq!(
                misses,
                [0, 0],
                "offset {offset}, width {width}: misses among {} rays",
                targets.len()
            );
        }
    }
}

#[test]
fn nan_and_infinite_rays_are_misses() {
    let (pos, tris) = icosphere(1);
    let scene = mesh_scene(pos, tris, vec![]);
    let bvh = HwBvh::build(&scene, &BvhParams::default()).expect("build");
    let good = Ray {
        origin: Vec3::ZERO,
        dir: Vec3::X,
        tmin: 0.0,
        tmax: f32::INFINITY,
    };
    assert!(trace(&bvh, &good, Order::RayStationary).is_some());
    let nan = f32::NAN;
    let inf = f32::INFINITY;
    let bad = [
        Ray {
            origin: Vec3::new(nan, 0.0, 0.0),
            ..good
        },
        Ray {
            origin: Vec3::new(0.0, inf, 0.0),
            ..good
        },
        Ray {
            dir: Vec3::new(1.0, nan, 0.0),
            ..good
        },
        Ray {
            dir: Vec3::new(inf, 0.0, 0.0),
            ..good
        },
        Ray {
            dir: Vec3::ZERO,
            ..good
        },
        Ray { tmin: nan, ..good },
        Ray { tmax: nan, ..good },
        Ray {
            tmin: 2.0,
            tmax: 1.0,
            ..good
        },
    ];
    for ray in bad {
        for order in [Order::RayStationary, Order::Treelet] {
            let mut fetches = Vec::new();
            assert_eq!(
                trace_with_fetches(&bvh, &ray, order, &mut fetches),
                None,
                "{ray:?}"
            );
            assert!(fetches.is_empty());
            let mut state = TraversalState::new(&bvh, &ray, order);
            assert!(state.is_done() && state.next_fetch().is_none());
            assert_eq!(state.visit(&bvh), Default::default());
            assert_eq!(state.hit(), None);
        }
    }
    // Infinite interval ends are valid: the hit is still found.
    let wide = Ray { tmin: -inf, ..good };
    let hit = trace(&bvh, &wide, Order::Treelet).expect("hit with tmin = -inf");
    assert!(
        hit.t < 0.0,
        "closest along the whole line is behind the origin"
    );
}

#[test]
fn degenerate_triangles_are_never_hit() {
    // Repeated vertices, collinear vertices and a non-finite vertex.
    let positions = vec![
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(3.0, 3.0, 0.0),
        Vec3::new(f32::NAN, 0.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
    ];
    let degenerate = vec![[0, 1, 2], [0, 0, 1], [2, 2, 2], [0, 1, 3], [4, 1, 5]];
    let scene = mesh_scene(positions.clone(), degenerate.clone(), vec![]);
    let bvh = HwBvh::build(&scene, &BvhParams::default()).expect("build");
    assert_eq!(bvh.stats().excluded_prims, 5);
    assert_eq!(bvh.stats().leaves(), 0);
    assert_eq!(bvh.root(), 0, "an empty BVH has no root");
    // Rays through the degenerate triangles' points, straight on and at an angle.
    let targets = [
        Vec3::ZERO,
        Vec3::new(0.5, 0.5, 0.0),
        Vec3::new(-1.0, -1.0, 0.0),
    ];
    for target in targets {
        for from in [Vec3::new(0.0, 0.0, 2.0), Vec3::new(0.3, -0.4, -2.0)] {
            let ray = Ray::new(from + target, -from);
            for order in [Order::RayStationary, Order::Treelet] {
                let mut fetches = Vec::new();
                assert_eq!(trace_with_fetches(&bvh, &ray, order, &mut fetches), None);
                assert_eq!(fetches.len(), 1, "only the header is fetched");
            }
        }
    }
    // Mixed with one valid triangle: only the valid one is ever reported.
    let mut tris = degenerate;
    tris.push([0, 5, 1]);
    let scene = mesh_scene(positions, tris, vec![]);
    let bvh = HwBvh::build(&scene, &BvhParams::default()).expect("build");
    assert_eq!(bvh.stats().leaves(), 1);
    for target in targets {
        let ray = Ray::new(target + Vec3::Z, -Vec3::Z);
        for order in [Order::RayStationary, Order::Treelet] {
            let hit = trace(&bvh, &ray, order).expect("valid triangle hit");
            assert_eq!(hit.prim, 5);
        }
    }
}
