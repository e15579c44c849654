//! What the polytope separating axis test needs of a convex polyhedron
//! beyond its vertices and faces, computed once when the shape is built
//! instead of on every narrow-phase test.
//!
//! * The two faces of every edge and the edge's arc on the Gauss map: the
//!   SAT's Gauss-map (Minkowski face) test reads them for every edge pair.
//! * A bounding ball and an inscribed ball about one centre, and per edge
//!   a cone that holds the edge's arc of normals: from these the SAT bounds
//!   every face's and every edge's separation with one dot product, and
//!   skips the exact test of the features that cannot win (see
//!   `collision/narrow/polytope.rs`). The bounds only decide what is
//!   skipped, never a result, so they may be loose; they must not be
//!   wrong, hence every radius is rounded outward (or inward) on purpose.

use crate::math::{Scalar, Vec3, elem};

/// Sentinel for an edge side with no face (never happens on a closed hull).
pub(crate) const NO_FACE: u16 = u16::MAX;

/// The SAT's per-shape data, in the shape's own frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct SatFeatures {
    /// Per edge `[low, high]`: `[the face whose loop runs low → high, the
    /// face whose loop runs high → low]`.
    pub edge_faces: Vec<[u16; 2]>,
    /// Per edge, `n₁ × n₀` of those two faces' normals (each component
    /// rounded once): the normal of the edge's arc on the Gauss map.
    pub arcs: Vec<Vec3>,
    /// Per edge, a unit axis and a radius: every unit vector on the edge's
    /// arc (between its faces' normals) is within `radius` of `axis`.
    pub cones: Vec<(Vec3, Scalar)>,
    /// Balls about `center`.
    pub balls: Balls,
}

/// A centre inside the shape with an inscribed and a bounding radius.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Balls {
    /// A point inside the shape (the mean of the vertices).
    pub center: Vec3,
    /// Every face plane is at least this far from `center` (rounded down,
    /// never negative): the ball of this radius is inside the shape.
    pub inner: Scalar,
    /// No vertex is farther than this from `center` (rounded up).
    pub outer: Scalar,
}

impl Balls {
    /// The balls of a vertex set whose face planes are `(normal, offset)`
    /// with `normal · v ≤ offset` for every vertex.
    pub(crate) fn new(vertices: &[Vec3], planes: impl Iterator<Item = (Vec3, Scalar)>) -> Balls {
        let n = vertices.len().max(1) as i128;
        let mean = |k: usize| {
            let sum: i128 = vertices.iter().map(|v| v.get(k).to_bits() as i128).sum();
            Scalar::from_bits(sum.div_euclid(n) as i64)
        };
        let center = Vec3::new(mean(0), mean(1), mean(2));
        let inner_wide = planes
            .map(|(normal, offset)| ((offset.to_bits() as i128) << 32) - normal.dot_wide(center))
            .min()
            .unwrap_or(0);
        // Floor of the Q64.64 distance, one ulp less for the normals'
        // rounding, and never below zero (the centre is inside).
        let inner = Scalar::from_bits(((inner_wide >> 32) - 1).max(0) as i64);
        let far = vertices
            .iter()
            .map(|v| (*v - center).length_squared_wide())
            .max()
            .unwrap_or(0);
        let outer = Scalar::from_bits(elem::isqrt_u128(far) as i64 + 1);
        Balls {
            center,
            inner,
            outer,
        }
    }
}

/// The cone around the arc between unit normals `n0` and `n1`: their
/// normalised mean as the axis, and the larger distance from it to either
/// end (rounded up) as the radius; the ends of an arc shorter than a half
/// circle are its farthest points from its midpoint. Opposite normals
/// (no arc) get the radius 2, which holds any unit vector.
pub(crate) fn arc_cone(n0: Vec3, n1: Vec3) -> (Vec3, Scalar) {
    match (n0 + n1).try_normalize() {
        Some(axis) => {
            let reach = (n0 - axis).length().max((n1 - axis).length());
            // Floor of the length, plus margin for the normals' and the
            // axis' own rounding.
            (axis, reach + Scalar::from_bits(16))
        }
        None => (n0, Scalar::from_int(2)),
    }
}

