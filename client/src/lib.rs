//! # lockstep-client
//!
//! The client side of lockstep: the network client ([`net`]), headless bots
//! ([`bot`]) and the game layer every peer runs before each step
//! ([`game`]). The offline tools behind the `lockstep` CLI (simulate a scene
//! file, verify a replay, tune, view) are the `lockstep-tools` crate. The
//! feature `test-hooks` adds `testing` rules that make a peer desync on
//! purpose.

#![warn(missing_docs)]

pub mod bot;
pub mod game;
pub mod load;
pub mod net;
#[cfg(feature = "test-hooks")]
pub mod testing;
