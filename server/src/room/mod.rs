//! One room's task: the I/O around the `Room` state machine. It owns
//! every send to the room's players and its replay file; the room decides
//! everything in time (the ticks, the timeouts, the match's lifecycle from
//! lobby to close) and this task only carries it out.
//!
//! The clock is drift-free: the room computes tick `t`'s deadline as
//! `start + (t + 1)·dt` in integer nanoseconds, and this task sleeps until
//! exactly the room's next deadline (`Room::poll_timeout`), never
//! `sleep(dt)` in a loop, so a late wake-up delays one tick, not every tick
//! after it. After every call into the room, its transmits and events are
//! drained.

mod bundle;
mod open;
mod report;

pub(crate) use open::{RoomHandle, check_settings, find_or_open};

use report::fill_traffic;

use std::fs::File;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime};

use bytes::Bytes;
use lockstep_proto::{
    Channel, ClientMessage, CloseReason, DesyncNotice, ENGINE_VERSION, LeaveReason, MatchPhase,
    PROTOCOL_VERSION, PlayerId, Rejection, ReplayHeader, ReplayRecorder, Room, RoomEvent,
    ServerMessage, Verdict,
};
use tokio::sync::mpsc;
use tokio::time::sleep_until;

use crate::peer::{Peer, RoomCmd, WriterCmd, close_cmd, close_of, send_close};
use crate::{PlayerReport, ServerEvent, Shared};

/// A seated player's connection and counters.
struct Seat {
    id: PlayerId,
    peer: Peer,
    report: usize,
    joined_at: Instant,
    closing: bool,
    /// UDP bytes sent at the last status line, for rates.
    last_udp_tx: u64,
    /// UDP bytes received at the last status line, for rates.
    last_udp_rx: u64,
}

struct Replay {
    recorder: ReplayRecorder,
    path: PathBuf,
    /// Open from the start of the match until a write fails.
    file: Option<File>,
    /// Whether the match started (and the file was created, or tried).
    started: bool,
}

impl Replay {
    /// Creates the file as the match starts; what the recorder holds so
    /// far (the lobby) is written at the next flush.
    fn start(&mut self, room: &str) {
        self.started = true;
        match File::create(&self.path) {
            Ok(f) => {
                crate::log!(
                    "room {room}: recording the replay to {}",
                    self.path.display()
                );
                self.file = Some(f);
            }
            Err(e) => crate::log!("room {room}: cannot create {}: {e}", self.path.display()),
        }
    }
}

struct RoomTask {
    shared: Arc<Shared>,
    seq: u64,
    name: String,
    room: Room,
    base: Instant,
    /// The match's phase as the room's events told it so far (the room
    /// may be further on while its events are handled).
    seen: MatchPhase,
    shutting_down: bool,
    seats: Vec<Option<Seat>>,
    players: Vec<PlayerReport>,
    desyncs: Vec<DesyncNotice>,
    /// Located desyncs, in order.
    located: Vec<lockstep_proto::DesyncReport>,
    /// Desync bundles written.
    bundles: Vec<PathBuf>,
    /// When the last desync notice went out (for the time to locate it).
    notice_at: Option<Instant>,
    /// The reference's checked snapshot, until the report comes.
    desync_snapshot: Option<bundle::CheckedSnapshot>,
    /// Bytes of probes and desync reports sent.
    forensics_bytes_down: u64,
    /// Bytes of probe replies received.
    forensics_bytes_up: u64,
    /// The server's own re-simulation (`--verify`).
    verifier: Option<Box<dyn lockstep_proto::verify::TickVerifier>>,
    /// Ticks the re-simulation applied.
    verified_ticks: u64,
    /// The time the re-simulation took.
    verify_time: Duration,
    /// What this room last added to the server's metrics.
    counted: report::Counted,
    /// Tick lateness samples in microseconds (the first 131,072 ticks).
    lateness_us: Vec<u32>,
    replay: Option<Replay>,
    /// The viewer's feed of this room (`--view`): its closed bundles.
    feed: Option<Arc<crate::spectate::RoomFeed>>,
}

