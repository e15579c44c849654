//! Every refusal's close reason and text, and the violations a decoder
//! names: what a client (or an operator reading a log) is told.

use lockstep_proto::{
    ClientMessage, CloseReason, DecodeError, JoinError, ProbeAnswer, ProbeReply, Violation,
};

/// Every join refusal the room gives: its `Close` reason and detail.
#[test]
fn every_join_refusal_has_its_close_reason_and_detail() {
    let table: Vec<(JoinError, CloseReason, &str)> = vec![
        (
            JoinError::VersionMismatch {
                client: 3,
                server: 4,
            },
            CloseReason::VersionMismatch,
            "client protocol version 3, server 4",
        ),
        (
            JoinError::WrongRoom("lobby".into()),
            CloseReason::WrongRoom,
            "no room named \"lobby\" here",
        ),
        (
            JoinError::RoomFull(8),
            CloseReason::RoomFull,
            "room is full (8 players)",
        ),
        (
            JoinError::MatchInProgress,
            CloseReason::MatchInProgress,
            "match already in progress",
        ),
        (
            JoinError::SeatTaken(3),
            CloseReason::SeatTaken,
            "seat 3 is taken",
        ),
        (
            JoinError::NoSuchSeat(12),
            CloseReason::BadToken,
            "the join token's seat 12 is not in this room",
        ),
        (
            JoinError::TokenUsed,
            CloseReason::BadToken,
            "this join token was already used in this match; its holder rejoins with the rejoin credential of its welcome",
        ),
        (
            JoinError::NotReserved(2),
            CloseReason::BadToken,
            "seat 2 is no longer reserved for a rejoin",
        ),
        (
            JoinError::JoinBusy,
            CloseReason::MatchInProgress,
            "another player is joining the running match; try again",
        ),
        (
            JoinError::NoAgreedState,
            CloseReason::MatchInProgress,
            "no agreed state to join the running match from yet; try again",
        ),
    ];
    for (error, reason, detail) in table {
        let close = error.to_close();
        assert_eq!((close.reason, close.detail.as_str()), (reason, detail));
        assert!(close.detail.len() <= lockstep_proto::MAX_DETAIL_BYTES);
    }
}

/// A join whose token is longer than any token is refused by the decoder
/// as a long token (it used to be called a long name), with the lengths.
#[test]
fn a_long_token_is_named_as_such() {
    let max = lockstep_proto::token::MAX_TOKEN_BYTES;
    assert_eq!(max, 344);
    // Header, Join, version 4, room "r", empty name, Some(token of 345
    // bytes: varint 251 + u16 LE), no rejoin credential.
    let mut bytes = vec![4, 0, 0, 4, 1, b'r', 0, 1, 251];
    bytes.extend_from_slice(&345u16.to_le_bytes());
    bytes.extend(std::iter::repeat_n(b'a', 345));
    bytes.push(0);
    let e = ClientMessage::decode(&bytes).expect_err("refused");
    assert!(
        matches!(
            e,
            DecodeError::Invalid(Violation::TokenTooLong { len: 345, max: 344 })
        ),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        "protocol violation: join token of 345 bytes exceeds 344"
    );
}

/// Snapshot pieces and totals over their bounds are named as snapshots
/// (they used to be called scenes), with the lengths.
#[test]
fn an_oversized_snapshot_is_named_as_such() {
    let piece = lockstep_proto::MAX_SNAPSHOT_CHUNK_BYTES;
    let reply = |total: u32, len: usize| {
        ClientMessage::ProbeReply(ProbeReply {
            tick: 1,
            answer: ProbeAnswer::Snapshot {
                total,
                offset: 0,
                bytes: vec![0; len],
            },
        })
    };
    let e = reply(piece as u32 + 1, piece + 1).validate().unwrap_err();
    assert_eq!(
        e,
        Violation::SnapshotTooLarge {
            what: "piece",
            len: piece + 1,
            max: piece,
        }
    );
    assert_eq!(
        e.to_string(),
        format!("snapshot piece of {} bytes exceeds {piece}", piece + 1)
    );
    let total = lockstep_proto::MAX_PROBE_SNAPSHOT_BYTES;
    let e = reply(total as u32 + 1, 1).validate().unwrap_err();
    assert_eq!(
        e.to_string(),
        format!("snapshot total of {} bytes exceeds {total}", total + 1)
    );
    // The encoder refuses it too, so a compliant client never sends one.
    assert!(reply(piece as u32 + 1, piece + 1).encode().is_err());
}
