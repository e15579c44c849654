//! The WebTransport endpoint (issue 47): browsers' way in, over HTTP/3 on
//! 127.0.0.1, into the same rooms as native QUIC, with the same messages,
//! tokens and refusals. The clients here are what a browser does with the
//! same certificate rules: WebTransport sessions on `/lockstep` that trust
//! the server's generated certificate by its SHA-256 only
//! (`serverCertificateHashes`).

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, SystemTime};

use lockstep_client::bot::{BotOptions, run_bot, run_bots};
use lockstep_client::game::{Demo, RulesVerifier};
use lockstep_client::net::{
    ClientOptions, TrustedCert, client_config, load_certs, read_frame, write_frame,
};
use lockstep_proto::{ClientMessage, CloseReason, Join, PROTOCOL_VERSION, ServerMessage};
use lockstep_server::{WEBTRANSPORT_PATH, issue_token};
use lockstep_tests::harness::{TestServer, assert_same_hashes, bots_ok};
use lockstep_tools::verify_replay_file;

/// The directory of a test's server (certificate, replays).
fn tmp(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("webtransport-{name}"))
}

/// A demo server with a WebTransport endpoint (see
/// [`TestServer::start_webtransport`]).
async fn start(
    name: &str,
    tweak: impl FnOnce(&mut lockstep_server::ServerConfig),
) -> (TestServer, SocketAddr, [u8; 32]) {
    TestServer::start_webtransport(tmp(name), tweak).await
}

/// A WebTransport session to `path` on `server`, trusting only the
/// certificate whose SHA-256 is `hash`, as a browser given
/// `serverCertificateHashes`.
async fn session(
    server: SocketAddr,
    hash: [u8; 32],
    path: &str,
) -> Result<web_transport_quinn::Session, web_transport_quinn::ClientError> {
    let client = web_transport_quinn::ClientBuilder::new()
        .with_server_certificate_hashes(vec![hash.to_vec()])?;
    let url = url::Url::parse(&format!("https://{server}{path}")).expect("url");
    client.connect(url).await
}

/// Sends `join` as the first frame of a WebTransport session's stream and
/// returns the server's `Close` message (reason, detail) and the
/// session's close code and reason.
async fn refused_over_webtransport(
    server: SocketAddr,
    hash: [u8; 32],
    join: &[u8],
) -> (CloseReason, String, u32, String) {
    let session = session(server, hash, WEBTRANSPORT_PATH)
        .await
        .expect("session");
    let (mut send, mut recv) = session.open_bi().await.expect("stream");
    write_frame(&mut send, join).await.expect("write join");
    let frame = tokio::time::timeout(Duration::from_secs(10), read_frame(&mut recv))
        .await
        .expect("an answer within 10 s")
        .expect("read")
        .expect("a frame");
    let ServerMessage::Close(close) = ServerMessage::decode(&frame).expect("decode") else {
        panic!("expected a close message");
    };
    let ended = tokio::time::timeout(Duration::from_secs(10), session.closed())
        .await
        .expect("closed within 10 s");
    let web_transport_quinn::SessionError::WebTransportError(
        web_transport_quinn::WebTransportError::Closed(code, reason),
    ) = ended
    else {
        panic!("the session ended without a WebTransport close: {ended}");
    };
    (close.reason, close.detail, code, reason)
}

/// The same over native QUIC: the `Close` message, and the connection's
/// close code and reason.
async fn refused_over_quic(
    server: SocketAddr,
    cert: &std::path::Path,
    join: &[u8],
) -> (CloseReason, String, u32, String) {
    let config = client_config(&load_certs(cert).expect("cert")).expect("tls");
    let mut endpoint = quinn::Endpoint::client("127.0.0.1:0".parse().unwrap()).expect("socket");
    endpoint.set_default_client_config(config);
    let connection = endpoint
        .connect(server, "localhost")
        .expect("connect")
        .await
        .expect("handshake");
    let (mut send, mut recv) = connection.open_bi().await.expect("stream");
    write_frame(&mut send, join).await.expect("write join");
    let frame = read_frame(&mut recv).await.expect("read").expect("a frame");
    let ServerMessage::Close(close) = ServerMessage::decode(&frame).expect("decode") else {
        panic!("expected a close message");
    };
    let quinn::ConnectionError::ApplicationClosed(c) = connection.closed().await else {
        panic!("closed without an application code");
    };
    let code = u32::try_from(c.error_code.into_inner()).expect("a u32 code");
    let reason = String::from_utf8(c.reason.to_vec()).expect("UTF-8");
    (close.reason, close.detail, code, reason)
}

