//! The browser client in a real browser (issue 47): headless Chromium,
//! driven through WebDriver (`lockstep_testsupport::webdriver`), loads the
//! page and the demo's WebAssembly module (`lockstep-web-demo`, built here
//! with cargo) and joins the server's WebTransport endpoint, trusting its
//! generated certificate by its SHA-256 as `serverCertificateHashes`.
//!
//! - A browser player and two native bots play 600 ticks: the room
//!   compares every tick's hash from all three with no mismatch, the page
//!   applied and reported every tick (part of them with the keyboard's
//!   input), its last hash is the bots', and the replay re-verifies
//!   offline.
//! - Forged and expired join tokens are refused, and the page shows the
//!   refusal's reason; a good token joins.
//!
//! Needs `chromium` and `chromium-driver` (see the webdriver module: a
//! missing browser skips, or fails under LOCKSTEP_BROWSER_TESTS=require)
//! and the `wasm32-unknown-unknown` target (added with rustup if missing).
//! The figures of docs/browser.md are printed by the first test
//! (`cargo test -p lockstep-tests --test browser -- --nocapture`).

use std::net::{SocketAddr, TcpListener};
use std::path::PathBuf;
use std::sync::OnceLock;
use std::time::{Duration, Instant, SystemTime};

use lockstep_client::bot::BotOptions;
use lockstep_client::game::{Demo, RulesFactory};
use lockstep_client::net::Client;
use lockstep_server::{ServerConfig, WEBTRANSPORT_PATH, issue_token};
use lockstep_tests::harness::{TestServer, bots_ok};
use lockstep_testsupport::webdriver::{self, Browser};
use lockstep_tools::verify_replay_file;
use lockstep_web::site::{JoinLink, ModuleBuild};
use serde_json::{Value, json};

/// Ticks of the match the browser plays.
const TICKS: u64 = 600;

fn tmp(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("browser-{name}"))
}

/// The demo's browser module, built once for this file's tests.
fn module() -> Vec<u8> {
    static MODULE: OnceLock<Vec<u8>> = OnceLock::new();
    MODULE
        .get_or_init(|| {
            let started = Instant::now();
            let path = ModuleBuild::demo()
                .build()
                .unwrap_or_else(|e| panic!("the browser module: {e}"));
            let bytes = std::fs::read(&path).unwrap();
            println!(
                "browser module: {} ({} bytes), built or checked in {:.1} s",
                path.display(),
                bytes.len(),
                started.elapsed().as_secs_f64()
            );
            bytes
        })
        .clone()
}

