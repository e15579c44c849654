//! The world's joint set: the joints, the body pairs they keep from
//! colliding, and the check of a joint's parameters.

use serde::{Deserialize, Serialize};

use crate::arena::Arena;
use crate::body::BodyHandle;
use crate::hash::StateHasher;
use crate::joint::{Joint, JointDesc, JointKind, Motor};
use crate::math::Scalar;

use super::config::WorldError;

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

    pub(super) fn note_added(&mut self, d: &JointDesc) {
        if let Some(k) = JointSet::key(d) {
            let at = self.unpaired.partition_point(|x| *x <= k);
            self.unpaired.insert(at, k);
        }
    }

    pub(super) fn note_removed(&mut self, d: &JointDesc) {
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
            // Bit 0: collide connected; bit 1: rigid limits; bit 2: joint
            // friction (its torque follows the break thresholds, so a joint
            // without friction hashes as before friction existed).
            let friction = d.friction.is_positive();
            h.word(
                d.collide_connected as u64 | (d.rigid_limits as u64) << 1 | (friction as u64) << 2,
            );
            opt(h, d.break_force);
            opt(h, d.break_torque);
            if friction {
                h.scalar(d.friction);
            }
            h.vec3(j.impulses.linear);
            h.vec3(j.impulses.angular);
            for a in j.impulses.axial {
                h.scalar(a);
            }
        }
    }
}

/// Checks a joint's parameters.
pub(super) fn validate(d: &JointDesc) -> Result<(), WorldError> {
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
    let turns = matches!(
        d.kind,
        JointKind::Spherical { .. } | JointKind::Revolute { .. }
    );
    if d.friction.is_negative() || (!turns && !d.friction.is_zero()) {
        return bad(format!(
            "joint {name:?}: friction must be a torque ≥ 0, on a spherical or revolute joint"
        ));
    }
    for (what, v) in [("force", d.break_force), ("torque", d.break_torque)] {
        if v.is_some_and(|v| !v.is_positive()) {
            return bad(format!("joint {name:?}: break {what} must be positive"));
        }
    }
    Ok(())
}
