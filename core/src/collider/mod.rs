//! Colliders: a shape attached to a body at a local pose, with a material,
//! collision filter and trigger flag. A body may carry several (a compound);
//! its mass properties combine theirs.

mod filter;
mod material;

pub use filter::CollisionFilter;
pub use material::Material;

use serde::{Deserialize, Serialize};

use crate::arena::RawHandle;
use crate::body::BodyHandle;
use crate::collision::ProxyId;
use crate::math::{Scalar, Transform};
use crate::shape::{MassProperties, Shape};

/// Identifies a collider: `{index, generation}`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct ColliderHandle(pub RawHandle);

impl ColliderHandle {
    /// The slot index.
    pub fn index(self) -> u32 {
        self.0.index
    }
}

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
    /// default material and filter.
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
