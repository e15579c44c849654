//! The breaking-point logic of the `stress` suite: when a sweep stops, and
//! which value is an engine's breaking point. Plain functions over
//! (value, passed) pairs, so they are tested without running an engine.

/// The largest value that passes with every smaller tried value passing
/// too, from results in ascending order of value: the engine's breaking
/// point. `None` when the smallest value already fails.
pub fn breaking_point(results: &[(f64, bool)]) -> Option<f64> {
    results
        .iter()
        .take_while(|(_, pass)| *pass)
        .last()
        .map(|&(v, _)| v)
}

/// The first value that fails, if any (ascending order).
pub fn first_failure(results: &[(f64, bool)]) -> Option<f64> {
    results.iter().find(|(_, pass)| !pass).map(|&(v, _)| v)
}

/// Values above the first failure that pass again (a non-monotone
/// sweep: reported, never hidden).
pub fn passes_after_failure(results: &[(f64, bool)]) -> Vec<f64> {
    let Some(first) = results.iter().position(|(_, pass)| !pass) else {
        return Vec::new();
    };
    results[first..]
        .iter()
        .filter(|(_, pass)| *pass)
        .map(|&(v, _)| v)
        .collect()
}

/// Whether a sweep stops: its last `after` results all failed (the larger
/// values are costlier and would fail too). `after == 0` never stops.
pub fn should_stop(results: &[(f64, bool)], after: usize) -> bool {
    after > 0 && results.len() >= after && results[results.len() - after..].iter().all(|r| !r.1)
}

/// Whether a measured figure meets an upper bound: finite and at most
/// `limit` (NaN and infinity fail).
pub fn within(measured: f64, limit: f64) -> bool {
    measured.is_finite() && measured <= limit
}

/// One line for an engine's result in a sweep, e.g. `30 (fails at 40)`.
pub fn summary(results: &[(f64, bool)], unit: &str) -> String {
    let fmt = |v: f64| format!("{}{unit}", number(v));
    let mut s = match (breaking_point(results), first_failure(results)) {
        (_, None) if results.is_empty() => "not run".to_owned(),
        (Some(bp), None) => format!("≥ {} (passes every value tried)", fmt(bp)),
        (Some(bp), Some(f)) => format!("{} (fails at {})", fmt(bp), fmt(f)),
        (None, Some(f)) => format!("< {} (fails at the smallest value)", fmt(f)),
        (None, None) => unreachable!("an empty result list is handled above"),
    };
    let again = passes_after_failure(results);
    if !again.is_empty() {
        let list: Vec<String> = again.iter().map(|&v| fmt(v)).collect();
        s.push_str(&format!("; passes again at {}", list.join(", ")));
    }
    s
}

/// A swept value, short: `1e4` style above 10,000, else plain.
pub fn number(v: f64) -> String {
    if v >= 1e4 && v == v.round() {
        let e = v.log10().floor() as i32;
        let m = v / 10f64.powi(e);
        if (m - m.round()).abs() < 1e-9 {
            return format!("{}e{e}", m.round());
        }
    }
    if v == v.round() {
        format!("{}", v as i64)
    } else {
        format!("{v}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_breaking_point_is_the_last_pass_before_the_first_failure() {
        let r = [(5.0, true), (10.0, true), (20.0, false), (30.0, true)];
        assert_eq!(breaking_point(&r), Some(10.0));
        assert_eq!(first_failure(&r), Some(20.0));
        assert_eq!(passes_after_failure(&r), vec![30.0]);
        assert_eq!(breaking_point(&[(1.0, false), (2.0, true)]), None);
        assert_eq!(breaking_point(&[(1.0, true), (2.0, true)]), Some(2.0));
        assert_eq!(first_failure(&[(1.0, true)]), None);
        assert!(passes_after_failure(&[(1.0, true), (2.0, false)]).is_empty());
    }

    #[test]
    fn a_sweep_stops_after_the_given_run_of_failures() {
        let r = [(1.0, true), (2.0, false), (3.0, false)];
        assert!(should_stop(&r, 2));
        assert!(should_stop(&r, 1));
        assert!(!should_stop(&r, 3));
        assert!(!should_stop(&r, 0), "0 never stops");
        assert!(!should_stop(&[(1.0, false), (2.0, true)], 1));
        assert!(!should_stop(&[], 1));
    }

    #[test]
    fn bounds_reject_nan_and_infinity() {
        assert!(within(0.02, 0.02));
        assert!(!within(0.0201, 0.02));
        assert!(!within(f64::NAN, 1.0));
        assert!(!within(f64::INFINITY, 1.0));
    }

    #[test]
    fn summaries_name_the_breaking_point_and_the_failure() {
        let r = [(5.0, true), (10.0, true), (20.0, false)];
        assert_eq!(summary(&r, ""), "10 (fails at 20)");
        assert_eq!(
            summary(&[(1e3, true), (1e7, true)], " m"),
            "≥ 1e7 m (passes every value tried)"
        );
        assert_eq!(
            summary(&[(2.0, false), (3.0, true)], ""),
            "< 2 (fails at the smallest value); passes again at 3"
        );
        assert_eq!(summary(&[], ""), "not run");
        assert_eq!(number(10000.0), "1e4");
        assert_eq!(number(3000.0), "3000");
        assert_eq!(number(30000.0), "3e4");
        assert_eq!(number(0.5), "0.5");
    }
}
