//! `SceneError`: why a scene file was rejected, and where.
//!
//! Scene files are written by hand, so every error names the file, the
//! 1-based line and column of the offending text, what is wrong and what was
//! expected: the form compilers use (`file:line:col: message`), which editors
//! and terminals turn into clickable links.

use std::ops::Range;

/// The broad class of a [`SceneError`], for callers that react to the kind
/// of problem (tests, tools that offer fixes) rather than print it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SceneErrorKind {
    /// The text is not valid TOML.
    Syntax,
    /// A key that the format does not define (usually a typo).
    UnknownKey,
    /// A required key is absent.
    MissingKey,
    /// A value of the wrong TOML type (a string where a number belongs, an
    /// array of the wrong length, ...).
    WrongType,
    /// A number that cannot be converted exactly: `inf`, `nan`, outside the
    /// Q32.32 range, or absurdly long.
    BadNumber,
    /// A number of the right type outside its allowed range (a negative
    /// radius, a restitution above 1, zero substeps, ...).
    OutOfRange,
    /// Two bodies share a name.
    DuplicateName,
    /// A shape refers to a material that is not defined.
    UnknownMaterial,
    /// A static-only shape (triangle mesh, height field) on a body that can
    /// move, or a static body given a velocity.
    StaticOnly,
    /// Geometry that cannot form the shape: triangle indices out of range, a
    /// height field whose sample count does not match its dimensions, a hull
    /// whose points are all in one plane, ...
    BadGeometry,
    /// A rotation that does not define one: a zero quaternion or zero axis.
    ZeroRotation,
    /// Two keys that exclude each other were both given (`density` and
    /// `mass`, `axis` and `quaternion`).
    Conflict,
}

/// A scene file rejected by [`parse_scene`](super::parse::parse_scene).
///
/// Displays as `file:line:column: message`, for example
/// `arena.toml:14:8: body "crate_3", shape 1: unknown shape kind "cube" (expected one of: sphere, capsule, box, convex_hull, trimesh, heightfield)`.
/// Line and column are 1-based; the column counts characters (Unicode scalar
/// values), not bytes, so it matches what an editor shows.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{file}:{line}:{column}: {message}")]
pub struct SceneError {
    /// The file name given to the parser (used only for messages).
    pub file: String,
    /// 1-based line of the offending text.
    pub line: u32,
    /// 1-based column (in characters) of the offending text.
    pub column: u32,
    /// The class of problem.
    pub kind: SceneErrorKind,
    /// What is wrong and what was expected, prefixed by where in the scene it
    /// is (`world`, `body "name"`, `body "name", shape 2`, ...).
    pub message: String,
}

/// The source text and its name: turns byte offsets into located errors.
#[derive(Clone, Copy, Debug)]
pub(super) struct Source<'a> {
    pub(super) text: &'a str,
    pub(super) file: &'a str,
    /// The byte offset at which each line starts (see [`line_starts`]).
    pub(super) line_starts: &'a [usize],
}

impl<'a> Source<'a> {
    /// An error at byte `offset` of the text.
    pub(super) fn error(&self, offset: usize, kind: SceneErrorKind, message: String) -> SceneError {
        let (line, column) = self.line_column(offset);
        SceneError {
            file: self.file.to_owned(),
            line,
            column,
            kind,
            message,
        }
    }

    /// The raw source text of a span, if the span is valid.
    pub(super) fn slice(&self, span: Option<Range<usize>>) -> Option<&'a str> {
        span.and_then(|s| self.text.get(s))
    }

    /// The 1-based line and character column of byte `offset`.
    ///
    /// Offsets past the end (TOML's "unexpected end of file") point just
    /// after the last character; an offset inside a multi-byte character
    /// points at that character. A binary search in the line index, then a
    /// count of the characters on that line only: every body, shape and
    /// joint records its line, so a scan from the top of the file for each
    /// would make parsing quadratic in the file's size.
    pub(super) fn line_column(&self, offset: usize) -> (u32, u32) {
        let text = self.text;
        let mut offset = offset.min(text.len());
        while !text.is_char_boundary(offset) {
            offset -= 1;
        }
        // The last line starting at or before `offset` (line 0 starts at 0).
        let line = self.line_starts.partition_point(|&s| s <= offset).max(1);
        let start = self.line_starts.get(line - 1).copied().unwrap_or(0);
        let column = text[start..offset].chars().count() + 1;
        (saturate_u32(line), saturate_u32(column))
    }

    /// The 1-based line of byte `offset`.
    pub(super) fn line(&self, offset: usize) -> u32 {
        self.line_column(offset).0
    }
}

/// The byte offset at which each line of `text` starts: 0, then one past
/// every `\n`.
pub(super) fn line_starts(text: &str) -> Vec<usize> {
    std::iter::once(0)
        .chain(
            text.bytes()
                .enumerate()
                .filter(|&(_, b)| b == b'\n')
                .map(|(i, _)| i + 1),
        )
        .collect()
}

fn saturate_u32(v: usize) -> u32 {
    u32::try_from(v).unwrap_or(u32::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Line and column by a scan from the top, the obvious way.
    fn scanned(text: &str, offset: usize) -> (u32, u32) {
        let mut offset = offset.min(text.len());
        while !text.is_char_boundary(offset) {
            offset -= 1;
        }
        let before = &text[..offset];
        let start = before.rfind('\n').map_or(0, |i| i + 1);
        let line = before.bytes().filter(|&b| b == b'\n').count() + 1;
        let column = before[start..].chars().count() + 1;
        (line as u32, column as u32)
    }

    #[test]
    fn the_line_index_agrees_with_a_scan_at_every_offset() {
        for text in [
            "",
            "\n",
            "a",
            "[world]\ngravity = [0, -9.81, 0]\n\n[[body]]\nname = \"été\"\n",
            "x = \"→ ∞\"\r\n\n\ny = 1",
            "no newline at the end",
        ] {
            let starts = line_starts(text);
            let src = Source {
                text,
                file: "t.toml",
                line_starts: &starts,
            };
            for offset in 0..=text.len() + 3 {
                assert_eq!(
                    src.line_column(offset),
                    scanned(text, offset),
                    "{text:?} @ {offset}"
                );
                assert_eq!(src.line(offset), scanned(text, offset).0);
            }
        }
    }
}
