//! The views the polytope SAT works through: [`Poly`], what it needs of a
//! shape (a box or a hull, in its own frame), and [`Frame`], a shape as
//! seen from A's frame, where the exact tests run: A itself ([`Fixed`]) or
//! B moved there ([`Moved`]), whose planes and arcs are computed only when
//! a test asks for them.

use std::mem::MaybeUninit;

use super::super::gjk::Rel;
use super::super::shared::BOX_FACE_LOOPS;
use super::{MAX_SAT_EDGES, MAX_SAT_FACES, MAX_SAT_VERTICES};
use crate::math::{Scalar, Vec3};
use crate::shape::sat_features::{Balls, NO_FACE};
use crate::shape::{ConvexHull, Cuboid};

/// The polyhedron view that SAT and clipping need.
pub(crate) trait Poly {
    fn vertices(&self) -> &[Vec3];
    fn nf(&self) -> usize;
    fn normal(&self, f: usize) -> Vec3;
    fn offset(&self, f: usize) -> Scalar;
    fn face(&self, f: usize) -> &[u32];
    fn edges(&self) -> &[[u32; 2]];
    /// The two faces of edge `e`: [face running low→high, high→low].
    fn edge_faces(&self, e: usize) -> [u16; 2];
    /// `n₁ × n₀` of edge `e`'s two face normals: the normal of the edge's
    /// arc on the Gauss map.
    fn arc(&self, e: usize) -> Vec3;
    /// A cone `(axis, radius)` holding edge `e`'s arc of normals.
    fn cone(&self, e: usize) -> (Vec3, Scalar);
    fn balls(&self) -> &Balls;
}

/// A box as a polyhedron: corners by index bits (bit 0: +x, bit 1: +y,
/// bit 2: +z), faces −x +x −y +y −z +z counter-clockwise from outside.
pub(crate) struct BoxPoly {
    corners: [Vec3; 8],
    half: Vec3,
    balls: Balls,
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

/// The two faces of each box edge, as [`SatFeatures`] defines them (the
/// face whose loop runs low → high, then high → low), from the face loops.
const BOX_EDGE_FACES: [[u16; 2]; 12] = {
    let mut adj = [[NO_FACE; 2]; 12];
    let mut f = 0;
    while f < 6 {
        let mut k = 0;
        while k < 4 {
            let (u, v) = (BOX_FACE_LOOPS[f][k], BOX_FACE_LOOPS[f][(k + 1) % 4]);
            let (lo, hi) = if u < v { (u, v) } else { (v, u) };
            let mut e = 0;
            while e < 12 {
                if BOX_EDGES[e][0] == lo && BOX_EDGES[e][1] == hi {
                    adj[e][(u > v) as usize] = f as u16;
                }
                e += 1;
            }
            k += 1;
        }
        f += 1;
    }
    adj
};

/// Unit normal of box face `f`.
fn box_normal(f: usize) -> Vec3 {
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

/// 1/√2 rounded to nearest (0xB504F333.F9DE… × 2⁻³²).
const INV_SQRT2: Scalar = Scalar::from_bits(0xB504_F334);
/// √(2 − √2) = 0.76537 (the distance from a box face normal to the mean
/// of two perpendicular ones), rounded up with room for the mean's
/// rounding.
const BOX_CONE_RADIUS: Scalar = Scalar::from_bits(3_287_280_000);

impl BoxPoly {
    pub(crate) fn new(c: &Cuboid) -> BoxPoly {
        let half = c.half_extents;
        let far =
            Scalar::from_bits(crate::math::elem::isqrt_u128(half.length_squared_wide()) as i64);
        BoxPoly {
            corners: c.corners(),
            half,
            balls: Balls {
                center: Vec3::ZERO,
                inner: half.min_element(),
                outer: far + Scalar::from_bits(1),
            },
        }
    }
}

impl Poly for BoxPoly {
    fn vertices(&self) -> &[Vec3] {
        &self.corners
    }
    fn nf(&self) -> usize {
        6
    }
    fn normal(&self, f: usize) -> Vec3 {
        box_normal(f)
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
    fn edge_faces(&self, e: usize) -> [u16; 2] {
        BOX_EDGE_FACES[e]
    }
    fn arc(&self, e: usize) -> Vec3 {
        let [f0, f1] = BOX_EDGE_FACES[e];
        box_normal(f1 as usize).cross(box_normal(f0 as usize))
    }
    fn cone(&self, e: usize) -> (Vec3, Scalar) {
        let [f0, f1] = BOX_EDGE_FACES[e];
        let axis = box_normal(f0 as usize) + box_normal(f1 as usize);
        (axis * INV_SQRT2, BOX_CONE_RADIUS)
    }
    fn balls(&self) -> &Balls {
        &self.balls
    }
}

impl Poly for ConvexHull {
    fn vertices(&self) -> &[Vec3] {
        ConvexHull::vertices(self)
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
    fn edge_faces(&self, e: usize) -> [u16; 2] {
        self.sat().edge_faces[e]
    }
    fn arc(&self, e: usize) -> Vec3 {
        self.sat().arcs[e]
    }
    fn cone(&self, e: usize) -> (Vec3, Scalar) {
        self.sat().cones[e]
    }
    fn balls(&self) -> &Balls {
        &self.sat().balls
    }
}

/// A polyhedron as the SAT sees it in A's frame: its vertices there, and
/// its face planes and Gauss-map arcs there, each computed on first use.
pub(super) trait Frame {
    type P: Poly;
    fn poly(&self) -> &Self::P;
    /// Every vertex, in A's frame.
    fn verts(&self) -> &[Vec3];
    /// Face `f`'s plane in A's frame: (unit normal, offset).
    fn plane(&mut self, f: usize) -> (Vec3, Scalar);
    /// Edge `e`'s arc normal in A's frame (its two faces exist).
    fn arc(&mut self, e: usize) -> Vec3;
}

/// A itself: its own frame, nothing to compute.
pub(super) struct Fixed<'p, P: Poly>(pub(super) &'p P);

impl<P: Poly> Frame for Fixed<'_, P> {
    type P = P;
    fn poly(&self) -> &P {
        self.0
    }
    fn verts(&self) -> &[Vec3] {
        self.0.vertices()
    }
    fn plane(&mut self, f: usize) -> (Vec3, Scalar) {
        (self.0.normal(f), self.0.offset(f))
    }
    fn arc(&mut self, e: usize) -> Vec3 {
        self.0.arc(e)
    }
}

/// B moved into A's frame: every vertex at once (the face tests read them
/// all); planes and arcs only as they are asked for, since the bounds
/// leave most faces and edges of a pair untested.
///
/// The arrays are sized for the largest hull but left uninitialised: a
/// hull-hull pair is built once per touching pair and step, and zeroing
/// 20 KB each time was a seventh of a hull pile's instructions. Only the
/// first `nv` vertices, and the planes and arcs whose bit is set in
/// `planes_done` / `arcs_done`, are ever read.
pub(super) struct Moved<'p, P: Poly> {
    pub(super) p: &'p P,
    rel: &'p Rel,
    /// The first `nv` are written by `new`.
    verts: [MaybeUninit<Vec3>; MAX_SAT_VERTICES],
    nv: usize,
    planes: [MaybeUninit<(Vec3, Scalar)>; MAX_SAT_FACES],
    arcs: [MaybeUninit<Vec3>; MAX_SAT_EDGES],
    /// Bit `f` of `planes_done`, bit `e` of `arcs_done`: written.
    planes_done: [u64; MAX_SAT_FACES.div_ceil(64)],
    arcs_done: [u64; MAX_SAT_EDGES.div_ceil(64)],
}

impl<'p, P: Poly> Moved<'p, P> {
    pub(super) fn new(p: &'p P, rel: &'p Rel) -> Moved<'p, P> {
        let mut verts = [const { MaybeUninit::uninit() }; MAX_SAT_VERTICES];
        let mut nv = 0;
        for (slot, v) in verts.iter_mut().zip(p.vertices()) {
            slot.write(rel.point(*v));
            nv += 1;
        }
        Moved {
            p,
            rel,
            verts,
            nv,
            planes: [const { MaybeUninit::uninit() }; MAX_SAT_FACES],
            arcs: [const { MaybeUninit::uninit() }; MAX_SAT_EDGES],
            planes_done: [0; MAX_SAT_FACES.div_ceil(64)],
            arcs_done: [0; MAX_SAT_EDGES.div_ceil(64)],
        }
    }

