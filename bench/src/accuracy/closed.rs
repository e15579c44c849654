//! The closed forms and exact invariants the `accuracy` cases measure
//! against, in plain `f64` and independent of every engine: nothing here
//! reads a simulation.

use super::sim::ShapeSpec;

/// Standard gravity used by every case, m/s².
pub const G: f64 = 9.81;

/// Volume of a shape, m³.
pub fn volume(shape: ShapeSpec) -> f64 {
    match shape {
        ShapeSpec::Sphere(r) => 4.0 / 3.0 * std::f64::consts::PI * r * r * r,
        ShapeSpec::Cuboid([x, y, z]) => 8.0 * x * y * z,
        ShapeSpec::Capsule(h, r) => std::f64::consts::PI * r * r * (2.0 * h + 4.0 / 3.0 * r),
        ShapeSpec::Octahedron(r) => 4.0 / 3.0 * r * r * r,
    }
}

/// Principal moments of inertia about the centre, body axes, kg·m²: a solid
/// sphere `2/5 m r²`; a box `m/3 (b² + c²)` from half-extents; a capsule as
/// its cylinder plus two hemispheres (each `83/320 m r²` about its own
/// centroid, `h + 3r/8` from the centre); a regular octahedron `m r²/5`.
pub fn inertia(shape: ShapeSpec, mass: f64) -> [f64; 3] {
    match shape {
        ShapeSpec::Sphere(r) => [0.4 * mass * r * r; 3],
        ShapeSpec::Cuboid([x, y, z]) => [
            mass / 3.0 * (y * y + z * z),
            mass / 3.0 * (x * x + z * z),
            mass / 3.0 * (x * x + y * y),
        ],
        ShapeSpec::Capsule(h, r) => {
            let cyl = 2.0 * h * r * r;
            let hemi = 2.0 / 3.0 * r * r * r;
            let (mc, mh) = (
                mass * cyl / (cyl + 2.0 * hemi),
                mass * hemi / (cyl + 2.0 * hemi),
            );
            let axial = mc * r * r / 2.0 + 2.0 * 0.4 * mh * r * r;
            let d = h + 3.0 * r / 8.0;
            let across =
                mc * (r * r / 4.0 + h * h / 3.0) + 2.0 * mh * (83.0 / 320.0 * r * r + d * d);
            [across, axial, across]
        }
        ShapeSpec::Octahedron(r) => [mass * r * r / 5.0; 3],
    }
}

/// Position under constant acceleration: `p0 + v0 t + ½ a t²`.
pub fn projectile(p0: [f64; 3], v0: [f64; 3], a: [f64; 3], t: f64) -> [f64; 3] {
    std::array::from_fn(|k| p0[k] + v0[k] * t + 0.5 * a[k] * t * t)
}

/// How far a box sliding at `v` stops on a level floor: `v²/(2μg)`.
pub fn stop_distance(v: f64, mu: f64) -> f64 {
    v * v / (2.0 * mu * G)
}

/// Acceleration of a box on a slope of `theta` radians: `g(sinθ − μcosθ)`
/// when it slides (`tanθ > μ`), zero when static friction holds it.
pub fn ramp_acceleration(theta: f64, mu: f64) -> f64 {
    if theta.tan() > mu {
        G * (theta.sin() - mu * theta.cos())
    } else {
        0.0
    }
}

/// Acceleration of a solid sphere rolling without slipping down a slope:
/// `5/7 g sinθ` (valid while `μ ≥ 2/7 tanθ`).
pub fn rolling_acceleration(theta: f64) -> f64 {
    5.0 / 7.0 * G * theta.sin()
}

/// A solid sphere launched sliding at `v0` without spin on a level floor:
/// kinetic friction `μg` slows it and spins it up until `v = ωr` at
/// `t* = 2v0/(7μg)`, after which it rolls at `5/7 v0`. Returns the distance
/// travelled and the speed at time `t`.
pub fn slide_to_roll(v0: f64, mu: f64, t: f64) -> (f64, f64) {
    let a = mu * G;
    let t_star = 2.0 * v0 / (7.0 * a);
    if t <= t_star {
        (v0 * t - 0.5 * a * t * t, v0 - a * t)
    } else {
        let x_star = v0 * t_star - 0.5 * a * t_star * t_star;
        let v_roll = v0 - a * t_star;
        (x_star + v_roll * (t - t_star), v_roll)
    }
}

/// Time for a body dropped from rest to fall `h`: `√(2h/g)`.
pub fn fall_time(h: f64) -> f64 {
    (2.0 * h / G).sqrt()
}

