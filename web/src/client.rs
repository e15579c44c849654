//! The browser client as an I/O-free state machine: what a native bot does
//! (`lockstep_client::net::LiveClient`), without sockets, tasks or a
//! clock. The page feeds it what arrived on the WebTransport stream and as
//! datagrams, with the time; it joins, builds the world from the welcome,
//! submits an input whenever the session wants one, applies every bundle
//! through the game's rules in tick order, reports every tick's hash, and
//! answers the room's probes; the page sends what it hands back.
//!
//! Stream bytes are framed exactly as on the native QUIC stream (a 4-byte
//! little-endian length before each message, `lockstep_proto::encode_frame`);
//! a datagram carries one message, as a QUIC datagram does.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Duration;

use lockstep_client::game::{BotPolicy, BotView, GameRules, apply_tick, start_match};
use lockstep_client::net::History;
use lockstep_core::World;
use lockstep_proto::{
    Channel, ClientMessage, Close, FRAME_HEADER_BYTES, ServerMessage, Session, SessionEvent,
    Welcome, encode_frame, frame_length,
};

use crate::game::{Keys, WebGame};

/// Past ticks' states kept to answer the room's probes after a desync
/// (as a native client's default `forensics_ticks`).
pub const FORENSICS_TICKS: usize = 64;

/// Why the client stopped playing (or never started).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Ending {
    /// The server refused the join: its close message before any welcome
    /// (a bad or expired token, a full room, another protocol version...).
    Refused(Close),
    /// The server ended the match for this player (the match is over, or
    /// the player was dropped).
    Closed(Close),
    /// Something failed: a message that does not decode, a scene that does
    /// not build, other rules, a lost connection.
    Failed(String),
    /// The player left.
    Left,
}

/// What the client counted so far.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// Bundles applied (ticks stepped).
    pub ticks_applied: u64,
    /// Hash reports queued for the room, one per tick played.
    pub reports_sent: u64,
    /// The last tick applied and the state hash after it.
    pub last: Option<(u64, u64)>,
    /// Inputs submitted.
    pub inputs: u64,
    /// Bundles in which the room substituted this player's input (it came
    /// late or not at all).
    pub substituted: u64,
    /// Desync notices received.
    pub desyncs: u64,
    /// Probes answered.
    pub probes: u64,
    /// Stream bytes received and sent, framing included.
    pub stream_bytes_in: u64,
    /// See `stream_bytes_in`.
    pub stream_bytes_out: u64,
    /// Datagrams received and sent, and their bytes.
    pub datagrams_in: u64,
    /// See `datagrams_in`.
    pub datagrams_out: u64,
    /// See `datagrams_in`.
    pub datagram_bytes_in: u64,
    /// See `datagrams_in`.
    pub datagram_bytes_out: u64,
}

/// A match being played: the session, the world and the rules.
struct Playing {
    session: Session,
    world: World,
    rules: Box<dyn GameRules>,
    policy: Option<Box<dyn BotPolicy>>,
    history: History,
    /// A tick stepped whose hash is not reported yet.
    pending: Option<(u64, u64)>,
}

/// The browser client; see the module documentation.
pub struct WebClient {
    game: Arc<dyn WebGame>,
    inbox: Vec<u8>,
    stream_out: Vec<u8>,
    datagrams_out: VecDeque<Vec<u8>>,
    playing: Option<Box<Playing>>,
    ending: Option<Ending>,
    keys: Keys,
    /// `Some(seed)`: the game's bot plays (its policy, else its scripted
    /// input with this seed) until a key is pressed.
    bot: Option<u64>,
    last_input: Vec<u8>,
    last_desync: Option<String>,
    counters: Counters,
}

impl std::fmt::Debug for WebClient {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WebClient")
            .field("rules", &self.game.rules_id())
            .field("slot", &self.slot())
            .field("ending", &self.ending)
            .field("counters", &self.counters)
            .finish_non_exhaustive()
    }
}

