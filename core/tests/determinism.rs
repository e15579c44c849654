//! Determinism: the same scene run twice gives the same hash every tick;
//! snapshots restore exactly; hashes see every change; an observed step is
//! a plain step.

use lockstep_core::math::FaultScope;
use lockstep_core::shape::{Cuboid, Shape, Sphere};
use lockstep_core::world::{Stage, StepObserver};
use lockstep_core::{
    BodyDesc, ColliderDesc, Faults, Quat, Scalar, Transform, Vec3, World, WorldConfig,
};
use lockstep_testsupport::s;

/// A mixed scene: spinning anisotropic boxes, a compound, a kinematic body
/// steered each tick, forces and impulses from a scripted "game".
fn build() -> World {
    let mut w = World::new(WorldConfig::default()).unwrap();
    let ground = w
        .create_body(&BodyDesc::fixed().name("ground").position(Vec3::new(
            Scalar::ZERO,
            s(-1.0),
            Scalar::ZERO,
        )))
        .unwrap();
    w.add_collider(
        ground,
        ColliderDesc::new(Shape::Cuboid(Cuboid {
            half_extents: Vec3::new(s(50.0), s(1.0), s(50.0)),
        })),
    )
    .unwrap();
    for i in 0..20 {
        let f = i as f64;
        let b = w
            .create_body(
                &BodyDesc::dynamic()
                    .name(format!("box{i}"))
                    .position(Vec3::new(s(f * 0.7), s(5.0 + f), s(-f * 0.3)))
                    .rotation(Quat::from_axis_angle(
                        Vec3::new(s(0.6), s(0.0), s(0.8)),
                        s(f * 0.37),
                    ))
                    .linear_velocity(Vec3::new(s(1.0 - f * 0.1), s(3.0), s(0.25)))
                    .angular_velocity(Vec3::new(s(f * 0.3), s(2.0 - f * 0.2), s(0.7))),
            )
            .unwrap();
        w.add_collider(
            b,
            ColliderDesc::new(Shape::Cuboid(Cuboid {
                half_extents: Vec3::new(s(0.1 + f * 0.01), s(0.3), s(0.55)),
            })),
        )
        .unwrap();
        if i % 5 == 0 {
            w.add_collider(
                b,
                ColliderDesc::new(Shape::Sphere(Sphere { radius: s(0.2) })).local_pose(
                    Transform::from_translation(Vec3::new(s(0.4), s(0.1), Scalar::ZERO)),
                ),
            )
            .unwrap();
        }
    }
    let k = w
        .create_body(&BodyDesc::kinematic().name("platform"))
        .unwrap();
    w.add_collider(
        k,
        ColliderDesc::new(Shape::Cuboid(Cuboid {
            half_extents: Vec3::new(s(2.0), s(0.2), s(2.0)),
        })),
    )
    .unwrap();
    w
}

/// Per-tick game input, a pure function of the tick.
fn drive(w: &mut World, tick: u64) {
    drive_but(w, tick, None);
}

/// [`drive`], except that the impulse on box3 is left out at tick `skip`.
fn drive_but(w: &mut World, tick: u64, skip: Option<u64>) {
    let k = w.find_body("platform").unwrap();
    let t = Scalar::from_ratio(tick as i64, 60);
    let x = lockstep_core::math::elem::sin_cos(t).0 * s(3.0);
    w.set_kinematic_target(
        k,
        Transform::new(
            Vec3::new(x, s(1.0), Scalar::ZERO),
            Quat::from_axis_angle(Vec3::Y, t),
        ),
    )
    .unwrap();
    if tick.is_multiple_of(30) && skip != Some(tick) {
        let b = w.find_body("box3").unwrap();
        w.apply_impulse_at_point(
            b,
            Vec3::new(s(5.0), s(0.0), s(-2.0)),
            Vec3::new(s(0.0), s(10.0), s(0.0)),
        )
        .unwrap();
    }
    let b = w.find_body("box7").unwrap();
    w.apply_torque(b, Vec3::new(s(0.5), s(-0.25), s(0.1)))
        .unwrap();
}

