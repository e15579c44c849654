//! The suite's outputs: the zero floor and NaN ceiling of a plot, the
//! verdict lines, the CSV, the settings text and the index page.

use std::fmt::Write as _;
use std::path::Path;

use super::cases::Case;
use super::frontier::{self, Comparison, Point};
use super::run::Failure;
use super::sim::Engine;
use super::{Measurement, Sweep, plot};

/// Errors of 0 are drawn at this floor: a decade below the smallest
/// positive error of the case, or the case's own floor if lower (1e-12 if
/// neither exists).
pub fn floor_for(errors: impl IntoIterator<Item = f64>, case_floor: Option<f64>) -> f64 {
    let min = errors
        .into_iter()
        .filter(|e| *e > 0.0 && e.is_finite())
        .fold(f64::INFINITY, f64::min);
    let data = if min.is_finite() {
        10f64.powf(min.log10().floor() - 1.0)
    } else {
        f64::INFINITY
    };
    let floor = data.min(case_floor.unwrap_or(f64::INFINITY));
    if floor.is_finite() { floor } else { 1e-12 }
}

/// NaN and infinite errors are drawn at this ceiling: the decade at or
/// above the largest finite error (at least 100 × the floor).
pub fn ceiling_for(errors: impl IntoIterator<Item = f64>, floor: f64) -> f64 {
    let max = errors
        .into_iter()
        .filter(|e| e.is_finite())
        .fold(0.0f64, f64::max);
    if max > 0.0 {
        10f64.powf(max.log10().ceil()).max(floor * 100.0)
    } else {
        floor * 100.0
    }
}

/// One engine's points of a case as frontier input (clamped as drawn).
fn frontier_points(ms: &[Measurement], engine: Engine, floor: f64, ceiling: f64) -> Vec<Point> {
    ms.iter()
        .filter(|m| m.engine == engine && m.on_frontier())
        .map(|m| {
            let (time, error) = plot::drawn(m, floor, ceiling);
            Point { time, error }
        })
        .collect()
}

/// The verdict of A against B at equal time, as one sentence.
pub fn verdict(
    a: Engine,
    b: Engine,
    c: Option<Comparison>,
    a_pts: &[Point],
    b_pts: &[Point],
) -> String {
    let span = |pts: &[Point]| {
        let lo = pts.iter().map(|p| p.time).fold(f64::INFINITY, f64::min);
        let hi = pts.iter().map(|p| p.time).fold(0.0f64, f64::max);
        let best = pts.iter().map(|p| p.error).fold(f64::INFINITY, f64::min);
        if pts.is_empty() {
            "no usable point".to_owned()
        } else {
            format!("{lo:.3}–{hi:.3} ms/s, best error {best:.2e}")
        }
    };
    let Some(c) = c else {
        return format!(
            "{} vs {}: no common time range ({} {}; {} {})",
            a.name(),
            b.name(),
            a.name(),
            span(a_pts),
            b.name(),
            span(b_pts)
        );
    };
    let n = c.a_lower + c.b_lower + c.ties;
    let lead = if c.a_lower > c.b_lower {
        format!("{} lower at {} of {n}", a.name(), c.a_lower)
    } else if c.b_lower > c.a_lower {
        format!("{} lower at {} of {n}", b.name(), c.b_lower)
    } else {
        format!("even ({} each of {n})", c.a_lower)
    };
    let ratio = if (1e-3..1e3).contains(&c.mean_ratio) {
        format!("{:.3}", c.mean_ratio)
    } else {
        format!("{:.2e}", c.mean_ratio)
    };
    format!(
        "{} vs {}: {lead} swept times ({} {}, {} {}, ties {}) in {:.3}–{:.3} ms/s; error {}/{} ×{ratio} (geometric mean)",
        a.name(),
        b.name(),
        a.name(),
        c.a_lower,
        b.name(),
        c.b_lower,
        c.ties,
        c.from,
        c.to,
        b.name(),
        a.name(),
    )
}

/// A case's summary: its verdict lines and failure counts.
pub struct CaseReport {
    /// The case.
    pub case: &'static Case,
    /// Ours against each Rapier at equal time.
    pub verdicts: Vec<String>,
    /// Marked runs per engine.
    pub failures: String,
    /// The plot's file name.
    pub svg_name: String,
}

