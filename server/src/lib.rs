//! # lockstep-server
//!
//! The lockstep server: tokio + quinn around `lockstep_proto::Room`, the way
//! `quinn` wraps `quinn-proto`. It relays inputs and compares hashes; it
//! never simulates.
//!
//! - [`run`] is the whole server as a library function: it listens, accepts
//!   connections, seats players in rooms (created on the first join of a
//!   name), drives each room's tick clock, records every match as a replay,
//!   and on `shutdown` finishes the current tick, closes every connection
//!   with a reason, flushes the replays and waits for its tasks.
//! - With [`ServerConfig::webtransport`], a WebTransport (HTTP/3) endpoint
//!   beside the QUIC one lets browsers join the same rooms: a session on
//!   [`WEBTRANSPORT_PATH`] is served by the same connection code as a
//!   native connection (`lockstep_net::Link`).
//! - Each connection has a task that reads its stream frames and datagrams
//!   and forwards decoded messages to its room (`conn`); each room has a task
//!   that owns the [`Room`](lockstep_proto::Room) state machine and all
//!   sending (`room`).
//! - The game is a parameter ([`ServerConfig::for_game`]: its scene and its
//!   rules' id); the server never runs the rules. The `lockstep-server`
//!   program and its `--demo` (the server with the demo game and
//!   in-process bots) are in the `lockstep` package (`cli/`).
//!
//! Nothing a client sends can disturb a room beyond that client: malformed
//! or oversized frames and datagrams, messages on the wrong channel, and
//! everything the room rejects (another slot's inputs, ticks outside the
//! window, conflicting hashes) close that client with a logged reason.

#![warn(missing_docs)]

pub mod agones;
mod clock;
mod config;
mod conn;
mod error;
pub mod log;
pub mod metrics;
mod peer;
mod report;
mod room;
mod server;
mod shared;
pub mod spectate;
mod tls;
mod webtransport;

use std::time::Duration;

pub use config::{RoomSettings, ServerConfig, ViewSettings};
pub use error::ServerError;
pub use lockstep_net::WEBTRANSPORT_PATH;
pub use lockstep_proto::RulesId;
pub use report::{
    Lateness, PlayerReport, RECENT_MATCHES, RECENT_REFUSALS, RoomReport, RoomStatus, ServerEvent,
    ServerReport,
};
pub use server::run;
pub(crate) use shared::Shared;
pub use tls::TlsSource;
pub use webtransport::{DEV_CERT_VALIDITY, cert_sha256};

/// A join token for a seat (or any seat, `seat: None`) of `room`, for
/// `player`, valid for `ttl` from `now`: what a matchmaker hands a player
/// it placed. The server checks it against the same `secret`
/// ([`ServerConfig::token_secret`]).
///
/// # Errors
/// [`lockstep_proto::token::TokenError::Unissuable`] for a secret shorter
/// than 16 bytes, names over 64 bytes or a seat out of range.
pub fn issue_token(
    secret: &[u8],
    room: &str,
    seat: Option<u8>,
    player: &str,
    ttl: Duration,
    now: std::time::SystemTime,
) -> Result<String, lockstep_proto::token::TokenError> {
    let now = now
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    lockstep_proto::token::issue(
        secret,
        &lockstep_proto::token::JoinClaims {
            room: room.to_owned(),
            seat: seat.map(lockstep_proto::Slot),
            player: player.to_owned(),
            expires: now.saturating_add(ttl.as_secs()),
        },
    )
}
