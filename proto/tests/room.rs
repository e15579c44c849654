//! The room driven by hand: inputs, substitution, lateness, rejections,
//! joins and datagram sizes, with exact ticks and times.

use std::time::Duration;

use lockstep_proto::{
    BundleDatagram, ClientMessage, CloseReason, HashReport, InputDatagram, Join, JoinError,
    LeaveReason, MAX_DATAGRAM_BYTES, MAX_INPUT_BYTES, MAX_PLAYERS, PROTOCOL_VERSION, PlayerId,
    Rejection, Room, RoomConfig, RoomEvent, ServerMessage, Slot, TickBundle, Transmit,
};

const MS: Duration = Duration::from_millis(1);

fn join_msg(name: &str) -> Join {
    Join {
        protocol_version: PROTOCOL_VERSION,
        room: "arena".into(),
        player_name: name.into(),
        token: None,
        rejoin: None,
    }
}

fn room_with(players: usize, config: RoomConfig) -> (Room, Vec<PlayerId>) {
    let mut room = Room::new(config).unwrap();
    let ids = (0..players)
        .map(|i| {
            room.join(Duration::ZERO, &join_msg(&format!("p{i}")))
                .unwrap()
        })
        .collect();
    room.start(Duration::ZERO).unwrap();
    drain(&mut room);
    (room, ids)
}

fn room(players: usize) -> (Room, Vec<PlayerId>) {
    room_with(players, RoomConfig::new("arena", vec![], 1))
}

fn drain(room: &mut Room) -> (Vec<Transmit>, Vec<RoomEvent>) {
    (
        std::iter::from_fn(|| room.poll_transmit()).collect(),
        std::iter::from_fn(|| room.poll_event()).collect(),
    )
}

fn input(id: PlayerId, first_tick: u64, inputs: Vec<Vec<u8>>) -> ClientMessage {
    ClientMessage::Input(InputDatagram {
        slot: id.slot,
        ack_bundle: None,
        first_tick,
        inputs,
    })
}

/// Time at which `tick` has just closed.
fn after(room: &Room, tick: u64) -> Duration {
    room.config().deadline_offset(tick)
}

fn closed(events: &[RoomEvent]) -> Vec<TickBundle> {
    events
        .iter()
        .filter_map(|e| match e {
            RoomEvent::TickClosed(b) => Some(b.clone()),
            _ => None,
        })
        .collect()
}

#[test]
fn a_missing_input_is_replaced_by_the_last_input_and_flagged() {
    let (mut room, ids) = room(2);
    for tick in 0..6u64 {
        room.handle_message(MS, ids[0], input(ids[0], tick, vec![vec![10 + tick as u8]]))
            .unwrap();
        if tick != 3 && tick != 4 {
            room.handle_message(MS, ids[1], input(ids[1], tick, vec![vec![20 + tick as u8]]))
                .unwrap();
        }
    }
    room.handle_timeout(after(&room, 5));
    let (_, events) = drain(&mut room);
    let bundles = closed(&events);
    assert_eq!(bundles.len(), 6);
    let p1: Vec<(u8, bool)> = bundles
        .iter()
        .map(|b| (b.inputs[1].input[0], b.inputs[1].substituted))
        .collect();
    assert_eq!(
        p1,
        vec![
            (20, false),
            (21, false),
            (22, false),
            (22, true),
            (22, true),
            (25, false)
        ]
    );
    assert_eq!(bundles[3].substituted(), vec![Slot(1)]);
    assert!(bundles.iter().all(|b| !b.inputs[0].substituted));
    let st = room.player_stats(ids[1]).unwrap();
    assert_eq!((st.inputs_on_time, st.inputs_substituted), (4, 2));
}

#[test]
fn a_player_with_no_input_yet_gets_an_empty_substitute() {
    let (mut room, ids) = room(1);
    room.handle_timeout(after(&room, 0));
    let (_, events) = drain(&mut room);
    let b = &closed(&events)[0];
    assert_eq!(b.inputs[0].input, Vec::<u8>::new());
    assert!(b.inputs[0].substituted);
    assert_eq!(room.player_stats(ids[0]).unwrap().inputs_substituted, 1);
}

#[test]
fn a_late_input_after_its_tick_closed_is_ignored_and_counted_once() {
    let (mut room, ids) = room(1);
    room.handle_message(MS, ids[0], input(ids[0], 0, vec![vec![1]]))
        .unwrap();
    room.handle_timeout(after(&room, 1));
    drain(&mut room);
    assert!(room.bundle(1).unwrap().inputs[0].substituted);
    // Tick 1 arrives after closing; sent twice (redundancy), with tick 2.
    let late = input(ids[0], 1, vec![vec![9], vec![2]]);
    room.handle_message(after(&room, 1) + MS, ids[0], late.clone())
        .unwrap();
    room.handle_message(after(&room, 1) + MS, ids[0], late)
        .unwrap();
    let (_, events) = drain(&mut room);
    assert_eq!(
        events,
        vec![RoomEvent::LateInput {
            id: ids[0],
            tick: 1
        }]
    );
    let b1 = room.bundle(1).unwrap();
    assert_eq!(
        (b1.inputs[0].input.clone(), b1.inputs[0].substituted),
        (vec![1], true)
    );
    let st = room.player_stats(ids[0]).unwrap();
    assert_eq!(st.late_inputs, 1);
    // Second copy of tick 1 and of tick 2 are redundant.
    assert_eq!(st.redundant_inputs, 2);
    room.handle_timeout(after(&room, 2));
    assert_eq!(room.bundle(2).unwrap().inputs[0].input, vec![2]);
}

