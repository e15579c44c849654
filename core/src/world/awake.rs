//! The awake set: the one place where a body falls asleep or wakes, and
//! where the lists that follow those states are kept current.
//!
//! Two lists follow the bodies' sleep states, each stored beside the data
//! it indexes: the body set's awake index (the slots the per-body stages
//! walk; `body/awake.rs`) and the contact set's active pairs (the pairs the
//! narrow phase, the solver's set-up and the sleep stage walk; see
//! `collision::contacts`). This module is their only writer: no other part
//! of the world changes a sleep flag, refreshes the awake index or drops or
//! rebuilds the active pairs (a test below holds the rest of the crate to
//! it). What it offers:
//!
//! - [`World::wake`] (one body; any call that moves, pushes or changes a
//!   body goes through it) and [`World::put_to_sleep`];
//! - [`World::wake_touching`]: the sleepers resting on a body or collider
//!   that is about to move or vanish;
//! - the step's three stages of waking and sleeping: `awake_list` (the
//!   index catches up with the game's calls), `wake_touched` (sleepers
//!   touched by a moving body wake, with their islands and the bodies
//!   joined to them) and `sleep` (rested islands fall asleep);
//! - [`World::refresh_awake_set`] for a new or restored world, whose index
//!   is rebuilt before the world is handed out.
//!
//! The invariants: the awake index lists exactly the live bodies that move
//! (awake dynamic and kinematic), in slot order, whenever a stage reads it;
//! the active pairs, when valid, hold every pair with a moving body; the
//! sleeping count is exact at any time. Debug builds check the first two
//! after the stages that change them.

use crate::body::{BodyHandle, BodyKind, BodySet};
use crate::collider::ColliderHandle;
use crate::collision::ContactSet;
use crate::collision::contacts::PairKind;
use crate::math::Vec3;
use crate::solver::sleep;

use super::state::World;

impl World {
    /// Wakes a live body (see the free function [`wake`]).
    pub(super) fn wake(&mut self, h: BodyHandle) {
        wake(&mut self.bodies, &mut self.contacts, h);
    }

    /// Puts a dynamic body to sleep now, its velocities zeroed (other
    /// kinds never sleep).
    pub(super) fn put_to_sleep(&mut self, h: BodyHandle) {
        let Some(hot) = self.bodies.hot_mut(h) else {
            return;
        };
        if hot.kind == BodyKind::Dynamic {
            hot.linear_velocity = Vec3::ZERO;
            hot.angular_velocity = Vec3::ZERO;
            hot.angular_momentum = Vec3::ZERO;
            self.bodies.set_sleeping(h, true);
        }
    }

    /// Wakes the sleeping dynamic bodies in solid contact (any manifold
    /// point) with `toucher`, because what they rest on is about to move or
    /// vanish: one pass over the pairs. The next step's `wake_touched`
    /// passes the wake on to the rest of their islands.
    pub(super) fn wake_touching(&mut self, toucher: Toucher) {
        let body_of = |c: ColliderHandle| self.colliders.get(c.0).map(|o| o.body);
        let mut i = 0;
        while let Some(p) = self.contacts.pairs().get(i) {
            i += 1;
            if p.kind != PairKind::Solid || p.manifold.is_empty() {
                continue;
            }
            let is_toucher = |c: ColliderHandle| match toucher {
                Toucher::Collider(t) => c == t,
                Toucher::Body(b) => body_of(c) == Some(b),
            };
            let other = if is_toucher(p.a) {
                p.b
            } else if is_toucher(p.b) {
                p.a
            } else {
                continue;
            };
            let Some(body) = body_of(other) else { continue };
            if self.bodies.hot(body).is_some_and(|b| b.sleeping) {
                wake(&mut self.bodies, &mut self.contacts, body);
            }
        }
    }

    /// Rebuilds the awake index from one scan of the bodies (a new or
    /// restored world: [`BodySet::sleeping_count`] is exact from the start).
    pub(super) fn refresh_awake_set(&mut self) {
        self.bodies.refresh_awake();
    }

    /// The per-body stages walk the awake slots only: sleeping and static
    /// bodies cost nothing (see `body/awake.rs`). Growths of the awake
    /// bookkeeping between steps (the game's calls) are not the step's.
    #[inline(never)]
    pub(super) fn stage_awake_list(&mut self) {
        self.bodies.take_awake_growths();
        self.bodies.refresh_awake();
    }

