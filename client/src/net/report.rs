//! What a client tells: its errors, its events, and its report (traffic
//! and latency figures).

use std::time::{Duration, Instant};

use lockstep_core::Faults;
use lockstep_proto::{Close, CloseReason, DecodeError, DesyncNotice, SessionError, Slot};
use thiserror::Error;

use lockstep_net::{FrameError, TlsError};

use crate::game::RulesId;

/// Why a client stopped with an error.
#[derive(Debug, Error)]
pub enum ClientError {
    /// The certificate or TLS settings are unusable.
    #[error("{0}")]
    Tls(#[from] TlsError),
    /// The UDP socket could not be opened.
    #[error("socket: {0}")]
    Socket(#[source] std::io::Error),
    /// Connecting failed (address, handshake, certificate, ALPN).
    #[error("connect: {0}")]
    Connect(String),
    /// Nothing arrived in time while connecting or joining.
    #[error("timed out {0}")]
    Timeout(&'static str),
    /// The server refused the join.
    #[error("refused by the server: {reason:?}: {detail}")]
    Refused {
        /// The protocol reason.
        reason: CloseReason,
        /// The server's detail.
        detail: String,
    },
    /// The connection failed or the server closed it without a close
    /// message.
    #[error("connection lost: {0}")]
    ConnectionLost(String),
    /// A stream frame could not be read or written.
    #[error("{0}")]
    Frame(#[from] FrameError),
    /// The server sent bytes that are not a valid message.
    #[error("bad message from the server: {0}")]
    Decode(#[from] DecodeError),
    /// The server sent a message that makes no sense here.
    #[error("unexpected {0} from the server")]
    Unexpected(&'static str),
    /// The welcome could not start a session.
    #[error("session: {0}")]
    Session(#[from] SessionError),
    /// The scene in the welcome does not build.
    #[error("scene: {0}")]
    Scene(String),
    /// The scene built, but its hash is not the one the server announced.
    #[error("scene hash {got:016x}, the server announced {expected:016x}")]
    SceneHashMismatch {
        /// Announced.
        expected: u64,
        /// Computed.
        got: u64,
    },
    /// The server plays other rules than this client's.
    #[error(
        "the server plays {server}, this client {ours}: build the client with the server's game (or point it at a server of its own)"
    )]
    WrongRules {
        /// What the server announced.
        server: RulesId,
        /// This client's.
        ours: RulesId,
    },
    /// The game rules refused the world.
    #[error("game: {0}")]
    Game(String),
}

/// Something the application should know about while playing.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ClientEvent {
    /// The room found a hash mismatch.
    Desync {
        /// The room's notice (tick, every player's hash, verdict).
        notice: DesyncNotice,
        /// This client's own hash for that tick, if still remembered.
        local_hash: Option<u64>,
    },
    /// A step raised an arithmetic fault (the scene left the fixed-point
    /// range): the hashes from here on still agree between peers, but the
    /// physics is no longer meaningful.
    Fault {
        /// The tick.
        tick: u64,
        /// Which faults.
        faults: Faults,
    },
    /// The server ended the session.
    Closed(Close),
    /// The room located a desync: the bodies and fields that differ.
    DesyncLocated(lockstep_proto::DesyncReport),
    /// Predicting: a confirmed tick differed from its prediction, and the
    /// predicted world was rolled back and simulated again (passed to the
    /// event callback, not kept in [`ClientReport::events`]).
    Rollback(super::predict::Rollback),
}

/// Bytes and datagrams one connection moved, for bandwidth figures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Traffic {
    /// UDP payload bytes sent (QUIC overhead, acks and retransmissions
    /// included), from quinn's counters.
    pub udp_bytes_sent: u64,
    /// UDP payload bytes received.
    pub udp_bytes_received: u64,
    /// Protocol datagrams sent.
    pub datagrams_sent: u64,
    /// Their protocol bytes (encoded messages, without QUIC framing).
    pub datagram_bytes_sent: u64,
    /// Largest protocol datagram sent.
    pub max_datagram_sent: usize,
    /// Protocol datagrams received.
    pub datagrams_received: u64,
    /// Their protocol bytes.
    pub datagram_bytes_received: u64,
    /// Largest protocol datagram received.
    pub max_datagram_received: usize,
    /// Stream frames sent, and their bytes (length prefix included).
    pub frames_sent: u64,
    /// Bytes of the frames sent.
    pub frame_bytes_sent: u64,
}

/// What a client did, returned by [`Client::play`](super::Client::play).
#[derive(Clone, Debug)]
pub struct ClientReport {
    /// This client's slot.
    pub slot: Slot,
    /// The first tick it took part in (its first input and report).
    pub start_tick: u64,
    /// The first tick it applied: `start_tick`, or for a player that joined
    /// a running match the tick after its snapshot. `hashes[i]` is the hash
    /// after tick `first_applied + i`.
    pub first_applied: u64,
    /// Ticks applied (bundles stepped).
    pub ticks_applied: u64,
    /// The state hash after every applied tick, in tick order from
    /// `first_applied` (reported from `start_tick` on).
    pub hashes: Vec<u64>,
    /// When each tick's bundle became applicable (in order, so a bundle
    /// waiting for a missing earlier one counts as late too); index is
    /// `tick - start_tick`. Compare with the server's tick deadlines.
    pub delivered_at: Vec<Instant>,
    /// Ticks where this client's own input was substituted by the room.
    pub own_inputs_substituted: u64,
    /// Every event seen, in order.
    pub events: Vec<ClientEvent>,
    /// The server's close message, if the server ended the session.
    pub close: Option<Close>,
    /// quinn's round-trip estimate at the end.
    pub rtt: Duration,
    /// Traffic counters.
    pub traffic: Traffic,
    /// From the welcome to the end of play.
    pub played_for: Duration,
    /// What prediction did ([`ClientOptions::predict`](super::ClientOptions::predict); zeros without).
    pub prediction: super::predict::PredictionStats,
    /// From choosing an input to the world shown containing its tick: the
    /// confirmed world's (a bundle's round trip), and, predicting, the
    /// predicted world's.
    pub input_latency: InputLatency,
}

/// Input-to-effect latency figures of one client (see
/// [`ClientReport::input_latency`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct InputLatency {
    /// Until the confirmed world applied the input's tick.
    pub confirmed: Latency,
    /// Until the predicted world simulated the input's tick (zero samples
    /// without prediction).
    pub predicted: Latency,
}

/// Samples of one latency: count, sum and largest.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Latency {
    /// Samples.
    pub count: u64,
    /// Their sum.
    pub total: Duration,
    /// The largest.
    pub max: Duration,
}

impl Latency {
    pub(super) fn add(&mut self, d: Duration) {
        self.count += 1;
        self.total += d;
        self.max = self.max.max(d);
    }

    /// The mean (zero without samples).
    pub fn mean(&self) -> Duration {
        if self.count == 0 {
            Duration::ZERO
        } else {
            self.total / u32::try_from(self.count).unwrap_or(u32::MAX)
        }
    }
}

impl ClientReport {
    /// The desync notices received, in order.
    pub fn desyncs(&self) -> impl Iterator<Item = &DesyncNotice> {
        self.events.iter().filter_map(|e| match e {
            ClientEvent::Desync { notice, .. } => Some(notice),
            _ => None,
        })
    }
}
