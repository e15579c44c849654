//! GJK: the distance and closest points between two convex shapes, from
//! nothing but their support functions.
//!
//! Every shape is seen as a *core* (a point, a segment, a box or a polytope)
//! grown by a radius ([`SupportShape`]): a sphere is a point plus its radius,
//! a capsule a segment plus its radius. GJK runs on the cores, and the radii
//! are subtracted at the end, so round shapes cost no more than a point.
//!
//! Fixed point, integers only:
//! * dot products are exact `i128` (Q64.64); the sub-simplex solver works on
//!   those, shifting a whole set of them right by a common amount only when
//!   their products would leave `i128` (beyond ~1 m² no precision that
//!   matters is lost: the relative error stays near 2⁻⁶⁰);
//! * barycentric weights are Q2.62 integers that sum to exactly 2⁶²;
//! * degenerate simplices (repeated, collinear or coplanar points) fall back
//!   to their faces and edges: a zero denominator is never divided by;
//! * the loop stops when the support point brings no progress (an integer
//!   comparison of `|v|²` with `v·w`), when the distance stops decreasing,
//!   when a support point repeats, or after [`MAX_GJK_ITERATIONS`]. Every
//!   exit returns the best simplex found: its closest point is a point of
//!   the Minkowski difference, so the distance reported is never *below* the
//!   true one (an upper bound with valid witness points).
//!
//! Everything is computed in A's local frame from the exact difference of
//! the translations, so moving both shapes by the same offset gives the same
//! bits (see `Rel`).

use crate::math::scalar::round_shift;
use crate::math::{Mat3, Scalar, Transform, Vec3};
use crate::shape::{Capsule, ConvexHull, Cuboid, Sphere};

/// The most GJK iterations: each adds one support point, and a polytope
/// pair that needs more than a few dozen is cycling on rounding.
pub const MAX_GJK_ITERATIONS: usize = 64;

/// Cores closer than this (raw Q64.64 squared length: 256, i.e. 16 ulps or
/// 3.7e-9 m) count as touching: below it the direction of `v` has too few
/// bits to mean anything.
const TOUCH_VV: u128 = 256;

/// A convex shape as GJK and EPA see it: a core given by its support
/// function, grown by a radius.
///
/// Why a trait: the queries (ray casts, sweeps, CCD) and the narrow phase
/// share one GJK for every pair of convex kinds, monomorphised per pair.
pub trait SupportShape {
    /// The point of the core farthest along `dir` (local coordinates). Ties
    /// are broken deterministically (see each implementation); `dir` need
    /// not be unit length, and a zero `dir` returns some core point.
    fn support(&self, dir: Vec3) -> Vec3;

    /// The radius added around the core (zero for boxes and hulls).
    fn core_radius(&self) -> Scalar {
        Scalar::ZERO
    }
}

impl SupportShape for Sphere {
    /// The centre: the core of a sphere is a point.
    fn support(&self, _dir: Vec3) -> Vec3 {
        Vec3::ZERO
    }

    fn core_radius(&self) -> Scalar {
        self.radius
    }
}

impl SupportShape for Capsule {
    /// The end of the core segment on `dir`'s side (the top end when `dir`
    /// is perpendicular to the axis).
    fn support(&self, dir: Vec3) -> Vec3 {
        let [bottom, top] = self.segment();
        if dir.y.is_negative() { bottom } else { top }
    }

    fn core_radius(&self) -> Scalar {
        self.radius
    }
}

impl SupportShape for Cuboid {
    /// The corner on `dir`'s side; a zero component picks the + side.
    fn support(&self, dir: Vec3) -> Vec3 {
        let h = self.half_extents;
        let pick = |d: Scalar, e: Scalar| if d.is_negative() { -e } else { e };
        Vec3::new(pick(dir.x, h.x), pick(dir.y, h.y), pick(dir.z, h.z))
    }
}

