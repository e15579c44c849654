//! The separating axis test between two convex polyhedra, with
//! reference-face clipping: the machinery behind box–hull and hull–hull
//! contacts ([`hull_contact`](super::hull_contact) holds those entry
//! points). It lives apart from them because it knows nothing of any shape
//! kind: a box and a hull both enter through the [`Poly`] view.
//!
//! # Design: SAT with Gauss-map pruning and ball bounds
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
//!   directly (EPA's triangulated faces would need a second search).
//!
//! Cost: a plain SAT tests `F·V` face–vertex pairs and `E_A·E_B` edge
//! pairs (a 32-point hull: 60 faces, 90 edges, so 8,100 edge pairs). Each
//! shape carries, from construction, an inscribed and a bounding ball about
//! one centre and a cone around each edge's arc of normals
//! ([`SatFeatures`](crate::shape::sat_features::SatFeatures)). With them
//! one dot product bounds a face's separation from both sides, and one
//! bounds every separation an edge can take part in. A pair whose best
//! face bound is beyond the margin ends there, before B's vertices are
//! moved into A's frame; otherwise only the faces whose upper bound
//! reaches the best lower bound, and the edges whose bound reaches the
//! best face, are tested exactly (for the hulls of `convex_pile`, a few
//! faces and about a fifth of the edges of each). Skipping never changes a
//! result: a skipped feature's separation is below the winner's by more
//! than any rounding in the bounds, so the outcome is bit for bit that of
//! testing everything (a test compares the two on random pairs). Gauss-map
//! pruning then rejects most remaining edge pairs in `O(1)` each.
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

mod poly;
#[cfg(test)]
mod tests;

pub(super) use poly::{BoxPoly, Poly};
use poly::{Fixed, Frame, Moved};

use super::gjk::{ONE_Q62, Rel, cross_wide, fit, q62, unit_from_wide};
use crate::collision::{ContactPoint, FeatureId, Manifold};
use crate::math::elem::isqrt_u128;
use crate::math::scalar::round_shift;
use crate::math::{Scalar, Transform, Vec3};
use crate::shape::sat_features::{Balls, NO_FACE};

/// Largest hull (in vertices) the SAT path handles; bigger hulls use GJK +
/// EPA with a single point.
pub const MAX_SAT_VERTICES: usize = 128;
pub(super) const MAX_SAT_FACES: usize = 2 * MAX_SAT_VERTICES - 4;
pub(super) const MAX_SAT_EDGES: usize = 3 * MAX_SAT_VERTICES - 6;
/// Room for a clipped polygon: an incident face grows by at most one point
/// per reference side.
const CLIP_CAP: usize = 2 * MAX_SAT_VERTICES;

/// A face axis beats an edge axis, and A's face beats B's, unless the other
/// separates by more than `1/1024 m + |separation|/32`: stacks then keep
/// their face contacts instead of flickering to edges.
pub(super) fn feature_tolerance(sep: Scalar) -> Scalar {
    Scalar::from_bits(1 << 22) + Scalar::from_bits(sep.to_bits().abs() >> 5)
}

/// The smallest `n · v` over `verts` (exact).
fn min_dot(verts: &[Vec3], n: Vec3) -> i128 {
    verts.iter().map(|v| n.dot_wide(*v)).min().unwrap_or(0)
}

/// `s` widened to Q64.64, to compare with exact `i128` dot products.
pub(super) fn wide_of(s: Scalar) -> i128 {
    (s.to_bits() as i128) << 32
}

/// The pair's balls in both frames, and the allowance that makes the
/// bounds built on them safe against rounding.
///
/// A face's separation (the smallest `n · v − d` over the other shape's
/// vertices) lies between `n · c − d − outer` and `n · c − d − inner` for
/// the other shape's balls about `c`: the vertices are within `outer` of
/// `c`, and the ball of radius `inner` is inside the shape. The exact test
/// then needs to run only for faces whose upper bound reaches the best
/// lower bound. An edge pair's separation is at most `u · (c_B − c_A) −
/// inner_A − inner_B` along its axis `u`, and `u` lies in both edges'
/// cones, which bounds `u · (c_B − c_A)` per edge. Features whose bound
/// falls short are skipped; the result is the same as testing them all,
/// bit for bit: a skipped feature's separation is below the winner's by
/// more than the rounding of any of these numbers.
struct Bounds {
    /// B's centre in A's frame; A's centre in B's frame.
    cb_in_a: Vec3,
    ca_in_b: Vec3,
    /// `|c_B − c_A|`, rounded up.
    dist: Scalar,
    /// Added to every upper bound and taken from every lower one (Q64.64):
    /// 2⁻¹⁶ m plus 2⁻¹⁶ of the pair's extent, far above the few ulps by
    /// which the rounded relative pose, normals and vertices move a
    /// separation.
    slack: i128,
}

