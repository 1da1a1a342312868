//! The simulator's worker threads: [`Workers::round`] runs one function with a round's
//! parameter on a number of *pre-jobs* (the engine's L2 partitions) and then on a chosen set of
//! items (the engine's SM nodes) on all threads at once and returns when every one is done. Jobs
//! and items are claimed one at a time from a shared counter, pre-jobs first, so threads balance
//! the load; no item starts before every pre-job is done; each item is behind its own
//! uncontended lock. Which thread runs a job or an item never changes the result: during a round
//! they only touch their own state.
//!
//! Rounds are short (a few hundred simulated cycles of one SM), so waiting threads spin
//! briefly before they yield, and the calling thread works on the round too.

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

/// Shared state of the rounds.
struct Round<T, P, F> {
    /// The function run on each chosen item.
    f: F,
    /// The items.
    items: Vec<Mutex<T>>,
    /// Which items take part in the current round.
    chosen: Vec<AtomicBool>,
    /// Pre-jobs of the current round.
    pre: AtomicUsize,
    /// Pre-jobs of the current round done.
    pre_done: AtomicUsize,
    /// Next unit to claim: pre-jobs `0..pre`, then items.
    next: AtomicUsize,
    /// Threads done with the current round.
    done: AtomicUsize,
    /// Round number; a change starts a round.
    epoch: AtomicU64,
    /// Set to end the helpers.
    stop: AtomicBool,
    /// Set when a job panicked on a helper thread.
    panicked: AtomicBool,
    /// The parameter of the current round.
    param: Mutex<Option<P>>,
}

impl<T, P, F: Fn(Unit<'_, T>, &P)> Round<T, P, F> {
    /// Claims and runs pre-jobs, then chosen items once every pre-job is done, until none is
    /// left.
    fn work(&self, param: &P) {
        let pre = self.pre.load(Ordering::Acquire);
        loop {
            let i = self.next.fetch_add(1, Ordering::AcqRel);
            if i < pre {
                (self.f)(Unit::Pre(i), param);
                self.pre_done.fetch_add(1, Ordering::AcqRel);
                continue;
            }
            let i = i - pre;
            if i >= self.items.len() {
                return;
            }
            if self.chosen[i].load(Ordering::Acquire) {
                wait(|| self.pre_done.load(Ordering::Acquire) == pre);
                (self.f)(Unit::Item(&mut lock(&self.items[i])), param);
            }
        }
    }
}

/// Locks an item's mutex (a panic in a job poisons nothing that matters: it is propagated).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
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

impl<'s, T: Send, P: Clone + Send, F: Fn(Unit<'_, T>, &P) + Sync> Workers<'s, T, P, F> {
    /// Runs `body` with workers running `f` over pre-jobs and `items` on `threads` threads in
    /// all (the caller's included; at least 1); returns its result and the items.
    pub fn with<R>(
        threads: usize,
        items: Vec<T>,
        f: F,
        body: impl FnOnce(&mut Workers<'_, T, P, F>) -> R,
    ) -> (R, Vec<T>) {
        let round = Round {
            f,
            chosen: items.iter().map(|_| AtomicBool::new(false)).collect(),
            items: items.into_iter().map(Mutex::new).collect(),
            pre: AtomicUsize::new(0),
            pre_done: AtomicUsize::new(0),
            next: AtomicUsize::new(0),
            done: AtomicUsize::new(0),
            epoch: AtomicU64::new(0),
            stop: AtomicBool::new(false),
            panicked: AtomicBool::new(false),
            param: Mutex::new(None),
        };
        let helpers = threads.max(1) - 1;
        let result = thread::scope(|scope: &Scope<'_, '_>| {
            for _ in 0..helpers {
                let round = &round;
                scope.spawn(move || helper(round));
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

    /// Runs the function with `param` on pre-jobs `0..pre` and then on every item `choose`
    /// selects, on all threads; returns when all are done.
    pub fn round(&mut self, pre: usize, choose: impl Fn(usize) -> bool, param: P) {
        let r = self.round;
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
        *lock(&r.param) = Some(param.clone());
        r.pre.store(pre, Ordering::Release);
        r.pre_done.store(0, Ordering::Release);
        r.next.store(0, Ordering::Release);
        r.done.store(0, Ordering::Release);
        r.epoch.fetch_add(1, Ordering::AcqRel);
        r.work(&param);
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

/// A helper thread: works on each round until told to stop.
fn helper<T, P: Clone, F: Fn(Unit<'_, T>, &P)>(round: &Round<T, P, F>) {
    let mut seen = 0;
    loop {
        wait(|| round.epoch.load(Ordering::Acquire) != seen);
        seen = round.epoch.load(Ordering::Acquire);
        if round.stop.load(Ordering::Acquire) {
            return;
        }
        let param = lock(&round.param).clone();
        if let Some(param) = param {
            let run = std::panic::AssertUnwindSafe(|| round.work(&param));
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
            let ((), items) = Workers::with(threads, items, add, |w| {
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
            let ((), items) = Workers::with(threads, vec![0u64; 6], f, |w| {
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
