//! The demo game's browser module: the whole of it is the one macro call
//! below, which exports lockstep-web's client (docs/browser.md) for the
//! demo's rules. Built for the browser with
//!
//! ```text
//! cargo build --release -p lockstep-web-demo --target wasm32-unknown-unknown
//! ```
//!
//! (the demo does it itself: `lockstep-server --demo --webtransport ADDR`).
//! A game of its own writes the same crate with its own rules: its
//! `RulesFactory` plus `lockstep_web::WebGame` (keys to input bytes).

lockstep_web::export_client!(lockstep_client::game::Demo);
