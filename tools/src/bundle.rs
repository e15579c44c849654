//! Desync bundles offline: re-simulate the match the bundle holds up to the
//! desync, check the majority's snapshot of the last agreed tick against
//! the re-simulation, and diff the bodies the room named, field by field,
//! between this machine's result and the diverging player's recorded
//! values. A machine that simulates like the majority prints the same diff
//! the room reported.

use lockstep_core::World;
use lockstep_proto::{BodyDiff, DesyncReport, FieldDiff, FieldDump, Replay, Slot, SuspectReport};

use super::replay::{ReplayVerifyError, apply_bundle, check_header, match_world};
use lockstep_client::game::RulesFactory;
use lockstep_client::net::{dump_bodies, dump_game};

/// What re-simulating a bundle found.
#[derive(Clone, Debug)]
pub struct BundleCheck {
    /// The report the room recorded.
    pub recorded: DesyncReport,
    /// The same report with this machine's values as the expected ones.
    pub offline: DesyncReport,
    /// The snapshot's tick, when the bundle holds one (it matched the
    /// re-simulation there, hash and restored state).
    pub snapshot_tick: Option<u64>,
    /// Agreed hashes checked on the way.
    pub hashes_checked: u64,
}

impl BundleCheck {
    /// Whether this machine's values equal the majority's recorded ones in
    /// every reported field: the desync reproduces, and the diverging
    /// player is the one that differs.
    pub fn reproduces(&self) -> bool {
        self.recorded == self.offline
    }

    /// When the desync does not reproduce: the diverging player this
    /// machine simulates like (its values equal that player's in every
    /// reported field, bodies and game state, and there is at least one).
    pub fn simulates_like(&self) -> Option<Slot> {
        if self.reproduces() {
            return None;
        }
        self.offline
            .suspects
            .iter()
            .find(|s| {
                let fields = s.bodies.iter().flat_map(|b| &b.fields).chain(&s.game);
                let mut any = false;
                fields.inspect(|_| any = true).all(|f| f.expected == f.got) && any
            })
            .map(|s| s.slot)
    }
}

/// Whether a parsed replay is a desync bundle: it holds a snapshot, or a
/// located desync and no end record.
pub fn is_bundle(replay: &Replay) -> bool {
    replay.snapshot.is_some() || (!replay.located.is_empty() && replay.end.is_none())
}

/// Re-simulates a bundle with `game`'s rules: checks every agreed hash up
/// to the desync, the snapshot, and then dumps the reported bodies.
///
/// # Errors
/// [`ReplayVerifyError`]: the header, scene or rules, a hash mismatch before
/// the desync, [`ReplayVerifyError::NotABundle`] or
/// [`ReplayVerifyError::BadSnapshot`].
pub fn reproduce_bundle(
    replay: &Replay,
    game: &dyn RulesFactory,
) -> Result<BundleCheck, ReplayVerifyError> {
    check_header(replay, game)?;
    let recorded = replay
        .located
        .last()
        .cloned()
        .ok_or(ReplayVerifyError::NotABundle)?;
    let mut world = match_world(replay, "bundle scene")?;
    let mut rules = game
        .rules_for(&world)
        .map_err(|e| ReplayVerifyError::Game(e.to_string()))?;
    let mut checked = 0;
    let end = usize::try_from(recorded.tick)
        .ok()
        .filter(|&t| t < replay.ticks.len())
        .ok_or(ReplayVerifyError::NotABundle)?;
    for (bundle, expected) in replay.ticks[..=end].iter().zip(&replay.hashes) {
        apply_bundle(&mut world, &mut *rules, bundle).map_err(super::replay::tick_failed)?;
        let got = world.state_hash();
        if bundle.tick < recorded.tick
            && let Some(expected) = *expected
        {
            if got != expected {
                return Err(ReplayVerifyError::Mismatch {
                    tick: bundle.tick,
                    expected,
                    got,
                    bodies: None,
                });
            }
            checked += 1;
        }
        if let Some((tick, hash, bytes)) = &replay.snapshot
            && *tick == bundle.tick
        {
            check_snapshot(&world, *tick, *hash, bytes)?;
        }
    }
    let offline = DesyncReport {
        suspects: recorded
            .suspects
            .iter()
            .map(|s| SuspectReport {
                bodies: s.bodies.iter().map(|b| offline_body(&world, b)).collect(),
                game: offline_fields(&dump_game(&world), &s.game),
                ..s.clone()
            })
            .collect(),
        ..recorded.clone()
    };
    Ok(BundleCheck {
        recorded,
        offline,
        snapshot_tick: replay.snapshot.as_ref().map(|s| s.0),
        hashes_checked: checked,
    })
}

fn check_snapshot(
    world: &World,
    tick: u64,
    hash: u64,
    bytes: &[u8],
) -> Result<(), ReplayVerifyError> {
    let ours = world.state_hash();
    let restored = World::restore(bytes)
        .map_err(|e| ReplayVerifyError::BadSnapshot {
            tick,
            detail: e.to_string(),
        })?
        .state_hash();
    if ours != hash || restored != hash {
        return Err(ReplayVerifyError::BadSnapshot {
            tick,
            detail: format!(
                "agreed hash {hash:016x}, the snapshot restores to {restored:016x}, the re-simulation hashes {ours:016x}"
            ),
        });
    }
    Ok(())
}

/// A reported body with this machine's words as the expected ones.
fn offline_body(world: &World, b: &BodyDiff) -> BodyDiff {
    let dump = dump_bodies(world, &[b.index]);
    let ours = dump.first().map_or(&[][..], |d| d.fields.as_slice());
    BodyDiff {
        fields: offline_fields(ours, &b.fields),
        ..b.clone()
    }
}

/// Reported field differences with this machine's words (`ours`) as the
/// expected ones.
fn offline_fields(ours: &[FieldDump], reported: &[FieldDiff]) -> Vec<FieldDiff> {
    reported
        .iter()
        .map(|f| FieldDiff {
            expected: ours
                .iter()
                .find(|x| x.name == f.name)
                .map(|x| x.words.clone())
                .unwrap_or_default(),
            ..f.clone()
        })
        .collect()
}
