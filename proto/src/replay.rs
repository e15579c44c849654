//! Replay files: a match as it was played — the scene, the players, every
//! tick's bundle and the hash the players agreed on — so it can be
//! re-simulated offline and every tick checked.
//!
//! The server writes a replay *as the match runs*: each record is appended
//! (and the file flushed about once a second) the moment it is known, so a
//! crash loses at most the records of the last second. The reader therefore
//! accepts a file whose last record is cut short and says so
//! ([`Replay::truncated`]).
//!
//! # Layout
//! ```text
//! "LSREPLAY" (8 bytes) | format version u16 LE | record*
//! record = length u32 LE | ReplayRecord in bincode 2 (the protocol's config)
//! ```
//! The first record is [`ReplayRecord::Header`]. Bundles ([`ReplayRecord::Tick`])
//! come in tick order from 0 without gaps; the agreed hash of a tick
//! ([`ReplayRecord::Hash`]) follows its bundle once enough players reported
//! it, usually a few ticks later.
//!
//! [`ReplayRecorder`] turns the room's events and the accepted hash reports
//! into these records; it is pure (no file, no clock), the server appends its
//! bytes to the file.

use bincode::config::{Configuration, Limit, LittleEndian, Varint};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::forensics::DesyncReport;
use crate::limits::MAX_MESSAGE_BYTES;
use crate::message::{DesyncNotice, Slot, TickBundle};

mod recorder;

pub use recorder::ReplayRecorder;

/// First bytes of every replay file, so a wrong file is refused at once.
pub const REPLAY_MAGIC: [u8; 8] = *b"LSREPLAY";

/// Version of the replay layout; bump on any change to [`ReplayRecord`].
///
/// Version 2 added what made the replay to the header (engine version,
/// state-hash layout, the rules' id and version) and per-body hash records.
/// Version 3 added desync reports and snapshot records (desync bundles);
/// version 2 files are still read (they cannot hold those records).
/// Version 4 added the game state and the tick's inputs to desync reports;
/// version 3 files read unless they hold a desync report (then they are
/// refused as too old).
pub const REPLAY_FORMAT_VERSION: u16 = 4;

/// The oldest format version this build reads.
pub const REPLAY_OLDEST_READABLE: u16 = 2;

/// The engine version recorded in new replays: the workspace version, which
/// lockstep-core, lockstep-proto and the server share.
pub const ENGINE_VERSION: &str = env!("CARGO_PKG_VERSION");

/// Which game rules a match was played with: the id names the game, the
/// version changes whenever the rules turn the same inputs into different
/// forces. A replay is only meaningful with the rules that recorded it.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct RulesId {
    /// The game's name, e.g. `"lockstep-demo"`.
    pub id: String,
    /// The rules' version.
    pub version: u32,
}

impl RulesId {
    /// Rules `id` at `version`.
    pub fn new(id: impl Into<String>, version: u32) -> Self {
        Self {
            id: id.into(),
            version,
        }
    }
}

impl std::fmt::Display for RulesId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} v{}", self.id, self.version)
    }
}

/// Bytes before the first record: the magic and the format version.
pub const REPLAY_PREAMBLE_BYTES: usize = REPLAY_MAGIC.len() + 2;

/// Largest record accepted: a header with the largest scene fits.
pub const MAX_RECORD_BYTES: usize = MAX_MESSAGE_BYTES;

const CONFIG: Configuration<LittleEndian, Varint, Limit<MAX_RECORD_BYTES>> =
    bincode::config::standard().with_limit::<MAX_RECORD_BYTES>();

/// What a replay needs before the first tick: enough to rebuild the world
/// every player started from.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ReplayHeader {
    /// [`PROTOCOL_VERSION`](crate::PROTOCOL_VERSION) of the server that
    /// recorded it (the meaning of the inputs may depend on it).
    pub protocol_version: u16,
    /// The room's name.
    pub room: String,
    /// Ticks per second of the match.
    pub tick_rate: u16,
    /// Input delay of the match, in ticks.
    pub input_delay: u16,
    /// The scene's hash as announced in the welcome (the initial
    /// `state_hash` of the world built from it).
    pub scene_hash: u64,
    /// The scene, exactly as sent to the players.
    pub scene: Vec<u8>,
    /// [`ENGINE_VERSION`] of the server that recorded it.
    pub engine_version: String,
    /// The state-hash layout (`lockstep_core::world::STATE_HASH_VERSION`)
    /// the players' hashes were computed with: hashes of two layouts never
    /// compare.
    pub hash_layout: u64,
    /// The game rules the match was played with.
    pub rules: RulesId,
}

