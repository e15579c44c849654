//! A room's reporting: the per-second status line, the replay file written
//! as the match runs, and the end-of-match summary.

use std::io::Write;

use std::time::Duration;

use lockstep_proto::{CloseReason, MatchPhase, PlayerId, PlayerStats};

use super::{RoomTask, Seat};
use crate::peer::{close_of, send_close};
use crate::{PlayerReport, RoomReport, RoomStatus, ServerEvent};

impl RoomTask {
    /// Copies the room's per-player counters into the reports (the room
    /// forgets them when a player leaves).
    pub(super) fn snapshot_stats(&mut self) {
        let ids: Vec<PlayerId> = self.room.players().map(|(id, _)| id).collect();
        for id in ids {
            let Some(stats) = self.room.player_stats(id).copied() else {
                continue;
            };
            let Some(report) = self.seat(id).map(|s| s.report) else {
                continue;
            };
            copy_stats(&mut self.players[report], &stats);
        }
    }

    /// Brings this room's part of the server's metrics up to date.
    pub(super) fn update_metrics(&mut self, ended: bool) {
        use std::sync::atomic::Ordering::Relaxed;
        let m = &self.shared.metrics;
        let players = if ended {
            0
        } else {
            self.room.player_count() as i64
        };
        let c = &mut self.counted;
        m.players.fetch_add(players - c.players, Relaxed);
        c.players = players;
        let mismatched = self.room.stats().mismatched_ticks;
        m.hash_mismatches
            .fetch_add(mismatched.saturating_sub(c.mismatched_ticks), Relaxed);
        c.mismatched_ticks = mismatched;
        let bad = self.room.stats().bad_snapshots;
        m.bad_snapshots
            .fetch_add(bad.saturating_sub(c.bad_snapshots), Relaxed);
        c.bad_snapshots = bad;
        if ended && c.running {
            c.running = false;
            m.matches_running.fetch_sub(1, Relaxed);
        }
    }

    pub(super) fn on_status(&mut self) {
        self.flush_replay(false);
        self.snapshot_stats();
        self.update_metrics(false);
        if self.room.phase() != MatchPhase::Running {
            return;
        }
        let mut down = 0u64;
        let mut up = 0u64;
        let mut rtts = Vec::new();
        let mut n = 0u64;
        let ids: Vec<PlayerId> = self.room.players().map(|(id, _)| id).collect();
        for id in ids {
            let rtt = self.room.player_stats(id).and_then(|s| s.rtt);
            rtts.extend(rtt);
            if let Some(seat) = self.seat(id) {
                let s = seat.peer.connection.stats();
                let (tx, rx) = (s.udp_tx.bytes, s.udp_rx.bytes);
                down += tx.saturating_sub(seat.last_udp_tx);
                up += rx.saturating_sub(seat.last_udp_rx);
                seat.last_udp_tx = tx;
                seat.last_udp_rx = rx;
                n += 1;
            }
        }
        {
            use std::sync::atomic::Ordering::Relaxed;
            self.shared.metrics.udp_bytes_out.fetch_add(down, Relaxed);
            self.shared.metrics.udp_bytes_in.fetch_add(up, Relaxed);
        }
        let stats = self.room.stats();
        let rtt = (!rtts.is_empty()).then(|| rtts.iter().sum::<Duration>() / rtts.len() as u32);
        let status = RoomStatus {
            room: self.name.clone(),
            tick: self.room.next_tick(),
            players: self.room.player_count(),
            rtt,
            down_bytes_per_sec: down / n.max(1),
            up_bytes_per_sec: up / n.max(1),
            ticks_compared: stats.ticks_compared,
            mismatched_ticks: stats.mismatched_ticks,
        };
        if self.shared.config.log_status {
            crate::log!("room {}: {status}", self.name);
        }
        self.shared.emit(ServerEvent::Status(status));
    }

    /// Appends the recorder's new records to the file; `sync` also asks the
    /// OS to put them on disk (at the end of the match).
    pub(super) fn flush_replay(&mut self, sync: bool) {
        let Some(r) = self.replay.as_mut() else {
            return;
        };
        if !r.started {
            // No file before the match starts; the recorder keeps the lobby.
            return;
        }
        let bytes = r.recorder.take_bytes();
        if let Some(f) = r.file.as_mut() {
            let ok = f.write_all(&bytes).and_then(|()| f.flush());
            let ok = if sync {
                ok.and_then(|()| f.sync_data())
            } else {
                ok
            };
            if let Err(e) = ok {
                crate::log!(
                    "room {}: replay {}: {e}; recording stops",
                    self.name,
                    r.path.display()
                );
                r.file = None;
            }
        }
    }

