//! The offline programs: `lockstep`, or a game's offline commands
//! ([`App`]): sim, replay, synctest, tune, view.

use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Subcommand, ValueEnum};
use lockstep_tools::tune::{self, Candidates, CostBasis, TuneOptions};
use lockstep_tools::{
    SimOptions, SyncTestError, SyncTestOptions, check_replay_command, run_sim, sync_test,
};

use crate::App;

/// The offline commands.
#[derive(Subcommand, Debug)]
pub enum ToolCommand {
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
    /// Re-simulate a recorded match of this program's game and check every
    /// tick's agreed hash (a desync bundle: reproduce the desync).
    ///
    /// Prints one OK line (status 0), or the first mismatch (tick, expected,
    /// got, and the diverging bodies where the replay recorded body hashes)
    /// with status 1. Status 2: not a valid replay; 3: recorded with other
    /// rules (id or version); 4: recorded with another state-hash layout.
    Replay {
        /// The replay file (written by lockstep-server).
        file: PathBuf,
    },
    /// Find the cheapest settings whose trajectory stays within an error of a
    /// fine-step reference (see docs/tune.md).
    ///
    /// Runs the scene as it is (no game inputs) at the reference settings and
    /// at every combination of tick rate, substeps and solver/relax
    /// iterations; prints each one's error, cost and pass/fail, then the
    /// cheapest that passes, and draws the work-precision plot. Exits with
    /// status 1 if no combination passes, 2 on an error.
    Tune {
        /// The scene file (TOML, see docs/scene-format.md).
        #[arg(long)]
        scene: PathBuf,
        /// The largest error accepted: a length with m, cm or mm.
        #[arg(long, default_value = "1mm", value_name = "LENGTH", value_parser = tune::parse_length)]
        max_error: f64,
        /// How long to run, in the scene's own ticks [default: 2 s of them].
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
        ticks: Option<u64>,
        /// Where to write the plot (SCENE.svg) and the table (SCENE.csv).
        #[arg(long, default_value = "out/tune", value_name = "DIR")]
        out: PathBuf,
        /// Timed runs per combination after the measuring run (the minimum is kept).
        #[arg(long, default_value_t = 5, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=100))]
        repeats: u32,
        /// What the choice minimises: measured CPU time, or the deterministic work count.
        #[arg(long, value_enum, default_value_t = Cost::Cpu)]
        cost: Cost,
        /// Tick rates to try, Hz (the scene's own is added).
        #[arg(long, value_delimiter = ',', value_name = "LIST", default_values_t = tune::DEFAULT_TICK_RATES)]
        tick_rates: Vec<u32>,
        /// Substep counts to try (the scene's own is added).
        #[arg(long, value_delimiter = ',', value_name = "LIST", default_values_t = tune::DEFAULT_SUBSTEPS)]
        substeps: Vec<u32>,
        /// Solver (push-out) iteration counts to try.
        #[arg(long, value_delimiter = ',', value_name = "LIST", default_values_t = tune::DEFAULT_SOLVER_ITERATIONS)]
        iterations: Vec<u32>,
        /// Relax iteration counts to try.
        #[arg(long, value_delimiter = ',', value_name = "LIST", default_values_t = tune::DEFAULT_RELAX_ITERATIONS)]
        relax: Vec<u32>,
    },
    /// Check the game's determinism on this machine: play its scene with
    /// scripted bots beside a twin and, every tick, restore the state of
    /// --rollback ticks ago into fresh rules and re-simulate; print the
    /// first tick and field that differ (status 1), or OK (status 0).
    Synctest(SyncTestArgs),
    /// Look at a scene, a replay or a desync bundle in a browser.
    ///
    /// Re-simulates the file (a scene for --ticks ticks with no inputs; a
    /// replay or bundle with its recorded inputs and the game's rules),
    /// then serves a page on a local HTTP socket and prints its URL. The
    /// page draws every body, with a tick slider, overlays and each body's
    /// exact state; a bundle shows the majority and the diverging player
    /// side by side. Runs until Ctrl-C.
    View {
        /// The scene file, replay or desync bundle.
        file: PathBuf,
        /// Where to serve the page (port 0: any free port).
        #[arg(long, default_value = "127.0.0.1:0", value_name = "ADDR")]
        listen: std::net::SocketAddr,
        /// The first tick shown [default: 0; for a bundle, the last --ticks
        /// ticks up to the desync].
        #[arg(long, value_name = "TICK")]
        from: Option<u64>,
        /// How many ticks to show: a scene is stepped to --from + N [default:
        /// 600]; a replay shows N ticks from --from [default: 3600, a minute
        /// at 60 Hz]. Every frame is kept in memory and sent to the browser.
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
        ticks: Option<u64>,
    },
}

