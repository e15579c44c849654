//! The bots program: `lockstep-bot`, or a game's `bots` command ([`App`]):
//! N headless bots in one process, each a full client that re-simulates
//! every tick and reports every tick's hash.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;

use clap::Parser;
use lockstep_client::bot::{BotOptions, run_bots};
use lockstep_client::game::{BotPolicy, GameError, GameRules, RulesFactory, RulesId};

use crate::App;

/// Headless lockstep bots with seeded scripted input.
#[derive(Parser, Debug)]
#[command(name = "lockstep-bot", version)]
pub struct BotArgs {
    /// The server's UDP address.
    #[arg(long, env = "LOCKSTEP_BOT_SERVER")]
    server: SocketAddr,
    /// PEM certificate to trust (the server's dev certificate file).
    #[arg(long, env = "LOCKSTEP_BOT_CERT")]
    cert: PathBuf,
    /// Number of bots.
    #[arg(long, default_value_t = 1, env = "LOCKSTEP_BOT_COUNT")]
    count: usize,
    /// Seed of the scripted input.
    #[arg(long, default_value_t = 1, env = "LOCKSTEP_BOT_SEED")]
    seed: u64,
    /// Leave after this many ticks (default: play until the match ends).
    #[arg(long, env = "LOCKSTEP_BOT_TICKS")]
    ticks: Option<u64>,
    /// Room to join [default: the game's room, `demo` for the demo].
    #[arg(long, env = "LOCKSTEP_BOT_ROOM")]
    room: Option<String>,
    /// Send every body's hash with every K-th tick's report (0: never), so
    /// the server's replay can name diverging bodies.
    #[arg(
        long,
        default_value_t = 0,
        value_name = "K",
        env = "LOCKSTEP_BOT_BODY_HASHES_EVERY"
    )]
    body_hashes_every: u64,
    /// A join token (`lockstep-server token`); repeat it once per bot, bot
    /// i presenting the i-th.
    #[arg(long = "token", value_name = "TOKEN", env = "LOCKSTEP_BOT_TOKENS")]
    tokens: Vec<String>,
    /// Predict and roll back: run ahead of the confirmed ticks to the
    /// last input chosen (leading the room's clock by the round trip).
    #[arg(long, env = "LOCKSTEP_BOT_PREDICT")]
    predict: bool,
    /// Serve the bots' prediction figures as Prometheus metrics on this TCP
    /// address (`GET /metrics`): rollbacks, their depth, re-simulated ticks.
    #[arg(long, value_name = "ADDR", env = "LOCKSTEP_BOT_METRICS")]
    metrics: Option<SocketAddr>,
    /// Blind bots: play the game's scripted input (a pure function of
    /// the seed, slot and tick) even when it has a bot that sees the world.
    #[arg(long, env = "LOCKSTEP_BOT_BLIND")]
    blind: bool,
    /// Light relays instead of bots: they play the protocol without
    /// simulating (their hash is a chain over the bundles), so one process
    /// drives hundreds of players for a load test.
    #[arg(long, env = "LOCKSTEP_BOT_RELAY")]
    relay: bool,
    /// With --relay: players per room (rooms ROOM-0, ROOM-1, ... fill in
    /// order).
    #[arg(long, default_value_t = 4, env = "LOCKSTEP_BOT_ROOM_SIZE")]
    room_size: usize,
}

