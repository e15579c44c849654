//! The game layer: the rules that turn players' inputs into forces.
//!
//! The server relays each player's input bytes without understanding them;
//! every peer (bots, clients, the offline replay tool) calls the same
//! [`GameRules::apply_inputs`] with the same bytes right before
//! `world.step()`, so the rules must be as deterministic as the physics:
//! integer and [`Scalar`](lockstep_core::Scalar) arithmetic only, no floats,
//! no hash-map iteration, no clock, no randomness that is not a pure
//! function of its arguments.
//!
//! A game plugs in through [`RulesFactory`]: its [`RulesId`] (recorded in
//! every replay), a constructor of fresh [`GameRules`] for each world (the
//! client, each bot and each replay check build their own), and optionally
//! a scripted bot input. The client ([`crate::net::Client::connect`]), the
//! bots ([`crate::bot`]) and the replay check
//! (`lockstep_tools::verify_replay`) all take one.
//!
//! The demo ([`Demo`], rules [`DemoGame`]) is one such game: each player
//! walks a capsule (the character controller) around a walled arena with piles of boxes
//! ([`DemoGame::SCENE`], from `scenes/demo.toml`), with the 3-byte input
//! [`DemoInput`]; [`bot_input`] scripts a bot's input for any tick.

mod demo;
mod input;
mod policy;
mod tick;

#[cfg(test)]
mod tests;

pub use demo::{
    DemoGame, GAIN, JUMP_SPEED, MAX_ACCEL, MAX_PLAYERS, MAX_SPEED, PUSH_FORCE, PlayerLimits,
    REST_SPEED, STANDING_COS,
};
pub use input::{DemoInput, INPUT_LEN, bot_input};

use std::sync::Arc;

pub use lockstep_core::{GameState, GameStateError};
pub use lockstep_proto::RulesId;
pub use policy::{BotPolicy, BotView};
use thiserror::Error;
pub use tick::{
    PLAYERS_FIELD, SEED_FIELD, TickError, apply_bundle, apply_tick, match_seed, start_match,
};

/// The game layer: turns one tick's player inputs into forces and impulses
/// on the world, called by every peer (bots, clients, the offline replay
/// tool) right before `world.step()`.
///
/// Implementations must be deterministic (integer/`Scalar` only, no floats,
/// no hash-map iteration, no clock): two peers that call it with the same
/// world state and the same inputs must leave the world in the same state,
/// bit for bit, or they desync.
///
/// # The game's own state
///
/// Whatever the rules remember from one tick to the next (scores, rounds,
/// cooldowns, a random generator's state) is simulation state: it must be
/// in the world's [`GameState`] after every tick, or a late joiner (whose
/// rules start fresh) desyncs and the state hash cannot see a difference.
/// Either keep it in the world (read and write
/// [`World::game_state_mut`](lockstep_core::World::game_state_mut) in
/// [`apply_inputs`](GameRules::apply_inputs)), or keep it in the rules and
/// implement [`save_state`](GameRules::save_state) and
/// [`load_state`](GameRules::load_state): [`apply_tick`] saves it after
/// every tick's inputs, and [`RulesFactory::rules_for`] loads it into fresh
/// rules for a restored world. A wrapper around other rules forwards all
/// five methods.
pub trait GameRules: Send + std::any::Any {
    /// Applies the inputs of `tick`: one entry per player present, ascending
    /// by slot. `bytes` may be anything up to 64 bytes long, including
    /// malformed: never panic, treat bad input as "no input".
    ///
    /// Determinism: must be called once per tick, before `world.step()`,
    /// with the entries in ascending slot order on every peer (what
    /// [`apply_tick`] does).
    fn apply_inputs(&mut self, world: &mut lockstep_core::World, tick: u64, inputs: &[(u8, &[u8])]);

    /// Writes the state the rules keep outside the world into `state`
    /// (called by [`apply_tick`] after every tick's inputs). Set the same
    /// fields in the same order every time. Default: nothing (rules that
    /// keep no state, or keep it in the world).
    ///
    /// # Errors
    /// A field past a [`GameState`] bound: the tick fails on every peer
    /// alike and the client reports it.
    fn save_state(&self, state: &mut GameState) -> Result<(), GameStateError> {
        let _ = state;
        Ok(())
    }

