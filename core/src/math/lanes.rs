//! Eight Q32.32 products at once, with exactly the bits of one at a time.
//!
//! The contact solver rounds a product to nearest with ties toward +∞
//! (`mul_round_up`): `(a·b + 2³¹) >> 32` on the 128-bit product, narrowed
//! to 64 bits with the overflow fault. [`mul_slice`] computes a slice of
//! them, eight at a time.
//!
//! - On an x86_64 CPU with AVX-512 IFMA (`vpmadd52luq`/`vpmadd52huq`: exact
//!   52×52-bit products in eight 64-bit lanes), found at run time, the
//!   lanes multiply the magnitudes, add the rounding half (one less for a
//!   negative product, which is how a tie goes up on both sides of zero),
//!   shift, and put the sign back. No rounding step differs from the scalar
//!   one, so every lane has the scalar product's bits.
//! - A range guard sends the whole batch to the scalar twin when a lane
//!   would not be exact: an operand of 2⁵² or more in magnitude, or a
//!   product whose rounded value may not fit 64 bits (the high 52-bit half
//!   at 2⁴³ or more). The scalar twin also raises the overflow fault where
//!   the product overflows; the lanes never see such a product.
//! - Everywhere else (i686, aarch64, x86_64 without IFMA, or with the lanes
//!   turned off) the scalar twin runs: `mul_round_up` eight times.
//!
//! It counts the batches each path computed ([`LaneCounts`]), so a caller
//! can report those the guard sent to the scalar twin.
//!
//! Not yet on the simulation path: the solver's wide kernels that will use
//! it need the constraints grouped into batches that share no body. Tests
//! compare the lanes with the scalar twin on random, tie, extreme and
//! guard-boundary inputs; the `math` benchmark measures both.

use super::scalar::{self, Scalar};

/// Lanes per batch (read only where the lanes exist: x86_64 and the
/// tests).
#[cfg_attr(not(any(target_arch = "x86_64", test)), allow(dead_code))]
pub(crate) const LANES: usize = 8;

/// `a·b` rounded to nearest with ties toward +∞ and saturated with the
/// overflow fault: the contact solver's product, and the scalar twin of
/// one lane of [`mul_slice`].
#[inline(always)]
pub(crate) fn mul_round_up(a: Scalar, b: Scalar) -> Scalar {
    narrow((a.to_bits() as i128 * b.to_bits() as i128 + (1i128 << 31)) >> 32)
}

/// An already rounded Q32.32 value in an `i128`, saturated with the
/// overflow fault when it does not fit ([`scalar::narrow`]'s check; the
/// solver's roundings end here).
#[inline(always)]
pub(crate) fn narrow(r: i128) -> Scalar {
    Scalar::from_bits(scalar::narrow(r))
}

