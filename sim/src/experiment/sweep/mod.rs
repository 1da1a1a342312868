//! Design-space sweeps and the result store behind them (`vtq sweep`, docs/sweeps.md).
//!
//! A sweep ([`spec::SweepSpec`]) expands into points (scene x configuration). Each point's
//! result is one JSON file in a results folder ([`store::ResultStore`]), named by a content
//! hash ([`key::RunKey`]) of the scene, the full effective configuration and the vtq version,
//! and written atomically, so a sweep that is killed and started again runs only what is
//! missing, and any command can reuse any stored run through
//! [`store::ResultStore::run_or_load`]. Points run in parallel ([`run::run_tasks`]), in
//! deterministic slices ([`spec::Shard`]) or as a Slurm job array ([`slurm::SlurmJob`]); the
//! results are gathered into one tidy CSV table ([`collect::table`]).

pub mod collect;
pub mod key;
pub mod prepared;
pub mod record;
pub mod run;
pub mod slurm;
pub mod spec;
pub mod store;

pub use key::{RunKey, Tier};
pub use prepared::PreparedScene;
pub use record::{RunRecord, RunStatus};
pub use spec::{Point, Shard, SweepSpec};
pub use store::{Fetched, ResultStore, Reuse};
