//! The suite's own logic.

use super::measure::*;
use super::ours::*;
use super::rapier::*;
use super::*;

#[test]
fn a_scene_file_builds_the_same_bodies_and_joints_in_both_engines() {
    let scene = scenes::from_file("ragdolls", &scenes::ragdolls_toml(2, 1), 1);
    let mut ours = Ours::new(&scene);
    let mut theirs = Rapier::new(&scene);
    assert_eq!(scene.positions.len(), 22);
    assert_eq!(ours.positions(), scene.positions);
    let apart = theirs
        .positions()
        .iter()
        .zip(&scene.positions)
        .map(|(a, b)| (0..3).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max))
        .fold(0.0, f64::max);
    assert!(apart < 1e-6, "Rapier's bodies are {apart} m off");
    assert_eq!(ours.world.joint_count(), 20);
    assert_eq!(theirs.world.impulse_joints.len(), 20);
    // 9 steps + floor + 22 capsules in each.
    assert_eq!(theirs.world.colliders.len(), 32);
    let mass = |i: usize| {
        let m = ours.world.body(ours.bodies[i]).unwrap().mass().to_f64();
        let rm = theirs.world.bodies[theirs.bodies[i]].mass() as f64;
        (m, rm)
    };
    for i in 0..22 {
        let (m, rm) = mass(i);
        assert!((m - rm).abs() < 1e-4 * m, "body {i}: {m} kg against {rm}");
    }
    // Both tumble down the stairs without flying apart.
    for _ in 0..120 {
        ours.step();
        theirs.step();
    }
    assert!(!ours.faulted);
    for p in ours.positions().iter().chain(&theirs.positions()) {
        assert!(p[1] < 2.5 && p[1] > -6.0 && p[0].abs() < 6.0, "{p:?}");
    }
}

#[test]
fn both_engines_build_the_same_bodies_at_the_same_places() {
    let scene = scenes::jolt_pyramid(3, 1);
    let ours = Ours::new(&scene);
    let theirs = Rapier::new(&scene);
    assert_eq!(ours.positions(), scene.positions);
    assert_eq!(theirs.positions(), scene.positions);
    // Same mass: density 1000 × 8 m³.
    let m = ours.world.body(ours.bodies[0]).unwrap().mass().to_f64();
    let rm = theirs.world.bodies[theirs.bodies[0]].mass() as f64;
    assert!(
        (m - 8000.0).abs() < 1e-6 && (rm - 8000.0).abs() < 1e-2,
        "{m} {rm}"
    );
}

#[test]
fn threads_runs_each_order_on_one_and_n_workers_to_the_same_positions() {
    let scene = scenes::large_pyramid(6, 20);
    let r = run_scene(&scene, 1, Some(3), false);
    let t = r.threaded.as_ref().expect("threaded runs");
    assert_eq!(t.workers, 3);
    for e in [&t.pairs_many, &t.one, &t.many, &t.rapier_many] {
        assert!(e.median_ms > 0.0 && !e.faulted);
    }
    // Rapier on 3 threads simulated the same scene: its pyramid stands
    // as on one thread.
    assert!(r.rapier.top_dy < 0.01 && t.rapier_many.top_dy < 0.01);
    // The same bits on 1 and 3 workers, so the same end positions.
    assert_eq!(
        t.one.max_displacement.to_bits(),
        t.many.max_displacement.to_bits()
    );
    assert_eq!(t.one.top_dy.to_bits(), t.many.top_dy.to_bits());
    assert_eq!(
        r.ours.max_displacement.to_bits(),
        t.pairs_many.max_displacement.to_bits()
    );
    assert_eq!(r.ours.top_dy.to_bits(), t.pairs_many.top_dy.to_bits());
    let table = threads_table(&[r]);
    assert!(table.contains("large_pyramid    3"), "{table}");
    assert!(table.contains("colours N"), "{table}");
    assert!(table.contains("rapier N"), "{table}");
}

#[test]
fn a_quick_scene_runs_in_both_engines_and_reports_every_column() {
    let scene = scenes::large_pyramid(3, 3);
    let r = run_scene(&scene, 1, None, false);
    assert_eq!((r.bodies, r.steps, r.runs), (6, 3, 1));
    assert!(r.threaded.is_none() && threads_table(std::slice::from_ref(&r)).is_empty());
    for e in [&r.ours, &r.rapier] {
        assert!(e.median_ms > 0.0 && e.min_ms <= e.median_ms);
        assert!(e.peak_bytes > 0);
        assert!(e.max_displacement.is_finite() && e.top_dy.is_finite());
        assert!(e.max_horizontal <= e.max_displacement);
        // Six boxes, all still on the ground, the median one at least
        // one box above the lowest layer's centre.
        for q in &e.settle {
            assert_eq!(q.on_ground, 6);
            assert!(q.median_y > 0.5 && q.median_y < 10.0, "{q:?}");
        }
    }
    // Rapier resolves the resting contacts: the 6 boxes touch.
    assert!(r.rapier.contact_points >= 4, "{}", r.rapier.contact_points);
    let c = csv(&[r]);
    assert_eq!(c.lines().count(), 3);
    assert!(
        c.lines()
            .nth(1)
            .unwrap()
            .starts_with("engines,large_pyramid,lockstep,6,3,1,")
    );
}

#[test]
fn median_of_even_and_odd_counts() {
    let run = |ms| Run {
        ms_per_step: ms,
        contact_points: 0,
        peak_bytes: 0,
        max_displacement: 0.0,
        max_horizontal: 0.0,
        top_dy: 0.0,
        settle: [Settle::default(); 4],
    };
    assert_eq!(median_min(&[run(3.0), run(1.0), run(2.0)]), (2.0, 1.0));
    assert_eq!(median_min(&[run(4.0), run(1.0)]), (2.5, 1.0));
}
