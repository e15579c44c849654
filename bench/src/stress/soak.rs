//! The long soak: a mixed pile (boxes, spheres, capsules and octahedral
//! hulls) dropped into a walled pit and stepped for one simulated hour
//! with sleeping on, in every engine; once a minute one body is kicked
//! upwards, so the pile wakes, churns and settles again sixty times. It
//! counts faults (our overflow flag, NaN for Rapier), energy growth (above
//! the energy right after the last kick), bodies that never sleep, and
//! violations of the invariant "a body whose pose stays the same bit for
//! bit must not gain speed" ([`Frozen`]).

use crate::accuracy::closed::{G, angular_momentum_energy, dot, inertia, norm};
use crate::accuracy::run::Runner;
use crate::accuracy::sim::{BodySpec, Engine, Settings, ShapeSpec, Sim, Spec, State};

/// Simulated seconds of the soak.
pub fn seconds(quick: bool) -> f64 {
    if quick { 20.0 } else { 3600.0 }
}

/// The energy reference is first taken this long after the drop, s; one
/// body is kicked this often from then on.
pub fn settle_seconds(quick: bool) -> f64 {
    if quick { 5.0 } else { 60.0 }
}

/// The kick: this velocity, m/s, given to dynamic body `7 n mod 48` at the
/// `n`-th kick.
pub const KICK: [f64; 3] = [1.0, 6.0, 0.5];

/// Largest energy growth after settling allowed, as the height the whole
/// pile's weight would be lifted by: ΔE / (M g), m.
pub const ENERGY_LIFT: f64 = 0.01;
/// A pose must stay frozen this many ticks after its speed gained before
/// the gain counts.
pub const FROZEN_TICKS: usize = 30;

/// Pose bits: position and orientation as stored (every engine's numbers
/// convert to `f64` exactly, so equal bits here are equal bits there).
fn pose_bits(s: &State) -> [u64; 7] {
    let mut out = [0; 7];
    for (o, v) in out.iter_mut().zip(s.pos.iter().chain(&s.rot)) {
        *o = v.to_bits();
    }
    out
}

/// The invariant check for one body: a pose that stays the same bit for
/// bit for [`FROZEN_TICKS`] ticks in a row while the speed (linear plus
/// angular) stays above 1.5 × its value when the pose froze, plus 1 mm/s,
/// is one violation (counted once per frozen episode). At 1 mm/s a body
/// moves about 4 µm per substep, thousands of units in the last place of
/// any engine's numbers here, so a frozen pose at that speed is never
/// rounding. A single tick whose velocity jumps before the pose has moved
/// (an impulse from the velocity-only relax pass, as when a resting body
/// is hit) is not a violation: the pose moves on the next tick.
#[derive(Clone, Debug, Default)]
pub struct Frozen {
    pose: Option<[u64; 7]>,
    gained: usize,
    speed_at_freeze: f64,
    flagged: bool,
    /// Violations seen.
    pub violations: usize,
}

impl Frozen {
    /// Looks at the body's state after a tick.
    pub fn observe(&mut self, s: &State) {
        let pose = pose_bits(s);
        let speed = norm(s.vel) + norm(s.omega);
        if self.pose == Some(pose) {
            if speed > 1.5 * self.speed_at_freeze + 1e-3 {
                self.gained += 1;
            } else {
                self.gained = 0;
            }
            if self.gained >= FROZEN_TICKS && !self.flagged {
                self.violations += 1;
                self.flagged = true;
            }
        } else {
            self.pose = Some(pose);
            self.gained = 0;
            self.speed_at_freeze = speed;
            self.flagged = false;
        }
    }
}

/// The pile: 48 bodies, a quarter each of boxes, spheres, capsules and
/// octahedra, in three layers of a 4 × 4 grid 3, 5.5 and 8 m up (landing
/// at up to 12 m/s), each tilted, over a 6 × 6 m pit with 4 m walls and a
/// static 1.8 × 1 × 1.8 m pedestal in its middle.
pub fn spec() -> Spec {
    let wall = |pos, half| BodySpec::fixed(ShapeSpec::Cuboid(half), pos).material(0.5, 0.0);
    let mut bodies = vec![
        wall([0.0, -1.0, 0.0], [4.0, 1.0, 4.0]),
        wall([3.25, 2.0, 0.0], [0.25, 2.0, 3.5]),
        wall([-3.25, 2.0, 0.0], [0.25, 2.0, 3.5]),
        wall([0.0, 2.0, 3.25], [3.5, 2.0, 0.25]),
        wall([0.0, 2.0, -3.25], [3.5, 2.0, 0.25]),
        // A static pedestal in the middle: tilted capsules and boxes of the
        // first layers land on a static box at 7–10 m/s.
        wall([0.0, 0.5, 0.0], [0.9, 0.5, 0.9]),
    ];
    let shapes = [
        ShapeSpec::Cuboid([0.3, 0.3, 0.3]),
        ShapeSpec::Sphere(0.3),
        ShapeSpec::Capsule(0.3, 0.2),
        ShapeSpec::Octahedron(0.4),
    ];
    for layer in 0..3 {
        for j in 0..16 {
            let i = layer * 16 + j;
            let x = -1.8 + 1.2 * (j % 4) as f64;
            let z = -1.8 + 1.2 * (j / 4) as f64;
            let angle = 0.4 + 0.37 * i as f64;
            let (s, c) = (angle / 2.0).sin_cos();
            let k = std::f64::consts::FRAC_1_SQRT_2;
            bodies.push(
                BodySpec::dynamic(shapes[(i + layer) % 4], [x, 3.0 + 2.5 * layer as f64, z])
                    .material(0.5, 0.0)
                    .rot([s * k, 0.0, s * k, c]),
            );
        }
    }
    let mut spec = Spec::new([0.0, -G, 0.0], bodies);
    spec.sleep = true;
    spec
}

