//! The broad phase: which pairs of colliders are close enough to be worth a
//! narrow-phase test this step.
//!
//! Proxies live in two [`DynamicTree`]s: the *static tree* holds static and
//! sleeping proxies (never paired with each other, so the tree is never
//! queried against itself), the *moving tree* holds dynamic and kinematic
//! proxies. A proxy changes tree when its kind changes (a body falls asleep
//! or wakes up), keeping its fat box.
//!
//! [`BroadPhase::update_pairs`] returns the **full set** of candidate pairs
//! of the step, sorted by `(key A, key B)` with `key A < key B`: the pairs
//! whose fat boxes overlap, whose kinds need a contact (see
//! [`ProxyKind::pairs_with`]) and that the caller's filter accepted. It is
//! computed incrementally: the pairs of the previous step between proxies
//! that did not move are kept without a test (their fat boxes did not
//! change), and only the proxies that moved, were created, or changed kind
//! since the last update query the trees. Because the output is sorted by
//! the caller's keys, it does not depend on the shape of the trees.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::dynamic_tree::{DynamicTree, LeafId, TreeError};
use crate::math::{Aabb, Scalar, Vec3};
use crate::scratch::Capacities;

/// The caller's name for a proxy (the world passes the collider handle).
/// Pairs are ordered by it; keys must be unique among live proxies for the
/// pair list to be meaningful (duplicates never panic, they only give pairs
/// that the caller cannot tell apart).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct ProxyKey(pub u64);

/// How a proxy takes part in pairing. Decides its tree and which pairs it
/// can be in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum ProxyKind {
    /// Never moves on its own; pairs only with dynamic bodies. Static tree.
    Static,
    /// Moved by the user, not by forces; pairs with dynamic and sleeping
    /// bodies (a kinematic body must be able to wake a sleeping one).
    /// Moving tree.
    Kinematic,
    /// Simulated; pairs with everything. Moving tree.
    Dynamic,
    /// A dynamic body asleep: like a static proxy (no pairs with static or
    /// sleeping proxies) except that it still pairs with kinematic bodies.
    /// Static tree.
    Sleeping,
}

impl ProxyKind {
    /// Whether a pair of these kinds needs a contact: at least one awake
    /// dynamic body, or a kinematic body touching a sleeping one. So no
    /// static–static, kinematic–static, kinematic–kinematic,
    /// sleeping–static or sleeping–sleeping pairs. Symmetric.
    pub const fn pairs_with(self, other: ProxyKind) -> bool {
        use ProxyKind::{Dynamic, Kinematic, Sleeping};
        matches!(
            (self, other),
            (Dynamic, _) | (_, Dynamic) | (Kinematic, Sleeping) | (Sleeping, Kinematic)
        )
    }

    /// Whether proxies of this kind live in the moving tree.
    pub const fn is_moving(self) -> bool {
        matches!(self, ProxyKind::Dynamic | ProxyKind::Kinematic)
    }
}

/// The broad phase's handle of a proxy: an index into its proxy table,
/// reused (LIFO) after [`BroadPhase::destroy_proxy`]. The owner must forget
/// an id once it is destroyed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct ProxyId(u32);

impl ProxyId {
    /// The table index, for storing in compact form.
    pub const fn index(self) -> u32 {
        self.0
    }

    /// The id back from [`index`](Self::index). An index that names no live
    /// proxy is rejected by every call with [`BroadPhaseError::InvalidProxy`].
    pub const fn from_index(index: u32) -> ProxyId {
        ProxyId(index)
    }
}

/// What can go wrong with a broad-phase call.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum BroadPhaseError {
    /// The id does not name a live proxy.
    #[error("proxy {0:?} is not a live proxy")]
    InvalidProxy(ProxyId),
    /// A tree is inconsistent (from [`BroadPhase::validate`]).
    #[error("broad-phase tree: {0}")]
    Tree(#[from] TreeError),
    /// The proxy table, trees and pair list disagree
    /// (from [`BroadPhase::validate`]).
    #[error("broad-phase bookkeeping broken at proxy {index}: {reason}")]
    Corrupt {
        /// The proxy slot (or pair index) where the check failed.
        index: u32,
        /// Which invariant.
        reason: &'static str,
    },
}

