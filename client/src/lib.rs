//! # lockstep-client
//!
//! The client side of lockstep: the network client ([`net`]), headless bots
//! ([`bot`]), the game layer every peer runs before each step ([`game`]),
//! and the offline tools behind the `lockstep` CLI (simulate a scene file,
//! dump its state, verify a replay). The feature `test-hooks` adds
//! `testing` rules that make a peer desync on purpose.

#![warn(missing_docs)]

pub mod bot;
pub mod game;
pub mod load;
pub mod net;
pub mod offline;
#[cfg(feature = "test-hooks")]
pub mod testing;
pub mod view;
