//! The treelet controller's next-state logic beyond the per-cycle bookkeeping of `eval`: the
//! sequencer's actions (refill, treelet-warp dispatch, claims and preloads, grouped warps and
//! repacks, enqueues), the handling of a popped entry and the fill sequence.

use super::{
    ControllerInputs, ControllerOutputs, ControllerRegs, FillCommand, FillKind, FillState,
    ResidentEntry, Seq, SlotState, TreeletController,
};
use crate::count_table::{CountOp, QueueCount};
use crate::mode::{queue_underpopulated, Mode};
use crate::queue_table::{PopResult, QueueOp};
use crate::warp_repacking::{lanes_to_refill, should_repack, split_refill};

impl TreeletController {
    /// Whether the oldest resident treelet's queue has fallen under the preload threshold
    /// (section 4.3: fewer than `preload_threshold_warps` warps of rays left).
    fn current_queue_low(&self, regs: &ControllerRegs) -> bool {
        let limit = self.cfg.preload_threshold_warps as u64 * self.cfg.warp_size as u64;
        regs.resident_order()
            .next()
            .is_none_or(|i| (regs.res[i].count as u64) < limit)
    }

    /// The count table's largest queue, if it may be claimed (made resident) this cycle: the
    /// table is not being updated by a pending remove, the treelet is not resident yet, it is not underpopulated (unless the design is naive), a resident entry
    /// is free, and either nothing is resident or preloading is on and the current queue is low.
    fn claimable(&self, regs: &ControllerRegs, inputs: &ControllerInputs) -> Option<QueueCount> {
        let max = inputs.ct.max?;
        let tail = regs.res_tail as usize;
        let ok = regs.mode == Mode::TreeletStationary
            && regs.pending_remove.is_none()
            && !regs.res[tail].valid
            && regs.resident_of(max.treelet).is_none()
            && (!self.features.group_underpopulated
                || !queue_underpopulated(max.count, self.cfg.underpopulation_threshold))
            && (regs.resident_count() == 0
                || (self.features.preload && self.current_queue_low(regs)));
        ok.then_some(max)
    }

    /// The sequencer's actions in `Seq::Idle`, in priority order; at most one per cycle.
    pub(super) fn idle_step(
        &self,
        regs: &ControllerRegs,
        inputs: &ControllerInputs,
        ct_port_free: bool,
        n: &mut ControllerRegs,
        out: &mut ControllerOutputs,
    ) {
        let free_slot = inputs.wb_free_slot.filter(|&s| s < self.widths.warp_slots);
        let ts = regs.mode == Mode::TreeletStationary;
        let frs = regs.mode == Mode::FinalRayStationary;
        let rays_waiting = self.rays_waiting(regs);

        // 1. Bring a spilled ray back while the table has room, so pops find every ray.
        if inputs.qt.ready && inputs.qt.spilled > 0 && inputs.qt.free_entries > 0 {
            out.qt_op = QueueOp::Refill;
            n.seq = Seq::RefillWait;
            return;
        }

        // 2. Dispatch a treelet warp: the oldest resident with queued rays, or (naive design)
        //    any entry once the count table tracks nothing.
        if ts && inputs.qt.ready {
            if let Some(slot) = free_slot {
                let resident = regs.resident_order().find(|&i| regs.res[i].count > 0);
                let naive_untracked = !self.features.group_underpopulated
                    && regs.resident_count() == 0
                    && inputs.ct.occupancy == 0
                    && regs.queued_rays > 0;
                if resident.is_some() || naive_untracked {
                    out.qt_op = match resident {
                        Some(i) => QueueOp::Pop {
                            treelet: regs.res[i].treelet as u64,
                        },
                        None => QueueOp::PopAny,
                    };
                    out.reserve = Some(slot);
                    n.seq = Seq::PopWait;
                    n.fill = FillState {
                        kind: FillKind::Treelet,
                        slot,
                        resident: resident.map(|i| i as u32),
                        need: self.cfg.warp_size,
                        started: false,
                    };
                    return;
                }
            }
        }

        // 3. Claim the largest queue: it becomes current, or is preloaded behind the current one.
        if let Some(max) = self.claimable(regs, inputs) {
            let first = regs.resident_count() == 0;
            let tail = regs.res_tail as usize;
            n.res[tail] = ResidentEntry {
                valid: true,
                treelet: max.treelet,
                count: max.count,
                warps: 0,
            };
            n.res_tail = ((tail + 1) % n.res.len()) as u32;
            out.claim = true;
            if !first {
                out.preload = Some(max.treelet);
            }
            return;
        }

        // 4. Final phase: group underpopulated queues into a free slot, or repack a warp.
        if frs && rays_waiting {
            if let Some(slot) = free_slot {
                out.reserve = Some(slot);
                n.seq = Seq::FillNext;
                n.fill = FillState {
                    kind: FillKind::Grouped,
                    slot,
                    resident: None,
                    need: self.cfg.warp_size,
                    started: false,
                };
                return;
            }
            if let Some(r) = inputs.active_report {
                if r.slot < self.widths.warp_slots
                    && should_repack(regs.mode, r.active, self.cfg.repack_threshold, rays_waiting)
                {
                    out.repack = Some(r.slot);
                    out.reserve = Some(r.slot);
                    n.seq = Seq::FillNext;
                    n.fill = FillState {
                        kind: FillKind::Repack,
                        slot: r.slot,
                        resident: None,
                        need: lanes_to_refill(r.active, self.cfg.warp_size),
                        started: true,
                    };
                    return;
                }
            }
        }

        // 5. Enqueue a ray at a treelet boundary: insert it and count it (a resident treelet's
        //    count is mirrored here).
        if let Some(e) = inputs.enqueue {
            if regs.mode != Mode::Done && inputs.qt.ready && ct_port_free {
                out.enq_ready = true;
                out.qt_op = QueueOp::Insert {
                    treelet: e.treelet as u64,
                    ray: e.ray,
                };
                out.ct_op = CountOp::Add {
                    treelet: e.treelet as u64,
                    n: 1,
                };
                if let Some(i) = regs.resident_of(e.treelet) {
                    n.res[i].count = (n.res[i].count + 1).min(self.cfg.max_rays);
                }
                n.queued_rays = (n.queued_rays + 1).min(self.cfg.max_rays);
            }
        }
    }

