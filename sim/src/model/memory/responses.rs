//! [`ResponseQueue`]: one SM's undelivered responses, delivered in (completion cycle,
//! acceptance order).
//!
//! Most completion cycles grow with the acceptance cycle, which never decreases (see the
//! timing rules in [`super`]): an L1 hit completes at `t + L1`, an L2 hit or a store at
//! `t + L1 + L2`, and a DRAM read at `start + D` where the channel's start cycle never
//! decreases. Each of these three kinds therefore arrives already sorted and is kept in a FIFO;
//! only merges (with an L1 or L2 fill accepted earlier) and, with several DRAM channels, DRAM
//! reads that overtake an earlier one on another channel complete out of order and go to a
//! binary heap. Delivery takes the smallest (cycle, sequence) among the four heads, which is
//! exactly the order of one heap holding every response, at a fraction of the cost.

use std::cmp::{Ordering, Reverse};
use std::collections::{BinaryHeap, VecDeque};

use super::request::{Response, Source};

/// A response waiting for its cycle; ordered by (completion cycle, acceptance order).
#[derive(Debug, Clone, Copy)]
struct Queued {
    /// Completion cycle (equals `response.cycle`).
    cycle: u64,
    /// Acceptance order: breaks completion-cycle ties.
    seq: u64,
    response: Response,
}

impl Queued {
    fn key(&self) -> (u64, u64) {
        (self.cycle, self.seq)
    }
}

impl PartialEq for Queued {
    fn eq(&self, other: &Self) -> bool {
        self.key() == other.key()
    }
}

impl Eq for Queued {}

impl PartialOrd for Queued {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Queued {
    fn cmp(&self, other: &Self) -> Ordering {
        self.key().cmp(&other.key())
    }
}

/// The FIFO of responses served from `source`, or `None` for merges (which complete out of
/// order) and prefetch drops (which deliver nothing).
fn fifo_of(source: Source) -> Option<usize> {
    match source {
        Source::L1Hit => Some(0),
        Source::L2Hit | Source::L2Write => Some(1),
        Source::Dram => Some(2),
        Source::L1Merge | Source::L2Merge | Source::AlreadyInL1 => None,
    }
}

/// Index of the merge heap among the places a response can wait (after the FIFOs).
const MERGES: usize = 3;

/// One SM's undelivered responses.
#[derive(Debug, Clone)]
pub struct ResponseQueue {
    /// Responses of fixed-latency kinds, each FIFO sorted by (cycle, sequence).
    fifos: [VecDeque<Queued>; 3],
    /// Responses that merged with an earlier fill.
    merges: BinaryHeap<Reverse<Queued>>,
    /// Key of the next response to deliver (`(u64::MAX, u64::MAX)` when empty).
    head_key: (u64, u64),
    /// Where that response waits: a FIFO index or [`MERGES`].
    head_at: usize,
}

impl Default for ResponseQueue {
    fn default() -> Self {
        ResponseQueue::new()
    }
}

impl ResponseQueue {
    /// An empty queue.
    pub fn new() -> Self {
        ResponseQueue {
            fifos: Default::default(),
            merges: BinaryHeap::new(),
            head_key: (u64::MAX, u64::MAX),
            head_at: MERGES,
        }
    }

    /// Queues `response`, accepted as number `seq` and served from `source`.
    pub fn push(&mut self, seq: u64, source: Source, response: Response) {
        let q = Queued {
            cycle: response.cycle,
            seq,
            response,
        };
        // With several DRAM channels a later read may complete before an earlier one: it
        // waits with the merges (delivery order is the same wherever a response waits).
        let in_order = |k: usize, fifos: &[VecDeque<Queued>; 3]| {
            fifos[k].back().is_none_or(|b| b.key() < q.key())
        };
        let place = match fifo_of(source) {
            Some(2) if !in_order(2, &self.fifos) => None,
            other => other,
        };
        let at = match place {
            Some(k) => {
                let fifo = &mut self.fifos[k];
                debug_assert!(
                    fifo.back().is_none_or(|b| b.key() < q.key()),
                    "{source:?} responses must complete in acceptance order"
                );
                fifo.push_back(q);
                k
            }
            None => {
                self.merges.push(Reverse(q));
                MERGES
            }
        };
        if q.key() < self.head_key {
            self.head_key = q.key();
            self.head_at = at;
        }
    }

