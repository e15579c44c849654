//! Per-tick hash comparison and majority arbitration.
//!
//! Each closed tick opens an entry listing the players expected to report a
//! hash for it. The entry is compared as soon as every expected player that
//! is still connected has reported, or when the hash timeout passes, or when
//! the ring needs its slot back. A mismatch yields a [`DesyncNotice`] whose
//! verdict is the arbiter's own (verified) hash, the voters' strict majority
//! ([`Voting`]), or undecided; a divergence that persists tick after tick is
//! reported once, on the tick it started.

use std::time::Duration;

use crate::limits::MAX_PLAYERS;
use crate::message::{DesyncNotice, PlayerHash, Slot, Verdict};
use crate::ring::TickRing;

use super::config::Voting;

/// Bit set of slots; `MAX_PLAYERS` is at most 32.
pub(crate) type SlotMask = u32;

const _: () = assert!(MAX_PLAYERS <= 32, "SlotMask must hold every slot");

pub(crate) fn bit(slot: Slot) -> SlotMask {
    1 << slot.0
}

#[derive(Debug)]
struct Entry {
    closed_at: Duration,
    expected: SlotMask,
    reported: SlotMask,
    hashes: [u64; MAX_PLAYERS],
    done: bool,
    /// The arbiter's own hash of the tick (a server that re-simulates).
    verified: Option<u64>,
}

/// What comparing one tick's hashes produced.
#[derive(Debug)]
pub(crate) struct Comparison {
    /// Expected players that never reported.
    pub missing: SlotMask,
    /// Players that reported.
    pub reported: SlotMask,
    /// Whether the reported hashes differed.
    pub mismatch: bool,
    /// Reporters of another hash than the right one (the verified hash, or
    /// the voters' strict majority; empty when they agree, when no hash is
    /// right, and always under [`Voting::Off`]), on every mismatched tick,
    /// announced or not.
    pub wrong: SlotMask,
    /// The notice to raise; `None` when the hashes agree, or when this tick
    /// continues a divergence already reported.
    pub notice: Option<DesyncNotice>,
    /// The right hash, if any: the verified one, the voters' strict
    /// majority, or under [`Voting::Off`] the hash every reporter holds.
    pub agreed: Option<u64>,
}

/// Outcome of recording one report.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum Recorded {
    /// Stored (or an identical duplicate).
    Stored,
    /// The tick has already left the ring or been compared; ignored.
    Stale,
    /// The player was not part of that tick's bundle.
    NotExpected,
    /// The player already reported a different hash for this tick.
    Conflict,
}

/// Hash entries for the most recent ticks, and the state that suppresses
/// repeated notices for one divergence.
#[derive(Debug)]
pub(crate) struct Arbiter {
    ring: TickRing<Entry>,
    /// No entry below this tick is pending.
    oldest_pending: u64,
    /// One past the newest opened tick.
    end: u64,
    timeout: Duration,
    /// Groups (slot masks) of the last reported divergence.
    last_groups: Option<Vec<SlotMask>>,
    /// Whether every tick waits for a verified hash, which is then the
    /// verdict (see [`Arbiter::verify`]).
    verifying: bool,
    /// Without a verified hash: who decides the right hash.
    voting: Voting,
    /// The players whose hashes count as votes under
    /// [`Voting::TokenHolders`] (kept up to date by the room).
    pub(crate) voters: SlotMask,
}

impl Arbiter {
    pub(crate) fn new(capacity: usize, timeout: Duration) -> Self {
        Self {
            ring: TickRing::new(capacity),
            oldest_pending: 0,
            end: 0,
            timeout,
            last_groups: None,
            verifying: false,
            voting: Voting::Off,
            voters: 0,
        }
    }

    /// Who decides the right hash of a tick without a verified hash.
    pub(crate) fn set_voting(&mut self, voting: Voting) {
        self.voting = voting;
    }

    /// From now on every tick is judged against the hash given to
    /// [`Arbiter::verify`], not by majority: an entry is compared once it
    /// has that hash (and its reports, or the timeout).
    pub(crate) fn set_verifying(&mut self) {
        self.verifying = true;
    }

    /// The arbiter's own hash of `tick`. Ignored for a tick already
    /// compared or out of the ring.
    pub(crate) fn verify(&mut self, tick: u64, hash: u64) {
        if let Some(e) = self.ring.get_mut(tick)
            && !e.done
        {
            e.verified = Some(hash);
        }
    }

