//! `lockstep`: the offline command-line tool.

use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use lockstep_client::game::Demo;
use lockstep_client::offline::{SimOptions, check_replay_command, run_sim};

/// lockstep: deterministic lockstep physics, offline tools.
#[derive(Parser, Debug)]
#[command(name = "lockstep", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Step a scene file and print its state hash (`tick <n> <16 hex digits>`).
    Sim {
        /// The scene file (TOML, see docs/scene-format.md).
        #[arg(long)]
        scene: PathBuf,
        /// How many ticks to step.
        #[arg(long)]
        ticks: u64,
        /// Print the hash every K ticks.
        #[arg(long, default_value_t = 1, value_name = "K")]
        hash_every: u64,
        /// Write every body's final state as JSON (exact decimal strings).
        #[arg(long, value_name = "OUT.json")]
        dump_state: Option<PathBuf>,
    },
    /// Re-simulate a recorded match of the demo game and check every tick's
    /// agreed hash.
    ///
    /// Prints one OK line (status 0), or the first mismatch (tick, expected,
    /// got, and the diverging bodies where the replay recorded body hashes)
    /// with status 1. Status 2: not a valid replay; 3: recorded with other
    /// rules (id or version); 4: recorded with another state-hash layout.
    Replay {
        /// The replay file (written by lockstep-server).
        file: PathBuf,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Replay { file } => ExitCode::from(check_replay_command(&file, &Demo)),
        Command::Sim {
            scene,
            ticks,
            hash_every,
            dump_state,
        } => {
            let opts = SimOptions {
                scene,
                ticks,
                hash_every,
                dump_state,
            };
            let stdout = std::io::stdout();
            let mut out = BufWriter::new(stdout.lock());
            let result = run_sim(&opts, &mut out);
            let flushed = out.flush();
            match (result, flushed) {
                (Ok(_), Ok(())) => ExitCode::SUCCESS,
                (Err(e), _) => {
                    eprintln!("lockstep sim: error: {e}");
                    ExitCode::from(2)
                }
                (Ok(_), Err(e)) => {
                    eprintln!("lockstep sim: error: writing output: {e}");
                    ExitCode::from(2)
                }
            }
        }
    }
}
