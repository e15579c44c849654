//! Prediction and rollback: the client runs ahead of the last tick the
//! server confirmed, with its own inputs as soon as it chose them and the
//! other players' predicted (their last confirmed input, or the game's
//! [`InputPredictor`]), so a player sees its input take effect without
//! waiting for the round trip.
//!
//! The confirmed path is untouched: the client still applies every
//! confirmed bundle to the confirmed world, in order, and reports that
//! world's hashes, so the server's comparison, forensics, bundles and
//! replays are as without prediction. Beside it, a second world holds the
//! predicted present. When a confirmed bundle differs from the inputs the
//! prediction used for its tick, the predicted world is reset to the
//! confirmed state (a clone of the world; the rules' state loaded back from
//! its game state, [`GameRules::load_state`]) and re-simulated to the
//! present: a rollback. A prediction that was right costs nothing more.
//!
//! I/O-free: [`LiveClient`](super::LiveClient) feeds it the confirmed
//! bundles, its own inputs and the tick to reach.

// The predictor is driven by the network client (feature `net`); without
// it only the public trait and counters here are used.
#![cfg_attr(not(feature = "net"), allow(dead_code))]

use std::collections::{BTreeMap, VecDeque};

use lockstep_core::World;
use lockstep_proto::TickBundle;

use crate::game::{GameError, GameRules, TickError, apply_tick};

/// Guesses another player's input for a tick it has not been confirmed
/// for. Default (no predictor): its last confirmed input.
pub trait InputPredictor: Send {
    /// The input `slot` is guessed to send at `tick`, given its last
    /// confirmed input (`last`, from tick `last_tick`).
    fn predict(&mut self, slot: u8, tick: u64, last: &[u8], last_tick: u64) -> Vec<u8>;
}

/// Prediction figures shared by several clients (the demo's bots), for a
/// live status line: counters only, added to as rollbacks happen.
#[derive(Debug, Default)]
pub struct PredictionTally {
    rollbacks: std::sync::atomic::AtomicU64,
    depth_sum: std::sync::atomic::AtomicU64,
    max_depth: std::sync::atomic::AtomicU64,
    resimulated: std::sync::atomic::AtomicU64,
}

/// A [`PredictionTally`]'s counts at one moment.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TallyCounts {
    /// Rollbacks.
    pub rollbacks: u64,
    /// Predicted ticks thrown away, over all rollbacks.
    pub depth_sum: u64,
    /// The deepest rollback.
    pub max_depth: u64,
    /// Ticks simulated again after rollbacks.
    pub resimulated: u64,
}

impl PredictionTally {
    /// Counts one rollback.
    pub fn add(&self, r: &Rollback) {
        use std::sync::atomic::Ordering::Relaxed;
        let depth = r.to.saturating_sub(r.from);
        self.rollbacks.fetch_add(1, Relaxed);
        self.depth_sum.fetch_add(depth, Relaxed);
        self.max_depth.fetch_max(depth, Relaxed);
        self.resimulated.fetch_add(r.resimulated, Relaxed);
    }

    /// The counts so far.
    pub fn counts(&self) -> TallyCounts {
        use std::sync::atomic::Ordering::Relaxed;
        TallyCounts {
            rollbacks: self.rollbacks.load(Relaxed),
            depth_sum: self.depth_sum.load(Relaxed),
            max_depth: self.max_depth.load(Relaxed),
            resimulated: self.resimulated.load(Relaxed),
        }
    }
}

/// What prediction did so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PredictionStats {
    /// Rollbacks: a confirmed tick differed from its prediction after the
    /// predicted world had passed it.
    pub rollbacks: u64,
    /// The largest number of predicted ticks thrown away by one rollback.
    pub max_depth: u64,
    /// Predicted ticks thrown away in all.
    pub discarded: u64,
    /// Ticks simulated on the predicted world (first predictions and
    /// re-simulations).
    pub simulated: u64,
    /// Predicted ticks whose inputs the server confirmed and whose
    /// predicted state hashed as the confirmed one: the prediction was
    /// the match, bit for bit.
    pub confirmed_right: u64,
    /// Predicted ticks whose inputs the server confirmed but whose state
    /// hashed otherwise: a determinism defect (the rules keep state
    /// outside the world, or read something beside their inputs). Zero.
    pub state_wrong: u64,
}

/// A rollback one [`Predictor::advance`] made: the predicted states of the
/// ticks from `from` up to `to` (exclusive) were wrong and were thrown
/// away (`from` is the first tick whose confirmed inputs differed from the
/// prediction; the confirmed world holds the ticks up to the last
/// confirmed one, and the predicted world was simulated again from
/// there).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rollback {
    /// The first tick whose prediction was wrong.
    pub from: u64,
    /// First tick after the predicted ticks thrown away.
    pub to: u64,
    /// Ticks simulated again on the predicted world after it (from the
    /// confirmed state to the present).
    pub resimulated: u64,
}

