//! The engine's L2 side: the memory partitions ([`crate::memory::L2Partition`]) as units of
//! work that worker threads apply side by side at the end of each window.
//!
//! At the end of a window the engine hands every SM's L2 operations to the partition of their
//! line ([`PartitionJobs::gather`], in SM order). In the first round of the next window each
//! partition, as a pre-job on any thread (partitions share no state), sorts its own operations
//! into key order ([`crate::memory::L2Op::key`]) and applies them ([`PartitionJobs::apply`]);
//! then every SM takes its own results from the partitions ([`PartitionJobs::results_for`])
//! before it settles the window. Within a partition the order is the global key order
//! restricted to it, so results are exactly those of one loop applying every operation in key
//! order.

use std::sync::{Mutex, MutexGuard};

use crate::gpu::parallelism::Stopwatch;
use crate::memory::{L2Op, L2Partition, L2Side, MemStats, PartitionMap, Source};

/// One partition with its share of the window's operations.
#[derive(Debug)]
struct Job {
    part: L2Partition,
    /// The window's operations of this partition: (operation, SM, index in the SM's window).
    ops: Vec<(L2Op, u32, u32)>,
    /// Their results per SM: (index in the SM's window, result).
    results: Vec<Vec<(u32, (u64, Source))>>,
    /// Nanoseconds the last [`PartitionJobs::apply`] took (profiled runs).
    ns: u64,
}

/// The L2 partitions as jobs, each behind its own (uncontended) lock.
#[derive(Debug)]
pub struct PartitionJobs {
    map: PartitionMap,
    jobs: Vec<Mutex<Job>>,
}

/// Locks a job (a panic elsewhere is propagated by the workers; the data is still usable).
fn lock(job: &Mutex<Job>) -> MutexGuard<'_, Job> {
    job.lock().unwrap_or_else(|e| e.into_inner())
}

impl PartitionJobs {
    /// The partitions of `l2`, serving `sms` SMs.
    pub fn new(l2: L2Side, sms: usize) -> Self {
        let (map, parts) = l2.into_partitions();
        PartitionJobs {
            map,
            jobs: parts
                .into_iter()
                .map(|part| {
                    Mutex::new(Job {
                        part,
                        ops: Vec::new(),
                        results: vec![Vec::new(); sms],
                        ns: 0,
                    })
                })
                .collect(),
        }
    }

    /// Number of partitions.
    pub fn len(&self) -> usize {
        self.jobs.len()
    }

    /// Whether there are none (never: an L2 has at least one partition).
    pub fn is_empty(&self) -> bool {
        self.jobs.is_empty()
    }

    /// Hands the window's operations of every SM (`ops[sm]`, in the SM's acceptance order) to
    /// their partitions, dropping the last window's results; returns whether there were any.
    pub fn gather<'o>(&self, ops: impl Iterator<Item = &'o [L2Op]>) -> bool {
        let mut any = false;
        let mut jobs: Vec<MutexGuard<'_, Job>> = self.jobs.iter().map(lock).collect();
        for job in &mut jobs {
            for r in job.results.iter_mut() {
                r.clear();
            }
        }
        for (sm, ops) in ops.enumerate() {
            for (k, op) in ops.iter().enumerate() {
                let p = self.map.partition(op.line);
                jobs[p].ops.push((*op, sm as u32, k as u32));
                any = true;
            }
        }
        any
    }

    /// Applies partition `p`'s operations of the window in key order (on any thread); times
    /// it if `profile`.
    pub fn apply(&self, p: usize, profile: bool) {
        let watch = Stopwatch::start(profile);
        let mut job = lock(&self.jobs[p]);
        let Job {
            part, ops, results, ..
        } = &mut *job;
        ops.sort_unstable_by_key(|(op, _, _)| op.key());
        for (op, sm, k) in ops.drain(..) {
            results[sm as usize].push((k, part.apply(&op)));
        }
        job.ns = watch.ns();
    }

    /// Nanoseconds the last [`apply`](Self::apply) of partition `p` took (profiled runs).
    pub fn apply_ns(&self, p: usize) -> u64 {
        lock(&self.jobs[p]).ns
    }

    /// Hands SM `sm`'s results of the last applied window to `f(index, result)`, partition by
    /// partition.
    pub fn results_for(&self, sm: usize, mut f: impl FnMut(usize, (u64, Source))) {
        for job in &self.jobs {
            for &(k, result) in &lock(job).results[sm] {
                f(k as usize, result);
            }
        }
    }

    /// The L2 and DRAM counters of all partitions.
    pub fn stats(&self) -> MemStats {
        let jobs: Vec<MutexGuard<'_, Job>> = self.jobs.iter().map(lock).collect();
        crate::memory::l2::total_stats(jobs.iter().map(|j| &j.part))
    }

    /// A one-line summary at cycle `now`, for a deadlock watchdog.
    pub fn debug_state(&self, now: u64) -> String {
        let jobs: Vec<MutexGuard<'_, Job>> = self.jobs.iter().map(lock).collect();
        crate::memory::l2::summary(jobs.iter().map(|j| &j.part), now)
    }
}
