//! Work-precision frontiers and the "at equal time" comparison of two
//! engines.
//!
//! An engine's frontier is the lower-left envelope of its swept points in
//! (time, error): sorted by time, a point is kept when its error is lower
//! than that of every faster point (no other setting is both faster and at
//! least as accurate), and the best error holds on to the slowest point
//! (spending more time can always fall back to the faster setting).
//! Between frontier points the error is interpolated
//! linearly in log(time)–log(error), as the curves are drawn on log–log
//! axes. Two engines are compared at the times both frontiers cover (from
//! the later of their fastest points to the earlier of their slowest): at
//! each swept time of either engine inside that range, whichever
//! interpolated error is lower wins; errors within [`TIE`] of each other
//! are a tie.

/// Errors within this factor of each other count as equal (1 %).
pub const TIE: f64 = 1.01;

/// One measured point: CPU time per simulated second and error (positive
/// and finite: zero errors are clamped to the plot's floor first).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// ms per simulated second.
    pub time: f64,
    /// The case's error.
    pub error: f64,
}

/// The Pareto frontier of `points` (positive, finite ones only), by
/// increasing time and strictly decreasing error, then held flat to the
/// slowest point (its last two points may have equal errors).
pub fn frontier(points: &[Point]) -> Vec<Point> {
    let mut v: Vec<Point> = points
        .iter()
        .copied()
        .filter(|p| p.time > 0.0 && p.time.is_finite() && p.error > 0.0 && p.error.is_finite())
        .collect();
    v.sort_by(|a, b| a.time.total_cmp(&b.time).then(a.error.total_cmp(&b.error)));
    let mut out: Vec<Point> = Vec::new();
    for &p in &v {
        if out.last().is_none_or(|last| p.error < last.error) {
            out.push(p);
        }
    }
    // More time never costs accuracy (the faster setting is still there):
    // the best error so far holds up to the slowest swept point.
    if let (Some(slowest), Some(&last)) = (v.last(), out.last())
        && slowest.time > last.time
    {
        out.push(Point {
            time: slowest.time,
            error: last.error,
        });
    }
    out
}

/// The frontier's error at `time`, interpolated log–log between its
/// points; `None` outside the times it covers.
pub fn error_at(frontier: &[Point], time: f64) -> Option<f64> {
    let first = frontier.first()?;
    let last = frontier.last()?;
    if time < first.time || time > last.time {
        return None;
    }
    let i = frontier.partition_point(|p| p.time <= time);
    if i == 0 {
        return Some(first.error);
    }
    let a = frontier[i - 1];
    if a.time == time || i == frontier.len() {
        return Some(a.error);
    }
    let b = frontier[i];
    let u = (time.ln() - a.time.ln()) / (b.time.ln() - a.time.ln());
    Some((a.error.ln() + u * (b.error.ln() - a.error.ln())).exp())
}

/// The outcome of comparing engine A with engine B at equal time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Comparison {
    /// The common time range, ms per simulated second.
    pub from: f64,
    /// (end of the range)
    pub to: f64,
    /// Swept times in the range where A's frontier error is lower.
    pub a_lower: usize,
    /// Where B's is lower.
    pub b_lower: usize,
    /// Where they are within [`TIE`].
    pub ties: usize,
    /// Geometric mean of B's error over A's at those times (above 1: A is
    /// more accurate on average).
    pub mean_ratio: f64,
}

