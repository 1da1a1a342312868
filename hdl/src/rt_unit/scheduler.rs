//! The memory scheduler (stage 3 of a cycle): this cycle's one 32 B request — the next chunk of
//! the node being requested, a hit-record store, or a ready lane's stack spill, stack fill or
//! next node (merged across the warp's lanes) — and the addresses it computes.

use super::{
    bits, pack_spill_chunk, raise, record, ErrorKind, ErrorRecord, InFlight, Lane, LaneAction,
    MemRequest, NodeDatapath, NodeEntry, RayRecord, RequestKind, RtCache, RtStats, RtUnit,
    RtUnitRegs, Split, StackSel, TraversalOrder, CHUNK_BYTES, STACK_ENTRIES_PER_CHUNK,
};

impl<D: NodeDatapath> RtUnit<D> {
    /// Picks this cycle's memory request and updates the lanes it serves.
    pub(super) fn schedule(
        &self,
        r: &mut RtUnitRegs,
        c: &mut RtCache,
        counts: &mut RtStats,
    ) -> Option<MemRequest> {
        let lane_bits = self.widths.lane;
        if let Some(split) = r.split.take() {
            let chunk = split.next_chunk;
            if chunk + 1 < split.node.chunks {
                r.split = Some(Split {
                    next_chunk: chunk + 1,
                    ..split
                });
            }
            counts.load_requests += 1;
            return Some(load_request(&split.node, chunk, split.tag));
        }
        for &s in &r.age {
            let slot = &mut r.slots[s as usize];
            let m = &mut c.masks[s as usize];
            if m.store != 0 {
                let l = m.store.trailing_zeros() as usize;
                let lane = &mut slot.lanes[l];
                lane.store_pending = false;
                m.set(l, lane);
                counts.stores += 1;
                return Some(self.store_request(&lane.ray, s << lane_bits | l as u32));
            }
        }
        for &s in &r.age {
            let slot = &mut r.slots[s as usize];
            let m = &mut c.masks[s as usize];
            // Serving a lane changes only that lane, so the ready set of the scan is the one at
            // its start.
            let ready = m.ready();
            if ready == 0 {
                continue;
            }
            let leader = ready.trailing_zeros() as usize;
            let order = slot.order;
            let tag = s << lane_bits | leader as u32;
            let node = match self.action(&slot.lanes[leader], order) {
                None => continue,
                Some(LaneAction::Fetch(node)) => node,
                Some(LaneAction::Spill(stack, k)) => {
                    let lane = &mut slot.lanes[leader];
                    let spilled = lane.ray.spilled(stack);
                    if spilled >= self.params.stack_spill_chunks {
                        let failure = ErrorRecord {
                            slot: s,
                            lane: leader as u32,
                            ray_id: lane.ray.ray_id,
                            ..record(
                                ErrorKind::SpillAreaFull,
                                spilled as u64 + 1,
                                self.params.stack_spill_chunks as u64,
                            )
                        };
                        raise(&mut r.errors, &mut r.first_error, failure);
                        return None;
                    }
                    let entries = lane.ray.stack_mut(stack).take_front(k);
                    *lane.ray.spilled_mut(stack) += 1;
                    m.set(leader, lane);
                    counts.stack_spills += 1;
                    return Some(MemRequest {
                        address: self.spill_address(lane.ray.ray_id, stack, spilled),
                        kind: RequestKind::StackSpill,
                        tag,
                        data: pack_spill_chunk(&entries),
                    });
                }
                Some(LaneAction::Fill(stack)) => {
                    let lane = &mut slot.lanes[leader];
                    lane.filling = Some(stack);
                    m.set(leader, lane);
                    counts.stack_fills += 1;
                    let index = lane.ray.spilled(stack) - 1;
                    return Some(MemRequest {
                        address: self.spill_address(lane.ray.ray_id, stack, index),
                        kind: RequestKind::StackFill,
                        tag,
                        data: [0; CHUNK_BYTES as usize],
                    });
                }
            };
            let mut served = 0;
            for l in bits(ready) {
                let lane = &mut slot.lanes[l];
                if self.action(lane, order) == Some(LaneAction::Fetch(node)) {
                    self.pop_next(&mut lane.ray);
                    lane.in_flight = Some(InFlight {
                        node,
                        leader: leader as u32,
                        returned: 0,
                    });
                    m.set(l, lane);
                    served += 1;
                }
            }
            counts.merged += served - 1;
            if node.chunks > 1 {
                r.split = Some(Split {
                    tag,
                    node,
                    next_chunk: 1,
                });
            }
            counts.load_requests += 1;
            return Some(load_request(&node, 0, tag));
        }
        None
    }

