//! Friction at the centre of each manifold's contact patch: the per-tick
//! constants of the two tangent rows and the twist row (the passes that
//! solve them are in the parent module).

use super::rows::{cross, effective, inverse_or_zero, mul, round_wide, scale};
use super::{Constraint, NONE, SolverBody};
use crate::collision::contacts::TOUCH_TOLERANCE;
use crate::collision::{ContactPair, MAX_MANIFOLD_POINTS};
use crate::math::scalar::wide_sum;
use crate::math::{Scalar, Vec3};

/// Friction of one manifold, solved at the centre of its contact patch
/// (the mean of its points) rather than at every point: two tangent rows
/// bounded by μ times the manifold's total normal impulse, and a twist row
/// about the normal bounded by μ times that total times the points' mean
/// distance from the centre. For a patch whose points share the load, the
/// friction force and its moment about the centre are the same as
/// per-point friction's, with three rows per manifold instead of two per
/// point (eight for a box face).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Patch {
    /// `ra × t_j`, `rb × t_j` for the anchor at the patch centre.
    pub(super) ra_t: [Vec3; 2],
    pub(super) rb_t: [Vec3; 2],
    /// `I⁻¹A (ra × t_j)`, `I⁻¹B (rb × t_j)`.
    pub(super) ia_t: [Vec3; 2],
    pub(super) ib_t: [Vec3; 2],
    /// `1/k` along each tangent.
    pub(super) tangent_mass: [Scalar; 2],
    /// `I⁻¹A n`, `I⁻¹B n`: the spin change per unit twist impulse.
    pub(super) ia_w: Vec3,
    pub(super) ib_w: Vec3,
    /// `1/k` of the twist row.
    pub(super) twist_mass: Scalar,
    /// μ times the points' mean distance from the centre: the twist bound
    /// per unit of total normal impulse.
    pub(super) twist_reach: Scalar,
    /// Accumulated tangent and twist impulses.
    pub(super) tangent_impulse: [Scalar; 2],
    pub(super) twist_impulse: Scalar,
    /// The two tangent and the twist impulses at the last write-back of
    /// angular impulses.
    pub(super) mark: [Scalar; 3],
}

/// The friction rows of pair `p` for constraint `c` (its normal, tangents
/// and friction already set) between solver bodies `ba` and `bb` (a body
/// that is `NONE` in `c`, static or asleep, takes no anchor), warm-started
/// from the pair's stored patch friction.
///
/// The centre is the mean of the touching points (all points if none
/// touches yet): a speculative point where nothing touches must not move
/// the friction off the actual contact.
pub(super) fn prepare_patch(
    p: &ContactPair,
    c: &Constraint,
    ba: &SolverBody,
    bb: &SolverBody,
) -> Patch {
    let n = c.normal;
    let pts = p.manifold.points();
    let touching = |q: &&crate::collision::ContactPoint| q.depth >= -TOUCH_TOLERANCE;
    let use_all = !pts.iter().any(|q| touching(&q));
    let chosen = || pts.iter().filter(move |q| use_all || touching(q));
    // 1/1, 1/2, 1/3, 1/4 (1/3 rounded to nearest): a mean is one product,
    // not a division.
    const RECIP: [Scalar; MAX_MANIFOLD_POINTS] = [
        Scalar::ONE,
        Scalar::from_bits(1 << 31),
        Scalar::from_bits(1_431_655_765),
        Scalar::from_bits(1 << 30),
    ];
    let inv = RECIP[chosen().count().clamp(1, MAX_MANIFOLD_POINTS) - 1];
    // Offsets from one of the points, not world positions, are summed: four
    // points far from the origin would overflow a sum of positions.
    let base = chosen().next().map_or(Vec3::ZERO, |q| q.point);
    let sum = chosen().fold(Vec3::ZERO, |acc, q| acc + (q.point - base));
    let center = base + scale(sum, inv);
    let spread = mul(
        chosen().fold(Scalar::ZERO, |acc, q| acc + (q.point - center).length()),
        inv,
    );
    let ra = if c.a == NONE {
        Vec3::ZERO
    } else {
        center - ba.center0
    };
    let rb = if c.b == NONE {
        Vec3::ZERO
    } else {
        center - bb.center0
    };
    let mut f = Patch {
        tangent_impulse: p.friction.tangent,
        twist_impulse: p.friction.twist,
        mark: [
            p.friction.tangent[0],
            p.friction.tangent[1],
            p.friction.twist,
        ],
        twist_reach: c.friction * spread,
        ..Patch::default()
    };
    for (j, &t) in c.tangent.iter().enumerate() {
        f.ra_t[j] = cross(ra, t);
        f.rb_t[j] = cross(rb, t);
        f.ia_t[j] = ba.inv_inertia_mul(f.ra_t[j]);
        f.ib_t[j] = bb.inv_inertia_mul(f.rb_t[j]);
        f.tangent_mass[j] = inverse_or_zero(effective(
            ba, bb, f.ra_t[j], f.rb_t[j], f.ia_t[j], f.ib_t[j],
        ));
    }
    // The twist row has no linear part: k = n·I⁻¹A n + n·I⁻¹B n.
    f.ia_w = ba.inv_inertia_mul(n);
    f.ib_w = bb.inv_inertia_mul(n);
    f.twist_mass = inverse_or_zero(round_wide(wide_sum([
        n.dot_wide(f.ia_w),
        n.dot_wide(f.ib_w),
    ])));
    f
}
