//! The ambient-occlusion workload (`workload.kind = "ao"`): per pixel sample a primary ray
//! (closest hit), then, where it hit, `rays` occlusion rays from the hit point into the
//! cosine-weighted hemisphere of its normal, each reaching `radius`. The sample's radiance is
//! the unoccluded fraction (white); a primary miss sees the sky. Occlusion rays carry the RT
//! unit's terminate-on-first-hit flag, so only whether each hits matters: the image does not
//! depend on the traversal order.

use glam::Vec3;

use crate::model::geometry::{Hit, Ray};
use crate::model::intersect::offset_ray_origin;
use crate::model::scene::Scene;
use crate::model::workload::pathtracer::sky;
use crate::model::workload::rng::Rng;
use crate::model::workload::scatter::SurfaceHit;

/// One ambient-occlusion sample in flight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AoState {
    rng: Rng,
    /// The primary ray (until it is answered).
    primary: Ray,
    /// Where the occlusion rays start (offset off the surface) and the surface normal.
    origin: Vec3,
    normal: Vec3,
    /// Occlusion rays per hit and their length.
    rays: u32,
    radius: f32,
    /// Occlusion rays handed out and, of those answered, the unoccluded ones.
    issued: u32,
    open: u32,
    radiance: Vec3,
    done: bool,
}

impl AoState {
    /// The sample whose primary ray is `primary` (from `rng`'s stream), with `rays` occlusion
    /// rays of length `radius` per hit.
    pub fn new(primary: Ray, rng: Rng, rays: u32, radius: f32) -> Self {
        AoState {
            rng,
            primary,
            origin: Vec3::ZERO,
            normal: Vec3::ZERO,
            rays,
            radius,
            issued: 0,
            open: 0,
            radiance: Vec3::ZERO,
            done: false,
        }
    }

    /// Consumes the answer to the last ray handed out — the primary ray's closest hit, then
    /// whether each occlusion ray hit something — and returns the next occlusion ray, or
    /// `None` when the sample has ended.
    pub fn on_answer(&mut self, scene: &Scene, hit: Option<Hit>) -> Option<Ray> {
        if self.done {
            return None;
        }
        if self.issued == 0 {
            let Some(hit) = hit else {
                self.radiance = sky(scene, self.primary.dir);
                self.done = true;
                return None;
            };
            let surface = SurfaceHit::new(scene, &self.primary, &hit);
            self.normal = surface.normal;
            self.origin = offset_ray_origin(surface.point, surface.normal);
        } else {
            self.open += u32::from(hit.is_none());
        }
        if self.issued == self.rays {
            self.radiance = Vec3::splat(self.open as f32 / self.rays.max(1) as f32);
            self.done = true;
            return None;
        }
        self.issued += 1;
        // Cosine-weighted about the normal (as the Lambertian scatter of the path tracer).
        let dir = self.normal + self.rng.in_unit_sphere();
        let dir = if dir.abs().max_element() < 1e-8 {
            self.normal
        } else {
            dir
        };
        let mut ray = Ray::new(self.origin, dir.normalize());
        ray.tmax = self.radius;
        Some(ray)
    }

    /// Radiance gathered so far (final once the sample has ended).
    pub fn radiance(&self) -> Vec3 {
        self.radiance
    }
}
