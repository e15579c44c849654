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
pub(crate) mod collision;
pub mod game_state;
mod handles;
pub mod hash;
pub mod joint;
pub mod math;
pub mod query;
pub mod scene;
mod scratch;
pub mod shape;
pub mod snapshot;
pub(crate) mod solver;
#[cfg(any(test, feature = "test-support"))]
pub mod testing;
pub(crate) mod workers;
pub mod world;

/// Contacts as the world reports them: the pairs of colliders whose boxes
/// overlap, with their manifolds and accumulated impulses
/// ([`World::contact_pairs`]), and the begin and end events of the last
/// step ([`World::contact_events`]). The collision pipeline that makes them
/// is internal.
pub mod contact {
    pub use crate::collision::contacts::{MATCH_DISTANCE, TOUCH_TOLERANCE};
    pub use crate::collision::reuse::{REUSE_ANGLE_SIN_HALF, REUSE_DISTANCE};
    pub use crate::collision::{
        ContactEvent, ContactEventKind, ContactPair, ContactPoint, FeatureId, MAX_MANIFOLD_POINTS,
        Manifold, PairKind, PatchFriction, PointImpulse, ReuseCache,
    };
}

pub use body::{BodyDesc, BodyHandle, BodyKind};
pub use collider::{ColliderDesc, ColliderHandle, CollisionFilter, Material};
pub use contact::{ContactEvent, ContactEventKind};
pub use game_state::{GameField, GameState, GameStateError};
pub use joint::{JointDesc, JointEvent, JointHandle, JointKind, Motor, Spring};
/// The elementary functions rules use most (exact to the documented ulp, the
/// same bits on every machine; the rest are in [`math::elem`]).
pub use math::elem::{atan2, sin_cos};
pub use math::{Aabb, Faults, Mat3, Quat, Scalar, SymMat3, Transform, Vec3};
pub use world::{
    BodyRef, ContactOrder, ContactRows, SleepConfig, StepReport, World, WorldConfig, WorldError,
};
