//! Islands and sleeping: touching bodies fall asleep together, a scene at
//! rest stops changing, and what a sleeper rests on waking it when it moves
//! or vanishes.

use lockstep_core::shape::{Cuboid, Shape};
use lockstep_core::{
    BodyDesc, BodyHandle, ColliderDesc, Material, Scalar, Transform, Vec3, World, WorldConfig,
};
use lockstep_testsupport::{s, v};

fn world() -> World {
    World::new(WorldConfig::default()).unwrap()
}

/// A static ground whose top face is y = 0 (friction `mu`).
fn ground(w: &mut World, mu: f64) -> BodyHandle {
    let g = w
        .create_body(&BodyDesc::fixed().name("ground").position(v(0.0, -1.0, 0.0)))
        .unwrap();
    w.add_collider(
        g,
        ColliderDesc::new(Shape::Cuboid(Cuboid {
            half_extents: v(100.0, 1.0, 100.0),
        }))
        .material(Material {
            friction: s(mu),
            restitution: Scalar::ZERO,
        }),
    )
    .unwrap();
    g
}

fn cube(w: &mut World, at: Vec3, vel: Vec3, half: f64, mu: f64) -> BodyHandle {
    let b = w
        .create_body(&BodyDesc::dynamic().position(at).linear_velocity(vel))
        .unwrap();
    w.add_collider(
        b,
        ColliderDesc::new(Shape::Cuboid(Cuboid {
            half_extents: v(half, half, half),
        }))
        .material(Material {
            friction: s(mu),
            restitution: Scalar::ZERO,
        }),
    )
    .unwrap();
    b
}

fn asleep(w: &World, b: BodyHandle) -> bool {
    w.body(b).unwrap().is_sleeping()
}

fn step(w: &mut World) -> lockstep_core::StepReport {
    let r = w.step();
    assert!(r.faults.is_empty(), "fault at tick {}", r.tick);
    r
}

#[test]
fn a_resting_box_stays_awake_while_the_box_on_it_still_slides() {
    // The bottom box rests from the start; the top one slides on it at
    // 1 m/s with μ = 0.1 (stops after v²/(2μg) ≈ 0.51 m, ≈ 1.0 s). Alone the
    // bottom box would sleep after 0.5 s; in one island it waits for the top.
    let mut w = world();
    ground(&mut w, 1.0);
    let bottom = cube(&mut w, v(0.0, 1.0, 0.0), Vec3::ZERO, 1.0, 0.1);
    let top = cube(&mut w, v(-0.6, 2.5, 0.0), v(1.0, 0.0, 0.0), 0.5, 0.1);
    let mut bottom_slept = None;
    let mut top_slept = None;
    let mut islands_while_sliding = 0;
    for tick in 1..=300u32 {
        let r = step(&mut w);
        if tick == 30 {
            islands_while_sliding = r.islands;
        }
        if bottom_slept.is_none() && asleep(&w, bottom) {
            bottom_slept = Some(tick);
        }
        if top_slept.is_none() && asleep(&w, top) {
            top_slept = Some(tick);
        }
    }
    println!("bottom slept at tick {bottom_slept:?}, top at {top_slept:?}");
    assert_eq!(islands_while_sliding, 1, "the two boxes form one island");
    let (b, t) = (
        bottom_slept.expect("bottom sleeps"),
        top_slept.expect("top sleeps"),
    );
    assert_eq!(b, t, "the island falls asleep as a whole");
    // The top box slows under 0.05 m/s after (1 − 0.05)/(μg) ≈ 0.97 s (58
    // ticks), then rests for 0.5 s (30 ticks): 88. Alone, the bottom box
    // would have slept at tick 30.
    assert!(t >= 85, "not before the top box stopped (tick {t})");
}

#[test]
fn separate_piles_on_one_floor_are_separate_islands() {
    let mut w = world();
    ground(&mut w, 0.6);
    let a0 = cube(&mut w, v(-5.0, 0.5, 0.0), Vec3::ZERO, 0.5, 0.6);
    let a1 = cube(&mut w, v(-5.0, 1.5, 0.0), Vec3::ZERO, 0.5, 0.6);
    let b0 = cube(&mut w, v(5.0, 0.5, 0.0), Vec3::ZERO, 0.5, 0.6);
    // A lone box, falling: its own island, not touching anything yet.
    let c = cube(&mut w, v(0.0, 3.0, 0.0), Vec3::ZERO, 0.5, 0.6);
    let r = step(&mut w);
    assert_eq!(r.islands, 3, "pile a, box b, falling box c");
    // Pile a and box b rest from the start; c lands later and sleeps later.
    let mut first = [None; 4];
    for tick in 2..=200u32 {
        step(&mut w);
        for (k, &h) in [a0, a1, b0, c].iter().enumerate() {
            if first[k].is_none() && asleep(&w, h) {
                first[k] = Some(tick);
            }
        }
    }
    let [a0t, a1t, b0t, ct] = first.map(|t| t.expect("every body sleeps"));
    println!("asleep at ticks: a0 {a0t}, a1 {a1t}, b0 {b0t}, c {ct}");
    assert_eq!(a0t, a1t, "one island");
    assert!(ct > b0t, "the falling box does not hold the others awake");
    let r = step(&mut w);
    assert_eq!((r.islands, r.awake_bodies), (0, 0));
}

