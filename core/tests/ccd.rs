//! Continuous collision: fast bodies, spinning rods and bullets do not pass
//! through thin shapes; slow bodies pay nothing; the stage is
//! deterministic.

use std::time::Instant;

use lockstep_testsupport::{Rng, f, s, v as v3, zero_g};

use lockstep_core::shape::{Capsule, Cuboid, Shape, Sphere};
use lockstep_core::world::CCD_TARGET_GAP;
use lockstep_core::{
    BodyDesc, BodyHandle, ColliderDesc, CollisionFilter, Material, Quat, Scalar, StepReport, Vec3,
    World, WorldConfig,
};

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// The projectile distributions of these tests, on the shared generator.
trait Draw {
    /// A uniformly random rotation (normalised random quaternion).
    fn rotation(&mut self) -> Quat;
}

impl Draw for Rng {
    fn rotation(&mut self) -> Quat {
        loop {
            let q = [
                self.uniform(-1.0, 1.0),
                self.uniform(-1.0, 1.0),
                self.uniform(-1.0, 1.0),
                self.uniform(-1.0, 1.0),
            ];
            let n = dot([q[0], q[1], q[2]], [q[0], q[1], q[2]]) + q[3] * q[3];
            if n > 0.01 && n <= 1.0 {
                return Quat::from_xyzw(s(q[0]), s(q[1]), s(q[2]), s(q[3])).normalize();
            }
        }
    }
}

/// The frame of a thin target: centre, unit normal (the side shots come
/// from), two unit tangents, and the half sizes along them.
#[derive(Clone, Copy)]
struct Target {
    center: [f64; 3],
    normal: [f64; 3],
    t1: [f64; 3],
    t2: [f64; 3],
    half_thickness: f64,
    half_size: f64,
}

impl Target {
    /// Whether `p` is behind the target's far face, within its outline:
    /// a projectile found there went through.
    fn behind(&self, p: [f64; 3]) -> bool {
        let d = sub(p, self.center);
        dot(d, self.normal) < -self.half_thickness
            && dot(d, self.t1).abs() < self.half_size
            && dot(d, self.t2).abs() < self.half_size
    }
}

/// Adds a projectile aimed at a point of `target`'s front face, at most 60°
/// off its normal, from 2–5 m away, at 50–500 m/s: a sphere (radius 2–20 cm)
/// or a randomly oriented, spinning box (half-extents 2–20 cm).
fn shoot(w: &mut World, rng: &mut Rng, target: &Target, filter: CollisionFilter) -> BodyHandle {
    let (u, v) = (
        rng.uniform(-0.7, 0.7) * target.half_size,
        rng.uniform(-0.7, 0.7) * target.half_size,
    );
    let aim: [f64; 3] = std::array::from_fn(|k| {
        target.center[k]
            + target.normal[k] * target.half_thickness
            + target.t1[k] * u
            + target.t2[k] * v
    });
    let theta = rng.uniform(0.0, 60f64.to_radians());
    let phi = rng.uniform(0.0, std::f64::consts::TAU);
    let back: [f64; 3] = std::array::from_fn(|k| {
        theta.cos() * target.normal[k]
            + theta.sin() * (phi.cos() * target.t1[k] + phi.sin() * target.t2[k])
    });
    let dist = rng.uniform(2.0, 5.0);
    let speed = rng.uniform(50.0, 500.0);
    let start = [
        aim[0] + back[0] * dist,
        aim[1] + back[1] * dist,
        aim[2] + back[2] * dist,
    ];
    let vel = [-back[0] * speed, -back[1] * speed, -back[2] * speed];
    let sphere = rng.next_u64().is_multiple_of(2);
    let mut desc = BodyDesc::dynamic()
        .position(v3(start[0], start[1], start[2]))
        .linear_velocity(v3(vel[0], vel[1], vel[2]));
    let shape = if sphere {
        Shape::Sphere(Sphere::new(s(rng.uniform(0.02, 0.2))).unwrap())
    } else {
        desc = desc.rotation(rng.rotation()).angular_velocity(v3(
            rng.uniform(-10.0, 10.0),
            rng.uniform(-10.0, 10.0),
            rng.uniform(-10.0, 10.0),
        ));
        Shape::Cuboid(
            Cuboid::new(v3(
                rng.uniform(0.02, 0.2),
                rng.uniform(0.02, 0.2),
                rng.uniform(0.02, 0.2),
            ))
            .unwrap(),
        )
    };
    let restitution = if rng.next_u64().is_multiple_of(2) {
        0.0
    } else {
        0.5
    };
    let b = w.create_body(&desc).unwrap();
    w.add_collider(
        b,
        ColliderDesc::new(shape)
            .material(Material {
                friction: Scalar::HALF,
                restitution: s(restitution),
            })
            .filter(filter),
    )
    .unwrap();
    b
}

