//! `lockstep replay`: re-simulate a recorded match and check every tick's
//! hash against the one the players agreed on.
//!
//! The replay holds the scene, every tick's bundle and the agreed hashes
//! (see `lockstep_proto::replay`). Re-simulating is exactly what every
//! client did: build the world from the scene (its initial hash must be the
//! recorded scene hash), then for each tick apply the bundle's inputs through
//! the game rules, step, and hash.

use std::path::{Path, PathBuf};

use lockstep_core::World;
use lockstep_proto::{Replay, ReplayError, TickBundle};
use thiserror::Error;

use crate::game::{DemoGame, GameRules};

/// What a successful verification found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReplayCheck {
    /// Ticks re-simulated.
    pub ticks: u64,
    /// Ticks whose hash was recorded and matched.
    pub checked: u64,
    /// Ticks without an agreed hash (no strict majority, or never
    /// reported): re-simulated but not checked.
    pub unchecked: u64,
    /// Players who took part.
    pub players: usize,
    /// Desync notices the server recorded (the replay still verifies: the
    /// agreed hash is the majority's).
    pub desyncs_recorded: usize,
    /// State hash after the last tick.
    pub final_hash: u64,
    /// Whether the file ended inside a record (the server stopped while
    /// writing); everything before it was checked.
    pub truncated: bool,
    /// Why the match ended, if the replay says so.
    pub end: Option<String>,
}

/// Why a replay does not verify.
#[derive(Debug, Error)]
pub enum ReplayVerifyError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// The bytes are not a replay.
    #[error("{0}")]
    Parse(#[from] ReplayError),
    /// The recorded scene does not build.
    #[error("scene: {0}")]
    Scene(String),
    /// The recorded scene does not hash as the server announced.
    #[error("scene hash {got:016x}, the replay says {expected:016x}")]
    SceneHash {
        /// Recorded.
        expected: u64,
        /// Computed.
        got: u64,
    },
    /// The game rules refuse the world.
    #[error("game: {0}")]
    Game(String),
    /// The first tick whose re-simulated hash differs from the agreed one.
    #[error("mismatch at tick {tick}: expected {expected:016x}, got {got:016x}")]
    Mismatch {
        /// The tick.
        tick: u64,
        /// The agreed hash in the replay.
        expected: u64,
        /// The re-simulated hash.
        got: u64,
    },
}

/// Applies one bundle to the world: game rules, then a step. The same
/// sequence every client runs, so the result hashes the same.
pub fn apply_bundle(world: &mut World, game: &mut dyn GameRules, bundle: &TickBundle) {
    let inputs: Vec<(u8, &[u8])> = bundle
        .inputs
        .iter()
        .map(|p| (p.slot.0, p.input.as_slice()))
        .collect();
    game.apply_inputs(world, bundle.tick, &inputs);
    world.step();
}

/// Re-simulates a parsed replay and checks every recorded hash.
///
/// # Errors
/// [`ReplayVerifyError`]; [`ReplayVerifyError::Mismatch`] names the first
/// tick that differs.
pub fn verify_replay(replay: &Replay) -> Result<ReplayCheck, ReplayVerifyError> {
    let text = std::str::from_utf8(&replay.header.scene)
        .map_err(|e| ReplayVerifyError::Scene(format!("not UTF-8: {e}")))?;
    let mut world = lockstep_core::scene::load_world(text, "replay scene")
        .map_err(|e| ReplayVerifyError::Scene(e.to_string()))?;
    let got = world.state_hash();
    if got != replay.header.scene_hash {
        return Err(ReplayVerifyError::SceneHash {
            expected: replay.header.scene_hash,
            got,
        });
    }
    let mut game = DemoGame::new(&world).map_err(|e| ReplayVerifyError::Game(e.to_string()))?;
    let mut checked = 0;
    for (bundle, expected) in replay.ticks.iter().zip(&replay.hashes) {
        apply_bundle(&mut world, &mut game, bundle);
        if let Some(expected) = *expected {
            let got = world.state_hash();
            if got != expected {
                return Err(ReplayVerifyError::Mismatch {
                    tick: bundle.tick,
                    expected,
                    got,
                });
            }
            checked += 1;
        }
    }
    let ticks = replay.ticks.len() as u64;
    Ok(ReplayCheck {
        ticks,
        checked,
        unchecked: ticks - checked,
        players: replay.players.len(),
        desyncs_recorded: replay.desyncs.len(),
        final_hash: world.state_hash(),
        truncated: replay.truncated,
        end: replay.end.as_ref().map(|(_, r)| r.clone()),
    })
}

/// Reads, parses and verifies a replay file.
///
/// # Errors
/// See [`verify_replay`]; also [`ReplayVerifyError::Io`] and
/// [`ReplayVerifyError::Parse`].
pub fn verify_replay_file(path: &Path) -> Result<ReplayCheck, ReplayVerifyError> {
    let bytes = std::fs::read(path).map_err(|source| ReplayVerifyError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    verify_replay(&Replay::parse(&bytes)?)
}
