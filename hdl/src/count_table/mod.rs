//! The treelet count table (paper sections 4.2, 4.4 and 6.5): how many rays wait for each
//! treelet, which treelet has the most rays, and eviction of the smallest entry when full.
//!
//! # Structure
//! - `entries`: a flip-flop array of `count_table_entries` words `{valid, treelet, count_m1}`
//!   (600 x (1 + 19 + 12) bits by default; a count `c` in 1..=max_rays is stored as `c - 1`).
//!   It has two parallel search ports (a CAM match of the treelet tag and a priority encoder for
//!   the first free entry), `scan_width + 1` combinational read ports and one write port.
//! - Registered pointers to the largest (`max_*`) and smallest (`min_*`) entry, ordered by
//!   count with ties broken towards the lower index (so the result is unique).
//! - A scan engine (FSM `IDLE`/`SCAN`) that recomputes both pointers by reading `scan_width`
//!   entries per cycle (8 by default: 75 cycles for 600 entries).
//! - Counters `occupancy` and `above` (entries with count >= `underpopulation_threshold`).
//!
//! # Operations and timing
//! One operation per cycle (`op_kind` 0 = Nop, 1 = Add, 2 = Remove, 3 = Clear), decided
//! combinationally in the cycle it is presented; state changes at the clock edge.
//! - **Add** `n` rays (1..=warp_size) to a treelet: a hit adds to the entry; a miss takes the
//!   first free entry; a miss with the table full evicts the smallest entry and reports it on
//!   `evict_*` — or, when the new treelet's `n` is not larger than the smallest count, reports the
//!   new treelet itself as evicted and changes nothing. A full-table miss needs a valid minimum:
//!   while it is stale, `ready` is low and the op must be held.
//! - **Remove** `n` rays: subtracts; reaching 0 frees the entry. Removing from an unknown treelet
//!   or more rays than held, `n` = 0 or `n` > warp_size, or an Add that would exceed `max_rays`,
//!   raises `error` for that cycle and changes nothing.
//! - **Clear** empties the table in one cycle (a common synchronous clear of the valid bits; the
//!   scan stops and both pointers become invalid). The controller clears the table when its
//!   rays are all traced (mode done): the rays that grouped warps and repacks took are not
//!   removed one by one, so without the clear their counts would outlive the wave of rays.
//!   Always accepted.
//!
//! The pointers are updated incrementally: growth of any entry (or a new entry) can only raise
//! the maximum, and shrinking can only lower the minimum, so those are folded in at once. An
//! update that may invalidate a pointer (the max entry shrinks or is freed, the min entry grows
//! or is freed or replaced) clears its valid bit and starts a scan. While a scan runs, ops keep
//! being accepted; an op on an entry the scan has already passed is folded into the scan's
//! running result by the same rules, and when it would invalidate the running result the scan
//! restarts from entry 0. A scan that is not restarted publishes both pointers after
//! `ceil(entries / scan_width)` cycles, and `max_valid` rises in the following cycle.

mod ports;
mod regs;

pub use ports::{
    CountOp, CountTableIn, CountTableOut, CountTableStatus, CountTableWidths, QueueCount,
};
pub use regs::{CountCtl, CountEntry, CountTableRegs, Extreme};

use crate::block::{Block, Signal};
use crate::config::{ConfigError, HwConfig};
use crate::describe::{block_params, BlockDesc, FsmDesc};
use crate::memory::{MemCycle, MemPorts, Memory};
use crate::registers::RegTable;
use regs::Change;

/// Entries the scan engine reads per cycle unless configured otherwise.
pub const DEFAULT_SCAN_WIDTH: u32 = 8;

/// The treelet count table block (see the module documentation).
#[derive(Debug, Clone)]
pub struct CountTable {
    cfg: HwConfig,
    scan_width: u32,
    widths: CountTableWidths,
}

impl CountTable {
    /// A count table for `cfg` with the default scan width (at most the number of entries).
    pub fn new(cfg: &HwConfig) -> Result<Self, ConfigError> {
        Self::with_scan_width(cfg, DEFAULT_SCAN_WIDTH.min(cfg.count_table_entries))
    }

