//! One scene description, built in each engine of the `accuracy` suite.
//!
//! A [`Spec`] lists bodies in plain `f64`; [`build`] turns it into a running
//! simulation of lockstep-core, Rapier f32 or Rapier f64 at given
//! [`Settings`], and the [`Sim`] trait reads the state back in `f64`, so a
//! case measures every engine with the same code. Inputs are rounded to
//! Q32.32 first (as the `engines` suite does), so all engines start from
//! the same numbers.

use std::sync::Arc;

use lockstep_core::SleepConfig;
use lockstep_core::joint::{JointDesc, JointKind, Motor};
use lockstep_core::shape::{Capsule, ConvexHull, Cuboid, Shape, Sphere};
use lockstep_core::{
    BodyDesc, BodyHandle, ColliderDesc, ContactRows, Material, Quat, Scalar, Transform, Vec3,
    World, WorldConfig,
};

/// The engines compared, in the order they are run and listed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Engine {
    /// lockstep-core, Q32.32.
    Ours,
    /// rapier3d 0.36.1, f32.
    RapierF32,
    /// rapier3d-f64 0.36.1.
    RapierF64,
}

impl Engine {
    /// Every engine.
    pub const ALL: [Engine; 3] = [Engine::Ours, Engine::RapierF32, Engine::RapierF64];

    /// The name used in tables, CSV and legends.
    pub fn name(self) -> &'static str {
        match self {
            Engine::Ours => "ours",
            Engine::RapierF32 => "rapier-f32",
            Engine::RapierF64 => "rapier-f64",
        }
    }
}

/// The contact rows every [`Ours`] world of this process uses (`--rows`;
/// 0: the world's default, 1: Q32.32, 2: narrow). One setting per
/// process: the suites compare engines within a run, and a run of the
/// other format is a second run.
static ROWS: std::sync::atomic::AtomicU8 = std::sync::atomic::AtomicU8::new(0);

/// Sets the contact rows of every [`Ours`] world built after it.
pub fn set_rows(rows: ContactRows) {
    let code = match rows {
        ContactRows::Exact => 1,
        ContactRows::Narrow => 2,
    };
    ROWS.store(code, std::sync::atomic::Ordering::Relaxed);
}

/// The contact rows [`Ours`] worlds are built with.
pub fn rows() -> ContactRows {
    match ROWS.load(std::sync::atomic::Ordering::Relaxed) {
        1 => ContactRows::Exact,
        2 => ContactRows::Narrow,
        _ => WorldConfig::default().contact_rows,
    }
}

/// The step settings swept, the same meaning for every engine (see
/// [`rapier_parameters`] for Rapier's side of the mapping).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Settings {
    /// Steps per simulated second.
    pub tick_rate: u32,
    /// Substeps per step.
    pub substeps: u32,
    /// Contact solve passes per substep.
    pub iterations: u32,
}

/// A collision shape, centred on its body's origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShapeSpec {
    /// A sphere of this radius, m.
    Sphere(f64),
    /// A box of these half-extents, m.
    Cuboid([f64; 3]),
    /// A capsule along local y: half the core segment's length and the
    /// radius, m.
    Capsule(f64, f64),
    /// A regular octahedron (the convex hull of the six points at this
    /// distance on the axes), m: the hull shape both engines have.
    Octahedron(f64),
}

impl ShapeSpec {
    /// The octahedron's six vertices.
    pub fn octahedron_points(r: f64) -> [[f64; 3]; 6] {
        [
            [r, 0.0, 0.0],
            [-r, 0.0, 0.0],
            [0.0, r, 0.0],
            [0.0, -r, 0.0],
            [0.0, 0.0, r],
            [0.0, 0.0, -r],
        ]
    }
}