/// Counters of one [`BroadPhase::update_pairs`] call, for the step report
/// and the benchmarks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PairStats {
    /// Proxies that queried the trees (moved, created or changed kind since
    /// the previous update).
    pub moved_proxies: u32,
    /// Tree queries run (a moving proxy queries both trees, a static or
    /// sleeping one only the moving tree).
    pub tree_queries: u32,
    /// Overlaps found by the queries whose kinds need a pair; each was
    /// offered to the filter once.
    pub pairs_found: u32,
    /// Of those, how many the filter rejected.
    pub pairs_filtered: u32,
    /// Pairs kept from the previous update without a test.
    pub pairs_kept: u32,
    /// Size of the pair set returned.
    pub pairs_total: u32,
    /// Tree reinsertions since the previous update: `move_proxy` calls that
    /// left the fat box, plus kind changes that switched trees.
    pub reinsertions: u32,
    /// Times an internal buffer (or the caller's `out`) had to grow since
    /// the previous update. Zero once warm: the per-step path does not
    /// allocate while the pair count and proxy count stay within the
    /// capacities reached so far.
    pub buffer_growths: u32,
}

/// One entry of the proxy table. 16 bytes.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
struct Slot {
    key: ProxyKey,
    /// Leaf in the tree given by `kind`, or the next free slot when dead.
    leaf: u32,
    kind: ProxyKind,
    live: bool,
    /// In `move_buffer` (moved, created, changed kind or destroyed since
    /// the previous update): its old pairs are dropped, it queries anew.
    moved: bool,
}

const _: () = assert!(std::mem::size_of::<Slot>() == 16);

/// A candidate pair, normalised so that `(a, ia) < (b, ib)`. The derived
/// order (keys first, then ids) is total, so sorting is deterministic even
/// with duplicate keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
struct Pair {
    a: ProxyKey,
    b: ProxyKey,
    ia: u32,
    ib: u32,
}

const NULL: u32 = u32::MAX;

/// Finds candidate pairs between proxies; see the module documentation.
///
/// Determinism: every output is a function of the sequence of calls and
/// their arguments; the pair list is moreover independent of the trees'
/// shape (it is sorted by key). Serializable for snapshots (scratch buffers
/// are not saved); call [`validate`](Self::validate) after deserializing
/// data that was not produced by this code.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BroadPhase {
    static_tree: DynamicTree,
    moving_tree: DynamicTree,
    slots: Vec<Slot>,
    free_slot: u32,
    proxy_count: u32,
    /// Slots to re-pair at the next update, in call order.
    move_buffer: Vec<u32>,
    /// The current pair set, sorted.
    pairs: Vec<Pair>,
    #[serde(skip)]
    new_pairs: Vec<Pair>,
    #[serde(skip)]
    merged: Vec<Pair>,
    reinsertions: u32,
    growths: u32,
    last: PairStats,
}

impl BroadPhase {
    /// An empty broad phase whose fat boxes are the tight boxes grown by
    /// `margin` (a negative margin counts as zero).
    pub fn new(margin: Scalar) -> BroadPhase {
        BroadPhase::with_capacity(margin, 0, 0)
    }

    /// An empty broad phase pre-sized for `proxies` proxies (in either tree)
    /// and `pairs` pairs, so that a scene within those counts never
    /// reallocates.
    pub fn with_capacity(margin: Scalar, proxies: usize, pairs: usize) -> BroadPhase {
        BroadPhase {
            static_tree: DynamicTree::with_capacity(margin, proxies),
            moving_tree: DynamicTree::with_capacity(margin, proxies),
            slots: Vec::with_capacity(proxies),
            free_slot: NULL,
            proxy_count: 0,
            move_buffer: Vec::with_capacity(proxies),
            pairs: Vec::with_capacity(pairs),
            new_pairs: Vec::with_capacity(pairs),
            merged: Vec::with_capacity(pairs),
            reinsertions: 0,
            growths: 0,
            last: PairStats::default(),
        }
    }

    /// Number of live proxies.
    pub fn proxy_count(&self) -> usize {
        self.proxy_count as usize
    }

    /// Returns and clears the count of buffer growths since the last call or
    /// [`update_pairs`](Self::update_pairs), which otherwise reports them.
    ///
    /// Why: a step moves proxies after its pair update (a body that fell
    /// asleep switches to the static tree, whose node pool may grow), and
    /// that growth is the step's, not the next one's.
    pub fn take_growths(&mut self) -> u32 {
        std::mem::take(&mut self.growths)
    }

