//! The decoders against hostile input: random bytes, random bodies behind a
//! valid header, every truncation, bit flips, byte mutations, oversized and
//! lying length prefixes. Nothing may panic; anything accepted must satisfy
//! every bound and survive a re-encode.

mod common;

use common::Rng;
use lockstep_proto::{
    BundleDatagram, ClientMessage, Close, CloseReason, DecodeError, DesyncNotice, HashReport,
    InputDatagram, Join, MAX_BODY_HASHES, MAX_INPUT_BYTES, MAX_MESSAGE_BYTES, PROTOCOL_VERSION,
    Ping, PlayerHash, PlayerInput, Pong, ServerMessage, Slot, TickBundle, Verdict, Welcome,
};

fn bundle(tick: u64, players: u8) -> TickBundle {
    TickBundle {
        tick,
        inputs: (0..players)
            .map(|s| PlayerInput {
                slot: Slot(s),
                input: vec![s; 8],
                substituted: s == 1,
            })
            .collect(),
    }
}

fn client_samples() -> Vec<ClientMessage> {
    vec![
        ClientMessage::Join(Join {
            protocol_version: PROTOCOL_VERSION,
            room: "arena".into(),
            player_name: "Zoë".into(),
            token: None,
            rejoin: None,
        }),
        ClientMessage::Input(InputDatagram {
            slot: Slot(3),
            ack_bundle: Some(36_000),
            first_tick: 36_001,
            inputs: vec![vec![1; 8]; 5],
        }),
        ClientMessage::Input(InputDatagram {
            slot: Slot(0),
            ack_bundle: None,
            first_tick: 0,
            inputs: vec![vec![0xFF; MAX_INPUT_BYTES]; 16],
        }),
        ClientMessage::HashReport(HashReport {
            tick: 36_000,
            hash: 0xDEAD_BEEF_F00D_CAFE,
            body_hashes: None,
        }),
        ClientMessage::HashReport(HashReport {
            tick: 7,
            hash: 1,
            body_hashes: Some((0..100).collect()),
        }),
        ClientMessage::Pong(Pong { nonce: u64::MAX }),
        ClientMessage::Leave,
    ]
}

fn server_samples() -> Vec<ServerMessage> {
    vec![
        ServerMessage::Welcome(Welcome {
            slot: Slot(2),
            tick_rate: 60,
            input_delay: 4,
            input_window: 64,
            max_input_bytes: 64,
            start_tick: 0,
            scene_hash: 99,
            scene: (0..=255).collect(),
            resume: None,
            rules: None,
            seed: 0,
            rejoin: Some(lockstep_proto::RejoinCredential([0xa5; 32])),
        }),
        ServerMessage::Bundles(BundleDatagram {
            ack_input: Some(36_004),
            bundles: (35_995..36_001).map(|t| bundle(t, 4)).collect(),
        }),
        ServerMessage::Bundles(BundleDatagram {
            ack_input: None,
            bundles: vec![bundle(0, 1), bundle(9, 2)],
        }),
        ServerMessage::Desync(DesyncNotice {
            tick: 300,
            hashes: (0..4)
                .map(|s| PlayerHash {
                    slot: Slot(s),
                    hash: if s == 3 {
                        None
                    } else {
                        Some(u64::from(s) + 10)
                    },
                })
                .collect(),
            verdict: Verdict::Majority {
                majority_hash: 10,
                wrong: vec![Slot(1), Slot(2)],
            },
        }),
        ServerMessage::Desync(DesyncNotice {
            tick: 1,
            hashes: vec![],
            verdict: Verdict::Undecided,
        }),
        ServerMessage::Ping(Ping { nonce: 5 }),
        ServerMessage::Close(Close {
            reason: CloseReason::FellBehind,
            detail: "bundle 4 is gone".into(),
        }),
    ]
}

/// Tally of outcomes, to show the fuzzing reached every layer.
#[derive(Debug, Default)]
struct Tally {
    ok: u32,
    too_large: u32,
    truncated: u32,
    wrong_version: u32,
    malformed: u32,
    trailing: u32,
    non_canonical: u32,
    invalid: u32,
}

