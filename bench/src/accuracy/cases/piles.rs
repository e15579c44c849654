//! Bodies resting on bodies: the stack, the pyramid, a heavy box on a light
//! one, and boxes spawned overlapping.

use super::{Case, ground, horizontal, unit_box};
use crate::accuracy::closed::{G, norm, sub};
use crate::accuracy::run::{Failure, Outcome};
use crate::accuracy::sim::Spec;

/// Friction of every pile case.
const MU: f64 = 0.5;

/// Simulated seconds of the stack case (the first settles).
fn stack_seconds(quick: bool) -> f64 {
    if quick { 2.0 } else { 6.0 }
}

/// Simulated seconds of the pyramid case (the first settles).
fn pyramid_seconds(quick: bool) -> f64 {
    if quick { 1.5 } else { 4.0 }
}

/// A vertical stack of 20 unit boxes.
pub const STACK: Case = Case {
    name: "stack_20",
    title: "vertical stack of 20 unit boxes, μ = 0.5: settles 1 s, then 5 s (quick: 1 s) more",
    metric: "top box drift after settling, m",
    reference: "a stack at rest stays put: 0 m",
    zero_floor: None,
    run: |r, quick| {
        let mut bodies = vec![ground(MU, 0.0)];
        bodies.extend((0..20).map(|i| unit_box([0.0, 0.5 + i as f64, 0.0], MU)));
        let top = bodies.len() - 1;
        let mut sim = r.build(&Spec::new([0.0, -G, 0.0], bodies));
        let settle = r.ticks(1.0);
        r.steps(sim.as_mut(), settle);
        let settled = sim.state(top).pos;
        let rest = r.ticks(stack_seconds(quick) - 1.0);
        r.steps(sim.as_mut(), rest);
        let p = sim.state(top).pos;
        let drift = norm(sub(p, settled));
        let off_axis = horizontal(p, [0.0; 3]);
        let sag = 19.5 - p[1];
        Outcome::ok(
            drift,
            format!("top drift {drift:.3e} m; sag {sag:.3e} m; off axis {off_axis:.3e} m"),
        )
        .failed_if(off_axis > 0.5 || sag > 1.0, Failure::Collapsed)
    },
};

/// A pyramid of base 20 (210 unit boxes) in the x–y plane.
pub const PYRAMID: Case = Case {
    name: "pyramid_20",
    title: "pyramid of base 20 (210 unit boxes), μ = 0.5: settles 1 s, then 3 s (quick: 0.5 s) more",
    metric: "largest movement of any box after settling, m",
    reference: "a pyramid at rest stays put: 0 m",
    zero_floor: None,
    run: |r, quick| {
        let mut bodies = vec![ground(MU, 0.0)];
        for row in 0..20 {
            for i in 0..(20 - row) {
                let x = i as f64 - (19 - row) as f64 * 0.5;
                bodies.push(unit_box([x, 0.5 + row as f64, 0.0], MU));
            }
        }
        let starts: Vec<[f64; 3]> = bodies.iter().map(|b| b.pos).collect();
        let mut sim = r.build(&Spec::new([0.0, -G, 0.0], bodies));
        let settle = r.ticks(1.0);
        r.steps(sim.as_mut(), settle);
        let settled: Vec<[f64; 3]> = (1..starts.len()).map(|i| sim.state(i).pos).collect();
        let rest = r.ticks(pyramid_seconds(quick) - 1.0);
        r.steps(sim.as_mut(), rest);
        let (mut drift, mut from_start): (f64, f64) = (0.0, 0.0);
        for (i, (p0, start)) in settled.iter().zip(&starts[1..]).enumerate() {
            let p = sim.state(i + 1).pos;
            drift = drift.max(norm(sub(p, *p0)));
            from_start = from_start.max(norm(sub(p, *start)));
        }
        Outcome::ok(
            drift,
            format!(
                "worst drift after settling {drift:.3e} m; worst from start {from_start:.3e} m"
            ),
        )
        .failed_if(from_start > 0.5, Failure::Collapsed)
    },
};

/// A 1,000 kg box resting on a 10 kg one.
pub const MASS_RATIO: Case = Case {
    name: "mass_ratio",
    title: "unit box of 1,000 kg on a unit box of 10 kg (1:100) on the ground, μ = 0.5, 5 s",
    metric: "worst penetration (box–box or light box–ground), m",
    reference: "rigid contact: 0 m",
    zero_floor: None,
    run: |r, _| {
        let bodies = vec![
            ground(MU, 0.0),
            unit_box([0.0, 0.5, 0.0], MU).density(10.0),
            unit_box([0.0, 1.5, 0.0], MU),
        ];
        let mut sim = r.build(&Spec::new([0.0, -G, 0.0], bodies));
        let mut worst: f64 = 0.0;
        for _ in 0..r.ticks(5.0) {
            r.step(sim.as_mut());
            let (light, heavy) = (sim.state(1).pos, sim.state(2).pos);
            let between = (light[1] + 0.5) - (heavy[1] - 0.5);
            let into_ground = 0.5 - light[1];
            worst = worst.max(between).max(into_ground);
        }
        let off = horizontal(sim.state(2).pos, sim.state(1).pos);
        Outcome::ok(
            worst,
            format!("worst penetration {worst:.3e} m; heavy box {off:.2e} m off centre"),
        )
        .failed_if(off > 0.5, Failure::Collapsed)
    },
};

/// Two unit boxes spawned half inside each other.
pub const OVERLAP: Case = Case {
    name: "overlap",
    title: "two unit boxes spawned overlapping by 0.5 m on the ground, μ = 0.5, 1 s",
    metric: "fastest speed of either box while separating, m/s",
    reference: "push-out should add no energy (no closed form: lower is better); separated within 1 s",
    zero_floor: None,
    run: |r, _| {
        let bodies = vec![
            ground(MU, 0.0),
            unit_box([0.0, 0.5, 0.0], MU),
            unit_box([0.5, 0.5, 0.0], MU),
        ];
        let mut sim = r.build(&Spec::new([0.0, -G, 0.0], bodies));
        let mut fastest: f64 = 0.0;
        let mut separated_at = None;
        for k in 1..=r.ticks(1.0) {
            r.step(sim.as_mut());
            let (a, b) = (sim.state(1), sim.state(2));
            fastest = fastest.max(norm(a.vel)).max(norm(b.vel));
            if separated_at.is_none() && (b.pos[0] - a.pos[0]).abs() - 1.0 > -1e-3 {
                separated_at = Some(k as f64 * r.dt());
            }
        }
        let when = separated_at.map_or("not separated".to_owned(), |t| {
            format!("separated at {t:.3} s")
        });
        Outcome::ok(fastest, format!("fastest {fastest:.3} m/s; {when}")).failed_if(
            separated_at.is_none(),
            Failure::Wrong("not separated in 1 s"),
        )
    },
};
