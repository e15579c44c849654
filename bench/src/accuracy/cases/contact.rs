//! Single bodies against the ground: bouncing, falling, sliding, ramps and
//! rolling.

use super::{Case, ground, ground_at, horizontal, slope_gravity, unit_box};
use crate::accuracy::closed::{self, G, relative};
use crate::accuracy::run::{Failure, Outcome, Runner};
use crate::accuracy::sim::{BodySpec, ShapeSpec, Spec};

/// Drops a ball with restitution `e` from 10 m and measures the first two
/// apex ratios against `e²`.
fn bounce(r: &mut Runner, e: f64) -> Outcome {
    let (rad, h) = (0.25, 10.0);
    let ball = BodySpec::dynamic(ShapeSpec::Sphere(rad), [0.0, h + rad, 0.0]).material(0.0, e);
    let mut sim = r.build(&Spec::new([0.0, -G, 0.0], vec![ground(0.0, e), ball]));
    let mut apex = Vec::new();
    let mut prev_vy = 0.0;
    for _ in 0..r.ticks(8.0) {
        r.step(sim.as_mut());
        let st = sim.state(1);
        let vy = st.vel[1];
        if prev_vy > 0.0 && vy <= 0.0 {
            // The peak of the parabola through this tick's state.
            apex.push(st.pos[1] - rad + vy * vy / (2.0 * G));
            if apex.len() == 2 {
                break;
            }
        }
        prev_vy = vy;
    }
    let e2 = e * e;
    let r1 = apex.first().map_or(0.0, |a| a / h);
    let r2 = match apex[..] {
        [a, b, ..] => b / a,
        _ => 0.0,
    };
    Outcome::ok(
        relative(r1, e2).max(relative(r2, e2)),
        format!("apex ratios {r1:.5}, {r2:.5} vs e² = {e2}"),
    )
    .failed_if(apex.len() < 2, Failure::Wrong("fewer than 2 bounces"))
}

/// A ball with e = 0.5 bouncing on the ground.
pub const BOUNCE_05: Case = Case {
    name: "bounce_e05",
    title: "0.25 m ball dropped from 10 m, e = 0.5 (ball and ground), first two bounces",
    metric: "largest relative error of the two apex ratios",
    reference: "each apex is e² = 0.25 of the one before",
    zero_floor: None,
    run: |r, _| bounce(r, 0.5),
};

/// The same with e = 0.9.
pub const BOUNCE_09: Case = Case {
    name: "bounce_e09",
    title: "0.25 m ball dropped from 10 m, e = 0.9 (ball and ground), first two bounces",
    metric: "largest relative error of the two apex ratios",
    reference: "each apex is e² = 0.81 of the one before",
    zero_floor: None,
    run: |r, _| bounce(r, 0.9),
};

/// A ball dropped from rest: when does it land?
pub const DROP_TIME: Case = Case {
    name: "drop_time",
    title: "0.25 m ball dropped from rest 5 m above the ground (e = 0), 2 s",
    metric: "relative error of the impact time",
    reference: "t = √(2h/g) = 1.0096 s (impact: the first step that slows the fall; its time is the previous step's plus the free fall left from there)",
    zero_floor: None,
    run: |r, _| {
        let (rad, h) = (0.25, 5.0);
        let ball =
            BodySpec::dynamic(ShapeSpec::Sphere(rad), [0.0, h + rad, 0.0]).material(0.5, 0.0);
        let mut sim = r.build(&Spec::new([0.0, -G, 0.0], vec![ground(0.5, 0.0), ball]));
        let mut prev = sim.state(1);
        let mut hit = None;
        for k in 1..=r.ticks(2.0) {
            r.step(sim.as_mut());
            let st = sim.state(1);
            if st.vel[1] > prev.vel[1] - 0.5 * G * r.dt() {
                let fall = prev.pos[1] - rad;
                let v = -prev.vel[1];
                let tau = (-v + (v * v + 2.0 * G * fall).max(0.0).sqrt()) / G;
                hit = Some((k - 1) as f64 * r.dt() + tau);
                break;
            }
            prev = st;
        }
        let expected = closed::fall_time(h);
        match hit {
            Some(t) => Outcome::ok(
                relative(t, expected),
                format!("impact at {t:.5} s vs {expected:.5} s"),
            ),
            None => Outcome::ok(1.0, "never landed".into())
                .failed_if(true, Failure::Wrong("never landed")),
        }
    },
};

