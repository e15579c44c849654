//! Cases without resting contact: projectiles, torque-free spins, isolated
//! collisions, and fast shots at a thin wall.

use std::sync::OnceLock;

use super::Case;
use crate::accuracy::closed::{self, G, norm, sub};
use crate::accuracy::run::{Failure, Outcome, Runner};
use crate::accuracy::sim::{BodySpec, ShapeSpec, Spec};
use crate::harness::Rng;

/// The projectile's wind acceleration (a constant applied force over the
/// closed-form mass), m/s².
const WIND: [f64; 3] = [1.5, 0.0, -0.5];

fn projectile(r: &mut Runner, origin: [f64; 3]) -> Outcome {
    let ball = ShapeSpec::Sphere(0.5);
    let p0 = [origin[0], origin[1] + 2.0, origin[2]];
    let v0 = [3.0, 12.5, -1.25];
    let body = BodySpec::dynamic(ball, p0).vel(v0);
    let m = body.mass();
    let spec = Spec::new([0.0, -G, 0.0], vec![body.force(WIND.map(|a| a * m))]);
    let accel = [WIND[0], WIND[1] - G, WIND[2]];
    let mut sim = r.build(&spec);
    let mut worst: f64 = 0.0;
    let ticks = r.ticks(3.0);
    for k in 1..=ticks {
        r.step(sim.as_mut());
        let t = k as f64 * r.dt();
        let exact = closed::projectile(p0, v0, accel, t);
        worst = worst.max(norm(sub(sim.state(0).pos, exact)));
    }
    let end = sim.state(0).pos;
    let exact = closed::projectile(p0, v0, accel, ticks as f64 * r.dt());
    Outcome::ok(
        worst,
        format!("final error {:.3e} m", norm(sub(end, exact))),
    )
}

/// A ball thrown with gravity and a constant sideways force.
pub const PROJECTILE: Case = Case {
    name: "projectile",
    title: "ball thrown at (3, 12.5, -1.25) m/s under gravity and a constant force, 3 s",
    metric: "largest position error over 3 s, m",
    reference: "p0 + v0 t + a t²/2, a = g + F/m",
    zero_floor: None,
    run: |r, _| projectile(r, [0.0; 3]),
};

/// The same 10 km out on x and z, where f32 keeps about 1 mm.
pub const FAR_PROJECTILE: Case = Case {
    name: "far_projectile",
    title: "the projectile 10 km from the origin (x = z = 10,000 m)",
    metric: "largest position error over 3 s, m",
    reference: "p0 + v0 t + a t²/2, a = g + F/m",
    zero_floor: None,
    run: |r, _| projectile(r, [10_000.0, 0.0, 10_000.0]),
};

/// What a torque-free run tracked.
struct Spin {
    /// Largest `‖L − L₀‖ / ‖L₀‖` (direction and size).
    l_drift: f64,
    /// Largest `|‖L‖ − ‖L₀‖| / ‖L₀‖` (size only).
    l_size_drift: f64,
    /// Largest `(E − E₀)/E₀` (negative: the energy only fell).
    energy_rise: f64,
    /// Sign changes of the body-axis angular velocity along `axis`.
    flips: u32,
}

fn spin(r: &mut Runner, half: [f64; 3], omega: [f64; 3], axis: usize, seconds: f64) -> Spin {
    let shape = ShapeSpec::Cuboid(half);
    let body = BodySpec::dynamic(shape, [0.0; 3])
        .density(500.0)
        .omega(omega);
    let inertia = closed::inertia(shape, body.mass());
    let mut sim = r.build(&Spec::new([0.0; 3], vec![body]));
    let st = sim.state(0);
    let (l0, e0) = closed::angular_momentum_energy(st.rot, st.omega, inertia);
    let mut out = Spin {
        l_drift: 0.0,
        l_size_drift: 0.0,
        energy_rise: f64::MIN,
        flips: 0,
    };
    let mut axis_series = Vec::new();
    for _ in 0..r.ticks(seconds) {
        r.step(sim.as_mut());
        let st = sim.state(0);
        let (l, e) = closed::angular_momentum_energy(st.rot, st.omega, inertia);
        out.l_drift = out.l_drift.max(norm(sub(l, l0)) / norm(l0));
        out.l_size_drift = out.l_size_drift.max((norm(l) - norm(l0)).abs() / norm(l0));
        out.energy_rise = out.energy_rise.max((e - e0) / e0);
        axis_series.push(closed::inverse_rotate(st.rot, st.omega)[axis]);
    }
    out.flips = closed::sign_changes(axis_series);
    out
}