    /// `Seq::PopWait`: the popped entry arrived; hand it to the slot being filled.
    pub(super) fn pop_done(
        &self,
        regs: &ControllerRegs,
        pop: &PopResult,
        n: &mut ControllerRegs,
        out: &mut ControllerOutputs,
    ) {
        let f = regs.fill;
        let popped = (pop.rays.len() as u32).min(self.cfg.warp_size);
        let rays = &pop.rays[..popped as usize];
        n.queued_rays = regs.queued_rays.saturating_sub(popped);
        out.reserve = Some(f.slot);
        if f.kind == FillKind::Treelet {
            n.seq = Seq::Idle;
            let treelet = match f.resident {
                Some(i) => {
                    // Keep the count table in step; an empty pop means the rest of the queue
                    // is spilled, so its whole count leaves the table (found again by PopAny).
                    let e = &mut n.res[i as usize];
                    let removed = if popped == 0 {
                        e.count
                    } else {
                        popped.min(e.count)
                    };
                    e.count -= removed;
                    if removed > 0 {
                        n.pending_remove = Some((e.treelet, removed));
                    }
                    e.treelet
                }
                None => pop.treelet,
            };
            if popped == 0 {
                return;
            }
            if let Some(i) = f.resident {
                n.res[i as usize].warps += 1;
            }
            n.slots[f.slot as usize] = SlotState {
                terminated: false,
                treelet_warp: true,
                resident: f.resident,
            };
            out.fill = Some(FillCommand {
                kind: FillKind::Treelet,
                slot: f.slot,
                treelet,
                first: true,
                last: true,
                rays: rays.to_vec(),
            });
            return;
        }

        // Grouped warp or repack: take what fits, keep the rest in the spare buffer.
        let (take, left) = split_refill(f.need, popped);
        n.spare_rays[..left as usize].copy_from_slice(&rays[take as usize..]);
        n.spare_rays[left as usize..].fill(0);
        n.spare_count = left;
        let need = f.need - take;
        let last = need == 0 || (left == 0 && n.queued_rays == 0);
        self.emit_fill(&f, &rays[..take as usize], last, n, out);
        n.fill.need = need;
        n.seq = if last { Seq::Idle } else { Seq::FillNext };
    }

    /// Gives `rays` to the slot of fill sequence `f` (for grouped warps and repacks).
    fn emit_fill(
        &self,
        f: &FillState,
        rays: &[u32],
        last: bool,
        n: &mut ControllerRegs,
        out: &mut ControllerOutputs,
    ) {
        if rays.is_empty() && !(f.started && last) {
            return; // nothing to give and nothing to close
        }
        if f.kind == FillKind::Grouped && !f.started {
            n.slots[f.slot as usize] = SlotState::default();
        }
        out.fill = Some(FillCommand {
            kind: f.kind,
            slot: f.slot,
            treelet: 0,
            first: f.kind == FillKind::Grouped && !f.started,
            last,
            rays: rays.to_vec(),
        });
        n.fill.started = true;
    }

    /// `Seq::FillNext`: give spare rays, pop another entry, or close the slot.
    pub(super) fn fill_next(
        &self,
        regs: &ControllerRegs,
        inputs: &ControllerInputs,
        n: &mut ControllerRegs,
        out: &mut ControllerOutputs,
    ) {
        let f = regs.fill;
        out.reserve = Some(f.slot);
        if regs.spare_count > 0 {
            let (take, left) = split_refill(f.need, regs.spare_count);
            let (given, kept) = regs.spare_rays.split_at(take as usize);
            n.spare_rays[..left as usize].copy_from_slice(&kept[..left as usize]);
            n.spare_rays[left as usize..].fill(0);
            n.spare_count = left;
            let need = f.need - take;
            let last = need == 0 || (left == 0 && regs.queued_rays == 0);
            self.emit_fill(&f, given, last, n, out);
            n.fill.need = need;
            if last {
                n.seq = Seq::Idle;
            }
        } else if regs.queued_rays == 0 {
            self.emit_fill(&f, &[], true, n, out);
            n.seq = Seq::Idle;
        } else if inputs.qt.ready && inputs.qt.spilled > 0 && inputs.qt.free_entries > 0 {
            // Spilled rays first, as in `Seq::Idle`: without this a table emptied by pops
            // answers every PopAny with nothing while its rays wait in memory. The sequence
            // stays here; the next op waits for `qt_ready` (the refill's answer is ignored).
            out.qt_op = QueueOp::Refill;
        } else if inputs.qt.ready {
            out.qt_op = QueueOp::PopAny;
            n.seq = Seq::PopWait;
        }
    }
}
