//! The export surface of a browser module: one [`Module`] per WebAssembly
//! instance, and [`export_client!`](crate::export_client), which exports
//! its methods as plain `extern "C"` functions for `web/page/client.js`.
//!
//! Bytes cross the boundary through linear memory, never as pointer
//! arguments: JS asks for room with `lockstep_buffer(len)` and writes
//! there, then calls the function that reads it (the length again as the
//! argument); a function that hands bytes back returns their length and
//! leaves them at `lockstep_output()`. Times are `performance.now()`
//! milliseconds (floats, for pacing only: nothing from them reaches the
//! world). The exports (all prefixed `lockstep_`):
//!
//! | export | what it does |
//! |---|---|
//! | `buffer(len) -> ptr` | room for `len` bytes JS writes next |
//! | `output() -> ptr` | where the last answer's bytes are |
//! | `start(room, name, token, bot) -> 0/1` | the buffer holds room, name and token (their lengths); `bot` ≥ 0: the game's bot plays with that seed; queues the join |
//! | `stream(len, now)`, `datagram(len, now)` | bytes that arrived (in the buffer) |
//! | `stream_ended(len)` | the connection ended; the buffer holds why |
//! | `keys(bits)` | the keys held ([`Keys`](crate::Keys)) |
//! | `pump(now) -> wake` | inputs due, timers; the time of the next wake-up (−1: none) |
//! | `step() -> tick` | applies the next bundle (−1: none ready) |
//! | `report()` | reports that tick's hash |
//! | `take_stream() -> len`, `take_datagram() -> len` | bytes to send (−1: no datagram) |
//! | `status() -> len` | the client's state as JSON |
//! | `world() -> len`, `frame() -> len` | the viewer's `/world` JSON and one `/frames` frame, for drawing |
//! | `leave()` | leaves the match |

use std::sync::Arc;
use std::time::Duration;

use lockstep_view::{Recorder, ViewKind, encode_frames, world_json};
use serde_json::json;

use crate::client::{Ending, WebClient};
use crate::game::{Keys, WebGame};

/// One browser module's state: the client, the buffers JS reads and
/// writes, and what the page draws from.
pub struct Module {
    game: Arc<dyn WebGame>,
    client: Option<WebClient>,
    input: Vec<u8>,
    output: Vec<u8>,
    error: Option<String>,
    recorder: Option<Recorder>,
}

fn duration(now_ms: f64) -> Duration {
    Duration::try_from_secs_f64(now_ms / 1000.0).unwrap_or_default()
}

impl Module {
    /// A module for `game`, no client yet.
    pub fn new(game: Arc<dyn WebGame>) -> Module {
        Module {
            game,
            client: None,
            input: Vec::new(),
            output: Vec::new(),
            error: None,
            recorder: None,
        }
    }

    /// Makes the input buffer `len` bytes long and returns where it starts.
    pub fn buffer(&mut self, len: usize) -> *mut u8 {
        self.input.clear();
        self.input.resize(len, 0);
        self.input.as_mut_ptr()
    }

    /// Where the last answer's bytes are.
    pub fn output(&self) -> *const u8 {
        self.output.as_ptr()
    }

    fn input(&self, from: usize, len: usize) -> &[u8] {
        let end = from.saturating_add(len).min(self.input.len());
        &self.input[from.min(end)..end]
    }

    fn answer(&mut self, bytes: Vec<u8>) -> usize {
        self.output = bytes;
        self.output.len()
    }

    /// Starts a client: the input buffer holds the room (`room` bytes),
    /// the player's name and the token (empty: none). `bot` ≥ 0 lets the
    /// game's bot play with that seed until a key is pressed. Returns 0,
    /// or 1 with the reason in the status.
    pub fn start(&mut self, room: usize, name: usize, token: usize, bot: f64) -> u32 {
        let text = |from, len| String::from_utf8_lossy(self.input(from, len)).into_owned();
        let (room_s, name_s, token_s) = (
            text(0, room),
            text(room, name),
            text(room.saturating_add(name), token),
        );
        let token = (!token_s.is_empty()).then_some(token_s);
        match WebClient::new(self.game.clone(), &room_s, &name_s, token) {
            Ok(mut c) => {
                c.set_bot((bot >= 0.0).then_some(bot as u64));
                self.client = Some(c);
                self.error = None;
                0
            }
            Err(e) => {
                self.error = Some(e);
                1
            }
        }
    }

    /// Stream bytes (the first `len` of the buffer) that arrived at `now`.
    pub fn stream(&mut self, len: usize, now_ms: f64) {
        let bytes = self.input(0, len).to_vec();
        if let Some(c) = &mut self.client {
            c.on_stream(duration(now_ms), &bytes);
        }
    }

