//! A scene file in both engines: the parsed description
//! ([`SceneDesc`]) built by our own scene builder and translated to Rapier
//! body by body, shape by shape and joint by joint, so that a benchmark
//! scene can have mixed shapes, many static bodies and joints with limits
//! (the ragdolls) and still be the same scene in both.
//!
//! What the translation cannot carry over exactly:
//! - a position motor: Rapier's is a spring of its own stiffness (see
//!   [`MOTOR_STIFFNESS`]);
//! - a cone limit: Rapier limits each swing axis on its own, so a cone of
//!   angle θ becomes ±θ about the joint frame's y and z axes (a square that
//!   the cone fits inside: Rapier allows the corners, up to θ·√2);
//! - friction: we combine two shapes' coefficients by their geometric mean,
//!   Rapier by one of its rules; it takes the average (equal coefficients
//!   give the same value either way, and stone on cloth in the ragdoll
//!   scene is 0.693 against 0.7);
//! - group indices (`collision_group`): Rapier has none; a scene that uses
//!   them is refused, as are height fields and distance joints.

use lockstep_core::collider::MassSpec;
use std::collections::BTreeMap;

use crate::accuracy::sim::RAPIER_MOTOR_FACTOR;
use lockstep_core::SleepConfig;
use lockstep_core::joint::{JointKind, Motor};
use lockstep_core::scene::{GeometryDesc, SceneDesc, build_world_with_config};
use lockstep_core::{
    BodyHandle, BodyKind, ContactOrder, ContactRows, Quat, Scalar, Vec3, World, WorldConfig,
};
use rapier3d::prelude::{
    CoefficientCombineRule, ColliderBuilder, GenericJointBuilder, Group, InteractionGroups,
    InteractionTestMode, JointAxesMask, JointAxis, PhysicsWorld, Pose, RigidBodyBuilder,
    RigidBodyHandle, Rotation, SharedShape, Vector,
};

/// Rapier's position motor is a spring with its own stiffness and damping;
/// ours is a stiff spring at the joint softness. These make Rapier's stiff
/// too (no benchmark scene has a position motor yet).
const MOTOR_STIFFNESS: f32 = 1e4;
/// See [`MOTOR_STIFFNESS`].
const MOTOR_DAMPING: f32 = 1e2;

/// The name errors and our builder report the scene under.
const FILE_NAME: &str = "bench scene";

fn f(v: Scalar) -> f32 {
    v.to_f64() as f32
}

fn vector(v: Vec3) -> Vector {
    Vector::new(f(v.x), f(v.y), f(v.z))
}

fn rotation(q: Quat) -> Rotation {
    Rotation::from_xyzw(f(q.x), f(q.y), f(q.z), f(q.w))
}

/// Our world for the scene, with the file's own settings except `sleep`;
/// and the dynamic bodies' handles in file order.
pub fn build_ours(
    desc: &SceneDesc,
    sleep: SleepConfig,
    order: ContactOrder,
    rows: ContactRows,
) -> (World, Vec<BodyHandle>) {
    let config = WorldConfig {
        sleep,
        contact_order: order,
        contact_rows: rows,
        ..desc.world
    };
    let world = build_world_with_config(desc, config, FILE_NAME).unwrap_or_else(|e| panic!("{e}"));
    // The builder creates the bodies in file order.
    let bodies = desc
        .bodies
        .iter()
        .zip(world.body_handles())
        .filter(|(b, _)| b.kind == BodyKind::Dynamic)
        .map(|(b, h)| {
            assert_eq!(world.body(h).expect("live body").name(), b.name);
            h
        })
        .collect();
    (world, bodies)
}

/// Whether Rapier can take the scene (see the module docs); the reason if
/// not.
pub fn rapier_support(desc: &SceneDesc) -> Result<(), String> {
    for body in &desc.bodies {
        for shape in &body.shapes {
            if matches!(shape.geometry, GeometryDesc::HeightField { .. }) {
                return Err(format!("{}: height fields are not translated", body.name));
            }
            if shape.collision_group != 0 {
                return Err(format!("{}: group indices are not translated", body.name));
            }
        }
    }
    for joint in &desc.joints {
        if matches!(joint.kind, JointKind::Distance { .. }) {
            return Err(format!(
                "{}: distance joints are not translated",
                joint.name
            ));
        }
    }
    Ok(())
}

fn shape(geometry: &GeometryDesc) -> SharedShape {
    match geometry {
        GeometryDesc::Sphere { radius } => SharedShape::ball(f(*radius)),
        GeometryDesc::Capsule {
            half_height,
            radius,
        } => SharedShape::capsule_y(f(*half_height), f(*radius)),
        GeometryDesc::Box { half_extents } => {
            SharedShape::cuboid(f(half_extents.x), f(half_extents.y), f(half_extents.z))
        }
        GeometryDesc::ConvexHull { points } => {
            let points: Vec<Vector> = points.iter().map(|&p| vector(p)).collect();
            SharedShape::convex_hull(&points).expect("a scene hull has volume")
        }
        GeometryDesc::TriMesh { vertices, indices } => SharedShape::trimesh(
            vertices.iter().map(|&p| vector(p)).collect(),
            indices.clone(),
        )
        .expect("a valid scene mesh"),
        GeometryDesc::HeightField { .. } => unreachable!("refused by rapier_support"),
    }
}

