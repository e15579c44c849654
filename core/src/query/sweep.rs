//! Shape casts: a convex shape moving along a translation (no rotation),
//! the first time it touches another shape.
//!
//! Method: conservative advancement on the GJK distance. At the current
//! fraction `t`, GJK gives the gap `g` and the separating direction `n`
//! (from the moving shape to the target). Along `n` the gap shrinks at
//! exactly `v_n = translation · n` per unit of `t` while that plane
//! separates the shapes, so advancing by `(g − TOL/2) / v_n` can never pass
//! through the target: the shapes are still at least `TOL/2` apart along
//! `n`. The loop stops when `g ≤ TOL` (a hit at `t`), when `v_n ≤ 0` (moving
//! away: no hit), when `t` passes the limit, or after
//! [`MAX_SWEEP_ITERATIONS`] (reported as no hit: every `t` reached so far was
//! verified apart, and no contact was verified).
//!
//! When rounding lets an advance land in contact, the interval between the
//! last fraction verified apart and that one is halved until a fraction is
//! apart by at most `TOL`; failing that, the last fraction verified apart is
//! reported.
//!
//! The reported fraction is therefore *safe*: the moving shape placed there
//! does not overlap the target, and is at most `TOL / v̂_n` earlier than the
//! exact first contact, with `v̂_n` the closing speed along the normal per
//! metre of translation (a head-on hit is at most `TOL` early in distance).
//!
//! Against a triangle mesh or height field, each triangle whose box touches
//! the swept box is swept as a convex shape; the nearest wins, the lowest
//! triangle index on ties.

use super::overlap::{box_in_frame, for_each_triangle, raw_box};
use super::{QueryError, Triangle, convex_support};
use crate::collision::narrow::epa::penetration;
use crate::collision::narrow::gjk::{DistanceResult, SupportShape, distance};
use crate::math::{Aabb, Scalar, Transform, Vec3};
use crate::shape::Shape;

/// The gap at which a sweep stops and reports a hit: 2⁻¹⁴ m ≈ 6.1e-5 m.
///
/// Why this value: far above the GJK's own resolution (its touch threshold
/// is 16 ulps, its witness points are good to a few ulps), so the normal at
/// the stopping point has some 17 significant bits; far below anything a game
/// places by hand (a tenth of a millimetre), so a shape moved to the
/// reported fraction sits visually on the surface. Each advance aims at half
/// of it, so a face-on approach stops after one step.
pub const SWEEP_TOLERANCE: Scalar = Scalar::from_bits(1 << 18);

/// The most GJK distance evaluations per convex pair. A face-on approach
/// needs 2 (one advance, one check); glancing approaches past curved or
/// edged features converge more slowly (each advance closes a fixed share
/// of the remaining gap).
pub const MAX_SWEEP_ITERATIONS: usize = 32;

/// Where a sweep first touches one shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SweepIntersection {
    /// Time of impact as a fraction of the translation.
    pub fraction: Scalar,
    /// The target's closest point to the moving shape at `fraction`.
    pub point: Vec3,
    /// Unit outward normal of the target there (towards the moving shape).
    pub normal: Vec3,
    /// Whether the shapes overlapped at the start (`fraction` is 0).
    pub initially_overlapping: bool,
}

/// Conservative advancement of `a` (at `pose_a`, moving by `translation`)
/// towards the fixed `b` at `pose_b`, up to fraction `max`.
fn sweep_convex<A: SupportShape + ?Sized, B: SupportShape + ?Sized>(
    a: &A,
    pose_a: &Transform,
    translation: Vec3,
    b: &B,
    pose_b: &Transform,
    max: Scalar,
) -> Option<SweepIntersection> {
    let mut t = Scalar::ZERO;
    // The last fraction verified apart, with the target's closest point and
    // normal there.
    let mut last: Option<(Scalar, Vec3, Vec3)> = None;
    for _ in 0..MAX_SWEEP_ITERATIONS {
        let pa = Transform::new(pose_a.translation + translation * t, pose_a.rotation);
        match distance(a, &pa, b, pose_b) {
            DistanceResult::Overlapping => {
                if let Some(apart) = last {
                    // An advance that aimed at TOL/2 landed in contact
                    // (rounding): the first contact lies between the last
                    // fraction verified apart and this one.
                    return Some(bisect(a, pose_a, translation, b, pose_b, apart, t));
                }
                let (point, normal) = match penetration(a, &pa, b, pose_b) {
                    Some(p) => (p.point_b, -p.normal),
                    None => (
                        pa.translation,
                        (-translation).try_normalize().unwrap_or(Vec3::Y),
                    ),
                };
                return Some(SweepIntersection {
                    fraction: Scalar::ZERO,
                    point,
                    normal,
                    initially_overlapping: true,
                });
            }
            DistanceResult::Separated {
                distance: gap,
                point_b,
                normal,
                ..
            } => {
                if gap <= SWEEP_TOLERANCE {
                    return Some(SweepIntersection {
                        fraction: t,
                        point: point_b,
                        normal: -normal,
                        initially_overlapping: false,
                    });
                }
                let closing = translation.dot(normal);
                if !closing.is_positive() {
                    return None;
                }
                let step = (gap - SWEEP_TOLERANCE.half()).checked_div(closing)?;
                t += step;
                if t > max {
                    return None;
                }
                last = Some((t, point_b, -normal));
            }
        }
    }
    None
}

