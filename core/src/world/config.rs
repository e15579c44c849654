//! World settings, the step report and the world's error type.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::body::BodyHandle;
use crate::collider::ColliderHandle;
use crate::math::{Faults, Scalar, Vec3};
use crate::shape::ShapeError;
use crate::solver::sleep::SleepConfig;

/// The most substeps a step may be split into.
pub const MAX_SUBSTEPS: u32 = 64;
/// The most solver (or relax) passes per substep.
pub const MAX_SOLVER_ITERATIONS: u32 = 64;
/// The highest tick rate accepted, Hz.
pub const MAX_TICK_RATE: u32 = 10_000;

/// Settings fixed for a world's lifetime.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct WorldConfig {
    /// Gravitational acceleration, m/s².
    pub gravity: Vec3,
    /// Ticks per second; one `step()` advances `1/tick_rate` seconds.
    pub tick_rate: u32,
    /// Substeps per tick (1..=64): each integrates `1/(tick_rate·substeps)`.
    pub substeps: u32,
    /// Sleep thresholds.
    pub sleep: SleepConfig,
    /// Speculative contact distance, m: shapes closer than this (plus the
    /// distance their bodies close in one tick) get contact points (with
    /// negative depth) before they touch, so the solver can stop them
    /// without a gap or an overlap.
    pub contact_margin: Scalar,
    /// How far the broad phase's fat boxes extend beyond the shapes, m: a
    /// body moving less than this per step does not touch the trees.
    pub broad_phase_margin: Scalar,
    /// Contact solver passes with bias (push-out) per substep, ≥ 1.
    pub solver_iterations: u32,
    /// Contact solver passes without bias (relax) per substep, ≥ 1.
    pub relax_iterations: u32,
    /// Stiffness of the soft contact, Hz: overlaps are pushed out like a
    /// spring of this frequency (capped at a quarter of the substep rate so
    /// it stays stable).
    pub contact_hertz: Scalar,
    /// Damping ratio of the soft contact (≥ 0; large values push out
    /// without overshoot).
    pub contact_damping_ratio: Scalar,
    /// The fastest the solver pushes overlapping shapes apart, m/s.
    pub max_push_out: Scalar,
    /// Approach speed under which contacts do not bounce, m/s (keeps
    /// resting contacts from jittering).
    pub restitution_threshold: Scalar,
    /// The order the contact solver visits its constraints in: pair order
    /// (the default) or colour order, which can be split over worker
    /// threads ([`World::set_workers`](crate::World::set_workers)).
    #[serde(default)]
    pub contact_order: ContactOrder,
    /// The number format of the contact solver's rows: Q32.32 (the
    /// default) or the narrow exact format (32-bit operands, exact 64-bit
    /// sums), which is about twice as fast and rounds velocities in the
    /// rows to 2⁻²⁰ m/s.
    #[serde(default)]
    pub contact_rows: ContactRows,
}

/// The number format the contact solver's rows compute in. The two give
/// different (each deterministic) results, so it is a world setting, in the
/// state hash and in snapshots.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ContactRows {
    /// Q32.32 operands, 128-bit products, one rounding per sum.
    #[default]
    Exact,
    /// Velocities and impulses as 32-bit integers of 2⁻²⁰ m/s (impulses in
    /// velocity units, `λ/m_eff`), Jacobian and response entries as 32-bit
    /// integers with one exponent each per constraint, every product
    /// 32 × 32 → 64 bits and every sum exact in 64 bits. A constraint whose
    /// values do not fit (a velocity past ±512 m/s, a high mass ratio, an
    /// extreme lever arm) is solved on the Q32.32 rows instead, alike on
    /// every machine; [`StepReport`] counts both.
    Narrow,
}

/// The order the contact solver visits its constraints in each pass. The
/// two orders give different (each deterministic) results, so it is a
/// world setting, in the state hash and in snapshots.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ContactOrder {
    /// Ascending collider handles, on one thread. A pyramid built from the
    /// ground up is solved bottom-up, which settles and sleeps it soonest.
    #[default]
    Pairs,
    /// Colour by colour: a greedy colouring puts constraints that share no
    /// moving dynamic body in one colour, each colour's constraints are
    /// split over the world's workers, and the colours follow one another.
    /// The results are the same bits for any number of workers.
    Colors,
}

