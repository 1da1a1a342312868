//! The queue table's operations as its FSM runs them: starting an Insert, a lookup or a walk,
//! allocating an entry, walking a bucket's chain one entry per cycle, and finishing an op — on
//! one cycle's memory guards and pending updates ([`Cycle`]).

use super::{HeadWord, MetaWord, QueueCtl, QueueState, QueueTable, QueueTableOut, WalkOp};
use crate::memory::MemCycle;

/// One cycle's memory guards and pending updates.
pub(super) struct Cycle<'a> {
    /// The bucket heads' memory this cycle.
    pub(super) heads: MemCycle<'a, HeadWord>,
    /// The entries' metadata memory this cycle.
    pub(super) meta: MemCycle<'a, MetaWord>,
    /// The entries' ray memory this cycle.
    pub(super) rays: MemCycle<'a, Box<[u32]>>,
    /// Priority encoder: lowest free entry.
    pub(super) first_free: Option<usize>,
    /// Priority encoder: lowest valid entry.
    pub(super) first_valid: Option<usize>,
    /// The scalar registers' next values.
    pub(super) nx: QueueCtl,
    /// This cycle's outputs.
    pub(super) out: QueueTableOut,
    /// An entry to mark valid at the edge.
    pub(super) set_valid: Option<usize>,
    /// An entry to mark free at the edge.
    pub(super) clear_valid: Option<usize>,
}

impl QueueTable {
    /// Starts an Insert (or a refilled ray's insertion): read the bucket head, then allocate at
    /// once (empty bucket) or walk.
    pub(super) fn start_insert(&self, cx: &mut Cycle, treelet: u64, ray: u32) {
        let h = self.bucket(treelet);
        let hw = cx.heads.read(h);
        cx.nx.key_treelet = treelet;
        cx.nx.key_ray = ray;
        cx.nx.head = hw;
        if hw.valid {
            self.begin_walk(cx, WalkOp::Insert, hw.idx);
        } else {
            self.allocate(cx, treelet, ray, hw);
        }
    }

    /// Starts a walk at entry `first` (its `meta` word arrives next cycle).
    pub(super) fn begin_walk(&self, cx: &mut Cycle, op: WalkOp, first: u32) {
        cx.meta.issue_read(0, first as usize);
        cx.nx.state = QueueState::Walk;
        cx.nx.walk_op = op;
        cx.nx.cur = first;
        cx.nx.prev_valid = false;
        cx.nx.walked = 0;
        cx.nx.acc = 0;
    }

    /// Links a new entry holding `ray` at the head of the treelet's chain, or spills the ray
    /// when no entry is free. Finishes the op.
    pub(super) fn allocate(&self, cx: &mut Cycle, treelet: u64, ray: u32, head: HeadWord) {
        match cx.first_free {
            Some(f) => {
                cx.meta.write(
                    f,
                    MetaWord {
                        treelet,
                        count_m1: 0,
                        next_valid: head.valid,
                        next: head.idx,
                    },
                );
                cx.rays.write_lane(f, 0, ray);
                cx.heads.write(
                    self.bucket(treelet),
                    HeadWord {
                        valid: true,
                        idx: f as u32,
                    },
                );
                cx.set_valid = Some(f);
                cx.nx.free_count -= 1;
            }
            None => {
                cx.out.spill_valid = true;
                cx.out.spill_treelet = treelet;
                cx.out.spill_ray = ray;
                cx.nx.spilled += 1;
            }
        }
        self.finish(cx);
    }

    pub(super) fn finish(&self, cx: &mut Cycle) {
        cx.out.done = true;
        cx.nx.state = QueueState::Idle;
    }

    /// Moves the walk to the next entry of the chain.
    pub(super) fn advance(&self, cx: &mut Cycle, c: &QueueCtl, m: &MetaWord) {
        cx.meta.issue_read(0, m.next as usize);
        cx.nx.prev_valid = true;
        cx.nx.prev = c.cur;
        cx.nx.prev_treelet = m.treelet;
        cx.nx.prev_count_m1 = m.count_m1;
        cx.nx.cur = m.next;
    }

    /// One walk step: the `meta` word of `c.cur` is on the read port.
    pub(super) fn walk(&self, cx: &mut Cycle, c: &QueueCtl) {
        let m = *cx.meta.rdata(0);
        let walked = c.walked + 1;
        cx.nx.walked = walked;
        cx.out.walk_len = walked;
        let matched = match c.walk_op {
            WalkOp::PopAny => c.cur == c.target,
            _ => m.treelet == c.key_treelet,
        };
        match c.walk_op {
            WalkOp::Insert => {
                if matched && m.count_m1 + 1 < self.cfg.warp_size {
                    let cur = c.cur as usize;
                    cx.rays
                        .write_lane(cur, (m.count_m1 + 1) as usize, c.key_ray);
                    cx.meta.write(
                        cur,
                        MetaWord {
                            count_m1: m.count_m1 + 1,
                            ..m
                        },
                    );
                    self.finish(cx);
                } else if matched || !m.next_valid {
                    self.allocate(cx, c.key_treelet, c.key_ray, c.head);
                } else {
                    self.advance(cx, c, &m);
                }
            }
            WalkOp::Pop | WalkOp::PopAny => {
                if matched {
                    let next = HeadWord {
                        valid: m.next_valid,
                        idx: m.next,
                    };
                    if c.prev_valid {
                        cx.meta.write(
                            c.prev as usize,
                            MetaWord {
                                treelet: c.prev_treelet,
                                count_m1: c.prev_count_m1,
                                next_valid: next.valid,
                                next: next.idx,
                            },
                        );
                    } else {
                        cx.heads.write(self.bucket(c.key_treelet), next);
                    }
                    cx.clear_valid = Some(c.cur as usize);
                    cx.nx.free_count += 1;
                    cx.rays.issue_read(0, c.cur as usize);
                    cx.nx.pop_count_m1 = m.count_m1;
                    cx.nx.pop_treelet = m.treelet;
                    cx.nx.state = QueueState::PopRays;
                } else if m.next_valid {
                    self.advance(cx, c, &m);
                } else {
                    cx.out.error = c.walk_op == WalkOp::PopAny;
                    self.finish(cx);
                }
            }
            WalkOp::Count => {
                let acc = c.acc + if matched { m.count_m1 + 1 } else { 0 };
                if m.next_valid {
                    cx.nx.acc = acc;
                    self.advance(cx, c, &m);
                } else {
                    cx.out.count_result = acc;
                    self.finish(cx);
                }
            }
        }
    }

    /// Starts a Pop or Count of `treelet` in `IDLE`.
    pub(super) fn start_lookup(&self, cx: &mut Cycle, op: WalkOp, treelet: u64) {
        let hw = cx.heads.read(self.bucket(treelet));
        cx.nx.key_treelet = treelet;
        if hw.valid {
            self.begin_walk(cx, op, hw.idx);
        } else {
            self.finish(cx);
        }
    }
}
