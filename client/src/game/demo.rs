//! The demo game: players drive balls around a walled arena with piles of
//! boxes to knock over.
//!
//! # Rules, per tick, for each player slot in ascending order
//! 1. **Who takes part.** A slot with an input entry is in the match; its
//!    bytes are decoded as a [`DemoInput`], and anything that does not decode
//!    counts as no input (stand still, no jump). A slot without an entry
//!    whose body sleeps is left alone: players who never joined stay asleep
//!    and untouched. A slot without an entry whose body is awake (a player
//!    who left) is driven as if it gave no input, and put back to sleep once
//!    it stands still on the floor.
//! 2. **Floor and walls (a stand-in for contacts).** lockstep-core has no
//!    collision detection or contact solver yet, so gravity alone would pull
//!    every player through the floor. Until it has, the rules keep players
//!    in, in two halves:
//!    * *corrective*, before the inputs are applied: a player whose centre
//!      is below its resting height (floor top + radius), or within
//!      [`GROUND_EPSILON`] above it and not rising faster than
//!      [`SNAP_SPEED`], is put on the floor (`set_pose` at the resting
//!      height, keeping x, z and the rotation) with its downward velocity
//!      zeroed, and then *stands on the floor*; a player whose centre is past
//!      a wall (the wall's inner face minus its radius) is put back at the
//!      wall with its outward velocity zeroed;
//!    * *speculative*, once its forces are planned: if the coming step would
//!      end with the centre past the floor or a wall, the acceleration toward
//!      it is cancelled (for the floor that includes gravity: the floor's
//!      normal force, which is what holds a standing player up), and if
//!      coasting would still carry it past, the velocity toward it is cut so
//!      that the centre arrives exactly there at the end of the step.
//!
//!    So a player's centre never ends a step below the floor or past a wall
//!    (up to a few ulps of rounding). All of this goes away once the contact
//!    solver exists.
//! 3. **Movement.** The wished horizontal velocity is `move · MAX_SPEED /
//!    100`; a horizontal force `F = m · (v_wished − v) · GAIN` drives the
//!    body toward it, with the acceleration capped at [`MAX_ACCEL`] (in the
//!    air too: the demo has full air control).
//! 4. **Jump.** A player standing on the floor who presses jump gets an
//!    upward impulse `m · JUMP_SPEED` (and no support force that tick).
//!
//! Every number is a [`Scalar`]; nothing here can panic, whatever the bytes.

use lockstep_core::math::{FaultScope, Faults};
use lockstep_core::scene::{SceneError, load_world};
use lockstep_core::shape::Shape;
use lockstep_core::{BodyHandle, BodyKind, Quat, Scalar, Transform, Vec3, World};

use super::input::DemoInput;
use super::{GameError, GameRules};

/// Player slots in the demo: bodies "player0" to "player15".
pub const MAX_PLAYERS: usize = 16;

/// Top horizontal speed, m/s (`move = ±100`).
pub const MAX_SPEED: Scalar = Scalar::from_int(6);

/// How fast the horizontal velocity closes on the wished one, 1/s: the
/// drive force is `m · (v_wished − v) · GAIN`. With a 60 Hz tick a gain of
/// 10/s closes 1/6 of the gap per tick, far from the explicit-integration
/// stability limit (gain · dt < 2).
pub const GAIN: Scalar = Scalar::from_int(10);

/// Cap on the horizontal drive acceleration, m/s²: from rest, a player
/// reaches 90 % of [`MAX_SPEED`] in about 0.3 s.
pub const MAX_ACCEL: Scalar = Scalar::from_int(20);

/// Vertical speed given by a jump, m/s (about 1.27 m high with g = 9.81).
pub const JUMP_SPEED: Scalar = Scalar::from_int(5);

/// How far above its resting height a player still counts as standing on
/// the floor: 2⁻¹⁰ m ≈ 0.98 mm.
pub const GROUND_EPSILON: Scalar = Scalar::from_bits(1 << 22);

/// The vertical speed under which a player near the floor is snapped onto
/// it, and the horizontal speed under which a player who left is put to
/// sleep: 2⁻⁴ = 0.0625 m/s.
pub const SNAP_SPEED: Scalar = Scalar::from_bits(1 << 28);

/// Where one player's body origin is allowed to be.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlayerLimits {
    /// The body.
    pub body: BodyHandle,
    /// Height of the centre when resting on the floor: floor top + radius.
    pub rest_y: Scalar,
    /// Lowest x of the centre: the inner face of the −x wall + radius.
    pub x_min: Scalar,
    /// Highest x of the centre.
    pub x_max: Scalar,
    /// Lowest z of the centre.
    pub z_min: Scalar,
    /// Highest z of the centre.
    pub z_max: Scalar,
}

