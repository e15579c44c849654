//! Locating a desync: the probes the room sends when hashes disagree, the
//! clients' answers, and the report naming the bodies and fields that
//! differ.
//!
//! When a tick's hashes disagree the room asks one client of the majority
//! (the *reference*) and every client outside it (the *suspects*) for their
//! per-body hashes of that tick, chunk by chunk; then, for the bodies whose
//! hashes differ (the first [`MAX_PROBE_BODIES`] in handle order), for every
//! hashed field as raw words. Clients answer from a short ring of past
//! ticks, so nothing is sent in steady state. The protocol does not
//! interpret the fields: names and words come from the engine, and a field
//! of kind [`FieldKind::Scalar`] is printed as a Q32.32 number.

use serde::{Deserialize, Serialize};

use crate::limits::{
    MAX_BODY_HASHES, MAX_DUMP_FIELDS, MAX_FIELD_NAME_BYTES, MAX_FIELD_WORDS, MAX_INPUT_BYTES,
    MAX_NAME_BYTES, MAX_PLAYERS, MAX_PROBE_BODIES, MAX_PROBE_SNAPSHOT_BYTES,
    MAX_PROBE_TOTAL_BODIES, MAX_REPORT_FIELDS, MAX_SNAPSHOT_CHUNK_BYTES,
};
use crate::message::{PlayerInput, Slot, Violation};

/// What the room asks a client about a past tick.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ProbeAsk {
    /// The per-body hashes (handle order) from body `from` on, at most
    /// [`MAX_BODY_HASHES`] per answer.
    BodyHashes {
        /// First body index wanted.
        from: u32,
    },
    /// Every hashed field of these bodies (indices in handle order,
    /// ascending, at most [`MAX_PROBE_BODIES`]).
    Fields {
        /// The bodies.
        bodies: Vec<u32>,
    },
    /// The world snapshot after the tick, from byte `offset` on, at most
    /// [`MAX_SNAPSHOT_CHUNK_BYTES`] per answer.
    Snapshot {
        /// First byte wanted.
        offset: u32,
    },
}

/// A question about the client's world after applying `tick` (reliable).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Probe {
    /// The tick asked about.
    pub tick: u64,
    /// What is asked.
    pub ask: ProbeAsk,
}

/// How a dumped field's words read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum FieldKind {
    /// Unsigned words (flags, counts, handles, hashes).
    Word,
    /// Signed integers.
    Int,
    /// Q32.32 fixed-point raw bits.
    Scalar,
}

/// One field of a body, as its state hash sees it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FieldDump {
    /// The engine's name for it.
    pub name: String,
    /// How its words read.
    pub kind: FieldKind,
    /// The raw words.
    pub words: Vec<u64>,
}

/// Every hashed field of one body.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct BodyDump {
    /// Position in handle order (the index in the body-hash list).
    pub index: u32,
    /// The body handle's index.
    pub handle: u32,
    /// The body handle's generation.
    pub generation: u32,
    /// The body's name in the scene (may be empty).
    pub name: String,
    /// Its fields in hash order.
    pub fields: Vec<FieldDump>,
}

/// A client's answer to a [`Probe`].
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ProbeAnswer {
    /// The tick is no longer (or not yet) in the client's ring.
    Unavailable,
    /// A chunk of the per-body hashes.
    BodyHashes {
        /// Bodies in the world.
        total: u32,
        /// Index of `hashes[0]`.
        from: u32,
        /// The hash of the world's contact state alone.
        contacts: u64,
        /// The hash of the game's own state alone.
        game: u64,
        /// Consecutive body hashes.
        hashes: Vec<u64>,
    },
    /// The asked bodies' fields (a body index past the world is left out),
    /// and every field of the game's own state.
    Fields {
        /// One dump per body, ascending by index.
        bodies: Vec<BodyDump>,
        /// The game state's fields, in order (at most
        /// [`MAX_DUMP_FIELDS`]).
        game: Vec<FieldDump>,
    },
    /// A chunk of the snapshot.
    Snapshot {
        /// The snapshot's length.
        total: u32,
        /// Offset of `bytes[0]`.
        offset: u32,
        /// The chunk.
        bytes: Vec<u8>,
    },
}

