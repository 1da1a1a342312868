//! The LumiBench path tracer: a per-pixel-sample state machine ([`PathState`]) that turns closest
//! hits into the next ray, and [`render`], which drives it over a whole image with any [`Tracer`].
//!
//! The cycle-level simulator drives [`PathState`] itself with hits it computes; [`render`] is the
//! functional reference that records the exact ray sequence of every pixel.

use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use crate::model::bvh::HwBvh;
use crate::model::geometry::{Hit, Ray};
use crate::model::intersect::{ray_sphere, ray_triangle, RayPrecomp};
use crate::model::scene::{Material, Scene};
use crate::model::traversal::{trace, trace_occlusion, Order};
use crate::model::workload::camera::{CameraError, CameraFrame};
use crate::model::workload::kind::{Sampler, TraceRay, Workload, WorkloadKind};
use crate::model::workload::rng::Rng;
use crate::model::workload::scatter::{scatter, Scatter, SurfaceHit};

/// Finds the closest hit of a ray in a scene (the BVH traversal, or brute force in tests).
pub trait Tracer: Sync {
    /// The closest hit of `ray` within `[ray.tmin, ray.tmax]`, or `None` (also for invalid rays).
    fn closest_hit(&self, ray: &Ray) -> Option<Hit>;

    /// Whether `ray` hits anything within `[ray.tmin, ray.tmax]` (an occlusion ray; `false`
    /// for invalid rays): whether [`Tracer::closest_hit`] finds a hit.
    fn occluded(&self, ray: &Ray) -> bool {
        self.closest_hit(ray).is_some()
    }
}

impl Tracer for HwBvh {
    /// Ray-stationary traversal of the hardware BVH (both orders find the same closest hit).
    fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        trace(self, ray, Order::RayStationary)
    }

    /// An occlusion ray's ray-stationary traversal: it stops at its first hit.
    fn occluded(&self, ray: &Ray) -> bool {
        trace_occlusion(self, ray, Order::RayStationary).is_some()
    }
}

/// Tests every primitive of a scene: the reference tracer for small scenes and tests.
#[derive(Debug, Clone, Copy)]
pub struct BruteForce<'a> {
    /// The scene whose primitives are tested.
    pub scene: &'a Scene,
}

impl Tracer for BruteForce<'_> {
    fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        if !ray.is_valid() {
            return None;
        }
        let pre = RayPrecomp::new(ray);
        let mut closest: Option<Hit> = None;
        let mut tmax = ray.tmax;
        let tris = self.scene.triangles.len();
        for i in 0..tris {
            if let Some((t, u, v)) = ray_triangle(&pre, self.scene.triangle(i), ray.tmin, tmax) {
                tmax = t;
                closest = Some(Hit {
                    t,
                    prim: i as u32,
                    u,
                    v,
                });
            }
        }
        for (i, s) in self.scene.spheres.iter().enumerate() {
            if let Some(t) = ray_sphere(ray, s.center, s.radius, ray.tmin, tmax) {
                tmax = t;
                closest = Some(Hit {
                    t,
                    prim: (tris + i) as u32,
                    u: 0.0,
                    v: 0.0,
                });
            }
        }
        closest
    }
}

/// The answer the functional renderer gives an occlusion ray that hits (only its presence is
/// read).
const OCCLUDED: Hit = Hit {
    t: 0.0,
    prim: 0,
    u: 0.0,
    v: 0.0,
};

/// Image size, the workload kind and path-tracing limits (the paper's workload: 256x256,
/// the path tracer, 1 spp, 3 bounces).
#[derive(Debug, Clone, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples (paths) per pixel.
    pub spp: u32,
    /// Maximum secondary rays per path (a path traces at most `1 + bounces` rays).
    pub bounces: u32,
    /// Which rays each sample traces.
    pub kind: WorkloadKind,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 256,
            height: 256,
            spp: 1,
            bounces: 3,
            kind: WorkloadKind::Path,
        }
    }
}

/// A render could not start: the settings or the scene's camera are unusable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RenderError {
    /// Width, height or spp is zero, or the image has more pixels than fit a `u32` index.
    #[error("invalid render settings: {0}")]
    Settings(String),
    /// The scene's camera does not define a view.
    #[error("scene camera: {0}")]
    Camera(#[from] CameraError),
}

