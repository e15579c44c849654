//! A ray against one shape of each kind.
//!
//! Every function works in the shape's local frame (the ray is brought
//! there by the pose) and returns the entering fraction of the segment
//! `origin + t · translation`, `t ∈ [0, max]`, and the local outward normal.
//!
//! **From inside.** A ray whose origin is inside a solid shape (sphere,
//! capsule, box, hull) or on its surface hits it at `t = 0` with the normal
//! opposite the ray direction (as parry does for solid shapes): a shot fired
//! from inside a wall is stopped by it, never let through. Exclude the
//! shooter's own body with [`QueryFilter::exclude_bodies`](super::filter::QueryFilter).
//! Meshes and height fields have no inside: their triangles are hit from
//! either side, with the normal turned towards the ray's origin.
//!
//! **Touching counts.** A ray grazing a face, edge or corner hits it (closed
//! shapes). A ray lying in the plane of a triangle does not hit it (its
//! plane gives no single point); parallel rays outside a slab miss.
//!
//! Arithmetic: integer only. The box test compares exact ratios; spheres and
//! capsules solve their quadratic on the unit direction through the point of
//! closest approach (no cancellation for grazing rays); triangles use signed
//! volumes `d · (A × B)` of the edges seen from the origin, which are exactly
//! opposite for the two triangles sharing an edge, so a ray through a
//! shared edge hits at least one of them (watertight meshes stay
//! watertight). Coordinates relative to the ray origin must stay below about
//! 2¹⁵ m (the products of the triangle test fit Q32.32 there).

use crate::collision::dynamic_tree::ray::{Frac, segment_box};
use crate::collision::narrow::closest_point_on_segment;
use crate::collision::narrow::gjk::{cross_wide, unit_from_wide};
use crate::collision::narrow::shared::ratio01;
use crate::math::elem::isqrt_u128;
use crate::math::{Scalar, Transform, Vec3};
use crate::shape::{Capsule, ConvexHull, Cuboid, HeightField, Shape, TriMesh};

/// A ray: the segment from `origin` to `origin + translation`.
///
/// Given by its full translation rather than a unit direction and a length,
/// so that hit fractions are exact ratios of the inputs and no
/// normalisation is needed to build one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ray {
    /// Start point, world frame.
    pub origin: Vec3,
    /// End point minus start point.
    pub translation: Vec3,
}

impl Ray {
    /// The ray from `origin` along `translation`.
    pub const fn new(origin: Vec3, translation: Vec3) -> Ray {
        Ray {
            origin,
            translation,
        }
    }

    /// The point at fraction `t`: `origin + t · translation`.
    pub fn point_at(&self, t: Scalar) -> Vec3 {
        self.origin + self.translation * t
    }
}

/// Where a ray hits one shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RayIntersection {
    /// Fraction of the translation, `[0, max]`.
    pub fraction: Scalar,
    /// `origin + fraction · translation`, world frame.
    pub point: Vec3,
    /// Unit outward normal, world frame (opposite the ray from inside).
    pub normal: Vec3,
}

/// A local hit: the fraction and the local normal, `None` meaning "from
/// inside" (the caller turns it into the reversed ray direction).
type LocalHit = (Scalar, Option<Vec3>);

/// The ray against `shape` posed at `pose`, hits with fraction `≤ max`
/// only. `None` for a miss, or for a zero translation.
pub fn cast_ray_shape(
    shape: &Shape,
    pose: &Transform,
    ray: &Ray,
    max: Scalar,
) -> Option<RayIntersection> {
    if ray.translation.is_zero() {
        return None;
    }
    let o = pose.inverse_transform_point(ray.origin);
    let d = pose.inverse_transform_vector(ray.translation);
    let (t, n) = match shape {
        Shape::Sphere(s) => ray_sphere(s.radius, o, d),
        Shape::Capsule(c) => ray_capsule(c, o, d),
        Shape::Cuboid(b) => ray_box(b, o, d),
        Shape::ConvexHull(h) => ray_hull(h, o, d),
        Shape::TriMesh(m) => ray_trimesh(m, o, d, max),
        Shape::HeightField(f) => ray_heightfield(f, o, d, max),
    }?;
    if t > max {
        return None;
    }
    let normal = match n {
        Some(n) => pose.rotation.rotate(n).try_normalize().unwrap_or(n),
        None => (-ray.translation).try_normalize()?,
    };
    Some(RayIntersection {
        fraction: t,
        point: ray.point_at(t),
        normal,
    })
}

