//! The normal rows of eight constraints of one colour at once, on the
//! CPU's exact integer lanes (AVX-512 IFMA), with the bits of
//! [`Pass::points`](super::Pass::points) visiting them one at a time.
//!
//! The scalar rows compute each relative velocity and separation as a sum
//! of 64×64-bit products in 128 bits, rounded once, and each single product
//! rounded once (ties toward +∞, or away from zero for `Scalar`'s own
//! product). The lanes compute the same sums exactly:
//!
//! - An operand `x` with `−2⁵¹ ≤ x < 2⁵¹` is offset to `x + 2⁵¹`, which the
//!   52-bit multiplier (`vpmadd52luq`/`vpmadd52huq`) takes as it is; the
//!   offsets' cross terms, `2⁵¹(a + b) + 2¹⁰²` per product, are summed apart
//!   and taken off once per sum. A sum is kept as `h·2⁵² + l` in two 64-bit
//!   lanes (not normalised: both may be negative), and rounding it is
//!   `h·2²⁰ + ((l + 2³¹) >> 32)`, the scalar `(sum + 2³¹) >> 32` exactly.
//! - A range guard refuses the batch unless every lane was exact and
//!   nothing overflowed: every operand offset into `[0, 2⁵²)`, every rounded
//!   sum's `|h|` below 2⁴² (so its value fits 63 bits, where the scalar
//!   narrowing never faults), and no addition wrapped (where the scalar
//!   addition would saturate with the overflow fault). Nothing is written
//!   before the verdict; a refused batch goes to the scalar rows, and is
//!   counted ([`Counts::guarded`]).
//!
//! The rest of each constraint's visit (friction, the linear impulses, the
//! write-backs) stays on the scalar code, before and after the lanes. Only
//! x86_64 CPUs with AVX-512 F and IFMA, found at run time, take the lanes;
//! every other machine runs the scalar rows, to the same bits.

use super::constraint::Constraint;
use super::params::SolverParams;
use super::pass::Visit;
use std::sync::atomic::{AtomicU32, Ordering};

/// Constraints per batch.
pub(super) const LANES: usize = 8;

/// Whether this CPU has the lanes (AVX-512 F and IFMA).
#[inline]
pub(super) fn available() -> bool {
    crate::math::lanes::ifma_available()
}

/// Batches of one pass or step, by path.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Counts {
    /// Batches whose normal rows ran on the lanes.
    pub lanes: u32,
    /// Batches the range guard sent to the scalar rows.
    pub guarded: u32,
}

/// [`Counts`] summed over the workers of a step (each adds once per run of
/// constraints it visited; integer sums, so the totals do not depend on
/// the order).
#[derive(Debug, Default)]
pub(crate) struct Tally {
    lanes: AtomicU32,
    guarded: AtomicU32,
}

impl Clone for Tally {
    fn clone(&self) -> Tally {
        let c = self.peek();
        Tally {
            lanes: AtomicU32::new(c.lanes),
            guarded: AtomicU32::new(c.guarded),
        }
    }
}

impl Tally {
    /// Adds one run's counts.
    pub(super) fn add(&self, c: Counts) {
        if c.lanes != 0 {
            self.lanes.fetch_add(c.lanes, Ordering::Relaxed);
        }
        if c.guarded != 0 {
            self.guarded.fetch_add(c.guarded, Ordering::Relaxed);
        }
    }

    fn peek(&self) -> Counts {
        Counts {
            lanes: self.lanes.load(Ordering::Relaxed),
            guarded: self.guarded.load(Ordering::Relaxed),
        }
    }

    /// The counts so far, and zero again.
    pub(crate) fn take(&self) -> Counts {
        Counts {
            lanes: self.lanes.swap(0, Ordering::Relaxed),
            guarded: self.guarded.swap(0, Ordering::Relaxed),
        }
    }
}

/// The normal rows of the eight constraints of `batch` (one colour: no two
/// share a moving body), from and into their visits: `true` when the lanes
/// did them, `false` (nothing written) when the range guard refused the
/// batch or this CPU has no lanes.
pub(super) fn points(
    batch: &mut [Constraint; LANES],
    visits: &mut [Visit; LANES],
    params: &SolverParams,
    use_bias: bool,
) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        if !available() {
            return false;
        }
        let Some(mut stage) = ifma::Stage::new(batch, visits) else {
            return false;
        };
        let settings = ifma::Settings {
            inv_h: params.inv_h.to_bits(),
            floor: (-params.max_push_out).to_bits(),
            use_bias,
        };
        // SAFETY: the CPU has AVX-512 F and IFMA (checked above); `stage`
        // was built from `batch`, whose eight constraints are borrowed
        // mutably here.
        let done = unsafe { ifma::rows(batch, &mut stage, &settings) };
        if done {
            stage.finish(batch, visits);
        }
        done
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (batch, visits, params, use_bias);
        false
    }
}

