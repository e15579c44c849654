//! The tuner behind `lockstep tune`: the choice is within the bound and the
//! cheapest, by recomputation; the reference against itself is exact; a
//! tighter bound moves the choice to finer settings; a faulting scene is an
//! error. Short runs (`ticks`) keep it fast; the choices asserted on are by
//! the deterministic work count. The command itself is tested in the
//! `lockstep` package (`cli/tests/tune.rs`).

mod common;

use common::{scene, temp_dir};

use lockstep_tools::tune::{
    Candidates, CostBasis, Plan, Scene, Settings, TuneError, TuneOptions, reference_settings,
    run_tune,
};

fn options(name: &str, ticks: u64, max_error: f64) -> TuneOptions {
    TuneOptions {
        ticks: Some(ticks),
        max_error,
        repeats: 1,
        cost: CostBasis::Work,
        out: None,
        ..TuneOptions::new(scene(name))
    }
}

#[test]
fn the_choice_is_within_the_bound_and_the_cheapest_by_recomputation() {
    let opts = options("pyramid.toml", 30, 1e-3);
    let mut printed = Vec::new();
    let report = run_tune(&opts, &mut printed).unwrap();
    let text = String::from_utf8(printed).unwrap();
    // Every combination is tried and shown: 4 tick rates × 4 substep counts
    // (the scene's own 60 Hz and 4 substeps are among them) × 3 × 2.
    assert_eq!(report.trials.len(), 4 * 4 * 3 * 2);
    let rows = text
        .lines()
        .filter(|l| l.ends_with("pass") || l.contains("fail") || l.contains("(scene's own)"))
        .count();
    assert_eq!(rows, report.trials.len(), "{text}");

    let chosen = report
        .chosen()
        .expect("the pyramid has settings within 1 mm");
    assert!(
        text.contains(&format!("chosen: {}", chosen.settings)),
        "{text}"
    );

    // Recompute the chosen run's error from scratch.
    let scene = Scene::load(&opts.scene).unwrap();
    let reference = scene.run(report.reference, report.plan).unwrap();
    let run = scene.run(chosen.settings, report.plan).unwrap();
    assert!(run.fault.is_none());
    let d = scene.deviation(&run.trajectory, &reference.trajectory);
    assert_eq!(Some(d), chosen.deviation);
    assert!(d.error <= opts.max_error, "{d:?}");
    assert!(d.error > 0.0, "the chosen settings are not the reference's");

    // It is the cheapest within the bound: every trial with less work fails,
    // and every trial's pass flag matches its recomputed error.
    for t in &report.trials {
        if t.work_per_s < chosen.work_per_s {
            assert!(
                !t.pass,
                "{:?} passes with less work than the choice",
                t.settings
            );
        }
        let e = t.deviation.expect("the pyramid never faults").error;
        assert_eq!(t.pass, e <= opts.max_error);
    }
    // The scene's own settings are in the table, marked.
    assert_eq!(
        report.own_trial().settings,
        Settings {
            tick_rate: 60,
            substeps: 4,
            solver_iterations: 1,
            relax_iterations: 1
        }
    );
}

#[test]
fn the_reference_against_itself_has_error_zero() {
    let scene_ = Scene::load(&scene("shapes.toml")).unwrap();
    let reference = reference_settings(scene_.own(), &Candidates::default());
    let plan = Plan {
        sample_hz: 30,
        samples: 15,
    };
    let a = scene_.run(reference, plan).unwrap();
    let b = scene_.run(reference, plan).unwrap();
    assert_eq!(a.trajectory.clone(), b.trajectory);
    let d = scene_.deviation(&a.trajectory, &b.trajectory);
    assert_eq!((d.error, d.position, d.angle), (0.0, 0.0, 0.0));
    // The same through the tuner: candidate lists of the reference's own
    // values (the scene's own are added) give a row with error exactly 0.
    let mut opts = options("shapes.toml", 30, 1e-3);
    opts.candidates = Candidates {
        tick_rates: vec![reference.tick_rate],
        substeps: vec![reference.substeps],
        solver_iterations: vec![reference.solver_iterations],
        relax_iterations: vec![reference.relax_iterations],
    };
    let report = run_tune(&opts, &mut Vec::new()).unwrap();
    assert_eq!(report.reference, reference);
    let same = report
        .trials
        .iter()
        .find(|t| t.settings == reference)
        .unwrap();
    assert_eq!(same.deviation.unwrap().error, 0.0);
    assert!(same.pass);
}

#[test]
fn a_bound_the_coarse_settings_miss_picks_finer_ones() {
    // The free spin's error depends on the substep length only: at 2 s the
    // coarsest settings (30 Hz, 1 substep) are centimetres off.
    let coarsest = Settings {
        tick_rate: 30,
        substeps: 1,
        solver_iterations: 1,
        relax_iterations: 1,
    };
    let loose = run_tune(&options("spin.toml", 120, 1.0), &mut Vec::new()).unwrap();
    assert_eq!(loose.chosen().unwrap().settings, coarsest);
    let coarse_error = loose.chosen().unwrap().deviation.unwrap().error;
    assert!(coarse_error > 1e-2, "{coarse_error}");

    let tight = run_tune(&options("spin.toml", 120, 1e-3), &mut Vec::new()).unwrap();
    let chosen = tight.chosen().unwrap();
    assert_ne!(chosen.settings, coarsest);
    assert!(chosen.deviation.unwrap().error <= 1e-3);
    // Finer: a shorter substep than the coarsest's.
    let substep_hz = |s: Settings| s.tick_rate * s.substeps;
    assert!(substep_hz(chosen.settings) > substep_hz(coarsest));
    assert!(chosen.work_per_s > loose.chosen().unwrap().work_per_s);
    // With no contacts, iterations buy nothing: the choice keeps the fewest.
    assert_eq!(
        (
            chosen.settings.solver_iterations,
            chosen.settings.relax_iterations
        ),
        (1, 1)
    );
}

#[test]
fn a_scene_that_faults_at_the_reference_is_an_error() {
    let dir = temp_dir("tune", "fault");
    let file = dir.join("runaway.toml");
    // 648 m short of the Q32.32 range, at 1 km/s: it overflows after 0.65 s.
    std::fs::write(
        &file,
        "[world]\ngravity = [0, 0, 0]\n\n[[bodies]]\nname = \"runaway\"\nkind = \"dynamic\"\n\
         position = [2147483000, 0, 0]\nlinear_velocity = [1000, 0, 0]\n\
         shapes = [{ kind = \"sphere\", radius = 0.5 }]\n",
    )
    .unwrap();
    let mut opts = options("unused", 60, 1e-3);
    opts.scene = file.clone();
    match run_tune(&opts, &mut Vec::new()) {
        Err(TuneError::ReferenceFault { tick, .. }) => assert!(tick > 0),
        other => panic!("expected a reference fault, got {other:?}"),
    }
}
