//! The parallelism report ([`ParallelProfile`]): measured in a one-thread run, it times the
//! work of every SM node (per stretch of simulated cycles), of every memory partition and of the
//! coordinator (halts, CTA dispatch, the end of the run, the watchdog), and predicts the speedup
//! on `N` threads by a work-span bound: the one-thread time over the serial time plus the larger
//! of the parallel work spread over `N` threads and the *lagged span*. The lagged span replays
//! the nodes' measured work with a thread per node under the bounded-lag rule of
//! [`crate::model::gpu::coordinator`]: time is cut into buckets of a quarter L2 round trip, and a node
//! starts a bucket once it has finished the one before and every node has finished the bucket
//! four before (a node may run one round trip past the slowest).
//!
//! Times are the thread's CPU time, so a busy machine (preemption) does not inflate them.
//! The prediction is an upper bound: it counts no cost for handing work between threads, for
//! cache traffic between cores or for a busy machine, and lets a node with no L2 operation in
//! flight wait as if it had one.
//! `vtq bench --sim --parallelism` prints it (docs/performance.md).

use std::fmt::Write as _;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Thread counts the report predicts.
pub const PREDICTED_THREADS: [usize; 6] = [1, 2, 4, 8, 16, 32];

/// Timings of a one-thread run.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ParallelProfile {
    /// Per SM node, nanoseconds of its visits (and settling, posting, publishing).
    per_sm_ns: Vec<u64>,
    /// Per memory partition, nanoseconds of its applies.
    per_partition_ns: Vec<u64>,
    /// Nanoseconds of the coordinator's work.
    coordinator_ns: u64,
    /// Time of the whole loop, less the profiling's own clock reads.
    total_ns: u64,
    /// The clock reads' estimated time, taken out of `total_ns`.
    clock_ns: u64,
    /// Nanoseconds of one clock read: a measured unit holds about one per measurement.
    read_ns: u64,
    /// The lagged span: the nodes' work replayed with a thread each under bounded lag.
    lagged_span_ns: u64,
}

