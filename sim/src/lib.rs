//! vtq's simulator crate: scenes, the hardware BVH layout and treelets, robust traversal, the
//! path-traced workload, and the `vtq` command line.

pub mod atomic_file;
pub mod bvh;
pub mod cmd;
pub mod config;
pub mod figure5;
pub mod geometry;
pub mod gpu;
pub mod intersect;
pub mod memory;
pub mod rays_csv;
pub mod scene;
pub mod sweep;
pub mod traversal;
pub mod workload;

pub use geometry::{Hit, Ray};
pub use scene::{Camera, Material, Scene, SceneError, Sphere};
