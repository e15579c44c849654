//! Filling a constraint's narrow rows from its Q32.32 terms at `prepare`:
//! the exponents (each kind of entry at the largest scale at which the
//! constraint's largest entry fits 31 bits), the entries, and the
//! accumulated impulses in velocity units (see the parent module).

use super::super::constraint::Constraint;
use super::super::rows::{mul, round_wide};
use super::{LIMIT, MAX_EXP, MIN_EXP, N_EXP, NarrowRows, R_EXP, ROWS, Row, S, SEP0_LIMIT, T0, TW};
use crate::collision::manifold::MAX_MANIFOLD_POINTS;
use crate::math::{Scalar, Vec3};

/// A Q32.32 value at `2^e` (`e ≤ 62`), rounded as [`super::rsh`]; the caller
/// chose `e` so that it fits in 31 bits.
fn at_exp(x: Scalar, e: i32) -> i32 {
    let bits = x.to_bits() as i128;
    let v = if e >= 32 {
        bits << (e - 32)
    } else {
        let sh = (32 - e) as u32;
        (bits + (1i128 << (sh - 1))) >> sh
    };
    v as i32
}

fn at_exp3(v: Vec3, e: i32) -> [i32; 3] {
    [at_exp(v.x, e), at_exp(v.y, e), at_exp(v.z, e)]
}

/// The largest exponent (at most [`MAX_EXP`](super::MAX_EXP)) at which values up to
/// `max_bits` (Q32.32 bits) are at most 2³⁰ in magnitude.
fn exponent_for(max_bits: u64) -> i32 {
    if max_bits <= 1 {
        return MAX_EXP;
    }
    // ⌈log₂ max_bits⌉
    let ceil_log2 = 64 - (max_bits - 1).leading_zeros() as i32;
    (62 - ceil_log2).min(MAX_EXP)
}

fn max_abs(v: Vec3) -> u64 {
    v.x.to_bits()
        .unsigned_abs()
        .max(v.y.to_bits().unsigned_abs())
        .max(v.z.to_bits().unsigned_abs())
}

/// `λ·k` in quanta (Q32.32 λ and k), rounded as [`super::rsh`]; `None` if it is
/// past the guard.
fn to_velocity_units(lambda: Scalar, k: Scalar) -> Option<i32> {
    let p = lambda.to_bits() as i128 * k.to_bits() as i128;
    let sh = 64 - S;
    let v = (p + (1i128 << (sh - 1))) >> sh;
    (v.unsigned_abs() < LIMIT as u128).then_some(v as i32)
}

/// A row's Q32.32 terms (references into the constraint), before the
/// exponents are known.
struct WideRow<'a> {
    /// The unit direction (Q32.32).
    d: Vec3,
    /// `r×d` of each anchor (zero for the twist row).
    ja: Vec3,
    jb: Vec3,
    /// `I⁻¹(r×d)` of each anchor (`I⁻¹d` for the twist).
    ia: &'a Vec3,
    ib: &'a Vec3,
    /// The effective mass.
    m: Scalar,
    /// `m·m_A⁻¹`, `m·m_B⁻¹` (zero for the twist row, which has no linear
    /// part).
    em: [Scalar; 2],
    /// Whether this is the twist row (its angular momentum is along `d`).
    twist: bool,
}

/// `x·y` (Q32.32 bits each) at `2^e`, rounded as [`super::rsh`] (`e ≤ 30`: a
/// shift of at least 34 bits; the caller's exponent keeps it in 31 bits).
#[inline(always)]
fn product_at(x: Scalar, y: Scalar, e: i32) -> i32 {
    let sh = (64 - e) as u32;
    ((x.to_bits() as i128 * y.to_bits() as i128 + (1i128 << (sh - 1))) >> sh) as i32
}

#[inline(always)]
fn product_at3(v: &Vec3, y: Scalar, e: i32) -> [i32; 3] {
    [
        product_at(v.x, y, e),
        product_at(v.y, y, e),
        product_at(v.z, y, e),
    ]
}

/// `a·b` for magnitudes in Q32.32 bits, as Q32.32 bits (an upper bound
/// for choosing an exponent: truncated, then one more).
#[inline(always)]
fn bound_product(a: u64, b: u64) -> u64 {
    ((a as u128 * b as u128) >> 32).min(u64::MAX as u128 - 1) as u64 + 1
}