impl WebClient {
    /// A client of `game` that asks for a seat in `room` as `name`,
    /// presenting `token` if given: the join is queued on the stream.
    ///
    /// # Errors
    /// The join breaks a protocol bound (an empty room name, a name or
    /// token too long).
    pub fn new(
        game: Arc<dyn WebGame>,
        room: &str,
        name: &str,
        token: Option<String>,
    ) -> Result<WebClient, String> {
        let join = Session::join_message_with_token(room, name, token);
        let frame = join
            .encode()
            .and_then(|b| encode_frame(&b))
            .map_err(|e| format!("join: {e}"))?;
        Ok(WebClient {
            game,
            inbox: Vec::new(),
            counters: Counters {
                stream_bytes_out: frame.len() as u64,
                ..Counters::default()
            },
            stream_out: frame,
            datagrams_out: VecDeque::new(),
            playing: None,
            ending: None,
            keys: Keys::default(),
            bot: None,
            last_input: Vec::new(),
            last_desync: None,
        })
    }

    /// Bytes that arrived on the stream at `now` (any cut: frames are
    /// reassembled here).
    pub fn on_stream(&mut self, now: Duration, bytes: &[u8]) {
        self.counters.stream_bytes_in += bytes.len() as u64;
        self.inbox.extend_from_slice(bytes);
        while self.ending.is_none() {
            let Some(header) = self.inbox.first_chunk::<FRAME_HEADER_BYTES>() else {
                return;
            };
            let len = match frame_length(*header) {
                Ok(len) => len,
                Err(e) => return self.fail(format!("stream frame: {e}")),
            };
            if self.inbox.len() < FRAME_HEADER_BYTES + len {
                return;
            }
            let frame: Vec<u8> = self.inbox.drain(..FRAME_HEADER_BYTES + len).collect();
            self.on_message(now, &frame[FRAME_HEADER_BYTES..], Channel::Reliable);
        }
    }

    /// A datagram that arrived at `now`.
    pub fn on_datagram(&mut self, now: Duration, bytes: &[u8]) {
        self.counters.datagrams_in += 1;
        self.counters.datagram_bytes_in += bytes.len() as u64;
        if self.ending.is_none() {
            self.on_message(now, bytes, Channel::Datagram);
        }
    }

    /// The stream or the connection ended (`detail`: what the page was
    /// told). After the server's close message this changes nothing.
    pub fn on_stream_end(&mut self, detail: &str) {
        self.fail(format!("the connection ended: {detail}"));
    }

    fn on_message(&mut self, now: Duration, bytes: &[u8], channel: Channel) {
        let message = match ServerMessage::decode(bytes) {
            Ok(m) if m.channel() == channel => m,
            Ok(m) => return self.fail(format!("a {} on the wrong channel", m.kind())),
            Err(e) => return self.fail(format!("server message: {e}")),
        };
        let Some(playing) = &mut self.playing else {
            return match message {
                ServerMessage::Welcome(w) => self.start(&w),
                ServerMessage::Close(c) => self.ending = Some(Ending::Refused(c)),
                // Datagrams may come before the welcome's frame; the room
                // sends them again.
                ServerMessage::Bundles(_) | ServerMessage::Ping(_) => {}
                other => self.fail(format!("a {} before the welcome", other.kind())),
            };
        };
        if let Err(e) = playing.session.handle_message(now, message) {
            return self.fail(e.to_string());
        }
        while let Some(event) = playing.session.poll_event() {
            match event {
                SessionEvent::Desync { notice, local_hash } => {
                    self.counters.desyncs += 1;
                    self.last_desync = Some(format!(
                        "tick {}: {:?}, mine {}",
                        notice.tick,
                        notice.verdict,
                        local_hash.map_or_else(|| "forgotten".into(), |h| format!("{h:016x}"))
                    ));
                }
                SessionEvent::DesyncLocated(report) => {
                    self.last_desync = Some(report.to_string());
                }
                SessionEvent::Probe(probe) => {
                    let reply = playing.history.answer(&probe);
                    if playing.session.reply_probe(reply).is_ok() {
                        self.counters.probes += 1;
                    }
                }
                SessionEvent::Closed(c) => self.ending = Some(Ending::Closed(c)),
            }
        }
    }

    /// Builds the world from the welcome, as a native client does
    /// (`Client::connect`): the scene (or a late joiner's snapshot) checked
    /// against its hash, the match's seed, the rules for it.
    fn start(&mut self, welcome: &Welcome) {
        match self.build(welcome) {
            Ok(p) => self.playing = Some(Box::new(p)),
            Err(e) => self.fail(e),
        }
    }

