//! `lockstep replay`: re-simulate a recorded match and check every tick's
//! hash against the one the players agreed on.
//!
//! The replay holds the scene, every tick's bundle and the agreed hashes
//! (see `lockstep_proto::replay`). Re-simulating is exactly what every
//! client did: build the world from the scene (its initial hash must be the
//! recorded scene hash), then for each tick apply the bundle's inputs through
//! the game rules, step, and hash.
//!
//! Before that, the header must say the replay was made with the same rules
//! (id and version) and the same state-hash layout as this check: otherwise
//! no hash could match, and the check says which of the two differs instead
//! of reporting a mismatch.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use lockstep_core::World;
use lockstep_core::world::STATE_HASH_VERSION;
use lockstep_proto::{Replay, ReplayError, RulesId};
use thiserror::Error;

pub use lockstep_client::game::apply_bundle;
use lockstep_client::game::{GameRules, RulesFactory, TickError, start_match};

/// A body whose hash differs from the one recorded in the replay.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BodyDiff {
    /// Its position in handle order (the index in `World::body_hashes`).
    pub index: usize,
    /// Its name in the scene (empty for bodies spawned by the rules, or if
    /// the lists differ in length past the world's bodies).
    pub name: String,
    /// The recorded hash (`None`: the replay lists fewer bodies).
    pub expected: Option<u64>,
    /// The re-simulated hash (`None`: the world has fewer bodies).
    pub got: Option<u64>,
}

impl std::fmt::Display for BodyDiff {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let h = |x: Option<u64>| x.map_or_else(|| "absent".to_owned(), |h| format!("{h:016x}"));
        let name = if self.name.is_empty() {
            String::new()
        } else {
            format!(" {:?}", self.name)
        };
        write!(
            f,
            "body #{}{name}: expected {}, got {}",
            self.index,
            h(self.expected),
            h(self.got)
        )
    }
}

/// The bodies that differ at the first tick from a mismatch on whose body
/// hashes the replay recorded.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BodiesAt {
    /// The tick compared (the mismatch's tick, or the next with recorded
    /// body hashes).
    pub tick: u64,
    /// The bodies that differ there, in handle order.
    pub bodies: Vec<BodyDiff>,
}

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

impl ReplayCheck {
    /// Whether the file is cut: no end record, or its last record cut
    /// short. What it holds was checked, but the match went on past
    /// [`ReplayCheck::ticks`].
    pub fn is_cut(&self) -> bool {
        self.truncated || self.end.is_none()
    }

    /// For a cut file (it stops at tick [`ReplayCheck::ticks`]), how it is
    /// cut: `the file has no end record[ and its last record is
    /// incomplete]`; `None` for a whole one. The CLI and the regression kit
    /// both say it this way.
    pub fn cut_description(&self) -> Option<String> {
        self.is_cut().then(|| {
            format!(
                "the file has no end record{}",
                if self.truncated {
                    " and its last record is incomplete"
                } else {
                    ""
                },
            )
        })
    }
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
    /// The replay was recorded with other rules than the ones checking it.
    #[error(
        "the replay was recorded with rules {recorded}, this check uses {ours}: check it with that game's own program (`<game> replay FILE`, a `lockstep::App` of its rules) or with `lockstep_testkit::assert_replays` in its tests (docs/own-game.md)"
    )]
    WrongRules {
        /// The replay's.
        recorded: RulesId,
        /// The checker's.
        ours: RulesId,
    },
    /// The replay's hashes use another state-hash layout than this engine.
    #[error(
        "the replay's hashes use state-hash layout {recorded} (engine {engine}), this engine hashes with layout {ours}"
    )]
    WrongHashLayout {
        /// The replay's.
        recorded: u64,
        /// The engine version that recorded it.
        engine: String,
        /// This engine's (`STATE_HASH_VERSION`).
        ours: u64,
    },
    /// The file has no located desync to reproduce.
    #[error("not a desync bundle: no located desync in it")]
    NotABundle,
    /// The bundle's snapshot does not restore, or does not match the
    /// re-simulation at its tick.
    #[error("the snapshot of tick {tick}: {detail}")]
    BadSnapshot {
        /// Its tick.
        tick: u64,
        /// What was wrong.
        detail: String,
    },
    /// Re-simulating the bundle does not give the majority's values in the
    /// reported fields.
    #[error(
        "the desync of tick {tick} does not reproduce: this machine's values differ from the majority's"
    )]
    NotReproduced {
        /// The desync's tick.
        tick: u64,
        /// The report with this machine's values as the expected ones.
        offline: Box<lockstep_proto::DesyncReport>,
    },
    /// The first tick whose re-simulated hash differs from the agreed one.
    #[error("mismatch at tick {tick}: expected {expected:016x}, got {got:016x}")]
    Mismatch {
        /// The tick.
        tick: u64,
        /// The agreed hash in the replay.
        expected: u64,
        /// The re-simulated hash.
        got: u64,
        /// The bodies that differ, if the replay holds body hashes at or
        /// after that tick.
        bodies: Option<BodiesAt>,
    },
}