/// One body of a scene with its single collider.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodySpec {
    /// Static (never moves) or dynamic.
    pub fixed: bool,
    /// The collider.
    pub shape: ShapeSpec,
    /// Position of the centre, m.
    pub pos: [f64; 3],
    /// Orientation as a unit quaternion `[x, y, z, w]`.
    pub rot: [f64; 4],
    /// Initial linear velocity, m/s.
    pub vel: [f64; 3],
    /// Initial angular velocity (world axes), rad/s.
    pub omega: [f64; 3],
    /// Density, kg/m³.
    pub density: f64,
    /// Friction coefficient (every body of a scene uses the same, so each
    /// engine's combine rule gives this value).
    pub friction: f64,
    /// Restitution (same remark).
    pub restitution: f64,
    /// A force applied at the centre in every step, N.
    pub force: [f64; 3],
    /// A torque applied in every step (world axes), N·m.
    pub torque: [f64; 3],
}

impl BodySpec {
    /// A dynamic body at rest, density 1000, no friction or restitution.
    pub fn dynamic(shape: ShapeSpec, pos: [f64; 3]) -> BodySpec {
        BodySpec {
            fixed: false,
            shape,
            pos,
            rot: [0.0, 0.0, 0.0, 1.0],
            vel: [0.0; 3],
            omega: [0.0; 3],
            density: 1000.0,
            friction: 0.0,
            restitution: 0.0,
            force: [0.0; 3],
            torque: [0.0; 3],
        }
    }

    /// A static body.
    pub fn fixed(shape: ShapeSpec, pos: [f64; 3]) -> BodySpec {
        BodySpec {
            fixed: true,
            ..BodySpec::dynamic(shape, pos)
        }
    }

    /// With this friction and restitution.
    pub fn material(mut self, friction: f64, restitution: f64) -> BodySpec {
        self.friction = friction;
        self.restitution = restitution;
        self
    }

    /// With this initial linear velocity.
    pub fn vel(mut self, v: [f64; 3]) -> BodySpec {
        self.vel = v;
        self
    }

    /// With this initial angular velocity.
    pub fn omega(mut self, w: [f64; 3]) -> BodySpec {
        self.omega = w;
        self
    }

    /// With this density.
    pub fn density(mut self, d: f64) -> BodySpec {
        self.density = d;
        self
    }

    /// With this orientation.
    pub fn rot(mut self, q: [f64; 4]) -> BodySpec {
        self.rot = q;
        self
    }

    /// With this constant force.
    pub fn force(mut self, f: [f64; 3]) -> BodySpec {
        self.force = f;
        self
    }

    /// With this constant torque.
    pub fn torque(mut self, t: [f64; 3]) -> BodySpec {
        self.torque = t;
        self
    }

    /// The mass from the closed-form volume (no engine involved), kg.
    pub fn mass(&self) -> f64 {
        self.density * crate::accuracy::closed::volume(self.shape)
    }
}

/// What a joint of a scene holds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JointSpecKind {
    /// A ball joint: the anchors meet, the bodies turn freely about them.
    Ball,
    /// A hinge about the joint's axis, with optional angle limits (rad) and
    /// an optional speed motor (target rad/s, largest torque N·m).
    Hinge {
        /// Lowest and highest angle, rad.
        limits: Option<[f64; 2]>,
        /// Target speed, rad/s, and the largest torque, N·m.
        motor: Option<[f64; 2]>,
        /// Whether ours holds the limits rigidly (`JointDesc::rigid_limits`,
        /// the setting for a door or an end stop; off, they give like a
        /// spring, the setting for ragdolls). Rapier's limits are always
        /// rigid.
        rigid_limits: bool,
    },
}

/// A joint between two bodies of a scene (indices into its `bodies`).
/// Collisions between the two bodies are off, in both engines.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointSpec {
    /// The first body (often the static one).
    pub a: usize,
    /// The second body.
    pub b: usize,
    /// The anchor in each body's own axes, m (the bodies' centres of mass
    /// are their origins: every shape here is centred).
    pub anchors: [[f64; 3]; 2],
    /// The hinge axis (unit), in each body's own axes: the cases start
    /// hinged bodies unrotated, so one axis serves both.
    pub axis: [f64; 3],
    /// What it holds.
    pub kind: JointSpecKind,
}

