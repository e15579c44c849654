//! Sphere against sphere: the centre line is the normal.

use super::shared::{push_point, relative_position};
use crate::collision::manifold::{FeatureId, Manifold};
use crate::math::{Scalar, Transform, Vec3};
use crate::shape::Sphere;

/// Contact between two spheres.
///
/// Normal along the centre line from A to B; depth `ra + rb − distance`
/// (the distance is the floor of the exact length); one point midway between
/// the two surfaces, feature id 0. Coincident centres use A's +y.
pub fn contact_sphere_sphere(
    a: &Sphere,
    pose_a: &Transform,
    b: &Sphere,
    pose_b: &Transform,
    margin: Scalar,
    out: &mut Manifold,
) -> bool {
    out.clear();
    let d = relative_position(pose_a, pose_b);
    let reach = a.radius + b.radius + margin;
    if d.length_squared_wide() > reach.wide_mul(reach) as u128 {
        return false;
    }
    let (n, dist) = d.normalize_and_length().unwrap_or((Vec3::Y, Scalar::ZERO));
    let depth = a.radius + b.radius - dist;
    if depth < -margin {
        return false;
    }
    let on_a = n * a.radius;
    let on_b = d - n * b.radius;
    out.normal = pose_a.transform_vector(n);
    push_point(out, pose_a, (on_a + on_b).half(), depth, FeatureId(0));
    true
}
