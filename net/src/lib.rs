//! # lockstep-net
//!
//! The QUIC transport both sides of lockstep share, so that the server and
//! the client agree on it by construction:
//!
//! - [`ALPN`]: the protocol id both sides require during the handshake;
//! - [`close_code`]: the QUIC application close codes, and
//!   [`close_code_for`] a protocol [`CloseReason`](lockstep_proto::CloseReason);
//! - [`read_frame`] and [`write_frame`]: length-prefixed protocol messages
//!   on the connection's one stream;
//! - [`transport_config`]: timeouts, stream limits, datagram buffers and
//!   congestion control (NewReno with a window floor of
//!   [`MIN_CONGESTION_WINDOW`]);
//! - [`load_certs`] and [`parse_certs`]: PEM certificates from a file or
//!   from memory;
//! - [`Link`]: a peer's connection over native QUIC or over WebTransport
//!   (HTTP/3, what a browser speaks), with its stream halves
//!   ([`LinkSend`], [`LinkRecv`]): the one type the server's connection
//!   code and the client run on.
//!
//! What goes where (see `docs/protocol.md`): inputs, bundles, pings and pongs
//! travel as QUIC datagrams; join, welcome, hash reports, desync notices,
//! leave and close go on the one bidirectional stream, each message framed
//! with `lockstep_proto::encode_frame`.

#![warn(missing_docs)]

mod certs;
pub mod close_code;
mod congestion;
mod frame;
mod link;
mod transport;

pub use certs::{TlsError, load_certs, parse_certs};
pub use close_code::close_code_for;
pub use congestion::MIN_CONGESTION_WINDOW;
pub use frame::{FrameError, read_frame, write_frame};
pub use link::{Link, LinkError, LinkRecv, LinkSend, WEBTRANSPORT_ALPN, WEBTRANSPORT_PATH};
pub use transport::{transport_config, webtransport_transport_config};

/// The ALPN protocol id both sides require: a QUIC peer that speaks
/// something else is refused during the handshake, before any message.
pub const ALPN: &[u8] = b"lockstep/1";
