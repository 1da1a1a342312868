//! The RT unit's error and statistics-event ports, each declared once as a bundle of its own
//! with [`crate::bundle!`]: the RT unit's outputs nest them (the error ports under their own
//! names, the event ports as `count_*`), and so does the treelet RT unit, which passes them on
//! (the error ports again under their own names, the event ports as `count_rt_*`). Each parent
//! gives the widths, so the treelet RT unit's lane counts may be wider than the RT unit's.

use super::bundles::{errors, ErrorRecord, RtStats};

/// Widths of the RT unit's error ports ([`RtErrorPorts`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RtErrorWidths {
    /// Bits of a warp-buffer slot index.
    pub slot: u32,
    /// Bits of a lane index.
    pub lane: u32,
    /// Bits of a ray id.
    pub ray_id: u32,
}

crate::bundle! {
    /// The RT unit's error ports: its sticky error flags and the first error's details.
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub struct RtErrorPorts (Out, w: RtErrorWidths, this) {
        /// Sticky error flags ([`errors`]), including any raised this cycle.
        pub errors: u8,
        /// The first error raised so far, with its details (sticky, like `errors`).
        pub first_error: Option<ErrorRecord>,
    }
    ports {
        /// sticky protocol errors: issue while full, bad issue, FIFO overflow, unmatched response, stack spill area full, bad child, bad controller command
        sig errors (errors::BITS) = this.errors as u64;
        /// an error was captured (first error, sticky)
        sig error_valid (1) = this.first_error.is_some() as u64;
        /// first error: bit index of its flag in errors
        sig error_kind (3) = this.first_error.map_or(0, |e| e.kind.code());
        /// first error: warp-buffer slot
        sig error_slot (w.slot) = this.first_error.map_or(0, |e| e.slot as u64);
        /// first error: lane
        sig error_lane (w.lane) = this.first_error.map_or(0, |e| e.lane as u64);
        /// first error: ray id
        sig error_ray_id (w.ray_id) = this.first_error.map_or(0, |e| e.ray_id as u64);
        /// first error: the value needed or seen
        sig error_value (64) = this.first_error.map_or(0, |e| e.value);
        /// first error: the limit it broke
        sig error_limit (64) = this.first_error.map_or(0, |e| e.limit);
    }
}

/// Widths of the RT unit's statistics-event ports ([`RtCountPorts`]); a parent may give its
/// lane counts more bits than they need.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RtCountWidths {
    /// Bits of a number of valid warps (0..=slots).
    pub warps: u32,
    /// Bits of a number of lanes of all warp-buffer slots (0..=slots x warp_size).
    pub lanes: u32,
    /// Bits of a number of a warp's lanes (0..=warp_size).
    pub warp_lanes: u32,
}

crate::bundle! {
    /// The RT unit's statistics-event ports: one cycle's increments of its counters.
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub struct RtCountPorts (Out, w: RtCountWidths, this) {
        /// The cycle's increments.
        pub counts: RtStats,
    }
    ports {
        /// valid warps this cycle (warp cycles)
        sig warps (w.warps) = this.counts.warp_cycles;
        /// traversing lanes of the valid warps this cycle (active-thread cycles)
        sig active (w.lanes) = this.counts.active_thread_cycles;
        /// of those, lanes waiting for a node in flight
        sig waiting (w.lanes) = this.counts.waiting_lane_cycles;
        /// lanes of the valid warps whose ray has finished
        sig done_lanes (w.lanes) = this.counts.done_lane_cycles;
        /// lanes of the valid warps parked at a treelet boundary
        sig parked_lanes (w.lanes) = this.counts.parked_lane_cycles;
        /// a node-chunk load was requested
        sig request (1) = this.counts.load_requests;
        /// a hit-record store was requested
        sig store (1) = this.counts.stores;
        /// a stack spill was requested
        sig spill (1) = this.counts.stack_spills;
        /// a stack fill was requested
        sig fill (1) = this.counts.stack_fills;
        /// lanes served by the leader's request (merged)
        sig merged (w.warp_lanes) = this.counts.merged;
        /// header tests completed
        sig tests_header (w.warp_lanes) = this.counts.tests[0];
        /// internal-node tests completed
        sig tests_internal (w.warp_lanes) = this.counts.tests[1];
        /// instance-leaf tests completed
        sig tests_instance_leaf (w.warp_lanes) = this.counts.tests[2];
        /// primitive-descriptor tests completed
        sig tests_primitive_descriptor (w.warp_lanes) = this.counts.tests[3];
        /// triangle-leaf tests completed
        sig tests_triangle_leaf (w.warp_lanes) = this.counts.tests[4];
        /// procedural tests completed
        sig tests_procedural (w.warp_lanes) = this.counts.tests[5];
        /// of the tests completed, those of lanes in warps in treelet-stop order
        sig tests_treelet_order (w.warp_lanes) = this.counts.treelet_order_tests;
        /// triangle tests that produced a new closest hit
        sig hits (w.warp_lanes) = this.counts.triangle_hits;
        /// a warp completed
        sig warp_done (1) = this.counts.warps;
    }
}
