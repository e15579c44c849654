//! Quickhull on exact predicates: the polygon faces of the convex hull of a
//! point set.
//!
//! Determinism: the points are sorted (lexicographically on their raw bits)
//! and deduplicated first, every choice below is made by exact comparisons
//! with ties going to the lowest index, and the output is put in a canonical
//! order. The result therefore depends only on the *set* of input points:
//! neither their order nor duplicates nor points inside (or on the boundary
//! of) the hull change a single bit.
//!
//! Robustness: every geometric decision is the exact sign of an orientation
//! determinant ([`orient3d`]), so there is no tolerance to tune. A point is
//! added only when it lies strictly outside a face; coplanar neighbouring
//! triangles are merged into polygons afterwards, and vertices that ended up
//! in the middle of a face or of an edge are dropped.

use super::error::ShapeError;
use super::wide::{RawPoint, Wide192, cross, orient3d, sub};

const NONE: u32 = u32::MAX;

/// The hull as polygons over its own vertex list.
pub(super) struct Polytope {
    /// The hull's vertices (exactly the extreme input points), sorted
    /// lexicographically by raw coordinates.
    pub vertices: Vec<RawPoint>,
    /// The faces: vertex indices counter-clockwise seen from outside, the
    /// smallest index first; faces sorted by their index lists.
    pub faces: Vec<Vec<u32>>,
}

/// A triangle of the hull under construction.
struct Face {
    /// Corners, counter-clockwise seen from outside.
    v: [u32; 3],
    /// `nbr[i]` is the face across the edge `v[i] → v[i + 1]`.
    nbr: [u32; 3],
    /// Points strictly above this face and assigned to it.
    outside: Vec<u32>,
    alive: bool,
}

struct Builder<'a> {
    pts: &'a [RawPoint],
    faces: Vec<Face>,
    /// Per face: the round in which it was last classified, and whether it
    /// was visible then.
    stamp: Vec<u32>,
    visible: Vec<bool>,
    round: u32,
}

fn internal(what: &'static str) -> ShapeError {
    ShapeError::HullConstruction(what)
}

/// Builds the hull polygons of `input` (coordinates within ±2⁵² raw).
///
/// # Errors
/// [`ShapeError::DegenerateHull`] when the distinct points do not span
/// three dimensions; [`ShapeError::HullConstruction`] if an internal
/// consistency check fails (a bug).
pub(super) fn build(input: &[RawPoint]) -> Result<Polytope, ShapeError> {
    let mut pts = input.to_vec();
    pts.sort_unstable();
    pts.dedup();
    let n = pts.len();
    let degenerate = |dimension: u8| ShapeError::DegenerateHull {
        distinct_points: n,
        dimension,
    };
    if n < 2 {
        return Err(degenerate(0));
    }
    if n > NONE as usize / 2 {
        return Err(internal("too many points"));
    }
    // The initial tetrahedron: the lexicographic extremes, then the point
    // farthest (in L1 norm of the cross product) from their line, then the
    // point farthest from that plane. Ties: lowest index.
    let (i0, i1) = (0usize, n - 1);
    let axis = sub(pts[i1], pts[i0]);
    let mut i2 = None;
    let mut best = 0u128;
    for (i, &p) in pts.iter().enumerate().take(n - 1).skip(1) {
        let c = cross(axis, sub(p, pts[i0]));
        let l1 = c.iter().map(|x| x.unsigned_abs()).sum::<u128>();
        if l1 > best {
            best = l1;
            i2 = Some(i);
        }
    }
    let i2 = i2.ok_or_else(|| degenerate(1))?;
    let mut i3 = None;
    let mut best = Wide192::ZERO;
    for (i, &p) in pts.iter().enumerate() {
        let d = orient3d(pts[i0], pts[i1], pts[i2], p).abs();
        if d > best {
            best = d;
            i3 = Some(i);
        }
    }
    let i3 = i3.ok_or_else(|| degenerate(2))?;

    let mut b = Builder {
        pts: &pts,
        faces: Vec::new(),
        stamp: Vec::new(),
        visible: Vec::new(),
        round: 0,
    };
    b.start([i0 as u32, i1 as u32, i2 as u32, i3 as u32])?;
    let simplex = [i0, i1, i2, i3];
    for p in (0..n).filter(|p| !simplex.contains(p)) {
        b.assign(p as u32, 0..4);
    }
    // Determinism: faces are processed in creation order; new faces are
    // appended, and points are only ever assigned to new faces, so one
    // forward sweep visits every face that still has outside points.
    let mut cursor = 0;
    while cursor < b.faces.len() {
        if !b.faces[cursor].alive || b.faces[cursor].outside.is_empty() {
            cursor += 1;
            continue;
        }
        let eye = b.farthest(cursor);
        b.add_point(cursor, eye)?;
    }
    b.polytope()
}

