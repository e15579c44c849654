//! Tests of the broad phase: tree invariants, queries and pairs against
//! brute force, determinism, allocation, timing.

mod broad_phase;
mod rng;
mod tree;