#[test]
fn an_input_for_another_players_slot_is_rejected_with_wrong_slot() {
    let (mut room, ids) = room(2);
    let forged = input(ids[1], 0, vec![vec![6]]);
    assert_eq!(
        room.handle_message(MS, ids[0], forged),
        Err(Rejection::WrongSlot {
            claimed: Slot(1),
            actual: Slot(0)
        })
    );
    room.handle_timeout(after(&room, 0));
    let (_, events) = drain(&mut room);
    assert!(closed(&events)[0].inputs[1].substituted, "nothing applied");
    let close = Rejection::WrongSlot {
        claimed: Slot(1),
        actual: Slot(0),
    }
    .to_close();
    assert_eq!(close.reason, CloseReason::ProtocolViolation);
}

#[test]
fn inputs_outside_the_window_oversized_or_conflicting_are_rejected_atomically() {
    let (mut room, ids) = room(1);
    let id = ids[0];
    // Window is 64 ticks from the next open tick (0): 0..=63.
    assert_eq!(
        room.handle_message(MS, id, input(id, 60, vec![vec![1]; 5])),
        Err(Rejection::TickOutOfWindow {
            tick: 64,
            lowest: 0,
            highest: 63
        })
    );
    assert_eq!(
        room.handle_message(
            MS,
            id,
            input(id, 0, vec![vec![1], vec![0; MAX_INPUT_BYTES + 1]])
        ),
        Err(Rejection::InputTooLarge {
            tick: 1,
            len: 65,
            max: 64
        })
    );
    room.handle_message(MS, id, input(id, 0, vec![vec![1], vec![2]]))
        .unwrap();
    assert_eq!(
        room.handle_message(MS, id, input(id, 1, vec![vec![3]])),
        Err(Rejection::InputConflict { tick: 1 })
    );
    room.handle_timeout(after(&room, 1));
    // After closing, a different copy of an on-time input is still a conflict.
    assert_eq!(
        room.handle_message(after(&room, 1), id, input(id, 0, vec![vec![5]])),
        Err(Rejection::InputConflict { tick: 0 })
    );
    // The first refused datagram's tick 60 was not stored.
    room.handle_timeout(after(&room, 60));
    assert!(room.bundle(60).unwrap().inputs[0].substituted);
    let mut small = RoomConfig::new("arena", vec![], 1);
    small.max_input_bytes = 4;
    let (mut room, ids) = room_with(1, small);
    assert_eq!(
        room.handle_message(MS, ids[0], input(ids[0], 0, vec![vec![0; 5]])),
        Err(Rejection::InputTooLarge {
            tick: 0,
            len: 5,
            max: 4
        })
    );
}

#[test]
fn hash_reports_for_unclosed_or_unplayed_ticks_and_conflicts_are_rejected() {
    let (mut room, ids) = room(2);
    let report = |tick, hash| {
        ClientMessage::HashReport(HashReport {
            tick,
            hash,
            body_hashes: None,
        })
    };
    assert_eq!(
        room.handle_message(MS, ids[0], report(0, 1)),
        Err(Rejection::HashForUnclosedTick {
            tick: 0,
            next_tick: 0
        })
    );
    room.handle_timeout(after(&room, 0));
    room.handle_message(after(&room, 0), ids[0], report(0, 1))
        .unwrap();
    assert_eq!(
        room.handle_message(after(&room, 0), ids[0], report(0, 2)),
        Err(Rejection::HashConflict { tick: 0 })
    );
    assert_eq!(
        room.handle_message(after(&room, 0), ids[0], ClientMessage::Join(join_msg("x"))),
        Err(Rejection::UnexpectedMessage("join"))
    );
    let ack = ClientMessage::Input(InputDatagram {
        slot: ids[0].slot,
        ack_bundle: Some(1),
        first_tick: 1,
        inputs: vec![],
    });
    assert_eq!(
        room.handle_message(after(&room, 0), ids[0], ack),
        Err(Rejection::AckFromFuture {
            ack: 1,
            next_tick: 1
        })
    );
}

#[test]
fn a_hash_compare_waits_for_all_then_times_out_with_the_missing_counted() {
    let (mut room, ids) = room(3);
    let report = |tick, hash| {
        ClientMessage::HashReport(HashReport {
            tick,
            hash,
            body_hashes: None,
        })
    };
    room.handle_timeout(after(&room, 0));
    room.handle_message(after(&room, 0), ids[0], report(0, 7))
        .unwrap();
    room.handle_message(after(&room, 0), ids[1], report(0, 8))
        .unwrap();
    assert_eq!(room.stats().ticks_compared, 0, "waits for slot 2");
    // The default timeout is 2 s after the tick closed.
    let timeout = after(&room, 0) + Duration::from_secs(2);
    assert!(room.poll_timeout().unwrap() <= timeout);
    room.handle_timeout(timeout);
    let (transmits, events) = drain(&mut room);
    let notice = events
        .iter()
        .find_map(|e| match e {
            RoomEvent::Desync(n) => Some(n.clone()),
            _ => None,
        })
        .unwrap();
    assert_eq!(notice.tick, 0);
    assert_eq!(
        notice.hashes.iter().map(|h| h.hash).collect::<Vec<_>>(),
        vec![Some(7), Some(8), None]
    );
    assert_eq!(notice.verdict, lockstep_proto::Verdict::Undecided);
    let to: Vec<_> = transmits
        .iter()
        .filter(|t| matches!(t.message, ServerMessage::Desync(_)))
        .map(|t| t.to)
        .collect();
    assert_eq!(to, ids);
    assert_eq!(room.player_stats(ids[2]).unwrap().missing_hash_reports, 1);
}

