//! What the workspace's tests and benchmarks share, in one place: the one
//! seeded generator ([`Rng`]), the helpers that write test numbers as the
//! core's types ([`s`], [`v`], [`f`]), a counting global allocator
//! ([`alloc`]), the scenes several tests build ([`scenes`]) and headless
//! Chromium driven through WebDriver for the browser tests ([`webdriver`]).
//!
//! Dev-only: no product crate depends on it. The generator is the
//! dependency-free `lockstep-test-rng` crate (the protocol's tests, which do
//! not depend on the core, draw from it directly); the core re-exports it
//! with the number helpers (`lockstep_core::testing`, behind its
//! `test-support` feature) so that its own unit tests draw from the same
//! generator; this crate turns the feature on and re-exports them.

pub mod alloc;
pub mod scenes;
pub mod webdriver;

pub use lockstep_core::testing::{Rng, s, v};
pub use scenes::{f, ground, pile, pile_in, step_pile, zero_g};
