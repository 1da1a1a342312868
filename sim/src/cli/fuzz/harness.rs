//! Running fuzz cases: each on a worker thread under a time bound, with panics caught.
//!
//! A case is sent to a long-lived worker thread (8 MB stack, like the main thread's) that runs
//! it under [`std::panic::catch_unwind`] and sends back the outcome and its duration. The
//! harness waits at most the time bound: a case that has not answered by then is a hang (a true
//! infinite loop included), and its worker is abandoned (it keeps the case and exits if the
//! case ever ends) and replaced by a new one. Panic messages, with their source location, are
//! captured by a process-wide panic hook that stays silent on worker threads only.

use std::cell::RefCell;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Once};
use std::thread;
use std::time::{Duration, Instant};

use super::targets::Outcome;

/// Name of the worker threads (the panic hook recognises them by it).
const WORKER_NAME: &str = "vtq-fuzz-worker";

/// Stack of a worker thread: the main thread's usual 8 MB, so that recursion limits are met as
/// `vtq` meets them.
const WORKER_STACK: usize = 8 << 20;

/// A parser run on one input.
pub type Target = Arc<dyn Fn(&[u8]) -> Outcome + Send + Sync>;

/// How one case ended.
#[derive(Debug, Clone, PartialEq)]
pub enum CaseEnd {
    /// The target returned within the time bound.
    Done(Outcome),
    /// The target panicked (the message, with its location).
    Panic(String),
    /// The target did not return within the time bound.
    Hang,
}

thread_local! {
    /// The last panic message of this worker thread.
    static PANIC_MESSAGE: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// Install (once per process) the hook that records panics of worker threads silently and
/// passes every other panic to the hook that was installed before.
fn install_panic_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if thread::current().name() == Some(WORKER_NAME) {
                PANIC_MESSAGE.with(|m| *m.borrow_mut() = Some(info.to_string()));
            } else {
                previous(info);
            }
        }));
    });
}

/// A worker thread and its channels.
struct Worker {
    /// Cases to run.
    cases: Sender<Vec<u8>>,
    /// Each case's end and its duration.
    results: Receiver<(CaseEnd, Duration)>,
}

impl Worker {
    /// Start a worker running `target`.
    fn spawn(target: Target) -> Worker {
        let (cases, inbox) = channel::<Vec<u8>>();
        let (outbox, results) = channel();
        thread::Builder::new()
            .name(WORKER_NAME.into())
            .stack_size(WORKER_STACK)
            .spawn(move || {
                for input in inbox {
                    let start = Instant::now();
                    let end = match catch_unwind(AssertUnwindSafe(|| target(&input))) {
                        Ok(outcome) => CaseEnd::Done(outcome),
                        Err(payload) => {
                            let hooked = PANIC_MESSAGE.with(|m| m.borrow_mut().take());
                            CaseEnd::Panic(hooked.unwrap_or_else(|| panic_text(&*payload)))
                        }
                    };
                    if outbox.send((end, start.elapsed())).is_err() {
                        break;
                    }
                }
            })
            .expect("spawning a fuzz worker thread");
        Worker { cases, results }
    }
}

/// The text of a panic payload.
fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic with a non-text payload".into())
}

/// Runs cases of one target, one at a time, each under `timeout`.
pub struct Runner {
    /// The parser under test.
    target: Target,
    /// The time bound of one case.
    timeout: Duration,
    /// The current worker.
    worker: Worker,
}

impl Runner {
    /// A runner of `target` with a time bound of `timeout` per case.
    pub fn new(target: Target, timeout: Duration) -> Runner {
        install_panic_hook();
        let worker = Worker::spawn(target.clone());
        Runner {
            target,
            timeout,
            worker,
        }
    }

    /// Run one case; returns how it ended and how long it took (the time bound for a hang).
    pub fn run(&mut self, input: &[u8]) -> (CaseEnd, Duration) {
        if self.worker.cases.send(input.to_vec()).is_err() {
            self.worker = Worker::spawn(self.target.clone());
            return self.run(input);
        }
        match self.worker.results.recv_timeout(self.timeout) {
            Ok(result) => result,
            Err(RecvTimeoutError::Timeout) => {
                // Abandon the busy worker; it exits if the case ever returns.
                self.worker = Worker::spawn(self.target.clone());
                (CaseEnd::Hang, self.timeout)
            }
            Err(RecvTimeoutError::Disconnected) => {
                self.worker = Worker::spawn(self.target.clone());
                (
                    CaseEnd::Panic("the worker thread died without an answer".into()),
                    Duration::ZERO,
                )
            }
        }
    }
}