#[test]
fn joins_are_refused_when_full_wrong_version_wrong_room_or_started() {
    let mut cfg = RoomConfig::new("arena", vec![], 1);
    cfg.max_players = 2;
    let mut room = Room::new(cfg).unwrap();
    let a = room.join(Duration::ZERO, &join_msg("a")).unwrap();
    room.join(Duration::ZERO, &join_msg("b")).unwrap();
    assert_eq!(
        room.join(Duration::ZERO, &join_msg("c")),
        Err(JoinError::RoomFull(2))
    );
    let mut old = join_msg("d");
    old.protocol_version = PROTOCOL_VERSION + 1;
    assert_eq!(
        room.join(Duration::ZERO, &old),
        Err(JoinError::VersionMismatch {
            client: PROTOCOL_VERSION + 1,
            server: PROTOCOL_VERSION
        })
    );
    let mut elsewhere = join_msg("e");
    elsewhere.room = "lobby".into();
    assert_eq!(
        room.join(Duration::ZERO, &elsewhere),
        Err(JoinError::WrongRoom("lobby".into()))
    );
    // A seat freed in the lobby is reused under a new generation; the old
    // handle no longer reaches anyone.
    room.handle_message(MS, a, ClientMessage::Leave).unwrap();
    let a2 = room.join(MS, &join_msg("f")).unwrap();
    assert_eq!((a2.slot, a2.generation), (Slot(0), 1));
    assert_eq!(
        room.handle_message(MS, a, ClientMessage::Leave),
        Err(Rejection::UnknownPlayer(a))
    );
    room.start(MS).unwrap();
    assert_eq!(room.start(MS), Err(lockstep_proto::AlreadyStarted));
    room.handle_message(MS, a2, ClientMessage::Leave).unwrap();
    assert_eq!(
        room.join(MS, &join_msg("g")),
        Err(JoinError::MatchInProgress)
    );
    assert_eq!(
        JoinError::MatchInProgress.to_close().reason,
        CloseReason::MatchInProgress
    );
}

#[test]
fn the_welcome_carries_the_room_parameters_and_scene() {
    let mut room = Room::new(RoomConfig::new("arena", vec![1, 2, 3], 0x55)).unwrap();
    let id = room.join(Duration::ZERO, &join_msg("a")).unwrap();
    let (transmits, events) = drain(&mut room);
    let ServerMessage::Welcome(w) = &transmits[0].message else {
        panic!("expected a welcome");
    };
    assert_eq!(transmits[0].to, id);
    assert_eq!(
        (
            w.slot,
            w.tick_rate,
            w.input_delay,
            w.input_window,
            w.start_tick
        ),
        (Slot(0), 60, 4, 64, 0)
    );
    assert_eq!(
        (w.scene.clone(), w.scene_hash, w.max_input_bytes),
        (vec![1, 2, 3], 0x55, 64)
    );
    assert_eq!(
        events,
        vec![RoomEvent::PlayerJoined {
            id,
            name: "a".into()
        }]
    );
}

#[test]
fn a_client_that_never_acknowledges_falls_behind_and_is_dropped() {
    let mut cfg = RoomConfig::new("arena", vec![], 1);
    cfg.history_ticks = 32;
    cfg.silence_timeout = Duration::from_secs(60);
    let (mut room, ids) = room_with(2, cfg);
    for tick in 0..40u64 {
        // Player 0 acknowledges each bundle; player 1 never does.
        let msg = ClientMessage::Input(InputDatagram {
            slot: ids[0].slot,
            ack_bundle: tick.checked_sub(1),
            first_tick: tick,
            inputs: vec![vec![0]],
        });
        let now = after(&room, tick.saturating_sub(1));
        room.handle_message(now, ids[0], msg).unwrap();
        room.handle_timeout(after(&room, tick));
    }
    let (transmits, events) = drain(&mut room);
    let left = left(&events);
    // Bundle 0 leaves the 32-tick history when tick 32 closes.
    assert_eq!(left, vec![(ids[1], LeaveReason::FellBehind, 33)]);
    assert!(transmits.iter().any(|t| t.to == ids[1]
        && matches!(&t.message, ServerMessage::Close(c) if c.reason == CloseReason::FellBehind)));
    assert_eq!(room.player_count(), 1);
}

#[test]
fn bundle_datagrams_stay_under_the_mtu_in_the_largest_room() {
    let mut cfg = RoomConfig::new("arena", vec![], 1);
    cfg.max_players = MAX_PLAYERS as u8;
    let (mut room, ids) = room_with(MAX_PLAYERS, cfg);
    // Every player sends maximal inputs; nobody acknowledges any bundle, so
    // the room always has more to resend than fits.
    let mut sizes = Vec::new();
    for tick in 0..40u64 {
        for &id in &ids {
            let msg = input(id, tick, vec![vec![0xEE; MAX_INPUT_BYTES]]);
            room.handle_message(after(&room, tick.saturating_sub(1)), id, msg)
                .unwrap();
        }
        room.handle_timeout(after(&room, tick));
        let (transmits, _) = drain(&mut room);
        for t in transmits {
            if let ServerMessage::Bundles(BundleDatagram { bundles, .. }) = &t.message {
                let bytes = t.message.encode().unwrap();
                assert!(bytes.len() <= MAX_DATAGRAM_BYTES, "{} bytes", bytes.len());
                sizes.push((bundles.len(), bytes.len()));
            }
        }
    }
    // One full bundle: tick 1 + count 1 + 16 × (slot 1 + len 1 + 64 + flag 1)
    // = 1074 bytes, so exactly one fits and it is the newest. The datagram
    // adds version 2 + variant 1 + ack Some(t) 2 + bundle count 1 = 1080.
    // Even with 9-byte ticks and ack (after 2^32 ticks) it is 1096 < 1150.
    assert!(sizes.iter().all(|&(n, _)| n == 1));
    let largest = sizes.iter().map(|s| s.1).max().unwrap();
    assert_eq!(largest, 1080);
}

