//! A link conditioner: a loopback UDP relay that makes a perfect local link
//! behave like a bad network (latency, jitter, loss, duplicates,
//! reordering), so end-to-end tests can check that the lockstep protocol
//! copes.
//!
//! ```text
//!   client A ─┐                       ┌─ upstream socket for A ─┐
//!             ├─▶ relay.local_addr() ─┤                          ├─▶ server
//!   client B ─┘                       └─ upstream socket for B ─┘
//! ```
//!
//! Clients send to [`LinkConditioner::local_addr`]; the relay opens one
//! upstream socket per client address, so the server sees each client as a
//! separate peer (QUIC needs that), and sends the server's answers back to
//! the client they belong to. Both directions are conditioned independently
//! with the same [`LinkConfig`].
//!
//! # What happens to a datagram
//! For each datagram, in each direction, the relay draws (always the same
//! five numbers, in order, from `lockstep_testsupport::Rng`, a SplitMix64
//! stream, seeded by
//! `(config.seed, flow, direction)`, where `flow` numbers the clients in
//! the order they first sent):
//! 1. *loss*: dropped with probability `loss`, independently of the others;
//! 2. *delay*: `latency` plus a uniform offset in `[−jitter, +jitter]`
//!    (never below zero); jitter larger than the spacing of the packets
//!    reorders them;
//! 3. *reordering*: with probability `reorder`, held back by a further
//!    `latency + 2·jitter + 1 ms`, so the packets sent during that time
//!    overtake it;
//! 4. *duplication*: with probability `duplicate`, a second copy is sent,
//!    with its own delay (draw 5).
//!
//! Delays are kept in one timer queue per direction (a binary heap ordered
//! by delivery time, then by arrival order, so ties go out first come first
//! served); the queue holds at most [`MAX_QUEUED`] datagrams (or the limit
//! given to [`LinkConditioner::start_with_queue_limit`]), and datagrams
//! beyond that are dropped and counted ([`LinkConditioner::overflowed`]).
//!
//! Floats are fine here: this is test infrastructure, not the simulation
//! path. Only loopback addresses are ever used.

use std::cmp::{Ordering, Reverse};
use std::collections::{BinaryHeap, HashMap};
use std::io;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr};
use std::sync::atomic::{AtomicU64, Ordering as AtomicOrdering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use lockstep_testsupport::Rng;
use tokio::net::UdpSocket;
use tokio::sync::{Notify, watch};
use tokio::task::{JoinHandle, JoinSet};
use tokio::time::{Instant, sleep_until};

/// The most datagrams waiting in one direction's timer queue; beyond it
/// datagrams are dropped (a bound, so a stuck receiver cannot grow the
/// relay's memory without limit).
pub const MAX_QUEUED: usize = 16_384;

/// The largest datagram relayed, bytes (the UDP maximum).
pub const MAX_DATAGRAM: usize = 65_535;

/// How the link misbehaves, in each direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkConfig {
    /// Base one-way delay.
    pub latency: Duration,
    /// Each datagram's delay is `latency` plus a uniform offset in
    /// `[−jitter, +jitter]` (never below zero).
    pub jitter: Duration,
    /// Probability (0 to 1) that a datagram is dropped.
    pub loss: f64,
    /// Probability (0 to 1) that a datagram is sent twice.
    pub duplicate: f64,
    /// Probability (0 to 1) that a datagram is held back by a further
    /// `latency + 2·jitter + 1 ms`, to be overtaken.
    pub reorder: f64,
    /// Seed of the random decisions: the same seed and the same datagrams in
    /// the same order give the same fates.
    pub seed: u64,
}

impl Default for LinkConfig {
    /// A perfect link: no delay, no loss, no duplicates, no reordering.
    fn default() -> LinkConfig {
        LinkConfig {
            latency: Duration::ZERO,
            jitter: Duration::ZERO,
            loss: 0.0,
            duplicate: 0.0,
            reorder: 0.0,
            seed: 0,
        }
    }
}

