//! Exact conversion between decimal text and Q32.32.
//!
//! Scene files, dumps and the CLI speak decimal. Converting through `f64`
//! would round twice (decimal → 53-bit binary → 32 fraction bits) and could
//! land one ulp off the nearest Q32.32 value; this module converts the digits
//! themselves, so `"0.1"` always becomes the Q32.32 value nearest to 1/10
//! (ties away from zero), on every machine. Formatting is exact too: every
//! Q32.32 value has a finite decimal expansion of at most 32 fraction digits,
//! and `format_exact` prints all of them (minus trailing zeros), so printing
//! and parsing round-trip bit for bit.

use std::fmt;

use super::scalar::Scalar;

/// The most digits (integer and fraction, after applying the exponent) a
/// decimal may have: far beyond anything meaningful, and a bound on the work.
pub const MAX_DIGITS: usize = 400;

/// Why a decimal could not be converted.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ParseDecimalError {
    /// Nothing to parse.
    Empty,
    /// A character that is not part of a decimal number, at a byte offset.
    InvalidChar {
        /// The offending character.
        ch: char,
        /// Its byte offset in the input.
        at: usize,
    },
    /// Digits are missing (for example `"-"`, `"1e"` or `"."`).
    MissingDigits,
    /// The value is outside Q32.32's range of ±2,147,483,648.
    OutOfRange,
    /// More digits than [`MAX_DIGITS`], or an absurd exponent.
    TooLong,
}

impl fmt::Display for ParseDecimalError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParseDecimalError::Empty => f.write_str("empty number"),
            ParseDecimalError::InvalidChar { ch, at } => {
                write!(f, "unexpected character {ch:?} at offset {at} in a number")
            }
            ParseDecimalError::MissingDigits => f.write_str("a number is missing its digits"),
            ParseDecimalError::OutOfRange => {
                f.write_str("number outside the fixed-point range ±2147483648")
            }
            ParseDecimalError::TooLong => {
                write!(f, "number longer than {MAX_DIGITS} digits")
            }
        }
    }
}

impl std::error::Error for ParseDecimalError {}

/// Parses `[+-]digits[.digits][(e|E)[+-]digits]` (underscores allowed
/// between digits, as TOML does) to the nearest Q32.32 value, ties away from
/// zero. Exact: no floating point is involved.
///
/// # Errors
/// See [`ParseDecimalError`].
pub(crate) fn parse_exact(text: &str) -> Result<Scalar, ParseDecimalError> {
    parse_exact_const(text)
}