    /// A count table whose scan engine reads `scan_width` entries per cycle
    /// (1..=count_table_entries).
    pub fn with_scan_width(cfg: &HwConfig, scan_width: u32) -> Result<Self, ConfigError> {
        cfg.validate()?;
        if scan_width == 0 || scan_width > cfg.count_table_entries {
            return Err(ConfigError {
                key: "scan_width",
                value: scan_width as u64,
                reason: format!(
                    "must be 1..=count_table_entries ({})",
                    cfg.count_table_entries
                ),
            });
        }
        Ok(CountTable {
            cfg: cfg.clone(),
            scan_width,
            widths: CountTableWidths::new(cfg),
        })
    }

    /// Signal widths of this table.
    pub fn widths(&self) -> CountTableWidths {
        self.widths
    }

    /// An input bundle carrying `op`.
    pub fn input(&self, op: CountOp) -> CountTableIn {
        CountTableIn {
            op,
            widths: self.widths,
        }
    }

    /// Cycles of one uninterrupted scan: ceil(entries / scan_width).
    pub fn scan_cycles(&self) -> u32 {
        self.cfg.count_table_entries.div_ceil(self.scan_width)
    }

    /// Whether a `Nop` cycle changes the registers: a scan is running, or a pointer is stale
    /// with entries left (the next cycle starts a scan). When false, `Nop` cycles change
    /// nothing, so a simulator need not evaluate them.
    pub(crate) fn busy(&self, r: &CountTableRegs) -> bool {
        r.ctl.scanning || ((!r.ctl.max.valid || !r.ctl.min.valid) && r.ctl.occupancy > 0)
    }

    /// `Nop` cycles after which both pointers are published again (`max_valid` high), if a
    /// scan is running or about to start; `None` when the table is not [`busy`](Self::busy).
    pub(crate) fn cycles_to_publish(&self, r: &CountTableRegs) -> Option<u32> {
        if r.ctl.scanning {
            Some((self.entries() - r.ctl.scan_pos).div_ceil(self.scan_width))
        } else if self.busy(r) {
            Some(1 + self.scan_cycles())
        } else {
            None
        }
    }

    /// One cycle from the start-of-cycle scalar registers `c` and the entry array's cycle
    /// `mem` (reads see the start-of-cycle words, writes land at the edge): this cycle's
    /// outputs and the next scalar registers. The block's only definition of a cycle.
    fn cycle(
        &self,
        c: CountCtl,
        mut mem: MemCycle<'_, CountEntry>,
        inputs: &CountTableIn,
    ) -> (CountTableOut, CountCtl) {
        let w = self.widths;
        let mut out = CountTableOut {
            ready: true,
            accepts: c.occupancy != self.entries() || c.min.valid,
            error: false,
            evict_valid: false,
            evict_treelet: 0,
            evict_count: 0,
            max_valid: c.max.valid,
            max_treelet: if c.max.valid { c.max.treelet } else { 0 },
            max_count: if c.max.valid { c.max.count_m1 + 1 } else { 0 },
            occupancy: c.occupancy,
            above_threshold: c.above,
            widths: w,
        };
        let n_entries = self.entries();
        if inputs.op == CountOp::Clear {
            // Every valid bit cleared at the edge; the scan and both pointers reset.
            mem.clear_all(|e| e.valid = false);
            return (out, CountCtl::default());
        }

        // ---- The operation (combinational lookup, write at the edge). ----
        let (change, occupancy, above) = self.operate(&c, &mut mem, inputs.op, &mut out);

        // ---- Published pointers: incremental rules. ----
        let mut max = c.max;
        let mut min = c.min;
        if max.valid {
            max.valid = change.fold_max(&mut max);
        } else if !c.scanning {
            // Not scanning and no max: the table was empty, so only an allocation applies.
            change.fold_max(&mut max);
        }
        if min.valid {
            min.valid = change.fold_min(&mut min);
        } else if !c.scanning {
            change.fold_min(&mut min);
        }

        // ---- Scan engine. ----
        let mut scanning = c.scanning;
        let mut scan_pos = c.scan_pos;
        let mut run_max = c.run_max;
        let mut run_min = c.run_min;
        if c.scanning {
            let end = (c.scan_pos + self.scan_width).min(n_entries);
            for i in c.scan_pos..end {
                let e = mem.read(i as usize);
                if e.valid {
                    if run_max.beaten_as_max(i, e.count_m1) {
                        run_max = Extreme::set(i, e.treelet, e.count_m1);
                    }
                    if run_min.beaten_as_min(i, e.count_m1) {
                        run_min = Extreme::set(i, e.treelet, e.count_m1);
                    }
                }
            }
            let seen = change.idx().is_some_and(|i| i < end);
            let intact = !seen || (change.fold_max(&mut run_max) & change.fold_min(&mut run_min));
            if !intact {
                scan_pos = 0;
                run_max = Extreme::default();
                run_min = Extreme::default();
            } else if end == n_entries {
                max = run_max;
                min = run_min;
                scanning = false;
                scan_pos = 0;
                run_max = Extreme::default();
                run_min = Extreme::default();
            } else {
                scan_pos = end;
            }
        } else if (!max.valid || !min.valid) && occupancy > 0 {
            scanning = true;
            scan_pos = 0;
        }
        drop(mem);
        let next = CountCtl {
            scanning,
            scan_pos,
            max,
            min,
            run_max,
            run_min,
            occupancy,
            above,
        };
        (out, next)
    }

