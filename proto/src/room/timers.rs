//! Every timer of a room in one table: [`Room::poll_timeout`] takes the
//! earliest deadline of the table, [`Room::handle_timeout`] handles each
//! expired kind, so a timer cannot be waited for in one place and
//! forgotten in the other.

use std::time::Duration;

use super::errors::close;
use super::{LeaveReason, MatchPhase, Room, Transmit};
use crate::message::{CloseReason, Ping, ServerMessage};

/// The kinds of timer a room keeps, in the order an expired one is
/// handled. A per-player timer is one entry whose deadline is the earliest
/// over the players.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Timer {
    /// A player heard nothing from for the silence timeout.
    Silence,
    /// The open tick's deadline.
    Tick,
    /// A hash comparison's timeout.
    Arbiter,
    /// The joiner's snapshot deadline.
    JoinSnapshot,
    /// The desync search's wait for its probe replies.
    Locator,
    /// A player due a ping.
    Ping,
    /// The lobby's wait for its players, from the first join.
    Lobby,
    /// After the last tick: repeat the bundles a player has not
    /// acknowledged, once per tick period.
    Resend,
    /// After the last tick: stop waiting for the last hash reports.
    FinalReports,
}

impl Timer {
    /// Every kind, in the order expired ones are handled.
    pub(crate) const ALL: [Timer; 9] = [
        Timer::Silence,
        Timer::Tick,
        Timer::Arbiter,
        Timer::JoinSnapshot,
        Timer::Locator,
        Timer::Ping,
        Timer::Lobby,
        Timer::Resend,
        Timer::FinalReports,
    ];
}

impl Room {
    /// When timer `timer` expires, if it is armed. The one place each
    /// kind's deadline is computed.
    pub(crate) fn deadline(&self, timer: Timer) -> Option<Duration> {
        let phase = self.lifecycle.phase;
        // After the last tick only the match's end keeps time.
        let playing = matches!(phase, MatchPhase::Lobby | MatchPhase::Running);
        match timer {
            Timer::Silence if playing => self
                .players
                .iter()
                .flatten()
                .map(|p| p.last_heard.saturating_add(self.config.silence_timeout))
                .min(),
            Timer::Tick if playing => self.tick_deadline(self.next_tick),
            Timer::Arbiter if playing => self.arbiter.next_deadline(),
            Timer::JoinSnapshot if playing => self.joining.as_ref().map(|j| j.deadline),
            Timer::Locator if playing => self.locator.deadline(),
            Timer::Ping if playing => self.players.iter().flatten().map(|p| p.next_ping_at).min(),
            Timer::Lobby => self.lifecycle.lobby_deadline(),
            Timer::Resend => self.lifecycle.resend_deadline(),
            Timer::FinalReports => self.lifecycle.final_deadline(),
            _ => None,
        }
    }

    /// Does the work of expired timer `timer` at `now`.
    fn on_timer(&mut self, timer: Timer, now: Duration) {
        match timer {
            Timer::Silence => self.drop_silent(now),
            Timer::Tick => {
                while self.tick_deadline(self.next_tick).is_some_and(|d| now >= d) {
                    self.close_tick(now);
                }
                self.send_bundles(now);
                // A closed tick may be comparable at once.
                self.run_arbiter(now);
            }
            Timer::Arbiter => self.run_arbiter(now),
            Timer::JoinSnapshot => {
                if let Some(id) = self.joining.as_ref().map(|j| j.id) {
                    self.fail_join(now, id, "the agreed snapshot did not come in time");
                }
            }
            Timer::Locator => {
                let mut out = Vec::new();
                self.locator.on_timeout(now, &mut out);
                self.apply_search(out);
            }
            Timer::Ping => self.send_pings(now),
            // The lifecycle's step judges an expired lobby.
            Timer::Lobby => self.step_lifecycle(now),
            Timer::Resend => self.resend_final_bundles(now),
            Timer::FinalReports => self.end_finishing(now),
        }
    }

    /// Advances the room to `now`: handles every timer of the table that
    /// expired (silent players dropped, due ticks closed and broadcast,
    /// timed-out hashes compared, due pings sent, and the match's own
    /// deadlines under [`RoomConfig::lifecycle`](super::RoomConfig::lifecycle)).
    pub fn handle_timeout(&mut self, now: Duration) {
        for timer in Timer::ALL {
            if self.deadline(timer).is_some_and(|d| now >= d) {
                self.on_timer(timer, now);
            }
        }
        self.step_lifecycle(now);
    }

    /// The next time [`Room::handle_timeout`] has work to do: the earliest
    /// deadline of the room's timer table.
    pub fn poll_timeout(&self) -> Option<Duration> {
        Timer::ALL
            .into_iter()
            .filter_map(|t| self.deadline(t))
            .min()
    }

    /// When tick `tick` closes, once the match runs and while the tick is
    /// before the match's end.
    pub(crate) fn tick_deadline(&self, tick: u64) -> Option<Duration> {
        let epoch = self.epoch?;
        if self.lifecycle.end.is_some_and(|end| tick >= end) {
            return None;
        }
        Some(epoch.saturating_add(self.config.deadline_offset(tick)))
    }

    /// Drops every player heard nothing from for the silence timeout.
    fn drop_silent(&mut self, now: Duration) {
        for index in 0..self.players.len() {
            let Some(p) = &self.players[index] else {
                continue;
            };
            if now.saturating_sub(p.last_heard) >= self.config.silence_timeout {
                let id = self.id_of(index);
                let c = close(
                    CloseReason::TimedOut,
                    "nothing heard from the client".into(),
                );
                self.remove(now, id, LeaveReason::TimedOut, Some(c));
            }
        }
    }

    /// Pings every player due one.
    fn send_pings(&mut self, now: Duration) {
        for index in 0..self.players.len() {
            let nonce = self.ping_nonce;
            let Some(p) = &mut self.players[index] else {
                continue;
            };
            if now >= p.next_ping_at {
                p.ping = Some((nonce, now));
                p.next_ping_at = now.saturating_add(self.config.ping_interval);
                self.ping_nonce += 1;
                let to = self.id_of(index);
                self.transmits.push_back(Transmit {
                    to,
                    message: ServerMessage::Ping(Ping { nonce }),
                });
            }
        }
    }
}
