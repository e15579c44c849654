//! `lockstep-bench`: runs a named benchmark suite and prints a table of
//! ns/op, ours against a reference, with their ratio.
//!
//! ```text
//! cargo run --release -p lockstep-bench -- math [--csv FILE] [--quick]
//! cargo run --release -p lockstep-bench -- engines [--quick] [--csv FILE] [--scenes a,b] [--runs N] [--steps N] [--threads N] [--stages [--callgrind-dir DIR]]
//! cargo run --release -p lockstep-bench -- sleep [--quick] [--csv FILE]
//! cargo run --release -p lockstep-bench -- queries [--quick] [--csv FILE] [--runs N]
//! cargo run --release -p lockstep-bench -- profile [--scenes a,b] [--steps N] [--threads N] [--stages]
//! cargo run --release -p lockstep-bench -- accuracy [--quick] [--csv FILE] [--scenes a,b] [--runs N]
//! cargo run --release -p lockstep-bench -- stress [--quick] [--csv FILE] [--scenes a,b]
//! cargo run --release -p lockstep-bench -- net [--quick] [--csv FILE] [--scenes 256x4,512x4]
//! ```
//!
//! Each suite is a module with a `run(&Options) -> SuiteOutput` function and
//! one entry in [`SUITES`]; adding a suite touches nothing else. `--quick`
//! runs a tiny size: CI uses it as a smoke test that every benchmark still
//! executes, not as a measurement.

mod accuracy;
mod callgrind;
mod engines;
mod harness;
mod math;
mod net;
mod profile;
mod queries;
mod rollback;
mod scene_file;
mod scenes;
mod sleep;
mod stages;
mod stress;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;

use harness::Budget;
use lockstep_core::{ContactRows, WorldConfig};
use lockstep_testsupport::alloc;

/// The heap high-water mark is measured in this binary (see [`alloc`]).
#[global_allocator]
static ALLOCATOR: alloc::Counting = alloc::Counting;

/// What a suite is asked to do, from the command line.
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// A smoke-run size instead of a measurement.
    pub quick: bool,
    /// Only these scenes (`engines`, `profile`) or cases (`accuracy`), if
    /// given.
    pub scenes: Option<Vec<String>>,
    /// Runs per measurement, if not the suite's default.
    pub runs: Option<usize>,
    /// Steps per run, if not the scene's own (`profile` suite).
    pub steps: Option<usize>,
    /// Also the per-stage tables (`engines`, `profile`).
    pub stages: bool,
    /// Where `engines --stages` keeps its callgrind files, if anywhere.
    pub callgrind_dir: Option<PathBuf>,
    /// `engines`: also ours on 1 and this many workers; `profile`: ours in
    /// colour order on this many.
    pub threads: Option<usize>,
    /// Ours with the solver's exact wide lanes turned on (`engines`,
    /// `profile`; used in colour order where the CPU has them): the same
    /// bits as the scalar rows.
    pub wide: bool,
    /// The number format of our contact rows (`engines`, `profile`).
    pub rows: ContactRows,
    /// Ours with the narrow rows' SIMD lanes on (off by default; the same
    /// bits).
    pub lanes: bool,
}

/// What a suite produced: the printed table and the CSV text.
pub struct SuiteOutput {
    /// The table(s) for the terminal.
    pub text: String,
    /// The same figures as CSV with a header line.
    pub csv: String,
}

/// A benchmark suite that can be selected by name.
struct Suite {
    name: &'static str,
    about: &'static str,
    run: fn(&Options) -> SuiteOutput,
    /// The names `--scenes` may give (empty: the suite takes none).
    scenes: fn() -> Vec<&'static str>,
}

fn engine_scenes() -> Vec<&'static str> {
    engines::SCENE_NAMES.to_vec()
}

/// The `math` suite behind the common interface.
fn run_math(opts: &Options) -> SuiteOutput {
    let mut budget = if opts.quick {
        Budget::QUICK
    } else {
        Budget::FULL
    };
    if let Some(runs) = opts.runs {
        budget.runs = runs;
    }
    let rows = math::run(budget);
    let text = format!(
        "{} ops per measurement, best of {} runs; ratio = ours / reference\n{}",
        budget.ops,
        budget.runs,
        harness::table(&rows)
    );
    SuiteOutput {
        text,
        csv: harness::csv("math", &rows),
    }
}

