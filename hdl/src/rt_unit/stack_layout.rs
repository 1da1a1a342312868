//! How a lane's on-chip traversal stack is stored in the hardware (the RTL's layout, described
//! by the block; the Rust model keeps each stack as a bounded list, bottom first, and the two
//! agree entry for entry, which co-simulation checks through the lane's behaviour).
//!
//! A stack of `stack_depth` entries is split three ways:
//! - the **window**: its bottom `window` entries in flip-flops, what a spill stores (the oldest
//!   four), a stack fill and an issued record write (at most four, and `record_stack_entries`)
//!   and a completing record carries;
//! - the **rest** in a ring of SRAM: `banks` banks of `bank_words` words, one read and one write
//!   port each, read latency 1; entry `j >= window` is at ring position `base + j - window`,
//!   in bank `position % banks`, word `position / banks`. A test's children (at most
//!   `max_children`, consecutive positions) meet each bank once; a spill moves `base` up
//!   instead of moving entries down, and reads the (at most four) entries that slide into the
//!   window for the next cycle;
//! - the **top** register: a copy of the top entry while it lies in the ring, reloaded by a
//!   one-cycle read after a pop, so the lane's next fetch never waits on the SRAM.
//!
//! A stack no deeper than the window has no ring.

use super::{RtUnitParams, STACK_ENTRIES_PER_CHUNK};
use crate::bits::clog2;
use crate::config::HwConfig;

/// Entries a spill or a stack fill moves at most (one 32 B chunk).
const CHUNK_ENTRIES: u32 = STACK_ENTRIES_PER_CHUNK as u32;

/// The storage of one lane's stack (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StackLayout {
    /// Bottom entries held in flip-flops: `max(4, record_stack_entries)`, at most the depth.
    pub window: u32,
    /// SRAM banks of the ring (0: no ring): `max(max_children, 4)` rounded up to a power of
    /// two, so a test's children and a spill's refill meet each bank once.
    pub banks: u32,
    /// Words per bank, a power of two: the ring holds at least `stack_depth - window` entries.
    pub bank_words: u32,
}

impl StackLayout {
    /// The layout for `cfg` and `params`.
    pub fn new(cfg: &HwConfig, params: &RtUnitParams) -> StackLayout {
        let window = cfg
            .stack_depth
            .min(cfg.record_stack_entries.max(CHUNK_ENTRIES));
        let rest = cfg.stack_depth - window;
        if rest == 0 {
            return StackLayout {
                window,
                banks: 0,
                bank_words: 0,
            };
        }
        let banks = params.max_children.max(CHUNK_ENTRIES).next_power_of_two();
        StackLayout {
            window,
            banks,
            bank_words: rest.div_ceil(banks).next_power_of_two(),
        }
    }

    /// Positions of the ring (`banks x bank_words`, a power of two; 0 without a ring).
    pub fn ring(&self) -> u32 {
        self.banks * self.bank_words
    }

    /// Bits of a ring position (the stack's `base` register): at least 1.
    pub fn position_bits(&self) -> u32 {
        clog2(self.ring().max(2) as u64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_stack_is_a_four_entry_window_and_a_ring_of_eight_banks() {
        let l = StackLayout::new(&HwConfig::default(), &RtUnitParams::default());
        assert_eq!((l.window, l.banks, l.bank_words), (4, 8, 4));
        assert_eq!((l.ring(), l.position_bits()), (32, 5));
    }

    #[test]
    fn a_stack_no_deeper_than_the_window_has_no_ring() {
        let cfg = HwConfig {
            stack_depth: 4,
            record_stack_entries: 2,
            ..HwConfig::default()
        };
        let params = RtUnitParams {
            max_children: 3,
            ..RtUnitParams::default()
        };
        let l = StackLayout::new(&cfg, &params);
        assert_eq!((l.window, l.banks, l.ring()), (4, 0, 0));
        assert_eq!(l.position_bits(), 1);
    }

    #[test]
    fn the_ring_holds_the_rest_and_each_burst_meets_a_bank_once() {
        for depth in [5, 8, 13, 32, 64] {
            for record in [1, 4, depth / 2, depth] {
                for children in [1, 3, 4, 6, 8] {
                    let cfg = HwConfig {
                        stack_depth: depth,
                        record_stack_entries: record.max(1),
                        ..HwConfig::default()
                    };
                    let params = RtUnitParams {
                        max_children: children.min(depth),
                        ..RtUnitParams::default()
                    };
                    let l = StackLayout::new(&cfg, &params);
                    assert!(l.window >= 4.min(depth) && l.window >= cfg.record_stack_entries);
                    assert!(l.window + l.ring() >= depth);
                    if l.banks > 0 {
                        assert!(l.banks >= params.max_children && l.banks >= 4);
                        assert!(l.ring().is_power_of_two());
                    }
                }
            }
        }
    }
}