#[test]
fn a_scene_at_rest_sleeps_and_its_state_stops_changing() {
    let mut w = world();
    ground(&mut w, 0.6);
    let mut boxes = Vec::new();
    for i in 0..4 {
        for j in 0..3 {
            boxes.push(cube(
                &mut w,
                v(i as f64 * 1.5, 0.5 + j as f64 * 1.01, 0.0),
                Vec3::ZERO,
                0.5,
                0.6,
            ));
        }
    }
    let mut ticks = 0;
    while !boxes.iter().all(|&b| asleep(&w, b)) {
        step(&mut w);
        ticks += 1;
        assert!(ticks < 600, "the scene sleeps within 10 s");
    }
    println!("12 boxes asleep after {ticks} ticks");
    let bodies = w.body_hashes();
    let pairs = w.contact_pairs().to_vec();
    let mut hashes = std::collections::BTreeSet::new();
    for _ in 0..120 {
        let r = step(&mut w);
        assert_eq!(
            (r.awake_bodies, r.woken_by_contact, r.fell_asleep),
            (0, 0, 0)
        );
        assert_eq!(w.body_hashes(), bodies, "no body changes, bit for bit");
        assert_eq!(w.contact_pairs(), &pairs[..], "nor any contact or impulse");
        hashes.insert(w.state_hash());
    }
    // The hash still moves with the tick (it covers it), once per tick.
    assert_eq!(hashes.len(), 120);
}

#[test]
fn removing_the_body_a_sleeper_rests_on_wakes_it_and_it_falls() {
    let mut w = world();
    ground(&mut w, 0.6);
    let lower = cube(&mut w, v(0.0, 0.5, 0.0), Vec3::ZERO, 0.5, 0.6);
    let upper = cube(&mut w, v(0.0, 1.5, 0.0), Vec3::ZERO, 0.5, 0.6);
    for _ in 0..120 {
        step(&mut w);
    }
    assert!(asleep(&w, upper) && asleep(&w, lower));
    let y0 = w.body(upper).unwrap().position().y.to_f64();
    w.remove_body(lower).unwrap();
    assert!(!asleep(&w, upper), "removal wakes what rested on it");
    for _ in 0..60 {
        step(&mut w);
    }
    let y1 = w.body(upper).unwrap().position().y.to_f64();
    println!("upper box fell from {y0:.4} to {y1:.4} m");
    assert!((y1 - 0.5).abs() < 0.01, "it landed on the ground ({y1})");
}

#[test]
fn moving_a_static_body_wakes_the_sleepers_on_it() {
    let mut w = world();
    let shelf = w
        .create_body(&BodyDesc::fixed().position(v(0.0, 2.0, 0.0)))
        .unwrap();
    w.add_collider(
        shelf,
        ColliderDesc::new(Shape::Cuboid(Cuboid {
            half_extents: v(1.0, 0.1, 1.0),
        })),
    )
    .unwrap();
    ground(&mut w, 0.6);
    let b = cube(&mut w, v(0.0, 2.6, 0.0), Vec3::ZERO, 0.5, 0.6);
    for _ in 0..120 {
        step(&mut w);
    }
    assert!(asleep(&w, b));
    // The shelf is pulled out from under the box.
    w.set_pose(shelf, Transform::from_translation(v(10.0, 2.0, 0.0)))
        .unwrap();
    assert!(!asleep(&w, b));
    for _ in 0..90 {
        step(&mut w);
    }
    let y = w.body(b).unwrap().position().y.to_f64();
    assert!((y - 0.5).abs() < 0.01, "the box fell to the ground ({y})");
}