/// The answer to the probe of `tick` (reliable).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProbeReply {
    /// The tick of the probe answered.
    pub tick: u64,
    /// The answer.
    pub answer: ProbeAnswer,
}

/// One field that differs: the reference's words and the suspect's.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FieldDiff {
    /// The field's name.
    pub name: String,
    /// How its words read.
    pub kind: FieldKind,
    /// The reference's words (empty: the reference has no such field).
    pub expected: Vec<u64>,
    /// The suspect's words (empty: the suspect has no such field).
    pub got: Vec<u64>,
}

/// A body whose hash differs between the reference and a suspect.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct BodyDiff {
    /// Position in handle order.
    pub index: u32,
    /// Handle index (from the reference's dump; the suspect's if only it
    /// has the body).
    pub handle: u32,
    /// Handle generation.
    pub generation: u32,
    /// The body's name.
    pub name: String,
    /// The fields that differ, in hash order (empty when no dump came).
    pub fields: Vec<FieldDiff>,
}

/// How far the room got with one player.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ProbeStatus {
    /// Every answer came.
    Complete,
    /// The player no longer had the tick in its ring.
    Unavailable,
    /// The player left, or did not answer in time.
    NoAnswer,
}

/// What differs between the reference and one suspect.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SuspectReport {
    /// The suspect.
    pub slot: Slot,
    /// How far the probes got with it.
    pub status: ProbeStatus,
    /// Bodies whose hash differs (all of them, listed or not).
    pub bodies_differing: u32,
    /// Whether the contact state differs.
    pub contacts_differ: bool,
    /// Whether the game's own state differs.
    pub game_differs: bool,
    /// The game-state fields that differ, in the reference's order.
    pub game: Vec<FieldDiff>,
    /// The first differing bodies with their differing fields, ascending.
    pub bodies: Vec<BodyDiff>,
}

/// Where a desync lies: sent to every player, logged and recorded.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct DesyncReport {
    /// The tick of the desync notice.
    pub tick: u64,
    /// Whose state the others were compared with.
    pub reference: Slot,
    /// Whether the reference holds the majority hash (otherwise the
    /// verdict was undecided and the lowest reporting slot is the
    /// reference).
    pub majority: bool,
    /// How far the probes got with the reference.
    pub reference_status: ProbeStatus,
    /// One entry per player whose hash differed, ascending by slot.
    pub suspects: Vec<SuspectReport>,
    /// Differing fields left out past [`MAX_REPORT_FIELDS`].
    pub fields_omitted: u32,
    /// The inputs of the desync tick, as every player applied them (empty
    /// when the room no longer held the tick).
    pub inputs: Vec<PlayerInput>,
}

impl DesyncReport {
    /// The first diverging body in handle order over every suspect.
    pub fn first_body(&self) -> Option<&BodyDiff> {
        self.suspects
            .iter()
            .flat_map(|s| s.bodies.first())
            .min_by_key(|b| b.index)
    }
}

fn check(len: usize, max: usize, err: fn(usize, usize) -> Violation) -> Result<(), Violation> {
    if len > max {
        Err(err(len, max))
    } else {
        Ok(())
    }
}

fn entries(count: usize, max: usize) -> Violation {
    Violation::TooManyEntries { count, max }
}

fn name(len: usize, max: usize) -> Violation {
    Violation::NameTooLong { len, max }
}

fn check_field(name_len: usize, words: &[u64]) -> Result<(), Violation> {
    check(name_len, MAX_FIELD_NAME_BYTES, name)?;
    check(words.len(), MAX_FIELD_WORDS, entries)
}

impl Probe {
    /// Checks the bounds a decoder enforces.
    ///
    /// # Errors
    /// The first [`Violation`].
    pub fn validate(&self) -> Result<(), Violation> {
        if let ProbeAsk::Fields { bodies } = &self.ask {
            check(bodies.len(), MAX_PROBE_BODIES, entries)?;
        }
        Ok(())
    }
}