/// One entry of a replay file.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ReplayRecord {
    /// Always first.
    Header(ReplayHeader),
    /// A player took `slot`; their inputs appear from `from_tick` on.
    PlayerJoined {
        /// The seat.
        slot: Slot,
        /// Display name.
        name: String,
        /// First tick they were part of.
        from_tick: u64,
    },
    /// A player left; bundles from `from_tick` on no longer list them.
    PlayerLeft {
        /// The seat.
        slot: Slot,
        /// First tick without them.
        from_tick: u64,
        /// Why, for people reading the replay.
        reason: String,
    },
    /// The bundle every player applied for its tick.
    Tick(TickBundle),
    /// The hash held by a strict majority of the players who reported for
    /// `tick`: what a correct re-simulation must produce.
    Hash {
        /// The tick.
        tick: u64,
        /// The agreed state hash after applying that tick's bundle.
        hash: u64,
    },
    /// Every body's hash after `tick` (in body handle order), as reported by
    /// a player whose state hash was the agreed one: lets a checker name the
    /// bodies that diverge. Only for ticks where players sent body hashes.
    BodyHashes {
        /// The tick.
        tick: u64,
        /// One hash per body, as `World::body_hashes` lists them.
        hashes: Vec<u64>,
    },
    /// The room found a desync at this tick (the notice it sent).
    Desync(DesyncNotice),
    /// The match ended normally after `ticks` ticks.
    End {
        /// Ticks played.
        ticks: u64,
        /// Why it ended.
        reason: String,
    },
    // Format version 3 (appended, so version 2 files read as before).
    /// Where a desync lies: the report the room sent to the players.
    Located(DesyncReport),
    /// A piece of the world snapshot after `tick` (a desync bundle's last
    /// agreed state): the pieces of one snapshot follow each other, offsets
    /// ascending from 0, until `total` bytes.
    Snapshot {
        /// The tick.
        tick: u64,
        /// The agreed hash of that tick, which the snapshot was checked
        /// against.
        hash: u64,
        /// The snapshot's whole length.
        total: u64,
        /// Offset of this piece.
        offset: u64,
        /// The piece.
        bytes: Vec<u8>,
    },
    // Format version 4.
    /// The match's seed (right after the header; a replay without one has
    /// seed 0).
    Seed(u64),
}

/// Why a replay could not be written.
#[derive(Debug, Error)]
pub enum ReplayEncodeError {
    /// bincode refused the record.
    #[error("bincode: {0}")]
    Bincode(#[source] bincode::error::EncodeError),
    /// The record is larger than [`MAX_RECORD_BYTES`].
    #[error("record of {0} bytes is too large")]
    TooLarge(usize),
}

/// Why bytes are not a readable replay.
#[derive(Debug, Error)]
pub enum ReplayError {
    /// The file does not start with [`REPLAY_MAGIC`].
    #[error("not a lockstep replay (bad magic)")]
    BadMagic,
    /// Written by another version of the format (version 1 replays predate
    /// the header's engine, hash-layout and rules fields).
    #[error(
        "replay format version {found}, this build reads versions {REPLAY_OLDEST_READABLE} to {expected}{}",
        if *found < *expected {
            " (an older replay whose records this build cannot read: re-record it)"
        } else {
            " (a newer replay: check it with a newer build)"
        }
    )]
    WrongVersion {
        /// Version in the file.
        found: u16,
        /// [`REPLAY_FORMAT_VERSION`].
        expected: u16,
    },
    /// A record's length prefix exceeds [`MAX_RECORD_BYTES`].
    #[error("record at byte {offset} claims {len} bytes")]
    RecordTooLarge {
        /// Offset of the record in the file.
        offset: usize,
        /// Claimed length.
        len: usize,
    },
    /// A complete record does not decode.
    #[error("record at byte {offset} is malformed: {source}")]
    Malformed {
        /// Offset of the record in the file.
        offset: usize,
        /// What bincode said.
        #[source]
        source: bincode::error::DecodeError,
    },
    /// The first record is not a header, or a header appears again.
    #[error("record at byte {offset}: the header must be the first record and only that")]
    MisplacedHeader {
        /// Offset of the record in the file.
        offset: usize,
    },
    /// The file ends before the header.
    #[error("the replay has no header")]
    NoHeader,
    /// Bundles are not consecutive from tick 0.
    #[error("bundle of tick {found} where tick {expected} was expected")]
    TickGap {
        /// The tick that should come next.
        expected: u64,
        /// The tick found.
        found: u64,
    },
    /// Snapshot pieces that do not follow each other.
    #[error("record at byte {offset}: a snapshot piece out of order")]
    BadSnapshot {
        /// Offset of the record in the file.
        offset: usize,
    },
    /// A hash for a tick whose bundle is not (yet) in the file, or two
    /// different hashes for one tick.
    #[error("hash record for tick {0} without its bundle, or twice")]
    BadHash(u64),
}

