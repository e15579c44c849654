//! The browser client's state machine against the protocol's room, in
//! memory and on a virtual clock: no browser, no network. Two web clients
//! (one driven by its keys, one by the demo's bot) play the demo; every
//! byte between them and the room goes through the wire encoding, stream
//! bytes cut at arbitrary places. The room compares every tick's hash, and
//! both clients' hashes equal those of a native re-simulation of the
//! room's bundles (what a native bot computes).

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

use lockstep_client::game::{Demo, DemoGame, DemoInput, RulesFactory, apply_bundle, start_match};
use lockstep_proto::{
    ClientMessage, CloseReason, PlayerId, Room, RoomConfig, RoomEvent, ServerMessage, encode_frame,
    frame_length,
};
use lockstep_web::{Ending, Keys, WebClient};

/// Splits framed stream bytes into messages.
fn frames(mut bytes: &[u8]) -> Vec<ClientMessage> {
    let mut out = Vec::new();
    while !bytes.is_empty() {
        let len = frame_length(bytes[..4].try_into().unwrap()).unwrap();
        out.push(ClientMessage::decode(&bytes[4..4 + len]).unwrap());
        bytes = &bytes[4 + len..];
    }
    out
}

fn demo_room(name: &str) -> Room {
    let scene_hash = DemoGame::world().unwrap().state_hash();
    let mut config = RoomConfig::new(name, DemoGame::SCENE.as_bytes().to_vec(), scene_hash);
    config.rules = Some(Demo.rules_id());
    config.seed = 7;
    Room::new(config).unwrap()
}

/// A room and its web clients on a virtual clock.
struct Net {
    room: Room,
    clients: Vec<WebClient>,
    ids: Vec<Option<PlayerId>>,
    /// Stream bytes queued for each client, delivered in pieces.
    to_client: Vec<Vec<u8>>,
    now: Duration,
    closed: BTreeMap<u64, lockstep_proto::TickBundle>,
    agreed: BTreeMap<u64, u64>,
    desyncs: usize,
}

impl Net {
    fn new(room: Room) -> Net {
        Net {
            room,
            clients: Vec::new(),
            ids: Vec::new(),
            to_client: Vec::new(),
            now: Duration::ZERO,
            closed: BTreeMap::new(),
            agreed: BTreeMap::new(),
            desyncs: 0,
        }
    }

    fn add(&mut self, client: WebClient) {
        self.clients.push(client);
        self.ids.push(None);
        self.to_client.push(Vec::new());
    }

    /// One millisecond of everything.
    fn run_ms(&mut self) {
        self.now += Duration::from_millis(1);
        let now = self.now;
        if self.room.is_started() {
            self.room.handle_timeout(now);
        }
        for i in 0..self.clients.len() {
            let c = &mut self.clients[i];
            c.pump(now);
            while c.step().is_some() {
                c.report();
            }
            for m in frames(&c.take_stream()) {
                match (m, self.ids[i]) {
                    (ClientMessage::Join(j), None) => match self.room.join(now, &j) {
                        Ok(id) => self.ids[i] = Some(id),
                        Err(e) => {
                            let close = ServerMessage::Close(e.to_close());
                            let frame = encode_frame(&close.encode().unwrap()).unwrap();
                            self.to_client[i].extend(frame);
                        }
                    },
                    (m, Some(id)) => self.room.handle_message(now, id, m).unwrap(),
                    (m, None) => panic!("{m:?} before joining"),
                }
            }
            while let Some(d) = c.pop_datagram() {
                let m = ClientMessage::decode(&d).unwrap();
                let id = self.ids[i].expect("joined");
                self.room.handle_message(now, id, m).unwrap();
            }
        }
        if !self.room.is_started() && self.room.player_count() == 2 && self.room.all_ready() {
            self.room.start(now).unwrap();
        }
        while let Some(t) = self.room.poll_transmit() {
            let i = self.ids.iter().position(|id| *id == Some(t.to)).unwrap();
            let bytes = t.message.encode().unwrap();
            match t.message.channel() {
                lockstep_proto::Channel::Reliable => {
                    self.to_client[i].extend(encode_frame(&bytes).unwrap());
                }
                lockstep_proto::Channel::Datagram => self.clients[i].on_datagram(now, &bytes),
            }
        }
        while let Some(e) = self.room.poll_event() {
            match e {
                RoomEvent::TickClosed(b) => {
                    self.closed.insert(b.tick, b);
                }
                RoomEvent::TickAgreed { tick, hash } => {
                    self.agreed.insert(tick, hash);
                }
                RoomEvent::Desync(_) => self.desyncs += 1,
                _ => {}
            }
        }
        // Stream bytes arrive in pieces of 1 to 700 bytes, cut anywhere.
        for i in 0..self.clients.len() {
            let pending = std::mem::take(&mut self.to_client[i]);
            let mut rest = &pending[..];
            let mut cut = 1 + (self.now.as_millis() as usize * 37) % 700;
            while !rest.is_empty() {
                let n = cut.min(rest.len());
                self.clients[i].on_stream(now, &rest[..n]);
                rest = &rest[n..];
                cut = 1 + (cut * 7 + 3) % 700;
            }
        }
    }
}