impl Bounds {
    fn new<PA: Poly, PB: Poly>(a: &PA, b: &PB, rel: &Rel) -> Bounds {
        let (ba, bb) = (a.balls(), b.balls());
        let cb_in_a = rel.point(bb.center);
        let ca_in_b = rel.dir_in_b(ba.center - rel.t);
        let d = cb_in_a - ba.center;
        let dist = Scalar::from_bits(isqrt_u128(d.length_squared_wide()) as i64 + 1);
        let l1 = |v: Vec3| {
            v.x.to_bits().unsigned_abs() as i128
                + v.y.to_bits().unsigned_abs() as i128
                + v.z.to_bits().unsigned_abs() as i128
        };
        let extent = ba.outer.to_bits() as i128
            + bb.outer.to_bits() as i128
            + l1(rel.t)
            + l1(ba.center)
            + l1(bb.center);
        Bounds {
            cb_in_a,
            ca_in_b,
            dist,
            slack: (1i128 << 48) + (extent << 16),
        }
    }
}

/// The best lower bound on `p`'s face separations against the shape with
/// balls `q` (centre `cq` in `p`'s own frame), Q64.64.
fn face_low<P: Poly>(p: &P, q: &Balls, cq: Vec3, slack: i128) -> i128 {
    (0..p.nf())
        .map(|f| face_estimate(p, f, cq))
        .max()
        .unwrap_or(0)
        - wide_of(q.outer)
        - slack
}

/// `n · c − d` for face `f` of `p` and a point `c` of `p`'s frame.
#[inline(always)]
fn face_estimate<P: Poly>(p: &P, f: usize, c: Vec3) -> i128 {
    p.normal(f).dot_wide(c) - wide_of(p.offset(f))
}

/// Whether a lower bound from [`face_low`] already puts the separation
/// beyond `margin`, after rounding to Q32.32.
fn beyond(low: i128, margin: Scalar) -> bool {
    low > wide_of(margin) + (1 << 32)
}

