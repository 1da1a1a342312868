//! The count table's operations and ports: the op presented each cycle ([`CountOp`]), the
//! signal widths, the input and output port bundles, and the register-only status a
//! controller reads before it drives an op.

use crate::bits::bits_for;
use crate::config::HwConfig;

/// Operation presented to the count table in one cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CountOp {
    /// No operation (`op_kind` 0).
    Nop,
    /// `n` more rays (1..=warp_size) wait for `treelet` (`op_kind` 1).
    Add {
        /// Treelet address (the bits above the treelet offset).
        treelet: u64,
        /// Number of rays.
        n: u32,
    },
    /// `n` rays (1..=warp_size) of `treelet` left its queue (`op_kind` 2).
    Remove {
        /// Treelet address.
        treelet: u64,
        /// Number of rays.
        n: u32,
    },
    /// Every entry is freed and both pointers become invalid (`op_kind` 3).
    Clear,
}

impl CountOp {
    /// The `op_kind` encoding: 0 Nop, 1 Add, 2 Remove, 3 Clear.
    pub fn kind_code(&self) -> u64 {
        match self {
            CountOp::Nop => 0,
            CountOp::Add { .. } => 1,
            CountOp::Remove { .. } => 2,
            CountOp::Clear => 3,
        }
    }
}

impl CountOp {
    /// Width of the op-kind code.
    pub const BITS: u32 = 2;

    /// `(treelet, n)` as driven on the wires (zeros for `Nop`).
    pub fn fields(&self) -> (u64, u32) {
        match *self {
            CountOp::Nop | CountOp::Clear => (0, 0),
            CountOp::Add { treelet, n } | CountOp::Remove { treelet, n } => (treelet, n),
        }
    }
}

/// Bit widths of the count table's signals, derived from the configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CountTableWidths {
    /// Treelet address bits (19 by default).
    pub treelet: u32,
    /// Bits of a per-op ray number 0..=warp_size.
    pub n: u32,
    /// Bits of a true count 0..=max_rays on the ports.
    pub count: u32,
    /// Bits of a stored count - 1 (12 by default).
    pub count_m1: u32,
    /// Bits of an entry index.
    pub index: u32,
    /// Bits of a number of entries 0..=count_table_entries.
    pub entries: u32,
}

impl CountTableWidths {
    /// Widths for a configuration.
    pub fn new(cfg: &HwConfig) -> Self {
        CountTableWidths {
            treelet: cfg.treelet_addr_bits(),
            n: bits_for(cfg.warp_size as u64),
            count: bits_for(cfg.max_rays as u64),
            count_m1: cfg.count_bits(),
            index: cfg.count_index_bits(),
            entries: bits_for(cfg.count_table_entries as u64),
        }
    }
}

crate::bundle! {
    /// Input ports of the count table.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct CountTableIn (In, w: CountTableWidths, this) {
        /// This cycle's operation.
        pub op: CountOp,
    }
    ports {
        /// operation: 0 Nop, 1 Add, 2 Remove, 3 Clear
        sig op_kind (CountOp::BITS) = this.op.kind_code();
        /// treelet address of the op
        sig op_treelet (w.treelet) = this.op.fields().0;
        /// rays added or removed (1..=warp_size)
        sig op_n (w.n) = this.op.fields().1 as u64;
    }
}

crate::bundle! {
    /// Output ports of the count table.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct CountTableOut (Out, w: CountTableWidths, this) {
        /// The presented op is accepted this cycle (low only for a full-table Add while the
        /// minimum is stale; hold the op until high).
        pub ready: bool,
        /// The table accepts any op this cycle (registers only: low only while it is full and
        /// its minimum is stale, [`CountTableStatus::ready`]).
        pub accepts: bool,
        /// The accepted op was invalid and ignored.
        pub error: bool,
        /// An entry was evicted this cycle (its rays go to ray-stationary processing later).
        pub evict_valid: bool,
        /// Treelet of the evicted entry (0 when `evict_valid` is low).
        pub evict_treelet: u64,
        /// Ray count of the evicted entry (0 when `evict_valid` is low).
        pub evict_count: u32,
        /// The max pointer is current and the table is not empty.
        pub max_valid: bool,
        /// The treelet with the most rays (lowest index on ties); 0 when `max_valid` is low.
        pub max_treelet: u64,
        /// Its ray count; 0 when `max_valid` is low.
        pub max_count: u32,
        /// Valid entries.
        pub occupancy: u32,
        /// Entries whose count is at least the underpopulation threshold.
        pub above_threshold: u32,
    }
    ports {
        /// op accepted this cycle (low: full-table Add waits for the minimum)
        sig ready (1) = this.ready as u64;
        /// any op is accepted this cycle (registers only: low only while full with a stale minimum)
        sig accepts (1) = this.accepts as u64;
        /// op invalid (unknown treelet, too many rays, n out of range) and ignored
        sig error (1) = this.error as u64;
        /// an entry was evicted: process its rays ray-stationary later
        sig evict_valid (1) = this.evict_valid as u64;
        /// evicted treelet
        sig evict_treelet (w.treelet) = this.evict_treelet;
        /// rays of the evicted treelet
        sig evict_count (w.count) = this.evict_count as u64;
        /// max_treelet/max_count are current and the table is not empty
        sig max_valid (1) = this.max_valid as u64;
        /// treelet with the most rays (largest treelet queue)
        sig max_treelet (w.treelet) = this.max_treelet;
        /// its ray count
        sig max_count (w.count) = this.max_count as u64;
        /// valid entries
        sig occupancy (w.entries) = this.occupancy as u64;
        /// entries with count >= underpopulation threshold
        sig above_threshold (w.entries) = this.above_threshold as u64;
    }
}

impl CountTableOut {
    /// The register-only ports among these outputs ([`crate::block::Moore`]: what
    /// [`super::CountTable`]'s `status` gives for the registers of the cycle).
    pub fn status(&self) -> CountTableStatus {
        CountTableStatus {
            ready: self.accepts,
            max: self.max_valid.then_some(QueueCount {
                treelet: self.max_treelet as u32,
                count: self.max_count,
            }),
            occupancy: self.occupancy,
            above_threshold: self.above_threshold,
        }
    }
}

/// A treelet and its queued rays, as the count table reports its largest entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct QueueCount {
    /// Treelet address.
    pub treelet: u32,
    /// Rays queued (1..=max_rays; on the wire as count - 1).
    pub count: u32,
}

/// The count table's register-only outputs: what a controller may read before it drives an op
/// in the same cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct CountTableStatus {
    /// The table accepts any op this cycle: low only while it is full and its minimum is stale
    /// (the one case in which it refuses an Add).
    pub ready: bool,
    /// The largest tracked treelet queue, if the max pointer is current (it is stale while the
    /// table rescans after the largest entry shrank, and absent when empty).
    pub max: Option<QueueCount>,
    /// Valid table entries.
    pub occupancy: u32,
    /// Entries holding at least `underpopulation_threshold` rays.
    pub above_threshold: u32,
}
