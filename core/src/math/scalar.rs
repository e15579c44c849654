//! `Scalar`: the Q32.32 fixed-point number every simulation quantity is made of.
//!
//! Storage is `fixed::types::I32F32` (an `i64` holding value × 2³²). The
//! arithmetic is our own, for two reasons (docs/determinism.md, "Numbers"):
//! `fixed`'s `*` rounds toward −∞ (a systematic bias in a solver) and its
//! release builds wrap silently on overflow. Here:
//!
//! * `*` and `/` round to nearest, ties away from zero, so `(-a) * b == -(a * b)`
//!   bit for bit (no drift toward −∞);
//! * every operation that can overflow saturates and raises
//!   [`Faults::OVERFLOW`](super::faults::Faults::OVERFLOW); division by zero saturates
//!   and raises [`Faults::DIV_BY_ZERO`](super::faults::Faults::DIV_BY_ZERO). Nothing
//!   panics, whatever the build profile.
//!
//! Conversions to and from floats exist only for the edges (printing,
//! rendering, tests) and are named so (`to_f64`, `to_f32`,
//! `from_f64_lossy`); the simulation path never calls them.

use std::cmp::Ordering;
use std::fmt;
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

use fixed::types::I32F32;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::faults::{self, Faults};

/// Number of fraction bits.
pub const FRAC_BITS: u32 = 32;

/// A Q32.32 fixed-point number: 32 integer bits (signed), 32 fraction bits.
///
/// Range ±2,147,483,648 with a resolution of 2⁻³² ≈ 2.3e-10.
#[derive(Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(transparent)]
pub struct Scalar(I32F32);

/// Rounds a Q64.64 (or any value scaled by 2³² too much) `i128` to the nearest
/// multiple of 2³², ties away from zero, and returns the quotient.
///
/// Symmetric: `round_shift32(-p) == -round_shift32(p)`.
#[inline(always)]
pub(crate) const fn round_shift32(p: i128) -> i128 {
    p.saturating_add((1i128 << 31) - (p < 0) as i128) >> 32
}

/// Rounds `p / 2^shift` to nearest, ties away from zero (`shift` in 1..=126).
#[inline(always)]
pub(crate) const fn round_shift(p: i128, shift: u32) -> i128 {
    p.saturating_add((1i128 << (shift - 1)) - (p < 0) as i128) >> shift
}

/// Narrows an `i128` to `i64`, saturating and raising the overflow fault.
#[inline(always)]
pub(crate) fn narrow(v: i128) -> i64 {
    // In range exactly when the high half is the low half's sign extension:
    // one comparison on the hot path instead of two.
    let low = v as i64;
    if low as i128 == v {
        low
    } else {
        faults::raise(Faults::OVERFLOW);
        if v < 0 { i64::MIN } else { i64::MAX }
    }
}

/// Adds Q64.64 terms (each a [`Scalar::wide_mul`] product or a sum of
/// such), saturating and raising the overflow fault if the sum leaves `i128`
/// (only possible with operands near ±2³¹).
#[inline(always)]
pub(crate) fn wide_sum<const N: usize>(terms: [i128; N]) -> i128 {
    let mut acc: i128 = 0;
    for t in terms {
        acc = match acc.checked_add(t) {
            Some(v) => v,
            None => {
                faults::raise(Faults::OVERFLOW);
                return if t > 0 { i128::MAX } else { i128::MIN };
            }
        };
    }
    acc
}

/// Divides `n` by `d` rounding to nearest, ties away from zero. `d != 0`.
#[inline]
pub(crate) fn div_round_i128(n: i128, d: i128) -> i128 {
    let q = n / d;
    let r = n % d;
    // |r| ≥ |d| / 2  ⇔  2|r| ≥ |d|; both fit since |r| < |d| ≤ 2^127 - 1 is
    // only reached for d = MIN, which callers never pass.
    if 2 * r.unsigned_abs() >= d.unsigned_abs() {
        if (n < 0) != (d < 0) { q - 1 } else { q + 1 }
    } else {
        q
    }
}