impl WideRow<'_> {
    /// The largest Jacobian entry (Q32.32 bits).
    fn max_j(&self) -> u64 {
        max_abs(self.ja).max(max_abs(self.jb))
    }

    /// The largest response entry: `e` is at most `em` (a unit `d`), `c`
    /// at most `m` times the largest entry of `I⁻¹(r×d)`.
    fn max_resp(&self) -> u64 {
        let m = self.m.to_bits() as u64;
        let em = self.em[0].to_bits().max(self.em[1].to_bits()) as u64;
        em.max(bound_product(m, max_abs(*self.ia).max(max_abs(*self.ib))))
    }

    /// The largest angular-momentum entry: `m` times the largest of `r×d`
    /// (of `d` for the twist).
    fn max_g(&self) -> u64 {
        let m = self.m.to_bits() as u64;
        let j = if self.twist {
            max_abs(self.d)
        } else {
            self.max_j()
        };
        bound_product(m, j)
    }

    fn narrow(&self, je: i32, ae: i32, ge: i32) -> Row {
        let (ga, gb) = if self.twist {
            let g = product_at3(&self.d, self.m, ge);
            (g, g)
        } else {
            (
                product_at3(&self.ja, self.m, ge),
                product_at3(&self.jb, self.m, ge),
            )
        };
        Row {
            ja: at_exp3(self.ja, je),
            jb: at_exp3(self.jb, je),
            ea: product_at3(&self.d, self.em[0], ae),
            eb: product_at3(&self.d, self.em[1], ae),
            ca: product_at3(self.ia, self.m, ae),
            cb: product_at3(self.ib, self.m, ae),
            ga,
            gb,
        }
    }
}

/// Fills `r` from constraint `c`'s Q32.32 terms (set just before by
/// `prepare`), with `k` the points' `1/m_eff` along the normal; returns
/// whether the constraint fits the narrow rows (see the module docs).
pub(in crate::solver::contact_solver) fn prepare(
    r: &mut NarrowRows,
    c: &Constraint,
    k: &[Scalar],
) -> bool {
    let count = c.count.min(MAX_MANIFOLD_POINTS);
    let f = &c.patch;
    let n = c.normal;
    let (ima, imb) = (c.inv_mass_a, c.inv_mass_b);
    if f.tangent_mass.iter().any(|m| !m.is_positive())
        || !f.twist_mass.is_positive()
        || c.points[..count]
            .iter()
            .any(|cp| !cp.normal_mass.is_positive())
    {
        return false;
    }
    fn row<'a>(
        d: Vec3,
        ja: Vec3,
        jb: Vec3,
        ia: &'a Vec3,
        ib: &'a Vec3,
        m: Scalar,
        im: [Scalar; 2],
    ) -> WideRow<'a> {
        WideRow {
            d,
            ja,
            jb,
            ia,
            ib,
            m,
            em: [mul(m, im[0]), mul(m, im[1])],
            twist: false,
        }
    }
    let im = [ima, imb];
    let twist = WideRow {
        d: n,
        ja: Vec3::ZERO,
        jb: Vec3::ZERO,
        ia: &f.ia_w,
        ib: &f.ib_w,
        m: f.twist_mass,
        em: [Scalar::ZERO; 2],
        twist: true,
    };
    let tangents = [0, 1].map(|j| {
        row(
            c.tangent[j],
            f.ra_t[j],
            f.rb_t[j],
            &f.ia_t[j],
            &f.ib_t[j],
            f.tangent_mass[j],
            im,
        )
    });
    let point = |cp: &super::super::constraint::ConstraintPoint| {
        (n, cp.ra_n, cp.rb_n, cp.ia_n, cp.ib_n, cp.normal_mass)
    };
    // The exponents, from the largest entries of every row (the normal and
    // tangents are unit vectors: at most 1).
    let (mut jmax, mut amax, mut gmax) = (1u64 << 32, 0u64, 0u64);
    let mut widen = |w: &WideRow| {
        jmax = jmax.max(w.max_j());
        amax = amax.max(w.max_resp());
        gmax = gmax.max(w.max_g());
    };
    for cp in &c.points[..count] {
        let (d, ja, jb, ia, ib, m) = point(cp);
        widen(&row(d, ja, jb, &ia, &ib, m, im));
    }
    for w in tangents.iter().chain([&twist]) {
        widen(w);
    }
    let (je, ae, ge) = (exponent_for(jmax), exponent_for(amax), exponent_for(gmax));
    if je < MIN_EXP || ae < MIN_EXP || ge < MIN_EXP {
        return false;
    }
    let mmax = f.tangent_mass[0].to_bits().max(f.tangent_mass[1].to_bits()) as u64;
    let me = exponent_for(mmax).max(-1);
    // The accumulated impulses in velocity units.
    let mut impulses = [0i32; MAX_MANIFOLD_POINTS];
    for (i, cp) in c.points[..count].iter().enumerate() {
        match to_velocity_units(cp.normal_impulse, k[i]) {
            Some(v) => impulses[i] = v,
            None => return false,
        }
    }
    let (Some(t0), Some(t1), Some(w)) = (
        to_velocity_units(f.tangent_impulse[0], f.k[0]),
        to_velocity_units(f.tangent_impulse[1], f.k[1]),
        to_velocity_units(f.twist_impulse, f.k[2]),
    ) else {
        return false;
    };
    // The separations' terms (see `separations`): anchors within ±128 m,
    // separations at the tick's start within ±256 m.
    let r_limit = 1u64 << (31 + 32 - R_EXP);
    let mut sep0 = [0i64; MAX_MANIFOLD_POINTS];
    for (i, cp) in c.points[..count].iter().enumerate() {
        if max_abs(cp.ra) >= r_limit || max_abs(cp.rb) >= r_limit {
            return false;
        }
        let s = n.dot_wide(cp.rb) - n.dot_wide(cp.ra);
        let s = round_wide(s) + cp.adjusted_separation;
        if s.to_bits().abs() >= SEP0_LIMIT {
            return false;
        }
        sep0[i] = s.to_bits();
    }
    r.count = count as u8;
    r.je = je as u8;
    r.ae = ae as u8;
    r.ge = ge as u8;
    r.me = me as i8;
    r.limits_set = false;
    r.warm_total = Scalar::ZERO;
    (r.a, r.b, r.wa, r.wb) = (c.a, c.b, c.wa, c.wb);
    r.bias_poses = 0;
    r.impulse = [0; ROWS];
    r.impulse[..count].copy_from_slice(&impulses[..count]);
    r.impulse[T0..].copy_from_slice(&[t0, t1, w]);
    r.mark = [0; ROWS];
    r.max_impulse = [0; MAX_MANIFOLD_POINTS];
    r.first_vn = [i32::MAX; MAX_MANIFOLD_POINTS];
    r.mass = [Scalar::ZERO; ROWS];
    r.n = at_exp3(n, je);
    r.nq = at_exp3(n, N_EXP as i32);
    r.sep0 = sep0;
    for (i, cp) in c.points[..count].iter().enumerate() {
        let (d, ja, jb, ia, ib, m) = point(cp);
        r.rows[i] = row(d, ja, jb, &ia, &ib, m, im).narrow(je, ae, ge);
        r.raq[i] = at_exp3(cp.ra, R_EXP as i32);
        r.rbq[i] = at_exp3(cp.rb, R_EXP as i32);
        r.mass[i] = cp.normal_mass;
    }
    for (j, tangent) in tangents.iter().enumerate() {
        r.rows[T0 + j] = tangent.narrow(je, ae, ge);
        r.t[j] = at_exp3(c.tangent[j], je);
        r.mass_t[j] = at_exp(f.tangent_mass[j], me);
        r.mass[T0 + j] = f.tangent_mass[j];
    }
    r.rows[TW] = twist.narrow(je, ae, ge);
    r.mass[TW] = f.twist_mass;
    r.friction = c.friction;
    r.twist_reach = f.twist_reach;
    r.k_w = f.k[2];
    true
}

