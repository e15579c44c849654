//! The contact set's active pairs: the index of the pairs that may involve
//! an awake or kinematic body, the fast update that walks only them, and
//! keeping the index in step with sleep and wake.

use super::{
    Candidate, ContactEvent, ContactPair, ContactSet, ContactStats, NEW_PAIR, NarrowTest, counts,
    reserve_near,
};
use crate::scratch::Capacities;
use crate::workers::Workers;

/// The active pairs: indices into the pair array, ascending, of every pair
/// that may involve an awake or kinematic body, plus running totals so the
/// step's counters need no walk over the sleeping pairs.
#[derive(Clone, Debug, Default)]
pub(super) struct ActivePairs {
    /// Whether `index` and the totals describe the pairs.
    pub(super) valid: bool,
    /// Ascending pair indices.
    pub(super) index: Vec<u32>,
    /// Scratch for the next `index`.
    pub(super) next_index: Vec<u32>,
    /// Scratch: the keys of `order`'s entries and whether each was a
    /// candidate, for the in-place merge after a fast update that created
    /// or dropped pairs.
    pub(super) keys: Vec<((u32, u32), bool)>,
    /// The pairs a fast update leaves active or asleep, in key order: an
    /// old pair updated in place (its index in the pair array) or a new
    /// one (its index in `ContactSet::next`, tagged with [`NEW_PAIR`]), and
    /// whether it was a candidate (otherwise a retired pair kept asleep).
    pub(super) order: Vec<(u32, bool)>,
    /// Touching pairs in the whole array.
    pub(super) touching: u32,
    /// Contact points of the touching pairs in the whole array.
    pub(super) points: u32,
}

impl PartialEq for ActivePairs {
    /// Always equal: derived from the pairs and the bodies.
    fn eq(&self, _: &ActivePairs) -> bool {
        true
    }
}

impl Eq for ActivePairs {}

impl ContactSet {
    /// [`update`](Self::update) over the active pairs only: the same merge
    /// as [`update_all`](Self::update_all), restricted to them. Pairs that
    /// stay are updated in place; if pairs were created or dropped, one
    /// merge with the untouched resting pairs follows.
    pub(super) fn update_active(
        &mut self,
        candidates: impl Iterator<Item = Candidate>,
        narrow: &impl NarrowTest,
        mut keep_asleep: impl FnMut(&ContactPair) -> bool,
        workers: &Workers,
    ) -> ContactStats {
        let mut stats = ContactStats::default();
        let before = self.fast_update_capacities();
        self.next.clear();
        self.events.clear();
        self.active.order.clear();
        // The active pairs' counts leave the totals now (they are updated
        // in place below); what the update leaves comes back at the end.
        let (mut touching, mut points) = (self.active.touching, self.active.points);
        for &i in &self.active.index {
            let (t, n) = counts(&self.pairs[i as usize]);
            touching -= t;
            points -= n;
        }
        // Whether a pair was created or dropped (the array changes shape).
        let mut reshaped = false;
        let mut k = 0usize;
        let n_active = self.active.index.len();
        reserve_near(&mut self.scratch.tests, n_active);
        for c in candidates {
            stats.candidates += 1;
            let key = (c.a.index(), c.b.index());
            while k < n_active && self.pairs[self.active.index[k] as usize].key() < key {
                reshaped |= !self.retire_active(k, &mut keep_asleep, &mut stats);
                k += 1;
            }
            let old = self.active.index.get(k).map(|&i| i as usize);
            let at = match old.map(|i| &self.pairs[i]) {
                Some(p) if p.key() == key && p.a == c.a && p.b == c.b => {
                    k += 1;
                    let i = old.unwrap_or_default();
                    self.active.order.push((i as u32, true));
                    i as u32
                }
                found => {
                    if found.is_some_and(|p| p.key() == key) {
                        // Same slots, other generations: the old pair's
                        // colliders were removed.
                        let p = self.pairs[self.active.index[k] as usize];
                        if p.touching {
                            self.events.push(ContactEvent::end(&p));
                            stats.end_events += 1;
                        }
                        k += 1;
                    }
                    reshaped = true;
                    self.active
                        .order
                        .push((NEW_PAIR | self.next.len() as u32, true));
                    self.next.push(ContactPair::new(c.a, c.b, c.kind));
                    NEW_PAIR | (self.next.len() - 1) as u32
                }
            };
            self.list_test(at, c.kind);
        }
        while k < n_active {
            reshaped |= !self.retire_active(k, &mut keep_asleep, &mut stats);
            k += 1;
        }
        self.run_tests(narrow, workers, &mut stats);
        // The resting pairs outside the active list were kept as they are.
        stats.kept_asleep += (self.pairs.len() - n_active) as u32;
        let a = &mut self.active;
        let entry = |(j, _): (u32, bool)| -> &ContactPair {
            if j & NEW_PAIR != 0 {
                &self.next[(j & !NEW_PAIR) as usize]
            } else {
                &self.pairs[j as usize]
            }
        };
        // The tested pairs' counts come from their tests (in the same
        // order as the candidates' entries), so this walk reads the pairs
        // kept asleep alone.
        let mut tested = self.scratch.tests.iter();
        for &e in &a.order {
            let test = if e.1 { tested.next() } else { None };
            let (t, n) = match test {
                Some(test) => {
                    debug_assert_eq!(test.at, e.0);
                    test.counts()
                }
                None => counts(entry(e)),
            };
            touching += t;
            points += n;
        }
        a.touching = touching;
        a.points = points;
        stats.touching = touching;
        stats.points = points;
        a.next_index.clear();
        if !reshaped {
            // Same pairs in the same places, already updated.
            debug_assert!(a.order.iter().map(|e| e.0).eq(a.index.iter().copied()));
            for &(i, cand) in &a.order {
                if cand {
                    a.next_index.push(i);
                }
            }
        } else {
            // Determinism: a merge by (A, B) key of the untouched resting
            // pairs with the updated active ones; the keys are distinct (a
            // resting pair is never a candidate while nothing wakes). Done
            // in place, so the world keeps one pair array, not two.
            a.keys.clear();
            a.keys
                .extend(a.order.iter().map(|&e| (entry(e).key(), e.1)));
            // 1. Drop the active pairs the update dropped: every other pair
            //    (resting, updated in place or kept asleep) stays, in order.
            //    The old entries of `order` are ascending pair indices.
            let mut olds = a.order.iter().filter(|e| e.0 & NEW_PAIR == 0).peekable();
            let mut active = a.index.iter().copied().peekable();
            let mut kept = 0usize;
            for i in 0..self.pairs.len() {
                let keep = if active.peek() == Some(&(i as u32)) {
                    active.next();
                    let updated = olds.peek().is_some_and(|e| e.0 == i as u32);
                    if updated {
                        olds.next();
                    }
                    updated
                } else {
                    true
                };
                if keep {
                    self.pairs[kept] = self.pairs[i];
                    kept += 1;
                }
            }
            self.pairs.truncate(kept);
            // 2. Merge the new pairs (in key order in `next`) in from the
            //    back.
            reserve_near(&mut self.pairs, kept + self.next.len());
            self.pairs.extend_from_slice(&self.next);
            let (mut i, mut j) = (kept, self.next.len());
            while j > 0 {
                let to = i + j - 1;
                if i > 0 && self.pairs[i - 1].key() > self.next[j - 1].key() {
                    self.pairs[to] = self.pairs[i - 1];
                    i -= 1;
                } else {
                    self.pairs[to] = self.next[j - 1];
                    j -= 1;
                }
            }
            // 3. The new active list: where the candidates landed (the
            //    entries of `order` are a subsequence of the array by key).
            let mut want = a.keys.iter().peekable();
            for (i, p) in self.pairs.iter().enumerate() {
                if let Some(&&(key, cand)) = want.peek()
                    && p.key() == key
                {
                    if cand {
                        a.next_index.push(i as u32);
                    }
                    want.next();
                }
            }
            debug_assert!(want.peek().is_none());
        }
        std::mem::swap(&mut a.index, &mut a.next_index);
        if self.fast_update_capacities().grew_since(&before) {
            stats.growths += 1;
        }
        stats
    }

