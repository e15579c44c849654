//! # lockstep-server
//!
//! The lockstep server: tokio + quinn around `lockstep_proto::Room`, the way
//! `quinn` wraps `quinn-proto`. It relays inputs and compares hashes; it
//! never simulates.
//!
//! - [`run`] is the whole server as a library function: it listens, accepts
//!   connections, seats players in rooms (created on the first join of a
//!   name), drives each room's tick clock, records every match as a replay,
//!   and on `shutdown` finishes the current tick, closes every connection
//!   with a reason, flushes the replays and waits for its tasks.
//! - Each connection has a task that reads its stream frames and datagrams
//!   and forwards decoded messages to its room (`conn`); each room has a task
//!   that owns the [`Room`](lockstep_proto::Room) state machine and all
//!   sending (`room`).
//! - The game is a parameter ([`ServerConfig::for_game`]: its scene and its
//!   rules' id); the server never runs the rules. The `lockstep-server`
//!   program and its `--demo` (the server with the demo game and
//!   in-process bots) are in the `lockstep` package (`cli/`).
//!
//! Nothing a client sends can disturb a room beyond that client: malformed
//! or oversized frames and datagrams, messages on the wrong channel, and
//! everything the room rejects (another slot's inputs, ticks outside the
//! window, conflicting hashes) close that client with a logged reason.

#![warn(missing_docs)]

pub mod agones;
mod clock;
mod conn;
pub mod log;
pub mod metrics;
mod room;
pub mod spectate;
mod tls;

use std::collections::HashMap;
use std::future::Future;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub use lockstep_proto::RulesId;
use lockstep_proto::{DesyncNotice, Slot};
use thiserror::Error;
use tokio::sync::{Semaphore, mpsc, watch};
use tokio::task::JoinSet;

pub use tls::TlsSource;

/// Settings of every room the server opens.
#[derive(Clone, Debug)]
pub struct RoomSettings {
    /// Seats per room (at most 16).
    pub max_players: u8,
    /// The match starts once this many players are seated and each has
    /// sent its first input.
    pub start_players: u8,
    /// Ticks per second.
    pub tick_rate: u16,
    /// Ticks between an input's sampling and the tick it applies to; inputs
    /// arrive on time while the round trip stays under `input_delay + 1`
    /// ticks.
    pub input_delay: u16,
    /// A player heard from for this long is dropped; the room goes on.
    pub silence_timeout: Duration,
    /// End the match after this many ticks (`None`: until every player
    /// left or the server shuts down).
    pub match_ticks: Option<u64>,
    /// After the last tick, how long to wait for the last hash reports
    /// before closing the match.
    pub final_reports_timeout: Duration,
    /// How long after its first join a lobby waits (`None`: for ever).
    /// Then the seated players that have not sent their first input are
    /// dropped (closed as timed out) and the match starts with the ready
    /// ones, however few; with nobody ready the room closes. So a client
    /// that joins and never plays cannot keep a match from starting.
    pub lobby_timeout: Option<Duration>,
    /// Messages a second each connection may send (and as many in a
    /// burst): past it datagrams are dropped and counted (logged once a
    /// second, [`PlayerReport::datagrams_dropped`]) and stream frames wait.
    /// A player at 60 Hz sends about 2 datagrams and 1 frame a tick.
    pub max_messages_per_second: u32,
    /// Let players join a running match (`--late-join`): they start from
    /// the snapshot of the last agreed tick, fetched from a player in
    /// agreement and checked against the agreed hash. Default false.
    pub late_join: bool,
    /// How long a dropped token holder's seat stays reserved for its
    /// rejoin (with the rejoin credential its welcome gave). Default 30 s.
    pub rejoin_grace: Duration,
    /// Every match's seed (announced in the welcome, recorded in the
    /// replay; the game's rules read it as their random source). `None`
    /// (default): a fresh random seed per room.
    pub seed: Option<u64>,
}

impl Default for RoomSettings {
    fn default() -> Self {
        Self {
            max_players: 8,
            start_players: 2,
            tick_rate: 60,
            input_delay: 4,
            silence_timeout: Duration::from_secs(5),
            match_ticks: None,
            final_reports_timeout: Duration::from_secs(2),
            lobby_timeout: Some(Duration::from_secs(30)),
            max_messages_per_second: 1000,
            late_join: false,
            rejoin_grace: Duration::from_secs(30),
            seed: None,
        }
    }
}

