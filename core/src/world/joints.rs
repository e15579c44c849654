//! The world's joints: adding, removing and reading them, the bodies they
//! keep from colliding, and the step's joint work outside the solver
//! (breaking, waking).

use serde::{Deserialize, Serialize};

use crate::arena::Arena;
use crate::body::{BodyHandle, BodyKind};
use crate::hash::StateHasher;
use crate::joint::{Joint, JointDesc, JointEvent, JointHandle, JointImpulses, JointKind, Motor};
use crate::math::{Scalar, Transform};

use super::{World, WorldError};

/// The joints of a world.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub(crate) struct JointSet {
    pub(crate) arena: Arena<Joint>,
    /// Derived: the body pairs (lower handle first) joined by a joint that
    /// does not let them collide, sorted, one entry per joint.
    #[serde(skip)]
    unpaired: Vec<(BodyHandle, BodyHandle)>,
}

impl JointSet {
    /// Whether a joint keeps `a` and `b` from colliding.
    pub(crate) fn blocks(&self, a: BodyHandle, b: BodyHandle) -> bool {
        if self.unpaired.is_empty() {
            return false;
        }
        let key = if a < b { (a, b) } else { (b, a) };
        self.unpaired.binary_search(&key).is_ok()
    }

    fn key(d: &JointDesc) -> Option<(BodyHandle, BodyHandle)> {
        if d.collide_connected {
            return None;
        }
        let (a, b) = (d.body_a, d.body_b);
        Some(if a < b { (a, b) } else { (b, a) })
    }

    fn note_added(&mut self, d: &JointDesc) {
        if let Some(k) = JointSet::key(d) {
            let at = self.unpaired.partition_point(|x| *x <= k);
            self.unpaired.insert(at, k);
        }
    }

    fn note_removed(&mut self, d: &JointDesc) {
        if let Some(k) = JointSet::key(d)
            && let Ok(at) = self.unpaired.binary_search(&k)
        {
            self.unpaired.remove(at);
        }
    }

    /// Rebuilds the derived list (after a snapshot is decoded).
    pub(crate) fn rebuild(&mut self) {
        self.unpaired = self
            .arena
            .iter()
            .filter_map(|(_, j)| JointSet::key(&j.desc))
            .collect();
        self.unpaired.sort_unstable();
    }

    /// Feeds the joints to the state hash: nothing for a world that never
    /// had a joint (so its hash is as it was before joints existed);
    /// otherwise the slot count, the live count, and per live joint in
    /// handle order its handle, kind and parameters, bodies, frames, flags,
    /// thresholds and accumulated impulses (see docs/determinism.md).
    pub(crate) fn hash_into(&self, h: &mut StateHasher) {
        if self.arena.slot_count() == 0 {
            return;
        }
        h.word(self.arena.slot_count() as u64);
        h.word(self.arena.len() as u64);
        let opt = |h: &mut StateHasher, v: Option<Scalar>| match v {
            Some(v) => {
                h.word(1);
                h.scalar(v);
            }
            None => h.word(0),
        };
        let range = |h: &mut StateHasher, v: Option<(Scalar, Scalar)>| match v {
            Some((lo, hi)) => {
                h.word(1);
                h.scalar(lo);
                h.scalar(hi);
            }
            None => h.word(0),
        };
        let motor = |h: &mut StateHasher, m: Option<Motor>| match m {
            Some(Motor::Speed { speed, max_force }) => {
                h.word(1);
                h.scalar(speed);
                h.scalar(max_force);
            }
            Some(Motor::Position { target, max_force }) => {
                h.word(2);
                h.scalar(target);
                h.scalar(max_force);
            }
            None => h.word(0),
        };
        for (handle, j) in self.arena.iter() {
            let d = &j.desc;
            h.word(handle.index as u64);
            h.word(handle.generation as u64);
            h.word(d.kind.code());
            match d.kind {
                JointKind::Spherical { cone, twist } => {
                    opt(h, cone);
                    range(h, twist);
                }
                JointKind::Revolute { limits, motor: m }
                | JointKind::Prismatic { limits, motor: m } => {
                    range(h, limits);
                    motor(h, m);
                }
                JointKind::Fixed => {}
                JointKind::Distance {
                    length,
                    min,
                    max,
                    spring,
                } => {
                    h.scalar(length);
                    h.scalar(min);
                    h.scalar(max);
                    match spring {
                        Some(s) => {
                            h.word(1);
                            h.scalar(s.hertz);
                            h.scalar(s.damping_ratio);
                        }
                        None => h.word(0),
                    }
                }
            }
            for b in [d.body_a, d.body_b] {
                h.word(b.index() as u64);
                h.word(b.generation() as u64);
            }
            h.transform(&d.frame_a);
            h.transform(&d.frame_b);
            h.word(d.collide_connected as u64);
            opt(h, d.break_force);
            opt(h, d.break_torque);
            h.vec3(j.impulses.linear);
            h.vec3(j.impulses.angular);
            for a in j.impulses.axial {
                h.scalar(a);
            }
        }
    }
}

/// Checks a joint's parameters.
fn validate(d: &JointDesc) -> Result<(), WorldError> {
    let bad = |m: String| Err(WorldError::InvalidJointParameter(m));
    let name = &d.name;
    let limits = |l: Option<(Scalar, Scalar)>, what: &str| match l {
        Some((lo, hi)) if lo > hi => bad(format!(
            "joint {name:?}: {what} lower limit {lo} is above the upper {hi}"
        )),
        _ => Ok(()),
    };
    let motor = |m: Option<Motor>| match m {
        Some(m) if m.max_force().is_negative() => bad(format!(
            "joint {name:?}: motor max force must not be negative"
        )),
        _ => Ok(()),
    };
    match d.kind {
        JointKind::Spherical { cone, twist } => {
            if cone.is_some_and(|c| c.is_negative() || c > Scalar::PI) {
                return bad(format!("joint {name:?}: cone angle must be in [0, π]"));
            }
            limits(twist, "twist")?;
        }
        JointKind::Revolute {
            limits: l,
            motor: m,
        } => {
            limits(l, "angle")?;
            motor(m)?;
        }
        JointKind::Prismatic {
            limits: l,
            motor: m,
        } => {
            limits(l, "position")?;
            motor(m)?;
        }
        JointKind::Fixed => {}
        JointKind::Distance {
            length,
            min,
            max,
            spring,
        } => {
            if min.is_negative() || min > max || length.is_negative() {
                return bad(format!(
                    "joint {name:?}: distance needs 0 ≤ min ≤ max and a length ≥ 0 (min {min}, length {length}, max {max})"
                ));
            }
            if spring.is_none() && !length.is_positive() {
                return bad(format!(
                    "joint {name:?}: a rigid distance needs a positive length"
                ));
            }
            if spring.is_some_and(|s| s.hertz.is_negative() || s.damping_ratio.is_negative()) {
                return bad(format!(
                    "joint {name:?}: spring frequency and damping must not be negative"
                ));
            }
        }
    }
    for (what, v) in [("force", d.break_force), ("torque", d.break_torque)] {
        if v.is_some_and(|v| !v.is_positive()) {
            return bad(format!("joint {name:?}: break {what} must be positive"));
        }
    }
    Ok(())
}

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
        let cap = self.joint_events.capacity();
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
        (n as u32, self.joint_events.capacity() != cap)
    }
}
