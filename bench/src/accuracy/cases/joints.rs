//! Joints: a pendulum's period and energy, a swinging chain, a hinge motor
//! under load, a hinge limit under torque and a heavy weight on light
//! links.

use super::Case;
use crate::accuracy::closed::{G, inertia, norm, pendulum_period, relative, rotate, sub, volume};
use crate::accuracy::run::{Failure, Outcome};
use crate::accuracy::sim::{BodySpec, JointSpec, JointSpecKind, ShapeSpec, Sim, Spec, State};

/// Where a body-local point of a body is in the world (every shape of
/// these cases is centred on its body's origin, its centre of mass).
fn world_point(st: &State, local: [f64; 3]) -> [f64; 3] {
    let r = rotate(st.rot, local);
    [st.pos[0] + r[0], st.pos[1] + r[1], st.pos[2] + r[2]]
}

/// The distance between a joint's two anchors in the world, m.
fn gap(sim: &dyn Sim, j: &JointSpec) -> f64 {
    let a = world_point(&sim.state(j.a), j.anchors[0]);
    let b = world_point(&sim.state(j.b), j.anchors[1]);
    norm(sub(a, b))
}

/// A ball joint.
fn ball(a: usize, b: usize, anchor_a: [f64; 3], anchor_b: [f64; 3]) -> JointSpec {
    JointSpec {
        a,
        b,
        anchors: [anchor_a, anchor_b],
        axis: [1.0, 0.0, 0.0],
        kind: JointSpecKind::Ball,
    }
}

/// The small static body a case hangs things from (its collider never
/// touches anything: joined bodies do not collide).
fn pivot(pos: [f64; 3]) -> BodySpec {
    BodySpec::fixed(ShapeSpec::Sphere(0.05), pos)
}

/// The pendulum: length, bob radius, amplitude.
const PENDULUM_L: f64 = 1.0;
const BOB_R: f64 = 0.05;
const PENDULUM_THETA0_DEG: f64 = 5.0;

/// A 5 cm ball (density 1,000) on a massless 1 m rod, as a ball joint 1 m
/// from the ball's centre, released from rest at 5°: its spec, and the
/// joint.
fn pendulum_spec() -> Spec {
    let th = PENDULUM_THETA0_DEG.to_radians();
    let l = PENDULUM_L;
    let bodies = vec![
        pivot([0.0, 2.0, 0.0]),
        BodySpec::dynamic(
            ShapeSpec::Sphere(BOB_R),
            [l * th.sin(), 2.0 - l * th.cos(), 0.0],
        ),
    ];
    let mut spec = Spec::new([0.0, -G, 0.0], bodies);
    spec.joints = vec![ball(0, 1, [0.0; 3], [-l * th.sin(), l * th.cos(), 0.0])];
    spec
}

/// The bob's mass and its moment of inertia about its centre.
fn bob_mass_inertia(spec: &Spec) -> (f64, f64) {
    let bob = spec.bodies[1];
    let m = bob.mass();
    (m, inertia(bob.shape, m)[0])
}

/// Simulated seconds of the pendulum period case.
fn period_seconds(quick: bool) -> f64 {
    if quick { 5.0 } else { 20.0 }
}

/// A pendulum's period against the exact one.
pub const PENDULUM_PERIOD: Case = Case {
    name: "pendulum_period",
    title: "pendulum: 5 cm ball on a ball joint 1 m below a pivot, released at 5°, 20 s (quick: 5 s)",
    metric: "relative error of the mean period",
    reference: "4√(I/(mgL))·K(sin(θ₀/2)) = 2.0080 s (I about the pivot, K the complete elliptic integral)",
    zero_floor: None,
    run: |r, quick| {
        let spec = pendulum_spec();
        let (m, i_cm) = bob_mass_inertia(&spec);
        let i_pivot = i_cm + m * PENDULUM_L * PENDULUM_L;
        let expected = pendulum_period(i_pivot, m, PENDULUM_L, PENDULUM_THETA0_DEG.to_radians());
        let mut sim = r.build(&spec);
        let dt = r.dt();
        // Upward zero crossings of x: the bob passing the bottom moving +x,
        // timed by linear interpolation within the step.
        let mut crossings = Vec::new();
        let mut prev = sim.state(1).pos[0];
        for k in 1..=r.ticks(period_seconds(quick)) {
            r.step(sim.as_mut());
            let x = sim.state(1).pos[0];
            if prev < 0.0 && x >= 0.0 {
                crossings.push((k as f64 - 1.0 + prev / (prev - x)) * dt);
            }
            prev = x;
        }
        if crossings.len() < 2 {
            return Outcome {
                error: f64::NAN,
                failure: Some(Failure::Wrong("no swing")),
                detail: format!("{} crossings", crossings.len()),
            };
        }
        let periods = (crossings.len() - 1) as f64;
        let period = (crossings[crossings.len() - 1] - crossings[0]) / periods;
        let err = relative(period, expected);
        Outcome::ok(
            err,
            format!(
                "mean period {period:.6} s over {periods} periods; exact {expected:.6} s; \
                 joint gap {:.2e} m",
                gap(sim.as_ref(), &spec.joints[0])
            ),
        )
    },
};