/// [`parse_exact`] as a `const fn` (it is the implementation of both), so
/// constants can be written as decimals and converted at compile time. What
/// [`Scalar::from_decimal_str`] and the [`scalar!`](crate::scalar) macro
/// run.
///
/// It works on fixed buffers of [`MAX_DIGITS`] digits instead of vectors:
/// the significant digits with the position of the decimal point, which
/// the exponent moves, then the same 33 doublings of the fraction.
///
/// # Errors
/// See [`ParseDecimalError`].
pub(crate) const fn parse_exact_const(text: &str) -> Result<Scalar, ParseDecimalError> {
    let bytes = text.as_bytes();
    if bytes.is_empty() {
        return Err(ParseDecimalError::Empty);
    }
    let mut i = 0;
    let negative = bytes[0] == b'-';
    if bytes[0] == b'-' || bytes[0] == b'+' {
        i = 1;
    }
    // The significant digits: the integer digits without leading zeros,
    // then the fraction digits; `int_len` of them before the point.
    let mut digits = [0u8; MAX_DIGITS];
    let mut len = 0usize;
    let mut int_len = 0usize;
    let mut seen_point = false;
    let mut any_digit = false;
    let mut exponent: i64 = 0;
    while i < bytes.len() {
        let c = bytes[i];
        if c.is_ascii_digit() {
            any_digit = true;
            let d = c - b'0';
            if seen_point || !(int_len == 0 && d == 0) {
                if len == MAX_DIGITS {
                    return Err(ParseDecimalError::TooLong);
                }
                digits[len] = d;
                len += 1;
                if !seen_point {
                    int_len += 1;
                }
            }
        } else if c == b'_' && i > 0 && bytes[i - 1].is_ascii_digit() {
        } else if c == b'.' && !seen_point {
            seen_point = true;
        } else if c == b'e' || c == b'E' {
            if !any_digit {
                return Err(ParseDecimalError::MissingDigits);
            }
            exponent = match parse_exponent_const(bytes, i + 1) {
                Ok(e) => e,
                Err(e) => return Err(e),
            };
            break;
        } else {
            return Err(ParseDecimalError::InvalidChar {
                ch: char_at(bytes, i),
                at: i,
            });
        }
        i += 1;
    }
    if !any_digit {
        return Err(ParseDecimalError::MissingDigits);
    }
    // The point moves `exponent` places right. Digit k (0-based, from the
    // first significant one) is `digits[k]` inside the buffer, 0 outside.
    // |exponent| <= MAX_DIGITS, so this cannot overflow.
    let point = int_len as i64 + exponent;
    let frac_len = len as i64 - point;
    if exponent < 0 && frac_len > MAX_DIGITS as i64 {
        return Err(ParseDecimalError::TooLong);
    }
    // The integer digits are those before the point, less leading zeros
    // (which only a positive exponent can bring in from the fraction).
    let mut first = 0i64;
    while first < point && first < len as i64 && digits[first as usize] == 0 {
        first += 1;
    }
    if first >= len as i64 {
        first = point; // all zero
    }
    if point - first > 12 {
        return Err(ParseDecimalError::OutOfRange);
    }
    let mut int_part: u128 = 0;
    let mut k = first;
    while k < point {
        int_part = int_part * 10 + digit_at(&digits, len, k) as u128;
        k += 1;
    }
    // The fraction digits, from the point on, into a buffer of their own.
    let mut frac = [0u8; MAX_DIGITS];
    let mut n = 0usize;
    let mut k = point;
    while k < len as i64 {
        frac[n] = digit_at(&digits, len, k);
        n += 1;
        k += 1;
    }
    // 32 fraction bits plus the rounding bit, one per doubling (as
    // `parse_exact` does).
    let mut frac_bits: u128 = 0;
    let mut round = 0;
    while round < 33 {
        let mut carry = 0u8;
        let mut j = n;
        while j > 0 {
            j -= 1;
            let v = frac[j] * 2 + carry;
            frac[j] = v % 10;
            carry = v / 10;
        }
        frac_bits = (frac_bits << 1) | carry as u128;
        round += 1;
    }
    let magnitude = (int_part << 32) + (frac_bits >> 1) + (frac_bits & 1);
    let limit = if negative {
        1u128 << 63
    } else {
        (1u128 << 63) - 1
    };
    if magnitude > limit {
        return Err(ParseDecimalError::OutOfRange);
    }
    let bits = if negative {
        (magnitude as i128).wrapping_neg() as i64
    } else {
        magnitude as i64
    };
    Ok(Scalar::from_bits(bits))
}

/// Digit `k` of the significant digits, 0 outside `0..len`.
const fn digit_at(digits: &[u8; MAX_DIGITS], len: usize, k: i64) -> u8 {
    if k >= 0 && k < len as i64 {
        digits[k as usize]
    } else {
        0
    }
}

/// The character starting at byte `i` of a `str`'s bytes (at a character
/// boundary), decoded from its UTF-8.
const fn char_at(bytes: &[u8], i: usize) -> char {
    let b0 = bytes[i] as u32;
    let (mut code, extra) = if b0 < 0x80 {
        (b0, 0)
    } else if b0 >= 0xf0 {
        (b0 & 0x07, 3)
    } else if b0 >= 0xe0 {
        (b0 & 0x0f, 2)
    } else {
        (b0 & 0x1f, 1)
    };
    let mut k = 1;
    while k <= extra && i + k < bytes.len() {
        code = (code << 6) | (bytes[i + k] as u32 & 0x3f);
        k += 1;
    }
    match char::from_u32(code) {
        Some(c) => c,
        None => '?',
    }
}

/// `parse_exponent` as a `const fn`, reading `bytes[start..]`.
const fn parse_exponent_const(bytes: &[u8], start: usize) -> Result<i64, ParseDecimalError> {
    let mut i = start;
    let negative = i < bytes.len() && bytes[i] == b'-';
    if i < bytes.len() && (bytes[i] == b'-' || bytes[i] == b'+') {
        i += 1;
    }
    let mut value: i64 = 0;
    let mut any = false;
    while i < bytes.len() {
        let c = bytes[i];
        if c.is_ascii_digit() {
            any = true;
            value = value * 10 + (c - b'0') as i64;
            if value > MAX_DIGITS as i64 {
                return Err(ParseDecimalError::TooLong);
            }
        } else if c == b'_' && i > start && bytes[i - 1].is_ascii_digit() {
        } else {
            return Err(ParseDecimalError::InvalidChar {
                ch: c as char,
                at: i,
            });
        }
        i += 1;
    }
    if !any {
        return Err(ParseDecimalError::MissingDigits);
    }
    Ok(if negative { -value } else { value })
}