impl SupportShape for ConvexHull {
    /// [`ConvexHull::support`]: exact dot products, lowest index on ties.
    fn support(&self, dir: Vec3) -> Vec3 {
        ConvexHull::support(self, dir)
    }
}

/// B's pose seen from A's local frame: `p_A = rot · p_B + t`.
///
/// Built from the exact difference of the translations, then rotated, so it
/// is the same, bit for bit, when both poses move by the same offset; all
/// narrow-phase geometry happens in A's frame through it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Rel {
    /// B's rotation in A's frame, as a matrix (one rounding per entry of a
    /// product).
    pub rot: Mat3,
    /// B's origin in A's frame.
    pub t: Vec3,
}

impl Rel {
    /// The relative pose of B seen from A.
    pub fn new(pose_a: &Transform, pose_b: &Transform) -> Rel {
        let d = pose_b.translation - pose_a.translation;
        let t = pose_a.rotation.inverse_rotate(d);
        let q = (pose_a.rotation.conjugate() * pose_b.rotation).normalize();
        Rel {
            rot: Mat3::from_quat(q),
            t,
        }
    }

    /// A point of B's frame in A's frame.
    #[inline]
    pub fn point(&self, p: Vec3) -> Vec3 {
        self.rot.mul_vec(p) + self.t
    }

    /// A direction of B's frame in A's frame.
    #[inline]
    pub fn vector(&self, v: Vec3) -> Vec3 {
        self.rot.mul_vec(v)
    }

    /// A direction of A's frame in B's frame.
    #[inline]
    pub fn dir_in_b(&self, v: Vec3) -> Vec3 {
        self.rot.transpose_mul_vec(v)
    }
}

/// Scales a direction up by a power of two so that its largest component
/// has about 60 bits: rotating a direction of a few ulps would otherwise
/// lose it to rounding. Directions only (the length changes).
#[inline]
pub(crate) fn boost(d: Vec3) -> Vec3 {
    let m = d
        .to_array()
        .iter()
        .map(|c| c.to_bits().unsigned_abs())
        .max()
        .unwrap_or(0);
    if m == 0 {
        return d;
    }
    let lz = m.leading_zeros();
    if lz > 4 { d.scale_pow2(lz - 4) } else { d }
}

/// Bit length of `|x|`.
#[inline]
fn bits(x: i128) -> u32 {
    128 - x.unsigned_abs().leading_zeros()
}

/// Shifts every value right by the same amount so that all fit in `limit`
/// bits (magnitude); a no-op when they already do.
#[inline]
pub(crate) fn fit<const N: usize>(vals: &mut [i128; N], limit: u32) {
    let top = vals.iter().map(|&v| bits(v)).max().unwrap_or(0);
    if top > limit {
        let s = top - limit;
        for v in vals.iter_mut() {
            *v >>= s;
        }
    }
}

/// One Q2.62 unit: barycentric weights are fractions of it.
pub(crate) const ONE_Q62: i128 = 1 << 62;

/// `num / den` as a Q2.62 fraction, for `0 ≤ num ≤ den`, `den > 0` (values
/// outside are clamped to 0 or 1).
#[inline]
pub(crate) fn q62(num: i128, den: i128) -> i128 {
    if den <= 0 || num <= 0 {
        return 0;
    }
    if num >= den {
        return ONE_Q62;
    }
    let mut v = [num, den];
    fit(&mut v, 62);
    if v[1] == 0 {
        return 0;
    }
    (v[0] << 62) / v[1]
}

/// `Σ λᵢ pᵢ` for Q2.62 weights, each component rounded once.
#[inline]
pub(crate) fn combine(points: &[Vec3], lambda: &[i128]) -> Vec3 {
    let mut out = Vec3::ZERO;
    for k in 0..3 {
        let mut acc: i128 = 0;
        for (p, &l) in points.iter().zip(lambda) {
            acc = acc.saturating_add(l * p.get(k).to_bits() as i128);
        }
        out.set(k, Scalar::from_bits(round_shift(acc, 62) as i64));
    }
    out
}

