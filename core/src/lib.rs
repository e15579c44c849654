//! # lockstep-core
//!
//! A deterministic 3D rigid-body engine on Q32.32 fixed-point numbers: the
//! same scene and inputs give bit-identical results on every machine and CPU
//! architecture. See `docs/determinism.md` for the rules the code keeps.

#![warn(missing_docs)]

pub mod collision;
pub mod math;
