//! `Aabb`: an axis-aligned bounding box.

use serde::{Deserialize, Serialize};

use super::scalar::{Scalar, wide_sum};
use super::vec3::Vec3;

/// An axis-aligned box `[min, max]` (inclusive).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Aabb {
    /// The lowest corner.
    pub min: Vec3,
    /// The highest corner.
    pub max: Vec3,
}

impl Aabb {
    /// A box from its corners (`min <= max` component-wise expected).
    pub const fn new(min: Vec3, max: Vec3) -> Aabb {
        Aabb { min, max }
    }

    /// The box around a centre with the given half-extents.
    pub fn from_center_half_extents(center: Vec3, half: Vec3) -> Aabb {
        Aabb::new(center - half, center + half)
    }

    /// The smallest box containing both.
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb::new(self.min.min(o.min), self.max.max(o.max))
    }

    /// The smallest box containing `self` and the point `p`.
    pub fn include_point(&self, p: Vec3) -> Aabb {
        Aabb::new(self.min.min(p), self.max.max(p))
    }

    /// Whether the two boxes overlap (touching counts).
    #[inline]
    pub fn overlaps(&self, o: &Aabb) -> bool {
        self.min.x <= o.max.x
            && o.min.x <= self.max.x
            && self.min.y <= o.max.y
            && o.min.y <= self.max.y
            && self.min.z <= o.max.z
            && o.min.z <= self.max.z
    }

    /// Whether `o` lies entirely inside `self`.
    pub fn contains(&self, o: &Aabb) -> bool {
        self.min.x <= o.min.x
            && self.min.y <= o.min.y
            && self.min.z <= o.min.z
            && o.max.x <= self.max.x
            && o.max.y <= self.max.y
            && o.max.z <= self.max.z
    }

    /// Whether the point lies inside (boundary included).
    pub fn contains_point(&self, p: Vec3) -> bool {
        self.min.x <= p.x
            && p.x <= self.max.x
            && self.min.y <= p.y
            && p.y <= self.max.y
            && self.min.z <= p.z
            && p.z <= self.max.z
    }

    /// The box grown by `margin` on every side.
    pub fn expanded(&self, margin: Scalar) -> Aabb {
        let m = Vec3::splat(margin);
        Aabb::new(self.min - m, self.max + m)
    }

    /// The centre.
    pub fn center(&self) -> Vec3 {
        (self.min + self.max).half()
    }

    /// The half-extents.
    pub fn half_extents(&self) -> Vec3 {
        (self.max - self.min).half()
    }

    /// Half the surface area (the cost metric of AABB trees): xy + yz + zx.
    pub fn half_area(&self) -> Scalar {
        let d = self.max - self.min;
        Scalar::from_wide(wide_sum([
            d.x.wide_mul(d.y),
            d.y.wide_mul(d.z),
            d.z.wide_mul(d.x),
        ]))
    }
}
