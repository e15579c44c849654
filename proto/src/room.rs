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
use crate::limits::{
    MAX_BUNDLES_PER_DATAGRAM, MAX_DATAGRAM_BYTES, PROTOCOL_VERSION, VERSION_HEADER_BYTES,
};
use crate::message::{
    BundleDatagram, ClientMessage, Close, CloseReason, HashReport, InputDatagram, Join,
    PlayerInput, ServerMessage, Slot, TickBundle, Welcome,
};
use arbiter::{Arbiter, Comparison, Recorded, SlotMask, bit};
use errors::close;
use history::{FellBehind, History};
use lifecycle::Lifecycle;
use locate::{Locator, Output};
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

/// The snapshot a player joining a running match waits for.
#[derive(Debug)]
struct JoinFetch {
    id: PlayerId,
    tick: u64,
    hash: u64,
    /// Who gives the snapshot: a player, or (`None`) the caller's own
    /// re-simulation ([`Room::offer_own_snapshots`]).
    source: Option<Slot>,
    /// The players asked so far, and those not holding the tick's hash.
    tried: SlotMask,
    /// The seat's rejoin reservation the join took, given back if it fails.
    reservation: Option<(u64, Duration)>,
    total: Option<u32>,
    bytes: Vec<u8>,
    deadline: Duration,
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

    /// Sets the secret key the room's rejoin credentials are made with
    /// (32 random bytes, e.g. from the operating system, never shown to
    /// anyone). From then on a player seated with a join token gets a
    /// credential in its welcome ([`Welcome::rejoin`]) that takes it back
    /// to its seat ([`Join::rejoin`]); its token seats nobody again in this
    /// match. Without a key no credential is given, and a used token still
    /// seats nobody again.
    pub fn set_rejoin_key(&mut self, key: [u8; 32]) {
        self.rejoin_key = Some(key);
    }

    /// The credential of seat `index` owned by the token of key `key`:
    /// HMAC-SHA256 under the room's rejoin key of the room's name, the
    /// seat and the token's key.
    fn credential(&self, index: usize, key: u64) -> Option<crate::message::RejoinCredential> {
        let mac = self.credential_mac(index, key)?;
        let mut out = [0u8; 32];
        out.copy_from_slice(&hmac::Mac::finalize(mac).into_bytes());
        Some(crate::message::RejoinCredential(out))
    }

    fn credential_mac(&self, index: usize, key: u64) -> Option<hmac::Hmac<sha2::Sha256>> {
        use hmac::Mac;
        let mut mac = hmac::Hmac::<sha2::Sha256>::new_from_slice(self.rejoin_key.as_ref()?).ok()?;
        mac.update(b"lockstep rejoin credential\0");
        mac.update(&[self.config.name.len() as u8]);
        mac.update(self.config.name.as_bytes());
        mac.update(&[index as u8]);
        mac.update(&key.to_le_bytes());
        Some(mac)
    }

    /// The seat a join's rejoin credential belongs to, and its owner's
    /// token key (checked in constant time against every owned seat).
    fn credential_seat(&self, join: &Join) -> Option<(usize, u64)> {
        let c = join.rejoin.as_ref()?;
        (0..self.owners.len()).find_map(|i| {
            let key = self.owners[i]?;
            let mac = self.credential_mac(i, key)?;
            hmac::Mac::verify_slice(mac, &c.0).ok().map(|()| (i, key))
        })
    }

    /// Whether `join` carries a rejoin credential this room gave: the
    /// caller then lets the room judge it even if its token no longer
    /// verifies (e.g. expired since the first join).
    pub fn knows_rejoin(&self, join: &Join) -> bool {
        self.credential_seat(join).is_some()
    }

    /// The player still seated in the seat `join`'s rejoin credential
    /// belongs to, by the same token (its owner's old connection, not yet
    /// known to be gone). The caller disconnects it
    /// ([`Room::disconnect`]) before the join, so the owner's new
    /// connection takes the seat back at once.
    pub fn rejoin_replaces(&self, join: &Join) -> Option<PlayerId> {
        let (index, key) = self.credential_seat(join)?;
        self.players[index]
            .as_ref()
            .filter(|p| p.ticket == Some(key))
            .map(|_| self.id_of(index))
    }

