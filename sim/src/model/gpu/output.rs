//! What a simulation returns ([`SimOutput`]): the statistics, the image, the time series and
//! what the run was asked to record. The engine ([`super::engine`]) runs the cycles and
//! [`super::finish`] turns the nodes' counters into this; both depend on it, neither on the
//! other's types.

use glam::Vec3;

use crate::model::geometry::{Hit, Ray};
use crate::model::gpu::parallelism::ParallelProfile;
use crate::model::gpu::rt::waveform::WaveformSummary;
use crate::model::gpu::sm::CtaSpan;
use crate::model::gpu::stats::{Sample, SimStats};

/// One traced ray and the hit the RT unit found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TracedRay {
    /// Pixel of the thread that traced it.
    pub pixel: u32,
    /// The ray.
    pub ray: Ray,
    /// An occlusion ray (terminate on first hit).
    pub occlusion: bool,
    /// Its closest hit (`None`: a miss); for an occlusion ray, the first hit it found (which
    /// one depends on the traversal order).
    pub hit: Option<Hit>,
}

/// The result of a simulation.
#[derive(Debug, Clone, PartialEq)]
pub struct SimOutput {
    /// Statistics.
    pub stats: SimStats,
    /// Linear radiance per pixel, row-major, as [`crate::model::workload::pathtracer::render`] gives.
    pub image: Vec<Vec3>,
    /// Samples whose radiance was NaN or infinite (written black).
    pub nonfinite_samples: u64,
    /// The time series (every `sim.sample_interval` cycles).
    pub time_series: Vec<Sample>,
    /// Every traced ray in completion order (only with [`SimOptions::record_rays`]).
    pub ray_log: Vec<TracedRay>,
    /// The recorded table inputs (only with [`SimOptions::record_tables`] in queues mode).
    pub table_log: Option<vtq_hdl::treelet_rt_unit::TableLog>,
    /// The waveform written (only with [`SimOptions::vcd`]).
    pub waveform: Option<WaveformSummary>,
    /// The parallelism report's timings (only with [`SimOptions::profile`]).
    pub parallelism: Option<ParallelProfile>,
    /// Per SM, the CTAs that ran there, in the order they retired.
    pub cta_spans: Vec<Vec<CtaSpan>>,
}
