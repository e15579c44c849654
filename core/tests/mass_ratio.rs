//! Large mass ratios: a heavy box resting on a light one, and a stack that
//! alternates light and heavy boxes. A soft contact of angular frequency ω
//! holds a load at the depth load/(m_eff·ω²), and between a light box and a
//! heavy one m_eff is about the light box's mass while the load is the
//! heavy box's weight: with the world's spring alone the heavy
//! box sinks in proportion to the ratio, (1 + R)·g/ω² (1:1000: 69 mm at
//! rest, 11 cm at the deepest). Above 1:64 the solver's shock pass holds
//! each upper body against the one under it instead.

use lockstep_core::shape::{Cuboid, Shape};
use lockstep_core::{BodyDesc, BodyHandle, ColliderDesc, Material, World, WorldConfig};
use lockstep_testsupport::{f, ground, s, v};

const G: f64 = 9.81;

/// The default world (60 Hz, 4 substeps, contacts at 60 Hz), sleeping off
/// so the solver alone holds the boxes.
fn world() -> World {
    let mut cfg = WorldConfig {
        gravity: v(0.0, -G, 0.0),
        ..WorldConfig::default()
    };
    cfg.sleep.enabled = false;
    World::new(cfg).unwrap()
}

/// A unit cube of `density` resting with its centre at height `y`.
fn cube(w: &mut World, y: f64, density: f64) -> BodyHandle {
    let b = w
        .create_body(&BodyDesc::dynamic().position(v(0.0, y, 0.0)))
        .unwrap();
    w.add_collider(
        b,
        ColliderDesc::new(Shape::Cuboid(Cuboid {
            half_extents: v(0.5, 0.5, 0.5),
        }))
        .density(s(density))
        .material(Material::default()),
    )
    .unwrap();
    b
}

fn center(w: &World, b: BodyHandle) -> [f64; 3] {
    f(w.body(b).unwrap().center_of_mass())
}

