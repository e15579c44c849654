//! The world's joints: adding, removing and reading them, the bodies they
//! keep from colliding, and the step's joint work outside the solver
//! (breaking, waking).

use crate::body::{BodyHandle, BodyKind};
use crate::joint::{Joint, JointDesc, JointEvent, JointHandle, JointImpulses, JointKind, Motor};
use crate::math::{Scalar, Transform};
use crate::scratch::Capacities;

use super::config::WorldError;
use super::joint_set::validate;
use super::state::World;

impl World {
    /// Joins two bodies. The joint's frames are in each body's frame (see
    /// [`crate::joint`]); both bodies wake. Unless `collide_connected`, the
    /// two bodies stop colliding with each other.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`] for a stale handle;
    /// [`WorldError::InvalidJointParameter`] for a body joined to itself,
    /// two bodies neither of which is dynamic, or parameters out of range.
    pub fn add_joint(&mut self, desc: JointDesc) -> Result<JointHandle, WorldError> {
        let (a, b) = (desc.body_a, desc.body_b);
        let ka = self.bodies.hot(a).ok_or(WorldError::InvalidBody(a))?.kind;
        let kb = self.bodies.hot(b).ok_or(WorldError::InvalidBody(b))?.kind;
        if a == b {
            return Err(WorldError::InvalidJointParameter(format!(
                "joint {:?} joins body {a} to itself",
                desc.name
            )));
        }
        if ka != BodyKind::Dynamic && kb != BodyKind::Dynamic {
            return Err(WorldError::InvalidJointParameter(format!(
                "joint {:?}: at least one body must be dynamic",
                desc.name
            )));
        }
        validate(&desc)?;
        let mut desc = desc;
        for f in [&mut desc.frame_a, &mut desc.frame_b] {
            *f = Transform::new(f.translation, f.rotation.normalize());
        }
        self.joints.note_added(&desc);
        let touch = !desc.collide_connected;
        let h = JointHandle(self.joints.arena.insert(Joint {
            desc,
            impulses: JointImpulses::default(),
        }));
        self.joined_changed(a, b, touch);
        Ok(h)
    }

    /// Removes a joint; its bodies wake (and collide again).
    ///
    /// # Errors
    /// [`WorldError::InvalidJoint`] for a stale handle.
    pub fn remove_joint(&mut self, h: JointHandle) -> Result<(), WorldError> {
        let j = self
            .joints
            .arena
            .remove(h.0)
            .ok_or(WorldError::InvalidJoint(h))?;
        self.joints.note_removed(&j.desc);
        self.joined_changed(j.desc.body_a, j.desc.body_b, !j.desc.collide_connected);
        Ok(())
    }

    /// Wakes both bodies and, when their collision changed, makes the broad
    /// phase filter their pairs again.
    fn joined_changed(&mut self, a: BodyHandle, b: BodyHandle, touch: bool) {
        for body in [a, b] {
            if self.bodies.contains(body) {
                self.wake(body);
            }
            if touch && let Some(cold) = self.bodies.cold(body) {
                for c in &cold.colliders {
                    if let Some(col) = self.colliders.get(c.0) {
                        let _ = self.broad.touch_proxy(col.proxy);
                    }
                }
            }
        }
    }

    /// Removes every joint of a body (before the body goes).
    pub(crate) fn remove_joints_of(&mut self, body: BodyHandle) {
        let doomed: Vec<JointHandle> = self
            .joints
            .arena
            .iter()
            .filter(|(_, j)| j.desc.body_a == body || j.desc.body_b == body)
            .map(|(h, _)| JointHandle(h))
            .collect();
        for h in doomed {
            let _ = self.remove_joint(h);
        }
    }

    /// A joint.
    ///
    /// # Errors
    /// [`WorldError::InvalidJoint`] for a stale handle.
    pub fn joint(&self, h: JointHandle) -> Result<&Joint, WorldError> {
        self.joints
            .arena
            .get(h.0)
            .ok_or(WorldError::InvalidJoint(h))
    }

    /// Every joint with its handle, in handle order.
    pub fn joints(&self) -> impl Iterator<Item = (JointHandle, &Joint)> {
        self.joints.arena.iter().map(|(h, j)| (JointHandle(h), j))
    }

    /// The number of joints.
    pub fn joint_count(&self) -> usize {
        self.joints.arena.len()
    }