    /// Face `f`'s plane in A's frame, as [`Frame::plane`] gives it: the
    /// stored one if computed, else computed now (the same value) without
    /// storing it.
    pub(super) fn plane_at(&self, f: usize) -> (Vec3, Scalar) {
        if self.planes_done[f / 64] & (1u64 << (f % 64)) != 0 {
            // SAFETY: the bit of `f` is set only after `planes[f]` was
            // written (`Frame::plane`).
            unsafe { self.planes[f].assume_init() }
        } else {
            self.compute_plane(f)
        }
    }

    /// Edge `e`'s arc in A's frame, as [`Frame::arc`] gives it (computed
    /// now if not stored, the same value).
    pub(super) fn arc_at(&self, e: usize) -> Vec3 {
        if self.arcs_done[e / 64] & (1u64 << (e % 64)) != 0 {
            // SAFETY: the bit of `e` is set only after `arcs[e]` was written
            // (`Frame::arc`).
            unsafe { self.arcs[e].assume_init() }
        } else {
            let [f0, f1] = self.p.edge_faces(e);
            let n0 = self.plane_at(f0 as usize).0;
            self.plane_at(f1 as usize).0.cross(n0)
        }
    }

    fn compute_plane(&self, f: usize) -> (Vec3, Scalar) {
        let m = self.rel.rot.mul_vec(self.p.normal(f));
        (m, self.p.offset(f) + m.dot(self.rel.t))
    }
}

impl<P: Poly> Frame for Moved<'_, P> {
    type P = P;
    fn poly(&self) -> &P {
        self.p
    }
    fn verts(&self) -> &[Vec3] {
        let init = &self.verts[..self.nv];
        // SAFETY: the first `nv` vertices were written in `new`, and
        // `MaybeUninit<Vec3>` has the layout of `Vec3`.
        unsafe { std::slice::from_raw_parts(init.as_ptr().cast::<Vec3>(), init.len()) }
    }
    fn plane(&mut self, f: usize) -> (Vec3, Scalar) {
        let bit = 1u64 << (f % 64);
        if self.planes_done[f / 64] & bit == 0 {
            let plane = self.compute_plane(f);
            self.planes[f].write(plane);
            self.planes_done[f / 64] |= bit;
            return plane;
        }
        self.plane_at(f)
    }
    fn arc(&mut self, e: usize) -> Vec3 {
        let bit = 1u64 << (e % 64);
        if self.arcs_done[e / 64] & bit == 0 {
            let [f0, f1] = self.p.edge_faces(e);
            let n0 = self.plane(f0 as usize).0;
            let arc = self.plane(f1 as usize).0.cross(n0);
            self.arcs[e].write(arc);
            self.arcs_done[e / 64] |= bit;
            return arc;
        }
        self.arc_at(e)
    }
}