#[test]
fn a_body_on_a_slow_moving_platform_does_not_sleep() {
    // The platform moves at 0.02 m/s, under the sleep threshold: a box
    // riding it is under the threshold too, yet must not fall asleep (it
    // would be left behind, or woken and put to sleep again every 0.5 s).
    let mut w = world();
    let platform = w
        .create_body(
            &BodyDesc::kinematic()
                .position(v(0.0, -0.5, 0.0))
                .linear_velocity(v(0.02, 0.0, 0.0)),
        )
        .unwrap();
    w.add_collider(
        platform,
        ColliderDesc::new(Shape::Cuboid(Cuboid {
            half_extents: v(5.0, 0.5, 5.0),
        })),
    )
    .unwrap();
    let b = cube(&mut w, v(0.0, 0.5, 0.0), Vec3::ZERO, 0.5, 0.6);
    for _ in 0..300 {
        step(&mut w);
        assert!(!asleep(&w, b), "tick {}", w.tick());
    }
    let x = w.body(b).unwrap().position().x.to_f64();
    println!("box rode the platform to x = {x:.4} (platform moved 0.1 m)");
    assert!((x - 0.1).abs() < 0.005, "it moved with the platform ({x})");
}

/// Two 2 × 3 piles of unit boxes on the ground, stepped until every box
/// sleeps.
fn sleeping_piles(w: &mut World) -> Vec<BodyHandle> {
    ground(w, 0.6);
    let mut boxes = Vec::new();
    for pile in 0..2 {
        for i in 0..2 {
            for j in 0..3 {
                let x = pile as f64 * 6.0 + i as f64 * 1.02;
                boxes.push(cube(
                    w,
                    v(x, 0.5 + j as f64 * 1.01, 0.0),
                    Vec3::ZERO,
                    0.5,
                    0.6,
                ));
            }
        }
    }
    let mut ticks = 0;
    while !boxes.iter().all(|&b| asleep(w, b)) {
        step(w);
        ticks += 1;
        assert!(ticks < 600, "the piles sleep within 10 s");
    }
    boxes
}

#[test]
fn a_restored_world_with_sleepers_steps_bit_identically_to_the_original() {
    let mut w = world();
    let boxes = sleeping_piles(&mut w);
    // A box thrown at the first pile wakes it on impact; the second pile
    // sleeps throughout. One sleeper is woken by the game just before the
    // snapshot, so its proxy still says "sleeping" in the snapshot.
    cube(&mut w, v(-4.0, 1.5, 0.0), v(6.0, 0.0, 0.0), 0.3, 0.6);
    for _ in 0..5 {
        step(&mut w);
    }
    w.wake_body(boxes[11]).unwrap();
    let sleepers = boxes.iter().filter(|&&b| asleep(&w, b)).count();
    assert_eq!(sleepers, 11, "all but the woken box sleep at the snapshot");
    let mut r = World::restore(&w.snapshot()).unwrap();
    assert_eq!(r.state_hash(), w.state_hash());
    let mut woken = 0;
    for _ in 0..240 {
        let mut a = step(&mut w);
        let mut b = step(&mut r);
        // (The restored world's scratch buffers start empty and grow.)
        a.buffer_growths = 0;
        b.buffer_growths = 0;
        assert_eq!(a, b, "same report at tick {}", a.tick);
        assert_eq!(w.state_hash(), r.state_hash(), "tick {}", a.tick);
        woken += a.woken_by_contact;
    }
    assert_eq!(w.contact_pairs(), r.contact_pairs());
    assert!(woken >= 6, "the thrown box woke the first pile ({woken})");
}

#[test]
fn sleeping_pairs_are_kept_without_narrow_tests_or_constraints() {
    let mut w = world();
    let boxes = sleeping_piles(&mut w);
    let pairs = w.contact_pairs().to_vec();
    let touching = pairs.iter().filter(|p| p.touching).count() as u32;
    let points: u32 = pairs
        .iter()
        .filter(|p| p.touching)
        .map(|p| p.manifold.count as u32)
        .sum();
    assert!(touching >= 12, "each box touches the ground or a box");
    // A box falling far from the piles stays awake and touches nothing.
    cube(&mut w, v(50.0, 40.0, 50.0), Vec3::ZERO, 0.5, 0.6);
    for _ in 0..30 {
        let r = step(&mut w);
        assert_eq!((r.awake_bodies, r.sleeping_bodies), (1, boxes.len() as u32));
        assert_eq!((r.candidate_pairs, r.narrow_tests), (0, 0));
        assert_eq!(r.contact_constraints, 0);
        // The counters still cover the resting pairs.
        assert_eq!((r.touching_pairs, r.contact_points), (touching, points));
        assert_eq!(w.contact_pairs(), &pairs[..]);
    }
}

/// Steps a copy of `w` once after `calls`, returning its state hash.
fn hash_after(w: &World, calls: impl FnOnce(&mut World)) -> u64 {
    let mut w = w.clone();
    calls(&mut w);
    step(&mut w);
    w.state_hash()
}

