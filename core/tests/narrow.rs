//! The narrow contact rows (`ContactRows::Narrow`: 32-bit operands, exact
//! 64-bit sums, impulses in velocity units): a pyramid settles and sleeps
//! on them, friction stops a sliding box where the closed form says, any
//! worker count gives the same bits, snapshots carry the setting, and a
//! value past the format's range sends its constraint to the Q32.32 rows
//! on every machine alike.

use lockstep_core::scene::{build_world_with_config, parse_scene};
use lockstep_core::{
    BodyDesc, ColliderDesc, ContactOrder, ContactRows, Material, StepReport, World, WorldConfig,
};
use lockstep_testsupport::{ground, pile_in, s, step_pile, v};

fn narrow(order: ContactOrder) -> WorldConfig {
    WorldConfig {
        contact_order: order,
        contact_rows: ContactRows::Narrow,
        ..WorldConfig::default()
    }
}

/// Steps `w` (turning its kinematic "paddle", if any) and returns each
/// tick's state hash and report, checking for faults.
fn trace(mut w: World, ticks: u64) -> Vec<(u64, StepReport)> {
    (0..ticks)
        .map(|t| {
            let r = step_pile(&mut w, t);
            (w.state_hash(), r)
        })
        .collect()
}

fn pyramid(rows: ContactRows) -> World {
    let path = format!("{}/../scenes/pyramid.toml", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap();
    let desc = parse_scene(&text, "pyramid.toml").unwrap();
    let config = WorldConfig {
        contact_rows: rows,
        ..desc.world
    };
    build_world_with_config(&desc, config, "pyramid.toml").unwrap()
}

#[test]
fn a_pyramid_settles_and_sleeps_on_the_narrow_rows_alone() {
    let mut w = pyramid(ContactRows::Narrow);
    let start: Vec<_> = w
        .body_handles()
        .map(|h| w.body(h).unwrap().position())
        .collect();
    let mut slept_at = None;
    for t in 0..600 {
        let r = w.step();
        assert!(r.faults.is_empty(), "tick {t}: {}", r.faults);
        // Every contact is between equal crates or a crate and the ground:
        // all on the narrow rows, none past the guard.
        assert_eq!(r.narrow_constraints, r.contact_constraints, "tick {t}");
        assert_eq!(r.narrow_fallbacks, 0, "tick {t}");
        if r.awake_bodies == 0 && slept_at.is_none() {
            slept_at = Some(t);
        }
    }
    let slept_at = slept_at.expect("the pyramid falls asleep");
    assert!(slept_at < 300, "asleep at tick {slept_at}");
    // Settled where it was built: each crate within 5 mm (the contact
    // spring's static depth and the settling of 1 cm gaps).
    for (h, p0) in w.body_handles().zip(&start) {
        let p = w.body(h).unwrap().position();
        let d = (p - *p0).length().to_f64();
        assert!(d < 0.005, "{} moved {d} m", w.body(h).unwrap().name());
    }
}

#[test]
fn friction_on_the_narrow_rows_stops_a_sliding_box_where_the_closed_form_says() {
    // A 1 m box launched at 4 m/s along a diagonal (friction in both
    // tangent rows) with μ = 0.5 slides v²/(2μg) = 1.631 m.
    for rows in [ContactRows::Narrow, ContactRows::Exact] {
        let mut w = World::new(WorldConfig {
            contact_rows: rows,
            ..WorldConfig::default()
        })
        .unwrap();
        let m = Material::new(s(0.5), s(0.0));
        ground(&mut w, m);
        let b = w
            .create_body(&BodyDesc::dynamic().position(v(0.0, 0.5, 0.0)))
            .unwrap();
        w.add_collider(b, ColliderDesc::cuboid(s(0.5), s(0.5), s(0.5)).material(m))
            .unwrap();
        for _ in 0..10 {
            w.step();
        }
        let dir = v(0.6, 0.0, 0.8);
        w.set_linear_velocity(b, dir * s(4.0)).unwrap();
        let p0 = w.body(b).unwrap().position();
        for _ in 0..180 {
            assert!(w.step().faults.is_empty());
        }
        let d = (w.body(b).unwrap().position() - p0).length().to_f64();
        let want = 16.0 / (2.0 * 0.5 * 9.81);
        assert!(
            (d - want).abs() < 0.02 * want,
            "{rows:?}: slid {d} m, closed form {want} m"
        );
        assert!(w.body(b).unwrap().linear_velocity().length().to_f64() < 1e-3);
    }
}

#[test]
fn narrow_rows_give_the_same_bits_on_1_to_8_workers() {
    let reference = trace(pile_in(narrow(ContactOrder::Colors), 150, 5), 120);
    assert!(reference.iter().any(|t| t.1.narrow_constraints > 200));
    for count in [1, 2, 3, 4, 8] {
        let mut w = pile_in(narrow(ContactOrder::Colors), 150, 5);
        w.set_workers(count);
        let got = trace(w, 120);
        if let Some(t) = (0..got.len()).find(|&t| got[t] != reference[t]) {
            panic!("{count} workers: tick {t} differs");
        }
    }
}

#[test]
fn the_rows_format_is_hashed_kept_in_snapshots_and_changes_motion() {
    let (mut a, mut b) = (
        pile_in(narrow(ContactOrder::Pairs), 72, 3),
        pile_in(
            WorldConfig {
                contact_rows: ContactRows::Exact,
                ..narrow(ContactOrder::Pairs)
            },
            72,
            3,
        ),
    );
    assert_ne!(a.state_hash(), b.state_hash(), "the setting is hashed");
    for _ in 0..60 {
        a.step();
        b.step();
    }
    assert_ne!(a.body_hashes(), b.body_hashes(), "the formats round apart");
    let mut restored = World::restore(&a.snapshot()).unwrap();
    assert_eq!(restored.config().contact_rows, ContactRows::Narrow);
    for t in 0..60 {
        a.step();
        restored.step();
        assert_eq!(
            a.state_hash(),
            restored.state_hash(),
            "tick {t} after restore"
        );
    }
}

/// A 600 m/s bullet is past the narrow rows' ±512 m/s: its contacts go to
/// the Q32.32 rows (counted), the same on any worker count. A hit (a point
/// approaching faster than `restitution_threshold`) goes to the Q32.32 rows
/// for its tick before any guard is tried, so the threshold here is above
/// the bullet's speed: the guard is what sends it.
#[test]
fn a_bullet_past_the_guard_is_solved_on_the_q32_rows_and_counted() {
    let build = || {
        let mut cfg = narrow(ContactOrder::Colors);
        cfg.restitution_threshold = s(1000.0);
        let mut w = World::new(cfg).unwrap();
        ground(&mut w, Material::default());
        let wall = w
            .create_body(&BodyDesc::dynamic().name("wall").position(v(0.0, 1.0, 0.0)))
            .unwrap();
        // 8 kg against the bullet's 4.2 kg: a ratio the narrow rows keep.
        w.add_collider(
            wall,
            ColliderDesc::cuboid(s(0.1), s(1.0), s(1.0)).density(s(10.0)),
        )
        .unwrap();
        let bullet = w
            .create_body(
                &BodyDesc::dynamic()
                    .position(v(-6.0, 1.0, 0.0))
                    .linear_velocity(v(600.0, 0.0, 0.0)),
            )
            .unwrap();
        w.add_collider(bullet, ColliderDesc::sphere(s(0.1)))
            .unwrap();
        w.set_bullet(bullet, true).unwrap();
        (w, bullet)
    };
    let (w, _) = build();
    let one = trace(w, 30);
    let fallbacks: u32 = one.iter().map(|t| t.1.narrow_fallbacks).sum();
    assert!(fallbacks > 0, "the bullet's contact fell back");
    // The bullet hit the wall and did not pass through it: the wall took
    // its push along +x, the bullet is still behind it.
    let (mut w, bullet) = build();
    for _ in 0..30 {
        w.step();
    }
    let wall = w.find_body("wall").unwrap();
    let (xb, xw) = (
        w.body(bullet).unwrap().position().x.to_f64(),
        w.body(wall).unwrap().position().x.to_f64(),
    );
    assert!(xb < xw, "bullet at {xb} m, wall at {xw} m");
    assert!(w.body(wall).unwrap().linear_velocity().x.to_f64() > 1.0);
    let (mut w3, _) = build();
    w3.set_workers(3);
    assert_eq!(trace(w3, 30), one, "3 workers");
}

/// A 1:4000 mass ratio is past what the narrow rows keep: the high-ratio
/// contacts (the heavy box on the light one, and the light one on the
/// ground, which carries the heavy one's weight) are solved on the Q32.32
/// rows with the shock pass, a crate beside them on the narrow rows, and
/// the heavy box stays on the light one.
#[test]
fn high_mass_ratio_contacts_stay_on_the_q32_rows() {
    let mut w = World::new(narrow(ContactOrder::Pairs)).unwrap();
    ground(&mut w, Material::default());
    let light = w
        .create_body(&BodyDesc::dynamic().position(v(0.0, 0.25, 0.0)))
        .unwrap();
    w.add_collider(
        light,
        ColliderDesc::cuboid(s(0.5), s(0.25), s(0.5)).density(s(1.0)),
    )
    .unwrap();
    let heavy = w
        .create_body(&BodyDesc::dynamic().position(v(0.0, 1.0, 0.0)))
        .unwrap();
    w.add_collider(
        heavy,
        ColliderDesc::cuboid(s(0.5), s(0.5), s(0.5)).density(s(2000.0)),
    )
    .unwrap();
    let other = w
        .create_body(&BodyDesc::dynamic().position(v(3.0, 0.5, 0.0)))
        .unwrap();
    w.add_collider(other, ColliderDesc::cuboid(s(0.5), s(0.5), s(0.5)))
        .unwrap();
    let mut mixed = false;
    for t in 0..240 {
        let r = w.step();
        assert!(r.faults.is_empty(), "tick {t}");
        mixed |= r.contact_constraints == 3 && r.narrow_constraints == 1;
    }
    assert!(mixed, "one contact on each rows");
    let y = w.body(heavy).unwrap().position().y.to_f64();
    assert!((y - 1.0).abs() < 0.01, "heavy box at {y}");
}

#[test]
fn scene_files_name_the_rows_and_a_bad_name_is_refused() {
    let text = "[world]\ncontact_rows = \"narrow\"\n";
    let desc = parse_scene(text, "t.toml").unwrap();
    assert_eq!(desc.world.contact_rows, ContactRows::Narrow);
    let desc = parse_scene("[world]\n", "t.toml").unwrap();
    assert_eq!(desc.world.contact_rows, ContactRows::Exact);
    let err = parse_scene("[world]\ncontact_rows = \"fast\"\n", "t.toml").unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("t.toml:2") && msg.contains("\"fast\"") && msg.contains("\"narrow\""),
        "{msg}"
    );
}

