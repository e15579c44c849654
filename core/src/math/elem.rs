//! Integer-only elementary functions on Q32.32: square roots, sine and
//! cosine, and the inverse trigonometric functions.
//!
//! Determinism: every function here uses only integer arithmetic (`u64`,
//! `i128`, `u128`, shifts, one table lookup), so the result bits are the
//! same on x86_64, i686 and aarch64 whatever the compiler does. No floats,
//! no platform intrinsics whose results could differ.
//!
//! How they are fast without floats:
//! * square roots start from a table of 384 values of 1/√a (built at
//!   compile time from integer square roots), refine it with integer Newton steps,
//!   and end with an exact integer fix-up, so `isqrt_u128` and [`sqrt`] are
//!   the exact floor and [`rsqrt`] is correctly rounded;
//! * sine and cosine reduce the argument by π/2 carried to 94 fraction bits
//!   (the reduced argument is off by under 2⁻⁶¹ even for |x| near 2³¹) and
//!   evaluate Chebyshev polynomials in Q62 with integer Horner steps;
//! * arc tangents use one integer division and a piecewise polynomial; arc
//!   sine and cosine go through it with an exact `1 − x²`.
//!
//! The error bounds in the doc comments are the maxima measured by
//! `core/tests/elem.rs` against `f64` over ≥100,000 inputs per function.
//!
//! The polynomial coefficients were derived offline with mpmath 1.3
//! (60 decimal digits) by Chebyshev interpolation, `mpmath.chebyfit`, which
//! is within a small factor of the minimax polynomial, and rounded to
//! nearest in Q62:
//! * sine: `chebyfit(lambda z: sin(sqrt(z))/sqrt(z), [0, R*R], 6)`,
//! * cosine: `chebyfit(lambda z: cos(sqrt(z)), [0, R*R], 7)`,
//!   with `R = pi/4 + 2**-20` (room for a reduction off by a hair),
//! * arc tangent: for each `i` in `0..16`, `c = (2i+1)/32`,
//!   `chebyfit(lambda e: atan(c + e), [-1/32, 1/32], 8)`.
//!
//! The approximation errors of those polynomials (measured in mpmath) are
//! 2⁻⁴⁸ (sine), 2⁻⁵⁴ (cosine) and 2⁻⁵⁰ (arc tangent), i.e. below 2⁻¹⁶ of an
//! ulp of Q32.32; the final rounding to Q32.32 dominates every bound.

use super::faults::{self, Faults};
use super::scalar::{Scalar, round_shift};

// ---------------------------------------------------------------------------
// Square roots
// ---------------------------------------------------------------------------

/// `RSQRT_SEED[i]` ≈ 1/√a in Q1.15 for every `a` in `[i/512, (i+1)/512)`,
/// for the 9-bit mantissas `i` in `128..512` of a normalised argument.
///
/// Each entry is `2 / (√(i/512) + √((i+1)/512))`, the value that balances the
/// relative error at both ends of its interval (at most 2⁻⁹, plus 2⁻¹⁶ from
/// rounding to Q1.15), computed at compile time with integer square roots
/// only. Entries below 128 are never used (zero); they make the index a
/// plain 9-bit field, with no bounds check on the hot path.
static RSQRT_SEED: [u16; 512] = build_rsqrt_seed();

const fn build_rsqrt_seed() -> [u16; 512] {
    let mut table = [0u16; 512];
    // y·2^15 = 2^16·√512 / (√i + √(i+1)) = 2^20·√2 / (√i + √(i+1)); every
    // root is taken with 40 extra fraction bits.
    let num = (2u128 << 80).isqrt() << 20;
    let mut i = 128;
    while i < 512 {
        let den = ((i as u128) << 80).isqrt() + ((i as u128 + 1) << 80).isqrt();
        table[i] = ((num + den / 2) / den) as u16;
        i += 1;
    }
    table
}

