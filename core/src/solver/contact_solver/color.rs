//! Constraint graph colouring: the solve order of the contact constraints.
//!
//! Two constraints get the same colour only if they share no dynamic body
//! that moves this tick. Within a colour no body's velocity is read by one
//! constraint and written by another, so the constraints of a colour could
//! be visited in any order, or at once, with the same result: that is what
//! lets a pass over a colour be split into lanes or over threads without
//! changing a bit. A pass visits the colours in order, then the overflow
//! (the constraints that found no free colour), each in pair order.
//!
//! How a constraint finds its colour (greedy, in pair order): the first
//! colour, counting up from 0, in which none of its dynamic bodies is taken
//! yet; a static, sleeping or kinematic body takes no colour (its velocity
//! never changes). None free: the overflow, visited after the last colour.
//!
//! Why contacts with the ground count up like the others: Box2D v3 counts
//! them down from the last colour, so that a stack's ground contacts are
//! solved after everything above them. Measured here, that left the
//! pyramid of 20 and a light/heavy stack awake for the whole 60 s, and
//! ragdolls on stairs never slept. Counting up keeps the ground contacts
//! (first in pair order, as the ground is usually built first) in the
//! first colours, close to the bottom-up order of the solver before it had
//! colours.
//!
//! The colouring is recomputed each tick from this tick's constraints, in
//! pair order: it is a pure function of the contact set and the bodies'
//! kinds and sleep states, which the state hash already covers, so it
//! needs no place in snapshots or the hash, and a restored world colours
//! exactly as the one it was saved from. Colouring costs one word per body
//! of each constraint, far less than one solver pass.

use super::constraint::NONE;
use crate::collision::contacts::reserve_near;
use crate::scratch::Scratch;

/// Colours before the overflow. A box in a pyramid touches at most six
/// dynamic neighbours and greedy colouring needs at most twice that; a
/// hull in a pile touches more. 24 kept the overflow empty on every
/// benchmark scene.
pub(crate) const COLORS: usize = 24;

/// The index of the overflow in the per-colour counts and ranges.
pub(crate) const OVERFLOW: usize = COLORS;

// A body's colours are the bits of one `u32`.
const _: () = assert!(COLORS < 32);

/// The colour assignment of one tick.
#[derive(Clone, Debug, Default)]
pub(crate) struct Coloring {
    /// Per body slot, the colours (bit `c` for colour `c`) in which a
    /// constraint has the body: one word per slot, so finding a
    /// constraint's first free colour is one load per body and a count of
    /// trailing ones. Every bit set is cleared again before
    /// [`Coloring::finish`] returns, so the next tick starts from zeros
    /// without clearing every word.
    taken: Vec<u32>,
    /// Per candidate constraint (in pair order), its colour.
    color: Vec<u8>,
    /// The dynamic slots of each candidate (`NONE` for no dynamic body), to
    /// clear `taken` afterwards.
    slots: Vec<[u32; 2]>,
    /// Constraints per colour, the overflow last.
    count: [u32; COLORS + 1],
    /// Whether this tick colours at all: if not, every constraint goes to
    /// the overflow, which is pair order.
    enabled: bool,
}

impl Coloring {
    /// Starts a tick over `slots` body slots; with `enabled` false every
    /// constraint of the tick goes to the overflow (pair order, one
    /// thread).
    pub(crate) fn begin(&mut self, slots: usize, enabled: bool) {
        self.enabled = enabled;
        // Only grows or shrinks the zeroed words: every bit is clear
        // between ticks.
        self.taken.resize(slots, 0);
        self.color.clear();
        self.slots.clear();
        self.count = [0; COLORS + 1];
    }

    /// Colours the next constraint in pair order, whose dynamic moving
    /// bodies are at slots `a` and `b` (`NONE` for a body that is not one),
    /// and returns its colour ([`OVERFLOW`] if none is free).
    pub(crate) fn assign(&mut self, a: u32, b: u32) -> usize {
        let mask = |s: u32| if s == NONE { 0 } else { self.taken[s as usize] };
        let free = if self.enabled {
            !(mask(a) | mask(b)) & ((1u32 << COLORS) - 1)
        } else {
            0
        };
        let color = if free != 0 {
            let c = free.trailing_zeros() as usize;
            for s in [a, b] {
                if s != NONE {
                    self.taken[s as usize] |= 1 << c;
                }
            }
            c
        } else {
            OVERFLOW
        };
        self.color.push(color as u8);
        self.slots.push([a, b]);
        self.count[color] += 1;
        color
    }

    /// Clears every bit this tick set, and returns the start of each
    /// colour's range in the colour-ordered constraint array (`COLORS + 2`
    /// entries: colour `c` is `starts[c]..starts[c + 1]`, the overflow
    /// `starts[OVERFLOW]..starts[OVERFLOW + 1]`).
    pub(crate) fn finish(&mut self) -> [u32; COLORS + 2] {
        for (k, &[a, b]) in self.slots.iter().enumerate() {
            let c = self.color[k] as usize;
            if c == OVERFLOW {
                continue;
            }
            for s in [a, b] {
                if s != NONE {
                    self.taken[s as usize] = 0;
                }
            }
        }
        let mut starts = [0u32; COLORS + 2];
        for c in 0..=COLORS {
            starts[c + 1] = starts[c] + self.count[c];
        }
        starts
    }

