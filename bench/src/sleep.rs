//! The `sleep` suite: what sleeping bodies cost.
//!
//! 9,600 unit boxes (a 120 × 80 grid, 2 m apart) rest on the ground at
//! y = 0.5 (just touching it), plus one box in free fall (dropped from 40 m
//! far from the grid, so it stays awake for the whole run). Four variants
//! are stepped alternately:
//! * `asleep`: sleeping on; the 9,600 boxes are put to sleep with
//!   `World::sleep_body` right after placement (the bench does not rely on
//!   the solver to bring them to rest first), so they have no contact pairs;
//! * `asleep_pairs`: the same, but the boxes are put to sleep after one
//!   awake step, so each keeps its touching ground pair (9,600 resting pairs
//!   with 4 points each, as a pile that fell asleep has);
//! * `awake`: the same scene with sleeping off (what the sleepers would cost
//!   awake; without a contact solver these boxes sink through the ground);
//! * `one_box`: the ground and the falling box only: the fixed cost of a
//!   step, so `asleep − one_box` is what the sleepers still cost.

use std::fmt::Write as _;
use std::time::Instant;

use lockstep_core::SleepConfig;
use lockstep_core::{BodyDesc, ColliderDesc, Scalar, StepReport, Vec3, World};

use crate::engines::build_ours;
use crate::scenes::{BodyShape, Scene};
use crate::{Options, SuiteOutput};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Variant {
    Asleep,
    AsleepPairs,
    Awake,
    OneBox,
}

impl Variant {
    fn name(self) -> &'static str {
        match self {
            Variant::Asleep => "asleep",
            Variant::AsleepPairs => "asleep_pairs",
            Variant::Awake => "awake",
            Variant::OneBox => "one_box",
        }
    }
}

/// The resting grid: `nx` × `nz` boxes 2 m apart on a ground of half-extent
/// 200.
fn grid(nx: usize, nz: usize, steps: usize) -> Scene {
    let mut positions = Vec::with_capacity(nx * nz);
    for i in 0..nx {
        for k in 0..nz {
            positions.push([
                2.0 * i as f64 - (nx as f64 - 1.0),
                0.5,
                2.0 * k as f64 - (nz as f64 - 1.0),
            ]);
        }
    }
    Scene {
        name: "sleep_grid",
        ground_half: [200.0, 1.0, 200.0],
        ground_y: -1.0,
        shape: BodyShape::Cube(0.5),
        density: 100.0,
        friction: 0.6,
        positions,
        tops: Vec::new(),
        steps,
        statics: Vec::new(),
        joints: Vec::new(),
        collide: true,
    }
}

fn build(variant: Variant, scene: &Scene) -> World {
    let sleep = SleepConfig {
        enabled: variant != Variant::Awake,
        ..SleepConfig::default()
    };
    let mut resting = scene.clone();
    if variant == Variant::OneBox {
        resting.positions.clear();
    }
    let (mut world, bodies) = build_ours(&resting, sleep);
    if variant == Variant::AsleepPairs {
        // One awake step creates the ground pairs the sleepers then keep.
        world.step();
    }
    if matches!(variant, Variant::Asleep | Variant::AsleepPairs) {
        for &b in &bodies {
            world.sleep_body(b).expect("live body");
        }
    }
    let falling = world
        .create_body(&BodyDesc::dynamic().position(Vec3::from_ints(0, 40, -150)))
        .expect("falling body");
    world
        .add_collider(
            falling,
            ColliderDesc::new(lockstep_core::shape::Shape::Cuboid(
                lockstep_core::shape::Cuboid {
                    half_extents: Vec3::splat(Scalar::HALF),
                },
            ))
            .density(Scalar::from_int(100)),
        )
        .expect("falling collider");
    world
}

/// One variant's figures.
#[derive(Clone, Debug)]
struct Figures {
    variant: Variant,
    bodies: usize,
    ms: Vec<f64>,
    last: StepReport,
}

fn run_once(variant: Variant, scene: &Scene) -> (f64, StepReport, usize) {
    let mut world = build(variant, scene);
    let bodies = world.bodies().len();
    let mut total = 0.0;
    let mut last = StepReport::default();
    for i in 0..scene.steps {
        let t = Instant::now();
        last = world.step();
        if i > 0 {
            total += t.elapsed().as_secs_f64();
        }
    }
    (total * 1e3 / (scene.steps.max(2) - 1) as f64, last, bodies)
}

fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn min(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::INFINITY, f64::min)
}