/// 1/√A in Q61 for `x = A·2⁶⁴` in `[2⁶², 2⁶⁴)`, with a relative error
/// below 2⁻³³. Q61 keeps every value (1/√A ≤ 2) and product in `i64` ×
/// `i64` → `i128`, a single multiply instruction on 64-bit targets.
///
/// Table seed (9 bits), one Newton step y ← y + y·(1 − A·y²)/2 in 64-bit
/// arithmetic (17 bits), one in 128-bit products (33 bits). Newton's
/// iteration for the reciprocal root approaches from below, so the result
/// never exceeds 2⁶² by more than rounding.
#[inline(always)]
pub(crate) fn rsqrt_q61(x: u64) -> i64 {
    debug_assert!(x >> 62 != 0);
    // Index: the top 9 bits, in 128..512.
    let y0 = RSQRT_SEED[(x >> 55) as usize] as i64; // Q15
    let a32 = x >> 32; // A in Q32
    // A·y0² in Q62 is within 2^62·(1 ± 2^-8) (the table test pins this).
    let e = (1i64 << 62) - (a32 * (y0 * y0) as u64) as i64; // |e| < 2^55
    let y1 = (y0 << 46) + ((y0 * (e >> 15)) >> 2); // Q61
    let y1sq = ((y1 as u128 * y1 as u128) >> 64) as u64; // Q58
    let p = x as u128 * y1sq as u128; // A·y1² in Q122
    let e = ((1u128 << 122).wrapping_sub(p) as i128 >> 64) as i64; // Q58, |e| < 2^43
    y1 + ((y1 as i128 * e as i128) >> 59) as i64
}

/// ⌊√n⌋ for a `u128`, exact for every input.
///
/// Why not `u128::isqrt`: that is a bit-by-bit loop (~1.4× this one in
/// `lockstep-bench math`); this
/// takes a table seed, two Newton steps for 1/√n, one Newton step for √n using that
/// reciprocal (landing within one unit of the root), and an exact integer
/// fix-up against `n` itself, so the result is always the floor.
/// Lengths and normalisation in [`Vec3`](super::vec3::Vec3) and
/// [`Quat`](super::quat::Quat) rest on it.
#[inline]
pub fn isqrt_u128(n: u128) -> u64 {
    if n == 0 {
        return 0;
    }
    // Normalise by an even shift so that m is in [2^126, 2^128); then
    // ⌊√n⌋ = ⌊√m⌋ >> (shift / 2).
    let shift = n.leading_zeros() & !1;
    let m = n << shift;
    let x = (m >> 64) as u64;
    let y = rsqrt_q61(x); // 1/√A in Q61, A = m / 2^128
    // s ≈ √m = A·(1/√A)·2^64, with a relative error below 2^-33.
    let s = ((x as u128 * y as u128) >> 61).min(u64::MAX as u128) as u64;
    // One Newton step for the root: s + (m − s²)/(2√m), with 1/√m = y/2^125.
    // |m − s²| < 2^96, so the wrapped difference is exact as i128.
    let d = m.wrapping_sub(s as u128 * s as u128) as i128;
    let corr = (((d >> 34) as i64 as i128 * y as i128) >> 92) as i64;
    let r = s.saturating_add_signed(corr);
    isqrt_fix_up(m, r) >> (shift / 2)
}

/// ⌊√m⌋ from an estimate `r` within one of it.
///
/// Why one step is enough: with 1/√ and the root both within 2⁻³³
/// (relative), the Newton step lands within R·(δε + ε²/2) < 0.375 of the real
/// root R ≥ 2⁶³, and its truncation adds less than one, so `r` is
/// ⌊R⌋ − 1, ⌊R⌋ or ⌊R⌋ + 1 (the tests see only the first two, the first
/// in 55 of 200,000 cases), and the branches predict almost perfectly.
#[inline(always)]
fn isqrt_fix_up(m: u128, r: u64) -> u64 {
    // r ≤ 2^64 − 1 so r² fits; ⌊√m⌋ ≤ 2^64 − 1 so r + 1 cannot overflow.
    let r2 = r as u128 * r as u128;
    if r2 > m {
        r - 1
    } else if m - r2 > 2 * r as u128 {
        r + 1
    } else {
        r
    }
}

