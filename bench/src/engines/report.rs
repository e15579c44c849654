//! The results as printed tables and CSV.

use std::fmt::Write as _;

use super::measure::{SceneResult, Settle};

/// The A/B of our contact rows: ms/step on the Q32.32 rows and on the
/// narrow rows (pair order, one worker, the same runs), beside Rapier.
pub fn rows_table(results: &[SceneResult]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "\ncontact rows: ours on the Q32.32 rows and on the narrow rows (pair order, one worker; median ms/step of the same runs)"
    );
    let _ = writeln!(
        out,
        "{:<14} {:>10} {:>10} {:>8} {:>10} {:>9} {:>9}  {:>8} {:>9}",
        "scene",
        "Q32.32",
        "narrow",
        "nar/Q32",
        "rapier",
        "Q32/rap",
        "nar/rap",
        "narrow%",
        "fallback%"
    );
    for r in results {
        let (e, n, rap) = (
            r.rows.exact.median_ms,
            r.rows.narrow.median_ms,
            r.rapier.median_ms,
        );
        let _ = writeln!(
            out,
            "{:<14} {:>10.3} {:>10.3} {:>8.2} {:>10.3} {:>9.2} {:>9.2}  {:>8.1} {:>9.3}",
            r.name,
            e,
            n,
            n / e,
            rap,
            e / rap,
            n / rap,
            100.0 * r.rows.narrow_share,
            100.0 * r.rows.fallback_share,
        );
    }
    out
}

pub(super) fn kib_per_body(bytes: usize, bodies: usize) -> f64 {
    bytes as f64 / 1024.0 / bodies.max(1) as f64
}

/// The results as the two printed tables (timing; memory and state).
pub fn table(results: &[SceneResult], skipped: &[&str]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:<14} {:>7} {:>6} {:>4}  {:>10} {:>10}  {:>10} {:>10}  {:>7}",
        "scene",
        "bodies",
        "steps",
        "runs",
        "ours med",
        "ours min",
        "rapier med",
        "rapier min",
        "ratio"
    );
    for r in results {
        let _ = writeln!(
            out,
            "{:<14} {:>7} {:>6} {:>4}  {:>10.3} {:>10.3}  {:>10.3} {:>10.3}  {:>7.2}",
            r.name,
            r.bodies,
            r.steps,
            r.runs,
            r.ours.median_ms,
            r.ours.min_ms,
            r.rapier.median_ms,
            r.rapier.min_ms,
            r.ours.median_ms / r.rapier.median_ms
        );
    }
    for s in skipped {
        let _ = writeln!(out, "{s:<14} skipped: needs joints");
    }
    let _ = writeln!(
        out,
        "(ms/step, first step excluded; ratio = ours median / Rapier median)\n"
    );
    let _ = writeln!(
        out,
        "{:<14} {:>9} {:>9}  {:>8} {:>8}  {:>10} {:>10}  {:>9} {:>9}  {:>9} {:>9}  {:>6} {:>6}",
        "scene",
        "contacts",
        "(rapier)",
        "KiB/body",
        "(rapier)",
        "max disp m",
        "(rapier)",
        "max xz m",
        "(rapier)",
        "top dy m",
        "(rapier)",
        "stands",
        "(rap.)"
    );
    for r in results {
        let _ = writeln!(
            out,
            "{:<14} {:>9} {:>9}  {:>8.2} {:>8.2}  {:>10.4} {:>10.4}  {:>9.4} {:>9.4}  {:>9.4} {:>9.4}  {:>6} {:>6}{}",
            r.name,
            r.ours.contact_points,
            r.rapier.contact_points,
            kib_per_body(r.ours.peak_bytes, r.bodies),
            kib_per_body(r.rapier.peak_bytes, r.bodies),
            r.ours.max_displacement,
            r.rapier.max_displacement,
            r.ours.max_horizontal,
            r.rapier.max_horizontal,
            r.ours.top_dy,
            r.rapier.top_dy,
            r.ours.standing(),
            r.rapier.standing(),
            if r.ours.faulted {
                "  (ours raised a fault flag)"
            } else {
                ""
            }
        );
    }
    let _ = writeln!(
        out,
        "(contacts after the last step: ours StepReport.contact_points, Rapier's solver contacts; \
         KiB/body = heap high-water mark while building and stepping / bodies; \
         max disp / max xz = largest total / horizontal distance of any body from its start; \
         stands = every pyramid's top box within 1 cm of its start height)"
    );
    let _ = writeln!(
        out,
        "\nsettling: median body height m / bodies still above the ground (y > -1 m), after each quarter of the run"
    );
    let _ = writeln!(
        out,
        "{:<14} {:<7} {:>18} {:>18} {:>18} {:>18}",
        "scene", "engine", "1/4", "1/2", "3/4", "end"
    );
    for r in results {
        for (engine, e) in [("ours", &r.ours), ("rapier", &r.rapier)] {
            let cell = |s: &Settle| format!("{:.3} / {}", s.median_y, s.on_ground);
            let _ = writeln!(
                out,
                "{:<14} {:<7} {:>18} {:>18} {:>18} {:>18}",
                r.name,
                engine,
                cell(&e.settle[0]),
                cell(&e.settle[1]),
                cell(&e.settle[2]),
                cell(&e.settle[3])
            );
        }
    }
    out
}

