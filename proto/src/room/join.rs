//! Seating players: joins to the lobby, joins and rejoins to the running
//! match (the agreed snapshot fetched from a player in good standing or
//! the caller's own state), and rejoin credentials.

use std::time::Duration;

use super::arbiter::{SlotMask, bit};
use super::errors::close;
use super::player::Player;
use super::{JoinError, LeaveReason, PlayerId, Room, RoomEvent, Transmit};
use crate::limits::PROTOCOL_VERSION;
use crate::message::{CloseReason, Join, ServerMessage, Slot, Welcome};

/// The snapshot a player joining a running match waits for.
#[derive(Debug)]
pub(super) struct JoinFetch {
    pub(super) id: PlayerId,
    pub(super) tick: u64,
    pub(super) hash: u64,
    /// Who gives the snapshot: a player, or (`None`) the caller's own
    /// re-simulation ([`Room::offer_own_snapshots`]).
    pub(super) source: Option<Slot>,
    /// The players asked so far, and those not holding the tick's hash.
    pub(super) tried: SlotMask,
    /// The seat's rejoin reservation the join took, given back if it fails.
    pub(super) reservation: Option<(u64, Duration)>,
    pub(super) total: Option<u32>,
    pub(super) bytes: Vec<u8>,
    pub(super) deadline: Duration,
}

impl Room {
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
    pub(super) fn credential(
        &self,
        index: usize,
        key: u64,
    ) -> Option<crate::message::RejoinCredential> {
        let mac = self.credential_mac(index, key)?;
        let mut out = [0u8; 32];
        out.copy_from_slice(&hmac::Mac::finalize(mac).into_bytes());
        Some(crate::message::RejoinCredential(out))
    }

    pub(super) fn credential_mac(
        &self,
        index: usize,
        key: u64,
    ) -> Option<hmac::Hmac<sha2::Sha256>> {
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
    pub(super) fn credential_seat(&self, join: &Join) -> Option<(usize, u64)> {
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
    /// allows late joins ([`RoomConfig::late_join`](super::RoomConfig::late_join)) or it is a rejoin (see
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
    /// ([`RoomConfig::rejoin_grace`](super::RoomConfig::rejoin_grace)).
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

    pub(super) fn seat_player(
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

    /// Asks the join's source for the snapshot from byte `offset`.
    pub(super) fn probe_join_snapshot(&mut self, offset: u32) {
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

    pub(super) fn is_join_reply(&self, from: Slot, r: &crate::forensics::ProbeReply) -> bool {
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
    pub(super) fn on_join_reply(&mut self, now: Duration, r: crate::forensics::ProbeReply) {
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
    pub(super) fn good_standing(&self) -> SlotMask {
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
    pub(super) fn pick_giver(&self, exclude: SlotMask) -> Option<Slot> {
        let candidates = self.good_standing() & !exclude;
        (candidates != 0).then(|| Slot(candidates.trailing_zeros() as u8))
    }

    /// The join's snapshot did not come from its giver (`why`): a bad one
    /// (`bad`) counts against the giver, which is never asked again; the
    /// next player in good standing is asked for the same tick, and with
    /// nobody left the join is refused.
    pub(super) fn retry_join(&mut self, now: Duration, why: &str, bad: bool) {
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
    pub(super) fn fail_join(&mut self, now: Duration, id: PlayerId, why: &str) {
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

    pub(super) fn admit_joiner(&mut self, now: Duration, id: PlayerId, snapshot: Vec<u8>) {
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
    /// ([`PlayerStats::bad_snapshots`](super::PlayerStats::bad_snapshots); that player is not asked again),
    /// and the next player in good standing is asked; with nobody left (or
    /// for the caller's own state) the join is refused with `why`.
    pub fn refuse_join(&mut self, now: Duration, id: PlayerId, why: &str) {
        if self.joining.as_ref().is_some_and(|j| j.id == id) {
            self.retry_join(now, why, true);
        }
        self.step_lifecycle(now);
    }
}
