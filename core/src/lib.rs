//! # lockstep-core
//!
//! A deterministic 3D rigid-body engine on Q32.32 fixed-point numbers: the
//! same scene and inputs give bit-identical results on every machine and CPU
//! architecture. See `docs/determinism.md` for the rules the code keeps.

#![warn(missing_docs)]

pub mod arena;
pub mod body;
pub mod character;
pub mod collider;
pub mod collision;
pub mod game_state;
pub mod hash;
pub mod joint;
pub mod math;
pub mod query;
pub mod scene;
pub mod shape;
pub mod snapshot;
pub mod solver;
pub(crate) mod workers;
pub mod world;

pub use body::{BodyDesc, BodyHandle, BodyKind};
pub use collider::{ColliderDesc, ColliderHandle, CollisionFilter, Material};
pub use game_state::{GameField, GameState, GameStateError};
pub use joint::{JointDesc, JointEvent, JointHandle, JointKind, Motor, Spring};
/// The elementary functions rules use most (exact to the documented ulp, the
/// same bits on every machine; the rest are in [`math::elem`]).
pub use math::elem::{atan2, sin_cos};
pub use math::{Aabb, Faults, Mat3, Quat, Scalar, SymMat3, Transform, Vec3};
pub use world::{BodyRef, ContactOrder, ContactRows, StepReport, World, WorldConfig, WorldError};