/// Simulated seconds of the pendulum energy case.
fn energy_seconds(quick: bool) -> f64 {
    if quick { 5.0 } else { 60.0 }
}

/// A pendulum's energy over a minute.
pub const PENDULUM_ENERGY: Case = Case {
    name: "pendulum_energy",
    title: "the same pendulum swinging for 60 s (quick: 5 s)",
    metric: "largest change of the energy over the run, over the swing's energy",
    reference: "no friction, no damping: the energy is constant",
    zero_floor: None,
    run: |r, quick| {
        let spec = pendulum_spec();
        let (m, i_cm) = bob_mass_inertia(&spec);
        let energy = |st: &State| {
            let v2 = st.vel.iter().map(|c| c * c).sum::<f64>();
            let w2 = st.omega.iter().map(|c| c * c).sum::<f64>();
            m * G * st.pos[1] + 0.5 * m * v2 + 0.5 * i_cm * w2
        };
        let mut sim = r.build(&spec);
        let e0 = energy(&sim.state(1));
        let swing = e0 - m * G * (2.0 - PENDULUM_L);
        let (mut lost, mut gained): (f64, f64) = (0.0, 0.0);
        for _ in 0..r.ticks(energy_seconds(quick)) {
            r.step(sim.as_mut());
            let de = (energy(&sim.state(1)) - e0) / swing;
            lost = lost.max(-de);
            gained = gained.max(de);
        }
        let end = (energy(&sim.state(1)) - e0) / swing;
        Outcome::ok(
            lost.max(gained),
            format!(
                "most lost {lost:.3e}, most gained {gained:.3e}, at the end {end:+.3e} \
                 of the swing energy"
            ),
        )
    },
};

/// Links of the swinging chain.
const CHAIN_LINKS: usize = 20;

/// Simulated seconds of the chain case.
fn chain_seconds(quick: bool) -> f64 {
    if quick { 2.0 } else { 10.0 }
}

/// A chain of 20 capsules released horizontally.
pub const CHAIN: Case = Case {
    name: "chain_20",
    title: "chain of 20 capsule links (1 m, 0.1 m radius, density 500) on ball joints, \
            released horizontally from a pivot, 10 s (quick: 2 s)",
    metric: "largest distance between a joint's anchors during the swing, m",
    reference: "rigid joints: 0 m",
    zero_floor: None,
    run: |r, quick| {
        let top = [0.0, 25.0, 0.0];
        // Capsules lie along their body's y axis: a quarter turn about z
        // lays them along x, local +y pointing to world −x.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let along_x = [0.0, 0.0, h, h];
        let mut bodies = vec![pivot(top)];
        let mut joints = Vec::new();
        for i in 0..CHAIN_LINKS {
            let pos = [top[0] + i as f64 + 0.5, top[1], top[2]];
            bodies.push(
                BodySpec::dynamic(ShapeSpec::Capsule(0.35, 0.1), pos)
                    .rot(along_x)
                    .density(500.0),
            );
            let to_prev = [0.0, 0.5, 0.0];
            let at_prev = if i == 0 { [0.0; 3] } else { [0.0, -0.5, 0.0] };
            joints.push(ball(i, i + 1, at_prev, to_prev));
        }
        let mut spec = Spec::new([0.0, -G, 0.0], bodies);
        spec.joints = joints;
        let mut sim = r.build(&spec);
        let mut worst: f64 = 0.0;
        for _ in 0..r.ticks(chain_seconds(quick)) {
            r.step(sim.as_mut());
            for j in &spec.joints {
                worst = worst.max(gap(sim.as_ref(), j));
            }
        }
        let end = sim.state(CHAIN_LINKS).pos;
        let reach = norm(sub(end, top));
        Outcome::ok(
            worst,
            format!(
                "worst joint gap {worst:.3e} m; last link {reach:.2} m from the pivot \
                 ({:.1} with rigid joints)",
                CHAIN_LINKS as f64 - 0.5
            ),
        )
        .failed_if(worst > 0.5, Failure::Wrong("came apart"))
    },
};