/// Steps `w` `ticks` times; returns (tunnelled shots, CCD hits, CCD bodies)
/// and checks every tick for faults.
fn run_batch(w: &mut World, shots: &[(BodyHandle, Target)], ticks: u32) -> (u32, u32, u32) {
    let mut through = vec![false; shots.len()];
    let (mut hits, mut bodies) = (0, 0);
    for _ in 0..ticks {
        let r = w.step();
        assert!(!r.overflowed(), "faults {:?}", r.faults);
        hits += r.ccd_hits;
        bodies += r.ccd_bodies;
        for (i, (b, t)) in shots.iter().enumerate() {
            let p = f(w.body(*b).unwrap().center_of_mass());
            if t.behind(p) {
                through[i] = true;
            }
        }
    }
    (through.iter().filter(|&&x| x).count() as u32, hits, bodies)
}

/// Projectiles never collide with each other.
const SHOTS: CollisionFilter = CollisionFilter {
    category: 1,
    mask: u32::MAX,
    group: -1,
};

/// Ticks until the slowest shot of a batch (5 m at 50 m/s = 6 ticks) has
/// arrived, plus 12 ticks to bounce or come to rest.
const BATCH_TICKS: u32 = 18;

/// `batches` batches of `per_batch` shots at a 1 cm thick static wall
/// (x = 0, 200 m × 200 m) in normal gravity. Returns (tunnelled, shots,
/// CCD hits, CCD bodies).
fn wall_shots(seed: u64, batches: u32, per_batch: u32) -> (u32, u32, u32, u32) {
    let mut rng = Rng::new(seed);
    let wall = Target {
        center: [0.0; 3],
        normal: [-1.0, 0.0, 0.0],
        t1: [0.0, 1.0, 0.0],
        t2: [0.0, 0.0, 1.0],
        half_thickness: 0.005,
        half_size: 100.0,
    };
    let mut totals = (0, 0, 0, 0);
    for _ in 0..batches {
        let mut w = World::new(WorldConfig::default()).unwrap();
        let wb = w.create_body(&BodyDesc::fixed().name("wall")).unwrap();
        w.add_collider(
            wb,
            ColliderDesc::new(Shape::Cuboid(Cuboid::new(v3(0.005, 100.0, 100.0)).unwrap())),
        )
        .unwrap();
        let mut shots = Vec::new();
        for _ in 0..per_batch {
            // Each shot aims at its own patch of the wall, so the batch
            // spreads out (±30 m) instead of piling up in one place.
            let mut lane = wall;
            lane.center = [0.0, rng.uniform(-30.0, 30.0), rng.uniform(-30.0, 30.0)];
            lane.half_size = 1.0;
            let b = shoot(&mut w, &mut rng, &lane, SHOTS);
            shots.push((b, wall));
        }
        let (through, hits, bodies) = run_batch(&mut w, &shots, BATCH_TICKS);
        totals.0 += through;
        totals.1 += per_batch;
        totals.2 += hits;
        totals.3 += bodies;
    }
    totals
}