/// The demo game's rules for one match (see the module docs for the
/// rules). Holds only the player bodies and their limits, found once by
/// [`DemoGame::new`], and the faults its own arithmetic raised.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DemoGame {
    /// One per slot, `MAX_PLAYERS` of them.
    players: Vec<PlayerLimits>,
    faults: Faults,
}

impl DemoGame {
    /// The embedded demo scene (`scenes/demo.toml`).
    pub const SCENE: &'static str = include_str!("../../../scenes/demo.toml");

    /// The file name errors in [`DemoGame::SCENE`] are reported against.
    pub const SCENE_FILE: &'static str = "scenes/demo.toml";

    /// The world for a match of the demo: builds [`DemoGame::SCENE`].
    ///
    /// # Errors
    /// A [`SceneError`] only if the embedded scene is broken (a test pins
    /// that it is not).
    pub fn world() -> Result<World, SceneError> {
        load_world(Self::SCENE, Self::SCENE_FILE)
    }

    /// Rules for a world built by [`DemoGame::world`]: finds the floor
    /// ("ground"), the walls ("wall_x_neg", "wall_x_pos", "wall_z_neg",
    /// "wall_z_pos") and the player bodies ("player0".."player15") by name,
    /// and works out where each player may be.
    ///
    /// The floor and walls must be static bodies with one unrotated box
    /// each; each player a dynamic body with one sphere at its origin (so
    /// its extent does not depend on how it is turned).
    ///
    /// # Errors
    /// [`GameError`] naming the body that is missing or not as expected.
    pub fn new(world: &World) -> Result<DemoGame, GameError> {
        let floor_top = static_box(world, "ground")?.1.y;
        let x_lo = static_box(world, "wall_x_neg")?.1.x;
        let x_hi = static_box(world, "wall_x_pos")?.0.x;
        let z_lo = static_box(world, "wall_z_neg")?.1.z;
        let z_hi = static_box(world, "wall_z_pos")?.0.z;
        let mut players = Vec::with_capacity(MAX_PLAYERS);
        for slot in 0..MAX_PLAYERS {
            let name = format!("player{slot}");
            let (body, radius) = player_ball(world, &name)?;
            let limits = PlayerLimits {
                body,
                rest_y: floor_top + radius,
                x_min: x_lo + radius,
                x_max: x_hi - radius,
                z_min: z_lo + radius,
                z_max: z_hi - radius,
            };
            if limits.x_min > limits.x_max || limits.z_min > limits.z_max {
                return Err(GameError::BadBody {
                    name,
                    problem: "the ball does not fit between the walls".into(),
                });
            }
            players.push(limits);
        }
        Ok(DemoGame {
            players,
            faults: Faults::NONE,
        })
    }

    /// A player's body and the box its centre is kept in; `None` for a slot
    /// ≥ [`MAX_PLAYERS`].
    pub fn limits(&self, slot: u8) -> Option<PlayerLimits> {
        self.players.get(usize::from(slot)).copied()
    }

    /// Every arithmetic fault raised by the rules' own arithmetic since
    /// creation (sticky). The world's step reports its faults itself; these
    /// are the ones raised in [`GameRules::apply_inputs`], which runs
    /// outside the step. Non-empty means the results can no longer be
    /// trusted, as for the world's faults.
    pub fn faults(&self) -> Faults {
        self.faults
    }

