//! # lockstep-testkit
//!
//! Desync regression tests for a game built on lockstep: a folder of replays
//! recorded from real matches, re-simulated with the game's current rules
//! and engine in the game's own `cargo test`.
//!
//! ```no_run
//! use lockstep_client::game::Demo;
//!
//! #[test]
//! fn recorded_matches_still_replay() {
//!     lockstep_testkit::assert_replays("tests/replays", &Demo);
//! }
//! ```
//!
//! Every `*.replay` file of the folder is checked (in name order): its
//! header must name the same rules (id and version) and state-hash layout,
//! and every tick's re-simulated hash must equal the one the players agreed
//! on, to the file's end record. A failure names the replay, the first tick
//! that differs, and the
//! bodies that differ (where the replay recorded body hashes: record with
//! `ClientOptions::body_hashes_every` set). `docs/own-game.md` says how to
//! record a replay from a real match and drop it into the folder.
//!
//! [`assert_sync`] is the other half: the game's determinism checked on one
//! machine (a twin and a rollback every tick), before any replay exists.

#![warn(missing_docs)]

use std::fmt;
use std::path::{Path, PathBuf};

use lockstep_client::game::RulesFactory;
use lockstep_tools::{
    ReplayCheck, ReplayVerifyError, SyncTestOptions, SyncTestReport, sync_test, verify_replay_file,
};

/// The replays that verified.
#[derive(Clone, Debug)]
pub struct KitReport {
    /// Each replay checked, in name order, with what its check found.
    pub replays: Vec<(PathBuf, ReplayCheck)>,
}

impl KitReport {
    /// Hashes checked over all replays.
    pub fn hashes_checked(&self) -> u64 {
        self.replays.iter().map(|(_, c)| c.checked).sum()
    }
}

/// Why a folder of replays does not pass.
pub enum KitFailure {
    /// The folder could not be listed.
    Folder(PathBuf, std::io::Error),
    /// The folder holds no `*.replay` file: a regression test that checks
    /// nothing would pass forever.
    Empty(PathBuf),
    /// Some replays failed; the others passed.
    Replays {
        /// Each failing replay with its error, in name order.
        failed: Vec<(PathBuf, ReplayVerifyError)>,
        /// Each cut replay (no end record, or its last record incomplete:
        /// the server stopped while recording, or the file was copied
        /// before the match ended), in name order. What it holds matched,
        /// but the rest of the match is checked by nobody, so it fails.
        cut: Vec<(PathBuf, ReplayCheck)>,
        /// The replays that passed.
        passed: Vec<(PathBuf, ReplayCheck)>,
    },
}

impl fmt::Display for KitFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            KitFailure::Folder(p, e) => write!(f, "{}: {e}", p.display()),
            KitFailure::Empty(p) => write!(f, "{}: no *.replay file to check", p.display()),
            KitFailure::Replays {
                failed,
                cut,
                passed,
            } => {
                let bad = failed.len() + cut.len();
                writeln!(f, "{bad} of {} replays failed:", bad + passed.len())?;
                for (path, c) in cut {
                    writeln!(
                        f,
                        "{}: cut at tick {}: {} (the server stopped while recording, or the file \
                         was copied before the match ended); the {} hashes it holds match, but \
                         the rest of the match is not checked: keep whole matches in a \
                         regression folder",
                        path.display(),
                        c.ticks,
                        c.cut_description().unwrap_or_default(),
                        c.checked,
                    )?;
                }
                for (path, e) in failed {
                    write!(f, "{}: {e}", path.display())?;
                    match e {
                        ReplayVerifyError::Mismatch {
                            bodies: Some(at), ..
                        } if at.bodies.is_empty() => writeln!(
                            f,
                            "; every body's hash agrees at tick {} (the difference is elsewhere in the state: contacts or settings)",
                            at.tick
                        )?,
                        ReplayVerifyError::Mismatch {
                            bodies: Some(at), ..
                        } => {
                            writeln!(
                                f,
                                "; {} bodies differ at tick {}:",
                                at.bodies.len(),
                                at.tick
                            )?;
                            for b in &at.bodies {
                                writeln!(f, "    {b}")?;
                            }
                        }
                        ReplayVerifyError::NotReproduced { offline, .. } => {
                            writeln!(f, "; this machine's values are the expected ones:")?;
                            write!(f, "{offline}")?;
                        }
                        ReplayVerifyError::Mismatch { bodies: None, .. } => writeln!(
                            f,
                            "; the replay holds no body hashes from that tick on, so the bodies cannot be named"
                        )?,
                        _ => writeln!(f)?,
                    }
                }
                Ok(())
            }
        }
    }
}

