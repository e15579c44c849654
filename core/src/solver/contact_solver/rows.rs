//! The solver's row arithmetic: relative velocities along a direction,
//! impulse application, and the products and roundings the passes use
//! (ties toward +∞, see [`mul`]; the ones on plain numbers and vectors are
//! in `arith`, re-exported here). Kept apart from the passes so the passes
//! read as the algorithm.

use super::constraint::{BodyVel, Constraint, NONE, SolverBody};
use super::quanta::{Quanta, flush_body};
use crate::math::scalar::wide_sum;
use crate::math::{Scalar, Vec3};

pub(super) use super::arith::{
    combine3, cross, inverse_or_zero, mul, prefetch, round_wide, scale, tangent_of,
};

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

impl Constraint {
    /// Adds the angular impulse of every impulse change since its mark
    /// (`r×n Δλ_n` per point; `ra×t_j Δλ_tj` and `n Δλ_twist` for the
    /// patch, all from stored products) to the write-back sums `dls` of A
    /// (negated) and B, and moves the marks.
    #[inline(always)]
    pub(super) fn collect_angular(&mut self, arrays: &BodyArrays) {
        let (a, b) = (self.wa, self.wb);
        for cp in &mut self.points[..self.count] {
            let dn = cp.normal_impulse - cp.mark;
            if dn.is_zero() {
                continue;
            }
            cp.mark = cp.normal_impulse;
            if a != NONE {
                arrays.add_dl(a, -scale(cp.ra_n, dn));
            }
            if b != NONE {
                arrays.add_dl(b, scale(cp.rb_n, dn));
            }
        }
        let f = &mut self.patch;
        let now = [f.tangent_impulse[0], f.tangent_impulse[1], f.twist_impulse];
        if now == f.mark {
            return;
        }
        let [d0, d1, dw] = [now[0] - f.mark[0], now[1] - f.mark[1], now[2] - f.mark[2]];
        f.mark = now;
        let n = self.normal;
        if a != NONE {
            arrays.add_dl(a, -combine3(f.ra_t[0], d0, f.ra_t[1], d1, n, dw));
        }
        if b != NONE {
            arrays.add_dl(b, combine3(f.rb_t[0], d0, f.rb_t[1], d1, n, dw));
        }
    }

    /// Applies the accumulated impulses to the velocities `va`, `vb` of A
    /// and B (the warm start), records their total normal impulse and
    /// clears the marks (the angular write-back takes them all again).
    ///
    /// Every change is a rounded product of the impulses and this
    /// constraint's constant terms, added to the velocity: none depends on
    /// the velocities, so the changes may be summed apart (from zero) and
    /// added later, to the same bits.
    #[inline(always)]
    pub(super) fn warm_start(&mut self, va: &mut BodyVel, vb: &mut BodyVel) {
        let (a, b) = (self.a, self.b);
        // The linear change is the same direction for every point: sum the
        // impulses (exactly) and scale once per constraint.
        let mut total = Scalar::ZERO;
        for cp in &mut self.points[..self.count] {
            cp.mark = Scalar::ZERO;
            let ni = cp.normal_impulse;
            if ni.is_zero() {
                continue;
            }
            total += ni;
            push_angular(va, vb, a, b, ni, cp.ia_n, cp.ib_n);
        }
        self.warm_total = total;
        let f = &mut self.patch;
        f.mark = [Scalar::ZERO; 3];
        let [i0, i1] = f.tangent_impulse;
        let iw = f.twist_impulse;
        if !(i0.is_zero() && i1.is_zero() && iw.is_zero()) {
            if a != NONE {
                va.w -= combine3(f.ia_t[0], i0, f.ia_t[1], i1, f.ia_w, iw);
            }
            if b != NONE {
                vb.w += combine3(f.ib_t[0], i0, f.ib_t[1], i1, f.ib_w, iw);
            }
        }
        apply_linear(self, va, vb, [total, i0, i1]);
    }
}