#[cfg(target_arch = "x86_64")]
mod ifma {
    use super::super::constraint::{ConstraintPoint, NONE};
    use super::super::wide::LANES;
    use crate::collision::MAX_MANIFOLD_POINTS;
    use crate::math::Vec3;
    use crate::solver::contact_solver::constraint::Constraint;
    use crate::solver::contact_solver::pass::Visit;
    use core::arch::x86_64::*;
    use std::mem::{offset_of, size_of};

    /// The offset that makes an operand in `[−2⁵¹, 2⁵¹)` a 52-bit unsigned
    /// one.
    const OFFSET: i64 = 1 << 51;
    /// Every offset operand must stay below this.
    const OPERAND_END: i64 = 1 << 52;
    /// Every rounded sum's high limb must stay below this in magnitude: its
    /// value, `h·2²⁰ + (l + 2³¹)/2³²`, then fits 63 bits.
    const HIGH_END: i64 = 1 << 42;
    /// Q32.32 one.
    const ONE: i64 = 1 << 32;

    /// The pass settings the rows read.
    pub(super) struct Settings {
        pub inv_h: i64,
        /// `−max_push_out`: the most negative push-out bias.
        pub floor: i64,
        pub use_bias: bool,
    }

    type Lanes = [i64; LANES];

    /// The batch's per-constraint inputs, one lane each, laid out for
    /// aligned vector loads.
    #[repr(C, align(64))]
    pub(super) struct Stage {
        wa: [Lanes; 3],
        wb: [Lanes; 3],
        u0: Lanes,
        applied0: Lanes,
        /// `−ΔR_Aᵀ n` and `ΔR_Bᵀ n` of the separation frame.
        na_neg: [Lanes; 3],
        nb: [Lanes; 3],
        /// The frame's `n·(Δp_B − Δp_A)` as `h·2⁵² + l`.
        base_h: Lanes,
        base_l: Lanes,
        bias_rate: Lanes,
        mass_scale: Lanes,
        impulse_scale: Lanes,
        inv_mass_sum: Lanes,
        /// Per visit step `kk`, the byte offset from the batch's first
        /// constraint to each lane's point visited then.
        point: [Lanes; MAX_MANIFOLD_POINTS],
        /// Per visit step, the new normal impulse, largest normal impulse
        /// and restitution speed of each lane's point (`rows`' results).
        impulse: [Lanes; MAX_MANIFOLD_POINTS],
        max_impulse: [Lanes; MAX_MANIFOLD_POINTS],
        relative: [Lanes; MAX_MANIFOLD_POINTS],
        /// Per visit step, each lane's point's separation (what the scalar
        /// rows cache; the lanes always compute it, from the frame).
        separation: [Lanes; MAX_MANIFOLD_POINTS],
        /// Per visit step, the lanes that have a point then.
        active: [u8; MAX_MANIFOLD_POINTS],
        /// The lanes whose A (B) is a body.
        has_a: u8,
        has_b: u8,
    }

    impl Stage {
        /// The inputs of `batch` at the state of `visits`; `None` if a
        /// frame's displacement term is too large for the limbs.
        pub(super) fn new(batch: &[Constraint; LANES], visits: &[Visit; LANES]) -> Option<Stage> {
            let mut s = Stage {
                wa: [[0; LANES]; 3],
                wb: [[0; LANES]; 3],
                u0: [0; LANES],
                applied0: [0; LANES],
                na_neg: [[0; LANES]; 3],
                nb: [[0; LANES]; 3],
                base_h: [0; LANES],
                base_l: [0; LANES],
                bias_rate: [0; LANES],
                mass_scale: [0; LANES],
                impulse_scale: [0; LANES],
                inv_mass_sum: [0; LANES],
                point: [[0; LANES]; MAX_MANIFOLD_POINTS],
                impulse: [[0; LANES]; MAX_MANIFOLD_POINTS],
                max_impulse: [[0; LANES]; MAX_MANIFOLD_POINTS],
                relative: [[0; LANES]; MAX_MANIFOLD_POINTS],
                separation: [[0; LANES]; MAX_MANIFOLD_POINTS],
                active: [0; MAX_MANIFOLD_POINTS],
                has_a: 0,
                has_b: 0,
            };
            for (i, (c, v)) in batch.iter().zip(visits).enumerate() {
                for j in 0..3 {
                    s.wa[j][i] = v.va.w.get(j).to_bits();
                    s.wb[j][i] = v.vb.w.get(j).to_bits();
                    // A component of a rotated unit normal is at most 1 in
                    // size; were it i64::MIN, its wrapped negation would
                    // fail the operand guard.
                    s.na_neg[j][i] = v.frame.na.get(j).to_bits().wrapping_neg();
                    s.nb[j][i] = v.frame.nb.get(j).to_bits();
                }
                s.u0[i] = v.u[0].to_bits();
                s.applied0[i] = v.applied[0].to_bits();
                let h = v.frame.base >> 52;
                s.base_h[i] = i64::try_from(h).ok()?;
                s.base_l[i] = (v.frame.base & ((1 << 52) - 1)) as i64;
                s.bias_rate[i] = c.softness.bias_rate.to_bits();
                s.mass_scale[i] = c.softness.mass_scale.to_bits();
                s.impulse_scale[i] = c.softness.impulse_scale.to_bits();
                s.inv_mass_sum[i] = c.inv_mass_sum.to_bits();
                if c.a != NONE {
                    s.has_a |= 1 << i;
                }
                if c.b != NONE {
                    s.has_b |= 1 << i;
                }
                let count = c.count.min(MAX_MANIFOLD_POINTS);
                for kk in 0..count {
                    let k = v.point(kk, count);
                    s.active[kk] |= 1 << i;
                    s.point[kk][i] = (i * size_of::<Constraint>()
                        + offset_of!(Constraint, points)
                        + k * size_of::<ConstraintPoint>())
                        as i64;
                }
            }
            Some(s)
        }

