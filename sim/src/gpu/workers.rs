//! The simulator's worker threads: [`Workers::round`] runs one function with a round's
//! parameter on a number of *pre-jobs* (the engine's L2 partitions) and then on a chosen set of
//! items (the engine's SM nodes) on all threads at once and returns when every one is done. No
//! item starts before every pre-job is done; each item is behind its own uncontended lock.
//! Which thread runs a job or an item never changes the result: during a round they only touch
//! their own state.
//!
//! # Affinity
//! Each unit has a *home* thread (pre-job or item `u` of `T` threads: thread `u mod T`, the
//! calling thread being thread 0). A thread first runs its home units, then takes any other
//! unit not yet claimed (each unit is claimed once per round by an atomic), so threads still
//! balance the load, but an SM's state (its RT unit, tables and L1: hundreds of KB) stays in
//! one core's caches from window to window unless its home thread falls behind. Threads are not
//! pinned to CPUs: on a 16-core machine pinning made sponza VTQ on 16 threads 1.25x slower
//! (docs/performance.md).
//!
//! Rounds are short (a few hundred simulated cycles of one SM), so waiting threads spin
//! briefly before they yield, and the calling thread works on the round too.

use std::cell::UnsafeCell;

use crossbeam_utils::CachePadded;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard};
use std::thread::{self, Scope};

/// Spins before a waiting thread starts yielding its core.
const SPINS: u32 = 4000;

/// What a round's function is called on.
pub enum Unit<'t, T> {
    /// Pre-job `i` of the round.
    Pre(usize),
    /// A chosen item.
    Item(&'t mut T),
}

/// The parameter of the current round, shared without a lock.
struct ParamCell<P>(UnsafeCell<Option<P>>);

// SAFETY: the cell is written only by the calling thread inside `Workers::round`, before it
// starts the round by raising the epoch (Release), at a time when every helper has finished the
// previous round (the caller waited for all of them) and waits for the epoch to change; helpers
// read it only after observing the new epoch (Acquire) and before they report the round done.
// So a write never overlaps a read, and every read sees the round's value.
unsafe impl<P: Send + Sync> Sync for ParamCell<P> {}

/// Shared state of the rounds.
struct Round<T, P, F> {
    /// The function run on each chosen item.
    f: F,
    /// The items.
    items: Vec<Mutex<T>>,
    /// Which items take part in the current round.
    chosen: Vec<AtomicBool>,
    /// The most pre-jobs a round may have.
    max_pre: usize,
    /// Per unit (pre-jobs `0..max_pre`, then items): the last epoch in which it was claimed,
    /// on a cache line of its own.
    claims: Vec<CachePadded<AtomicU64>>,
    /// Threads in all, the calling thread included.
    threads: usize,
    /// Pre-jobs of the current round.
    pre: AtomicUsize,
    /// Pre-jobs of the current round done.
    pre_done: AtomicUsize,
    /// Threads done with the current round.
    done: AtomicUsize,
    /// Round number; a change starts a round.
    epoch: AtomicU64,
    /// Set to end the helpers.
    stop: AtomicBool,
    /// Set when a job panicked on a helper thread.
    panicked: AtomicBool,
    /// The parameter of the current round.
    param: ParamCell<P>,
}

impl<T, P, F: Fn(Unit<'_, T>, &P)> Round<T, P, F> {
    /// Claims unit `u` for the round of `epoch`; false if another thread already has (a
    /// plain read first, so that threads looking for work do not take the line from the
    /// claiming one).
    fn claim(&self, u: usize, epoch: u64) -> bool {
        let c = &self.claims[u];
        c.load(Ordering::Acquire) < epoch && c.fetch_max(epoch, Ordering::AcqRel) < epoch
    }

    /// Units `0..n` in the order thread `me` takes them: its home units, then the others.
    fn order(&self, n: usize, me: usize) -> impl Iterator<Item = usize> + '_ {
        let t = self.threads;
        (me..n)
            .step_by(t)
            .chain((0..n).filter(move |u| u % t != me))
    }

    /// Thread `me`'s part of the round of `epoch`: claims and runs pre-jobs, then, once every
    /// pre-job is done, chosen items, until none is left.
    fn work(&self, me: usize, epoch: u64, param: &P) {
        let pre = self.pre.load(Ordering::Acquire);
        for p in self.order(pre, me) {
            if self.claim(p, epoch) {
                (self.f)(Unit::Pre(p), param);
                self.pre_done.fetch_add(1, Ordering::AcqRel);
            }
        }
        let mut waited = pre == 0;
        for i in self.order(self.items.len(), me) {
            if self.chosen[i].load(Ordering::Acquire) && self.claim(self.max_pre + i, epoch) {
                if !waited {
                    wait(|| self.pre_done.load(Ordering::Acquire) == pre);
                    waited = true;
                }
                (self.f)(Unit::Item(&mut lock(&self.items[i])), param);
            }
        }
    }
}

