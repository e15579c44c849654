//! The `math` suite: our Q32.32 arithmetic and elementary functions against
//! `f64` (what a float engine pays), the `fixed` crate's `I32F32` (what a
//! naive fixed-point engine pays) and, for sine/cosine and atan2, the
//! `cordic` crate.
//!
//! Every operation gets its own precomputed inputs in a range where all the
//! implementations are valid (e.g. `cordic::sin_cos` reduces its argument
//! with a loop, so angles stay within ±8; divisors stay away from zero), and
//! the same values are fed to ours and to the references.

use fixed::types::I32F32;
use lockstep_core::math::lanes;
use lockstep_core::math::{Scalar, Vec3, elem};

use crate::harness::{Budget, Rng, Row, ns_per_op};

/// Inputs per array: 4096 values of up to 48 bytes stay in L1/L2.
const N: usize = 4096;

fn scalars(rng: &mut Rng, lo: f64, hi: f64) -> Vec<Scalar> {
    (0..N)
        .map(|_| Scalar::from_f64_lossy(rng.uniform(lo, hi)))
        .collect()
}

/// Positive values spread evenly over every magnitude from 2⁻³² to 2³¹.
fn positive_any_magnitude(rng: &mut Rng) -> Vec<Scalar> {
    (0..N)
        .map(|_| {
            let shift = rng.next_u64() % 63;
            Scalar::from_bits(((rng.next_u64() >> 1) >> shift).max(1) as i64)
        })
        .collect()
}

fn to_f64(v: &[Scalar]) -> Vec<f64> {
    v.iter().map(|s| s.to_f64()).collect()
}

fn to_fixed(v: &[Scalar]) -> Vec<I32F32> {
    v.iter().map(|s| s.to_fixed()).collect()
}

fn zip<A: Copy, B: Copy>(a: &[A], b: &[B]) -> Vec<(A, B)> {
    a.iter().copied().zip(b.iter().copied()).collect()
}

