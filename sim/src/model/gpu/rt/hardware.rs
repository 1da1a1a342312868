//! The RT hardware beside an SM as one trait ([`RtHardware`]): what an [`super::RtPort`] asks of
//! the design's kind of hardware, whatever it is. The baseline and prefetch designs step the RT
//! unit ([`super::plain`]), the queues design the treelet RT unit ([`super::treelet`]); a new
//! kind is one implementation, a variant of [`Kind`] (with its arm in `on_kind`) and its
//! construction in [`super::RtPort::new`]. The methods with defaults
//! are the queues design's (ray records, the statistics observer, the tables' log): hardware
//! without treelet queues has none of them.

use std::fmt::Debug;

use vtq_hdl::rt_unit::RtStats;
use vtq_hdl::treelet_rt_unit::TableLog;

use super::plain::Plain;
use super::treelet::{QueueObserver, Treelet};
use super::warp_costs::WarpCosts;
use super::waveform::Waveform;
use super::{RtCycle, Shell};
use crate::model::gpu::error::SimError;
use crate::model::gpu::warp_simt::WarpSimt;
use crate::model::memory::{Acceptance, Response};
use crate::model::workload::kind::TraceRay;

/// One SM's RT hardware, stepped by its port (which owns the surroundings: [`Shell`]).
pub(super) trait RtHardware<'a>: Debug {
    /// Whether a warp can be offered this cycle (the `issue_ready` or `sm_ready` output).
    fn issue_ready(&self) -> bool;

    /// Follows the warp-buffer slots over the next `n` cycles in the registers' current state.
    fn observe_warps(&self, simt: &mut WarpSimt, n: u64);

    /// Resident warps and their traversing lanes (what an idle cycle adds to the counters).
    fn resident(&self) -> (u64, u64);

    /// Rays traversing in the warp buffer.
    fn traversing_rays(&self) -> u64;

    /// Cycles from now in which the hardware, given idle inputs, only counts.
    fn idle_cycles(&self) -> u64;

    /// Skips `n` idle cycles, adding the RT unit's counts to `stats`.
    fn skip(&mut self, n: u64, stats: &mut RtStats);

    /// One cycle `now` of SM `sm`'s hardware, offered `warp` (SM warp slot and its lanes'
    /// rays) if given, fed from and queueing into `shell`.
    fn step(
        &mut self,
        shell: &mut Shell<'a>,
        now: u64,
        sm: usize,
        warp: Option<(usize, &[Option<TraceRay>])>,
    ) -> Result<RtCycle, SimError>;

    /// One idle cycle `c` stepped with idle inputs and recorded into `w` (inside a waveform's
    /// window), adding the RT unit's counts to `stats`.
    fn idle_step(&mut self, stats: &mut RtStats, w: &mut Waveform, c: u64);

    /// A summary of the registers, with the port's `common` part, for the watchdog.
    fn debug_state(&self, common: &str) -> String;

    /// Ray records held on chip whose load is due by `now` are handed to the next step.
    fn records_due(&mut self, _now: u64) {}

    /// A ray-record or queued-stack load `r` answered by memory.
    fn ray_response(&mut self, _r: &Response) {}

    /// Work to hand on in the next cycle besides the hardware's own (records that arrived, a
    /// finished SM warp).
    fn has_work(&self) -> bool {
        false
    }

    /// The next cycle after `now` at which [`RtHardware::has_work`] or a record load's arrival
    /// asks for a step.
    fn next_event(&self, _now: u64) -> Option<u64> {
        None
    }

    /// The L1 accepted a demand BVH load of the hardware's ([`Acceptance`]): attributed to the
    /// warp kind and phase of the cycle, `idle` when the hardware was not stepped in it (its
    /// idle cycles are skipped later).
    fn bvh_access_accepted(&mut self, _acceptance: &Acceptance, _idle: bool) {}

    /// What each kind of warp cost in each phase so far (`stats`: the port's RT-unit counters).
    fn warp_costs(&self, _stats: &RtStats) -> Option<WarpCosts> {
        None
    }

    /// The statistics observer of the treelet hardware.
    fn queue_stats(&self) -> Option<&QueueObserver> {
        None
    }

    /// The queued-stack chunk stores and loads issued (`rt.queued_stack_traffic`).
    fn queued_stack_chunks(&self) -> (u64, u64) {
        (0, 0)
    }

    /// Records the treelet tables' input ports of the next `cycles` cycles; false when the
    /// hardware has no tables.
    fn record_tables(&mut self, _cycles: usize) -> bool {
        false
    }

    /// The tables' inputs recorded so far.
    fn take_table_log(&mut self) -> Option<TableLog> {
        None
    }
}