impl RenderSettings {
    /// Check that the settings describe a non-empty image with `u32` pixel indices.
    pub fn validate(&self) -> Result<(), RenderError> {
        if self.width == 0 || self.height == 0 || self.spp == 0 {
            return Err(RenderError::Settings(format!(
                "width ({}), height ({}) and spp ({}) must be at least 1",
                self.width, self.height, self.spp
            )));
        }
        if u64::from(self.width) * u64::from(self.height) > u64::from(u32::MAX) {
            return Err(RenderError::Settings(format!(
                "{}x{} pixels do not fit a 32-bit pixel index",
                self.width, self.height
            )));
        }
        Ok(())
    }

    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

/// The sky seen by rays that miss: the RTIOW gradient from white (down) to (0.5, 0.7, 1.0) (up),
/// or black when the scene has no sky.
pub fn sky(scene: &Scene, dir: Vec3) -> Vec3 {
    if !scene.sky {
        return Vec3::ZERO;
    }
    let a = 0.5 * (dir.normalize().y + 1.0);
    Vec3::ONE.lerp(Vec3::new(0.5, 0.7, 1.0), a)
}

/// The primary ray of sample `sample` of row-major pixel `pixel` and the sample's random
/// stream after the camera's draws.
pub fn camera_ray(
    frame: &CameraFrame,
    settings: &RenderSettings,
    pixel: u32,
    sample: u32,
) -> (Rng, Ray) {
    let mut rng = Rng::for_pixel(pixel, sample);
    let ray = frame.ray(pixel % settings.width, pixel / settings.width, &mut rng);
    (rng, ray)
}

/// One path (one sample of one pixel) in flight: the ray it is waiting on, its throughput and the
/// radiance gathered so far.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathState {
    rng: Rng,
    ray: Ray,
    throughput: Vec3,
    radiance: Vec3,
    /// Rays handed out so far (the primary ray counts).
    rays: u32,
    /// `1 + bounces`.
    max_rays: u32,
    done: bool,
}

impl PathState {
    /// Start sample `sample` of row-major pixel `pixel` (`y * width + x`); returns the state and
    /// its primary ray. `frame` must be the camera frame for `settings`' image size.
    pub fn new(
        frame: &CameraFrame,
        settings: &RenderSettings,
        pixel: u32,
        sample: u32,
    ) -> (PathState, Ray) {
        let (rng, ray) = camera_ray(frame, settings, pixel, sample);
        let state = PathState {
            rng,
            ray,
            throughput: Vec3::ONE,
            radiance: Vec3::ZERO,
            rays: 1,
            max_rays: settings.bounces.saturating_add(1),
            done: false,
        };
        (state, ray)
    }

    /// Consume the closest hit (or miss) of the current ray; returns the next ray, or `None`
    /// when the path has ended (miss: sky or black; light; absorbed; bounce limit reached).
    /// Calling it again after the path ended returns `None` and changes nothing.
    pub fn on_hit(&mut self, scene: &Scene, hit: Option<Hit>) -> Option<Ray> {
        if self.done {
            return None;
        }
        let Some(hit) = hit else {
            self.radiance += self.throughput * sky(scene, self.ray.dir);
            self.done = true;
            return None;
        };
        let material = scene.material_of(hit.prim);
        if self.rays >= self.max_rays && !matches!(material, Material::Light { .. }) {
            self.done = true;
            return None;
        }
        let surface = SurfaceHit::new(scene, &self.ray, &hit);
        match scatter(material, &self.ray, &surface, &mut self.rng) {
            Scatter::Scattered { ray, attenuation } => {
                self.throughput *= attenuation;
                self.ray = ray;
                self.rays += 1;
                Some(ray)
            }
            Scatter::Emitted(emit) => {
                self.radiance += self.throughput * emit;
                self.done = true;
                None
            }
            Scatter::Absorbed => {
                self.done = true;
                None
            }
        }
    }

    /// Radiance gathered so far (final once the path has ended).
    pub fn radiance(&self) -> Vec3 {
        self.radiance
    }

    /// Whether the path has ended.
    pub fn is_done(&self) -> bool {
        self.done
    }

    /// Rays this path has traced or is tracing (primary included).
    pub fn rays(&self) -> u32 {
        self.rays
    }
}

/// Counters of one render.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RenderStats {
    /// Rays traced (primary + secondary, all samples; occlusion rays included).
    pub rays_traced: u64,
    /// Of those, occlusion rays (only whether they hit is asked).
    pub occlusion_rays: u64,
    /// Samples whose radiance was NaN or infinite; they contribute black to their pixel.
    pub nonfinite_samples: u64,
    /// Wall-clock time of the render in seconds (informational only).
    pub wall_seconds: f64,
}

/// A rendered image and the exact rays every pixel traced.
#[derive(Debug, Clone, PartialEq)]
pub struct Render {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Linear radiance per pixel, row-major from the top row, averaged over samples.
    pub image: Vec<Vec3>,
    /// Every ray traced, grouped by pixel in pixel order (samples in order within a pixel).
    pub rays: Vec<Ray>,
    /// Per ray of `rays`, whether it is an occlusion ray.
    pub occlusion: Vec<bool>,
    /// `rays[ray_offsets[p]..ray_offsets[p + 1]]` are pixel `p`'s rays (length = pixels + 1).
    pub ray_offsets: Vec<usize>,
    /// Counters.
    pub stats: RenderStats,
}

