//! Kinematic bodies: driven by velocity or by a target pose, never by
//! forces.

use lockstep_core::shape::{Cuboid, Shape};
use lockstep_core::{
    BodyDesc, ColliderDesc, Quat, Scalar, Transform, Vec3, World, WorldConfig, WorldError,
};

fn s(v: f64) -> Scalar {
    Scalar::from_f64_lossy(v)
}

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
