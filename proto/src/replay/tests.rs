//! The replay format's and the recorder's unit tests.

use super::*;
use crate::message::PlayerInput;
use crate::room::RoomEvent;
use crate::room::{LeaveReason, PlayerId};

fn header() -> ReplayHeader {
    ReplayHeader {
        protocol_version: crate::PROTOCOL_VERSION,
        room: "r".into(),
        tick_rate: 60,
        input_delay: 4,
        scene_hash: 0xabc,
        scene: b"scene".to_vec(),
        engine_version: ENGINE_VERSION.into(),
        hash_layout: 6,
        rules: RulesId::new("test", 1),
    }
}

fn id(slot: u8) -> PlayerId {
    PlayerId {
        slot: Slot(slot),
        generation: 0,
    }
}

fn closed(tick: u64, slots: &[u8]) -> RoomEvent {
    RoomEvent::TickClosed(TickBundle {
        tick,
        inputs: slots
            .iter()
            .map(|&s| PlayerInput {
                slot: Slot(s),
                input: vec![s, tick as u8],
                substituted: false,
            })
            .collect(),
    })
}

fn three_players() -> ReplayRecorder {
    let mut r = ReplayRecorder::new(header(), 10).unwrap();
    for s in 0..3 {
        r.on_event(&RoomEvent::PlayerJoined {
            id: id(s),
            name: format!("p{s}"),
        });
    }
    r
}

#[test]
fn majority_hash_is_recorded_once_every_present_player_reported() {
    let mut r = three_players();
    r.on_event(&closed(0, &[0, 1, 2]));
    r.on_hash(Slot(0), 0, 7);
    r.on_hash(Slot(1), 0, 7);
    assert_eq!(r.hashed_ticks(), 0, "slot 2 has not reported yet");
    r.on_hash(Slot(2), 0, 9);
    assert_eq!(r.hashed_ticks(), 1);
    r.finish("done");
    let replay = Replay::parse(&r.take_bytes()).unwrap();
    assert_eq!(replay.hashes, vec![Some(7)]);
    assert_eq!(replay.players.len(), 3);
    assert_eq!(replay.end, Some((1, "done".into())));
    assert!(!replay.truncated);
}

/// Following the room, a majority of reporters records nothing: only
/// the room's agreed hashes are written, with the matching body hashes.
#[test]
fn following_the_room_records_only_its_agreed_hashes() {
    let mut r = three_players();
    r.follow_room();
    r.on_event(&closed(0, &[0, 1, 2]));
    r.on_event(&closed(1, &[0, 1, 2]));
    for t in 0..2 {
        r.on_hash_with_bodies(Slot(0), t, 0xbad, Some(&[1]));
        r.on_hash_with_bodies(Slot(1), t, 0xbad, Some(&[1]));
        r.on_hash_with_bodies(Slot(2), t, 7, Some(&[2]));
    }
    assert_eq!(r.hashed_ticks(), 0, "no majority of reporters is recorded");
    r.on_event(&RoomEvent::TickAgreed { tick: 1, hash: 7 });
    r.finish("done");
    let replay = Replay::parse(&r.take_bytes()).unwrap();
    assert_eq!(replay.hashes, vec![None, Some(7)]);
    assert_eq!(r.hashed_ticks(), 1);
}

#[test]
fn a_departed_or_silent_player_does_not_hold_the_hash_back() {
    let mut r = three_players();
    r.on_event(&closed(0, &[0, 1, 2]));
    r.on_hash(Slot(0), 0, 5);
    r.on_hash(Slot(1), 0, 5);
    r.on_event(&RoomEvent::PlayerLeft {
        id: id(2),
        reason: LeaveReason::TimedOut,
        from_tick: 1,
    });
    assert_eq!(r.hashed_ticks(), 1);
    // Tick 1: only slot 0 reports; decided 10 ticks later by age.
    r.on_event(&closed(1, &[0, 1]));
    r.on_hash(Slot(0), 1, 6);
    for t in 2..11 {
        r.on_event(&closed(t, &[0, 1]));
    }
    assert_eq!(r.pending_ticks(), 10);
    r.on_event(&closed(11, &[0, 1]));
    assert_eq!(r.hashed_ticks(), 2, "tick 1 decided by its sole reporter");
    let replay = Replay::parse(&r.take_bytes()).unwrap();
    assert_eq!(replay.hashes[..2], [Some(5), Some(6)]);
    assert_eq!(replay.departures, vec![(Slot(2), 1, "TimedOut".into())]);
}

#[test]
fn the_agreed_hash_carries_its_body_hashes_and_a_minority_s_are_dropped() {
    let mut r = three_players();
    r.on_event(&closed(0, &[0, 1, 2]));
    r.on_hash_with_bodies(Slot(2), 0, 9, Some(&[90, 91]));
    r.on_hash_with_bodies(Slot(0), 0, 7, Some(&[70, 71]));
    r.on_hash_with_bodies(Slot(1), 0, 7, Some(&[72, 73]));
    r.on_event(&closed(1, &[0, 1, 2]));
    for s in 0..3 {
        r.on_hash(Slot(s), 1, 8);
    }
    r.finish("done");
    let replay = Replay::parse(&r.take_bytes()).unwrap();
    assert_eq!(replay.hashes, vec![Some(7), Some(8)]);
    assert_eq!(replay.body_hashes, vec![(0, vec![70, 71])]);
    assert_eq!(replay.header.rules, RulesId::new("test", 1));
    assert_eq!(replay.header.engine_version, ENGINE_VERSION);
}