    /// Opens tick `tick` (ticks are opened in order). If its slot held an
    /// entry that was never compared, that entry is compared now.
    pub(crate) fn open(
        &mut self,
        tick: u64,
        closed_at: Duration,
        expected: SlotMask,
    ) -> Option<(u64, Comparison)> {
        let entry = Entry {
            closed_at,
            expected,
            reported: 0,
            hashes: [0; MAX_PLAYERS],
            done: expected == 0,
            verified: None,
        };
        self.end = tick + 1;
        let evicted = self.ring.insert(tick, entry);
        match evicted {
            Some((t, e)) if !e.done => Some((t, self.compare(t, &e))),
            _ => None,
        }
    }

    /// Records `slot`'s hash for `tick`; the caller checked that the tick is
    /// closed.
    pub(crate) fn record(&mut self, tick: u64, slot: Slot, hash: u64) -> Recorded {
        let Some(e) = self.ring.get_mut(tick) else {
            return Recorded::Stale;
        };
        if e.expected & bit(slot) == 0 {
            return Recorded::NotExpected;
        }
        if e.reported & bit(slot) != 0 {
            return if e.hashes[slot.index()] == hash {
                Recorded::Stored
            } else {
                Recorded::Conflict
            };
        }
        if e.done {
            return Recorded::Stale;
        }
        e.reported |= bit(slot);
        e.hashes[slot.index()] = hash;
        Recorded::Stored
    }

    /// Compares every pending entry that is complete (all expected players
    /// in `connected` reported) or whose timeout passed, in tick order.
    pub(crate) fn finalize(
        &mut self,
        now: Duration,
        connected: SlotMask,
    ) -> Vec<(u64, Comparison)> {
        let mut out = Vec::new();
        let first = self
            .oldest_pending
            .max(self.end.saturating_sub(self.ring.capacity() as u64));
        let mut all_done_so_far = true;
        for tick in first..self.end {
            let Some(e) = self.ring.get(tick) else {
                continue;
            };
            let (expected, reported, hashes, verified) =
                (e.expected, e.reported, e.hashes, e.verified);
            let waiting =
                expected & connected & !reported != 0 || self.verifying && verified.is_none();
            let ready = e.done || !waiting || now >= e.closed_at.saturating_add(self.timeout);
            if !ready {
                all_done_so_far = false;
                continue;
            }
            if !e.done {
                let c = self.compare_parts(tick, expected, reported, &hashes, verified);
                if let Some(e) = self.ring.get_mut(tick) {
                    e.done = true;
                }
                out.push((tick, c));
            }
            if all_done_so_far {
                self.oldest_pending = tick + 1;
            }
        }
        out
    }

    /// The newest of the last `depth` ticks a joiner can start from without
    /// waiting for everyone's report: every player of `good` in its bundle
    /// reported it, and it has a right hash by the room's rule as far as
    /// the reports go (the verified hash; under voting, the one a strict
    /// majority of the voters who reported hold; without either, the one
    /// every reporter holds). Returns the tick, its hash and the players of
    /// `good` that hold it.
    pub(crate) fn fresh_agreed(&self, good: SlotMask, depth: u64) -> Option<(u64, u64, SlotMask)> {
        let first = self
            .end
            .saturating_sub(depth)
            .max(self.end.saturating_sub(self.ring.capacity() as u64));
        (first..self.end).rev().find_map(|tick| {
            let e = self.ring.get(tick)?;
            let wanted = e.expected & good;
            if wanted == 0 || wanted & !e.reported != 0 {
                return None;
            }
            let holding = |mask: SlotMask, h: u64| {
                (0..MAX_PLAYERS)
                    .filter(|&i| mask & (1 << i) != 0 && e.hashes[i] == h)
                    .fold(0, |m, i| m | (1 << i))
            };
            let first_of = |mask: SlotMask| e.hashes[mask.trailing_zeros() as usize];
            let h = match (self.verifying, self.voting) {
                (true, _) => e.verified?,
                (false, Voting::Off) => {
                    let h = first_of(e.reported);
                    (holding(e.reported, h) == e.reported).then_some(h)?
                }
                (false, voting) => {
                    let voters = if voting == Voting::Everyone {
                        e.reported
                    } else {
                        e.reported & self.voters
                    };
                    (0..MAX_PLAYERS)
                        .filter(|&i| voters & (1 << i) != 0)
                        .map(|i| e.hashes[i])
                        .find(|&h| {
                            SlotMask::count_ones(holding(voters, h)) * 2 > voters.count_ones()
                        })?
                }
            };
            let givers = holding(wanted, h);
            (givers != 0).then_some((tick, h, givers))
        })
    }