/// The unit vector along an exact `i128` vector (any scale), or `None` for
/// zero: scaled to 60 bits by a power of two, then normalised.
pub(crate) fn unit_from_wide(n: [i128; 3]) -> Option<Vec3> {
    let top = n.iter().map(|&c| bits(c)).max().unwrap_or(0);
    if top == 0 {
        return None;
    }
    let scaled = |c: i128| -> i64 {
        if top > 60 {
            (c >> (top - 60)) as i64
        } else {
            (c << (60 - top)) as i64
        }
    };
    Vec3::new(
        Scalar::from_bits(scaled(n[0])),
        Scalar::from_bits(scaled(n[1])),
        Scalar::from_bits(scaled(n[2])),
    )
    .try_normalize()
}

/// The exact cross product of two Q32.32 vectors, as raw `i128` components
/// (scale 2⁶⁴).
#[inline]
pub(crate) fn cross_wide(u: Vec3, v: Vec3) -> [i128; 3] {
    let c =
        |a: Scalar, b: Scalar, c: Scalar, d: Scalar| a.wide_mul(b).saturating_sub(c.wide_mul(d));
    [
        c(u.y, v.z, u.z, v.y),
        c(u.z, v.x, u.x, v.z),
        c(u.x, v.y, u.y, v.x),
    ]
}

/// A vertex of the simplex: the Minkowski point `w = a − b` and the two
/// support points (A's frame) that made it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct SVert {
    pub w: Vec3,
    pub a: Vec3,
    pub b: Vec3,
}

/// The Minkowski difference `A − B` of two cores, in A's frame.
pub(crate) struct Pair<'s, A: ?Sized, B: ?Sized> {
    pub a: &'s A,
    pub b: &'s B,
    pub rel: Rel,
}

impl<A: SupportShape + ?Sized, B: SupportShape + ?Sized> Pair<'_, A, B> {
    /// The support point of `A − B` along `d`.
    #[inline]
    pub fn support(&self, d: Vec3) -> SVert {
        let d = boost(d);
        let a = self.a.support(d);
        let b = self.rel.point(self.b.support(self.rel.dir_in_b(-d)));
        SVert { w: a - b, a, b }
    }
}

/// Up to four simplex vertices, the newest last.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Simplex {
    pub v: [SVert; 4],
    pub n: usize,
}

/// What solving a simplex gives: the kept vertices are compacted into the
/// simplex (in their original order) with their weights.
struct Solved {
    lambda: [i128; 4],
    inside: bool,
}

impl Simplex {
    fn keep(&mut self, idx: &[usize], lambda: &[i128]) -> Solved {
        let old = self.v;
        let mut l = [0i128; 4];
        for (k, (&i, &w)) in idx.iter().zip(lambda).enumerate() {
            self.v[k] = old[i];
            l[k] = w;
        }
        self.n = idx.len();
        Solved {
            lambda: l,
            inside: false,
        }
    }

    fn points(&self) -> [Vec3; 4] {
        [self.v[0].w, self.v[1].w, self.v[2].w, self.v[3].w]
    }

    /// Reduces the simplex to the smallest sub-simplex whose affine hull
    /// holds the point closest to the origin, with its weights.
    fn solve(&mut self) -> Solved {
        let p = self.points();
        match self.n {
            1 => self.keep(&[0], &[ONE_Q62]),
            2 => {
                let (idx, l, k) = closest_segment(p[0], p[1]);
                self.keep(&[0, 1][idx..idx + k], &l[..k])
            }
            3 => {
                let (idx, l, k) = closest_triangle(p[0], p[1], p[2]);
                let map = [0, 1, 2];
                let sel: [usize; 3] = std::array::from_fn(|i| map[idx[i]]);
                self.keep(&sel[..k], &l[..k])
            }
            _ => self.solve_tetrahedron(p),
        }
    }