#[test]
fn a_force_on_a_body_put_to_sleep_is_cleared_and_one_woken_again_is_applied() {
    let mut w = world();
    let boxes = sleeping_piles(&mut w);
    let top = boxes[2];
    let f = v(0.0, 0.0, 300.0);
    // Put to sleep after the force: the step clears it, as it clears every
    // body's forces, and the box does not move.
    let mut a = w.clone();
    a.apply_force(top, f).unwrap();
    a.sleep_body(top).unwrap();
    step(&mut a);
    let hot = a.body(top).unwrap().hot().clone();
    assert_eq!((hot.force, hot.sleeping), (Vec3::ZERO, true));
    let no_force = hash_after(&w, |w| {
        w.wake_body(top).unwrap();
        w.sleep_body(top).unwrap();
    });
    assert_eq!(a.state_hash(), no_force);
    // Woken again before the step: the force acts as if sleep_body had not
    // been called.
    let slept_and_woken = hash_after(&w, |w| {
        w.apply_force(top, f).unwrap();
        w.sleep_body(top).unwrap();
        w.wake_body(top).unwrap();
    });
    let pushed = hash_after(&w, |w| w.apply_force(top, f).unwrap());
    assert_eq!(slept_and_woken, pushed);
    assert_ne!(pushed, hash_after(&w, |_| {}));
}

#[test]
fn sleeping_and_awake_counts_stay_exact_as_bodies_come_and_go() {
    let mut w = world();
    let boxes = sleeping_piles(&mut w);
    let count = |w: &World| {
        let dynamic = w
            .body_handles()
            .filter(|&h| w.body(h).unwrap().kind() == lockstep_core::BodyKind::Dynamic);
        let (mut asleep_n, mut awake_n) = (0, 0);
        for h in dynamic {
            if asleep(w, h) {
                asleep_n += 1;
            } else {
                awake_n += 1;
            }
        }
        (awake_n, asleep_n)
    };
    // Remove a lone sleeper (held asleep in the air, touching nothing) and
    // an awake box, then reuse their slots.
    let lone = w
        .create_body(
            &BodyDesc::dynamic()
                .position(v(30.0, 10.0, 0.0))
                .asleep(true),
        )
        .unwrap();
    let flyer = cube(&mut w, v(-20.0, 30.0, 0.0), Vec3::ZERO, 0.5, 0.6);
    let r = step(&mut w);
    assert_eq!((r.awake_bodies, r.sleeping_bodies), (1, 13));
    assert_eq!(boxes.len(), 12);
    w.remove_body(lone).unwrap();
    w.remove_body(flyer).unwrap();
    let r = step(&mut w);
    assert_eq!((r.awake_bodies, r.sleeping_bodies), (0, 12));
    let a = cube(&mut w, v(-20.0, 30.0, 0.0), Vec3::ZERO, 0.5, 0.6);
    let b = w
        .create_body(
            &BodyDesc::dynamic()
                .position(v(20.0, 30.0, 0.0))
                .asleep(true),
        )
        .unwrap();
    for _ in 0..10 {
        let r = step(&mut w);
        assert_eq!((r.awake_bodies, r.sleeping_bodies), count(&w));
        assert_eq!((r.awake_bodies, r.sleeping_bodies), (1, 13));
    }
    w.wake_body(b).unwrap();
    w.sleep_body(a).unwrap();
    let r = step(&mut w);
    assert_eq!((r.awake_bodies, r.sleeping_bodies), count(&w));
    assert_eq!((r.awake_bodies, r.sleeping_bodies), (1, 13));
    assert!(!asleep(&w, b) && asleep(&w, a));
}

/// Sleeping dynamic bodies by a scan of every body.
fn sleepers(w: &World) -> u32 {
    w.body_handles().filter(|&h| asleep(w, h)).count() as u32
}

/// `bodies().sleeping_count()` is exact at any time, not only after a step:
/// in a new world, after the game wakes or puts bodies to sleep, and in a
/// restored world (it read 0 there until the first step, although every
/// body's own flag was right).
#[test]
fn the_sleeping_count_is_exact_between_steps_and_after_a_restore() {
    let mut w = world();
    let held = w
        .create_body(
            &BodyDesc::dynamic()
                .position(v(30.0, 10.0, 0.0))
                .asleep(true),
        )
        .unwrap();
    assert_eq!(w.bodies().sleeping_count(), 1, "created asleep");
    w.remove_body(held).unwrap();
    assert_eq!(w.bodies().sleeping_count(), 0, "removed");
    let boxes = sleeping_piles(&mut w);
    assert_eq!(w.bodies().sleeping_count(), 12);
    w.wake_body(boxes[3]).unwrap();
    assert_eq!(w.bodies().sleeping_count(), sleepers(&w));
    assert_eq!(sleepers(&w), 11);
    let r = World::restore(&w.snapshot()).unwrap();
    assert_eq!(r.bodies().sleeping_count(), 11, "restored");
    w.sleep_body(boxes[3]).unwrap();
    assert_eq!(w.bodies().sleeping_count(), 12, "put to sleep");
}
