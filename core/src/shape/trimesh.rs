//! `TriMesh`: a static triangle soup (level geometry).

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::error::ShapeError;
use super::wide::{BigInt, raw, unit_of_wide};

use crate::collision::dynamic_tree::ray::{Frac, segment_box};
use crate::math::{Aabb, Scalar, Vec3};

/// A triangle mesh for static geometry: terrain pieces, walls, ramps.
///
/// Triangles are one-sided in the sense that each has an outward normal
/// `(b − a) × (c − a)` (counter-clockwise seen from the front), which the
/// collision code uses to push bodies out. The mesh need not be closed, so
/// it has no volume and no mass: bodies carrying one must be static.
///
/// Validated on construction (indices in range, no zero-area triangle), and
/// again when deserialised; the per-triangle unit normals are computed once
/// from the exact cross products.
///
/// Construction also builds what the narrow phase needs, all derived (never
/// serialised, rebuilt on load, so a snapshot cannot carry a stale copy):
/// * a static AABB tree over the triangles (the mid-phase, see
///   [`query_triangles`](Self::query_triangles));
/// * per-triangle "active edge" flags (see
///   [`edge_active`](Self::edge_active)) so contacts on seams between
///   coplanar triangles do not bump.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TriMesh {
    vertices: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
    normals: Vec<Vec3>,
    local_aabb: Aabb,
    nodes: Vec<BvhNode>,
    order: Vec<u32>,
    edge_flags: Vec<u8>,
}

/// Most triangles a leaf of the mesh's AABB tree holds.
const LEAF_SIZE: usize = 4;

/// Deepest traversal stack the query needs: the median split halves the
/// triangle count at each level, so depth ≤ log₂(2³²) + 1.
const QUERY_STACK: usize = 64;

/// Two triangles whose unit normals have a dot product above `1 − 2⁻¹²`
/// (an angle below about 1.27°) count as coplanar: their shared edge is not
/// a feature a body can hit.
pub(crate) const COPLANAR_COS_BITS: i64 = (1i64 << 32) - (1i64 << 20);

/// A node of the mesh's AABB tree: a leaf (`count > 0`) owns
/// `order[start..start + count]`; an inner node's children are the next node
/// and node `start`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct BvhNode {
    aabb: Aabb,
    start: u32,
    count: u32,
}

