//! vtq's simulator crate: scenes, the hardware BVH layout and treelets, robust traversal, the
//! path-traced workload, and the `vtq` command line.

pub mod geometry;
pub mod scene;

pub use geometry::{Hit, Ray};
pub use scene::{Camera, Material, Scene, SceneError, Sphere};