    /// An active pair (the `k`-th) that is no longer a candidate, in a fast
    /// update: kept in place if asleep, else dropped with an end event if
    /// it was touching; returns whether it was kept.
    pub(super) fn retire_active(
        &mut self,
        k: usize,
        keep_asleep: &mut impl FnMut(&ContactPair) -> bool,
        stats: &mut ContactStats,
    ) -> bool {
        let i = self.active.index[k] as usize;
        let p = &self.pairs[i];
        if keep_asleep(p) {
            self.active.order.push((i as u32, false));
            stats.kept_asleep += 1;
            true
        } else {
            if p.touching {
                self.events.push(ContactEvent::end(p));
                stats.end_events += 1;
            }
            false
        }
    }

    /// Forgets the active list: the next update walks every pair. Called
    /// when a resting pair may have become active (a body woke).
    pub(crate) fn invalidate_active(&mut self) {
        self.active.valid = false;
    }

    /// The active pairs' indices (ascending), if the list is valid: a
    /// superset of the pairs with an awake or kinematic body.
    pub(crate) fn active(&self) -> Option<&[u32]> {
        self.active.valid.then_some(&self.active.index[..])
    }

    /// Rebuilds the active list from one walk over the pairs: `is_active`
    /// says whether a pair may involve an awake or kinematic body (answer
    /// true when unsure). Returns whether a buffer grew.
    pub(crate) fn rebuild_active(
        &mut self,
        mut is_active: impl FnMut(&ContactPair) -> bool,
    ) -> bool {
        let before = Capacities::of([&self.active.index]);
        self.active.index.clear();
        let (mut touching, mut points) = (0, 0);
        for (i, p) in self.pairs.iter().enumerate() {
            if is_active(p) {
                self.active.index.push(i as u32);
            }
            let (t, n) = counts(p);
            touching += t;
            points += n;
        }
        self.active.touching = touching;
        self.active.points = points;
        self.active.valid = true;
        Capacities::of([&self.active.index]).grew_since(&before)
    }

    /// The buffers [`update_active`](Self::update_active) fills; buffers
    /// that trade contents count by their summed capacity.
    fn fast_update_capacities(&self) -> Capacities<6> {
        Capacities::of([
            &self.next,
            &(&self.events, &self.scratch.merged),
            &self.active.order,
            &(&self.active.index, &self.active.next_index),
            &self.pairs,
            &self.active.keys,
        ])
    }
}