    /// Rest counters advance; islands of touching awake bodies that all
    /// rested long enough fall asleep together (and leave the awake list).
    #[inline(never)]
    pub(super) fn stage_sleep(&mut self) -> sleep::SleepStats {
        let World {
            bodies,
            colliders,
            contacts,
            islands,
            config,
            joints,
            ..
        } = self;
        // Only pairs with an awake body can join islands or stop a body
        // resting: the active pairs hold all of them.
        let pairs = contacts.pairs();
        let all = 0..pairs.len() as u32;
        let indices: &mut dyn Iterator<Item = u32> = match contacts.active() {
            Some(active) => &mut active.iter().copied(),
            None => &mut all.into_iter(),
        };
        let links = indices
            .map(|i| &pairs[i as usize])
            .filter(|p| p.touching && p.kind == PairKind::Solid)
            .filter_map(|p| {
                let a = colliders.get(p.a.0)?.body.0.index;
                let b = colliders.get(p.b.0)?.body.0.index;
                Some(sleep::Link { a, b })
            });
        // Joined bodies share an island: they sleep and wake together.
        let joined = joints.arena.iter().map(|(_, j)| sleep::Link {
            a: j.desc.body_a.index(),
            b: j.desc.body_b.index(),
        });
        let links = links.chain(joined);
        let (hot, awake) = bodies.awake_slots_mut();
        let slept =
            sleep::update_sleep(hot, awake, links, &config.sleep, config.tick_rate, islands);
        if slept.fell_asleep > 0 {
            // The awake index does not change until the refresh below, so
            // its k-th slot stays put while bodies fall asleep. Slot order,
            // as the sleep stage decided.
            for k in 0..self.bodies.awake_len() {
                let Some((h, hot)) = self.bodies.awake_at(k) else {
                    continue;
                };
                if hot.kind == BodyKind::Dynamic && !hot.sleeping && self.islands.rested(h.index())
                {
                    self.put_to_sleep(h);
                }
            }
            self.bodies.refresh_awake();
        }
        slept
    }

    /// Wakes sleeping dynamic bodies that a moving body touches or is about
    /// to touch (any contact point, speculative ones included): an awake
    /// dynamic body that was not resting at the last sleep update, or a
    /// kinematic body with a velocity. A woken body counts as moving, so a
    /// whole resting pile wakes when something hits it (as an island would);
    /// a body that merely rests against a sleeper does not wake it, so two
    /// resting bodies cannot keep waking each other. Returns how many woke.
    /// Each pass wakes at least one body or ends the loop, so it runs at
    /// most (sleeping bodies + 1) passes. The awake list then includes the
    /// woken.
    ///
    /// Determinism: pairs in handle order; each decision reads the state as
    /// left by the pairs before it.
    #[inline(never)]
    pub(super) fn stage_wake_touched(&mut self) -> u32 {
        // Repeat until a pass wakes nothing, so a woken body passes the wake
        // on through pairs that come before it in handle order: the whole
        // touching set wakes this step, whatever the handle order. The set
        // of bodies woken is the closure of "touched by a moving body", so
        // it does not depend on the order of the pairs or the passes: the
        // first pass walks only the active pairs (every pair with a moving
        // body is among them), the next ones every pair (a woken sleeper's
        // resting pairs are not active).
        // Nothing asleep, nothing to wake: the passes would find no sleeper
        // (the count is exact at any time, see `BodySet::sleeping_count`).
        if self.bodies.sleeping_count() == 0 {
            return 0;
        }
        let mut total = 0;
        let mut all = false;
        loop {
            let woken = self.wake_pass(all) + self.wake_joined();
            total += woken;
            if woken == 0 {
                break;
            }
            all = true;
        }
        if all {
            // Sleepers woke: their resting pairs may be active now.
            self.rebuild_active_pairs();
        }
        if total > 0 {
            self.bodies.refresh_awake();
        }
        total
    }

    /// Rebuilds the contact set's active list from the bodies' states (one
    /// walk over all pairs): a pair is active unless both bodies are
    /// sleeping or static. Returns whether a buffer grew.
    fn rebuild_active_pairs(&mut self) -> bool {
        let World {
            bodies,
            colliders,
            contacts,
            ..
        } = self;
        let dormant = |c: ColliderHandle| {
            colliders
                .get(c.0)
                .and_then(|c| bodies.hot(c.body))
                .is_some_and(|b| b.kind == BodyKind::Static || b.sleeping)
        };
        contacts.rebuild_active(|p| !(dormant(p.a) && dormant(p.b)))
    }

