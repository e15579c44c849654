//! `ConvexHull`: a convex polyhedron with polygon faces and exact mass
//! properties.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::error::ShapeError;
use super::mass::MassProperties;
use super::quickhull;
use super::rotation_margin;
use super::sat_features::SatFeatures;
use super::wide::{self, BigInt, RawPoint, from_raw, orient3d, ratio_to_scalar, raw};
use crate::math::{Aabb, Mat3, Scalar, SymMat3, Transform, Vec3};

/// A face of a [`ConvexHull`]: a convex polygon.
///
/// Its corners are `ConvexHull::face_vertices(face index)`, counter-clockwise
/// seen from outside. Only a hull makes these (the fields are private), so
/// a face's normal and offset always belong to a real hull.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct HullFace {
    first: u32,
    count: u32,
    normal: Vec3,
    offset: Scalar,
}

impl HullFace {
    /// The outward unit normal (the exact normal, normalised: within about
    /// an ulp per component).
    pub fn normal(&self) -> Vec3 {
        self.normal
    }

    /// The plane offset `d` of `normal · x = d`: the smallest Q32.32 value
    /// with `normal · v ≤ d` (computed exactly) for every vertex `v` of the
    /// hull, so the plane supports the hull even though the normal is
    /// rounded.
    pub fn offset(&self) -> Scalar {
        self.offset
    }

    /// Number of corners.
    pub fn vertex_count(&self) -> usize {
        self.count as usize
    }
}

/// A convex polyhedron: the convex hull of a point set.
///
/// Built by [`ConvexHull::from_points`] with exact predicates, so it is
/// always a valid closed convex polytope, with coplanar triangles merged
/// into polygon faces (a cube has 6 quads) and no vertex that is not a
/// corner. The layout is canonical: vertices sorted by their coordinates,
/// each face starting at its smallest vertex index, faces and edges sorted.
/// The hull of a point set is therefore the same, bit for bit, whatever the
/// points' order, duplicates or interior points.
///
/// Serialised as its vertex list, and rebuilt (identically) on
/// deserialisation.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ConvexHull {
    vertices: Vec<Vec3>,
    faces: Vec<HullFace>,
    face_vertices: Vec<u32>,
    edges: Vec<[u32; 2]>,
    local_aabb: Aabb,
    /// Derived from the above at construction (never serialised).
    sat: SatFeatures,
}

/// The exact integrals of a hull relative to the local origin (raw scales
/// in parentheses): `d = Σ det = 6 V` (2⁹⁶); `s = Σ det (a + b + c) = 24 ∫x`
/// (2¹²⁸); `q = Σ det (aaᵀ + bbᵀ + ccᵀ + (a+b+c)(a+b+c)ᵀ) = 120 ∫xxᵀ`
/// (2¹⁶⁰), over the tetrahedra (origin, a, b, c) of a fan of each face.
struct Integrals {
    d: BigInt,
    s: [BigInt; 3],
    q: [BigInt; 6],
}

/// Vertex adjacency (compressed rows) for hill climbing.
struct Adjacency {
    start: Vec<usize>,
    list: Vec<u32>,
}

