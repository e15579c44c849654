//! The server side of lockstep as a state machine: seats, the tick clock,
//! input collection and substitution, bundle broadcast with redundancy, and
//! hash arbitration.
//!
//! Like `quinn-proto`, a [`Room`] owns no socket and reads no clock. The
//! caller feeds it decoded messages with [`Room::handle_message`], tells it
//! the time with [`Room::handle_timeout`] (at the latest by
//! [`Room::poll_timeout`]), and drains [`Room::poll_transmit`] and
//! [`Room::poll_event`] after every call. Every piece of per-tick state is in
//! a fixed-size ring, so memory does not grow with the length of a match.

mod arbiter;
mod config;
mod errors;
mod events;
mod history;
mod join;
mod judge;
mod lifecycle;
mod locate;
mod player;
mod timers;

use std::collections::VecDeque;
use std::time::Duration;

pub use config::{ConfigError, MIN_PROBE_REPLY_BYTES, MatchLifecycle, RoomConfig, Voting};
pub use errors::{AlreadyStarted, JoinError, Rejection};
pub use events::{LeaveReason, PlayerId, RoomEvent, RoomStats, Transmit};
pub use lifecycle::MatchPhase;
pub use player::PlayerStats;

use crate::codec::body_len;
use crate::limits::{MAX_BUNDLES_PER_DATAGRAM, MAX_DATAGRAM_BYTES, VERSION_HEADER_BYTES};
use crate::message::{
    BundleDatagram, ClientMessage, Close, CloseReason, InputDatagram, PlayerInput, ServerMessage,
    Slot, TickBundle,
};
use arbiter::{Arbiter, SlotMask, bit};
use errors::close;
use history::{FellBehind, History};
use join::JoinFetch;
use lifecycle::Lifecycle;
use locate::Locator;
use player::Player;

/// A lockstep room: see the module documentation for how to drive it.
///
/// One player joins, sends its input for tick 0, and receives tick 0's
/// bundle once the tick closes; the network is the two `while` loops:
///
/// ```
/// use std::time::Duration;
/// use lockstep_proto::{ClientMessage, Room, RoomConfig, ServerMessage, Session};
///
/// let mut room = Room::new(RoomConfig::new("demo", b"scene".to_vec(), 0x5ce9e))?;
/// let now = Duration::ZERO;
/// let ClientMessage::Join(join) = Session::join_message("demo", "ada") else { unreachable!() };
/// let ada = room.join(now, &join)?;
/// let Some(ServerMessage::Welcome(welcome)) = room.poll_transmit().map(|t| t.message) else {
///     unreachable!()
/// };
/// let mut session = Session::new(&welcome)?;
///
/// assert_eq!(session.submit_input(b"jump".to_vec())?, 0); // for tick 0
/// while let Some(m) = session.poll_transmit() {
///     room.handle_message(now, ada, ClientMessage::decode(&m.encode()?)?)?;
/// }
/// assert!(room.all_ready());
/// room.start(now)?;
///
/// // One tick period (1/60 s) later, tick 0 closes and its bundle goes out.
/// let now = now + Duration::from_millis(17);
/// room.handle_timeout(now);
/// while let Some(t) = room.poll_transmit() {
///     session.handle_message(now, ServerMessage::decode(&t.message.encode()?)?)?;
/// }
/// let bundle = session.poll_bundle().unwrap();
/// assert_eq!(bundle.tick, 0);
/// assert_eq!(bundle.inputs[0].input, b"jump");
/// assert!(!bundle.inputs[0].substituted);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct Room {
    config: RoomConfig,
    players: Vec<Option<Player>>,
    generations: Vec<u32>,
    /// Time of `start`; tick `t` closes at `epoch + config.deadline_offset(t)`.
    epoch: Option<Duration>,
    next_tick: u64,
    history: History,
    arbiter: Arbiter,
    transmits: VecDeque<Transmit>,
    events: VecDeque<RoomEvent>,
    ping_nonce: u64,
    stats: RoomStats,
    locator: Locator,
    /// The last compared tick whose hashes agreed, with that hash.
    last_agreed: Option<(u64, u64)>,
    /// Per seat: the token key and deadline of a dropped player's
    /// reservation for a rejoin.
    reserved: Vec<Option<(u64, Duration)>>,
    /// The player joining the running match, while its snapshot comes.
    joining: Option<JoinFetch>,
    /// The caller gives joiners its own verified state
    /// ([`Room::offer_own_snapshots`]).
    own_snapshots: bool,
    /// The newest tick the caller verified, with its hash.
    last_verified: Option<(u64, u64)>,
    /// The key rejoin credentials are signed with
    /// ([`Room::set_rejoin_key`]); without it none are given.
    rejoin_key: Option<[u8; 32]>,
    /// The keys of the join tokens that seated a player in this match:
    /// each seats once.
    used_tokens: std::collections::BTreeSet<u64>,
    /// Per seat: the key of the token that first took it in this match
    /// (its owner, who may come back with its rejoin credential).
    owners: Vec<Option<u64>>,
    /// The match's lifecycle: lobby, running, finishing, done.
    lifecycle: Lifecycle,
    /// Per seat: the last player that left it, with its final counters.
    departed: Vec<Option<(PlayerId, PlayerStats)>>,
}

