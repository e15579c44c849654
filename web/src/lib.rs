//! # lockstep-web
//!
//! The browser client: a player in a page, in the same rooms as native
//! clients, simulating exactly what they simulate. The game's rules, the
//! protocol's [`Session`](lockstep_proto::Session) and the core run in
//! WebAssembly (`wasm32-unknown-unknown`); a small JavaScript layer
//! (`web/page/client.js`) connects with WebTransport, moves bytes between
//! the connection and the module, runs the page loop, reads the keyboard
//! and draws with the viewer's renderer. docs/browser.md has the whole
//! story: how it works, what differs on WebTransport, the certificate
//! rules, the figures.
//!
//! - [`WebClient`]: the client as an I/O-free state machine (what a
//!   native bot's loop does, fed bytes and times by the page).
//! - [`WebGame`]: what a game adds for its browser client (the keys a
//!   player holds to its input bytes); the demo's is here.
//! - [`Module`] and [`export_client!`]: the module's plain `extern "C"`
//!   exports for a game; a game's browser module is a `cdylib` crate
//!   whose whole source is `lockstep_web::export_client!(MyGame);`
//!   (`web/demo` is the demo's).
//! - [`site`]: natively, the page's HTTP routes (beside the viewer's
//!   renderer) and the build of a browser module with cargo.
//!
//! Determinism: the module runs the same core, proto and rules code as the
//! native programs, with no floats on the simulation path; floats appear
//! only in what the page reads to draw (poses converted from fixed point)
//! and in the page's clock, which paces inputs and never reaches the
//! world. The browser test (`tests/tests/browser.rs`) has the room compare
//! every tick's hash from the page and from native bots.

#![warn(missing_docs)]

mod client;
mod game;
pub mod module;
pub mod site;

pub use client::{Counters, Ending, FORENSICS_TICKS, WebClient};
pub use game::{Keys, WebGame};
pub use module::Module;
