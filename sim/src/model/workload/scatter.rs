//! Surface interaction of the path tracer: the hit point and geometric normal of a closest hit,
//! and how each LumiBench material scatters (or absorbs, or emits) the incoming ray.

use glam::Vec3;

use crate::model::geometry::{Hit, Ray};
use crate::model::intersect::offset_ray_origin;
use crate::model::scene::{Material, Scene};
use crate::model::workload::rng::Rng;

/// Where a ray hit a surface, with the geometric normal facing the incoming ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceHit {
    /// Hit point: from the barycentrics for triangles, `ray.at(t)` for spheres.
    pub point: Vec3,
    /// Unit geometric normal, flipped to face against the incoming ray.
    pub normal: Vec3,
    /// Whether the ray hit the outward-facing side (sphere outside, triangle counter-clockwise side).
    pub front_face: bool,
}

impl SurfaceHit {
    /// The hit point and normal of `hit`, a closest hit of `ray` in `scene`.
    pub fn new(scene: &Scene, ray: &Ray, hit: &Hit) -> SurfaceHit {
        let (point, outward) = match scene.sphere_of(hit.prim) {
            Some(sphere) => {
                let p = ray.at(hit.t);
                (p, (p - sphere.center) / sphere.radius)
            }
            None => {
                let [a, b, c] = scene.triangle(hit.prim as usize);
                let p = a * (1.0 - hit.u - hit.v) + b * hit.u + c * hit.v;
                (p, (b - a).cross(c - a).normalize_or_zero())
            }
        };
        // A degenerate normal cannot come from a hit (traversal rejects zero-area triangles);
        // facing the ray keeps the path well-defined regardless.
        let outward = if outward == Vec3::ZERO {
            -ray.dir.normalize()
        } else {
            outward.normalize()
        };
        let front_face = ray.dir.dot(outward) < 0.0;
        SurfaceHit {
            point,
            normal: if front_face { outward } else { -outward },
            front_face,
        }
    }

    /// A ray leaving the surface along `dir`, its origin offset off the surface on the side
    /// `dir` points to.
    fn outgoing(&self, dir: Vec3) -> Ray {
        let side = if dir.dot(self.normal) >= 0.0 {
            self.normal
        } else {
            -self.normal
        };
        Ray::new(offset_ray_origin(self.point, side), dir.normalize())
    }
}

/// What a material does with a ray that hit it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Scatter {
    /// The path continues along `ray`, its throughput multiplied by `attenuation`.
    Scattered {
        /// The next ray (unit direction, default interval).
        ray: Ray,
        /// Per-channel throughput factor.
        attenuation: Vec3,
    },
    /// The path ends at a light that adds `emit` (times the throughput) to the pixel.
    Emitted(Vec3),
    /// The path ends without contribution (e.g. metal scattered below the surface).
    Absorbed,
}

/// Scatter `ray` off `surface` according to `material`, drawing random numbers from `rng`.
pub fn scatter(material: &Material, ray: &Ray, surface: &SurfaceHit, rng: &mut Rng) -> Scatter {
    let n = surface.normal;
    match *material {
        Material::Lambertian { albedo } => {
            let dir = n + rng.in_unit_sphere();
            let dir = if dir.abs().max_element() < 1e-8 {
                n
            } else {
                dir
            };
            Scatter::Scattered {
                ray: surface.outgoing(dir),
                attenuation: albedo,
            }
        }
        Material::Metal { albedo, fuzz } => {
            let reflected = reflect(ray.dir.normalize(), n);
            let dir = reflected + fuzz * rng.in_unit_sphere();
            if dir.dot(n) > 0.0 {
                Scatter::Scattered {
                    ray: surface.outgoing(dir),
                    attenuation: albedo,
                }
            } else {
                Scatter::Absorbed
            }
        }
        Material::Dielectric { ior } => {
            let ratio = if surface.front_face { 1.0 / ior } else { ior };
            let unit = ray.dir.normalize();
            let cos_theta = (-unit).dot(n).min(1.0);
            let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
            let dir = if ratio * sin_theta > 1.0 || schlick(cos_theta, ratio) > rng.next_f32() {
                reflect(unit, n)
            } else {
                refract(unit, n, cos_theta, ratio)
            };
            Scatter::Scattered {
                ray: surface.outgoing(dir),
                attenuation: Vec3::ONE,
            }
        }
        Material::Light { emit } => Scatter::Emitted(emit),
    }
}

/// Mirror `v` about the plane with unit normal `n`.
fn reflect(v: Vec3, n: Vec3) -> Vec3 {
    v - 2.0 * v.dot(n) * n
}

