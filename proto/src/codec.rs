//! Bytes ↔ messages: a two-byte version header, then the message in bincode 2
//! (standard config: little-endian, variable-length integers), with every
//! bound checked on both sides.
//!
//! Decoding is the attack surface of the server: it takes any byte slice and
//! returns either a message that satisfies every invariant of
//! [`message`](crate::message) or a typed [`DecodeError`]. It never panics
//! (the fuzz tests feed it random bytes, truncations and bit flips) and never
//! allocates more than [`MAX_MESSAGE_BYTES`] worth of elements per container.
//!
//! On the reliable stream each message is framed by a 4-byte little-endian
//! length ([`encode_frame`], [`frame_length`]); datagrams carry one message
//! each, unframed.

use bincode::config::{Configuration, Limit, LittleEndian, Varint};
use bincode::enc::write::SizeWriter;
use serde::Serialize;
use serde::de::DeserializeOwned;
use thiserror::Error;

use crate::limits::{
    MAX_DATAGRAM_BYTES, MAX_MESSAGE_BYTES, PROTOCOL_VERSION, VERSION_HEADER_BYTES,
};
use crate::message::{Channel, ClientMessage, ServerMessage, Violation};

/// Bytes of the length prefix in front of each message on the reliable stream.
pub const FRAME_HEADER_BYTES: usize = 4;

/// The one bincode configuration of the protocol. The limit makes bincode
/// refuse length prefixes (strings) that claim more than a whole message.
const CONFIG: Configuration<LittleEndian, Varint, Limit<MAX_MESSAGE_BYTES>> =
    bincode::config::standard().with_limit::<MAX_MESSAGE_BYTES>();