impl Tally {
    fn add<T>(&mut self, r: &Result<T, DecodeError>) {
        match r {
            Ok(_) => self.ok += 1,
            Err(DecodeError::TooLarge { .. }) => self.too_large += 1,
            Err(DecodeError::Truncated { .. }) => self.truncated += 1,
            Err(DecodeError::WrongVersion { .. }) => self.wrong_version += 1,
            Err(DecodeError::Malformed(_)) => self.malformed += 1,
            Err(DecodeError::TrailingBytes { .. }) => self.trailing += 1,
            Err(DecodeError::NotCanonical) => self.non_canonical += 1,
            Err(DecodeError::Invalid(_)) => self.invalid += 1,
        }
    }
}

/// Decodes `bytes` both ways; anything accepted must re-encode and decode
/// to itself.
fn check(bytes: &[u8], client: &mut Tally, server: &mut Tally) {
    let c = ClientMessage::decode(bytes);
    if let Ok(m) = &c {
        assert_eq!(m.validate(), Ok(()));
        let again = m.encode().expect("accepted message re-encodes");
        assert_eq!(again, bytes, "accepted bytes are the message's encoding");
        assert_eq!(&ClientMessage::decode(&again).unwrap(), m);
    }
    client.add(&c);
    let s = ServerMessage::decode(bytes);
    if let Ok(m) = &s {
        assert_eq!(m.validate(), Ok(()));
        let again = m.encode().expect("accepted message re-encodes");
        assert_eq!(again, bytes, "accepted bytes are the message's encoding");
        assert_eq!(&ServerMessage::decode(&again).unwrap(), m);
    }
    server.add(&s);
}

/// Every sample encoded, with whether it is a client message.
fn encoded_samples() -> Vec<(bool, Vec<u8>)> {
    client_samples()
        .iter()
        .map(|m| (true, m.encode().unwrap()))
        .chain(
            server_samples()
                .iter()
                .map(|m| (false, m.encode().unwrap())),
        )
        .collect()
}

#[test]
fn every_sample_round_trips() {
    for m in client_samples() {
        assert_eq!(ClientMessage::decode(&m.encode().unwrap()).unwrap(), m);
    }
    for m in server_samples() {
        assert_eq!(ServerMessage::decode(&m.encode().unwrap()).unwrap(), m);
    }
}

#[test]
fn random_bytes_never_panic_and_die_at_the_version_header() {
    let mut rng = Rng::new(0x00F0_F0F0);
    let (mut c, mut s) = (Tally::default(), Tally::default());
    for _ in 0..20_000 {
        let len = rng.below(400) as usize;
        check(&rng.bytes(len), &mut c, &mut s);
    }
    eprintln!("random bytes: client {c:?}\nserver {s:?}");
    // Only 1 in 65 536 random headers is the right version.
    assert!(c.wrong_version > 19_800, "{c:?}");
    assert!(c.truncated > 0, "{c:?}");
}

#[test]
fn random_bodies_behind_a_valid_header_never_panic() {
    let mut rng = Rng::new(42);
    let (mut c, mut s) = (Tally::default(), Tally::default());
    for _ in 0..30_000 {
        let len = rng.below(300) as usize;
        let mut bytes = PROTOCOL_VERSION.to_le_bytes().to_vec();
        bytes.extend(rng.bytes(len));
        check(&bytes, &mut c, &mut s);
    }
    eprintln!("random bodies: client {c:?}\nserver {s:?}");
    assert_eq!(c.ok + c.malformed + c.trailing + c.invalid, 30_000, "{c:?}");
    assert!(c.malformed > 20_000, "{c:?}");
    assert!(c.trailing > 0 && s.trailing > 0, "{c:?} {s:?}");
}

#[test]
fn every_truncation_of_a_valid_message_is_refused() {
    let (mut c, mut s) = (Tally::default(), Tally::default());
    let mut cases = 0;
    for (is_client, bytes) in encoded_samples() {
        for cut in 0..bytes.len() {
            let prefix = &bytes[..cut];
            // A prefix of one side's message can be a valid message of the
            // other side (a server ping is a client pong), never of its own.
            let refused = if is_client {
                ClientMessage::decode(prefix).is_err()
            } else {
                ServerMessage::decode(prefix).is_err()
            };
            assert!(refused, "prefix {cut} accepted");
            check(prefix, &mut c, &mut s);
            cases += 1;
        }
    }
    eprintln!("{cases} truncations: client {c:?}\nserver {s:?}");
    assert!(cases > 1500, "{cases}");
}

