//! The solver's row arithmetic: relative velocities along a direction,
//! impulse application, and the products and roundings the passes use
//! (ties toward +∞, see [`mul`]). Kept apart from the passes so the passes
//! read as the algorithm.

use super::narrow::{Quanta, flush_body};
use super::{BodyVel, Constraint, NONE, SolverBody};
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

/// `k = 1/mA + 1/mB + (rA×d)·I⁻¹A(rA×d) + (rB×d)·I⁻¹B(rB×d)`.
/// `ia_d`, `ib_d` are `I⁻¹A (rA×d)` and `I⁻¹B (rB×d)`, already computed.
pub(super) fn effective(
    a: &SolverBody,
    b: &SolverBody,
    ra_d: Vec3,
    rb_d: Vec3,
    ia_d: Vec3,
    ib_d: Vec3,
) -> Scalar {
    let wide = a.inv_mass.to_bits() as i128 * (1i128 << 32)
        + b.inv_mass.to_bits() as i128 * (1i128 << 32)
        + ra_d.dot_wide(ia_d)
        + rb_d.dot_wide(ib_d);
    round_wide(wide)
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

/// Velocity of B's anchor relative to A's along the unit direction `d`,
/// from `r×d` of each anchor: `d·(vB − vA) + (rB×d)·ωB − (rA×d)·ωA`,
/// rounded once.
#[inline(always)]
pub(super) fn along(a: &BodyVel, b: &BodyVel, d: Vec3, ra_d: Vec3, rb_d: Vec3) -> Scalar {
    round_wide(wide_sum([
        d.dot_wide(b.v - a.v),
        rb_d.dot_wide(b.w),
        -ra_d.dot_wide(a.w),
    ]))
}

/// Applies the angular part of impulse `λ·d` at the anchors: `ω_B` moves by
/// `λ·I⁻¹B(rB×d)` and `ω_A` by `−λ·I⁻¹A(rA×d)` (given as `ib_d`, `ia_d`);
/// the linear part is summed per visit and applied by [`apply_linear`], the
/// angular impulse at the write-back ([`ContactSolver::scatter`]). A missing
/// body (`NONE`) is skipped; a kinematic one has zero inverse inertia.
#[inline(always)]
pub(super) fn push_angular(
    va: &mut BodyVel,
    vb: &mut BodyVel,
    a: u32,
    b: u32,
    lambda: Scalar,
    ia_d: Vec3,
    ib_d: Vec3,
) {
    if a != NONE {
        va.w -= scale(ia_d, lambda);
    }
    if b != NONE {
        vb.w += scale(ib_d, lambda);
    }
}

/// The relative linear velocity `vB − vA` along the constraint's normal and
/// two tangents, each rounded once.
#[inline(always)]
pub(super) fn linear_basis(c: &Constraint, va: &BodyVel, vb: &BodyVel) -> [Scalar; 3] {
    let dv = vb.v - va.v;
    [
        round_wide(c.normal.dot_wide(dv)),
        round_wide(c.tangent[0].dot_wide(dv)),
        round_wide(c.tangent[1].dot_wide(dv)),
    ]
}

/// Applies the linear part of impulses `imp` along the normal and the two
/// tangents (B receives `+P`, A receives `−P`, `P = imp₀n + imp₁t₀ +
/// imp₂t₁`): `vB += P/mB`, `vA −= P/mA`.
#[inline(always)]
pub(super) fn apply_linear(c: &Constraint, va: &mut BodyVel, vb: &mut BodyVel, imp: [Scalar; 3]) {
    if imp == [Scalar::ZERO; 3] {
        return;
    }
    let [i0, i1, i2] = imp;
    let p = combine3(c.normal, i0, c.tangent[0], i1, c.tangent[1], i2);
    if c.a != NONE {
        va.v -= scale(p, c.inv_mass_a);
    }
    if c.b != NONE {
        vb.v += scale(p, c.inv_mass_b);
    }
}

/// The angular part of the relative velocity of B's anchor against A's
/// along a direction `d`, from `r×d` of each anchor: `(rB×d)·ωB −
/// (rA×d)·ωA`, rounded once.
#[inline(always)]
pub(super) fn angular_along(a: &BodyVel, b: &BodyVel, ra_d: Vec3, rb_d: Vec3) -> Scalar {
    round_wide(wide_sum([rb_d.dot_wide(b.w), -ra_d.dot_wide(a.w)]))
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

/// The velocity state of solver body `i`, or zero for `NONE`.
#[inline(always)]
pub(super) fn vel_or_zero(vels: &[BodyVel], i: u32) -> BodyVel {
    if i == NONE {
        BodyVel::default()
    } else {
        vels[i as usize]
    }
}

#[inline(always)]
pub(super) fn load(vels: &[BodyVel], a: u32, b: u32) -> (BodyVel, BodyVel) {
    (vel_or_zero(vels, a), vel_or_zero(vels, b))
}

#[inline(always)]
pub(super) fn store(vels: &mut [BodyVel], a: u32, b: u32, va: BodyVel, vb: BodyVel) {
    if a != NONE {
        vels[a as usize] = va;
    }
    if b != NONE {
        vels[b as usize] = vb;
    }
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

/// The solver bodies' velocities and angular write-back sums, shared by
/// the workers of one colour pass (see [`BodyArrays::new`]).
#[derive(Clone, Copy)]
pub(super) struct BodyArrays {
    vels: *mut BodyVel,
    dls: *mut Vec3,
    warm: *mut BodyVel,
    /// The narrow rows' velocities in quanta during a pass, and their
    /// values when last taken from `vels` (see [`Quanta`]); null
    /// outside the narrow rows' passes.
    q: *mut Quanta,
    q0: *mut Quanta,
    len: usize,
}

// SAFETY: see `BodyArrays::new`: workers touch disjoint entries within a
// colour, and a colour starts after the one before it has finished.
unsafe impl Send for BodyArrays {}
// SAFETY: as above.
unsafe impl Sync for BodyArrays {}

impl BodyArrays {
    /// Shares `vels`, `dls` and `warm` (one entry per solver body) for one
    /// pass.
    ///
    /// # Safety
    /// Until the pass ends the caller uses neither slice, and any entry
    /// written through the result by one thread is touched by no other
    /// thread until they synchronise: the constraints visited at once share
    /// no dynamic body (one colour), and only dynamic bodies are written
    /// (`wa`/`wb` of a constraint are `NONE` for a kinematic body).
    pub(super) unsafe fn new(
        vels: &mut [BodyVel],
        dls: &mut [Vec3],
        warm: &mut [BodyVel],
    ) -> BodyArrays {
        debug_assert!(vels.len() == dls.len() && vels.len() == warm.len());
        BodyArrays {
            vels: vels.as_mut_ptr(),
            dls: dls.as_mut_ptr(),
            warm: warm.as_mut_ptr(),
            q: std::ptr::null_mut(),
            q0: std::ptr::null_mut(),
            len: vels.len().min(dls.len()).min(warm.len()),
        }
    }

    /// Also shares the narrow rows' velocities in quanta (`q`, `q0`: one
    /// entry per solver body), taken from `vels` by the caller
    /// ([`super::narrow::quantize`]) and given back after the pass
    /// ([`super::narrow::flush`]).
    ///
    /// # Safety
    /// As [`BodyArrays::new`], for `q` and `q0` too.
    pub(super) unsafe fn with_quanta(self, q: &mut [Quanta], q0: &mut [Quanta]) -> BodyArrays {
        assert!(q.len() >= self.len && q0.len() >= self.len);
        BodyArrays {
            q: q.as_mut_ptr(),
            q0: q0.as_mut_ptr(),
            ..self
        }
    }

    /// Body `i`'s velocity in quanta (zero for `NONE`).
    #[inline(always)]
    pub(super) fn quanta(&self, i: u32) -> Quanta {
        if i == NONE {
            return Quanta::default();
        }
        assert!((i as usize) < self.len && !self.q.is_null());
        // SAFETY: in bounds; no other thread writes this entry now (`new`).
        unsafe { *self.q.add(i as usize) }
    }

    /// Writes dynamic body `i`'s velocity in quanta (`NONE`: not written).
    #[inline(always)]
    pub(super) fn set_quanta(&self, i: u32, q: Quanta) {
        if i != NONE {
            assert!((i as usize) < self.len && !self.q.is_null());
            // SAFETY: as in `store`.
            unsafe { *self.q.add(i as usize) = q };
        }
    }

    /// Before a Q32.32 visit in a narrow pass: dynamic body `i`'s Q32.32
    /// velocity takes the change its quanta made since they were taken
    /// (`NONE`: nothing; a kinematic body's quanta never change).
    #[inline(always)]
    pub(super) fn flush_one(&self, i: u32) {
        if i != NONE && !self.q.is_null() {
            assert!((i as usize) < self.len);
            // SAFETY: as in `store`.
            unsafe {
                let (v, q, q0) = (
                    &mut *self.vels.add(i as usize),
                    &*self.q.add(i as usize),
                    &mut *self.q0.add(i as usize),
                );
                flush_body(v, q, q0);
            }
        }
    }

    /// After a Q32.32 visit in a narrow pass: dynamic body `i`'s quanta
    /// taken again from its Q32.32 velocity.
    #[inline(always)]
    pub(super) fn requantize_one(&self, i: u32) {
        if i != NONE && !self.q.is_null() {
            assert!((i as usize) < self.len);
            // SAFETY: as in `store`.
            unsafe {
                let q = Quanta::of(&*self.vels.add(i as usize));
                *self.q.add(i as usize) = q;
                *self.q0.add(i as usize) = q;
            }
        }
    }

    #[inline(always)]
    fn vel(&self, i: u32) -> BodyVel {
        if i == NONE {
            return BodyVel::default();
        }
        assert!((i as usize) < self.len);
        // SAFETY: in bounds; no other thread writes this entry now (`new`).
        unsafe { *self.vels.add(i as usize) }
    }

    /// The velocities of bodies `a` and `b` (zero for `NONE`).
    #[inline(always)]
    pub(super) fn load(&self, a: u32, b: u32) -> (BodyVel, BodyVel) {
        (self.vel(a), self.vel(b))
    }

    /// Writes the velocities of the dynamic bodies `wa` and `wb` (`NONE`:
    /// not written).
    #[inline(always)]
    pub(super) fn store(&self, wa: u32, wb: u32, va: BodyVel, vb: BodyVel) {
        for (i, v) in [(wa, va), (wb, vb)] {
            if i != NONE {
                assert!((i as usize) < self.len);
                // SAFETY: in bounds; this thread alone touches the entry of
                // a dynamic body during its colour (`new`).
                unsafe { *self.vels.add(i as usize) = v };
            }
        }
    }

    /// Adds the changes `da`, `db` to the next warm start's sums of the
    /// dynamic bodies `wa` and `wb` (`NONE`: not written).
    #[inline(always)]
    pub(super) fn add_warm(&self, wa: u32, wb: u32, da: BodyVel, db: BodyVel) {
        for (i, d) in [(wa, da), (wb, db)] {
            if i != NONE {
                assert!((i as usize) < self.len);
                // SAFETY: as in `store`.
                let w = unsafe { &mut *self.warm.add(i as usize) };
                w.v += d.v;
                w.w += d.w;
            }
        }
    }

    /// Adds `d` to dynamic body `i`'s angular write-back sum.
    #[inline(always)]
    pub(super) fn add_dl(&self, i: u32, d: Vec3) {
        assert!((i as usize) < self.len);
        // SAFETY: as in `store`.
        unsafe { *self.dls.add(i as usize) += d };
    }
}
