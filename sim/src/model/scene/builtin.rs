//! Built-in scenes: `wknd`, the "Ray Tracing in One Weekend" cover as LumiBench renders it (all
//! procedural spheres), `cornell`, the classic Cornell box as triangles, and the generated
//! `city:N` family ([`super::city`]).

use glam::Vec3;

use super::{city, Camera, Material, Scene, SceneError, Sphere};

/// Names of the built-in scenes, in listing order (`city` stands for the `city:N` family).
pub const BUILTIN_NAMES: [&str; 3] = ["wknd", "cornell", "city"];

/// Seed of the LCG that places the small spheres of [`wknd`]. Any constant gives a valid cover
/// scene; this one is fixed so the scene is identical on every run and machine.
pub const WKND_SEED: u32 = 1;

/// The built-in scene called `name` (ASCII case-insensitive): `None` if `name` is not a
/// built-in, else the scene, or for a malformed `city:N` spec a [`SceneError::Parse`] naming the
/// spec and the problem (see [`city::parse_spec`]).
pub fn builtin(name: &str) -> Option<Result<Scene, SceneError>> {
    if name.eq_ignore_ascii_case("wknd") {
        Some(Ok(wknd()))
    } else if name.eq_ignore_ascii_case("cornell") {
        Some(Ok(cornell()))
    } else {
        city::parse_spec(name).map(|budget| budget.map(city::city))
    }
}

/// A one-line description of built-in `name` for listings, or `None` if there is no such scene.
pub fn builtin_title(name: &str) -> Option<&'static str> {
    if name.eq_ignore_ascii_case("wknd") {
        Some("Ray Tracing in One Weekend cover (LumiBench WKND), procedural spheres")
    } else if name.eq_ignore_ascii_case("cornell") {
        Some("Cornell box with two rotated blocks, triangles")
    } else if name.eq_ignore_ascii_case("city") {
        Some(
            "generated city of exactly N triangles: `city:N`, N = 1000..64M with suffix k or M \
             (default 1M; BVHs fit the 32-bit address space up to about 4.9M)",
        )
    } else {
        None
    }
}

/// Triangle and sphere counts of built-in `name` for listings, or `None` if there is no such
/// scene. `city` is its default budget, known without generating it (a city has exactly its
/// budget of triangles); the others are generated and counted.
pub fn builtin_counts(name: &str) -> Option<(usize, usize)> {
    if name.eq_ignore_ascii_case("city") {
        return Some((city::DEFAULT_TRIANGLES as usize, 0));
    }
    let scene = builtin(name)?.ok()?;
    Some((scene.triangles.len(), scene.spheres.len()))
}

/// LCG multiplier (Numerical Recipes), as in LumiBench (its path tracer, `workload::rng`, and
/// its scene generator use the same LCG).
pub const LCG_A: u32 = 1_664_525;
/// LCG increment (Numerical Recipes), as in LumiBench.
pub const LCG_C: u32 = 1_013_904_223;

/// The LCG of LumiBench's path tracer (multiplier 1664525, increment 1013904223), producing
/// floats in `[0, 1)` as `(state & 0xFFFFFF) / 2^24`.
struct Lcg(u32);

impl Lcg {
    /// Advance and return a float in `[0, 1)`.
    fn next(&mut self) -> f32 {
        self.0 = LCG_A.wrapping_mul(self.0).wrapping_add(LCG_C);
        (self.0 & 0x00FF_FFFF) as f32 / 16_777_216.0
    }

    /// A float in `[lo, hi)`.
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next()
    }

    /// A vector of three draws (x, y, z in that order).
    fn vec3(&mut self) -> Vec3 {
        let x = self.next();
        let y = self.next();
        Vec3::new(x, y, self.next())
    }
}

