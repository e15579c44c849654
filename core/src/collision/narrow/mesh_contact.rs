//! Convex shapes (sphere, capsule, box, hull) against triangle meshes and
//! height fields.
//!
//! # Pipeline
//! 1. Mid-phase: the convex shape's bounding box in the mesh's frame (grown
//!    by the margin) selects candidate triangles — the mesh's AABB tree
//!    ([`TriMesh::query_triangles`]) or the height field's cell range
//!    ([`HeightField::cell_range`], two triangles per cell, row-major) — in
//!    ascending triangle index. At most [`MAX_MESH_TRIANGLES`] are kept (the
//!    lowest indices); beyond that [`MeshContact::truncated`] is set.
//! 2. Per triangle, in the convex shape's frame: the SAT of
//!    [`triangle`](super::triangle) with one-sided triangles and
//!    internal-edge handling (a normal from an inactive edge or corner
//!    becomes the face normal).
//! 3. Merge into **one** manifold: its normal is the axis of the deepest
//!    triangle contact (largest penetration, lowest triangle index on ties);
//!    when that axis is a face normal it is taken from the mesh's own
//!    triangle normal (so a flat floor gives exactly its normal). Points come
//!    from every triangle whose axis is within about 7° of it (cosine ≥
//!    1 − 2⁻⁷), each with its own depth (at most 256; more set
//!    [`MeshContact::truncated`]). Contacts from triangles facing
//!    other ways (a sphere in a sharp V groove) are dropped for this step:
//!    one manifold, one normal. A flat region acts as one plane: when the
//!    normal is a triangle's face normal and the shape's deepest corner
//!    along it sank under a candidate triangle of the same plane (normals
//!    within the same 7°, planes within 2⁻¹² m) that its own test found
//!    apart (the corner passed under it without the shape crossing that
//!    triangle), the corner joins with its depth below that plane; without
//!    it a deep hull kept only the shallower points of the triangles it
//!    crosses (0.6 mm short at 0.44 m deep in the seeded tests).
//! 4. Reduce to at most four: the deepest point (among those within 2⁻¹² m
//!    of the deepest, the one farthest from the shape's centre across the
//!    normal), the farthest from it, then the points making the largest
//!    positive and negative triangle areas with those two. On a flat face
//!    contact this keeps the corners of the contact polygon, as box–box
//!    does. Of two kept points within 2⁻¹² m of each other (the same corner
//!    seen from two triangles) only the deeper stays.
//!
//! Feature ids: `(triangle index & 0x3ffff) << 14 | label`, the label
//! naming the features inside the triangle contact (see
//! [`triangle`](super::triangle)); ids are unique for meshes of up to 2¹⁸
//! triangles.
//!
//! Mesh–mesh, mesh–height-field and height-field–height-field pairs have
//! no contact function: both shapes are static-only, so such pairs are never
//! created.
//!
//! No allocation: the candidate list, the per-triangle results and the
//! points live in fixed arrays on the stack.

use super::gjk::Rel;
use super::shared::relative_pose;
use super::triangle::{
    Axis, Convex, DeepestCorner, TriPoint, TriSat, Triangle, triangle_points, triangle_sat,
};
use crate::collision::manifold::{ContactPoint, FeatureId, Manifold};
use crate::math::{Aabb, Scalar, Transform, Vec3};
use crate::shape::{Capsule, ConvexHull, Cuboid, HeightField, Shape, Sphere, TriMesh};

/// Most triangles one contact query considers (the lowest indices win).
pub const MAX_MESH_TRIANGLES: usize = 64;

/// Most contact points gathered before the reduction to four.
const MAX_MESH_POINTS: usize = 256;

/// Triangle axes with a cosine to the manifold normal of at least this
/// (1 − 2⁻⁷, about 7.2°) contribute points.
const MERGE_COS: Scalar = Scalar::from_bits((1i64 << 32) - (1i64 << 25));

