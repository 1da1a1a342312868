//! What an RT-unit stimulus stream exercised ([`RtUnitCoverage`]).

use crate::stimulus::{counters_below, coverage_verdict};
use serde::Serialize;
use vtq_hdl::rt_unit::{errors, ErrorKind};

/// Every error flag of the RT unit (for [`RtUnitCoverage::covers_everything`]).
pub const ALL_ERRORS: u8 = (1 << errors::BITS) - 1;

/// The error kinds in flag order (bit `k` of `errors` is kind `k`), with their names.
const ERROR_KINDS: [(ErrorKind, &str); 7] = [
    (ErrorKind::IssueWhileFull, "issue while full"),
    (ErrorKind::BadIssue, "bad issue"),
    (ErrorKind::FifoOverflow, "FIFO overflow"),
    (ErrorKind::UnmatchedResponse, "unmatched response"),
    (ErrorKind::SpillAreaFull, "spill area full"),
    (ErrorKind::BadChild, "bad child"),
    (ErrorKind::BadCommand, "bad command"),
];

/// What an RT-unit stimulus stream exercised, counted on the Rust block's outputs and
/// registers.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct RtUnitCoverage {
    /// Cycles simulated.
    pub cycles: u64,
    /// 32 B node-load requests.
    pub node_loads: u64,
    /// Of those, later chunks of multi-chunk nodes (split requests).
    pub split_loads: u64,
    /// Hit-record stores.
    pub hit_stores: u64,
    /// Stack spills.
    pub stack_spills: u64,
    /// Stack fills.
    pub stack_fills: u64,
    /// Lanes served by another lane's node load (merged).
    pub merged: u64,
    /// Node tests.
    pub tests: u64,
    /// Triangle tests that gave a new closest hit.
    pub triangle_hits: u64,
    /// Occlusion rays that left the RT unit (completed or released) with a hit.
    pub occlusion_hits: u64,
    /// Treelet-boundary events.
    pub boundaries: u64,
    /// Rays that left in a completed warp parked at a treelet boundary.
    pub parked: u64,
    /// Warps completed.
    pub warps_done: u64,
    /// Stops of a valid warp.
    pub stops: u64,
    /// Repacks that held a warp.
    pub repacks: u64,
    /// Finished lanes released by repacks.
    pub released: u64,
    /// Appends into a held warp accepted.
    pub appends: u64,
    /// Warps loaded into a slot named by number.
    pub slot_issues: u64,
    /// Lanes written ahead of their warp's issue.
    pub lane_writes: u64,
    /// Issues (new warps or appends) that activated written lanes.
    pub written_issues: u64,
    /// Warps loaded per traversal order, in [`TraversalOrder::ALL`] order.
    pub issued: [u64; 3],
    /// Cycles with the response FIFO full (`resp_free` 0).
    pub fifo_full: u64,
    /// Cycles with the warp buffer full (`issue_ready` low).
    pub buffer_full: u64,
    /// Per error kind (bit order of the `errors` flags), the cycles that raised it.
    pub errors: [u64; 7],
    /// The most warps resident at once.
    pub max_occupancy: u64,
    /// Pops whose stack's new top lies above its window, in the RTL's SRAM ring
    /// (`vtq_hdl::rt_unit::StackLayout`; none where the stacks have no ring).
    pub ring_pops: u64,
}

impl RtUnitCoverage {
    /// Every behaviour happened at least `n` times (but the maximal occupancy), and each
    /// error kind whose flag is set in `required` (e.g. [`ALL_ERRORS`]) was raised at least
    /// once. An error lists what was not covered.
    pub fn covers_everything(&self, n: u64, required: u8) -> Result<(), String> {
        let mut missing = counters_below(self.counters(), n);
        for (kind, name) in ERROR_KINDS {
            if required & kind.flag() != 0 && self.errors[kind.code() as usize] == 0 {
                missing.push(format!("error {name}"));
            }
        }
        coverage_verdict(&missing, self)
    }

    /// The behaviour counters with their names.
    fn counters(&self) -> [(&'static str, u64); 24] {
        [
            ("node loads", self.node_loads),
            ("split loads", self.split_loads),
            ("hit stores", self.hit_stores),
            ("spills", self.stack_spills),
            ("fills", self.stack_fills),
            ("merged", self.merged),
            ("tests", self.tests),
            ("triangle hits", self.triangle_hits),
            ("occlusion hits", self.occlusion_hits),
            ("boundaries", self.boundaries),
            ("parked", self.parked),
            ("warps done", self.warps_done),
            ("stops", self.stops),
            ("repacks", self.repacks),
            ("released", self.released),
            ("appends", self.appends),
            ("slot issues", self.slot_issues),
            ("lane writes", self.lane_writes),
            ("written issues", self.written_issues),
            ("ray-stationary warps", self.issued[0]),
            ("treelet-continue warps", self.issued[1]),
            ("treelet-stop warps", self.issued[2]),
            ("FIFO full", self.fifo_full),
            ("buffer full", self.buffer_full),
        ]
    }
}

impl std::fmt::Display for RtUnitCoverage {
    /// Cycles, the behaviour counters, the largest occupancy and the errors raised.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let text: Vec<String> = (self.counters().iter())
            .map(|(name, v)| format!("{name} {v}"))
            .collect();
        let errs: Vec<String> = ERROR_KINDS
            .iter()
            .map(|(kind, name)| format!("{name} {}", self.errors[kind.code() as usize]))
            .collect();
        write!(
            f,
            "{} cycles; {}; max occupancy {}; ring pops {}; error cycles: {}",
            self.cycles,
            text.join(", "),
            self.max_occupancy,
            self.ring_pops,
            errs.join(", ")
        )
    }
}
