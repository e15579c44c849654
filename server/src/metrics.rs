//! Prometheus metrics, `/healthz` and `/readyz` on one small HTTP listener
//! (`ServerConfig::metrics`): counters the rooms and connections update
//! with relaxed atomics, read on each scrape. Plain HTTP/1.1, one request
//! per connection, so no web framework is needed.

use std::fmt::Write as _;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicI64, AtomicU64, Ordering};
use std::time::Duration;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpListener;

use crate::Shared;

/// Upper bounds of the tick-lateness histogram's buckets, in seconds.
pub const LATENESS_BUCKETS: [f64; 10] = [
    0.0001, 0.00025, 0.0005, 0.001, 0.002, 0.005, 0.01, 0.025, 0.05, 0.1,
];

/// Why a connection or player was refused, as metric labels.
pub(crate) const REFUSAL_KINDS: [&str; 6] = [
    "handshake",
    "join",
    "token",
    "protocol_violation",
    "overloaded",
    "other",
];

/// Every figure the endpoint exposes.
#[derive(Debug, Default)]
pub(crate) struct Metrics {
    pub(crate) players: AtomicI64,
    pub(crate) matches_running: AtomicI64,
    pub(crate) matches_total: AtomicU64,
    pub(crate) ticks_closed: AtomicU64,
    pub(crate) udp_bytes_in: AtomicU64,
    pub(crate) udp_bytes_out: AtomicU64,
    pub(crate) datagrams_in: AtomicU64,
    pub(crate) datagrams_out: AtomicU64,
    pub(crate) inputs_substituted: AtomicU64,
    pub(crate) hash_mismatches: AtomicU64,
    pub(crate) desyncs: AtomicU64,
    pub(crate) bad_snapshots: AtomicU64,
    pub(crate) refusals: [AtomicU64; REFUSAL_KINDS.len()],
    lateness_buckets: [AtomicU64; LATENESS_BUCKETS.len()],
    lateness_count: AtomicU64,
    lateness_sum_ns: AtomicU64,
    pub(crate) ready: AtomicBool,
    /// The latest a tick closed since the Agones health check last looked
    /// (nanoseconds; the check resets it).
    pub(crate) worst_late_ns: AtomicU64,
}

impl Metrics {
    /// One tick closed `late` after its deadline.
    pub(crate) fn tick_closed(&self, late: Duration) {
        let secs = late.as_secs_f64();
        for (i, &b) in LATENESS_BUCKETS.iter().enumerate() {
            if secs <= b {
                self.lateness_buckets[i].fetch_add(1, Ordering::Relaxed);
            }
        }
        self.lateness_count.fetch_add(1, Ordering::Relaxed);
        let ns = u64::try_from(late.as_nanos()).unwrap_or(u64::MAX);
        self.lateness_sum_ns.fetch_add(ns, Ordering::Relaxed);
        self.worst_late_ns.fetch_max(ns, Ordering::Relaxed);
        self.ticks_closed.fetch_add(1, Ordering::Relaxed);
    }

    /// Counts one refusal, classified by its reason text.
    pub(crate) fn refused(&self, reason: &str) {
        let kind = if reason.contains("token") {
            2
        } else if reason.contains("protocol violation") || reason.contains("bad ") {
            3
        } else if reason.contains("too many") || reason.contains("does not read") {
            4
        } else if reason.contains("refused") || reason.contains("join") {
            1
        } else if reason.contains("handshake") || reason.contains("ALPN") {
            0
        } else {
            5
        };
        self.refusals[kind].fetch_add(1, Ordering::Relaxed);
    }

