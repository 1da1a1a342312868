//! One cycle of the RT unit ([`RtUnit::update`], the seven stages of the module documentation's
//! "One cycle") and the stages that change the warp buffer's occupancy: a warp issued into a
//! slot, a treelet warp stopped, a warp repacked, and completion.

use super::{
    bits, occupied, raise, record, ErrorKind, ErrorRecord, IssueTarget, Lane, LaneMasks,
    LaneStatus, LaneWrite, NodeDatapath, RayOutcome, RayRecord, RtCache, RtStats, RtUnit,
    RtUnitError, RtUnitInputs, RtUnitOutputs, RtUnitRegs, TraversalOrder, WarpDone, WarpIssue,
    WarpSlot,
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

        // 7. Warp issue and lane write (they share the issue bus), then the treelet
        // controller's commands.
        if inp.issue.is_some() || inp.write.is_some() {
            self.issue_and_write(r, c, free_mask, inp.issue.as_ref(), inp.write.as_ref());
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

    /// Step 7: checks the records on the issue bus (a bad one drops both the issue and the
    /// write), then issues the warp and writes the lanes.
    fn issue_and_write(
        &self,
        r: &mut RtUnitRegs,
        c: &mut RtCache,
        free_mask: u64,
        issue: Option<&WarpIssue>,
        write: Option<&LaneWrite>,
    ) {
        let n = self.cfg.warp_size as usize;
        let lengths = issue
            .map(|i| i.lanes.len())
            .into_iter()
            .chain(write.map(|w| w.lanes.len()));
        let checked = match lengths.into_iter().find(|&len| len != n) {
            Some(len) => Err(RtUnitError::BadIssue {
                lane: 0,
                reason: format!("{len} lanes, expected warp_size = {n}"),
            }),
            // Lane l of the bus carries the issue's record, else the write's.
            None => self.check_lanes((0..n).map(|l| {
                lane_of(issue.map(|i| &i.lanes[..]), l)
                    .or_else(|| lane_of(write.map(|w| &w.lanes[..]), l))
            })),
        };
        if let Err(e) = checked {
            let lane = match e {
                RtUnitError::BadIssue { lane, .. } => lane,
                _ => 0,
            };
            let ray_id = [issue.map(|i| &i.lanes), write.map(|w| &w.lanes)]
                .into_iter()
                .flatten()
                .find_map(|lanes| lanes.get(lane as usize)?.as_ref())
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
        let issued = issue.and_then(|i| self.issue(r, c, free_mask, i));
        if let Some(w) = write {
            let busy = issue.map_or(0, |i| occupied(&i.lanes));
            self.write(r, c, w, busy, issued);
        }
    }

    /// Loads an issued warp into a slot that was free at the start of the cycle (bit `s` of
    /// `free_mask`) or appends a repack fill to a held slot; lanes named in
    /// [`WarpIssue::written`] enter from the records written into them before. Returns the
    /// slot acted on (`None`: the command was refused).
    fn issue(
        &self,
        r: &mut RtUnitRegs,
        c: &mut RtCache,
        free_mask: u64,
        issue: &WarpIssue,
    ) -> Option<usize> {
        let free_slot = (free_mask != 0).then(|| free_mask.trailing_zeros() as usize);
        let lane_bits = lane_mask(self.cfg.warp_size);
        let active = occupied(&issue.lanes);
        let written = issue.written & lane_bits;
        // The lanes named written hold written records, and none also takes one from the bus.
        let written_ok =
            |slot: &WarpSlot| written & active == 0 && bits(written).all(|l| slot.lanes[l].written);
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
        let target = match issue.target {
            IssueTarget::AnyFree => {
                let Some(s) = free_slot else {
                    raise(
                        &mut r.errors,
                        &mut r.first_error,
                        record(
                            ErrorKind::IssueWhileFull,
                            self.cfg.warp_buffer_size as u64 + 1,
                            self.cfg.warp_buffer_size as u64,
                        ),
                    );
                    return None;
                };
                s
            }
            IssueTarget::Slot(s) if s < 64 && free_mask >> s & 1 == 1 => s as usize,
            IssueTarget::Slot(s) => {
                bad_command(r, s);
                return None;
            }
            IssueTarget::Append { slot: s, .. } => {
                let ok = r.slots.get(s as usize).is_some_and(|slot| {
                    slot.valid && slot.held && bits(active).all(|l| slot.lanes[l].empty())
                });
                if !ok {
                    bad_command(r, s);
                    return None;
                }
                s as usize
            }
        };
        if !written_ok(&r.slots[target]) {
            bad_command(r, issue.target.slot());
            return None;
        }
        match issue.target {
            IssueTarget::Append { last, .. } => {
                let slot = &mut r.slots[target];
                for (l, (lane, ray)) in slot.lanes.iter_mut().zip(&issue.lanes).enumerate() {
                    if let Some(ray) = ray {
                        *lane = self.lane_for(ray);
                    } else if written >> l & 1 == 1 {
                        wake(lane);
                    }
                }
                c.masks[target] = LaneMasks::of(&slot.lanes, self.keep());
                if last {
                    slot.held = false;
                }
            }
            _ => self.load(r, c, target, issue.order, &issue.lanes, written),
        }
        Some(target)
    }

    /// Writes the records of `write` into their lanes, inactive until an issue names them,
    /// unless the write is refused (a bad controller command): its slot is out of range, holds
    /// a warp that is not held, or is the slot this cycle's issue acted on (`issued`); a lane
    /// it writes carries an issued ray on the bus (`busy`) or is not an empty inactive lane.
    fn write(
        &self,
        r: &mut RtUnitRegs,
        c: &mut RtCache,
        write: &LaneWrite,
        busy: u64,
        issued: Option<usize>,
    ) {
        let s = write.slot as usize;
        let mask = write.mask();
        let ok = busy & mask == 0
            && issued != Some(s)
            && r.slots.get(s).is_some_and(|slot| {
                (!slot.valid || slot.held) && bits(mask).all(|l| slot.lanes[l].empty())
            });
        if !ok {
            raise(
                &mut r.errors,
                &mut r.first_error,
                ErrorRecord {
                    slot: write.slot,
                    ..record(ErrorKind::BadCommand, WRITE_COMMAND, 0)
                },
            );
            return;
        }
        let slot = &mut r.slots[s];
        for (l, ray) in write.lanes.iter().enumerate() {
            if let Some(ray) = ray {
                let lane = &mut slot.lanes[l];
                *lane = Lane {
                    status: LaneStatus::Inactive,
                    written: true,
                    ..self.lane_for(ray)
                };
                c.masks[s].set(l, lane);
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
            status: entering(ray),
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

    /// Writes an issued warp of order `order` into slot `s`: each lane from its record on the
    /// bus (`lanes`), or from the record written into it before (bit set in `written`), or
    /// empty.
    pub(super) fn load(
        &self,
        r: &mut RtUnitRegs,
        c: &mut RtCache,
        s: usize,
        order: TraversalOrder,
        lanes: &[Option<RayRecord>],
        written: u64,
    ) {
        let slot = &mut r.slots[s];
        slot.valid = true;
        slot.held = false;
        slot.order = order;
        for (l, (lane, ray)) in slot.lanes.iter_mut().zip(lanes).enumerate() {
            match ray {
                Some(ray) => *lane = self.lane_for(ray),
                None if written >> l & 1 == 1 => wake(lane),
                None => *lane = Lane::default(),
            }
        }
        c.masks[s] = LaneMasks::of(&slot.lanes, self.keep());
        // A slot enters only when free, so the age list never holds more than every slot.
        let entered = r.age.push(s as u32);
        debug_assert!(entered.is_ok(), "age list full");
    }
}

/// The `BadCommand` error's value for a refused lane write (the issue's are its target codes,
/// 0 to 3).
const WRITE_COMMAND: u64 = 4;

/// A written lane enters its warp: traversing, or done if its ray has finished (as
/// [`RtUnit::lane_for`] enters a ray issued on the bus).
fn wake(lane: &mut Lane) {
    lane.written = false;
    lane.status = entering(&lane.ray);
}

/// The status a lane enters its warp with holding `ray`: done if the ray has finished, else
/// traversing.
fn entering(ray: &RayRecord) -> LaneStatus {
    if ray.finished() {
        LaneStatus::Done
    } else {
        LaneStatus::Traversing
    }
}

/// A mask of the lanes of a `warp_size`-lane warp.
fn lane_mask(warp_size: u32) -> u64 {
    if warp_size >= 64 {
        u64::MAX
    } else {
        (1 << warp_size) - 1
    }
}

/// Lane `l`'s record in `lanes`, if any.
fn lane_of(lanes: Option<&[Option<RayRecord>]>, l: usize) -> Option<&RayRecord> {
    lanes?.get(l)?.as_ref()
}