/// The scene in Rapier: every body (sleep off, as in the rest of the
/// suite), every shape and every joint; and the dynamic bodies' handles in
/// file order. Panics on a scene [`rapier_support`] refuses.
pub fn build_rapier(desc: &SceneDesc) -> (PhysicsWorld, Vec<RigidBodyHandle>) {
    if let Err(why) = rapier_support(desc) {
        panic!("{why}");
    }
    let mut world = PhysicsWorld {
        gravity: vector(desc.world.gravity),
        integration_parameters: crate::engines::rapier_parameters_for(
            desc.world.tick_rate,
            desc.world.substeps,
        ),
        ..PhysicsWorld::default()
    };
    // By name, for the joints; and the dynamic bodies in file order.
    let mut handles: BTreeMap<&str, RigidBodyHandle> = BTreeMap::new();
    let mut dynamic = Vec::new();
    for body in &desc.bodies {
        let builder = match body.kind {
            BodyKind::Static => RigidBodyBuilder::fixed(),
            BodyKind::Dynamic => RigidBodyBuilder::dynamic(),
            BodyKind::Kinematic => RigidBodyBuilder::kinematic_velocity_based(),
        };
        let builder = builder
            .pose(Pose::from_parts(
                vector(body.position),
                rotation(body.rotation),
            ))
            .linvel(vector(body.linear_velocity))
            .angvel(vector(body.angular_velocity))
            .linear_damping(f(body.linear_damping))
            .angular_damping(f(body.angular_damping))
            .can_sleep(false);
        let handle = world.bodies.insert(builder);
        for s in &body.shapes {
            let collider = ColliderBuilder::new(shape(&s.geometry))
                .position(Pose::from_parts(vector(s.offset), rotation(s.rotation)))
                .friction(f(s.friction))
                .friction_combine_rule(CoefficientCombineRule::Average)
                .restitution(f(s.restitution))
                .restitution_combine_rule(CoefficientCombineRule::Max)
                .sensor(s.trigger)
                .collision_groups(InteractionGroups::new(
                    Group::from_bits_retain(s.group),
                    Group::from_bits_retain(s.mask),
                    InteractionTestMode::And,
                ));
            let collider = match s.density_or_mass {
                MassSpec::Density(d) => collider.density(f(d)),
                MassSpec::Mass(m) => collider.mass(f(m)),
            };
            world
                .colliders
                .insert_with_parent(collider, handle, &mut world.bodies);
        }
        handles.insert(body.name.as_str(), handle);
        if body.kind == BodyKind::Dynamic {
            dynamic.push(handle);
        }
    }
    let handle_of = |name: &str| *handles.get(name).expect("joint bodies exist");
    for joint in &desc.joints {
        let (mask, limits, motor): (JointAxesMask, Vec<(JointAxis, f32, f32)>, Option<Motor>) =
            match joint.kind {
                JointKind::Spherical { cone, twist } => {
                    let mut limits = Vec::new();
                    if let Some((lo, hi)) = twist {
                        limits.push((JointAxis::AngX, f(lo), f(hi)));
                    }
                    if let Some(cone) = cone {
                        limits.push((JointAxis::AngY, -f(cone), f(cone)));
                        limits.push((JointAxis::AngZ, -f(cone), f(cone)));
                    }
                    (JointAxesMask::LOCKED_SPHERICAL_AXES, limits, None)
                }
                JointKind::Revolute { limits, motor } => (
                    JointAxesMask::LOCKED_REVOLUTE_AXES,
                    limits
                        .map(|(lo, hi)| vec![(JointAxis::AngX, f(lo), f(hi))])
                        .unwrap_or_default(),
                    motor,
                ),
                JointKind::Prismatic { limits, motor } => (
                    JointAxesMask::LOCKED_PRISMATIC_AXES,
                    limits
                        .map(|(lo, hi)| vec![(JointAxis::LinX, f(lo), f(hi))])
                        .unwrap_or_default(),
                    motor,
                ),
                JointKind::Fixed => (JointAxesMask::LOCKED_FIXED_AXES, Vec::new(), None),
                JointKind::Distance { .. } => unreachable!("refused by rapier_support"),
            };
        let mut builder = GenericJointBuilder::new(mask)
            .local_frame1(Pose::from_parts(
                vector(joint.frame_a.translation),
                rotation(joint.frame_a.rotation),
            ))
            .local_frame2(Pose::from_parts(
                vector(joint.frame_b.translation),
                rotation(joint.frame_b.rotation),
            ))
            .contacts_enabled(joint.collide_connected);
        for (axis, lo, hi) in limits {
            builder = builder.limits(axis, [lo, hi]);
        }
        if let Some(motor) = motor {
            let axis = if matches!(joint.kind, JointKind::Prismatic { .. }) {
                JointAxis::LinX
            } else {
                JointAxis::AngX
            };
            builder = match motor {
                Motor::Speed { speed, .. } => {
                    builder.motor_velocity(axis, f(speed), RAPIER_MOTOR_FACTOR as f32)
                }
                Motor::Position { target, .. } => {
                    builder.motor_position(axis, f(target), MOTOR_STIFFNESS, MOTOR_DAMPING)
                }
            }
            .motor_max_force(axis, f(motor.max_force()));
        }
        // Joint friction: a speed motor at 0 with the friction torque about
        // each free angular axis (not on a hinge's axis that has a motor).
        if joint.friction.is_positive() {
            let free: &[JointAxis] = match joint.kind {
                JointKind::Spherical { .. } => &[JointAxis::AngX, JointAxis::AngY, JointAxis::AngZ],
                JointKind::Revolute { motor: None, .. } => &[JointAxis::AngX],
                _ => &[],
            };
            for &axis in free {
                builder = builder
                    .motor_velocity(axis, 0.0, RAPIER_MOTOR_FACTOR as f32)
                    .motor_max_force(axis, f(joint.friction));
            }
        }
        world.insert_impulse_joint(
            handle_of(&joint.body_a),
            handle_of(&joint.body_b),
            builder.build(),
        );
    }
    (world, dynamic)
}
