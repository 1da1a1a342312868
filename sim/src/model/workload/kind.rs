//! Which rays a pixel sample traces: the workload kinds ([`WorkloadKind`], `[workload]`
//! `kind`), resolved for a scene ([`Workload`]), and the per-sample state machine over every
//! kind ([`SampleState`]) that the functional renderer, the sampled tier's profile and the
//! simulator's raygen threads all start through a [`Sampler`] and drive one [`TraceRay`] at a
//! time.

use std::sync::Arc;

use glam::Vec3;

use crate::model::geometry::{Hit, Ray};
use crate::model::scene::Scene;
use crate::model::workload::ao::AoState;
use crate::model::workload::camera::CameraFrame;
use crate::model::workload::path_nee::{Emitters, PathNeeState};
use crate::model::workload::pathtracer::{camera_ray, PathState, RenderSettings, Tracer};
use crate::model::workload::ray_file::RaySet;
use crate::model::workload::rng::Rng;

/// A workload kind with its parameters, as configured.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum WorkloadKind {
    /// The LumiBench path tracer (closest-hit rays; `spp` and `bounces`).
    #[default]
    Path,
    /// Ambient occlusion: a primary ray per sample, then `rays` occlusion rays per primary
    /// hit, each `radius` long as a fraction of the scene's bounding-box diagonal.
    Ao {
        /// Occlusion rays per primary hit.
        rays: u32,
        /// Their length, as a fraction of the scene's bounding-box diagonal.
        radius: f32,
    },
    /// Rays from a file, one per pixel of a one-row image, in file order (each closest-hit or
    /// occlusion as the file says).
    Rays(Arc<RaySet>),
    /// The path tracer with a shadow ray toward a sampled emitter at each diffuse hit.
    PathNee,
    /// The path tracer with its primary hits taken as given, as a rasterizer's G-buffer would
    /// give them: only the secondary rays are traced (`spp` and `bounces` as the path tracer).
    Hybrid,
}

/// A workload resolved for one scene (lengths in the scene's units); build it once per run.
#[derive(Debug, Clone, PartialEq)]
pub enum Workload {
    /// The path tracer.
    Path,
    /// Ambient occlusion with occlusion rays of length `radius` (scene units).
    Ao {
        /// Occlusion rays per primary hit.
        rays: u32,
        /// Their length in scene units.
        radius: f32,
    },
    /// Rays from a file: pixel `p` traces ray `p`.
    Rays(Arc<RaySet>),
    /// The path tracer with next-event estimation toward the scene's emitting triangles.
    PathNee(Arc<Emitters>),
    /// The path tracer without tracing its primary rays.
    Hybrid,
}

impl Workload {
    /// `settings`' workload in `scene`.
    pub fn new(settings: &RenderSettings, scene: &Scene) -> Self {
        match &settings.kind {
            WorkloadKind::Path => Workload::Path,
            WorkloadKind::Hybrid => Workload::Hybrid,
            WorkloadKind::Rays(set) => Workload::Rays(set.clone()),
            WorkloadKind::PathNee => Workload::PathNee(Arc::new(Emitters::of(scene))),
            &WorkloadKind::Ao { rays, radius } => {
                let diagonal = scene.bounds().map_or(0.0, |(lo, hi)| (hi - lo).length());
                Workload::Ao {
                    rays,
                    radius: radius * diagonal,
                }
            }
        }
    }
}

/// A ray to trace and what is asked of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceRay {
    /// The ray.
    pub ray: Ray,
    /// An occlusion ray: only whether it hits anything is asked (the RT unit's
    /// terminate-on-first-hit flag); otherwise its closest hit.
    pub occlusion: bool,
}

/// One pixel sample in flight, of any workload kind.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SampleState {
    /// A path.
    Path(PathState),
    /// An ambient-occlusion sample.
    Ao(AoState),
    /// A path with next-event estimation.
    PathNee(PathNeeState),
    /// One ray from a file; `hit` once answered.
    Ray {
        /// Whether the ray hit something (`None` until answered).
        hit: Option<bool>,
    },
}

/// What starting and answering a pixel sample needs: the scene and its workload, the camera
/// frame and image settings, and the `raster` that gives a hybrid frame's primary hits (the
/// functional closest hit, as a rasterizer's G-buffer would hold it; not timed).
#[derive(Clone, Copy)]
pub struct Sampler<'a> {
    /// The scene (materials for shading).
    pub scene: &'a Scene,
    /// Its workload.
    pub workload: &'a Workload,
    /// The camera frame for `settings`' image size.
    pub frame: &'a CameraFrame,
    /// Image size and path limits.
    pub settings: &'a RenderSettings,
    /// The primary hits of hybrid frames.
    pub raster: &'a dyn Tracer,
}

