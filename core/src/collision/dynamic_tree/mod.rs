//! A dynamic AABB tree: the bounding-volume hierarchy the broad phase keeps
//! its proxies in.
//!
//! The design follows the one in Box2D/Box3D (`b2DynamicTree`), rewritten for
//! integer arithmetic:
//!
//! * nodes live in one `Vec`, freed nodes go on an intrusive LIFO free list,
//!   so the node a proxy gets depends only on the history of calls;
//! * a leaf stores a *fat* box (the tight box grown by a margin, optionally
//!   stretched along the displacement) so that a slowly moving proxy does not
//!   touch the tree every step;
//! * a new leaf picks its sibling by the surface-area heuristic (SAH) with a
//!   branch-and-bound descent, and every ancestor is refitted and offered a
//!   tree rotation on the way back up (after insertions and removals alike);
//! * [`DynamicTree::rebuild`] rebuilds the whole tree top-down with a binned
//!   SAH, for trees that were built by many insertions (level loading).
//!
//! Costs are half surface areas measured in ulps² as `u128` (each extent fits
//! `u64`, so each product fits `u128` exactly; sums saturate). Nothing rounds,
//! so the same boxes give the same choices on every machine, and ties always
//! go to the first candidate in a fixed order.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::math::{Aabb, Scalar, Vec3};

pub(crate) mod ray;
// The SAH rebuild: not called by the step (the trees stay balanced by
// rotations as proxies move); its tests compare tree quality against it.
#[cfg(test)]
mod rebuild;
mod validate;

#[cfg(test)]
use rebuild::RebuildScratch;

/// The "no node" index.
const NULL: u32 = u32::MAX;
/// The height stored in a node that sits on the free list.
const FREE: u32 = u32::MAX;
/// Depth of the traversal stack kept on the call stack; trees taller than
/// this spill into a heap `Vec` (not seen in practice: the SAH trees of the
/// tests stay under 40 levels for 10⁴ leaves).
const INLINE_STACK: usize = 128;

/// A leaf of a [`DynamicTree`]: the handle of one proxy.
///
/// It is the index of the leaf's node, which never changes while the proxy
/// lives (rotations relink nodes, they do not move them).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct LeafId(u32);

impl LeafId {
    /// The node index, for diagnostics and compact storage.
    pub const fn index(self) -> u32 {
        self.0
    }

    /// Rebuilds an id from [`index`](Self::index) (the broad phase stores
    /// leaves as bare `u32`s).
    pub(crate) const fn from_raw(index: u32) -> LeafId {
        LeafId(index)
    }
}

/// What can go wrong with a tree call.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum TreeError {
    /// The id does not name a live leaf of this tree (destroyed already, or
    /// from another tree).
    #[error("leaf {0:?} is not a live proxy of this tree")]
    InvalidLeaf(LeafId),
    /// [`DynamicTree::validate`] found a broken invariant.
    #[error("tree invariant broken at node {node}: {reason}")]
    Corrupt {
        /// The node where the check failed.
        node: u32,
        /// Which invariant.
        reason: &'static str,
    },
}

/// One node: a leaf (`child1 == NULL`) or an internal node with two children.
/// 72 bytes.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
struct Node {
    /// Fat box of a leaf; exact union of the children of an internal node.
    aabb: Aabb,
    /// The caller's data (leaves only).
    user_data: u64,
    /// The parent, or the next free node while on the free list.
    parent: u32,
    child1: u32,
    child2: u32,
    /// 0 for a leaf, 1 + the larger child height otherwise, `FREE` if free.
    height: u32,
}

const _: () = assert!(std::mem::size_of::<Node>() == 72);

impl Node {
    const EMPTY: Node = Node {
        aabb: Aabb::new(Vec3::ZERO, Vec3::ZERO),
        user_data: 0,
        parent: NULL,
        child1: NULL,
        child2: NULL,
        height: FREE,
    };

    #[inline(always)]
    fn is_leaf(&self) -> bool {
        self.child1 == NULL
    }
}

/// A dynamic AABB tree of proxies with `u64` user data.
///
/// Determinism: every result (node indices, tree shape, query visit order)
/// is a function of the sequence of calls only: integer costs, fixed tie
/// breaks, LIFO node reuse.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DynamicTree {
    nodes: Vec<Node>,
    root: u32,
    free_list: u32,
    leaf_count: u32,
    margin: Scalar,
    #[cfg(test)]
    #[serde(skip)]
    scratch: RebuildScratch,
}