    fn build(&self, welcome: &Welcome) -> Result<Playing, String> {
        let ours = self.game.rules_id();
        if let Some(server) = &welcome.rules
            && *server != ours
        {
            return Err(format!(
                "the room plays {} v{}, this client {} v{}",
                server.id, server.version, ours.id, ours.version
            ));
        }
        let session = Session::new(welcome).map_err(|e| e.to_string())?;
        let (mut world, expected) = match &welcome.resume {
            Some(r) => (
                World::restore(&r.snapshot).map_err(|e| format!("resume snapshot: {e}"))?,
                r.hash,
            ),
            None => {
                let text = std::str::from_utf8(&welcome.scene)
                    .map_err(|e| format!("scene is not UTF-8: {e}"))?;
                let world = lockstep_core::scene::load_world(text, "welcome scene")
                    .map_err(|e| e.to_string())?;
                (world, welcome.scene_hash)
            }
        };
        let got = world.state_hash();
        if got != expected {
            return Err(format!(
                "the scene hashes to {got:016x}, the welcome says {expected:016x}"
            ));
        }
        if welcome.resume.is_none() {
            start_match(&mut world, welcome.seed).map_err(|e| e.to_string())?;
        }
        let rules = self.game.rules_for(&world).map_err(|e| e.to_string())?;
        let policy = self
            .bot
            .and_then(|seed| self.game.bot_policy(seed, welcome.slot.0));
        Ok(Playing {
            session,
            world,
            rules,
            policy,
            history: History::new(FORENSICS_TICKS),
            pending: None,
        })
    }

    fn fail(&mut self, why: String) {
        if self.ending.is_none() {
            self.ending = Some(Ending::Failed(why));
        }
    }

    /// The keys the player holds now. Pressing any key takes over from the
    /// bot.
    pub fn set_keys(&mut self, keys: Keys) {
        if keys.0 != 0 {
            self.bot = None;
        }
        self.keys = keys;
    }

    /// Lets the game's bot play (seeded with `seed`) until a key is
    /// pressed: its [`BotPolicy`] when it has one, else its scripted input.
    /// Call before the welcome for a policy to be made.
    pub fn set_bot(&mut self, seed: Option<u64>) {
        self.bot = seed;
    }

    /// Does what is due at `now`: the session's resend timer, and an input
    /// for every tick the session wants one for (chosen from the keys, or
    /// by the bot), queued for sending.
    pub fn pump(&mut self, now: Duration) {
        if self.ending.is_some() {
            return;
        }
        let Some(p) = &mut self.playing else {
            return;
        };
        if p.session.poll_timeout().is_some_and(|t| t <= now) {
            p.session.handle_timeout(now);
        }
        while p.session.wants_input(now) {
            let tick = p.session.next_input_tick();
            let slot = p.session.slot().0;
            let view = BotView {
                world: &p.world,
                rules: &*p.rules,
                slot,
                tick,
            };
            let input = match (self.bot, &mut p.policy) {
                (Some(_), Some(policy)) => policy.input(&view),
                (Some(seed), None) => self.game.bot_input(seed, slot, tick),
                (None, _) => self.game.keys_input(self.keys, &view),
            };
            if let Err(e) = p.session.submit_input(input.clone()) {
                return self.fail(e.to_string());
            }
            self.counters.inputs += 1;
            self.last_input = input;
        }
    }

    /// Applies the next bundle if it has arrived: the rules, the step, the
    /// state hash. Returns its tick, or `None` when no bundle is ready (or
    /// the client has ended). The hash is reported by [`WebClient::report`]
    /// (or the next `step`), so that a page can time the step alone.
    pub fn step(&mut self) -> Option<u64> {
        self.report();
        if self.ending.is_some() {
            return None;
        }
        let p = self.playing.as_mut()?;
        let bundle = p.session.poll_bundle()?;
        let slot = p.session.slot();
        let inputs: Vec<(u8, &[u8])> = bundle
            .inputs
            .iter()
            .map(|i| (i.slot.0, i.input.as_slice()))
            .collect();
        if let Err(e) = apply_tick(&mut p.world, &mut *p.rules, bundle.tick, &inputs) {
            self.fail(e.to_string());
            return None;
        }
        let hash = p.world.state_hash();
        p.pending = Some((bundle.tick, hash));
        self.counters.substituted += u64::from(
            bundle
                .inputs
                .iter()
                .any(|i| i.slot == slot && i.substituted),
        );
        self.counters.ticks_applied += 1;
        self.counters.last = Some((bundle.tick, hash));
        Some(bundle.tick)
    }

