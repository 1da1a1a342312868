//! [`RunKey`]: the content hash naming one run's result file.

use std::fmt;

use crate::model::config::{ConfigError, SimConfig};

/// Version of the result file format and of what a key covers; part of every key, so a change
/// starts a fresh set of results instead of misreading old ones. 2: the statistics gained
/// `warp_costs` (what each kind of RT-unit warp costs per phase).
pub const RESULT_FORMAT: u32 = 2;

/// The vtq version (the crate version) results are keyed by.
pub const VTQ_VERSION: &str = env!("CARGO_PKG_VERSION");

/// Which tier a stored run was simulated in.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Tier {
    /// Full detail: exact statistics.
    #[default]
    Full,
    /// The sampled tier (`[sample]` as the configuration gives it): estimates with 95%
    /// intervals (docs/accuracy.md).
    Sampled,
}

impl Tier {
    /// `full` or `sampled`, as in the result file and the collected table.
    pub fn name(self) -> &'static str {
        match self {
            Tier::Full => "full",
            Tier::Sampled => "sampled",
        }
    }

    /// Whether this is full detail (left out of result files, which predate tiers).
    pub fn is_full(&self) -> bool {
        *self == Tier::Full
    }
}

/// A run's key: blake3 over the result format, the vtq version, the scene's content hash
/// ([`Scene::content_hash`](crate::model::scene::Scene::content_hash)) and the full effective
/// configuration as canonical TOML ([`SimConfig::to_toml`]: every key, in a fixed order). Two
/// runs with the same key simulate the same thing and give the same statistics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct RunKey(blake3::Hash);

impl RunKey {
    /// The key of simulating `config` on the scene whose content hash is `scene_hash`.
    pub fn new(scene_hash: &blake3::Hash, config: &SimConfig) -> Result<RunKey, ConfigError> {
        Ok(RunKey::from_canonical(scene_hash, &config.to_toml()?))
    }

    /// The key of running `config` on that scene in `tier`: full detail's is
    /// [`new`](Self::new)'s, the sampled tier's another (an estimate and an exact result of the
    /// same point are different store entries).
    pub fn for_tier(
        scene_hash: &blake3::Hash,
        config: &SimConfig,
        tier: Tier,
    ) -> Result<RunKey, ConfigError> {
        Ok(RunKey::of_tier(scene_hash, &config.to_toml()?, tier))
    }

    /// The key from the scene hash and the configuration's canonical TOML.
    pub fn from_canonical(scene_hash: &blake3::Hash, config_toml: &str) -> RunKey {
        RunKey::of_tier(scene_hash, config_toml, Tier::Full)
    }

    /// The key from the scene hash, the configuration's canonical TOML and the tier.
    pub fn of_tier(scene_hash: &blake3::Hash, config_toml: &str, tier: Tier) -> RunKey {
        let mut h = blake3::Hasher::new();
        h.update(b"vtq-sweep-result");
        h.update(&RESULT_FORMAT.to_le_bytes());
        h.update(&(VTQ_VERSION.len() as u64).to_le_bytes());
        h.update(VTQ_VERSION.as_bytes());
        h.update(scene_hash.as_bytes());
        h.update(config_toml.as_bytes());
        if tier == Tier::Sampled {
            // Full detail's keys are as before this tag existed.
            h.update(b"tier=sampled");
        }
        RunKey(h.finalize())
    }

    /// The key as 64 hexadecimal digits (the result file's stem).
    pub fn hex(&self) -> String {
        self.0.to_hex().to_string()
    }
}

impl fmt::Display for RunKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.hex())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_key_covers_scene_and_every_config_key() {
        let scene = blake3::hash(b"scene");
        let cfg = SimConfig::default();
        let key = RunKey::new(&scene, &cfg).unwrap();
        assert_eq!(RunKey::new(&scene, &cfg.clone()).unwrap(), key);
        assert_ne!(RunKey::new(&blake3::hash(b"other"), &cfg).unwrap(), key);
        let mut c = cfg.clone();
        c.sim.sample_interval += 1;
        assert_ne!(RunKey::new(&scene, &c).unwrap(), key);
        let mut c = cfg.clone();
        c.mode.prefetch_threshold = 0.5;
        assert_ne!(RunKey::new(&scene, &c).unwrap(), key);
        assert_eq!(key.hex().len(), 64);
        // Full detail's key is the plain one; the sampled tier's another.
        assert_eq!(RunKey::for_tier(&scene, &cfg, Tier::Full).unwrap(), key);
        assert_ne!(RunKey::for_tier(&scene, &cfg, Tier::Sampled).unwrap(), key);
        // The same configuration read from a file and from overrides has the same key.
        let a = SimConfig::load_unvalidated(
            Some((
                std::path::Path::new("x.toml"),
                "[hw]\nrepack_threshold = 16\n",
            )),
            &[],
        )
        .unwrap();
        let b = SimConfig::load_unvalidated(None, &["hw.repack_threshold=16".into()]).unwrap();
        assert_eq!(
            RunKey::new(&scene, &a).unwrap(),
            RunKey::new(&scene, &b).unwrap()
        );
    }
}
