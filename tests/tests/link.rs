//! The link conditioner, measured: an echo server behind it, clients that
//! stamp every datagram with a sequence number, and the delays, losses,
//! duplicates and reorderings seen at both ends compared with the config.

use std::collections::{BTreeMap, BTreeSet};
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use lockstep_tests::link::{Direction, LinkConditioner, LinkConfig};
use tokio::net::UdpSocket;
use tokio::task::JoinHandle;
use tokio::time::{Instant, sleep, timeout};

/// A datagram: client id (1 byte), sequence number (8 bytes), padding.
const PACKET_LEN: usize = 32;

fn packet(client: u8, seq: u64) -> [u8; PACKET_LEN] {
    let mut p = [0u8; PACKET_LEN];
    p[0] = client;
    p[1..9].copy_from_slice(&seq.to_le_bytes());
    p
}

fn parse(p: &[u8]) -> (u8, u64) {
    let mut seq = [0u8; 8];
    seq.copy_from_slice(&p[1..9]);
    (p[0], u64::from_le_bytes(seq))
}

/// One datagram seen by an endpoint: when, from where, which.
#[derive(Clone, Copy, Debug)]
struct Seen {
    at: Instant,
    from: SocketAddr,
    client: u8,
    seq: u64,
}

type Log = Arc<Mutex<Vec<Seen>>>;

/// An echo server on loopback that logs what it receives.
async fn echo_server() -> (SocketAddr, Log, JoinHandle<()>) {
    let socket = UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let addr = socket.local_addr().unwrap();
    let log: Log = Arc::default();
    let l = log.clone();
    let task = tokio::spawn(async move {
        let mut buf = [0u8; 2048];
        loop {
            let Ok((n, from)) = socket.recv_from(&mut buf).await else {
                continue;
            };
            let (client, seq) = parse(&buf[..n]);
            l.lock().unwrap().push(Seen {
                at: Instant::now(),
                from,
                client,
                seq,
            });
            let _ = socket.send_to(&buf[..n], from).await;
        }
    });
    (addr, log, task)
}

/// A client: its socket, and a task logging the echoes it gets back.
struct Client {
    id: u8,
    socket: Arc<UdpSocket>,
    received: Log,
    sent: Arc<Mutex<BTreeMap<u64, Instant>>>,
    task: JoinHandle<()>,
}

impl Client {
    async fn new(id: u8) -> Client {
        let socket = Arc::new(UdpSocket::bind("127.0.0.1:0").await.unwrap());
        let received: Log = Arc::default();
        let (s, r) = (socket.clone(), received.clone());
        let task = tokio::spawn(async move {
            let mut buf = [0u8; 2048];
            loop {
                let Ok((n, from)) = s.recv_from(&mut buf).await else {
                    continue;
                };
                let (client, seq) = parse(&buf[..n]);
                r.lock().unwrap().push(Seen {
                    at: Instant::now(),
                    from,
                    client,
                    seq,
                });
            }
        });
        Client {
            id,
            socket,
            received,
            sent: Arc::default(),
            task,
        }
    }

    /// Sends `count` datagrams to `to`, `burst` at a time, a millisecond
    /// apart (paced so loopback buffers never overflow), then waits
    /// `settle` for the stragglers.
    async fn send(&self, to: SocketAddr, count: u64, burst: u64, settle: Duration) {
        for seq in 0..count {
            self.sent.lock().unwrap().insert(seq, Instant::now());
            self.socket
                .send_to(&packet(self.id, seq), to)
                .await
                .unwrap();
            if (seq + 1) % burst == 0 {
                sleep(Duration::from_millis(1)).await;
            }
        }
        sleep(settle).await;
    }

    fn received(&self) -> Vec<Seen> {
        self.received.lock().unwrap().clone()
    }
}

impl Drop for Client {
    fn drop(&mut self) {
        self.task.abort();
    }
}

fn config() -> LinkConfig {
    LinkConfig {
        seed: 7,
        ..LinkConfig::default()
    }
}

