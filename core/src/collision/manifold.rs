//! Contact manifolds: what the narrow phase tells the solver about a
//! touching (or nearly touching) pair of shapes.
//!
//! Fixed capacity (at most [`MAX_MANIFOLD_POINTS`] points) so the narrow
//! phase never allocates.

use serde::{Deserialize, Serialize};

use crate::math::{Scalar, Vec3};

/// The most points a manifold keeps (a box face on a box face reduces its
/// clipped polygon to the four points that span the largest area).
pub const MAX_MANIFOLD_POINTS: usize = 4;

/// Identifies a contact point across steps by the features that produced it,
/// so the solver can warm start from last step's impulses. Built by each
/// pair function from its own feature numbering (for example a box face and
/// the incident edge clipped against it); only equality between steps of the
/// same pair matters.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct FeatureId(pub u32);

impl FeatureId {
    /// Packs two 16-bit feature numbers, one per shape.
    pub const fn pair(a: u16, b: u16) -> FeatureId {
        FeatureId(((a as u32) << 16) | b as u32)
    }
}

/// One contact point.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ContactPoint {
    /// World position: the midpoint between the two surfaces along the
    /// normal.
    pub point: Vec3,
    /// Penetration depth along the manifold normal: positive when the shapes
    /// overlap, negative when separated by less than the speculative margin.
    pub depth: Scalar,
    /// The features that made this point.
    pub id: FeatureId,
}

/// The contact between shapes A and B: a shared unit normal pointing from A
/// to B and up to four points.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Manifold {
    /// Unit normal from A to B, world axes.
    pub normal: Vec3,
    /// The points; only the first `count` are meaningful.
    pub points: [ContactPoint; MAX_MANIFOLD_POINTS],
    /// How many points are in use (0 means no contact).
    pub count: u8,
}

impl Manifold {
    /// An empty manifold.
    pub const EMPTY: Manifold = Manifold {
        normal: Vec3::ZERO,
        points: [ContactPoint {
            point: Vec3::ZERO,
            depth: Scalar::ZERO,
            id: FeatureId(0),
        }; MAX_MANIFOLD_POINTS],
        count: 0,
    };

    /// The points in use (a count beyond capacity, as from a corrupted
    /// snapshot, is read as full).
    pub fn points(&self) -> &[ContactPoint] {
        &self.points[..(self.count as usize).min(MAX_MANIFOLD_POINTS)]
    }

    /// Whether there is no contact.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Removes every point.
    pub fn clear(&mut self) {
        self.count = 0;
    }

    /// Adds a point; returns false (and drops it) when full.
    pub fn push(&mut self, p: ContactPoint) -> bool {
        if (self.count as usize) < MAX_MANIFOLD_POINTS {
            self.points[self.count as usize] = p;
            self.count += 1;
            true
        } else {
            false
        }
    }

    /// The same contact seen from B: the normal flips, points and depths
    /// stay.
    pub fn flipped(&self) -> Manifold {
        Manifold {
            normal: -self.normal,
            ..*self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn push_stops_at_capacity_and_flip_only_negates_the_normal() {
        let mut m = Manifold::EMPTY;
        m.normal = Vec3::Y;
        for i in 0..6 {
            let ok = m.push(ContactPoint {
                point: Vec3::from_ints(i, 0, 0),
                depth: Scalar::from_int(i),
                id: FeatureId::pair(i as u16, 7),
            });
            assert_eq!(ok, i < 4);
        }
        assert_eq!(m.points().len(), 4);
        assert_eq!(m.points()[3].id, FeatureId((3 << 16) | 7));
        let f = m.flipped();
        assert_eq!(f.normal, -Vec3::Y);
        assert_eq!(f.points(), m.points());
    }
}