/// The motor case's target speed, rad/s.
const MOTOR_SPEED: f64 = 2.0;

/// Simulated seconds of the motor case (the first settles the speed).
fn motor_seconds(quick: bool) -> f64 {
    if quick { 1.5 } else { 3.0 }
}

/// A rod turned by a speed motor against gravity.
pub const HINGE_MOTOR: Case = Case {
    name: "hinge_motor",
    title: "10 kg rod (1 m) hinged at one end about a horizontal axis, speed motor at 2 rad/s \
            with at most 200 N·m against up to 49 N·m of gravity, 3 s (quick: 1.5 s)",
    metric: "largest relative error of the rod's speed after 1 s",
    reference: "the motor holds its target: 2 rad/s",
    zero_floor: None,
    run: |r, quick| {
        let bodies = vec![
            pivot([0.0, 5.0, 0.0]),
            BodySpec::dynamic(ShapeSpec::Cuboid([0.5, 0.05, 0.05]), [0.5, 5.0, 0.0]),
        ];
        let mut spec = Spec::new([0.0, -G, 0.0], bodies);
        spec.joints = vec![JointSpec {
            a: 0,
            b: 1,
            anchors: [[0.0; 3], [-0.5, 0.0, 0.0]],
            axis: [0.0, 0.0, 1.0],
            kind: JointSpecKind::Hinge {
                limits: None,
                motor: Some([MOTOR_SPEED, 200.0]),
                rigid_limits: false,
            },
        }];
        let mut sim = r.build(&spec);
        let settle = r.ticks(1.0);
        r.steps(sim.as_mut(), settle);
        let (mut worst, mut sum, mut n): (f64, f64, f64) = (0.0, 0.0, 0.0);
        let mut worst_gap: f64 = 0.0;
        for _ in settle..r.ticks(motor_seconds(quick)) {
            r.step(sim.as_mut());
            let w = sim.state(1).omega[2];
            worst = worst.max(relative(w, MOTOR_SPEED));
            sum += w;
            n += 1.0;
            worst_gap = worst_gap.max(gap(sim.as_ref(), &spec.joints[0]));
        }
        let mean = sum / n.max(1.0);
        Outcome::ok(
            worst,
            format!("mean speed {mean:.5} rad/s; worst joint gap {worst_gap:.2e} m"),
        )
        .failed_if(mean < 0.5 * MOTOR_SPEED, Failure::Wrong("short of target"))
    },
};

/// The hinge limit, rad.
const LIMIT: f64 = 0.5;

/// Simulated seconds of the limit case.
fn limit_seconds(quick: bool) -> f64 {
    if quick { 2.0 } else { 3.0 }
}

/// When the door has reached its limit and the case starts measuring how
/// far it stays from it, s (it gets there after about 0.8 s).
const LIMIT_REACHED_S: f64 = 1.5;

/// The angle of a body turned about y from its start, rad.
fn yaw(q: [f64; 4]) -> f64 {
    let s = if q[3] < 0.0 { -1.0 } else { 1.0 };
    2.0 * (s * q[1]).atan2(s * q[3])
}