    fn solve_tetrahedron(&mut self, p: [Vec3; 4]) -> Solved {
        // Determinism: faces in a fixed order, strict comparison keeps the
        // first on ties.
        const FACES: [([usize; 3], usize); 4] = [
            ([0, 1, 2], 3),
            ([0, 1, 3], 2),
            ([0, 2, 3], 1),
            ([1, 2, 3], 0),
        ];
        let mut best: Option<(u128, [usize; 3], [i128; 3], usize)> = None;
        for (f, opp) in FACES {
            let (so, sd) = plane_sides(p[f[0]], p[f[1]], p[f[2]], p[opp]);
            // The origin is outside this face when it is on the other side
            // from the opposite vertex; a flat tetrahedron (sd = 0) tests
            // every face.
            if sd != 0 && so * sd >= 0 {
                continue;
            }
            let (idx, l, k) = closest_triangle(p[f[0]], p[f[1]], p[f[2]]);
            let pts = [p[f[idx[0]]], p[f[idx[1]]], p[f[idx[2]]]];
            let v = combine(&pts[..k], &l[..k]);
            let vv = v.length_squared_wide();
            if best.is_none_or(|b| vv < b.0) {
                let sel = [f[idx[0]], f[idx[1]], f[idx[2]]];
                best = Some((vv, sel, l, k));
            }
        }
        match best {
            Some((_, sel, l, k)) => self.keep(&sel[..k], &l[..k]),
            None => Solved {
                lambda: [0; 4],
                inside: true,
            },
        }
    }
}