/// `synctest`'s flags.
#[derive(clap::Args, Debug)]
pub struct SyncTestArgs {
    /// The scene file [default: the game's own scene].
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Ticks to play.
    #[arg(long, default_value_t = 600)]
    ticks: u64,
    /// How many ticks back each tick's rollback restores.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u64).range(1..=64))]
    rollback: u64,
    /// Players, each playing the game's scripted bot input.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(1..=16))]
    players: u8,
    /// Seed of the bot inputs.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// `--cost`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Cost {
    /// CPU time per simulated second (minimum of the timed runs).
    Cpu,
    /// The deterministic work count per simulated second.
    Work,
}

/// Runs one offline command with `app`'s game.
pub fn run_tool(app: &App, command: ToolCommand) -> ExitCode {
    match command {
        ToolCommand::Replay { file } => ExitCode::from(check_replay_command(&file, &*app.game)),
        ToolCommand::Synctest(args) => synctest(app, &args),
        ToolCommand::View {
            file,
            listen,
            from,
            ticks,
        } => view(
            app,
            &file,
            listen,
            lockstep_tools::view::Window { from, ticks },
        ),
        ToolCommand::Tune {
            scene,
            max_error,
            ticks,
            out,
            repeats,
            cost,
            tick_rates,
            substeps,
            iterations,
            relax,
        } => {
            let opts = TuneOptions {
                scene,
                max_error,
                ticks,
                repeats,
                cost: match cost {
                    Cost::Cpu => CostBasis::Cpu,
                    Cost::Work => CostBasis::Work,
                },
                candidates: Candidates {
                    tick_rates,
                    substeps,
                    solver_iterations: iterations,
                    relax_iterations: relax,
                },
                out: Some(out),
            };
            let stdout = std::io::stdout();
            let mut w = stdout.lock();
            match tune::run_tune(&opts, &mut w) {
                Ok(report) if report.chosen.is_some() => ExitCode::SUCCESS,
                Ok(_) => ExitCode::from(1),
                Err(e) => {
                    eprintln!("lockstep tune: error: {e}");
                    ExitCode::from(2)
                }
            }
        }
        ToolCommand::Sim {
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

fn synctest(app: &App, args: &SyncTestArgs) -> ExitCode {
    let (text, label) = match &args.scene {
        Some(path) => match std::fs::read_to_string(path) {
            Ok(t) => (t, path.display().to_string()),
            Err(e) => {
                eprintln!("synctest: error: {}: {e}", path.display());
                return ExitCode::from(2);
            }
        },
        None => (app.scene.clone(), app.scene_name.clone()),
    };
    let options = SyncTestOptions {
        ticks: args.ticks,
        rollback: args.rollback,
        players: args.players,
        seed: args.seed,
    };
    match sync_test(&text, &label, &*app.game, &options) {
        Ok(r) => {
            println!(
                "OK: {} ({}) deterministic over {} ticks with {} players: a twin agreed on every \
                 tick and {} ticks were re-simulated from states {} ticks back; final hash {:016x}",
                app.game.rules_id(),
                label,
                r.ticks,
                args.players,
                r.resimulated,
                args.rollback,
                r.final_hash
            );
            ExitCode::SUCCESS
        }
        Err(e @ SyncTestError::Diverged { .. }) => {
            println!("FAILED: {} ({label}) {e}", app.game.rules_id());
            ExitCode::from(1)
        }
        Err(e) => {
            eprintln!("synctest: error: {e}");
            ExitCode::from(2)
        }
    }
}

fn view(
    app: &App,
    file: &std::path::Path,
    listen: std::net::SocketAddr,
    window: lockstep_tools::view::Window,
) -> ExitCode {
    let data = match lockstep_tools::view::load_view(file, &*app.game, window) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("lockstep view: error: {e}");
            return ExitCode::from(2);
        }
    };
    let listener = match std::net::TcpListener::bind(listen) {
        Ok(l) => l,
        Err(e) => {
            eprintln!("lockstep view: error: listening on {listen}: {e}");
            return ExitCode::from(2);
        }
    };
    let addr = listener.local_addr().unwrap_or(listen);
    println!(
        "viewing {} ({:?}: {} bodies, ticks {}..={}): http://{addr}/",
        file.display(),
        data.kind,
        data.bodies.len(),
        data.ticks.first().copied().unwrap_or(0),
        data.ticks.last().copied().unwrap_or(0),
    );
    let _ = std::io::stdout().flush();
    match lockstep_tools::view::http::serve_data(listener, data) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("lockstep view: error: {e}");
            ExitCode::from(2)
        }
    }
}
