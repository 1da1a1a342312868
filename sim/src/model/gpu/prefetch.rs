//! The treelet prefetcher of Chou et al. (MICRO 2023), the paper's comparison point (its public
//! code): one per SM, beside the RT unit. After every RT-unit step it counts the treelet
//! of each traversing ray's next node over all warps in the warp buffer; when the most popular
//! treelet (ties: lowest treelet id) holds at least `mode.prefetch_threshold` of those rays, it
//! queues every 32 B sector of that treelet's nodes. Queued sectors go to the L1 as prefetches
//! ([`MemRequest::prefetch`]), at most one per cycle and only in cycles in which the RT unit's
//! memory access queue is empty (no demand request to send). Sectors already in or being filled
//! into the L1 are skipped without using the cycle.
//!
//! A treelet is not queued again while it is one of the last [`HISTORY`] treelets queued, so a
//! popularity peak that lasts many cycles queues its treelet once. Observing unchanged
//! registers twice changes nothing, which keeps idle-cycle skipping exact: the registers only
//! change when the RT unit steps, and a cycle with queued prefetches is reported as an event.

use std::collections::VecDeque;

use vtq_hdl::rt_unit::CHUNK_BYTES;

use crate::model::bvh::HwBvh;
use crate::model::gpu::error::SimError;
use crate::model::memory::{AccessClass, AccessError, L1Port, MemRequest};

/// How many recently queued treelets are remembered (and not queued again).
pub const HISTORY: usize = 4;

/// One SM's treelet prefetcher.
#[derive(Debug, Clone)]
pub struct Prefetcher<'a> {
    bvh: &'a HwBvh,
    /// Fraction of the counted rays the most popular treelet must hold.
    threshold: f64,
    /// Rays per treelet in the current count (all zero between observations).
    counts: Vec<u32>,
    /// Treelets with a non-zero count, to find the winner and clear the counts cheaply.
    touched: Vec<u32>,
    /// The last treelets queued, oldest first.
    history: VecDeque<u32>,
    /// Sector addresses waiting to be prefetched, oldest first.
    queue: VecDeque<u64>,
    /// First cycle the head of `queue` may be offered again after an L1 stall.
    retry_at: u64,
    /// Treelets its popularity rule queued for prefetching ([`Prefetcher::observe`]; the
    /// treelet controller's preloads are counted by the controller).
    pub treelets_queued: u64,
    /// The next accesses of the last observation (debug builds check that skipped
    /// observations saw the same).
    #[cfg(debug_assertions)]
    last: Vec<u64>,
}

impl<'a> Prefetcher<'a> {
    /// A prefetcher over `bvh`'s treelets that triggers when one treelet holds at least
    /// `threshold` (0..=1, validated with the configuration) of the RT unit's traversing rays.
    pub fn new(bvh: &'a HwBvh, threshold: f64) -> Self {
        Prefetcher {
            bvh,
            threshold,
            counts: vec![0; bvh.treelets().len()],
            touched: Vec::new(),
            history: VecDeque::with_capacity(HISTORY + 1),
            queue: VecDeque::new(),
            retry_at: 0,
            treelets_queued: 0,
            #[cfg(debug_assertions)]
            last: Vec::new(),
        }
    }

    /// The RT unit stepped without changing any ray's next access: observing `next` again
    /// would change nothing (the counts are the same, and a winning treelet was queued by the
    /// last observation and is in the history, which only observations change). Debug builds
    /// check that `next` is what the last observation saw.
    pub fn unchanged(&mut self, next: impl Iterator<Item = u64>) {
        #[cfg(debug_assertions)]
        assert!(
            next.eq(self.last.iter().copied()),
            "a skipped prefetcher observation would have seen other accesses"
        );
        #[cfg(not(debug_assertions))]
        let _ = next;
    }

    /// Counts the treelets of the next accesses `next` of the RT unit's traversing rays
    /// ([`vtq_hdl::rt_unit::RtUnit::next_addresses`]) and queues the most popular treelet's
    /// sectors if it holds enough of them and was not queued recently.
    pub fn observe(&mut self, next: impl Iterator<Item = u64>) {
        let mut total = 0u32;
        #[cfg(debug_assertions)]
        self.last.clear();
        for address in next {
            #[cfg(debug_assertions)]
            self.last.push(address);
            let Ok(addr) = u32::try_from(address) else {
                continue;
            };
            let t = self.bvh.treelet_of(addr);
            let Some(count) = self.counts.get_mut(t as usize) else {
                continue;
            };
            if *count == 0 {
                self.touched.push(t);
            }
            *count += 1;
            total += 1;
        }
        let mut best: Option<(u32, u32)> = None;
        for &t in &self.touched {
            let c = self.counts[t as usize];
            if best.is_none_or(|(bt, bc)| c > bc || (c == bc && t < bt)) {
                best = Some((t, c));
            }
            self.counts[t as usize] = 0;
        }
        self.touched.clear();
        let Some((treelet, count)) = best else {
            return;
        };
        if (count as f64) < self.threshold * total as f64 || self.history.contains(&treelet) {
            return;
        }
        self.history.push_back(treelet);
        if self.history.len() > HISTORY {
            self.history.pop_front();
        }
        self.treelets_queued += 1;
        self.queue_treelet(treelet);
    }

    /// Queues every 32 B sector of `treelet`'s nodes for prefetching (the treelet controller's
    /// preload in queues mode; a treelet number outside the BVH is ignored).
    pub fn queue_treelet(&mut self, treelet: u32) {
        let Some(&info) = self.bvh.treelets().get(treelet as usize) else {
            return;
        };
        let (base, end) = (info.base as u64, info.base as u64 + info.bytes as u64);
        let step = CHUNK_BYTES as u64;
        self.queue
            .extend((base..end.next_multiple_of(step)).step_by(step as usize));
    }

    /// Offers the next queued sector not already in the SM's L1 as a prefetch in phase `phase`
    /// of cycle `now` (the caller checks that no demand request goes to the L1 this cycle).
    pub fn issue(&mut self, now: u64, phase: u8, mem: &mut L1Port) -> Result<(), SimError> {
        if now < self.retry_at {
            return Ok(());
        }
        while let Some(&addr) = self.queue.front() {
            if !mem.l1_contains(addr) {
                break;
            }
            self.queue.pop_front();
        }
        let Some(&addr) = self.queue.front() else {
            return Ok(());
        };
        match mem.access(now, phase, MemRequest::prefetch(addr, AccessClass::Bvh)) {
            Ok(_) => {
                self.queue.pop_front();
                Ok(())
            }
            Err(AccessError::Stall(s)) => {
                self.retry_at = s.retry_at.max(now + 1);
                Ok(())
            }
            Err(e) => Err(SimError::Memory(e)),
        }
    }

    /// After the L1 port settled L2 results: makes a deferred stall's retry cycle real if that
    /// settle resolved it.
    pub fn settle_retry(&mut self, mem: &L1Port) {
        self.retry_at = mem.resolve_retry(self.retry_at);
    }

    /// The next cycle after `now` at which a queued prefetch may be offered, if any.
    pub fn next_event(&self, now: u64) -> Option<u64> {
        (!self.queue.is_empty()).then(|| self.retry_at.max(now + 1))
    }

    /// Sectors waiting to be prefetched.
    pub fn pending(&self) -> usize {
        self.queue.len()
    }
}
