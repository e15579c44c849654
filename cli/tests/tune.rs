//! `lockstep tune` as a user runs it: it prints the table and the choice and
//! draws the plot; bad flags and faulting scenes give clear errors and exit
//! with status 2. Short runs keep it fast. The tuner's choices are
//! tested in the client library (`client/tests/tune.rs`).

mod common;

use common::{lockstep, scene, temp_dir};

#[test]
fn a_scene_that_faults_at_the_reference_exits_two_naming_the_fault() {
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