/// The exact cross product `(b − a) × (c − a)` of raw points, with
/// components up to 2¹²⁹ in magnitude, scaled down (by a power of two,
/// rounded to nearest) when needed so that they fit `i128`; zero exactly when
/// the three points are collinear.
fn exact_normal(a: Vec3, b: Vec3, c: Vec3) -> [i128; 3] {
    let (a, b, c) = (raw(a), raw(b), raw(c));
    let d = |p: [i64; 3], k: usize| p[k] as i128 - a[k] as i128;
    let u = [d(b, 0), d(b, 1), d(b, 2)];
    let v = [d(c, 0), d(c, 1), d(c, 2)];
    let fits = u.iter().chain(&v).all(|x| x.unsigned_abs() < 1 << 62);
    if fits {
        return [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
    }
    // Far-apart vertices: exact on BigInts, then shifted into range.
    let m = |p: i128, q: i128, r: i128, s: i128| {
        BigInt::from_i128(p)
            .mul_i128(q)
            .sub(&BigInt::from_i128(r).mul_i128(s))
    };
    let big = [
        m(u[1], v[2], u[2], v[1]),
        m(u[2], v[0], u[0], v[2]),
        m(u[0], v[1], u[1], v[0]),
    ];
    // |component| < 2¹³¹: shift the largest down to 120 bits (rounded).
    // Smaller components may lose low bits, but the largest stays non-zero,
    // so the result is zero exactly when the exact cross product is.
    let bits = big.iter().map(BigInt::bit_len).max().unwrap_or(0);
    let shift = bits.saturating_sub(120);
    let one = BigInt::from_i64(1);
    big.map(|x| {
        let scaled = if shift == 0 {
            x
        } else {
            x.div_round(&one.shl(shift))
        };
        scaled.to_i128().unwrap_or(0)
    })
}

impl TriMesh {
    /// Whether the edge from `p` shared by a triangle with unit normal `n1` and
    /// a neighbour with unit normal `n2`, whose vertex off the edge is `w`, is a
    /// feature a body can touch: only a convex (outward) crease sharper than the
    /// coplanar threshold is. Flat and concave edges are "inactive": a contact
    /// normal coming from them is replaced by the face normal (no seam bumps).
    pub(crate) fn crease_is_active(n1: Vec3, n2: Vec3, p: Vec3, w: Vec3) -> bool {
        if n1.dot(n2).to_bits() > COPLANAR_COS_BITS {
            return false;
        }
        // Convex: the neighbour's far vertex lies below this triangle's plane.
        n1.dot_wide(w - p) < 0
    }

    /// The unit normal of triangle `a, b, c` (`(b − a) × (c − a)` normalised from
    /// the exact cross product), or `None` for a degenerate triangle.
    pub(crate) fn triangle_normal(a: Vec3, b: Vec3, c: Vec3) -> Option<Vec3> {
        unit_of_wide(exact_normal(a, b, c))
    }

    /// A mesh from a vertex list and triangles indexing into it.
    ///
    /// # Errors
    /// * [`ShapeError::TriMeshEmpty`] with no triangle;
    /// * [`ShapeError::TriMeshIndexOutOfRange`] naming the first triangle
    ///   with an index `≥ vertices.len()`;
    /// * [`ShapeError::TriMeshDegenerateTriangle`] naming the first triangle
    ///   whose corners are collinear (zero area, tested exactly).
    pub fn new(vertices: Vec<Vec3>, indices: Vec<[u32; 3]>) -> Result<TriMesh, ShapeError> {
        if indices.is_empty() {
            return Err(ShapeError::TriMeshEmpty);
        }
        let mut normals = Vec::with_capacity(indices.len());
        for (t, tri) in indices.iter().enumerate() {
            let mut corner = [Vec3::ZERO; 3];
            for (k, &i) in tri.iter().enumerate() {
                corner[k] =
                    *vertices
                        .get(i as usize)
                        .ok_or(ShapeError::TriMeshIndexOutOfRange {
                            triangle: t,
                            index: i,
                            vertex_count: vertices.len(),
                        })?;
            }
            let n = unit_of_wide(exact_normal(corner[0], corner[1], corner[2]))
                .ok_or(ShapeError::TriMeshDegenerateTriangle { triangle: t })?;
            normals.push(n);
        }
        let first = vertices[indices[0][0] as usize];
        let local_aabb = vertices
            .iter()
            .fold(Aabb::new(first, first), |b, &v| b.include_point(v));
        let mut mesh = TriMesh {
            vertices,
            indices,
            normals,
            local_aabb,
            nodes: Vec::new(),
            order: Vec::new(),
            edge_flags: Vec::new(),
        };
        mesh.build_tree();
        mesh.build_edge_flags();
        Ok(mesh)
    }

    /// The box around triangle `t`'s corners.
    fn triangle_aabb(&self, t: usize) -> Aabb {
        let [a, b, c] = self.indices[t].map(|i| self.vertices[i as usize]);
        Aabb::new(a.min(b).min(c), a.max(b).max(c))
    }

    /// Builds the AABB tree top down: each node splits its triangles at the
    /// median of their centroids along the longest axis of the centroids'
    /// box.
    // Determinism: the split orders triangles by the exact centroid sum
    // (i128, no division) and then by index, a total key, so the set in each
    // child — and hence the whole tree — is unique; leaves list their
    // triangles in ascending index.
    fn build_tree(&mut self) {
        let n = self.indices.len();
        let sums: Vec<[i128; 3]> = self
            .indices
            .iter()
            .map(|tri| {
                let mut s = [0i128; 3];
                for &i in tri {
                    let v = raw(self.vertices[i as usize]);
                    for k in 0..3 {
                        s[k] += v[k] as i128;
                    }
                }
                s
            })
            .collect();
        let boxes: Vec<Aabb> = (0..n).map(|t| self.triangle_aabb(t)).collect();
        let mut order: Vec<u32> = (0..n as u32).collect();
        let mut nodes = Vec::with_capacity(2 * n.div_ceil(LEAF_SIZE));
        // Explicit work stack instead of recursion: (node slot, start, end).
        let mut work = vec![(usize::MAX, 0usize, n)];
        while let Some((parent, start, end)) = work.pop() {
            let me = nodes.len();
            if parent != usize::MAX {
                let p: &mut BvhNode = &mut nodes[parent];
                p.start = me as u32;
            }
            let range = &mut order[start..end];
            let aabb = range
                .iter()
                .skip(1)
                .fold(boxes[range[0] as usize], |b, &t| {
                    b.union(&boxes[t as usize])
                });
            if range.len() <= LEAF_SIZE {
                range.sort_unstable();
                nodes.push(BvhNode {
                    aabb,
                    start: start as u32,
                    count: range.len() as u32,
                });
                continue;
            }
            let mut lo = sums[range[0] as usize];
            let mut hi = lo;
            for &t in range.iter() {
                for k in 0..3 {
                    lo[k] = lo[k].min(sums[t as usize][k]);
                    hi[k] = hi[k].max(sums[t as usize][k]);
                }
            }
            let ext = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
            let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
                0
            } else if ext[1] >= ext[2] {
                1
            } else {
                2
            };
            let mid = range.len() / 2;
            range.select_nth_unstable_by_key(mid, |&t| (sums[t as usize][axis], t));
            nodes.push(BvhNode {
                aabb,
                start: 0,
                count: 0,
            });
            // The right child is pushed first so the left one is built next
            // and lands right after its parent.
            work.push((me, start + mid, end));
            work.push((usize::MAX, start, start + mid));
        }
        self.nodes = nodes;
        self.order = order;
    }

    /// Marks each triangle edge active or not (see `crease_is_active`).
    /// Edges are matched by their end positions (not vertex indices), so an
    /// unwelded triangle soup is handled too. An edge with no neighbour (the
    /// mesh border) or more than one (non-manifold) stays active.
    // Determinism: the edge list is sorted by a total key (positions, then
    // triangle and edge number).
    fn build_edge_flags(&mut self) {
        type Key = ([i64; 3], [i64; 3]);
        let mut edges: Vec<(Key, u32, u8)> = Vec::with_capacity(3 * self.indices.len());
        for (t, tri) in self.indices.iter().enumerate() {
            for k in 0..3 {
                let p = raw(self.vertices[tri[k] as usize]);
                let q = raw(self.vertices[tri[(k + 1) % 3] as usize]);
                edges.push(((p.min(q), p.max(q)), t as u32, k as u8));
            }
        }
        edges.sort_unstable();
        let mut flags = vec![0b111u8; self.indices.len()];
        let mut i = 0;
        while i < edges.len() {
            let mut j = i + 1;
            while j < edges.len() && edges[j].0 == edges[i].0 {
                j += 1;
            }
            if j - i == 2 {
                for (me, other) in [(i, i + 1), (i + 1, i)] {
                    let (_, t, k) = edges[me];
                    let (_, u, l) = edges[other];
                    let tri = self.indices[t as usize];
                    let p = self.vertices[tri[k as usize] as usize];
                    let w = self.vertices[self.indices[u as usize][(l as usize + 2) % 3] as usize];
                    let n1 = self.normals[t as usize];
                    let n2 = self.normals[u as usize];
                    if !TriMesh::crease_is_active(n1, n2, p, w) {
                        flags[t as usize] &= !(1 << k);
                    }
                }
            }
            i = j;
        }
        self.edge_flags = flags;
    }

    /// Whether edge `k` of triangle `t` (from corner `k` to corner
    /// `(k + 1) % 3`) is a convex crease a body can hit, computed from the
    /// mesh's adjacency at construction. False for edges between coplanar
    /// (within about 1.27°) or concave neighbours: the narrow phase replaces
    /// a normal from such an edge by the face normal so bodies slide over
    /// seams without bumping. `false` past the end.
    pub fn edge_active(&self, t: usize, k: usize) -> bool {
        self.edge_flags
            .get(t)
            .is_some_and(|f| k < 3 && f & (1 << k) != 0)
    }

    /// The triangles whose bounding box overlaps `aabb` (local frame),
    /// written to `out` in ascending index order: the mid-phase of the
    /// mesh's contacts. Returns how many were written.
    ///
    /// When more than `out.len()` triangles overlap, the `out.len()` lowest
    /// indices are kept (so the answer does not depend on the tree's shape)
    /// and the result's `truncated` is set, for the caller to count.
    ///
    /// Never allocates: the traversal stack is fixed (the tree's depth is
    /// bounded by its median splits).
    pub fn query_triangles(&self, aabb: &Aabb, out: &mut [u32]) -> TriangleQuery {
        let cap = out.len();
        let mut count = 0usize;
        let mut truncated = false;
        if cap == 0 || self.nodes.is_empty() {
            return TriangleQuery {
                count: 0,
                truncated: !self.nodes.is_empty() && self.nodes[0].aabb.overlaps(aabb),
            };
        }
        let mut stack = [0u32; QUERY_STACK];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if !node.aabb.overlaps(aabb) {
                continue;
            }
            if node.count == 0 {
                let me = stack[top];
                if top + 2 > QUERY_STACK {
                    // Cannot happen for median-split trees; stay safe.
                    truncated = true;
                    continue;
                }
                stack[top] = node.start;
                stack[top + 1] = me + 1;
                top += 2;
                continue;
            }
            let s = node.start as usize;
            for &t in &self.order[s..s + node.count as usize] {
                if !self.triangle_aabb(t as usize).overlaps(aabb) {
                    continue;
                }
                if count < cap {
                    out[count] = t;
                    count += 1;
                } else {
                    truncated = true;
                    // Keep the lowest indices: replace the largest kept.
                    let (imax, &vmax) = out
                        .iter()
                        .enumerate()
                        .max_by_key(|&(_, v)| *v)
                        .unwrap_or((0, &0));
                    if t < vmax {
                        out[imax] = t;
                    }
                }
            }
        }
        out[..count].sort_unstable();
        TriangleQuery { count, truncated }
    }

    /// Visits the triangles whose leaf box the segment
    /// `origin + t · translation`, `t ∈ [0, max]`, touches (local frame),
    /// calling `f(triangle, max)` with the current `max`; `f` returns
    /// `Some(m)` to go on with `max = min(max, m)` or `None` to stop.
    ///
    /// Why: a ray cast against a level mesh should cost the depth of the
    /// tree plus the triangles near the ray, not every triangle. A nearest-hit
    /// search clips `max` to its best hit, so subtrees entered beyond it are
    /// skipped; boxes entered exactly at `max` are still visited (touching
    /// counts), so a caller breaking ties by triangle index sees every tie.
    ///
    /// Determinism: nodes are visited near child first (by the exact
    /// entering fraction, the left child on ties); a caller whose answer is
    /// a minimum over a total order gets a result that does not depend on
    /// the visit order. Never allocates (fixed traversal stack).
    pub fn walk_ray(
        &self,
        origin: Vec3,
        translation: Vec3,
        max: Scalar,
        mut f: impl FnMut(usize, Scalar) -> Option<Scalar>,
    ) {
        let mut max = max;
        let enters = |node: &BvhNode, max: Scalar| {
            segment_box(
                origin,
                translation,
                node.aabb.min,
                node.aabb.max,
                Frac::from_scalar(max),
            )
            .map(|h| h.enter)
        };
        if self.nodes.is_empty() || enters(&self.nodes[0], max).is_none() {
            return;
        }
        let mut stack = [0u32; QUERY_STACK];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let i = stack[top];
            let node = &self.nodes[i as usize];
            // Re-test with the clipped max: a hit found since this node was
            // pushed may put it out of reach.
            if enters(node, max).is_none() {
                continue;
            }
            if node.count == 0 {
                let (left, right) = (i + 1, node.start);
                let el = enters(&self.nodes[left as usize], max);
                let er = enters(&self.nodes[right as usize], max);
                // Push the farther child first so the nearer is popped next.
                let order = match (el, er) {
                    (Some(a), Some(b)) if b.lt(a) => [Some(left), Some(right)],
                    (a, b) => [b.map(|_| right), a.map(|_| left)],
                };
                for c in order.into_iter().flatten() {
                    if top < QUERY_STACK {
                        stack[top] = c;
                        top += 1;
                    }
                }
                continue;
            }
            let s = node.start as usize;
            for &t in &self.order[s..s + node.count as usize] {
                match f(t as usize, max) {
                    Some(m) => max = max.min(m),
                    None => return,
                }
            }
        }
    }

    /// The vertex positions.
    pub fn vertices(&self) -> &[Vec3] {
        &self.vertices
    }

    /// The triangles, as indices into [`vertices`](Self::vertices).
    pub fn indices(&self) -> &[[u32; 3]] {
        &self.indices
    }

    /// The unit normal of each triangle, `(b − a) × (c − a)` normalised
    /// (within about an ulp per component of the exact direction).
    pub fn normals(&self) -> &[Vec3] {
        &self.normals
    }

    /// The corners of triangle `t`, or `None` past the end.
    pub fn triangle(&self, t: usize) -> Option<[Vec3; 3]> {
        let tri = self.indices.get(t)?;
        Some(tri.map(|i| self.vertices[i as usize]))
    }

    /// The box around every vertex (referenced or not).
    pub fn local_aabb(&self) -> Aabb {
        self.local_aabb
    }
}

