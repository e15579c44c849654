//! Adding and removing bodies and colliders, their mass, and the check of
//! the references between them.

use crate::body::{BodyCold, BodyDesc, BodyHandle, BodyHot, BodyKind};
use crate::collider::{Collider, ColliderDesc, ColliderHandle, MassSpec};
use crate::collision::ProxyId;
use crate::math::{Scalar, SymMat3, Transform, Vec3};
use crate::shape::MassProperties;
use crate::solver::integrate::momentum_from_omega;

use super::awake::Toucher;
use super::collide;
use super::config::WorldError;
use super::state::World;

impl World {
    /// Creates a body. Its mass comes from the colliders added later, unless
    /// set with [`World::set_mass_properties`]; a dynamic body with neither
    /// has mass 1 kg and the inertia of a unit-radius solid sphere
    /// (0.4 kg·m² about every axis), so it still moves sensibly.
    ///
    /// # Errors
    /// [`WorldError::InvalidParameter`] for negative damping.
    pub fn create_body(&mut self, desc: &BodyDesc) -> Result<BodyHandle, WorldError> {
        if desc.linear_damping.is_negative() || desc.angular_damping.is_negative() {
            return Err(WorldError::InvalidParameter(format!(
                "body {:?}: damping must not be negative",
                desc.name
            )));
        }
        let rotation = desc.rotation.normalize();
        let moving = desc.kind != BodyKind::Static;
        let hot = BodyHot {
            kind: desc.kind,
            sleeping: desc.asleep && desc.kind == BodyKind::Dynamic,
            isotropic: true,
            bullet: desc.bullet && desc.kind == BodyKind::Dynamic,
            center: desc.position,
            rotation,
            linear_velocity: if moving {
                desc.linear_velocity
            } else {
                Vec3::ZERO
            },
            angular_velocity: if moving {
                desc.angular_velocity
            } else {
                Vec3::ZERO
            },
            angular_momentum: Vec3::ZERO,
            force: Vec3::ZERO,
            torque: Vec3::ZERO,
            inv_mass: Scalar::ZERO,
            inertia: SymMat3::ZERO,
            inv_inertia: SymMat3::ZERO,
            linear_damping: desc.linear_damping,
            angular_damping: desc.angular_damping,
            gravity_scale: desc.gravity_scale,
            rest_ticks: 0,
            ccd_extent: Scalar::ZERO,
            ccd_radius: Scalar::ZERO,
        };
        let cold = BodyCold {
            name: desc.name.clone(),
            user_data: desc.user_data,
            ..BodyCold::default()
        };
        let h = self.bodies.insert(hot, cold);
        self.update_mass(h);
        Ok(h)
    }

    /// Removes a body and its colliders.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`] for a stale handle.
    pub fn remove_body(&mut self, h: BodyHandle) -> Result<(), WorldError> {
        if !self.bodies.contains(h) {
            return Err(WorldError::InvalidBody(h));
        }
        self.remove_joints_of(h);
        // (The pairs still name its colliders: wake what rested on it first.)
        self.wake_touching(Toucher::Body(h));
        let cold = self.bodies.remove(h).ok_or(WorldError::InvalidBody(h))?;
        for c in cold.colliders {
            if let Some(removed) = self.colliders.remove(c.0) {
                let _ = self.broad.destroy_proxy(removed.proxy);
                self.contacts.remove_collider(c);
            }
        }
        Ok(())
    }

