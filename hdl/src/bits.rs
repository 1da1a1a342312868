//! Fixed-width unsigned values: every hardware field has a width derived from the configuration,
//! and writing a value that does not fit is an error (a `debug_assert` in [`UBits::new`], a
//! [`WidthError`] from [`UBits::try_new`]).

use serde::Serialize;
use std::fmt;

/// A value did not fit in the width of the field it was written to.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("value {value} does not fit in {width} bits")]
pub struct WidthError {
    /// The value that was written.
    pub value: u64,
    /// The width of the field, in bits.
    pub width: u32,
}

/// An unsigned hardware value of a fixed width (1..=64 bits).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default, Serialize)]
pub struct UBits {
    value: u64,
    width: u32,
}

impl UBits {
    /// A value of `width` bits; in debug builds (and so in tests) a value that does not fit panics.
    #[inline]
    pub fn new(value: u64, width: u32) -> Self {
        debug_assert!(
            fits(value, width),
            "value {value} does not fit in a {width}-bit field"
        );
        UBits { value, width }
    }

    /// A value of `width` bits, or an error naming the value and width when it does not fit.
    pub fn try_new(value: u64, width: u32) -> Result<Self, WidthError> {
        if fits(value, width) {
            Ok(UBits { value, width })
        } else {
            Err(WidthError { value, width })
        }
    }

    /// Zero of the given width.
    #[inline]
    pub fn zero(width: u32) -> Self {
        UBits { value: 0, width }
    }

    /// The value.
    #[inline]
    pub fn value(self) -> u64 {
        self.value
    }

    /// The width in bits.
    #[inline]
    pub fn width(self) -> u32 {
        self.width
    }
}

impl fmt::Debug for UBits {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}'d{}", self.width, self.value)
    }
}

/// A bit vector built field by field from bit 0 up, as 64-bit words (word 0 lowest): how a
/// wide port's value (many lanes' records) is laid out for co-simulation.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct BitPacker {
    words: Vec<u64>,
    len: u32,
}

impl BitPacker {
    /// An empty vector.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends the low `width` bits (at most 64) of `value` above the bits so far.
    pub fn push(&mut self, value: u64, width: u32) -> &mut Self {
        debug_assert!(width <= 64, "a field of {width} bits");
        let value = if width >= 64 {
            value
        } else {
            value & ((1u64 << width) - 1)
        };
        let (word, shift) = ((self.len / 64) as usize, self.len % 64);
        let needed = (self.len + width).div_ceil(64) as usize;
        self.words.resize(needed.max(self.words.len()), 0);
        if width > 0 {
            self.words[word] |= value << shift;
            if shift != 0 && shift + width > 64 {
                self.words[word + 1] |= value >> (64 - shift);
            }
        }
        self.len += width;
        self
    }

    /// Bits pushed so far.
    pub fn len(&self) -> u32 {
        self.len
    }

    /// Whether nothing was pushed.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The words, lowest first.
    pub fn into_words(self) -> Vec<u64> {
        self.words
    }
}

/// Whether `value` fits in `width` bits (`width` 0 holds only 0; 64 holds everything).
#[inline]
pub fn fits(value: u64, width: u32) -> bool {
    width >= 64 || value >> width == 0
}

/// Bits needed to index `n` distinct things: ceil(log2(n)), at least 1 (so 4096 -> 12, 600 -> 10).
pub fn clog2(n: u64) -> u32 {
    if n <= 2 {
        1
    } else {
        64 - (n - 1).leading_zeros()
    }
}

/// Bits needed to hold every value in 0..=max (so 32 -> 6, 4095 -> 12, 4096 -> 13).
pub fn bits_for(max: u64) -> u32 {
    (64 - max.leading_zeros()).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packer_lays_fields_from_bit_0_across_words() {
        let mut p = BitPacker::new();
        p.push(0b101, 3).push(u64::MAX, 64).push(0xff, 4);
        assert_eq!(p.len(), 71);
        assert_eq!(p.into_words(), vec![u64::MAX << 3 | 0b101, 0x7f]);
    }

    #[test]
    fn widths() {
        assert_eq!(clog2(4096), 12);
        assert_eq!(clog2(4097), 13);
        assert_eq!(clog2(600), 10);
        assert_eq!(clog2(128), 7);
        assert_eq!(clog2(1), 1);
        assert_eq!(bits_for(32), 6);
        assert_eq!(bits_for(4095), 12);
        assert_eq!(bits_for(0), 1);
    }

    #[test]
    fn try_new_rejects_overflow() {
        assert!(UBits::try_new(4095, 12).is_ok());
        assert_eq!(
            UBits::try_new(4096, 12),
            Err(WidthError {
                value: 4096,
                width: 12
            })
        );
        assert!(UBits::try_new(u64::MAX, 64).is_ok());
    }

    #[test]
    #[should_panic(expected = "does not fit")]
    fn new_panics_on_overflow_in_debug() {
        let _ = UBits::new(8, 3);
    }
}