        /// Writes the lanes' results into the points of `batch` and into
        /// `visits`.
        pub(super) fn finish(&self, batch: &mut [Constraint; LANES], visits: &mut [Visit; LANES]) {
            use crate::math::Scalar;
            for (i, (c, v)) in batch.iter_mut().zip(visits.iter()).enumerate() {
                let count = c.count.min(MAX_MANIFOLD_POINTS);
                for kk in 0..count {
                    let cp = &mut c.points[v.point(kk, count)];
                    cp.normal_impulse = Scalar::from_bits(self.impulse[kk][i]);
                    cp.max_normal_impulse = Scalar::from_bits(self.max_impulse[kk][i]);
                    cp.relative_velocity = Scalar::from_bits(self.relative[kk][i]);
                    cp.separation = Scalar::from_bits(self.separation[kk][i]);
                }
            }
            for (i, v) in visits.iter_mut().enumerate() {
                for j in 0..3 {
                    v.va.w.set(j, crate::math::Scalar::from_bits(self.wa[j][i]));
                    v.vb.w.set(j, crate::math::Scalar::from_bits(self.wb[j][i]));
                }
                v.u[0] = crate::math::Scalar::from_bits(self.u0[i]);
                v.applied[0] = crate::math::Scalar::from_bits(self.applied0[i]);
            }
        }
    }

    /// What the range guard has seen so far in a batch.
    struct Guard {
        /// The OR of every offset operand (all below 2⁵² exactly when this
        /// is).
        operands: __m512i,
        /// The OR of every rounded sum's `|h|`.
        highs: __m512i,
        /// Sign bit set where an addition or subtraction wrapped.
        wrapped: __m512i,
    }

    /// A sum of products, `h·2⁵² + l` plus the offsets' cross terms still
    /// to take off: `2⁵¹·s + n·2¹⁰²`.
    struct Sum {
        h: __m512i,
        l: __m512i,
        s: __m512i,
        n: i64,
    }

    #[inline]
    #[target_feature(enable = "avx512f,avx512ifma")]
    fn load(a: &Lanes) -> __m512i {
        // SAFETY: 64 readable bytes, 64-byte aligned (`Stage` is aligned
        // and each of its lane arrays is 64 bytes long).
        unsafe { _mm512_load_si512(a.as_ptr().cast()) }
    }

    #[inline]
    #[target_feature(enable = "avx512f,avx512ifma")]
    fn store(a: &mut Lanes, v: __m512i) {
        // SAFETY: as in `load`, writable.
        unsafe { _mm512_store_si512(a.as_mut_ptr().cast(), v) }
    }

    impl Guard {
        #[inline]
        #[target_feature(enable = "avx512f,avx512ifma")]
        fn new() -> Guard {
            Guard {
                operands: _mm512_setzero_si512(),
                highs: _mm512_setzero_si512(),
                wrapped: _mm512_setzero_si512(),
            }
        }

        /// Whether every lane of the batch was exact.
        #[inline]
        #[target_feature(enable = "avx512f,avx512ifma")]
        fn passed(&self) -> bool {
            let operands = _mm512_cmplt_epu64_mask(self.operands, _mm512_set1_epi64(OPERAND_END));
            let highs = _mm512_cmplt_epu64_mask(self.highs, _mm512_set1_epi64(HIGH_END));
            let wrapped = _mm512_cmplt_epi64_mask(self.wrapped, _mm512_setzero_si512());
            operands == 0xff && highs == 0xff && wrapped == 0
        }

