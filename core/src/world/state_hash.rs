//! The world's canonical state hash and per-body hashes (the algorithm is
//! specified word by word in `docs/determinism.md`).

use crate::body::{BodyCold, BodyHandle, BodyHot};
use crate::collider::MassSpec;
use crate::hash::{FieldKind, StateHasher};

use super::config::{ContactOrder, ContactRows, WorldError};
use super::state::World;

/// Version of the hashed layout; bumped whenever the list of hashed words
/// changes, so hashes from different layouts never compare equal by
/// accident.
pub const STATE_HASH_VERSION: u64 = 7;

impl World {
    /// The canonical hash of everything that influences later steps: the
    /// settings, the tick, every body's state and colliders, in handle
    /// order, the contact cache and the joints, from the raw bits. Equal hashes on two peers mean equal
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
        // Hashed only when it is not the default, so the hashes of worlds
        // built before the setting existed (recorded matches, golden files)
        // stay valid.
        if c.contact_order == ContactOrder::Colors {
            h.word(u64::from_le_bytes(*b"colours\0"));
        }
        if c.contact_rows == ContactRows::Narrow {
            h.word(u64::from_le_bytes(*b"narrow\0\0"));
        }
        h.word(self.bodies.len() as u64);
        for (handle, hot, cold) in self.bodies.iter() {
            h.word(handle.index() as u64);
            h.word(handle.generation() as u64);
            h.word(self.body_hash_of(hot, cold));
        }
        self.contacts.hash_into(&mut h);
        self.joints.hash_into(&mut h);
        // The game's own state, only when it has a field (a world whose
        // rules keep none hashes as before game state existed).
        if !self.game.is_empty() {
            h.word(u64::from_le_bytes(*b"game\0\0\0\0"));
            self.game.hash_into(&mut h);
        }
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
        let mut h = HashSink(StateHasher::new());
        self.visit_body(b, cold, &mut h);
        h.0.finish()
    }

    /// Every hashed field of one body, in hash order, with its raw words:
    /// exactly the words its body hash is made of (so two peers whose body
    /// hashes differ differ in at least one of these). Then the body's
    /// contacts: the state of every contact pair one of its colliders
    /// carries, as the world hash holds them.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`](WorldError::InvalidBody) for a
    /// stale handle.
    pub fn body_fields(&self, handle: BodyHandle) -> Result<Vec<BodyField>, WorldError> {
        let (Some(hot), Some(cold)) = (self.bodies.hot(handle), self.bodies.cold(handle)) else {
            return Err(WorldError::InvalidBody(handle));
        };
        let mut out = FieldList(Vec::new());
        self.visit_body(hot, cold, &mut out);
        self.contacts
            .visit_pairs_of(&cold.colliders, &mut |name, kind, words| {
                out.0.push(BodyField {
                    name,
                    kind,
                    words: words.to_vec(),
                });
            });
        Ok(out.0)
    }

    /// The hash of the contact state alone (the part of
    /// [`state_hash`](World::state_hash) after the bodies): when two peers'
    /// body hashes all agree but their world hashes do not, this names the
    /// contact cache as the difference.
    pub fn contacts_hash(&self) -> u64 {
        let mut h = StateHasher::new();
        self.contacts.hash_into(&mut h);
        h.finish()
    }

    /// Feeds `sink` every hashed field of a body, in hash order.
    fn visit_body(&self, b: &BodyHot, cold: &BodyCold, sink: &mut impl FieldSink) {
        use FieldKind::{Int, Scalar as Q, Word};
        let s = |v: crate::math::Scalar| v.to_bits() as u64;
        let v3 = |v: crate::math::Vec3| [s(v.x), s(v.y), s(v.z)];
        let tr = |t: &crate::math::Transform| {
            let (p, q) = (t.translation, t.rotation);
            [s(p.x), s(p.y), s(p.z), s(q.x), s(q.y), s(q.z), s(q.w)]
        };
        let sym = |m: &crate::math::SymMat3| [m.xx, m.yy, m.zz, m.xy, m.xz, m.yz].map(s);
        let q = b.rotation;
        sink.field(FieldName::Body("kind"), Word, &[b.kind.code()]);
        let flags = b.sleeping as u64 | (b.isotropic as u64) << 1 | (b.bullet as u64) << 2;
        sink.field(
            FieldName::Body("flags (sleeping, isotropic, bullet)"),
            Word,
            &[flags],
        );
        sink.field(FieldName::Body("center_of_mass"), Q, &v3(b.center));
        sink.field(
            FieldName::Body("rotation (x, y, z, w)"),
            Q,
            &[s(q.x), s(q.y), s(q.z), s(q.w)],
        );
        sink.field(
            FieldName::Body("linear_velocity"),
            Q,
            &v3(b.linear_velocity),
        );
        sink.field(
            FieldName::Body("angular_velocity"),
            Q,
            &v3(b.angular_velocity),
        );
        sink.field(
            FieldName::Body("angular_momentum"),
            Q,
            &v3(b.angular_momentum),
        );
        sink.field(FieldName::Body("force"), Q, &v3(b.force));
        sink.field(FieldName::Body("torque"), Q, &v3(b.torque));
        sink.field(FieldName::Body("inv_mass"), Q, &[s(b.inv_mass)]);
        sink.field(FieldName::Body("inertia"), Q, &sym(&b.inertia));
        sink.field(FieldName::Body("inv_inertia"), Q, &sym(&b.inv_inertia));
        sink.field(FieldName::Body("linear_damping"), Q, &[s(b.linear_damping)]);
        sink.field(
            FieldName::Body("angular_damping"),
            Q,
            &[s(b.angular_damping)],
        );
        sink.field(FieldName::Body("gravity_scale"), Q, &[s(b.gravity_scale)]);
        sink.field(
            FieldName::Body("sleep_timer (rest ticks)"),
            Word,
            &[b.rest_ticks as u64],
        );
        sink.field(FieldName::Body("local_center"), Q, &v3(cold.local_center));
        sink.field(FieldName::Body("mass"), Q, &[s(cold.mass)]);
        sink.field(
            FieldName::Body("mass_override"),
            Word,
            &[cold.mass_override as u64],
        );
        match &cold.kinematic_target {
            Some(t) => {
                sink.field(FieldName::Body("kinematic_target set"), Word, &[1]);
                sink.field(FieldName::Body("kinematic_target"), Q, &tr(t));
            }
            None => sink.field(FieldName::Body("kinematic_target set"), Word, &[0]),
        }
        // The game's value for the body, only when set (a world that never
        // sets one hashes as before it was hashed).
        if cold.user_data != 0 {
            sink.field(FieldName::Body("user_data"), Word, &[cold.user_data]);
        }
        sink.field(
            FieldName::Body("collider count"),
            Word,
            &[cold.colliders.len() as u64],
        );
        for (i, ch) in cold.colliders.iter().enumerate() {
            let handle = [ch.0.index as u64, ch.0.generation as u64];
            sink.field(FieldName::Collider(i, "handle"), Word, &handle);
            let Some(c) = self.colliders.get(ch.0) else {
                sink.field(FieldName::Collider(i, "missing"), Word, &[u64::MAX]);
                continue;
            };
            sink.field(FieldName::Collider(i, "local_pose"), Q, &tr(&c.local_pose));
            match c.mass_spec {
                MassSpec::Density(d) => {
                    sink.field(FieldName::Collider(i, "mass_spec kind"), Word, &[0]);
                    sink.field(FieldName::Collider(i, "density"), Q, &[s(d)]);
                }
                MassSpec::Mass(m) => {
                    sink.field(FieldName::Collider(i, "mass_spec kind"), Word, &[1]);
                    sink.field(FieldName::Collider(i, "mass"), Q, &[s(m)]);
                }
            }
            sink.field(
                FieldName::Collider(i, "friction"),
                Q,
                &[s(c.material.friction)],
            );
            sink.field(
                FieldName::Collider(i, "restitution"),
                Q,
                &[s(c.material.restitution)],
            );
            let (cat, mask) = (c.filter.category as u64, c.filter.mask as u64);
            sink.field(
                FieldName::Collider(i, "filter category, mask"),
                Word,
                &[cat, mask],
            );
            sink.field(
                FieldName::Collider(i, "filter group"),
                Int,
                &[c.filter.group as i64 as u64],
            );
            sink.field(
                FieldName::Collider(i, "is_trigger"),
                Word,
                &[c.is_trigger as u64],
            );
            sink.field(FieldName::Collider(i, "shape_hash"), Word, &[c.shape_hash]);
        }
    }
}