/// Serves the page and the module on a free port of 127.0.0.1.
fn site() -> SocketAddr {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let module = module();
    std::thread::spawn(move || lockstep_web::site::serve(listener, module));
    addr
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

/// A demo server with a WebTransport endpoint on a free port, with its
/// address and certificate hash (hex).
fn start(
    rt: &tokio::runtime::Runtime,
    name: &str,
    tweak: impl FnOnce(&mut ServerConfig),
) -> (TestServer, SocketAddr, String) {
    let (server, addr, hash) = rt.block_on(TestServer::start_webtransport(tmp(name), tweak));
    let hex = hash.iter().map(|b| format!("{b:02x}")).collect();
    (server, addr, hex)
}

fn link(webtransport: SocketAddr, hash: &str, room: &str) -> JoinLink {
    JoinLink {
        webtransport,
        path: WEBTRANSPORT_PATH.into(),
        cert_sha256: Some(hash.to_owned()),
        room: room.to_owned(),
        name: "chromium".into(),
        token: None,
        bot: None,
    }
}

/// The page's state (`window.lockstep.state()`, docs/browser.md).
fn state(b: &Browser) -> Value {
    b.run("return window.lockstep ? window.lockstep.state() : null")
}

/// Waits up to `timeout` for the page's state to satisfy `done`; fails
/// at once on an error the page reports.
fn wait_page(b: &Browser, timeout: Duration, what: &str, done: impl Fn(&Value) -> bool) -> Value {
    let deadline = Instant::now() + timeout;
    loop {
        let s = state(b);
        assert!(s["pageError"].is_null(), "{what}: the page failed: {s}");
        assert!(s["workerError"].is_null(), "{what}: the worker failed: {s}");
        assert!(
            s["ended"]["kind"] != "failed",
            "{what}: the client failed: {s}"
        );
        if done(&s) {
            return s;
        }
        assert!(Instant::now() < deadline, "{what}: timed out at {s}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn a_browser_player_and_two_native_bots_agree_on_every_tick_and_the_replay_reverifies() {
    let Some((chromium, driver)) = webdriver::browser() else {
        return;
    };
    let site = site();
    let rt = runtime();
    let (mut server, wt, hash) = start(&rt, "match", |c| {
        c.room.start_players = 3;
        c.room.match_ticks = Some(TICKS);
    });
    // The bots are seated (welcomed) first and wait in the lobby, so that
    // the page's first tick comes as soon as it has joined.
    let options = BotOptions::new(server.addr, &server.cert, "browser", 2);
    let bots: Vec<_> = (0..2)
        .map(|i| {
            let client = rt
                .block_on(Client::connect(options.client_options(i), &Demo))
                .expect("a bot joins");
            let slot = client.slot().0;
            rt.spawn(client.play(
                move |tick| Demo.bot_input(1, slot, tick),
                |_| {},
                std::future::pending(),
            ))
        })
        .collect();
    let b = Browser::start(&chromium, &driver, &tmp("match").join("chromium"), &[]);
    let mut page = link(wt, &hash, "browser");
    page.bot = Some(5);
    b.open(&page.url(site));
    let s = wait_page(&b, Duration::from_secs(60), "joining", |s| {
        s["joined"] == true
    });
    assert_eq!(s["rules"], "lockstep-demo v3");
    assert_eq!(s["bot"], true, "{s}");
    // Half-way the keyboard takes over: the right arrow walks along +x.
    wait_page(&b, Duration::from_secs(60), "half the match", |s| {
        s["ticksApplied"].as_u64() >= Some(TICKS / 2)
    });
    b.hold("\u{E014}");
    let s = wait_page(&b, Duration::from_secs(10), "the keys' input", |s| {
        s["bot"] == false && s["lastInput"] == json!([100, 0, 0])
    });
    let keys_from = s["lastTick"].as_u64().unwrap();
    std::thread::sleep(Duration::from_millis(500));
    b.release_keys();
    let ended = rt.block_on(server.match_end(Duration::from_secs(60)));
    let s = wait_page(&b, Duration::from_secs(30), "the end on the page", |s| {
        s["ended"]["kind"] == "closed"
    });
    b.save_screenshot(&tmp("match"), "browser-client.png");
    let bots = bots_ok(
        bots.into_iter()
            .map(|b| rt.block_on(b).expect("the bot's task"))
            .collect(),
    );
    let report = rt.block_on(server.shutdown());

    // The room: three players, every tick compared, no mismatch.
    assert_eq!(ended.ticks, TICKS);
    assert_eq!(ended.ticks_compared, TICKS);
    assert_eq!(ended.mismatched_ticks, 0);
    assert!(ended.desyncs.is_empty(), "{:?}", ended.desyncs);
    assert_eq!(ended.players.len(), 3);
    assert!(report.refused.is_empty(), "{:?}", report.refused);
    let browser = ended
        .players
        .iter()
        .find(|p| p.name == "chromium")
        .expect("the browser player in the report");
    assert_eq!(browser.hash_reports, TICKS, "{browser:?}");
    // Its inputs arrived in time, mostly (a page whose datagrams queue up
    // behind its drawing has nearly all of them substituted; the bound
    // leaves room for a loaded machine's stalls).
    assert!(browser.inputs_substituted < TICKS / 4, "{browser:?}");
    assert!(browser.rtt.is_some(), "pongs came back: {browser:?}");
    // The page: every tick applied and reported, the match closed by the
    // room, the same last hash as the bots.
    assert_eq!(s["ended"]["reason"], "RoomClosed", "{s}");
    assert_eq!(s["ticksApplied"].as_u64(), Some(TICKS), "{s}");
    assert_eq!(s["reportsSent"].as_u64(), Some(TICKS), "{s}");
    assert_eq!(s["desyncs"].as_u64(), Some(0), "{s}");
    assert_eq!(s["lastTick"].as_u64(), Some(TICKS - 1));
    for bot in &bots {
        assert_eq!(bot.hashes.len() as u64, TICKS);
        assert_eq!(
            s["lastHash"].as_str(),
            Some(format!("{:016x}", bot.hashes[TICKS as usize - 1]).as_str())
        );
    }
    // The replay holds the keyboard's input from that tick on, and
    // re-verifies offline.
    let path = ended.replay.expect("replay recorded");
    let check = verify_replay_file(&path, &Demo).expect("replay verifies");
    assert_eq!(
        (check.ticks, check.checked, check.players),
        (TICKS, TICKS, 3)
    );
    let replay = lockstep_proto::Replay::parse(&std::fs::read(&path).unwrap()).unwrap();
    let slot = s["slot"].as_u64().unwrap() as u8;
    let walked = replay.ticks.iter().any(|b| {
        b.tick > keys_from
            && b.inputs
                .iter()
                .any(|p| p.slot.0 == slot && p.input == [100, 0, 0] && !p.substituted)
    });
    let around: Vec<_> = replay
        .ticks
        .iter()
        .filter(|b| b.tick > keys_from && b.tick < keys_from + 40)
        .map(|b| (b.tick, b.inputs.iter().find(|p| p.slot.0 == slot).cloned()))
        .collect();
    assert!(
        walked,
        "the keyboard's input is in the replay: from {keys_from}, slot {slot}: {around:?}"
    );

    // Figures for docs/browser.md.
    let step = &s["step"];
    let at = &s["at"];
    let secs = browser.connected_for.as_secs_f64();
    println!(
        "browser step (wasm, Chromium, performance.now, cross-origin isolated: {}): median {:.3} ms, \
         p90 {:.3} ms, max {:.3} ms over {} ticks",
        s["isolated"],
        step["median"].as_f64().unwrap(),
        step["p90"].as_f64().unwrap(),
        step["max"].as_f64().unwrap(),
        step["count"]
    );
    println!(
        "browser player: UDP down {:.0} B/s, up {:.0} B/s (server's counters, {:.1} s connected); \
         page's own protocol bytes: stream in {} out {}, datagrams in {} B ({}) out {} B ({})",
        browser.udp_bytes_down as f64 / secs,
        browser.udp_bytes_up as f64 / secs,
        secs,
        s["streamBytesIn"],
        s["streamBytesOut"],
        s["datagramBytesIn"],
        s["datagramsIn"],
        s["datagramBytesOut"],
        s["datagramsOut"]
    );
    for p in ended.players.iter().filter(|p| p.name != "chromium") {
        let t = p.connected_for.as_secs_f64();
        println!(
            "native {}: UDP down {:.0} B/s, up {:.0} B/s",
            p.name,
            p.udp_bytes_down as f64 / t,
            p.udp_bytes_up as f64 / t
        );
    }
    println!(
        "page load to: module ready {:.0} ms, WebTransport ready {:.0} ms, welcome {:.0} ms, \
         first tick {:.0} ms",
        at["module"].as_f64().unwrap(),
        at["connected"].as_f64().unwrap(),
        at["welcome"].as_f64().unwrap(),
        at["firstTick"].as_f64().unwrap()
    );
    println!("replay: {}", path.display());
}

#[test]
fn forged_and_expired_tokens_are_refused_with_the_reason_on_the_page() {
    let Some((chromium, driver)) = webdriver::browser() else {
        return;
    };
    let site = site();
    let rt = runtime();
    let secret = b"a browser test secret of 16+ bytes".to_vec();
    let key = secret.clone();
    let (server, wt, hash) = start(&rt, "tokens", move |c| {
        c.token_secret = Some(key);
        c.require_tokens = true;
        c.room.start_players = 1;
        c.room.match_ticks = Some(60);
    });
    let now = SystemTime::now();
    let token = |secret: &[u8], from: SystemTime, ttl: u64| {
        issue_token(
            secret,
            "tokens",
            None,
            "chromium",
            Duration::from_secs(ttl),
            from,
        )
        .unwrap()
    };
    let forged = token(b"not the server's secret at all!!", now, 600);
    let expired = token(&secret, now - Duration::from_secs(3600), 60);
    let good = token(&secret, now, 600);
    let b = Browser::start(&chromium, &driver, &tmp("tokens").join("chromium"), &[]);
    for (what, t, detail) in [
        ("forged", forged, "join token signature invalid"),
        ("expired", expired, "join token expired at "),
    ] {
        let mut page = link(wt, &hash, "tokens");
        page.token = Some(t);
        b.open(&page.url(site));
        let s = wait_page(&b, Duration::from_secs(30), what, |s| {
            s["ended"]["kind"] == "refused"
        });
        assert_eq!(s["ended"]["reason"], "BadToken", "{what}: {s}");
        assert!(
            s["ended"]["detail"].as_str().unwrap().starts_with(detail),
            "{what}: {s}"
        );
        assert_eq!(s["joined"], false);
        // What a player sees: the status line, read from the DOM.
        let shown = b.run("return document.getElementById('status').textContent");
        let shown = shown.as_str().unwrap();
        assert!(
            shown.starts_with("refused: BadToken (") && shown.contains(detail),
            "{what}: the page shows {shown:?}"
        );
    }
    // The same page with a good token plays.
    let mut page = link(wt, &hash, "tokens");
    page.token = Some(good);
    b.open(&page.url(site));
    let s = wait_page(&b, Duration::from_secs(30), "a good token", |s| {
        s["ticksApplied"].as_u64() >= Some(30)
    });
    assert_eq!(s["joined"], true);
    drop(b);
    let report = rt.block_on(server.shutdown());
    assert_eq!(report.refused.len(), 2, "{:?}", report.refused);
}