    /// One pass of [`World::stage_wake_touched`] over the active pairs, or
    /// over every pair when `all`.
    fn wake_pass(&mut self, all: bool) -> u32 {
        let mut woken = 0;
        let n = match (all, self.contacts.active()) {
            (false, Some(active)) => active.len(),
            _ => self.contacts.pairs().len(),
        };
        let use_active = !all && self.contacts.active().is_some();
        for k in 0..n {
            let i = if use_active {
                self.contacts.active().map_or(k, |a| a[k] as usize)
            } else {
                k
            };
            let p = self.contacts.pairs()[i];
            // Any point counts, speculative ones included: the solver would
            // otherwise stop the mover against a sleeper as against a wall
            // in this very step.
            if p.manifold.is_empty() || p.kind != PairKind::Solid {
                continue;
            }
            let (Some(ca), Some(cb)) = (self.colliders.get(p.a.0), self.colliders.get(p.b.0))
            else {
                continue;
            };
            for (sleeper, other) in [(ca.body, cb.body), (cb.body, ca.body)] {
                let moving = match self.bodies.hot(other) {
                    Some(o) => match o.kind {
                        BodyKind::Dynamic => !o.sleeping && o.rest_ticks == 0,
                        BodyKind::Kinematic => {
                            !o.linear_velocity.is_zero() || !o.angular_velocity.is_zero()
                        }
                        BodyKind::Static => false,
                    },
                    None => false,
                };
                if !moving {
                    continue;
                }
                if self.bodies.set_sleeping(sleeper, false) {
                    if let Some(s) = self.bodies.hot_mut(sleeper) {
                        s.rest_ticks = 0;
                    }
                    woken += 1;
                }
            }
        }
        woken
    }

    /// Wakes the sleeping dynamic bodies joined to a moving body. Returns
    /// how many woke.
    fn wake_joined(&mut self) -> u32 {
        let mut woken = 0;
        for i in 0..self.joints.arena.slot_count() as u32 {
            let Some(j) = self.joints.arena.get_by_index(i) else {
                continue;
            };
            let (a, b) = (j.desc.body_a, j.desc.body_b);
            for (sleeper, other) in [(a, b), (b, a)] {
                let moving = self.bodies.hot(other).is_some_and(|o| match o.kind {
                    BodyKind::Dynamic => !o.sleeping,
                    BodyKind::Kinematic => {
                        !o.linear_velocity.is_zero() || !o.angular_velocity.is_zero()
                    }
                    BodyKind::Static => false,
                });
                if moving && self.bodies.hot(sleeper).is_some_and(|s| s.sleeping) {
                    self.wake(sleeper);
                    woken += 1;
                }
            }
        }
        woken
    }
}

/// Whose contacts [`World::wake_touching`] follows.
#[derive(Clone, Copy)]
pub(super) enum Toucher {
    /// One collider's.
    Collider(ColliderHandle),
    /// Every collider of a body.
    Body(BodyHandle),
}

/// Wakes a body (any kind: its rest counter restarts) through the body set,
/// so the awake list learns of it; a sleeper that wakes may turn resting
/// contact pairs active, so the contact set's active list is dropped.
fn wake(bodies: &mut BodySet, contacts: &mut ContactSet, h: BodyHandle) {
    if let Some(b) = bodies.hot_mut(h) {
        b.rest_ticks = 0;
    }
    if bodies.set_sleeping(h, false) {
        contacts.invalidate_active();
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    /// Every `.rs` file under `dir`, with its path relative to `root`.
    fn sources(root: &Path, dir: &Path, out: &mut Vec<(String, String)>) {
        for entry in std::fs::read_dir(dir).expect("read the source folder") {
            let path = entry.expect("a folder entry").path();
            if path.is_dir() {
                sources(root, &path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let rel = path
                    .strip_prefix(root)
                    .expect("under src")
                    .to_string_lossy();
                let text = std::fs::read_to_string(&path).expect("read a source file");
                out.push((rel.replace('\\', "/"), text));
            }
        }
    }

    /// The awake set is the only writer of sleep states and of the lists
    /// that follow them: outside it, only the modules that store them (the
    /// body set and the contact set, with their own unit tests) call their
    /// writers.
    #[test]
    fn only_the_awake_set_changes_sleep_states_and_their_lists() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        let mut files = Vec::new();
        sources(&root, &root, &mut files);
        assert!(files.iter().any(|(p, _)| p == "world/awake.rs"));
        let writers = [
            ".set_sleeping(",
            ".refresh_awake(",
            ".invalidate_active(",
            ".rebuild_active(",
            ".sleeping = ",
        ];
        let mut found = Vec::new();
        for (path, text) in &files {
            let owner = path == "world/awake.rs"
                || path.starts_with("body/")
                || path.starts_with("collision/");
            if owner {
                continue;
            }
            for (n, line) in text.lines().enumerate() {
                for w in writers {
                    if line.contains(w) {
                        found.push(format!("{path}:{}: {}", n + 1, line.trim()));
                    }
                }
            }
        }
        assert!(
            found.is_empty(),
            "sleep state written outside the awake set:\n{}",
            found.join("\n")
        );
    }
}