/// Runs the suite.
pub fn run(opts: &Options) -> SuiteOutput {
    let (nx, nz, steps) = if opts.quick {
        (12, 8, 5)
    } else {
        (120, 80, 120)
    };
    let runs = opts.runs.unwrap_or(if opts.quick { 1 } else { 5 });
    let scene = grid(nx, nz, steps);
    eprintln!(
        "sleep: {} resting boxes + 1 falling, {steps} steps, {runs} runs per variant...",
        scene.positions.len()
    );
    let mut figs: Vec<Figures> = [
        Variant::Asleep,
        Variant::AsleepPairs,
        Variant::Awake,
        Variant::OneBox,
    ]
    .into_iter()
    .map(|variant| Figures {
        variant,
        bodies: 0,
        ms: Vec::new(),
        last: StepReport::default(),
    })
    .collect();
    for _ in 0..runs.max(1) {
        for f in &mut figs {
            let (ms, last, bodies) = run_once(f.variant, &scene);
            f.ms.push(ms);
            f.last = last;
            f.bodies = bodies;
        }
    }
    let awake_med = median(&figs[2].ms);
    let mut text = String::new();
    let _ = writeln!(
        text,
        "ours: tick_rate 60, substeps 4, gravity (0, -10, 0); {} resting boxes put to sleep with \
         World::sleep_body after placement (not brought to rest by the solver; asleep_pairs after one \
         awake step, keeping their ground pairs), one box falling from 40 m",
        scene.positions.len()
    );
    let _ = writeln!(
        text,
        "{:<12} {:>7} {:>9} {:>9} {:>9}  {:>6} {:>8} {:>10} {:>9} {:>8}",
        "variant",
        "bodies",
        "ms med",
        "ms min",
        "/awake",
        "awake",
        "sleeping",
        "candidates",
        "touching",
        "contacts"
    );
    let mut csv = String::from(
        "suite,variant,bodies,steps,runs,ms_median,ms_min,ratio_to_awake,awake_bodies,sleeping_bodies,candidate_pairs,touching_pairs,contact_points\n",
    );
    for f in &figs {
        let med = median(&f.ms);
        let l = &f.last;
        let _ = writeln!(
            text,
            "{:<12} {:>7} {:>9.4} {:>9.4} {:>8.3}%  {:>6} {:>8} {:>10} {:>9} {:>8}",
            f.variant.name(),
            f.bodies,
            med,
            min(&f.ms),
            100.0 * med / awake_med,
            l.awake_bodies,
            l.sleeping_bodies,
            l.candidate_pairs,
            l.touching_pairs,
            l.contact_points
        );
        let _ = writeln!(
            csv,
            "sleep,{},{},{},{},{:.4},{:.4},{:.5},{},{},{},{},{}",
            f.variant.name(),
            f.bodies,
            steps,
            f.ms.len(),
            med,
            min(&f.ms),
            med / awake_med,
            l.awake_bodies,
            l.sleeping_bodies,
            l.candidate_pairs,
            l.touching_pairs,
            l.contact_points
        );
    }
    let asleep = median(&figs[0].ms);
    let asleep_pairs = median(&figs[1].ms);
    let one = median(&figs[3].ms);
    let sleepers = scene.positions.len().max(1) as f64;
    let _ = writeln!(
        text,
        "asleep/awake = {:.3}%, asleep_pairs/awake = {:.3}% (target < 1%); per sleeping body: \
         asleep − one_box = {:.3} ns, asleep_pairs − one_box = {:.3} ns; one_box = {:.4} ms/step \
         fixed cost.\n\
         What sleepers still cost (by reading World::step, not profiled): the per-body stages \
         walk a list of the awake slots, and the contact set updates only its active pairs, so \
         no stage visits a sleeper or a resting pair while nothing wakes. Left: a step that \
         wakes a sleeper walks every pair once (and rebuilds the active list); while any \
         contact has points, the contact solver's prepare clears and scans one word per body \
         slot; memory (hot state, per-slot scratch) stays per slot.\n\
         (counters are from the last step of the last run)",
        100.0 * asleep / awake_med,
        100.0 * asleep_pairs / awake_med,
        (asleep - one) * 1e6 / sleepers,
        (asleep_pairs - one) * 1e6 / sleepers,
        one
    );
    if figs[2].last.touching_pairs == 0 {
        let _ = writeln!(
            text,
            "note: at the end of the awake run no box touches the ground: the engine does not \
             resolve contacts yet and the boxes sank through it, so `awake` averages steps with \
             and without ground contacts"
        );
    }
    SuiteOutput { text, csv }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn asleep_variant_keeps_the_grid_asleep_and_only_the_faller_awake() {
        let scene = grid(4, 3, 3);
        assert_eq!(scene.positions.len(), 12);
        let (_, last, bodies) = run_once(Variant::Asleep, &scene);
        assert_eq!(bodies, 14, "ground + 12 + faller");
        assert_eq!(last.sleeping_bodies, 12);
        assert_eq!(last.awake_bodies, 1);
        assert_eq!(last.touching_pairs, 0, "put to sleep before any contact");
        let (_, last, _) = run_once(Variant::AsleepPairs, &scene);
        assert_eq!((last.sleeping_bodies, last.awake_bodies), (12, 1));
        assert_eq!(
            last.touching_pairs, 12,
            "each sleeper keeps its ground pair"
        );
        assert_eq!((last.narrow_tests, last.contact_constraints), (0, 0));
        let (_, last, _) = run_once(Variant::Awake, &scene);
        assert_eq!((last.sleeping_bodies, last.awake_bodies), (0, 13));
        let (_, last, bodies) = run_once(Variant::OneBox, &scene);
        assert_eq!((bodies, last.awake_bodies), (2, 1));
    }
}
