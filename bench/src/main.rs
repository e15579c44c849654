//! `lockstep-bench`: runs a named benchmark suite and prints a table of
//! ns/op, ours against a reference, with their ratio.
//!
//! ```text
//! cargo run --release -p lockstep-bench -- math [--csv FILE] [--quick]
//! ```
//!
//! Each suite is a module with a `run(Budget) -> Vec<Row>` function and one
//! entry in [`SUITES`]; adding a suite (engines, sleep, ...) touches nothing
//! else. `--quick` runs a tiny number of iterations: CI uses it as a smoke
//! test that every benchmark still executes, not as a measurement.

mod harness;
mod math;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;

use harness::{Budget, Row};

/// A benchmark suite that can be selected by name.
struct Suite {
    name: &'static str,
    about: &'static str,
    run: fn(Budget) -> Vec<Row>,
}

/// Every suite, in the order `--help` lists them.
const SUITES: &[Suite] = &[Suite {
    name: "math",
    about: "Q32.32 arithmetic and elementary functions vs f64, fixed and cordic",
    run: math::run,
}];

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
    /// A tiny iteration count: a smoke run that every benchmark executes,
    /// not a measurement.
    #[arg(long)]
    quick: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let Some(suite) = SUITES.iter().find(|s| s.name == cli.suite) else {
        eprintln!(
            "error: unknown suite `{}`; available suites:\n{}",
            cli.suite,
            suite_list()
        );
        return ExitCode::from(2);
    };
    let budget = if cli.quick {
        Budget::QUICK
    } else {
        Budget::FULL
    };
    let rows = (suite.run)(budget);
    println!(
        "suite {} ({} ops per measurement, best of {} runs; ratio = ours / reference)",
        suite.name, budget.ops, budget.runs
    );
    print!("{}", harness::table(&rows));
    if let Some(path) = &cli.csv {
        if let Err(e) = std::fs::write(path, harness::csv(suite.name, &rows)) {
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
    }
}
