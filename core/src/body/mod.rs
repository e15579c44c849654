//! Rigid bodies: handles, descriptions, hot and cold state, and the set that
//! stores them.

mod awake;
mod desc;
mod set;
mod state;

pub use desc::BodyDesc;
pub use set::BodySet;
pub use state::{BodyCold, BodyHot, BodyKind};

pub use crate::handles::BodyHandle;
