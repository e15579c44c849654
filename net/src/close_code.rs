//! QUIC application close codes, so a peer (or a packet capture) can tell
//! why a connection ended without the reason text.

use lockstep_proto::CloseReason;

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
/// The peer's state hash stayed outside the majority: it diverged (or
/// lies) and cannot follow the match any more.
pub const DIVERGED: u32 = 6;

/// The QUIC close code for a protocol [`CloseReason`].
pub fn close_code_for(reason: CloseReason) -> u32 {
    match reason {
        CloseReason::Kicked => NORMAL,
        CloseReason::RoomClosed => NORMAL,
        CloseReason::TimedOut | CloseReason::FellBehind => TIMED_OUT,
        CloseReason::RoomFull
        | CloseReason::MatchInProgress
        | CloseReason::WrongRoom
        | CloseReason::VersionMismatch
        | CloseReason::SeatTaken
        | CloseReason::BadToken => REFUSED,
        CloseReason::ProtocolViolation | CloseReason::NoHashReports => PROTOCOL_VIOLATION,
        CloseReason::Diverged => DIVERGED,
    }
}
