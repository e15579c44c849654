//! `World::step`: the named stages, in order.
//!
//! Every stage runs in its own `#[inline(never)]` function named `stage_`
//! and the [`Stage::name`], so profilers attribute instructions to stages
//! (see [`Stage`]); an observed step is told when each one ends.

use crate::arena::Arena;
use crate::body::{BodyHot, BodyKind};
use crate::collision::ContactPair;
use crate::joint::Joint;
use crate::math::{Scalar, Vec3};
use crate::solver::contact_solver::{ContactSolver, PairInfo, Softness, SolverParams, SolverStats};
use crate::solver::integrate::{self, VelocityCounters};
use crate::solver::joint_solver::{JOINT_DAMPING_RATIO, JointParams, JointSolver};
use crate::workers::Workers;

use super::config::{ContactOrder, ContactRows, StepReport};
use super::observe::{Guarded, Notify, Quiet, Stage, StepObserver};
use super::state::World;
use crate::solver::integrate::rotation_delta;

impl World {
    /// Advances the world by one tick (`1/tick_rate` seconds).
    ///
    /// Stages, in order ([`Stage::ALL`]):
    /// 1. `awake_list`: the list of awake bodies catches up with the game's
    ///    calls since the last step; `kinematic_targets`: kinematic bodies
    ///    with a target pose get the velocities that reach it over the tick;
    ///    then `broad_phase`: candidate pairs from the broad phase (whose
    ///    proxies follow the poses at the start of the tick); `narrow_phase`:
    ///    narrow phase, persistent manifolds and contact/trigger events
    ///    (read them with [`World::contact_events`]); `wake_touched`:
    ///    sleeping bodies touched by a moving body wake;
    /// 2. `prepare_contacts`: solver bodies and contact constraints from the
    ///    touching and speculative points (effective masses, anchors);
    ///    `ccd_begin`: the start-of-tick poses are recorded;
    /// 3. per substep: `integrate_velocities` (gravity, forces, torques,
    ///    damping, the gyroscopic midpoint), `warm_start`, `solve` (soft,
    ///    with push-out), `integrate_positions`, `relax` (no push-out);
    /// 4. `restitution`, then `store_impulses` for warm starting next tick;
    /// 5. `finish_velocities`: end-of-tick angular velocities from momenta;
    ///    then `ccd`: fast dynamic bodies and bullets are swept from their
    ///    start-of-tick poses to where the substeps left them, and stopped
    ///    just short of what they would have passed through (see
    ///    `world/ccd.rs`);
    /// 6. `snap_kinematic`: targeted kinematic bodies land exactly on their
    ///    targets and stop;
    /// 7. `clear_forces`;
    /// 8. `sleep`: rest timers advance; islands (awake dynamic bodies joined
    ///    by touching contacts) whose every body rested long enough fall
    ///    asleep together;
    /// 9. `sync_proxies`: broad-phase proxies follow the step's motion (so
    ///    queries between steps see the new poses);
    /// 10. the tick counter advances.
    ///
    /// Never allocates once the world is built, never panics; arithmetic
    /// faults are reported in the returned [`StepReport`] and kept in
    /// [`World::faults`].
    pub fn step(&mut self) -> StepReport {
        self.step_notifying(&mut Quiet)
    }

    /// [`World::step`], telling `observer` as each stage ends (the substep
    /// stages once per substep), so a benchmark can time the stages with its
    /// own clock.
    ///
    /// The observer cannot change the results: it sees only the stage, the
    /// faults it raises are discarded rather than attributed to the step,
    /// and the state after an observed step is the state after a plain one,
    /// bit for bit. The plain step does not pay for the hook: it is compiled
    /// without it.
    pub fn step_observed(&mut self, observer: &mut dyn StepObserver) -> StepReport {
        self.step_notifying(&mut Guarded(observer))
    }

    fn step_notifying<N: Notify>(&mut self, notify: &mut N) -> StepReport {
        let (mut report, faults) = self.with_fault_scope(|w| w.step_stages(notify));
        report.faults = faults;
        report.sticky_faults = self.faults;
        report
    }

