//! The demo game: players drive balls around a walled arena with piles of
//! boxes to knock over.
//!
//! # Rules, per tick, for each player slot in ascending order
//! 1. **Who takes part.** A slot with an input entry is in the match; its
//!    bytes are decoded as a [`DemoInput`], and anything that does not decode
//!    counts as no input (stand still, no jump). A slot without an entry
//!    whose body sleeps is left alone: players who never joined stay asleep
//!    and untouched. A slot without an entry whose body is awake (a player
//!    who left) is driven as if it gave no input until it is slower than
//!    [`REST_SPEED`]; then it gets no force, comes to rest and falls asleep
//!    like any resting body.
//! 2. **Floor and walls** are the world's own contacts: the arena's boxes
//!    stop the balls, and the crates are knocked over (sleeping crates wake
//!    when a moving player touches them).
//! 3. **Movement.** The wished horizontal velocity is `move · MAX_SPEED /
//!    100`; a horizontal force `F = m · (v_wished − v) · GAIN` drives the
//!    body toward it, with the acceleration capped at [`MAX_ACCEL`] (in the
//!    air too: the demo has full air control).
//! 4. **Jump.** A player standing on something (a contact whose normal,
//!    seen from the player, points up by more than [`STANDING_COS`]) and
//!    not already rising (vertical speed under 1 m/s) who presses jump gets
//!    the impulse that sets its vertical speed to `JUMP_SPEED`.
//!
//! Every number is a [`Scalar`]; nothing here can panic, whatever the bytes.

use lockstep_core::math::{FaultScope, Faults};
use lockstep_core::scene::{SceneError, load_world};
use lockstep_core::shape::Shape;
use lockstep_core::{BodyHandle, BodyKind, Quat, Scalar, Vec3, World};

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

/// Below this horizontal speed a player who left gets no more drive force,
/// so it can come to rest and fall asleep: 2⁻⁷ ≈ 0.0078 m/s (a rolling
/// ball of radius 0.5 m then spins at v/r = 0.016 rad/s: both are under
/// the world's 0.05 sleep thresholds).
pub const REST_SPEED: Scalar = Scalar::from_bits(1 << 25);

/// A contact supports a player when its normal, pointing from the support
/// to the player, has an up component above this (cos 45°, rounded down):
/// floors and crate tops, not walls.
pub const STANDING_COS: Scalar = Scalar::from_bits(3_037_000_499);

/// Where one player's centre can be: inside the arena, on or above the
/// floor (the world's contacts keep it there).
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
        for (limits, entry) in self.players.iter().zip(entries) {
            let Ok(body) = world.body(limits.body) else {
                continue;
            };
            if entry.is_none() && body.is_sleeping() {
                continue;
            }
            if entry.is_some() && body.is_sleeping() {
                // A player in the match is awake, so it has its floor
                // contact (and can jump) even when it stands still.
                let _ = world.wake_body(limits.body);
            }
            let Ok(body) = world.body(limits.body) else {
                continue;
            };
            let mass = body.mass();
            let v = body.linear_velocity();
            let input = entry.and_then(DemoInput::decode).unwrap_or_default();
            // A player who left and has (almost) stopped gets no force: any
            // force would wake it, and it must be able to rest and sleep.
            let idle = entry.is_none() && horizontal_speed_below(v, REST_SPEED);
            let force = drive_acceleration(v, input) * mass;
            if !idle && !force.is_zero() {
                let _ = world.apply_force(limits.body, force);
            }
            // Not while already rising: the contact that launched the jump
            // is still listed until the next step's collision stage.
            if input.jump && v.y < Scalar::ONE && standing(world, limits.body) {
                // Sets the vertical speed to JUMP_SPEED, whatever it was (a
                // jump on the landing tick must not just cancel the fall).
                let impulse = Vec3::new(Scalar::ZERO, (JUMP_SPEED - v.y) * mass, Scalar::ZERO);
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

/// Whether a contact supports the player's body from below (rule 4): a
/// touching solid pair whose normal, turned to point from the other shape
/// to the player, has an up component above [`STANDING_COS`]. Scans the
/// world's contact pairs (a few hundred in the demo).
fn standing(world: &World, player: BodyHandle) -> bool {
    let Ok(body) = world.body(player) else {
        return false;
    };
    let [own] = body.colliders() else {
        return false;
    };
    world.contact_pairs().iter().any(|p| {
        if !p.touching || p.manifold.is_empty() {
            return false;
        }
        // The normal points from A to B.
        let up = if p.b == *own {
            p.manifold.normal.y
        } else if p.a == *own {
            -p.manifold.normal.y
        } else {
            return false;
        };
        up > STANDING_COS
    })
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
