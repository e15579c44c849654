//! Colliders: a shape attached to a body at a local pose, with a material,
//! collision filter and trigger flag. A body may carry several (a compound);
//! its mass properties combine theirs.

mod filter;
mod material;

pub use filter::CollisionFilter;
pub use material::Material;

use serde::{Deserialize, Serialize};

use crate::collision::broad_phase::ProxyId;
use crate::handles::BodyHandle;
pub use crate::handles::ColliderHandle;
use crate::math::{Scalar, Transform, Vec3};
use crate::shape::{Capsule, Cuboid, MassProperties, Shape, Sphere};

/// How a collider's mass is given.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum MassSpec {
    /// Mass from the shape's volume times this density, kg/m³.
    Density(Scalar),
    /// This total mass, kg, spread uniformly over the shape.
    Mass(Scalar),
}

/// A description of a collider to add with
/// [`World::add_collider`](crate::World::add_collider).
///
/// The shortcuts [`sphere`](ColliderDesc::sphere),
/// [`cuboid`](ColliderDesc::cuboid) and [`capsule`](ColliderDesc::capsule)
/// make the common shapes; [`new`](ColliderDesc::new) takes any [`Shape`].
/// A dynamic body's mass comes from its colliders' densities (default
/// 1000 kg/m³) or masses.
///
/// ```
/// use lockstep_core::{BodyDesc, ColliderDesc, Material, Scalar, World, WorldConfig, scalar};
///
/// let mut world = World::new(WorldConfig::default())?;
/// let crate_ = world.create_body(&BodyDesc::dynamic())?;
/// // A 1 m cube (half-extents 0.5 m) of density 500 kg/m³ weighs 500 kg.
/// let cube = ColliderDesc::cuboid(scalar!(0.5), scalar!(0.5), scalar!(0.5))
///     .density(scalar!(500))
///     .material(Material::new(scalar!(0.8), Scalar::ZERO));
/// world.add_collider(crate_, cube)?;
/// assert_eq!(world.body(crate_)?.mass(), scalar!(500));
///
/// // Or give the mass itself.
/// let pawn = world.create_body(&BodyDesc::dynamic())?;
/// world.add_collider(pawn, ColliderDesc::capsule(scalar!(0.9), scalar!(0.3)).mass(scalar!(80)))?;
/// assert_eq!(world.body(pawn)?.mass(), scalar!(80));
///
/// // Dimensions are checked when the collider is added.
/// assert!(world.add_collider(pawn, ColliderDesc::sphere(Scalar::ZERO)).is_err());
/// # Ok::<(), lockstep_core::WorldError>(())
/// ```
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ColliderDesc {
    /// The geometry.
    pub shape: Shape,
    /// Pose of the shape in the body's frame.
    pub local_pose: Transform,
    /// Density or mass (ignored on static and kinematic bodies).
    pub mass: MassSpec,
    /// Friction and restitution.
    pub material: Material,
    /// Which other colliders it may touch.
    pub filter: CollisionFilter,
    /// A trigger reports overlaps and produces no contacts.
    pub is_trigger: bool,
}

impl ColliderDesc {
    /// A collider of `shape` at the body origin, density 1000 kg/m³ (water),
    /// default material and filter. The shape's dimensions are checked by
    /// [`World::add_collider`](crate::World::add_collider).
    pub fn new(shape: Shape) -> ColliderDesc {
        ColliderDesc {
            shape,
            local_pose: Transform::IDENTITY,
            mass: MassSpec::Density(Scalar::from_int(1000)),
            material: Material::default(),
            filter: CollisionFilter::default(),
            is_trigger: false,
        }
    }

    /// A ball of radius `radius` (> 0) centred on the body origin.
    pub fn sphere(radius: Scalar) -> ColliderDesc {
        ColliderDesc::new(Shape::Sphere(Sphere { radius }))
    }

    /// A box with half-extents `hx`, `hy`, `hz` (each > 0) along the body's
    /// axes, centred on the body origin.
    pub fn cuboid(hx: Scalar, hy: Scalar, hz: Scalar) -> ColliderDesc {
        ColliderDesc::new(Shape::Cuboid(Cuboid {
            half_extents: Vec3::new(hx, hy, hz),
        }))
    }

    /// A capsule along the body's y axis: the segment from `−half_height`
    /// to `+half_height` (≥ 0), thickened by `radius` (> 0). Its total
    /// height is `2 · (half_height + radius)`.
    pub fn capsule(half_height: Scalar, radius: Scalar) -> ColliderDesc {
        ColliderDesc::new(Shape::Capsule(Capsule {
            half_height,
            radius,
        }))
    }

