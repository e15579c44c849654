//! Collision shapes and their exact mass properties.
//!
//! One file per shape kind: [`Sphere`], [`Capsule`], [`Cuboid`] (the box),
//! [`ConvexHull`], [`TriMesh`] and [`HeightField`]; [`MassProperties`] in
//! `mass.rs`. [`Shape`] is the closed set the rest of the engine dispatches
//! on. `wide.rs` holds the exact integer arithmetic (orientation predicate,
//! 768-bit integers) and `quickhull.rs` the hull construction.
//!
//! Every constructor validates its input and returns a [`ShapeError`]; a
//! shape that exists is valid. Mass properties are computed from exact
//! integer products and rounded once per output number.

mod capsule;
mod cuboid;
mod error;
mod heightfield;
mod hull;
mod kind;
mod mass;
mod quickhull;
pub(crate) mod sat_features;
mod sphere;
mod trimesh;
mod wide;

#[cfg(test)]
mod hull_tests;

use std::sync::Arc;

use serde::{Deserialize, Serialize};

pub use capsule::Capsule;
pub use cuboid::Cuboid;
pub use error::ShapeError;
pub use heightfield::HeightField;
pub use hull::{ConvexHull, HullFace};
pub use kind::ShapeKind;
pub use mass::MassProperties;
pub use sphere::Sphere;
pub use trimesh::{TriMesh, TriangleQuery};

use crate::math::{Aabb, Mat3, Scalar, Transform, Vec3};

/// A collision shape: the closed set of kinds the engine supports.
///
/// The small shapes are stored inline; hulls, meshes and height fields are
/// shared behind an `Arc`, so cloning a shape (or giving the same mesh to
/// many bodies) is cheap.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Shape {
    /// A ball.
    Sphere(Sphere),
    /// A capsule along local y.
    Capsule(Capsule),
    /// A box.
    Cuboid(Cuboid),
    /// A convex polyhedron.
    ConvexHull(Arc<ConvexHull>),
    /// A static triangle mesh.
    TriMesh(Arc<TriMesh>),
    /// A static height field.
    HeightField(Arc<HeightField>),
}

/// The allowance added to rotated bounding boxes: `2⁻²⁶ · extent + 32` ulps
/// (about 15 nm per metre of extent, plus 7.5e-9 m).
///
/// A unit quaternion in Q32.32 is unit only to about 2⁻³⁰, and the rotation
/// matrix and `Quat::rotate` round differently, so a point rotated by one and
/// by the other can differ by a few parts in 2³⁰ of its distance from the
/// origin. The allowance makes a box computed one way contain the points
/// computed the other way.
pub(crate) fn rotation_margin(extent: Scalar) -> Scalar {
    Scalar::from_bits((extent.to_bits().max(0) >> 26) + 32)
}

/// `|R| h`: the half-extents of the box around a box of half-extents `h`
/// rotated by `R`, each component accumulated exactly and rounded once.
fn rotated_half_extents(r: &Mat3, h: Vec3) -> Vec3 {
    let row = |i: usize| {
        let acc = r.cols[0].get(i).abs().wide_mul(h.x)
            + r.cols[1].get(i).abs().wide_mul(h.y)
            + r.cols[2].get(i).abs().wide_mul(h.z);
        Scalar::from_wide(acc)
    };
    Vec3::new(row(0), row(1), row(2))
}