/// WKND: the "Ray Tracing in One Weekend" cover. Sphere order (and so primitive ids): the ground
/// (r = 1000 at (0, -1000, 0), [`Material::DEFAULT`] grey), then the small spheres (r = 0.2) in
/// loop order `a` then `b` over `-11..11`, then glass (0, 1, 0), diffuse (-4, 1, 0) and metal
/// (4, 1, 0) spheres of radius 1. Per grid cell the draws are, in order: `choose_mat`, the x and
/// z jitter of the centre `(a + 0.9 rnd, 0.2, b + 0.9 rnd)`; a centre within 0.9 of (4, 0.2, 0)
/// is skipped; otherwise `choose_mat < 0.8` gives Lambertian albedo `rnd3 * rnd3` (first vector
/// drawn first), `< 0.95` Metal albedo `0.5 + 0.5 rnd3` then fuzz `0.5 rnd`, else glass (ior 1.5).
/// Draws come from the path tracer's LCG seeded with [`WKND_SEED`]. Camera (13, 2, 3) ->
/// (0, 0, 0), up +Y, 20 degrees; sky on; no triangles.
pub fn wknd() -> Scene {
    let mut rng = Lcg(WKND_SEED);
    let mut materials = vec![Material::DEFAULT];
    let mut spheres = vec![Sphere {
        center: Vec3::new(0.0, -1000.0, 0.0),
        radius: 1000.0,
        material: 0,
    }];
    let mut add = |materials: &mut Vec<Material>, center: Vec3, radius: f32, m: Material| {
        materials.push(m);
        spheres.push(Sphere {
            center,
            radius,
            material: (materials.len() - 1) as u32,
        });
    };
    for a in -11..11 {
        for b in -11..11 {
            let choose_mat = rng.next();
            let x = a as f32 + 0.9 * rng.next();
            let z = b as f32 + 0.9 * rng.next();
            let center = Vec3::new(x, 0.2, z);
            if (center - Vec3::new(4.0, 0.2, 0.0)).length() <= 0.9 {
                continue;
            }
            let material = if choose_mat < 0.8 {
                let first = rng.vec3();
                Material::Lambertian {
                    albedo: first * rng.vec3(),
                }
            } else if choose_mat < 0.95 {
                let albedo = rng.vec3() * 0.5 + Vec3::splat(0.5);
                Material::Metal {
                    albedo,
                    fuzz: rng.range(0.0, 0.5),
                }
            } else {
                Material::Dielectric { ior: 1.5 }
            };
            add(&mut materials, center, 0.2, material);
        }
    }
    add(
        &mut materials,
        Vec3::new(0.0, 1.0, 0.0),
        1.0,
        Material::Dielectric { ior: 1.5 },
    );
    add(
        &mut materials,
        Vec3::new(-4.0, 1.0, 0.0),
        1.0,
        Material::Lambertian {
            albedo: Vec3::new(0.4, 0.2, 0.1),
        },
    );
    add(
        &mut materials,
        Vec3::new(4.0, 1.0, 0.0),
        1.0,
        Material::Metal {
            albedo: Vec3::new(0.7, 0.6, 0.5),
            fuzz: 0.0,
        },
    );
    Scene {
        name: "wknd".into(),
        positions: Vec::new(),
        triangles: Vec::new(),
        tri_material: Vec::new(),
        spheres,
        materials,
        camera: Camera {
            eye: Vec3::new(13.0, 2.0, 3.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 20.0,
        },
        sky: true,
    }
}

/// Side of the Cornell room.
const ROOM: f32 = 555.0;

/// Material indices of [`cornell`].
const RED: u32 = 1;
/// White walls and blocks.
const WHITE: u32 = 2;
/// Green wall.
const GREEN: u32 = 3;
/// Ceiling light.
const LIGHT: u32 = 4;

/// The Cornell box as in "Ray Tracing: The Next Week": a 555-unit room (red wall at x = 0, green
/// at x = 555, white floor, ceiling and back wall at z = 555; the front at z = 0 is open), a
/// 130 x 105 emitter (15, 15, 15) at y = 554 under the ceiling, a short 165-unit block turned
/// -18 degrees about +Y at (130, 0, 65) and a tall 165 x 330 x 165 block turned 15 degrees at
/// (265, 0, 295). 36 triangles: 10 walls, 2 light, 12 per block; the room's 8 corners are shared
/// by its walls and each block's 8 corners by its faces. Walls and light face into the room,
/// blocks face outward. Camera (278, 278, -800) -> (278, 278, 0), 40 degrees; no sky.
pub fn cornell() -> Scene {
    let mut scene = Scene {
        name: "cornell".into(),
        positions: Vec::new(),
        triangles: Vec::new(),
        tri_material: Vec::new(),
        spheres: Vec::new(),
        materials: vec![
            Material::DEFAULT,
            Material::Lambertian {
                albedo: Vec3::new(0.65, 0.05, 0.05),
            },
            Material::Lambertian {
                albedo: Vec3::splat(0.73),
            },
            Material::Lambertian {
                albedo: Vec3::new(0.12, 0.45, 0.15),
            },
            Material::Light {
                emit: Vec3::splat(15.0),
            },
        ],
        camera: Camera {
            eye: Vec3::new(278.0, 278.0, -800.0),
            look_at: Vec3::new(278.0, 278.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 40.0,
        },
        sky: false,
    };

    // Room corners: bit 0 = x, bit 1 = y, bit 2 = z (0 or ROOM).
    let room = push_corners(&mut scene, Vec3::ZERO, Vec3::splat(ROOM), |p| p);
    let c = |i: usize| room[i];
    // Quads listed counter-clockwise as seen from inside the room.
    push_quad(&mut scene, [c(0), c(2), c(6), c(4)], RED); // x = 0
    push_quad(&mut scene, [c(1), c(5), c(7), c(3)], GREEN); // x = 555
    push_quad(&mut scene, [c(0), c(4), c(5), c(1)], WHITE); // floor y = 0
    push_quad(&mut scene, [c(2), c(3), c(7), c(6)], WHITE); // ceiling y = 555
    push_quad(&mut scene, [c(4), c(6), c(7), c(5)], WHITE); // back z = 555

    let base = scene.positions.len() as u32;
    for (x, z) in [
        (213.0, 227.0),
        (343.0, 227.0),
        (343.0, 332.0),
        (213.0, 332.0),
    ] {
        scene.positions.push(Vec3::new(x, ROOM - 1.0, z));
    }
    push_quad(&mut scene, [base, base + 1, base + 2, base + 3], LIGHT); // faces down

    push_block(
        &mut scene,
        Vec3::new(165.0, 165.0, 165.0),
        -18.0,
        Vec3::new(130.0, 0.0, 65.0),
    );
    push_block(
        &mut scene,
        Vec3::new(165.0, 330.0, 165.0),
        15.0,
        Vec3::new(265.0, 0.0, 295.0),
    );
    scene
}

/// Push the 8 corners of the box `[lo, hi]`, each mapped by `place`, and return their indices
/// (corner `i` takes x from bit 0, y from bit 1, z from bit 2 of `i`; 0 = `lo`, 1 = `hi`).
fn push_corners(scene: &mut Scene, lo: Vec3, hi: Vec3, place: impl Fn(Vec3) -> Vec3) -> [u32; 8] {
    std::array::from_fn(|i| {
        let pick = |bit: usize, l: f32, h: f32| if i & bit != 0 { h } else { l };
        let p = Vec3::new(
            pick(1, lo.x, hi.x),
            pick(2, lo.y, hi.y),
            pick(4, lo.z, hi.z),
        );
        scene.positions.push(place(p));
        (scene.positions.len() - 1) as u32
    })
}

/// Push the quad `q` (corners in order) as the fan `(q0, q1, q2), (q0, q2, q3)`.
fn push_quad(scene: &mut Scene, q: [u32; 4], material: u32) {
    scene.triangles.push([q[0], q[1], q[2]]);
    scene.triangles.push([q[0], q[2], q[3]]);
    scene.tri_material.extend([material, material]);
}

/// Push a white block of size `size` with a corner at the origin, turned `degrees` about +Y
/// (RTNW's `rotate_y`: x' = cos x + sin z, z' = -sin x + cos z) and moved by `offset`.
fn push_block(scene: &mut Scene, size: Vec3, degrees: f32, offset: Vec3) {
    let (sin, cos) = degrees.to_radians().sin_cos();
    let c = push_corners(scene, Vec3::ZERO, size, |p| {
        Vec3::new(cos * p.x + sin * p.z, p.y, -sin * p.x + cos * p.z) + offset
    });
    // Counter-clockwise as seen from outside the block.
    push_quad(scene, [c[0], c[4], c[6], c[2]], WHITE); // x = 0 side
    push_quad(scene, [c[1], c[3], c[7], c[5]], WHITE); // x = size side
    push_quad(scene, [c[0], c[1], c[5], c[4]], WHITE); // bottom
    push_quad(scene, [c[2], c[6], c[7], c[3]], WHITE); // top
    push_quad(scene, [c[0], c[2], c[3], c[1]], WHITE); // z = 0 side
    push_quad(scene, [c[4], c[5], c[7], c[6]], WHITE); // z = size side
}