/// Shots at thin static boxes (1 m × 1 m × 1 cm, random orientations, one
/// per shot on a 6 m grid) without gravity; each shot collides only with
/// its own box and the boxes 32 lanes away. Returns (tunnelled, shots, CCD
/// hits, CCD bodies).
fn thin_box_shots(seed: u64, batches: u32, per_batch: u32) -> (u32, u32, u32, u32) {
    let mut rng = Rng::new(seed);
    let mut totals = (0, 0, 0, 0);
    for _ in 0..batches {
        let mut w = zero_g();
        let mut shots = Vec::new();
        for lane in 0..per_batch {
            let bit = 1u32 << (lane % 32);
            let center = [(lane % 10) as f64 * 6.0, (lane / 10) as f64 * 6.0, 0.0];
            let q = rng.rotation();
            let axis = |v: Vec3| f(q.rotate(v));
            let target = Target {
                center,
                normal: axis(Vec3::Z),
                t1: axis(Vec3::X),
                t2: axis(Vec3::Y),
                half_thickness: 0.005,
                half_size: 0.5,
            };
            let tb = w
                .create_body(
                    &BodyDesc::fixed()
                        .position(v3(center[0], center[1], center[2]))
                        .rotation(q),
                )
                .unwrap();
            w.add_collider(
                tb,
                ColliderDesc::new(Shape::Cuboid(Cuboid::new(v3(0.5, 0.5, 0.005)).unwrap())).filter(
                    CollisionFilter {
                        category: bit,
                        mask: bit,
                        group: 0,
                    },
                ),
            )
            .unwrap();
            let b = shoot(
                &mut w,
                &mut rng,
                &target,
                CollisionFilter {
                    category: bit,
                    mask: bit,
                    group: -1,
                },
            );
            shots.push((b, target));
        }
        let (through, hits, bodies) = run_batch(&mut w, &shots, BATCH_TICKS);
        totals.0 += through;
        totals.1 += per_batch;
        totals.2 += hits;
        totals.3 += bodies;
    }
    totals
}

#[test]
fn ten_thousand_shots_at_a_1_cm_wall_never_tunnel() {
    let t0 = Instant::now();
    let (through, shots, hits, bodies) = wall_shots(0xcc_d001, 100, 100);
    eprintln!(
        "wall: {shots} shots, {through} through, {hits} CCD hits, {bodies} CCD body sweeps, {:.2} s",
        t0.elapsed().as_secs_f64()
    );
    assert_eq!(shots, 10_000);
    assert_eq!(through, 0);
    // CCD did the stopping for most shots (the first tick has no contact
    // pair yet: only the sweep can stop a shot that arrives in it).
    assert!(hits > 5_000, "only {hits} CCD hits");
}

#[test]
fn ten_thousand_shots_at_thin_boxes_never_tunnel() {
    let t0 = Instant::now();
    let (through, shots, hits, bodies) = thin_box_shots(0xcc_d002, 100, 100);
    eprintln!(
        "thin boxes: {shots} shots, {through} through, {hits} CCD hits, {bodies} CCD body sweeps, {:.2} s",
        t0.elapsed().as_secs_f64()
    );
    assert_eq!(shots, 10_000);
    assert_eq!(through, 0);
    assert!(hits > 5_000, "only {hits} CCD hits");
}

/// A 1 m × 2 cm rod (capsule) spinning at 50 rad/s end over end while
/// flying at the wall.
fn rod_world(speed: f64, phase: f64, offset: f64) -> (World, BodyHandle) {
    let mut w = World::new(WorldConfig::default()).unwrap();
    let wb = w.create_body(&BodyDesc::fixed().name("wall")).unwrap();
    w.add_collider(
        wb,
        ColliderDesc::new(Shape::Cuboid(Cuboid::new(v3(0.005, 20.0, 20.0)).unwrap())),
    )
    .unwrap();
    let rod = w
        .create_body(
            &BodyDesc::dynamic()
                .name("rod")
                .position(v3(-3.0 - offset, 1.0, 0.0))
                .rotation(Quat::from_axis_angle(Vec3::Z, s(phase)))
                .linear_velocity(v3(speed, 0.0, 0.0))
                .angular_velocity(v3(0.0, 0.0, 50.0)),
        )
        .unwrap();
    w.add_collider(
        rod,
        ColliderDesc::new(Shape::Capsule(Capsule::new(s(0.49), s(0.01)).unwrap())),
    )
    .unwrap();
    (w, rod)
}

