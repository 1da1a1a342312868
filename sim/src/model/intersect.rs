//! Numerically robust ray/primitive intersection: the watertight ray/triangle test, the
//! conservative ray/box slab test, a cancellation-free ray/sphere test, and the secondary-ray
//! origin offset that keeps bounced rays from re-hitting the surface they leave.
//!
//! Every routine treats NaN or infinite input (in the ray, the interval or the primitive) as a
//! miss; none of them panics.

use crate::model::geometry::Ray;
use glam::{DVec3, Vec3};

/// PBRT's bound on the relative error of `n` chained f32 roundings:
/// `gamma(n) = n*eps / (1 - n*eps)` with `eps = 2^-24` (half an ulp of 1.0).
pub const fn gamma(n: i32) -> f32 {
    let ne = n as f32 * (f32::EPSILON * 0.5);
    ne / (1.0 - ne)
}

/// Factor applied to every far slab distance in [`ray_box`] so that rounding in the slab
/// distances can never make the test miss a box the exact ray passes through (PBRT 3, sec. 3.9.2).
const FAR_PAD: f32 = 1.0 + 2.0 * gamma(3);

/// Per-ray precomputation shared by every [`ray_triangle`] and [`ray_box`] test of one ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayPrecomp {
    /// Axis of the largest |dir| component; the shear maps it onto the projection's z.
    kz: usize,
    /// First projected axis (swapped with `ky` when `dir[kz] < 0` to keep the winding).
    kx: usize,
    /// Second projected axis.
    ky: usize,
    /// Shear coefficient of the x axis: `-dir[kx] / dir[kz]`.
    sx: f32,
    /// Shear coefficient of the y axis: `-dir[ky] / dir[kz]`.
    sy: f32,
    /// Scale of the z axis: `1 / dir[kz]`.
    sz: f32,
    /// Per-component reciprocal of the direction (infinite for zero components).
    inv_dir: Vec3,
    /// Ray origin.
    origin: Vec3,
    /// Whether origin and direction are finite and the direction is non-zero; tests of an
    /// invalid ray always miss.
    valid: bool,
}

impl RayPrecomp {
    /// Precomputes the shear of the watertight triangle test and the reciprocal direction of
    /// the slab test. Rays with non-finite components or a zero direction are recorded as
    /// invalid, and every test of them misses.
    pub fn new(ray: &Ray) -> RayPrecomp {
        let dir = ray.dir;
        let abs = dir.abs();
        let kz = if abs.x >= abs.y && abs.x >= abs.z {
            0
        } else if abs.y >= abs.z {
            1
        } else {
            2
        };
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let valid = ray.origin.is_finite() && dir.is_finite() && dir[kz] != 0.0;
        RayPrecomp {
            kz,
            kx,
            ky,
            sx: -dir[kx] / dir[kz],
            sy: -dir[ky] / dir[kz],
            sz: 1.0 / dir[kz],
            inv_dir: dir.recip(),
            origin: ray.origin,
            valid,
        }
    }
}