/// Encodes the file preamble (magic and format version).
pub fn encode_preamble() -> Vec<u8> {
    let mut out = REPLAY_MAGIC.to_vec();
    out.extend_from_slice(&REPLAY_FORMAT_VERSION.to_le_bytes());
    out
}

/// Encodes one record with its length prefix, ready to append to a file.
///
/// # Errors
/// [`ReplayEncodeError`] if bincode refuses it or it is too large.
pub fn encode_record(record: &ReplayRecord) -> Result<Vec<u8>, ReplayEncodeError> {
    let body = bincode::serde::encode_to_vec(record, CONFIG).map_err(ReplayEncodeError::Bincode)?;
    if body.len() > MAX_RECORD_BYTES {
        return Err(ReplayEncodeError::TooLarge(body.len()));
    }
    let mut out = Vec::with_capacity(4 + body.len());
    // Bounded by MAX_RECORD_BYTES, far below u32::MAX.
    out.extend_from_slice(&(body.len() as u32).to_le_bytes());
    out.extend_from_slice(&body);
    Ok(out)
}

/// A replay read back: the header, the timeline of bundles with their agreed
/// hashes, and everything else the server noted.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Replay {
    /// The match's settings and scene.
    pub header: ReplayHeader,
    /// Bundles of ticks `0..ticks.len()`, in order.
    pub ticks: Vec<TickBundle>,
    /// The agreed hash of each tick in `ticks`, where one was recorded.
    pub hashes: Vec<Option<u64>>,
    /// Players in the order they joined: slot, name, first tick.
    pub players: Vec<(Slot, String, u64)>,
    /// Departures: slot, first tick without them, reason.
    pub departures: Vec<(Slot, u64, String)>,
    /// Recorded per-body hashes: tick and the hashes, in tick order.
    pub body_hashes: Vec<(u64, Vec<u64>)>,
    /// Desync notices the room raised.
    pub desyncs: Vec<DesyncNotice>,
    /// Where the room located them.
    pub located: Vec<DesyncReport>,
    /// A bundle's snapshot: tick, agreed hash, bytes (complete only).
    pub snapshot: Option<(u64, u64, Vec<u8>)>,
    /// Ticks played and the reason, if the match ended normally.
    pub end: Option<(u64, String)>,
    /// Whether the file ends inside a record (the server stopped while
    /// writing it, e.g. a crash); everything before it was read.
    pub truncated: bool,
    /// The match's seed (0 when the replay records none).
    pub seed: u64,
}

impl Replay {
    /// Parses a whole replay file.
    ///
    /// # Errors
    /// [`ReplayError`] for a file that is not a replay, or whose complete
    /// records are inconsistent. A cut-short last record is not an error.
    pub fn parse(bytes: &[u8]) -> Result<Replay, ReplayError> {
        let Some((magic, rest)) = bytes.split_first_chunk::<8>() else {
            return Err(ReplayError::BadMagic);
        };
        if *magic != REPLAY_MAGIC {
            return Err(ReplayError::BadMagic);
        }
        let Some((version, _)) = rest.split_first_chunk::<2>() else {
            return Err(ReplayError::NoHeader);
        };
        let found = u16::from_le_bytes(*version);
        if !(REPLAY_OLDEST_READABLE..=REPLAY_FORMAT_VERSION).contains(&found) {
            return Err(ReplayError::WrongVersion {
                found,
                expected: REPLAY_FORMAT_VERSION,
            });
        }
        let mut offset = REPLAY_PREAMBLE_BYTES;
        let mut header = None;
        let mut replay_parts = Parts::default();
        let mut truncated = false;
        while offset < bytes.len() {
            let Some(len_bytes) = bytes[offset..].first_chunk::<4>() else {
                truncated = true;
                break;
            };
            let len = u32::from_le_bytes(*len_bytes) as usize;
            if len > MAX_RECORD_BYTES {
                return Err(ReplayError::RecordTooLarge { offset, len });
            }
            let start = offset + 4;
            let Some(body) = bytes.get(start..start + len) else {
                truncated = true;
                break;
            };
            let (record, used) = bincode::serde::decode_from_slice::<ReplayRecord, _>(body, CONFIG)
                .map_err(|source| {
                    if found < REPLAY_FORMAT_VERSION {
                        // A record of an older shape (a version 3 desync
                        // report).
                        ReplayError::WrongVersion {
                            found,
                            expected: REPLAY_FORMAT_VERSION,
                        }
                    } else {
                        ReplayError::Malformed { offset, source }
                    }
                })?;
            if used != body.len() {
                return Err(ReplayError::Malformed {
                    offset,
                    source: bincode::error::DecodeError::Other("trailing bytes in record"),
                });
            }
            match (record, header.is_some()) {
                (ReplayRecord::Header(h), false) => header = Some(h),
                (ReplayRecord::Header(_), true) | (_, false) => {
                    return Err(ReplayError::MisplacedHeader { offset });
                }
                (record, true) => replay_parts.add(record, offset)?,
            }
            offset = start + len;
        }
        let header = header.ok_or(ReplayError::NoHeader)?;
        Ok(Replay {
            header,
            ticks: replay_parts.ticks,
            hashes: replay_parts.hashes,
            players: replay_parts.players,
            departures: replay_parts.departures,
            body_hashes: replay_parts.body_hashes,
            desyncs: replay_parts.desyncs,
            located: replay_parts.located,
            snapshot: replay_parts
                .snapshot
                .filter(|(_, _, total, b)| b.len() as u64 == *total)
                .map(|(t, h, _, b)| (t, h, b)),
            end: replay_parts.end,
            seed: replay_parts.seed,
            truncated,
        })
    }