    /// Attaches a collider to a body and updates the body's mass properties
    /// (keeping the body origin, linear velocity and angular velocity).
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`]; [`WorldError::StaticOnlyShape`] for a
    /// triangle mesh or height field on a dynamic or kinematic body;
    /// [`WorldError::Shape`] for a shape with a non-positive dimension (see
    /// [`Shape::validate`](crate::shape::Shape::validate)) or a non-positive
    /// density or mass.
    pub fn add_collider(
        &mut self,
        body: BodyHandle,
        desc: ColliderDesc,
    ) -> Result<ColliderHandle, WorldError> {
        let hot = self.bodies.hot(body).ok_or(WorldError::InvalidBody(body))?;
        let kind = hot.kind;
        if desc.shape.is_static_only() && kind != BodyKind::Static {
            let name = self
                .bodies
                .cold(body)
                .map(|c| c.name.clone())
                .unwrap_or_default();
            return Err(WorldError::StaticOnlyShape {
                shape: desc.shape.kind().name(),
                body: name,
                kind: kind.name(),
            });
        }
        desc.shape.validate()?;
        let mass_properties = if kind == BodyKind::Dynamic {
            collider_mass(&desc)?
        } else {
            MassProperties::default()
        };
        let shape_hash = crate::hash::shape_hash(&desc.shape);
        let local_pose = Transform::new(
            desc.local_pose.translation,
            desc.local_pose.rotation.normalize(),
        );
        let origin = self.body_origin(body);
        let aabb = desc
            .shape
            .aabb(&origin.mul_transform(&local_pose))
            .expanded(self.config.contact_margin);
        let ch = ColliderHandle(self.colliders.insert(Collider {
            body,
            shape: desc.shape,
            local_pose: Transform::new(
                desc.local_pose.translation,
                desc.local_pose.rotation.normalize(),
            ),
            mass_spec: desc.mass,
            mass_properties,
            material: desc.material,
            filter: desc.filter,
            is_trigger: desc.is_trigger,
            shape_hash,
            // Replaced just below: the proxy's key is the collider handle,
            // which only exists once the collider is inserted.
            proxy: ProxyId::from_index(u32::MAX),
        }));
        let proxy = self.broad.create_proxy(
            aabb,
            collide::proxy_key(ch),
            collide::proxy_kind_of(&self.bodies, body),
        );
        if let Some(c) = self.colliders.get_mut(ch.0) {
            c.proxy = proxy;
        }
        if let Some(cold) = self.bodies.cold_mut(body) {
            cold.colliders.push(ch);
        }
        self.update_mass(body);
        Ok(ch)
    }

    /// Detaches and removes a collider; the body's mass is recomputed.
    ///
    /// # Errors
    /// [`WorldError::InvalidCollider`] for a stale handle.
    pub fn remove_collider(&mut self, h: ColliderHandle) -> Result<(), WorldError> {
        let c = self
            .colliders
            .remove(h.0)
            .ok_or(WorldError::InvalidCollider(h))?;
        // (The pairs still name `h`: wake what rested on it first.)
        self.wake_touching(Toucher::Collider(h));
        let _ = self.broad.destroy_proxy(c.proxy);
        self.contacts.remove_collider(h);
        if let Some(cold) = self.bodies.cold_mut(c.body) {
            cold.colliders.retain(|x| *x != h);
        }
        self.update_mass(c.body);
        Ok(())
    }

    /// Overrides a dynamic body's mass properties (colliders then no longer
    /// change them). `props.inertia` is about `props.local_center`, in body
    /// axes.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`]; [`WorldError::InvalidParameter`] for a
    /// non-positive mass or a body that is not dynamic.
    pub fn set_mass_properties(
        &mut self,
        h: BodyHandle,
        props: MassProperties,
    ) -> Result<(), WorldError> {
        let kind = self.bodies.hot(h).ok_or(WorldError::InvalidBody(h))?.kind;
        if kind != BodyKind::Dynamic {
            return Err(WorldError::InvalidParameter(
                "only dynamic bodies have a mass".into(),
            ));
        }
        if !props.mass.is_positive() {
            return Err(WorldError::InvalidParameter(format!(
                "mass must be positive, got {}",
                props.mass
            )));
        }
        self.apply_mass(h, props, true);
        Ok(())
    }

    /// Recomputes a body's mass properties from its colliders.
    fn update_mass(&mut self, h: BodyHandle) {
        let Some(cold) = self.bodies.cold(h) else {
            return;
        };
        let kind = self.bodies.hot(h).map(|b| b.kind).unwrap_or_default();
        if cold.mass_override && kind == BodyKind::Dynamic {
            return;
        }
        let props = if kind == BodyKind::Dynamic {
            let parts: Vec<(MassProperties, Transform)> = cold
                .colliders
                .iter()
                .filter_map(|c| self.colliders.get(c.0))
                .map(|c| (c.mass_properties, c.local_pose))
                .collect();
            let combined = MassProperties::combine(&parts);
            if combined.mass.is_positive() {
                combined
            } else {
                MassProperties {
                    mass: Scalar::ONE,
                    local_center: Vec3::ZERO,
                    inertia: SymMat3::from_diagonal(Vec3::splat(Scalar::from_ratio(2, 5))),
                }
            }
        } else {
            MassProperties::default()
        };
        self.apply_mass(h, props, false);
    }

    /// Installs mass properties, keeping the body origin and the velocities.
    fn apply_mass(&mut self, h: BodyHandle, props: MassProperties, is_override: bool) {
        let Some((hot, cold)) = self.bodies.both_mut(h) else {
            return;
        };
        let origin = hot.origin_pose(cold.local_center);
        cold.local_center = props.local_center;
        cold.mass_override = is_override;
        hot.center = origin.transform_point(props.local_center);
        if hot.kind == BodyKind::Dynamic {
            cold.mass = props.mass;
            hot.inv_mass = props.inverse_mass();
            hot.inertia = props.inertia;
            hot.inv_inertia = props.inverse_inertia().unwrap_or(SymMat3::ZERO);
            let i = &props.inertia;
            hot.isotropic =
                i.xx == i.yy && i.yy == i.zz && i.xy.is_zero() && i.xz.is_zero() && i.yz.is_zero();
            hot.angular_momentum =
                momentum_from_omega(hot.rotation, &hot.inertia, hot.angular_velocity);
        } else {
            cold.mass = Scalar::ZERO;
            hot.inv_mass = Scalar::ZERO;
            hot.inertia = SymMat3::ZERO;
            hot.inv_inertia = SymMat3::ZERO;
            hot.isotropic = true;
            hot.angular_momentum = Vec3::ZERO;
        }
        self.refresh_ccd_extents(h);
    }

    /// The pose of a body's origin (identity for a stale handle).
    pub(super) fn body_origin(&self, h: BodyHandle) -> Transform {
        match (self.bodies.hot(h), self.bodies.cold(h)) {
            (Some(hot), Some(cold)) => hot.origin_pose(cold.local_center),
            _ => Transform::IDENTITY,
        }
    }

    /// Checks the cross-references a decoded snapshot must satisfy: every
    /// collider's body exists and lists it, and every listed collider exists.
    pub(crate) fn check_invariants(&self) -> Result<(), String> {
        self.game.validate()?;
        self.bodies.check()?;
        self.colliders.check()?;
        self.broad.validate().map_err(|e| e.to_string())?;
        if self.broad.proxy_count() != self.colliders.len() {
            return Err("broad-phase proxies and colliders disagree in number".into());
        }
        for (h, c) in self.colliders.iter() {
            if self.broad.key(c.proxy).ok() != Some(collide::proxy_key(ColliderHandle(h))) {
                return Err(format!("collider {h:?} has no matching broad-phase proxy"));
            }
        }
        for (h, c) in self.colliders.iter() {
            let listed = self
                .bodies
                .cold(c.body)
                .map(|b| b.colliders.contains(&ColliderHandle(h)))
                .unwrap_or(false);
            if !listed {
                return Err(format!("collider {h:?} is not attached to a live body"));
            }
        }
        for (bh, _, cold) in self.bodies.iter() {
            for ch in &cold.colliders {
                if self.colliders.get(ch.0).map(|c| c.body) != Some(bh) {
                    return Err(format!("{bh} lists a collider that is not its own"));
                }
            }
        }
        for (jh, j) in self.joints.arena.iter() {
            let (a, b) = (j.desc.body_a, j.desc.body_b);
            if !self.bodies.contains(a) || !self.bodies.contains(b) || a == b {
                return Err(format!("joint {jh:?} does not join two live bodies"));
            }
        }
        Ok(())
    }
}

/// A collider's mass properties in the body frame (before the local pose is
/// applied; `MassProperties::combine` applies it).
fn collider_mass(desc: &ColliderDesc) -> Result<MassProperties, WorldError> {
    match desc.mass {
        MassSpec::Density(d) => Ok(desc.shape.mass_properties(d)?),
        MassSpec::Mass(m) => {
            if !m.is_positive() {
                return Err(WorldError::InvalidParameter(format!(
                    "collider mass must be positive, got {m}"
                )));
            }
            let unit = desc.shape.mass_properties(Scalar::ONE)?;
            // Scale density so the total is m: every entry scales by m / m1.
            let k = m / unit.mass;
            Ok(MassProperties {
                mass: m,
                local_center: unit.local_center,
                inertia: unit.inertia.scale(k),
            })
        }
    }
}