/// Runs the suite with the given budget and returns one row per
/// (operation, reference) pair.
pub fn run(budget: Budget) -> Vec<Row> {
    let mut rng = Rng::new(0x5EED_0001);
    let mut rows = Vec::new();

    // mul and div: operands within ±1000 (products fit), divisors ≥ 0.01.
    let a = scalars(&mut rng, -1000.0, 1000.0);
    let b = scalars(&mut rng, -1000.0, 1000.0);
    let d: Vec<Scalar> = scalars(&mut rng, 0.01, 1000.0)
        .into_iter()
        .enumerate()
        .map(|(i, v)| if i % 2 == 0 { v } else { -v })
        .collect();
    let (af, bf, df) = (to_f64(&a), to_f64(&b), to_f64(&d));
    let (ax, bx, dx) = (to_fixed(&a), to_fixed(&b), to_fixed(&d));
    let ours = ns_per_op(budget, &zip(&a, &b), |(x, y)| x * y);
    rows.push(Row::new(
        "mul",
        ours,
        "f64 *",
        ns_per_op(budget, &zip(&af, &bf), |(x, y)| x * y),
    ));
    rows.push(Row::new(
        "mul",
        ours,
        "I32F32 *",
        ns_per_op(budget, &zip(&ax, &bx), |(x, y)| x * y),
    ));
    // The contact solver's product (ties toward +∞) over arrays, eight at
    // once on the IFMA lanes against their scalar twin: ns per product.
    // Chunks of 512 products per call, as a wide kernel would take a run
    // of constraints of one colour.
    const CHUNK: usize = 512;
    let starts: Vec<usize> = (0..N / CHUNK).map(|k| k * CHUNK).collect();
    let mut out = vec![Scalar::ZERO; N];
    let mut per_product = |lanes: bool| {
        ns_per_op(budget, &starts, |i| {
            let r = i..i + CHUNK;
            lanes::mul_slice(&a[r.clone()], &b[r.clone()], &mut out[r], lanes)
        }) / CHUNK as f64
    };
    let (wide, twin) = (per_product(true), per_product(false));
    rows.push(Row::new(
        if lanes::ifma_available() {
            "mul on IFMA lanes"
        } else {
            "mul lanes (no IFMA)"
        },
        wide,
        "scalar twin",
        twin,
    ));
    let ours = ns_per_op(budget, &zip(&a, &d), |(x, y)| x / y);
    rows.push(Row::new(
        "div",
        ours,
        "f64 /",
        ns_per_op(budget, &zip(&af, &df), |(x, y)| x / y),
    ));
    rows.push(Row::new(
        "div",
        ours,
        "I32F32 /",
        ns_per_op(budget, &zip(&ax, &dx), |(x, y)| x / y),
    ));

    // isqrt_u128: every bit length from 0 to 128.
    let wide: Vec<u128> = (0..N)
        .map(|_| {
            let bits = rng.next_u64() % 129;
            let v = (rng.next_u64() as u128) << 64 | rng.next_u64() as u128;
            if bits == 0 { 0 } else { v >> (128 - bits) }
        })
        .collect();
    rows.push(Row::new(
        "isqrt_u128",
        ns_per_op(budget, &wide, elem::isqrt_u128),
        "u128::isqrt",
        ns_per_op(budget, &wide, u128::isqrt),
    ));

    // sqrt and rsqrt: positive values of every magnitude.
    let p = positive_any_magnitude(&mut rng);
    let (pf, px) = (to_f64(&p), to_fixed(&p));
    let ours = ns_per_op(budget, &p, elem::sqrt);
    rows.push(Row::new(
        "sqrt",
        ours,
        "f64::sqrt",
        ns_per_op(budget, &pf, f64::sqrt),
    ));
    rows.push(Row::new(
        "sqrt",
        ours,
        "I32F32::sqrt",
        ns_per_op(budget, &px, I32F32::sqrt),
    ));
    let ours = ns_per_op(budget, &p, elem::rsqrt);
    rows.push(Row::new(
        "rsqrt",
        ours,
        "1/f64::sqrt",
        ns_per_op(budget, &pf, |x| 1.0 / x.sqrt()),
    ));
    rows.push(Row::new(
        "rsqrt",
        ours,
        "1/I32F32::sqrt",
        ns_per_op(budget, &px, |x| I32F32::ONE / x.sqrt()),
    ));

    // sin_cos: angles within ±8 rad (cordic reduces by looping).
    let t = scalars(&mut rng, -8.0, 8.0);
    let (tf, tx) = (to_f64(&t), to_fixed(&t));
    let ours = ns_per_op(budget, &t, elem::sin_cos);
    rows.push(Row::new(
        "sin_cos",
        ours,
        "f64::sin_cos",
        ns_per_op(budget, &tf, f64::sin_cos),
    ));
    rows.push(Row::new(
        "sin_cos",
        ours,
        "cordic::sin_cos",
        ns_per_op(budget, &tx, cordic::sin_cos::<I32F32>),
    ));

    // atan2: both coordinates within ±1000, x at least 0.001 from zero so
    // cordic's y/x stays in range.
    let y = scalars(&mut rng, -1000.0, 1000.0);
    let x: Vec<Scalar> = scalars(&mut rng, 0.001, 1000.0)
        .into_iter()
        .enumerate()
        .map(|(i, v)| if i % 3 == 0 { -v } else { v })
        .collect();
    let (yf, xf, yx, xx) = (to_f64(&y), to_f64(&x), to_fixed(&y), to_fixed(&x));
    let ours = ns_per_op(budget, &zip(&y, &x), |(y, x)| elem::atan2(y, x));
    rows.push(Row::new(
        "atan2",
        ours,
        "f64::atan2",
        ns_per_op(budget, &zip(&yf, &xf), |(y, x)| y.atan2(x)),
    ));
    rows.push(Row::new(
        "atan2",
        ours,
        "cordic::atan2",
        ns_per_op(budget, &zip(&yx, &xx), |(y, x)| cordic::atan2(y, x)),
    ));

    // asin: the whole domain.
    let s = scalars(&mut rng, -1.0, 1.0);
    rows.push(Row::new(
        "asin",
        ns_per_op(budget, &s, elem::asin),
        "f64::asin",
        ns_per_op(budget, &to_f64(&s), f64::asin),
    ));

    // Vec3::try_normalize: components within ±1000.
    let c = [
        scalars(&mut rng, -1000.0, 1000.0),
        scalars(&mut rng, -1000.0, 1000.0),
        scalars(&mut rng, -1000.0, 1000.0),
    ];
    let v: Vec<Vec3> = (0..N)
        .map(|i| Vec3::new(c[0][i], c[1][i], c[2][i]))
        .collect();
    let vf: Vec<[f64; 3]> = v
        .iter()
        .map(|v| [v.x.to_f64(), v.y.to_f64(), v.z.to_f64()])
        .collect();
    rows.push(Row::new(
        "Vec3::try_normalize",
        ns_per_op(budget, &v, Vec3::try_normalize),
        "[f64; 3] normalize",
        ns_per_op(budget, &vf, normalize_f64),
    ));

    rows
}

/// The float version of `Vec3::try_normalize`, as a float engine writes it.
fn normalize_f64(v: [f64; 3]) -> Option<[f64; 3]> {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if len == 0.0 {
        None
    } else {
        let inv = 1.0 / len;
        Some([v[0] * inv, v[1] * inv, v[2] * inv])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suite_measures_every_operation_against_its_references() {
        let rows = run(Budget::QUICK);
        let ops: Vec<&str> = rows.iter().map(|r| r.op.as_str()).collect();
        for op in [
            "mul",
            "div",
            "isqrt_u128",
            "sqrt",
            "rsqrt",
            "sin_cos",
            "atan2",
            "Vec3::try_normalize",
        ] {
            assert!(ops.contains(&op), "missing {op}");
        }
        assert!(
            ops.iter()
                .any(|op| op.starts_with("mul on IFMA lanes") || op.starts_with("mul lanes")),
            "missing the lanes row"
        );
        assert_eq!(rows.len(), 16);
        assert!(
            rows.iter()
                .all(|r| r.ours_ns.is_finite() && r.reference_ns.is_finite())
        );
    }

    #[test]
    fn float_normalize_reference_gives_a_unit_vector() {
        let n = normalize_f64([3.0, 0.0, 4.0]).unwrap();
        for (got, want) in n.iter().zip([0.6, 0.0, 0.8]) {
            assert!((got - want).abs() < 1e-15, "{n:?}");
        }
        assert_eq!(normalize_f64([0.0; 3]), None);
    }
}