/// One tick's inputs: (slot, bytes), ascending by slot.
type Inputs = Vec<(u8, Vec<u8>)>;

/// A predicted tick: the inputs it was simulated with and the predicted
/// state's hash after it.
struct Predicted {
    tick: u64,
    inputs: Inputs,
    hash: u64,
}

/// The predicted world beside the confirmed one (see the module docs).
pub(crate) struct Predictor {
    max_ahead: u64,
    slot: u8,
    world: World,
    rules: Box<dyn GameRules>,
    /// The next tick to simulate on the predicted world.
    next: u64,
    /// Every predicted tick from the first not yet confirmed.
    used: VecDeque<Predicted>,
    /// This client's own inputs by tick, from the first not confirmed.
    own: BTreeMap<u64, Vec<u8>>,
    /// The players of the last confirmed tick with their inputs (and that
    /// tick).
    last: Inputs,
    last_tick: u64,
    /// The predicted world must restart from the confirmed state.
    stale: bool,
    /// The first confirmed tick whose prediction was wrong.
    wrong_from: Option<u64>,
    predictor: Option<Box<dyn InputPredictor>>,
    stats: PredictionStats,
}

impl Predictor {
    /// A predictor starting at the confirmed state `confirmed`, whose next
    /// tick is `next`; `rules` is a second instance of the game's rules
    /// (the predicted world's), `slot` this client's.
    pub(crate) fn new(
        confirmed: &World,
        next: u64,
        mut rules: Box<dyn GameRules>,
        slot: u8,
        max_ahead: u64,
        predictor: Option<Box<dyn InputPredictor>>,
    ) -> Result<Predictor, GameError> {
        rules.load_state(confirmed.game_state())?;
        Ok(Predictor {
            max_ahead,
            slot,
            world: confirmed.clone(),
            rules,
            next,
            used: VecDeque::new(),
            own: BTreeMap::new(),
            last: Vec::new(),
            last_tick: 0,
            stale: false,
            wrong_from: None,
            predictor,
            stats: PredictionStats::default(),
        })
    }

    /// The predicted world (after tick [`Predictor::next`]` − 1`).
    pub(crate) fn world(&self) -> &World {
        &self.world
    }

    /// The rules of the predicted world.
    pub(crate) fn rules(&self) -> &dyn GameRules {
        &*self.rules
    }

    /// The next tick the predicted world will simulate.
    pub(crate) fn next(&self) -> u64 {
        self.next
    }

    pub(crate) fn stats(&self) -> PredictionStats {
        self.stats
    }

    /// This client chose `input` for `tick`.
    pub(crate) fn own_input(&mut self, tick: u64, input: &[u8]) {
        self.own.insert(tick, input.to_vec());
    }

    /// The confirmed world has applied `bundle` and hashes `hash`: a
    /// prediction of its tick that used other inputs is stale from there
    /// on; one that used the same inputs must have hashed the same.
    pub(crate) fn confirmed(&mut self, bundle: &TickBundle, hash: u64) {
        let inputs: Inputs = bundle
            .inputs
            .iter()
            .map(|p| (p.slot.0, p.input.clone()))
            .collect();
        match self.used.front() {
            // Stale already (an earlier tick of this poll was wrong): the
            // predictions after it started from a wrong state.
            Some(p) if p.tick == bundle.tick && self.stale => {
                self.used.pop_front();
            }
            Some(p) if p.tick == bundle.tick => {
                if p.inputs != inputs {
                    self.stale = true;
                    self.wrong_from.get_or_insert(bundle.tick);
                } else if p.hash == hash {
                    self.stats.confirmed_right += 1;
                } else {
                    self.stats.state_wrong += 1;
                    self.stale = true;
                    self.wrong_from.get_or_insert(bundle.tick);
                }
                self.used.pop_front();
            }
            // Not predicted (the predicted world was behind), or the
            // predictions are out of step: start again from the confirmed
            // state.
            _ => self.stale = true,
        }
        self.own = self.own.split_off(&(bundle.tick + 1));
        self.last = inputs;
        self.last_tick = bundle.tick;
    }

    /// The inputs of predicted tick `tick`: the last confirmed players with
    /// their guessed inputs, and this client's own (an empty input if it
    /// chose none), ascending by slot.
    fn guess(&mut self, tick: u64) -> Inputs {
        let mut out: Inputs = Vec::with_capacity(self.last.len() + 1);
        for (slot, last) in &self.last {
            if *slot == self.slot {
                continue;
            }
            let input = match &mut self.predictor {
                Some(p) => p.predict(*slot, tick, last, self.last_tick),
                None => last.clone(),
            };
            out.push((*slot, input));
        }
        let own = self.own.get(&tick).cloned().unwrap_or_default();
        let at = out.partition_point(|(s, _)| *s < self.slot);
        out.insert(at, (self.slot, own));
        out
    }

