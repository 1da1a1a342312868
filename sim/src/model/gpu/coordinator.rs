//! The cycle loop's coordination: SM nodes, memory partitions and the CTA scheduler on any
//! number of threads, with no barrier between them (*bounded lag*).
//!
//! # What waits for what
//! An SM affects another only through the L2 and the CTA scheduler, and no L2 result is needed
//! before one L2 round trip after its access was accepted ([`crate::model::memory::l1`]). So:
//! - a **node** ([`SmNode`]) visits its own cycles on whatever thread claims it, as far as its
//!   L1 port's horizon (one round trip past its oldest unsettled L2 operation) and the
//!   watchdog's limit allow; as it goes it posts its L2 operations to the partitions and
//!   publishes how far it has *reached* (every visit before that cycle done, every L2
//!   operation accepted before it posted);
//! - a **memory partition** applies, in key order, the operations accepted before the cycle
//!   every node has reached ([`PartitionJobs::apply`]) — exactly the order of one loop
//!   visiting every SM each cycle, as partitions share no state — and a node takes its
//!   results and settles them as soon as they are there ([`SmNode::absorb`]);
//! - the **coordinator** (one thread at a time) serves the nodes' halts in cycle order: a CTA
//!   dispatch of cycle `t` once every node has reached past `t` or halted at `t` (the
//!   scheduler hands CTAs out round-robin over the SMs with room in the same cycle), and, once a
//!   node is idle for good, each further visit if the run has not ended by then. It ends the
//!   run after the cycle in which the last SM fell idle, reports the first error in (cycle, SM)
//!   order, and fires the watchdog when every node has reached its deadline without progress.
//!
//! A node may thus run up to one round trip ahead of the slowest node it exchanges L2 results
//! with, and further where it has no L2 operation in flight; bursts of work on different SMs
//! overlap instead of each window waiting for its slowest SM. Which thread runs what, and when,
//! changes no result: every value a node reads is final when it reads it.
//!
//! Each node and partition has a *home* thread (unit `u` of `T` threads: thread `u mod T`); a
//! thread looks at its home units first, so an SM's state (RT unit, treelet tables, L1 tags:
//! hundreds of KB) tends to stay in one core's caches.

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::{Mutex, MutexGuard, TryLockError};

use crossbeam_utils::CachePadded;

use crate::model::gpu::cta_scheduler::CtaScheduler;
use crate::model::gpu::error::SimError;
use crate::model::gpu::l2_partitions::PartitionJobs;
use crate::model::gpu::node::{Ctx, HaltKind, SmNode};
use crate::model::gpu::parallelism::{ParallelProfile, Stopwatch};
use crate::model::gpu::shader::PathThread;
use crate::model::gpu::watchdog::Watchdog;
use crate::model::gpu::workers::{lock, run_threads};

/// Cycles a node visits between two reports of how far it has reached.
const REPORT_CYCLES: u64 = 64;

/// Cycles every node must gain before a partition applies again, unless a node waits for it.
const APPLY_STEP: u64 = 64;

/// Nodes whose waits a thread looks at without allocating (more: partitions apply at every
/// chance).
const MAX_WAITS: usize = 128;

/// A node the threads may run (or running, or blocked until the L2 or the limit moves).
const RUNNABLE: u8 = 0;
/// A node halted for the coordinator.
const HALTED: u8 = 1;
/// A node stopped by an error.
const FAILED: u8 = 2;
/// A node that visits nothing more.
const DONE: u8 = 3;

/// What a node publishes for the other threads, on cache lines of its own.
#[derive(Debug)]
struct Board {
    /// Every visit before this cycle is done and its L2 operations posted (a halted or failed
    /// node: the cycle of the halt or error).
    reached: AtomicU64,
    /// [`RUNNABLE`], [`HALTED`], [`FAILED`] or [`DONE`].
    stop: AtomicU8,
    /// A blocked node may go on once memory partition `wait_part` has applied everything
    /// before this cycle (`u64::MAX`: not by the L2).
    wait_applied: AtomicU64,
    /// The partition of its oldest unsettled L2 operation.
    wait_part: AtomicU64,
    /// ... or once the watchdog's limit is above this cycle (`u64::MAX`: not by the limit).
    wait_limit: AtomicU64,
    /// [`SmNode::idle_since`] (`u64::MAX`: it holds CTAs).
    idle_since: AtomicU64,
    /// [`SmNode::last_progress`].
    last_progress: AtomicU64,
    /// Pixels it finished.
    pixels: AtomicU64,
}

