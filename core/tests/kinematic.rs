//! Kinematic bodies: driven by velocity or by a target pose, never by
//! forces.

use lockstep_core::shape::{Cuboid, Shape};
use lockstep_core::{
    BodyDesc, ColliderDesc, Quat, Scalar, Transform, Vec3, World, WorldConfig, WorldError,
};
use lockstep_testsupport::s;

fn platform(w: &mut World) -> lockstep_core::BodyHandle {
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
    k
}

#[test]
fn a_target_pose_is_reached_exactly_at_the_end_of_the_step() {
    let mut w = World::new(WorldConfig::default()).unwrap();
    let k = platform(&mut w);
    let target = Transform::new(
        Vec3::new(s(0.25), s(1.5), s(-0.125)),
        Quat::from_axis_angle(Vec3::Y, s(0.3)).normalize(),
    );
    w.set_kinematic_target(k, target).unwrap();
    let r = w.step();
    assert_eq!(r.kinematic_bodies, 1);
    let body = w.body(k).unwrap();
    assert_eq!(body.pose(), target);
    // It moved with the velocity that reaches the target in one tick, and
    // stops once the game stops steering it.
    assert!(body.linear_velocity().is_zero());
    w.step();
    assert_eq!(w.body(k).unwrap().pose(), target);
}

#[test]
fn velocity_driven_kinematic_bodies_ignore_gravity_forces_and_impulses() {
    let mut w = World::new(WorldConfig::default()).unwrap();
    let k = platform(&mut w);
    w.set_linear_velocity(k, Vec3::new(s(2.0), Scalar::ZERO, Scalar::ZERO))
        .unwrap();
    for _ in 0..60 {
        w.apply_force(k, Vec3::new(Scalar::ZERO, s(1000.0), Scalar::ZERO))
            .unwrap();
        w.apply_impulse(k, Vec3::new(Scalar::ZERO, s(1000.0), Scalar::ZERO))
            .unwrap();
        w.step();
    }
    let p = w.body(k).unwrap().position();
    assert!((p.x.to_f64() - 2.0).abs() < 1e-6, "{p:?}");
    assert!(p.y.is_zero() && p.z.is_zero());
    assert!(w.body(k).unwrap().mass().is_zero());
}

#[test]
fn targets_are_refused_for_bodies_that_are_not_kinematic() {
    let mut w = World::new(WorldConfig::default()).unwrap();
    let b = w.create_body(&BodyDesc::dynamic().name("crate")).unwrap();
    let err = w.set_kinematic_target(b, Transform::IDENTITY).unwrap_err();
    assert!(matches!(err, WorldError::InvalidParameter(_)));
    assert_eq!(
        err.to_string(),
        "invalid body parameter: set_kinematic_target needs a kinematic body; \"crate\" is dynamic"
    );
    w.remove_body(b).unwrap();
    assert_eq!(
        w.set_kinematic_target(b, Transform::IDENTITY),
        Err(WorldError::InvalidBody(b))
    );
}

/// How the platform is driven in [`box_rides_a_platform`].
#[derive(Clone, Copy, Debug)]
enum Drive {
    Velocity,
    Target,
}

/// A 1 m box resting on a 4 m × 0.4 m × 4 m kinematic platform (friction
/// 0.5); once the box sleeps, the platform speeds up to 2 m/s along x over
/// 1 s (2 m/s², under the μg = 4.9 m/s² friction can give, so the box need
/// not slip) and then holds 2 m/s for 5 s. Returns the largest drift of the
/// box relative to the platform along x, the largest |Δy| from its resting
/// height, and the platform's final x.
fn box_rides_a_platform(drive: Drive) -> (f64, f64, f64) {
    let mut w = World::new(WorldConfig::default()).unwrap();
    let k = platform(&mut w);
    let b = w
        .create_body(&BodyDesc::dynamic().position(Vec3::new(s(0.3), s(0.7), s(-0.2))))
        .unwrap();
    w.add_collider(
        b,
        ColliderDesc::new(Shape::Cuboid(Cuboid {
            half_extents: Vec3::splat(s(0.5)),
        })),
    )
    .unwrap();
    for _ in 0..120 {
        w.step();
    }
    assert!(w.body(b).unwrap().is_sleeping(), "the box settles first");
    let rest = w.body(b).unwrap().center_of_mass();
    let offset = rest.x.to_f64() - w.body(k).unwrap().position().x.to_f64();
    let (mut drift, mut lift) = (0.0f64, 0.0f64);
    let mut x = Scalar::ZERO;
    for tick in 1..=360 {
        // Speed this tick: ramps by 2/60 m/s per tick up to 2 m/s.
        let v = Scalar::from_ratio(2 * tick.min(60), 60);
        match drive {
            Drive::Velocity => w
                .set_linear_velocity(k, Vec3::new(v, Scalar::ZERO, Scalar::ZERO))
                .unwrap(),
            Drive::Target => {
                x += v * w.dt();
                w.set_kinematic_target(
                    k,
                    Transform::new(Vec3::new(x, Scalar::ZERO, Scalar::ZERO), Quat::IDENTITY),
                )
                .unwrap()
            }
        }
        let r = w.step();
        assert!(!r.overflowed());
        let px = w.body(k).unwrap().position().x.to_f64();
        let c = w.body(b).unwrap().center_of_mass();
        drift = drift.max((c.x.to_f64() - px - offset).abs());
        lift = lift.max((c.y.to_f64() - rest.y.to_f64()).abs());
    }
    (drift, lift, w.body(k).unwrap().position().x.to_f64())
}

#[test]
fn a_box_rides_a_platform_moving_at_2_m_per_s_for_5_s() {
    for drive in [Drive::Velocity, Drive::Target] {
        let (drift, lift, end) = box_rides_a_platform(drive);
        eprintln!("{drive:?}: drift {drift:.2e} m, lift {lift:.2e} m, platform at {end:.3} m");
        // The platform went 61/60 m in the ramp (Σ 2k/60 · 1/60, k = 1..60)
        // and 10 m in 5 s at 2 m/s.
        assert!(
            (end - (10.0 + 61.0 / 60.0)).abs() < 1e-4,
            "{drive:?}: platform at {end}"
        );
        // The ramp's 2 m/s² is under μg, so the box sticks: it follows
        // within 0.5 mm (the soft contacts' give while the ramp accelerates
        // it; sliding off the 4 m platform would take 1.5 m) and stays on
        // top.
        assert!(drift < 5e-4, "{drive:?}: box drifted {drift} m");
        assert!(lift < 0.01, "{drive:?}: box moved {lift} m vertically");
    }
}