        /// `x + y`, wrapping (the guard notes it).
        #[inline]
        #[target_feature(enable = "avx512f,avx512ifma")]
        fn add(&mut self, x: __m512i, y: __m512i) -> __m512i {
            let r = _mm512_add_epi64(x, y);
            // Wrapped where x and y share a sign that r does not:
            // (x ^ r) & (y ^ r) has the sign bit set.
            let w = _mm512_ternarylogic_epi64::<0x42>(x, y, r);
            self.wrapped = _mm512_or_si512(self.wrapped, w);
            r
        }

        /// `x − y`, wrapping (the guard notes it).
        #[inline]
        #[target_feature(enable = "avx512f,avx512ifma")]
        fn sub(&mut self, x: __m512i, y: __m512i) -> __m512i {
            let r = _mm512_sub_epi64(x, y);
            // Wrapped where x and y differ in sign and r's differs from
            // x's: (x ^ y) & (x ^ r).
            let w = _mm512_ternarylogic_epi64::<0x18>(x, y, r);
            self.wrapped = _mm512_or_si512(self.wrapped, w);
            r
        }

        /// Adds `a·b` to `sum`.
        #[inline]
        #[target_feature(enable = "avx512f,avx512ifma")]
        fn prod(&mut self, sum: &mut Sum, a: __m512i, b: __m512i) {
            let off = _mm512_set1_epi64(OFFSET);
            let (x, y) = (_mm512_add_epi64(a, off), _mm512_add_epi64(b, off));
            self.operands = _mm512_ternarylogic_epi64::<0xFE>(self.operands, x, y);
            sum.l = _mm512_madd52lo_epu64(sum.l, x, y);
            sum.h = _mm512_madd52hi_epu64(sum.h, x, y);
            sum.s = _mm512_add_epi64(sum.s, _mm512_add_epi64(a, b));
            sum.n += 1;
        }

        /// Adds `−a·b` to `sum`.
        #[inline]
        #[target_feature(enable = "avx512f,avx512ifma")]
        fn neg_prod(&mut self, sum: &mut Sum, a: __m512i, b: __m512i) {
            let off = _mm512_set1_epi64(OFFSET);
            // −a + 2⁵¹, and the cross term's −a.
            let (x, y) = (_mm512_sub_epi64(off, a), _mm512_add_epi64(b, off));
            self.operands = _mm512_ternarylogic_epi64::<0xFE>(self.operands, x, y);
            sum.l = _mm512_madd52lo_epu64(sum.l, x, y);
            sum.h = _mm512_madd52hi_epu64(sum.h, x, y);
            sum.s = _mm512_add_epi64(sum.s, _mm512_sub_epi64(b, a));
            sum.n += 1;
        }

        /// The exact sum as `(h, l)`, cross terms taken off.
        #[inline]
        #[target_feature(enable = "avx512f,avx512ifma")]
        fn limbs(&mut self, sum: &Sum) -> (__m512i, __m512i) {
            // 2⁵¹·s = (s >> 1)·2⁵² + (s & 1)·2⁵¹, and n·2¹⁰² = n·2⁵⁰·2⁵².
            let h = _mm512_sub_epi64(
                sum.h,
                _mm512_add_epi64(
                    _mm512_srai_epi64::<1>(sum.s),
                    _mm512_set1_epi64(sum.n << 50),
                ),
            );
            let odd = _mm512_and_si512(sum.s, _mm512_set1_epi64(1));
            let l = _mm512_sub_epi64(sum.l, _mm512_slli_epi64::<51>(odd));
            self.highs = _mm512_or_si512(self.highs, _mm512_abs_epi64(h));
            (h, l)
        }

        /// The sum rounded to nearest, ties toward +∞ (the scalar
        /// `round_wide`).
        #[inline]
        #[target_feature(enable = "avx512f,avx512ifma")]
        fn round_up(&mut self, sum: &Sum) -> __m512i {
            let (h, l) = self.limbs(sum);
            let l = _mm512_add_epi64(l, _mm512_set1_epi64(1 << 31));
            _mm512_add_epi64(_mm512_slli_epi64::<20>(h), _mm512_srai_epi64::<32>(l))
        }

        /// `a·b` rounded to nearest, ties toward +∞ (the solver's `mul`).
        #[inline]
        #[target_feature(enable = "avx512f,avx512ifma")]
        fn mul_up(&mut self, a: __m512i, b: __m512i) -> __m512i {
            let mut sum = Sum::zero();
            self.prod(&mut sum, a, b);
            self.round_up(&sum)
        }

