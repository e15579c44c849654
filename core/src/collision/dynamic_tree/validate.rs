//! Structural checks of a [`DynamicTree`], for tests and snapshots.

use super::{DynamicTree, FREE, NULL, TreeError};

impl DynamicTree {
    /// Checks every structural invariant: parent links, heights, exact
    /// enclosing boxes, leaf count, and that live and free nodes partition
    /// the pool. For tests and after deserializing a snapshot.
    ///
    /// # Errors
    /// [`TreeError::Corrupt`] naming the first node where a check fails.
    pub fn validate(&self) -> Result<(), TreeError> {
        let bad = |node: u32, reason: &'static str| Err(TreeError::Corrupt { node, reason });
        let len = self.nodes.len() as u32;
        let mut free = 0u32;
        let mut f = self.free_list;
        while f != NULL {
            if f >= len || self.nodes[f as usize].height != FREE {
                return bad(f, "free list points at a live or missing node");
            }
            free += 1;
            if free > len {
                return bad(f, "free list has a cycle");
            }
            f = self.nodes[f as usize].parent;
        }
        let mut live = 0u32;
        let mut leaves = 0u32;
        if self.root != NULL {
            if self.root >= len || self.nodes[self.root as usize].parent != NULL {
                return bad(self.root, "root has a parent or is missing");
            }
            let mut stack = vec![self.root];
            while let Some(i) = stack.pop() {
                live += 1;
                if live > len {
                    return bad(i, "tree has a cycle");
                }
                let n = &self.nodes[i as usize];
                if n.height == FREE {
                    return bad(i, "reachable node is on the free list");
                }
                if n.is_leaf() {
                    if n.height != 0 || n.child2 != NULL {
                        return bad(i, "leaf with height or second child");
                    }
                    leaves += 1;
                    continue;
                }
                if n.child1 >= len || n.child2 >= len || n.child1 == n.child2 {
                    return bad(i, "bad child index");
                }
                let (a, b) = (
                    &self.nodes[n.child1 as usize],
                    &self.nodes[n.child2 as usize],
                );
                if a.parent != i || b.parent != i {
                    return bad(i, "child's parent link does not point back");
                }
                if a.height == FREE || b.height == FREE {
                    return bad(i, "child is free");
                }
                if n.height != 1 + a.height.max(b.height) {
                    return bad(i, "height is not 1 + max(child heights)");
                }
                if n.aabb != a.aabb.union(&b.aabb) {
                    return bad(i, "box is not the union of the children");
                }
                stack.push(n.child1);
                stack.push(n.child2);
            }
        }
        if leaves != self.leaf_count {
            return bad(self.root, "leaf count mismatch");
        }
        if live + free != len {
            return bad(self.root, "nodes neither reachable nor free");
        }
        Ok(())
    }
}
