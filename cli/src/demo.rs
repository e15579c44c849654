//! The demo match: the server on loopback with a game's scene and
//! in-process bots over real QUIC, a status line per second, and a summary
//! at the end. The game is a parameter ([`DemoOptions::game`], with the
//! server's scene and rules id): the demo game by default (the README's
//! main job), any other game likewise (`<game> server --demo`).
//!
//! With the server's WebTransport endpoint on (`--webtransport ADDR`) and
//! the game's browser module ([`DemoOptions::web`]), the demo also serves
//! the browser client's page, prints its URL, and the match waits for a
//! player in a browser beside the bots (docs/browser.md).

use std::future::Future;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use lockstep_client::bot::{BotOptions, run_bots};
use lockstep_client::game::{Demo, DemoGame, RulesFactory};
use lockstep_tools::verify_replay_file;
use tokio::sync::{mpsc, oneshot};

use lockstep_server::{
    RoomReport, RoomStatus, ServerConfig, ServerError, ServerEvent, TlsSource, run,
};

/// What the demo runs.
#[derive(Clone)]
pub struct DemoOptions {
    /// Server settings; `events` is set by the demo. Its scene and rules id
    /// must be `game`'s.
    pub server: ServerConfig,
    /// The game the bots play and the replay is checked with.
    pub game: Arc<dyn RulesFactory>,
    /// Number of bots.
    pub bots: usize,
    /// Seed of the bots' input.
    pub seed: u64,
    /// How long the match lasts (it also ends on Ctrl-C).
    pub duration: Duration,
    /// Make the last bot nudge one body by one ulp before this tick, to
    /// show a desync being located (`--diverge-at`).
    pub diverge_at: Option<u64>,
    /// The room the bots play in.
    pub room: String,
    /// The bots predict and roll back (`--predict`): the status line shows
    /// their rollbacks, and the summary their input-to-effect latency with
    /// and without prediction.
    pub predict: bool,
    /// How to run the offline tool with this game, for the hints printed
    /// (`cargo run --release -p lockstep --bin lockstep --` for the demo).
    pub tool: String,
    /// The browser client's page and module, served when the server has a
    /// WebTransport endpoint (`server.webtransport`); the match then waits
    /// for `players` players in browsers as well as the bots.
    pub web: Option<crate::web::WebDemo>,
}

impl DemoOptions {
    /// The demo game with four bots, 20 s, on a free loopback port, dev
    /// certificate in `out/`.
    pub fn new() -> Self {
        let mut server = ServerConfig::for_game(
            SocketAddr::from(([127, 0, 0, 1], 0)),
            DemoGame::SCENE,
            "demo",
            Demo.rules_id(),
        );
        server.tls = TlsSource::dev("out/dev-cert.pem");
        Self {
            server,
            game: Arc::new(Demo),
            bots: 4,
            seed: 1,
            duration: Duration::from_secs(20),
            diverge_at: None,
            room: "demo".into(),
            predict: false,
            tool: "cargo run --release -p lockstep --bin lockstep --".into(),
            web: None,
        }
    }
}

impl std::fmt::Debug for DemoOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DemoOptions")
            .field("server", &self.server)
            .field("game", &self.game.rules_id())
            .field("bots", &self.bots)
            .field("seed", &self.seed)
            .field("duration", &self.duration)
            .finish()
    }
}

impl Default for DemoOptions {
    fn default() -> Self {
        Self::new()
    }
}

/// What the demo did.
#[derive(Clone, Debug)]
pub struct DemoSummary {
    /// The match, as the server saw it.
    pub report: Option<RoomReport>,
    /// Bots that finished without error.
    pub bots_ok: usize,
    /// Whether every bot reported the same hash for every tick they share.
    pub bots_agree: bool,
    /// The replay's verification line.
    pub replay_check: Option<String>,
}

fn kb(bytes_per_sec: u64) -> String {
    format!("{:.1} kB/s", bytes_per_sec as f64 / 1000.0)
}

/// One status line: tick, players, round trip, bytes per second per player,
/// hash agreement (the server's own format).
pub fn status_line(s: &RoomStatus) -> String {
    s.to_string()
}

