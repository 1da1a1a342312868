//! `[sample]`: the settings of the sampled tier ([`SampleConfig`]) and the scale model they
//! make of a configuration ([`SampleConfig::scale_model`]).

use serde::{Deserialize, Serialize};

use super::{ConfigError, SimConfig};

/// Stripe sampling's default `stripe_bound`: above its error of cycles on the 256x256
/// scenes under VTQ but for two with known causes (docs/accuracy.md, "Stripe sampling").
pub const STRIPE_BOUND: f64 = 0.07;

/// Stratified sampling's default `tail_bound`: the smallest that held 90% of the issue's
/// 256x256 baseline and prefetch estimates at 1/16x4 (docs/accuracy.md, "Honest intervals").
pub const TAIL_BOUND: f64 = 0.3;

/// Largest `ghost_l2_footprint`, in L2 capacities.
pub const MAX_GHOST_FOOTPRINT: f64 = 1e6;

/// The default `ghost_l2_footprint`: every frame. With the mirrors of the private data spread
/// over the L2's sets, the replay brought each class's L2 hit rate to full detail's on scenes
/// of every footprint (docs/accuracy.md, "The L2 of a scale model, mended").
pub const GHOST_FOOTPRINT: f64 = MAX_GHOST_FOOTPRINT;

/// Largest `profile_stride`.
pub const MAX_PROFILE_STRIDE: u32 = 64;

/// Largest `cluster`, and most sizes in a per-replicate list.
pub const MAX_CLUSTER: u32 = 64;

/// The default `cluster`: single CTAs. Pairs fit scenes whose GPU dispatch gives an SM clumps
/// of neighbouring CTAs (spring) and not those whose dispatch does not (lands), and over the
/// issue's 33 pairs at 1024x1024 they lowered the mean error of cycles but raised the worst
/// errors of cycles and speedups (docs/accuracy.md, "Samples in clumps of neighbours").
pub const CLUSTER: u32 = 1;

/// `sample.cluster`: CTAs per unit of a stratified sample, one size for every replicate
/// (`cluster = 2`) or one per replicate in turn (`cluster = [1, 2]`: replicates 0, 2, ... draw
/// single CTAs, 1, 3, ... pairs of neighbours; docs/accuracy.md, "One replicate of single CTAs,
/// one of pairs").
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Cluster {
    /// Every replicate draws units of this many CTAs.
    Each(u32),
    /// Replicate `r` draws units of the `r mod len`-th size.
    PerReplicate(Vec<u32>),
}

impl Cluster {
    /// CTAs per unit of replicate `replicate`'s sample.
    pub fn for_replicate(&self, replicate: u32) -> u32 {
        match self {
            Cluster::Each(g) => *g,
            Cluster::PerReplicate(sizes) if sizes.is_empty() => CLUSTER,
            Cluster::PerReplicate(sizes) => sizes[replicate as usize % sizes.len()],
        }
    }

    /// The sizes given, each to be checked.
    fn sizes(&self) -> &[u32] {
        match self {
            Cluster::Each(g) => std::slice::from_ref(g),
            Cluster::PerReplicate(sizes) => sizes,
        }
    }
}

impl std::fmt::Display for Cluster {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Cluster::Each(g) => write!(f, "{g}"),
            Cluster::PerReplicate(sizes) => {
                let sizes: Vec<String> = sizes.iter().map(u32::to_string).collect();
                write!(f, "[{}]", sizes.join(", "))
            }
        }
    }
}

/// Largest number of replicates.
pub const MAX_REPLICATES: u32 = 256;

