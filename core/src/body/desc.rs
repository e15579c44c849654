//! `BodyDesc`: everything needed to create a body.

use crate::math::{Quat, Scalar, Vec3};

use super::state::BodyKind;

/// A description of a body to create with
/// [`World::create_body`](crate::World::create_body). Shapes are added
/// afterwards with [`World::add_collider`](crate::World::add_collider); the
/// mass comes from their densities unless set here.
///
/// Start from [`fixed`](BodyDesc::fixed), [`dynamic`](BodyDesc::dynamic) or
/// [`kinematic`](BodyDesc::kinematic) and set what differs from the
/// defaults (at rest at the origin, no damping, full gravity):
///
/// ```
/// use lockstep_core::{BodyDesc, BodyKind, ColliderDesc, Vec3, World, WorldConfig, scalar};
///
/// let mut world = World::new(WorldConfig::default())?;
/// let desc = BodyDesc::dynamic()
///     .name("ball")
///     .position(Vec3::new(scalar!(1), scalar!(5), scalar!(0)))
///     .linear_velocity(Vec3::new(scalar!(2.5), scalar!(0), scalar!(0)))
///     .damping(scalar!(0.1), scalar!(0.1));
/// let ball = world.create_body(&desc)?;
/// world.add_collider(ball, ColliderDesc::sphere(scalar!(0.25)))?;
///
/// let body = world.body(ball)?;
/// assert_eq!(body.kind(), BodyKind::Dynamic);
/// assert_eq!(body.position(), desc.position);
/// assert_eq!(body.linear_velocity().x, scalar!(2.5));
/// assert_eq!(world.find_body("ball"), Some(ball));
/// # Ok::<(), lockstep_core::WorldError>(())
/// ```
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BodyDesc {
    /// How the body moves.
    pub kind: BodyKind,
    /// A name for the game, dumps and desync reports.
    pub name: String,
    /// World position of the body origin.
    pub position: Vec3,
    /// Orientation (normalised on creation).
    pub rotation: Quat,
    /// Initial linear velocity of the centre of mass, m/s.
    pub linear_velocity: Vec3,
    /// Initial angular velocity, world axes, rad/s.
    pub angular_velocity: Vec3,
    /// Linear damping rate, 1/s (≥ 0).
    pub linear_damping: Scalar,
    /// Angular damping rate, 1/s (≥ 0).
    pub angular_damping: Scalar,
    /// Multiplier on gravity.
    pub gravity_scale: Scalar,
    /// Whether the body starts asleep.
    pub asleep: bool,
    /// Whether the body is a bullet: continuous collision checks its every
    /// move, against dynamic bodies too (see [`BodyDesc::bullet`]).
    pub bullet: bool,
    /// An opaque value for the game.
    pub user_data: u64,
}

impl BodyDesc {
    fn with_kind(kind: BodyKind) -> BodyDesc {
        BodyDesc {
            kind,
            name: String::new(),
            position: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            linear_velocity: Vec3::ZERO,
            angular_velocity: Vec3::ZERO,
            linear_damping: Scalar::ZERO,
            angular_damping: Scalar::ZERO,
            gravity_scale: Scalar::ONE,
            asleep: false,
            bullet: false,
            user_data: 0,
        }
    }

    /// A static body at the origin.
    pub fn fixed() -> BodyDesc {
        BodyDesc::with_kind(BodyKind::Static)
    }

    /// A dynamic body at the origin.
    pub fn dynamic() -> BodyDesc {
        BodyDesc::with_kind(BodyKind::Dynamic)
    }

    /// A kinematic body at the origin.
    pub fn kinematic() -> BodyDesc {
        BodyDesc::with_kind(BodyKind::Kinematic)
    }

    /// Sets the name.
    pub fn name(mut self, name: impl Into<String>) -> BodyDesc {
        self.name = name.into();
        self
    }

    /// Sets the position of the body origin.
    pub fn position(mut self, p: Vec3) -> BodyDesc {
        self.position = p;
        self
    }

    /// Sets the orientation.
    pub fn rotation(mut self, q: Quat) -> BodyDesc {
        self.rotation = q;
        self
    }

    /// Sets the initial linear velocity.
    pub fn linear_velocity(mut self, v: Vec3) -> BodyDesc {
        self.linear_velocity = v;
        self
    }

    /// Sets the initial angular velocity (world axes).
    pub fn angular_velocity(mut self, w: Vec3) -> BodyDesc {
        self.angular_velocity = w;
        self
    }

    /// Sets linear and angular damping rates.
    pub fn damping(mut self, linear: Scalar, angular: Scalar) -> BodyDesc {
        self.linear_damping = linear;
        self.angular_damping = angular;
        self
    }

    /// Sets the gravity multiplier.
    pub fn gravity_scale(mut self, s: Scalar) -> BodyDesc {
        self.gravity_scale = s;
        self
    }

    /// Starts the body asleep.
    pub fn asleep(mut self, asleep: bool) -> BodyDesc {
        self.asleep = asleep;
        self
    }

    /// Marks the body as a bullet (dynamic bodies only; ignored otherwise).
    ///
    /// Why: any fast dynamic body is already swept against static shapes
    /// when it moves more than a quarter of its smallest extent in a tick;
    /// a bullet is swept every tick, also against dynamic and kinematic
    /// bodies (at their end-of-tick poses), so a small fast projectile
    /// cannot pass through a thin moving target. It costs a sweep per tick.
    pub fn bullet(mut self, bullet: bool) -> BodyDesc {
        self.bullet = bullet;
        self
    }

    /// Sets the opaque game value.
    pub fn user_data(mut self, v: u64) -> BodyDesc {
        self.user_data = v;
        self
    }
}