impl Render {
    /// The rays pixel `pixel` traced, in order.
    pub fn pixel_rays(&self, pixel: usize) -> &[Ray] {
        &self.rays[self.ray_offsets[pixel]..self.ray_offsets[pixel + 1]]
    }

    /// Every ray traced with its occlusion flag, in the order of `rays`.
    pub fn trace_rays(&self) -> Vec<TraceRay> {
        (self.rays.iter().zip(&self.occlusion))
            .map(|(&ray, &occlusion)| TraceRay { ray, occlusion })
            .collect()
    }
}

/// One row's result.
struct RowResult {
    colors: Vec<Vec3>,
    rays: Vec<Ray>,
    /// Per ray, whether it is an occlusion ray.
    occlusion: Vec<bool>,
    /// Rays per pixel of the row.
    counts: Vec<usize>,
    nonfinite: u64,
}

/// Trace every sample of every pixel of row `y`.
fn render_row(
    scene: &Scene,
    tracer: &impl Tracer,
    (workload, frame): (&Workload, &CameraFrame),
    settings: &RenderSettings,
    y: u32,
) -> RowResult {
    let mut row = RowResult {
        colors: Vec::with_capacity(settings.width as usize),
        rays: Vec::new(),
        counts: Vec::with_capacity(settings.width as usize),
        nonfinite: 0,
        occlusion: Vec::new(),
    };
    let sampler = Sampler {
        scene,
        workload,
        frame,
        settings,
        raster: tracer,
    };
    for x in 0..settings.width {
        let pixel = y * settings.width + x;
        let before = row.rays.len();
        let mut sum = Vec3::ZERO;
        for sample in 0..settings.spp {
            let (mut state, mut next) = sampler.start(pixel, sample);
            while let Some(ray) = next {
                row.rays.push(ray.ray);
                row.occlusion.push(ray.occlusion);
                let hit = if ray.occlusion {
                    // Only whether an occlusion ray hits is used.
                    tracer.occluded(&ray.ray).then_some(OCCLUDED)
                } else {
                    tracer.closest_hit(&ray.ray)
                };
                next = sampler.answer(&mut state, hit);
            }
            state.add_to(&mut sum, &mut row.nonfinite);
        }
        row.colors.push(sum / settings.spp as f32);
        row.counts.push(row.rays.len() - before);
    }
    row
}

/// Render `scene` with `tracer` on all rayon threads. Pixels are independent and collected in
/// pixel order, so the result is bit-identical to [`render_serial`]. `progress` (if any) advances
/// by one per image row.
pub fn render(
    scene: &Scene,
    tracer: &impl Tracer,
    settings: &RenderSettings,
    progress: Option<&indicatif::ProgressBar>,
) -> Result<Render, RenderError> {
    render_with(scene, tracer, settings, progress, true)
}

/// [`render`] on the calling thread only.
pub fn render_serial(
    scene: &Scene,
    tracer: &impl Tracer,
    settings: &RenderSettings,
    progress: Option<&indicatif::ProgressBar>,
) -> Result<Render, RenderError> {
    render_with(scene, tracer, settings, progress, false)
}

fn render_with(
    scene: &Scene,
    tracer: &impl Tracer,
    settings: &RenderSettings,
    progress: Option<&indicatif::ProgressBar>,
    parallel: bool,
) -> Result<Render, RenderError> {
    settings.validate()?;
    let frame = CameraFrame::new(&scene.camera, settings.width, settings.height)?;
    let workload = Workload::new(settings, scene);
    let start = Instant::now();
    let row = |y: u32| {
        let r = render_row(scene, tracer, (&workload, &frame), settings, y);
        if let Some(p) = progress {
            p.inc(1);
        }
        r
    };
    let rows: Vec<RowResult> = if parallel {
        (0..settings.height).into_par_iter().map(row).collect()
    } else {
        (0..settings.height).map(row).collect()
    };

    let mut image = Vec::with_capacity(settings.pixels());
    let mut rays = Vec::with_capacity(rows.iter().map(|r| r.rays.len()).sum());
    let mut ray_offsets = Vec::with_capacity(settings.pixels() + 1);
    ray_offsets.push(0);
    let mut nonfinite = 0;
    let mut occlusion = Vec::with_capacity(rays.capacity());
    for r in rows {
        image.extend_from_slice(&r.colors);
        rays.extend_from_slice(&r.rays);
        for c in r.counts {
            ray_offsets.push(ray_offsets[ray_offsets.len() - 1] + c);
        }
        nonfinite += r.nonfinite;
        occlusion.extend_from_slice(&r.occlusion);
    }
    Ok(Render {
        width: settings.width,
        height: settings.height,
        image,
        stats: RenderStats {
            rays_traced: rays.len() as u64,
            occlusion_rays: occlusion.iter().filter(|&&o| o).count() as u64,
            nonfinite_samples: nonfinite,
            wall_seconds: start.elapsed().as_secs_f64(),
        },
        rays,
        occlusion,
        ray_offsets,
    })
}
