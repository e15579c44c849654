//! `lockstep replay` end to end: replays recorded with the server's recorder
//! from an offline match, checked by the binary.

use std::path::PathBuf;
use std::process::Command;

use lockstep_client::game::{Demo, DemoGame, DemoInput, RulesFactory, bot_input};
use lockstep_proto::{
    PROTOCOL_VERSION, PlayerId, PlayerInput, ReplayHeader, ReplayRecorder, RoomEvent, RulesId,
    Slot, TickBundle,
};
use lockstep_tools::apply_bundle;

/// Plays `ticks` ticks of the demo offline with two players and records
/// them; `corrupt` makes both players report a wrong hash at that tick.
fn record(ticks: u64, corrupt: Option<u64>) -> Vec<u8> {
    record_with(ticks, corrupt, |_| {})
}

/// As [`record`], with the header changed by `tweak` before recording.
fn record_with(ticks: u64, corrupt: Option<u64>, tweak: impl FnOnce(&mut ReplayHeader)) -> Vec<u8> {
    record_lying(ticks, corrupt, None, tweak)
}

/// As [`record_with`]; `lie_at` writes another input for player 0 into the
/// file at that tick than the one simulated (body hashes are recorded).
fn record_lying(
    ticks: u64,
    corrupt: Option<u64>,
    lie_at: Option<u64>,
    tweak: impl FnOnce(&mut ReplayHeader),
) -> Vec<u8> {
    let mut world = DemoGame::world().expect("demo scene");
    let mut game = DemoGame::new(&world).expect("demo game");
    let header = ReplayHeader {
        protocol_version: PROTOCOL_VERSION,
        room: "cli".into(),
        tick_rate: 60,
        input_delay: 4,
        scene_hash: world.state_hash(),
        scene: DemoGame::SCENE.as_bytes().to_vec(),
        engine_version: lockstep_proto::ENGINE_VERSION.into(),
        hash_layout: lockstep_core::world::STATE_HASH_VERSION,
        rules: Demo.rules_id(),
    };
    let mut header = header;
    tweak(&mut header);
    let mut rec = ReplayRecorder::new(header, 120).expect("header");
    // The match starts with its seed (0: the recorder's).
    lockstep_client::game::start_match(&mut world, 0).expect("seed");
    for s in 0..2u8 {
        rec.on_event(&RoomEvent::PlayerJoined {
            id: PlayerId {
                slot: Slot(s),
                generation: 0,
            },
            name: format!("p{s}"),
        });
    }
    for tick in 0..ticks {
        let bundle = TickBundle {
            tick,
            inputs: (0..2u8)
                .map(|s| PlayerInput {
                    slot: Slot(s),
                    input: bot_input(7, s, tick).encode(),
                    substituted: false,
                })
                .collect(),
        };
        apply_bundle(&mut world, &mut game, &bundle).expect("tick");
        let mut bundle = bundle;
        if lie_at == Some(tick) {
            // The file says player 0 pressed something else than it did.
            bundle.inputs[0].input = DemoInput {
                move_x: 100,
                move_z: 0,
                jump: false,
            }
            .encode();
        }
        rec.on_event(&RoomEvent::TickClosed(bundle));
        let hash = world.state_hash() ^ u64::from(corrupt == Some(tick));
        for s in 0..2u8 {
            let bodies: Vec<u64> = world.body_hashes().iter().map(|(_, h)| *h).collect();
            rec.on_hash_with_bodies(Slot(s), tick, hash, Some(&bodies));
        }
    }
    rec.finish("test over");
    rec.take_bytes()
}

fn run(name: &str, bytes: &[u8]) -> (i32, String) {
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::write(&path, bytes).expect("write replay");
    let out = Command::new(env!("CARGO_BIN_EXE_lockstep"))
        .arg("replay")
        .arg(&path)
        .output()
        .expect("run lockstep");
    let text =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    (out.status.code().unwrap_or(-1), text)
}

