//! Contact pairs: their lifetime, persistent manifolds and events.
//!
//! Each step the broad phase hands over the sorted candidate pairs; this
//! module merges them with last step's pairs (both sorted by collider
//! handle, so a single linear walk), runs the narrow phase on each, carries
//! each contact point's accumulated impulses over from the previous step's
//! point with the same [`FeatureId`] (warm starting for the solver), and
//! emits begin/end events when a pair starts or stops touching (enter/exit
//! for trigger pairs, which never keep contact points).
//!
//! Pairs whose two bodies sleep (or one sleeps and the other is static) are
//! not candidates, but they are kept unchanged, so a sleeping pile keeps its
//! contacts and emits no events.
//!
//! Sleeping pairs cost nothing per step: the set keeps the (derived,
//! unserialized) list of *active* pairs, a superset of the pairs with an
//! awake or kinematic body, and while it is valid an update only walks the
//! active pairs and the candidates; the sleeping pairs stay where they are
//! in the pair array. Anything that may turn a sleeping pair active (a body
//! waking, a collider removed, a restore) invalidates the list, and the next
//! update walks all pairs once, as it always did, and rebuilds it.
//!
//! Determinism: pairs, and therefore events, are in ascending order of
//! (collider A, collider B) handles, whatever the trees' shape.
//!
//! Threads: an update is three passes. The merge walks the candidates and
//! the old pairs in key order on the calling thread and lists the pairs to
//! test; the narrow phase then runs on the listed pairs in blocks over the
//! world's workers (each test reads the two colliders' poses and writes its
//! own pair alone, so its result does not depend on who runs it); last, one
//! walk in key order on the calling thread counts the tests and puts each
//! pair's begin/end event in its place among the end events of the retired
//! pairs. The pairs, events and counters are the same for any worker count.

use serde::{Deserialize, Serialize};

use crate::handles::ColliderHandle;
use crate::math::Scalar;
use crate::scratch::Capacities;
use crate::workers::{SharedMut, Workers};

use super::manifold::{ContactPoint, MAX_MANIFOLD_POINTS, Manifold};
use super::reuse::ReuseCache;

mod active;
use active::ActivePairs;

/// How far a contact point may move between steps and still inherit an old
/// point's impulses when its feature id changed, m.
pub const MATCH_DISTANCE: Scalar = Scalar::from_bits(1 << 26); // 1/64 m

/// How close counts as touching for solid pairs, m (2⁻¹⁰ ≈ 1 mm). The
/// solver stops speculative contacts at zero gap, give or take rounding, so
/// a strict `depth ≥ 0` could miss a collision entirely; a millimetre is far
/// below anything a player sees and far above rounding. Trigger pairs use
/// actual overlap (depth ≥ 0): nothing resolves them.
pub const TOUCH_TOLERANCE: Scalar = Scalar::from_bits(1 << 22);

/// What the solver accumulated on one contact point, carried to the same
/// point (same feature id) next step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PointImpulse {
    /// Accumulated normal impulse, N·s, over one substep (the solver
    /// applies it again at the start of every substep: warm starting).
    pub normal: Scalar,
}

/// The friction the solver accumulated on a whole manifold (friction acts
/// at the centre of the contact patch, not per point: see
/// `solver::contact_solver`), carried to the same pair next step while it
/// keeps any contact point.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PatchFriction {
    /// Accumulated friction impulses along the two tangent directions of
    /// the normal, N·s per substep.
    pub tangent: [Scalar; 2],
    /// Accumulated twist impulse about the normal (resisting spin of one
    /// shape on the other), N·m·s per substep.
    pub twist: Scalar,
}

/// Whether a pair makes contacts or only reports overlap.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum PairKind {
    /// Two solid colliders: contact points for the solver.
    Solid,
    /// At least one trigger: overlap events, no contact points.
    Trigger,
}