/// `--relay`: `count` relays in rooms of `room_size`; prints one line per
/// room and a total.
async fn run_relays(cli: &BotArgs, room: &str) -> ExitCode {
    use lockstep_client::load::{relay_endpoint, run_relay};
    let cert = lockstep_client::net::TrustedCert::File(cli.cert.clone());
    let size = cli.room_size.max(1);
    let mut tasks = Vec::with_capacity(cli.count);
    let mut endpoint = None;
    for i in 0..cli.count {
        if i % 32 == 0 {
            endpoint = match relay_endpoint(&cert) {
                Ok(e) => Some(e),
                Err(e) => {
                    eprintln!("lockstep-bot: {e}");
                    return ExitCode::from(2);
                }
            };
        }
        let Some(ep) = endpoint.clone() else {
            return ExitCode::from(2);
        };
        let (server, room) = (cli.server, format!("{room}-{}", i / size));
        tasks.push(tokio::spawn(async move {
            run_relay(&ep, server, &room, &format!("relay-{i}")).await
        }));
        if i % 16 == 15 {
            tokio::time::sleep(std::time::Duration::from_millis(5)).await;
        }
    }
    let (mut ok, mut failed, mut desyncs, mut down, mut ticks) = (0, 0, 0, 0.0, 0);
    for t in tasks {
        match t.await {
            Ok(Ok(r)) => {
                ok += 1;
                desyncs += r.desyncs;
                ticks += r.ticks;
                down += r.bytes_down as f64 / r.played_for.as_secs_f64().max(1e-9);
            }
            Ok(Err(e)) => {
                failed += 1;
                println!("relay: error: {e}");
            }
            Err(e) => {
                failed += 1;
                println!("relay: {e}");
            }
        }
    }
    println!(
        "{ok} relays played {ticks} ticks in all, {failed} failed, {desyncs} desync notices, {:.0} B/s down per relay (protocol bytes)",
        down / f64::from(ok.max(1))
    );
    if failed == 0 && desyncs == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    }
}

/// The bots' prediction figures in Prometheus' text format.
pub fn render_metrics(c: &lockstep_client::net::TallyCounts) -> String {
    format!(
        "# HELP lockstep_bot_rollbacks_total Rollbacks of the bots' predicted worlds.\n\
         # TYPE lockstep_bot_rollbacks_total counter\n\
         lockstep_bot_rollbacks_total {}\n\
         # HELP lockstep_bot_rollback_depth_ticks_total Predicted ticks thrown away by rollbacks.\n\
         # TYPE lockstep_bot_rollback_depth_ticks_total counter\n\
         lockstep_bot_rollback_depth_ticks_total {}\n\
         # HELP lockstep_bot_rollback_depth_max_ticks The deepest rollback.\n\
         # TYPE lockstep_bot_rollback_depth_max_ticks gauge\n\
         lockstep_bot_rollback_depth_max_ticks {}\n\
         # HELP lockstep_bot_resimulated_ticks_total Ticks simulated again after rollbacks.\n\
         # TYPE lockstep_bot_resimulated_ticks_total counter\n\
         lockstep_bot_resimulated_ticks_total {}\n",
        c.rollbacks, c.depth_sum, c.max_depth, c.resimulated
    )
}

/// Answers `GET /metrics` (anything else: 404) until the process ends.
async fn serve_metrics(
    listener: tokio::net::TcpListener,
    tally: Arc<lockstep_client::net::PredictionTally>,
) {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    while let Ok((mut s, _)) = listener.accept().await {
        let tally = tally.clone();
        tokio::spawn(async move {
            let mut buf = [0u8; 1024];
            let n = s.read(&mut buf).await.unwrap_or(0);
            let head = String::from_utf8_lossy(&buf[..n]);
            let (status, body) = if head.starts_with("GET /metrics ") {
                ("200 OK", render_metrics(&tally.counts()))
            } else {
                ("404 Not Found", "not found\n".to_owned())
            };
            let reply = format!(
                "HTTP/1.1 {status}\r\ncontent-type: text/plain; version=0.0.4\r\ncontent-length: {}\r\nconnection: close\r\n\r\n{body}",
                body.len()
            );
            let _ = s.write_all(reply.as_bytes()).await;
        });
    }
}

/// A game whose bots play its scripted input, never its policy.
struct Blind(Arc<dyn RulesFactory>);