/// Runs the demo until its duration passes or `interrupt` completes,
/// printing status lines and the summary to stdout.
///
/// # Errors
/// [`ServerError`] if the server cannot start.
pub async fn run_demo(
    mut options: DemoOptions,
    interrupt: impl Future<Output = ()>,
) -> Result<DemoSummary, ServerError> {
    let (events_tx, mut events) = mpsc::unbounded_channel();
    // The browser module first: its first build takes minutes, and the
    // match must not start without the browser players.
    let web = match (&options.web, options.server.webtransport) {
        (Some(web), Some(_)) => {
            println!("demo: building the browser module (the first build takes a few minutes)");
            let module = web.module.load().map_err(ServerError::Config)?;
            Some((web.clone(), module))
        }
        _ => None,
    };
    let browsers = web.as_ref().map_or(0, |(w, _)| usize::from(w.players));
    if browsers > 0 {
        // A person opens the page: the lobby waits for them (Ctrl-C ends
        // the demo), instead of starting without them after its timeout.
        options.server.room.lobby_timeout = None;
    }
    options.server.room.start_players =
        u8::try_from((options.bots + browsers).max(1)).unwrap_or(u8::MAX);
    options.server.room.max_players = options
        .server
        .room
        .max_players
        .max(options.server.room.start_players);
    let rate = u64::from(options.server.room.tick_rate);
    let ticks = (options.duration.as_millis() as u64 * rate)
        .div_ceil(1000)
        .max(1);
    options.server.room.match_ticks = Some(ticks);
    let (stop_tx, stop_rx) = oneshot::channel::<()>();
    let mut server_config = options.server.clone();
    // The demo prints the status lines itself.
    server_config.log_status = false;
    // The server holds the only sender: the channel closes when it stops.
    server_config.events = Some(events_tx);
    let server = tokio::spawn(run(server_config, async {
        let _ = stop_rx.await;
    }));
    // Wait for the address and certificate.
    let (addr, cert) = loop {
        match events.recv().await {
            Some(ServerEvent::Listening { addr, cert }) => break (addr, cert),
            Some(_) => {}
            None => {
                return match server.await {
                    Ok(Err(e)) => Err(e),
                    _ => Err(ServerError::Config("the server stopped at start-up".into())),
                };
            }
        }
    };
    let webtransport = match options.server.webtransport {
        Some(_) => loop {
            match events.recv().await {
                Some(ServerEvent::WebTransportListening { addr, cert_sha256 }) => {
                    break Some((addr, cert_sha256));
                }
                Some(_) => {}
                None => return Err(ServerError::Config("the server stopped at start-up".into())),
            }
        },
        None => None,
    };
    let cert: PathBuf = match (cert, &options.server.tls) {
        (Some(c), _) => c,
        (None, TlsSource::Files { cert, .. }) => cert.clone(),
        (None, TlsSource::SelfSigned { cert_out, .. }) => cert_out.clone(),
    };
    println!(
        "demo: server on {addr}, {} bots, {} ticks at {rate} Hz ({:.0} s); Ctrl-C ends it early",
        options.bots,
        ticks,
        options.duration.as_secs_f64()
    );
    match (web, webtransport) {
        (Some((web, module)), Some((addr, hash))) => {
            let site = crate::web::start_site(web.listen, module).map_err(ServerError::Config)?;
            let hash: String = hash.iter().map(|b| format!("{b:02x}")).collect();
            let url = crate::web::page_url(site, addr, &hash, &options.room, "browser");
            println!(
                "demo: the match starts when {browsers} player(s) join from a browser \
                 (Chromium or Chrome: WebTransport with serverCertificateHashes); open\n  {url}"
            );
        }
        (None, Some((addr, _))) => println!(
            "demo: WebTransport on {addr}; this game has no browser module, so no page is served"
        ),
        _ => {}
    }
    let mut bot_options = BotOptions::for_game(
        addr,
        cert,
        &options.room,
        options.bots,
        options.game.clone(),
    );
    bot_options.seed = options.seed;
    bot_options.predict = options.predict;
    let tally = options
        .predict
        .then(|| Arc::new(lockstep_client::net::PredictionTally::default()));
    bot_options.tally.clone_from(&tally);
    let mut last_counts = lockstep_client::net::TallyCounts::default();
    if let Some(tick) = options.diverge_at {
        bot_options.game_of_bot = vec![(
            options.bots.saturating_sub(1),
            Arc::new(lockstep_client::testing::Diverge {
                inner: options.game.clone(),
                tick,
            }),
        )];
    }
    let bots = tokio::spawn(async move { run_bots(&bot_options, std::future::pending()).await });
    tokio::pin!(interrupt);
    let mut stop_tx = Some(stop_tx);
    let mut report = None;
    loop {
        tokio::select! {
            () = &mut interrupt, if stop_tx.is_some() => {
                println!("demo: interrupted; finishing the tick and closing the match");
                if let Some(tx) = stop_tx.take() {
                    let _ = tx.send(());
                }
            }
            event = events.recv() => match event {
                Some(ServerEvent::Status(s)) => {
                    let mut line = status_line(&s);
                    if let Some(t) = &tally {
                        // The status comes once a second: the counts since
                        // the last one are per second.
                        let c = t.counts();
                        let rollbacks = c.rollbacks - last_counts.rollbacks;
                        let depth = (c.depth_sum - last_counts.depth_sum) as f64
                            / rollbacks.max(1) as f64;
                        line.push_str(&format!(
                            " | prediction: {rollbacks} rollbacks/s, mean depth {depth:.1}, largest {}, {} re-simulated ticks/s",
                            c.max_depth,
                            c.resimulated - last_counts.resimulated
                        ));
                        last_counts = c;
                    }
                    println!("{line}");
                }
                Some(ServerEvent::MatchStarted { players, .. }) => {
                    println!("demo: match started with {players} players");
                }
                Some(ServerEvent::Desync { notice, .. }) => {
                    println!("demo: DESYNC at tick {}: {:?}", notice.tick, notice.verdict);
                }
                Some(ServerEvent::DesyncLocated { report, bundle, .. }) => {
                    print!("demo: {report}");
                    if let Some(b) = bundle {
                        println!("demo: desync bundle {} (check it: {} replay {})", b.display(), options.tool, b.display());
                    }
                }
                Some(ServerEvent::MatchEnded(r)) => {
                    report = Some(r);
                    if let Some(tx) = stop_tx.take() {
                        let _ = tx.send(());
                    }
                }
                Some(_) => {}
                None => break,
            },
        }
    }
    let server_result = server.await;
    let bot_results = bots.await.unwrap_or_default();
    if let Ok(Err(e)) = server_result {
        return Err(e);
    }
    let oks: Vec<_> = bot_results.iter().filter_map(|r| r.as_ref().ok()).collect();
    for (i, r) in bot_results.iter().enumerate() {
        if let Err(e) = r {
            println!("demo: bot-{i} failed: {e}");
        }
    }
    let shortest = oks.iter().map(|r| r.hashes.len()).min().unwrap_or(0);
    let bots_agree = (0..shortest).all(|t| oks.iter().all(|r| r.hashes[t] == oks[0].hashes[t]));
    let replay_check = report.as_ref().and_then(|r| r.replay.as_ref()).map(|p| {
        match verify_replay_file(p, &*options.game) {
            Ok(c) => format!(
                "OK, {} ticks re-simulated, {} hashes checked",
                c.ticks, c.checked
            ),
            Err(e) => format!("FAILED: {e}"),
        }
    });
    if options.predict {
        for (i, r) in oks.iter().enumerate() {
            let (p, l) = (r.prediction, r.input_latency);
            println!(
                "bot-{i}: {} rollbacks (deepest {} ticks), {} predictions confirmed bit for bit, {} wrong; \
                 input to effect: predicted {:.1} ms (largest {:.1}), confirmed {:.1} ms (largest {:.1})",
                p.rollbacks,
                p.max_depth,
                p.confirmed_right,
                p.state_wrong,
                l.predicted.mean().as_secs_f64() * 1e3,
                l.predicted.max.as_secs_f64() * 1e3,
                l.confirmed.mean().as_secs_f64() * 1e3,
                l.confirmed.max.as_secs_f64() * 1e3,
            );
        }
    }
    let summary = DemoSummary {
        report,
        bots_ok: oks.len(),
        bots_agree,
        replay_check,
    };
    print_summary(&summary, options.bots, &options.tool);
    Ok(summary)
}

