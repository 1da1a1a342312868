//! The count table's registers: the entry word, the registered pointers to the largest and
//! smallest entry, the scalar registers, and the rules by which one cycle's change to an
//! entry moves those pointers.

use crate::memory::Memory;

/// One word of the entry array.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CountEntry {
    /// The entry holds a treelet.
    pub valid: bool,
    /// Treelet address.
    pub treelet: u64,
    /// Ray count - 1.
    pub count_m1: u32,
}

/// A registered pointer to an extreme (largest or smallest) entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Extreme {
    /// The pointer names a valid entry and is current.
    pub valid: bool,
    /// Entry index.
    pub idx: u32,
    /// The entry's treelet.
    pub treelet: u64,
    /// The entry's count - 1.
    pub count_m1: u32,
}

impl Extreme {
    pub(super) fn set(idx: u32, treelet: u64, count_m1: u32) -> Self {
        Extreme {
            valid: true,
            idx,
            treelet,
            count_m1,
        }
    }

    /// (count, index) orders before the pointer for a maximum: larger count, then lower index.
    pub(super) fn beaten_as_max(&self, idx: u32, count_m1: u32) -> bool {
        !self.valid || count_m1 > self.count_m1 || (count_m1 == self.count_m1 && idx < self.idx)
    }

    /// (count, index) orders before the pointer for a minimum: smaller count, then lower index.
    pub(super) fn beaten_as_min(&self, idx: u32, count_m1: u32) -> bool {
        !self.valid || count_m1 < self.count_m1 || (count_m1 == self.count_m1 && idx < self.idx)
    }
}

/// Registers of the count table: the entry array and the scalar registers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CountTableRegs {
    /// The entry array.
    pub entries: Memory<CountEntry>,
    /// The scalar registers.
    pub ctl: CountCtl,
}

/// The count table's scalar registers: the scan engine's state, the published pointers and the
/// counters. The next-state function reads them as one start-of-cycle value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CountCtl {
    /// FSM state: false = IDLE, true = SCAN.
    pub scanning: bool,
    /// First entry the scan reads this cycle.
    pub scan_pos: u32,
    /// Published largest entry.
    pub max: Extreme,
    /// Published smallest entry.
    pub min: Extreme,
    /// Scan's largest entry so far.
    pub run_max: Extreme,
    /// Scan's smallest entry so far.
    pub run_min: Extreme,
    /// Valid entries.
    pub occupancy: u32,
    /// Entries with count >= the underpopulation threshold.
    pub above: u32,
}

/// How the op changed one entry this cycle (for the pointer update rules).
#[derive(Debug, Clone, Copy)]
pub(super) enum Change {
    None,
    /// The entry grew, was newly allocated, or was replaced by a larger new treelet.
    Grow {
        idx: u32,
        treelet: u64,
        count_m1: u32,
    },
    /// The entry shrank but stays valid.
    Shrink {
        idx: u32,
        treelet: u64,
        count_m1: u32,
    },
    /// The entry was freed.
    Free {
        idx: u32,
    },
    /// A free entry was allocated.
    Alloc {
        idx: u32,
        treelet: u64,
        count_m1: u32,
    },
}

impl Change {
    pub(super) fn idx(&self) -> Option<u32> {
        match *self {
            Change::None => None,
            Change::Grow { idx, .. }
            | Change::Shrink { idx, .. }
            | Change::Free { idx }
            | Change::Alloc { idx, .. } => Some(idx),
        }
    }

    /// Applies the change to a max pointer; false when the pointer can no longer be trusted.
    pub(super) fn fold_max(&self, x: &mut Extreme) -> bool {
        match *self {
            Change::None => true,
            Change::Grow {
                idx,
                treelet,
                count_m1,
            }
            | Change::Alloc {
                idx,
                treelet,
                count_m1,
            } => {
                if x.beaten_as_max(idx, count_m1) || x.idx == idx {
                    *x = Extreme::set(idx, treelet, count_m1);
                }
                true
            }
            Change::Shrink { idx, .. } | Change::Free { idx } => !(x.valid && x.idx == idx),
        }
    }

    /// Applies the change to a min pointer; false when the pointer can no longer be trusted.
    pub(super) fn fold_min(&self, x: &mut Extreme) -> bool {
        match *self {
            Change::None => true,
            Change::Shrink {
                idx,
                treelet,
                count_m1,
            }
            | Change::Alloc {
                idx,
                treelet,
                count_m1,
            } => {
                if x.beaten_as_min(idx, count_m1) || (x.valid && x.idx == idx) {
                    *x = Extreme::set(idx, treelet, count_m1);
                }
                true
            }
            Change::Grow { idx, .. } | Change::Free { idx } => !(x.valid && x.idx == idx),
        }
    }
}
