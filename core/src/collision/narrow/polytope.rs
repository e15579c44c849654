//! The separating axis test between two convex polyhedra, with
//! reference-face clipping: the machinery behind box–hull and hull–hull
//! contacts ([`hull_contact`](super::hull_contact) holds those entry
//! points). It lives apart from them because it knows nothing of any shape
//! kind: a box and a hull both enter through the [`Poly`] view.
//!
//! # Design: SAT with Gauss-map pruning
//!
//! The test runs over the face normals of both shapes and the edge–edge
//! axes, then clips the incident face against the reference face (as
//! box–box does), keeping at most four points. The box is viewed as an
//! 8-vertex, 6-face, 12-edge polyhedron so one routine serves both pairs.
//! Why SAT rather than GJK + EPA:
//! * robustness in fixed point: every decision is a sign or a comparison of
//!   exact `i128` dot products against planes the hull already carries;
//!   nothing iterates to convergence, so there is no cycling, no tolerance
//!   tuning per scale, and touching or deeply overlapping shapes are handled
//!   by the same code;
//! * stable features: the winning axis *is* a face or an edge pair, which
//!   gives the clipping its reference face and the points their feature ids
//!   directly (EPA's triangulated faces would need a second search);
//! * cost: faces are `O(F·V)`; edge pairs are pruned by the Gauss-map
//!   (Minkowski face) test, `O(1)` each, so only pairs that can realise the
//!   separation compute an axis. For hulls of a few dozen vertices this is
//!   cheaper than EPA's expansion with its normalisations.
//!
//! The test works on stack buffers for hulls of up to [`MAX_SAT_VERTICES`]
//! vertices (hence at most 252 faces and 378 edges); the callers send
//! larger hulls elsewhere. Everything is in A's frame; ties go to the
//! lowest face/edge index. Feature ids of the points made here:
//! * clipped face contacts: `pair(reference, incident)` with the reference
//!   face index (bit 15 set when B holds the reference face) and the
//!   incident vertex index, or for a point cut by a reference side plane,
//!   `0x8000 | side << 7 | (low 7 bits of the cut edge's start id)`; the
//!   deep-overlap fallback point uses the deepest incident vertex index;
//! * edge–edge: `pair(0x4000 | edge of A, 0x4000 | edge of B)`.

use super::BOX_FACE_LOOPS;
use super::gjk::{ONE_Q62, Rel, cross_wide, fit, q62, unit_from_wide};
use crate::collision::{ContactPoint, FeatureId, Manifold};
use crate::math::scalar::round_shift;
use crate::math::{Scalar, Transform, Vec3};
use crate::shape::{ConvexHull, Cuboid};

/// Largest hull (in vertices) the SAT path handles; bigger hulls use GJK +
/// EPA with a single point.
pub const MAX_SAT_VERTICES: usize = 128;
const MAX_SAT_FACES: usize = 2 * MAX_SAT_VERTICES - 4;
const MAX_SAT_EDGES: usize = 3 * MAX_SAT_VERTICES - 6;
/// Room for a clipped polygon: an incident face grows by at most one point
/// per reference side.
const CLIP_CAP: usize = 2 * MAX_SAT_VERTICES;

/// A face axis beats an edge axis, and A's face beats B's, unless the other
/// separates by more than `1/1024 m + |separation|/32`: stacks then keep
/// their face contacts instead of flickering to edges.
pub(super) fn feature_tolerance(sep: Scalar) -> Scalar {
    Scalar::from_bits(1 << 22) + Scalar::from_bits(sep.to_bits().abs() >> 5)
}

/// The polyhedron view that SAT and clipping need.
pub(super) trait Poly {
    fn nv(&self) -> usize;
    fn vertex(&self, i: usize) -> Vec3;
    fn nf(&self) -> usize;
    fn normal(&self, f: usize) -> Vec3;
    fn offset(&self, f: usize) -> Scalar;
    fn face(&self, f: usize) -> &[u32];
    fn edges(&self) -> &[[u32; 2]];
}

/// A box as a polyhedron: corners by index bits (bit 0: +x, bit 1: +y,
/// bit 2: +z), faces −x +x −y +y −z +z counter-clockwise from outside.
pub(super) struct BoxPoly {
    corners: [Vec3; 8],
    half: Vec3,
}

const BOX_EDGES: [[u32; 2]; 12] = [
    [0, 1],
    [0, 2],
    [0, 4],
    [1, 3],
    [1, 5],
    [2, 3],
    [2, 6],
    [3, 7],
    [4, 5],
    [4, 6],
    [5, 7],
    [6, 7],
];

