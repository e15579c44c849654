//! Friction at the centre of each manifold's contact patch: the per-tick
//! constants of the two tangent rows and the twist row (the passes that
//! solve them are in the parent module).

use super::constraint::{BodyVel, Constraint, NONE, Patch, SolverBody};
use super::rows::{
    angular_along, cross, effective, inverse_or_zero, mul, push_angular, round_wide, scale,
};
use crate::collision::contacts::TOUCH_TOLERANCE;
use crate::collision::{ContactPair, MAX_MANIFOLD_POINTS};
use crate::math::elem::isqrt_u128;
use crate::math::scalar::wide_sum;
use crate::math::{Scalar, Vec3};

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
        f.k[j] = effective(ba, bb, f.ra_t[j], f.rb_t[j], f.ia_t[j], f.ib_t[j]);
        f.tangent_mass[j] = inverse_or_zero(f.k[j]);
    }
    // The twist row has no linear part: k = n·I⁻¹A n + n·I⁻¹B n.
    f.ia_w = ba.inv_inertia_mul(n);
    f.ib_w = bb.inv_inertia_mul(n);
    f.k[2] = round_wide(wide_sum([n.dot_wide(f.ia_w), n.dot_wide(f.ib_w)]));
    f.twist_mass = inverse_or_zero(f.k[2]);
    f
}

/// One visit of constraint `c`'s friction rows, after its normal rows:
/// `total` is the normal impulse that bounds them, `u` the linear relative
/// velocity along (n, t₀, t₁) and `applied` the linear impulses of the
/// visit (the tangent ones are added here).
///
/// Why the bound is the warm start's total and not the current one: the
/// relax pass, whose impulses are the substep's, runs after the soft pass,
/// whose normal impulse follows the contact spring and at a fine substep
/// lags the weight the rigid relax ends up carrying for a long time (the
/// spring settles at a rate of about ω²h). Bounded by it, a box launched at
/// 5 m/s with μ = 0.5 slid 2.3% too far at 480 Hz × 4, 9% at 1,920 Hz × 4
/// and 18% at 3,840 Hz × 4. The last relax pass's total is one substep old,
/// an error that vanishes with the substep. (Bounding by what the normal
/// rows of the same visit settle does the same, and with friction as the
/// last row of the soft pass it also set a box under one 100 times heavier
/// rocking, its speed growing past 0.2 m/s in 10 s.) A contact new this
/// substep has no warm start: its bound is what its normal rows just
/// settled, so that friction acts from a landing's first visit.
///
/// Why after the normal rows, measured (`stress` and `accuracy`, 60 Hz × 4
/// substeps): visited last, friction leaves each visit's velocities with
/// the patch held against sliding and turning, and the normal rows' small
/// error for the next visit and the push-out to take back. With friction
/// first the 50-box stack leaned past its bound within 10 s (it stood to
/// 40); with friction last it stands, as Rapier's does, the pyramids stand
/// as before, and a box sliding to a stop on a ramp lands within a tenth
/// of the error.
///
/// The twist row runs only with `twist`: in the relax pass, and in a soft
/// pass for a contact without a warm start (new this substep); otherwise
/// it holds its warm-started impulse through the soft pass. Solved in both
/// passes, the twist let a wall of boxes (a pyramid one box deep) rock out
/// of its plane in a mode that grew for ever, slowly (a 10-box base: the
/// top box's speed doubled about every 10 s, 1.1 cm/s after 40 s); now the
/// same wall comes to rest (0.3 mm/s) and the stacks and pyramids stand as
/// tall as before (`stress`; docs/stress.md has the variants measured).
#[inline(always)]
pub(super) fn solve_patch(
    c: &mut Constraint,
    va: &mut BodyVel,
    vb: &mut BodyVel,
    u: &[Scalar; 3],
    applied: &mut [Scalar; 3],
    total: Scalar,
    twist: bool,
) {
    let limit = mul(c.friction, total);
    let f = &mut c.patch;
    if limit.is_zero() && f.tangent_impulse == [Scalar::ZERO; 2] && f.twist_impulse.is_zero() {
        return;
    }
    // Both tangent rows from the same velocities, then the pair held in
    // the disc.
    // (No `array::map` here or below: its closures were not inlined.)
    let old = f.tangent_impulse;
    let vt0 = u[1] + angular_along(va, vb, f.ra_t[0], f.rb_t[0]);
    let vt1 = u[2] + angular_along(va, vb, f.ra_t[1], f.rb_t[1]);
    let want = [
        old[0] - mul(f.tangent_mass[0], vt0),
        old[1] - mul(f.tangent_mass[1], vt1),
    ];
    let new = clamp_to_disc(want, limit);
    f.tangent_impulse = new;
    for j in 0..2 {
        let d = new[j] - old[j];
        if !d.is_zero() {
            applied[1 + j] += d;
            push_angular(va, vb, c.a, c.b, d, f.ia_t[j], f.ib_t[j]);
        }
    }
    if !twist {
        return;
    }
    // Twist: the relative spin about the normal.
    let twist_limit = mul(f.twist_reach, total);
    let spin = angular_along(va, vb, c.normal, c.normal);
    let old = f.twist_impulse;
    let new = (old - mul(f.twist_mass, spin)).clamp(-twist_limit, twist_limit);
    let d = new - old;
    f.twist_impulse = new;
    if !d.is_zero() {
        push_angular(va, vb, c.a, c.b, d, f.ia_w, f.ib_w);
    }
}

