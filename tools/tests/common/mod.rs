//! Helpers shared by the integration tests: the example scenes and
//! per-test scratch folders.

#![allow(dead_code)]

use std::path::PathBuf;

/// An example scene from the repository's `scenes/`.
pub fn scene(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../scenes")
        .join(name)
}

/// A scratch folder for one test, named by the test file's `suite` and
/// the test's `tag` (and the process, so parallel runs do not collide).
pub fn temp_dir(suite: &str, tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("lockstep-{suite}-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}