        /// `a·b` rounded to nearest, ties away from zero (`Scalar`'s `*`).
        #[inline]
        #[target_feature(enable = "avx512f,avx512ifma")]
        fn mul_away(&mut self, a: __m512i, b: __m512i) -> __m512i {
            let mut sum = Sum::zero();
            self.prod(&mut sum, a, b);
            let (h, l) = self.limbs(&sum);
            // A negative product rounds `(P + 2³¹ − 1) >> 32`.
            let zero = _mm512_setzero_si512();
            let negative = _mm512_cmplt_epi64_mask(_mm512_xor_si512(a, b), zero)
                & _mm512_test_epi64_mask(a, a)
                & _mm512_test_epi64_mask(b, b);
            let l = _mm512_mask_sub_epi64(l, negative, l, _mm512_set1_epi64(1));
            let l = _mm512_add_epi64(l, _mm512_set1_epi64(1 << 31));
            _mm512_add_epi64(_mm512_slli_epi64::<20>(h), _mm512_srai_epi64::<32>(l))
        }
    }

    impl Sum {
        #[inline]
        #[target_feature(enable = "avx512f,avx512ifma")]
        fn zero() -> Sum {
            Sum::from_limbs(_mm512_setzero_si512(), _mm512_setzero_si512())
        }

        #[inline]
        #[target_feature(enable = "avx512f,avx512ifma")]
        fn from_limbs(h: __m512i, l: __m512i) -> Sum {
            Sum {
                h,
                l,
                s: _mm512_setzero_si512(),
                n: 0,
            }
        }
    }

    /// Byte offsets in a [`ConstraintPoint`] of the fields the rows read.
    const fn vec_at(field: usize) -> [usize; 3] {
        [
            field + offset_of!(Vec3, x),
            field + offset_of!(Vec3, y),
            field + offset_of!(Vec3, z),
        ]
    }
    const RA: [usize; 3] = vec_at(offset_of!(ConstraintPoint, ra));
    const RB: [usize; 3] = vec_at(offset_of!(ConstraintPoint, rb));
    const RA_N: [usize; 3] = vec_at(offset_of!(ConstraintPoint, ra_n));
    const RB_N: [usize; 3] = vec_at(offset_of!(ConstraintPoint, rb_n));
    const IA_N: [usize; 3] = vec_at(offset_of!(ConstraintPoint, ia_n));
    const IB_N: [usize; 3] = vec_at(offset_of!(ConstraintPoint, ib_n));
    const ADJUSTED: usize = offset_of!(ConstraintPoint, adjusted_separation);
    const RELATIVE: usize = offset_of!(ConstraintPoint, relative_velocity);
    const MASS: usize = offset_of!(ConstraintPoint, normal_mass);
    const IMPULSE: usize = offset_of!(ConstraintPoint, normal_impulse);
    const MAX_IMPULSE: usize = offset_of!(ConstraintPoint, max_normal_impulse);