fn join_with(token: String) -> Vec<u8> {
    ClientMessage::Join(Join {
        protocol_version: PROTOCOL_VERSION,
        room: "tokens".into(),
        player_name: "browser".into(),
        token: Some(token),
        rejoin: None,
    })
    .encode()
    .expect("join")
}

/// A forged token (signed with another secret) and an expired one are
/// refused over WebTransport exactly as over QUIC: the same `Close`
/// message on the stream (`BadToken` and its detail), then the session
/// closed with the same code (2, refused) and reason text as the QUIC
/// connection. A session on another path is refused (404), and a good
/// token still joins over WebTransport.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn forged_and_expired_tokens_are_refused_over_webtransport_as_over_quic() {
    let secret = b"a webtransport test secret, 16+ bytes".to_vec();
    let key = secret.clone();
    let (server, wt, hash) = start("tokens", move |c| {
        c.token_secret = Some(key);
        c.require_tokens = true;
    })
    .await;
    let now = SystemTime::now();
    let ttl = Duration::from_secs(600);
    let forged = issue_token(
        b"not the server's secret at all!!",
        "tokens",
        None,
        "browser",
        ttl,
        now,
    )
    .expect("token");
    let an_hour_ago = now - Duration::from_secs(3600);
    let expired = issue_token(
        &secret,
        "tokens",
        None,
        "browser",
        Duration::from_secs(60),
        an_hour_ago,
    )
    .expect("token");

    let forged_wt = refused_over_webtransport(wt, hash, &join_with(forged.clone())).await;
    let forged_quic = refused_over_quic(server.addr, &server.cert, &join_with(forged)).await;
    assert_eq!(forged_wt, forged_quic);
    assert_eq!(forged_wt.0, CloseReason::BadToken);
    assert_eq!(forged_wt.1, "join token signature invalid");
    assert_eq!(forged_wt.2, lockstep_client::net::close_code::REFUSED);
    assert_eq!(forged_wt.3, "BadToken: join token signature invalid");

    let expired_wt = refused_over_webtransport(wt, hash, &join_with(expired.clone())).await;
    let expired_quic = refused_over_quic(server.addr, &server.cert, &join_with(expired)).await;
    assert_eq!(expired_wt.0, CloseReason::BadToken);
    assert_eq!(expired_wt.2, lockstep_client::net::close_code::REFUSED);
    // The detail names the expiry and the server's clock, which may have
    // ticked a second between the two joins.
    let expiry = an_hour_ago
        .duration_since(SystemTime::UNIX_EPOCH)
        .unwrap()
        .as_secs()
        + 60;
    let prefix = format!("join token expired at {expiry} (now ");
    for (reason, detail, code, text) in [&expired_wt, &expired_quic] {
        assert_eq!(*reason, CloseReason::BadToken);
        assert!(detail.starts_with(&prefix), "{detail}");
        assert_eq!(*code, lockstep_client::net::close_code::REFUSED);
        assert_eq!(*text, format!("BadToken: {detail}"));
    }

    // Another path: no session (HTTP 404).
    let other = session(wt, hash, "/elsewhere").await;
    assert!(other.is_err(), "a session on /elsewhere opened");
    // A certificate of another hash is not trusted.
    assert!(session(wt, [7; 32], WEBTRANSPORT_PATH).await.is_err());

    // A valid token is seated over WebTransport: the welcome comes.
    let good = issue_token(&secret, "tokens", None, "browser", ttl, now).expect("token");
    let s = session(wt, hash, WEBTRANSPORT_PATH).await.expect("session");
    let (mut send, mut recv) = s.open_bi().await.expect("stream");
    write_frame(&mut send, &join_with(good))
        .await
        .expect("write");
    let frame = read_frame(&mut recv).await.expect("read").expect("frame");
    let ServerMessage::Welcome(w) = ServerMessage::decode(&frame).expect("decode") else {
        panic!("expected a welcome");
    };
    assert_eq!(w.slot.0, 0);
    assert!(
        w.rejoin.is_some(),
        "a token holder gets its rejoin credential"
    );
    drop((send, recv, s));

    let report = server.shutdown().await;
    let refusals: Vec<&str> = report.refused.iter().map(|(_, r)| r.as_str()).collect();
    assert!(
        refusals
            .iter()
            .filter(|r| r.contains("join token signature invalid"))
            .count()
            == 2,
        "{refusals:?}"
    );
    assert!(
        refusals
            .iter()
            .any(|r| r.contains("no session on path \"/elsewhere\" (404")),
        "{refusals:?}"
    );
}

