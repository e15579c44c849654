//! One tick of a match, as every peer runs it: who came and went, the
//! rules' inputs, their state saved into the world, the step.

use lockstep_core::{GameStateError, StepReport, World};
use lockstep_proto::TickBundle;
use thiserror::Error;

use super::GameRules;

/// The game-state field in which [`apply_tick`] keeps the players present
/// at the last tick (bit `s` for slot `s`), so that joins and departures
/// reach the rules as events on every peer alike, a restored world's
/// included. Names starting with `match.` are the library's.
pub const PLAYERS_FIELD: &str = "match.players";

/// The game-state field holding the match's seed (announced in the
/// welcome, recorded in the replay): the rules' deterministic random
/// source, the same on every peer ([`match_seed`]).
pub const SEED_FIELD: &str = "match.seed";

/// Starts a match on a world just built from its scene: writes the match's
/// seed into its game state ([`SEED_FIELD`]). Every peer that builds the
/// world from the scene does this before the first tick (a world restored
/// from a snapshot already holds it).
///
/// # Errors
/// [`GameStateError`] only if the game state is already full.
pub fn start_match(world: &mut World, seed: u64) -> Result<(), GameStateError> {
    world.game_state_mut().set_word(SEED_FIELD, seed)
}

/// The match's seed ([`start_match`]); 0 for a world no match started on.
pub fn match_seed(world: &World) -> u64 {
    world.game_state().word(SEED_FIELD).unwrap_or(0)
}

/// Why a tick could not be applied whole. It fails alike on every peer
/// (the inputs and the state are the same), so it is a defect of the rules,
/// not a desync.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum TickError {
    /// The rules' [`save_state`](GameRules::save_state) failed.
    #[error("tick {tick}: saving the rules' state: {source}")]
    SaveState {
        /// The tick.
        tick: u64,
        /// What the game state refused.
        source: GameStateError,
    },
    /// An input names a slot past 63.
    #[error("tick {tick}: slot {slot} is past the 64 a match can have")]
    Slot {
        /// The tick.
        tick: u64,
        /// The slot.
        slot: u8,
    },
}

/// Applies one tick: the departures and joins since the last tick (the
/// players whose inputs `inputs` lists, against the ones the world's
/// [`PLAYERS_FIELD`] remembers) as [`GameRules::player_left`] and
/// [`GameRules::player_joined`], then [`GameRules::apply_inputs`], then the
/// rules' state saved into the world ([`GameRules::save_state`]), then the
/// step. Every peer (clients, bots, the server's verifier, the replay
/// check, the sync test) runs exactly this, so they hash alike.
///
/// `inputs` holds one entry per player present, ascending by slot.
///
/// # Errors
/// [`TickError`]; the world has then not stepped.
pub fn apply_tick(
    world: &mut World,
    rules: &mut dyn GameRules,
    tick: u64,
    inputs: &[(u8, &[u8])],
) -> Result<StepReport, TickError> {
    let before = world.game_state().word(PLAYERS_FIELD).unwrap_or(0);
    let mut now = 0u64;
    for &(slot, _) in inputs {
        if slot >= 64 {
            return Err(TickError::Slot { tick, slot });
        }
        now |= 1 << slot;
    }
    if now != before {
        for slot in 0..64u8 {
            if before & !now & (1 << slot) != 0 {
                rules.player_left(world, tick, slot);
            }
        }
        for slot in 0..64u8 {
            if now & !before & (1 << slot) != 0 {
                rules.player_joined(world, tick, slot);
            }
        }
        world
            .game_state_mut()
            .set_word(PLAYERS_FIELD, now)
            .map_err(|source| TickError::SaveState { tick, source })?;
    }
    rules.apply_inputs(world, tick, inputs);
    rules
        .save_state(world.game_state_mut())
        .map_err(|source| TickError::SaveState { tick, source })?;
    Ok(world.step())
}