    fn step_stages<N: Notify>(&mut self, n: &mut N) -> StepReport {
        let cfg = self.config;
        let h = cfg.substep_dt();
        let mut report = StepReport {
            substeps: cfg.substeps,
            ..StepReport::default()
        };

        self.stage_awake_list();
        n.finished(Stage::AwakeList);
        report.kinematic_bodies = self.stage_kinematic_targets();
        n.finished(Stage::KinematicTargets);

        let pairs = self.stage_broad_phase();
        n.finished(Stage::BroadPhase);
        let contacts = self.stage_narrow_phase();
        n.finished(Stage::NarrowPhase);
        report.woken_by_contact = self.stage_wake_touched();
        n.finished(Stage::WakeTouched);
        report.candidate_pairs = contacts.candidates;
        report.narrow_tests = contacts.narrow_tests;
        report.reused_manifolds = contacts.reused;
        report.touching_pairs = contacts.touching;
        report.contact_points = contacts.points;
        report.begin_events = contacts.begin_events;
        report.end_events = contacts.end_events;
        report.proxies_reinserted = pairs.reinsertions;
        report.buffer_growths = contacts.growths + pairs.buffer_growths;

        let params = self.solver_params();
        let prep = self.stage_prepare_contacts(&params);
        report.buffer_growths += u32::from(self.prepare_joints());
        report.joints = self.joint_solver.len() as u32;
        n.finished(Stage::PrepareContacts);
        let jparams = self.joint_params(&params);
        report.contact_constraints = prep.constraints;
        report.contact_colors = prep.colors;
        report.contact_overflow = prep.overflow;
        report.narrow_constraints = prep.narrow;
        report.lane_batches = prep.lane_batches;
        report.buffer_growths += prep.growths;

        report.buffer_growths += self.stage_ccd_begin();
        n.finished(Stage::CcdBegin);
        let World {
            bodies,
            solver,
            workers,
            contacts,
            joints,
            joint_solver,
            ..
        } = self;
        let workers = &*workers;
        let (hot, awake) = bodies.awake_slots_mut();
        let mut js = Joints {
            solver: joint_solver,
            arena: &mut joints.arena,
            params: jparams,
        };
        for substep in 0..cfg.substeps {
            let c = stage_integrate_velocities(hot, awake, cfg.gravity, h, workers);
            n.finished(Stage::IntegrateVelocities);
            report.awake_bodies = c.integrated;
            report.gyroscopic_solves += c.gyroscopic;
            report.spin_capped += c.clamped;
            // Poses are as the last full gather (or `prepare`) saw them.
            // After the first substep, the joints' last measurement (the
            // relax's, after the positions moved) is still at these poses:
            // only the velocities changed since.
            let measured = substep > 0 && cfg.relax_iterations > 0;
            stage_warm_start(solver, workers, &mut js, hot, !measured);
            n.finished(Stage::WarmStart);
            stage_solve(
                solver,
                workers,
                &mut js,
                &params,
                cfg.solver_iterations,
                hot,
            );
            n.finished(Stage::Solve);
            stage_integrate_positions(hot, awake, h, workers);
            n.finished(Stage::IntegratePositions);
            let warm_next = substep + 1 < cfg.substeps;
            stage_relax(
                solver,
                workers,
                &mut js,
                &params,
                cfg.relax_iterations,
                hot,
                warm_next,
            );
            n.finished(Stage::Relax);
        }
        stage_restitution(solver, workers, &params, hot);
        n.finished(Stage::Restitution);
        stage_store_impulses(solver, workers, contacts.pairs_mut());
        n.finished(Stage::StoreImpulses);
        stage_finish_velocities(hot, awake, workers);
        // Joints past their thresholds break (after the last substep's
        // impulses are known).
        let (broken, grew) = self.stage_break_joints();
        report.joints_broken = broken;
        report.buffer_growths += u32::from(grew);
        n.finished(Stage::FinishVelocities);

        let ccd = self.stage_ccd();
        n.finished(Stage::Ccd);
        report.ccd_bodies = ccd.bodies;
        report.ccd_hits = ccd.hits;
        report.buffer_growths += ccd.growths;

        self.stage_snap_kinematic();
        n.finished(Stage::SnapKinematic);
        self.stage_clear_forces();
        n.finished(Stage::ClearForces);
        let slept = self.stage_sleep();
        n.finished(Stage::Sleep);
        let lanes = self.solver.take_lane_counts();
        report.wide_batches = lanes.lanes;
        report.wide_batches_guarded = lanes.guarded;
        report.narrow_fallbacks = self.solver.take_fallbacks();
        report.fell_asleep = slept.fell_asleep;
        report.islands = slept.islands;
        report.buffer_growths += u32::from(slept.grew);
        // A maintained count, not a scan of the slots.
        report.sleeping_bodies = self.bodies.sleeping_count();

        report.buffer_growths += self.stage_sync_proxies();
        n.finished(Stage::SyncProxies);

        self.tick += 1;
        report.tick = self.tick;
        report
    }

