//! Golden hashes: every example scene still produces the recorded hashes.
//! A mismatch means simulation results changed: if on purpose, rerun with
//! `LOCKSTEP_BLESS=1` and commit the new files on their own, saying why.

use lockstep_tests::{example_scenes, golden_lines, repo_root};

#[test]
fn example_scenes_match_their_golden_hashes() {
    let bless = std::env::var_os("LOCKSTEP_BLESS").is_some();
    let scenes = example_scenes();
    assert!(scenes.len() >= 3, "expected the example scenes in scenes/");
    let mut failures = Vec::new();
    for scene in scenes {
        let name = scene.file_stem().unwrap().to_string_lossy().to_string();
        let golden = repo_root()
            .join("tests/golden")
            .join(format!("{name}.hashes"));
        let got = golden_lines(&scene);
        if bless {
            std::fs::write(&golden, &got).unwrap();
            continue;
        }
        let want = std::fs::read_to_string(&golden).unwrap_or_else(|e| {
            panic!(
                "{}: {e} (run with LOCKSTEP_BLESS=1 to create it)",
                golden.display()
            )
        });
        if got != want {
            let first = got.lines().zip(want.lines()).find(|(g, w)| g != w);
            failures.push(format!("{name}: first difference (got, golden): {first:?}"));
        }
    }
    assert!(
        failures.is_empty(),
        "golden hashes changed:\n{}",
        failures.join("\n")
    );
}

#[test]
fn the_same_scene_file_gives_the_same_hashes_twice() {
    for scene in example_scenes() {
        assert_eq!(
            golden_lines(&scene),
            golden_lines(&scene),
            "{}",
            scene.display()
        );
    }
}
