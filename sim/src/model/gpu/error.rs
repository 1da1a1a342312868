//! [`SimError`]: why a simulation could not run or had to stop. A leaf of the `gpu` module:
//! every component returns it, and it names only what lies below them (the RT unit's faults,
//! the memory system's and the hardware models' errors).

/// Why a simulation could not run or had to stop.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The configuration does not fit the scene or the BVH.
    #[error("invalid simulation setup: {0}")]
    Setup(String),
    /// The image settings or the scene camera are unusable.
    #[error(transparent)]
    Render(#[from] crate::model::workload::pathtracer::RenderError),
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
        fault: Box<super::rt_fault::RtFault>,
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
    Memory(#[from] crate::model::memory::AccessError),
    /// The memory system rejected its configuration.
    #[error("memory: {0}")]
    MemoryConfig(#[from] crate::model::memory::MemConfigError),
    /// A waveform (`vtq sim --vcd`) could not be written as asked.
    #[error("waveform (--vcd): {0}")]
    Waveform(String),
    /// The energy model could not read the run's statistics (a modelling bug, reported rather
    /// than giving no energy).
    #[error("energy model: {0}")]
    Energy(String),
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
