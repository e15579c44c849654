//! Box against box: separating-axis test over the 15 candidate axes, then
//! either a face contact (the incident face clipped against the reference
//! face's side planes, reduced to at most four points) or one edge–edge
//! point.

use super::clip::{ClipPolygon, ClipVertex, MAX_CLIP_VERTICES, clip_polygon};
use super::segment::closest_points_segments;
use super::shared::{push_point, relative_pose, sat_tolerance};
use crate::collision::manifold::{FeatureId, Manifold};
use crate::math::{Mat3, Scalar, Transform, Vec3};
use crate::shape::Cuboid;

/// Edge cross products shorter than this (squared, Q64.64: sine² below
/// 2⁻²⁰) are skipped: the edges are parallel and the face axes cover them.
const MIN_EDGE_AXIS_SQ: u128 = 1 << 44;

/// Flag in an edge–edge contact's feature numbers.
const EDGE_FEATURE: u16 = 0x100;

/// Which axis the SAT chose.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoxAxis {
    /// Face normal `e_i` of A.
    FaceA(usize),
    /// Face normal `b_j` of B.
    FaceB(usize),
    /// The cross product of A's edge direction `i` and B's `j`.
    Edge(usize, usize),
}

/// The separating-axis result for two boxes, in A's frame. Kept public in
/// the crate so tests can compare it with an independent reference.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BoxSat {
    /// The chosen axis after the face preference.
    pub chosen: BoxAxis,
    /// Its separation (negative: penetration depth).
    pub separation: Scalar,
    /// The largest separation over all tested axes, before the preference.
    pub max_separation: Scalar,
    /// The chosen axis as a unit vector in A's frame, pointing from A to B.
    pub axis: Vec3,
}

fn sign_of(x: Scalar) -> Scalar {
    if x.is_negative() {
        Scalar::NEG_ONE
    } else {
        Scalar::ONE
    }
}

fn unit(k: usize) -> Vec3 {
    let mut e = Vec3::ZERO;
    e.set(k, Scalar::ONE);
    e
}

/// The two axes other than `k`, in increasing order.
fn other_axes(k: usize) -> [usize; 2] {
    match k {
        0 => [1, 2],
        1 => [0, 2],
        _ => [0, 1],
    }
}