/// `[sample]`: how the sampled tier simulates less (docs/accuracy.md). Used only when a command
/// is asked to sample (`vtq sim --sample`, `vtq compare --sample`); full detail ignores it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SampleConfig {
    /// Fraction of the GPU each replicate simulates — its SMs, L2 capacity and DRAM bandwidth —
    /// and of the frame's CTAs it runs (0 < fraction <= 1; `fraction * gpu.sms` must be a whole
    /// number of SMs, or below one: then one SM runs `fraction` of the CTAs). 1 is full detail.
    pub fraction: f64,
    /// Independent replicates, each a scale model on its own stratified sample of CTAs; the 95%
    /// confidence intervals come from their spread (at least 2 for an interval).
    pub replicates: u32,
    /// Seed of the CTA samples (replicate `r` uses a stream derived from it and `r`).
    pub seed: u64,
    /// Stripe sampling where the design's SMs hold every CTA of the frame at once: the
    /// replicates simulate the whole stripes (one SM's fixed CTAs) the profile predicts slowest
    /// instead of stratified samples, and the estimate of cycles is the slowest of them
    /// (docs/accuracy.md). `false`: stratified samples everywhere.
    pub stripes: bool,
    /// Half-width of stripe sampling's interval of cycles, relative to its estimate: a bound on
    /// the method's error validated against full detail (docs/accuracy.md), not a sampling
    /// interval (0 <= stripe_bound < 1).
    pub stripe_bound: f64,
    /// Bias bound of stratified sampling: its interval of cycles is the replicates' Student-t
    /// half-width plus `tail_bound / waves` of the estimate, `waves` being the frame's CTAs over
    /// the CTAs the GPU holds at once — the share of the run in which the slowest SM's last
    /// CTAs, which a sample does not see, decide the end (docs/accuracy.md; 0 <= tail_bound
    /// <= 10; 0: sampling noise only).
    pub tail_bound: f64,
    /// Warm each scale model's L2 before its run with the frame's BVH lines that the GPU's SMs
    /// the model leaves out would have fetched first (a hash deals each line of the frame's
    /// footprint to one of `gpu.sms` SMs; those dealt to the others are present, as they are
    /// for an SM of the full GPU that reaches a line after another did). `false`: a cold L2.
    pub warm_l2: bool,
    /// Replay the BVH reads of the GPU's SMs the scale model leaves out into its L2 while it
    /// runs, where the frame's BVH footprint is at most this many times the L2's capacity
    /// (0: never): the profile records each CTA's BVH sector reads that miss a private L1 of
    /// the SM's size, and every BVH read of the model's SMs at the L2 is followed by
    /// `(sms - k) / k` reads of the left-out SMs' stripes of CTAs, in turn, which take room and
    /// refresh lines in the L2 as the other SMs' reads do in the full GPU (no DRAM traffic,
    /// counted nowhere). The default replays on every frame; a lower limit skips the replay
    /// (and its cost) on frames whose footprint is larger, at the price of the scale model's
    /// L2 missing the lines the other SMs bring.
    pub ghost_l2_footprint: f64,
    /// The functional profile traces one warp in this many of each CTA (of its `n` warps those
    /// `w` with `w mod profile_stride = cta mod min(profile_stride, n)`) and scales their work
    /// to the CTA's (the CTAs stratified samples simulate are then traced in full): an
    /// estimate of each CTA's work at a fraction of the profile's cost, for the strata, the
    /// dispatch model and the frame's rays (1: every warp, exact; 1..=64). Beyond `n`, one
    /// CTA in `profile_stride / n` is traced so (the tiles whose column plus row is a multiple
    /// of it) and each other CTA's work is the mean of its traced neighbouring tiles'.
    pub profile_stride: u32,
    /// CTAs per unit of a stratified sample: the frame's CTAs are cut into runs of this many
    /// consecutive CTAs (neighbouring tiles), and the strata and draws are of runs, by their
    /// work (1..=64; 1: single CTAs). A list gives each replicate its size in turn
    /// (`[1, 2]`: one replicate of single CTAs, one of pairs, ...).
    pub cluster: Cluster,
}

impl Default for SampleConfig {
    fn default() -> Self {
        SampleConfig {
            fraction: 0.125,
            replicates: 4,
            seed: 1,
            stripes: true,
            stripe_bound: STRIPE_BOUND,
            tail_bound: TAIL_BOUND,
            warm_l2: true,
            ghost_l2_footprint: GHOST_FOOTPRINT,
            profile_stride: 1,
            cluster: Cluster::Each(CLUSTER),
        }
    }
}

/// A `[sample]` value out of range, as the configuration's error naming its key.
fn invalid(key: &str, value: impl ToString, reason: impl Into<String>) -> ConfigError {
    ConfigError::Invalid {
        key: format!("sample.{key}"),
        value: value.to_string(),
        reason: reason.into(),
    }
}