/// Locks a mutex of the engine's shared state (a panic in a job poisons nothing that matters:
/// the workers propagate it, and the data is still usable).
pub fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Waits (spinning, then yielding) until `cond` holds.
fn wait(cond: impl Fn() -> bool) {
    let mut spins = 0u32;
    while !cond() {
        if spins < SPINS {
            spins += 1;
            std::hint::spin_loop();
        } else {
            thread::yield_now();
        }
    }
}

/// A set of items and the threads that work on them in rounds.
pub struct Workers<'s, T, P, F> {
    round: &'s Round<T, P, F>,
    helpers: usize,
}

impl<'s, T: Send, P: Clone + Send + Sync, F: Fn(Unit<'_, T>, &P) + Sync> Workers<'s, T, P, F> {
    /// Runs `body` with workers running `f` over up to `max_pre` pre-jobs per round and over
    /// `items` on `threads` threads in all (the caller's included; at least 1); returns its
    /// result and the items.
    pub fn with<R>(
        threads: usize,
        max_pre: usize,
        items: Vec<T>,
        f: F,
        body: impl FnOnce(&mut Workers<'_, T, P, F>) -> R,
    ) -> (R, Vec<T>) {
        let threads = threads.max(1);
        let round = Round {
            f,
            chosen: items.iter().map(|_| AtomicBool::new(false)).collect(),
            max_pre,
            claims: (0..max_pre + items.len())
                .map(|_| CachePadded::new(AtomicU64::new(0)))
                .collect(),
            threads,
            items: items.into_iter().map(Mutex::new).collect(),
            pre: AtomicUsize::new(0),
            pre_done: AtomicUsize::new(0),
            done: AtomicUsize::new(0),
            epoch: AtomicU64::new(0),
            stop: AtomicBool::new(false),
            panicked: AtomicBool::new(false),
            param: ParamCell(UnsafeCell::new(None)),
        };
        let helpers = threads - 1;
        let result = thread::scope(|scope: &Scope<'_, '_>| {
            for me in 1..threads {
                let round = &round;
                scope.spawn(move || helper(round, me));
            }
            let mut workers = Workers {
                round: &round,
                helpers,
            };
            let result = body(&mut workers);
            round.stop.store(true, Ordering::Release);
            round.epoch.fetch_add(1, Ordering::AcqRel);
            result
        });
        let items = round
            .items
            .into_iter()
            .map(|m| m.into_inner().unwrap_or_else(|e| e.into_inner()))
            .collect();
        (result, items)
    }

    /// Runs the function with `param` on pre-jobs `0..pre` (at most the `max_pre` given to
    /// [`Workers::with`]) and then on every item `choose` selects, on all threads; returns
    /// when all are done.
    pub fn round(&mut self, pre: usize, choose: impl Fn(usize) -> bool, param: P) {
        let r = self.round;
        assert!(pre <= r.max_pre, "{pre} pre-jobs exceed the {}", r.max_pre);
        let mut any = 0;
        let mut only = 0;
        for (i, c) in r.chosen.iter().enumerate() {
            let yes = choose(i);
            c.store(yes, Ordering::Relaxed);
            if yes {
                any += 1;
                only = i;
            }
        }
        if any + pre == 0 {
            return;
        }
        // One unit, or no helpers: no hand-over needed.
        if any + pre == 1 || self.helpers == 0 {
            for i in 0..pre {
                (r.f)(Unit::Pre(i), &param);
            }
            if any == 1 {
                (r.f)(Unit::Item(&mut lock(&r.items[only])), &param);
            } else {
                for i in 0..r.items.len() {
                    if r.chosen[i].load(Ordering::Relaxed) {
                        (r.f)(Unit::Item(&mut lock(&r.items[i])), &param);
                    }
                }
            }
            return;
        }
        // SAFETY: every helper has finished the last round (see `ParamCell`).
        unsafe { *r.param.0.get() = Some(param.clone()) };
        r.pre.store(pre, Ordering::Release);
        r.pre_done.store(0, Ordering::Release);
        r.done.store(0, Ordering::Release);
        let epoch = r.epoch.fetch_add(1, Ordering::AcqRel) + 1;
        r.work(0, epoch, &param);
        wait(|| r.done.load(Ordering::Acquire) == self.helpers);
        assert!(
            !r.panicked.load(Ordering::Acquire),
            "a simulator worker thread panicked (its message is above)"
        );
    }
}