/// √x, the exact floor of the true root: error in [0, 1) ulp, never above
/// the true value (checked exactly in integers over 200,000 inputs; `f64`
/// cannot resolve the difference from 1 ulp at the top of the range).
///
/// A negative argument raises [`Faults::DOMAIN`] and returns zero (a peer
/// must not panic on bad data).
#[inline]
pub fn sqrt(x: Scalar) -> Scalar {
    let bits = x.to_bits();
    if bits < 0 {
        faults::raise(Faults::DOMAIN);
        return Scalar::ZERO;
    }
    // √(b/2^32)·2^32 = √(b·2^32).
    Scalar::from_bits(isqrt_u128((bits as u128) << 32) as i64)
}

/// 1/√x, correctly rounded: error ≤ 0.5 ulp (the result is checked
/// against x in exact integer arithmetic before it is returned; the tests
/// confirm the rounding exactly over 200,000 inputs).
///
/// Why: normalising a vector by a reciprocal root and three multiplications
/// is cheaper than three divisions. Zero or a negative argument raises
/// [`Faults::DOMAIN`] and returns [`Scalar::MAX`].
#[inline]
pub fn rsqrt(x: Scalar) -> Scalar {
    let bits = x.to_bits();
    if bits <= 0 {
        faults::raise(Faults::DOMAIN);
        return Scalar::MAX;
    }
    let b = bits as u64;
    // The result is q = round(2^48 / √b). Normalise b by an even shift to
    // B = b·2^shift in [2^62, 2^64): 2^48/√b = (1/√A)·2^(16 + shift/2) with
    // A = B / 2^64.
    let shift = b.leading_zeros() & !1;
    let big = b << shift;
    let y2 = rsqrt_q61(big);
    // A third Newton step: relative error ~2^-58 (the truncations of y2²).
    let y2sq = ((y2 as u128 * y2 as u128) >> 64) as u64; // Q58
    let p = big as u128 * y2sq as u128; // A·y2² in Q122
    let e = ((1u128 << 122).wrapping_sub(p) as i128 >> 32) as i64; // Q90, |e| < 2^58
    let y3 = y2 + ((y2 as i128 * e as i128) >> 91) as i64; // Q61
    // The result is y3 / 2^(45 − shift/2), rounded: within 2^-10 ulp of it.
    let q = round_shift(y3 as i128, 45 - shift / 2) as u64;
    Scalar::from_bits(rsqrt_fix_up(b, q) as i64)
}

/// round(2⁴⁸/√b) from an estimate `q` off by at most one.
///
/// Why one step is enough: y3 is within ~2⁻⁵⁸ (relative) of 1/√A, so before
/// rounding the estimate is within 2⁴⁸·2⁻⁵⁸ < 0.001 of the true 2⁴⁸/√b,
/// and rounding leaves it at most one away from the correctly rounded
/// value (the tests never see it off at all). Branches, not `while` loops:
/// LLVM vectorised a loop here into a 16-lane search that cost five times
/// the whole function.
///
/// q is right iff (2q−1)²·b < 2⁹⁸ < (2q+1)²·b (equality is impossible: 2⁹⁸/b
/// would have to be the square of an odd number above 1). For q within one
/// of 2⁴⁸/√b both products are below 2¹⁰⁰, so the wrapping products are
/// exact.
#[inline(always)]
fn rsqrt_fix_up(b: u64, q: u64) -> u64 {
    const TARGET: u128 = 1 << 98;
    let check = |t: u64| (t as u128 * t as u128).wrapping_mul(b as u128);
    if check(2 * q + 1) < TARGET {
        q + 1
    } else if check(2 * q - 1) > TARGET {
        q - 1
    } else {
        q
    }
}

// ---------------------------------------------------------------------------
// Sine and cosine
// ---------------------------------------------------------------------------