impl fmt::Debug for KitFailure {
    // `Result::unwrap` prints the Debug form: make it the readable one.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

impl std::error::Error for KitFailure {}

/// The `*.replay` files and `*.bundle` desync bundles of `dir`, in name
/// order. A bundle passes when re-simulating it gives the majority's
/// values in every field the room reported (the desync still reproduces,
/// and the engine and rules still simulate like the majority did).
///
/// # Errors
/// The folder cannot be read.
pub fn replay_files(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir)? {
        let path = entry?.path();
        if path.is_file()
            && path
                .extension()
                .is_some_and(|e| e == "replay" || e == "bundle")
        {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

/// Checks every `*.replay` file in `dir` with fresh rules from `game`.
///
/// # Errors
/// [`KitFailure`]: the folder is unreadable or empty, or replays failed
/// (each named with its first differing tick and bodies), or a replay is
/// cut (it ends without the match's end record).
pub fn check_replays(
    dir: impl AsRef<Path>,
    game: &dyn RulesFactory,
) -> Result<KitReport, KitFailure> {
    let dir = dir.as_ref();
    let files = replay_files(dir).map_err(|e| KitFailure::Folder(dir.to_path_buf(), e))?;
    if files.is_empty() {
        return Err(KitFailure::Empty(dir.to_path_buf()));
    }
    let mut passed = Vec::new();
    let mut failed = Vec::new();
    let mut cut = Vec::new();
    for path in files {
        match verify_replay_file(&path, game) {
            Ok(c) if c.is_cut() => cut.push((path, c)),
            Ok(c) => passed.push((path, c)),
            Err(e) => failed.push((path, e)),
        }
    }
    if failed.is_empty() && cut.is_empty() {
        Ok(KitReport { replays: passed })
    } else {
        Err(KitFailure::Replays {
            failed,
            cut,
            passed,
        })
    }
}

/// [`check_replays`] for a test: panics with the failure's text (replay,
/// tick, bodies), returns the report otherwise.
///
/// # Panics
/// If [`check_replays`] fails.
#[track_caller]
pub fn assert_replays(dir: impl AsRef<Path>, game: &dyn RulesFactory) -> KitReport {
    match check_replays(dir, game) {
        Ok(r) => r,
        Err(e) => panic!("{e}"),
    }
}

/// The sync test for a test: plays `scene` (TOML, `label` in errors) with
/// `game`'s rules and four scripted bots for 600 ticks beside a twin, and
/// every tick re-simulates the last two from the saved state with fresh
/// rules (see [`lockstep_tools::sync_test`]); panics naming the
/// first tick and the fields that differ. It catches rules that are not
/// deterministic (a `HashMap`'s iteration order, a clock, a float that
/// depends on the machine is not among them: run the replays on each
/// machine for that) or that keep state outside the world, on one machine
/// and before any network.
///
/// ```no_run
/// use lockstep_client::game::{Demo, DemoGame};
///
/// #[test]
/// fn the_rules_are_deterministic() {
///     lockstep_testkit::assert_sync(DemoGame::SCENE, "scenes/demo.toml", &Demo);
/// }
/// ```
///
/// # Panics
/// If the sync test fails.
#[track_caller]
pub fn assert_sync(scene: &str, label: &str, game: &dyn RulesFactory) -> SyncTestReport {
    match sync_test(scene, label, game, &SyncTestOptions::default()) {
        Ok(r) => r,
        Err(e) => panic!("sync test of {}: {e}", game.rules_id()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lockstep_client::game::Demo;

    fn dir(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("lockstep-testkit-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_folder_without_replays_fails_instead_of_passing_vacuously() {
        let d = dir("empty");
        std::fs::write(d.join("notes.txt"), "not a replay").unwrap();
        let e = check_replays(&d, &Demo).unwrap_err();
        assert!(matches!(e, KitFailure::Empty(_)));
        assert!(e.to_string().ends_with("no *.replay file to check"), "{e}");
        let missing = d.join("missing");
        assert!(matches!(
            check_replays(&missing, &Demo),
            Err(KitFailure::Folder(..))
        ));
    }

    #[test]
    fn each_failing_replay_is_named_with_its_reason() {
        let d = dir("bad");
        std::fs::write(d.join("b.replay"), "garbage").unwrap();
        std::fs::write(d.join("a.replay"), "LSREPLAY\x01\x00").unwrap();
        let e = check_replays(&d, &Demo).unwrap_err();
        let text = e.to_string();
        let KitFailure::Replays { failed, passed, .. } = e else {
            panic!("{text}");
        };
        assert!(passed.is_empty());
        let names: Vec<_> = failed
            .iter()
            .map(|(p, _)| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["a.replay", "b.replay"]);
        assert!(text.starts_with("2 of 2 replays failed:"), "{text}");
        assert!(text.contains("a.replay: replay format version 1"), "{text}");
        assert!(text.contains("b.replay: not a lockstep replay"), "{text}");
    }
}
