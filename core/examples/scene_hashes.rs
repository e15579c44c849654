//! Steps a scene and prints its state hash every tick, needing nothing but
//! lockstep-core and the standard library: the program the cross-architecture
//! check (`scripts/cross-arch-check.sh`) builds for wasm32-wasip1 and runs
//! under Node's WASI, to compare with the same program built natively.
//!
//! ```text
//! scene_hashes --scene FILE  --ticks N   # a scene file (docs/scene-format.md)
//! scene_hashes --random SEED --ticks N   # a seeded random scene
//! ```
//!
//! Prints one line per tick, `tick <n> <16 hex digits>`: for a scene file
//! the very lines `lockstep sim --scene FILE --ticks N` prints (and the
//! golden files in `tests/golden` hold every 50th of them).
//!
//! The random scene (`support/random_scene.rs`) is built through the core
//! API from integers only, so every architecture builds the same world.

use std::io::{BufWriter, Write};
use std::process::ExitCode;

#[path = "support/random_scene.rs"]
mod random_scene;
use random_scene::random_world;

const USAGE: &str = "usage: scene_hashes (--scene FILE | --random SEED) --ticks N";

/// Where the world comes from.
enum Source {
    Scene(String),
    Random(u64),
}

fn main() -> ExitCode {
    let (source, ticks) = match parse_args(std::env::args().skip(1)) {
        Ok(v) => v,
        Err(e) => {
            eprintln!("scene_hashes: {e}\n{USAGE}");
            return ExitCode::from(2);
        }
    };
    let world = match &source {
        Source::Scene(path) => std::fs::read_to_string(path)
            .map_err(|e| format!("{path}: {e}"))
            .and_then(|text| {
                lockstep_core::scene::load_world(&text, path).map_err(|e| e.to_string())
            }),
        Source::Random(seed) => {
            random_world(*seed).map_err(|e| format!("random scene {seed}: {e}"))
        }
    };
    let mut world = match world {
        Ok(w) => w,
        Err(e) => {
            eprintln!("scene_hashes: error: {e}");
            return ExitCode::from(2);
        }
    };
    let mut out = BufWriter::new(std::io::stdout().lock());
    for _ in 0..ticks {
        let report = world.step();
        if !report.faults.is_empty() {
            let _ = out.flush();
            eprintln!(
                "scene_hashes: error: arithmetic fault at tick {}: {}",
                report.tick, report.faults
            );
            return ExitCode::from(2);
        }
        if let Err(e) = writeln!(out, "tick {} {:016x}", report.tick, world.state_hash()) {
            eprintln!("scene_hashes: error: writing output: {e}");
            return ExitCode::from(2);
        }
    }
    match out.flush() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("scene_hashes: error: writing output: {e}");
            ExitCode::from(2)
        }
    }
}

fn parse_args(mut args: impl Iterator<Item = String>) -> Result<(Source, u64), String> {
    let mut source = None;
    let mut ticks = None;
    while let Some(flag) = args.next() {
        let mut value = || args.next().ok_or(format!("{flag} needs a value"));
        match flag.as_str() {
            "--scene" => source = Some(Source::Scene(value()?)),
            "--random" => {
                let v = value()?;
                let seed = v.parse().map_err(|_| format!("--random {v}: not a u64"))?;
                source = Some(Source::Random(seed));
            }
            "--ticks" => {
                let v = value()?;
                ticks = Some(v.parse().map_err(|_| format!("--ticks {v}: not a u64"))?);
            }
            _ => return Err(format!("unknown argument {flag}")),
        }
    }
    match (source, ticks) {
        (Some(s), Some(t)) => Ok((s, t)),
        (None, _) => Err("--scene or --random is required".into()),
        (_, None) => Err("--ticks is required".into()),
    }
}