/// A pair of colliders whose fat bounding boxes overlap, with its contact
/// state. `a` has the lower handle index.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ContactPair {
    /// The first collider (lower handle).
    pub a: ColliderHandle,
    /// The second collider.
    pub b: ColliderHandle,
    /// Solid or trigger.
    pub kind: PairKind,
    /// Whether the shapes touch: some point within [`TOUCH_TOLERANCE`] of
    /// contact (depth ≥ −1 mm); for triggers, whether they overlap.
    pub touching: bool,
    /// The contact manifold, normal from A to B (always empty for triggers).
    pub manifold: Manifold,
    /// Accumulated normal impulses, one per manifold point.
    pub impulses: [PointImpulse; MAX_MANIFOLD_POINTS],
    /// Accumulated friction of the whole manifold.
    pub friction: PatchFriction,
    /// What the last full narrow-phase test left for reuse (see
    /// `docs/determinism.md`, contact reuse); never valid for triggers, nor for a pair with a
    /// sphere or capsule.
    pub reuse: ReuseCache,
}

impl ContactPair {
    /// A fresh pair with no contact yet.
    pub fn new(a: ColliderHandle, b: ColliderHandle, kind: PairKind) -> ContactPair {
        ContactPair {
            a,
            b,
            kind,
            touching: false,
            manifold: Manifold::EMPTY,
            impulses: [PointImpulse::default(); MAX_MANIFOLD_POINTS],
            friction: PatchFriction::default(),
            reuse: ReuseCache::EMPTY,
        }
    }

    /// The order pairs are kept in.
    pub fn key(&self) -> (u32, u32) {
        (self.a.index(), self.b.index())
    }

    /// Installs this step's manifold, carrying each point's impulses over
    /// from last step's point with the same feature id, or else from the
    /// nearest unclaimed old point within [`MATCH_DISTANCE`] (new points
    /// start at zero). The patch friction is kept while the manifold has
    /// points and dropped when it empties.
    pub fn update_manifold(&mut self, new: &Manifold) {
        let mut impulses = [PointImpulse::default(); MAX_MANIFOLD_POINTS];
        let old = self.manifold.points();
        let mut used = [false; MAX_MANIFOLD_POINTS];
        let mut matched = [false; MAX_MANIFOLD_POINTS];
        for (i, p) in new.points().iter().enumerate() {
            if let Some(j) = old.iter().position(|q| q.id == p.id)
                && !used[j]
            {
                impulses[i] = self.impulses[j];
                used[j] = true;
                matched[i] = true;
            }
        }
        // A point whose features changed (a box pair that swapped its
        // reference face as it tilted a hair) keeps the impulse of the
        // nearest unclaimed old point within MATCH_DISTANCE: losing the warm
        // start there rocks tall stacks.
        let limit = MATCH_DISTANCE.wide_mul(MATCH_DISTANCE) as u128;
        for (i, p) in new.points().iter().enumerate() {
            if matched[i] {
                continue;
            }
            let mut best: Option<(usize, u128)> = None;
            for (j, q) in old.iter().enumerate() {
                let d = (p.point - q.point).length_squared_wide();
                if !used[j] && d <= limit && best.is_none_or(|(_, b)| d < b) {
                    best = Some((j, d));
                }
            }
            if let Some((j, _)) = best {
                impulses[i] = self.impulses[j];
                used[j] = true;
            }
        }
        self.manifold = *new;
        self.impulses = impulses;
        if new.is_empty() {
            self.friction = PatchFriction::default();
        }
        self.touching = new.points().iter().any(|p| p.depth >= -TOUCH_TOLERANCE);
    }
}

/// Which way a pair's touching state changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ContactEventKind {
    /// Two solid colliders started touching.
    BeginTouch,
    /// Two solid colliders stopped touching (or one was removed).
    EndTouch,
    /// A collider entered a trigger.
    TriggerEnter,
    /// A collider left a trigger (or one was removed).
    TriggerExit,
}