#[cfg(test)]
mod tests {
    use super::super::impulse;
    use super::*;

    #[test]
    fn exponents_keep_entries_within_31_bits() {
        for bits in [
            0u64,
            1,
            2,
            3,
            1 << 31,
            (1 << 32) - 1,
            1 << 32,
            (1 << 32) + 1,
            5 << 40,
            i64::MAX as u64,
        ] {
            let e = exponent_for(bits);
            assert!(e <= MAX_EXP);
            let v = at_exp(Scalar::from_bits(bits as i64), e) as i64;
            assert!(v.abs() <= 1 << 30, "{bits} at 2^{e} is {v}");
            if bits > 1 && e < MAX_EXP {
                // One more bit of exponent would not fit.
                assert!((bits as i128) << (e + 1) > 1i128 << 62, "{bits} at 2^{e}");
            }
        }
        assert_eq!(exponent_for(1 << 32), 30);
        assert_eq!(exponent_for((1 << 32) + 1), 29);
    }

    #[test]
    fn impulses_convert_both_ways_within_a_quantum() {
        // λ = 3.25 N·s, m_eff = 2 kg: Λ = 1.625 m/s.
        let lambda = Scalar::from_ratio(13, 4);
        let (m, k) = (Scalar::from_int(2), Scalar::from_ratio(1, 2));
        let big = to_velocity_units(lambda, k).unwrap();
        assert_eq!(big, 13 << (S - 3));
        assert_eq!(impulse(big, m), lambda);
        // 4,096 m/s is past the guard.
        assert_eq!(
            to_velocity_units(Scalar::from_int(1 << 12), Scalar::ONE),
            None
        );
    }
}