    /// The cycle's operation `op` on the entry array (combinational lookup, writes at the
    /// edge) from the start-of-cycle registers `c`, setting `out`'s error, evict and ready
    /// ports: the change to publish and the next occupancy and above-threshold count.
    fn operate(
        &self,
        c: &CountCtl,
        mem: &mut MemCycle<'_, CountEntry>,
        op: CountOp,
        out: &mut CountTableOut,
    ) -> (Change, u32, u32) {
        let warp = self.cfg.warp_size;
        let mut change = Change::None;
        let mut occupancy = c.occupancy;
        let mut above = c.above;
        match op {
            CountOp::Nop | CountOp::Clear => {}
            CountOp::Add { treelet, n } => {
                let hit = mem.search(|e| e.valid && e.treelet == treelet);
                if n == 0 || n > warp {
                    out.error = true;
                } else if let Some(i) = hit {
                    let e = mem.read(i);
                    let total = e.count_m1 + 1 + n;
                    if total > self.cfg.max_rays {
                        out.error = true;
                    } else {
                        mem.write(
                            i,
                            CountEntry {
                                count_m1: total - 1,
                                ..e
                            },
                        );
                        above = above + self.above(Some(total - 1)) - self.above(Some(e.count_m1));
                        change = Change::Grow {
                            idx: i as u32,
                            treelet,
                            count_m1: total - 1,
                        };
                    }
                } else if let Some(f) = mem.search(|e| !e.valid) {
                    mem.write(
                        f,
                        CountEntry {
                            valid: true,
                            treelet,
                            count_m1: n - 1,
                        },
                    );
                    occupancy += 1;
                    above += self.above(Some(n - 1));
                    change = Change::Alloc {
                        idx: f as u32,
                        treelet,
                        count_m1: n - 1,
                    };
                } else if !c.min.valid {
                    out.ready = false;
                } else if n - 1 <= c.min.count_m1 {
                    out.evict_valid = true;
                    out.evict_treelet = treelet;
                    out.evict_count = n;
                } else {
                    out.evict_valid = true;
                    out.evict_treelet = c.min.treelet;
                    out.evict_count = c.min.count_m1 + 1;
                    mem.write(
                        c.min.idx as usize,
                        CountEntry {
                            valid: true,
                            treelet,
                            count_m1: n - 1,
                        },
                    );
                    above = above + self.above(Some(n - 1)) - self.above(Some(c.min.count_m1));
                    change = Change::Grow {
                        idx: c.min.idx,
                        treelet,
                        count_m1: n - 1,
                    };
                }
            }
            CountOp::Remove { treelet, n } => {
                let hit = mem.search(|e| e.valid && e.treelet == treelet);
                match hit {
                    Some(i) if n > 0 && n <= warp => {
                        let e = mem.read(i);
                        let c = e.count_m1 + 1;
                        if n > c {
                            out.error = true;
                        } else if n == c {
                            mem.write(i, CountEntry::default());
                            occupancy -= 1;
                            above -= self.above(Some(e.count_m1));
                            change = Change::Free { idx: i as u32 };
                        } else {
                            mem.write(
                                i,
                                CountEntry {
                                    count_m1: c - n - 1,
                                    ..e
                                },
                            );
                            above =
                                above + self.above(Some(c - n - 1)) - self.above(Some(e.count_m1));
                            change = Change::Shrink {
                                idx: i as u32,
                                treelet,
                                count_m1: c - n - 1,
                            };
                        }
                    }
                    _ => out.error = true,
                }
            }
        }
        (change, occupancy, above)
    }

    fn entries(&self) -> u32 {
        self.cfg.count_table_entries
    }

    fn above(&self, count_m1: Option<u32>) -> u32 {
        count_m1.map_or(0, |c| (c + 1 >= self.cfg.underpopulation_threshold) as u32)
    }
}

