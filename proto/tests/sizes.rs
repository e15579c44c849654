//! Measured wire sizes for a typical room (4 players, 8-byte inputs, a match
//! 10 minutes in, i.e. tick 36 000), and the redundancy actually carried at
//! several round trips. The numbers are quoted in docs/protocol.md; each
//! assertion spells out the byte count it expects. Run with `--nocapture`
//! to print the table.

mod common;

use std::time::Duration;

use common::{LinkConfig, Sim};
use lockstep_proto::{
    BundleDatagram, ClientMessage, Close, CloseReason, DesyncNotice, HashReport, InputDatagram,
    Join, PROTOCOL_VERSION, Ping, PlayerHash, PlayerInput, Pong, RoomConfig, ServerMessage, Slot,
    TickBundle, Verdict, Welcome,
};

const TICK: u64 = 36_000;
const HASH: u64 = 0x9E37_79B9_7F4A_7C15;

fn bundle(tick: u64) -> TickBundle {
    TickBundle {
        tick,
        inputs: (0..4)
            .map(|s| PlayerInput {
                slot: Slot(s),
                input: vec![0xA5; 8],
                substituted: false,
            })
            .collect(),
    }
}

fn input(k: u64) -> ClientMessage {
    ClientMessage::Input(InputDatagram {
        slot: Slot(1),
        ack_bundle: Some(TICK),
        first_tick: TICK + 5 - k,
        inputs: vec![vec![0x5A; 8]; k as usize],
    })
}

fn bundles(n: u64) -> ServerMessage {
    ServerMessage::Bundles(BundleDatagram {
        ack_input: Some(TICK + 4),
        bundles: (TICK - n + 1..=TICK).map(bundle).collect(),
    })
}

fn len_c(m: &ClientMessage) -> usize {
    m.encode().unwrap().len()
}

fn len_s(m: &ServerMessage) -> usize {
    m.encode().unwrap().len()
}

#[test]
fn message_sizes_for_a_4_player_room_with_8_byte_inputs() {
    // Every message: 2 bytes version + 1 byte variant tag. Varints: below 251
    // take 1 byte, up to 65 535 take 3, up to 2^32 take 5, else 9.
    let join = ClientMessage::Join(Join {
        protocol_version: PROTOCOL_VERSION,
        room: "arena".into(),
        player_name: "player-1".into(),
        token: None,
        rejoin: None,
    });
    // 3 + version 1 + (1 + 5) + (1 + 8) + no token 1 + no rejoin 1
    assert_eq!(len_c(&join), 21);
    // 3 + slot 1 + ack Some 1+3 + first tick 3 + count 1 + k × (len 1 + 8)
    assert_eq!(len_c(&input(1)), 21);
    assert_eq!(len_c(&input(5)), 57);
    assert_eq!(len_c(&input(16)), 156);
    let report = ClientMessage::HashReport(HashReport {
        tick: TICK,
        hash: HASH,
        body_hashes: None,
    });
    // 3 + tick 3 + hash 9 + None 1
    assert_eq!(len_c(&report), 16);
    let bodies = ClientMessage::HashReport(HashReport {
        tick: TICK,
        hash: HASH,
        body_hashes: Some(vec![HASH; 100]),
    });
    // 16 + count 1 + 100 × 9
    assert_eq!(len_c(&bodies), 917);
    assert_eq!(len_c(&ClientMessage::Pong(Pong { nonce: 1234 })), 6);
    assert_eq!(len_c(&ClientMessage::Leave), 3);

    let welcome = ServerMessage::Welcome(Welcome {
        slot: Slot(1),
        tick_rate: 60,
        input_delay: 4,
        input_window: 64,
        max_input_bytes: 64,
        start_tick: 0,
        scene_hash: HASH,
        scene: vec![0; 2048],
        resume: None,
        rules: None,
        seed: 0,
        rejoin: None,
    });
    // 3 + six 1-byte fields + scene hash 9 + scene length 3 + 2048 + no
    // resume 1 + no rules 1 + seed 1 + no rejoin credential 1
    assert_eq!(len_s(&welcome), 25 + 2048);
    // One bundle: tick 3 + count 1 + 4 × (slot 1 + len 1 + 8 + flag 1) = 48.
    // Datagram: 3 + ack Some 1+3 + count 1 + n × 48.
    assert_eq!(len_s(&bundles(1)), 56);
    assert_eq!(len_s(&bundles(4)), 200);
    assert_eq!(len_s(&bundles(8)), 392);
    assert_eq!(len_s(&bundles(16)), 776);
    let desync = ServerMessage::Desync(DesyncNotice {
        tick: TICK,
        hashes: (0..4)
            .map(|s| PlayerHash {
                slot: Slot(s),
                hash: Some(if s == 2 { HASH ^ 1 } else { HASH }),
            })
            .collect(),
        verdict: Verdict::Majority {
            majority_hash: HASH,
            wrong: vec![Slot(2)],
        },
    });
    // 3 + tick 3 + count 1 + 4 × (slot 1 + Some 1 + 9) + verdict (1 + 9 + 1 + 1)
    assert_eq!(len_s(&desync), 63);
    assert_eq!(len_s(&ServerMessage::Ping(Ping { nonce: 1234 })), 6);
    let close = ServerMessage::Close(Close {
        reason: CloseReason::TimedOut,
        detail: "nothing heard from the client".into(),
    });
    // 3 + reason 1 + length 1 + 29
    assert_eq!(len_s(&close), 34);

    eprintln!("| message | bytes |");
    eprintln!("|---|---|");
    for (name, n) in [
        ("Join", len_c(&join)),
        ("Input, 1 input", len_c(&input(1))),
        ("Input, 5 inputs", len_c(&input(5))),
        ("Input, 16 inputs (cap)", len_c(&input(16))),
        ("HashReport", len_c(&report)),
        ("HashReport + 100 body hashes", len_c(&bodies)),
        (
            "Pong / Ping",
            len_c(&ClientMessage::Pong(Pong { nonce: 1234 })),
        ),
        ("Leave", 3),
        ("Welcome + 2 KiB scene", len_s(&welcome)),
        ("Bundles, 1 bundle", len_s(&bundles(1))),
        ("Bundles, 4 bundles", len_s(&bundles(4))),
        ("Bundles, 8 bundles", len_s(&bundles(8))),
        ("Bundles, 16 bundles (cap)", len_s(&bundles(16))),
        ("DesyncNotice", len_s(&desync)),
        ("Close", len_s(&close)),
    ] {
        eprintln!("| {name} | {n} |");
    }
}