    /// Makes room for `n` constraints this tick (see `reserve_near`).
    pub(crate) fn reserve(&mut self, n: usize) {
        reserve_near(&mut self.color, n);
        reserve_near(&mut self.slots, n);
    }

    /// This tick's colours with at least one constraint, and the
    /// constraints that found no free colour: both zero without colours
    /// (pair order is not an overflow).
    pub(crate) fn report(&self) -> (u32, u32) {
        if !self.enabled {
            return (0, 0);
        }
        let used = self.count[..COLORS].iter().filter(|&&n| n > 0).count();
        (used as u32, self.count[OVERFLOW])
    }

    /// The colour of the `k`th candidate coloured this tick.
    pub(crate) fn color_of(&self, k: usize) -> usize {
        self.color[k] as usize
    }

    /// The buffers, for the growth check of `prepare`.
    pub(crate) fn buffers(&self) -> [&dyn Scratch; 3] {
        [&self.taken, &self.color, &self.slots]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::testing::Rng;

    /// The next draw of the workspace's test generator.
    fn next(seed: &mut Rng) -> u64 {
        seed.next_u64()
    }

    #[test]
    fn no_colour_holds_a_dynamic_body_twice() {
        let mut col = Coloring::default();
        let mut seed = Rng::new(7);
        for round in 0..20 {
            let slots = 10 + (next(&mut seed) % 200) as u32;
            col.begin(slots as usize, true);
            let mut edges = Vec::new();
            for _ in 0..(slots * 3) {
                let pick = |seed: &mut Rng| {
                    if next(seed).is_multiple_of(4) {
                        NONE
                    } else {
                        (next(seed) % u64::from(slots)) as u32
                    }
                };
                let (a, b) = (pick(&mut seed), pick(&mut seed));
                if a == b || (a == NONE && b == NONE) {
                    continue;
                }
                let c = col.assign(a, b);
                edges.push((a, b, c));
            }
            let starts = col.finish();
            assert_eq!(starts[OVERFLOW + 1] as usize, edges.len(), "round {round}");
            for (i, &(a, b, c)) in edges.iter().enumerate() {
                assert_eq!(col.color_of(i), c);
                if c == OVERFLOW {
                    continue;
                }
                for &(a2, b2, c2) in &edges[i + 1..] {
                    if c2 != c {
                        continue;
                    }
                    for s in [a, b] {
                        assert!(
                            s == NONE || (s != a2 && s != b2),
                            "round {round}: slot {s} twice in colour {c}"
                        );
                    }
                }
            }
            // Every bit is clear for the next round.
            assert!(col.taken.iter().all(|&w| w == 0), "round {round}");
        }
    }

    #[test]
    fn each_constraint_takes_the_first_colour_free_for_its_dynamic_bodies() {
        let mut col = Coloring::default();
        col.begin(8, true);
        // A chain 0-1-2 on the ground (no slot: it takes no colour), and a
        // pair 3-4.
        assert_eq!(col.assign(NONE, 0), 0);
        assert_eq!(col.assign(1, NONE), 0);
        assert_eq!(col.assign(0, 1), 1);
        assert_eq!(col.assign(1, 2), 2);
        assert_eq!(col.assign(2, NONE), 0);
        assert_eq!(col.assign(3, 4), 0);
        let starts = col.finish();
        assert_eq!(starts[0], 0);
        assert_eq!(starts[1], 4, "four constraints in colour 0");
        assert_eq!(starts[2], 5);
        assert_eq!(starts[3], 6);
        assert_eq!(starts[COLORS], 6);
        assert_eq!(starts[OVERFLOW + 1], 6, "nothing in the overflow");
        assert_eq!(col.report(), (3, 0));
    }

    #[test]
    fn a_body_in_more_constraints_than_colours_overflows() {
        let mut col = Coloring::default();
        col.begin(200, true);
        // A hub touching 30 others: the first COLORS take one colour each,
        // the rest go to the overflow.
        for k in 0..30u32 {
            let c = col.assign(0, k + 1);
            if (k as usize) < COLORS {
                assert_eq!(c, k as usize);
            } else {
                assert_eq!(c, OVERFLOW);
            }
        }
        let starts = col.finish();
        assert_eq!(starts[OVERFLOW + 1] - starts[OVERFLOW], 30 - COLORS as u32);
        assert_eq!(col.report(), (COLORS as u32, 30 - COLORS as u32));
        assert!(col.taken.iter().all(|&w| w == 0));
        // A second tick with fewer slots starts clear too.
        col.begin(10, true);
        assert_eq!(col.assign(0, 1), 0);
        assert_eq!(col.assign(0, 2), 1);
        col.finish();
    }

    #[test]
    fn without_colours_every_constraint_keeps_pair_order_in_the_overflow() {
        let mut col = Coloring::default();
        col.begin(8, false);
        for (a, b) in [(NONE, 0), (0, 1), (2, 3), (1, NONE)] {
            assert_eq!(col.assign(a, b), OVERFLOW);
        }
        let starts = col.finish();
        assert_eq!(starts[OVERFLOW], 0, "no colour holds a constraint");
        assert_eq!(starts[OVERFLOW + 1], 4);
        assert_eq!(col.report(), (0, 0), "pair order reports no overflow");
        assert!(col.taken.iter().all(|&w| w == 0));
    }
}
