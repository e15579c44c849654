//! The example game end to end: two bots and a polled client (as a game's
//! frame loop drives it) play it over QUIC against a real lockstep server
//! on loopback (every tick's hash compared by the room),
//! the server's replay passes the kit, the replays recorded in
//! `tests/replays` still pass, and a replay edited by one input byte fails
//! with the tick and the bodies named.
//!
//! To record a new reference replay: `EXAMPLE_GAME_RECORD=1 cargo test -p
//! lockstep-example-game --test match` copies the match's replay into
//! `tests/replays/` (see docs/own-game.md).

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use lockstep_client::bot::{BotOptions, run_bots};
use lockstep_client::game::RulesFactory;
use lockstep_client::net::{Client, ClientOptions};
use lockstep_example_game::{PaddleGame, PaddleInput, SCENE};
use lockstep_proto::Replay;
use lockstep_proto::replay::{ReplayRecord, encode_record};
use lockstep_server::{ServerConfig, ServerEvent, TlsSource, run};
use lockstep_tools::{ReplayVerifyError, verify_replay};
use tokio::sync::{mpsc, oneshot};

const TICKS: u64 = 180;

fn replays_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/replays")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_bots_and_a_polled_frame_loop_play_over_quic_agree_on_every_tick_and_the_replay_passes_the_kit()
 {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("example-game-match");
    let _ = std::fs::remove_dir_all(&dir);
    let mut config = ServerConfig::for_game(
        SocketAddr::from(([127, 0, 0, 1], 0)),
        SCENE,
        "example-game/scene.toml",
        PaddleGame.rules_id(),
    );
    config.tls = TlsSource::dev(dir.join("cert.pem"));
    config.replay_dir = Some(dir.join("replays"));
    config.room.start_players = 3;
    config.room.match_ticks = Some(TICKS);
    let (tx, mut events) = mpsc::unbounded_channel();
    config.events = Some(tx);
    let (stop, stop_rx) = oneshot::channel::<()>();
    let server = tokio::spawn(run(config, async {
        let _ = stop_rx.await;
    }));
    let (addr, cert) = loop {
        match events.recv().await.expect("server stopped at start-up") {
            ServerEvent::Listening { addr, cert } => break (addr, cert.expect("dev cert")),
            _ => continue,
        }
    };
    // The certificate as bytes, as a game shipping it in its binary would.
    let pem = std::fs::read(&cert).expect("cert");
    let mut options = BotOptions::for_game(
        addr,
        lockstep_client::net::TrustedCert::Pem(pem),
        "table",
        3,
        Arc::new(PaddleGame),
    );
    options.seed = 11;
    options.body_hashes_every = 1;
    options.count = 2;
    let bots_task = tokio::spawn(async move { run_bots(&options, std::future::pending()).await });
    // The third player is a game's frame loop: it polls the client each
    // frame (about 120 per second) and reads the world to "render" it.
    let mut live_options = ClientOptions::new(addr, cert.clone(), "table", "frame-loop");
    live_options.body_hashes_every = 1;
    let client = Client::connect(live_options, &PaddleGame)
        .await
        .expect("connect");
    let slot = client.slot().0;
    let mut live = client.start();
    let (mut frames, mut live_hashes, mut lowest_crate) = (0u64, Vec::new(), f64::MAX);
    while !live.is_closed() {
        let polled = live
            .poll(|tick| PaddleGame.bot_input(5, slot, tick))
            .expect("poll");
        live_hashes.extend(polled.ticks.iter().map(|t| t.hash));
        let world = live.world();
        for h in world.body_handles() {
            let b = world.body(h).expect("body");
            if b.name().starts_with("crate") {
                lowest_crate = lowest_crate.min(b.position().y.to_f64());
            }
        }
        frames += 1;
        tokio::time::sleep(Duration::from_millis(8)).await;
    }
    live.shutdown().await;
    let bots: Vec<_> = bots_task
        .await
        .expect("bots task")
        .into_iter()
        .map(|r| r.expect("bot"))
        .collect();
    assert_eq!(live_hashes, bots[0].hashes);
    // 3 s of match at ~120 frames per second, fewer on a loaded machine.
    assert!(frames > TICKS, "{frames} frames");
    // Crates rest on the table (centre 0.4 m up) or fell off it.
    assert!(lowest_crate < 0.41, "{lowest_crate}");
    let ended = loop {
        match events.recv().await.expect("server events") {
            ServerEvent::MatchEnded(r) => break r,
            _ => continue,
        }
    };
    let _ = stop.send(());
    server.await.expect("server task").expect("server");
    assert_eq!(ended.ticks, TICKS);
    assert!(ended.desyncs.is_empty(), "{:?}", ended.desyncs);
    assert_eq!(ended.mismatched_ticks, 0);
    assert_eq!(ended.ticks_compared, TICKS);
    for b in &bots {
        assert_eq!(b.hashes.len() as u64, TICKS);
        assert_eq!(b.hashes, bots[0].hashes);
    }
    let replay = ended.replay.expect("replay");
    let parsed = Replay::parse(&std::fs::read(&replay).unwrap()).unwrap();
    assert_eq!(parsed.header.rules, PaddleGame.rules_id());
    assert_eq!(parsed.body_hashes.len() as u64, TICKS);
    // The game moved: balls were dropped, so bodies were spawned.
    let inputs = parsed.ticks.iter().flat_map(|t| &t.inputs);
    let drops = inputs
        .filter(|p| PaddleInput::decode(&p.input).is_some_and(|i| i.drop))
        .count();
    assert!(drops >= 3, "{drops} drops");
    let report = lockstep_testkit::assert_replays(replay.parent().unwrap(), &PaddleGame);
    assert_eq!(report.hashes_checked(), TICKS);
    if std::env::var_os("EXAMPLE_GAME_RECORD").is_some() {
        let to = replays_dir().join("three-players.replay");
        std::fs::copy(&replay, &to).expect("copy the replay into tests/replays");
        println!("recorded {}", to.display());
    }
}