    /// Earliest time at which a pending entry times out.
    pub(crate) fn next_deadline(&self) -> Option<Duration> {
        let first = self
            .oldest_pending
            .max(self.end.saturating_sub(self.ring.capacity() as u64));
        (first..self.end)
            .filter_map(|t| self.ring.get(t))
            .find(|e| !e.done)
            .map(|e| e.closed_at.saturating_add(self.timeout))
    }

    fn compare(&mut self, tick: u64, e: &Entry) -> Comparison {
        self.compare_parts(tick, e.expected, e.reported, &e.hashes, e.verified)
    }

    fn compare_parts(
        &mut self,
        tick: u64,
        expected: SlotMask,
        reported: SlotMask,
        hashes: &[u64; MAX_PLAYERS],
        verified: Option<u64>,
    ) -> Comparison {
        let missing = expected & !reported;
        // Determinism: groups are built in ascending slot order, so the same
        // reports always give the same groups and verdict.
        let mut groups: Vec<(u64, SlotMask)> = Vec::new();
        for (s, &h) in hashes.iter().enumerate() {
            if reported & (1 << s) == 0 {
                continue;
            }
            match groups.iter_mut().find(|(gh, _)| *gh == h) {
                Some((_, m)) => *m |= 1 << s,
                None => groups.push((h, 1 << s)),
            }
        }
        // The right hash and its holders. A verifying arbiter judges
        // against its own hash: everyone who reported another one is wrong,
        // however many they are. Otherwise the voters' strict majority
        // decides, or (no voting) only a unanimous hash is agreed and
        // nobody is judged.
        let holders = |h: u64| groups.iter().find(|g| g.0 == h).map_or(0, |g| g.1);
        let right: Option<(u64, SlotMask)> = match (verified, self.voting) {
            (Some(v), _) => Some((v, holders(v))),
            (None, Voting::Off) => (groups.len() == 1).then(|| groups[0]),
            (None, voting) => {
                let voters = if voting == Voting::Everyone {
                    reported
                } else {
                    reported & self.voters
                };
                let n = voters.count_ones();
                groups
                    .iter()
                    .find(|(_, m)| (m & voters).count_ones() * 2 > n)
                    .copied()
            }
        };
        let all_agree = match verified {
            Some(_) => reported & !right.map_or(0, |r| r.1) == 0,
            None => groups.len() <= 1,
        };
        if all_agree {
            // The divergence is over only when everyone in it reported and
            // agreed: a player that diverges on some ticks and stays silent
            // on the others must not raise a new notice each time it
            // speaks again.
            let involved = self
                .last_groups
                .as_ref()
                .map_or(0, |g| g.iter().fold(0, |a, m| a | m));
            if involved & !reported == 0 {
                self.last_groups = None;
            }
            return Comparison {
                missing,
                reported,
                mismatch: false,
                wrong: 0,
                notice: None,
                agreed: right.map(|r| r.0),
            };
        }
        let wrong = match (verified, self.voting) {
            (None, Voting::Off) => 0,
            _ => right.map_or(0, |(_, m)| reported & !m),
        };
        let masks: Vec<SlotMask> = groups.iter().map(|g| g.1).collect();
        let same_divergence = self
            .last_groups
            .as_ref()
            .is_some_and(|old| refines(&masks, old));
        self.last_groups = Some(masks);
        if same_divergence {
            return Comparison {
                missing,
                reported,
                mismatch: true,
                wrong,
                notice: None,
                agreed: right.map(|r| r.0),
            };
        }
        let verdict = match (verified, right) {
            (Some(hash), _) => Verdict::Verified {
                hash,
                wrong: slots(wrong),
            },
            (None, Some((majority_hash, _))) => Verdict::Majority {
                majority_hash,
                wrong: slots(wrong),
            },
            (None, None) => Verdict::Undecided,
        };
        let notice = DesyncNotice {
            tick,
            hashes: slots(expected)
                .into_iter()
                .map(|slot| PlayerHash {
                    slot,
                    hash: (reported & bit(slot) != 0).then(|| hashes[slot.index()]),
                })
                .collect(),
            verdict,
        };
        Comparison {
            missing,
            reported,
            mismatch: true,
            wrong,
            notice: Some(notice),
            agreed: right.map(|r| r.0),
        }
    }
}

