//! `Transform`: a rigid placement (rotation then translation).

use serde::{Deserialize, Serialize};

use super::quat::Quat;
use super::vec3::Vec3;

/// A rigid transform: `p ↦ rotation · p + translation`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Transform {
    /// Where the local origin lands.
    pub translation: Vec3,
    /// The rotation applied before translating (a unit quaternion).
    pub rotation: Quat,
}

impl Transform {
    /// No motion.
    pub const IDENTITY: Transform = Transform {
        translation: Vec3::ZERO,
        rotation: Quat::IDENTITY,
    };

    /// A transform from its parts.
    pub const fn new(translation: Vec3, rotation: Quat) -> Transform {
        Transform {
            translation,
            rotation,
        }
    }

    /// A pure translation.
    pub const fn from_translation(translation: Vec3) -> Transform {
        Transform::new(translation, Quat::IDENTITY)
    }

    /// Maps a point from local to world.
    #[inline]
    pub fn transform_point(&self, p: Vec3) -> Vec3 {
        self.rotation.rotate(p) + self.translation
    }

    /// Maps a direction from local to world (no translation).
    #[inline]
    pub fn transform_vector(&self, v: Vec3) -> Vec3 {
        self.rotation.rotate(v)
    }

    /// Maps a point from world to local.
    #[inline]
    pub fn inverse_transform_point(&self, p: Vec3) -> Vec3 {
        self.rotation.inverse_rotate(p - self.translation)
    }

    /// Maps a direction from world to local.
    #[inline]
    pub fn inverse_transform_vector(&self, v: Vec3) -> Vec3 {
        self.rotation.inverse_rotate(v)
    }

    /// `self ∘ local`: first `local`, then `self` (a child's world pose from
    /// its parent's world pose and its local pose).
    pub fn mul_transform(&self, local: &Transform) -> Transform {
        Transform::new(
            self.transform_point(local.translation),
            (self.rotation * local.rotation).normalize(),
        )
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Transform {
        let r = self.rotation.conjugate();
        Transform::new(-r.rotate(self.translation), r)
    }
}
