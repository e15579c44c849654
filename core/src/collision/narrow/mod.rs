//! The narrow phase: one pure function per pair of convex shape kinds that
//! fills a [`Manifold`] (normal from A to B, up to four points with depths
//! and feature ids), and [`contact`], the dispatcher over [`Shape`]s.
//!
//! Conventions shared by every pair function (see each file):
//! - `contact_<a>_<b>(a, pose_a, b, pose_b, margin, out) -> bool` clears
//!   `out`, fills it, and returns `!out.is_empty()`. Shapes separated by at
//!   most `margin` still get points, with negative depth.
//! - The geometry is done in one shape's local frame, with the other shape's
//!   pose built from the exact difference of the two translations, so moving
//!   both poses by the same offset moves the points by exactly that offset
//!   and leaves normals and depths bit-identical.
//! - Integer arithmetic only; ties go to the lowest feature index; every
//!   degenerate case has a documented fallback instead of a panic.
//!
//! Kind order for the dispatcher: sphere < capsule < box < hull < triangle
//! mesh < height field. A pair whose first shape ranks after the second is
//! computed swapped and [flipped](Manifold::flipped). Convex shapes against
//! meshes and height fields are in [`mesh_contact`] (the mesh is always B).

pub mod box_box;
pub mod capsule_box;
pub mod capsule_capsule;
pub mod clip;
pub mod epa;
pub mod gjk;
pub mod hull_contact;
pub mod mesh_contact;
mod polytope;
pub mod segment;
pub mod sphere_box;
pub mod sphere_capsule;
pub mod sphere_sphere;
pub mod triangle;

#[cfg(test)]
mod tests_analytic;
#[cfg(test)]
mod tests_box;
#[cfg(test)]
mod tests_mesh;

pub use box_box::contact_box_box;
pub use capsule_box::contact_capsule_box;
pub use capsule_capsule::contact_capsule_capsule;
pub use hull_contact::{
    contact_box_hull, contact_capsule_hull, contact_hull_hull, contact_sphere_hull,
};
pub use mesh_contact::{
    contact_box_heightfield, contact_box_trimesh, contact_capsule_heightfield,
    contact_capsule_trimesh, contact_hull_heightfield, contact_hull_trimesh,
    contact_sphere_heightfield, contact_sphere_trimesh,
};
pub use segment::closest_point_on_segment;
pub use sphere_box::contact_sphere_box;
pub use sphere_capsule::contact_sphere_capsule;
pub use sphere_sphere::contact_sphere_sphere;

use super::manifold::{ContactPoint, FeatureId, Manifold};
use crate::math::scalar::div_round_i128;
use crate::math::{Quat, Scalar, Transform, Vec3};
use crate::shape::Shape;

