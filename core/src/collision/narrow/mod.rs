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
pub(crate) mod shared;
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

use super::manifold::Manifold;
use crate::math::{Scalar, Transform};
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
