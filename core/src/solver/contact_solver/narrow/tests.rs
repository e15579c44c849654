use super::*;

#[test]
fn rounding_is_to_nearest_ties_up() {
    assert_eq!(rsh(5, 1), 3);
    assert_eq!(rsh(-5, 1), -2);
    assert_eq!(rsh(6, 2), 2);
    assert_eq!(rsh(-6, 2), -1);
    assert_eq!(rsh(-7, 2), -2);
    // Q32.32 to quanta: 2⁻²⁰ m/s is 4096 bits.
    assert_eq!(quanta(Scalar::from_bits(4096)), 1);
    assert_eq!(quanta(Scalar::from_bits(2048)), 1);
    assert_eq!(quanta(Scalar::from_bits(2047)), 0);
    assert_eq!(quanta(Scalar::from_bits(-2048)), 0);
    assert_eq!(quanta(Scalar::from_bits(-2049)), -1);
    assert_eq!(quanta(Scalar::MAX), 1 << 51);
    assert_eq!(quanta(Scalar::MIN), -(1 << 51));
}

#[test]
fn the_disc_keeps_inside_and_scales_outside_onto_it() {
    let mass = [1 << 30, 1 << 29];
    assert_eq!(clamp_to_disc([3, -4], &mass, 10 << 30), [3, -4]);
    let want = [1_000_000, -2_000_000];
    let limit = 500_000i64 << 30;
    let q = clamp_to_disc(want, &mass, limit);
    let l = |w: i64, m: i32| (w * m as i64) as f64;
    let len = (l(q[0], mass[0]).powi(2) + l(q[1], mass[1]).powi(2)).sqrt();
    // Within the truncation of each component (about 3e-6 here).
    assert!(
        len <= limit as f64 && len >= limit as f64 * (1.0 - 1e-5),
        "{q:?}"
    );
    assert!(q[0] > 0 && q[1] < 0 && q[0] <= want[0] && q[1] >= want[1]);
    assert_eq!(clamp_to_disc(want, &mass, 0), [0, 0]);
}
