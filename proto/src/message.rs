//! The messages clients and the server exchange, and the invariants each one
//! must satisfy on the wire.
//!
//! Inputs are opaque bytes and world state is summarised by `u64` hashes: the
//! protocol never interprets either, which keeps it independent of the physics
//! engine. Every message names the [`Channel`] it belongs on.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::limits::{
    MAX_BODY_HASHES, MAX_BUNDLES_PER_DATAGRAM, MAX_DETAIL_BYTES, MAX_INPUT_BYTES, MAX_INPUT_WINDOW,
    MAX_INPUTS_PER_DATAGRAM, MAX_NAME_BYTES, MAX_PLAYERS, MAX_SCENE_BYTES,
};

/// A player's seat in a room, `0..MAX_PLAYERS`. Bundles list inputs by slot
/// and the game maps slots to avatars, so the slot is the player's identity
/// inside a match (names are only for display).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Slot(pub u8);

impl Slot {
    /// The slot as an array index.
    pub fn index(self) -> usize {
        usize::from(self.0)
    }
}

/// Which QUIC channel a message travels on. Datagrams are for the per-tick
/// traffic where a late copy is worthless and redundancy replaces
/// retransmission; the reliable stream is for everything that must arrive
/// exactly once and in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    /// The connection's reliable, ordered stream (length-prefixed frames).
    Reliable,
    /// An unreliable QUIC datagram of at most
    /// [`MAX_DATAGRAM_BYTES`](crate::MAX_DATAGRAM_BYTES) bytes.
    Datagram,
}

// ---------------------------------------------------------------------------
// Client → server
// ---------------------------------------------------------------------------

/// First message of a connection: asks for a seat in a room.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Join {
    /// The client's [`PROTOCOL_VERSION`](crate::PROTOCOL_VERSION). The frame
    /// header already guards decoding; this copy lets a room refuse an
    /// in-process join (bots, tests) on the same terms.
    pub protocol_version: u16,
    /// Name of the room to join.
    pub room: String,
    /// Display name of the player.
    pub player_name: String,
    /// A signed join token (see [`token`](crate::token)), when the server
    /// requires one or the player holds one. A token seats one player once
    /// per match; the seat's owner comes back with `rejoin`.
    pub token: Option<String>,
    /// The rejoin credential the room gave this player in an earlier
    /// [`Welcome`] of the same match: it takes the player back to its own
    /// seat (the token is then not needed). A credential the room does not
    /// know is ignored, and the join is judged by its token.
    pub rejoin: Option<RejoinCredential>,
}

/// A secret the room gives a token holder at its first join
/// ([`Welcome::rejoin`]), bound to the room, the seat and the token, valid
/// for the rest of the match: only its holder can take the seat back. 32
/// random-looking bytes (an HMAC-SHA256 tag under a key only the room
/// knows).
#[derive(Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct RejoinCredential(pub [u8; 32]);

impl std::fmt::Debug for RejoinCredential {
    /// Never prints the secret itself.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("RejoinCredential(..)")
    }
}

/// One input datagram: the player's inputs for the consecutive ticks
/// `first_tick..first_tick + inputs.len()`, repeated until the server
/// acknowledges them, plus the client's acknowledgement of bundles.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct InputDatagram {
    /// The sender's slot; the room rejects a datagram naming another slot.
    pub slot: Slot,
    /// Last tick up to which the client holds every bundle (contiguous), so
    /// the server stops repeating those. `None` before the first bundle.
    pub ack_bundle: Option<u64>,
    /// Tick of `inputs[0]`.
    pub first_tick: u64,
    /// Opaque inputs, one per consecutive tick.
    pub inputs: Vec<Vec<u8>>,
}

/// The hash of the client's world after applying the bundle of `tick`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct HashReport {
    /// Tick whose bundle was applied.
    pub tick: u64,
    /// Canonical state hash after that tick.
    pub hash: u64,
    /// Optional per-body hashes in body order, sent to help locate the first
    /// divergent body; the room does not interpret them yet.
    pub body_hashes: Option<Vec<u64>>,
}

/// Answer to a [`Ping`], echoing its nonce so the server can measure RTT.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Pong {
    /// The nonce of the ping being answered.
    pub nonce: u64,
}