#[test]
fn a_rod_spinning_at_50_rad_per_s_does_not_pass_through_a_1_cm_wall() {
    let mut rng = Rng::new(0xcc_d003);
    let mut hits = 0;
    for run in 0..200 {
        let speed = rng.uniform(50.0, 150.0);
        let (mut w, rod) = rod_world(speed, rng.uniform(0.0, 3.2), rng.uniform(0.0, 1.0));
        for tick in 0..30 {
            let r = w.step();
            assert!(!r.overflowed());
            hits += r.ccd_hits;
            let b = w.body(rod).unwrap();
            let c = b.center_of_mass();
            // Neither the centre nor either end of the rod is ever behind
            // the wall.
            let axis = b.rotation().rotate(Vec3::Y);
            for end in [c, c + axis * s(0.5), c - axis * s(0.5)] {
                assert!(
                    end.x.to_f64() < 0.005,
                    "run {run} tick {tick}: rod point at x = {} (speed {speed})",
                    end.x.to_f64()
                );
            }
        }
    }
    eprintln!("rods: 200 runs, {hits} CCD hits");
    assert!(hits >= 200, "{hits}");
}

#[test]
fn a_resting_pile_reports_no_ccd_bodies() {
    let mut w = World::new(WorldConfig::default()).unwrap();
    let ground = w.create_body(&BodyDesc::fixed()).unwrap();
    w.add_collider(
        ground,
        ColliderDesc::new(Shape::Cuboid(Cuboid::new(v3(20.0, 0.5, 20.0)).unwrap())),
    )
    .unwrap();
    let mut boxes = Vec::new();
    for row in 0..5 {
        for i in 0..(5 - row) {
            let b = w
                .create_body(&BodyDesc::dynamic().position(v3(
                    i as f64 * 1.05 + row as f64 * 0.525,
                    0.5 + row as f64 * 1.0,
                    0.0,
                )))
                .unwrap();
            w.add_collider(
                b,
                ColliderDesc::new(Shape::Cuboid(Cuboid::new(v3(0.5, 0.5, 0.5)).unwrap())),
            )
            .unwrap();
            boxes.push(b);
        }
    }
    let mut spheres = 0;
    for k in 0..4 {
        let b = w
            .create_body(&BodyDesc::dynamic().position(v3(-3.0 - k as f64, 0.25, 2.0)))
            .unwrap();
        w.add_collider(
            b,
            ColliderDesc::new(Shape::Sphere(Sphere::new(s(0.25)).unwrap())),
        )
        .unwrap();
        spheres += 1;
    }
    let mut max_awake = 0;
    for _ in 0..300 {
        let r = w.step();
        assert_eq!(r.ccd_bodies, 0, "tick {}", r.tick);
        assert_eq!(r.ccd_hits, 0);
        max_awake = max_awake.max(r.awake_bodies);
    }
    assert_eq!(max_awake, boxes.len() as u32 + spheres);
    let top = w.body(*boxes.last().unwrap()).unwrap().center_of_mass();
    assert!((top.y.to_f64() - 5.0).abs() < 0.05, "top at {}", top.y);
}

/// A thin dynamic box floating in zero gravity, and a 4 cm ball at 300 m/s.
fn bullet_world(bullet: bool, speed: f64) -> (World, BodyHandle, BodyHandle) {
    let mut w = zero_g();
    let plate = w.create_body(&BodyDesc::dynamic().name("plate")).unwrap();
    w.add_collider(
        plate,
        ColliderDesc::new(Shape::Cuboid(Cuboid::new(v3(0.005, 0.5, 0.5)).unwrap())),
    )
    .unwrap();
    let shot = w
        .create_body(
            &BodyDesc::dynamic()
                .name("shot")
                .bullet(bullet)
                .position(v3(-4.0, 0.1, -0.2))
                .linear_velocity(v3(speed, 0.0, 0.0)),
        )
        .unwrap();
    w.add_collider(
        shot,
        ColliderDesc::new(Shape::Sphere(Sphere::new(s(0.02)).unwrap())),
    )
    .unwrap();
    (w, plate, shot)
}