/// Why bytes could not be turned into a message. The server logs it and
/// closes the offending connection; nothing in it can be trusted further.
#[derive(Debug, Error)]
pub enum DecodeError {
    /// The input is longer than any message of its kind may be.
    #[error("{len} bytes exceed the {max}-byte limit")]
    TooLarge {
        /// Bytes received.
        len: usize,
        /// Limit for this kind of message.
        max: usize,
    },
    /// The input is too short to hold even the version header.
    #[error("{len} bytes are too few for the version header")]
    Truncated {
        /// Bytes received.
        len: usize,
    },
    /// The peer speaks another protocol version.
    #[error("protocol version {found}, expected {expected}")]
    WrongVersion {
        /// Version in the header.
        found: u16,
        /// [`PROTOCOL_VERSION`].
        expected: u16,
    },
    /// The body is not a valid bincode encoding of a message (unknown
    /// variant, truncated field, invalid UTF-8, bad bool, oversized length...).
    #[error("malformed message: {0}")]
    Malformed(#[source] bincode::error::DecodeError),
    /// A valid message is followed by extra bytes.
    #[error("{extra} trailing bytes after the message")]
    TrailingBytes {
        /// Bytes left over.
        extra: usize,
    },
    /// The bytes decode, but not in the one encoding of their message (a
    /// varint in more bytes than it needs): what is accepted re-encodes to
    /// itself.
    #[error("not the canonical encoding of its message")]
    NotCanonical,
    /// The message decoded but breaks a protocol bound (too many entries, an
    /// input over [`MAX_INPUT_BYTES`](crate::MAX_INPUT_BYTES), ...).
    #[error("protocol violation: {0}")]
    Invalid(#[from] Violation),
}

/// Why a message could not be encoded. Only reachable by building a message
/// that breaks a bound; the room and session never do.
#[derive(Debug, Error)]
pub enum EncodeError {
    /// The message breaks a protocol bound.
    #[error("protocol violation: {0}")]
    Invalid(#[from] Violation),
    /// The encoding is longer than its channel allows.
    #[error("{len} bytes exceed the {max}-byte limit of the channel")]
    TooLarge {
        /// Encoded size.
        len: usize,
        /// Limit of the channel.
        max: usize,
    },
    /// bincode refused the value.
    #[error("bincode: {0}")]
    Bincode(#[source] bincode::error::EncodeError),
}

/// Largest encoded size, version header included, of a message on `channel`.
pub fn max_len(channel: Channel) -> usize {
    match channel {
        Channel::Datagram => MAX_DATAGRAM_BYTES,
        Channel::Reliable => MAX_MESSAGE_BYTES,
    }
}

/// Exact encoded size of `value` in the protocol's bincode configuration,
/// without the version header. Used by the room to pack datagrams without
/// encoding them twice.
pub(crate) fn body_len<T: Serialize>(value: &T) -> usize {
    let mut w = SizeWriter::default();
    // Sizing cannot fail for the plain data types of this crate; should it
    // ever, the count is still a lower bound and `encode` re-checks the limit.
    let _ = bincode::serde::encode_into_writer(value, &mut w, CONFIG);
    w.bytes_written
}

fn encode_checked<T: Serialize>(
    value: &T,
    validate: Result<(), Violation>,
    channel: Channel,
) -> Result<Vec<u8>, EncodeError> {
    validate?;
    let mut out = Vec::with_capacity(64);
    out.extend_from_slice(&PROTOCOL_VERSION.to_le_bytes());
    let body = bincode::serde::encode_to_vec(value, CONFIG).map_err(EncodeError::Bincode)?;
    out.extend_from_slice(&body);
    let max = max_len(channel);
    if out.len() > max {
        return Err(EncodeError::TooLarge {
            len: out.len(),
            max,
        });
    }
    Ok(out)
}

fn decode_checked<T: DeserializeOwned + Serialize>(bytes: &[u8]) -> Result<T, DecodeError> {
    if bytes.len() > MAX_MESSAGE_BYTES {
        return Err(DecodeError::TooLarge {
            len: bytes.len(),
            max: MAX_MESSAGE_BYTES,
        });
    }
    let (header, body) = match bytes.split_first_chunk::<VERSION_HEADER_BYTES>() {
        Some(split) => split,
        None => return Err(DecodeError::Truncated { len: bytes.len() }),
    };
    let found = u16::from_le_bytes(*header);
    if found != PROTOCOL_VERSION {
        return Err(DecodeError::WrongVersion {
            found,
            expected: PROTOCOL_VERSION,
        });
    }
    let (value, used) =
        bincode::serde::decode_from_slice::<T, _>(body, CONFIG).map_err(DecodeError::Malformed)?;
    if used != body.len() {
        return Err(DecodeError::TrailingBytes {
            extra: body.len() - used,
        });
    }
    // Varints have one shortest form; anything longer is refused, so two
    // peers never disagree on what a message's bytes are.
    if bincode::serde::encode_to_vec(&value, CONFIG)
        .ok()
        .as_deref()
        != Some(body)
    {
        return Err(DecodeError::NotCanonical);
    }
    Ok(value)
}

fn check_channel_len(len: usize, channel: Channel) -> Result<(), DecodeError> {
    let max = max_len(channel);
    if len > max {
        Err(DecodeError::TooLarge { len, max })
    } else {
        Ok(())
    }
}

impl ClientMessage {
    /// Encodes the message with its version header.
    ///
    /// ```
    /// use lockstep_proto::{ClientMessage, InputDatagram, Slot};
    ///
    /// let message = ClientMessage::Input(InputDatagram {
    ///     slot: Slot(2),
    ///     ack_bundle: Some(41),
    ///     first_tick: 45,
    ///     inputs: vec![vec![1, 0], vec![1, 1]], // the game's own bytes
    /// });
    /// let bytes = message.encode()?;
    /// assert_eq!(ClientMessage::decode(&bytes)?, message);
    /// // Anything else is an error, never a panic.
    /// assert!(ClientMessage::decode(&bytes[..bytes.len() - 1]).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`EncodeError`] if the message breaks a bound or its channel's size.
    pub fn encode(&self) -> Result<Vec<u8>, EncodeError> {
        encode_checked(self, self.validate(), self.channel())
    }

    /// Decodes one message from exactly `bytes` (a datagram, or a stream
    /// frame's payload).
    ///
    /// # Errors
    /// [`DecodeError`] for anything but a valid, complete message of this
    /// protocol version within every bound.
    pub fn decode(bytes: &[u8]) -> Result<Self, DecodeError> {
        let msg: Self = decode_checked(bytes)?;
        check_channel_len(bytes.len(), msg.channel())?;
        msg.validate()?;
        Ok(msg)
    }
}

impl ServerMessage {
    /// Encodes the message with its version header.
    ///
    /// # Errors
    /// [`EncodeError`] if the message breaks a bound or its channel's size.
    pub fn encode(&self) -> Result<Vec<u8>, EncodeError> {
        encode_checked(self, self.validate(), self.channel())
    }

    /// Decodes one message from exactly `bytes` (a datagram, or a stream
    /// frame's payload).
    ///
    /// # Errors
    /// [`DecodeError`] for anything but a valid, complete message of this
    /// protocol version within every bound.
    pub fn decode(bytes: &[u8]) -> Result<Self, DecodeError> {
        let msg: Self = decode_checked(bytes)?;
        check_channel_len(bytes.len(), msg.channel())?;
        msg.validate()?;
        Ok(msg)
    }
}

/// Prefixes an encoded message with its 4-byte little-endian length, for the
/// reliable stream.
///
/// # Errors
/// [`EncodeError::TooLarge`] if `message` exceeds [`MAX_MESSAGE_BYTES`].
pub fn encode_frame(message: &[u8]) -> Result<Vec<u8>, EncodeError> {
    if message.len() > MAX_MESSAGE_BYTES {
        return Err(EncodeError::TooLarge {
            len: message.len(),
            max: MAX_MESSAGE_BYTES,
        });
    }
    let mut out = Vec::with_capacity(FRAME_HEADER_BYTES + message.len());
    // The check above keeps the length far below u32::MAX.
    out.extend_from_slice(&(message.len() as u32).to_le_bytes());
    out.extend_from_slice(message);
    Ok(out)
}

/// Reads a stream frame's length prefix and checks it before the reader
/// allocates or waits for the payload.
///
/// # Errors
/// [`DecodeError::TooLarge`] above [`MAX_MESSAGE_BYTES`];
/// [`DecodeError::Truncated`] below the version header size.
pub fn frame_length(header: [u8; FRAME_HEADER_BYTES]) -> Result<usize, DecodeError> {
    let len = u32::from_le_bytes(header) as usize;
    if len > MAX_MESSAGE_BYTES {
        Err(DecodeError::TooLarge {
            len,
            max: MAX_MESSAGE_BYTES,
        })
    } else if len < VERSION_HEADER_BYTES {
        Err(DecodeError::Truncated { len })
    } else {
        Ok(len)
    }
}

#[cfg(test)]
mod tests {

    //! Decoding of messages that are valid bincode but break protocol bounds;
    //! these need the raw encoder, which bypasses validation.
    use super::*;
    use crate::limits::{MAX_INPUT_BYTES, MAX_INPUTS_PER_DATAGRAM, MAX_PLAYERS};
    use crate::message::{BundleDatagram, InputDatagram, PlayerInput, Slot, TickBundle, Welcome};

    fn raw<T: Serialize>(value: &T) -> Vec<u8> {
        let mut out = PROTOCOL_VERSION.to_le_bytes().to_vec();
        out.extend(bincode::serde::encode_to_vec(value, CONFIG).unwrap());
        out
    }

    fn input(inputs: Vec<Vec<u8>>) -> ClientMessage {
        ClientMessage::Input(InputDatagram {
            slot: Slot(1),
            ack_bundle: Some(9),
            first_tick: 10,
            inputs,
        })
    }

    #[test]
    fn input_over_max_input_bytes_is_a_semantic_violation() {
        let bytes = raw(&input(vec![vec![7; MAX_INPUT_BYTES + 1]]));
        match ClientMessage::decode(&bytes) {
            Err(DecodeError::Invalid(Violation::InputTooLarge { len, max })) => {
                assert_eq!((len, max), (65, 64));
            }
            other => panic!("expected InputTooLarge, got {other:?}"),
        }
        // The encoder refuses to produce it in the first place.
        assert!(matches!(
            input(vec![vec![7; MAX_INPUT_BYTES + 1]]).encode(),
            Err(EncodeError::Invalid(Violation::InputTooLarge { .. }))
        ));
    }

    #[test]
    fn too_many_repeated_inputs_is_a_semantic_violation() {
        let bytes = raw(&input(vec![vec![1]; MAX_INPUTS_PER_DATAGRAM + 1]));
        assert!(matches!(
            ClientMessage::decode(&bytes),
            Err(DecodeError::Invalid(Violation::TooManyEntries {
                count: 17,
                max: 16
            }))
        ));
    }

    #[test]
    fn bundle_with_duplicate_slots_or_unordered_ticks_is_refused() {
        let p = |s| PlayerInput {
            slot: Slot(s),
            input: vec![1, 2],
            substituted: false,
        };
        let dup = ServerMessage::Bundles(BundleDatagram {
            ack_input: None,
            bundles: vec![TickBundle {
                tick: 3,
                inputs: vec![p(1), p(1)],
            }],
        });
        assert!(matches!(
            ServerMessage::decode(&raw(&dup)),
            Err(DecodeError::Invalid(Violation::SlotsNotAscending))
        ));
        let unordered = ServerMessage::Bundles(BundleDatagram {
            ack_input: None,
            bundles: vec![
                TickBundle {
                    tick: 5,
                    inputs: vec![p(0)],
                },
                TickBundle {
                    tick: 4,
                    inputs: vec![p(0)],
                },
            ],
        });
        assert!(matches!(
            ServerMessage::decode(&raw(&unordered)),
            Err(DecodeError::Invalid(Violation::TicksNotAscending))
        ));
        let slot = ServerMessage::Bundles(BundleDatagram {
            ack_input: None,
            bundles: vec![TickBundle {
                tick: 5,
                inputs: vec![p(MAX_PLAYERS as u8)],
            }],
        });
        assert!(matches!(
            ServerMessage::decode(&raw(&slot)),
            Err(DecodeError::Invalid(Violation::SlotOutOfRange(16)))
        ));
    }

    #[test]
    fn oversized_bundle_datagram_is_refused_by_size_on_both_sides() {
        let big = ServerMessage::Bundles(BundleDatagram {
            ack_input: Some(1),
            bundles: (0..16)
                .map(|t| TickBundle {
                    tick: t,
                    inputs: (0..4)
                        .map(|s| PlayerInput {
                            slot: Slot(s),
                            input: vec![0; MAX_INPUT_BYTES],
                            substituted: false,
                        })
                        .collect(),
                })
                .collect(),
        });
        let bytes = raw(&big);
        assert!(bytes.len() > MAX_DATAGRAM_BYTES);
        assert!(matches!(
            ServerMessage::decode(&bytes),
            Err(DecodeError::TooLarge { max: 1150, .. })
        ));
        assert!(matches!(
            big.encode(),
            Err(EncodeError::TooLarge { max: 1150, .. })
        ));
    }

    #[test]
    fn welcome_with_window_not_above_delay_is_refused() {
        let w = ServerMessage::Welcome(Welcome {
            slot: Slot(0),
            tick_rate: 60,
            input_delay: 8,
            input_window: 8,
            max_input_bytes: 8,
            start_tick: 0,
            scene_hash: 1,
            scene: vec![],
            resume: None,
            rules: None,
            seed: 0,
            rejoin: None,
        });
        assert!(matches!(
            ServerMessage::decode(&raw(&w)),
            Err(DecodeError::Invalid(Violation::BadInputWindow {
                window: 8,
                delay: 8
            }))
        ));
    }

    #[test]
    fn body_len_matches_encoding() {
        let m = input(vec![vec![1; 8]; 5]);
        assert_eq!(
            body_len(&m) + VERSION_HEADER_BYTES,
            m.encode().unwrap().len()
        );
    }

    #[test]
    fn frame_header_round_trips_and_rejects_bad_lengths() {
        let msg = ClientMessage::Leave.encode().unwrap();
        let framed = encode_frame(&msg).unwrap();
        let header: [u8; 4] = framed[..4].try_into().unwrap();
        assert_eq!(frame_length(header).unwrap(), msg.len());
        assert_eq!(
            ClientMessage::decode(&framed[4..]).unwrap(),
            ClientMessage::Leave
        );
        assert!(matches!(
            frame_length(u32::MAX.to_le_bytes()),
            Err(DecodeError::TooLarge { .. })
        ));
        assert!(matches!(
            frame_length(1u32.to_le_bytes()),
            Err(DecodeError::Truncated { len: 1 })
        ));
    }

    /// A varint in more bytes than it needs decodes to a valid message,
    /// but is not that message's encoding: refused. So is a join without a
    /// room name.
    #[test]
    fn non_canonical_encodings_and_empty_room_names_are_refused() {
        let pong = ClientMessage::Pong(crate::message::Pong { nonce: 5 });
        let bytes = pong.encode().unwrap();
        assert_eq!(&bytes[2..], &[3, 5]);
        assert_eq!(ClientMessage::decode(&bytes).unwrap(), pong);
        let mut long = bytes[..3].to_vec();
        long.extend_from_slice(&[251, 5, 0]);
        assert!(matches!(
            ClientMessage::decode(&long),
            Err(DecodeError::NotCanonical)
        ));
        let crate::message::ClientMessage::Join(mut join) = crate::Session::join_message("r", "p")
        else {
            unreachable!()
        };
        join.room.clear();
        assert!(matches!(
            ClientMessage::Join(join).encode(),
            Err(EncodeError::Invalid(Violation::EmptyRoomName))
        ));
    }
}