/// Everything a client sends to the server.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ClientMessage {
    /// Ask for a seat (reliable).
    Join(Join),
    /// Inputs with redundancy and the bundle ack (datagram).
    Input(InputDatagram),
    /// State hash of one tick (reliable).
    HashReport(HashReport),
    /// Answer to a ping (datagram).
    Pong(Pong),
    /// Leave the room for good (reliable).
    Leave,
    /// The answer to a [`Probe`](crate::forensics::Probe) (reliable).
    ProbeReply(crate::forensics::ProbeReply),
}

impl ClientMessage {
    /// The channel this message must be sent on.
    pub fn channel(&self) -> Channel {
        match self {
            Self::Input(_) | Self::Pong(_) => Channel::Datagram,
            Self::Join(_) | Self::HashReport(_) | Self::Leave | Self::ProbeReply(_) => {
                Channel::Reliable
            }
        }
    }

    /// Short name of the variant, for logs and error messages.
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Join(_) => "join",
            Self::Input(_) => "input",
            Self::HashReport(_) => "hash report",
            Self::Pong(_) => "pong",
            Self::Leave => "leave",
            Self::ProbeReply(_) => "probe reply",
        }
    }

    /// Checks the bounds and invariants a decoder must enforce.
    ///
    /// # Errors
    /// The first [`Violation`] found.
    pub fn validate(&self) -> Result<(), Violation> {
        match self {
            Self::Join(j) => {
                if j.room.is_empty() {
                    return Err(Violation::EmptyRoomName);
                }
                check_len(j.room.len(), MAX_NAME_BYTES, |len, max| {
                    Violation::NameTooLong { len, max }
                })?;
                check_len(j.player_name.len(), MAX_NAME_BYTES, |len, max| {
                    Violation::NameTooLong { len, max }
                })?;
                check_len(
                    j.token.as_ref().map_or(0, String::len),
                    crate::token::MAX_TOKEN_BYTES,
                    |len, max| Violation::TokenTooLong { len, max },
                )
            }
            Self::Input(d) => {
                check_slot(d.slot)?;
                check_len(d.inputs.len(), MAX_INPUTS_PER_DATAGRAM, |count, max| {
                    Violation::TooManyEntries { count, max }
                })?;
                for input in &d.inputs {
                    check_len(input.len(), MAX_INPUT_BYTES, |len, max| {
                        Violation::InputTooLarge { len, max }
                    })?;
                }
                // The last tick must be representable.
                d.first_tick
                    .checked_add(d.inputs.len() as u64)
                    .map(|_| ())
                    .ok_or(Violation::TickOverflow)
            }
            Self::HashReport(h) => match &h.body_hashes {
                Some(b) => check_len(b.len(), MAX_BODY_HASHES, |count, max| {
                    Violation::TooManyEntries { count, max }
                }),
                None => Ok(()),
            },
            Self::Pong(_) | Self::Leave => Ok(()),
            Self::ProbeReply(r) => r.validate(),
        }
    }
}

// ---------------------------------------------------------------------------
// Server → client
// ---------------------------------------------------------------------------

/// The server's answer to a successful [`Join`]: everything the client needs
/// to build the world and take part in the match.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Welcome {
    /// The seat assigned to this client.
    pub slot: Slot,
    /// Ticks per second of the room's clock.
    pub tick_rate: u16,
    /// Ticks between sampling an input and the tick it applies to.
    pub input_delay: u16,
    /// The room accepts inputs for ticks below `next open tick + input_window`;
    /// the client never sends further ahead.
    pub input_window: u16,
    /// Largest input the room accepts, at most
    /// [`MAX_INPUT_BYTES`].
    pub max_input_bytes: u8,
    /// First tick whose bundle includes this player.
    pub start_tick: u64,
    /// Hash of `scene`, so the client can verify what it loaded.
    pub scene_hash: u64,
    /// The scene, opaque to the protocol (empty when `resume` is given).
    pub scene: Vec<u8>,
    /// For a player joining a running match (a late join or a rejoin): the
    /// state to start from instead of the scene.
    pub resume: Option<Resume>,
    /// The game rules the match is played with (`None`: the server does not
    /// say). A client with other rules must not play.
    pub rules: Option<crate::RulesId>,
    /// The match's seed: the game state of a world built from the scene
    /// starts with it (ignored with `resume`: the snapshot holds it).
    pub seed: u64,
    /// For a player seated with a join token: the credential that takes it
    /// back to this seat for the rest of the match ([`Join::rejoin`]). Its
    /// token is used up and seats nobody else. `None` for other players.
    pub rejoin: Option<RejoinCredential>,
}