/// Contact between any two shapes: the entry point the contact pipeline calls
/// for every candidate pair, so it needs no knowledge of pair functions.
///
/// Clears `out`; returns `!out.is_empty()`. Convex pairs whose first kind
/// ranks after the second (sphere < capsule < box < hull) are computed with
/// the shapes swapped and the manifold [flipped](Manifold::flipped): the
/// normal still points from `shape_a` to `shape_b`, points keep their order.
///
/// Convex shapes against triangle meshes and height fields go to
/// [`mesh_contact`] (mesh or height field as B, flipped when given as A).
/// Mesh–mesh, mesh–height-field and height-field–height-field pairs return
/// `false` with `out` empty: both shapes are static-only, so the broad phase
/// never creates such pairs.
pub fn contact(
    shape_a: &Shape,
    pose_a: &Transform,
    shape_b: &Shape,
    pose_b: &Transform,
    margin: Scalar,
    out: &mut Manifold,
) -> bool {
    use Shape::*;
    // Every arm that does not return computes the pair swapped.
    let hit = match (shape_a, shape_b) {
        (Sphere(a), Sphere(b)) => return contact_sphere_sphere(a, pose_a, b, pose_b, margin, out),
        (Sphere(a), Capsule(b)) => {
            return contact_sphere_capsule(a, pose_a, b, pose_b, margin, out);
        }
        (Sphere(a), Cuboid(b)) => return contact_sphere_box(a, pose_a, b, pose_b, margin, out),
        (Sphere(a), ConvexHull(b)) => {
            return contact_sphere_hull(a, pose_a, b, pose_b, margin, out);
        }
        (Capsule(a), Capsule(b)) => {
            return contact_capsule_capsule(a, pose_a, b, pose_b, margin, out);
        }
        (Capsule(a), Cuboid(b)) => return contact_capsule_box(a, pose_a, b, pose_b, margin, out),
        (Capsule(a), ConvexHull(b)) => {
            return contact_capsule_hull(a, pose_a, b, pose_b, margin, out);
        }
        (Cuboid(a), Cuboid(b)) => return contact_box_box(a, pose_a, b, pose_b, margin, out),
        (Cuboid(a), ConvexHull(b)) => return contact_box_hull(a, pose_a, b, pose_b, margin, out),
        (ConvexHull(a), ConvexHull(b)) => {
            return contact_hull_hull(a, pose_a, b, pose_b, margin, out);
        }
        (Capsule(a), Sphere(b)) => contact_sphere_capsule(b, pose_b, a, pose_a, margin, out),
        (Cuboid(a), Sphere(b)) => contact_sphere_box(b, pose_b, a, pose_a, margin, out),
        (Cuboid(a), Capsule(b)) => contact_capsule_box(b, pose_b, a, pose_a, margin, out),
        (ConvexHull(a), Sphere(b)) => contact_sphere_hull(b, pose_b, a, pose_a, margin, out),
        (ConvexHull(a), Capsule(b)) => contact_capsule_hull(b, pose_b, a, pose_a, margin, out),
        (ConvexHull(a), Cuboid(b)) => contact_box_hull(b, pose_b, a, pose_a, margin, out),
        (Sphere(a), TriMesh(b)) => {
            return contact_sphere_trimesh(a, pose_a, b, pose_b, margin, out);
        }
        (Capsule(a), TriMesh(b)) => {
            return contact_capsule_trimesh(a, pose_a, b, pose_b, margin, out);
        }
        (Cuboid(a), TriMesh(b)) => return contact_box_trimesh(a, pose_a, b, pose_b, margin, out),
        (ConvexHull(a), TriMesh(b)) => {
            return contact_hull_trimesh(a, pose_a, b, pose_b, margin, out);
        }
        (Sphere(a), HeightField(b)) => {
            return contact_sphere_heightfield(a, pose_a, b, pose_b, margin, out);
        }
        (Capsule(a), HeightField(b)) => {
            return contact_capsule_heightfield(a, pose_a, b, pose_b, margin, out);
        }
        (Cuboid(a), HeightField(b)) => {
            return contact_box_heightfield(a, pose_a, b, pose_b, margin, out);
        }
        (ConvexHull(a), HeightField(b)) => {
            return contact_hull_heightfield(a, pose_a, b, pose_b, margin, out);
        }
        (TriMesh(a), Sphere(b)) => contact_sphere_trimesh(b, pose_b, a, pose_a, margin, out),
        (TriMesh(a), Capsule(b)) => contact_capsule_trimesh(b, pose_b, a, pose_a, margin, out),
        (TriMesh(a), Cuboid(b)) => contact_box_trimesh(b, pose_b, a, pose_a, margin, out),
        (TriMesh(a), ConvexHull(b)) => contact_hull_trimesh(b, pose_b, a, pose_a, margin, out),
        (HeightField(a), Sphere(b)) => {
            contact_sphere_heightfield(b, pose_b, a, pose_a, margin, out)
        }
        (HeightField(a), Capsule(b)) => {
            contact_capsule_heightfield(b, pose_b, a, pose_a, margin, out)
        }
        (HeightField(a), Cuboid(b)) => contact_box_heightfield(b, pose_b, a, pose_a, margin, out),
        (HeightField(a), ConvexHull(b)) => {
            contact_hull_heightfield(b, pose_b, a, pose_a, margin, out)
        }
        (TriMesh(_) | HeightField(_), TriMesh(_) | HeightField(_)) => {
            out.clear();
            return false;
        }
    };
    *out = out.flipped();
    hit
}