/// A case's verdicts and failure counts, and its plot as SVG text.
pub fn report_case(case: &'static Case, ms: &[Measurement], sweep: &Sweep) -> (CaseReport, String) {
    let floor = floor_for(ms.iter().map(|m| m.error), case.zero_floor);
    let ceiling = ceiling_for(ms.iter().map(|m| m.error), floor);
    let ours = frontier_points(ms, Engine::Ours, floor, ceiling);
    let verdicts = [Engine::RapierF32, Engine::RapierF64]
        .iter()
        .map(|&b| {
            let theirs = frontier_points(ms, b, floor, ceiling);
            verdict(
                Engine::Ours,
                b,
                frontier::compare(&ours, &theirs),
                &ours,
                &theirs,
            )
        })
        .collect();
    let failures = Engine::ALL
        .iter()
        .map(|&e| {
            let all: Vec<&Measurement> = ms.iter().filter(|m| m.engine == e).collect();
            let bad: Vec<&str> = all
                .iter()
                .filter_map(|m| m.failure.map(Failure::name))
                .collect();
            let mut kinds: Vec<&str> = bad.clone();
            kinds.sort_unstable();
            kinds.dedup();
            if bad.is_empty() {
                format!("{} 0/{}", e.name(), all.len())
            } else {
                format!(
                    "{} {}/{} ({})",
                    e.name(),
                    bad.len(),
                    all.len(),
                    kinds.join(", ")
                )
            }
        })
        .collect::<Vec<_>>()
        .join(", ");
    let runs_note = sweep.runs_note();
    let svg = plot::svg(&plot::Plot {
        name: case.name,
        title: case.title,
        reference: case.reference,
        metric: case.metric,
        runs_note: &runs_note,
        measurements: ms,
        engines: &Engine::ALL,
        iterations: &sweep.iterations,
        floor,
        ceiling,
    })
    .unwrap_or_else(|e| {
        format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\"><text y=\"20\">plot failed: {}</text></svg>",
            html_escape(&e)
        )
    });
    let report = CaseReport {
        case,
        verdicts,
        failures,
        svg_name: format!("{}.svg", case.name),
    };
    (report, svg)
}

/// The CSV of every measurement.
pub fn csv(ms: &[Measurement]) -> String {
    let mut out = String::from(
        "suite,case,engine,tick_rate,substeps,iterations,ms_per_simulated_s,timed_runs,error,status,detail\n",
    );
    for m in ms {
        let _ = writeln!(
            out,
            "accuracy,{},{},{},{},{},{:.6},{},{:.6e},{},\"{}\"",
            m.case,
            m.engine.name(),
            m.settings.tick_rate,
            m.settings.substeps,
            m.settings.iterations,
            m.ms,
            m.timed_runs,
            m.error,
            m.status(),
            m.detail.replace('"', "\"\"")
        );
    }
    out
}