/// The world box around a local box posed at `pose` (conservative: the box
/// of the rotated box).
///
/// The local centre and half-extents are taken in `i128` (centre rounded
/// down, half-extents up), so a box spanning most of the Q32.32 range, as a
/// level mesh may, does not overflow on the way.
fn posed_box(local: &Aabb, pose: &Transform) -> Aabb {
    let (lo, hi) = (local.min.to_array(), local.max.to_array());
    let mut center = Vec3::ZERO;
    let mut half = Vec3::ZERO;
    for k in 0..3 {
        let (a, b) = (lo[k].to_bits() as i128, hi[k].to_bits() as i128);
        let c = (a + b) >> 1;
        center.set(k, Scalar::from_bits(c as i64));
        half.set(k, Scalar::from_bits(crate::math::scalar::narrow(b - c)));
    }
    let r = Mat3::from_quat(pose.rotation);
    let world_half = rotated_half_extents(&r, half);
    let c = center.abs();
    let margin = rotation_margin(c.x + c.y + c.z + half.x + half.y + half.z);
    Aabb::from_center_half_extents(pose.transform_point(center), world_half).expanded(margin)
}

impl Shape {
    /// The shape's kind.
    pub fn kind(&self) -> ShapeKind {
        match self {
            Shape::Sphere(_) => ShapeKind::Sphere,
            Shape::Capsule(_) => ShapeKind::Capsule,
            Shape::Cuboid(_) => ShapeKind::Cuboid,
            Shape::ConvexHull(_) => ShapeKind::ConvexHull,
            Shape::TriMesh(_) => ShapeKind::TriMesh,
            Shape::HeightField(_) => ShapeKind::HeightField,
        }
    }

    /// How far the surface lies out from the shape's core: the radius of a
    /// sphere (whose core is its centre) or a capsule (its segment), zero
    /// for the flat-faced shapes.
    ///
    /// Why: the point of a round surface that touches something is not a
    /// point of the body (it moves over the surface as the body rolls), but
    /// the point of the core behind it, one radius in from the contact, is;
    /// the contact solver follows a contact's separation through it.
    pub fn rounding(&self) -> Scalar {
        match self {
            Shape::Sphere(s) => s.radius,
            Shape::Capsule(c) => c.radius,
            Shape::Cuboid(_) | Shape::ConvexHull(_) | Shape::TriMesh(_) | Shape::HeightField(_) => {
                Scalar::ZERO
            }
        }
    }

    /// Checks the dimensions of the shapes whose fields are public (sphere,
    /// capsule, box), as their `new` does: a literal such as
    /// `Sphere { radius }` is not checked when written.
    /// [`World::add_collider`](crate::World::add_collider) calls this. Hulls,
    /// meshes and height fields can only be built by their checking
    /// constructors, so they are valid.
    ///
    /// # Errors
    /// The [`ShapeError`] the shape's `new` would give.
    pub fn validate(&self) -> Result<(), ShapeError> {
        match self {
            Shape::Sphere(s) => Sphere::new(s.radius).map(drop),
            Shape::Capsule(c) => Capsule::new(c.half_height, c.radius).map(drop),
            Shape::Cuboid(b) => Cuboid::new(b.half_extents).map(drop),
            Shape::ConvexHull(_) | Shape::TriMesh(_) | Shape::HeightField(_) => Ok(()),
        }
    }

    /// Whether only static bodies may carry this shape (triangle meshes and
    /// height fields: they enclose no volume, so they have no mass).
    pub fn is_static_only(&self) -> bool {
        matches!(self, Shape::TriMesh(_) | Shape::HeightField(_))
    }

    /// The bounding box in the shape's local frame.
    pub fn local_aabb(&self) -> Aabb {
        match self {
            Shape::Sphere(s) => s.local_aabb(),
            Shape::Capsule(c) => c.local_aabb(),
            Shape::Cuboid(b) => b.local_aabb(),
            Shape::ConvexHull(h) => h.local_aabb(),
            Shape::TriMesh(m) => m.local_aabb(),
            Shape::HeightField(f) => f.local_aabb(),
        }
    }