#[test]
fn a_faithful_replay_prints_ok_and_exits_zero() {
    let (code, out) = run("faithful.replay", &record(120, None));
    assert_eq!(code, 0, "{out}");
    assert!(
        out.starts_with("OK: 120 ticks re-simulated, 120 hashes checked"),
        "{out}"
    );
}

#[test]
fn a_wrong_hash_at_tick_77_is_named_and_exits_one() {
    let good = record(120, None);
    let (code, out) = run("corrupt.replay", &record(120, Some(77)));
    assert_eq!(code, 1, "{out}");
    let replay = lockstep_proto::Replay::parse(&good).unwrap();
    let expected = replay.hashes[77].unwrap() ^ 1;
    let got = replay.hashes[77].unwrap();
    assert_eq!(
        out.trim(),
        format!("MISMATCH at tick 77: expected {expected:016x}, got {got:016x}")
    );
}

#[test]
fn a_file_that_is_not_a_replay_exits_two() {
    let (code, out) = run("garbage.replay", b"this is not a replay");
    assert_eq!(code, 2, "{out}");
    assert!(out.contains("not a lockstep replay"), "{out}");
}

#[test]
fn a_replay_of_other_rules_says_so_and_exits_three() {
    let bytes = record_with(10, None, |h| {
        h.rules = RulesId::new("someone-elses-game", 4)
    });
    let (code, out) = run("other-rules.replay", &bytes);
    assert_eq!(code, 3, "{out}");
    assert!(
        out.contains("recorded with rules someone-elses-game v4, this check uses lockstep-demo v3"),
        "{out}"
    );
    // And how to check it.
    assert!(
        out.contains("check it with that game's own program"),
        "{out}"
    );
    assert!(out.contains("lockstep_testkit::assert_replays"), "{out}");
    let bytes = record_with(10, None, |h| h.rules.version = Demo::VERSION + 1);
    let (code, out) = run("other-rules-version.replay", &bytes);
    assert_eq!(code, 3, "{out}");
}

#[test]
fn a_replay_of_another_hash_layout_says_so_and_exits_four() {
    let layout = lockstep_core::world::STATE_HASH_VERSION;
    let bytes = record_with(10, None, |h| h.hash_layout = layout - 1);
    let (code, out) = run("other-layout.replay", &bytes);
    assert_eq!(code, 4, "{out}");
    assert!(
        out.contains(&format!(
            "state-hash layout {} (engine {}), this engine hashes with layout {layout}",
            layout - 1,
            lockstep_proto::ENGINE_VERSION
        )),
        "{out}"
    );
}

#[test]
fn a_version_1_replay_is_refused_with_a_clear_error() {
    let mut bytes = record(10, None);
    bytes[8..10].copy_from_slice(&1u16.to_le_bytes());
    let (code, out) = run("v1.replay", &bytes);
    assert_eq!(code, 2, "{out}");
    assert!(
        out.contains("replay format version 1") && out.contains("re-record"),
        "{out}"
    );
}

#[test]
fn a_changed_input_is_named_with_its_tick_and_the_player_s_body() {
    let (code, out) = run("lie.replay", &record_lying(120, None, Some(50), |_| {}));
    assert_eq!(code, 1, "{out}");
    let mut lines = out.lines();
    assert!(
        lines.next().unwrap().starts_with("MISMATCH at tick 50: "),
        "{out}"
    );
    // Player 0's body moved otherwise at once; nothing else yet.
    let bodies: Vec<_> = lines.collect();
    assert_eq!(bodies.len(), 1, "{out}");
    assert!(bodies[0].starts_with("  at tick 50: body #"), "{out}");
    assert!(bodies[0].contains("\"player0\": expected "), "{out}");
}