    /// Reads back what [`save_state`](GameRules::save_state) wrote, into
    /// rules just made for a restored world (a late join, a rejoin, a desync
    /// bundle, a sync test). Default: nothing.
    ///
    /// # Errors
    /// [`GameError::BadState`] if the state is not one these rules wrote.
    fn load_state(&mut self, state: &GameState) -> Result<(), GameError> {
        let _ = state;
        Ok(())
    }

    /// Player `slot` is in the match from `tick` on (at tick 0 for the
    /// players who started it; later for a late joiner or a rejoin).
    /// Called by [`apply_tick`] before that tick's inputs, in ascending slot
    /// order. Default: nothing.
    fn player_joined(&mut self, world: &mut lockstep_core::World, tick: u64, slot: u8) {
        let _ = (world, tick, slot);
    }

    /// Player `slot` is no longer in the match from `tick` on (left,
    /// dropped, or waiting to rejoin). Called by [`apply_tick`] before
    /// that tick's inputs and before any join, in ascending slot order.
    /// Default: nothing.
    fn player_left(&mut self, world: &mut lockstep_core::World, tick: u64, slot: u8) {
        let _ = (world, tick, slot);
    }
}

impl dyn GameRules {
    /// These rules as their concrete type, if they are an `R` (a frame
    /// loop reading its game's score, a bot policy reading a cooldown).
    pub fn downcast_ref<R: GameRules>(&self) -> Option<&R> {
        (self as &dyn std::any::Any).downcast_ref::<R>()
    }
}

/// A game, as the client, the bots and the replay check see it: which rules
/// these are, and how to make a fresh instance of them for a world.
///
/// `new_rules` is called once per world (each client, each bot, each replay
/// check), right after the world is built from the match's scene and before
/// the first tick; it may look bodies up by name and keep their handles.
///
/// # Example
///
/// A one-button game: a player's input byte `1` kicks the ball called
/// `"ball"` upward by 2 m/s; anything else (a malformed input included)
/// does nothing. Every peer builds its own rules from the same world and
/// applies the same inputs before each step, so two peers stay identical.
///
/// ```
/// use lockstep_client::game::{GameError, GameRules, RulesFactory, RulesId};
/// use lockstep_core::{BodyHandle, Scalar, Vec3, World, scene::load_world};
///
/// struct Kick;
/// struct KickRules {
///     ball: BodyHandle,
/// }
///
/// impl RulesFactory for Kick {
///     fn rules_id(&self) -> RulesId {
///         RulesId::new("kick", 1)
///     }
///     fn new_rules(&self, world: &World) -> Result<Box<dyn GameRules>, GameError> {
///         let ball = world
///             .find_body("ball")
///             .ok_or_else(|| GameError::MissingBody("ball".into()))?;
///         Ok(Box::new(KickRules { ball }))
///     }
/// }
///
/// impl GameRules for KickRules {
///     fn apply_inputs(&mut self, world: &mut World, _tick: u64, inputs: &[(u8, &[u8])]) {
///         for &(_slot, bytes) in inputs {
///             if bytes == [1] {
///                 let mass = world.body(self.ball).map(|b| b.mass()).unwrap_or(Scalar::ZERO);
///                 let up = Vec3::new(Scalar::ZERO, Scalar::from_int(2) * mass, Scalar::ZERO);
///                 let _ = world.apply_impulse(self.ball, up);
///             }
///         }
///     }
/// }
///
/// let scene = "[[bodies]]\nname = \"ball\"\nkind = \"dynamic\"\n\
///              [[bodies.shapes]]\nkind = \"sphere\"\nradius = 0.5\n";
/// let mut peers: Vec<(World, Box<dyn GameRules>)> = (0..2)
///     .map(|_| {
///         let world = load_world(scene, "kick.toml").unwrap();
///         let rules = Kick.new_rules(&world).unwrap();
///         (world, rules)
///     })
///     .collect();
/// for tick in 0..30 {
///     let kick: &[u8] = if tick == 0 { &[1] } else { &[7, 7] }; // then garbage
///     for (world, rules) in &mut peers {
///         rules.apply_inputs(world, tick, &[(0, kick)]);
///         world.step();
///     }
/// }
/// let (a, b) = (&peers[0].0, &peers[1].0);
/// assert_eq!(a.state_hash(), b.state_hash());
/// // Kicked at 2 m/s and falling since: v = 2 − 9.81·0.5 s.
/// let ball = a.find_body("ball").unwrap();
/// let vy = a.body(ball).unwrap().linear_velocity().y.to_f64();
/// assert!((vy - (2.0 - 9.81 * 0.5)).abs() < 1e-6, "{vy}");
/// // A game without a ball is refused with the reason.
/// let empty = load_world("", "empty.toml").unwrap();
/// assert_eq!(
///     Kick.new_rules(&empty).err(),
///     Some(GameError::MissingBody("ball".into()))
/// );
/// ```
pub trait RulesFactory: Send + Sync {
    /// The rules' id and version, recorded in every replay; a replay is
    /// checked only with rules of the same id and version.
    fn rules_id(&self) -> RulesId;

