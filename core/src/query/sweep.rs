//! Shape casts: a convex shape moving along a translation (no rotation),
//! the first time it touches another shape.
//!
//! Method: the time-of-impact routine shared with continuous collision
//! (the collision pipeline's `toi`), with a motion of translation only. Each
//! advance aims at a gap of `TOL/2`; a gap of at most `TOL` is a hit. A shape
//! touching the target at the start is a hit at fraction 0 only while it
//! moves towards it by more than its gap over the whole translation: one
//! resting on a floor and moving along it or away from it is not stopped,
//! even when the computed normal leans by a few ulps (the distance along a
//! translation is a convex function, so a path that closes less than the gap
//! never touches). When the iteration cap is reached (glancing approaches
//! close a share of the gap per step), the last fraction verified apart is
//! reported as the hit: the path beyond it was not proven clear.
//!
//! The reported fraction is therefore *safe*: the moving shape placed there
//! was measured apart from the target, and a converged hit is at most
//! `TOL / v̂_n` earlier than the exact first contact, with `v̂_n` the closing
//! speed along the normal per metre of translation (a head-on hit is at most
//! `TOL` early in distance).
//!
//! Against a triangle mesh or height field, each triangle whose box touches
//! the swept box is swept as a convex shape; the nearest wins, the lowest
//! triangle index on ties.

use super::convex::{QueryError, Triangle, convex_support};
use super::overlap::{box_in_frame, for_each_triangle, raw_box};
use crate::collision::narrow::epa::penetration;
use crate::collision::narrow::gjk::SupportShape;
use crate::collision::toi::{Motion, Toi, ToiPoint, ToiSettings, time_of_impact};
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

/// The sweep settings: aim at `TOL/2`, a hit within `TOL`.
const SETTINGS: ToiSettings = ToiSettings {
    target: Scalar::from_bits(SWEEP_TOLERANCE.to_bits() / 2),
    tolerance: Scalar::from_bits(SWEEP_TOLERANCE.to_bits() / 2),
    max_iterations: MAX_SWEEP_ITERATIONS,
};

/// The sweep of `a` (at `pose_a`, moving by `translation`) against the fixed
/// `b` at `pose_b`, up to fraction `max`.
fn sweep_convex<A: SupportShape + ?Sized, B: SupportShape + ?Sized>(
    a: &A,
    pose_a: &Transform,
    translation: Vec3,
    b: &B,
    pose_b: &Transform,
    max: Scalar,
) -> Option<SweepIntersection> {
    let m = Motion::linear(pose_a, translation);
    let hit = |at: ToiPoint| SweepIntersection {
        fraction: at.fraction,
        point: at.point,
        normal: at.normal,
        initially_overlapping: false,
    };
    match time_of_impact(
        a,
        &Transform::IDENTITY,
        Scalar::ZERO,
        &m,
        b,
        pose_b,
        max,
        &SETTINGS,
    ) {
        // Touching at the start while closing the gap by less than the gap
        // over the whole path: the distance along a translation is convex,
        // so it stays above `gap − closing · fraction > 0` and the path is
        // clear (a shape sliding along a face whose computed normal leans
        // by a few ulps is not stopped).
        Toi::Hit { at, at_start: true } if at.gap > (-translation).dot(at.normal) * max => None,
        Toi::Hit { at, .. } | Toi::Exhausted(at) => Some(hit(at)),
        Toi::Miss => None,
        Toi::Overlapping => {
            let (point, normal) = match penetration(a, pose_a, b, pose_b) {
                Some(p) => (p.point_b, -p.normal),
                None => (
                    pose_a.translation,
                    (-translation).try_normalize().unwrap_or(Vec3::Y),
                ),
            };
            Some(SweepIntersection {
                fraction: Scalar::ZERO,
                point,
                normal,
                initially_overlapping: true,
            })
        }
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
