//! The path tracer's random numbers, as in LumiBench / the OptiX SDK samples: a per-pixel seed
//! from 16 rounds of the TEA block cipher, then a 32-bit LCG producing floats in `[0, 1)`.

use glam::Vec3;

/// TEA with `rounds` rounds over `(v0, v1)`, returning the first word: the OptiX SDK's `tea<N>`
/// helper (key schedule `0xa341316c, 0xc8013ea4, 0xad90777d, 0x7e95761e`, delta `0x9e3779b9`).
pub fn tea(rounds: u32, v0: u32, v1: u32) -> u32 {
    let (mut v0, mut v1) = (v0, v1);
    let mut s0: u32 = 0;
    for _ in 0..rounds {
        s0 = s0.wrapping_add(0x9e37_79b9);
        v0 = v0.wrapping_add(
            (v1 << 4).wrapping_add(0xa341_316c)
                ^ v1.wrapping_add(s0)
                ^ (v1 >> 5).wrapping_add(0xc801_3ea4),
        );
        v1 = v1.wrapping_add(
            (v0 << 4).wrapping_add(0xad90_777d)
                ^ v0.wrapping_add(s0)
                ^ (v0 >> 5).wrapping_add(0x7e95_761e),
        );
    }
    v0
}

pub use crate::model::scene::builtin::{LCG_A, LCG_C};

/// One path's random-number stream: an LCG state seeded by TEA.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rng {
    state: u32,
}

impl Rng {
    /// The stream of sample `sample` of pixel `pixel` (row-major pixel index): seed = `tea<16>(pixel, sample)`.
    pub fn for_pixel(pixel: u32, sample: u32) -> Rng {
        Rng {
            state: tea(16, pixel, sample),
        }
    }

    /// The current LCG state (the seed before the first draw).
    pub fn state(&self) -> u32 {
        self.state
    }

    /// Advance the LCG and return its low 24 bits.
    pub fn next_u24(&mut self) -> u32 {
        self.state = LCG_A.wrapping_mul(self.state).wrapping_add(LCG_C);
        self.state & 0x00FF_FFFF
    }

    /// A float in `[0, 1)`: `(lcg & 0x00FFFFFF) / 0x01000000` (exact in f32).
    pub fn next_f32(&mut self) -> f32 {
        self.next_u24() as f32 / 16_777_216.0
    }

    /// A point strictly inside the unit sphere, by rejection from the cube `[-1, 1)^3`
    /// (x, y, z drawn in that order).
    pub fn in_unit_sphere(&mut self) -> Vec3 {
        loop {
            let p = Vec3::new(self.next_f32(), self.next_f32(), self.next_f32()) * 2.0 - Vec3::ONE;
            if p.length_squared() < 1.0 {
                return p;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lcg_follows_the_recurrence() {
        let mut rng = Rng { state: 0 };
        assert_eq!(rng.next_u24(), LCG_C & 0x00FF_FFFF);
        assert_eq!(rng.state(), LCG_C);
        let expected = LCG_A.wrapping_mul(LCG_C).wrapping_add(LCG_C);
        rng.next_u24();
        assert_eq!(rng.state(), expected);
    }

    #[test]
    fn zero_rounds_of_tea_is_the_identity_on_v0() {
        assert_eq!(tea(0, 1234, 5678), 1234);
        assert_ne!(tea(1, 1234, 5678), 1234);
    }

    #[test]
    fn unit_sphere_points_are_inside() {
        let mut rng = Rng::for_pixel(7, 0);
        for _ in 0..1000 {
            assert!(rng.in_unit_sphere().length_squared() < 1.0);
        }
    }
}