    /// Broad phase: proxies follow this step's motion, so queries between
    /// steps see where the bodies are now. Returns the buffer growths of the
    /// whole step's awake bookkeeping.
    #[inline(never)]
    fn stage_sync_proxies(&mut self) -> u32 {
        self.sync_proxies(true);
        // The growth of the broad phase here (bodies that fell asleep
        // this step moved to the static tree) is this step's.
        self.broad.take_growths() + self.bodies.take_awake_growths()
    }

    /// Forces and torques the game applied for this tick are used up.
    #[inline(never)]
    fn stage_clear_forces(&mut self) {
        self.bodies.clear_forces();
    }

    /// The solver's settings for this world's substep.
    fn solver_params(&self) -> SolverParams {
        let cfg = &self.config;
        let h = cfg.substep_dt();
        // A spring faster than a quarter of the substep rate is not resolved
        // by the substeps: cap it there (as Box2D does).
        let substep_rate = cfg.tick_rate as i64 * cfg.substeps as i64;
        let hertz = cfg.contact_hertz.min(Scalar::from_ratio(substep_rate, 4));
        let omega = if hertz.is_positive() {
            Scalar::TAU * hertz
        } else {
            Scalar::ZERO
        };
        SolverParams {
            h,
            inv_h: Scalar::from_int(substep_rate as i32),
            softness: Softness::new(hertz, cfg.contact_damping_ratio, h),
            omega,
            zeta: cfg.contact_damping_ratio,
            omega_max: omega_max(substep_rate),
            max_push_out: cfg.max_push_out,
            restitution_threshold: cfg.restitution_threshold,
            colored: cfg.contact_order == ContactOrder::Colors,
            narrow: cfg.contact_rows == ContactRows::Narrow,
        }
    }

    /// Lists this tick's joints for the solver. Returns whether a buffer
    /// grew.
    fn prepare_joints(&mut self) -> bool {
        let World {
            bodies,
            joints,
            joint_solver,
            ..
        } = self;
        if joints.arena.is_empty() && joint_solver.is_empty() {
            return false;
        }
        joint_solver.prepare(&joints.arena, bodies)
    }

    /// The joints' settings for this world's substep: the contact spring's
    /// frequency doubled (capped at a quarter of the substep rate, as the
    /// contacts' is) and [`JOINT_DAMPING_RATIO`].
    fn joint_params(&self, params: &SolverParams) -> JointParams {
        let cfg = &self.config;
        let substep_rate = cfg.tick_rate as i64 * cfg.substeps as i64;
        let hertz = (cfg.contact_hertz * Scalar::TWO).min(Scalar::from_ratio(substep_rate, 4));
        JointParams {
            h: params.h,
            inv_h: params.inv_h,
            softness: Softness::new(hertz, JOINT_DAMPING_RATIO, params.h),
        }
    }