/// Watertight ray/triangle test (Woop, Benthin, Wald 2013, "Watertight Ray/Triangle
/// Intersection"). Returns `(t, u, v)` with `tmin <= t <= tmax` and hit point
/// `(1-u-v)*v0 + u*v1 + v*v2`. Both windings hit (no back-face culling). Rays through a shared
/// edge or vertex of a mesh hit at least one of the triangles sharing it. Degenerate (zero-area)
/// triangles, triangles with non-finite vertices, invalid rays and NaN bounds never hit.
pub fn ray_triangle(
    pre: &RayPrecomp,
    v: [Vec3; 3],
    tmin: f32,
    tmax: f32,
) -> Option<(f32, f32, f32)> {
    if !pre.valid || !v.iter().all(|p| p.is_finite()) {
        return None;
    }
    let (kx, ky, kz) = (pre.kx, pre.ky, pre.kz);
    // Vertices relative to the origin, then sheared so that the ray runs along +z.
    let a = v[0] - pre.origin;
    let b = v[1] - pre.origin;
    let c = v[2] - pre.origin;
    let ax = a[kx] + pre.sx * a[kz];
    let ay = a[ky] + pre.sy * a[kz];
    let bx = b[kx] + pre.sx * b[kz];
    let by = b[ky] + pre.sy * b[kz];
    let cx = c[kx] + pre.sx * c[kz];
    let cy = c[ky] + pre.sy * c[kz];
    // Scaled barycentric edge functions. Each edge is evaluated by the same expression in
    // every triangle that shares it, which is what makes the test watertight.
    let mut u = cx * by - cy * bx;
    let mut v_ = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;
    if u == 0.0 || v_ == 0.0 || w == 0.0 {
        // An f32 zero may be two unequal products rounded together. In f64 the products of
        // f32 values are exact, so the sign (and exact zero) of each edge function is right.
        let (ax, ay, bx, by, cx, cy) = (
            f64::from(ax),
            f64::from(ay),
            f64::from(bx),
            f64::from(by),
            f64::from(cx),
            f64::from(cy),
        );
        u = (cx * by - cy * bx) as f32;
        v_ = (ax * cy - ay * cx) as f32;
        w = (bx * ay - by * ax) as f32;
    }
    if (u < 0.0 || v_ < 0.0 || w < 0.0) && (u > 0.0 || v_ > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v_ + w;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let az = pre.sz * a[kz];
    let bz = pre.sz * b[kz];
    let cz = pre.sz * c[kz];
    let t_scaled = u * az + v_ * bz + w * cz;
    let (t_signed, det_abs) = if det < 0.0 {
        (-t_scaled, -det)
    } else {
        (t_scaled, det)
    };
    // Negated form so that NaN bounds reject.
    if !(t_signed >= tmin * det_abs && t_signed <= tmax * det_abs) {
        return None;
    }
    if !has_area(&v) {
        return None;
    }
    let rcp = 1.0 / det;
    // The division may round a hair outside the interval that the scaled test accepted.
    let t = (t_scaled * rcp).max(tmin).min(tmax);
    Some((t, v_ * rcp, w * rcp))
}

/// Whether the triangle has non-zero area, decided in f64 (exact whenever the edge vectors'
/// components need at most 26 significant bits, e.g. repeated or exactly collinear vertices).
fn has_area(v: &[Vec3; 3]) -> bool {
    let p0 = v[0].as_dvec3();
    let e1 = v[1].as_dvec3() - p0;
    let e2 = v[2].as_dvec3() - p0;
    e1.cross(e2) != DVec3::ZERO
}

/// Conservative slab test of the ray segment `[tmin, tmax]` against the box `[lo, hi]`.
/// Returns `Some(t_near)` (the entry distance clamped to `tmin`) when the segment may overlap
/// the box. Far distances are padded by `1 + 2*gamma(3)` so rounding never causes a false miss;
/// a `0 * inf` NaN (zero direction component, origin on a slab plane) constrains nothing; empty
/// boxes (`lo > hi`), invalid rays and NaN bounds miss.
pub fn ray_box(pre: &RayPrecomp, lo: Vec3, hi: Vec3, tmin: f32, tmax: f32) -> Option<f32> {
    if !pre.valid {
        return None;
    }
    let mut t0 = tmin;
    let mut t1 = tmax;
    for axis in 0..3 {
        let inv = pre.inv_dir[axis];
        // Pick the planes by the direction's sign (not by swapping distances) so that an
        // inverted, empty box stays a miss.
        let (near, far) = if inv.is_sign_negative() {
            (hi[axis], lo[axis])
        } else {
            (lo[axis], hi[axis])
        };
        let t_near = (near - pre.origin[axis]) * inv;
        let t_far = (far - pre.origin[axis]) * inv * FAR_PAD;
        // Written so that a NaN slab distance leaves the interval unchanged.
        if t_near > t0 {
            t0 = t_near;
        }
        if t_far < t1 {
            t1 = t_far;
        }
        if t0 > t1 {
            return None;
        }
    }
    // Also rejects a NaN tmin or tmax.
    if t0 <= t1 {
        Some(t0)
    } else {
        None
    }
}

/// Analytic ray/sphere test returning the nearest root `t` in `[tmin, tmax]`.
///
/// Uses the formulation of Haines et al., Ray Tracing Gems ch. 7: the discriminant is computed
/// from the vector from the centre to the ray's closest point (no `b^2 - 4ac` cancellation), and
/// the second root comes from `c / q` (no `-b + sqrt` cancellation). The scalar algebra runs in
/// f64 because `|o - c|^2 - r^2` still cancels for large spheres seen from nearby (the
/// 1000-radius ground of Ray Tracing in One Weekend loses ~5e-5 relative accuracy in f32).
/// Invalid rays, non-finite centres and radii that are not finite and positive never hit.
pub fn ray_sphere(ray: &Ray, center: Vec3, radius: f32, tmin: f32, tmax: f32) -> Option<f32> {
    let usable = ray.origin.is_finite()
        && ray.dir.is_finite()
        && ray.dir != Vec3::ZERO
        && center.is_finite()
        && radius > 0.0
        && radius.is_finite();
    if !usable {
        return None;
    }
    let f = ray.origin.as_dvec3() - center.as_dvec3();
    let d = ray.dir.as_dvec3();
    let r2 = f64::from(radius) * f64::from(radius);
    let a = d.dot(d);
    // Half of the usual b: the quadratic is a t^2 + 2 hb t + c = 0.
    let hb = f.dot(d);
    let closest = f - (hb / a) * d;
    let disc = r2 - closest.dot(closest);
    if disc < 0.0 {
        return None;
    }
    let c = f.dot(f) - r2;
    let q = -(hb + (a * disc).sqrt().copysign(hb));
    let (r1, r2) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q / a) };
    let (near, far) = if r1 <= r2 { (r1, r2) } else { (r2, r1) };
    let (lo, hi) = (f64::from(tmin), f64::from(tmax));
    let t = if near >= lo && near <= hi {
        near
    } else if far >= lo && far <= hi {
        far
    } else {
        return None;
    };
    // Rounding to f32 may step just outside the interval.
    Some((t as f32).max(tmin).min(tmax))
}