#[test]
fn a_bullet_does_not_pass_through_a_thin_dynamic_box() {
    for speed in [100.0, 300.0, 500.0] {
        let (mut w, plate, shot) = bullet_world(true, speed);
        assert!(w.is_bullet(shot).unwrap());
        let mut ccd_hits = 0;
        for tick in 0..30 {
            let r = w.step();
            assert!(!r.overflowed());
            ccd_hits += r.ccd_hits;
            assert!(r.ccd_bodies >= 1, "the bullet is swept every tick");
            // The bullet seen in the plate's frame: never behind it.
            let pb = w.body(plate).unwrap();
            let q = pb.rotation();
            let target = Target {
                center: f(pb.center_of_mass()),
                normal: f(q.rotate(-Vec3::X)),
                t1: f(q.rotate(Vec3::Y)),
                t2: f(q.rotate(Vec3::Z)),
                half_thickness: 0.005,
                half_size: 0.5,
            };
            let b = f(w.body(shot).unwrap().center_of_mass());
            assert!(
                !target.behind(b),
                "speed {speed} tick {tick}: bullet at {b:?}, plate at {:?}",
                target.center
            );
        }
        assert!(ccd_hits >= 1);
        // The plate took the hit: the bullet's momentum went into it
        // (a plastic hit: the two end up moving together).
        let pb = w.body(plate).unwrap();
        let p_plate = pb.linear_velocity().x.to_f64() * pb.mass().to_f64();
        let p_shot = speed * w.body(shot).unwrap().mass().to_f64();
        assert!(
            (p_plate / p_shot - 1.0).abs() < 0.05,
            "speed {speed}: plate momentum {p_plate}, shot momentum {p_shot}"
        );
    }
    // Without the flag, the dynamic plate is not a CCD target: the shot is
    // swept (it is fast) but only against static shapes.
    let (mut w, _, _) = bullet_world(false, 300.0);
    let r = w.step();
    assert_eq!((r.ccd_bodies, r.ccd_hits), (1, 0));
}

#[test]
fn a_ccd_hit_stops_the_body_a_few_mm_short_and_keeps_its_velocity() {
    for (restitution, expect_vx) in [(0.0, 0.0), (1.0, -300.0)] {
        let mut w = zero_g();
        let wall = w.create_body(&BodyDesc::fixed()).unwrap();
        let mat = Material {
            friction: Scalar::HALF,
            restitution: s(restitution),
        };
        w.add_collider(
            wall,
            ColliderDesc::new(Shape::Cuboid(Cuboid::new(v3(0.005, 5.0, 5.0)).unwrap()))
                .material(mat),
        )
        .unwrap();
        let ball = w
            .create_body(
                &BodyDesc::dynamic()
                    .position(v3(-2.0, 0.0, 0.0))
                    .linear_velocity(v3(300.0, 0.0, 0.0)),
            )
            .unwrap();
        w.add_collider(
            ball,
            ColliderDesc::new(Shape::Sphere(Sphere::new(s(0.1)).unwrap())).material(mat),
        )
        .unwrap();
        let r = w.step();
        assert_eq!((r.ccd_bodies, r.ccd_hits), (1, 1));
        let b = w.body(ball).unwrap();
        let gap = -0.005 - (b.center_of_mass().x.to_f64() + 0.1);
        let target = CCD_TARGET_GAP.to_f64();
        assert!(
            gap >= target - 1e-6 && gap <= target + 0.0011,
            "gap {gap} (target {target})"
        );
        assert_eq!(b.linear_velocity(), v3(300.0, 0.0, 0.0));
        // The next tick's speculative contact stops or bounces it.
        w.step();
        let vx = w.body(ball).unwrap().linear_velocity().x.to_f64();
        assert!(
            (vx - expect_vx).abs() < 0.02 * 300.0,
            "restitution {restitution}: vx {vx}"
        );
        let x = w.body(ball).unwrap().center_of_mass().x.to_f64();
        assert!(x < -0.1, "x {x}");
    }
}