impl Scalar {
    /// 0.
    pub const ZERO: Scalar = Scalar::from_bits(0);
    /// 1.
    pub const ONE: Scalar = Scalar::from_bits(1 << 32);
    /// 2.
    pub const TWO: Scalar = Scalar::from_bits(2 << 32);
    /// 0.5.
    pub const HALF: Scalar = Scalar::from_bits(1 << 31);
    /// −1.
    pub const NEG_ONE: Scalar = Scalar::from_bits(-(1 << 32));
    /// The smallest positive value, 2⁻³².
    pub const DELTA: Scalar = Scalar::from_bits(1);
    /// The largest value, just under 2³¹.
    pub const MAX: Scalar = Scalar::from_bits(i64::MAX);
    /// The most negative value, −2³¹.
    pub const MIN: Scalar = Scalar::from_bits(i64::MIN);
    /// π rounded to nearest: 13493037705 / 2³² (error 1.1e-10).
    pub const PI: Scalar = Scalar::from_bits(13_493_037_705);
    /// 2π rounded to nearest.
    pub const TAU: Scalar = Scalar::from_bits(26_986_075_409);
    /// π/2 rounded to nearest.
    pub const FRAC_PI_2: Scalar = Scalar::from_bits(6_746_518_852);

    /// Builds a value from its raw bits (value × 2³²).
    #[inline(always)]
    pub const fn from_bits(bits: i64) -> Scalar {
        Scalar(I32F32::from_bits(bits))
    }

    /// The raw bits (value × 2³²): what hashes and snapshots store.
    #[inline(always)]
    pub const fn to_bits(self) -> i64 {
        self.0.to_bits()
    }

    /// The underlying `fixed` value.
    #[inline(always)]
    pub const fn to_fixed(self) -> I32F32 {
        self.0
    }

    /// Wraps a `fixed` value.
    #[inline(always)]
    pub const fn from_fixed(v: I32F32) -> Scalar {
        Scalar(v)
    }

    /// An integer, exactly.
    #[inline(always)]
    pub const fn from_int(v: i32) -> Scalar {
        Scalar::from_bits((v as i64) << 32)
    }

    /// The value nearest to a decimal number written as text, ties away from
    /// zero: exactly what scene files give for the same digits (no `f64` on
    /// the way). A `const fn`, so constants can be written as decimals; the
    /// [`scalar!`](crate::scalar) macro is the short form for literals.
    ///
    /// The grammar is the scene files': an optional sign, digits with an
    /// optional fraction, an optional exponent (`2.5e-3`), underscores
    /// between digits (`1_000`).
    ///
    /// ```
    /// use lockstep_core::Scalar;
    ///
    /// const HALF: Scalar = Scalar::from_decimal_str("0.5");
    /// assert_eq!(HALF, Scalar::HALF);
    /// // 0.1 is not a binary fraction: the nearest Q32.32 value, exactly.
    /// assert_eq!(Scalar::from_decimal_str("0.1").to_bits(), 429_496_730);
    /// assert_eq!(Scalar::from_decimal_str("-9.81"), Scalar::from_ratio(-981, 100));
    /// // Below half of 2⁻³², a value rounds to zero.
    /// assert_eq!(Scalar::from_decimal_str("1e-10"), Scalar::ZERO);
    /// ```
    ///
    /// In a constant, a malformed number does not compile:
    ///
    /// ```compile_fail
    /// use lockstep_core::Scalar;
    /// const BAD: Scalar = Scalar::from_decimal_str("1.2.3");
    /// ```
    ///
    /// # Panics
    /// On text that [`str::parse`] would refuse (see
    /// [`ParseDecimalError`](super::decimal::ParseDecimalError)): in a
    /// constant that is a compile error. Use `str::parse` for text read at
    /// run time.
    pub const fn from_decimal_str(s: &str) -> Scalar {
        use super::decimal::ParseDecimalError as E;
        match super::decimal::parse_exact_const(s) {
            Ok(v) => v,
            Err(E::Empty) => panic!("Scalar::from_decimal_str: empty number"),
            Err(E::InvalidChar { .. }) => {
                panic!("Scalar::from_decimal_str: a character that is not part of a decimal number")
            }
            Err(E::MissingDigits) => panic!("Scalar::from_decimal_str: digits are missing"),
            Err(E::OutOfRange) => {
                panic!("Scalar::from_decimal_str: outside the fixed-point range ±2147483648")
            }
            Err(E::TooLong) => panic!("Scalar::from_decimal_str: too many digits"),
        }
    }