impl BoxPoly {
    pub(super) fn new(c: &Cuboid) -> BoxPoly {
        BoxPoly {
            corners: c.corners(),
            half: c.half_extents,
        }
    }
}

impl Poly for BoxPoly {
    fn nv(&self) -> usize {
        8
    }
    fn vertex(&self, i: usize) -> Vec3 {
        self.corners[i]
    }
    fn nf(&self) -> usize {
        6
    }
    fn normal(&self, f: usize) -> Vec3 {
        let mut n = Vec3::ZERO;
        n.set(
            f / 2,
            if f % 2 == 1 {
                Scalar::ONE
            } else {
                Scalar::NEG_ONE
            },
        );
        n
    }
    fn offset(&self, f: usize) -> Scalar {
        self.half.get(f / 2)
    }
    fn face(&self, f: usize) -> &[u32] {
        &BOX_FACE_LOOPS[f]
    }
    fn edges(&self) -> &[[u32; 2]] {
        &BOX_EDGES
    }
}

impl Poly for ConvexHull {
    fn nv(&self) -> usize {
        self.vertices().len()
    }
    fn vertex(&self, i: usize) -> Vec3 {
        self.vertices()[i]
    }
    fn nf(&self) -> usize {
        self.faces().len()
    }
    fn normal(&self, f: usize) -> Vec3 {
        self.faces()[f].normal()
    }
    fn offset(&self, f: usize) -> Scalar {
        self.faces()[f].offset()
    }
    fn face(&self, f: usize) -> &[u32] {
        self.face_vertices(f)
    }
    fn edges(&self) -> &[[u32; 2]] {
        ConvexHull::edges(self)
    }
}

/// A polyhedron expressed in A's frame, in fixed buffers.
struct Posed<'p, P: Poly> {
    p: &'p P,
    verts: [Vec3; MAX_SAT_VERTICES],
    normals: [Vec3; MAX_SAT_FACES],
    offsets: [Scalar; MAX_SAT_FACES],
    /// The two faces of each edge: [face running low→high, high→low].
    adj: [[u16; 2]; MAX_SAT_EDGES],
    /// Per edge, `n₁ × n₀` of its two face normals: the normal of the
    /// edge's arc on the Gauss map (the same formula serves A and −B).
    arcs: [Vec3; MAX_SAT_EDGES],
}