impl JointSpec {
    /// The joint frames' rotation: the one that takes x onto the axis
    /// (both engines' hinges turn about their frame's x axis).
    pub fn frame_rotation(&self) -> [f64; 4] {
        let a = self.axis;
        let n = crate::accuracy::closed::norm(a);
        let a = [a[0] / n, a[1] / n, a[2] / n];
        if a[0] < -1.0 + 1e-12 {
            return [0.0, 1.0, 0.0, 0.0];
        }
        // Half-way quaternion: (x × a, 1 + x·a), normalised.
        let q = [0.0, -a[2], a[1], 1.0 + a[0]];
        let len = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        q.map(|c| c / len)
    }
}

/// A scene: gravity and bodies (indices into `bodies` name them).
#[derive(Clone, Debug, PartialEq)]
pub struct Spec {
    /// Gravitational acceleration, m/s².
    pub gravity: [f64; 3],
    /// The bodies, static and dynamic.
    pub bodies: Vec<BodySpec>,
    /// Joints between them.
    pub joints: Vec<JointSpec>,
    /// Dynamic bodies that get continuous collision in Rapier (ours sweeps
    /// every fast body by itself).
    pub ccd: Vec<usize>,
    /// A dynamic body faster than this, m/s, has exploded.
    pub explode_speed: f64,
    /// Whether bodies may fall asleep (each engine's own default rule);
    /// off unless a case asks.
    pub sleep: bool,
}

impl Spec {
    /// A scene with this gravity and bodies, no CCD requests, exploding
    /// above 100 m/s.
    pub fn new(gravity: [f64; 3], bodies: Vec<BodySpec>) -> Spec {
        Spec {
            gravity,
            bodies,
            joints: Vec::new(),
            ccd: Vec::new(),
            explode_speed: 100.0,
            sleep: false,
        }
    }
}

/// A body's state read back from an engine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct State {
    /// Centre, m.
    pub pos: [f64; 3],
    /// Orientation `[x, y, z, w]`.
    pub rot: [f64; 4],
    /// Linear velocity, m/s.
    pub vel: [f64; 3],
    /// Angular velocity, world axes, rad/s.
    pub omega: [f64; 3],
}

impl State {
    /// Whether every component is finite.
    pub fn is_finite(&self) -> bool {
        self.pos
            .iter()
            .chain(&self.rot)
            .chain(&self.vel)
            .chain(&self.omega)
            .all(|x| x.is_finite())
    }
}

/// A running simulation of one engine.
pub trait Sim {
    /// Advances one step (applying the scene's constant forces).
    fn step(&mut self);
    /// The state of body `i` of the spec.
    fn state(&self, i: usize) -> State;
    /// Sets body `i`'s linear velocity (a launch after settling).
    fn set_linvel(&mut self, i: usize, v: [f64; 3]);
    /// Whether the engine reported an arithmetic fault (ours only).
    fn faulted(&self) -> bool;
    /// Whether body `i` is asleep.
    fn sleeping(&self, i: usize) -> bool;
}

/// A simulation of `spec` in `engine` at `settings`.
pub fn build(engine: Engine, spec: &Spec, settings: Settings) -> Box<dyn Sim> {
    match engine {
        Engine::Ours => Box::new(Ours::new(spec, settings)),
        Engine::RapierF32 => Box::new(rapier_f32::Rapier::new(spec, settings)),
        Engine::RapierF64 => Box::new(rapier_f64::Rapier::new(spec, settings)),
    }
}

fn s(v: f64) -> Scalar {
    Scalar::from_f64_lossy(v)
}

fn v3(p: [f64; 3]) -> Vec3 {
    Vec3::new(s(p[0]), s(p[1]), s(p[2]))
}

fn f3(v: Vec3) -> [f64; 3] {
    [v.x.to_f64(), v.y.to_f64(), v.z.to_f64()]
}

/// A spec value as the engines receive it: rounded to Q32.32.
fn q(v: f64) -> f64 {
    s(v).to_f64()
}

/// lockstep-core.
struct Ours {
    world: World,
    handles: Vec<BodyHandle>,
    forces: Vec<(BodyHandle, Vec3)>,
    torques: Vec<(BodyHandle, Vec3)>,
    faulted: bool,
}

