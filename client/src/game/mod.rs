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
//! The built-in game is the demo ([`DemoGame`]): each player drives a ball
//! around a walled arena with piles of boxes ([`DemoGame::SCENE`], from
//! `scenes/demo.toml`), with the 3-byte input [`DemoInput`]; [`bot_input`]
//! scripts a bot's input for any tick.

mod demo;
mod input;

#[cfg(test)]
mod tests;

pub use demo::{
    DemoGame, GAIN, JUMP_SPEED, MAX_ACCEL, MAX_PLAYERS, MAX_SPEED, PlayerLimits, REST_SPEED,
    STANDING_COS,
};
pub use input::{DemoInput, INPUT_LEN, bot_input};

use thiserror::Error;

/// The game layer: turns one tick's player inputs into forces and impulses
/// on the world, called by every peer (bots, clients, the offline replay
/// tool) right before `world.step()`.
///
/// Implementations must be deterministic (integer/`Scalar` only, no floats,
/// no hash-map iteration, no clock): two peers that call it with the same
/// world state and the same inputs must leave the world in the same state,
/// bit for bit, or they desync.
pub trait GameRules: Send {
    /// Applies the inputs of `tick`: one entry per player present, ascending
    /// by slot. `bytes` may be anything up to 64 bytes long, including
    /// malformed: never panic, treat bad input as "no input".
    ///
    /// Determinism: must be called once per tick, before `world.step()`,
    /// with the entries in ascending slot order on every peer.
    fn apply_inputs(&mut self, world: &mut lockstep_core::World, tick: u64, inputs: &[(u8, &[u8])]);
}

/// Why game rules could not be set up for a world: the world is not the
/// one the game expects (a body is missing or has the wrong shape).
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum GameError {
    /// The world has no body with this name.
    #[error("the world has no body named {0:?}")]
    MissingBody(String),
    /// A body exists but is not what the game needs.
    #[error("body {name:?}: {problem}")]
    BadBody {
        /// The body's name.
        name: String,
        /// What is wrong and what was expected.
        problem: String,
    },
}
