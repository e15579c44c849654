//! Sphere against box: the sphere's centre clamped to the box, or pushed out
//! through the nearest face when it is inside.

use super::shared::{push_point, relative_position};
use crate::collision::manifold::{FeatureId, Manifold};
use crate::math::{Scalar, Transform, Vec3};
use crate::shape::{Cuboid, Sphere};

/// The box feature a clamped point lies on: per axis 0 inside the slab,
/// 1 on the + side, 2 on the − side, combined as `x + 3y + 9z` (so a face is
/// one nonzero digit, an edge two, a corner three).
pub(crate) fn box_region(p: Vec3, h: Vec3) -> u16 {
    let mut code = 0u16;
    for (k, w) in [1u16, 3, 9].into_iter().enumerate() {
        if p.get(k) > h.get(k) {
            code += w;
        } else if p.get(k) < -h.get(k) {
            code += 2 * w;
        }
    }
    code
}

/// Contact between sphere A and box B, computed in B's frame.
///
/// Centre outside the box: normal from the centre to its clamp onto the box,
/// depth `r − distance`, id `(0, region)` with the face/edge/corner region
/// of [`box_region`]. Centre inside (or on the surface): the face with the
/// least distance to the centre, ties in the order +x, −x, +y, −y, +z, −z;
/// normal minus that face's outward normal, depth `r + distance to face`,
/// id `(0, 27 + face)`. The point is midway between the sphere's deepest
/// point and the box surface.
pub fn contact_sphere_box(
    a: &Sphere,
    pose_a: &Transform,
    b: &Cuboid,
    pose_b: &Transform,
    margin: Scalar,
    out: &mut Manifold,
) -> bool {
    out.clear();
    let c = relative_position(pose_b, pose_a);
    let h = b.half_extents;
    let reach = a.radius + h.x + h.y + h.z + margin;
    if c.length_squared_wide() > reach.wide_mul(reach) as u128 {
        return false;
    }
    let clamped = c.max(-h).min(h);
    let region = box_region(c, h);
    let (n, depth, on_box, id) = if region != 0 {
        let gap = clamped - c;
        let (n, dist) = match gap.normalize_and_length() {
            Some(x) => x,
            None => return false,
        };
        (n, a.radius - dist, clamped, region)
    } else {
        let mut best = (Scalar::MAX, 0usize);
        for k in 0..3 {
            for (s, room) in [(0, h.get(k) - c.get(k)), (1, h.get(k) + c.get(k))] {
                if room < best.0 {
                    best = (room, 2 * k + s);
                }
            }
        }
        let (room, face) = best;
        let k = face / 2;
        let outward = if face % 2 == 0 {
            Scalar::ONE
        } else {
            Scalar::NEG_ONE
        };
        let mut n = Vec3::ZERO;
        n.set(k, -outward);
        let mut on_box = c;
        on_box.set(k, h.get(k) * outward);
        (n, a.radius + room, on_box, 27 + face as u16)
    };
    if depth < -margin {
        return false;
    }
    let deepest = c + n * a.radius;
    out.normal = pose_b.transform_vector(n);
    push_point(
        out,
        pose_b,
        (deepest + on_box).half(),
        depth,
        FeatureId::pair(0, id),
    );
    true
}