impl<'p, P: Poly> Posed<'p, P> {
    /// `rel` maps the polyhedron's frame into A's (`None`: it is A).
    fn new(p: &'p P, rel: Option<&Rel>) -> Posed<'p, P> {
        let mut s = Posed {
            p,
            verts: [Vec3::ZERO; MAX_SAT_VERTICES],
            normals: [Vec3::ZERO; MAX_SAT_FACES],
            offsets: [Scalar::ZERO; MAX_SAT_FACES],
            adj: [[u16::MAX; 2]; MAX_SAT_EDGES],
            arcs: [Vec3::ZERO; MAX_SAT_EDGES],
        };
        for i in 0..p.nv() {
            s.verts[i] = match rel {
                Some(r) => r.point(p.vertex(i)),
                None => p.vertex(i),
            };
        }
        for f in 0..p.nf() {
            let (n, d) = (p.normal(f), p.offset(f));
            (s.normals[f], s.offsets[f]) = match rel {
                Some(r) => {
                    let m = r.rot.mul_vec(n);
                    (m, d + m.dot(r.t))
                }
                None => (n, d),
            };
            let fv = p.face(f);
            for k in 0..fv.len() {
                let (u, v) = (fv[k], fv[(k + 1) % fv.len()]);
                let key = [u.min(v), u.max(v)];
                if let Ok(e) = p.edges().binary_search(&key) {
                    s.adj[e][usize::from(u > v)] = f as u16;
                }
            }
        }
        for e in 0..p.edges().len() {
            let [f0, f1] = s.adj[e];
            if f0 != u16::MAX && f1 != u16::MAX {
                s.arcs[e] = s.normals[f1 as usize].cross(s.normals[f0 as usize]);
            }
        }
        s
    }

    /// The smallest `n · v` over the vertices (exact).
    fn min_dot(&self, n: Vec3) -> i128 {
        self.verts[..self.p.nv()]
            .iter()
            .map(|v| n.dot_wide(*v))
            .min()
            .unwrap_or(0)
    }
}

/// `s` widened to Q64.64, to compare with exact `i128` dot products.
pub(super) fn wide_of(s: Scalar) -> i128 {
    (s.to_bits() as i128) << 32
}

/// The face of `p` that separates `q` most: (separation, face).
fn face_query<P: Poly, Q: Poly>(p: &Posed<P>, q: &Posed<Q>) -> (Scalar, usize) {
    let mut best = (Scalar::MIN, 0);
    for f in 0..p.p.nf() {
        let sep = Scalar::from_wide(q.min_dot(p.normals[f]) - wide_of(p.offsets[f]));
        if sep > best.0 {
            best = (sep, f);
        }
    }
    best
}

/// Sign of `u · v` for vectors of length ≤ 1 (unit normals, Gauss-map arc
/// normals), from their top 32 bits in 64-bit integers: the Gauss-map test
/// needs only signs, and this runs for every edge pair.
#[inline(always)]
fn dot_sign(u: Vec3, v: Vec3) -> i64 {
    let t = |c: Scalar| c.to_bits() >> 2;
    (t(u.x) * t(v.x) + t(u.y) * t(v.y) + t(u.z) * t(v.z)).signum()
}

/// The best edge–edge axis: (separation, edge of A, edge of B, axis A→B).
///
/// Only pairs whose arcs cross on the Gauss map (Gregorius' Minkowski-face
/// test, on the signs of exact dot products with the precomputed arc
/// normals) can realise the separation; the others are skipped without
/// computing an axis. Strict signs: parallel edges never pass (their axes
/// are face axes).
fn edge_query<P: Poly, Q: Poly>(
    a: &Posed<P>,
    b: &Posed<Q>,
) -> Option<(Scalar, usize, usize, Vec3)> {
    let mut best: Option<(Scalar, usize, usize, Vec3)> = None;
    for (ea, &[alo, ahi]) in a.p.edges().iter().enumerate() {
        let [fa0, fa1] = a.adj[ea];
        if fa0 == u16::MAX || fa1 == u16::MAX {
            continue;
        }
        let (na, nb) = (a.normals[fa0 as usize], a.normals[fa1 as usize]);
        let arc_a = a.arcs[ea];
        let pa = a.verts[alo as usize];
        let ua = a.verts[ahi as usize] - pa;
        for (eb, &[blo, bhi]) in b.p.edges().iter().enumerate() {
            let [fb0, fb1] = b.adj[eb];
            if fb0 == u16::MAX || fb1 == u16::MAX {
                continue;
            }
            // B's normals enter negated (the Minkowski difference A − B).
            let cba = -dot_sign(b.normals[fb0 as usize], arc_a);
            let dba = -dot_sign(b.normals[fb1 as usize], arc_a);
            if cba * dba >= 0 {
                continue;
            }
            let arc_b = b.arcs[eb];
            let adc = dot_sign(na, arc_b);
            let bdc = dot_sign(nb, arc_b);
            if adc * bdc >= 0 || cba * bdc <= 0 {
                continue;
            }
            let pb = b.verts[blo as usize];
            let Some(mut axis) = unit_from_wide(cross_wide(ua, b.verts[bhi as usize] - pb)) else {
                continue;
            };
            if axis.dot_wide(na + nb) < 0 {
                axis = -axis;
            }
            let sep = axis.dot(pb - pa);
            if best.is_none_or(|x| sep > x.0) {
                best = Some((sep, ea, eb, axis));
            }
        }
    }
    best
}

/// `p + (q − p)·t` for a Q2.62 `t`.
pub(super) fn lerp62(p: Vec3, q: Vec3, t: i128) -> Vec3 {
    let d = q - p;
    let f = |c: Scalar| Scalar::from_bits(round_shift(c.to_bits() as i128 * t, 62) as i64);
    p + Vec3::new(f(d.x), f(d.y), f(d.z))
}

/// Closest points between segments `p1q1` and `p2q2` (exact dots, Q2.62
/// parameters). Degenerate segments are points.
pub(super) fn closest_segments(p1: Vec3, q1: Vec3, p2: Vec3, q2: Vec3) -> (Vec3, Vec3) {
    let (d1, d2, r) = (q1 - p1, q2 - p2, p1 - p2);
    let mut v = [
        d1.dot_wide(d1),
        d2.dot_wide(d2),
        d2.dot_wide(r),
        d1.dot_wide(r),
        d1.dot_wide(d2),
    ];
    fit(&mut v, 62);
    let [a, e, f, c, b] = v;
    let (s, t);
    if a == 0 && e == 0 {
        (s, t) = (0, 0);
    } else if a == 0 {
        (s, t) = (0, q62(f, e));
    } else if e == 0 {
        (s, t) = (q62(-c, a), 0);
    } else {
        let mut den = [a * e - b * b, b * f - c * e];
        fit(&mut den, 62);
        let s0 = if den[0] > 0 { q62(den[1], den[0]) } else { 0 };
        let tn = ((b * s0) >> 62) + f;
        if tn <= 0 {
            (s, t) = (q62(-c, a), 0);
        } else if tn >= e {
            (s, t) = (q62(b - c, a), ONE_Q62);
        } else {
            (s, t) = (s0, q62(tn, e));
        }
    }
    (lerp62(p1, q1, s), lerp62(p2, q2, t))
}

/// A candidate contact point in A's frame.
#[derive(Clone, Copy, Default)]
pub(super) struct Cand {
    pub(super) point: Vec3,
    pub(super) depth: Scalar,
    pub(super) id: FeatureId,
}

/// Keeps at most four of `c` that span the largest area: the deepest, the
/// farthest from it, then the farthest on each side of the line between.
fn reduce(c: &[Cand], normal: Vec3, out: &mut [Cand; 4]) -> usize {
    if c.len() <= 4 {
        out[..c.len()].copy_from_slice(c);
        return c.len();
    }
    let argmax = |key: &dyn Fn(&Cand) -> i128| -> usize {
        let mut best = 0;
        for i in 1..c.len() {
            if key(&c[i]) > key(&c[best]) {
                best = i;
            }
        }
        best
    };
    let i0 = argmax(&|p| p.depth.to_bits() as i128);
    let p0 = c[i0].point;
    let i1 = argmax(&|p| (p.point - p0).length_squared_wide() as i128);
    let p1 = c[i1].point;
    let area = |p: &Cand| normal.dot_wide((p1 - p0).cross(p.point - p0));
    let i2 = argmax(&|p| area(p));
    let i3 = argmax(&|p| area(p).saturating_neg());
    let mut n = 0;
    for (k, i) in [i0, i1, i2, i3].into_iter().enumerate() {
        let fresh = ![i0, i1, i2, i3][..k].contains(&i);
        let side = match k {
            2 => area(&c[i]) > 0,
            3 => area(&c[i]) < 0,
            _ => true,
        };
        if fresh && side {
            out[n] = c[i];
            n += 1;
        }
    }
    n
}

/// Writes the candidates to `out` in world coordinates.
pub(super) fn emit(out: &mut Manifold, pose_a: &Transform, normal: Vec3, cands: &[Cand]) -> bool {
    out.normal = pose_a.transform_vector(normal);
    for c in cands {
        out.push(ContactPoint {
            point: pose_a.transform_point(c.point),
            depth: c.depth,
            id: c.id,
        });
    }
    !out.is_empty()
}

/// Clips the incident face of `inc` against reference face `rf` of `rfp`
/// and returns the points within `margin` (A's frame, normal of the
/// reference face; the caller orients it).
fn clip_faces<R: Poly, I: Poly>(
    rfp: &Posed<R>,
    rf: usize,
    inc: &Posed<I>,
    ref_is_b: bool,
    margin: Scalar,
    out: &mut [Cand; 4],
) -> usize {
    let n = rfp.normals[rf];
    let d = rfp.offsets[rf];
    // The incident shape's deepest vertex along −n, then the face through
    // it most anti-parallel to n (lowest index on ties): the polygon then
    // always holds the deepest point.
    let mut deep = 0;
    let mut deep_dot = i128::MAX;
    for (i, v) in inc.verts[..inc.p.nv()].iter().enumerate() {
        let dot = n.dot_wide(*v);
        if dot < deep_dot {
            deep_dot = dot;
            deep = i;
        }
    }
    let mut inc_f = 0;
    let mut low = i128::MAX;
    for f in 0..inc.p.nf() {
        if !inc.p.face(f).contains(&(deep as u32)) {
            continue;
        }
        let dot = inc.normals[f].dot_wide(n);
        if dot < low {
            low = dot;
            inc_f = f;
        }
    }
    let mut buf = [[(Vec3::ZERO, 0u16); CLIP_CAP]; 2];
    let iv = inc.p.face(inc_f);
    let mut count = iv.len().min(CLIP_CAP);
    for (k, &v) in iv.iter().take(count).enumerate() {
        buf[0][k] = (inc.verts[v as usize], v as u16);
    }
    let rv = rfp.p.face(rf);
    let mut cur = 0;
    for k in 0..rv.len() {
        let a = rfp.verts[rv[k] as usize];
        let b = rfp.verts[rv[(k + 1) % rv.len()] as usize];
        let Some(side) = unit_from_wide(cross_wide(b - a, n)) else {
            continue;
        };
        let (src, dst) = if cur == 0 {
            let (x, y) = buf.split_at_mut(1);
            (&x[0], &mut y[0])
        } else {
            let (x, y) = buf.split_at_mut(1);
            (&y[0], &mut x[0])
        };
        let mut m = 0;
        for i in 0..count {
            let (p, pid) = src[i];
            let (q, _) = src[(i + 1) % count];
            let dp = side.dot_wide(p - a);
            let dq = side.dot_wide(q - a);
            if dp <= 0 && m < CLIP_CAP {
                dst[m] = (p, pid);
                m += 1;
            }
            if (dp <= 0) != (dq <= 0) && m < CLIP_CAP {
                let t = q62(dp.abs(), (dp - dq).abs());
                let id = 0x8000 | ((k as u16 & 0x7f) << 7) | (pid & 0x7f);
                dst[m] = (lerp62(p, q, t), id);
                m += 1;
            }
        }
        count = m;
        cur ^= 1;
        if count == 0 {
            break;
        }
    }
    let mut cands = [Cand::default(); CLIP_CAP];
    let mut nc = 0;
    let ref_id = (u16::from(ref_is_b) << 15) | rf as u16;
    for &(p, pid) in &buf[cur][..count] {
        let sep = Scalar::from_wide(n.dot_wide(p) - wide_of(d));
        if sep <= margin {
            // Midway between the incident point and its projection.
            cands[nc] = Cand {
                point: p - n * sep.half(),
                depth: -sep,
                id: FeatureId::pair(ref_id, pid),
            };
            nc += 1;
        }
    }
    if nc == 0 {
        // Deep overlap with the incident face outside the reference face's
        // prism: the deepest vertex alone.
        let p = inc.verts[deep];
        let sep = Scalar::from_wide(deep_dot - wide_of(d));
        if sep > margin {
            return 0;
        }
        cands[0] = Cand {
            point: p - n * sep.half(),
            depth: -sep,
            id: FeatureId::pair(ref_id, deep as u16),
        };
        nc = 1;
    }
    reduce(&cands[..nc], n, out)
}

/// SAT + clipping between two polyhedra, A's frame; the callers keep hulls
/// beyond the buffers ([`MAX_SAT_VERTICES`]) away from it.
pub(super) fn poly_poly<PA: Poly, PB: Poly>(
    a: &PA,
    pose_a: &Transform,
    b: &PB,
    pose_b: &Transform,
    margin: Scalar,
    out: &mut Manifold,
) -> bool {
    let rel = Rel::new(pose_a, pose_b);
    let pa = Posed::new(a, None);
    let pb = Posed::new(b, Some(&rel));
    let (sa, fa) = face_query(&pa, &pb);
    if sa > margin {
        return false;
    }
    let (sb, fb) = face_query(&pb, &pa);
    if sb > margin {
        return false;
    }
    let edge = edge_query(&pa, &pb);
    if let Some((se, ..)) = edge
        && se > margin
    {
        return false;
    }
    let (sf, b_ref) = if sb > sa + feature_tolerance(sa) {
        (sb, true)
    } else {
        (sa, false)
    };
    if let Some((se, ea, eb, axis)) = edge
        && se > sf + feature_tolerance(sf)
    {
        let [a0, a1] = a.edges()[ea];
        let [b0, b1] = b.edges()[eb];
        let (ca, cb) = closest_segments(
            pa.verts[a0 as usize],
            pa.verts[a1 as usize],
            pb.verts[b0 as usize],
            pb.verts[b1 as usize],
        );
        let c = Cand {
            point: ca + (cb - ca).half(),
            depth: -se,
            id: FeatureId::pair(0x4000 | ea as u16, 0x4000 | eb as u16),
        };
        return emit(out, pose_a, axis, &[c]);
    }
    let mut cands = [Cand::default(); 4];
    let (n, normal) = if b_ref {
        let n = clip_faces(&pb, fb, &pa, true, margin, &mut cands);
        (n, -pb.normals[fb])
    } else {
        let n = clip_faces(&pa, fa, &pb, false, margin, &mut cands);
        (n, pa.normals[fa])
    };
    emit(out, pose_a, normal, &cands[..n])
}
