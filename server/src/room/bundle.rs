//! Desync bundles: when the room has located a desync, one file holds the
//! match's replay so far, the majority's snapshot of the last agreed tick
//! (checked against the agreed hash before it is kept) and the report, so
//! `lockstep replay BUNDLE` reproduces the diff offline.
//!
//! Layout: a replay file (same magic and records) with the report
//! (`ReplayRecord::Located`, already in the replay) and the snapshot
//! (`ReplayRecord::Snapshot` pieces) appended.

use std::path::PathBuf;
use std::time::Instant;

use lockstep_core::World;
use lockstep_proto::replay::encode_record;
use lockstep_proto::{DesyncReport, ReplayRecord, Slot};

use super::RoomTask;
use crate::ServerEvent;

/// Largest snapshot piece per record (records are bounded by the replay
/// format's limit).
const PIECE_BYTES: usize = 1 << 20;

/// Desyncs a room logs in full (the notice, the located report in at most
/// 40 lines, its snapshot and bundle): past them, a player that keeps
/// diverging (on a server that drops nobody for its hash) is counted, not
/// logged, so one liar cannot fill the log.
pub(super) const LOGGED_DESYNCS: usize = 16;

/// Desync bundles a room writes (each holds the replay so far).
const MAX_BUNDLES: usize = 4;

/// Desync notices and located reports a room's report keeps (the rest are
/// counted: `RoomStats::desync_notices`, `RoomStats::desyncs_located`), so
/// its memory does not grow with a player that keeps diverging.
pub(super) const KEPT_DESYNCS: usize = 256;

/// A snapshot the room checked against the agreed hash of its tick.
pub(super) struct CheckedSnapshot {
    tick: u64,
    hash: u64,
    bytes: Vec<u8>,
}

impl RoomTask {
    /// Keeps the reference's snapshot for the bundle if it restores and
    /// hashes to the agreed hash of its tick.
    pub(super) fn on_desync_snapshot(
        &mut self,
        tick: u64,
        agreed_hash: Option<u64>,
        from: Slot,
        bytes: Vec<u8>,
    ) {
        let name = &self.name;
        let log = self.room.stats().desyncs_located < LOGGED_DESYNCS as u64;
        let Some(expected) = agreed_hash else {
            if !log {
                return;
            }
            crate::log!(
                "room {name}: snapshot of tick {tick} from slot {}: no agreed hash to check it against; not kept",
                from.0
            );
            return;
        };
        match World::restore(&bytes) {
            Ok(w) if w.state_hash() == expected => {
                self.desync_snapshot = Some(CheckedSnapshot {
                    tick,
                    hash: expected,
                    bytes,
                });
            }
            _ if !log => {}
            Ok(w) => crate::log!(
                "room {name}: snapshot of tick {tick} from slot {} hashes to {:016x}, the agreed hash is {expected:016x}; not kept",
                from.0,
                w.state_hash()
            ),
            Err(e) => crate::log!(
                "room {name}: snapshot of tick {tick} from slot {}: {e}; not kept",
                from.0
            ),
        }
    }

    /// Logs and announces a located desync and writes its bundle.
    pub(super) fn on_desync_located(&mut self, report: DesyncReport) {
        let took = self
            .notice_at
            .take()
            .map(|t| format!(" ({} ms after the notice)", t.elapsed().as_millis()))
            .unwrap_or_default();
        // The room counted it already.
        let located = self.room.stats().desyncs_located;
        if located > LOGGED_DESYNCS as u64 {
            // Counted (the room's report keeps the first ones), not
            // logged, no bundle.
            self.desync_snapshot = None;
            if self.located.len() < KEPT_DESYNCS {
                self.located.push(report.clone());
            }
            self.shared.emit(ServerEvent::DesyncLocated {
                room: self.name.clone(),
                report,
                bundle: None,
                at: Instant::now(),
            });
            return;
        }
        // At most 40 lines a desync, however many bodies a report lists
        // (every player got the whole report, and the bundle keeps it).
        let text = report.to_string();
        let lines: Vec<&str> = text.lines().collect();
        let shown = lines.len().min(40);
        let more = if lines.len() > shown {
            format!("\n  ... {} more lines in the report", lines.len() - shown)
        } else {
            String::new()
        };
        crate::log!(
            "room {}: {}{more}{took}",
            self.name,
            lines[..shown].join("\n")
        );
        let bundle = if self.bundles.len() < MAX_BUNDLES {
            self.write_bundle(&report)
        } else {
            self.desync_snapshot = None;
            None
        };
        if let Some(p) = &bundle {
            crate::log!("room {}: desync bundle {}", self.name, p.display());
            self.bundles.push(p.clone());
        }
        self.located.push(report.clone());
        self.shared.emit(ServerEvent::DesyncLocated {
            room: self.name.clone(),
            report,
            bundle,
            at: Instant::now(),
        });
    }

    /// The replay so far (flushed and read back), with the checked
    /// snapshot appended. `None` without a replay, or on an I/O error
    /// (logged).
    fn write_bundle(&mut self, report: &DesyncReport) -> Option<PathBuf> {
        let snapshot = self.desync_snapshot.take();
        self.flush_replay(true);
        let r = self.replay.as_ref().filter(|r| r.file.is_some())?;
        let path = r
            .path
            .with_extension(format!("desync-{}.bundle", report.tick));
        let mut bytes = match std::fs::read(&r.path) {
            Ok(b) => b,
            Err(e) => {
                crate::log!("room {}: bundle: {}: {e}", self.name, r.path.display());
                return None;
            }
        };
        match &snapshot {
            Some(s) => {
                let total = s.bytes.len() as u64;
                for (i, piece) in s.bytes.chunks(PIECE_BYTES).enumerate() {
                    let record = ReplayRecord::Snapshot {
                        tick: s.tick,
                        hash: s.hash,
                        total,
                        offset: (i * PIECE_BYTES) as u64,
                        bytes: piece.to_vec(),
                    };
                    // A piece is far below the record limit.
                    if let Ok(b) = encode_record(&record) {
                        bytes.extend(b);
                    }
                }
            }
            None => crate::log!(
                "room {}: the bundle of tick {} holds no snapshot (none checked)",
                self.name,
                report.tick
            ),
        }
        match std::fs::write(&path, &bytes) {
            Ok(()) => Some(path),
            Err(e) => {
                crate::log!("room {}: bundle {}: {e}", self.name, path.display());
                None
            }
        }
    }
}
