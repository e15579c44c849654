//! The `rollback` suite: what prediction's rollbacks cost.
//!
//! A predicting client keeps the confirmed world and, on a rollback,
//! restores the predicted world from it (`World::clone_from` and the rules'
//! `load_state`: an in-memory copy, no serialisation) and simulates the
//! predicted ticks again. Per scene, after a warm-up of 120 ticks played
//! with the game's scripted bots:
//! * `restore`: clone_from + load_state, µs and ns per body;
//! * `snapshot`: the serialised alternative (`World::snapshot` then
//!   `World::restore`), for comparison;
//! * `step`: one tick (rules + step), ms;
//! * `deepest`: the most ticks a rollback can re-simulate within one
//!   60 Hz frame (16.7 ms) after its restore.
//!
//! Scenes: `demo` (4 players), `example_game` (4 players), `pile_500`
//! (500 boxes falling into a heap, no rules).

use std::fmt::Write as _;
use std::time::Instant;

use lockstep_client::game::{
    Demo, DemoGame, GameError, GameRules, RulesFactory, RulesId, apply_tick,
};
use lockstep_core::{BodyDesc, ColliderDesc, Scalar, Vec3, World};

use crate::{Options, SuiteOutput};

/// The scenes `--scenes` may name.
pub fn scene_names() -> Vec<&'static str> {
    vec!["demo", "example_game", "pile_500"]
}

/// No rules: the pile is physics only.
struct NoRules;

impl GameRules for NoRules {
    fn apply_inputs(&mut self, _: &mut World, _: u64, _: &[(u8, &[u8])]) {}
}

struct Pile;

impl RulesFactory for Pile {
    fn rules_id(&self) -> RulesId {
        RulesId::new("pile", 1)
    }
    fn new_rules(&self, _: &World) -> Result<Box<dyn GameRules>, GameError> {
        Ok(Box::new(NoRules))
    }
}

/// 500 unit boxes in a 10 × 10 × 5 block 1.2 m apart, dropped on the
/// ground.
fn pile() -> World {
    let mut w = World::new(lockstep_core::WorldConfig::default()).expect("world");
    let ground = w
        .create_body(&BodyDesc::fixed().position(Vec3::new(
            Scalar::ZERO,
            Scalar::from_int(-1),
            Scalar::ZERO,
        )))
        .expect("ground");
    let half = |x: i32| Scalar::from_int(x);
    w.add_collider(ground, ColliderDesc::cuboid(half(50), half(1), half(50)))
        .expect("ground box");
    let s = Scalar::from_ratio(6, 5);
    for i in 0..10 {
        for j in 0..5 {
            for k in 0..10 {
                let at = Vec3::new(
                    s * Scalar::from_int(i - 5),
                    Scalar::from_int(1) + s * Scalar::from_int(j),
                    s * Scalar::from_int(k - 5),
                );
                let b = w
                    .create_body(&BodyDesc::dynamic().position(at))
                    .expect("box");
                let h = Scalar::from_ratio(1, 2);
                w.add_collider(b, ColliderDesc::cuboid(h, h, h))
                    .expect("box shape");
            }
        }
    }
    w
}

struct Case {
    name: &'static str,
    world: World,
    game: Box<dyn RulesFactory>,
    players: u8,
}

fn cases(opts: &Options) -> Vec<Case> {
    let wanted = |n: &str| {
        opts.scenes
            .as_ref()
            .is_none_or(|s| s.iter().any(|x| x == n))
    };
    let mut out = Vec::new();
    if wanted("demo") {
        out.push(Case {
            name: "demo",
            world: DemoGame::world().expect("demo scene"),
            game: Box::new(Demo),
            players: 4,
        });
    }
    if wanted("example_game") {
        out.push(Case {
            name: "example_game",
            world: lockstep_core::scene::load_world(lockstep_example_game::SCENE, "example-game")
                .expect("example scene"),
            game: Box::new(lockstep_example_game::PaddleGame),
            players: 4,
        });
    }
    if wanted("pile_500") {
        out.push(Case {
            name: "pile_500",
            world: pile(),
            game: Box::new(Pile),
            players: 0,
        });
    }
    out
}

