//! Joints: constraints between two bodies, solved with the contacts in the
//! soft step (see `solver/joint_solver.rs`).
//!
//! A joint holds a frame on each body (a pose in the body's frame, like a
//! collider's local pose). The joint's *axis* is the x axis of those frames:
//! the hinge of a revolute joint, the slide of a prismatic joint, the twist
//! axis of a spherical joint's cone and twist limits. Angles are measured
//! from B's frame relative to A's, about A's x axis, right-handed.
//!
//! | kind | keeps | optional |
//! |---|---|---|
//! | [`JointKind::Spherical`] | the two anchors together | a swing cone and twist limits |
//! | [`JointKind::Revolute`] | anchors together, x axes aligned | angle limits, a motor |
//! | [`JointKind::Prismatic`] | frames aligned, B's anchor on A's x axis | position limits, a motor |
//! | [`JointKind::Fixed`] | the two frames together | |
//! | [`JointKind::Distance`] | the anchors' distance | a spring, min and max (a rope) |

use serde::{Deserialize, Serialize};

use crate::arena::RawHandle;
use crate::body::BodyHandle;
use crate::math::{Scalar, Transform, Vec3};

/// A generational handle to a joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct JointHandle(pub RawHandle);

impl JointHandle {
    /// The slot index (handle order is index order).
    pub fn index(self) -> u32 {
        self.0.index
    }

    /// The slot's generation.
    pub fn generation(self) -> u32 {
        self.0.generation
    }
}

/// The `max` of a distance joint with no longest length (a spring without
/// limits): 2²⁰ m, far beyond any scene and beyond the distance at which the
/// solver treats a limit as idle.
pub const UNBOUNDED_LENGTH: Scalar = Scalar::from_int(1 << 20);

/// A motor on a revolute or prismatic joint's axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Motor {
    /// Drives the relative speed (rad/s or m/s) to `speed`.
    Speed {
        /// Target speed of B relative to A about or along the axis.
        speed: Scalar,
        /// The largest torque (N·m) or force (N) it may apply.
        max_force: Scalar,
    },
    /// Drives the angle (rad) or position (m) to `target`, as a stiff
    /// spring at the joint softness.
    Position {
        /// Target angle or position of B relative to A.
        target: Scalar,
        /// The largest torque (N·m) or force (N) it may apply.
        max_force: Scalar,
    },
}

impl Motor {
    /// The largest torque or force.
    pub fn max_force(&self) -> Scalar {
        match *self {
            Motor::Speed { max_force, .. } | Motor::Position { max_force, .. } => max_force,
        }
    }
}

/// A spring: a soft constraint with its own stiffness and damping.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Spring {
    /// Natural frequency, Hz (0: no spring force at all).
    pub hertz: Scalar,
    /// Damping ratio (1: critical).
    pub damping_ratio: Scalar,
}

/// What a joint constrains (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum JointKind {
    /// A ball joint.
    Spherical {
        /// The largest angle between the two x axes (swing), rad.
        cone: Option<Scalar>,
        /// Twist limits about the x axis, rad (lower ≤ upper).
        twist: Option<(Scalar, Scalar)>,
    },
    /// A hinge about the x axis.
    Revolute {
        /// Angle limits, rad (lower ≤ upper).
        limits: Option<(Scalar, Scalar)>,
        /// A motor about the hinge.
        motor: Option<Motor>,
    },
    /// A slider along the x axis.
    Prismatic {
        /// Position limits, m (lower ≤ upper).
        limits: Option<(Scalar, Scalar)>,
        /// A motor along the slide.
        motor: Option<Motor>,
    },
    /// A weld.
    Fixed,
    /// The distance between the two anchors.
    Distance {
        /// The rest length, m.
        length: Scalar,
        /// The shortest allowed length, m.
        min: Scalar,
        /// The longest allowed length, m.
        max: Scalar,
        /// `None`: held rigidly at `length`; a spring pulls towards
        /// `length` (a spring of 0 Hz pulls not at all: a rope when `min`
        /// is 0).
        spring: Option<Spring>,
    },
}