/// A browser-like player (the client library joining over WebTransport,
/// trusting the generated certificate by its hash) and two native bots
/// play one 600-tick match of the demo: every one of them re-simulates and
/// reports every tick, the verifying server compares all 600 ticks with no
/// mismatch, and the replay re-verifies offline.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_webtransport_player_and_native_bots_agree_on_600_ticks_and_the_replay_reverifies() {
    const TICKS: u64 = 600;
    let (mut server, wt, hash) = start("match", |c| {
        c.room.start_players = 3;
        c.room.match_ticks = Some(TICKS);
        c.verifier = Some(Arc::new(RulesVerifier {
            game: Arc::new(Demo),
        }));
    })
    .await;
    let mut options = ClientOptions::new(wt, TrustedCert::Sha256(hash), "mixed", "browser");
    options.webtransport = true;
    let browser = tokio::spawn(run_bot(
        options,
        Arc::new(Demo),
        7,
        false,
        std::future::pending(),
    ));
    let natives = run_bots(
        &BotOptions::new(server.addr, &server.cert, "mixed", 2),
        std::future::pending(),
    )
    .await;
    let browser = browser
        .await
        .expect("task")
        .expect("the WebTransport player");
    let mut players = bots_ok(natives);
    players.push(browser);
    let ended = server.match_end(Duration::from_secs(30)).await;
    let report = server.shutdown().await;

    assert_same_hashes(&players, TICKS as usize);
    for p in &players {
        assert_eq!(p.desyncs().count(), 0);
        let close = p.close.as_ref().expect("closed by the server");
        assert_eq!(close.reason, CloseReason::RoomClosed);
    }
    assert_eq!(ended.ticks, TICKS);
    assert_eq!(ended.ticks_compared, TICKS);
    assert_eq!(ended.mismatched_ticks, 0);
    assert!(ended.desyncs.is_empty());
    assert_eq!(
        ended.verified.map(|v| v.0),
        Some(TICKS),
        "the server re-simulated"
    );
    assert!(report.refused.is_empty(), "{:?}", report.refused);
    assert_eq!(ended.players.len(), 3);
    let web = ended
        .players
        .iter()
        .find(|p| p.name == "browser")
        .expect("the WebTransport player in the room's report");
    assert_eq!(
        web.hash_reports, TICKS,
        "every tick's hash came over WebTransport"
    );
    assert!(
        web.datagrams_up >= TICKS,
        "inputs: {} datagrams",
        web.datagrams_up
    );
    assert!(
        web.datagrams_down >= TICKS,
        "bundles: {} datagrams",
        web.datagrams_down
    );
    assert!(web.left.is_none(), "played to the end: {:?}", web.left);

    let path = ended.replay.expect("replay recorded");
    let check = verify_replay_file(&path, &Demo).expect("replay verifies");
    assert_eq!(
        (check.ticks, check.checked, check.players),
        (TICKS, TICKS, 3)
    );
    assert_eq!(check.final_hash, players[2].hashes[TICKS as usize - 1]);

    // Figures (docs/protocol.md): what each player costs on the wire.
    let secs = ended.duration.as_secs_f64();
    for p in &ended.players {
        println!(
            "{} (slot {}): UDP down {:.0} B/s up {:.0} B/s; datagrams down {} (max {} B) up {} (max {} B); substituted {}",
            p.name,
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
}

/// The connection limits count WebTransport sessions with QUIC
/// connections: with one connection allowed per address, a session from
/// the address of a seated native player is refused with the overloaded
/// code (5) and the reason, in its WebTransport close.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn webtransport_sessions_count_against_the_per_address_limit() {
    let (server, wt, hash) = start("limits", |c| {
        c.max_connections_per_address = Some(1);
    })
    .await;
    let config = client_config(&load_certs(&server.cert).expect("cert")).expect("tls");
    let mut endpoint = quinn::Endpoint::client("127.0.0.1:0".parse().unwrap()).expect("socket");
    endpoint.set_default_client_config(config);
    let native = endpoint
        .connect(server.addr, "localhost")
        .expect("connect")
        .await
        .expect("handshake");
    let refused = session(wt, hash, WEBTRANSPORT_PATH).await.expect("session");
    let ended = tokio::time::timeout(Duration::from_secs(10), refused.closed())
        .await
        .expect("closed within 10 s");
    let web_transport_quinn::SessionError::WebTransportError(
        web_transport_quinn::WebTransportError::Closed(code, reason),
    ) = ended
    else {
        panic!("the session ended without a WebTransport close: {ended}");
    };
    assert_eq!(code, lockstep_client::net::close_code::OVERLOADED);
    assert_eq!(
        reason,
        "too many connections from 127.0.0.1 (at most 1 per address)"
    );
    native.close(0u32.into(), b"done");
    let report = server.shutdown().await;
    assert!(
        report
            .refused
            .iter()
            .any(|(_, r)| r.starts_with("too many connections from 127.0.0.1")),
        "{:?}",
        report.refused
    );
}

