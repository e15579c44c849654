//! The handles of bodies and colliders: a leaf that the body, collider and
//! collision modules all import, so none of them imports another for them.

use serde::{Deserialize, Serialize};

use crate::arena::RawHandle;

/// Identifies a body: `{index, generation}`. Stale handles (of removed
/// bodies) are refused by every world method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct BodyHandle(pub RawHandle);

impl BodyHandle {
    /// The slot index (handle order is index order).
    pub fn index(self) -> u32 {
        self.0.index
    }

    /// The slot generation.
    pub fn generation(self) -> u32 {
        self.0.generation
    }
}

impl std::fmt::Display for BodyHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "body#{}v{}", self.0.index, self.0.generation)
    }
}

/// Identifies a collider: `{index, generation}`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct ColliderHandle(pub RawHandle);

impl ColliderHandle {
    /// The slot index.
    pub fn index(self) -> u32 {
        self.0.index
    }
}