/// Half the surface area of a box in ulps² (Q64.64), exact unless it
/// saturates (only for boxes wider than 2³² units). An inverted box counts
/// as flat.
#[inline]
pub(crate) fn half_area_wide(b: &Aabb) -> u128 {
    #[inline(always)]
    fn extent(lo: Scalar, hi: Scalar) -> u64 {
        // hi - lo in two's complement is the exact distance when hi >= lo.
        if hi <= lo {
            0
        } else {
            hi.to_bits().wrapping_sub(lo.to_bits()) as u64
        }
    }
    #[inline(always)]
    fn mul(a: u64, b: u64) -> u128 {
        a as u128 * b as u128
    }
    let dx = extent(b.min.x, b.max.x);
    let dy = extent(b.min.y, b.max.y);
    let dz = extent(b.min.z, b.max.z);
    // Each extent < 2^64, so each product < 2^128: only the sums can saturate.
    mul(dx, dy)
        .saturating_add(mul(dy, dz))
        .saturating_add(mul(dz, dx))
}

/// Twice the centre of a box, per axis, exactly.
#[inline(always)]
fn center2(b: &Aabb) -> [i128; 3] {
    [
        b.min.x.to_bits() as i128 + b.max.x.to_bits() as i128,
        b.min.y.to_bits() as i128 + b.max.y.to_bits() as i128,
        b.min.z.to_bits() as i128 + b.max.z.to_bits() as i128,
    ]
}

/// Manhattan distance between the centres of two boxes (×2), for tie breaks.
#[inline]
fn center_distance(a: &Aabb, b: &Aabb) -> u128 {
    let (ca, cb) = (center2(a), center2(b));
    (0..3).fold(0u128, |acc, i| {
        acc.saturating_add((ca[i] - cb[i]).unsigned_abs())
    })
}

/// A traversal stack that lives on the call stack and only spills to the
/// heap for pathologically deep trees.
struct Stack {
    inline: [u32; INLINE_STACK],
    len: usize,
    spill: Vec<u32>,
}

impl Stack {
    #[inline(always)]
    fn new() -> Stack {
        Stack {
            inline: [0; INLINE_STACK],
            len: 0,
            spill: Vec::new(),
        }
    }

    #[inline(always)]
    fn push(&mut self, v: u32) {
        if self.len < INLINE_STACK {
            self.inline[self.len] = v;
            self.len += 1;
        } else {
            self.spill.push(v);
        }
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<u32> {
        if let Some(v) = self.spill.pop() {
            return Some(v);
        }
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        Some(self.inline[self.len])
    }
}

impl DynamicTree {
    /// An empty tree whose leaves are their tight boxes grown by `margin` on
    /// every side (a negative margin is treated as zero).
    #[cfg(test)]
    pub fn new(margin: Scalar) -> DynamicTree {
        DynamicTree::with_capacity(margin, 0)
    }

    /// An empty tree with room for `leaves` proxies (2·leaves − 1 nodes), so
    /// that filling it up to that count never reallocates.
    pub fn with_capacity(margin: Scalar, leaves: usize) -> DynamicTree {
        DynamicTree {
            nodes: Vec::with_capacity((2 * leaves).saturating_sub(1)),
            root: NULL,
            free_list: NULL,
            leaf_count: 0,
            margin: margin.max(Scalar::ZERO),
            #[cfg(test)]
            scratch: RebuildScratch::default(),
        }
    }

    /// Number of live proxies.
    pub fn proxy_count(&self) -> usize {
        self.leaf_count as usize
    }

    /// Number of node slots allocated so far (live + free): grows only when
    /// the free list is empty.
    #[cfg(test)]
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Capacity of the node pool; compare before and after a call to detect
    /// a reallocation.
    pub fn node_capacity(&self) -> usize {
        self.nodes.capacity()
    }

    /// Height of the tree: 0 for a single leaf or an empty tree.
    #[cfg(test)]
    pub fn height(&self) -> u32 {
        if self.root == NULL {
            0
        } else {
            self.nodes[self.root as usize].height
        }
    }

    /// Sum of the half areas of the internal nodes, in ulps²: the quantity
    /// the SAH minimises. Two trees over the same leaves with different
    /// costs have different shapes; a rebuild should lower it.
    #[cfg(test)]
    pub fn internal_area(&self) -> u128 {
        self.nodes
            .iter()
            .filter(|n| n.height != FREE && !n.is_leaf())
            .fold(0u128, |acc, n| acc.saturating_add(half_area_wide(&n.aabb)))
    }

