//! Scratch of the narrow phase: the world pose of every collider of a
//! moving body, with its rotation as a matrix, worked out once per step
//! instead of once per pair.
//!
//! A box in a pyramid touches up to ten others, and before this table each
//! of its pairs looked the collider and its body up, composed the body's
//! pose with the collider's, and turned the rotation into a matrix again.
//! The table holds the same values, computed the same way (so every result
//! is the same, bit for bit), once per collider.
//!
//! Only the colliders of the bodies the step moves (the awake list) are in
//! the table: a pair's other collider may be on a static or sleeping body,
//! and [`ColliderPoses::pose`] works that one out on the spot. An entry
//! holds for the narrow phase that filled it: a stamp per entry says which,
//! so nothing is cleared between steps.
//!
//! Not simulation state: derived from the bodies at the start of each
//! narrow phase, never hashed or saved.

use crate::arena::Arena;
use crate::body::BodySet;
use crate::collider::{Collider, ColliderHandle};
use crate::collision::reuse::PoseAndMatrix;
use crate::math::{Mat3, Transform, Vec3};

/// A collider's world pose, the rotation as a matrix, and its body's
/// linear velocity.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ColliderPose {
    /// The collider's pose in the world.
    pub pose: Transform,
    /// `Mat3::from_quat(pose.rotation)`.
    pub rotation: Mat3,
    /// The body's linear velocity (for the speculative distance).
    pub velocity: Vec3,
}

impl ColliderPose {
    /// Works the pose out from the collider and its body, as the table
    /// does.
    fn of(bodies: &BodySet, c: &Collider) -> Option<ColliderPose> {
        let hot = bodies.hot(c.body)?;
        let cold = bodies.cold(c.body)?;
        let pose = c.world_pose(&hot.origin_pose(cold.local_center));
        Some(ColliderPose {
            pose,
            rotation: Mat3::from_quat(pose.rotation),
            velocity: hot.linear_velocity,
        })
    }
}

impl PoseAndMatrix for ColliderPose {
    fn pose_and_matrix(&self) -> (Transform, Mat3) {
        (self.pose, self.rotation)
    }
}

/// One slot of the table: a pose, valid while `stamp` is the table's.
#[derive(Clone, Copy, Debug)]
struct Entry {
    stamp: u32,
    pose: ColliderPose,
}

/// The table (see the module docs), indexed by collider slot.
#[derive(Clone, Debug, Default)]
pub(crate) struct ColliderPoses {
    /// The current fill's stamp; 0 is never one.
    stamp: u32,
    entries: Vec<Entry>,
}

impl PartialEq for ColliderPoses {
    /// Always equal: scratch.
    fn eq(&self, _: &ColliderPoses) -> bool {
        true
    }
}

impl Eq for ColliderPoses {}

impl ColliderPoses {
    /// Fills the table for the colliders of the awake bodies. Returns 1 if
    /// the table had to grow (an allocation in the step: colliders were
    /// added since the last fill), else 0.
    ///
    /// Determinism: every entry is a pure function of its collider and
    /// body, so the order of the walk does not matter.
    pub(crate) fn fill(&mut self, bodies: &BodySet, colliders: &Arena<Collider>) -> u32 {
        if self.stamp == u32::MAX {
            for e in &mut self.entries {
                e.stamp = 0;
            }
            self.stamp = 0;
        }
        self.stamp += 1;
        let mut grew = 0;
        for k in 0..bodies.awake_len() {
            let Some((h, _)) = bodies.awake_at(k) else {
                continue;
            };
            let Some(cold) = bodies.cold(h) else {
                continue;
            };
            for ch in &cold.colliders {
                let Some(c) = colliders.get(ch.0) else {
                    continue;
                };
                let Some(pose) = ColliderPose::of(bodies, c) else {
                    continue;
                };
                let i = ch.0.index as usize;
                if i >= self.entries.len() {
                    if i >= self.entries.capacity() {
                        grew = 1;
                    }
                    let blank = Entry {
                        stamp: 0,
                        pose: ColliderPose {
                            pose: Transform::IDENTITY,
                            rotation: Mat3::IDENTITY,
                            velocity: Vec3::ZERO,
                        },
                    };
                    self.entries.resize(i + 1, blank);
                }
                self.entries[i] = Entry {
                    stamp: self.stamp,
                    pose,
                };
            }
        }
        grew
    }

    /// The collider and its pose: from the table if this fill holds it,
    /// else worked out now (the same values).
    pub(crate) fn pose<'a>(
        &self,
        bodies: &BodySet,
        colliders: &'a Arena<Collider>,
        ch: ColliderHandle,
    ) -> Option<(&'a Collider, ColliderPose)> {
        let c = colliders.get(ch.0)?;
        match self.entries.get(ch.0.index as usize) {
            Some(e) if e.stamp == self.stamp => Some((c, e.pose)),
            _ => Some((c, ColliderPose::of(bodies, c)?)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::BodyDesc;
    use crate::collider::ColliderDesc;
    use crate::math::{Quat, Scalar};
    use crate::world::{World, WorldConfig};

    /// Every collider's pose from the table is the one worked out on the
    /// spot: awake bodies from the table, a static one on the spot, and a
    /// collider offset and turned on its body.
    #[test]
    fn the_table_gives_the_same_poses_as_working_them_out() {
        let one = Scalar::ONE;
        let mut w = World::new(WorldConfig::default()).unwrap();
        let ground = w.create_body(&BodyDesc::fixed()).unwrap();
        let ten = Scalar::from_int(10);
        let g = w
            .add_collider(ground, ColliderDesc::cuboid(ten, one, ten))
            .unwrap();
        let q = Quat::from_axis_angle(Vec3::Y, Scalar::from_ratio(1, 3));
        let body = w
            .create_body(
                &BodyDesc::dynamic()
                    .position(Vec3::from_ints(1, 3, -2))
                    .rotation(q),
            )
            .unwrap();
        let offset = Transform::new(Vec3::from_ints(0, 1, 0), q);
        let c1 = w
            .add_collider(body, ColliderDesc::cuboid(one, one, one))
            .unwrap();
        let c2 = w
            .add_collider(body, ColliderDesc::cuboid(one, one, one).local_pose(offset))
            .unwrap();
        w.step();
        let mut table = ColliderPoses::default();
        assert_eq!(table.fill(&w.bodies, &w.colliders), 1);
        for ch in [g, c1, c2] {
            let (c, got) = table.pose(&w.bodies, &w.colliders, ch).unwrap();
            let want = ColliderPose::of(&w.bodies, c).unwrap();
            assert_eq!(got.pose, want.pose);
            assert_eq!(got.rotation, want.rotation);
            assert_eq!(got.velocity, want.velocity);
        }
        // The static ground is not in the table; the moving body's
        // colliders are.
        let stamp = table.stamp;
        assert!(
            table
                .entries
                .get(g.0.index as usize)
                .is_none_or(|e| e.stamp != stamp)
        );
        assert_eq!(table.entries[c2.0.index as usize].stamp, stamp);
        // A second fill needs no growth.
        assert_eq!(table.fill(&w.bodies, &w.colliders), 0);
    }
}
