//! Exact integer arithmetic for the shape module: the orientation predicate
//! of the convex hull and the mass integrals.
//!
//! Two tools, for two jobs:
//!
//! * [`Wide192`] and [`orient3d`]: the sign (and size, for comparisons) of a
//!   3×3 determinant of coordinate differences. With Q32.32 coordinates
//!   bounded by 2²⁰ m the raw differences have 54 bits, the cross product 108
//!   and the determinant about 164: more than `i128`. The cross product is
//!   exact in `i128`; the final dot product is summed as `i128` pieces (high
//!   and low halves of each cross component times the third vector) and
//!   carried into a 192-bit value. Fast enough for the inner loop of the hull.
//! * [`BigInt`]: a fixed-width (768-bit) sign–magnitude integer for the mass
//!   integrals, where products of up to seven Q32.32 numbers and a 127-bit π
//!   are formed exactly and divided once. Slow (bit-serial division) but only
//!   used when a shape's mass properties are asked for.
//!
//! Everything here is integer-only and platform-independent.

use std::cmp::Ordering;

use crate::math::faults::{self, Faults};
use crate::math::{Scalar, Vec3};

/// A point as the raw Q32.32 bits of its coordinates.
pub(crate) type RawPoint = [i64; 3];

/// The raw bits of a vector.
pub(crate) fn raw(v: Vec3) -> RawPoint {
    [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()]
}

/// The vector with the given raw bits.
pub(crate) fn from_raw(p: RawPoint) -> Vec3 {
    Vec3::new(
        Scalar::from_bits(p[0]),
        Scalar::from_bits(p[1]),
        Scalar::from_bits(p[2]),
    )
}

/// `b - a`, component-wise. Callers keep coordinates within ±2⁶² so the
/// differences cannot overflow.
#[inline]
pub(crate) fn sub(b: RawPoint, a: RawPoint) -> RawPoint {
    [b[0] - a[0], b[1] - a[1], b[2] - a[2]]
}

/// The exact cross product of two raw vectors whose components are below
/// 2⁶² in magnitude (each product then has at most 124 bits).
#[inline]
pub(crate) fn cross(u: RawPoint, v: RawPoint) -> [i128; 3] {
    let m = |a: i64, b: i64| a as i128 * b as i128;
    [
        m(u[1], v[2]) - m(u[2], v[1]),
        m(u[2], v[0]) - m(u[0], v[2]),
        m(u[0], v[1]) - m(u[1], v[0]),
    ]
}

/// A signed 192-bit integer `hi · 2⁶⁴ + lo`. The derived ordering (first
/// `hi`, then the unsigned `lo`) is the numeric ordering.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct Wide192 {
    hi: i128,
    lo: u64,
}

impl Wide192 {
    /// Zero.
    pub(crate) const ZERO: Wide192 = Wide192 { hi: 0, lo: 0 };

    /// Whether the value is above zero.
    #[inline]
    pub(crate) fn is_positive(self) -> bool {
        self > Wide192::ZERO
    }

    /// The absolute value (exact: the values formed here are far from the
    /// 192-bit limit).
    pub(crate) fn abs(self) -> Wide192 {
        if self.hi >= 0 {
            self
        } else if self.lo == 0 {
            Wide192 {
                hi: -self.hi,
                lo: 0,
            }
        } else {
            Wide192 {
                hi: -self.hi - 1,
                lo: self.lo.wrapping_neg(),
            }
        }
    }

    /// The same value as a [`BigInt`].
    pub(crate) fn to_big(self) -> BigInt {
        BigInt::from_i128(self.hi)
            .shl(64)
            .add(&BigInt::from_u128(self.lo as u128))
    }
}

/// `Σ n[i] · w[i]` exactly, for `|n[i]| < 2¹¹⁰` and `|w[i]| < 2⁵⁴`.
///
/// Each `n[i]` is split into a signed high half and an unsigned low half;
/// the partial sums of the two halves each fit `i128` comfortably, and the
/// carry of the low sum moves into the high one.
#[inline]
pub(crate) fn dot_wide(n: [i128; 3], w: RawPoint) -> Wide192 {
    let mut high: i128 = 0;
    let mut low: i128 = 0;
    for i in 0..3 {
        let h = n[i] >> 64;
        let l = (n[i] as u128 & u64::MAX as u128) as i128;
        high += h * w[i] as i128;
        low += l * w[i] as i128;
    }
    high += low >> 64;
    Wide192 {
        hi: high,
        lo: low as u64,
    }
}