/// True when every group of `new` lies inside a distinct group of `old`: the
/// same players still disagree the same way (some may just not have
/// reported), so this is the divergence already announced.
fn refines(new: &[SlotMask], old: &[SlotMask]) -> bool {
    let mut used: SlotMask = 0;
    for &g in new {
        match old.iter().position(|&o| g & !o == 0) {
            Some(i) if used & (1 << i) == 0 => used |= 1 << i,
            _ => return false,
        }
    }
    true
}

/// The slots of a mask, ascending.
pub(crate) fn slots(mask: SlotMask) -> Vec<Slot> {
    (0..MAX_PLAYERS as u8)
        .map(Slot)
        .filter(|s| mask & bit(*s) != 0)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: Duration = Duration::from_secs(2);

    #[test]
    fn divergence_is_announced_once_and_again_after_recovery() {
        let mut a = Arbiter::new(16, T);
        a.set_voting(Voting::Everyone);
        let now = Duration::ZERO;
        let mut notices = Vec::new();
        for tick in 0..10u64 {
            a.open(tick, now, 0b111);
            let bad = (3..6).contains(&tick) || tick >= 8;
            a.record(tick, Slot(0), 5);
            a.record(tick, Slot(1), if bad { 6 } else { 5 });
            a.record(tick, Slot(2), 5);
            for (t, c) in a.finalize(now, 0b111) {
                assert_eq!(c.mismatch, bad);
                if let Some(n) = c.notice {
                    notices.push((t, n.verdict));
                }
            }
        }
        let wrong1 = Verdict::Majority {
            majority_hash: 5,
            wrong: vec![Slot(1)],
        };
        assert_eq!(notices, vec![(3, wrong1.clone()), (8, wrong1)]);
    }

    /// A liar that reports a wrong hash on even ticks and nothing on odd
    /// ones is one divergence, announced once, and judged wrong on every
    /// tick it reports.
    #[test]
    fn a_liar_that_alternates_with_silence_is_announced_once() {
        let mut a = Arbiter::new(16, T);
        a.set_voting(Voting::Everyone);
        let mut notices = 0;
        let mut judged_wrong = 0;
        for tick in 0..40u64 {
            let now = Duration::from_millis(tick * 100);
            a.open(tick, now, 0b1111);
            for s in 0..3 {
                a.record(tick, Slot(s), 7);
            }
            if tick % 2 == 0 {
                a.record(tick, Slot(3), 9);
            }
            // Odd ticks are compared at their timeout, without slot 3.
            for (_, c) in a.finalize(now + T, 0b1111) {
                notices += usize::from(c.notice.is_some());
                judged_wrong += usize::from(c.wrong == 0b1000);
            }
        }
        assert_eq!(notices, 1);
        assert_eq!(judged_wrong, 20);
        // Everyone agreeing again ends the divergence: the next lie is new.
        a.open(40, Duration::ZERO, 0b1111);
        for s in 0..4 {
            a.record(40, Slot(s), 7);
        }
        a.open(41, Duration::ZERO, 0b1111);
        for s in 0..3 {
            a.record(41, Slot(s), 7);
        }
        a.record(41, Slot(3), 9);
        let out = a.finalize(Duration::ZERO, 0b1111);
        assert_eq!(out.len(), 2);
        assert!(out[1].1.notice.is_some());
    }

    #[test]
    fn evicted_entry_is_compared_before_its_slot_is_reused() {
        let mut a = Arbiter::new(2, T);
        a.open(0, Duration::ZERO, 0b11);
        a.record(0, Slot(0), 1);
        a.record(0, Slot(1), 2);
        a.open(1, Duration::ZERO, 0b11);
        let (t, c) = a.open(2, Duration::ZERO, 0b11).expect("tick 0 evicted");
        assert_eq!(t, 0);
        assert_eq!(c.notice.map(|n| n.verdict), Some(Verdict::Undecided));
        assert_eq!(a.record(0, Slot(0), 1), Recorded::Stale);
    }

    #[test]
    fn timeout_compares_with_missing_reporters_listed() {
        let mut a = Arbiter::new(8, T);
        a.open(0, Duration::ZERO, 0b111);
        a.record(0, Slot(0), 1);
        a.record(0, Slot(2), 1);
        assert!(a.finalize(Duration::from_millis(1999), 0b111).is_empty());
        assert_eq!(a.next_deadline(), Some(T));
        let out = a.finalize(T, 0b111);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].1.missing, 0b010);
        assert!(!out[0].1.mismatch);
        assert_eq!(a.next_deadline(), None);
    }
}