    /// `num / den` rounded to nearest (ties away from zero): the way to build
    /// constants such as `1/60` without floats.
    ///
    /// A zero denominator saturates and raises `DIV_BY_ZERO`.
    pub fn from_ratio(num: i64, den: i64) -> Scalar {
        if den == 0 {
            faults::raise(Faults::DIV_BY_ZERO);
            return if num < 0 { Scalar::MIN } else { Scalar::MAX };
        }
        Scalar::from_bits(narrow(div_round_i128((num as i128) << 32, den as i128)))
    }

    /// The value as `f64`, exact (every Q32.32 value is an `f64`... to 53
    /// bits; values above 2²¹ lose their lowest fraction bits). For printing
    /// and tests only: never on the simulation path.
    pub fn to_f64(self) -> f64 {
        self.to_bits() as f64 / 4_294_967_296.0
    }

    /// The nearest `f32` to the value, for rendering (a renderer's
    /// transforms, a debug overlay): never on the simulation path. One
    /// rounding, so values within about ±2²⁴ ulps of a float are exact and
    /// larger ones keep 24 significant bits.
    pub fn to_f32(self) -> f32 {
        self.to_bits() as f32 / 4_294_967_296.0
    }

    /// The nearest value to `v`, for tests and tools at the edges only (never
    /// on the simulation path: scene files use exact decimal parsing).
    /// Saturates out-of-range values and maps NaN to zero.
    pub fn from_f64_lossy(v: f64) -> Scalar {
        let scaled = (v * 4_294_967_296.0).round();
        if scaled.is_nan() {
            Scalar::ZERO
        } else if scaled >= i64::MAX as f64 {
            Scalar::MAX
        } else if scaled <= i64::MIN as f64 {
            Scalar::MIN
        } else {
            Scalar::from_bits(scaled as i64)
        }
    }

    /// Whether the value is exactly zero.
    #[inline(always)]
    pub const fn is_zero(self) -> bool {
        self.to_bits() == 0
    }

    /// Whether the value is below zero.
    #[inline(always)]
    pub const fn is_negative(self) -> bool {
        self.to_bits() < 0
    }

    /// Whether the value is above zero.
    #[inline(always)]
    pub const fn is_positive(self) -> bool {
        self.to_bits() > 0
    }

    /// |self|, saturating (|MIN| raises `OVERFLOW`).
    #[inline(always)]
    pub fn abs(self) -> Scalar {
        if self.is_negative() { -self } else { self }
    }

    /// −1, 0 or 1.
    #[inline(always)]
    pub fn signum(self) -> Scalar {
        match self.to_bits().cmp(&0) {
            Ordering::Less => Scalar::NEG_ONE,
            Ordering::Equal => Scalar::ZERO,
            Ordering::Greater => Scalar::ONE,
        }
    }

    /// The smaller of two values.
    #[inline(always)]
    pub fn min(self, other: Scalar) -> Scalar {
        if other < self { other } else { self }
    }

    /// The larger of two values.
    #[inline(always)]
    pub fn max(self, other: Scalar) -> Scalar {
        if other > self { other } else { self }
    }

    /// `self` limited to `[lo, hi]` (`lo <= hi` expected; if not, `lo` wins).
    #[inline(always)]
    pub fn clamp(self, lo: Scalar, hi: Scalar) -> Scalar {
        self.min(hi).max(lo)
    }

    /// `self / 2`, rounded to nearest, ties away from zero.
    #[inline(always)]
    pub fn half(self) -> Scalar {
        let b = self.to_bits() as i128;
        Scalar::from_bits(((b + 1 - (b < 0) as i128) >> 1) as i64)
    }

    /// Multiplication by an integer, exact unless it overflows.
    #[inline(always)]
    pub fn mul_int(self, k: i64) -> Scalar {
        Scalar::from_bits(narrow(self.to_bits() as i128 * k as i128))
    }

    /// Division by an integer, rounded to nearest. Zero raises `DIV_BY_ZERO`.
    #[inline]
    pub fn div_int(self, k: i64) -> Scalar {
        if k == 0 {
            faults::raise(Faults::DIV_BY_ZERO);
            return self.saturate_sign();
        }
        Scalar::from_bits(narrow(div_round_i128(self.to_bits() as i128, k as i128)))
    }