impl Default for WorldConfig {
    /// Gravity (0, −9.81, 0), 60 Hz, 4 substeps, default sleep settings,
    /// 2 cm contact margin, 10 cm broad-phase margin; one solve and one
    /// relax pass per substep, contacts at 60 Hz with damping ratio 10,
    /// push-out at most 3 m/s, no bounce under 1 m/s (Box2D v3's values,
    /// except the contact frequency: Box2D's 30 Hz lets a stack of 20 sag
    /// 11 cm; 60 Hz is still a quarter of the 240 Hz substep rate).
    fn default() -> WorldConfig {
        WorldConfig {
            gravity: Vec3::new(Scalar::ZERO, Scalar::from_ratio(-981, 100), Scalar::ZERO),
            tick_rate: 60,
            substeps: 4,
            sleep: SleepConfig::default(),
            contact_margin: Scalar::from_ratio(1, 50),
            broad_phase_margin: Scalar::from_ratio(1, 10),
            solver_iterations: 1,
            relax_iterations: 1,
            contact_hertz: Scalar::from_int(60),
            contact_damping_ratio: Scalar::from_int(10),
            max_push_out: Scalar::from_int(3),
            restitution_threshold: Scalar::ONE,
            contact_order: ContactOrder::Pairs,
            contact_rows: ContactRows::Exact,
        }
    }
}

impl WorldConfig {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`WorldError::InvalidConfig`] naming the bad setting.
    pub fn validate(&self) -> Result<(), WorldError> {
        if self.tick_rate == 0 || self.tick_rate > MAX_TICK_RATE {
            return Err(WorldError::InvalidConfig(format!(
                "tick_rate must be in 1..={MAX_TICK_RATE}, got {}",
                self.tick_rate
            )));
        }
        if self.substeps == 0 || self.substeps > MAX_SUBSTEPS {
            return Err(WorldError::InvalidConfig(format!(
                "substeps must be in 1..={MAX_SUBSTEPS}, got {}",
                self.substeps
            )));
        }
        if self.contact_margin.is_negative() || self.broad_phase_margin.is_negative() {
            return Err(WorldError::InvalidConfig(
                "contact and broad-phase margins must not be negative".into(),
            ));
        }
        if self.solver_iterations == 0
            || self.relax_iterations == 0
            || self.solver_iterations > MAX_SOLVER_ITERATIONS
            || self.relax_iterations > MAX_SOLVER_ITERATIONS
        {
            return Err(WorldError::InvalidConfig(format!(
                "solver and relax iterations must be in 1..={MAX_SOLVER_ITERATIONS}"
            )));
        }
        if self.contact_hertz.is_negative()
            || self.contact_damping_ratio.is_negative()
            || self.max_push_out.is_negative()
            || self.restitution_threshold.is_negative()
        {
            return Err(WorldError::InvalidConfig(
                "contact hertz, damping ratio, push-out speed and restitution threshold must not be negative".into(),
            ));
        }
        let s = &self.sleep;
        if s.linear_threshold.is_negative()
            || s.angular_threshold.is_negative()
            || s.time_to_sleep.is_negative()
        {
            return Err(WorldError::InvalidConfig(
                "sleep thresholds and time_to_sleep must not be negative".into(),
            ));
        }
        Ok(())
    }

    /// The tick length `1/tick_rate`, rounded to nearest once.
    pub fn dt(&self) -> Scalar {
        Scalar::from_ratio(1, self.tick_rate as i64)
    }

    /// The substep length `1/(tick_rate·substeps)`, rounded to nearest once
    /// (not `dt/substeps`, which would round twice).
    pub fn substep_dt(&self) -> Scalar {
        Scalar::from_ratio(1, self.tick_rate as i64 * self.substeps as i64)
    }
}

