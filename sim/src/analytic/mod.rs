//! The analytical tier (docs/accuracy.md): each design's cycles estimated from the functional
//! trace of the frame ([`trace`]) with a first-principles timing model and a functional cache
//! model ([`model`]), in about the time of a functional render. No constant is fitted: the
//! model reads only the configuration.

pub mod model;
pub mod trace;

use std::time::Instant;

use serde::Serialize;

use crate::bvh::HwBvh;
use crate::config::SimConfig;
use crate::scene::Scene;
use crate::workload::pathtracer::RenderError;

pub use model::Timing;
pub use trace::FrameTrace;

/// An analytical estimate and what it took.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Analytic {
    /// The estimate.
    pub timing: Timing,
    /// Wall-clock seconds of the model (the trace excluded).
    pub model_seconds: f64,
}

/// The trace's treelets of `bvh` as (base address, bytes), for the prefetch model.
pub fn treelets(bvh: &HwBvh) -> Vec<(u64, u64)> {
    bvh.treelets()
        .iter()
        .map(|t| (t.base as u64, t.bytes as u64))
        .collect()
}

/// Estimates `cfg`'s design on `trace` (the frame of `cfg`'s workload on `bvh`).
pub fn estimate(cfg: &SimConfig, bvh: &HwBvh, trace: &FrameTrace) -> Analytic {
    let start = Instant::now();
    let timing = model::estimate(cfg, trace, &treelets(bvh));
    Analytic {
        timing,
        model_seconds: start.elapsed().as_secs_f64(),
    }
}

/// Traces `cfg`'s workload on `scene` and estimates its design; returns the estimate and the
/// trace's seconds.
pub fn trace_and_estimate(
    scene: &Scene,
    bvh: &HwBvh,
    cfg: &SimConfig,
) -> Result<(Analytic, f64), RenderError> {
    let start = Instant::now();
    let trace = FrameTrace::new(scene, bvh, cfg)?;
    let traced = start.elapsed().as_secs_f64();
    Ok((estimate(cfg, bvh, &trace), traced))
}
