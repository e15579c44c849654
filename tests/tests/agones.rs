//! The server in Agones mode against the SDK stand-in (a local gRPC server
//! implementing the SDK service): `Ready` once listening, joins refused until
//! allocated, the allocation's room and token secret enforced, health pings
//! while the match runs, and `Shutdown` after the match with its replay
//! flushed.

use std::path::PathBuf;
use std::time::{Duration, SystemTime};

use lockstep_client::bot::{BotOptions, run_bots};
use lockstep_client::game::Demo;
use lockstep_client::net::{Client, ClientError, ClientOptions};
use lockstep_proto::CloseReason;
use lockstep_server::agones::{AgonesSettings, ROOM_KEY, TOKEN_SECRET_KEY};
use lockstep_server::{ServerError, issue_token};
use lockstep_tests::agones::StandIn;
use lockstep_tests::harness::{TestServer, assert_same_hashes, bots_ok};
use lockstep_tools::verify_replay_file;

fn tmp(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("agones-{name}"))
}

/// The refusal a join to `room` gets.
async fn refusal(server: &TestServer, room: &str) -> (CloseReason, String) {
    let o = ClientOptions::new(server.addr, &server.cert, room, "p");
    match Client::connect(o, &Demo).await {
        Err(ClientError::Refused { reason, detail }) => (reason, detail),
        Err(e) => panic!("expected a refusal, got {e}"),
        Ok(c) => panic!("expected a refusal, got a seat: {c:?}"),
    }
}

/// The refusal a join to `room` gets once the server has seen its
/// allocation (the watch delivers it a moment after the stand-in allocates).
async fn refusal_once_allocated(server: &TestServer, room: &str) -> (CloseReason, String) {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(5);
    loop {
        let r = refusal(server, room).await;
        if r.1 != "this game server is not allocated yet" {
            return r;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "allocation not seen"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_agones_game_server_is_ready_waits_for_its_allocation_plays_one_match_and_shuts_down() {
    let (sdk, sdk_addr) = StandIn::start().await;
    let server = TestServer::start(tmp("match"), |c| {
        c.room.start_players = 2;
        c.room.match_ticks = Some(180);
        c.agones = Some(AgonesSettings {
            sdk: format!("http://{sdk_addr}"),
            health_period: Duration::from_millis(200),
            connect_timeout: Duration::from_secs(5),
        });
    })
    .await;
    // Ready once listening, with the watch on the allocation open first.
    let calls = sdk.calls();
    assert_eq!(
        calls.methods[..2],
        ["WatchGameServer".to_owned(), "Ready".to_owned()]
    );
    assert_eq!(sdk.state(), "Ready");
    // Not allocated: no joins.
    assert_eq!(
        refusal(&server, "match-7").await,
        (
            CloseReason::WrongRoom,
            "this game server is not allocated yet".to_owned()
        )
    );
    // The allocator names the room and the token secret.
    let secret = "a per-match secret of 32 bytes..";
    sdk.allocate(&[(ROOM_KEY, "match-7"), (TOKEN_SECRET_KEY, secret)]);
    let other = refusal_once_allocated(&server, "other").await;
    assert_eq!(
        other,
        (
            CloseReason::WrongRoom,
            "this game server hosts room \"match-7\" only".to_owned()
        )
    );
    // Its secret makes tokens required.
    assert_eq!(
        refusal(&server, "match-7").await,
        (CloseReason::BadToken, "no join token".to_owned())
    );
    let token = |seat: u8| {
        issue_token(
            secret.as_bytes(),
            "match-7",
            Some(seat),
            &format!("bot-{seat}"),
            Duration::from_secs(600),
            SystemTime::now(),
        )
        .unwrap()
    };
    let mut options = BotOptions::new(server.addr, &server.cert, "match-7", 2);
    options.tokens = vec![token(0), token(1)];
    let bots = bots_ok(run_bots(&options, std::future::pending()).await);
    assert_same_hashes(&bots, 180);
    // After the match the server shuts down by itself: replay flushed,
    // then `Shutdown`.
    let report = tokio::time::timeout(Duration::from_secs(10), server.task)
        .await
        .expect("the server exits after its match")
        .expect("server task")
        .expect("server run");
    assert_eq!(report.matches_total, 1);
    let m = &report.matches[0];
    assert_eq!((m.room.as_str(), m.ticks), ("match-7", 180));
    let check = verify_replay_file(m.replay.as_ref().unwrap(), &Demo).expect("replay flushed");
    assert_eq!(check.ticks, 180);
    let calls = sdk.calls();
    assert_eq!(calls.count("Shutdown"), 1, "{:?}", calls.methods);
    assert_eq!(calls.methods.last().map(String::as_str), Some("Shutdown"));
    assert_eq!(sdk.state(), "Shutdown");
    assert_eq!(calls.count("Ready"), 1);
    // A ping every 200 ms over the 3-s match and the lobby.
    assert!(
        calls.health_pings >= 10,
        "{} health pings",
        calls.health_pings
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_allocation_with_a_short_token_secret_refuses_every_join_with_the_reason() {
    let (sdk, sdk_addr) = StandIn::start().await;
    let server = TestServer::start(tmp("short"), |c| {
        c.agones = Some(AgonesSettings {
            sdk: format!("http://{sdk_addr}"),
            health_period: Duration::from_millis(200),
            connect_timeout: Duration::from_secs(5),
        });
    })
    .await;
    sdk.allocate(&[(TOKEN_SECRET_KEY, "too short")]);
    let r = refusal_once_allocated(&server, "any").await;
    assert_eq!(
        r,
        (
            CloseReason::WrongRoom,
            "the allocation's token secret has 9 bytes; at least 16 are needed".to_owned()
        )
    );
    let report = server.shutdown().await;
    assert_eq!(report.matches_total, 0);
    // Shut down by the test (SIGTERM in a pod): still tells Agones.
    assert_eq!(sdk.calls().count("Shutdown"), 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_an_sdk_to_talk_to_the_server_does_not_start() {
    // A port nothing listens on: bind one, then free it.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let dir = tmp("nosdk");
    let _ = std::fs::remove_dir_all(&dir);
    let mut config = lockstep_server::ServerConfig::for_game(
        "127.0.0.1:0".parse().unwrap(),
        lockstep_client::game::DemoGame::SCENE,
        "demo",
        lockstep_client::game::RulesFactory::rules_id(&Demo),
    );
    config.tls = lockstep_server::TlsSource::dev(dir.join("cert.pem"));
    config.replay_dir = None;
    config.agones = Some(AgonesSettings {
        sdk: format!("http://127.0.0.1:{port}"),
        health_period: Duration::from_secs(2),
        connect_timeout: Duration::from_millis(600),
    });
    let r = tokio::time::timeout(
        Duration::from_secs(10),
        lockstep_server::run(config, std::future::pending()),
    )
    .await
    .expect("gives up after its connect timeout");
    match r {
        Err(ServerError::Agones(e)) => {
            let msg = e.to_string();
            assert!(
                msg.starts_with(&format!("SDK at http://127.0.0.1:{port}")),
                "{msg}"
            );
        }
        other => panic!("expected an Agones error, got {other:?}"),
    }
}