/// The settings text printed with the results and shown in the index.
pub fn settings_text(sweep: &Sweep) -> String {
    format!(
        "sweep: tick rate {:?} Hz × substeps {:?} × solver iterations {:?}; {}\n\
         ours: lockstep-core ({}), WorldConfig {{ tick_rate, substeps, solver_iterations = iterations, \
         relax_iterations = 1, sleep off, the rest default }}: contacts 60 Hz / damping ratio 10, margin 2 cm, \
         restitution threshold 1 m/s; fast bodies are swept by its CCD on their own\n\
         rapier3d 0.36.1 (f32) and rapier3d-f64 0.36.1 (enhanced-determinism, one thread): IntegrationParameters \
         {{ dt = 1/tick rate, num_solver_iterations = substeps (each is a TGS-soft substep: integrate, PGS with \
         bias, relax, like ours), num_internal_pgs_iterations = iterations, num_internal_stabilization_iterations = 1, \
         the rest default }}; can_sleep(false); CCD on the tunnelling shots only\n\
         both: every body of a case has the same friction and restitution, so each engine's combine rule gives \
         the case's value; inputs are rounded to Q32.32 first, so all engines start from the same numbers",
        sweep.tick_rates,
        sweep.substeps,
        sweep.iterations,
        sweep.runs_note(),
        match super::sim::rows() {
            lockstep_core::ContactRows::Exact => "Q32.32 contact rows",
            lockstep_core::ContactRows::Narrow => "narrow contact rows",
        }
    )
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The index page: the settings, one verdict block per case, every plot.
pub fn index_html(reports: &[CaseReport], sweep: &Sweep, elapsed_s: f64) -> String {
    let mut out = String::from(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>lockstep accuracy</title>\n\
         <style>body{font-family:sans-serif;max-width:1000px;margin:auto}li{margin:.2em 0}\
         img{max-width:100%;border:1px solid #ddd}pre{white-space:pre-wrap}</style></head><body>\n\
         <h1>Work-precision: lockstep-core beside Rapier</h1>\n",
    );
    let _ = writeln!(
        out,
        "<pre>{}</pre>\n<p>At equal time: each engine's frontier (its best error at a given CPU time, \
         interpolated on log–log axes) is compared at every swept time both frontiers cover; errors within 1 % tie. \
         Suite run time {elapsed_s:.0} s. See docs/accuracy.md.</p>\n<h2>Verdicts</h2>\n<ul>",
        html_escape(&settings_text(sweep))
    );
    for r in reports {
        let _ = writeln!(
            out,
            "<li><a href=\"#{0}\"><b>{0}</b></a>: {1}</li>",
            r.case.name,
            html_escape(&r.verdicts.join("; "))
        );
    }
    out.push_str("</ul>\n");
    for r in reports {
        let _ = writeln!(
            out,
            "<h2 id=\"{}\">{}</h2>\n<p>{}<br>error: {}<br>reference: {}<br>marked runs: {}</p>\n<ul>",
            r.case.name,
            r.case.name,
            html_escape(r.case.title),
            html_escape(r.case.metric),
            html_escape(r.case.reference),
            html_escape(&r.failures)
        );
        for v in &r.verdicts {
            let _ = writeln!(out, "<li>{}</li>", html_escape(v));
        }
        let _ = writeln!(
            out,
            "</ul>\n<img src=\"{}\" alt=\"{}\">",
            r.svg_name, r.case.name
        );
    }
    out.push_str("</body></html>\n");
    out
}

/// Writes the CSV, the plots and the index into `dir`.
pub fn write_outputs(
    dir: &Path,
    csv: &str,
    svgs: &[(&str, String)],
    index: &str,
) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    std::fs::write(dir.join("accuracy.csv"), csv)?;
    for (name, svg) in svgs {
        std::fs::write(dir.join(format!("{name}.svg")), svg)?;
    }
    std::fs::write(dir.join("index.html"), index)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accuracy::sim::Settings;

    fn m(engine: Engine, error: f64, failure: Option<Failure>) -> Measurement {
        Measurement {
            case: "t",
            engine,
            settings: Settings {
                tick_rate: 60,
                substeps: 1,
                iterations: 1,
            },
            ms: 1.0,
            timed_runs: 1,
            error,
            failure,
            detail: "a \"quoted\", detail".into(),
        }
    }

    #[test]
    fn floor_and_ceiling_are_decades_around_the_errors() {
        let f = floor_for([0.0, 3e-5, 0.2, f64::NAN], None);
        assert!((f / 1e-6 - 1.0).abs() < 1e-9, "{f}");
        assert_eq!(floor_for([0.0, f64::INFINITY], None), 1e-12);
        assert_eq!(floor_for([0.0, 0.5], Some(1e-3)), 1e-3);
        assert!((floor_for([0.0, 5e-4], Some(1e-3)) / 1e-5 - 1.0).abs() < 1e-9);
        let c = ceiling_for([0.0, 3e-5, 0.2, f64::INFINITY], f);
        assert!((c - 1.0).abs() < 1e-12, "{c}");
        assert!((ceiling_for([0.0], 1e-12) - 1e-10).abs() < 1e-24);
    }

    #[test]
    fn failed_runs_are_kept_and_only_untrusted_ones_leave_the_frontier() {
        assert!(m(Engine::Ours, 0.1, Some(Failure::Collapsed)).on_frontier());
        assert!(m(Engine::Ours, 0.1, Some(Failure::Tunnelled)).on_frontier());
        assert!(!m(Engine::Ours, 0.1, Some(Failure::Faulted)).on_frontier());
        assert!(!m(Engine::Ours, 0.1, Some(Failure::Wrong("slid"))).on_frontier());
        assert!(!m(Engine::Ours, f64::NAN, None).on_frontier());
        // Drawn: 0 at the floor, NaN and ∞ at the ceiling.
        assert_eq!(
            plot::drawn(&m(Engine::Ours, 0.0, None), 1e-6, 1.0),
            (1.0, 1e-6)
        );
        assert_eq!(
            plot::drawn(&m(Engine::Ours, f64::NAN, None), 1e-6, 1.0).1,
            1.0
        );
        assert_eq!(plot::drawn(&m(Engine::Ours, 5.0, None), 1e-6, 1.0).1, 1.0);
    }

    #[test]
    fn csv_has_one_quoted_line_per_measurement() {
        let text = csv(&[
            m(Engine::Ours, 0.5, None),
            m(Engine::RapierF32, 0.25, Some(Failure::Wrong("slid"))),
        ]);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3);
        assert_eq!(
            lines[1],
            "accuracy,t,ours,60,1,1,1.000000,1,5.000000e-1,ok,\"a \"\"quoted\"\", detail\""
        );
        assert!(lines[2].contains(",rapier-f32,") && lines[2].contains(",slid,"));
    }

    #[test]
    fn verdict_names_the_lower_engine_and_the_point_counts() {
        let p = |time, error| Point { time, error };
        let ours = [p(1.0, 1e-3), p(10.0, 1e-5)];
        let theirs = [p(1.0, 1e-2), p(10.0, 1e-4)];
        let c = frontier::compare(&ours, &theirs);
        let v = verdict(Engine::Ours, Engine::RapierF32, c, &ours, &theirs);
        assert!(
            v.starts_with("ours vs rapier-f32: ours lower at 4 of 4 swept times"),
            "{v}"
        );
        assert!(v.contains("×10.000"), "{v}");
        let late = [p(20.0, 1e-3)];
        let v = verdict(
            Engine::Ours,
            Engine::RapierF64,
            frontier::compare(&ours, &late),
            &ours,
            &late,
        );
        assert!(v.contains("no common time range"), "{v}");
    }
}
