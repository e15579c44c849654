//! The sync test: a game's determinism checked on one machine, before any
//! network (as GGRS's `SyncTestSession` does).
//!
//! The scene is played with the game's rules and scripted bot inputs, and
//! every tick two checks run:
//!
//! - **a twin**: a second world and a second instance of the rules, built
//!   the same way and fed the same inputs, must hash the same after every
//!   tick. Rules that read anything but their arguments (a clock, a
//!   thread-local random source, the iteration order of a `HashMap`, which
//!   is seeded per map) differ between the two instances;
//! - **a rollback**: the state saved `rollback` ticks ago is restored into
//!   a fresh world with fresh rules ([`RulesFactory::rules_for`]) and
//!   re-simulated to the present, and every re-simulated tick must hash as
//!   it did the first time. Rules whose state is not all in the world's
//!   game state (saved and loaded) fail here: it is the state a late
//!   joiner, a rejoin and a desync bundle start from.
//!
//! The first difference is reported with its tick and what differs: the
//! game-state fields, or the first bodies and their fields, as a desync
//! report names them.

use std::collections::VecDeque;

use lockstep_core::World;
use lockstep_proto::forensics::{field_diffs, list_diffs};
use thiserror::Error;

use lockstep_client::game::{GameRules, RulesFactory, apply_tick, start_match};
use lockstep_client::net::{dump_bodies, dump_game};

/// What the sync test runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SyncTestOptions {
    /// Ticks to play.
    pub ticks: u64,
    /// How far back each tick's rollback restores (at least 1).
    pub rollback: u64,
    /// Players (slots `0..players`), each with the game's scripted bot
    /// input.
    pub players: u8,
    /// Seed of the bot inputs.
    pub seed: u64,
}

impl Default for SyncTestOptions {
    /// 600 ticks, rolling back 2, 4 players, seed 1.
    fn default() -> Self {
        Self {
            ticks: 600,
            rollback: 2,
            players: 4,
            seed: 1,
        }
    }
}

/// A passed sync test.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SyncTestReport {
    /// Ticks played.
    pub ticks: u64,
    /// Ticks re-simulated from a restored state.
    pub resimulated: u64,
    /// The state hash after the last tick.
    pub final_hash: u64,
}

/// Which check found the difference.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SyncCheck {
    /// A second instance of the rules, fed the same inputs from the start.
    Twin,
    /// Fresh rules on the state restored from `from`.
    Rollback {
        /// The tick whose saved state was restored.
        from: u64,
    },
}

/// Why the sync test failed.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum SyncTestError {
    /// The scene does not build or the rules refuse it.
    #[error("{0}")]
    Setup(String),
    /// A tick could not be applied.
    #[error("{0}")]
    Tick(String),
    /// The state differs.
    #[error(
        "not deterministic: tick {tick} hashes {got:016x} on the {}, {expected:016x} first\n{}",
        check_name(*check),
        differences.join("\n")
    )]
    Diverged {
        /// The first tick whose hash differs.
        tick: u64,
        /// Which check saw it.
        check: SyncCheck,
        /// The first run's hash.
        expected: u64,
        /// The check's hash.
        got: u64,
        /// What differs, one line per field (game-state fields first,
        /// then the first bodies).
        differences: Vec<String>,
    },
}

fn check_name(c: SyncCheck) -> String {
    match c {
        SyncCheck::Twin => "twin (a second instance of the rules)".into(),
        SyncCheck::Rollback { from } => {
            format!("re-simulation from the state saved at tick {from}")
        }
    }
}

impl SyncTestError {
    /// The first tick that differs, for a divergence.
    pub fn tick(&self) -> Option<u64> {
        match self {
            Self::Diverged { tick, .. } => Some(*tick),
            _ => None,
        }
    }
}

/// Most bodies whose fields a divergence lists.
const MAX_BODIES_LISTED: usize = 4;

