//! The printed table, the summary and the CSV of `lockstep tune`.

use std::io::Write;

use super::{Deviation, Settings, Trial, TuneReport};

pub(super) fn table_row(t: &Trial, own: Settings) -> String {
    let s = t.settings;
    let (err, pos, angle) = match t.deviation {
        Some(d) => (
            fmt_len(d.error),
            fmt_len(d.position),
            format!("{:.3}°", d.angle.to_degrees()),
        ),
        None => ("-".into(), "-".into(), "-".into()),
    };
    let result = match (t.fault, t.pass) {
        (Some(f), _) => format!("FAIL: fault at tick {} ({})", f.tick, f.faults),
        (None, true) => "pass".into(),
        (None, false) => "fail".into(),
    };
    format!(
        "{:>6} {:>8} {:>6}  {:>12} {:>12} {:>10} {:>10.3} {:>12}  {result}{}",
        s.tick_rate,
        s.substeps,
        format!("{}+{}", s.solver_iterations, s.relax_iterations),
        err,
        pos,
        angle,
        t.cpu_ms_per_s,
        t.work_per_s,
        if s == own { " (scene's own)" } else { "" }
    )
}

/// Where a deviation is largest: ` (body "name" at 1.5 s)`.
fn worst_at(r: &TuneReport, d: &Deviation) -> String {
    match d.worst {
        Some((body, sample)) => format!(
            " (largest: body {:?} at {} s)",
            r.body_names.get(body).map_or("?", String::as_str),
            fmt_time(sample, r.plan.sample_hz)
        ),
        None => String::new(),
    }
}

pub(super) fn write_summary(r: &TuneReport, out: &mut impl Write) -> std::io::Result<()> {
    let own = r.own_trial();
    let own_err = own.deviation.map_or_else(
        || "a fault".to_owned(),
        |d| format!("{}{}", fmt_len(d.error), worst_at(r, &d)),
    );
    match r.chosen() {
        Some(t) => {
            let d = t.deviation.unwrap_or_default();
            writeln!(
                out,
                "chosen: {}: error {}{} (bound {}), {:.3} CPU ms per simulated second, work {}/s",
                t.settings,
                fmt_len(d.error),
                worst_at(r, &d),
                fmt_len(r.max_error),
                t.cpu_ms_per_s,
                t.work_per_s
            )?;
            let speedup = |a: f64, b: f64| {
                if b > 0.0 {
                    format!("{:.2}×", a / b)
                } else {
                    "-".to_owned()
                }
            };
            writeln!(
                out,
                "speed-up over the scene's own settings: {} in CPU time, {} in work",
                speedup(own.cpu_ms_per_s, t.cpu_ms_per_s),
                speedup(own.work_per_s as f64, t.work_per_s as f64)
            )?;
        }
        None => {
            let best = r
                .trials
                .iter()
                .filter_map(|t| t.deviation.map(|d| (t, d)))
                .min_by(|a, b| a.1.error.total_cmp(&b.1.error));
            writeln!(
                out,
                "chosen: none: no combination tried is within {} of the reference ({}); try a \
                 larger --max-error or finer candidates",
                fmt_len(r.max_error),
                r.reference
            )?;
            if let Some((t, d)) = best {
                writeln!(
                    out,
                    "closest: {}: error {}{}",
                    t.settings,
                    fmt_len(d.error),
                    worst_at(r, &d)
                )?;
            }
        }
    }
    writeln!(
        out,
        "scene's own settings ({}): error {}{}, {:.3} CPU ms per simulated second, work {}/s",
        r.own,
        own_err,
        if own.pass { "" } else { " (outside the bound)" },
        own.cpu_ms_per_s,
        own.work_per_s
    )?;
    if let (Some(p), Some(c)) = (&r.plot, &r.csv) {
        writeln!(out, "plot: {}  table: {}", p.display(), c.display())?;
    }
    Ok(())
}

/// The table as CSV, one line per trial.
pub(super) fn csv(r: &TuneReport) -> String {
    let mut s = String::from(
        "tick_rate,substeps,solver_iterations,relax_iterations,error_m,position_m,angle_rad,\
         worst_body,worst_time_s,cpu_ms_per_s,work_per_s,fault_tick,pass,own,chosen\n",
    );
    for (i, t) in r.trials.iter().enumerate() {
        let (e, p, a) = t
            .deviation
            .map_or((String::new(), String::new(), String::new()), |d| {
                (
                    format!("{:e}", d.error),
                    format!("{:e}", d.position),
                    format!("{:e}", d.angle),
                )
            });
        let (wb, wt) =
            t.deviation
                .and_then(|d| d.worst)
                .map_or((String::new(), String::new()), |(b, k)| {
                    (
                        r.body_names.get(b).cloned().unwrap_or_default(),
                        fmt_time(k, r.plan.sample_hz),
                    )
                });
        s.push_str(&format!(
            "{},{},{},{},{e},{p},{a},{wb},{wt},{},{},{},{},{},{}\n",
            t.settings.tick_rate,
            t.settings.substeps,
            t.settings.solver_iterations,
            t.settings.relax_iterations,
            t.cpu_ms_per_s,
            t.work_per_s,
            t.fault.map_or(String::new(), |f| f.tick.to_string()),
            t.pass,
            i == r.own_index,
            Some(i) == r.chosen,
        ));
    }
    s
}

/// A number without trailing zeros.
pub(super) fn fmt_num(v: f64) -> String {
    let s = format!("{v:.6}");
    s.trim_end_matches('0').trim_end_matches('.').to_owned()
}

/// Sample `k`'s time, s, to the millisecond.
fn fmt_time(k: u64, hz: u32) -> String {
    let s = format!("{:.3}", k as f64 / f64::from(hz));
    s.trim_end_matches('0').trim_end_matches('.').to_owned()
}

/// A length in the unit that reads best (m, mm, µm, nm).
pub fn fmt_len(m: f64) -> String {
    let a = m.abs();
    if m == 0.0 {
        "0".into()
    } else if a >= 1.0 {
        format!("{m:.3} m")
    } else if a >= 1e-3 {
        format!("{:.3} mm", m * 1e3)
    } else if a >= 1e-6 {
        format!("{:.3} µm", m * 1e6)
    } else {
        format!("{:.3} nm", m * 1e9)
    }
}
