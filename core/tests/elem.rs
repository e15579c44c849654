//! Accuracy of the integer-only elementary functions against `f64` (and, for
//! the square roots, against exact integer identities).
//!
//! Inputs: random bits over every magnitude (a random 64-bit value shifted
//! right by a random amount, so each power of two is equally likely), plus
//! the edge cases 0, ±DELTA, ±MAX, MIN and multiples of π/2 up to 2³¹.
//!
//! Errors are in ulps of Q32.32 (2⁻³²). `f64` is exact to ~2⁻⁵² absolute
//! for every reference value here (all below 4 in magnitude), i.e. to ~2⁻²⁰
//! ulp, so the measured maxima are the functions' own. Arguments above 2²¹
//! have more than 53 significant bits: for sine and cosine the test reduces
//! them itself, exactly, before calling `f64::sin_cos` (see
//! [`reference_sin_cos`]); for atan2 the rounding of the inputs moves the
//! angle by at most 2⁻⁵³ rad (2⁻²¹ ulp), far inside the bound.

use lockstep_core::math::elem;
use lockstep_core::math::{FaultScope, Faults, Scalar};
use lockstep_testsupport::Rng;

/// 2³², the Q32.32 scale.
const SCALE: f64 = 4_294_967_296.0;

/// The input distributions of these tests, on the shared generator.
trait Draw {
    /// Random bits with a uniformly random magnitude: any sign, any power of
    /// two from 2⁻³² to 2³¹.
    fn scalar(&mut self) -> Scalar;
    /// A `u128` whose bit length is uniform in 0..=128.
    fn u128_any_magnitude(&mut self) -> u128;
}

impl Draw for Rng {
    fn scalar(&mut self) -> Scalar {
        let shift = self.next_u64() % 64;
        Scalar::from_bits((self.next_u64() as i64) >> shift)
    }

    fn u128_any_magnitude(&mut self) -> u128 {
        let bits = self.next_u64() % 129;
        let v = (self.next_u64() as u128) << 64 | self.next_u64() as u128;
        if bits == 0 { 0 } else { v >> (128 - bits) }
    }
}

/// |ours − reference| in ulps of Q32.32.
fn ulps(ours: Scalar, reference: f64) -> f64 {
    (ours.to_bits() as f64 - reference * SCALE).abs()
}

fn edge_scalars() -> Vec<Scalar> {
    let mut v = vec![
        Scalar::ZERO,
        Scalar::DELTA,
        -Scalar::DELTA,
        Scalar::MAX,
        -Scalar::MAX,
        Scalar::MIN,
        Scalar::ONE,
        Scalar::NEG_ONE,
        Scalar::HALF,
        Scalar::PI,
        -Scalar::PI,
        Scalar::FRAC_PI_2,
        Scalar::TAU,
    ];
    for k in 0..63 {
        v.push(Scalar::from_bits(1 << k));
        v.push(Scalar::from_bits(-(1 << k)));
        v.push(Scalar::from_bits((1 << k) - 1));
        v.push(Scalar::from_bits((1i64 << k) + 1));
    }
    v
}

/// The nearest Q32.32 values to k·π/2 (and their neighbours) for k spread
/// over the whole range, where the reduced argument cancels the most.
fn multiples_of_half_pi() -> Vec<Scalar> {
    // π/2 in Q126 (floor), from mpmath: exact enough for k < 2^31.
    const FRAC_PI_2_Q126: i128 = 133_628_573_008_120_843_482_460_046_645_233_847_912;
    let mut ks: Vec<i64> = (-40..=40).collect();
    let mut k = 41i64;
    while k < 1_367_130_551 {
        ks.push(k);
        ks.push(-k);
        k = k * 3 / 2 + 1;
    }
    ks.push(1_367_130_550); // the largest multiple below 2^31
    ks.push(-1_367_130_551);
    let mut out = Vec::new();
    for k in ks {
        // k·π/2·2^32 = k·FRAC_PI_2_Q126 / 2^94, rounded.
        let wide = k as i128 * (FRAC_PI_2_Q126 >> 32); // Q94
        let bits = ((wide + (1 << 61)) >> 62) as i64;
        for d in -2..=2 {
            out.push(Scalar::from_bits(bits.saturating_add(d)));
        }
    }
    out
}