/// With `--threads N`: ours in pair order on 1 and N workers and in colour
/// order on 1 and N, beside Rapier on one thread and on N, from the same
/// runs.
pub fn threads_table(results: &[SceneResult]) -> String {
    let mut out = String::new();
    if results.iter().all(|r| r.threaded.is_none()) {
        return out;
    }
    let _ = writeln!(
        out,
        "\nthreads: ours on N workers (the same bits for any N; in pair order the narrow phase, integrators and solver set-up split, in colour order the solver passes too), Rapier on N threads (its `parallel` build)"
    );
    let _ = writeln!(
        out,
        "{:<14} {:>3}  {:>10} {:>10} {:>7}  {:>10} {:>10} {:>7}  {:>10} {:>10} {:>7} {:>5}  {:>8} {:>8}  {:>9} {:>9}  {:>11}",
        "scene",
        "N",
        "pairs 1",
        "pairs N",
        "1→N",
        "colours 1",
        "colours N",
        "1→N",
        "rapier 1",
        "rapier N",
        "1→N",
        "same",
        "N/rap N",
        "1/rap 1",
        "top dy N",
        "max xz N",
        "trip ns"
    );
    for r in results {
        let Some(t) = &r.threaded else { continue };
        let _ = writeln!(
            out,
            "{:<14} {:>3}  {:>10.3} {:>10.3} {:>6.2}×  {:>10.3} {:>10.3} {:>6.2}×  {:>10.3} {:>10.3} {:>6.2}× {:>5}  {:>8.2} {:>8.2}  {:>9.4} {:>9.4}  {:>11}",
            r.name,
            t.workers,
            r.ours.median_ms,
            t.pairs_many.median_ms,
            r.ours.median_ms / t.pairs_many.median_ms,
            t.one.median_ms,
            t.many.median_ms,
            t.one.median_ms / t.many.median_ms,
            r.rapier.median_ms,
            t.rapier_many.median_ms,
            r.rapier.median_ms / t.rapier_many.median_ms,
            if t.rapier_same { "yes" } else { "NO" },
            t.many.median_ms / t.rapier_many.median_ms,
            r.ours.median_ms / r.rapier.median_ms,
            t.many.top_dy,
            t.many.max_horizontal,
            trip_range(&t.round_trip_ns)
        );
    }
    for r in results {
        if let Some(t) = &r.threaded {
            let _ = writeln!(
                out,
                "{:<14} colour order's normal rows: {}",
                r.name, t.kernels
            );
        }
    }
    let _ = writeln!(
        out,
        "(median ms/step; 1→N = on 1 worker or thread / on N, in each order and for Rapier; same = Rapier on N threads ended \
         every run at the same positions, to the bit, as on one; N/rap N = ours in colour order on N workers / Rapier on N \
         threads; 1/rap 1 = ours in pair order / Rapier, both on one; trip ns = fewest–most ns for a cache line to go to \
         another thread and back, probed before and after each run's N-thread measurements: on a virtual machine, whether \
         the host kept the CPUs near each other (tens of ns) or far apart (hundreds), which moves every N-worker figure)"
    );
    out
}

/// The fewest and most of the round-trip probes, as `min–max` ns.
pub(super) fn trip_range(ns: &[f64]) -> String {
    let lo = ns.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = ns.iter().copied().fold(0.0, f64::max);
    if lo.is_finite() {
        format!("{lo:.0}–{hi:.0}")
    } else {
        "-".to_string()
    }
}

/// The results as CSV, one line per scene and engine.
pub fn csv(results: &[SceneResult]) -> String {
    let mut out = String::from(
        "suite,scene,engine,bodies,steps,runs,ms_median,ms_min,ratio_ours_to_rapier,contact_points,peak_bytes,bytes_per_body,max_displacement_m,max_horizontal_m,top_dy_m,standing\n",
    );
    for r in results {
        let ratio = r.ours.median_ms / r.rapier.median_ms;
        for (engine, e) in [("lockstep", &r.ours), ("rapier3d", &r.rapier)] {
            let _ = writeln!(
                out,
                "engines,{},{engine},{},{},{},{:.4},{:.4},{:.4},{},{},{:.1},{:.6},{:.6},{:.6},{}",
                r.name,
                r.bodies,
                r.steps,
                r.runs,
                e.median_ms,
                e.min_ms,
                ratio,
                e.contact_points,
                e.peak_bytes,
                e.peak_bytes as f64 / r.bodies.max(1) as f64,
                e.max_displacement,
                e.max_horizontal,
                e.top_dy,
                e.standing()
            );
        }
    }
    out
}
