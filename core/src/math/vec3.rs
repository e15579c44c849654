//! `Vec3`: a 3-vector of [`Scalar`]s.
//!
//! Dot products, squared lengths and cross-product components accumulate
//! their products exactly in `i128` (Q64.64) and round once, so they are as
//! accurate as one multiplication. Lengths take the integer square root of
//! the exact `i128` sum of squares: |v| never overflows, even for vectors
//! whose squared length would not fit in Q32.32 (anything over ~46 km).

use std::ops::{Add, AddAssign, Mul, MulAssign, Neg, Sub, SubAssign};

use serde::{Deserialize, Serialize};

use super::elem;
use super::scalar::{Scalar, narrow, round_shift, wide_sum};

/// A 3-vector.
#[derive(Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Vec3 {
    /// x component.
    pub x: Scalar,
    /// y component.
    pub y: Scalar,
    /// z component.
    pub z: Scalar,
}

impl std::fmt::Debug for Vec3 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "({}, {}, {})", self.x, self.y, self.z)
    }
}

impl Vec3 {
    /// (0, 0, 0).
    pub const ZERO: Vec3 = Vec3::new(Scalar::ZERO, Scalar::ZERO, Scalar::ZERO);
    /// (1, 0, 0).
    pub const X: Vec3 = Vec3::new(Scalar::ONE, Scalar::ZERO, Scalar::ZERO);
    /// (0, 1, 0).
    pub const Y: Vec3 = Vec3::new(Scalar::ZERO, Scalar::ONE, Scalar::ZERO);
    /// (0, 0, 1).
    pub const Z: Vec3 = Vec3::new(Scalar::ZERO, Scalar::ZERO, Scalar::ONE);

    /// A vector from its components.
    #[inline(always)]
    pub const fn new(x: Scalar, y: Scalar, z: Scalar) -> Vec3 {
        Vec3 { x, y, z }
    }

    /// A vector with integer components.
    pub const fn from_ints(x: i32, y: i32, z: i32) -> Vec3 {
        Vec3::new(
            Scalar::from_int(x),
            Scalar::from_int(y),
            Scalar::from_int(z),
        )
    }

    /// All three components equal to `v`.
    #[inline(always)]
    pub const fn splat(v: Scalar) -> Vec3 {
        Vec3::new(v, v, v)
    }

    /// Component `i` (0, 1 or 2; anything else is z).
    #[inline(always)]
    pub fn get(self, i: usize) -> Scalar {
        match i {
            0 => self.x,
            1 => self.y,
            _ => self.z,
        }
    }

    /// Sets component `i` (0, 1 or 2; anything else is z).
    #[inline(always)]
    pub fn set(&mut self, i: usize, v: Scalar) {
        match i {
            0 => self.x = v,
            1 => self.y = v,
            _ => self.z = v,
        }
    }

    /// The components as an array.
    pub const fn to_array(self) -> [Scalar; 3] {
        [self.x, self.y, self.z]
    }

    /// The components as the nearest `f32`s, for a renderer (positions,
    /// velocities to draw): output only, never fed back into the
    /// simulation.
    ///
    /// ```
    /// use lockstep_core::{Vec3, scalar};
    ///
    /// let p = Vec3::new(scalar!(1.5), scalar!(-2), scalar!(0.1));
    /// assert_eq!(p.to_f32_array(), [1.5, -2.0, 0.1]);
    /// assert_eq!(p.to_f64_array()[2], 0.1000000000931322574615478515625); // exact
    /// ```
    pub fn to_f32_array(self) -> [f32; 3] {
        self.to_array().map(Scalar::to_f32)
    }

    /// The components as `f64`s (exact below 2²¹ m), for output: tools,
    /// plots, renderers in double precision.
    pub fn to_f64_array(self) -> [f64; 3] {
        self.to_array().map(Scalar::to_f64)
    }

    /// The exact dot product as Q64.64, for further exact accumulation.
    #[inline(always)]
    pub fn dot_wide(self, o: Vec3) -> i128 {
        wide_sum([
            self.x.wide_mul(o.x),
            self.y.wide_mul(o.y),
            self.z.wide_mul(o.z),
        ])
    }

    /// Dot product, rounded once.
    #[inline(always)]
    pub fn dot(self, o: Vec3) -> Scalar {
        Scalar::from_wide(self.dot_wide(o))
    }

    /// Cross product; each component rounded once.
    #[inline(always)]
    pub fn cross(self, o: Vec3) -> Vec3 {
        Vec3::new(
            Scalar::mul_sub2(self.y, o.z, self.z, o.y),
            Scalar::mul_sub2(self.z, o.x, self.x, o.z),
            Scalar::mul_sub2(self.x, o.y, self.y, o.x),
        )
    }