/// π/2 in Q94: round(π/2 · 2⁹⁴).
const FRAC_PI_2_Q94: i128 = 31_112_826_664_028_885_653_815_243_078;
/// The high 63 bits of [`FRAC_PI_2_Q94`] (π/2 in Q62, truncated).
const FRAC_PI_2_HI: i64 = (FRAC_PI_2_Q94 >> 32) as i64;
/// The low 32 bits of [`FRAC_PI_2_Q94`].
const FRAC_PI_2_LO: i64 = (FRAC_PI_2_Q94 & 0xFFFF_FFFF) as i64;
/// 2/π in Q63: round(2/π · 2⁶³).
const FRAC_2_PI_Q63: i64 = 5_871_781_006_564_002_453;

/// sin(r)/r ≈ Σ SIN_POLY[5−j]·z^j with z = r², in Q62, highest degree first.
const SIN_POLY: [i64; 6] = [
    -114_169_472_661,
    12_707_626_207_902,
    -915_016_765_409_047,
    38_430_716_776_623_472,
    -768_614_336_402_259_623,
    4_611_686_018_427_368_157,
];

/// cos(r) ≈ Σ COS_POLY[6−j]·z^j with z = r², in Q62, highest degree first.
const COS_POLY: [i64; 7] = [
    9_514_117_527,
    -1_270_760_867_947,
    114_377_092_980_926,
    -6_405_119_461_317_150,
    192_153_584_100_244_820,
    -2_305_843_009_213_659_400,
    4_611_686_018_427_387_687,
];

/// Horner's rule, `Σ poly[n−1−j]·v^j`, with coefficients and result in Q62
/// and `v` in Q64 (so |v| < ½).
///
/// Why Q64 for `v`: the product's high word is then already in Q62, so each
/// step is one multiply and one add, with no double-word shift on the
/// critical path. Every coefficient and partial sum is below 2 in
/// magnitude, so nothing overflows; each step truncates by less than 2⁻⁶².
#[inline(always)]
fn horner_q62(poly: &[i64], v: i64) -> i64 {
    let mut acc = poly[0];
    for &c in &poly[1..] {
        acc = c + ((acc as i128 * v as i128) >> 64) as i64;
    }
    acc
}

/// Rewrites P(z) as a polynomial in w = z/2: the coefficient of degree k
/// is multiplied by 2ᵏ, exactly (compile-time overflow is a build error).
const fn in_half_variable<const N: usize>(mut poly: [i64; N]) -> [i64; N] {
    let mut j = 0;
    while j < N {
        poly[j] *= 1 << (N - 1 - j);
        j += 1;
    }
    poly
}

/// [`SIN_POLY`] in w = r²/2, for [`horner_q62`] (w < 0.31 fits Q64).
const SIN_POLY_W: [i64; 6] = in_half_variable(SIN_POLY);
/// [`COS_POLY`] in w = r²/2.
const COS_POLY_W: [i64; 7] = in_half_variable(COS_POLY);

/// Reduces `x` to `x − k·π/2` with |r| ≤ π/4 (plus 2⁻³³), returning
/// `(r in Q62, k mod 4)`.
///
/// Valid over the whole Q32.32 range: |k| < 2³¹ and π/2 is carried to 2⁻⁹⁵,
/// so `k·π/2` is off by less than 2⁻⁶³ and r by under two Q62 units. The
/// reduction is odd: `-x` gives `(-r, -k mod 4)` exactly.
#[inline(always)]
fn reduce_frac_pi_2(x: Scalar) -> (i64, u32) {
    let xb = x.to_bits() as i128;
    // k = round(x·2/π): |x_bits·2/π·2^63| < 2^126.
    let k = round_shift(xb * FRAC_2_PI_Q63 as i128, 95) as i64;
    // r·2^62 = x_bits·2^30 − k·(π/2)·2^62, with (π/2)·2^62 = HI + LO/2^32.
    let r = (xb << 30)
        - k as i128 * FRAC_PI_2_HI as i128
        - round_shift(k as i128 * FRAC_PI_2_LO as i128, 32);
    (r as i64, (k & 3) as u32)
}