/// A door pushed against its hinge limit.
pub const HINGE_LIMIT: Case = Case {
    name: "hinge_limit",
    title: "unit box (1,000 kg) hinged about a vertical axis 1 m from its centre, rigid limits \
            ±0.5 rad, under a steady 2 kN·m torque, no gravity, 3 s (quick: 2 s)",
    metric: "largest angle past the limit, and largest distance from it after 1.5 s, rad",
    reference: "the limit stops the box at 0.5 rad and holds it there: 0",
    zero_floor: None,
    run: |r, quick| {
        let bodies = vec![
            pivot([0.0; 3]),
            BodySpec::dynamic(ShapeSpec::Cuboid([0.5; 3]), [1.0, 0.0, 0.0])
                .torque([0.0, 2000.0, 0.0]),
        ];
        let mut spec = Spec::new([0.0; 3], bodies);
        spec.joints = vec![JointSpec {
            a: 0,
            b: 1,
            anchors: [[0.0; 3], [-1.0, 0.0, 0.0]],
            axis: [0.0, 1.0, 0.0],
            kind: JointSpecKind::Hinge {
                limits: Some([-LIMIT, LIMIT]),
                motor: None,
                // A door's end stop: rigid (ours; Rapier's always are).
                rigid_limits: true,
            },
        }];
        let mut sim = r.build(&spec);
        let reached = r.ticks(LIMIT_REACHED_S);
        let (mut past, mut off): (f64, f64) = (0.0, 0.0);
        let mut worst_gap: f64 = 0.0;
        for k in 1..=r.ticks(limit_seconds(quick)) {
            r.step(sim.as_mut());
            let angle = yaw(sim.state(1).rot);
            past = past.max(angle - LIMIT);
            if k >= reached {
                off = off.max((angle - LIMIT).abs());
            }
            worst_gap = worst_gap.max(gap(sim.as_ref(), &spec.joints[0]));
        }
        let end = yaw(sim.state(1).rot);
        Outcome::ok(
            past.max(off),
            format!(
                "most past the limit {past:.3e} rad; most off it after {LIMIT_REACHED_S} s \
                 {off:.3e} rad; ends at {end:.5} rad; worst joint gap {worst_gap:.2e} m"
            ),
        )
        .failed_if(end < 0.8 * LIMIT, Failure::Wrong("never reached the limit"))
    },
};

/// Light links and the weight of the mass-ratio chain, kg.
const LIGHT_LINKS: usize = 10;
const LINK_KG: f64 = 1.0;
const WEIGHT_KG: f64 = 100.0;

/// Simulated seconds of the heavy chain case.
fn heavy_seconds(quick: bool) -> f64 {
    if quick { 3.0 } else { 10.0 }
}

/// A 100 kg weight hung on ten 1 kg links.
pub const HEAVY_CHAIN: Case = Case {
    name: "heavy_chain",
    title: "100 kg ball hung on ten 1 kg balls (1:100) joined 1 m apart by ball joints, \
            released unstretched, 10 s (quick: 3 s)",
    metric: "the chain's total stretch at the end, m",
    reference: "rigid joints: 0 m",
    zero_floor: None,
    run: |r, quick| {
        let ball_shape = ShapeSpec::Sphere(0.2);
        let volume = volume(ball_shape);
        let top = [0.0, 30.0, 0.0];
        let mut bodies = vec![pivot(top)];
        let mut joints = Vec::new();
        for i in 0..=LIGHT_LINKS {
            let kg = if i == LIGHT_LINKS { WEIGHT_KG } else { LINK_KG };
            let pos = [0.0, top[1] - (i as f64 + 0.5), 0.0];
            bodies.push(BodySpec::dynamic(ball_shape, pos).density(kg / volume));
            let at_prev = if i == 0 { [0.0; 3] } else { [0.0, -0.5, 0.0] };
            joints.push(ball(i, i + 1, at_prev, [0.0, 0.5, 0.0]));
        }
        let weight = bodies.len() - 1;
        let mut spec = Spec::new([0.0, -G, 0.0], bodies);
        spec.joints = joints;
        let mut sim = r.build(&spec);
        let mut fastest: f64 = 0.0;
        for _ in 0..r.ticks(heavy_seconds(quick)) {
            r.step(sim.as_mut());
            fastest = fastest.max(norm(sim.state(weight).vel));
        }
        let stretch: f64 = spec.joints.iter().map(|j| gap(sim.as_ref(), j)).sum();
        let speed = norm(sim.state(weight).vel);
        Outcome::ok(
            stretch,
            format!(
                "total stretch {stretch:.3e} m; weight at {speed:.2e} m/s at the end, \
                 {fastest:.3} m/s at most"
            ),
        )
        .failed_if(!quick && speed > 0.02, Failure::Wrong("still moving"))
    },
};
