//! The energy model's coefficients ([`Coefficients`]): one value per [`Term`], from one of the
//! named sets of [`CoefficientSet`]. Every figure and its source is in
//! /work/shared/reference/energy-sources.md and docs/energy.md; they are declared here once.

use crate::model::config::{CoefficientSet, SimConfig};

/// SMs of the GPU AccelWattch's time terms were fitted for (the QV100, an 80-SM V100). The chip's
/// constant and static power are scaled by `gpu.sms / REFERENCE_SMS` (docs/energy.md).
pub const REFERENCE_SMS: f64 = 80.0;

/// One coefficient of the model: a time-proportional power (W) or an energy per event (pJ).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Term {
    /// Constant power of the whole reference chip (W), scaled by SMs / [`REFERENCE_SMS`].
    ConstantW,
    /// Static power of the reference chip with every SM active (W), times the active-SM
    /// fraction, scaled by SMs / [`REFERENCE_SMS`].
    StaticW,
    /// Power of one idle SM (W).
    IdleSmW,
    /// L1 read that hits (or merges with a fill), per 32 B sector (pJ).
    L1ReadHit,
    /// L1 read that misses (pJ).
    L1ReadMiss,
    /// L1 store that hits (pJ).
    L1WriteHit,
    /// L1 store that misses (pJ).
    L1WriteMiss,
    /// L2 read that hits or merges (pJ).
    L2ReadHit,
    /// L2 read that misses (pJ).
    L2ReadMiss,
    /// L2 write that hits (pJ).
    L2WriteHit,
    /// L2 write that misses (pJ).
    L2WriteMiss,
    /// DRAM read, per 32 B (pJ).
    DramRead,
    /// DRAM write, per 32 B (pJ).
    DramWrite,
    /// Interconnect flit of 32 B between an L1 and the L2 (pJ).
    Flit,
    /// One ray-box test (pJ).
    BoxTest,
    /// One ray-triangle (or ray-sphere) test (pJ).
    TriangleTest,
    /// Treelet count table: search by treelet id (pJ).
    CountTableSearch,
    /// Treelet count table: write of one entry (pJ).
    CountTableWrite,
    /// Treelet count table: read of one entry in a scan for the largest queue (pJ).
    CountTableRead,
    /// Treelet queue table: read of one entry (pJ).
    QueueTableRead,
    /// Treelet queue table: write of one entry (pJ).
    QueueTableWrite,
}

impl Term {
    /// Every term, in report order.
    pub const ALL: [Term; 21] = [
        Term::ConstantW,
        Term::StaticW,
        Term::IdleSmW,
        Term::L1ReadHit,
        Term::L1ReadMiss,
        Term::L1WriteHit,
        Term::L1WriteMiss,
        Term::L2ReadHit,
        Term::L2ReadMiss,
        Term::L2WriteHit,
        Term::L2WriteMiss,
        Term::DramRead,
        Term::DramWrite,
        Term::Flit,
        Term::BoxTest,
        Term::TriangleTest,
        Term::CountTableSearch,
        Term::CountTableWrite,
        Term::CountTableRead,
        Term::QueueTableRead,
        Term::QueueTableWrite,
    ];

    /// The term's name in reports (`vtq energy --vary`, docs/energy.md).
    pub fn name(self) -> &'static str {
        match self {
            Term::ConstantW => "constant_w",
            Term::StaticW => "static_w",
            Term::IdleSmW => "idle_sm_w",
            Term::L1ReadHit => "l1_read_hit",
            Term::L1ReadMiss => "l1_read_miss",
            Term::L1WriteHit => "l1_write_hit",
            Term::L1WriteMiss => "l1_write_miss",
            Term::L2ReadHit => "l2_read_hit",
            Term::L2ReadMiss => "l2_read_miss",
            Term::L2WriteHit => "l2_write_hit",
            Term::L2WriteMiss => "l2_write_miss",
            Term::DramRead => "dram_read",
            Term::DramWrite => "dram_write",
            Term::Flit => "flit",
            Term::BoxTest => "box_test",
            Term::TriangleTest => "triangle_test",
            Term::CountTableSearch => "count_table_search",
            Term::CountTableWrite => "count_table_write",
            Term::CountTableRead => "count_table_read",
            Term::QueueTableRead => "queue_table_read",
            Term::QueueTableWrite => "queue_table_write",
        }
    }

    /// Whether the term is a power (W) rather than an energy per event (pJ).
    pub fn is_power(self) -> bool {
        matches!(self, Term::ConstantW | Term::StaticW | Term::IdleSmW)
    }

    /// The term's index in [`Term::ALL`].
    fn index(self) -> usize {
        self as usize
    }
}

