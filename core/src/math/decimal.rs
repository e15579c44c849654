//! Exact conversion between decimal text and Q32.32.
//!
//! Scene files, dumps and the CLI speak decimal. Converting through `f64`
//! would round twice (decimal → 53-bit binary → 32 fraction bits) and could
//! land one ulp off the nearest Q32.32 value; this module converts the digits
//! themselves, so `"0.1"` always becomes the Q32.32 value nearest to 1/10
//! (ties away from zero), on every machine. Formatting is exact too: every
//! Q32.32 value has a finite decimal expansion of at most 32 fraction digits,
//! and [`format_exact`] prints all of them (minus trailing zeros), so printing
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
pub fn parse_exact(text: &str) -> Result<Scalar, ParseDecimalError> {
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
                exponent = parse_exponent(&bytes[i + 1..], i + 1)?;
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

fn parse_exponent(bytes: &[u8], offset: usize) -> Result<i64, ParseDecimalError> {
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

/// The exact decimal value of `v`: an optional `-`, the integer part, and,
/// when the value is not an integer, `.` and up to 32 fraction digits with
/// trailing zeros removed.
pub fn format_exact(v: Scalar) -> String {
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
        let mut x: u64 = 12345;
        for _ in 0..20_000 {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
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