/// SAT for boxes with half-extents `ha` (at A's origin, axis-aligned) and
/// `hb` (axes the columns of `rot`, centre `t`). Faces of A, then faces of
/// B, then the nine edge pairs in `(i, j)` order; a later group wins only by
/// more than [`sat_tolerance`] of the best so far, a later axis within a
/// group only by being strictly larger.
pub(crate) fn box_sat(ha: Vec3, hb: Vec3, rot: &Mat3, t: Vec3) -> BoxSat {
    let abs_cols = [rot.cols[0].abs(), rot.cols[1].abs(), rot.cols[2].abs()];
    let mut face_a = (Scalar::MIN, 0usize);
    for i in 0..3 {
        let rb = Scalar::from_wide(
            hb.x.wide_mul(abs_cols[0].get(i))
                + hb.y.wide_mul(abs_cols[1].get(i))
                + hb.z.wide_mul(abs_cols[2].get(i)),
        );
        let s = t.get(i).abs() - ha.get(i) - rb;
        if s > face_a.0 {
            face_a = (s, i);
        }
    }
    let mut face_b = (Scalar::MIN, 0usize);
    for (j, col) in abs_cols.iter().enumerate() {
        let ra = Scalar::from_wide(col.dot_wide(ha));
        let s = t.dot(rot.cols[j]).abs() - ra - hb.get(j);
        if s > face_b.0 {
            face_b = (s, j);
        }
    }
    let mut edge: Option<(Scalar, usize, usize, Vec3)> = None;
    for i in 0..3 {
        for j in 0..3 {
            let l = unit(i).cross(rot.cols[j]);
            if l.length_squared_wide() < MIN_EDGE_AXIS_SQ {
                continue;
            }
            let Some(mut l) = l.try_normalize() else {
                continue;
            };
            if t.dot_wide(l) < 0 {
                l = -l;
            }
            let ra = l.abs().dot_wide(ha);
            let rb = hb.x.wide_mul(l.dot(rot.cols[0]).abs())
                + hb.y.wide_mul(l.dot(rot.cols[1]).abs())
                + hb.z.wide_mul(l.dot(rot.cols[2]).abs());
            let s = Scalar::from_wide(t.dot_wide(l) - ra - rb);
            if edge.is_none_or(|(best, ..)| s > best) {
                edge = Some((s, i, j, l));
            }
        }
    }
    // Determinism: the order faces of A, faces of B, edges, each group in
    // index order with strict comparisons, is what makes ties go to the
    // lowest feature; do not reorder.
    let mut max_separation = face_a.0.max(face_b.0);
    let (mut chosen, mut separation) = (BoxAxis::FaceA(face_a.1), face_a.0);
    if face_b.0 > separation + sat_tolerance(separation) {
        chosen = BoxAxis::FaceB(face_b.1);
        separation = face_b.0;
    }
    let mut axis = match chosen {
        BoxAxis::FaceA(i) => unit(i) * sign_of(t.get(i)),
        _ => rot.cols[face_b.1] * sign_of(t.dot(rot.cols[face_b.1])),
    };
    if let Some((s, i, j, l)) = edge {
        max_separation = max_separation.max(s);
        if s > separation + sat_tolerance(separation) {
            chosen = BoxAxis::Edge(i, j);
            separation = s;
            axis = l;
        }
    }
    BoxSat {
        chosen,
        separation,
        max_separation,
        axis,
    }
}

/// Contact between boxes A and B.
///
/// SAT as in [`box_sat`] (faces of A preferred over faces of B, faces over
/// edges, within [`sat_tolerance`]). Any axis separating by more than
/// `margin` means no contact.
///
/// - Face axis: the face of the chosen box is the reference; the incident
///   face is the other box's face most anti-parallel to it (ties: lowest
///   axis). The incident quad is clipped against the reference face's four
///   side planes, vertices more than `margin` above the reference face are
///   dropped, and more than four are reduced to four: the deepest, the one
///   farthest from it, the one making the largest triangle with those, then
///   the one adding the most area. Each point sits midway between the
///   incident vertex and its projection on the reference face; depth is the
///   vertex's depth below the reference face. Ids: `(reference code,
///   incident code)` with reference code `8·(B is reference) + 2·axis +
///   (1 if − face)` and incident code `64·incident face + the clip vertex's
///   two edge labels` (see [`ClipVertex::label`]), so a point keeps its id
///   while the same features make it.
/// - Edge axis: one point midway between the closest points of the two
///   supporting edges, depth minus the separation, ids `(0x100 + edge of A,
///   0x100 + edge of B)` with edge `4·axis + sign bits`.
pub fn contact_box_box(
    a: &Cuboid,
    pose_a: &Transform,
    b: &Cuboid,
    pose_b: &Transform,
    margin: Scalar,
    out: &mut Manifold,
) -> bool {
    out.clear();
    let (t, q) = relative_pose(pose_a, pose_b);
    let (ha, hb) = (a.half_extents, b.half_extents);
    let reach = ha.x + ha.y + ha.z + hb.x + hb.y + hb.z + margin;
    if t.length_squared_wide() > reach.wide_mul(reach) as u128 {
        return false;
    }
    let rot = Mat3::from_quat(q);
    let sat = box_sat(ha, hb, &rot, t);
    if sat.max_separation > margin {
        return false;
    }
    match sat.chosen {
        BoxAxis::FaceA(i) => {
            let sigma = sign_of(t.get(i));
            out.normal = pose_a.transform_vector(unit(i) * sigma);
            face_contact(out, pose_a, 0, ha, hb, &rot, t, i, sigma, margin);
        }
        BoxAxis::FaceB(j) => {
            let rot_t = rot.transpose();
            let a_in_b = -rot_t.mul_vec(t);
            let sigma = sign_of(a_in_b.get(j));
            out.normal = pose_b.transform_vector(unit(j) * -sigma);
            face_contact(out, pose_b, 8, hb, ha, &rot_t, a_in_b, j, sigma, margin);
        }
        BoxAxis::Edge(i, j) => {
            let l = sat.axis;
            let mut signs_a = 0u16;
            let mut ca = Vec3::ZERO;
            for (bit, m) in other_axes(i).into_iter().enumerate() {
                let s = sign_of(l.get(m));
                ca.set(m, ha.get(m) * s);
                signs_a |= (!s.is_negative() as u16) << bit;
            }
            let (mut a0, mut a1) = (ca, ca);
            a0.set(i, -ha.get(i));
            a1.set(i, ha.get(i));
            let dir_b = rot.transpose_mul_vec(-l);
            let mut signs_b = 0u16;
            let mut cb = Vec3::ZERO;
            for (bit, m) in other_axes(j).into_iter().enumerate() {
                let s = sign_of(dir_b.get(m));
                cb.set(m, hb.get(m) * s);
                signs_b |= (!s.is_negative() as u16) << bit;
            }
            let (mut b0, mut b1) = (cb, cb);
            b0.set(j, -hb.get(j));
            b1.set(j, hb.get(j));
            let (b0, b1) = (rot.mul_vec(b0) + t, rot.mul_vec(b1) + t);
            let cp = closest_points_segments(a0, a1, b0, b1);
            out.normal = pose_a.transform_vector(l);
            let id = FeatureId::pair(
                EDGE_FEATURE + 4 * i as u16 + signs_a,
                EDGE_FEATURE + 4 * j as u16 + signs_b,
            );
            push_point(out, pose_a, (cp.p1 + cp.p2).half(), -sat.separation, id);
        }
    }
    !out.is_empty()
}

