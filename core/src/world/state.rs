//! The `World` type: what it holds, its construction, its settings and
//! read access to its bodies and colliders.

use serde::{Deserialize, Serialize};

use crate::arena::Arena;
use crate::body::{BodyHandle, BodySet};
use crate::collider::{Collider, ColliderHandle};
use crate::collision::{BroadPhase, ContactEvent, ContactPair, ContactSet, ProxyKey};
use crate::math::{Faults, Quat, Scalar, Vec3};
use crate::solver::contact_solver::ContactSolver;
use crate::solver::sleep::IslandScratch;

use crate::workers::{MAX_WORKERS, Workers};

use super::body_ref::BodyRef;
use super::config::{WorldConfig, WorldError};
use super::joint_set::JointSet;
use super::poses::ColliderPoses;

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
    pub(super) config: WorldConfig,
    pub(super) tick: u64,
    pub(super) bodies: BodySet,
    pub(super) colliders: Arena<Collider>,
    pub(super) broad: BroadPhase,
    pub(super) contacts: ContactSet,
    pub(super) faults: Faults,
    pub(super) joints: JointSet,
    /// The game's own state (see [`crate::game_state`]).
    pub(super) game: crate::game_state::GameState,
    /// The joints that broke in the last step (an output, not state).
    #[serde(skip)]
    pub(super) joint_events: Vec<crate::joint::JointEvent>,
    /// Scratch: this tick's joints for the solver (reused every step).
    #[serde(skip)]
    pub(super) joint_solver: crate::solver::joint_solver::JointSolver,
    /// Scratch: the broad phase's candidate pairs (reused every step).
    #[serde(skip)]
    pub(super) candidates: Vec<(ProxyKey, ProxyKey)>,
    /// Scratch: the contact solver's bodies and constraints (reused every
    /// step).
    #[serde(skip)]
    pub(super) solver: ContactSolver,
    /// The threads a step splits its work over (the narrow phase, the
    /// integrators, the contact solver's set-up and colour passes). Not
    /// simulation state: any count gives the same bits.
    #[serde(skip)]
    pub(super) workers: Workers,
    /// Scratch: the sleep stage's union–find (reused every step).
    #[serde(skip)]
    pub(super) islands: IslandScratch,
    /// Scratch: continuous collision's start poses and candidate lists
    /// (reused every step).
    #[serde(skip)]
    pub(super) ccd: CcdScratch,
    /// Scratch: the colliders' world poses for the narrow phase (filled
    /// every step).
    #[serde(skip)]
    pub(super) poses: ColliderPoses,
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
            joints: JointSet::default(),
            game: crate::game_state::GameState::default(),
            joint_events: Vec::new(),
            joint_solver: Default::default(),
            candidates: Vec::new(),
            solver: ContactSolver::default(),
            workers: Workers::default(),
            islands: IslandScratch::default(),
            ccd: CcdScratch::default(),
            poses: ColliderPoses::default(),
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
    ///
    /// [`ContactOrder::Colors`]: super::config::ContactOrder::Colors
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
    ///
    /// [`ContactOrder::Colors`]: super::config::ContactOrder::Colors
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
    ///
    /// [`ContactOrder::Colors`]: super::config::ContactOrder::Colors
    /// [`ContactRows::Narrow`]: super::config::ContactRows::Narrow
    /// [`StepReport::lane_batches`]: super::config::StepReport::lane_batches
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
}

/// Continuous collision's reusable buffers.
#[derive(Clone, Debug, Default)]
pub(crate) struct CcdScratch {
    /// Centre of mass and rotation of every body slot at the start of the
    /// tick.
    pub(super) start: Vec<(Vec3, Quat)>,
    /// This tick's candidate bodies.
    pub(super) movers: Vec<BodyHandle>,
    /// The target colliders of one candidate, sorted.
    pub(super) keys: Vec<ProxyKey>,
}