    /// A datagram (the first `len` bytes of the buffer) that arrived at
    /// `now`.
    pub fn datagram(&mut self, len: usize, now_ms: f64) {
        let bytes = self.input(0, len).to_vec();
        if let Some(c) = &mut self.client {
            c.on_datagram(duration(now_ms), &bytes);
        }
    }

    /// The connection ended; the buffer's first `len` bytes say why.
    pub fn stream_ended(&mut self, len: usize) {
        let why = String::from_utf8_lossy(self.input(0, len)).into_owned();
        if let Some(c) = &mut self.client {
            c.on_stream_end(&why);
        }
    }

    /// The keys held.
    pub fn keys(&mut self, bits: u32) {
        if let Some(c) = &mut self.client {
            c.set_keys(Keys(bits));
        }
    }

    /// Does what is due at `now`; returns when to call again (ms), or −1.
    pub fn pump(&mut self, now_ms: f64) -> f64 {
        let Some(c) = &mut self.client else {
            return -1.0;
        };
        c.pump(duration(now_ms));
        c.poll_timeout().map_or(-1.0, |t| t.as_secs_f64() * 1000.0)
    }

    /// Applies the next bundle; its tick, or −1 when none is ready.
    pub fn step(&mut self) -> f64 {
        self.client
            .as_mut()
            .and_then(WebClient::step)
            .map_or(-1.0, |t| t as f64)
    }

    /// Reports the hash of the tick just stepped.
    pub fn report(&mut self) {
        if let Some(c) = &mut self.client {
            c.report();
        }
    }

    /// The stream bytes to send; their length.
    pub fn take_stream(&mut self) -> usize {
        let bytes = self
            .client
            .as_mut()
            .map(WebClient::take_stream)
            .unwrap_or_default();
        self.answer(bytes)
    }

    /// The next datagram to send; its length, or −1.
    pub fn take_datagram(&mut self) -> i32 {
        match self.client.as_mut().and_then(WebClient::pop_datagram) {
            Some(d) => self.answer(d) as i32,
            None => -1,
        }
    }

    /// Leaves the match (the leave message is then in `take_stream`).
    pub fn leave(&mut self) {
        if let Some(c) = &mut self.client {
            c.leave();
        }
    }

    /// The client's state as JSON (`docs/browser.md`); its length.
    pub fn status(&mut self) -> usize {
        let json = self.status_json().to_string();
        self.answer(json.into_bytes())
    }

    /// The client's state (see [`Module::status`]).
    pub fn status_json(&self) -> serde_json::Value {
        let rules = self.game.rules_id();
        let Some(c) = &self.client else {
            return json!({
                "phase": "idle",
                "rules": format!("{} v{}", rules.id, rules.version),
                "error": self.error,
            });
        };
        let n = c.counters();
        let ended = c.ending().map(|e| match e {
            Ending::Refused(close) => json!({
                "kind": "refused", "reason": format!("{:?}", close.reason), "detail": close.detail,
            }),
            Ending::Closed(close) => json!({
                "kind": "closed", "reason": format!("{:?}", close.reason), "detail": close.detail,
            }),
            Ending::Failed(why) => json!({ "kind": "failed", "reason": "Failed", "detail": why }),
            Ending::Left => json!({ "kind": "left", "reason": "Left", "detail": "" }),
        });
        let phase = match (c.ending(), c.joined()) {
            (Some(_), _) => "ended",
            (None, true) => "playing",
            (None, false) => "joining",
        };
        let session = c.session();
        let own = c
            .world()
            .zip(c.slot())
            .and_then(|(w, s)| self.game.player_body(w, s))
            .map(|h| json!({ "handle": h.index(), "generation": h.generation() }));
        json!({
            "phase": phase,
            "rules": format!("{} v{}", rules.id, rules.version),
            "joined": c.joined(),
            "slot": c.slot(),
            "tickRate": session.map(lockstep_proto::Session::tick_rate),
            "startTick": session.map(lockstep_proto::Session::start_tick),
            "ticksApplied": n.ticks_applied,
            "reportsSent": n.reports_sent,
            "lastTick": n.last.map(|(t, _)| t),
            "lastHash": n.last.map(|(_, h)| format!("{h:016x}")),
            "inputs": n.inputs,
            "lastInput": c.last_input(),
            "bot": c.bot_playing(),
            "substituted": n.substituted,
            "desyncs": n.desyncs,
            "lastDesync": c.last_desync(),
            "probes": n.probes,
            "streamBytesIn": n.stream_bytes_in,
            "streamBytesOut": n.stream_bytes_out,
            "datagramsIn": n.datagrams_in,
            "datagramsOut": n.datagrams_out,
            "datagramBytesIn": n.datagram_bytes_in,
            "datagramBytesOut": n.datagram_bytes_out,
            "ownBody": own,
            "ended": ended,
            "error": self.error,
        })
    }