    /// The tree of static and sleeping proxies (read-only: statistics).
    pub fn static_tree(&self) -> &DynamicTree {
        &self.static_tree
    }

    /// The tree of dynamic and kinematic proxies (read-only: statistics).
    pub fn moving_tree(&self) -> &DynamicTree {
        &self.moving_tree
    }

    fn tree_mut(&mut self, kind: ProxyKind) -> &mut DynamicTree {
        if kind.is_moving() {
            &mut self.moving_tree
        } else {
            &mut self.static_tree
        }
    }

    fn tree(&self, kind: ProxyKind) -> &DynamicTree {
        if kind.is_moving() {
            &self.moving_tree
        } else {
            &self.static_tree
        }
    }

    fn slot(&self, id: ProxyId) -> Result<&Slot, BroadPhaseError> {
        match self.slots.get(id.0 as usize) {
            Some(s) if s.live => Ok(s),
            _ => Err(BroadPhaseError::InvalidProxy(id)),
        }
    }

    /// Queues a slot for re-pairing at the next update (once).
    fn mark_moved(&mut self, i: u32) {
        let s = &mut self.slots[i as usize];
        if !s.moved {
            s.moved = true;
            if self.move_buffer.len() == self.move_buffer.capacity() {
                self.growths += 1;
            }
            self.move_buffer.push(i);
        }
    }

    /// Adds a proxy with tight box `aabb`. It is paired at the next update.
    ///
    /// Determinism: ids are reused LIFO, so the id returned depends only on
    /// the order of earlier create/destroy calls.
    pub fn create_proxy(&mut self, aabb: Aabb, key: ProxyKey, kind: ProxyKind) -> ProxyId {
        let slot = if self.free_slot != NULL {
            let i = self.free_slot;
            self.free_slot = self.slots[i as usize].leaf;
            i
        } else {
            if self.slots.len() == self.slots.capacity() {
                self.growths += 1;
            }
            self.slots.push(Slot {
                key,
                leaf: NULL,
                kind,
                live: false,
                moved: false,
            });
            (self.slots.len() - 1) as u32
        };
        let tree = self.tree_mut(kind);
        let cap = tree.node_capacity();
        let leaf = tree.create_proxy(aabb, u64::from(slot));
        let grew = tree.node_capacity() != cap;
        self.growths += u32::from(grew);
        let s = &mut self.slots[slot as usize];
        s.key = key;
        s.leaf = leaf.index();
        s.kind = kind;
        s.live = true;
        self.proxy_count += 1;
        self.mark_moved(slot);
        ProxyId(slot)
    }

    /// Removes a proxy; its pairs disappear at the next update.
    ///
    /// # Errors
    /// [`BroadPhaseError::InvalidProxy`] if `id` is not live.
    pub fn destroy_proxy(&mut self, id: ProxyId) -> Result<(), BroadPhaseError> {
        let s = *self.slot(id)?;
        self.tree_mut(s.kind)
            .destroy_proxy(LeafId::from_raw(s.leaf))?;
        // Marked so that the pairs naming this slot are dropped, even if the
        // slot is reused before the next update.
        self.mark_moved(id.0);
        let slot = &mut self.slots[id.0 as usize];
        slot.live = false;
        slot.leaf = self.free_slot;
        self.free_slot = id.0;
        self.proxy_count -= 1;
        Ok(())
    }

    /// Tells the broad phase that the proxy's tight box is now `aabb` after
    /// moving by `displacement` (used to stretch the fat box forward).
    /// Returns whether the fat box changed (the proxy was reinserted and
    /// will be re-paired at the next update).
    ///
    /// # Errors
    /// [`BroadPhaseError::InvalidProxy`] if `id` is not live.
    pub fn move_proxy(
        &mut self,
        id: ProxyId,
        aabb: Aabb,
        displacement: Vec3,
    ) -> Result<bool, BroadPhaseError> {
        let s = *self.slot(id)?;
        let moved =
            self.tree_mut(s.kind)
                .move_proxy(LeafId::from_raw(s.leaf), aabb, displacement)?;
        if moved {
            self.reinsertions += 1;
            self.mark_moved(id.0);
        }
        Ok(moved)
    }

