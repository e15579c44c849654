//! `net`: how many players one server holds. The server runs in this
//! process on its own 2-thread tokio runtime (threads named `lockstep-srv`,
//! beside the server's own `lockstep-clock` and `lockstep-rooms` threads,
//! so their CPU time is read apart from the relays'); relays
//! (`lockstep_client::load`), light players that follow the protocol without
//! simulating, fill rooms of 4 or 16 on another runtime. Each configuration
//! plays a match at 60 Hz and reports the server's tick lateness (from the
//! rooms' own measurements), bandwidth per player, desyncs, the server's
//! CPU and the process's memory.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use lockstep_client::game::{Demo, DemoGame, RulesFactory};
use lockstep_client::load::{RelayReport, relay_endpoint, run_relay};
use lockstep_client::net::TrustedCert;
use lockstep_server::{ServerConfig, ServerEvent, ServerReport, TlsSource};

use crate::{Options, SuiteOutput};

/// One configuration's figures.
struct Row {
    players: usize,
    room_size: usize,
    rooms: usize,
    ticks: u64,
    p50_ms: f64,
    p99_ms: f64,
    max_ms: f64,
    desyncs: u64,
    mismatched: u64,
    failed: usize,
    down_proto: f64,
    down_udp: f64,
    up_udp: f64,
    down_playing: f64,
    up_playing: f64,
    server_cpu: f64,
    /// Seconds from the first connection to the last relay's end (what
    /// `server_cpu` is measured over).
    wall_s: f64,
    /// The clock thread's scheduling policy while the match ran.
    policy: String,
    /// Why relays failed: each distinct error and how many had it.
    failures: Vec<(String, usize)>,
    rss_mb: f64,
}

/// Each of this process's threads as (name, stat fields from field 3, the
/// state, on), read from `/proc/self/task`; `None` if /proc is unreadable.
fn thread_stats() -> Option<Vec<(String, Vec<String>)>> {
    let dir = std::fs::read_dir("/proc/self/task").ok()?;
    let mut out = Vec::new();
    for t in dir.flatten() {
        let Ok(stat) = std::fs::read_to_string(t.path().join("stat")) else {
            continue;
        };
        // pid (comm) state ...: the name may hold spaces and parentheses.
        let Some((head, rest)) = stat.rsplit_once(") ") else {
            continue;
        };
        let Some((_, comm)) = head.split_once('(') else {
            continue;
        };
        out.push((
            comm.to_owned(),
            rest.split_whitespace().map(str::to_owned).collect(),
        ));
    }
    Some(out)
}

/// CPU seconds of this process's threads whose name starts with `prefix`.
fn threads_cpu(prefix: &str) -> f64 {
    let Some(threads) = thread_stats() else {
        return f64::NAN;
    };
    let ticks: u64 = threads
        .iter()
        .filter(|(comm, _)| comm.starts_with(prefix))
        .map(|(_, f)| {
            // utime and stime: fields 14 and 15.
            let field = |i: usize| f.get(i).and_then(|v| v.parse::<u64>().ok()).unwrap_or(0);
            field(11) + field(12)
        })
        .sum();
    ticks as f64 / 100.0
}

/// The scheduling policy of this process's thread named `name` (field 41
/// of its stat): "fifo", "normal" or "other N"; "gone" if no such thread
/// runs.
fn thread_policy(name: &str) -> String {
    let Some(threads) = thread_stats() else {
        return "unknown".into();
    };
    match threads.iter().find(|(comm, _)| comm == name) {
        None => "gone".into(),
        Some((_, f)) => match f.get(38).map(String::as_str) {
            Some("0") => "normal".into(),
            Some("1") => "fifo".into(),
            Some(p) => format!("other {p}"),
            None => "unknown".into(),
        },
    }
}

