//! The server program: `lockstep-server`, or a game's `server` command
//! ([`App`]): parses flags and runs the library's server (or the demo
//! match, [`crate::demo`]); Ctrl-C or SIGTERM shuts it down gracefully.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::{Parser, Subcommand};
use lockstep_client::game::RulesFactory;
use lockstep_server::{ServerConfig, TlsSource, run};

use crate::App;
use crate::demo::{DemoOptions, run_demo};

/// The lockstep server: relays inputs, compares every tick's hashes,
/// records replays.
#[derive(Parser, Debug)]
#[command(name = "lockstep-server", version)]
pub struct ServerArgs {
    #[command(subcommand)]
    command: Option<ServerCommand>,
    /// Run the demo: the server on loopback with 4 in-process bots playing
    /// this program's game, a status line per second, a summary at the end.
    #[arg(long, env = "LOCKSTEP_DEMO")]
    demo: bool,
    /// Demo: how many seconds the match lasts (default 20, or 120 with
    /// --webtransport: time to play in the browser).
    #[arg(long, env = "LOCKSTEP_DURATION")]
    duration: Option<f64>,
    /// Demo: number of bots.
    #[arg(long, default_value_t = 4, env = "LOCKSTEP_BOTS")]
    bots: usize,
    /// Demo: seed of the bots' input.
    #[arg(long, default_value_t = 1, env = "LOCKSTEP_SEED")]
    seed: u64,
    /// Demo: the bots predict and roll back (no input delay felt; they
    /// lead the room's clock by their round trip).
    #[arg(long, env = "LOCKSTEP_PREDICT")]
    predict: bool,
    /// Demo: the last bot nudges one body by one ulp before this tick, so
    /// the match shows a desync being located to its body and field.
    #[arg(long, value_name = "TICK", env = "LOCKSTEP_DIVERGE_AT")]
    diverge_at: Option<u64>,
    /// UDP address to listen on (the demo picks a free loopback port).
    #[arg(long, default_value = "127.0.0.1:4433", env = "LOCKSTEP_LISTEN")]
    listen: SocketAddr,
    /// Also serve WebTransport (HTTP/3, for browsers) on this UDP address
    /// (e.g. 127.0.0.1:4434): sessions on the path /lockstep join the same
    /// rooms. Its certificate is --cert's, or without one a generated
    /// ECDSA certificate valid 13 days whose SHA-256 is logged (browsers
    /// take it through serverCertificateHashes).
    #[arg(long, value_name = "ADDR", env = "LOCKSTEP_WEBTRANSPORT")]
    webtransport: Option<SocketAddr>,
    /// Demo with --webtransport: where the browser client's page is served
    /// (HTTP; the demo prints its URL and waits for a player in a browser).
    #[arg(
        long,
        value_name = "ADDR",
        default_value = "127.0.0.1:8047",
        env = "LOCKSTEP_WEB_LISTEN"
    )]
    web_listen: SocketAddr,
    /// Demo with --webtransport: the browser module to serve, built
    /// beforehand (default: built with cargo at start).
    #[arg(long, value_name = "FILE", env = "LOCKSTEP_WEB_MODULE")]
    web_module: Option<PathBuf>,
    /// Certificate chain (PEM) of a real certificate; needs --key.
    #[arg(long, requires = "key", env = "LOCKSTEP_CERT")]
    cert: Option<PathBuf>,
    /// Private key (PEM) of --cert.
    #[arg(long, requires = "cert", env = "LOCKSTEP_KEY")]
    key: Option<PathBuf>,
    /// Where the generated dev certificate is written (without --cert).
    #[arg(long, default_value = "out/dev-cert.pem", env = "LOCKSTEP_CERT_OUT")]
    cert_out: PathBuf,
    /// Scene file sent to the players (default: the game's embedded
    /// scene). Without --rules-id the game's rules must accept it.
    #[arg(long, env = "LOCKSTEP_SCENE")]
    scene: Option<PathBuf>,
    /// Id of the game rules the players run, announced in the welcome and
    /// recorded in every replay (default: this program's game; give another
    /// game's with its --scene to relay a game this program does not have,
    /// without --verify or --view: such a server does not verify).
    #[arg(long, requires = "rules_version", env = "LOCKSTEP_RULES_ID")]
    rules_id: Option<String>,
    /// Version of those rules.
    #[arg(long, requires = "rules_id", env = "LOCKSTEP_RULES_VERSION")]
    rules_version: Option<u32>,
    /// Directory for replay files.
    #[arg(long, default_value = "out/replays", env = "LOCKSTEP_REPLAY_DIR")]
    replay_dir: PathBuf,
    /// Do not record replays.
    #[arg(long, env = "LOCKSTEP_NO_REPLAY")]
    no_replay: bool,
    /// Seats per room.
    #[arg(long, default_value_t = 8, env = "LOCKSTEP_MAX_PLAYERS")]
    max_players: u8,
    /// Players needed to start a match.
    #[arg(long, default_value_t = 2, env = "LOCKSTEP_START_PLAYERS")]
    start_players: u8,
    /// Ticks per second.
    #[arg(long, default_value_t = 60, env = "LOCKSTEP_TICK_RATE")]
    tick_rate: u16,
    /// Input delay in ticks.
    #[arg(long, default_value_t = 4, env = "LOCKSTEP_INPUT_DELAY")]
    input_delay: u16,
    /// End each match after this many ticks.
    #[arg(long, env = "LOCKSTEP_MATCH_TICKS")]
    match_ticks: Option<u64>,
    /// Seconds a lobby waits after its first join; then players without
    /// their first input are dropped and the ready ones start (0: wait for
    /// ever).
    #[arg(long, default_value_t = 30.0, env = "LOCKSTEP_LOBBY_TIMEOUT")]
    lobby_timeout: f64,
    /// Most rooms open at once; a join for a new room beyond it is refused.
    #[arg(long, default_value_t = 16, env = "LOCKSTEP_MAX_ROOMS")]
    max_rooms: usize,
    /// Most connections at once; beyond it a connection is refused with
    /// QUIC code 5 (overloaded) and the reason.
    #[arg(long, default_value_t = 256, env = "LOCKSTEP_MAX_CONNECTIONS")]
    max_connections: usize,
    /// Most connections at once from one IP address (handshaking, waiting
    /// to join or playing); beyond it a connection is refused with QUIC
    /// code 5 and the reason. Raise it for load tests from one host.
    #[arg(
        long,
        default_value_t = 16,
        env = "LOCKSTEP_MAX_CONNECTIONS_PER_ADDRESS"
    )]
    max_connections_per_address: usize,
    /// Messages a second each connection may send; past it datagrams are
    /// dropped (counted and logged) and stream frames wait.
    #[arg(long, default_value_t = 1000, env = "LOCKSTEP_MAX_MESSAGES_PER_SECOND")]
    max_messages_per_second: u32,
    /// File holding the secret join tokens are signed with: its bytes
    /// without trailing whitespace (a final newline is not part of it), at
    /// least 16. With it, a join that carries a token is seated only if the
    /// token verifies, and in its seat.
    #[arg(long, value_name = "FILE", env = "LOCKSTEP_TOKEN_SECRET_FILE")]
    token_secret_file: Option<PathBuf>,
    /// Refuse every join without a valid token (needs --token-secret-file).
    #[arg(long, requires = "token_secret_file", env = "LOCKSTEP_REQUIRE_TOKENS")]
    require_tokens: bool,
    /// Re-simulate every match on the server with the game's rules and
    /// judge every hash report against the server's own hash, so a
    /// majority of liars cannot outvote honest players (costs one
    /// simulation per room). The default whenever the match is played with
    /// this program's rules; the flag is kept for scripts that pass it.
    #[arg(long, env = "LOCKSTEP_VERIFY", conflicts_with = "no_verify")]
    verify: bool,
    /// Do not re-simulate: relay and compare only. Nobody is then dropped
    /// for its hash (mismatches are announced as undecided) unless --vote,
    /// and the replay records only hashes every reporter agreed on.
    #[arg(long, env = "LOCKSTEP_NO_VERIFY")]
    no_verify: bool,
    /// Without verifying: the players seated with a join token vote, and a
    /// player whose hash stays outside their strict majority is dropped as
    /// diverged (needs --token-secret-file, and --no-verify when the
    /// program has the match's rules: a relay of another game's rules
    /// never verifies).
    #[arg(long, env = "LOCKSTEP_VOTE", requires = "token_secret_file")]
    vote: bool,
    /// Let players join a running match: they start from the last agreed
    /// state, fetched from a player in agreement and checked by its hash.
    #[arg(long, env = "LOCKSTEP_LATE_JOIN")]
    late_join: bool,
    /// Every match's seed, the game rules' random source (default: a fresh
    /// random seed per room; it is announced in the welcome and recorded
    /// in the replay either way).
    #[arg(long, value_name = "SEED", env = "LOCKSTEP_MATCH_SEED")]
    match_seed: Option<u64>,
    /// Seconds a dropped token holder's seat stays reserved for its rejoin
    /// (with the rejoin credential its welcome gave).
    #[arg(long, default_value_t = 30.0, env = "LOCKSTEP_REJOIN_GRACE")]
    rejoin_grace: f64,
    /// Serve Prometheus metrics, /healthz and /readyz over HTTP on this TCP
    /// address (e.g. 0.0.0.0:9100 in a container).
    #[arg(long, value_name = "ADDR", env = "LOCKSTEP_METRICS")]
    metrics: Option<SocketAddr>,
    /// Serve the live rooms to the browser viewer on this TCP address (e.g.
    /// 127.0.0.1:8080; open it in a browser). A room is re-simulated on the
    /// server with the game's rules only while someone watches; viewers
    /// only read and cannot send input.
    #[arg(long, value_name = "ADDR", env = "LOCKSTEP_VIEW")]
    view: Option<SocketAddr>,
    /// Exit (status 0) once the first match has ended and its replay is
    /// flushed: one match per process.
    #[arg(long, env = "LOCKSTEP_EXIT_AFTER_MATCH")]
    exit_after_match: bool,
    /// Run the tick clock and the rooms at real-time priority (SCHED_FIFO,
    /// Linux), so a tick that is due is not queued behind the connection
    /// threads on a busy machine. Needs CAP_SYS_NICE or an rtprio limit of
    /// at least 10 (docs/deploy.md); without either the server warns and
    /// runs at normal priority.
    #[arg(long, env = "LOCKSTEP_REALTIME_CLOCK")]
    realtime_clock: bool,
    /// Run as an Agones game server: Ready once listening, health pings
    /// while the tick clocks keep time, joins only after allocation (for
    /// the room and with the token secret its lockstep.dev/room and
    /// lockstep.dev/token-secret annotations give), Shutdown and exit after
    /// the match. The SDK address comes from AGONES_SDK_GRPC_HOST and
    /// AGONES_SDK_GRPC_PORT (default localhost:9357).
    #[arg(long, env = "LOCKSTEP_AGONES", conflicts_with = "demo")]
    agones: bool,
    /// Seconds between two Agones health pings (keep it under the
    /// fleet's health.periodSeconds).
    #[arg(long, default_value_t = 2.0, env = "LOCKSTEP_AGONES_HEALTH_PERIOD")]
    agones_health_period: f64,
}

