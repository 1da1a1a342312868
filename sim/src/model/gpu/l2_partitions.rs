//! The engine's L2 side: the memory partitions ([`crate::model::memory::L2Partition`]) as units of
//! work that worker threads apply side by side, each as far as every SM has gone.
//!
//! Each SM posts its L2 operations to the partition of their line as it goes
//! ([`PartitionJobs::post`], on its own thread) into a slot of its own per partition, and then
//! says how far it has gone (every operation accepted before that cycle is posted). A partition
//! applies its operations *through* a cycle every SM has reached ([`PartitionJobs::apply`], on
//! any thread: partitions share no state): it takes the operations of its slots accepted before
//! that cycle, sorts them into key order ([`crate::model::memory::L2Op::key`]) and applies them,
//! leaving each SM's results in that SM's slot; every SM takes its own results
//! ([`PartitionJobs::results_for`]) before it needs them. Operations before a cycle are applied
//! only once every SM has passed it, and in key order (cycle first), so within a partition the
//! order is the global key order restricted to it, and the results are exactly those of one
//! loop applying every operation in key order.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};

use crossbeam_utils::CachePadded;

use crate::model::gpu::parallelism::Stopwatch;
use crate::model::gpu::workers::lock;
use crate::model::memory::{L2Op, L2Partition, L2Side, MemStats, PartitionMap, Source};

/// One partition with its scratch space.
#[derive(Debug)]
struct Part {
    part: L2Partition,
    /// Operations being applied: (operation, SM).
    ops: Vec<(L2Op, u32)>,
    /// Their results per SM, before they go to the SMs' slots.
    results: Vec<Vec<(u64, (u64, Source))>>,
    /// Every operation accepted before this cycle is applied.
    through: u64,
    /// Nanoseconds of all applies (profiled runs).
    ns: u64,
    /// Applies that did something.
    applies: u64,
}

/// What one SM and one partition exchange.
#[derive(Debug, Default)]
struct Exchange {
    /// The SM's operations for the partition not yet applied, in acceptance order (their
    /// numbers are their `seq`).
    ops: std::collections::VecDeque<L2Op>,
    /// The partition's results for the SM not yet taken: (operation number, result).
    results: Vec<(u64, (u64, Source))>,
}

/// One exchange slot with what its readers check before they take the lock.
#[derive(Debug)]
struct Slot {
    exchange: Mutex<Exchange>,
    /// The cycle of the oldest operation not yet taken (`u64::MAX`: none).
    oldest: AtomicU64,
    /// Results not yet taken.
    results: AtomicU64,
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
    slots: Vec<CachePadded<Slot>>,
}

impl PartitionJobs {
    /// The partitions of `l2`, serving `sms` SMs.
    pub fn new(l2: L2Side, sms: usize) -> Self {
        let (map, parts) = l2.into_partitions();
        let slots = (0..parts.len() * sms)
            .map(|_| {
                CachePadded::new(Slot {
                    exchange: Mutex::default(),
                    oldest: AtomicU64::new(u64::MAX),
                    results: AtomicU64::new(0),
                })
            })
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
                        through: 0,
                        ns: 0,
                        applies: 0,
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

    /// The partition of line `line`.
    pub fn partition(&self, line: u64) -> usize {
        self.map.partition(line)
    }

    /// Whether there are none (never: an L2 has at least one partition).
    pub fn is_empty(&self) -> bool {
        self.parts.is_empty()
    }

    /// The slot of partition `p` and SM `sm`.
    fn slot(&self, p: usize, sm: usize) -> &Slot {
        &self.slots[p * self.sms + sm]
    }

    /// Posts SM `sm`'s operations `ops` (the next in its acceptance order; each numbered by
    /// its `seq`) to their partitions.
    pub fn post(&self, sm: usize, ops: &[L2Op]) {
        for op in ops {
            let p = self.map.partition(op.line);
            let slot = self.slot(p, sm);
            let mut ex = lock(&slot.exchange);
            if ex.ops.is_empty() {
                slot.oldest.store(op.cycle, Ordering::Release);
            }
            ex.ops.push_back(*op);
        }
    }

    /// Applies partition `p`'s operations accepted before cycle `through` (every SM has posted
    /// all of them) in key order, on any thread, leaving every SM's results (and only those) in
    /// its slot; times it if `profile`. Returns the cycle through which the partition has now
    /// applied everything, or `None` if another thread is applying it.
    pub fn apply(&self, p: usize, through: u64, profile: bool) -> Option<u64> {
        let watch = Stopwatch::start(profile);
        let mut job = match self.parts[p].try_lock() {
            Ok(job) => job,
            Err(std::sync::TryLockError::Poisoned(e)) => e.into_inner(),
            Err(std::sync::TryLockError::WouldBlock) => return None,
        };
        if through <= job.through {
            return Some(job.through);
        }
        let Part {
            part, ops, results, ..
        } = &mut *job;
        for sm in 0..self.sms {
            let slot = self.slot(p, sm);
            if slot.oldest.load(Ordering::Acquire) >= through {
                continue;
            }
            let mut ex = lock(&slot.exchange);
            while ex.ops.front().is_some_and(|op| op.cycle < through) {
                let op = ex.ops.pop_front().expect("checked above");
                ops.push((op, sm as u32));
            }
            let oldest = ex.ops.front().map_or(u64::MAX, |op| op.cycle);
            slot.oldest.store(oldest, Ordering::Release);
        }
        ops.sort_unstable_by_key(|(op, _)| op.key());
        for (op, sm) in ops.drain(..) {
            results[sm as usize].push((op.seq, part.apply(&op)));
        }
        for (sm, r) in results.iter_mut().enumerate() {
            if !r.is_empty() {
                let slot = self.slot(p, sm);
                let mut ex = lock(&slot.exchange);
                ex.results.append(r);
                slot.results
                    .store(ex.results.len() as u64, Ordering::Release);
            }
        }
        job.through = through;
        job.ns += watch.ns();
        job.applies += 1;
        Some(through)
    }

    /// Nanoseconds all [`apply`](Self::apply) calls of partition `p` took (profiled runs), and
    /// how many applied something.
    pub fn apply_ns(&self, p: usize) -> (u64, u64) {
        let job = lock(&self.parts[p]);
        (job.ns, job.applies)
    }

    /// Hands SM `sm`'s results not yet taken to `f(operation number, result)`, partition by
    /// partition.
    pub fn results_for(&self, sm: usize, mut f: impl FnMut(u64, (u64, Source))) {
        for p in 0..self.parts.len() {
            let slot = self.slot(p, sm);
            if slot.results.load(Ordering::Acquire) == 0 {
                continue;
            }
            let mut ex = lock(&slot.exchange);
            for (k, result) in ex.results.drain(..) {
                f(k, result);
            }
            slot.results.store(0, Ordering::Release);
        }
    }

    /// The L2 and DRAM counters of all partitions.
    pub fn stats(&self) -> MemStats {
        let parts: Vec<MutexGuard<'_, Part>> = self.parts.iter().map(lock).collect();
        crate::model::memory::l2::total_stats(parts.iter().map(|j| &j.part))
    }

    /// A one-line summary at cycle `now`, for a deadlock watchdog.
    pub fn debug_state(&self, now: u64) -> String {
        let parts: Vec<MutexGuard<'_, Part>> = self.parts.iter().map(lock).collect();
        crate::model::memory::l2::summary(parts.iter().map(|j| &j.part), now)
    }
}