/// What one `step()` did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepReport {
    /// The world's tick after the step (the first step reports 1).
    pub tick: u64,
    /// Substeps run.
    pub substeps: u32,
    /// Dynamic bodies integrated (awake).
    pub awake_bodies: u32,
    /// Dynamic bodies skipped because they sleep.
    pub sleeping_bodies: u32,
    /// Kinematic bodies moved.
    pub kinematic_bodies: u32,
    /// Joints solved (those with an awake dynamic body).
    pub joints: u32,
    /// Joints that broke (see `World::joint_events`).
    pub joints_broken: u32,
    /// Body-substeps that needed the gyroscopic midpoint solve.
    pub gyroscopic_solves: u32,
    /// Body-substeps whose angular speed was capped at
    /// `MAX_ROTATION_PER_SUBSTEP / h` (π/4 per substep, 188.5 rad/s at 60 Hz
    /// with 4 substeps; as Box2D and Jolt cap it).
    pub spin_capped: u32,
    /// Sleeping bodies woken because a moving body touched them.
    pub woken_by_contact: u32,
    /// Bodies that fell asleep during this step.
    pub fell_asleep: u32,
    /// Islands of awake dynamic bodies joined by touching contacts, counted
    /// by the sleep stage before any fell asleep (0 with sleeping disabled).
    pub islands: u32,
    /// Candidate pairs from the broad phase (fat boxes overlap).
    pub candidate_pairs: u32,
    /// Narrow-phase tests run (full tests plus reuses).
    pub narrow_tests: u32,
    /// Of those, pairs that had barely moved relative to each other and
    /// rebuilt their manifold from its cached features instead of a full
    /// test.
    pub reused_manifolds: u32,
    /// Pairs touching after the collision stage.
    pub touching_pairs: u32,
    /// Contact points in all manifolds.
    pub contact_points: u32,
    /// Begin-touch and trigger-enter events.
    pub begin_events: u32,
    /// End-touch and trigger-exit events.
    pub end_events: u32,
    /// Broad-phase proxies moved in their trees this step.
    pub proxies_reinserted: u32,
    /// Contact constraints solved (solid pairs with points and at least
    /// one awake dynamic body).
    pub contact_constraints: u32,
    /// Colours the contact constraints took this step: the solver visits
    /// the constraints colour by colour, and no two of one colour share a
    /// moving dynamic body.
    pub contact_colors: u32,
    /// Contact constraints that found no free colour (visited after the
    /// last colour, one at a time). Zero on every benchmark scene.
    pub contact_overflow: u32,
    /// Batches of eight contact constraints of one colour whose normal rows
    /// ran on the CPU's exact wide lanes (AVX-512 IFMA; see
    /// `World::set_wide`, with the `wide` feature), over all the
    /// step's solve and relax passes. Zero in pair order, with the lanes
    /// off (the default), and on CPUs without them: the results are the
    /// same bits.
    pub wide_batches: u32,
    /// Batches the lanes' range guard sent to the scalar rows instead
    /// (a value too large for the lanes to be exact).
    pub wide_batches_guarded: u32,
    /// Contact constraints that started the step on the narrow rows
    /// ([`ContactRows::Narrow`]); the others of `contact_constraints` were
    /// solved on the Q32.32 rows (a value that does not fit, a high mass
    /// ratio, or the setting off).
    pub narrow_constraints: u32,
    /// Of those, the constraints a narrow visit's guard moved to the
    /// Q32.32 rows during the step (a value past the format's range).
    pub narrow_fallbacks: u32,
    /// Batches of eight narrow constraints that the step's solve and relax
    /// passes could visit on the SIMD lanes (see
    /// [`World::set_lanes`](crate::World::set_lanes)): zero in pair order,
    /// with the lanes off, and on CPUs without them.
    pub lane_batches: u32,
    /// Bodies whose motion continuous collision swept this step: fast ones
    /// (moved more than a quarter of their smallest extent) and bullets.
    /// Zero while everything is slow.
    pub ccd_bodies: u32,
    /// Of those, the bodies stopped at a time of impact (moved back to just
    /// before a surface they would have passed through).
    pub ccd_hits: u32,
    /// Times an internal buffer had to grow during the step (an allocation:
    /// zero once the world is warm).
    pub buffer_growths: u32,
    /// Arithmetic faults raised during this step (overflow, division by
    /// zero, domain errors). Non-empty means the results can no longer be
    /// trusted: tests and desync checks treat it as a failure.
    pub faults: Faults,
    /// Every fault raised since the world was created or restored (sticky).
    pub sticky_faults: Faults,
}

impl StepReport {
    /// Whether any arithmetic fault happened during this step.
    pub fn overflowed(&self) -> bool {
        !self.faults.is_empty()
    }
}

/// Errors from world operations.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum WorldError {
    /// The body handle is stale or was never issued by this world.
    #[error("no such body: {0}")]
    InvalidBody(BodyHandle),
    /// The collider handle is stale or was never issued by this world.
    #[error("no such collider: {0:?}")]
    InvalidCollider(ColliderHandle),
    /// A world setting is out of range.
    #[error("invalid world config: {0}")]
    InvalidConfig(String),
    /// A triangle mesh or height field was put on a body that can move.
    #[error("{shape} shapes are static only: body {body:?} is {kind}")]
    StaticOnlyShape {
        /// The shape kind's name.
        shape: &'static str,
        /// The body's name.
        body: String,
        /// The body kind's name.
        kind: &'static str,
    },
    /// A shape rejected its parameters or cannot give mass properties.
    #[error("shape: {0}")]
    Shape(#[from] ShapeError),
    /// A mass, density or other body parameter is out of range.
    #[error("invalid body parameter: {0}")]
    InvalidParameter(String),
    /// The joint handle is stale or was never issued by this world.
    #[error("no such joint: {0:?}")]
    InvalidJoint(crate::joint::JointHandle),
    /// A joint's parameters are out of range.
    #[error("invalid joint: {0}")]
    InvalidJointParameter(String),
}