    /// Reports the hash of the tick [`WebClient::step`] applied (once), and
    /// keeps its state for the room's probes. A player that joined a
    /// running match does not report the ticks before its start.
    pub fn report(&mut self) {
        let Some(p) = &mut self.playing else {
            return;
        };
        let Some((tick, hash)) = p.pending.take() else {
            return;
        };
        p.history.record(tick, &p.world);
        if tick < p.session.start_tick() || self.ending.is_some() {
            return;
        }
        match p.session.report_hash(tick, hash, None) {
            Ok(()) => self.counters.reports_sent += 1,
            Err(e) => self.fail(e.to_string()),
        }
    }

    /// Leaves the match: a leave message is queued on the stream.
    pub fn leave(&mut self) {
        self.report();
        if let Some(p) = &mut self.playing {
            p.session.leave();
        }
        self.flush();
        if self.ending.is_none() {
            self.ending = Some(Ending::Left);
        }
    }

    /// Moves what the session wants sent into the outgoing stream bytes
    /// and datagrams.
    fn flush(&mut self) {
        let Some(p) = &mut self.playing else {
            return;
        };
        while let Some(message) = p.session.poll_transmit() {
            let bytes = match message.encode() {
                Ok(b) => b,
                Err(e) => return self.fail(format!("encode {}: {e}", message.kind())),
            };
            match message.channel() {
                Channel::Reliable => match encode_frame(&bytes) {
                    Ok(frame) => {
                        self.counters.stream_bytes_out += frame.len() as u64;
                        self.stream_out.extend_from_slice(&frame);
                    }
                    Err(e) => return self.fail(format!("frame: {e}")),
                },
                Channel::Datagram => {
                    self.counters.datagrams_out += 1;
                    self.counters.datagram_bytes_out += bytes.len() as u64;
                    self.datagrams_out.push_back(bytes);
                }
            }
            if matches!(message, ClientMessage::Leave) {
                return;
            }
        }
    }

    /// The bytes to write to the stream now (empty when there are none).
    pub fn take_stream(&mut self) -> Vec<u8> {
        self.flush();
        std::mem::take(&mut self.stream_out)
    }

    /// The next datagram to send, if any.
    pub fn pop_datagram(&mut self) -> Option<Vec<u8>> {
        self.flush();
        self.datagrams_out.pop_front()
    }

    /// When [`WebClient::pump`] next has something to do even if nothing
    /// arrives (`None`: not playing).
    pub fn poll_timeout(&self) -> Option<Duration> {
        if self.ending.is_some() {
            return None;
        }
        self.playing.as_ref()?.session.poll_timeout()
    }

    /// Why the client stopped, once it has.
    pub fn ending(&self) -> Option<&Ending> {
        self.ending.as_ref()
    }

    /// Whether a welcome came and the world was built.
    pub fn joined(&self) -> bool {
        self.playing.is_some()
    }

    /// The world after the last tick applied (`None` before the welcome).
    pub fn world(&self) -> Option<&World> {
        self.playing.as_ref().map(|p| &p.world)
    }

    /// The session (`None` before the welcome).
    pub fn session(&self) -> Option<&Session> {
        self.playing.as_ref().map(|p| &p.session)
    }

    /// This player's slot (`None` before the welcome).
    pub fn slot(&self) -> Option<u8> {
        self.session().map(|s| s.slot().0)
    }

    /// What the client counted.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// The last input submitted.
    pub fn last_input(&self) -> &[u8] {
        &self.last_input
    }

    /// Whether the bot is playing.
    pub fn bot_playing(&self) -> bool {
        self.bot.is_some()
    }

    /// The last desync notice or located report, as text.
    pub fn last_desync(&self) -> Option<&str> {
        self.last_desync.as_deref()
    }
}