impl RoomTask {
    fn new(shared: Arc<Shared>, name: String, room: Room, seq: u64) -> Self {
        let replay = shared.config.replay_dir.as_ref().and_then(|dir| {
            let c = room.config();
            let header = ReplayHeader {
                protocol_version: PROTOCOL_VERSION,
                room: name.clone(),
                tick_rate: c.tick_rate,
                input_delay: c.input_delay,
                scene_hash: c.scene_hash,
                scene: c.scene.clone(),
                engine_version: ENGINE_VERSION.into(),
                hash_layout: lockstep_core::world::STATE_HASH_VERSION,
                rules: shared.config.rules.clone(),
            };
            let decide_after = c.ticks_in(c.hash_timeout);
            let recorder = match ReplayRecorder::with_seed(header, c.seed, decide_after) {
                Ok(r) => r,
                Err(e) => {
                    crate::log!("room {name}: no replay: {e}");
                    return None;
                }
            };
            let secs = SystemTime::now()
                .duration_since(SystemTime::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs());
            let safe: String = name
                .chars()
                .map(|c| {
                    if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                        c
                    } else {
                        '_'
                    }
                })
                .collect();
            let path = dir.join(format!("{safe}-{secs}-{seq}.replay"));
            // The file is created when the match starts: a lobby that
            // closes before leaves no empty replay behind.
            Some(Replay {
                recorder,
                path,
                file: None,
                started: false,
            })
        });
        let mut replay = replay;
        let verifier = shared.config.verifier.as_ref().and_then(|f| {
            let c = room.config();
            match f.new_verifier(&c.scene, c.scene_hash, c.seed) {
                Ok(v) => Some(v),
                Err(e) => {
                    // Checked at start-up: only a verifier that fails now
                    // and not then lands here.
                    tracing::warn!("room {name}: cannot verify: {e}; hashes are judged by majority after each tick's timeout");
                    None
                }
            }
        });
        let mut room = room;
        if verifier.as_ref().is_some_and(|v| v.snapshot().is_some()) {
            // Joiners start from the server's own state: no player can
            // hold a join back.
            room.offer_own_snapshots();
        }
        // A verifying room records its own hashes (`on_verified`); any
        // other records the hashes its room agreed on, never a majority of
        // strangers.
        if verifier.is_none()
            && let Some(r) = replay.as_mut()
        {
            r.recorder.follow_room();
        }
        crate::log!(
            "room {name}: opened{}",
            if verifier.is_some() {
                " (verifying: the server re-simulates every tick)"
            } else if shared.config.vote {
                " (not verifying: the token holders' majority judges hashes)"
            } else {
                " (not verifying: nobody is judged by hash, mismatches are only announced)"
            }
        );
        let feed = shared.spectate.as_ref().map(|v| {
            let c = room.config();
            v.open(&name, &c.scene, c.scene_hash, c.seed)
        });
        let seats = (0..room.config().max_players).map(|_| None).collect();
        Self {
            shared,
            seq,
            name,
            room,
            base: Instant::now(),
            seen: MatchPhase::Lobby,
            shutting_down: false,
            seats,
            players: Vec::new(),
            desyncs: Vec::new(),
            located: Vec::new(),
            bundles: Vec::new(),
            notice_at: None,
            desync_snapshot: None,
            forensics_bytes_down: 0,
            forensics_bytes_up: 0,
            verifier,
            verified_ticks: 0,
            verify_time: Duration::ZERO,
            counted: report::Counted::default(),
            lateness_us: Vec::new(),
            replay,
            feed,
        }
    }

    fn now(&self) -> Duration {
        self.base.elapsed()
    }

    async fn run(mut self, mut rx: mpsc::Receiver<RoomCmd>) {
        let mut shutdown = self.shared.shutdown.clone();
        let mut status = tokio::time::interval(Duration::from_secs(1));
        status.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        // The room's timers wake through the precise clock thread; tokio's
        // timer (1 ms, rounded up) stays as a backstop a millisecond later.
        let alarm = std::sync::Arc::new(tokio::sync::Notify::new());
        let mut registered: Option<Instant> = None;
        while self.room.phase() != MatchPhase::Done {
            let wake_at = self.room.poll_timeout().map(|d| self.base + d);
            if let Some(at) = wake_at
                && registered != Some(at)
            {
                self.shared.clock.wake_at(at, &alarm);
                registered = Some(at);
            }
            let backstop =
                wake_at.map(|at| tokio::time::Instant::from_std(at + Duration::from_millis(1)));
            tokio::select! {
                biased;
                _ = shutdown.wait_for(|s| *s), if !self.shutting_down => self.begin_shutdown(),
                cmd = rx.recv() => match cmd {
                    Some(cmd) => self.on_cmd(cmd),
                    None => break,
                },
                () = alarm.notified() => {
                    // A stale alarm (for an earlier wake-up) is harmless:
                    // the room finds nothing due.
                    if wake_at.is_some_and(|at| Instant::now() >= at) {
                        registered = None;
                    }
                    self.on_timer();
                }
                () = sleep_until(backstop.unwrap_or_else(tokio::time::Instant::now)), if backstop.is_some() => {
                    registered = None;
                    self.on_timer();
                }
                _ = status.tick() => self.on_status(),
            }
            self.pump();
        }
        self.finish();
        if let (Some(v), Some(f)) = (&self.shared.spectate, &self.feed) {
            v.close(f);
        }
        // Stop taking joins: a join racing the end is refused by the
        // closed channel.
        rx.close();
        while let Some(cmd) = rx.recv().await {
            if let RoomCmd::Join { peer, reply, .. } = cmd {
                let close = close_of(CloseReason::RoomClosed, "the match is over");
                send_close(&peer.writer, &close);
                let _ = reply.send(Err(close));
            }
        }
    }

    fn begin_shutdown(&mut self) {
        self.shutting_down = true;
        if self.room.phase() == MatchPhase::Running {
            crate::log!(
                "room {}: shutting down after tick {}",
                self.name,
                self.room.next_tick()
            );
        }
        let now = self.now();
        self.room.shut_down(now);
    }

    /// Tells the room the time, and measures how late each tick it closed
    /// was.
    fn on_timer(&mut self) {
        let now = self.now();
        let first = self.room.next_tick();
        self.room.handle_timeout(now);
        let Some(epoch) = self.room.started_at() else {
            return;
        };
        for t in first..self.room.next_tick() {
            let due = epoch + self.room.config().deadline_offset(t);
            let late = now.saturating_sub(due);
            self.shared.metrics.tick_closed(late);
            if self.lateness_us.len() < 1 << 17 {
                let us = u32::try_from(late.as_micros()).unwrap_or(u32::MAX);
                self.lateness_us.push(us);
            }
        }
    }

    /// The match started: the replay file is created and the start told.
    fn on_match_started(&mut self, players: usize) {
        if let Some(r) = self.replay.as_mut() {
            r.start(&self.name);
        }
        self.counted.running = true;
        self.shared
            .metrics
            .matches_running
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        crate::log!(
            "room {}: match started with {players} players at {} Hz, input delay {}",
            self.name,
            self.room.config().tick_rate,
            self.room.config().input_delay
        );
        let epoch = self.room.started_at().unwrap_or_default();
        self.shared.emit(ServerEvent::MatchStarted {
            room: self.name.clone(),
            epoch: self.base + epoch,
            tick_rate: self.room.config().tick_rate,
            players,
        });
    }

    fn seat(&mut self, id: PlayerId) -> Option<&mut Seat> {
        self.seats
            .get_mut(id.slot.index())
            .and_then(Option::as_mut)
            .filter(|s| s.id == id)
    }

    fn on_cmd(&mut self, cmd: RoomCmd) {
        let now = self.now();
        match cmd {
            RoomCmd::Join {
                join,
                ticket,
                token_refusal,
                peer,
                reply,
            } => {
                let known = self.room.knows_rejoin(&join);
                if known && let Some(old) = self.room.rejoin_replaces(&join) {
                    // The owner is back on a new connection: its old one
                    // is dropped (its seat stays reserved for it).
                    tracing::info!(
                        slot = old.slot.0,
                        "room {}: slot {}'s owner rejoins from a new connection; the old one is dropped",
                        self.name,
                        old.slot.0
                    );
                    self.room.disconnect(now, old);
                    self.pump();
                }
                let result = if self.shutting_down {
                    Err(close_of(
                        CloseReason::RoomClosed,
                        "the server is shutting down",
                    ))
                } else if matches!(self.room.phase(), MatchPhase::Finishing | MatchPhase::Done) {
                    Err(close_of(CloseReason::RoomClosed, "the match is over"))
                } else if let Some(close) = token_refusal.filter(|_| !known) {
                    Err(close)
                } else {
                    self.room
                        .join_with_ticket(now, &join, ticket.as_ref())
                        .map_err(|e| e.to_close())
                };
                match result {
                    Ok(id) => {
                        self.players.push(PlayerReport {
                            slot: id.slot,
                            name: join.player_name.clone(),
                            remote: peer.remote,
                            left: None,
                            rtt: None,
                            udp_bytes_down: 0,
                            udp_bytes_up: 0,
                            datagrams_down: 0,
                            max_datagram_down: 0,
                            datagrams_up: 0,
                            max_datagram_up: 0,
                            inputs_substituted: 0,
                            hash_reports: 0,
                            bad_snapshots: 0,
                            datagrams_dropped: 0,
                            connected_for: Duration::ZERO,
                        });
                        self.seats[id.slot.index()] = Some(Seat {
                            id,
                            peer,
                            report: self.players.len() - 1,
                            joined_at: Instant::now(),
                            closing: false,
                            last_udp_tx: 0,
                            last_udp_rx: 0,
                        });
                        let _ = reply.send(Ok(id));
                    }
                    Err(close) => {
                        send_close(&peer.writer, &close);
                        let _ = reply.send(Err(close));
                    }
                }
            }
            RoomCmd::Message {
                id,
                msg,
                len,
                channel,
            } => {
                let Some(seat) = self.seat(id) else { return };
                let report = seat.report;
                let hash = match &msg {
                    ClientMessage::HashReport(h) => {
                        // Body hashes only matter to the replay.
                        let bodies = self.replay.as_ref().and(h.body_hashes.clone());
                        Some((h.tick, h.hash, bodies))
                    }
                    _ => None,
                };
                if matches!(msg, ClientMessage::ProbeReply(_)) {
                    self.forensics_bytes_up += len as u64;
                }
                if channel == Channel::Datagram {
                    self.shared
                        .metrics
                        .datagrams_in
                        .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let p = &mut self.players[report];
                    p.datagrams_up += 1;
                    p.max_datagram_up = p.max_datagram_up.max(len);
                }
                match self.room.handle_message(now, id, msg) {
                    Ok(()) => {
                        if let (Some((tick, h, bodies)), Some(r)) = (hash, self.replay.as_mut()) {
                            r.recorder
                                .on_hash_with_bodies(id.slot, tick, h, bodies.as_deref());
                        }
                    }
                    Err(Rejection::UnknownPlayer(_)) => {}
                    Err(rejection) => self.expel(id, &rejection.to_string()),
                }
            }
            RoomCmd::Misbehaved { id, detail } => self.expel(id, &detail),
            RoomCmd::Throttled { id, dropped } => {
                if let Some(seat) = self.seat(id) {
                    let report = seat.report;
                    self.players[report].datagrams_dropped += dropped;
                    crate::log!(
                        "room {}: slot {}: {dropped} datagrams over the rate limit dropped",
                        self.name,
                        id.slot.0
                    );
                }
            }
            RoomCmd::Gone { id, why } => {
                if let Some(seat) = self.seat(id)
                    && !seat.closing
                {
                    crate::log!("room {}: slot {} disconnected: {why}", self.name, id.slot.0);
                    self.snapshot_stats();
                    self.room.disconnect(now, id);
                }
            }
        }
    }

    /// Removes a player for breaking the protocol, with a logged reason.
    fn expel(&mut self, id: PlayerId, detail: &str) {
        let now = self.now();
        let Some(seat) = self.seat(id) else { return };
        if seat.closing {
            return;
        }
        let remote = seat.peer.remote;
        let reason = format!(
            "room {}: slot {} closed for a protocol violation: {detail}",
            self.name, id.slot.0
        );
        self.shared.refused(remote, reason);
        self.snapshot_stats();
        self.room
            .kick(now, id, CloseReason::ProtocolViolation, detail);
    }

    /// Sends every queued transmit and handles every queued event.
    fn pump(&mut self) {
        while let Some(t) = self.room.poll_transmit() {
            self.transmit(t.to, t.message);
        }
        while let Some(event) = self.room.poll_event() {
            if let Some(r) = self.replay.as_mut() {
                r.recorder.on_event(&event);
            }
            self.on_event(event);
            // Leaving players may have queued nothing, but kicks did.
            while let Some(t) = self.room.poll_transmit() {
                self.transmit(t.to, t.message);
            }
        }
    }

    fn transmit(&mut self, to: PlayerId, message: ServerMessage) {
        let now = self.now();
        let name = self.name.clone();
        if self.seat(to).is_none() {
            return;
        }
        let bytes = match message.encode() {
            Ok(b) => b,
            Err(e) => {
                // The room never builds an out-of-bounds message.
                crate::log!("room {name}: cannot encode {}: {e}", message.kind());
                return;
            }
        };
        if matches!(
            message,
            ServerMessage::Probe(_) | ServerMessage::DesyncReport(_)
        ) {
            self.forensics_bytes_down += bytes.len() as u64;
        }
        let Some(seat) = self.seat(to) else { return };
        match message.channel() {
            Channel::Datagram => {
                let len = bytes.len();
                if seat
                    .peer
                    .connection
                    .send_datagram(Bytes::from(bytes))
                    .is_ok()
                {
                    let report = seat.report;
                    self.shared
                        .metrics
                        .datagrams_out
                        .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let p = &mut self.players[report];
                    p.datagrams_down += 1;
                    p.max_datagram_down = p.max_datagram_down.max(len);
                }
            }
            Channel::Reliable => {
                let close = match &message {
                    ServerMessage::Close(c) => Some(c.clone()),
                    _ => None,
                };
                let queued = seat.peer.writer.try_send(WriterCmd::Frame(bytes)).is_ok();
                if let Some(c) = close {
                    seat.closing = true;
                    let _ = seat.peer.writer.try_send(close_cmd(&c));
                } else if !queued && !seat.closing {
                    // The client does not read its stream.
                    seat.closing = true;
                    let remote = seat.peer.remote;
                    seat.peer.connection.close(
                        lockstep_net::close_code::OVERLOADED,
                        b"stream send queue full",
                    );
                    self.shared.refused(
                        remote,
                        format!("room {name}: slot {} does not read its stream", to.slot.0),
                    );
                    self.room.disconnect(now, to);
                }
            }
        }
    }

    /// Admits a player joining the running match if its snapshot restores
    /// and hashes to the agreed hash of `tick`; otherwise tells the room,
    /// which counts it against the giver (`from`) and asks another player.
    fn check_join_snapshot(
        &mut self,
        id: PlayerId,
        tick: u64,
        agreed_hash: u64,
        from: Option<lockstep_proto::Slot>,
        bytes: Vec<u8>,
    ) {
        let now = self.now();
        let giver = from.map_or_else(
            || "the server's own state".to_owned(),
            |s| format!("slot {}", s.0),
        );
        let why = match lockstep_core::World::restore(&bytes) {
            Ok(w) if w.state_hash() == agreed_hash => {
                crate::log!(
                    "room {}: slot {} joins the running match from the agreed state of tick {tick} ({} B, from {giver})",
                    self.name,
                    id.slot.0,
                    bytes.len()
                );
                self.room.admit(now, id, bytes);
                return;
            }
            Ok(w) => format!(
                "the snapshot of tick {tick} hashes to {:016x}, not the agreed {agreed_hash:016x}",
                w.state_hash()
            ),
            Err(e) => e.to_string(),
        };
        crate::log!(
            "room {}: the snapshot for slot {}'s join from {giver} is refused: {why}",
            self.name,
            id.slot.0
        );
        self.room.refuse_join(now, id, &why);
    }

    fn on_event(&mut self, event: RoomEvent) {
        match event {
            RoomEvent::PlayerJoined { id, name } => {
                let remote = self.seat(id).map(|s| s.peer.remote);
                tracing::info!(
                    slot = id.slot.0,
                    player = %name,
                    "room {}: {name:?} joined in slot {} from {}",
                    self.name,
                    id.slot.0,
                    remote.map_or_else(|| "?".into(), |r| r.to_string())
                );
            }
            RoomEvent::PlayerLeft {
                id,
                reason,
                from_tick,
            } => {
                if reason == LeaveReason::JoinRefused {
                    // Logged and counted as the refusal it is, not as a
                    // player leaving.
                    if let Some(remote) = self.seat(id).map(|s| s.peer.remote) {
                        self.shared.refused(
                            remote,
                            format!(
                                "room {}: slot {}: join to the running match refused: no agreed state",
                                self.name, id.slot.0
                            ),
                        );
                    }
                } else if reason == LeaveReason::RoomClosed {
                    tracing::info!(
                        slot = id.slot.0,
                        "room {}: slot {} played to the end (tick {from_tick})",
                        self.name,
                        id.slot.0
                    );
                } else {
                    tracing::info!(
                        slot = id.slot.0,
                        reason = ?reason,
                        "room {}: slot {} left ({reason:?}) from tick {from_tick}",
                        self.name,
                        id.slot.0
                    );
                }
                let index = id.slot.index();
                if reason == LeaveReason::RoomClosed
                    && let Some(stats) = self.room.departed_stats(id).copied()
                    && let Some(report) = self.seat(id).map(|s| s.report)
                {
                    // The room's final counters of a player it closed.
                    report::copy_stats(&mut self.players[report], &stats);
                }
                if let Some(seat) = self.seats[index].take() {
                    if !seat.closing {
                        // Left or lost: nothing more to tell it.
                        let _ = seat.peer.writer.try_send(WriterCmd::Close {
                            code: lockstep_net::close_code::NORMAL,
                            reason: format!("{reason:?}"),
                        });
                    }
                    let ended = matches!(self.seen, MatchPhase::Finishing | MatchPhase::Done)
                        || self.shutting_down && self.room.player_count() == 0;
                    let p = &mut self.players[seat.report];
                    fill_traffic(p, &seat);
                    if !ended {
                        p.left = Some((from_tick, format!("{reason:?}")));
                    }
                }
            }
            RoomEvent::TickClosed(bundle) => {
                let substituted = bundle.inputs.iter().filter(|p| p.substituted).count();
                self.shared
                    .metrics
                    .inputs_substituted
                    .fetch_add(substituted as u64, std::sync::atomic::Ordering::Relaxed);
                if let Some(f) = &self.feed {
                    f.push(&bundle);
                }
                if let Some(v) = self.verifier.as_mut() {
                    let started = Instant::now();
                    let hash = v.apply(&bundle);
                    self.verified_ticks += 1;
                    self.verify_time += started.elapsed();
                    let now = self.now();
                    self.room.verify_tick(now, bundle.tick, hash);
                    if let Some(r) = self.replay.as_mut() {
                        r.recorder.on_verified(bundle.tick, hash);
                    }
                }
            }
            RoomEvent::LateInput { .. } | RoomEvent::TickAgreed { .. } => {}
            RoomEvent::MatchStarted { players } => {
                self.seen = MatchPhase::Running;
                self.on_match_started(players);
            }
            RoomEvent::MatchEnding { reason } => {
                self.seen = MatchPhase::Finishing;
                crate::log!(
                    "room {}: {reason}; collecting the last hash reports",
                    self.name
                );
            }
            RoomEvent::MatchOver {
                reason: _,
                all_reported,
            } => {
                if self.seen == MatchPhase::Finishing && !all_reported {
                    crate::log!(
                        "room {}: closing without every final hash report",
                        self.name
                    );
                }
                self.seen = MatchPhase::Done;
            }
            RoomEvent::Desync(notice) => {
                let hashes: Vec<String> = notice
                    .hashes
                    .iter()
                    .map(|h| match h.hash {
                        Some(x) => format!("slot {}={x:016x}", h.slot.0),
                        None => format!("slot {}=none", h.slot.0),
                    })
                    .collect();
                let verdict = match &notice.verdict {
                    Verdict::Majority {
                        majority_hash,
                        wrong,
                    } => format!(
                        "majority {majority_hash:016x}, wrong: {:?}",
                        wrong.iter().map(|s| s.0).collect::<Vec<_>>()
                    ),
                    Verdict::Undecided => "undecided (no strict majority)".into(),
                    Verdict::Verified { hash, wrong } => format!(
                        "verified by the server {hash:016x}, wrong: {:?}",
                        wrong.iter().map(|s| s.0).collect::<Vec<_>>()
                    ),
                };
                // The room counted this notice already.
                let logged = self.room.stats().desync_notices.saturating_sub(1);
                if logged < bundle::LOGGED_DESYNCS as u64 {
                    crate::log!(
                        "room {}: DESYNC at tick {}: {}; verdict: {verdict}",
                        self.name,
                        notice.tick,
                        hashes.join(", ")
                    );
                } else if logged == bundle::LOGGED_DESYNCS as u64 {
                    crate::log!(
                        "room {}: DESYNC at tick {}; more than {logged} desyncs in this match: the rest are counted (lockstep_desyncs_total, the room's report), not logged",
                        self.name,
                        notice.tick
                    );
                }
                self.shared.emit(ServerEvent::Desync {
                    room: self.name.clone(),
                    notice: notice.clone(),
                });
                self.notice_at = Some(Instant::now());
                self.shared
                    .metrics
                    .desyncs
                    .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                if self.desyncs.len() < bundle::KEPT_DESYNCS {
                    self.desyncs.push(notice);
                }
            }
            RoomEvent::DesyncLocated(report) => self.on_desync_located(report),
            RoomEvent::JoinSnapshot {
                id,
                tick,
                agreed_hash,
                from,
                bytes,
            } => self.check_join_snapshot(id, tick, agreed_hash, from, bytes),
            RoomEvent::JoinFromOwnState {
                id,
                tick,
                agreed_hash,
            } => match self.verifier.as_ref().and_then(|v| v.snapshot()) {
                Some(bytes) => self.check_join_snapshot(id, tick, agreed_hash, None, bytes),
                None => {
                    let now = self.now();
                    self.room
                        .refuse_join(now, id, "the server has no snapshot of its own state");
                }
            },
            RoomEvent::DesyncSnapshot {
                tick,
                agreed_hash,
                from,
                bytes,
            } => self.on_desync_snapshot(tick, agreed_hash, from, bytes),
        }
    }
}