    /// Brings the predicted world to the state after tick `target` (at
    /// most `max_ahead` past the confirmed state, whose next tick is
    /// `confirmed_next`), rolling back first if a confirmed tick showed the
    /// prediction wrong. Returns the rollback, if one was made.
    ///
    /// # Errors
    /// [`TickError`] from the rules; [`GameError`] from loading their state.
    pub(crate) fn advance(
        &mut self,
        confirmed: &World,
        confirmed_next: u64,
        target: u64,
    ) -> Result<Option<Rollback>, PredictError> {
        let mut rollback = None;
        if self.stale || self.next < confirmed_next {
            if let Some(from) = self.wrong_from.take()
                && self.next > from
            {
                let thrown = self.next - from;
                self.stats.rollbacks += 1;
                self.stats.max_depth = self.stats.max_depth.max(thrown);
                self.stats.discarded += thrown;
                rollback = Some(Rollback {
                    from,
                    to: self.next,
                    resimulated: 0,
                });
            }
            self.world.clone_from(confirmed);
            self.rules
                .load_state(self.world.game_state())
                .map_err(PredictError::Game)?;
            self.next = confirmed_next;
            self.used.clear();
            self.stale = false;
        }
        let end = target.min(confirmed_next.saturating_add(self.max_ahead));
        let first = self.next;
        while self.next <= end {
            let tick = self.next;
            let inputs = self.guess(tick);
            let refs: Vec<(u8, &[u8])> = inputs.iter().map(|(s, b)| (*s, b.as_slice())).collect();
            apply_tick(&mut self.world, &mut *self.rules, tick, &refs)
                .map_err(PredictError::Tick)?;
            let hash = self.world.state_hash();
            self.used.push_back(Predicted { tick, inputs, hash });
            self.next += 1;
            self.stats.simulated += 1;
        }
        if let Some(r) = &mut rollback {
            r.resimulated = self.next - first;
        }
        Ok(rollback)
    }
}

/// Why the predicted world could not be advanced (the confirmed path is
/// not affected).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PredictError {
    /// A predicted tick failed.
    #[error("prediction: {0}")]
    Tick(TickError),
    /// The rules refused the confirmed state.
    #[error("prediction: {0}")]
    Game(GameError),
}

#[cfg(test)]
mod tests {
    use lockstep_proto::{PlayerInput, Slot};

    use super::*;
    use crate::game::{Demo, DemoGame, DemoInput, RulesFactory, bot_input};

    fn bundle(tick: u64, inputs: &[(u8, Vec<u8>)]) -> TickBundle {
        TickBundle {
            tick,
            inputs: inputs
                .iter()
                .map(|(s, b)| PlayerInput {
                    slot: Slot(*s),
                    input: b.clone(),
                    substituted: false,
                })
                .collect(),
        }
    }

    /// Slot 1's confirmed inputs: the bot script, so they change every
    /// 40-odd ticks and a prediction from the last one is sometimes wrong.
    fn other(tick: u64) -> Vec<u8> {
        bot_input(9, 1, tick).encode()
    }

    fn own(tick: u64) -> Vec<u8> {
        DemoInput {
            move_x: ((tick / 7) % 3) as i8 * 50 - 50,
            move_z: 20,
            jump: tick.is_multiple_of(50),
        }
        .encode()
    }

    /// A client that predicts (slot 0, running `lead` ticks ahead of the
    /// confirmed bundles) ends, after every rollback, in the very state of a
    /// client that never predicted: every predicted tick that the
    /// confirmed inputs agree with hashes as the confirmed world did.
    #[test]
    fn rolled_back_prediction_lands_on_the_confirmed_states_bit_for_bit() {
        predict_and_confirm(1);
    }

    /// The same with the confirmed bundles arriving three at a time (a
    /// wrong tick followed by right ones in one poll: those were predicted
    /// from the wrong state, and are not counted as right or wrong).
    #[test]
    fn bundles_confirmed_together_after_a_wrong_one_count_nothing_wrong() {
        predict_and_confirm(3);
    }

    /// The demo's world at the start of a match, its confirmed rules, and a
    /// predictor for slot 0 at most `max` ticks ahead.
    fn start(
        max: u64,
        predictor: Option<Box<dyn InputPredictor>>,
    ) -> (World, Box<dyn GameRules>, Predictor) {
        let mut confirmed = DemoGame::world().unwrap();
        crate::game::start_match(&mut confirmed, 5).unwrap();
        let rules = Demo.rules_for(&confirmed).unwrap();
        let fresh = Demo.rules_for(&confirmed).unwrap();
        let p = Predictor::new(&confirmed, 0, fresh, 0, max, predictor).unwrap();
        (confirmed, rules, p)
    }

