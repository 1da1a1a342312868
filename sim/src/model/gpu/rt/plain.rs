//! The baseline RT unit's cycle in an [`RtPort`]: a warp offered into a free warp-buffer slot,
//! responses fed into its FIFO, its request queued, a completed warp's hits returned; the
//! treelet prefetcher (prefetch mode) observes it.

use vtq_hdl::rt_unit::{
    RtCache, RtStats, RtUnit, RtUnitError, RtUnitInputs, RtUnitParams, RtUnitRegs, RtUnitStatus,
    StatusSelect, WarpIssue,
};
use vtq_hdl::trace::BlockCycle;
use vtq_hdl::{Block, Cached, HwConfig, Moore, Skip, Taps};

use super::hardware::RtHardware;
use super::waveform::Waveform;
use super::{rt_error, tally, waveform, RtCycle, Shell, TracedWarp};
use crate::model::geometry::Hit;
use crate::model::gpu::datapath::{hit_from_hw, BvhDatapath};
use crate::model::gpu::error::SimError;
use crate::model::gpu::warp_simt::WarpSimt;
use crate::model::workload::kind::TraceRay;

/// The baseline RT unit with its registers, cache and input bundle.
#[derive(Debug, Clone)]
pub(super) struct Plain<'a> {
    pub(super) unit: RtUnit<BvhDatapath<'a>>,
    pub(super) regs: RtUnitRegs,
    pub(super) cache: RtCache,
    /// Reused every step so feeding responses does not allocate.
    pub(super) inputs: RtUnitInputs,
    /// SM warp slot held by each warp-buffer slot.
    pub(super) slot_warp: Vec<Option<usize>>,
    /// The RT unit's status ports, computed when a warp is offered (kept for their storage).
    pub(super) status: RtUnitStatus,
}

impl<'a> Plain<'a> {
    /// The RT unit of `hw` and `params` after reset.
    pub(super) fn new(
        hw: &HwConfig,
        params: RtUnitParams,
        datapath: BvhDatapath<'a>,
    ) -> Result<Self, RtUnitError> {
        let unit = RtUnit::new(hw.clone(), params, datapath)?;
        let regs = unit.reset();
        let cache = unit.cache(&regs);
        let inputs = unit.idle_inputs();
        Ok(Plain {
            slot_warp: vec![None; hw.warp_buffer_size as usize],
            status: unit.status(&regs, &cache, StatusSelect::Slots),
            unit,
            regs,
            cache,
            inputs,
        })
    }
}