/// Six times the signed volume of the tetrahedron `abcd`:
/// `((b − a) × (c − a)) · (d − a)`, exactly.
///
/// Positive when `d` lies on the side the right-handed normal of the
/// triangle `abc` points to (that is, `abc` is clockwise seen from `d`).
/// Requires every coordinate within ±2⁵² raw (±2²⁰ m).
#[inline]
pub(crate) fn orient3d(a: RawPoint, b: RawPoint, c: RawPoint, d: RawPoint) -> Wide192 {
    dot_wide(cross(sub(b, a), sub(c, a)), sub(d, a))
}

/// A unit vector along the exact raw vector `n` (any non-zero magnitude up to
/// 2¹²⁷), or `None` for the zero vector.
///
/// The vector is first scaled (by a power of two, rounded) so that its
/// largest component has 60 bits; the direction then carries a relative
/// error near 2⁻⁶⁰, far below the output's 2⁻³², and the normalisation is
/// that of [`Vec3::try_normalize`].
pub(crate) fn unit_of_wide(n: [i128; 3]) -> Option<Vec3> {
    let big = n.iter().map(|c| c.unsigned_abs()).max().unwrap_or(0);
    if big == 0 {
        return None;
    }
    let bits = 128 - big.leading_zeros();
    let scaled = |c: i128| -> i64 {
        if bits > 60 {
            let s = bits - 60;
            ((c + (1i128 << (s - 1)) - (c < 0) as i128) >> s) as i64
        } else {
            (c << (60 - bits)) as i64
        }
    };
    Vec3::new(
        Scalar::from_bits(scaled(n[0])),
        Scalar::from_bits(scaled(n[1])),
        Scalar::from_bits(scaled(n[2])),
    )
    .try_normalize()
}

/// Number of 64-bit limbs of a [`BigInt`]: 768 bits, enough for a product of
/// nine Q32.32 numbers and π in Q2.125.
const LIMBS: usize = 12;

/// π · 2¹²⁵, rounded to nearest (relative error below 2⁻¹²⁷).
pub(crate) const PI_Q125: i128 = 0x6487_ed51_10b4_611a_6263_3145_c06e_0e69;

/// A fixed-width sign–magnitude integer (768-bit magnitude).
///
/// Operations that would exceed the width saturate the magnitude and raise
/// [`Faults::OVERFLOW`]; the shape code's bounds keep far below it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct BigInt {
    neg: bool,
    mag: [u64; LIMBS],
}

type Mag = [u64; LIMBS];

fn mag_cmp(a: &Mag, b: &Mag) -> Ordering {
    for i in (0..LIMBS).rev() {
        match a[i].cmp(&b[i]) {
            Ordering::Equal => {}
            o => return o,
        }
    }
    Ordering::Equal
}

fn saturated() -> Mag {
    faults::raise(Faults::OVERFLOW);
    [u64::MAX; LIMBS]
}

fn mag_add(a: &Mag, b: &Mag) -> Mag {
    let mut out = [0u64; LIMBS];
    let mut carry = 0u64;
    for i in 0..LIMBS {
        let (s1, c1) = a[i].overflowing_add(b[i]);
        let (s2, c2) = s1.overflowing_add(carry);
        out[i] = s2;
        carry = (c1 as u64) + (c2 as u64);
    }
    if carry != 0 { saturated() } else { out }
}

/// `a − b` modulo 2⁷⁶⁸ (exact when `a ≥ b`).
fn mag_sub(a: &Mag, b: &Mag) -> Mag {
    let mut out = [0u64; LIMBS];
    let mut borrow = 0u64;
    for i in 0..LIMBS {
        let (d1, b1) = a[i].overflowing_sub(b[i]);
        let (d2, b2) = d1.overflowing_sub(borrow);
        out[i] = d2;
        borrow = (b1 as u64) + (b2 as u64);
    }
    out
}

fn mag_len(a: &Mag) -> usize {
    (0..LIMBS).rev().find(|&i| a[i] != 0).map_or(0, |i| i + 1)
}

fn mag_bit_len(a: &Mag) -> u32 {
    match mag_len(a) {
        0 => 0,
        n => 64 * (n as u32 - 1) + (64 - a[n - 1].leading_zeros()),
    }
}

impl BigInt {
    /// Zero.
    pub(crate) const ZERO: BigInt = BigInt {
        neg: false,
        mag: [0; LIMBS],
    };