/// Settles a unit box on the ground at `origin`, launches it at 5 m/s along
/// the unit horizontal `dir` and measures where it stops.
fn slide(r: &mut Runner, origin: [f64; 3], ground_half: f64, dir: [f64; 3]) -> Outcome {
    let (mu, v) = (0.5, 5.0);
    let bodies = vec![
        ground_at(origin[0], origin[2], ground_half, mu, 0.0),
        unit_box([origin[0], 0.5, origin[2]], mu),
    ];
    let mut sim = r.build(&Spec::new([0.0, -G, 0.0], bodies));
    let settle = r.ticks(0.5);
    r.steps(sim.as_mut(), settle);
    let p0 = sim.state(1).pos;
    sim.set_linvel(1, dir.map(|d| d * v));
    let ticks = r.ticks(2.5);
    r.steps(sim.as_mut(), ticks);
    let st = sim.state(1);
    let d = closed::sub(st.pos, p0);
    let along = closed::dot(d, dir);
    let lateral = horizontal(d, dir.map(|x| x * along));
    let expected = closed::stop_distance(v, mu);
    let speed = closed::norm(st.vel);
    Outcome::ok(
        relative(along, expected).max(lateral / expected),
        format!(
            "stopped after {along:.4} m vs {expected:.4} m, {lateral:.2e} m off line, speed {speed:.2e} m/s"
        ),
    )
    .failed_if(speed > 0.05, Failure::Wrong("still sliding"))
}

/// A box launched along x on a μ = 0.5 floor.
pub const SLIDE: Case = Case {
    name: "slide",
    title: "unit box launched at 5 m/s along x on a level floor, μ = 0.5 (settled 0.5 s first), 2.5 s",
    metric: "max of stop-distance relative error and sideways drift / distance",
    reference: "stops after v²/(2μg) = 2.548 m on its launch line",
    zero_floor: None,
    run: |r, _| slide(r, [0.0; 3], 200.0, [1.0, 0.0, 0.0]),
};

/// The same launched at 45° to the box's axes: the friction circle.
pub const SLIDE_45: Case = Case {
    name: "slide_45",
    title: "the sliding box launched at 45° to its faces (direction (1, 0, 1)/√2)",
    metric: "max of stop-distance relative error and sideways drift / distance",
    reference: "Coulomb friction is isotropic: v²/(2μg) = 2.548 m on its launch line (a per-axis clamp stops it at 1/√2 of that)",
    zero_floor: None,
    run: |r, _| {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        slide(r, [0.0; 3], 200.0, [h, 0.0, h])
    },
};

/// The same 10 km out.
pub const FAR_SLIDE: Case = Case {
    name: "far_slide",
    title: "the sliding box on a 40 m floor 10 km from the origin (x = z = 10,000 m)",
    metric: "max of stop-distance relative error and sideways drift / distance",
    reference: "v²/(2μg) = 2.548 m on its launch line",
    zero_floor: None,
    run: |r, _| slide(r, [10_000.0, 0.0, 10_000.0], 20.0, [1.0, 0.0, 0.0]),
};

/// A unit box released on a 30° slope for 2 s: (down-slope displacement,
/// down-slope speed).
fn ramp(r: &mut Runner, mu: f64) -> (f64, f64) {
    let bodies = vec![ground(mu, 0.0), unit_box([0.0, 0.5, 0.0], mu)];
    let mut sim = r.build(&Spec::new(slope_gravity(30.0), bodies));
    let p0 = sim.state(1).pos;
    let ticks = r.ticks(2.0);
    r.steps(sim.as_mut(), ticks);
    let st = sim.state(1);
    (horizontal(st.pos, p0), st.vel[0])
}

