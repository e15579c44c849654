//! Sleeping: islands of touching bodies that stay slow for long enough stop
//! being simulated, together.
//!
//! An island is a set of awake dynamic bodies joined by touching solid
//! contacts (static and kinematic bodies do not join islands: a floor under
//! two piles does not make them one island). Each body counts the
//! consecutive ticks its linear speed stayed under
//! [`SleepConfig::linear_threshold`] and its angular speed under
//! [`SleepConfig::angular_threshold`]; an island falls asleep when its
//! *least* rested body has rested for [`SleepConfig::time_to_sleep`], so a
//! box never freezes while the box on top of it still settles. A body
//! touching a moving kinematic body (a platform) does not count as resting.
//! Sleeping bodies have their velocities zeroed and are skipped by the
//! integrator and the solver until something wakes them (a force, an
//! impulse, a velocity or pose set by the game, an awake body touching
//! them, a body they rest on moved or removed); a woken body wakes the
//! sleepers it touches in the next step's `wake_touched` stage, so a
//! sleeping island wakes as a whole.
//!
//! Islands are rebuilt every step by union–find over the touching pairs.
//! The partition does not depend on the order of unions, and the sleep
//! decision depends only on the partition, so the result is the same
//! whatever order the pairs come in.

use serde::{Deserialize, Serialize};

use crate::body::{BodyHot, BodyKind};
use crate::math::Scalar;

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

/// Scratch for the island pass, kept by the world between steps so a warm
/// world never allocates.
#[derive(Clone, Debug, Default)]
pub(crate) struct IslandScratch {
    /// Union–find parent per body slot (only awake dynamic slots are set and
    /// read, so a step never touches a sleeper's entry).
    parent: Vec<u32>,
    /// Per island root: the fewest rest ticks of its bodies.
    min_rest: Vec<u32>,
    /// The rest ticks an island needs to fall asleep (as of the last
    /// [`update_sleep`]).
    ticks_to_sleep: u32,
}

impl IslandScratch {
    /// Whether the awake dynamic body in slot `s` is in an island that
    /// [`update_sleep`] found rested: it falls asleep now. Valid for the
    /// awake dynamic slots of the last `update_sleep`, until the next.
    pub(crate) fn rested(&mut self, s: u32) -> bool {
        let root = find(&mut self.parent, s) as usize;
        self.min_rest[root] >= self.ticks_to_sleep
    }
}

/// What the sleep stage did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct SleepStats {
    /// Bodies that fell asleep this tick.
    pub fell_asleep: u32,
    /// Islands of awake dynamic bodies (before any fell asleep).
    pub islands: u32,
    /// Whether the scratch had to grow (a new body slot since last step).
    pub grew: bool,
}

/// How one touching solid pair's two bodies relate, for the island pass:
/// body slots `a` and `b`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Link {
    /// The first body's slot.
    pub a: u32,
    /// The second body's slot.
    pub b: u32,
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    // Path halving: every visited node skips to its grandparent.
    while parent[i as usize] != i {
        let up = parent[parent[i as usize] as usize];
        parent[i as usize] = up;
        i = up;
    }
    i
}

fn is_awake_dynamic(b: &BodyHot) -> bool {
    b.kind == BodyKind::Dynamic && !b.sleeping
}

fn is_moving_kinematic(b: &BodyHot) -> bool {
    b.kind == BodyKind::Kinematic && (!b.linear_velocity.is_zero() || !b.angular_velocity.is_zero())
}

/// Updates rest counters after a tick and puts whole islands to sleep.
///
/// `awake` lists the awake slots (ascending; sleeping and static bodies are
/// never visited); `links` yields the body slots of the touching solid
/// contact pairs, and must include every such pair with an awake dynamic
/// body (pairs between sleeping or static bodies change nothing and may be
/// left out). Decides and counts; writes no sleep flag: the awake set puts
/// each awake dynamic body whose island rested
/// ([`IslandScratch::rested`]) to sleep.
///
/// Determinism: slot order for the counters; union by the lower root (any
/// union order gives the same partition); decisions read only the
/// partition and the counters.
pub(crate) fn update_sleep(
    hot: &mut [BodyHot],
    awake: &[u32],
    links: impl Iterator<Item = Link>,
    cfg: &SleepConfig,
    tick_rate: u32,
    scratch: &mut IslandScratch,
) -> SleepStats {
    let mut stats = SleepStats::default();
    if !cfg.enabled {
        return stats;
    }
    let n = hot.len();
    if scratch.parent.len() < n {
        stats.grew = scratch.parent.capacity() < n || scratch.min_rest.capacity() < n;
        scratch.parent.resize(n, 0);
        scratch.min_rest.resize(n, 0);
    }
    let lin2 = cfg.linear_threshold.wide_mul(cfg.linear_threshold) as u128;
    let ang2 = cfg.angular_threshold.wide_mul(cfg.angular_threshold) as u128;
    let ticks_to_sleep = cfg.ticks_to_sleep(tick_rate);

    // 1. Rest counters, and every awake dynamic body its own island (only
    //    awake dynamic slots are ever read from the scratch).
    for &s in awake {
        let b = &mut hot[s as usize];
        if !is_awake_dynamic(b) {
            continue;
        }
        scratch.parent[s as usize] = s;
        let resting = b.linear_velocity.length_squared_wide() < lin2
            && b.angular_velocity.length_squared_wide() < ang2;
        b.rest_ticks = if resting {
            b.rest_ticks.saturating_add(1)
        } else {
            0
        };
    }
    // 2. Touching pairs join islands; riding a moving kinematic body is not
    //    resting. (Removed bodies have a static, awake-less hot state.)
    for link in links {
        let (a, b) = (link.a as usize, link.b as usize);
        if a >= n || b >= n {
            continue;
        }
        match (is_awake_dynamic(&hot[a]), is_awake_dynamic(&hot[b])) {
            (true, true) => {
                let ra = find(&mut scratch.parent, a as u32);
                let rb = find(&mut scratch.parent, b as u32);
                if ra != rb {
                    let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
                    scratch.parent[hi as usize] = lo;
                }
            }
            (true, false) if is_moving_kinematic(&hot[b]) => hot[a].rest_ticks = 0,
            (false, true) if is_moving_kinematic(&hot[a]) => hot[b].rest_ticks = 0,
            _ => {}
        }
    }
    // 3. Each island's least rested body.
    for &s in awake {
        if is_awake_dynamic(&hot[s as usize]) {
            scratch.min_rest[s as usize] = u32::MAX;
        }
    }
    for &s in awake {
        let b = &hot[s as usize];
        if !is_awake_dynamic(b) {
            continue;
        }
        let root = find(&mut scratch.parent, s) as usize;
        if root == s as usize {
            stats.islands += 1;
        }
        scratch.min_rest[root] = scratch.min_rest[root].min(b.rest_ticks);
    }
    // 4. Rested islands fall asleep whole (counted here, put to sleep by
    //    the caller).
    scratch.ticks_to_sleep = ticks_to_sleep;
    for &s in awake {
        if is_awake_dynamic(&hot[s as usize]) && scratch.rested(s) {
            stats.fell_asleep += 1;
        }
    }
    stats
}