/// The status `lockstep replay` exits with for each outcome, so scripts can
/// tell them apart.
pub mod exit_status {
    /// The replay verifies.
    pub const OK: u8 = 0;
    /// A tick's hash differs from the recorded one.
    pub const MISMATCH: u8 = 1;
    /// The file is not a readable replay (or its scene does not build).
    pub const INVALID: u8 = 2;
    /// The replay was recorded with other rules (id or version).
    pub const WRONG_RULES: u8 = 3;
    /// The replay's hashes use another state-hash layout.
    pub const WRONG_HASH_LAYOUT: u8 = 4;
    /// Every hash the file holds matches, but the file is cut: it has no
    /// end record (the server stopped while recording), so the match went
    /// on past what it shows.
    pub const CUT: u8 = 5;
}

impl ReplayVerifyError {
    /// The `lockstep replay` exit status of this error (see
    /// [`exit_status`]).
    pub fn exit_status(&self) -> u8 {
        match self {
            Self::Mismatch { .. } | Self::NotReproduced { .. } | Self::BadSnapshot { .. } => {
                exit_status::MISMATCH
            }
            Self::WrongRules { .. } => exit_status::WRONG_RULES,
            Self::WrongHashLayout { .. } => exit_status::WRONG_HASH_LAYOUT,
            _ => exit_status::INVALID,
        }
    }
}

/// A failed tick as a replay error.
pub(crate) fn tick_failed(e: TickError) -> ReplayVerifyError {
    ReplayVerifyError::Game(e.to_string())
}

/// The world every player started the recorded match from: built from the
/// recorded scene (checked against the recorded scene hash), with the
/// match's seed ([`start_match`]).
///
/// # Errors
/// [`ReplayVerifyError::Scene`] or [`ReplayVerifyError::SceneHash`].
pub fn match_world(replay: &Replay, label: &str) -> Result<World, ReplayVerifyError> {
    let mut world = recorded_world(replay, label)?;
    let got = world.state_hash();
    if got != replay.header.scene_hash {
        return Err(ReplayVerifyError::SceneHash {
            expected: replay.header.scene_hash,
            got,
        });
    }
    start_match(&mut world, replay.seed).map_err(|e| ReplayVerifyError::Game(e.to_string()))?;
    Ok(world)
}

/// Builds the world from the scene a replay (or bundle) recorded;
/// `label` names it in error messages.
///
/// # Errors
/// [`ReplayVerifyError::Scene`] if the scene is not UTF-8 or does not build.
pub fn recorded_world(replay: &Replay, label: &str) -> Result<World, ReplayVerifyError> {
    let text = std::str::from_utf8(&replay.header.scene)
        .map_err(|e| ReplayVerifyError::Scene(format!("not UTF-8: {e}")))?;
    lockstep_core::scene::load_world(text, label)
        .map_err(|e| ReplayVerifyError::Scene(e.to_string()))
}

