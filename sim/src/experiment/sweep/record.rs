//! [`RunRecord`]: what one run of a sweep left in its result file (JSON): the scene, the
//! effective configuration, whether it ran, its error or its statistics and time series.

use serde::{Deserialize, Serialize};

use super::key::{RunKey, Tier, RESULT_FORMAT, VTQ_VERSION};
use crate::model::gpu::stats::{Sample, HOST_DEPENDENT_KEYS};

/// Whether a run produced statistics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RunStatus {
    /// The simulation finished; [`RunRecord::result`] holds its statistics.
    Ok,
    /// The configuration was invalid, the BVH could not be built, or the simulation stopped
    /// with an error or a panic; [`RunRecord::error`] says which.
    Failed,
}

impl RunStatus {
    /// `ok` or `failed`, as in the result file and the collected table.
    pub fn name(self) -> &'static str {
        match self {
            RunStatus::Ok => "ok",
            RunStatus::Failed => "failed",
        }
    }
}

/// What a finished simulation measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunResult {
    /// The statistics, as `vtq sim` writes them (docs/stats.md); for a sampled run the
    /// estimates ([`crate::estimate::sample::SampledStats::record_stats`]: the headline values
    /// under the same names, their intervals under `estimates`).
    pub stats: serde_json::Value,
    /// The time series (BVH L1 miss rate and active rays every `sim.sample_interval` cycles;
    /// empty for a sampled run).
    pub time_series: Vec<Sample>,
    /// blake3 of the image's pixel bits (row-major RGB f32, little-endian): equal images, equal
    /// hashes (empty for a sampled run, which renders no whole image).
    pub image_blake3: String,
    /// Samples whose radiance was NaN or infinite (written black).
    pub nonfinite_samples: u64,
}

/// One run's result file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunRecord {
    /// The result format ([`RESULT_FORMAT`]).
    pub format: u32,
    /// The run's key ([`RunKey`], hex): the file's stem.
    pub key: String,
    /// The vtq version that ran it.
    pub vtq_version: String,
    /// The scene's name.
    pub scene: String,
    /// The scene as the sweep named it (a built-in name, a folder, a path).
    pub scene_spec: String,
    /// The scene's content hash (hex).
    pub scene_hash: String,
    /// The effective configuration, canonical TOML.
    pub config: String,
    /// The tier it ran in (left out for full detail): a sampled run's statistics are estimates
    /// ([`RunResult::stats`]).
    #[serde(default, skip_serializing_if = "Tier::is_full")]
    pub tier: Tier,
    /// Whether it produced statistics.
    pub status: RunStatus,
    /// Why it failed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Wall-clock seconds of the run (host dependent).
    pub wall_seconds: f64,
    /// The statistics of a run that finished.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub result: Option<RunResult>,
}

impl RunRecord {
    /// A record of a run of `config_toml` on a scene, with its outcome.
    pub fn new(
        scene: (&str, &str, &blake3::Hash),
        (config_toml, tier): (String, Tier),
        outcome: Result<RunResult, String>,
        wall_seconds: f64,
    ) -> RunRecord {
        let (name, spec, hash) = scene;
        let key = RunKey::of_tier(hash, &config_toml, tier);
        let (status, error, result) = match outcome {
            Ok(r) => (RunStatus::Ok, None, Some(r)),
            Err(e) => (RunStatus::Failed, Some(e), None),
        };
        RunRecord {
            format: RESULT_FORMAT,
            key: key.hex(),
            vtq_version: VTQ_VERSION.to_string(),
            scene: name.to_string(),
            scene_spec: spec.to_string(),
            scene_hash: hash.to_hex().to_string(),
            config: config_toml,
            tier,
            status,
            error,
            wall_seconds,
            result,
        }
    }

    /// The statistics, for a run that finished.
    pub fn stats(&self) -> Option<&serde_json::Value> {
        self.result.as_ref().map(|r| &r.stats)
    }

    /// The statistics without the [`HOST_DEPENDENT_KEYS`] (equal for every run of the same
    /// key), for a run that finished.
    pub fn comparable_stats(&self) -> Option<serde_json::Value> {
        let mut stats = self.stats()?.clone();
        if let Some(map) = stats.as_object_mut() {
            for k in HOST_DEPENDENT_KEYS {
                map.remove(k);
            }
        }
        Some(stats)
    }
}