    /// 1 / self, rounded to nearest. Zero raises `DIV_BY_ZERO` and saturates.
    #[inline]
    pub fn recip(self) -> Scalar {
        Scalar::ONE / self
    }

    /// `self / d`, or `None` when `d` is zero or the quotient overflows.
    /// For callers that have a meaningful fallback (no fault is raised).
    pub fn checked_div(self, d: Scalar) -> Option<Scalar> {
        if d.is_zero() {
            return None;
        }
        let q = div_round_i128((self.to_bits() as i128) << 32, d.to_bits() as i128);
        i64::try_from(q).ok().map(Scalar::from_bits)
    }

    /// The product as an unrounded Q64.64 `i128`, for exact accumulation.
    #[inline(always)]
    pub const fn wide_mul(self, other: Scalar) -> i128 {
        self.to_bits() as i128 * other.to_bits() as i128
    }

    /// Rounds a Q64.64 accumulator (sum of [`wide_mul`](Self::wide_mul)s)
    /// back to Q32.32: one rounding for a whole dot product.
    #[inline(always)]
    pub fn from_wide(acc: i128) -> Scalar {
        Scalar::from_bits(narrow(round_shift32(acc)))
    }

    /// `a * b + c * d` with a single rounding.
    #[inline(always)]
    pub fn mul_add2(a: Scalar, b: Scalar, c: Scalar, d: Scalar) -> Scalar {
        Scalar::from_wide(wide_sum([a.wide_mul(b), c.wide_mul(d)]))
    }

    /// `a * b - c * d` with a single rounding.
    #[inline(always)]
    pub fn mul_sub2(a: Scalar, b: Scalar, c: Scalar, d: Scalar) -> Scalar {
        // -(c*d) cannot overflow: |c*d| <= 2^126.
        Scalar::from_wide(wide_sum([a.wide_mul(b), -c.wide_mul(d)]))
    }

    fn saturate_sign(self) -> Scalar {
        if self.is_negative() {
            Scalar::MIN
        } else {
            Scalar::MAX
        }
    }

    /// The integer part, rounded toward −∞.
    pub const fn floor_int(self) -> i64 {
        self.to_bits() >> 32
    }
}

/// A [`Scalar`] from a number literal, converted exactly at compile time:
/// `scalar!(0.5)` is `Scalar::from_decimal_str("0.5")` in a `const` block.
///
/// The literal is taken as written (its digits, not an `f64`), so
/// `scalar!(0.1)` is the Q32.32 value nearest to one tenth, the same bits a
/// scene file gives for `0.1`. Integers, negative numbers, exponents and
/// underscores work; suffixes (`0.5f32`) and hex do not compile.
///
/// ```
/// use lockstep_core::{Scalar, scalar};
///
/// assert_eq!(scalar!(0.5), Scalar::HALF);
/// assert_eq!(scalar!(-9.81), Scalar::from_ratio(-981, 100));
/// assert_eq!(scalar!(3), Scalar::from_int(3));
/// assert_eq!(scalar!(2.5e-3), Scalar::from_ratio(1, 400));
/// assert_eq!(scalar!(1_000.25), Scalar::from_ratio(4001, 4));
/// ```
#[macro_export]
macro_rules! scalar {
    ($lit:literal) => {
        const { $crate::math::scalar::Scalar::from_decimal_str(stringify!($lit)) }
    };
}

impl Add for Scalar {
    type Output = Scalar;
    #[inline(always)]
    fn add(self, rhs: Scalar) -> Scalar {
        match self.to_bits().checked_add(rhs.to_bits()) {
            Some(v) => Scalar::from_bits(v),
            None => {
                faults::raise(Faults::OVERFLOW);
                self.saturate_sign()
            }
        }
    }
}

impl Sub for Scalar {
    type Output = Scalar;
    #[inline(always)]
    fn sub(self, rhs: Scalar) -> Scalar {
        match self.to_bits().checked_sub(rhs.to_bits()) {
            Some(v) => Scalar::from_bits(v),
            None => {
                faults::raise(Faults::OVERFLOW);
                self.saturate_sign()
            }
        }
    }
}