/// The face contact in the reference box's frame (`pose` maps it to world):
/// reference half-extents `rh`, face on axis `k` with outward sign `sigma`;
/// incident box with half-extents `ih`, axes the columns of `rot`, centre
/// `pos`.
#[allow(clippy::too_many_arguments)]
fn face_contact(
    out: &mut Manifold,
    pose: &Transform,
    ref_flag: u16,
    rh: Vec3,
    ih: Vec3,
    rot: &Mat3,
    pos: Vec3,
    k: usize,
    sigma: Scalar,
    margin: Scalar,
) {
    // Incident face: the most anti-parallel face of the incident box.
    let mut j = 0;
    for c in 1..3 {
        if rot.cols[c].get(k).abs() > rot.cols[j].get(k).abs() {
            j = c;
        }
    }
    let tau = -sign_of(rot.cols[j].get(k) * sigma);
    let [u, v] = other_axes(j);
    let mut poly = ClipPolygon::default();
    for (i, (su, sv)) in [(1, 1), (-1, 1), (-1, -1), (1, -1)].into_iter().enumerate() {
        let mut p = Vec3::ZERO;
        p.set(j, ih.get(j) * tau);
        p.set(u, ih.get(u).mul_int(su));
        p.set(v, ih.get(v).mul_int(sv));
        poly.v[i] = ClipVertex {
            p: rot.mul_vec(p) + pos,
            edge_in: ((i + 3) % 4) as u8,
            edge_out: i as u8,
        };
    }
    poly.len = 4;
    let mut other = ClipPolygon::default();
    let [c1, c2] = other_axes(k);
    let planes = [
        (c1, Scalar::ONE, 4u8),
        (c1, Scalar::NEG_ONE, 5),
        (c2, Scalar::ONE, 6),
        (c2, Scalar::NEG_ONE, 7),
    ];
    for (axis, sign, label) in planes {
        clip_polygon(&poly, axis, sign, rh.get(axis), label, &mut other);
        std::mem::swap(&mut poly, &mut other);
    }
    // Keep the vertices within the margin of the reference face.
    let mut pts = [(Vec3::ZERO, Scalar::ZERO, 0u16); MAX_CLIP_VERTICES];
    let mut n = 0;
    for cv in poly.vertices() {
        let depth = rh.get(k) - cv.p.get(k) * sigma;
        if depth >= -margin {
            let mut mid = cv.p;
            mid.set(k, (cv.p.get(k) + rh.get(k) * sigma).half());
            pts[n] = (mid, depth, cv.label());
            n += 1;
        }
    }
    let keep = reduce_to_four(&pts[..n], c1, c2);
    let ref_code = ref_flag + 2 * k as u16 + sigma.is_negative() as u16;
    let inc_face = 2 * j as u16 + tau.is_negative() as u16;
    for (idx, &(p, depth, label)) in pts[..n].iter().enumerate() {
        if keep & (1 << idx) != 0 {
            push_point(
                out,
                pose,
                p,
                depth,
                FeatureId::pair(ref_code, inc_face << 6 | label),
            );
        }
    }
}