/// Every suite, in the order `--help` lists them.
const SUITES: &[Suite] = &[
    Suite {
        name: "math",
        about: "Q32.32 arithmetic and elementary functions vs f64, fixed and cordic",
        run: run_math,
        scenes: Vec::new,
    },
    Suite {
        name: "engines",
        about: "performance scenes (docs/engines.md), ours vs rapier3d, alternating in one process",
        run: engines::run,
        scenes: engine_scenes,
    },
    Suite {
        name: "queries",
        about: "rays and sphere sweeps across 1,000 boxes, and a triangle mesh's build",
        run: queries::run,
        scenes: Vec::new,
    },
    Suite {
        name: "sleep",
        about: "9,600 sleeping boxes + 1 awake vs the same scene awake",
        run: sleep::run,
        scenes: Vec::new,
    },
    Suite {
        name: "profile",
        about: "steps only our engine on a scene (for perf/callgrind), prints ms/step",
        run: profile::run,
        scenes: engine_scenes,
    },
    Suite {
        name: "accuracy",
        about: "work-precision: error vs CPU time on closed-form cases, ours vs Rapier f32 and f64",
        run: accuracy::run,
        scenes: accuracy::case_names,
    },
    Suite {
        name: "net",
        about: "players one server holds: relays in rooms of 4 and 16 at 60 Hz, tick lateness, bandwidth, CPU",
        run: net::run,
        scenes: net::config_names,
    },
    Suite {
        name: "rollback",
        about: "prediction's rollback: restore cost per body, a tick's cost, the deepest rollback in a 60 Hz frame",
        run: rollback::run,
        scenes: rollback::scene_names,
    },
    Suite {
        name: "stress",
        about: "where each engine breaks: stack, pyramid, mass ratio, speed, distance, overlap, soak",
        run: stress::run,
        scenes: stress::sweep_names,
    },
];

/// Printed with every suite's output.
const MACHINE_CAVEAT: &str = "caveat: this machine has 2 vCPUs shared with other work; absolute \
times drift between runs, so compare only ratios measured in the same run";

fn suite_list() -> String {
    SUITES
        .iter()
        .map(|s| format!("  {:<8} {}", s.name, s.about))
        .collect::<Vec<_>>()
        .join("\n")
}

#[derive(Parser, Debug)]
#[command(
    name = "lockstep-bench",
    about = "Benchmarks for lockstep, side by side with reference implementations",
    after_help = format!("Suites:\n{}", suite_list())
)]
struct Cli {
    /// The suite to run (see the list below).
    suite: String,
    /// Also write the results as CSV to this file.
    #[arg(long, value_name = "FILE")]
    csv: Option<PathBuf>,
    /// A tiny size: a smoke run that every benchmark executes, not a
    /// measurement.
    #[arg(long)]
    quick: bool,
    /// Only these scenes, comma-separated (`engines`, `profile`), cases
    /// (`accuracy`) or sweeps (`stress`).
    #[arg(long, value_delimiter = ',', value_name = "A,B")]
    scenes: Option<Vec<String>>,
    /// Runs per measurement (default: the suite's own).
    #[arg(long, value_name = "N")]
    runs: Option<usize>,
    /// Steps per run (`profile` suite, default 20; `engines`: instead of
    /// the scene's own count).
    #[arg(long, value_name = "N")]
    steps: Option<usize>,
    /// `engines` suite: also per scene ms/step for each stage of ours beside
    /// Rapier's own stage counters, and our instruction counts per stage
    /// (callgrind, if valgrind is installed); `profile`: ms/step per stage.
    #[arg(long)]
    stages: bool,
    /// `engines --stages`: keep each scene's callgrind file as
    /// DIR/SCENE.callgrind (for `callgrind_annotate`).
    #[arg(long, value_name = "DIR")]
    callgrind_dir: Option<PathBuf>,
    /// `engines` suite: also step ours on N workers in pair order, and in
    /// colour order on 1 and on N (N in 1..=64), in the same runs;
    /// `profile`: ours in colour order on N workers.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..=64))]
    threads: Option<u16>,
    /// `engines`, `profile`: ours with the solver's exact wide lanes
    /// (AVX-512 IFMA) turned on, used in colour order where the CPU has
    /// them: the same bits as the scalar rows.
    #[arg(long)]
    wide: bool,
    /// `engines`, `profile`: the number format of our contact solver's
    /// rows: `narrow` (32-bit operands, exact 64-bit sums) or `exact`
    /// (Q32.32); default: the world's default.
    #[arg(long, value_name = "FORMAT", value_parser = parse_rows)]
    rows: Option<ContactRows>,
    /// `engines`, `profile`: ours with the narrow rows' SIMD lanes on (in
    /// colour order, where the CPU has AVX2 or AVX-512; the same bits as
    /// the scalar rows).
    #[arg(long)]
    lanes: bool,
    /// Internal: the callgrind child of `engines --stages` (restore this
    /// snapshot, step once, then count `--steps` steps).
    #[arg(long, value_name = "FILE", hide = true)]
    count_snapshot: Option<PathBuf>,
}

