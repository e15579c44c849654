//! Tests of the broad phase: tree invariants, queries and pairs against
//! brute force, determinism, allocation.

mod broad_phase;
pub(in crate::collision) mod rng;
mod tree;
