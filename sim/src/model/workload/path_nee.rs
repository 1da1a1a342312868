//! The path tracer with next-event estimation (`workload.kind = "path-nee"`): the path
//! tracer's paths (the same camera and scattering), and at each diffuse hit a shadow ray —
//! an occlusion ray — toward a sampled emitter, traced before the path goes on:
//!
//! - a point on the scene's emitting triangles, by area, when it has any: an unoccluded
//!   shadow ray adds the emitter's light reflected as the path tracer's diffuse bounce
//!   reflects it (its directions n + a point in the unit ball have density 2 cos^3 / pi and
//!   carry the albedo: a reflectance of albedo x 2 cos^2 / pi), so both estimate one image;
//! - otherwise, in a scene lit by its sky, a direction drawn as the diffuse bounce draws it:
//!   an unoccluded shadow ray adds the sky seen that way, weighted by the albedo (the path
//!   tracer's own estimator of the sky's light).
//!
//! A path that reaches the sampled light after a diffuse bounce (a sampled emitter, or the sky
//! when it is sampled) does not add it again. Emitting spheres are not sampled: their light
//! arrives by the paths alone, as in the plain path tracer.

use std::f32::consts::PI;

use glam::Vec3;

use crate::model::geometry::{Hit, Ray};
use crate::model::intersect::offset_ray_origin;
use crate::model::scene::{Material, Scene};
use crate::model::workload::pathtracer::sky;
use crate::model::workload::rng::Rng;
use crate::model::workload::scatter::{scatter, Scatter, SurfaceHit};

/// The end of a shadow ray, as a fraction of the way to the sampled point: it stops short of
/// the emitter's own surface.
const SHADOW_END: f32 = 0.999;

/// The lights next-event estimation samples: the scene's emitting triangles by area, or,
/// without any, its sky.
#[derive(Debug, Clone, PartialEq)]
pub struct Emitters {
    /// Per emitter: its vertices and emitted radiance.
    triangles: Vec<([Vec3; 3], Vec3)>,
    /// Running sums of their areas (the last is the total).
    cdf: Vec<f32>,
    /// The sky is sampled (no emitting triangle, and the scene has a sky).
    sky: bool,
}

impl Emitters {
    /// The emitting triangles of `scene` with a positive area.
    pub fn of(scene: &Scene) -> Self {
        let mut triangles = Vec::new();
        let mut cdf = Vec::new();
        let mut total = 0.0f32;
        for i in 0..scene.triangles.len() {
            let Material::Light { emit } = *scene.material_of(i as u32) else {
                continue;
            };
            let [a, b, c] = scene.triangle(i);
            let area = 0.5 * (b - a).cross(c - a).length();
            if area > 0.0 && area.is_finite() {
                total += area;
                triangles.push(([a, b, c], emit));
                cdf.push(total);
            }
        }
        let sky = triangles.is_empty() && scene.sky;
        Emitters {
            triangles,
            cdf,
            sky,
        }
    }

    /// Whether the sky is the sampled light.
    pub fn samples_sky(&self) -> bool {
        self.sky
    }

    /// Whether there is nothing to sample (no emitting triangle, no sky): no shadow ray.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty() && !self.sky
    }

    /// Total emitting area.
    fn area(&self) -> f32 {
        self.cdf.last().copied().unwrap_or(0.0)
    }

    /// A point on the emitters, uniform by area, with its unit normal and radiance.
    fn sample(&self, rng: &mut Rng) -> Option<(Vec3, Vec3, Vec3)> {
        let pick = rng.next_f32() * self.area();
        let k = (self.cdf.partition_point(|&c| c <= pick)).min(self.triangles.len() - 1);
        let ([a, b, c], emit) = *self.triangles.get(k)?;
        let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let normal = (b - a).cross(c - a).normalize_or_zero();
        Some((a + (b - a) * u + (c - a) * v, normal, emit))
    }
}

/// One path with next-event estimation in flight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathNeeState {
    /// The path's random numbers (the path tracer's stream).
    rng: Rng,
    /// The light samples' random numbers (a stream of their own).
    light_rng: Rng,
    /// The path ray last handed out (or waiting behind a shadow ray).
    ray: Ray,
    throughput: Vec3,
    radiance: Vec3,
    /// Path rays handed out (the primary counts; shadow rays do not).
    rays: u32,
    max_rays: u32,
    /// Whether a hit emitter's light counts: the camera ray, after a specular bounce, or an
    /// emitter NEE does not sample (a sphere).
    count_emission: bool,
    /// A shadow ray is out: its light if it arrives, then the path ray to go on with, if any.
    shadow: Option<(Vec3, Option<Ray>)>,
    done: bool,
}

