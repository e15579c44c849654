//! What the server tells while it runs (events, room status lines) and
//! what it returns when it stops (match and server reports).

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use lockstep_proto::{DesyncNotice, Slot};

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
    /// The WebTransport endpoint listens (`ServerConfig::webtransport`);
    /// told right after [`Listening`](ServerEvent::Listening).
    WebTransportListening {
        /// The bound UDP address (sessions on the path `/lockstep`).
        addr: SocketAddr,
        /// The SHA-256 of its certificate's DER: what a browser passes in
        /// `serverCertificateHashes` to accept the generated development
        /// certificate.
        cert_sha256: [u8; 32],
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
    /// [`RoomSettings::max_messages_per_second`](crate::RoomSettings::max_messages_per_second).
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

/// What [`run`](crate::run) returns after shutting down. Bounded, so a server that
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
