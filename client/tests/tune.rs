//! `lockstep tune`: the choice is within the bound and the cheapest, by
//! recomputation; the reference against itself is exact; a tighter bound
//! moves the choice to finer settings; bad flags and faulting scenes give
//! clear errors. Short runs (`ticks`) and one timed run keep it fast; the
//! choices asserted on are by the deterministic work count.

mod common;

use common::{lockstep, scene, temp_dir};

use lockstep_client::offline::tune::{
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
    let out = lockstep()
        .args(["tune", "--scene"])
        .arg(&file)
        .args(["--ticks", "60", "--repeats", "1", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("arithmetic fault") && err.contains("overflow"),
        "{err}"
    );
}

#[test]
fn the_cli_prints_the_table_and_the_choice_and_draws_the_plot() {
    let dir = temp_dir("tune", "cli");
    let out = lockstep()
        .args(["tune", "--scene"])
        .arg(scene("spin.toml"))
        .args([
            "--ticks",
            "60",
            "--max-error",
            "0.5cm",
            "--repeats",
            "1",
            "--cost",
            "work",
            "--iterations",
            "1",
            "--relax",
            "1",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    // 4 tick rates × 4 substep counts, one iteration pair.
    let rows = text
        .lines()
        .filter(|l| l.trim_start().starts_with(|c: char| c.is_ascii_digit()))
        .count();
    assert_eq!(rows, 16, "{text}");
    assert!(text.contains("chosen: "), "{text}");
    assert!(
        text.contains("speed-up over the scene's own settings"),
        "{text}"
    );
    assert!(
        text.contains("scene's own settings (60 Hz, 8 substeps"),
        "{text}"
    );
    let svg = std::fs::read_to_string(dir.join("spin.svg")).unwrap();
    assert!(
        svg.starts_with("<svg") && svg.contains("chosen: "),
        "{}",
        &svg[..100]
    );
    let csv = std::fs::read_to_string(dir.join("spin.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 16);
    assert_eq!(csv.lines().filter(|l| l.ends_with(",true")).count(), 1);
}

#[test]
fn bad_flags_give_clear_errors() {
    let cases: [(&[&str], &str); 7] = [
        (&["--max-error", "1"], "no unit"),
        (&["--max-error", "1km"], "not a length"),
        (&["--max-error=-2mm"], "at least 0"),
        (&["--ticks", "0"], "--ticks"),
        (&["--ticks", "1"], "shorter than one comparison interval"),
        (&["--substeps", "0"], "out of range"),
        (&["--tick-rates", "60,20000"], "out of range"),
    ];
    for (args, expected) in cases {
        let out = lockstep()
            .args(["tune", "--scene"])
            .arg(scene("spin.toml"))
            .args(args)
            .args(["--repeats", "1", "--out"])
            .arg(temp_dir("tune", "flags"))
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(expected), "{args:?}: {err}");
    }
    let out = lockstep()
        .args(["tune", "--scene", "no/such/scene.toml"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no/such/scene.toml"));
}