    /// Inserts a proxy whose tight box is `aabb`; the tree stores
    /// `aabb.expanded(margin)`.
    pub fn create_proxy(&mut self, aabb: Aabb, user_data: u64) -> LeafId {
        let fat = aabb.expanded(self.margin);
        self.create_proxy_fat(fat, user_data)
    }

    /// Inserts a proxy with a fat box given as is (the broad phase uses it to
    /// move a proxy between trees without changing its fat box).
    pub(crate) fn create_proxy_fat(&mut self, fat: Aabb, user_data: u64) -> LeafId {
        let leaf = self.alloc_node();
        let node = &mut self.nodes[leaf as usize];
        node.aabb = fat;
        node.user_data = user_data;
        node.height = 0;
        self.insert_leaf(leaf);
        self.leaf_count += 1;
        LeafId(leaf)
    }

    /// Removes a proxy and returns its user data.
    ///
    /// # Errors
    /// [`TreeError::InvalidLeaf`] if `id` is not a live leaf.
    pub fn destroy_proxy(&mut self, id: LeafId) -> Result<u64, TreeError> {
        self.check_leaf(id)?;
        let data = self.nodes[id.0 as usize].user_data;
        self.remove_leaf(id.0);
        self.free_node(id.0);
        self.leaf_count -= 1;
        Ok(data)
    }

    /// Tells the tree that the proxy's tight box is now `aabb`, after moving
    /// by `displacement` this step. Returns whether the proxy was reinserted
    /// (its fat box changed).
    ///
    /// Nothing happens while the fat box still contains `aabb` and is not
    /// much larger than needed. Otherwise the new fat box is `aabb` grown by
    /// the margin and stretched by `displacement` on the side it moves
    /// towards (a predictive box: a proxy moving steadily reinserts about
    /// once per `margin / speed` steps instead of every step), and the leaf
    /// is removed and reinserted. A fat box that has grown larger than the
    /// new one plus four margins (a fast proxy that slowed down) is shrunk.
    ///
    /// # Errors
    /// [`TreeError::InvalidLeaf`] if `id` is not a live leaf.
    pub fn move_proxy(
        &mut self,
        id: LeafId,
        aabb: Aabb,
        displacement: Vec3,
    ) -> Result<bool, TreeError> {
        self.check_leaf(id)?;
        let old = self.nodes[id.0 as usize].aabb;
        let mut fat = aabb.expanded(self.margin);
        let zero = Scalar::ZERO;
        fat.min += displacement.min(Vec3::splat(zero));
        fat.max += displacement.max(Vec3::splat(zero));
        if old.contains(&aabb) {
            let huge = fat.expanded(self.margin.mul_int(4));
            if huge.contains(&old) {
                return Ok(false);
            }
        }
        self.remove_leaf(id.0);
        self.nodes[id.0 as usize].aabb = fat;
        self.insert_leaf(id.0);
        Ok(true)
    }

    /// The fat box stored for a proxy.
    ///
    /// # Errors
    /// [`TreeError::InvalidLeaf`] if `id` is not a live leaf.
    pub fn fat_aabb(&self, id: LeafId) -> Result<Aabb, TreeError> {
        self.check_leaf(id)?;
        Ok(self.nodes[id.0 as usize].aabb)
    }

    /// The user data of a proxy.
    ///
    /// # Errors
    /// [`TreeError::InvalidLeaf`] if `id` is not a live leaf.
    pub fn user_data(&self, id: LeafId) -> Result<u64, TreeError> {
        self.check_leaf(id)?;
        Ok(self.nodes[id.0 as usize].user_data)
    }

    /// Calls `f(leaf, user_data, fat_box)` for every live proxy in node-index
    /// order (independent of the tree's shape): for brute-force checks and
    /// snapshots.
    #[cfg(test)]
    pub fn for_each_proxy(&self, mut f: impl FnMut(LeafId, u64, &Aabb)) {
        for (i, n) in self.nodes.iter().enumerate() {
            if n.height == 0 {
                f(LeafId(i as u32), n.user_data, &n.aabb);
            }
        }
    }