impl Builder<'_> {
    fn orient(&self, f: usize, p: u32) -> Wide192 {
        let v = self.faces[f].v;
        let q = |i: u32| self.pts[i as usize];
        orient3d(q(v[0]), q(v[1]), q(v[2]), q(p))
    }

    /// Whether `p` is strictly outside face `f`.
    fn above(&self, f: usize, p: u32) -> bool {
        self.orient(f, p).is_positive()
    }

    fn push_face(&mut self, v: [u32; 3], nbr: [u32; 3]) -> u32 {
        let id = self.faces.len() as u32;
        self.faces.push(Face {
            v,
            nbr,
            outside: Vec::new(),
            alive: true,
        });
        self.stamp.push(0);
        self.visible.push(false);
        id
    }

    /// The four outward-facing triangles of a (non-flat) tetrahedron.
    fn start(&mut self, t: [u32; 4]) -> Result<(), ShapeError> {
        for skip in 0..4 {
            let mut tri: Vec<u32> = (0..4).filter(|&k| k != skip).map(|k| t[k]).collect();
            let probe = orient3d(
                self.pts[tri[0] as usize],
                self.pts[tri[1] as usize],
                self.pts[tri[2] as usize],
                self.pts[t[skip] as usize],
            );
            if probe.is_positive() {
                tri.swap(1, 2);
            }
            self.push_face([tri[0], tri[1], tri[2]], [NONE; 3]);
        }
        for f in 0..4 {
            for e in 0..3 {
                let (a, b) = (self.faces[f].v[e], self.faces[f].v[(e + 1) % 3]);
                let g = (0..4)
                    .find(|&g| {
                        (0..3).any(|j| self.faces[g].v[j] == b && self.faces[g].v[(j + 1) % 3] == a)
                    })
                    .ok_or(internal("tetrahedron edges do not pair up"))?;
                self.faces[f].nbr[e] = g as u32;
            }
        }
        Ok(())
    }

    /// Gives `p` to the first face of `faces` it lies strictly outside; a
    /// point outside none of them is inside the hull and is dropped.
    fn assign(&mut self, p: u32, faces: std::ops::Range<usize>) {
        for f in faces {
            if self.above(f, p) {
                self.faces[f].outside.push(p);
                return;
            }
        }
    }

    /// The outside point of `f` farthest from its plane (largest exact
    /// orientation; ties to the lowest index).
    fn farthest(&self, f: usize) -> u32 {
        let out = &self.faces[f].outside;
        let mut best = out[0];
        let mut best_d = self.orient(f, best);
        for &p in &out[1..] {
            let d = self.orient(f, p);
            if d > best_d || (d == best_d && p < best) {
                best = p;
                best_d = d;
            }
        }
        best
    }

    /// Adds `eye` (strictly outside face `f0`): removes every face it sees,
    /// fans new faces from the horizon to it and hands the orphaned outside
    /// points to the new faces.
    fn add_point(&mut self, f0: usize, eye: u32) -> Result<(), ShapeError> {
        self.round += 1;
        let round = self.round;
        let mut visible = vec![f0];
        self.stamp[f0] = round;
        self.visible[f0] = true;
        // Horizon edges (a → b as in the visible face) and the hidden face
        // across each.
        let mut horizon: Vec<(u32, u32, u32)> = Vec::new();
        let mut k = 0;
        // Determinism: breadth-first in neighbour order from `f0`.
        while k < visible.len() {
            let f = visible[k];
            k += 1;
            for e in 0..3 {
                let g = self.faces[f].nbr[e] as usize;
                if self.stamp[g] != round {
                    self.stamp[g] = round;
                    let seen = self.above(g, eye);
                    self.visible[g] = seen;
                    if seen {
                        visible.push(g);
                    }
                }
                if !self.visible[g] {
                    let v = self.faces[f].v;
                    horizon.push((v[e], v[(e + 1) % 3], g as u32));
                }
            }
        }
        if horizon.len() < 3 {
            return Err(internal("horizon has fewer than three edges"));
        }
        let base = self.faces.len();
        for &(a, b, g) in &horizon {
            let id = self.faces.len() as u32;
            let hidden = &mut self.faces[g as usize];
            let j = (0..3)
                .find(|&j| hidden.v[j] == b && hidden.v[(j + 1) % 3] == a)
                .ok_or(internal("horizon edge missing from the hidden face"))?;
            hidden.nbr[j] = id;
            self.push_face([a, b, eye], [g, NONE, NONE]);
        }
        // Link the cone: the face (a, b, eye) meets (b, c, eye) along b–eye.
        let mut starts: Vec<(u32, u32)> = (base..self.faces.len())
            .map(|f| (self.faces[f].v[0], f as u32))
            .collect();
        starts.sort_unstable();
        if starts.windows(2).any(|w| w[0].0 == w[1].0) {
            return Err(internal("horizon is not a simple cycle"));
        }
        for f in base..self.faces.len() {
            let b = self.faces[f].v[1];
            let i = starts
                .binary_search_by_key(&b, |&(s, _)| s)
                .map_err(|_| internal("horizon is not closed"))?;
            let next = starts[i].1;
            self.faces[f].nbr[1] = next;
            self.faces[next as usize].nbr[2] = f as u32;
        }
        let mut orphans = Vec::new();
        for &f in &visible {
            self.faces[f].alive = false;
            orphans.append(&mut self.faces[f].outside);
        }
        let end = self.faces.len();
        for p in orphans {
            if p != eye {
                self.assign(p, base..end);
            }
        }
        Ok(())
    }

    /// Whether the neighbouring triangles `f` and `g` lie in one plane.
    fn coplanar(&self, f: usize, g: usize) -> bool {
        let fv = self.faces[f].v;
        match self.faces[g].v.iter().find(|x| !fv.contains(x)) {
            Some(&apex) => self.orient(f, apex) == Wide192::ZERO,
            None => true,
        }
    }

    /// Merges coplanar triangles into polygons, drops vertices that are not
    /// corners, and puts everything in canonical order.
    fn polytope(&self) -> Result<Polytope, ShapeError> {
        let nf = self.faces.len();
        let mut group = vec![NONE; nf];
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for f in (0..nf).filter(|&f| self.faces[f].alive) {
            if group[f] != NONE {
                continue;
            }
            let gid = groups.len() as u32;
            group[f] = gid;
            let mut members = vec![f];
            let mut k = 0;
            while k < members.len() {
                let h = members[k];
                k += 1;
                for e in 0..3 {
                    let g = self.faces[h].nbr[e] as usize;
                    if group[g] == NONE && self.coplanar(h, g) {
                        group[g] = gid;
                        members.push(g);
                    }
                }
            }
            groups.push(members);
        }
        let mut polys: Vec<Vec<u32>> = Vec::with_capacity(groups.len());
        for (gid, members) in groups.iter().enumerate() {
            let mut edges: Vec<(u32, u32)> = Vec::new();
            for &h in members {
                let f = &self.faces[h];
                for e in 0..3 {
                    if group[f.nbr[e] as usize] != gid as u32 {
                        edges.push((f.v[e], f.v[(e + 1) % 3]));
                    }
                }
            }
            edges.sort_unstable();
            if edges.len() < 3 || edges.windows(2).any(|w| w[0].0 == w[1].0) {
                return Err(internal("face boundary is not a simple cycle"));
            }
            let first = edges[0].0;
            let mut cycle = vec![first];
            let mut cur = edges[0].1;
            while cur != first {
                if cycle.len() >= edges.len() {
                    return Err(internal("face boundary does not close"));
                }
                cycle.push(cur);
                let i = edges
                    .binary_search_by_key(&cur, |&(s, _)| s)
                    .map_err(|_| internal("face boundary is broken"))?;
                cur = edges[i].1;
            }
            if cycle.len() != edges.len() {
                return Err(internal("face boundary has more than one cycle"));
            }
            // Keep the corners: drop vertices in the middle of a straight
            // run of the boundary.
            let k = cycle.len();
            let p = |i: usize| self.pts[cycle[i % k] as usize];
            let corners: Vec<u32> = (0..k)
                .filter(|&i| cross(sub(p(i), p(i + k - 1)), sub(p(i + 1), p(i))) != [0; 3])
                .map(|i| cycle[i])
                .collect();
            if corners.len() < 3 {
                return Err(internal("face has fewer than three corners"));
            }
            polys.push(corners);
        }
        // Keep only vertices that are corners of some face, in their
        // (lexicographic) order.
        let mut used = vec![false; self.pts.len()];
        for poly in &polys {
            for &v in poly {
                used[v as usize] = true;
            }
        }
        let mut remap = vec![NONE; self.pts.len()];
        let mut vertices = Vec::new();
        for (i, _) in used.iter().enumerate().filter(|(_, u)| **u) {
            remap[i] = vertices.len() as u32;
            vertices.push(self.pts[i]);
        }
        for poly in &mut polys {
            for v in poly.iter_mut() {
                *v = remap[*v as usize];
            }
            let min_at = (0..poly.len()).min_by_key(|&i| poly[i]).unwrap_or(0);
            poly.rotate_left(min_at);
        }
        polys.sort_unstable();
        let edge_count: usize = polys.iter().map(Vec::len).sum::<usize>() / 2;
        if vertices.len() + polys.len() != edge_count + 2 {
            return Err(internal("Euler characteristic is not 2"));
        }
        Ok(Polytope {
            vertices,
            faces: polys,
        })
    }
}
