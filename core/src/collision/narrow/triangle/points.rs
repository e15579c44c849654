//! The contact points of one convex shape on one triangle, once the
//! triangle SAT (the parent module) has chosen the axis: clipping of the
//! incident polygon against the reference one for face axes, closest
//! points for edge–edge and round-core axes. It sits apart from the SAT
//! because it only consumes the SAT's verdict ([`TriSat`]) and the shape
//! view ([`Convex`]); the two halves meet at that result and nowhere else.
//!
//! Point labels (14 bits, the low part of the mesh feature id):
//! `0x1000 | incident label` when the triangle's face is the reference,
//! `0x2000 | triangle corner label` when a shape face is, where a vertex
//! made by clipping is labelled `0x800 | side << 8 | (low 8 bits of the cut
//! edge's start label)`; `0x3000 | triangle edge << 10 | shape edge` for
//! edge–edge; `0x3c00 | code << 1 | segment end` for round cores, with code
//! 0 for the face, 1–3 for edges and 4–6 for corners.

use super::{Axis, Convex, Kind, MAX_POLY, TriFeature, TriSat, Triangle, closest_on_triangle};
use crate::collision::narrow::segment::closest_points_segments;
use crate::collision::narrow::shared::ratio01;
use crate::math::{Scalar, Vec3};

/// A clipped polygon on a fixed buffer, each vertex with a 12-bit label.
#[derive(Clone, Copy)]
struct Poly {
    p: [Vec3; MAX_POLY],
    id: [u16; MAX_POLY],
    len: usize,
}

impl Poly {
    fn new() -> Poly {
        Poly {
            p: [Vec3::ZERO; MAX_POLY],
            id: [0; MAX_POLY],
            len: 0,
        }
    }

    fn push(&mut self, p: Vec3, id: u16) {
        if self.len < MAX_POLY {
            self.p[self.len] = p;
            self.id[self.len] = id & 0xfff;
            self.len += 1;
        }
    }

    /// Keeps the part where `s · (x − o) ≥ 0` (`s` need not be unit).
    /// A vertex cut by plane `plane` from the edge starting at vertex label
    /// `l` gets label `0x800 | plane << 8 | (l & 0xff)`.
    fn clip(&self, s: Vec3, o: Vec3, plane: u16, out: &mut Poly) {
        out.len = 0;
        if self.len == 0 {
            return;
        }
        let side = |x: Vec3| s.dot_wide(x - o);
        let mut prev = self.len - 1;
        let mut dp = side(self.p[prev]);
        for i in 0..self.len {
            let di = side(self.p[i]);
            let (pin, iin) = (dp >= 0, di >= 0);
            if pin != iin {
                let t = ratio01(dp.abs(), dp.abs() + di.abs());
                let x = self.p[prev] + (self.p[i] - self.p[prev]) * t;
                out.push(x, 0x800 | plane << 8 | (self.id[prev] & 0xff));
            }
            if iin {
                out.push(self.p[i], self.id[i]);
            }
            prev = i;
            dp = di;
        }
    }
}

/// A contact point of one triangle, in the shape's frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct TriPoint {
    /// Midway between the two surfaces.
    pub p: Vec3,
    /// Penetration depth along the triangle's contact axis.
    pub depth: Scalar,
    /// A 14-bit label of the features within the triangle contact.
    pub id: u16,
}

/// Whether a segment of direction `dir` lies within about 5° of the plane of
/// unit normal `n`.
fn lies_along(n: Vec3, dir: Vec3) -> bool {
    let a = n.dot(dir);
    a.wide_mul(a) as u128 <= dir.length_squared_wide() >> 7
}