/// The exact decimal value of `v`: an optional `-`, the integer part, and,
/// when the value is not an integer, `.` and up to 32 fraction digits with
/// trailing zeros removed.
pub(crate) fn format_exact(v: Scalar) -> String {
    let bits = v.to_bits();
    let magnitude = bits.unsigned_abs();
    let int_part = magnitude >> 32;
    let frac = (magnitude & 0xffff_ffff) as u128;
    let mut out = String::with_capacity(48);
    if bits < 0 {
        out.push('-');
    }
    out.push_str(&int_part.to_string());
    if frac != 0 {
        // frac / 2^32 = frac * 5^32 / 10^32, and frac * 5^32 < 10^32.
        const FIVE_POW_32: u128 = 23_283_064_365_386_962_890_625;
        let digits = format!("{:032}", frac * FIVE_POW_32);
        out.push('.');
        out.push_str(digits.trim_end_matches('0'));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(s: &str) -> Scalar {
        parse_exact(s).unwrap_or_else(|e| panic!("{s}: {e}"))
    }

    #[test]
    fn simple_values_are_exact() {
        assert_eq!(p("0"), Scalar::ZERO);
        assert_eq!(p("1"), Scalar::ONE);
        assert_eq!(p("-1"), Scalar::NEG_ONE);
        assert_eq!(p("0.5"), Scalar::HALF);
        assert_eq!(p("+2.000"), Scalar::TWO);
        assert_eq!(p("1_000"), Scalar::from_int(1000));
        assert_eq!(p("2.5e2"), Scalar::from_int(250));
        assert_eq!(p("25E-1"), Scalar::from_ratio(5, 2));
        assert_eq!(p("-0.0"), Scalar::ZERO);
    }

    #[test]
    fn tenths_round_to_the_nearest_value() {
        // 0.1 * 2^32 = 429496729.6 -> 429496730.
        assert_eq!(p("0.1").to_bits(), 429_496_730);
        assert_eq!(p("-0.1").to_bits(), -429_496_730);
        assert_eq!(p("9.81"), Scalar::from_ratio(981, 100));
        assert_eq!(p("0.016666666666666666"), Scalar::from_ratio(1, 60));
    }

    #[test]
    fn half_ulp_ties_round_away_from_zero() {
        // 2^-33 exactly = 0.000000000116415321826934814453125
        assert_eq!(p("0.000000000116415321826934814453125"), Scalar::DELTA);
        assert_eq!(p("-0.000000000116415321826934814453125"), -Scalar::DELTA);
        // Just below the tie rounds to zero.
        assert_eq!(p("0.000000000116415321826934814453124"), Scalar::ZERO);
    }

    #[test]
    fn formatting_round_trips_every_sampled_value() {
        let mut rng = Rng::new(12345);
        for _ in 0..20_000 {
            let x = rng.next_u64();
            let v = Scalar::from_bits(x as i64);
            assert_eq!(p(&format_exact(v)), v, "{}", format_exact(v));
        }
        for v in [Scalar::MAX, Scalar::MIN, Scalar::DELTA, -Scalar::DELTA] {
            assert_eq!(p(&format_exact(v)), v);
        }
        assert_eq!(
            format_exact(Scalar::DELTA),
            "0.00000000023283064365386962890625"
        );
        assert_eq!(format_exact(Scalar::from_ratio(-3, 2)), "-1.5");
    }

    use crate::testing::Rng;

    /// Decimal texts drawn from the workspace's test generator.
    trait Texts {
        fn digits(&mut self, max: u64) -> String;
        fn toml_float(&mut self) -> String;
    }

    impl Texts for Rng {
        fn digits(&mut self, max: u64) -> String {
            let n = self.below(max + 1);
            (0..n)
                .map(|_| char::from(b'0' + self.below(10) as u8))
                .collect()
        }

        /// A decimal as TOML writes floats: `[-]int.frac[e[-]exp]`, the
        /// integer part without leading zeros.
        fn toml_float(&mut self) -> String {
            let sign = if self.below(2) == 0 { "-" } else { "" };
            let int = match self.below(4) {
                0 => "0".to_owned(),
                _ => {
                    let bits = 1 + self.below(31);
                    format!("{}", 1 + self.below(1 << bits))
                }
            };
            let mut frac = self.digits(45);
            if frac.is_empty() {
                frac.push('5');
            }
            let exp = match self.below(4) {
                0 => format!("e-{}", self.below(15)),
                1 => format!("e{}", self.below(4)),
                _ => String::new(),
            };
            format!("{sign}{int}.{frac}{exp}")
        }
    }

    /// Literals around every rule of the grammar and of the rounding,
    /// separated by spaces (the empty text and spaces are added by the test).
    const LITERALS: &str = "\
        0 1 -1 +1 0.5 -0.5 0.1 -0.1 9.81 -9.81 +2.000 -0.0 00012.5 0.000 1_000 1_000.000_5 \
        1__0 _1 1_ 1._5 -_1 2.5e2 25E-1 1e0 1e+3 1e-3 1.e5 .5 5. . - + e5 .e5 -.5e1 1e 1e- 1e+ \
        1e_5 1e5_ 1e5_0 1e-_5 1ee5 1e5.0 1.2.3 12x nan inf -inf 0x10 1,5 ½ 1é 1e½ é \
        3.14159265358979323846264338327950288 \
        0.000000000116415321826934814453125 -0.000000000116415321826934814453125 \
        0.000000000116415321826934814453124 0.000000000116415321826934814453126 \
        0.00000000023283064365386962890625 0.0000000001 -0.0000000001 1e-10 -1e-10 \
        1e-400 1e-401 1e400 0e400 0.0e400 0.00000e12 0.0001e12 0.001e12 1e11 1e12 -1e12 \
        999999999999 9999999999999 0000000000000000001 2147483647 2147483648 -2147483648 \
        -2147483649 2147483647.99999999988358467817306518554688 \
        2147483647.9999999998835846781730651855469 2147483647.99999999999 \
        -2147483648.0000000001 -2147483648.00000000011641532182693481445313 \
        0.016666666666666666 123456.789e-3 0.0000123456789e7 1.0e-5000 \
        12345678901234567890e-10 0.12345678901234567890123456789012345678901234567890 \
        12e-400 123e-400 0.5e-399 0.5e-400 1.5e-399 1.5e-400";

    /// An independent parser written with vectors (the first
    /// implementation): the oracle the const parser is checked against.
    fn reference_parse(text: &str) -> Result<Scalar, ParseDecimalError> {
        let bytes = text.as_bytes();
        if bytes.is_empty() {
            return Err(ParseDecimalError::Empty);
        }
        let mut i = 0;
        let negative = match bytes[0] {
            b'-' => {
                i = 1;
                true
            }
            b'+' => {
                i = 1;
                false
            }
            _ => false,
        };
        let mut int_digits: Vec<u8> = Vec::new();
        let mut frac_digits: Vec<u8> = Vec::new();
        let mut seen_point = false;
        let mut any_digit = false;
        let mut exponent: i64 = 0;
        while i < bytes.len() {
            let c = bytes[i];
            match c {
                b'0'..=b'9' => {
                    any_digit = true;
                    let d = c - b'0';
                    if seen_point {
                        frac_digits.push(d);
                    } else if !(int_digits.is_empty() && d == 0) {
                        int_digits.push(d);
                    }
                    if int_digits.len() + frac_digits.len() > MAX_DIGITS {
                        return Err(ParseDecimalError::TooLong);
                    }
                }
                b'_' if i > 0 && bytes[i - 1].is_ascii_digit() => {}
                b'.' if !seen_point => seen_point = true,
                b'e' | b'E' => {
                    if !any_digit {
                        return Err(ParseDecimalError::MissingDigits);
                    }
                    exponent = reference_exponent(&bytes[i + 1..], i + 1)?;
                    break;
                }
                _ => {
                    let ch = text[i..].chars().next().unwrap_or('?');
                    return Err(ParseDecimalError::InvalidChar { ch, at: i });
                }
            }
            i += 1;
        }
        if !any_digit {
            return Err(ParseDecimalError::MissingDigits);
        }
        // Apply the exponent by moving digits across the decimal point.
        if exponent > 0 {
            for _ in 0..exponent {
                let d = if frac_digits.is_empty() {
                    0
                } else {
                    frac_digits.remove(0)
                };
                if !(int_digits.is_empty() && d == 0) {
                    int_digits.push(d);
                }
                if int_digits.len() > 12 {
                    return Err(ParseDecimalError::OutOfRange);
                }
            }
        } else if exponent < 0 {
            for _ in 0..(-exponent) {
                let d = int_digits.pop().unwrap_or(0);
                frac_digits.insert(0, d);
                if frac_digits.len() > MAX_DIGITS {
                    return Err(ParseDecimalError::TooLong);
                }
            }
        }
        if int_digits.len() > 12 {
            return Err(ParseDecimalError::OutOfRange);
        }
        let mut int_part: u128 = 0;
        for &d in &int_digits {
            int_part = int_part * 10 + d as u128;
        }
        // Binary expansion of the fraction, one bit per doubling: 32 bits plus
        // the rounding bit. Ties (and above) round away from zero, so the 33rd
        // bit alone decides.
        let mut frac = frac_digits;
        let mut frac_bits: u128 = 0;
        for _ in 0..33 {
            let mut carry = 0u8;
            for d in frac.iter_mut().rev() {
                let v = *d * 2 + carry;
                *d = v % 10;
                carry = v / 10;
            }
            frac_bits = (frac_bits << 1) | carry as u128;
        }
        let magnitude = (int_part << 32) + (frac_bits >> 1) + (frac_bits & 1);
        let limit = if negative {
            1u128 << 63
        } else {
            (1u128 << 63) - 1
        };
        if magnitude > limit {
            return Err(ParseDecimalError::OutOfRange);
        }
        let bits = if negative {
            (magnitude as i128).wrapping_neg() as i64
        } else {
            magnitude as i64
        };
        Ok(Scalar::from_bits(bits))
    }

    fn reference_exponent(bytes: &[u8], offset: usize) -> Result<i64, ParseDecimalError> {
        let mut i = 0;
        let negative = match bytes.first() {
            Some(b'-') => {
                i = 1;
                true
            }
            Some(b'+') => {
                i = 1;
                false
            }
            _ => false,
        };
        let mut value: i64 = 0;
        let mut any = false;
        while i < bytes.len() {
            match bytes[i] {
                c @ b'0'..=b'9' => {
                    any = true;
                    value = value * 10 + (c - b'0') as i64;
                    if value > MAX_DIGITS as i64 {
                        return Err(ParseDecimalError::TooLong);
                    }
                }
                b'_' if i > 0 && bytes[i - 1].is_ascii_digit() => {}
                c => {
                    return Err(ParseDecimalError::InvalidChar {
                        ch: c as char,
                        at: offset + i,
                    });
                }
            }
            i += 1;
        }
        if !any {
            return Err(ParseDecimalError::MissingDigits);
        }
        Ok(if negative { -value } else { value })
    }

    #[test]
    fn the_parser_agrees_with_an_independent_one_on_every_input() {
        let mut inputs: Vec<String> = LITERALS.split(' ').map(str::to_owned).collect();
        for text in ["", " 1", "1 ", "\t1"] {
            inputs.push(text.to_owned());
        }
        inputs.push("1".repeat(400));
        inputs.push("1".repeat(401));
        inputs.push(format!("0.{}", "0".repeat(399)));
        inputs.push(format!("0.{}", "0".repeat(400)));
        inputs.push(format!("0.{}1", "0".repeat(398)));
        inputs.push(format!("0.{}e-1", "0".repeat(398)));
        inputs.push(format!("0.{}e-2", "0".repeat(398)));
        inputs.push(format!("0.{}e-3", "0".repeat(398)));
        inputs.push(format!("{}e-390", "7".repeat(12)));
        inputs.push(format!("0.{}5e11", "9".repeat(60)));
        inputs.push(format!("-{}.{}", "0".repeat(30), "3".repeat(300)));
        let mut rng = Rng::new(0x5eed);
        // Random strings over the grammar's alphabet (mostly malformed).
        let alphabet = b"0123456789012345678900_.-+eE";
        for _ in 0..20_000 {
            let n = rng.below(14) as usize;
            let s: String = (0..n)
                .map(|_| char::from(alphabet[rng.below(alphabet.len() as u64) as usize]))
                .collect();
            inputs.push(s);
        }
        // Random well-formed decimals of many digits and magnitudes.
        for _ in 0..20_000 {
            inputs.push(rng.toml_float());
        }
        // Every Q32.32 value printed exactly, and one digit more or less.
        for _ in 0..5_000 {
            let text = format_exact(Scalar::from_bits(rng.next_u64() as i64));
            inputs.push(format!("{text}1"));
            inputs.push(format!("{text}9"));
            inputs.push(text[..text.len() - 1].to_owned());
            inputs.push(text);
        }
        for text in &inputs {
            assert_eq!(parse_exact(text), reference_parse(text), "{text:?}");
        }
    }

    #[test]
    fn from_decimal_str_and_the_macro_give_what_a_scene_file_gives() {
        use crate::scene::parse_scene;
        // The scene reader converts a TOML float from its source text.
        // A scene refuses a non-zero literal that rounds to 0 (its author
        // meant something); the constant is then exactly zero.
        let through_scene = |lit: &str| -> Scalar {
            let text = format!("[world]\ngravity = [{lit}, 0.0, 0.0]\n");
            match parse_scene(&text, "t.toml") {
                Ok(desc) => desc.world.gravity.x,
                Err(e) if e.to_string().contains("rounds to 0") => Scalar::ZERO,
                Err(e) => panic!("{lit}: {e}"),
            }
        };
        let mut rng = Rng::new(17);
        let mut literals: Vec<String> = [
            "0.5",
            "-0.5",
            "0.1",
            "9.81",
            "-9.81",
            "1.0",
            "-2147483648.0",
            "2147483647.99999999988",
            "0.000000000116415321826934814453125",
            "-0.000000000116415321826934814453124",
            "1e-10",
            "-3.0e-11",
            "1_000.000_1",
            "3.14159265358979323846264338327950288419716939937510",
            "12.5e3",
        ]
        .iter()
        .map(|s| (*s).to_owned())
        .collect();
        while literals.len() < 3_000 {
            let lit = rng.toml_float();
            // (Out-of-range values are errors in both; compared above.)
            if parse_exact(&lit).is_ok() {
                literals.push(lit);
            }
        }
        for lit in &literals {
            let scene = through_scene(lit);
            assert_eq!(Scalar::from_decimal_str(lit), scene, "{lit}");
            assert_eq!(lit.parse::<Scalar>(), Ok(scene), "{lit}");
        }
        // The macro takes Rust literals, which are the same digits.
        assert_eq!(crate::scalar!(0.1), through_scene("0.1"));
        assert_eq!(crate::scalar!(-9.81), through_scene("-9.81"));
        assert_eq!(crate::scalar!(1e-10), Scalar::ZERO);
        assert_eq!(crate::scalar!(-3e-11), Scalar::ZERO);
        assert_eq!(crate::scalar!(1.5e-10), Scalar::DELTA);
        assert_eq!(crate::scalar!(-1.5e-10), -Scalar::DELTA);
        assert_eq!(crate::scalar!(7), Scalar::from_int(7));
        assert_eq!(crate::scalar!(-2147483648), Scalar::MIN);
        assert_eq!(
            crate::scalar!(3.14159265358979323846264338327950288419716939937510),
            through_scene("3.14159265358979323846264338327950288419716939937510")
        );
        assert_eq!(
            crate::scalar!(0.000_000_000_116_415_321_826_934_814_453_125),
            Scalar::DELTA
        );
    }

    #[test]
    #[should_panic(expected = "outside the fixed-point range")]
    fn from_decimal_str_panics_at_run_time_on_bad_text() {
        let text = String::from("2147483648");
        let _ = Scalar::from_decimal_str(&text);
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        assert_eq!(parse_exact(""), Err(ParseDecimalError::Empty));
        assert_eq!(parse_exact("-"), Err(ParseDecimalError::MissingDigits));
        assert_eq!(parse_exact("."), Err(ParseDecimalError::MissingDigits));
        assert_eq!(parse_exact("1e"), Err(ParseDecimalError::MissingDigits));
        assert!(matches!(
            parse_exact("1.2.3"),
            Err(ParseDecimalError::InvalidChar { ch: '.', at: 3 })
        ));
        assert!(matches!(
            parse_exact("12x"),
            Err(ParseDecimalError::InvalidChar { ch: 'x', at: 2 })
        ));
        assert_eq!(
            parse_exact("2147483648"),
            Err(ParseDecimalError::OutOfRange)
        );
        assert_eq!(parse_exact("-2147483648"), Ok(Scalar::MIN));
        assert_eq!(parse_exact("1e300"), Err(ParseDecimalError::OutOfRange));
        assert_eq!(parse_exact("1e-5000"), Err(ParseDecimalError::TooLong));
        assert_eq!(parse_exact("1e12"), Err(ParseDecimalError::OutOfRange));
        assert_eq!(
            parse_exact(&"1".repeat(500)),
            Err(ParseDecimalError::TooLong)
        );
        assert!(parse_exact("nan").is_err());
        assert!(parse_exact("inf").is_err());
    }
}