/// The state hash and the body hashes (which do not include the tick)
/// after each of `ticks` steps, driven by [`drive_but`].
fn run_but(ticks: u64, skip: Option<u64>) -> Vec<(u64, Vec<u64>)> {
    let mut w = build();
    (0..ticks)
        .map(|t| {
            drive_but(&mut w, t, skip);
            let r = w.step();
            assert!(r.faults.is_empty(), "tick {t}: {}", r.faults);
            let bodies = w.body_hashes().into_iter().map(|(_, h)| h).collect();
            (w.state_hash(), bodies)
        })
        .collect()
}

fn run(ticks: u64) -> Vec<(u64, Vec<u64>)> {
    run_but(ticks, None)
}

#[test]
fn the_same_scene_run_twice_gives_the_same_hash_every_tick() {
    let a = run(1000);
    let b = run(1000);
    assert_eq!(a, b);
    // The bodies' hashes, which leave the tick out, change every tick (the
    // steered platform never stops): the state hash changing alone proved
    // nothing, since the tick is one of its words.
    assert!(a.windows(2).all(|w| w[0].1 != w[1].1));
}

/// Two worlds at the same tick with different motion hash differently: one
/// impulse left out at tick 30 makes the hashes differ from that tick on,
/// and they agree before it.
#[test]
fn the_hash_tells_apart_worlds_at_the_same_tick_that_moved_differently() {
    let a = run(120);
    let b = run_but(120, Some(30));
    for (t, (x, y)) in a.iter().zip(&b).enumerate() {
        if t < 30 {
            assert_eq!(x.0, y.0, "tick {t}: the same so far");
        } else {
            assert_ne!(x.0, y.0, "tick {t}: box3 moved differently");
        }
    }
}

#[test]
fn snapshot_restore_at_tick_k_continues_identically_for_1000_ticks() {
    let k = 137;
    let mut straight = build();
    for t in 0..k {
        drive(&mut straight, t);
        straight.step();
    }
    let bytes = straight.snapshot();
    let mut restored = World::restore(&bytes).unwrap();
    assert_eq!(restored.state_hash(), straight.state_hash());
    assert_eq!(restored, straight);
    for t in k..k + 1000 {
        drive(&mut straight, t);
        drive(&mut restored, t);
        straight.step();
        restored.step();
        assert_eq!(restored.state_hash(), straight.state_hash(), "tick {t}");
    }
}

#[test]
fn corrupt_snapshots_are_errors_not_panics() {
    let mut w = build();
    w.step();
    let bytes = w.snapshot();
    assert!(World::restore(b"nonsense").is_err());
    assert!(World::restore(&bytes[..bytes.len() / 2]).is_err());
    let mut extra = bytes.clone();
    extra.push(0);
    assert!(World::restore(&extra).is_err());
    // Flip bits all over the payload: every result is Ok or Err, never a panic.
    let mut rng = lockstep_testsupport::Rng::new(99);
    for _ in 0..2000 {
        let x = rng.next_u64();
        let mut b = bytes.clone();
        let i = 8 + (x >> 33) as usize % (b.len() - 8);
        b[i] ^= 1 << ((x >> 20) % 8);
        if let Ok(mut w2) = World::restore(&b) {
            w2.step();
        }
    }
}

#[test]
fn body_hashes_name_the_body_that_changed() {
    let mut a = build();
    let mut b = build();
    for t in 0..10 {
        drive(&mut a, t);
        drive(&mut b, t);
        a.step();
        b.step();
    }
    let target = b.find_body("box11").unwrap();
    let v = b.body(target).unwrap().linear_velocity();
    b.set_linear_velocity(
        target,
        v + Vec3::new(Scalar::DELTA, Scalar::ZERO, Scalar::ZERO),
    )
    .unwrap();
    assert_ne!(a.state_hash(), b.state_hash());
    let diff: Vec<_> = a
        .body_hashes()
        .into_iter()
        .zip(b.body_hashes())
        .filter(|(x, y)| x.1 != y.1)
        .map(|(x, _)| x.0)
        .collect();
    assert_eq!(diff, vec![target]);
}

