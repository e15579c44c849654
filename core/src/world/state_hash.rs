//! The world's canonical state hash and per-body hashes (the algorithm is
//! specified word by word in `docs/determinism.md`).

use crate::body::{BodyCold, BodyHandle, BodyHot};
use crate::collider::MassSpec;
use crate::hash::StateHasher;

use super::World;

/// Version of the hashed layout; bumped whenever the list of hashed words
/// changes, so hashes from different layouts never compare equal by
/// accident.
pub const STATE_HASH_VERSION: u64 = 7;

impl World {
    /// The canonical hash of everything that influences later steps: the
    /// settings, the tick, and every body's state and colliders, in handle
    /// order, from the raw bits. Equal hashes on two peers mean equal
    /// simulations (up to 2⁻⁶⁴ chance).
    ///
    /// Two worlds built and stepped the same way have the same hash; a
    /// difference in their state, down to one bit, shows:
    ///
    /// ```
    /// use lockstep_core::{BodyDesc, ColliderDesc, Scalar, Vec3, World, WorldConfig, scalar};
    ///
    /// let build = || -> Result<_, lockstep_core::WorldError> {
    ///     let mut world = World::new(WorldConfig::default())?;
    ///     let ball = world.create_body(&BodyDesc::dynamic().position(Vec3::from_ints(0, 3, 0)))?;
    ///     world.add_collider(ball, ColliderDesc::sphere(scalar!(0.5)))?;
    ///     Ok((world, ball))
    /// };
    /// let ((mut a, _), (mut b, ball)) = (build()?, build()?);
    /// for _ in 0..60 {
    ///     a.step();
    ///     b.step();
    /// }
    /// assert_eq!(a.state_hash(), b.state_hash());
    ///
    /// // 2⁻³² m/s more on one ball.
    /// let v = b.body(ball)?.linear_velocity();
    /// b.set_linear_velocity(ball, v + Vec3::new(Scalar::DELTA, Scalar::ZERO, Scalar::ZERO))?;
    /// assert_ne!(a.state_hash(), b.state_hash());
    /// # Ok::<(), lockstep_core::WorldError>(())
    /// ```
    pub fn state_hash(&self) -> u64 {
        let mut h = StateHasher::new();
        h.word(STATE_HASH_VERSION);
        h.word(self.tick);
        let c = &self.config;
        h.vec3(c.gravity);
        h.word(c.tick_rate as u64);
        h.word(c.substeps as u64);
        h.word(c.sleep.enabled as u64);
        h.scalar(c.sleep.linear_threshold);
        h.scalar(c.sleep.angular_threshold);
        h.scalar(c.sleep.time_to_sleep);
        h.scalar(c.contact_margin);
        h.scalar(c.broad_phase_margin);
        h.word(c.solver_iterations as u64);
        h.word(c.relax_iterations as u64);
        h.scalar(c.contact_hertz);
        h.scalar(c.contact_damping_ratio);
        h.scalar(c.max_push_out);
        h.scalar(c.restitution_threshold);
        h.word(self.bodies.len() as u64);
        for (handle, hot, cold) in self.bodies.iter() {
            h.word(handle.index() as u64);
            h.word(handle.generation() as u64);
            h.word(self.body_hash_of(hot, cold));
        }
        self.contacts.hash_into(&mut h);
        h.finish()
    }

    /// One hash per body, in handle order: comparing two peers' lists names
    /// the bodies that diverged.
    pub fn body_hashes(&self) -> Vec<(BodyHandle, u64)> {
        self.bodies
            .iter()
            .map(|(handle, hot, cold)| (handle, self.body_hash_of(hot, cold)))
            .collect()
    }

    fn body_hash_of(&self, b: &BodyHot, cold: &BodyCold) -> u64 {
        let mut h = StateHasher::new();
        h.word(b.kind.code());
        h.word(b.sleeping as u64 | (b.isotropic as u64) << 1 | (b.bullet as u64) << 2);
        h.vec3(b.center);
        h.quat(b.rotation);
        h.vec3(b.linear_velocity);
        h.vec3(b.angular_velocity);
        h.vec3(b.angular_momentum);
        h.vec3(b.force);
        h.vec3(b.torque);
        h.scalar(b.inv_mass);
        h.sym(&b.inertia);
        h.sym(&b.inv_inertia);
        h.scalar(b.linear_damping);
        h.scalar(b.angular_damping);
        h.scalar(b.gravity_scale);
        h.word(b.rest_ticks as u64);
        h.vec3(cold.local_center);
        h.scalar(cold.mass);
        h.word(cold.mass_override as u64);
        match &cold.kinematic_target {
            Some(t) => {
                h.word(1);
                h.transform(t);
            }
            None => h.word(0),
        }
        h.word(cold.colliders.len() as u64);
        for ch in &cold.colliders {
            h.word(ch.0.index as u64);
            h.word(ch.0.generation as u64);
            let Some(c) = self.colliders.get(ch.0) else {
                h.word(u64::MAX);
                continue;
            };
            h.transform(&c.local_pose);
            match c.mass_spec {
                MassSpec::Density(d) => {
                    h.word(0);
                    h.scalar(d);
                }
                MassSpec::Mass(m) => {
                    h.word(1);
                    h.scalar(m);
                }
            }
            h.scalar(c.material.friction);
            h.scalar(c.material.restitution);
            h.word(c.filter.category as u64);
            h.word(c.filter.mask as u64);
            h.int(c.filter.group as i64);
            h.word(c.is_trigger as u64);
            h.word(c.shape_hash);
        }
        h.finish()
    }
}
