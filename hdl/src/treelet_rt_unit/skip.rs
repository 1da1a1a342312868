//! Clock gating of the treelet RT unit ([`Skip`]): the cycles in which, with idle inputs, the
//! block does nothing but count cycles, count down intersection delays and advance a
//! count-table scan, and the jump over them that equals stepping them one by one.

use super::wiring::{self, Peeks};
use super::{log_controller, TreeletCounts, TreeletRtUnit, TreeletRtUnitCache, TreeletRtUnitRegs};
use crate::block::{Block, Moore, Skip};
use crate::mode::Mode;
use crate::rt_unit::{NodeDatapath, StatusSelect};

/// Idle while the wiring has nothing to report or issue and the last dry run found the
/// controller asleep: the RT unit's and the count table's own idle cycles bound it.
impl<D: NodeDatapath> Skip for TreeletRtUnit<D> {
    type Counts = TreeletCounts;

    /// Cycles from now in which the block, with idle inputs, does nothing but count cycles,
    /// count down intersection delays and advance a count-table scan (`u64::MAX`: it waits
    /// only for inputs). 0 while the wiring has work: events to report, a complete fill to
    /// issue, or a controller the last dry run found awake.
    fn idle_cycles(&self, regs: &TreeletRtUnitRegs, cache: &TreeletRtUnitCache) -> u64 {
        if cache.awake || wiring::glue_busy(&regs.glue) {
            return 0;
        }
        let rt = self.rt.idle_cycles(&regs.rt, &cache.rt);
        let ct = self.ct.idle_cycles(&regs.ct, &());
        rt.min(ct)
    }

    /// Advances `n <= idle_cycles` idle cycles, as `n` cached steps with idle inputs would: the
    /// RT unit's delays, the count table's scan (its `Nop` cycles) and the controller's cycle
    /// counter. Returns the statistics increments of those cycles. Afterwards `idle_cycles`
    /// counts from the new cycle (0 if the skip reached the end of the idle period).
    fn skip(
        &self,
        regs: &mut TreeletRtUnitRegs,
        cache: &mut TreeletRtUnitCache,
        n: u64,
    ) -> TreeletCounts {
        let mut counts = TreeletCounts::default();
        if n == 0 {
            return counts;
        }
        debug_assert!(
            n <= self.idle_cycles(regs, cache),
            "skip beyond the idle cycles"
        );
        // Registers hold through the skipped cycles but for delays that end only at its end, so
        // the first cycle's repack verdict is every skipped cycle's.
        if self.repack_withheld_at(regs, cache) {
            counts.ctl.repack_starved_cycles += n;
        }
        self.log_skipped(regs, cache, n);
        cache.dry_valid = false;
        cache.probed = None;
        // A skip to the RT unit's bound ends a delay, which may change the slot summaries the
        // controller reads.
        let delay_ends = n >= self.rt.idle_cycles(&regs.rt, &cache.rt);
        counts.rt = self.rt.skip(&mut regs.rt, &mut cache.rt, n);
        // The status ports change only where a delay ends (the lanes' other state and the
        // controller's mode stay); then they are computed again, so they stay current.
        if delay_ends {
            super::fast_path::refresh_rt_status(self, regs, cache);
        }
        let scanning = !self.ct.gated(&regs.ct, &());
        self.ct.skip(&mut regs.ct, &mut (), n);
        // So does a scan that published its pointers: the next cycle evaluates the controller
        // (no more idle cycles until then).
        cache.awake |= delay_ends || (scanning && self.ct.gated(&regs.ct, &()));
        counts
            .ctl
            .count_cycles(self.ctl.status(&regs.ctl, &(), ()), n);
        counts
    }
}

impl<D: NodeDatapath> TreeletRtUnit<D> {
    /// Records the `n` skipped cycles' inputs while the cache records them: the controller's
    /// (those the wiring gives it now, with no SM warp: they hold through the skipped cycles,
    /// which end before a delay ends or a scan publishes), and idle inputs for the RT unit, the
    /// tables and the whole block.
    fn log_skipped(&self, regs: &TreeletRtUnitRegs, cache: &mut TreeletRtUnitCache, n: u64) {
        let Some(log) = cache.tables.as_ref() else {
            return;
        };
        let room = log.limit.saturating_sub(log.controller.len()) as u64;
        if room > 0 {
            let distinct = wiring::reads_distinct(self, &regs.ctl, false);
            let status = self
                .rt
                .status(&regs.rt, &cache.rt, StatusSelect::slots(distinct));
            let peeks = Peeks::of(self, &status, &regs.ctl, &regs.ct, &regs.qt);
            let (inputs, _) = wiring::controller_inputs(self, &regs.glue, &peeks, false);
            for _ in 0..n.min(room) {
                log_controller(&mut cache.tables, &inputs);
            }
        }
        if let Some(log) = cache.tables.as_mut() {
            let room = log.limit.saturating_sub(log.rt_unit.len()) as u64;
            log.rt_unit.extend(std::iter::repeat_n(
                self.rt.idle_inputs(),
                n.min(room) as usize,
            ));
            let room = log.limit.saturating_sub(log.treelet.len()) as u64;
            log.treelet.extend(std::iter::repeat_n(
                self.idle_inputs(),
                n.min(room) as usize,
            ));
            let (ct, qt) = (self.ct.idle_inputs(), self.qt.idle_inputs());
            for _ in 0..n {
                cache.log_tables(&ct, &qt);
            }
        }
    }

    /// Whether a cycle starting with `regs` withholds a repack for want of rays (the
    /// controller's `repack_starved` output on the inputs the wiring would give it); for idle
    /// cycles, whose controller is not evaluated. Free unless the controller is in the final
    /// ray-stationary phase with repacking on: then the last dry run's verdict (the same
    /// registers; its inputs hold the same active-lane report, which does not depend on
    /// whether the SM offers a warp), else the controller evaluated.
    fn repack_withheld_at(&self, regs: &TreeletRtUnitRegs, cache: &mut TreeletRtUnitCache) -> bool {
        let mode = self.ctl.status(&regs.ctl, &(), ());
        if mode != Mode::FinalRayStationary
            || !crate::warp_repacking::repack_enabled(self.cfg.repack_threshold)
        {
            return false;
        }
        // The report the wiring would give the controller, from the RT unit's status ports.
        let mut evaluated = || {
            let status = self.rt.status(&regs.rt, &cache.rt, StatusSelect::Slots);
            let peeks = Peeks::of(self, &status, &regs.ctl, &regs.ct, &regs.qt);
            let mut inputs = self.ctl.idle_inputs();
            inputs.active_report = wiring::active_report(&regs.glue, &peeks, mode);
            let scratch = cache
                .scratch
                .get_or_insert_with(|| Box::new(regs.ctl.clone()));
            self.ctl
                .next_into(&regs.ctl, &inputs, scratch)
                .repack_starved
        };
        if cache.dry_valid {
            let withheld = cache.repack_starved;
            debug_assert_eq!(withheld, evaluated(), "the dry run's verdict is stale");
            withheld
        } else {
            evaluated()
        }
    }
}
