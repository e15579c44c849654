//! A seeded xorshift generator and random boxes for the tests (no `rand`).

use crate::math::{Aabb, Scalar, Vec3};

/// xorshift64*: deterministic, good enough to scatter boxes.
pub struct XorShift(u64);

impl XorShift {
    pub fn new(seed: u64) -> XorShift {
        XorShift(seed.max(1))
    }

    pub fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform f64 in `[0, 1)`.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `0..n` (n > 0), modulo bias irrelevant here.
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }

    /// Uniform Scalar in `[lo, hi)` given in whole units.
    pub fn scalar(&mut self, lo: i32, hi: i32) -> Scalar {
        let span = ((hi - lo) as u64) << 32;
        Scalar::from_bits(((lo as i64) << 32) + self.below(span) as i64)
    }

    pub fn vec(&mut self, lo: i32, hi: i32) -> Vec3 {
        Vec3::new(
            self.scalar(lo, hi),
            self.scalar(lo, hi),
            self.scalar(lo, hi),
        )
    }

    /// A box centred in `[-extent, extent)³` with half-extents in
    /// `[0.05, max_half)` on each axis.
    pub fn aabb(&mut self, extent: i32, max_half: i32) -> Aabb {
        let c = self.vec(-extent, extent);
        let lo = Scalar::from_ratio(1, 20);
        let h = Vec3::new(
            self.scalar(0, max_half).max(lo),
            self.scalar(0, max_half).max(lo),
            self.scalar(0, max_half).max(lo),
        );
        Aabb::from_center_half_extents(c, h)
    }
}
