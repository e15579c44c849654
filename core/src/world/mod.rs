//! The `World`: bodies, colliders, settings, and the step that advances them.

mod awake;
use awake::Toucher;
mod body_ref;
mod ccd;
mod collide;
mod config;
mod joints;
mod observe;
mod poses;
mod query;
mod state_hash;
mod step;

pub use crate::hash::FieldKind;
pub use crate::solver::integrate::max_angular_speed;
pub use crate::solver::sleep::SleepConfig;
pub use crate::workers::MAX_WORKERS;
use crate::workers::Workers;
pub use body_ref::BodyRef;
pub use ccd::{CCD_MAX_ITERATIONS, CCD_TARGET_GAP, CCD_TOLERANCE};
pub use config::{
    ContactOrder, ContactRows, MAX_SOLVER_ITERATIONS, MAX_SUBSTEPS, MAX_TICK_RATE, StepReport,
    WorldConfig, WorldError,
};
pub use observe::{Stage, StepObserver};
pub use state_hash::{BodyField, STATE_HASH_VERSION};

use serde::{Deserialize, Serialize};

use crate::arena::Arena;
use crate::body::{BodyCold, BodyDesc, BodyHandle, BodyHot, BodyKind, BodySet};
use crate::collider::{Collider, ColliderDesc, ColliderHandle, MassSpec};
use crate::collision::{BroadPhase, ContactEvent, ContactPair, ContactSet, ProxyId, ProxyKey};
use crate::math::{FaultScope, Faults, Quat, Scalar, SymMat3, Transform, Vec3};
use crate::shape::MassProperties;
use crate::solver::contact_solver::ContactSolver;
use crate::solver::integrate::{momentum_from_omega, omega_from_momentum};
use crate::solver::sleep::IslandScratch;

/// A physics world: everything one simulation needs, and nothing global.
///
/// Determinism: every operation visits bodies and colliders in handle
/// order; the same sequence of calls gives the same state, bit for bit, on
/// every platform. [`World::state_hash`] summarises that state.
///
/// A ball dropped on the ground comes to rest on it:
///
/// ```
/// use lockstep_core::{BodyDesc, ColliderDesc, Vec3, World, WorldConfig, scalar};
///
/// let mut world = World::new(WorldConfig::default())?; // 60 Hz, gravity −9.81 m/s² on y
/// // A static ground whose top face is y = 0.
/// let ground = world.create_body(&BodyDesc::fixed().position(Vec3::new(
///     scalar!(0),
///     scalar!(-0.5),
///     scalar!(0),
/// )))?;
/// world.add_collider(ground, ColliderDesc::cuboid(scalar!(20), scalar!(0.5), scalar!(20)))?;
/// // A ball of radius 0.5 m, 2 m up.
/// let ball = world.create_body(&BodyDesc::dynamic().position(Vec3::from_ints(0, 2, 0)))?;
/// world.add_collider(ball, ColliderDesc::sphere(scalar!(0.5)))?;
///
/// for _ in 0..120 {
///     let report = world.step();
///     assert!(!report.overflowed());
/// }
/// assert_eq!(world.tick(), 120);
/// let y = world.body(ball)?.position().y; // resting: one radius above the ground
/// assert!((y - scalar!(0.5)).abs() < scalar!(0.005), "{y}");
/// # Ok::<(), lockstep_core::WorldError>(())
/// ```
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct World {
    config: WorldConfig,
    tick: u64,
    bodies: BodySet,
    colliders: Arena<Collider>,
    broad: BroadPhase,
    contacts: ContactSet,
    faults: Faults,
    joints: joints::JointSet,
    /// The game's own state (see [`crate::game_state`]).
    game: crate::game_state::GameState,
    /// The joints that broke in the last step (an output, not state).
    #[serde(skip)]
    joint_events: Vec<crate::joint::JointEvent>,
    /// Scratch: this tick's joints for the solver (reused every step).
    #[serde(skip)]
    joint_solver: crate::solver::joint_solver::JointSolver,
    /// Scratch: the broad phase's candidate pairs (reused every step).
    #[serde(skip)]
    candidates: Vec<(ProxyKey, ProxyKey)>,
    /// Scratch: the contact solver's bodies and constraints (reused every
    /// step).
    #[serde(skip)]
    solver: ContactSolver,
    /// The threads a step splits its work over (the narrow phase, the
    /// integrators, the contact solver's set-up and colour passes). Not
    /// simulation state: any count gives the same bits.
    #[serde(skip)]
    workers: Workers,
    /// Scratch: the sleep stage's union–find (reused every step).
    #[serde(skip)]
    islands: IslandScratch,
    /// Scratch: continuous collision's start poses and candidate lists
    /// (reused every step).
    #[serde(skip)]
    ccd: ccd::CcdScratch,
    /// Scratch: the colliders' world poses for the narrow phase (filled
    /// every step).
    #[serde(skip)]
    poses: poses::ColliderPoses,
}

