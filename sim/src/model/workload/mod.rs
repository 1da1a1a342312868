//! The LumiBench path tracer: the workload whose rays every simulation traces.

pub mod camera;
pub mod image;
pub mod pathtracer;
pub mod rng;
pub mod scatter;
