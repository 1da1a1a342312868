//! The commands the RT unit's environment drives each cycle: the SM's warp issues, the
//! treelet controller's stops, repacks, appends and lane writes (a free slot staged ahead of
//! its issue), and the protocol faults injected after the quiet start.

use super::{Env, Staged};
use vtq_hdl::bounded::BoundedVec;
use vtq_hdl::rt_unit::{
    occupied, IssueTarget, LaneStatus, LaneWrite, NodeEntry, RtUnitInputs, TraversalOrder,
    WarpIssue,
};

/// The protocol breaks the environment injects, in this order: a warp issued while no slot is
/// free, a warp issued into a taken or missing slot, an append to a slot not held, a stop and
/// a repack of an empty or missing slot (the repack is ignored, not an error), a malformed
/// warp, an append into a lane of the held slot that holds a ray, and a lane write into a slot
/// holding a warp that is not held (or an issue naming a lane never written).
pub(super) const FAULTS: u64 = 8;

impl Env {
    /// Injects fault `f` ([`FAULTS`]) into `inp` if it applies this cycle.
    pub(super) fn inject(&mut self, f: u64, inp: &mut RtUnitInputs) -> Option<()> {
        let (free, taken) = (self.slots(false), self.slots(true));
        match f {
            0 if free.is_empty() => inp.issue = Some(self.throwaway(IssueTarget::AnyFree)),
            0 => return None,
            1 => {
                let s = self.bad_slot(&taken)?;
                inp.issue = Some(self.throwaway(IssueTarget::Slot(s)));
            }
            2 | 6 => {
                // To a slot not held, or (fault 6) into a lane of the held slot that holds a ray.
                let slots = &self.regs.slots;
                let held = self.held.map(|(s, _)| s as usize);
                let busy: Vec<usize> = held.map_or(Vec::new(), |s| {
                    let lanes = slots[s].lanes.iter().enumerate();
                    (lanes.filter(|(_, l)| l.status != LaneStatus::Inactive))
                        .map(|(l, _)| l)
                        .collect()
                });
                let unheld: Vec<u32> = (0..slots.len() as u32)
                    .filter(|&s| !slots[s as usize].held)
                    .collect();
                let lane = if f == 6 {
                    Some(self.pick(&busy)?)
                } else {
                    None
                };
                let slot = match (held, lane) {
                    (Some(s), Some(_)) => s as u32,
                    _ => self.pick(&unheld)?,
                };
                let last = self.rng.chance(50);
                let mut warp = self.throwaway(IssueTarget::Append { slot, last });
                if let Some(l) = lane {
                    warp.lanes[l] = Some(self.ray(0));
                }
                inp.issue = Some(warp);
            }
            7 => {
                let lanes = (0..self.ws).map(|_| self.rng.chance(50).then(|| self.ray(0)));
                let lanes: Vec<_> = lanes.collect();
                let unheld: Vec<u32> = (taken.iter().copied())
                    .filter(|&s| !self.regs.slots[s as usize].held)
                    .collect();
                let staged = self.staged.map(|st| st.slot);
                let unstaged: Vec<u32> = (free.iter().copied())
                    .filter(|&s| Some(s) != staged)
                    .collect();
                if self.rng.chance(50) {
                    // A write into a warp's lanes.
                    let slot = self.pick(&unheld)?;
                    inp.write = Some(LaneWrite { slot, lanes });
                } else {
                    // An issue naming lanes never written.
                    let slot = self.pick(&unstaged)?;
                    let mut warp = self.throwaway(IssueTarget::Slot(slot));
                    warp.lanes = vec![None; self.ws];
                    warp.written = 1 << self.idx(self.ws);
                    inp.issue = Some(warp);
                }
            }
            3 => inp.stop = Some(self.bad_slot(&free)?),
            4 => inp.repack = Some(self.bad_slot(&free)?),
            _ => {
                // A malformed warp.
                let mut warp = self.throwaway(IssueTarget::AnyFree);
                let w = self.block.widths();
                let mut ray = self.ray(0);
                match self.rng.below(3) {
                    0 if (self.record + 1) >> w.record_pointer == 0 => {
                        ray.current_stack = self.stack(self.record + 1, false);
                    }
                    1 if (self.chunks + 1) >> w.spilled == 0 => ray.other_spilled = self.chunks + 1,
                    _ => {
                        let n = self.node(false);
                        let bad = NodeEntry {
                            address: n.address + 8,
                            ..n
                        };
                        ray.other_stack = BoundedVec::with(self.depth, [bad]).ok()?;
                    }
                }
                let l = self.idx(self.ws);
                warp.lanes[l] = Some(ray);
                inp.issue = Some(warp);
            }
        }
        Some(())
    }