impl LinkConfig {
    fn validate(&self) -> io::Result<()> {
        for (name, p) in [
            ("loss", self.loss),
            ("duplicate", self.duplicate),
            ("reorder", self.reorder),
        ] {
            if !(0.0..=1.0).contains(&p) {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidInput,
                    format!("link config: {name} must be a probability in 0..=1, got {p}"),
                ));
            }
        }
        Ok(())
    }
}

/// What the relay did so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Datagrams sent on (duplicates included).
    pub forwarded: u64,
    /// Datagrams not sent on: lost on purpose, dropped because the queue was
    /// full, or refused by the socket.
    pub dropped: u64,
    /// Extra copies made.
    pub duplicated: u64,
    /// Datagrams delivered after a datagram of the same client and direction
    /// that was received after them (overtaken, whether by jitter or by the
    /// `reorder` hold-back).
    pub reordered: u64,
}

/// A direction through the relay.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Client to server.
    Upstream,
    /// Server to client.
    Downstream,
}

impl Direction {
    fn index(self) -> usize {
        match self {
            Direction::Upstream => 0,
            Direction::Downstream => 1,
        }
    }
}

/// Counters of one direction.
#[derive(Debug, Default)]
struct Counters {
    forwarded: AtomicU64,
    lost: AtomicU64,
    overflowed: AtomicU64,
    send_failed: AtomicU64,
    duplicated: AtomicU64,
    reordered: AtomicU64,
}

impl Counters {
    fn bump(c: &AtomicU64) {
        c.fetch_add(1, AtomicOrdering::Relaxed);
    }

    fn snapshot(&self) -> LinkStats {
        let get = |c: &AtomicU64| c.load(AtomicOrdering::Relaxed);
        LinkStats {
            forwarded: get(&self.forwarded),
            dropped: get(&self.lost) + get(&self.overflowed) + get(&self.send_failed),
            duplicated: get(&self.duplicated),
            reordered: get(&self.reordered),
        }
    }
}

/// A loopback UDP relay: clients send to `relay.local_addr()`, it forwards
/// to `upstream` with per-packet delay/loss/duplication/reordering in both
/// directions (one upstream socket per client address, so the server tells
/// clients apart). Runs on the current tokio runtime until dropped or
/// stopped; dropping it aborts its tasks, [`LinkConditioner::stop`] ends
/// them and waits for them.
#[derive(Debug)]
pub struct LinkConditioner {
    local_addr: SocketAddr,
    counters: Arc<[Counters; 2]>,
    shutdown: watch::Sender<bool>,
    tasks: Vec<JoinHandle<()>>,
}

impl LinkConditioner {
    /// Binds the relay on the loopback address of `upstream`'s family (port
    /// chosen by the system) and starts relaying.
    ///
    /// # Errors
    /// `InvalidInput` if `upstream` is not a loopback address or a
    /// probability in `config` is outside 0..=1; any error binding the
    /// socket.
    pub async fn start(upstream: SocketAddr, config: LinkConfig) -> io::Result<LinkConditioner> {
        Self::start_with_queue_limit(upstream, config, MAX_QUEUED).await
    }