    fn from_parts(neg: bool, mag: Mag) -> BigInt {
        let neg = neg && mag.iter().any(|&l| l != 0);
        BigInt { neg, mag }
    }

    /// An unsigned value.
    pub(crate) fn from_u128(v: u128) -> BigInt {
        let mut mag = [0u64; LIMBS];
        mag[0] = v as u64;
        mag[1] = (v >> 64) as u64;
        BigInt { neg: false, mag }
    }

    /// A signed value.
    pub(crate) fn from_i128(v: i128) -> BigInt {
        let mut b = BigInt::from_u128(v.unsigned_abs());
        b.neg = v < 0;
        b
    }

    /// A signed value.
    pub(crate) fn from_i64(v: i64) -> BigInt {
        BigInt::from_i128(v as i128)
    }

    /// The raw bits of a Q32.32 number, as an integer.
    pub(crate) fn from_scalar(s: Scalar) -> BigInt {
        BigInt::from_i64(s.to_bits())
    }

    /// Whether the value is zero.
    pub(crate) fn is_zero(&self) -> bool {
        mag_len(&self.mag) == 0
    }

    /// Whether the value is below zero.
    #[cfg(test)]
    pub(crate) fn is_negative(&self) -> bool {
        self.neg
    }

    /// `−self`.
    pub(crate) fn neg(&self) -> BigInt {
        BigInt::from_parts(!self.neg, self.mag)
    }

    /// `self + o`.
    pub(crate) fn add(&self, o: &BigInt) -> BigInt {
        if self.neg == o.neg {
            return BigInt::from_parts(self.neg, mag_add(&self.mag, &o.mag));
        }
        match mag_cmp(&self.mag, &o.mag) {
            Ordering::Less => BigInt::from_parts(o.neg, mag_sub(&o.mag, &self.mag)),
            _ => BigInt::from_parts(self.neg, mag_sub(&self.mag, &o.mag)),
        }
    }

    /// `self − o`.
    pub(crate) fn sub(&self, o: &BigInt) -> BigInt {
        self.add(&o.neg())
    }

    /// `self · o`.
    pub(crate) fn mul(&self, o: &BigInt) -> BigInt {
        let (la, lb) = (mag_len(&self.mag), mag_len(&o.mag));
        if la == 0 || lb == 0 {
            return BigInt::ZERO;
        }
        if la + lb > LIMBS + 1 {
            return BigInt::from_parts(self.neg != o.neg, saturated());
        }
        let mut out = [0u64; LIMBS + 1];
        for i in 0..la {
            let mut carry: u128 = 0;
            for j in 0..lb {
                let cur = out[i + j] as u128 + self.mag[i] as u128 * o.mag[j] as u128 + carry;
                out[i + j] = cur as u64;
                carry = cur >> 64;
            }
            // i + lb ≤ LIMBS because la + lb ≤ LIMBS + 1.
            out[i + lb] = carry as u64;
        }
        if out[LIMBS] != 0 {
            return BigInt::from_parts(self.neg != o.neg, saturated());
        }
        let mut mag = [0u64; LIMBS];
        mag.copy_from_slice(&out[..LIMBS]);
        BigInt::from_parts(self.neg != o.neg, mag)
    }

    /// `self · v`.
    pub(crate) fn mul_i128(&self, v: i128) -> BigInt {
        self.mul(&BigInt::from_i128(v))
    }

    /// `self · 2^k`.
    pub(crate) fn shl(&self, k: u32) -> BigInt {
        if self.is_zero() {
            return *self;
        }
        if mag_bit_len(&self.mag) + k > 64 * LIMBS as u32 {
            return BigInt::from_parts(self.neg, saturated());
        }
        let (limbs, bits) = ((k / 64) as usize, k % 64);
        let mut mag = [0u64; LIMBS];
        for i in (limbs..LIMBS).rev() {
            let src = i - limbs;
            let mut v = self.mag[src] << bits;
            if bits > 0 && src > 0 {
                v |= self.mag[src - 1] >> (64 - bits);
            }
            mag[i] = v;
        }
        BigInt::from_parts(self.neg, mag)
    }

