//! What each kind of RT-unit warp costs in each traversal phase of treelet queues (issue 55,
//! docs/fidelity.md cause G): SM warps, treelet warps and grouped warps
//! ([`WarpKind`]) in the initial, treelet-stationary and final ray-stationary phases.
//!
//! The observer beside the treelet RT unit attributes each cycle's RT-unit counters to the
//! controller's mode during the cycle and to the kind of warp the lowest occupied warp-buffer
//! slot holds at its start ([`vtq_hdl::treelet_rt_unit::TreeletRtUnit::warp_kind`]; a cycle
//! whose slots are empty at its start goes to the warp it issues, else to the last kind seen).
//! With one warp-buffer slot (Table 1, the default) that is exact: one warp traverses at a
//! time. With more slots, a cycle in which warps of different kinds are resident counts whole
//! for the lowest slot's kind. BVH demand loads are attributed when the L1 accepts them (hit,
//! merge or miss), to the cell of the cycle in which it accepts them (in a cycle the RT unit
//! idles, the cell a lockstep step of it would count in: the mode, which holds, and the resident
//! warp's kind): a load still queued at the SM's L1 port when the warp changes counts for the
//! next warp. Ray-record loads count for the kind of
//! the fill they load, with the cycles their ray waited in the queues (from being parked at a
//! boundary or terminated to the load's request).

use serde::Serialize;
use vtq_hdl::rt_unit::RtStats;
use vtq_hdl::treelet_rt_unit::WarpKind;

use crate::model::memory::{Acceptance, Source};

vtq_hdl::counters! {
    /// The events of one (phase, warp kind) cell, summed over its cycles (and SMs).
    #[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
    pub struct CostCounts {
        /// The RT unit's counters of the cycles attributed to the cell (warp cycles, lanes,
        /// node loads, tests, stack traffic, hit stores).
        pub rt: RtStats,
        /// Rays entering warps of this kind: an SM warp's rays when accepted, a fill's rays
        /// when their records are loaded.
        pub rays_in: u64,
        /// BVH demand loads (32 B) the L1 accepted.
        pub bvh_l1_accesses: u64,
        /// ... that hit the L1.
        pub bvh_l1_hits: u64,
        /// ... that merged with a fill of the same sector in flight.
        pub bvh_l1_merges: u64,
        /// ... that missed and fetched the sector from the L2.
        pub bvh_l1_misses: u64,
        /// 32 B ray records loaded (L1 bypass) into fills of this kind.
        pub ray_loads: u64,
        /// Cycles the rays of those loads waited in the treelet queues.
        pub queue_wait_cycles: u64,
    }
}

vtq_hdl::counters! {
    /// Per phase (initial, treelet stationary, final ray stationary: the order of
    /// `QueueObserver::tests`) and per [`WarpKind`], the cell's counters.
    #[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
    pub struct WarpCosts {
        /// `cells[phase][kind.index()]`.
        pub cells: [[CostCounts; 3]; 3],
    }
}

impl WarpCosts {
    /// The cell of phase index `phase` and warp kind `kind`.
    pub fn cell(&mut self, phase: usize, kind: WarpKind) -> &mut CostCounts {
        &mut self.cells[phase][kind.index()]
    }
}

impl CostCounts {
    /// Counts a BVH demand load the L1 accepted as `acceptance`.
    pub fn count_bvh_access(&mut self, acceptance: &Acceptance) {
        self.bvh_l1_accesses += 1;
        match acceptance {
            Acceptance::Known(a) if a.source == Source::L1Hit => self.bvh_l1_hits += 1,
            Acceptance::Known(a) if a.source == Source::L1Merge => self.bvh_l1_merges += 1,
            Acceptance::Pending { merge: true, .. } => self.bvh_l1_merges += 1,
            _ => self.bvh_l1_misses += 1,
        }
    }

    /// The cell's report for warps of `warp_size` lanes.
    pub fn report(&self, warp_size: u32) -> CostReport {
        let rt = &self.rt;
        let tests = rt.total_tests();
        let lanes = rt.warp_cycles * warp_size as u64;
        let chunks_from_l2 = self.bvh_l1_misses + self.ray_loads + rt.stack_fills;
        let chunks_to_l2 = rt.stores + rt.stack_spills;
        CostReport {
            rays_in: self.rays_in,
            intersection_tests: tests,
            warp_cycles: rt.warp_cycles,
            simt_efficiency: ratio(rt.active_thread_cycles, lanes),
            warp_cycles_per_test: ratio(rt.warp_cycles, tests),
            tests_per_ray: ratio(tests, self.rays_in),
            waiting_lanes: ratio(rt.waiting_lane_cycles, rt.warp_cycles),
            parked_lane_share: ratio(rt.parked_lane_cycles, lanes),
            bvh_l1_accesses: self.bvh_l1_accesses,
            bvh_l1_miss_rate: ratio(self.bvh_l1_misses, self.bvh_l1_accesses),
            bvh_l1_merge_rate: ratio(self.bvh_l1_merges, self.bvh_l1_accesses),
            l2_bytes: 32 * (chunks_from_l2 + chunks_to_l2),
            l2_bytes_per_ray: ratio(32 * (chunks_from_l2 + chunks_to_l2), self.rays_in),
            ray_record_loads: self.ray_loads,
            stack_chunks: rt.stack_spills + rt.stack_fills,
            queue_wait_cycles_per_ray: ratio(self.queue_wait_cycles, self.ray_loads),
        }
    }
}