#[test]
fn pings_measure_rtt_and_silence_drops_the_player() {
    let (mut room, ids) = room(1);
    room.handle_timeout(Duration::ZERO);
    let (transmits, _) = drain(&mut room);
    let nonce = transmits
        .iter()
        .find_map(|t| match t.message {
            ServerMessage::Ping(p) => Some(p.nonce),
            _ => None,
        })
        .unwrap();
    room.handle_message(
        Duration::from_millis(80),
        ids[0],
        ClientMessage::Pong(lockstep_proto::Pong { nonce }),
    )
    .unwrap();
    assert_eq!(
        room.player_stats(ids[0]).unwrap().rtt,
        Some(Duration::from_millis(80))
    );
    // Heard at 80 ms; dropped at 5.08 s, not before.
    room.handle_timeout(Duration::from_millis(5079));
    assert_eq!(room.player_count(), 1);
    room.handle_timeout(Duration::from_millis(5080));
    assert_eq!(room.player_count(), 0);
    let (_, events) = drain(&mut room);
    assert!(events.iter().any(|e| matches!(
        e,
        RoomEvent::PlayerLeft {
            reason: LeaveReason::TimedOut,
            ..
        }
    )));
    // The room keeps ticking with nobody in it.
    let before = room.next_tick();
    room.handle_timeout(Duration::from_secs(6));
    assert!(room.next_tick() > before);
}

/// Plays `ticks` ticks at their deadlines: every present player sends its
/// input in time, and `report(slot, tick)` gives the hash each reports once
/// the tick closed (`None`: no report). Returns every event and transmit.
fn play_reporting(
    room: &mut Room,
    ids: &[PlayerId],
    ticks: u64,
    report: impl Fn(usize, u64) -> Option<u64>,
) -> (Vec<Transmit>, Vec<RoomEvent>) {
    let (mut transmits, mut events) = (Vec::new(), Vec::new());
    let mut gone = vec![false; ids.len()];
    for tick in 0..ticks {
        let now = after(room, tick);
        for (i, &id) in ids.iter().enumerate() {
            if !gone[i] {
                room.handle_message(now, id, input(id, tick, vec![vec![1]]))
                    .unwrap();
            }
        }
        room.handle_timeout(now);
        for (i, &id) in ids.iter().enumerate() {
            if let (false, Some(hash)) = (gone[i], report(i, tick)) {
                let r = ClientMessage::HashReport(HashReport {
                    tick,
                    hash,
                    body_hashes: None,
                });
                room.handle_message(now, id, r).unwrap();
            }
        }
        let (t, e) = drain(room);
        for e in &e {
            if let RoomEvent::PlayerLeft { id, .. } = e {
                gone[ids.iter().position(|x| x == id).unwrap()] = true;
            }
        }
        transmits.extend(t);
        events.extend(e);
    }
    (transmits, events)
}

fn left(events: &[RoomEvent]) -> Vec<(PlayerId, LeaveReason, u64)> {
    events
        .iter()
        .filter_map(|e| match e {
            RoomEvent::PlayerLeft {
                id,
                reason,
                from_tick,
            } => Some((*id, *reason, *from_tick)),
            _ => None,
        })
        .collect()
}

fn closes_to(transmits: &[Transmit], to: PlayerId) -> Vec<CloseReason> {
    transmits
        .iter()
        .filter(|t| t.to == to)
        .filter_map(|t| match &t.message {
            ServerMessage::Close(c) => Some(c.reason),
            _ => None,
        })
        .collect()
}

/// A client that lies on even ticks and stays silent on odd ones is one
/// divergence, announced once (it used to be announced every 2 ticks), and
/// is dropped as diverged after `max_wrong_ticks` of its reports; the
/// honest players play on.
#[test]
fn a_liar_alternating_with_silence_gets_one_notice_and_is_dropped() {
    let mut c = RoomConfig::new("arena", vec![], 1);
    c.voting = lockstep_proto::Voting::Everyone;
    let (mut room, ids) = room_with(4, c);
    let (transmits, events) = play_reporting(&mut room, &ids, 500, |i, tick| match i {
        3 if tick % 2 == 1 => None,
        3 => Some(9),
        _ => Some(7),
    });
    let notices = events
        .iter()
        .filter(|e| matches!(e, RoomEvent::Desync(_)))
        .count();
    assert_eq!(notices, 1);
    // Its 180th wrong report is tick 358; that tick compares as it arrives.
    assert_eq!(left(&events), vec![(ids[3], LeaveReason::Diverged, 359)]);
    assert_eq!(closes_to(&transmits, ids[3]), vec![CloseReason::Diverged]);
    assert_eq!(room.player_count(), 3);
    assert_eq!(room.config().max_wrong_ticks, 180);
}

fn agreed(events: &[RoomEvent]) -> Vec<(u64, u64)> {
    events
        .iter()
        .filter_map(|e| match e {
            RoomEvent::TickAgreed { tick, hash } => Some((*tick, *hash)),
            _ => None,
        })
        .collect()
}