    /// `self / d` rounded to nearest, ties away from zero. A zero divisor
    /// raises [`Faults::DIV_BY_ZERO`] and gives zero.
    pub(crate) fn div_round(&self, d: &BigInt) -> BigInt {
        if d.is_zero() {
            faults::raise(Faults::DIV_BY_ZERO);
            return BigInt::ZERO;
        }
        // Restoring binary long division on the magnitudes.
        let mut q = [0u64; LIMBS];
        let mut r = [0u64; LIMBS];
        for i in (0..mag_bit_len(&self.mag)).rev() {
            let carry = r[LIMBS - 1] >> 63;
            for k in (1..LIMBS).rev() {
                r[k] = (r[k] << 1) | (r[k - 1] >> 63);
            }
            r[0] = (r[0] << 1) | ((self.mag[(i / 64) as usize] >> (i % 64)) & 1);
            // With the carry out the true remainder exceeds d; the wrapping
            // subtraction still gives the right (smaller than d) result.
            if carry != 0 || mag_cmp(&r, &d.mag) != Ordering::Less {
                r = mag_sub(&r, &d.mag);
                q[(i / 64) as usize] |= 1 << (i % 64);
            }
        }
        // Round: up when r ≥ d − r, that is 2r ≥ d.
        if mag_cmp(&r, &mag_sub(&d.mag, &r)) != Ordering::Less {
            let mut one = [0u64; LIMBS];
            one[0] = 1;
            q = mag_add(&q, &one);
        }
        BigInt::from_parts(self.neg != d.neg, q)
    }

    /// The number of significant bits of the magnitude (0 for zero).
    pub(crate) fn bit_len(&self) -> u32 {
        mag_bit_len(&self.mag)
    }

    /// The value as `i128`, or `None` when it does not fit.
    pub(crate) fn to_i128(self) -> Option<i128> {
        if mag_len(&self.mag) > 2 {
            return None;
        }
        let m = self.mag[0] as u128 | (self.mag[1] as u128) << 64;
        if self.neg {
            if m <= 1u128 << 127 {
                Some((m as i128).wrapping_neg())
            } else {
                None
            }
        } else {
            i128::try_from(m).ok()
        }
    }

    /// The value as `i64`, or `None` when it does not fit.
    pub(crate) fn to_i64(self) -> Option<i64> {
        if mag_len(&self.mag) > 1 {
            return None;
        }
        let m = self.mag[0];
        if self.neg {
            if m <= 1u64 << 63 {
                Some((m as i64).wrapping_neg())
            } else {
                None
            }
        } else {
            i64::try_from(m).ok()
        }
    }

    /// The value as `i64`, saturating and raising [`Faults::OVERFLOW`] when
    /// it does not fit.
    pub(crate) fn to_i64_saturating(self) -> i64 {
        self.to_i64().unwrap_or_else(|| {
            faults::raise(Faults::OVERFLOW);
            if self.neg { i64::MIN } else { i64::MAX }
        })
    }

    /// `π · 2¹²⁵` as a `BigInt`.
    pub(crate) fn pi_q125() -> BigInt {
        BigInt::from_i128(PI_Q125)
    }
}

/// The product of the raw bits of several Q32.32 numbers (scale 2^(32·k)).
pub(crate) fn product(xs: &[Scalar]) -> BigInt {
    xs.iter().fold(BigInt::from_i64(1), |acc, &x| {
        acc.mul(&BigInt::from_scalar(x))
    })
}

/// The Q32.32 number nearest to `num / (den · 2^shift)`, or `None` when it
/// is out of range. `den` must not be zero.
pub(crate) fn ratio_to_scalar(num: &BigInt, den: &BigInt, shift: u32) -> Option<Scalar> {
    num.div_round(&den.shl(shift))
        .to_i64()
        .map(Scalar::from_bits)
}