fn spin_error(s: &Spin) -> f64 {
    s.l_drift.max(s.energy_rise)
}

const SYMMETRIC_HALF: [f64; 3] = [0.3, 0.3, 0.8];
const INTERMEDIATE_HALF: [f64; 3] = [0.1, 0.4, 0.9];
const INTERMEDIATE_OMEGA: [f64; 3] = [0.01, 5.0, 0.01];
const INTERMEDIATE_SECONDS: f64 = 20.0;

/// A box with a square cross-section spinning about its symmetry axis with
/// a wobble: steady precession, the spin about the axis stays constant.
pub const SPIN_SYMMETRIC: Case = Case {
    name: "spin_symmetric",
    title: "0.6 × 0.6 × 1.6 m box spinning at 6 rad/s about its symmetry axis with a (0.5, 0.3) rad/s wobble, no gravity, 10 s",
    metric: "max of ‖L − L0‖/‖L0‖ and energy growth (E − E0)/E0",
    reference: "L and E of a torque-free body are constant",
    zero_floor: None,
    run: |r, _| {
        let s = spin(r, SYMMETRIC_HALF, [0.5, 0.3, 6.0], 2, 10.0);
        Outcome::ok(
            spin_error(&s),
            format!(
                "L drift {:.3e} (|L| {:.3e}); energy rise {:.3e}; spin-axis sign changes {}",
                s.l_drift, s.l_size_drift, s.energy_rise, s.flips
            ),
        )
        .failed_if(s.flips > 0, Failure::Wrong("spin reversed"))
    },
};

/// The flips of the reference solution of the intermediate-axis spin.
fn intermediate_reference_flips() -> u32 {
    static FLIPS: OnceLock<u32> = OnceLock::new();
    *FLIPS.get_or_init(|| {
        let shape = ShapeSpec::Cuboid(INTERMEDIATE_HALF);
        let inertia = closed::inertia(shape, 500.0 * closed::volume(shape));
        let run = closed::torque_free_reference(
            inertia,
            INTERMEDIATE_OMEGA,
            INTERMEDIATE_SECONDS,
            240,
            48_000,
        );
        closed::sign_changes(run.iter().map(|w| w[1]))
    })
}

/// The Dzhanibekov effect: a spin about the intermediate axis flips over
/// and over, conserving L and E.
pub const SPIN_INTERMEDIATE: Case = Case {
    name: "spin_intermediate",
    title: "0.2 × 0.8 × 1.8 m box spinning at 5 rad/s about its intermediate axis (0.01 rad/s off), no gravity, 20 s",
    metric: "max of ‖L − L0‖/‖L0‖ and energy growth (E − E0)/E0",
    reference: "L, E constant; flips as often as Euler's equations integrated by RK4 at 48 kHz",
    zero_floor: None,
    run: |r, _| {
        let s = spin(
            r,
            INTERMEDIATE_HALF,
            INTERMEDIATE_OMEGA,
            1,
            INTERMEDIATE_SECONDS,
        );
        let expected = intermediate_reference_flips();
        Outcome::ok(
            spin_error(&s),
            format!(
                "L drift {:.3e} (|L| {:.3e}); energy rise {:.3e}; flips {} (reference {expected})",
                s.l_drift, s.l_size_drift, s.energy_rise, s.flips
            ),
        )
        .failed_if(s.flips.abs_diff(expected) > 1, Failure::Wrong("flip count"))
    },
};

