//! The simulator's worker threads: [`run_threads`] runs a work function on a number of
//! threads (the calling thread among them) until a flag says the run is over. The function
//! finds and runs one ready unit of work; a thread that finds none spins briefly, then yields
//! its core. Threads are not pinned to CPUs: on a 16-core machine pinning made sponza VTQ on 16
//! threads 1.25x slower (docs/performance.md).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, MutexGuard};
use std::thread;

/// Spins before a thread with nothing to do starts yielding its core.
const SPINS: u32 = 2000;

/// Locks a mutex of the engine's shared state (a panic in a job poisons nothing that matters:
/// the threads propagate it, and the data is still usable).
pub fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Runs `work(me, threads)` over and over on `threads` threads (at least 1; the calling thread
/// is thread 0) until `done` is set; `work` returns whether it found something to do. A panic
/// on any thread sets `done` and is raised again on the calling thread.
pub fn run_threads(threads: usize, done: &AtomicBool, work: impl Fn(usize, usize) -> bool + Sync) {
    let threads = threads.max(1);
    let body = |me: usize| {
        let mut idle = 0u32;
        while !done.load(Ordering::Acquire) {
            if work(me, threads) {
                idle = 0;
            } else if idle < SPINS {
                idle += 1;
                std::hint::spin_loop();
            } else {
                thread::yield_now();
            }
        }
    };
    thread::scope(|scope| {
        let helpers: Vec<_> = (1..threads)
            .map(|me| {
                let body = &body;
                scope.spawn(move || {
                    let run = std::panic::AssertUnwindSafe(|| body(me));
                    let result = std::panic::catch_unwind(run);
                    if result.is_err() {
                        done.store(true, Ordering::Release);
                    }
                    result
                })
            })
            .collect();
        let run = std::panic::AssertUnwindSafe(|| body(0));
        if let Err(p) = std::panic::catch_unwind(run) {
            done.store(true, Ordering::Release);
            std::panic::resume_unwind(p);
        }
        for h in helpers {
            if let Ok(Err(p)) = h.join() {
                std::panic::resume_unwind(p);
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicU64;

    #[test]
    fn every_thread_works_until_done_is_set() {
        for threads in [1, 2, 3, 16] {
            let done = AtomicBool::new(false);
            let count = AtomicU64::new(0);
            let seen = Mutex::new(vec![false; threads]);
            // Done once 1000 units ran and every thread (the calling one too) ran one: the
            // run ends only if every thread works.
            run_threads(threads, &done, |me, t| {
                assert_eq!(t, threads);
                let mut seen = lock(&seen);
                seen[me] = true;
                if count.fetch_add(1, Ordering::AcqRel) + 1 >= 1000 && seen.iter().all(|&s| s) {
                    done.store(true, Ordering::Release);
                }
                true
            });
            assert!(count.load(Ordering::Acquire) >= 1000);
            assert!(lock(&seen).iter().all(|&s| s));
        }
    }

    #[test]
    fn a_panic_on_a_helper_reaches_the_caller() {
        let done = AtomicBool::new(false);
        let result = std::panic::catch_unwind(|| {
            run_threads(3, &done, |me, _| {
                if me == 2 {
                    panic!("helper failed");
                }
                false
            })
        });
        assert!(result.is_err());
    }
}