impl Room {
    /// Creates an empty room in its lobby: players may join, no tick closes
    /// until [`Room::start`].
    ///
    /// # Errors
    /// [`ConfigError`] if `config` fails [`RoomConfig::validate`].
    pub fn new(config: RoomConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        let seats = usize::from(config.max_players);
        let mut arbiter = Arbiter::new(config.hash_window_ticks as usize, config.hash_timeout);
        if config.verify {
            arbiter.set_verifying();
        }
        arbiter.set_voting(config.voting);
        let mut locator = Locator::new(config.locate_timeout);
        locator.max_bodies = config.max_probe_bodies;
        Ok(Self {
            lifecycle: Lifecycle::new(config.lifecycle),
            departed: vec![None; seats],
            locator,
            last_agreed: None,
            reserved: vec![None; seats],
            joining: None,
            own_snapshots: false,
            last_verified: None,
            rejoin_key: None,
            used_tokens: std::collections::BTreeSet::new(),
            owners: vec![None; seats],
            history: History::new(config.history_ticks as usize),
            arbiter,
            players: (0..seats).map(|_| None).collect(),
            generations: vec![0; seats],
            config,
            epoch: None,
            next_tick: 0,
            transmits: VecDeque::new(),
            events: VecDeque::new(),
            ping_nonce: 0,
            stats: RoomStats::default(),
        })
    }

    /// The caller's own hash of closed tick `tick` (rooms configured with
    /// [`RoomConfig::verify`]): reports are judged against it. Give it as
    /// soon as the tick closes ([`RoomEvent::TickClosed`]); a tick still
    /// without it when its hash timeout passes is judged by majority.
    pub fn verify_tick(&mut self, now: Duration, tick: u64, hash: u64) {
        if self.last_verified.is_none_or(|(t, _)| t < tick) {
            self.last_verified = Some((tick, hash));
        }
        self.arbiter.verify(tick, hash);
        self.run_arbiter(now);
        self.step_lifecycle(now);
    }

    /// Sets [`RoomConfig::max_probe_bodies`] from now on (e.g. the body
    /// count of the caller's own world, with some slack).
    pub fn set_max_probe_bodies(&mut self, bodies: u32) {
        self.config.max_probe_bodies = bodies;
        self.locator.max_bodies = bodies;
    }

    /// The caller re-simulates every tick ([`RoomConfig::verify`]) and can
    /// give the state after the newest verified tick as a snapshot when it
    /// handles [`RoomEvent::JoinFromOwnState`]: players joining the running
    /// match then start from the caller's own state, so no player (silent,
    /// sparse or lying) is asked for it or can hold a join back.
    pub fn offer_own_snapshots(&mut self) {
        self.own_snapshots = true;
    }

    /// Whether every seated player (at least one) has already sent its input
    /// for the first tick. A server that calls [`Room::start`] only then
    /// does not substitute anyone's first inputs because their welcome was
    /// still in flight.
    pub fn all_ready(&self) -> bool {
        let mut seated = self.players.iter().flatten().peekable();
        seated.peek().is_some() && seated.all(|p| p.pending.contains(self.next_tick))
    }

    /// The seated players that have not sent their input for the first
    /// tick yet, in slot order: whom a server drops when its lobby waited
    /// long enough, so one player that never sends it cannot keep a match
    /// from starting.
    pub fn unready_players(&self) -> Vec<PlayerId> {
        (0..self.players.len())
            .filter(|&i| {
                self.players[i]
                    .as_ref()
                    .is_some_and(|p| !p.pending.contains(self.next_tick))
            })
            .map(|i| self.id_of(i))
            .collect()
    }