impl JointKind {
    /// A stable lowercase name.
    pub fn name(&self) -> &'static str {
        match self {
            JointKind::Spherical { .. } => "spherical",
            JointKind::Revolute { .. } => "revolute",
            JointKind::Prismatic { .. } => "prismatic",
            JointKind::Fixed => "fixed",
            JointKind::Distance { .. } => "distance",
        }
    }

    /// A stable code for hashing.
    pub(crate) fn code(&self) -> u64 {
        match self {
            JointKind::Spherical { .. } => 1,
            JointKind::Revolute { .. } => 2,
            JointKind::Prismatic { .. } => 3,
            JointKind::Fixed => 4,
            JointKind::Distance { .. } => 5,
        }
    }
}

/// How to build a joint.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct JointDesc {
    /// What it constrains.
    pub kind: JointKind,
    /// The first body.
    pub body_a: BodyHandle,
    /// The second body.
    pub body_b: BodyHandle,
    /// The joint frame in A's body frame.
    pub frame_a: Transform,
    /// The joint frame in B's body frame.
    pub frame_b: Transform,
    /// Whether the two bodies still collide with each other (default: no).
    pub collide_connected: bool,
    /// The force (N) at which the joint breaks, if any: compared with the
    /// joint's constraint force (linear part) at the end of each step.
    pub break_force: Option<Scalar>,
    /// The torque (N·m) at which the joint breaks, if any (angular part).
    pub break_torque: Option<Scalar>,
    /// Whether the angle limits (a revolute joint's; a spherical joint's
    /// cone and twist) hold rigidly instead of giving like the joints' soft
    /// spring (default: soft). A rigid limit stops the joint at the limit
    /// and holds it there under a steady load (a door, a lever, a
    /// machine's end stop); soft limits let a pile of ragdolls settle and
    /// sleep (see docs/joints.md). Prismatic and distance limits are soft
    /// either way.
    #[serde(default)]
    pub rigid_limits: bool,
    /// Joint friction (spherical and revolute joints): the largest torque
    /// (N·m) that resists the bodies' rotation relative to each other about
    /// each axis the joint leaves free (a revolute joint's hinge; each of a
    /// spherical joint's three frame axes), like a motor holding speed 0
    /// with that much torque. Zero (the default): none. A ragdoll's knee or
    /// neck with a little friction comes to rest where one without swings
    /// on (see docs/joints.md).
    #[serde(default)]
    pub friction: Scalar,
    /// A name for tools and scene files.
    pub name: String,
}

impl JointDesc {
    /// A joint of `kind` between `a` and `b` with both frames at the body
    /// origins; set the frames with [`frames`](Self::frames) or
    /// [`anchors`](Self::anchors).
    pub fn new(kind: JointKind, a: BodyHandle, b: BodyHandle) -> JointDesc {
        JointDesc {
            kind,
            body_a: a,
            body_b: b,
            frame_a: Transform::IDENTITY,
            frame_b: Transform::IDENTITY,
            collide_connected: false,
            break_force: None,
            break_torque: None,
            rigid_limits: false,
            friction: Scalar::ZERO,
            name: String::new(),
        }
    }

    /// A ball joint, free.
    pub fn spherical(a: BodyHandle, b: BodyHandle) -> JointDesc {
        JointDesc::new(
            JointKind::Spherical {
                cone: None,
                twist: None,
            },
            a,
            b,
        )
    }

    /// A free hinge.
    pub fn revolute(a: BodyHandle, b: BodyHandle) -> JointDesc {
        JointDesc::new(
            JointKind::Revolute {
                limits: None,
                motor: None,
            },
            a,
            b,
        )
    }

    /// A free slider.
    pub fn prismatic(a: BodyHandle, b: BodyHandle) -> JointDesc {
        JointDesc::new(
            JointKind::Prismatic {
                limits: None,
                motor: None,
            },
            a,
            b,
        )
    }

    /// A weld.
    pub fn fixed(a: BodyHandle, b: BodyHandle) -> JointDesc {
        JointDesc::new(JointKind::Fixed, a, b)
    }

