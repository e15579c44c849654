//! The `accuracy` suite: work-precision curves of our engine beside Rapier
//! (f32 and f64) on cases with a closed form or an exact invariant.
//!
//! Every case ([`cases::CASES`]) is run in every engine at every setting of
//! a sweep (tick rate × substeps × solver iterations). A point is the
//! case's error against its closed form ([`closed`]) and the CPU time per
//! simulated second: the fastest of several timed runs after a warm-up
//! (the SciML work-precision convention; engines alternate, so they share
//! the machine's noise). Runs that went unstable are kept and marked.
//! Output: a printed summary, `out/bench/accuracy/accuracy.csv` (and
//! `--csv FILE`), one SVG plot per case and `index.html` with every plot
//! and a verdict line per case ([`frontier::compare`], [`report`]). docs/accuracy.md
//! explains the cases and how to read the plots.

pub mod cases;
pub mod closed;
pub mod frontier;
pub mod plot;
pub mod report;
pub mod run;
pub mod sim;

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use cases::{CASES, Case};
use report::{csv, index_html, report_case, settings_text, write_outputs};
use run::{Failure, Runner};
use sim::{Engine, Settings};

use crate::{Options, SuiteOutput};

/// Where the CSV, the plots and the index go (relative to the working
/// directory: the repository root under `cargo run`).
pub const OUT_DIR: &str = "out/bench/accuracy";

/// What is swept and how often each point is timed.
#[derive(Clone, Debug, PartialEq)]
pub struct Sweep {
    /// Steps per second.
    pub tick_rates: Vec<u32>,
    /// Substeps per step.
    pub substeps: Vec<u32>,
    /// Solver passes per substep (one plot family each).
    pub iterations: Vec<u32>,
    /// Whether a first, untimed run warms up caches and the allocator.
    pub warm_up: bool,
    /// Timed runs per point (at least one; the fastest counts).
    pub runs: usize,
    /// After this much timed stepping of one point and engine, s, no more
    /// repeats (the slow settings of the long cases run once after the
    /// warm-up).
    pub budget_s: f64,
}

impl Sweep {
    /// The default sweep: 4 tick rates × 4 substep counts × 2 iteration
    /// counts, best of 3 after a warm-up.
    pub fn full() -> Sweep {
        Sweep {
            tick_rates: vec![30, 60, 120, 240],
            substeps: vec![1, 2, 4, 8],
            iterations: vec![1, 4],
            warm_up: true,
            runs: 3,
            budget_s: 1.5,
        }
    }

    /// The smoke run: 60 Hz, 1 and 4 substeps, 1 iteration, one run.
    pub fn quick() -> Sweep {
        Sweep {
            tick_rates: vec![60],
            substeps: vec![1, 4],
            iterations: vec![1],
            warm_up: false,
            runs: 1,
            budget_s: 0.0,
        }
    }

    /// Every setting, by tick rate, then substeps, then iterations.
    pub fn settings(&self) -> Vec<Settings> {
        let mut out = Vec::new();
        for &tick_rate in &self.tick_rates {
            for &substeps in &self.substeps {
                for &iterations in &self.iterations {
                    out.push(Settings {
                        tick_rate,
                        substeps,
                        iterations,
                    });
                }
            }
        }
        out
    }

    /// How the times were taken, for the plots' x axis.
    pub fn runs_note(&self) -> String {
        if self.warm_up {
            format!("fastest of up to {} runs after a warm-up", self.runs)
        } else {
            "one run: not a measurement".into()
        }
    }
}

/// One point: a case in one engine at one setting.
#[derive(Clone, Debug, PartialEq)]
pub struct Measurement {
    /// The case's name.
    pub case: &'static str,
    /// The engine.
    pub engine: Engine,
    /// The setting.
    pub settings: Settings,
    /// CPU ms per simulated second (fastest timed run).
    pub ms: f64,
    /// Timed runs the time is the minimum of.
    pub timed_runs: usize,
    /// The case's error.
    pub error: f64,
    /// Why the point is marked, if it is.
    pub failure: Option<Failure>,
    /// The case's secondary figures.
    pub detail: String,
}

impl Measurement {
    /// Whether the point may stand on a frontier: a finite error that
    /// still measures something (see [`Failure::error_is_meaningful`]).
    pub fn on_frontier(&self) -> bool {
        !self.error.is_nan() && self.failure.is_none_or(|f| f.error_is_meaningful())
    }

