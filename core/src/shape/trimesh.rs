//! `TriMesh`: a static triangle soup (level geometry).

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::ShapeError;
use super::wide::{BigInt, raw, unit_of_wide};
use crate::math::{Aabb, Vec3};

/// A triangle mesh for static geometry: terrain pieces, walls, ramps.
///
/// Triangles are one-sided in the sense that each has an outward normal
/// `(b − a) × (c − a)` (counter-clockwise seen from the front), which the
/// collision code uses to push bodies out. The mesh need not be closed, so
/// it has no volume and no mass: bodies carrying one must be static.
///
/// Validated on construction (indices in range, no zero-area triangle), and
/// again when deserialised; the per-triangle unit normals are computed once
/// from the exact cross products.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TriMesh {
    vertices: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
    normals: Vec<Vec3>,
    local_aabb: Aabb,
}

/// The exact cross product `(b − a) × (c − a)` of raw points, with
/// components up to 2¹²⁹ in magnitude, scaled down (by a power of two,
/// rounded to nearest) when needed so that they fit `i128`; zero exactly when
/// the three points are collinear.
fn exact_normal(a: Vec3, b: Vec3, c: Vec3) -> [i128; 3] {
    let (a, b, c) = (raw(a), raw(b), raw(c));
    let d = |p: [i64; 3], k: usize| p[k] as i128 - a[k] as i128;
    let u = [d(b, 0), d(b, 1), d(b, 2)];
    let v = [d(c, 0), d(c, 1), d(c, 2)];
    let fits = u.iter().chain(&v).all(|x| x.unsigned_abs() < 1 << 62);
    if fits {
        return [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
    }
    // Far-apart vertices: exact on BigInts, then shifted into range.
    let m = |p: i128, q: i128, r: i128, s: i128| {
        BigInt::from_i128(p)
            .mul_i128(q)
            .sub(&BigInt::from_i128(r).mul_i128(s))
    };
    let big = [
        m(u[1], v[2], u[2], v[1]),
        m(u[2], v[0], u[0], v[2]),
        m(u[0], v[1], u[1], v[0]),
    ];
    // |component| < 2¹³¹: shift the largest down to 120 bits (rounded).
    // Smaller components may lose low bits, but the largest stays non-zero,
    // so the result is zero exactly when the exact cross product is.
    let bits = big.iter().map(BigInt::bit_len).max().unwrap_or(0);
    let shift = bits.saturating_sub(120);
    let one = BigInt::from_i64(1);
    big.map(|x| {
        let scaled = if shift == 0 {
            x
        } else {
            x.div_round(&one.shl(shift))
        };
        scaled.to_i128().unwrap_or(0)
    })
}

impl TriMesh {
    /// A mesh from a vertex list and triangles indexing into it.
    ///
    /// # Errors
    /// * [`ShapeError::TriMeshEmpty`] with no triangle;
    /// * [`ShapeError::TriMeshIndexOutOfRange`] naming the first triangle
    ///   with an index `≥ vertices.len()`;
    /// * [`ShapeError::TriMeshDegenerateTriangle`] naming the first triangle
    ///   whose corners are collinear (zero area, tested exactly).
    pub fn new(vertices: Vec<Vec3>, indices: Vec<[u32; 3]>) -> Result<TriMesh, ShapeError> {
        if indices.is_empty() {
            return Err(ShapeError::TriMeshEmpty);
        }
        let mut normals = Vec::with_capacity(indices.len());
        for (t, tri) in indices.iter().enumerate() {
            let mut corner = [Vec3::ZERO; 3];
            for (k, &i) in tri.iter().enumerate() {
                corner[k] =
                    *vertices
                        .get(i as usize)
                        .ok_or(ShapeError::TriMeshIndexOutOfRange {
                            triangle: t,
                            index: i,
                            vertex_count: vertices.len(),
                        })?;
            }
            let n = unit_of_wide(exact_normal(corner[0], corner[1], corner[2]))
                .ok_or(ShapeError::TriMeshDegenerateTriangle { triangle: t })?;
            normals.push(n);
        }
        let first = vertices[indices[0][0] as usize];
        let local_aabb = vertices
            .iter()
            .fold(Aabb::new(first, first), |b, &v| b.include_point(v));
        Ok(TriMesh {
            vertices,
            indices,
            normals,
            local_aabb,
        })
    }

    /// The vertex positions.
    pub fn vertices(&self) -> &[Vec3] {
        &self.vertices
    }

    /// The triangles, as indices into [`vertices`](Self::vertices).
    pub fn indices(&self) -> &[[u32; 3]] {
        &self.indices
    }

    /// The unit normal of each triangle, `(b − a) × (c − a)` normalised
    /// (within about an ulp per component of the exact direction).
    pub fn normals(&self) -> &[Vec3] {
        &self.normals
    }

    /// The corners of triangle `t`, or `None` past the end.
    pub fn triangle(&self, t: usize) -> Option<[Vec3; 3]> {
        let tri = self.indices.get(t)?;
        Some(tri.map(|i| self.vertices[i as usize]))
    }

    /// The box around every vertex (referenced or not).
    pub fn local_aabb(&self) -> Aabb {
        self.local_aabb
    }
}

#[derive(Serialize)]
struct TriMeshRef<'a> {
    vertices: &'a [Vec3],
    indices: &'a [[u32; 3]],
}

