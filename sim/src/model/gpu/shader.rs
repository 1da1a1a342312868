//! The shaders run on the SMs: the raygen thread of one pixel ([`PathThread`], which drives the
//! workload's [`SampleState`] — a path, or an ambient-occlusion sample — with the answers the
//! RT unit returns) and the timing model of shader invocations ([`ShaderTiming`]).

use glam::Vec3;

use crate::model::config::GpuConfig;
use crate::model::geometry::{Hit, Ray};
use crate::model::workload::kind::{SampleState, Sampler, TraceRay};

/// One raygen thread: one pixel, its samples traced one after another (sample order, as
/// [`crate::model::workload::pathtracer::render`] accumulates them), one ray at a time, for
/// any workload kind. A sample that traces no ray (a hybrid sample whose given primary hit
/// ends its path) is shaded without a trace.
#[derive(Debug, Clone)]
pub struct PathThread {
    pixel: u32,
    sample: u32,
    path: SampleState,
    ray: TraceRay,
    sum: Vec3,
    nonfinite: u64,
}

/// A pixel whose samples have all ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FinishedPixel {
    /// The pixel.
    pub pixel: u32,
    /// Average radiance over the finite samples' sum (as the functional renderer).
    pub color: Vec3,
    /// Samples whose radiance was not finite (contributing black).
    pub nonfinite: u64,
}

/// What a thread does after its ray's hit or miss is shaded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ThreadStep {
    /// It traces another ray (the next bounce or a later sample's first ray).
    Trace,
    /// Every sample has ended.
    Finished(FinishedPixel),
}

impl PathThread {
    /// The thread of `pixel`, at the first of its samples that traces a ray; or, when none
    /// does, the finished pixel.
    pub fn new(sampler: &Sampler<'_>, pixel: u32) -> Result<Self, FinishedPixel> {
        Self::from_sample(sampler, pixel, 0, (Vec3::ZERO, 0))
    }

    /// The thread of `pixel` at the first of samples `first..` that traces a ray, with the
    /// earlier samples' radiance sum and non-finite count `tally`; or the finished pixel.
    fn from_sample(
        sampler: &Sampler<'_>,
        pixel: u32,
        first: u32,
        (mut sum, mut nonfinite): (Vec3, u64),
    ) -> Result<Self, FinishedPixel> {
        let spp = sampler.settings.spp;
        for sample in first..spp {
            let (path, ray) = sampler.start(pixel, sample);
            if let Some(ray) = ray {
                return Ok(PathThread {
                    pixel,
                    sample,
                    path,
                    ray,
                    sum,
                    nonfinite,
                });
            }
            path.add_to(&mut sum, &mut nonfinite);
        }
        Err(FinishedPixel {
            pixel,
            color: sum / spp as f32,
            nonfinite,
        })
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
    pub fn on_hit(&mut self, sampler: &Sampler<'_>, hit: Option<Hit>) -> ThreadStep {
        if let Some(next) = sampler.answer(&mut self.path, hit) {
            self.ray = next;
            return ThreadStep::Trace;
        }
        self.path.add_to(&mut self.sum, &mut self.nonfinite);
        let tally = (self.sum, self.nonfinite);
        match Self::from_sample(sampler, self.pixel, self.sample + 1, tally) {
            Ok(next) => {
                *self = next;
                ThreadStep::Trace
            }
            Err(done) => ThreadStep::Finished(done),
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
