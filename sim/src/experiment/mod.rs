//! Experiment tooling over the model and the estimate tiers, listed bottom-up: charts, then
//! sweeps of configurations and their result store, full detail under small perturbations,
//! then what draws on them — the comparison of designs on one scene, the recorded traffic of
//! co-simulation replays, the figures and tables of `vtq reproduce` and the accuracy benchmark.

// Charts.
pub mod plot;

// Sweeps and their result store.
pub mod sweep;

// Full detail under small perturbations.
pub mod perturb;

// Built on the two above.
pub mod accuracy;
pub mod compare;
pub mod compare_report;
pub mod cosim;
pub mod reproduce;
