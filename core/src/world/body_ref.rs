//! `BodyRef`: a read-only view of one body.

use crate::body::{BodyCold, BodyHandle, BodyHot, BodyKind};
use crate::collider::ColliderHandle;
use crate::math::{Quat, Scalar, SymMat3, Transform, Vec3};

/// A read-only view of one body's state, from [`World::body`](super::state::World::body).
#[derive(Clone, Copy, Debug)]
pub struct BodyRef<'a> {
    handle: BodyHandle,
    hot: &'a BodyHot,
    cold: &'a BodyCold,
}

impl<'a> BodyRef<'a> {
    pub(crate) fn new(handle: BodyHandle, hot: &'a BodyHot, cold: &'a BodyCold) -> BodyRef<'a> {
        BodyRef { handle, hot, cold }
    }

    /// The body's handle.
    pub fn handle(&self) -> BodyHandle {
        self.handle
    }

    /// The name given at creation.
    pub fn name(&self) -> &'a str {
        &self.cold.name
    }

    /// How the body moves.
    pub fn kind(&self) -> BodyKind {
        self.hot.kind
    }

    /// The kinematic target set for the coming step
    /// ([`World::set_kinematic_target`](super::state::World::set_kinematic_target)),
    /// if any: where a kinematic body will be after it.
    pub fn kinematic_target(&self) -> Option<Transform> {
        self.cold.kinematic_target
    }

    /// Pose of the body origin.
    pub fn pose(&self) -> Transform {
        self.hot.origin_pose(self.cold.local_center)
    }

    /// World position of the body origin.
    pub fn position(&self) -> Vec3 {
        self.pose().translation
    }

    /// Orientation.
    pub fn rotation(&self) -> Quat {
        self.hot.rotation
    }

    /// World position of the centre of mass.
    pub fn center_of_mass(&self) -> Vec3 {
        self.hot.center
    }

    /// Linear velocity of the centre of mass.
    pub fn linear_velocity(&self) -> Vec3 {
        self.hot.linear_velocity
    }

    /// Angular velocity, world axes.
    pub fn angular_velocity(&self) -> Vec3 {
        self.hot.angular_velocity
    }

    /// Angular momentum about the centre of mass, world axes (zero unless
    /// dynamic).
    pub fn angular_momentum(&self) -> Vec3 {
        self.hot.angular_momentum
    }

    /// Mass, kg (zero unless dynamic).
    pub fn mass(&self) -> Scalar {
        self.cold.mass
    }

    /// Centre of mass in body coordinates.
    pub fn local_center(&self) -> Vec3 {
        self.cold.local_center
    }

    /// Inertia tensor about the centre of mass, body axes.
    pub fn inertia(&self) -> SymMat3 {
        self.hot.inertia
    }

    /// Kinetic energy `½ m v² + ½ L·ω`, J.
    pub fn kinetic_energy(&self) -> Scalar {
        let lin = self.hot.linear_velocity.dot(self.hot.linear_velocity) * self.cold.mass;
        let ang = self.hot.angular_momentum.dot(self.hot.angular_velocity);
        (lin + ang).half()
    }

    /// Whether the body sleeps.
    pub fn is_sleeping(&self) -> bool {
        self.hot.sleeping
    }

    /// The body's colliders in the order they were added.
    pub fn colliders(&self) -> &'a [ColliderHandle] {
        &self.cold.colliders
    }

    /// The opaque game value.
    pub fn user_data(&self) -> u64 {
        self.cold.user_data
    }

    /// The full hot state (for tools such as state dumps).
    pub fn hot(&self) -> &'a BodyHot {
        self.hot
    }
}
