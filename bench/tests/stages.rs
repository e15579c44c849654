//! `engines --stages` end to end: the binary prints a stage table per
//! scene, and, where valgrind is installed, instruction counts that add up
//! and are the same on every run (callgrind counts are exact).

use std::path::PathBuf;
use std::process::Command;

/// Runs `engines --stages --quick` on one scene; returns stdout and the
/// CSV's stage section (without its header).
fn run(scene: &str, tag: &str) -> (String, Vec<Vec<String>>) {
    let csv: PathBuf = std::env::temp_dir().join(format!(
        "lockstep-bench-stages-test-{}-{tag}.csv",
        std::process::id()
    ));
    let out = Command::new(env!("CARGO_BIN_EXE_lockstep-bench"))
        .args(["engines", "--stages", "--quick", "--scenes", scene, "--csv"])
        .arg(&csv)
        .output()
        .expect("run lockstep-bench");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&csv).expect("csv written");
    let _ = std::fs::remove_file(&csv);
    let (headline, stages) = text.split_once("\n\n").expect("a stage section");
    // The headline section is as without --stages: a header and two lines.
    assert_eq!(headline.lines().count(), 3, "{headline}");
    let mut lines = stages.lines();
    assert!(
        lines
            .next()
            .unwrap()
            .starts_with("section,scene,engine,group,stage,")
    );
    let rows = lines
        .map(|l| l.split(',').map(str::to_owned).collect())
        .collect();
    (stdout, rows)
}

fn valgrind_installed() -> bool {
    Command::new("valgrind")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

#[test]
fn stage_tables_add_up_and_instruction_counts_repeat() {
    let (stdout, rows) = run("large_pyramid", "a");
    assert!(stdout.contains("stages of large_pyramid"), "{stdout}");
    for stage in [
        "broad_phase",
        "narrow_phase",
        "solve",
        "relax",
        "sync_proxies",
    ] {
        assert!(
            stdout
                .lines()
                .any(|l| l.starts_with(&format!("  {stage} "))),
            "no {stage} line in\n{stdout}"
        );
    }
    if !valgrind_installed() {
        assert!(
            stdout.contains("instruction counts skipped: valgrind is not installed"),
            "{stdout}"
        );
        return;
    }
    let ir = |r: &Vec<String>| r[7].parse::<u64>().ok();
    let ours: Vec<&Vec<String>> = rows.iter().filter(|r| r[2] == "lockstep").collect();
    assert!(ours.iter().all(|r| ir(r).is_some()), "{rows:?}");
    // Stages add up to their groups, groups to the total.
    let total = ours.iter().find(|r| r[3] == "total").and_then(|r| ir(r));
    let groups: u64 = ours
        .iter()
        .filter(|r| r[3] != "total" && r[4].is_empty())
        .filter_map(|r| ir(r))
        .sum();
    let stages: u64 = ours
        .iter()
        .filter(|r| !r[4].is_empty())
        .filter_map(|r| ir(r))
        .sum();
    assert_eq!(Some(groups), total);
    assert_eq!(stages, groups);
    // The solver does work on touching boxes: well above zero.
    let solve = ours.iter().find(|r| r[4] == "solve").and_then(|r| ir(r));
    assert!(solve.unwrap() > 1000, "{solve:?}");
    // Counted again: the same instructions, stage by stage.
    let (_, again) = run("large_pyramid", "b");
    let counts = |rows: &[Vec<String>]| -> Vec<(String, String)> {
        rows.iter()
            .filter(|r| r[2] == "lockstep")
            .map(|r| (r[4].clone(), r[7].clone()))
            .collect()
    };
    assert_eq!(counts(&rows), counts(&again));
}