/// The default room (no verifying, no voting) against four sybils that
/// report one made-up hash beside three honest players: nobody is dropped
/// for its hash, every mismatch is undecided, and no tick they lie on has
/// an agreed hash (so a replay records none of the made-up ones); once
/// they report the honest hash (from tick 300), ticks are agreed again.
#[test]
fn without_verifying_or_voting_sybils_drop_nobody_and_agree_on_nothing() {
    let (mut room, ids) = room(7);
    assert_eq!(room.config().voting, lockstep_proto::Voting::Off);
    let (_, events) = play_reporting(&mut room, &ids, 400, |i, tick| {
        Some(if i < 4 && tick < 300 { 0xbad } else { 7 })
    });
    assert!(left(&events).is_empty(), "{:?}", left(&events));
    let agreed = agreed(&events);
    assert!(
        agreed.iter().all(|&(t, h)| t >= 300 && h == 7),
        "{agreed:?}"
    );
    assert!(agreed.len() >= 50, "{}", agreed.len());
    let verdicts: Vec<_> = events
        .iter()
        .filter_map(|e| match e {
            RoomEvent::Desync(n) => Some(n.verdict.clone()),
            _ => None,
        })
        .collect();
    assert_eq!(verdicts, vec![lockstep_proto::Verdict::Undecided]);
}

/// Voting among token holders: four sybils without tokens report one
/// made-up hash beside three players seated with tokens. Only the token
/// holders vote, so the sybils are the ones judged wrong and dropped as
/// diverged, and every agreed hash is the honest one.
#[test]
fn only_token_holders_vote_and_tokenless_sybils_are_dropped() {
    use lockstep_proto::token::{JoinClaims, Ticket};
    let mut c = RoomConfig::new("arena", vec![], 1);
    c.voting = lockstep_proto::Voting::TokenHolders;
    let mut room = Room::new(c).unwrap();
    let mut ids = Vec::new();
    for i in 0..7u64 {
        let ticket = (i >= 4).then(|| Ticket {
            claims: JoinClaims {
                room: "arena".into(),
                seat: None,
                player: format!("p{i}"),
                expires: u64::MAX,
            },
            key: i,
        });
        let join = join_msg(&format!("p{i}"));
        ids.push(
            room.join_with_ticket(Duration::ZERO, &join, ticket.as_ref())
                .unwrap(),
        );
    }
    room.start(Duration::ZERO).unwrap();
    drain(&mut room);
    let (transmits, events) = play_reporting(&mut room, &ids, 400, |i, _| {
        Some(if i < 4 { 0xbad } else { 7 })
    });
    let gone = left(&events);
    assert_eq!(gone.len(), 4, "{gone:?}");
    for (n, g) in gone.iter().enumerate() {
        assert_eq!((g.0, g.1), (ids[n], LeaveReason::Diverged));
        assert_eq!(closes_to(&transmits, ids[n]), vec![CloseReason::Diverged]);
    }
    let agreed = agreed(&events);
    assert!(agreed.len() >= 200, "{}", agreed.len());
    assert!(agreed.iter().all(|&(_, h)| h == 7));
}

/// Hash reports are not optional: a player that sends inputs but never a
/// hash is dropped once more than `max_missing_reports` (240) of its last
/// `report_window` (600) compared ticks lack one (each compared at its 2 s
/// timeout), and nobody else is.
#[test]
fn a_player_that_never_reports_its_hash_is_dropped() {
    let (mut room, ids) = room(3);
    let (transmits, events) = play_reporting(&mut room, &ids, 500, |i, _| (i != 1).then_some(7));
    let gone = left(&events);
    assert_eq!(gone.len(), 1, "{gone:?}");
    assert_eq!((gone[0].0, gone[0].1), (ids[1], LeaveReason::NoHashReports));
    // Its 241st missing tick, 240, is compared at its timeout, 2 s (120
    // ticks) after it closed: it is in no bundle from tick 361.
    assert_eq!(gone[0].2, 361);
    assert_eq!(
        closes_to(&transmits, ids[1]),
        vec![CloseReason::NoHashReports]
    );
    assert!(!events.iter().any(|e| matches!(e, RoomEvent::Desync(_))));
}

/// A sparse reporter (one hash every 250 ticks, which used to reset a run
/// of misses and so was never dropped) is judged over the sliding window:
/// it goes with `NoHashReports` and the reason, at the same tick as one
/// that never reports; a player that misses a few reports now and then
/// stays.
#[test]
fn a_sparse_reporter_is_dropped_over_the_sliding_window() {
    let (mut room, ids) = room(3);
    let (transmits, events) = play_reporting(&mut room, &ids, 500, |i, tick| match i {
        1 => (tick % 250 == 100).then_some(7),
        2 => (tick % 10 != 0).then_some(7),
        _ => Some(7),
    });
    let gone = left(&events);
    assert_eq!(gone.len(), 1, "{gone:?}");
    assert_eq!((gone[0].0, gone[0].1), (ids[1], LeaveReason::NoHashReports));
    assert_eq!(gone[0].2, 362, "its one report delays it one tick");
    let detail = transmits
        .iter()
        .find_map(|t| match &t.message {
            ServerMessage::Close(c) if t.to == ids[1] => Some(c.detail.clone()),
            _ => None,
        })
        .expect("a close");
    assert!(
        detail.starts_with("no state hash for 241 of the last 242 compared ticks"),
        "{detail}"
    );
}

fn snapshot_probes(transmits: &[Transmit]) -> Vec<(PlayerId, u64)> {
    transmits
        .iter()
        .filter_map(|t| match &t.message {
            ServerMessage::Probe(p)
                if matches!(p.ask, lockstep_proto::ProbeAsk::Snapshot { offset: 0 }) =>
            {
                Some((t.to, p.tick))
            }
            _ => None,
        })
        .collect()
}

fn snapshot_reply(tick: u64, bytes: &[u8]) -> ClientMessage {
    ClientMessage::ProbeReply(lockstep_proto::ProbeReply {
        tick,
        answer: lockstep_proto::ProbeAnswer::Snapshot {
            total: bytes.len() as u32,
            offset: 0,
            bytes: bytes.to_vec(),
        },
    })
}