/// Signs of `n·(o − a)` and `n·(d − a)` with `n = (b − a) × (c − a)`: on
/// which side of the plane `abc` the origin and `d` lie. Exact for vectors
/// under 256 m; beyond, the inputs are shifted down together (the signs of
/// clearly non-degenerate configurations are unaffected).
fn plane_sides(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> (i128, i128) {
    let raw = |v: Vec3, o: Vec3| -> [i128; 3] {
        [
            v.x.to_bits() as i128 - o.x.to_bits() as i128,
            v.y.to_bits() as i128 - o.y.to_bits() as i128,
            v.z.to_bits() as i128 - o.z.to_bits() as i128,
        ]
    };
    let mut all = [0i128; 12];
    let groups = [raw(b, a), raw(c, a), raw(d, a), raw(Vec3::ZERO, a)];
    for (g, v) in groups.iter().enumerate() {
        all[g * 3..g * 3 + 3].copy_from_slice(v);
    }
    fit(&mut all, 40);
    let e = |g: usize| [all[g * 3], all[g * 3 + 1], all[g * 3 + 2]];
    let (ab, ac, ad, ao) = (e(0), e(1), e(2), e(3));
    let n = [
        ab[1] * ac[2] - ab[2] * ac[1],
        ab[2] * ac[0] - ab[0] * ac[2],
        ab[0] * ac[1] - ab[1] * ac[0],
    ];
    let dot = |u: [i128; 3]| n[0] * u[0] + n[1] * u[1] + n[2] * u[2];
    (dot(ao).signum(), dot(ad).signum())
}

/// Closest point of segment `ab` to the origin: (first kept index, weights,
/// how many kept). Keeps `a` for a degenerate segment.
fn closest_segment(a: Vec3, b: Vec3) -> (usize, [i128; 2], usize) {
    let ab = b - a;
    let num = -a.dot_wide(ab);
    let den = ab.dot_wide(ab);
    if num <= 0 || den == 0 {
        (0, [ONE_Q62, 0], 1)
    } else if num >= den {
        (1, [ONE_Q62, 0], 1)
    } else {
        let t = q62(num, den);
        (0, [ONE_Q62 - t, t], 2)
    }
}

/// Closest point of triangle `abc` to the origin (Voronoi regions on exact
/// dot products): (kept indices into [a, b, c], weights, how many kept).
/// A degenerate (zero-area) triangle falls back to its closest edge.
pub(crate) fn closest_triangle(a: Vec3, b: Vec3, c: Vec3) -> ([usize; 3], [i128; 3], usize) {
    let (ab, ac) = (b - a, c - a);
    let mut d = [
        -ab.dot_wide(a),
        -ac.dot_wide(a),
        -ab.dot_wide(b),
        -ac.dot_wide(b),
        -ab.dot_wide(c),
        -ac.dot_wide(c),
    ];
    fit(&mut d, 62);
    let [d1, d2, d3, d4, d5, d6] = d;
    if d1 <= 0 && d2 <= 0 {
        return ([0, 0, 0], [ONE_Q62, 0, 0], 1);
    }
    if d3 >= 0 && d4 <= d3 {
        return ([1, 0, 0], [ONE_Q62, 0, 0], 1);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0 && d1 >= 0 && d3 <= 0 {
        let t = q62(d1, d1 - d3);
        return ([0, 1, 0], [ONE_Q62 - t, t, 0], 2);
    }
    if d6 >= 0 && d5 <= d6 {
        return ([2, 0, 0], [ONE_Q62, 0, 0], 1);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0 && d2 >= 0 && d6 <= 0 {
        let t = q62(d2, d2 - d6);
        return ([0, 2, 0], [ONE_Q62 - t, t, 0], 2);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0 {
        let t = q62(d4 - d3, (d4 - d3) + (d5 - d6));
        return ([1, 2, 0], [ONE_Q62 - t, t, 0], 2);
    }
    let (va, vb, vc) = (va.max(0), vb.max(0), vc.max(0));
    let den = va + vb + vc;
    if den <= 0 {
        // Zero area: the closest of the three edges.
        let mut best: Option<(u128, [usize; 3], [i128; 3], usize)> = None;
        for (i, j) in [(0usize, 1usize), (0, 2), (1, 2)] {
            let p = [a, b, c];
            let (first, l, k) = closest_segment(p[i], p[j]);
            let idx = if k == 2 {
                [i, j, 0]
            } else if first == 0 {
                [i, 0, 0]
            } else {
                [j, 0, 0]
            };
            let pts = [p[idx[0]], p[idx[1]]];
            let vv = combine(&pts[..k], &l[..k]).length_squared_wide();
            if best.is_none_or(|bb| vv < bb.0) {
                best = Some((vv, idx, [l[0], l[1], 0], k));
            }
        }
        let (_, idx, l, k) = best.unwrap_or((0, [0, 0, 0], [ONE_Q62, 0, 0], 1));
        return (idx, l, k);
    }
    let lb = q62(vb, den);
    let lc = q62(vc, den).min(ONE_Q62 - lb);
    ([0, 1, 2], [ONE_Q62 - lb - lc, lb, lc], 3)
}

/// What GJK on two cores found, in A's frame.
// The simplex travels by value on purpose: boxing it would allocate.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug)]
pub(crate) enum CoreResult {
    /// The cores are apart: `v = pa − pb` is the closest point of `A − B`.
    Separated {
        /// Closest point of A's core.
        pa: Vec3,
        /// Closest point of B's core.
        pb: Vec3,
        /// `pa − pb`.
        v: Vec3,
        /// Exact `|v|²` (Q64.64).
        vv: u128,
        /// False when the iteration cap stopped the loop.
        converged: bool,
    },
    /// The cores overlap or touch; the final simplex seeds EPA.
    Overlapping(Simplex),
}

/// GJK on the cores of a pair, in A's frame.
pub(crate) fn gjk_core<A: SupportShape + ?Sized, B: SupportShape + ?Sized>(
    pair: &Pair<'_, A, B>,
) -> CoreResult {
    let start = if pair.rel.t.is_zero() {
        Vec3::X
    } else {
        pair.rel.t
    };
    let first = pair.support(start);
    let mut s = Simplex {
        v: [first; 4],
        n: 1,
    };
    let mut lambda = [ONE_Q62, 0, 0, 0];
    let mut v = first.w;
    let mut vv = v.length_squared_wide();
    let mut converged = false;
    for _ in 0..MAX_GJK_ITERATIONS {
        if vv <= TOUCH_VV {
            return CoreResult::Overlapping(s);
        }
        let w = pair.support(-v);
        // No progress possible: the support plane through w is (almost) at
        // the distance already reached.
        let gap = (vv as i128).saturating_sub(v.dot_wide(w.w));
        let tol = (vv >> 26) as i128 + (1 << 12);
        if gap <= tol || s.v[..s.n].iter().any(|x| x.w == w.w) {
            converged = true;
            break;
        }
        let saved = (s, lambda);
        s.v[s.n] = w;
        s.n += 1;
        let solved = s.solve();
        if solved.inside {
            return CoreResult::Overlapping(s);
        }
        let pts = s.points();
        let nv = combine(&pts[..s.n], &solved.lambda[..s.n]);
        let nvv = nv.length_squared_wide();
        if nvv >= vv {
            // The distance stopped decreasing: rounding, not geometry. Keep
            // the previous (better) simplex.
            (s, lambda) = saved;
            converged = true;
            break;
        }
        lambda = solved.lambda;
        v = nv;
        vv = nvv;
    }
    if vv <= TOUCH_VV {
        return CoreResult::Overlapping(s);
    }
    let a: [Vec3; 4] = std::array::from_fn(|i| s.v[i].a);
    let b: [Vec3; 4] = std::array::from_fn(|i| s.v[i].b);
    CoreResult::Separated {
        pa: combine(&a[..s.n], &lambda[..s.n]),
        pb: combine(&b[..s.n], &lambda[..s.n]),
        v,
        vv,
        converged,
    }
}

/// The distance between two posed convex shapes, or that they overlap.
///
/// Why it exists: queries and continuous collision need the gap between
/// shapes that do not touch, which contact generation does not give.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DistanceResult {
    /// The shapes are apart.
    Separated {
        /// The gap between the surfaces (radii included), > 0 (at least
        /// 16 ulps).
        distance: Scalar,
        /// The closest point of A's surface, world frame.
        point_a: Vec3,
        /// The closest point of B's surface, world frame.
        point_b: Vec3,
        /// Unit direction from A to B (world): the separating axis.
        normal: Vec3,
        /// False when [`MAX_GJK_ITERATIONS`] ran out first; the distance is
        /// then an upper bound with valid (but maybe not closest) points.
        converged: bool,
    },
    /// The shapes overlap, or touch within 16 ulps (3.7e-9 m). Use
    /// [`penetration`](super::epa::penetration) for depth and normal.
    Overlapping,
}

/// GJK distance between `a` at `pose_a` and `b` at `pose_b`.
///
/// Integer-only and deterministic; at most [`MAX_GJK_ITERATIONS`]
/// iterations, no allocation. Translation invariant bit for bit: the
/// geometry is done in A's frame from the exact difference of the
/// translations. A touching pair (gap within 16 ulps) is reported as
/// overlapping.
pub fn distance<A: SupportShape + ?Sized, B: SupportShape + ?Sized>(
    a: &A,
    pose_a: &Transform,
    b: &B,
    pose_b: &Transform,
) -> DistanceResult {
    let pair = Pair {
        a,
        b,
        rel: Rel::new(pose_a, pose_b),
    };
    match gjk_core(&pair) {
        CoreResult::Overlapping(_) => DistanceResult::Overlapping,
        CoreResult::Separated {
            pa,
            pb,
            v,
            vv,
            converged,
        } => {
            let core = Scalar::from_bits(crate::math::elem::isqrt_u128(vv) as i64);
            let (ra, rb) = (a.core_radius(), b.core_radius());
            let gap = core - ra - rb;
            if gap.to_bits() <= 16 {
                return DistanceResult::Overlapping;
            }
            let n = (-v).try_normalize().unwrap_or(Vec3::Y);
            DistanceResult::Separated {
                distance: gap,
                point_a: pose_a.transform_point(pa + n * ra),
                point_b: pose_a.transform_point(pb - n * rb),
                normal: pose_a.transform_vector(n),
                converged,
            }
        }
    }
}