/// `p` if it lies inside the disc of radius `limit` (≥ 0), else `p` scaled
/// onto the disc, never outside it.
///
/// Exact in integers: the squared lengths are compared as `u128` (the
/// common case, a sticking contact, ends there without a square root);
/// outside, the length is the ceiling of the integer square root and the
/// scale factor `limit/length` (one division, < 1) and both products are
/// truncated toward zero, so each component only shrinks and the result's
/// length is at most `limit`. A `limit` of zero gives zero.
#[inline(always)]
pub(super) fn clamp_to_disc(p: [Scalar; 2], limit: Scalar) -> [Scalar; 2] {
    let (x, y) = (
        p[0].to_bits().unsigned_abs() as u128,
        p[1].to_bits().unsigned_abs() as u128,
    );
    // Each square is below 2¹²⁶ + 1, so the sum fits.
    let len2 = x * x + y * y;
    let lim = limit.to_bits().max(0) as u128;
    if len2 <= lim * lim {
        return p;
    }
    // len2 > 0 here; ⌈√len2⌉ ≤ 2⁶⁴ fits a u128 and is never zero.
    let root = isqrt_u128(len2) as u128;
    let len = if root * root < len2 { root + 1 } else { root };
    // limit < len: the factor, Q0.64, is below one and fits; each product
    // is below 2⁶³·2⁶⁴. With the rounded-up length, each component ends at
    // most a few ulps below its exact `c·limit/|p|`.
    let factor = (lim << 64) / len;
    let scaled = |m: u128, c: Scalar| {
        let m = ((m * factor) >> 64) as i64;
        Scalar::from_bits(if c.is_negative() { -m } else { m })
    };
    [scaled(x, p[0]), scaled(y, p[1])]
}

#[cfg(test)]
mod tests {
    use super::clamp_to_disc;
    use crate::math::Scalar;
    use crate::math::faults::FaultScope;

    fn len2(p: [Scalar; 2]) -> i128 {
        p.iter()
            .map(|c| c.to_bits() as i128 * c.to_bits() as i128)
            .sum()
    }

    #[test]
    fn inside_the_disc_is_kept_bit_for_bit() {
        let limit = Scalar::from_int(5);
        for p in [
            [Scalar::from_int(3), Scalar::from_int(-4)],
            [Scalar::ZERO, Scalar::from_int(-5)],
            [Scalar::from_ratio(-1, 3), Scalar::from_ratio(7, 9)],
        ] {
            assert_eq!(clamp_to_disc(p, limit), p);
        }
    }

    /// Outside, the result keeps the direction (signs and ratio), is never
    /// outside the disc, and is within a few ulps of its rim.
    #[test]
    fn outside_the_disc_lands_on_the_rim_from_inside() {
        let cases = [
            ([3.0, 4.0], 1.0),
            ([-6.0, 8.0], 5.0),
            ([1e-6, -1e-6], 1e-7),
            ([1e8, 1e8], 2.5),
            ([-2e9, 0.0], 1e-3),
            ([0.0, 3.0], 0.0),
        ];
        for (p, limit) in cases {
            let p = p.map(Scalar::from_f64_lossy);
            let limit = Scalar::from_f64_lossy(limit);
            let q = clamp_to_disc(p, limit);
            let lim = limit.to_bits() as i128;
            assert!(len2(q) <= lim * lim, "{p:?} → {q:?} outside {limit:?}");
            let len = (len2(q) as f64).sqrt();
            assert!(lim as f64 - len <= 4.0, "{p:?} → {q:?}: {len} vs {lim}");
            for j in 0..2 {
                assert!(q[j].to_bits().signum() * p[j].to_bits().signum() >= 0);
                assert!(q[j].to_bits().abs() <= p[j].to_bits().abs());
            }
        }
    }

    #[test]
    fn the_extremes_neither_overflow_nor_fault() {
        let ((q, z), faults) = FaultScope::run(|| {
            (
                clamp_to_disc([Scalar::MIN, Scalar::MIN], Scalar::MAX),
                clamp_to_disc([Scalar::MAX, Scalar::MIN], Scalar::ZERO),
            )
        });
        let lim = Scalar::MAX.to_bits() as i128;
        assert!(len2(q) <= lim * lim);
        assert!(q[0].is_negative() && q[0] == q[1]);
        assert_eq!(z, [Scalar::ZERO; 2]);
        assert!(faults.is_empty());
    }
}
