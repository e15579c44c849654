//! The server as an arbiter that cannot be outvoted: it re-simulates the
//! match from the scene and every closed bundle, and its own hash is the
//! verdict ([`RoomConfig::verify`](crate::RoomConfig::verify)).
//!
//! The protocol does not know the engine or the game: a verifier is a
//! plugin the server is given, built by the game's side (the client
//! library has one for any `RulesFactory`).

use crate::message::TickBundle;

/// One room's re-simulation.
pub trait TickVerifier: Send {
    /// Applies the bundle of the next tick (ticks come in order from 0) and
    /// returns the state hash after it.
    fn apply(&mut self, bundle: &TickBundle) -> u64;

    /// The state after the last applied tick as snapshot bytes, if the
    /// verifier can give them (for late joiners).
    fn snapshot(&self) -> Option<Vec<u8>> {
        None
    }
}

/// Makes a verifier for each room.
pub trait VerifierFactory: Send + Sync + std::fmt::Debug {
    /// A verifier starting from `scene` (the bytes the room sends), whose
    /// initial state must hash to `scene_hash`, for a match played with
    /// `seed` (the welcome's).
    ///
    /// # Errors
    /// A message saying why the scene cannot be simulated.
    fn new_verifier(
        &self,
        scene: &[u8],
        scene_hash: u64,
        seed: u64,
    ) -> Result<Box<dyn TickVerifier>, String>;
}