#[test]
fn ccd_is_deterministic_and_survives_a_snapshot() {
    let build = || {
        let mut rng = Rng::new(0xcc_d004);
        let mut w = World::new(WorldConfig::default()).unwrap();
        let wb = w.create_body(&BodyDesc::fixed()).unwrap();
        w.add_collider(
            wb,
            ColliderDesc::new(Shape::Cuboid(Cuboid::new(v3(0.005, 100.0, 100.0)).unwrap())),
        )
        .unwrap();
        let wall = Target {
            center: [0.0, 0.0, 0.0],
            normal: [-1.0, 0.0, 0.0],
            t1: [0.0, 1.0, 0.0],
            t2: [0.0, 0.0, 1.0],
            half_thickness: 0.005,
            half_size: 5.0,
        };
        for i in 0..40 {
            let b = shoot(&mut w, &mut rng, &wall, SHOTS);
            if i % 4 == 0 {
                w.set_bullet(b, true).unwrap();
            }
        }
        w
    };
    let (mut a, mut b) = (build(), build());
    let mut snap = None;
    let mut hashes = Vec::new();
    let mut hits = 0;
    for tick in 0..40 {
        let (ra, rb): (StepReport, StepReport) = (a.step(), b.step());
        assert_eq!(ra, rb);
        hits += ra.ccd_hits;
        assert_eq!(a.state_hash(), b.state_hash(), "tick {tick}");
        hashes.push(a.state_hash());
        if tick == 4 {
            snap = Some(a.snapshot());
        }
    }
    assert!(hits > 10, "{hits}");
    let mut c = World::restore(&snap.unwrap()).unwrap();
    for h in &hashes[5..] {
        c.step();
        assert_eq!(c.state_hash(), *h);
    }
}

#[test]
fn the_bullet_flag_is_hashed_and_set_only_on_dynamic_bodies() {
    let mut w = World::new(WorldConfig::default()).unwrap();
    let d = w.create_body(&BodyDesc::dynamic()).unwrap();
    let k = w.create_body(&BodyDesc::kinematic().bullet(true)).unwrap();
    assert!(!w.is_bullet(k).unwrap());
    let before = w.state_hash();
    w.set_bullet(d, true).unwrap();
    assert!(w.is_bullet(d).unwrap());
    assert_ne!(w.state_hash(), before);
    w.set_bullet(d, false).unwrap();
    assert_eq!(w.state_hash(), before);
    w.set_bullet(k, true).unwrap();
    assert!(!w.is_bullet(k).unwrap());
    // Kept in snapshots.
    w.set_bullet(d, true).unwrap();
    let back = World::restore(&w.snapshot()).unwrap();
    assert!(back.is_bullet(d).unwrap());
}

/// 400 bodies (spheres and spinning boxes) flying at `height` over a
/// static floor (top at 0.5), without gravity, at `speed`; returns the mean
/// step time over 60 ticks (after 5 warm-up ticks) and the CCD bodies and
/// growths reported.
fn skimmers(speed: f64, height: f64) -> (f64, u32, u32) {
    let mut w = zero_g();
    let floor = w.create_body(&BodyDesc::fixed()).unwrap();
    w.add_collider(
        floor,
        ColliderDesc::new(Shape::Cuboid(Cuboid::new(v3(500.0, 0.5, 500.0)).unwrap())),
    )
    .unwrap();
    for i in 0..400 {
        let (x, z) = ((i % 20) as f64 * 2.0, (i / 20) as f64 * 2.0);
        let b = w
            .create_body(
                &BodyDesc::dynamic()
                    .position(v3(x, height, z))
                    .linear_velocity(v3(speed, 0.0, 0.0))
                    .angular_velocity(v3(0.0, speed / 50.0, 0.0)),
            )
            .unwrap();
        let shape = if i % 2 == 0 {
            Shape::Sphere(Sphere::new(s(0.25)).unwrap())
        } else {
            Shape::Cuboid(Cuboid::new(v3(0.25, 0.25, 0.25)).unwrap())
        };
        w.add_collider(b, ColliderDesc::new(shape)).unwrap();
    }
    for _ in 0..5 {
        w.step();
    }
    let (mut bodies, mut growths) = (0, 0);
    let t0 = Instant::now();
    for _ in 0..60 {
        let r = w.step();
        assert!(!r.overflowed());
        assert_eq!(r.ccd_hits, 0);
        bodies += r.ccd_bodies;
        growths += r.buffer_growths;
    }
    (t0.elapsed().as_secs_f64() / 60.0, bodies, growths)
}

