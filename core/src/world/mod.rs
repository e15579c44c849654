//! The `World`: bodies, colliders, settings, and the step that advances them.

mod awake;
mod bodies;
mod body_ref;
mod ccd;
mod collide;
mod config;
mod control;
mod joint_set;
mod joints;
mod observe;
mod poses;
mod query;
mod state;
mod state_hash;
mod step;

pub use crate::hash::FieldKind;
pub use crate::solver::integrate::max_angular_speed;
pub use crate::solver::sleep::SleepConfig;
pub use crate::workers::MAX_WORKERS;
pub use body_ref::BodyRef;
pub use ccd::{CCD_MAX_ITERATIONS, CCD_TARGET_GAP, CCD_TOLERANCE};
pub use config::{
    ContactOrder, ContactRows, MAX_SOLVER_ITERATIONS, MAX_SUBSTEPS, MAX_TICK_RATE, StepReport,
    WorldConfig, WorldError,
};
pub use observe::{Stage, StepObserver};
pub use state::World;
pub use state_hash::{BodyField, STATE_HASH_VERSION};
