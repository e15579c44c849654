//! The swept scenes of the `stress` suite. Each sweep raises one quantity
//! (stack height, pyramid base, the base of a pyramid that must come to
//! rest, mass ratio, projectile speed, distance from the origin,
//! overlapping boxes, the step under a thrown box's landing) until an
//! engine fails its criterion,
//! which is stated in numbers in [`Sweep::criterion`] (and in
//! docs/stress.md: keep the two in step). A trial stops stepping as soon as
//! its criterion has failed; the generic checks of the accuracy suite's
//! [`Runner`] (fault, NaN, explosion) fail it too.

use crate::accuracy::closed::{G, norm, sub};
use crate::accuracy::run::{Failure, Outcome, Runner};
use crate::accuracy::sim::{BodySpec, ShapeSpec, Sim, Spec};

use super::search::within;

/// One sweep of the suite.
pub struct Sweep {
    /// Short name (file names, CSV, `--scenes`).
    pub name: &'static str,
    /// What is simulated.
    pub title: &'static str,
    /// The swept quantity and its unit (the chart's x axis).
    pub param: &'static str,
    /// The unit appended to a breaking point (may be empty).
    pub unit: &'static str,
    /// The figure measured in each trial and its unit (the y axis).
    pub metric: &'static str,
    /// The pass criterion, in numbers.
    pub criterion: &'static str,
    /// The bound on the metric that the criterion sets (drawn as a line).
    pub limit: f64,
    /// The swept values, ascending (`quick`: the smoke-run values).
    pub values: fn(bool) -> Vec<f64>,
    /// Whether the x axis is logarithmic.
    pub log_x: bool,
    /// Stop an engine's sweep after this many failures in a row (0: run
    /// every value).
    pub stop_after: usize,
    /// Runs one trial at one value.
    pub trial: fn(&mut Runner, f64, bool) -> Outcome,
}

/// Friction of every stress scene.
const MU: f64 = 0.5;
/// Gravity, −y.
const GRAVITY: [f64; 3] = [0.0, -G, 0.0];

/// A static ground box whose top face is `y = top.y`, centred at `top`,
/// `half` m across.
fn ground(top: [f64; 3], half: f64) -> BodySpec {
    BodySpec::fixed(
        ShapeSpec::Cuboid([half, 1.0, half]),
        [top[0], top[1] - 1.0, top[2]],
    )
    .material(MU, 0.0)
}

/// A unit box (density 1000 unless changed) at `pos`.
fn unit_box(pos: [f64; 3]) -> BodySpec {
    BodySpec::dynamic(ShapeSpec::Cuboid([0.5; 3]), pos).material(MU, 0.0)
}

