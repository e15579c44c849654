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

#[cfg(test)]
mod tests {
    use lockstep_proto::{Close, CloseReason, ServerMessage};

    use super::close_code_for;

    const EVERY_REASON: [CloseReason; 13] = [
        CloseReason::Kicked,
        CloseReason::TimedOut,
        CloseReason::RoomFull,
        CloseReason::MatchInProgress,
        CloseReason::WrongRoom,
        CloseReason::VersionMismatch,
        CloseReason::ProtocolViolation,
        CloseReason::FellBehind,
        CloseReason::RoomClosed,
        CloseReason::Diverged,
        CloseReason::NoHashReports,
        CloseReason::SeatTaken,
        CloseReason::BadToken,
    ];

    /// Every close reason's index on the wire and QUIC close code are the
    /// ones docs/protocol.md's table gives, row by row.
    #[test]
    fn every_close_reason_has_the_documented_index_and_quic_code() {
        let docs =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/protocol.md"))
                .expect("docs/protocol.md");
        let start = docs
            .find("| index | reason | QUIC code |")
            .expect("the close reason table");
        let rows: Vec<(u8, String, u32)> = docs[start..]
            .lines()
            .skip(2)
            .take_while(|l| l.starts_with('|'))
            .map(|l| {
                let cells: Vec<&str> = l.split('|').map(str::trim).collect();
                let name = cells[2].split('`').nth(1).expect("a name").to_owned();
                (
                    cells[1].parse().expect("an index"),
                    name,
                    cells[3].parse().expect("a code"),
                )
            })
            .collect();
        assert_eq!(rows.len(), EVERY_REASON.len(), "{rows:?}");
        for (reason, (index, name, code)) in EVERY_REASON.into_iter().zip(&rows) {
            let bytes = ServerMessage::Close(Close {
                reason,
                detail: String::new(),
            })
            .encode()
            .unwrap();
            // Version header (2 bytes), variant Close (4), then the reason.
            assert_eq!(bytes[3], *index, "{reason:?}");
            assert_eq!(format!("{reason:?}"), *name);
            assert_eq!(close_code_for(reason), *code, "{reason:?}");
        }
    }
}