impl SampleConfig {
    /// Applies a command-line sample setting: a named operating point
    /// ([`super::sample_points::POINTS`]: `default`, `fast`), `FRACTION[xREPLICATES]`, e.g.
    /// `1/8x4`, `0.25`, `1/16x8`, or `config` (as does an empty text: the section's settings
    /// as configured). The values are checked later with the configuration
    /// ([`validate`](Self::validate)).
    pub fn apply_spec(&mut self, spec: &str) -> Result<(), String> {
        use super::sample_points::{point, CONFIG_POINT, POINTS};
        let spec = spec.trim();
        if spec.is_empty() || spec == CONFIG_POINT {
            return Ok(());
        }
        if let Some(p) = point(spec) {
            p.apply(self);
            return Ok(());
        }
        let bad = || {
            let names: Vec<&str> = POINTS.iter().map(|p| p.name).collect();
            format!(
                "--sample `{spec}`: expected a named point ({}), `{CONFIG_POINT}` or \
                 FRACTION[xREPLICATES], e.g. `1/8x4` or `0.25` (FRACTION a number or a/b in \
                 (0, 1])",
                names.join(", ")
            )
        };
        let (fraction, replicates) = match spec.split_once(['x', 'X']) {
            Some((f, r)) => (f, Some(r)),
            None => (spec, None),
        };
        let fraction = match fraction.split_once('/') {
            Some((a, b)) => {
                let (a, b): (f64, f64) = (
                    a.trim().parse().map_err(|_| bad())?,
                    b.trim().parse().map_err(|_| bad())?,
                );
                a / b
            }
            None => fraction.trim().parse().map_err(|_| bad())?,
        };
        self.fraction = fraction;
        if let Some(r) = replicates {
            self.replicates = r.trim().parse().map_err(|_| bad())?;
        }
        Ok(())
    }

    /// SMs of the scale model for a GPU of `sms` SMs, if `fraction` gives a whole number of
    /// them that divides `sms` (each simulated SM stands for `sms / k` real ones). Below one SM
    /// (`fraction < 1 / sms`) the model is one SM, which runs `fraction` of the frame's CTAs:
    /// fewer than a real SM's share ([`below_one_sm`](Self::below_one_sm)).
    pub fn scale_sms(&self, sms: u32) -> Option<u32> {
        if self.below_one_sm(sms) {
            return Some(1);
        }
        let k = self.fraction * sms as f64;
        let r = k.round();
        let whole = (k - r).abs() < 1e-9 && r >= 1.0 && r <= sms as f64;
        (whole && sms.is_multiple_of(r as u32)).then_some(r as u32)
    }

    /// Whether `fraction` is less than one of `sms` SMs (e.g. 1/32 of 16): the scale model is
    /// one SM with everything per SM and the L2 and DRAM shares of one SM, and its sample holds
    /// `fraction / (1 / sms)` of a real SM's CTAs; the dispatch model carries its cycles to the
    /// frame as it does any sample's (docs/accuracy.md, "Less than one SM and a cheaper
    /// profile").
    pub fn below_one_sm(&self, sms: u32) -> bool {
        let k = self.fraction * sms as f64;
        k > 0.0 && k < 1.0 - 1e-9
    }

    /// Checks each value's own range (part of every configuration's validation).
    pub fn validate_ranges(&self) -> Result<(), ConfigError> {
        let f = self.fraction;
        if !(f > 0.0 && f <= 1.0) {
            return Err(invalid(
                "fraction",
                f,
                "must be in (0, 1]: the share of the GPU and of the frame simulated",
            ));
        }
        if !(0.0..1.0).contains(&self.stripe_bound) {
            return Err(invalid(
                "stripe_bound",
                self.stripe_bound,
                "must be in [0, 1)",
            ));
        }
        if !(0.0..=10.0).contains(&self.tail_bound) {
            return Err(invalid("tail_bound", self.tail_bound, "must be in [0, 10]"));
        }
        if !(0.0..=MAX_GHOST_FOOTPRINT).contains(&self.ghost_l2_footprint) {
            return Err(invalid(
                "ghost_l2_footprint",
                self.ghost_l2_footprint,
                format!("must be in [0, {MAX_GHOST_FOOTPRINT}] (L2 capacities)"),
            ));
        }
        if !(1..=MAX_PROFILE_STRIDE).contains(&self.profile_stride) {
            return Err(invalid(
                "profile_stride",
                self.profile_stride,
                format!("must be 1..={MAX_PROFILE_STRIDE}"),
            ));
        }
        let sizes = self.cluster.sizes();
        if sizes.is_empty()
            || sizes.len() > MAX_CLUSTER as usize
            || !sizes.iter().all(|g| (1..=MAX_CLUSTER).contains(g))
        {
            return Err(invalid(
                "cluster",
                &self.cluster,
                format!(
                    "must be 1..={MAX_CLUSTER} (CTAs per sampling unit), or a list of 1 to \
                     {MAX_CLUSTER} such sizes, one per replicate in turn"
                ),
            ));
        }
        if !(1..=MAX_REPLICATES).contains(&self.replicates) {
            return Err(invalid(
                "replicates",
                self.replicates,
                format!("must be 1..={MAX_REPLICATES}"),
            ));
        }
        Ok(())
    }

