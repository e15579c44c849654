//! End-to-end matches over real QUIC on 127.0.0.1: the server library, bots
//! built on the client library, the replay format and the offline verifier.
//!
//! Every test runs its own server on a free port with its own certificate
//! and replay directory, so the tests of this file run in parallel (cargo
//! runs the test binaries one after another, so they share one file): the
//! two 1,200-tick matches take 20 s each, and the whole file about as long.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use bytes::Bytes;
use lockstep_client::bot::{BotOptions, run_bots};
use lockstep_client::game::{Demo, DemoGame};
use lockstep_client::net::{client_config, load_certs, read_frame, write_frame};
use lockstep_client::testing::Diverge;
use lockstep_proto::{
    ClientMessage, CloseReason, InputDatagram, Replay, ServerMessage, Session, Slot, Verdict,
};
use lockstep_server::ServerEvent;
use lockstep_tests::harness::{TestServer, assert_same_hashes, bots_ok};
use lockstep_tests::link::{LinkConditioner, LinkConfig};
use lockstep_tools::verify_replay_file;

/// The configuration the `lockstep-server` program runs with given only
/// `--scene` (and `extra` flags), on the harness's address, certificate,
/// replay directory and events.
fn program_config(c: &mut lockstep_server::ServerConfig, extra: &[&str]) {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/demo.toml");
    let args = ["lockstep-server", "--scene", scene]
        .into_iter()
        .chain(extra.iter().copied());
    let mut p = lockstep::App::demo()
        .server_config(args)
        .expect("the program's flags");
    p.listen = c.listen;
    p.tls = c.tls.clone();
    p.replay_dir = c.replay_dir.clone();
    p.events = c.events.take();
    *c = p;
}