    /// Number of ticks with an agreed hash.
    pub fn hashed_ticks(&self) -> usize {
        self.hashes.iter().flatten().count()
    }
}

#[derive(Default)]
struct Parts {
    ticks: Vec<TickBundle>,
    hashes: Vec<Option<u64>>,
    players: Vec<(Slot, String, u64)>,
    departures: Vec<(Slot, u64, String)>,
    body_hashes: Vec<(u64, Vec<u64>)>,
    desyncs: Vec<DesyncNotice>,
    located: Vec<DesyncReport>,
    snapshot: Option<(u64, u64, u64, Vec<u8>)>,
    end: Option<(u64, String)>,
    seed: u64,
}

impl Parts {
    fn add(&mut self, record: ReplayRecord, offset: usize) -> Result<(), ReplayError> {
        let at = offset;
        match record {
            ReplayRecord::Header(_) => return Err(ReplayError::MisplacedHeader { offset }),
            ReplayRecord::Seed(seed) => self.seed = seed,
            ReplayRecord::PlayerJoined {
                slot,
                name,
                from_tick,
            } => self.players.push((slot, name, from_tick)),
            ReplayRecord::PlayerLeft {
                slot,
                from_tick,
                reason,
            } => self.departures.push((slot, from_tick, reason)),
            ReplayRecord::Tick(bundle) => {
                let expected = self.ticks.len() as u64;
                if bundle.tick != expected {
                    return Err(ReplayError::TickGap {
                        expected,
                        found: bundle.tick,
                    });
                }
                self.ticks.push(bundle);
                self.hashes.push(None);
            }
            ReplayRecord::Hash { tick, hash } => {
                let slot = usize::try_from(tick)
                    .ok()
                    .and_then(|i| self.hashes.get_mut(i))
                    .ok_or(ReplayError::BadHash(tick))?;
                if slot.is_some_and(|h| h != hash) {
                    return Err(ReplayError::BadHash(tick));
                }
                *slot = Some(hash);
            }
            ReplayRecord::BodyHashes { tick, hashes } => {
                if tick >= self.ticks.len() as u64 {
                    return Err(ReplayError::BadHash(tick));
                }
                self.body_hashes.push((tick, hashes));
            }
            ReplayRecord::Desync(n) => self.desyncs.push(n),
            ReplayRecord::Located(r) => self.located.push(r),
            ReplayRecord::Snapshot {
                tick,
                hash,
                total,
                offset,
                bytes,
            } => {
                let fresh = offset == 0;
                let s = self.snapshot.get_or_insert((tick, hash, total, Vec::new()));
                if fresh {
                    *s = (tick, hash, total, Vec::new());
                }
                if (s.0, s.1, s.2) != (tick, hash, total)
                    || offset != s.3.len() as u64
                    || s.3.len() as u64 + bytes.len() as u64 > total
                {
                    return Err(ReplayError::BadSnapshot { offset: at });
                }
                s.3.extend_from_slice(&bytes);
            }
            ReplayRecord::End { ticks, reason } => self.end = Some((ticks, reason)),
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
