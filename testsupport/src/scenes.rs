//! Scenes and helpers that several tests share: the zero-gravity world,
//! the ground, and the walled pit with a paddle and a seeded pile.

use lockstep_core::shape::{Cuboid, Shape};
use lockstep_core::{
    BodyDesc, BodyHandle, ColliderDesc, ContactOrder, Material, Quat, Vec3, World, WorldConfig,
};

use crate::{Rng, s, v};

/// A result vector as f64 components, for comparing with closed forms.
pub fn f(v: Vec3) -> [f64; 3] {
    [v.x.to_f64(), v.y.to_f64(), v.z.to_f64()]
}

/// A world with the default configuration but no gravity: projectiles and
/// colliding pairs then move in straight lines the test can predict.
pub fn zero_g() -> World {
    World::new(WorldConfig {
        gravity: Vec3::ZERO,
        ..WorldConfig::default()
    })
    .unwrap()
}

/// A static ground 400 m × 400 m whose top face is y = 0, of material `m`:
/// the floor of the closed-form solver and friction tests.
pub fn ground(w: &mut World, m: Material) -> BodyHandle {
    let g = w
        .create_body(&BodyDesc::fixed().name("ground").position(v(0.0, -1.0, 0.0)))
        .unwrap();
    w.add_collider(
        g,
        ColliderDesc::new(Shape::Cuboid(Cuboid {
            half_extents: v(200.0, 1.0, 200.0),
        }))
        .material(m),
    )
    .unwrap();
    g
}

/// A walled pit with a kinematic paddle turning in it, and `n` random
/// boxes, spheres and capsules dropped in (seeded: the same pile every
/// run).
pub fn pile(order: ContactOrder, n: usize, seed: u64) -> World {
    pile_in(
        WorldConfig {
            contact_order: order,
            ..WorldConfig::default()
        },
        n,
        seed,
    )
}

/// Steps tick `t` of a world from [`pile`]: first its kinematic "paddle"
/// (if it has one) is sent to turn about y by `t/40` rad, then the world
/// steps; panics on a fault.
pub fn step_pile(w: &mut World, t: u64) -> lockstep_core::StepReport {
    if let Some(k) = w.find_body("paddle") {
        let a = s(t as f64 / 40.0);
        w.set_kinematic_target(
            k,
            lockstep_core::Transform::new(
                v(0.0, 0.6, 0.0),
                Quat::from_axis_angle(v(0.0, 1.0, 0.0), a),
            ),
        )
        .unwrap();
    }
    let r = w.step();
    assert!(r.faults.is_empty(), "tick {t}: {}", r.faults);
    r
}

/// [`pile`] in a world of the given configuration.
pub fn pile_in(config: WorldConfig, n: usize, seed: u64) -> World {
    let mut w = World::new(config).unwrap();
    let ground = w
        .create_body(&BodyDesc::fixed().position(v(0.0, -0.5, 0.0)))
        .unwrap();
    w.add_collider(ground, ColliderDesc::cuboid(s(6.0), s(0.5), s(6.0)))
        .unwrap();
    for (x, z, hx, hz) in [
        (4.0, 0.0, 0.2, 4.0),
        (-4.0, 0.0, 0.2, 4.0),
        (0.0, 4.0, 4.0, 0.2),
        (0.0, -4.0, 4.0, 0.2),
    ] {
        let wall = w
            .create_body(&BodyDesc::fixed().position(v(x, 2.0, z)))
            .unwrap();
        w.add_collider(wall, ColliderDesc::cuboid(s(hx), s(2.0), s(hz)))
            .unwrap();
    }
    let paddle = w
        .create_body(
            &BodyDesc::kinematic()
                .name("paddle")
                .position(v(0.0, 0.6, 0.0)),
        )
        .unwrap();
    w.add_collider(paddle, ColliderDesc::cuboid(s(3.0), s(0.2), s(0.3)))
        .unwrap();
    let mut rng = Rng::new(seed);
    let mut unit = || rng.unit();
    for i in 0..n {
        let (layer, k) = (i / 36, i % 36);
        let pos = v(
            -3.0 + (k % 6) as f64 + 0.3 * unit(),
            1.5 + layer as f64 * 0.9,
            -3.0 + (k / 6) as f64 + 0.3 * unit(),
        );
        let rot =
            Quat::from_axis_angle(v(unit(), 1.0, unit()).normalize_or_zero(), s(unit() * 3.0));
        let b = w
            .create_body(&BodyDesc::dynamic().position(pos).rotation(rot))
            .unwrap();
        let shape = match i % 3 {
            0 => ColliderDesc::cuboid(s(0.2 + 0.2 * unit()), s(0.2), s(0.3)),
            1 => ColliderDesc::sphere(s(0.25 + 0.1 * unit())),
            _ => ColliderDesc::capsule(s(0.2), s(0.2)),
        };
        w.add_collider(b, shape).unwrap();
    }
    w
}
