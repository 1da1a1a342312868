//! The parallelism report ([`ParallelProfile`]): measured in a one-thread run, it times every
//! round of node visits per SM, every round of L2 partitions and every serial section of the
//! engine (L2 hand-over, CTA dispatch and halts, the rest of the bookkeeping), and predicts the
//! speedup on `N` threads by the work-span bound: the one-thread time over the serial time plus,
//! for every round, its critical path when its units (in the order the worker threads claim
//! them) are list-scheduled onto `N` threads.
//!
//! Times are the thread's CPU time, so a busy machine (preemption) does not inflate them.
//! The prediction is an upper bound of what the engine's structure allows: it counts no cost
//! for handing a round to other threads, for cache traffic between cores or for a busy machine.
//! `vtq bench --sim --parallelism` prints it (docs/performance.md).

use std::fmt::Write as _;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Thread counts the report predicts.
pub const PREDICTED_THREADS: [usize; 6] = [1, 2, 4, 8, 16, 32];

/// Serial sections of the engine, timed separately.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Serial {
    /// Ending a window: whether L2 operations wait, the next window's start, progress.
    WindowEnd,
    /// Serving halts: CTA dispatch, deciding which halted nodes go on.
    Halts,
    /// The rest of the loop: window bookkeeping, the watchdog, the progress bar.
    Other,
}

/// Names of the [`Serial`] sections, in declaration order.
const SERIAL_NAMES: [&str; 3] = [
    "window end (L2 operations waiting, next start, progress)",
    "halts (CTA dispatch, which halted SMs go on)",
    "other (window bookkeeping, watchdog, progress)",
];

/// Kinds of parallel rounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RoundKind {
    /// The first round of a window: every SM visits its cycles.
    Window,
    /// A round after serving halts: the halted SMs go on.
    AfterHalt,
    /// The L2 partitions apply the last window's operations (pre-jobs of a window's first
    /// round: the SMs start when all are done; one partition is serial work).
    L2,
}

/// Names of the [`RoundKind`]s, in declaration order.
const ROUND_NAMES: [&str; 3] = [
    "SM visits, first round of a window",
    "SM visits after a halt",
    "L2 partitions",
];

/// Timings of a one-thread run, gathered as it goes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ParallelProfile {
    /// Nanoseconds in each [`Serial`] section.
    serial_ns: [u64; 3],
    /// Rounds of each [`RoundKind`].
    rounds: [u64; 3],
    /// Units run in rounds of each kind.
    units: [u64; 3],
    /// Nanoseconds of work in rounds of each kind (the units' times).
    work_ns: [u64; 3],
    /// Per predicted thread count: the sum over rounds of the round's makespan.
    span_ns: [u64; PREDICTED_THREADS.len()],
    /// The longest unit of each kind.
    longest_unit_ns: [u64; 3],
    /// Per unit index (SM), its work in first rounds of windows.
    per_unit_ns: Vec<u64>,
    /// Sum over first rounds of windows of their longest unit.
    window_max_ns: u64,
    /// Windows run.
    windows: u64,
    /// Time of the whole engine loop, less the profiling's own clock reads.
    total_ns: u64,
    /// The clock reads' estimated time, taken out of `total_ns`.
    clock_ns: u64,
    /// Nanoseconds of one clock read: a measured unit or section holds about one, taken out.
    read_ns: u64,
}

/// A stopwatch of the calling thread's CPU time (on Unix; wall time elsewhere), so that time
/// the thread spends preempted on a busy machine does not count as work.
#[derive(Debug)]
pub struct Stopwatch(Option<u64>);

/// Clock reads made by stopwatches (their cost is taken out of the report).
static CLOCK_READS: AtomicU64 = AtomicU64::new(0);

impl Stopwatch {
    /// Starts timing if `on` (a profiled run).
    pub fn start(on: bool) -> Self {
        Stopwatch(on.then(|| {
            CLOCK_READS.fetch_add(1, Ordering::Relaxed);
            thread_ns()
        }))
    }

    /// Nanoseconds since the start (0 when not timing).
    pub fn ns(&self) -> u64 {
        self.0.map_or(0, |t| {
            CLOCK_READS.fetch_add(1, Ordering::Relaxed);
            thread_ns().saturating_sub(t)
        })
    }
}

/// Nanoseconds one clock read takes, measured over 10,000 reads.
fn clock_read_ns() -> f64 {
    const READS: u32 = 10_000;
    let start = thread_ns();
    let mut last = start;
    for _ in 0..READS {
        last = std::hint::black_box(thread_ns());
    }
    last.saturating_sub(start) as f64 / f64::from(READS)
}