impl Ours {
    fn new(spec: &Spec, settings: Settings) -> Ours {
        let mut world = World::new(WorldConfig {
            gravity: v3(spec.gravity),
            tick_rate: settings.tick_rate,
            substeps: settings.substeps,
            solver_iterations: settings.iterations,
            relax_iterations: 1,
            sleep: SleepConfig {
                enabled: spec.sleep,
                ..SleepConfig::default()
            },
            contact_rows: rows(),
            ..WorldConfig::default()
        })
        .expect("valid world config");
        let mut handles = Vec::new();
        let mut forces = Vec::new();
        let mut torques = Vec::new();
        for b in &spec.bodies {
            let desc = if b.fixed {
                BodyDesc::fixed()
            } else {
                BodyDesc::dynamic()
                    .linear_velocity(v3(b.vel))
                    .angular_velocity(v3(b.omega))
            };
            let [x, y, z, w] = b.rot;
            let rot = Quat::from_xyzw(s(x), s(y), s(z), s(w));
            let h = world
                .create_body(&desc.position(v3(b.pos)).rotation(rot))
                .expect("body");
            let shape = match b.shape {
                ShapeSpec::Sphere(r) => Shape::Sphere(Sphere::new(s(r)).expect("sphere")),
                ShapeSpec::Cuboid(half) => Shape::Cuboid(Cuboid::new(v3(half)).expect("box")),
                ShapeSpec::Capsule(h, r) => {
                    Shape::Capsule(Capsule::new(s(h), s(r)).expect("capsule"))
                }
                ShapeSpec::Octahedron(r) => {
                    let pts = ShapeSpec::octahedron_points(r).map(v3);
                    Shape::ConvexHull(Arc::new(ConvexHull::from_points(&pts).expect("hull")))
                }
            };
            world
                .add_collider(
                    h,
                    ColliderDesc::new(shape)
                        .density(s(b.density))
                        .material(Material::new(s(b.friction), s(b.restitution))),
                )
                .expect("collider");
            if b.force != [0.0; 3] {
                forces.push((h, v3(b.force)));
            }
            if b.torque != [0.0; 3] {
                torques.push((h, v3(b.torque)));
            }
            handles.push(h);
        }
        for j in &spec.joints {
            let [x, y, z, w] = j.frame_rotation();
            let rot = Quat::from_xyzw(s(x), s(y), s(z), s(w)).normalize();
            let kind = match j.kind {
                JointSpecKind::Ball => JointKind::Spherical {
                    cone: None,
                    twist: None,
                },
                JointSpecKind::Hinge { limits, motor, .. } => JointKind::Revolute {
                    limits: limits.map(|[lo, hi]| (s(lo), s(hi))),
                    motor: motor.map(|[speed, torque]| Motor::Speed {
                        speed: s(speed),
                        max_force: s(torque),
                    }),
                },
            };
            let frame = |anchor: [f64; 3]| Transform::new(v3(anchor), rot);
            let rigid_limits = matches!(
                j.kind,
                JointSpecKind::Hinge {
                    rigid_limits: true,
                    ..
                }
            );
            world
                .add_joint(
                    JointDesc::new(kind, handles[j.a], handles[j.b])
                        .frames(frame(j.anchors[0]), frame(j.anchors[1]))
                        .rigid_limits(rigid_limits),
                )
                .expect("joint");
        }
        Ours {
            world,
            handles,
            forces,
            torques,
            faulted: false,
        }
    }
}

impl Sim for Ours {
    fn step(&mut self) {
        // Our forces act for one step: apply them before each.
        for &(h, f) in &self.forces {
            self.world.apply_force(h, f).expect("live body");
        }
        for &(h, t) in &self.torques {
            self.world.apply_torque(h, t).expect("live body");
        }
        let report = self.world.step();
        self.faulted |= !report.faults.is_empty();
    }

    fn state(&self, i: usize) -> State {
        let b = self.world.body(self.handles[i]).expect("live body");
        let r = b.rotation();
        State {
            pos: f3(b.center_of_mass()),
            rot: [r.x.to_f64(), r.y.to_f64(), r.z.to_f64(), r.w.to_f64()],
            vel: f3(b.linear_velocity()),
            omega: f3(b.angular_velocity()),
        }
    }

    fn set_linvel(&mut self, i: usize, v: [f64; 3]) {
        self.world
            .set_linear_velocity(self.handles[i], v3(v))
            .expect("live body");
    }