impl Board {
    /// The board of a node that has not started.
    fn new() -> Self {
        Board {
            reached: AtomicU64::new(0),
            stop: AtomicU8::new(RUNNABLE),
            wait_applied: AtomicU64::new(0),
            wait_part: AtomicU64::new(0),
            wait_limit: AtomicU64::new(0),
            idle_since: AtomicU64::new(0),
            last_progress: AtomicU64::new(0),
            pixels: AtomicU64::new(0),
        }
    }
}

/// What only the coordinator touches.
struct Coord<'r> {
    scheduler: CtaScheduler,
    watchdog: Watchdog,
    progress: Option<&'r indicatif::ProgressBar>,
    /// The run's outcome once known: the cycle count or the error.
    outcome: Option<Result<u64, SimError>>,
    /// CPU time of the coordinator's work (profiled runs).
    ns: u64,
}

/// Everything the threads share.
struct Shared<'r, 'a> {
    ctx: &'r Ctx<'a>,
    l2: &'r PartitionJobs,
    nodes: Vec<CachePadded<Mutex<SmNode<'a>>>>,
    boards: Vec<CachePadded<Board>>,
    /// Per partition: every operation before this cycle is applied and its results are in
    /// the SMs' slots.
    through: Vec<CachePadded<AtomicU64>>,
    /// No node visits this cycle or later (the watchdog's deadline as last raised).
    limit: CachePadded<AtomicU64>,
    /// CTAs are pending at the scheduler.
    pending: AtomicBool,
    /// The run is over.
    done: AtomicBool,
    coord: Mutex<Coord<'r>>,
    /// Nanoseconds of one clock read, taken out of each measurement (profiled runs).
    read_ns: u64,
    /// Every thread has a core of its own: nodes stay on their home threads.
    home_only: bool,
    /// Nodes halted or failed (the coordinator has work while any is).
    stopped: CachePadded<AtomicU64>,
    /// Events that may give the coordinator work: a node fell idle, is idle, or is blocked
    /// by the limit.
    events: CachePadded<AtomicU64>,
    /// The events the coordinator last looked at with nothing to do.
    seen: CachePadded<AtomicU64>,
}

/// The outcome of [`run`]: the cycle count or the first error, the nodes, and the profile.
pub struct Outcome<'a> {
    /// The cycle count or the first error.
    pub cycles: Result<u64, SimError>,
    /// The nodes as the run left them.
    pub nodes: Vec<SmNode<'a>>,
    /// The parallelism report's timings (profiled runs).
    pub profile: Option<ParallelProfile>,
}

