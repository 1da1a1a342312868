//! SplitMix64 (Steele, Lea and Flood, "Fast splittable pseudorandom number generators", OOPSLA
//! 2014): vtq's one seeded generator, small, fast and fully determined by its seed. It lives in
//! the lowest crate so that every crate and test shares it: the generated cities (`city:N`), the
//! sampled tier's CTA draws, the fuzzer's inputs, `vtq-gen`'s co-simulation stimulus and the
//! randomized tests use it, so each is reproduced exactly by its seed. It is not hardware. (The path tracer's per-pixel random numbers are
//! LumiBench's TEA-seeded LCG, `workload/rng.rs`, part of the workload's definition.)

/// The generator's state.
#[derive(Debug, Clone)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator started from `seed`.
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A number in `0..n` from the top 32 bits by multiply and shift (fast, uniform to within
    /// `n / 2^32`; 0 when `n` is 0).
    pub fn below(&mut self, n: u64) -> u64 {
        (((self.next_u64() >> 32) as u128 * n as u128) >> 32) as u64
    }

    /// A number in `0..n`, exactly uniform (rejection; `n > 0`).
    pub fn below_exact(&mut self, n: u64) -> u64 {
        let zone = u64::MAX - u64::MAX % n;
        loop {
            let x = self.next_u64();
            if x < zone {
                return x % n;
            }
        }
    }

    /// A float in `[0, 1)` (24 random bits).
    pub fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / 16_777_216.0
    }

    /// A float in `[lo, hi)`.
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_reference_sequence() {
        // SplitMix64 from seed 0 (the published reference values).
        let mut r = SplitMix64::new(0);
        assert_eq!(r.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(r.next_u64(), 0x6E78_9E6A_A1B9_65F4);
        let mut r = SplitMix64::new(7);
        for n in [1u64, 3, 1000, 1 << 40] {
            assert!(r.below(n) < n);
            assert!(r.below_exact(n) < n);
        }
        assert_eq!(r.below(0), 0);
        let u = r.range(2.0, 3.0);
        assert!((2.0..3.0).contains(&u));
    }
}