    fn predict_and_confirm(every: u64) {
        let (mut confirmed, mut rules, mut p) = start(8, None);
        let lead = 4;
        let ticks = 400;
        let mut confirmed_hashes = Vec::new();
        let mut predicted_hashes: BTreeMap<u64, u64> = BTreeMap::new();
        let mut rollbacks = 0;
        for now in 0..ticks + lead {
            // This client chooses its input for `now` and predicts to it.
            if now < ticks {
                p.own_input(now, &own(now));
            }
            // The bundle of `now - lead` is confirmed.
            if let Some(t) = now.checked_sub(lead) {
                let b = bundle(t, &[(0, own(t)), (1, other(t))]);
                crate::game::apply_bundle(&mut confirmed, &mut *rules, &b).unwrap();
                confirmed_hashes.push(confirmed.state_hash());
                p.confirmed(&b, confirmed.state_hash());
            }
            let next = confirmed_hashes.len() as u64;
            if !now.is_multiple_of(every) && now < ticks + lead - 1 {
                continue;
            }
            if let Some(r) = p.advance(&confirmed, next, now.min(ticks - 1)).unwrap() {
                rollbacks += 1;
                assert!(r.to > r.from && r.to - r.from <= lead + every, "{r:?}");
                // The predicted ticks thrown away are predicted again.
                for t in r.from..r.to {
                    predicted_hashes.remove(&t);
                }
            }
            let at = p.next() - 1;
            predicted_hashes
                .entry(at)
                .or_insert_with(|| p.world().state_hash());
        }
        assert!(rollbacks > 3, "{rollbacks} rollbacks");
        assert_eq!(p.stats().rollbacks, rollbacks);
        assert_eq!(p.stats().state_wrong, 0);
        assert!(p.stats().confirmed_right > 300 / every, "{:?}", p.stats());
        // The predicted world caught up with the last confirmed tick.
        assert_eq!(p.next(), ticks);
        assert_eq!(p.world().state_hash(), confirmed.state_hash());
        assert_eq!(p.world(), &confirmed);
        // Every predicted state that survived equals the confirmed one.
        for (t, h) in predicted_hashes {
            assert_eq!(h, confirmed_hashes[t as usize], "tick {t}");
        }
    }

    /// A game's own predictor: here one that knows slot 1's script, so
    /// every prediction is right and only the first tick (a player the
    /// prediction did not know yet) rolls back.
    #[test]
    fn a_game_s_input_predictor_is_used() {
        struct Oracle;
        impl InputPredictor for Oracle {
            fn predict(&mut self, slot: u8, tick: u64, _: &[u8], _: u64) -> Vec<u8> {
                assert_eq!(slot, 1);
                other(tick)
            }
        }
        let (mut confirmed, mut rules, mut p) = start(8, Some(Box::new(Oracle)));
        for now in 0..200u64 {
            p.own_input(now, &own(now));
            if let Some(t) = now.checked_sub(4) {
                let b = bundle(t, &[(0, own(t)), (1, other(t))]);
                crate::game::apply_bundle(&mut confirmed, &mut *rules, &b).unwrap();
                p.confirmed(&b, confirmed.state_hash());
            }
            let next = now.saturating_sub(3);
            p.advance(&confirmed, next, now).unwrap();
        }
        assert_eq!(p.stats().rollbacks, 1, "{:?}", p.stats());
        assert_eq!(p.stats().state_wrong, 0);
        assert!(p.stats().confirmed_right >= 190, "{:?}", p.stats());
    }

    #[test]
    fn a_right_prediction_costs_no_rollback_and_never_runs_past_the_limit() {
        let (mut confirmed, mut rules, mut p) = start(3, None);
        let still = DemoInput::default().encode();
        // Nothing confirmed yet: at most 3 ticks past the confirmed state
        // (its next tick 0): ticks 0..=3.
        for t in 0..4 {
            p.own_input(t, &still);
        }
        p.advance(&confirmed, 0, 10).unwrap();
        assert_eq!(p.next(), 4);
        // The players' inputs never change: no rollback after the first.
        for t in 0..60 {
            p.own_input(t + 4, &still);
            let b = bundle(t, &[(0, still.clone()), (1, still.clone())]);
            crate::game::apply_bundle(&mut confirmed, &mut *rules, &b).unwrap();
            p.confirmed(&b, confirmed.state_hash());
            p.advance(&confirmed, t + 1, t + 4).unwrap();
        }
        // The first confirmed tick had a player the prediction did not know.
        assert_eq!(p.stats().rollbacks, 1);
        assert_eq!(p.stats().confirmed_right, 59);
        assert_eq!(p.next(), 64);
    }
}