/// `a / b`, 0 when `b` is 0.
fn ratio(a: u64, b: u64) -> f64 {
    if b == 0 {
        0.0
    } else {
        a as f64 / b as f64
    }
}

/// What warps of one kind cost in one phase (docs/stats.md, `warp_costs`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct CostReport {
    /// Rays entering warps of this kind (SM rays accepted; fill rays loaded).
    pub rays_in: u64,
    /// Node tests (node visits) the warps made.
    pub intersection_tests: u64,
    /// RT-unit warp cycles the warps held a slot.
    pub warp_cycles: u64,
    /// Traversing lanes per lane of those warp cycles.
    pub simt_efficiency: f64,
    /// Warp cycles per node test: the cost of a node visit in warp-buffer time.
    pub warp_cycles_per_test: f64,
    /// Node tests per ray entering.
    pub tests_per_ray: f64,
    /// Lanes waiting for a node in flight per warp cycle: the warp's memory-level parallelism.
    pub waiting_lanes: f64,
    /// Share of lane cycles parked at a treelet boundary.
    pub parked_lane_share: f64,
    /// BVH demand loads the L1 accepted.
    pub bvh_l1_accesses: u64,
    /// Share of them that missed the L1.
    pub bvh_l1_miss_rate: f64,
    /// Share of them that merged with a fill in flight.
    pub bvh_l1_merge_rate: f64,
    /// Bytes between the L1 port and the L2: BVH misses, ray-record loads, stack spills and
    /// fills, hit stores (32 B each).
    pub l2_bytes: u64,
    /// `l2_bytes` per ray entering.
    pub l2_bytes_per_ray: f64,
    /// 32 B ray-record loads (fills of this kind).
    pub ray_record_loads: u64,
    /// 32 B stack spill and fill chunks.
    pub stack_chunks: u64,
    /// Mean cycles a loaded ray had waited in the queues.
    pub queue_wait_cycles_per_ray: f64,
}

/// The `warp_costs` statistics: per phase, per warp kind, the cell's report.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct WarpCostStats {
    /// Initial ray-stationary phase.
    pub initial: KindReports,
    /// Treelet-stationary mode.
    pub treelet_stationary: KindReports,
    /// Final ray-stationary phase.
    pub ray_stationary: KindReports,
}

/// One phase's reports per warp kind.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct KindReports {
    /// SM warps (initial phase, terminated or not).
    pub sm: CostReport,
    /// Treelet warps.
    pub treelet: CostReport,
    /// Grouped (and repacked) warps.
    pub grouped: CostReport,
}

impl WarpCosts {
    /// The statistics of these counters for warps of `warp_size` lanes.
    pub fn stats(&self, warp_size: u32) -> WarpCostStats {
        let phase = |p: usize| {
            let r = |k: WarpKind| self.cells[p][k.index()].report(warp_size);
            KindReports {
                sm: r(WarpKind::Sm),
                treelet: r(WarpKind::Treelet),
                grouped: r(WarpKind::Grouped),
            }
        };
        WarpCostStats {
            initial: phase(0),
            treelet_stationary: phase(1),
            ray_stationary: phase(2),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::memory::Accepted;

    #[test]
    fn accesses_split_into_hits_merges_and_misses() {
        let mut c = CostCounts::default();
        let known = |source| Acceptance::Known(Accepted { done: 0, source });
        c.count_bvh_access(&known(Source::L1Hit));
        c.count_bvh_access(&known(Source::L1Merge));
        c.count_bvh_access(&Acceptance::Pending { op: 0, merge: true });
        c.count_bvh_access(&Acceptance::Pending {
            op: 1,
            merge: false,
        });
        assert_eq!(
            (
                c.bvh_l1_accesses,
                c.bvh_l1_hits,
                c.bvh_l1_merges,
                c.bvh_l1_misses
            ),
            (4, 1, 2, 1)
        );
        let r = c.report(32);
        assert_eq!(r.bvh_l1_miss_rate, 0.25);
        assert_eq!(r.l2_bytes, 32);
        assert_eq!(r.warp_cycles_per_test, 0.0, "no tests: 0, not NaN");
    }

    #[test]
    fn cells_add_up_and_report_their_ratios() {
        let mut a = WarpCosts::default();
        let cell = a.cell(1, WarpKind::Treelet);
        cell.rt.warp_cycles = 100;
        cell.rt.active_thread_cycles = 1600;
        cell.rt.tests[1] = 50;
        cell.rays_in = 32;
        cell.ray_loads = 32;
        cell.queue_wait_cycles = 320;
        let mut total = WarpCosts::default();
        total.add(&a);
        total.add(&a);
        let s = total.stats(32);
        let t = s.treelet_stationary.treelet;
        assert_eq!(t.intersection_tests, 100);
        assert_eq!(t.warp_cycles_per_test, 2.0);
        assert_eq!(t.simt_efficiency, 0.5);
        assert_eq!(t.queue_wait_cycles_per_ray, 10.0);
        assert_eq!(t.l2_bytes_per_ray, 32.0);
        assert_eq!(s.ray_stationary.grouped, CostReport::default());
    }
}
