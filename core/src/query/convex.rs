//! What a sweep or an overlap can move: a convex shape. The error for one
//! that is not, and the GJK support shapes the queries use.

use thiserror::Error;

use crate::collision::narrow::gjk::SupportShape;
use crate::math::Vec3;
use crate::shape::{Shape, ShapeKind};

/// Why a query could not run.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum QueryError {
    /// Sweeps and shape overlaps need a convex query shape (sphere, capsule,
    /// box or hull): triangle meshes and height fields have no inside.
    #[error("a {kind} cannot be swept or overlapped: the query shape must be convex")]
    NonConvexQueryShape {
        /// The kind given.
        kind: ShapeKind,
    },
}

/// A triangle as a convex shape for GJK (sweeps and overlaps against mesh
/// and height-field triangles).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Triangle(pub [Vec3; 3]);

impl SupportShape for Triangle {
    /// The corner farthest along `dir` (exact dot products; the lowest
    /// corner index on ties).
    fn support(&self, dir: Vec3) -> Vec3 {
        let mut best = self.0[0];
        let mut best_d = best.dot_wide(dir);
        for &v in &self.0[1..] {
            let d = v.dot_wide(dir);
            if d > best_d {
                best = v;
                best_d = d;
            }
        }
        best
    }
}

/// The shape as a GJK support shape, or `None` for meshes and height fields.
pub(crate) fn convex_support(shape: &Shape) -> Option<&dyn SupportShape> {
    match shape {
        Shape::Sphere(s) => Some(s),
        Shape::Capsule(c) => Some(c),
        Shape::Cuboid(b) => Some(b),
        Shape::ConvexHull(h) => Some(&**h),
        Shape::TriMesh(_) | Shape::HeightField(_) => None,
    }
}
