//! The treelet controller's traversal modes (paper sections 3.2, 4.2 and 4.4) and the rules that
//! move it from one to the next, as small pure functions.
//!
//! The RT unit goes through three phases in order (section 3.2, Figure 7):
//! 1. **Initial** ray-stationary traversal: warps enter from the SM and traverse like the
//!    baseline until one diverges past the divergence threshold (❶).
//! 2. **Treelet stationary**: diverged warps are terminated into the treelet queues and the
//!    controller dispatches warps from the largest queues, one treelet at a time (❷).
//! 3. **Final ray stationary**: once the largest queue is underpopulated and no rays remain in the
//!    current treelet queue to repopulate the others (section 4.4), the stray rays of the
//!    underpopulated queues are grouped into warps and traversed to completion (❸).
//!
//! **Done** follows once every ray has drained. The phases never go backwards: the paper
//! describes them as chronological, and rays arriving late are traversed ray-stationary.

use serde::Serialize;

/// The controller's traversal mode (the `mode` FSM; the discriminant is the state encoding).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum Mode {
    /// Ray-stationary initial traversal phase: warps traverse until their rays diverge.
    Initial = 0,
    /// Treelet-stationary mode: warps are formed from one treelet's queue at a time.
    TreeletStationary = 1,
    /// Final ray-stationary phase: rays of underpopulated queues are grouped into warps.
    FinalRayStationary = 2,
    /// Every ray has finished traversal.
    Done = 3,
}

impl Mode {
    /// Every mode in encoding order.
    pub const ALL: [Mode; 4] = [
        Mode::Initial,
        Mode::TreeletStationary,
        Mode::FinalRayStationary,
        Mode::Done,
    ];

    /// Width of the mode register.
    pub const BITS: u32 = 2;

    /// The state encoding of this mode.
    pub fn encoding(self) -> u64 {
        self as u64
    }

    /// The state name used in block descriptions and traces.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Initial => "initial",
            Mode::TreeletStationary => "treelet_stationary",
            Mode::FinalRayStationary => "final_ray_stationary",
            Mode::Done => "done",
        }
    }

    /// Whether warps still in their initial phase are terminated into the treelet queues when
    /// they diverge. In the final ray-stationary phase they simply keep traversing: their rays
    /// would only be grouped back into ray-stationary warps.
    pub fn terminates_divergent_warps(self) -> bool {
        matches!(self, Mode::Initial | Mode::TreeletStationary)
    }

    /// The controller's `mode` output for mode register `self` when its `restart` input is
    /// `restart`: a `done` controller that restarts is in the initial phase that cycle.
    pub fn restarted_if(self, restart: bool) -> Mode {
        if restart && self == Mode::Done {
            Mode::Initial
        } else {
            self
        }
    }
}

/// Whether a warp in its initial phase has diverged: its active rays need more than
/// `divergence_threshold` distinct treelets next (section 3.2 ❶).
pub fn warp_diverged(distinct_next_treelets: u32, divergence_threshold: u32) -> bool {
    distinct_next_treelets > divergence_threshold
}

/// Whether a treelet queue holding `rays` rays is underpopulated: fewer rays than the
/// underpopulation threshold (section 4.4, HwConfig::underpopulation_threshold).
pub fn queue_underpopulated(rays: u32, underpopulation_threshold: u32) -> bool {
    rays < underpopulation_threshold
}

/// Whether the largest treelet queue the count table tracks is underpopulated. `largest` is
/// the table's maximum when its max pointer is current; while the table rescans (`None` with
/// entries left) the table's count of entries at or above the threshold decides, and an empty
/// table has no queue worth processing.
pub fn largest_queue_underpopulated(
    largest: Option<u32>,
    occupancy: u32,
    above_threshold: u32,
    underpopulation_threshold: u32,
) -> bool {
    match largest {
        Some(rays) => queue_underpopulated(rays, underpopulation_threshold),
        None => occupancy == 0 || above_threshold == 0,
    }
}

