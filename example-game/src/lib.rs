//! # lockstep-example-game
//!
//! A small game of its own on lockstep, and the template a team copies:
//! up to four players each steer a paddle (a kinematic box) around a table
//! without walls to push crates off it, and drop balls in front of their
//! paddle. Everything a game brings is here:
//!
//! - its input format ([`PaddleInput`], 2 bytes: a compass direction and a
//!   drop button), which the server relays without reading;
//! - its rules ([`PaddleRules`]): kinematic targets for the paddles, balls
//!   spawned on a press, bodies removed once they fell off the table;
//! - its scene ([`SCENE`], `example-game/scene.toml`);
//! - its [`RulesFactory`] ([`PaddleGame`]): rules id and version, fresh
//!   rules per world, and scripted bot input;
//! - its tests (`tests/`): bots playing it over QUIC against a real
//!   lockstep server, and its recorded replays checked by
//!   `lockstep-testkit`.
//!
//! Like every rules implementation it is deterministic: `Scalar` and
//! integer arithmetic only, bodies visited in handle order.

#![warn(missing_docs)]

use lockstep_client::game::{
    BotPolicy, BotView, GameError, GameRules, GameState, GameStateError, RulesFactory, RulesId,
};
use lockstep_core::shape::{Shape, Sphere};
use lockstep_core::{BodyDesc, BodyHandle, BodyKind, ColliderDesc, Scalar, Transform, Vec3, World};

/// The table (`example-game/scene.toml`).
pub const SCENE: &str = include_str!("../scene.toml");

/// Players (one paddle each).
pub const PLAYERS: usize = 4;

/// Input bytes per tick.
pub const INPUT_LEN: usize = 2;

/// Paddle speed along each axis: 4 m/s, as metres per tick at 60 Hz.
pub const PADDLE_STEP: Scalar = Scalar::from_bits((4i64 << 32) / 60);

/// How far from the centre a paddle's centre may go on x and z (m).
pub const PADDLE_LIMIT: Scalar = Scalar::from_int(5);

/// Bodies whose centre falls below this height are removed (m).
pub const FALL_LIMIT: Scalar = Scalar::from_int(-3);

/// Most balls on the table at once.
pub const MAX_BALLS: usize = 8;

/// Ticks between two drops of one player.
pub const DROP_COOLDOWN: u64 = 30;

/// Radius of a dropped ball: 0.25 m.
pub const BALL_RADIUS: Scalar = Scalar::from_bits(1 << 30);

/// The name of dropped balls.
pub const BALL_NAME: &str = "ball";

/// Unit steps of the eight compass directions, 1 = +x, counter-clockwise
/// seen from above (+x, then towards -z).
const DIRECTIONS: [(i32, i32); 8] = [
    (1, 0),
    (1, -1),
    (0, -1),
    (-1, -1),
    (-1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

/// One player's input for one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PaddleInput {
    /// 0: stand still; 1..=8: move along a compass direction (1 = +x,
    /// counter-clockwise seen from above).
    pub dir: u8,
    /// Drop a ball in front of the paddle.
    pub drop: bool,
}

impl PaddleInput {
    /// The wire form: `[dir, flags]`, flags bit 0 = drop.
    pub fn encode(&self) -> Vec<u8> {
        vec![self.dir, u8::from(self.drop)]
    }

    /// Reads the wire form; `None` for anything else (wrong length, a
    /// direction above 8, unknown flag bits), which the rules treat as no
    /// input.
    pub fn decode(bytes: &[u8]) -> Option<PaddleInput> {
        match *bytes {
            [dir, flags] if dir <= 8 && flags <= 1 => Some(PaddleInput {
                dir,
                drop: flags == 1,
            }),
            _ => None,
        }
    }
}

/// The example game as a [`RulesFactory`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PaddleGame;

impl PaddleGame {
    /// Rules id.
    pub const ID: &'static str = "example-paddles";
    /// Rules version: bump it whenever the rules turn the same inputs into
    /// different forces, so old replays say so instead of mismatching.
    /// 2: each player's last drop is game state (in every tick's hash).
    pub const VERSION: u32 = 2;
}

impl RulesFactory for PaddleGame {
    fn rules_id(&self) -> RulesId {
        RulesId::new(Self::ID, Self::VERSION)
    }

    fn new_rules(&self, world: &World) -> Result<Box<dyn GameRules>, GameError> {
        Ok(Box::new(PaddleRules::new(world)?))
    }

    fn bot_input(&self, seed: u64, slot: u8, tick: u64) -> Vec<u8> {
        bot_input(seed, slot, tick).encode()
    }

    fn bot_policy(&self, _seed: u64, slot: u8) -> Option<Box<dyn BotPolicy>> {
        Some(Box::new(ChaseBot::new(slot)))
    }
}

/// The rules for one world: the paddles' handles and each player's last
/// drop. The last drops are the game's own state: saved into the world
/// after every tick (field [`LAST_DROP_FIELD`]) and loaded back into the
/// rules of a restored world, so a late joiner's cooldowns are everyone's.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PaddleRules {
    paddles: Vec<BodyHandle>,
    last_drop: [Option<u64>; PLAYERS],
}