    fn apply(&self, world: &mut World, inputs: &[(u8, &[u8])]) {
        // Determinism: the first entry of a slot wins and slots are visited
        // in ascending order, whatever order the entries came in.
        let mut entries: [Option<&[u8]>; MAX_PLAYERS] = [None; MAX_PLAYERS];
        for &(slot, bytes) in inputs {
            if let Some(e) = entries.get_mut(usize::from(slot))
                && e.is_none()
            {
                *e = Some(bytes);
            }
        }
        let step = StepShape::of(world);
        for (limits, entry) in self.players.iter().zip(entries) {
            let Ok(body) = world.body(limits.body) else {
                continue;
            };
            if entry.is_none() && body.is_sleeping() {
                continue;
            }
            let mass = body.mass();
            let input = entry.and_then(DemoInput::decode).unwrap_or_default();
            let grounded = settle(world, limits);
            let Ok(body) = world.body(limits.body) else {
                continue;
            };
            let (p, v0) = (body.position(), body.linear_velocity());
            if entry.is_none() && grounded && horizontal_speed_below(v0, SNAP_SPEED) {
                // A player who left, now standing still: back to sleep.
                let _ = world.sleep_body(limits.body);
                continue;
            }
            let jump = grounded && input.jump;
            let mut accel = drive_acceleration(v0, input);
            let mut v = v0;
            // The velocity the step starts with: the jump impulse is applied
            // below, but the floor-and-walls limit must already see it.
            let mut v_start = v0;
            if jump {
                v_start.y += JUMP_SPEED;
            }
            let axes = [
                (0, Some(limits.x_min), Some(limits.x_max)),
                (1, Some(limits.rest_y), None),
                (2, Some(limits.z_min), Some(limits.z_max)),
            ];
            for (i, lo, hi) in axes {
                let (a, vs) = step.keep_within(
                    p.get(i),
                    v_start.get(i),
                    step.gravity.get(i),
                    accel.get(i),
                    lo,
                    hi,
                );
                accel.set(i, a);
                if vs != v_start.get(i) {
                    // The impulse below still adds the jump's share.
                    v.set(i, vs - (v_start.get(i) - v0.get(i)));
                }
            }
            if v != v0 {
                let _ = world.set_linear_velocity(limits.body, v);
            }
            let force = accel * mass;
            if !force.is_zero() {
                let _ = world.apply_force(limits.body, force);
            }
            if jump {
                let impulse = Vec3::new(Scalar::ZERO, JUMP_SPEED * mass, Scalar::ZERO);
                let _ = world.apply_impulse(limits.body, impulse);
            }
        }
    }
}

impl GameRules for DemoGame {
    /// Applies the demo rules (see the module docs). `tick` is not used:
    /// the demo's rules are the same every tick.
    fn apply_inputs(&mut self, world: &mut World, _tick: u64, inputs: &[(u8, &[u8])]) {
        let ((), faults) = FaultScope::run(|| self.apply(world, inputs));
        self.faults = self.faults.union(faults);
    }
}

/// What the rules need to know about the coming step to predict where a
/// body ends it.
#[derive(Clone, Copy, Debug)]
struct StepShape {
    gravity: Vec3,
    /// The tick length, s.
    dt: Scalar,
    /// `dt² · (n + 1) / (2n)` for `n` substeps: under a constant
    /// acceleration `a`, semi-implicit Euler moves a body by
    /// `v·dt + a·dt²·(n + 1)/(2n)` over one tick (exactly, up to rounding).
    accel_factor: Scalar,
}

impl StepShape {
    fn of(world: &World) -> StepShape {
        let cfg = world.config();
        let n = i64::from(cfg.substeps);
        let dt = cfg.dt();
        StepShape {
            gravity: cfg.gravity,
            dt,
            accel_factor: (dt * dt).mul_int(n + 1).div_int(2 * n),
        }
    }

    /// The speculative half of the floor-and-walls stand-in, for one axis:
    /// given the position `p`, the starting velocity `v`, gravity `g` and
    /// the planned acceleration `a` along the axis, returns the acceleration
    /// and starting velocity that keep the body's end-of-step position
    /// within `[lo, hi]` (either may be open). When the body would end past
    /// a limit, the acceleration toward it is cancelled (including gravity's
    /// part: the floor's normal force), and if coasting would still carry it
    /// past, the velocity toward the limit is cut so that the body arrives
    /// exactly at it at the end of the step.
    fn keep_within(
        &self,
        p: Scalar,
        v: Scalar,
        g: Scalar,
        a: Scalar,
        lo: Option<Scalar>,
        hi: Option<Scalar>,
    ) -> (Scalar, Scalar) {
        let end = |v: Scalar, net: Scalar| p + v * self.dt + net * self.accel_factor;
        let (mut a, mut v) = (a, v);
        if let Some(lo) = lo
            && end(v, g + a) < lo
        {
            if (g + a).is_negative() {
                a = -g;
            }
            if end(v, g + a) < lo {
                v = (lo - p) / self.dt;
            }
        }
        if let Some(hi) = hi
            && end(v, g + a) > hi
        {
            if (g + a).is_positive() {
                a = -g;
            }
            if end(v, g + a) > hi {
                v = (hi - p) / self.dt;
            }
        }
        (a, v)
    }
}