/// The contact points of `shape` on `tri` for the axis `sat` chose, written
/// to `sink` (at most [`MAX_POLY`]). Points more than `margin` apart are
/// dropped; if clipping leaves nothing, the single deepest point is used.
pub(crate) fn triangle_points(
    shape: &Convex,
    tri: &Triangle,
    sat: &TriSat,
    margin: Scalar,
    sink: &mut impl FnMut(TriPoint),
) {
    let n = sat.axis;
    let r = shape.radius;
    let verts = shape.vertices();
    match sat.kind {
        Axis::TriFace => {
            // Reference: the triangle. Incident: the shape's most
            // anti-parallel face, the capsule segment lying along the plane,
            // or the deepest core point.
            let mut poly = Poly::new();
            let mut clip = true;
            match shape.kind {
                Kind::Point => {
                    poly.push(Vec3::ZERO, 0);
                    clip = false;
                }
                Kind::Segment([s0, s1]) => {
                    if lies_along(n, s1 - s0) {
                        poly.push(s0, 0);
                        poly.push(s1, 1);
                    } else {
                        let i = (n.dot(s1) < n.dot(s0)) as usize;
                        poly.push([s0, s1][i], i as u16);
                        clip = false;
                    }
                }
                Kind::Box(..) | Kind::Hull(_) => {
                    let mut best = (Scalar::MAX, 0usize);
                    for f in 0..shape.face_count() {
                        let d = shape.face_plane(f).0.dot(n);
                        if d < best.0 {
                            best = (d, f);
                        }
                    }
                    let lp = shape.face_loop(best.1);
                    if lp.len() + 3 > MAX_POLY {
                        clip = false;
                    } else {
                        for &i in lp {
                            poly.push(verts[i as usize], i as u16);
                        }
                    }
                }
            }
            if clip {
                let mut other = Poly::new();
                for k in 0..3 {
                    let (a, b) = (tri.v[k], tri.v[(k + 1) % 3]);
                    poly.clip(n.cross(b - a), a, k as u16, &mut other);
                    std::mem::swap(&mut poly, &mut other);
                }
                // The incident face need not hold the deepest corner of a
                // hull (or a segment's lower end): add it when it lies over
                // the triangle, so the manifold keeps the real depth.
                let (k, &v) = deepest(verts, n);
                let over = lies_over(tri, n, v);
                let known = poly.id[..poly.len].contains(&(k as u16 & 0xfff));
                if over && !known {
                    poly.push(v, k as u16);
                }
            }
            let plane = n.dot(tri.v[0]);
            // Unclipped round cores: capped by the SAT's depth (see
            // `triangle_sat`'s fallback to the face normal); clipped points
            // lie over the triangle, where the plane depth is the real one.
            let cap = if clip { Scalar::MAX } else { -sat.sep };
            let mut any = false;
            for i in 0..poly.len {
                let s = poly.p[i] - n * r;
                let depth = (plane - n.dot(s)).min(cap);
                if depth >= -margin {
                    any = true;
                    sink(TriPoint {
                        p: s + n * depth.half(),
                        depth,
                        id: 0x1000 | poly.id[i],
                    });
                }
            }
            if !any {
                // Never deeper than the SAT says (the deepest corner may lie
                // outside this triangle when the face normal was forced).
                let (k, &v) = deepest(verts, n);
                let s = v - n * r;
                let depth = (plane - n.dot(s)).min(-sat.sep);
                sink(TriPoint {
                    p: s + n * depth.half(),
                    depth,
                    id: 0x1000 | (k as u16 & 0xfff),
                });
            }
        }
        Axis::ShapeFace(f) => {
            // Reference: the shape's face; incident: the triangle.
            let (m, d) = shape.face_plane(f);
            let lp = shape.face_loop(f);
            let mut poly = Poly::new();
            for (k, &v) in tri.v.iter().enumerate() {
                poly.push(v, k as u16);
            }
            let mut other = Poly::new();
            if lp.len() + 3 > MAX_POLY {
                // Too many side planes for the buffer: deepest corner only.
                poly.len = 0;
            }
            for (j, &i) in lp.iter().enumerate() {
                if poly.len == 0 {
                    break;
                }
                let (a, b) = (verts[i as usize], verts[lp[(j + 1) % lp.len()] as usize]);
                poly.clip(m.cross(b - a), a, (j & 7) as u16, &mut other);
                std::mem::swap(&mut poly, &mut other);
            }
            let mut any = false;
            for i in 0..poly.len {
                let depth = d - m.dot(poly.p[i]);
                if depth >= -margin {
                    any = true;
                    sink(TriPoint {
                        p: poly.p[i] + m * depth.half(),
                        depth,
                        id: 0x2000 | poly.id[i],
                    });
                }
            }
            if !any {
                let (k, &v) = deepest(&tri.v, m);
                let depth = d - m.dot(v);
                sink(TriPoint {
                    p: v + m * depth.half(),
                    depth,
                    id: 0x2000 | k as u16,
                });
            }
        }
        Axis::Edge(k, e) => {
            let [ia, ib] = shape.edges()[e];
            let cp = closest_points_segments(
                tri.v[k],
                tri.v[(k + 1) % 3],
                verts[ia as usize],
                verts[ib as usize],
            );
            let s = cp.p2 - n * r;
            sink(TriPoint {
                p: (s + cp.p1).half(),
                depth: -sat.sep,
                id: 0x3000 | ((k as u16) << 10) | (e as u16 & 0x3ff),
            });
        }
        Axis::Round { tri: q, core } => {
            let s = core - n * r;
            let code = match closest_on_triangle(core, &tri.v).1 {
                TriFeature::Face => 0,
                TriFeature::Edge(k) => 1 + k as u16,
                TriFeature::Corner(k) => 4 + k as u16,
            };
            let end = (core == verts[verts.len() - 1]) as u16;
            sink(TriPoint {
                p: (s + q).half(),
                depth: -sat.sep,
                id: 0x3c00 | code << 1 | end,
            });
        }
    }
}