/// The AccelWattch terms of one QV100 fit: time terms, then the memory events in
/// [`Term::ALL`]'s order from `L1ReadHit` to `Flit` (energy-sources.md, "AccelWattch's
/// structure"). RT-unit tests and tables cost nothing: no public Vulkan-Sim tree has an RT-unit
/// energy term.
const fn accelwattch(memory: [f64; 11]) -> [f64; 21] {
    let mut v = [0.0; 21];
    // Time terms, PTX and SASS alike: constant 32.33 W, static 34.79 W (the L1-only mix:
    // RT-unit node fetches are L1 data reads; docs/energy.md), 0.283 W per idle SM.
    v[0] = 32.33;
    v[1] = 34.79;
    v[2] = 0.283;
    let mut i = 0;
    while i < 11 {
        v[3 + i] = memory[i];
        i += 1;
    }
    v
}

/// AccelWattch PTX fit: L1 read hit / miss, write hit / miss, L2 read hit / miss, write hit /
/// miss, DRAM read / write per 32 B, interconnect flit (pJ).
const PTX: [f64; 21] = accelwattch([
    399.0, 266.0, 29.0, 309.0, 57.0, 5.0, 214.0, 232.0, 2148.0, 1192.0, 223.0,
]);

/// AccelWattch SASS fit, same order.
const SASS: [f64; 21] = accelwattch([
    507.0, 338.0, 37.0, 393.0, 69.0, 4.5, 270.0, 130.0, 2011.0, 1115.0, 86.0,
]);

/// CACTI 7 (22 nm, itrs-hp, one RW port) read / write energy of the reference L1: 16 KB fully
/// associative (pJ).
const L1_RW_22NM: (f64, f64, f64) = (57.0, 64.0, 16384.0);
/// ... of a 128 KB 16-way L2 slice (pJ, bytes).
const L2_RW_22NM: (f64, f64, f64) = (51.0, 50.0, 131072.0);
/// ... of the 600-entry treelet count table searched by treelet id: search, write (pJ), and
/// its RAM read (pJ), entries.
const COUNT_TABLE_22NM: (f64, f64, f64, f64) = (8.1, 3.8, 0.61, 600.0);
/// ... of the 128-entry treelet queue table: read, write (pJ), entries.
const QUEUE_TABLE_22NM: (f64, f64, f64) = (5.74, 8.69, 128.0);
/// GDDR6 energy per bit (pJ; Micron), the RTX 3070's memory.
const GDDR6_PJ_PER_BIT: f64 = 7.5;
/// Datapath energy of one ray-box test at 45 nm (pJ): 6 adds and 6 multiply(-add)s and ~6
/// compares (Horowitz ISSCC 2014 figures, purdue-aalp/raytracer operation counts).
const BOX_TEST_45NM: f64 = 30.0;
/// ... of one ray-triangle test at 45 nm (pJ).
const TRIANGLE_TEST_45NM: f64 = 90.0;

/// The values of one coefficient set, one per [`Term`].
#[derive(Debug, Clone, PartialEq)]
pub struct Coefficients {
    /// The set they come from.
    pub set: CoefficientSet,
    /// One value per term, in [`Term::ALL`]'s order.
    values: [f64; 21],
}

impl Coefficients {
    /// The coefficients of `set` for the hardware of `cfg` (the physical set scales its SRAM
    /// energies to the configured L1, L2 and treelet-table sizes; the AccelWattch sets do not
    /// depend on `cfg`).
    pub fn of(set: CoefficientSet, cfg: &SimConfig) -> Coefficients {
        let values = match set {
            CoefficientSet::AccelwattchPtx => PTX,
            CoefficientSet::AccelwattchSass => SASS,
            CoefficientSet::Physical => physical(cfg),
        };
        Coefficients { set, values }
    }

    /// The value of `term` (W or pJ).
    pub fn get(&self, term: Term) -> f64 {
        self.values[term.index()]
    }

    /// These coefficients with `term` multiplied by `factor` (for sensitivity).
    pub fn scaled(&self, term: Term, factor: f64) -> Coefficients {
        let mut c = self.clone();
        c.values[term.index()] *= factor;
        c
    }
}

/// An SRAM's energy per access scaled from a reference size to `bytes`: by the square root of
/// the capacity ratio (an estimate: word and bit lines grow with the side of the array).
fn sram_scale(bytes: f64, reference: f64) -> f64 {
    (bytes / reference).sqrt()
}