impl Neg for Scalar {
    type Output = Scalar;
    #[inline(always)]
    fn neg(self) -> Scalar {
        match self.to_bits().checked_neg() {
            Some(v) => Scalar::from_bits(v),
            None => {
                faults::raise(Faults::OVERFLOW);
                Scalar::MAX
            }
        }
    }
}

impl Mul for Scalar {
    type Output = Scalar;
    /// Rounds to nearest, ties away from zero; saturates on overflow.
    #[inline(always)]
    fn mul(self, rhs: Scalar) -> Scalar {
        Scalar::from_wide(self.wide_mul(rhs))
    }
}

impl Div for Scalar {
    type Output = Scalar;
    /// Rounds to nearest, ties away from zero. Division by zero saturates
    /// toward the dividend's sign and raises `DIV_BY_ZERO`; overflow
    /// saturates and raises `OVERFLOW`.
    #[inline]
    #[allow(clippy::suspicious_arithmetic_impl)] // the shift is the Q32.32 scaling
    fn div(self, rhs: Scalar) -> Scalar {
        if rhs.is_zero() {
            faults::raise(Faults::DIV_BY_ZERO);
            return self.saturate_sign();
        }
        Scalar::from_bits(narrow(div_round_i128(
            (self.to_bits() as i128) << 32,
            rhs.to_bits() as i128,
        )))
    }
}

macro_rules! assign_op {
    ($tr:ident, $f:ident, $op:tt) => {
        impl $tr for Scalar {
            #[inline(always)]
            fn $f(&mut self, rhs: Scalar) {
                *self = *self $op rhs;
            }
        }
    };
}
assign_op!(AddAssign, add_assign, +);
assign_op!(SubAssign, sub_assign, -);
assign_op!(MulAssign, mul_assign, *);
assign_op!(DivAssign, div_assign, /);

impl std::iter::Sum for Scalar {
    fn sum<I: Iterator<Item = Scalar>>(iter: I) -> Scalar {
        iter.fold(Scalar::ZERO, |a, b| a + b)
    }
}

impl fmt::Display for Scalar {
    /// The exact decimal value (at most 32 fraction digits, trailing zeros
    /// removed): printing then parsing gives back the same bits.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&super::decimal::format_exact(*self))
    }
}

impl fmt::Debug for Scalar {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

impl std::str::FromStr for Scalar {
    type Err = super::decimal::ParseDecimalError;
    /// Parses a decimal exactly, rounding to the nearest Q32.32 value.
    fn from_str(s: &str) -> Result<Scalar, Self::Err> {
        super::decimal::parse_exact(s)
    }
}

impl Serialize for Scalar {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_i64(self.to_bits())
    }
}

impl<'de> Deserialize<'de> for Scalar {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Scalar, D::Error> {
        i64::deserialize(d).map(Scalar::from_bits)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::faults::{self, FaultScope};
    use crate::testing::{Rng, s};

    #[test]
    fn multiplication_rounds_to_nearest_and_is_odd_symmetric() {
        // DELTA * 0.5 is exactly half an ulp: ties go away from zero.
        assert_eq!(Scalar::DELTA * Scalar::HALF, Scalar::DELTA);
        assert_eq!((-Scalar::DELTA) * Scalar::HALF, -Scalar::DELTA);
        // A third of an ulp rounds to zero on both sides.
        let third = Scalar::from_ratio(1, 3);
        assert_eq!(Scalar::DELTA * third, Scalar::ZERO);
        assert_eq!((-Scalar::DELTA) * third, Scalar::ZERO);
        for (a, b) in [(1.75, -3.125), (-0.1, 0.3), (12345.678, -0.000123)] {
            assert_eq!(s(-a) * s(b), -(s(a) * s(b)));
        }
    }

    #[test]
    fn multiplication_is_within_half_an_ulp_of_the_exact_product() {
        let mut rng = Rng::new(0x9e37_79b9_7f4a_7c15);
        for _ in 0..10_000 {
            let x = rng.next_u64();
            let a = Scalar::from_bits((x as i64) >> 24);
            let b = Scalar::from_bits((x.rotate_left(32) as i64) >> 26);
            let exact = a.wide_mul(b); // value * 2^64
            let got = (a * b).to_bits() as i128;
            let err = (got << 32) - exact;
            assert!(err.abs() <= 1i128 << 31, "{a} * {b}");
        }
    }

