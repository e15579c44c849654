//! Fast landings on a static box (issue 18, defect 2): a tilted capsule
//! dropped from 3–8 m (up to 12.5 m/s) used to end up 7 cm inside the box,
//! its pose then the same bit for bit tick after tick while its velocity
//! grew without bound, never asleep.
//!
//! The cause was the capsule–box contact: it gave two points only to a
//! capsule within 1.8° of lying flat on a face, one (the deepest clipped
//! end) otherwise. A capsule landing on one end and swinging down onto the
//! face then had no contact under its other end: the solver held the deep
//! end and let the body pivot about it, the other end swept into the box,
//! and continuous collision stopped it at the start of every tick, keeping
//! its velocities, to which gravity added. Now the segment clipped to the
//! face gives both ends, each as a point when it is within the margin.
//!
//! The invariant of the soak ([`check_no_frozen_growth`]): velocity must
//! never grow while the pose stays bit-identical.

use lockstep_core::shape::{Capsule, ConvexHull, Cuboid, Shape, Sphere};
use lockstep_core::{BodyDesc, BodyHandle, ColliderDesc, Material, Quat, Vec3, World, WorldConfig};
use lockstep_testsupport::{Rng, f, s, v};

const G: f64 = 9.81;

/// Ticks a pose may stay bit-identical while the body's speed grows before
/// the invariant fails (a resting body's pose repeats with a constant or
/// shrinking speed; a frozen one gains g·dt every tick).
const FROZEN_TICKS: u32 = 10;

/// A world with the default settings (60 Hz, 4 substeps, sleeping on) and
/// a static 4 m × 1 m × 4 m box whose top face is y = 0.
fn world_with_box() -> World {
    let mut w = World::new(WorldConfig::default()).unwrap();
    let g = w
        .create_body(&BodyDesc::fixed().position(v(0.0, -0.5, 0.0)))
        .unwrap();
    w.add_collider(
        g,
        ColliderDesc::new(Shape::Cuboid(Cuboid {
            half_extents: v(2.0, 0.5, 2.0),
        }))
        .material(Material::default()),
    )
    .unwrap();
    w
}

fn drop(w: &mut World, shape: Shape, at: Vec3, q: Quat) -> BodyHandle {
    let b = w
        .create_body(&BodyDesc::dynamic().position(at).rotation(q))
        .unwrap();
    w.add_collider(b, ColliderDesc::new(shape).material(Material::default()))
        .unwrap();
    b
}

