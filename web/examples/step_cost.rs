//! The native side of the browser client's step cost (docs/browser.md):
//! re-simulates a demo replay (the browser test prints the path of its
//! match's) with exactly what the module does for each tick (the rules
//! and the step, `apply_tick`, then the state hash), timing each tick
//! with `Instant`, and prints the median, 90th percentile and maximum.
//! Every hash is checked against the replay's agreed one.
//!
//! ```text
//! cargo run --release -p lockstep-web --example step_cost -- REPLAY
//! ```

use std::process::ExitCode;
use std::time::Instant;

use lockstep_client::game::{Demo, RulesFactory, apply_bundle, start_match};
use lockstep_proto::Replay;

fn main() -> ExitCode {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: step_cost REPLAY");
        return ExitCode::from(2);
    };
    match run(&path) {
        Ok(line) => {
            println!("{line}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("step_cost: {path}: {e}");
            ExitCode::from(1)
        }
    }
}

fn run(path: &str) -> Result<String, String> {
    let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
    let replay = Replay::parse(&bytes).map_err(|e| e.to_string())?;
    let scene = std::str::from_utf8(&replay.header.scene).map_err(|e| e.to_string())?;
    let mut world =
        lockstep_core::scene::load_world(scene, "replay scene").map_err(|e| e.to_string())?;
    start_match(&mut world, replay.seed).map_err(|e| e.to_string())?;
    let mut rules = Demo.rules_for(&world).map_err(|e| e.to_string())?;
    let mut ms = Vec::with_capacity(replay.ticks.len());
    for (bundle, agreed) in replay.ticks.iter().zip(&replay.hashes) {
        let t0 = Instant::now();
        apply_bundle(&mut world, &mut *rules, bundle).map_err(|e| e.to_string())?;
        let hash = world.state_hash();
        ms.push(t0.elapsed().as_secs_f64() * 1e3);
        if agreed.is_some_and(|h| h != hash) {
            return Err(format!(
                "tick {}: hash {hash:016x}, the replay agreed {agreed:016x?}",
                bundle.tick
            ));
        }
    }
    if ms.is_empty() {
        return Err("no ticks".into());
    }
    ms.sort_by(f64::total_cmp);
    let at = |p: f64| ms[((p * ms.len() as f64) as usize).min(ms.len() - 1)];
    Ok(format!(
        "native step (release, Instant): median {:.3} ms, p90 {:.3} ms, max {:.3} ms over {} ticks",
        at(0.5),
        at(0.9),
        ms[ms.len() - 1],
        ms.len()
    ))
}