/// Runs the sync test on `scene` (TOML; `label` names it in errors) with
/// `game`'s rules (see the module docs).
///
/// # Errors
/// [`SyncTestError::Diverged`] with the first tick and what differs; the
/// others when the scene, the rules or a tick fail.
pub fn sync_test(
    scene: &str,
    label: &str,
    game: &dyn RulesFactory,
    options: &SyncTestOptions,
) -> Result<SyncTestReport, SyncTestError> {
    let build = || -> Result<(World, Box<dyn GameRules>), SyncTestError> {
        let mut world = lockstep_core::scene::load_world(scene, label)
            .map_err(|e| SyncTestError::Setup(e.to_string()))?;
        start_match(&mut world, options.seed).map_err(|e| SyncTestError::Setup(e.to_string()))?;
        let rules = game
            .rules_for(&world)
            .map_err(|e| SyncTestError::Setup(e.to_string()))?;
        Ok((world, rules))
    };
    let (mut world, mut rules) = build()?;
    let (mut twin, mut twin_rules) = build()?;
    let rollback = options.rollback.max(1);
    // Every tick's inputs and hash, and the saved states of the last
    // `rollback + 1` ticks (the state after tick t, for the rollbacks).
    let mut inputs: Vec<Vec<(u8, Vec<u8>)>> = Vec::new();
    let mut hashes: Vec<u64> = Vec::new();
    let mut saved: VecDeque<(u64, Vec<u8>)> = VecDeque::new();
    let mut resimulated = 0;
    for tick in 0..options.ticks {
        let these: Vec<(u8, Vec<u8>)> = (0..options.players)
            .map(|slot| (slot, game.bot_input(options.seed, slot, tick)))
            .collect();
        step(&mut world, &mut *rules, tick, &these)?;
        step(&mut twin, &mut *twin_rules, tick, &these)?;
        let hash = world.state_hash();
        inputs.push(these);
        hashes.push(hash);
        if twin.state_hash() != hash {
            return Err(diverged(tick, SyncCheck::Twin, &world, &twin));
        }
        if let Some((from, bytes)) = saved.front().filter(|(t, _)| tick - t >= rollback) {
            let from = *from;
            let mut again =
                World::restore(bytes).map_err(|e| SyncTestError::Setup(e.to_string()))?;
            let mut fresh = game
                .rules_for(&again)
                .map_err(|e| SyncTestError::Setup(e.to_string()))?;
            for t in from + 1..=tick {
                step(&mut again, &mut *fresh, t, &inputs[t as usize])?;
                resimulated += 1;
                if again.state_hash() != hashes[t as usize] {
                    // The first run's state at `t` is gone unless t is now.
                    let reference = if t == tick {
                        world.clone()
                    } else {
                        saved_world(&saved, t)?
                    };
                    return Err(diverged(
                        t,
                        SyncCheck::Rollback { from },
                        &reference,
                        &again,
                    ));
                }
            }
            saved.pop_front();
        }
        saved.push_back((tick, world.snapshot()));
    }
    Ok(SyncTestReport {
        ticks: options.ticks,
        resimulated,
        final_hash: world.state_hash(),
    })
}

/// The first run's world after tick `t`, from its saved state (`saved`
/// holds `t`: the rollback started at an earlier saved tick).
fn saved_world(saved: &VecDeque<(u64, Vec<u8>)>, t: u64) -> Result<World, SyncTestError> {
    let bytes = saved
        .iter()
        .find(|(s, _)| *s == t)
        .map(|(_, b)| b)
        .ok_or_else(|| SyncTestError::Setup(format!("no saved state of tick {t}")))?;
    World::restore(bytes).map_err(|e| SyncTestError::Setup(e.to_string()))
}

