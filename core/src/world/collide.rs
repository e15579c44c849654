//! The collision stages of `World::step`: broad-phase update and candidate
//! pairs; narrow phase, persistent manifolds and events; waking.

use crate::body::{BodyHandle, BodyHot, BodyKind, BodySet};
use crate::collider::ColliderHandle;
use crate::collision::contacts::{Candidate, ContactStats, PairKind};
use crate::collision::reuse::{RelativePose, ReuseCache, shapes_reuse};
use crate::collision::{Manifold, PairStats, ProxyKey, ProxyKind, narrow};

use super::state::World;

/// A collider's broad-phase key: its handle index in the high 32 bits and
/// generation in the low ones, so sorting by key sorts by handle.
pub(crate) fn proxy_key(c: ColliderHandle) -> ProxyKey {
    ProxyKey(((c.0.index as u64) << 32) | c.0.generation as u64)
}

/// The collider handle behind a key (the inverse of [`proxy_key`]).
pub(crate) fn collider_of(key: ProxyKey) -> ColliderHandle {
    ColliderHandle(crate::arena::RawHandle {
        index: (key.0 >> 32) as u32,
        generation: key.0 as u32,
    })
}

/// How the broad phase should treat a body's colliders.
pub(crate) fn proxy_kind_of(bodies: &BodySet, body: BodyHandle) -> ProxyKind {
    match bodies.hot(body) {
        Some(b) => proxy_kind_of_hot(b),
        None => ProxyKind::Static,
    }
}

/// How the broad phase should treat the colliders of a live body.
fn proxy_kind_of_hot(b: &BodyHot) -> ProxyKind {
    match b.kind {
        BodyKind::Static => ProxyKind::Static,
        BodyKind::Kinematic => ProxyKind::Kinematic,
        BodyKind::Dynamic if b.sleeping => ProxyKind::Sleeping,
        BodyKind::Dynamic => ProxyKind::Dynamic,
    }
}

impl World {
    /// Moves a body's proxies to its current pose and sleep state (after a
    /// teleport, or a change of sleep state outside the step).
    pub(crate) fn refresh_proxies(&mut self, h: BodyHandle) {
        let (Some(hot), Some(cold)) = (self.bodies.hot(h), self.bodies.cold(h)) else {
            return;
        };
        let origin = hot.origin_pose(cold.local_center);
        let kind = proxy_kind_of(&self.bodies, h);
        for ch in &cold.colliders {
            if let Some(c) = self.colliders.get(ch.0) {
                let aabb = c
                    .shape
                    .aabb(&c.world_pose(&origin))
                    .expanded(self.config.contact_margin);
                let _ = self
                    .broad
                    .move_proxy(c.proxy, aabb, crate::math::Vec3::ZERO);
                if self.broad.kind(c.proxy).ok() != Some(kind) {
                    let _ = self.broad.set_kind(c.proxy, kind);
                }
            }
        }
    }

    /// Brings every proxy's kind in line with its body (static, kinematic,
    /// awake or asleep) and, when `move_shapes`, moves the proxies of awake
    /// moving bodies to their shapes' current boxes (fat boxes extended by
    /// the coming step's motion `v·dt`).
    ///
    /// Called with `move_shapes` at the end of every step, so queries
    /// between steps see where bodies are, and kinds-only at the start of the
    /// collision stage, since the game may wake or put bodies to sleep
    /// between steps.
    ///
    /// Only the awake bodies and those whose sleep state changed since the
    /// last call are visited (every body after a snapshot restore): a
    /// sleeping or static body's proxies neither move nor change kind. The
    /// broad phase sees the same calls in the same order as from a walk over
    /// every body.
    ///
    /// Determinism: bodies in handle order, colliders in the order added.
    pub(crate) fn sync_proxies(&mut self, move_shapes: bool) {
        let margin = self.config.contact_margin;
        let dt = self.config.dt();
        let World {
            bodies,
            colliders,
            broad,
            ..
        } = self;
        bodies.for_each_to_sync(|_, hot, cold| {
            if cold.colliders.is_empty() {
                return;
            }
            let kind = proxy_kind_of_hot(hot);
            let moving = move_shapes && matches!(kind, ProxyKind::Dynamic | ProxyKind::Kinematic);
            let origin = hot.origin_pose(cold.local_center);
            let displacement = hot.linear_velocity * dt;
            for ch in &cold.colliders {
                let Some(c) = colliders.get(ch.0) else {
                    continue;
                };
                if broad.kind(c.proxy).ok() != Some(kind) {
                    let _ = broad.set_kind(c.proxy, kind);
                }
                if moving {
                    let aabb = c.shape.aabb(&c.world_pose(&origin)).expanded(margin);
                    let _ = broad.move_proxy(c.proxy, aabb, displacement);
                }
            }
        });
    }