fn norm(x: [f64; 3]) -> f64 {
    (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt()
}

/// What one drop did over its ticks.
struct Run {
    /// The first tick at whose end the body was asleep.
    asleep_at: Option<u32>,
    /// The fastest the body moved after its first contact, m/s.
    fastest_after_contact: f64,
}

/// Steps `w` for `ticks`, checking the invariant on `b` every tick: while
/// its pose (centre and rotation) is bit-identical to the last tick's and
/// it is awake, its speed and spin must not grow for more than
/// [`FROZEN_TICKS`] ticks in a row.
fn check_no_frozen_growth(w: &mut World, b: BodyHandle, ticks: u32, what: &str) -> Run {
    let mut last = None;
    let mut growing = 0;
    let mut run = Run {
        asleep_at: None,
        fastest_after_contact: 0.0,
    };
    let mut touched = false;
    for t in 1..=ticks {
        let r = w.step();
        assert!(r.faults.is_empty(), "{what}: fault at tick {t}");
        let body = w.body(b).unwrap();
        let pose = (body.center_of_mass(), body.rotation());
        let speed = (
            norm(f(body.linear_velocity())),
            norm(f(body.angular_velocity())),
        );
        if let Some((p, (v0, w0))) = last
            && p == pose
            && !body.is_sleeping()
            && (speed.0 > v0 || speed.1 > w0)
        {
            growing += 1;
            assert!(
                growing <= FROZEN_TICKS,
                "{what}: pose frozen for {growing} ticks while the velocity grows (tick {t}: \
                 v {:.3} m/s, ω {:.3} rad/s)",
                speed.0,
                speed.1
            );
        } else {
            growing = 0;
        }
        last = Some((pose, speed));
        touched |= w.contact_pairs().iter().any(|p| !p.manifold.is_empty());
        if touched {
            run.fastest_after_contact = run.fastest_after_contact.max(speed.0);
        }
        if run.asleep_at.is_none() && body.is_sleeping() {
            run.asleep_at = Some(t);
        }
    }
    run
}

/// How far the capsule's lowest point is below y = 0.
fn capsule_depth(w: &World, b: BodyHandle, half: f64, r: f64) -> f64 {
    let body = w.body(b).unwrap();
    let y = f(body.center_of_mass())[1];
    let up = f(body.rotation().rotate(v(0.0, 1.0, 0.0)));
    r + half * up[1].abs() - y
}

/// The grid of the defect: a capsule (core 0.8 m, radius 0.1 m) dropped
/// from 3, 4, … 8 m with tilts of 0°, 7.5°, … 82.5° about x, z and the
/// diagonal (216 drops, up to 12.5 m/s at impact; before the fix, drops from
/// 3 m at 82.5° and from 4 m at 67.5° froze 7 cm deep). Each must come to rest on the box: asleep within
/// 3 s, its lowest point at the end no deeper than the soft contact holds
/// it (`4·g/ω²`, 0.28 mm, ω = 2π·60 Hz: a capsule lying on its two ends
/// sinks about 1.9·g/ω²), never faster than the impact speed plus 10%, and
/// never frozen with a growing velocity.
#[test]
fn a_tilted_capsule_dropped_on_a_box_comes_to_rest_on_it() {
    let (half, r) = (0.4, 0.1);
    let bound = 4.0 * G / (2.0 * std::f64::consts::PI * 60.0).powi(2);
    let mut deepest: f64 = 0.0;
    let mut latest = 0;
    for height in [3.0, 4.0, 5.0, 6.0, 7.0, 8.0] {
        for ti in 0..12 {
            for (ai, axis) in [v(1.0, 0.0, 0.0), v(0.0, 0.0, 1.0), v(1.0, 0.0, 1.0)]
                .into_iter()
                .enumerate()
            {
                let tilt = ti as f64 * 7.5;
                let what = format!("capsule from {height} m, tilt {tilt}° about axis {ai}");
                let mut w = world_with_box();
                let q = Quat::from_axis_angle(axis.normalize_or_zero(), s(tilt.to_radians()));
                let shape = Shape::Capsule(Capsule {
                    half_height: s(half),
                    radius: s(r),
                });
                let b = drop(&mut w, shape, v(0.1, height, 0.05), q);
                let run = check_no_frozen_growth(&mut w, b, 240, &what);
                let depth = capsule_depth(&w, b, half, r);
                let impact = (2.0 * G * (height - r - half)).sqrt();
                let asleep = run.asleep_at.unwrap_or(u32::MAX);
                assert!(asleep <= 180, "{what}: asleep at tick {asleep}");
                assert!(depth < bound, "{what}: {depth} m deep at the end");
                assert!(
                    run.fastest_after_contact < 1.1 * impact,
                    "{what}: {} m/s after contact, impact {impact}",
                    run.fastest_after_contact
                );
                deepest = deepest.max(depth);
                latest = latest.max(asleep);
            }
        }
    }
    println!(
        "capsule drops: deepest at rest {:.3} mm (bound {:.3} mm), last asleep at tick {latest}",
        deepest * 1e3,
        bound * 1e3
    );
}

/// Seeded drops of every convex shape onto the box: random heights
/// (0.5–8 m), orientations and (for the boxes and hulls) spins. The
/// invariant holds for each; each ends on the box, the boxes and hulls
/// asleep within 4 s, the balls and capsules (which may roll on, with no
/// rolling resistance) under 0.1 m/s.
#[test]
fn no_shape_dropped_on_a_box_freezes_with_a_growing_velocity() {
    let hull = || -> Shape {
        ConvexHull::from_points(&[
            v(-0.3, 0.0, 0.0),
            v(0.3, 0.03, 0.0),
            v(0.0, 0.36, 0.09),
            v(0.06, 0.03, 0.3),
            v(0.0, -0.24, -0.15),
        ])
        .unwrap()
        .into()
    };
    let mut rng = Rng::new(18);
    let mut unit = move || rng.unit();
    let mut latest = 0;
    for i in 0..48 {
        let shape = match i % 4 {
            0 => Shape::Sphere(Sphere { radius: s(0.15) }),
            1 => Shape::Capsule(Capsule {
                half_height: s(0.1 + 0.4 * unit()),
                radius: s(0.05 + 0.1 * unit()),
            }),
            2 => Shape::Cuboid(Cuboid {
                half_extents: v(
                    0.05 + 0.3 * unit(),
                    0.05 + 0.3 * unit(),
                    0.05 + 0.3 * unit(),
                ),
            }),
            _ => hull(),
        };
        let height = 0.5 + 7.5 * unit();
        let axis = v(unit() - 0.5, unit() - 0.5, unit() - 0.5).normalize_or_zero();
        let q = Quat::from_axis_angle(axis, s(unit() * std::f64::consts::TAU));
        let mut w = world_with_box();
        let b = drop(&mut w, shape, v(unit() - 0.5, height, unit() - 0.5), q);
        // A spinning ball or capsule would roll on for ever (no rolling
        // resistance): only the boxes and hulls spin.
        let spin = v(4.0 * unit() - 2.0, 4.0 * unit() - 2.0, 4.0 * unit() - 2.0);
        if i % 4 >= 2 {
            w.set_angular_velocity(b, spin).unwrap();
        }
        let what = format!("drop {i} (shape {}) from {height:.2} m", i % 4);
        let run = check_no_frozen_growth(&mut w, b, 300, &what);
        let body = w.body(b).unwrap();
        let (at, speed) = (f(body.center_of_mass()), norm(f(body.linear_velocity())));
        if i % 4 >= 2 {
            let asleep = run.asleep_at.unwrap_or(u32::MAX);
            assert!(asleep <= 240, "{what}: asleep at tick {asleep}");
            latest = latest.max(asleep);
        } else {
            // Round shapes may roll on slowly (no rolling resistance), but
            // on the box, not in it.
            assert!(speed < 0.1, "{what}: still at {speed} m/s");
        }
        assert!(
            at[1] > 0.0 && at[0].abs() < 2.0 && at[2].abs() < 2.0,
            "{what}: ended at {at:?}, not on the box"
        );
    }
    println!("seeded drops: last asleep at tick {latest}");
}