fn print_summary(s: &DemoSummary, bots: usize, tool: &str) {
    println!("== summary");
    let Some(r) = &s.report else {
        println!("no match was played");
        return;
    };
    let secs = r.duration.as_secs_f64().max(1e-3);
    println!(
        "ticks played: {} in {:.1} s ({}); players: {}",
        r.ticks,
        secs,
        r.end_reason,
        r.players.len()
    );
    println!(
        "hashes: {} ticks compared, {} mismatched, {} desync notices; bots agree on every tick: {}",
        r.ticks_compared,
        r.mismatched_ticks,
        r.desyncs.len(),
        if s.bots_agree { "yes" } else { "NO" }
    );
    for p in &r.players {
        let t = p.connected_for.as_secs_f64().max(1e-3);
        println!(
            "  slot {} {:8}: down {} up {} (UDP incl. QUIC), largest datagram down {} B up {} B, \
             rtt {}, {} inputs substituted",
            p.slot.0,
            p.name,
            kb((p.udp_bytes_down as f64 / t) as u64),
            kb((p.udp_bytes_up as f64 / t) as u64),
            p.max_datagram_down,
            p.max_datagram_up,
            p.rtt.map_or_else(
                || "-".into(),
                |r| format!("{:.1} ms", r.as_secs_f64() * 1000.0)
            ),
            p.inputs_substituted
        );
    }
    println!("bots finished: {}/{bots}", s.bots_ok);
    match (&r.replay, &s.replay_check) {
        (Some(p), Some(check)) => {
            println!(
                "replay: {} ({} ticks with an agreed hash)",
                p.display(),
                r.replay_hashed_ticks
            );
            println!("replay check: {check}");
            println!("  re-check with: {tool} replay {}", p.display());
        }
        _ => println!("replay: not recorded"),
    }
}