/// A body's field dump holds exactly the words of its hash (the fields
/// before its contacts, hashed in order, give its body hash), and after a
/// nudge of the angular velocity that field is named among those that
/// changed, by the nudge (to within the momentum round trip's roundings).
#[test]
fn body_fields_are_the_hashed_words_and_name_the_field_that_changed() {
    let mut a = build();
    let mut b = build();
    for t in 0..300 {
        drive(&mut a, t);
        drive(&mut b, t);
        a.step();
        b.step();
    }
    for (handle, hash) in a.body_hashes() {
        let fields = a.body_fields(handle).unwrap();
        let mut h = lockstep_core::hash::StateHasher::new();
        for f in fields
            .iter()
            .take_while(|f| !f.name.starts_with("contact "))
        {
            for &w in &f.words {
                h.word(w);
            }
        }
        assert_eq!(h.finish(), hash, "body {handle}");
    }
    // The ground's dump carries its contacts.
    let floor = a.find_body("ground").unwrap();
    assert!(
        a.body_fields(floor)
            .unwrap()
            .iter()
            .any(|f| f.name.contains("impulses"))
    );
    let target = b.find_body("box11").unwrap();
    let v = b.body(target).unwrap().angular_velocity();
    // A nudge of 2⁻¹⁶ rad/s about y. The velocity is set through the
    // angular momentum it implies (`I ω`, then `I⁻¹ L`), whose roundings
    // move a turned box's components by a few ulps besides.
    let nudge = Scalar::from_bits(1 << 16);
    b.set_angular_velocity(target, v + Vec3::new(Scalar::ZERO, nudge, Scalar::ZERO))
        .unwrap();
    let (fa, fb) = (
        a.body_fields(target).unwrap(),
        b.body_fields(target).unwrap(),
    );
    assert_eq!(fa.len(), fb.len());
    let differ: Vec<_> = fa.iter().zip(&fb).filter(|(x, y)| x != y).collect();
    let names: Vec<&str> = differ.iter().map(|(x, _)| x.name.as_str()).collect();
    // The angular velocity and the momentum it implies are both set.
    assert!(names.contains(&"angular_velocity"), "{names:?}");
    let (x, y) = differ
        .iter()
        .find(|(x, _)| x.name == "angular_velocity")
        .unwrap();
    assert_eq!(x.kind, lockstep_core::world::FieldKind::Scalar);
    let moved = |k: usize| y.words[k].wrapping_sub(x.words[k]) as i64;
    assert!((moved(1) - (1 << 16)).abs() <= 8, "{x:?} {y:?}");
    assert!(moved(0).abs() <= 8 && moved(2).abs() <= 8, "{x:?} {y:?}");
}

/// Records the stages it is told about (preallocated: an observer must not
/// allocate), and raises an overflow fault at each one when `faulty`.
struct Recorder {
    stages: Vec<Stage>,
    faulty: bool,
}

impl StepObserver for Recorder {
    fn finished(&mut self, stage: Stage) {
        self.stages.push(stage);
        if self.faulty {
            lockstep_core::math::faults::raise(Faults::OVERFLOW);
        }
    }
}

/// A unit box resting on a ground box, stepped with `substeps`.
fn resting_box(substeps: u32) -> World {
    let mut w = World::new(WorldConfig {
        substeps,
        ..WorldConfig::default()
    })
    .unwrap();
    let ground = w
        .create_body(&BodyDesc::fixed().position(Vec3::new(Scalar::ZERO, s(-1.0), Scalar::ZERO)))
        .unwrap();
    let cube = |h: f64| {
        ColliderDesc::new(Shape::Cuboid(Cuboid {
            half_extents: Vec3::new(s(h), s(1.0f64.min(h)), s(h)),
        }))
    };
    w.add_collider(ground, cube(10.0)).unwrap();
    let b = w
        .create_body(&BodyDesc::dynamic().position(Vec3::new(Scalar::ZERO, s(0.5), Scalar::ZERO)))
        .unwrap();
    w.add_collider(b, cube(0.5)).unwrap();
    w
}