/// Points closer than this merge; depths within it of the deepest count as
/// equally deep for the reduction.
const MERGE_DIST: Scalar = Scalar::from_bits(1 << 20);

/// The outcome of a mesh or height-field contact beyond the manifold.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MeshContact {
    /// Whether a contact was found (`!out.is_empty()`).
    pub hit: bool,
    /// Triangles the mid-phase selected.
    pub triangles: u32,
    /// Whether some triangles (beyond [`MAX_MESH_TRIANGLES`]) or points
    /// (beyond the gathering buffer) were ignored: the caller can count
    /// these and raise the capacity, as Jolt's "contacts ignored" flag.
    pub truncated: bool,
}

/// Where triangles come from: a mesh or a height field.
trait TriangleSource {
    /// Candidate triangle indices overlapping `aabb` (local frame),
    /// ascending, at most `out.len()`; `(count, truncated)`.
    fn gather(&self, aabb: &Aabb, out: &mut [u64; MAX_MESH_TRIANGLES]) -> (usize, bool);
    /// Corners and unit normal of a triangle (local frame).
    fn corners(&self, t: u64) -> Option<([Vec3; 3], Vec3)>;
    /// Whether edge `k` of triangle `t` is a convex crease.
    fn edge_active(&self, t: u64, k: usize) -> bool;
}

impl TriangleSource for TriMesh {
    fn gather(&self, aabb: &Aabb, out: &mut [u64; MAX_MESH_TRIANGLES]) -> (usize, bool) {
        let mut idx = [0u32; MAX_MESH_TRIANGLES];
        let q = self.query_triangles(aabb, &mut idx);
        for i in 0..q.count {
            out[i] = idx[i] as u64;
        }
        (q.count, q.truncated)
    }

    fn corners(&self, t: u64) -> Option<([Vec3; 3], Vec3)> {
        let c = self.triangle(t as usize)?;
        Some((c, self.normals()[t as usize]))
    }

    fn edge_active(&self, t: u64, k: usize) -> bool {
        TriMesh::edge_active(self, t as usize, k)
    }
}

impl TriangleSource for HeightField {
    fn gather(&self, aabb: &Aabb, out: &mut [u64; MAX_MESH_TRIANGLES]) -> (usize, bool) {
        let Some(([r0, r1], [c0, c1])) = self.cell_range(aabb) else {
            return (0, false);
        };
        let w = self.cols() as u64 - 1;
        let mut n = 0;
        // Determinism: rows, then columns, then the cell's two triangles:
        // ascending triangle index.
        for r in r0..=r1 {
            for c in c0..=c1 {
                for k in 0..2 {
                    let t = 2 * (r as u64 * w + c as u64) + k;
                    let Some(tri) = self.triangle(t) else {
                        continue;
                    };
                    // Cheap vertical reject before the narrow phase.
                    let lo = tri[0].y.min(tri[1].y).min(tri[2].y);
                    let hi = tri[0].y.max(tri[1].y).max(tri[2].y);
                    if hi < aabb.min.y || lo > aabb.max.y {
                        continue;
                    }
                    if n == MAX_MESH_TRIANGLES {
                        return (n, true);
                    }
                    out[n] = t;
                    n += 1;
                }
            }
        }
        (n, false)
    }

    fn corners(&self, t: u64) -> Option<([Vec3; 3], Vec3)> {
        let c = self.triangle(t)?;
        let n = TriMesh::triangle_normal(c[0], c[1], c[2])?;
        Some((c, n))
    }

    fn edge_active(&self, t: u64, k: usize) -> bool {
        HeightField::edge_active(self, t, k)
    }
}

/// The convex shape's bounding box in B's frame.
fn aabb_in(
    shape: &Shape,
    hull: Option<&ConvexHull>,
    pose_a: &Transform,
    pose_b: &Transform,
) -> Aabb {
    let (t, q) = relative_pose(pose_b, pose_a);
    let pose = Transform::new(t, q);
    match hull {
        Some(h) => h.aabb(&pose),
        None => shape.aabb(&pose),
    }
}