/// What the treelet-stationary phase needs to know to decide whether it is over.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TreeletPhaseStatus {
    /// The largest queue is underpopulated ([`largest_queue_underpopulated`]).
    pub largest_underpopulated: bool,
    /// Treelets still resident (claimed and being processed or preloaded); zero means the
    /// current treelet queue is empty and its last warp has finished.
    pub resident_treelets: u32,
    /// Warps whose rays may still enter the queues: treelet warps traversing, and terminated
    /// initial-phase warps still sending their rays.
    pub warps_feeding_queues: u32,
    /// Warps still in their initial phase are in the warp buffer (they may diverge into the
    /// queues).
    pub initial_warps: bool,
    /// A ray is waiting to be enqueued this cycle.
    pub enqueue_pending: bool,
}

/// Whether the treelet-stationary phase is over (section 4.4): grouping is enabled, the largest
/// queue is underpopulated (or there is none), and no rays remain in the current treelet queue
/// or in flight to populate the queues further. Without grouping (the naive design) the
/// controller stays treelet-stationary until everything has drained.
pub fn treelet_phase_over(status: &TreeletPhaseStatus, group_underpopulated: bool) -> bool {
    group_underpopulated
        && status.largest_underpopulated
        && status.resident_treelets == 0
        && status.warps_feeding_queues == 0
        && !status.initial_warps
        && !status.enqueue_pending
}

/// What the controller needs to know to decide that every ray has finished.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DrainStatus {
    /// The SM will send no more warps to the RT unit.
    pub launch_done: bool,
    /// The RT unit's warp buffer is empty and it has no events pending.
    pub rt_idle: bool,
    /// Rays waiting in the treelet queue table.
    pub queued_rays: u32,
    /// Rays popped from the queues but not yet given to a warp (the controller's spare buffer).
    pub held_rays: u32,
    /// Treelets still resident.
    pub resident_treelets: u32,
    /// The controller is in the middle of a table sequence (pop, fill or refill).
    pub sequence_busy: bool,
    /// A ray is waiting to be enqueued this cycle.
    pub enqueue_pending: bool,
}

/// Whether every ray has drained: nothing will arrive, nothing is traversing, and nothing is
/// queued or held (section 4.2: "traversal is done when the treelet count table is empty"; the
/// controller counts queued rays exactly, so it uses that count instead of the table).
pub fn drained(status: &DrainStatus) -> bool {
    status.launch_done
        && status.rt_idle
        && status.queued_rays == 0
        && status.held_rays == 0
        && status.resident_treelets == 0
        && !status.sequence_busy
        && !status.enqueue_pending
}

/// The events of one cycle that can change the mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModeEvents {
    /// A warp in its initial phase diverged and is being terminated into the queues.
    pub divergent_warp: bool,
    /// [`treelet_phase_over`] holds.
    pub treelet_phase_over: bool,
    /// [`drained`] holds.
    pub drained: bool,
}

