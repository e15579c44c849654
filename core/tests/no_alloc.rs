//! `step()` (and `step_observed()`) allocates nothing once the world is
//! warm: proven with a counting global allocator. It counts per thread (the
//! test harness's own threads allocate at any time), and the world is
//! stepped on the test's thread.

use lockstep_core::shape::{Cuboid, Shape, Sphere};
use lockstep_core::world::{Stage, StepObserver};
use lockstep_core::{
    BodyDesc, BodyHandle, ColliderDesc, ContactOrder, ContactRows, Quat, Scalar, StepReport,
    Transform, Vec3, World, WorldConfig,
};
use lockstep_testsupport::alloc::{Counting, allocations};
use lockstep_testsupport::s;

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Fifty spinning boxes and spheres dropped just onto a floor, and a
/// kinematic body.
fn scene(sleep: bool) -> (World, BodyHandle) {
    scene_in(sleep, ContactOrder::Pairs)
}

fn scene_in(sleep: bool, order: ContactOrder) -> (World, BodyHandle) {
    scene_with(sleep, order, ContactRows::Exact)
}

fn scene_with(sleep: bool, order: ContactOrder, rows: ContactRows) -> (World, BodyHandle) {
    let mut cfg = WorldConfig::default();
    cfg.sleep.enabled = sleep;
    cfg.contact_order = order;
    cfg.contact_rows = rows;
    let mut w = World::new(cfg).unwrap();
    for i in 0..50 {
        let f = i as f64;
        let b = w
            .create_body(
                &BodyDesc::dynamic()
                    .position(Vec3::new(s(f), s(10.0), Scalar::ZERO))
                    .angular_velocity(Vec3::new(s(1.0), s(2.0 + f * 0.1), s(0.5))),
            )
            .unwrap();
        let shape = if i % 2 == 0 {
            Shape::Cuboid(Cuboid {
                half_extents: Vec3::new(s(0.2), s(0.5), s(0.9)),
            })
        } else {
            Shape::Sphere(Sphere { radius: s(0.5) })
        };
        w.add_collider(b, ColliderDesc::new(shape)).unwrap();
    }
    // A floor just under them, so contacts exist through the whole run
    // (spinning boxes tumble and settle, spinning spheres roll on): without
    // it the bodies only brushed against each other, and whether a pair
    // still touched after the warm-up was luck.
    let floor = w
        .create_body(&BodyDesc::fixed().position(Vec3::new(s(24.5), s(9.0), Scalar::ZERO)))
        .unwrap();
    w.add_collider(
        floor,
        ColliderDesc::new(Shape::Cuboid(Cuboid {
            half_extents: Vec3::new(s(40.0), s(0.5), s(40.0)),
        })),
    )
    .unwrap();
    let k = w.create_body(&BodyDesc::kinematic()).unwrap();
    (w, k)
}

/// Steps `w` once and checks that it allocated only if its report says a
/// buffer grew (an exceeded capacity is reported, never hidden); returns
/// the report.
fn checked_step(w: &mut World, t: u32) -> StepReport {
    let before = allocations();
    let r = w.step();
    let allocated = allocations() - before;
    assert!(
        allocated == 0 || r.buffer_growths > 0,
        "step {t} allocated {allocated} times without reporting a growth"
    );
    r
}

/// Steps the scene until it is warm: at least 60 ticks, and then until 60
/// ticks in a row have grown no buffer (the tumbling bodies meet new
/// partners for a while; when the last pair appears depends on the solver's
/// every bit). Returns how many steps grew a buffer.
fn warm_up(w: &mut World) -> u32 {
    let (mut growth_steps, mut quiet) = (0, 0);
    for t in 0..600 {
        let grew = checked_step(w, t).buffer_growths > 0;
        growth_steps += grew as u32;
        quiet = if grew { 0 } else { quiet + 1 };
        if quiet >= 60 {
            return growth_steps;
        }
    }
    panic!("the scene still grew buffers after 600 ticks");
}