    /// Builds this tick's contact constraints from the solid pairs: only
    /// the active ones (those with a moving body) when the contact set
    /// keeps that list, since pairs between sleeping or static bodies make
    /// no constraint.
    #[inline(never)]
    fn stage_prepare_contacts(&mut self, params: &SolverParams) -> SolverStats {
        let World {
            bodies,
            colliders,
            contacts,
            solver,
            workers,
            ..
        } = self;
        let (hot, _) = bodies.hot_slots_mut();
        let info = |p: &ContactPair| {
            let ca = colliders.get(p.a.0)?;
            let cb = colliders.get(p.b.0)?;
            let m = ca.material.combine(&cb.material);
            Some(PairInfo {
                slot_a: ca.body.0.index,
                slot_b: cb.body.0.index,
                friction: m.friction,
                restitution: m.restitution,
                rounding: [ca.shape.rounding(), cb.shape.rounding()],
            })
        };
        solver.prepare(
            contacts.pairs(),
            contacts.active(),
            hot,
            params,
            info,
            workers,
        )
    }

    /// Kinematic bodies with a target get the constant velocities that carry
    /// their centre and orientation there in one tick. Returns how many
    /// kinematic bodies will move.
    #[inline(never)]
    fn stage_kinematic_targets(&mut self) -> u32 {
        let ticks_per_second = self.config.tick_rate as i64;
        let mut moving = 0;
        // Kinematic bodies never sleep: they are all in the awake list.
        self.bodies.for_each_awake_mut(|b, cold| {
            if b.kind != BodyKind::Kinematic {
                return;
            }
            if let Some(t) = cold.kinematic_target {
                let target_center = t.transform_point(cold.local_center);
                b.linear_velocity = (target_center - b.center).mul_int(ticks_per_second);
                b.angular_velocity =
                    rotation_delta(b.rotation, t.rotation).mul_int(ticks_per_second);
            }
            if !b.linear_velocity.is_zero() || !b.angular_velocity.is_zero() {
                moving += 1;
            }
        });
        moving
    }

    /// Targeted kinematic bodies land exactly on their targets and stop.
    #[inline(never)]
    fn stage_snap_kinematic(&mut self) {
        self.bodies.for_each_awake_mut(|b, cold| {
            if b.kind != BodyKind::Kinematic {
                return;
            }
            if let Some(t) = cold.kinematic_target.take() {
                b.rotation = t.rotation;
                b.center = t.transform_point(cold.local_center);
                b.linear_velocity = Vec3::ZERO;
                b.angular_velocity = Vec3::ZERO;
            }
        });
    }
}

// The substep and solver stages borrow the bodies and the solver apart, so
// they are functions rather than methods. Each skips its solver work when
// there is no constraint this tick (the stage is still reported, so the
// sequence of stages is the same in every step).

/// Gravity, forces, torques, damping and the gyroscopic midpoint for one
/// substep.
#[inline(never)]
fn stage_integrate_velocities(
    hot: &mut [BodyHot],
    awake: &[u32],
    gravity: Vec3,
    h: Scalar,
    workers: &Workers,
) -> VelocityCounters {
    integrate::integrate_velocities(hot, awake, gravity, h, workers)
}

/// The joints of this tick, for the substep stages.
struct Joints<'a> {
    solver: &'a mut JointSolver,
    arena: &'a mut Arena<Joint>,
    params: JointParams,
}

impl Joints<'_> {
    fn is_empty(&self) -> bool {
        self.solver.is_empty()
    }
}

/// The previous substep's (or tick's) impulses applied again: the joints'
/// to the bodies (each joint measured at these poses on the way, for the
/// solve passes too), the contacts' to the contact solver's velocities
/// (which go back to the bodies at once when joints will solve next, so
/// they see them).
#[inline(never)]
fn stage_warm_start(
    solver: &mut ContactSolver,
    workers: &Workers,
    js: &mut Joints<'_>,
    hot: &mut [BodyHot],
    measure_joints: bool,
) {
    if !js.is_empty() {
        js.solver.warm_start(js.arena, hot, measure_joints);
    }
    if solver.is_empty() {
        return;
    }
    solver.gather_velocities(hot, workers);
    solver.warm_start(workers);
    if !js.is_empty() {
        solver.scatter_velocities(hot, workers);
    }
}

