//! Changing one body from outside the step: poses, velocities, forces,
//! impulses, waking and sleeping.

use crate::body::{BodyHandle, BodyHot, BodyKind};
use crate::math::{FaultScope, Faults, Quat, Transform, Vec3};
use crate::solver::integrate::{momentum_from_omega, omega_from_momentum};

use super::awake::Toucher;
use super::config::WorldError;
use super::state::World;

impl World {
    fn hot_mut(&mut self, h: BodyHandle) -> Result<&mut BodyHot, WorldError> {
        self.bodies.hot_mut(h).ok_or(WorldError::InvalidBody(h))
    }

    /// Teleports a body: its origin goes to `pose` (velocities kept, body
    /// woken). Use sparingly on dynamic bodies: it ignores everything in the
    /// way. A rotation that is already unit (as every pose the world reports
    /// is) is kept bit for bit, so setting a body to its own pose changes
    /// nothing it is hashed by; any other is normalized.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`].
    pub fn set_pose(&mut self, h: BodyHandle, pose: Transform) -> Result<(), WorldError> {
        let (hot, cold) = self.bodies.both_mut(h).ok_or(WorldError::InvalidBody(h))?;
        let rotation = unit_or_normalized(pose.rotation);
        hot.rotation = rotation;
        hot.center = pose.translation + rotation.rotate(cold.local_center);
        if hot.kind == BodyKind::Dynamic {
            hot.angular_momentum =
                momentum_from_omega(rotation, &hot.inertia, hot.angular_velocity);
        }
        self.wake(h);
        // Whatever rested on it (or under it) must see the change.
        self.wake_touching(Toucher::Body(h));
        self.refresh_proxies(h);
        Ok(())
    }