#[test]
fn a_version_1_replay_is_refused_as_older_than_the_header_fields() {
    let mut v = encode_preamble();
    v[8] = 1;
    let e = Replay::parse(&v).unwrap_err();
    assert!(matches!(
        e,
        ReplayError::WrongVersion {
            found: 1,
            expected: REPLAY_FORMAT_VERSION
        }
    ));
    // Version 2 files (no desync reports, no snapshots) still read.
    let mut r = three_players();
    r.on_event(&closed(0, &[0, 1, 2]));
    r.finish("done");
    let mut v2 = r.take_bytes();
    v2[8] = 2;
    assert_eq!(Replay::parse(&v2).unwrap().ticks.len(), 1);
    let text = e.to_string();
    assert!(
        text.contains("version 1") && text.contains("re-record"),
        "{text}"
    );
}

#[test]
fn a_split_without_majority_records_no_hash() {
    let mut r = ReplayRecorder::new(header(), 10).unwrap();
    r.on_event(&RoomEvent::PlayerJoined {
        id: id(0),
        name: "a".into(),
    });
    r.on_event(&RoomEvent::PlayerJoined {
        id: id(1),
        name: "b".into(),
    });
    r.on_event(&closed(0, &[0, 1]));
    r.on_hash(Slot(0), 0, 1);
    r.on_hash(Slot(1), 0, 2);
    r.finish("end");
    let replay = Replay::parse(&r.take_bytes()).unwrap();
    assert_eq!(replay.hashes, vec![None]);
    assert_eq!(replay.hashed_ticks(), 0);
}

#[test]
fn a_file_cut_anywhere_parses_up_to_the_cut() {
    let mut r = three_players();
    for t in 0..5 {
        r.on_event(&closed(t, &[0, 1, 2]));
        for s in 0..3 {
            r.on_hash(Slot(s), t, 100 + t);
        }
    }
    r.finish("end");
    let bytes = r.take_bytes();
    let full = Replay::parse(&bytes).unwrap();
    assert_eq!(full.ticks.len(), 5);
    assert_eq!(full.hashed_ticks(), 5);
    let mut seen_truncated = 0;
    for cut in REPLAY_PREAMBLE_BYTES..bytes.len() {
        match Replay::parse(&bytes[..cut]) {
            Ok(p) => {
                assert!(p.ticks.len() <= 5);
                assert!(p.truncated || p.end.is_none() || cut == bytes.len());
                seen_truncated += usize::from(p.truncated);
                // Every hash present belongs to a bundle present.
                assert_eq!(p.hashes.len(), p.ticks.len());
            }
            Err(ReplayError::NoHeader) => {}
            Err(e) => panic!("cut at {cut}: {e}"),
        }
    }
    assert!(seen_truncated > 20, "{seen_truncated}");
}

#[test]
fn bad_files_are_refused_with_a_reason() {
    assert!(matches!(
        Replay::parse(b"NOTAREPLAY"),
        Err(ReplayError::BadMagic)
    ));
    let mut v = encode_preamble();
    v[8] = 99;
    assert!(matches!(
        Replay::parse(&v),
        Err(ReplayError::WrongVersion { found: 99, .. })
    ));
    let mut v = encode_preamble();
    v.extend(encode_record(&ReplayRecord::Hash { tick: 0, hash: 1 }).unwrap());
    assert!(matches!(
        Replay::parse(&v),
        Err(ReplayError::MisplacedHeader { offset: 10 })
    ));
    let mut v = encode_preamble();
    v.extend(encode_record(&ReplayRecord::Header(header())).unwrap());
    v.extend(
        encode_record(&ReplayRecord::Tick(TickBundle {
            tick: 3,
            inputs: vec![],
        }))
        .unwrap(),
    );
    assert!(matches!(
        Replay::parse(&v),
        Err(ReplayError::TickGap {
            expected: 0,
            found: 3
        })
    ));
    let mut v = encode_preamble();
    v.extend(encode_record(&ReplayRecord::Header(header())).unwrap());
    v.extend(encode_record(&ReplayRecord::Hash { tick: 0, hash: 1 }).unwrap());
    assert!(matches!(Replay::parse(&v), Err(ReplayError::BadHash(0))));
    let mut v = encode_preamble();
    v.extend(u32::MAX.to_le_bytes());
    assert!(matches!(
        Replay::parse(&v),
        Err(ReplayError::RecordTooLarge { offset: 10, .. })
    ));
    let mut v = encode_preamble();
    v.extend(3u32.to_le_bytes());
    v.extend([0xff, 0xff, 0xff]);
    assert!(matches!(
        Replay::parse(&v),
        Err(ReplayError::Malformed { offset: 10, .. })
    ));
}