/// One gathered point: position (A's frame), depth, id.
#[derive(Clone, Copy, Default)]
struct Gathered {
    p: Vec3,
    depth: Scalar,
    id: u32,
}

/// The shared body of every convex–mesh pair.
#[allow(clippy::too_many_arguments)]
fn contact_convex_source<S: TriangleSource>(
    shape: &Convex,
    aabb_b: Aabb,
    pose_a: &Transform,
    src: &S,
    pose_b: &Transform,
    margin: Scalar,
    out: &mut Manifold,
) -> MeshContact {
    out.clear();
    let mut info = MeshContact::default();
    let query = aabb_b.expanded(margin + Scalar::from_bits(1 << 16));
    let mut cand = [0u64; MAX_MESH_TRIANGLES];
    let (count, truncated) = src.gather(&query, &mut cand);
    info.triangles = count as u32;
    info.truncated = truncated;
    if count == 0 {
        return info;
    }
    let rel = Rel::new(pose_a, pose_b);
    let mut tris = [Triangle {
        v: [Vec3::ZERO; 3],
        n: Vec3::Y,
    }; MAX_MESH_TRIANGLES];
    let mut sats: [Option<TriSat>; MAX_MESH_TRIANGLES] = [None; MAX_MESH_TRIANGLES];
    let mut valid = [false; MAX_MESH_TRIANGLES];
    let mut best: Option<usize> = None;
    for i in 0..count {
        let Some((c, n)) = src.corners(cand[i]) else {
            continue;
        };
        tris[i] = Triangle {
            v: c.map(|p| rel.point(p)),
            n: rel.vector(n),
        };
        valid[i] = true;
        let t = cand[i];
        sats[i] = triangle_sat(shape, &tris[i], margin, |k| src.edge_active(t, k));
        if let Some(s) = sats[i]
            && best.is_none_or(|b| sats[b].is_some_and(|bs| s.sep < bs.sep))
        {
            best = Some(i);
        }
    }
    let Some(bi) = best else {
        return info;
    };
    let Some(bsat) = sats[bi] else {
        return info;
    };
    let axis = bsat.axis;
    let mut pts = [Gathered::default(); MAX_MESH_POINTS];
    let mut np = 0usize;
    for i in 0..count {
        let Some(s) = sats[i] else {
            continue;
        };
        if s.axis.dot(axis) < MERGE_COS {
            continue;
        }
        let tri_id = ((cand[i] & 0x3ffff) as u32) << 14;
        triangle_points(shape, &tris[i], &s, margin, &mut |tp: TriPoint| {
            let g = Gathered {
                p: tp.p,
                depth: tp.depth,
                id: tri_id | (tp.id as u32 & 0x3fff),
            };
            if np < MAX_MESH_POINTS {
                pts[np] = g;
                np += 1;
            } else {
                info.truncated = true;
            }
        });
    }
    if bsat.kind == Axis::TriFace && np < MAX_MESH_POINTS {
        let plane = axis.dot(tris[bi].v[0]);
        let label = |g: &Gathered| g.id & 0x3fff;
        let mut corner: Option<DeepestCorner> = None;
        for i in 0..count {
            // The shape's deepest corner under a nearly coplanar candidate
            // that its own test found apart (the corner sank past the
            // triangles the shape touches): the flat region is one plane.
            if sats[i].is_some()
                || !valid[i]
                || tris[i].n.dot(axis) < MERGE_COS
                || (axis.dot(tris[i].v[0]) - plane).abs() > MERGE_DIST
                || tris[i].n.dot_wide(tris[i].v[0]) > 0
            {
                continue;
            }
            let corner = *corner.get_or_insert_with(|| DeepestCorner::of(shape, axis));
            let Some(tp) = corner.over(&tris[i]) else {
                continue;
            };
            // Known already unless only as a shallower copy (a triangle
            // whose own depth capped it).
            let known = pts[..np]
                .iter()
                .any(|g| label(g) == u32::from(tp.id) && g.depth >= tp.depth);
            if tp.depth >= -margin && !known {
                let tri_id = ((cand[i] & 0x3ffff) as u32) << 14;
                pts[np] = Gathered {
                    p: tp.p,
                    depth: tp.depth,
                    id: tri_id | u32::from(tp.id),
                };
                np += 1;
            }
            break;
        }
    }
    if np == 0 {
        return info;
    }
    let (mut keep, mut nk) = reduce_to_four(&pts[..np], axis);
    keep[..nk].sort_unstable();
    // The same point from two triangles (a shared corner or seam): keep
    // the deeper (the first on ties). Only small sets can keep both, since
    // the reduction otherwise picks distinct extremes.
    let mut i = 0;
    while i < nk {
        let mut dup = false;
        for j in 0..nk {
            let (a, b) = (&pts[keep[i]], &pts[keep[j]]);
            let d = a.p - b.p;
            let near =
                d.x.abs() <= MERGE_DIST && d.y.abs() <= MERGE_DIST && d.z.abs() <= MERGE_DIST;
            if j != i && near && (b.depth > a.depth || (b.depth == a.depth && j < i)) {
                dup = true;
                break;
            }
        }
        if dup {
            keep.copy_within(i + 1..nk, i);
            nk -= 1;
        } else {
            i += 1;
        }
    }
    out.normal = if bsat.kind == Axis::TriFace {
        let (_, n) = src.corners(cand[bi]).unwrap_or(([Vec3::ZERO; 3], Vec3::Y));
        -pose_b.transform_vector(n)
    } else {
        -pose_a.transform_vector(axis)
    };
    for &k in &keep[..nk] {
        let g = pts[k];
        out.push(ContactPoint {
            point: pose_a.transform_point(g.p),
            depth: g.depth,
            id: FeatureId(g.id),
        });
    }
    info.hit = !out.is_empty();
    info
}

