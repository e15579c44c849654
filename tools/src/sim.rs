//! `lockstep sim`: load a scene file, step it, print hashes.

use std::io::Write;
use std::path::{Path, PathBuf};

use lockstep_core::World;
use lockstep_core::math::Faults;
use lockstep_core::scene::SceneError;
use thiserror::Error;

use super::dump::dump_state;

/// What `lockstep sim` was asked to do.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SimOptions {
    /// The scene file.
    pub scene: PathBuf,
    /// How many ticks to step.
    pub ticks: u64,
    /// Print the hash every this many ticks (≥ 1).
    pub hash_every: u64,
    /// Where to write the final state as JSON, if anywhere.
    pub dump_state: Option<PathBuf>,
}

/// What a run did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SimSummary {
    /// Ticks stepped.
    pub ticks: u64,
    /// The final state hash.
    pub final_hash: u64,
}

/// Why `lockstep sim` failed.
#[derive(Debug, Error)]
pub enum SimError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// The scene file is invalid.
    #[error("{0}")]
    Scene(#[from] SceneError),
    /// The simulation raised an arithmetic fault: its results, and every
    /// hash from here on, cannot be trusted.
    #[error(
        "arithmetic fault at tick {tick}: {faults} (the scene is outside the fixed-point range)"
    )]
    Fault {
        /// The tick whose step raised it.
        tick: u64,
        /// Which faults.
        faults: Faults,
    },
    /// An argument is out of range.
    #[error("{0}")]
    InvalidArgument(String),
    /// Writing the output failed.
    #[error("writing output: {0}")]
    Output(std::io::Error),
}

/// Reads and builds a scene file into a world.
///
/// # Errors
/// [`SimError::Io`] if the file cannot be read; [`SimError::Scene`] with
/// the file, line and column of the problem.
pub fn load_scene_file(path: &Path) -> Result<World, SimError> {
    let text = std::fs::read_to_string(path).map_err(|source| SimError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(lockstep_core::scene::load_world(
        &text,
        &path.display().to_string(),
    )?)
}

/// Runs `lockstep sim`, writing `tick <n> <hash>` lines to `out`.
///
/// # Errors
/// See [`SimError`].
pub fn run_sim(opts: &SimOptions, out: &mut impl Write) -> Result<SimSummary, SimError> {
    if opts.hash_every == 0 {
        return Err(SimError::InvalidArgument(
            "--hash-every must be at least 1".into(),
        ));
    }
    let mut world = load_scene_file(&opts.scene)?;
    for _ in 0..opts.ticks {
        let report = world.step();
        if !report.faults.is_empty() {
            return Err(SimError::Fault {
                tick: report.tick,
                faults: report.faults,
            });
        }
        if report.tick.is_multiple_of(opts.hash_every) {
            writeln!(out, "tick {} {:016x}", report.tick, world.state_hash())
                .map_err(SimError::Output)?;
        }
    }
    if let Some(path) = &opts.dump_state {
        let json = serde_json::to_string_pretty(&dump_state(&world)).map_err(|e| SimError::Io {
            path: path.clone(),
            source: std::io::Error::other(e),
        })?;
        std::fs::write(path, json + "\n").map_err(|source| SimError::Io {
            path: path.clone(),
            source,
        })?;
    }
    Ok(SimSummary {
        ticks: opts.ticks,
        final_hash: world.state_hash(),
    })
}
