//! The game's own state, kept in the world: scores, rounds, cooldowns,
//! whatever a game's rules remember from one tick to the next.
//!
//! Rules that keep such state outside the world desync a late joiner (its
//! fresh rules start over) and hide the difference from the state hash.
//! Kept here instead, it is simulation state like a body's velocity: the
//! world's [`state_hash`](crate::World::state_hash) covers it, snapshots
//! carry it (late join, rejoin, desync bundles), and a desync report names
//! the field that differs as it names a body's field.
//!
//! The state is an ordered list of named fields, each a short list of
//! 64-bit words read as unsigned words, signed integers or Q32.32 values
//! (byte strings are packed into words). The order is the order in which
//! names were first set, so rules that set their fields in a fixed order
//! give every peer the same list. Setting a field that exists replaces its
//! words in place.
//!
//! ```
//! use lockstep_core::{World, WorldConfig};
//!
//! let mut world = World::new(WorldConfig::default())?;
//! let before = world.state_hash();
//! world.game_state_mut().set_int("round", 1)?;
//! world.game_state_mut().set_words("score", &[0, 3])?;
//! assert_ne!(world.state_hash(), before);
//! assert_eq!(world.game_state().int("round"), Some(1));
//!
//! let copy = World::restore(&world.snapshot())?;
//! assert_eq!(copy.game_state().words("score"), Some(&[0, 3][..]));
//! assert_eq!(copy.state_hash(), world.state_hash());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use serde::{Deserialize, Serialize};

use crate::hash::FieldKind;
use crate::hash::StateHasher;
use crate::math::Scalar;

/// Most fields a game state holds; a setter refuses a new field beyond it.
pub const MAX_GAME_FIELDS: usize = 256;

/// Most words one field holds (a byte string: 8 bytes per word).
pub const MAX_GAME_FIELD_WORDS: usize = 4096;

/// Longest field name, in bytes.
pub const MAX_GAME_FIELD_NAME: usize = 64;

/// Why a field could not be set.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum GameStateError {
    /// The name is empty or longer than [`MAX_GAME_FIELD_NAME`] bytes.
    #[error("game state field name {0:?}: must be 1 to 64 bytes")]
    BadName(String),
    /// The field has more than [`MAX_GAME_FIELD_WORDS`] words.
    #[error("game state field {name:?}: {words} words, at most 4096")]
    TooLong {
        /// The field.
        name: String,
        /// Its length.
        words: usize,
    },
    /// The state already has [`MAX_GAME_FIELDS`] fields.
    #[error("game state field {0:?}: the state already has 256 fields")]
    TooManyFields(String),
}

/// One named field of a game state.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct GameField {
    name: String,
    kind: FieldKind,
    words: Vec<u64>,
}

impl GameField {
    /// The field's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// How its words read.
    pub fn kind(&self) -> FieldKind {
        self.kind
    }

    /// Its raw words.
    pub fn words(&self) -> &[u64] {
        &self.words
    }
}

/// The game's own state: named fields of words (see the module docs).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct GameState {
    fields: Vec<GameField>,
}

impl GameState {
    /// No fields: the state of a game that keeps none (and of every world
    /// until its rules set one).
    pub fn new() -> GameState {
        GameState::default()
    }

    /// Whether it has no field.
    pub fn is_empty(&self) -> bool {
        self.fields.is_empty()
    }

    /// Removes every field.
    pub fn clear(&mut self) {
        self.fields.clear();
    }

    /// The fields, in the order their names were first set.
    pub fn fields(&self) -> &[GameField] {
        &self.fields
    }

