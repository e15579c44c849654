//! Contacts between a convex hull and a sphere, a capsule, a box or another
//! hull: the pair entry points and the round-core (sphere, capsule) cases.
//! The polyhedron–polyhedron separating axis test that box–hull and
//! hull–hull use lives in the sibling module `polytope`, which knows no
//! shape kind; this file picks the method per pair and owns the fallbacks.
//!
//! # Design: SAT for polyhedra, GJK for round cores
//!
//! Box–hull and hull–hull run the polytope SAT (faces of both shapes and
//! Gauss-map-pruned edge pairs, reference-face clipping, at most four
//! points; see that module for why SAT rather than GJK + EPA). It works on
//! stack buffers for hulls of up to [`MAX_SAT_VERTICES`] vertices. Larger
//! hulls fall back to GJK + EPA and a single contact point (documented;
//! rare for game hulls).
//!
//! Sphere– and capsule–hull run GJK on the core (a point, a segment)
//! against the hull: when the core is apart by more than 2⁻¹⁶ m the normal
//! comes from the closest points (distance ≤ radius + margin makes a
//! contact). When the core touches or enters the hull, SAT takes over:
//! the hull's faces (and, for the capsule, the axes across the segment and
//! each hull edge). A capsule lying along a face gets two points by
//! clipping its segment to that face.
//!
//! Everything is computed in A's frame from the exact difference of the
//! translations (`Rel`), so results are translation invariant bit for
//! bit. Ties go to the lowest face/edge index. Feature ids:
//! * box–hull and hull–hull: as documented in `polytope`
//!   (clipped face points and edge–edge points);
//! * sphere/capsule: `pair(core feature, hull face)`, with `0x7fff` for a
//!   GJK point and `0x4000 | edge` for a capsule–edge point;
//! * hulls beyond the SAT buffers: `FeatureId(u32::MAX)`.

use super::epa::epa_core;
use super::gjk::{
    CoreResult, ONE_Q62, Pair, Rel, SupportShape, cross_wide, gjk_core, q62, unit_from_wide,
};
pub use super::polytope::MAX_SAT_VERTICES;
use super::polytope::{
    BoxPoly, Cand, closest_segments, emit, feature_tolerance, lerp62, poly_poly, wide_of,
};
use crate::collision::{FeatureId, Manifold};
use crate::math::{Scalar, Transform, Vec3};
use crate::shape::{Capsule, ConvexHull, Cuboid, Sphere};

/// Cores closer than 2⁻¹⁶ m (squared, Q64.64 raw) go to SAT: below it the
/// GJK direction has too few significant bits.
const CORE_EPS_VV: u128 = 1 << 32;

/// A capsule lying within about 5° of a hull face (cosine ≥ 1 − 2⁻⁸) gets
/// the two-point face contact.
const FACE_COS: i128 = (1i128 << 64) - (1i128 << 56);

/// Whether the segment direction `dir` is within about 5° of the plane with
/// unit normal `m` (`(m·dir)² ≤ 2⁻⁷ |dir|²`, sin² 5.07°): only then do its
/// clipped points lie on the capsule's surface to within `r (1 − cos 5°)`.
fn lies_along(m: Vec3, dir: Vec3) -> bool {
    let a = m.dot(dir);
    a.wide_mul(a) as u128 <= dir.length_squared_wide() >> 7
}

/// One point from GJK (within the margin) or EPA (overlap): the fallback for
/// hulls beyond the SAT buffers.
fn general<A: SupportShape + ?Sized, B: SupportShape + ?Sized>(
    a: &A,
    pose_a: &Transform,
    b: &B,
    pose_b: &Transform,
    margin: Scalar,
    out: &mut Manifold,
) -> bool {
    let pair = Pair {
        a,
        b,
        rel: Rel::new(pose_a, pose_b),
    };
    let (ra, rb) = (a.core_radius(), b.core_radius());
    let (n, core_depth, pa, pb) = match gjk_core(&pair) {
        CoreResult::Separated { pa, pb, v, vv, .. } => {
            let core = Scalar::from_bits(crate::math::elem::isqrt_u128(vv) as i64);
            if core - ra - rb > margin {
                return false;
            }
            ((-v).try_normalize().unwrap_or(Vec3::Y), -core, pa, pb)
        }
        CoreResult::Overlapping(s) => {
            let p = epa_core(&pair, &s);
            (p.normal, p.depth, p.pa, p.pb)
        }
    };
    let depth = core_depth + ra + rb;
    let sa = pa + n * ra;
    let sb = pb - n * rb;
    let c = Cand {
        point: sa + (sb - sa).half(),
        depth,
        id: FeatureId(u32::MAX),
    };
    emit(out, pose_a, n, &[c])
}

