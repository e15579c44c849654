//! # lockstep-client
//!
//! The client side of lockstep: the network client ([`net`]), headless bots
//! ([`bot`]), the game layer every peer runs before each step ([`game`]),
//! and the offline tools behind the `lockstep` CLI (simulate a scene file,
//! dump its state, verify a replay).

#![warn(missing_docs)]

pub mod bot;
pub mod game;
pub mod net;
pub mod offline;