/// The calling thread's CPU time in nanoseconds.
#[cfg(unix)]
fn thread_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid timespec for clock_gettime to write.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    if rc != 0 {
        return wall_ns();
    }
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// The calling thread's CPU time in nanoseconds (wall time where no thread clock is used).
#[cfg(not(unix))]
fn thread_ns() -> u64 {
    wall_ns()
}

/// Nanoseconds of wall time since the first call.
fn wall_ns() -> u64 {
    static START: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
    START.get_or_init(Instant::now).elapsed().as_nanos() as u64
}

impl ParallelProfile {
    /// An empty profile, with the cost of a clock read measured.
    pub fn new() -> Self {
        ParallelProfile {
            read_ns: clock_read_ns() as u64,
            ..ParallelProfile::default()
        }
    }

    /// Adds `ns` (as a stopwatch measured it) to serial section `s`.
    pub fn serial(&mut self, s: Serial, ns: u64) {
        self.serial_ns[s as usize] += ns.saturating_sub(self.read_ns);
    }

    /// Counts one window.
    pub fn window(&mut self) {
        self.windows += 1;
    }

    /// Sets the time of the whole loop, taking out the estimated cost of the clock reads made
    /// since the profile was created (`reads_before`: [`clock_reads`] then).
    pub fn set_total(&mut self, ns: u64, reads_before: u64) {
        let reads = clock_reads().saturating_sub(reads_before);
        self.clock_ns = reads * self.read_ns;
        self.total_ns = ns.saturating_sub(self.clock_ns);
    }

    /// One round of kind `kind` whose units took `units` nanoseconds each (as stopwatches
    /// measured them), in the order the worker threads claim them.
    pub fn round(&mut self, kind: RoundKind, units: &[u64]) {
        if units.is_empty() {
            return;
        }
        let units: Vec<u64> = units
            .iter()
            .map(|u| u.saturating_sub(self.read_ns))
            .collect();
        let units = &units[..];
        let k = kind as usize;
        if kind == RoundKind::Window {
            if self.per_unit_ns.len() < units.len() {
                self.per_unit_ns.resize(units.len(), 0);
            }
            for (total, &u) in self.per_unit_ns.iter_mut().zip(units) {
                *total += u;
            }
            self.window_max_ns += units.iter().copied().max().unwrap_or(0);
        }
        self.rounds[k] += 1;
        self.units[k] += units.len() as u64;
        self.work_ns[k] += units.iter().sum::<u64>();
        self.longest_unit_ns[k] = self.longest_unit_ns[k].max(*units.iter().max().unwrap_or(&0));
        for (span, &threads) in self.span_ns.iter_mut().zip(&PREDICTED_THREADS) {
            *span += makespan(units, threads);
        }
    }

    /// Nanoseconds of serial work: the timed serial sections plus whatever of the loop's wall
    /// time no round or section accounts for (the hand-over of rounds to the workers).
    pub fn serial_total_ns(&self) -> u64 {
        let timed: u64 = self.serial_ns.iter().sum::<u64>() + self.work_ns.iter().sum::<u64>();
        self.serial_ns.iter().sum::<u64>() + self.total_ns.saturating_sub(timed)
    }

    /// The one-thread time the prediction starts from: serial time plus all work.
    pub fn one_thread_ns(&self) -> u64 {
        self.serial_total_ns() + self.work_ns.iter().sum::<u64>()
    }

    /// Predicted time on `PREDICTED_THREADS[i]` threads.
    fn predicted_ns(&self, i: usize) -> u64 {
        self.serial_total_ns() + self.span_ns[i]
    }

    /// Predicted speedups over one thread, one per entry of [`PREDICTED_THREADS`].
    pub fn predicted_speedups(&self) -> Vec<(usize, f64)> {
        let one = self.one_thread_ns().max(1) as f64;
        PREDICTED_THREADS
            .iter()
            .enumerate()
            .map(|(i, &n)| (n, one / self.predicted_ns(i).max(1) as f64))
            .collect()
    }