/// Where a player joining a running match starts: the world after `tick`
/// as the players agreed on it. The client restores the snapshot, applies
/// the bundles from `tick + 1` (sent to it like any other) as fast as it
/// can, and plays from the welcome's `start_tick` on.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Resume {
    /// The tick the snapshot is the state after.
    pub tick: u64,
    /// The agreed hash of that tick; the snapshot hashes to it.
    pub hash: u64,
    /// The engine's snapshot bytes.
    pub snapshot: Vec<u8>,
}

impl Welcome {
    /// Checks the bounds and invariants a decoder must enforce.
    ///
    /// # Errors
    /// The first [`Violation`] found.
    pub fn validate(&self) -> Result<(), Violation> {
        check_slot(self.slot)?;
        if self.tick_rate == 0 {
            return Err(Violation::ZeroTickRate);
        }
        if self.input_window <= self.input_delay || self.input_window > MAX_INPUT_WINDOW {
            return Err(Violation::BadInputWindow {
                window: self.input_window,
                delay: self.input_delay,
            });
        }
        check_len(
            usize::from(self.max_input_bytes),
            MAX_INPUT_BYTES,
            |len, max| Violation::InputTooLarge { len, max },
        )?;
        if let Some(r) = &self.rules {
            check_len(r.id.len(), MAX_NAME_BYTES, |len, max| {
                Violation::NameTooLong { len, max }
            })?;
        }
        let resume = self.resume.as_ref().map_or(0, |r| r.snapshot.len());
        check_len(self.scene.len() + resume, MAX_SCENE_BYTES, |len, max| {
            Violation::SceneTooLarge { len, max }
        })?;
        match &self.resume {
            Some(r) if r.tick >= self.start_tick => Err(Violation::TickOverflow),
            _ => Ok(()),
        }
    }
}

/// One player's input inside a tick bundle.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PlayerInput {
    /// Whose input.
    pub slot: Slot,
    /// The opaque input applied for this tick.
    pub input: Vec<u8>,
    /// True when the player's input did not arrive by the deadline and the
    /// room repeated their previous input instead.
    pub substituted: bool,
}

/// Everything needed to step tick `tick`: the input of every player in the
/// room, in ascending slot order.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TickBundle {
    /// The tick these inputs apply to.
    pub tick: u64,
    /// One entry per player present at this tick, ascending by slot.
    pub inputs: Vec<PlayerInput>,
}

impl TickBundle {
    /// Slots whose input was substituted in this bundle, ascending.
    pub fn substituted(&self) -> Vec<Slot> {
        self.inputs
            .iter()
            .filter(|p| p.substituted)
            .map(|p| p.slot)
            .collect()
    }
}

/// One bundle datagram: closed tick bundles the client has not acknowledged,
/// ascending by tick, plus the server's acknowledgement of the client's inputs.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct BundleDatagram {
    /// Last tick for which the room needs no more input from this client
    /// (closed, or received contiguously); the client stops repeating those.
    pub ack_input: Option<u64>,
    /// Bundles, strictly ascending by tick (not necessarily consecutive).
    pub bundles: Vec<TickBundle>,
}

/// A player's reported hash for the tick of a desync; `None` if the player did
/// not report before the comparison timed out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PlayerHash {
    /// The player.
    pub slot: Slot,
    /// What they reported, if anything.
    pub hash: Option<u64>,
}

/// Who the room believes is wrong after a hash mismatch.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Verdict {
    /// More than half of the reporting players agree on `majority_hash`; the
    /// players in `wrong` (ascending) reported something else.
    Majority {
        /// The hash held by the strict majority.
        majority_hash: u64,
        /// The players in the minority.
        wrong: Vec<Slot>,
    },
    /// No hash is held by more than half of the reporters (e.g. two players
    /// that disagree): the room cannot tell who is wrong and says so.
    Undecided,
    /// The server re-simulated the tick itself (`--verify`): its `hash` is
    /// the truth, and the players in `wrong` (ascending) reported another,
    /// however many they are.
    Verified {
        /// The server's own hash of the tick.
        hash: u64,
        /// The players whose hash differs from it.
        wrong: Vec<Slot>,
    },
}

/// Announces that players' world hashes differ at `tick`: sent to every
/// player, and raised as a room event.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct DesyncNotice {
    /// First tick (of this divergence) whose hashes differ.
    pub tick: u64,
    /// Every player expected at that tick with their hash, ascending by slot.
    pub hashes: Vec<PlayerHash>,
    /// The majority verdict.
    pub verdict: Verdict,
}

