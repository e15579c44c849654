//! Collision detection. So far the broad phase: a dynamic AABB tree
//! ([`dynamic_tree`]) and the pair finder built on two of them
//! ([`broad_phase`]). The narrow phase (manifolds, GJK/EPA, SAT, the
//! `contact_<a>_<b>` functions) will sit beside them.

pub mod broad_phase;
pub mod dynamic_tree;

pub use broad_phase::{BroadPhase, BroadPhaseError, PairStats, ProxyId, ProxyKey, ProxyKind};
pub use dynamic_tree::{DynamicTree, LeafId, TreeError};

#[cfg(test)]
mod tests;