/// Buckets per L2 round trip in the lagged span (a node may be this many buckets ahead).
const LAG_BUCKETS: u64 = 4;

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

    /// Nanoseconds of one clock read (to take out of each measurement).
    pub fn read_ns(&self) -> u64 {
        self.read_ns
    }

    /// Sets the work of each SM node and of each memory partition (already less their clock
    /// reads).
    pub fn set_units(&mut self, per_sm_ns: Vec<u64>, per_partition_ns: Vec<u64>) {
        self.per_sm_ns = per_sm_ns;
        self.per_partition_ns = per_partition_ns;
    }

    /// Sets the lagged span from each node's stretches of visits (first cycle, cycle reached,
    /// nanoseconds) and the L2 round trip: each stretch's time is spread evenly over the
    /// buckets it covers (at most one round trip of them).
    pub fn set_stretches<'s>(
        &mut self,
        nodes: impl Iterator<Item = &'s [(u64, u64, u64)]>,
        round_trip: u64,
    ) {
        let bucket = (round_trip / LAG_BUCKETS).max(1);
        let mut costs: Vec<Vec<u64>> = Vec::new();
        for stretches in nodes {
            let mut cost: Vec<u64> = Vec::new();
            // A stretch that starts at or past what it reached, or past every real cycle (a
            // node with no visit to come), visited nothing.
            let visited = |s: &&(u64, u64, u64)| s.0 < s.1 && s.0 < 1 << 60;
            for &(from, reached, ns) in stretches.iter().filter(visited) {
                let first = from / bucket;
                let last = reached
                    .max(from.saturating_add(1))
                    .min(from.saturating_add(round_trip))
                    .saturating_sub(1)
                    / bucket;
                let n = last - first + 1;
                if cost.len() <= last as usize {
                    cost.resize(last as usize + 1, 0);
                }
                for (k, c) in cost[first as usize..=last as usize].iter_mut().enumerate() {
                    *c += ns / n + u64::from((k as u64) < ns % n);
                }
            }
            costs.push(cost);
        }
        self.lagged_span_ns = lagged_span(&costs, LAG_BUCKETS as usize);
    }

    /// Sets the coordinator's work (already less its clock reads).
    pub fn set_serial(&mut self, ns: u64) {
        self.coordinator_ns = ns;
    }

    /// Sets the time of the whole loop, taking out the estimated cost of the clock reads made
    /// since `reads_before` ([`clock_reads`] then).
    pub fn set_total(&mut self, ns: u64, reads_before: u64) {
        let reads = clock_reads().saturating_sub(reads_before);
        self.clock_ns = reads * self.read_ns;
        self.total_ns = ns.saturating_sub(self.clock_ns);
    }

    /// Nanoseconds of serial work: the coordinator's.
    pub fn serial_total_ns(&self) -> u64 {
        self.coordinator_ns
    }

    /// Nanoseconds of the loop no unit accounts for: threads looking for work (every thread
    /// does its own, so it counts as parallel work).
    fn looking_ns(&self) -> u64 {
        let timed = self.per_sm_ns.iter().sum::<u64>()
            + self.per_partition_ns.iter().sum::<u64>()
            + self.coordinator_ns;
        self.total_ns.saturating_sub(timed)
    }

    /// Nanoseconds of parallel work: the nodes', the partitions' and looking for work.
    fn parallel_ns(&self) -> u64 {
        self.per_sm_ns.iter().sum::<u64>()
            + self.per_partition_ns.iter().sum::<u64>()
            + self.looking_ns()
    }

    /// The one-thread time the prediction starts from: serial time plus all work.
    pub fn one_thread_ns(&self) -> u64 {
        self.serial_total_ns() + self.parallel_ns()
    }

    /// The longest chain of work: the busiest node or partition, or the lagged span.
    fn span_ns(&self) -> u64 {
        self.per_sm_ns
            .iter()
            .chain(&self.per_partition_ns)
            .copied()
            .max()
            .unwrap_or(0)
            .max(self.lagged_span_ns)
    }

    /// Predicted time on `n` threads.
    fn predicted_ns(&self, n: usize) -> u64 {
        let spread = self.parallel_ns().div_ceil(n.max(1) as u64);
        self.serial_total_ns() + spread.max(self.span_ns())
    }

    /// Predicted speedups over one thread, one per entry of [`PREDICTED_THREADS`].
    pub fn predicted_speedups(&self) -> Vec<(usize, f64)> {
        let one = self.one_thread_ns().max(1) as f64;
        PREDICTED_THREADS
            .iter()
            .map(|&n| {
                let x = if n == 1 {
                    1.0
                } else {
                    one / self.predicted_ns(n).max(1) as f64
                };
                (n, x)
            })
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
            "parallelism (one-thread run, {:.1} ms in the loop):",
            ms(self.total_ns)
        );
        let sms: u64 = self.per_sm_ns.iter().sum();
        let parts: u64 = self.per_partition_ns.iter().sum();
        let _ = writeln!(
            s,
            "  parallel  SM nodes (visits, settling L2 results, posting operations): {:.1} ms \
             ({:.1}%)",
            ms(sms),
            pct(sms)
        );
        let _ = writeln!(
            s,
            "  parallel  memory partitions (applying L2 operations): {:.1} ms ({:.1}%)",
            ms(parts),
            pct(parts)
        );
        let other = self.looking_ns();
        let _ = writeln!(
            s,
            "  serial    coordinator (CTA dispatch, halts, end of run, watchdog): {:.1} ms \
             ({:.1}%)",
            ms(self.coordinator_ns),
            pct(self.coordinator_ns)
        );
        let _ = writeln!(
            s,
            "  parallel  looking for work: {:.1} ms ({:.1}%)",
            ms(other),
            pct(other)
        );
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
        if let (Some(&max), Some(&min)) = (self.per_sm_ns.iter().max(), self.per_sm_ns.iter().min())
        {
            let mean = sms / self.per_sm_ns.len() as u64;
            let _ = writeln!(
                s,
                "  balance: work per SM over the run {:.1} / {:.1} / {:.1} ms (least / mean / \
                 most); with a thread per SM, bounded lag takes {:.1} ms of it (the lagged \
                 span: at most {:.2}x)",
                ms(min),
                ms(mean),
                ms(max),
                ms(self.lagged_span_ns),
                one / (self.serial_total_ns() + self.span_ns()).max(1) as f64
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

/// The time the nodes' work `costs` (per node, nanoseconds per bucket of cycles) takes with a
/// thread per node when a node starts bucket `k` only after finishing bucket `k - 1` and once
/// every node has finished bucket `k - lag`.
fn lagged_span(costs: &[Vec<u64>], lag: usize) -> u64 {
    let buckets = costs.iter().map(Vec::len).max().unwrap_or(0);
    // finish[k % (lag + 1)][node]: when the node finished bucket k.
    let mut finish = vec![vec![0u64; costs.len()]; lag + 1];
    let mut all_done = vec![0u64; lag + 1];
    for k in 0..buckets {
        let gate = if k >= lag {
            all_done[(k - lag) % (lag + 1)]
        } else {
            0
        };
        let prev = (k + lag) % (lag + 1);
        let mut latest = 0;
        for (i, cost) in costs.iter().enumerate() {
            let start = if k == 0 { 0 } else { finish[prev][i] }.max(gate);
            let done = start + cost.get(k).copied().unwrap_or(0);
            finish[k % (lag + 1)][i] = done;
            latest = latest.max(done);
        }
        all_done[k % (lag + 1)] = latest;
    }
    all_done.iter().copied().max().unwrap_or(0)
}

/// Clock reads made by stopwatches so far (in every thread).
pub fn clock_reads() -> u64 {
    CLOCK_READS.load(Ordering::Relaxed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prediction_is_the_work_span_bound() {
        let mut p = ParallelProfile::default();
        // 16 SMs of 1,000 ns but one of 4,000 ns, 16 partitions of 100 ns, 400 ns serial.
        let mut sms = vec![1_000; 16];
        sms[3] = 4_000;
        p.set_units(sms, vec![100; 16]);
        p.set_serial(400);
        p.total_ns = 15_000 + 4_000 + 1_600 + 400;
        assert_eq!(p.one_thread_ns(), 21_000);
        let s = p.predicted_speedups();
        assert_eq!(s[0], (1, 1.0));
        // 2 threads: 400 + 20,600 / 2 = 10,700.
        assert!((s[1].1 - 21_000.0 / 10_700.0).abs() < 1e-9, "{:?}", s[1]);
        // 16 threads: the busiest SM, 400 + 4,000.
        assert!((s[4].1 - 21_000.0 / 4_400.0).abs() < 1e-9, "{:?}", s[4]);
        assert_eq!(s[5].1, s[4].1);
        assert!(p.report().contains("predicted speedup"));
    }

    #[test]
    fn looking_for_work_counts_as_parallel_work() {
        let mut p = ParallelProfile::default();
        p.set_units(vec![100, 100], vec![]);
        p.set_serial(50);
        p.total_ns = 300;
        // 300 - 200 - 50 = 50 ns of looking for work, spread like the nodes' work.
        assert_eq!(p.serial_total_ns(), 50);
        assert_eq!(p.one_thread_ns(), 300);
    }

    #[test]
    fn lagged_span_lets_bursts_on_different_nodes_overlap_within_the_lag() {
        // Two nodes, each busy (10) in alternate buckets: with a lag of 4 buckets they overlap
        // (each takes only its own 4 x 10); with a lag of 1 (a barrier per bucket) they run one
        // after the other.
        let a = vec![10, 0, 10, 0, 10, 0, 10, 0];
        let b = vec![0, 10, 0, 10, 0, 10, 0, 10];
        assert_eq!(lagged_span(&[a.clone(), b.clone()], 4), 40);
        assert_eq!(lagged_span(&[a, b], 1), 80);
        // One node alone: its own work.
        assert_eq!(lagged_span(&[vec![5, 5, 5]], 4), 15);
    }

    #[test]
    fn stretches_spread_over_the_buckets_they_cover() {
        let mut p = ParallelProfile::default();
        // Round trip 8: buckets of 2 cycles; a stretch of cycles 0..4 (two buckets) of 10 ns.
        p.set_stretches([&[(0, 4, 10)][..]].into_iter(), 8);
        assert_eq!(p.lagged_span_ns, 10);
        // A stretch of a node with no visit to come counts nothing.
        p.set_stretches([&[(0, 4, 10), (u64::MAX, u64::MAX, 3)][..]].into_iter(), 8);
        assert_eq!(p.lagged_span_ns, 10);
    }
}