/// `s / len` as a fraction in `[0, 1]`.
fn fraction(s: Scalar, len: Scalar) -> Scalar {
    ratio01(s.to_bits() as i128, len.to_bits() as i128)
}

/// The distance along the unit direction `dn` at which a ray from `o`
/// (relative to the sphere's centre, outside it) enters a sphere of radius
/// `r`: through the point of closest approach `p = o − (o·dn) dn`, whose
/// squared distance is accurate even for grazing rays.
fn sphere_entry(o: Vec3, dn: Vec3, r: Scalar) -> Option<Scalar> {
    let b = o.dot(dn);
    if !b.is_negative() {
        return None;
    }
    let p = o - dn * b;
    let h2 = r.wide_mul(r) - p.length_squared_wide() as i128;
    if h2 < 0 {
        return None;
    }
    let h = Scalar::from_bits(isqrt_u128(h2 as u128) as i64);
    Some((-b - h).max(Scalar::ZERO))
}

/// Sphere of radius `r` at the local origin.
fn ray_sphere(r: Scalar, o: Vec3, d: Vec3) -> Option<LocalHit> {
    if o.length_squared_wide() as i128 <= r.wide_mul(r) {
        return Some((Scalar::ZERO, None));
    }
    let (dn, len) = d.normalize_and_length()?;
    let s = sphere_entry(o, dn, r)?;
    if s > len {
        return None;
    }
    let p = o + dn * s;
    Some((fraction(s, len), Some(p.try_normalize().unwrap_or(-dn))))
}

/// Capsule along local y: the first entry into the union of its side
/// cylinder and its two end spheres (the minimum of the three entries, the
/// side first, then the bottom, then the top on ties).
fn ray_capsule(c: &Capsule, o: Vec3, d: Vec3) -> Option<LocalHit> {
    let [bottom, top] = c.segment();
    let r = c.radius;
    let rr = r.wide_mul(r);
    let (_, q) = closest_point_on_segment(o, bottom, top);
    if (o - q).length_squared_wide() as i128 <= rr {
        return Some((Scalar::ZERO, None));
    }
    let (dn, len) = d.normalize_and_length()?;
    let mut best: Option<(Scalar, Vec3)> = None;
    // The side: a circle in the xz plane, entered from outside it.
    let o2 = Vec3::new(o.x, Scalar::ZERO, o.z);
    if o2.length_squared_wide() as i128 > rr
        && let Some((u, k)) = Vec3::new(dn.x, Scalar::ZERO, dn.z).normalize_and_length()
        && let Some(s2) = sphere_entry(o2, u, r)
        && let Some(s) = s2.checked_div(k)
        && s <= len
    {
        let p = o + dn * s;
        if p.y >= bottom.y && p.y <= top.y {
            let n = Vec3::new(p.x, Scalar::ZERO, p.z)
                .try_normalize()
                .unwrap_or(-u);
            best = Some((s, n));
        }
    }
    for end in [bottom, top] {
        if let Some(s) = sphere_entry(o - end, dn, r)
            && s <= len
            && best.is_none_or(|(b, _)| s < b)
        {
            let n = (o + dn * s - end).try_normalize().unwrap_or(-dn);
            best = Some((s, n));
        }
    }
    let (s, n) = best?;
    Some((fraction(s, len), Some(n)))
}