/// Twice the signed area of triangle `a, b, c` projected on the plane of
/// axes `c1, c2`, exact.
fn area2(a: Vec3, b: Vec3, c: Vec3, c1: usize, c2: usize) -> i128 {
    let (e, f) = (b - a, c - a);
    e.get(c1).wide_mul(f.get(c2)) - e.get(c2).wide_mul(f.get(c1))
}

/// A bit mask of at most four of `pts` (all when there are four or fewer):
/// the deepest, the farthest from it, the one spanning the largest triangle
/// with those two, then the one adding the most area outside that triangle
/// (none if all lie inside). Ties go to the lowest index.
// Determinism: every choice scans in index order with strict comparisons and
// exact (i128) areas and distances, so ties go to the lowest index.
fn reduce_to_four(pts: &[(Vec3, Scalar, u16)], c1: usize, c2: usize) -> u32 {
    let n = pts.len();
    if n <= 4 {
        return (1u32 << n) - 1;
    }
    let mut i0 = 0;
    for i in 1..n {
        if pts[i].1 > pts[i0].1 {
            i0 = i;
        }
    }
    let p0 = pts[i0].0;
    let mut i1 = usize::MAX;
    let mut best = 0u128;
    for (i, pt) in pts.iter().enumerate() {
        let d = (pt.0 - p0).length_squared_wide();
        if i != i0 && (i1 == usize::MAX || d > best) {
            (i1, best) = (i, d);
        }
    }
    let p1 = pts[i1].0;
    let mut i2 = usize::MAX;
    let mut best = 0i128;
    for (i, pt) in pts.iter().enumerate() {
        let a = area2(p0, p1, pt.0, c1, c2);
        if i != i0 && i != i1 && (i2 == usize::MAX || a.abs() > best.abs()) {
            (i2, best) = (i, a);
        }
    }
    let mut mask = (1u32 << i0) | (1 << i1) | (1 << i2);
    // Orient the triangle counter-clockwise: outside an edge is negative.
    let (p2, orient) = (pts[i2].0, if best < 0 { -1 } else { 1 });
    let mut i3 = usize::MAX;
    let mut best = 0i128;
    for (i, pt) in pts.iter().enumerate() {
        if mask & (1 << i) != 0 {
            continue;
        }
        let gain = [(p0, p1), (p1, p2), (p2, p0)]
            .into_iter()
            .map(|(a, b)| -orient * area2(a, b, pt.0, c1, c2))
            .max()
            .unwrap_or(0);
        if gain > best {
            (i3, best) = (i, gain);
        }
    }
    if i3 != usize::MAX {
        mask |= 1 << i3;
    }
    mask
}