    /// Calls `f(leaf, user_data)` for every proxy whose fat box overlaps
    /// `aabb` (touching counts), until `f` returns `false`.
    ///
    /// Determinism: the visit order depends on the tree's shape (which is
    /// itself deterministic); callers that need an order independent of the
    /// shape sort what they collect. Does not allocate unless the tree is
    /// taller than 128 levels.
    pub fn query(&self, aabb: &Aabb, mut f: impl FnMut(LeafId, u64) -> bool) {
        if self.root == NULL {
            return;
        }
        let mut stack = Stack::new();
        stack.push(self.root);
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i as usize];
            if !node.aabb.overlaps(aabb) {
                continue;
            }
            if node.is_leaf() {
                if !f(LeafId(i), node.user_data) {
                    return;
                }
            } else {
                stack.push(node.child2);
                stack.push(node.child1);
            }
        }
    }

    fn check_leaf(&self, id: LeafId) -> Result<(), TreeError> {
        match self.nodes.get(id.0 as usize) {
            Some(n) if n.height == 0 => Ok(()),
            _ => Err(TreeError::InvalidLeaf(id)),
        }
    }

    // Determinism: the free list is LIFO, so which node a call gets depends
    // only on the order of earlier calls.
    fn alloc_node(&mut self) -> u32 {
        if self.free_list != NULL {
            let i = self.free_list;
            self.free_list = self.nodes[i as usize].parent;
            self.nodes[i as usize] = Node::EMPTY;
            i
        } else {
            self.nodes.push(Node::EMPTY);
            (self.nodes.len() - 1) as u32
        }
    }

    fn free_node(&mut self, i: u32) {
        let n = &mut self.nodes[i as usize];
        *n = Node::EMPTY;
        n.parent = self.free_list;
        self.free_list = i;
    }

    /// The best sibling for a new leaf with box `d`: the node whose pairing
    /// with `d` adds the least area to the tree (branch and bound along one
    /// greedy path, as in Box2D v3). Ties keep the earlier candidate; equal
    /// lower bounds descend towards the nearer centre, then child 1.
    fn find_best_sibling(&self, d: &Aabb) -> u32 {
        let area_d = half_area_wide(d);
        let mut index = self.root;
        let root = &self.nodes[index as usize];
        let mut direct = half_area_wide(&root.aabb.union(d));
        let mut inherited: u128 = 0;
        let mut best = index;
        let mut best_cost = direct;
        loop {
            let node = &self.nodes[index as usize];
            if node.is_leaf() {
                break;
            }
            let cost = direct.saturating_add(inherited);
            if cost < best_cost {
                best = index;
                best_cost = cost;
            }
            // Every descendant of `node` pays for its growth too.
            inherited = inherited.saturating_add(direct.saturating_sub(half_area_wide(&node.aabb)));

            let mut lower = [u128::MAX; 2];
            let children = [node.child1, node.child2];
            for (k, &c) in children.iter().enumerate() {
                let child = &self.nodes[c as usize];
                let direct_c = half_area_wide(&child.aabb.union(d));
                if child.is_leaf() {
                    let cost_c = direct_c.saturating_add(inherited);
                    if cost_c < best_cost {
                        best = c;
                        best_cost = cost_c;
                    }
                } else {
                    // Below `child`, the cheapest possible sibling costs the
                    // child's growth plus at least area(d) for the new node.
                    let area_c = half_area_wide(&child.aabb);
                    lower[k] = inherited
                        .saturating_add(direct_c)
                        .saturating_sub(area_c.saturating_sub(area_d));
                }
            }
            if best_cost <= lower[0] && best_cost <= lower[1] {
                break;
            }
            let c1 = &self.nodes[children[0] as usize];
            let c2 = &self.nodes[children[1] as usize];
            let go_first = if lower[0] == lower[1] {
                center_distance(&c1.aabb, d) <= center_distance(&c2.aabb, d)
            } else {
                lower[0] < lower[1]
            };
            let next = if go_first { 0 } else { 1 };
            if lower[next] == u128::MAX {
                break;
            }
            index = children[next];
            direct = half_area_wide(&self.nodes[index as usize].aabb.union(d));
        }
        best
    }

    fn insert_leaf(&mut self, leaf: u32) {
        if self.root == NULL {
            self.root = leaf;
            self.nodes[leaf as usize].parent = NULL;
            return;
        }
        let leaf_box = self.nodes[leaf as usize].aabb;
        let sibling = self.find_best_sibling(&leaf_box);
        let old_parent = self.nodes[sibling as usize].parent;
        let new_parent = self.alloc_node();
        let sib = self.nodes[sibling as usize];
        self.nodes[new_parent as usize] = Node {
            aabb: sib.aabb.union(&leaf_box),
            user_data: 0,
            parent: old_parent,
            child1: sibling,
            child2: leaf,
            height: sib.height + 1,
        };
        self.replace_child(old_parent, sibling, new_parent);
        self.nodes[sibling as usize].parent = new_parent;
        self.nodes[leaf as usize].parent = new_parent;
        // The new parent's box is already exact; it may still rotate.
        self.rotate(new_parent);
        self.refit_upwards(old_parent);
    }

    fn remove_leaf(&mut self, leaf: u32) {
        if leaf == self.root {
            self.root = NULL;
            return;
        }
        let parent = self.nodes[leaf as usize].parent;
        let p = self.nodes[parent as usize];
        let sibling = if p.child1 == leaf { p.child2 } else { p.child1 };
        self.replace_child(p.parent, parent, sibling);
        self.nodes[sibling as usize].parent = p.parent;
        self.free_node(parent);
        if p.parent != NULL {
            self.refit_upwards(p.parent);
        }
    }

    /// Points `parent`'s link to `old` at `new` (or the root, if `parent` is
    /// NULL). Does not touch `new.parent`.
    fn replace_child(&mut self, parent: u32, old: u32, new: u32) {
        if parent == NULL {
            self.root = new;
            return;
        }
        let p = &mut self.nodes[parent as usize];
        if p.child1 == old {
            p.child1 = new;
        } else {
            p.child2 = new;
        }
    }

    /// Refits boxes and heights from `i` towards the root, offering each
    /// node a rotation, and stops at the first node whose box and height
    /// come out unchanged (nothing above it can change either).
    fn refit_upwards(&mut self, mut i: u32) {
        while i != NULL {
            let before = self.nodes[i as usize];
            self.refit(i);
            self.rotate(i);
            let after = &self.nodes[i as usize];
            if after.aabb == before.aabb && after.height == before.height {
                break;
            }
            i = after.parent;
        }
    }

    #[inline]
    fn refit(&mut self, i: u32) {
        let n = self.nodes[i as usize];
        let (a, b) = (
            &self.nodes[n.child1 as usize],
            &self.nodes[n.child2 as usize],
        );
        let aabb = a.aabb.union(&b.aabb);
        let height = 1 + a.height.max(b.height);
        let n = &mut self.nodes[i as usize];
        n.aabb = aabb;
        n.height = height;
    }

    /// Swaps a child of `a` with a grandchild on the other side when that
    /// shrinks the other child's box (the only internal box that changes).
    /// With children B, C and grandchildren C = (F, G), B = (D, E), the
    /// candidates in order are B↔F, B↔G, C↔D, C↔E; the largest strict
    /// decrease wins, the first one on a tie.
    fn rotate(&mut self, a: u32) {
        let node = self.nodes[a as usize];
        let children = [node.child1, node.child2];
        // (down slot in `a`, up slot in the other child, area decrease)
        let mut best: Option<(usize, usize, u128)> = None;
        for down in 0..2 {
            let x = &self.nodes[children[down] as usize];
            let y = &self.nodes[children[down ^ 1] as usize];
            if y.is_leaf() {
                continue;
            }
            let area_y = half_area_wide(&y.aabb);
            let grand = [y.child1, y.child2];
            for up in 0..2 {
                // `x` goes down beside the grandchild that stays.
                let stays = &self.nodes[grand[up ^ 1] as usize];
                let new_area = half_area_wide(&x.aabb.union(&stays.aabb));
                if new_area < area_y {
                    let gain = area_y - new_area;
                    if best.is_none_or(|(_, _, g)| gain > g) {
                        best = Some((down, up, gain));
                    }
                }
            }
        }
        let Some((down, up, _)) = best else { return };
        let x = children[down];
        let y = children[down ^ 1];
        let yn = self.nodes[y as usize];
        let z = if up == 0 { yn.child1 } else { yn.child2 };
        // a.child[down] = z, y.child[up] = x.
        if down == 0 {
            self.nodes[a as usize].child1 = z;
        } else {
            self.nodes[a as usize].child2 = z;
        }
        if up == 0 {
            self.nodes[y as usize].child1 = x;
        } else {
            self.nodes[y as usize].child2 = x;
        }
        self.nodes[z as usize].parent = a;
        self.nodes[x as usize].parent = y;
        self.refit(y);
        // `a` keeps the same leaves, hence the same box; only its height moves.
        let (h1, h2) = (
            self.nodes[self.nodes[a as usize].child1 as usize].height,
            self.nodes[self.nodes[a as usize].child2 as usize].height,
        );
        self.nodes[a as usize].height = 1 + h1.max(h2);
    }
}
