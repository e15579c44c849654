//! # lockstep-proto
//!
//! The wire protocol of lockstep and its logic as I/O-free state machines,
//! the way `quinn-proto` is to `quinn`: no sockets, no clock, no threads.
//! The server wraps a [`Room`] and each client a [`Session`]; both are driven
//! by the caller's messages and time and hand back messages to send.
//!
//! - [`message`]: what is exchanged, and on which [`Channel`].
//! - [`codec`]: bytes ↔ messages with a version header and strict bounds;
//!   decoding never panics and returns a typed [`DecodeError`].
//! - [`room`]: the server's room — seats, the tick clock, input substitution,
//!   bundles with redundancy, per-tick hash arbitration by majority.
//! - [`session`]: the client — inputs with redundancy, in-order exactly-once
//!   bundle delivery, hash reports.
//! - [`limits`]: the protocol version and every bound.
//! - [`replay`]: the replay file format and the recorder the server feeds.
//!
//! The crate does not depend on the physics engine: inputs are opaque bytes
//! and world state is a `u64` hash. `docs/protocol.md` describes the wire
//! format, channels and measured message sizes.

#![warn(missing_docs)]

pub mod codec;
pub mod forensics;
pub mod limits;
pub mod message;
pub mod replay;
mod ring;
pub mod room;
pub mod session;
pub mod token;
pub mod verify;

pub use codec::{DecodeError, EncodeError, FRAME_HEADER_BYTES, encode_frame, frame_length};
pub use forensics::{
    BodyDiff, BodyDump, DesyncReport, FieldDiff, FieldDump, FieldKind, Probe, ProbeAnswer,
    ProbeAsk, ProbeReply, ProbeStatus, SuspectReport,
};
pub use limits::*;
pub use message::{
    BundleDatagram, Channel, ClientMessage, Close, CloseReason, DesyncNotice, HashReport,
    InputDatagram, Join, Ping, PlayerHash, PlayerInput, Pong, RejoinCredential, ServerMessage,
    Slot, TickBundle, Verdict, Violation, Welcome,
};
pub use replay::{
    ENGINE_VERSION, Replay, ReplayError, ReplayHeader, ReplayRecord, ReplayRecorder, RulesId,
};
pub use room::{
    AlreadyStarted, ConfigError, JoinError, LeaveReason, MIN_PROBE_REPLY_BYTES, MatchLifecycle,
    MatchPhase, PlayerId, PlayerStats, Rejection, Room, RoomConfig, RoomEvent, RoomStats, Transmit,
    Voting,
};
pub use session::{Session, SessionError, SessionEvent, SessionStats};