impl PartialEq for World {
    /// Two worlds are equal when their snapshots are: the same state, bit
    /// for bit, including the broad phase's trees (scratch excluded).
    fn eq(&self, other: &World) -> bool {
        self.snapshot() == other.snapshot()
    }
}

impl Eq for World {}

impl World {
    /// An empty world.
    ///
    /// # Errors
    /// [`WorldError::InvalidConfig`] if a setting is out of range.
    pub fn new(config: WorldConfig) -> Result<World, WorldError> {
        config.validate()?;
        let mut world = World {
            config,
            tick: 0,
            bodies: BodySet::default(),
            colliders: Arena::default(),
            broad: BroadPhase::new(config.broad_phase_margin),
            contacts: ContactSet::default(),
            faults: Faults::NONE,
            joints: joints::JointSet::default(),
            game: crate::game_state::GameState::default(),
            joint_events: Vec::new(),
            joint_solver: Default::default(),
            candidates: Vec::new(),
            solver: ContactSolver::default(),
            workers: Workers::default(),
            islands: IslandScratch::default(),
            ccd: ccd::CcdScratch::default(),
            poses: poses::ColliderPoses::default(),
        };
        // An index that describes the (empty) set from the start, so counts
        // are exact before the first step.
        world.refresh_awake_set();
        Ok(world)
    }

    /// The settings.
    pub fn config(&self) -> &WorldConfig {
        &self.config
    }

    /// Sets how many threads (this one included, clamped to
    /// `1..=MAX_WORKERS`) a step uses: in either contact order for the
    /// narrow phase, the integrators and the contact solver's per-body and
    /// per-constraint set-up, and in colour order
    /// ([`ContactOrder::Colors`]) for the solver passes too (in pair order
    /// they run on this thread). The threads start here, not in `step()`,
    /// and wait between steps (spinning briefly, then parked).
    ///
    /// Not simulation state: every count gives the same bits (each piece of
    /// shared work writes only its own pair, body or constraint; the
    /// constraints of one colour share no moving body; nothing but integer
    /// counters is summed across threads), so peers may use different
    /// counts, and the
    /// count is in neither the state hash nor snapshots: a restored world
    /// has one worker until this is called, a clone as many as the world
    /// it was cloned from.
    pub fn set_workers(&mut self, count: usize) {
        if count.clamp(1, MAX_WORKERS) != self.workers.count() {
            self.workers = Workers::new(count);
        }
    }

    /// Turns the solver's exact wide lanes on (`true`) or off (the
    /// default). On an x86_64 CPU with AVX-512 IFMA, found at run time,
    /// the normal rows of contact constraints in colour order
    /// ([`ContactOrder::Colors`]) then run eight constraints at a time on
    /// the lanes, with exactly the bits of the scalar rows (see
    /// [`StepReport::wide_batches`]); elsewhere the scalar rows run.
    ///
    /// Off by default because they do not pay yet: on the CPUs measured so
    /// far the lanes' rows cost about what the scalar rows cost, and
    /// gathering eight constraints into them made a step a few percent
    /// slower (figures in docs/engines.md).
    ///
    /// Not simulation state, like the worker count: peers with and without
    /// the lanes compute the same bits, and the setting is in neither the
    /// state hash nor snapshots (a restored world has them off).
    ///
    /// Only with the `wide` cargo feature: an experiment, not a setting a
    /// game needs.
    #[cfg(feature = "wide")]
    pub fn set_wide(&mut self, on: bool) {
        self.solver.set_wide(on);
    }

    /// Whether steps use the wide lanes: turned on and present on this CPU
    /// (see [`World::set_wide`]; only with the `wide` feature).
    #[cfg(feature = "wide")]
    pub fn wide(&self) -> bool {
        self.solver.wide()
    }

    /// Turns the narrow contact rows' SIMD lanes on (`true`) or off (the
    /// default). With [`ContactRows::Narrow`] in colour order
    /// ([`ContactOrder::Colors`]), eight constraints of one colour with the
    /// same point count then go through the rows together on the widest
    /// lanes this CPU has (AVX-512 or AVX2 on x86_64, found at run time;
    /// see [`StepReport::lane_batches`]); elsewhere the scalar rows run.
    ///
    /// Off by default because they do not pay yet: on the CPU measured so
    /// far (docs/engines.md) the passes took about twice as long on the
    /// lanes as on the scalar rows, their time going to loading eight
    /// constraints' constants and state.
    ///
    /// Not simulation state: the lanes compute the scalar rows' bits, so
    /// the setting is in neither the state hash nor snapshots (a restored
    /// world has them off).
    pub fn set_lanes(&mut self, on: bool) {
        self.solver.set_lanes(on);
    }