    /// The report as text: where the one-thread time goes and the predicted speedups.
    pub fn report(&self) -> String {
        let one = self.one_thread_ns().max(1) as f64;
        let pct = |ns: u64| 100.0 * ns as f64 / one;
        let ms = |ns: u64| ns as f64 / 1e6;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "parallelism (one-thread run, {} windows, {:.1} ms in the engine loop):",
            self.windows,
            ms(self.total_ns)
        );
        for (k, name) in ROUND_NAMES.iter().enumerate() {
            if self.rounds[k] == 0 {
                continue;
            }
            let _ = writeln!(
                s,
                "  parallel  {name}: {:.1} ms ({:.1}%), {} rounds, {} units, mean unit {:.1} us, \
                 longest {:.1} us",
                ms(self.work_ns[k]),
                pct(self.work_ns[k]),
                self.rounds[k],
                self.units[k],
                self.work_ns[k] as f64 / self.units[k].max(1) as f64 / 1e3,
                self.longest_unit_ns[k] as f64 / 1e3
            );
        }
        for (k, name) in SERIAL_NAMES.iter().enumerate() {
            let ns = if k == Serial::Other as usize {
                self.serial_total_ns() - self.serial_ns.iter().sum::<u64>() + self.serial_ns[k]
            } else {
                self.serial_ns[k]
            };
            if ns > 0 || k == Serial::Other as usize {
                let _ = writeln!(s, "  serial    {name}: {:.1} ms ({:.1}%)", ms(ns), pct(ns));
            }
        }
        let _ = writeln!(
            s,
            "  (the profile's own {:.1} ms of clock reads taken out of the loop's time)",
            ms(self.clock_ns)
        );
        let _ = writeln!(
            s,
            "  serial in all: {:.1}% (Amdahl's limit {:.1}x)",
            pct(self.serial_total_ns()),
            one / self.serial_total_ns().max(1) as f64
        );
        if let (Some(&max), Some(&min)) =
            (self.per_unit_ns.iter().max(), self.per_unit_ns.iter().min())
        {
            let sms = self.per_unit_ns.len() as u64;
            let mean = self.per_unit_ns.iter().sum::<u64>() / sms;
            let _ = writeln!(
                s,
                "  balance: work per SM over the run {:.1} / {:.1} / {:.1} ms (least / mean / \
                 most); in a window the slowest SM takes {:.2}x the mean; without a barrier per \
                 window the SM visits could take as little as the busiest SM's {:.1} ms",
                ms(min),
                ms(mean),
                ms(max),
                self.window_max_ns as f64 / mean.max(1) as f64,
                ms(max),
            );
        }
        let speedups: Vec<String> = self
            .predicted_speedups()
            .iter()
            .skip(1)
            .map(|(n, x)| format!("{n}: {x:.2}x"))
            .collect();
        let _ = writeln!(
            s,
            "  predicted speedup (work-span bound; threads: speedup): {}",
            speedups.join(", ")
        );
        s
    }
}

/// Clock reads made by stopwatches so far (in every thread).
pub fn clock_reads() -> u64 {
    CLOCK_READS.load(Ordering::Relaxed)
}

/// Time to run `units` (in claim order, each thread taking the next unit when it is free) on
/// `threads` threads.
fn makespan(units: &[u64], threads: usize) -> u64 {
    if threads <= 1 {
        return units.iter().sum();
    }
    if threads >= units.len() {
        return units.iter().copied().max().unwrap_or(0);
    }
    let mut free = vec![0u64; threads];
    for &u in units {
        let (i, _) = free
            .iter()
            .enumerate()
            .min_by_key(|&(_, &t)| t)
            .expect("at least one thread");
        free[i] += u;
    }
    free.into_iter().max().unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn makespan_is_list_scheduling_in_claim_order() {
        assert_eq!(makespan(&[5, 3, 2, 4], 1), 14);
        // Threads: [5] [3, 2, 4]? No: 3 then 2 go to the free thread (t=3, t=5); 4 goes to the
        // earliest free, thread 0 at 5 or thread 1 at 5 (the first): 9.
        assert_eq!(makespan(&[5, 3, 2, 4], 2), 9);
        assert_eq!(makespan(&[5, 3, 2, 4], 4), 5);
        assert_eq!(makespan(&[5, 3, 2, 4], 32), 5);
        assert_eq!(makespan(&[], 2), 0);
    }

    #[test]
    fn prediction_follows_amdahl_for_even_units() {
        let mut p = ParallelProfile::default();
        // 100 rounds of 16 equal units of 10 ns, 400 ns serial.
        for _ in 0..100 {
            p.round(RoundKind::Window, &[10; 16]);
        }
        p.serial(Serial::Halts, 400);
        p.total_ns = 16_400;
        let s = p.predicted_speedups();
        assert_eq!(s[0], (1, 1.0));
        // 16 threads: 400 + 100 x 10 = 1,400 ns against 16,400.
        let (n, x) = s[4];
        assert_eq!(n, 16);
        assert!((x - 16_400.0 / 1_400.0).abs() < 1e-9, "{x}");
        // 32 threads gain nothing over 16 with 16 units a round.
        assert_eq!(s[5].1, x);
        assert!(p.report().contains("predicted speedup"));
    }

    #[test]
    fn unaccounted_loop_time_counts_as_serial() {
        let mut p = ParallelProfile::default();
        p.round(RoundKind::AfterHalt, &[100, 100]);
        p.serial(Serial::WindowEnd, 50);
        p.total_ns = 300;
        // 300 - 200 - 50 = 50 ns of hand-over on top of the 50 timed.
        assert_eq!(p.serial_total_ns(), 100);
        assert_eq!(p.one_thread_ns(), 300);
    }
}