impl RulesFactory for Blind {
    fn rules_id(&self) -> RulesId {
        self.0.rules_id()
    }
    fn new_rules(&self, world: &lockstep_core::World) -> Result<Box<dyn GameRules>, GameError> {
        self.0.new_rules(world)
    }
    fn rules_for(&self, world: &lockstep_core::World) -> Result<Box<dyn GameRules>, GameError> {
        self.0.rules_for(world)
    }
    fn bot_input(&self, seed: u64, slot: u8, tick: u64) -> Vec<u8> {
        self.0.bot_input(seed, slot, tick)
    }
    fn bot_policy(&self, _: u64, _: u8) -> Option<Box<dyn BotPolicy>> {
        None
    }
    fn input_predictor(&self) -> Option<Box<dyn lockstep_client::net::InputPredictor>> {
        self.0.input_predictor()
    }
}

/// Runs the bots (or relays) as `cli` says, playing `app`'s game.
pub async fn run_bot_command(app: &App, cli: BotArgs) -> ExitCode {
    let room = cli.room.clone().unwrap_or_else(|| app.room.clone());
    if cli.relay {
        return run_relays(&cli, &room).await;
    }
    let game: Arc<dyn RulesFactory> = if cli.blind {
        Arc::new(Blind(app.game.clone()))
    } else {
        app.game.clone()
    };
    let mut options = BotOptions::for_game(cli.server, cli.cert, room, cli.count, game);
    options.seed = cli.seed;
    options.ticks = cli.ticks;
    options.body_hashes_every = cli.body_hashes_every;
    options.tokens = cli.tokens;
    options.predict = cli.predict;
    let predict = cli.predict;
    options.verbose = true;
    let tally = Arc::new(lockstep_client::net::PredictionTally::default());
    options.tally = Some(tally.clone());
    if let Some(addr) = cli.metrics {
        match tokio::net::TcpListener::bind(addr).await {
            Ok(listener) => {
                let local = listener.local_addr().unwrap_or(addr);
                println!("bot metrics on http://{local}/metrics");
                tokio::spawn(serve_metrics(listener, tally.clone()));
            }
            Err(e) => {
                eprintln!("lockstep-bot: metrics on {addr}: {e}");
                return ExitCode::from(2);
            }
        }
    }
    let stop = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    let results = run_bots(&options, stop).await;
    let mut failed = false;
    for (i, r) in results.iter().enumerate() {
        match r {
            Ok(rep) => println!(
                "bot-{i} slot {}: {} ticks, last hash {}, {} desync notices, {} own inputs substituted, \
                 up {} B down {} B (UDP), ended: {}",
                rep.slot.0,
                rep.ticks_applied,
                rep.hashes
                    .last()
                    .map_or_else(|| "-".into(), |h| format!("{h:016x}")),
                rep.desyncs().count(),
                rep.own_inputs_substituted,
                rep.traffic.udp_bytes_sent,
                rep.traffic.udp_bytes_received,
                rep.close.as_ref().map_or_else(
                    || "left".into(),
                    |c| format!("{:?}: {}", c.reason, c.detail)
                ),
            ),
            Err(e) => {
                failed = true;
                println!("bot-{i}: error: {e}");
            }
        }
    }
    if predict {
        for (i, rep) in results.iter().enumerate() {
            if let Ok(rep) = rep {
                println!(
                    "bot-{i} slot {}: predicting: {} rollbacks (deepest {}), {} predictions confirmed bit for bit, {} wrong; \
                     input to effect {:.1} ms predicted, {:.1} ms confirmed",
                    rep.slot.0,
                    rep.prediction.rollbacks,
                    rep.prediction.max_depth,
                    rep.prediction.confirmed_right,
                    rep.prediction.state_wrong,
                    rep.input_latency.predicted.mean().as_secs_f64() * 1e3,
                    rep.input_latency.confirmed.mean().as_secs_f64() * 1e3,
                );
            }
        }
    }
    if failed {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    }
}
