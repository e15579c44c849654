//! A room that runs its own match (`RoomConfig::lifecycle`), on a virtual
//! clock: the lobby and its timeout, the match's end, the finishing grace
//! that collects the last hash reports, and the close.

use std::time::Duration;

use lockstep_proto::{
    ClientMessage, CloseReason, HashReport, InputDatagram, Join, LeaveReason, MatchLifecycle,
    MatchPhase, PROTOCOL_VERSION, PlayerId, Room, RoomConfig, RoomEvent, ServerMessage, Transmit,
};

const SEC: Duration = Duration::from_secs(1);

fn join_msg(name: &str) -> Join {
    Join {
        protocol_version: PROTOCOL_VERSION,
        room: "arena".into(),
        player_name: name.into(),
        token: None,
        rejoin: None,
    }
}

/// A room that starts with `start_players`, waits `lobby_timeout` in its
/// lobby and plays `match_ticks` ticks. Pings and silence are far away, so
/// only the lifecycle keeps time.
fn room(start_players: u8, lobby_timeout: Option<Duration>, match_ticks: Option<u64>) -> Room {
    let mut c = RoomConfig::new("arena", vec![], 1);
    c.silence_timeout = 600 * SEC;
    c.ping_interval = 600 * SEC;
    c.lifecycle = Some(MatchLifecycle {
        start_players,
        lobby_timeout,
        match_ticks,
        final_reports_timeout: 2 * SEC,
    });
    Room::new(c).unwrap()
}

fn drain(room: &mut Room) -> (Vec<Transmit>, Vec<RoomEvent>) {
    (
        std::iter::from_fn(|| room.poll_transmit()).collect(),
        std::iter::from_fn(|| room.poll_event()).collect(),
    )
}

fn input(id: PlayerId, first_tick: u64, ack_bundle: Option<u64>) -> ClientMessage {
    ClientMessage::Input(InputDatagram {
        slot: id.slot,
        ack_bundle,
        first_tick,
        inputs: vec![vec![1]],
    })
}

fn hash(tick: u64) -> ClientMessage {
    ClientMessage::HashReport(HashReport {
        tick,
        hash: 7,
        body_hashes: None,
    })
}

fn closes(transmits: &[Transmit]) -> Vec<(PlayerId, CloseReason)> {
    transmits
        .iter()
        .filter_map(|t| match &t.message {
            ServerMessage::Close(c) => Some((t.to, c.reason)),
            _ => None,
        })
        .collect()
}

/// Runs the room's timers up to `until` as a driver would: at each
/// deadline in turn.
fn run_until(room: &mut Room, until: Duration) -> (Vec<Transmit>, Vec<RoomEvent>) {
    let (mut transmits, mut events) = (Vec::new(), Vec::new());
    while let Some(at) = room.poll_timeout().filter(|&at| at <= until) {
        room.handle_timeout(at);
        let (t, e) = drain(room);
        transmits.extend(t);
        events.extend(e);
    }
    (transmits, events)
}

#[test]
fn the_match_starts_once_enough_players_are_ready() {
    let mut room = room(2, None, None);
    let a = room.join(SEC, &join_msg("a")).unwrap();
    room.handle_message(SEC, a, input(a, 0, None)).unwrap();
    // One ready player of the two wanted: still the lobby.
    assert_eq!(room.phase(), MatchPhase::Lobby);
    let b = room.join(2 * SEC, &join_msg("b")).unwrap();
    assert_eq!(room.phase(), MatchPhase::Lobby);
    room.handle_message(3 * SEC, b, input(b, 0, None)).unwrap();
    assert_eq!(room.phase(), MatchPhase::Running);
    assert_eq!(room.started_at(), Some(3 * SEC));
    let (_, events) = drain(&mut room);
    assert!(events.contains(&RoomEvent::MatchStarted { players: 2 }));
    // Tick 0 closes one tick period after the start (the pings due at
    // the joins go first).
    room.handle_timeout(3 * SEC);
    assert_eq!(
        room.poll_timeout(),
        Some(3 * SEC + room.config().deadline_offset(0))
    );
}

#[test]
fn the_lobby_timeout_drops_the_unready_players_and_starts_the_ready_ones() {
    let mut room = room(3, Some(10 * SEC), None);
    let a = room.join(SEC, &join_msg("a")).unwrap();
    let b = room.join(4 * SEC, &join_msg("b")).unwrap();
    room.handle_message(5 * SEC, a, input(a, 0, None)).unwrap();
    drain(&mut room);
    // The lobby's deadline counts from the first join.
    let (_, events) = run_until(&mut room, 11 * SEC - Duration::from_nanos(1));
    assert_eq!(room.phase(), MatchPhase::Lobby);
    assert!(events.is_empty(), "{events:?}");
    assert_eq!(room.poll_timeout(), Some(11 * SEC));
    let (transmits, events) = run_until(&mut room, 11 * SEC);
    assert_eq!(closes(&transmits), vec![(b, CloseReason::TimedOut)]);
    assert!(events.contains(&RoomEvent::PlayerLeft {
        id: b,
        reason: LeaveReason::Kicked,
        from_tick: 0,
    }));
    assert!(events.contains(&RoomEvent::MatchStarted { players: 1 }));
    assert_eq!(room.phase(), MatchPhase::Running);
    assert_eq!(room.started_at(), Some(11 * SEC));
}