#[test]
fn web_clients_play_the_demo_with_the_room_and_hash_like_a_native_peer() {
    let mut net = Net::new(demo_room("web"));
    let mut keys = WebClient::new(Arc::new(Demo), "web", "keys", None).unwrap();
    keys.set_keys(Keys(Keys::RIGHT | Keys::UP));
    net.add(keys);
    let mut bot = WebClient::new(Arc::new(Demo), "web", "bot", None).unwrap();
    bot.set_bot(Some(3));
    net.add(bot);
    while net.agreed.len() < 300 {
        net.run_ms();
        assert!(net.now < Duration::from_secs(30), "the match stalled");
        for c in &net.clients {
            assert!(c.ending().is_none(), "{c:?}");
        }
    }
    assert_eq!(net.desyncs, 0);
    // A native peer: the scene, the match's seed, the demo's rules, every
    // closed bundle applied in order.
    let mut world = DemoGame::world().unwrap();
    start_match(&mut world, 7).unwrap();
    let mut rules = Demo.rules_for(&world).unwrap();
    for (tick, bundle) in &net.closed {
        apply_bundle(&mut world, &mut *rules, bundle).unwrap();
        if let Some(h) = net.agreed.get(tick) {
            assert_eq!(*h, world.state_hash(), "tick {tick}");
        }
    }
    for c in &net.clients {
        let n = c.counters();
        assert!(
            n.ticks_applied >= 300 && n.reports_sent == n.ticks_applied,
            "{n:?}"
        );
        let (tick, hash) = n.last.unwrap();
        let mut w = DemoGame::world().unwrap();
        start_match(&mut w, 7).unwrap();
        let mut r = Demo.rules_for(&w).unwrap();
        for b in net.closed.range(..=tick).map(|(_, b)| b) {
            apply_bundle(&mut w, &mut *r, b).unwrap();
        }
        assert_eq!(hash, w.state_hash());
    }
    // The keys were the input: right and up, at 71 % each.
    let walk = DemoInput {
        move_x: 71,
        move_z: -71,
        jump: false,
    };
    assert_eq!(net.clients[0].last_input(), walk.encode());
    let slot0 = net.ids[0].unwrap().slot;
    let sent = net.closed.values().rev().find_map(|b| {
        b.inputs
            .iter()
            .find(|p| p.slot == slot0 && !p.substituted)
            .map(|p| p.input.clone())
    });
    assert_eq!(sent, Some(walk.encode()));
    // The bot's input is the demo's scripted input for its seed.
    let slot1 = net.ids[1].unwrap().slot;
    let (tick, b) = net.closed.iter().next_back().unwrap();
    let p = b.inputs.iter().find(|p| p.slot == slot1).unwrap();
    if !p.substituted {
        assert_eq!(p.input, Demo.bot_input(3, slot1.0, *tick));
    }
}

#[test]
fn a_refused_join_ends_the_client_with_the_rooms_reason() {
    let mut net = Net::new(demo_room("web"));
    net.add(WebClient::new(Arc::new(Demo), "elsewhere", "lost", None).unwrap());
    for _ in 0..5 {
        net.run_ms();
    }
    let Some(Ending::Refused(close)) = net.clients[0].ending() else {
        panic!("{:?}", net.clients[0]);
    };
    assert_eq!(close.reason, CloseReason::WrongRoom);
    assert!(!net.clients[0].joined());
}

#[test]
fn garbage_on_the_stream_fails_the_client_without_a_panic() {
    let mut c = WebClient::new(Arc::new(Demo), "web", "x", None).unwrap();
    c.on_stream(Duration::ZERO, &[9, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9]);
    assert!(matches!(c.ending(), Some(Ending::Failed(_))), "{c:?}");
    let mut c = WebClient::new(Arc::new(Demo), "web", "x", None).unwrap();
    c.on_stream(Duration::ZERO, &u32::MAX.to_le_bytes());
    assert!(matches!(c.ending(), Some(Ending::Failed(_))), "{c:?}");
}