#[test]
fn fast_bodies_pay_for_a_sweep_slow_ones_do_not_and_nothing_grows_once_warm() {
    // 5 cm over the floor (every sweep runs GJK against it), and 20 m up
    // (the swept box finds nothing).
    for height in [0.8, 20.0] {
        let (slow_t, slow_n, slow_g) = skimmers(1.0, height);
        let (fast_t, fast_n, fast_g) = skimmers(100.0, height);
        assert_eq!(slow_n, 0);
        assert_eq!(fast_n, 400 * 60);
        assert_eq!((slow_g, fast_g), (0, 0));
        eprintln!(
            "400 bodies at y = {height}: slow step {:.1} µs, fast step {:.1} µs, \
             {:.2} µs more per fast body",
            slow_t * 1e6,
            fast_t * 1e6,
            (fast_t - slow_t) * 1e6 / 400.0
        );
    }
}

#[test]
fn two_thousand_shots_at_a_triangle_mesh_wall_never_cross_it() {
    use lockstep_core::shape::TriMesh;
    use std::sync::Arc;
    let mut rng = Rng::new(0xcc_d005);
    let wall = Target {
        center: [0.0; 3],
        normal: [-1.0, 0.0, 0.0],
        t1: [0.0, 1.0, 0.0],
        t2: [0.0, 0.0, 1.0],
        half_thickness: 0.0,
        half_size: 100.0,
    };
    let (mut through, mut hits) = (0, 0);
    for _ in 0..20 {
        let mut w = World::new(WorldConfig::default()).unwrap();
        let wb = w.create_body(&BodyDesc::fixed()).unwrap();
        // A zero-thickness quad of 8 × 8 triangles facing −x.
        let mut verts = Vec::new();
        for r in 0..9 {
            for c in 0..9 {
                verts.push(v3(0.0, -100.0 + 25.0 * r as f64, -100.0 + 25.0 * c as f64));
            }
        }
        let mut idx = Vec::new();
        for r in 0..8u32 {
            for c in 0..8u32 {
                let a = r * 9 + c;
                idx.push([a, a + 1, a + 9]);
                idx.push([a + 1, a + 10, a + 9]);
            }
        }
        let mesh = TriMesh::new(verts, idx).unwrap();
        w.add_collider(wb, ColliderDesc::new(Shape::TriMesh(Arc::new(mesh))))
            .unwrap();
        let mut shots = Vec::new();
        for _ in 0..100 {
            let mut lane = wall;
            lane.center = [0.0, rng.uniform(-30.0, 30.0), rng.uniform(-30.0, 30.0)];
            lane.half_size = 1.0;
            shots.push((shoot(&mut w, &mut rng, &lane, SHOTS), wall));
        }
        let (t, h, _) = run_batch(&mut w, &shots, BATCH_TICKS);
        through += t;
        hits += h;
    }
    eprintln!("mesh wall: 2000 shots, {through} through, {hits} CCD hits");
    assert_eq!(through, 0);
    assert!(hits > 1_000, "{hits}");
}