#[test]
fn a_lobby_where_nobody_is_ready_closes_at_its_timeout() {
    let mut room = room(2, Some(10 * SEC), None);
    let a = room.join(SEC, &join_msg("a")).unwrap();
    drain(&mut room);
    let (transmits, events) = run_until(&mut room, 20 * SEC);
    assert_eq!(closes(&transmits), vec![(a, CloseReason::TimedOut)]);
    assert_eq!(room.phase(), MatchPhase::Done);
    assert!(events.contains(&RoomEvent::MatchOver {
        reason: "nobody was ready within the lobby timeout".into(),
        all_reported: true,
    }));
    assert!(!room.is_started());
    assert_eq!(room.poll_timeout(), None);
}

#[test]
fn a_lobby_whose_players_all_left_closes_at_once() {
    let mut room = room(2, Some(10 * SEC), None);
    let a = room.join(SEC, &join_msg("a")).unwrap();
    room.handle_message(2 * SEC, a, ClientMessage::Leave)
        .unwrap();
    assert_eq!(room.phase(), MatchPhase::Done);
    assert_eq!(room.end_reason(), "every player left the lobby");
}

/// One player, ready at 0 s, in a match of `ticks` ticks.
fn running(ticks: u64) -> (Room, PlayerId) {
    let mut room = room(1, None, Some(ticks));
    let a = room.join(Duration::ZERO, &join_msg("a")).unwrap();
    for tick in 0..ticks.min(3) {
        room.handle_message(Duration::ZERO, a, input(a, tick, None))
            .unwrap();
    }
    assert_eq!(room.phase(), MatchPhase::Running);
    drain(&mut room);
    (room, a)
}

#[test]
fn the_match_ends_after_its_ticks_and_closes_once_every_report_came() {
    let (mut room, a) = running(3);
    // However late the wake-up, no tick at or past the end closes.
    let late = room.config().deadline_offset(10);
    room.handle_timeout(late);
    let (_, events) = drain(&mut room);
    let ticks: Vec<u64> = events
        .iter()
        .filter_map(|e| match e {
            RoomEvent::TickClosed(b) => Some(b.tick),
            _ => None,
        })
        .collect();
    assert_eq!(ticks, vec![0, 1, 2]);
    assert_eq!(room.next_tick(), 3);
    assert_eq!(room.phase(), MatchPhase::Finishing);
    assert!(events.contains(&RoomEvent::MatchEnding {
        reason: "match over after 3 ticks".into(),
    }));
    // The player's hashes of every tick: the room closes at once.
    room.handle_message(late, a, hash(0)).unwrap();
    room.handle_message(late, a, hash(1)).unwrap();
    assert_eq!(room.phase(), MatchPhase::Finishing);
    room.handle_message(late, a, hash(2)).unwrap();
    assert_eq!(room.phase(), MatchPhase::Done);
    let (transmits, events) = drain(&mut room);
    assert_eq!(closes(&transmits), vec![(a, CloseReason::RoomClosed)]);
    assert_eq!(
        events.last(),
        Some(&RoomEvent::MatchOver {
            reason: "match over after 3 ticks".into(),
            all_reported: true,
        })
    );
    assert!(room.departed_stats(a).is_some_and(|s| s.hash_reports == 3));
    assert_eq!(room.poll_timeout(), None);
}

#[test]
fn finishing_repeats_unacknowledged_bundles_then_closes_at_its_deadline() {
    let (mut room, a) = running(3);
    let end = room.config().deadline_offset(2);
    room.handle_timeout(end);
    drain(&mut room);
    assert_eq!(room.phase(), MatchPhase::Finishing);
    // The player acknowledged bundle 0: ticks 1 and 2 are repeated once
    // per tick period.
    room.handle_message(end, a, input(a, 3, Some(0))).unwrap();
    drain(&mut room);
    let period = room.config().deadline_offset(0);
    assert_eq!(room.poll_timeout(), Some(end + period));
    let (transmits, _) = run_until(&mut room, end + period);
    let repeated: Vec<Vec<u64>> = transmits
        .iter()
        .filter_map(|t| match &t.message {
            ServerMessage::Bundles(d) => Some(d.bundles.iter().map(|b| b.tick).collect()),
            _ => None,
        })
        .collect();
    assert_eq!(repeated, vec![vec![1, 2]]);
    // No report comes: the room closes at the grace's end (2 s).
    let (transmits, events) = run_until(&mut room, end + 2 * SEC);
    assert_eq!(closes(&transmits), vec![(a, CloseReason::RoomClosed)]);
    assert_eq!(room.phase(), MatchPhase::Done);
    assert!(events.contains(&RoomEvent::MatchOver {
        reason: "match over after 3 ticks".into(),
        all_reported: false,
    }));
}

#[test]
fn shutting_down_finishes_the_tick_in_progress() {
    let (mut room, _) = running(100);
    room.handle_timeout(room.config().deadline_offset(4));
    room.shut_down(room.config().deadline_offset(4));
    room.handle_timeout(room.config().deadline_offset(50));
    assert_eq!(room.next_tick(), 6);
    assert_eq!(room.phase(), MatchPhase::Finishing);
    assert_eq!(room.end_reason(), "server shutting down");
}