/// A change in a pair's touching state during the last step.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ContactEvent {
    /// What happened.
    pub kind: ContactEventKind,
    /// The first collider (lower handle; may be stale on an end event if it
    /// was removed).
    pub a: ColliderHandle,
    /// The second collider.
    pub b: ColliderHandle,
}

impl ContactEvent {
    fn begin(p: &ContactPair) -> ContactEvent {
        let kind = match p.kind {
            PairKind::Solid => ContactEventKind::BeginTouch,
            PairKind::Trigger => ContactEventKind::TriggerEnter,
        };
        ContactEvent {
            kind,
            a: p.a,
            b: p.b,
        }
    }

    fn end(p: &ContactPair) -> ContactEvent {
        let kind = match p.kind {
            PairKind::Solid => ContactEventKind::EndTouch,
            PairKind::Trigger => ContactEventKind::TriggerExit,
        };
        ContactEvent {
            kind,
            a: p.a,
            b: p.b,
        }
    }
}

/// Counters from one contact update.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ContactStats {
    /// Candidate pairs from the broad phase.
    pub candidates: u32,
    /// Narrow-phase calls (full tests and reuses).
    pub narrow_tests: u32,
    /// Of those, the pairs that reused their manifold's features instead
    /// of running the full test.
    pub reused: u32,
    /// Pairs touching after the update.
    pub touching: u32,
    /// Contact points in all manifolds.
    pub points: u32,
    /// Pairs of sleeping bodies kept without a test.
    pub kept_asleep: u32,
    /// Begin/enter events.
    pub begin_events: u32,
    /// End/exit events.
    pub end_events: u32,
    /// Times a buffer had to grow (allocation inside the step).
    pub growths: u32,
}

/// The world's contact pairs and the events of the last step.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ContactSet {
    pairs: Vec<ContactPair>,
    #[serde(skip)]
    next: Vec<ContactPair>,
    events: Vec<ContactEvent>,
    /// Derived: which pairs an update must visit (see the module docs).
    #[serde(skip)]
    active: ActivePairs,
    /// Scratch of the current update.
    #[serde(skip)]
    scratch: UpdateScratch,
}

/// Buffers an update reuses (no state: always equal).
#[derive(Clone, Debug, Default)]
struct UpdateScratch {
    /// The pairs the update tests (see the module docs).
    tests: Vec<Test>,
    /// The events being put in order.
    merged: Vec<ContactEvent>,
}

impl PartialEq for UpdateScratch {
    fn eq(&self, _: &UpdateScratch) -> bool {
        true
    }
}

impl Eq for UpdateScratch {}

/// A pair the current update tests: where it is, how many events came
/// before it in key order, and what the test did ([`Test::REUSED`],
/// [`Test::BEGIN`], [`Test::END`]).
#[derive(Clone, Copy, Debug)]
struct Test {
    /// Its index in the pair array, or in `ContactSet::next` tagged with
    /// [`NEW_PAIR`].
    at: u32,
    /// Events before this pair's own.
    events_before: u32,
    /// The candidate's kind, given to the pair as it is tested (on a
    /// worker, so the merge reads an old pair and never writes it).
    kind: PairKind,
    /// What the test did.
    outcome: u8,
    /// The pair's contact points after the test, if it touches (what
    /// [`counts`] gives for it).
    points: u8,
}

impl Test {
    /// The manifold was rebuilt from the reuse cache.
    const REUSED: u8 = 1;
    /// The pair started touching.
    const BEGIN: u8 = 2;
    /// The pair stopped touching.
    const END: u8 = 4;
    /// The pair touches after the test.
    const TOUCHING: u8 = 8;

    /// What the pair adds to the touching and point counters.
    fn counts(&self) -> (u32, u32) {
        (
            u32::from(self.outcome & Test::TOUCHING != 0),
            u32::from(self.points),
        )
    }
}

