//! vtq's simulator crate, in four layers, each a folder that imports only from the layers
//! listed before it:
//!
//! - [`model`]: the simulator core — scenes, the hardware BVH and its treelets, robust
//!   traversal, the path-traced workload, the configuration and the design registry, the
//!   memory system and the cycle-exact GPU that steps the hardware blocks of `vtq-hdl`;
//! - [`estimate`]: the estimate tiers built on the model — the sampled tier and the paper's
//!   Figure 5 analytical model;
//! - [`experiment`]: experiment tooling — sweeps and their result store, `vtq reproduce`'s
//!   figures and tables, the accuracy benchmark, and charts;
//! - [`cli`]: the `vtq` command line, its output files and ray CSVs, and the fuzzing of the
//!   parsers of user input.

pub mod model;

pub mod estimate;

pub mod experiment;

pub mod cli;

pub use model::geometry::{Hit, Ray};
pub use model::scene::{Camera, Material, Scene, SceneError, Sphere};