impl Block for CountTable {
    type Inputs = CountTableIn;
    type Outputs = CountTableOut;
    type Regs = CountTableRegs;

    fn reset(&self) -> CountTableRegs {
        let ports = MemPorts {
            read: self.scan_width + 1,
            write: 1,
            search: 2,
            read_latency: 0,
        };
        CountTableRegs {
            entries: Memory::new(self.entries() as usize, CountEntry::default(), ports),
            ctl: CountCtl::default(),
        }
    }

    /// A `Nop`.
    fn idle_inputs(&self) -> CountTableIn {
        self.input(CountOp::Nop)
    }

    /// The next-state function: the entries copied into `next`'s storage, then
    /// [`CountTable::cycle`] on them.
    fn next_into(
        &self,
        regs: &CountTableRegs,
        inputs: &CountTableIn,
        next: &mut CountTableRegs,
    ) -> CountTableOut {
        next.entries.copy_from(&regs.entries);
        let (out, ctl) = self.cycle(regs.ctl, next.entries.cycle(), inputs);
        next.ctl = ctl;
        out
    }

    /// In place: the same [`CountTable::cycle`] on the registers' own entries (whose writes
    /// take effect at the clock edge, after every read of the cycle).
    fn step(&self, r: &mut CountTableRegs, inputs: &CountTableIn) -> CountTableOut {
        let (out, ctl) = self.cycle(r.ctl, r.entries.cycle(), inputs);
        r.ctl = ctl;
        out
    }

    fn reg_signals(&self, r: &CountTableRegs) -> Vec<Signal> {
        self.registers().signals(r)
    }

    fn describe(&self) -> BlockDesc {
        let w = self.widths;
        let c = &self.cfg;
        let regs = self.reset();
        let mut ports = CountTableIn::ports(&w);
        ports.extend(CountTableOut::ports(&w));
        let registers = self.registers().descs();
        BlockDesc {
            name: "treelet_count_table".into(),
            doc: "Treelet count table (sections 4.2, 4.4, 6.5): rays per treelet, the largest \
                  treelet for treelet-stationary dispatch, and eviction of the smallest entry \
                  when full (its rays are processed ray-stationary later)."
                .into(),
            params: block_params!(c;
                count_table_entries, max_rays, warp_size,
                treelet_addr_bits = w.treelet,
                underpopulation_threshold,
                scan_width = self.scan_width,
            ),
            ports,
            registers,
            memories: vec![regs.entries.desc(
                "entries",
                vec![
                    ("valid".into(), 1),
                    ("treelet".into(), w.treelet),
                    ("count_m1".into(), w.count_m1),
                ],
                "Treelet count entries; count stored as count - 1. Read ports: scan_width for the \
                 scan engine plus one for the op's entry.",
            )],
            fsms: vec![FsmDesc {
                name: "state".into(),
                states: vec!["IDLE".into(), "SCAN".into()],
                width: 1,
            }],
            timing: vec![
                "One Add or Remove accepted per cycle, decided combinationally (CAM lookup of \
                 the treelet, priority encoder for the first free entry); results (ready, \
                 error, evict_*) in the same cycle, state at the clock edge."
                    .into(),
                "Growth or a new entry updates the registered max pointer at once; shrinking \
                 updates the min pointer at once."
                    .into(),
                format!(
                    "When the max entry shrinks or is freed, or the min entry grows, is freed or \
                     is replaced, that pointer goes invalid and a scan reads {} entries per \
                     cycle: {} cycles for {} entries, pointers valid the cycle after; an op that \
                     invalidates the scan's running result on an already-scanned entry restarts it.",
                    self.scan_width,
                    self.scan_cycles(),
                    c.count_table_entries
                ),
                "Ops run during a scan; only an Add of a new treelet into a full table needs the \
                 min pointer and stalls (ready low) until the scan publishes it."
                    .into(),
            ],
        }
    }
}