    /// Starts the tick clock: tick 0 closes one tick period after `now`.
    ///
    /// # Errors
    /// [`AlreadyStarted`] on a second call.
    pub fn start(&mut self, now: Duration) -> Result<(), AlreadyStarted> {
        if self.epoch.is_some() {
            return Err(AlreadyStarted);
        }
        self.epoch = Some(now);
        self.started();
        Ok(())
    }

    /// Applies one decoded message from a seated player. Any message counts
    /// as a sign of life, even a refused one.
    ///
    /// # Errors
    /// [`Rejection`] saying why the message was refused; nothing of it was
    /// applied.
    pub fn handle_message(
        &mut self,
        now: Duration,
        from: PlayerId,
        message: ClientMessage,
    ) -> Result<(), Rejection> {
        let handled = self.apply_message(now, from, message);
        self.step_lifecycle(now);
        handled
    }

    fn apply_message(
        &mut self,
        now: Duration,
        from: PlayerId,
        message: ClientMessage,
    ) -> Result<(), Rejection> {
        let player = self.player_mut(from)?;
        player.last_heard = player.last_heard.max(now);
        match message {
            ClientMessage::Join(_) => Err(Rejection::UnexpectedMessage("join")),
            ClientMessage::Input(d) => self.on_input(from, d),
            ClientMessage::HashReport(h) => {
                let tick = h.tick;
                self.on_hash(now, from, h)?;
                if let Ok(p) = self.player_mut(from) {
                    p.last_hash_accepted = p.last_hash_accepted.max(Some(tick));
                }
                Ok(())
            }
            ClientMessage::Pong(p) => {
                if let Some((nonce, sent)) = player.ping
                    && nonce == p.nonce
                {
                    player.rtt_sample(now.saturating_sub(sent));
                    player.ping = None;
                }
                Ok(())
            }
            ClientMessage::Leave => {
                self.remove(now, from, LeaveReason::Left, None);
                Ok(())
            }
            ClientMessage::ProbeReply(r) => {
                // One reply over the byte budget ends the sender's part
                // unread.
                let over = body_len(&r) > self.config.max_probe_reply_bytes as usize;
                if self.is_join_reply(from.slot, &r) {
                    if over {
                        self.retry_join(now, "a snapshot piece over the probe reply budget", true);
                    } else {
                        self.on_join_reply(now, r);
                    }
                } else {
                    let mut out = Vec::new();
                    if over {
                        self.locator.reply_too_large(from.slot, r.tick, &mut out);
                    } else {
                        self.locator.on_reply(from.slot, r, &mut out);
                    }
                    self.apply_search(out);
                }
                Ok(())
            }
        }
    }

    /// The caller lost the player's connection.
    pub fn disconnect(&mut self, now: Duration, id: PlayerId) {
        self.remove(now, id, LeaveReason::Disconnected, None);
        self.step_lifecycle(now);
    }

    /// Removes a player, queuing a [`Close`] with `reason` and `detail`
    /// (e.g. after a [`Rejection`]).
    pub fn kick(&mut self, now: Duration, id: PlayerId, reason: CloseReason, detail: &str) {
        let leave = if reason == CloseReason::RoomClosed {
            LeaveReason::RoomClosed
        } else {
            LeaveReason::Kicked
        };
        let c = close(reason, detail.to_owned());
        self.remove(now, id, leave, Some(c));
        self.step_lifecycle(now);
    }

    /// Next message to send, in the order they were produced.
    pub fn poll_transmit(&mut self) -> Option<Transmit> {
        self.transmits.pop_front()
    }

    /// Next event. Drain after every call; events queue until taken.
    pub fn poll_event(&mut self) -> Option<RoomEvent> {
        self.events.pop_front()
    }

    /// The configuration the room runs with.
    pub fn config(&self) -> &RoomConfig {
        &self.config
    }

    /// Whether [`Room::start`] was called.
    pub fn is_started(&self) -> bool {
        self.epoch.is_some()
    }

    /// Next tick to close; every tick below it is closed.
    pub fn next_tick(&self) -> u64 {
        self.next_tick
    }

