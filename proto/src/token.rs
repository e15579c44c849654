//! Join tokens: a seat (or any seat) in one room for one player until an
//! expiry, signed by the server's secret with HMAC-SHA256, so nobody joins
//! a seat they were not given and one connection cannot vote as many.
//!
//! A token is printable hex of a fixed layout:
//! ```text
//! version u8 (1) | expires u64 LE (unix seconds) | seat u8 (255: any) |
//! room length u8 | room UTF-8 | player length u8 | player UTF-8 |
//! HMAC-SHA256 of everything before it (32 bytes)
//! ```
//! Pure: the caller passes the time, and the checks are constant-time in
//! the signature.

use hmac::Mac;

type HmacSha256 = hmac::Hmac<sha2::Sha256>;
use thiserror::Error;

use crate::limits::{MAX_NAME_BYTES, MAX_PLAYERS};
use crate::message::Slot;

/// The layout version in the first byte.
pub const TOKEN_VERSION: u8 = 1;

/// The shortest secret accepted, in bytes.
pub const MIN_SECRET_BYTES: usize = 16;

/// The longest token text: hex of the largest layout.
pub const MAX_TOKEN_BYTES: usize = 2 * (1 + 8 + 1 + 1 + MAX_NAME_BYTES + 1 + MAX_NAME_BYTES + 32);

const ANY_SEAT: u8 = 255;

/// What a token grants.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JoinClaims {
    /// The room it is for.
    pub room: String,
    /// The seat it is for (`None`: any free seat).
    pub seat: Option<Slot>,
    /// Who it was issued to (for logs; the join's display name is free).
    pub player: String,
    /// Unix seconds after which it is refused.
    pub expires: u64,
}

/// Why a token is refused. The texts are the refusal's detail.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum TokenError {
    /// The server requires a token and the join had none.
    #[error("no join token")]
    Missing,
    /// Not hex of a token layout.
    #[error("join token malformed: {0}")]
    Malformed(&'static str),
    /// Signed with another secret, or altered.
    #[error("join token signature invalid")]
    BadSignature,
    /// Past its expiry.
    #[error("join token expired at {expires} (now {now})")]
    Expired {
        /// Its expiry.
        expires: u64,
        /// The time of the check.
        now: u64,
    },
    /// For another room.
    #[error("join token is for room {0:?}")]
    WrongRoom(String),
    /// The secret or the claims cannot make a token.
    #[error("cannot issue: {0}")]
    Unissuable(&'static str),
}

/// A verified token's claims and a key naming the token (so one token
/// seats one connection at a time).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Ticket {
    /// The verified claims.
    pub claims: JoinClaims,
    /// The first 8 bytes of the token's signature.
    pub key: u64,
}

/// Signs `claims` with `secret`.
///
/// # Errors
/// [`TokenError::Unissuable`] for a secret shorter than
/// [`MIN_SECRET_BYTES`], names over [`MAX_NAME_BYTES`], or a seat out of
/// range.
pub fn issue(secret: &[u8], claims: &JoinClaims) -> Result<String, TokenError> {
    if secret.len() < MIN_SECRET_BYTES {
        return Err(TokenError::Unissuable(
            "the secret is shorter than 16 bytes",
        ));
    }
    if claims.room.len() > MAX_NAME_BYTES || claims.player.len() > MAX_NAME_BYTES {
        return Err(TokenError::Unissuable("a name is longer than 64 bytes"));
    }
    if claims.seat.is_some_and(|s| s.index() >= MAX_PLAYERS) {
        return Err(TokenError::Unissuable("the seat is out of range"));
    }
    let mut body = vec![TOKEN_VERSION];
    body.extend_from_slice(&claims.expires.to_le_bytes());
    body.push(claims.seat.map_or(ANY_SEAT, |s| s.0));
    for name in [&claims.room, &claims.player] {
        body.push(name.len() as u8);
        body.extend_from_slice(name.as_bytes());
    }
    // HMAC takes a key of any length.
    let Ok(mut mac) = HmacSha256::new_from_slice(secret) else {
        return Err(TokenError::Unissuable("the secret is unusable"));
    };
    mac.update(&body);
    body.extend_from_slice(&mac.finalize().into_bytes());
    Ok(hex(&body))
}

/// Checks `token` for a join to `room` at `now` (unix seconds).
///
/// # Errors
/// The [`TokenError`] that refuses it; the signature is checked before
/// anything it claims.
pub fn verify(secret: &[u8], token: &str, room: &str, now: u64) -> Result<Ticket, TokenError> {
    if token.len() > MAX_TOKEN_BYTES {
        return Err(TokenError::Malformed("too long"));
    }
    let bytes = unhex(token).ok_or(TokenError::Malformed("not hex"))?;
    let Some(split) = bytes.len().checked_sub(32) else {
        return Err(TokenError::Malformed("too short"));
    };
    let (body, tag) = bytes.split_at(split);
    let mut mac = HmacSha256::new_from_slice(secret).map_err(|_| TokenError::BadSignature)?;
    mac.update(body);
    // A constant-time comparison.
    mac.verify_slice(tag)
        .map_err(|_| TokenError::BadSignature)?;
    let claims = parse(body).ok_or(TokenError::Malformed("bad layout"))?;
    if now > claims.expires {
        return Err(TokenError::Expired {
            expires: claims.expires,
            now,
        });
    }
    if claims.room != room {
        return Err(TokenError::WrongRoom(claims.room));
    }
    let mut k = [0u8; 8];
    k.copy_from_slice(&tag[..8]);
    Ok(Ticket {
        claims,
        key: u64::from_le_bytes(k),
    })
}