/// What [`TriMesh::query_triangles`] found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TriangleQuery {
    /// How many triangle indices were written.
    pub count: usize,
    /// Whether more triangles overlapped than the buffer holds (the lowest
    /// indices were kept).
    pub truncated: bool,
}

#[derive(Serialize)]
struct TriMeshRef<'a> {
    vertices: &'a [Vec3],
    indices: &'a [[u32; 3]],
}

#[derive(Deserialize)]
struct TriMeshData {
    vertices: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
}

impl Serialize for TriMesh {
    /// Only the vertices and indices: normals and bounds are derived.
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        TriMeshRef {
            vertices: &self.vertices,
            indices: &self.indices,
        }
        .serialize(s)
    }
}

impl<'de> Deserialize<'de> for TriMesh {
    /// Rebuilds (and so re-validates) the mesh.
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<TriMesh, D::Error> {
        let data = TriMeshData::deserialize(d)?;
        TriMesh::new(data.vertices, data.indices).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let v = vec![
            Vec3::from_ints(0, 0, 0),
            Vec3::from_ints(1, 0, 0),
            Vec3::from_ints(1, 0, 1),
            Vec3::from_ints(0, 0, 1),
        ];
        (v, vec![[0, 2, 1], [0, 3, 2]])
    }

    #[test]
    fn floor_quad_has_upward_unit_normals_and_tight_bounds() {
        let (v, i) = quad();
        let m = TriMesh::new(v, i).unwrap();
        assert_eq!(m.normals(), &[Vec3::Y, Vec3::Y]);
        assert_eq!(
            m.local_aabb(),
            Aabb::new(Vec3::ZERO, Vec3::from_ints(1, 0, 1))
        );
        assert_eq!(
            m.triangle(1),
            Some([
                Vec3::ZERO,
                Vec3::from_ints(0, 0, 1),
                Vec3::from_ints(1, 0, 1)
            ])
        );
        assert_eq!(m.triangle(2), None);
    }