/// A WebTransport address that cannot be bound stops the server at start
/// with an error naming the endpoint and the address.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_webtransport_address_in_use_is_a_clear_start_up_error() {
    let taken = std::net::UdpSocket::bind("127.0.0.1:0").expect("a UDP socket");
    let addr = taken.local_addr().expect("its address");
    let dir = tmp("bind");
    let mut config = lockstep_server::ServerConfig::for_game(
        SocketAddr::from(([127, 0, 0, 1], 0)),
        lockstep_client::game::DemoGame::SCENE,
        "demo",
        lockstep_client::game::RulesFactory::rules_id(&Demo),
    );
    config.tls = lockstep_server::TlsSource::dev(dir.join("cert.pem"));
    config.replay_dir = None;
    config.webtransport = Some(addr);
    let e = lockstep_server::run(config, std::future::pending())
        .await
        .expect_err("the address is taken");
    assert!(matches!(e, lockstep_server::ServerError::BindWebTransport(a, _) if a == addr));
    let text = e.to_string();
    assert!(
        text.starts_with(&format!("bind the WebTransport endpoint on {addr}: ")),
        "{text}"
    );
    drop(taken);
}

/// Protocol violations close a WebTransport player as they close a QUIC
/// one: a first frame that does not decode is refused with the same
/// `Close` message, code (1) and reason over both; and a datagram that
/// names another WebTransport session than the player's own closes it as a
/// bad datagram.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn protocol_violations_close_a_webtransport_player_with_code_1() {
    let (server, wt, hash) = start("violations", |_| {}).await;
    // A version header, then a variant that does not exist.
    let garbage = [PROTOCOL_VERSION.to_le_bytes().as_slice(), &[99, 1, 2]].concat();
    let over_wt = refused_over_webtransport(wt, hash, &garbage).await;
    let over_quic = refused_over_quic(server.addr, &server.cert, &garbage).await;
    assert_eq!(over_wt, over_quic);
    assert_eq!(over_wt.0, CloseReason::ProtocolViolation);
    assert!(over_wt.1.starts_with("undecodable join: "), "{}", over_wt.1);
    assert_eq!(
        over_wt.2,
        lockstep_client::net::close_code::PROTOCOL_VIOLATION
    );

    let s = session(wt, hash, WEBTRANSPORT_PATH).await.expect("session");
    let (mut send, mut recv) = s.open_bi().await.expect("stream");
    let join = ClientMessage::Join(Join {
        protocol_version: PROTOCOL_VERSION,
        room: "violations".into(),
        player_name: "browser".into(),
        token: None,
        rejoin: None,
    })
    .encode()
    .expect("join");
    write_frame(&mut send, &join).await.expect("write");
    let frame = read_frame(&mut recv).await.expect("read").expect("frame");
    assert!(matches!(
        ServerMessage::decode(&frame),
        Ok(ServerMessage::Welcome(_))
    ));
    // A raw QUIC datagram under the session: its first byte is the
    // session's quarter stream id, and 5 names a session there is not.
    let pong = ClientMessage::Pong(lockstep_proto::Pong { nonce: 1 })
        .encode()
        .expect("pong");
    let foreign = [[5u8].as_slice(), &pong].concat();
    quinn::Connection::send_datagram(&s, foreign.into()).expect("datagram");
    let close = tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            let frame = read_frame(&mut recv).await.expect("read").expect("frame");
            if let Ok(ServerMessage::Close(c)) = ServerMessage::decode(&frame) {
                return c;
            }
        }
    })
    .await
    .expect("closed within 10 s");
    assert_eq!(close.reason, CloseReason::ProtocolViolation);
    assert_eq!(
        close.detail,
        "bad datagram: a datagram for another WebTransport session"
    );
    let ended = tokio::time::timeout(Duration::from_secs(10), s.closed())
        .await
        .expect("session closed within 10 s");
    let web_transport_quinn::SessionError::WebTransportError(
        web_transport_quinn::WebTransportError::Closed(code, _),
    ) = ended
    else {
        panic!("the session ended without a WebTransport close: {ended}");
    };
    assert_eq!(code, lockstep_client::net::close_code::PROTOCOL_VIOLATION);
    server.shutdown().await;
}