    /// Changes how the proxy pairs (a body falls asleep, wakes up, or
    /// changes type). The fat box is kept; the proxy switches tree when
    /// needed and is re-paired at the next update. No-op if the kind is the
    /// same.
    ///
    /// # Errors
    /// [`BroadPhaseError::InvalidProxy`] if `id` is not live.
    pub fn set_kind(&mut self, id: ProxyId, kind: ProxyKind) -> Result<(), BroadPhaseError> {
        let s = *self.slot(id)?;
        if s.kind == kind {
            return Ok(());
        }
        if s.kind.is_moving() != kind.is_moving() {
            let leaf = LeafId::from_raw(s.leaf);
            let fat = self.tree(s.kind).fat_aabb(leaf)?;
            self.tree_mut(s.kind).destroy_proxy(leaf)?;
            let tree = self.tree_mut(kind);
            let cap = tree.node_capacity();
            let new_leaf = tree.create_proxy_fat(fat, u64::from(id.0));
            let grew = tree.node_capacity() != cap;
            self.growths += u32::from(grew);
            self.slots[id.0 as usize].leaf = new_leaf.index();
            self.reinsertions += 1;
        }
        self.slots[id.0 as usize].kind = kind;
        self.mark_moved(id.0);
        Ok(())
    }

    /// Makes the proxy re-pair at the next update without moving: call it
    /// when the inputs of the caller's filter change (collision groups,
    /// masks), since kept pairs are not filtered again.
    ///
    /// # Errors
    /// [`BroadPhaseError::InvalidProxy`] if `id` is not live.
    pub fn touch_proxy(&mut self, id: ProxyId) -> Result<(), BroadPhaseError> {
        self.slot(id)?;
        self.mark_moved(id.0);
        Ok(())
    }

    /// The proxy's fat box.
    ///
    /// # Errors
    /// [`BroadPhaseError::InvalidProxy`] if `id` is not live.
    #[cfg(test)]
    pub fn fat_aabb(&self, id: ProxyId) -> Result<Aabb, BroadPhaseError> {
        let s = self.slot(id)?;
        Ok(self.tree(s.kind).fat_aabb(LeafId::from_raw(s.leaf))?)
    }

    /// The proxy's key.
    ///
    /// # Errors
    /// [`BroadPhaseError::InvalidProxy`] if `id` is not live.
    pub fn key(&self, id: ProxyId) -> Result<ProxyKey, BroadPhaseError> {
        Ok(self.slot(id)?.key)
    }

    /// The proxy's kind.
    ///
    /// # Errors
    /// [`BroadPhaseError::InvalidProxy`] if `id` is not live.
    pub fn kind(&self, id: ProxyId) -> Result<ProxyKind, BroadPhaseError> {
        Ok(self.slot(id)?.kind)
    }

    /// Calls `f(id, key)` for every proxy (both trees) whose fat box
    /// overlaps `aabb`, until `f` returns `false`. For scene queries: does
    /// not change any state.
    ///
    /// Determinism: the static tree is visited first, then the moving tree,
    /// each in an order that depends on its shape; sort what you collect if
    /// the order matters.
    pub fn query(&self, aabb: &Aabb, mut f: impl FnMut(ProxyId, ProxyKey) -> bool) {
        let mut go_on = true;
        for tree in [&self.static_tree, &self.moving_tree] {
            if !go_on {
                return;
            }
            tree.query(aabb, |_, data| {
                let i = data as u32;
                go_on = f(ProxyId(i), self.slots[i as usize].key);
                go_on
            });
        }
    }

    /// Calls `f(id, key, max)` for every proxy (both trees) whose fat box
    /// the segment `origin + t · translation`, `t ∈ [0, max]`, touches; `f`
    /// returns `Some(m)` to go on with `max = min(max, m)` or `None` to stop
    /// (see [`DynamicTree::ray_cast`]). For scene queries: does not change
    /// any state.
    ///
    /// Determinism: the static tree is visited first, then the moving tree
    /// with the clipped `max`, each in an order that depends on its shape;
    /// callers take a minimum over a total order or sort what they collect.
    pub fn ray_cast(
        &self,
        origin: Vec3,
        translation: Vec3,
        max: Scalar,
        mut f: impl FnMut(ProxyId, ProxyKey, Scalar) -> Option<Scalar>,
    ) {
        let mut max = max;
        for tree in [&self.static_tree, &self.moving_tree] {
            let r = tree.ray_cast(origin, translation, max, |_, data, m| {
                let i = data as u32;
                f(ProxyId(i), self.slots[i as usize].key, m)
            });
            match r {
                Some(m) => max = m,
                None => return,
            }
        }
    }

