//! The network client: QUIC (quinn) around `lockstep_proto::Session`.
//!
//! [`Client::connect`] opens a QUIC connection to a server (trusting the
//! certificate file the server wrote, or a real one), or a WebTransport
//! session to its `--webtransport` endpoint
//! ([`ClientOptions::webtransport`], trusting the certificate by its hash
//! with [`TrustedCert::Sha256`] as a browser does), joins a room, receives
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
//!
//! The transport both sides share (ALPN, close codes, stream framing,
//! transport and congestion settings, certificate files, the
//! [`Link`] over QUIC or WebTransport) is the crate `lockstep-net`; its
//! items are re-exported here.
//!
//! Prediction ([`predict`]) and the forensics history ([`History`]) are
//! I/O-free and stay without the feature `net`; everything else here needs
//! it.

#[cfg(feature = "net")]
mod client;
mod forensics;
#[cfg(feature = "net")]
mod live;
#[cfg(feature = "net")]
mod options;
pub mod predict;
#[cfg(feature = "net")]
mod report;
#[cfg(feature = "net")]
mod tls;

#[cfg(feature = "net")]
pub use client::Client;
pub use forensics::{History, dump_bodies, dump_game};
#[cfg(feature = "net")]
pub use live::{AppliedTick, LiveClient, Polled};
#[cfg(feature = "net")]
pub use lockstep_net::{
    ALPN, FrameError, Link, LinkError, LinkRecv, LinkSend, MIN_CONGESTION_WINDOW, TlsError,
    WEBTRANSPORT_PATH, close_code, close_code_for, load_certs, parse_certs, read_frame,
    transport_config, webtransport_transport_config, write_frame,
};
#[cfg(feature = "net")]
pub use options::{ClientOptions, RejoinStore, TrustedCert};
pub use predict::{InputPredictor, PredictionStats, PredictionTally, Rollback, TallyCounts};
#[cfg(feature = "net")]
pub use report::{ClientError, ClientEvent, ClientReport, InputLatency, Latency, Traffic};
#[cfg(feature = "net")]
pub use tls::client_config;