    /// The request a ready lane makes next in a warp of traversal order `order` (`None` when
    /// its ray is finished): a parked lane spills the oldest of its other stack's entries down
    /// to what a record carries ([`RtUnit::keep`]); a traversing one fills, spills or fetches.
    pub(super) fn action(&self, lane: &Lane, order: TraversalOrder) -> Option<LaneAction> {
        let ray = &lane.ray;
        if lane.park_spilling(self.keep()) {
            let after = ray.other_stack.len() - self.keep();
            return Some(LaneAction::Spill(
                StackSel::Other,
                after.min(STACK_ENTRIES_PER_CHUNK),
            ));
        }
        let depth = self.cfg.stack_depth as usize;
        let room = self.params.max_children as usize;
        let (pop, node) = if let Some(&n) = ray.current_stack.last() {
            (StackSel::Current, n)
        } else if ray.current_spilled > 0 {
            return Some(LaneAction::Fill(StackSel::Current));
        } else if let Some(&n) = ray.other_stack.last() {
            (StackSel::Other, n)
        } else if ray.other_spilled > 0 {
            return Some(LaneAction::Fill(StackSel::Other));
        } else {
            return None;
        };
        // After the pop, every stack that may receive children needs `room` free entries.
        let receivers: &[StackSel] = if order.two_stack() {
            &[StackSel::Current, StackSel::Other]
        } else {
            &[StackSel::Current]
        };
        for &stack in receivers {
            let keep = usize::from(stack == pop);
            let after = ray.stack(stack).len() - keep;
            if after + room > depth {
                let k = after.min(STACK_ENTRIES_PER_CHUNK);
                return Some(LaneAction::Spill(stack, k));
            }
        }
        Some(LaneAction::Fetch(node))
    }

    /// Byte address of chunk `index` of stack `stack`'s spill area of ray `ray_id`.
    pub(super) fn spill_address(&self, ray_id: u32, stack: StackSel, index: u32) -> u64 {
        let area = ray_id as u64 * 2 + stack.code();
        self.spill.0
            + (area * self.params.stack_spill_chunks as u64 + index as u64) * CHUNK_BYTES as u64
    }

    /// Whether `address` lies in the stack spill area.
    pub(super) fn in_spill_area(&self, address: u64) -> bool {
        (self.spill.0..self.spill.1).contains(&address)
    }

    /// The 32 B hit-record store of a ray: t, hit id, two attribute words, ray id, zeros.
    pub(super) fn store_request(&self, ray: &RayRecord, tag: u32) -> MemRequest {
        let hit = ray.hit.unwrap_or_default();
        let words = [
            hit.t,
            hit.hit_id,
            hit.attribs[0],
            hit.attribs[1],
            ray.ray_id,
            0,
            0,
            0,
        ];
        let mut data = [0u8; CHUNK_BYTES as usize];
        for (bytes, w) in data.chunks_exact_mut(4).zip(words) {
            bytes.copy_from_slice(&w.to_le_bytes());
        }
        MemRequest {
            address: self.params.hit_record_base + ray.ray_id as u64 * CHUNK_BYTES as u64,
            kind: RequestKind::HitStore,
            tag,
            data,
        }
    }

    /// Pops the ray's next node, switching treelets when the current stack is empty.
    pub(super) fn pop_next(&self, ray: &mut RayRecord) {
        if ray.current_stack.pop().is_none() {
            if let Some(node) = ray.other_stack.pop() {
                ray.current_treelet = self.treelet_of(node.address);
            }
        }
    }
}

/// The load request for chunk `chunk` of `node`.
pub(super) fn load_request(node: &NodeEntry, chunk: u8, tag: u32) -> MemRequest {
    MemRequest {
        address: node.address + chunk as u64 * CHUNK_BYTES as u64,
        kind: RequestKind::NodeLoad,
        tag,
        data: [0; CHUNK_BYTES as usize],
    }
}
