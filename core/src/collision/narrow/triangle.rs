//! One convex shape (sphere, capsule, box, hull) against one triangle: the
//! per-triangle step of the mesh and height-field contacts.
//!
//! # Design: SAT with the triangle as a zero-thickness polytope
//!
//! Candidate axes, all oriented from the triangle towards the shape:
//! 1. the triangle's face normal (one-sided: only its front);
//! 2. the shape's face normals (box, hull), reversed;
//! 3. the cross products of each triangle edge with each shape edge (box,
//!    hull, the capsule's segment), each tried in both orientations and
//!    kept only when both edges really support the shapes along it (a
//!    Gauss-map check done on projections);
//! 4. for round shapes (sphere, capsule), the directions from the closest
//!    triangle feature (edge or corner) to the core (the centre, each
//!    segment end, and the segment's closest points to each triangle edge).
//!
//! The separation along a unit axis is `min(shape) − max(triangle)`; the
//! largest wins, faces preferred over edges by [`sat_tolerance`] so resting
//! contacts keep their feature. Why SAT rather than GJK + EPA against the
//! triangle: a triangle has a face, three edges and three corners, so the
//! axis set is small and complete; every decision is a comparison of dot
//! products (no iteration to convergence in fixed point); and the winner
//! names the triangle feature (face, edge, corner) that internal-edge
//! handling needs. Hulls with many edges stay affordable because an edge
//! pair whose own endpoints cannot beat the best separation so far is
//! skipped before the hull's support is computed.
//!
//! # One-sided triangles and internal edges
//!
//! A triangle only pushes towards its front: it is skipped when the shape's
//! centre lies behind its plane (a body that has tunnelled past its centre
//! is CCD's business), and a winning axis pointing into its back half-space
//! is replaced by the face normal. A winning axis that comes from an
//! inactive edge (shared with a coplanar or concave neighbour, see
//! [`TriMesh::edge_active`](crate::shape::trimesh::TriMesh::edge_active)) or from a
//! corner both of whose edges in this triangle are inactive is also
//! replaced by the face normal, so a box sliding over a flat mesh never
//! sees a seam.
//!
//! Everything is in the shape's local frame; the caller maps the triangle
//! in (translation-invariant relative pose) and the results back.
//!
//! This file holds the shape view (`Convex`), the closest-point query and
//! the SAT (`triangle_sat`); the contact points for the axis it picks
//! (clipping, closest points) are made in the child module `points`
//! (`triangle_points`), which reads the shape view's private parts.

use super::segment::{closest_point_on_segment, closest_points_segments};
use super::shared::{BOX_FACE_LOOPS, sat_tolerance};
use crate::math::{Scalar, Vec3};
use crate::shape::{Capsule, ConvexHull, Cuboid, Sphere};

mod points;
pub(crate) use points::{DeepestCorner, TriPoint, triangle_points};

/// Box edges as corner pairs: the four along x, then y, then z, each group
/// ordered by the corner bits of the other two axes.
const BOX_EDGE_LIST: [[u32; 2]; 12] = [
    [0, 1],
    [2, 3],
    [4, 5],
    [6, 7],
    [0, 2],
    [1, 3],
    [4, 6],
    [5, 7],
    [0, 4],
    [1, 5],
    [2, 6],
    [3, 7],
];