impl CountTable {
    /// The registers (all but the entry memory): their descriptions and trace signals, declared
    /// once.
    fn registers(&self) -> RegTable<'static, CountTableRegs> {
        let w = self.widths;
        let mut t = RegTable::new();
        t.one("state", 1, "FSM state (IDLE/SCAN)", |r: &CountTableRegs| {
            r.ctl.scanning as u64
        })
        .one(
            "scan_pos",
            w.index,
            "first entry the scan reads this cycle",
            |r| r.ctl.scan_pos as u64,
        );
        type Pointer = fn(&CountTableRegs) -> &Extreme;
        let pointers: [(&str, Pointer); 4] = [
            ("max", |r| &r.ctl.max),
            ("min", |r| &r.ctl.min),
            ("run_max", |r| &r.ctl.run_max),
            ("run_min", |r| &r.ctl.run_min),
        ];
        for (p, x) in pointers {
            t.one(
                &format!("{p}_valid"),
                1,
                &format!("{p} pointer valid"),
                move |r| x(r).valid as u64,
            )
            .one(
                &format!("{p}_idx"),
                w.index,
                &format!("{p} entry index"),
                move |r| x(r).idx as u64,
            )
            .one(
                &format!("{p}_treelet"),
                w.treelet,
                &format!("{p} entry treelet"),
                move |r| x(r).treelet,
            )
            .one(
                &format!("{p}_count_m1"),
                w.count_m1,
                &format!("{p} entry count - 1"),
                move |r| x(r).count_m1 as u64,
            );
        }
        t.one("occupancy", w.entries, "valid entries", |r| {
            r.ctl.occupancy as u64
        })
        .one(
            "above",
            w.entries,
            "entries at or above the underpopulation threshold",
            |r| r.ctl.above as u64,
        );
        t
    }
}

crate::uncached!(CountTable);

/// The `accepts`, `max_*`, `occupancy` and `above_threshold` ports.
impl crate::block::Moore for CountTable {
    type Status = CountTableStatus;
    type Select = ();

    fn status(&self, r: &CountTableRegs, _: &(), _: ()) -> CountTableStatus {
        CountTableStatus {
            ready: r.ctl.occupancy != self.entries() || r.ctl.min.valid,
            max: r.ctl.max.valid.then_some(QueueCount {
                treelet: r.ctl.max.treelet as u32,
                count: r.ctl.max.count_m1 + 1,
            }),
            occupancy: r.ctl.occupancy,
            above_threshold: r.ctl.above,
        }
    }
}

/// A scan in progress (or about to start) advances with `Nop`s; the table is idle until it
/// publishes its pointers, and gated when not `busy`.
impl crate::block::Skip for CountTable {
    type Counts = ();

    fn idle_cycles(&self, r: &CountTableRegs, _: &()) -> u64 {
        self.cycles_to_publish(r).map_or(u64::MAX, u64::from)
    }