/// Box: the exact slab test (see `segment_box`); the entering face is the
/// axis entered last, the lowest axis on ties (edges and corners).
fn ray_box(b: &Cuboid, o: Vec3, d: Vec3) -> Option<LocalHit> {
    let h = b.half_extents;
    let a = o.abs();
    if a.x <= h.x && a.y <= h.y && a.z <= h.z {
        return Some((Scalar::ZERO, None));
    }
    let hit = segment_box(o, d, -h, h, Frac::from_scalar(Scalar::ONE))?;
    let k = hit.axis?;
    let mut n = Vec3::ZERO;
    n.set(
        k,
        if d.get(k).is_positive() {
            Scalar::NEG_ONE
        } else {
            Scalar::ONE
        },
    );
    Some((ratio01(hit.enter.num, hit.enter.den), Some(n)))
}

/// Hull: clip the segment by every face plane `n · x ≤ offset`; the
/// entering face is the plane entered last (the lowest face index on ties).
fn ray_hull(hull: &ConvexHull, o: Vec3, d: Vec3) -> Option<LocalHit> {
    // Signed distance and closing rate per face, rounded once to Q32.32 so
    // that the ratio comparisons below fit i128.
    let round = |w: i128| crate::math::scalar::round_shift32(w);
    let mut inside = true;
    let mut enter: Option<(Frac, usize)> = None;
    let mut exit = Frac { num: 1, den: 1 };
    for (i, f) in hull.faces().iter().enumerate() {
        let n = f.normal();
        let dist = round(n.dot_wide(o) - ((f.offset().to_bits() as i128) << 32));
        let rate = round(n.dot_wide(d));
        if dist > 0 {
            inside = false;
        }
        // Outside this face's plane and not closing on it (parallel, or
        // moving away): the ray never gets in. (Only a plane the ray
        // closes on can be entered; without this, a ray whose line crosses
        // the hull behind its origin "hit" at fraction 0.)
        if dist > 0 && rate >= 0 {
            return None;
        }
        if rate == 0 {
            continue;
        }
        if rate < 0 {
            let t = Frac {
                num: dist,
                den: -rate,
            };
            if enter.is_none_or(|(e, _)| e.lt(t)) {
                enter = Some((t, i));
            }
        } else {
            let t = Frac {
                num: -dist,
                den: rate,
            };
            if t.lt(exit) {
                exit = t;
            }
        }
    }
    if inside {
        return Some((Scalar::ZERO, None));
    }
    // Outside some plane: that plane is entered (or the ray already
    // returned), so `enter` is set and not before 0.
    let (enter, f) = enter?;
    if exit.lt(enter) {
        return None;
    }
    Some((
        ratio01(enter.num, enter.den),
        Some(hull.faces()[f].normal()),
    ))
}

/// The ray against one triangle, two-sided: the fraction, and whether the
/// ray runs along the triangle's normal `(b − a) × (c − a)` (so the hit
/// normal must be flipped to face the ray).
fn ray_triangle(tri: [Vec3; 3], o: Vec3, d: Vec3) -> Option<(Scalar, bool)> {
    let [a, b, c] = tri.map(|v| v - o);
    // Determinism: each edge's volume is computed from its two corners in
    // the triangle's order; a shared edge seen from the neighbour is the
    // exact negation (cross and dot round symmetrically).
    let e0 = d.dot_wide(a.cross(b));
    let e1 = d.dot_wide(b.cross(c));
    let e2 = d.dot_wide(c.cross(a));
    let neg = e0 < 0 || e1 < 0 || e2 < 0;
    let pos = e0 > 0 || e1 > 0 || e2 > 0;
    if neg && pos {
        return None;
    }
    let n = (b - a).cross(c - a);
    let den = d.dot_wide(n);
    if den == 0 {
        return None;
    }
    let along = den > 0;
    let num = a.dot_wide(n);
    let (num, den) = if along { (num, den) } else { (-num, -den) };
    if num < 0 || num > den {
        return None;
    }
    Some((ratio01(num, den), along))
}

/// The local box of the segment `o`, `o + d` (exact, in raw bits).
pub(crate) fn segment_bounds(o: Vec3, d: Vec3) -> ([i128; 3], [i128; 3]) {
    let mut lo = [0i128; 3];
    let mut hi = [0i128; 3];
    for k in 0..3 {
        let a = o.get(k).to_bits() as i128;
        let b = a + d.get(k).to_bits() as i128;
        lo[k] = a.min(b);
        hi[k] = a.max(b);
    }
    (lo, hi)
}