fn parse(body: &[u8]) -> Option<JoinClaims> {
    let (&version, rest) = body.split_first()?;
    if version != TOKEN_VERSION {
        return None;
    }
    let (expires, rest) = rest.split_first_chunk::<8>()?;
    let (&seat, mut rest) = rest.split_first()?;
    let mut names = [String::new(), String::new()];
    for name in &mut names {
        let (&len, tail) = rest.split_first()?;
        let (text, tail) = tail.split_at_checked(usize::from(len))?;
        *name = String::from_utf8(text.to_vec()).ok()?;
        rest = tail;
    }
    if !rest.is_empty() || (seat != ANY_SEAT && usize::from(seat) >= MAX_PLAYERS) {
        return None;
    }
    let [room, player] = names;
    Some(JoinClaims {
        room,
        seat: (seat != ANY_SEAT).then_some(Slot(seat)),
        player,
        expires: u64::from_le_bytes(*expires),
    })
}

fn hex(bytes: &[u8]) -> String {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    let mut out = String::with_capacity(bytes.len() * 2);
    for &b in bytes {
        out.push(char::from(DIGITS[usize::from(b >> 4)]));
        out.push(char::from(DIGITS[usize::from(b & 15)]));
    }
    out
}

fn unhex(text: &str) -> Option<Vec<u8>> {
    let digit = |c: u8| match c {
        b'0'..=b'9' => Some(c - b'0'),
        b'a'..=b'f' => Some(c - b'a' + 10),
        b'A'..=b'F' => Some(c - b'A' + 10),
        _ => None,
    };
    let t = text.as_bytes();
    if !t.len().is_multiple_of(2) {
        return None;
    }
    t.chunks(2)
        .map(|p| Some(digit(p[0])? << 4 | digit(p[1])?))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const SECRET: &[u8] = b"0123456789abcdef-secret";

    #[test]
    fn the_mac_is_hmac_sha256_as_rfc_4231_gives_it() {
        // RFC 4231, test case 2.
        let mut mac = HmacSha256::new_from_slice(b"Jefe").unwrap();
        mac.update(b"what do ya want for nothing?");
        assert_eq!(
            hex(&mac.finalize().into_bytes()),
            "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843"
        );
    }

    fn claims() -> JoinClaims {
        JoinClaims {
            room: "arena".into(),
            seat: Some(Slot(2)),
            player: "alice".into(),
            expires: 1_000,
        }
    }

    #[test]
    fn a_token_verifies_with_its_secret_room_and_time() {
        let t = issue(SECRET, &claims()).unwrap();
        let ticket = verify(SECRET, &t, "arena", 999).unwrap();
        assert_eq!(ticket.claims, claims());
        // The expiry second itself is still valid.
        assert!(verify(SECRET, &t, "arena", 1_000).is_ok());
        let any = JoinClaims {
            seat: None,
            ..claims()
        };
        let t = issue(SECRET, &any).unwrap();
        assert_eq!(verify(SECRET, &t, "arena", 0).unwrap().claims.seat, None);
        assert!(t.len() <= MAX_TOKEN_BYTES);
    }

    #[test]
    fn altered_foreign_expired_and_misdirected_tokens_are_refused_with_their_reason() {
        let t = issue(SECRET, &claims()).unwrap();
        // Flip one hex digit in every position: never accepted.
        for i in 0..t.len() {
            let mut b = t.clone().into_bytes();
            b[i] = if b[i] == b'0' { b'1' } else { b'0' };
            let altered = String::from_utf8(b).unwrap();
            assert!(verify(SECRET, &altered, "arena", 0).is_err(), "digit {i}");
        }
        assert_eq!(
            verify(b"another secret of 16+ bytes", &t, "arena", 0),
            Err(TokenError::BadSignature)
        );
        assert_eq!(
            verify(SECRET, &t, "arena", 1_001),
            Err(TokenError::Expired {
                expires: 1_000,
                now: 1_001
            })
        );
        assert_eq!(
            verify(SECRET, &t, "lobby", 0),
            Err(TokenError::WrongRoom("arena".into()))
        );
        assert_eq!(
            verify(SECRET, &t[..t.len() - 2], "arena", 0),
            Err(TokenError::BadSignature)
        );
        assert_eq!(
            verify(SECRET, "abc", "arena", 0),
            Err(TokenError::Malformed("not hex"))
        );
        assert_eq!(
            verify(SECRET, "zz", "arena", 0),
            Err(TokenError::Malformed("not hex"))
        );
        assert_eq!(
            verify(SECRET, "00", "arena", 0),
            Err(TokenError::Malformed("too short"))
        );
        assert_eq!(
            verify(SECRET, &"0".repeat(MAX_TOKEN_BYTES + 2), "arena", 0),
            Err(TokenError::Malformed("too long"))
        );
        assert!(issue(b"short", &claims()).is_err());
        let far = JoinClaims {
            seat: Some(Slot(16)),
            ..claims()
        };
        assert!(issue(SECRET, &far).is_err());
    }
}
