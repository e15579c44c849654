//! Ray (segment) traversal of a [`DynamicTree`], and the exact segment–box
//! slab test it rests on.
//!
//! A segment is `origin + t · translation` for `t` in `[0, max]`. Fractions
//! are kept as exact ratios of integers (`num / den`, `den > 0`) of raw
//! Q32.32 bits and compared by cross multiplication in `i128`, so the slab
//! test never divides, never rounds and never raises a fault: the same boxes
//! give the same answer on every machine.

use super::{DynamicTree, LeafId, NULL, Stack};
use crate::math::{Aabb, Scalar, Vec3};

/// An exact fraction `num / den` with `den > 0`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Frac {
    /// Numerator (raw bits of a length, or of a fraction when `den = 2³²`).
    pub num: i128,
    /// Denominator, positive.
    pub den: i128,
}

impl Frac {
    /// The Scalar fraction `f`, exactly.
    pub fn from_scalar(f: Scalar) -> Frac {
        Frac {
            num: f.to_bits() as i128,
            den: 1 << 32,
        }
    }

    /// `self < o`, exactly (products saturate only for operands beyond the
    /// Q32.32 range, where the order is still right in sign).
    #[inline]
    pub fn lt(self, o: Frac) -> bool {
        self.num.saturating_mul(o.den) < o.num.saturating_mul(self.den)
    }
}

/// Where a segment enters a box: the entering fraction and the axis of the
/// entering face (`None` when the origin is inside or on the box: then the
/// fraction is 0).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct SlabHit {
    /// Entering fraction, in `[0, max]`.
    pub enter: Frac,
    /// Axis (0, 1, 2) of the entering face, or `None` from inside.
    pub axis: Option<usize>,
}

/// The exact slab test of the segment `origin + t · translation`,
/// `t ∈ [0, max]`, against the closed box `[lo, hi]`.
///
/// Touching counts (a segment grazing a face or an edge hits it). A
/// component of `translation` that is zero makes that axis a pure
/// inside/outside test of the origin. Ties between axes for the entering
/// face go to the lowest axis.
pub(crate) fn segment_box(
    origin: Vec3,
    translation: Vec3,
    lo: Vec3,
    hi: Vec3,
    max: Frac,
) -> Option<SlabHit> {
    let mut enter = Frac { num: 0, den: 1 };
    let mut axis = None;
    let mut exit = max;
    for k in 0..3 {
        let o = origin.get(k).to_bits() as i128;
        let d = translation.get(k).to_bits() as i128;
        let (l, h) = (lo.get(k).to_bits() as i128, hi.get(k).to_bits() as i128);
        if d == 0 {
            if o < l || o > h {
                return None;
            }
            continue;
        }
        // Sign-normalised so that the denominator is |d|.
        let (near, far) = if d > 0 {
            (Frac { num: l - o, den: d }, Frac { num: h - o, den: d })
        } else {
            (
                Frac {
                    num: o - h,
                    den: -d,
                },
                Frac {
                    num: o - l,
                    den: -d,
                },
            )
        };
        if enter.lt(near) {
            enter = near;
            axis = Some(k);
        }
        if far.lt(exit) {
            exit = far;
        }
        if exit.lt(enter) {
            return None;
        }
    }
    Some(SlabHit { enter, axis })
}

impl DynamicTree {
    /// Visits every proxy whose fat box the segment
    /// `origin + t · translation`, `t ∈ [0, max]`, touches, calling
    /// `f(leaf, user_data, max)` with the current `max`.
    ///
    /// `f` returns `Some(m)` to go on with `max = min(max, m)` (a closest-hit
    /// search clips the segment to its best hit so far, so farther subtrees
    /// are skipped), or `None` to stop. Boxes entered exactly at `max` are
    /// still visited, so a caller that breaks ties between equal fractions
    /// by its own key sees every tied candidate.
    ///
    /// Determinism: the visit order depends on the tree's shape; a caller
    /// whose answer is a minimum over a total order (fraction, then key), or
    /// which sorts what it collects, gets a result independent of it. Does
    /// not allocate unless the tree is taller than 128 levels.
    pub fn ray_cast(
        &self,
        origin: Vec3,
        translation: Vec3,
        max: Scalar,
        f: impl FnMut(LeafId, u64, Scalar) -> Option<Scalar>,
    ) -> Option<Scalar> {
        self.cast(origin, translation, Vec3::ZERO, max, f)
    }

    /// Like [`ray_cast`](Self::ray_cast) for a moving box: visits every
    /// proxy whose fat box the box `start` touches while it moves by
    /// `translation · t`, `t ∈ [0, max]` (each node box is grown by `start`'s
    /// extents and crossed by the segment of its lower corner). For shape
    /// sweeps: `start` is the moving shape's box at the start pose.
    pub fn box_cast(
        &self,
        start: &Aabb,
        translation: Vec3,
        max: Scalar,
        f: impl FnMut(LeafId, u64, Scalar) -> Option<Scalar>,
    ) -> Option<Scalar> {
        let size = start.max - start.min;
        self.cast(start.min, translation, size, max, f)
    }

    /// The traversal: a box of size `size` whose lower corner runs along
    /// the segment from `origin` touches a node box `[lo, hi]` exactly when
    /// the segment touches `[lo − size, hi]` (`size = 0` for a ray).
    fn cast(
        &self,
        origin: Vec3,
        translation: Vec3,
        size: Vec3,
        max: Scalar,
        mut f: impl FnMut(LeafId, u64, Scalar) -> Option<Scalar>,
    ) -> Option<Scalar> {
        let mut max = max;
        if self.root == NULL {
            return Some(max);
        }
        let mut stack = Stack::new();
        stack.push(self.root);
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i as usize];
            let b = &node.aabb;
            if segment_box(
                origin,
                translation,
                b.min - size,
                b.max,
                Frac::from_scalar(max),
            )
            .is_none()
            {
                continue;
            }
            if node.is_leaf() {
                let m = f(LeafId(i), node.user_data, max)?;
                max = max.min(m);
            } else {
                stack.push(node.child2);
                stack.push(node.child1);
            }
        }
        Some(max)
    }

    /// Whether the segment touches `aabb` (the test [`ray_cast`](Self::ray_cast)
    /// applies to each node), for callers that prune their own boxes the
    /// same way.
    #[cfg(test)]
    pub fn segment_touches(origin: Vec3, translation: Vec3, max: Scalar, aabb: &Aabb) -> bool {
        segment_box(
            origin,
            translation,
            aabb.min,
            aabb.max,
            Frac::from_scalar(max),
        )
        .is_some()
    }
}