/// How many datagrams arrived after one with a higher sequence number.
fn overtaken(seen: &[Seen]) -> usize {
    let mut top = None;
    let mut n = 0;
    for s in seen {
        if top.is_some_and(|t| s.seq < t) {
            n += 1;
        }
        top = Some(top.map_or(s.seq, |t: u64| t.max(s.seq)));
    }
    n
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

struct Summary {
    min: f64,
    mean: f64,
    max: f64,
}

fn summary(v: &[f64]) -> Summary {
    Summary {
        min: v.iter().copied().fold(f64::INFINITY, f64::min),
        mean: v.iter().sum::<f64>() / v.len() as f64,
        max: v.iter().copied().fold(0.0, f64::max),
    }
}

#[tokio::test]
async fn without_loss_every_packet_arrives_delayed_by_latency_plus_minus_jitter() {
    let (server, server_log, echo) = echo_server().await;
    let relay = LinkConditioner::start(
        server,
        LinkConfig {
            latency: Duration::from_millis(30),
            jitter: Duration::from_millis(10),
            ..config()
        },
    )
    .await
    .unwrap();
    let client = Client::new(1).await;
    let n = 400;
    client
        .send(relay.local_addr(), n, 2, Duration::from_millis(150))
        .await;

    let sent = client.sent.lock().unwrap().clone();
    let at_server = server_log.lock().unwrap().clone();
    let back = client.received();
    assert_eq!(at_server.len() as u64, n, "every packet reaches the server");
    assert_eq!(back.len() as u64, n, "every echo comes back");
    let server_at: BTreeMap<u64, Instant> = at_server.iter().map(|s| (s.seq, s.at)).collect();
    let up: Vec<f64> = at_server.iter().map(|s| ms(s.at - sent[&s.seq])).collect();
    let down: Vec<f64> = back.iter().map(|s| ms(s.at - server_at[&s.seq])).collect();
    for (name, d) in [("upstream", &up), ("downstream", &down)] {
        let s = summary(d);
        println!(
            "{name}: one-way delay min {:.2} ms, mean {:.2} ms, max {:.2} ms (config 30 ± 10 ms)",
            s.min, s.mean, s.max
        );
        // Timers never fire early; they may fire late by a timer tick
        // (1 ms) plus scheduling on a busy machine.
        assert!(s.min >= 20.0, "{name}: min {:.2} ms < 20 ms", s.min);
        assert!(
            s.min <= 23.0,
            "{name}: min {:.2} ms: jitter not seen",
            s.min
        );
        assert!(
            s.max >= 38.0,
            "{name}: max {:.2} ms: jitter not seen",
            s.max
        );
        assert!(s.max <= 55.0, "{name}: max {:.2} ms > 40 + 15 ms", s.max);
        assert!(
            (29.0..=34.0).contains(&s.mean),
            "{name}: mean {:.2} ms, expected 30 ms + timer granularity",
            s.mean
        );
    }
    let stats = relay.stats();
    assert_eq!(stats.forwarded, 2 * n);
    assert_eq!((stats.dropped, stats.duplicated), (0, 0));
    relay.stop().await;
    echo.abort();
}

#[tokio::test]
async fn loss_of_30_percent_drops_about_30_percent_each_way() {
    let (server, server_log, echo) = echo_server().await;
    let relay = LinkConditioner::start(
        server,
        LinkConfig {
            latency: Duration::from_millis(2),
            loss: 0.3,
            ..config()
        },
    )
    .await
    .unwrap();
    let client = Client::new(1).await;
    let n = 2000;
    client
        .send(relay.local_addr(), n, 5, Duration::from_millis(100))
        .await;

    let reached = server_log.lock().unwrap().len() as f64;
    let back = client.received().len() as f64;
    let up_loss = 1.0 - reached / n as f64;
    let down_loss = 1.0 - back / reached;
    println!(
        "loss 0.3: upstream {up_loss:.4} ({reached} of {n}), downstream {down_loss:.4} ({back} of {reached})"
    );
    // Binomial: σ = √(0.21 / n) ≈ 0.010 upstream, 0.012 downstream; allow 4σ.
    assert!((up_loss - 0.3).abs() < 0.041, "upstream loss {up_loss}");
    assert!(
        (down_loss - 0.3).abs() < 0.049,
        "downstream loss {down_loss}"
    );
    let up = relay.direction_stats(Direction::Upstream);
    let down = relay.direction_stats(Direction::Downstream);
    assert_eq!(up.forwarded as f64, reached);
    assert_eq!(up.dropped + up.forwarded, n);
    assert_eq!(down.forwarded as f64, back);
    assert_eq!(down.dropped as f64 + back, reached);
    assert_eq!(relay.overflowed(), 0);
    relay.stop().await;
    echo.abort();
}

#[tokio::test]
async fn the_same_seed_loses_the_same_packets() {
    let mut runs = Vec::new();
    for _ in 0..2 {
        let (server, server_log, echo) = echo_server().await;
        let relay = LinkConditioner::start(
            server,
            LinkConfig {
                loss: 0.5,
                ..config()
            },
        )
        .await
        .unwrap();
        let client = Client::new(1).await;
        client
            .send(relay.local_addr(), 200, 5, Duration::from_millis(50))
            .await;
        let seqs: BTreeSet<u64> = server_log.lock().unwrap().iter().map(|s| s.seq).collect();
        runs.push(seqs);
        relay.stop().await;
        echo.abort();
    }
    assert!((60..=140).contains(&runs[0].len()), "{}", runs[0].len());
    assert_eq!(runs[0], runs[1]);
}

#[tokio::test]
async fn duplicates_appear_at_the_configured_rate() {
    let (server, server_log, echo) = echo_server().await;
    let relay = LinkConditioner::start(
        server,
        LinkConfig {
            latency: Duration::from_millis(2),
            duplicate: 0.25,
            ..config()
        },
    )
    .await
    .unwrap();
    let client = Client::new(1).await;
    let n = 1000;
    client
        .send(relay.local_addr(), n, 5, Duration::from_millis(100))
        .await;

    let at_server = server_log.lock().unwrap().clone();
    let distinct: BTreeSet<u64> = at_server.iter().map(|s| s.seq).collect();
    assert_eq!(
        distinct.len() as u64,
        n,
        "no loss: every packet at least once"
    );
    let up_rate = at_server.len() as f64 / n as f64 - 1.0;
    let back = client.received();
    let down_rate = back.len() as f64 / at_server.len() as f64 - 1.0;
    println!("duplicate 0.25: upstream {up_rate:.4}, downstream {down_rate:.4}");
    // σ = √(0.1875 / n) ≈ 0.014 upstream, 0.012 downstream; allow 4σ.
    assert!(
        (up_rate - 0.25).abs() < 0.055,
        "upstream duplicates {up_rate}"
    );
    assert!(
        (down_rate - 0.25).abs() < 0.05,
        "downstream duplicates {down_rate}"
    );
    let stats = relay.stats();
    assert_eq!(
        stats.duplicated as usize,
        at_server.len() - n as usize + back.len() - at_server.len()
    );
    assert_eq!(stats.forwarded as usize, at_server.len() + back.len());
    relay.stop().await;
    echo.abort();
}

#[tokio::test]
async fn jitter_wider_than_the_packet_spacing_reorders_and_none_does_not() {
    for (jitter_ms, expect_reordering) in [(15, true), (0, false)] {
        let (server, server_log, echo) = echo_server().await;
        let relay = LinkConditioner::start(
            server,
            LinkConfig {
                latency: Duration::from_millis(20),
                jitter: Duration::from_millis(jitter_ms),
                ..config()
            },
        )
        .await
        .unwrap();
        let client = Client::new(1).await;
        // One packet a millisecond: 15 ms of jitter spans ~30 packets.
        client
            .send(relay.local_addr(), 300, 1, Duration::from_millis(100))
            .await;
        let at_server = server_log.lock().unwrap().clone();
        let back = client.received();
        assert_eq!((at_server.len(), back.len()), (300, 300));
        let (up, down) = (overtaken(&at_server), overtaken(&back));
        let stats = relay.stats();
        println!(
            "jitter {jitter_ms} ms: overtaken upstream {up}, at the client {down}, relay counted {}",
            stats.reordered
        );
        if expect_reordering {
            assert!(up >= 30, "upstream: only {up} of 300 overtaken");
            assert!(down >= 30, "at the client: only {down} of 300 overtaken");
            assert_eq!(
                relay.direction_stats(Direction::Upstream).reordered as usize,
                up
            );
        } else {
            assert_eq!((up, down, stats.reordered), (0, 0, 0));
        }
        relay.stop().await;
        echo.abort();
    }
}

#[tokio::test]
async fn reorder_holds_back_about_the_configured_share() {
    let (server, server_log, echo) = echo_server().await;
    let relay = LinkConditioner::start(
        server,
        LinkConfig {
            latency: Duration::from_millis(5),
            reorder: 0.1,
            ..config()
        },
    )
    .await
    .unwrap();
    let client = Client::new(1).await;
    let n = 1000;
    // Two packets a millisecond: a packet held back 6 ms is overtaken by
    // about 12.
    client
        .send(relay.local_addr(), n, 2, Duration::from_millis(100))
        .await;
    let at_server = server_log.lock().unwrap().clone();
    assert_eq!(at_server.len() as u64, n);
    let up = overtaken(&at_server) as f64 / n as f64;
    println!("reorder 0.1: {up:.4} of the packets arrive after a later one");
    // σ = √(0.09 / 1000) ≈ 0.0095; allow 4σ.
    assert!((up - 0.1).abs() < 0.04, "{up}");
    assert_eq!(
        relay.direction_stats(Direction::Upstream).reordered as f64 / n as f64,
        up
    );
    relay.stop().await;
    echo.abort();
}

#[tokio::test]
async fn each_client_gets_its_own_upstream_socket_and_its_own_echoes() {
    let (server, server_log, echo) = echo_server().await;
    let relay = LinkConditioner::start(
        server,
        LinkConfig {
            latency: Duration::from_millis(3),
            ..config()
        },
    )
    .await
    .unwrap();
    let (a, b) = (Client::new(1).await, Client::new(2).await);
    let to = relay.local_addr();
    tokio::join!(
        a.send(to, 50, 5, Duration::from_millis(50)),
        b.send(to, 50, 5, Duration::from_millis(50)),
    );
    let at_server = server_log.lock().unwrap().clone();
    let sources: BTreeMap<u8, BTreeSet<SocketAddr>> =
        at_server.iter().fold(BTreeMap::new(), |mut m, s| {
            m.entry(s.client).or_default().insert(s.from);
            m
        });
    assert_eq!(sources.len(), 2);
    let (src_a, src_b) = (&sources[&1], &sources[&2]);
    assert_eq!((src_a.len(), src_b.len()), (1, 1), "one source per client");
    assert_ne!(src_a, src_b, "the server sees two peers");
    for s in src_a.iter().chain(src_b) {
        assert!(s.ip().is_loopback());
        assert_ne!(*s, to, "not the client-facing socket");
        assert_ne!(*s, a.socket.local_addr().unwrap());
    }
    for c in [&a, &b] {
        let got = c.received();
        assert_eq!(got.len(), 50);
        assert!(got.iter().all(|s| s.client == c.id && s.from == to));
    }
    relay.stop().await;
    echo.abort();
}

#[tokio::test]
async fn a_full_queue_drops_and_counts_the_excess() {
    let (server, server_log, echo) = echo_server().await;
    let relay = LinkConditioner::start_with_queue_limit(
        server,
        LinkConfig {
            latency: Duration::from_millis(300),
            ..config()
        },
        10,
    )
    .await
    .unwrap();
    let client = Client::new(1).await;
    // 30 packets within ~6 ms, each held 300 ms: only the first 10 fit.
    client
        .send(relay.local_addr(), 30, 5, Duration::from_millis(100))
        .await;
    assert_eq!(relay.overflowed(), 20);
    assert_eq!(server_log.lock().unwrap().len(), 0, "still queued");
    sleep(Duration::from_millis(400)).await;
    let seqs: Vec<u64> = server_log.lock().unwrap().iter().map(|s| s.seq).collect();
    assert_eq!(seqs, (0..10).collect::<Vec<_>>());
    let up = relay.direction_stats(Direction::Upstream);
    assert_eq!((up.forwarded, up.dropped), (10, 20));
    relay.stop().await;
    echo.abort();
}

#[tokio::test]
async fn stop_ends_the_relay_and_frees_its_port() {
    let (server, _log, echo) = echo_server().await;
    let relay = LinkConditioner::start(server, config()).await.unwrap();
    let addr = relay.local_addr();
    let client = Client::new(1).await;
    client.send(addr, 5, 5, Duration::from_millis(20)).await;
    assert_eq!(client.received().len(), 5);
    timeout(Duration::from_secs(5), relay.stop())
        .await
        .expect("stop returns promptly");
    // The port is free again: the relay's socket is closed.
    let rebound = UdpSocket::bind(addr).await;
    assert!(rebound.is_ok(), "{rebound:?}");
    echo.abort();
}

#[tokio::test]
async fn refuses_non_loopback_upstreams_and_bad_probabilities() {
    let err = LinkConditioner::start("192.0.2.1:9".parse().unwrap(), config())
        .await
        .unwrap_err();
    assert_eq!(err.kind(), std::io::ErrorKind::InvalidInput);
    let bad = LinkConfig {
        loss: 1.5,
        ..config()
    };
    let err = LinkConditioner::start("127.0.0.1:9".parse().unwrap(), bad)
        .await
        .unwrap_err();
    assert_eq!(err.kind(), std::io::ErrorKind::InvalidInput);
    let nan = LinkConfig {
        duplicate: f64::NAN,
        ..config()
    };
    assert!(
        LinkConditioner::start("127.0.0.1:9".parse().unwrap(), nan)
            .await
            .is_err()
    );
}
