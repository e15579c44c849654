//! Collision filtering: which colliders may touch.

use serde::{Deserialize, Serialize};

/// Category/mask bits plus a group index.
///
/// Two colliders A and B may collide when
/// - they are on different bodies, and
/// - if both have the same non-zero `group`: a positive group always
///   collides, a negative group never does (the mask test is skipped);
/// - otherwise `A.category & B.mask != 0` and `B.category & A.mask != 0`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct CollisionFilter {
    /// The categories this collider belongs to.
    pub category: u32,
    /// The categories it collides with.
    pub mask: u32,
    /// Group index overriding the bits for members of the same group.
    pub group: i32,
}

impl Default for CollisionFilter {
    /// Category 1, collides with everything, no group.
    fn default() -> CollisionFilter {
        CollisionFilter {
            category: 1,
            mask: u32::MAX,
            group: 0,
        }
    }
}

impl CollisionFilter {
    /// Whether colliders with these two filters may collide (the
    /// same-body rule is checked by the caller).
    pub fn allows(&self, other: &CollisionFilter) -> bool {
        if self.group != 0 && self.group == other.group {
            return self.group > 0;
        }
        self.category & other.mask != 0 && other.category & self.mask != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_override_bits_and_bits_must_agree_both_ways() {
        let a = CollisionFilter {
            category: 1,
            mask: 2,
            group: 0,
        };
        let b = CollisionFilter {
            category: 2,
            mask: 1,
            group: 0,
        };
        let c = CollisionFilter {
            category: 2,
            mask: 2,
            group: 0,
        };
        assert!(a.allows(&b) && b.allows(&a));
        assert!(!a.allows(&c));
        let n1 = CollisionFilter {
            group: -3,
            ..CollisionFilter::default()
        };
        assert!(!n1.allows(&n1));
        let p1 = CollisionFilter {
            category: 1,
            mask: 0,
            group: 4,
        };
        assert!(p1.allows(&p1));
        assert!(CollisionFilter::default().allows(&n1));
    }
}