/// Two equal balls, e = 1, head-on in zero gravity: the velocities swap.
pub const ELASTIC_SPHERES: Case = Case {
    name: "elastic_spheres",
    title: "two 0.5 m balls at +4 and -2 m/s head-on, e = 1, no friction, no gravity, 2 s",
    metric: "max of momentum error / Σm|u|, |ΔE|/E0 and velocity error / Σ|u|",
    reference: "equal masses, e = 1: velocities swap (-2, +4) m/s",
    zero_floor: None,
    run: |r, _| {
        let ball = ShapeSpec::Sphere(0.5);
        let (u1, u2) = (4.0, -2.0);
        let a = BodySpec::dynamic(ball, [-2.0, 0.0, 0.0])
            .vel([u1, 0.0, 0.0])
            .material(0.0, 1.0);
        let b = BodySpec::dynamic(ball, [2.0, 0.0, 0.0])
            .vel([u2, 0.0, 0.0])
            .material(0.0, 1.0);
        let m = a.mass();
        let mut sim = r.build(&Spec::new([0.0; 3], vec![a, b]));
        let ticks = r.ticks(2.0);
        r.steps(sim.as_mut(), ticks);
        let (va, vb) = (sim.state(0).vel, sim.state(1).vel);
        // Equal masses: the unit-mass form is exact in f64 (−2, +4).
        let (w1, w2) = closed::collision_1d(1.0, u1, 1.0, u2, 1.0);
        let p: [f64; 3] = std::array::from_fn(|k| m * (va[k] + vb[k]));
        let p_err = norm(sub(p, [m * (u1 + u2), 0.0, 0.0])) / (m * (u1.abs() + u2.abs()));
        let e0 = 0.5 * m * (u1 * u1 + u2 * u2);
        let e_err = (0.5 * m * (closed::dot(va, va) + closed::dot(vb, vb)) - e0).abs() / e0;
        let v_err = norm(sub(va, [w1, 0.0, 0.0])).max(norm(sub(vb, [w2, 0.0, 0.0])))
            / (u1.abs() + u2.abs());
        Outcome::ok(
            p_err.max(e_err).max(v_err),
            format!(
                "momentum {p_err:.3e}; energy {e_err:.3e}; velocities {:.4}, {:.4} m/s",
                va[0], vb[0]
            ),
        )
        .failed_if(v_err > 0.25, Failure::Wrong("did not swap"))
    },
};

/// Total linear momentum and angular momentum about the origin of a set of
/// bodies (closed-form masses and inertias).
fn momenta(bodies: &[BodySpec], states: &[crate::accuracy::sim::State]) -> ([f64; 3], [f64; 3]) {
    let mut p = [0.0; 3];
    let mut l = [0.0; 3];
    for (b, st) in bodies.iter().zip(states) {
        let m = b.mass();
        let (spin, _) =
            closed::angular_momentum_energy(st.rot, st.omega, closed::inertia(b.shape, m));
        let orbital = closed::cross(st.pos, st.vel.map(|v| m * v));
        for k in 0..3 {
            p[k] += m * st.vel[k];
            l[k] += orbital[k] + spin[k];
        }
    }
    (p, l)
}

/// Two boxes of different mass meet off-centre, spinning, with friction
/// and some bounce, in zero gravity: an isolated system.
pub const ISOLATED_COLLISION: Case = Case {
    name: "isolated_collision",
    title: "two spinning boxes (384 and 1,024 kg) collide off-centre with friction 0.5, e = 0.3, no gravity, 2 s",
    metric: "max of ‖P − P0‖/Σm|v| and ‖L − L0‖/Σ(|r × mv| + |Iω|) (L about the origin)",
    reference: "an isolated system conserves linear and angular momentum exactly",
    zero_floor: None,
    run: |r, _| {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let bodies = vec![
            BodySpec::dynamic(ShapeSpec::Cuboid([0.5, 0.3, 0.4]), [-2.0, 0.1, 0.0])
                .density(800.0)
                .vel([3.0, 0.0, 0.5])
                .omega([0.0, 1.0, 2.0])
                .material(0.5, 0.3),
            BodySpec::dynamic(ShapeSpec::Cuboid([0.4; 3]), [1.0, -0.2, 0.3])
                .density(2000.0)
                .vel([-1.0, 0.2, 0.0])
                .rot([0.0, 0.5 * h, 0.0, (1.0 - 0.125f64).sqrt()])
                .material(0.5, 0.3),
        ];
        let mut sim = r.build(&Spec::new([0.0; 3], bodies.clone()));
        let states = |sim: &dyn crate::accuracy::sim::Sim| [sim.state(0), sim.state(1)];
        let s0 = states(sim.as_ref());
        let (p0, l0) = momenta(&bodies, &s0);
        let p_scale: f64 = bodies
            .iter()
            .zip(&s0)
            .map(|(b, s)| b.mass() * norm(s.vel))
            .sum();
        let l_scale: f64 = bodies
            .iter()
            .zip(&s0)
            .map(|(b, s)| {
                let m = b.mass();
                let (spin, _) =
                    closed::angular_momentum_energy(s.rot, s.omega, closed::inertia(b.shape, m));
                norm(closed::cross(s.pos, s.vel.map(|v| m * v))) + norm(spin)
            })
            .sum();
        let (mut p_err, mut l_err): (f64, f64) = (0.0, 0.0);
        for _ in 0..r.ticks(2.0) {
            r.step(sim.as_mut());
            let (p, l) = momenta(&bodies, &states(sim.as_ref()));
            p_err = p_err.max(norm(sub(p, p0)) / p_scale);
            l_err = l_err.max(norm(sub(l, l0)) / l_scale);
        }
        let dv = norm(sub(sim.state(0).vel, s0[0].vel));
        Outcome::ok(
            p_err.max(l_err),
            format!("momentum {p_err:.3e}; angular momentum {l_err:.3e}; first box Δv {dv:.3} m/s"),
        )
        .failed_if(dv < 0.5, Failure::Wrong("no collision"))
    },
};

