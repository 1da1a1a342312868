//! A sampled run's estimates as the result store keeps them
//! ([`SampledStats::record_stats`]): the headline values under the names full detail's
//! statistics use, so tables and figures read either, and beside them each estimate's 95%
//! interval and what is needed to pair speedups per replicate.

use serde_json::{json, Value};

use super::run::speedup_of;
use super::{Estimate, Method, SampledStats};

/// The estimates a stored sampled run carries an interval for, as (name, column of the
/// collected table): cycles, SIMT efficiency, BVH L1 miss rate, DRAM bytes and the three
/// phases' shares of cycles.
pub const ESTIMATED: [&str; 7] = [
    "cycles",
    "simt_efficiency",
    "bvh_l1_miss_rate",
    "dram_bytes",
    "initial_share",
    "treelet_stationary_share",
    "ray_stationary_share",
];

impl SampledStats {
    /// The statistics a result file keeps for this sampled run: `tier = "sampled"`, the
    /// headline values (`cycles`, `rays`, `simt_efficiency`, `bvh_l1_miss_rate`, `dram_bytes`)
    /// as full detail names them, `estimates` with each [`ESTIMATED`] value and the half-width
    /// of its 95% interval, and `sample` with how it was sampled (method, fraction, replicates,
    /// seed, the bias bound, each replicate's cycles for paired speedups, wall times).
    pub fn record_stats(&self) -> Value {
        let estimate = |e: &Estimate| json!({"value": e.value, "half_width": e.half_width});
        let [initial, treelet, ray] = &self.phase_shares;
        json!({
            "tier": "sampled",
            "cycles": self.cycles.value,
            "rays": self.rays,
            "rays_estimated": self.rays_estimated,
            "simt_efficiency": self.simt_efficiency.value,
            "bvh_l1_miss_rate": self.bvh_l1_miss_rate.value,
            "dram_bytes": self.dram_bytes.value,
            "estimates": {
                "cycles": estimate(&self.cycles),
                "simt_efficiency": estimate(&self.simt_efficiency),
                "bvh_l1_miss_rate": estimate(&self.bvh_l1_miss_rate),
                "dram_bytes": estimate(&self.dram_bytes),
                "initial_share": estimate(initial),
                "treelet_stationary_share": estimate(treelet),
                "ray_stationary_share": estimate(ray),
            },
            "sample": {
                "method": match self.method {
                    Method::Strata => "strata",
                    Method::Stripes => "stripes",
                },
                "fraction": self.fraction,
                "scale_sms": self.scale_sms,
                "replicates": self.replicates,
                "seed": self.seed,
                "cluster": self.cluster.to_string(),
                "every_cta_resident": self.every_cta_resident,
                "stripes_dynamic": self.stripes_dynamic,
                "bias_bound": self.bias_bound,
                "replicate_cycles": self.replicate_runs.iter().map(|r| r.cycles).collect::<Vec<f64>>(),
                "profile_seconds": self.profile_seconds,
                "sim_seconds": self.sim_seconds,
            },
        })
    }
}

/// The estimate `name` ([`ESTIMATED`]) of stored statistics `stats`, if they are a sampled
/// run's: its value and 95% half-width.
pub fn stored_estimate(stats: &Value, name: &str) -> Option<Estimate> {
    let e = stats.pointer(&format!("/estimates/{name}"))?;
    Some(Estimate {
        value: e.get("value")?.as_f64()?,
        half_width: e.get("half_width").and_then(Value::as_f64),
    })
}

/// Whether stored statistics are a sampled run's estimates.
pub fn is_sampled(stats: &Value) -> bool {
    stats.get("tier").and_then(Value::as_str) == Some("sampled")
}

/// The speedup of a stored sampled `design` over a stored sampled `baseline` (cycles over
/// cycles) with its 95% interval, combined as [`super::paired_speedup`] combines the runs
/// themselves ([`speedup_of`]): paired per replicate for stratified samples of the same seed
/// and replicate count, the two intervals' relative widths added otherwise. `None` unless both
/// are sampled runs.
pub fn stored_speedup(baseline: &Value, design: &Value) -> Option<Estimate> {
    let cycles = |s: &Value| stored_estimate(s, "cycles");
    let (b, d) = (cycles(baseline)?, cycles(design)?);
    fn method(s: &Value) -> Option<&str> {
        s.pointer("/sample/method").and_then(Value::as_str)
    }
    let replicates = |s: &Value| -> Option<Vec<f64>> {
        s.pointer("/sample/replicate_cycles")?
            .as_array()?
            .iter()
            .map(Value::as_f64)
            .collect()
    };
    let bias = |s: &Value| {
        s.pointer("/sample/bias_bound")
            .and_then(Value::as_f64)
            .unwrap_or(0.0)
    };
    let seed = |s: &Value| s.pointer("/sample/seed").and_then(Value::as_u64);
    let strata = method(baseline) == Some("strata")
        && method(design) == Some("strata")
        && seed(baseline) == seed(design);
    let (rb, rd) = (replicates(baseline), replicates(design));
    let paired = match (&rb, &rd) {
        (Some(rb), Some(rd)) if strata && rb.len() == rd.len() && !rb.is_empty() => {
            Some((&rb[..], &rd[..], bias(baseline) + bias(design)))
        }
        _ => None,
    };
    Some(speedup_of(b, d, paired))
}
