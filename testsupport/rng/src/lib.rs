//! The one seeded generator that the workspace's tests and benchmarks draw
//! from. It has no dependencies, so every crate's tests can use it: the
//! protocol's (which do not depend on the core) as well as the core's own
//! unit tests (through `lockstep_core::testing`, which re-exports it).
//!
//! Not part of any product: the simulation never draws a random number.

/// SplitMix64: a small seeded 64-bit generator. The same seed gives the
/// same numbers on every machine, so a randomised test draws the same
/// inputs on every run.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator whose state starts at `seed` (any value, zero too).
    pub const fn new(seed: u64) -> Rng {
        Rng(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// A number in `0..n` (`n > 0`): the remainder of the next draw. Its
    /// small bias does not matter to a test.
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }

    /// An integer in `lo..=hi`.
    pub fn int(&mut self, lo: i64, hi: i64) -> i64 {
        lo + self.below((hi - lo + 1) as u64) as i64
    }

    /// A float in `[0, 1)`: the top 53 bits of the next draw.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A float in `[lo, hi)`.
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// True with probability `ppm` / 1 000 000.
    pub fn chance(&mut self, ppm: u32) -> bool {
        self.below(1_000_000) < u64::from(ppm)
    }

    /// `len` random bytes (the low byte of a draw each).
    pub fn bytes(&mut self, len: usize) -> Vec<u8> {
        (0..len).map(|_| self.next_u64() as u8).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_draws_of_seed_zero_are_splitmix64s() {
        // The reference values of SplitMix64 from state 0.
        let mut r = Rng::new(0);
        assert_eq!(r.next_u64(), 0xe220_a839_7b1d_cdaf);
        assert_eq!(r.next_u64(), 0x6e78_9e6a_a1b9_65f4);
    }

    #[test]
    fn draws_stay_in_their_ranges() {
        let mut r = Rng::new(7);
        for _ in 0..1000 {
            assert!(r.below(10) < 10);
            assert!((-3..=3).contains(&r.int(-3, 3)));
            let u = r.unit();
            assert!((0.0..1.0).contains(&u));
            let x = r.uniform(-2.0, 5.0);
            assert!((-2.0..5.0).contains(&x));
            assert_eq!(r.bytes(3).len(), 3);
        }
    }
}