/// Sine and cosine of `x` (radians) together, each within 0.50001 ulp of
/// the true value over the whole Q32.32 range, including |x| near 2³¹
/// (measured maximum 0.5000038 ulp over 300,000 inputs).
///
/// Why both at once: a rotation needs both, and the two polynomial chains
/// run in parallel for little more than the cost of one. The result is
/// exactly odd/even: `sin_cos(-x) == (-s, c)`. Never panics or faults.
#[inline]
pub fn sin_cos(x: Scalar) -> (Scalar, Scalar) {
    let (r, quadrant) = reduce_frac_pi_2(x);
    let w = ((r as i128 * r as i128) >> 61) as i64; // r²/2 in Q64, < 0.31
    let p = horner_q62(&SIN_POLY_W, w);
    let c = horner_q62(&COS_POLY_W, w);
    // sin r = r·P(z): Q124 → Q32 with one rounding; cos r = Q(z): Q62 → Q32.
    let s = round_shift(r as i128 * p as i128, 92) as i64;
    let c = round_shift(c as i128, 30) as i64;
    // Quadrant k: (sin, cos) = (s, c), (c, −s), (−s, −c), (−c, s). Selected
    // with masks rather than branches, which random angles would mispredict.
    let swap = -((quadrant & 1) as i64); // all ones for odd k
    let neg_sin = -((quadrant >> 1) as i64); // k = 2, 3
    let neg_cos = -((((quadrant + 1) >> 1) & 1) as i64); // k = 1, 2
    let diff = (s ^ c) & swap;
    let (a, b) = (s ^ diff, c ^ diff);
    (
        Scalar::from_bits((a ^ neg_sin) - neg_sin),
        Scalar::from_bits((b ^ neg_cos) - neg_cos),
    )
}

/// sin x (radians), within 0.50001 ulp (see [`sin_cos`]).
#[inline]
pub fn sin(x: Scalar) -> Scalar {
    sin_cos(x).0
}

/// cos x (radians), within 0.50001 ulp (see [`sin_cos`]).
#[inline]
pub fn cos(x: Scalar) -> Scalar {
    sin_cos(x).1
}

// ---------------------------------------------------------------------------
// Arc tangent, sine, cosine
// ---------------------------------------------------------------------------

/// π in Q62, rounded.
const PI_Q62: i128 = 14_488_038_916_154_245_685;
/// π/2 in Q62, rounded.
const FRAC_PI_2_Q62: i128 = 7_244_019_458_077_122_842;