/// The box edge along axis `i` that supports the box in direction `d`:
/// index `4i + b₁ + 2b₂` in [`BOX_EDGE_LIST`], with `b₁`, `b₂` set when
/// `d` is not negative on the other two axes (in increasing order).
fn box_edge(i: usize, d: Vec3) -> usize {
    let (j, k) = match i {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    4 * i + (!d.get(j).is_negative()) as usize + 2 * (!d.get(k).is_negative()) as usize
}

fn unit(k: usize) -> Vec3 {
    let mut e = Vec3::ZERO;
    e.set(k, Scalar::ONE);
    e
}

/// The segment of a capsule as an edge list.
const SEGMENT_EDGE: [[u32; 2]; 1] = [[0, 1]];

/// Most vertices a clipped polygon may hold: a hull face of up to
/// `MAX_POLY − 3` corners clipped by a triangle's three side planes (or a
/// triangle clipped by such a face's sides). Larger faces fall back to the
/// single deepest point.
pub const MAX_POLY: usize = 40;

/// Edge cross products shorter than this (squared, Q64.64: sine² below
/// 2⁻²⁰ for unit-ish edges) are skipped: parallel edges are covered by the
/// face axes.
const MIN_AXIS_SQ: u128 = 1 << 44;

/// Round-core directions shorter than 2⁻¹⁶ m (squared, Q64.64) are skipped:
/// the core touches the triangle and the face/edge axes decide.
const MIN_ROUND_SQ: u128 = 1 << 32;

/// How far (2⁻¹⁴ m) an edge's end may sit from the support plane and still
/// count as supporting in the Gauss-map check (covers the rounding of the
/// normalised axis times coordinates up to a few thousand metres).
const SUPPORT_TOL: Scalar = Scalar::from_bits(1 << 18);

/// A convex shape as the triangle SAT sees it, in its own local frame: a
/// core polytope (a point, a segment, a box's or a hull's corners) grown by
/// `radius`, with its faces and edges.
#[derive(Clone, Copy)]
pub(crate) struct Convex<'a> {
    kind: Kind<'a>,
    /// Radius around the core (zero for boxes and hulls).
    pub radius: Scalar,
}

#[derive(Clone, Copy)]
enum Kind<'a> {
    Point,
    Segment([Vec3; 2]),
    Box(Vec3, [Vec3; 8]),
    Hull(&'a ConvexHull),
}

impl<'a> Convex<'a> {
    /// A sphere: its centre grown by the radius.
    pub fn sphere(s: &Sphere) -> Convex<'a> {
        Convex {
            kind: Kind::Point,
            radius: s.radius,
        }
    }

    /// A capsule: its segment grown by the radius.
    pub fn capsule(c: &Capsule) -> Convex<'a> {
        Convex {
            kind: Kind::Segment(c.segment()),
            radius: c.radius,
        }
    }

    /// A box: eight corners, six faces, twelve edges.
    pub fn cuboid(b: &Cuboid) -> Convex<'a> {
        Convex {
            kind: Kind::Box(b.half_extents, b.corners()),
            radius: Scalar::ZERO,
        }
    }

    /// A hull: its vertices, faces and edges.
    pub fn hull(h: &'a ConvexHull) -> Convex<'a> {
        Convex {
            kind: Kind::Hull(h),
            radius: Scalar::ZERO,
        }
    }

    fn vertices(&self) -> &[Vec3] {
        match &self.kind {
            Kind::Point => &[Vec3::ZERO],
            Kind::Segment(s) => s,
            Kind::Box(_, c) => c,
            Kind::Hull(h) => h.vertices(),
        }
    }

    fn face_count(&self) -> usize {
        match &self.kind {
            Kind::Point | Kind::Segment(_) => 0,
            Kind::Box(..) => 6,
            Kind::Hull(h) => h.faces().len(),
        }
    }

    /// Outward unit normal and plane offset of face `f`.
    fn face_plane(&self, f: usize) -> (Vec3, Scalar) {
        match &self.kind {
            Kind::Box(h, _) => {
                let mut n = Vec3::ZERO;
                let s = if f % 2 == 1 {
                    Scalar::ONE
                } else {
                    Scalar::NEG_ONE
                };
                n.set(f / 2, s);
                (n, h.get(f / 2))
            }
            Kind::Hull(h) => (h.faces()[f].normal(), h.faces()[f].offset()),
            _ => (Vec3::Y, Scalar::ZERO),
        }
    }

    fn face_loop(&self, f: usize) -> &[u32] {
        match &self.kind {
            Kind::Box(..) => &BOX_FACE_LOOPS[f],
            Kind::Hull(h) => h.face_vertices(f),
            _ => &[],
        }
    }

    fn edges(&self) -> &[[u32; 2]] {
        match &self.kind {
            Kind::Point => &[],
            Kind::Segment(_) => &SEGMENT_EDGE,
            Kind::Box(..) => &BOX_EDGE_LIST,
            Kind::Hull(h) => h.edges(),
        }
    }

    /// The smallest and largest projection of the core on `d`.
    fn project(&self, d: Vec3) -> (Scalar, Scalar) {
        let vs = self.vertices();
        let first = d.dot(vs[0]);
        vs[1..].iter().fold((first, first), |(lo, hi), &v| {
            let x = d.dot(v);
            (lo.min(x), hi.max(x))
        })
    }
}

