//! Scene queries: ray casts, shape sweeps and overlap tests against a
//! world's colliders (the `World` methods are in `world/query.rs`), and the
//! per-shape geometry they rest on.
//!
//! * [`ray`]: a ray against each shape kind (sphere, capsule, box slab test,
//!   hull plane clipping, mesh triangles, height-field cells);
//! * [`sweep`]: a convex shape moving along a translation, time of impact by
//!   conservative advancement on the GJK distance;
//! * [`overlap`]: whether a convex shape at a pose intersects a shape;
//! * [`filter`]: [`QueryFilter`], which colliders a query considers.
//!
//! Conventions shared by every query:
//! * a ray or sweep is `start + t · translation` with the *fraction*
//!   `t ∈ [0, 1]`;
//! * a hit's normal is the unit outward normal of the collider that was hit
//!   (it points back towards the ray or the moving shape);
//! * integer arithmetic only, no allocation in the per-shape code, ties go
//!   to the lowest feature index (axis, face, triangle, cell), and between
//!   colliders to the lowest collider handle;
//! * queries read the world and never change it (`&self`).

mod convex;
pub mod filter;
pub mod overlap;
pub mod ray;
pub mod sweep;

pub use convex::QueryError;
pub(crate) use convex::{Triangle, convex_support};
pub use filter::{QueryFilter, QueryPredicate};
pub use overlap::shapes_overlap;
pub use ray::{Ray, RayIntersection, cast_ray_shape};
pub use sweep::{MAX_SWEEP_ITERATIONS, SWEEP_TOLERANCE, SweepIntersection, sweep_shape};

use crate::body::BodyHandle;
use crate::collider::ColliderHandle;
use crate::math::{Scalar, Vec3};

/// A ray hit on a collider.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RayHit {
    /// The collider hit.
    pub collider: ColliderHandle,
    /// Its body.
    pub body: BodyHandle,
    /// Where along the ray, `[0, 1]` of its translation.
    pub fraction: Scalar,
    /// The hit point, world frame: `origin + fraction · translation`.
    pub point: Vec3,
    /// Unit outward normal of the collider at the point (opposite the ray
    /// for a ray that starts inside a solid shape).
    pub normal: Vec3,
}

/// A shape-sweep hit on a collider.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShapeHit {
    /// The collider hit.
    pub collider: ColliderHandle,
    /// Its body.
    pub body: BodyHandle,
    /// The time of impact as a fraction of the translation, `[0, 1]`: the
    /// moving shape placed there is apart from the collider by at most
    /// [`SWEEP_TOLERANCE`] and does not overlap it.
    pub fraction: Scalar,
    /// The closest point of the collider to the moving shape at `fraction`
    /// (world frame).
    pub point: Vec3,
    /// Unit outward normal of the collider there (pointing at the moving
    /// shape).
    pub normal: Vec3,
    /// The shapes already overlapped at the start (`fraction` is 0, and the
    /// normal is the direction that separates them fastest).
    pub initially_overlapping: bool,
}

/// A collider found by an overlap query.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct OverlapHit {
    /// The collider.
    pub collider: ColliderHandle,
    /// Its body.
    pub body: BodyHandle,
}
