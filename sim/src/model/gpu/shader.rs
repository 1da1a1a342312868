//! The shaders run on the SMs: the raygen thread of one pixel ([`PathThread`], which drives the
//! workload's [`SampleState`] — a path, or an ambient-occlusion sample — with the answers the
//! RT unit returns) and the timing model of shader invocations ([`ShaderTiming`]).

use glam::Vec3;

use crate::model::config::GpuConfig;
use crate::model::geometry::{Hit, Ray};
use crate::model::scene::Scene;
use crate::model::workload::camera::CameraFrame;
use crate::model::workload::kind::{SampleState, TraceRay, Workload};
use crate::model::workload::pathtracer::RenderSettings;

/// One raygen thread: one pixel, its samples traced one after another (sample order, as
/// [`crate::model::workload::pathtracer::render`] accumulates them), one ray at a time, for
/// any workload kind.
#[derive(Debug, Clone)]
pub struct PathThread {
    pixel: u32,
    sample: u32,
    path: SampleState,
    ray: TraceRay,
    sum: Vec3,
    nonfinite: u64,
}

/// What a thread does after its ray's hit or miss is shaded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ThreadStep {
    /// It traces another ray (the next bounce or the next sample's primary ray).
    Trace,
    /// Every sample has ended: the pixel's colour and how many samples were NaN or infinite.
    Finished {
        /// The pixel.
        pixel: u32,
        /// Average radiance over the finite samples' sum (as the functional renderer).
        color: Vec3,
        /// Samples whose radiance was not finite (contributing black).
        nonfinite: u64,
    },
}

impl PathThread {
    /// The thread of `pixel` of `workload`, starting sample 0.
    pub fn new(
        workload: &Workload,
        frame: &CameraFrame,
        settings: &RenderSettings,
        pixel: u32,
    ) -> Self {
        let (path, ray) = SampleState::new(workload, frame, settings, pixel, 0);
        PathThread {
            pixel,
            sample: 0,
            path,
            ray,
            sum: Vec3::ZERO,
            nonfinite: 0,
        }
    }

    /// The ray the thread traces next.
    pub fn ray(&self) -> Ray {
        self.ray.ray
    }

    /// The ray the thread traces next, with whether it is an occlusion ray.
    pub fn trace_ray(&self) -> TraceRay {
        self.ray
    }

    /// The pixel of the thread.
    pub fn pixel(&self) -> u32 {
        self.pixel
    }

    /// Shades the closest hit (or miss) of the current ray — for an occlusion ray, any hit —
    /// and picks what comes next.
    pub fn on_hit(
        &mut self,
        scene: &Scene,
        (workload, frame): (&Workload, &CameraFrame),
        settings: &RenderSettings,
        hit: Option<Hit>,
    ) -> ThreadStep {
        if let Some(next) = self.path.on_answer(workload, scene, hit) {
            self.ray = next;
            return ThreadStep::Trace;
        }
        let l = self.path.radiance();
        if l.is_finite() {
            self.sum += l;
        } else {
            self.nonfinite += 1;
        }
        self.sample += 1;
        if self.sample < settings.spp {
            let (path, ray) = SampleState::new(workload, frame, settings, self.pixel, self.sample);
            self.path = path;
            self.ray = ray;
            return ThreadStep::Trace;
        }
        ThreadStep::Finished {
            pixel: self.pixel,
            color: self.sum / settings.spp as f32,
            nonfinite: self.nonfinite,
        }
    }
}

/// Cycles of shader invocations of one warp (`[gpu]` raygen, closest-hit and miss cycles).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ShaderTiming {
    /// Raygen work before each trace.
    pub raygen: u64,
    /// One closest-hit invocation.
    pub closest_hit: u64,
    /// One miss invocation.
    pub miss: u64,
}

impl ShaderTiming {
    /// The timing of `[gpu]`.
    pub fn new(gpu: &GpuConfig) -> Self {
        ShaderTiming {
            raygen: gpu.raygen_cycles as u64,
            closest_hit: gpu.closest_hit_cycles as u64,
            miss: gpu.miss_cycles as u64,
        }
    }

    /// Cycles of a warp between its trace completing and its next trace (or its end): the
    /// closest-hit shader if some lane hit, then the miss shader if some lane missed (the two
    /// run one after the other under SIMT), then the raygen shader if some thread traces again.
    pub fn after_trace(&self, any_hit: bool, any_miss: bool, traces_again: bool) -> u64 {
        let mut c = 0;
        if any_hit {
            c += self.closest_hit;
        }
        if any_miss {
            c += self.miss;
        }
        if traces_again {
            c += self.raygen;
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shading_serializes_hit_and_miss_shaders_then_raygen() {
        let t = ShaderTiming {
            raygen: 100,
            closest_hit: 50,
            miss: 20,
        };
        assert_eq!(t.after_trace(true, true, true), 170);
        assert_eq!(t.after_trace(true, false, false), 50);
        assert_eq!(t.after_trace(false, true, true), 120);
    }
}
