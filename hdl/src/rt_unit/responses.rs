//! Responses (stage 5 of a cycle): a popped response delivered to the lanes waiting for it —
//! node chunks, stack fills — and the intersection test run when a lane's node is complete.

use super::{
    bits, raise, record, unpack_spill_chunk, BoundaryEvent, BoundedVec, ErrorKind, ErrorRecord,
    Lane, LaneMasks, LaneStatus, MemResponse, NodeDatapath, NodeEntry, NodeKind, RtCache, RtStats,
    RtUnit, RtUnitRegs, StackSel, TraversalOrder, WarpSlot, CHUNK_BYTES, CHUNK_MASK,
};

impl<D: NodeDatapath> RtUnit<D> {
    /// Delivers a popped response to the lanes waiting for it and runs completed tests.
    pub(super) fn deliver(
        &self,
        r: &mut RtUnitRegs,
        c: &mut RtCache,
        resp: &MemResponse,
        boundary: &mut Vec<BoundaryEvent>,
        counts: &mut RtStats,
    ) {
        let s = resp.tag >> self.widths.lane;
        let leader = resp.tag & ((1 << self.widths.lane) - 1);
        let unmatched = ErrorRecord {
            slot: s,
            lane: leader,
            ..record(ErrorKind::UnmatchedResponse, resp.address, 0)
        };
        let Some(slot) = r.slots.get_mut(s as usize).filter(|slot| slot.valid) else {
            raise(&mut r.errors, &mut r.first_error, unmatched);
            return;
        };
        let m = &mut c.masks[s as usize];
        if self.in_spill_area(resp.address) {
            if !self.fill(slot, m, s, leader as usize, resp, boundary) {
                raise(&mut r.errors, &mut r.first_error, unmatched);
            }
            return;
        }
        let order = slot.order;
        let mut matched = false;
        // Only lanes whose cached leader matches can match (the full check follows).
        let group = bits(m.in_flight)
            .filter(|&l| m.leader[l] == leader as u8)
            .fold(0u64, |m, l| m | 1 << l);
        for l in bits(group) {
            let lane = &mut slot.lanes[l];
            let Some(f) = lane.in_flight.as_mut() else {
                continue;
            };
            let offset = resp.address.wrapping_sub(f.node.address);
            let chunk = offset / CHUNK_BYTES as u64;
            if f.leader != leader
                || resp.address < f.node.address
                || offset & CHUNK_MASK != 0
                || chunk >= f.node.chunks as u64
                || f.returned & (1 << chunk) != 0
            {
                continue;
            }
            matched = true;
            f.returned |= 1 << chunk;
            lane.chunks[chunk as usize] = resp.data;
            if f.returned == (1u8 << f.node.chunks) - 1 {
                let node = f.node;
                lane.in_flight = None;
                let event = self.test(
                    lane,
                    (s, l as u32),
                    &node,
                    order,
                    counts,
                    (&mut r.errors, &mut r.first_error),
                );
                m.set(l, lane);
                if let Some(treelet) = event {
                    boundary.push(BoundaryEvent {
                        slot: s,
                        lane: l as u32,
                        ray_id: lane.ray.ray_id,
                        treelet,
                    });
                }
            }
        }
        if !matched {
            raise(&mut r.errors, &mut r.first_error, unmatched);
        }
    }