impl SatFeatures {
    /// The features of a closed polyhedron: `edges` sorted `[low, high]`
    /// pairs, `face_loop(f)` the vertex loop of face `f` (counter-clockwise
    /// from outside), `normal(f)` / `offset(f)` its plane.
    pub(crate) fn new<'a>(
        vertices: &[Vec3],
        edges: &[[u32; 2]],
        face_count: usize,
        face_loop: impl Fn(usize) -> &'a [u32],
        normal: impl Fn(usize) -> Vec3,
        offset: impl Fn(usize) -> Scalar,
    ) -> SatFeatures {
        let mut edge_faces = vec![[NO_FACE; 2]; edges.len()];
        for f in 0..face_count {
            let fv = face_loop(f);
            for k in 0..fv.len() {
                let (u, v) = (fv[k], fv[(k + 1) % fv.len()]);
                if let Ok(e) = edges.binary_search(&[u.min(v), u.max(v)]) {
                    edge_faces[e][usize::from(u > v)] = f as u16;
                }
            }
        }
        let mut arcs = vec![Vec3::ZERO; edges.len()];
        let mut cones = vec![(Vec3::ZERO, Scalar::from_int(2)); edges.len()];
        for (e, &[f0, f1]) in edge_faces.iter().enumerate() {
            if f0 != NO_FACE && f1 != NO_FACE {
                let (n0, n1) = (normal(f0 as usize), normal(f1 as usize));
                arcs[e] = n1.cross(n0);
                cones[e] = arc_cone(n0, n1);
            }
        }
        let balls = Balls::new(vertices, (0..face_count).map(|f| (normal(f), offset(f))));
        SatFeatures {
            edge_faces,
            arcs,
            cones,
            balls,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(x: f64, y: f64, z: f64) -> Vec3 {
        let s = |c: f64| Scalar::from_f64_lossy(c);
        Vec3::new(s(x), s(y), s(z)).try_normalize().unwrap()
    }

    #[test]
    fn a_cone_holds_every_point_of_its_arc() {
        for (a, b) in [
            (unit(1.0, 0.0, 0.0), unit(0.0, 1.0, 0.0)),
            (unit(1.0, 0.2, -0.3), unit(0.1, 1.0, 0.4)),
            (unit(0.0, 0.0, 1.0), unit(0.0, 0.999, -0.04)),
        ] {
            let (axis, radius) = arc_cone(a, b);
            for k in 0..=16 {
                let t = Scalar::from_ratio(k, 16);
                let p = (a + (b - a) * t).try_normalize().unwrap();
                assert!((p - axis).length() <= radius, "{k}");
            }
            // Not loose: the ends sit within 2⁻²⁰ of the radius.
            assert!(radius - (a - axis).length() < Scalar::from_bits(1 << 12));
        }
        assert_eq!(arc_cone(Vec3::X, -Vec3::X).1, Scalar::from_int(2));
    }

    #[test]
    fn balls_of_a_box_are_its_half_extents_and_corner_distance() {
        let h = [1, 2, 3];
        let corners: Vec<Vec3> = (0..8)
            .map(|i| {
                let pick = |bit: usize, c: i32| Scalar::from_int(if i & bit != 0 { c } else { -c });
                Vec3::new(pick(1, h[0]), pick(2, h[1]), pick(4, h[2]))
            })
            .collect();
        let planes = (0..6).map(|f| {
            let mut n = Vec3::ZERO;
            n.set(
                f / 2,
                if f % 2 == 1 {
                    Scalar::ONE
                } else {
                    Scalar::NEG_ONE
                },
            );
            (n, Scalar::from_int(h[f / 2]))
        });
        let b = Balls::new(&corners, planes);
        assert_eq!(b.center, Vec3::ZERO);
        // One ulp inside the nearest face; one ulp beyond the corners
        // (√14 = 3.7417).
        assert_eq!(b.inner, Scalar::ONE - Scalar::from_bits(1));
        let outer = b.outer.to_f64();
        assert!(
            outer >= 14f64.sqrt() && outer < 14f64.sqrt() + 1e-9,
            "{outer}"
        );
    }
}