/// The narrow-phase function [`ContactSet::update`] calls (see there).
pub(crate) trait NarrowTest:
    Fn(
        ColliderHandle,
        ColliderHandle,
        Option<(&mut Manifold, &mut ReuseCache)>,
        &mut Manifold,
    ) -> bool
    + Sync
{
}

impl<F> NarrowTest for F where
    F: Fn(
            ColliderHandle,
            ColliderHandle,
            Option<(&mut Manifold, &mut ReuseCache)>,
            &mut Manifold,
        ) -> bool
        + Sync
{
}

/// Makes `v` hold at least `want` items, growing it once to `want` and an
/// eighth more rather than by doubling: a contact pair is over half a
/// kilobyte, and a pair array left to double holds up to twice what the
/// scene needs (three times while it moves). Only capacity: no change in
/// results.
pub(crate) fn reserve_near<T>(v: &mut Vec<T>, want: usize) {
    if want > v.capacity() {
        v.reserve_exact(want + want / 8 - v.len());
    }
}

/// Tag of an entry of [`ActivePairs::order`] that indexes the new pairs.
const NEW_PAIR: u32 = 1 << 31;

/// What a pair adds to the touching and point counters.
fn counts(p: &ContactPair) -> (u32, u32) {
    if p.touching {
        (1, p.manifold.count as u32)
    } else {
        (0, 0)
    }
}

/// What the caller knows about one candidate pair.
pub struct Candidate {
    /// The lower collider handle.
    pub a: ColliderHandle,
    /// The higher collider handle.
    pub b: ColliderHandle,
    /// Solid or trigger.
    pub kind: PairKind,
}

impl ContactSet {
    /// The current pairs, ascending by (A, B) handle index.
    pub fn pairs(&self) -> &[ContactPair] {
        &self.pairs
    }

    /// The current pairs, mutably (the solver writes the impulses back).
    pub(crate) fn pairs_mut(&mut self) -> &mut [ContactPair] {
        &mut self.pairs
    }

    /// The events of the last update, in pair order.
    pub fn events(&self) -> &[ContactEvent] {
        &self.events
    }

    /// Merges the sorted `candidates` with the current pairs.
    ///
    /// - `narrow(a, b, reuse, manifold)` fills the manifold of a candidate
    ///   (called once per candidate, on any of the `workers`, in any
    ///   order: it must read nothing another call writes). For a solid pair
    ///   `reuse` holds the pair's current manifold and its reuse cache: the
    ///   closure may rebuild the manifold from the cache (returning true) or
    ///   run the full test and record the cache anew, or empty it for a
    ///   pair that never reuses (returning false);
    /// - `keep_asleep(pair)` says whether a pair that is no longer a
    ///   candidate rests between sleeping (or sleeping and static) bodies and
    ///   must be kept as it is.
    ///
    /// Every pair that is not a candidate afterwards rests between sleeping
    /// (or sleeping and static) bodies; the candidates become the active
    /// pairs. With a valid active list only the active pairs and the
    /// candidates are visited (the other pairs rested at the last update and
    /// nothing woke since, so they are neither candidates nor changed), and
    /// the result is the same pair array, events and counters as a walk over
    /// all pairs.
    ///
    /// Determinism: must be given candidates sorted by (A, B) handle index.
    pub(crate) fn update(
        &mut self,
        candidates: impl Iterator<Item = Candidate>,
        narrow: impl NarrowTest,
        keep_asleep: impl FnMut(&ContactPair) -> bool,
        workers: &Workers,
    ) -> ContactStats {
        let caps = self.scratch.tests.capacity();
        self.scratch.tests.clear();
        let mut stats = if self.active.valid {
            self.update_active(candidates, &narrow, keep_asleep, workers)
        } else {
            self.update_all(candidates, &narrow, keep_asleep, workers)
        };
        if self.scratch.tests.capacity() != caps {
            stats.growths += 1;
        }
        stats
    }