    /// The normal rows of the batch on the lanes (see the module): `true`
    /// with the results in `stage` (for [`Stage::finish`]), or `false`.
    ///
    /// # Safety
    /// The CPU has AVX-512 F and IFMA, and `stage` was built from `batch`.
    #[target_feature(enable = "avx512f,avx512ifma")]
    pub(super) unsafe fn rows(
        batch: &mut [Constraint; LANES],
        stage: &mut Stage,
        set: &Settings,
    ) -> bool {
        let base = batch.as_mut_ptr().cast::<u8>();
        let zero = _mm512_setzero_si512();
        let one = _mm512_set1_epi64(ONE);
        let mut g = Guard::new();
        let mut wa = [load(&stage.wa[0]), load(&stage.wa[1]), load(&stage.wa[2])];
        let mut wb = [load(&stage.wb[0]), load(&stage.wb[1]), load(&stage.wb[2])];
        let mut u0 = load(&stage.u0);
        let mut applied0 = load(&stage.applied0);
        let na_neg = [
            load(&stage.na_neg[0]),
            load(&stage.na_neg[1]),
            load(&stage.na_neg[2]),
        ];
        let nb = [load(&stage.nb[0]), load(&stage.nb[1]), load(&stage.nb[2])];
        let (base_h, base_l) = (load(&stage.base_h), load(&stage.base_l));
        let inv_mass_sum = load(&stage.inv_mass_sum);
        // Below the surface, with push-out: the spring; without: rigid.
        let (rate, mass_scale, impulse_scale) = if set.use_bias {
            (
                load(&stage.bias_rate),
                load(&stage.mass_scale),
                load(&stage.impulse_scale),
            )
        } else {
            (zero, one, zero)
        };
        let inv_h = _mm512_set1_epi64(set.inv_h);
        let floor = _mm512_set1_epi64(set.floor);
        for kk in 0..MAX_MANIFOLD_POINTS {
            let active = stage.active[kk];
            if active == 0 {
                break;
            }
            let idx = load(&stage.point[kk]);
            // SAFETY: each active lane's offset is a field of a point of a
            // constraint of `batch` (`Stage::new`); inactive lanes read
            // nothing.
            let get = |field: usize| unsafe {
                _mm512_mask_i64gather_epi64::<1>(zero, active, idx, base.add(field).cast())
            };
            let get3 = |f: [usize; 3]| [get(f[0]), get(f[1]), get(f[2])];
            let (ra, rb) = (get3(RA), get3(RB));
            let (ra_n, rb_n) = (get3(RA_N), get3(RB_N));
            let (ia_n, ib_n) = (get3(IA_N), get3(IB_N));
            let (adjusted, relative) = (get(ADJUSTED), get(RELATIVE));
            let (mass, impulse, max_impulse) = (get(MASS), get(IMPULSE), get(MAX_IMPULSE));

            // The current separation: base + nb·rb − na·ra, rounded once,
            // plus the adjusted separation.
            let mut sum = Sum::from_limbs(base_h, base_l);
            for j in 0..3 {
                g.prod(&mut sum, nb[j], rb[j]);
            }
            for j in 0..3 {
                g.prod(&mut sum, na_neg[j], ra[j]);
            }
            let s = g.round_up(&sum);
            let s = g.add(s, adjusted);
            store(&mut stage.separation[kk], s);
            let above = _mm512_cmpgt_epi64_mask(s, zero);
            // A gap: s/h, rigid. Overlap: the spring's (or nothing).
            let factor = _mm512_mask_blend_epi64(above, rate, inv_h);
            let product = g.mul_away(s, factor);
            let below = if set.use_bias {
                _mm512_max_epi64(product, floor)
            } else {
                zero
            };
            let bias = _mm512_mask_blend_epi64(above, below, product);
            let ms = _mm512_mask_blend_epi64(above, mass_scale, one);
            let is = _mm512_mask_blend_epi64(above, impulse_scale, zero);

            // vn = u0 + rb_n·ωB − ra_n·ωA, the angular part rounded once.
            let mut sum = Sum::zero();
            for j in 0..3 {
                g.prod(&mut sum, rb_n[j], wb[j]);
            }
            for j in 0..3 {
                g.neg_prod(&mut sum, ra_n[j], wa[j]);
            }
            let angular = g.round_up(&sum);
            let vn = g.add(u0, angular);
            let scaled_mass = g.mul_up(mass, ms);
            let push = g.add(vn, bias);
            let t2 = g.mul_up(scaled_mass, push);
            let t3 = g.mul_up(is, impulse);
            let neg_t2 = g.sub(zero, t2);
            let lambda = g.sub(neg_t2, t3);
            let new = _mm512_max_epi64(g.add(impulse, lambda), zero);
            let d = g.sub(new, impulse);
            let first = active
                & _mm512_cmpeq_epi64_mask(max_impulse, zero)
                & _mm512_cmpgt_epi64_mask(new, zero);
            let relative = _mm512_mask_min_epi64(relative, first, relative, vn);
            let max_impulse = _mm512_max_epi64(max_impulse, new);
            // The points' new values go back through the stage, written
            // by `Stage::finish` with plain stores: the constraint's tail
            // reads them at once, and a load cannot take its value from a
            // scatter's pending store (it waits for the scatter to reach
            // the cache).
            store(&mut stage.impulse[kk], new);
            store(&mut stage.max_impulse[kk], max_impulse);
            store(&mut stage.relative[kk], relative);
            // With d = 0 every change below is an exact zero, as the scalar
            // rows' skip.
            let du = g.mul_up(inv_mass_sum, d);
            u0 = _mm512_mask_mov_epi64(u0, active, g.add(u0, du));
            applied0 = _mm512_mask_mov_epi64(applied0, active, g.add(applied0, d));
            let (on_a, on_b) = (active & stage.has_a, active & stage.has_b);
            for j in 0..3 {
                let da = g.mul_up(ia_n[j], d);
                wa[j] = _mm512_mask_mov_epi64(wa[j], on_a, g.sub(wa[j], da));
                let db = g.mul_up(ib_n[j], d);
                wb[j] = _mm512_mask_mov_epi64(wb[j], on_b, g.add(wb[j], db));
            }
        }
        if !g.passed() {
            return false;
        }
        for j in 0..3 {
            store(&mut stage.wa[j], wa[j]);
            store(&mut stage.wb[j], wb[j]);
        }
        store(&mut stage.u0, u0);
        store(&mut stage.applied0, applied0);
        true
    }

    /// The lane operations against the scalar ones they stand for, one lane
    /// at a time, on random, tie, extreme and guard-boundary inputs: where
    /// the guard passes a batch, every lane has the scalar bits (and the
    /// scalar raised no fault); the guard refuses what it must.
    #[cfg(test)]
    mod tests {
        use super::*;
        use crate::math::lanes::mul_round_up;
        use crate::math::{FaultScope, Scalar};
        use crate::solver::contact_solver::rows::round_wide;

        fn vec(a: &Lanes) -> __m512i {
            // SAFETY: 64 readable bytes; an unaligned load (the tests need
            // the CPU's lanes, checked by `lanes_here`).
            unsafe { _mm512_loadu_si512(a.as_ptr().cast()) }
        }