/// Whether the triangle's box misses the box `[lo, hi]` (raw bits).
pub(crate) fn triangle_outside(tri: &[Vec3; 3], lo: &[i128; 3], hi: &[i128; 3]) -> bool {
    (0..3).any(|k| {
        let v = tri.map(|p| p.get(k).to_bits() as i128);
        v.iter().all(|&x| x < lo[k]) || v.iter().all(|&x| x > hi[k])
    })
}

/// Triangle mesh: a walk of the mesh's AABB tree (see
/// [`TriMesh::walk_ray`]), the nearest hit kept, the lowest triangle index
/// on ties. The walk clips the segment to one ulp past the best fraction so
/// far: a triangle whose exact hit rounds to the same fraction lies in a box
/// entered within that ulp, so every tie is still seen and the answer is
/// the one a linear scan of every triangle gives.
fn ray_trimesh(mesh: &TriMesh, o: Vec3, d: Vec3, max: Scalar) -> Option<LocalHit> {
    let (lo, hi) = segment_bounds(o, d);
    let mut best: Option<(Scalar, usize, bool)> = None;
    mesh.walk_ray(o, d, max, |i, _| {
        if let Some(tri) = mesh.triangle(i)
            && !triangle_outside(&tri, &lo, &hi)
            && let Some((t, flip)) = ray_triangle(tri, o, d)
            && t <= max
            && best.is_none_or(|(b, j, _)| (t, i) < (b, j))
        {
            best = Some((t, i, flip));
            return Some(t + Scalar::DELTA);
        }
        Some(max)
    });
    let (t, i, flip) = best?;
    let n = mesh.normals()[i];
    Some((t, Some(if flip { -n } else { n })))
}

/// The linear scan [`ray_trimesh`] replaced: every triangle in index order,
/// the nearest hit kept (the lowest index on ties). Kept to check that the
/// tree walk gives the same answers.
#[cfg(test)]
pub(crate) fn ray_trimesh_linear(
    mesh: &TriMesh,
    o: Vec3,
    d: Vec3,
    max: Scalar,
) -> Option<(Scalar, Option<Vec3>)> {
    let (lo, hi) = segment_bounds(o, d);
    let mut best: Option<(Scalar, usize, bool)> = None;
    for i in 0..mesh.indices().len() {
        let Some(tri) = mesh.triangle(i) else {
            continue;
        };
        if triangle_outside(&tri, &lo, &hi) {
            continue;
        }
        if let Some((t, flip)) = ray_triangle(tri, o, d)
            && t <= max
            && best.is_none_or(|(b, _, _)| t < b)
        {
            best = Some((t, i, flip));
        }
    }
    let (t, i, flip) = best?;
    let n = mesh.normals()[i];
    Some((t, Some(if flip { -n } else { n })))
}

/// `⌊(x − origin) / step⌋` on raw bits (`step > 0`), exact.
fn cell_of(x: i128, origin: i128, step: i128) -> i128 {
    (x - origin).div_euclid(step)
}

/// The cells `[first, last]` (of `count`) a coordinate range `[lo, hi]`
/// (raw bits) may touch, one cell of margin on each side for the rounding
/// of the grid coordinates; `None` if the range misses the grid.
pub(crate) fn cell_span(
    lo: i128,
    hi: i128,
    origin: Scalar,
    step: Scalar,
    count: u32,
) -> Option<(u32, u32)> {
    let (o, s) = (origin.to_bits() as i128, step.to_bits() as i128);
    let first = cell_of(lo, o, s) - 1;
    let last = cell_of(hi, o, s) + 1;
    let top = count as i128 - 1;
    if last < 0 || first > top {
        return None;
    }
    Some((first.max(0) as u32, last.min(top) as u32))
}