    /// The bodies to draw, as the viewer's `/world` JSON (`kind` "live");
    /// its length (0 before the welcome).
    pub fn world(&mut self) -> usize {
        let Some(world) = self.client.as_ref().and_then(WebClient::world) else {
            return self.answer(Vec::new());
        };
        let title = format!("{} (browser client)", self.game.rules_id().id);
        let recorder = self
            .recorder
            .get_or_insert_with(|| Recorder::new(ViewKind::Live, title, world));
        recorder.add_bodies(world);
        let json = world_json(recorder.data());
        self.answer(json.into_bytes())
    }

    /// The world now as one frame of the viewer's frame stream (poses as
    /// `f32`, for drawing only); its length (0 before the welcome). A body
    /// that appeared since [`Module::world`] makes the frame list more
    /// bodies than that JSON: ask for the world again.
    pub fn frame(&mut self) -> usize {
        let Some(world) = self.client.as_ref().and_then(WebClient::world) else {
            return self.answer(Vec::new());
        };
        let tick = self
            .client
            .as_ref()
            .and_then(|c| c.counters().last)
            .map_or(0, |(t, _)| t);
        let title = format!("{} (browser client)", self.game.rules_id().id);
        let recorder = self
            .recorder
            .get_or_insert_with(|| Recorder::new(ViewKind::Live, title, world));
        recorder.record(world, tick);
        recorder.keep_last(1);
        let bytes = encode_frames(recorder.data());
        self.answer(bytes)
    }
}

/// Exports lockstep-web's browser client for a game, as plain `extern "C"`
/// functions (the table in [`module`](crate::module)) that
/// `web/page/client.js` calls. `$game` is an expression whose value is the
/// game: a [`WebGame`](crate::WebGame) (its rules and its keys), e.g.
/// `lockstep_client::game::Demo`. Invoke it once, at the root of the
/// game's `cdylib` crate, and build that crate for
/// `wasm32-unknown-unknown`:
///
/// ```text
/// lockstep_web::export_client!(my_game::MyGame);
/// ```
///
/// The module then imports nothing and holds one client.
#[macro_export]
macro_rules! export_client {
    ($game:expr) => {
        ::std::thread_local! {
            static LOCKSTEP_WEB_MODULE: ::std::cell::RefCell<$crate::Module> =
                ::std::cell::RefCell::new($crate::Module::new(::std::sync::Arc::new($game)));
        }

        fn lockstep_web_module<R>(f: impl FnOnce(&mut $crate::Module) -> R) -> R {
            LOCKSTEP_WEB_MODULE.with(|m| f(&mut m.borrow_mut()))
        }

        /// Room for `len` bytes JS writes next.
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_buffer(len: usize) -> *mut u8 {
            lockstep_web_module(|m| m.buffer(len))
        }

        /// Where the last answer's bytes are.
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_output() -> *const u8 {
            lockstep_web_module(|m| m.output())
        }

        /// Starts the client (room, name and token in the buffer).
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_start(room: usize, name: usize, token: usize, bot: f64) -> u32 {
            lockstep_web_module(|m| m.start(room, name, token, bot))
        }

        /// Stream bytes arrived (in the buffer).
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_stream(len: usize, now: f64) {
            lockstep_web_module(|m| m.stream(len, now))
        }

        /// A datagram arrived (in the buffer).
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_datagram(len: usize, now: f64) {
            lockstep_web_module(|m| m.datagram(len, now))
        }

        /// The connection ended (why, in the buffer).
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_stream_ended(len: usize) {
            lockstep_web_module(|m| m.stream_ended(len))
        }

        /// The keys held.
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_keys(bits: u32) {
            lockstep_web_module(|m| m.keys(bits))
        }

        /// What is due now; when to call again (ms), or −1.
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_pump(now: f64) -> f64 {
            lockstep_web_module(|m| m.pump(now))
        }

        /// Applies the next bundle; its tick, or −1.
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_step() -> f64 {
            lockstep_web_module(|m| m.step())
        }

        /// Reports the hash of the tick just stepped.
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_report() {
            lockstep_web_module(|m| m.report())
        }

        /// Stream bytes to send; their length.
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_take_stream() -> usize {
            lockstep_web_module(|m| m.take_stream())
        }

        /// The next datagram to send; its length, or −1.
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_take_datagram() -> i32 {
            lockstep_web_module(|m| m.take_datagram())
        }

        /// The client's state as JSON; its length.
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_status() -> usize {
            lockstep_web_module(|m| m.status())
        }

        /// The bodies to draw (JSON); its length.
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_world() -> usize {
            lockstep_web_module(|m| m.world())
        }

        /// The world now as one frame; its length.
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_frame() -> usize {
            lockstep_web_module(|m| m.frame())
        }

        /// Leaves the match.
        #[unsafe(no_mangle)]
        pub extern "C" fn lockstep_leave() {
            lockstep_web_module(|m| m.leave())
        }
    };
}
