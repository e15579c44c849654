//! Sleeping: bodies that stay slow for long enough stop being simulated.
//!
//! Without contacts every body is its own island, so sleep is decided per
//! body: a dynamic body whose linear speed stays under
//! [`SleepConfig::linear_threshold`] and angular speed under
//! [`SleepConfig::angular_threshold`] for [`SleepConfig::time_to_sleep`]
//! falls asleep; its velocities are zeroed and the integrator skips it until
//! something wakes it (a force, an impulse, a velocity or pose set by the
//! game).

use serde::{Deserialize, Serialize};

use crate::body::{BodyHot, BodyKind};
use crate::math::{Scalar, Vec3};

/// When bodies fall asleep.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct SleepConfig {
    /// Whether bodies may fall asleep at all.
    pub enabled: bool,
    /// Linear speed under which a body counts as resting, m/s.
    pub linear_threshold: Scalar,
    /// Angular speed under which a body counts as resting, rad/s.
    pub angular_threshold: Scalar,
    /// How long a body must rest before it sleeps, s.
    pub time_to_sleep: Scalar,
}

impl Default for SleepConfig {
    /// Enabled; 0.05 m/s, 0.05 rad/s, 0.5 s (the values Box2D, Jolt and
    /// Rapier use).
    fn default() -> SleepConfig {
        SleepConfig {
            enabled: true,
            linear_threshold: Scalar::from_ratio(1, 20),
            angular_threshold: Scalar::from_ratio(1, 20),
            time_to_sleep: Scalar::HALF,
        }
    }
}

impl SleepConfig {
    /// Whole ticks of rest before a body sleeps: `ceil(time_to_sleep ·
    /// tick_rate)`, at least 1.
    pub fn ticks_to_sleep(&self, tick_rate: u32) -> u32 {
        let t = self.time_to_sleep.to_bits() as i128 * tick_rate as i128;
        let ticks = (t + (1 << 32) - 1) >> 32;
        ticks.clamp(1, u32::MAX as i128) as u32
    }
}

/// Updates rest counters after a tick; returns how many bodies fell asleep.
/// A body sleeps once it has rested for `ceil(time_to_sleep · tick_rate)`
/// consecutive ticks.
///
/// Determinism: slot order; each body's decision reads only its own state.
pub(crate) fn update_sleep(
    hot: &mut [BodyHot],
    live: &[bool],
    cfg: &SleepConfig,
    tick_rate: u32,
) -> u32 {
    if !cfg.enabled {
        return 0;
    }
    let lin2 = cfg.linear_threshold.wide_mul(cfg.linear_threshold) as u128;
    let ang2 = cfg.angular_threshold.wide_mul(cfg.angular_threshold) as u128;
    let ticks_to_sleep = cfg.ticks_to_sleep(tick_rate);
    let mut fell_asleep = 0;
    for (b, &alive) in hot.iter_mut().zip(live) {
        if !alive || b.kind != BodyKind::Dynamic || b.sleeping {
            continue;
        }
        let resting = b.linear_velocity.length_squared_wide() < lin2
            && b.angular_velocity.length_squared_wide() < ang2;
        if resting {
            b.rest_ticks = b.rest_ticks.saturating_add(1);
            if b.rest_ticks >= ticks_to_sleep {
                b.sleeping = true;
                b.linear_velocity = Vec3::ZERO;
                b.angular_velocity = Vec3::ZERO;
                b.angular_momentum = Vec3::ZERO;
                fell_asleep += 1;
            }
        } else {
            b.rest_ticks = 0;
        }
    }
    fell_asleep
}