/// Whether this CPU has the IFMA lanes (AVX-512 F and IFMA), found once.
pub fn ifma_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512ifma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Batches of a slice computed on each path (see [`mul_slice`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LaneCounts {
    /// Batches of eight on the IFMA lanes.
    pub ifma: u32,
    /// Batches of eight the range guard sent to the scalar twin.
    pub guarded: u32,
    /// Products computed by the scalar twin for another reason: no IFMA,
    /// the lanes turned off, or the tail after the last whole batch.
    pub scalar: u32,
}

/// `out[i] = a[i]·b[i]` over three slices of one length, each with the bits
/// of `mul_round_up`: whole batches of eight on the IFMA lanes when
/// `lanes` is set and the CPU has them (a batch the guard refuses goes to
/// the scalar twin), the rest on the twin. Counts the batches per path.
///
/// # Panics
/// If the slices differ in length.
pub fn mul_slice(a: &[Scalar], b: &[Scalar], out: &mut [Scalar], lanes: bool) -> LaneCounts {
    assert!(
        a.len() == b.len() && b.len() == out.len(),
        "slices of one length"
    );
    let (done, mut counts) = if lanes && ifma_available() {
        whole_batches_on_lanes(a, b, out)
    } else {
        (0, LaneCounts::default())
    };
    for i in done..a.len() {
        out[i] = mul_round_up(a[i], b[i]);
    }
    counts.scalar = (a.len() - done) as u32;
    counts
}

/// The whole batches of eight of the slices on the IFMA lanes (the CPU has
/// them): how many products that covered, and the counts.
#[cfg(target_arch = "x86_64")]
fn whole_batches_on_lanes(a: &[Scalar], b: &[Scalar], out: &mut [Scalar]) -> (usize, LaneCounts) {
    let done = a.len() / LANES * LANES;
    // SAFETY: the callers check `ifma_available` first.
    let counts = unsafe { ifma::mul_batches(&a[..done], &b[..done], &mut out[..done]) };
    (done, counts)
}

/// No IFMA lanes on this architecture: nothing done on them.
#[cfg(not(target_arch = "x86_64"))]
fn whole_batches_on_lanes(_: &[Scalar], _: &[Scalar], _: &mut [Scalar]) -> (usize, LaneCounts) {
    (0, LaneCounts::default())
}

#[cfg(target_arch = "x86_64")]
mod ifma {
    use super::{LANES, LaneCounts, Scalar};
    use core::arch::x86_64::*;

    /// Largest operand magnitude the 52-bit multiplier takes.
    const OPERAND_MAX: i64 = (1 << 52) - 1;
    /// The high half of the magnitude's product must stay below this so
    /// that the rounded product, `hi·2²⁰ + (lo + half)/2³²`, fits 63 bits.
    const HIGH_LIMIT: i64 = 1 << 43;

    /// Whole batches (the slices' lengths are multiples of [`LANES`]) on
    /// the lanes, the scalar twin for each batch the guard refuses.
    #[target_feature(enable = "avx512f,avx512ifma")]
    pub(super) fn mul_batches(a: &[Scalar], b: &[Scalar], out: &mut [Scalar]) -> LaneCounts {
        let mut counts = LaneCounts::default();
        for ((x, y), o) in a
            .chunks_exact(LANES)
            .zip(b.chunks_exact(LANES))
            .zip(out.chunks_exact_mut(LANES))
        {
            let (x, y): (&[Scalar; LANES], &[Scalar; LANES]) =
                (x.try_into().unwrap(), y.try_into().unwrap());
            let o: &mut [Scalar; LANES] = o.try_into().unwrap();
            if mul8(x, y, o) {
                counts.ifma += 1;
            } else {
                counts.guarded += 1;
                for i in 0..LANES {
                    o[i] = super::mul_round_up(x[i], y[i]);
                }
            }
        }
        counts
    }

    /// Eight products on the IFMA lanes; `false` (and `out` untouched) if
    /// the range guard refuses the batch.
    ///
    /// With `P = |a|·|b| = hi·2⁵² + lo` (`lo`, `hi` below 2⁵²): a positive
    /// product rounds to `(P + 2³¹) >> 32`; a negative one to
    /// `−((P + 2³¹ − 1) >> 32)`, the floor of `(−P + 2³¹)/2³²` that the
    /// scalar shift gives. `(P + c) >> 32 = hi·2²⁰ + ((lo + c) >> 32)` for
    /// `c < 2³²`, since `hi·2⁵²` is a multiple of 2³² and `lo + c` stays
    /// below 2⁵³ in a 64-bit lane.
    #[target_feature(enable = "avx512f,avx512ifma")]
    pub(super) fn mul8(
        a: &[Scalar; LANES],
        b: &[Scalar; LANES],
        out: &mut [Scalar; LANES],
    ) -> bool {
        // `Scalar` is a transparent `i64`: eight of them are one 512-bit
        // vector.
        let (pa, pb) = (a.as_ptr().cast::<__m512i>(), b.as_ptr().cast::<__m512i>());
        // SAFETY: each array is 64 readable bytes; unaligned loads.
        let (va, vb) = unsafe { (_mm512_loadu_si512(pa), _mm512_loadu_si512(pb)) };
        // |i64::MIN| stays i64::MIN, which as unsigned exceeds the limit.
        let (ma, mb) = (_mm512_abs_epi64(va), _mm512_abs_epi64(vb));
        let limit = _mm512_set1_epi64(OPERAND_MAX);
        let fits = _mm512_cmple_epu64_mask(ma, limit) & _mm512_cmple_epu64_mask(mb, limit);
        let zero = _mm512_setzero_si512();
        let lo = _mm512_madd52lo_epu64(zero, ma, mb);
        let hi = _mm512_madd52hi_epu64(zero, ma, mb);
        let small = _mm512_cmplt_epu64_mask(hi, _mm512_set1_epi64(HIGH_LIMIT));
        if fits & small != 0xff {
            return false;
        }
        let negative = _mm512_cmplt_epi64_mask(_mm512_xor_si512(va, vb), zero);
        let half = _mm512_set1_epi64(1 << 31);
        let add = _mm512_mask_sub_epi64(half, negative, half, _mm512_set1_epi64(1));
        let magnitude = _mm512_add_epi64(
            _mm512_slli_epi64::<20>(hi),
            _mm512_srli_epi64::<32>(_mm512_add_epi64(lo, add)),
        );
        let product = _mm512_mask_sub_epi64(magnitude, negative, zero, magnitude);
        // SAFETY: `out` is 64 writable bytes; unaligned store.
        unsafe { _mm512_storeu_si512(out.as_mut_ptr().cast::<__m512i>(), product) };
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Faults;

    fn batch(v: [i64; LANES]) -> [Scalar; LANES] {
        v.map(Scalar::from_bits)
    }

    /// Which path a batch of eight should take on an IFMA machine.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    enum Path {
        Ifma,
        Guarded,
    }

    /// The path one batch took, from its counts.
    fn path_of(counts: LaneCounts) -> Option<Path> {
        match counts {
            LaneCounts {
                ifma: 1,
                guarded: 0,
                scalar: 0,
            } => Some(Path::Ifma),
            LaneCounts {
                ifma: 0,
                guarded: 1,
                scalar: 0,
            } => Some(Path::Guarded),
            LaneCounts {
                ifma: 0,
                guarded: 0,
                scalar: 8,
            } => None,
            other => panic!("one batch counted as {other:?}"),
        }
    }

    /// The scalar twin on each lane.
    fn twin_of(a: &[Scalar; LANES], b: &[Scalar; LANES]) -> [Scalar; LANES] {
        std::array::from_fn(|i| mul_round_up(a[i], b[i]))
    }

    /// Runs one batch both ways; the lanes must agree with the twin bit for
    /// bit, and the path must be the expected one on an IFMA machine.
    fn check(a: [i64; LANES], b: [i64; LANES], expect: Path) -> [Scalar; LANES] {
        let (a, b) = (batch(a), batch(b));
        let scope = crate::math::FaultScope::enter();
        let twin = twin_of(&a, &b);
        let twin_faults = scope.finish();
        let mut lanes = [Scalar::ZERO; LANES];
        let scope = crate::math::FaultScope::enter();
        let path = path_of(mul_slice(&a, &b, &mut lanes, true));
        let lane_faults = scope.finish();
        assert_eq!(lanes, twin, "a {a:?} b {b:?} ({path:?})");
        assert_eq!(lane_faults, twin_faults);
        if ifma_available() {
            assert_eq!(path, Some(expect), "a {a:?} b {b:?}");
        } else {
            assert_eq!(path, None);
        }
        let mut off = [Scalar::ZERO; LANES];
        assert_eq!(path_of(mul_slice(&a, &b, &mut off, false)), None);
        assert_eq!(off, twin);
        twin
    }

    #[test]
    fn the_twin_is_the_solver_product() {
        // Ties: 0.5·2⁻³² is exactly half a unit; it rounds up on both sides.
        let half_unit = |a: i64, b: i64| mul_round_up(Scalar::from_bits(a), Scalar::from_bits(b));
        assert_eq!(half_unit(1 << 31, 1).to_bits(), 1);
        assert_eq!(half_unit(-(1 << 31), 1).to_bits(), 0);
        assert_eq!(half_unit(3 << 31, 1).to_bits(), 2);
        assert_eq!(half_unit(-(3 << 31), 1).to_bits(), -1);
        // Just under and over a half.
        assert_eq!(half_unit((1 << 31) - 1, 1).to_bits(), 0);
        assert_eq!(half_unit(-(1 << 31) - 1, 1).to_bits(), -1);
        let scope = crate::math::FaultScope::enter();
        assert_eq!(half_unit(i64::MAX, i64::MAX), Scalar::MAX);
        assert!(scope.finish().contains(Faults::OVERFLOW));
    }

    #[test]
    fn lanes_match_the_twin_on_ties_and_signs() {
        let t = 1i64 << 31;
        let r = check(
            [t, -t, 3 * t, -3 * t, t - 1, -t - 1, 0, -5],
            [1, 1, 1, 1, 1, 1, -7, 0],
            Path::Ifma,
        );
        assert_eq!(r.map(Scalar::to_bits), [1, 0, 2, -1, 0, -1, 0, 0]);
        // Ties with larger operands: a·b = (2k + 1)·2³¹.
        check(
            [3 << 20, -(3 << 20), 5 << 12, -(5 << 12), 1 << 31, 7, -7, 1],
            [
                1 << 11,
                1 << 11,
                3 << 19,
                -(3 << 19),
                -1,
                1 << 31,
                1 << 31,
                -(1 << 31),
            ],
            Path::Ifma,
        );
    }

    #[test]
    fn lanes_match_the_twin_on_random_inputs_of_every_magnitude() {
        let mut rng = crate::testing::Rng::new(0x1F3A);
        let mut next = || rng.next_u64();
        let (mut ifma, mut guarded) = (0, 0);
        for _ in 0..20_000 {
            let mut a = [0i64; LANES];
            let mut b = [0i64; LANES];
            for i in 0..LANES {
                // Magnitudes of 0 to 53 bits: most batches fit, and some
                // have an operand or a product past the guard.
                let mut draw = || {
                    let bits = next() % 54;
                    let m = if bits == 0 {
                        0
                    } else {
                        (next() >> (64 - bits)) as i64
                    };
                    if next() & 1 == 0 { m } else { -m }
                };
                a[i] = draw();
                b[i] = draw();
            }
            let (sa, sb) = (batch(a), batch(b));
            let mut out = [Scalar::ZERO; LANES];
            let path = path_of(mul_slice(&sa, &sb, &mut out, true));
            assert_eq!(out, twin_of(&sa, &sb), "a {a:?} b {b:?}");
            match path {
                Some(Path::Ifma) => ifma += 1,
                Some(Path::Guarded) => guarded += 1,
                None => {}
            }
        }
        if ifma_available() {
            // Both paths were exercised.
            assert!(
                ifma > 1000 && guarded > 1000,
                "ifma {ifma}, guarded {guarded}"
            );
        }
    }

    #[test]
    fn a_slice_matches_the_twin_and_counts_its_batches() {
        let n = 8 * 5 + 3;
        let a: Vec<Scalar> = (0..n)
            .map(|i| Scalar::from_bits((i as i64 - 20) << 30))
            .collect();
        let mut b: Vec<Scalar> = (0..n)
            .map(|i| Scalar::from_bits(i as i64 * 3 + 1))
            .collect();
        // The third batch has an operand past the guard.
        b[17] = Scalar::from_bits(1 << 53);
        let twin: Vec<Scalar> = a
            .iter()
            .zip(&b)
            .map(|(&x, &y)| mul_round_up(x, y))
            .collect();
        let mut out = vec![Scalar::ZERO; n];
        let counts = mul_slice(&a, &b, &mut out, true);
        let all_scalar = LaneCounts {
            ifma: 0,
            guarded: 0,
            scalar: n as u32,
        };
        assert_eq!(out, twin);
        if ifma_available() {
            assert_eq!(
                counts,
                LaneCounts {
                    ifma: 4,
                    guarded: 1,
                    scalar: 3
                }
            );
        } else {
            assert_eq!(counts, all_scalar);
        }
        let mut off = vec![Scalar::ZERO; n];
        let counts = mul_slice(&a, &b, &mut off, false);
        assert_eq!(off, twin);
        assert_eq!(counts, all_scalar);
    }

    #[test]
    fn the_guard_sends_a_batch_to_the_twin_at_its_boundaries() {
        let max = (1i64 << 52) - 1;
        let ones = [1i64; LANES];
        // Operands at the largest magnitude the lanes take, times 1.
        check([max, -max, max, -max, 1, 2, 3, 4], ones, Path::Ifma);
        // One operand past it: the whole batch goes to the twin.
        check([max + 1, 0, 0, 0, 0, 0, 0, 0], ones, Path::Guarded);
        check([0, 0, 0, 0, 0, 0, 0, -(max + 1)], ones, Path::Guarded);
        check([i64::MIN, 0, 0, 0, 0, 0, 0, 0], ones, Path::Guarded);
        check(ones, [i64::MIN, 0, 0, 0, 0, 0, 0, 0], Path::Guarded);
        // The high half just below 2⁴³: P = 2⁹⁵ − 2⁵² (a = 2⁴⁴ − 1, b = 2⁵¹).
        let a = (1i64 << 44) - 1;
        check(
            [a, -a, 0, 0, 0, 0, 0, 0],
            [1 << 51, 1 << 51, 0, 0, 0, 0, 0, 0],
            Path::Ifma,
        );
        // At 2⁴³: P = 2⁹⁵, whose rounded value 2⁶³ does not fit a positive
        // i64 (the twin saturates with the fault) but does fit a negative
        // one; the lanes refuse both.
        let r = check(
            [1 << 44, -(1 << 44), 0, 0, 0, 0, 0, 0],
            [1 << 51, 1 << 51, 0, 0, 0, 0, 0, 0],
            Path::Guarded,
        );
        assert_eq!(r[0], Scalar::MAX);
        assert_eq!(r[1].to_bits(), i64::MIN);
    }
}