/// Checks that a replay's header matches `game` and this engine's hash
/// layout.
///
/// # Errors
/// [`ReplayVerifyError::WrongHashLayout`] or
/// [`ReplayVerifyError::WrongRules`].
pub fn check_header(replay: &Replay, game: &dyn RulesFactory) -> Result<(), ReplayVerifyError> {
    let h = &replay.header;
    if h.hash_layout != STATE_HASH_VERSION {
        return Err(ReplayVerifyError::WrongHashLayout {
            recorded: h.hash_layout,
            engine: h.engine_version.clone(),
            ours: STATE_HASH_VERSION,
        });
    }
    let ours = game.rules_id();
    if h.rules != ours {
        return Err(ReplayVerifyError::WrongRules {
            recorded: h.rules.clone(),
            ours,
        });
    }
    Ok(())
}

/// Re-simulates a parsed replay with `game`'s rules and checks every
/// recorded hash.
///
/// # Errors
/// [`ReplayVerifyError`]; [`ReplayVerifyError::Mismatch`] names the first
/// tick that differs and, where the replay holds body hashes, the bodies.
pub fn verify_replay(
    replay: &Replay,
    game: &dyn RulesFactory,
) -> Result<ReplayCheck, ReplayVerifyError> {
    check_header(replay, game)?;
    let mut world = match_world(replay, "replay scene")?;
    let mut rules = game
        .rules_for(&world)
        .map_err(|e| ReplayVerifyError::Game(e.to_string()))?;
    let mut checked = 0;
    for (i, (bundle, expected)) in replay.ticks.iter().zip(&replay.hashes).enumerate() {
        apply_bundle(&mut world, &mut *rules, bundle).map_err(tick_failed)?;
        if let Some(expected) = *expected {
            let got = world.state_hash();
            if got != expected {
                let bodies = diverging_bodies(replay, i, &mut world, &mut *rules);
                return Err(ReplayVerifyError::Mismatch {
                    tick: bundle.tick,
                    expected,
                    got,
                    bodies,
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

/// After a mismatch at tick index `at` (already applied to `world`): goes on
/// re-simulating to the first tick from there with recorded body hashes and
/// compares them, body by body.
fn diverging_bodies(
    replay: &Replay,
    at: usize,
    world: &mut World,
    rules: &mut dyn GameRules,
) -> Option<BodiesAt> {
    let tick = at as u64;
    let (target, recorded) = replay.body_hashes.iter().find(|(t, _)| *t >= tick)?;
    for bundle in replay.ticks.get(at + 1..=usize::try_from(*target).ok()?)? {
        apply_bundle(world, rules, bundle).ok()?;
    }
    let ours = world.body_hashes();
    let n = ours.len().max(recorded.len());
    let bodies = (0..n)
        .filter_map(|i| {
            let got = ours.get(i).map(|(_, h)| *h);
            let expected = recorded.get(i).copied();
            (got != expected).then(|| BodyDiff {
                index: i,
                name: ours
                    .get(i)
                    .and_then(|(h, _)| world.body(*h).ok())
                    .map(|b| b.name().to_owned())
                    .unwrap_or_default(),
                expected,
                got,
            })
        })
        .collect();
    Some(BodiesAt {
        tick: *target,
        bodies,
    })
}

/// Reads, parses and verifies a replay file.
///
/// # Errors
/// See [`verify_replay`]; also [`ReplayVerifyError::Io`] and
/// [`ReplayVerifyError::Parse`].
pub fn verify_replay_file(
    path: &Path,
    game: &dyn RulesFactory,
) -> Result<ReplayCheck, ReplayVerifyError> {
    let bytes = std::fs::read(path).map_err(|source| ReplayVerifyError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let replay = Replay::parse(&bytes)?;
    if super::bundle::is_bundle(&replay) {
        let c = super::bundle::reproduce_bundle(&replay, game)?;
        if !c.reproduces() {
            return Err(ReplayVerifyError::NotReproduced {
                tick: c.recorded.tick,
                offline: Box::new(c.offline),
            });
        }
        return Ok(ReplayCheck {
            ticks: c.recorded.tick + 1,
            checked: c.hashes_checked,
            unchecked: c.recorded.tick + 1 - c.hashes_checked,
            players: replay.players.len(),
            desyncs_recorded: replay.desyncs.len(),
            final_hash: 0,
            truncated: false,
            end: Some(format!("desync bundle of tick {}", c.recorded.tick)),
        });
    }
    verify_replay(&replay, game)
}

/// What `lockstep replay FILE` does, for any game: verifies the file with
/// `game`, prints one `OK` line (stdout), or the first mismatch and the
/// bodies that differ (stdout), or the error (stderr), and returns the exit
/// status ([`exit_status`]). A game's own replay tool is a `main` around it.
pub fn check_replay_command(path: &Path, game: &dyn RulesFactory) -> u8 {
    if let Some(status) = check_bundle_command(path, game) {
        return status;
    }
    match verify_replay_file(path, game) {
        Ok(c) => {
            let figures = format!(
                "{} ticks re-simulated, {} hashes checked ({} without an agreed hash), \
                 {} players, {} desync notices recorded, final hash {:016x}",
                c.ticks, c.checked, c.unchecked, c.players, c.desyncs_recorded, c.final_hash,
            );
            if let Some(cut) = c.cut_description() {
                println!(
                    "CUT at tick {}: {cut} (the server stopped while recording); what it holds \
                     matches: {figures}",
                    c.ticks,
                );
                exit_status::CUT
            } else {
                println!("OK: {figures}");
                exit_status::OK
            }
        }
        Err(ReplayVerifyError::Mismatch {
            tick,
            expected,
            got,
            bodies,
        }) => {
            println!("MISMATCH at tick {tick}: expected {expected:016x}, got {got:016x}");
            if let Some(at) = &bodies {
                for b in &at.bodies {
                    println!("  at tick {}: {b}", at.tick);
                }
            }
            exit_status::MISMATCH
        }
        Err(e) => {
            let _ = writeln!(std::io::stderr(), "lockstep replay: error: {e}");
            e.exit_status()
        }
    }
}

/// `lockstep replay BUNDLE`: re-simulates a desync bundle and prints the
/// body/field diff between this machine and the diverging players. `None`
/// when the file is not a bundle (a plain replay).
fn check_bundle_command(path: &Path, game: &dyn RulesFactory) -> Option<u8> {
    let replay = Replay::parse(&std::fs::read(path).ok()?).ok()?;
    if !super::bundle::is_bundle(&replay) {
        return None;
    }
    Some(match super::bundle::reproduce_bundle(&replay, game) {
        Ok(c) => {
            let snapshot = c.snapshot_tick.map_or_else(
                || "no snapshot in the bundle".to_owned(),
                |t| format!("the snapshot of tick {t} matches"),
            );
            let like = c.simulates_like();
            let verdict = match like {
                _ if c.reproduces() => "REPRODUCED".to_owned(),
                Some(slot) => format!(
                    "NOT REPRODUCED: this build simulates as slot {} did, not as the majority \
                     (its values equal slot {}'s in every reported field): this build is the \
                     odd one out, or slot {} ran this build",
                    slot.0, slot.0, slot.0
                ),
                None => "NOT REPRODUCED (this machine differs from the majority too)".to_owned(),
            };
            println!(
                "BUNDLE {verdict}: {} agreed hashes checked up to tick {}, {snapshot}; \
                 this machine's values are the expected ones below",
                c.hashes_checked, c.recorded.tick
            );
            if let Some(slot) = like {
                // Every field of that slot would read "expected = got".
                let mut shown = c.offline.clone();
                shown.suspects.retain(|s| s.slot != slot);
                println!(
                    "  (slot {}'s {} fields, equal to this machine's, not listed)",
                    slot.0,
                    c.offline
                        .suspects
                        .iter()
                        .filter(|s| s.slot == slot)
                        .map(|s| s.game.len()
                            + s.bodies.iter().map(|b| b.fields.len()).sum::<usize>())
                        .sum::<usize>()
                );
                print!("{shown}");
            } else {
                print!("{}", c.offline);
            }
            if c.reproduces() {
                exit_status::OK
            } else {
                exit_status::MISMATCH
            }
        }
        Err(e) => {
            let _ = writeln!(std::io::stderr(), "lockstep replay: error: {e}");
            e.exit_status()
        }
    })
}
