//! Figures for the collision pipeline on the `engines` benchmark pyramids (docs/engines.md):
//! how many pairs each stage leaves, and what the collision stage costs.
//! Ignored (release-only figures): run with
//! `cargo test --release -p lockstep-core --test pyramid_pairs -- --ignored --nocapture`.

use std::time::Instant;

use lockstep_core::shape::{Cuboid, Shape};
use lockstep_core::{BodyDesc, ColliderDesc, Scalar, Vec3, World, WorldConfig};

/// `count` pyramids with `base` cubes (half-extent 0.5, density 100) in the
/// x–y plane, on a ground box of half-extents (ground, 1, ground) at y = −1.
fn pyramids(grid: i32, base: i32, ground: i32) -> World {
    let mut w = World::new(WorldConfig {
        gravity: Vec3::new(Scalar::ZERO, Scalar::from_int(-10), Scalar::ZERO),
        sleep: lockstep_core::SleepConfig {
            enabled: false,
            ..Default::default()
        },
        ..WorldConfig::default()
    })
    .unwrap();
    let g = w
        .create_body(&BodyDesc::fixed().position(Vec3::from_ints(0, -1, 0)))
        .unwrap();
    w.add_collider(
        g,
        ColliderDesc::new(Shape::Cuboid(Cuboid {
            half_extents: Vec3::from_ints(ground, 1, ground),
        })),
    )
    .unwrap();
    let half = Scalar::HALF;
    let cube = Shape::Cuboid(Cuboid {
        half_extents: Vec3::splat(half),
    });
    let spacing = base + 2;
    for gx in 0..grid {
        for gz in 0..grid {
            let ox = (gx - grid / 2) * spacing;
            let oz = (gz - grid / 2) * spacing * 2;
            for row in 0..base {
                for i in 0..base - row {
                    // x = ox + i + row/2 - (base-1)/2, y = 0.5 + row
                    let x = Scalar::from_int(ox + i) + Scalar::from_int(row).half()
                        - Scalar::from_int(base - 1).half();
                    let y = half + Scalar::from_int(row);
                    let b = w
                        .create_body(&BodyDesc::dynamic().position(Vec3::new(
                            x,
                            y,
                            Scalar::from_int(oz),
                        )))
                        .unwrap();
                    w.add_collider(
                        b,
                        ColliderDesc::new(cube.clone()).density(Scalar::from_int(100)),
                    )
                    .unwrap();
                }
            }
        }
    }
    w
}

fn report(name: &str, mut w: World) {
    let bodies = w.bodies().len() as u64;
    let t = Instant::now();
    let r = w.step();
    let first = t.elapsed();
    assert!(r.faults.is_empty());
    let all_pairs = bodies * (bodies - 1) / 2;
    println!(
        "{name}: {bodies} bodies; all pairs {all_pairs}; broad-phase candidates {}; touching after the narrow phase {} ({} contact points); first step {:.1} ms (collision stage incl. building the trees)",
        r.candidate_pairs,
        r.touching_pairs,
        r.contact_points,
        first.as_secs_f64() * 1e3
    );
    let t = Instant::now();
    let steps = 5;
    for _ in 0..steps {
        w.step();
    }
    println!(
        "{name}: next {steps} steps {:.1} ms/step (collision + integration, no solver yet)",
        t.elapsed().as_secs_f64() * 1e3 / steps as f64
    );
}

#[test]
#[ignore]
fn pyramid_pair_stages() {
    report("large_pyramid", pyramids(1, 100, 400));
    report("many_pyramids", pyramids(14, 10, 77));
}