/// The face of `p` that separates the other shape most: (separation,
/// face), the lowest index on ties, as if every face were tested exactly
/// by `exact(f)` (Q64.64, in A's frame) and rounded. Only faces whose upper
/// bound (from the other shape's balls `q`, centre `cq` in `p`'s frame)
/// reaches `low` (from [`face_low`]) are tested.
fn face_query<P: Poly>(
    p: &P,
    q: &Balls,
    cq: Vec3,
    slack: i128,
    low: i128,
    mut exact: impl FnMut(usize) -> i128,
) -> (Scalar, usize) {
    let mut best = (Scalar::MIN, 0);
    for f in 0..p.nf() {
        if face_estimate(p, f, cq) - wide_of(q.inner) + slack < low {
            continue;
        }
        let sep = Scalar::from_wide(exact(f));
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

/// The edges of `p` (own frame) whose cone bounds can reach `floor`:
/// `dir` is `c_B − c_A` seen from `p`'s side (A: `c_B − c_A`; B: `c_A −
/// c_B`, as B's arcs hold `−u`), in `p`'s frame; `inner` is both inner
/// radii; `other` is the other shape's centre in `p`'s frame and
/// `other_inner` its inner radius. Writes their indices, ascending, to
/// `out`; returns how many.
///
/// Two bounds, the cheap one first. With `u` in the edge's cone, `p`'s
/// extent along `u` is reached on the edge itself (at its vertex `q`),
/// and the other shape reaches at least `inner` past its centre, so the
/// separation is at most `u · (other − q) − other_inner`; before paying for
/// `|other − q|`, the same with `p`'s inner ball in place of the edge.
#[allow(clippy::too_many_arguments)]
fn edge_candidates<P: Poly>(
    p: &P,
    dir: Vec3,
    bounds: &Bounds,
    inner: i128,
    other: Vec3,
    other_inner: Scalar,
    floor: i128,
    out: &mut [u16; MAX_SAT_EDGES],
) -> usize {
    let mut n = 0;
    let verts = p.vertices();
    for (e, &[lo, _]) in p.edges().iter().enumerate() {
        let [f0, f1] = p.edge_faces(e);
        if f0 == NO_FACE || f1 == NO_FACE {
            continue;
        }
        let (axis, radius) = p.cone(e);
        let up = axis.dot_wide(dir) + radius.wide_mul(bounds.dist) - inner + bounds.slack;
        if up < floor {
            continue;
        }
        let w = other - verts[lo as usize];
        let reach = Scalar::from_bits(isqrt_u128(w.length_squared_wide()) as i64 + 1);
        let up = axis.dot_wide(w) + radius.wide_mul(reach) - wide_of(other_inner) + bounds.slack;
        if up >= floor {
            out[n] = e as u16;
            n += 1;
        }
    }
    n
}

/// The best edge–edge axis: (separation, edge of A, edge of B, axis A→B),
/// over the edges whose cone bounds can beat `floor` (the best face
/// separation; an edge pair below it can neither win nor separate).
///
/// Only pairs whose arcs cross on the Gauss map (Gregorius' Minkowski-face
/// test, on the signs of exact dot products with the arc normals) can
/// realise the separation; the others are skipped without computing an
/// axis. Strict signs: parallel edges never pass (their axes are face
/// axes).
fn edge_query<PA: Poly, PB: Poly>(
    a: &PA,
    b: &mut Moved<PB>,
    bounds: &Bounds,
    floor: Scalar,
) -> Option<(Scalar, usize, usize, Vec3)> {
    let (ba, bb) = (a.balls(), b.p.balls());
    let inner = wide_of(ba.inner) + wide_of(bb.inner);
    let floor = wide_of(floor);
    let mut ca = [0u16; MAX_SAT_EDGES];
    let na_count = edge_candidates(
        a,
        bounds.cb_in_a - ba.center,
        bounds,
        inner,
        bounds.cb_in_a,
        bb.inner,
        floor,
        &mut ca,
    );
    if na_count == 0 {
        return None;
    }
    let mut cb = [0u16; MAX_SAT_EDGES];
    let nb_count = edge_candidates(
        b.p,
        bounds.ca_in_b - bb.center,
        bounds,
        inner,
        bounds.ca_in_b,
        ba.inner,
        floor,
        &mut cb,
    );
    // B's planes and arcs for the candidates, once, before the pair loop.
    for &eb in &cb[..nb_count] {
        b.arc(eb as usize);
    }
    let av = a.vertices();
    let mut best: Option<(Scalar, usize, usize, Vec3)> = None;
    for &ea in &ca[..na_count] {
        let ea = ea as usize;
        let [alo, ahi] = a.edges()[ea];
        let [fa0, fa1] = a.edge_faces(ea);
        let (na, nb) = (a.normal(fa0 as usize), a.normal(fa1 as usize));
        let arc_a = a.arc(ea);
        let pa = av[alo as usize];
        let ua = av[ahi as usize] - pa;
        for &eb in &cb[..nb_count] {
            let eb = eb as usize;
            let [blo, bhi] = b.p.edges()[eb];
            let [fb0, fb1] = b.p.edge_faces(eb);
            // B's normals enter negated (the Minkowski difference A − B).
            let cba = -dot_sign(b.plane_at(fb0 as usize).0, arc_a);
            let dba = -dot_sign(b.plane_at(fb1 as usize).0, arc_a);
            if cba * dba >= 0 {
                continue;
            }
            let arc_b = b.arc_at(eb);
            let adc = dot_sign(na, arc_b);
            let bdc = dot_sign(nb, arc_b);
            if adc * bdc >= 0 || cba * bdc <= 0 {
                continue;
            }
            let pb = b.verts()[blo as usize];
            let Some(mut axis) = unit_from_wide(cross_wide(ua, b.verts()[bhi as usize] - pb))
            else {
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
fn clip_faces<R: Frame, I: Frame>(
    rfp: &mut R,
    rf: usize,
    inc: &mut I,
    ref_is_b: bool,
    margin: Scalar,
    out: &mut [Cand; 4],
) -> usize {
    let (n, d) = rfp.plane(rf);
    // The incident shape's deepest vertex along −n, then the face through
    // it most anti-parallel to n (lowest index on ties): the polygon then
    // always holds the deepest point.
    let mut deep = 0;
    let mut deep_dot = i128::MAX;
    for (i, v) in inc.verts().iter().enumerate() {
        let dot = n.dot_wide(*v);
        if dot < deep_dot {
            deep_dot = dot;
            deep = i;
        }
    }
    let mut inc_f = 0;
    let mut low = i128::MAX;
    for f in 0..inc.poly().nf() {
        if !inc.poly().face(f).contains(&(deep as u32)) {
            continue;
        }
        let dot = inc.plane(f).0.dot_wide(n);
        if dot < low {
            low = dot;
            inc_f = f;
        }
    }
    let mut buf = [[(Vec3::ZERO, 0u16); CLIP_CAP]; 2];
    let iv = inc.poly().face(inc_f);
    let mut count = iv.len().min(CLIP_CAP);
    for (k, &v) in iv.iter().take(count).enumerate() {
        buf[0][k] = (inc.verts()[v as usize], v as u16);
    }
    let rv = rfp.poly().face(rf);
    let mut cur = 0;
    for k in 0..rv.len() {
        let a = rfp.verts()[rv[k] as usize];
        let b = rfp.verts()[rv[(k + 1) % rv.len()] as usize];
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
        let p = inc.verts()[deep];
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
///
/// The same result, bit for bit, as testing every face and every
/// Gauss-map-valid edge pair exactly; the balls' bounds (see [`Bounds`])
/// decide only which of those tests can be skipped, and a pair apart by
/// more than `margin` on a face bound ends before any vertex is moved.
pub(super) fn poly_poly<PA: Poly, PB: Poly>(
    a: &PA,
    pose_a: &Transform,
    b: &PB,
    pose_b: &Transform,
    margin: Scalar,
    out: &mut Manifold,
) -> bool {
    sat_and_clip(a, pose_a, b, pose_b, margin, true, out)
}

/// [`poly_poly`], or with `prune` false the same test with bounds so loose
/// that nothing is skipped (the reference its tests compare with).
fn sat_and_clip<PA: Poly, PB: Poly>(
    a: &PA,
    pose_a: &Transform,
    b: &PB,
    pose_b: &Transform,
    margin: Scalar,
    prune: bool,
    out: &mut Manifold,
) -> bool {
    let rel = Rel::new(pose_a, pose_b);
    let mut bounds = Bounds::new(a, b, &rel);
    if !prune {
        bounds.slack = 1 << 100;
    }
    let slack = bounds.slack;
    let low_a = face_low(a, b.balls(), bounds.cb_in_a, slack);
    if beyond(low_a, margin) {
        return false;
    }
    let low_b = face_low(b, a.balls(), bounds.ca_in_b, slack);
    if beyond(low_b, margin) {
        return false;
    }
    let mut pa = Fixed(a);
    let mut pb = Moved::new(b, &rel);
    let (sa, fa) = face_query(a, b.balls(), bounds.cb_in_a, slack, low_a, |f| {
        min_dot(pb.verts(), a.normal(f)) - wide_of(a.offset(f))
    });
    if sa > margin {
        return false;
    }
    let (sb, fb) = face_query(b, a.balls(), bounds.ca_in_b, slack, low_b, |f| {
        let (m, d) = pb.plane(f);
        min_dot(a.vertices(), m) - wide_of(d)
    });
    if sb > margin {
        return false;
    }
    let (sf, b_ref) = if sb > sa + feature_tolerance(sa) {
        (sb, true)
    } else {
        (sa, false)
    };
    let edge = edge_query(a, &mut pb, &bounds, sf);
    if let Some((se, ..)) = edge
        && se > margin
    {
        return false;
    }
    if let Some((se, ea, eb, axis)) = edge
        && se > sf + feature_tolerance(sf)
    {
        let [a0, a1] = a.edges()[ea];
        let [b0, b1] = b.edges()[eb];
        let (ca, cb) = closest_segments(
            a.vertices()[a0 as usize],
            a.vertices()[a1 as usize],
            pb.verts()[b0 as usize],
            pb.verts()[b1 as usize],
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
        let n = clip_faces(&mut pb, fb, &mut pa, true, margin, &mut cands);
        (n, -pb.plane(fb).0)
    } else {
        let n = clip_faces(&mut pa, fa, &mut pb, false, margin, &mut cands);
        (n, a.normal(fa))
    };
    emit(out, pose_a, normal, &cands[..n])
}
