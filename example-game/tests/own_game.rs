//! The example game shipped whole: its state survives a late join and a
//! rejoin (every hash agrees), its own binary runs the server with
//! `--verify` and `--view`, its bots with the world-aware policy, and its
//! `replay` reproduces a desync bundle; its sync test passes.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use std::time::Duration;

use lockstep_client::bot::{BotOptions, run_bots};
use lockstep_client::game::{BotPolicy, RulesFactory, RulesVerifier};
use lockstep_client::net::{Client, ClientReport};
use lockstep_example_game::{
    ChaseBot, LAST_DROP_FIELD, PaddleGame, PaddleInput, PaddleRules, SCENE,
};
use lockstep_proto::{Replay, Slot};
use lockstep_server::{RoomReport, ServerConfig, ServerEvent, TlsSource, run};
use lockstep_tools::verify_replay_file;
use tokio::sync::{mpsc, oneshot};

const BIN: &str = env!("CARGO_BIN_EXE_example-game");

fn tmp(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The example game's server in-process (verifying with its rules).
struct Server {
    addr: SocketAddr,
    cert: PathBuf,
    events: mpsc::UnboundedReceiver<ServerEvent>,
    stop: Option<oneshot::Sender<()>>,
    task: tokio::task::JoinHandle<
        Result<lockstep_server::ServerReport, lockstep_server::ServerError>,
    >,
}

impl Server {
    async fn start(dir: &Path, tweak: impl FnOnce(&mut ServerConfig)) -> Server {
        let mut config = ServerConfig::for_game(
            SocketAddr::from(([127, 0, 0, 1], 0)),
            SCENE,
            "example-game/scene.toml",
            PaddleGame.rules_id(),
        );
        config.tls = TlsSource::dev(dir.join("cert.pem"));
        config.replay_dir = Some(dir.join("replays"));
        config.verifier = Some(Arc::new(RulesVerifier {
            game: Arc::new(PaddleGame),
        }));
        tweak(&mut config);
        let (tx, mut events) = mpsc::unbounded_channel();
        config.events = Some(tx);
        let (stop, stop_rx) = oneshot::channel::<()>();
        let task = tokio::spawn(run(config, async {
            let _ = stop_rx.await;
        }));
        let (addr, cert) = loop {
            match events.recv().await.expect("server stopped at start-up") {
                ServerEvent::Listening { addr, cert } => break (addr, cert.expect("dev cert")),
                _ => continue,
            }
        };
        Server {
            addr,
            cert,
            events,
            stop: Some(stop),
            task,
        }
    }

    async fn until<T>(&mut self, mut f: impl FnMut(&ServerEvent) -> Option<T>) -> T {
        tokio::time::timeout(Duration::from_secs(30), async {
            loop {
                let e = self.events.recv().await.expect("server events");
                if let Some(t) = f(&e) {
                    return t;
                }
            }
        })
        .await
        .expect("server event in time")
    }

    async fn ended(mut self) -> RoomReport {
        let r = self
            .until(|e| match e {
                ServerEvent::MatchEnded(r) => Some(r.clone()),
                _ => None,
            })
            .await;
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        self.task.await.expect("server task").expect("server");
        r
    }
}

/// Connects a player, checks what it starts from with `check`, then plays
/// with the chase bot to the end of the match.
async fn join_and_play(
    options: lockstep_client::net::ClientOptions,
    check: impl FnOnce(&Client),
) -> ClientReport {
    let client = Client::connect(options, &PaddleGame)
        .await
        .expect("connect");
    check(&client);
    let mut bot = ChaseBot::new(client.slot().0);
    client
        .play_seeing(move |v| bot.input(v), |_| {}, std::future::pending())
        .await
        .expect("plays")
}

fn assert_agree(late: &ClientReport, reference: &ClientReport) {
    assert!(late.first_applied > 30, "{}", late.first_applied);
    for (i, h) in late.hashes.iter().enumerate() {
        let t = late.first_applied as usize + i;
        assert_eq!(*h, reference.hashes[t], "tick {t}");
    }
    assert_eq!(late.desyncs().count(), 0);
}

/// What a player joining mid-match starts from: a round already under way
/// (drops made, so cooldowns running) in the world's game state and in
/// the rules made for it.
fn started_mid_round(client: &Client) {
    let drops = client
        .world()
        .game_state()
        .words(LAST_DROP_FIELD)
        .expect("the last drops are game state")
        .to_vec();
    assert!(drops.iter().any(|&d| d > 0), "{drops:?}");
    let rules = client
        .rules()
        .downcast_ref::<PaddleRules>()
        .expect("the example game's rules");
    let dropped = (0..4).filter(|&s| rules.last_drop(s).is_some()).count();
    assert_eq!(dropped, drops.iter().filter(|&&d| d > 0).count());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_late_joiner_mid_round_agrees_on_every_hash() {
    let dir = tmp("own-game-late");
    let server = Server::start(&dir, |c| {
        c.room.start_players = 2;
        c.room.match_ticks = Some(360);
        c.room.late_join = true;
    })
    .await;
    let mut options = BotOptions::for_game(
        server.addr,
        server.cert.clone(),
        "table",
        2,
        Arc::new(PaddleGame),
    );
    options.body_hashes_every = 30;
    let early_options = options.clone();
    let early = tokio::spawn(async move { run_bots(&early_options, std::future::pending()).await });
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let mut late_options = options.client_options(2);
    late_options.player_name = "late".into();
    let late = join_and_play(late_options, started_mid_round).await;
    let early: Vec<ClientReport> = early
        .await
        .unwrap()
        .into_iter()
        .map(|r| r.expect("bot"))
        .collect();
    let ended = server.ended().await;
    assert_eq!(early[0].hashes, early[1].hashes);
    assert_agree(&late, &early[0]);
    assert!(ended.desyncs.is_empty(), "{:?}", ended.desyncs);
    assert_eq!(ended.mismatched_ticks, 0);
    assert_eq!(ended.verified.map(|v| v.0), Some(360));
    let check = verify_replay_file(ended.replay.as_ref().unwrap(), &PaddleGame).expect("replay");
    assert_eq!((check.ticks, check.checked, check.players), (360, 360, 3));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_killed_player_rejoins_its_seat_mid_round_and_agrees() {
    let secret = b"own game rejoin secret, 16+ bytes".to_vec();
    let dir = tmp("own-game-rejoin");
    let key = secret.clone();
    let server = Server::start(&dir, move |c| {
        c.room.start_players = 3;
        c.room.match_ticks = Some(420);
        c.token_secret = Some(key);
    })
    .await;
    let now = std::time::SystemTime::now();
    let mut options = BotOptions::for_game(
        server.addr,
        server.cert.clone(),
        "table",
        3,
        Arc::new(PaddleGame),
    );
    options.tokens = (0..3u8)
        .map(|s| {
            lockstep_server::issue_token(
                &secret,
                "table",
                Some(s),
                &format!("p{s}"),
                Duration::from_secs(600),
                now,
            )
            .unwrap()
        })
        .collect();
    // Player 1's options keep the rejoin credential its welcome gives
    // (clones share it): its token seats it once, the credential again.
    let owner = options.client_options(1);
    let mut tasks = Vec::new();
    for i in 0..3 {
        let o = if i == 1 {
            owner.clone()
        } else {
            options.client_options(i)
        };
        tasks.push(tokio::spawn(join_and_play(o, |_| {})));
        tokio::time::sleep(Duration::from_millis(30)).await;
    }
    tokio::time::sleep(Duration::from_millis(2000)).await;
    tasks[1].abort();
    let _ = (&mut tasks[1]).await;
    tokio::time::sleep(Duration::from_millis(300)).await;
    let again = join_and_play(owner, |c| {
        assert_eq!(c.slot(), Slot(1));
        started_mid_round(c);
    })
    .await;
    let mut others = Vec::new();
    for (i, t) in tasks.into_iter().enumerate() {
        if i != 1 {
            others.push(t.await.unwrap());
        }
    }
    let ended = server.ended().await;
    assert_eq!(others[0].hashes, others[1].hashes);
    assert_agree(&again, &others[0]);
    assert!(ended.desyncs.is_empty(), "{:?}", ended.desyncs);
    assert_eq!(ended.mismatched_ticks, 0);
    let check = verify_replay_file(ended.replay.as_ref().unwrap(), &PaddleGame).expect("replay");
    assert_eq!((check.ticks, check.checked), (420, 420));
}

/// A client with other rules refuses to play, and says whose.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_of_another_game_refuses_to_join() {
    let dir = tmp("own-game-other");
    let server = Server::start(&dir, |c| c.room.start_players = 2).await;
    let options =
        lockstep_client::net::ClientOptions::new(server.addr, server.cert.clone(), "table", "demo");
    let Err(err) = Client::connect(options, &lockstep_client::game::Demo).await else {
        panic!("a client of another game joined");
    };
    assert!(
        matches!(&err, lockstep_client::net::ClientError::WrongRules { server, .. } if *server == PaddleGame.rules_id()),
        "{err}"
    );
    assert!(
        err.to_string()
            .starts_with("the server plays example-paddles v2, this client lockstep-demo v3"),
        "{err}"
    );
}

#[test]
fn the_kit_sync_test_passes() {
    let r = lockstep_testkit::assert_sync(SCENE, "example-game/scene.toml", &PaddleGame);
    assert_eq!(r.ticks, 600);
}

fn run_bin(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(BIN)
        .args(args)
        .output()
        .expect("run example-game");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The binary's own match: `server --demo --verify --view` with a bot that
/// desyncs on purpose; then `replay` on the bundle it wrote reproduces the
/// desync, and on a whole replay says OK.
#[test]
fn its_binary_serves_verifies_views_and_reproduces_a_bundle() {
    let dir = tmp("own-game-bin");
    let d = |p: &str| dir.join(p).display().to_string();
    let (cert, replays) = (d("cert.pem"), d("replays"));
    let (code, out, err) = run_bin(&[
        "server",
        "--demo",
        "--duration",
        "3",
        "--bots",
        "3",
        "--verify",
        "--view",
        "127.0.0.1:0",
        "--diverge-at",
        "90",
        "--cert-out",
        &cert,
        "--replay-dir",
        &replays,
    ]);
    // The nudged bot desyncs: the demo exits 1, and says where.
    assert_eq!(code, 1, "{out}\n{err}");
    assert!(out.contains("desync located at tick 90"), "{out}");
    assert!(out.contains("inputs of tick 90: slot 0 ["), "{out}");
    let bundle = out
        .lines()
        .find_map(|l| l.strip_prefix("demo: desync bundle "))
        .and_then(|l| l.split(" (check it: example-game replay").next())
        .expect("a bundle")
        .to_owned();
    let (code, out, err) = run_bin(&["replay", &bundle]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.starts_with("BUNDLE REPRODUCED"), "{out}");
    let replay = std::fs::read_dir(&replays)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| {
            p.extension().is_some_and(|e| e == "replay")
                && Replay::parse(&std::fs::read(p).unwrap()).is_ok_and(|r| r.end.is_some())
        })
        .expect("the match's replay");
    let (code, out, err) = run_bin(&["replay", replay.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.starts_with("OK"), "{out}");
    // The sync test from the binary.
    let (code, out, err) = run_bin(&["synctest", "--ticks", "120"]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.starts_with("OK: example-paddles v2"), "{out}");
}

/// `example-game bots --predict --metrics` against a server: the chase
/// bots play (a drop at their first tick and then one every cooldown,
/// which the blind script never does) on their predicted worlds, every
/// hash agrees, and the metrics answer while they play.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn its_bots_play_with_the_world_aware_policy() {
    let dir = tmp("own-game-bots");
    let server = Server::start(&dir, |c| {
        c.room.start_players = 2;
        c.room.match_ticks = Some(150);
    })
    .await;
    let addr = server.addr.to_string();
    let cert = server.cert.display().to_string();
    let out = tokio::task::spawn_blocking(move || {
        use std::io::{BufRead, Read, Write};
        let mut child = Command::new(BIN)
            .args(["bots", "--server", &addr, "--cert", &cert, "--count", "2"])
            .args(["--predict", "--metrics", "127.0.0.1:0"])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("run example-game bots");
        let mut stdout = std::io::BufReader::new(child.stdout.take().unwrap());
        let mut first = String::new();
        stdout.read_line(&mut first).unwrap();
        // The metrics, scraped while the bots play.
        let host = first
            .trim()
            .strip_prefix("bot metrics on http://")
            .and_then(|u| u.strip_suffix("/metrics"))
            .unwrap_or_else(|| panic!("{first}"))
            .to_owned();
        std::thread::sleep(Duration::from_millis(1500));
        let mut conn = std::net::TcpStream::connect(&host).unwrap();
        conn.write_all(b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n")
            .unwrap();
        let mut metrics = String::new();
        conn.read_to_string(&mut metrics).unwrap();
        let mut rest = String::new();
        stdout.read_to_string(&mut rest).unwrap();
        let mut err = String::new();
        child
            .stderr
            .take()
            .unwrap()
            .read_to_string(&mut err)
            .unwrap();
        let code = child.wait().unwrap().code().unwrap_or(-1);
        (code, first + &rest, err, metrics)
    })
    .await
    .unwrap();
    let (code, stdout, stderr, metrics) = out;
    assert_eq!(code, 0, "{stdout}\n{stderr}");
    assert!(stdout.contains("bot-0 slot 0: 150 ticks"), "{stdout}");
    // They predicted, and every prediction the server confirmed was right.
    assert!(stdout.contains("bot-0 slot 0: predicting: "), "{stdout}");
    assert!(stdout.contains(", 0 wrong;"), "{stdout}");
    assert!(metrics.starts_with("HTTP/1.1 200 OK"), "{metrics}");
    assert!(
        metrics.contains("lockstep_bot_rollbacks_total "),
        "{metrics}"
    );
    let ended = server.ended().await;
    assert!(ended.desyncs.is_empty(), "{:?}", ended.desyncs);
    assert_eq!(ended.mismatched_ticks, 0);
    let replay = Replay::parse(&std::fs::read(ended.replay.unwrap()).unwrap()).unwrap();
    for slot in 0..2u8 {
        let drops: Vec<u64> = replay
            .ticks
            .iter()
            .filter(|b| {
                // A late input is substituted by the player's last one (a
                // press repeated): only the inputs that came count.
                b.inputs.iter().any(|p| {
                    p.slot.0 == slot
                        && !p.substituted
                        && PaddleInput::decode(&p.input).is_some_and(|i| i.drop)
                })
            })
            .map(|b| b.tick)
            .collect();
        // Pressed whenever ready: every 30 ticks from its first tick on
        // (five in 150 ticks, one spared for a press that came late).
        assert!(drops.len() >= 4, "slot {slot}: {drops:?}");
        assert!(drops.windows(2).all(|w| w[1] - w[0] >= 30), "{drops:?}");
    }
}
