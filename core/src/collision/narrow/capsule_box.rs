//! Capsule against box: the capsule's core segment against the solid box,
//! by exact closest features when they are apart and by a six-axis SAT when
//! the segment enters the box; two points when the capsule lies along a face
//! or both its ends are within the margin of it.

use super::clip::clip_segment_to_face;
use super::segment::closest_points_segments;
use super::shared::{push_point, relative_direction, relative_position, sat_tolerance};
use super::sphere_box::box_region;
use super::sphere_capsule::segment_feature;
use crate::collision::manifold::{FeatureId, Manifold};
use crate::math::{Scalar, Transform, Vec3};
use crate::shape::{Capsule, Cuboid};

/// A-side feature number of the two points of a capsule lying along a face.
const ALONG_FACE: u16 = 0x10;
/// Offset of box face ids (`27 + 2·axis + (1 if −)`), after the 27 regions.
const FACE_BASE: u16 = 27;
/// Offset of box edge ids (`100 + 4·axis + sign bits of the other two`).
const EDGE_BASE: u16 = 100;

/// Whether the segment half-vector `u` is within about 1.8° of lying in the
/// plane normal to axis `k` (the sine below 1/32), which makes a capsule
/// lying on that face get two points.
fn lies_along_face(u: Vec3, k: usize) -> bool {
    !u.is_zero() && u.get(k).wide_mul(u.get(k)) <= u.dot_wide(u) >> 10
}

fn sign_of(x: Scalar) -> Scalar {
    if x.is_negative() {
        Scalar::NEG_ONE
    } else {
        Scalar::ONE
    }
}

