//! The simulator core: what is simulated and how. The groups below are listed bottom-up: a
//! module imports only from its own group's earlier modules and from the groups above it
//! (and from `vtq-hdl`).

pub use vtq_hdl::splitmix;

// Geometry and scenes: files written safely, rays and hits, intersection tests, scene loading.
pub mod atomic_file;
pub mod geometry;
pub mod intersect;
pub mod scene;

// The hardware BVH and its treelets, traversal over it, and the path-traced workload.
pub mod bvh;
pub mod traversal;
pub mod workload;

// The memory system (caches, DRAM).
pub mod memory;

// The configuration, then the designs known by name.
pub mod config;
pub mod designs;

// The energy model: an observer of a run's statistics.
pub mod energy;

// The cycle-exact GPU stepping the hardware blocks.
pub mod gpu;