    /// `ok` or the failure's name.
    pub fn status(&self) -> &'static str {
        self.failure.map_or("ok", Failure::name)
    }
}

/// Runs one case once: the outcome with the generic failures folded in,
/// the time per simulated second, and the seconds spent stepping.
fn run_once(
    case: &Case,
    engine: Engine,
    settings: Settings,
    quick: bool,
) -> (run::Outcome, f64, f64) {
    let mut runner = Runner::new(engine, settings);
    let mut outcome = (case.run)(&mut runner, quick);
    if let Some(f) = runner.failure() {
        outcome.failure = Some(f);
    }
    (
        outcome,
        runner.ms_per_simulated_second(),
        runner.busy.as_secs_f64(),
    )
}

/// Measures one case at one setting in every engine, alternating engines
/// between runs.
fn measure_point(case: &Case, settings: Settings, sweep: &Sweep, quick: bool) -> Vec<Measurement> {
    let mut spent = Vec::new();
    let mut points: Vec<Measurement> = Engine::ALL
        .iter()
        .map(|&engine| {
            let (o, ms, busy) = run_once(case, engine, settings, quick);
            let timed = !sweep.warm_up;
            spent.push(if timed { busy } else { 0.0 });
            Measurement {
                case: case.name,
                engine,
                settings,
                ms: if timed { ms } else { f64::INFINITY },
                timed_runs: usize::from(timed),
                error: o.error,
                failure: o.failure,
                detail: o.detail,
            }
        })
        .collect();
    for _ in 0..sweep.runs {
        for (m, spent) in points.iter_mut().zip(&mut spent) {
            if m.timed_runs >= sweep.runs || (m.timed_runs > 0 && *spent > sweep.budget_s) {
                continue;
            }
            let (o, ms, busy) = run_once(case, m.engine, settings, quick);
            if o.error.to_bits() != m.error.to_bits() {
                m.detail.push_str("; NOTE: a repeat gave a different error");
            }
            m.ms = m.ms.min(ms);
            m.timed_runs += 1;
            *spent += busy;
        }
    }
    points
}

/// The case names, for `--scenes`.
pub fn case_names() -> Vec<&'static str> {
    CASES.iter().map(|c| c.name).collect()
}

