//! `World::step`: the named stages, in order.

use crate::body::BodyKind;
use crate::math::Vec3;
use crate::solver::{integrate, sleep};

use super::{StepReport, World, rotation_delta};

impl World {
    /// Advances the world by one tick (`1/tick_rate` seconds).
    ///
    /// Stages, in order:
    /// 1. `kinematic_targets`: kinematic bodies with a target pose get the
    ///    velocities that reach it over the tick;
    ///    then `collide`: broad-phase update from the poses at the start of
    ///    the tick, candidate pairs, narrow phase, persistent manifolds and
    ///    contact/trigger events (read them with
    ///    [`World::contact_events`]);
    /// 2. per substep: `integrate_velocities` (gravity, forces, torques,
    ///    damping, the gyroscopic midpoint), then `integrate_positions`;
    /// 3. `finish_velocities`: end-of-tick angular velocities from momenta;
    /// 4. `snap_kinematic`: targeted kinematic bodies land exactly on their
    ///    targets and stop;
    /// 5. `clear_forces`;
    /// 6. `sleep`: timers advance, resting bodies fall asleep;
    /// 7. the tick counter advances.
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

        report.kinematic_bodies = self.stage_kinematic_targets();

        let (contacts, reinserted) = self.stage_collide();
        report.candidate_pairs = contacts.candidates;
        report.narrow_tests = contacts.narrow_tests;
        report.touching_pairs = contacts.touching;
        report.contact_points = contacts.points;
        report.begin_events = contacts.begin_events;
        report.end_events = contacts.end_events;
        report.proxies_reinserted = reinserted;
        report.buffer_growths = contacts.growths;

        let (hot, live) = self.bodies.hot_slots_mut();
        for _ in 0..cfg.substeps {
            let c = integrate::integrate_velocities(hot, live, cfg.gravity, h);
            report.awake_bodies = c.integrated;
            report.gyroscopic_solves += c.gyroscopic;
            integrate::integrate_positions(hot, live, h);
        }
        integrate::finish_angular_velocities(hot, live);

        self.stage_snap_kinematic();
        self.stage_clear_forces();
        let (hot, live) = self.bodies.hot_slots_mut();
        report.fell_asleep = sleep::update_sleep(hot, live, &cfg.sleep, cfg.tick_rate);
        report.sleeping_bodies = hot
            .iter()
            .zip(live)
            .filter(|(b, l)| **l && b.kind == BodyKind::Dynamic && b.sleeping)
            .count() as u32;

        self.tick += 1;
        report.tick = self.tick;
        report
    }

    /// Kinematic bodies with a target get the constant velocities that carry
    /// their centre and orientation there in one tick. Returns how many
    /// kinematic bodies will move.
    fn stage_kinematic_targets(&mut self) -> u32 {
        let ticks_per_second = self.config.tick_rate as i64;
        let mut moving = 0;
        self.bodies.for_each_mut(|b, cold| {
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
        self.bodies.for_each_mut(|b, cold| {
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

    fn stage_clear_forces(&mut self) {
        let (hot, live) = self.bodies.hot_slots_mut();
        for (b, &alive) in hot.iter_mut().zip(live) {
            if alive {
                b.force = Vec3::ZERO;
                b.torque = Vec3::ZERO;
            }
        }
    }
}