/// Runs `nodes` on `threads` threads until the last SM falls idle with no CTA pending (or an
/// error or the watchdog stops the run); every L2 operation posted is applied at the end.
pub fn run<'a>(
    ctx: &Ctx<'a>,
    l2: &PartitionJobs,
    nodes: Vec<SmNode<'a>>,
    scheduler: CtaScheduler,
    threads: usize,
    progress: Option<&indicatif::ProgressBar>,
) -> Outcome<'a> {
    let watchdog = Watchdog::new(ctx.cfg.sim.watchdog_cycles);
    let mut profile = ctx.profile.then(ParallelProfile::new);
    let pending = scheduler.pending() > 0;
    let shared = Shared {
        ctx,
        l2,
        boards: nodes
            .iter()
            .map(|_| CachePadded::new(Board::new()))
            .collect(),
        nodes: nodes
            .into_iter()
            .map(|n| CachePadded::new(Mutex::new(n)))
            .collect(),
        through: (0..l2.len())
            .map(|_| CachePadded::new(AtomicU64::new(0)))
            .collect(),
        limit: CachePadded::new(AtomicU64::new(watchdog.deadline())),
        pending: AtomicBool::new(pending),
        done: AtomicBool::new(false),
        coord: Mutex::new(Coord {
            scheduler,
            watchdog,
            progress,
            outcome: None,
            ns: 0,
        }),
        read_ns: profile.as_ref().map_or(0, ParallelProfile::read_ns),
        home_only: std::thread::available_parallelism().is_ok_and(|n| threads <= n.get()),
        stopped: CachePadded::new(AtomicU64::new(0)),
        events: CachePadded::new(AtomicU64::new(1)),
        seen: CachePadded::new(AtomicU64::new(0)),
    };
    let total = Stopwatch::start(ctx.profile);
    let reads_before = crate::model::gpu::parallelism::clock_reads();
    run_threads(threads.max(1), &shared.done, |me, t| shared.work(me, t));
    let total_ns = total.ns();
    let coord = shared.coord.into_inner().unwrap_or_else(|e| e.into_inner());
    let cycles = coord
        .outcome
        .expect("the threads stop only once the run has an outcome");
    // Every L2 operation posted counts in the L2 and DRAM statistics (nobody takes the
    // results of those the run ended before).
    if cycles.is_ok() {
        for p in 0..l2.len() {
            l2.apply(p, u64::MAX, false);
        }
    }
    let nodes: Vec<SmNode<'a>> = shared
        .nodes
        .into_iter()
        .map(|m| {
            CachePadded::into_inner(m)
                .into_inner()
                .unwrap_or_else(|e| e.into_inner())
        })
        .collect();
    if let Some(p) = &mut profile {
        let read = p.read_ns();
        p.set_stretches(
            nodes.iter().map(|n| n.stretches.as_slice()),
            crate::model::memory::L1Port::round_trip(&ctx.cfg.memory),
        );
        p.set_units(
            nodes
                .iter()
                .map(|n| n.stretches.iter().map(|s| s.2).sum())
                .collect(),
            (0..l2.len())
                .map(|j| {
                    let (ns, applies) = l2.apply_ns(j);
                    ns.saturating_sub(applies * read)
                })
                .collect(),
        );
        p.set_serial(coord.ns);
        p.set_total(total_ns, reads_before);
    }
    Outcome {
        cycles,
        nodes,
        profile,
    }
}

/// Units `0..n` in the order thread `me` of `t` looks at them: its home units, then the others.
fn order(n: usize, me: usize, t: usize) -> impl Iterator<Item = usize> {
    (me..n)
        .step_by(t)
        .chain((0..n).filter(move |u| u % t != me))
}

/// Locks `m` unless another thread holds it.
fn try_lock<T>(m: &Mutex<T>) -> Option<MutexGuard<'_, T>> {
    match m.try_lock() {
        Ok(g) => Some(g),
        Err(TryLockError::Poisoned(e)) => Some(e.into_inner()),
        Err(TryLockError::WouldBlock) => None,
    }
}