impl PaddleRules {
    /// Finds the paddles ("paddle0".."paddle3", kinematic) in a world built
    /// from [`SCENE`].
    ///
    /// # Errors
    /// [`GameError`] naming a paddle that is missing or not kinematic.
    pub fn new(world: &World) -> Result<PaddleRules, GameError> {
        let mut paddles = Vec::with_capacity(PLAYERS);
        for slot in 0..PLAYERS {
            let name = format!("paddle{slot}");
            let h = world
                .find_body(&name)
                .ok_or_else(|| GameError::MissingBody(name.clone()))?;
            let kind = world.body(h).map(|b| b.kind()).ok();
            if kind != Some(BodyKind::Kinematic) {
                return Err(GameError::BadBody {
                    name,
                    problem: "a paddle must be a kinematic body".into(),
                });
            }
            paddles.push(h);
        }
        Ok(PaddleRules {
            paddles,
            last_drop: [None; PLAYERS],
        })
    }

    /// Whether player `slot` may drop a ball at `tick` (its cooldown has
    /// passed).
    pub fn ready(&self, slot: u8, tick: u64) -> bool {
        self.last_drop
            .get(usize::from(slot))
            .is_some_and(|d| d.is_none_or(|t| tick >= t + DROP_COOLDOWN))
    }

    /// The tick of player `slot`'s last drop.
    pub fn last_drop(&self, slot: u8) -> Option<u64> {
        self.last_drop.get(usize::from(slot)).copied().flatten()
    }

    fn balls(world: &World) -> usize {
        world
            .body_handles()
            .filter(|&h| world.body(h).is_ok_and(|b| b.name() == BALL_NAME))
            .count()
    }

    fn drop_ball(world: &mut World, at: Vec3) {
        let desc = BodyDesc::dynamic().name(BALL_NAME).position(at);
        let Ok(h) = world.create_body(&desc) else {
            return;
        };
        if let Ok(sphere) = Sphere::new(BALL_RADIUS) {
            let _ = world.add_collider(h, ColliderDesc::new(Shape::Sphere(sphere)));
        }
    }
}

/// The game-state field of the last drops: per player, the tick of the
/// last drop plus one (0: none yet).
pub const LAST_DROP_FIELD: &str = "last_drop";

impl GameRules for PaddleRules {
    fn save_state(&self, state: &mut GameState) -> Result<(), GameStateError> {
        let words = self.last_drop.map(|t| t.map_or(0, |t| t + 1));
        state.set_words(LAST_DROP_FIELD, &words)
    }