/// The live viewer (`ServerConfig::view`).
#[derive(Clone, Debug)]
pub struct ViewSettings {
    /// The viewer's HTTP address (TCP; port 0 picks one, see
    /// [`ServerEvent::ViewListening`]).
    pub listen: SocketAddr,
    /// How rooms are re-simulated for viewers: the game's rules, as for
    /// `verifier` (`lockstep_client::game::RulesVerifier`).
    pub sim: Arc<dyn lockstep_proto::verify::VerifierFactory>,
}

/// Everything [`run`] needs.
#[derive(Clone, Debug)]
pub struct ServerConfig {
    /// UDP address to listen on (port 0 picks one; see
    /// [`ServerEvent::Listening`]).
    pub listen: SocketAddr,
    /// The certificate.
    pub tls: TlsSource,
    /// Scene text sent to every player in the welcome.
    pub scene: String,
    /// Its name, for messages.
    pub scene_name: String,
    /// The game rules the players run (the server never runs them): written
    /// into every replay, so a replay is checked with the same rules.
    pub rules: RulesId,
    /// Settings of each room.
    pub room: RoomSettings,
    /// Directory where replays are written (`None`: no replays).
    pub replay_dir: Option<PathBuf>,
    /// Most rooms open at once; a join for a new name beyond it is refused.
    pub max_rooms: usize,
    /// Most connections at once; beyond it a connection is refused with
    /// QUIC code 5 (overloaded) and the reason.
    pub max_connections: usize,
    /// Most connections at once from one IP address, handshaking, waiting
    /// to join or seated: beyond it a connection is refused with QUIC code
    /// 5 (overloaded) and the reason, so one address cannot squat every
    /// free slot with idle connections. `None` (the library's default, for
    /// load tests from one host): only `max_connections` applies. The
    /// `lockstep-server` program's default is 16
    /// (`--max-connections-per-address`).
    pub max_connections_per_address: Option<usize>,
    /// The secret join tokens are signed with (at least 16 bytes). With it,
    /// a join that carries a token is seated only if the token verifies
    /// (and in the token's seat); see [`issue_token`].
    pub token_secret: Option<Vec<u8>>,
    /// Refuse joins without a valid token (needs `token_secret`).
    pub require_tokens: bool,
    /// Re-simulate every room's match with this plugin and judge every
    /// hash report against the server's own hash (`--verify`): a majority
    /// of liars cannot outvote honest players, and the replay records only
    /// verified hashes. `lockstep_client::game::RulesVerifier` makes one
    /// for any game's rules. The `lockstep-server` program always sets it
    /// (unless `--no-verify`); a library caller without the game's rules
    /// leaves it `None`, and then `vote` decides.
    pub verifier: Option<Arc<dyn lockstep_proto::verify::VerifierFactory>>,
    /// Without a verifier: let the players seated with a join token vote
    /// (`--vote`, needs `token_secret`): a player whose hash stays outside
    /// the token holders' strict majority is dropped as diverged. Default
    /// false: an unverifying server drops nobody for its hash, announces
    /// mismatches as undecided, and records in the replay only hashes every
    /// reporter agreed on, so connections that do not simulate cannot take
    /// a room over.
    pub vote: bool,
    /// Address of the Prometheus `/metrics`, `/healthz` and `/readyz`
    /// listener (TCP), if any (`--metrics`).
    pub metrics: Option<SocketAddr>,
    /// Serve live rooms to the browser viewer (`--view`); see [`spectate`].
    pub view: Option<ViewSettings>,
    /// Stop after the first match ends (one match per process, as game
    /// server fleets run them; `--exit-after-match`).
    pub exit_after_match: bool,
    /// Run as an Agones game server (`--agones`): `Ready` once listening,
    /// health pings while the tick clocks keep time, joins only once
    /// allocated (for the allocation's room, with its token secret), and
    /// `Shutdown` and exit after the match. See [`agones`].
    pub agones: Option<agones::AgonesSettings>,
    /// Run the tick clock and the rooms at real-time priority
    /// (`SCHED_FIFO`, Linux; `--realtime-clock`), so a tick that is due is
    /// not queued behind the connection threads on a busy box. Needs
    /// `CAP_SYS_NICE` or an rtprio limit of at least 10; without either the
    /// server logs a warning and runs at normal priority.
    pub realtime_clock: bool,
    /// Log each running room's status line once a second (the demo prints
    /// its own instead).
    pub log_status: bool,
    /// Where the server reports what happens (listening address, matches,
    /// a status per room per second, desyncs), for the demo and tests.
    pub events: Option<mpsc::UnboundedSender<ServerEvent>>,
}

