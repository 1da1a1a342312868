//! [`PreparedScene`]: a loaded scene with its content hash and the BVHs built for it, and
//! [`PreparedScene::simulate`], which turns one configuration into a [`RunRecord`] whatever
//! happens (an invalid configuration, a BVH that cannot be built, a simulation error or panic
//! become a failed record).

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use anyhow::Context;

use super::key::Tier;
use super::record::{RunRecord, RunResult};
use crate::estimate::sample::{simulate_sampled, Profile};
use crate::model::bvh::{build_cached, BvhParams, HwBvh};
use crate::model::config::SimConfig;
use crate::model::gpu::{simulate, SimOptions};
use crate::model::scene::Scene;

/// Builds (or loads) the BVH of a scene for some build parameters.
pub type BvhBuilder<'a> = dyn Fn(&Scene, &BvhParams) -> anyhow::Result<HwBvh> + Sync + 'a;

/// A builder through the BVH cache in `cache_dir` (`None`: no cache), printing nothing.
pub fn cached_builder(
    cache_dir: Option<&Path>,
) -> impl Fn(&Scene, &BvhParams) -> anyhow::Result<HwBvh> + Sync + '_ {
    move |scene, params| match cache_dir {
        Some(dir) => Ok(build_cached(scene, params, Some(dir))?.0),
        None => Ok(HwBvh::build(scene, params)?),
    }
}

/// A scene ready to be simulated under many configurations.
#[derive(Debug)]
pub struct PreparedScene {
    /// The scene as the sweep named it.
    pub spec: String,
    /// The scene.
    pub scene: Scene,
    /// Its content hash ([`Scene::content_hash`]).
    pub hash: blake3::Hash,
    /// BVHs built so far, one per build parameters.
    bvhs: Mutex<Vec<(BvhParams, Arc<HwBvh>)>>,
    /// Functional profiles made so far for sampled runs, one per [`Profile::key`]: shared by
    /// the designs of the scene, as `vtq compare --sample` shares them.
    profiles: Mutex<Vec<(String, Arc<Profile>)>>,
}

impl PreparedScene {
    /// Prepares a loaded scene (hashes it).
    pub fn new(spec: &str, scene: Scene) -> PreparedScene {
        PreparedScene {
            spec: spec.to_string(),
            hash: scene.content_hash(),
            scene,
            bvhs: Mutex::new(Vec::new()),
            profiles: Mutex::new(Vec::new()),
        }
    }

    /// The BVH for `params`: built once with `build`, then shared.
    pub fn bvh(&self, params: &BvhParams, build: &BvhBuilder) -> anyhow::Result<Arc<HwBvh>> {
        // A panic while building leaves the list as it was: the poison can be ignored.
        let mut bvhs = self.bvhs.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, bvh)) = bvhs.iter().find(|(p, _)| p == params) {
            return Ok(Arc::clone(bvh));
        }
        let bvh = Arc::new(build(&self.scene, params)?);
        bvhs.push((*params, Arc::clone(&bvh)));
        Ok(bvh)
    }

    /// Whether the BVH for `params` is already built.
    pub fn has_bvh(&self, params: &BvhParams) -> bool {
        let bvhs = self.bvhs.lock().unwrap_or_else(|e| e.into_inner());
        bvhs.iter().any(|(p, _)| p == params)
    }

    /// The functional profile of `config`'s frame on `bvh`: made once per [`Profile::key`],
    /// then shared.
    fn profile(&self, config: &SimConfig, bvh: &HwBvh) -> anyhow::Result<Arc<Profile>> {
        let key = Profile::key(config);
        let mut profiles = self.profiles.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, p)) = profiles.iter().find(|(k, _)| *k == key) {
            return Ok(Arc::clone(p));
        }
        let profile = Arc::new(
            Profile::new(&self.scene, bvh, config)
                .with_context(|| format!("profiling scene '{}'", self.scene.name))?,
        );
        profiles.push((key, Arc::clone(&profile)));
        Ok(profile)
    }

    /// Simulates `config` in `tier` (one thread, no progress bar) and records the outcome:
    /// statistics (a sampled run's estimates, [`crate::estimate::sample::stored`]), or the
    /// error that stopped it (invalid configuration, BVH build, simulation error or panic).
    /// Fails only if the configuration cannot be written as TOML (then it has no key).
    pub fn simulate(
        &self,
        config: &SimConfig,
        tier: Tier,
        build: &BvhBuilder,
    ) -> anyhow::Result<RunRecord> {
        let config_toml = config
            .to_toml()
            .context("writing the configuration as TOML")?;
        let start = Instant::now();
        let run = || -> anyhow::Result<RunResult> {
            config.validate()?;
            let bvh = self
                .bvh(&config.bvh_params(), build)
                .context("building the BVH")?;
            if tier == Tier::Sampled {
                config.sample.validate(config)?;
                let profile = self.profile(config, &bvh)?;
                let s = simulate_sampled(&self.scene, &bvh, config, &profile, 1)?;
                return Ok(RunResult {
                    stats: s.record_stats(),
                    time_series: Vec::new(),
                    image_blake3: String::new(),
                    nonfinite_samples: 0,
                });
            }
            let out = simulate(&self.scene, &bvh, config, SimOptions::default(), None)?;
            let mut image = blake3::Hasher::new();
            for pixel in &out.image {
                for x in pixel.to_array() {
                    image.update(&x.to_bits().to_le_bytes());
                }
            }
            Ok(RunResult {
                stats: serde_json::to_value(&out.stats).context("serializing the statistics")?,
                time_series: out.time_series,
                image_blake3: image.finalize().to_hex().to_string(),
                nonfinite_samples: out.nonfinite_samples,
            })
        };
        let outcome = match catch_unwind(AssertUnwindSafe(run)) {
            Ok(Ok(result)) => Ok(result),
            Ok(Err(e)) => Err(format!("{e:#}")),
            Err(panic) => {
                let message = panic
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| panic.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "no message".into());
                Err(format!(
                    "the simulation panicked (a simulator bug): {message}"
                ))
            }
        };
        Ok(RunRecord::new(
            (&self.scene.name, &self.spec, &self.hash),
            (config_toml, tier),
            outcome,
            start.elapsed().as_secs_f64(),
        ))
    }
}
