//! Test harness: the workspace's seeded test generator, a lossy datagram link, a reliable pipe, and a
//! simulation of one room and its clients on a virtual clock (1 ms steps).
//! Everything crosses the codec as bytes, so the tests exercise encoding,
//! framing and decoding as well as the state machines.

#![allow(dead_code)]

use std::collections::VecDeque;
use std::time::Duration;

use lockstep_proto::{
    BodyDump, Channel, ClientMessage, FRAME_HEADER_BYTES, FieldDump, FieldKind, MAX_DATAGRAM_BYTES,
    PlayerId, Probe, ProbeAnswer, ProbeAsk, ProbeReply, Rejection, Room, RoomConfig, RoomEvent,
    ServerMessage, Session, SessionEvent, TickBundle, encode_frame, frame_length,
};

pub use lockstep_test_rng::Rng;

/// One direction of an unreliable datagram path.
#[derive(Clone, Debug, Default)]
pub struct LinkConfig {
    pub latency: Duration,
    /// Extra delay uniform in `0..=jitter`; reorders datagrams.
    pub jitter: Duration,
    /// Independent loss, parts per million.
    pub loss_ppm: u32,
    /// Chance that a datagram is delivered twice (the copy with its own delay).
    pub duplicate_ppm: u32,
    /// Gilbert–Elliott bursts: chance per datagram to enter the lossy state,
    /// and to leave it. Everything is lost in the lossy state.
    pub burst_enter_ppm: u32,
    pub burst_leave_ppm: u32,
    /// Time windows in which every datagram is lost.
    pub outages: Vec<(Duration, Duration)>,
}

impl LinkConfig {
    pub fn clean(latency_ms: u64) -> Self {
        Self {
            latency: Duration::from_millis(latency_ms),
            ..Self::default()
        }
    }
}

#[derive(Debug)]
pub struct Link {
    cfg: LinkConfig,
    rng: Rng,
    in_flight: Vec<(Duration, u64, Vec<u8>)>,
    seq: u64,
    in_burst: bool,
    pub sent: u64,
    pub lost: u64,
    pub duplicated: u64,
}

impl Link {
    pub fn new(cfg: LinkConfig, seed: u64) -> Self {
        Self {
            cfg,
            rng: Rng::new(seed),
            in_flight: Vec::new(),
            seq: 0,
            in_burst: false,
            sent: 0,
            lost: 0,
            duplicated: 0,
        }
    }

    pub fn send(&mut self, now: Duration, bytes: Vec<u8>) {
        self.sent += 1;
        if self.in_burst {
            if self.rng.chance(self.cfg.burst_leave_ppm) {
                self.in_burst = false;
            }
        } else if self.rng.chance(self.cfg.burst_enter_ppm) {
            self.in_burst = true;
        }
        let in_outage = self.cfg.outages.iter().any(|&(a, b)| now >= a && now < b);
        if self.in_burst || in_outage || self.rng.chance(self.cfg.loss_ppm) {
            self.lost += 1;
            return;
        }
        let copies = if self.rng.chance(self.cfg.duplicate_ppm) {
            self.duplicated += 1;
            2
        } else {
            1
        };
        for _ in 0..copies {
            let jitter_us = self.rng.below(self.cfg.jitter.as_micros() as u64 + 1);
            let at = now + self.cfg.latency + Duration::from_micros(jitter_us);
            self.in_flight.push((at, self.seq, bytes.clone()));
            self.seq += 1;
        }
    }

    /// Every datagram that has arrived by `now`, in arrival order.
    pub fn receive(&mut self, now: Duration) -> Vec<Vec<u8>> {
        let mut arrived: Vec<(Duration, u64, Vec<u8>)> = Vec::new();
        let mut i = 0;
        while i < self.in_flight.len() {
            if self.in_flight[i].0 <= now {
                arrived.push(self.in_flight.swap_remove(i));
            } else {
                i += 1;
            }
        }
        arrived.sort_by_key(|a| (a.0, a.1));
        arrived.into_iter().map(|a| a.2).collect()
    }
}

/// A reliable, ordered byte stream with fixed latency, carrying
/// length-prefixed frames exactly as a QUIC stream would.
#[derive(Debug, Default)]
pub struct Pipe {
    latency: Duration,
    chunks: VecDeque<(Duration, Vec<u8>)>,
    buffer: Vec<u8>,
}

impl Pipe {
    pub fn new(latency: Duration) -> Self {
        Self {
            latency,
            ..Self::default()
        }
    }