/// The minimum over `runs` of `f`'s time in ns.
fn best(runs: usize, mut f: impl FnMut()) -> f64 {
    (0..runs.max(1))
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_nanos() as f64
        })
        .fold(f64::MAX, f64::min)
}

/// The suite (see the module docs).
pub fn run(opts: &Options) -> SuiteOutput {
    let (warm, runs) = if opts.quick {
        (10, 2)
    } else {
        (120, opts.runs.unwrap_or(30))
    };
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{:<13} {:>7} {:>12} {:>12} {:>13} {:>10} {:>9}",
        "scene", "bodies", "restore µs", "ns/body", "snapshot µs", "step ms", "deepest"
    );
    let mut csv = String::from(
        "suite,scene,bodies,restore_us,restore_ns_per_body,snapshot_us,step_ms,deepest\n",
    );
    for mut c in cases(opts) {
        let mut rules = c.game.rules_for(&c.world).expect("rules");
        let inputs = |t: u64| -> Vec<(u8, Vec<u8>)> {
            (0..c.players)
                .map(|s| (s, c.game.bot_input(1, s, t)))
                .collect()
        };
        let mut tick = 0;
        let play = |w: &mut World, r: &mut dyn GameRules, t: u64| {
            let ins = inputs(t);
            let refs: Vec<(u8, &[u8])> = ins.iter().map(|(s, b)| (*s, b.as_slice())).collect();
            apply_tick(w, r, t, &refs).expect("tick");
        };
        for _ in 0..warm {
            play(&mut c.world, &mut *rules, tick);
            tick += 1;
        }
        let bodies = c.world.body_handles().count();
        let confirmed = c.world.clone();
        let mut predicted = c.world.clone();
        let mut predicted_rules = c.game.rules_for(&predicted).expect("rules");
        // Ahead by 8 ticks, so that a restore has something to undo.
        for t in tick..tick + 8 {
            play(&mut predicted, &mut *predicted_rules, t);
        }
        let restore = best(runs, || {
            predicted.clone_from(&confirmed);
            predicted_rules
                .load_state(predicted.game_state())
                .expect("state");
        });
        let snapshot = best(runs, || {
            let bytes = confirmed.snapshot();
            predicted = World::restore(&bytes).expect("restore");
            predicted_rules
                .load_state(predicted.game_state())
                .expect("state");
        });
        let steps = 8;
        let step = best(runs.min(10), || {
            predicted.clone_from(&confirmed);
            for t in tick..tick + steps {
                play(&mut predicted, &mut *predicted_rules, t);
            }
        });
        let step_ns = ((step - restore) / steps as f64).max(1.0);
        let frame_ns = 1e9 / 60.0;
        let deepest = ((frame_ns - restore) / step_ns).floor().max(0.0) as u64;
        let _ = writeln!(
            text,
            "{:<13} {:>7} {:>12.1} {:>12.1} {:>13.1} {:>10.3} {:>9}",
            c.name,
            bodies,
            restore / 1e3,
            restore / bodies as f64,
            snapshot / 1e3,
            step_ns / 1e6,
            deepest
        );
        let _ = writeln!(
            csv,
            "rollback,{},{bodies},{:.3},{:.3},{:.3},{:.4},{deepest}",
            c.name,
            restore / 1e3,
            restore / bodies as f64,
            snapshot / 1e3,
            step_ns / 1e6
        );
    }
    let _ = writeln!(
        text,
        "restore: World::clone_from + the rules' load_state (what a rollback does); snapshot: \
         World::snapshot + World::restore (the serialised alternative); deepest: ticks a rollback \
         can re-simulate in one 60 Hz frame (16.7 ms) after its restore"
    );
    SuiteOutput { text, csv }
}
