//! The canonical state hash.
//!
//! A desync is found by comparing hashes, so the hash must be a fixed
//! function of the simulation state, stable across builds, platforms and
//! versions of Rust (no `std::hash`, whose `DefaultHasher` is allowed to
//! change and whose `RandomState` is seeded per process). The algorithm is
//! written down in `docs/determinism.md` so another program can recompute it.
//!
//! `StateHasher` consumes 64-bit words. Each word is mixed with
//! `h = (h ⊕ w) · K` followed by `h ⊕= h >> 29`. Both steps are bijections of
//! `h` for a fixed `w` and of `w` for a fixed `h`, so changing any single
//! word always changes the result; `finish` applies the SplitMix64
//! finaliser so that nearby states give unrelated hashes.

/// Initial value: the ASCII bytes of "lockstep", big-endian.
pub(crate) const HASH_SEED: u64 = 0x6c6f_636b_7374_6570;
/// The odd multiplier (2⁶⁴/φ).
pub(crate) const HASH_MULTIPLIER: u64 = 0x9e37_79b9_7f4a_7c15;

/// A word-at-a-time hasher with a fixed, documented algorithm.
#[derive(Clone, Copy, Debug)]
pub struct StateHasher {
    h: u64,
}

impl Default for StateHasher {
    fn default() -> Self {
        StateHasher::new()
    }
}

impl StateHasher {
    /// A hasher in its initial state.
    pub const fn new() -> StateHasher {
        StateHasher { h: HASH_SEED }
    }

    /// Mixes in one word.
    #[inline(always)]
    pub fn word(&mut self, w: u64) {
        let h = (self.h ^ w).wrapping_mul(HASH_MULTIPLIER);
        self.h = h ^ (h >> 29);
    }

    /// Mixes in a signed word (its two's-complement bits).
    #[inline(always)]
    pub fn int(&mut self, v: i64) {
        self.word(v as u64);
    }

    /// Mixes in a fixed-point value's raw bits.
    #[inline(always)]
    pub fn scalar(&mut self, v: crate::math::Scalar) {
        self.int(v.to_bits());
    }

    /// Mixes in x, y, z.
    #[inline(always)]
    pub fn vec3(&mut self, v: crate::math::Vec3) {
        self.scalar(v.x);
        self.scalar(v.y);
        self.scalar(v.z);
    }

    /// Mixes in x, y, z, w.
    #[inline(always)]
    pub fn quat(&mut self, q: crate::math::Quat) {
        self.scalar(q.x);
        self.scalar(q.y);
        self.scalar(q.z);
        self.scalar(q.w);
    }

    /// Mixes in translation then rotation.
    pub fn transform(&mut self, t: &crate::math::Transform) {
        self.vec3(t.translation);
        self.quat(t.rotation);
    }

    /// Mixes in xx, yy, zz, xy, xz, yz.
    pub fn sym(&mut self, m: &crate::math::SymMat3) {
        for v in [m.xx, m.yy, m.zz, m.xy, m.xz, m.yz] {
            self.scalar(v);
        }
    }

    /// Mixes in a byte string: its length, then its bytes packed
    /// little-endian into words (the last word zero-padded).
    pub fn bytes(&mut self, b: &[u8]) {
        self.word(b.len() as u64);
        for chunk in b.chunks(8) {
            let mut w = [0u8; 8];
            w[..chunk.len()].copy_from_slice(chunk);
            self.word(u64::from_le_bytes(w));
        }
    }

    /// The final hash (SplitMix64 finaliser of the state).
    pub fn finish(&self) -> u64 {
        let mut z = self.h;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
}

/// A fingerprint of a shape's geometry, computed once when a collider is
/// added (shapes never change afterwards). The words, per kind, are listed
/// in `docs/determinism.md`.
pub(crate) fn shape_hash(shape: &crate::shape::Shape) -> u64 {
    use crate::shape::Shape;
    let mut h = StateHasher::new();
    match shape {
        Shape::Sphere(s) => {
            h.word(0);
            h.scalar(s.radius);
        }
        Shape::Capsule(c) => {
            h.word(1);
            h.scalar(c.half_height);
            h.scalar(c.radius);
        }
        Shape::Cuboid(b) => {
            h.word(2);
            h.vec3(b.half_extents);
        }
        Shape::ConvexHull(hull) => {
            h.word(3);
            h.word(hull.vertices().len() as u64);
            for v in hull.vertices() {
                h.vec3(*v);
            }
        }
        Shape::TriMesh(mesh) => {
            h.word(4);
            h.word(mesh.vertices().len() as u64);
            for v in mesh.vertices() {
                h.vec3(*v);
            }
            h.word(mesh.indices().len() as u64);
            for t in mesh.indices() {
                for &i in t {
                    h.word(i as u64);
                }
            }
        }
        Shape::HeightField(f) => {
            h.word(5);
            h.word(f.rows() as u64);
            h.word(f.cols() as u64);
            h.vec3(f.scale());
            for &y in f.heights() {
                h.scalar(y);
            }
        }
    }
    h.finish()
}

/// How a dumped field's words read (the state hash's field dumps: the
/// world's bodies and pairs, and the game's own state).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum FieldKind {
    /// Unsigned words (flags, counts, handles, hashes).
    Word,
    /// Signed integers (two's complement).
    Int,
    /// Q32.32 fixed-point values: the raw bits of a [`Scalar`](crate::Scalar).
    Scalar,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_algorithm_gives_the_documented_values() {
        // These values are in docs/determinism.md, computed there by an
        // independent Python transcription of the algorithm.
        assert_eq!(StateHasher::new().finish(), 0x8574_94ab_d8fd_accc);
        let mut h = StateHasher::new();
        h.word(1);
        h.word(2);
        h.word(3);
        assert_eq!(h.finish(), 0xdd9a_c8ed_7100_044c);
    }

    #[test]
    fn any_single_word_change_changes_the_hash() {
        let base: Vec<u64> = (0..64).map(|i| i * 0x1234_5678_9abc).collect();
        let hash = |ws: &[u64]| {
            let mut h = StateHasher::new();
            for &w in ws {
                h.word(w);
            }
            h.finish()
        };
        let h0 = hash(&base);
        for i in 0..base.len() {
            for bit in [0, 1, 31, 63] {
                let mut m = base.clone();
                m[i] ^= 1 << bit;
                assert_ne!(hash(&m), h0);
            }
        }
    }
}