    /// Seats a player in the lowest free slot and queues their
    /// [`Welcome`]. Once the match runs, a join is refused unless the room
    /// allows late joins ([`RoomConfig::late_join`]) or it is a rejoin (see
    /// [`Room::join_with_ticket`]); such a player waits for the agreed
    /// snapshot ([`RoomEvent::JoinSnapshot`], then [`Room::admit`]).
    ///
    /// # Errors
    /// [`JoinError`]; the caller sends its [`JoinError::to_close`].
    pub fn join(&mut self, now: Duration, join: &Join) -> Result<PlayerId, JoinError> {
        self.join_with_ticket(now, join, None)
    }

    /// [`Room::join`] for a join whose token the caller verified
    /// ([`token::verify`](crate::token::verify)): a seat token seats the
    /// player in exactly that seat, and a token seats one player once per
    /// match, so votes are counted per granted seat and a copy of a token
    /// cannot take its owner's seat. A join carrying the rejoin credential
    /// of its seat ([`Join::rejoin`], see [`Room::set_rejoin_key`]) takes
    /// the seat back, with or without its token: in the lobby if the seat
    /// is free, in the running match while the seat is reserved for it
    /// ([`RoomConfig::rejoin_grace`]).
    ///
    /// # Errors
    /// As [`Room::join`], and [`JoinError::SeatTaken`],
    /// [`JoinError::NoSuchSeat`], [`JoinError::TokenUsed`],
    /// [`JoinError::NotReserved`].
    pub fn join_with_ticket(
        &mut self,
        now: Duration,
        join: &Join,
        ticket: Option<&crate::token::Ticket>,
    ) -> Result<PlayerId, JoinError> {
        let joined = self.seat_player(now, join, ticket);
        if joined.is_ok() {
            self.joined(now);
        }
        self.step_lifecycle(now);
        joined
    }