    /// Squared length as an exact Q64.64 `i128` (never overflows).
    #[inline(always)]
    pub fn length_squared_wide(self) -> u128 {
        self.dot_wide(self) as u128
    }

    /// Squared length, rounded once (overflows, with the fault raised, past
    /// about 46,341).
    #[inline(always)]
    pub fn length_squared(self) -> Scalar {
        self.dot(self)
    }

    /// Length, the floor of the exact value (integer square root of the
    /// exact sum of squares); never overflows.
    #[inline]
    pub fn length(self) -> Scalar {
        Scalar::from_bits(elem::isqrt_u128(self.length_squared_wide()) as i64)
    }

    /// Distance to another point.
    #[inline]
    pub fn distance(self, o: Vec3) -> Scalar {
        (self - o).length()
    }

    /// The unit vector in the same direction (each component within 1 ulp
    /// of exact, whatever the magnitude; see `scale_to_unit`) and the
    /// original length (the exact floor); `None` for the zero vector.
    #[inline]
    pub fn normalize_and_length(self) -> Option<(Vec3, Scalar)> {
        let sq = self.length_squared_wide();
        if sq == 0 {
            return None;
        }
        let [x, y, z] = scale_to_unit([self.x, self.y, self.z], sq);
        Some((
            Vec3::new(x, y, z),
            Scalar::from_bits(elem::isqrt_u128(sq) as i64),
        ))
    }

    /// The unit vector in the same direction, or `None` for the zero vector.
    #[inline]
    pub fn try_normalize(self) -> Option<Vec3> {
        let sq = self.length_squared_wide();
        if sq == 0 {
            return None;
        }
        let [x, y, z] = scale_to_unit([self.x, self.y, self.z], sq);
        Some(Vec3::new(x, y, z))
    }

    /// The unit vector in the same direction, or zero for the zero vector.
    #[inline]
    pub fn normalize_or_zero(self) -> Vec3 {
        self.try_normalize().unwrap_or(Vec3::ZERO)
    }

    /// Multiplies every component by 2^k exactly (saturating on overflow).
    pub fn scale_pow2(self, k: u32) -> Vec3 {
        let f = |c: Scalar| Scalar::from_bits(narrow((c.to_bits() as i128) << k));
        Vec3::new(f(self.x), f(self.y), f(self.z))
    }

    /// Every component times an integer, exact unless it overflows.
    #[inline(always)]
    pub fn mul_int(self, k: i64) -> Vec3 {
        Vec3::new(self.x.mul_int(k), self.y.mul_int(k), self.z.mul_int(k))
    }

    /// Component-wise product.
    #[inline(always)]
    pub fn mul_elem(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x * o.x, self.y * o.y, self.z * o.z)
    }

    /// Component-wise minimum.
    #[inline(always)]
    pub fn min(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x.min(o.x), self.y.min(o.y), self.z.min(o.z))
    }

    /// Component-wise maximum.
    #[inline(always)]
    pub fn max(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x.max(o.x), self.y.max(o.y), self.z.max(o.z))
    }

    /// Component-wise absolute value.
    #[inline(always)]
    pub fn abs(self) -> Vec3 {
        Vec3::new(self.x.abs(), self.y.abs(), self.z.abs())
    }

    /// The largest component.
    pub fn max_element(self) -> Scalar {
        self.x.max(self.y).max(self.z)
    }

    /// The smallest component.
    pub fn min_element(self) -> Scalar {
        self.x.min(self.y).min(self.z)
    }

    /// Whether every component is zero.
    #[inline(always)]
    pub fn is_zero(self) -> bool {
        self.x.is_zero() && self.y.is_zero() && self.z.is_zero()
    }

    /// Half of each component (rounded to nearest).
    #[inline(always)]
    pub fn half(self) -> Vec3 {
        Vec3::new(self.x.half(), self.y.half(), self.z.half())
    }

    /// `self + d * s` with each component rounded once.
    #[inline(always)]
    pub fn add_scaled(self, d: Vec3, s: Scalar) -> Vec3 {
        self + d * s
    }

    /// Linear interpolation `self + (o - self) * t`.
    pub fn lerp(self, o: Vec3, t: Scalar) -> Vec3 {
        self + (o - self) * t
    }

    /// A unit vector perpendicular to `self` (which should be unit length).
    /// Deterministic choice: crosses with the axis of the smallest component.
    pub fn any_orthonormal(self) -> Vec3 {
        let a = self.abs();
        let other = if a.x <= a.y && a.x <= a.z {
            Vec3::X
        } else if a.y <= a.z {
            Vec3::Y
        } else {
            Vec3::Z
        };
        self.cross(other).normalize_or_zero()
    }
}

