//! Statistics counters declared once: [`counters!`](crate::counters!) declares a struct of
//! counters and derives how two of them add up ([`Count`]) from the same field list, so a new
//! counter is one field (and its doc comment) — one cycle's increments added to a running total,
//! one SM's totals added to the whole GPU's, nested groups and per-kind arrays alike.

/// Counters that add up: one cycle's increments to a running total, one SM's to the GPU's.
pub trait Count {
    /// Adds `other`'s counts to these.
    fn add_counts(&mut self, other: &Self);
    /// Takes `other`'s counts from these (an earlier snapshot of the same running total, so
    /// no counter goes below 0): what was counted since the snapshot.
    fn sub_counts(&mut self, other: &Self);
}

impl Count for u64 {
    fn add_counts(&mut self, other: &Self) {
        *self += *other;
    }

    fn sub_counts(&mut self, other: &Self) {
        *self -= *other;
    }
}

impl<T: Count, const N: usize> Count for [T; N] {
    fn add_counts(&mut self, other: &Self) {
        for (a, b) in self.iter_mut().zip(other) {
            a.add_counts(b);
        }
    }

    fn sub_counts(&mut self, other: &Self) {
        for (a, b) in self.iter_mut().zip(other) {
            a.sub_counts(b);
        }
    }
}

/// Declares a struct of counters (every field a `u64`, an array of them or another counters
/// struct) with its doc comments and attributes as written, and implements [`Count`] and an
/// inherent `add` for it from the same field list.
///
/// ```
/// vtq_hdl::counters! {
///     /// Two counters.
///     #[derive(Debug, Default, PartialEq)]
///     pub struct Pair {
///         /// Loads.
///         pub loads: u64,
///         /// Stores per port.
///         pub stores: [u64; 2],
///     }
/// }
/// let mut total = Pair { loads: 1, stores: [2, 3] };
/// total.add(&Pair { loads: 10, stores: [20, 30] });
/// assert_eq!(total, Pair { loads: 11, stores: [22, 33] });
/// total.sub(&Pair { loads: 1, stores: [2, 3] });
/// assert_eq!(total, Pair { loads: 10, stores: [20, 30] });
/// ```
#[macro_export]
macro_rules! counters {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident {
            $( $(#[$fmeta:meta])* $fvis:vis $field:ident : $ty:ty ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        $vis struct $name {
            $( $(#[$fmeta])* $fvis $field: $ty, )*
        }

        impl $crate::counters::Count for $name {
            fn add_counts(&mut self, other: &Self) {
                $( $crate::counters::Count::add_counts(&mut self.$field, &other.$field); )*
            }

            fn sub_counts(&mut self, other: &Self) {
                $( $crate::counters::Count::sub_counts(&mut self.$field, &other.$field); )*
            }
        }

        impl $name {
            /// Adds every counter of `other` to these.
            pub fn add(&mut self, other: &Self) {
                $crate::counters::Count::add_counts(self, other);
            }

            /// Takes every counter of `other`, an earlier snapshot of the same running total,
            /// from these: what was counted since.
            #[allow(dead_code)]
            pub fn sub(&mut self, other: &Self) {
                $crate::counters::Count::sub_counts(self, other);
            }
        }
    };
}
