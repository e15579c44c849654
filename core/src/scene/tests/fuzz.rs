//! Robustness: extreme values and randomly mutated files never panic.

use super::errors::assert_error;
use super::{BALL, PYRAMID, SHAPES, SPIN, parse};
use crate::math::Scalar;
use crate::scene::*;
use crate::testing::Rng;

// ---- robustness ----

#[test]
fn extreme_but_valid_values_are_handled_without_overflow() {
    // A hull spanning the whole Q32.32 range: the flatness test overflows and
    // stays lenient instead of panicking.
    let scene = parse(
        "[[bodies]]\nname = \"big\"\nkind = \"dynamic\"\n[[bodies.shapes]]\nkind = \"convex_hull\"\npoints = [[-2147483648, 0, 0], [2147483647, 0, 0], [0, 2147483647, 0], [0, 0, -2147483648]]\n",
    );
    match &scene.bodies[0].shapes[0].geometry {
        GeometryDesc::ConvexHull { points } => assert_eq!(points[0].x, Scalar::MIN),
        other => panic!("{other:?}"),
    }
    // A huge axis is scaled down before normalising: 90° about (1, 1, 0)/√2.
    let scene = parse(&format!(
        "{BALL}rotation = {{ axis = [2147483647, 2147483647, 0], angle_deg = 90 }}\n"
    ));
    let q = scene.bodies[0].shapes[0].rotation;
    // sin 45° / √2 = 0.5 and cos 45° = 0.70710678...: 2^31 and 3037000500 in bits.
    assert!((q.x.to_bits() - (1 << 31)).abs() <= 2, "{q:?}");
    assert_eq!(q.x, q.y);
    assert!((q.w.to_bits() - 3_037_000_500).abs() <= 2, "{q:?}");
    // A height field too large to allocate is refused before its heights
    // are read.
    assert_error(
        "[[bodies]]\nname = \"h\"\nkind = \"static\"\n[[bodies.shapes]]\nkind = \"heightfield\"\nrows = 4096\ncols = 4096\nheights = []\n",
        "test.toml:7:8: body \"h\", shape 1: rows × cols = 16777216 samples is too many (at most 1048576)",
    );
}

/// Indices drawn from the workspace's test generator.
trait Pick {
    /// A number in `0..n` (0 when `n` is 0).
    fn pick(&mut self, n: usize) -> usize;
}

impl Pick for Rng {
    fn pick(&mut self, n: usize) -> usize {
        self.below(n.max(1) as u64) as usize
    }
}

/// One random edit of `text`: truncation, deletion, insertion of TOML-ish
/// characters, a replaced number, or a duplicated or dropped line.
fn mutate(text: &str, rng: &mut Rng) -> String {
    const PIECES: &[&str] = &[
        "[",
        "]",
        "{",
        "}",
        "=",
        ",",
        ".",
        "\"",
        "'",
        "-",
        "+",
        "0",
        "9",
        "e",
        "_",
        " ",
        "\n",
        "#",
        "inf",
        "nan",
        "1e99",
        "-0",
        "0x",
        "[[bodies]]",
        "[[bodies.shapes]]",
        "kind",
        "é",
        "\\",
        "2147483648",
        "0.1",
        "true",
        "1979-05-27",
        "\"\"\"",
        "]]",
    ];
    let chars: Vec<char> = text.chars().collect();
    let at = rng.pick(chars.len() + 1);
    let mut out: Vec<char> = chars.clone();
    match rng.pick(6) {
        0 => out.truncate(at),
        1 => {
            let end = (at + 1 + rng.pick(12)).min(out.len());
            out.drain(at.min(end)..end);
        }
        2 | 3 => {
            let piece = PIECES[rng.pick(PIECES.len())];
            out.splice(at..at, piece.chars());
        }
        4 => {
            let lines: Vec<&str> = text.lines().collect();
            let i = rng.pick(lines.len());
            let mut l: Vec<String> = lines.iter().map(|s| (*s).to_owned()).collect();
            if rng.pick(2) == 0 {
                l.insert(i, lines.get(i).copied().unwrap_or("").to_owned());
            } else if i < l.len() {
                l.remove(i);
            }
            return l.join("\n");
        }
        _ => {
            // Replace the digit run under `at` with a random number.
            let digits = ["0", "-1", "1e-40", "99999999999", "-2147483648", "0.5", "3"];
            let mut start = at.min(out.len());
            while start > 0 && out[start - 1].is_ascii_digit() {
                start -= 1;
            }
            let mut end = start;
            while end < out.len() && out[end].is_ascii_digit() {
                end += 1;
            }
            out.splice(start..end, digits[rng.pick(digits.len())].chars());
        }
    }
    out.into_iter().collect()
}

#[test]
fn mutated_scene_files_give_errors_not_panics() {
    let mut rng = Rng::new(0x5eed_1234_abcd_0001);
    let mut ok = 0;
    let mut err = 0;
    for round in 0..1500 {
        let base = [PYRAMID, SHAPES, SPIN][round % 3];
        let mut text = mutate(base, &mut rng);
        for _ in 0..rng.pick(3) {
            text = mutate(&text, &mut rng);
        }
        let result = std::panic::catch_unwind(|| parse_scene(&text, "fuzz.toml"));
        match result {
            Ok(Ok(_)) => ok += 1,
            Ok(Err(e)) => {
                assert!(e.line >= 1 && e.column >= 1, "{e}");
                assert!(e.to_string().starts_with("fuzz.toml:"), "{e}");
                err += 1;
            }
            Err(_) => panic!("parse_scene panicked on:\n{text}"),
        }
    }
    eprintln!("fuzz: ok {ok}, err {err}");
    // Both outcomes must occur for the fuzz to mean anything.
    assert_eq!(ok + err, 1500);
    assert!(ok > 100 && err > 300, "ok {ok}, err {err}");
}