/// One field of a body's state as its hash sees it: a name, how to read it,
/// and its raw words.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BodyField {
    /// What it is, e.g. `linear_velocity` or `collider[0] friction`.
    pub name: String,
    /// How its words read.
    pub kind: FieldKind,
    /// The raw words, in hash order.
    pub words: Vec<u64>,
}

/// A field's name without allocating (the hashing path never formats).
enum FieldName {
    Body(&'static str),
    Collider(usize, &'static str),
}

impl FieldName {
    fn text(&self) -> String {
        match self {
            FieldName::Body(n) => (*n).to_owned(),
            FieldName::Collider(i, n) => format!("collider[{i}] {n}"),
        }
    }
}

/// Receives a body's fields in hash order.
trait FieldSink {
    fn field(&mut self, name: FieldName, kind: FieldKind, words: &[u64]);
}

/// Hashes the words, as the body hash always did.
struct HashSink(StateHasher);

impl FieldSink for HashSink {
    #[inline(always)]
    fn field(&mut self, _: FieldName, _: FieldKind, words: &[u64]) {
        for &w in words {
            self.0.word(w);
        }
    }
}

/// Collects the fields for a dump.
struct FieldList(Vec<BodyField>);

impl FieldSink for FieldList {
    fn field(&mut self, name: FieldName, kind: FieldKind, words: &[u64]) {
        self.0.push(BodyField {
            name: name.text(),
            kind,
            words: words.to_vec(),
        });
    }
}