    /// Checks the settings against the configuration `cfg` they sample (a whole number of SMs,
    /// a valid scale model); called when sampling.
    pub fn validate(&self, cfg: &SimConfig) -> Result<(), ConfigError> {
        self.validate_ranges()?;
        let f = self.fraction;
        if self.scale_sms(cfg.gpu.sms).is_none() {
            return Err(invalid(
                "fraction",
                f,
                format!(
                    "fraction x gpu.sms = {} must be a whole number of SMs k dividing gpu.sms = \
                     {}, or below 1 (use 1/m for m dividing {}, or m > {})",
                    f * cfg.gpu.sms as f64,
                    cfg.gpu.sms,
                    cfg.gpu.sms,
                    cfg.gpu.sms
                ),
            ));
        }
        self.scale_model(cfg).validate()
    }

    /// The scale model of `cfg`: `k = fraction x gpu.sms` of its SMs (one below one SM), with
    /// that share of the DRAM bandwidth — as that share of the DRAM channels, each as wide as
    /// the GPU's, where the channels divide evenly (16 channels, 1 of 16 SMs: one channel),
    /// else all the channels, each narrower — and the whole L2, in which the private data (ray
    /// records, CTA state, stacks, hit records) of every simulated SM also stands for that of
    /// the `sms / k - 1` SMs not simulated (`memory.l2_private_mirrors`, each copy in another
    /// set), while BVH nodes, which all SMs share, are cached once; everything per SM (L1, RT
    /// unit, CTA slots) unchanged. Call after [`validate`](Self::validate) (an unvalidated
    /// fraction gives one SM).
    pub fn scale_model(&self, cfg: &SimConfig) -> SimConfig {
        let sms = cfg.gpu.sms;
        let k = self.scale_sms(sms).unwrap_or(1);
        let mut m = cfg.clone();
        m.gpu.sms = k;
        m.memory.l2_private_mirrors = cfg.memory.l2_private_mirrors * (sms / k).max(1);
        let [num, den] = cfg.memory.dram_share;
        let (num, den) = (
            u64::from(num) * u64::from(k),
            u64::from(den) * u64::from(sms),
        );
        let g = gcd(num, den);
        m.memory.dram_share = [(num / g) as u32, (den / g) as u32];
        let channels = cfg.memory.dram_channels;
        if (channels * k).is_multiple_of(sms) {
            // `dram_share` of the bandwidth over `channels x k / sms` channels: each channel has
            // the GPU's per-channel bandwidth.
            m.memory.dram_channels = channels * k / sms;
        }
        m
    }
}