/// Applies one bundle to the world with [`apply_tick`]: the sequence every
/// client runs, so the result hashes the same.
///
/// # Errors
/// [`TickError`] from the rules.
pub fn apply_bundle(
    world: &mut World,
    game: &mut dyn GameRules,
    bundle: &TickBundle,
) -> Result<StepReport, TickError> {
    let inputs: Vec<(u8, &[u8])> = bundle
        .inputs
        .iter()
        .map(|p| (p.slot.0, p.input.as_slice()))
        .collect();
    apply_tick(world, game, bundle.tick, &inputs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::game::{GameError, GameState};

    /// Counts joins and leaves per slot, and ticks, as its own state.
    #[derive(Default)]
    struct Tally {
        joins: [u64; 4],
        leaves: [u64; 4],
        ticks: u64,
        log: Vec<(u64, u8, bool)>,
    }

    impl GameRules for Tally {
        fn apply_inputs(&mut self, _: &mut World, _: u64, _: &[(u8, &[u8])]) {
            self.ticks += 1;
        }
        fn save_state(&self, state: &mut GameState) -> Result<(), GameStateError> {
            state.set_words("joins", &self.joins)?;
            state.set_words("leaves", &self.leaves)?;
            state.set_word("ticks", self.ticks)
        }
        fn load_state(&mut self, state: &GameState) -> Result<(), GameError> {
            let get = |name: &str| {
                state
                    .words(name)
                    .and_then(|w| <[u64; 4]>::try_from(w).ok())
                    .ok_or_else(|| GameError::BadState(format!("no {name}")))
            };
            self.joins = get("joins")?;
            self.leaves = get("leaves")?;
            self.ticks = state.word("ticks").unwrap_or(0);
            Ok(())
        }
        fn player_joined(&mut self, _: &mut World, tick: u64, slot: u8) {
            self.joins[usize::from(slot)] += 1;
            self.log.push((tick, slot, true));
        }
        fn player_left(&mut self, _: &mut World, tick: u64, slot: u8) {
            self.leaves[usize::from(slot)] += 1;
            self.log.push((tick, slot, false));
        }
    }

    fn world() -> World {
        lockstep_core::scene::load_world("", "empty.toml").unwrap()
    }

    #[test]
    fn joins_and_departures_reach_the_rules_and_survive_a_restore() {
        let mut w = world();
        let mut rules = Tally::default();
        let none: &[u8] = &[];
        let players = |slots: &[u8]| slots.iter().map(|&s| (s, none)).collect::<Vec<_>>();
        apply_tick(&mut w, &mut rules, 0, &players(&[0, 1])).unwrap();
        apply_tick(&mut w, &mut rules, 1, &players(&[0, 1])).unwrap();
        apply_tick(&mut w, &mut rules, 2, &players(&[1])).unwrap();
        // A restored world with fresh rules knows who is present and the
        // rules' counts: slot 0 coming back is a join, slot 1 staying none.
        let mut copy = World::restore(&w.snapshot()).unwrap();
        let mut fresh = Tally::default();
        fresh.load_state(copy.game_state()).unwrap();
        for (world, rules) in [(&mut w, &mut rules), (&mut copy, &mut fresh)] {
            apply_tick(world, rules, 3, &players(&[0, 1, 3])).unwrap();
        }
        assert_eq!(
            rules.log,
            [
                (0, 0, true),
                (0, 1, true),
                (2, 0, false),
                (3, 0, true),
                (3, 3, true)
            ]
        );
        assert_eq!(fresh.log, [(3, 0, true), (3, 3, true)]);
        assert_eq!(fresh.joins, [2, 1, 0, 1]);
        assert_eq!(fresh.ticks, 4);
        assert_eq!(copy.state_hash(), w.state_hash());
        assert_eq!(
            apply_tick(&mut w, &mut rules, 4, &players(&[64])).err(),
            Some(TickError::Slot { tick: 4, slot: 64 })
        );
    }
}