/// The kinds of RT hardware, each an [`RtHardware`], dispatched statically (the baseline's step
/// stays inlinable into the SM's visit). Adding a kind is a variant here and an arm in
/// [`on_kind`].
#[derive(Debug)]
pub(super) enum Kind<'a> {
    /// The RT unit (baseline and prefetch designs).
    Plain(Box<Plain<'a>>),
    /// The treelet RT unit (queues designs).
    Treelet(Box<Treelet<'a>>),
}

/// `$call` with `$h` bound to the hardware of kind `$kind`: the one match over the kinds.
macro_rules! on_kind {
    ($kind:expr, $h:ident => $call:expr) => {
        match $kind {
            Kind::Plain($h) => $call,
            Kind::Treelet($h) => $call,
        }
    };
}

impl<'a> RtHardware<'a> for Kind<'a> {
    #[inline]
    fn issue_ready(&self) -> bool {
        on_kind!(self, h => h.issue_ready())
    }

    #[inline]
    fn observe_warps(&self, simt: &mut WarpSimt, n: u64) {
        on_kind!(self, h => h.observe_warps(simt, n))
    }

    fn resident(&self) -> (u64, u64) {
        on_kind!(self, h => h.resident())
    }

    fn traversing_rays(&self) -> u64 {
        on_kind!(self, h => h.traversing_rays())
    }

    #[inline]
    fn idle_cycles(&self) -> u64 {
        on_kind!(self, h => h.idle_cycles())
    }

    #[inline]
    fn skip(&mut self, n: u64, stats: &mut RtStats) {
        on_kind!(self, h => h.skip(n, stats))
    }

    #[inline]
    fn step(
        &mut self,
        shell: &mut Shell<'a>,
        now: u64,
        sm: usize,
        warp: Option<(usize, &[Option<TraceRay>])>,
    ) -> Result<RtCycle, SimError> {
        on_kind!(self, h => h.step(shell, now, sm, warp))
    }

    fn idle_step(&mut self, stats: &mut RtStats, w: &mut Waveform, c: u64) {
        on_kind!(self, h => h.idle_step(stats, w, c))
    }

    fn debug_state(&self, common: &str) -> String {
        on_kind!(self, h => h.debug_state(common))
    }

    #[inline]
    fn records_due(&mut self, now: u64) {
        on_kind!(self, h => h.records_due(now))
    }

    fn ray_response(&mut self, r: &Response) {
        on_kind!(self, h => h.ray_response(r))
    }

    #[inline]
    fn has_work(&self) -> bool {
        on_kind!(self, h => h.has_work())
    }

    #[inline]
    fn next_event(&self, now: u64) -> Option<u64> {
        on_kind!(self, h => h.next_event(now))
    }

    #[inline]
    fn bvh_access_accepted(&mut self, acceptance: &Acceptance, idle: bool) {
        on_kind!(self, h => h.bvh_access_accepted(acceptance, idle))
    }

    fn warp_costs(&self, stats: &RtStats) -> Option<WarpCosts> {
        on_kind!(self, h => h.warp_costs(stats))
    }

    fn queue_stats(&self) -> Option<&QueueObserver> {
        on_kind!(self, h => h.queue_stats())
    }

    fn queued_stack_chunks(&self) -> (u64, u64) {
        on_kind!(self, h => h.queued_stack_chunks())
    }

    fn record_tables(&mut self, cycles: usize) -> bool {
        on_kind!(self, h => h.record_tables(cycles))
    }

    fn take_table_log(&mut self) -> Option<TableLog> {
        on_kind!(self, h => h.take_table_log())
    }
}