/// A limb pressed 41 mm into a step (a capsule of radius 6 cm, as a
/// ragdoll's shin under a pile) while it spins fast enough to be swept: its
/// core starts 4 mm from the step, within the sweep's reach, and is still
/// apart on the same side at the end of the tick. It is left to the contact
/// solver; it used to report a hit at fraction 0 and hold the body where it
/// started, tick after tick, while the joints and contacts kept adding
/// velocity that never moved it (until it exploded).
#[test]
fn a_deeply_pressed_spinning_limb_is_not_frozen_by_its_core() {
    let mut w = zero_g();
    let floor = w
        .create_body(&BodyDesc::fixed().position(v3(0.0, -0.5, 0.0)))
        .unwrap();
    w.add_collider(
        floor,
        ColliderDesc::new(Shape::Cuboid(Cuboid::new(v3(5.0, 0.5, 5.0)).unwrap())),
    )
    .unwrap();
    let lying = Quat::from_axis_angle(Vec3::Z, Scalar::PI.half()).normalize();
    let shin = w
        .create_body(
            &BodyDesc::dynamic()
                .position(v3(0.0, 0.019, 0.0))
                .rotation(lying)
                .angular_velocity(v3(0.0, 20.0, 0.0))
                .linear_velocity(v3(0.0, -0.3, 0.0)),
        )
        .unwrap();
    w.add_collider(
        shin,
        ColliderDesc::new(Shape::Capsule(Capsule::new(s(0.15), s(0.06)).unwrap())),
    )
    .unwrap();
    let r = w.step();
    assert!(r.faults.is_empty(), "{}", r.faults);
    assert_eq!(r.ccd_bodies, 1, "it spins fast enough to be swept");
    assert_eq!(r.ccd_hits, 0, "the core already within reach is not a hit");
    let b = w.body(shin).unwrap();
    let turned = (b.rotation().conjugate() * lying)
        .w
        .to_f64()
        .abs()
        .min(1.0)
        .acos()
        * 2.0;
    // 20 rad/s for a tick is 0.33 rad; friction on the step takes some.
    assert!(turned > 0.1, "turned {turned} rad in a tick");
    let y = b.center_of_mass().y.to_f64();
    assert!(y > 0.019, "the contact pushed it up: y {y}");
}

/// A thin door (8 cm) hinged to a static post and swung at 7.5 rad/s: its
/// edge moves farther in a tick than it is thick, so CCD sweeps it, and the
/// post it touches at the hinge is a target the joint keeps it from
/// colliding with. Swept against the post it found its time of impact at
/// the hinge and froze there (at 69° on its way to a 100° stop) while its
/// velocity stayed; the sweep now skips what a joint keeps a body from
/// touching, as the contacts do. A post that may collide with the door
/// (`collide_connected`) still stops it.
#[test]
fn ccd_skips_what_a_joint_keeps_a_body_from_touching() {
    use lockstep_core::joint::{JointDesc, JointKind};
    let swing = |collide: bool| {
        let mut w = zero_g();
        let post = w
            .create_body(&BodyDesc::fixed().position(v3(0.0, 0.0, 0.0)))
            .unwrap();
        w.add_collider(post, ColliderDesc::cuboid(s(0.05), s(1.0), s(0.05)))
            .unwrap();
        let door = w
            .create_body(
                &BodyDesc::dynamic()
                    .position(v3(0.55, 0.0, 0.0))
                    .angular_velocity(v3(0.0, 7.5, 0.0))
                    .linear_velocity(v3(0.0, 0.0, -7.5 * 0.5)),
            )
            .unwrap();
        w.add_collider(door, ColliderDesc::cuboid(s(0.5), s(1.0), s(0.04)))
            .unwrap();
        let axis = Quat::from_axis_angle(Vec3::Z, Scalar::PI.half()).normalize();
        let j = w
            .add_joint(
                JointDesc::new(
                    JointKind::Revolute {
                        limits: None,
                        motor: None,
                    },
                    post,
                    door,
                )
                .frames(
                    lockstep_core::Transform::new(v3(0.05, 0.0, 0.0), axis),
                    lockstep_core::Transform::new(v3(-0.5, 0.0, 0.0), axis),
                )
                .collide_connected(collide),
            )
            .unwrap();
        let mut swept = 0;
        for _ in 0..10 {
            swept += w.step().ccd_bodies;
        }
        (w.joint_position(j).unwrap().to_f64(), swept)
    };
    let (angle, swept) = swing(false);
    assert!(swept > 0, "the door was not swept");
    // 10 ticks at 7.5 rad/s: 1.25 rad.
    assert!((angle - 1.25).abs() < 0.02, "the door turned {angle} rad");
    let (angle, _) = swing(true);
    assert!(
        angle < 1.0,
        "a post the door may touch let it turn {angle} rad"
    );
}
