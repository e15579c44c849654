//! Judging the players' state hashes: the arbiter's comparisons, the
//! players dropped for missing or wrong hashes, desync notices, and the
//! search that locates a desync.

use std::time::Duration;

use super::arbiter::{Comparison, Recorded, SlotMask, bit};
use super::errors::close;
use super::locate::Output;
use super::{LeaveReason, PlayerId, Rejection, Room, RoomEvent, Transmit};
use crate::message::{CloseReason, HashReport, ServerMessage, Slot};

impl Room {
    pub(super) fn on_hash(
        &mut self,
        now: Duration,
        from: PlayerId,
        h: HashReport,
    ) -> Result<(), Rejection> {
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

    /// The players seated with a join token (the voters under
    /// [`Voting::TokenHolders`]).
    pub(super) fn token_holders(&self) -> SlotMask {
        (0..self.players.len())
            .filter(|&i| self.players[i].as_ref().is_some_and(|p| p.ticket.is_some()))
            .fold(0, |m, i| m | bit(Slot(i as u8)))
    }

    pub(super) fn run_arbiter(&mut self, now: Duration) {
        self.arbiter.voters = self.token_holders();
        let connected = self.present_mask();
        for (tick, c) in self.arbiter.finalize(now, connected) {
            self.apply_comparison(now, tick, c);
        }
    }

    pub(super) fn apply_comparison(&mut self, now: Duration, tick: u64, c: Comparison) {
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

    /// Sends the search's probes, and announces its report and snapshot.
    pub(super) fn apply_search(&mut self, out: Vec<Output>) {
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