impl<'a> Shared<'_, 'a> {
    /// Thread `me` of `t`: runs one unit of work that is ready (a partition, a node, the
    /// coordinator); false if it found none.
    fn work(&self, me: usize, t: usize) -> bool {
        let g = self.reached_min();
        let mut waits = [(0u64, 0u64); MAX_WAITS];
        for (w, b) in waits.iter_mut().zip(self.boards.iter()) {
            *w = (
                b.wait_applied.load(Ordering::Acquire),
                b.wait_part.load(Ordering::Acquire),
            );
        }
        let waits = &waits[..self.boards.len().min(MAX_WAITS)];
        for p in order(self.through.len(), me, t) {
            let done = self.through[p].load(Ordering::Acquire);
            // Apply in steps, or sooner where a node waits for an operation of this partition
            // that every node has passed.
            if g > done
                && (g >= done.saturating_add(APPLY_STEP)
                    || self.boards.len() > MAX_WAITS
                    || waits
                        .iter()
                        .any(|&(w, q)| q == p as u64 && w > done && w <= g))
            {
                if let Some(now) = self.l2.apply(p, g, self.ctx.profile) {
                    self.through[p].store(now, Ordering::Release);
                    return true;
                }
            }
        }
        // With a core for every node's thread, a node stays on its home thread: moving its
        // state to another core costs more than the wait (on 16 cores, sponza VTQ took 6.5 s
        // with stealing and 4.1 s without). With more threads than cores a thread may be
        // descheduled for a whole time slice, so others take its node.
        let home_only = self.home_only && t >= self.nodes.len();
        for i in order(self.nodes.len(), me, t) {
            if home_only && i % t != me {
                continue;
            }
            if self.runnable(i) {
                if let Some(mut node) = try_lock(&self.nodes[i]) {
                    if self.runnable(i) {
                        self.run_node(&mut node);
                        return true;
                    }
                }
            }
        }
        let events = self.events.load(Ordering::Acquire);
        if self.stopped.load(Ordering::Acquire) == 0 && events == self.seen.load(Ordering::Acquire)
        {
            return false;
        }
        if let Some(mut c) = try_lock(&self.coord) {
            if self.done.load(Ordering::Acquire) {
                return false;
            }
            let watch = Stopwatch::start(self.ctx.profile);
            let did = self.coordinate(&mut c);
            if !did {
                self.seen.fetch_max(events, Ordering::AcqRel);
            }
            c.ns += watch.ns().saturating_sub(self.read_ns);
            return did;
        }
        false
    }

    /// The cycle every node has reached.
    fn reached_min(&self) -> u64 {
        self.boards
            .iter()
            .map(|b| b.reached.load(Ordering::Acquire))
            .min()
            .unwrap_or(u64::MAX)
    }

    /// Whether node `i` may have work: not stopped, and not blocked or no longer blocked.
    fn runnable(&self, i: usize) -> bool {
        let b = &self.boards[i];
        let wait_applied = b.wait_applied.load(Ordering::Acquire);
        b.stop.load(Ordering::Acquire) == RUNNABLE
            && ((wait_applied != u64::MAX
                && self.through[b.wait_part.load(Ordering::Acquire) as usize]
                    .load(Ordering::Acquire)
                    >= wait_applied)
                || self.limit.load(Ordering::Acquire) > b.wait_limit.load(Ordering::Acquire))
    }

    /// Runs a node as far as it can go: visits in stretches of [`REPORT_CYCLES`], posting
    /// its L2 operations and publishing how far it reached after each, and settling L2
    /// results as they arrive; then publishes why it stopped.
    fn run_node(&self, node: &mut SmNode<'a>) {
        let ctx = self.ctx;
        let watch = Stopwatch::start(ctx.profile);
        let lockstep = ctx.cfg.sim.lockstep;
        let pending = self.pending.load(Ordering::Acquire);
        let limit = self.limit.load(Ordering::Acquire);
        let b = &self.boards[node.index];
        b.wait_applied.store(0, Ordering::Release);
        b.wait_limit.store(0, Ordering::Release);
        let from = node.halt.map_or(node.next, |h| h.cycle);
        loop {
            if node.halt.is_none() && self.can_absorb(node) {
                node.absorb(self.l2, lockstep, pending);
            }
            let end = limit.min(node.next.saturating_add(REPORT_CYCLES));
            node.run(ctx, end, pending);
            self.publish(node, limit);
            if node.error.is_some() || node.halt.is_some() {
                break;
            }
            if node.next >= limit.min(node.mem.horizon()) && !self.can_absorb(node) {
                break;
            }
        }
        if let Some((c, _)) = node.error {
            b.reached.store(c, Ordering::Release);
            b.stop.store(FAILED, Ordering::Release);
            self.stopped.fetch_add(1, Ordering::AcqRel);
        } else if let Some(h) = node.halt {
            b.reached.store(h.cycle, Ordering::Release);
            b.stop.store(HALTED, Ordering::Release);
            self.stopped.fetch_add(1, Ordering::AcqRel);
        } else {
            let ops = node.mem.ops();
            let wait_applied = ops.first().map_or(u64::MAX, |op| op.cycle + 1);
            let wait_part = ops.first().map_or(0, |op| self.l2.partition(op.line));
            b.wait_part.store(wait_part as u64, Ordering::Release);
            let free = node.next.min(node.mem.horizon());
            let wait_limit = if free >= limit && free != u64::MAX {
                limit
            } else {
                u64::MAX
            };
            b.wait_applied.store(wait_applied, Ordering::Release);
            b.wait_limit.store(wait_limit, Ordering::Release);
            if wait_limit != u64::MAX || node.idle_since.is_some() {
                self.events.fetch_add(1, Ordering::AcqRel);
            }
        }
        if ctx.profile {
            let ns = watch.ns().saturating_sub(self.read_ns);
            let reached = b.reached.load(Ordering::Acquire);
            node.stretches.push((from, reached, ns));
        }
    }

    /// Whether the L2 has applied the node's oldest unsettled operation.
    fn can_absorb(&self, node: &SmNode) -> bool {
        node.mem.ops().first().is_some_and(|op| {
            self.through[self.l2.partition(op.line)].load(Ordering::Acquire) > op.cycle
        })
    }

    /// Posts the node's new L2 operations and publishes how far it reached (all its visits
    /// before it done: its next visit, its horizon or the limit, whichever comes first; a
    /// halted or failed node publishes that when it stops).
    fn publish(&self, node: &mut SmNode, limit: u64) {
        let ops = node.mem.ops();
        let new = (node.posted - node.mem.first_op()) as usize;
        if new < ops.len() {
            self.l2.post(node.index, &ops[new..]);
            node.posted = node.mem.first_op() + ops.len() as u64;
        }
        let b = &self.boards[node.index];
        b.idle_since
            .store(node.idle_since.unwrap_or(u64::MAX), Ordering::Release);
        b.last_progress.store(node.last_progress, Ordering::Release);
        b.pixels.store(node.pixels.len() as u64, Ordering::Release);
        if node.error.is_none() && node.halt.is_none() {
            // A node with no visit to come and no L2 operation in flight has reached the end.
            let free = node.next.min(node.mem.horizon());
            let reached = if free == u64::MAX {
                free
            } else {
                free.min(limit)
            };
            b.reached.fetch_max(reached, Ordering::AcqRel);
        }
    }

    /// Ends the run with `outcome`.
    fn finish(&self, c: &mut Coord, outcome: Result<u64, SimError>) {
        c.outcome = Some(outcome);
        self.done.store(true, Ordering::Release);
    }

    /// The coordinator's work, if any is ready: raising the watchdog's limit, serving the
    /// earliest halts or error, ending the run, firing the watchdog. False if none was.
    fn coordinate(&self, c: &mut Coord) -> bool {
        let n = self.nodes.len();
        let lp = self
            .boards
            .iter()
            .map(|b| b.last_progress.load(Ordering::Acquire))
            .max()
            .unwrap_or(0);
        c.watchdog.progress(lp);
        if let Some(bar) = c.progress {
            let pixels: u64 = self
                .boards
                .iter()
                .map(|b| b.pixels.load(Ordering::Acquire))
                .sum();
            bar.set_position(pixels);
        }
        let limit = self.limit.load(Ordering::Acquire);
        let deadline = c.watchdog.deadline();
        if deadline > limit {
            self.limit.store(deadline, Ordering::Release);
            return true;
        }
        // Stop flags first: a node publishes its reached cycle before it stops.
        let stops: Vec<u8> = self
            .boards
            .iter()
            .map(|b| b.stop.load(Ordering::Acquire))
            .collect();
        let reached: Vec<u64> = self
            .boards
            .iter()
            .map(|b| b.reached.load(Ordering::Acquire))
            .collect();
        let stopped = |i: usize| stops[i] == HALTED || stops[i] == FAILED;
        if let Some(t) = (0..n).filter(|&i| stopped(i)).map(|i| reached[i]).min() {
            if (0..n).all(|i| stopped(i) || reached[i] > t) {
                let at: Vec<usize> = (0..n).filter(|&i| stopped(i) && reached[i] == t).collect();
                self.serve(c, t, &at, &stops);
                return true;
            }
        }
        let idle: Vec<u64> = self
            .boards
            .iter()
            .map(|b| b.idle_since.load(Ordering::Acquire))
            .collect();
        if c.scheduler.pending() == 0 && idle.iter().all(|&s| s != u64::MAX) {
            let end = idle.iter().copied().max().unwrap_or(0) + 1;
            if (0..n).all(|i| !stopped(i) && reached[i] >= end) {
                self.finish(c, Ok(end));
                return true;
            }
        }
        if reached.iter().all(|&r| r >= limit) && deadline <= limit {
            let e = self.watchdog_error(c, limit);
            self.finish(c, Err(e));
            return true;
        }
        false
    }

    /// Serves the halts and errors of cycle `t` (nodes `at`, whose stop flags are in `stops`):
    /// the first error in SM order ends the run; otherwise the CTA dispatch of cycle `t`, and
    /// each halted node goes on unless it is idle for good and the run has ended by `t`.
    fn serve(&self, c: &mut Coord, t: u64, at: &[usize], stops: &[u8]) {
        if let Some(&i) = at.iter().find(|&&i| stops[i] == FAILED) {
            let (_, e) = lock(&self.nodes[i])
                .error
                .take()
                .expect("a failed node holds its error");
            self.finish(c, Err(e));
            return;
        }
        let mut halted: Vec<MutexGuard<'_, SmNode<'a>>> =
            at.iter().map(|&i| lock(&self.nodes[i])).collect();
        let dispatch: Vec<usize> = halted
            .iter()
            .enumerate()
            .filter(|(_, n)| n.halt.is_some_and(|h| h.kind == HaltKind::Dispatch))
            .map(|(k, _)| k)
            .collect();
        if !dispatch.is_empty() {
            self.dispatch(c, t, &mut halted, &dispatch);
        }
        let pending = c.scheduler.pending() > 0;
        self.pending.store(pending, Ordering::Release);
        // Visits of nodes idle for good happen only if the run goes on past cycle t: some CTA
        // is pending, or some SM holds CTAs or fell idle at t or later (as each last published).
        let goes_on = pending
            || self.boards.iter().any(|b| {
                let s = b.idle_since.load(Ordering::Acquire);
                s == u64::MAX || s >= t
            });
        for node in &mut halted {
            let b = &self.boards[node.index];
            if goes_on || pending || !node.sm.is_idle() {
                b.wait_applied.store(0, Ordering::Release);
                b.wait_limit.store(0, Ordering::Release);
                b.stop.store(RUNNABLE, Ordering::Release);
            } else {
                // Beyond the end of the run: the visit never happens.
                node.halt = None;
                node.next = u64::MAX;
                b.reached.store(u64::MAX, Ordering::Release);
                b.stop.store(DONE, Ordering::Release);
                self.events.fetch_add(1, Ordering::AcqRel);
            }
            self.stopped.fetch_sub(1, Ordering::AcqRel);
        }
    }

    /// Hands pending CTAs out at cycle `t` to the nodes halted for them (`halted[k]` for `k` in
    /// `dispatch`, in SM order), round-robin over the SMs; new CTAs' warps trace after launch
    /// and raygen.
    fn dispatch(
        &self,
        c: &mut Coord,
        t: u64,
        halted: &mut [MutexGuard<'_, SmNode<'a>>],
        dispatch: &[usize],
    ) {
        let ctx = self.ctx;
        let mut free = vec![0; self.nodes.len()];
        for &k in dispatch {
            free[halted[k].index] = halted[k].sm.launchable();
        }
        let start = t + ctx.cfg.gpu.cta_launch_cycles as u64 + ctx.timing.raygen;
        let warp_size = ctx.cfg.gpu.warp_size as usize;
        let sampler = ctx.sampler();
        for (sm, cta) in c.scheduler.dispatch(&mut free) {
            let node = halted
                .iter_mut()
                .find(|n| n.index == sm)
                .expect("the scheduler hands CTAs only to SMs with room");
            // A thread none of whose samples traces a ray (a hybrid frame's) finishes at launch.
            let threads: Vec<Option<PathThread>> = (c.scheduler.pixels(cta).into_iter())
                .map(|p| match PathThread::new(&sampler, p?) {
                    Ok(thread) => Some(thread),
                    Err(done) => {
                        node.finish_pixel(done);
                        None
                    }
                })
                .collect();
            let warps = threads.chunks(warp_size).map(<[_]>::to_vec).collect();
            node.sm.launch(cta, warps, start);
        }
    }

    /// The watchdog's error at cycle `cycle` with every component's state.
    fn watchdog_error(&self, c: &Coord, cycle: u64) -> SimError {
        let mut dump = format!(
            "CTA scheduler: {} of {} CTAs not dispatched\n",
            c.scheduler.pending(),
            c.scheduler.total()
        );
        let virtualization = self.ctx.cfg.mode.virtualization;
        for node in &self.nodes {
            dump += &lock(node).debug_state(virtualization, cycle);
        }
        dump += &format!("memory: {}\n", self.l2.debug_state(cycle));
        SimError::Watchdog {
            cycle,
            last_progress: c.watchdog.last_progress(),
            dump,
        }
    }
}
