//! The cycle-exact GPU simulator: SMs running the path tracer's raygen / closest-hit / miss
//! shaders, a CTA scheduler, one RT unit per SM (the `vtq-hdl` hardware model with the BVH
//! datapath) and the memory hierarchy, driven by an engine that skips idle cycles.
//!
//! One file per concept: [`datapath`] (the RT unit's intersection tests over the BVH image),
//! [`rt`] (an SM's RT unit — the plain one, or the `queues` mode's treelet RT unit of `vtq-hdl`
//! — stepped through its ports, with its memory queues, and [`rt::waveform`], the VCD of its
//! blocks over a window of cycles), [`ray_memory`] (the memory contents
//! the treelet hardware reads and writes), [`rt_fault`] (RT-unit errors in words), [`sm`] (CTA
//! and warp slots), [`shader`] (raygen threads and shader timing), [`cta_scheduler`],
//! [`engine`] (the cycle loop: setting up a run), [`output`] (what a run returns), [`coordinator`] (the loop on any number of
//! threads), [`l2_partitions`] (the L2's memory partitions as units of work), [`watchdog`], [`stats`], [`warp_simt`] (SIMT efficiency averaged per RT-unit warp), [`prefetch`] (the treelet prefetcher of
//! the `prefetch` mode, which also serves the controller's preloads), [`queued_stacks`] (the
//! traffic of queued rays' stacks, a modelling switch) and [`virtualization`] (ray
//! virtualization's CTA-state traffic; suspending and resuming CTAs is in [`sm`]); [`error`]
//! holds the error every component returns. Every design runs with or without ray
//! virtualization.

pub mod coordinator;
pub mod cta_scheduler;
pub mod datapath;
pub mod engine;
pub mod error;
pub mod finish;
pub mod l2_partitions;
pub mod node;
pub mod output;
pub mod parallelism;
pub mod prefetch;
pub mod queued_stacks;
pub mod ray_memory;
pub mod rt;
pub mod rt_fault;
pub mod shader;
pub mod sm;
pub mod stats;
pub mod virtualization;
pub mod warp_simt;
pub mod watchdog;
pub mod workers;

pub use engine::{simulate, SimOptions};
pub use output::{SimOutput, TracedRay};
pub use rt::waveform::VcdWindow;
pub use stats::{SimStats, HOST_DEPENDENT_KEYS};

pub use error::SimError;