    fn faulted(&self) -> bool {
        self.faulted
    }

    fn sleeping(&self, i: usize) -> bool {
        self.world
            .body(self.handles[i])
            .expect("live body")
            .is_sleeping()
    }
}

/// Rapier's integration parameters for our settings. In Rapier 0.36 each
/// "solver iteration" is a substep of its TGS-soft solver (integrate, then
/// `num_internal_pgs_iterations` solve passes with bias, then
/// `num_internal_stabilization_iterations` relax passes without), which is
/// what our substep does with `solver_iterations` solve passes and one
/// relax pass; so `num_solver_iterations = substeps`,
/// `num_internal_pgs_iterations = iterations`, one stabilization pass.
pub fn rapier_parameters(settings: Settings) -> (f64, usize, usize, usize) {
    (
        1.0 / settings.tick_rate as f64,
        settings.substeps as usize,
        settings.iterations as usize,
        1,
    )
}

/// The damping factor of Rapier's speed motors: the gain (per second) that
/// drives the joint's speed towards its target. At 1 (the value in Rapier's
/// examples) the `hinge_motor` case's rod swings 55–60 % off its target
/// speed; from 1e4 up the error stops falling (5 % at 60 Hz, 4 substeps),
/// so Rapier gets its best motor.
pub const RAPIER_MOTOR_FACTOR: f64 = 1.0e4;