impl Add for Vec3 {
    type Output = Vec3;
    #[inline(always)]
    fn add(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}

impl Sub for Vec3 {
    type Output = Vec3;
    #[inline(always)]
    fn sub(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}

impl Neg for Vec3 {
    type Output = Vec3;
    #[inline(always)]
    fn neg(self) -> Vec3 {
        Vec3::new(-self.x, -self.y, -self.z)
    }
}

impl Mul<Scalar> for Vec3 {
    type Output = Vec3;
    #[inline(always)]
    fn mul(self, s: Scalar) -> Vec3 {
        Vec3::new(self.x * s, self.y * s, self.z * s)
    }
}

impl Mul<Vec3> for Scalar {
    type Output = Vec3;
    #[inline(always)]
    fn mul(self, v: Vec3) -> Vec3 {
        v * self
    }
}

impl AddAssign for Vec3 {
    #[inline(always)]
    fn add_assign(&mut self, o: Vec3) {
        *self = *self + o;
    }
}

impl SubAssign for Vec3 {
    #[inline(always)]
    fn sub_assign(&mut self, o: Vec3) {
        *self = *self - o;
    }
}

impl MulAssign<Scalar> for Vec3 {
    #[inline(always)]
    fn mul_assign(&mut self, s: Scalar) {
        *self = *self * s;
    }
}

/// Divides `components` by the square root of `sq` (their exact sum of
/// squares, Q64.64, non-zero), each to within 1 ulp.
///
/// The sum is scaled by an even power of two into `[2¹²⁶, 2¹²⁸)`, so short
/// vectors keep their precision; its top 64 bits go to the table-seeded
/// integer reciprocal square root ([`elem::rsqrt_q61`], relative error below
/// 2⁻³³), and each component is one 64×64-bit product and a shift: no
/// division.
#[inline]
pub(crate) fn scale_to_unit<const N: usize>(components: [Scalar; N], sq: u128) -> [Scalar; N] {
    let shift = sq.leading_zeros() & !1; // even, <= 126 since sq >= 1
    let x = ((sq << shift) >> 64) as u64; // A * 2^64 with A in [1/4, 1)
    let y = elem::rsqrt_q61(x) as i128; // 1/sqrt(A) in Q61, in (2^61, 2^62]
    // unit = c / sqrt(sq) = c * y * 2^(shift/2 - 93) in bits.
    let down = 93 - shift / 2;
    components.map(|c| Scalar::from_bits(narrow(round_shift(c.to_bits() as i128 * y, down))))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::faults::{FaultScope, Faults};
    use crate::testing::{Rng, v};

    #[test]
    fn length_of_world_scale_vectors_does_not_overflow() {
        // 1,000 km: the squared length (1e12) is far outside Q32.32.
        let big = v(600_000.0, -800_000.0, 0.0);
        let (len, faults) = FaultScope::run(|| big.length());
        assert_eq!(len, Scalar::from_int(1_000_000));
        assert!(faults.is_empty());
        let (_, faults) = FaultScope::run(|| big.length_squared());
        assert!(faults.contains(Faults::OVERFLOW));
    }

    #[test]
    fn dot_and_cross_match_f64_within_half_an_ulp() {
        let a = v(1.25, -3.5, 7.125);
        let b = v(-0.3, 2.2, 0.7);
        let exact = |p: Vec3, q: Vec3| {
            p.x.to_f64() * q.x.to_f64() + p.y.to_f64() * q.y.to_f64() + p.z.to_f64() * q.z.to_f64()
        };
        let ulp = 1.0 / 4_294_967_296.0;
        assert!((a.dot(b).to_f64() - exact(a, b)).abs() <= 0.5 * ulp + 1e-15);
        let c = a.cross(b);
        assert!(c.dot(a).abs() <= Scalar::from_bits(64));
        assert!(c.dot(b).abs() <= Scalar::from_bits(64));
        assert_eq!(Vec3::X.cross(Vec3::Y), Vec3::Z);
    }

    #[test]
    fn normalize_gives_unit_length_within_two_ulps() {
        let mut rng = Rng::new(7);
        for _ in 0..10_000 {
            let x = rng.next_u64();
            let p = Vec3::new(
                Scalar::from_bits((x as i64) >> 20),
                Scalar::from_bits((x.rotate_left(21) as i64) >> 20),
                Scalar::from_bits((x.rotate_left(42) as i64) >> 20),
            );
            let n = p.try_normalize().unwrap();
            let len = n.length_squared_wide() as f64 / 2f64.powi(64);
            assert!(
                (len.sqrt() - 1.0).abs() < 3.0 / 4_294_967_296.0,
                "{p:?} -> {n:?}"
            );
        }
        assert_eq!(Vec3::ZERO.try_normalize(), None);
        let tiny = Vec3::new(Scalar::DELTA, Scalar::ZERO, Scalar::ZERO);
        assert_eq!(tiny.try_normalize(), Some(Vec3::X));
        assert_eq!(v(0.0, -5.0, 0.0).try_normalize(), Some(-Vec3::Y));
    }
}
