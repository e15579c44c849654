//! Clipping in a box's local frame, on fixed-size buffers (no allocation):
//! a polygon against the side planes of a reference face, and a segment
//! against a face's rectangle.

use super::shared::ratio01;
use crate::math::{Scalar, Vec3};

/// The most vertices a clipped polygon can have: a quadrilateral clipped by
/// four planes gains at most one vertex per plane.
pub const MAX_CLIP_VERTICES: usize = 8;

/// A polygon vertex with the two edge labels that meet at it, so a clipped
/// vertex is named by the features that made it rather than by its position
/// in the buffer. Labels 0–3 are the incident face's edges, 4–7 the clip
/// planes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClipVertex {
    /// Position (in the reference box's frame).
    pub p: Vec3,
    /// The edge arriving at this vertex.
    pub edge_in: u8,
    /// The edge leaving this vertex.
    pub edge_out: u8,
}

impl ClipVertex {
    /// The 6-bit label `edge_in · 8 + edge_out`: equal between steps when
    /// the same features produce the vertex.
    pub fn label(&self) -> u16 {
        (self.edge_in as u16) << 3 | self.edge_out as u16
    }
}

/// A convex polygon of at most [`MAX_CLIP_VERTICES`] vertices.
#[derive(Clone, Copy, Debug, Default)]
pub struct ClipPolygon {
    /// The vertices; only the first `len` are meaningful.
    pub v: [ClipVertex; MAX_CLIP_VERTICES],
    /// Number of vertices in use.
    pub len: usize,
}

impl ClipPolygon {
    /// Appends a vertex (ignored when full, which a quad clipped by four
    /// planes never is).
    fn push(&mut self, v: ClipVertex) {
        if self.len < MAX_CLIP_VERTICES {
            self.v[self.len] = v;
            self.len += 1;
        }
    }

    /// The vertices in use.
    pub fn vertices(&self) -> &[ClipVertex] {
        &self.v[..self.len]
    }
}

/// Keeps the part of `input` where `sign · p[axis] ≤ limit` (`sign` ±1),
/// Sutherland–Hodgman style, writing into `out`. A new vertex where edge `e`
/// crosses the plane gets labels (plane, e) when entering and (e, plane) when
/// leaving; its clipped coordinate is set to exactly `sign · limit`.
pub fn clip_polygon(
    input: &ClipPolygon,
    axis: usize,
    sign: Scalar,
    limit: Scalar,
    plane: u8,
    out: &mut ClipPolygon,
) {
    out.len = 0;
    let n = input.len;
    if n == 0 {
        return;
    }
    let side = |p: Vec3| p.get(axis) * sign - limit;
    let mut prev = input.v[n - 1];
    let mut prev_d = side(prev.p);
    for i in 0..n {
        let cur = input.v[i];
        let cur_d = side(cur.p);
        let prev_in = !prev_d.is_positive();
        let cur_in = !cur_d.is_positive();
        if prev_in != cur_in {
            // Crossing: t from prev to cur where the distance reaches zero.
            // t = prev_d / (prev_d − cur_d), the signs made positive.
            let (num, den) = (
                prev_d.to_bits() as i128,
                prev_d.to_bits() as i128 - cur_d.to_bits() as i128,
            );
            let t = if den < 0 {
                ratio01(-num, -den)
            } else {
                ratio01(num, den)
            };
            let mut p = prev.p + (cur.p - prev.p) * t;
            p.set(axis, limit * sign);
            let edge = prev.edge_out;
            let (edge_in, edge_out) = if cur_in { (plane, edge) } else { (edge, plane) };
            out.push(ClipVertex {
                p,
                edge_in,
                edge_out,
            });
        }
        if cur_in {
            out.push(cur);
        }
        prev = cur;
        prev_d = cur_d;
    }
}

/// `n / d`, saturating to the extreme of the quotient's sign when it does
/// not fit (a segment almost parallel to a slab).
fn div_saturating(n: Scalar, d: Scalar) -> Scalar {
    n.checked_div(d)
        .unwrap_or(if n.is_negative() == d.is_negative() {
            Scalar::MAX
        } else {
            Scalar::MIN
        })
}

/// The parameter range `[t_lo, t_hi] ⊆ [0, 1]` of the segment `p0`–`p1`
/// whose points lie within the box's slabs on the two axes other than `k`
/// (the rectangle of the faces normal to `k`, extruded), or `None` if empty.
pub fn clip_segment_to_face(p0: Vec3, p1: Vec3, h: Vec3, k: usize) -> Option<(Scalar, Scalar)> {
    let (mut lo, mut hi) = (Scalar::ZERO, Scalar::ONE);
    for j in 0..3 {
        if j == k {
            continue;
        }
        let (a, d, w) = (p0.get(j), p1.get(j) - p0.get(j), h.get(j));
        if d.is_zero() {
            if a.abs() > w {
                return None;
            }
            continue;
        }
        let t0 = div_saturating(-w - a, d);
        let t1 = div_saturating(w - a, d);
        lo = lo.max(t0.min(t1));
        hi = hi.min(t0.max(t1));
    }
    if lo > hi { None } else { Some((lo, hi)) }
}