    /// [`ray_cast`](Self::ray_cast) for a moving box (see
    /// [`DynamicTree::box_cast`]): the candidates of a shape sweep, with the
    /// same `Some(max)` / `None` protocol and the same determinism contract.
    pub fn box_cast(
        &self,
        start: &Aabb,
        translation: Vec3,
        max: Scalar,
        mut f: impl FnMut(ProxyId, ProxyKey, Scalar) -> Option<Scalar>,
    ) {
        let mut max = max;
        for tree in [&self.static_tree, &self.moving_tree] {
            let r = tree.box_cast(start, translation, max, |_, data, m| {
                let i = data as u32;
                f(ProxyId(i), self.slots[i as usize].key, m)
            });
            match r {
                Some(m) => max = m,
                None => return,
            }
        }
    }

    /// Rebuilds both trees with the binned SAH (see
    /// [`DynamicTree::rebuild`]); pairs are not affected. Useful after
    /// loading a level proxy by proxy.
    #[cfg(test)]
    pub fn rebuild_trees(&mut self) {
        self.static_tree.rebuild();
        self.moving_tree.rebuild();
    }

    /// Finds this step's candidate pairs and writes them to `out` (cleared
    /// first) as `(key A, key B)` with `key A < key B` (by id on equal keys),
    /// sorted and without duplicates.
    ///
    /// `filter(a, b)` is called once for each new overlap between proxies
    /// whose kinds need a pair (never for pairs kept from the previous
    /// update), with `a < b` as in the output; `false` drops the pair. It
    /// must be a pure function of its inputs between
    /// [`touch_proxy`](Self::touch_proxy) calls.
    ///
    /// Determinism: the filter is called in an order that depends on the
    /// trees' shape; the output does not.
    pub fn update_pairs<F>(
        &mut self,
        mut filter: F,
        out: &mut Vec<(ProxyKey, ProxyKey)>,
    ) -> PairStats
    where
        F: FnMut(ProxyKey, ProxyKey) -> bool,
    {
        let before = Capacities::of([&self.new_pairs, &self.merged, &self.pairs, &*out]);
        let mut stats = PairStats {
            moved_proxies: 0,
            reinsertions: std::mem::take(&mut self.reinsertions),
            ..PairStats::default()
        };
        let BroadPhase {
            static_tree,
            moving_tree,
            slots,
            move_buffer,
            pairs,
            new_pairs,
            merged,
            ..
        } = self;

        // 1. New overlaps of every proxy that moved.
        new_pairs.clear();
        for &m in move_buffer.iter() {
            let ms = slots[m as usize];
            if !ms.live {
                continue;
            }
            stats.moved_proxies += 1;
            let tree = if ms.kind.is_moving() {
                &*moving_tree
            } else {
                &*static_tree
            };
            let Ok(fat) = tree.fat_aabb(LeafId::from_raw(ms.leaf)) else {
                continue;
            };
            let mut visit = |_: LeafId, data: u64| -> bool {
                let o = data as u32;
                if o == m {
                    return true;
                }
                let os = &slots[o as usize];
                // Both moved: the query of the lower slot reports the pair
                // (each of the two queries the other's tree).
                if os.moved && o < m {
                    return true;
                }
                if !ms.kind.pairs_with(os.kind) {
                    return true;
                }
                stats.pairs_found += 1;
                let pair = if (ms.key, m) < (os.key, o) {
                    Pair {
                        a: ms.key,
                        b: os.key,
                        ia: m,
                        ib: o,
                    }
                } else {
                    Pair {
                        a: os.key,
                        b: ms.key,
                        ia: o,
                        ib: m,
                    }
                };
                if filter(pair.a, pair.b) {
                    new_pairs.push(pair);
                } else {
                    stats.pairs_filtered += 1;
                }
                true
            };
            if ms.kind.is_moving() {
                static_tree.query(&fat, &mut visit);
                moving_tree.query(&fat, &mut visit);
                stats.tree_queries += 2;
            } else {
                moving_tree.query(&fat, &mut visit);
                stats.tree_queries += 1;
            }
        }

        // 2. Old pairs between proxies that did not move still overlap.
        pairs.retain(|p| !slots[p.ia as usize].moved && !slots[p.ib as usize].moved);
        stats.pairs_kept = pairs.len() as u32;

        // 3. Determinism: sort by the total order (keys, then ids), so the
        // result does not depend on the order the trees reported overlaps.
        new_pairs.sort_unstable();
        new_pairs.dedup();

        // 4. Merge the two sorted, disjoint lists (every new pair names a
        // moved proxy, no kept pair does).
        merged.clear();
        let (mut i, mut j) = (0, 0);
        while i < pairs.len() && j < new_pairs.len() {
            if pairs[i] < new_pairs[j] {
                merged.push(pairs[i]);
                i += 1;
            } else {
                merged.push(new_pairs[j]);
                j += 1;
            }
        }
        merged.extend_from_slice(&pairs[i..]);
        merged.extend_from_slice(&new_pairs[j..]);
        std::mem::swap(pairs, merged);

        for &m in move_buffer.iter() {
            slots[m as usize].moved = false;
        }
        move_buffer.clear();

        out.clear();
        out.extend(pairs.iter().map(|p| (p.a, p.b)));
        stats.pairs_total = pairs.len() as u32;

        // `pairs` and `merged` swapped: each buffer against itself.
        let grew = Capacities::of([&*new_pairs, &*pairs, &*merged, &*out]).growths_since(&before);
        stats.buffer_growths = std::mem::take(&mut self.growths) + grew;
        self.last = stats;
        stats
    }

