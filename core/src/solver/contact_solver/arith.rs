//! The contact solver's small exact helpers on Q32.32 numbers and vectors
//! (no solver types), and the cache hint.

use crate::math::lanes::narrow;
use crate::math::scalar::wide_sum;
use crate::math::{Scalar, Vec3};

/// A unit tangent for normal `n`, continuous for normals within about 54°
/// of the y or z axis and of the x axis: the switch between the two
/// formulas (at |n.x| = 0.577) is far from the axis-aligned normals of
/// resting contacts, so the friction impulses carried from last tick keep
/// their directions while a normal wobbles.
pub(super) fn tangent_of(n: Vec3) -> Vec3 {
    // 0.57735 ≈ 1/√3 (bits of 0.57735·2³²): every unit vector has a
    // component at least this big.
    const SWITCH: Scalar = Scalar::from_bits(2_479_700_526);
    if n.x.abs() >= SWITCH {
        Vec3::new(n.y, -n.x, Scalar::ZERO).normalize_or_zero()
    } else {
        Vec3::new(Scalar::ZERO, n.z, -n.y).normalize_or_zero()
    }
}

/// `1/k`, or zero when `k` is zero (two infinite masses never reach here,
/// but a degenerate inertia must not divide by zero).
pub(super) fn inverse_or_zero(k: Scalar) -> Scalar {
    if k.is_positive() {
        k.recip()
    } else {
        Scalar::ZERO
    }
}

/// `a·x + b·y + c·z`, each component rounded once.
#[inline(always)]
pub(super) fn combine3(a: Vec3, x: Scalar, b: Vec3, y: Scalar, c: Vec3, z: Scalar) -> Vec3 {
    let e = |i: usize| {
        round_wide(wide_sum([
            a.get(i).wide_mul(x),
            b.get(i).wide_mul(y),
            c.get(i).wide_mul(z),
        ]))
    };
    Vec3::new(e(0), e(1), e(2))
}

/// `a·b` rounded to nearest, ties toward +∞ (one rounding per product, as
/// `a * b`, which sends ties away from zero: a tie needs the low 32 bits
/// of the product to be exactly one half, about one product in 2³²), and
/// saturated with the overflow fault. Cheaper than `a * b` in the
/// iterations: a product of two `i64` is at most 2¹²⁶ in size, so adding
/// the half cannot overflow and only the final narrowing needs a check.
#[inline(always)]
pub(super) fn mul(a: Scalar, b: Scalar) -> Scalar {
    crate::math::lanes::mul_round_up(a, b)
}

/// A Q64.64 accumulator rounded to Q32.32, to nearest with ties toward +∞
/// (as [`mul`]), saturated with the overflow fault. Cheaper than
/// `Scalar::from_wide` (one checked add for the half, one check of the
/// narrowing).
#[inline(always)]
pub(super) fn round_wide(acc: i128) -> Scalar {
    narrow(match acc.checked_add(1 << 31) {
        Some(x) => x >> 32,
        None => i128::MAX >> 32,
    })
}

/// `a × b`, each component rounded once by [`round_wide`].
#[inline(always)]
pub(super) fn cross(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(
        round_wide(wide_sum([a.y.wide_mul(b.z), -a.z.wide_mul(b.y)])),
        round_wide(wide_sum([a.z.wide_mul(b.x), -a.x.wide_mul(b.z)])),
        round_wide(wide_sum([a.x.wide_mul(b.y), -a.y.wide_mul(b.x)])),
    )
}

/// `v·s` per component with [`mul`].
#[inline(always)]
pub(super) fn scale(v: Vec3, s: Scalar) -> Vec3 {
    Vec3::new(mul(v.x, s), mul(v.y, s), mul(v.z, s))
}

/// Hints the CPU to start loading `x` into the cache (a hint only: it
/// changes no value, so results do not depend on it).
#[inline(always)]
pub(super) fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let base = x as *const T as *const i8;
        let mut off = 0;
        while off < size_of::<T>() {
            // SAFETY: a prefetch never faults and reads nothing into the
            // program; the address lies inside `x`.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(base.add(off)) };
            off += 64;
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}