/// Refract unit `v` through the surface with unit normal `n` (facing `v`'s origin side),
/// given `cos_theta = -v.n` and the ratio of refractive indices (Snell; total internal
/// reflection is handled by the caller).
fn refract(v: Vec3, n: Vec3, cos_theta: f32, ratio: f32) -> Vec3 {
    let perp = ratio * (v + cos_theta * n);
    let parallel = -(1.0 - perp.length_squared()).abs().sqrt() * n;
    perp + parallel
}

/// Schlick's approximation of the Fresnel reflectance.
fn schlick(cos_theta: f32, ratio: f32) -> f32 {
    let r0 = ((1.0 - ratio) / (1.0 + ratio)).powi(2);
    r0 + (1.0 - r0) * (1.0 - cos_theta).powi(5)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn surface() -> SurfaceHit {
        SurfaceHit {
            point: Vec3::ZERO,
            normal: Vec3::Y,
            front_face: true,
        }
    }

    #[test]
    fn lambertian_leaves_above_the_surface() {
        let mut rng = Rng::for_pixel(3, 0);
        let incoming = Ray::new(Vec3::new(-1.0, 1.0, 0.0), Vec3::new(1.0, -1.0, 0.0));
        let albedo = Vec3::new(0.2, 0.4, 0.6);
        for _ in 0..100 {
            match scatter(
                &Material::Lambertian { albedo },
                &incoming,
                &surface(),
                &mut rng,
            ) {
                Scatter::Scattered { ray, attenuation } => {
                    assert!(ray.dir.y >= 0.0);
                    assert!(
                        ray.origin.y > 0.0,
                        "origin must be offset above the surface"
                    );
                    assert_eq!(attenuation, albedo);
                }
                other => panic!("lambertian must scatter, got {other:?}"),
            }
        }
    }

    #[test]
    fn smooth_metal_is_a_mirror_and_grazing_fuzz_can_absorb() {
        let mut rng = Rng::for_pixel(5, 0);
        let incoming = Ray::new(Vec3::new(-1.0, 1.0, 0.0), Vec3::new(1.0, -1.0, 0.0));
        let m = Material::Metal {
            albedo: Vec3::ONE,
            fuzz: 0.0,
        };
        match scatter(&m, &incoming, &surface(), &mut rng) {
            Scatter::Scattered { ray, .. } => {
                let expected = Vec3::new(1.0, 1.0, 0.0).normalize();
                assert!((ray.dir - expected).length() < 1e-6);
            }
            other => panic!("mirror must scatter, got {other:?}"),
        }
        let grazing = Ray::new(Vec3::new(-1.0, 1e-3, 0.0), Vec3::new(1.0, -1e-3, 0.0));
        let rough = Material::Metal {
            albedo: Vec3::ONE,
            fuzz: 1.0,
        };
        let absorbed = (0..200)
            .filter(|_| scatter(&rough, &grazing, &surface(), &mut rng) == Scatter::Absorbed)
            .count();
        assert!(
            absorbed > 0,
            "a rough grazing reflection must sometimes go below the surface"
        );
    }

    #[test]
    fn glass_at_normal_incidence_mostly_refracts_straight_through() {
        let mut rng = Rng::for_pixel(9, 0);
        let incoming = Ray::new(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, -1.0, 0.0));
        let glass = Material::Dielectric { ior: 1.5 };
        let mut through = 0;
        for _ in 0..100 {
            if let Scatter::Scattered { ray, attenuation } =
                scatter(&glass, &incoming, &surface(), &mut rng)
            {
                assert_eq!(attenuation, Vec3::ONE);
                if ray.dir.y < 0.0 {
                    assert!((ray.dir - Vec3::NEG_Y).length() < 1e-6);
                    assert!(
                        ray.origin.y < 0.0,
                        "refracted origin must be below the surface"
                    );
                    through += 1;
                }
            }
        }
        // Schlick reflectance at normal incidence for ior 1.5 is 4%.
        assert!(through > 80, "only {through}/100 refracted");
    }

    #[test]
    fn total_internal_reflection_from_inside_glass() {
        let mut rng = Rng::for_pixel(11, 0);
        let inside = SurfaceHit {
            front_face: false,
            ..surface()
        };
        let incoming = Ray::new(Vec3::new(-1.0, 0.2, 0.0), Vec3::new(1.0, -0.2, 0.0));
        match scatter(
            &Material::Dielectric { ior: 1.5 },
            &incoming,
            &inside,
            &mut rng,
        ) {
            Scatter::Scattered { ray, .. } => assert!(ray.dir.y > 0.0),
            other => panic!("glass must scatter, got {other:?}"),
        }
    }

    #[test]
    fn lights_emit() {
        let mut rng = Rng::for_pixel(0, 0);
        let incoming = Ray::new(Vec3::Y, Vec3::NEG_Y);
        let emit = Vec3::new(4.0, 3.0, 2.0);
        assert_eq!(
            scatter(&Material::Light { emit }, &incoming, &surface(), &mut rng),
            Scatter::Emitted(emit)
        );
    }
}