/// B's face `f` as a plane in A's frame: (normal, offset).
fn plane_in_a(hull: &ConvexHull, rel: &Rel, f: usize) -> (Vec3, Scalar) {
    let face = &hull.faces()[f];
    let m = rel.rot.mul_vec(face.normal());
    (m, face.offset() + m.dot(rel.t))
}

/// The hull face (in A's frame) that separates point set `pts` most:
/// (separation, face, normal, offset).
fn best_face_for(hull: &ConvexHull, rel: &Rel, pts: &[Vec3]) -> (Scalar, usize, Vec3, Scalar) {
    let mut best = (Scalar::MIN, 0, Vec3::Y, Scalar::ZERO);
    for f in 0..hull.faces().len() {
        let (m, e) = plane_in_a(hull, rel, f);
        let low = pts.iter().map(|p| m.dot_wide(*p)).min().unwrap_or(0);
        let sep = Scalar::from_wide(low - wide_of(e));
        if sep > best.0 {
            best = (sep, f, m, e);
        }
    }
    best
}

/// Contact between a sphere (A) and a convex hull (B).
///
/// GJK from the centre to the hull while the centre is outside by more
/// than 2⁻¹⁶ m; otherwise the hull face the centre is least deep behind.
/// One point, midway between the surfaces; `margin` ≥ 0 keeps separated
/// pairs closer than it (negative depth). Returns `!out.is_empty()`.
pub fn contact_sphere_hull(
    a: &Sphere,
    pose_a: &Transform,
    b: &ConvexHull,
    pose_b: &Transform,
    margin: Scalar,
    out: &mut Manifold,
) -> bool {
    out.clear();
    let rel = Rel::new(pose_a, pose_b);
    let r = a.radius;
    let pair = Pair { a, b, rel };
    if let CoreResult::Separated { pa, v, vv, .. } = gjk_core(&pair)
        && vv > CORE_EPS_VV
    {
        let d = Scalar::from_bits(crate::math::elem::isqrt_u128(vv) as i64);
        if d - r > margin {
            return false;
        }
        let n = (-v).try_normalize().unwrap_or(Vec3::Y);
        let c = Cand {
            point: pa + n * (r + d).half(),
            depth: r - d,
            id: FeatureId::pair(0, 0x7fff),
        };
        return emit(out, pose_a, n, &[c]);
    }
    let (sep, f, m, _) = best_face_for(b, &rel, &[Vec3::ZERO]);
    if sep - r > margin {
        return false;
    }
    let n = -m;
    let c = Cand {
        point: n * (r + sep).half(),
        depth: r - sep,
        id: FeatureId::pair(0, f as u16),
    };
    emit(out, pose_a, n, &[c])
}

