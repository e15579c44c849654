//! Velocities in quanta for the narrow passes: a body's Q32.32 velocity
//! taken to quanta once per pass, and the change given back once.

use super::constraint::BodyVel;
use crate::math::{Scalar, Vec3};

/// The velocity quantum's exponent: rows hold velocities and impulses as
/// integers of `2^-S` m/s (rad/s).
pub(crate) const S: u32 = 20;

/// Q32.32 bits to quanta: a right shift by this many bits.
pub(super) const TO_Q: u32 = 32 - S;

/// `x / 2^e` rounded to nearest, ties toward +∞ (`1 ≤ e ≤ 62`). Wrapping:
/// exact whenever `|x| < 2⁶³ − 2^(e−1)`, which every caller's bound gives
/// (a guard-failed visit may compute garbage here; it is thrown away).
#[inline(always)]
pub(super) fn rsh(x: i64, e: u32) -> i64 {
    x.wrapping_add(1 << (e - 1)) >> e
}

/// Q32.32 bits to quanta, rounded as [`rsh`]; cannot overflow
/// (`⌊(⌊x/2⌋ + 2¹⁰)/2¹¹⌋ = ⌊(x + 2¹¹)/2¹²⌋`).
#[inline(always)]
pub(super) fn quanta(x: Scalar) -> i64 {
    ((x.to_bits() >> 1) + (1 << (TO_Q - 2))) >> (TO_Q - 1)
}

/// A change in quanta as Q32.32 (exact: `|q| < 2⁵¹`).
#[inline(always)]
pub(super) fn from_quanta3(q: &[i64; 3]) -> Vec3 {
    Vec3::new(
        Scalar::from_bits(q[0] << TO_Q),
        Scalar::from_bits(q[1] << TO_Q),
        Scalar::from_bits(q[2] << TO_Q),
    )
}

/// A solver body's velocity in quanta during a narrow pass: `v` in
/// `q[0..3]`, `ω` in `q[4..7]` (32 bytes, aligned for the lanes' loads).
/// Each component is the Q32.32 velocity rounded to the quantum as
/// [`quanta`] rounds it, saturated to 32 bits (a saturated component is
/// past the guard, so no narrow visit writes its body).
///
/// A pass takes every body's quanta from its Q32.32 velocity once
/// ([`quantize`]), the narrow visits read and write the quanta, and the
/// pass gives the change back once ([`flush`]): `v += (q − q₀)·2^(32−S)`.
/// That is the same bits as taking the quanta at every visit and adding
/// each visit's change back at once, because adding a whole number of
/// quanta to a Q32.32 velocity moves its rounded quanta by exactly that
/// number. A Q32.32 visit inside a narrow pass gives its bodies' change
/// back first and takes their quanta again after (see
/// `BodyArrays::flush_one`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(C, align(32))]
pub(super) struct Quanta {
    pub(super) q: [i32; 8],
}

impl Quanta {
    /// The quanta of a Q32.32 velocity (saturated to 32 bits).
    #[inline(always)]
    pub(super) fn of(vel: &BodyVel) -> Quanta {
        let s = |x: Scalar| quanta(x).clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        Quanta {
            q: [
                s(vel.v.x),
                s(vel.v.y),
                s(vel.v.z),
                0,
                s(vel.w.x),
                s(vel.w.y),
                s(vel.w.z),
                0,
            ],
        }
    }
}

/// Every body's quanta taken from its Q32.32 velocity, at a narrow pass's
/// start.
pub(super) fn quantize(vels: &[BodyVel], q: &mut [Quanta], q0: &mut [Quanta]) {
    for ((v, q), q0) in vels.iter().zip(q.iter_mut()).zip(q0.iter_mut()) {
        *q = Quanta::of(v);
        *q0 = *q;
    }
}

/// Every body's change in quanta given back to its Q32.32 velocity, at a
/// narrow pass's end.
pub(super) fn flush(vels: &mut [BodyVel], q: &[Quanta], q0: &mut [Quanta]) {
    for ((v, q), q0) in vels.iter_mut().zip(q).zip(q0.iter_mut()) {
        flush_body(v, q, q0);
    }
}

/// One body's change in quanta since `q0` added to its Q32.32 velocity
/// (exact: the change is below 2³⁰ quanta while the guard passes, and a
/// body the guard refused did not change); `q0` moves to `q`.
#[inline(always)]
pub(super) fn flush_body(v: &mut BodyVel, q: &Quanta, q0: &mut Quanta) {
    if q.q != q0.q {
        let d = |k: usize| q.q[k] as i64 - q0.q[k] as i64;
        v.v += from_quanta3(&[d(0), d(1), d(2)]);
        v.w += from_quanta3(&[d(4), d(5), d(6)]);
        *q0 = *q;
    }
}