/// Contact between capsule A and box B, computed in B's frame.
///
/// - Core segment outside the box: the closest pair among the two segment
///   ends against the box and the segment against the twelve edges; normal
///   along it, depth `r − distance`, id `(segment feature, box region)`.
/// - Segment touching or inside the box: SAT over the 3 face normals and the
///   3 cross products of the segment with the box edges (skipped when nearly
///   parallel), faces preferred within [`sat_tolerance`]; a face gives the
///   deepest clipped end (id `(segment feature, 27 + face)`), an edge the
///   closest points of the segment and that box edge (id `(segment feature,
///   100 + edge)`), depth `r − separation`.
/// - In both cases, when the normal is a face normal (or, apart, the
///   closest point is over an edge or corner: the face nearest the gap
///   direction) and the capsule lies within about 1.8° of parallel to that
///   face, the ends of the segment clipped to the face's rectangle become
///   the points (ids `(0x10 + end, 27 + face)`), each with its own depth;
///   tilted further, so do the two ends' lowest points when the whole
///   segment and both lowest points are over the face, both are within the
///   margin and the shallower end's core is not below the face. (With two
///   points only within 1.8°, a capsule that landed on one end and swung
///   down had no contact under the other: the solver let it pivot about the
///   deep end, continuous collision stopped the other end at the start of
///   every tick, and the capsule stayed 7 cm deep with a growing velocity.
///   With the face tried only when the closest point is over it, a capsule
///   lying on a step with one end out past the edge touched the edge alone
///   whenever it dipped towards it: it rocked onto its far end, two points,
///   and back, for as long as it lay there.)
pub fn contact_capsule_box(
    a: &Capsule,
    pose_a: &Transform,
    b: &Cuboid,
    pose_b: &Transform,
    margin: Scalar,
    out: &mut Manifold,
) -> bool {
    out.clear();
    let c = relative_position(pose_b, pose_a);
    let h = b.half_extents;
    let r = a.radius;
    let reach = r + a.half_height + h.x + h.y + h.z + margin;
    if c.length_squared_wide() > reach.wide_mul(reach) as u128 {
        return false;
    }
    let u = relative_direction(
        pose_b,
        pose_a,
        Vec3::new(Scalar::ZERO, a.half_height, Scalar::ZERO),
    );
    let (p0, p1) = (c - u, c + u);

    // SAT: faces, then the edge crosses.
    let mut face = (Scalar::MIN, 0usize);
    for k in 0..3 {
        let s = c.get(k).abs() - h.get(k) - u.get(k).abs();
        if s > face.0 {
            face = (s, k);
        }
    }
    let mut edge: Option<(Scalar, usize, Vec3)> = None;
    for k in 0..3 {
        let mut e = Vec3::ZERO;
        e.set(k, Scalar::ONE);
        let l = u.cross(e);
        if l.length_squared_wide() <= u.length_squared_wide() >> 20 {
            continue;
        }
        let Some(mut l) = l.try_normalize() else {
            continue;
        };
        if c.dot_wide(l) < 0 {
            l = -l;
        }
        let s = c.dot(l) - Scalar::from_wide(l.abs().dot_wide(h));
        if edge.is_none_or(|(best, _, _)| s > best) {
            edge = Some((s, k, l));
        }
    }
    let best = edge.map_or(face.0, |(s, _, _)| s.max(face.0));
    if best > r + margin {
        return false;
    }

    if best.is_positive() {
        // Apart: exact closest features.
        let mut found = (u128::MAX, Vec3::ZERO, Vec3::ZERO, Scalar::ZERO);
        for (t, p) in [(Scalar::ZERO, p0), (Scalar::ONE, p1)] {
            let on_box = p.max(-h).min(h);
            let d2 = (on_box - p).length_squared_wide();
            if d2 < found.0 {
                found = (d2, p, on_box, t);
            }
        }
        for k in 0..3 {
            for signs in 0..4 {
                let (e0, e1) = box_edge(h, k, signs);
                let cp = closest_points_segments(p0, p1, e0, e1);
                let d2 = (cp.p2 - cp.p1).length_squared_wide();
                if d2 < found.0 {
                    found = (d2, cp.p1, cp.p2, cp.s);
                }
            }
        }
        let (_, on_seg, on_box, t) = found;
        let gap = on_box - on_seg;
        if let Some((n, dist)) = gap.normalize_and_length() {
            if r - dist < -margin {
                return false;
            }
            out.normal = pose_b.transform_vector(n);
            // The face under the closest point, or, when that point is over
            // an edge or corner, the face whose normal is nearest the gap
            // direction: a capsule lying on a face with one end out past its
            // edge rests on the edge and on the face (two points), not on
            // the edge alone.
            let over_face = face_region(on_seg, h);
            let k = over_face.unwrap_or_else(|| dominant_axis(n));
            let sigma = sign_of(on_seg.get(k));
            let mut f = Vec3::ZERO;
            f.set(k, -sigma);
            out.normal = pose_b.transform_vector(f);
            if along_face(out, pose_b, p0, p1, u, h, k, sigma, r, margin) {
                if over_face.is_none() {
                    // The deeper point is the one at the edge, where the
                    // closest features are: it takes their separation
                    // exactly (measured along the face normal it is short
                    // by up to r·(1/cos θ − 1) and the core's rise across
                    // the rounding).
                    let mut deepest = 0;
                    for i in 1..out.count as usize {
                        if out.points[i].depth > out.points[deepest].depth {
                            deepest = i;
                        }
                    }
                    out.points[deepest].depth = r - dist;
                }
                return true;
            }
            out.normal = pose_b.transform_vector(n);
            let mid = (on_seg + n * r + on_box).half();
            let id = FeatureId::pair(segment_feature(t), box_region(on_seg, h));
            push_point(out, pose_b, mid, r - dist, id);
            return true;
        }
    }

    // Touching or overlapping: the SAT axis.
    let use_edge = match edge {
        Some((s, _, _)) => s > face.0 + sat_tolerance(face.0),
        None => false,
    };
    if let (true, Some((s, k, l))) = (use_edge, edge) {
        let n = -l;
        let mut signs = 0;
        let others = other_axes(k);
        for (bit, j) in others.into_iter().enumerate() {
            if !l.get(j).is_negative() {
                signs |= 1 << bit;
            }
        }
        let (e0, e1) = box_edge(h, k, signs);
        let cp = closest_points_segments(p0, p1, e0, e1);
        out.normal = pose_b.transform_vector(n);
        let mid = (cp.p1 + n * r + cp.p2).half();
        let id = FeatureId::pair(segment_feature(cp.s), EDGE_BASE + (4 * k + signs) as u16);
        push_point(out, pose_b, mid, r - s, id);
        return true;
    }
    let k = face.1;
    let sigma = sign_of(c.get(k));
    let mut n = Vec3::ZERO;
    n.set(k, -sigma);
    out.normal = pose_b.transform_vector(n);
    if along_face(out, pose_b, p0, p1, u, h, k, sigma, r, margin) {
        return true;
    }
    let (tlo, thi) = clip_segment_to_face(p0, p1, h, k).unwrap_or((Scalar::ZERO, Scalar::ONE));
    let height = |t: Scalar| (p0 + (p1 - p0) * t).get(k) * sigma;
    let t = if height(thi) < height(tlo) { thi } else { tlo };
    let p = p0 + (p1 - p0) * t;
    let depth = r + h.get(k) - p.get(k) * sigma;
    if depth < -margin {
        out.clear();
        return false;
    }
    let mut on_box = p;
    on_box.set(k, h.get(k) * sigma);
    let mid = (p + n * r + on_box).half();
    let id = FeatureId::pair(segment_feature(t), face_id(k, sigma));
    push_point(out, pose_b, mid, depth, id);
    true
}

