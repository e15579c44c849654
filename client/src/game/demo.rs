//! The demo game: players walk around a walled arena with piles of boxes
//! to knock over.
//!
//! Each player is a kinematic capsule moved by the character controller
//! ([`lockstep_core::character`]): it slides along walls and crates, climbs
//! steps, snaps to the ground and pushes crates with a force of at most
//! [`PUSH_FORCE`].
//!
//! # Rules, per tick, for each player slot in ascending order
//! 1. **Who moves.** A slot with an input entry is in the match; its bytes
//!    are decoded as a [`DemoInput`], and anything that does not decode
//!    counts as no input (stand still, no jump). A slot without an entry is
//!    driven as if it gave no input while its body still moves (a player who
//!    left mid-run or mid-jump slows down and lands), and is left alone once
//!    it has stopped: players who never joined stand where the scene put
//!    them.
//! 2. **Walking.** The wished horizontal velocity is `move · MAX_SPEED /
//!    100`. The horizontal velocity closes on it at `(v_wished − v) · GAIN`,
//!    the acceleration capped at [`MAX_ACCEL`] (in the air too: the demo
//!    has full air control), where `v` is the velocity the body moved with
//!    last tick less the velocity of the ground under it
//!    ([`CharacterController::ground_velocity`]: the walk relative to the
//!    crate a player stands on; the controller adds the crate's carry). A
//!    player with no stick input below [`REST_SPEED`] stops.
//! 3. **Jump.** A player on walkable ground (slopes up to 45°, [`STANDING_COS`])
//!    who presses jump leaves it at `JUMP_SPEED`; in the air, jump does
//!    nothing.
//! 4. **The move.** The controller sweeps the capsule along the tick's
//!    motion (gravity included) and gives the body the velocity that carries
//!    it there during the step.
//!
//! Every number is a [`Scalar`]; nothing here can panic, whatever the bytes.

use lockstep_core::character::{CharacterConfig, CharacterController, CharacterInput};
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

/// Below this horizontal speed a player with no stick input stops:
/// 2⁻⁷ ≈ 0.0078 m/s (the closing rule alone would shrink the speed by a
/// sixth per tick and never reach zero).
pub const REST_SPEED: Scalar = Scalar::from_bits(1 << 25);

/// The steepest ground a player stands and jumps on: cos 45°, rounded down
/// (floors, crate tops and gentle slopes, not walls).
pub const STANDING_COS: Scalar = Scalar::from_bits(3_037_000_499);

/// The most force a player puts on a crate it walks into, N: a 153.6 kg
/// crate alone on the floor (friction 0.6) needs 904 N to slide, a bottom
/// crate of a pyramid with the crates above it pressing and rubbing on it
/// more than 2,000 N. 6,000 N lets a player shove into a pyramid and topple
/// it, as the demo's knock-over game wants, while a crate still slows a
/// player down.
pub const PUSH_FORCE: Scalar = Scalar::from_int(6000);

/// Where one player's centre can be: inside the arena, on or above the
/// floor (the character controller keeps it there).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlayerLimits {
    /// The body.
    pub body: BodyHandle,
    /// Height of the centre when standing on the floor: floor top +
    /// half-height + radius + the controller's skin.
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
/// rules). Holds only the players' controllers and limits, found once by
/// [`DemoGame::new`], and the faults its own arithmetic raised; everything
/// that moves is in the world.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DemoGame {
    /// One per slot, `MAX_PLAYERS` of them.
    players: Vec<PlayerLimits>,
    controllers: Vec<CharacterController>,
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
    /// each; each player an upright kinematic body with one capsule at its
    /// origin (what the character controller drives).
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
        let mut controllers = Vec::with_capacity(MAX_PLAYERS);
        let config = player_config();
        for slot in 0..MAX_PLAYERS {
            let name = format!("player{slot}");
            let body = world
                .find_body(&name)
                .ok_or_else(|| GameError::MissingBody(name.clone()))?;
            let controller = CharacterController::attach(world, body, config)
                .map_err(|e| bad_body(&name, &e.to_string()))?;
            let capsule = controller.capsule();
            let radius = capsule.radius;
            let limits = PlayerLimits {
                body,
                rest_y: floor_top + capsule.half_height + radius + config.skin,
                x_min: x_lo + radius,
                x_max: x_hi - radius,
                z_min: z_lo + radius,
                z_max: z_hi - radius,
            };
            if limits.x_min > limits.x_max || limits.z_min > limits.z_max {
                return Err(GameError::BadBody {
                    name,
                    problem: "the capsule does not fit between the walls".into(),
                });
            }
            players.push(limits);
            controllers.push(controller);
        }
        Ok(DemoGame {
            players,
            controllers,
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

    fn apply(&self, world: &mut World, inputs: &[(u8, &[u8])]) -> Faults {
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
        let dt = world.dt();
        let mut faults = Faults::NONE;
        for (controller, entry) in self.controllers.iter().zip(entries) {
            let Ok(body) = world.body(controller.body()) else {
                continue;
            };
            let v = body.linear_velocity();
            // A player who is not in the match and has stopped stays put.
            if entry.is_none() && v.is_zero() {
                continue;
            }
            let input = entry.and_then(DemoInput::decode).unwrap_or_default();
            // The walk relative to the ground: the body's velocity also
            // holds last tick's carry by the crate under the player, which
            // the controller adds again.
            let v = v - controller.ground_velocity(world).unwrap_or(Vec3::ZERO);
            let mut walk = Vec3::new(v.x, Scalar::ZERO, v.z) + drive_acceleration(v, input) * dt;
            if input.move_x == 0 && input.move_z == 0 && horizontal_speed_below(walk, REST_SPEED) {
                walk = Vec3::ZERO;
            }
            let wish = CharacterInput {
                velocity: walk,
                jump_speed: if input.jump { JUMP_SPEED } else { Scalar::ZERO },
            };
            if let Ok(m) = controller.move_character(world, &wish) {
                faults = faults.union(m.faults);
            }
        }
        faults
    }
}

impl GameRules for DemoGame {
    /// Applies the demo rules (see the module docs). `tick` is not used:
    /// the demo's rules are the same every tick.
    fn apply_inputs(&mut self, world: &mut World, _tick: u64, inputs: &[(u8, &[u8])]) {
        let (own, faults) = FaultScope::run(|| self.apply(world, inputs));
        self.faults = self.faults.union(faults).union(own);
    }
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

/// The character controller settings of every player.
fn player_config() -> CharacterConfig {
    CharacterConfig {
        max_slope_cos: STANDING_COS,
        push_force: PUSH_FORCE,
        ..CharacterConfig::default()
    }
}