/// The wall the shots are fired at: 1 cm thick, 4 × 4 m, normal +x.
const WALL_HALF: [f64; 3] = [0.005, 2.0, 2.0];

/// One shot's body: a sphere or a spinning, randomly oriented box of 2–20
/// cm, 2–5 m in front of the wall, aimed within 60° of its normal at a
/// point on it, at 50–500 m/s.
fn shot(rng: &mut Rng) -> BodySpec {
    let (u, v) = (
        rng.uniform(-0.7, 0.7) * WALL_HALF[1],
        rng.uniform(-0.7, 0.7) * WALL_HALF[2],
    );
    let aim = [WALL_HALF[0], u, v];
    let theta = rng.uniform(0.0, 60f64.to_radians());
    let phi = rng.uniform(0.0, std::f64::consts::TAU);
    let back = [
        theta.cos(),
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
    ];
    let dist = rng.uniform(2.0, 5.0);
    let speed = rng.uniform(50.0, 500.0);
    let start = std::array::from_fn(|k| aim[k] + back[k] * dist);
    let vel = back.map(|b| -b * speed);
    if rng.next_u64().is_multiple_of(2) {
        BodySpec::dynamic(ShapeSpec::Sphere(rng.uniform(0.02, 0.2)), start).vel(vel)
    } else {
        let half = [(); 3].map(|_| rng.uniform(0.02, 0.2));
        let q = loop {
            let q = [(); 4].map(|_| rng.uniform(-1.0, 1.0));
            let n = q.iter().map(|x| x * x).sum::<f64>();
            if n > 0.01 && n <= 1.0 {
                break q.map(|x| x / n.sqrt());
            }
        };
        let omega = [(); 3].map(|_| rng.uniform(-10.0, 10.0));
        BodySpec::dynamic(ShapeSpec::Cuboid(half), start)
            .vel(vel)
            .rot(q)
            .omega(omega)
    }
}

/// Fast spheres and boxes at a thin static wall, one world per shot.
pub const TUNNELLING: Case = Case {
    name: "tunnelling",
    title: "24 (quick: 4) seeded shots (spheres and spinning boxes, 2–20 cm, 50–500 m/s, up to 60° off normal) at a 1 cm static wall, 0.25 s each",
    metric: "fraction of shots that end behind the wall",
    reference: "none passes through (0)",
    // One shot of 24 is 0.042: zeros sit a decade and a half below.
    zero_floor: Some(1e-3),
    run: |r, quick| {
        let shots = if quick { 4 } else { 24 };
        let mut rng = Rng::new(0x5EED_7E57);
        let mut through = 0;
        for _ in 0..shots {
            let wall = BodySpec::fixed(ShapeSpec::Cuboid(WALL_HALF), [0.0; 3]);
            let mut spec = Spec::new([0.0; 3], vec![wall, shot(&mut rng)]);
            spec.ccd = vec![1];
            spec.explode_speed = 1000.0;
            let mut sim = r.build(&spec);
            let ticks = r.ticks(0.25);
            r.steps(sim.as_mut(), ticks);
            let p = sim.state(1).pos;
            let behind =
                p[0] < -WALL_HALF[0] && p[1].abs() < WALL_HALF[1] && p[2].abs() < WALL_HALF[2];
            through += usize::from(behind);
        }
        let fraction = through as f64 / shots as f64;
        Outcome::ok(fraction, format!("{through} of {shots} shots went through"))
            .failed_if(through > 0, Failure::Tunnelled)
    },
};