/// Greatest common divisor.
fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a.max(1)
    } else {
        gcd(b, a % b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scale_model_shares_the_gpu() {
        let cfg = SimConfig::default();
        let s = SampleConfig {
            fraction: 0.125,
            ..SampleConfig::default()
        };
        s.validate(&cfg).unwrap();
        let m = s.scale_model(&cfg);
        assert_eq!(m.gpu.sms, 2);
        assert_eq!(m.memory.l2_bytes, cfg.memory.l2_bytes);
        assert_eq!(m.memory.l2_private_mirrors, 8);
        assert_eq!(m.memory.dram_share, [1, 8]);
        // 2 of the 16 channels, each as wide as one of the GPU's.
        assert_eq!(m.memory.dram_channels, 2);
        assert_eq!(m.memory.l1_bytes, cfg.memory.l1_bytes);
        let one = SampleConfig {
            fraction: 0.0625,
            ..SampleConfig::default()
        };
        let mut single = cfg.clone();
        single.memory.dram_channels = 1;
        // One channel cannot be split: it keeps its address map with 1/16 of the bandwidth.
        assert_eq!(one.scale_model(&single).memory.dram_channels, 1);
        assert_eq!(one.scale_model(&single).memory.dram_share, [1, 16]);
        assert_eq!(one.scale_model(&cfg).memory.dram_channels, 1);
        let whole = SampleConfig {
            fraction: 1.0,
            ..SampleConfig::default()
        };
        assert_eq!(whole.scale_model(&cfg), cfg);
        // Below one SM: the model of one SM (the same as 1/16's), running fewer CTAs.
        let half = SampleConfig {
            fraction: 1.0 / 32.0,
            ..SampleConfig::default()
        };
        half.validate(&cfg).unwrap();
        assert!(half.below_one_sm(cfg.gpu.sms) && !one.below_one_sm(cfg.gpu.sms));
        assert_eq!(half.scale_sms(cfg.gpu.sms), Some(1));
        assert_eq!(half.scale_model(&cfg), one.scale_model(&cfg));
    }

    #[test]
    fn cluster_sizes_per_replicate() {
        assert_eq!(Cluster::Each(2).for_replicate(5), 2);
        let mix = Cluster::PerReplicate(vec![1, 2]);
        let sizes: Vec<u32> = (0..4).map(|r| mix.for_replicate(r)).collect();
        assert_eq!(sizes, [1, 2, 1, 2]);
        assert_eq!(mix.to_string(), "[1, 2]");
        // Written and read back as TOML, a size or a list.
        for cluster in [Cluster::Each(3), mix] {
            let s = SampleConfig {
                cluster: cluster.clone(),
                ..SampleConfig::default()
            };
            let text = toml::to_string(&s).unwrap();
            assert_eq!(
                toml::from_str::<SampleConfig>(&text).unwrap().cluster,
                cluster
            );
        }
        let cfg = SimConfig::default();
        for bad in [vec![], vec![1, 0], vec![1, MAX_CLUSTER + 1], vec![1; 65]] {
            let s = SampleConfig {
                cluster: Cluster::PerReplicate(bad.clone()),
                ..SampleConfig::default()
            };
            let e = s.validate(&cfg).unwrap_err();
            assert_eq!(e.key(), Some("sample.cluster"), "{bad:?}: {e}");
        }
    }

    #[test]
    fn command_line_specs() {
        let mut s = SampleConfig::default();
        s.apply_spec("1/16x8").unwrap();
        assert_eq!((s.fraction, s.replicates), (0.0625, 8));
        s.apply_spec("0.5").unwrap();
        assert_eq!((s.fraction, s.replicates), (0.5, 8));
        s.apply_spec("").unwrap();
        assert_eq!(s.fraction, 0.5);
        s.apply_spec("config").unwrap();
        assert_eq!(s.fraction, 0.5);
        s.apply_spec("default").unwrap();
        assert_eq!((s.fraction, s.replicates, s.profile_stride), (0.0625, 2, 4));
        assert_eq!(s.cluster, Cluster::PerReplicate(vec![1, 2]));
        s.apply_spec("fast").unwrap();
        assert_eq!(s.fraction, 1.0 / 32.0);
        assert!(s.apply_spec("quick").unwrap_err().contains("default, fast"));
        for bad in ["x4", "1/", "a/b", "0.5x", "0.5x-1", "half"] {
            assert!(s.apply_spec(bad).unwrap_err().contains(bad), "{bad}");
        }
    }

    #[test]
    fn bad_settings_name_their_key() {
        let cfg = SimConfig::default();
        for (fraction, replicates, key) in [
            (0.0, 4, "sample.fraction"),
            (1.5, 4, "sample.fraction"),
            (0.1, 4, "sample.fraction"),
            (f64::NAN, 4, "sample.fraction"),
            (0.5, 0, "sample.replicates"),
        ] {
            let s = SampleConfig {
                fraction,
                replicates,
                ..SampleConfig::default()
            };
            let e = s.validate(&cfg).unwrap_err();
            assert_eq!(e.key(), Some(key), "{e}");
        }
        for bound in [-0.1, 1.0, f64::NAN] {
            let s = SampleConfig {
                stripe_bound: bound,
                ..SampleConfig::default()
            };
            let e = s.validate(&cfg).unwrap_err();
            assert_eq!(e.key(), Some("sample.stripe_bound"), "{e}");
            let s = SampleConfig {
                tail_bound: bound * 20.0,
                ..SampleConfig::default()
            };
            let e = s.validate(&cfg).unwrap_err();
            assert_eq!(e.key(), Some("sample.tail_bound"), "{e}");
        }
        for limit in [-1.0, f64::NAN, f64::INFINITY] {
            let s = SampleConfig {
                ghost_l2_footprint: limit,
                ..SampleConfig::default()
            };
            let e = s.validate(&cfg).unwrap_err();
            assert_eq!(e.key(), Some("sample.ghost_l2_footprint"), "{e}");
        }
        // 3 of 16 SMs cannot each stand for the same number of SMs.
        let s = SampleConfig {
            fraction: 3.0 / 16.0,
            ..SampleConfig::default()
        };
        assert_eq!(s.validate(&cfg).unwrap_err().key(), Some("sample.fraction"));
    }
}