/// The period of a physical pendulum: a rigid body of mass `m` and
/// moment of inertia `i_pivot` about its pivot, its centre of mass `l`
/// below the pivot, released from rest at `theta0` rad. Exact at any
/// amplitude: `4·√(I/(m g l))·K(sin(θ₀/2))`, with the complete elliptic
/// integral of the first kind `K(k) = π / (2·AGM(1, √(1 − k²)))`.
pub fn pendulum_period(i_pivot: f64, m: f64, l: f64, theta0: f64) -> f64 {
    let k = (theta0 / 2.0).sin();
    let (mut a, mut b) = (1.0f64, (1.0 - k * k).sqrt());
    // The AGM converges quadratically: a dozen rounds reach f64's last bit
    // (a tolerance test could miss by an ulp and loop for ever).
    for _ in 0..12 {
        (a, b) = ((a + b) / 2.0, (a * b).sqrt());
    }
    let elliptic_k = std::f64::consts::PI / (2.0 * a);
    4.0 * (i_pivot / (m * G * l)).sqrt() * elliptic_k
}

/// Velocities after a 1-D collision of masses `m1`, `m2` at `u1`, `u2` with
/// restitution `e` (momentum conserved, relative speed scaled by `e`).
pub fn collision_1d(m1: f64, u1: f64, m2: f64, u2: f64, e: f64) -> (f64, f64) {
    let p = m1 * u1 + m2 * u2;
    let m = m1 + m2;
    let v1 = (p + m2 * e * (u2 - u1)) / m;
    let v2 = (p + m1 * e * (u1 - u2)) / m;
    (v1, v2)
}

/// Rotates `v` by the unit quaternion `q = [x, y, z, w]`.
pub fn rotate(q: [f64; 4], v: [f64; 3]) -> [f64; 3] {
    let [x, y, z, w] = q;
    let u = [x, y, z];
    let t = cross(u, v).map(|c| 2.0 * c);
    let ut = cross(u, t);
    std::array::from_fn(|k| v[k] + w * t[k] + ut[k])
}

/// Rotates `v` by the inverse of `q`.
pub fn inverse_rotate(q: [f64; 4], v: [f64; 3]) -> [f64; 3] {
    rotate([-q[0], -q[1], -q[2], q[3]], v)
}

/// The cross product.
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The dot product.
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The Euclidean length.
pub fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// `a − b`.
pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|k| a[k] - b[k])
}

/// A rigid body's angular momentum about its centre (world axes) and its
/// rotational kinetic energy, from its orientation and world angular
/// velocity and the closed-form principal inertia (body axes principal):
/// `L = R I Rᵀ ω`, `E = ½ ω·L`.
pub fn angular_momentum_energy(q: [f64; 4], omega: [f64; 3], inertia: [f64; 3]) -> ([f64; 3], f64) {
    let wb = inverse_rotate(q, omega);
    let lb = std::array::from_fn(|k| inertia[k] * wb[k]);
    let l = rotate(q, lb);
    (l, 0.5 * dot(omega, l))
}

/// Euler's equations for a torque-free body in body axes:
/// `I₁ ω̇₁ = (I₂ − I₃) ω₂ ω₃` and cyclic.
fn euler_rate(i: [f64; 3], w: [f64; 3]) -> [f64; 3] {
    [
        (i[1] - i[2]) * w[1] * w[2] / i[0],
        (i[2] - i[0]) * w[2] * w[0] / i[1],
        (i[0] - i[1]) * w[0] * w[1] / i[2],
    ]
}

/// The reference for the torque-free cases: the body-axis angular velocity
/// of a free body integrated with classical RK4 at `steps_per_second`
/// (far finer than any engine step), sampled once per `1/rate` s for
/// `seconds`. The first sample is `w0`.
pub fn torque_free_reference(
    inertia: [f64; 3],
    w0: [f64; 3],
    seconds: f64,
    rate: u32,
    steps_per_second: u32,
) -> Vec<[f64; 3]> {
    let samples = (seconds * rate as f64).round() as usize;
    let per_sample = (steps_per_second / rate).max(1);
    let h = 1.0 / (rate as f64 * per_sample as f64);
    let mut w = w0;
    let mut out = Vec::with_capacity(samples + 1);
    out.push(w);
    for _ in 0..samples {
        for _ in 0..per_sample {
            let k1 = euler_rate(inertia, w);
            let k2 = euler_rate(inertia, std::array::from_fn(|k| w[k] + 0.5 * h * k1[k]));
            let k3 = euler_rate(inertia, std::array::from_fn(|k| w[k] + 0.5 * h * k2[k]));
            let k4 = euler_rate(inertia, std::array::from_fn(|k| w[k] + h * k3[k]));
            w = std::array::from_fn(|k| {
                w[k] + h / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k])
            });
        }
        out.push(w);
    }
    out
}