/// `ATAN_POLY[i]`: atan(c + e) for c = (2i+1)/32 and |e| ≤ 1/32, as a
/// degree-7 polynomial in e, Q62, highest degree first.
const ATAN_POLY: [[i64; 8]; 16] = [
    [
        -639_973_005_687_305_366,
        -142_530_384_162_085_860,
        908_887_214_019_266_320,
        143_413_251_757_016_979,
        -1_528_243_423_649_464_774,
        -143_834_124_846_786_301,
        4_607_186_812_555_747_951,
        144_068_303_048_367_707,
    ],
    [
        -506_327_455_725_947_182,
        -397_506_129_313_574_090,
        805_598_180_913_528_666,
        413_804_453_951_494_038,
        -1_457_916_272_844_768_612,
        -424_844_771_393_584_757,
        4_571_506_759_796_362_833,
        431_085_564_716_661_030,
    ],
    [
        -282_559_722_384_654_449,
        -572_152_185_173_269_053,
        620_386_005_377_482_662,
        638_326_334_149_977_371,
        -1_325_189_962_069_260_299,
        -686_639_358_863_275_378,
        4_501_779_297_301_853_778,
        714_796_307_632_433_268,
    ],
    [
        -35_672_037_426_520_011,
        -641_359_708_181_710_312,
        389_102_394_105_513_802,
        796_733_510_364_754_783,
        -1_144_297_152_439_764_619,
        -918_773_080_532_375_700,
        4_401_087_122_898_086_065,
        993_162_092_656_739_304,
    ],
    [
        171_739_961_183_126_830,
        -609_318_428_981_410_298,
        151_453_050_581_863_605,
        880_875_457_364_350_031,
        -933_044_999_249_963_923,
        -1_113_852_334_692_850_602,
        4_273_634_826_126_377_775,
        1_264_374_201_036_402_322,
    ],
    [
        302_154_119_279_775_010,
        -502_602_115_921_725_299,
        -59_007_289_845_246_214,
        894_268_658_946_122_548,
        -709_779_397_723_147_700,
        -1_267_918_614_760_842_413,
        4_124_337_539_624_146_463,
        1_526_911_147_692_606_723,
    ],
    [
        348_676_432_109_515_016,
        -357_425_615_064_487_153,
        -220_963_111_460_566_557,
        849_096_996_326_055_023,
        -490_803_444_363_129_518,
        -1_380_295_687_450_355_572,
        3_958_396_045_992_998_556,
        1_779_569_711_216_534_771,
    ],
    [
        327_567_296_907_916_846,
        -207_537_791_467_446_881,
        -326_568_635_165_145_963,
        762_075_448_976_092_676,
        -288_719_755_727_179_294,
        -1_453_034_909_471_912_286,
        3_780_917_920_632_222_983,
        2_021_470_584_462_504_479,
    ],
    [
        265_381_232_294_166_654,
        -76_858_685_459_030_636,
        -378_946_384_778_262_495,
        650_559_609_438_369_180,
        -111_800_530_398_872_238,
        -1_490_147_077_319_994_023,
        3_596_623_368_522_197_793,
        2_252_042_854_410_230_755,
    ],
    [
        187_804_791_670_034_644,
        22_435_632_301_578_764,
        -387_972_679_845_700_574,
        529_758_351_146_041_558,
        35_796_542_497_878_914,
        -1_496_799_813_189_138_082,
        3_409_650_890_158_588_500,
        2_470_993_194_618_541_639,
    ],
    [
        113_495_786_336_006_856,
        87_993_962_375_600_102,
        -366_140_314_520_727_860,
        411_289_049_120_927_039,
        153_283_957_315_730_975,
        -1_478_610_246_622_314_172,
        3_223_458_350_081_668_731,
        2_678_265_955_860_899_213,
    ],
    [
        52_705_707_466_731_182,
        123_772_382_577_545_510,
        -325_513_343_531_727_438,
        302_870_527_636_798_479,
        242_288_285_869_727_018,
        -1_441_101_567_931_363_688,
        3_040_802_629_021_020_307,
        2_873_999_636_550_249_317,
    ],
    [
        8_802_780_166_475_772,
        136_623_927_520_926_468,
        -276_024_742_418_039_304,
        208_756_535_564_953_101,
        305_918_670_294_596_302,
        -1_389_339_436_967_231_176,
        2_863_775_914_414_581_289,
        3_058_483_968_841_891_691,
    ],
    [
        -19_219_355_417_293_104,
        133_827_761_350_415_300,
        -224_891_544_517_606_585,
        130_517_247_205_763_261,
        347_994_480_884_766_025,
        -1_327_729_479_877_690_518,
        2_693_877_058_111_605_617,
        3_232_120_473_793_924_815,
    ],
    [
        -34_457_621_352_948_043,
        121_695_481_518_174_912,
        -176_751_022_285_791_137,
        67_880_263_445_451_086,
        372_480_476_447_991_001,
        -1_259_940_370_769_376_776,
        2_532_099_990_814_822_940,
        3_395_388_091_196_947_759,
    ],
    [
        -40_517_213_800_662_983,
        105_029_825_731_515_396,
        -134_148_963_594_246_627,
        19_465_697_044_903_676,
        383_121_254_594_630_791,
        -1_188_913_717_112_972_022,
        2_379_025_935_954_481_068,
        3_548_814_510_496_411_514,
    ],
];

/// atan(t) in Q62 for `t` in Q62 with 0 ≤ t ≤ 1 (error below 2⁻⁵⁰).
#[inline(always)]
fn atan_unit_q62(t: u64) -> i64 {
    let i = ((t >> 58) as usize).min(15);
    let e = (t as i64 - ((2 * i as i64 + 1) << 57)) << 2; // Q64, |e| ≤ 2^59
    horner_q62(&ATAN_POLY[i], e)
}