#[test]
fn an_observed_step_reports_the_documented_stages_in_order() {
    use Stage::*;
    for substeps in [1, 4] {
        let mut w = resting_box(substeps);
        let mut rec = Recorder {
            stages: Vec::with_capacity(64),
            faulty: false,
        };
        // The second step: the box touches the ground, the solver works.
        w.step();
        let r = w.step_observed(&mut rec);
        assert!(r.contact_constraints == 1 && r.contact_points >= 4, "{r:?}");
        let mut want = vec![
            AwakeList,
            KinematicTargets,
            BroadPhase,
            NarrowPhase,
            WakeTouched,
            PrepareContacts,
            CcdBegin,
        ];
        for _ in 0..substeps {
            want.extend([
                IntegrateVelocities,
                WarmStart,
                Solve,
                IntegratePositions,
                Relax,
            ]);
        }
        want.extend([
            Restitution,
            StoreImpulses,
            FinishVelocities,
            Ccd,
            SnapKinematic,
            ClearForces,
            Sleep,
            SyncProxies,
        ]);
        assert_eq!(rec.stages, want, "substeps {substeps}");
        if substeps == 1 {
            // `Stage::ALL` is the order of a one-substep step.
            assert_eq!(rec.stages, Stage::ALL);
        }
    }
    for (i, st) in Stage::ALL.iter().enumerate() {
        assert_eq!(st.index(), i);
        assert!(Stage::ALL[..i].iter().all(|o| o.name() != st.name()));
        let in_loop = matches!(
            st,
            IntegrateVelocities | WarmStart | Solve | IntegratePositions | Relax
        );
        assert_eq!(st.per_substep(), in_loop, "{st:?}");
    }
}

#[test]
fn an_observed_step_gives_the_same_state_and_report_as_a_plain_one() {
    let mut plain = build();
    let mut observed = build();
    let mut rec = Recorder {
        stages: Vec::with_capacity(64),
        faulty: false,
    };
    let mut contacts = 0;
    for t in 0..400 {
        drive(&mut plain, t);
        drive(&mut observed, t);
        let a = plain.step();
        rec.stages.clear();
        let b = observed.step_observed(&mut rec);
        assert_eq!(a, b, "tick {t}");
        assert_eq!(plain.state_hash(), observed.state_hash(), "tick {t}");
        assert_eq!(rec.stages.len(), 7 + 5 * 4 + 8);
        contacts += a.contact_points;
    }
    // The comparison covered steps with contacts, not only free flight.
    assert!(contacts > 0);
    assert_eq!(plain, observed);
}

#[test]
fn faults_raised_by_the_observer_are_not_the_steps() {
    let mut plain = build();
    let mut observed = build();
    let mut rec = Recorder {
        stages: Vec::with_capacity(64),
        faulty: true,
    };
    for t in 0..20 {
        drive(&mut plain, t);
        drive(&mut observed, t);
        let a = plain.step();
        rec.stages.clear();
        let (b, outside) = FaultScope::run(|| observed.step_observed(&mut rec));
        assert!(
            b.faults.is_empty() && b.sticky_faults.is_empty(),
            "tick {t}"
        );
        assert_eq!(a, b, "tick {t}");
        assert!(observed.faults().is_empty());
        // Nor the caller's: the observer's own scope swallowed them.
        assert!(outside.is_empty(), "tick {t}: {outside}");
    }
    assert_eq!(plain.state_hash(), observed.state_hash());
}

/// A body's game value and the world's game state are state: hashed (only
/// when set, so a world that sets neither hashes as before), named in the
/// body's fields, and carried by snapshots.
#[test]
fn user_data_and_game_state_are_hashed_named_and_restored() {
    let mut w = build();
    let h = w.body_handles().nth(1).unwrap();
    let (before, body_before) = (w.state_hash(), w.body_hashes()[1].1);
    w.set_user_data(h, 0).unwrap();
    assert_eq!(w.state_hash(), before, "zero is the unset value");
    w.set_user_data(h, 42).unwrap();
    assert_ne!(w.state_hash(), before);
    assert_ne!(w.body_hashes()[1].1, body_before);
    let fields = w.body_fields(h).unwrap();
    let f = fields.iter().find(|f| f.name == "user_data").unwrap();
    assert_eq!(f.words, [42]);
    let with_data = w.state_hash();
    w.game_state_mut().set_int("score", -3).unwrap();
    assert_ne!(w.state_hash(), with_data);
    let copy = World::restore(&w.snapshot()).unwrap();
    assert_eq!(copy.state_hash(), w.state_hash());
    assert_eq!(copy.body(h).unwrap().user_data(), 42);
    assert_eq!(copy.game_state().int("score"), Some(-3));
    // A stale handle is refused.
    w.remove_body(h).unwrap();
    assert!(w.set_user_data(h, 1).is_err());
}