/// The axis of the face whose region (outside that slab only, by more than
/// 2⁻²⁴ m) holds `p`, or `None` for an edge or corner region. The slack keeps
/// a point rounded onto a neighbouring slab's boundary in the face region.
fn face_region(p: Vec3, h: Vec3) -> Option<usize> {
    let slack = Scalar::from_bits(1 << 8);
    let mut face = None;
    for k in 0..3 {
        if p.get(k).abs() > h.get(k) + slack {
            if face.is_some() {
                return None;
            }
            face = Some(k);
        }
    }
    face
}

/// The axis along which `n` has its largest magnitude (the lowest axis on
/// a tie).
fn dominant_axis(n: Vec3) -> usize {
    let a = n.abs();
    if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    }
}

/// The face id of the face on axis `k` with outward sign `sigma`.
fn face_id(k: usize, sigma: Scalar) -> u16 {
    FACE_BASE + 2 * k as u16 + sigma.is_negative() as u16
}

/// The two axes other than `k`, in increasing order.
fn other_axes(k: usize) -> [usize; 2] {
    match k {
        0 => [1, 2],
        1 => [0, 2],
        _ => [0, 1],
    }
}

/// The box edge along axis `k` whose other two coordinates are `+h` where
/// the matching bit of `signs` is set (bit 0 for the lower axis) and `−h`
/// otherwise; from its `−h_k` end to its `+h_k` end.
fn box_edge(h: Vec3, k: usize, signs: usize) -> (Vec3, Vec3) {
    let mut p = Vec3::ZERO;
    for (bit, j) in other_axes(k).into_iter().enumerate() {
        let v = h.get(j);
        p.set(j, if signs & (1 << bit) != 0 { v } else { -v });
    }
    let (mut e0, mut e1) = (p, p);
    e0.set(k, -h.get(k));
    e1.set(k, h.get(k));
    (e0, e1)
}

/// The two-point contact of a capsule lying along face `(k, sigma)` (outward
/// normal `sigma·e_k`): the segment clipped to the face rectangle, each end
/// with its own depth. Pushes nothing and returns false unless the capsule
/// lies along the face and at least one end is within the margin, or (a
/// tilted capsule) the whole segment and both ends' lowest points are over
/// the face rectangle, both within the margin, and the shallower end's core
/// is not below the face (depth at most `r`), so each point lies between
/// the two surfaces.
#[allow(clippy::too_many_arguments)]
fn along_face(
    out: &mut Manifold,
    pose_b: &Transform,
    p0: Vec3,
    p1: Vec3,
    u: Vec3,
    h: Vec3,
    k: usize,
    sigma: Scalar,
    r: Scalar,
    margin: Scalar,
) -> bool {
    let Some((tlo, thi)) = clip_segment_to_face(p0, p1, h, k) else {
        return false;
    };
    if thi - tlo <= Scalar::from_bits(1 << 16) {
        return false;
    }
    let mut f = Vec3::ZERO;
    f.set(k, sigma);
    let flat = lies_along_face(u, k);
    // The lowest point (along −f) of the capsule's cross-section at core
    // point `p`: the bottom of the sphere there, except at the shallower
    // end of a tilted capsule, whose lowest point is on the cylinder, `r`
    // out along f's part perpendicular to the axis (below the sphere's
    // bottom by r(1 − cos θ)). Lying flat, both are the sphere's bottom.
    let axis = p1 - p0;
    let lowest = |p: Vec3, toward_other: Scalar| -> Vec3 {
        if flat || !toward_other.is_negative() {
            return p - f * r;
        }
        let along = f
            .dot(axis)
            .checked_div(axis.dot(axis))
            .unwrap_or(Scalar::ZERO);
        match (f - axis * along).try_normalize() {
            Some(w) => p - w * r,
            None => p - f * r,
        }
    };
    let fa = f.dot(axis);
    let ends = [(tlo, fa), (thi, -fa)].map(|(t, toward_other)| {
        let p = p0 + axis * t;
        let q = lowest(p, toward_other);
        (q, h.get(k) - q.get(k) * sigma)
    });
    if !flat {
        // Tilted: the whole segment over the face, both ends within the
        // margin, the shallower one's core end not below the face.
        let shallow = ends[0].1.min(ends[1].1);
        if !tlo.is_zero() || thi != Scalar::ONE || shallow < -margin || shallow > r {
            return false;
        }
        // And both lowest points over the face rectangle.
        let over = |q: Vec3| (0..3).all(|j| j == k || q.get(j).abs() <= h.get(j));
        if !(over(ends[0].0) && over(ends[1].0)) {
            return false;
        }
    }
    for (end, (q, depth)) in ends.into_iter().enumerate() {
        if depth >= -margin {
            let mut on_box = q;
            on_box.set(k, h.get(k) * sigma);
            let mid = (q + on_box).half();
            let id = FeatureId::pair(ALONG_FACE + end as u16, face_id(k, sigma));
            push_point(out, pose_b, mid, depth, id);
        }
    }
    !out.is_empty()
}