    fn seat_player(
        &mut self,
        now: Duration,
        join: &Join,
        ticket: Option<&crate::token::Ticket>,
    ) -> Result<PlayerId, JoinError> {
        if join.protocol_version != PROTOCOL_VERSION {
            return Err(JoinError::VersionMismatch {
                client: join.protocol_version,
                server: PROTOCOL_VERSION,
            });
        }
        if join.room != self.config.name {
            return Err(JoinError::WrongRoom(join.room.clone()));
        }
        // Who the join is: the owner of a seat coming back with its
        // credential, or the holder of a token (used once per match).
        let by_credential = self.credential_seat(join);
        let (key, seat_wanted) = match by_credential {
            Some((index, key)) => (Some(key), Some(Slot(index as u8))),
            None => match ticket {
                Some(t) if self.used_tokens.contains(&t.key) => {
                    return Err(JoinError::TokenUsed);
                }
                Some(t) => (Some(t.key), t.claims.seat),
                None => (None, None),
            },
        };
        let running = self.epoch.is_some();
        // A seat still reserved for its owner's rejoin.
        let reserved_for = |i: usize| {
            self.reserved
                .get(i)
                .copied()
                .flatten()
                .filter(|&(_, until)| now <= until)
                .map(|(k, _)| k)
        };
        if let Some(seat) = seat_wanted {
            match self.players.get(seat.index()) {
                None => return Err(JoinError::NoSuchSeat(seat.0)),
                Some(Some(_)) => return Err(JoinError::SeatTaken(seat.0)),
                Some(None) => {}
            }
            if running && reserved_for(seat.index()).is_some_and(|k| Some(k) != key) {
                return Err(JoinError::SeatTaken(seat.0));
            }
        }
        let source = if running {
            let rejoin = seat_wanted.is_some_and(|s| {
                by_credential.is_some() && reserved_for(s.index()).is_some_and(|k| Some(k) == key)
            });
            if !(self.config.late_join || rejoin) {
                return match (by_credential, seat_wanted) {
                    (Some(_), Some(s)) => Err(JoinError::NotReserved(s.0)),
                    _ => Err(JoinError::MatchInProgress),
                };
            }
            if self.joining.is_some() {
                return Err(JoinError::JoinBusy);
            }
            let own = self.last_verified.filter(|&(t, _)| {
                self.own_snapshots && self.config.verify && t + 1 == self.next_tick
            });
            match own {
                // The caller's own state of the newest tick.
                Some((tick, hash)) => Some((tick, hash, None::<(Slot, SlotMask)>)),
                None => {
                    // The newest tick the players in good standing agree
                    // on (they hold its snapshot: the last 32 ticks), not
                    // only the last tick compared, which a silent player
                    // holds 2 s back.
                    self.arbiter.voters = self.token_holders();
                    let good = self.good_standing();
                    let (tick, hash, givers) = self
                        .arbiter
                        .fresh_agreed(good, 32)
                        .or_else(|| self.last_agreed.map(|(t, h)| (t, h, good)))
                        .ok_or(JoinError::NoAgreedState)?;
                    let source = self.pick_giver(!givers).ok_or(JoinError::NoAgreedState)?;
                    Some((tick, hash, Some((source, givers))))
                }
            }
        } else {
            None
        };
        let index = match seat_wanted {
            Some(seat) => seat.index(),
            None => {
                // Seats reserved for a rejoin are not given to others.
                let free = |i: usize| self.players[i].is_none() && reserved_for(i).is_none();
                let Some(index) = (0..self.players.len()).find(|&i| free(i)) else {
                    return Err(JoinError::RoomFull(self.config.max_players));
                };
                index
            }
        };
        if let Some(k) = key {
            self.used_tokens.insert(k);
            self.owners[index] = Some(k);
        }
        let reservation = self.reserved[index].take();
        // The index is below max_players, a u8.
        let slot = Slot(index as u8);
        let id = PlayerId {
            slot,
            generation: self.generations[index],
        };
        let window = usize::from(self.config.input_window);
        let mut player = Player::new(join.player_name.clone(), self.next_tick, window, now);
        player.ticket = key;
        if let Some((tick, hash, source)) = source {
            // Joining the running match: seated, but in no bundle until the
            // agreed snapshot came and was checked (`admit`).
            player.admitted = false;
            self.players[index] = Some(player);
            let deadline =
                now.saturating_add(self.config.locate_timeout.max(Duration::from_secs(2)));
            // Only the players holding the tick's hash may give it.
            let (source, tried) = match source {
                Some((s, givers)) => (Some(s), !givers | bit(s)),
                None => (None, 0),
            };
            self.joining = Some(JoinFetch {
                id,
                tick,
                hash,
                source,
                tried,
                reservation,
                total: None,
                bytes: Vec::new(),
                deadline,
            });
            match source {
                Some(_) => self.probe_join_snapshot(0),
                None => self.events.push_back(RoomEvent::JoinFromOwnState {
                    id,
                    tick,
                    agreed_hash: hash,
                }),
            }
            return Ok(id);
        }
        self.players[index] = Some(player);
        self.transmits.push_back(Transmit {
            to: id,
            message: ServerMessage::Welcome(Welcome {
                slot,
                tick_rate: self.config.tick_rate,
                input_delay: self.config.input_delay,
                input_window: self.config.input_window,
                // validate() keeps max_input_bytes within MAX_INPUT_BYTES (64).
                max_input_bytes: self.config.max_input_bytes as u8,
                start_tick: self.next_tick,
                scene_hash: self.config.scene_hash,
                scene: self.config.scene.clone(),
                resume: None,
                rules: self.config.rules.clone(),
                seed: self.config.seed,
                rejoin: key.and_then(|k| self.credential(index, k)),
            }),
        });
        self.events.push_back(RoomEvent::PlayerJoined {
            id,
            name: join.player_name.clone(),
        });
        Ok(id)
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

    fn on_hash(&mut self, now: Duration, from: PlayerId, h: HashReport) -> Result<(), Rejection> {
        if h.tick >= self.next_tick {
            return Err(Rejection::HashForUnclosedTick {
                tick: h.tick,
                next_tick: self.next_tick,
            });
        }
        match self.arbiter.record(h.tick, from.slot, h.hash) {
            Recorded::Stored => {
                if let Ok(p) = self.player_mut(from) {
                    p.stats.hash_reports += 1;
                    p.last_report = p.last_report.max(Some(h.tick));
                }
                self.run_arbiter(now);
                Ok(())
            }
            Recorded::Stale => Ok(()),
            Recorded::NotExpected => Err(Rejection::HashForTickNotPlayed { tick: h.tick }),
            Recorded::Conflict => Err(Rejection::HashConflict { tick: h.tick }),
        }
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

    /// The players seated with a join token (the voters under
    /// [`Voting::TokenHolders`]).
    fn token_holders(&self) -> SlotMask {
        (0..self.players.len())
            .filter(|&i| self.players[i].as_ref().is_some_and(|p| p.ticket.is_some()))
            .fold(0, |m, i| m | bit(Slot(i as u8)))
    }

    fn run_arbiter(&mut self, now: Duration) {
        self.arbiter.voters = self.token_holders();
        let connected = self.present_mask();
        for (tick, c) in self.arbiter.finalize(now, connected) {
            self.apply_comparison(now, tick, c);
        }
    }

    fn apply_comparison(&mut self, now: Duration, tick: u64, c: Comparison) {
        self.stats.ticks_compared += 1;
        if c.mismatch {
            self.stats.mismatched_ticks += 1;
        } else if let Some(h) = c.agreed {
            self.last_agreed = Some((tick, h));
        }
        if let Some(hash) = c.agreed {
            self.events.push_back(RoomEvent::TickAgreed { tick, hash });
        }
        // Hashes missing within the sliding report window, and ticks judged
        // wrong in a row among the ticks the player reported.
        let mut drop: Vec<(PlayerId, CloseReason, String)> = Vec::new();
        for index in 0..self.players.len() {
            let id = self.id_of(index);
            let Some(p) = &mut self.players[index] else {
                continue;
            };
            let b = bit(Slot(index as u8));
            let expected = (c.missing | c.reported) & b != 0;
            if c.missing & b != 0 {
                p.stats.missing_hash_reports += 1;
                p.missing_streak += 1;
            } else if c.reported & b != 0 {
                p.missing_streak = 0;
                if c.wrong & b != 0 {
                    p.wrong_streak += 1;
                } else {
                    p.wrong_streak = 0;
                }
            }
            let (max_missing, max_wrong, window) = (
                self.config.max_missing_reports,
                self.config.max_wrong_ticks,
                self.config.report_window,
            );
            let missed = if expected {
                p.judge_report(c.missing & b != 0, window)
            } else {
                p.missing_in_window
            };
            if expected && max_missing > 0 && missed > max_missing {
                let detail = format!(
                    "no state hash for {missed} of the last {} compared ticks (up to tick {tick}; at most {max_missing} may be missing)",
                    p.recent_missing.len()
                );
                drop.push((id, CloseReason::NoHashReports, detail));
            } else if max_wrong > 0 && p.wrong_streak >= max_wrong {
                let judge = if self.config.verify {
                    "the server's own hash"
                } else {
                    "the voters' majority"
                };
                let detail = format!(
                    "state hash differs from {judge} on {} reported ticks in a row (up to tick {tick})",
                    p.wrong_streak
                );
                drop.push((id, CloseReason::Diverged, detail));
            }
        }
        if let Some(notice) = c.notice {
            self.stats.desync_notices += 1;
            for index in 0..self.players.len() {
                if self.players[index].is_some() {
                    let to = self.id_of(index);
                    self.transmits.push_back(Transmit {
                        to,
                        message: ServerMessage::Desync(notice.clone()),
                    });
                }
            }
            let before = self
                .last_agreed
                .filter(|&(t, _)| t + 1 == notice.tick)
                .map(|(_, h)| h);
            let mut out = Vec::new();
            if !self.config.locate_timeout.is_zero()
                && self.locator.start(now, &notice, before, &mut out)
            {
                self.stats.desync_searches += 1;
            }
            self.events.push_back(RoomEvent::Desync(notice));
            self.apply_search(out);
        }
        for (id, reason, detail) in drop {
            let leave = match reason {
                CloseReason::NoHashReports => LeaveReason::NoHashReports,
                _ => LeaveReason::Diverged,
            };
            self.remove(now, id, leave, Some(close(reason, detail)));
        }
    }

    /// Asks the join's source for the snapshot from byte `offset`.
    fn probe_join_snapshot(&mut self, offset: u32) {
        let Some(j) = &self.joining else { return };
        let (tick, Some(source)) = (j.tick, j.source) else {
            return;
        };
        if self.players[source.index()].is_some() {
            let to = self.id_of(source.index());
            self.transmits.push_back(Transmit {
                to,
                message: ServerMessage::Probe(crate::forensics::Probe {
                    tick,
                    ask: crate::forensics::ProbeAsk::Snapshot { offset },
                }),
            });
        }
    }

    fn is_join_reply(&self, from: Slot, r: &crate::forensics::ProbeReply) -> bool {
        use crate::forensics::ProbeAnswer;
        self.joining.as_ref().is_some_and(|j| {
            j.source == Some(from)
                && j.tick == r.tick
                && matches!(
                    r.answer,
                    ProbeAnswer::Snapshot { .. } | ProbeAnswer::Unavailable
                )
        })
    }

    /// A piece of the joiner's snapshot: the next piece is asked for, the
    /// whole is handed to the caller ([`RoomEvent::JoinSnapshot`]).
    fn on_join_reply(&mut self, now: Duration, r: crate::forensics::ProbeReply) {
        use crate::forensics::ProbeAnswer;
        let Some(j) = &mut self.joining else { return };
        let id = j.id;
        match r.answer {
            ProbeAnswer::Snapshot {
                total,
                offset,
                bytes,
            } if j.total.is_none_or(|t| t == total)
                && offset as usize == j.bytes.len()
                && (!bytes.is_empty() || total == 0)
                && j.bytes.len() + bytes.len() <= total as usize
                && total as usize <= crate::limits::MAX_SCENE_BYTES =>
            {
                j.total = Some(total);
                j.bytes.extend_from_slice(&bytes);
                if j.bytes.len() < total as usize {
                    let next = j.bytes.len() as u32;
                    self.probe_join_snapshot(next);
                } else {
                    self.events.push_back(RoomEvent::JoinSnapshot {
                        id,
                        tick: j.tick,
                        agreed_hash: j.hash,
                        from: j.source,
                        bytes: std::mem::take(&mut j.bytes),
                    });
                }
            }
            ProbeAnswer::Unavailable => {
                self.retry_join(now, "the agreed tick left the players' history", false);
            }
            _ => self.retry_join(now, "the snapshot came in pieces that do not fit", true),
        }
    }

    /// The players in good standing: admitted, reporting (a hash for one
    /// of the last 32 closed ticks), not judged wrong on their last
    /// reported tick, and no bad snapshot given before.
    fn good_standing(&self) -> SlotMask {
        let recent = self.next_tick.saturating_sub(32);
        (0..self.players.len())
            .filter(|&i| {
                self.players[i].as_ref().is_some_and(|p| {
                    p.admitted
                        && p.last_report.is_some_and(|t| t >= recent)
                        && p.wrong_streak == 0
                        && p.stats.bad_snapshots == 0
                })
            })
            .fold(0, |m, i| m | bit(Slot(i as u8)))
    }

    /// The lowest player in good standing to give a joiner its snapshot,
    /// other than those in `exclude`.
    fn pick_giver(&self, exclude: SlotMask) -> Option<Slot> {
        let candidates = self.good_standing() & !exclude;
        (candidates != 0).then(|| Slot(candidates.trailing_zeros() as u8))
    }

    /// The join's snapshot did not come from its giver (`why`): a bad one
    /// (`bad`) counts against the giver, which is never asked again; the
    /// next player in good standing is asked for the same tick, and with
    /// nobody left the join is refused.
    fn retry_join(&mut self, now: Duration, why: &str, bad: bool) {
        let Some(j) = &self.joining else { return };
        let (id, source, tried) = (j.id, j.source, j.tried);
        if bad
            && let Some(s) = source
            && let Some(Some(p)) = self.players.get_mut(s.index())
        {
            p.stats.bad_snapshots += 1;
            self.stats.bad_snapshots += 1;
        }
        let next = source.and_then(|_| self.pick_giver(tried));
        let Some(next) = next else {
            self.fail_join(now, id, why);
            return;
        };
        if let Some(j) = &mut self.joining {
            j.source = Some(next);
            j.tried |= bit(next);
            j.total = None;
            j.bytes.clear();
        }
        self.probe_join_snapshot(0);
    }

    /// Ends a join to the running match that cannot complete.
    fn fail_join(&mut self, now: Duration, id: PlayerId, why: &str) {
        let reservation = self.joining.take().and_then(|j| j.reservation);
        let detail = format!("no agreed state to join the running match from: {why}; try again");
        let c = close(CloseReason::MatchInProgress, detail);
        self.remove(now, id, LeaveReason::JoinRefused, Some(c));
        // A rejoiner may try again for its own seat.
        if let Some(r) = reservation
            && self.players[id.slot.index()].is_none()
        {
            self.reserved[id.slot.index()] = Some(r);
        }
    }

    /// Admits the player joining the running match once the caller checked
    /// its snapshot (from [`RoomEvent::JoinSnapshot`]): the snapshot must
    /// restore and hash to the agreed hash. The welcome carries the
    /// snapshot; the player catches up from the bundle after it and is in
    /// every bundle from the next open tick on.
    pub fn admit(&mut self, now: Duration, id: PlayerId, snapshot: Vec<u8>) {
        self.admit_joiner(now, id, snapshot);
        self.step_lifecycle(now);
    }

    fn admit_joiner(&mut self, now: Duration, id: PlayerId, snapshot: Vec<u8>) {
        let Some(j) = self.joining.take_if(|j| j.id == id) else {
            return;
        };
        let oldest = self
            .next_tick
            .saturating_sub(self.config.history_ticks as u64);
        if j.tick + 1 < oldest || self.player(id).is_none() {
            self.fail_join(now, id, "the snapshot is older than the bundles kept");
            return;
        }
        let start_tick = self.next_tick;
        let Some(Some(p)) = self.players.get_mut(id.slot.index()) else {
            return;
        };
        p.admitted = true;
        p.start_tick = start_tick;
        p.first_bundle = j.tick + 1;
        p.last_heard = now;
        let name = p.name.clone();
        let rejoin = p.ticket.and_then(|k| self.credential(id.slot.index(), k));
        self.transmits.push_back(Transmit {
            to: id,
            message: ServerMessage::Welcome(Welcome {
                slot: id.slot,
                tick_rate: self.config.tick_rate,
                input_delay: self.config.input_delay,
                input_window: self.config.input_window,
                max_input_bytes: self.config.max_input_bytes as u8,
                start_tick,
                scene_hash: self.config.scene_hash,
                scene: Vec::new(),
                resume: Some(crate::message::Resume {
                    tick: j.tick,
                    hash: j.hash,
                    snapshot,
                }),
                rules: self.config.rules.clone(),
                seed: self.config.seed,
                rejoin,
            }),
        });
        self.events.push_back(RoomEvent::PlayerJoined { id, name });
    }

    /// The snapshot for the player joining the running match did not check
    /// out (`why` says how): it counts against the player that gave it
    /// ([`PlayerStats::bad_snapshots`]; that player is not asked again),
    /// and the next player in good standing is asked; with nobody left (or
    /// for the caller's own state) the join is refused with `why`.
    pub fn refuse_join(&mut self, now: Duration, id: PlayerId, why: &str) {
        if self.joining.as_ref().is_some_and(|j| j.id == id) {
            self.retry_join(now, why, true);
        }
        self.step_lifecycle(now);
    }

    /// Sends the search's probes, and announces its report and snapshot.
    fn apply_search(&mut self, out: Vec<Output>) {
        for o in out {
            match o {
                Output::Probe(slot, probe) => {
                    if self.players.get(slot.index()).is_some_and(Option::is_some) {
                        let to = self.id_of(slot.index());
                        self.transmits.push_back(Transmit {
                            to,
                            message: ServerMessage::Probe(probe),
                        });
                    }
                }
                Output::Report(mut report) => {
                    // The inputs of the desync tick beside the bodies: a
                    // wrong input handling shows there first.
                    if let Some(b) = self.history.get(report.tick) {
                        report.inputs.clone_from(&b.inputs);
                    }
                    self.stats.desyncs_located += 1;
                    for index in 0..self.players.len() {
                        if self.players[index].is_some() {
                            let to = self.id_of(index);
                            self.transmits.push_back(Transmit {
                                to,
                                message: ServerMessage::DesyncReport(report.clone()),
                            });
                        }
                    }
                    self.events.push_back(RoomEvent::DesyncLocated(report));
                }
                Output::Snapshot {
                    tick,
                    agreed_hash,
                    from,
                    bytes,
                } => self.events.push_back(RoomEvent::DesyncSnapshot {
                    tick,
                    agreed_hash,
                    from,
                    bytes,
                }),
            }
        }
    }
}