    #[test]
    fn overflow_saturates_and_raises_the_flag() {
        let (v, f) = FaultScope::run(|| Scalar::from_int(100_000) * Scalar::from_int(100_000));
        assert_eq!(v, Scalar::MAX);
        assert_eq!(f, Faults::OVERFLOW);
        let (v, f) = FaultScope::run(|| Scalar::MIN - Scalar::ONE);
        assert_eq!(v, Scalar::MIN);
        assert_eq!(f, Faults::OVERFLOW);
        let (v, f) = FaultScope::run(|| -Scalar::MIN);
        assert_eq!(v, Scalar::MAX);
        assert_eq!(f, Faults::OVERFLOW);
        let (v, f) = FaultScope::run(|| Scalar::from_int(7) + Scalar::from_int(8));
        assert_eq!(v, Scalar::from_int(15));
        assert!(f.is_empty());
    }

    #[test]
    fn division_by_zero_never_panics_and_is_reported() {
        let (v, f) = FaultScope::run(|| Scalar::ONE / Scalar::ZERO);
        assert_eq!(v, Scalar::MAX);
        assert_eq!(f, Faults::DIV_BY_ZERO);
        let (v, f) = FaultScope::run(|| Scalar::NEG_ONE / Scalar::ZERO);
        assert_eq!(v, Scalar::MIN);
        assert_eq!(f, Faults::DIV_BY_ZERO);
        let (v, f) = FaultScope::run(|| Scalar::ONE.div_int(0));
        assert_eq!(v, Scalar::MAX);
        assert_eq!(f, Faults::DIV_BY_ZERO);
        assert_eq!(Scalar::ONE.checked_div(Scalar::ZERO), None);
        assert!(faults::peek().is_empty());
    }

    #[test]
    fn division_rounds_to_nearest() {
        assert_eq!(
            Scalar::ONE / Scalar::from_int(3),
            Scalar::from_bits(1_431_655_765)
        );
        assert_eq!(
            Scalar::TWO / Scalar::from_int(3),
            Scalar::from_bits(2_863_311_531)
        );
        assert_eq!(
            Scalar::NEG_ONE * Scalar::TWO / Scalar::from_int(3),
            Scalar::from_bits(-2_863_311_531)
        );
        assert_eq!(Scalar::from_ratio(1, 60), Scalar::from_bits(71_582_788));
        assert_eq!(Scalar::from_int(-7).div_int(2), Scalar::from_ratio(-7, 2));
    }

    #[test]
    fn constants_are_the_nearest_values() {
        for (c, v) in [
            (Scalar::PI, std::f64::consts::PI),
            (Scalar::TAU, std::f64::consts::TAU),
            (Scalar::FRAC_PI_2, std::f64::consts::FRAC_PI_2),
        ] {
            assert!((c.to_f64() - v).abs() <= 0.5 / 4_294_967_296.0, "{c}");
        }
    }

    #[test]
    fn to_f32_is_the_nearest_float() {
        let mut rng = Rng::new(7);
        for _ in 0..10_000 {
            let x = rng.next_u64();
            // Below 2^21 the f64 is exact, so rounding it to f32 is the one
            // rounding to compare with.
            let v = Scalar::from_bits((x as i64) >> 10);
            assert_eq!(v.to_f32(), v.to_f64() as f32, "{v}");
        }
        assert_eq!(Scalar::MAX.to_f32(), 2_147_483_648.0);
        assert_eq!(Scalar::MIN.to_f32(), -2_147_483_648.0);
        assert_eq!(Scalar::DELTA.to_f32(), 1.0 / 4_294_967_296.0);
        assert_eq!(Scalar::from_ratio(-3, 2).to_f32(), -1.5);
    }

    #[test]
    fn half_rounds_ties_away_from_zero() {
        assert_eq!(Scalar::DELTA.half(), Scalar::DELTA);
        assert_eq!((-Scalar::DELTA).half(), -Scalar::DELTA);
        assert_eq!(Scalar::from_int(3).half(), Scalar::from_ratio(3, 2));
        assert_eq!(Scalar::from_int(-3).half(), Scalar::from_ratio(-3, 2));
    }
}