impl ProbeReply {
    /// Checks the bounds a decoder enforces.
    ///
    /// # Errors
    /// The first [`Violation`].
    pub fn validate(&self) -> Result<(), Violation> {
        match &self.answer {
            ProbeAnswer::Unavailable => Ok(()),
            ProbeAnswer::BodyHashes { total, hashes, .. } => {
                check(*total as usize, MAX_PROBE_TOTAL_BODIES, entries)?;
                check(hashes.len(), MAX_BODY_HASHES, entries)
            }
            ProbeAnswer::Fields { bodies, game } => {
                check(game.len(), MAX_DUMP_FIELDS, entries)?;
                for f in game {
                    check_field(f.name.len(), &f.words)?;
                }
                check(bodies.len(), MAX_PROBE_BODIES, entries)?;
                for b in bodies {
                    check(b.name.len(), MAX_NAME_BYTES, name)?;
                    check(b.fields.len(), MAX_DUMP_FIELDS, entries)?;
                    for f in &b.fields {
                        check_field(f.name.len(), &f.words)?;
                    }
                }
                Ok(())
            }
            ProbeAnswer::Snapshot { total, bytes, .. } => {
                check(*total as usize, MAX_PROBE_SNAPSHOT_BYTES, |len, max| {
                    Violation::SnapshotTooLarge {
                        what: "total",
                        len,
                        max,
                    }
                })?;
                check(bytes.len(), MAX_SNAPSHOT_CHUNK_BYTES, |len, max| {
                    Violation::SnapshotTooLarge {
                        what: "piece",
                        len,
                        max,
                    }
                })
            }
        }
    }
}

impl DesyncReport {
    /// Checks the bounds a decoder enforces.
    ///
    /// # Errors
    /// The first [`Violation`].
    pub fn validate(&self) -> Result<(), Violation> {
        check(self.suspects.len(), MAX_PLAYERS, entries)?;
        check(self.inputs.len(), MAX_PLAYERS, entries)?;
        for p in &self.inputs {
            if p.slot.index() >= MAX_PLAYERS {
                return Err(Violation::SlotOutOfRange(p.slot.0));
            }
            check(p.input.len(), MAX_INPUT_BYTES, |len, max| {
                Violation::InputTooLarge { len, max }
            })?;
        }
        let mut fields = 0;
        for s in &self.suspects {
            if s.slot.index() >= MAX_PLAYERS {
                return Err(Violation::SlotOutOfRange(s.slot.0));
            }
            check(s.bodies.len(), MAX_PROBE_BODIES, entries)?;
            fields += s.game.len();
            for f in &s.game {
                check_field(f.name.len(), &f.expected)?;
                check_field(f.name.len(), &f.got)?;
            }
            for b in &s.bodies {
                check(b.name.len(), MAX_NAME_BYTES, name)?;
                fields += b.fields.len();
                for f in &b.fields {
                    check_field(f.name.len(), &f.expected)?;
                    check_field(f.name.len(), &f.got)?;
                }
            }
        }
        check(fields, MAX_REPORT_FIELDS, entries)
    }
}

/// A Q32.32 value from its raw bits, in exact decimal (every bit shows:
/// the fraction of a Q32.32 number has at most 32 decimal digits).
pub fn q32_decimal(bits: u64) -> String {
    let v = bits as i64;
    let mag = v.unsigned_abs();
    let (int, mut frac) = (mag >> 32, mag & 0xffff_ffff);
    let mut out = String::new();
    if v < 0 {
        out.push('-');
    }
    out.push_str(&int.to_string());
    if frac != 0 {
        out.push('.');
        while frac != 0 {
            frac *= 10;
            out.push(char::from(b'0' + (frac >> 32) as u8));
            frac &= 0xffff_ffff;
        }
    }
    out
}

fn words_text(kind: FieldKind, words: &[u64]) -> String {
    if words.is_empty() {
        return "absent".into();
    }
    let items: Vec<String> = words
        .iter()
        .map(|&w| match kind {
            FieldKind::Scalar => format!("{} (0x{w:016x})", q32_decimal(w)),
            FieldKind::Int => format!("{} (0x{w:016x})", w as i64),
            FieldKind::Word => format!("{w} (0x{w:016x})"),
        })
        .collect();
    format!("[{}]", items.join(", "))
}

impl std::fmt::Display for FieldDiff {
    /// `NAME: expected […], got […]` (a side without the field: `absent`).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: expected {}, got {}",
            self.name,
            words_text(self.kind, &self.expected),
            words_text(self.kind, &self.got)
        )
    }
}

