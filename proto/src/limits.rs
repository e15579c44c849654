//! Protocol constants: the version and every bound the codec enforces.
//!
//! Each bound exists so that a hostile or buggy peer cannot make the other
//! side allocate without limit, and so that every datagram fits one QUIC
//! datagram frame. `docs/protocol.md` explains how the numbers were chosen.

/// Version of the wire format. Every encoded message starts with it (two
/// bytes, little-endian) so a peer built from another version is refused with
/// [`DecodeError::WrongVersion`](crate::DecodeError::WrongVersion) instead of
/// being misread. Bump it on any change to a message layout.
/// Version 2 added the join token and the desync probes and report.
/// Version 3 added the rules in the welcome and the game state in the
/// desync probes and report.
/// Version 4 added the rejoin credential to the join and the welcome.
pub const PROTOCOL_VERSION: u16 = 4;

/// Bytes taken by the version header in front of every encoded message.
pub const VERSION_HEADER_BYTES: usize = 2;

/// Largest input a player may send for one tick. Inputs are opaque to the
/// protocol (the game encodes buttons, axes, commands); a bound keeps a tick
/// bundle of [`MAX_PLAYERS`] inputs inside one datagram.
pub const MAX_INPUT_BYTES: usize = 64;

/// Most players a room can hold. With [`MAX_INPUT_BYTES`] inputs a single tick
/// bundle of this many players still fits one [`MAX_DATAGRAM_BYTES`] datagram
/// (checked by a test), which is what lets bundles travel unfragmented.
pub const MAX_PLAYERS: usize = 16;

/// Largest encoded size of a datagram-channel message (inputs, bundles, ping,
/// pong). QUIC guarantees 1200-byte UDP payloads on every path; a 1-RTT
/// packet spends at most 50 bytes of that on itself (flags 1, connection id
/// 20, packet number 4, AEAD tag 16, DATAGRAM frame header 9), so a
/// 1150-byte datagram can be sent on any path by any QUIC stack (quinn
/// reports 1162 with its 8-byte connection ids). Encoders stay within it and
/// decoders refuse anything larger.
pub const MAX_DATAGRAM_BYTES: usize = 1150;

/// Most inputs one input datagram repeats. At the largest input size
/// (16 × 65 bytes + header) this still fits [`MAX_DATAGRAM_BYTES`]. A session
/// paced by bundles has at most `input_delay + 1` inputs outstanding, so with
/// an input delay below 16 ticks (267 ms at 60 Hz) every unacknowledged input
/// is in every datagram; beyond that the oldest (most urgent) go first.
pub const MAX_INPUTS_PER_DATAGRAM: usize = 16;

/// Most tick bundles one bundle datagram carries. The room packs fewer when
/// their bytes would exceed [`MAX_DATAGRAM_BYTES`]. At 60 Hz, 16 bundles cover
/// a 250 ms round trip with every unacknowledged bundle repeated in every
/// datagram, and a loss burst of up to 15 datagrams costs no retransmission.
pub const MAX_BUNDLES_PER_DATAGRAM: usize = 16;

/// Most per-body hashes one hash report may carry (32 KiB on the reliable
/// stream). Reserved for locating the first divergent body of a desync.
pub const MAX_BODY_HASHES: usize = 4096;

/// Longest room or player name, in UTF-8 bytes.
pub const MAX_NAME_BYTES: usize = 64;

/// Longest human-readable detail attached to a close message, in UTF-8 bytes.
pub const MAX_DETAIL_BYTES: usize = 256;

/// Largest scene blob a welcome may carry. Scenes are sent once per join on the
/// reliable stream; 4 MiB is far above a hand-made scene and still small
/// enough that a malicious length cannot exhaust memory.
pub const MAX_SCENE_BYTES: usize = 4 << 20;

/// Largest encoded message of any kind (a welcome with the largest scene plus
/// headroom for its other fields). The decoder refuses longer input before
/// looking at it, and bincode's own allocation limit is set to the same value.
pub const MAX_MESSAGE_BYTES: usize = MAX_SCENE_BYTES + 4096;

/// Largest input window (ticks ahead of the next open tick for which the room
/// accepts inputs) a welcome may announce; bounds the client's input ring.
pub const MAX_INPUT_WINDOW: u16 = 1024;

/// Most bodies one field probe asks for, and most bodies a desync report
/// lists per player.
pub const MAX_PROBE_BODIES: usize = 8;

/// Most fields in one body's dump.
pub const MAX_DUMP_FIELDS: usize = 128;

/// Most words in one dumped field.
pub const MAX_FIELD_WORDS: usize = 32;

/// Longest field name, in UTF-8 bytes.
pub const MAX_FIELD_NAME_BYTES: usize = 96;

/// Most snapshot bytes one probe reply carries (the snapshot is fetched in
/// chunks of at most this size).
pub const MAX_SNAPSHOT_CHUNK_BYTES: usize = 32 << 10;

/// Largest snapshot a room fetches for a desync bundle (chunk by chunk).
pub const MAX_PROBE_SNAPSHOT_BYTES: usize = 64 << 20;

/// Most bodies a world may list in a body-hash probe reply's total.
pub const MAX_PROBE_TOTAL_BODIES: usize = 1 << 20;

/// Most differing fields a desync report lists in all (what lies beyond is
/// counted, not listed).
pub const MAX_REPORT_FIELDS: usize = 256;