fn step(
    world: &mut World,
    rules: &mut dyn GameRules,
    tick: u64,
    inputs: &[(u8, Vec<u8>)],
) -> Result<(), SyncTestError> {
    let refs: Vec<(u8, &[u8])> = inputs.iter().map(|(s, b)| (*s, b.as_slice())).collect();
    let report =
        apply_tick(world, rules, tick, &refs).map_err(|e| SyncTestError::Tick(e.to_string()))?;
    if !report.faults.is_empty() {
        return Err(SyncTestError::Tick(format!(
            "tick {tick}: the step reported {}",
            report.faults
        )));
    }
    Ok(())
}

/// What differs between `expected` and `got`, one line per field: the
/// game state's fields, then the first bodies' (as a desync report
/// dumps and diffs them).
fn diverged(tick: u64, check: SyncCheck, expected: &World, got: &World) -> SyncTestError {
    let mut lines: Vec<String> = list_diffs(&dump_game(expected), &dump_game(got))
        .iter()
        // The name quoted: a game names its fields freely.
        .map(|d| {
            format!(
                "  game state {:?}{}",
                d.name,
                &d.to_string()[d.name.len()..]
            )
        })
        .collect();
    let (ha, hb) = (expected.body_hashes(), got.body_hashes());
    let differing = (0..ha.len().max(hb.len()))
        .filter(|&i| ha.get(i).map(|e| e.1) != hb.get(i).map(|e| e.1))
        .map(|i| i as u32);
    for (n, i) in differing.enumerate() {
        if n == MAX_BODIES_LISTED {
            lines.push("  (more bodies differ)".into());
            break;
        }
        match (
            dump_bodies(expected, &[i]).pop(),
            dump_bodies(got, &[i]).pop(),
        ) {
            (Some(a), Some(b)) => lines.extend(
                field_diffs(&a, &b)
                    .iter()
                    .map(|d| format!("  body #{i} {:?} {d}", a.name)),
            ),
            (Some(a), None) => lines.push(format!("  body #{i} {:?}: missing", a.name)),
            (None, Some(b)) => lines.push(format!("  body #{i} {:?}: unexpected", b.name)),
            (None, None) => {}
        }
    }
    if lines.is_empty() && expected.contacts_hash() != got.contacts_hash() {
        lines.push("  the contact state differs".into());
    }
    SyncTestError::Diverged {
        tick,
        check,
        expected: expected.state_hash(),
        got: got.state_hash(),
        differences: lines,
    }
}

#[cfg(test)]
mod tests {
    use std::collections::HashMap;

    use lockstep_core::{BodyHandle, Scalar, Vec3};

    use super::*;
    use lockstep_client::game::{Demo, GameError, GameState, GameStateError, RulesId};

    const SCENE: &str = "[[bodies]]\nname = \"ball\"\nkind = \"dynamic\"\nposition = [0, 5, 0]\n\
                         [[bodies.shapes]]\nkind = \"sphere\"\nradius = 0.5\n";

    /// Rules with a flaw chosen by `flaw`.
    #[derive(Clone, Copy, PartialEq, Eq)]
    enum Flaw {
        None,
        /// The order of a `HashMap`'s iteration decides the game state.
        HashMapOrder,
        /// A counter kept in the rules, not saved, decides a push.
        UnsavedCounter,
    }

    struct Flawed(Flaw);

    struct FlawedRules {
        flaw: Flaw,
        ball: BodyHandle,
        counter: u64,
    }

    impl RulesFactory for Flawed {
        fn rules_id(&self) -> RulesId {
            RulesId::new("flawed", 1)
        }
        fn new_rules(&self, world: &World) -> Result<Box<dyn GameRules>, GameError> {
            Ok(Box::new(FlawedRules {
                flaw: self.0,
                ball: world
                    .find_body("ball")
                    .ok_or_else(|| GameError::MissingBody("ball".into()))?,
                counter: 0,
            }))
        }
        fn bot_input(&self, seed: u64, slot: u8, tick: u64) -> Vec<u8> {
            vec![(seed as u8) ^ slot ^ (tick as u8)]
        }
    }