fn horizontal(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// Steps `ticks` ticks, calling `check` after each; stops early when
/// `check` returns false (the criterion has failed) or the runner saw a
/// fault, NaN or explosion.
fn run_while(
    r: &mut Runner,
    sim: &mut dyn Sim,
    ticks: usize,
    mut check: impl FnMut(&dyn Sim) -> bool,
) {
    for _ in 0..ticks {
        r.step(sim);
        if r.failure().is_some() || !check(sim) {
            return;
        }
    }
}

/// How long a stack or pyramid must stand, s.
fn stand_seconds(quick: bool) -> f64 {
    if quick { 1.0 } else { 10.0 }
}

/// A stack or pyramid stands while no box has moved more than this
/// horizontally from where it spawned, m.
pub const STAND_OFFSET: f64 = 0.25;
/// ... and no box has dropped more than this below its spawn height, m.
pub const STAND_DROP: f64 = 1.0;

/// A vertical stack of `n` unit boxes.
fn stack(r: &mut Runner, n: f64, quick: bool) -> Outcome {
    let n = n as usize;
    let mut bodies = vec![ground([0.0; 3], 50.0)];
    bodies.extend((0..n).map(|i| unit_box([0.0, 0.5 + i as f64, 0.0])));
    let top0 = bodies[n].pos;
    let mut sim = r.build(&Spec::new(GRAVITY, bodies));
    let (mut off, mut drop): (f64, f64) = (0.0, 0.0);
    let ticks = r.ticks(stand_seconds(quick));
    run_while(r, sim.as_mut(), ticks, |sim| {
        let p = sim.state(n).pos;
        off = off.max(horizontal(p, top0));
        drop = drop.max(top0[1] - p[1]);
        off <= STAND_OFFSET && drop <= STAND_DROP
    });
    Outcome::ok(
        off,
        format!("top box: off axis up to {off:.3e} m, dropped up to {drop:.3e} m"),
    )
    .failed_if(
        !(within(off, STAND_OFFSET) && within(drop, STAND_DROP)),
        Failure::Collapsed,
    )
}

/// The ground and a pyramid of base `n` unit boxes in the x–y plane on
/// it, row by row from the bottom.
fn pyramid_bodies(n: usize) -> Vec<BodySpec> {
    let mut bodies = vec![ground([0.0; 3], 100.0)];
    for row in 0..n {
        for i in 0..(n - row) {
            let x = i as f64 - (n - 1 - row) as f64 * 0.5;
            bodies.push(unit_box([x, 0.5 + row as f64, 0.0]));
        }
    }
    bodies
}

/// What watching a pyramid found: the largest sideways move and drop of
/// any box, and the fastest box through the last quarter of the run (if
/// asked for).
struct PyramidWatch {
    off: f64,
    drop: f64,
    fastest: f64,
}

impl PyramidWatch {
    /// Whether every box stayed within the stand bounds.
    fn stood(&self) -> bool {
        within(self.off, STAND_OFFSET) && within(self.drop, STAND_DROP)
    }
}

/// Steps the pyramid of base `n` for `seconds`, stopping once a box leaves
/// the stand bounds; with `last_quarter`, also records the fastest box
/// through the last quarter of the ticks.
fn watch_pyramid(r: &mut Runner, n: usize, seconds: f64, last_quarter: bool) -> PyramidWatch {
    let bodies = pyramid_bodies(n);
    let starts: Vec<[f64; 3]> = bodies.iter().map(|b| b.pos).collect();
    let mut sim = r.build(&Spec::new(GRAVITY, bodies));
    let mut w = PyramidWatch {
        off: 0.0,
        drop: 0.0,
        fastest: 0.0,
    };
    let ticks = r.ticks(seconds);
    let rest_from = if last_quarter {
        ticks - ticks / 4
    } else {
        ticks
    };
    let mut tick = 0;
    run_while(r, sim.as_mut(), ticks, |sim| {
        tick += 1;
        for (i, p0) in starts.iter().enumerate().skip(1) {
            let s = sim.state(i);
            w.off = w.off.max(horizontal(s.pos, *p0));
            w.drop = w.drop.max(p0[1] - s.pos[1]);
            if tick > rest_from {
                w.fastest = w.fastest.max(norm(s.vel));
            }
        }
        w.off <= STAND_OFFSET && w.drop <= STAND_DROP
    });
    w
}

/// A pyramid of base `n` unit boxes in the x–y plane.
fn pyramid(r: &mut Runner, n: f64, quick: bool) -> Outcome {
    let w = watch_pyramid(r, n as usize, stand_seconds(quick), false);
    Outcome::ok(
        w.off,
        format!(
            "worst box: moved up to {:.3e} m sideways, dropped up to {:.3e} m",
            w.off, w.drop
        ),
    )
    .failed_if(!w.stood(), Failure::Collapsed)
}

/// How long a pyramid is watched for coming to rest, s (quick: a smoke
/// run's 2 s).
fn rest_seconds(quick: bool) -> f64 {
    if quick { 2.0 } else { 40.0 }
}

/// The speed every box of a pyramid at rest stays under through the last
/// quarter of the run, m/s.
pub const REST_SPEED: f64 = 0.01;

/// A pyramid of base `n` unit boxes in the x–y plane, sleeping off, for
/// [`rest_seconds`]: it must stand (as in [`pyramid`]) and come to rest,
/// every box under [`REST_SPEED`] through the last quarter of the run. A
/// pyramid that stands but keeps swaying (a solver that pumps energy into a
/// mode the structure has) fails here though it passes `pyramid_base`.
fn pyramid_rest(r: &mut Runner, n: f64, quick: bool) -> Outcome {
    let w = watch_pyramid(r, n as usize, rest_seconds(quick), true);
    Outcome::ok(
        w.fastest,
        format!(
            "fastest box in the last quarter {:.3e} m/s; worst box moved up to {:.3e} m \
             sideways, dropped up to {:.3e} m",
            w.fastest, w.off, w.drop
        ),
    )
    .failed_if(!w.stood(), Failure::Collapsed)
    .failed_if(
        !within(w.fastest, REST_SPEED),
        Failure::Wrong("not at rest"),
    )
}

/// The heavy box's mass in the mass-ratio sweeps, kg (a unit box of
/// density 1000); the light box is this divided by the ratio.
const HEAVY_DENSITY: f64 = 1000.0;
/// Largest penetration a pair at rest may show, m.
pub const PAIR_PENETRATION: f64 = 0.02;

/// A heavy unit box on a light one, ratio `ratio`:1, on the ground, 5 s.
fn mass_pair(r: &mut Runner, ratio: f64, quick: bool) -> Outcome {
    let bodies = vec![
        ground([0.0; 3], 50.0),
        unit_box([0.0, 0.5, 0.0]).density(HEAVY_DENSITY / ratio),
        unit_box([0.0, 1.5, 0.0]).density(HEAVY_DENSITY),
    ];
    let mut sim = r.build(&Spec::new(GRAVITY, bodies));
    let (mut worst, mut off): (f64, f64) = (0.0, 0.0);
    let ticks = r.ticks(if quick { 2.0 } else { 5.0 });
    run_while(r, sim.as_mut(), ticks, |sim| {
        let (light, heavy) = (sim.state(1).pos, sim.state(2).pos);
        let between = (light[1] + 0.5) - (heavy[1] - 0.5);
        worst = worst.max(between).max(0.5 - light[1]);
        off = off.max(horizontal(heavy, light));
        worst <= 0.5 && off <= STAND_OFFSET
    });
    Outcome::ok(
        worst,
        format!("worst penetration {worst:.3e} m; heavy box up to {off:.2e} m off centre"),
    )
    .failed_if(off > STAND_OFFSET, Failure::Collapsed)
    .failed_if(!within(worst, PAIR_PENETRATION), Failure::Wrong("sank"))
}

/// How far the alternating stack's top may drop, m.
pub const STACK5_DROP: f64 = 0.5;

/// Five unit boxes, light / heavy alternating from the bottom (light,
/// heavy, light, heavy, light), ratio `ratio`:1, 10 s.
fn mass_stack(r: &mut Runner, ratio: f64, quick: bool) -> Outcome {
    let mut bodies = vec![ground([0.0; 3], 50.0)];
    for i in 0..5 {
        let d = if i % 2 == 0 {
            HEAVY_DENSITY / ratio
        } else {
            HEAVY_DENSITY
        };
        bodies.push(unit_box([0.0, 0.5 + i as f64, 0.0]).density(d));
    }
    let top0 = bodies[5].pos;
    let mut sim = r.build(&Spec::new(GRAVITY, bodies));
    let (mut off, mut drop): (f64, f64) = (0.0, 0.0);
    let ticks = r.ticks(stand_seconds(quick));
    run_while(r, sim.as_mut(), ticks, |sim| {
        let p = sim.state(5).pos;
        off = off.max(horizontal(p, top0));
        drop = drop.max(top0[1] - p[1]);
        off <= STAND_OFFSET && drop <= STACK5_DROP
    });
    Outcome::ok(
        drop,
        format!("top box: dropped up to {drop:.3e} m, off axis up to {off:.3e} m"),
    )
    .failed_if(
        !(within(off, STAND_OFFSET) && within(drop, STACK5_DROP)),
        Failure::Collapsed,
    )
}

/// The wall the projectiles are fired at: 1 cm thick, 4 × 4 m, normal +x.
const WALL_HALF: [f64; 3] = [0.005, 2.0, 2.0];
/// The projectile: a sphere of this radius, m.
const SHOT_RADIUS: f64 = 0.05;

/// Shots per speed.
fn shots(quick: bool) -> usize {
    if quick { 2 } else { 8 }
}

/// Shot `k` of `n`: where the sphere's centre would touch the wall (a point
/// of a 2 × 2 m grid on its face) and the unit direction back to its start,
/// `k · 30°/(n−1)` off the normal.
fn aim(k: usize, n: usize) -> ([f64; 3], [f64; 3]) {
    let at = [
        WALL_HALF[0] + SHOT_RADIUS,
        -1.0 + 2.0 * ((k * 3) % n) as f64 / n as f64,
        -1.0 + 2.0 * ((k * 5 + 1) % n) as f64 / n as f64,
    ];
    let theta = (30.0f64 * k as f64 / (n.max(2) - 1) as f64).to_radians();
    (at, [theta.cos(), theta.sin(), 0.0])
}

/// `n` shots at `speed`: sphere `k` starts 3 m back from its [`aim`], so
/// every shot hits the wall.
fn projectile(r: &mut Runner, speed: f64, quick: bool) -> Outcome {
    let n = shots(quick);
    let mut through = 0;
    let mut failure = None;
    for k in 0..n {
        let (at, back) = aim(k, n);
        let start = std::array::from_fn(|i| at[i] + back[i] * 3.0);
        let vel = back.map(|b| -b * speed);
        let wall = BodySpec::fixed(ShapeSpec::Cuboid(WALL_HALF), [0.0; 3]);
        let ball = BodySpec::dynamic(ShapeSpec::Sphere(SHOT_RADIUS), start).vel(vel);
        let mut spec = Spec::new([0.0; 3], vec![wall, ball]);
        spec.ccd = vec![1];
        spec.explode_speed = 1.5 * speed + 10.0;
        let mut shot = Runner::new(r.engine, r.settings);
        let mut sim = shot.build(&spec);
        let ticks = shot.ticks(4.0 / speed + 0.1).max(2);
        shot.steps(sim.as_mut(), ticks);
        let p = sim.state(1).pos;
        let behind = p[0] < -WALL_HALF[0] && p[1].abs() < 3.0 && p[2].abs() < 3.0;
        through += usize::from(behind);
        failure = failure.or(shot.failure());
        r.busy += shot.busy;
        r.simulated += shot.simulated;
    }
    let mut o = Outcome::ok(
        through as f64,
        format!("{through} of {n} shots went through"),
    )
    .failed_if(through > 0, Failure::Tunnelled);
    if let Some(f) = failure {
        o = o.failed_if(true, f);
    }
    o
}

/// The point at distance `d` from the origin along (1, 1, 1).
fn far(d: f64) -> [f64; 3] {
    [d / 3f64.sqrt(); 3]
}

/// Largest distance of a resting stack's top box from where a rigid stack
/// rests, after settling, m.
pub const FAR_REST: f64 = 0.01;

/// A stack of three unit boxes on a ground at distance `d` from the
/// origin: settles 1 s, then stands 10 s (quick: 1 s).
fn far_stack(r: &mut Runner, d: f64, quick: bool) -> Outcome {
    let o = far(d);
    let mut bodies = vec![ground(o, 10.0)];
    bodies.extend((0..3).map(|i| unit_box(add(o, [0.0, 0.5 + i as f64, 0.0]))));
    let rest = bodies[3].pos;
    let mut sim = r.build(&Spec::new(GRAVITY, bodies));
    let settle = r.ticks(1.0);
    r.steps(sim.as_mut(), settle);
    let settled = sim.state(3).pos;
    let (mut drift, mut off): (f64, f64) = (0.0, norm(sub(settled, rest)));
    let ticks = r.ticks(stand_seconds(quick));
    if r.failure().is_none() {
        run_while(r, sim.as_mut(), ticks, |sim| {
            let p = sim.state(3).pos;
            drift = drift.max(norm(sub(p, settled)));
            off = off.max(norm(sub(p, rest)));
            off <= 1.0
        });
    }
    let sag = rest[1] - settled[1];
    Outcome::ok(
        off,
        format!(
            "top box up to {off:.3e} m from rest; drift after settling {drift:.3e} m; settled sag {sag:.3e} m"
        ),
    )
    .failed_if(!within(off, FAR_REST), Failure::Wrong("off its rest"))
}

/// Largest error of the rolling ball against its closed form, m.
pub const ROLL_ERROR: f64 = 0.01;
/// The ball's radius, m, and speed, m/s.
const ROLL_RADIUS: f64 = 0.5;
const ROLL_SPEED: f64 = 2.0;

/// A ball of radius 0.5 m rolling without slipping at 2 m/s along +x on a
/// flat ground at distance `d` from the origin, 3 s (quick: 1 s). The
/// closed form: it keeps rolling at 2 m/s, `p(t) = p(0) + v t`.
fn far_roll(r: &mut Runner, d: f64, quick: bool) -> Outcome {
    let o = far(d);
    let ball = BodySpec::dynamic(
        ShapeSpec::Sphere(ROLL_RADIUS),
        add(o, [-3.0, ROLL_RADIUS, 0.0]),
    )
    .material(MU, 0.0)
    .vel([ROLL_SPEED, 0.0, 0.0])
    .omega([0.0, 0.0, -ROLL_SPEED / ROLL_RADIUS]);
    let mut sim = r.build(&Spec::new(GRAVITY, vec![ground(o, 20.0), ball]));
    let p0 = sim.state(1).pos;
    let mut err: f64 = 0.0;
    let mut t = 0.0;
    let dt = r.dt();
    let ticks = r.ticks(if quick { 1.0 } else { 3.0 });
    run_while(r, sim.as_mut(), ticks, |sim| {
        t += dt;
        let p = sim.state(1).pos;
        let expect = add(p0, [ROLL_SPEED * t, 0.0, 0.0]);
        err = err.max(norm(sub(p, expect)));
        err <= 10.0
    });
    let v = sim.state(1).vel[0];
    Outcome::ok(
        err,
        format!("largest position error {err:.3e} m; final speed {v:.4} m/s"),
    )
    .failed_if(
        !within(err, ROLL_ERROR),
        Failure::Wrong("off the closed form"),
    )
}

/// The thrown box's velocity, m/s, and the height of its bottom above the
/// floor when thrown, m.
const THROW_VEL: [f64; 3] = [5.0, 2.0, 0.0];
const THROW_HEIGHT: f64 = 1.0;
/// Largest distance of the thrown box's rest point from the closed form, m.
pub const LANDING_ERROR: f64 = 0.01;
/// The tick rates of the landing sweep, finest first (its values are their
/// step lengths, ascending).
const LANDING_RATES: [f64; 7] = [3840.0, 1920.0, 960.0, 480.0, 240.0, 120.0, 60.0];

/// Where a rigid unit box thrown flat (its bottom [`THROW_HEIGHT`] above the
/// floor, at [`THROW_VEL`]) comes to rest along x. It flies until its
/// bottom reaches the floor; the landing is fully inelastic, and friction
/// takes μ times the hit's normal impulse from the sliding speed (the
/// normal impulse moves toward the leading edge and cancels friction's
/// pitch, which it can while μ times the half height is below the half
/// width); the slide then adds `v²/(2μg)`. 3.4965 + 0.6733 = 4.1698 m.
pub fn landing_rest() -> f64 {
    let [vx, vy, _] = THROW_VEL;
    let t = (vy + (vy * vy + 2.0 * G * THROW_HEIGHT).sqrt()) / G;
    let hit = G * t - vy;
    let slide = vx - MU * hit;
    vx * t + slide * slide / (2.0 * MU * G)
}

/// A unit box thrown flat at [`THROW_VEL`], its bottom [`THROW_HEIGHT`]
/// above the floor, stepped `ms` milliseconds per step (the suite's
/// substeps) for 2.5 s: how far from [`landing_rest`] it comes to rest.
fn landing(r: &mut Runner, ms: f64, _quick: bool) -> Outcome {
    r.set_tick_rate((1000.0 / ms).round() as u32);
    let thrown = unit_box([0.0, 0.5 + THROW_HEIGHT, 0.0]).vel(THROW_VEL);
    let bodies = vec![ground([0.0; 3], 50.0), thrown];
    let mut sim = r.build(&Spec::new(GRAVITY, bodies));
    let (mut landed, mut spin) = (false, 0.0_f64);
    let ticks = r.ticks(2.5);
    run_while(r, sim.as_mut(), ticks, |sim| {
        let s = sim.state(1);
        // Its centre is half a box up once its bottom meets the floor.
        landed |= s.pos[1] < 0.5 + 0.01;
        if landed {
            spin = spin.max(norm(s.omega));
        }
        true
    });
    let s = sim.state(1);
    let expect = landing_rest();
    let err = horizontal(s.pos, [expect, 0.0, 0.0]);
    let speed = norm(s.vel);
    Outcome::ok(
        err,
        format!(
            "rests at x = {:.4} m, z = {:.4} m (closed form x = {expect:.4} m); \
             spin after landing up to {spin:.3} rad/s; final speed {speed:.2e} m/s",
            s.pos[0], s.pos[2]
        ),
    )
    .failed_if(speed > 1e-3, Failure::Wrong("not at rest"))
    .failed_if(
        !within(err, LANDING_ERROR),
        Failure::Wrong("off the closed form"),
    )
}

/// Fastest speed a box may reach while overlapping boxes separate, m/s.
pub const OVERLAP_SPEED: f64 = 2.0;
/// Boxes count as separated when every two centres are at least this far
/// apart, m (two unit boxes whose centres are closer than 1 m overlap:
/// their inscribed spheres do).
const SEPARATED: f64 = 0.99;

/// `k` unit boxes spawned in a row on the ground, 0.5 m apart (each
/// overlaps its neighbours by half its width), 3 s (quick: 1 s).
fn overlap(r: &mut Runner, k: f64, quick: bool) -> Outcome {
    let k = k as usize;
    let mut bodies = vec![ground([0.0; 3], 50.0)];
    let x0 = -(k as f64 - 1.0) * 0.25;
    bodies.extend((0..k).map(|i| unit_box([x0 + 0.5 * i as f64, 0.5, 0.0])));
    let mut sim = r.build(&Spec::new(GRAVITY, bodies));
    let mut fastest: f64 = 0.0;
    let ticks = r.ticks(if quick { 1.0 } else { 3.0 });
    run_while(r, sim.as_mut(), ticks, |sim| {
        for i in 1..=k {
            fastest = fastest.max(norm(sim.state(i).vel));
        }
        fastest <= OVERLAP_SPEED
    });
    let pos: Vec<[f64; 3]> = (1..=k).map(|i| sim.state(i).pos).collect();
    let mut closest = f64::INFINITY;
    for (i, a) in pos.iter().enumerate() {
        for b in &pos[i + 1..] {
            closest = closest.min(norm(sub(*a, *b)));
        }
    }
    Outcome::ok(
        fastest,
        format!("fastest {fastest:.3} m/s; closest centres at the end {closest:.3} m"),
    )
    .failed_if(!within(fastest, OVERLAP_SPEED), Failure::Wrong("too fast"))
    .failed_if(
        closest.is_nan() || closest < SEPARATED,
        Failure::Wrong("not separated"),
    )
}

/// Every sweep, in the order they are run and listed.
pub const SWEEPS: &[Sweep] = &[
    Sweep {
        name: "stack_height",
        title: "vertical stack of n unit boxes (1 m, 1000 kg/m³, μ = 0.5) on the ground, 10 s (quick: 1 s)",
        param: "boxes in the stack",
        unit: " boxes",
        metric: "top box's largest horizontal offset, m",
        criterion: "stands 10 s: the top box never more than 0.25 m off its axis nor 1 m below its start",
        limit: STAND_OFFSET,
        values: |q| {
            if q {
                vec![2.0, 5.0]
            } else {
                vec![
                    5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 40.0, 50.0, 60.0, 80.0, 100.0, 150.0, 200.0,
                ]
            }
        },
        log_x: false,
        stop_after: 2,
        trial: stack,
    },
    Sweep {
        name: "pyramid_base",
        title: "pyramid of base n unit boxes (n(n+1)/2 boxes, μ = 0.5), 10 s (quick: 1 s)",
        param: "boxes in the base",
        unit: "",
        metric: "any box's largest horizontal movement, m",
        criterion: "stands 10 s: no box ever more than 0.25 m sideways from its start nor 1 m below it",
        limit: STAND_OFFSET,
        values: |q| {
            if q {
                vec![3.0, 5.0]
            } else {
                vec![5.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 80.0]
            }
        },
        log_x: false,
        stop_after: 1,
        trial: pyramid,
    },
    Sweep {
        name: "pyramid_rest",
        title: "pyramid of base n unit boxes (μ = 0.5), sleeping off, 40 s (quick: 2 s)",
        param: "boxes in the base",
        unit: "",
        metric: "fastest box's speed through the last quarter of the run, m/s",
        criterion: "comes to rest: stands (as pyramid_base) and every box slower than 1 cm/s through the last 10 s",
        limit: REST_SPEED,
        values: |q| {
            if q {
                vec![3.0, 5.0]
            } else {
                vec![5.0, 10.0, 15.0, 20.0, 30.0]
            }
        },
        log_x: false,
        stop_after: 1,
        trial: pyramid_rest,
    },
    Sweep {
        name: "mass_ratio_pair",
        title: "a 1000 kg unit box on a light unit box (1000/ratio kg) on the ground, μ = 0.5, 5 s (quick: 2 s)",
        param: "mass ratio heavy : light",
        unit: ":1",
        metric: "worst penetration (box–box or light box–ground), m",
        criterion: "penetration never above 2 cm and the heavy box never 0.25 m off the light one's centre",
        limit: PAIR_PENETRATION,
        values: |q| {
            if q {
                vec![1.0, 100.0]
            } else {
                vec![1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1e3, 3e3, 1e4]
            }
        },
        log_x: true,
        stop_after: 0,
        trial: mass_pair,
    },
    Sweep {
        name: "mass_ratio_stack",
        title: "five unit boxes, light/heavy alternating from the bottom (L H L H L, heavy 1000 kg), μ = 0.5, 10 s (quick: 1 s)",
        param: "mass ratio heavy : light",
        unit: ":1",
        metric: "top box's largest drop below its start, m",
        criterion: "stands 10 s: the top box never 0.5 m below its start nor 0.25 m off its axis",
        limit: STACK5_DROP,
        values: |q| {
            if q {
                vec![1.0, 100.0]
            } else {
                vec![1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1e3, 3e3, 1e4]
            }
        },
        log_x: true,
        stop_after: 0,
        trial: mass_stack,
    },
    Sweep {
        name: "projectile_speed",
        title: "8 (quick: 2) spheres of radius 5 cm fired at a 1 cm static wall, 0–30° off its normal, from 3 m",
        param: "projectile speed, m/s",
        unit: " m/s",
        metric: "shots that end behind the wall (of 8)",
        criterion: "no shot tunnels (0 behind the wall), no fault, no speed above 1.5 × the launch speed",
        limit: 0.0,
        values: |q| {
            if q {
                vec![50.0, 500.0]
            } else {
                vec![
                    10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1e3, 2e3, 5e3, 1e4, 3e4, 1e5,
                ]
            }
        },
        log_x: true,
        stop_after: 0,
        trial: projectile,
    },
    Sweep {
        name: "far_stack",
        title: "stack of 3 unit boxes resting on a ground at distance d from the origin (along (1,1,1)): settles 1 s, then 10 s (quick: 1 s)",
        param: "distance from the origin, m",
        unit: " m",
        metric: "top box's largest distance from its rigid rest position after settling, m",
        criterion: "after settling, the top box stays within 1 cm of where a rigid stack rests (2.5 m above the ground's top), no fault",
        limit: FAR_REST,
        values: |q| {
            if q {
                vec![1.0, 1e5]
            } else {
                vec![1.0, 10.0, 100.0, 1e3, 1e4, 1e5, 1e6, 1e7]
            }
        },
        log_x: true,
        stop_after: 0,
        trial: far_stack,
    },
    Sweep {
        name: "far_roll",
        title: "ball of radius 0.5 m rolling at 2 m/s on a flat ground at distance d from the origin, 3 s (quick: 1 s)",
        param: "distance from the origin, m",
        unit: " m",
        metric: "largest position error against p(0) + v·t, m",
        criterion: "the ball stays within 1 cm of its closed form (rolling at constant speed), no fault",
        limit: ROLL_ERROR,
        values: |q| {
            if q {
                vec![1.0, 1e5]
            } else {
                vec![1.0, 10.0, 100.0, 1e3, 1e4, 1e5, 1e6, 1e7]
            }
        },
        log_x: true,
        stop_after: 0,
        trial: far_roll,
    },
    Sweep {
        name: "overlap",
        title: "k unit boxes spawned in a row on the ground, each overlapping its neighbours by half, 3 s (quick: 1 s)",
        param: "overlapping boxes k",
        unit: " boxes",
        metric: "fastest speed of any box while separating, m/s",
        criterion: "no box faster than 2 m/s, and all separated at the end (every two centres ≥ 0.99 m apart)",
        limit: OVERLAP_SPEED,
        values: |q| {
            if q {
                vec![2.0, 4.0]
            } else {
                vec![2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0, 32.0]
            }
        },
        log_x: false,
        stop_after: 2,
        trial: overlap,
    },
    Sweep {
        name: "landing",
        title: "unit box thrown flat at (5, 2, 0) m/s, its bottom 1 m above the floor (μ = 0.5, e = 0), stepped at 3840 Hz down to 60 Hz, 2.5 s",
        param: "step length, ms",
        unit: " ms",
        metric: "rest point's distance from the closed form (rigid landing, Coulomb friction), m",
        criterion: "comes to rest within 1 cm of where a rigid box does (x = 4.170 m)",
        limit: LANDING_ERROR,
        values: |q| {
            let rates: &[f64] = if q { &[480.0, 60.0] } else { &LANDING_RATES };
            // Rounded to 0.1 µs for the tables; the rate comes back exact.
            rates.iter().map(|r| (1e7 / r).round() / 1e4).collect()
        },
        log_x: true,
        stop_after: 0,
        trial: landing,
    },
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sweeps_are_named_once_and_ascend() {
        for (i, s) in SWEEPS.iter().enumerate() {
            assert!(SWEEPS[i + 1..].iter().all(|t| t.name != s.name));
            for quick in [false, true] {
                let v = (s.values)(quick);
                assert!(
                    !v.is_empty() && v.windows(2).all(|w| w[0] < w[1]),
                    "{}",
                    s.name
                );
                assert!(!s.log_x || v[0] > 0.0);
            }
            assert!((s.values)(true).len() <= 2, "quick stays tiny");
        }
    }

    #[test]
    fn the_thrown_box_rests_where_the_closed_form_says() {
        // Flight 0.6993 s to x = 3.4965 m, hitting at 4.8602 m/s; it slides
        // on at 5 − 0.5·4.8602 = 2.5699 m/s for 0.6733 m.
        assert!((landing_rest() - 4.1698).abs() < 1e-4, "{}", landing_rest());
        let ms = (SWEEPS.iter().find(|s| s.name == "landing").unwrap().values)(false);
        let rates: Vec<u32> = ms.iter().map(|m| (1000.0 / m).round() as u32).collect();
        assert_eq!(rates, [3840, 1920, 960, 480, 240, 120, 60]);
    }

    #[test]
    fn the_far_point_is_at_the_given_distance() {
        assert!((norm(far(1e7)) - 1e7).abs() < 1e-6);
    }

    /// Every shot's straight path meets the wall's face inside its edges
    /// (by at least a radius), at 0–30° off the normal, from 3 m.
    #[test]
    fn every_projectile_is_aimed_at_the_wall() {
        for quick in [false, true] {
            let n = shots(quick);
            let mut points = Vec::new();
            for k in 0..n {
                let (at, back) = aim(k, n);
                assert!((norm(back) - 1.0).abs() < 1e-12);
                let angle = back[0].acos().to_degrees();
                assert!((-1e-9..=30.0 + 1e-9).contains(&angle), "{angle}");
                assert!(at[0] > WALL_HALF[0], "the sphere starts in front");
                assert!(at[1].abs() + SHOT_RADIUS < WALL_HALF[1]);
                assert!(at[2].abs() + SHOT_RADIUS < WALL_HALF[2]);
                points.push([at[1], at[2]]);
            }
            let distinct = points
                .iter()
                .enumerate()
                .all(|(i, p)| points[i + 1..].iter().all(|q| q != p));
            assert!(distinct, "each shot hits its own point");
        }
        let (_, last) = aim(7, 8);
        assert!((last[0].acos().to_degrees() - 30.0).abs() < 1e-9);
    }
}
