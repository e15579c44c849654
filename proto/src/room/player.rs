//! One seated player: pending inputs, acknowledgements, liveness and counters.

use std::time::Duration;

use crate::ring::TickRing;

/// Counters the server can log or export per player. They explain a bad
/// experience after the fact (was it loss, lateness, or a slow client?).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PlayerStats {
    /// Ticks whose input arrived before the deadline.
    pub inputs_on_time: u64,
    /// Ticks where the previous input was substituted.
    pub inputs_substituted: u64,
    /// Inputs that arrived after their tick closed with a substitute
    /// (each tick counted once).
    pub late_inputs: u64,
    /// Redundant copies of inputs already received or no longer needed.
    pub redundant_inputs: u64,
    /// Hash reports accepted.
    pub hash_reports: u64,
    /// Ticks compared without this player's hash (timed out).
    pub missing_hash_reports: u64,
    /// Snapshots it gave a player joining the running match that did not
    /// check out (it is not asked again).
    pub bad_snapshots: u64,
    /// Smoothed round-trip time from pings (7/8 old + 1/8 new sample).
    pub rtt: Option<Duration>,
}

#[derive(Debug)]
pub(crate) struct Player {
    pub(crate) name: String,
    /// First tick this player is part of.
    pub(crate) start_tick: u64,
    /// Inputs received for ticks not yet closed.
    pub(crate) pending: TickRing<Vec<u8>>,
    /// Input used for this player in the last closed tick (what a missing
    /// input is replaced by); empty before the first input.
    pub(crate) last_input: Vec<u8>,
    /// Last contiguous bundle tick the client acknowledged.
    pub(crate) bundle_ack: Option<u64>,
    pub(crate) last_heard: Duration,
    pub(crate) next_ping_at: Duration,
    /// Nonce and send time of the ping awaiting its pong.
    pub(crate) ping: Option<(u64, Duration)>,
    pub(crate) stats: PlayerStats,
    /// Compared ticks in a row without this player's hash.
    pub(crate) missing_streak: u32,
    /// Its last compared ticks (at most the report window), oldest first:
    /// true where its hash was missing.
    pub(crate) recent_missing: std::collections::VecDeque<bool>,
    /// How many of `recent_missing` are true.
    pub(crate) missing_in_window: u32,
    /// The newest tick it reported a hash for.
    pub(crate) last_report: Option<u64>,
    /// The newest tick of a hash report the room accepted (stored, or
    /// for a tick already compared).
    pub(crate) last_hash_accepted: Option<u64>,
    /// Ticks in a row, among those it reported, where its hash was outside
    /// the majority.
    pub(crate) wrong_streak: u32,
    /// The key of the join token that seated this player, if any.
    pub(crate) ticket: Option<u64>,
    /// False while a player joining a running match waits for the agreed
    /// snapshot: it is in no bundle and gets none.
    pub(crate) admitted: bool,
    /// The first bundle sent to it (before `start_tick` for a player that
    /// joined a running match and catches up from a snapshot).
    pub(crate) first_bundle: u64,
}

impl Player {
    pub(crate) fn new(name: String, start_tick: u64, window: usize, now: Duration) -> Self {
        Self {
            name,
            start_tick,
            pending: TickRing::new(window),
            last_input: Vec::new(),
            bundle_ack: None,
            last_heard: now,
            next_ping_at: now,
            ping: None,
            stats: PlayerStats::default(),
            missing_streak: 0,
            recent_missing: std::collections::VecDeque::new(),
            missing_in_window: 0,
            last_report: None,
            last_hash_accepted: None,
            wrong_streak: 0,
            ticket: None,
            admitted: true,
            first_bundle: start_tick,
        }
    }

    /// Records whether its hash was missing on one more compared tick, in
    /// a window of the last `window` ticks; returns the misses in it.
    pub(crate) fn judge_report(&mut self, missing: bool, window: u32) -> u32 {
        self.recent_missing.push_back(missing);
        self.missing_in_window += u32::from(missing);
        while self.recent_missing.len() > window as usize {
            if self.recent_missing.pop_front() == Some(true) {
                self.missing_in_window -= 1;
            }
        }
        self.missing_in_window
    }

    /// Folds one RTT sample into the smoothed estimate.
    pub(crate) fn rtt_sample(&mut self, sample: Duration) {
        self.stats.rtt = Some(match self.stats.rtt {
            None => sample,
            Some(old) => (old * 7 + sample) / 8,
        });
    }
}