/// Height field: the rows the segment's z range covers; in each row, the
/// columns its x range covers within that row's z slab; two triangles per
/// cell in [`HeightField::cell_triangles`] order. Cells are visited row by
/// row, column by column; the nearest hit is kept (the first visited on
/// ties).
fn ray_heightfield(f: &HeightField, o: Vec3, d: Vec3, max: Scalar) -> Option<LocalHit> {
    let (lo, hi) = segment_bounds(o, d);
    let corner = f.vertex(0, 0)?;
    let scale = f.scale();
    let (r0, r1) = cell_span(lo[2], hi[2], corner.z, scale.z, f.rows() - 1)?;
    let (ox, oz) = (o.x.to_bits() as i128, o.z.to_bits() as i128);
    let (dx, dz) = (d.x.to_bits() as i128, d.z.to_bits() as i128);
    // x where the segment's line crosses height-field z (raw bits, floor).
    let x_at = |z: i128| ox + dx.saturating_mul(z - oz).div_euclid(dz);
    let mut best: Option<(Scalar, Vec3)> = None;
    for r in r0..=r1 {
        let (mut xlo, mut xhi) = (lo[0], hi[0]);
        if dz != 0 {
            let z0 = f.vertex(r, 0)?.z.to_bits() as i128;
            let z1 = f.vertex(r + 1, 0)?.z.to_bits() as i128;
            let (xa, xb) = (x_at(z0), x_at(z1));
            // One raw unit of slack for the floor division.
            xlo = xlo.max(xa.min(xb) - 1);
            xhi = xhi.min(xa.max(xb) + 1);
            if xlo > xhi {
                continue;
            }
        }
        let Some((c0, c1)) = cell_span(xlo, xhi, corner.x, scale.x, f.cols() - 1) else {
            continue;
        };
        for c in c0..=c1 {
            let Some(tris) = f.cell_triangles(r, c) else {
                continue;
            };
            for tri in tris {
                if let Some((t, flip)) = ray_triangle(tri, o, d)
                    && t <= max
                    && best.is_none_or(|(b, _)| t < b)
                {
                    let n = unit_from_wide(cross_wide(tri[1] - tri[0], tri[2] - tri[0]))
                        .unwrap_or(Vec3::Y);
                    best = Some((t, if flip { -n } else { n }));
                }
            }
        }
    }
    let (t, n) = best?;
    Some((t, Some(n)))
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::testing::Rng;

    /// Fixed-point draws for the test's rays.
    trait Draw {
        fn scalar(&mut self, lo: i64, hi: i64) -> Scalar;
    }

    impl Draw for Rng {
        /// A Scalar in `[lo, hi)` with 2⁻¹⁶ m resolution.
        fn scalar(&mut self, lo: i64, hi: i64) -> Scalar {
            let span = ((hi - lo) as u64) << 16;
            Scalar::from_bits((lo << 32) + ((self.below(span) as i64) << 16))
        }
    }

    /// A bumpy 24 × 24 grid (1,152 triangles) plus 64 loose triangles, a
    /// quarter of them exact copies of grid triangles (ties by index).
    fn test_mesh(rng: &mut Rng) -> TriMesh {
        let n = 25u32;
        let mut v = Vec::new();
        for r in 0..n {
            for c in 0..n {
                let h = rng.scalar(-1, 1);
                v.push(Vec3::new(
                    Scalar::from_int(c as i32 - 12),
                    h,
                    Scalar::from_int(r as i32 - 12),
                ));
            }
        }
        let mut idx = Vec::new();
        for r in 0..n - 1 {
            for c in 0..n - 1 {
                let a = r * n + c;
                idx.push([a, a + n, a + 1]);
                idx.push([a + 1, a + n, a + n + 1]);
            }
        }
        for k in 0..64 {
            if k % 4 == 0 {
                let copy = idx[(rng.next_u64() % idx.len() as u64) as usize];
                idx.push(copy);
                continue;
            }
            let base = v.len() as u32;
            let p = Vec3::new(rng.scalar(-12, 12), rng.scalar(-2, 3), rng.scalar(-12, 12));
            v.push(p);
            v.push(p + Vec3::new(rng.scalar(1, 3), rng.scalar(-1, 1), rng.scalar(-1, 1)));
            v.push(p + Vec3::new(rng.scalar(-1, 1), rng.scalar(-1, 1), rng.scalar(1, 3)));
            idx.push([base, base + 1, base + 2]);
        }
        TriMesh::new(v, idx).unwrap()
    }

    /// A ray that starts outside a hull and moves away from it misses, even
    /// though its line runs through the hull behind the origin; towards the
    /// hull it hits where it enters.
    #[test]
    fn a_ray_leaving_a_hull_from_outside_misses() {
        let corners: Vec<Vec3> = (0..8)
            .map(|i| Vec3::from_ints(1 - 2 * (i & 1), 1 - (i & 2), 1 - (i & 4) / 2))
            .collect();
        let hull = ConvexHull::from_points(&corners).unwrap();
        let o = Vec3::from_ints(3, 0, 0);
        assert_eq!(ray_hull(&hull, o, Vec3::from_ints(1, 0, 0)), None);
        assert_eq!(ray_hull(&hull, o, Vec3::from_ints(4, 1, 0)), None);
        // Towards it: enters the x = 1 face at 2/4 of the way.
        let (t, n) = ray_hull(&hull, o, Vec3::from_ints(-4, 0, 0)).unwrap();
        assert_eq!(t, Scalar::HALF);
        assert_eq!(n, Some(Vec3::X));
        // Too short to reach it.
        assert_eq!(ray_hull(&hull, o, Vec3::from_ints(-1, 0, 0)), None);
        // From inside: fraction 0, no face.
        assert_eq!(
            ray_hull(&hull, Vec3::ZERO, Vec3::from_ints(5, 0, 0)),
            Some((Scalar::ZERO, None))
        );
    }

    #[test]
    fn mesh_ray_tree_walk_matches_the_linear_scan_on_4000_seeded_rays() {
        let mut rng = Rng::new(0x5eed_0005);
        let mesh = test_mesh(&mut rng);
        let (mut hits, mut ties) = (0, 0);
        for k in 0..4000 {
            let o = Vec3::new(rng.scalar(-14, 14), rng.scalar(-4, 6), rng.scalar(-14, 14));
            // Mostly downward rays onto the terrain, some in any direction,
            // some aimed exactly through a grid vertex (shared edges).
            let d = if k % 8 == 0 {
                let target = Vec3::from_ints(
                    (rng.next_u64() % 25) as i32 - 12,
                    0,
                    (rng.next_u64() % 25) as i32 - 12,
                );
                (target - o).mul_int(2)
            } else if k % 3 == 0 {
                Vec3::new(
                    rng.scalar(-20, 20),
                    rng.scalar(-20, 20),
                    rng.scalar(-20, 20),
                )
            } else {
                Vec3::new(rng.scalar(-3, 3), rng.scalar(-12, -2), rng.scalar(-3, 3))
            };
            let max = if k % 5 == 0 {
                rng.scalar(0, 1)
            } else {
                Scalar::ONE
            };
            let tree = ray_trimesh(&mesh, o, d, max);
            let linear = ray_trimesh_linear(&mesh, o, d, max);
            assert_eq!(tree, linear, "ray {k}: origin {o:?} translation {d:?}");
            if tree.is_some() {
                hits += 1;
            }
            // Count the rays whose hit fraction two triangles share.
            if let Some((t, _)) = tree {
                let same = (0..mesh.indices().len())
                    .filter(|&i| {
                        mesh.triangle(i)
                            .and_then(|tri| ray_triangle(tri, o, d))
                            .is_some_and(|(u, _)| u == t)
                    })
                    .count();
                if same > 1 {
                    ties += 1;
                }
            }
        }
        eprintln!("mesh rays: {hits} hits, {ties} ties");
        assert!(hits > 1500, "only {hits} of 4000 rays hit");
        assert!(ties > 20, "only {ties} rays had tied triangles");
    }
}
