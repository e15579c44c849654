//! The `stress` suite: where each engine breaks. Each sweep
//! ([`sweeps::SWEEPS`]) raises one quantity until an engine fails the
//! sweep's criterion, in ours, Rapier f32 and Rapier f64 at the same
//! settings (the game defaults: 60 Hz, 4 substeps, 1 solver pass); the
//! breaking point is the largest value that passes with every smaller one
//! passing too ([`search`]). The soak ([`soak`]) steps a mixed pile for one
//! simulated hour. Failed trials are kept, never dropped. Output: a printed
//! table, `out/bench/stress/stress.csv` (and `--csv FILE`), one chart per
//! sweep and `index.html`. docs/stress.md describes every sweep.

pub mod chart;
pub mod search;
pub mod soak;
pub mod sweeps;

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use crate::accuracy::run::Runner;
use crate::accuracy::sim::{Engine, Settings};
use crate::{Options, SuiteOutput};
use sweeps::{SWEEPS, Sweep};

/// Where the CSV, the charts and the index go.
pub const OUT_DIR: &str = "out/bench/stress";

/// The settings every trial runs at (our `WorldConfig` defaults; Rapier's
/// mapping is the accuracy suite's).
pub const SETTINGS: Settings = Settings {
    tick_rate: 60,
    substeps: 4,
    iterations: 1,
};

/// One trial: a sweep's value in one engine.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    /// The engine.
    pub engine: Engine,
    /// The swept value.
    pub value: f64,
    /// Whether it met the criterion.
    pub passed: bool,
    /// The sweep's metric.
    pub metric: f64,
    /// `ok` or why it failed.
    pub status: &'static str,
    /// CPU ms per simulated second.
    pub ms: f64,
    /// Secondary figures.
    pub detail: String,
}

/// Runs one trial.
pub fn trial(sweep: &Sweep, engine: Engine, value: f64, quick: bool) -> Point {
    let mut r = Runner::new(engine, SETTINGS);
    let mut o = (sweep.trial)(&mut r, value, quick);
    if let Some(f) = r.failure() {
        o.failure = Some(f);
    }
    Point {
        engine,
        value,
        passed: o.failure.is_none(),
        metric: o.error,
        status: o.failure.map_or("ok", |f| f.name()),
        ms: r.ms_per_simulated_second(),
        detail: o.detail,
    }
}

/// Runs a sweep in one engine, ascending, until its stop rule.
pub fn sweep_engine(sweep: &Sweep, engine: Engine, quick: bool) -> Vec<Point> {
    let mut out: Vec<Point> = Vec::new();
    for v in (sweep.values)(quick) {
        out.push(trial(sweep, engine, v, quick));
        if search::should_stop(&pass_list(&out), sweep.stop_after) {
            break;
        }
    }
    out
}

fn pass_list(points: &[Point]) -> Vec<(f64, bool)> {
    points.iter().map(|p| (p.value, p.passed)).collect()
}

/// The names `--scenes` takes: every sweep and `soak`.
pub fn sweep_names() -> Vec<&'static str> {
    SWEEPS
        .iter()
        .map(|s| s.name)
        .chain(std::iter::once("soak"))
        .collect()
}

fn csv_field(s: &str) -> String {
    format!("\"{}\"", s.replace('"', "\"\""))
}