impl<T, P, F> Workers<'_, T, P, F> {
    /// Number of items.
    pub fn len(&self) -> usize {
        self.round.items.len()
    }

    /// Whether there are no items.
    pub fn is_empty(&self) -> bool {
        self.round.items.is_empty()
    }

    /// Item `i`, locked (between rounds).
    pub fn item(&self, i: usize) -> MutexGuard<'_, T> {
        lock(&self.round.items[i])
    }
}

/// Helper thread `me`: works on each round until told to stop.
fn helper<T, P: Clone + Send + Sync, F: Fn(Unit<'_, T>, &P)>(round: &Round<T, P, F>, me: usize) {
    let mut seen = 0;
    loop {
        wait(|| round.epoch.load(Ordering::Acquire) != seen);
        seen = round.epoch.load(Ordering::Acquire);
        if round.stop.load(Ordering::Acquire) {
            return;
        }
        // SAFETY: the round of epoch `seen` has started and the caller does not write the
        // parameter again before this thread reports it done (see `ParamCell`).
        let param = unsafe { (*round.param.0.get()).clone() };
        if let Some(param) = param {
            let run = std::panic::AssertUnwindSafe(|| round.work(me, seen, &param));
            if std::panic::catch_unwind(run).is_err() {
                round.panicked.store(true, Ordering::Release);
            }
        }
        round.done.fetch_add(1, Ordering::AcqRel);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_chosen_item_runs_once_per_round_on_any_thread_count() {
        for threads in [1, 2, 3, 16] {
            let items: Vec<u64> = vec![0; 10];
            let add = |u: Unit<'_, u64>, by: &u64| {
                if let Unit::Item(x) = u {
                    *x += by;
                }
            };
            let ((), items) = Workers::with(threads, 0, items, add, |w| {
                for round in 0..50u64 {
                    w.round(0, |i| !(i as u64 + round).is_multiple_of(3), 1);
                }
                assert_eq!(w.len(), 10);
            });
            let want: Vec<u64> = (0..10u64)
                .map(|i| (0..50u64).filter(|r| !(i + r).is_multiple_of(3)).count() as u64)
                .collect();
            assert_eq!(items, want, "{threads} threads");
        }
    }

    #[test]
    fn items_start_after_every_pre_job_is_done() {
        use std::sync::atomic::AtomicU64;
        for threads in [1, 2, 3, 16] {
            // Each pre-job adds to a shared sum; each item copies the sum it sees.
            let sum = AtomicU64::new(0);
            let f = |u: Unit<'_, u64>, round: &u64| match u {
                Unit::Pre(i) => {
                    // Uneven pre-jobs: later ones take longer.
                    for _ in 0..i * 1000 {
                        std::hint::spin_loop();
                    }
                    sum.fetch_add(round * 100 + i as u64, Ordering::AcqRel);
                }
                Unit::Item(x) => *x = sum.load(Ordering::Acquire),
            };
            let ((), items) = Workers::with(threads, 5, vec![0u64; 6], f, |w| {
                for round in 1..=20u64 {
                    w.round(5, |_| true, round);
                }
            });
            // After round r the sum holds every pre-job of rounds 1..=r.
            let want: u64 = (1..=20u64).map(|r| 5 * r * 100 + 10).sum();
            assert_eq!(items, vec![want; 6], "{threads} threads");
        }
    }
}
