//! Random boxes for the tests, drawn from the workspace's one test
//! generator ([`Rng`]).

pub use crate::testing::Rng;

use crate::math::{Aabb, Scalar, Vec3};

/// Fixed-point draws the broad-phase and SAT tests scatter things with.
pub trait Draw {
    /// Uniform Scalar in `[lo, hi)` given in whole units.
    fn scalar(&mut self, lo: i32, hi: i32) -> Scalar;

    /// A vector with each component from [`Draw::scalar`].
    fn vec(&mut self, lo: i32, hi: i32) -> Vec3 {
        Vec3::new(
            self.scalar(lo, hi),
            self.scalar(lo, hi),
            self.scalar(lo, hi),
        )
    }

    /// A box centred in `[-extent, extent)³` with half-extents in
    /// `[0.05, max_half)` on each axis.
    fn aabb(&mut self, extent: i32, max_half: i32) -> Aabb {
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

impl Draw for Rng {
    fn scalar(&mut self, lo: i32, hi: i32) -> Scalar {
        let span = ((hi - lo) as u64) << 32;
        Scalar::from_bits(((lo as i64) << 32) + self.below(span) as i64)
    }
}
