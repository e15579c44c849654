//! The match's lifecycle as protocol state: the lobby (and its timeout),
//! the running match (and its end), the finishing grace that collects the
//! last hash reports, and the close. Its deadlines are entries of the
//! room's timer table ([`super::timers`]).

use std::time::Duration;

use super::errors::close;
use super::{LeaveReason, MatchLifecycle, PlayerId, Room, RoomEvent, Transmit};
use crate::limits::{MAX_BUNDLES_PER_DATAGRAM, MAX_DATAGRAM_BYTES};
use crate::message::{BundleDatagram, CloseReason, ServerMessage};

/// Where a room's match is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MatchPhase {
    /// Seating players; no tick closes.
    #[default]
    Lobby,
    /// The tick clock runs.
    Running,
    /// No more ticks: the room collects the last hash reports, repeating
    /// the bundles a player has not acknowledged.
    Finishing,
    /// Everyone was closed; the room has nothing more to do.
    Done,
}

/// The lifecycle's state in a room.
#[derive(Debug, Default)]
pub(crate) struct Lifecycle {
    /// The rules of a room that runs its own match; `None` when the caller
    /// starts it.
    pub(crate) plan: Option<MatchLifecycle>,
    pub(crate) phase: MatchPhase,
    /// When the first player joined (the lobby timeout counts from it).
    pub(crate) first_join: Option<Duration>,
    /// The first tick not to close, if known.
    pub(crate) end: Option<u64>,
    /// Finishing: when the room stops waiting for the last reports.
    pub(crate) until: Duration,
    /// Finishing: when the last bundles are repeated next (a fixed
    /// schedule, which the players' datagrams do not postpone).
    pub(crate) resend_at: Duration,
    /// Why the match ends, once known.
    pub(crate) reason: String,
    /// The caller is stopping ([`Room::shut_down`]).
    pub(crate) shutting_down: bool,
}

impl Lifecycle {
    pub(crate) fn new(plan: Option<MatchLifecycle>) -> Self {
        Self {
            plan,
            ..Self::default()
        }
    }

    /// When the lobby stops waiting: its timeout after the first join.
    pub(crate) fn lobby_deadline(&self) -> Option<Duration> {
        if self.phase != MatchPhase::Lobby {
            return None;
        }
        let timeout = self.plan?.lobby_timeout?;
        Some(self.first_join?.saturating_add(timeout))
    }

    pub(crate) fn resend_deadline(&self) -> Option<Duration> {
        (self.phase == MatchPhase::Finishing).then_some(self.resend_at)
    }

    pub(crate) fn final_deadline(&self) -> Option<Duration> {
        (self.phase == MatchPhase::Finishing).then_some(self.until)
    }
}

impl Room {
    /// Where the match is. A room without
    /// [`RoomConfig::lifecycle`](super::RoomConfig::lifecycle) is in the lobby until
    /// [`Room::start`], then running.
    pub fn phase(&self) -> MatchPhase {
        self.lifecycle.phase
    }

    /// When the match started ([`Room::start`]), if it did.
    pub fn started_at(&self) -> Option<Duration> {
        self.epoch
    }

    /// Why the match ended, once it did (empty before).
    pub fn end_reason(&self) -> &str {
        &self.lifecycle.reason
    }

    /// The caller is stopping: a running match finishes the tick in
    /// progress and ends; a lobby closes its players at once. Under
    /// [`RoomConfig::lifecycle`](super::RoomConfig::lifecycle) the room
    /// then finishes and closes as after any match end.
    pub fn shut_down(&mut self, now: Duration) {
        let l = &mut self.lifecycle;
        if l.shutting_down {
            return;
        }
        l.shutting_down = true;
        match l.phase {
            MatchPhase::Running => {
                l.end = Some(self.next_tick + 1);
                l.reason = "server shutting down".into();
            }
            MatchPhase::Lobby => {
                l.reason = "server shutting down before the match started".into();
                self.close_everyone(now, "server shutting down");
                self.end_match(true);
            }
            MatchPhase::Finishing | MatchPhase::Done => {}
        }
        self.step_lifecycle(now);
    }

    /// The lifecycle's moves that follow from the room's state at `now`
    /// (run after every call that may change it).
    pub(crate) fn step_lifecycle(&mut self, now: Duration) {
        let Some(plan) = self.lifecycle.plan else {
            return;
        };
        match self.lifecycle.phase {
            MatchPhase::Lobby => self.step_lobby(now, plan),
            MatchPhase::Running => {
                let next = self.next_tick;
                if self.lifecycle.end.is_some_and(|e| next >= e) {
                    if self.lifecycle.reason.is_empty() {
                        self.lifecycle.reason = format!("match over after {next} ticks");
                    }
                    self.begin_finishing(now, plan);
                } else if self.player_count() == 0 {
                    self.lifecycle.reason = format!("every player left by tick {next}");
                    self.begin_finishing(now, plan);
                }
            }
            MatchPhase::Finishing => {
                if self.all_reported() {
                    self.end_finishing(now);
                }
            }
            MatchPhase::Done => {}
        }
    }

