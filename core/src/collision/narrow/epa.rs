//! EPA: penetration depth and normal of two overlapping convex shapes.
//!
//! When GJK finds the cores overlapping, its final simplex holds the
//! origin. EPA grows it into a polytope inside the Minkowski difference
//! `A − B`, always expanding the face nearest the origin by the support
//! point along that face's normal, until the support point brings no
//! progress. The nearest face then gives the penetration: its normal
//! (pointing from A to B) and its distance (the depth of the cores; the
//! radii are added on top).
//!
//! Fixed capacity, no allocation: at most [`EPA_MAX_VERTICES`] vertices and
//! [`EPA_MAX_FACES`] live faces (dead faces' slots are reused, lowest slot
//! first), and [`MAX_EPA_ITERATIONS`] expansions. When a capacity or the
//! iteration cap is reached, EPA stops and reports the nearest face so far
//! with `complete: false`: its depth is then a lower bound (the polytope is
//! inside `A − B`), its normal a valid but maybe not minimal direction.
//!
//! Determinism: the nearest face is the lowest slot among equal distances;
//! faces are created in horizon order (visible faces by slot, then their
//! edges in winding order). Face normals come from exact `i128` cross
//! products, normalised once, so thin faces of small shapes keep their
//! direction.
//!
//! Degenerate differences (a point against a point, or against a segment:
//! `A − B` has no volume) cannot hold a tetrahedron; EPA then returns a
//! depth of zero for the cores along a documented direction: +y of A's
//! frame for two points, a fixed perpendicular of the segment, or the plane
//! normal of a flat difference, turned to point from A's origin towards B's.

use super::gjk::{
    CoreResult, Pair, Rel, SVert, Simplex, SupportShape, closest_triangle, combine, cross_wide,
    gjk_core, unit_from_wide,
};
use crate::math::{Scalar, Transform, Vec3};

/// Most vertices of the expanding polytope (the starting tetrahedron plus
/// one per expansion).
pub const EPA_MAX_VERTICES: usize = 68;
/// Most live faces of the expanding polytope.
pub const EPA_MAX_FACES: usize = 128;
/// Most expansions.
pub const MAX_EPA_ITERATIONS: usize = 64;

/// The penetration of two overlapping shapes: how far and along which
/// direction B must move to just touch A.
///
/// Why: contact generation for pairs without a dedicated routine, and
/// queries that need the depth of an overlap.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Penetration {
    /// Overlap along `normal` (radii included), ≥ 0.
    pub depth: Scalar,
    /// Unit direction from A to B, world frame: moving B by
    /// `depth · normal` separates the shapes.
    pub normal: Vec3,
    /// The point of A deepest inside B, world frame.
    pub point_a: Vec3,
    /// The point of B deepest inside A, world frame
    /// (`point_a − depth · normal`).
    pub point_b: Vec3,
    /// False when EPA stopped on a capacity or the iteration cap (depth is
    /// then a lower bound).
    pub complete: bool,
}

/// The penetration of the cores, in A's frame.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CorePenetration {
    pub normal: Vec3,
    pub depth: Scalar,
    pub pa: Vec3,
    pub pb: Vec3,
    pub complete: bool,
}

#[derive(Clone, Copy, Default)]
struct Face {
    v: [u8; 3],
    n: Vec3,
    d: Scalar,
    alive: bool,
}

struct Polytope {
    verts: [SVert; EPA_MAX_VERTICES],
    nv: usize,
    faces: [Face; EPA_MAX_FACES],
    /// Slots used so far (live or dead).
    used: usize,
}

impl Polytope {
    fn face(&self, v: [u8; 3]) -> Face {
        let p = |i: u8| self.verts[i as usize].w;
        let (a, b, c) = (p(v[0]), p(v[1]), p(v[2]));
        match unit_from_wide(cross_wide(b - a, c - a)) {
            Some(n) => Face {
                v,
                n,
                d: n.dot(a),
                alive: true,
            },
            // A zero-area face is kept for the topology but never chosen.
            None => Face {
                v,
                n: Vec3::ZERO,
                d: Scalar::MAX,
                alive: true,
            },
        }
    }

    fn nearest(&self) -> Option<usize> {
        let mut best: Option<usize> = None;
        for (i, f) in self.faces[..self.used].iter().enumerate() {
            if f.alive && f.d < Scalar::MAX && best.is_none_or(|b| f.d < self.faces[b].d) {
                best = Some(i);
            }
        }
        best
    }
}

/// Whether `c` is off the line through `a` and `b` (exact).
fn off_line(a: Vec3, b: Vec3, c: Vec3) -> bool {
    cross_wide(b - a, c - a) != [0, 0, 0]
}

