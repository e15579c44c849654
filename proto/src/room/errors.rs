//! Why the room refuses a join or a message.

use thiserror::Error;

use crate::limits::MAX_DETAIL_BYTES;
use crate::message::{Close, CloseReason, Slot};

use super::events::PlayerId;

/// Why a join was refused. Send [`JoinError::to_close`] and close.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum JoinError {
    /// The client speaks another protocol version.
    #[error("client protocol version {client}, server {server}")]
    VersionMismatch {
        /// The client's version.
        client: u16,
        /// [`PROTOCOL_VERSION`](crate::PROTOCOL_VERSION).
        server: u16,
    },
    /// The join named another room.
    #[error("no room named {0:?} here")]
    WrongRoom(String),
    /// Every seat is taken.
    #[error("room is full ({0} players)")]
    RoomFull(u8),
    /// The match started; joining now would need a world snapshot.
    #[error("match already in progress")]
    MatchInProgress,
    /// The token's seat is held by another player.
    #[error("seat {0} is taken")]
    SeatTaken(u8),
    /// The token's seat does not exist in this room.
    #[error("the join token's seat {0} is not in this room")]
    NoSuchSeat(u8),
    /// The token already seated a player in this match (a token is used
    /// once per match; its holder comes back with the rejoin credential of
    /// its welcome).
    #[error(
        "this join token was already used in this match; its holder rejoins with the rejoin credential of its welcome"
    )]
    TokenUsed,
    /// The join's rejoin credential names a seat that is no longer
    /// reserved for it (the player was dropped, or stayed away longer than
    /// the rejoin grace).
    #[error("seat {0} is no longer reserved for a rejoin")]
    NotReserved(u8),
    /// Another player is joining the running match; one at a time.
    #[error("another player is joining the running match; try again")]
    JoinBusy,
    /// No tick was agreed on yet, or no player can give its state.
    #[error("no agreed state to join the running match from yet; try again")]
    NoAgreedState,
}

impl JoinError {
    /// The close message telling the client why.
    pub fn to_close(&self) -> Close {
        let reason = match self {
            Self::VersionMismatch { .. } => CloseReason::VersionMismatch,
            Self::WrongRoom(_) => CloseReason::WrongRoom,
            Self::RoomFull(_) => CloseReason::RoomFull,
            Self::MatchInProgress | Self::JoinBusy | Self::NoAgreedState => {
                CloseReason::MatchInProgress
            }
            Self::SeatTaken(_) => CloseReason::SeatTaken,
            Self::NoSuchSeat(_) | Self::TokenUsed | Self::NotReserved(_) => CloseReason::BadToken,
        };
        close(reason, self.to_string())
    }
}

/// Why a message from a seated player was refused. Nothing of a refused
/// message is applied. A compliant [`Session`](crate::Session) never causes
/// one; the server should log it and may close the client with
/// [`Rejection::to_close`].
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum Rejection {
    /// The handle names no current player (left, or never joined).
    #[error("no such player {0:?}")]
    UnknownPlayer(PlayerId),
    /// An input datagram names another player's slot.
    #[error("input for slot {claimed:?} from the player in slot {actual:?}")]
    WrongSlot {
        /// Slot named in the datagram.
        claimed: Slot,
        /// Slot of the sender.
        actual: Slot,
    },
    /// An input for a tick beyond the acceptance window (next open tick +
    /// `input_window`). Past ticks are never refused: a datagram delayed in
    /// the network carries them legitimately; they are ignored and counted.
    #[error("input for tick {tick} outside the window {lowest}..={highest}")]
    TickOutOfWindow {
        /// The offending tick.
        tick: u64,
        /// Next open tick.
        lowest: u64,
        /// Last tick accepted.
        highest: u64,
    },
    /// An input larger than [`RoomConfig::max_input_bytes`](super::RoomConfig::max_input_bytes).
    #[error("input of {len} bytes for tick {tick} exceeds {max}")]
    InputTooLarge {
        /// Its tick.
        tick: u64,
        /// Its size.
        len: usize,
        /// The room's limit.
        max: usize,
    },
    /// A different input for a tick whose input was already received.
    #[error("conflicting input for tick {tick}")]
    InputConflict {
        /// The tick.
        tick: u64,
    },
    /// A bundle acknowledgement for a tick that has not closed.
    #[error("ack of bundle {ack} before it closed (next tick {next_tick})")]
    AckFromFuture {
        /// The acknowledged tick.
        ack: u64,
        /// Next tick to close.
        next_tick: u64,
    },
    /// A hash for a tick that has not closed: the client cannot have
    /// applied it.
    #[error("hash for tick {tick} which has not closed (next tick {next_tick})")]
    HashForUnclosedTick {
        /// The tick.
        tick: u64,
        /// Next tick to close.
        next_tick: u64,
    },
    /// A hash for a tick whose bundle did not include the player.
    #[error("hash for tick {tick} which the player was not part of")]
    HashForTickNotPlayed {
        /// The tick.
        tick: u64,
    },
    /// A second, different hash for the same tick.
    #[error("conflicting hash for tick {tick}")]
    HashConflict {
        /// The tick.
        tick: u64,
    },
    /// A message that makes no sense now (e.g. a second join).
    #[error("unexpected {0} message")]
    UnexpectedMessage(&'static str),
}

impl Rejection {
    /// A close message naming the violation.
    pub fn to_close(&self) -> Close {
        close(CloseReason::ProtocolViolation, self.to_string())
    }
}

/// [`Room::start`](super::Room::start) was called twice.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Error)]
#[error("the room has already started")]
pub struct AlreadyStarted;

/// A close message, its detail cut to [`MAX_DETAIL_BYTES`] on a char boundary.
pub(crate) fn close(reason: CloseReason, mut detail: String) -> Close {
    let max = MAX_DETAIL_BYTES;
    if detail.len() > max {
        let mut cut = max;
        while !detail.is_char_boundary(cut) {
            cut -= 1;
        }
        detail.truncate(cut);
    }
    Close { reason, detail }
}
