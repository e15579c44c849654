//! Test support: the one seeded generator that the workspace's tests and
//! benchmarks draw from (re-exported from `lockstep-test-rng`), and the
//! small helpers that turn test numbers into the core's types.
//!
//! Built for the core's own unit tests, and with the `test-support` feature
//! for everyone else (through the `lockstep-testsupport` crate). It is not
//! part of the engine: the simulation never draws a random number, and
//! these helpers go through floating point.

use crate::math::{Scalar, Vec3};

pub use lockstep_test_rng::Rng;

/// A test number as the nearest [`Scalar`].
pub fn s(x: f64) -> Scalar {
    Scalar::from_f64_lossy(x)
}

/// A test vector from three floats, each the nearest [`Scalar`].
pub fn v(x: f64, y: f64, z: f64) -> Vec3 {
    Vec3::new(s(x), s(y), s(z))
}
