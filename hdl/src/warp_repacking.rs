//! Warp repacking (paper section 4.5): in the final ray-stationary phase, a warp whose active
//! rays fall below the repack threshold is terminated as a unit and its idle lanes are refilled
//! with rays from the underpopulated treelet queues; its remaining active rays keep their lanes.
//! The paper's best threshold is 22 of 32 lanes (+95%), 16 gives +84%; 0 turns repacking off.
//!
//! The whole rule is here: which lanes a repack releases ([`releases`]) and so which count as
//! the warp's active rays ([`kept_lanes`]), when the controller repacks ([`should_repack`]), how
//! many rays it asks for ([`lanes_to_refill`]) and how popped rays are split ([`split_refill`]).
//! The RT unit releases the lanes and takes the fill into them; the controller decides.

use crate::mode::Mode;

/// Whether a repack releases a lane, from its predicates: its ray is `done` and the lane is
/// `quiescent` (nothing of it — a node or stack fill in flight, an intersection delay, a
/// hit-record store — is outstanding). Plain predicates, so this rule needs nothing of the RT
/// unit's types (the RT unit imports it, not the other way round).
pub fn releases(done: bool, quiescent: bool) -> bool {
    done && quiescent
}

/// The lanes a repack keeps, from a slot's lane predicate masks (bit `l` for lane `l`): the
/// traversing and parked ones and the done ones with something outstanding (`busy`). Their
/// number is the warp's active rays in the controller's repacking report; the complement of
/// [`releases`] among the lanes holding a ray.
pub fn kept_lanes(traversing: u64, parked: u64, done: u64, busy: u64) -> u64 {
    traversing | parked | (done & busy)
}

/// Whether repacking is enabled at all (a threshold of 0 disables it).
pub fn repack_enabled(repack_threshold: u32) -> bool {
    repack_threshold > 0
}

/// Whether a warp with `active_rays` active rays should be repacked: the controller is in the
/// final ray-stationary phase, repacking is enabled, the warp still has at least one active
/// ray (an empty warp simply completes), fewer than `repack_threshold` rays are active, and
/// the queues (or the controller's spare buffer) hold rays to refill it with.
pub fn should_repack(
    mode: Mode,
    active_rays: u32,
    repack_threshold: u32,
    rays_waiting: bool,
) -> bool {
    mode == Mode::FinalRayStationary
        && repack_enabled(repack_threshold)
        && active_rays > 0
        && active_rays < repack_threshold
        && rays_waiting
}

/// Whether a repack is withheld for want of rays: everything [`should_repack`] asks but rays
/// to refill with — the controller is in the final ray-stationary phase with repacking enabled
/// and reports a warp with fewer than `repack_threshold` active rays (at least one), but the
/// queues and the spare buffer are empty (the pool has drained, as at the end of each bounce).
pub fn withheld_for_want_of_rays(
    mode: Mode,
    active_rays: u32,
    repack_threshold: u32,
    rays_waiting: bool,
) -> bool {
    !rays_waiting && should_repack(mode, active_rays, repack_threshold, true)
}

/// Idle lanes of a warp with `active_rays` active rays: how many rays a repack asks for.
pub fn lanes_to_refill(active_rays: u32, warp_size: u32) -> u32 {
    warp_size.saturating_sub(active_rays)
}

/// How `available` popped rays are split when `need` lanes remain to be filled:
/// `(rays given to the warp now, rays left over for the spare buffer)`.
pub fn split_refill(need: u32, available: u32) -> (u32, u32) {
    let take = need.min(available);
    (take, available - take)
}

#[cfg(test)]
mod tests {
    use super::*;

    const FRS: Mode = Mode::FinalRayStationary;

    #[test]
    fn a_repack_is_withheld_only_for_want_of_rays() {
        assert!(withheld_for_want_of_rays(FRS, 5, 22, false));
        assert!(!withheld_for_want_of_rays(FRS, 5, 22, true)); // it repacks
        assert!(!withheld_for_want_of_rays(FRS, 22, 22, false)); // not below the threshold
        assert!(!withheld_for_want_of_rays(FRS, 0, 22, false)); // an empty warp completes
        assert!(!withheld_for_want_of_rays(FRS, 5, 0, false)); // repacking off
        assert!(!withheld_for_want_of_rays(
            Mode::TreeletStationary,
            5,
            22,
            false
        ));
    }

    #[test]
    fn threshold_22_repacks_21_not_22() {
        assert!(should_repack(FRS, 21, 22, true));
        assert!(!should_repack(FRS, 22, 22, true));
        assert!(!should_repack(FRS, 32, 22, true));
        assert!(should_repack(FRS, 1, 22, true));
    }

    #[test]
    fn threshold_16_variant() {
        assert!(should_repack(FRS, 15, 16, true));
        assert!(!should_repack(FRS, 16, 16, true));
        assert!(!should_repack(FRS, 21, 16, true));
    }

    #[test]
    fn zero_threshold_disables() {
        assert!(!repack_enabled(0));
        for active in 0..=32 {
            assert!(!should_repack(FRS, active, 0, true));
        }
    }

    #[test]
    fn only_in_final_phase_with_rays_and_a_live_warp() {
        for mode in [Mode::Initial, Mode::TreeletStationary, Mode::Done] {
            assert!(!should_repack(mode, 10, 22, true), "{mode:?}");
        }
        assert!(!should_repack(FRS, 10, 22, false), "nothing to refill with");
        assert!(!should_repack(FRS, 0, 22, true), "an empty warp completes");
    }

    #[test]
    fn refill_arithmetic() {
        assert_eq!(lanes_to_refill(21, 32), 11);
        assert_eq!(lanes_to_refill(40, 32), 0);
        assert_eq!(split_refill(11, 32), (11, 21));
        assert_eq!(split_refill(11, 5), (5, 0));
        assert_eq!(split_refill(0, 5), (0, 5));
    }
}
