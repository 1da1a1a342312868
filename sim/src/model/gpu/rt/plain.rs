//! The baseline RT unit's cycle in an [`RtPort`]: a warp offered into a free warp-buffer slot,
//! responses fed into its FIFO, its request queued, a completed warp's hits returned; the
//! treelet prefetcher (prefetch mode) observes it.

use vtq_hdl::rt_unit::{RtCache, RtUnit, RtUnitInputs, RtUnitRegs, RtUnitStatus, WarpIssue};
use vtq_hdl::trace::BlockCycle;

use super::{rt_error, waveform, Hardware, RtCycle, RtPort, TracedWarp};
use crate::model::geometry::Hit;
use crate::model::gpu::datapath::{hit_from_hw, BvhDatapath};
use crate::model::gpu::error::SimError;
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

impl<'a> RtPort<'a> {
    /// A cycle `now` of the baseline RT unit.
    pub(super) fn step_plain(
        &mut self,
        now: u64,
        sm: usize,
        warp: Option<(usize, &[Option<TraceRay>])>,
    ) -> Result<RtCycle, SimError> {
        let mut cycle = RtCycle::default();
        let record = self.recording(now);
        let Hardware::Plain(p) = &mut self.hw else {
            unreachable!("a plain port")
        };
        let warp_size = p.unit.config().warp_size as usize;
        // A new warp goes to the lowest slot the status ports show free.
        let free = warp.and_then(|_| {
            p.unit.status_into(&p.regs, &p.cache, false, &mut p.status);
            (0..p.slot_warp.len() as u32).find(|&s| p.status.slot(s as usize).is_none())
        });
        let issue = match (warp, free) {
            (Some((idx, rays)), Some(slot)) => Some((
                idx,
                slot,
                WarpIssue {
                    order: self.order,
                    lanes: self.warp_lanes(slot as usize, rays, warp_size),
                    ..WarpIssue::default()
                },
            )),
            _ => None,
        };
        let Hardware::Plain(p) = &mut self.hw else {
            unreachable!("a plain port")
        };
        p.inputs.issue = None;
        if let Some((idx, slot, issue)) = issue {
            p.unit
                .check_issue(&issue)
                .map_err(|e| SimError::Rt { sm, source: e })?;
            self.rays_issued += issue.lanes.iter().flatten().count() as u64;
            p.slot_warp[slot as usize] = Some(idx);
            p.inputs.issue = Some(issue);
            cycle.accepted = Some(idx);
        }
        let free = p.unit.resp_free(&p.regs);
        let regs_before = record.then(|| waveform::rt_unit_regs(&p.unit, &p.regs));
        // The rays' next nodes change only when a response is delivered (the FIFO held one),
        // a request pops a stack, or a warp enters or completes.
        let delivers = free < p.unit.params().resp_fifo_depth || p.inputs.issue.is_some();
        let ports = free.min(p.unit.params().resp_ports);
        let n = (ports as usize).min(self.responses.len());
        p.inputs.responses.clear();
        p.inputs.responses.extend(self.responses.drain(..n));
        let out = p.unit.step_cached(&mut p.regs, &mut p.cache, &p.inputs);
        if let (Some(regs), Some(w)) = (regs_before, self.waveform.as_mut()) {
            w.record_rt_unit(BlockCycle::new(&p.inputs, &out, regs));
        }
        self.stats.add(&out.counts);
        if let Some(pf) = self.prefetcher.as_mut() {
            let next = p.unit.next_addresses(&p.regs, &p.cache);
            if delivers || out.request.is_some() || out.done.is_some() {
                pf.observe(next);
            } else {
                pf.unchanged(next);
            }
        }
        if let Some(record) = out.first_error {
            let owner = p
                .slot_warp
                .get(record.slot as usize)
                .copied()
                .flatten()
                .map(|w| (w, record.lane));
            return Err(rt_error(sm, record, owner, self.address_bits));
        }
        let done = out.done.map(|done| {
            let warp = p.slot_warp[done.slot as usize].take();
            (warp, done)
        });
        if let Some(req) = out.request {
            self.push_request(&req);
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
            self.rays_completed += hits.iter().flatten().count() as u64;
            cycle.done = Some(TracedWarp { warp, hits });
        }
        Ok(cycle)
    }
}