/// Runs the suite.
pub fn run(opts: &Options) -> SuiteOutput {
    sim::set_rows(opts.rows);
    let mut sweep = if opts.quick {
        Sweep::quick()
    } else {
        Sweep::full()
    };
    if let Some(runs) = opts.runs {
        sweep.runs = runs.max(1);
    }
    let started = Instant::now();
    let mut all = Vec::new();
    let mut reports = Vec::new();
    let mut svgs = Vec::new();
    for case in CASES {
        if let Some(filter) = &opts.scenes
            && !filter.iter().any(|f| f == case.name)
        {
            continue;
        }
        let t = Instant::now();
        let mut ms = Vec::new();
        for settings in sweep.settings() {
            ms.extend(measure_point(case, settings, &sweep, opts.quick));
        }
        eprintln!(
            "accuracy: {} ({} points) {:.1} s",
            case.name,
            ms.len(),
            t.elapsed().as_secs_f64()
        );
        let (report, svg) = report_case(case, &ms, &sweep);
        reports.push(report);
        svgs.push((case.name, svg));
        all.extend(ms);
    }
    let elapsed = started.elapsed().as_secs_f64();
    let csv_text = csv(&all);
    let mut text = format!("{}\n\n", settings_text(&sweep));
    for r in &reports {
        let _ = writeln!(text, "{}: {}", r.case.name, r.case.title);
        for v in &r.verdicts {
            let _ = writeln!(text, "  {v}");
        }
        let _ = writeln!(text, "  marked runs: {}", r.failures);
    }
    let _ = writeln!(text, "suite run time {elapsed:.1} s");
    match write_outputs(
        Path::new(OUT_DIR),
        &csv_text,
        &svgs,
        &index_html(&reports, &sweep, elapsed),
    ) {
        Ok(()) => {
            let _ = writeln!(
                text,
                "wrote {OUT_DIR}/accuracy.csv, {OUT_DIR}/index.html and {} plots",
                svgs.len()
            );
        }
        Err(e) => {
            let _ = writeln!(text, "error: cannot write {OUT_DIR}: {e}");
        }
    }
    SuiteOutput {
        text,
        csv: csv_text,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn find(name: &str) -> &'static Case {
        CASES.iter().find(|c| c.name == name).expect("case")
    }

    #[test]
    fn the_sweep_covers_every_combination_and_quick_is_tiny() {
        let full = Sweep::full();
        let s = full.settings();
        assert_eq!(s.len(), 4 * 4 * 2);
        assert_eq!(
            s[0],
            Settings {
                tick_rate: 30,
                substeps: 1,
                iterations: 1
            }
        );
        assert!(s.windows(2).all(|w| w[0] < w[1]), "sorted, no repeats");
        assert_eq!(Sweep::quick().settings().len(), 2);
    }

    /// Every engine integrates free flight with symplectic Euler, whose
    /// position error after time t is ½|a|·h·t for substep h: the
    /// projectile case must measure exactly that (a check of the harness
    /// against a closed form, not of the engines' quality).
    #[test]
    fn the_projectile_case_measures_the_euler_error_in_every_engine() {
        let a = (1.5f64.powi(2) + (9.81f64).powi(2) + 0.5f64.powi(2)).sqrt();
        for substeps in [1, 4] {
            let settings = Settings {
                tick_rate: 60,
                substeps,
                iterations: 1,
            };
            let expected = 0.5 * a * (1.0 / (60.0 * substeps as f64)) * 3.0;
            for engine in Engine::ALL {
                let (o, ms, _) = run_once(find("projectile"), engine, settings, true);
                let tol = if engine == Engine::RapierF32 {
                    1e-2
                } else {
                    1e-4
                };
                assert!(
                    (o.error - expected).abs() / expected < tol,
                    "{engine:?} {substeps}: {} vs {expected}",
                    o.error
                );
                assert!(o.failure.is_none() && ms > 0.0);
            }
        }
    }

    /// The joint cases build the same joints in every engine: the
    /// pendulum swings at the exact period with its anchors together, the
    /// door stops at its limit about the vertical axis, the motor turns
    /// the rod forwards near its target, and the chains hold. (Checks of
    /// the harness's joint frames, anchors and signs; the bars are loose
    /// enough for every engine at 60 Hz and 4 substeps.)
    #[test]
    fn the_joint_cases_build_the_same_joints_in_every_engine() {
        let settings = Settings {
            tick_rate: 60,
            substeps: 4,
            iterations: 1,
        };
        let detail_number = |detail: &str, before: &str| -> f64 {
            let at = detail.find(before).expect(before) + before.len();
            let rest = detail[at..].trim_start();
            let end = rest.find(' ').unwrap_or(rest.len());
            rest[..end].parse().expect("number")
        };
        for engine in Engine::ALL {
            let (o, _, _) = run_once(find("pendulum_period"), engine, settings, true);
            assert!(o.failure.is_none() && o.error < 1e-4, "{engine:?}: {o:?}");
            assert!(detail_number(&o.detail, "joint gap") < 1e-3, "{o:?}");
            let (o, _, _) = run_once(find("hinge_limit"), engine, settings, true);
            assert!(o.failure.is_none() && o.error < 0.01, "{engine:?}: {o:?}");
            let end = detail_number(&o.detail, "ends at");
            assert!((end - 0.5).abs() < 0.01, "{engine:?}: {o:?}");
            let (o, _, _) = run_once(find("hinge_motor"), engine, settings, true);
            let mean = detail_number(&o.detail, "mean speed");
            assert!((mean - 2.0).abs() < 0.2, "{engine:?}: {o:?}");
            for case in ["chain_20", "heavy_chain"] {
                let (o, _, _) = run_once(find(case), engine, settings, true);
                assert!(
                    o.failure.is_none() && o.error < 0.5,
                    "{engine:?} {case}: {o:?}"
                );
            }
        }
    }

    #[test]
    fn a_point_is_measured_in_every_engine_and_timed_as_asked() {
        let sweep = Sweep {
            runs: 2,
            warm_up: true,
            budget_s: 10.0,
            ..Sweep::quick()
        };
        let settings = sweep.settings()[0];
        let ms = measure_point(find("elastic_spheres"), settings, &sweep, true);
        assert_eq!(ms.len(), 3);
        for m in &ms {
            assert_eq!(m.timed_runs, 2);
            assert!(m.ms.is_finite() && m.ms > 0.0);
            assert!(m.error < 1e-3, "{m:?}");
            assert!(!m.detail.contains("NOTE"), "deterministic: {}", m.detail);
        }
    }
}