    /// [`LinkConditioner::start`] with another bound than [`MAX_QUEUED`]
    /// on each direction's timer queue (to test what happens when it
    /// overflows, or to model a small router buffer).
    ///
    /// # Errors
    /// As [`LinkConditioner::start`].
    pub async fn start_with_queue_limit(
        upstream: SocketAddr,
        config: LinkConfig,
        max_queued: usize,
    ) -> io::Result<LinkConditioner> {
        if !upstream.ip().is_loopback() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("the link conditioner relays to loopback only, not {upstream}"),
            ));
        }
        config.validate()?;
        let front = Arc::new(UdpSocket::bind(loopback(upstream)).await?);
        let local_addr = front.local_addr()?;
        let counters: Arc<[Counters; 2]> = Arc::default();
        let (shutdown, _) = watch::channel(false);
        let queues = [(); 2].map(|()| Arc::new(Queue::new(max_queued)));
        let mut tasks = Vec::with_capacity(3);
        for dir in [Direction::Upstream, Direction::Downstream] {
            tasks.push(tokio::spawn(run_scheduler(
                queues[dir.index()].clone(),
                counters.clone(),
                dir,
                shutdown.subscribe(),
            )));
        }
        let relay = Relay {
            front,
            upstream,
            config,
            counters: counters.clone(),
            queues,
        };
        tasks.push(tokio::spawn(relay.run(shutdown.subscribe())));
        Ok(LinkConditioner {
            local_addr,
            counters,
            shutdown,
            tasks,
        })
    }

    /// The address clients send to.
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// Both directions added up.
    pub fn stats(&self) -> LinkStats {
        let [up, down] = [&self.counters[0], &self.counters[1]].map(Counters::snapshot);
        LinkStats {
            forwarded: up.forwarded + down.forwarded,
            dropped: up.dropped + down.dropped,
            duplicated: up.duplicated + down.duplicated,
            reordered: up.reordered + down.reordered,
        }
    }

    /// One direction's counters.
    pub fn direction_stats(&self, dir: Direction) -> LinkStats {
        self.counters[dir.index()].snapshot()
    }

    /// Datagrams dropped because a timer queue was full
    /// (both directions; they are also counted in [`LinkStats::dropped`]).
    pub fn overflowed(&self) -> u64 {
        self.counters
            .iter()
            .map(|c| c.overflowed.load(AtomicOrdering::Relaxed))
            .sum()
    }

    /// Stops relaying and waits until every task has ended and every socket
    /// is closed. Datagrams still queued are discarded.
    pub async fn stop(mut self) {
        let _ = self.shutdown.send(true);
        for task in std::mem::take(&mut self.tasks) {
            let _ = task.await;
        }
    }
}

impl Drop for LinkConditioner {
    fn drop(&mut self) {
        for task in &self.tasks {
            task.abort();
        }
    }
}

/// The unspecified-port loopback address of `addr`'s family.
fn loopback(addr: SocketAddr) -> SocketAddr {
    let ip = match addr.ip() {
        IpAddr::V4(_) => IpAddr::V4(Ipv4Addr::LOCALHOST),
        IpAddr::V6(_) => IpAddr::V6(Ipv6Addr::LOCALHOST),
    };
    SocketAddr::new(ip, 0)
}

// ---- random fates -------------------------------------------------------------