    /// Lists a pair to test (its kind set to the candidate's); `at` as in
    /// [`Test::at`].
    fn list_test(&mut self, at: u32, kind: PairKind) {
        self.scratch.tests.push(Test {
            at,
            events_before: self.events.len() as u32,
            kind,
            outcome: 0,
            points: 0,
        });
    }

    /// The narrow phase on every listed pair, in blocks over the workers,
    /// then the tests' counters and events in key order (see the module
    /// docs).
    fn run_tests(&mut self, narrow: &impl NarrowTest, workers: &Workers, stats: &mut ContactStats) {
        const BLOCK: usize = 8;
        let len = self.scratch.tests.len();
        {
            let tests = SharedMut::new(&mut self.scratch.tests);
            let pairs = SharedMut::new(&mut self.pairs);
            let next = SharedMut::new(&mut self.next);
            workers.for_each_block(len, BLOCK, |r| {
                let mut scratch = Manifold::EMPTY;
                // SAFETY: each block goes to one worker alone, and each
                // listed pair is listed once.
                for t in unsafe { tests.slice(r) } {
                    let pair = unsafe {
                        if t.at & NEW_PAIR != 0 {
                            next.get((t.at & !NEW_PAIR) as usize)
                        } else {
                            pairs.get(t.at as usize)
                        }
                    };
                    pair.kind = t.kind;
                    t.outcome = Self::test_pair(pair, narrow, &mut scratch);
                    let (touching, points) = counts(pair);
                    if touching != 0 {
                        t.outcome |= Test::TOUCHING;
                    }
                    t.points = points as u8;
                }
            });
        }
        stats.narrow_tests += len as u32;
        self.scratch.merged.clear();
        reserve_near(&mut self.scratch.merged, self.events.len() + len);
        let mut retired = 0;
        for t in &self.scratch.tests {
            stats.reused += u32::from(t.outcome & Test::REUSED != 0);
            if t.outcome & (Test::BEGIN | Test::END) == 0 {
                continue;
            }
            let upto = t.events_before as usize;
            self.scratch
                .merged
                .extend_from_slice(&self.events[retired..upto]);
            retired = upto;
            let pair = if t.at & NEW_PAIR != 0 {
                &self.next[(t.at & !NEW_PAIR) as usize]
            } else {
                &self.pairs[t.at as usize]
            };
            if t.outcome & Test::BEGIN != 0 {
                self.scratch.merged.push(ContactEvent::begin(pair));
                stats.begin_events += 1;
            } else {
                self.scratch.merged.push(ContactEvent::end(pair));
                stats.end_events += 1;
            }
        }
        self.scratch
            .merged
            .extend_from_slice(&self.events[retired..]);
        std::mem::swap(&mut self.events, &mut self.scratch.merged);
    }

    /// [`update`](Self::update) walking every pair; rebuilds the active
    /// list.
    fn update_all(
        &mut self,
        candidates: impl Iterator<Item = Candidate>,
        narrow: &impl NarrowTest,
        mut keep_asleep: impl FnMut(&ContactPair) -> bool,
        workers: &Workers,
    ) -> ContactStats {
        let mut stats = ContactStats::default();
        let before = self.full_update_capacities();
        self.active.index.clear();
        self.next.clear();
        self.events.clear();
        // Every candidate makes one pair, and retired pairs may stay asleep.
        let bound = candidates.size_hint().0.max(self.pairs.len());
        reserve_near(&mut self.next, bound);
        reserve_near(&mut self.active.index, bound);
        reserve_near(&mut self.scratch.tests, bound);
        let mut old = 0usize;
        for c in candidates {
            stats.candidates += 1;
            let key = (c.a.index(), c.b.index());
            // Old pairs before this candidate are gone (or asleep).
            while old < self.pairs.len() && self.pairs[old].key() < key {
                self.retire(old, &mut keep_asleep, &mut stats);
                old += 1;
            }
            let pair = if old < self.pairs.len()
                && self.pairs[old].key() == key
                && self.pairs[old].a == c.a
                && self.pairs[old].b == c.b
            {
                old += 1;
                self.pairs[old - 1]
            } else {
                if old < self.pairs.len() && self.pairs[old].key() == key {
                    // Same slots, other generations: the old pair's
                    // colliders were removed.
                    self.retire(old, &mut |_| false, &mut stats);
                    old += 1;
                }
                ContactPair::new(c.a, c.b, c.kind)
            };
            self.active.index.push(self.next.len() as u32);
            // The test gives the pair the candidate's kind.
            self.list_test(NEW_PAIR | self.next.len() as u32, c.kind);
            self.next.push(pair);
        }
        while old < self.pairs.len() {
            self.retire(old, &mut keep_asleep, &mut stats);
            old += 1;
        }
        self.run_tests(narrow, workers, &mut stats);
        std::mem::swap(&mut self.pairs, &mut self.next);
        self.active.touching = 0;
        self.active.points = 0;
        for p in &self.pairs {
            let (t, n) = counts(p);
            self.active.touching += t;
            self.active.points += n;
        }
        stats.touching = self.active.touching;
        stats.points = self.active.points;
        self.active.valid = true;
        if self.full_update_capacities().grew_since(&before) {
            stats.growths += 1;
        }
        stats
    }