/// `--rows`: `narrow` or `exact`.
fn parse_rows(s: &str) -> Result<ContactRows, String> {
    match s {
        "narrow" => Ok(ContactRows::Narrow),
        "exact" => Ok(ContactRows::Exact),
        _ => Err(format!("expected `narrow` or `exact`, got `{s}`")),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Some(snapshot) = &cli.count_snapshot {
        return match callgrind::child(snapshot, cli.steps.unwrap_or(stages::COUNT_STEPS)) {
            Ok(line) => {
                println!("{line}");
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::FAILURE
            }
        };
    }
    let Some(suite) = SUITES.iter().find(|s| s.name == cli.suite) else {
        eprintln!(
            "error: unknown suite `{}`; available suites:\n{}",
            cli.suite,
            suite_list()
        );
        return ExitCode::from(2);
    };
    if let Some(given) = &cli.scenes {
        let known = (suite.scenes)();
        if let Some(bad) = given.iter().find(|s| !known.contains(&s.as_str())) {
            if known.is_empty() {
                eprintln!("error: suite `{}` takes no --scenes", suite.name);
            } else {
                eprintln!(
                    "error: unknown scene `{bad}` for `{}`; scenes: {}",
                    suite.name,
                    known.join(", ")
                );
            }
            return ExitCode::from(2);
        }
    }
    let opts = Options {
        quick: cli.quick,
        scenes: cli.scenes.clone(),
        runs: cli.runs,
        steps: cli.steps,
        stages: cli.stages,
        callgrind_dir: cli.callgrind_dir.clone(),
        threads: cli.threads.map(usize::from),
        wide: cli.wide,
        rows: cli.rows.unwrap_or(WorldConfig::default().contact_rows),
        lanes: cli.lanes,
    };
    // Rapier's `parallel` build splits work over the rayon pool it is called
    // in: every suite runs in a pool of one thread, and `engines --threads N`
    // gives its N-thread Rapier runs their own pool.
    let out = engines::on_one_thread(|| (suite.run)(&opts));
    println!(
        "suite {}{}\n{MACHINE_CAVEAT}",
        suite.name,
        if cli.quick {
            " (--quick: smoke-run size, not a measurement)"
        } else {
            ""
        }
    );
    print!("{}", out.text);
    if let Some(path) = &cli.csv {
        if let Err(e) = std::fs::write(path, &out.csv) {
            eprintln!("error: cannot write {}: {e}", path.display());
            return ExitCode::FAILURE;
        }
        println!("wrote {}", path.display());
    }
    ExitCode::SUCCESS
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suite_names_are_unique_and_parse() {
        for (i, s) in SUITES.iter().enumerate() {
            assert!(SUITES[i + 1..].iter().all(|t| t.name != s.name));
            let cli = Cli::try_parse_from(["lockstep-bench", s.name, "--quick"]).unwrap();
            assert_eq!(cli.suite, s.name);
            assert!(cli.quick && cli.csv.is_none());
        }
        let cli = Cli::try_parse_from(["lockstep-bench", "math", "--csv", "out.csv"]).unwrap();
        assert_eq!(cli.csv, Some(PathBuf::from("out.csv")));
        let cli = Cli::try_parse_from([
            "lockstep-bench",
            "engines",
            "--scenes",
            "large_pyramid,many_pyramids",
            "--runs",
            "2",
        ])
        .unwrap();
        assert_eq!(
            cli.scenes,
            Some(vec!["large_pyramid".to_owned(), "many_pyramids".to_owned()])
        );
        assert_eq!(cli.runs, Some(2));
        assert!(!cli.stages);
        let cli =
            Cli::try_parse_from(["lockstep-bench", "engines", "--stages", "--quick"]).unwrap();
        assert!(cli.stages && cli.quick && cli.count_snapshot.is_none());
    }
}