#[test]
fn bit_flips_and_byte_mutations_never_panic() {
    let mut rng = Rng::new(0xB17F);
    let (mut c, mut s) = (Tally::default(), Tally::default());
    let samples = encoded_samples();
    for (_, bytes) in &samples {
        for _ in 0..3_000 {
            let mut m = bytes.clone();
            match rng.below(4) {
                0 | 1 => {
                    for _ in 0..=rng.below(3) {
                        let bit = rng.below(m.len() as u64 * 8);
                        m[(bit / 8) as usize] ^= 1 << (bit % 8);
                    }
                }
                2 => {
                    let i = rng.below(m.len() as u64 + 1) as usize;
                    m.insert(i, rng.next_u64() as u8);
                }
                _ => {
                    let i = rng.below(m.len() as u64) as usize;
                    m[i] = rng.next_u64() as u8;
                }
            }
            check(&m, &mut c, &mut s);
        }
    }
    let total = samples.len() as u32 * 3_000;
    eprintln!("{total} mutations: client {c:?}\nserver {s:?}");
    assert_eq!(
        c.ok + c.too_large + c.truncated + c.wrong_version + c.malformed + c.trailing + c.invalid,
        total
    );
    // Flips inside payload bytes still decode; flips in tags and lengths do not.
    assert!(c.ok > 1_000 && s.ok > 1_000, "{c:?} {s:?}");
    assert!(c.malformed > 1_000 && s.malformed > 1_000, "{c:?} {s:?}");
    assert!(c.wrong_version > 0 && c.trailing > 0, "{c:?}");
    assert!(s.invalid > 0, "{s:?}");
}

#[test]
fn oversized_input_is_refused_before_decoding() {
    let mut big = PROTOCOL_VERSION.to_le_bytes().to_vec();
    big.resize(MAX_MESSAGE_BYTES + 1, 0);
    assert!(matches!(
        ClientMessage::decode(&big),
        Err(DecodeError::TooLarge { len, max }) if len == MAX_MESSAGE_BYTES + 1 && max == MAX_MESSAGE_BYTES
    ));
    assert!(matches!(
        ServerMessage::decode(&big),
        Err(DecodeError::TooLarge { .. })
    ));
}

#[test]
fn lying_length_prefixes_fail_without_allocating_their_claim() {
    // Join { protocol_version: 1, room: <length 2^40>, ... }: varint 253
    // announces a u64 length.
    let mut bytes = PROTOCOL_VERSION.to_le_bytes().to_vec();
    bytes.extend([0, 1, 253]);
    bytes.extend((1u64 << 40).to_le_bytes());
    bytes.extend(b"arena");
    assert!(matches!(
        ClientMessage::decode(&bytes),
        Err(DecodeError::Malformed(_))
    ));
    // An input datagram claiming 2^60 inputs, and a hash report claiming
    // u64::MAX body hashes.
    let mut bytes = PROTOCOL_VERSION.to_le_bytes().to_vec();
    bytes.extend([1, 0, 0, 0, 253]);
    bytes.extend((1u64 << 60).to_le_bytes());
    bytes.extend([1, 2]);
    assert!(matches!(
        ClientMessage::decode(&bytes),
        Err(DecodeError::Malformed(_))
    ));
    let mut bytes = PROTOCOL_VERSION.to_le_bytes().to_vec();
    bytes.extend([2, 0, 0, 1, 253]);
    bytes.extend(u64::MAX.to_le_bytes());
    assert!(matches!(
        ClientMessage::decode(&bytes),
        Err(DecodeError::Malformed(_))
    ));
    // Within bounds on the wire but over the protocol's bound: refused as a
    // violation after decoding.
    let over = ClientMessage::HashReport(HashReport {
        tick: 1,
        hash: 2,
        body_hashes: Some(vec![0; MAX_BODY_HASHES + 1]),
    });
    assert!(over.encode().is_err());
}

#[test]
fn wrong_version_and_trailing_bytes_are_named() {
    let mut bytes = ClientMessage::Leave.encode().unwrap();
    bytes.push(0);
    assert!(matches!(
        ClientMessage::decode(&bytes),
        Err(DecodeError::TrailingBytes { extra: 1 })
    ));
    let mut bytes = ClientMessage::Leave.encode().unwrap();
    bytes[..2].copy_from_slice(&(PROTOCOL_VERSION + 1).to_le_bytes());
    assert!(matches!(
        ClientMessage::decode(&bytes),
        Err(DecodeError::WrongVersion { found, expected })
            if found == PROTOCOL_VERSION + 1 && expected == PROTOCOL_VERSION
    ));
    assert!(matches!(
        ServerMessage::decode(&[1]),
        Err(DecodeError::Truncated { len: 1 })
    ));
}