    /// Fresh rules for a world built from the match's scene.
    ///
    /// # Errors
    /// [`GameError`] if the world is not the one the game expects.
    fn new_rules(&self, world: &lockstep_core::World) -> Result<Box<dyn GameRules>, GameError>;

    /// Rules for `world` wherever it comes from: [`new_rules`] for it,
    /// then its game state loaded into them ([`GameRules::load_state`]).
    /// Every program of the library makes rules this way, so a world
    /// restored mid-match (a late join, a bundle) continues with the rules'
    /// state it was saved with.
    ///
    /// [`new_rules`]: RulesFactory::new_rules
    ///
    /// # Errors
    /// [`GameError`] from either.
    fn rules_for(&self, world: &lockstep_core::World) -> Result<Box<dyn GameRules>, GameError> {
        let mut rules = self.new_rules(world)?;
        rules.load_state(world.game_state())?;
        Ok(rules)
    }

    /// A headless bot's input for `tick` (pure function of its arguments
    /// so that bot matches are reproducible). Default: no input (empty
    /// bytes), which rules must accept.
    fn bot_input(&self, seed: u64, slot: u8, tick: u64) -> Vec<u8> {
        let _ = (seed, slot, tick);
        Vec::new()
    }

    /// A bot that sees the world, for the bot in `slot` of a match played
    /// with `seed`; the bots ([`crate::bot`]) use it when there is one, and
    /// [`bot_input`](RulesFactory::bot_input) otherwise (and always for
    /// load tests' blind bots). Default: none.
    fn bot_policy(&self, seed: u64, slot: u8) -> Option<Box<dyn BotPolicy>> {
        let _ = (seed, slot);
        None
    }

    /// How a predicting client guesses the other players' inputs for the
    /// ticks not confirmed yet
    /// ([`ClientOptions::predict`](crate::net::ClientOptions::predict)).
    /// Default: none, each player's last confirmed input.
    fn input_predictor(&self) -> Option<Box<dyn crate::net::InputPredictor>> {
        None
    }
}

impl<T: RulesFactory + ?Sized> RulesFactory for Arc<T> {
    fn rules_id(&self) -> RulesId {
        (**self).rules_id()
    }
    fn new_rules(&self, world: &lockstep_core::World) -> Result<Box<dyn GameRules>, GameError> {
        (**self).new_rules(world)
    }
    fn bot_input(&self, seed: u64, slot: u8, tick: u64) -> Vec<u8> {
        (**self).bot_input(seed, slot, tick)
    }
    fn rules_for(&self, world: &lockstep_core::World) -> Result<Box<dyn GameRules>, GameError> {
        (**self).rules_for(world)
    }
    fn bot_policy(&self, seed: u64, slot: u8) -> Option<Box<dyn BotPolicy>> {
        (**self).bot_policy(seed, slot)
    }
    fn input_predictor(&self) -> Option<Box<dyn crate::net::InputPredictor>> {
        (**self).input_predictor()
    }
}

