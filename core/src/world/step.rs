//! `World::step`: the named stages, in order.

use crate::body::BodyKind;
use crate::collision::contacts::PairKind;
use crate::math::{Scalar, Vec3};
use crate::solver::contact_solver::{PairInfo, Softness, SolverParams, SolverStats};
use crate::solver::{integrate, sleep};

use super::{StepReport, World, rotation_delta};

impl World {
    /// Advances the world by one tick (`1/tick_rate` seconds).
    ///
    /// Stages, in order:
    /// 1. `kinematic_targets`: kinematic bodies with a target pose get the
    ///    velocities that reach it over the tick;
    ///    then `collide`: candidate pairs from the broad phase (whose proxies
    ///    follow the poses at the start of the tick), narrow phase,
    ///    persistent manifolds and contact/trigger events (read them with
    ///    [`World::contact_events`]); then `wake_touched`: sleeping bodies
    ///    touched by a moving body wake;
    /// 2. `prepare_contacts`: solver bodies and contact constraints from the
    ///    touching and speculative points (effective masses, anchors);
    /// 3. per substep: `integrate_velocities` (gravity, forces, torques,
    ///    damping, the gyroscopic midpoint), `warm_start`, `solve` (soft,
    ///    with push-out), `integrate_positions`, `relax` (no push-out);
    /// 4. `restitution`, then `store_impulses` for warm starting next tick;
    /// 5. `finish_velocities`: end-of-tick angular velocities from momenta;
    ///    then `ccd`: fast dynamic bodies and bullets are swept from their
    ///    start-of-tick poses (recorded before the substeps) to where the
    ///    substeps left them, and stopped just short of what they would
    ///    have passed through (see `world/ccd.rs`);
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
        let (mut report, faults) = self.with_fault_scope(|w| w.step_stages());
        report.faults = faults;
        report.sticky_faults = self.faults;
        report
    }

    fn step_stages(&mut self) -> StepReport {
        let cfg = self.config;
        let h = cfg.substep_dt();
        let mut report = StepReport {
            substeps: cfg.substeps,
            ..StepReport::default()
        };

        // The per-body stages walk the awake slots only: sleeping and static
        // bodies cost nothing (see `body/awake.rs`). Growths of the awake
        // bookkeeping between steps (the game's calls) are not the step's.
        self.bodies.take_awake_growths();
        self.bodies.refresh_awake();

        report.kinematic_bodies = self.stage_kinematic_targets();

        let (contacts, reinserted) = self.stage_collide();
        report.woken_by_contact = self.stage_wake_touched();
        if report.woken_by_contact > 0 {
            self.bodies.refresh_awake();
        }
        report.candidate_pairs = contacts.candidates;
        report.narrow_tests = contacts.narrow_tests;
        report.touching_pairs = contacts.touching;
        report.contact_points = contacts.points;
        report.begin_events = contacts.begin_events;
        report.end_events = contacts.end_events;
        report.proxies_reinserted = reinserted;
        report.buffer_growths = contacts.growths;

        let params = self.solver_params();
        let prep = self.stage_prepare_contacts();
        report.contact_constraints = prep.constraints;
        report.buffer_growths += prep.growths;

        report.buffer_growths += self.stage_ccd_begin();
        let World {
            bodies,
            solver,
            contacts,
            ..
        } = self;
        let (hot, awake) = bodies.awake_slots_mut();
        let solving = !solver.is_empty();
        for _ in 0..cfg.substeps {
            let c = integrate::integrate_velocities(hot, awake, cfg.gravity, h);
            report.awake_bodies = c.integrated;
            report.gyroscopic_solves += c.gyroscopic;
            report.spin_capped += c.clamped;
            if solving {
                // Poses are as the last full gather (or `prepare`) saw them.
                solver.gather_velocities(hot);
                solver.warm_start();
                for _ in 0..cfg.solver_iterations {
                    solver.solve(&params, true);
                }
                solver.scatter_velocities(hot);
            }
            integrate::integrate_positions(hot, awake, h);
            if solving {
                solver.gather(hot);
                for _ in 0..cfg.relax_iterations {
                    solver.solve(&params, false);
                }
                solver.scatter(hot);
            }
        }
        if solving {
            solver.gather_velocities(hot);
            solver.restitution(&params);
            solver.scatter(hot);
            solver.store_impulses(contacts.pairs_mut());
        }
        integrate::finish_angular_velocities(hot, awake);

        let ccd = self.stage_ccd();
        report.ccd_bodies = ccd.bodies;
        report.ccd_hits = ccd.hits;
        report.buffer_growths += ccd.growths;

        self.stage_snap_kinematic();
        self.bodies.clear_forces();
        let slept = self.stage_sleep();
        report.fell_asleep = slept.fell_asleep;
        report.islands = slept.islands;
        report.buffer_growths += u32::from(slept.grew);
        if slept.fell_asleep > 0 {
            self.bodies.note_fell_asleep();
            self.bodies.refresh_awake();
        }
        // A maintained count, not a scan of the slots.
        report.sleeping_bodies = self.bodies.sleeping_count();

        // Broad phase: proxies follow this step's motion, so queries between
        // steps see where the bodies are now.
        self.sync_proxies(true);
        report.buffer_growths += self.broad.take_growths();
        report.buffer_growths += self.bodies.take_awake_growths();

        self.tick += 1;
        report.tick = self.tick;
        report
    }

    /// Rest counters advance; islands of touching awake bodies that all
    /// rested long enough fall asleep together.
    fn stage_sleep(&mut self) -> sleep::SleepStats {
        let World {
            bodies,
            colliders,
            contacts,
            islands,
            config,
            ..
        } = self;
        // Only pairs with an awake body can join islands or stop a body
        // resting: the active pairs hold all of them.
        let pairs = contacts.pairs();
        let all = 0..pairs.len() as u32;
        let indices: &mut dyn Iterator<Item = u32> = match contacts.active() {
            Some(active) => &mut active.iter().copied(),
            None => &mut all.into_iter(),
        };
        let links = indices
            .map(|i| &pairs[i as usize])
            .filter(|p| p.touching && p.kind == PairKind::Solid)
            .filter_map(|p| {
                let a = colliders.get(p.a.0)?.body.0.index;
                let b = colliders.get(p.b.0)?.body.0.index;
                Some(sleep::Link { a, b })
            });
        let (hot, awake) = bodies.awake_slots_mut();
        sleep::update_sleep(hot, awake, links, &config.sleep, config.tick_rate, islands)
    }

    /// The solver's settings for this world's substep.
    fn solver_params(&self) -> SolverParams {
        let cfg = &self.config;
        let h = cfg.substep_dt();
        // A spring faster than a quarter of the substep rate is not resolved
        // by the substeps: cap it there (as Box2D does).
        let substep_rate = cfg.tick_rate as i64 * cfg.substeps as i64;
        let hertz = cfg.contact_hertz.min(Scalar::from_ratio(substep_rate, 4));
        SolverParams {
            inv_h: Scalar::from_int(substep_rate as i32),
            softness: Softness::new(hertz, cfg.contact_damping_ratio, h),
            max_push_out: cfg.max_push_out,
            restitution_threshold: cfg.restitution_threshold,
        }
    }

    /// Builds this tick's contact constraints from the solid pairs: only
    /// the active ones (those with a moving body) when the contact set
    /// keeps that list, since pairs between sleeping or static bodies make
    /// no constraint.
    fn stage_prepare_contacts(&mut self) -> SolverStats {
        let World {
            bodies,
            colliders,
            contacts,
            solver,
            ..
        } = self;
        let (hot, _) = bodies.hot_slots_mut();
        solver.prepare(contacts.pairs(), contacts.active(), hot, |p| {
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
        })
    }

    /// Kinematic bodies with a target get the constant velocities that carry
    /// their centre and orientation there in one tick. Returns how many
    /// kinematic bodies will move.
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