impl std::fmt::Display for BodyDiff {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "body #{} {:?} (handle {}:{})",
            self.index, self.name, self.handle, self.generation
        )
    }
}

impl std::fmt::Display for DesyncReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let whose = if self.majority {
            "the majority"
        } else {
            "no majority"
        };
        writeln!(
            f,
            "desync located at tick {}: compared with slot {} ({whose}, {:?})",
            self.tick, self.reference.0, self.reference_status
        )?;
        match self.first_body() {
            Some(b) => writeln!(f, "  first diverging body in handle order: {b}")?,
            None => writeln!(f, "  no diverging body found")?,
        }
        if !self.inputs.is_empty() {
            let inputs: Vec<String> = self
                .inputs
                .iter()
                .map(|p| {
                    let hex: String = p.input.iter().map(|b| format!("{b:02x}")).collect();
                    let sub = if p.substituted { " (substituted)" } else { "" };
                    format!("slot {} [{hex}]{sub}", p.slot.0)
                })
                .collect();
            writeln!(f, "  inputs of tick {}: {}", self.tick, inputs.join(", "))?;
        }
        for s in &self.suspects {
            writeln!(
                f,
                "  slot {} ({:?}): {} bodies differ{}",
                s.slot.0,
                s.status,
                s.bodies_differing,
                match (s.contacts_differ, s.game_differs) {
                    (true, true) => ", the contact state and the game state differ",
                    (true, false) => ", the contact state differs",
                    (false, true) => ", the game state differs",
                    (false, false) => "",
                }
            )?;
            for d in &s.game {
                writeln!(f, "    game state {}:", d.name)?;
                writeln!(f, "        expected {}", words_text(d.kind, &d.expected))?;
                writeln!(f, "        got      {}", words_text(d.kind, &d.got))?;
            }
            for b in &s.bodies {
                writeln!(f, "    {b}")?;
                for d in &b.fields {
                    writeln!(f, "      {}:", d.name)?;
                    writeln!(f, "        expected {}", words_text(d.kind, &d.expected))?;
                    writeln!(f, "        got      {}", words_text(d.kind, &d.got))?;
                }
            }
        }
        if self.fields_omitted > 0 {
            writeln!(
                f,
                "  ({} more differing fields not listed)",
                self.fields_omitted
            )?;
        }
        Ok(())
    }
}

/// The fields of two dumps of one body that differ, matched by name in
/// order (a field only one side has differs).
pub fn field_diffs(expected: &BodyDump, got: &BodyDump) -> Vec<FieldDiff> {
    list_diffs(&expected.fields, &got.fields)
}

/// The fields of two lists that differ, matched by name in order (a field
/// only one side has differs).
pub fn list_diffs(expected: &[FieldDump], got: &[FieldDump]) -> Vec<FieldDiff> {
    let mut out = Vec::new();
    for f in expected {
        match got.iter().find(|g| g.name == f.name) {
            Some(g) if g.words == f.words && g.kind == f.kind => {}
            Some(g) => out.push(FieldDiff {
                name: f.name.clone(),
                kind: f.kind,
                expected: f.words.clone(),
                got: g.words.clone(),
            }),
            None => out.push(FieldDiff {
                name: f.name.clone(),
                kind: f.kind,
                expected: f.words.clone(),
                got: Vec::new(),
            }),
        }
    }
    for g in got {
        if !expected.iter().any(|f| f.name == g.name) {
            out.push(FieldDiff {
                name: g.name.clone(),
                kind: g.kind,
                expected: Vec::new(),
                got: g.words.clone(),
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn q32_decimals_are_exact() {
        assert_eq!(q32_decimal(0), "0");
        assert_eq!(q32_decimal(3 << 32), "3");
        assert_eq!(q32_decimal(1 << 31), "0.5");
        assert_eq!(q32_decimal((-(1i64 << 31)) as u64), "-0.5");
        assert_eq!(q32_decimal(1), "0.00000000023283064365386962890625");
        assert_eq!(q32_decimal(i64::MIN as u64), "-2147483648");
        assert_eq!(q32_decimal((5i64 << 32 | 1 << 30) as u64), "5.25");
    }
}