/// A late join whose giver sends a snapshot that does not check out: the
/// bad snapshot counts against that giver, the next player in good
/// standing is asked for the same tick, and its snapshot admits the
/// joiner. The giver of the bad one is not asked again by the next joiner.
#[test]
fn a_bad_join_snapshot_counts_against_its_giver_and_another_player_is_asked() {
    let mut c = RoomConfig::new("arena", vec![], 1);
    c.late_join = true;
    let (mut room, ids) = room_with(3, c);
    play_reporting(&mut room, &ids, 130, |_, _| Some(7));
    let now = after(&room, 130);
    let late = room.join(now, &join_msg("late")).unwrap();
    let (t, _) = drain(&mut room);
    let probes = snapshot_probes(&t);
    assert_eq!(probes.len(), 1);
    let (giver, tick) = probes[0];
    assert_eq!(giver, ids[0]);
    room.handle_message(now, ids[0], snapshot_reply(tick, b"garbage"))
        .unwrap();
    let (_, e) = drain(&mut room);
    assert!(e.iter().any(|e| matches!(
        e,
        RoomEvent::JoinSnapshot {
            from: Some(Slot(0)),
            ..
        }
    )));
    // The caller finds it bad.
    room.refuse_join(now, late, "not a lockstep snapshot");
    assert_eq!(room.player_stats(ids[0]).unwrap().bad_snapshots, 1);
    let (t, e) = drain(&mut room);
    assert!(left(&e).is_empty(), "the joiner waits: {:?}", left(&e));
    assert_eq!(snapshot_probes(&t), vec![(ids[1], tick)]);
    room.handle_message(now, ids[1], snapshot_reply(tick, b"good"))
        .unwrap();
    let (_, e) = drain(&mut room);
    assert!(e.iter().any(|e| matches!(
        e,
        RoomEvent::JoinSnapshot {
            from: Some(Slot(1)),
            ..
        }
    )));
    room.admit(now, late, b"good".to_vec());
    let (t, _) = drain(&mut room);
    assert!(
        t.iter().any(|t| t.to == late
            && matches!(&t.message, ServerMessage::Welcome(w) if w.resume.is_some()))
    );
    // The next joiner's snapshot is not asked of slot 0.
    room.join(now, &join_msg("later")).unwrap();
    let (t, _) = drain(&mut room);
    assert_eq!(snapshot_probes(&t), vec![(ids[1], tick)]);
}

/// Without verifying, a silent reporter holds every comparison back 2 s
/// (120 ticks, longer than the players keep snapshots); the joiner starts
/// from the newest tick the players in good standing all reported alike,
/// not from the last compared one, and the silent one is never asked.
#[test]
fn a_silent_reporter_does_not_age_the_tick_a_joiner_starts_from() {
    let mut c = RoomConfig::new("arena", vec![], 1);
    c.late_join = true;
    let (mut room, ids) = room_with(3, c);
    play_reporting(&mut room, &ids, 200, |i, _| (i != 0).then_some(7));
    let now = after(&room, 199);
    room.join(now, &join_msg("late")).unwrap();
    let (t, _) = drain(&mut room);
    assert_eq!(snapshot_probes(&t), vec![(ids[1], 199)]);
}

/// A join to the running match that gets no snapshot (its only giver no
/// longer has the tick) is refused with `MatchInProgress` and the reason,
/// and leaves as `JoinRefused`, not as kicked.
#[test]
fn a_join_without_an_agreed_state_is_refused_as_such() {
    let mut c = RoomConfig::new("arena", vec![], 1);
    c.late_join = true;
    let (mut room, ids) = room_with(1, c);
    play_reporting(&mut room, &ids, 130, |_, _| Some(7));
    let now = after(&room, 130);
    let late = room.join(now, &join_msg("late")).unwrap();
    let (t, _) = drain(&mut room);
    let (_, tick) = snapshot_probes(&t)[0];
    let reply = ClientMessage::ProbeReply(lockstep_proto::ProbeReply {
        tick,
        answer: lockstep_proto::ProbeAnswer::Unavailable,
    });
    room.handle_message(now, ids[0], reply).unwrap();
    let (t, e) = drain(&mut room);
    assert_eq!(left(&e), vec![(late, LeaveReason::JoinRefused, 130)]);
    let detail = t
        .iter()
        .find_map(|t| match &t.message {
            ServerMessage::Close(c) if t.to == late => Some((c.reason, c.detail.clone())),
            _ => None,
        })
        .expect("a close");
    assert_eq!(detail.0, CloseReason::MatchInProgress);
    assert!(
        detail.1.contains("left the players' history"),
        "{}",
        detail.1
    );
    // Not counted against the giver: it had no snapshot, it gave no bad one.
    assert_eq!(room.player_stats(ids[0]).unwrap().bad_snapshots, 0);
}

/// A verifying room that offers its own state: a joiner starts from the
/// caller's state of the newest tick, no player is asked, and a player that
/// never reports cannot hold the join back.
#[test]
fn a_verifying_room_gives_joiners_its_own_state() {
    let mut c = RoomConfig::new("arena", vec![], 1);
    c.late_join = true;
    c.verify = true;
    let (mut room, ids) = room_with(2, c);
    room.offer_own_snapshots();
    for tick in 0..100 {
        let now = after(&room, tick);
        for &id in &ids {
            room.handle_message(now, id, input(id, tick, vec![vec![1]]))
                .unwrap();
        }
        room.handle_timeout(now);
        room.verify_tick(now, tick, 7);
        // Slot 1 never reports.
        let r = ClientMessage::HashReport(HashReport {
            tick,
            hash: 7,
            body_hashes: None,
        });
        room.handle_message(now, ids[0], r).unwrap();
        drain(&mut room);
    }
    let now = after(&room, 99);
    let late = room.join(now, &join_msg("late")).unwrap();
    let (t, e) = drain(&mut room);
    assert!(snapshot_probes(&t).is_empty());
    assert!(e.contains(&RoomEvent::JoinFromOwnState {
        id: late,
        tick: 99,
        agreed_hash: 7
    }));
    room.admit(now, late, b"state".to_vec());
    let (t, _) = drain(&mut room);
    let resume = t.iter().find_map(|t| match &t.message {
        ServerMessage::Welcome(w) if t.to == late => w.resume.clone(),
        _ => None,
    });
    assert_eq!(resume.map(|r| (r.tick, r.hash)), Some((99, 7)));
}