/// Clips segment `p0p1` to the prism over hull face `f` (A's frame, face
/// normal `m`): the parameters (Q2.62) of the part inside, if any.
fn clip_segment_to_face(
    hull: &ConvexHull,
    rel: &Rel,
    f: usize,
    m: Vec3,
    p0: Vec3,
    p1: Vec3,
) -> Option<(i128, i128)> {
    let fv = hull.face_vertices(f);
    let (mut t0, mut t1) = (0i128, ONE_Q62);
    for k in 0..fv.len() {
        let a = rel.point(hull.vertices()[fv[k] as usize]);
        let b = rel.point(hull.vertices()[fv[(k + 1) % fv.len()] as usize]);
        let Some(side) = unit_from_wide(cross_wide(b - a, m)) else {
            continue;
        };
        let d0 = side.dot_wide(p0 - a);
        let d1 = side.dot_wide(p1 - a);
        match (d0 > 0, d1 > 0) {
            (true, true) => return None,
            (true, false) => t0 = t0.max(q62(d0, d0 - d1)),
            (false, true) => t1 = t1.min(q62(-d0, d1 - d0)),
            (false, false) => {}
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

/// Face contact of a capsule segment against hull face `f`: up to two
/// points (clipped ends) within `margin`.
#[allow(clippy::too_many_arguments)]
fn capsule_face_points(
    hull: &ConvexHull,
    rel: &Rel,
    f: usize,
    m: Vec3,
    e: Scalar,
    seg: [Vec3; 2],
    r: Scalar,
    margin: Scalar,
    cands: &mut [Cand; 2],
) -> usize {
    let Some((t0, t1)) = clip_segment_to_face(hull, rel, f, m, seg[0], seg[1]) else {
        return 0;
    };
    let n = -m;
    let mut k = 0;
    for (end, t) in [(0u16, t0), (1u16, t1)] {
        if end == 1 && t1 == t0 {
            break;
        }
        let p = lerp62(seg[0], seg[1], t);
        let sep = Scalar::from_wide(m.dot_wide(p) - wide_of(e));
        if sep - r <= margin {
            let clipped = u16::from(t != if end == 0 { 0 } else { ONE_Q62 });
            cands[k] = Cand {
                point: p + n * (r + sep).half(),
                depth: r - sep,
                id: FeatureId::pair(end | (clipped << 1), f as u16),
            };
            k += 1;
        }
    }
    k
}

/// Contact between a capsule (A) and a convex hull (B).
///
/// GJK from the core segment while it is outside the hull by more than
/// 2⁻¹⁶ m: one point, or two when the segment lies within ~5° of a hull
/// face (its clipped ends). A penetrating core takes the best of the hull's
/// face axes and the axes across the segment and each hull edge. Returns
/// `!out.is_empty()`.
pub fn contact_capsule_hull(
    a: &Capsule,
    pose_a: &Transform,
    b: &ConvexHull,
    pose_b: &Transform,
    margin: Scalar,
    out: &mut Manifold,
) -> bool {
    out.clear();
    let rel = Rel::new(pose_a, pose_b);
    let r = a.radius;
    let seg = a.segment();
    let pair = Pair { a, b, rel };
    let mut cands = [Cand::default(); 2];
    if let CoreResult::Separated { pa, v, vv, .. } = gjk_core(&pair)
        && vv > CORE_EPS_VV
    {
        let d = Scalar::from_bits(crate::math::elem::isqrt_u128(vv) as i64);
        if d - r > margin {
            return false;
        }
        let n = (-v).try_normalize().unwrap_or(Vec3::Y);
        // The face most against n.
        let mut best = (i128::MAX, 0usize);
        for f in 0..b.faces().len() {
            let dot = rel.rot.mul_vec(b.faces()[f].normal()).dot_wide(n);
            if dot < best.0 {
                best = (dot, f);
            }
        }
        let (m, e) = plane_in_a(b, &rel, best.1);
        if -best.0 >= FACE_COS && lies_along(m, seg[1] - seg[0]) {
            let k = capsule_face_points(b, &rel, best.1, m, e, seg, r, margin, &mut cands);
            if k == 2 {
                return emit(out, pose_a, -m, &cands[..k]);
            }
        }
        let c = Cand {
            point: pa + n * (r + d).half(),
            depth: r - d,
            id: FeatureId::pair(2, 0x7fff),
        };
        return emit(out, pose_a, n, &[c]);
    }
    // The core touches or enters the hull: SAT.
    let (sf, f, m, e) = best_face_for(b, &rel, &seg);
    if sf - r > margin {
        return false;
    }
    let axis_seg = seg[1] - seg[0];
    let mut best_edge: Option<(Scalar, usize, Vec3)> = None;
    for (ei, &[lo, hi]) in b.edges().iter().enumerate() {
        let (p, q) = (b.vertices()[lo as usize], b.vertices()[hi as usize]);
        let Some(axis) = unit_from_wide(cross_wide(axis_seg, rel.vector(q - p))) else {
            continue;
        };
        let ab = rel.dir_in_b(axis);
        let shift = wide_of(axis.dot(rel.t));
        let (mut lo_b, mut hi_b) = (i128::MAX, i128::MIN);
        for v in b.vertices() {
            let x = ab.dot_wide(*v);
            lo_b = lo_b.min(x);
            hi_b = hi_b.max(x);
        }
        let (lo_b, hi_b) = (lo_b + shift, hi_b + shift);
        let (s0, s1) = (axis.dot_wide(seg[0]), axis.dot_wide(seg[1]));
        let (lo_s, hi_s) = (s0.min(s1), s0.max(s1));
        // The edge must lie on B's extreme side along the chosen direction.
        let on = |x: i128, ext: i128| (x + shift - ext).abs() <= 1 << 44;
        let edge_pos = ab.dot_wide(p);
        let (sep, dir) = if lo_b - hi_s >= lo_s - hi_b {
            (lo_b - hi_s, axis)
        } else {
            (lo_s - hi_b, -axis)
        };
        let ext = if dir == axis { lo_b } else { hi_b };
        if !on(edge_pos, ext) {
            continue;
        }
        let sep = Scalar::from_wide(sep);
        if best_edge.is_none_or(|x| sep > x.0) {
            best_edge = Some((sep, ei, dir));
        }
    }
    if let Some((se, ei, dir)) = best_edge {
        if se - r > margin {
            return false;
        }
        if se > sf + feature_tolerance(sf) {
            let [lo, hi] = b.edges()[ei];
            let (cs, ch) = closest_segments(
                seg[0],
                seg[1],
                rel.point(b.vertices()[lo as usize]),
                rel.point(b.vertices()[hi as usize]),
            );
            let _ = ch;
            let c = Cand {
                point: cs + dir * (r + se).half(),
                depth: r - se,
                id: FeatureId::pair(3, 0x4000 | ei as u16),
            };
            return emit(out, pose_a, dir, &[c]);
        }
    }
    if lies_along(m, seg[1] - seg[0]) {
        let k = capsule_face_points(b, &rel, f, m, e, seg, r, margin, &mut cands);
        if k > 0 {
            return emit(out, pose_a, -m, &cands[..k]);
        }
    }
    // Tilted against the face, or projecting outside it: the deepest end
    // (the capsule's support point along the normal).
    let s = seg.map(|p| Scalar::from_wide(m.dot_wide(p) - wide_of(e)));
    let end = usize::from(s[1] < s[0]);
    let c = Cand {
        point: seg[end] - m * (r + s[end]).half(),
        depth: r - s[end],
        id: FeatureId::pair(end as u16, f as u16),
    };
    emit(out, pose_a, -m, &[c])
}

/// Contact between a box (A) and a convex hull (B): SAT over both shapes'
/// faces and the Gauss-map-pruned edge pairs, reference-face clipping, at
/// most four points. Hulls over [`MAX_SAT_VERTICES`] get one GJK/EPA point.
/// Returns `!out.is_empty()`.
pub fn contact_box_hull(
    a: &Cuboid,
    pose_a: &Transform,
    b: &ConvexHull,
    pose_b: &Transform,
    margin: Scalar,
    out: &mut Manifold,
) -> bool {
    out.clear();
    if b.vertices().len() > MAX_SAT_VERTICES {
        return general(a, pose_a, b, pose_b, margin, out);
    }
    poly_poly(&BoxPoly::new(a), pose_a, b, pose_b, margin, out)
}

/// Contact between two convex hulls: as [`contact_box_hull`]. Returns
/// `!out.is_empty()`.
pub fn contact_hull_hull(
    a: &ConvexHull,
    pose_a: &Transform,
    b: &ConvexHull,
    pose_b: &Transform,
    margin: Scalar,
    out: &mut Manifold,
) -> bool {
    out.clear();
    if a.vertices().len() > MAX_SAT_VERTICES || b.vertices().len() > MAX_SAT_VERTICES {
        return general(a, pose_a, b, pose_b, margin, out);
    }
    poly_poly(a, pose_a, b, pose_b, margin, out)
}

#[cfg(test)]
mod tests_gjk;