/// Offsets a surface point `p` along the normal `n` (towards the side `n` points to) so that a
/// secondary ray starting there does not re-hit the surface (Waechter & Binder, Ray Tracing
/// Gems ch. 6). Components with magnitude at least 1/32 move by `256 * n_i` units in the last
/// place; smaller ones (near the origin, where ulps are tiny) move by `n_i / 65536`. `n` need not
/// be normalized; a zero or non-finite `n` leaves `p` unchanged, as do non-finite components of
/// `p`.
pub fn offset_ray_origin(p: Vec3, n: Vec3) -> Vec3 {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let n = n.normalize_or_zero();
    let mut out = p;
    for i in 0..3 {
        let (pi, ni) = (p[i], n[i]);
        if !pi.is_finite() {
            continue;
        }
        out[i] = if pi.abs() < ORIGIN {
            pi + FLOAT_SCALE * ni
        } else {
            // Truncation keeps the sign of n_i; for negative p the bit pattern grows with
            // magnitude, so the step is negated to move the value in the direction of n_i.
            let steps = (INT_SCALE * ni) as i32;
            let steps = if pi < 0.0 { -steps } else { steps };
            f32::from_bits((pi.to_bits() as i32).wrapping_add(steps) as u32)
        };
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Roughly uniform unit directions (Fibonacci sphere), deterministic.
    fn sphere_dirs(n: usize) -> Vec<Vec3> {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let phi = golden * i as f64;
                DVec3::new(r * phi.cos(), r * phi.sin(), z).as_vec3()
            })
            .collect()
    }

    fn ray(origin: Vec3, dir: Vec3) -> Ray {
        Ray {
            origin,
            dir,
            tmin: 0.0,
            tmax: f32::INFINITY,
        }
    }

    fn tri_hit(r: &Ray, v: [Vec3; 3]) -> Option<(f32, f32, f32)> {
        ray_triangle(&RayPrecomp::new(r), v, r.tmin, r.tmax)
    }

    /// A tilted plane frame (origin, two in-plane axes) so that no mesh is axis-aligned.
    fn tilted_frame(offset: f32) -> (Vec3, Vec3, Vec3) {
        let e1 = Vec3::new(0.8, 0.36, -0.48).normalize();
        let e2 = Vec3::new(-0.3, 0.9, 0.1);
        let e2 = (e2 - e1 * e1.dot(e2)).normalize();
        (Vec3::splat(offset) + Vec3::new(0.3, -0.7, 0.2), e1, e2)
    }

    /// Counts rays aimed at `targets` from every direction at least 15 degrees off the mesh
    /// plane that miss all `tris`; returns (misses, rays).
    fn count_misses(tris: &[[Vec3; 3]], targets: &[Vec3], normal: Vec3) -> (usize, usize) {
        let min_cos = 15f32.to_radians().sin();
        let mut misses = 0;
        let mut rays = 0;
        for &target in targets {
            for d in sphere_dirs(300) {
                if d.dot(normal).abs() < min_cos {
                    continue;
                }
                let origin = target + d * 3.0;
                let r = ray(origin, target - origin);
                rays += 1;
                if tris.iter().all(|&t| tri_hit(&r, t).is_none()) {
                    misses += 1;
                }
            }
        }
        (misses, rays)
    }

    #[test]
    fn gamma_matches_pbrt_definition() {
        let eps = f64::from(f32::EPSILON) / 2.0;
        let expect = 3.0 * eps / (1.0 - 3.0 * eps);
        assert!((f64::from(gamma(3)) - expect).abs() < 1e-6 * expect);
        assert!(gamma(1) < gamma(2) && gamma(2) < gamma(3));
        assert_eq!(gamma(0), 0.0);
    }

    #[test]
    fn rays_through_centroid_hit_with_matching_barycentrics() {
        let v = [
            Vec3::new(-1.0, -1.0, 2.0),
            Vec3::new(2.0, -0.5, 3.0),
            Vec3::new(0.0, 1.5, 2.5),
        ];
        let centroid = (v[0] + v[1] + v[2]) / 3.0;
        let n = (v[1] - v[0]).cross(v[2] - v[0]).normalize();
        for d in sphere_dirs(200) {
            // Grazing rays are covered by the watertightness tests; their t is ill-conditioned.
            if d.dot(n).abs() < 0.05 {
                continue;
            }
            let origin = centroid + d * 5.0;
            // Scaled direction: t is in units of dir.
            let r = ray(origin, (centroid - origin) * 0.5);
            let (t, u, w) = tri_hit(&r, v).expect("ray through centroid must hit");
            assert!((t - 2.0).abs() < 1e-4, "t = {t}");
            assert!((u - 1.0 / 3.0).abs() < 1e-4 && (w - 1.0 / 3.0).abs() < 1e-4);
            let p = (1.0 - u - w) * v[0] + u * v[1] + w * v[2];
            assert!(
                p.distance(r.at(t)) < 1e-4,
                "barycentric convention mismatch"
            );
        }
    }

    #[test]
    fn barycentric_convention_at_vertices_region() {
        // Ray close to v1 must give u near 1; close to v2 must give v near 1.
        let v = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        let near_v1 = ray(Vec3::new(0.9, 0.05, 1.0), Vec3::NEG_Z);
        let (_, u, w) = tri_hit(&near_v1, v).unwrap();
        assert!((u - 0.9).abs() < 1e-6 && (w - 0.05).abs() < 1e-6);
        let near_v2 = ray(Vec3::new(0.05, 0.9, -1.0), Vec3::Z);
        let (t, u, w) = tri_hit(&near_v2, v).unwrap();
        assert!((u - 0.05).abs() < 1e-6 && (w - 0.9).abs() < 1e-6 && (t - 1.0).abs() < 1e-6);
    }

    #[test]
    fn quad_diagonal_is_watertight() {
        for offset in [0.0, 1e3, 1e5] {
            for tilted in [false, true] {
                let (o, e1, e2, n) = if tilted {
                    let (o, e1, e2) = tilted_frame(offset);
                    (o, e1, e2, e1.cross(e2))
                } else {
                    (Vec3::splat(offset), Vec3::X, Vec3::Y, Vec3::Z)
                };
                let q = [o, o + e1, o + e1 + e2, o + e2];
                let tris = [[q[0], q[1], q[2]], [q[0], q[2], q[3]]];
                let targets: Vec<Vec3> = [0.1f32, 0.25, 0.5, 0.7, 0.95]
                    .iter()
                    .map(|&s| q[0].lerp(q[2], s))
                    .collect();
                let (misses, rays) = count_misses(&tris, &targets, n);
                assert!(rays > 1000);
                assert_eq!(misses, 0, "offset {offset}, tilted {tilted}");
            }
        }
    }

    #[test]
    fn vertex_fan_is_watertight() {
        for offset in [0.0, 1e3, 1e5] {
            for tilted in [false, true] {
                let (o, e1, e2) = if tilted {
                    tilted_frame(offset)
                } else {
                    (Vec3::splat(offset), Vec3::X, Vec3::Z)
                };
                let n = e1.cross(e2);
                let rim: Vec<Vec3> = (0..6)
                    .map(|i| {
                        let a = i as f32 * std::f32::consts::TAU / 6.0 + 0.2;
                        o + e1 * a.cos() + e2 * a.sin()
                    })
                    .collect();
                let tris: Vec<[Vec3; 3]> = (0..6).map(|i| [o, rim[i], rim[(i + 1) % 6]]).collect();
                // The shared centre vertex and points along every shared spoke.
                let mut targets = vec![o];
                for &r in &rim {
                    for s in [0.05f32, 0.3, 0.6, 0.85] {
                        targets.push(o.lerp(r, s));
                    }
                }
                let (misses, rays) = count_misses(&tris, &targets, n);
                assert!(rays > 5000);
                assert_eq!(misses, 0, "offset {offset}, tilted {tilted}");
            }
        }
    }

    /// `x` moved by `k` units in the last place.
    fn ulps(x: f32, k: i32) -> f32 {
        f32::from_bits((x.to_bits() as i32 + if x < 0.0 { -k } else { k }) as u32)
    }

    #[test]
    fn edge_decisions_are_exact_when_f32_products_tie() {
        // Slivers along the diagonal through the ray (the z axis): the edge functions are a few
        // ulps, and often the two f32 products of an edge function round to the same value. The
        // inside/outside decision must still equal the exact one (signs of the edge functions
        // computed exactly in f64), which needs the f64 recomputation of zero edge functions.
        let pre = RayPrecomp::new(&ray(Vec3::ZERO, Vec3::Z));
        let (mut ties, mut disagreements) = (0, 0);
        let steps = [-2, -1, 0, 1, 2];
        for &bx in &steps {
            for &by in &steps {
                for &cx in &steps {
                    for &cy in &steps {
                        for &ak in &[-1, 0, 1] {
                            let a = Vec3::new(ulps(-1.0, ak), -1.0, 1.0);
                            let b = Vec3::new(ulps(1.0, bx), ulps(1.0, by), 1.0);
                            let c = Vec3::new(ulps(1.0, cx), ulps(1.0, cy), 1.0);
                            let edge32 = |p: Vec3, q: Vec3| q.x * p.y - q.y * p.x;
                            let edge64 = |p: Vec3, q: Vec3| {
                                f64::from(q.x) * f64::from(p.y) - f64::from(q.y) * f64::from(p.x)
                            };
                            let exact = [edge64(b, c), edge64(c, a), edge64(a, b)];
                            let rounded = [edge32(b, c), edge32(c, a), edge32(a, b)];
                            if rounded
                                .iter()
                                .zip(&exact)
                                .any(|(&r, &e)| r == 0.0 && e != 0.0)
                            {
                                ties += 1;
                            }
                            let mixed =
                                exact.iter().any(|&e| e < 0.0) && exact.iter().any(|&e| e > 0.0);
                            let expect =
                                !mixed && exact.iter().any(|&e| e != 0.0) && has_area(&[a, b, c]);
                            let got = ray_triangle(&pre, [a, b, c], 0.0, 10.0).is_some();
                            if got != expect {
                                disagreements += 1;
                            }
                        }
                    }
                }
            }
        }
        assert!(
            ties > 100,
            "only {ties} configurations exercise the f64 path"
        );
        assert_eq!(disagreements, 0);
    }

    #[test]
    fn degenerate_triangles_never_hit() {
        let p = Vec3::new(0.1, 0.2, 0.3);
        let degenerate = [
            [Vec3::ZERO, Vec3::ONE, Vec3::splat(2.0)],
            [Vec3::ZERO, p, p * 2.0],
            [p, p, Vec3::new(1.0, 0.0, 0.0)],
            [p, p, p],
            [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(3.0, 0.0, 0.0),
            ],
        ];
        for tri in degenerate {
            for target in [
                tri[0],
                tri[1],
                tri[2],
                (tri[0] + tri[1]) * 0.5,
                (tri[0] + tri[2]) * 0.5,
            ] {
                for d in sphere_dirs(100) {
                    let origin = target + d * 2.0;
                    let r = ray(origin, target - origin);
                    assert!(tri_hit(&r, tri).is_none(), "{tri:?} hit from {origin}");
                }
            }
        }
    }

    #[test]
    fn non_finite_rays_and_vertices_miss() {
        let tri = [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        let good = ray(Vec3::new(0.0, 0.0, 1.0), Vec3::NEG_Z);
        assert!(tri_hit(&good, tri).is_some());
        let bad_rays = [
            ray(Vec3::new(f32::NAN, 0.0, 1.0), Vec3::NEG_Z),
            ray(Vec3::new(0.0, f32::INFINITY, 1.0), Vec3::NEG_Z),
            ray(Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, f32::NAN)),
            ray(Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, f32::NAN, -1.0)),
            ray(
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(0.0, 0.0, f32::NEG_INFINITY),
            ),
            ray(Vec3::new(0.0, 0.0, 1.0), Vec3::ZERO),
        ];
        for r in bad_rays {
            let pre = RayPrecomp::new(&r);
            assert!(tri_hit(&r, tri).is_none(), "{r:?}");
            assert!(ray_box(&pre, Vec3::splat(-2.0), Vec3::splat(2.0), 0.0, 1e30).is_none());
            assert!(ray_sphere(&r, Vec3::ZERO, 0.5, 0.0, 1e30).is_none());
        }
        let pre = RayPrecomp::new(&good);
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            for i in 0..3 {
                for axis in 0..3 {
                    let mut t = tri;
                    t[i][axis] = bad;
                    assert!(ray_triangle(&pre, t, 0.0, f32::INFINITY).is_none());
                }
            }
            assert!(ray_sphere(&good, Vec3::splat(bad), 0.5, 0.0, 10.0).is_none());
            assert!(ray_sphere(&good, Vec3::ZERO, bad, 0.0, 10.0).is_none());
        }
        // NaN interval bounds.
        assert!(ray_triangle(&pre, tri, f32::NAN, 10.0).is_none());
        assert!(ray_triangle(&pre, tri, 0.0, f32::NAN).is_none());
        assert!(ray_box(&pre, Vec3::splat(-2.0), Vec3::splat(2.0), f32::NAN, 10.0).is_none());
        assert!(ray_box(&pre, Vec3::splat(-2.0), Vec3::splat(2.0), 0.0, f32::NAN).is_none());
        assert!(ray_sphere(&good, Vec3::ZERO, 0.5, f32::NAN, 10.0).is_none());
        // Zero and negative radii.
        assert!(ray_sphere(&good, Vec3::ZERO, 0.0, 0.0, 10.0).is_none());
        assert!(ray_sphere(&good, Vec3::ZERO, -0.5, 0.0, 10.0).is_none());
    }

    #[test]
    fn triangle_respects_interval_and_both_windings() {
        let tri = [
            Vec3::new(-1.0, -1.0, 5.0),
            Vec3::new(1.0, -1.0, 5.0),
            Vec3::new(0.0, 1.0, 5.0),
        ];
        let flipped = [tri[0], tri[2], tri[1]];
        let pre = RayPrecomp::new(&ray(Vec3::ZERO, Vec3::Z));
        for t in [tri, flipped] {
            assert_eq!(ray_triangle(&pre, t, 0.0, 10.0).map(|h| h.0), Some(5.0));
            assert_eq!(ray_triangle(&pre, t, 5.0, 5.0).map(|h| h.0), Some(5.0));
            assert!(ray_triangle(&pre, t, 0.0, 4.99).is_none());
            assert!(ray_triangle(&pre, t, 5.01, 10.0).is_none());
            assert!(ray_triangle(&pre, t, 6.0, 4.0).is_none());
        }
        // Behind the origin.
        let back = RayPrecomp::new(&ray(Vec3::ZERO, Vec3::NEG_Z));
        assert!(ray_triangle(&back, tri, 0.0, f32::INFINITY).is_none());
        // Parallel to the triangle's plane.
        let parallel = RayPrecomp::new(&ray(Vec3::new(-5.0, 0.0, 5.0), Vec3::X));
        assert!(ray_triangle(&parallel, tri, 0.0, f32::INFINITY).is_none());
        // Just outside an edge.
        let outside = RayPrecomp::new(&ray(Vec3::new(0.0, -1.001, 0.0), Vec3::Z));
        assert!(ray_triangle(&outside, tri, 0.0, f32::INFINITY).is_none());
    }

    #[test]
    fn box_hits_misses_and_interval() {
        let (lo, hi) = (Vec3::new(-1.0, -2.0, -3.0), Vec3::new(1.0, 2.0, 3.0));
        for d in sphere_dirs(200) {
            let origin = d * 10.0;
            let pre = RayPrecomp::new(&ray(origin, -d));
            let t = ray_box(&pre, lo, hi, 0.0, f32::INFINITY).expect("ray through centre");
            assert!(t > 0.0 && t < 10.0);
            assert!(
                ray_box(&pre, lo, hi, 0.0, t * 0.99).is_none(),
                "segment ends short"
            );
            // Pointing away from the box.
            let away = RayPrecomp::new(&ray(origin, d));
            assert!(ray_box(&away, lo, hi, 0.0, f32::INFINITY).is_none());
        }
        // Origin inside: t_near is tmin.
        let inside = RayPrecomp::new(&ray(Vec3::ZERO, Vec3::new(0.3, -0.2, 1.0)));
        assert_eq!(ray_box(&inside, lo, hi, 0.5, 100.0), Some(0.5));
        // Empty (inverted) box never hits.
        assert!(ray_box(&inside, hi, lo, 0.0, 100.0).is_none());
    }

    #[test]
    fn box_grazing_face_counts_as_hit() {
        let (lo, hi) = (Vec3::splat(1e3), Vec3::splat(1e3 + 1.0));
        // Rays that touch the box only along its top face (y = hi.y), at shallow angles, from
        // far away: rounding in the slab distances must not turn them into misses.
        for i in 0..200 {
            let x = lo.x + 0.5 + (i as f32) * 1e-3;
            let target = Vec3::new(x, hi.y, lo.z + 0.5);
            let origin = target + Vec3::new(-(i as f32 + 1.0) * 37.0, 0.0, 13.0);
            let pre = RayPrecomp::new(&ray(origin, target - origin));
            assert!(
                ray_box(&pre, lo, hi, 0.0, f32::INFINITY).is_some(),
                "i = {i}"
            );
        }
        // A ray that just clips a box corner diagonally.
        let pre = RayPrecomp::new(&ray(Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0)));
        assert!(ray_box(
            &pre,
            Vec3::new(1.0, 0.0, -1.0),
            Vec3::new(2.0, 1.0, 1.0),
            0.0,
            10.0
        )
        .is_some());
    }

    #[test]
    fn box_ray_through_an_edge_exactly_hits() {
        // Rays that pass exactly through the edge x = hi.x, y = lo.y of the box: in exact
        // arithmetic they leave the x slab at the very distance where they enter the y slab, so
        // the rounded slab distances cross in about half the cases and only the far padding keeps
        // them hits.
        let (lo, hi) = (Vec3::ZERO, Vec3::ONE);
        let edge_point = Vec3::new(1.0, 0.0, 0.5);
        let mut checked = 0;
        for i in 0..60 {
            for j in 0..60 {
                let a = 0.5 + i as f32 * 0.0377;
                let b = 0.5 + j as f32 * 0.0291;
                let origin = Vec3::new(1.0 - a, -b, 0.25);
                let dir = edge_point - origin;
                // Keep only rays that contain the edge point exactly (origin + 1 * dir).
                if origin.as_dvec3() + dir.as_dvec3() != edge_point.as_dvec3() {
                    continue;
                }
                checked += 1;
                let pre = RayPrecomp::new(&ray(origin, dir));
                assert!(ray_box(&pre, lo, hi, 0.0, 10.0).is_some(), "{origin} {dir}");
            }
        }
        assert!(checked > 1000, "only {checked} exact rays");
    }

    #[test]
    fn box_zero_direction_component_is_nan_safe() {
        let (lo, hi) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 1.0));
        // dir.y == 0 (both signs) with the origin exactly on the y = lo.y and y = hi.y planes:
        // (plane - origin) * inf = 0 * inf = NaN must not cause a miss.
        for y in [lo.y, hi.y, 0.5] {
            for dy in [0.0f32, -0.0] {
                let pre = RayPrecomp::new(&ray(Vec3::new(-1.0, y, 0.5), Vec3::new(1.0, dy, 0.0)));
                assert_eq!(
                    ray_box(&pre, lo, hi, 0.0, 10.0),
                    Some(1.0),
                    "y = {y}, dy = {dy}"
                );
            }
        }
        // Flat box (lo.y == hi.y) with the origin in its plane.
        let flat_pre = RayPrecomp::new(&ray(Vec3::new(-1.0, 0.0, 0.5), Vec3::X));
        assert!(ray_box(
            &flat_pre,
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 1.0),
            0.0,
            10.0
        )
        .is_some());
        // Zero component with the origin outside that slab is a miss.
        let pre = RayPrecomp::new(&ray(Vec3::new(-1.0, 1.5, 0.5), Vec3::X));
        assert!(ray_box(&pre, lo, hi, 0.0, 10.0).is_none());
        let pre = RayPrecomp::new(&ray(Vec3::new(-1.0, -0.5, 0.5), Vec3::X));
        assert!(ray_box(&pre, lo, hi, 0.0, 10.0).is_none());
    }

    #[test]
    fn sphere_from_outside_and_inside() {
        let c = Vec3::new(1.0, 2.0, 3.0);
        let outside = ray(c + Vec3::new(0.0, 0.0, -5.0), Vec3::new(0.0, 0.0, 2.0));
        assert_eq!(ray_sphere(&outside, c, 1.0, 0.0, 100.0), Some(2.0));
        // Near root excluded by tmin: far root.
        assert_eq!(ray_sphere(&outside, c, 1.0, 2.5, 100.0), Some(3.0));
        assert!(ray_sphere(&outside, c, 1.0, 0.0, 1.9).is_none());
        assert!(ray_sphere(&outside, c, 1.0, 3.1, 100.0).is_none());
        let inside = ray(c, Vec3::new(0.0, 3.0, 4.0));
        assert_eq!(ray_sphere(&inside, c, 2.0, 0.001, 100.0), Some(0.4));
        let miss = ray(c + Vec3::new(0.0, 1.01, -5.0), Vec3::Z);
        assert!(ray_sphere(&miss, c, 1.0, 0.0, 100.0).is_none());
        let behind = ray(c + Vec3::new(0.0, 0.0, 5.0), Vec3::Z);
        assert!(ray_sphere(&behind, c, 1.0, 0.0, 100.0).is_none());
    }

    /// Nearest root in [tmin, tmax] by the textbook quadratic in f64.
    fn sphere_ref(o: Vec3, d: Vec3, c: Vec3, r: f32, tmin: f64) -> Option<f64> {
        let (o, d, c, r) = (o.as_dvec3(), d.as_dvec3(), c.as_dvec3(), f64::from(r));
        let f = o - c;
        let (a, b, cc) = (d.dot(d), 2.0 * f.dot(d), f.dot(f) - r * r);
        let disc = b * b - 4.0 * a * cc;
        if disc < 0.0 {
            return None;
        }
        let roots = [
            (-b - disc.sqrt()) / (2.0 * a),
            (-b + disc.sqrt()) / (2.0 * a),
        ];
        roots.into_iter().find(|&t| t >= tmin)
    }

    #[test]
    fn large_ground_sphere_is_accurate() {
        let (center, radius) = (Vec3::new(0.0, -1000.0, 0.0), 1000.0);
        let origin = Vec3::new(13.0, 2.0, 3.0);
        let mut checked = 0;
        for i in 0..40 {
            for j in 0..40 {
                // Ground points within ~60 units of the scene centre.
                let (x, z) = (-60.0 + 3.0 * i as f32, -60.0 + 3.0 * j as f32);
                let up = Vec3::new(x, 1000.0, z).normalize();
                let target = center + up * radius;
                // Far ground points are seen almost tangentially from a height of 2, where a
                // rounding of the target may legitimately turn the ray into a miss; skip those.
                if (origin - target).normalize().dot(up) < 0.02 {
                    continue;
                }
                for dir in [target - origin, (target - origin).normalize()] {
                    let r = ray(origin, dir);
                    let t = ray_sphere(&r, center, radius, 0.001, 10000.0).expect("ground hit");
                    let expect = sphere_ref(origin, dir, center, radius, 0.001).unwrap();
                    let rel = (f64::from(t) - expect).abs() / expect;
                    assert!(rel < 1e-4, "t {t} vs {expect} (rel {rel})");
                    checked += 1;
                }
            }
        }
        assert!(checked > 1000, "only {checked} rays checked");
    }

    #[test]
    fn offset_moves_strictly_to_normal_side() {
        let normals = sphere_dirs(64);
        let mut rng = crate::model::splitmix::SplitMix64::new(0x2545_f491);
        // Deterministic pseudo-random values in [0, 1).
        let mut next = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        for mag in [0.0, 1e-3, 0.02, 0.5, 1.0, 37.0, 1e3, 3e4, 1e5] {
            for &n in &normals {
                let p = DVec3::new(next() * 2.0 - 1.0, next() * 2.0 - 1.0, next() * 2.0 - 1.0);
                let p = (p * mag).as_vec3();
                let q = offset_ray_origin(p, n * 3.0);
                let side = (q.as_dvec3() - p.as_dvec3()).dot(n.as_dvec3());
                assert!(side > 0.0, "p {p} n {n} q {q}");
            }
        }
        // Degenerate normals leave the point alone; non-finite components stay put.
        let p = Vec3::new(5.0, -3.0, 0.01);
        assert_eq!(offset_ray_origin(p, Vec3::ZERO), p);
        assert_eq!(offset_ray_origin(p, Vec3::new(f32::NAN, 0.0, 1.0)), p);
        let q = offset_ray_origin(Vec3::new(f32::INFINITY, 1.0, 1.0), Vec3::X);
        assert_eq!(q.x, f32::INFINITY);
    }

    #[test]
    fn offset_origin_does_not_rehit_its_triangle() {
        let dirs = sphere_dirs(200);
        for offset in [0.0, 1e3, 1e5] {
            let (o, e1, e2) = tilted_frame(offset);
            let tri = [o, o + e1 * 3.0, o + e2 * 2.0 + e1];
            let geo_n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
            let plane_n = (tri[1].as_dvec3() - tri[0].as_dvec3())
                .cross(tri[2].as_dvec3() - tri[0].as_dvec3());
            for (bu, bv) in [(0.2f32, 0.3f32), (0.6, 0.1), (0.05, 0.9), (0.33, 0.33)] {
                let p = (1.0 - bu - bv) * tri[0] + bu * tri[1] + bv * tri[2];
                for side in [1.0f32, -1.0] {
                    let q = offset_ray_origin(p, geo_n * side);
                    let dist = (q.as_dvec3() - tri[0].as_dvec3()).dot(plane_n) * f64::from(side);
                    assert!(dist > 0.0, "offset point not on the normal's side");
                    for &d in &dirs {
                        if d.dot(geo_n.normalize() * side) < 0.05 {
                            continue;
                        }
                        let r = ray(q, d);
                        assert!(tri_hit(&r, tri).is_none(), "re-hit from {q} along {d}");
                    }
                }
            }
        }
    }

    proptest! {
        // About half the generated triangles/directions are rejected as badly shaped or grazing.
        #![proptest_config(ProptestConfig {
            cases: 400,
            max_global_rejects: 100_000,
            ..ProptestConfig::default()
        })]

        #[test]
        fn rays_aimed_inside_triangles_hit(
            verts in prop::array::uniform3(prop::array::uniform3(-10.0f32..10.0)),
            offset in prop::array::uniform3(prop_oneof![Just(0.0f32), -1e3f32..1e3]),
            b1 in 0.05f32..0.9,
            b2_frac in 0.0f32..1.0,
            from in prop::array::uniform3(-1.0f32..1.0),
            dist in 0.5f32..100.0,
            scale in 0.01f32..100.0,
        ) {
            let off = Vec3::from(offset);
            let v = verts.map(|p| Vec3::from(p) + off);
            let n = (v[1] - v[0]).cross(v[2] - v[0]);
            let longest = (v[1] - v[0])
                .length_squared()
                .max((v[2] - v[1]).length_squared())
                .max((v[0] - v[2]).length_squared());
            // Reasonably shaped triangles only, so barycentrics are well conditioned.
            prop_assume!(n.length() > 0.1 * longest && longest > 1.0);
            // b1, b2 >= 0.05 and b0 = 1 - b1 - b2 >= 0.05.
            let b2 = 0.05 + b2_frac * (0.9 - b1);
            prop_assume!(b2 <= 0.95 - b1);
            let target = (1.0 - b1 - b2) * v[0] + b1 * v[1] + b2 * v[2];
            let from = Vec3::from(from);
            prop_assume!(from.length() > 0.1);
            let w = from.normalize();
            // Not grazing: at least ~11 degrees off the plane.
            prop_assume!(w.dot(n.normalize()).abs() > 0.2);
            let origin = target + w * dist;
            let r = ray(origin, (target - origin) * scale);
            let expect = (target.as_dvec3() - origin.as_dvec3()).length()
                / f64::from(r.dir.length());
            // Allowed distance error: a few ulps of the largest coordinate involved (the
            // rounded ray passes that close to the target) magnified by the incidence angle.
            let cos = f64::from(w.dot(n.normalize()).abs());
            let magnitude = f64::from(origin.abs().max_element().max(target.abs().max_element()));
            let tol = 4.0 * f64::from(f32::EPSILON) * magnitude / cos;
            let hit = tri_hit(&r, v);
            prop_assert!(hit.is_some(), "miss: v {:?} origin {} target {}", v, origin, target);
            let (t, u, vv) = hit.unwrap();
            let len = f64::from(r.dir.length());
            prop_assert!((f64::from(t) - expect).abs() * len <= tol, "t {} vs {}", t, expect);
            // Barycentric error: the same distance over the triangle's smallest height.
            let height = f64::from(n.length()) / f64::from(longest.sqrt());
            let uv_tol = 2.0 * tol / height + 1e-6;
            prop_assert!(
                f64::from((u - b1).abs()) < uv_tol && f64::from((vv - b2).abs()) < uv_tol,
                "uv {} {} vs {} {}", u, vv, b1, b2
            );
        }
    }
}