    /// Delivers a stack-fill response to lane `l` of slot `s`: the chunk's entries become the
    /// lane's on-chip stack. A ray whose current stack is empty and whose other stack's top
    /// came back reaches its treelet boundary now. Returns whether the response matched.
    pub(super) fn fill(
        &self,
        slot: &mut WarpSlot,
        m: &mut LaneMasks,
        s: u32,
        l: usize,
        resp: &MemResponse,
        boundary: &mut Vec<BoundaryEvent>,
    ) -> bool {
        let order = slot.order;
        let Some(lane) = slot.lanes.get_mut(l) else {
            return false;
        };
        let Some(stack) = lane.filling else {
            return false;
        };
        let spilled = lane.ray.spilled(stack);
        let entries = unpack_spill_chunk(&resp.data);
        if spilled == 0
            || resp.address != self.spill_address(lane.ray.ray_id, stack, spilled - 1)
            || !lane.ray.stack(stack).is_empty()
            || entries.is_empty()
        {
            return false;
        }
        let Ok(entries) = BoundedVec::with(self.cfg.stack_depth as usize, entries) else {
            return false;
        };
        *lane.ray.stack_mut(stack) = entries;
        *lane.ray.spilled_mut(stack) -= 1;
        lane.filling = None;
        if stack == StackSel::Other && order.two_stack() && lane.ray.current_empty() {
            if let Some(top) = lane.ray.other_stack.last() {
                if order == TraversalOrder::TreeletStop {
                    lane.status = LaneStatus::Parked;
                }
                boundary.push(BoundaryEvent {
                    slot: s,
                    lane: l as u32,
                    ray_id: lane.ray.ray_id,
                    treelet: self.treelet_of(top.address),
                });
            }
        }
        m.set(l, lane);
        true
    }

    /// Runs the datapath on a complete node and writes the result back; returns the treelet
    /// needed next when the ray reached a treelet boundary.
    pub(super) fn test(
        &self,
        lane: &mut Lane,
        (s, l): (u32, u32),
        node: &NodeEntry,
        order: TraversalOrder,
        stats: &mut RtStats,
        (flags, first): (&mut u8, &mut Option<ErrorRecord>),
    ) -> Option<u64> {
        let data = &lane.chunks.as_flattened()[..node.bytes() as usize];
        let result = self
            .datapath
            .test(&lane.ray.words, lane.ray.hit.as_ref(), node, data);
        stats.tests[node.kind.code() as usize] += 1;
        stats.treelet_order_tests += u64::from(order == TraversalOrder::TreeletStop);
        let best = lane.ray.hit;
        let accepted = result
            .hit
            .filter(|h| best.is_none_or(|b| h.closer_than(&b)));
        if let Some(hit) = accepted {
            lane.ray.hit = Some(hit);
            lane.store_pending = true;
            if node.kind == NodeKind::TriangleLeaf {
                stats.triangle_hits += 1;
            }
        }
        lane.delay = self.params.latencies.of(node.kind, accepted.is_some());
        let ray = &mut lane.ray;
        let ray_id = ray.ray_id;
        let bad_child = |value: u64, limit: u64| ErrorRecord {
            slot: s,
            lane: l,
            ray_id,
            ..record(ErrorKind::BadChild, value, limit)
        };
        let children = result.children.len();
        if children > self.params.max_children as usize {
            let failure = bad_child(children as u64, self.params.max_children as u64);
            raise(flags, first, failure);
        }
        // The fetch kept `max_children` entries free on every stack that may receive them.
        for child in result.children[..children.min(self.params.max_children as usize)]
            .iter()
            .rev()
        {
            if self.check_node(child).is_err() {
                let failure = bad_child(child.address, 1 << self.cfg.address_bits);
                raise(flags, first, failure);
                continue;
            }
            let current =
                !order.two_stack() || self.treelet_of(child.address) == ray.current_treelet;
            let stack = if current {
                &mut ray.current_stack
            } else {
                &mut ray.other_stack
            };
            let pushed = stack.push(*child);
            debug_assert!(pushed.is_ok(), "stack room");
        }
        if ray.occlusion && accepted.is_some() {
            // An occlusion ray's first accepted hit ends its traversal: both stacks are
            // dropped, their spilled chunks abandoned in the spill area.
            ray.current_stack.clear();
            ray.other_stack.clear();
            ray.current_spilled = 0;
            ray.other_spilled = 0;
        }
        if ray.finished() {
            lane.status = LaneStatus::Done;
            return None;
        }
        // A boundary whose next treelet waits in memory is reported when the fill returns.
        if !order.two_stack() || !ray.current_empty() || ray.other_stack.is_empty() {
            return None;
        }
        if order == TraversalOrder::TreeletStop {
            lane.status = LaneStatus::Parked;
        }
        ray.other_stack.last().map(|n| self.treelet_of(n.address))
    }
}