/// Steady-state traffic of one client in a 4-player room on a clean link.
fn steady_state(one_way_ms: u64) -> (f64, f64, f64, f64) {
    let links = (0..4)
        .map(|_| (LinkConfig::clean(one_way_ms), LinkConfig::clean(one_way_ms)))
        .collect();
    let mut cfg = RoomConfig::new("arena", vec![], 0);
    // Inputs must arrive on time at every measured round trip.
    cfg.input_delay = 16;
    let mut sim = Sim::new(cfg, links, 17);
    sim.run_until_delivered(1200, Duration::from_secs(40));
    let c = &sim.clients[0];
    let secs = sim.now.as_secs_f64();
    (
        c.bundles_received as f64 / c.bundle_datagrams as f64,
        c.bundle_bytes as f64 / secs,
        c.inputs_sent as f64 / c.input_datagrams as f64,
        c.input_bytes as f64 / secs,
    )
}

#[test]
fn redundancy_grows_with_the_round_trip_until_the_cap() {
    eprintln!("| RTT | bundles/datagram | down B/s | inputs/datagram | up B/s |");
    eprintln!("|---|---|---|---|---|");
    let mut per_datagram = Vec::new();
    for one_way in [10, 25, 50, 100, 200] {
        let (b, down, i, up) = steady_state(one_way);
        eprintln!(
            "| {} ms | {b:.1} | {down:.0} | {i:.1} | {up:.0} |",
            2 * one_way
        );
        per_datagram.push(b);
        // A bundle is repeated in every datagram until its ack returns one
        // round trip later: ceil(RTT / tick period) copies, at most the cap
        // (3% slack for the start of the match, before the pipe is full).
        let rtt_ticks = (2 * one_way) as f64 * 60.0 / 1000.0;
        assert!(
            b >= rtt_ticks.min(16.0) * 0.97 && b <= (rtt_ticks + 1.0).min(16.0) + 0.05,
            "RTT {} ms: {b}",
            2 * one_way
        );
    }
    assert!(per_datagram.windows(2).all(|w| w[0] <= w[1]));
}

#[test]
fn worst_case_datagrams_fit_the_datagram_limit() {
    use lockstep_proto::{
        MAX_DATAGRAM_BYTES, MAX_INPUT_BYTES, MAX_INPUTS_PER_DATAGRAM, MAX_PLAYERS,
    };
    // Largest room, largest inputs, ticks needing 9-byte varints.
    let far = u64::MAX - 100;
    let full = TickBundle {
        tick: far,
        inputs: (0..MAX_PLAYERS as u8)
            .map(|s| PlayerInput {
                slot: Slot(s),
                input: vec![0xFF; MAX_INPUT_BYTES],
                substituted: true,
            })
            .collect(),
    };
    let one = ServerMessage::Bundles(BundleDatagram {
        ack_input: Some(far),
        bundles: vec![full],
    });
    // 3 + ack 1+9 + count 1 + (tick 9 + count 1 + 16 × 67)
    assert_eq!(len_s(&one), 1096);
    let inputs = ClientMessage::Input(InputDatagram {
        slot: Slot(15),
        ack_bundle: Some(far),
        first_tick: far,
        inputs: vec![vec![0xFF; MAX_INPUT_BYTES]; MAX_INPUTS_PER_DATAGRAM],
    });
    // 3 + slot 1 + ack 1+9 + first tick 9 + count 1 + 16 × 65
    assert_eq!(len_c(&inputs), 1064);
    assert!(len_s(&one) <= MAX_DATAGRAM_BYTES && len_c(&inputs) <= MAX_DATAGRAM_BYTES);
}