    impl GameRules for FlawedRules {
        fn apply_inputs(&mut self, world: &mut World, _tick: u64, inputs: &[(u8, &[u8])]) {
            self.counter += 1;
            if self.flaw == Flaw::HashMapOrder {
                let map: HashMap<u8, u8> = inputs
                    .iter()
                    .map(|&(s, b)| (s, b.first().copied().unwrap_or(0)))
                    .collect();
                // The bug: the map's iteration order reaches the state.
                let order: Vec<u64> = map.keys().map(|&k| u64::from(k)).collect();
                let _ = world.game_state_mut().set_words("order", &order);
            }
            let push = match self.flaw {
                Flaw::UnsavedCounter => self.counter.is_multiple_of(7),
                _ => false,
            };
            if push {
                let _ = world.apply_impulse(
                    self.ball,
                    Vec3::new(Scalar::ONE, Scalar::ZERO, Scalar::ZERO),
                );
            }
        }
        fn save_state(&self, state: &mut GameState) -> Result<(), GameStateError> {
            match self.flaw {
                Flaw::UnsavedCounter => Ok(()),
                _ => state.set_word("counter", self.counter),
            }
        }
        fn load_state(&mut self, state: &GameState) -> Result<(), GameError> {
            if self.flaw != Flaw::UnsavedCounter {
                self.counter = state.word("counter").unwrap_or(0);
            }
            Ok(())
        }
    }

    fn options(ticks: u64) -> SyncTestOptions {
        SyncTestOptions {
            ticks,
            players: 8,
            ..SyncTestOptions::default()
        }
    }

    #[test]
    fn sound_rules_pass_and_every_tick_is_resimulated() {
        let r = sync_test(SCENE, "ball.toml", &Flawed(Flaw::None), &options(40)).unwrap();
        assert_eq!(r.ticks, 40);
        // Ticks 2..40 each re-simulate the last two.
        assert_eq!(r.resimulated, 38 * 2);
    }

    #[test]
    fn a_hash_map_iteration_is_caught_at_once_with_the_field_named() {
        let err = sync_test(
            SCENE,
            "ball.toml",
            &Flawed(Flaw::HashMapOrder),
            &options(40),
        )
        .unwrap_err();
        let SyncTestError::Diverged {
            check, differences, ..
        } = &err
        else {
            panic!("{err}");
        };
        assert_eq!(*check, SyncCheck::Twin);
        assert!(err.tick().is_some_and(|t| t < 5), "{err}");
        assert!(
            differences
                .iter()
                .any(|d| d.contains("game state \"order\"")),
            "{err}"
        );
    }

    #[test]
    fn state_kept_outside_the_world_is_caught_by_the_rollback() {
        let err = sync_test(
            SCENE,
            "ball.toml",
            &Flawed(Flaw::UnsavedCounter),
            &options(40),
        )
        .unwrap_err();
        let SyncTestError::Diverged {
            check, differences, ..
        } = &err
        else {
            panic!("{err}");
        };
        // The first push is at the 7th tick (tick 6); the re-simulation
        // from tick 4's state counts from zero and pushes at tick 11, so
        // the first run's push at tick 6 is missing there.
        assert_eq!(*check, SyncCheck::Rollback { from: 4 }, "{err}");
        assert_eq!(err.tick(), Some(6), "{err}");
        assert!(
            differences
                .iter()
                .any(|d| d.contains("\"ball\" linear_velocity")),
            "{err}"
        );
    }

    #[test]
    fn the_demo_passes() {
        let r = sync_test(
            lockstep_client::game::DemoGame::SCENE,
            lockstep_client::game::DemoGame::SCENE_FILE,
            &Demo,
            &SyncTestOptions {
                ticks: 90,
                ..SyncTestOptions::default()
            },
        )
        .unwrap();
        assert_eq!(r.resimulated, 88 * 2);
    }
}
