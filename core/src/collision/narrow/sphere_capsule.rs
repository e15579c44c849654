//! Sphere against capsule: the sphere's centre against the capsule's core
//! segment.

use super::segment::closest_point_on_segment;
use super::shared::{perpendicular_fallback, push_point, relative_direction, relative_position};
use crate::collision::manifold::{FeatureId, Manifold};
use crate::math::{Scalar, Transform, Vec3};
use crate::shape::{Capsule, Sphere};

/// The feature number of a point at parameter `t` on a capsule's core
/// segment: 1 at the bottom end, 2 at the top end, 0 in between. Shared by
/// the capsule pair functions so that a point sliding along the side keeps
/// its id.
pub(crate) fn segment_feature(t: Scalar) -> u16 {
    if t.is_zero() {
        1
    } else if t == Scalar::ONE {
        2
    } else {
        0
    }
}

/// Contact between sphere A and capsule B.
///
/// The normal runs from the sphere's centre to the closest point of the
/// capsule's segment; depth `ra + rb − distance`; one point midway between
/// the surfaces, id `(0, segment feature)` (1 bottom end, 2 top end, 0 side).
/// A centre exactly on the segment uses A's +y made perpendicular to the
/// capsule's axis.
pub fn contact_sphere_capsule(
    a: &Sphere,
    pose_a: &Transform,
    b: &Capsule,
    pose_b: &Transform,
    margin: Scalar,
    out: &mut Manifold,
) -> bool {
    out.clear();
    let d = relative_position(pose_a, pose_b);
    let reach = a.radius + b.radius + b.half_height + margin;
    if d.length_squared_wide() > reach.wide_mul(reach) as u128 {
        return false;
    }
    let axis = relative_direction(
        pose_a,
        pose_b,
        Vec3::new(Scalar::ZERO, b.half_height, Scalar::ZERO),
    );
    let (t, c) = closest_point_on_segment(Vec3::ZERO, d - axis, d + axis);
    let (n, dist) = c
        .normalize_and_length()
        .unwrap_or_else(|| (perpendicular_fallback(axis), Scalar::ZERO));
    let depth = a.radius + b.radius - dist;
    if depth < -margin {
        return false;
    }
    let on_a = n * a.radius;
    let on_b = c - n * b.radius;
    out.normal = pose_a.transform_vector(n);
    push_point(
        out,
        pose_a,
        (on_a + on_b).half(),
        depth,
        FeatureId::pair(0, segment_feature(t)),
    );
    true
}