    /// The SM's and the treelet controller's commands in a cycle without a fault.
    pub(super) fn commands(&mut self, inp: &mut RtUnitInputs) {
        let free = self.slots(false);
        let finale = self.finale.is_some_and(|c| self.cycle >= c);
        if finale && self.staged.is_none() && !free.is_empty() && !self.free_ids.is_empty() {
            // A current stack full on chip and in memory: the next fetch must spill, and can't.
            self.finale = None;
            let mut lanes = vec![None; self.ws];
            let id = self.free_ids.pop().unwrap_or(0);
            let mut ray = self.ray(id);
            // (Full on chip only where a record carries a whole stack.)
            ray.current_stack = self.stack(self.record, true);
            ray.current_spilled = self.chunks;
            self.store_spills(&ray);
            lanes[0] = Some(ray);
            let (order, target) = (TraversalOrder::RayStationary, IssueTarget::AnyFree);
            inp.issue = Some(WarpIssue {
                order,
                lanes,
                target,
                written: 0,
            });
        } else if let Some((slot, left)) = self.held.filter(|_| self.rng.chance(35)) {
            let s = &self.regs.slots[slot as usize];
            let order = s.order;
            let inactive: Vec<usize> = (0..self.ws).filter(|&l| s.lanes[l].empty()).collect();
            let empty = inactive.is_empty() || self.rng.chance(10);
            let k = if empty {
                0
            } else {
                1 + self.idx(inactive.len())
            };
            let lanes = self.subset(inactive, k);
            let lanes = self.fill(order, lanes);
            if !empty && self.rng.chance(40) {
                // Written ahead of the next append.
                self.held_written |= occupied(&lanes);
                inp.write = Some(LaneWrite { slot, lanes });
            } else {
                let last = empty || left <= 1;
                self.held = (!last).then_some((slot, left - 1));
                let written = std::mem::take(&mut self.held_written);
                let target = IssueTarget::Append { slot, last };
                inp.issue = Some(WarpIssue {
                    order,
                    lanes,
                    target,
                    written,
                });
            }
        } else if let Some(st) = self.staged.filter(|_| self.rng.chance(40)) {
            self.staged_step(st, inp);
        } else if !free.is_empty() && self.rng.chance(85) {
            let order = TraversalOrder::ALL[self.idx(3)];
            let staged = self.staged.map(|st| st.slot);
            let unstaged: Vec<u32> = free
                .iter()
                .copied()
                .filter(|&s| Some(s) != staged)
                .collect();
            // The lowest free slot, where AnyFree goes, must not be the one being written.
            let target = match self.pick(&unstaged) {
                Some(s) if self.rng.chance(20) || staged == free.first().copied() => {
                    Some(IssueTarget::Slot(s))
                }
                Some(_) => Some(IssueTarget::AnyFree),
                None => None,
            };
            if let Some(target) = target {
                if self.staged.is_none() && unstaged.len() > 1 && self.rng.chance(15) {
                    // Reserve a free slot (not where this warp goes) and start writing it.
                    let slot = match target {
                        IssueTarget::Slot(s) => unstaged.iter().copied().find(|&x| x != s),
                        _ => unstaged.iter().copied().rfind(|&x| x != free[0]),
                    };
                    if let Some(slot) = slot {
                        let order = TraversalOrder::ALL[self.idx(3)];
                        let left = 1 + self.rng.below(3) as u32;
                        let (written, left) = (0, left);
                        self.staged = Some(Staged {
                            slot,
                            order,
                            written,
                            left,
                        });
                    }
                }
                let k = 1 + self.idx(self.ws);
                let lanes = self.subset((0..self.ws).collect(), k);
                let lanes = self.fill(order, lanes);
                inp.issue = Some(WarpIssue {
                    order,
                    lanes,
                    target,
                    written: 0,
                });
                if let Some(st) = self.staged.filter(|st| st.left > 0 && self.rng.chance(50)) {
                    // A write beside the issue, on the bus lanes it leaves free.
                    let used = inp.issue.as_ref().map_or(0, |i| occupied(&i.lanes));
                    self.stage_write(st, !used, inp);
                }
            }
        }
        if self.rng.chance(3) {
            // Never a ray-stationary warp, nor one that completes (freeing its slot) first.
            let slots = &self.regs.slots;
            let completing = (self.regs.age.iter().copied()).find(|&s| {
                !slots[s as usize].held
                    && slots[s as usize]
                        .lanes
                        .iter()
                        .all(|l| l.quiescent(self.record))
            });
            let stoppable: Vec<u32> = (self.slots(true).into_iter())
                .filter(|&s| slots[s as usize].order != TraversalOrder::RayStationary)
                .filter(|&s| Some(s) != completing)
                .collect();
            inp.stop = self.pick(&stoppable);
        }
        if self.held.is_none() && self.rng.below(200) == 0 {
            inp.repack = self.pick(&self.slots(true));
        }
    }

    /// One step of the staged slot `st`: a write of some lanes not written yet, or, when the
    /// writes are sent, the warp's issue naming the written lanes (with rays on the bus in some
    /// others: the last records written and issued in one cycle).
    pub(super) fn staged_step(&mut self, st: Staged, inp: &mut RtUnitInputs) {
        if st.left > 0 {
            self.stage_write(st, u64::MAX, inp);
            return;
        }
        self.staged = None;
        let rest: Vec<usize> = (0..self.ws).filter(|&l| st.written >> l & 1 == 0).collect();
        let k = self.idx(rest.len() + 1);
        let lanes = self.subset(rest, k);
        let lanes = self.fill(st.order, lanes);
        inp.issue = Some(WarpIssue {
            order: st.order,
            lanes,
            target: IssueTarget::Slot(st.slot),
            written: st.written,
        });
    }

    /// A write of some of the staged slot's unwritten lanes among `free` (bus lanes), with new
    /// rays; counts one of its writes down.
    pub(super) fn stage_write(&mut self, st: Staged, free: u64, inp: &mut RtUnitInputs) {
        let open: Vec<usize> = (0..self.ws)
            .filter(|&l| (free & !st.written) >> l & 1 == 1)
            .collect();
        let k = if open.is_empty() {
            0
        } else {
            1 + self.idx(open.len())
        };
        let lanes = self.subset(open, k);
        let lanes = self.fill(st.order, lanes);
        let mask = occupied(&lanes);
        self.staged = Some(Staged {
            written: st.written | mask,
            left: st.left - 1,
            ..st
        });
        if mask != 0 {
            inp.write = Some(LaneWrite {
                slot: st.slot,
                lanes,
            });
        }
    }
}