/// A sweep's result, for the index and the printed table.
struct SweepReport {
    sweep: &'static Sweep,
    lines: Vec<(Engine, String)>,
    seconds: f64,
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Runs the suite.
pub fn run(opts: &Options) -> SuiteOutput {
    crate::accuracy::sim::set_rows(opts.rows);
    let quick = opts.quick;
    let wanted = |name: &str| {
        opts.scenes
            .as_ref()
            .is_none_or(|f| f.iter().any(|s| s == name))
    };
    let started = Instant::now();
    let mut csv = String::from("sweep,engine,value,status,metric,ms_per_sim_s,detail\n");
    let mut svgs: Vec<(String, String)> = Vec::new();
    let mut reports = Vec::new();
    let mut errors = Vec::new();
    for sweep in SWEEPS.iter().filter(|s| wanted(s.name)) {
        let t = Instant::now();
        let mut points = Vec::new();
        let mut lines = Vec::new();
        for engine in Engine::ALL {
            let ps = sweep_engine(sweep, engine, quick);
            lines.push((engine, search::summary(&pass_list(&ps), sweep.unit)));
            points.extend(ps);
        }
        for p in &points {
            let _ = writeln!(
                csv,
                "{},{},{},{},{:e},{:.3},{}",
                sweep.name,
                p.engine.name(),
                p.value,
                p.status,
                p.metric,
                p.ms,
                csv_field(&p.detail)
            );
        }
        let seconds = t.elapsed().as_secs_f64();
        eprintln!(
            "stress: {} ({} trials) {seconds:.1} s",
            sweep.name,
            points.len()
        );
        match chart::svg(&chart::Chart {
            name: sweep.name,
            title: sweep.title,
            criterion: sweep.criterion,
            param: sweep.param,
            metric: sweep.metric,
            log_x: sweep.log_x,
            limit: sweep.limit,
            points: &points,
            engines: &lines,
        }) {
            Ok(svg) => svgs.push((sweep.name.to_owned(), svg)),
            Err(e) => errors.push(format!("{}: {e}", sweep.name)),
        }
        reports.push(SweepReport {
            sweep,
            lines,
            seconds,
        });
    }
    let mut soaks = Vec::new();
    if wanted("soak") {
        let t = Instant::now();
        for engine in Engine::ALL {
            let s = soak::run(engine, SETTINGS, quick);
            let _ = writeln!(
                csv,
                "soak,{},{},{},{:e},{:.3},{}",
                s.engine.name(),
                s.seconds,
                s.status(),
                s.energy_lift,
                s.ms,
                csv_field(&soak_detail(&s))
            );
            soaks.push(s);
        }
        eprintln!("stress: soak {:.1} s", t.elapsed().as_secs_f64());
        let series: Vec<(Engine, Vec<(f64, f64)>)> =
            soaks.iter().map(|s| (s.engine, s.series.clone())).collect();
        let lines: Vec<(Engine, String)> = soaks.iter().map(|s| (s.engine, soak_line(s))).collect();
        match chart::soak_svg(&soak_title(quick), &series, &lines) {
            Ok(svg) => svgs.push(("soak".to_owned(), svg)),
            Err(e) => errors.push(format!("soak: {e}")),
        }
    }
    let elapsed = started.elapsed().as_secs_f64();

    let mut text = format!(
        "settings: {} Hz, {} substeps, {} solver pass (every engine); breaking point = largest value passing with every smaller one passing\n\n",
        SETTINGS.tick_rate, SETTINGS.substeps, SETTINGS.iterations
    );
    for r in &reports {
        let _ = writeln!(text, "{}: {}", r.sweep.name, r.sweep.criterion);
        for (e, line) in &r.lines {
            let _ = writeln!(text, "  {:<10} {line}", e.name());
        }
    }
    if !soaks.is_empty() {
        let _ = writeln!(text, "soak: {}", soak_title(quick));
        for s in &soaks {
            let _ = writeln!(text, "  {:<10} {}", s.engine.name(), soak_line(s));
        }
    }
    for e in &errors {
        let _ = writeln!(text, "error: chart {e}");
    }
    let _ = writeln!(text, "suite run time {elapsed:.1} s");
    let index = index_html(&reports, &soaks, quick, elapsed);
    match write_outputs(Path::new(OUT_DIR), &csv, &svgs, &index) {
        Ok(()) => {
            let _ = writeln!(
                text,
                "wrote {OUT_DIR}/stress.csv, {OUT_DIR}/index.html and {} charts",
                svgs.len()
            );
        }
        Err(e) => {
            let _ = writeln!(text, "error: cannot write {OUT_DIR}: {e}");
        }
    }
    SuiteOutput { text, csv }
}

fn soak_title(quick: bool) -> String {
    format!(
        "48 bodies (12 each: boxes, spheres, capsules, octahedral hulls) dropped from 3–8 m into a walled 6 × 6 m pit, sleeping on, one body kicked up at 6 m/s every {} s, {} s simulated{}",
        soak::settle_seconds(quick),
        soak::seconds(quick),
        if quick { " (quick)" } else { " (one hour)" }
    )
}

fn soak_line(s: &soak::SoakResult) -> String {
    format!(
        "{}: faults {}; energy growth {:.2e} m of lift; never sleep {}; frozen-pose violations {}",
        if s.passed() { "passes" } else { "fails" },
        s.failure
            .map_or("none".to_owned(), |f| format!("{f} at {:.1} s", s.seconds)),
        s.energy_lift,
        s.never_sleep,
        s.violations
    )
}

fn soak_detail(s: &soak::SoakResult) -> String {
    format!(
        "energy growth {:.3e} m of lift; never sleep {}; violations {} (bodies: {}); asleep at end {} of {}; {} kicks",
        s.energy_lift,
        s.never_sleep,
        s.violations,
        s.violators.join(" "),
        s.asleep_at_end,
        s.bodies,
        s.kicks
    )
}

fn index_html(
    reports: &[SweepReport],
    soaks: &[soak::SoakResult],
    quick: bool,
    elapsed: f64,
) -> String {
    let mut h = String::from(
        "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>lockstep stress</title>\n<style>body{font-family:sans-serif;max-width:1150px;margin:auto}li{margin:2px 0}</style></head><body>\n<h1>lockstep-bench stress: where each engine breaks</h1>\n",
    );
    let _ = writeln!(
        h,
        "<p>Every engine at {} Hz, {} substeps, {} solver pass. Breaking point: the largest swept value that passes with every smaller one passing. Failed trials are drawn as crosses and kept in <a href=\"stress.csv\">stress.csv</a>.{} Suite run time {elapsed:.0} s on a shared 2-core machine.</p>",
        SETTINGS.tick_rate,
        SETTINGS.substeps,
        SETTINGS.iterations,
        if quick {
            " <b>--quick: smoke-run size, not a measurement.</b>"
        } else {
            ""
        }
    );
    h.push_str("<h2>Breaking points</h2>\n<ul>\n");
    for r in reports {
        let parts: Vec<String> = r
            .lines
            .iter()
            .map(|(e, l)| format!("{} {}", e.name(), html_escape(l)))
            .collect();
        let _ = writeln!(
            h,
            "<li><a href=\"#{0}\">{0}</a>: {1}</li>",
            r.sweep.name,
            parts.join("; ")
        );
    }
    if !soaks.is_empty() {
        let parts: Vec<String> = soaks
            .iter()
            .map(|s| format!("{} {}", s.engine.name(), html_escape(&soak_line(s))))
            .collect();
        let _ = writeln!(
            h,
            "<li><a href=\"#soak\">soak</a>: {}</li>",
            parts.join("; ")
        );
    }
    h.push_str("</ul>\n");
    for r in reports {
        let _ = writeln!(
            h,
            "<h2 id=\"{0}\">{0}</h2>\n<p>{1}<br>pass: {2} ({3:.0} s)</p>\n<img src=\"{0}.svg\" alt=\"{0} breaking-point chart\">",
            r.sweep.name,
            html_escape(r.sweep.title),
            html_escape(r.sweep.criterion),
            r.seconds
        );
    }
    if !soaks.is_empty() {
        let _ = writeln!(
            h,
            "<h2 id=\"soak\">soak</h2>\n<p>{}</p>\n<img src=\"soak.svg\" alt=\"soak chart\">",
            html_escape(&soak_title(quick))
        );
    }
    h.push_str("</body></html>\n");
    h
}

fn write_outputs(
    dir: &Path,
    csv: &str,
    svgs: &[(String, String)],
    index: &str,
) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    std::fs::write(dir.join("stress.csv"), csv)?;
    for (name, svg) in svgs {
        std::fs::write(dir.join(format!("{name}.svg")), svg)?;
    }
    std::fs::write(dir.join("index.html"), index)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn find(name: &str) -> &'static Sweep {
        SWEEPS.iter().find(|s| s.name == name).expect("sweep")
    }

    #[test]
    fn names_include_every_sweep_and_the_soak() {
        let names = sweep_names();
        assert_eq!(names.len(), SWEEPS.len() + 1);
        assert_eq!(names.last(), Some(&"soak"));
        assert!(
            names
                .iter()
                .all(|n| n.chars().all(|c| c.is_ascii_lowercase() || c == '_'))
        );
    }

    /// A short stack stands in every engine, and an impossible bound (a
    /// trial forced to fail through its criterion) is recorded as a
    /// failure with its metric, not dropped.
    #[test]
    fn a_short_stack_stands_in_every_engine() {
        let s = find("stack_height");
        for engine in Engine::ALL {
            let p = trial(s, engine, 2.0, true);
            assert!(p.passed, "{engine:?}: {p:?}");
            assert!(p.metric < 0.01 && p.ms > 0.0);
        }
    }

    /// Boxes spawned overlapping at 1:1 mass in a row of 2 separate slowly
    /// in every engine, and the sweep stops after its failures.
    #[test]
    fn overlapping_pairs_separate_and_sweeps_stop_on_failure() {
        let s = find("overlap");
        let p = trial(s, Engine::Ours, 2.0, true);
        assert!(
            p.passed && p.metric > 0.0 && p.metric < sweeps::OVERLAP_SPEED,
            "{p:?}"
        );
        let always_fails = Sweep {
            trial: |_, _, _| {
                crate::accuracy::run::Outcome::ok(f64::NAN, String::new())
                    .failed_if(true, crate::accuracy::run::Failure::Collapsed)
            },
            stop_after: 1,
            ..*s
        };
        let ps = sweep_engine(&always_fails, Engine::Ours, false);
        assert_eq!(ps.len(), 1, "stops after one failure");
        assert!(!ps[0].passed && ps[0].status == "collapsed" && ps[0].metric.is_nan());
    }

    #[test]
    fn csv_fields_are_quoted() {
        assert_eq!(csv_field("a \"b\", c"), "\"a \"\"b\"\", c\"");
    }
}
