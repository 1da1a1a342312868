//! The sampled tier (docs/accuracy.md): estimates of a design's cycles and headline statistics
//! from simulating less — scale models of the GPU (a fraction of its SMs with that share of the
//! L2 and DRAM bandwidth) running stratified samples of the frame's CTAs, chosen by a functional
//! profile of each CTA's work, in independent replicates whose spread gives 95% intervals; or,
//! where the design's SMs hold every CTA at once, the whole stripes of CTAs the profile ranks
//! slowest, with a validated bound as the interval (or, when their scale model shows that CTAs
//! finished before the last was dispatched, so the stripes were not fixed, stratified samples
//! after all).
//!
//! - the `[sample]` configuration section and the scale model it makes are the configuration's
//!   ([`crate::model::config::SampleConfig`]).
//! - [`profile`]: the functional profile (rays and node fetches per CTA, the frame's footprint,
//!   and where it is small each CTA's BVH reads at the L2 for the scale models' ghost reads).
//! - [`strata`]: stratified CTA samples.
//! - [`stripes`]: whole-stripe samples, where every CTA is resident at once.
//! - [`dispatch`]: the CTA-level dispatch model that carries a scale model's cycles to the GPU's.
//! - [`estimate`]: estimates with Student's t intervals.
//! - [`run`]: simulating the replicates and combining them.
//! - [`stored`]: a sampled run's estimates as the result store keeps them.
//! - the named operating points (`--sample default`) are the configuration's
//!   ([`crate::model::config::sample_points`]).

pub mod dispatch;
pub mod estimate;
pub mod profile;
pub mod run;
pub mod stored;
pub mod strata;
pub mod stripes;

pub use crate::model::config::SampleConfig;
pub use estimate::Estimate;
pub use profile::Profile;
pub use run::{paired_speedup, simulate_sampled, Method, SampledStats};

/// What `vtq sim --sample` and `vtq compare --sample` print when
/// [`SampledStats::every_cta_resident`] holds but stratified samples were used
/// (`sample.stripes = false`).
pub const STRIPE_CAUTION: &str = "every CTA is resident on its SM at once in this \
     design and frame, so each SM runs a fixed stripe of CTAs and the run ends with the slowest \
     stripe, which a CTA sample does not see: the 95% interval covers sampling noise only and \
     may miss full detail by much more (docs/accuracy.md; sample.stripes = true samples the \
     stripes instead)";

/// What `vtq compare --sample` prints for a design whose stripe sampling found the dispatch not
/// static ([`SampledStats::stripes_dynamic`]).
pub const STRIPES_DYNAMIC_NOTE: &str = "every CTA fits on the SMs at once in this design and \
     frame, but CTAs finished before the last was dispatched (the stripes' scale model ran CTAs \
     of several stripes on one SM), so the SMs' CTAs are not fixed stripes: the estimate is \
     stratified, with its bias bound for a frame of one wave (docs/accuracy.md)";

/// What `vtq sim --sample` and `vtq compare --sample` print for a design sampled by stripes
/// ([`Method::Stripes`]).
pub const STRIPE_NOTE: &str = "every CTA is resident on its SM at once in this design \
     and frame, so the replicates simulated the whole stripes (one SM's fixed CTAs) the profile \
     predicts slowest and the estimate is the slowest of them; its interval is the bound \
     sample.stripe_bound, validated against full detail (docs/accuracy.md), not a sampling \
     interval, and its speedups do not pair replicates";

#[cfg(test)]
mod tests {
    /// The notes the commands print are single lines of prose: no line breaks, no runs of
    /// spaces left by a string continuation.
    #[test]
    fn printed_notes_are_clean_lines() {
        for note in [
            super::STRIPE_CAUTION,
            super::STRIPE_NOTE,
            super::STRIPES_DYNAMIC_NOTE,
        ] {
            assert!(!note.contains("  ") && !note.contains('\n'), "{note}");
        }
    }
}
