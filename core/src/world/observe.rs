//! The stages of `World::step` by name, and a hook that is told when each
//! one ends, so a benchmark can time them without a clock in the core.
//!
//! The hook sees nothing but the stage that just ended: it has no access to
//! the world, its arithmetic faults are kept out of the step's (see
//! [`World::step_observed`](super::state::World::step_observed)), and nothing about
//! it is in the state hash or the snapshot. An observed step and a plain step
//! give the same state, bit for bit.

use crate::math::FaultScope;

/// One stage of [`World::step`](super::state::World::step), in the order the step
/// runs them ([`Stage::ALL`]).
///
/// Each stage runs in its own `#[inline(never)]` function of the core named
/// `stage_` followed by [`Stage::name`] (`stage_broad_phase`, ...), so a
/// profiler's inclusive cost of that function is the stage's cost: the
/// bench's per-stage instruction counts (callgrind) read them by that name.
/// The five substep stages run once per substep.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Stage {
    /// The awake list is brought up to date with the game's calls since the
    /// last step (wakes, sleeps, new and removed bodies).
    AwakeList,
    /// Kinematic bodies with a target pose get the velocities that reach it.
    KinematicTargets,
    /// Broad phase: proxy kinds follow the bodies' sleep states, then the
    /// candidate pairs (fat boxes that overlap) are found and filtered.
    BroadPhase,
    /// Narrow phase on every candidate, the persistent manifolds and the
    /// contact and trigger events.
    NarrowPhase,
    /// Sleeping bodies touched by a moving body wake (and the awake list
    /// follows).
    WakeTouched,
    /// The solver's bodies and contact constraints (effective masses,
    /// anchors) from the touching and speculative points.
    PrepareContacts,
    /// Continuous collision records the start-of-tick poses.
    CcdBegin,
    /// Per substep: gravity, forces, damping, the gyroscopic midpoint.
    IntegrateVelocities,
    /// Per substep: last substep's impulses applied again.
    WarmStart,
    /// Per substep: the soft solve passes (with push-out).
    Solve,
    /// Per substep: positions and orientations advance.
    IntegratePositions,
    /// Per substep: the relax passes (no push-out).
    Relax,
    /// The restitution pass.
    Restitution,
    /// The accumulated impulses are stored in the pairs for warm starting.
    StoreImpulses,
    /// End-of-tick angular velocities from the momenta.
    FinishVelocities,
    /// Continuous collision: fast bodies and bullets are swept and stopped
    /// short of what they would have passed through.
    Ccd,
    /// Targeted kinematic bodies land exactly on their targets.
    SnapKinematic,
    /// Forces and torques applied by the game are cleared.
    ClearForces,
    /// Rest timers advance; resting islands fall asleep.
    Sleep,
    /// Broad-phase proxies follow the step's motion.
    SyncProxies,
}

impl Stage {
    /// Every stage, in the order a step runs them (the substep stages once
    /// each: a step runs them `substeps` times over, in this order).
    pub const ALL: [Stage; 20] = [
        Stage::AwakeList,
        Stage::KinematicTargets,
        Stage::BroadPhase,
        Stage::NarrowPhase,
        Stage::WakeTouched,
        Stage::PrepareContacts,
        Stage::CcdBegin,
        Stage::IntegrateVelocities,
        Stage::WarmStart,
        Stage::Solve,
        Stage::IntegratePositions,
        Stage::Relax,
        Stage::Restitution,
        Stage::StoreImpulses,
        Stage::FinishVelocities,
        Stage::Ccd,
        Stage::SnapKinematic,
        Stage::ClearForces,
        Stage::Sleep,
        Stage::SyncProxies,
    ];

    /// The stage's position in [`Stage::ALL`]: an index for per-stage
    /// tables (an observer must not allocate, so it keeps an array).
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The stage's name in snake case; the core function that runs it is
    /// `stage_` followed by this name.
    pub const fn name(self) -> &'static str {
        match self {
            Stage::AwakeList => "awake_list",
            Stage::KinematicTargets => "kinematic_targets",
            Stage::BroadPhase => "broad_phase",
            Stage::NarrowPhase => "narrow_phase",
            Stage::WakeTouched => "wake_touched",
            Stage::PrepareContacts => "prepare_contacts",
            Stage::CcdBegin => "ccd_begin",
            Stage::IntegrateVelocities => "integrate_velocities",
            Stage::WarmStart => "warm_start",
            Stage::Solve => "solve",
            Stage::IntegratePositions => "integrate_positions",
            Stage::Relax => "relax",
            Stage::Restitution => "restitution",
            Stage::StoreImpulses => "store_impulses",
            Stage::FinishVelocities => "finish_velocities",
            Stage::Ccd => "ccd",
            Stage::SnapKinematic => "snap_kinematic",
            Stage::ClearForces => "clear_forces",
            Stage::Sleep => "sleep",
            Stage::SyncProxies => "sync_proxies",
        }
    }

    /// Whether the stage runs once per substep (rather than once per step).
    pub const fn per_substep(self) -> bool {
        matches!(
            self,
            Stage::IntegrateVelocities
                | Stage::WarmStart
                | Stage::Solve
                | Stage::IntegratePositions
                | Stage::Relax
        )
    }
}

/// Told when each stage of an observed step ends
/// ([`World::step_observed`](super::state::World::step_observed)).
///
/// Why: a benchmark reads a clock in `finished` and attributes the time
/// since the previous call to the stage; the core itself never reads a
/// clock. An implementation must not allocate if the step is to stay
/// allocation-free, and a panic in it unwinds out of the step, leaving the
/// world part-way through a tick.
pub trait StepObserver {
    /// `stage` has just ended.
    fn finished(&mut self, stage: Stage);
}

/// How the step reports its stages: not at all (the plain step, which
/// compiles to nothing) or to an observer.
pub(super) trait Notify {
    /// `stage` has just ended.
    fn finished(&mut self, stage: Stage);
}

/// The plain step's: tells no one.
pub(super) struct Quiet;

impl Notify for Quiet {
    #[inline(always)]
    fn finished(&mut self, _: Stage) {}
}

/// An observed step's: calls the observer in a fault scope of its own, so
/// arithmetic faults it raises are not the step's.
pub(super) struct Guarded<'a>(pub(super) &'a mut dyn StepObserver);

impl Notify for Guarded<'_> {
    #[inline]
    fn finished(&mut self, stage: Stage) {
        let ((), _observer_faults) = FaultScope::run(|| self.0.finished(stage));
    }
}
