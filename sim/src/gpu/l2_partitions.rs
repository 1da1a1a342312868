//! The engine's L2 side: the memory partitions ([`crate::memory::L2Partition`]) as units of
//! work that worker threads apply side by side at the end of each window.
//!
//! Each SM posts its L2 operations to the partition of their line as it goes
//! ([`PartitionJobs::post`], at the end of each of its visits, on its own thread) into a slot of
//! its own per partition. In the first round of the next window each partition, as a pre-job on
//! any thread (partitions share no state), takes the operations of its slots, sorts them into
//! key order ([`crate::memory::L2Op::key`]) and applies them ([`PartitionJobs::apply`]),
//! leaving each SM's results in that SM's slot; then every SM takes its own results
//! ([`PartitionJobs::results_for`]) before it settles the window. Within a partition the order
//! is the global key order restricted to it, so results are exactly those of one loop applying
//! every operation in key order.

use std::sync::{Mutex, MutexGuard};

use crossbeam_utils::CachePadded;

use crate::gpu::parallelism::Stopwatch;
use crate::gpu::workers::lock;
use crate::memory::{L2Op, L2Partition, L2Side, MemStats, PartitionMap, Source};

/// One partition with its scratch space.
#[derive(Debug)]
struct Part {
    part: L2Partition,
    /// The window's operations of this partition: (operation, SM, index in the SM's window).
    ops: Vec<(L2Op, u32, u32)>,
    /// Their results per SM, before they go to the SMs' slots.
    results: Vec<Vec<(u32, (u64, Source))>>,
    /// Nanoseconds the last [`PartitionJobs::apply`] took (profiled runs).
    ns: u64,
}

/// What one SM and one partition exchange in a window.
#[derive(Debug, Default)]
struct Exchange {
    /// The SM's operations for the partition: (operation, index in the SM's window).
    ops: Vec<(L2Op, u32)>,
    /// The partition's results for the SM: (index in the SM's window, result).
    results: Vec<(u32, (u64, Source))>,
}

/// The L2 partitions as jobs, each behind its own (uncontended) lock, and one exchange slot
/// per partition and SM.
#[derive(Debug)]
pub struct PartitionJobs {
    map: PartitionMap,
    sms: usize,
    parts: Vec<Mutex<Part>>,
    /// Slot of partition `p` and SM `sm` at `p * sms + sm`, each behind its own lock on cache
    /// lines of its own (SMs and partitions write neighbouring slots from different threads).
    slots: Vec<CachePadded<Mutex<Exchange>>>,
}

impl PartitionJobs {
    /// The partitions of `l2`, serving `sms` SMs.
    pub fn new(l2: L2Side, sms: usize) -> Self {
        let (map, parts) = l2.into_partitions();
        let slots = (0..parts.len() * sms)
            .map(|_| CachePadded::new(Mutex::default()))
            .collect();
        PartitionJobs {
            map,
            sms,
            parts: parts
                .into_iter()
                .map(|part| {
                    Mutex::new(Part {
                        part,
                        ops: Vec::new(),
                        results: vec![Vec::new(); sms],
                        ns: 0,
                    })
                })
                .collect(),
            slots,
        }
    }

    /// Number of partitions.
    pub fn len(&self) -> usize {
        self.parts.len()
    }

    /// Whether there are none (never: an L2 has at least one partition).
    pub fn is_empty(&self) -> bool {
        self.parts.is_empty()
    }

    /// The slot of partition `p` and SM `sm`, locked.
    fn slot(&self, p: usize, sm: usize) -> MutexGuard<'_, Exchange> {
        lock(&self.slots[p * self.sms + sm])
    }

    /// Posts SM `sm`'s operations `ops` of the window, the first of them being its operation
    /// number `first`, to their partitions (called with each new stretch of the SM's
    /// operations, in acceptance order).
    pub fn post(&self, sm: usize, first: usize, ops: &[L2Op]) {
        for (k, op) in ops.iter().enumerate() {
            let p = self.map.partition(op.line);
            self.slot(p, sm).ops.push((*op, (first + k) as u32));
        }
    }

    /// Applies partition `p`'s operations of the window in key order (on any thread), leaving
    /// every SM's results (and only those) in its slot; times it if `profile`.
    pub fn apply(&self, p: usize, profile: bool) {
        let watch = Stopwatch::start(profile);
        let mut job = lock(&self.parts[p]);
        let Part {
            part, ops, results, ..
        } = &mut *job;
        for sm in 0..self.sms {
            let mut slot = self.slot(p, sm);
            slot.results.clear();
            ops.extend(slot.ops.drain(..).map(|(op, k)| (op, sm as u32, k)));
        }
        ops.sort_unstable_by_key(|(op, _, _)| op.key());
        for (op, sm, k) in ops.drain(..) {
            results[sm as usize].push((k, part.apply(&op)));
        }
        for (sm, r) in results.iter_mut().enumerate() {
            if !r.is_empty() {
                self.slot(p, sm).results.append(r);
            }
        }
        job.ns = watch.ns();
    }

    /// Nanoseconds the last [`apply`](Self::apply) of partition `p` took (profiled runs).
    pub fn apply_ns(&self, p: usize) -> u64 {
        lock(&self.parts[p]).ns
    }

    /// Hands SM `sm`'s results of the last applied window to `f(index, result)`, partition by
    /// partition.
    pub fn results_for(&self, sm: usize, mut f: impl FnMut(usize, (u64, Source))) {
        for p in 0..self.parts.len() {
            for &(k, result) in &self.slot(p, sm).results {
                f(k as usize, result);
            }
        }
    }

    /// The L2 and DRAM counters of all partitions.
    pub fn stats(&self) -> MemStats {
        let parts: Vec<MutexGuard<'_, Part>> = self.parts.iter().map(lock).collect();
        crate::memory::l2::total_stats(parts.iter().map(|j| &j.part))
    }

    /// A one-line summary at cycle `now`, for a deadlock watchdog.
    pub fn debug_state(&self, now: u64) -> String {
        let parts: Vec<MutexGuard<'_, Part>> = self.parts.iter().map(lock).collect();
        crate::memory::l2::summary(parts.iter().map(|j| &j.part), now)
    }
}