/// The demo game as a [`RulesFactory`]: [`DemoGame`] rules, [`bot_input`]
/// bots, id [`Demo::ID`] at version [`Demo::VERSION`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Demo;

impl Demo {
    /// The demo's rules id.
    pub const ID: &'static str = "lockstep-demo";
    /// The demo rules' version: bump whenever [`DemoGame`] turns the same
    /// inputs into different motions. 2: players are kinematic capsules
    /// moved by the character controller (1 drove dynamic balls by forces).
    /// 3: every tick's hash covers the game state (the players present).
    pub const VERSION: u32 = 3;
}

impl RulesFactory for Demo {
    fn rules_id(&self) -> RulesId {
        RulesId::new(Self::ID, Self::VERSION)
    }
    fn new_rules(&self, world: &lockstep_core::World) -> Result<Box<dyn GameRules>, GameError> {
        Ok(Box::new(DemoGame::new(world)?))
    }
    fn bot_input(&self, seed: u64, slot: u8, tick: u64) -> Vec<u8> {
        bot_input(seed, slot, tick).encode()
    }
}

/// Why game rules could not be set up for a world: the world is not the
/// one the game expects (a body is missing or has the wrong shape).
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum GameError {
    /// The world has no body with this name.
    #[error("the world has no body named {0:?}")]
    MissingBody(String),
    /// The world's game state is not one these rules wrote.
    #[error("game state: {0}")]
    BadState(String),
    /// A body exists but is not what the game needs.
    #[error("body {name:?}: {problem}")]
    BadBody {
        /// The body's name.
        name: String,
        /// What is wrong and what was expected.
        problem: String,
    },
}

/// A server-side re-simulation of a match with a game's rules (what
/// `lockstep-server --verify` runs, and what a game's own server gives
/// `ServerConfig::verifier`): builds the world from the room's scene, then
/// applies every closed bundle through the rules and steps, exactly as each
/// client does.
#[derive(Clone)]
pub struct RulesVerifier {
    /// The game.
    pub game: std::sync::Arc<dyn RulesFactory>,
}

impl std::fmt::Debug for RulesVerifier {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RulesVerifier")
            .field("rules", &self.game.rules_id())
            .finish()
    }
}

struct VerifiedWorld {
    world: lockstep_core::World,
    rules: Box<dyn GameRules>,
}

impl lockstep_proto::verify::TickVerifier for VerifiedWorld {
    fn apply(&mut self, bundle: &lockstep_proto::TickBundle) -> u64 {
        // A tick the rules cannot apply fails alike on every peer; the
        // hash of the state as it is stays the verdict.
        let _ = apply_bundle(&mut self.world, &mut *self.rules, bundle);
        self.world.state_hash()
    }

    fn snapshot(&self) -> Option<Vec<u8>> {
        Some(self.world.snapshot())
    }
}

impl lockstep_proto::verify::VerifierFactory for RulesVerifier {
    fn new_verifier(
        &self,
        scene: &[u8],
        scene_hash: u64,
        seed: u64,
    ) -> Result<Box<dyn lockstep_proto::verify::TickVerifier>, String> {
        let text = std::str::from_utf8(scene).map_err(|e| format!("scene is not UTF-8: {e}"))?;
        let world =
            lockstep_core::scene::load_world(text, "room scene").map_err(|e| e.to_string())?;
        let got = world.state_hash();
        if got != scene_hash {
            return Err(format!(
                "scene hashes to {got:016x}, the room announces {scene_hash:016x}"
            ));
        }
        let mut world = world;
        start_match(&mut world, seed).map_err(|e| e.to_string())?;
        let rules = self.game.rules_for(&world).map_err(|e| e.to_string())?;
        Ok(Box::new(VerifiedWorld { world, rules }))
    }
}