    /// The world bounding box of the shape posed at `pose`, for the broad
    /// phase. Always contains the shape:
    /// * sphere: exactly `center ± r`;
    /// * capsule: the box of the two rotated segment ends grown by `r`
    ///   (tight up to the rotation allowance);
    /// * box: `|R| h` around the centre;
    /// * hull: the box of its rotated vertices;
    /// * mesh, height field: the box of the rotated local box.
    ///
    /// Rotated boxes are grown by a small rounding allowance (2⁻²⁶ of the
    /// shape's extent plus 32 ulps) so that they also contain points rotated
    /// through [`Transform::transform_point`].
    pub fn aabb(&self, pose: &Transform) -> Aabb {
        let t = pose.translation;
        match self {
            Shape::Sphere(s) => Aabb::from_center_half_extents(t, Vec3::splat(s.radius)),
            Shape::Capsule(c) => {
                let r = Mat3::from_quat(pose.rotation);
                let axis = r.cols[1] * c.half_height;
                let half = axis.abs() + Vec3::splat(c.radius + rotation_margin(c.half_height));
                Aabb::from_center_half_extents(t, half)
            }
            Shape::Cuboid(b) => {
                let h = b.half_extents;
                let r = Mat3::from_quat(pose.rotation);
                let half =
                    rotated_half_extents(&r, h) + Vec3::splat(rotation_margin(h.x + h.y + h.z));
                Aabb::from_center_half_extents(t, half)
            }
            Shape::ConvexHull(h) => h.aabb(pose),
            Shape::TriMesh(m) => posed_box(&m.local_aabb(), pose),
            Shape::HeightField(f) => posed_box(&f.local_aabb(), pose),
        }
    }

    /// The volume (rounded once from the exact value); zero for the
    /// static-only shapes, which enclose none.
    pub fn volume(&self) -> Scalar {
        match self {
            Shape::Sphere(s) => s.volume(),
            Shape::Capsule(c) => c.volume(),
            Shape::Cuboid(b) => b.volume(),
            Shape::ConvexHull(h) => h.volume(),
            Shape::TriMesh(_) | Shape::HeightField(_) => Scalar::ZERO,
        }
    }

    /// Mass, centre of mass and inertia of the shape filled at `density`
    /// (kg/m³), each number within half an ulp of the exact value.
    ///
    /// # Errors
    /// * [`ShapeError::StaticOnly`] for triangle meshes and height fields;
    /// * [`ShapeError::InvalidDensity`] unless `density > 0`;
    /// * [`ShapeError::MassOutOfRange`] when a value does not fit Q32.32 or
    ///   the mass rounds to zero.
    pub fn mass_properties(&self, density: Scalar) -> Result<MassProperties, ShapeError> {
        match self {
            Shape::Sphere(s) => s.mass_properties(density),
            Shape::Capsule(c) => c.mass_properties(density),
            Shape::Cuboid(b) => b.mass_properties(density),
            Shape::ConvexHull(h) => h.mass_properties(density),
            Shape::TriMesh(_) | Shape::HeightField(_) => {
                Err(ShapeError::StaticOnly { kind: self.kind() })
            }
        }
    }
}

impl From<Sphere> for Shape {
    fn from(s: Sphere) -> Shape {
        Shape::Sphere(s)
    }
}

impl From<Capsule> for Shape {
    fn from(c: Capsule) -> Shape {
        Shape::Capsule(c)
    }
}

impl From<Cuboid> for Shape {
    fn from(b: Cuboid) -> Shape {
        Shape::Cuboid(b)
    }
}

impl From<ConvexHull> for Shape {
    fn from(h: ConvexHull) -> Shape {
        Shape::ConvexHull(Arc::new(h))
    }
}

impl From<TriMesh> for Shape {
    fn from(m: TriMesh) -> Shape {
        Shape::TriMesh(Arc::new(m))
    }
}