/// Liveness and RTT probe; the client answers with a [`Pong`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Ping {
    /// Opaque value to echo.
    pub nonce: u64,
}

/// Why the server ends a player's participation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum CloseReason {
    /// The server operator removed the player.
    Kicked,
    /// Nothing was heard from the player for the silence timeout.
    TimedOut,
    /// The room has no free slot.
    RoomFull,
    /// The match already started; late join is not supported.
    MatchInProgress,
    /// The join named another room.
    WrongRoom,
    /// The client speaks another protocol version.
    VersionMismatch,
    /// The client sent something the protocol forbids.
    ProtocolViolation,
    /// The client fell so far behind that the bundles it still needs were
    /// dropped from the room's history.
    FellBehind,
    /// The room was shut down.
    RoomClosed,
    /// The player's state hash stayed outside the majority, tick after
    /// tick: it diverged, or it lies.
    Diverged,
    /// The player stopped reporting its state hash.
    NoHashReports,
    /// The join's token names a seat another player holds.
    SeatTaken,
    /// The server requires a valid join token and the join had none, or a
    /// bad one: altered, expired, for another room or seat, or already used
    /// in this match; or a rejoin credential whose seat is no longer
    /// reserved (the detail says what was wrong).
    BadToken,
}

/// Final message to a player before the server closes the connection.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Close {
    /// Machine-readable reason.
    pub reason: CloseReason,
    /// Human-readable detail for logs.
    pub detail: String,
}

/// Everything the server sends to a client.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ServerMessage {
    /// Seat granted (reliable).
    Welcome(Welcome),
    /// Tick bundles with redundancy and the input ack (datagram).
    Bundles(BundleDatagram),
    /// Hash mismatch detected (reliable).
    Desync(DesyncNotice),
    /// RTT probe (datagram).
    Ping(Ping),
    /// Participation ended (reliable).
    Close(Close),
    /// A question about a past tick, to locate a desync (reliable).
    Probe(crate::forensics::Probe),
    /// Where a desync lies: bodies and fields (reliable).
    DesyncReport(crate::forensics::DesyncReport),
}

impl ServerMessage {
    /// The channel this message must be sent on.
    pub fn channel(&self) -> Channel {
        match self {
            Self::Bundles(_) | Self::Ping(_) => Channel::Datagram,
            Self::Welcome(_)
            | Self::Desync(_)
            | Self::Close(_)
            | Self::Probe(_)
            | Self::DesyncReport(_) => Channel::Reliable,
        }
    }

    /// Short name of the variant, for logs and error messages.
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Welcome(_) => "welcome",
            Self::Bundles(_) => "bundles",
            Self::Desync(_) => "desync notice",
            Self::Ping(_) => "ping",
            Self::Close(_) => "close",
            Self::Probe(_) => "probe",
            Self::DesyncReport(_) => "desync report",
        }
    }

    /// Checks the bounds and invariants a decoder must enforce.
    ///
    /// # Errors
    /// The first [`Violation`] found.
    pub fn validate(&self) -> Result<(), Violation> {
        match self {
            Self::Welcome(w) => w.validate(),
            Self::Bundles(d) => {
                check_len(d.bundles.len(), MAX_BUNDLES_PER_DATAGRAM, |count, max| {
                    Violation::TooManyEntries { count, max }
                })?;
                ascending(
                    d.bundles.iter().map(|b| b.tick),
                    Violation::TicksNotAscending,
                )?;
                for b in &d.bundles {
                    check_len(b.inputs.len(), MAX_PLAYERS, |count, max| {
                        Violation::TooManyEntries { count, max }
                    })?;
                    for p in &b.inputs {
                        check_slot(p.slot)?;
                        check_len(p.input.len(), MAX_INPUT_BYTES, |len, max| {
                            Violation::InputTooLarge { len, max }
                        })?;
                    }
                    ascending(
                        b.inputs.iter().map(|p| p.slot),
                        Violation::SlotsNotAscending,
                    )?;
                }
                Ok(())
            }
            Self::Desync(n) => {
                check_len(n.hashes.len(), MAX_PLAYERS, |count, max| {
                    Violation::TooManyEntries { count, max }
                })?;
                for h in &n.hashes {
                    check_slot(h.slot)?;
                }
                ascending(
                    n.hashes.iter().map(|h| h.slot),
                    Violation::SlotsNotAscending,
                )?;
                if let Verdict::Majority { wrong, .. } | Verdict::Verified { wrong, .. } =
                    &n.verdict
                {
                    check_len(wrong.len(), MAX_PLAYERS, |count, max| {
                        Violation::TooManyEntries { count, max }
                    })?;
                    for &s in wrong {
                        check_slot(s)?;
                    }
                    ascending(wrong.iter().copied(), Violation::SlotsNotAscending)?;
                }
                Ok(())
            }
            Self::Ping(_) => Ok(()),
            Self::Close(c) => check_len(c.detail.len(), MAX_DETAIL_BYTES, |len, max| {
                Violation::DetailTooLong { len, max }
            }),
            Self::Probe(p) => p.validate(),
            Self::DesyncReport(r) => r.validate(),
        }
    }
}