/// One triangle in the shape's frame.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Triangle {
    /// Corners, counter-clockwise seen from the front.
    pub v: [Vec3; 3],
    /// Unit front normal.
    pub n: Vec3,
}

impl Triangle {
    fn project(&self, d: Vec3) -> (Scalar, Scalar) {
        let x = [d.dot(self.v[0]), d.dot(self.v[1]), d.dot(self.v[2])];
        (x[0].min(x[1]).min(x[2]), x[0].max(x[1]).max(x[2]))
    }
}

/// Which part of the triangle a contact comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum TriFeature {
    /// The interior.
    Face,
    /// Edge `k`.
    Edge(usize),
    /// Corner `k`.
    Corner(usize),
}

/// The axis the triangle SAT chose.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Axis {
    /// The triangle's face normal.
    TriFace,
    /// Face `f` of the shape.
    ShapeFace(usize),
    /// Triangle edge `k` crossed with shape edge `e`.
    Edge(usize, usize),
    /// From the triangle point `tri` to the core point `core`.
    Round { tri: Vec3, core: Vec3 },
}

/// The per-triangle SAT result, in the shape's frame.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TriSat {
    /// Unit axis from the triangle towards the shape.
    pub axis: Vec3,
    /// Separation along it (negative: penetration).
    pub sep: Scalar,
    /// Which axis.
    pub kind: Axis,
}

/// The closest point of the triangle to `p` and the feature it lies on.
/// Works on the barycentric regions (Ericson's method) with exact `i128`
/// dot products; ties go to the lower-numbered feature.
pub(crate) fn closest_on_triangle(p: Vec3, t: &[Vec3; 3]) -> (Vec3, TriFeature) {
    let (a, b, c) = (t[0], t[1], t[2]);
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let d1 = ab.dot_wide(ap);
    let d2 = ac.dot_wide(ap);
    if d1 <= 0 && d2 <= 0 {
        return (a, TriFeature::Corner(0));
    }
    let bp = p - b;
    let d3 = ab.dot_wide(bp);
    let d4 = ac.dot_wide(bp);
    if d3 >= 0 && d4 <= d3 {
        return (b, TriFeature::Corner(1));
    }
    let cp = p - c;
    let d5 = ab.dot_wide(cp);
    let d6 = ac.dot_wide(cp);
    if d6 >= 0 && d5 <= d6 {
        return (c, TriFeature::Corner(2));
    }
    // Region tests on products of Q64.64 values: shift to keep i128 room.
    let m = |x: i128, y: i128| (x >> 40) * (y >> 40);
    let vc = m(d1, d4) - m(d3, d2);
    if vc <= 0 && d1 >= 0 && d3 <= 0 {
        let (_, q) = closest_point_on_segment(p, a, b);
        return (q, TriFeature::Edge(0));
    }
    let vb = m(d5, d2) - m(d1, d6);
    if vb <= 0 && d2 >= 0 && d6 <= 0 {
        let (_, q) = closest_point_on_segment(p, c, a);
        return (q, TriFeature::Edge(2));
    }
    let va = m(d3, d6) - m(d5, d4);
    if va <= 0 && d4 >= d3 && d5 >= d6 {
        let (_, q) = closest_point_on_segment(p, b, c);
        return (q, TriFeature::Edge(1));
    }
    // Inside: project on the plane.
    let n = (b - a).cross(c - a);
    let nn = n.dot_wide(n);
    let h = n.dot_wide(ap);
    if nn == 0 {
        return (a, TriFeature::Corner(0));
    }
    // p − n·(h / nn), with the ratio taken in one rounding.
    let s = signed_ratio(h, nn);
    (p - n * s, TriFeature::Face)
}