/// Sign of the orientation of `d` relative to the plane `abc`.
fn orient(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> i128 {
    let n = cross_wide(b - a, c - a);
    let mut all = [n[0], n[1], n[2], 0, 0, 0];
    let e = d - a;
    all[3] = e.x.to_bits() as i128;
    all[4] = e.y.to_bits() as i128;
    all[5] = e.z.to_bits() as i128;
    // Scale the normal alone down to 62 bits; the offset has ≤ 64.
    let mut nn = [all[0], all[1], all[2]];
    super::gjk::fit(&mut nn, 62);
    (nn[0] * all[3] + nn[1] * all[4] + nn[2] * all[5]).signum()
}

/// The documented result for a difference with no volume.
fn flat_result(rel: &Rel, normal: Vec3, v: &SVert) -> CorePenetration {
    let n = if normal.dot_wide(rel.t) < 0 {
        -normal
    } else {
        normal
    };
    CorePenetration {
        normal: n,
        depth: Scalar::ZERO,
        pa: v.a,
        pb: v.b,
        complete: true,
    }
}

/// EPA on the cores of a pair from GJK's final simplex, in A's frame.
pub(crate) fn epa_core<A: SupportShape + ?Sized, B: SupportShape + ?Sized>(
    pair: &Pair<'_, A, B>,
    simplex: &Simplex,
) -> CorePenetration {
    // Gather distinct starting points.
    let mut start = [SVert::default(); 4];
    let mut n = 0;
    for v in &simplex.v[..simplex.n] {
        if !start[..n].iter().any(|x| x.w == v.w) {
            start[n] = *v;
            n += 1;
        }
    }
    if n == 0 {
        start[0] = pair.support(Vec3::X);
        n = 1;
    }
    const AXES: [Vec3; 6] = [
        Vec3::X,
        Vec3::Y,
        Vec3::Z,
        Vec3::new(Scalar::NEG_ONE, Scalar::ZERO, Scalar::ZERO),
        Vec3::new(Scalar::ZERO, Scalar::NEG_ONE, Scalar::ZERO),
        Vec3::new(Scalar::ZERO, Scalar::ZERO, Scalar::NEG_ONE),
    ];
    // Grow to a segment.
    if n == 1 {
        for d in AXES {
            let w = pair.support(d);
            if w.w != start[0].w {
                start[1] = w;
                n = 2;
                break;
            }
        }
        if n == 1 {
            return flat_result(&pair.rel, Vec3::Y, &start[0]);
        }
    }
    // Grow to a triangle.
    if n == 2 {
        let ab = start[1].w - start[0].w;
        for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
            let perp = ab.cross(axis);
            if perp.is_zero() {
                continue;
            }
            for d in [perp, -perp] {
                let w = pair.support(d);
                if off_line(start[0].w, start[1].w, w.w) {
                    start[2] = w;
                    n = 3;
                    break;
                }
            }
            if n == 3 {
                break;
            }
        }
        if n == 2 {
            let dir = ab.try_normalize().unwrap_or(Vec3::X).any_orthonormal();
            return flat_result(&pair.rel, dir, &start[0]);
        }
    }
    // Grow to a tetrahedron.
    if n == 3 {
        let (a, b, c) = (start[0].w, start[1].w, start[2].w);
        let normal = unit_from_wide(cross_wide(b - a, c - a)).unwrap_or(Vec3::Y);
        for d in [normal, -normal] {
            let w = pair.support(d);
            if orient(a, b, c, w.w) != 0 {
                start[3] = w;
                n = 4;
                break;
            }
        }
        if n == 3 {
            return flat_result(&pair.rel, normal, &start[0]);
        }
    }
    let mut poly = Polytope {
        verts: [SVert::default(); EPA_MAX_VERTICES],
        nv: 4,
        faces: [Face::default(); EPA_MAX_FACES],
        used: 0,
    };
    poly.verts[..4].copy_from_slice(&start);
    // Wind the tetrahedron so that every face normal points away from the
    // opposite vertex.
    let p = |i: usize| start[i].w;
    let (b, c) = if orient(p(0), p(1), p(2), p(3)) > 0 {
        (2u8, 1u8)
    } else {
        (1u8, 2u8)
    };
    for v in [[0, b, c], [0, 3, b], [0, c, 3], [b, 3, c]] {
        poly.faces[poly.used] = poly.face(v);
        poly.used += 1;
    }
    let mut complete = false;
    let mut best = poly.nearest();
    for _ in 0..MAX_EPA_ITERATIONS {
        let Some(bi) = best else { break };
        let f = poly.faces[bi];
        let w = pair.support(f.n);
        let gap = w.w.dot(f.n) - f.d;
        let tol = Scalar::from_bits((f.d.to_bits().abs() >> 20) + 256);
        if gap <= tol || poly.verts[..poly.nv].iter().any(|x| x.w == w.w) {
            complete = true;
            break;
        }
        if poly.nv == EPA_MAX_VERTICES {
            break;
        }
        // Faces that see the new point.
        let mut visible = [false; EPA_MAX_FACES];
        for (i, g) in poly.faces[..poly.used].iter().enumerate() {
            if g.alive {
                let a = poly.verts[g.v[0] as usize].w;
                // A zero-area face has no plane: it never sees the point
                // (it stays, keeping the surface closed).
                visible[i] = i == bi || (!g.n.is_zero() && g.n.dot_wide(w.w - a) > 0);
            }
        }
        // Horizon: edges of visible faces whose twin is not visible.
        let mut horizon = [(0u8, 0u8); 3 * EPA_MAX_FACES];
        let mut nh = 0;
        for i in 0..poly.used {
            if !visible[i] {
                continue;
            }
            let v = poly.faces[i].v;
            for k in 0..3 {
                let (s, e) = (v[k], v[(k + 1) % 3]);
                let twin_visible = (0..poly.used).any(|j| {
                    visible[j] && {
                        let u = poly.faces[j].v;
                        (0..3).any(|m| u[m] == e && u[(m + 1) % 3] == s)
                    }
                });
                if !twin_visible && nh < horizon.len() {
                    horizon[nh] = (s, e);
                    nh += 1;
                }
            }
        }
        let live_after = poly.faces[..poly.used]
            .iter()
            .enumerate()
            .filter(|(i, g)| g.alive && !visible[*i])
            .count();
        if live_after + nh > EPA_MAX_FACES {
            break;
        }
        let wi = poly.nv as u8;
        poly.verts[poly.nv] = w;
        poly.nv += 1;
        for (i, g) in poly.faces[..poly.used].iter_mut().enumerate() {
            if visible[i] {
                g.alive = false;
            }
        }
        let mut slot = 0;
        for &(s, e) in &horizon[..nh] {
            while slot < poly.used && poly.faces[slot].alive {
                slot += 1;
            }
            let face = poly.face([s, e, wi]);
            poly.faces[slot] = face;
            if slot == poly.used {
                poly.used += 1;
            }
        }
        best = poly.nearest();
    }
    let Some(bi) = best else {
        return flat_result(&pair.rel, Vec3::Y, &start[0]);
    };
    let f = poly.faces[bi];
    let sv = [
        poly.verts[f.v[0] as usize],
        poly.verts[f.v[1] as usize],
        poly.verts[f.v[2] as usize],
    ];
    let (idx, l, k) = closest_triangle(sv[0].w, sv[1].w, sv[2].w);
    let pick = |g: fn(&SVert) -> Vec3| -> Vec3 {
        let pts = [g(&sv[idx[0]]), g(&sv[idx[1]]), g(&sv[idx[2]])];
        combine(&pts[..k], &l[..k])
    };
    CorePenetration {
        normal: f.n,
        depth: f.d.max(Scalar::ZERO),
        pa: pick(|s| s.a),
        pb: pick(|s| s.b),
        complete,
    }
}