/// What one engine's soak found.
#[derive(Clone, Debug)]
pub struct SoakResult {
    /// The engine.
    pub engine: Engine,
    /// Simulated seconds actually stepped (less than asked if it failed).
    pub seconds: f64,
    /// The generic failure (fault, NaN, explosion), if any.
    pub failure: Option<&'static str>,
    /// Largest energy growth above the energy right after the last kick
    /// (or the settled energy before the first), as a lift of the pile's
    /// weight, m.
    pub energy_lift: f64,
    /// Bodies awake at every tick of the soak's last quarter.
    pub never_sleep: usize,
    /// Invariant violations (frozen pose, growing speed), all bodies.
    pub violations: usize,
    /// The shapes of the bodies with a violation, one entry per body.
    pub violators: Vec<&'static str>,
    /// Bodies asleep at the end.
    pub asleep_at_end: usize,
    /// Dynamic bodies.
    pub bodies: usize,
    /// CPU ms per simulated second.
    pub ms: f64,
    /// Kicks given.
    pub kicks: usize,
    /// (simulated time, energy above the reference in J) once per chart
    /// bin: the bin's largest.
    pub series: Vec<(f64, f64)>,
}

impl SoakResult {
    /// Whether every check passed.
    pub fn passed(&self) -> bool {
        self.failure.is_none()
            && self.energy_lift <= ENERGY_LIFT
            && self.never_sleep == 0
            && self.violations == 0
    }

    /// `ok` or the first check that failed.
    pub fn status(&self) -> &'static str {
        if let Some(f) = self.failure {
            f
        } else if self.violations > 0 {
            "frozen pose gaining speed"
        } else if self.energy_lift > ENERGY_LIFT {
            "energy grew"
        } else if self.never_sleep > 0 {
            "never sleeps"
        } else {
            "ok"
        }
    }
}

/// A shape's kind, for the report.
fn shape_name(s: ShapeSpec) -> &'static str {
    match s {
        ShapeSpec::Sphere(_) => "sphere",
        ShapeSpec::Cuboid(_) => "box",
        ShapeSpec::Capsule(..) => "capsule",
        ShapeSpec::Octahedron(_) => "hull",
    }
}

/// Points in the chart's series.
const BINS: usize = 240;

