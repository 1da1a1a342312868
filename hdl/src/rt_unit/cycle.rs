//! One cycle of the RT unit ([`RtUnit::update`], the seven stages of the module documentation's
//! "One cycle") and the stages that change the warp buffer's occupancy: a warp issued into a
//! slot, a treelet warp stopped, a warp repacked, and completion.

use super::{
    bits, raise, record, ErrorKind, ErrorRecord, IssueTarget, Lane, LaneMasks, LaneStatus,
    NodeDatapath, RayOutcome, RayRecord, RtCache, RtStats, RtUnit, RtUnitError, RtUnitInputs,
    RtUnitOutputs, RtUnitRegs, TraversalOrder, WarpDone, WarpIssue,
};

impl<D: NodeDatapath> RtUnit<D> {
    /// The whole cycle, in place on `r` with its cache `c`.
    pub(super) fn update(
        &self,
        r: &mut RtUnitRegs,
        c: &mut RtCache,
        inp: &RtUnitInputs,
    ) -> RtUnitOutputs {
        let mut counts = RtStats::default();
        let free_mask = r
            .slots
            .iter()
            .enumerate()
            .fold(0u64, |m, (i, s)| m | (u64::from(!s.valid) << i));
        let free_slot = (free_mask != 0).then(|| free_mask.trailing_zeros() as usize);
        let issue_ready = free_slot.is_some();
        let resp_free = self.resp_free(r);

        // 1. Statistics.
        for (slot, m) in r.slots.iter().zip(&c.masks) {
            if slot.valid {
                counts.warp_cycles += 1;
                counts.active_thread_cycles += u64::from(m.traversing.count_ones());
                counts.waiting_lane_cycles += u64::from((m.traversing & m.in_flight).count_ones());
                counts.done_lane_cycles += u64::from(m.done.count_ones());
                counts.parked_lane_cycles += u64::from(m.parked.count_ones());
            }
        }

        // 2. Completion, 3. memory scheduler, 4. delay countdown.
        let done = self.complete(r, c, &mut counts);
        let request = self.schedule(r, c, &mut counts);
        for (slot, m) in r.slots.iter_mut().zip(&mut c.masks) {
            for l in bits(m.delayed) {
                let lane = &mut slot.lanes[l];
                lane.delay -= 1;
                if lane.delay == 0 {
                    m.delayed &= !(1 << l);
                }
            }
        }

        // 5. Response pop, 6. response push.
        let mut boundary = Vec::new();
        if let Some(resp) = r.fifo.pop_front() {
            self.deliver(r, c, &resp, &mut boundary, &mut counts);
        }
        for (k, resp) in inp.responses.iter().enumerate() {
            let accepted = k < self.params.resp_ports as usize && r.fifo.push_back(*resp).is_ok();
            if !accepted {
                let limit = (self.params.resp_ports as usize).min(resp_free as usize);
                raise(
                    &mut r.errors,
                    &mut r.first_error,
                    record(
                        ErrorKind::FifoOverflow,
                        inp.responses.len() as u64,
                        limit as u64,
                    ),
                );
            }
        }

        // 7. Warp issue, then the treelet controller's commands.
        if let Some(issue) = &inp.issue {
            self.issue(r, c, free_mask, issue);
        }
        if let Some(s) = inp.stop {
            self.stop(r, c, s);
        }
        let released = inp.repack.and_then(|s| self.repack(r, c, s));

        RtUnitOutputs {
            widths: self.widths,
            issue_ready,
            resp_free,
            request,
            done,
            boundary,
            released,
            errors: r.errors,
            first_error: r.first_error,
            counts,
        }
    }

    /// Step 7: loads an issued warp into a slot that was free at the start of the cycle (bit
    /// `s` of `free_mask`) or appends a repack fill to a held slot.
    pub(super) fn issue(
        &self,
        r: &mut RtUnitRegs,
        c: &mut RtCache,
        free_mask: u64,
        issue: &WarpIssue,
    ) {
        let free_slot = (free_mask != 0).then(|| free_mask.trailing_zeros() as usize);
        if let Err(e) = self.check_issue(issue) {
            let lane = match e {
                RtUnitError::BadIssue { lane, .. } => lane,
                _ => 0,
            };
            let ray_id = issue
                .lanes
                .get(lane as usize)
                .and_then(|l| l.as_ref())
                .map_or(0, |ray| ray.ray_id);
            raise(
                &mut r.errors,
                &mut r.first_error,
                ErrorRecord {
                    lane,
                    ray_id,
                    ..record(ErrorKind::BadIssue, 0, 0)
                },
            );
            return;
        }
        let bad_command = |r: &mut RtUnitRegs, slot: u32| {
            raise(
                &mut r.errors,
                &mut r.first_error,
                ErrorRecord {
                    slot,
                    ..record(ErrorKind::BadCommand, issue.target.code(), 0)
                },
            )
        };
        match issue.target {
            IssueTarget::AnyFree => match free_slot {
                None => raise(
                    &mut r.errors,
                    &mut r.first_error,
                    record(
                        ErrorKind::IssueWhileFull,
                        self.cfg.warp_buffer_size as u64 + 1,
                        self.cfg.warp_buffer_size as u64,
                    ),
                ),
                Some(s) => self.load(r, c, s, issue),
            },
            IssueTarget::Slot(s) if s < 64 && free_mask >> s & 1 == 1 => {
                self.load(r, c, s as usize, issue)
            }
            IssueTarget::Slot(s) => bad_command(r, s),
            IssueTarget::Append { slot: s, last } => {
                let ok =
                    r.slots.get(s as usize).is_some_and(|slot| {
                        slot.valid
                            && slot.held
                            && slot.lanes.iter().zip(&issue.lanes).all(|(lane, ray)| {
                                ray.is_none() || lane.status == LaneStatus::Inactive
                            })
                    });
                if !ok {
                    bad_command(r, s);
                    return;
                }
                let slot = &mut r.slots[s as usize];
                for (lane, ray) in slot.lanes.iter_mut().zip(&issue.lanes) {
                    if let Some(ray) = ray {
                        *lane = self.lane_for(ray);
                    }
                }
                c.masks[s as usize] = LaneMasks::of(&slot.lanes, self.keep());
                if last {
                    slot.held = false;
                }
            }
        }
    }