impl<'a> RtHardware<'a> for Plain<'a> {
    fn issue_ready(&self) -> bool {
        self.unit
            .status(&self.regs, &self.cache, StatusSelect::Scalars)
            .issue_ready
    }

    fn observe_warps(&self, simt: &mut WarpSimt, n: u64) {
        simt.observe(n, self.unit.slot_lanes(&self.regs, &self.cache));
    }

    fn resident(&self) -> (u64, u64) {
        tally(self.unit.slot_lanes(&self.regs, &self.cache))
    }

    fn traversing_rays(&self) -> u64 {
        self.unit.traversing_rays(&self.regs, &self.cache)
    }

    fn idle_cycles(&self) -> u64 {
        self.unit.idle_cycles(&self.regs, &self.cache)
    }

    fn skip(&mut self, n: u64, stats: &mut RtStats) {
        let counts = self.unit.skip(&mut self.regs, &mut self.cache, n);
        stats.add(&counts);
    }

    fn idle_step(&mut self, stats: &mut RtStats, w: &mut Waveform, c: u64) {
        let regs = self.unit.reg_signals(&self.regs);
        let inputs: RtUnitInputs = self.unit.idle_inputs();
        let out = self
            .unit
            .step_cached(&mut self.regs, &mut self.cache, &inputs);
        debug_assert!(
            out.request.is_none() && out.done.is_none() && out.first_error.is_none(),
            "an idle cycle did something (cycle {c})"
        );
        stats.add(&out.counts);
        w.record_rt_unit(BlockCycle::new(&inputs, &out, regs));
    }

    fn debug_state(&self, common: &str) -> String {
        format!(
            "{}; warps {:?}; {common}",
            self.unit.debug_state(&self.regs),
            self.slot_warp
        )
    }

    /// A cycle `now` of the baseline RT unit.
    #[inline]
    fn step(
        &mut self,
        shell: &mut Shell<'a>,
        now: u64,
        sm: usize,
        warp: Option<(usize, &[Option<TraceRay>])>,
    ) -> Result<RtCycle, SimError> {
        let mut cycle = RtCycle::default();
        let record = shell.recording(now);
        let warp_size = self.unit.config().warp_size as usize;
        // A new warp goes to the lowest slot the status ports show free.
        let free = warp.and_then(|_| {
            self.unit.status_into(
                &self.regs,
                &self.cache,
                StatusSelect::Slots,
                &mut self.status,
            );
            (0..self.slot_warp.len() as u32).find(|&s| self.status.slot(s as usize).is_none())
        });
        let issue = match (warp, free) {
            (Some((idx, rays)), Some(slot)) => Some((
                idx,
                slot,
                WarpIssue {
                    order: shell.order,
                    lanes: shell.warp_lanes(slot as usize, rays, warp_size),
                    ..WarpIssue::default()
                },
            )),
            _ => None,
        };
        self.inputs.issue = None;
        if let Some((idx, slot, issue)) = issue {
            self.unit
                .check_issue(&issue)
                .map_err(|e| SimError::Rt { sm, source: e })?;
            shell.rays_issued += issue.lanes.iter().flatten().count() as u64;
            self.slot_warp[slot as usize] = Some(idx);
            self.inputs.issue = Some(issue);
            cycle.accepted = Some(idx);
        }
        let free = self
            .unit
            .status(&self.regs, &self.cache, StatusSelect::Scalars)
            .resp_free;
        let regs_before = record.then(|| waveform::rt_unit_regs(&self.unit, &self.regs));
        // The rays' next nodes change only when a response is delivered (the FIFO held one),
        // a request pops a stack, or a warp enters or completes.
        let delivers = free < self.unit.params().resp_fifo_depth || self.inputs.issue.is_some();
        let ports = free.min(self.unit.params().resp_ports);
        let n = (ports as usize).min(shell.responses.len());
        self.inputs.responses.clear();
        self.inputs.responses.extend(shell.responses.drain(..n));
        let out = self
            .unit
            .step_cached(&mut self.regs, &mut self.cache, &self.inputs);
        if let (Some(regs), Some(w)) = (regs_before, shell.waveform.as_mut()) {
            w.record_rt_unit(BlockCycle::new(&self.inputs, &out, regs));
        }
        shell.stats.add(&out.counts);
        if let Some(pf) = shell.prefetcher.as_mut() {
            let next = self.unit.next_addresses(&self.regs, &self.cache);
            if delivers || out.request.is_some() || out.done.is_some() {
                pf.observe(next);
            } else {
                pf.unchanged(next);
            }
        }
        if let Some(record) = out.first_error {
            let owner = self
                .slot_warp
                .get(record.slot as usize)
                .copied()
                .flatten()
                .map(|w| (w, record.lane));
            return Err(rt_error(sm, record, owner, shell.address_bits));
        }
        let done = out.done.map(|done| {
            let warp = self.slot_warp[done.slot as usize].take();
            (warp, done)
        });
        if let Some(req) = out.request {
            shell.push_request(&req);
        }
        if let Some((warp, done)) = done {
            let warp = warp.ok_or_else(|| SimError::Queues {
                sm,
                reason: format!(
                    "warp-buffer slot {} completed a warp it never got",
                    done.slot
                ),
            })?;
            let hits: Vec<Option<Option<Hit>>> = done
                .lanes
                .iter()
                .map(|l| l.as_ref().map(|(rec, _)| rec.hit.as_ref().map(hit_from_hw)))
                .collect();
            shell.rays_completed += hits.iter().flatten().count() as u64;
            cycle.done = Some(TracedWarp { warp, hits });
        }
        Ok(cycle)
    }
}