    /// Finds the next response to deliver among the heads of the FIFOs and the heap.
    fn find_head(&mut self) {
        self.head_key = (u64::MAX, u64::MAX);
        self.head_at = MERGES;
        for (k, fifo) in self.fifos.iter().enumerate() {
            if let Some(q) = fifo.front() {
                if q.key() < self.head_key {
                    self.head_key = q.key();
                    self.head_at = k;
                }
            }
        }
        if let Some(Reverse(q)) = self.merges.peek() {
            if q.key() < self.head_key {
                self.head_key = q.key();
                self.head_at = MERGES;
            }
        }
    }

    /// The next response to deliver, whatever its cycle.
    pub fn peek(&self) -> Option<Response> {
        match self.head_at {
            MERGES => self.merges.peek().map(|Reverse(q)| q.response),
            k => self.fifos[k].front().map(|q| q.response),
        }
    }

    /// Completion cycle of the next response to deliver.
    #[inline]
    pub fn earliest(&self) -> Option<u64> {
        (!self.is_empty()).then_some(self.head_key.0)
    }

    /// Removes and returns the next response if it completes at or before `now`.
    #[inline]
    pub fn pop_due(&mut self, now: u64) -> Option<Response> {
        if self.head_key.0 > now || self.is_empty() {
            return None;
        }
        let q = match self.head_at {
            MERGES => self.merges.pop().map(|Reverse(q)| q),
            k => self.fifos[k].pop_front(),
        };
        self.find_head();
        q.map(|q| q.response)
    }

    /// Number of queued responses.
    pub fn len(&self) -> usize {
        self.fifos.iter().map(VecDeque::len).sum::<usize>() + self.merges.len()
    }

    /// Whether no response is queued.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.head_key == (u64::MAX, u64::MAX)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::memory::AccessClass;

    fn response(tag: u64, cycle: u64) -> Response {
        Response {
            tag,
            addr: 0,
            class: AccessClass::Bvh,
            store: false,
            cycle,
        }
    }

    #[test]
    fn delivers_in_cycle_then_acceptance_order_across_kinds() {
        let mut q = ResponseQueue::new();
        // (seq, source, cycle), accepted in this order.
        let pushed = [
            (0, Source::Dram, 500),
            (1, Source::L1Hit, 40),
            (2, Source::L1Merge, 500),
            (3, Source::L2Hit, 230),
            (4, Source::L1Hit, 41),
            (5, Source::L2Merge, 40),
            (6, Source::L2Write, 231),
            (7, Source::L1Merge, 30),
            (8, Source::Dram, 500),
        ];
        for (seq, source, cycle) in pushed {
            q.push(seq, source, response(seq, cycle));
        }
        assert_eq!(q.len(), 9);
        assert_eq!(q.earliest(), Some(30));
        assert_eq!(q.pop_due(29), None);
        let mut order = Vec::new();
        while let Some(r) = q.pop_due(1000) {
            order.push(r.tag);
        }
        // Sorted by (cycle, seq): the single-heap order.
        let mut want = pushed.to_vec();
        want.sort_by_key(|&(seq, _, cycle)| (cycle, seq));
        let want: Vec<u64> = want.iter().map(|&(seq, _, _)| seq).collect();
        assert_eq!(order, want);
        assert!(q.is_empty());
        assert_eq!(q.earliest(), None);
    }

    #[test]
    fn stops_at_responses_not_yet_due() {
        let mut q = ResponseQueue::new();
        q.push(0, Source::L2Hit, response(0, 100));
        q.push(1, Source::L1Merge, response(1, 50));
        assert_eq!(q.pop_due(60).map(|r| r.tag), Some(1));
        assert_eq!(q.pop_due(60), None);
        assert_eq!(q.peek().map(|r| r.tag), Some(0));
        assert_eq!(q.earliest(), Some(100));
        assert_eq!(q.len(), 1);
    }
}