/// A replay whose end record is missing (the server stopped while
/// recording) is reported as cut, with the tick where it stops, not as a
/// whole match: exit status 5. Cut inside a record, it says so too.
#[test]
fn a_replay_without_its_end_is_reported_as_cut_at_its_last_tick() {
    let whole = record(120, None);
    let end = lockstep_proto::replay::encode_record(&lockstep_proto::ReplayRecord::End {
        ticks: 120,
        reason: "test over".into(),
    })
    .expect("end record");
    let at_boundary = &whole[..whole.len() - end.len()];
    assert!(
        lockstep_proto::Replay::parse(at_boundary)
            .unwrap()
            .end
            .is_none()
    );
    let (code, out) = run("cut.replay", at_boundary);
    assert_eq!(code, 5, "{out}");
    assert!(
        out.starts_with("CUT at tick 120: the file has no end record (the server"),
        "{out}"
    );
    assert!(out.contains("120 hashes checked"), "{out}");
    let (code, out) = run("cut-inside.replay", &whole[..whole.len() - 1]);
    assert_eq!(code, 5, "{out}");
    assert!(
        out.starts_with(
            "CUT at tick 120: the file has no end record and its last record is incomplete"
        ),
        "{out}"
    );
}

/// The demo world after `ticks` ticks of the two players [`record`] plays.
fn world_after(ticks: u64) -> lockstep_core::World {
    let mut world = DemoGame::world().expect("demo scene");
    lockstep_client::game::start_match(&mut world, 0).expect("seed");
    let mut game = DemoGame::new(&world).expect("demo game");
    for tick in 0..ticks {
        let bundle = TickBundle {
            tick,
            inputs: (0..2u8)
                .map(|s| PlayerInput {
                    slot: Slot(s),
                    input: bot_input(7, s, tick).encode(),
                    substituted: false,
                })
                .collect(),
        };
        apply_bundle(&mut world, &mut game, &bundle).expect("tick");
    }
    world
}

/// A desync bundle of tick 60 (61 ticks recorded): the room's report says
/// slot 1's body #5 had one ulp more x velocity than slot 0's, whose values
/// `expected` overrides when given; the snapshot is the world after tick 59
/// (or `snapshot` when given).
fn bundle(expected: Option<Vec<u64>>, snapshot: Option<Vec<u8>>) -> Vec<u8> {
    bundle_with(expected, None, snapshot)
}

/// [`bundle`] with the diverging player's values `got` given too.
fn bundle_with(
    expected: Option<Vec<u64>>,
    got: Option<Vec<u64>>,
    snapshot: Option<Vec<u8>>,
) -> Vec<u8> {
    use lockstep_proto::replay::encode_record;
    use lockstep_proto::{
        BodyDiff, DesyncReport, FieldDiff, ProbeStatus, ReplayRecord, SuspectReport,
    };
    let at_59 = world_after(60);
    let at_60 = world_after(61);
    let dump = lockstep_client::net::dump_bodies(&at_60, &[5]).remove(0);
    let v = dump
        .fields
        .iter()
        .find(|f| f.name == "linear_velocity")
        .unwrap()
        .words
        .clone();
    let got = got.unwrap_or_else(|| {
        let mut g = v.clone();
        g[0] = g[0].wrapping_add(1);
        g
    });
    let report = DesyncReport {
        tick: 60,
        reference: Slot(0),
        majority: false,
        reference_status: ProbeStatus::Complete,
        suspects: vec![SuspectReport {
            slot: Slot(1),
            status: ProbeStatus::Complete,
            bodies_differing: 1,
            contacts_differ: false,
            game_differs: false,
            game: Vec::new(),
            bodies: vec![BodyDiff {
                index: 5,
                handle: dump.handle,
                generation: dump.generation,
                name: dump.name.clone(),
                fields: vec![FieldDiff {
                    name: "linear_velocity".into(),
                    kind: lockstep_proto::FieldKind::Scalar,
                    expected: expected.unwrap_or(v),
                    got,
                }],
            }],
        }],
        fields_omitted: 0,
        inputs: Vec::new(),
    };
    let snap = snapshot.unwrap_or_else(|| at_59.snapshot());
    let mut bytes = record(61, None);
    bytes.extend(encode_record(&ReplayRecord::Located(report)).unwrap());
    let piece = ReplayRecord::Snapshot {
        tick: 59,
        hash: at_59.state_hash(),
        total: snap.len() as u64,
        offset: 0,
        bytes: snap,
    };
    bytes.extend(encode_record(&piece).unwrap());
    bytes
}

