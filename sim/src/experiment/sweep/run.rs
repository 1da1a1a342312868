//! Running a sweep's pending points on several threads: each simulation runs on one thread (and
//! is deterministic), each record is stored the moment its run ends, and the caller hears of
//! every finished run, in completion order, on its own thread.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;

use super::key::Tier;
use super::prepared::{BvhBuilder, PreparedScene};
use super::record::RunRecord;
use super::store::ResultStore;
use crate::model::config::SimConfig;

/// One point to simulate.
#[derive(Debug, Clone, Copy)]
pub struct Task<'a> {
    /// The scene.
    pub scene: &'a PreparedScene,
    /// The effective configuration.
    pub config: &'a SimConfig,
    /// The tier to simulate it in.
    pub tier: Tier,
}

/// Simulates every task on up to `jobs` threads, storing each record in `store` as soon as it
/// is made, and calls `report(task index, record)` on the calling thread as runs finish. A
/// failed run is a failed record, not an error; the error returned is a record that could not
/// be stored (then no new run starts).
pub fn run_tasks(
    store: &ResultStore,
    tasks: &[Task],
    jobs: usize,
    build: &BvhBuilder,
    mut report: impl FnMut(usize, &RunRecord),
) -> anyhow::Result<()> {
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let (send, receive) = mpsc::channel::<(usize, anyhow::Result<RunRecord>)>();
    std::thread::scope(|s| {
        for _ in 0..jobs.clamp(1, tasks.len().max(1)) {
            let send = send.clone();
            let (next, stop) = (&next, &stop);
            s.spawn(move || {
                while !stop.load(Ordering::Relaxed) {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(task) = tasks.get(i) else {
                        return;
                    };
                    let result = task
                        .scene
                        .simulate(task.config, task.tier, build)
                        .and_then(|record| store.save(&record).map(|()| record));
                    if send.send((i, result)).is_err() {
                        return;
                    }
                }
            });
        }
        drop(send);
        let mut first_error = None;
        for (i, result) in receive {
            match result {
                Ok(record) => report(i, &record),
                Err(e) => {
                    stop.store(true, Ordering::Relaxed);
                    first_error.get_or_insert(e);
                }
            }
        }
        first_error.map_or(Ok(()), Err)
    })
}