/// sin x and cos x in `f64` for any Q32.32 `x`, accurate to ~2⁻⁵⁰ absolute.
///
/// Cody–Waite reduction with π/2 cut into 22-bit pieces P1..P3 (plus a
/// tail), so that each `k·Pi` (|k| < 2³¹) is exact in `f64`; x is split
/// into its integer part and its 32-bit fraction, both exact in `f64`.
/// Every subtraction but the last two is then exact (the operands are
/// multiples of 2⁻⁴³ and the differences small), so only ~2⁻⁵² of rounding
/// enters the reduced argument.
fn reference_sin_cos(x: Scalar) -> (f64, f64) {
    const V: u128 = 133_628_573_008_120_843_482_460_046_645_233_847_912; // π/2·2^126
    const MASK: u128 = (1 << 22) - 1;
    let p1 = (V >> 105) as f64 / 2f64.powi(21);
    let p2 = ((V >> 83) & MASK) as f64 / 2f64.powi(43);
    let p3 = ((V >> 61) & MASK) as f64 / 2f64.powi(65);
    let p4 = (V & ((1 << 61) - 1)) as f64 / 2f64.powi(126);
    let bits = x.to_bits();
    let int_part = (bits >> 32) as f64;
    let frac = (bits & 0xFFFF_FFFF) as f64 / SCALE;
    let k = ((bits as f64 / SCALE) * std::f64::consts::FRAC_2_PI).round();
    let r = (((int_part - k * p1) - k * p2) + frac) - k * p3 - k * p4;
    let (s, c) = r.sin_cos();
    match (k as i64).rem_euclid(4) {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

#[test]
fn isqrt_u128_is_the_exact_floor_for_random_and_edge_inputs() {
    let mut rng = Rng::new(1);
    let mut inputs: Vec<u128> = (0..200_000).map(|_| rng.u128_any_magnitude()).collect();
    inputs.extend([0, 1, 2, 3, 4, 5, 8, 9, 15, 16, 17, u128::MAX, u128::MAX - 1]);
    for k in 0..128 {
        let p = 1u128 << k;
        inputs.extend([p, p - 1, p + 1]);
    }
    // Perfect squares and their neighbours, including (2^64 − 1)².
    for _ in 0..50_000 {
        let r = (rng.next_u64() >> (rng.next_u64() % 64)) as u128;
        let sq = r * r;
        inputs.extend([sq, sq.saturating_sub(1), sq + 1]);
    }
    let top = (u64::MAX as u128) * (u64::MAX as u128);
    inputs.extend([top, top - 1, top + 1]);
    for &n in &inputs {
        assert_eq!(elem::isqrt_u128(n) as u128, n.isqrt(), "isqrt({n})");
    }
    assert!(inputs.len() > 300_000);
}

#[test]
fn sqrt_is_the_exact_floor_and_under_one_ulp_from_f64() {
    let mut rng = Rng::new(2);
    let mut worst = 0.0f64;
    let mut inputs: Vec<Scalar> = (0..200_000).map(|_| rng.scalar().abs()).collect();
    inputs.extend(edge_scalars().into_iter().filter(|x| !x.is_negative()));
    for &x in &inputs {
        let ((r, faults), bits) = (FaultScope::run(|| elem::sqrt(x)), x.to_bits());
        assert!(faults.is_empty());
        // Exact floor: r² ≤ x·2^32 < (r+1)² in integers.
        let n = (bits as u128) << 32;
        let r_int = r.to_bits() as u128;
        assert!(
            r_int * r_int <= n && (r_int + 1) * (r_int + 1) > n,
            "sqrt({x})"
        );
        let err = r.to_bits() as f64 - x.to_f64().sqrt() * SCALE;
        // The floor is never above the root (allow f64's own rounding).
        assert!(err <= 1e-3, "sqrt({x}) above the root by {err}");
        worst = worst.max(-err);
    }
    eprintln!(
        "sqrt: max error {worst:.7} ulp over {} inputs",
        inputs.len()
    );
    // The exact check above is the bound (< 1 ulp); f64 sees results of up
    // to 47 bits with 6 bits to spare.
    assert!(worst <= 1.0 + 1.0 / 32.0);
}

#[test]
fn sqrt_of_a_negative_is_zero_and_a_domain_fault() {
    for x in [-Scalar::DELTA, Scalar::NEG_ONE, Scalar::MIN] {
        let (r, faults) = FaultScope::run(|| elem::sqrt(x));
        assert_eq!(r, Scalar::ZERO);
        assert_eq!(faults, Faults::DOMAIN);
    }
    assert_eq!(elem::sqrt(Scalar::from_int(4)), Scalar::TWO);
    assert_eq!(elem::sqrt(Scalar::DELTA), Scalar::from_bits(1 << 16));
    // √(2^31 − 2^-32) = 46340.95...: floor of the exact root.
    assert_eq!(elem::sqrt(Scalar::MAX).to_bits(), 199_032_864_766_430);
}

#[test]
fn rsqrt_is_correctly_rounded_everywhere() {
    let mut rng = Rng::new(3);
    let mut worst = 0.0f64;
    let mut inputs: Vec<Scalar> = (0..200_000)
        .map(|_| rng.scalar().abs().max(Scalar::DELTA))
        .collect();
    inputs.extend(edge_scalars().into_iter().filter(|x| x.is_positive()));
    for &x in &inputs {
        let (q, faults) = FaultScope::run(|| elem::rsqrt(x));
        assert!(faults.is_empty());
        // q = round(2^48/√b) ⇔ (2q−1)²·b < 2^98 < (2q+1)²·b, in integers.
        let (b, q) = (x.to_bits() as u128, q.to_bits() as u128);
        assert!(
            (2 * q - 1) * (2 * q - 1) * b < 1 << 98 && (2 * q + 1) * (2 * q + 1) * b > 1 << 98,
            "rsqrt({x}) = {q} is not the nearest"
        );
        worst = worst.max(ulps(elem::rsqrt(x), 1.0 / x.to_f64().sqrt()));
    }
    eprintln!(
        "rsqrt: max error {worst:.7} ulp over {} inputs",
        inputs.len()
    );
    // f64 holds the up-to-49-bit results with 4 bits to spare.
    assert!(worst <= 0.5 + 1.0 / 16.0);
}

#[test]
fn rsqrt_of_zero_or_negative_is_max_and_a_domain_fault() {
    for x in [Scalar::ZERO, -Scalar::DELTA, Scalar::MIN] {
        let (r, faults) = FaultScope::run(|| elem::rsqrt(x));
        assert_eq!(r, Scalar::MAX);
        assert_eq!(faults, Faults::DOMAIN);
    }
    assert_eq!(elem::rsqrt(Scalar::ONE), Scalar::ONE);
    assert_eq!(elem::rsqrt(Scalar::from_int(4)), Scalar::HALF);
    assert_eq!(elem::rsqrt(Scalar::DELTA), Scalar::from_bits(1 << 48));
    // 1/√(2^31 − 2^-32) = 2^-15.5 = 2.157918643... e-5 → 92681.9 ulps.
    assert_eq!(elem::rsqrt(Scalar::MAX), Scalar::from_bits(92_682));
}

#[test]
fn sin_cos_are_within_half_an_ulp_over_the_whole_range() {
    let mut rng = Rng::new(4);
    let mut inputs: Vec<Scalar> = (0..300_000).map(|_| rng.scalar()).collect();
    inputs.extend(edge_scalars());
    inputs.extend(multiples_of_half_pi());
    let (mut worst_s, mut worst_c) = (0.0f64, 0.0f64);
    let mut worst_small = 0.0f64;
    for &x in &inputs {
        let ((s, c), faults) = FaultScope::run(|| elem::sin_cos(x));
        assert!(faults.is_empty(), "sin_cos({x}) raised {faults}");
        let (rs, rc) = reference_sin_cos(x);
        worst_s = worst_s.max(ulps(s, rs));
        worst_c = worst_c.max(ulps(c, rc));
        assert_eq!(elem::sin(x), s);
        assert_eq!(elem::cos(x), c);
        // Where x is exact in f64, compare with the library directly too.
        if x.to_bits().unsigned_abs() < 1 << 53 {
            let (fs, fc) = x.to_f64().sin_cos();
            worst_small = worst_small.max(ulps(s, fs)).max(ulps(c, fc));
        }
    }
    eprintln!(
        "sin_cos over {} inputs: sin {worst_s:.7} ulp, cos {worst_c:.7} ulp, |x| < 2^21 vs f64 \
         directly {worst_small:.7} ulp",
        inputs.len()
    );
    assert!(worst_s <= 0.50001 && worst_c <= 0.50001);
    assert!(worst_small <= 0.50001);
}

#[test]
fn sin_is_odd_and_cos_even_bit_for_bit() {
    let mut rng = Rng::new(5);
    for _ in 0..100_000 {
        let x = rng.scalar();
        if x == Scalar::MIN {
            continue;
        }
        let (s, c) = elem::sin_cos(x);
        let (sn, cn) = elem::sin_cos(-x);
        assert_eq!((sn, cn), (-s, c), "x = {x}");
    }
}

#[test]
fn sin_cos_hit_exact_values_at_quadrant_points() {
    assert_eq!(elem::sin_cos(Scalar::ZERO), (Scalar::ZERO, Scalar::ONE));
    // π/2 rounded is 2.3e-11 below... sin is 1 to the last bit, cos the
    // (tiny) offset.
    let (s, c) = elem::sin_cos(Scalar::FRAC_PI_2);
    assert_eq!(s, Scalar::ONE);
    assert!(c.to_bits().abs() <= 1);
    let (s, c) = elem::sin_cos(Scalar::PI);
    assert!(s.to_bits().abs() <= 1);
    assert_eq!(c, Scalar::NEG_ONE);
    // The extremes of the range must not panic or fault, and agree with the
    // exact reference.
    for x in [Scalar::MAX, Scalar::MIN] {
        let ((s, c), faults) = FaultScope::run(|| elem::sin_cos(x));
        assert!(faults.is_empty());
        let (rs, rc) = reference_sin_cos(x);
        assert!(ulps(s, rs) <= 0.50001 && ulps(c, rc) <= 0.50001, "{x}");
    }
}

#[test]
fn atan2_is_within_half_an_ulp_in_every_quadrant() {
    let mut rng = Rng::new(6);
    let edges = edge_scalars();
    let mut pairs: Vec<(Scalar, Scalar)> =
        (0..300_000).map(|_| (rng.scalar(), rng.scalar())).collect();
    for &a in &edges {
        for &b in &edges {
            pairs.push((a, b));
        }
    }
    let mut worst = 0.0f64;
    for &(y, x) in &pairs {
        let (a, faults) = FaultScope::run(|| elem::atan2(y, x));
        assert!(faults.is_empty(), "atan2({y}, {x}) raised {faults}");
        assert!(a >= -Scalar::PI && a <= Scalar::PI, "atan2({y}, {x}) = {a}");
        worst = worst.max(ulps(a, y.to_f64().atan2(x.to_f64())));
    }
    eprintln!("atan2: max error {worst:.7} ulp over {} pairs", pairs.len());
    assert!(worst <= 0.50001);
}

#[test]
fn atan2_special_cases() {
    let (a, faults) = FaultScope::run(|| elem::atan2(Scalar::ZERO, Scalar::ZERO));
    assert_eq!((a, faults), (Scalar::ZERO, Faults::NONE));
    assert_eq!(elem::atan2(Scalar::ZERO, Scalar::NEG_ONE), Scalar::PI);
    assert_eq!(elem::atan2(Scalar::ZERO, Scalar::MIN), Scalar::PI);
    assert_eq!(elem::atan2(Scalar::ONE, Scalar::ZERO), Scalar::FRAC_PI_2);
    assert_eq!(
        elem::atan2(Scalar::NEG_ONE, Scalar::ZERO),
        -Scalar::FRAC_PI_2
    );
    assert_eq!(elem::atan2(Scalar::ZERO, Scalar::ONE), Scalar::ZERO);
    // Just below the negative x axis: the angle approaches −π from above.
    assert_eq!(elem::atan2(-Scalar::DELTA, Scalar::MIN), -Scalar::PI);
    // Odd in y, bit for bit (except y = 0, where −π is never returned).
    let mut rng = Rng::new(7);
    for _ in 0..100_000 {
        let (y, x) = (rng.scalar(), rng.scalar());
        if y != Scalar::MIN && y != Scalar::ZERO {
            assert_eq!(elem::atan2(-y, x), -elem::atan2(y, x));
        }
    }
}

#[test]
fn atan_is_within_half_an_ulp() {
    let mut rng = Rng::new(8);
    let mut inputs: Vec<Scalar> = (0..200_000).map(|_| rng.scalar()).collect();
    inputs.extend(edge_scalars());
    let mut worst = 0.0f64;
    for &x in &inputs {
        let (a, faults) = FaultScope::run(|| elem::atan(x));
        assert!(faults.is_empty());
        worst = worst.max(ulps(a, x.to_f64().atan()));
    }
    eprintln!(
        "atan: max error {worst:.7} ulp over {} inputs",
        inputs.len()
    );
    assert!(worst <= 0.50001);
    assert_eq!(elem::atan(Scalar::ONE), Scalar::from_bits(3_373_259_426)); // π/4
}

#[test]
fn asin_and_acos_are_within_half_an_ulp_up_to_the_ends() {
    let mut rng = Rng::new(9);
    let one = 1i64 << 32;
    let mut inputs: Vec<Scalar> = Vec::new();
    for _ in 0..100_000 {
        // Uniform over [-1, 1] ...
        inputs.push(Scalar::from_bits(
            (rng.next_u64() % (2 * one as u64 + 1)) as i64 - one,
        ));
        // ... and bunched toward ±1 and 0, where the slopes differ most.
        let d = ((rng.next_u64() >> (rng.next_u64() % 64)) % (one as u64)) as i64;
        inputs.push(Scalar::from_bits(one - d));
        inputs.push(Scalar::from_bits(d - one));
        inputs.push(Scalar::from_bits(d >> 16));
    }
    inputs.extend(
        edge_scalars()
            .into_iter()
            .filter(|x| x.to_bits().unsigned_abs() <= 1 << 32),
    );
    let (mut worst_s, mut worst_c) = (0.0f64, 0.0f64);
    for &x in &inputs {
        let ((s, c), faults) = FaultScope::run(|| (elem::asin(x), elem::acos(x)));
        assert!(faults.is_empty(), "{x}");
        worst_s = worst_s.max(ulps(s, x.to_f64().asin()));
        worst_c = worst_c.max(ulps(c, x.to_f64().acos()));
    }
    eprintln!(
        "asin {worst_s:.7} ulp, acos {worst_c:.7} ulp over {} inputs",
        inputs.len()
    );
    assert!(worst_s <= 0.50001 && worst_c <= 0.50001);
}

#[test]
fn asin_and_acos_clamp_out_of_range_inputs_and_raise_domain() {
    for (x, asin, acos) in [
        (
            Scalar::from_bits((1 << 32) + 1),
            Scalar::FRAC_PI_2,
            Scalar::ZERO,
        ),
        (Scalar::MAX, Scalar::FRAC_PI_2, Scalar::ZERO),
        (Scalar::from_int(-2), -Scalar::FRAC_PI_2, Scalar::PI),
        (Scalar::MIN, -Scalar::FRAC_PI_2, Scalar::PI),
    ] {
        assert_eq!(FaultScope::run(|| elem::asin(x)), (asin, Faults::DOMAIN));
        assert_eq!(FaultScope::run(|| elem::acos(x)), (acos, Faults::DOMAIN));
    }
    // ±1 exactly are in the domain.
    assert_eq!(
        FaultScope::run(|| elem::asin(Scalar::ONE)),
        (Scalar::FRAC_PI_2, Faults::NONE)
    );
    assert_eq!(
        FaultScope::run(|| elem::acos(Scalar::NEG_ONE)),
        (Scalar::PI, Faults::NONE)
    );
}

#[test]
fn results_are_bit_identical_to_the_reference_digest() {
    // Determinism pin: an FNV-1a digest of every function's result bits over
    // 300,000 pseudo-random inputs. The value was produced on x86_64 and
    // checked identical on i686 and aarch64 (under qemu). A change here
    // changes simulation results, and so replays and the wire protocol:
    // update it only on purpose, after checking every target.
    let mut rng = Rng::new(0x1234_5678);
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut mix = |v: u64| {
        h ^= v;
        h = h.wrapping_mul(0x0100_0000_01b3);
    };
    for _ in 0..300_000 {
        let (a, b, sh) = (rng.next_u64(), rng.next_u64(), rng.next_u64() % 64);
        let x = Scalar::from_bits((a as i64) >> sh);
        let y = Scalar::from_bits((b as i64) >> (b % 64));
        let n = ((a as u128) << 64 | b as u128) >> (rng.next_u64() % 128);
        mix(elem::isqrt_u128(n));
        mix(elem::sqrt(x).to_bits() as u64);
        mix(elem::rsqrt(x).to_bits() as u64);
        let (s, c) = elem::sin_cos(x);
        mix(s.to_bits() as u64);
        mix(c.to_bits() as u64);
        mix(elem::atan2(y, x).to_bits() as u64);
        mix(elem::atan(x).to_bits() as u64);
        let u = Scalar::from_bits(((a as i64) >> 31).clamp(-(1 << 32), 1 << 32));
        mix(elem::asin(u).to_bits() as u64);
        mix(elem::acos(u).to_bits() as u64);
    }
    assert_eq!(h, 0x7191_5486_cdd3_c7cb);
}