fn rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches(" kB").trim().parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn play(players: usize, room_size: usize, realtime: bool, ticks: u64) -> Row {
    let rooms = players.div_ceil(room_size);
    let dir = std::env::temp_dir().join(format!("lockstep-net-{}", std::process::id()));
    let mut config = ServerConfig::for_game(
        SocketAddr::from(([127, 0, 0, 1], 0)),
        DemoGame::SCENE,
        "demo",
        Demo.rules_id(),
    );
    config.tls = TlsSource::dev(dir.join("cert.pem"));
    config.replay_dir = None;
    config.max_rooms = rooms + 1;
    config.max_connections = players + 16;
    config.room.max_players = room_size.min(16) as u8;
    config.room.start_players = room_size.min(players) as u8;
    config.room.match_ticks = Some(ticks);
    config.room.lobby_timeout = Some(Duration::from_secs(120));
    config.log_status = false;
    config.realtime_clock = realtime;
    let (events_tx, mut events) = tokio::sync::mpsc::unbounded_channel();
    config.events = Some(events_tx);
    let server_rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("lockstep-srv")
        .enable_all()
        .build()
        .expect("server runtime");
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let server = server_rt.spawn(lockstep_server::run(config, async {
        let _ = stop_rx.await;
    }));
    let relay_rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("lockstep-relay")
        .enable_all()
        .build()
        .expect("relay runtime");
    let server_cpu = || {
        threads_cpu("lockstep-srv") + threads_cpu("lockstep-clock") + threads_cpu("lockstep-rooms")
    };
    let cpu_before = server_cpu();
    let started = Instant::now();
    let mut policy = String::new();
    let relays: Vec<Result<RelayReport, String>> = relay_rt.block_on(async {
        let (addr, cert): (SocketAddr, PathBuf) = loop {
            match events.recv().await {
                Some(ServerEvent::Listening { addr, cert }) => {
                    break (addr, cert.expect("dev cert"));
                }
                Some(_) => {}
                None => panic!("the server stopped at start-up"),
            }
        };
        let cert = TrustedCert::File(cert);
        // One UDP socket per 32 relays.
        let endpoints: Vec<quinn::Endpoint> = (0..players.div_ceil(32))
            .map(|_| relay_endpoint(&cert).expect("relay endpoint"))
            .collect();
        let mut tasks = Vec::with_capacity(players);
        for i in 0..players {
            let endpoint = endpoints[i / 32].clone();
            let room = format!("room-{}", i / room_size);
            tasks.push(tokio::spawn(async move {
                run_relay(&endpoint, addr, &room, &format!("relay-{i}"))
                    .await
                    .map_err(|e| e.to_string())
            }));
            // Connect in order, a little apart, so rooms fill one by one.
            if i % 16 == 15 {
                tokio::time::sleep(Duration::from_millis(5)).await;
            }
        }
        policy = thread_policy("lockstep-clock");
        let mut out = Vec::with_capacity(players);
        for t in tasks {
            out.push(t.await.unwrap_or_else(|e| Err(e.to_string())));
        }
        drop(events);
        out
    });
    let wall_s = started.elapsed().as_secs_f64();
    let _ = stop_tx.send(());
    let report: ServerReport = server_rt
        .block_on(server)
        .expect("server task")
        .expect("server run");
    let server_cpu = server_cpu() - cpu_before;
    let _ = std::fs::remove_dir_all(&dir);
    let ok: Vec<&RelayReport> = relays.iter().filter_map(|r| r.as_ref().ok()).collect();
    let failed = relays.len() - ok.len();
    let mut failures: Vec<(String, usize)> = Vec::new();
    for e in relays.iter().filter_map(|r| r.as_ref().err()) {
        // Group by the message up to its first figure (tick counts and
        // times differ between relays that failed for the same reason).
        let e = e
            .split(|c: char| c.is_ascii_digit())
            .next()
            .unwrap_or("")
            .trim_end()
            .to_owned();
        match failures.iter_mut().find(|(m, _)| *m == e) {
            Some((_, n)) => *n += 1,
            None => failures.push((e.clone(), 1)),
        }
    }
    let mut p50s = Vec::new();
    let (mut p99, mut max, mut mismatched, mut measured) = (0f64, 0f64, 0u64, 0u64);
    let (mut udp_down, mut udp_up, mut seconds) = (0f64, 0f64, 0f64);
    for m in &report.matches {
        mismatched += m.mismatched_ticks;
        if let Some(l) = m.lateness {
            p50s.push(l.p50.as_secs_f64() * 1e3);
            p99 = p99.max(l.p99.as_secs_f64() * 1e3);
            max = max.max(l.max.as_secs_f64() * 1e3);
            measured += l.ticks;
        }
        let secs = m.duration.as_secs_f64().max(1e-9);
        for p in &m.players {
            udp_down += p.udp_bytes_down as f64 / secs;
            udp_up += p.udp_bytes_up as f64 / secs;
            seconds += 1.0;
        }
    }
    p50s.sort_by(f64::total_cmp);
    let n = seconds.max(1.0);
    let down_proto = ok
        .iter()
        .map(|r| r.bytes_down as f64 / r.played_for.as_secs_f64().max(1e-9))
        .sum::<f64>()
        / ok.len().max(1) as f64;
    let per_relay = |f: fn(&RelayReport) -> u64| {
        ok.iter()
            .map(|r| f(r) as f64 / r.playing_for.as_secs_f64().max(1e-9))
            .sum::<f64>()
            / ok.len().max(1) as f64
    };
    Row {
        down_playing: per_relay(|r| r.udp_down_playing),
        up_playing: per_relay(|r| r.udp_up_playing),
        players,
        room_size,
        rooms,
        ticks: measured,
        p50_ms: p50s.get(p50s.len() / 2).copied().unwrap_or(f64::NAN),
        p99_ms: p99,
        max_ms: max,
        desyncs: ok.iter().map(|r| r.desyncs).sum(),
        mismatched,
        failed,
        down_proto,
        down_udp: udp_down / n,
        up_udp: udp_up / n,
        server_cpu,
        wall_s,
        policy,
        failures,
        rss_mb: rss_mb(),
    }
}

