//! # lockstep-client
//!
//! The client side of lockstep: the network client ([`net`]), headless bots
//! ([`bot`]) and the game layer every peer runs before each step
//! ([`game`]). The offline tools behind the `lockstep` CLI (simulate a scene
//! file, verify a replay, tune, view) are the `lockstep-tools` crate. The
//! feature `test-hooks` adds `testing` rules that make a peer desync on
//! purpose.
//!
//! The default feature `net` is the network part (tokio and quinn): the
//! QUIC client in [`net`], the [`bot`]s and the load relays. Without it
//! (`default-features = false`) the crate is the game layer, prediction and
//! the forensics history, which need only `lockstep-core` and
//! `lockstep-proto` and build for `wasm32-unknown-unknown`: the browser
//! client (`lockstep-web`) is built on that.

#![warn(missing_docs)]

#[cfg(feature = "net")]
pub mod bot;
pub mod game;
#[cfg(feature = "net")]
pub mod load;
pub mod net;
#[cfg(feature = "test-hooks")]
pub mod testing;
