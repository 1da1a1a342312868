//! The cycle-exact GPU simulator: SMs running the path tracer's raygen / closest-hit / miss
//! shaders, a CTA scheduler, one RT unit per SM (the `vtq-hdl` hardware model with the BVH
//! datapath) and the memory hierarchy, driven by an engine that skips idle cycles.
//!
//! One file per concept: [`datapath`] (the RT unit's intersection tests over the BVH image),
//! [`rt`] (an SM's RT unit — the plain one, or the `queues` mode's treelet RT unit of `vtq-hdl`
//! — stepped through its ports, with its memory queues), [`ray_memory`] (the memory contents
//! the treelet hardware reads and writes), [`rt_fault`] (RT-unit errors in words), [`sm`] (CTA
//! and warp slots), [`shader`] (raygen threads and shader timing), [`cta_scheduler`],
//! [`engine`] (the cycle loop), [`watchdog`], [`stats`], [`prefetch`] (the treelet prefetcher of
//! the `prefetch` mode, which also serves the controller's preloads) and [`virtualization`] (ray
//! virtualization's CTA-state traffic; suspending and resuming CTAs is in [`sm`]). Every design
//! runs with or without ray virtualization.

pub mod cta_scheduler;
pub mod datapath;
pub mod engine;
pub mod prefetch;
pub mod ray_memory;
pub mod rt;
pub mod rt_fault;
pub mod shader;
pub mod sm;
pub mod stats;
pub mod virtualization;
pub mod watchdog;

pub use engine::{simulate, SimOptions, SimOutput, TracedRay};
pub use stats::{SimStats, HOST_DEPENDENT_KEYS};

/// Why a simulation could not run or had to stop.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The configuration does not fit the scene or the BVH.
    #[error("invalid simulation setup: {0}")]
    Setup(String),
    /// The image settings or the scene camera are unusable.
    #[error(transparent)]
    Render(#[from] crate::workload::pathtracer::RenderError),
    /// An RT unit rejected its parameters or a warp.
    #[error("RT unit of SM {sm}: {source}")]
    Rt {
        /// The SM.
        sm: usize,
        /// The hardware model's error.
        source: vtq_hdl::rt_unit::RtUnitError,
    },
    /// An RT unit raised an error: a ray outgrew its stack spill area, the datapath returned
    /// a child the unit cannot hold, or the simulator broke the unit's protocol. The message
    /// names what happened, the ray, its SM warp, lane and pixel, and the limit.
    #[error("RT unit of SM {sm}: {fault}")]
    RtUnit {
        /// The SM.
        sm: usize,
        /// What happened and where.
        fault: Box<rt_fault::RtFault>,
    },
    /// The treelet hardware of queues mode lost track of a ray (a modelling bug, reported
    /// rather than giving wrong numbers).
    #[error("treelet queues of SM {sm}: {reason}")]
    Queues {
        /// The SM.
        sm: usize,
        /// What went wrong.
        reason: String,
    },
    /// The memory system rejected a request.
    #[error("memory: {0}")]
    Memory(#[from] crate::memory::AccessError),
    /// The memory system rejected its configuration.
    #[error("memory: {0}")]
    MemoryConfig(#[from] crate::memory::MemConfigError),
    /// Nothing progressed for `sim.watchdog_cycles` cycles.
    #[error("watchdog: no ray completed and no request issued from cycle {last_progress} to cycle {cycle}; state:\n{dump}")]
    Watchdog {
        /// Cycle the watchdog fired.
        cycle: u64,
        /// Last cycle with progress.
        last_progress: u64,
        /// Every component's state.
        dump: String,
    },
}