    fn find(&self, name: &str) -> Option<&GameField> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// Sets field `name` to `words`, read as `kind`: replaced in place if
    /// it exists, else appended.
    ///
    /// # Errors
    /// [`GameStateError`] past a bound (the state is left as it was).
    pub fn set(
        &mut self,
        name: &str,
        kind: FieldKind,
        words: &[u64],
    ) -> Result<(), GameStateError> {
        if name.is_empty() || name.len() > MAX_GAME_FIELD_NAME {
            return Err(GameStateError::BadName(name.into()));
        }
        if words.len() > MAX_GAME_FIELD_WORDS {
            return Err(GameStateError::TooLong {
                name: name.into(),
                words: words.len(),
            });
        }
        if let Some(f) = self.fields.iter_mut().find(|f| f.name == name) {
            f.kind = kind;
            f.words.clear();
            f.words.extend_from_slice(words);
            return Ok(());
        }
        if self.fields.len() >= MAX_GAME_FIELDS {
            return Err(GameStateError::TooManyFields(name.into()));
        }
        self.fields.push(GameField {
            name: name.into(),
            kind,
            words: words.to_vec(),
        });
        Ok(())
    }

    /// Sets an unsigned word (a flag, a count, a tick, a handle). Every
    /// setter below is [`GameState::set`] with a kind, and fails as it does.
    ///
    /// # Errors
    /// [`GameStateError`] past a bound.
    pub fn set_word(&mut self, name: &str, value: u64) -> Result<(), GameStateError> {
        self.set(name, FieldKind::Word, &[value])
    }

    /// Sets a signed integer.
    pub fn set_int(&mut self, name: &str, value: i64) -> Result<(), GameStateError> {
        self.set(name, FieldKind::Int, &[value as u64])
    }

    /// Sets a Q32.32 value.
    pub fn set_scalar(&mut self, name: &str, value: Scalar) -> Result<(), GameStateError> {
        self.set(name, FieldKind::Scalar, &[value.to_bits() as u64])
    }

    /// Sets a list of unsigned words.
    pub fn set_words(&mut self, name: &str, values: &[u64]) -> Result<(), GameStateError> {
        self.set(name, FieldKind::Word, values)
    }

    /// Sets a list of signed integers.
    pub fn set_ints(&mut self, name: &str, values: &[i64]) -> Result<(), GameStateError> {
        let words: Vec<u64> = values.iter().map(|&v| v as u64).collect();
        self.set(name, FieldKind::Int, &words)
    }

    /// Sets a byte string: its length, then its bytes packed little-endian
    /// into words (the last zero-padded), as the state hash packs bytes.
    pub fn set_bytes(&mut self, name: &str, bytes: &[u8]) -> Result<(), GameStateError> {
        let mut words = Vec::with_capacity(1 + bytes.len().div_ceil(8));
        words.push(bytes.len() as u64);
        for chunk in bytes.chunks(8) {
            let mut w = [0u8; 8];
            w[..chunk.len()].copy_from_slice(chunk);
            words.push(u64::from_le_bytes(w));
        }
        self.set(name, FieldKind::Word, &words)
    }

    /// The words of field `name`.
    pub fn words(&self, name: &str) -> Option<&[u64]> {
        self.find(name).map(|f| f.words.as_slice())
    }

    /// Field `name`'s first word.
    pub fn word(&self, name: &str) -> Option<u64> {
        self.words(name).and_then(|w| w.first().copied())
    }

    /// Field `name`'s first word as a signed integer.
    pub fn int(&self, name: &str) -> Option<i64> {
        self.word(name).map(|w| w as i64)
    }

    /// Field `name`'s words as signed integers.
    pub fn ints(&self, name: &str) -> Option<Vec<i64>> {
        self.words(name)
            .map(|w| w.iter().map(|&v| v as i64).collect())
    }

    /// Field `name`'s first word as a Q32.32 value.
    pub fn scalar(&self, name: &str) -> Option<Scalar> {
        self.word(name).map(|w| Scalar::from_bits(w as i64))
    }

    /// Field `name` as a byte string written by [`GameState::set_bytes`]
    /// (`None` if absent or not such a string).
    pub fn bytes(&self, name: &str) -> Option<Vec<u8>> {
        let w = self.words(name)?;
        let (&len, rest) = w.split_first()?;
        let len = usize::try_from(len).ok()?;
        if len.div_ceil(8) != rest.len() {
            return None;
        }
        let mut out: Vec<u8> = rest.iter().flat_map(|w| w.to_le_bytes()).collect();
        out.truncate(len);
        Some(out)
    }