    pub fn send(&mut self, now: Duration, message: &[u8]) {
        let framed = encode_frame(message).expect("frame");
        self.chunks.push_back((now + self.latency, framed));
    }

    pub fn receive(&mut self, now: Duration) -> Vec<Vec<u8>> {
        while self.chunks.front().is_some_and(|c| c.0 <= now) {
            let (_, c) = self.chunks.pop_front().expect("front");
            self.buffer.extend(c);
        }
        let mut out = Vec::new();
        loop {
            if self.buffer.len() < FRAME_HEADER_BYTES {
                break;
            }
            let header: [u8; FRAME_HEADER_BYTES] = self.buffer[..FRAME_HEADER_BYTES]
                .try_into()
                .expect("4 bytes");
            let len = frame_length(header).expect("valid frame header");
            if self.buffer.len() < FRAME_HEADER_BYTES + len {
                break;
            }
            out.push(self.buffer[FRAME_HEADER_BYTES..FRAME_HEADER_BYTES + len].to_vec());
            self.buffer.drain(..FRAME_HEADER_BYTES + len);
        }
        out
    }
}

/// The input a test client submits for `tick`: 8 bytes naming slot and tick,
/// so every bundle entry can be checked against its origin.
pub fn input_for(slot: u8, tick: u64) -> Vec<u8> {
    let mut v = tick.to_le_bytes().to_vec();
    v[7] = slot;
    v
}

/// The "world": a hash chain over every applied bundle.
pub fn step_world(state: u64, b: &TickBundle) -> u64 {
    let mut h = state ^ b.tick.wrapping_mul(0x100_0000_01B3);
    for p in &b.inputs {
        for &byte in [p.slot.0, u8::from(p.substituted)].iter().chain(&p.input) {
            h = (h ^ u64::from(byte)).wrapping_mul(0x100_0000_01B3);
        }
    }
    h
}

#[derive(Debug)]
pub struct Client {
    pub name: String,
    pub id: Option<PlayerId>,
    pub session: Option<Session>,
    pub up: Link,
    pub down: Link,
    pub up_stream: Pipe,
    pub down_stream: Pipe,
    pub delivered: Vec<TickBundle>,
    /// World hash after each delivered tick.
    pub hashes: Vec<u64>,
    pub state: u64,
    /// From this tick on, the client's world diverges (its state is flipped
    /// once when it applies this tick).
    pub corrupt_at: Option<u64>,
    /// Once this many bundles were delivered, the client sends nothing more.
    pub silent_after: Option<u64>,
    pub events: Vec<SessionEvent>,
    pub bundle_datagrams: u64,
    pub bundles_received: u64,
    pub bundle_bytes: u64,
    pub input_datagrams: u64,
    pub inputs_sent: u64,
    pub input_bytes: u64,
}

impl Client {
    pub fn is_silent(&self) -> bool {
        self.silent_after
            .is_some_and(|n| self.delivered.len() as u64 >= n)
    }
}

#[derive(Debug)]
pub struct Sim {
    pub now: Duration,
    pub room: Room,
    pub clients: Vec<Client>,
    pub events: Vec<(Duration, RoomEvent)>,
    pub rejections: Vec<Rejection>,
    pub largest_datagram: usize,
    pub start_when_full: bool,
}

impl Sim {
    /// A room and one client per `(uplink, downlink)` pair; each client
    /// sends its join at time zero over its reliable stream, whose latency
    /// is the uplink's base latency.
    pub fn new(config: RoomConfig, links: Vec<(LinkConfig, LinkConfig)>, seed: u64) -> Self {
        let room = Room::new(config.clone()).expect("valid config");
        let now = Duration::ZERO;
        let clients = links
            .into_iter()
            .enumerate()
            .map(|(i, (up, down))| {
                let i = i as u64;
                let mut c = Client {
                    name: format!("player-{i}"),
                    id: None,
                    session: None,
                    up_stream: Pipe::new(up.latency),
                    down_stream: Pipe::new(down.latency),
                    up: Link::new(up, seed ^ (i * 2 + 1).wrapping_mul(0x5851_F42D)),
                    down: Link::new(down, seed ^ (i * 2 + 2).wrapping_mul(0x5851_F42D)),
                    delivered: Vec::new(),
                    hashes: Vec::new(),
                    state: 0,
                    corrupt_at: None,
                    silent_after: None,
                    events: Vec::new(),
                    bundle_datagrams: 0,
                    bundles_received: 0,
                    bundle_bytes: 0,
                    input_datagrams: 0,
                    inputs_sent: 0,
                    input_bytes: 0,
                };
                let join = Session::join_message(&config.name, &c.name)
                    .encode()
                    .expect("encode join");
                c.up_stream.send(now, &join);
                c
            })
            .collect();
        Self {
            now,
            room,
            clients,
            events: Vec::new(),
            rejections: Vec::new(),
            largest_datagram: 0,
            start_when_full: true,
        }
    }

