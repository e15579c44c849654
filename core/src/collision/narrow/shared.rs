//! What the pair functions share: the relative frame of a pair, adding a
//! manifold point, exact ratios and the box's face loops.

use super::super::manifold::{ContactPoint, FeatureId, Manifold};
use crate::math::scalar::div_round_i128;
use crate::math::{Quat, Scalar, Transform, Vec3};

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
pub(crate) const BOX_FACE_LOOPS: [[u32; 4]; 6] = [
    [0, 4, 6, 2],
    [1, 3, 7, 5],
    [0, 1, 5, 4],
    [2, 6, 7, 3],
    [0, 2, 3, 1],
    [4, 5, 7, 6],
];
