//! The demo's player input, its wire format, and scripted bot inputs.

/// Length of an encoded [`DemoInput`], bytes.
pub const INPUT_LEN: usize = 3;

/// The most a move component may be: 100 % of the maximum speed.
const MOVE_LIMIT: i8 = 100;

/// Bit 0 of the flags byte: jump.
const FLAG_JUMP: u8 = 1;

/// A demo player's input for one tick.
///
/// `move_x` and `move_z` are the wished horizontal velocity along world x
/// and z, in percent of [`MAX_SPEED`](super::MAX_SPEED), each in
/// `-100..=100`; `jump` asks for a jump (taken only when the player stands
/// on the floor). The default is "no input": stand still, no jump.
///
/// # Wire format
/// Exactly [`INPUT_LEN`] = 3 bytes:
///
/// | byte | meaning |
/// |---|---|
/// | 0 | `move_x` as a two's-complement `i8`, −100..=100 |
/// | 1 | `move_z` as a two's-complement `i8`, −100..=100 |
/// | 2 | flags: bit 0 = jump; bits 1–7 must be 0 |
///
/// Anything else (another length, a move outside ±100, a reserved flag bit
/// set) does not decode, and the rules treat it as no input. Reserved bits
/// are rejected rather than ignored so that a later format can give them a
/// meaning without old peers silently misreading it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct DemoInput {
    /// Wished velocity along x, percent of the maximum speed (−100..=100).
    pub move_x: i8,
    /// Wished velocity along z, percent of the maximum speed (−100..=100).
    pub move_z: i8,
    /// Jump if standing on the floor.
    pub jump: bool,
}

impl DemoInput {
    /// The 3-byte wire form (see the type's docs). Move components outside
    /// −100..=100 are clamped into it first, so every encoded input decodes.
    pub fn encode(&self) -> Vec<u8> {
        let clamp = |m: i8| m.clamp(-MOVE_LIMIT, MOVE_LIMIT).to_le_bytes()[0];
        vec![
            clamp(self.move_x),
            clamp(self.move_z),
            if self.jump { FLAG_JUMP } else { 0 },
        ]
    }

    /// Reads the 3-byte wire form; `None` for anything malformed (wrong
    /// length, a move outside −100..=100, a reserved flag bit set). Never
    /// panics, whatever the bytes.
    pub fn decode(bytes: &[u8]) -> Option<DemoInput> {
        let &[x, z, flags] = bytes else {
            return None;
        };
        let (move_x, move_z) = (i8::from_le_bytes([x]), i8::from_le_bytes([z]));
        let in_range = |m: i8| (-MOVE_LIMIT..=MOVE_LIMIT).contains(&m);
        if !in_range(move_x) || !in_range(move_z) || flags & !FLAG_JUMP != 0 {
            return None;
        }
        Some(DemoInput {
            move_x,
            move_z,
            jump: flags & FLAG_JUMP != 0,
        })
    }
}

/// Sixteen compass directions, 22.5° apart, as rounded `100·(cos, sin)`.
const DIRECTIONS: [(i8, i8); 16] = [
    (100, 0),
    (92, 38),
    (71, 71),
    (38, 92),
    (0, 100),
    (-38, 92),
    (-71, 71),
    (-92, 38),
    (-100, 0),
    (-92, -38),
    (-71, -71),
    (-38, -92),
    (0, -100),
    (38, -92),
    (71, -71),
    (92, -38),
];

/// Salts that keep the hash streams of [`bot_input`] independent.
const STREAM_PERIOD: u64 = 1;
const STREAM_PHASE: u64 = 2;
const STREAM_HEADING: u64 = 3;
const STREAM_JUMP: u64 = 4;

/// How often (ticks) a bot considers jumping, and for how many ticks it
/// then holds the button.
const JUMP_WINDOW: u64 = 30;
const JUMP_HOLD: u64 = 2;

/// The SplitMix64 finaliser: a bijective 64-bit mix with full avalanche.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A hash of (seed, slot, stream, n): the only source of "randomness" for
/// bots, so a bot's input is a pure function of its arguments.
fn bot_hash(seed: u64, slot: u8, stream: u64, n: u64) -> u64 {
    let a = mix(seed ^ stream.wrapping_mul(0x9e37_79b9_7f4a_7c15));
    let b = mix(a ^ u64::from(slot));
    mix(b ^ n)
}

/// Deterministic bot input: a pure function of `(seed, slot, tick)`, so a
/// bot needs no state, and any peer (or a test) can recompute what a bot
/// pressed at any tick.
///
/// Each bot wanders: it keeps one heading for a period of 60 to 120 ticks
/// (1 to 2 s at 60 Hz; the period and its phase are fixed per bot, so bots
/// do not all turn at once), then picks another one of 16 compass headings
/// at 40 % to 100 % of the maximum speed, or stands still one period in
/// eight. Once every 30 ticks it jumps with probability 1/4 (holding the
/// button for 2 ticks).
pub fn bot_input(seed: u64, slot: u8, tick: u64) -> DemoInput {
    let period = 60 + bot_hash(seed, slot, STREAM_PERIOD, 0) % 61;
    let phase = bot_hash(seed, slot, STREAM_PHASE, 0) % period;
    let segment = tick.wrapping_add(phase) / period;
    let h = bot_hash(seed, slot, STREAM_HEADING, segment);
    let (move_x, move_z) = if h.is_multiple_of(8) {
        (0, 0)
    } else {
        let (dx, dz) = DIRECTIONS[((h >> 3) % 16) as usize];
        // Speed in 40..=100 percent; the product stays within ±100.
        let speed = 40 + ((h >> 7) % 61) as i16;
        let scale = |d: i8| ((i16::from(d) * speed) / 100) as i8;
        (scale(dx), scale(dz))
    };
    let window = tick / JUMP_WINDOW;
    let jump = tick % JUMP_WINDOW < JUMP_HOLD
        && bot_hash(seed, slot, STREAM_JUMP, window).is_multiple_of(4);
    DemoInput {
        move_x,
        move_z,
        jump,
    }
}