impl Adjacency {
    fn new(n: usize, edges: &[[u32; 2]]) -> Adjacency {
        let mut start = vec![0usize; n + 1];
        for e in edges {
            start[e[0] as usize + 1] += 1;
            start[e[1] as usize + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut list = vec![0u32; start[n]];
        for e in edges {
            for (a, b) in [(e[0], e[1]), (e[1], e[0])] {
                list[fill[a as usize]] = b;
                fill[a as usize] += 1;
            }
        }
        Adjacency { start, list }
    }

    /// The exact maximum of `dir · v` over all vertices, by hill climbing
    /// from `from`: on a convex polytope a vertex with no strictly better
    /// neighbour is a global maximum.
    fn max_dot(&self, vertices: &[Vec3], from: usize, dir: Vec3) -> i128 {
        let mut at = from;
        let mut best = vertices[at].dot_wide(dir);
        loop {
            let better = self.list[self.start[at]..self.start[at + 1]]
                .iter()
                .map(|&u| (vertices[u as usize].dot_wide(dir), u as usize))
                .filter(|&(d, _)| d > best)
                .max_by_key(|&(d, _)| d);
            match better {
                Some((d, u)) => {
                    best = d;
                    at = u;
                }
                None => return best,
            }
        }
    }
}

/// Index pairs of the six entries of a symmetric tensor: xx yy zz xy xz yz.
const PAIRS: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

impl ConvexHull {
    /// The largest coordinate magnitude [`from_points`](Self::from_points)
    /// accepts: 2²⁰ m (1,048,576 m). Within it the exact orientation
    /// determinant fits the 192-bit arithmetic of the predicates.
    pub const COORDINATE_LIMIT: Scalar = Scalar::from_int(1 << 20);

    /// The convex hull of `points`.
    ///
    /// Quickhull on exact predicates (see `quickhull.rs`): deterministic,
    /// depending only on the set of points. Duplicates, and points inside
    /// the hull, on its faces or on its edges, are ignored.
    ///
    /// # Errors
    /// * [`ShapeError::HullCoordinateOutOfRange`] for a coordinate beyond
    ///   ±[`COORDINATE_LIMIT`](Self::COORDINATE_LIMIT), naming the point;
    /// * [`ShapeError::DegenerateHull`] when the points do not span three
    ///   dimensions (fewer than 4 distinct points, or all coplanar,
    ///   collinear or equal);
    /// * [`ShapeError::HullConstruction`] if an internal check fails (a
    ///   bug: please report the input).
    pub fn from_points(points: &[Vec3]) -> Result<ConvexHull, ShapeError> {
        let limit = Self::COORDINATE_LIMIT;
        let mut pts: Vec<RawPoint> = Vec::with_capacity(points.len());
        for (index, p) in points.iter().enumerate() {
            if let Some(&coordinate) = p.to_array().iter().find(|c| **c > limit || **c < -limit) {
                return Err(ShapeError::HullCoordinateOutOfRange { index, coordinate });
            }
            pts.push(raw(*p));
        }
        let poly = quickhull::build(&pts)?;
        let vertices: Vec<Vec3> = poly.vertices.iter().map(|&p| from_raw(p)).collect();
        let mut edges = Vec::new();
        for f in &poly.faces {
            for i in 0..f.len() {
                let (a, b) = (f[i], f[(i + 1) % f.len()]);
                if a < b {
                    edges.push([a, b]);
                }
            }
        }
        edges.sort_unstable();
        let neighbours = Adjacency::new(vertices.len(), &edges);
        let mut faces = Vec::with_capacity(poly.faces.len());
        let mut face_vertices = Vec::new();
        for f in &poly.faces {
            let p = |i: usize| poly.vertices[f[i] as usize];
            // Any three corners of a convex polygon without collinear
            // corners span its plane.
            let n = wide::cross(wide::sub(p(1), p(0)), wide::sub(p(2), p(0)));
            let normal = wide::unit_of_wide(n)
                .ok_or(ShapeError::HullConstruction("face with zero normal"))?;
            let top = neighbours.max_dot(&vertices, f[0] as usize, normal);
            // Ceiling, so that every vertex is on or below the plane.
            let offset = Scalar::from_bits(((top + (1i128 << 32) - 1) >> 32) as i64);
            faces.push(HullFace {
                first: face_vertices.len() as u32,
                count: f.len() as u32,
                normal,
                offset,
            });
            face_vertices.extend_from_slice(f);
        }
        let first = vertices[0];
        let local_aabb = vertices
            .iter()
            .fold(Aabb::new(first, first), |b, &v| b.include_point(v));
        let sat = SatFeatures::new(
            &vertices,
            &edges,
            faces.len(),
            |f| {
                let face = &faces[f];
                &face_vertices[face.first as usize..(face.first + face.count) as usize]
            },
            |f| faces[f].normal,
            |f| faces[f].offset,
        );
        Ok(ConvexHull {
            vertices,
            faces,
            face_vertices,
            edges,
            local_aabb,
            sat,
        })
    }

    /// The vertices: exactly the extreme input points, sorted by
    /// coordinates (x, then y, then z).
    pub fn vertices(&self) -> &[Vec3] {
        &self.vertices
    }

    /// The faces (polygons), sorted by their vertex index lists.
    pub fn faces(&self) -> &[HullFace] {
        &self.faces
    }

    /// The vertex indices of face `face`, counter-clockwise seen from
    /// outside, starting at the smallest; empty for a face index out of
    /// range.
    pub fn face_vertices(&self, face: usize) -> &[u32] {
        self.faces.get(face).map_or(&[], |f| {
            &self.face_vertices[f.first as usize..(f.first + f.count) as usize]
        })
    }

    /// The unique edges as `[low, high]` vertex index pairs, sorted: what SAT
    /// needs for its edge–edge axes.
    pub fn edges(&self) -> &[[u32; 2]] {
        &self.edges
    }

    /// The edge adjacency, Gauss-map arcs and bounding balls that the
    /// narrow phase's separating axis test reads.
    pub(crate) fn sat(&self) -> &SatFeatures {
        &self.sat
    }

    /// The index of the vertex farthest along `dir` (exact dot products;
    /// ties go to the lowest index, so every peer picks the same vertex).
    pub fn support_index(&self, dir: Vec3) -> usize {
        let mut best = 0;
        let mut best_d = self.vertices[0].dot_wide(dir);
        for (i, v) in self.vertices.iter().enumerate().skip(1) {
            let d = v.dot_wide(dir);
            if d > best_d {
                best = i;
                best_d = d;
            }
        }
        best
    }

    /// The vertex farthest along `dir` (see [`support_index`](Self::support_index)).
    pub fn support(&self, dir: Vec3) -> Vec3 {
        self.vertices[self.support_index(dir)]
    }

    /// The box around the vertices.
    pub fn local_aabb(&self) -> Aabb {
        self.local_aabb
    }

    /// The world box of the hull posed at `pose`: every vertex rotated (by
    /// the pose's rotation matrix), plus the translation, grown by the
    /// rotation rounding allowance so that it also contains the vertices as
    /// [`Transform::transform_point`] computes them.
    pub fn aabb(&self, pose: &Transform) -> Aabb {
        let r = Mat3::from_quat(pose.rotation);
        let first = r.mul_vec(self.vertices[0]);
        let b = self.vertices.iter().fold(Aabb::new(first, first), |b, &v| {
            b.include_point(r.mul_vec(v))
        });
        let reach = self.local_aabb.min.abs().max(self.local_aabb.max.abs());
        let margin = rotation_margin(reach.x + reach.y + reach.z);
        Aabb::new(b.min + pose.translation, b.max + pose.translation).expanded(margin)
    }

    fn integrals(&self) -> Integrals {
        let mut d = BigInt::ZERO;
        let mut s = [BigInt::ZERO; 3];
        let mut q = [BigInt::ZERO; 6];
        for f in 0..self.faces.len() {
            let idx = self.face_vertices(f);
            let p = |i: usize| raw(self.vertices[idx[i] as usize]);
            let a = p(0);
            for i in 1..idx.len() - 1 {
                let (b, c) = (p(i), p(i + 1));
                let det = orient3d([0; 3], a, b, c).to_big();
                d = d.add(&det);
                let sum: [i128; 3] =
                    std::array::from_fn(|k| a[k] as i128 + b[k] as i128 + c[k] as i128);
                for k in 0..3 {
                    s[k] = s[k].add(&det.mul_i128(sum[k]));
                }
                for (e, &(i, j)) in PAIRS.iter().enumerate() {
                    let m = |x: RawPoint| x[i] as i128 * x[j] as i128;
                    let w = m(a) + m(b) + m(c) + sum[i] * sum[j];
                    q[e] = q[e].add(&det.mul_i128(w));
                }
            }
        }
        Integrals { d, s, q }
    }

    /// The volume, rounded once from the exact sum of the tetrahedra
    /// volumes (within half an ulp of the exact polytope's).
    pub fn volume(&self) -> Scalar {
        // d raw scale 2⁹⁶ → shift 64.
        wide::ratio_to_scalar_saturating(&self.integrals().d, &BigInt::from_i64(6), 64)
    }

    /// Mass, centre of mass and inertia about it, from the exact integrals
    /// over a fan of tetrahedra from the local origin (the canonical-
    /// tetrahedron covariance `det/120 (aaᵀ + bbᵀ + ccᵀ + ssᵀ)`, `s = a+b+c`).
    /// The origin need not be inside the hull: tetrahedra on the far side
    /// count negatively and, the sums being exact, cancel exactly.
    ///
    /// Everything is accumulated exactly (up to 768 bits) and each output
    /// number is rounded once, so each is within half an ulp of the exact
    /// value for the polytope of the (Q32.32) vertices. In particular the
    /// hull of a box's corners gives the same bits as [`Cuboid`](super::cuboid::Cuboid).
    /// With the centroid `c = s / 4d` and
    /// `C = (4 d q − 5 s sᵀ) / 480 d` (the covariance about `c`), the
    /// inertia is `ρ (tr C · 1 − C)`.
    ///
    /// # Errors
    /// [`ShapeError::InvalidDensity`] unless `density > 0`;
    /// [`ShapeError::MassOutOfRange`] when a value does not fit Q32.32 or
    /// the mass rounds to zero.
    pub fn mass_properties(&self, density: Scalar) -> Result<MassProperties, ShapeError> {
        if !density.is_positive() {
            return Err(ShapeError::InvalidDensity { density });
        }
        let out_of_range = || ShapeError::MassOutOfRange {
            kind: "convex_hull",
            density,
        };
        let Integrals { d, s, q } = self.integrals();
        let rho = BigInt::from_scalar(density);
        // mass: ρ 2³² · d 2⁹⁶ = 2¹²⁸ → shift 96.
        let mass =
            ratio_to_scalar(&rho.mul(&d), &BigInt::from_i64(6), 96).ok_or_else(out_of_range)?;
        // centre: s 2¹²⁸ / d 2⁹⁶ = 2³².
        let d4 = d.shl(2);
        let mut center = Vec3::ZERO;
        for (k, sk) in s.iter().enumerate() {
            center.set(k, ratio_to_scalar(sk, &d4, 0).ok_or_else(out_of_range)?);
        }
        // m = 4 d q − 5 s sᵀ [2²⁵⁶]; inertia numerator n = tr(m) 1 − m.
        let m: [BigInt; 6] = std::array::from_fn(|e| {
            let (i, j) = PAIRS[e];
            d.mul(&q[e]).shl(2).sub(&s[i].mul(&s[j]).mul_i128(5))
        });
        let n = [
            m[1].add(&m[2]),
            m[0].add(&m[2]),
            m[0].add(&m[1]),
            m[3].neg(),
            m[4].neg(),
            m[5].neg(),
        ];
        // ρ 2³² · n 2²⁵⁶ / (480 d 2⁹⁶) = 2¹⁹² → shift 160.
        let den = d.mul_i128(480);
        let mut e = [Scalar::ZERO; 6];
        for (slot, nk) in e.iter_mut().zip(&n) {
            *slot = ratio_to_scalar(&rho.mul(nk), &den, 160).ok_or_else(out_of_range)?;
        }
        let inertia = SymMat3 {
            xx: e[0],
            yy: e[1],
            zz: e[2],
            xy: e[3],
            xz: e[4],
            yz: e[5],
        };
        MassProperties::checked(mass, center, inertia, out_of_range)
    }
}

impl Serialize for ConvexHull {
    /// The vertex list only: everything else is rebuilt from it.
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.vertices.serialize(s)
    }
}

impl<'de> Deserialize<'de> for ConvexHull {
    /// Rebuilds the hull from its vertices (validating them); a hull's own
    /// vertices rebuild it bit for bit.
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<ConvexHull, D::Error> {
        let points = Vec::<Vec3>::deserialize(d)?;
        ConvexHull::from_points(&points).map_err(serde::de::Error::custom)
    }
}