impl PathNeeState {
    /// The path of primary ray `ray`, drawing from `rng` (after the camera's draws) and its
    /// light samples from `light_rng`, with at most `max_rays` path rays.
    pub fn new(ray: Ray, rng: Rng, light_rng: Rng, max_rays: u32) -> Self {
        PathNeeState {
            rng,
            light_rng,
            ray,
            throughput: Vec3::ONE,
            radiance: Vec3::ZERO,
            rays: 1,
            max_rays,
            count_emission: true,
            shadow: None,
            done: false,
        }
    }

    /// Consumes the answer to the last ray — a path ray's closest hit or whether a shadow ray
    /// hit anything — and returns the next ray and whether it is a shadow (occlusion) ray, or
    /// `None` when the path has ended.
    pub fn on_answer(
        &mut self,
        scene: &Scene,
        emitters: &Emitters,
        hit: Option<Hit>,
    ) -> Option<(Ray, bool)> {
        if self.done {
            return None;
        }
        if let Some((light, next)) = self.shadow.take() {
            if hit.is_none() {
                self.radiance += light;
            }
            return self.go_on(next);
        }
        let Some(hit) = hit else {
            if self.count_emission || !emitters.samples_sky() {
                self.radiance += self.throughput * sky(scene, self.ray.dir);
            }
            return self.go_on(None);
        };
        let material = *scene.material_of(hit.prim);
        if let Material::Light { emit } = material {
            let sampled = scene.sphere_of(hit.prim).is_none();
            if self.count_emission || !sampled {
                self.radiance += self.throughput * emit;
            }
            return self.go_on(None);
        }
        let surface = SurfaceHit::new(scene, &self.ray, &hit);
        let light = match material {
            Material::Lambertian { albedo } => {
                self.light_sample((scene, emitters), &surface, albedo)
            }
            _ => None,
        };
        let next = if self.rays < self.max_rays {
            match scatter(&material, &self.ray, &surface, &mut self.rng) {
                Scatter::Scattered { ray, attenuation } => {
                    self.throughput *= attenuation;
                    self.count_emission = !matches!(material, Material::Lambertian { .. });
                    Some(ray)
                }
                Scatter::Emitted(_) | Scatter::Absorbed => None,
            }
        } else {
            None
        };
        match light {
            Some((shadow, light)) => {
                self.shadow = Some((light, next));
                Some((shadow, true))
            }
            None => self.go_on(next),
        }
    }

    /// Hands out the path ray `next`, or ends the path.
    fn go_on(&mut self, next: Option<Ray>) -> Option<(Ray, bool)> {
        match next {
            Some(ray) => {
                self.ray = ray;
                self.rays += 1;
                Some((ray, false))
            }
            None => {
                self.done = true;
                None
            }
        }
    }

    /// A shadow ray from `surface` toward a point sampled on the emitters (or a direction
    /// toward the sky) and the light it brings if unoccluded (Lambertian `albedo`); `None`
    /// when there is nothing to sample or the point faces away.
    fn light_sample(
        &mut self,
        (scene, emitters): (&Scene, &Emitters),
        surface: &SurfaceHit,
        albedo: Vec3,
    ) -> Option<(Ray, Vec3)> {
        if emitters.is_empty() {
            return None;
        }
        let origin = offset_ray_origin(surface.point, surface.normal);
        if emitters.samples_sky() {
            // As the diffuse bounce draws its direction, so the weight is the albedo.
            let n = surface.normal;
            let dir = n + self.light_rng.in_unit_sphere();
            let dir = if dir.abs().max_element() < 1e-8 {
                n
            } else {
                dir
            };
            let ray = Ray::new(origin, dir.normalize());
            return Some((ray, self.throughput * albedo * sky(scene, ray.dir)));
        }
        let (point, normal, emit) = emitters.sample(&mut self.light_rng)?;
        let to = point - origin;
        let d2 = to.length_squared();
        let wi = to / d2.sqrt();
        let (cos_s, cos_l) = (surface.normal.dot(wi), normal.dot(wi).abs());
        if !(cos_s > 0.0 && cos_l > 0.0 && d2 > 0.0 && d2.is_finite()) {
            return None;
        }
        // The diffuse reflection the path tracer's bounce implies: it draws n + a point in
        // the unit ball (density 2 cos^3 / pi) and weighs by the albedo, so its reflectance is
        // albedo x 2 cos^2 / pi; the same here, so both estimate the same image.
        let reflect = albedo * (2.0 * cos_s * cos_s / PI);
        let light = self.throughput * reflect * emit * (cos_s * cos_l * emitters.area() / d2);
        let mut ray = Ray::new(origin, to);
        ray.tmax = SHADOW_END;
        Some((ray, light))
    }

    /// Radiance gathered so far (final once the path has ended).
    pub fn radiance(&self) -> Vec3 {
        self.radiance
    }
}