/// The angle of the vector (±`ay`, ±`ax`) in Q62, in (−π, π]; the two
/// magnitudes are integers at any common scale. (0, 0) gives 0.
///
/// Octant reduction (swap so the ratio is at most 1), one `u128 / u64`
/// division for the ratio in Q62, then [`atan_unit_q62`]. Odd in y exactly (y ≠ 0).
#[inline]
fn atan2_q62(y_neg: bool, ay: u64, x_neg: bool, ax: u64) -> i128 {
    let (lo, hi, swapped) = if ay > ax {
        (ax, ay, true)
    } else {
        (ay, ax, false)
    };
    if hi == 0 {
        return 0;
    }
    // t = lo/hi in Q62, in [0, 2^62]; truncation costs under 2^-62.
    let t = (((lo as u128) << 62) / hi as u128) as u64;
    let a = atan_unit_q62(t) as i128;
    let a = if swapped { FRAC_PI_2_Q62 - a } else { a };
    let a = if x_neg { PI_Q62 - a } else { a };
    if y_neg { -a } else { a }
}

/// A Q62 angle rounded to Q32.32 (to nearest, ties away from zero).
#[inline(always)]
fn angle_to_scalar(a: i128) -> Scalar {
    Scalar::from_bits(round_shift(a, 30) as i64)
}

/// The angle of the vector (x, y) from the +x axis, in (−π, π] (rounded, so
/// results lie in [−[`Scalar::PI`], [`Scalar::PI`]]), within 0.50001 ulp
/// (measured maximum 0.5000005 ulp over 370,000 pairs).
///
/// Why: headings and joint angles from vectors, without a division that
/// can overflow. atan2(0, 0) is 0 and raises no fault (a zero vector has no
/// direction; callers that care test for it). Exactly odd in `y` for
/// y ≠ 0 (the negative x axis itself gives +π).
#[inline]
pub fn atan2(y: Scalar, x: Scalar) -> Scalar {
    let (yb, xb) = (y.to_bits(), x.to_bits());
    angle_to_scalar(atan2_q62(
        yb < 0,
        yb.unsigned_abs(),
        xb < 0,
        xb.unsigned_abs(),
    ))
}

/// atan x in (−π/2, π/2), within 0.50001 ulp (measured maximum 0.49999
/// ulp over 200,000 inputs); see [`atan2`].
#[inline]
pub fn atan(x: Scalar) -> Scalar {
    let xb = x.to_bits();
    angle_to_scalar(atan2_q62(xb < 0, xb.unsigned_abs(), false, 1 << 32))
}

/// Clamps `x` to [−1, 1], raising [`Faults::DOMAIN`] when it was outside,
/// and returns (|x|·2⁶³, √(1 − x²)·2⁶³ floored, x < 0).
///
/// 1 − x² is exact (Q64 in a `u128`) and its root keeps 63 bits, so arc
/// sine and cosine stay accurate right up to ±1 where their slope is
/// infinite.
#[inline(always)]
fn unit_sides(x: Scalar) -> (u64, u64, bool) {
    let xb = x.to_bits();
    let mag = xb.unsigned_abs();
    let mag = if mag > 1 << 32 {
        faults::raise(Faults::DOMAIN);
        1 << 32
    } else {
        mag
    };
    let rest = (1u128 << 64) - mag as u128 * mag as u128; // (1 − x²)·2^64
    (mag << 31, isqrt_u128(rest << 62), xb < 0)
}

/// asin x in [−π/2, π/2], within 0.50001 ulp (measured maximum 0.4999955
/// ulp over 400,000 inputs, bunched toward ±1 and 0).
///
/// |x| > 1 raises [`Faults::DOMAIN`] and is clamped to ±1 (so the result is
/// ±π/2): a contact solver that drifts a hair past 1 gets a usable angle.
#[inline]
pub fn asin(x: Scalar) -> Scalar {
    let (sin_side, cos_side, neg) = unit_sides(x);
    angle_to_scalar(atan2_q62(neg, sin_side, false, cos_side))
}