/// The configurations of a full run, as `PLAYERSxROOM_SIZE` (what
/// `--scenes` picks from): 4 to 1,000 players in rooms of 4 and of 16, and
/// the counts between 256 and 1,000 in rooms of 4, to find the largest the
/// machine holds. The server asks for real-time scheduling of its clock
/// and rooms (`realtime_clock`, as docs/deploy.md advises); a name ending
/// in `-normal` runs it at normal priority instead, to show what that
/// costs in the same run.
const CONFIGS: [&str; 13] = [
    "4x4",
    "4x16",
    "64x4",
    "64x16",
    "256x4",
    "256x4-normal",
    "256x16",
    "384x4",
    "384x4-normal",
    "512x4",
    "768x4",
    "1000x4",
    "1000x16",
];

/// The names `--scenes` may give.
pub fn config_names() -> Vec<&'static str> {
    CONFIGS.to_vec()
}

/// Players, room size, and whether the clock asks for real-time priority.
fn parse_config(name: &str) -> (usize, usize, bool) {
    let (size, realtime) = match name.strip_suffix("-normal") {
        Some(s) => (s, false),
        None => (name, true),
    };
    let (p, r) = size.split_once('x').expect("PLAYERSxROOM");
    (
        p.parse().expect("players"),
        r.parse().expect("room size"),
        realtime,
    )
}

/// Runs every configuration ([`CONFIGS`], or those `--scenes` names), 600
/// ticks each (`--quick`: 4 players, 60 ticks).
pub fn run(o: &Options) -> SuiteOutput {
    let ticks = if o.quick { 60 } else { 600 };
    let configs: Vec<(usize, usize, bool)> = match (&o.scenes, o.quick) {
        (Some(names), _) => names.iter().map(|n| parse_config(n)).collect(),
        (None, true) => vec![(4, 4, true)],
        (None, false) => CONFIGS.iter().map(|n| parse_config(n)).collect(),
    };
    let started = Instant::now();
    let mut text = String::from(
        "players room rooms  ticks  late p50 ms  p99 ms  max ms  desyncs mismatched failed  down B/s (proto)  down B/s (UDP, all)  up B/s (UDP, all)  down B/s (UDP, playing)  up B/s (UDP, playing)  server CPU s  CPU %  clock   RSS MB\n",
    );
    let mut csv = String::from(
        "players,room_size,rooms,ticks,p50_ms,p99_ms,max_ms,desyncs,mismatched,failed,down_proto_bps,down_udp_bps,up_udp_bps,down_udp_playing_bps,up_udp_playing_bps,server_cpu_s,server_cpu_pct,clock_policy,rss_mb\n",
    );
    let mut failures = String::new();
    for (players, room, realtime) in configs {
        let r = play(players, room, realtime, ticks);
        for (e, n) in &r.failures {
            failures.push_str(&format!(
                "{}x{}{}: {n} relay(s) failed: {e}\n",
                r.players,
                r.room_size,
                if realtime { "" } else { "-normal" }
            ));
        }
        let pct = r.server_cpu / r.wall_s.max(1e-9) * 100.0;
        text.push_str(&format!(
            "{:7} {:4} {:5} {:6} {:11.3} {:7.3} {:7.3} {:8} {:10} {:6} {:17.0} {:20.0} {:18.0} {:24.0} {:22.0} {:13.2} {:6.1} {:7} {:7.1}\n",
            r.players, r.room_size, r.rooms, r.ticks, r.p50_ms, r.p99_ms, r.max_ms, r.desyncs,
            r.mismatched, r.failed, r.down_proto, r.down_udp, r.up_udp, r.down_playing,
            r.up_playing, r.server_cpu, pct, r.policy, r.rss_mb
        ));
        csv.push_str(&format!(
            "{},{},{},{},{:.4},{:.4},{:.4},{},{},{},{:.0},{:.0},{:.0},{:.0},{:.0},{:.3},{:.1},{},{:.1}\n",
            r.players,
            r.room_size,
            r.rooms,
            r.ticks,
            r.p50_ms,
            r.p99_ms,
            r.max_ms,
            r.desyncs,
            r.mismatched,
            r.failed,
            r.down_proto,
            r.down_udp,
            r.up_udp,
            r.down_playing,
            r.up_playing,
            r.server_cpu,
            pct,
            r.policy,
            r.rss_mb
        ));
    }
    if !failures.is_empty() {
        text.push('\n');
        text.push_str(&failures);
    }
    text.push_str(&format!(
        "\nlateness: each room measures every tick it closes (time closed minus deadline); p50 is the median of the rooms' medians, p99 and max the worst room's. CPU: the server runtime's two threads, its clock thread and its rooms' threads, from the first connection to the last relay's end (a match of {} ticks at 60 Hz = {:.0} s, plus connecting; 100% = one core). Clock: the clock thread's scheduling policy as /proc shows it (fifo: real-time, as asked; normal: asked for normal priority with -normal, or refused for want of CAP_SYS_NICE). Bandwidth per player: UDP (QUIC included) \"all\" as the server counts it over the connection's life (handshake, welcome and lobby included) divided by the match's duration; \"playing\" as each relay counts it from its first bundle to the end. RSS: the whole process (server and relays), high-water mark so far in the run. Relays run in this process on their own two threads. Wall time {:.0} s.\n",
        ticks,
        ticks as f64 / 60.0,
        started.elapsed().as_secs_f64()
    ));
    SuiteOutput { text, csv }
}