    fn skip(&self, r: &mut CountTableRegs, _: &mut (), n: u64) {
        let nop = self.input(CountOp::Nop);
        let mut left = n;
        while left > 0 && self.busy(r) {
            self.step(r, &nop);
            left -= 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> HwConfig {
        HwConfig {
            count_table_entries: 4,
            max_rays: 64,
            warp_size: 4,
            underpopulation_threshold: 5,
            repack_threshold: 2,
            divergence_threshold: 2,
            ..HwConfig::default()
        }
    }

    #[test]
    fn add_tracks_max_and_evicts_smallest_when_full() {
        let t = CountTable::with_scan_width(&small(), 1).unwrap();
        let mut r = t.reset();
        for (treelet, n) in [(10, 3), (11, 4), (12, 2), (13, 1)] {
            let o = t.step(&mut r, &t.input(CountOp::Add { treelet, n }));
            assert!(o.ready && !o.error && !o.evict_valid);
        }
        let o = t.step(&mut r, &t.input(CountOp::Nop));
        assert_eq!((o.max_valid, o.max_treelet, o.max_count), (true, 11, 4));
        assert_eq!((o.occupancy, o.above_threshold), (4, 0));
        // Full: a new treelet with 1 ray is not larger than the smallest (13: 1) and is evicted.
        let o = t.step(&mut r, &t.input(CountOp::Add { treelet: 14, n: 1 }));
        assert_eq!(
            (o.evict_valid, o.evict_treelet, o.evict_count),
            (true, 14, 1)
        );
        // 3 rays beat the smallest: 13 is evicted and replaced.
        let o = t.step(&mut r, &t.input(CountOp::Add { treelet: 14, n: 3 }));
        assert_eq!(
            (o.evict_valid, o.evict_treelet, o.evict_count),
            (true, 13, 1)
        );
        // The min pointer is now stale: the next full-table Add stalls until the scan ends.
        let add = t.input(CountOp::Add { treelet: 15, n: 4 });
        let mut stalls = 0;
        loop {
            let o = t.step(&mut r, &add);
            if o.ready {
                assert_eq!((o.evict_treelet, o.evict_count), (12, 2));
                break;
            }
            stalls += 1;
        }
        assert_eq!(stalls, t.scan_cycles());
    }

    #[test]
    fn clear_empties_the_table_in_one_cycle_even_mid_scan() {
        let t = CountTable::with_scan_width(&small(), 1).unwrap();
        let mut r = t.reset();
        for (treelet, n) in [(10, 3), (11, 4), (12, 2)] {
            t.step(&mut r, &t.input(CountOp::Add { treelet, n }));
        }
        // Shrinking the largest entry stales the max pointer and starts a scan.
        t.step(&mut r, &t.input(CountOp::Remove { treelet: 11, n: 4 }));
        t.step(&mut r, &t.input(CountOp::Nop));
        assert!(r.ctl.scanning, "a scan runs when the table is cleared");
        let o = t.step(&mut r, &t.input(CountOp::Clear));
        assert!(o.ready && !o.error && !o.evict_valid);
        assert_eq!(r.ctl, CountCtl::default());
        assert!(r.entries.words().iter().all(|e| !e.valid));
        assert!(!t.busy(&r), "a cleared table has nothing to do");
        let o = t.step(&mut r, &t.input(CountOp::Nop));
        assert_eq!((o.max_valid, o.occupancy, o.above_threshold), (false, 0, 0));
        // The table works as from reset: the next Add is its largest entry at once.
        t.step(&mut r, &t.input(CountOp::Add { treelet: 12, n: 1 }));
        let o = t.step(&mut r, &t.input(CountOp::Nop));
        assert_eq!((o.max_valid, o.max_treelet, o.max_count), (true, 12, 1));
    }

    #[test]
    fn bad_ops_raise_error_and_change_nothing() {
        let t = CountTable::new(&small()).unwrap();
        let mut r = t.reset();
        t.step(&mut r, &t.input(CountOp::Add { treelet: 1, n: 2 }));
        let before = r.clone();
        for op in [
            CountOp::Remove { treelet: 1, n: 3 },
            CountOp::Remove { treelet: 2, n: 1 },
            CountOp::Add { treelet: 1, n: 0 },
            CountOp::Add { treelet: 1, n: 5 },
        ] {
            let o = t.step(&mut r, &t.input(op));
            assert!(o.error, "{op:?}");
            assert_eq!(r, before, "{op:?} changed state");
        }
    }

    #[test]
    fn cycles_to_publish_counts_the_nop_cycles_of_a_scan() {
        let cfg = HwConfig {
            count_table_entries: 20,
            ..HwConfig::default()
        };
        let t = CountTable::with_scan_width(&cfg, 8).unwrap();
        let mut r = t.reset();
        for (treelet, n) in [(1, 3), (2, 5), (3, 2)] {
            t.step(&mut r, &t.input(CountOp::Add { treelet, n }));
        }
        assert!(!t.busy(&r) && t.cycles_to_publish(&r).is_none());
        // Shrinking the largest entry makes the max stale and starts a scan.
        t.step(&mut r, &t.input(CountOp::Remove { treelet: 2, n: 4 }));
        let k = t.cycles_to_publish(&r).expect("scanning");
        for step in 1..=k {
            assert!(!r.ctl.max.valid, "published early, after {step} of {k}");
            t.step(&mut r, &t.input(CountOp::Nop));
        }
        assert!(r.ctl.max.valid && !t.busy(&r));
        assert_eq!((r.ctl.max.treelet, r.ctl.max.count_m1 + 1), (1, 3));
    }

    #[test]
    fn step_equals_eval() {
        let t = CountTable::with_scan_width(&small(), 2).unwrap();
        let mut r = t.reset();
        let ops = [
            CountOp::Add { treelet: 3, n: 4 },
            CountOp::Add { treelet: 4, n: 2 },
            CountOp::Remove { treelet: 3, n: 4 },
            CountOp::Nop,
            CountOp::Add { treelet: 5, n: 1 },
            CountOp::Nop,
        ];
        for op in ops {
            let i = t.input(op);
            let (o, next) = t.eval(&r, &i);
            assert_eq!(t.step(&mut r, &i), o);
            assert_eq!(r, next);
        }
    }

    #[test]
    fn rejects_bad_scan_width() {
        assert_eq!(
            CountTable::with_scan_width(&small(), 0).unwrap_err().key,
            "scan_width"
        );
        assert!(CountTable::with_scan_width(&small(), 5).is_err());
    }
}