/// The contact between `apart` (a fraction verified apart, with the
/// target's closest point and normal there) and `overlapping` (a fraction in
/// contact): halves the interval until a fraction is apart by at most
/// [`SWEEP_TOLERANCE`], and otherwise reports the last fraction verified
/// apart. Never a fraction at which the shapes overlap.
fn bisect<A: SupportShape + ?Sized, B: SupportShape + ?Sized>(
    a: &A,
    pose_a: &Transform,
    translation: Vec3,
    b: &B,
    pose_b: &Transform,
    apart: (Scalar, Vec3, Vec3),
    overlapping: Scalar,
) -> SweepIntersection {
    let (mut lo, mut point, mut normal) = apart;
    let mut hi = overlapping;
    for _ in 0..MAX_SWEEP_ITERATIONS {
        // The midpoint rounded down, so that it never reaches `hi`.
        let mid = Scalar::from_bits(lo.to_bits() + ((hi.to_bits() - lo.to_bits()) >> 1));
        if mid == lo {
            break;
        }
        let pa = Transform::new(pose_a.translation + translation * mid, pose_a.rotation);
        match distance(a, &pa, b, pose_b) {
            DistanceResult::Overlapping => hi = mid,
            DistanceResult::Separated {
                distance: gap,
                point_b,
                normal: n,
                ..
            } => {
                (lo, point, normal) = (mid, point_b, -n);
                if gap <= SWEEP_TOLERANCE {
                    break;
                }
            }
        }
    }
    SweepIntersection {
        fraction: lo,
        point,
        normal,
        initially_overlapping: false,
    }
}

/// Sweeps the convex shape `moving` from `pose` along `translation` against
/// `target` at `target_pose`, reporting a first contact at a fraction
/// `≤ max` (see the module documentation for the method and tolerance).
///
/// # Errors
/// [`QueryError::NonConvexQueryShape`] if `moving` is a mesh or height field.
pub fn sweep_shape(
    moving: &Shape,
    pose: &Transform,
    translation: Vec3,
    target: &Shape,
    target_pose: &Transform,
    max: Scalar,
) -> Result<Option<SweepIntersection>, QueryError> {
    let a = convex_support(moving).ok_or(QueryError::NonConvexQueryShape {
        kind: moving.kind(),
    })?;
    if let Some(b) = convex_support(target) {
        return Ok(sweep_convex(a, pose, translation, b, target_pose, max));
    }
    // The swept box in the target's frame, grown by the tolerance.
    let start = box_in_frame(moving, pose, target_pose);
    let shift = target_pose.inverse_transform_vector(translation);
    let end = Aabb::new(start.min + shift, start.max + shift);
    let local = raw_box(&start.union(&end).expanded(SWEEP_TOLERANCE));
    let mut best: Option<SweepIntersection> = None;
    for_each_triangle(target, &local, |_, tri| {
        let limit = best.map_or(max, |b| b.fraction);
        if let Some(h) = sweep_convex(a, pose, translation, &Triangle(tri), target_pose, limit)
            && best.is_none_or(|b| h.fraction < b.fraction)
        {
            best = Some(h);
        }
        true
    });
    Ok(best)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shape::Sphere;

    /// The interval an advance that landed in contact leaves: the result is
    /// apart, within the tolerance of the exact contact, and no later.
    #[test]
    fn bisecting_a_landed_advance_reports_a_fraction_apart() {
        let ball = Sphere::new(Scalar::ONE).unwrap();
        let origin = Transform::IDENTITY;
        let target = Transform::from_translation(Vec3::from_ints(5, 0, 0));
        let translation = Vec3::from_ints(10, 0, 0);
        // The spheres touch when the mover has gone 3 m: fraction 0.3.
        let apart = (Scalar::from_ratio(1, 10), Vec3::ZERO, -Vec3::X);
        let h = bisect(
            &ball,
            &origin,
            translation,
            &ball,
            &target,
            apart,
            Scalar::from_ratio(1, 2),
        );
        assert!(!h.initially_overlapping);
        let exact = Scalar::from_ratio(3, 10);
        assert!(h.fraction <= exact, "{}", h.fraction);
        assert!((exact - h.fraction) * Scalar::from_int(10) <= SWEEP_TOLERANCE);
        let at = Transform::from_translation(translation * h.fraction);
        assert!(matches!(
            distance(&ball, &at, &ball, &target),
            DistanceResult::Separated { .. }
        ));
        assert_eq!(h.normal, -Vec3::X);
        // An interval with nothing apart in it to find keeps the fraction
        // verified apart.
        let h = bisect(
            &ball,
            &origin,
            translation,
            &ball,
            &target,
            apart,
            Scalar::from_ratio(1, 10) + Scalar::from_bits(1),
        );
        assert_eq!(h.fraction, Scalar::from_ratio(1, 10));
    }
}
