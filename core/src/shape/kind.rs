//! The kind of a shape, without its data.

use serde::{Deserialize, Serialize};

/// The kind of a shape, without its data: what dispatch tables, logs and
/// scene files name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum ShapeKind {
    /// [`Sphere`](super::sphere::Sphere).
    Sphere,
    /// [`Capsule`](super::capsule::Capsule).
    Capsule,
    /// [`Cuboid`](super::cuboid::Cuboid), named "box".
    Cuboid,
    /// [`ConvexHull`](super::hull::ConvexHull).
    ConvexHull,
    /// [`TriMesh`](super::trimesh::TriMesh).
    TriMesh,
    /// [`HeightField`](super::heightfield::HeightField).
    HeightField,
}

impl ShapeKind {
    /// The stable lower-case name: "sphere", "capsule", "box",
    /// "convex_hull", "trimesh" or "heightfield". Scene files and logs use
    /// it; never change one.
    pub const fn name(self) -> &'static str {
        match self {
            ShapeKind::Sphere => "sphere",
            ShapeKind::Capsule => "capsule",
            ShapeKind::Cuboid => "box",
            ShapeKind::ConvexHull => "convex_hull",
            ShapeKind::TriMesh => "trimesh",
            ShapeKind::HeightField => "heightfield",
        }
    }
}

impl std::fmt::Display for ShapeKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