        fn arr(v: __m512i) -> Lanes {
            let mut out = [0; LANES];
            // SAFETY: 64 writable bytes; unaligned.
            unsafe { _mm512_storeu_si512(out.as_mut_ptr().cast(), v) };
            out
        }

        fn lanes_here() -> bool {
            let here = super::super::available();
            if !here {
                eprintln!("no AVX-512 IFMA on this CPU: the lane tests check nothing here");
            }
            here
        }

        /// `a·b` both ways; the guard's verdict.
        fn mul(a: Lanes, b: Lanes, away: bool) -> (Lanes, bool) {
            // SAFETY: the callers checked `lanes_here`.
            unsafe {
                let mut g = Guard::new();
                let r = if away {
                    g.mul_away(vec(&a), vec(&b))
                } else {
                    g.mul_up(vec(&a), vec(&b))
                };
                (arr(r), g.passed())
            }
        }

        /// `base + a·b − c·d + e·f`, rounded once, and the guard's verdict.
        fn dot(base: [i128; LANES], t: [Lanes; 6]) -> (Lanes, bool) {
            // SAFETY: as in `mul`.
            unsafe {
                let mut g = Guard::new();
                let h = base.map(|x| (x >> 52) as i64);
                let l = base.map(|x| (x & ((1 << 52) - 1)) as i64);
                let mut sum = Sum::from_limbs(vec(&h), vec(&l));
                g.prod(&mut sum, vec(&t[0]), vec(&t[1]));
                g.neg_prod(&mut sum, vec(&t[2]), vec(&t[3]));
                g.prod(&mut sum, vec(&t[4]), vec(&t[5]));
                (arr(g.round_up(&sum)), g.passed())
            }
        }

        fn scalar_mul(a: i64, b: i64, away: bool) -> i64 {
            let (a, b) = (Scalar::from_bits(a), Scalar::from_bits(b));
            if away { a * b } else { mul_round_up(a, b) }.to_bits()
        }

        fn scalar_dot(base: i128, t: [i64; 6]) -> i64 {
            let p = |x: i64, y: i64| x as i128 * y as i128;
            let sum =
                crate::math::scalar::wide_sum([base, p(t[0], t[1]), -p(t[2], t[3]), p(t[4], t[5])]);
            round_wide(sum).to_bits()
        }

        /// Checks one batch of products: where the guard passed, each lane
        /// equals the scalar product and the scalar raised no fault.
        /// Returns the verdict.
        fn check_mul(a: Lanes, b: Lanes, away: bool) -> bool {
            let (got, passed) = mul(a, b, away);
            if passed {
                for i in 0..LANES {
                    let (want, faults) = FaultScope::run(|| scalar_mul(a[i], b[i], away));
                    assert!(
                        faults.is_empty(),
                        "passed a faulting lane: {} · {}",
                        a[i],
                        b[i]
                    );
                    assert_eq!(got[i], want, "{} · {} (away {away})", a[i], b[i]);
                }
            }
            passed
        }

        /// Draws from the workspace's test generator.
        struct Draw(crate::testing::Rng);

        impl Draw {
            fn next(&mut self) -> u64 {
                self.0.next_u64()
            }

            /// A signed value of 0 to `max_bits` bits.
            fn value(&mut self, max_bits: u64) -> i64 {
                let bits = self.next() % (max_bits + 1);
                let m = if bits == 0 {
                    0
                } else {
                    (self.next() >> (64 - bits)) as i64
                };
                if self.next() & 1 == 0 { m } else { -m }
            }

            fn lanes(&mut self, max_bits: u64) -> Lanes {
                std::array::from_fn(|_| self.value(max_bits))
            }
        }

        #[test]
        fn products_match_the_scalar_ones_on_random_inputs() {
            if !lanes_here() {
                return;
            }
            let mut d = Draw(crate::testing::Rng::new(0x5EED));
            let (mut passed, mut refused) = (0, 0);
            for round in 0..40_000 {
                let away = round % 2 == 0;
                let (a, b) = (d.lanes(53), d.lanes(53));
                if check_mul(a, b, away) {
                    passed += 1;
                } else {
                    refused += 1;
                }
                // Operands the lanes take (|x| < 2⁵¹) always pass unless
                // the product's value is past 2⁶².
                let (a, b) = (d.lanes(50), d.lanes(40));
                assert!(check_mul(a, b, away), "{a:?} {b:?}");
            }
            assert!(passed > 1000 && refused > 1000, "{passed} {refused}");
        }