/// The directory of a test's server (certificate, replays).
fn tmp(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("e2e-{name}"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn four_bots_agree_on_every_tick_of_1200_and_the_replay_reverifies() {
    let started = Instant::now();
    let mut server = TestServer::start(tmp("agree"), |c| {
        c.room.start_players = 4;
        c.room.match_ticks = Some(1200);
    })
    .await;
    let bots = run_bots(
        &BotOptions::new(server.addr, &server.cert, "agree", 4),
        std::future::pending(),
    )
    .await;
    let bots = bots_ok(bots);
    let ended = server.match_end(Duration::from_secs(10)).await;
    let report = server.shutdown().await;
    assert_same_hashes(&bots, 1200);
    for b in &bots {
        assert_eq!(b.desyncs().count(), 0);
        let close = b.close.as_ref().expect("closed by the server");
        assert_eq!(close.reason, CloseReason::RoomClosed);
    }
    assert_eq!(ended.ticks, 1200);
    assert_eq!(ended.ticks_compared, 1200);
    assert_eq!(ended.mismatched_ticks, 0);
    assert!(ended.desyncs.is_empty());
    assert_eq!(report.matches.len(), 1);
    assert!(report.refused.is_empty(), "{:?}", report.refused);
    let path = ended.replay.expect("replay recorded");
    let check = verify_replay_file(&path, &Demo).expect("replay verifies");
    assert_eq!((check.ticks, check.checked, check.players), (1200, 1200, 4));
    assert_eq!(check.final_hash, bots[0].hashes[1199]);
    // Figures for docs/protocol.md.
    let secs = ended.duration.as_secs_f64();
    for p in &ended.players {
        println!(
            "slot {}: UDP down {:.0} B/s up {:.0} B/s; datagrams down {} (max {} B) up {} (max {} B); substituted {}",
            p.slot.0,
            p.udp_bytes_down as f64 / secs,
            p.udp_bytes_up as f64 / secs,
            p.datagrams_down,
            p.max_datagram_down,
            p.datagrams_up,
            p.max_datagram_up,
            p.inputs_substituted
        );
    }
    let b = &bots[0];
    println!(
        "bot 0 protocol bytes: datagrams up {} B in {} (mean {:.1} B), down {} B in {} (mean {:.1} B), frames up {} B in {}",
        b.traffic.datagram_bytes_sent,
        b.traffic.datagrams_sent,
        b.traffic.datagram_bytes_sent as f64 / b.traffic.datagrams_sent as f64,
        b.traffic.datagram_bytes_received,
        b.traffic.datagrams_received,
        b.traffic.datagram_bytes_received as f64 / b.traffic.datagrams_received as f64,
        b.traffic.frame_bytes_sent,
        b.traffic.frames_sent
    );
    println!("agree: wall time {:.1} s", started.elapsed().as_secs_f64());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_bot_nudged_one_ulp_at_tick_300_is_the_only_one_reported_at_tick_300() {
    let mut server = TestServer::start(tmp("diverge"), |c| {
        program_config(c, &[]);
        c.room.start_players = 4;
        c.room.match_ticks = Some(420);
    })
    .await;
    let mut options = BotOptions::new(server.addr, &server.cert, "diverge", 4);
    options.game_of_bot = vec![(
        2,
        std::sync::Arc::new(Diverge {
            inner: std::sync::Arc::new(Demo),
            tick: 300,
        }),
    )];
    let bots = bots_ok(run_bots(&options, std::future::pending()).await);
    let mut notice_at = None;
    let mut located_at = None;
    let ended = server
        .wait_for(Duration::from_secs(10), |e| match e {
            ServerEvent::Desync { .. } => {
                notice_at = Some(Instant::now());
                None
            }
            ServerEvent::DesyncLocated { at, .. } => {
                located_at = Some(*at);
                None
            }
            ServerEvent::MatchEnded(r) => Some(r.clone()),
            _ => None,
        })
        .await;
    server.shutdown().await;
    let odd = bots
        .iter()
        .find(|b| b.slot == Slot(2))
        .expect("bot in slot 2");
    let good: Vec<_> = bots.iter().filter(|b| b.slot != Slot(2)).collect();
    // Same up to tick 299, different from tick 300 on.
    assert_eq!(odd.hashes[..300], good[0].hashes[..300]);
    assert_ne!(odd.hashes[300], good[0].hashes[300]);
    // The room saw it on that tick, said who, and said it once.
    assert_eq!(ended.desyncs.len(), 1, "{:?}", ended.desyncs);
    let notice = &ended.desyncs[0];
    assert_eq!(notice.tick, 300);
    match &notice.verdict {
        Verdict::Verified { hash, wrong } => {
            assert_eq!(wrong, &vec![Slot(2)]);
            assert_eq!(*hash, good[0].hashes[300]);
        }
        other => panic!("expected a verified verdict, got {other:?}"),
    }
    assert_eq!(ended.mismatched_ticks, 120, "ticks 300..420 all mismatch");
    // Every player was told, with their own hash alongside.
    for b in &bots {
        let n: Vec<_> = b.desyncs().collect();
        assert_eq!(n.len(), 1);
        assert_eq!(n[0].tick, 300);
    }
    // The replay keeps the server's own hashes: it verifies.
    let check =
        verify_replay_file(ended.replay.as_ref().expect("replay"), &Demo).expect("replay verifies");
    assert_eq!(
        (check.ticks, check.checked, check.desyncs_recorded),
        (420, 420, 1)
    );
    // Located on that tick: the nudged body (the scene's first dynamic
    // body) and its linear velocity, found by the odd bot's dump against
    // slot 0's.
    assert_eq!(ended.located.len(), 1, "{:?}", ended.located);
    let r = &ended.located[0];
    println!("{r}");
    assert_eq!((r.tick, r.reference, r.majority), (300, Slot(0), true));
    assert_eq!(r.suspects.len(), 1);
    assert_eq!(r.suspects[0].slot, Slot(2));
    assert_eq!(r.suspects[0].status, lockstep_proto::ProbeStatus::Complete);
    let world = lockstep_core::scene::load_world(DemoGame::SCENE, "demo").unwrap();
    let nudged = world
        .body_handles()
        .find(|&h| world.body(h).unwrap().kind() == lockstep_core::BodyKind::Dynamic)
        .unwrap();
    let first = r.first_body().expect("a diverging body");
    assert_eq!(
        (first.handle, first.name.as_str()),
        (nudged.index(), world.body(nudged).unwrap().name())
    );
    let names: Vec<&str> = first.fields.iter().map(|f| f.name.as_str()).collect();
    assert!(names.contains(&"linear_velocity"), "{names:?}");
    // Every player was told where, in the same words.
    for b in &bots {
        let got: Vec<_> = b
            .events
            .iter()
            .filter_map(|e| match e {
                lockstep_client::net::ClientEvent::DesyncLocated(x) => Some(x),
                _ => None,
            })
            .collect();
        assert_eq!(got, vec![r], "slot {}", b.slot.0);
    }
    // The replay holds the report too.
    let replay = Replay::parse(&std::fs::read(ended.replay.as_ref().unwrap()).unwrap()).unwrap();
    assert_eq!(replay.located, vec![r.clone()]);
    // The bundle re-simulates offline to the same diff, its snapshot of
    // tick 299 checked, and passes as a regression test.
    assert_eq!(ended.bundles.len(), 1);
    let bundle = Replay::parse(&std::fs::read(&ended.bundles[0]).unwrap()).unwrap();
    let c = lockstep_tools::reproduce_bundle(&bundle, &Demo).expect("bundle reproduces");
    assert_eq!(c.snapshot_tick, Some(299));
    assert_eq!(c.hashes_checked, 300);
    assert!(c.reproduces());
    assert_eq!(c.offline.to_string(), r.to_string());
    let kit = verify_replay_file(&ended.bundles[0], &Demo).expect("the bundle passes");
    assert_eq!(kit.checked, 300);
    let (notice_at, located_at) = (notice_at.unwrap(), located_at.unwrap());
    println!(
        "localization: {} B down (probes and reports to 4 players), {} B up (replies), located {:.1} ms after the notice, bundle {} B",
        ended.forensics_bytes_down,
        ended.forensics_bytes_up,
        located_at
            .saturating_duration_since(notice_at)
            .as_secs_f64()
            * 1e3,
        std::fs::metadata(&ended.bundles[0]).unwrap().len()
    );
    // A generous bound (the figure is printed above): a loaded 2-core machine cannot fail it.
    assert!(located_at.saturating_duration_since(notice_at) < Duration::from_secs(10));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_lossy_jittery_link_keeps_1200_ticks_in_sync_and_none_a_second_late() {
    /// Ticks in the match; every one's lateness is asserted, the last included.
    const TICKS: usize = 1200;
    let mut server = TestServer::start(tmp("link"), |c| {
        c.room.start_players = 4;
        c.room.match_ticks = Some(TICKS as u64);
        // 50 ± 10 ms each way: a 100–120 ms round trip needs 7–8 ticks.
        c.room.input_delay = 10;
    })
    .await;
    let link = LinkConditioner::start(
        server.addr,
        LinkConfig {
            latency: Duration::from_millis(50),
            jitter: Duration::from_millis(10),
            loss: 0.05,
            duplicate: 0.02,
            reorder: 0.05,
            seed: 0x5eed,
        },
    )
    .await
    .expect("link conditioner");
    let options = BotOptions::new(link.local_addr(), &server.cert, "link", 4);
    let bots_task = tokio::spawn(async move { run_bots(&options, std::future::pending()).await });
    let (epoch, rate) = server
        .wait_for(Duration::from_secs(20), |e| match e {
            ServerEvent::MatchStarted {
                epoch, tick_rate, ..
            } => Some((*epoch, *tick_rate)),
            _ => None,
        })
        .await;
    let bots = bots_ok(bots_task.await.expect("bots"));
    let ended = server.match_end(Duration::from_secs(10)).await;
    let stats = link.stats();
    link.stop().await;
    server.shutdown().await;
    assert_same_hashes(&bots, TICKS);
    assert!(ended.desyncs.is_empty());
    assert_eq!(ended.mismatched_ticks, 0);
    // Lateness: when the bundle became applicable at the client (in order)
    // minus the tick's deadline on the server's clock (same process), over
    // every tick. The final tick has no later tick's datagram to carry a
    // redundant copy; the server repeats it once per tick period until
    // acknowledged, so it is held to the same bar.
    let deadline = |t: u64| epoch + Duration::from_nanos((t + 1) * 1_000_000_000 / u64::from(rate));
    let mut worst = Duration::ZERO;
    let mut worst_at = (0, 0);
    let mut total = Duration::ZERO;
    let mut final_tick_worst = Duration::ZERO;
    for b in &bots {
        assert_eq!(b.delivered_at.len(), TICKS, "slot {}", b.slot.0);
        let last = (TICKS - 1) as u64;
        final_tick_worst = final_tick_worst
            .max(b.delivered_at[TICKS - 1].saturating_duration_since(deadline(last)));
        for (i, at) in b.delivered_at.iter().enumerate() {
            let late = at.saturating_duration_since(deadline(i as u64));
            total += late;
            if late > worst {
                worst = late;
                worst_at = (b.slot.0, i);
            }
        }
    }
    let mean = total / (bots.len() * TICKS) as u32;
    println!(
        "link: the match's final tick was delivered at worst {:.1} ms late",
        final_tick_worst.as_secs_f64() * 1000.0
    );
    let secs = ended.duration.as_secs_f64();
    println!(
        "link: worst lateness {:.1} ms (slot {}, tick {}), mean {:.1} ms; link {:?}",
        worst.as_secs_f64() * 1000.0,
        worst_at.0,
        worst_at.1,
        mean.as_secs_f64() * 1000.0,
        stats
    );
    for p in &ended.players {
        println!(
            "link slot {}: UDP down {:.0} B/s up {:.0} B/s, max datagram down {} B up {} B, rtt {:?}, substituted {}",
            p.slot.0,
            p.udp_bytes_down as f64 / secs,
            p.udp_bytes_up as f64 / secs,
            p.max_datagram_down,
            p.max_datagram_up,
            p.rtt,
            p.inputs_substituted
        );
    }
    assert!(stats.dropped > 100 && stats.duplicated > 20, "{stats:?}");
    // A generous bound (the measured figure is printed above): it catches a
    // tick that waits far longer than the link's 60 ms, and a loaded 2-core
    // machine's stalls cannot reach it.
    assert!(worst <= Duration::from_secs(1), "worst lateness {worst:?}");
}

/// A raw client: connects, joins, returns its stream and welcome.
async fn raw_join(
    server: SocketAddr,
    cert: &std::path::Path,
    room: &str,
    name: &str,
) -> (
    quinn::Endpoint,
    quinn::Connection,
    quinn::SendStream,
    quinn::RecvStream,
    Slot,
) {
    let (endpoint, connection, mut send, mut recv) = raw_connect(server, cert).await;
    let join = Session::join_message(room, name).encode().expect("join");
    write_frame(&mut send, &join).await.expect("write join");
    let frame = read_frame(&mut recv)
        .await
        .expect("welcome")
        .expect("frame");
    let ServerMessage::Welcome(w) = ServerMessage::decode(&frame).expect("decode") else {
        panic!("expected a welcome");
    };
    (endpoint, connection, send, recv, w.slot)
}

async fn raw_connect(
    server: SocketAddr,
    cert: &std::path::Path,
) -> (
    quinn::Endpoint,
    quinn::Connection,
    quinn::SendStream,
    quinn::RecvStream,
) {
    let config = client_config(&load_certs(cert).expect("cert")).expect("tls");
    let mut endpoint = quinn::Endpoint::client("127.0.0.1:0".parse().unwrap()).expect("socket");
    endpoint.set_default_client_config(config);
    let connection = endpoint
        .connect(server, "localhost")
        .expect("connect")
        .await
        .expect("handshake");
    let (send, recv) = connection.open_bi().await.expect("stream");
    (endpoint, connection, send, recv)
}

fn inputs(slot: Slot, first_tick: u64, n: usize) -> Bytes {
    let m = ClientMessage::Input(InputDatagram {
        slot,
        ack_bundle: None,
        first_tick,
        inputs: vec![vec![0, 0, 0]; n],
    });
    Bytes::from(m.encode().expect("encode"))
}

/// Reads frames until the server's close message; returns its reason.
async fn close_reason(recv: &mut quinn::RecvStream) -> Option<(CloseReason, String)> {
    close_reason_within(recv, Duration::from_secs(10)).await
}

/// [`close_reason`], waiting up to `limit`.
async fn close_reason_within(
    recv: &mut quinn::RecvStream,
    limit: Duration,
) -> Option<(CloseReason, String)> {
    let read = async {
        while let Ok(Some(frame)) = read_frame(recv).await {
            if let Ok(ServerMessage::Close(c)) = ServerMessage::decode(&frame) {
                return Some((c.reason, c.detail));
            }
        }
        None
    };
    tokio::time::timeout(limit, read).await.ok().flatten()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn garbage_oversized_frames_foreign_or_far_inputs_and_silence_are_refused_and_the_match_completes()
 {
    let mut server = TestServer::start(tmp("evil"), |c| {
        c.room.start_players = 7;
        c.room.match_ticks = Some(300);
        c.room.silence_timeout = Duration::from_secs(2);
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());

    // Not seated: garbage instead of a join.
    let (_e1, c1, mut s1, mut r1) = raw_connect(addr, &cert).await;
    s1.write_all(&[8, 0, 0, 0, 0xde, 0xad, 0xbe, 0xef, 1, 2, 3, 4])
        .await
        .unwrap();
    // Told why, as a protocol violation (Close message and QUIC code 1).
    let (reason1, detail1) = close_reason(&mut r1)
        .await
        .expect("a close for the garbage join");
    assert_eq!(reason1, CloseReason::ProtocolViolation);
    assert!(detail1.contains("undecodable join"), "{detail1}");
    match c1.closed().await {
        quinn::ConnectionError::ApplicationClosed(a) => {
            assert_eq!(a.error_code, quinn::VarInt::from_u32(1));
        }
        other => panic!("expected an application close, got {other}"),
    }
    // Seated, then a garbage datagram before its first input: removed
    // before the match can start with it.
    let (_e2, c2, _s2, mut r2, _) = raw_join(addr, &cert, "evil", "garbage-datagram").await;
    c2.send_datagram(Bytes::from_static(&[1, 0, 0xff, 0xff, 0xff]))
        .unwrap();
    assert_eq!(
        close_reason(&mut r2).await.map(|c| c.0),
        Some(CloseReason::ProtocolViolation)
    );
    // Seated and ready, misbehaving once the match runs.
    let (_e3, c3, _s3, mut r3, slot3) = raw_join(addr, &cert, "evil", "foreign-inputs").await;
    let (_e4, c4, mut s4, mut r4, slot4) = raw_join(addr, &cert, "evil", "oversized-frame").await;
    let (_e5, c5, _s5, mut r5, slot5) = raw_join(addr, &cert, "evil", "far-future").await;
    let (_e6, c6, _s6, mut r6, slot6) = raw_join(addr, &cert, "evil", "silent").await;
    for (c, slot) in [(&c3, slot3), (&c4, slot4), (&c5, slot5), (&c6, slot6)] {
        c.send_datagram(inputs(slot, 0, 5)).unwrap();
    }
    let options = BotOptions::new(addr, &cert, "evil", 3);
    let bots_task = tokio::spawn(async move { run_bots(&options, std::future::pending()).await });
    server
        .wait_for(Duration::from_secs(10), |e| {
            matches!(e, ServerEvent::MatchStarted { .. }).then_some(())
        })
        .await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    // Inputs for another player's slot.
    c3.send_datagram(inputs(slot4, 40, 2)).unwrap();
    // A frame header claiming 16 MiB.
    s4.write_all(&(16u32 << 20).to_le_bytes()).await.unwrap();
    // An input far beyond the window.
    c5.send_datagram(inputs(slot5, 10_000, 1)).unwrap();
    let (reason3, detail3) = close_reason(&mut r3)
        .await
        .expect("close for foreign inputs");
    let (reason4, detail4) = close_reason(&mut r4)
        .await
        .expect("close for the oversized frame");
    assert_eq!(reason3, CloseReason::ProtocolViolation);
    assert!(detail3.contains("slot"), "{detail3}");
    assert_eq!(reason4, CloseReason::ProtocolViolation);
    assert!(detail4.contains("frame"), "{detail4}");
    let (reason5, detail5) = close_reason(&mut r5).await.expect("close for the far tick");
    assert_eq!(reason5, CloseReason::ProtocolViolation);
    assert!(
        detail5.contains("tick 10000 outside the window"),
        "{detail5}"
    );
    // The silent one is dropped after the silence timeout; the room goes on.
    let (reason6, _) = close_reason(&mut r6).await.expect("close for silence");
    assert_eq!(reason6, CloseReason::TimedOut);
    let bots = bots_ok(bots_task.await.expect("bots"));
    let ended = server.match_end(Duration::from_secs(10)).await;
    let report = server.shutdown().await;
    // The other players' match completed, in sync, to the last tick.
    assert_same_hashes(&bots, 300);
    assert_eq!(ended.ticks, 300);
    assert_eq!(ended.mismatched_ticks, 0);
    assert!(
        c1.close_reason().is_some(),
        "the garbage connection was closed"
    );
    let reasons: Vec<&str> = report.refused.iter().map(|(_, r)| r.as_str()).collect();
    println!("refused: {reasons:#?}");
    assert_eq!(reasons.len(), 5, "{reasons:?}");
    assert!(reasons.iter().any(|r| r.contains("outside the window")));
    let left: Vec<_> = ended
        .players
        .iter()
        .map(|p| (p.name.as_str(), p.left.as_ref().map(|l| l.1.as_str())))
        .collect();
    assert!(left.contains(&("silent", Some("TimedOut"))), "{left:?}");
    assert!(
        left.contains(&("foreign-inputs", Some("Kicked"))),
        "{left:?}"
    );
    assert_eq!(
        left.iter().filter(|l| l.1.is_none()).count(),
        3,
        "bots stay: {left:?}"
    );
    assert!(reasons.iter().any(|r| r.contains("undecodable join")));
    assert!(reasons.iter().any(|r| r.contains("bad datagram")));
    assert!(reasons.iter().any(|r| r.contains("input for slot")));
    assert!(reasons.iter().any(|r| r.contains("bad frame")));
    let check = verify_replay_file(&ended.replay.expect("replay"), &Demo).expect("replay verifies");
    assert_eq!(check.ticks, 300);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn graceful_shutdown_mid_match_finishes_the_tick_and_flushes_a_replay_that_verifies() {
    let mut server = TestServer::start(tmp("shutdown"), |c| {
        c.room.start_players = 3;
    })
    .await;
    let options = BotOptions::new(server.addr, &server.cert, "shutdown", 3);
    let bots_task = tokio::spawn(async move { run_bots(&options, std::future::pending()).await });
    server
        .wait_for(Duration::from_secs(10), |e| {
            matches!(e, ServerEvent::MatchStarted { .. }).then_some(())
        })
        .await;
    tokio::time::sleep(Duration::from_secs(2)).await;
    let report = server.shutdown().await;
    let bots = bots_ok(bots_task.await.expect("bots"));
    assert_eq!(report.matches.len(), 1);
    let m = &report.matches[0];
    assert_eq!(m.end_reason, "server shutting down");
    assert!((100..=140).contains(&m.ticks), "{} ticks", m.ticks);
    // Every bot got every bundle, the last one included, and the close.
    assert_same_hashes(&bots, m.ticks as usize);
    for b in &bots {
        assert_eq!(
            b.close.as_ref().map(|c| c.reason),
            Some(CloseReason::RoomClosed)
        );
    }
    let path = m.replay.clone().expect("replay");
    let replay = Replay::parse(&std::fs::read(&path).unwrap()).unwrap();
    assert!(!replay.truncated);
    assert_eq!(replay.end.as_ref().map(|e| e.0), Some(m.ticks));
    let check = verify_replay_file(&path, &Demo).expect("replay verifies");
    assert_eq!((check.ticks, check.checked), (m.ticks, m.ticks));
}

/// Two bots start a match in `room`; 1.5 s into it a third joins late.
/// Returns the two bots' reports, the late joiner's and the match's.
async fn two_bots_and_a_late_joiner(
    server: &mut TestServer,
    room: &'static str,
) -> (
    Vec<lockstep_client::net::ClientReport>,
    lockstep_client::net::ClientReport,
    lockstep_server::RoomReport,
) {
    let (addr, cert) = (server.addr, server.cert.clone());
    let options = BotOptions::new(addr, &cert, room, 2);
    let early = tokio::spawn(async move { run_bots(&options, std::future::pending()).await });
    server
        .wait_for(Duration::from_secs(10), |e| {
            matches!(e, ServerEvent::MatchStarted { .. }).then_some(())
        })
        .await;
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let late_options = BotOptions::new(addr, &cert, room, 3).client_options(2);
    let late = lockstep_client::bot::run_bot(
        late_options,
        std::sync::Arc::new(Demo),
        1,
        false,
        std::future::pending(),
    )
    .await
    .expect("the late joiner plays");
    let early = bots_ok(early.await.unwrap());
    let ended = server.match_end(Duration::from_secs(10)).await;
    (early, late, ended)
}

/// Four connections that never simulate and report one made-up hash for
/// every tick, joined in order (so they hold slots 0-3) to `room`.
async fn sybils(
    addr: SocketAddr,
    cert: &std::path::Path,
    room: &'static str,
) -> Vec<tokio::task::JoinHandle<Option<(CloseReason, String)>>> {
    let mut sybils = Vec::new();
    for name in ["sybil-0", "sybil-1", "sybil-2", "sybil-3"] {
        sybils.push(tokio::spawn(raw_reporter(
            addr,
            cert.to_path_buf(),
            room,
            name,
            |_| Some(0xbad),
        )));
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    sybils
}

/// A raw player that keeps up with the match without simulating: it sends
/// its input ahead, acknowledges bundles, and reports `report(tick)` for
/// each closed tick (`None`: no report). Runs until the server closes it;
/// returns the reason of the server's `Close`.
async fn raw_reporter(
    server: SocketAddr,
    cert: PathBuf,
    room: &'static str,
    name: &'static str,
    report: fn(u64) -> Option<u64>,
) -> Option<(CloseReason, String)> {
    let (_endpoint, connection, mut send, mut recv, slot) =
        raw_join(server, &cert, room, name).await;
    connection.send_datagram(inputs(slot, 0, 5)).unwrap();
    let play = async {
        let mut next = 0u64;
        loop {
            let Ok(d) = connection.read_datagram().await else {
                return;
            };
            let Ok(ServerMessage::Bundles(b)) = ServerMessage::decode(&d) else {
                continue;
            };
            for bundle in &b.bundles {
                if bundle.tick != next {
                    continue;
                }
                next += 1;
                if let Some(hash) = report(bundle.tick) {
                    let m = ClientMessage::HashReport(lockstep_proto::HashReport {
                        tick: bundle.tick,
                        hash,
                        body_hashes: None,
                    });
                    if write_frame(&mut send, &m.encode().unwrap()).await.is_err() {
                        return;
                    }
                }
            }
            // Inputs up to 4 ticks ahead, with the bundle ack.
            let m = ClientMessage::Input(InputDatagram {
                slot,
                ack_bundle: next.checked_sub(1),
                first_tick: next,
                inputs: vec![vec![0, 0, 0]; 5],
            });
            if connection
                .send_datagram(Bytes::from(m.encode().unwrap()))
                .is_err()
            {
                return;
            }
        }
    };
    let closed = close_reason_within(&mut recv, Duration::from_secs(30));
    tokio::select! {
        () = play => None,
        c = closed => c,
    }
}

/// A raw player like [`raw_reporter`] that reports a made-up hash for
/// every tick and answers the room's probes with `answer` (a liar about
/// its world). Returns the reason of the server's `Close`.
async fn raw_liar(
    server: SocketAddr,
    cert: PathBuf,
    room: &'static str,
    name: &'static str,
    answer: fn(&lockstep_proto::Probe) -> lockstep_proto::ProbeAnswer,
) -> Option<(CloseReason, String)> {
    let (_endpoint, connection, mut send, mut recv, slot) =
        raw_join(server, &cert, room, name).await;
    connection.send_datagram(inputs(slot, 0, 5)).unwrap();
    let (probes_tx, mut probes) = tokio::sync::mpsc::unbounded_channel();
    let reader = tokio::spawn(async move {
        while let Ok(Some(frame)) = read_frame(&mut recv).await {
            match ServerMessage::decode(&frame) {
                Ok(ServerMessage::Probe(p)) => {
                    let _ = probes_tx.send(Ok(p));
                }
                Ok(ServerMessage::Close(c)) => {
                    let _ = probes_tx.send(Err((c.reason, c.detail)));
                    return;
                }
                _ => {}
            }
        }
    });
    let mut next = 0u64;
    let closed = tokio::time::timeout(Duration::from_secs(30), async {
        loop {
            tokio::select! {
                p = probes.recv() => match p {
                    Some(Ok(probe)) => {
                        let reply = ClientMessage::ProbeReply(lockstep_proto::ProbeReply {
                            tick: probe.tick,
                            answer: answer(&probe),
                        });
                        if write_frame(&mut send, &reply.encode().unwrap()).await.is_err() {
                            return None;
                        }
                    }
                    Some(Err(close)) => return Some(close),
                    None => return None,
                },
                d = connection.read_datagram() => {
                    let Ok(d) = d else { return None };
                    let Ok(ServerMessage::Bundles(b)) = ServerMessage::decode(&d) else {
                        continue;
                    };
                    for bundle in &b.bundles {
                        if bundle.tick != next {
                            continue;
                        }
                        next += 1;
                        let m = ClientMessage::HashReport(lockstep_proto::HashReport {
                            tick: bundle.tick,
                            hash: 0xbad,
                            body_hashes: None,
                        });
                        if write_frame(&mut send, &m.encode().unwrap()).await.is_err() {
                            return None;
                        }
                    }
                    let m = ClientMessage::Input(InputDatagram {
                        slot,
                        ack_bundle: next.checked_sub(1),
                        first_tick: next,
                        inputs: vec![vec![0, 0, 0]; 5],
                    });
                    let _ = connection.send_datagram(Bytes::from(m.encode().unwrap()));
                }
            }
        }
    })
    .await
    .ok()
    .flatten();
    reader.abort();
    closed
}

/// Counts the server's log lines (a multi-line event counts each line)
/// inside the span of one room, by its name: a layer of the process's
/// tracing subscriber, installed once for this test binary.
mod room_logs {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::{Arc, Mutex, OnceLock};

    use tracing::field::{Field, Visit};
    use tracing::span::{Attributes, Id};
    use tracing::{Event, Subscriber};
    use tracing_subscriber::layer::{Context, Layer, SubscriberExt};
    use tracing_subscriber::registry::LookupSpan;

    type Counters = Mutex<Vec<(String, Arc<AtomicUsize>, Arc<Mutex<Vec<String>>>)>>;

    struct Counter(&'static Counters);

    /// The room a span is for.
    struct RoomName(String);

    struct Fields {
        room: Option<String>,
        message: Option<String>,
    }

    impl Visit for Fields {
        fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
            match field.name() {
                "room" => self.room = Some(format!("{value:?}")),
                "message" => self.message = Some(format!("{value:?}")),
                _ => {}
            }
        }
    }

    impl<S: Subscriber + for<'a> LookupSpan<'a>> Layer<S> for Counter {
        fn on_new_span(&self, attrs: &Attributes<'_>, id: &Id, ctx: Context<'_, S>) {
            let mut f = Fields {
                room: None,
                message: None,
            };
            attrs.record(&mut f);
            if let (Some(room), Some(span)) = (f.room, ctx.span(id)) {
                span.extensions_mut().insert(RoomName(room));
            }
        }

        fn on_event(&self, event: &Event<'_>, ctx: Context<'_, S>) {
            let Some(scope) = ctx.event_scope(event) else {
                return;
            };
            let room = scope
                .from_root()
                .find_map(|s| s.extensions().get::<RoomName>().map(|r| r.0.clone()));
            let Some(room) = room else { return };
            let counters = self.0.lock().unwrap();
            if let Some((_, n, lines)) = counters.iter().find(|c| c.0 == room) {
                let mut f = Fields {
                    room: None,
                    message: None,
                };
                event.record(&mut f);
                let text = f.message.unwrap_or_default();
                n.fetch_add(text.lines().count().max(1), Ordering::Relaxed);
                lines
                    .lock()
                    .unwrap()
                    .extend(text.lines().map(str::to_owned));
            }
        }
    }

    static COUNTERS: OnceLock<&'static Counters> = OnceLock::new();

    /// Starts counting the log lines of room `room`: the line count, and
    /// the lines.
    pub fn count(room: &str) -> (Arc<AtomicUsize>, Arc<Mutex<Vec<String>>>) {
        let counters = *COUNTERS.get_or_init(|| {
            let c: &'static Counters = Box::leak(Box::default());
            let subscriber = tracing_subscriber::registry().with(Counter(c));
            tracing::subscriber::set_global_default(subscriber).expect("one subscriber");
            c
        });
        let n = Arc::new(AtomicUsize::new(0));
        let lines = Arc::new(Mutex::new(Vec::new()));
        counters
            .lock()
            .unwrap()
            .push((room.to_owned(), n.clone(), lines.clone()));
        (n, lines)
    }
}

/// Bounded logs (issue 42, item 7): on a server that does not verify and
/// drops nobody for its hash, a bot that simulates right but reports a
/// wrong hash on every even tick raises a new divergence every other
/// tick. The room logs its first 16 desyncs (notice, located report,
/// bundle) and says once that it stops; the rest are counted, not
/// logged. Its report keeps every notice (up to 256) and at most 4
/// bundles; the bots (the liar's real hashes too) agree on every tick and
/// the replay, holding only the hashes every player reported, re-verifies.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_liar_raising_a_desync_every_other_tick_cannot_fill_the_log() {
    use lockstep_client::bot::run_bot;
    let (lines, text) = room_logs::count("many-desyncs");
    let mut server = TestServer::start(tmp("many-desyncs"), |c| {
        program_config(c, &["--no-verify"]);
        c.room.start_players = 3;
        c.room.match_ticks = Some(300);
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let options = BotOptions::new(addr, &cert, "many-desyncs", 3);
    let mut tasks = Vec::new();
    for i in 0..3 {
        let mut o = options.client_options(i);
        o.lie_on_even_ticks = i == 2;
        tasks.push(tokio::spawn(run_bot(
            o,
            std::sync::Arc::new(Demo),
            1,
            false,
            std::future::pending(),
        )));
        tokio::time::sleep(Duration::from_millis(30)).await;
    }
    let mut bots = Vec::new();
    for t in tasks {
        bots.push(t.await.unwrap().expect("bot plays"));
    }
    let ended = server.match_end(Duration::from_secs(10)).await;
    server.shutdown().await;
    assert_same_hashes(&bots, 300);
    assert!(ended.desync_notices >= 32, "{}", ended.desync_notices);
    assert_eq!(ended.desyncs.len() as u64, ended.desync_notices.min(256));
    assert!(ended.bundles.len() <= 4, "{:?}", ended.bundles);
    let text = text.lock().unwrap().clone();
    let notices = text.iter().filter(|l| l.contains("DESYNC at tick")).count();
    let reports = text.iter().filter(|l| l.contains("desync bundle")).count();
    let total = lines.load(std::sync::atomic::Ordering::Relaxed);
    println!(
        "{} desync notices, {} located; the room logged {total} lines, {notices} notice lines",
        ended.desync_notices,
        ended.located.len()
    );
    assert_eq!(
        notices, 17,
        "16 logged and the one that says the rest are not"
    );
    assert!(reports <= 4, "{reports}");
    assert!(
        text.iter().any(|l| l.contains("the rest are counted")),
        "{text:#?}"
    );
    assert!(total < 900, "{total} lines");
    let check = verify_replay_file(ended.replay.as_ref().unwrap(), &Demo).expect("replay verifies");
    assert_eq!(check.ticks, 300);
    assert!(check.checked >= 100, "{}", check.checked);
}

/// Forensics bounded by what the server knows (issue 42, item 7), against
/// the default (verifying) program: two liars report a made-up hash beside
/// two bots and lie to the desync search. One claims a world of 2^20
/// bodies (it used to make the server pull 10.5 MB); its claim is over the
/// scene's bound (twice its bodies plus 64), so its part ends after one
/// piece, unread. The other claims the scene's body count, then answers
/// the field probe with a dump over the probe reply budget (128 KiB); its
/// part ends unread too. The search reports both as unanswered, the
/// server pulls and sends bounded bytes, raises one notice (one log line)
/// and one report of bounded lines; both liars are dropped as diverged,
/// the bots agree on every tick, and the replay re-verifies.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn liars_about_their_world_make_the_server_pull_bounded_bytes() {
    use lockstep_proto::{BodyDump, FieldDump, FieldKind, ProbeAnswer, ProbeAsk, ProbeStatus};
    let mut server = TestServer::start(tmp("forensic-liars"), |c| {
        program_config(c, &[]);
        c.room.start_players = 4;
        c.room.match_ticks = Some(360);
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let options = BotOptions::new(addr, &cert, "forensic-liars", 2);
    let bots = tokio::spawn(async move { run_bots(&options, std::future::pending()).await });
    tokio::time::sleep(Duration::from_millis(300)).await;
    let huge = tokio::spawn(raw_liar(
        addr,
        cert.clone(),
        "forensic-liars",
        "huge",
        |p| match p.ask {
            ProbeAsk::BodyHashes { from } => ProbeAnswer::BodyHashes {
                total: 1 << 20,
                from,
                contacts: 1,
                game: 1,
                hashes: vec![3; 4096],
            },
            _ => ProbeAnswer::Unavailable,
        },
    ));
    let fat = tokio::spawn(raw_liar(addr, cert.clone(), "forensic-liars", "fat", |p| {
        match &p.ask {
            ProbeAsk::BodyHashes { .. } => ProbeAnswer::BodyHashes {
                total: 66,
                from: 0,
                contacts: 1,
                game: 1,
                hashes: vec![3; 66],
            },
            // 8 bodies of 64 fields of 32 words: about 150 kB.
            ProbeAsk::Fields { bodies } => ProbeAnswer::Fields {
                bodies: bodies
                    .iter()
                    .map(|&index| BodyDump {
                        index,
                        handle: index,
                        generation: 0,
                        name: String::new(),
                        fields: (0..64)
                            .map(|f| FieldDump {
                                name: format!("field-{f}"),
                                kind: FieldKind::Word,
                                words: vec![u64::MAX; 32],
                            })
                            .collect(),
                    })
                    .collect(),
                game: Vec::new(),
            },
            ProbeAsk::Snapshot { .. } => ProbeAnswer::Unavailable,
        }
    }));
    let bots = bots_ok(bots.await.unwrap());
    let ended = server.match_end(Duration::from_secs(10)).await;
    server.shutdown().await;
    for (who, task) in [("huge", huge), ("fat", fat)] {
        let (reason, detail) = task.await.unwrap().expect("closed by the server");
        assert_eq!(reason, CloseReason::Diverged, "{who}: {detail}");
    }
    assert_same_hashes(&bots, 360);
    for b in &bots {
        assert!(b.desyncs().all(|n| !matches!(
            &n.verdict,
            Verdict::Verified { wrong, .. } if wrong.contains(&b.slot)
        )));
    }
    // One divergence: one notice and one report.
    assert_eq!(ended.desync_notices, 1);
    assert_eq!(ended.desyncs.len(), 1, "{:?}", ended.desyncs);
    assert_eq!(ended.located.len(), 1);
    let report = &ended.located[0];
    assert_eq!(report.reference_status, ProbeStatus::Complete);
    assert_eq!(report.suspects.len(), 2, "{report}");
    for s in &report.suspects {
        assert_eq!(s.status, ProbeStatus::NoAnswer, "{report}");
        assert!(s.bodies.is_empty(), "{report}");
    }
    assert!(report.to_string().lines().count() <= 40, "{report}");
    println!(
        "forensic liars: {} B of probes sent, {} B of replies received",
        ended.forensics_bytes_down, ended.forensics_bytes_up
    );
    // The liars' replies were one body-hash piece and one field dump each
    // at most (the server asked nothing more of them), the reference's a
    // hash list, a snapshot and a few dumps.
    assert!(
        ended.forensics_bytes_up < 512 << 10,
        "{}",
        ended.forensics_bytes_up
    );
    assert!(
        ended.forensics_bytes_down < 16 << 10,
        "{}",
        ended.forensics_bytes_down
    );
    let check = verify_replay_file(ended.replay.as_ref().unwrap(), &Demo).expect("replay verifies");
    assert_eq!((check.ticks, check.checked), (360, 360));
}

/// Two attacks on the hash vote, each by a raw client beside three honest
/// bots: a liar that reports a fake hash on even ticks and nothing on odd
/// ones (it used to raise a desync notice every 2 ticks), and a player that
/// never reports (it used to be never judged). Against the default
/// (verifying) server, the liar gets one notice and is dropped as
/// diverged; the silent reporter is dropped for its missing reports; the
/// bots play on with 0 desyncs of their own and the replay re-verifies.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_liar_alternating_with_silence_and_a_player_that_never_reports_are_dropped() {
    let mut server = TestServer::start(tmp("vote"), |c| {
        program_config(c, &[]);
        c.room.start_players = 5;
        c.room.match_ticks = Some(540);
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let liar = tokio::spawn(raw_reporter(addr, cert.clone(), "vote", "liar", |t| {
        (t % 2 == 0).then_some(0xbad)
    }));
    let mute = tokio::spawn(raw_reporter(addr, cert.clone(), "vote", "mute", |_| None));
    let options = BotOptions::new(addr, &cert, "vote", 3);
    let bots = bots_ok(run_bots(&options, std::future::pending()).await);
    let ended = server.match_end(Duration::from_secs(10)).await;
    server.shutdown().await;
    let (liar_reason, liar_detail) = liar.await.unwrap().expect("the liar is closed");
    assert_eq!(liar_reason, CloseReason::Diverged, "{liar_detail}");
    let (mute_reason, mute_detail) = mute.await.unwrap().expect("the mute player is closed");
    assert_eq!(mute_reason, CloseReason::NoHashReports, "{mute_detail}");
    // One notice for the liar's whole divergence, then nothing.
    assert_eq!(ended.desyncs.len(), 1, "{:?}", ended.desyncs);
    match &ended.desyncs[0].verdict {
        Verdict::Verified { wrong, .. } => assert_eq!(wrong.len(), 1),
        other => panic!("expected a verified verdict, got {other:?}"),
    }
    assert_same_hashes(&bots, 540);
    for b in &bots {
        assert_eq!(b.desyncs().count(), 1, "the one notice, about the liar");
    }
    let left: Vec<_> = ended
        .players
        .iter()
        .map(|p| (p.name.as_str(), p.left.as_ref().map(|l| l.1.as_str())))
        .collect();
    assert!(left.contains(&("liar", Some("Diverged"))), "{left:?}");
    assert!(left.contains(&("mute", Some("NoHashReports"))), "{left:?}");
    let check = verify_replay_file(&ended.replay.expect("replay"), &Demo).expect("replay verifies");
    assert_eq!(check.ticks, 540);
}

/// A connection that opens its stream but never sends a join is refused
/// after 5 s with the join-refused close code and the reason (it used to be
/// dropped with code 0 and no reason).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_connection_that_never_joins_is_refused_with_its_reason() {
    let server = TestServer::start(tmp("nojoin"), |_| {}).await;
    // Started before connecting, so the server's 5 s (counted from its
    // accept) lie inside `waited` however slow the handshake.
    let started = Instant::now();
    let (_endpoint, connection, _send, _recv) = raw_connect(server.addr, &server.cert).await;
    let closed = tokio::time::timeout(Duration::from_secs(10), connection.closed())
        .await
        .expect("closed within 10 s");
    let waited = started.elapsed();
    match closed {
        quinn::ConnectionError::ApplicationClosed(c) => {
            assert_eq!(
                c.error_code,
                quinn::VarInt::from_u32(lockstep_client::net::close_code::REFUSED)
            );
            assert_eq!(&c.reason[..], b"no join within 5 s");
        }
        other => panic!("expected an application close, got {other:?}"),
    }
    assert!(waited >= Duration::from_secs(4), "{waited:?}");
    let report = server.shutdown().await;
    assert!(
        report
            .refused
            .iter()
            .any(|(_, r)| r == "no join within 5 s"),
        "{:?}",
        report.refused
    );
}

/// A squatter that joins and answers but never sends its first input no
/// longer keeps the match from starting: after the lobby timeout it is
/// closed as timed out and the two bots play their match.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_lobby_squatter_is_dropped_at_the_lobby_timeout_and_the_match_starts() {
    let mut server = TestServer::start(tmp("squat"), |c| {
        c.room.start_players = 3;
        c.room.match_ticks = Some(120);
        c.room.lobby_timeout = Some(Duration::from_secs(2));
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let (_e, connection, _s, mut recv, _slot) = raw_join(addr, &cert, "squat", "squatter").await;
    // It keeps the connection alive (QUIC keep-alives) but sends no input.
    let options = BotOptions::new(addr, &cert, "squat", 2);
    let bots = tokio::spawn(async move { run_bots(&options, std::future::pending()).await });
    let (reason, detail) = close_reason(&mut recv)
        .await
        .expect("the squatter is closed");
    assert_eq!(reason, CloseReason::TimedOut);
    assert!(detail.contains("lobby timeout"), "{detail}");
    let started = server
        .wait_for(Duration::from_secs(10), |e| match e {
            ServerEvent::MatchStarted { players, .. } => Some(*players),
            _ => None,
        })
        .await;
    assert_eq!(started, 2);
    let bots = bots_ok(bots.await.expect("bots"));
    assert_same_hashes(&bots, 120);
    drop(connection);
    server.shutdown().await;
}

/// Sixteen short-lived connections to sixteen new room names, with a limit
/// of four rooms: each lobby closes when its only player leaves, so the
/// next name always finds room, no lobby leaves a replay file, and the
/// server's report counts no match.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn empty_lobbies_close_and_leave_no_replay_files() {
    let mut server = TestServer::start(tmp("rooms"), |c| {
        c.max_rooms = 4;
        c.room.start_players = 2;
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    const NAMES: [&str; 16] = [
        "r0", "r1", "r2", "r3", "r4", "r5", "r6", "r7", "r8", "r9", "r10", "r11", "r12", "r13",
        "r14", "r15",
    ];
    for name in NAMES {
        let (endpoint, connection, mut send, _recv, _slot) =
            raw_join(addr, &cert, name, "visitor").await;
        let leave = ClientMessage::Leave.encode().unwrap();
        write_frame(&mut send, &leave).await.unwrap();
        let _ = send.finish();
        // The room closes once its only player left.
        let closed = server
            .wait_for(Duration::from_secs(10), |e| match e {
                ServerEvent::MatchEnded(r) if r.room == name => Some(r.clone()),
                _ => None,
            })
            .await;
        assert_eq!(closed.ticks, 0);
        assert!(closed.replay.is_none(), "{closed:?}");
        connection.close(0u32.into(), b"bye");
        endpoint.wait_idle().await;
    }
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("e2e-rooms/replays");
    let files = std::fs::read_dir(&dir).map(|d| d.count()).unwrap_or(0);
    assert_eq!(files, 0, "no replay file in {}", dir.display());
    let report = server.shutdown().await;
    // Sixteen lobbies closed; none played a match.
    assert_eq!((report.matches.len(), report.matches_total), (0, 0));
}

/// A player that floods valid (redundant) input datagrams is throttled:
/// past the per-connection rate the excess is dropped and counted, the
/// flooder stays, and the bots' match completes in sync.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flood_of_valid_datagrams_is_throttled_and_counted() {
    let mut server = TestServer::start(tmp("flood"), |c| {
        c.room.start_players = 3;
        c.room.match_ticks = Some(180);
        c.room.max_messages_per_second = 400;
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let (_e, connection, _s, _recv, slot) = raw_join(addr, &cert, "flood", "flooder").await;
    let first = inputs(slot, 0, 5);
    connection.send_datagram(first.clone()).unwrap();
    let options = BotOptions::new(addr, &cert, "flood", 2);
    let bots = tokio::spawn(async move { run_bots(&options, std::future::pending()).await });
    server
        .wait_for(Duration::from_secs(10), |e| {
            matches!(e, ServerEvent::MatchStarted { .. }).then_some(())
        })
        .await;
    // 5,000 copies of its first inputs in about a second (the same bytes
    // each time: redundant, never a violation).
    for _ in 0..50 {
        for _ in 0..100 {
            let _ = connection.send_datagram(first.clone());
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let bots = bots_ok(bots.await.expect("bots"));
    let ended = server.match_end(Duration::from_secs(10)).await;
    server.shutdown().await;
    assert_same_hashes(&bots, 180);
    assert_eq!(ended.mismatched_ticks, 0);
    let flooder = ended
        .players
        .iter()
        .find(|p| p.name == "flooder")
        .expect("flooder");
    assert!(
        flooder.datagrams_dropped > 1000,
        "dropped {}",
        flooder.datagrams_dropped
    );
    for p in ended.players.iter().filter(|p| p.name != "flooder") {
        assert_eq!(p.datagrams_dropped, 0, "{}", p.name);
    }
}

/// With `--require-tokens`: a join without a token, with an expired one, one
/// for another room or one signed with another secret is refused with its
/// reason; a seat token seats its holder in its seat, and nobody else gets
/// that seat or a second seat with the same token (a token seats once); bots
/// holding seat tokens play a match in sync.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_tokens_required_only_valid_tokens_join_and_each_seats_one_connection() {
    use lockstep_client::net::{Client, ClientError, ClientOptions};
    use lockstep_server::issue_token;
    use std::time::SystemTime;
    let secret = b"an e2e secret longer than 16 bytes".to_vec();
    let key = secret.clone();
    let server = TestServer::start(tmp("tokens"), move |c| {
        c.room.start_players = 2;
        c.room.match_ticks = Some(120);
        c.token_secret = Some(key);
        c.require_tokens = true;
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let now = SystemTime::now();
    let token = |room: &str, seat: Option<u8>, player: &str| {
        issue_token(&secret, room, seat, player, Duration::from_secs(600), now).unwrap()
    };
    let join = |token: Option<String>| {
        let cert = cert.clone();
        async move {
            let mut o = ClientOptions::new(addr, &cert, "tokens", "p");
            o.token = token;
            Client::connect(o, &Demo).await
        }
    };
    let refused = |r: Result<Client, ClientError>| match r {
        Err(ClientError::Refused { reason, detail }) => (reason, detail),
        Err(e) => panic!("expected a refusal, got {e}"),
        Ok(c) => panic!("expected a refusal, got a seat: {c:?}"),
    };
    let (reason, detail) = refused(join(None).await);
    assert_eq!(
        (reason, detail.as_str()),
        (CloseReason::BadToken, "no join token")
    );
    let old = issue_token(
        &secret,
        "tokens",
        Some(0),
        "p",
        Duration::from_secs(60),
        now - Duration::from_secs(3600),
    )
    .unwrap();
    let (reason, detail) = refused(join(Some(old)).await);
    assert_eq!(reason, CloseReason::BadToken);
    assert!(detail.starts_with("join token expired at "), "{detail}");
    let (reason, detail) = refused(join(Some(token("elsewhere", Some(0), "p"))).await);
    assert_eq!(
        (reason, detail.as_str()),
        (
            CloseReason::BadToken,
            "join token is for room \"elsewhere\""
        )
    );
    let forged = issue_token(
        b"a guess at the secret, 16+ bytes",
        "tokens",
        Some(0),
        "p",
        Duration::from_secs(600),
        now,
    )
    .unwrap();
    let (reason, detail) = refused(join(Some(forged)).await);
    assert_eq!(
        (reason, detail.as_str()),
        (CloseReason::BadToken, "join token signature invalid")
    );
    // A seat token seats its holder in its seat ...
    let seat3 = token("tokens", Some(3), "alice");
    let holder = join(Some(seat3.clone())).await.expect("seated");
    assert_eq!(holder.slot(), Slot(3));
    // ... the same token seats nobody else (it is used up), nor does
    // another token for the held seat, nor a seat the room does not have.
    let (reason, detail) = refused(join(Some(seat3)).await);
    assert_eq!(reason, CloseReason::BadToken);
    assert!(
        detail.starts_with("this join token was already used in this match"),
        "{detail}"
    );
    let (reason, detail) = refused(join(Some(token("tokens", Some(3), "mallory"))).await);
    assert_eq!(
        (reason, detail.as_str()),
        (CloseReason::SeatTaken, "seat 3 is taken")
    );
    let (reason, _) = refused(join(Some(token("tokens", Some(12), "p"))).await);
    assert_eq!(reason, CloseReason::BadToken);
    // An any-seat token takes the lowest free seat, once.
    let any = token("tokens", None, "bob");
    let second = join(Some(any.clone())).await.expect("seated");
    assert_eq!(second.slot(), Slot(0));
    let (reason, _) = refused(join(Some(any)).await);
    assert_eq!(reason, CloseReason::BadToken);
    drop((holder, second));
    // Bots with seat tokens play a match in sync.
    let mut options = BotOptions::new(addr, &cert, "tokens-play", 2);
    options.tokens = vec![
        token("tokens-play", Some(1), "bot-0"),
        token("tokens-play", Some(0), "bot-1"),
    ];
    let bots = bots_ok(run_bots(&options, std::future::pending()).await);
    assert_eq!((bots[0].slot, bots[1].slot), (Slot(1), Slot(0)));
    assert_same_hashes(&bots, 120);
    for b in &bots {
        assert_eq!(b.desyncs().count(), 0);
    }
    let report = server.shutdown().await;
    let refusals = report
        .refused
        .iter()
        .filter(|r| format!("{r:?}").contains("token"))
        .count();
    assert!(refusals >= 5, "{:?}", report.refused);
}

/// Sends `first` as a connection's first frame and returns the server's
/// `Close` (reason, detail) and the QUIC close code the connection ended
/// with.
async fn refused_raw(
    server: SocketAddr,
    cert: &std::path::Path,
    first: &[u8],
) -> (CloseReason, String, u64) {
    let (_endpoint, connection, mut send, mut recv) = raw_connect(server, cert).await;
    write_frame(&mut send, first).await.expect("write");
    let (reason, detail) = close_reason(&mut recv).await.expect("a close message");
    let code = match connection.closed().await {
        quinn::ConnectionError::ApplicationClosed(c) => c.error_code.into_inner(),
        e => panic!("closed without a code: {e}"),
    };
    (reason, detail, code)
}

/// Every refusal of a join reachable over QUIC (issue 42, item 8), one
/// server, each with its `Close` reason, detail and QUIC close code:
/// a first frame that is not a join, a join of another protocol version
/// (in the header or in the join), an over-long token, a used token, a
/// seat the room does not have, a taken seat, a full room, the server's
/// room limit, and a match in progress. (Token texts: the tokens test;
/// `WrongRoom`: the Agones tests; drops during a match: the tests of each
/// attack.)
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_join_refusal_reachable_over_quic_has_its_close_code_and_reason() {
    use lockstep_proto::Join;
    use lockstep_server::issue_token;
    let secret = b"a refusal test secret, 16+ bytes".to_vec();
    let key = secret.clone();
    let server = TestServer::start(tmp("refusals"), move |c| {
        c.room.max_players = 2;
        c.room.start_players = 2;
        c.max_rooms = 1;
        c.token_secret = Some(key);
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let now = std::time::SystemTime::now();
    let token = |seat: u8, player: &str| {
        issue_token(
            &secret,
            "refusals",
            Some(seat),
            player,
            Duration::from_secs(600),
            now,
        )
        .unwrap()
    };
    let join = |token: Option<String>| {
        ClientMessage::Join(Join {
            protocol_version: lockstep_proto::PROTOCOL_VERSION,
            room: "refusals".into(),
            player_name: "p".into(),
            token,
            rejoin: None,
        })
        .encode()
        .unwrap()
    };
    // The seat owner, in seat 1.
    let (_e1, c1, _s1, _r1, owner) = {
        let (endpoint, connection, mut send, mut recv) = raw_connect(addr, &cert).await;
        write_frame(&mut send, &join(Some(token(1, "owner"))))
            .await
            .unwrap();
        let frame = read_frame(&mut recv).await.unwrap().unwrap();
        let ServerMessage::Welcome(w) = ServerMessage::decode(&frame).unwrap() else {
            panic!("expected a welcome");
        };
        assert!(w.rejoin.is_some());
        (endpoint, connection, send, recv, w.slot)
    };
    assert_eq!(owner, Slot(1));
    let mut old_header = join(None);
    old_header[0] = 3;
    let mut old_join = join(None);
    old_join[3] = 3;
    let mut long_token = vec![4, 0, 0, 4, 8];
    long_token.extend_from_slice(b"refusals");
    long_token.extend_from_slice(&[0, 1, 251]);
    long_token.extend_from_slice(&345u16.to_le_bytes());
    long_token.extend(std::iter::repeat_n(b'a', 345));
    long_token.push(0);
    let table: Vec<(&str, Vec<u8>, CloseReason, &str, u64)> = vec![
        (
            "a first frame that is not a join",
            ClientMessage::Leave.encode().unwrap(),
            CloseReason::ProtocolViolation,
            "leave before joining",
            1,
        ),
        (
            "another protocol version's header",
            old_header,
            CloseReason::VersionMismatch,
            "client protocol version 3, server 4",
            2,
        ),
        (
            "another protocol version in the join",
            old_join,
            CloseReason::VersionMismatch,
            "client protocol version 3, server 4",
            2,
        ),
        (
            "a token over the longest token",
            long_token,
            CloseReason::ProtocolViolation,
            "undecodable join: protocol violation: join token of 345 bytes exceeds 344",
            1,
        ),
        (
            "a copy of the owner's token",
            join(Some(token(1, "owner"))),
            CloseReason::BadToken,
            "this join token was already used in this match; its holder rejoins with the rejoin credential of its welcome",
            2,
        ),
        (
            "a seat the room does not have",
            join(Some(token(5, "p"))),
            CloseReason::BadToken,
            "the join token's seat 5 is not in this room",
            2,
        ),
        (
            "another token for the taken seat",
            join(Some(token(1, "mallory"))),
            CloseReason::SeatTaken,
            "seat 1 is taken",
            2,
        ),
    ];
    for (what, first, reason, detail, code) in table {
        let got = refused_raw(addr, &cert, &first).await;
        assert_eq!(got, (reason, detail.to_owned(), code), "{what}");
    }
    // Seat 0 taken: the room is full; another room is over the server's
    // limit of one.
    let (_e0, c0, _s0, _r0, zero) = raw_join(addr, &cert, "refusals", "zero").await;
    assert_eq!(zero, Slot(0));
    let got = refused_raw(addr, &cert, &join(None)).await;
    assert_eq!(
        got,
        (CloseReason::RoomFull, "room is full (2 players)".into(), 2)
    );
    let other = Session::join_message("other", "p").encode().unwrap();
    let got = refused_raw(addr, &cert, &other).await;
    assert_eq!(
        got,
        (
            CloseReason::RoomFull,
            "the server has 1 rooms open, its limit".into(),
            2
        )
    );
    // Both send their first input: the match starts, and a join now is
    // refused (no late join).
    c0.send_datagram(inputs(Slot(0), 0, 5)).unwrap();
    c1.send_datagram(inputs(Slot(1), 0, 5)).unwrap();
    let mut server = server;
    server
        .wait_for(Duration::from_secs(10), |e| {
            matches!(e, ServerEvent::MatchStarted { .. }).then_some(())
        })
        .await;
    let got = refused_raw(addr, &cert, &join(None)).await;
    assert_eq!(
        got,
        (
            CloseReason::MatchInProgress,
            "match already in progress".into(),
            2
        )
    );
    let report = server.shutdown().await;
    assert_eq!(report.refused_total, 10, "{:?}", report.refused);
}

/// Sybil voters against the default `lockstep-server` (no flag but
/// `--scene`): four raw connections report the same fake hash on every tick
/// beside three honest bots. By majority they would win; the program
/// verifies by default (it re-simulates every tick), so the four are the
/// ones judged wrong and dropped as diverged, the bots are never judged
/// wrong, and the replay holds only the server's verified hashes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sybil_voters_cannot_take_over_the_default_lockstep_server() {
    let mut server = TestServer::start(tmp("sybil"), |c| {
        program_config(c, &[]);
        assert!(c.verifier.is_some(), "the program verifies by default");
        assert!(!c.vote);
        c.room.start_players = 7;
        c.room.match_ticks = Some(300);
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let sybils = sybils(addr, &cert, "sybil").await;
    let options = BotOptions::new(addr, &cert, "sybil", 3);
    let bots = bots_ok(run_bots(&options, std::future::pending()).await);
    let ended = server.match_end(Duration::from_secs(15)).await;
    server.shutdown().await;
    for s in sybils {
        let (reason, detail) = s.await.unwrap().expect("a sybil is closed");
        assert_eq!(reason, CloseReason::Diverged, "{detail}");
    }
    assert_same_hashes(&bots, 300);
    assert_eq!(ended.desyncs.len(), 1, "{:?}", ended.desyncs);
    match &ended.desyncs[0].verdict {
        Verdict::Verified { hash, wrong } => {
            assert_eq!(*hash, bots[0].hashes[ended.desyncs[0].tick as usize]);
            assert_eq!(wrong, &vec![Slot(0), Slot(1), Slot(2), Slot(3)]);
        }
        other => panic!("expected a verified verdict, got {other:?}"),
    }
    for b in &bots {
        assert!(b.slot.0 >= 4);
        let close = b.close.as_ref().expect("closed by the server");
        assert_eq!(close.reason, CloseReason::RoomClosed);
    }
    let path = ended.replay.as_ref().expect("replay");
    let check = verify_replay_file(path, &Demo).expect("replay verifies");
    assert_eq!((check.ticks, check.checked), (300, 300));
    let (ticks, spent) = ended.verified.expect("verified");
    assert_eq!(ticks, 300);
    println!(
        "verify: {ticks} ticks re-simulated in {:.1} ms, {:.1} us per tick ({:.3}% of a 60 Hz room's time)",
        spent.as_secs_f64() * 1e3,
        spent.as_secs_f64() * 1e6 / ticks as f64,
        spent.as_secs_f64() / ticks as f64 * 60.0 * 100.0
    );
}

/// The same four sybils against an open server that does not verify
/// (`--no-verify`): it cannot tell who is right, so it drops nobody for its
/// hash: the bots play the whole match in agreement, the one notice is
/// undecided, and the replay records no made-up hash (only hashes every
/// reporter held), so it re-verifies.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sybils_against_an_unverifying_server_drop_nobody_and_reach_no_replay() {
    let mut server = TestServer::start(tmp("sybil-open"), |c| {
        program_config(c, &["--no-verify"]);
        assert!(c.verifier.is_none() && !c.vote);
        c.room.start_players = 7;
        c.room.match_ticks = Some(240);
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let sybils = sybils(addr, &cert, "sybil-open").await;
    let options = BotOptions::new(addr, &cert, "sybil-open", 3);
    let bots = bots_ok(run_bots(&options, std::future::pending()).await);
    let ended = server.match_end(Duration::from_secs(15)).await;
    server.shutdown().await;
    assert_same_hashes(&bots, 240);
    for b in &bots {
        let close = b.close.as_ref().expect("closed by the server");
        assert_eq!(close.reason, CloseReason::RoomClosed);
    }
    // Nobody left before the end: not the bots, not the sybils.
    assert!(
        ended.players.iter().all(|p| p.left.is_none()),
        "{:?}",
        ended.players
    );
    for s in sybils {
        let (reason, _) = s.await.unwrap().expect("a sybil is closed at the end");
        assert_eq!(reason, CloseReason::RoomClosed);
    }
    assert_eq!(ended.desyncs.len(), 1, "{:?}", ended.desyncs);
    assert_eq!(ended.desyncs[0].verdict, Verdict::Undecided);
    let path = ended.replay.as_ref().expect("replay");
    let replay = Replay::parse(&std::fs::read(path).unwrap()).unwrap();
    assert!(
        replay.hashes.iter().all(|h| *h != Some(0xbad)),
        "a made-up hash reached the replay"
    );
    let check = verify_replay_file(path, &Demo).expect("replay verifies");
    assert_eq!(check.ticks, 240);
}

/// Voting made explicit (`--no-verify --vote` with a token secret): only
/// players seated with a join token vote. Three bots hold tokens; four
/// sybils without one report a made-up hash on every tick. The sybils are
/// judged by the token holders' majority and dropped as diverged; the bots
/// agree on every tick and the replay (the voters' hashes) re-verifies.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_voting_only_token_holders_vote_and_tokenless_sybils_are_dropped() {
    use lockstep_server::issue_token;
    let dir = tmp("sybil-vote");
    let _ = std::fs::create_dir_all(&dir);
    let secret_file = dir.with_extension("secret");
    let secret = b"vote test secret, 16+ bytes".to_vec();
    std::fs::write(&secret_file, &secret).unwrap();
    let file = secret_file.display().to_string();
    let mut server = TestServer::start(dir, |c| {
        program_config(c, &["--no-verify", "--vote", "--token-secret-file", &file]);
        assert!(c.verifier.is_none() && c.vote);
        c.room.start_players = 7;
        c.room.match_ticks = Some(300);
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let sybils = sybils(addr, &cert, "sybil-vote").await;
    let now = std::time::SystemTime::now();
    let mut options = BotOptions::new(addr, &cert, "sybil-vote", 3);
    options.tokens = (0..3)
        .map(|i| {
            issue_token(
                &secret,
                "sybil-vote",
                None,
                &format!("bot-{i}"),
                Duration::from_secs(600),
                now,
            )
            .unwrap()
        })
        .collect();
    let bots = bots_ok(run_bots(&options, std::future::pending()).await);
    let ended = server.match_end(Duration::from_secs(15)).await;
    server.shutdown().await;
    for s in sybils {
        let (reason, detail) = s.await.unwrap().expect("a sybil is closed");
        assert_eq!(reason, CloseReason::Diverged, "{detail}");
        assert!(detail.contains("the voters' majority"), "{detail}");
    }
    assert_same_hashes(&bots, 300);
    match &ended.desyncs[0].verdict {
        Verdict::Majority {
            majority_hash,
            wrong,
        } => {
            assert_eq!(
                *majority_hash,
                bots[0].hashes[ended.desyncs[0].tick as usize]
            );
            assert_eq!(wrong, &vec![Slot(0), Slot(1), Slot(2), Slot(3)]);
        }
        other => panic!("expected a majority verdict, got {other:?}"),
    }
    let check = verify_replay_file(ended.replay.as_ref().unwrap(), &Demo).expect("replay verifies");
    assert_eq!((check.ticks, check.checked), (300, 300));
}

/// Connection squatting: with `--max-connections-per-address 4`, two bots
/// play while one address opens idle connections. Two fit beside the bots
/// (and are dropped for not joining); the next is refused with QUIC code 5
/// (overloaded) and the reason, counted as a refusal; the bots agree on
/// every tick and the replay re-verifies.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_address_cannot_squat_the_connection_slots() {
    let mut server = TestServer::start(tmp("addr-squat"), |c| {
        program_config(c, &["--max-connections-per-address", "4"]);
        assert_eq!(c.max_connections_per_address, Some(4));
        c.room.start_players = 2;
        c.room.match_ticks = Some(300);
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let options = BotOptions::new(addr, &cert, "addr-squat", 2);
    let bots = tokio::spawn(async move { run_bots(&options, std::future::pending()).await });
    server
        .wait_for(Duration::from_secs(10), |e| {
            matches!(e, ServerEvent::MatchStarted { .. }).then_some(())
        })
        .await;
    let _idle = [
        raw_connect(addr, &cert).await,
        raw_connect(addr, &cert).await,
    ];
    let config = client_config(&load_certs(&cert).expect("cert")).expect("tls");
    let mut endpoint = quinn::Endpoint::client("127.0.0.1:0".parse().unwrap()).expect("socket");
    endpoint.set_default_client_config(config);
    let refused = match endpoint.connect(addr, "localhost").expect("connect").await {
        Ok(c) => c.closed().await,
        Err(e) => e,
    };
    match refused {
        quinn::ConnectionError::ApplicationClosed(a) => {
            assert_eq!(a.error_code, quinn::VarInt::from_u32(5));
            let reason = String::from_utf8_lossy(&a.reason);
            assert!(
                reason.contains("too many connections from 127.0.0.1 (at most 4 per address)"),
                "{reason}"
            );
        }
        other => panic!("expected an application close, got {other}"),
    }
    let bots = bots_ok(bots.await.unwrap());
    let ended = server.match_end(Duration::from_secs(10)).await;
    let report = server.shutdown().await;
    assert_same_hashes(&bots, 300);
    assert!(
        report
            .refused
            .iter()
            .any(|(_, r)| r.contains("too many connections from 127.0.0.1")),
        "{:?}",
        report.refused
    );
    let check = verify_replay_file(ended.replay.as_ref().unwrap(), &Demo).expect("replay verifies");
    assert_eq!((check.ticks, check.checked), (300, 300));
}

/// Late join on a server that does not verify: two bots play beside a
/// silent seat (a raw player that sends inputs but never a hash, in slot
/// 0); 1.5 s in, a third bot joins the running match. It starts from the
/// snapshot of the newest tick the players in good standing agree on
/// (fetched from a bot, not the silent seat, and checked against the agreed
/// hash), catches up, and from its first reported tick its hashes match;
/// the silent seat is dropped for its missing reports, and the replay
/// re-verifies.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_late_joiner_starts_from_the_agreed_snapshot_and_matches() {
    let mut server = TestServer::start(tmp("late"), |c| {
        c.room.start_players = 3;
        c.room.match_ticks = Some(480);
        c.room.late_join = true;
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let mute = tokio::spawn(raw_reporter(addr, cert.clone(), "late", "mute", |_| None));
    tokio::time::sleep(Duration::from_millis(50)).await;
    let (early, late, ended) = two_bots_and_a_late_joiner(&mut server, "late").await;
    server.shutdown().await;
    assert_same_hashes(&early, 480);
    println!(
        "late join: snapshot after tick {}, first report at tick {}",
        late.first_applied - 1,
        late.start_tick
    );
    assert!(late.first_applied > 60 && late.first_applied <= late.start_tick);
    assert!(late.start_tick < 200, "joined at tick {}", late.start_tick);
    assert_eq!(late.hashes.len() as u64, 480 - late.first_applied);
    for (i, h) in late.hashes.iter().enumerate() {
        let t = late.first_applied as usize + i;
        assert_eq!(*h, early[0].hashes[t], "tick {t}");
    }
    assert_eq!(late.desyncs().count(), 0);
    assert!(ended.desyncs.is_empty(), "{:?}", ended.desyncs);
    assert_eq!(ended.mismatched_ticks, 0);
    let (reason, detail) = mute.await.unwrap().expect("the silent seat is closed");
    assert_eq!(reason, CloseReason::NoHashReports, "{detail}");
    let check = verify_replay_file(ended.replay.as_ref().unwrap(), &Demo).expect("replay verifies");
    assert_eq!((check.ticks, check.checked, check.players), (480, 480, 4));
}

/// A sparse reporter (one made-up hash every 250 ticks) and a silent seat
/// (inputs, never a hash) in the default program's room with `--late-join`:
/// a bot joining 1.5 s in is not held back by them (it starts from the
/// server's own verified state) and matches the others' hashes; both are
/// dropped for their missing reports over the sliding window, with the
/// reason; the bots agree on every tick and the replay re-verifies.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sparse_and_silent_reporters_are_dropped_and_cannot_block_a_late_join() {
    let mut server = TestServer::start(tmp("sparse"), |c| {
        program_config(c, &["--late-join"]);
        c.room.start_players = 4;
        c.room.match_ticks = Some(480);
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let sparse = tokio::spawn(raw_reporter(addr, cert.clone(), "sparse", "sparse", |t| {
        (t % 250 == 0).then_some(0xbad)
    }));
    let mute = tokio::spawn(raw_reporter(addr, cert.clone(), "sparse", "mute", |_| None));
    let (early, late, ended) = two_bots_and_a_late_joiner(&mut server, "sparse").await;
    server.shutdown().await;
    for (who, task) in [("sparse", sparse), ("mute", mute)] {
        let (reason, detail) = task.await.unwrap().expect("closed by the server");
        assert_eq!(reason, CloseReason::NoHashReports, "{who}: {detail}");
        assert!(detail.contains("of the last"), "{who}: {detail}");
    }
    assert_same_hashes(&early, 480);
    assert!(late.start_tick < 200, "joined at tick {}", late.start_tick);
    assert_eq!(late.hashes.len() as u64, 480 - late.first_applied);
    for (i, h) in late.hashes.iter().enumerate() {
        let t = late.first_applied as usize + i;
        assert_eq!(*h, early[0].hashes[t], "tick {t}");
    }
    let check = verify_replay_file(ended.replay.as_ref().unwrap(), &Demo).expect("replay verifies");
    assert_eq!((check.ticks, check.checked), (480, 480));
}

/// A bad snapshot giver (issue 42, item 4) on an unverifying server with
/// late joins (a verifying server gives joiners its own state and asks no
/// player): three bots play, and bot 0 (slot 0, the first giver asked)
/// answers every snapshot probe with its bytes inverted. A fourth bot
/// joining 1.5 s in is not refused: the garbage is refused, counted
/// against slot 0 (in the match's report, the player's report and
/// `lockstep_bad_snapshots_total`), and slot 1 gives the snapshot. Every
/// bot, the joiner included, agrees on every tick, and the replay
/// re-verifies.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_bad_snapshot_giver_is_counted_and_the_joiner_joins_from_another() {
    use lockstep_client::bot::run_bot;
    let mut server = TestServer::start(tmp("bad-giver"), |c| {
        program_config(c, &["--no-verify", "--late-join"]);
        c.room.start_players = 3;
        c.room.match_ticks = Some(420);
        c.metrics = Some(SocketAddr::from(([127, 0, 0, 1], 0)));
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let options = BotOptions::new(addr, &cert, "bad-giver", 4);
    let mut tasks = Vec::new();
    for i in 0..3 {
        let mut o = options.client_options(i);
        o.corrupt_snapshots = i == 0;
        tasks.push(tokio::spawn(run_bot(
            o,
            std::sync::Arc::new(Demo),
            1,
            false,
            std::future::pending(),
        )));
        tokio::time::sleep(Duration::from_millis(30)).await;
    }
    server
        .wait_for(Duration::from_secs(10), |e| {
            matches!(e, ServerEvent::MatchStarted { .. }).then_some(())
        })
        .await;
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let late = run_bot(
        options.client_options(3),
        std::sync::Arc::new(Demo),
        1,
        false,
        std::future::pending(),
    )
    .await
    .expect("the late joiner is not refused");
    let mut early = Vec::new();
    for t in tasks {
        early.push(t.await.unwrap().expect("bot plays"));
    }
    let ended = server.match_end(Duration::from_secs(10)).await;
    let (_, body) = http_get(server.metrics.unwrap(), "/metrics").await;
    server.shutdown().await;
    assert_same_hashes(&early, 420);
    assert_eq!(late.slot, Slot(3));
    assert_eq!(late.hashes.len() as u64, 420 - late.first_applied);
    for (i, h) in late.hashes.iter().enumerate() {
        let t = late.first_applied as usize + i;
        assert_eq!(*h, early[0].hashes[t], "tick {t}");
    }
    assert!(ended.desyncs.is_empty(), "{:?}", ended.desyncs);
    assert_eq!(ended.bad_snapshots, 1);
    let bad: Vec<_> = ended
        .players
        .iter()
        .map(|p| (p.slot, p.bad_snapshots))
        .collect();
    assert_eq!(
        bad,
        vec![(Slot(0), 1), (Slot(1), 0), (Slot(2), 0), (Slot(3), 0)]
    );
    assert!(body.contains("lockstep_bad_snapshots_total 1"), "{body}");
    let check = verify_replay_file(ended.replay.as_ref().unwrap(), &Demo).expect("replay verifies");
    assert_eq!((check.ticks, check.checked, check.players), (420, 420, 4));
}

/// Tokens whose copy cannot take a seat from its owner (issue 42, item
/// 6), with `--require-tokens`: three bots hold seat tokens. An attacker
/// replaying bot 1's token while bot 1 plays, and again once bot 1 is
/// killed mid-match (its connection drops without a leave), is refused
/// with `BadToken` and the reason. Bot 1 comes back with the rejoin
/// credential its welcome gave (kept by the client library, no token this
/// time), takes back its seat from the agreed snapshot and matches the
/// others from its first reported tick; late joins are off, and the match
/// has no desync.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_replayed_token_is_refused_and_its_owner_rejoins_with_its_credential() {
    use lockstep_client::bot::run_bot;
    use lockstep_client::net::{Client, ClientError, ClientOptions};
    use lockstep_server::issue_token;
    let secret = b"rejoin test secret, 16+ bytes".to_vec();
    let key = secret.clone();
    let mut server = TestServer::start(tmp("rejoin"), move |c| {
        c.room.start_players = 3;
        c.room.match_ticks = Some(600);
        c.token_secret = Some(key);
        c.require_tokens = true;
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let now = std::time::SystemTime::now();
    let mut options = BotOptions::new(addr, &cert, "rejoin", 3);
    options.tokens = (0..3u8)
        .map(|s| {
            issue_token(
                &secret,
                "rejoin",
                Some(s),
                &format!("bot-{s}"),
                Duration::from_secs(600),
                now,
            )
            .unwrap()
        })
        .collect();
    let owner = options.client_options(1);
    let replay_token = || {
        let mut o = ClientOptions::new(addr, &cert, "rejoin", "mallory");
        o.token = owner.token.clone();
        async move {
            match Client::connect(o, &Demo).await {
                Err(ClientError::Refused { reason, detail }) => (reason, detail),
                Err(e) => panic!("expected a refusal, got {e}"),
                Ok(c) => panic!("the copy took a seat: {c:?}"),
            }
        }
    };
    let mut tasks = Vec::new();
    for i in 0..3 {
        // Bot 1 keeps its credential in `owner`'s store (clones share it).
        let o = if i == 1 {
            owner.clone()
        } else {
            options.client_options(i)
        };
        tasks.push(tokio::spawn(run_bot(
            o,
            std::sync::Arc::new(Demo),
            1,
            false,
            std::future::pending(),
        )));
        tokio::time::sleep(Duration::from_millis(30)).await;
    }
    server
        .wait_for(Duration::from_secs(10), |e| {
            matches!(e, ServerEvent::MatchStarted { .. }).then_some(())
        })
        .await;
    assert!(
        owner.rejoin.get().is_some(),
        "the welcome gave a credential"
    );
    let (reason, detail) = replay_token().await;
    assert_eq!(reason, CloseReason::BadToken, "{detail}");
    assert!(detail.contains("already used in this match"), "{detail}");
    tokio::time::sleep(Duration::from_millis(2000)).await;
    // Kill bot 1: its task is dropped mid-match, its connection closes.
    tasks[1].abort();
    let _ = (&mut tasks[1]).await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let (reason, detail) = replay_token().await;
    assert_eq!(reason, CloseReason::BadToken, "{detail}");
    assert!(detail.contains("already used in this match"), "{detail}");
    // The owner comes back with its credential alone.
    let mut back = owner.clone();
    back.token = None;
    let again = run_bot(
        back,
        std::sync::Arc::new(Demo),
        1,
        false,
        std::future::pending(),
    )
    .await
    .expect("the killed bot rejoins");
    let mut others = Vec::new();
    for (i, t) in tasks.into_iter().enumerate() {
        if i != 1 {
            others.push(t.await.unwrap().expect("bot plays"));
        }
    }
    let ended = server.match_end(Duration::from_secs(10)).await;
    server.shutdown().await;
    assert_same_hashes(&others, 600);
    assert_eq!(again.slot, Slot(1));
    println!(
        "rejoin: snapshot after tick {}, first report at tick {}",
        again.first_applied - 1,
        again.start_tick
    );
    assert!(again.first_applied > 100 && again.first_applied <= again.start_tick);
    for (i, h) in again.hashes.iter().enumerate() {
        let t = again.first_applied as usize + i;
        assert_eq!(*h, others[0].hashes[t], "tick {t}");
    }
    assert_eq!(again.hashes.len() as u64, 600 - again.first_applied);
    assert!(ended.desyncs.is_empty(), "{:?}", ended.desyncs);
    assert_eq!(ended.mismatched_ticks, 0);
    let left: Vec<_> = ended
        .players
        .iter()
        .filter_map(|p| p.left.as_ref().map(|l| (p.slot, l.1.clone())))
        .collect();
    assert_eq!(left.len(), 1, "{left:?}");
    assert_eq!(left[0].0, Slot(1));
    let check = verify_replay_file(ended.replay.as_ref().unwrap(), &Demo).expect("replay verifies");
    assert_eq!((check.ticks, check.checked), (600, 600));
}

/// The owner comes back while its old connection still holds the seat
/// (the server has not noticed it is gone, e.g. the game restarted): the
/// rejoin credential drops the old connection and the new one takes the
/// seat from the agreed snapshot, matching the others to the end; the
/// old bot's session ends; the replay re-verifies.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rejoin_with_the_credential_replaces_the_owner_s_stale_connection() {
    use lockstep_client::bot::run_bot;
    use lockstep_server::issue_token;
    let secret = b"replace test secret, 16+ bytes".to_vec();
    let key = secret.clone();
    let mut server = TestServer::start(tmp("replace"), move |c| {
        c.room.start_players = 3;
        c.room.match_ticks = Some(480);
        c.token_secret = Some(key);
    })
    .await;
    let (addr, cert) = (server.addr, server.cert.clone());
    let now = std::time::SystemTime::now();
    let mut options = BotOptions::new(addr, &cert, "replace", 3);
    options.tokens = (0..3u8)
        .map(|s| {
            let name = format!("bot-{s}");
            issue_token(
                &secret,
                "replace",
                Some(s),
                &name,
                Duration::from_secs(600),
                now,
            )
            .unwrap()
        })
        .collect();
    let owner = options.client_options(1);
    let mut tasks = Vec::new();
    for i in 0..3 {
        let o = if i == 1 {
            owner.clone()
        } else {
            options.client_options(i)
        };
        tasks.push(tokio::spawn(run_bot(
            o,
            std::sync::Arc::new(Demo),
            1,
            false,
            std::future::pending(),
        )));
        tokio::time::sleep(Duration::from_millis(30)).await;
    }
    server
        .wait_for(Duration::from_secs(10), |e| {
            matches!(e, ServerEvent::MatchStarted { .. }).then_some(())
        })
        .await;
    tokio::time::sleep(Duration::from_millis(1500)).await;
    // The old bot still plays; the owner connects again beside it.
    let again = run_bot(
        owner.clone(),
        std::sync::Arc::new(Demo),
        1,
        false,
        std::future::pending(),
    )
    .await
    .expect("the owner takes its seat back");
    let old = tasks.remove(1).await.unwrap();
    let mut others = Vec::new();
    for t in tasks {
        others.push(t.await.unwrap().expect("bot plays"));
    }
    let ended = server.match_end(Duration::from_secs(10)).await;
    server.shutdown().await;
    assert_same_hashes(&others, 480);
    assert_eq!(again.slot, Slot(1));
    assert!(again.first_applied > 60, "{}", again.first_applied);
    assert_eq!(again.hashes.len() as u64, 480 - again.first_applied);
    for (i, h) in again.hashes.iter().enumerate() {
        let t = again.first_applied as usize + i;
        assert_eq!(*h, others[0].hashes[t], "tick {t}");
    }
    // The old connection was dropped before the end of the match.
    if let Ok(r) = &old {
        assert!((r.hashes.len() as u64) < 480, "{}", r.hashes.len());
    }
    assert!(ended.desyncs.is_empty(), "{:?}", ended.desyncs);
    let check = verify_replay_file(ended.replay.as_ref().unwrap(), &Demo).expect("replay verifies");
    assert_eq!((check.ticks, check.checked), (480, 480));
}

/// One HTTP GET on the metrics listener: status line and body.
async fn http_get(addr: SocketAddr, path: &str) -> (String, String) {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut s = tokio::net::TcpStream::connect(addr).await.expect("connect");
    let req = format!("GET {path} HTTP/1.1\r\nHost: x\r\n\r\n");
    s.write_all(req.as_bytes()).await.unwrap();
    let mut out = String::new();
    s.read_to_string(&mut out).await.unwrap();
    let (head, body) = out.split_once("\r\n\r\n").unwrap_or((&out, ""));
    (
        head.lines().next().unwrap_or("").to_owned(),
        body.to_owned(),
    )
}

/// The metrics listener during a match: the tick-lateness histogram, the
/// player count, a refused join in `lockstep_refusals_total` and no match
/// yet in `lockstep_matches_total` (a lobby closed before, which is none)
/// on `/metrics`, `/healthz` and `/readyz` answer; with `exit_after_match`
/// the server stops by itself after the match (not after the lobby that
/// closed), with its replay flushed. The clock asks for real-time priority, so the match also
/// shows that a granted (root) or refused (no CAP_SYS_NICE) request plays
/// the same.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn metrics_and_health_are_served_and_the_server_exits_after_its_match() {
    let mut server = TestServer::start(tmp("metrics"), |c| {
        c.room.start_players = 2;
        c.room.match_ticks = Some(240);
        c.metrics = Some(SocketAddr::from(([127, 0, 0, 1], 0)));
        c.exit_after_match = true;
        c.realtime_clock = true;
    })
    .await;
    let metrics = server.metrics.expect("the metrics listener");
    // A lobby whose only player leaves closes before any match: the server
    // must not take it for the match it exits after.
    let (endpoint, connection, mut send, _recv, _slot) =
        raw_join(server.addr, &server.cert, "lobby", "visitor").await;
    write_frame(&mut send, &ClientMessage::Leave.encode().unwrap())
        .await
        .unwrap();
    server
        .wait_for(Duration::from_secs(10), |e| match e {
            ServerEvent::MatchEnded(r) if r.room == "lobby" => Some(()),
            _ => None,
        })
        .await;
    connection.close(0u32.into(), b"bye");
    endpoint.wait_idle().await;
    let options = BotOptions::new(server.addr, &server.cert, "metrics", 2);
    let bots = tokio::spawn(async move { run_bots(&options, std::future::pending()).await });
    server
        .wait_for(Duration::from_secs(10), |e| {
            matches!(e, ServerEvent::MatchStarted { .. }).then_some(())
        })
        .await;
    tokio::time::sleep(Duration::from_millis(1500)).await;
    // A join to the running match (no late join) is refused and counted.
    let late = lockstep_client::net::ClientOptions::new(server.addr, &server.cert, "metrics", "p");
    match lockstep_client::net::Client::connect(late, &Demo).await {
        Err(lockstep_client::net::ClientError::Refused { reason, .. }) => {
            assert_eq!(reason, CloseReason::MatchInProgress);
        }
        other => panic!("expected a refusal, got {other:?}"),
    }
    let (status, body) = http_get(metrics, "/metrics").await;
    assert_eq!(status, "HTTP/1.1 200 OK");
    assert!(
        body.contains("lockstep_refusals_total{reason=\"join\"} 1"),
        "{body}"
    );
    // The closed lobby is no match, and the running one has not ended.
    assert!(body.contains("lockstep_matches_total 0"), "{body}");
    assert!(body.contains("lockstep_players 2"), "{body}");
    assert!(body.contains("lockstep_rooms 1"), "{body}");
    assert!(body.contains("lockstep_matches_running 1"), "{body}");
    assert!(body.contains("# TYPE lockstep_tick_lateness_seconds histogram"));
    let count: u64 = body
        .lines()
        .find_map(|l| l.strip_prefix("lockstep_tick_lateness_seconds_count "))
        .and_then(|v| v.parse().ok())
        .expect("a lateness count");
    assert!(count >= 60, "{count} ticks measured");
    assert!(body.contains("lockstep_tick_lateness_seconds_bucket{le=\"0.002\"}"));
    let (status, body) = http_get(metrics, "/healthz").await;
    assert_eq!(
        (status.as_str(), body.as_str()),
        ("HTTP/1.1 200 OK", "ok\n")
    );
    let (status, _) = http_get(metrics, "/readyz").await;
    assert_eq!(status, "HTTP/1.1 200 OK");
    let (status, _) = http_get(metrics, "/nothing").await;
    assert_eq!(status, "HTTP/1.1 404 Not Found");
    bots_ok(bots.await.unwrap());
    // The server stops by itself once the match is over.
    let task = server.task;
    let report = tokio::time::timeout(Duration::from_secs(10), task)
        .await
        .expect("the server exits after its match")
        .expect("server task")
        .expect("server run");
    assert_eq!(report.matches_total, 1);
    let m = &report.matches[0];
    assert_eq!(m.ticks, 240);
    let check = verify_replay_file(m.replay.as_ref().unwrap(), &Demo).expect("replay flushed");
    assert_eq!(check.ticks, 240);
    println!("metrics sample:\n{}", body_sample(&metrics).await);
}

async fn body_sample(addr: &SocketAddr) -> String {
    // The listener is gone with the server: say so rather than hang.
    match tokio::time::timeout(Duration::from_secs(1), tokio::net::TcpStream::connect(addr)).await {
        Ok(Ok(_)) => "the listener still accepts".into(),
        _ => "the listener closed with the server".into(),
    }
}