/// `((b − a) × (c − a)) · n`, twice the signed area of the triangle seen
/// along `n`.
fn area_along(a: Vec3, b: Vec3, c: Vec3, n: Vec3) -> i128 {
    (b - a).cross(c - a).dot_wide(n)
}

/// The squared distance of `d` across the normal `n` (its part
/// perpendicular to `n`), Q64.64.
fn across_sq(d: Vec3, n: Vec3) -> u128 {
    d.cross(n).length_squared_wide()
}

/// The indices of at most four of `pts` (see the module docs, step 4) and
/// how many.
// Determinism: scans in index order with strict comparisons.
fn reduce_to_four(pts: &[Gathered], n: Vec3) -> ([usize; 4], usize) {
    let len = pts.len();
    if len <= 4 {
        return ([0, 1, 2, 3], len);
    }
    let max_depth = pts.iter().map(|g| g.depth).fold(Scalar::MIN, Scalar::max);
    let mut i0 = usize::MAX;
    let mut best = 0u128;
    for (i, g) in pts.iter().enumerate() {
        if g.depth < max_depth - MERGE_DIST {
            continue;
        }
        let d = across_sq(g.p, n);
        if i0 == usize::MAX || d > best {
            (i0, best) = (i, d);
        }
    }
    let p0 = pts[i0].p;
    let mut i1 = usize::MAX;
    let mut best = 0u128;
    for (i, g) in pts.iter().enumerate() {
        let d = across_sq(g.p - p0, n);
        if i != i0 && (i1 == usize::MAX || d > best) {
            (i1, best) = (i, d);
        }
    }
    let p1 = pts[i1].p;
    let mut keep = [i0, i1, 0, 0];
    let mut count = 2;
    let (mut ip, mut ineg) = (usize::MAX, usize::MAX);
    let (mut bp, mut bn) = (0i128, 0i128);
    for (i, g) in pts.iter().enumerate() {
        if i == i0 || i == i1 {
            continue;
        }
        let a = area_along(p0, p1, g.p, n);
        if a > bp {
            (ip, bp) = (i, a);
        }
        if a < bn {
            (ineg, bn) = (i, a);
        }
    }
    for i in [ip, ineg] {
        if i != usize::MAX {
            keep[count] = i;
            count += 1;
        }
    }
    (keep, count)
}

