//! The workloads whose rays every simulation traces: the LumiBench path tracer (the default)
//! and ambient occlusion, chosen by `[workload]` `kind` ([`kind`]).

pub mod ao;
pub mod camera;
pub mod kind;
pub mod path_nee;
pub mod pathtracer;
pub mod ray_file;
pub mod rays_csv;
pub mod rng;
pub mod scatter;