/// The next mode: Done once drained (from any mode), Initial → TreeletStationary on the first
/// divergent warp, TreeletStationary → FinalRayStationary when the treelet phase is over.
pub fn next_mode(mode: Mode, events: &ModeEvents) -> Mode {
    match mode {
        Mode::Done => Mode::Done,
        _ if events.drained => Mode::Done,
        Mode::Initial if events.divergent_warp => Mode::TreeletStationary,
        Mode::TreeletStationary if events.treelet_phase_over => Mode::FinalRayStationary,
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quiet() -> ModeEvents {
        ModeEvents {
            divergent_warp: false,
            treelet_phase_over: false,
            drained: false,
        }
    }

    #[test]
    fn encodings_are_dense_and_named() {
        for (i, m) in Mode::ALL.iter().enumerate() {
            assert_eq!(m.encoding(), i as u64);
            assert!(m.encoding() < 1 << Mode::BITS);
        }
        assert_eq!(Mode::FinalRayStationary.name(), "final_ray_stationary");
    }

    #[test]
    fn divergence_is_strictly_above_threshold() {
        assert!(!warp_diverged(4, 4));
        assert!(warp_diverged(5, 4));
        assert!(warp_diverged(2, 1));
    }

    #[test]
    fn initial_goes_treelet_stationary_only_on_divergence() {
        assert_eq!(next_mode(Mode::Initial, &quiet()), Mode::Initial);
        let ev = ModeEvents {
            divergent_warp: true,
            ..quiet()
        };
        assert_eq!(next_mode(Mode::Initial, &ev), Mode::TreeletStationary);
        // Later divergent warps do not move the mode back or forward.
        assert_eq!(
            next_mode(Mode::FinalRayStationary, &ev),
            Mode::FinalRayStationary
        );
    }

    #[test]
    fn largest_queue_underpopulated_handles_a_stale_max() {
        assert!(largest_queue_underpopulated(Some(127), 5, 0, 128));
        assert!(!largest_queue_underpopulated(Some(128), 5, 1, 128));
        assert!(largest_queue_underpopulated(None, 0, 0, 128), "empty table");
        assert!(
            largest_queue_underpopulated(None, 7, 0, 128),
            "rescan, all small"
        );
        assert!(
            !largest_queue_underpopulated(None, 7, 2, 128),
            "rescan, big ones left"
        );
    }

    #[test]
    fn treelet_phase_ends_only_with_grouping_and_an_empty_current_queue() {
        let mut s = TreeletPhaseStatus {
            largest_underpopulated: true,
            resident_treelets: 0,
            warps_feeding_queues: 0,
            initial_warps: false,
            enqueue_pending: false,
        };
        assert!(treelet_phase_over(&s, true));
        assert!(!treelet_phase_over(&s, false), "naive never groups");
        s.largest_underpopulated = false;
        assert!(!treelet_phase_over(&s, true));
        s.largest_underpopulated = true;
        s.resident_treelets = 1;
        assert!(!treelet_phase_over(&s, true));
        s.resident_treelets = 0;
        s.warps_feeding_queues = 1;
        assert!(!treelet_phase_over(&s, true));
        s.warps_feeding_queues = 0;
        s.initial_warps = true;
        assert!(!treelet_phase_over(&s, true));
        s.initial_warps = false;
        s.enqueue_pending = true;
        assert!(!treelet_phase_over(&s, true));
    }

    #[test]
    fn done_from_any_mode_when_drained_and_absorbing() {
        let ev = ModeEvents {
            drained: true,
            ..quiet()
        };
        for m in Mode::ALL {
            assert_eq!(next_mode(m, &ev), Mode::Done);
        }
        let ev = ModeEvents {
            divergent_warp: true,
            treelet_phase_over: true,
            drained: false,
        };
        assert_eq!(next_mode(Mode::Done, &ev), Mode::Done);
    }

    #[test]
    fn drained_needs_every_condition() {
        let all = DrainStatus {
            launch_done: true,
            rt_idle: true,
            queued_rays: 0,
            held_rays: 0,
            resident_treelets: 0,
            sequence_busy: false,
            enqueue_pending: false,
        };
        assert!(drained(&all));
        let variants = [
            DrainStatus {
                launch_done: false,
                ..all
            },
            DrainStatus {
                rt_idle: false,
                ..all
            },
            DrainStatus {
                queued_rays: 1,
                ..all
            },
            DrainStatus {
                held_rays: 1,
                ..all
            },
            DrainStatus {
                resident_treelets: 1,
                ..all
            },
            DrainStatus {
                sequence_busy: true,
                ..all
            },
            DrainStatus {
                enqueue_pending: true,
                ..all
            },
        ];
        for v in variants {
            assert!(!drained(&v), "{v:?}");
        }
    }
}
