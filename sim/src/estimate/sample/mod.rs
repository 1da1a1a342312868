//! The sampled tier (docs/accuracy.md): estimates of a design's cycles and headline statistics
//! from simulating less — scale models of the GPU (a fraction of its SMs with that share of the
//! L2 and DRAM bandwidth) running stratified samples of the frame's CTAs, chosen by a functional
//! profile of each CTA's work, in independent replicates whose spread gives 95% intervals.
//!
//! - the `[sample]` configuration section and the scale model it makes are the configuration's
//!   ([`crate::model::config::SampleConfig`]).
//! - [`profile`]: the functional profile (rays and node fetches per CTA).
//! - [`strata`]: stratified CTA samples.
//! - [`dispatch`]: the CTA-level dispatch model that carries a scale model's cycles to the GPU's.
//! - [`estimate`]: estimates with Student's t intervals.
//! - [`run`]: simulating the replicates and combining them.

pub mod dispatch;
pub mod estimate;
pub mod profile;
pub mod run;
pub mod strata;

pub use crate::model::config::SampleConfig;
pub use estimate::Estimate;
pub use profile::Profile;
pub use run::{paired_speedup, simulate_sampled, SampledStats};

/// What `vtq sim --sample` and `vtq compare --sample` print when
/// [`SampledStats::every_cta_resident`] holds.
pub const STRIPE_CAUTION: &str = "every CTA is resident on its SM at once in this \
     design and frame, so each SM runs a fixed stripe of CTAs and the run ends with the slowest \
     stripe, which a CTA sample does not see: the 95% interval covers sampling noise only and \
     may miss full detail by much more (docs/accuracy.md; check one scene against full detail, \
     or simulate a larger frame)";