/// Compares A and B (each engine's points over the whole sweep) at equal
/// time; `None` when their frontiers share no time range.
pub fn compare(a: &[Point], b: &[Point]) -> Option<Comparison> {
    let (fa, fb) = (frontier(a), frontier(b));
    let from = fa.first()?.time.max(fb.first()?.time);
    let to = fa.last()?.time.min(fb.last()?.time);
    if from > to {
        return None;
    }
    let mut times: Vec<f64> = a
        .iter()
        .chain(b)
        .map(|p| p.time)
        .filter(|&t| t >= from && t <= to)
        .collect();
    times.sort_by(f64::total_cmp);
    let mut c = Comparison {
        from,
        to,
        a_lower: 0,
        b_lower: 0,
        ties: 0,
        mean_ratio: 1.0,
    };
    let mut log_sum = 0.0;
    for &t in &times {
        let (Some(ea), Some(eb)) = (error_at(&fa, t), error_at(&fb, t)) else {
            continue;
        };
        log_sum += (eb / ea).ln();
        if eb > ea * TIE {
            c.a_lower += 1;
        } else if ea > eb * TIE {
            c.b_lower += 1;
        } else {
            c.ties += 1;
        }
    }
    let n = c.a_lower + c.b_lower + c.ties;
    if n > 0 {
        c.mean_ratio = (log_sum / n as f64).exp();
    }
    Some(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(time: f64, error: f64) -> Point {
        Point { time, error }
    }

    #[test]
    fn frontier_keeps_only_points_no_faster_point_beats() {
        let pts = [
            p(4.0, 0.5),
            p(1.0, 1.0),
            p(2.0, 2.0), // slower and worse than (1, 1)
            p(8.0, 0.1),
            p(3.0, 0.5),
            p(5.0, f64::INFINITY),
            p(6.0, 0.0), // not positive: dropped
        ];
        assert_eq!(frontier(&pts), vec![p(1.0, 1.0), p(3.0, 0.5), p(8.0, 0.1)]);
        // A slowest point that is no better extends the frontier flat.
        let flat = frontier(&[p(1.0, 1.0), p(2.0, 0.5), p(9.0, 0.7)]);
        assert_eq!(flat, vec![p(1.0, 1.0), p(2.0, 0.5), p(9.0, 0.5)]);
        assert!(frontier(&[]).is_empty());
    }

    #[test]
    fn interpolation_is_linear_on_log_log_axes() {
        let f = [p(1.0, 1.0), p(100.0, 1e-4)];
        // Halfway in log time is halfway in log error.
        let e = error_at(&f, 10.0).unwrap();
        assert!((e - 1e-2).abs() < 1e-15, "{e}");
        assert_eq!(error_at(&f, 1.0), Some(1.0));
        assert_eq!(error_at(&f, 100.0), Some(1e-4));
        assert_eq!(error_at(&f, 0.5), None);
        assert_eq!(error_at(&f, 101.0), None);
        assert_eq!(error_at(&[p(2.0, 3.0)], 2.0), Some(3.0));
    }

    #[test]
    fn comparison_counts_swept_times_in_the_common_range() {
        // A: error 1/t on [1, 100]; B: ten times A's error on [10, 1000].
        let a: Vec<Point> = [1.0, 10.0, 100.0].iter().map(|&t| p(t, 1.0 / t)).collect();
        let b: Vec<Point> = [10.0, 100.0, 1000.0]
            .iter()
            .map(|&t| p(t, 10.0 / t))
            .collect();
        let c = compare(&a, &b).unwrap();
        assert_eq!((c.from, c.to), (10.0, 100.0));
        // Times 10 and 100 of each engine: four comparisons, all A.
        assert_eq!((c.a_lower, c.b_lower, c.ties), (4, 0, 0));
        assert!((c.mean_ratio - 10.0).abs() < 1e-9);
        let c = compare(&b, &a).unwrap();
        assert_eq!((c.a_lower, c.b_lower), (0, 4));
    }

    #[test]
    fn crossing_frontiers_split_the_points_and_equal_ones_tie() {
        // A is flat at 1e-2; B falls from 1 to 1e-4 across the same times.
        let a: Vec<Point> = [1.0, 10.0, 100.0].iter().map(|&t| p(t, 1e-2)).collect();
        let b = vec![p(1.0, 1.0), p(100.0, 1e-4)];
        let c = compare(&a, &b).unwrap();
        // A wins at t = 1 (twice), ties at 10 (B interpolates to 1e-2),
        // loses at 100 (twice).
        assert_eq!((c.a_lower, c.b_lower, c.ties), (2, 2, 1));
        assert_eq!(compare(&a, &a).unwrap().ties, 6);
    }

    #[test]
    fn disjoint_time_ranges_do_not_compare() {
        let a = [p(1.0, 1.0), p(2.0, 0.5)];
        let b = [p(3.0, 1.0), p(4.0, 0.5)];
        assert_eq!(compare(&a, &b), None);
        assert_eq!(compare(&a, &[]), None);
    }
}
