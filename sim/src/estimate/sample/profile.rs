//! The functional profile the sampled tier stratifies by: for every CTA of the frame, the rays
//! its threads trace and the BVH nodes those rays fetch, from the functional path tracer (the
//! same paths, hence the same rays, the simulation traces) in the treelet traversal order the
//! simulated RT units use. One traversal per ray, CTAs in parallel.

use std::time::Instant;

use rayon::prelude::*;

use crate::model::bvh::HwBvh;
use crate::model::config::SimConfig;
use crate::model::gpu::cta_scheduler::CtaScheduler;
use crate::model::scene::Scene;
use crate::model::traversal::{trace_with_fetches, Order};
use crate::model::workload::camera::CameraFrame;
use crate::model::workload::pathtracer::{PathState, RenderError};

/// The work of one CTA.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CtaWork {
    /// Rays its threads trace.
    pub rays: u64,
    /// BVH node fetches of those rays (treelet order, header included).
    pub fetches: u64,
}

/// The work of every CTA of a frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    /// Per CTA, in CTA order (tiles row-major).
    pub ctas: Vec<CtaWork>,
    /// Wall-clock seconds the profile took.
    pub seconds: f64,
}

impl Profile {
    /// Profiles `cfg`'s workload on `scene` (whose BVH is `bvh`) on all rayon threads.
    pub fn new(scene: &Scene, bvh: &HwBvh, cfg: &SimConfig) -> Result<Profile, RenderError> {
        let start = Instant::now();
        let settings = cfg.render_settings();
        settings.validate()?;
        let frame = CameraFrame::new(&scene.camera, settings.width, settings.height)?;
        let scheduler = CtaScheduler::new(settings.width, settings.height, cfg.gpu.threads_per_cta);
        let ctas = (0..scheduler.total())
            .into_par_iter()
            .map_init(Vec::new, |fetches, cta| {
                let mut work = CtaWork::default();
                for pixel in scheduler.pixels(cta).into_iter().flatten() {
                    for sample in 0..settings.spp {
                        let (mut path, mut ray) = PathState::new(&frame, &settings, pixel, sample);
                        loop {
                            fetches.clear();
                            let hit = trace_with_fetches(bvh, &ray, Order::Hardware, fetches);
                            work.rays += 1;
                            work.fetches += fetches.len() as u64;
                            match path.on_hit(scene, hit) {
                                Some(next) => ray = next,
                                None => break,
                            }
                        }
                    }
                }
                work
            })
            .collect();
        Ok(Profile {
            ctas,
            seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// Total work of the CTAs `subset` (all of them with `None`).
    pub fn work(&self, subset: Option<&[u32]>) -> CtaWork {
        let add = |a: CtaWork, b: &CtaWork| CtaWork {
            rays: a.rays + b.rays,
            fetches: a.fetches + b.fetches,
        };
        match subset {
            None => self.ctas.iter().fold(CtaWork::default(), add),
            Some(s) => s
                .iter()
                .map(|&c| &self.ctas[c as usize])
                .fold(CtaWork::default(), add),
        }
    }
}