    /// A rigid rod of `length` between the anchors.
    pub fn distance(a: BodyHandle, b: BodyHandle, length: Scalar) -> JointDesc {
        JointDesc::new(
            JointKind::Distance {
                length,
                min: length,
                max: length,
                spring: None,
            },
            a,
            b,
        )
    }

    /// A rope: the anchors at most `max` apart, free closer.
    pub fn rope(a: BodyHandle, b: BodyHandle, max: Scalar) -> JointDesc {
        JointDesc::new(
            JointKind::Distance {
                length: max,
                min: Scalar::ZERO,
                max,
                spring: Some(Spring {
                    hertz: Scalar::ZERO,
                    damping_ratio: Scalar::ZERO,
                }),
            },
            a,
            b,
        )
    }

    /// A spring of rest `length` (no limits: `min` 0, `max`
    /// [`UNBOUNDED_LENGTH`]).
    pub fn spring(a: BodyHandle, b: BodyHandle, length: Scalar, spring: Spring) -> JointDesc {
        JointDesc::new(
            JointKind::Distance {
                length,
                min: Scalar::ZERO,
                max: UNBOUNDED_LENGTH,
                spring: Some(spring),
            },
            a,
            b,
        )
    }

    /// Sets both frames.
    pub fn frames(mut self, frame_a: Transform, frame_b: Transform) -> JointDesc {
        self.frame_a = frame_a;
        self.frame_b = frame_b;
        self
    }

    /// Sets the frames' origins (the anchors), keeping their rotations.
    pub fn anchors(mut self, anchor_a: Vec3, anchor_b: Vec3) -> JointDesc {
        self.frame_a.translation = anchor_a;
        self.frame_b.translation = anchor_b;
        self
    }

    /// Lets the two bodies collide with each other.
    pub fn collide_connected(mut self, yes: bool) -> JointDesc {
        self.collide_connected = yes;
        self
    }

    /// Breaks the joint above this force (N) or torque (N·m).
    pub fn breakable(mut self, force: Option<Scalar>, torque: Option<Scalar>) -> JointDesc {
        self.break_force = force;
        self.break_torque = torque;
        self
    }

    /// Makes the angle limits rigid (see [`JointDesc::rigid_limits`]).
    pub fn rigid_limits(mut self, yes: bool) -> JointDesc {
        self.rigid_limits = yes;
        self
    }

    /// Sets the joint friction, N·m (see [`JointDesc::friction`]).
    pub fn friction(mut self, torque: Scalar) -> JointDesc {
        self.friction = torque;
        self
    }

    /// Sets the name.
    pub fn name(mut self, name: impl Into<String>) -> JointDesc {
        self.name = name.into();
        self
    }
}

/// A joint's accumulated impulses (per substep), kept for warm starting
/// across ticks: part of the state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct JointImpulses {
    /// The anchor constraint (world axes); for a prismatic joint, the two
    /// rows across the slide in `x` and `y`; for a distance joint, the rod
    /// in `x`.
    pub linear: Vec3,
    /// The rotation lock (world axes); for a revolute joint, its two rows
    /// in `x` and `y` and its friction in `z`; for a spherical joint, its
    /// friction about A's joint frame axes.
    pub angular: Vec3,
    /// Lower limit (or cone), upper limit (or twist lower), motor (or twist
    /// upper), spring.
    pub axial: [Scalar; 4],
}

/// A joint as stored in the world.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Joint {
    /// How it was built (the kind may be changed later, e.g. the motor).
    pub desc: JointDesc,
    /// Accumulated impulses, for warm starting.
    pub impulses: JointImpulses,
}

/// What happened to a joint during a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointEvent {
    /// The joint's force or torque passed its threshold: it was removed.
    Broken {
        /// The handle it had.
        joint: JointHandle,
        /// Its first body.
        body_a: BodyHandle,
        /// Its second body.
        body_b: BodyHandle,
        /// The constraint force (N) and torque (N·m) it carried.
        force: Scalar,
        /// See `force`.
        torque: Scalar,
    },
}