#[derive(Deserialize)]
struct TriMeshData {
    vertices: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
}

impl Serialize for TriMesh {
    /// Only the vertices and indices: normals and bounds are derived.
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        TriMeshRef {
            vertices: &self.vertices,
            indices: &self.indices,
        }
        .serialize(s)
    }
}

impl<'de> Deserialize<'de> for TriMesh {
    /// Rebuilds (and so re-validates) the mesh.
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<TriMesh, D::Error> {
        let data = TriMeshData::deserialize(d)?;
        TriMesh::new(data.vertices, data.indices).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Scalar;

    fn quad() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let v = vec![
            Vec3::from_ints(0, 0, 0),
            Vec3::from_ints(1, 0, 0),
            Vec3::from_ints(1, 0, 1),
            Vec3::from_ints(0, 0, 1),
        ];
        (v, vec![[0, 2, 1], [0, 3, 2]])
    }

    #[test]
    fn floor_quad_has_upward_unit_normals_and_tight_bounds() {
        let (v, i) = quad();
        let m = TriMesh::new(v, i).unwrap();
        assert_eq!(m.normals(), &[Vec3::Y, Vec3::Y]);
        assert_eq!(
            m.local_aabb(),
            Aabb::new(Vec3::ZERO, Vec3::from_ints(1, 0, 1))
        );
        assert_eq!(
            m.triangle(1),
            Some([
                Vec3::ZERO,
                Vec3::from_ints(0, 0, 1),
                Vec3::from_ints(1, 0, 1)
            ])
        );
        assert_eq!(m.triangle(2), None);
    }

    #[test]
    fn mesh_validation_names_the_offending_triangle() {
        let (v, _) = quad();
        assert_eq!(
            TriMesh::new(v.clone(), vec![]),
            Err(ShapeError::TriMeshEmpty)
        );
        let e = TriMesh::new(v.clone(), vec![[0, 2, 1], [0, 4, 2]]).unwrap_err();
        assert_eq!(
            e,
            ShapeError::TriMeshIndexOutOfRange {
                triangle: 1,
                index: 4,
                vertex_count: 4
            }
        );
        assert_eq!(
            e.to_string(),
            "triangle 1 of the mesh uses vertex 4, but there are only 4 vertices"
        );
        // A repeated index and three collinear points both have zero area.
        let e = TriMesh::new(v.clone(), vec![[0, 2, 1], [1, 1, 2]]).unwrap_err();
        assert_eq!(e, ShapeError::TriMeshDegenerateTriangle { triangle: 1 });
        assert_eq!(e.to_string(), "triangle 1 of the mesh has zero area");
        let mut w = v;
        w.push(Vec3::from_ints(2, 0, 2)); // on the line through 0 and 2
        let e = TriMesh::new(w, vec![[0, 2, 1], [0, 3, 2], [0, 2, 4]]).unwrap_err();
        assert_eq!(e, ShapeError::TriMeshDegenerateTriangle { triangle: 2 });
    }

    #[test]
    fn tiny_and_huge_triangles_are_judged_exactly() {
        // A sliver one raw unit high is not degenerate; its normal is exact.
        let d = Scalar::DELTA;
        let v = vec![
            Vec3::ZERO,
            Vec3::new(Scalar::ZERO, Scalar::ZERO, d),
            Vec3::new(d, Scalar::ZERO, Scalar::ZERO),
        ];
        let m = TriMesh::new(v, vec![[0, 1, 2]]).unwrap();
        assert_eq!(m.normals()[0], Vec3::Y);
        // Corners far apart (differences above 2⁶² raw) take the wide path.
        let big = Scalar::from_int(2_000_000_000);
        let v = vec![
            Vec3::new(-big, Scalar::ZERO, -big),
            Vec3::new(-big, Scalar::ZERO, big),
            Vec3::new(big, Scalar::ZERO, -big),
            Vec3::new(big, Scalar::ZERO, big),
        ];
        let m = TriMesh::new(v.clone(), vec![[0, 1, 2]]).unwrap();
        assert_eq!(m.normals()[0], Vec3::Y);
        // Collinear at that scale is still caught.
        let v2 = vec![v[0], Vec3::ZERO, v[3]];
        assert_eq!(
            TriMesh::new(v2, vec![[0, 1, 2]]),
            Err(ShapeError::TriMeshDegenerateTriangle { triangle: 0 })
        );
    }

    #[test]
    fn mesh_survives_a_serde_round_trip_and_rejects_bad_data() {
        let (v, i) = quad();
        let m = TriMesh::new(v.clone(), i).unwrap();
        let cfg = bincode::config::standard();
        let bytes = bincode::serde::encode_to_vec(&m, cfg).unwrap();
        let (back, _): (TriMesh, usize) = bincode::serde::decode_from_slice(&bytes, cfg).unwrap();
        assert_eq!(back, m);
        let bad = TriMeshRef {
            vertices: &v,
            indices: &[[0, 1, 9]],
        };
        let bytes = bincode::serde::encode_to_vec(&bad, cfg).unwrap();
        assert!(bincode::serde::decode_from_slice::<TriMesh, _>(&bytes, cfg).is_err());
    }
}
