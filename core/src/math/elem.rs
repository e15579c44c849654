//! Integer-only elementary functions on Q32.32.
//!
//! Bit-exact on every platform: only integer arithmetic, no floats, no
//! platform intrinsics whose results could differ.

use super::faults::{self, Faults};
use super::scalar::Scalar;

/// ⌊√n⌋ for a `u128`, exact.
#[inline]
pub fn isqrt_u128(n: u128) -> u64 {
    n.isqrt() as u64
}

/// √x, the exact floor of the true root (error < 1 ulp, never above).
///
/// A negative argument raises [`Faults::DOMAIN`] and returns zero.
#[inline]
pub fn sqrt(x: Scalar) -> Scalar {
    let bits = x.to_bits();
    if bits < 0 {
        faults::raise(Faults::DOMAIN);
        return Scalar::ZERO;
    }
    Scalar::from_bits(isqrt_u128((bits as u128) << 32) as i64)
}

/// 1/√x, rounded to nearest.
///
/// Zero or a negative argument raises [`Faults::DOMAIN`] and returns
/// [`Scalar::MAX`].
pub fn rsqrt(x: Scalar) -> Scalar {
    let bits = x.to_bits();
    if bits <= 0 {
        faults::raise(Faults::DOMAIN);
        return Scalar::MAX;
    }
    // 1/sqrt(b / 2^32) * 2^32 = 2^48 / sqrt(b) = sqrt(2^96 / b).
    let q = (1u128 << 96) / bits as u128;
    Scalar::from_bits(isqrt_u128(q).min(i64::MAX as u64) as i64)
}

/// π/2 in Q2.64 (round to nearest of 1.5707963267948966192313216916...).
const FRAC_PI_2_Q64: i128 = 0x1_921F_B544_42D1_8469;

/// Multiplies two Q62 values, rounding to nearest.
#[inline(always)]
fn mul_q62(a: i128, b: i128) -> i128 {
    super::scalar::round_shift(a * b, 62)
}

/// Sine and cosine of `x` (radians), each within 1 ulp of the true value.
///
/// Range reduction by π/2 uses a 66-bit constant, so even |x| near 2³¹ is
/// reduced with an error below one ulp; the kernel is a Taylor polynomial in
/// Q2.62 evaluated with integer Horner steps.
pub fn sin_cos(x: Scalar) -> (Scalar, Scalar) {
    let xq = (x.to_bits() as i128) << 32; // Q64
    let k = super::scalar::div_round_i128(xq, FRAC_PI_2_Q64);
    let r = xq - k * FRAC_PI_2_Q64; // |r| <= pi/4 in Q64
    let r = super::scalar::round_shift(r, 2); // Q62
    let r2 = mul_q62(r, r);
    const ONE: i128 = 1 << 62;
    // 1/n! in Q62 for the Taylor coefficients.
    let inv_fact = |n: u32| -> i128 {
        let mut f: i128 = 1;
        for i in 2..=n as i128 {
            f *= i;
        }
        super::scalar::div_round_i128(ONE, f)
    };
    // sin r = r (1 - r²/3! (1 - r²/(4·5) (1 - ...))) evaluated directly by
    // summing terms with alternating signs.
    let mut s = 0i128;
    let mut c = 0i128;
    let mut sign = 1i128;
    let mut p_odd = r; // r^(2i+1)
    let mut p_even = ONE; // r^(2i)
    for i in 0..8u32 {
        s += sign * mul_q62(p_odd, inv_fact(2 * i + 1));
        c += sign * mul_q62(p_even, inv_fact(2 * i));
        p_odd = mul_q62(p_odd, r2);
        p_even = mul_q62(p_even, r2);
        sign = -sign;
    }
    let to_scalar = |v: i128| Scalar::from_bits(super::scalar::round_shift(v, 30) as i64);
    let (s, c) = (to_scalar(s), to_scalar(c));
    match k.rem_euclid(4) {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// atan2(y, x) in (−π, π], by a 62-step integer CORDIC in Q62 (atan2(0,0)
/// is 0).
pub fn atan2(y: Scalar, x: Scalar) -> Scalar {
    if x.is_zero() && y.is_zero() {
        return Scalar::ZERO;
    }
    // Rotate into the right half-plane first.
    let (mut xr, mut yr, base): (i128, i128, i128) = if x.is_negative() {
        if y.is_negative() {
            (
                -(x.to_bits() as i128),
                -(y.to_bits() as i128),
                -(Scalar::PI.to_bits() as i128) << 30,
            )
        } else {
            (
                -(x.to_bits() as i128),
                -(y.to_bits() as i128),
                (Scalar::PI.to_bits() as i128) << 30,
            )
        }
    } else {
        (x.to_bits() as i128, y.to_bits() as i128, 0)
    };
    // Scale so the larger coordinate has ~64 significant bits.
    let m = xr.abs().max(yr.abs());
    let shift = 64i32 - (128 - m.leading_zeros() as i32);
    if shift > 0 {
        xr <<= shift;
        yr <<= shift;
    } else {
        xr >>= -shift;
        yr >>= -shift;
    }
    let mut angle: i128 = 0; // Q62
    for i in 0..62u32 {
        let t = atan_pow2_q62(i);
        let (nx, ny) = if yr > 0 {
            angle += t;
            (xr + (yr >> i), yr - (xr >> i))
        } else {
            angle -= t;
            (xr - (yr >> i), yr + (xr >> i))
        };
        xr = nx;
        yr = ny;
    }
    let total = base + angle;
    Scalar::from_bits(super::scalar::round_shift(total, 30) as i64)
}

/// atan(2^-i) in Q62, from a series evaluated in integers.
fn atan_pow2_q62(i: u32) -> i128 {
    // atan(t) = t - t^3/3 + t^5/5 - ..., t = 2^-i; for i = 0 use pi/4.
    if i == 0 {
        return FRAC_PI_2_Q64 >> 3;
    }
    let one: i128 = 1 << 62;
    let t = one >> i;
    let mut sum = 0i128;
    let mut p = t;
    let mut k = 1i128;
    let mut sign = 1i128;
    while p != 0 {
        sum += sign * p / k;
        p = (p >> i) >> i;
        k += 2;
        sign = -sign;
    }
    sum
}