/// Static friction holds a box on a 30° slope when μ > tan 30°.
pub const RAMP_STICK: Case = Case {
    name: "ramp_stick",
    title: "unit box released on a 30° slope, μ = 0.7 > tan 30° (gravity tilted instead of the ground), 2 s",
    metric: "creep along the slope, m",
    reference: "static friction holds it: 0 m",
    zero_floor: None,
    run: |r, _| {
        let (d, v) = ramp(r, 0.7);
        Outcome::ok(d, format!("moved {d:.3e} m, speed {v:.2e} m/s"))
            .failed_if(d > 0.1, Failure::Wrong("slid"))
    },
};

/// Kinetic friction on a 30° slope with μ = 0.3.
pub const RAMP_SLIDE: Case = Case {
    name: "ramp_slide",
    title: "unit box released on a 30° slope, μ = 0.3, 2 s",
    metric: "relative error of the acceleration (speed after 2 s / 2 s)",
    reference: "a = g(sin θ − μ cos θ) = 2.356 m/s²",
    zero_floor: None,
    run: |r, _| {
        let (d, v) = ramp(r, 0.3);
        let a = v / 2.0;
        let expected = closed::ramp_acceleration(30f64.to_radians(), 0.3);
        Outcome::ok(
            relative(a, expected),
            format!("a {a:.5} vs {expected:.5} m/s², moved {d:.4} m"),
        )
    },
};

/// A ball rolling down a 20° slope.
pub const ROLL: Case = Case {
    name: "roll",
    title: "0.5 m ball released on a 20° slope, μ = 0.6 (rolls: μ > 2/7 tan θ), 2 s",
    metric: "relative error of the acceleration (speed after 2 s / 2 s)",
    reference: "a = 5/7 g sin θ = 2.397 m/s², rolling without slip (v = ωr)",
    zero_floor: None,
    run: |r, _| {
        let (mu, rad) = (0.6, 0.5);
        let ball = BodySpec::dynamic(ShapeSpec::Sphere(rad), [0.0, rad, 0.0]).material(mu, 0.0);
        let mut sim = r.build(&Spec::new(slope_gravity(20.0), vec![ground(mu, 0.0), ball]));
        let ticks = r.ticks(2.0);
        r.steps(sim.as_mut(), ticks);
        let st = sim.state(1);
        let a = st.vel[0] / 2.0;
        let expected = closed::rolling_acceleration(20f64.to_radians());
        let slip = (st.vel[0] + st.omega[2] * rad).abs() / st.vel[0].abs().max(1e-9);
        Outcome::ok(
            relative(a, expected),
            format!("a {a:.5} vs {expected:.5} m/s²; slip |v + ωr|/v {slip:.2e}"),
        )
        .failed_if(slip > 0.05, Failure::Wrong("slipped"))
    },
};

/// A ball launched sliding without spin: it slips, spins up and rolls.
pub const SLIDE_TO_ROLL: Case = Case {
    name: "slide_to_roll",
    title: "0.5 m ball launched sliding at 5 m/s without spin on a level floor, μ = 0.3 (settled 0.25 s first), 2 s",
    metric: "max of relative errors of distance and speed after 2 s",
    reference: "slips until t* = 2v0/(7μg) = 0.485 s, then rolls at 5/7 v0 = 3.571 m/s",
    zero_floor: None,
    run: |r, _| {
        let (mu, rad, v0) = (0.3, 0.5, 5.0);
        let ball = BodySpec::dynamic(ShapeSpec::Sphere(rad), [0.0, rad, 0.0]).material(mu, 0.0);
        let mut sim = r.build(&Spec::new([0.0, -G, 0.0], vec![ground(mu, 0.0), ball]));
        let settle = r.ticks(0.25);
        r.steps(sim.as_mut(), settle);
        let p0 = sim.state(1).pos;
        sim.set_linvel(1, [v0, 0.0, 0.0]);
        let ticks = r.ticks(2.0);
        r.steps(sim.as_mut(), ticks);
        let st = sim.state(1);
        let x = st.pos[0] - p0[0];
        let (x_exp, v_exp) = closed::slide_to_roll(v0, mu, ticks as f64 * r.dt());
        Outcome::ok(
            relative(x, x_exp).max(relative(st.vel[0], v_exp)),
            format!(
                "x {x:.4} vs {x_exp:.4} m; v {:.4} vs {v_exp:.4} m/s",
                st.vel[0]
            ),
        )
    },
};
