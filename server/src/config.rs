//! The server's settings: the rooms', the viewer's, and the whole
//! server's.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use tokio::sync::mpsc;

use crate::{RulesId, ServerEvent, TlsSource, agones};

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
    /// second, [`PlayerReport::datagrams_dropped`](crate::PlayerReport::datagrams_dropped)) and stream frames wait.
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

/// Everything [`run`](crate::run) needs.
#[derive(Clone, Debug)]
pub struct ServerConfig {
    /// UDP address to listen on (port 0 picks one; see
    /// [`ServerEvent::Listening`]).
    pub listen: SocketAddr,
    /// The certificate.
    pub tls: TlsSource,
    /// UDP address of the WebTransport (HTTP/3) endpoint for browsers, if
    /// any (`--webtransport`; port 0 picks one, see
    /// [`ServerEvent::WebTransportListening`]). Sessions on the path
    /// `/lockstep` join the same rooms as native QUIC connections, with the
    /// same messages, limits and tokens. Its certificate is `tls`'s files,
    /// or with a self-signed `tls` one generated at start that browsers
    /// accept through `serverCertificateHashes` (ECDSA P-256, 13 days).
    pub webtransport: Option<SocketAddr>,
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
    /// (and in the token's seat); see [`issue_token`](crate::issue_token).
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
    /// Serve live rooms to the browser viewer (`--view`); see [`spectate`](crate::spectate).
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
            webtransport: None,
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