/// `num / den` (den > 0) as a Scalar, rounded, saturating.
fn signed_ratio(num: i128, den: i128) -> Scalar {
    let neg = num < 0;
    let mag = num.unsigned_abs() as i128;
    let (mut n, mut d) = (mag, den);
    let bits = 128 - d.leading_zeros();
    if bits > 90 {
        n >>= bits - 90;
        d >>= bits - 90;
    }
    if d == 0 {
        return Scalar::ZERO;
    }
    let whole = n / d;
    let q = if whole >= 1 << 31 {
        i64::MAX as i128
    } else {
        ((n << 32) + d / 2) / d
    };
    let q = q.min(i64::MAX as i128) as i64;
    Scalar::from_bits(if neg { -q } else { q })
}

/// Whether `u / |l|` (with `u` a Q64.64 dot product along the unnormalised
/// axis `l`, `l2 = |l|²` in Q64.64) is at most `bound`, decided on squares
/// without a square root. Rounding (about 2⁻³² relative) can only matter for
/// an axis that would beat the bound by less than that; the decision is
/// deterministic either way.
fn cannot_beat(u: i128, l2: u128, bound: Scalar) -> bool {
    let u = Scalar::from_wide(u);
    let u2 = u.wide_mul(u);
    let b2 = Scalar::from_wide(bound.wide_mul(bound)).wide_mul(Scalar::from_wide(l2 as i128));
    if bound.is_negative() {
        u.is_negative() && u2 >= b2
    } else {
        !u.is_positive() || u2 <= b2
    }
}

/// Separation of the shape from the triangle along unit `d` (from the
/// triangle towards the shape), with both projection ranges.
fn separation(shape: &Convex, tri: &Triangle, d: Vec3) -> Scalar {
    let (smin, _) = shape.project(d);
    let (_, tmax) = tri.project(d);
    smin - shape.radius - tmax
}

