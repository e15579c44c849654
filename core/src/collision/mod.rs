//! Collision detection. The broad phase: a dynamic AABB tree
//! ([`dynamic_tree`]) and the pair finder built on two of them
//! ([`broad_phase`]), and the manifold type the narrow phase fills
//! ([`manifold`]), and the narrow phase's pair functions ([`narrow`]).

pub mod broad_phase;
pub mod contacts;
pub mod dynamic_tree;
pub mod manifold;
pub mod narrow;
pub mod reuse;
pub mod toi;

pub use broad_phase::{BroadPhase, PairStats, ProxyId, ProxyKey, ProxyKind};
pub use contacts::{
    ContactEvent, ContactEventKind, ContactPair, ContactSet, PairKind, PatchFriction, PointImpulse,
};
pub use manifold::{ContactPoint, FeatureId, MAX_MANIFOLD_POINTS, Manifold};
pub use reuse::ReuseCache;

#[cfg(test)]
mod tests;