    fn load_state(&mut self, state: &GameState) -> Result<(), GameError> {
        let Some(words) = state.words(LAST_DROP_FIELD) else {
            // A world no tick was applied to yet.
            return Ok(());
        };
        let words = <[u64; PLAYERS]>::try_from(words).map_err(|_| {
            GameError::BadState(format!(
                "{LAST_DROP_FIELD}: {} words, expected {PLAYERS}",
                words.len()
            ))
        })?;
        self.last_drop = words.map(|w| w.checked_sub(1));
        Ok(())
    }

    fn apply_inputs(&mut self, world: &mut World, tick: u64, inputs: &[(u8, &[u8])]) {
        // Whatever fell off the table goes (handle order: the same on every
        // peer).
        let fallen: Vec<BodyHandle> = world
            .body_handles()
            .filter(|&h| {
                world
                    .body(h)
                    .is_ok_and(|b| b.kind() == BodyKind::Dynamic && b.position().y < FALL_LIMIT)
            })
            .collect();
        for h in fallen {
            let _ = world.remove_body(h);
        }
        let mut balls = Self::balls(world);
        for &(slot, bytes) in inputs {
            let s = usize::from(slot);
            let Some(&paddle) = self.paddles.get(s) else {
                continue;
            };
            let input = PaddleInput::decode(bytes).unwrap_or_default();
            let Ok(body) = world.body(paddle) else {
                continue;
            };
            let (pos, rot) = (body.position(), body.rotation());
            if input.dir > 0 {
                let (dx, dz) = DIRECTIONS[usize::from(input.dir - 1)];
                let clamp = |v: Scalar| v.max(-PADDLE_LIMIT).min(PADDLE_LIMIT);
                let target = Vec3::new(
                    clamp(pos.x + PADDLE_STEP * Scalar::from_int(dx)),
                    pos.y,
                    clamp(pos.z + PADDLE_STEP * Scalar::from_int(dz)),
                );
                let _ = world.set_kinematic_target(paddle, Transform::new(target, rot));
            }
            let ready = self.last_drop[s].is_none_or(|t| tick >= t + DROP_COOLDOWN);
            if input.drop && ready && balls < MAX_BALLS {
                self.last_drop[s] = Some(tick);
                balls += 1;
                // Above the paddle, towards the centre: pos × 3/4, 2 m up.
                let inward = Scalar::from_ratio(3, 4);
                let at = Vec3::new(pos.x * inward, Scalar::from_int(2), pos.z * inward);
                Self::drop_ball(world, at);
            }
        }
    }
}

/// A bot that plays: it steers its paddle towards the crate nearest to it
/// (straight at it along the compass direction closest to the way there)
/// and drops a ball whenever its cooldown allows, reading the cooldown from
/// the rules it sees and remembering its own presses (an input applies a
/// few ticks after it is chosen).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChaseBot {
    slot: u8,
    pressed: Option<u64>,
}

impl ChaseBot {
    /// The bot of player `slot`.
    pub fn new(slot: u8) -> ChaseBot {
        ChaseBot {
            slot,
            pressed: None,
        }
    }
}

impl BotPolicy for ChaseBot {
    fn input(&mut self, view: &BotView<'_>) -> Vec<u8> {
        let world = view.world;
        let ready = view
            .rules
            .downcast_ref::<PaddleRules>()
            .is_some_and(|r| r.ready(self.slot, view.tick))
            && self.pressed.is_none_or(|p| view.tick >= p + DROP_COOLDOWN);
        if ready {
            self.pressed = Some(view.tick);
        }
        let Some(paddle) = world
            .find_body(&format!("paddle{}", self.slot))
            .and_then(|h| world.body(h).ok())
            .map(|b| b.position())
        else {
            return PaddleInput::default().encode();
        };
        let crates = world.body_handles().filter_map(|h| {
            let b = world.body(h).ok()?;
            b.name().starts_with("crate").then(|| b.position() - paddle)
        });
        let nearest = crates.min_by_key(|d| (d.x * d.x + d.z * d.z).to_bits());
        let dir = nearest.map_or(0, |d| {
            // Within 0.3 m along an axis counts as there.
            let near = Scalar::from_ratio(3, 10);
            let sign = |v: Scalar| {
                if v > near {
                    1
                } else if v < -near {
                    -1
                } else {
                    0
                }
            };
            let want = (sign(d.x), sign(d.z));
            DIRECTIONS
                .iter()
                .position(|&step| step == want)
                .map_or(0, |i| i as u8 + 1)
        });
        PaddleInput { dir, drop: ready }.encode()
    }
}