    /// Sets (or clears) a revolute or prismatic joint's motor; its bodies
    /// wake.
    ///
    /// # Errors
    /// [`WorldError::InvalidJoint`]; [`WorldError::InvalidJointParameter`]
    /// for another joint kind or a negative force.
    pub fn set_joint_motor(
        &mut self,
        h: JointHandle,
        motor: Option<Motor>,
    ) -> Result<(), WorldError> {
        let j = self
            .joints
            .arena
            .get_mut(h.0)
            .ok_or(WorldError::InvalidJoint(h))?;
        if motor.is_some_and(|m| m.max_force().is_negative()) {
            return Err(WorldError::InvalidJointParameter(
                "motor max force must not be negative".into(),
            ));
        }
        match &mut j.desc.kind {
            JointKind::Revolute { motor: m, .. } | JointKind::Prismatic { motor: m, .. } => {
                *m = motor;
            }
            other => {
                return Err(WorldError::InvalidJointParameter(format!(
                    "a {} joint has no motor",
                    other.name()
                )));
            }
        }
        j.impulses.axial[2] = Scalar::ZERO;
        let (a, b) = (j.desc.body_a, j.desc.body_b);
        self.joined_changed(a, b, false);
        Ok(())
    }

    /// The joint's two frames in world axes (A's, then B's).
    ///
    /// # Errors
    /// [`WorldError::InvalidJoint`].
    pub fn joint_frames(&self, h: JointHandle) -> Result<(Transform, Transform), WorldError> {
        let j = self.joint(h)?;
        let fa = self
            .body_origin(j.desc.body_a)
            .mul_transform(&j.desc.frame_a);
        let fb = self
            .body_origin(j.desc.body_b)
            .mul_transform(&j.desc.frame_b);
        Ok((fa, fb))
    }

    /// A revolute joint's angle or a spherical joint's twist (rad, B's frame
    /// about A's x axis, in (−π, π]); a prismatic joint's position (m, B's
    /// anchor along A's x axis); a distance joint's length (m); 0 for a
    /// fixed joint.
    ///
    /// # Errors
    /// [`WorldError::InvalidJoint`].
    pub fn joint_position(&self, h: JointHandle) -> Result<Scalar, WorldError> {
        let j = self.joint(h)?;
        let (fa, fb) = self.joint_frames(h)?;
        let d = fb.translation - fa.translation;
        Ok(match j.desc.kind {
            JointKind::Revolute { .. } | JointKind::Spherical { .. } => {
                crate::solver::joint_solver::twist_between(fa.rotation, fb.rotation)
            }
            JointKind::Prismatic { .. } => fa.rotation.rotate(crate::math::Vec3::X).dot(d),
            JointKind::Distance { .. } => d.length(),
            JointKind::Fixed => Scalar::ZERO,
        })
    }

    /// The constraint force (N) and torque (N·m) a joint carried in the last
    /// substep of the last step.
    ///
    /// # Errors
    /// [`WorldError::InvalidJoint`].
    pub fn joint_load(&self, h: JointHandle) -> Result<(Scalar, Scalar), WorldError> {
        let inv_h = Scalar::from_int((self.config.tick_rate * self.config.substeps) as i32);
        Ok(crate::solver::joint_solver::loads(self.joint(h)?, inv_h))
    }

    /// The joints that broke in the last step, in handle order.
    pub fn joint_events(&self) -> &[JointEvent] {
        &self.joint_events
    }

    /// After the substeps: joints past their force or torque threshold are
    /// removed and reported. Returns how many broke and whether the event
    /// list grew (an allocation).
    pub(crate) fn stage_break_joints(&mut self) -> (u32, bool) {
        self.joint_events.clear();
        let before = Capacities::of([&self.joint_events]);
        let inv_h = Scalar::from_int((self.config.tick_rate * self.config.substeps) as i32);
        let World {
            joints,
            joint_solver,
            joint_events,
            ..
        } = self;
        for (slot, force, torque) in joint_solver.over_threshold(&joints.arena, inv_h) {
            let Some(h) = joints.arena.handle_at(slot) else {
                continue;
            };
            let Some(j) = joints.arena.get(h) else {
                continue;
            };
            joint_events.push(JointEvent::Broken {
                joint: JointHandle(h),
                body_a: j.desc.body_a,
                body_b: j.desc.body_b,
                force,
                torque,
            });
        }
        let n = self.joint_events.len();
        for i in 0..n {
            let JointEvent::Broken { joint, .. } = self.joint_events[i];
            let _ = self.remove_joint(joint);
        }
        (
            n as u32,
            Capacities::of([&self.joint_events]).grew_since(&before),
        )
    }
}