/// acos x in [0, π], within 0.50001 ulp (measured maximum 0.4999962 ulp
/// over 400,000 inputs).
///
/// |x| > 1 raises [`Faults::DOMAIN`] and is clamped to ±1 (result 0 or π).
#[inline]
pub fn acos(x: Scalar) -> Scalar {
    let (cos_side, sin_side, neg) = unit_sides(x);
    angle_to_scalar(atan2_q62(false, sin_side, neg, cos_side))
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::testing::Rng;

    #[test]
    fn seed_table_is_within_two_to_the_minus_9_of_the_reciprocal_root() {
        let mut worst = 0.0f64;
        for (i, &y) in RSQRT_SEED.iter().enumerate().skip(128) {
            let y = y as f64 / 32768.0;
            for a in [i, i + 1] {
                let a = a as f64 / 512.0;
                worst = worst.max((y * a.sqrt() - 1.0).abs());
            }
        }
        assert!(worst <= 2f64.powi(-9) + 2f64.powi(-16), "{worst:e}");
        assert!(worst > 2f64.powi(-10), "{worst:e}");
    }

    #[test]
    fn reciprocal_root_kernel_has_33_bits() {
        let mut rng = Rng::new(7);
        let mut worst = 0.0f64;
        // Both ends of every seed interval (where the seed is worst), then
        // random arguments.
        let ends = (128u64..512).flat_map(|i| [i << 55, ((i + 1) << 55).wrapping_sub(1) | 1 << 62]);
        let random = (0..200_000).map(|_| rng.next_u64() | 1 << 62);
        for x in ends.chain(random).collect::<Vec<_>>() {
            let y = rsqrt_q61(x) as f64 / 2f64.powi(61);
            let a = x as f64 / 2f64.powi(64);
            worst = worst.max((y * a.sqrt() - 1.0).abs());
        }
        assert!(worst < 2f64.powi(-33), "worst relative error {worst:e}");
    }

    #[test]
    fn isqrt_estimate_is_within_one_of_the_floor() {
        // Replays isqrt_u128's estimate and measures how far the exact
        // fix-up has to move it, over random normalised inputs.
        let mut rng = Rng::new(11);
        let mut hist = [0u32; 3];
        for _ in 0..200_000 {
            let m = ((rng.next_u64() as u128) << 64 | rng.next_u64() as u128) | 1 << 126;
            let x = (m >> 64) as u64;
            let y = rsqrt_q61(x);
            let s = ((x as u128 * y as u128) >> 61).min(u64::MAX as u128) as u64;
            let d = m.wrapping_sub(s as u128 * s as u128) as i128;
            let r = s.saturating_add_signed((((d >> 34) as i64 as i128 * y as i128) >> 92) as i64);
            let off = r as i128 - m.isqrt() as i128;
            assert!(off.abs() <= 1, "estimate off by {off}");
            hist[(off + 1) as usize] += 1;
        }
        eprintln!(
            "isqrt estimate − floor: −1: {}, 0: {}, +1: {}",
            hist[0], hist[1], hist[2]
        );
    }

    #[test]
    fn reduction_constants_split_pi_over_2_exactly() {
        assert_eq!(
            ((FRAC_PI_2_HI as i128) << 32) + FRAC_PI_2_LO as i128,
            FRAC_PI_2_Q94
        );
        // π/2 = 1.5707963267948966192313216916397514...
        assert_eq!(
            (FRAC_PI_2_Q94 * 10i128.pow(9)) >> 94,
            1_570_796_326 // first ten digits
        );
        assert_eq!(round_shift(FRAC_PI_2_Q94, 32), FRAC_PI_2_Q62);
        assert!((PI_Q62 - 2 * FRAC_PI_2_Q62).abs() <= 1);
        // 2/π·2^63 times π/2·2^62, over 2^125, is 1 to 2^-62.
        let unit = FRAC_2_PI_Q63 as i128 * FRAC_PI_2_Q62;
        assert!((unit - (1i128 << 125)).abs() < 1i128 << 64);
    }
}