    /// The buffers [`update_all`](Self::update_all) fills (the events trade
    /// contents with the merge buffer).
    fn full_update_capacities(&self) -> Capacities<3> {
        Capacities::of([
            &self.next,
            &(&self.events, &self.scratch.merged),
            &self.active.index,
        ])
    }

    /// Runs the narrow phase on one listed pair and installs its manifold.
    /// A reused manifold is rebuilt in place: its features, and so its
    /// impulses, are the ones it had. Returns the [`Test`] outcome bits.
    fn test_pair(pair: &mut ContactPair, narrow: &impl NarrowTest, scratch: &mut Manifold) -> u8 {
        let was_touching = pair.touching;
        let mut outcome = 0;
        scratch.clear();
        match pair.kind {
            PairKind::Trigger => {
                narrow(pair.a, pair.b, None, scratch);
                pair.reuse = ReuseCache::EMPTY;
                pair.touching = scratch.points().iter().any(|p| !p.depth.is_negative());
                pair.manifold = Manifold::EMPTY;
            }
            PairKind::Solid => {
                if narrow(
                    pair.a,
                    pair.b,
                    Some((&mut pair.manifold, &mut pair.reuse)),
                    scratch,
                ) {
                    outcome |= Test::REUSED;
                    pair.touching = pair
                        .manifold
                        .points()
                        .iter()
                        .any(|p| p.depth >= -TOUCH_TOLERANCE);
                } else {
                    pair.update_manifold(scratch);
                }
            }
        }
        if pair.touching != was_touching {
            outcome |= if pair.touching {
                Test::BEGIN
            } else {
                Test::END
            };
        }
        outcome
    }

    /// An old pair that is no longer a candidate: kept if asleep, otherwise
    /// dropped with an end event if it was touching.
    fn retire(
        &mut self,
        i: usize,
        keep_asleep: &mut impl FnMut(&ContactPair) -> bool,
        stats: &mut ContactStats,
    ) {
        let p = self.pairs[i];
        if keep_asleep(&p) {
            self.next.push(p);
            stats.kept_asleep += 1;
        } else if p.touching {
            self.events.push(ContactEvent::end(&p));
            stats.end_events += 1;
        }
    }

    /// Drops every pair that involves `c` because its collider was removed;
    /// a touching pair's end event is appended to the current event list
    /// (removals happen between steps).
    pub fn remove_collider(&mut self, c: ColliderHandle) {
        self.active.valid = false;
        let events = &mut self.events;
        self.pairs.retain(|p| {
            let involved = p.a == c || p.b == c;
            if involved && p.touching {
                events.push(ContactEvent::end(p));
            }
            !involved
        });
    }