    pub(super) fn finish(&mut self) {
        // Players still seated (the task was told to stop abruptly).
        for index in 0..self.seats.len() {
            if let Some(seat) = self.seats[index].take() {
                let p = &mut self.players[seat.report];
                fill_traffic(p, &seat);
                if !seat.closing {
                    let close = close_of(CloseReason::RoomClosed, self.room.end_reason());
                    send_close(&seat.peer.writer, &close);
                }
            }
        }
        let reason = match self.room.end_reason() {
            "" => "room closed".to_owned(),
            r => r.to_owned(),
        };
        if let Some(r) = self.replay.as_mut() {
            r.recorder.finish(&reason);
        }
        self.flush_replay(true);
        self.update_metrics(true);
        // A lobby that closed before its match started played no match.
        if self.room.is_started() {
            self.shared
                .metrics
                .matches_total
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
        let stats = *self.room.stats();
        let duration = match (self.room.phase(), self.room.started_at()) {
            (MatchPhase::Running, Some(epoch)) => self.now().saturating_sub(epoch),
            _ => self
                .room
                .config()
                .deadline_offset(self.room.next_tick().saturating_sub(1)),
        };
        let report = RoomReport {
            room: self.name.clone(),
            ticks: self.room.next_tick(),
            ticks_compared: stats.ticks_compared,
            mismatched_ticks: stats.mismatched_ticks,
            bad_snapshots: stats.bad_snapshots,
            desyncs: self.desyncs.clone(),
            desync_notices: stats.desync_notices,
            located: self.located.clone(),
            forensics_bytes_down: self.forensics_bytes_down,
            forensics_bytes_up: self.forensics_bytes_up,
            verified: self
                .verifier
                .as_ref()
                .map(|_| (self.verified_ticks, self.verify_time)),
            lateness: crate::Lateness::of(&self.lateness_us),
            bundles: self.bundles.clone(),
            players: self.players.clone(),
            replay: self
                .replay
                .as_ref()
                .filter(|r| r.started && r.file.is_some())
                .map(|r| r.path.clone()),
            replay_hashed_ticks: self
                .replay
                .as_ref()
                .map_or(0, |r| r.recorder.hashed_ticks()),
            duration,
            end_reason: reason,
        };
        crate::log!(
            "room {}: closed: {} ticks, {} compared, {} mismatched, {} desync notices{}",
            self.name,
            report.ticks,
            report.ticks_compared,
            report.mismatched_ticks,
            report.desync_notices,
            report
                .replay
                .as_ref()
                .map(|p| format!(", replay {}", p.display()))
                .unwrap_or_default()
        );
        {
            let mut rooms = self.shared.rooms.lock().unwrap_or_else(|e| e.into_inner());
            if rooms.get(&self.name).is_some_and(|h| h.seq == self.seq) {
                rooms.remove(&self.name);
            }
        }
        // A lobby that closed before its match started played no match.
        if self.room.is_started()
            && let Ok(mut r) = self.shared.report.lock()
        {
            r.add_match(report.clone());
        }
        let started = self.room.is_started();
        self.shared.emit(ServerEvent::MatchEnded(report));
        // A lobby that closed is not the match `exit_after_match` waits for.
        if started {
            self.shared.match_ended.notify_one();
        }
    }
}

/// What a room last added to the server's metrics.
#[derive(Debug, Default)]
pub(super) struct Counted {
    /// Players seated.
    pub(super) players: i64,
    /// Mismatched ticks.
    pub(super) mismatched_ticks: u64,
    /// Whether its match counts as running.
    pub(super) running: bool,
    /// Bad snapshots given to joiners.
    pub(super) bad_snapshots: u64,
}

/// Copies the room's per-player counters into the player's report.
pub(super) fn copy_stats(p: &mut PlayerReport, stats: &PlayerStats) {
    p.rtt = stats.rtt;
    p.inputs_substituted = stats.inputs_substituted;
    p.hash_reports = stats.hash_reports;
    p.bad_snapshots = stats.bad_snapshots;
}

pub(super) fn fill_traffic(p: &mut PlayerReport, seat: &Seat) {
    let s = seat.peer.connection.stats();
    p.udp_bytes_down = s.udp_tx.bytes;
    p.udp_bytes_up = s.udp_rx.bytes;
    p.connected_for = seat.joined_at.elapsed();
}