/// Sign changes along a sampled series (zeros skipped) (how often a
/// spin about the intermediate axis flips).
pub fn sign_changes(series: impl IntoIterator<Item = f64>) -> u32 {
    let mut last = 0.0f64;
    let mut flips = 0;
    for x in series {
        let sign = if x > 0.0 {
            1.0
        } else if x < 0.0 {
            -1.0
        } else {
            0.0
        };
        if sign != 0.0 {
            if last != 0.0 && sign != last {
                flips += 1;
            }
            last = sign;
        }
    }
    flips
}

/// Relative error `|measured − expected| / |expected|` (absolute when the
/// expected value is zero).
pub fn relative(measured: f64, expected: f64) -> f64 {
    let d = (measured - expected).abs();
    if expected == 0.0 {
        d
    } else {
        d / expected.abs()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol * b.abs().max(1e-300)
    }

    #[test]
    fn masses_and_inertias_of_the_shapes() {
        let sphere = ShapeSpec::Sphere(0.5);
        let m = 1000.0 * volume(sphere);
        assert!(close(m, 523.598_775_598_3, 1e-12), "{m}");
        assert_eq!(inertia(sphere, m), [0.1 * m; 3]);
        // A unit cube: I = m/6 about every axis.
        let cube = ShapeSpec::Cuboid([0.5; 3]);
        assert_eq!(volume(cube), 1.0);
        for i in inertia(cube, 6.0) {
            assert!(close(i, 1.0, 1e-15));
        }
        // A 0.2 × 0.8 × 1.8 box: I_x = m/12 (0.8² + 1.8²).
        let i = inertia(ShapeSpec::Cuboid([0.1, 0.4, 0.9]), 12.0);
        assert!(close(i[0], 0.64 + 3.24, 1e-12) && close(i[2], 0.04 + 0.64, 1e-12));
    }

    #[test]
    fn pendulum_period_is_the_small_angle_one_grown_by_the_series() {
        // A point mass on 1 m: I = m l², so T₀ = 2π√(l/g).
        let t0 = 2.0 * std::f64::consts::PI * (1.0 / G).sqrt();
        assert!(close(pendulum_period(1.0, 1.0, 1.0, 1e-9), t0, 1e-15));
        // T = T₀ (1 + θ²/16 + 11θ⁴/3072 + ...): within θ⁶ at 0.2 rad.
        let th: f64 = 0.2;
        let series = t0 * (1.0 + th * th / 16.0 + 11.0 * th.powi(4) / 3072.0);
        assert!(close(pendulum_period(1.0, 1.0, 1.0, th), series, 1e-6));
        // At 90°: K(sin 45°) = 1.854 074 677 301 372.
        let quarter = 4.0 * (1.0 / G).sqrt() * 1.854_074_677_301_372;
        assert!(close(
            pendulum_period(1.0, 1.0, 1.0, std::f64::consts::FRAC_PI_2),
            quarter,
            1e-14
        ));
    }

    #[test]
    fn projectile_and_fall_time_agree() {
        // Dropped from 5 m: after √(2h/g) it has fallen 5 m at speed g t.
        let t = fall_time(5.0);
        let p = projectile([0.0, 5.0, 0.0], [0.0; 3], [0.0, -G, 0.0], t);
        assert!(p[1].abs() < 1e-12, "{p:?}");
        let p = projectile([1.0, 2.0, 3.0], [3.0, 0.0, -1.0], [1.0, 0.0, 0.0], 2.0);
        assert_eq!(p, [1.0 + 6.0 + 2.0, 2.0, 3.0 - 2.0]);
    }

    #[test]
    fn friction_closed_forms() {
        assert!(close(stop_distance(5.0, 0.5), 25.0 / 9.81, 1e-12));
        let t = 30f64.to_radians();
        assert_eq!(
            ramp_acceleration(t, 0.7),
            0.0,
            "tan 30° = 0.577 < 0.7 sticks"
        );
        assert!(close(
            ramp_acceleration(t, 0.3),
            G * (0.5 - 0.3 * 0.75f64.sqrt()),
            1e-12
        ));
        assert!(close(
            rolling_acceleration(20f64.to_radians()),
            2.396_58,
            1e-5
        ));
    }

    #[test]
    fn slide_to_roll_ends_rolling_at_five_sevenths_after_t_star() {
        let (v0, mu) = (5.0, 0.3);
        let t_star = 2.0 * v0 / (7.0 * mu * G);
        let (_, v) = slide_to_roll(v0, mu, t_star);
        assert!(close(v, 5.0 / 7.0 * v0, 1e-12));
        // Before t*: uniformly decelerated; after: constant speed.
        let (x1, v1) = slide_to_roll(v0, mu, 0.5 * t_star);
        assert!(close(v1, v0 - mu * G * 0.5 * t_star, 1e-12));
        assert!(close(x1, (v0 + v1) / 2.0 * 0.5 * t_star, 1e-12));
        let (x2, v2) = slide_to_roll(v0, mu, t_star + 1.0);
        let (x3, _) = slide_to_roll(v0, mu, t_star);
        assert!(close(v2, v, 1e-12));
        assert!(close(x2 - x3, v, 1e-12));
        // The rolling sphere keeps (5/7)² · 7/5 = 5/7 of ½ m v0² (linear
        // plus rotational ½ · 2/5 m r² ω²).
        let kept = 0.5 * (v * v) * 1.4 / (0.5 * v0 * v0);
        assert!(close(kept, 5.0 / 7.0, 1e-12));
    }

    #[test]
    fn collisions_conserve_momentum_and_scale_relative_speed() {
        let (v1, v2) = collision_1d(1.0, 4.0, 1.0, -2.0, 1.0);
        assert_eq!((v1, v2), (-2.0, 4.0), "equal masses swap velocities");
        let (m1, m2, u1, u2, e) = (2.0, 3.0, 1.5, -0.5, 0.4);
        let (v1, v2) = collision_1d(m1, u1, m2, u2, e);
        assert!(close(m1 * v1 + m2 * v2, m1 * u1 + m2 * u2, 1e-12));
        assert!(close(v2 - v1, e * (u1 - u2), 1e-12));
    }

    #[test]
    fn rotation_helpers_and_angular_momentum() {
        // 90° about z takes x to y.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let q = [0.0, 0.0, h, h];
        let r = rotate(q, [1.0, 0.0, 0.0]);
        assert!(norm(sub(r, [0.0, 1.0, 0.0])) < 1e-15, "{r:?}");
        assert!(norm(sub(inverse_rotate(q, r), [1.0, 0.0, 0.0])) < 1e-15);
        // Spinning about body x (now world y) with I_x = 2: L = 2 ω.
        let (l, e) = angular_momentum_energy(q, [0.0, 3.0, 0.0], [2.0, 5.0, 7.0]);
        assert!(norm(sub(l, [0.0, 6.0, 0.0])) < 1e-14 && close(e, 9.0, 1e-14));
    }

    #[test]
    fn torque_free_reference_conserves_invariants_and_flips_only_about_the_intermediate_axis() {
        let i = inertia(ShapeSpec::Cuboid([0.1, 0.4, 0.9]), 144.0);
        let invariants = |w: [f64; 3]| {
            let l: [f64; 3] = std::array::from_fn(|k| i[k] * w[k]);
            (norm(l), 0.5 * dot(w, l))
        };
        let w0 = [0.01, 5.0, 0.01];
        let run = torque_free_reference(i, w0, 20.0, 60, 6000);
        assert_eq!(run.len(), 1201);
        let (l0, e0) = invariants(w0);
        for &w in &run {
            let (l, e) = invariants(w);
            assert!(close(l, l0, 1e-9) && close(e, e0, 1e-9));
        }
        let flips = sign_changes(run.iter().map(|w| w[1]));
        assert!(flips >= 4, "the Dzhanibekov flip: {flips}");
        // Halving the step changes nothing visible: the reference has converged.
        let fine = torque_free_reference(i, w0, 20.0, 60, 12000);
        let d = run
            .iter()
            .zip(&fine)
            .map(|(a, b)| norm(sub(*a, *b)))
            .fold(0.0, f64::max);
        assert!(d < 1e-6, "{d}");
        // About the major (x) or minor (z) axis: no flip.
        for (axis, w0) in [(0, [5.0, 0.01, 0.01]), (2, [0.01, 0.01, 5.0])] {
            let run = torque_free_reference(i, w0, 20.0, 60, 6000);
            assert_eq!(sign_changes(run.iter().map(|w| w[axis])), 0);
        }
    }

    #[test]
    fn sign_changes_skip_zeros() {
        assert_eq!(sign_changes([1.0, 0.0, -1.0, -2.0, 0.0, 3.0]), 2);
        assert_eq!(sign_changes([0.0, 0.0]), 0);
    }

    #[test]
    fn relative_error_falls_back_to_absolute_at_zero() {
        assert!(close(relative(1.1, 1.0), 0.1, 1e-12));
        assert!(close(relative(-0.9, -1.0), 0.1, 1e-12));
        assert_eq!(relative(0.25, 0.0), 0.25);
    }
}