    /// Feeds every pair's persistent state into the world's state hash (the
    /// word order is in `docs/determinism.md`). Pairs that carry nothing (no
    /// points, not touching, so no impulses) are left out: whether the broad
    /// phase lists such a pair depends on the history of its fat boxes, which
    /// does not influence any later step.
    pub(crate) fn hash_into(&self, h: &mut crate::hash::StateHasher) {
        let carries = |p: &&ContactPair| p.touching || p.manifold.count != 0;
        h.word(self.pairs.iter().filter(carries).count() as u64);
        for p in self.pairs.iter().filter(carries) {
            h.word(p.a.0.index as u64);
            h.word(p.a.0.generation as u64);
            h.word(p.b.0.index as u64);
            h.word(p.b.0.generation as u64);
            h.word(match p.kind {
                PairKind::Solid => 0,
                PairKind::Trigger => 1,
            });
            h.word(p.touching as u64);
            h.vec3(p.manifold.normal);
            h.word(p.manifold.count as u64);
            for (pt, imp) in p.manifold.points().iter().zip(&p.impulses) {
                hash_point(h, pt);
                h.scalar(imp.normal);
            }
            h.scalar(p.friction.tangent[0]);
            h.scalar(p.friction.tangent[1]);
            h.scalar(p.friction.twist);
            p.reuse.hash_into(h, p.manifold.points().len());
        }
    }
}

impl ContactSet {
    /// Feeds `field` the state of every pair that the world hash carries and
    /// that involves one of `colliders` (a body's colliders), in pair order:
    /// for a body's field dump. Each pair gives its state words, normal,
    /// points, impulses and a hash of its reuse cache, named after its two
    /// colliders.
    pub(crate) fn visit_pairs_of(
        &self,
        colliders: &[ColliderHandle],
        field: &mut impl FnMut(String, crate::hash::FieldKind, &[u64]),
    ) {
        use crate::hash::FieldKind::{Scalar as Q, Word};
        let s = |v: Scalar| v.to_bits() as u64;
        for p in &self.pairs {
            let carries = p.touching || p.manifold.count != 0;
            if !carries || !colliders.iter().any(|&c| c == p.a || c == p.b) {
                continue;
            }
            let name = |what: &str| {
                format!(
                    "contact c{}:{}-c{}:{} {what}",
                    p.a.0.index, p.a.0.generation, p.b.0.index, p.b.0.generation
                )
            };
            let points = p.manifold.points();
            let kind = match p.kind {
                PairKind::Solid => 0,
                PairKind::Trigger => 1,
            };
            let mut state = vec![kind, p.touching as u64, p.manifold.count as u64];
            state.extend(points.iter().map(|pt| pt.id.0 as u64));
            field(name("kind, touching, count, point ids"), Word, &state);
            let n = p.manifold.normal;
            field(name("normal"), Q, &[s(n.x), s(n.y), s(n.z)]);
            let mut geometry = Vec::with_capacity(points.len() * 4);
            for pt in points {
                geometry.extend([s(pt.point.x), s(pt.point.y), s(pt.point.z), s(pt.depth)]);
            }
            field(name("points (x, y, z, depth)"), Q, &geometry);
            let mut impulses: Vec<u64> = p.impulses[..points.len()]
                .iter()
                .map(|i| s(i.normal))
                .collect();
            impulses.extend([
                s(p.friction.tangent[0]),
                s(p.friction.tangent[1]),
                s(p.friction.twist),
            ]);
            field(
                name("impulses (normal per point, tangent 1, tangent 2, twist)"),
                Q,
                &impulses,
            );
            let mut h = crate::hash::StateHasher::new();
            p.reuse.hash_into(&mut h, points.len());
            field(name("reuse cache hash"), Word, &[h.finish()]);
        }
    }
}

fn hash_point(h: &mut crate::hash::StateHasher, p: &ContactPoint) {
    h.vec3(p.point);
    h.scalar(p.depth);
    h.word(p.id.0 as u64);
}

#[cfg(test)]
mod tests;
