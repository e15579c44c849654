//! Why a shape could not be built.

use thiserror::Error;

use super::kind::ShapeKind;
use crate::math::{Scalar, Vec3};

/// Why a shape could not be built, or has no mass properties.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum ShapeError {
    /// A sphere needs a positive radius.
    #[error("sphere radius must be positive, got {radius}")]
    SphereRadius {
        /// The radius given.
        radius: Scalar,
    },
    /// A capsule needs a positive radius.
    #[error("capsule radius must be positive, got {radius}")]
    CapsuleRadius {
        /// The radius given.
        radius: Scalar,
    },
    /// A capsule's half-height may be zero (a sphere) but not negative.
    #[error("capsule half-height must not be negative, got {half_height}")]
    CapsuleHalfHeight {
        /// The half-height given.
        half_height: Scalar,
    },
    /// A box needs three positive half-extents.
    #[error("box half-extents must all be positive, got {half_extents:?}")]
    CuboidHalfExtents {
        /// The half-extents given.
        half_extents: Vec3,
    },
    /// The hull's points do not enclose any volume.
    #[error(
        "convex hull needs at least 4 points that are not coplanar; \
         got {distinct_points} distinct point(s) spanning {dimension} dimension(s)"
    )]
    DegenerateHull {
        /// Number of distinct input points.
        distinct_points: usize,
        /// Dimension of their affine span: 0 (one point), 1 (a line) or 2
        /// (a plane).
        dimension: u8,
    },
    /// A hull point is too far from the origin for the exact predicates.
    #[error(
        "convex hull point {index} has coordinate {coordinate}, beyond the limit of \
         ±1048576 (2^20 m) that keeps the exact predicates exact"
    )]
    HullCoordinateOutOfRange {
        /// Index of the point in the input slice.
        index: usize,
        /// The offending coordinate.
        coordinate: Scalar,
    },
    /// An internal consistency check of the hull construction failed. This
    /// is a bug, never the input's fault: please report it with the points.
    #[error("convex hull construction failed an internal check ({0}); this is a bug")]
    HullConstruction(&'static str),
    /// A triangle mesh needs at least one triangle.
    #[error("triangle mesh needs at least one triangle")]
    TriMeshEmpty,
    /// A triangle refers to a vertex that does not exist.
    #[error(
        "triangle {triangle} of the mesh uses vertex {index}, but there are only \
         {vertex_count} vertices"
    )]
    TriMeshIndexOutOfRange {
        /// Index of the triangle.
        triangle: usize,
        /// The bad vertex index.
        index: u32,
        /// Number of vertices.
        vertex_count: usize,
    },
    /// A triangle's corners are collinear (or repeated): it has no normal.
    #[error("triangle {triangle} of the mesh has zero area")]
    TriMeshDegenerateTriangle {
        /// Index of the triangle.
        triangle: usize,
    },
    /// A height field needs at least one cell.
    #[error("height field needs at least 2 rows and 2 columns, got {rows}×{cols}")]
    HeightFieldTooSmall {
        /// Rows given.
        rows: u32,
        /// Columns given.
        cols: u32,
    },
    /// The height list does not match the grid size.
    #[error("height field of {rows}×{cols} needs {expected} heights, got {got}")]
    HeightFieldSizeMismatch {
        /// Rows given.
        rows: u32,
        /// Columns given.
        cols: u32,
        /// `rows · cols`.
        expected: u64,
        /// Number of heights given.
        got: usize,
    },
    /// A height field's scale must be positive on every axis.
    #[error("height field scale must be positive on every axis, got {scale:?}")]
    HeightFieldScale {
        /// The scale given.
        scale: Vec3,
    },
    /// The grid's extent or a scaled height does not fit Q32.32.
    #[error("height field extent or a scaled height does not fit the Q32.32 range")]
    HeightFieldOutOfRange,
    /// Triangle meshes and height fields have no volume, hence no mass.
    #[error("a {kind} shape is static-only: it has no mass properties")]
    StaticOnly {
        /// The shape's kind.
        kind: ShapeKind,
    },
    /// Densities must be positive.
    #[error("density must be positive, got {density}")]
    InvalidDensity {
        /// The density given.
        density: Scalar,
    },
    /// The mass or inertia does not fit Q32.32, or the mass rounds to zero.
    #[error(
        "mass properties of the {kind} at density {density} are out of the Q32.32 range \
         (overflow, or a mass that rounds to zero)"
    )]
    MassOutOfRange {
        /// The shape kind's name.
        kind: &'static str,
        /// The density given.
        density: Scalar,
    },
}
