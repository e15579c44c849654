//! Capsule against capsule: closest points of the two core segments, and two
//! points when the segments are parallel so a capsule lying on another one
//! rests on a line, not a single point.

use super::segment::closest_points_segments;
use super::shared::{perpendicular_fallback, push_point, relative_direction, relative_position};
use super::sphere_capsule::segment_feature;
use crate::collision::manifold::{FeatureId, Manifold};
use crate::math::{Scalar, Transform, Vec3};
use crate::shape::Capsule;

/// Id of the two points of a parallel contact (low end, high end along A).
const PARALLEL_FEATURE: u16 = 0x10;

/// Contact between capsules A and B.
///
/// One point at the closest points of the core segments (normal along them,
/// depth `ra + rb − distance`, id `(A feature, B feature)` as in
/// [`segment_feature`](super::sphere_capsule)), except when the axes are
/// within about 1.8° of parallel (sine below 1/32) and B's segment overlaps
/// A's in projection on A's axis over more than 2⁻¹⁶ m: then two points at the
/// ends of that overlap, sharing the closest-points normal, each with its own
/// depth along it, ids `(0x10, 0)` and `(0x10, 1)`.
///
/// Segments that touch or cross: the normal is their common perpendicular
/// (oriented from A to B), or, for collinear axes, A's +y made perpendicular
/// to A's axis (that is A's +x).
pub fn contact_capsule_capsule(
    a: &Capsule,
    pose_a: &Transform,
    b: &Capsule,
    pose_b: &Transform,
    margin: Scalar,
    out: &mut Manifold,
) -> bool {
    out.clear();
    let d = relative_position(pose_a, pose_b);
    let radii = a.radius + b.radius;
    let reach = radii + a.half_height + b.half_height + margin;
    if d.length_squared_wide() > reach.wide_mul(reach) as u128 {
        return false;
    }
    let ha = Vec3::new(Scalar::ZERO, a.half_height, Scalar::ZERO);
    let hb = relative_direction(
        pose_a,
        pose_b,
        Vec3::new(Scalar::ZERO, b.half_height, Scalar::ZERO),
    );
    let (a0, a1, b0, b1) = (-ha, ha, d - hb, d + hb);
    let cp = closest_points_segments(a0, a1, b0, b1);
    let gap = cp.p2 - cp.p1;
    let (n, dist) = match gap.normalize_and_length() {
        Some(x) => x,
        None => {
            let mut n = ha
                .cross(hb)
                .try_normalize()
                .unwrap_or_else(|| perpendicular_fallback(ha));
            if n.dot_wide(d) < 0 {
                n = -n;
            }
            (n, Scalar::ZERO)
        }
    };
    if radii - dist < -margin {
        return false;
    }
    out.normal = pose_a.transform_vector(n);
    let emit = |out: &mut Manifold, pa: Vec3, pb: Vec3, id: FeatureId| {
        let depth = radii - (pb - pa).dot(n);
        if depth >= -margin {
            let mid = (pa + n * a.radius + (pb - n * b.radius)).half();
            push_point(out, pose_a, mid, depth, id);
        }
    };
    // Parallel within 1/32 in sine: |hb × y|² = hb.x² + hb.z² ≤ |hb|² / 1024.
    let off_axis = hb.x.wide_mul(hb.x) + hb.z.wide_mul(hb.z);
    let parallel = a.half_height.is_positive()
        && b.half_height.is_positive()
        && off_axis <= hb.dot_wide(hb) >> 10;
    if parallel {
        let (y0, y1) = (b0.y, b1.y);
        let lo = y0.min(y1).max(-a.half_height);
        let hi = y0.max(y1).min(a.half_height);
        let span = y1 - y0;
        if hi - lo > Scalar::from_bits(1 << 16) && !span.is_zero() {
            for (k, y) in [lo, hi].into_iter().enumerate() {
                let t = (y - y0).checked_div(span).unwrap_or(Scalar::ZERO);
                let pb = b0 + (b1 - b0) * t;
                let pa = Vec3::new(Scalar::ZERO, y, Scalar::ZERO);
                emit(out, pa, pb, FeatureId::pair(PARALLEL_FEATURE, k as u16));
            }
            if !out.is_empty() {
                return true;
            }
        }
    }
    let id = FeatureId::pair(segment_feature(cp.s), segment_feature(cp.t));
    let depth = radii - dist;
    let mid = (cp.p1 + n * a.radius + (cp.p2 - n * b.radius)).half();
    push_point(out, pose_a, mid, depth, id);
    true
}
