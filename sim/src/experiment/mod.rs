//! Experiment tooling over the model and the estimate tiers, listed bottom-up: charts, then
//! sweeps of configurations and their result store, then what draws on both — the figures and
//! tables of `vtq reproduce` and the accuracy benchmark.

// Charts.
pub mod plot;

// Sweeps and their result store.
pub mod sweep;

// Built on the two above.
pub mod accuracy;
pub mod reproduce;