/// B's centre in A's local frame, rotated from the exact world difference of
/// the translations (so it does not depend on where the pair sits in the
/// world). The cheap part of [`relative_pose`] for pairs that need no
/// relative rotation.
pub(crate) fn relative_position(pose_a: &Transform, pose_b: &Transform) -> Vec3 {
    pose_a
        .rotation
        .inverse_rotate(pose_b.translation - pose_a.translation)
}

/// A direction `v` of B's local frame expressed in A's local frame (two
/// rotations; cheaper than building and normalising the relative rotation
/// when only one axis is needed, as for a capsule).
pub(crate) fn relative_direction(pose_a: &Transform, pose_b: &Transform, v: Vec3) -> Vec3 {
    pose_a.rotation.inverse_rotate(pose_b.rotation.rotate(v))
}

/// B's placement in A's local frame: B's centre (rotated from the exact
/// world difference of the translations, so it does not depend on where the
/// pair sits in the world) and B's rotation relative to A.
pub(crate) fn relative_pose(pose_a: &Transform, pose_b: &Transform) -> (Vec3, Quat) {
    let d = pose_a
        .rotation
        .inverse_rotate(pose_b.translation - pose_a.translation);
    let q = (pose_a.rotation.conjugate() * pose_b.rotation).normalize();
    (d, q)
}

/// Writes one point given in the frame `pose` maps to world.
pub(crate) fn push_point(
    out: &mut Manifold,
    pose: &Transform,
    point: Vec3,
    depth: Scalar,
    id: FeatureId,
) {
    out.push(ContactPoint {
        point: pose.transform_point(point),
        depth,
        id,
    });
}

/// `num / den` clamped to `[0, 1]` as a Scalar, rounded to nearest; `den`
/// must be positive (zero gives 0). Both are integers in any common scale
/// (Q32.32 or Q64.64), so the ratio of two exact accumulators loses nothing
/// before the one rounding. Large operands are shifted down together first
/// so `num << 32` fits (a relative change below 2⁻⁶⁰).
pub(crate) fn ratio01(num: i128, den: i128) -> Scalar {
    if den <= 0 || num <= 0 {
        return Scalar::ZERO;
    }
    if num >= den {
        return Scalar::ONE;
    }
    let bits = 128 - den.leading_zeros();
    let (mut n, mut d) = (num, den);
    if bits > 94 {
        let s = bits - 94;
        n >>= s;
        d >>= s;
    }
    Scalar::from_bits(div_round_i128(n << 32, d) as i64)
}

/// A Q32.32 value widened to the Q64.64 scale of [`Scalar::wide_mul`].
#[inline(always)]
pub(crate) fn widen(s: Scalar) -> i128 {
    (s.to_bits() as i128) << 32
}

/// A unit vector perpendicular to `axis`, the deterministic fallback normal
/// when two cores touch and the contact direction is otherwise undefined:
/// A's +y made perpendicular to `axis`, or +x when `axis` is along y, or +y
/// itself when `axis` is zero.
pub(crate) fn perpendicular_fallback(axis: Vec3) -> Vec3 {
    if axis.is_zero() {
        return Vec3::Y;
    }
    let w = axis.cross(Vec3::Y).cross(axis);
    if let Some(n) = w.try_normalize() {
        return n;
    }
    axis.cross(Vec3::X)
        .cross(axis)
        .try_normalize()
        .unwrap_or(Vec3::X)
}

/// The tolerance by which a later SAT axis must beat an earlier one to be
/// chosen (faces before edges, A's face before B's): 1/32 of the current
/// best separation's magnitude plus 2⁻¹¹ m. Keeps resting stacks on the same
/// feature from step to step instead of flickering between near-equal axes.
pub(crate) fn sat_tolerance(best: Scalar) -> Scalar {
    Scalar::from_bits((best.abs().to_bits() >> 5) + (1 << 21))
}

/// Box faces by corner index bits (bit 0: +x, bit 1: +y, bit 2: +z), in the
/// order −x, +x, −y, +y, −z, +z, counter-clockwise seen from outside: the
/// polytope SAT and the triangle–box test walk the same loops.
pub(super) const BOX_FACE_LOOPS: [[u32; 4]; 6] = [
    [0, 4, 6, 2],
    [1, 3, 7, 5],
    [0, 1, 5, 4],
    [2, 6, 7, 3],
    [0, 2, 3, 1],
    [4, 5, 7, 6],
];