/// Whether `v` lies over `tri` seen along `n` (inside its three edge
/// planes, as the clipping keeps).
fn lies_over(tri: &Triangle, n: Vec3, v: Vec3) -> bool {
    (0..3).all(|e| {
        let (a, b) = (tri.v[e], tri.v[(e + 1) % 3]);
        n.cross(b - a).dot_wide(v - a) >= 0
    })
}

/// The shape's deepest point along a contact axis: its deepest core point
/// (found once per pair) with the radius below it. A flat region of a mesh
/// acts as one plane for this corner when it sank under a neighbour of the
/// triangles that touch (see the mesh contact's step 3).
#[derive(Clone, Copy)]
pub(crate) struct DeepestCorner {
    /// The core point's index, for its label.
    k: usize,
    /// The core point.
    v: Vec3,
    /// The axis.
    n: Vec3,
    /// The surface point below the core point (the radius along `−n`).
    s: Vec3,
}

impl DeepestCorner {
    /// The deepest core point of `shape` along `n`.
    pub(crate) fn of(shape: &Convex, n: Vec3) -> DeepestCorner {
        let (k, &v) = deepest(shape.vertices(), n);
        DeepestCorner {
            k,
            v,
            n,
            s: v - n * shape.radius,
        }
    }

    /// The corner measured against `tri`'s plane across the axis, when it
    /// lies over `tri`; labelled as the face-axis points are.
    pub(crate) fn over(&self, tri: &Triangle) -> Option<TriPoint> {
        if !lies_over(tri, self.n, self.v) {
            return None;
        }
        let depth = self.n.dot(tri.v[0]) - self.n.dot(self.s);
        Some(TriPoint {
            p: self.s + self.n * depth.half(),
            depth,
            id: 0x1000 | (self.k as u16 & 0xfff),
        })
    }
}

/// The point of `pts` with the smallest projection on `n` (the first on
/// ties) and its index; `k` counts from the end for the triangle fallback.
fn deepest(pts: &[Vec3], n: Vec3) -> (usize, &Vec3) {
    let mut best = 0;
    for i in 1..pts.len() {
        if n.dot_wide(pts[i]) < n.dot_wide(pts[best]) {
            best = i;
        }
    }
    (best, &pts[best])
}