    /// Sets the linear velocity of the centre of mass (wakes the body;
    /// ignored for static bodies).
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`].
    pub fn set_linear_velocity(&mut self, h: BodyHandle, v: Vec3) -> Result<(), WorldError> {
        let hot = self.hot_mut(h)?;
        if hot.kind != BodyKind::Static {
            hot.linear_velocity = v;
            self.wake(h);
        }
        Ok(())
    }

    /// Sets the angular velocity, world axes (wakes the body; ignored for
    /// static bodies). For a dynamic body this sets its angular momentum to
    /// `I_world · ω`.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`].
    pub fn set_angular_velocity(&mut self, h: BodyHandle, w: Vec3) -> Result<(), WorldError> {
        let hot = self.hot_mut(h)?;
        match hot.kind {
            BodyKind::Static => {}
            BodyKind::Kinematic => {
                hot.angular_velocity = w;
            }
            BodyKind::Dynamic => {
                hot.angular_momentum = momentum_from_omega(hot.rotation, &hot.inertia, w);
                hot.angular_velocity =
                    omega_from_momentum(hot.rotation, &hot.inv_inertia, hot.angular_momentum);
                self.wake(h);
            }
        }
        Ok(())
    }

    /// Asks a kinematic body to arrive exactly at `pose` (its origin) at the
    /// end of the next step. During the step it moves with the constant
    /// velocities that reach the pose, so contacts see a smooth motion; after
    /// the step its velocities are zero again unless a new target is set
    /// (the body stops where the game stops steering it).
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`]; [`WorldError::InvalidParameter`] if the
    /// body is not kinematic.
    pub fn set_kinematic_target(
        &mut self,
        h: BodyHandle,
        pose: Transform,
    ) -> Result<(), WorldError> {
        let (hot, cold) = self.bodies.both_mut(h).ok_or(WorldError::InvalidBody(h))?;
        if hot.kind != BodyKind::Kinematic {
            return Err(WorldError::InvalidParameter(format!(
                "set_kinematic_target needs a kinematic body; {:?} is {}",
                cold.name,
                hot.kind.name()
            )));
        }
        cold.kinematic_target = Some(Transform::new(pose.translation, pose.rotation.normalize()));
        Ok(())
    }

    /// Sets the game's opaque value for a body (an entity id, a team, a
    /// kind; also given at creation,
    /// [`BodyDesc::user_data`](crate::body::BodyDesc::user_data)). It is
    /// state like the body's pose: in the body's hash (when not zero), in
    /// snapshots, and in a desync report's fields.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`] for a stale handle.
    pub fn set_user_data(&mut self, h: BodyHandle, value: u64) -> Result<(), WorldError> {
        let (_, cold) = self.bodies.both_mut(h).ok_or(WorldError::InvalidBody(h))?;
        cold.user_data = value;
        Ok(())
    }

    /// Marks a dynamic body as a bullet or not (see
    /// [`BodyDesc::bullet`](crate::body::BodyDesc::bullet)); ignored for
    /// static and kinematic bodies.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`].
    pub fn set_bullet(&mut self, h: BodyHandle, bullet: bool) -> Result<(), WorldError> {
        let hot = self.hot_mut(h)?;
        hot.bullet = bullet && hot.kind == BodyKind::Dynamic;
        Ok(())
    }

    /// Whether the body is a bullet.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`].
    pub fn is_bullet(&self, h: BodyHandle) -> Result<bool, WorldError> {
        Ok(self.bodies.hot(h).ok_or(WorldError::InvalidBody(h))?.bullet)
    }

    /// Adds a force at the centre of mass, applied over the next step
    /// (dynamic bodies only; wakes the body).
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`].
    pub fn apply_force(&mut self, h: BodyHandle, f: Vec3) -> Result<(), WorldError> {
        let hot = self.hot_mut(h)?;
        if hot.kind == BodyKind::Dynamic {
            hot.force += f;
            self.wake(h);
        }
        Ok(())
    }

    /// Adds a force at a world point: a force at the centre of mass plus the
    /// torque `(p − c) × f`, over the next step.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`].
    pub fn apply_force_at_point(
        &mut self,
        h: BodyHandle,
        f: Vec3,
        point: Vec3,
    ) -> Result<(), WorldError> {
        let hot = self.hot_mut(h)?;
        if hot.kind == BodyKind::Dynamic {
            hot.force += f;
            hot.torque += (point - hot.center).cross(f);
            self.wake(h);
        }
        Ok(())
    }

    /// Adds a torque (world axes) over the next step.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`].
    pub fn apply_torque(&mut self, h: BodyHandle, t: Vec3) -> Result<(), WorldError> {
        let hot = self.hot_mut(h)?;
        if hot.kind == BodyKind::Dynamic {
            hot.torque += t;
            self.wake(h);
        }
        Ok(())
    }

    /// Applies an impulse at the centre of mass now: `v += j/m`.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`].
    pub fn apply_impulse(&mut self, h: BodyHandle, j: Vec3) -> Result<(), WorldError> {
        let hot = self.hot_mut(h)?;
        if hot.kind == BodyKind::Dynamic {
            hot.linear_velocity += j * hot.inv_mass;
            self.wake(h);
        }
        Ok(())
    }

    /// Applies an impulse at a world point now (an explosion, a hit):
    /// `v += j/m`, `L += (p − c) × j`.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`].
    pub fn apply_impulse_at_point(
        &mut self,
        h: BodyHandle,
        j: Vec3,
        point: Vec3,
    ) -> Result<(), WorldError> {
        let hot = self.hot_mut(h)?;
        if hot.kind == BodyKind::Dynamic {
            hot.linear_velocity += j * hot.inv_mass;
            hot.angular_momentum += (point - hot.center).cross(j);
            hot.angular_velocity =
                omega_from_momentum(hot.rotation, &hot.inv_inertia, hot.angular_momentum);
            self.wake(h);
        }
        Ok(())
    }

    /// Applies an angular impulse (world axes) now: `L += a`.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`].
    pub fn apply_angular_impulse(&mut self, h: BodyHandle, a: Vec3) -> Result<(), WorldError> {
        let hot = self.hot_mut(h)?;
        if hot.kind == BodyKind::Dynamic {
            hot.angular_momentum += a;
            hot.angular_velocity =
                omega_from_momentum(hot.rotation, &hot.inv_inertia, hot.angular_momentum);
            self.wake(h);
        }
        Ok(())
    }

    /// Wakes a sleeping body.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`].
    pub fn wake_body(&mut self, h: BodyHandle) -> Result<(), WorldError> {
        self.hot_mut(h)?;
        self.wake(h);
        Ok(())
    }

    /// Puts a dynamic body to sleep now (velocities zeroed).
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`].
    pub fn sleep_body(&mut self, h: BodyHandle) -> Result<(), WorldError> {
        self.hot_mut(h)?;
        self.put_to_sleep(h);
        Ok(())
    }

    /// Runs `f` with this world's faults attributed to it.
    pub(crate) fn with_fault_scope<T>(&mut self, f: impl FnOnce(&mut World) -> T) -> (T, Faults) {
        let scope = FaultScope::enter();
        let v = f(self);
        let faults = scope.finish();
        self.faults = self.faults.union(faults);
        (v, faults)
    }
}

/// `q` itself if it is already a unit quaternion to within the rounding
/// of [`Quat::normalize`] (`|‖q‖² − 1| ≤ 2⁻²⁸`, far wider than that
/// rounding and far narrower than any rotation a game means), else `q`
/// normalized. `normalize` is not idempotent to the last bit, so setting a
/// body to the pose it reports would otherwise turn it by an ulp.
fn unit_or_normalized(q: Quat) -> Quat {
    const ONE: u128 = 1 << 64;
    const TOLERANCE: u128 = 1 << 36;
    if q.norm_squared_wide().abs_diff(ONE) <= TOLERANCE {
        q
    } else {
        q.normalize()
    }
}
