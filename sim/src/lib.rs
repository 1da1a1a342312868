//! vtq's simulator crate: scenes, the hardware BVH layout and treelets, robust traversal, the
//! path-traced workload, the `vtq` command line, and the fuzzing of its parsers.

pub mod accuracy;
pub mod atomic_file;
pub mod bvh;
pub mod cmd;
pub mod config;
pub mod designs;
pub mod figure5;
pub mod fuzz;
pub mod geometry;
pub mod gpu;
pub mod intersect;
pub mod memory;
pub mod output;
pub mod plot;
pub mod rays_csv;
pub mod reproduce;
pub mod sample;
pub mod scene;
pub use vtq_hdl::splitmix;
pub mod sweep;
pub mod traversal;
pub mod workload;

pub use geometry::{Hit, Ray};
pub use scene::{Camera, Material, Scene, SceneError, Sphere};