/// Moves the kinematic body `k` along x with the tick and steps once,
/// without faults.
fn drive_and_step(w: &mut World, k: BodyHandle, t: i64) -> StepReport {
    let target = Transform::new(
        Vec3::new(Scalar::from_ratio(t, 60), s(1.0), Scalar::ZERO),
        Quat::IDENTITY,
    );
    w.set_kinematic_target(k, target).unwrap();
    let r = w.step();
    assert!(r.faults.is_empty(), "step {t}: {}", r.faults);
    r
}

/// Without sleeping the scene reaches a state where no buffer grows, and
/// from then on steps allocate nothing.
#[test]
fn step_does_not_allocate_once_warm() {
    let (mut w, k) = scene(false);
    // While warming up, buffers grow as contact pairs appear: every step that
    // allocates must say so in its report (an exceeded capacity is reported,
    // never hidden).
    let growth_steps = warm_up(&mut w);
    assert!(
        growth_steps > 0,
        "the warm-up should have grown the contact buffers"
    );
    assert!(
        w.step().touching_pairs > 0,
        "the test scene has touching pairs"
    );
    let before = allocations();
    for t in 0..200 {
        let r = drive_and_step(&mut w, k, t);
        assert!(r.contact_constraints > 0, "step {t} solved no contact");
    }
    let after = allocations();
    assert_eq!(
        after - before,
        0,
        "step() allocated {} times",
        after - before
    );
    // An observed step adds no allocation of its own (the observer here
    // counts into a fixed array, as an observer must).
    let mut counts = StageCounts([0; Stage::ALL.len()]);
    let before = allocations();
    for _ in 0..50 {
        let r = w.step_observed(&mut counts);
        assert!(r.faults.is_empty());
    }
    let after = allocations();
    assert_eq!(after - before, 0, "step_observed() allocated");
    // Every stage was reported: once a step, the substep ones per substep.
    for st in Stage::ALL {
        let per_step = if st.per_substep() {
            w.config().substeps
        } else {
            1
        };
        assert_eq!(counts.0[st.index()], 50 * per_step, "{st:?}");
    }
}

/// Colour order with its colours split over two workers: the worker
/// threads start in `set_workers`, and a warm step allocates nothing (on
/// this thread, which does the colouring and its share of every pass; the
/// helpers run the same visits).
#[test]
fn colour_order_on_two_workers_does_not_allocate_once_warm() {
    let (mut w, k) = scene_in(false, ContactOrder::Colors);
    w.set_workers(2);
    warm_up(&mut w);
    let before = allocations();
    for t in 0..200 {
        let r = drive_and_step(&mut w, k, t);
        assert!(r.contact_colors > 1, "step {t} coloured nothing");
    }
    assert_eq!(allocations() - before, 0, "step() allocated");
}

/// The narrow contact rows, their lanes on, in colour order on two
/// workers: a warm step allocates nothing either.
#[test]
fn narrow_rows_with_their_lanes_do_not_allocate_once_warm() {
    let (mut w, k) = scene_with(false, ContactOrder::Colors, ContactRows::Narrow);
    w.set_workers(2);
    w.set_lanes(true);
    warm_up(&mut w);
    let before = allocations();
    for t in 0..200 {
        let r = drive_and_step(&mut w, k, t);
        assert!(
            r.narrow_constraints > 0,
            "step {t}: nothing on the narrow rows"
        );
    }
    assert_eq!(allocations() - before, 0, "step() allocated");
}

/// Counts the calls per stage.
struct StageCounts([u32; Stage::ALL.len()]);

impl StepObserver for StageCounts {
    fn finished(&mut self, stage: Stage) {
        self.0[stage.index()] += 1;
    }
}

/// With sleeping, bodies falling asleep move to the broad phase's static
/// tree, whose node pool grows: the step that did it reports the growth
/// (it used to show only in the next step's report).
#[test]
fn a_step_that_allocates_says_so_as_bodies_fall_asleep() {
    let (mut w, _) = scene(true);
    let mut fell_asleep = 0;
    for t in 0..300 {
        fell_asleep += checked_step(&mut w, t).fell_asleep;
    }
    assert!(fell_asleep > 0, "some bodies fell asleep");
}