    fn client_of(&self, id: PlayerId) -> Option<usize> {
        self.clients.iter().position(|c| c.id == Some(id))
    }

    /// Advances the virtual clock by 1 ms and runs everything due.
    pub fn step(&mut self) {
        self.now += Duration::from_millis(1);
        let now = self.now;
        // Client → room.
        for i in 0..self.clients.len() {
            let c = &mut self.clients[i];
            let mut arrived = c.up_stream.receive(now);
            arrived.extend(c.up.receive(now));
            for bytes in arrived {
                let msg = ClientMessage::decode(&bytes).expect("client message decodes");
                match (&msg, self.clients[i].id) {
                    (ClientMessage::Join(j), None) => {
                        let id = self.room.join(now, j).expect("join accepted");
                        self.clients[i].id = Some(id);
                    }
                    (_, Some(id)) => {
                        if let Err(r) = self.room.handle_message(now, id, msg) {
                            self.rejections.push(r);
                        }
                    }
                    (_, None) => panic!("message before join"),
                }
            }
        }
        if self.start_when_full
            && !self.room.is_started()
            && self.room.player_count() == self.clients.len()
            && self.room.all_ready()
        {
            self.room.start(now).expect("first start");
        }
        if self.room.poll_timeout().is_some_and(|t| t <= now) {
            self.room.handle_timeout(now);
        }
        while let Some(t) = self.room.poll_transmit() {
            let bytes = t.message.encode().expect("server message encodes");
            let Some(i) = self.client_of(t.to) else {
                continue;
            };
            let c = &mut self.clients[i];
            match t.channel() {
                Channel::Datagram => {
                    assert!(bytes.len() <= MAX_DATAGRAM_BYTES);
                    self.largest_datagram = self.largest_datagram.max(bytes.len());
                    if let ServerMessage::Bundles(d) = &t.message {
                        c.bundle_datagrams += 1;
                        c.bundles_received += d.bundles.len() as u64;
                        c.bundle_bytes += bytes.len() as u64;
                    }
                    c.down.send(now, bytes);
                }
                Channel::Reliable => c.down_stream.send(now, &bytes),
            }
        }
        while let Some(e) = self.room.poll_event() {
            self.events.push((now, e));
        }
        // Room → clients, and each client's reaction.
        for c in &mut self.clients {
            let mut arrived = c.down_stream.receive(now);
            arrived.extend(c.down.receive(now));
            for bytes in arrived {
                let msg = ServerMessage::decode(&bytes).expect("server message decodes");
                match (msg, &mut c.session) {
                    (ServerMessage::Welcome(w), None) => {
                        c.session = Some(Session::new(&w).expect("valid welcome"));
                    }
                    (msg, Some(s)) => s.handle_message(now, msg).expect("session accepts"),
                    (other, None) => panic!("{} before welcome", other.kind()),
                }
            }
            let silent = c.is_silent();
            let Some(s) = &mut c.session else {
                continue;
            };
            while let Some(e) = s.poll_event() {
                if let SessionEvent::Probe(p) = &e
                    && !silent
                {
                    let reply = answer_probe(&c.hashes, c.corrupt_at, p);
                    s.reply_probe(reply).expect("reply accepted");
                }
                c.events.push(e);
            }
            if silent {
                continue;
            }
            if s.poll_timeout().is_some_and(|t| t <= now) {
                s.handle_timeout(now);
            }
            while let Some(b) = s.poll_bundle() {
                c.state = step_world(c.state, &b);
                if c.corrupt_at == Some(b.tick) {
                    c.state ^= 1;
                }
                s.report_hash(b.tick, c.state, None).expect("hash accepted");
                c.hashes.push(c.state);
                c.delivered.push(b);
                if c.silent_after
                    .is_some_and(|n| c.delivered.len() as u64 >= n)
                {
                    break;
                }
            }
            let silent = c
                .silent_after
                .is_some_and(|n| c.delivered.len() as u64 >= n);
            while !silent && s.wants_input(now) {
                let tick = s.next_input_tick();
                s.submit_input(input_for(s.slot().0, tick))
                    .expect("input accepted");
            }
            if silent {
                continue;
            }
            while let Some(m) = s.poll_transmit() {
                let bytes = m.encode().expect("client message encodes");
                if let ClientMessage::Input(d) = &m {
                    c.input_datagrams += 1;
                    c.inputs_sent += d.inputs.len() as u64;
                    c.input_bytes += bytes.len() as u64;
                }
                match m.channel() {
                    Channel::Datagram => c.up.send(now, bytes),
                    Channel::Reliable => c.up_stream.send(now, &bytes),
                }
            }
        }
    }