impl From<HeightField> for Shape {
    fn from(f: HeightField) -> Shape {
        Shape::HeightField(Arc::new(f))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Quat;

    use crate::testing::{Rng, s};

    fn random_pose(rng: &mut Rng) -> Transform {
        let axis = Vec3::new(
            s(rng.unit() - 0.5),
            s(rng.unit() - 0.5),
            s(rng.unit() - 0.5),
        )
        .try_normalize()
        .unwrap_or(Vec3::X);
        let q = Quat::from_axis_angle(axis, s(rng.unit() * 6.3)).normalize();
        let t = Vec3::new(
            s(rng.unit() * 200.0 - 100.0),
            s(rng.unit() * 20.0),
            s(rng.unit() * 200.0 - 100.0),
        );
        Transform::new(t, q)
    }

    fn shapes() -> Vec<Shape> {
        let mesh = TriMesh::new(
            vec![
                Vec3::ZERO,
                Vec3::from_ints(4, 0, 0),
                Vec3::from_ints(0, 1, 3),
            ],
            vec![[0, 2, 1]],
        )
        .unwrap();
        let field = HeightField::new(
            2,
            2,
            vec![Scalar::ZERO, Scalar::ONE, Scalar::TWO, Scalar::NEG_ONE],
            Vec3::splat(Scalar::ONE),
        )
        .unwrap();
        let hull = ConvexHull::from_points(&[
            Vec3::from_ints(0, 0, 0),
            Vec3::from_ints(2, 0, 0),
            Vec3::from_ints(0, 3, 0),
            Vec3::from_ints(0, 0, 1),
        ])
        .unwrap();
        vec![
            Sphere::new(s(0.5)).unwrap().into(),
            Capsule::new(s(1.0), s(0.25)).unwrap().into(),
            Cuboid::new(Vec3::new(s(1.5), s(0.5), s(0.25)))
                .unwrap()
                .into(),
            hull.into(),
            mesh.into(),
            field.into(),
        ]
    }

    #[test]
    fn kinds_have_stable_names_and_static_flags() {
        let names: Vec<&str> = shapes().iter().map(|x| x.kind().name()).collect();
        assert_eq!(
            names,
            [
                "sphere",
                "capsule",
                "box",
                "convex_hull",
                "trimesh",
                "heightfield"
            ]
        );
        let statics: Vec<bool> = shapes().iter().map(Shape::is_static_only).collect();
        assert_eq!(statics, [false, false, false, false, true, true]);
    }

    #[test]
    fn static_shapes_and_bad_densities_have_no_mass() {
        let all = shapes();
        assert_eq!(
            all[4].mass_properties(Scalar::ONE),
            Err(ShapeError::StaticOnly {
                kind: ShapeKind::TriMesh
            })
        );
        assert_eq!(
            all[5].mass_properties(Scalar::ONE).unwrap_err().to_string(),
            "a heightfield shape is static-only: it has no mass properties"
        );
        for shape in &all[..4] {
            assert_eq!(
                shape.mass_properties(-Scalar::ONE),
                Err(ShapeError::InvalidDensity {
                    density: -Scalar::ONE
                })
            );
            assert_eq!(
                shape.mass_properties(Scalar::ZERO),
                Err(ShapeError::InvalidDensity {
                    density: Scalar::ZERO
                })
            );
            assert!(shape.volume().is_positive());
        }
        assert_eq!(all[4].volume(), Scalar::ZERO);
        // The hull tetrahedron: 2·3·1/6 = 1 m³.
        assert_eq!(all[3].volume(), Scalar::ONE);
    }

    #[test]
    fn sphere_and_capsule_boxes_are_tight() {
        let all = shapes();
        let t = Vec3::from_ints(10, -3, 7);
        let pose = Transform::from_translation(t);
        assert_eq!(
            all[0].aabb(&pose),
            Aabb::from_center_half_extents(t, Vec3::splat(s(0.5)))
        );
        // Lying along x after a quarter turn about z: extents (h + r, r, r).
        let quarter = Transform::new(
            t,
            Quat::from_axis_angle(Vec3::Z, Scalar::FRAC_PI_2).normalize(),
        );
        let b = all[1].aabb(&quarter);
        let want = Aabb::from_center_half_extents(t, Vec3::new(s(1.25), s(0.25), s(0.25)));
        let slack = (b.max - want.max).max(want.min - b.min);
        assert!(b.contains(&want), "{b:?}");
        assert!(slack.max_element() <= Scalar::from_bits(128), "{slack:?}");
        // Unrotated: exactly the local box plus the 32-ulp allowance on the
        // rotated axis.
        assert_eq!(
            all[1].aabb(&Transform::IDENTITY).max.y,
            s(1.25) + rotation_margin(Scalar::ONE)
        );
    }

    #[test]
    fn world_boxes_contain_the_posed_shape_for_random_rotations() {
        let mut st = Rng::new(11);
        let all = shapes();
        for _ in 0..500 {
            let pose = random_pose(&mut st);
            for shape in &all {
                let b = shape.aabb(&pose);
                let points: Vec<Vec3> = match shape {
                    Shape::Sphere(sp) => {
                        // Six extreme points of the sphere.
                        let r = sp.radius;
                        [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z]
                            .iter()
                            .map(|d| pose.translation + *d * r)
                            .collect()
                    }
                    Shape::Capsule(c) => c
                        .segment()
                        .iter()
                        .flat_map(|&e| {
                            let w = pose.transform_point(e);
                            let r = c.radius;
                            [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z]
                                .map(|d| w + d * r)
                        })
                        .collect(),
                    Shape::Cuboid(bx) => bx
                        .corners()
                        .iter()
                        .map(|&c| pose.transform_point(c))
                        .collect(),
                    Shape::ConvexHull(h) => h
                        .vertices()
                        .iter()
                        .map(|&v| pose.transform_point(v))
                        .collect(),
                    Shape::TriMesh(m) => m
                        .vertices()
                        .iter()
                        .map(|&v| pose.transform_point(v))
                        .collect(),
                    Shape::HeightField(f) => (0..2)
                        .flat_map(|r| (0..2).map(move |c| (r, c)))
                        .map(|(r, c)| pose.transform_point(f.vertex(r, c).unwrap()))
                        .collect(),
                };
                for p in points {
                    assert!(
                        b.contains_point(p),
                        "{:?} at {pose:?}: {p:?} outside {b:?}",
                        shape.kind()
                    );
                }
            }
        }
    }

    #[test]
    fn box_world_box_is_tight_up_to_the_allowance() {
        // 45° about z: the x and y extents become (hx + hy)/√2.
        let b: Shape = Cuboid::new(Vec3::new(s(2.0), s(1.0), s(0.5)))
            .unwrap()
            .into();
        let q = Quat::from_axis_angle(Vec3::Z, Scalar::PI.div_int(4)).normalize();
        let a = b.aabb(&Transform::new(Vec3::ZERO, q));
        let want = 3.0 / 2f64.sqrt();
        for got in [a.max.x, a.max.y, -a.min.x] {
            let err = got.to_f64() - want;
            assert!((0.0..1e-7).contains(&err), "{got} vs {want}");
        }
        assert!((a.max.z.to_f64() - 0.5).abs() < 1e-7);
    }

    #[test]
    fn shapes_survive_a_serde_round_trip() {
        let cfg = bincode::config::standard();
        for shape in shapes() {
            let bytes = bincode::serde::encode_to_vec(&shape, cfg).unwrap();
            let (back, _): (Shape, usize) = bincode::serde::decode_from_slice(&bytes, cfg).unwrap();
            assert_eq!(back, shape);
        }
        // Invalid data is rejected on the way in.
        #[derive(Serialize)]
        enum Fake {
            Sphere { radius: Scalar },
        }
        let bytes = bincode::serde::encode_to_vec(
            Fake::Sphere {
                radius: -Scalar::ONE,
            },
            cfg,
        )
        .unwrap();
        assert!(bincode::serde::decode_from_slice::<Shape, _>(&bytes, cfg).is_err());
    }
}
