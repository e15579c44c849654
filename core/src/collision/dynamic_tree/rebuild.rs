//! The full rebuild of a [`DynamicTree`]: top-down, binned SAH.

use super::{DynamicTree, FREE, NULL, center2, half_area_wide};
use crate::math::Aabb;

/// Number of bins of the binned SAH rebuild.
const BINS: usize = 16;

/// A work item of the top-down rebuild: leaves `[start, end)` of the scratch
/// list become the subtree hanging from `parent` (`slot` 0/1, or the root).
#[derive(Clone, Copy, Debug)]
struct BuildTask {
    start: u32,
    end: u32,
    parent: u32,
    slot: u8,
}

/// Reused buffers of [`DynamicTree::rebuild`].
#[derive(Clone, Debug, Default)]
pub(super) struct RebuildScratch {
    leaves: Vec<u32>,
    tasks: Vec<BuildTask>,
    order: Vec<u32>,
}

impl DynamicTree {
    /// Rebuilds the whole tree top-down with a binned SAH (16 bins on the
    /// longest axis of the leaf centres), keeping every leaf's id, box and
    /// user data. Queries give the same sets before and after; only the
    /// shape (and so the cost of queries) changes.
    ///
    /// Determinism: leaves are gathered in node-index order, bins are
    /// computed with integer arithmetic, ties pick the lowest axis and the
    /// lowest split, and internal nodes come off the free list in a fixed
    /// order. Allocates only the first time (scratch buffers are kept).
    pub fn rebuild(&mut self) {
        let mut s = std::mem::take(&mut self.scratch);
        s.leaves.clear();
        for i in 0..self.nodes.len() {
            let n = &self.nodes[i];
            if n.height == FREE {
                continue;
            }
            if n.is_leaf() {
                s.leaves.push(i as u32);
            } else {
                self.free_node(i as u32);
            }
        }
        self.root = NULL;
        if s.leaves.is_empty() {
            self.scratch = s;
            return;
        }
        s.tasks.clear();
        s.tasks.push(BuildTask {
            start: 0,
            end: s.leaves.len() as u32,
            parent: NULL,
            slot: 2,
        });
        while let Some(t) = s.tasks.pop() {
            let node = if t.end - t.start == 1 {
                s.leaves[t.start as usize]
            } else {
                let (mid, bounds) = self.split(&mut s.leaves[t.start as usize..t.end as usize]);
                let idx = self.alloc_node();
                let n = &mut self.nodes[idx as usize];
                n.aabb = bounds;
                n.height = 1; // fixed below
                let mid = t.start + mid;
                s.tasks.push(BuildTask {
                    start: mid,
                    end: t.end,
                    parent: idx,
                    slot: 1,
                });
                s.tasks.push(BuildTask {
                    start: t.start,
                    end: mid,
                    parent: idx,
                    slot: 0,
                });
                idx
            };
            self.nodes[node as usize].parent = t.parent;
            match t.slot {
                0 => self.nodes[t.parent as usize].child1 = node,
                1 => self.nodes[t.parent as usize].child2 = node,
                _ => self.root = node,
            }
        }
        // Heights bottom-up: children come after their parent in pre-order.
        s.order.clear();
        s.order.push(self.root);
        let mut k = 0;
        while k < s.order.len() {
            let n = self.nodes[s.order[k] as usize];
            if !n.is_leaf() {
                s.order.push(n.child1);
                s.order.push(n.child2);
            }
            k += 1;
        }
        for &i in s.order.iter().rev() {
            if !self.nodes[i as usize].is_leaf() {
                self.refit(i);
            }
        }
        self.scratch = s;
    }

    /// Partitions `leaves` (at least two) by the best binned-SAH split and
    /// returns the size of the first part (1..len) and the union of all
    /// their boxes.
    fn split(&self, leaves: &mut [u32]) -> (u32, Aabb) {
        let n = leaves.len();
        let first = &self.nodes[leaves[0] as usize].aabb;
        let mut bounds = *first;
        let mut cmin = center2(first);
        let mut cmax = cmin;
        for &l in leaves.iter() {
            let b = &self.nodes[l as usize].aabb;
            bounds = bounds.union(b);
            let c = center2(b);
            for ax in 0..3 {
                cmin[ax] = cmin[ax].min(c[ax]);
                cmax[ax] = cmax[ax].max(c[ax]);
            }
        }
        let mut axis = 0;
        for ax in 1..3 {
            if cmax[ax] - cmin[ax] > cmax[axis] - cmin[axis] {
                axis = ax;
            }
        }
        let extent = cmax[axis] - cmin[axis];
        let median = ((n / 2) as u32, bounds);
        if extent == 0 {
            return median;
        }
        let bin_of = |l: u32| -> usize {
            let c = center2(&self.nodes[l as usize].aabb)[axis];
            (((c - cmin[axis]) * BINS as i128) / (extent + 1)) as usize
        };
        let mut counts = [0u32; BINS];
        let mut boxes = [Aabb::default(); BINS];
        for &l in leaves.iter() {
            let b = bin_of(l);
            let aabb = &self.nodes[l as usize].aabb;
            boxes[b] = if counts[b] == 0 {
                *aabb
            } else {
                boxes[b].union(aabb)
            };
            counts[b] += 1;
        }
        // Left sweep: area and count of bins 0..=k.
        let mut left_cost = [0u128; BINS];
        let mut acc: Option<Aabb> = None;
        let mut count = 0u128;
        for k in 0..BINS - 1 {
            if counts[k] > 0 {
                acc = Some(acc.map_or(boxes[k], |a| a.union(&boxes[k])));
                count += counts[k] as u128;
            }
            left_cost[k] = acc.map_or(0, |a| half_area_wide(&a).saturating_mul(count));
        }
        // Right sweep; split k puts bins 0..=k left.
        let mut best: Option<(usize, u128)> = None;
        let mut acc: Option<Aabb> = None;
        let mut right = 0u128;
        let mut left = n as u128;
        for k in (0..BINS - 1).rev() {
            let b = k + 1;
            if counts[b] > 0 {
                acc = Some(acc.map_or(boxes[b], |a| a.union(&boxes[b])));
                right += counts[b] as u128;
                left -= counts[b] as u128;
            }
            if right == 0 || left == 0 {
                continue;
            }
            let cost = acc.map_or(0, |a| half_area_wide(&a).saturating_mul(right));
            let cost = cost.saturating_add(left_cost[k]);
            // `<=` while sweeping downwards keeps the lowest split on ties.
            if best.is_none_or(|(_, c)| cost <= c) {
                best = Some((k, cost));
            }
        }
        let Some((k, _)) = best else { return median };
        let (mut i, mut j) = (0usize, n);
        while i < j {
            if bin_of(leaves[i]) <= k {
                i += 1;
            } else {
                j -= 1;
                leaves.swap(i, j);
            }
        }
        if i == 0 || i == n {
            return median;
        }
        (i as u32, bounds)
    }
}
