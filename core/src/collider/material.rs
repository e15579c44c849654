//! Surface materials and how two of them combine at a contact.

use serde::{Deserialize, Serialize};

use crate::math::{Scalar, elem};

/// Friction and restitution of a surface.
///
/// Combine rule at a contact between materials A and B (documented in
/// `docs/scene-format.md`): friction is the geometric mean `√(μA·μB)`, so
/// a frictionless surface stays frictionless against anything; restitution
/// is the maximum `max(eA, eB)`, so a bouncy ball bounces on any floor.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Material {
    /// Coulomb friction coefficient, ≥ 0.
    pub friction: Scalar,
    /// Coefficient of restitution in [0, 1].
    pub restitution: Scalar,
}

impl Default for Material {
    /// Friction 0.5, restitution 0.
    fn default() -> Material {
        Material {
            friction: Scalar::HALF,
            restitution: Scalar::ZERO,
        }
    }
}

impl Material {
    /// A material from its coefficients.
    pub fn new(friction: Scalar, restitution: Scalar) -> Material {
        Material {
            friction,
            restitution,
        }
    }

    /// The coefficients used at a contact between `self` and `other`.
    pub fn combine(&self, other: &Material) -> Material {
        Material {
            friction: elem::sqrt(self.friction * other.friction),
            restitution: self.restitution.max(other.restitution),
        }
    }
}