    /// Steps until every non-silent client has been delivered `ticks`
    /// bundles, or panics after `limit` of virtual time.
    pub fn run_until_delivered(&mut self, ticks: usize, limit: Duration) {
        while self
            .clients
            .iter()
            .any(|c| c.silent_after.is_none() && c.delivered.len() < ticks)
        {
            assert!(
                self.now < limit,
                "not done by {limit:?}: delivered {:?}",
                self.clients
                    .iter()
                    .map(|c| c.delivered.len())
                    .collect::<Vec<_>>()
            );
            self.step();
        }
    }

    pub fn run_for(&mut self, d: Duration) {
        let end = self.now + d;
        while self.now < end {
            self.step();
        }
    }

    /// The bundles the room closed, from its events, in order.
    pub fn closed_bundles(&self) -> Vec<&TickBundle> {
        self.events
            .iter()
            .filter_map(|(_, e)| match e {
                RoomEvent::TickClosed(b) => Some(b),
                _ => None,
            })
            .collect()
    }
}

/// Bodies in the synthetic world the probes see.
pub const PROBE_BODIES: u32 = 10;
/// The body a corrupted client differs in.
pub const CORRUPT_BODY: u32 = 5;
/// The length of the synthetic snapshot (two chunks).
pub const SNAPSHOT_LEN: usize = 40_000;

/// A client's answer to a probe about its synthetic world: ten bodies whose
/// hashes are all zero but body 5's, which is one from the corrupted tick on
/// (its `linear_velocity` field then reads 1 instead of 0); the snapshot of
/// a tick is its state hash repeated.
pub fn answer_probe(hashes: &[u64], corrupt_at: Option<u64>, p: &Probe) -> ProbeReply {
    let Some(&state) = hashes.get(p.tick as usize) else {
        return ProbeReply {
            tick: p.tick,
            answer: ProbeAnswer::Unavailable,
        };
    };
    let bad = corrupt_at.is_some_and(|t| p.tick >= t);
    let answer = match &p.ask {
        ProbeAsk::BodyHashes { from } => ProbeAnswer::BodyHashes {
            total: PROBE_BODIES,
            from: *from,
            contacts: 0,
            game: 0,
            hashes: (*from..PROBE_BODIES)
                .map(|i| u64::from(bad && i == CORRUPT_BODY))
                .collect(),
        },
        ProbeAsk::Fields { bodies } => ProbeAnswer::Fields {
            bodies: bodies
                .iter()
                .map(|&index| BodyDump {
                    index,
                    handle: index + 1,
                    generation: 0,
                    name: format!("body{index}"),
                    fields: vec![
                        FieldDump {
                            name: "mass".into(),
                            kind: FieldKind::Scalar,
                            words: vec![7 << 32],
                        },
                        FieldDump {
                            name: "linear_velocity".into(),
                            kind: FieldKind::Scalar,
                            words: vec![u64::from(bad && index == CORRUPT_BODY), 0, 0],
                        },
                    ],
                })
                .collect(),
            game: Vec::new(),
        },
        ProbeAsk::Snapshot { offset } => {
            let all: Vec<u8> = state
                .to_le_bytes()
                .iter()
                .copied()
                .cycle()
                .take(SNAPSHOT_LEN)
                .collect();
            let start = (*offset as usize).min(SNAPSHOT_LEN);
            let end = (start + lockstep_proto::MAX_SNAPSHOT_CHUNK_BYTES).min(SNAPSHOT_LEN);
            ProbeAnswer::Snapshot {
                total: SNAPSHOT_LEN as u32,
                offset: start as u32,
                bytes: all[start..end].to_vec(),
            }
        }
    };
    ProbeReply {
        tick: p.tick,
        answer,
    }
}