    /// Mixes the state into a hash: the number of fields, then per field
    /// its name (a byte string), its kind (0 word, 1 int, 2 scalar), its
    /// number of words and the words.
    pub fn hash_into(&self, h: &mut StateHasher) {
        h.word(self.fields.len() as u64);
        for f in &self.fields {
            h.bytes(f.name.as_bytes());
            h.word(kind_code(f.kind));
            h.word(f.words.len() as u64);
            for &w in &f.words {
                h.word(w);
            }
        }
    }

    /// The hash of the state alone (what a desync probe compares first).
    pub fn hash(&self) -> u64 {
        let mut h = StateHasher::new();
        self.hash_into(&mut h);
        h.finish()
    }

    /// Checks the bounds after decoding a snapshot.
    pub(crate) fn validate(&self) -> Result<(), String> {
        if self.fields.len() > MAX_GAME_FIELDS {
            return Err(format!("game state: {} fields", self.fields.len()));
        }
        for (i, f) in self.fields.iter().enumerate() {
            if f.name.is_empty() || f.name.len() > MAX_GAME_FIELD_NAME {
                return Err(format!("game state: field {i} has a bad name"));
            }
            if f.words.len() > MAX_GAME_FIELD_WORDS {
                return Err(format!("game state: field {:?} too long", f.name));
            }
            if self.fields[..i].iter().any(|g| g.name == f.name) {
                return Err(format!("game state: field {:?} twice", f.name));
            }
        }
        Ok(())
    }
}

fn kind_code(kind: FieldKind) -> u64 {
    match kind {
        FieldKind::Word => 0,
        FieldKind::Int => 1,
        FieldKind::Scalar => 2,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_keep_their_first_order_and_replace_in_place() {
        let mut s = GameState::new();
        s.set_int("round", 1).unwrap();
        s.set_words("score", &[1, 2]).unwrap();
        s.set_int("round", 2).unwrap();
        let names: Vec<&str> = s.fields().iter().map(|f| f.name()).collect();
        assert_eq!(names, ["round", "score"]);
        assert_eq!(s.int("round"), Some(2));
        assert_eq!(s.words("score"), Some(&[1, 2][..]));
        assert_eq!(s.word("missing"), None);
    }

    #[test]
    fn bytes_round_trip_and_bounds_are_refused() {
        let mut s = GameState::new();
        for len in [0, 1, 7, 8, 9, 100] {
            let b: Vec<u8> = (0..len as u8).collect();
            s.set_bytes("b", &b).unwrap();
            assert_eq!(s.bytes("b"), Some(b));
        }
        assert!(s.set("", FieldKind::Word, &[1]).is_err());
        assert!(s.set(&"x".repeat(65), FieldKind::Word, &[1]).is_err());
        assert!(s.set("long", FieldKind::Word, &[0; 4097]).is_err());
        for i in 1..MAX_GAME_FIELDS {
            s.set(&format!("f{i}"), FieldKind::Word, &[1]).unwrap();
        }
        assert_eq!(
            s.set("one_more", FieldKind::Word, &[1]),
            Err(GameStateError::TooManyFields("one_more".into()))
        );
        assert_eq!(s.fields().len(), MAX_GAME_FIELDS);
        assert!(s.validate().is_ok());
    }

    #[test]
    fn the_hash_sees_names_kinds_and_words() {
        let mut a = GameState::new();
        a.set_int("x", 1).unwrap();
        let mut b = GameState::new();
        b.set_word("x", 1).unwrap();
        assert_ne!(a.hash(), b.hash());
        let mut c = GameState::new();
        c.set_int("y", 1).unwrap();
        assert_ne!(a.hash(), c.hash());
        let mut d = GameState::new();
        d.set_int("x", 2).unwrap();
        assert_ne!(a.hash(), d.hash());
        assert_eq!(a.hash(), a.clone().hash());
    }
}