/// The penetration of `a` at `pose_a` and `b` at `pose_b`, or `None` when
/// they are apart (when [`distance`](super::gjk::distance) reports them
/// separated).
///
/// Round cores (spheres, capsules) separated by less than their radii are
/// answered from GJK alone; overlapping cores go through EPA and get the
/// radii added to the depth. Integer-only, bounded work, no allocation;
/// translation invariant bit for bit.
pub fn penetration<A: SupportShape + ?Sized, B: SupportShape + ?Sized>(
    a: &A,
    pose_a: &Transform,
    b: &B,
    pose_b: &Transform,
) -> Option<Penetration> {
    let pair = Pair {
        a,
        b,
        rel: Rel::new(pose_a, pose_b),
    };
    let (ra, rb) = (a.core_radius(), b.core_radius());
    let (n, core_depth, pa, pb, complete) = match gjk_core(&pair) {
        CoreResult::Separated { pa, pb, v, vv, .. } => {
            let core = Scalar::from_bits(crate::math::elem::isqrt_u128(vv) as i64);
            if (core - ra - rb).to_bits() > 16 {
                return None;
            }
            let n = (-v).try_normalize().unwrap_or(Vec3::Y);
            (n, -core, pa, pb, true)
        }
        CoreResult::Overlapping(s) => {
            let p = epa_core(&pair, &s);
            (p.normal, p.depth, p.pa, p.pb, p.complete)
        }
    };
    let depth = (core_depth + ra + rb).max(Scalar::ZERO);
    Some(Penetration {
        depth,
        normal: pose_a.transform_vector(n),
        point_a: pose_a.transform_point(pa + n * ra),
        point_b: pose_a.transform_point(pb - n * rb),
        complete,
    })
}
