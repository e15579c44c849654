//! Body state, split into what the integrator and solver touch every
//! substep (hot) and what they do not (cold).

use serde::{Deserialize, Serialize};

use crate::handles::ColliderHandle;
use crate::math::{Quat, Scalar, SymMat3, Transform, Vec3};

/// How a body moves.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum BodyKind {
    /// Never moves; infinite mass.
    #[default]
    Static,
    /// Moved by gravity, forces, impulses and contacts.
    Dynamic,
    /// Moved only by its velocity or a target pose set by the game each
    /// tick; infinite mass to everything else.
    Kinematic,
}

impl BodyKind {
    /// A stable lowercase name: "static", "dynamic", "kinematic".
    pub fn name(self) -> &'static str {
        match self {
            BodyKind::Static => "static",
            BodyKind::Dynamic => "dynamic",
            BodyKind::Kinematic => "kinematic",
        }
    }

    /// A stable code for hashing.
    pub(crate) fn code(self) -> u64 {
        match self {
            BodyKind::Static => 0,
            BodyKind::Dynamic => 1,
            BodyKind::Kinematic => 2,
        }
    }
}

/// The state the integrator reads and writes every substep. Kept compact
/// and apart from names and bookkeeping (about 360 bytes).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BodyHot {
    /// How the body moves.
    pub kind: BodyKind,
    /// Whether the body is asleep (skipped by the integrator).
    pub sleeping: bool,
    /// Whether the inertia is a multiple of the identity, so the gyroscopic
    /// term vanishes and is skipped (spheres, cubes).
    pub isotropic: bool,
    /// Whether the body is a bullet: continuous collision sweeps it every
    /// tick, against dynamic and kinematic bodies too (dynamic bodies only).
    pub bullet: bool,
    /// World position of the centre of mass.
    pub center: Vec3,
    /// Orientation (unit quaternion), body axes to world axes.
    pub rotation: Quat,
    /// Velocity of the centre of mass, m/s.
    pub linear_velocity: Vec3,
    /// Angular velocity in world axes, rad/s. For dynamic bodies it is
    /// derived from `angular_momentum` (during a substep it holds the
    /// substep's midpoint value); for kinematic bodies it is the state.
    pub angular_velocity: Vec3,
    /// Angular momentum about the centre of mass, world axes (dynamic bodies
    /// only): the rotational state, so torque-free bodies conserve it
    /// exactly.
    pub angular_momentum: Vec3,
    /// Force accumulated since the last step, applied over the next step.
    pub force: Vec3,
    /// Torque accumulated since the last step, applied over the next step.
    pub torque: Vec3,
    /// 1/mass (0 for static and kinematic bodies).
    pub inv_mass: Scalar,
    /// Inertia tensor about the centre of mass, in body axes.
    pub inertia: SymMat3,
    /// Its inverse (zero for static and kinematic bodies).
    pub inv_inertia: SymMat3,
    /// Linear damping rate, 1/s: `v ← v / (1 + h·c)` each substep.
    pub linear_damping: Scalar,
    /// Angular damping rate, 1/s.
    pub angular_damping: Scalar,
    /// Multiplier on the world's gravity for this body.
    pub gravity_scale: Scalar,
    /// Consecutive ticks spent below the sleep thresholds (counted in whole
    /// ticks, so the time to sleep is exact).
    pub rest_ticks: u32,
    /// The smallest extent of the body's solid colliders, m (a sphere's or
    /// capsule's radius, a box's smallest half-extent, a hull's smallest
    /// distance from its vertex centroid to a face); zero for a body with
    /// no solid collider. Derived from the colliders whenever they or the
    /// mass change: continuous collision sweeps a body that moves more than
    /// a quarter of it in one tick.
    pub ccd_extent: Scalar,
    /// The largest distance from the centre of mass to any point of the
    /// body's solid colliders, m (derived like `ccd_extent`): bounds how far
    /// a rotation moves the surface.
    pub ccd_radius: Scalar,
}

/// Body data the step does not touch every substep.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BodyCold {
    /// The game's name for the body (scene files name every body).
    pub name: String,
    /// Centre of mass in body-local coordinates.
    pub local_center: Vec3,
    /// Mass, kg (0 for static and kinematic bodies).
    pub mass: Scalar,
    /// Whether the mass was set explicitly (colliders then do not change it).
    pub mass_override: bool,
    /// The body's colliders, in the order they were added.
    pub colliders: Vec<ColliderHandle>,
    /// A pose a kinematic body must reach at the end of the next step.
    pub kinematic_target: Option<Transform>,
    /// An opaque value for the game.
    pub user_data: u64,
}

impl BodyHot {
    /// The pose of the body origin (what colliders are attached to), derived
    /// from the centre of mass and the rotation. A centre of mass at the
    /// origin (a single centred shape, the common case) skips the rotation:
    /// it would rotate the zero vector.
    #[inline]
    pub fn origin_pose(&self, local_center: Vec3) -> Transform {
        if local_center.is_zero() {
            return Transform::new(self.center, self.rotation);
        }
        Transform::new(
            self.center - self.rotation.rotate(local_center),
            self.rotation,
        )
    }

    /// Whether the integrator moves this body this step.
    #[inline]
    pub fn is_moving(&self) -> bool {
        self.kind != BodyKind::Static && !self.sleeping
    }
}
