//! The byte layout docs/protocol.md ("Field by field") gives a client written
//! in another language, checked byte for byte against the codec.

use lockstep_proto::{BundleDatagram, Ping, Pong, Welcome};
use lockstep_proto::{
    ClientMessage, Close, CloseReason, DesyncNotice, HashReport, InputDatagram, Join, PlayerHash,
    PlayerInput, ServerMessage, Slot, TickBundle, Verdict,
};

/// The version header: protocol version 4, little-endian.
const V: [u8; 2] = [4, 0];

fn with_header(body: &[u8]) -> Vec<u8> {
    [&V[..], body].concat()
}

#[test]
fn client_messages_have_the_documented_bytes() {
    let join = ClientMessage::Join(Join {
        protocol_version: 4,
        room: "ab".into(),
        player_name: "p".into(),
        token: None,
        rejoin: None,
    });
    // variant 0; u16 varint 4; string = varint length + UTF-8; string;
    // no token: Option tag 0; no rejoin credential: Option tag 0.
    assert_eq!(
        join.encode().unwrap(),
        with_header(&[0, 4, 2, b'a', b'b', 1, b'p', 0, 0])
    );
    let join = ClientMessage::Join(Join {
        protocol_version: 4,
        room: "ab".into(),
        player_name: "p".into(),
        token: Some("0f".into()),
        rejoin: Some(lockstep_proto::RejoinCredential([7; 32])),
    });
    // A token: Option tag 1, then the string; a rejoin credential: Option
    // tag 1, then its 32 bytes raw (no length).
    let mut bytes = vec![0, 4, 2, b'a', b'b', 1, b'p', 1, 2, b'0', b'f', 1];
    bytes.extend_from_slice(&[7; 32]);
    assert_eq!(join.encode().unwrap(), with_header(&bytes));
    let probe = ServerMessage::Probe(lockstep_proto::Probe {
        tick: 300,
        ask: lockstep_proto::ProbeAsk::Fields { bodies: vec![5] },
    });
    // variant 5; tick 300 (251, u16 LE); ask variant 1; 1 body: u32 5.
    assert_eq!(
        probe.encode().unwrap(),
        with_header(&[5, 251, 0x2c, 0x01, 1, 1, 5])
    );
    let reply = ClientMessage::ProbeReply(lockstep_proto::ProbeReply {
        tick: 7,
        answer: lockstep_proto::ProbeAnswer::Unavailable,
    });
    // variant 5; tick 7; answer variant 0.
    assert_eq!(reply.encode().unwrap(), with_header(&[5, 7, 0]));

    let input = ClientMessage::Input(InputDatagram {
        slot: Slot(3),
        ack_bundle: Some(300),
        first_tick: 70_000,
        inputs: vec![vec![0x9c, 0x64, 0x01]],
    });
    // variant 1; slot u8 raw; Option tag 1 + varint 300 (251, u16 LE);
    // varint 70 000 (252, u32 LE); 1 input: length 3, the raw bytes.
    assert_eq!(
        input.encode().unwrap(),
        with_header(&[
            1, 3, 1, 251, 0x2c, 0x01, 252, 0x70, 0x11, 0x01, 0x00, 1, 3, 0x9c, 0x64, 0x01
        ])
    );

    let hash = ClientMessage::HashReport(HashReport {
        tick: 5,
        hash: 0x0102_0304_0506_0708,
        body_hashes: None,
    });
    // variant 2; tick; hash varint 253 + u64 LE; Option tag 0.
    assert_eq!(
        hash.encode().unwrap(),
        with_header(&[2, 5, 253, 8, 7, 6, 5, 4, 3, 2, 1, 0])
    );
    let pong = ClientMessage::Pong(Pong { nonce: 250 });
    assert_eq!(pong.encode().unwrap(), with_header(&[3, 250]));
    assert_eq!(ClientMessage::Leave.encode().unwrap(), with_header(&[4]));
}

#[test]
fn server_messages_have_the_documented_bytes() {
    let welcome = ServerMessage::Welcome(Welcome {
        slot: Slot(1),
        tick_rate: 60,
        input_delay: 4,
        input_window: 64,
        max_input_bytes: 64,
        start_tick: 0,
        scene_hash: 17,
        scene: b"s".to_vec(),
        resume: None,
        rules: None,
        seed: 0,
        rejoin: None,
    });
    // variant 0; slot u8; tick rate, delay, window varints; max input
    // bytes u8 raw; start tick; scene hash; scene = length + bytes; no
    // resume: Option tag 0; no rules: Option tag 0; seed varint 0; no
    // rejoin credential: Option tag 0.
    assert_eq!(
        welcome.encode().unwrap(),
        with_header(&[0, 1, 60, 4, 64, 64, 0, 17, 1, b's', 0, 0, 0, 0])
    );
    let bundles = ServerMessage::Bundles(BundleDatagram {
        ack_input: None,
        bundles: vec![TickBundle {
            tick: 9,
            inputs: vec![
                PlayerInput {
                    slot: Slot(0),
                    input: vec![7],
                    substituted: false,
                },
                PlayerInput {
                    slot: Slot(2),
                    input: vec![],
                    substituted: true,
                },
            ],
        }],
    });
    // variant 1; ack None; 1 bundle: tick 9, 2 inputs (slot, length +
    // bytes, bool).
    assert_eq!(
        bundles.encode().unwrap(),
        with_header(&[1, 0, 1, 9, 2, 0, 1, 7, 0, 2, 0, 1])
    );

    let desync = ServerMessage::Desync(DesyncNotice {
        tick: 4,
        hashes: vec![
            PlayerHash {
                slot: Slot(0),
                hash: Some(6),
            },
            PlayerHash {
                slot: Slot(1),
                hash: None,
            },
        ],
        verdict: Verdict::Majority {
            majority_hash: 6,
            wrong: vec![Slot(1)],
        },
    });
    // variant 2; tick; 2 hashes (slot, Option); verdict variant 0
    // (Majority): hash, 1 wrong slot.
    assert_eq!(
        desync.encode().unwrap(),
        with_header(&[2, 4, 2, 0, 1, 6, 1, 0, 0, 6, 1, 1])
    );
    let undecided = ServerMessage::Desync(DesyncNotice {
        tick: 4,
        hashes: vec![],
        verdict: Verdict::Undecided,
    });
    assert_eq!(undecided.encode().unwrap(), with_header(&[2, 4, 0, 1]));

    let ping = ServerMessage::Ping(Ping { nonce: 1 });
    assert_eq!(ping.encode().unwrap(), with_header(&[3, 1]));

    // Close: variant 4; reason (its index in the documented list); detail.
    let reasons = [
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
    ];
    for (i, reason) in reasons.into_iter().enumerate() {
        let close = ServerMessage::Close(Close {
            reason,
            detail: "x".into(),
        });
        assert_eq!(close.encode().unwrap(), with_header(&[4, i as u8, 1, b'x']));
    }
}
