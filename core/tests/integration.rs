//! Linear motion against closed forms: free fall and projectiles, forces,
//! impulses, damping.

use lockstep_core::shape::{Shape, Sphere};
use lockstep_core::{BodyDesc, ColliderDesc, Scalar, Vec3, World, WorldConfig};
use lockstep_testsupport::s;

fn world(gravity: Vec3, substeps: u32) -> World {
    World::new(WorldConfig {
        gravity,
        substeps,
        ..WorldConfig::default()
    })
    .unwrap()
}

fn ball(world: &mut World, desc: BodyDesc) -> lockstep_core::BodyHandle {
    let b = world.create_body(&desc).unwrap();
    world
        .add_collider(
            b,
            ColliderDesc::new(Shape::Sphere(Sphere { radius: s(0.5) })),
        )
        .unwrap();
    b
}

/// Semi-implicit Euler with substep h: after n substeps
/// x_n = x0 + v0·t + ½·a·t² + ½·a·h·t (t = n·h). The last term is the
/// method's known error; everything else must match to rounding.
#[test]
fn projectile_matches_the_closed_form_plus_the_known_euler_term() {
    let g = -9.81;
    for substeps in [1u32, 2, 4] {
        let mut w = world(Vec3::new(Scalar::ZERO, s(g), Scalar::ZERO), substeps);
        let v0 = (3.0, 12.5, -1.25);
        let b = ball(
            &mut w,
            BodyDesc::dynamic()
                .position(Vec3::new(s(1.0), s(2.0), s(3.0)))
                .linear_velocity(Vec3::new(s(v0.0), s(v0.1), s(v0.2))),
        );
        let ticks = 120;
        for _ in 0..ticks {
            assert!(w.step().faults.is_empty());
        }
        let h = 1.0 / (60.0 * substeps as f64);
        let t = ticks as f64 / 60.0;
        let p = w.body(b).unwrap().position();
        let closed_y = 2.0 + v0.1 * t + 0.5 * g * t * t;
        let euler_term = 0.5 * g * h * t;
        let err_y = p.y.to_f64() - closed_y;
        println!(
            "substeps {substeps}: y error vs closed form {err_y:.6e} m, predicted {euler_term:.6e} m"
        );
        // Rounding: dt and g are rounded to 2^-32 and each substep rounds
        // v·h; over 480 substeps that stays far below 1e-6 m.
        assert!(
            (err_y - euler_term).abs() < 1e-6,
            "substeps {substeps}: {err_y} vs {euler_term}"
        );
        // Horizontal motion is exact up to the rounding of h.
        assert!((p.x.to_f64() - (1.0 + v0.0 * t)).abs() < 1e-6);
        assert!((p.z.to_f64() - (3.0 + v0.2 * t)).abs() < 1e-6);
        let v = w.body(b).unwrap().linear_velocity();
        assert!((v.y.to_f64() - (v0.1 + g * t)).abs() < 1e-6);
    }
}

#[test]
fn constant_force_accelerates_by_f_over_m() {
    let mut w = world(Vec3::ZERO, 4);
    let b = ball(&mut w, BodyDesc::dynamic());
    let m = w.body(b).unwrap().mass().to_f64();
    // 4/3·π·0.125·1000 = 523.6 kg
    assert!(
        (m - 4.0 / 3.0 * std::f64::consts::PI * 0.125 * 1000.0).abs() < 1e-3,
        "{m}"
    );
    for _ in 0..60 {
        w.apply_force(b, Vec3::new(s(1000.0), Scalar::ZERO, Scalar::ZERO))
            .unwrap();
        w.step();
    }
    let v = w.body(b).unwrap().linear_velocity().x.to_f64();
    assert!((v - 1000.0 / m).abs() < 1e-6, "{v}");
}

#[test]
fn forces_last_one_step_and_impulses_act_at_once() {
    let mut w = world(Vec3::ZERO, 2);
    let b = ball(&mut w, BodyDesc::dynamic());
    let m = w.body(b).unwrap().mass();
    w.apply_impulse(b, Vec3::new(Scalar::ZERO, m * s(2.0), Scalar::ZERO))
        .unwrap();
    assert!((w.body(b).unwrap().linear_velocity().y.to_f64() - 2.0).abs() < 1e-6);
    w.apply_force(b, Vec3::new(m * s(60.0), Scalar::ZERO, Scalar::ZERO))
        .unwrap();
    w.step();
    w.step();
    // 60 m/s² for one tick of 1/60 s adds 1 m/s, and only once.
    assert!((w.body(b).unwrap().linear_velocity().x.to_f64() - 1.0).abs() < 1e-6);
}

#[test]
fn an_off_centre_impulse_spins_the_body() {
    let mut w = world(Vec3::ZERO, 1);
    let b = ball(&mut w, BodyDesc::dynamic());
    let body = w.body(b).unwrap();
    let (m, i) = (body.mass().to_f64(), body.inertia().xx.to_f64());
    // 2/5 m r²
    assert!((i - 0.4 * m * 0.25).abs() / i < 1e-6);
    w.apply_impulse_at_point(
        b,
        Vec3::new(Scalar::ZERO, s(10.0), Scalar::ZERO),
        Vec3::new(s(0.5), Scalar::ZERO, Scalar::ZERO),
    )
    .unwrap();
    let body = w.body(b).unwrap();
    // ω = r × j / I about +z.
    assert!((body.angular_velocity().z.to_f64() - 5.0 / i).abs() < 1e-6);
    assert!((body.linear_velocity().y.to_f64() - 10.0 / m).abs() < 1e-7);
}

#[test]
fn linear_damping_follows_the_implicit_decay() {
    let mut w = world(Vec3::ZERO, 1);
    let b = ball(
        &mut w,
        BodyDesc::dynamic()
            .linear_velocity(Vec3::new(s(10.0), Scalar::ZERO, Scalar::ZERO))
            .damping(s(0.5), Scalar::ZERO),
    );
    for _ in 0..60 {
        w.step();
    }
    // v_n = v0 / (1 + h c)^n
    let expected = 10.0 / (1.0f64 + 0.5 / 60.0).powi(60);
    assert!((w.body(b).unwrap().linear_velocity().x.to_f64() - expected).abs() < 1e-6);
}

#[test]
fn a_body_at_rest_in_zero_gravity_falls_asleep_and_wakes_on_impulse() {
    let mut w = world(Vec3::ZERO, 1);
    let b = ball(
        &mut w,
        BodyDesc::dynamic().linear_velocity(Vec3::new(s(0.01), Scalar::ZERO, Scalar::ZERO)),
    );
    let mut slept_at = None;
    for t in 1..=60 {
        let r = w.step();
        if r.fell_asleep == 1 {
            slept_at = Some(t);
        }
    }
    // 0.5 s at 60 Hz: asleep after the 30th step.
    assert_eq!(slept_at, Some(30));
    let body = w.body(b).unwrap();
    assert!(body.is_sleeping());
    assert!(body.linear_velocity().is_zero());
    let h_before = w.state_hash();
    let p = body.position();
    let r = w.step();
    assert_eq!(r.awake_bodies, 0);
    assert_eq!(r.sleeping_bodies, 1);
    assert_eq!(w.body(b).unwrap().position(), p);
    assert_ne!(w.state_hash(), h_before, "the tick is part of the hash");
    w.apply_impulse(b, Vec3::new(s(100.0), Scalar::ZERO, Scalar::ZERO))
        .unwrap();
    assert!(!w.body(b).unwrap().is_sleeping());
    assert_eq!(w.step().awake_bodies, 1);
}
