//! Helpers shared by the cross-crate tests.
//!
//! Golden hash files (`tests/golden/<scene>.hashes`) pin the simulation
//! results of each example scene: one line `tick <n> <16 hex digits>` every
//! [`GOLDEN_EVERY`] ticks up to [`GOLDEN_TICKS`]. A change that alters
//! results must update them on purpose, in its own commit, with the reason
//! in the message: run the tests with `LOCKSTEP_BLESS=1` to rewrite them.

#![warn(missing_docs)]

pub mod agones;
pub mod harness;
pub mod link;

use std::path::{Path, PathBuf};

use lockstep_tools::load_scene_file;

/// How many ticks the golden files cover.
pub const GOLDEN_TICKS: u64 = 1000;
/// A golden line every this many ticks.
pub const GOLDEN_EVERY: u64 = 50;

/// The repository root.
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Every `scenes/*.toml`, sorted by name.
pub fn example_scenes() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(repo_root().join("scenes"))
        .expect("scenes/ exists")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    v.sort();
    v
}

/// Steps a scene file and returns the golden lines; panics on a bad scene
/// or an arithmetic fault (both are test failures).
pub fn golden_lines(scene: &Path) -> String {
    let mut world = load_scene_file(scene).unwrap_or_else(|e| panic!("{e}"));
    let mut out = String::new();
    for _ in 0..GOLDEN_TICKS {
        let r = world.step();
        assert!(
            r.faults.is_empty(),
            "{}: tick {}: {}",
            scene.display(),
            r.tick,
            r.faults
        );
        if r.tick.is_multiple_of(GOLDEN_EVERY) {
            out.push_str(&format!("tick {} {:016x}\n", r.tick, world.state_hash()));
        }
    }
    out
}