    #[test]
    fn mesh_validation_names_the_offending_triangle() {
        let (v, _) = quad();
        assert_eq!(
            TriMesh::new(v.clone(), vec![]),
            Err(ShapeError::TriMeshEmpty)
        );
        let e = TriMesh::new(v.clone(), vec![[0, 2, 1], [0, 4, 2]]).unwrap_err();
        assert_eq!(
            e,
            ShapeError::TriMeshIndexOutOfRange {
                triangle: 1,
                index: 4,
                vertex_count: 4
            }
        );
        assert_eq!(
            e.to_string(),
            "triangle 1 of the mesh uses vertex 4, but there are only 4 vertices"
        );
        // A repeated index and three collinear points both have zero area.
        let e = TriMesh::new(v.clone(), vec![[0, 2, 1], [1, 1, 2]]).unwrap_err();
        assert_eq!(e, ShapeError::TriMeshDegenerateTriangle { triangle: 1 });
        assert_eq!(e.to_string(), "triangle 1 of the mesh has zero area");
        let mut w = v;
        w.push(Vec3::from_ints(2, 0, 2)); // on the line through 0 and 2
        let e = TriMesh::new(w, vec![[0, 2, 1], [0, 3, 2], [0, 2, 4]]).unwrap_err();
        assert_eq!(e, ShapeError::TriMeshDegenerateTriangle { triangle: 2 });
    }