    /// The build of the narrow rows' lanes that steps use (`"AVX-512"` or
    /// `"AVX2"`), or `None` when they are off or this CPU has none (see
    /// [`World::set_lanes`]).
    pub fn lanes(&self) -> Option<&'static str> {
        self.solver.lanes().map(|k| k.name())
    }

    /// The threads a step uses (see [`World::set_workers`]).
    pub fn workers(&self) -> usize {
        self.workers.count()
    }

    /// Changes gravity (takes effect at the next step).
    pub fn set_gravity(&mut self, g: Vec3) {
        self.config.gravity = g;
    }

    /// The tick length, s.
    pub fn dt(&self) -> Scalar {
        self.config.dt()
    }

    /// Steps taken since creation (restored with snapshots).
    pub fn tick(&self) -> u64 {
        self.tick
    }

    /// Every arithmetic fault raised by this world since creation or
    /// restore (sticky).
    pub fn faults(&self) -> Faults {
        self.faults
    }

    /// The bodies (read-only access to hot and cold state).
    pub fn bodies(&self) -> &BodySet {
        &self.bodies
    }

    /// Live body handles in handle order.
    pub fn body_handles(&self) -> impl Iterator<Item = BodyHandle> + '_ {
        self.bodies.handles()
    }

    /// A read-only view of one body.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`] for a stale handle.
    pub fn body(&self, h: BodyHandle) -> Result<BodyRef<'_>, WorldError> {
        match (self.bodies.hot(h), self.bodies.cold(h)) {
            (Some(hot), Some(cold)) => Ok(BodyRef::new(h, hot, cold)),
            _ => Err(WorldError::InvalidBody(h)),
        }
    }

    /// The first body with this name, in handle order (a linear search: for
    /// tools and tests, not for every tick).
    pub fn find_body(&self, name: &str) -> Option<BodyHandle> {
        self.bodies
            .iter()
            .find(|(_, _, c)| c.name == name)
            .map(|(h, _, _)| h)
    }

    /// A collider.
    ///
    /// # Errors
    /// [`WorldError::InvalidCollider`] for a stale handle.
    pub fn collider(&self, h: ColliderHandle) -> Result<&Collider, WorldError> {
        self.colliders
            .get(h.0)
            .ok_or(WorldError::InvalidCollider(h))
    }

    /// All colliders with their handles, in handle order.
    pub fn colliders(&self) -> impl Iterator<Item = (ColliderHandle, &Collider)> {
        self.colliders.iter().map(|(h, c)| (ColliderHandle(h), c))
    }

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
    fn body_origin(&self, h: BodyHandle) -> Transform {
        match (self.bodies.hot(h), self.bodies.cold(h)) {
            (Some(hot), Some(cold)) => hot.origin_pose(cold.local_center),
            _ => Transform::IDENTITY,
        }
    }

    /// The contact pairs after the last step, ascending by collider
    /// handles: touching pairs carry their manifold (normal from A to B).
    pub fn contact_pairs(&self) -> &[ContactPair] {
        self.contacts.pairs()
    }

    /// The contact and trigger events of the last step (plus end events of
    /// colliders removed since), in pair order.
    pub fn contact_events(&self) -> &[ContactEvent] {
        self.contacts.events()
    }

    fn hot_mut(&mut self, h: BodyHandle) -> Result<&mut BodyHot, WorldError> {
        self.bodies.hot_mut(h).ok_or(WorldError::InvalidBody(h))
    }

    /// Teleports a body: its origin goes to `pose` (velocities kept, body
    /// woken). Use sparingly on dynamic bodies: it ignores everything in the
    /// way.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`].
    pub fn set_pose(&mut self, h: BodyHandle, pose: Transform) -> Result<(), WorldError> {
        let (hot, cold) = self.bodies.both_mut(h).ok_or(WorldError::InvalidBody(h))?;
        let rotation = pose.rotation.normalize();
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
    /// kind; also given at creation, [`BodyDesc::user_data`]). It is state
    /// like the body's pose: in the body's hash (when not zero), in
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
    /// [`BodyDesc::bullet`]); ignored for static and kinematic bodies.
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

/// The quaternion rotation vector (axis × angle, angle in [0, π]) taking
/// orientation `from` to `to`.
pub(crate) fn rotation_delta(from: Quat, to: Quat) -> Vec3 {
    let d = (to * from.conjugate()).canonical();
    match d.xyz().normalize_and_length() {
        Some((axis, s)) => {
            let angle = crate::math::elem::atan2(s, d.w) * Scalar::TWO;
            axis * angle
        }
        None => Vec3::ZERO,
    }
}

impl World {
    /// Rebuilds what a snapshot does not carry and the public counts read
    /// (the awake index: [`BodySet::sleeping_count`] read 0 in a restored
    /// world until its first step).
    pub(crate) fn rebuild_derived(&mut self) {
        self.refresh_awake_set();
        self.joints.rebuild();
    }

    /// The game's own state (see [`crate::game_state`]): hashed,
    /// snapshotted and restored with the world.
    pub fn game_state(&self) -> &crate::game_state::GameState {
        &self.game
    }

    /// The game's own state, to change (see [`crate::game_state`]).
    pub fn game_state_mut(&mut self) -> &mut crate::game_state::GameState {
        &mut self.game
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