fn speed(w: &World, b: BodyHandle) -> f64 {
    let u = f(w.body(b).unwrap().linear_velocity());
    (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt()
}

/// The soft contact's depth under its own weight, g/ω², ω = 2π·60 Hz.
fn soft_depth() -> f64 {
    G / (2.0 * std::f64::consts::PI * 60.0).powi(2)
}

struct Sink {
    /// Heavy box into the light one after 10 s, m.
    depth: f64,
    /// The deepest it went over the 10 s, m.
    worst: f64,
    /// Light box into the ground after 10 s, m.
    ground: f64,
    /// Fastest of the two boxes at the end, m/s.
    speed: f64,
}

/// A box `ratio` times heavier than the unit cube under it, starting just
/// touching it, for 10 s.
fn sink(ratio: f64) -> Sink {
    let mut w = world();
    ground(&mut w, Material::default());
    let light = cube(&mut w, 0.5, 1.0);
    let heavy = cube(&mut w, 1.5, ratio);
    let mut worst: f64 = 0.0;
    for _ in 0..600 {
        let r = w.step();
        assert!(r.faults.is_empty(), "fault at tick {}", r.tick);
        let gap = (center(&w, heavy)[1] - 0.5) - (center(&w, light)[1] + 0.5);
        worst = worst.max(-gap);
    }
    let r = Sink {
        depth: (center(&w, light)[1] + 0.5) - (center(&w, heavy)[1] - 0.5),
        worst,
        ground: 0.5 - center(&w, light)[1],
        speed: speed(&w, heavy).max(speed(&w, light)),
    };
    println!(
        "mass ratio 1:{ratio}: heavy into light {:.3} mm (worst {:.3} mm), light into ground \
         {:.3} mm, speed {:.1e} m/s",
        r.depth * 1e3,
        r.worst * 1e3,
        r.ground * 1e3,
        r.speed
    );
    r
}

/// The soft contact's static depth at 1:10: the box–box contact (four
/// corners, total effective mass m·M/(m + M)) holds the heavy box's weight
/// M·g at (1 + R)·g/ω², and the ground contact under the light box,
/// effective mass m, holds (m + M)·g at the same depth: 0.76 mm, each
/// within 3%, and the pair at rest.
#[test]
fn at_1_to_10_the_heavy_box_sinks_as_the_soft_contact_predicts() {
    let r = sink(10.0);
    let expect = 11.0 * soft_depth();
    for (what, d) in [("box into box", r.depth), ("box into ground", r.ground)] {
        assert!((d - expect).abs() < 0.03 * expect, "{what} {d} vs {expect}");
    }
    assert!(r.worst < 1.03 * expect, "worst {}", r.worst);
    assert!(r.speed < 1e-3, "speed {}", r.speed);
}

/// Above 1:64 the solver's shock pass holds each upper body of a
/// high-ratio contact against the body under it (core/src/solver/
/// contact_solver/shock.rs), so neither contact sinks at all: before it,
/// at 1:1000 the heavy box sank 4.5 mm into the light one and the light
/// one 69 mm into the ground (11 cm at the deepest). Both contacts stay
/// within 0.1 mm, at 1:100, 1:1000 and 1:10,000, at every tick of the
/// 10 s (measured: 0.005 mm or less), and neither box falls off.
#[test]
fn heavy_boxes_on_light_ones_do_not_sink_up_to_1_to_10000() {
    for ratio in [100.0, 1000.0, 10000.0] {
        let r = sink(ratio);
        assert!(r.worst < 1e-4, "1:{ratio}: worst {}", r.worst);
        assert!(r.depth.abs() < 1e-4, "1:{ratio}: depth {}", r.depth);
        assert!(r.ground.abs() < 1e-4, "1:{ratio}: ground {}", r.ground);
    }
}

/// Issue 18, defect 3 (open): the pair must also be at rest. With the
/// shock pass the boxes keep a residual speed, mostly sideways: 0.6 mm/s
/// at 1:100, 0.95 mm/s at 1:1000, 3.4 mm/s at 1:10,000, the pair creeping
/// by millimetres over 10 s.
#[test]
#[ignore = "issue 18 defect 3, open: the 1:10,000 pair creeps sideways at 3.4 mm/s"]
fn heavy_boxes_on_light_ones_come_to_rest_up_to_1_to_10000() {
    for ratio in [100.0, 1000.0, 10000.0] {
        let r = sink(ratio);
        assert!(r.speed < 1e-3, "1:{ratio}: speed {}", r.speed);
    }
}

/// The alternating stack's contacts and top with the shock pass: no
/// contact sinks (deepest 0.000 mm over 10 s, the top 0.025 mm above its
/// start) where without it the heavy boxes passed through the light ones
/// within 2 s.
#[test]
fn alternating_stack_of_five_at_1_to_1000_does_not_sink() {
    let r = alternating_stack();
    assert!(r.worst < 1e-4, "deepest contact {}", r.worst);
    assert!(r.sag.abs() < 1e-4, "sag {}", r.sag);
}

struct Stack {
    /// The deepest any contact went over the 10 s, m.
    worst: f64,
    /// How far the top box sank below its start, m.
    sag: f64,
    /// How far the top box moved off the stack's axis, m.
    lateral: f64,
    /// The fastest box at the end, m/s.
    fastest: f64,
}

/// Five unit cubes, light and heavy (1:1000) in turn from the ground up,
/// 10 s without sleeping.
fn alternating_stack() -> Stack {
    let mut w = world();
    ground(&mut w, Material::default());
    let boxes: Vec<_> = (0..5)
        .map(|i| {
            cube(
                &mut w,
                0.5 + i as f64,
                if i % 2 == 0 { 1.0 } else { 1000.0 },
            )
        })
        .collect();
    let mut worst: f64 = 0.0;
    for _ in 0..600 {
        let r = w.step();
        assert!(r.faults.is_empty(), "fault at tick {}", r.tick);
        for k in 1..5 {
            let gap = (center(&w, boxes[k])[1] - 0.5) - (center(&w, boxes[k - 1])[1] + 0.5);
            worst = worst.max(-gap);
        }
        worst = worst.max(0.5 - center(&w, boxes[0])[1]);
    }
    let top = center(&w, boxes[4]);
    let r = Stack {
        worst,
        sag: 4.5 - top[1],
        lateral: (top[0] * top[0] + top[2] * top[2]).sqrt(),
        fastest: boxes.iter().map(|&b| speed(&w, b)).fold(0.0, f64::max),
    };
    println!(
        "alternating stack 1:1000: deepest contact {:.3} mm, top sag {:.3} mm, off-axis \
         {:.1e} m, fastest {:.1e} m/s",
        r.worst * 1e3,
        r.sag * 1e3,
        r.lateral,
        r.fastest
    );
    r
}

/// Issue 18, defect 3 (open): the stack must also stay on its axis and at
/// rest: each contact within 2 cm, the top box within 10 cm of its resting
/// height and 1 cm of its axis, every box slower than 1 mm/s. With the
/// shock pass it no longer sinks, but it creeps: the top box 1.2 cm off
/// its axis after 10 s, the fastest box at 3.5 mm/s.
#[test]
#[ignore = "issue 18 defect 3, open: the 1:1000 alternating stack creeps 1.2 cm off its axis in 10 s"]
fn alternating_stack_of_five_at_1_to_1000_stands_10_seconds() {
    let r = alternating_stack();
    assert!(r.worst < 0.02, "deepest contact {}", r.worst);
    assert!(
        r.sag < 0.1 && r.lateral < 0.01,
        "sag {}, off-axis {}",
        r.sag,
        r.lateral
    );
    assert!(r.fastest < 1e-3, "fastest {}", r.fastest);
}

/// With the default settings (sleeping on) the residual creep of the
/// shock pass never shows: the alternating stack at 1:1000 and the pair at
/// 1:10,000 fall asleep within 1 s (measured: tick 29) and every box
/// stays within 2 mm of where it started (measured: the pair's light box
/// 1.87 mm sideways before it sleeps, the heavy one 0.32 mm; the stack's
/// boxes 0.10–0.97 mm; with the normal rows one way only, 0.45 mm at most:
/// the creep's direction and size come from the solver's seed).
#[test]
fn high_ratio_stack_and_pair_fall_asleep_where_they_started() {
    let cfg = WorldConfig {
        gravity: v(0.0, -G, 0.0),
        ..WorldConfig::default()
    };
    assert!(cfg.sleep.enabled);
    let stack: &[f64] = &[1.0, 1000.0, 1.0, 1000.0, 1.0];
    let pair: &[f64] = &[1.0, 10000.0];
    for densities in [stack, pair] {
        let mut w = World::new(cfg).unwrap();
        ground(&mut w, Material::default());
        let boxes: Vec<_> = densities
            .iter()
            .enumerate()
            .map(|(i, &d)| cube(&mut w, 0.5 + i as f64, d))
            .collect();
        let mut slept = None;
        for t in 0..600 {
            let r = w.step();
            assert!(r.faults.is_empty(), "fault at tick {}", r.tick);
            if slept.is_none() && boxes.iter().all(|&b| w.body(b).unwrap().is_sleeping()) {
                slept = Some(t);
            }
        }
        let slept = slept.expect("fell asleep");
        assert!(slept < 60, "{densities:?}: asleep at tick {slept}");
        for (i, &b) in boxes.iter().enumerate() {
            let c = center(&w, b);
            let off = (c[0] * c[0] + (c[1] - 0.5 - i as f64).powi(2) + c[2] * c[2]).sqrt();
            assert!(off < 2e-3, "{densities:?}: box {i} {off} m from its start");
        }
    }
}
