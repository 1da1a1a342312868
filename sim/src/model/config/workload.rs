//! `[workload]`: the traced image and which rays its samples trace ([`WorkloadKindName`]),
//! with the ray file read for `kind = "rays"`.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::{invalid, ConfigError};
use crate::model::workload::pathtracer::RenderSettings;
use crate::model::workload::ray_file::RaySet;

/// The workload kinds `workload.kind` names.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum WorkloadKindName {
    /// The LumiBench path tracer (the paper's workload; closest-hit rays).
    #[default]
    Path,
    /// The path tracer with a shadow (occlusion) ray toward a sampled emitting triangle at
    /// each diffuse hit (`crate::model::workload::path_nee`).
    #[serde(rename = "path-nee")]
    PathNee,
    /// Ambient occlusion: a primary ray per sample, then `ao_rays` occlusion rays per
    /// primary hit (`crate::model::workload::ao`).
    Ao,
    /// Rays from the file `rays_file` (`crate::model::workload::ray_file`), one per pixel of a
    /// one-row image, in file order.
    Rays,
    /// The path tracer with its primary hits given, as rasterization gives them: only the
    /// secondary rays are traced (`crate::model::workload::kind::Sampler`).
    Hybrid,
}

impl WorkloadKindName {
    /// The name `workload.kind` takes.
    pub fn name(self) -> &'static str {
        match self {
            WorkloadKindName::Path => "path",
            WorkloadKindName::PathNee => "path-nee",
            WorkloadKindName::Ao => "ao",
            WorkloadKindName::Rays => "rays",
            WorkloadKindName::Hybrid => "hybrid",
        }
    }
}

/// `[workload]`: the traced image (the fields of [`RenderSettings`]; paper section 5.1) and
/// which rays its samples trace. Random numbers are seeded per pixel and sample (TEA), so the
/// workload has no seed key.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WorkloadConfig {
    /// Image width in pixels (256).
    pub width: u32,
    /// Image height in pixels (256).
    pub height: u32,
    /// Samples (paths) per pixel (1).
    pub spp: u32,
    /// Maximum secondary rays per path (3); 0 traces primary rays only.
    pub bounces: u32,
    /// What each sample traces: `"path"` (the default), `"path-nee"`, `"ao"`, `"hybrid"` or
    /// `"rays"`.
    pub kind: WorkloadKindName,
    /// `ao`: occlusion rays per primary hit (4), 1..=64.
    pub ao_rays: u32,
    /// `ao`: the occlusion rays' length as a fraction of the scene's bounding-box diagonal
    /// (0.05), above 0 and at most 1.
    pub ao_radius: f64,
    /// `rays`: the ray file (CSV or binary, `crate::model::workload::ray_file`), relative to
    /// the working directory. Loading the configuration reads it and makes the image one row of
    /// one pixel per ray (`width` = the ray count, `height` = 1).
    pub rays_file: String,
    /// `rays`: the rays read from `rays_file` (not a key).
    #[serde(skip)]
    pub rays: Option<Arc<RaySet>>,
}

impl WorkloadConfig {
    /// With `kind = "rays"`, reads `rays_file` into `rays` and sizes the image to it (one row,
    /// one pixel per ray); otherwise drops any rays read before.
    pub fn read_rays(&mut self) -> Result<(), ConfigError> {
        if self.kind != WorkloadKindName::Rays {
            self.rays = None;
            return Ok(());
        }
        if self.rays_file.is_empty() {
            return Err(invalid(
                "workload.rays_file",
                "\"\"",
                "workload.kind = \"rays\" needs the ray file (CSV or binary) to trace",
            ));
        }
        let set = RaySet::read(&self.rays_file)
            .map_err(|e| invalid("workload.rays_file", &self.rays_file, e.to_string()))?;
        self.width = u32::try_from(set.rays.len()).unwrap_or(u32::MAX);
        self.height = 1;
        self.rays = Some(Arc::new(set));
        Ok(())
    }
}

impl Default for WorkloadConfig {
    fn default() -> Self {
        let r = RenderSettings::default();
        WorkloadConfig {
            width: r.width,
            height: r.height,
            spp: r.spp,
            bounces: r.bounces,
            kind: WorkloadKindName::Path,
            ao_rays: 4,
            ao_radius: 0.05,
            rays_file: String::new(),
            rays: None,
        }
    }
}