#[test]
fn the_recorded_replays_still_pass() {
    let report = lockstep_testkit::assert_replays(replays_dir(), &PaddleGame);
    assert!(report.hashes_checked() >= TICKS, "{report:?}");
}

#[test]
fn a_replay_edited_by_one_input_byte_fails_at_that_tick_naming_the_paddle() {
    let path = replays_dir().join("three-players.replay");
    let bytes = std::fs::read(&path).expect("recorded replay");
    let replay = Replay::parse(&bytes).expect("parses");
    // The first tick after 60 where slot 0 moves: reverse its direction.
    let (tick, at) = replay
        .ticks
        .iter()
        .enumerate()
        .skip(60)
        .find_map(|(t, b)| {
            let i = b.inputs.iter().position(|p| p.slot.0 == 0)?;
            let dir = PaddleInput::decode(&b.inputs[i].input)?.dir;
            (dir > 0).then_some((t, i))
        })
        .expect("slot 0 moves");
    let original = replay.ticks[tick].clone();
    let mut edited = original.clone();
    let dir = edited.inputs[at].input[0];
    edited.inputs[at].input[0] = (dir - 1 + 4) % 8 + 1;
    let old = encode_record(&ReplayRecord::Tick(original)).unwrap();
    let new = encode_record(&ReplayRecord::Tick(edited)).unwrap();
    let pos = bytes
        .windows(old.len())
        .position(|w| w == old.as_slice())
        .expect("the tick's record in the file");
    let mut changed = bytes.clone();
    changed[pos..pos + new.len()].copy_from_slice(&new);
    let differing = bytes.iter().zip(&changed).filter(|(a, b)| a != b).count();
    assert_eq!(differing, 1, "one input byte edited");
    // The check names the tick and the paddle.
    let edited_replay = Replay::parse(&changed).unwrap();
    match verify_replay(&edited_replay, &PaddleGame) {
        Err(ReplayVerifyError::Mismatch {
            tick: t,
            bodies: Some(b),
            ..
        }) => {
            assert_eq!(t, tick as u64);
            assert_eq!(b.tick, tick as u64);
            let names: Vec<_> = b.bodies.iter().map(|d| d.name.as_str()).collect();
            assert!(names.contains(&"paddle0"), "{names:?}");
        }
        other => panic!("expected a mismatch at tick {tick}, got {other:?}"),
    }
    // And the kit says so for the folder, naming the file.
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("example-game-edited");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("edited.replay"), &changed).unwrap();
    let failure = lockstep_testkit::check_replays(&dir, &PaddleGame).unwrap_err();
    let text = failure.to_string();
    assert!(text.contains("edited.replay: mismatch at tick"), "{text}");
    assert!(text.contains(&format!("tick {tick}:")), "{text}");
    assert!(text.contains("\"paddle0\""), "{text}");
}

#[test]
fn a_cut_replay_fails_the_kit_though_what_it_holds_matches() {
    let bytes = std::fs::read(replays_dir().join("three-players.replay")).expect("recorded replay");
    let whole = Replay::parse(&bytes).expect("parses");
    assert!(whole.end.is_some(), "the recorded replay is a whole match");
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("example-game-cut");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    // Cut at a record boundary (the end record dropped) and in the middle
    // of a record.
    let mut at = 10;
    let mut boundaries = Vec::new();
    while at + 4 <= bytes.len() {
        boundaries.push(at);
        at += 4 + u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    }
    let last = *boundaries.last().unwrap();
    std::fs::write(dir.join("a-no-end.replay"), &bytes[..last]).unwrap();
    // Inside the record that starts half-way through the file.
    let inside = boundaries[boundaries.len() / 2] + 6;
    std::fs::write(dir.join("b-half.replay"), &bytes[..inside]).unwrap();
    std::fs::copy(
        replays_dir().join("three-players.replay"),
        dir.join("c-whole.replay"),
    )
    .unwrap();
    let failure = lockstep_testkit::check_replays(&dir, &PaddleGame).unwrap_err();
    let text = failure.to_string();
    assert!(text.starts_with("2 of 3 replays failed:"), "{text}");
    assert!(text.contains("a-no-end.replay: cut at tick"), "{text}");
    assert!(!text.contains("a-no-end.replay: cut at tick 0"), "{text}");
    assert!(text.contains("b-half.replay: cut at tick"), "{text}");
    assert!(text.contains("last record is incomplete"), "{text}");
    assert!(!text.contains("c-whole.replay"), "{text}");
    let lockstep_testkit::KitFailure::Replays {
        cut,
        passed,
        failed,
    } = failure
    else {
        panic!("{text}");
    };
    assert!(failed.is_empty());
    assert_eq!(cut.len(), 2);
    assert_eq!(passed.len(), 1);
    assert!(cut.iter().all(|(_, c)| c.checked > 0 && c.is_cut()));
}