/// The server program's subcommands.
#[derive(Subcommand, Debug)]
pub enum ServerCommand {
    /// Print a join token for a seat of a room (what a matchmaker hands a
    /// player), signed with the server's secret.
    Token {
        /// File holding the server's secret (trailing whitespace is not
        /// part of it).
        #[arg(long, value_name = "FILE")]
        secret_file: PathBuf,
        /// The room.
        #[arg(long)]
        room: String,
        /// The seat (slot); without it, any free seat.
        #[arg(long)]
        seat: Option<u8>,
        /// Who it is for (in the server's logs).
        #[arg(long)]
        player: String,
        /// Seconds it stays valid for joining (a player seated with it
        /// comes back with the rejoin credential of its welcome, which
        /// lasts the match, so the token need not outlive the first join).
        #[arg(long, default_value_t = 600)]
        ttl_seconds: u64,
    },
}

/// The token secret in the file at `path`: its bytes without trailing
/// whitespace (the newline an editor or `echo` adds is not part of it).
pub(crate) fn read_secret(path: &std::path::Path) -> Result<Vec<u8>, String> {
    let mut secret = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    while secret.last().is_some_and(u8::is_ascii_whitespace) {
        secret.pop();
    }
    Ok(secret)
}

pub(crate) async fn terminate() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = tokio::signal::ctrl_c() => {}
                    _ = term.recv() => {}
                }
            }
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}