    /// Seated players and their names, ascending by slot.
    pub fn players(&self) -> impl Iterator<Item = (PlayerId, &str)> + '_ {
        self.players
            .iter()
            .enumerate()
            .filter_map(|(i, p)| p.as_ref().map(|p| (self.id_of(i), p.name.as_str())))
    }

    /// Number of seated players.
    pub fn player_count(&self) -> usize {
        self.players.iter().flatten().count()
    }

    /// Counters of a seated player.
    pub fn player_stats(&self, id: PlayerId) -> Option<&PlayerStats> {
        self.player(id).map(|p| &p.stats)
    }

    /// The final counters of a player that left (until another player
    /// leaves its seat).
    pub fn departed_stats(&self, id: PlayerId) -> Option<&PlayerStats> {
        match self.departed.get(id.slot.index()) {
            Some(Some((left, stats))) if *left == id => Some(stats),
            _ => None,
        }
    }

    /// Room-wide counters.
    pub fn stats(&self) -> &RoomStats {
        &self.stats
    }

    /// The bundle of a closed tick, while it is still in the history.
    pub fn bundle(&self, tick: u64) -> Option<&TickBundle> {
        self.history.get(tick)
    }

    // -- internals ----------------------------------------------------------

    fn id_of(&self, index: usize) -> PlayerId {
        PlayerId {
            slot: Slot(index as u8),
            generation: self.generations[index],
        }
    }

    fn player(&self, id: PlayerId) -> Option<&Player> {
        let index = id.slot.index();
        match self.players.get(index) {
            Some(Some(p)) if self.generations[index] == id.generation => Some(p),
            _ => None,
        }
    }

    fn player_mut(&mut self, id: PlayerId) -> Result<&mut Player, Rejection> {
        let index = id.slot.index();
        match self.players.get_mut(index) {
            Some(Some(p)) if self.generations[index] == id.generation => Ok(p),
            _ => Err(Rejection::UnknownPlayer(id)),
        }
    }

    fn present_mask(&self) -> SlotMask {
        (0..self.players.len())
            .filter(|&i| self.players[i].is_some())
            .fold(0, |m, i| m | bit(Slot(i as u8)))
    }

    fn remove(&mut self, now: Duration, id: PlayerId, reason: LeaveReason, close: Option<Close>) {
        if self.player(id).is_none() {
            return;
        }
        let index = id.slot.index();
        // Who may come back to the seat: not a player removed for cause.
        let keeps_seat = !matches!(
            reason,
            LeaveReason::Kicked
                | LeaveReason::RoomClosed
                | LeaveReason::Diverged
                | LeaveReason::NoHashReports
                | LeaveReason::JoinRefused
        );
        if let Some(p) = &self.players[index]
            && let Some(key) = p.ticket
            && self.epoch.is_some()
            && p.admitted
            && keeps_seat
        {
            self.reserved[index] = Some((key, now.saturating_add(self.config.rejoin_grace)));
        }
        if let Some(p) = self.players[index].take() {
            self.departed[index] = Some((id, p.stats));
        }
        self.generations[index] = self.generations[index].wrapping_add(1);
        if let Some(c) = close {
            self.transmits.push_back(Transmit {
                to: id,
                message: ServerMessage::Close(c),
            });
        }
        self.events.push_back(RoomEvent::PlayerLeft {
            id,
            reason,
            from_tick: self.next_tick,
        });
        if let Some(j) = &self.joining {
            if j.id == id {
                // A rejoiner lost while its snapshot came keeps its seat's
                // reservation.
                if let Some(r) = self.joining.take().and_then(|j| j.reservation)
                    && keeps_seat
                {
                    self.reserved[index] = Some(r);
                }
            } else if j.source == Some(id.slot) {
                self.retry_join(now, "the player giving the snapshot left", false);
            }
        }
        let mut out = Vec::new();
        self.locator.player_left(id.slot, &mut out);
        self.apply_search(out);
        // Ticks that were only waiting for this player's hash can be compared.
        self.run_arbiter(now);
    }

    fn on_input(&mut self, from: PlayerId, d: InputDatagram) -> Result<(), Rejection> {
        if d.slot != from.slot {
            return Err(Rejection::WrongSlot {
                claimed: d.slot,
                actual: from.slot,
            });
        }
        if let Some(ack) = d.ack_bundle
            && ack >= self.next_tick
        {
            return Err(Rejection::AckFromFuture {
                ack,
                next_tick: self.next_tick,
            });
        }
        let lowest = self.next_tick;
        let highest = lowest + u64::from(self.config.input_window) - 1;
        let max = self.config.max_input_bytes;
        let index = from.slot.index();
        let Some(player) = self.players[index].as_mut() else {
            return Err(Rejection::UnknownPlayer(from));
        };
        // Validate everything before applying anything.
        for (i, input) in d.inputs.iter().enumerate() {
            let tick = d.first_tick.saturating_add(i as u64);
            if tick > highest {
                return Err(Rejection::TickOutOfWindow {
                    tick,
                    lowest,
                    highest,
                });
            }
            if input.len() > max {
                return Err(Rejection::InputTooLarge {
                    tick,
                    len: input.len(),
                    max,
                });
            }
            let conflict = if tick >= lowest {
                player.pending.get(tick).is_some_and(|prev| prev != input)
            } else {
                self.history.get(tick).is_some_and(|b| {
                    b.inputs
                        .iter()
                        .any(|p| p.slot == from.slot && !p.substituted && p.input != *input)
                })
            };
            if conflict {
                return Err(Rejection::InputConflict { tick });
            }
        }
        player.bundle_ack = player.bundle_ack.max(d.ack_bundle);
        for (tick, input) in (d.first_tick..).zip(d.inputs) {
            if tick < player.start_tick {
                player.stats.redundant_inputs += 1;
            } else if tick >= lowest {
                if player.pending.contains(tick) {
                    player.stats.redundant_inputs += 1;
                } else {
                    player.pending.insert(tick, input);
                }
            } else if self.history.mark_late(tick, from.slot) {
                player.stats.late_inputs += 1;
                self.events
                    .push_back(RoomEvent::LateInput { id: from, tick });
            } else {
                player.stats.redundant_inputs += 1;
            }
        }
        Ok(())
    }

    /// Closes `next_tick`: each present player's input, or their last input
    /// marked as substituted.
    fn close_tick(&mut self, now: Duration) {
        let tick = self.next_tick;
        let mut inputs = Vec::with_capacity(self.players.len());
        let mut expected: SlotMask = 0;
        // Determinism: inputs are listed in ascending slot order.
        for (index, p) in self.players.iter_mut().enumerate() {
            let Some(p) = p else { continue };
            if p.start_tick > tick || !p.admitted {
                continue;
            }
            let slot = Slot(index as u8);
            let substituted = match p.pending.remove(tick) {
                Some(input) => {
                    p.last_input = input;
                    p.stats.inputs_on_time += 1;
                    false
                }
                None => {
                    p.stats.inputs_substituted += 1;
                    true
                }
            };
            expected |= bit(slot);
            inputs.push(PlayerInput {
                slot,
                input: p.last_input.clone(),
                substituted,
            });
        }
        let bundle = TickBundle { tick, inputs };
        self.history.push(bundle.clone());
        self.events.push_back(RoomEvent::TickClosed(bundle));
        self.next_tick += 1;
        self.stats.ticks_closed += 1;
        self.arbiter.voters = self.token_holders();
        if let Some((t, c)) = self.arbiter.open(tick, now, expected) {
            self.apply_comparison(now, t, c);
        }
    }

    /// The last tick for which the room needs no more input from `p`: every
    /// closed tick, then every open tick received contiguously.
    fn input_ack(&self, p: &Player) -> Option<u64> {
        let mut t = self.next_tick.max(p.start_tick);
        while p.pending.contains(t) {
            t += 1;
        }
        t.checked_sub(1)
    }

    fn send_bundles(&mut self, now: Duration) {
        for index in 0..self.players.len() {
            let Some(p) = self.players[index].as_ref().filter(|p| p.admitted) else {
                continue;
            };
            let from = p
                .bundle_ack
                .map_or(p.first_bundle, |a| (a + 1).max(p.first_bundle));
            let ack_input = self.input_ack(p);
            let empty = ServerMessage::Bundles(BundleDatagram {
                ack_input,
                bundles: Vec::new(),
            });
            // The bundle count prefix stays one byte for up to 250 entries,
            // so the empty message's size is the exact header size.
            let header = VERSION_HEADER_BYTES + body_len(&empty);
            let budget = MAX_DATAGRAM_BYTES.saturating_sub(header);
            let id = self.id_of(index);
            match self.history.select(from, budget, MAX_BUNDLES_PER_DATAGRAM) {
                Ok(bundles) => self.transmits.push_back(Transmit {
                    to: id,
                    message: ServerMessage::Bundles(BundleDatagram { ack_input, bundles }),
                }),
                Err(FellBehind) => {
                    let detail = format!("bundle {from} is no longer in the history");
                    let c = close(CloseReason::FellBehind, detail);
                    self.remove(now, id, LeaveReason::FellBehind, Some(c));
                }
            }
        }
    }
}