impl ServerConfig {
    /// A server on `listen` for a game: its scene text (and a name for
    /// messages) and its rules' id, with a dev certificate written to
    /// `out/dev-cert.pem`, replays in `out/replays`, and default rooms.
    ///
    /// The server never runs the rules; it only records their id. For the
    /// demo game: `for_game(listen, DemoGame::SCENE, "demo",
    /// Demo.rules_id())` (`lockstep_client::game`).
    pub fn for_game(
        listen: SocketAddr,
        scene: impl Into<String>,
        scene_name: impl Into<String>,
        rules: RulesId,
    ) -> Self {
        Self {
            listen,
            tls: TlsSource::dev("out/dev-cert.pem"),
            scene: scene.into(),
            scene_name: scene_name.into(),
            rules,
            room: RoomSettings::default(),
            replay_dir: Some(PathBuf::from("out/replays")),
            max_rooms: 16,
            max_connections: 256,
            max_connections_per_address: None,
            token_secret: None,
            require_tokens: false,
            verifier: None,
            vote: false,
            metrics: None,
            view: None,
            exit_after_match: false,
            realtime_clock: false,
            agones: None,
            log_status: true,
            events: None,
        }
    }
}

/// Why the server could not run.
#[derive(Debug, Error)]
pub enum ServerError {
    /// The scene does not build.
    #[error("scene {name}: {detail}")]
    Scene {
        /// Its name.
        name: String,
        /// What is wrong.
        detail: String,
    },
    /// The room settings are incoherent.
    #[error("room settings: {0}")]
    Config(String),
    /// The certificate could not be made or loaded.
    #[error("tls: {0}")]
    Tls(String),
    /// A file or directory could not be written.
    #[error("{0}: {1}")]
    Io(PathBuf, #[source] std::io::Error),
    /// The Agones SDK could not be reached or refused a call.
    #[error("agones: {0}")]
    Agones(#[from] agones::AgonesError),
    /// The UDP socket could not be bound.
    #[error("bind {0}: {1}")]
    Bind(SocketAddr, #[source] std::io::Error),
    /// The clock's or the rooms' threads could not be started.
    #[error("start the tick clock's threads: {0}")]
    Thread(#[source] std::io::Error),
}

/// What the server reports while it runs.
#[derive(Clone, Debug)]
// A match's report is the large variant; events come a few a second at
// most, so boxing it would buy nothing.
#[allow(clippy::large_enum_variant)]
pub enum ServerEvent {
    /// Listening on `addr`; clients should trust `cert` (if generated).
    Listening {
        /// The bound address.
        addr: SocketAddr,
        /// The dev certificate file, if one was generated.
        cert: Option<PathBuf>,
    },
    /// A match started: tick `t` closes at `epoch + (t + 1) / tick_rate`.
    MatchStarted {
        /// The room.
        room: String,
        /// When the tick clock started.
        epoch: Instant,
        /// Ticks per second.
        tick_rate: u16,
        /// Players seated.
        players: usize,
    },
    /// Once per second per running room.
    Status(RoomStatus),
    /// The metrics listener is bound.
    MetricsListening {
        /// Its address.
        addr: SocketAddr,
    },
    /// The live viewer is bound (`--view`).
    ViewListening {
        /// Its address.
        addr: SocketAddr,
    },
    /// The room found a desync.
    Desync {
        /// The room.
        room: String,
        /// The notice sent to the players.
        notice: DesyncNotice,
    },
    /// The room located a desync: the bodies and fields that differ.
    DesyncLocated {
        /// The room.
        room: String,
        /// The report sent to the players.
        report: lockstep_proto::DesyncReport,
        /// The desync bundle, if one was written.
        bundle: Option<PathBuf>,
        /// When the report was made.
        at: Instant,
    },
    /// A connection was refused or a player removed for cause.
    Refused {
        /// The peer.
        remote: SocketAddr,
        /// Why, as logged.
        reason: String,
    },
    /// A match is over (or its room shut down); the replay is flushed.
    MatchEnded(RoomReport),
}

/// A room's figures at one moment.
#[derive(Clone, Debug)]
pub struct RoomStatus {
    /// The room.
    pub room: String,
    /// Next tick to close.
    pub tick: u64,
    /// Players seated.
    pub players: usize,
    /// Mean of the players' smoothed ping round trips.
    pub rtt: Option<Duration>,
    /// Mean UDP bytes per second sent to each player over the last second.
    pub down_bytes_per_sec: u64,
    /// Mean UDP bytes per second received from each player.
    pub up_bytes_per_sec: u64,
    /// Ticks whose hashes were compared so far.
    pub ticks_compared: u64,
    /// Compared ticks whose hashes differed.
    pub mismatched_ticks: u64,
}

impl std::fmt::Display for RoomStatus {
    /// One readable line: tick, players, round trip, bytes per second per
    /// player, hash agreement.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kb = |b: u64| format!("{:.1} kB/s", b as f64 / 1000.0);
        let rtt = self.rtt.map_or_else(
            || "-".into(),
            |r| format!("{:.1} ms", r.as_secs_f64() * 1000.0),
        );
        let hashes = if self.mismatched_ticks == 0 {
            format!("{} ticks compared, all agree", self.ticks_compared)
        } else {
            format!(
                "{} ticks compared, {} MISMATCHED",
                self.ticks_compared, self.mismatched_ticks
            )
        };
        write!(
            f,
            "tick {:6} | players {} | rtt {rtt} | per player: down {} up {} | hashes: {hashes}",
            self.tick,
            self.players,
            kb(self.down_bytes_per_sec),
            kb(self.up_bytes_per_sec)
        )
    }
}

/// Percentiles of a room's tick lateness (the time a tick closed minus
/// its deadline).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Lateness {
    /// Ticks measured.
    pub ticks: u64,
    /// Median.
    pub p50: Duration,
    /// 99th percentile.
    pub p99: Duration,
    /// Worst.
    pub max: Duration,
}

impl Lateness {
    /// The percentiles of `samples` (microseconds), if any.
    pub fn of(samples: &[u32]) -> Option<Lateness> {
        let mut s = samples.to_vec();
        s.sort_unstable();
        let at = |q: usize| Duration::from_micros(u64::from(s[(s.len() - 1) * q / 100]));
        (!s.is_empty()).then(|| Lateness {
            ticks: s.len() as u64,
            p50: at(50),
            p99: at(99),
            max: at(100),
        })
    }
}

/// One player's part in a match.
#[derive(Clone, Debug)]
pub struct PlayerReport {
    /// The seat.
    pub slot: Slot,
    /// Display name.
    pub name: String,
    /// The peer address.
    pub remote: SocketAddr,
    /// First tick without them and why, if they left before the end.
    pub left: Option<(u64, String)>,
    /// Smoothed ping round trip at the end.
    pub rtt: Option<Duration>,
    /// UDP bytes sent to the player (QUIC overhead included).
    pub udp_bytes_down: u64,
    /// UDP bytes received from the player.
    pub udp_bytes_up: u64,
    /// Protocol datagrams sent to the player, and their largest size.
    pub datagrams_down: u64,
    /// Largest protocol datagram sent to the player, in bytes.
    pub max_datagram_down: usize,
    /// Protocol datagrams received from the player.
    pub datagrams_up: u64,
    /// Largest protocol datagram received from the player, in bytes.
    pub max_datagram_up: usize,
    /// Ticks whose input the room substituted.
    pub inputs_substituted: u64,
    /// Hash reports accepted.
    pub hash_reports: u64,
    /// Snapshots it gave a player joining the running match that did not
    /// check out (it is not asked again).
    pub bad_snapshots: u64,
    /// Datagrams dropped for coming faster than
    /// [`RoomSettings::max_messages_per_second`].
    pub datagrams_dropped: u64,
    /// How long they were connected.
    pub connected_for: Duration,
}

/// A finished match.
#[derive(Clone, Debug)]
pub struct RoomReport {
    /// The room.
    pub room: String,
    /// Ticks played.
    pub ticks: u64,
    /// Ticks whose hashes were compared.
    pub ticks_compared: u64,
    /// Compared ticks whose hashes differed.
    pub mismatched_ticks: u64,
    /// Snapshots players gave joiners that did not check out (each player's
    /// count is in its [`PlayerReport::bad_snapshots`]).
    pub bad_snapshots: u64,
    /// The desync notices, in order (the first 256: a player that keeps
    /// diverging does not grow the report; `desync_notices` counts all).
    pub desyncs: Vec<DesyncNotice>,
    /// Desync notices raised in all.
    pub desync_notices: u64,
    /// Where the room located them (one search at a time: a notice raised
    /// during a search has no report; the first 256 reports are kept).
    pub located: Vec<lockstep_proto::DesyncReport>,
    /// The desync bundles written (with a replay directory only).
    pub bundles: Vec<PathBuf>,
    /// Bytes of desync probes and reports the room sent (encoded messages,
    /// without stream framing): what locating desyncs cost downstream.
    pub forensics_bytes_down: u64,
    /// Bytes of probe replies the room received.
    pub forensics_bytes_up: u64,
    /// Ticks the server re-simulated (`--verify`), and the CPU time they
    /// took (wall time of the re-simulation on the room's task).
    pub verified: Option<(u64, Duration)>,
    /// How late the room's ticks closed after their deadlines: median,
    /// 99th percentile and worst (over the first 131,072 ticks).
    pub lateness: Option<Lateness>,
    /// Every player who was seated, by join order.
    pub players: Vec<PlayerReport>,
    /// The replay file, if recorded.
    pub replay: Option<PathBuf>,
    /// Ticks of the replay with an agreed hash.
    pub replay_hashed_ticks: u64,
    /// From the start of the tick clock to the end.
    pub duration: Duration,
    /// Why the match ended.
    pub end_reason: String,
}

/// How many finished matches a [`ServerReport`] keeps (the oldest go first).
pub const RECENT_MATCHES: usize = 64;

/// How many refusals a [`ServerReport`] keeps (the oldest go first).
pub const RECENT_REFUSALS: usize = 256;

/// What [`run`] returns after shutting down. Bounded, so a server that
/// runs for days does not grow: counts of everything, and the most recent
/// matches and refusals.
#[derive(Clone, Debug, Default)]
pub struct ServerReport {
    /// The last [`RECENT_MATCHES`] matches played, in the order they ended
    /// (a lobby that closed before its match started is none).
    pub matches: Vec<RoomReport>,
    /// Matches played in all (as `lockstep_matches_total`).
    pub matches_total: u64,
    /// The last [`RECENT_REFUSALS`] connections refused or players removed
    /// for cause: peer and reason.
    pub refused: Vec<(SocketAddr, String)>,
    /// Refusals in all.
    pub refused_total: u64,
}

impl ServerReport {
    pub(crate) fn add_match(&mut self, m: RoomReport) {
        if self.matches.len() == RECENT_MATCHES {
            self.matches.remove(0);
        }
        self.matches.push(m);
        self.matches_total += 1;
    }

    pub(crate) fn add_refusal(&mut self, remote: SocketAddr, reason: String) {
        if self.refused.len() == RECENT_REFUSALS {
            self.refused.remove(0);
        }
        self.refused.push((remote, reason));
        self.refused_total += 1;
    }
}

/// State shared by the accept loop, the connection tasks and the rooms.
pub(crate) struct Shared {
    pub(crate) config: ServerConfig,
    pub(crate) scene_hash: u64,
    /// Bodies in the scene's world.
    pub(crate) scene_bodies: u32,
    pub(crate) rooms: Mutex<HashMap<String, room::RoomHandle>>,
    pub(crate) shutdown: watch::Receiver<bool>,
    pub(crate) report: Mutex<ServerReport>,
    pub(crate) room_tasks: Mutex<JoinSet<()>>,
    pub(crate) room_seq: std::sync::atomic::AtomicU64,
    pub(crate) metrics: metrics::Metrics,
    /// Notified when a match ends (for `exit_after_match`).
    pub(crate) match_ended: tokio::sync::Notify,
    /// Precise wake-ups for the rooms' tick clocks.
    pub(crate) clock: clock::Clock,
    /// The real-time threads room tasks run on (`None`: the server's
    /// runtime).
    pub(crate) room_threads: Option<clock::RoomThreads>,
    /// Agones mode: whether and how the server is allocated.
    pub(crate) allocation: std::sync::RwLock<agones::AllocationState>,
    /// The live viewer's rooms (`--view`).
    pub(crate) spectate: Option<Arc<spectate::Spectate>>,
    /// Open connections per IP address.
    pub(crate) per_address: Mutex<HashMap<std::net::IpAddr, usize>>,
}

/// One connection counted against its address while it lives.
pub(crate) struct AddressSlot {
    shared: Arc<Shared>,
    ip: std::net::IpAddr,
}

impl Drop for AddressSlot {
    fn drop(&mut self) {
        let mut map = self
            .shared
            .per_address
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        if let Some(n) = map.get_mut(&self.ip) {
            *n -= 1;
            if *n == 0 {
                map.remove(&self.ip);
            }
        }
    }
}

impl Shared {
    pub(crate) fn emit(&self, event: ServerEvent) {
        if let Some(tx) = &self.config.events {
            let _ = tx.send(event);
        }
    }

    /// Counts one more connection from `ip`, unless it already has
    /// `max_connections_per_address`.
    pub(crate) fn address_slot(self: &Arc<Self>, ip: std::net::IpAddr) -> Option<AddressSlot> {
        let mut map = self.per_address.lock().unwrap_or_else(|e| e.into_inner());
        let n = map.entry(ip).or_insert(0);
        if self
            .config
            .max_connections_per_address
            .is_some_and(|max| *n >= max)
        {
            return None;
        }
        *n += 1;
        Some(AddressSlot {
            shared: self.clone(),
            ip,
        })
    }

    pub(crate) fn refused(&self, remote: SocketAddr, reason: String) {
        crate::log!("refused {remote}: {reason}");
        self.metrics.refused(&reason);
        if let Ok(mut r) = self.report.lock() {
            r.add_refusal(remote, reason.clone());
        }
        self.emit(ServerEvent::Refused { remote, reason });
    }
}

/// Runs the server until `shutdown` completes, then shuts down gracefully:
/// stops accepting, lets every running room finish its current tick and
/// collect the last hash reports, closes every connection with a reason,
/// flushes the replays, and waits for every task.
///
/// # Example
///
/// A server for a game of one static box on a free port, with its own dev
/// certificate and no replays, stopped as soon as it listens:
///
/// ```
/// use lockstep_server::{RulesId, ServerConfig, ServerEvent, TlsSource, run};
///
/// # #[tokio::main(flavor = "current_thread")]
/// # async fn main() {
/// let dir = std::env::temp_dir().join(format!("lockstep-doc-{}", std::process::id()));
/// let scene = "[[bodies]]\nname = \"ground\"\nkind = \"static\"\n\
///              [[bodies.shapes]]\nkind = \"box\"\nhalf_extents = [10, 1, 10]\n";
/// let listen = "127.0.0.1:0".parse().unwrap();
/// let mut config = ServerConfig::for_game(listen, scene, "ground", RulesId::new("my-game", 1));
/// config.tls = TlsSource::dev(dir.join("cert.pem"));
/// config.replay_dir = None;
/// let (events_tx, mut events) = tokio::sync::mpsc::unbounded_channel();
/// config.events = Some(events_tx);
/// let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
/// let server = tokio::spawn(run(config, async {
///     let _ = stopped.await;
/// }));
/// let Some(ServerEvent::Listening { addr, cert }) = events.recv().await else {
///     panic!("the server did not start");
/// };
/// assert_ne!(addr.port(), 0);
/// assert!(cert.expect("a dev certificate").exists()); // for clients to trust
/// stop.send(()).unwrap();
/// let report = server.await.unwrap().unwrap();
/// assert!(report.matches.is_empty());
/// # }
/// ```
///
/// # Errors
/// [`ServerError`] if the scene does not build, the settings are incoherent,
/// the certificate cannot be made, or the socket cannot be bound. Errors of
/// single connections are logged, never returned.
pub async fn run(
    config: ServerConfig,
    shutdown: impl Future<Output = ()>,
) -> Result<ServerReport, ServerError> {
    let world =
        lockstep_core::scene::load_world(&config.scene, &config.scene_name).map_err(|e| {
            ServerError::Scene {
                name: config.scene_name.clone(),
                detail: e.to_string(),
            }
        })?;
    let scene_hash = world.state_hash();
    let scene_bodies = u32::try_from(world.body_handles().count()).unwrap_or(u32::MAX);
    room::check_settings(&config, scene_hash)?;
    match &config.token_secret {
        Some(s) if s.len() < lockstep_proto::token::MIN_SECRET_BYTES => {
            return Err(ServerError::Config(format!(
                "the token secret has {} bytes; at least {} are needed",
                s.len(),
                lockstep_proto::token::MIN_SECRET_BYTES
            )));
        }
        None if config.require_tokens => {
            return Err(ServerError::Config(
                "tokens are required but no token secret is set".into(),
            ));
        }
        None if config.vote && config.verifier.is_none() => {
            return Err(ServerError::Config(
                "voting counts only token holders' hashes, and no token secret is set".into(),
            ));
        }
        _ => {}
    }
    if let Some(dir) = &config.replay_dir {
        std::fs::create_dir_all(dir).map_err(|e| ServerError::Io(dir.clone(), e))?;
    }
    let (server_config, cert) = tls::server_config(&config.tls)?;
    let endpoint = quinn::Endpoint::server(server_config, config.listen)
        .map_err(|e| ServerError::Bind(config.listen, e))?;
    let addr = endpoint
        .local_addr()
        .map_err(|e| ServerError::Bind(config.listen, e))?;
    crate::log!(
        "listening on {addr} (scene {}, hash {scene_hash:016x}){}",
        config.scene_name,
        cert.as_ref()
            .map(|c| format!(", dev certificate in {}", c.display()))
            .unwrap_or_default()
    );
    let (shutdown_tx, shutdown_rx) = watch::channel(false);
    let limit = Arc::new(Semaphore::new(config.max_connections));
    // Handshakes spent on telling refused connections why, at once.
    let refusals = Arc::new(Semaphore::new(32));
    let config_agones = config.agones.is_some();
    let priority = clock::Priority {
        realtime: config.realtime_clock,
    };
    // At real-time priority: relaying rooms cost microseconds a tick, so
    // one thread holds hundreds and a second one only adds wake-ups;
    // verifying rooms re-simulate, so they get one thread per core.
    let room_threads = if config.verifier.is_some() {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        1
    };
    let room_threads =
        clock::RoomThreads::start(room_threads, priority).map_err(ServerError::Thread)?;
    let clock = clock::Clock::start(priority).map_err(ServerError::Thread)?;
    let spectate = config
        .view
        .as_ref()
        .map(|v| Arc::new(spectate::Spectate::new(v.sim.clone())));
    let view_listener = match &config.view {
        Some(v) => {
            let l = std::net::TcpListener::bind(v.listen)
                .map_err(|e| ServerError::Bind(v.listen, e))?;
            let local = l.local_addr().map_err(|e| ServerError::Bind(v.listen, e))?;
            Some((l, local))
        }
        None => None,
    };
    let shared = Arc::new(Shared {
        config,
        scene_hash,
        scene_bodies,
        rooms: Mutex::new(HashMap::new()),
        shutdown: shutdown_rx,
        report: Mutex::new(ServerReport::default()),
        room_tasks: Mutex::new(JoinSet::new()),
        room_seq: std::sync::atomic::AtomicU64::new(0),
        metrics: metrics::Metrics::default(),
        match_ended: tokio::sync::Notify::new(),
        clock,
        room_threads,
        allocation: std::sync::RwLock::new(if config_agones {
            agones::AllocationState::Waiting
        } else {
            agones::AllocationState::Off
        }),
        spectate,
        per_address: Mutex::new(HashMap::new()),
    });
    if let (Some((listener, local)), Some(spectate)) = (view_listener, &shared.spectate) {
        crate::log!("viewer on http://{local}/ (live rooms, read-only)");
        shared.emit(ServerEvent::ViewListening { addr: local });
        let routes = Arc::new(spectate::LiveRoutes(spectate.clone()));
        std::thread::Builder::new()
            .name("lockstep-view".into())
            .spawn(move || lockstep_view::http::serve(listener, routes))
            .map_err(ServerError::Thread)?;
    }
    let metrics_task = match shared.config.metrics {
        Some(a) => {
            let listener = metrics::bind(a)
                .await
                .map_err(|e| ServerError::Bind(a, e))?;
            let local = listener.local_addr().map_err(|e| ServerError::Bind(a, e))?;
            crate::log!("metrics on http://{local}/metrics (and /healthz, /readyz)");
            shared.emit(ServerEvent::MetricsListening { addr: local });
            Some(tokio::spawn(metrics::serve(shared.clone(), listener)))
        }
        None => None,
    };
    let mut sdk = match &shared.config.agones {
        Some(a) => Some(agones::start(&shared, a).await?),
        None => None,
    };
    shared
        .metrics
        .ready
        .store(true, std::sync::atomic::Ordering::Relaxed);
    shared.emit(ServerEvent::Listening { addr, cert });
    // An Agones game server hosts one match.
    let exit_after_match = shared.config.exit_after_match || sdk.is_some();
    let mut connections = JoinSet::new();
    tokio::pin!(shutdown);
    loop {
        tokio::select! {
            () = &mut shutdown => break,
            () = shared.match_ended.notified(), if exit_after_match => {
                crate::log!("the match ended; exiting (--exit-after-match)");
                break;
            }
            incoming = endpoint.accept() => {
                let Some(incoming) = incoming else { break };
                let remote = incoming.remote_address();
                let admitted = match (shared.address_slot(remote.ip()), limit.clone().try_acquire_owned()) {
                    (Some(slot), Ok(permit)) => Ok((slot, permit)),
                    (None, _) => Err(format!(
                        "too many connections from {} (at most {} per address)",
                        remote.ip(),
                        shared.config.max_connections_per_address.unwrap_or_default()
                    )),
                    (Some(_), Err(_)) => Err(format!(
                        "too many connections (at most {} on this server)",
                        shared.config.max_connections
                    )),
                };
                match admitted {
                    Ok((slot, permit)) => {
                        let shared = shared.clone();
                        let span = tracing::info_span!(
                            "conn",
                            remote = %remote,
                            slot = tracing::field::Empty
                        );
                        connections.spawn(tracing::Instrument::instrument(
                            async move {
                                conn::serve(shared, incoming).await;
                                drop(permit);
                                drop(slot);
                            },
                            span,
                        ));
                    }
                    Err(reason) => {
                        shared.refused(remote, reason.clone());
                        // Told why (QUIC code 5 and the reason) when a
                        // handshake can be spared; a flood past that gets
                        // a bare refusal.
                        match refusals.clone().try_acquire_owned() {
                            Ok(permit) => {
                                connections.spawn(async move {
                                    conn::refuse(incoming, &reason).await;
                                    drop(permit);
                                });
                            }
                            Err(_) => incoming.refuse(),
                        }
                    }
                }
            }
            Some(_) = connections.join_next(), if !connections.is_empty() => {}
        }
    }
    crate::log!("shutting down: finishing every room's tick");
    let _ = shutdown_tx.send(true);
    // Rooms first: they finish their tick, close their players with a
    // reason and flush their replays.
    let mut rooms =
        std::mem::take(&mut *shared.room_tasks.lock().unwrap_or_else(|e| e.into_inner()));
    while rooms.join_next().await.is_some() {}
    // Then the connection tasks, which end once their room closed them.
    let drained = tokio::time::timeout(Duration::from_secs(3), async {
        while connections.join_next().await.is_some() {}
    })
    .await;
    if drained.is_err() {
        crate::log!(
            "{} connection tasks did not end in 3 s; aborting them",
            connections.len()
        );
        connections.shutdown().await;
    }
    endpoint.close(
        lockstep_net::close_code::SHUTDOWN.into(),
        b"server shutting down",
    );
    let _ = tokio::time::timeout(Duration::from_secs(2), endpoint.wait_idle()).await;
    if let Some(t) = metrics_task {
        let _ = t.await;
    }
    // The replays are flushed: Agones may delete the pod now.
    if let Some(sdk) = &mut sdk {
        match sdk.shutdown().await {
            Ok(()) => crate::log!("agones: shutdown requested"),
            Err(e) => crate::log!("agones: {e}"),
        }
    }
    crate::log!("server stopped");
    let report = shared.report.lock().map(|r| r.clone()).unwrap_or_default();
    Ok(report)
}

/// A join token for a seat (or any seat, `seat: None`) of `room`, for
/// `player`, valid for `ttl` from `now`: what a matchmaker hands a player
/// it placed. The server checks it against the same `secret`
/// ([`ServerConfig::token_secret`]).
///
/// # Errors
/// [`lockstep_proto::token::TokenError::Unissuable`] for a secret shorter
/// than 16 bytes, names over 64 bytes or a seat out of range.
pub fn issue_token(
    secret: &[u8],
    room: &str,
    seat: Option<u8>,
    player: &str,
    ttl: Duration,
    now: std::time::SystemTime,
) -> Result<String, lockstep_proto::token::TokenError> {
    let now = now
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    lockstep_proto::token::issue(
        secret,
        &lockstep_proto::token::JoinClaims {
            room: room.to_owned(),
            seat: seat.map(lockstep_proto::Slot),
            player: player.to_owned(),
            expires: now.saturating_add(ttl.as_secs()),
        },
    )
}
