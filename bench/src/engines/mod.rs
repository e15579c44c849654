//! The `engines` suite: the performance scenes (docs/engines.md) built from one
//! recipe ([`crate::scenes`]) in lockstep-core and in Rapier, stepped
//! alternately (ours, Rapier, ours, Rapier, ...) in one process.
//!
//! Per scene it reports ms/step for both (median and minimum over the runs,
//! the first step of each run excluded: it builds the trees and the first
//! contacts), their ratio, the bodies, the contact points after the last
//! step, the heap high-water mark per body, and whether the pyramids still
//! stand (the largest displacement of any body from its start, and how far
//! each pyramid's top box moved vertically: standing = every top within
//! 1 cm).

mod measure;
mod ours;
mod rapier;
mod report;
#[cfg(test)]
mod tests;

use std::fmt::Write as _;

pub use measure::run_scene;
pub(crate) use ours::sleep_off;
pub use ours::{build_ours, build_ours_in};
use rapier::rapier_parameters;
pub(crate) use rapier::{Rapier, on_one_thread, rapier_parameters_for};
pub use report::{csv, rows_table, table, threads_table};

use crate::scenes::{self, Scene};
use crate::stages;
use crate::{Options, SuiteOutput};

/// Steps per second in both engines.
pub(super) const TICK_RATE: u32 = 60;
/// Our substeps per step.
pub(crate) const SUBSTEPS: u32 = 4;

/// The settings line printed with the table.
pub(super) fn settings_text() -> String {
    let p = rapier_parameters();
    format!(
        "ours: lockstep-core (Q32.32), tick_rate {TICK_RATE}, substeps {SUBSTEPS} (1 solve + 1 relax pass each), \
         friction at each manifold's patch centre (2 tangent rows + twist), sleep off, contact margin 2 cm\n\
         rapier3d 0.36.1 (dim3, f32, enhanced-determinism, `parallel` on a pool of one thread; `--threads N`: also on N): dt 1/{TICK_RATE}, \
         num_solver_iterations {} (= substeps), num_internal_pgs_iterations {}, \
         num_internal_stabilization_iterations {}, warmstart_coefficient {}, contact_clustering {}, \
         contact_recycling {}, prediction distance {} m, CCD off, can_sleep(false)\n\
         both: gravity (0, -10, 0), friction 0.6, restitution 0; bodies = dynamic bodies (plus one static ground)\n\
         ragdolls: the scene file's own world (gravity -9.81, 60 Hz, 4 substeps), shapes, statics and joints in both; \
         Rapier's cone limits are +/- the cone about the frame's y and z axes (docs/engines.md)",
        p.num_solver_iterations,
        p.num_internal_pgs_iterations,
        p.num_internal_stabilization_iterations,
        p.warmstart_coefficient,
        p.contact_clustering,
        p.contact_recycling,
        p.normalized_prediction_distance * p.length_unit,
    )
}

/// The two engines behind one small interface.
pub(super) trait Sim {
    fn step(&mut self);
    /// Contact points after the last step.
    fn contact_points(&self) -> usize;
    /// Positions of the dynamic bodies, in scene order.
    fn positions(&self) -> Vec<[f64; 3]>;
}
/// The scenes by name, at full or quick size.
pub(crate) fn scene_list(quick: bool) -> Vec<(&'static str, Option<Scene>)> {
    if quick {
        vec![
            ("large_pyramid", Some(scenes::large_pyramid(10, 5))),
            ("many_pyramids", Some(scenes::many_pyramids(2, 4, 10.0, 5))),
            ("joint_grid", Some(scenes::joint_grid(4, 5))),
            ("convex_pile", Some(scenes::convex_pile(2, 2, 2, 5))),
            ("jolt_pyramid", Some(scenes::jolt_pyramid(4, 5))),
            (
                "ragdolls",
                Some(scenes::from_file(
                    "ragdolls",
                    &scenes::ragdolls_toml(2, 1),
                    5,
                )),
            ),
        ]
    } else {
        vec![
            ("large_pyramid", Some(scenes::large_pyramid(100, 200))),
            (
                "many_pyramids",
                Some(scenes::many_pyramids(14, 10, 77.0, 100)),
            ),
            ("joint_grid", Some(scenes::joint_grid(100, 100))),
            ("convex_pile", Some(scenes::convex_pile(8, 8, 80, 500))),
            ("jolt_pyramid", Some(scenes::jolt_pyramid(15, 500))),
            (
                "ragdolls",
                Some(scenes::from_file(
                    "ragdolls",
                    include_str!("../../../scenes/ragdolls_100.toml"),
                    RAGDOLL_STEPS,
                )),
            ),
        ]
    }
}

/// The scene names the suite knows, for `--scenes` checking.
pub const SCENE_NAMES: &[&str] = &[
    "large_pyramid",
    "many_pyramids",
    "joint_grid",
    "convex_pile",
    "jolt_pyramid",
    "ragdolls",
];

/// Steps of the ragdoll scene: 10 s, time for the 100 ragdolls to tumble
/// down the stairs and come to rest.
const RAGDOLL_STEPS: usize = 600;

/// Runs the suite (with `--stages`, the stage tables after the headline
/// ones; the headline runs are the same either way).
pub fn run(opts: &Options) -> SuiteOutput {
    let runs = opts.runs.unwrap_or(if opts.quick { 1 } else { 3 });
    let mut results = Vec::new();
    let mut staged = Vec::new();
    let mut skipped = Vec::new();
    for (name, scene) in scene_list(opts.quick) {
        if let Some(filter) = &opts.scenes
            && !filter.iter().any(|f| f == name)
        {
            continue;
        }
        match scene {
            None => skipped.push(name),
            Some(mut scene) => {
                if let Some(steps) = opts.steps {
                    scene.steps = steps.max(2);
                }
                eprintln!(
                    "engines: {name} ({} bodies, {} steps, {runs} runs per engine)...",
                    scene.positions.len(),
                    scene.steps
                );
                let result = run_scene(&scene, runs, opts.threads, opts.wide);
                if opts.stages {
                    eprintln!("engines --stages: {name}: stage runs, then instruction counts...");
                    let headline = (result.ours.median_ms, result.rapier.median_ms);
                    let count_steps = if opts.quick { 2 } else { stages::COUNT_STEPS };
                    staged.push(stages::run_scene(
                        &scene,
                        runs,
                        headline,
                        count_steps,
                        opts.callgrind_dir.as_deref(),
                    ));
                }
                results.push(result);
            }
        }
    }
    let mut text = format!("{}\n\n", settings_text());
    text.push_str(&table(&results, &skipped));
    text.push_str(&rows_table(&results));
    text.push_str(&threads_table(&results));
    let mut csv = csv(&results);
    if opts.stages {
        let _ = writeln!(text, "\n{}\n", stages::RAPIER_MAPPING);
        let _ = writeln!(csv, "\n{}", stages::CSV_HEADER);
        for r in &staged {
            let _ = writeln!(text, "{}", stages::table(r));
            csv.push_str(&stages::csv_lines(r));
        }
    }
    SuiteOutput { text, csv }
}