/// The soft solve passes with push-out and the shock pass over the
/// high-mass-ratio contacts, then the velocities go back to the bodies.
#[inline(never)]
fn stage_solve(
    solver: &mut ContactSolver,
    workers: &Workers,
    js: &mut Joints<'_>,
    params: &SolverParams,
    iterations: u32,
    hot: &mut [BodyHot],
) {
    if !js.is_empty() {
        for _ in 0..iterations {
            // The warm start measured the joints at these poses.
            js.solver.solve(js.arena, hot, &js.params, true, false);
        }
    }
    if solver.is_empty() {
        return;
    }
    if !js.is_empty() {
        solver.gather_velocities(hot, workers);
    }
    for _ in 0..iterations {
        solver.solve(params, true, false, workers);
    }
    solver.shock(params, false);
    solver.scatter_velocities(hot, workers);
}

/// Positions and orientations advance by one substep.
#[inline(never)]
fn stage_integrate_positions(hot: &mut [BodyHot], awake: &[u32], h: Scalar, workers: &Workers) {
    integrate::integrate_positions(hot, awake, h, workers);
}

/// The relax passes (no push-out) at the substep's new poses, and the shock
/// pass over the high-mass-ratio contacts. With `warm_next` (a substep
/// follows) the last pass also sums the next warm start.
#[inline(never)]
fn stage_relax(
    solver: &mut ContactSolver,
    workers: &Workers,
    js: &mut Joints<'_>,
    params: &SolverParams,
    iterations: u32,
    hot: &mut [BodyHot],
    warm_next: bool,
) {
    if !js.is_empty() {
        // The positions moved since the solve passes: the first relax pass
        // measures the joints again.
        for i in 0..iterations {
            js.solver.solve(js.arena, hot, &js.params, false, i == 0);
        }
    }
    if solver.is_empty() {
        return;
    }
    solver.gather(hot, workers);
    for i in 0..iterations {
        solver.solve(params, false, warm_next && i + 1 == iterations, workers);
    }
    solver.shock(params, true);
    solver.scatter(hot, workers);
}

/// The restitution pass after the last substep.
#[inline(never)]
fn stage_restitution(
    solver: &mut ContactSolver,
    workers: &Workers,
    params: &SolverParams,
    hot: &mut [BodyHot],
) {
    if solver.is_empty() {
        return;
    }
    solver.gather_velocities(hot, workers);
    solver.restitution(params, workers);
    solver.scatter(hot, workers);
}

/// The accumulated impulses go into the pairs, for warm starting next tick.
#[inline(never)]
fn stage_store_impulses(solver: &ContactSolver, workers: &Workers, pairs: &mut [ContactPair]) {
    if solver.is_empty() {
        return;
    }
    solver.store_impulses(pairs, workers);
}

/// End-of-tick angular velocities from the momenta.
#[inline(never)]
fn stage_finish_velocities(hot: &mut [BodyHot], awake: &[u32], workers: &Workers) {
    integrate::finish_angular_velocities(hot, awake, workers);
}

/// The stiffest contact spring a high-mass-ratio contact may get, rad/s
/// (see the solver's `RATIO_KEPT`): `OMEGA_MAX_PER_RATE` times the substep
/// rate.
fn omega_max(substep_rate: i64) -> Scalar {
    Scalar::from_int(OMEGA_MAX_PER_RATE).mul_int(substep_rate)
}

/// `ω_max·h`: how far past the base spring's cap (`ω·h = π/2`, a quarter of
/// the substep rate) a high-ratio contact's spring may go (8: a 1:1000
/// pair needs `ω·h` = 6.2 at the default 240 Hz substeps).
const OMEGA_MAX_PER_RATE: i32 = 8;