    /// Sets the local pose.
    pub fn local_pose(mut self, pose: Transform) -> ColliderDesc {
        self.local_pose = pose;
        self
    }

    /// Sets the density, kg/m³.
    pub fn density(mut self, d: Scalar) -> ColliderDesc {
        self.mass = MassSpec::Density(d);
        self
    }

    /// Sets the total mass, kg.
    pub fn mass(mut self, m: Scalar) -> ColliderDesc {
        self.mass = MassSpec::Mass(m);
        self
    }

    /// Sets the material.
    pub fn material(mut self, m: Material) -> ColliderDesc {
        self.material = m;
        self
    }

    /// Sets the collision filter.
    pub fn filter(mut self, f: CollisionFilter) -> ColliderDesc {
        self.filter = f;
        self
    }

    /// Makes it a trigger (overlap events, no contacts).
    pub fn trigger(mut self, is_trigger: bool) -> ColliderDesc {
        self.is_trigger = is_trigger;
        self
    }
}

/// A collider as stored in the world.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Collider {
    /// The body it is attached to.
    pub body: BodyHandle,
    /// The geometry.
    pub shape: Shape,
    /// Pose in the body frame.
    pub local_pose: Transform,
    /// How its mass was given.
    pub mass_spec: MassSpec,
    /// Its mass properties in the body frame (zero for static-only shapes and
    /// colliders on static or kinematic bodies).
    pub mass_properties: MassProperties,
    /// Friction and restitution.
    pub material: Material,
    /// Collision filter.
    pub filter: CollisionFilter,
    /// Whether it is a trigger.
    pub is_trigger: bool,
    /// A hash of the shape's geometry, computed once, for the state hash.
    pub shape_hash: u64,
    /// Its proxy in the world's broad phase.
    pub proxy: ProxyId,
}

impl Collider {
    /// The collider's world pose given its body's origin pose. A collider at
    /// the body origin (the common case) has exactly the body's pose: the
    /// body rotation is already unit, so it is not normalized again.
    #[inline]
    pub fn world_pose(&self, body_origin: &Transform) -> Transform {
        if self.local_pose == Transform::IDENTITY {
            return *body_origin;
        }
        body_origin.mul_transform(&self.local_pose)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::BodyDesc;
    use crate::shape::ShapeError;
    use crate::world::{World, WorldConfig, WorldError};
    use crate::{Vec3, scalar};

    #[test]
    fn the_shortcuts_make_the_shapes_their_constructors_make() {
        let (r, h) = (scalar!(0.25), scalar!(0.75));
        assert_eq!(
            ColliderDesc::sphere(r).shape,
            Shape::Sphere(Sphere::new(r).unwrap())
        );
        assert_eq!(
            ColliderDesc::capsule(h, r).shape,
            Shape::Capsule(Capsule::new(h, r).unwrap())
        );
        assert_eq!(
            ColliderDesc::cuboid(r, h, Scalar::ONE).shape,
            Shape::Cuboid(Cuboid::new(Vec3::new(r, h, Scalar::ONE)).unwrap())
        );
        assert_eq!(
            ColliderDesc::sphere(r),
            ColliderDesc::new(Shape::Sphere(Sphere { radius: r }))
        );
    }

    #[test]
    fn bad_dimensions_are_refused_on_every_kind_of_body() {
        let mut world = World::new(WorldConfig::default()).unwrap();
        let bodies = [
            BodyDesc::fixed(),
            BodyDesc::kinematic(),
            BodyDesc::dynamic(),
        ]
        .map(|d| world.create_body(&d).unwrap());
        let bad = [
            ColliderDesc::sphere(Scalar::ZERO),
            ColliderDesc::sphere(-Scalar::ONE),
            ColliderDesc::capsule(-Scalar::DELTA, Scalar::ONE),
            ColliderDesc::capsule(Scalar::ONE, Scalar::ZERO),
            ColliderDesc::cuboid(Scalar::ONE, Scalar::ZERO, Scalar::ONE),
        ];
        for body in bodies {
            for desc in &bad {
                let err = world.add_collider(body, desc.clone()).unwrap_err();
                assert_eq!(err, WorldError::Shape(desc.shape.validate().unwrap_err()));
            }
            assert!(world.body(body).unwrap().colliders().is_empty());
            // A zero half-height is a sphere: allowed.
            world
                .add_collider(body, ColliderDesc::capsule(Scalar::ZERO, Scalar::ONE))
                .unwrap();
        }
        assert!(matches!(
            ColliderDesc::sphere(Scalar::ZERO).shape.validate(),
            Err(ShapeError::SphereRadius { .. })
        ));
    }
}
