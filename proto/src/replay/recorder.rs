//! The recorder: the room's events and accepted hash reports turned into
//! replay records.

use std::collections::VecDeque;

use super::{ReplayEncodeError, ReplayHeader, ReplayRecord, encode_preamble, encode_record};
use crate::limits::MAX_PLAYERS;
use crate::message::Slot;
use crate::room::RoomEvent;

/// A closed tick whose agreed hash is not decided yet.
#[derive(Debug)]
struct PendingTick {
    tick: u64,
    /// Players in the tick's bundle.
    expected: u32,
    reported: u32,
    hashes: [u64; MAX_PLAYERS],
    /// The first body-hash list received for each distinct state hash.
    bodies: Vec<(u64, Vec<u64>)>,
}

impl PendingTick {
    /// The hash held by more than half of the reporters, if any.
    fn majority(&self) -> Option<u64> {
        let reporters: Vec<u64> = (0..MAX_PLAYERS)
            .filter(|&i| self.reported & (1 << i) != 0)
            .map(|i| self.hashes[i])
            .collect();
        // Determinism of the outcome does not matter here (the majority is
        // unique when it exists), but the scan is in slot order anyway.
        reporters
            .iter()
            .copied()
            .find(|h| reporters.iter().filter(|&x| x == h).count() * 2 > reporters.len())
    }
}

/// Turns what the room does into replay records: feed it every
/// [`RoomEvent`] and every hash report the room accepted, and append
/// [`ReplayRecorder::take_bytes`] to the file.
///
/// A tick's hash is decided once every player of its bundle who is still in
/// the room has reported, or at the latest `decide_after` ticks later (a
/// player who stopped reporting does not hold the replay back for long). The
/// agreed hash is the one held by a strict majority of the reporters — the
/// same rule as the room's arbiter — so a desynced minority does not spoil the
/// replay; a tick without a majority gets no hash record.
///
/// After [`ReplayRecorder::follow_room`] it decides nothing itself: a
/// tick's hash is the one the room agreed on ([`RoomEvent::TickAgreed`]),
/// so the replay holds exactly the hashes the room stands behind.
#[derive(Debug)]
pub struct ReplayRecorder {
    pending: VecDeque<PendingTick>,
    present: u32,
    next_tick: u64,
    decide_after: u64,
    out: Vec<u8>,
    hashed: u64,
    ended: bool,
    /// Hashes come from the room's [`RoomEvent::TickAgreed`] only.
    follow: bool,
}

impl ReplayRecorder {
    /// Starts a replay with `header`; `decide_after` bounds how many ticks
    /// a tick's hash may wait for late reports.
    ///
    /// # Errors
    /// [`ReplayEncodeError`] if the header cannot be encoded (a scene over
    /// the size limit).
    pub fn new(header: ReplayHeader, decide_after: u64) -> Result<Self, ReplayEncodeError> {
        Self::with_seed(header, 0, decide_after)
    }

    /// [`ReplayRecorder::new`] for a match played with `seed`.
    ///
    /// # Errors
    /// As [`ReplayRecorder::new`].
    pub fn with_seed(
        header: ReplayHeader,
        seed: u64,
        decide_after: u64,
    ) -> Result<Self, ReplayEncodeError> {
        let mut out = encode_preamble();
        out.extend(encode_record(&ReplayRecord::Header(header))?);
        out.extend(encode_record(&ReplayRecord::Seed(seed))?);
        Ok(Self {
            pending: VecDeque::new(),
            present: 0,
            next_tick: 0,
            decide_after: decide_after.max(1),
            out,
            hashed: 0,
            ended: false,
            follow: false,
        })
    }

    /// Records as a tick's hash only the one the room agreed on
    /// ([`RoomEvent::TickAgreed`]), never a majority of its own: a room
    /// that does not verify agrees on a hash only under its voting rule
    /// ([`Voting`](crate::Voting)), so strangers' made-up hashes never
    /// reach the replay. Reports are still needed for the body hashes
    /// written after the agreed hash.
    pub fn follow_room(&mut self) {
        self.follow = true;
    }

    fn push(&mut self, record: &ReplayRecord) {
        // Every record but the header is bounded far below the limit (a
        // bundle is at most 16 × 64 bytes, names 64, details 256).
        if let Ok(bytes) = encode_record(record) {
            self.out.extend(bytes);
        }
    }