#[test]
fn a_desync_bundle_reproduces_the_body_and_field_diff_offline() {
    let (code, out) = run("good.bundle", &bundle(None, None));
    assert_eq!(code, 0, "{out}");
    assert!(
        out.starts_with(
            "BUNDLE REPRODUCED: 60 agreed hashes checked up to tick 60, the snapshot of tick 59 matches"
        ),
        "{out}"
    );
    assert!(out.contains("body #5 \"player0\""), "{out}");
    assert!(out.contains("linear_velocity:"), "{out}");
}

#[test]
fn a_bundle_whose_majority_values_this_machine_does_not_produce_exits_one() {
    let (code, out) = run("other.bundle", &bundle(Some(vec![0, 0, 0]), None));
    assert_eq!(code, 1, "{out}");
    assert!(out.starts_with("BUNDLE NOT REPRODUCED"), "{out}");
    // This machine's values are shown as the expected ones.
    assert!(
        !out.contains("expected [0 (0x0000000000000000), 0 "),
        "{out}"
    );
}

#[test]
fn a_bundle_whose_odd_one_out_this_build_matches_says_so_without_the_field_dump() {
    // The majority recorded other values; the diverging slot 1 recorded
    // exactly what this build computes.
    let ours = {
        let at_60 = world_after(61);
        let dump = lockstep_client::net::dump_bodies(&at_60, &[5]).remove(0);
        let f = dump.fields.iter().find(|f| f.name == "linear_velocity");
        f.unwrap().words.clone()
    };
    let bytes = bundle_with(Some(vec![0, 0, 0]), Some(ours), None);
    let (code, out) = run("odd.bundle", &bytes);
    assert_eq!(code, 1, "{out}");
    assert!(
        out.starts_with("BUNDLE NOT REPRODUCED: this build simulates as slot 1 did"),
        "{out}"
    );
    assert!(
        out.contains("(slot 1's 1 fields, equal to this machine's, not listed)"),
        "{out}"
    );
    assert!(!out.contains("linear_velocity:"), "{out}");
}

#[test]
fn a_bundle_with_a_foreign_snapshot_is_refused_with_its_tick() {
    let other = world_after(30).snapshot();
    let (code, out) = run("snap.bundle", &bundle(None, Some(other)));
    assert_eq!(code, 1, "{out}");
    assert!(
        out.contains("the snapshot of tick 59: agreed hash"),
        "{out}"
    );
}

/// The README lists every exit status of `lockstep replay`, the ones of
/// `lockstep_tools::exit_status` and nothing else; a command
/// line without a file is a usage error (2).
#[test]
fn the_readme_lists_every_replay_exit_status() {
    use lockstep_tools::exit_status;
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../README.md"))
        .expect("README.md");
    let start = readme
        .find("`lockstep replay FILE` re-simulates")
        .expect("the replay section");
    let table = &readme[start..];
    let table = &table[table.find("| status | meaning |").expect("the table")..];
    let listed: Vec<u8> = table
        .lines()
        .skip(2)
        .take_while(|l| l.starts_with('|'))
        .map(|l| {
            l.split('|')
                .nth(1)
                .unwrap()
                .trim()
                .parse()
                .expect("a status")
        })
        .collect();
    let every = [
        exit_status::OK,
        exit_status::MISMATCH,
        exit_status::INVALID,
        exit_status::WRONG_RULES,
        exit_status::WRONG_HASH_LAYOUT,
        exit_status::CUT,
    ];
    assert_eq!(listed, every);
    let out = Command::new(env!("CARGO_BIN_EXE_lockstep"))
        .arg("replay")
        .output()
        .expect("run lockstep");
    assert_eq!(out.status.code(), Some(2));
}