/// SplitMix64 of the bot's coordinates: the blind bots' whole "brain".
fn mix(seed: u64, slot: u8, stream: u64, n: u64) -> u64 {
    let mut z = seed
        ^ (u64::from(slot) << 56)
        ^ stream.wrapping_mul(0xd1b5_4a32_d192_ed03)
        ^ n.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A bot's input: a pure function of `(seed, slot, tick)`. It keeps a
/// direction (or stands still, one time in nine) for 40 ticks, and presses
/// drop on one tick of each 20 with probability 1/4.
pub fn bot_input(seed: u64, slot: u8, tick: u64) -> PaddleInput {
    let dir = (mix(seed, slot, 1, tick / 40) % 9) as u8;
    let drop = tick.is_multiple_of(20) && mix(seed, slot, 2, tick / 20).is_multiple_of(4);
    PaddleInput { dir, drop }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn world() -> World {
        lockstep_core::scene::load_world(SCENE, "example-game/scene.toml").expect("scene")
    }

    #[test]
    fn input_round_trips_and_junk_is_no_input() {
        for dir in 0..=8 {
            for drop in [false, true] {
                let i = PaddleInput { dir, drop };
                assert_eq!(PaddleInput::decode(&i.encode()), Some(i));
            }
        }
        assert_eq!(PaddleInput::decode(&[9, 0]), None);
        assert_eq!(PaddleInput::decode(&[1, 2]), None);
        assert_eq!(PaddleInput::decode(&[1]), None);
        assert_eq!(PaddleInput::decode(&[1, 0, 0]), None);
    }

    #[test]
    fn a_paddle_moves_its_step_per_tick_and_stops_at_the_limit() {
        let mut w = world();
        let mut rules = PaddleRules::new(&w).unwrap();
        let p0 = w.find_body("paddle0").unwrap();
        let z0 = w.body(p0).unwrap().position().z;
        // dir 7 = +z: 10 ticks at 4/60 m per tick.
        for t in 0..10 {
            rules.apply_inputs(&mut w, t, &[(0, &[7, 0])]);
            w.step();
        }
        let z = w.body(p0).unwrap().position().z;
        let moved = (z - z0).to_f64();
        assert!((moved - 10.0 * 4.0 / 60.0).abs() < 1e-6, "{moved}");
        // dir 3 = -z for 60 ticks: clamped at z = -5.
        for t in 10..70 {
            rules.apply_inputs(&mut w, t, &[(0, &[3, 0])]);
            w.step();
        }
        assert_eq!(w.body(p0).unwrap().position().z, -PADDLE_LIMIT);
    }

    #[test]
    fn drops_respect_the_cooldown_and_fallen_bodies_are_removed() {
        let mut w = world();
        let mut rules = PaddleRules::new(&w).unwrap();
        let before = w.body_handles().count();
        for t in 0..31 {
            rules.apply_inputs(&mut w, t, &[(0, &[0, 1]), (1, &[0, 1])]);
            w.step();
        }
        // Two players, drops at ticks 0 and 30 each.
        assert_eq!(PaddleRules::balls(&w), 4);
        assert_eq!(w.body_handles().count(), before + 4);
        // A crate pushed off the table is removed once below the limit.
        let c = w.find_body("crate0").unwrap();
        let far = Vec3::new(Scalar::from_int(20), Scalar::ZERO, Scalar::ZERO);
        w.set_pose(c, Transform::new(far, lockstep_core::Quat::IDENTITY))
            .unwrap();
        let mut t = 31;
        while w.find_body("crate0").is_some() && t < 200 {
            rules.apply_inputs(&mut w, t, &[]);
            w.step();
            t += 1;
        }
        assert!(w.find_body("crate0").is_none(), "crate0 still there at {t}");
        // Fall time to y = -3 from 0.4 at g = 9.81: about 0.83 s = 50 ticks.
        assert!((75..=90).contains(&t), "{t}");
    }

    #[test]
    fn the_chase_bot_heads_for_the_nearest_crate_and_drops_when_ready() {
        let mut w = world();
        let mut rules = PaddleRules::new(&w).unwrap();
        let mut bot = ChaseBot::new(0);
        let ask = |w: &World, rules: &PaddleRules, bot: &mut ChaseBot, tick| {
            let view = BotView {
                world: w,
                rules,
                slot: 0,
                tick,
            };
            PaddleInput::decode(&bot.input(&view)).unwrap()
        };
        let first = ask(&w, &rules, &mut ChaseBot::new(0), 0);
        assert!(first.drop && first.dir > 0, "{first:?}");
        // Moving as told brings the paddle closer to its nearest crate.
        let distance = |w: &World| {
            let p = w.body(w.find_body("paddle0").unwrap()).unwrap().position();
            w.body_handles()
                .filter_map(|h| {
                    let b = w.body(h).ok()?;
                    b.name()
                        .starts_with("crate")
                        .then(|| (b.position() - p).length().to_f64())
                })
                .fold(f64::MAX, f64::min)
        };
        let before = distance(&w);
        for t in 0..20 {
            let input = ask(&w, &rules, &mut bot, t).encode();
            rules.apply_inputs(&mut w, t, &[(0, &input)]);
            w.step();
        }
        assert!(distance(&w) < before - 0.5, "{before} -> {}", distance(&w));
        // It dropped at tick 0 and waits for the cooldown.
        assert_eq!(rules.last_drop(0), Some(0));
        assert!(!ask(&w, &rules, &mut bot, 20).drop);
        assert!(ask(&w, &rules, &mut bot, DROP_COOLDOWN).drop);
        // Its own press counts before the rules see it.
        assert!(!ask(&w, &rules, &mut bot, DROP_COOLDOWN + 1).drop);
    }

    #[test]
    fn the_last_drops_are_game_state_and_load_back() {
        let mut w = world();
        let mut rules = PaddleRules::new(&w).unwrap();
        rules.apply_inputs(&mut w, 5, &[(2, &[0, 1])]);
        rules.save_state(w.game_state_mut()).unwrap();
        assert_eq!(
            w.game_state().words(LAST_DROP_FIELD),
            Some(&[0, 0, 6, 0][..])
        );
        let copy = World::restore(&w.snapshot()).unwrap();
        let restored = PaddleGame.rules_for(&copy).unwrap();
        let restored = restored.downcast_ref::<PaddleRules>().unwrap();
        assert_eq!(restored.last_drop(2), Some(5));
        assert!(!restored.ready(2, 20) && restored.ready(2, 35));
        // A state that is not the game's is refused.
        let mut bad = copy.clone();
        bad.game_state_mut()
            .set_words(LAST_DROP_FIELD, &[1])
            .unwrap();
        assert!(matches!(
            PaddleGame.rules_for(&bad).err(),
            Some(GameError::BadState(_))
        ));
    }

    #[test]
    fn bots_press_every_direction_and_drop_sometimes() {
        let mut dirs = [0u32; 9];
        let mut drops = 0;
        for tick in 0..40 * 200 {
            let i = bot_input(3, 1, tick);
            dirs[usize::from(i.dir)] += 1;
            drops += u32::from(i.drop);
        }
        assert!(dirs.iter().all(|&n| n > 0), "{dirs:?}");
        // 400 windows of 20 ticks, a quarter of them drop.
        assert!((60..=140).contains(&drops), "{drops}");
    }
}