/// The corrective half of the floor-and-walls stand-in for contacts
/// (module docs, rule 2): puts the player back on the floor and inside the
/// walls, zeroing the velocity into them. Returns whether the player stands
/// on the floor (centre at the resting height, vertical velocity zero).
fn settle(world: &mut World, limits: &PlayerLimits) -> bool {
    let Ok(body) = world.body(limits.body) else {
        return false;
    };
    let pose = body.pose();
    let v0 = body.linear_velocity();
    let (mut p, mut v) = (pose.translation, v0);
    let mut grounded = false;

    let below = p.y < limits.rest_y;
    let near = p.y <= limits.rest_y + GROUND_EPSILON && v.y <= SNAP_SPEED;
    if below || near {
        p.y = limits.rest_y;
        if v.y <= SNAP_SPEED {
            v.y = Scalar::ZERO;
            grounded = true;
        }
    }
    let walls = [
        (&mut p.x, &mut v.x, limits.x_min, limits.x_max),
        (&mut p.z, &mut v.z, limits.z_min, limits.z_max),
    ];
    for (pos, vel, lo, hi) in walls {
        if *pos <= lo {
            *pos = lo;
            *vel = (*vel).max(Scalar::ZERO);
        } else if *pos >= hi {
            *pos = hi;
            *vel = (*vel).min(Scalar::ZERO);
        }
    }
    if p != pose.translation {
        let _ = world.set_pose(limits.body, Transform::new(p, pose.rotation));
    }
    if v != v0 {
        let _ = world.set_linear_velocity(limits.body, v);
    }
    grounded
}

/// Whether the horizontal part of `v` is slower than `limit` (compared
/// exactly, squared in i128).
fn horizontal_speed_below(v: Vec3, limit: Scalar) -> bool {
    let h = Vec3::new(v.x, Scalar::ZERO, v.z);
    h.length_squared_wide() < limit.wide_mul(limit) as u128
}

/// The horizontal drive acceleration toward the wished velocity (module
/// docs, rule 3): `(v_wished − v) · GAIN`, its length capped at
/// [`MAX_ACCEL`].
fn drive_acceleration(v: Vec3, input: DemoInput) -> Vec3 {
    let wished = |m: i8| MAX_SPEED.mul_int(i64::from(m)).div_int(100);
    let a = Vec3::new(
        (wished(input.move_x) - v.x) * GAIN,
        Scalar::ZERO,
        (wished(input.move_z) - v.z) * GAIN,
    );
    match a.normalize_and_length() {
        Some((dir, len)) if len > MAX_ACCEL => dir * MAX_ACCEL,
        _ => a,
    }
}

fn bad_body(name: &str, problem: &str) -> GameError {
    GameError::BadBody {
        name: name.to_owned(),
        problem: problem.to_owned(),
    }
}

/// The body called `name`, which must be of `kind` and carry exactly one
/// collider, with that collider.
fn single_collider<'w>(
    world: &'w World,
    name: &str,
    kind: BodyKind,
) -> Result<
    (
        lockstep_core::BodyRef<'w>,
        &'w lockstep_core::collider::Collider,
    ),
    GameError,
> {
    let h = world
        .find_body(name)
        .ok_or_else(|| GameError::MissingBody(name.to_owned()))?;
    let body = world.body(h).map_err(|e| bad_body(name, &e.to_string()))?;
    if body.kind() != kind {
        return Err(bad_body(name, &format!("expected a {} body", kind.name())));
    }
    let [c] = body.colliders() else {
        return Err(bad_body(name, "expected exactly one collider"));
    };
    let collider = world
        .collider(*c)
        .map_err(|e| bad_body(name, &e.to_string()))?;
    Ok((body, collider))
}

/// The box of a static body with one unrotated box collider: (min, max).
fn static_box(world: &World, name: &str) -> Result<(Vec3, Vec3), GameError> {
    let (body, collider) = single_collider(world, name, BodyKind::Static)?;
    let bad = |problem: &str| bad_body(name, problem);
    let Shape::Cuboid(cuboid) = &collider.shape else {
        return Err(bad("expected a box shape"));
    };
    if body.rotation() != Quat::IDENTITY || collider.local_pose.rotation != Quat::IDENTITY {
        return Err(bad("expected an unrotated box"));
    }
    let center = body.position() + collider.local_pose.translation;
    Ok((center - cuboid.half_extents, center + cuboid.half_extents))
}

/// A player body: dynamic, with one sphere at its origin. Returns the
/// handle and the radius.
fn player_ball(world: &World, name: &str) -> Result<(BodyHandle, Scalar), GameError> {
    let (body, collider) = single_collider(world, name, BodyKind::Dynamic)?;
    let h = body.handle();
    let bad = |problem: &str| bad_body(name, problem);
    let Shape::Sphere(sphere) = &collider.shape else {
        return Err(bad("expected a sphere shape"));
    };
    if !collider.local_pose.translation.is_zero() {
        return Err(bad("expected the sphere at the body origin"));
    }
    Ok((h, sphere.radius))
}