/// A 64-bit draw as a uniform number in [0, 1) (its top 53 bits).
fn unit(x: u64) -> f64 {
    (x >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Decides the fate of each datagram of one client in one direction.
#[derive(Debug)]
struct Fates {
    rng: Rng,
    config: LinkConfig,
    /// Sequence number of the next datagram (for reordering stats).
    next_seq: u64,
}

/// One datagram's fate: its sequence number and up to two delays.
#[derive(Clone, Copy, Debug)]
struct Fate {
    seq: u64,
    lost: bool,
    delay: Duration,
    duplicate: Option<Duration>,
}

impl Fates {
    fn new(config: LinkConfig, flow: u64, dir: Direction) -> Fates {
        let mut seeder = Rng::new(config.seed ^ flow.wrapping_mul(0xd6e8_feb8_6659_fd93));
        let salt = seeder.next_u64() ^ (dir.index() as u64 + 1);
        Fates {
            rng: Rng::new(Rng::new(salt).next_u64()),
            config,
            next_seq: 0,
        }
    }

    /// A delay: latency ± jitter, at least zero.
    fn delay(&self, draw: u64) -> Duration {
        let jitter = self.config.jitter.as_nanos().min(u64::MAX as u128 / 4) as i128;
        let offset = (draw as i128 % (2 * jitter + 1)) - jitter;
        let nanos = (self.config.latency.as_nanos() as i128 + offset).max(0);
        Duration::from_nanos(nanos.min(u64::MAX as i128) as u64)
    }

    fn next(&mut self) -> Fate {
        // Determinism: always five draws per datagram, so the fate of the
        // n-th datagram depends only on the seed and n.
        let [loss, delay, reorder, duplicate, dup_delay] = [(); 5].map(|()| self.rng.next_u64());
        let seq = self.next_seq;
        self.next_seq += 1;
        let mut d = self.delay(delay);
        if unit(reorder) < self.config.reorder {
            d += self.config.latency + self.config.jitter * 2 + Duration::from_millis(1);
        }
        Fate {
            seq,
            lost: unit(loss) < self.config.loss,
            delay: d,
            duplicate: (unit(duplicate) < self.config.duplicate).then(|| self.delay(dup_delay)),
        }
    }
}

// ---- timer queues -----------------------------------------------------------

/// A datagram waiting to be delivered.
#[derive(Debug)]
struct Pending {
    at: Instant,
    /// Arrival order in this queue: the tie-break, so equal delivery times
    /// go out first come, first served.
    order: u64,
    flow: u64,
    seq: u64,
    socket: Arc<UdpSocket>,
    dest: SocketAddr,
    data: Arc<[u8]>,
}

impl PartialEq for Pending {
    fn eq(&self, o: &Pending) -> bool {
        (self.at, self.order) == (o.at, o.order)
    }
}
impl Eq for Pending {}
impl PartialOrd for Pending {
    fn partial_cmp(&self, o: &Pending) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Pending {
    fn cmp(&self, o: &Pending) -> Ordering {
        (self.at, self.order).cmp(&(o.at, o.order))
    }
}

/// One direction's timer queue.
#[derive(Debug)]
struct Queue {
    /// The datagrams, and the arrival counter that orders ties.
    heap: Mutex<(BinaryHeap<Reverse<Pending>>, u64)>,
    limit: usize,
    wake: Notify,
}

impl Queue {
    fn new(limit: usize) -> Queue {
        Queue {
            heap: Mutex::new((BinaryHeap::new(), 0)),
            limit,
            wake: Notify::new(),
        }
    }

    /// Queues a datagram; `false` if the queue is full.
    fn push(&self, mut p: Pending) -> bool {
        {
            let mut guard = self.heap.lock().unwrap_or_else(PoisonError::into_inner);
            let (heap, next_order) = &mut *guard;
            if heap.len() >= self.limit {
                return false;
            }
            p.order = *next_order;
            *next_order += 1;
            heap.push(Reverse(p));
        }
        self.wake.notify_one();
        true
    }

    /// Takes every datagram due at `now`, in delivery order, and says when
    /// the next one is due.
    fn take_due(&self, now: Instant, out: &mut Vec<Pending>) -> Option<Instant> {
        let mut guard = self.heap.lock().unwrap_or_else(PoisonError::into_inner);
        let heap = &mut guard.0;
        while heap.peek().is_some_and(|Reverse(p)| p.at <= now) {
            if let Some(Reverse(p)) = heap.pop() {
                out.push(p);
            }
        }
        heap.peek().map(|Reverse(p)| p.at)
    }
}

/// Delivers one direction's datagrams when they are due.
async fn run_scheduler(
    queue: Arc<Queue>,
    counters: Arc<[Counters; 2]>,
    dir: Direction,
    mut shutdown: watch::Receiver<bool>,
) {
    let c = &counters[dir.index()];
    // Highest sequence number delivered per flow: a datagram delivered
    // below it was overtaken.
    let mut highest: HashMap<u64, u64> = HashMap::new();
    let mut due = Vec::new();
    loop {
        let next = queue.take_due(Instant::now(), &mut due);
        for p in due.drain(..) {
            let top = highest.entry(p.flow).or_insert(p.seq);
            if p.seq < *top {
                Counters::bump(&c.reordered);
            }
            *top = (*top).max(p.seq);
            match p.socket.send_to(&p.data, p.dest).await {
                Ok(_) => Counters::bump(&c.forwarded),
                Err(_) => Counters::bump(&c.send_failed),
            }
        }
        let timer = async {
            match next {
                Some(at) => sleep_until(at).await,
                None => std::future::pending().await,
            }
        };
        tokio::select! {
            _ = queue.wake.notified() => {}
            _ = timer => {}
            _ = shutdown.changed() => return,
        }
    }
}

// ---- the relay ------------------------------------------------------------------

/// The receiving side: the client-facing socket and one upstream socket per
/// client.
struct Relay {
    front: Arc<UdpSocket>,
    upstream: SocketAddr,
    config: LinkConfig,
    counters: Arc<[Counters; 2]>,
    queues: [Arc<Queue>; 2],
}

/// A client's upstream socket and its upstream fates.
struct Flow {
    id: u64,
    socket: Arc<UdpSocket>,
    fates: Fates,
}

impl Relay {
    async fn run(self, mut shutdown: watch::Receiver<bool>) {
        let mut flows: HashMap<SocketAddr, Flow> = HashMap::new();
        // Dropping the set (when this task ends or is aborted) aborts the
        // per-client readers.
        let mut readers = JoinSet::new();
        let mut buf = vec![0u8; MAX_DATAGRAM];
        loop {
            let (n, from) = tokio::select! {
                r = self.front.recv_from(&mut buf) => match r {
                    Ok(v) => v,
                    // E.g. a port-unreachable report for an earlier send;
                    // yield so a persistent error cannot spin the runtime.
                    Err(_) => {
                        tokio::task::yield_now().await;
                        continue;
                    }
                },
                _ = shutdown.changed() => break,
            };
            if !flows.contains_key(&from) {
                let Ok(socket) = UdpSocket::bind(loopback(self.upstream)).await else {
                    Counters::bump(&self.counters[0].send_failed);
                    continue;
                };
                let id = flows.len() as u64;
                let socket = Arc::new(socket);
                let downstream = Downstream {
                    flow: id,
                    socket: socket.clone(),
                    server: self.upstream,
                    client: from,
                    front: self.front.clone(),
                    fates: Fates::new(self.config, id, Direction::Downstream),
                    queue: self.queues[1].clone(),
                    counters: self.counters.clone(),
                };
                readers.spawn(downstream.run());
                flows.insert(
                    from,
                    Flow {
                        id,
                        socket,
                        fates: Fates::new(self.config, id, Direction::Upstream),
                    },
                );
            }
            let Some(flow) = flows.get_mut(&from) else {
                continue;
            };
            let fate = flow.fates.next();
            let data: Arc<[u8]> = Arc::from(&buf[..n]);
            schedule(
                fate,
                flow.id,
                &flow.socket,
                self.upstream,
                data,
                &self.queues[0],
                &self.counters[0],
            );
        }
        readers.shutdown().await;
    }
}

/// The server-to-client half of one client's flow.
struct Downstream {
    flow: u64,
    /// The client's upstream socket, where the server's answers arrive.
    socket: Arc<UdpSocket>,
    server: SocketAddr,
    client: SocketAddr,
    /// The client-facing socket the answers leave from.
    front: Arc<UdpSocket>,
    fates: Fates,
    queue: Arc<Queue>,
    counters: Arc<[Counters; 2]>,
}

impl Downstream {
    /// Reads the server's datagrams for the client and queues them toward
    /// it, until aborted.
    async fn run(mut self) {
        let mut buf = vec![0u8; MAX_DATAGRAM];
        loop {
            let (n, from) = match self.socket.recv_from(&mut buf).await {
                Ok(v) => v,
                Err(_) => {
                    tokio::task::yield_now().await;
                    continue;
                }
            };
            if from != self.server {
                continue; // only the server's answers go back
            }
            let fate = self.fates.next();
            let data: Arc<[u8]> = Arc::from(&buf[..n]);
            let c = &self.counters[1];
            schedule(
                fate,
                self.flow,
                &self.front,
                self.client,
                data,
                &self.queue,
                c,
            );
        }
    }
}

/// Queues the copies a fate calls for.
fn schedule(
    fate: Fate,
    flow: u64,
    socket: &Arc<UdpSocket>,
    dest: SocketAddr,
    data: Arc<[u8]>,
    queue: &Queue,
    c: &Counters,
) {
    if fate.lost {
        Counters::bump(&c.lost);
        return;
    }
    let now = Instant::now();
    let copies = std::iter::once(fate.delay).chain(fate.duplicate);
    for (i, delay) in copies.enumerate() {
        if i > 0 {
            Counters::bump(&c.duplicated);
        }
        let queued = queue.push(Pending {
            at: now + delay,
            order: 0,
            flow,
            seq: fate.seq,
            socket: socket.clone(),
            dest,
            data: data.clone(),
        });
        if !queued {
            Counters::bump(&c.overflowed);
        }
    }
}