impl Sampler<'_> {
    /// Starts sample `sample` of row-major pixel `pixel`: its state and the first ray it
    /// traces, or `None` when it traces none (a hybrid sample whose given primary hit ends the
    /// path: a miss, an emitter, or no bounce left).
    pub fn start(&self, pixel: u32, sample: u32) -> (SampleState, Option<TraceRay>) {
        let (mut state, first) =
            SampleState::new(self.workload, self.frame, self.settings, pixel, sample);
        if !matches!(self.workload, Workload::Hybrid) {
            return (state, Some(first));
        }
        let hit = self.raster.closest_hit(&first.ray);
        let next = state.on_answer(self.workload, self.scene, hit);
        (state, next)
    }

    /// Consumes the answer to `state`'s last ray and returns its next ray, or `None` when the
    /// sample has ended ([`SampleState::on_answer`]).
    pub fn answer(&self, state: &mut SampleState, hit: Option<Hit>) -> Option<TraceRay> {
        state.on_answer(self.workload, self.scene, hit)
    }
}

impl SampleState {
    /// Starts sample `sample` of row-major pixel `pixel`; returns the state and its first ray
    /// (a hybrid sample's primary ray, which [`Sampler::start`] answers without tracing it).
    /// `frame` must be the camera frame for `settings`' image size.
    fn new(
        workload: &Workload,
        frame: &CameraFrame,
        settings: &RenderSettings,
        pixel: u32,
        sample: u32,
    ) -> (SampleState, TraceRay) {
        let closest = |ray| TraceRay {
            ray,
            occlusion: false,
        };
        match workload {
            Workload::Path | Workload::Hybrid => {
                let (path, ray) = PathState::new(frame, settings, pixel, sample);
                (SampleState::Path(path), closest(ray))
            }
            Workload::PathNee(_) => {
                // The path tracer's camera and stream; the light samples draw from their own.
                let (rng, ray) = camera_ray(frame, settings, pixel, sample);
                let light_rng = Rng::for_pixel(pixel, sample ^ 0x4000_0000);
                let max_rays = settings.bounces.saturating_add(1);
                let state = PathNeeState::new(ray, rng, light_rng, max_rays);
                (SampleState::PathNee(state), closest(ray))
            }
            &Workload::Ao { rays, radius } => {
                // The path tracer's primary ray; the occlusion rays draw from a stream of their
                // own.
                let (_, ray) = camera_ray(frame, settings, pixel, sample);
                let rng = Rng::for_pixel(pixel, sample ^ 0x8000_0000);
                (
                    SampleState::Ao(AoState::new(ray, rng, rays, radius)),
                    closest(ray),
                )
            }
            Workload::Rays(set) => {
                // The configuration makes the image one row of one pixel per ray (a pixel past
                // the file would trace an invalid ray: a miss).
                let ray = (set.rays.get(pixel as usize).copied())
                    .unwrap_or_else(|| closest(Ray::new(Vec3::ZERO, Vec3::ZERO)));
                (SampleState::Ray { hit: None }, ray)
            }
        }
    }

    /// Consumes the answer to the last ray — its closest hit, or for an occlusion ray any hit
    /// (only whether there is one is used) — and returns the next ray, or `None` when the
    /// sample has ended. Calling it after the end returns `None` and changes nothing.
    fn on_answer(
        &mut self,
        workload: &Workload,
        scene: &Scene,
        hit: Option<Hit>,
    ) -> Option<TraceRay> {
        match self {
            SampleState::PathNee(p) => {
                let Workload::PathNee(emitters) = workload else {
                    return None;
                };
                let (ray, occlusion) = p.on_answer(scene, emitters, hit)?;
                Some(TraceRay { ray, occlusion })
            }
            SampleState::Path(p) => p.on_hit(scene, hit).map(|ray| TraceRay {
                ray,
                occlusion: false,
            }),
            SampleState::Ao(a) => a.on_answer(scene, hit).map(|ray| TraceRay {
                ray,
                occlusion: true,
            }),
            SampleState::Ray { hit: answer } => {
                answer.get_or_insert(hit.is_some());
                None
            }
        }
    }

    /// Adds the ended sample's radiance to its pixel's `sum`, or, when it is NaN or infinite
    /// (the sample then contributes black), counts it in `nonfinite`: how the functional
    /// renderer and the simulator's raygen threads both accumulate a pixel.
    pub fn add_to(&self, sum: &mut Vec3, nonfinite: &mut u64) {
        let l = self.radiance();
        if l.is_finite() {
            *sum += l;
        } else {
            *nonfinite += 1;
        }
    }

    /// Radiance gathered so far (final once the sample has ended).
    pub fn radiance(&self) -> Vec3 {
        match self {
            SampleState::Path(p) => p.radiance(),
            SampleState::Ao(a) => a.radiance(),
            SampleState::PathNee(p) => p.radiance(),
            // A ray from a file: white where it hit something, black where it missed.
            SampleState::Ray { hit } => Vec3::splat(f32::from(u8::from(hit.unwrap_or(false)))),
        }
    }
}
