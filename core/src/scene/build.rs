//! Building a [`World`] from a parsed [`SceneDesc`].
//!
//! Determinism: bodies are created in file order and each body's shapes in
//! file order, so handles (and therefore simulation order) follow the file.

use std::sync::Arc;

use crate::body::{BodyDesc as WorldBodyDesc, BodyKind};
use crate::collider::{ColliderDesc, CollisionFilter, Material};
use crate::math::{Scalar, Transform};
use crate::shape::{Capsule, ConvexHull, Cuboid, HeightField, Shape, Sphere, TriMesh};
use crate::world::{World, WorldConfig};

use super::desc::{GeometryDesc, SceneDesc, ShapeDesc};
use super::error::{SceneError, SceneErrorKind};
use super::parse::parse_scene;

/// Parses and builds a scene in one go: the usual way to load a file.
///
/// # Errors
/// [`SceneError`] naming `file_name`, the line and column, and what is wrong.
pub fn load_world(text: &str, file_name: &str) -> Result<World, SceneError> {
    let desc = parse_scene(text, file_name)?;
    build_world(&desc, file_name)
}

/// Builds the world a scene describes.
///
/// # Errors
/// [`SceneError`] (with `file_name` and the line of the body or shape) when
/// geometry that parsed cannot be built, e.g. a convex hull whose points are
/// all coplanar or out of range.
pub fn build_world(desc: &SceneDesc, file_name: &str) -> Result<World, SceneError> {
    build_world_with_config(desc, desc.world, file_name)
}

/// Builds the bodies a scene describes into a world with other settings:
/// `config` replaces everything the scene's `[world]` table gives (start
/// from the scene's own [`SceneDesc::world`] to change only some
/// settings). `lockstep tune` runs one scene at many tick rates, substep
/// and solver iteration counts this way.
///
/// # Errors
/// As [`build_world`]; also an `OutOfRange` error (line 1) if `config` is
/// invalid.
pub fn build_world_with_config(
    desc: &SceneDesc,
    config: WorldConfig,
    file_name: &str,
) -> Result<World, SceneError> {
    let at = |line: u32, kind: SceneErrorKind, message: String| SceneError {
        file: file_name.to_owned(),
        line,
        column: 1,
        kind,
        message,
    };
    let mut world =
        World::new(config).map_err(|e| at(1, SceneErrorKind::OutOfRange, e.to_string()))?;
    let mut handles = Vec::with_capacity(desc.bodies.len());
    let mut sleepers = Vec::new();
    for body in &desc.bodies {
        let kind = body.kind;
        let world_desc = WorldBodyDesc {
            kind,
            name: body.name.clone(),
            position: body.position,
            rotation: body.rotation,
            linear_velocity: body.linear_velocity,
            angular_velocity: body.angular_velocity,
            linear_damping: body.linear_damping,
            angular_damping: body.angular_damping,
            gravity_scale: Scalar::ONE,
            asleep: body.asleep,
            bullet: body.bullet,
            user_data: 0,
        };
        let handle = world.create_body(&world_desc).map_err(|e| {
            at(
                body.line,
                SceneErrorKind::OutOfRange,
                format!("body {:?}: {e}", body.name),
            )
        })?;
        for shape in &body.shapes {
            let collider = collider_desc(shape).map_err(|e| {
                at(
                    shape.line,
                    SceneErrorKind::BadGeometry,
                    format!(
                        "body {:?}: {} shape: {e}",
                        body.name,
                        shape.geometry.kind_name()
                    ),
                )
            })?;
            world.add_collider(handle, collider).map_err(|e| {
                at(
                    shape.line,
                    SceneErrorKind::BadGeometry,
                    format!("body {:?}: {e}", body.name),
                )
            })?;
        }
        // Velocities were set before the colliders gave the body its
        // inertia; set the angular velocity again so the angular momentum
        // matches the final inertia.
        if kind == BodyKind::Dynamic {
            world
                .set_angular_velocity(handle, body.angular_velocity)
                .map_err(|e| at(body.line, SceneErrorKind::OutOfRange, e.to_string()))?;
            if body.asleep {
                sleepers.push((handle, body.line));
            }
        }
        handles.push(handle);
    }
    // Joints after every body (a joint may name a later body), in file
    // order.
    for j in &desc.joints {
        let find = |name: &str| {
            desc.bodies
                .iter()
                .position(|b| b.name == name)
                .map(|i| handles[i])
        };
        let (Some(a), Some(b)) = (find(&j.body_a), find(&j.body_b)) else {
            return Err(at(
                j.line,
                SceneErrorKind::OutOfRange,
                format!("joint {:?}: a body it names is not in the scene", j.name),
            ));
        };
        let mut jd = crate::joint::JointDesc::new(j.kind, a, b)
            .frames(j.frame_a, j.frame_b)
            .collide_connected(j.collide_connected)
            .rigid_limits(j.rigid_limits)
            .friction(j.friction)
            .breakable(j.break_force, j.break_torque);
        jd.name = j.name.clone();
        world
            .add_joint(jd)
            .map_err(|e| at(j.line, SceneErrorKind::OutOfRange, e.to_string()))?;
    }
    // Asleep bodies go to sleep last: adding a joint wakes its bodies.
    for (handle, line) in sleepers {
        world
            .sleep_body(handle)
            .map_err(|e| at(line, SceneErrorKind::OutOfRange, e.to_string()))?;
    }
    Ok(world)
}

/// The collider a shape description asks for.
fn collider_desc(s: &ShapeDesc) -> Result<ColliderDesc, crate::shape::ShapeError> {
    let shape = match &s.geometry {
        GeometryDesc::Sphere { radius } => Shape::Sphere(Sphere::new(*radius)?),
        GeometryDesc::Capsule {
            half_height,
            radius,
        } => Shape::Capsule(Capsule::new(*half_height, *radius)?),
        GeometryDesc::Box { half_extents } => Shape::Cuboid(Cuboid::new(*half_extents)?),
        GeometryDesc::ConvexHull { points } => {
            Shape::ConvexHull(Arc::new(ConvexHull::from_points(points)?))
        }
        GeometryDesc::TriMesh { vertices, indices } => {
            Shape::TriMesh(Arc::new(TriMesh::new(vertices.clone(), indices.clone())?))
        }
        GeometryDesc::HeightField {
            rows,
            cols,
            heights,
            scale,
        } => Shape::HeightField(Arc::new(HeightField::new(
            *rows,
            *cols,
            heights.clone(),
            *scale,
        )?)),
    };
    Ok(ColliderDesc {
        shape,
        local_pose: Transform::new(s.offset, s.rotation),
        mass: s.density_or_mass,
        material: Material::new(s.friction, s.restitution),
        filter: CollisionFilter {
            category: s.group,
            mask: s.mask,
            group: s.collision_group,
        },
        is_trigger: s.trigger,
    })
}