    /// Records a room event.
    pub fn on_event(&mut self, event: &RoomEvent) {
        match event {
            RoomEvent::PlayerJoined { id, name } => {
                self.present |= 1 << id.slot.0;
                let r = ReplayRecord::PlayerJoined {
                    slot: id.slot,
                    name: name.clone(),
                    from_tick: self.next_tick,
                };
                self.push(&r);
            }
            RoomEvent::PlayerLeft {
                id,
                reason,
                from_tick,
            } => {
                self.present &= !(1 << id.slot.0);
                let r = ReplayRecord::PlayerLeft {
                    slot: id.slot,
                    from_tick: *from_tick,
                    reason: format!("{reason:?}"),
                };
                self.push(&r);
                self.decide(false);
            }
            RoomEvent::TickClosed(bundle) => {
                self.push(&ReplayRecord::Tick(bundle.clone()));
                self.next_tick = bundle.tick + 1;
                let expected = bundle.inputs.iter().fold(0u32, |m, p| m | 1 << p.slot.0);
                self.pending.push_back(PendingTick {
                    tick: bundle.tick,
                    expected,
                    reported: 0,
                    hashes: [0; MAX_PLAYERS],
                    bodies: Vec::new(),
                });
                self.decide(false);
            }
            RoomEvent::Desync(notice) => self.push(&ReplayRecord::Desync(notice.clone())),
            &RoomEvent::TickAgreed { tick, hash } if self.follow => {
                let bodies = self
                    .pending
                    .iter()
                    .position(|p| p.tick == tick)
                    .and_then(|i| self.pending.remove(i))
                    .and_then(|p| p.bodies.into_iter().find(|(h, _)| *h == hash));
                self.hashed += 1;
                self.push(&ReplayRecord::Hash { tick, hash });
                if let Some((_, hashes)) = bodies {
                    self.push(&ReplayRecord::BodyHashes { tick, hashes });
                }
            }
            RoomEvent::TickAgreed { .. } => {}
            RoomEvent::DesyncLocated(report) => {
                self.push(&ReplayRecord::Located(report.clone()));
            }
            RoomEvent::LateInput { .. }
            | RoomEvent::DesyncSnapshot { .. }
            | RoomEvent::JoinSnapshot { .. }
            | RoomEvent::JoinFromOwnState { .. }
            | RoomEvent::MatchStarted { .. }
            | RoomEvent::MatchEnding { .. }
            | RoomEvent::MatchOver { .. } => {}
        }
    }

    /// Records a hash report the room accepted.
    pub fn on_hash(&mut self, slot: Slot, tick: u64, hash: u64) {
        self.on_hash_with_bodies(slot, tick, hash, None);
    }

    /// Records the server's own hash of `tick` (a verifying server): it is
    /// the agreed hash, whatever the players reported, and the players'
    /// reports for that tick are no longer needed.
    pub fn on_verified(&mut self, tick: u64, hash: u64) {
        self.pending.retain(|p| p.tick != tick);
        self.hashed += 1;
        self.push(&ReplayRecord::Hash { tick, hash });
    }

    /// Records a hash report the room accepted, with the per-body hashes
    /// the player sent, if any: the agreed hash's body hashes are written
    /// after it.
    pub fn on_hash_with_bodies(
        &mut self,
        slot: Slot,
        tick: u64,
        hash: u64,
        bodies: Option<&[u64]>,
    ) {
        let bit = 1u32 << slot.0;
        if let Some(p) = self.pending.iter_mut().find(|p| p.tick == tick)
            && p.expected & bit != 0
            && p.reported & bit == 0
        {
            p.reported |= bit;
            p.hashes[slot.index()] = hash;
            if let Some(b) = bodies
                && !p.bodies.iter().any(|(h, _)| *h == hash)
            {
                p.bodies.push((hash, b.to_vec()));
            }
            self.decide(false);
        }
    }

    /// Decides every pending tick that is complete or too old (or all of
    /// them, with `all`), writing its hash record.
    fn decide(&mut self, all: bool) {
        if self.follow {
            // The room decides; what it has not agreed on long after the
            // tick closed, it never will.
            let horizon = self.next_tick.saturating_sub(2 * self.decide_after);
            self.pending.retain(|p| !all && p.tick >= horizon);
            return;
        }
        let present = self.present;
        let horizon = self.next_tick.saturating_sub(self.decide_after);
        let mut records = Vec::new();
        self.pending.retain(|p| {
            let complete = p.expected & present & !p.reported == 0;
            if !(all || complete || p.tick < horizon) {
                return true;
            }
            if let Some(hash) = p.majority() {
                records.push(ReplayRecord::Hash { tick: p.tick, hash });
                if let Some((_, b)) = p.bodies.iter().find(|(h, _)| *h == hash) {
                    records.push(ReplayRecord::BodyHashes {
                        tick: p.tick,
                        hashes: b.clone(),
                    });
                }
            }
            false
        });
        self.hashed += records
            .iter()
            .filter(|r| matches!(r, ReplayRecord::Hash { .. }))
            .count() as u64;
        for r in &records {
            self.push(r);
        }
    }

    /// Ends the replay: decides every pending tick with the reports it has
    /// and writes the end record. Later calls do nothing.
    pub fn finish(&mut self, reason: &str) {
        if self.ended {
            return;
        }
        self.ended = true;
        self.decide(true);
        let r = ReplayRecord::End {
            ticks: self.next_tick,
            reason: reason.to_owned(),
        };
        self.push(&r);
    }

    /// The bytes produced since the last call, to append to the file.
    pub fn take_bytes(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.out)
    }

    /// Ticks whose agreed hash was recorded so far.
    pub fn hashed_ticks(&self) -> u64 {
        self.hashed
    }

    /// Ticks recorded so far.
    pub fn ticks(&self) -> u64 {
        self.next_tick
    }

    /// Ticks still waiting for hash reports.
    pub fn pending_ticks(&self) -> usize {
        self.pending.len()
    }
}
