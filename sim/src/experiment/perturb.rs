//! Full detail under small perturbations: the same run with the DRAM latency moved by a cycle
//! or two, far below any real GPU's variation. Where the makespan hangs on which SM ends up with
//! the heaviest CTAs (dynamic dispatch on small frames), such a change moves it by up to tens of
//! percent (docs/accuracy.md, "How far the reference moves"): `vtq accuracy --perturb` and
//! `vtq compare --perturb` use these runs to say how far a result can be trusted.

use crate::model::config::SimConfig;

/// The DRAM latency offsets of `n` perturbed runs: +1, -1, +2, -2, ... cycles.
pub fn perturbations(n: usize) -> Vec<i64> {
    (0..n as i64)
        .map(|k| if k % 2 == 0 { k / 2 + 1 } else { -(k / 2 + 1) })
        .collect()
}

/// `cfg` with its DRAM latency moved by `offset` cycles (an error naming the key if that leaves
/// the configuration's valid range).
pub fn perturbed(cfg: &SimConfig, offset: i64) -> Result<SimConfig, String> {
    let mut c = cfg.clone();
    let latency = i64::from(c.memory.dram_latency) + offset;
    c.memory.dram_latency = u32::try_from(latency).map_err(|_| {
        format!(
            "a perturbation of {offset} cycles takes memory.dram_latency ({}) below 0",
            cfg.memory.dram_latency
        )
    })?;
    c.validate()
        .map_err(|e| format!("perturbed by {offset} cycles: {e}"))?;
    Ok(c)
}

/// Per run, the baseline's cycles over the design's (`baseline[k] / design[k]`: runs with the
/// same perturbation paired).
pub fn speedups(baseline: &[f64], design: &[f64]) -> Vec<f64> {
    baseline
        .iter()
        .zip(design)
        .map(|(b, d)| b / d.max(1.0))
        .collect()
}

/// The spread of a few runs' values: mean, smallest, largest.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spread {
    /// Mean of the values.
    pub mean: f64,
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
}

impl Spread {
    /// The spread of `values` (`None` for none).
    pub fn of(values: &[f64]) -> Option<Spread> {
        if values.is_empty() {
            return None;
        }
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let (min, max) = values
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            });
        Some(Spread { mean, min, max })
    }

    /// (max - min) / mean: the relative width of the range.
    pub fn relative(&self) -> f64 {
        (self.max - self.min) / self.mean.abs().max(f64::MIN_POSITIVE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn perturbations_alternate_around_the_configured_latency() {
        assert_eq!(perturbations(0), Vec::<i64>::new());
        assert_eq!(perturbations(5), [1, -1, 2, -2, 3]);
        let cfg = SimConfig::default();
        let c = perturbed(&cfg, -2).unwrap();
        assert_eq!(c.memory.dram_latency + 2, cfg.memory.dram_latency);
        let e = perturbed(&cfg, -1_000_000).unwrap_err();
        assert!(e.contains("memory.dram_latency"), "{e}");
    }

    #[test]
    fn a_spread_has_its_mean_and_range() {
        assert_eq!(Spread::of(&[]), None);
        let s = Spread::of(&[100.0, 120.0, 80.0]).unwrap();
        assert_eq!((s.mean, s.min, s.max), (100.0, 80.0, 120.0));
        assert!((s.relative() - 0.4).abs() < 1e-12);
        assert_eq!(speedups(&[200.0, 90.0], &[100.0, 90.0]), [2.0, 1.0]);
    }
}