    /// Terminates slot `s`'s warp into the treelet queues: treelet-stop order from now on, and
    /// rays already between treelets park at once.
    pub(super) fn stop(&self, r: &mut RtUnitRegs, c: &mut RtCache, s: u32) {
        let Some(slot) = r.slots.get_mut(s as usize).filter(|slot| slot.valid) else {
            raise(
                &mut r.errors,
                &mut r.first_error,
                ErrorRecord {
                    slot: s,
                    ..record(ErrorKind::BadCommand, 0, 0)
                },
            );
            return;
        };
        slot.order = TraversalOrder::TreeletStop;
        for (l, lane) in slot.lanes.iter_mut().enumerate() {
            if lane.status == LaneStatus::Traversing
                && lane.in_flight.is_none()
                && lane.filling.is_none()
                && lane.ray.current_empty()
                && !lane.ray.other_stack.is_empty()
            {
                lane.status = LaneStatus::Parked;
                c.masks[s as usize].set(l, lane);
            }
        }
    }

    /// Repacks slot `s`: releases its finished, quiescent lanes and holds the slot. A slot
    /// that completed this cycle is left alone (nothing to repack).
    pub(super) fn repack(&self, r: &mut RtUnitRegs, c: &mut RtCache, s: u32) -> Option<WarpDone> {
        let slot = r.slots.get_mut(s as usize).filter(|slot| slot.valid)?;
        slot.held = true;
        let lanes = slot
            .lanes
            .iter_mut()
            .map(|lane| {
                crate::warp_repacking::releases(
                    lane.status == LaneStatus::Done,
                    lane.quiescent(self.keep()),
                )
                .then(|| {
                    lane.status = LaneStatus::Inactive;
                    (std::mem::take(&mut lane.ray), RayOutcome::Finished)
                })
            })
            .collect();
        c.masks[s as usize] = LaneMasks::of(&slot.lanes, self.keep());
        Some(WarpDone { slot: s, lanes })
    }

    /// A fresh lane holding `ray` (already finished rays enter done), its on-chip stacks of
    /// depth `stack_depth` ([`RtUnit::check_issue`] checked that they fit).
    pub(super) fn lane_for(&self, ray: &RayRecord) -> Lane {
        let depth = self.cfg.stack_depth as usize;
        let stacks = (
            ray.current_stack.with_capacity_of(depth),
            ray.other_stack.with_capacity_of(depth),
        );
        let (Ok(current_stack), Ok(other_stack)) = stacks else {
            unreachable!("check_issue bounds the stacks by stack_depth");
        };
        Lane {
            status: if ray.finished() {
                LaneStatus::Done
            } else {
                LaneStatus::Traversing
            },
            ray: RayRecord {
                current_stack,
                other_stack,
                ..ray.clone()
            },
            ..Lane::default()
        }
    }

    /// Removes and reports the oldest warp with nothing outstanding.
    pub(super) fn complete(
        &self,
        r: &mut RtUnitRegs,
        c: &mut RtCache,
        counts: &mut RtStats,
    ) -> Option<WarpDone> {
        let pos = r
            .age
            .iter()
            .position(|&s| !r.slots[s as usize].held && c.masks[s as usize].busy() == 0)?;
        let s = r.age.remove(pos);
        let slot = &mut r.slots[s as usize];
        slot.valid = false;
        counts.warps += 1;
        let lanes = slot
            .lanes
            .iter_mut()
            .map(|lane| {
                let outcome = match lane.status {
                    LaneStatus::Inactive | LaneStatus::Traversing => return None,
                    LaneStatus::Done => RayOutcome::Finished,
                    LaneStatus::Parked => RayOutcome::AtBoundary {
                        treelet: self.treelet_of(lane.ray.next_node()?.address),
                    },
                };
                lane.status = LaneStatus::Inactive;
                Some((std::mem::take(&mut lane.ray), outcome))
            })
            .collect();
        c.masks[s as usize] = LaneMasks::of(&slot.lanes, self.keep());
        Some(WarpDone { slot: s, lanes })
    }

    /// Writes an issued warp into slot `s`.
    pub(super) fn load(&self, r: &mut RtUnitRegs, c: &mut RtCache, s: usize, issue: &WarpIssue) {
        let slot = &mut r.slots[s];
        slot.valid = true;
        slot.held = false;
        slot.order = issue.order;
        for (lane, ray) in slot.lanes.iter_mut().zip(&issue.lanes) {
            *lane = ray
                .as_ref()
                .map_or_else(Lane::default, |ray| self.lane_for(ray));
        }
        c.masks[s] = LaneMasks::of(&slot.lanes, self.keep());
        // A slot enters only when free, so the age list never holds more than every slot.
        let entered = r.age.push(s as u32);
        debug_assert!(entered.is_ok(), "age list full");
    }
}