/// Like [`ratio_to_scalar`], but saturating (and raising
/// [`Faults::OVERFLOW`]) when out of range.
pub(crate) fn ratio_to_scalar_saturating(num: &BigInt, den: &BigInt, shift: u32) -> Scalar {
    Scalar::from_bits(num.div_round(&den.shl(shift)).to_i64_saturating())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::Rng;

    /// A reference 3×3 determinant with i128 entries, evaluated on BigInts.
    fn det_big(u: RawPoint, v: RawPoint, w: RawPoint) -> BigInt {
        let c = cross(u, v);
        let mut acc = BigInt::ZERO;
        for i in 0..3 {
            acc = acc.add(&BigInt::from_i128(c[i]).mul_i128(w[i] as i128));
        }
        acc
    }

    #[test]
    fn orientation_sign_agrees_with_bigint_determinant_at_the_coordinate_limit() {
        let lim = 1i64 << 52;
        let mut rng = Rng::new(42);
        for round in 0..20_000 {
            let mut p = [[0i64; 3]; 4];
            for q in p.iter_mut() {
                for c in q.iter_mut() {
                    // Mix extreme values with random ones.
                    let r = rng.next_u64();
                    *c = match r % 5 {
                        0 => lim,
                        1 => -lim,
                        _ => ((r >> 8) as i64) % (lim + 1),
                    };
                }
            }
            if round % 3 == 0 {
                // Force a nearly-degenerate configuration: d = a + (b − a) + (c − a) ± 1.
                p[3] = std::array::from_fn(|k| {
                    let d = (p[1][k] + p[2][k] - p[0][k]).clamp(-lim, lim) + (round % 2) as i64;
                    d.clamp(-lim, lim)
                });
            }
            let w = orient3d(p[0], p[1], p[2], p[3]);
            let b = det_big(sub(p[1], p[0]), sub(p[2], p[0]), sub(p[3], p[0]));
            assert_eq!(w.to_big(), b, "{p:?}");
            assert_eq!(w.is_positive(), !b.is_zero() && !b.is_negative());
            assert_eq!(w.abs().to_big(), if b.is_negative() { b.neg() } else { b });
        }
    }

    #[test]
    fn wide_values_order_numerically() {
        let a = dot_wide([-(1i128 << 100), 0, 0], [3, 0, 0]);
        let b = dot_wide([1, 0, 0], [-5, 0, 0]);
        let c = dot_wide([1i128 << 70, 0, 0], [1, 0, 0]);
        assert!(a < b && b < Wide192::ZERO && Wide192::ZERO < c);
        assert_eq!(a.abs().to_big(), BigInt::from_i128(3i128 << 100));
    }

    #[test]
    fn bigint_division_rounds_to_nearest_ties_away_from_zero() {
        let d = |n: i128, m: i128| BigInt::from_i128(n).div_round(&BigInt::from_i128(m));
        assert_eq!(d(7, 2), BigInt::from_i128(4));
        assert_eq!(d(-7, 2), BigInt::from_i128(-4));
        assert_eq!(d(5, 3), BigInt::from_i128(2));
        assert_eq!(d(4, 3), BigInt::from_i128(1));
        assert_eq!(d(-4, -3), BigInt::from_i128(1));
        assert_eq!(d(4, -3), BigInt::from_i128(-1));
        let mut rng = Rng::new(9);
        for _ in 0..2_000 {
            let n = (rng.next_u64() as i128) << 40 | rng.next_u64() as i128;
            let m =
                ((rng.next_u64() >> 3) as i128 + 1) * if rng.next_u64() & 1 == 0 { 1 } else { -1 };
            let want = crate::math::scalar::div_round_i128(n, m);
            assert_eq!(d(n, m), BigInt::from_i128(want), "{n} / {m}");
        }
    }

    #[test]
    fn bigint_products_and_shifts_are_exact() {
        // (2^100 + 3)(2^90 − 7) = 2^190 − 7·2^100 + 3·2^90 − 21
        let a = BigInt::from_i128((1 << 100) + 3);
        let b = BigInt::from_i128((1 << 90) - 7);
        let want = BigInt::from_i64(1)
            .shl(190)
            .sub(&BigInt::from_i64(7).shl(100))
            .add(&BigInt::from_i64(3).shl(90))
            .sub(&BigInt::from_i64(21));
        assert_eq!(a.mul(&b), want);
        assert_eq!(a.mul(&b.neg()), want.neg());
        assert_eq!(
            want.div_round(&b),
            a,
            "exact quotient survives the round trip"
        );
        let (v, f) = crate::math::FaultScope::run(|| BigInt::from_i64(1).shl(800));
        assert!(f.contains(Faults::OVERFLOW));
        assert!(!v.is_zero());
    }

    #[test]
    fn unit_of_wide_points_along_the_vector() {
        let n = unit_of_wide([3i128 << 100, 0, -(4i128 << 100)]).unwrap();
        assert_eq!(n.x, Scalar::from_ratio(3, 5));
        assert_eq!(n.z, Scalar::from_ratio(-4, 5));
        assert_eq!(unit_of_wide([0, 0, 0]), None);
        assert_eq!(unit_of_wide([0, -1, 0]), Some(-Vec3::Y));
    }
}