/// A message that decoded as bincode but breaks a protocol bound or
/// invariant. Decoders and encoders both refuse such messages, so a peer can
/// rely on every bound listed in [`limits`](crate::limits).
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum Violation {
    /// A room or player name is longer than allowed.
    #[error("name of {len} bytes exceeds {max}")]
    NameTooLong {
        /// Actual length in bytes.
        len: usize,
        /// Allowed length.
        max: usize,
    },
    /// A join names no room.
    #[error("the room name is empty")]
    EmptyRoomName,
    /// A join token is longer than
    /// [`MAX_TOKEN_BYTES`](crate::token::MAX_TOKEN_BYTES).
    #[error("join token of {len} bytes exceeds {max}")]
    TokenTooLong {
        /// Actual length in bytes.
        len: usize,
        /// Allowed length.
        max: usize,
    },
    /// A snapshot (its announced total, or one piece) is larger than
    /// allowed.
    #[error("snapshot {what} of {len} bytes exceeds {max}")]
    SnapshotTooLarge {
        /// "total" or "piece".
        what: &'static str,
        /// Actual length in bytes.
        len: usize,
        /// Allowed length.
        max: usize,
    },
    /// An input is larger than [`MAX_INPUT_BYTES`].
    #[error("input of {len} bytes exceeds {max}")]
    InputTooLarge {
        /// Actual length in bytes.
        len: usize,
        /// Allowed length.
        max: usize,
    },
    /// A list holds more entries than its bound.
    #[error("{count} entries exceed the bound of {max}")]
    TooManyEntries {
        /// Entries present.
        count: usize,
        /// Allowed entries.
        max: usize,
    },
    /// The scene blob is larger than allowed.
    #[error("scene of {len} bytes exceeds {max}")]
    SceneTooLarge {
        /// Actual length in bytes.
        len: usize,
        /// Allowed length.
        max: usize,
    },
    /// A close detail is longer than allowed.
    #[error("close detail of {len} bytes exceeds {max}")]
    DetailTooLong {
        /// Actual length in bytes.
        len: usize,
        /// Allowed length.
        max: usize,
    },
    /// A slot number is not below [`MAX_PLAYERS`].
    #[error("slot {0} is out of range")]
    SlotOutOfRange(u8),
    /// Slots in a list are not strictly ascending (duplicates or disorder).
    #[error("slots are not strictly ascending")]
    SlotsNotAscending,
    /// Bundle ticks in a datagram are not strictly ascending.
    #[error("ticks are not strictly ascending")]
    TicksNotAscending,
    /// The tick range of an input datagram overflows `u64`.
    #[error("tick range overflows")]
    TickOverflow,
    /// A welcome announces a tick rate of zero.
    #[error("tick rate is zero")]
    ZeroTickRate,
    /// A welcome's input window does not exceed its input delay or is too big.
    #[error("input window {window} must exceed input delay {delay} and be at most the limit")]
    BadInputWindow {
        /// Announced window.
        window: u16,
        /// Announced delay.
        delay: u16,
    },
}

fn check_len(
    len: usize,
    max: usize,
    err: impl FnOnce(usize, usize) -> Violation,
) -> Result<(), Violation> {
    if len > max {
        Err(err(len, max))
    } else {
        Ok(())
    }
}

fn check_slot(slot: Slot) -> Result<(), Violation> {
    if slot.index() < MAX_PLAYERS {
        Ok(())
    } else {
        Err(Violation::SlotOutOfRange(slot.0))
    }
}

fn ascending<T: PartialOrd>(
    mut items: impl Iterator<Item = T>,
    err: Violation,
) -> Result<(), Violation> {
    let Some(mut prev) = items.next() else {
        return Ok(());
    };
    for item in items {
        if item <= prev {
            return Err(err);
        }
        prev = item;
    }
    Ok(())
}
