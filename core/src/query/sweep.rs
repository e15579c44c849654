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
    let mut last: Option<(Vec3, Vec3)> = None;
    for _ in 0..MAX_SWEEP_ITERATIONS {
        let pa = Transform::new(pose_a.translation + translation * t, pose_a.rotation);
        match distance(a, &pa, b, pose_b) {
            DistanceResult::Overlapping => {
                if let Some((point, normal)) = last {
                    // An advance that aimed at TOL/2 landed in contact
                    // (rounding): report it with the last good normal.
                    return Some(SweepIntersection {
                        fraction: t,
                        point,
                        normal,
                        initially_overlapping: false,
                    });
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
                last = Some((point_b, -normal));
            }
        }
    }
    None
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