/// The SAT between `shape` and `tri`, or `None` when the shape's centre is
/// behind the triangle or any axis separates them by more than `margin`.
/// Internal-edge handling and the back-side rule are applied (see the
/// module docs), so the result's axis is the one the contact uses.
///
/// `active(k)` tells whether edge `k` (corner `k` to `k + 1`) is a convex
/// crease; it is asked only when an edge or corner wins, so height fields
/// can compute it lazily. A corner keeps its own normal when either of this
/// triangle's edges meeting there is active.
pub(crate) fn triangle_sat(
    shape: &Convex,
    tri: &Triangle,
    margin: Scalar,
    active: impl Fn(usize) -> bool,
) -> Option<TriSat> {
    let n = tri.n;
    // One-sided: the centre (the frame's origin) must be in front.
    if n.dot_wide(tri.v[0]) > 0 {
        return None;
    }
    let face_sep = separation(shape, tri, n);
    if face_sep > margin {
        return None;
    }
    let face = TriSat {
        axis: n,
        sep: face_sep,
        kind: Axis::TriFace,
    };
    let mut best = face;
    // Determinism: triangle face, then shape faces, then edge pairs, then
    // round axes, each in index order with strict comparisons.
    for f in 0..shape.face_count() {
        let (m, d) = shape.face_plane(f);
        let (tmin, _) = tri.project(m);
        let s = tmin - d;
        if s > margin {
            return None;
        }
        if s > best.sep + sat_tolerance(best.sep) {
            best = TriSat {
                axis: -m,
                sep: s,
                kind: Axis::ShapeFace(f),
            };
        }
    }
    let verts = shape.vertices();
    let edges = shape.edges();
    // A box needs one edge per axis: the one supporting it along the axis,
    // picked from the axis's signs once the orientation is known.
    let boxed = matches!(shape.kind, Kind::Box(..));
    let candidates = if boxed { 3 } else { edges.len() };
    for k in 0..3 {
        let (t0, t1, t2) = (tri.v[k], tri.v[(k + 1) % 3], tri.v[(k + 2) % 3]);
        let e = t1 - t0;
        for c in 0..candidates {
            let dir = if boxed {
                unit(c)
            } else {
                let [ia, ib] = edges[c];
                verts[ib as usize] - verts[ia as usize]
            };
            let l = e.cross(dir);
            if l.length_squared_wide() < MIN_AXIS_SQ {
                continue;
            }
            // Orientation: the triangle edge must be the triangle's top
            // along the axis (its third corner not above), an exact sign
            // test; the shape then lies on the axis's positive side.
            let l = if l.dot_wide(t2 - t0) > 0 { -l } else { l };
            let ei = if boxed { box_edge(c, -l) } else { c };
            let va = verts[edges[ei][0] as usize];
            let need = if matches!(best.kind, Axis::Edge(..)) {
                best.sep
            } else {
                best.sep + sat_tolerance(best.sep)
            };
            // Cheap prune before the normalisation: the edge's own
            // projection above the triangle edge bounds the separation.
            if cannot_beat(
                l.dot_wide(va - t0),
                l.length_squared_wide(),
                need + shape.radius,
            ) {
                continue;
            }
            let Some(axis) = l.try_normalize() else {
                continue;
            };
            let tmax = tri.project(axis).1;
            let pa = axis.dot(va);
            // The edge's own projection bounds the separation from above.
            if pa - shape.radius - tmax <= need {
                continue;
            }
            let smin = match shape.kind {
                Kind::Box(h, _) => -Scalar::from_wide(axis.abs().dot_wide(h)),
                _ => shape.project(axis).0,
            };
            let s = smin - shape.radius - tmax;
            if s > margin {
                return None;
            }
            let supporting = boxed || pa - smin <= SUPPORT_TOL;
            if supporting && s > need {
                best = TriSat {
                    axis,
                    sep: s,
                    kind: Axis::Edge(k, ei),
                };
            }
        }
    }
    if shape.radius.is_positive() {
        let round = |core: Vec3, q: Vec3, feature_face: bool, best: &mut TriSat| {
            if feature_face {
                return;
            }
            let d = core - q;
            if d.length_squared_wide() < MIN_ROUND_SQ {
                return;
            }
            let Some(axis) = d.try_normalize() else {
                return;
            };
            let s = separation(shape, tri, axis);
            if s > best.sep {
                *best = TriSat {
                    axis,
                    sep: s,
                    kind: Axis::Round { tri: q, core },
                };
            }
        };
        for &p in verts {
            let (q, f) = closest_on_triangle(p, &tri.v);
            round(p, q, f == TriFeature::Face, &mut best);
        }
        if let Kind::Segment([s0, s1]) = shape.kind {
            for k in 0..3 {
                let cp = closest_points_segments(s0, s1, tri.v[k], tri.v[(k + 1) % 3]);
                round(cp.p1, cp.p2, false, &mut best);
            }
        }
    }
    if best.sep > margin {
        return None;
    }
    // Internal edges and the back side: fall back to the face normal.
    let feature = triangle_feature(tri, &best);
    let keeps = match feature {
        TriFeature::Face => true,
        TriFeature::Edge(k) => active(k),
        TriFeature::Corner(k) => active(k) || active((k + 2) % 3),
    };
    if !keeps || best.axis.dot_wide(n) < 0 {
        // The face normal, but never deeper than the real feature says (a
        // round shape over a concave crease would otherwise get the depth
        // to the extended plane).
        return Some(TriSat {
            sep: face.sep.max(best.sep),
            ..face
        });
    }
    Some(best)
}

/// The triangle feature that realises the chosen axis.
fn triangle_feature(tri: &Triangle, sat: &TriSat) -> TriFeature {
    match sat.kind {
        Axis::TriFace => TriFeature::Face,
        Axis::Edge(k, _) => TriFeature::Edge(k),
        Axis::ShapeFace(_) => {
            // The triangle corners touching the face: one is a corner, two
            // an edge, three the whole face.
            let (_, tmax) = tri.project(sat.axis);
            let on: [bool; 3] =
                std::array::from_fn(|k| tmax - sat.axis.dot(tri.v[k]) <= SUPPORT_TOL);
            match on {
                [true, true, true] => TriFeature::Face,
                [true, true, false] => TriFeature::Edge(0),
                [false, true, true] => TriFeature::Edge(1),
                [true, false, true] => TriFeature::Edge(2),
                [true, false, false] => TriFeature::Corner(0),
                [false, true, false] => TriFeature::Corner(1),
                _ => TriFeature::Corner(2),
            }
        }
        Axis::Round { core, .. } => closest_on_triangle(core, &tri.v).1,
    }
}
