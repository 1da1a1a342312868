//! Small meshes generated in code for the BVH and traversal tests: a scene of given triangles
//! and spheres, and a closed icosphere.

use glam::Vec3;
use vtq_sim::{Camera, Material, Scene, Sphere};

/// A scene of the given triangles (grey Lambertian) and spheres, with a default camera.
pub fn mesh_scene(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>, spheres: Vec<Sphere>) -> Scene {
    Scene {
        name: "generated".into(),
        tri_material: vec![0; triangles.len()],
        positions,
        triangles,
        spheres,
        materials: vec![Material::DEFAULT],
        camera: Camera {
            eye: Vec3::new(0.0, 0.0, 5.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 45.0,
        },
        sky: true,
    }
}

/// A closed unit icosphere with shared vertices: an icosahedron whose faces are split into four
/// `subdivisions` times, new vertices projected onto the sphere (f64 arithmetic, rounded once).
/// Returns positions and outward-wound triangles (20 * 4^subdivisions of them).
pub fn icosphere(subdivisions: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    use std::collections::BTreeMap;
    let p = (1.0 + 5f64.sqrt()) / 2.0;
    let mut pos: Vec<glam::DVec3> = [
        (-1.0, p, 0.0),
        (1.0, p, 0.0),
        (-1.0, -p, 0.0),
        (1.0, -p, 0.0),
        (0.0, -1.0, p),
        (0.0, 1.0, p),
        (0.0, -1.0, -p),
        (0.0, 1.0, -p),
        (p, 0.0, -1.0),
        (p, 0.0, 1.0),
        (-p, 0.0, -1.0),
        (-p, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| glam::DVec3::new(x, y, z).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid: BTreeMap<(u32, u32), u32> = BTreeMap::new();
        let mut midpoint = |a: u32, b: u32, pos: &mut Vec<glam::DVec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                pos.push(((pos[a as usize] + pos[b as usize]) * 0.5).normalize());
                pos.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(tris.len() * 4);
        for [a, b, c] in tris {
            let ab = midpoint(a, b, &mut pos);
            let bc = midpoint(b, c, &mut pos);
            let ca = midpoint(c, a, &mut pos);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    (pos.into_iter().map(|p| p.as_vec3()).collect(), tris)
}