/// The players a lobby would drop: seated without their first input.
#[test]
fn unready_players_are_those_without_their_first_input() {
    let mut room = Room::new(RoomConfig::new("arena", vec![], 1)).unwrap();
    let ids: Vec<_> = (0..3)
        .map(|i| room.join(MS, &join_msg(&format!("p{i}"))).unwrap())
        .collect();
    assert_eq!(room.unready_players(), ids);
    for &id in &[ids[0], ids[2]] {
        room.handle_message(MS, id, input(id, 0, vec![vec![1]]))
            .unwrap();
    }
    assert_eq!(room.unready_players(), vec![ids[1]]);
    assert!(!room.all_ready());
    room.kick(MS, ids[1], CloseReason::TimedOut, "no first input");
    assert!(room.unready_players().is_empty());
    assert!(room.all_ready());
}

fn seat_ticket(seat: u8, key: u64) -> lockstep_proto::token::Ticket {
    lockstep_proto::token::Ticket {
        claims: lockstep_proto::token::JoinClaims {
            room: "arena".into(),
            seat: Some(Slot(seat)),
            player: format!("owner-{seat}"),
            expires: u64::MAX,
        },
        key,
    }
}

fn welcome_to(transmits: &[Transmit], to: PlayerId) -> Option<lockstep_proto::Welcome> {
    transmits.iter().find_map(|t| match &t.message {
        ServerMessage::Welcome(w) if t.to == to => Some(w.clone()),
        _ => None,
    })
}

/// A join token seats one player once per match: its owner gets a rejoin
/// credential in its welcome; a copy of the token is refused (in the lobby
/// and in the match, seat free or not); the owner takes its seat back with
/// the credential alone (no token), its stale connection is named for the
/// caller to drop, and a credential of another room or a made-up one is
/// ignored (the join is judged by its token).
#[test]
fn a_used_token_seats_nobody_again_and_its_owner_rejoins_with_its_credential() {
    let mut c = RoomConfig::new("arena", vec![], 1);
    c.rejoin_grace = Duration::from_secs(30);
    let mut room = Room::new(c).unwrap();
    room.set_rejoin_key([9; 32]);
    let t0 = Duration::ZERO;
    let tickets = [seat_ticket(0, 100), seat_ticket(1, 101)];
    let ids: Vec<PlayerId> = (0..2)
        .map(|i| {
            room.join_with_ticket(t0, &join_msg("owner"), Some(&tickets[i]))
                .unwrap()
        })
        .collect();
    let (t, _) = drain(&mut room);
    let credential = welcome_to(&t, ids[1])
        .unwrap()
        .rejoin
        .expect("a credential");
    assert_ne!(welcome_to(&t, ids[0]).unwrap().rejoin, Some(credential));
    // A tokenless player gets none.
    let plain = room.join(t0, &join_msg("plain")).unwrap();
    let (t, _) = drain(&mut room);
    assert_eq!(welcome_to(&t, plain).unwrap().rejoin, None);
    // The copy of a used token, while its owner is seated ...
    let copy = room.join_with_ticket(t0, &join_msg("mallory"), Some(&tickets[1]));
    assert_eq!(copy, Err(JoinError::TokenUsed));
    let close = JoinError::TokenUsed.to_close();
    assert_eq!(close.reason, CloseReason::BadToken);
    assert!(close.detail.contains("already used"), "{}", close.detail);
    room.start(t0).unwrap();
    drain(&mut room);
    let all = [ids[0], ids[1], plain];
    play_reporting(&mut room, &all, 130, |_, _| Some(7));
    // ... and once the owner's connection is gone (its seat reserved).
    let now = after(&room, 130);
    room.disconnect(now, ids[1]);
    drain(&mut room);
    let copy = room.join_with_ticket(now, &join_msg("mallory"), Some(&tickets[1]));
    assert_eq!(copy, Err(JoinError::TokenUsed));
    // A made-up credential is ignored: judged by its (used) token.
    let mut forged = join_msg("mallory");
    forged.rejoin = Some(lockstep_proto::RejoinCredential([1; 32]));
    assert!(!room.knows_rejoin(&forged));
    assert_eq!(
        room.join_with_ticket(now, &forged, Some(&tickets[1])),
        Err(JoinError::TokenUsed)
    );
    assert_eq!(room.join(now, &forged), Err(JoinError::MatchInProgress));
    // The owner, with its credential and no token, takes its seat back.
    let mut back = join_msg("owner");
    back.rejoin = Some(credential);
    assert!(room.knows_rejoin(&back));
    assert_eq!(room.rejoin_replaces(&back), None);
    let again = room.join(now, &back).unwrap();
    assert_eq!(again.slot, Slot(1));
    let (t, _) = drain(&mut room);
    let (giver, tick) = snapshot_probes(&t)[0];
    room.handle_message(now, giver, snapshot_reply(tick, b"state"))
        .unwrap();
    drain(&mut room);
    room.admit(now, again, b"state".to_vec());
    let (t, _) = drain(&mut room);
    let w = welcome_to(&t, again).unwrap();
    assert!(w.resume.is_some());
    assert_eq!(w.rejoin, Some(credential), "the same credential again");
    // While seated, the credential names the seated connection, which the
    // caller drops before the owner's new join takes the seat back.
    assert_eq!(room.rejoin_replaces(&back), Some(again));
    assert_eq!(room.join(now, &back), Err(JoinError::SeatTaken(1)));
    // Another room's credential for the same seat and token is unknown here.
    let mut other = Room::new(RoomConfig::new("arena", vec![], 1)).unwrap();
    other.set_rejoin_key([8; 32]);
    other
        .join_with_ticket(t0, &join_msg("owner"), Some(&tickets[0]))
        .unwrap();
    other
        .join_with_ticket(t0, &join_msg("owner"), Some(&tickets[1]))
        .unwrap();
    let (t, _) = drain(&mut other);
    let theirs = t
        .iter()
        .find_map(|t| match &t.message {
            ServerMessage::Welcome(w) if w.slot == Slot(1) => w.rejoin,
            _ => None,
        })
        .unwrap();
    assert_ne!(theirs, credential);
    let mut foreign = join_msg("owner");
    foreign.rejoin = Some(theirs);
    assert!(!room.knows_rejoin(&foreign));
}

