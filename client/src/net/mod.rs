//! The network client: QUIC (quinn) around `lockstep_proto::Session`.
//!
//! [`Client::connect`] opens a QUIC connection to a server (trusting the
//! certificate file the server wrote, or a real one), joins a room, receives
//! the welcome, and builds the world from the scene it carries, checking the
//! scene hash. [`Client::play`] then runs the lockstep loop: submit the local
//! input for tick `t + input_delay`, apply the bundles strictly in tick order
//! through the game rules, step the world, report every tick's state hash,
//! and surface the room's events (desync notices, the close).
//!
//! What goes where (see `docs/protocol.md`): inputs, bundles, pings and pongs
//! travel as QUIC datagrams; join, welcome, hash reports, desync notices,
//! leave and close go on the one bidirectional stream, each message framed
//! with `lockstep_proto::encode_frame`.

mod client;
mod frame;
mod tls;

pub use client::{
    AppliedTick, Client, ClientError, ClientEvent, ClientOptions, ClientReport, LiveClient, Polled,
    Traffic, TrustedCert,
};
pub use frame::{FrameError, read_frame, write_frame};
pub use tls::{
    MIN_CONGESTION_WINDOW, TlsError, client_config, load_certs, parse_certs, transport_config,
};

use lockstep_proto::CloseReason;

/// The ALPN protocol id both sides require: a QUIC peer that speaks
/// something else is refused during the handshake, before any message.
pub const ALPN: &[u8] = b"lockstep/1";

/// QUIC application close codes, so a peer (or a packet capture) can tell
/// why a connection ended without the reason text.
pub mod close_code {
    /// The match ended, or the client left.
    pub const NORMAL: u32 = 0;
    /// The peer sent something the protocol forbids.
    pub const PROTOCOL_VIOLATION: u32 = 1;
    /// The join was refused (room full, wrong version, match in progress...).
    pub const REFUSED: u32 = 2;
    /// The server is shutting down.
    pub const SHUTDOWN: u32 = 3;
    /// The peer was silent for too long or fell behind.
    pub const TIMED_OUT: u32 = 4;
    /// The server cannot serve the peer (too many connections, a full
    /// send queue).
    pub const OVERLOADED: u32 = 5;
}

/// The QUIC close code for a protocol [`CloseReason`].
pub fn close_code_for(reason: CloseReason) -> u32 {
    match reason {
        CloseReason::Kicked => close_code::NORMAL,
        CloseReason::RoomClosed => close_code::NORMAL,
        CloseReason::TimedOut | CloseReason::FellBehind => close_code::TIMED_OUT,
        CloseReason::RoomFull
        | CloseReason::MatchInProgress
        | CloseReason::WrongRoom
        | CloseReason::VersionMismatch => close_code::REFUSED,
        CloseReason::ProtocolViolation => close_code::PROTOCOL_VIOLATION,
    }
}