/// One adapter for both precisions of Rapier: the crates have the same API
/// over a different `Real`, so the code is written once and instantiated
/// for each.
macro_rules! rapier_adapter {
    ($module:ident, $krate:ident, $real:ty) => {
        mod $module {
            use $krate::prelude::{
                ColliderBuilder, GenericJointBuilder, IntegrationParameters, JointAxesMask,
                JointAxis, PhysicsWorld, Pose, RigidBodyBuilder, RigidBodyHandle, Rotation, Vector,
            };

            use super::{
                JointSpecKind, RAPIER_MOTOR_FACTOR, Settings, ShapeSpec, Sim, Spec, State, q,
                rapier_parameters,
            };

            fn r(v: f64) -> $real {
                q(v) as $real
            }

            fn rv(p: [f64; 3]) -> Vector {
                Vector::new(r(p[0]), r(p[1]), r(p[2]))
            }

            fn f3(v: Vector) -> [f64; 3] {
                [v.x as f64, v.y as f64, v.z as f64]
            }

            /// A Rapier world of this precision and its bodies in spec
            /// order.
            pub struct Rapier {
                world: PhysicsWorld,
                handles: Vec<RigidBodyHandle>,
            }

            impl Rapier {
                /// Builds `spec` at `settings` (see [`rapier_parameters`]).
                pub fn new(spec: &Spec, settings: Settings) -> Rapier {
                    let (dt, substeps, pgs, stabilization) = rapier_parameters(settings);
                    let mut world = PhysicsWorld {
                        gravity: rv(spec.gravity),
                        integration_parameters: IntegrationParameters {
                            dt: dt as $real,
                            num_solver_iterations: substeps,
                            num_internal_pgs_iterations: pgs,
                            num_internal_stabilization_iterations: stabilization,
                            ..IntegrationParameters::default()
                        },
                        ..PhysicsWorld::default()
                    };
                    let mut handles = Vec::new();
                    for (i, b) in spec.bodies.iter().enumerate() {
                        let [x, y, z, w] = b.rot;
                        let pose = Pose::from_parts(
                            rv(b.pos),
                            Rotation::from_xyzw(r(x), r(y), r(z), r(w)).normalize(),
                        );
                        let body = if b.fixed {
                            RigidBodyBuilder::fixed().pose(pose)
                        } else {
                            RigidBodyBuilder::dynamic()
                                .pose(pose)
                                .linvel(rv(b.vel))
                                .angvel(rv(b.omega))
                                .can_sleep(spec.sleep)
                                .ccd_enabled(spec.ccd.contains(&i))
                        };
                        let collider = match b.shape {
                            ShapeSpec::Sphere(rad) => ColliderBuilder::ball(r(rad)),
                            ShapeSpec::Cuboid([hx, hy, hz]) => {
                                ColliderBuilder::cuboid(r(hx), r(hy), r(hz))
                            }
                            ShapeSpec::Capsule(hh, rad) => {
                                ColliderBuilder::capsule_y(r(hh), r(rad))
                            }
                            ShapeSpec::Octahedron(rad) => {
                                let pts = ShapeSpec::octahedron_points(rad).map(rv);
                                ColliderBuilder::convex_hull(&pts).expect("hull")
                            }
                        };
                        let (h, _) = world.insert(
                            body,
                            collider
                                .density(r(b.density))
                                .friction(r(b.friction))
                                .restitution(r(b.restitution)),
                        );
                        if b.force != [0.0; 3] {
                            // Rapier's user forces persist until reset.
                            world.bodies[h].add_force(rv(b.force), true);
                        }
                        if b.torque != [0.0; 3] {
                            world.bodies[h].add_torque(rv(b.torque), true);
                        }
                        handles.push(h);
                    }
                    for j in &spec.joints {
                        let [x, y, z, w] = j.frame_rotation();
                        let rot = Rotation::from_xyzw(r(x), r(y), r(z), r(w)).normalize();
                        let frame = |anchor: [f64; 3]| Pose::from_parts(rv(anchor), rot);
                        let mask = match j.kind {
                            JointSpecKind::Ball => JointAxesMask::LOCKED_SPHERICAL_AXES,
                            JointSpecKind::Hinge { .. } => JointAxesMask::LOCKED_REVOLUTE_AXES,
                        };
                        let mut joint = GenericJointBuilder::new(mask)
                            .local_frame1(frame(j.anchors[0]))
                            .local_frame2(frame(j.anchors[1]))
                            .contacts_enabled(false);
                        if let JointSpecKind::Hinge { limits, motor, .. } = j.kind {
                            if let Some([lo, hi]) = limits {
                                joint = joint.limits(JointAxis::AngX, [r(lo), r(hi)]);
                            }
                            if let Some([speed, torque]) = motor {
                                joint = joint
                                    .motor_velocity(
                                        JointAxis::AngX,
                                        r(speed),
                                        RAPIER_MOTOR_FACTOR as $real,
                                    )
                                    .motor_max_force(JointAxis::AngX, r(torque));
                            }
                        }
                        world.insert_impulse_joint(handles[j.a], handles[j.b], joint.build());
                    }
                    Rapier { world, handles }
                }
            }

            impl Sim for Rapier {
                fn step(&mut self) {
                    self.world.step();
                }

                fn state(&self, i: usize) -> State {
                    let b = &self.world.bodies[self.handles[i]];
                    let q = b.rotation();
                    State {
                        pos: f3(b.center_of_mass()),
                        rot: [q.x as f64, q.y as f64, q.z as f64, q.w as f64],
                        vel: f3(b.linvel()),
                        omega: f3(b.angvel()),
                    }
                }

                fn set_linvel(&mut self, i: usize, v: [f64; 3]) {
                    self.world.bodies[self.handles[i]].set_linvel(rv(v), true);
                }

                fn faulted(&self) -> bool {
                    false
                }

                fn sleeping(&self, i: usize) -> bool {
                    self.world.bodies[self.handles[i]].is_sleeping()
                }
            }
        }
    };
}

rapier_adapter!(rapier_f32, rapier3d, f32);
rapier_adapter!(rapier_f64, rapier3d_f64, f64);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accuracy::closed::rotate;

    #[test]
    fn joint_frames_turn_x_onto_the_axis() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        for axis in [
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [-1.0, 0.0, 0.0],
            [0.0, -h, h],
            [0.6, 0.0, -0.8],
        ] {
            let j = JointSpec {
                a: 0,
                b: 1,
                anchors: [[0.0; 3]; 2],
                axis,
                kind: JointSpecKind::Ball,
            };
            let q = j.frame_rotation();
            let len: f64 = q.iter().map(|c| c * c).sum();
            assert!((len - 1.0).abs() < 1e-12, "{q:?}");
            let x = rotate(q, [1.0, 0.0, 0.0]);
            for k in 0..3 {
                assert!((x[k] - axis[k]).abs() < 1e-12, "{axis:?} -> {x:?}");
            }
        }
    }
}
