//! The `profile` suite: steps only lockstep-core on the chosen scenes (by
//! default `large_pyramid`) for a few steps, so `perf record` or
//! `valgrind --tool=callgrind` see our engine alone, and prints ms/step
//! (first step excluded) with the scene's contact points, the last step's
//! narrow-phase tests and how many of them reused a manifold, top-box drop and
//! final state hash (so a change meant to keep results can be checked bit
//! for bit). `--threads N` steps the contact solver in colour order on N
//! workers instead of pair order on one; `--stages` also prints ms/step per
//! stage (timed through `World::step_observed`).

use std::fmt::Write as _;
use std::time::Instant;

use lockstep_core::ContactOrder;
use lockstep_core::world::Stage;

use crate::engines::{build_ours_in, scene_list, sleep_off};
use crate::stages::StageClock;
use crate::{Options, SuiteOutput};

/// Steps when `--steps` is not given.
const DEFAULT_STEPS: usize = 20;

/// Runs the suite.
pub fn run(opts: &Options) -> SuiteOutput {
    let steps = opts.steps.unwrap_or(DEFAULT_STEPS).max(2);
    let wanted = opts
        .scenes
        .clone()
        .unwrap_or_else(|| vec!["large_pyramid".to_owned()]);
    let order = match opts.threads {
        Some(_) => ContactOrder::Colors,
        None => ContactOrder::Pairs,
    };
    let workers = opts.threads.unwrap_or(1);
    let mut text = format!(
        "ours in {} order on {workers} worker(s)\n",
        match order {
            ContactOrder::Colors => "colour",
            ContactOrder::Pairs => "pair",
        }
    );
    text.push_str(
        "scene           bodies  steps   ms/step  contacts    tests  reused  top dy m  state hash\n",
    );
    let mut csv = String::from(
        "suite,scene,bodies,steps,ms_per_step,contact_points,narrow_tests,reused_manifolds,top_dy_m,state_hash\n",
    );
    for (name, scene) in scene_list(opts.quick) {
        let Some(scene) = scene else { continue };
        if !wanted.iter().any(|w| w == name) {
            continue;
        }
        let (mut world, bodies) = build_ours_in(&scene, sleep_off(), order, opts.rows);
        world.set_workers(workers);
        world.set_wide(opts.wide);
        world.set_lanes(opts.lanes);
        // With workers, where the host had the CPUs (see
        // `harness::core_round_trip_ns`), before and after the steps.
        let trip_before =
            (workers > 1).then(|| crate::harness::core_round_trip_ns(crate::harness::ROUND_TRIPS));
        let mut clock = StageClock::new();
        let mut total = 0.0;
        let (mut points, mut tests, mut reused) = (0, 0, 0);
        let (mut wide, mut guarded) = (0u64, 0u64);
        let (mut narrow, mut fallbacks, mut batches, mut constraints) = (0u64, 0u64, 0u64, 0u64);
        for i in 0..steps {
            let t = Instant::now();
            let r = if opts.stages {
                clock.start_step();
                world.step_observed(&mut clock)
            } else {
                world.step()
            };
            if i == 0 {
                clock.reset();
            } else {
                total += t.elapsed().as_secs_f64();
            }
            (points, tests, reused) = (r.contact_points, r.narrow_tests, r.reused_manifolds);
            wide += u64::from(r.wide_batches);
            guarded += u64::from(r.wide_batches_guarded);
            narrow += u64::from(r.narrow_constraints);
            fallbacks += u64::from(r.narrow_fallbacks);
            batches += u64::from(r.lane_batches);
            constraints += u64::from(r.contact_constraints);
        }
        // The final state hash: optimisations that must not change results
        // are checked by comparing it before and after.
        let hash = world.state_hash();
        let ms = total * 1e3 / (steps - 1) as f64;
        let trips = trip_before.map(|before| {
            let after = crate::harness::core_round_trip_ns(crate::harness::ROUND_TRIPS);
            format!("  (core round trip {before:.0} ns before, {after:.0} ns after)")
        });
        let top_dy = scene
            .tops
            .iter()
            .map(|&i| {
                let y = world
                    .body(bodies[i])
                    .map_or(f64::NAN, |b| b.position().y.to_f64());
                (y - scene.positions[i][1]).abs()
            })
            .fold(0.0, f64::max);
        let _ = writeln!(
            text,
            "{name:<14} {:>7} {steps:>6} {ms:>9.3} {points:>9} {tests:>8} {reused:>7} {top_dy:>9.4}  {hash:016x}{}",
            scene.positions.len(),
            trips.unwrap_or_default()
        );
        let _ = writeln!(
            csv,
            "profile,{name},{},{steps},{ms:.4},{points},{tests},{reused},{top_dy:.6},{hash:016x}",
            scene.positions.len()
        );
        let _ = writeln!(
            text,
            "    normal rows: {}",
            crate::harness::kernels(&world, order, wide, guarded)
        );
        let _ = writeln!(
            text,
            "    {}",
            crate::harness::rows_line(&world, constraints, narrow, fallbacks, batches)
        );
        if opts.stages {
            for (stage, d) in Stage::ALL.iter().zip(clock.spent()) {
                let ms = d.as_secs_f64() * 1e3 / (steps - 1) as f64;
                let _ = writeln!(text, "    {:<22} {ms:>9.3}", stage.name());
            }
        }
    }
    SuiteOutput { text, csv }
}