/// The narrow rows' SIMD lanes (where this CPU has them) give the scalar
/// rows' bits every tick, on one worker and on three, on a random pile of
/// boxes, spheres and capsules (constraints of one to four points) and on
/// the pyramid scene, whose crates go to sleep on the way.
#[test]
fn the_lanes_step_to_the_scalar_rows_hashes_and_reports() {
    let pile = || pile_in(narrow(ContactOrder::Colors), 150, 9);
    let pyramid = || {
        let path = format!("{}/../scenes/pyramid.toml", env!("CARGO_MANIFEST_DIR"));
        let text = std::fs::read_to_string(&path).unwrap();
        let desc = parse_scene(&text, "pyramid.toml").unwrap();
        let config = WorldConfig {
            contact_order: ContactOrder::Colors,
            contact_rows: ContactRows::Narrow,
            ..desc.world
        };
        build_world_with_config(&desc, config, "pyramid.toml").unwrap()
    };
    let builds: [&dyn Fn() -> World; 2] = [&pile, &pyramid];
    for (b, build) in builds.iter().enumerate() {
        let reference = trace(build(), 150);
        assert!(reference.iter().all(|t| t.1.lane_batches == 0));
        for workers in [1, 3] {
            let mut w = build();
            w.set_lanes(true);
            w.set_workers(workers);
            let has_lanes = w.lanes().is_some();
            let got = trace(w, 150);
            if has_lanes && b == 0 {
                assert!(got.iter().any(|t| t.1.lane_batches > 10), "batches");
            }
            if !has_lanes {
                eprintln!("this CPU has no narrow-row lanes: the scalar rows ran both times");
            }
            for t in 0..got.len() {
                // All but the lanes' own counts: their batches and the
                // growth of the buffer that holds them.
                let (mut want, mut have) = (reference[t].1, got[t].1);
                (want.lane_batches, have.lane_batches) = (0, 0);
                (want.buffer_growths, have.buffer_growths) = (0, 0);
                assert_eq!(
                    (reference[t].0, want),
                    (got[t].0, have),
                    "scene {b}, {workers} workers, tick {t}"
                );
            }
        }
    }
}