/// The physical set for the hardware of `cfg` (docs/energy.md, "The physical set").
fn physical(cfg: &SimConfig) -> [f64; 21] {
    let mut v = PTX;
    let l1 = sram_scale(cfg.memory.l1_bytes as f64, L1_RW_22NM.2);
    let (l1r, l1w) = (L1_RW_22NM.0 * l1, L1_RW_22NM.1 * l1);
    let l2 = sram_scale(cfg.memory.l2_bytes as f64, L2_RW_22NM.2);
    let (l2r, l2w) = (L2_RW_22NM.0 * l2, L2_RW_22NM.1 * l2);
    let ct = sram_scale(cfg.hw.count_table_entries as f64, COUNT_TABLE_22NM.3);
    let qt = sram_scale(cfg.hw.queue_table_entries as f64, QUEUE_TABLE_22NM.2);
    let dram = GDDR6_PJ_PER_BIT * 256.0;
    let set = |v: &mut [f64; 21], t: Term, x: f64| v[t.index()] = x;
    // A hit reads (or writes) the array; a read miss probes it and writes the fill; a store
    // miss probes it (L1: no write-allocate) or allocates (L2: write-allocate).
    set(&mut v, Term::L1ReadHit, l1r);
    set(&mut v, Term::L1ReadMiss, l1r + l1w);
    set(&mut v, Term::L1WriteHit, l1w);
    set(&mut v, Term::L1WriteMiss, l1r);
    set(&mut v, Term::L2ReadHit, l2r);
    set(&mut v, Term::L2ReadMiss, l2r + l2w);
    set(&mut v, Term::L2WriteHit, l2w);
    set(&mut v, Term::L2WriteMiss, l2w);
    set(&mut v, Term::DramRead, dram);
    set(&mut v, Term::DramWrite, dram);
    set(&mut v, Term::BoxTest, BOX_TEST_45NM);
    set(&mut v, Term::TriangleTest, TRIANGLE_TEST_45NM);
    set(&mut v, Term::CountTableSearch, COUNT_TABLE_22NM.0 * ct);
    set(&mut v, Term::CountTableWrite, COUNT_TABLE_22NM.1 * ct);
    set(&mut v, Term::CountTableRead, COUNT_TABLE_22NM.2 * ct);
    set(&mut v, Term::QueueTableRead, QUEUE_TABLE_22NM.0 * qt);
    set(&mut v, Term::QueueTableWrite, QUEUE_TABLE_22NM.1 * qt);
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_term_has_its_index_and_a_unique_name() {
        for (i, t) in Term::ALL.iter().enumerate() {
            assert_eq!(t.index(), i);
        }
        let names: std::collections::BTreeSet<_> = Term::ALL.iter().map(|t| t.name()).collect();
        assert_eq!(names.len(), Term::ALL.len());
    }

    #[test]
    fn accelwattch_sets_charge_no_tests_or_tables_and_share_time_terms() {
        let cfg = SimConfig::default();
        let ptx = Coefficients::of(CoefficientSet::AccelwattchPtx, &cfg);
        let sass = Coefficients::of(CoefficientSet::AccelwattchSass, &cfg);
        for t in [Term::BoxTest, Term::TriangleTest, Term::QueueTableWrite] {
            assert_eq!((ptx.get(t), sass.get(t)), (0.0, 0.0));
        }
        assert_eq!(ptx.get(Term::ConstantW), sass.get(Term::ConstantW));
        assert_eq!(ptx.get(Term::L1ReadHit), 399.0);
        assert_eq!(sass.get(Term::Flit), 86.0);
    }

    #[test]
    fn the_physical_set_follows_the_configured_sizes() {
        let mut cfg = SimConfig::default();
        let base = Coefficients::of(CoefficientSet::Physical, &cfg);
        assert_eq!(base.get(Term::L1ReadHit), 57.0);
        assert_eq!(base.get(Term::CountTableSearch), 8.1);
        assert_eq!(base.get(Term::DramRead), 1920.0);
        cfg.hw.count_table_entries = 2400;
        cfg.memory.l1_bytes = 65536;
        let big = Coefficients::of(CoefficientSet::Physical, &cfg);
        assert!((big.get(Term::CountTableSearch) - 16.2).abs() < 1e-9);
        assert!((big.get(Term::L1ReadHit) - 114.0).abs() < 1e-9);
        assert_eq!(
            big.get(Term::QueueTableRead),
            base.get(Term::QueueTableRead)
        );
    }

    #[test]
    fn scaling_one_term_leaves_the_others() {
        let c = Coefficients::of(CoefficientSet::AccelwattchPtx, &SimConfig::default());
        let d = c.scaled(Term::DramRead, 2.0);
        for t in Term::ALL {
            let want = if t == Term::DramRead { 2.0 } else { 1.0 } * c.get(t);
            assert_eq!(d.get(t), want, "{}", t.name());
        }
    }
}
