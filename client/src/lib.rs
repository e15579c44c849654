//! # lockstep-client
//!
//! The client side of lockstep: the offline tools behind the `lockstep` CLI
//! (simulate a scene file, dump its state), and later the network client and
//! headless bots.

#![warn(missing_docs)]

pub mod game;
pub mod offline;