macro_rules! mesh_pair {
    ($(#[$doc:meta])* $name:ident, $info:ident, $a:ty, $b:ty, $conv:expr, $hull:expr) => {
        $(#[$doc])*
        pub fn $name(
            a: &$a,
            pose_a: &Transform,
            b: &$b,
            pose_b: &Transform,
            margin: Scalar,
            out: &mut Manifold,
        ) -> bool {
            $info(a, pose_a, b, pose_b, margin, out).hit
        }

        /// As the function without `_info`, also returning how many
        /// triangles were considered and whether any were ignored
        /// ([`MeshContact::truncated`]).
        pub fn $info(
            a: &$a,
            pose_a: &Transform,
            b: &$b,
            pose_b: &Transform,
            margin: Scalar,
            out: &mut Manifold,
        ) -> MeshContact {
            let hull: fn(&$a) -> (Shape, Option<&ConvexHull>) = $hull;
            let (shape, h) = hull(a);
            let aabb = aabb_in(&shape, h, pose_a, pose_b);
            contact_convex_source(&$conv(a), aabb, pose_a, b, pose_b, margin, out)
        }
    };
}

mesh_pair!(
    /// Sphere against a triangle mesh (normal from the sphere to the mesh;
    /// see the module docs for the rules).
    contact_sphere_trimesh, contact_sphere_trimesh_info, Sphere, TriMesh,
    Convex::sphere, |s| (Shape::Sphere(*s), None)
);
mesh_pair!(
    /// Capsule against a triangle mesh (a capsule lying along a face gets
    /// two points).
    contact_capsule_trimesh, contact_capsule_trimesh_info, Capsule, TriMesh,
    Convex::capsule, |c| (Shape::Capsule(*c), None)
);
mesh_pair!(
    /// Box against a triangle mesh: a box resting on a flat mesh gets the
    /// same four points as on a box floor.
    contact_box_trimesh, contact_box_trimesh_info, Cuboid, TriMesh,
    Convex::cuboid, |b| (Shape::Cuboid(*b), None)
);
mesh_pair!(
    /// Convex hull against a triangle mesh.
    contact_hull_trimesh, contact_hull_trimesh_info, ConvexHull, TriMesh,
    Convex::hull, |h| (Shape::Sphere(Sphere { radius: Scalar::ZERO }), Some(h))
);
mesh_pair!(
    /// Sphere against a height field.
    contact_sphere_heightfield, contact_sphere_heightfield_info, Sphere, HeightField,
    Convex::sphere, |s| (Shape::Sphere(*s), None)
);
mesh_pair!(
    /// Capsule against a height field.
    contact_capsule_heightfield, contact_capsule_heightfield_info, Capsule, HeightField,
    Convex::capsule, |c| (Shape::Capsule(*c), None)
);
mesh_pair!(
    /// Box against a height field.
    contact_box_heightfield, contact_box_heightfield_info, Cuboid, HeightField,
    Convex::cuboid, |b| (Shape::Cuboid(*b), None)
);
mesh_pair!(
    /// Convex hull against a height field.
    contact_hull_heightfield, contact_hull_heightfield_info, ConvexHull, HeightField,
    Convex::hull, |h| (Shape::Sphere(Sphere { radius: Scalar::ZERO }), Some(h))
);