    /// Sum of the capacities of the per-step buffers: unchanged between two
    /// updates means nothing was reallocated.
    #[cfg(test)]
    pub fn buffer_capacity(&self) -> usize {
        self.move_buffer.capacity()
            + self.pairs.capacity()
            + self.new_pairs.capacity()
            + self.merged.capacity()
            + self.slots.capacity()
            + self.static_tree.node_capacity()
            + self.moving_tree.node_capacity()
    }

    /// Checks both trees, the proxy table (each live proxy is the leaf its
    /// slot names, in the tree its kind names, and points back), the free
    /// list, and that the pair list is strictly sorted with live,
    /// pairable members.
    ///
    /// # Errors
    /// The first inconsistency found.
    pub fn validate(&self) -> Result<(), BroadPhaseError> {
        let bad = |index: u32, reason| Err(BroadPhaseError::Corrupt { index, reason });
        self.static_tree.validate()?;
        self.moving_tree.validate()?;
        let mut live = 0u32;
        for (i, s) in self.slots.iter().enumerate() {
            if !s.live {
                continue;
            }
            live += 1;
            match self.tree(s.kind).user_data(LeafId::from_raw(s.leaf)) {
                Ok(d) if d == i as u64 => {}
                _ => return bad(i as u32, "slot's leaf does not point back"),
            }
        }
        if live != self.proxy_count
            || live as usize != self.static_tree.proxy_count() + self.moving_tree.proxy_count()
        {
            return bad(NULL, "proxy counts disagree");
        }
        let mut f = self.free_slot;
        let mut free = 0usize;
        while f != NULL {
            match self.slots.get(f as usize) {
                Some(s) if !s.live => f = s.leaf,
                _ => return bad(f, "free list names a live or missing slot"),
            }
            free += 1;
            if free > self.slots.len() {
                return bad(f, "free list has a cycle");
            }
        }
        if free + live as usize != self.slots.len() {
            return bad(NULL, "slots neither live nor free");
        }
        for (k, p) in self.pairs.iter().enumerate() {
            if k > 0 && self.pairs[k - 1] >= *p {
                return bad(k as u32, "pair list not strictly sorted");
            }
            let (sa, sb) = (self.slots.get(p.ia as usize), self.slots.get(p.ib as usize));
            let (Some(sa), Some(sb)) = (sa, sb) else {
                return bad(k as u32, "pair names a missing slot");
            };
            // Pairs naming moved or dead proxies are only dropped at the
            // next update; the others must match their proxies now.
            let settled = sa.live && sb.live && !sa.moved && !sb.moved;
            if settled && !(sa.key == p.a && sb.key == p.b && sa.kind.pairs_with(sb.kind)) {
                return bad(k as u32, "pair does not match its proxies");
            }
        }
        Ok(())
    }
}