    /// The broad-phase stage: proxy kinds follow the bodies' sleep states
    /// (the game may wake or put bodies to sleep between steps; the proxies
    /// were moved at the end of the previous step), then the candidate pairs
    /// are found, filtered by body, category/mask/group and trigger rules,
    /// and left in `self.candidates` for the narrow phase.
    ///
    /// Determinism: candidates come out of the broad phase sorted by collider
    /// handle.
    #[inline(never)]
    pub(crate) fn stage_broad_phase(&mut self) -> PairStats {
        self.sync_proxies(false);
        let World {
            colliders,
            broad,
            candidates,
            joints,
            ..
        } = self;
        let filter = |ka: ProxyKey, kb: ProxyKey| {
            let (Some(a), Some(b)) = (
                colliders.get(collider_of(ka).0),
                colliders.get(collider_of(kb).0),
            ) else {
                return false;
            };
            a.body != b.body
                && !(a.is_trigger && b.is_trigger)
                && a.filter.allows(&b.filter)
                && !joints.blocks(a.body, b.body)
        };
        broad.update_pairs(filter, candidates)
    }

    /// The narrow-phase stage: the narrow phase on each candidate pair of
    /// the broad phase, and the persistent contact set and its events.
    ///
    /// Determinism: the candidates are in collider-handle order and
    /// everything here follows that order.
    #[inline(never)]
    pub(crate) fn stage_narrow_phase(&mut self) -> ContactStats {
        let margin = self.config.contact_margin;
        let dt = self.config.dt();
        let grew = self.poses.fill(&self.bodies, &self.colliders);
        let World {
            bodies,
            colliders,
            contacts,
            candidates,
            workers,
            poses,
            ..
        } = self;
        let cands = candidates.iter().map(|&(ka, kb)| {
            let (a, b) = (collider_of(ka), collider_of(kb));
            let trigger = colliders.get(a.0).is_some_and(|c| c.is_trigger)
                || colliders.get(b.0).is_some_and(|c| c.is_trigger);
            Candidate {
                a,
                b,
                kind: if trigger {
                    PairKind::Trigger
                } else {
                    PairKind::Solid
                },
            }
        });
        let poses = &*poses;
        let bodies_ref = &*bodies;
        let colliders_ref = &*colliders;
        // Speculative distance: the fixed margin plus how far the two bodies
        // close in one tick, so a fast body gets its contact point before it
        // passes the surface, and the solver stops it exactly there (no
        // overlap to push out, and a bounce from the right height).
        //
        // A solid pair of flat-faced shapes whose relative pose has barely
        // changed since its manifold was built rebuilds it from the cached
        // anchors instead; a pair with a sphere or capsule never does, and
        // its cache stays empty (see `collision::reuse`).
        let narrow_phase = |a: ColliderHandle,
                            b: ColliderHandle,
                            reuse: Option<(&mut Manifold, &mut ReuseCache)>,
                            out: &mut Manifold| {
            let (Some((ca, pa)), Some((cb, pb))) = (
                poses.pose(bodies_ref, colliders_ref, a),
                poses.pose(bodies_ref, colliders_ref, b),
            ) else {
                return false;
            };
            let reuse = match reuse {
                Some((_, cache)) if !shapes_reuse(&ca.shape, &cb.shape) => {
                    *cache = ReuseCache::EMPTY;
                    None
                }
                r => r,
            };
            let reach = || margin + (pb.velocity - pa.velocity).length() * dt;
            let Some((prev, cache)) = reuse else {
                narrow::contact(&ca.shape, &pa.pose, &cb.shape, &pb.pose, reach(), out);
                return false;
            };
            let rel = RelativePose::between(&pa.pose, &pb.pose);
            if !prev.is_empty() && cache.holds_for(&rel) {
                cache.rebuild(&pa, &pb, prev);
                return true;
            }
            narrow::contact(&ca.shape, &pa.pose, &cb.shape, &pb.pose, reach(), out);
            cache.record(&pa, &pb, &rel, out);
            false
        };
        let resting = |p: &crate::collision::ContactPair| {
            let kind =
                |ch: ColliderHandle| colliders.get(ch.0).map(|c| proxy_kind_of(bodies, c.body));
            matches!(
                (kind(p.a), kind(p.b)),
                (
                    Some(ProxyKind::Sleeping),
                    Some(ProxyKind::Sleeping | ProxyKind::Static)
                ) | (Some(ProxyKind::Static), Some(ProxyKind::Sleeping))
            )
        };
        let mut stats = contacts.update(cands, narrow_phase, resting, workers);
        stats.growths += grew;
        debug_assert!(
            self.active_pairs_cover_moving(),
            "active pair list misses a pair"
        );
        stats
    }

    /// Whether the contact set's active list is valid, ascending, and holds
    /// every pair with an awake or kinematic body, and the pairs are in
    /// strictly ascending key order (a debug check: walks every pair).
    fn active_pairs_cover_moving(&self) -> bool {
        let Some(active) = self.contacts.active() else {
            return false;
        };
        let pairs = self.contacts.pairs();
        if pairs.windows(2).any(|w| w[0].key() >= w[1].key())
            || active.windows(2).any(|w| w[0] >= w[1])
        {
            return false;
        }
        let moving = |c: ColliderHandle| {
            self.colliders
                .get(c.0)
                .and_then(|c| self.bodies.hot(c.body))
                .is_none_or(|b| b.is_moving())
        };
        let mut listed = active.iter().peekable();
        for (i, p) in pairs.iter().enumerate() {
            let is_listed = listed.next_if(|&&k| k as usize == i).is_some();
            if !is_listed && (moving(p.a) || moving(p.b)) {
                return false;
            }
        }
        listed.next().is_none()
    }
}