/// Runs the soak in one engine.
pub fn run(engine: Engine, settings: Settings, quick: bool) -> SoakResult {
    let spec = spec();
    let dynamic: Vec<usize> = (0..spec.bodies.len())
        .filter(|&i| !spec.bodies[i].fixed)
        .collect();
    let props: Vec<(f64, [f64; 3])> = dynamic
        .iter()
        .map(|&i| {
            let b = &spec.bodies[i];
            (b.mass(), inertia(b.shape, b.mass()))
        })
        .collect();
    let total_mass: f64 = props.iter().map(|p| p.0).sum();
    let mut r = Runner::new(engine, settings);
    let mut sim = r.build(&spec);
    let ticks = r.ticks(seconds(quick));
    let settle = r.ticks(settle_seconds(quick));
    let last_quarter = ticks - ticks / 4;
    let per_bin = ticks.div_ceil(BINS);
    let mut frozen = vec![Frozen::default(); dynamic.len()];
    let mut awake_all_along = vec![true; dynamic.len()];
    let (mut reference, mut growth) = (f64::NAN, 0.0f64);
    let mut series = Vec::new();
    let mut bin_max = f64::NEG_INFINITY;
    let mut stepped = 0;
    let mut kicks = 0;
    let energy_of = |sim: &dyn Sim| -> f64 {
        let mut energy = 0.0;
        for (k, &i) in dynamic.iter().enumerate() {
            let s = sim.state(i);
            let (m, inert) = props[k];
            let (_, rot) = angular_momentum_energy(s.rot, s.omega, inert);
            energy += m * G * s.pos[1] + 0.5 * m * dot(s.vel, s.vel) + rot;
        }
        energy
    };
    for tick in 1..=ticks {
        r.step(sim.as_mut());
        stepped = tick;
        if r.failure().is_some() {
            break;
        }
        for (k, &i) in dynamic.iter().enumerate() {
            frozen[k].observe(&sim.state(i));
            if tick > last_quarter && sim.sleeping(i) {
                awake_all_along[k] = false;
            }
        }
        let energy = energy_of(sim.as_ref());
        if tick == settle {
            reference = energy;
        }
        if tick > settle {
            growth = growth.max(energy - reference);
            bin_max = bin_max.max(energy - reference);
        }
        if tick % per_bin == 0 && tick > settle {
            series.push((tick as f64 * r.dt(), bin_max));
            bin_max = f64::NEG_INFINITY;
        }
        if tick % settle == 0 && tick < ticks {
            sim.set_linvel(dynamic[(7 * kicks) % dynamic.len()], KICK);
            kicks += 1;
            reference = energy_of(sim.as_ref());
        }
    }
    let asleep_at_end = dynamic.iter().filter(|&&i| sim.sleeping(i)).count();
    SoakResult {
        engine,
        seconds: stepped as f64 * r.dt(),
        failure: r.failure().map(|f| f.name()),
        energy_lift: growth / (total_mass * G),
        never_sleep: if stepped > last_quarter {
            awake_all_along.iter().filter(|&&a| a).count()
        } else {
            0
        },
        violations: frozen.iter().map(|f| f.violations).sum(),
        violators: dynamic
            .iter()
            .zip(&frozen)
            .filter(|(_, f)| f.violations > 0)
            .map(|(&i, _)| shape_name(spec.bodies[i].shape))
            .collect(),
        asleep_at_end,
        bodies: dynamic.len(),
        kicks,
        ms: r.ms_per_simulated_second(),
        series,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(x: f64, v: f64) -> State {
        State {
            pos: [x, 1.0, 0.0],
            rot: [0.0, 0.0, 0.0, 1.0],
            vel: [v, 0.0, 0.0],
            omega: [0.0; 3],
        }
    }

    #[test]
    fn a_frozen_pose_gaining_speed_is_one_violation() {
        let mut f = Frozen::default();
        for k in 0..100 {
            f.observe(&state(0.5, 0.1 * k as f64));
        }
        assert_eq!(f.violations, 1, "counted once per episode");
        // It moves, then freezes again and gains again: a second one.
        for k in 0..100 {
            f.observe(&state(0.75, 0.1 * k as f64));
        }
        assert_eq!(f.violations, 2);
    }

    #[test]
    fn moving_or_resting_bodies_are_no_violation() {
        let mut f = Frozen::default();
        for k in 0..200 {
            // Moving while speeding up: fine.
            f.observe(&state(0.001 * k as f64, 0.1 * k as f64));
        }
        for _ in 0..200 {
            // Resting with a constant reported speed (a contact's −g·dt/2):
            // not a gain.
            f.observe(&state(2.0, 0.08));
        }
        for _ in 0..200 {
            f.observe(&state(3.0, 0.0));
        }
        assert_eq!(f.violations, 0);
        // A gain shorter than the frozen window does not count either.
        let mut g = Frozen::default();
        for k in 0..FROZEN_TICKS {
            g.observe(&state(5.0, k as f64));
        }
        assert_eq!(g.violations, 0);
        // A resting body hit after a long rest: its velocity jumps one tick
        // before its pose moves.
        let mut h = Frozen::default();
        for _ in 0..100 {
            h.observe(&state(6.0, 1e-10));
        }
        h.observe(&state(6.0, 3e-3));
        for k in 0..100 {
            h.observe(&state(6.0 + 1e-4 * k as f64, 3e-3));
        }
        assert_eq!(h.violations, 0);
    }

    #[test]
    fn the_pile_is_mixed_and_fits_the_pit() {
        let spec = spec();
        let dynamic: Vec<&BodySpec> = spec.bodies.iter().filter(|b| !b.fixed).collect();
        assert_eq!(dynamic.len(), 48);
        for kind in 0..4 {
            let n = dynamic
                .iter()
                .filter(|b| {
                    matches!(
                        (kind, b.shape),
                        (0, ShapeSpec::Cuboid(_))
                            | (1, ShapeSpec::Sphere(_))
                            | (2, ShapeSpec::Capsule(..))
                            | (3, ShapeSpec::Octahedron(_))
                    )
                })
                .count();
            assert_eq!(n, 12, "kind {kind}");
        }
        assert!(
            dynamic
                .iter()
                .all(|b| b.pos[0].abs() < 2.5 && b.pos[2].abs() < 2.5)
        );
        assert!(spec.sleep);
    }
}