    /// The Prometheus text exposition of every metric; `view_ticks`: the
    /// ticks re-simulated for the live viewer, when it is on.
    pub(crate) fn render(&self, rooms: usize, view_ticks: Option<u64>) -> String {
        let mut o = String::new();
        let get = |a: &AtomicU64| a.load(Ordering::Relaxed);
        let gauge = |o: &mut String, name: &str, help: &str, v: i64| {
            let _ = writeln!(o, "# HELP {name} {help}\n# TYPE {name} gauge\n{name} {v}");
        };
        gauge(
            &mut o,
            "lockstep_players",
            "Players seated in every room.",
            self.players.load(Ordering::Relaxed),
        );
        gauge(&mut o, "lockstep_rooms", "Rooms open.", rooms as i64);
        gauge(
            &mut o,
            "lockstep_matches_running",
            "Rooms whose tick clock runs.",
            self.matches_running.load(Ordering::Relaxed),
        );
        let counters: [(&str, &str, u64); 11] = [
            (
                "lockstep_matches_total",
                "Matches ended (rooms whose match started; a lobby that closes is none).",
                get(&self.matches_total),
            ),
            (
                "lockstep_ticks_closed_total",
                "Ticks closed over every room.",
                get(&self.ticks_closed),
            ),
            (
                "lockstep_udp_bytes_received_total",
                "UDP payload bytes received from players (QUIC included).",
                get(&self.udp_bytes_in),
            ),
            (
                "lockstep_udp_bytes_sent_total",
                "UDP payload bytes sent to players (QUIC included).",
                get(&self.udp_bytes_out),
            ),
            (
                "lockstep_datagrams_received_total",
                "Protocol datagrams received.",
                get(&self.datagrams_in),
            ),
            (
                "lockstep_datagrams_sent_total",
                "Protocol datagrams sent.",
                get(&self.datagrams_out),
            ),
            (
                "lockstep_inputs_substituted_total",
                "Inputs that missed their tick and were repeated.",
                get(&self.inputs_substituted),
            ),
            (
                "lockstep_hash_mismatches_total",
                "Compared ticks whose hashes differed.",
                get(&self.hash_mismatches),
            ),
            (
                "lockstep_desyncs_total",
                "Desync notices (one per divergence).",
                get(&self.desyncs),
            ),
            (
                "lockstep_bad_snapshots_total",
                "Snapshots players gave a joiner that did not check out.",
                get(&self.bad_snapshots),
            ),
            (
                "lockstep_refusals_total",
                "Connections refused or players removed for cause.",
                0,
            ),
        ];
        for (name, help, v) in counters {
            let _ = writeln!(o, "# HELP {name} {help}\n# TYPE {name} counter");
            if name == "lockstep_refusals_total" {
                for (kind, c) in REFUSAL_KINDS.iter().zip(&self.refusals) {
                    let _ = writeln!(o, "{name}{{reason=\"{kind}\"}} {}", get(c));
                }
            } else {
                let _ = writeln!(o, "{name} {v}");
            }
        }
        if let Some(v) = view_ticks {
            let name = "lockstep_view_ticks_simulated_total";
            let _ = writeln!(
                o,
                "# HELP {name} Ticks re-simulated for live viewers (none while nobody watches).\n\
                 # TYPE {name} counter\n{name} {v}"
            );
        }
        let name = "lockstep_tick_lateness_seconds";
        let _ = writeln!(
            o,
            "# HELP {name} Time a tick closed after its deadline.\n# TYPE {name} histogram"
        );
        for (b, c) in LATENESS_BUCKETS.iter().zip(&self.lateness_buckets) {
            let _ = writeln!(o, "{name}_bucket{{le=\"{b}\"}} {}", get(c));
        }
        let count = get(&self.lateness_count);
        let _ = writeln!(o, "{name}_bucket{{le=\"+Inf\"}} {count}");
        let _ = writeln!(o, "{name}_sum {}", get(&self.lateness_sum_ns) as f64 / 1e9);
        let _ = writeln!(o, "{name}_count {count}");
        o
    }
}

/// Serves `/metrics`, `/healthz` and `/readyz` until the server shuts down.
pub(crate) async fn serve(shared: Arc<Shared>, listener: TcpListener) {
    let mut shutdown = shared.shutdown.clone();
    let limit = Arc::new(tokio::sync::Semaphore::new(16));
    loop {
        let accepted = tokio::select! {
            _ = shutdown.wait_for(|s| *s) => break,
            a = listener.accept() => a,
        };
        let Ok((stream, _)) = accepted else { continue };
        let Ok(permit) = limit.clone().try_acquire_owned() else {
            continue;
        };
        let shared = shared.clone();
        tokio::spawn(async move {
            let _ = tokio::time::timeout(Duration::from_secs(5), answer(&shared, stream)).await;
            drop(permit);
        });
    }
}

async fn answer(shared: &Shared, mut stream: tokio::net::TcpStream) -> std::io::Result<()> {
    let mut buf = vec![0u8; 4096];
    let mut len = 0;
    // The request line and headers, up to a blank line or 4 KiB.
    while len < buf.len() && !buf[..len].windows(4).any(|w| w == b"\r\n\r\n") {
        let n = stream.read(&mut buf[len..]).await?;
        if n == 0 {
            break;
        }
        len += n;
    }
    let head = String::from_utf8_lossy(&buf[..len]);
    let mut parts = head.split_whitespace();
    let (method, path) = (parts.next().unwrap_or(""), parts.next().unwrap_or(""));
    let m = &shared.metrics;
    let (status, body, kind) = match (method, path) {
        ("GET", "/metrics") => {
            let rooms = shared.rooms.lock().map_or(0, |r| r.len());
            let view = shared
                .spectate
                .as_ref()
                .map(|v| v.ticks_simulated.load(Ordering::Relaxed));
            ("200 OK", m.render(rooms, view), "text/plain; version=0.0.4")
        }
        ("GET", "/healthz") => ("200 OK", "ok\n".into(), "text/plain"),
        ("GET", "/readyz") if m.ready.load(Ordering::Relaxed) && !*shared.shutdown.borrow() => {
            ("200 OK", "ready\n".into(), "text/plain")
        }
        ("GET", "/readyz") => (
            "503 Service Unavailable",
            "not ready\n".into(),
            "text/plain",
        ),
        _ => ("404 Not Found", "not found\n".into(), "text/plain"),
    };
    let response = format!(
        "HTTP/1.1 {status}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    stream.write_all(response.as_bytes()).await?;
    stream.shutdown().await
}

/// Binds the listener (so a bad address fails at start-up).
pub(crate) async fn bind(addr: SocketAddr) -> std::io::Result<TcpListener> {
    TcpListener::bind(addr).await
}