        #[test]
        fn products_round_ties_as_the_scalar_ones() {
            if !lanes_here() {
                return;
            }
            let t = 1i64 << 31;
            // a·b = (2k + 1)·2³¹: exactly half a unit above a whole one.
            let a = [t, -t, 3 * t, -3 * t, 3 << 20, -(3 << 20), 5 << 12, t - 1];
            let b = [1, 1, 1, 1, 1 << 11, 1 << 11, -(3 << 19), 1];
            for away in [false, true] {
                assert!(check_mul(a, b, away));
            }
            let (up, _) = mul(a, b, false);
            let (away, _) = mul(a, b, true);
            assert_eq!(up[..4], [1, 0, 2, -1]);
            assert_eq!(away[..4], [1, -1, 2, -2]);
        }

        #[test]
        fn the_guard_refuses_operands_outside_the_offset_range() {
            if !lanes_here() {
                return;
            }
            let ones = [1i64 << 32; LANES];
            let edge = 1i64 << 51;
            // −2⁵¹ and 2⁵¹ − 1 offset to 0 and 2⁵² − 1: taken.
            assert!(check_mul([-edge, edge - 1, 0, 0, 0, 0, 0, 0], ones, false));
            // 2⁵¹ and −2⁵¹ − 1 do not fit; nor does either extreme.
            for bad in [edge, -edge - 1, i64::MAX, i64::MIN] {
                let mut a = [0; LANES];
                a[5] = bad;
                assert!(!check_mul(a, ones, false), "{bad}");
                assert!(!check_mul(ones, a, true), "{bad}");
            }
            // A product whose rounded value reaches 2⁶²: refused.
            let big = (1i64 << 51) - 1;
            let mut a = [0; LANES];
            a[0] = big;
            let mut b = [0; LANES];
            b[0] = 1 << 44;
            assert!(!check_mul(a, b, false));
            b[0] = 1 << 42;
            assert!(check_mul(a, b, false));
        }

        #[test]
        fn sums_of_products_round_once_as_the_scalar_rows() {
            if !lanes_here() {
                return;
            }
            let mut d = Draw(crate::testing::Rng::new(0xD07));
            let (mut passed, mut refused) = (0, 0);
            for round in 0..20_000 {
                let bits = if round % 4 == 0 { 53 } else { 48 };
                let t: [Lanes; 6] = std::array::from_fn(|_| d.lanes(bits));
                let base: [i128; LANES] =
                    std::array::from_fn(|_| (d.value(62) as i128) << (d.next() % 40));
                let (got, ok) = dot(base, t);
                if !ok {
                    refused += 1;
                    continue;
                }
                passed += 1;
                for i in 0..LANES {
                    let ti = t.map(|x| x[i]);
                    let (want, faults) = FaultScope::run(|| scalar_dot(base[i], ti));
                    assert!(faults.is_empty(), "passed a faulting lane {ti:?}");
                    assert_eq!(got[i], want, "base {} terms {ti:?}", base[i]);
                }
            }
            assert!(passed > 1000 && refused > 100, "{passed} {refused}");
        }

        #[test]
        fn wrapped_sums_and_differences_are_refused() {
            if !lanes_here() {
                return;
            }
            let check = |x: Lanes, y: Lanes| {
                // SAFETY: `lanes_here` was checked.
                unsafe {
                    let mut g = Guard::new();
                    let s = arr(g.add(vec(&x), vec(&y)));
                    let add_ok = g.passed();
                    let mut g = Guard::new();
                    let d = arr(g.sub(vec(&x), vec(&y)));
                    let sub_ok = g.passed();
                    for i in 0..LANES {
                        assert_eq!(s[i], x[i].wrapping_add(y[i]));
                        assert_eq!(d[i], x[i].wrapping_sub(y[i]));
                    }
                    let add_fits = (0..LANES).all(|i| x[i].checked_add(y[i]).is_some());
                    let sub_fits = (0..LANES).all(|i| x[i].checked_sub(y[i]).is_some());
                    assert_eq!(add_ok, add_fits, "{x:?} + {y:?}");
                    assert_eq!(sub_ok, sub_fits, "{x:?} − {y:?}");
                }
            };
            check(
                [i64::MAX, 1, -5, 0, 0, 0, 0, 0],
                [0, i64::MAX - 1, 5, 0, 0, 0, 0, 0],
            );
            check([i64::MAX, 0, 0, 0, 0, 0, 0, 0], [1, 0, 0, 0, 0, 0, 0, 0]);
            check([i64::MIN, 0, 0, 0, 0, 0, 0, 0], [1, 0, 0, 0, 0, 0, 0, 0]);
            check([0, 0, 0, i64::MIN, 0, 0, 0, 0], [0, 0, 0, -1, 0, 0, 0, 0]);
            check([-2, 0, 0, 0, 0, 0, 0, 0], [i64::MAX, 0, 0, 0, 0, 0, 0, 0]);
            let mut d = Draw(crate::testing::Rng::new(0xADD));
            for _ in 0..5_000 {
                check(d.lanes(63), d.lanes(63));
            }
        }
    }
}