    fn step_lobby(&mut self, now: Duration, plan: MatchLifecycle) {
        if self.lifecycle.shutting_down {
            return;
        }
        if self.player_count() == 0 && self.lifecycle.first_join.is_some() {
            // Everyone who joined left before the match: the room closes
            // instead of holding a slot of the server.
            self.lifecycle.reason = "every player left the lobby".into();
            self.end_match(true);
            return;
        }
        let mut start = usize::from(plan.start_players);
        if self.lifecycle.lobby_deadline().is_some_and(|d| now >= d) {
            // Nobody may hold the match back: the players without their
            // first input go, and the ready ones start.
            let unready = self.unready_players();
            if unready.len() == self.player_count() {
                // Nobody is ready: the match is over before its players
                // are closed.
                self.lifecycle.reason = "nobody was ready within the lobby timeout".into();
                self.end_match(true);
            }
            for id in unready {
                let c = close(
                    CloseReason::TimedOut,
                    "no first input within the lobby timeout".into(),
                );
                self.remove(now, id, LeaveReason::Kicked, Some(c));
            }
            if self.lifecycle.phase == MatchPhase::Done {
                return;
            }
            start = 1;
        }
        if self.player_count() >= start && self.all_ready() {
            // all_ready() is true, so the room has not started.
            let _ = self.start(now);
        }
    }

    /// Records the first join, for the lobby timeout.
    pub(crate) fn joined(&mut self, now: Duration) {
        self.lifecycle.first_join.get_or_insert(now);
    }

    /// The match just started ([`Room::start`]): the lifecycle runs it.
    pub(crate) fn started(&mut self) {
        self.lifecycle.phase = MatchPhase::Running;
        let Some(plan) = self.lifecycle.plan else {
            return;
        };
        self.lifecycle.end = plan.match_ticks;
        self.events.push_back(RoomEvent::MatchStarted {
            players: self.player_count(),
        });
    }

    fn begin_finishing(&mut self, now: Duration, plan: MatchLifecycle) {
        let period = self.tick_period();
        let l = &mut self.lifecycle;
        l.phase = MatchPhase::Finishing;
        l.until = now.saturating_add(plan.final_reports_timeout);
        l.resend_at = now.saturating_add(period);
        self.events.push_back(RoomEvent::MatchEnding {
            reason: l.reason.clone(),
        });
        self.resend_bundles();
    }

    /// Ends the finishing grace: everyone is closed.
    pub(crate) fn end_finishing(&mut self, now: Duration) {
        if self.lifecycle.phase != MatchPhase::Finishing {
            return;
        }
        let all_reported = self.all_reported();
        let reason = self.lifecycle.reason.clone();
        self.close_everyone(now, &reason);
        self.end_match(all_reported);
    }

    fn end_match(&mut self, all_reported: bool) {
        self.lifecycle.phase = MatchPhase::Done;
        self.events.push_back(RoomEvent::MatchOver {
            reason: self.lifecycle.reason.clone(),
            all_reported,
        });
    }

    fn close_everyone(&mut self, now: Duration, detail: &str) {
        let ids: Vec<PlayerId> = self.players().map(|(id, _)| id).collect();
        for id in ids {
            let c = close(CloseReason::RoomClosed, detail.to_owned());
            self.remove(now, id, LeaveReason::RoomClosed, Some(c));
        }
    }

    /// Whether every seated player's hash of the last closed tick came.
    fn all_reported(&self) -> bool {
        let last = self.next_tick.checked_sub(1);
        self.players
            .iter()
            .flatten()
            .all(|p| p.last_hash_accepted >= last)
    }

    fn tick_period(&self) -> Duration {
        Duration::from_nanos(1_000_000_000 / u64::from(self.config.tick_rate.max(1)))
    }

    /// The resend timer: repeats the last bundles, then once per tick
    /// period (never scheduled in the past, however late the call).
    pub(crate) fn resend_final_bundles(&mut self, now: Duration) {
        self.resend_bundles();
        let period = self.tick_period();
        let mut next = self.lifecycle.resend_at.saturating_add(period);
        if next <= now {
            next = now.saturating_add(period);
        }
        self.lifecycle.resend_at = next;
    }

    /// No tick closes any more, so no bundle goes out with one: repeats to
    /// each player the newest bundles it has not acknowledged, as many as
    /// fit one datagram.
    fn resend_bundles(&mut self) {
        let Some(last) = self.next_tick.checked_sub(1) else {
            return;
        };
        for index in 0..self.players.len() {
            let Some(p) = &self.players[index] else {
                continue;
            };
            if p.bundle_ack >= Some(last) {
                continue;
            }
            let from = p.bundle_ack.map_or(0, |a| a + 1);
            let mut bundles: Vec<_> = (from..=last)
                .rev()
                .take(MAX_BUNDLES_PER_DATAGRAM)
                .filter_map(|t| self.history.get(t).cloned())
                .collect();
            bundles.reverse();
            while !bundles.is_empty() {
                let message = ServerMessage::Bundles(BundleDatagram {
                    ack_input: None,
                    bundles: bundles.clone(),
                });
                match message.encode() {
                    Ok(bytes) if bytes.len() <= MAX_DATAGRAM_BYTES => {
                        let to = self.id_of(index);
                        self.transmits.push_back(Transmit { to, message });
                        break;
                    }
                    _ => {
                        bundles.remove(0);
                    }
                }
            }
        }
    }
}