/// Logs to stderr through `tracing`: `RUST_LOG` filters (default `info`),
/// spans (a room, a connection) prefix their events.
pub(crate) fn init_logging() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
}

/// Whether `game`'s rules accept the world `scene` builds.
fn check_scene(game: &dyn RulesFactory, scene: &str, name: &str) -> Result<(), String> {
    let world = lockstep_core::scene::load_world(scene, name).map_err(|e| e.to_string())?;
    game.new_rules(&world)
        .map(|_| ())
        .map_err(|e| format!("{name}: the rules of {} refuse it: {e}", game.rules_id()))
}

/// The server configuration `cli` describes for `app`'s game (without
/// the demo's own settings).
///
/// # Errors
/// What is wrong with the flags or the files they name, as a sentence.
pub(crate) fn build_config(app: &App, cli: &ServerArgs) -> Result<ServerConfig, String> {
    let listen = if cli.demo {
        SocketAddr::from(([127, 0, 0, 1], 0))
    } else {
        cli.listen
    };
    let mut config = ServerConfig::for_game(
        listen,
        app.scene.clone(),
        app.scene_name.clone(),
        app.game.rules_id(),
    );
    config.webtransport = cli.webtransport;
    config.tls = match (cli.cert.clone(), cli.key.clone()) {
        (Some(cert), Some(key)) => TlsSource::Files { cert, key },
        _ => TlsSource::dev(cli.cert_out.clone()),
    };
    if let Some(path) = &cli.scene {
        match std::fs::read_to_string(path) {
            Ok(text) => {
                config.scene = text;
                config.scene_name = path.display().to_string();
            }
            Err(e) => return Err(format!("{}: {e}", path.display())),
        }
    }
    if let (Some(id), Some(version)) = (cli.rules_id.clone(), cli.rules_version) {
        config.rules = lockstep_server::RulesId::new(id, version);
    }
    let ours = app.game.rules_id();
    if config.rules == ours {
        // The rules this program has: they must accept the scene, or the
        // players' would refuse it at their first tick.
        if let Err(e) = check_scene(&*app.game, &config.scene, &config.scene_name) {
            return Err(format!(
                "{e}\n  the match would be announced and recorded as {ours}: give \
                 --rules-id and --rules-version of the game this scene is for, or run that game's \
                 own server (docs/own-game.md)"
            ));
        }
    } else if cli.verify || cli.view.is_some() {
        return Err(format!(
            "--verify and --view re-simulate with this program's rules ({ours}), \
             and the match is played with {}: run the game's own server (a lockstep::App of its \
             rules, docs/own-game.md), or drop --verify and --view to relay it",
            config.rules
        ));
    }
    config.replay_dir = (!cli.no_replay).then(|| cli.replay_dir.clone());
    config.room.max_players = cli.max_players;
    config.room.start_players = cli.start_players;
    config.room.tick_rate = cli.tick_rate;
    config.room.input_delay = cli.input_delay;
    config.room.match_ticks = cli.match_ticks;
    config.room.lobby_timeout =
        (cli.lobby_timeout > 0.0).then(|| Duration::from_secs_f64(cli.lobby_timeout.min(86_400.0)));
    config.max_rooms = cli.max_rooms.max(1);
    config.max_connections = cli.max_connections.max(1);
    // The demo's own bots all come from loopback.
    config.max_connections_per_address =
        (!cli.demo).then_some(cli.max_connections_per_address.max(1));
    config.room.max_messages_per_second = cli.max_messages_per_second.max(1);
    if let Some(path) = &cli.token_secret_file {
        config.token_secret = Some(read_secret(path)?);
    }
    config.require_tokens = cli.require_tokens;
    config.room.late_join = cli.late_join;
    config.room.seed = cli.match_seed;
    config.metrics = cli.metrics;
    config.view = cli.view.map(|listen| lockstep_server::ViewSettings {
        listen,
        sim: std::sync::Arc::new(lockstep_client::game::RulesVerifier {
            game: app.game.clone(),
        }),
    });
    config.exit_after_match = cli.exit_after_match;
    config.realtime_clock = cli.realtime_clock;
    if cli.agones {
        let mut a = lockstep_server::agones::AgonesSettings::from_env();
        a.health_period = Duration::from_secs_f64(cli.agones_health_period.clamp(0.1, 3600.0));
        config.agones = Some(a);
    }
    config.room.rejoin_grace = Duration::from_secs_f64(cli.rejoin_grace.clamp(0.0, 86_400.0));
    // Verifying is the default whenever this program has the match's
    // rules: a relay of another game's rules cannot re-simulate.
    if config.rules == ours && !cli.no_verify {
        config.verifier = Some(std::sync::Arc::new(lockstep_client::game::RulesVerifier {
            game: app.game.clone(),
        }));
    } else {
        tracing::warn!(
            "not verifying ({}): {}",
            if cli.no_verify {
                "--no-verify".to_owned()
            } else {
                format!("the match is played with {}", config.rules)
            },
            if cli.vote {
                "the token holders' majority judges hashes"
            } else {
                "nobody is dropped for its hash; mismatches are only announced"
            }
        );
    }
    if cli.vote && config.verifier.is_some() {
        return Err(format!(
            "--vote lets token holders judge hashes, and this server verifies them itself \
             (it has the match's rules, {ours}): add --no-verify to vote instead"
        ));
    }
    config.vote = cli.vote;
    Ok(config)
}