/// A rejoin credential whose seat is no longer reserved (its owner was
/// dropped as diverged, or stayed away past the grace) is refused as such,
/// and a failed rejoin gives the seat's reservation back.
#[test]
fn a_credential_past_its_reservation_is_refused_and_a_failed_rejoin_keeps_the_seat_reserved() {
    let mut c = RoomConfig::new("arena", vec![], 1);
    c.rejoin_grace = Duration::from_secs(30);
    let mut room = Room::new(c).unwrap();
    room.set_rejoin_key([9; 32]);
    let t0 = Duration::ZERO;
    let owner = room
        .join_with_ticket(t0, &join_msg("owner"), Some(&seat_ticket(1, 5)))
        .unwrap();
    let other = room.join(t0, &join_msg("other")).unwrap();
    let (t, _) = drain(&mut room);
    let credential = welcome_to(&t, owner).unwrap().rejoin.unwrap();
    room.start(t0).unwrap();
    drain(&mut room);
    play_reporting(&mut room, &[other, owner], 130, |_, _| Some(7));
    let now = after(&room, 130);
    room.disconnect(now, owner);
    drain(&mut room);
    let mut back = join_msg("owner");
    back.rejoin = Some(credential);
    // The rejoin's snapshot cannot be had: refused, the seat stays reserved.
    let first = room.join(now, &back).unwrap();
    let (t, _) = drain(&mut room);
    let (giver, tick) = snapshot_probes(&t)[0];
    let unavailable = ClientMessage::ProbeReply(lockstep_proto::ProbeReply {
        tick,
        answer: lockstep_proto::ProbeAnswer::Unavailable,
    });
    room.handle_message(now, giver, unavailable).unwrap();
    let (_, e) = drain(&mut room);
    assert_eq!(left(&e), vec![(first, LeaveReason::JoinRefused, 130)]);
    // Nobody else takes the reserved seat; the owner gets it on its retry.
    let stranger = room.join(now, &join_msg("stranger"));
    assert_eq!(stranger, Err(JoinError::MatchInProgress));
    let second = room.join(now, &back).unwrap();
    assert_eq!(second.slot, Slot(1));
    drain(&mut room);
    // Its connection drops while the snapshot comes: still reserved.
    room.disconnect(now, second);
    drain(&mut room);
    assert_eq!(
        room.join(now, &join_msg("stranger")),
        Err(JoinError::MatchInProgress)
    );
    let second = room.join(now, &back).unwrap();
    drain(&mut room);
    room.kick(now, second, CloseReason::Kicked, "test");
    drain(&mut room);
    // Kicked: no reservation, so the credential no longer seats it.
    assert_eq!(room.join(now, &back), Err(JoinError::NotReserved(1)));
    assert_eq!(
        JoinError::NotReserved(1).to_close().reason,
        CloseReason::BadToken
    );
}

/// A snapshot piece over the probe reply budget is not read: it counts as
/// a bad snapshot against its giver, and the next player is asked.
#[test]
fn a_snapshot_piece_over_the_reply_budget_counts_as_a_bad_snapshot() {
    let mut c = RoomConfig::new("arena", vec![], 1);
    c.late_join = true;
    c.max_probe_reply_bytes = lockstep_proto::MIN_PROBE_REPLY_BYTES;
    let (mut room, ids) = room_with(3, c);
    play_reporting(&mut room, &ids, 130, |_, _| Some(7));
    let now = after(&room, 130);
    room.join(now, &join_msg("late")).unwrap();
    let (t, _) = drain(&mut room);
    let (giver, tick) = snapshot_probes(&t)[0];
    assert_eq!(giver, ids[0]);
    let big = vec![0u8; lockstep_proto::MIN_PROBE_REPLY_BYTES as usize + 1];
    room.handle_message(now, giver, snapshot_reply(tick, &big))
        .unwrap();
    let (t, e) = drain(&mut room);
    assert!(
        !e.iter()
            .any(|e| matches!(e, RoomEvent::JoinSnapshot { .. }))
    );
    assert_eq!(room.player_stats(ids[0]).unwrap().bad_snapshots, 1);
    assert_eq!(room.stats().bad_snapshots, 1);
    assert_eq!(snapshot_probes(&t), vec![(ids[1], tick)]);
    let mut c = RoomConfig::new("arena", vec![], 1);
    c.max_probe_reply_bytes = lockstep_proto::MIN_PROBE_REPLY_BYTES - 1;
    assert!(Room::new(c).is_err());
}
