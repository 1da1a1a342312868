//! Rays and hits: the values that pass between the path tracer, the traversal and the simulator.

use glam::Vec3;

/// Default minimum hit distance of the path tracer's rays (LumiBench).
pub const DEFAULT_TMIN: f32 = 0.001;
/// Default maximum hit distance of the path tracer's rays (LumiBench).
pub const DEFAULT_TMAX: f32 = 10000.0;

/// A ray segment: points `origin + t * dir` for `tmin <= t <= tmax`. `dir` need not be unit length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Origin.
    pub origin: Vec3,
    /// Direction.
    pub dir: Vec3,
    /// Nearest accepted hit distance.
    pub tmin: f32,
    /// Farthest accepted hit distance.
    pub tmax: f32,
}

impl Ray {
    /// A ray with the path tracer's default interval.
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Ray {
            origin,
            dir,
            tmin: DEFAULT_TMIN,
            tmax: DEFAULT_TMAX,
        }
    }

    /// Whether every component is finite, the direction is non-zero and tmin <= tmax.
    /// Rays that fail this are reported as misses by every traversal.
    pub fn is_valid(&self) -> bool {
        self.origin.is_finite()
            && self.dir.is_finite()
            && self.dir != Vec3::ZERO
            && !self.tmin.is_nan()
            && !self.tmax.is_nan()
            && self.tmin <= self.tmax
    }

    /// The point at distance `t`.
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }

    /// The ray's eight values as f32 bit patterns: origin xyz, direction xyz, tmin, tmax (the
    /// RT unit's ray words, the binary ray file's order).
    pub fn bits(&self) -> [u32; 8] {
        let (o, d) = (self.origin, self.dir);
        [o.x, o.y, o.z, d.x, d.y, d.z, self.tmin, self.tmax].map(f32::to_bits)
    }
}

/// The closest hit of a ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Hit distance along the ray (in units of `dir`).
    pub t: f32,
    /// Global primitive id: triangles first (`0..scene.triangles.len()`), then spheres.
    pub prim: u32,
    /// First barycentric coordinate (triangles) or 0 (spheres).
    pub u: f32,
    /// Second barycentric coordinate (triangles) or 0 (spheres).
    pub v: f32,
}