    #[test]
    fn tiny_and_huge_triangles_are_judged_exactly() {
        // A sliver one raw unit high is not degenerate; its normal is exact.
        let d = Scalar::DELTA;
        let v = vec![
            Vec3::ZERO,
            Vec3::new(Scalar::ZERO, Scalar::ZERO, d),
            Vec3::new(d, Scalar::ZERO, Scalar::ZERO),
        ];
        let m = TriMesh::new(v, vec![[0, 1, 2]]).unwrap();
        assert_eq!(m.normals()[0], Vec3::Y);
        // Corners far apart (differences above 2⁶² raw) take the wide path.
        let big = Scalar::from_int(2_000_000_000);
        let v = vec![
            Vec3::new(-big, Scalar::ZERO, -big),
            Vec3::new(-big, Scalar::ZERO, big),
            Vec3::new(big, Scalar::ZERO, -big),
            Vec3::new(big, Scalar::ZERO, big),
        ];
        let m = TriMesh::new(v.clone(), vec![[0, 1, 2]]).unwrap();
        assert_eq!(m.normals()[0], Vec3::Y);
        // Collinear at that scale is still caught.
        let v2 = vec![v[0], Vec3::ZERO, v[3]];
        assert_eq!(
            TriMesh::new(v2, vec![[0, 1, 2]]),
            Err(ShapeError::TriMeshDegenerateTriangle { triangle: 0 })
        );
    }

    #[test]
    fn mesh_survives_a_serde_round_trip_and_rejects_bad_data() {
        let (v, i) = quad();
        let m = TriMesh::new(v.clone(), i).unwrap();
        let cfg = bincode::config::standard();
        let bytes = bincode::serde::encode_to_vec(&m, cfg).unwrap();
        let (back, _): (TriMesh, usize) = bincode::serde::decode_from_slice(&bytes, cfg).unwrap();
        assert_eq!(back, m);
        let bad = TriMeshRef {
            vertices: &v,
            indices: &[[0, 1, 9]],
        };
        let bytes = bincode::serde::encode_to_vec(&bad, cfg).unwrap();
        assert!(bincode::serde::decode_from_slice::<TriMesh, _>(&bytes, cfg).is_err());
    }
}