/// Runs the server (or the demo match) as `cli` says, with `app`'s game.
pub async fn run_server(app: &App, cli: ServerArgs) -> ExitCode {
    if let Some(ServerCommand::Token {
        secret_file,
        room,
        seat,
        player,
        ttl_seconds,
    }) = &cli.command
    {
        let token = read_secret(secret_file).and_then(|secret| {
            lockstep_server::issue_token(
                &secret,
                room,
                *seat,
                player,
                Duration::from_secs(*ttl_seconds),
                std::time::SystemTime::now(),
            )
            .map_err(|e| e.to_string())
        });
        return match token {
            Ok(t) => {
                println!("{t}");
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("lockstep-server token: {e}");
                ExitCode::from(2)
            }
        };
    }
    let config = match build_config(app, &cli) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("lockstep-server: {e}");
            return ExitCode::from(2);
        }
    };
    if cli.demo {
        let mut options = DemoOptions::new();
        options.game = app.game.clone();
        options.room = app.room.clone();
        options.tool = app.tool.clone();
        options.predict = cli.predict;
        options.server = config;
        options.bots = cli.bots;
        options.seed = cli.seed;
        options.diverge_at = cli.diverge_at;
        let duration = cli.duration.unwrap_or(if cli.webtransport.is_some() {
            120.0
        } else {
            20.0
        });
        options.duration = Duration::from_secs_f64(duration.clamp(0.1, 86_400.0));
        let module = match &cli.web_module {
            Some(file) => Some(crate::web::ModuleSource::File(file.clone())),
            None => app.web_module.clone(),
        };
        options.web = module.map(|module| crate::web::WebDemo {
            listen: cli.web_listen,
            module,
            players: 1,
        });
        return match run_demo(options, terminate()).await {
            Ok(s) => {
                let ok = s.report.as_ref().is_some_and(|r| r.desyncs.is_empty())
                    && s.bots_agree
                    && s.replay_check
                        .as_deref()
                        .is_none_or(|c| c.starts_with("OK"));
                if ok {
                    ExitCode::SUCCESS
                } else {
                    ExitCode::from(1)
                }
            }
            Err(e) => {
                eprintln!("lockstep-server: {e}");
                ExitCode::from(2)
            }
        };
    }
    match run(config, terminate()).await {
        Ok(_) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("lockstep-server: {e}");
            ExitCode::from(2)
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_secret_file_s_trailing_newline_is_not_part_of_the_secret() {
        let dir = std::env::temp_dir().join(format!("lockstep-secret-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("secret");
        std::fs::write(&path, b"sixteen bytes at least\r\n").unwrap();
        assert_eq!(
            super::read_secret(&path).unwrap(),
            b"sixteen bytes at least".to_vec()
        );
        std::fs::write(&path, b" keep leading, inner  spaces \n\n").unwrap();
        assert_eq!(
            super::read_secret(&path).unwrap(),
            b" keep leading, inner  spaces".to_vec()
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// `--webtransport ADDR` sets the WebTransport endpoint's address (none
    /// by default), and an address that does not parse is refused naming
    /// the flag.
    #[test]
    fn webtransport_takes_an_address() {
        let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/demo.toml");
        let app = crate::App::demo();
        let config = |extra: &[&str]| {
            let args = ["lockstep-server", "--scene", scene]
                .into_iter()
                .chain(extra.iter().copied());
            app.server_config(args)
        };
        assert_eq!(config(&[]).unwrap().webtransport, None);
        let c = config(&["--webtransport", "127.0.0.1:4434"]).unwrap();
        assert_eq!(c.webtransport, Some("127.0.0.1:4434".parse().unwrap()));
        let c = config(&["--webtransport", "[::1]:0"]).unwrap();
        assert_eq!(c.webtransport, Some("[::1]:0".parse().unwrap()));
        let e = config(&["--webtransport", "localhost"]).unwrap_err();
        assert!(e.contains("--webtransport <ADDR>"), "{e}");
    }

    /// `--vote` needs `--no-verify` only where the server would verify: a
    /// server relaying another game's rules never verifies, so it votes
    /// with `--vote` alone.
    #[test]
    fn vote_needs_no_verify_only_where_the_server_verifies() {
        let dir = std::env::temp_dir().join(format!("lockstep-vote-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let secret = dir.join("secret");
        std::fs::write(&secret, b"a vote test secret of 16+ bytes\n").unwrap();
        let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/demo.toml");
        let app = crate::App::demo();
        let config = |extra: &[&str]| {
            let args = ["lockstep-server", "--scene", scene, "--token-secret-file"]
                .into_iter()
                .chain([secret.to_str().unwrap()])
                .chain(extra.iter().copied());
            app.server_config(args)
        };
        let e = config(&["--vote"]).expect_err("a verifying server does not vote");
        assert!(e.contains("add --no-verify to vote instead"), "{e}");
        let c = config(&["--vote", "--no-verify"]).expect("votes");
        assert!(c.vote && c.verifier.is_none());
        let c = config(&[
            "--vote",
            "--rules-id",
            "another-game",
            "--rules-version",
            "2",
        ])
        .expect("a relay of another game's rules votes with --vote alone");
        assert!(c.vote && c.verifier.is_none());
        assert!(config(&["--no-verify"]).is_ok_and(|c| !c.vote));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
