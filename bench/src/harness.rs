//! Timing and reporting shared by every suite.
//!
//! A measurement runs one operation over a precomputed input array (small
//! enough to stay in L1, so memory does not dominate), repeats the pass
//! until the requested number of operations is reached, and keeps the
//! fastest of several runs: the minimum is the least disturbed by the other
//! work on a shared machine. Inputs and results go through
//! `std::hint::black_box`, so the compiler can neither hoist the work out
//! of the loop nor drop it. Successive calls are independent, so the
//! figure is throughput (ns per operation with the CPU overlapping calls),
//! not the latency of one isolated call.

use std::fmt::Write as _;
use std::hint::black_box;
use std::time::Instant;

/// How much work each measurement does.
#[derive(Clone, Copy, Debug)]
pub struct Budget {
    /// Operations per run.
    pub ops: usize,
    /// Runs per measurement; the fastest is reported.
    pub runs: usize,
}

impl Budget {
    /// The default: 1M operations, best of 7 runs.
    pub const FULL: Budget = Budget {
        ops: 1_000_000,
        runs: 7,
    };
    /// A smoke run for CI: checks that every benchmark executes, nothing
    /// more (the numbers are noise).
    pub const QUICK: Budget = Budget {
        ops: 2_000,
        runs: 1,
    };
}

/// Nanoseconds per call of `f` over `inputs`: the best of `budget.runs`.
pub fn ns_per_op<T: Copy, R>(budget: Budget, inputs: &[T], mut f: impl FnMut(T) -> R) -> f64 {
    assert!(!inputs.is_empty(), "a benchmark needs inputs");
    let passes = budget.ops.div_ceil(inputs.len()).max(1);
    let ops = passes * inputs.len();
    let mut best = f64::INFINITY;
    for _ in 0..budget.runs.max(1) {
        let start = Instant::now();
        for _ in 0..passes {
            for &x in inputs {
                black_box(f(black_box(x)));
            }
        }
        let ns = start.elapsed().as_nanos() as f64 / ops as f64;
        best = best.min(ns);
    }
    best
}

/// One line of a report: our operation against one reference.
#[derive(Clone, Debug)]
pub struct Row {
    /// What is measured, e.g. `sqrt`.
    pub op: String,
    /// Our ns/op.
    pub ours_ns: f64,
    /// What we are compared with, e.g. `f64::sqrt`.
    pub reference: String,
    /// The reference's ns/op.
    pub reference_ns: f64,
}

impl Row {
    /// A row from the two measurements.
    pub fn new(op: &str, ours_ns: f64, reference: &str, reference_ns: f64) -> Row {
        Row {
            op: op.to_owned(),
            ours_ns,
            reference: reference.to_owned(),
            reference_ns,
        }
    }

    /// ours / reference: above 1 means we are slower.
    pub fn ratio(&self) -> f64 {
        self.ours_ns / self.reference_ns
    }
}

/// The rows as an aligned text table.
pub fn table(rows: &[Row]) -> String {
    let op_w = rows.iter().map(|r| r.op.len()).max().unwrap_or(2).max(2);
    let ref_w = rows
        .iter()
        .map(|r| r.reference.len())
        .max()
        .unwrap_or(9)
        .max(9);
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:<op_w$}  {:>10}  {:<ref_w$}  {:>10}  {:>7}",
        "op", "ours ns/op", "reference", "ref ns/op", "ratio"
    );
    for r in rows {
        let _ = writeln!(
            out,
            "{:<op_w$}  {:>10.2}  {:<ref_w$}  {:>10.2}  {:>7.2}",
            r.op,
            r.ours_ns,
            r.reference,
            r.reference_ns,
            r.ratio()
        );
    }
    out
}

/// The rows as CSV with a header line, for plots and for comparing runs.
pub fn csv(suite: &str, rows: &[Row]) -> String {
    let mut out = String::from("suite,op,ours_ns,reference,reference_ns,ratio\n");
    for r in rows {
        let _ = writeln!(
            out,
            "{suite},{},{:.3},{},{:.3},{:.4}",
            r.op,
            r.ours_ns,
            r.reference,
            r.reference_ns,
            r.ratio()
        );
    }
    out
}

/// The generator of benchmark inputs: the workspace's one seeded test
/// generator (SplitMix64), so runs compare like with like.
pub use lockstep_testsupport::Rng;

/// Round trips a probe of [`core_round_trip_ns`] makes.
pub const ROUND_TRIPS: usize = 20_000;

/// Mean nanoseconds for one cache line to go from this thread to another
/// and back (`trips` round trips through one atomic word): what every
/// hand-over between two solver workers pays. On a virtual machine it
/// tells where the host put the two virtual CPUs at that moment: on this
/// project's 2-vCPU machines it is about 70 ns when they share a core
/// complex and 320–370 ns when they do not, and the host moves them
/// between the two every few minutes, which changes a 2-worker step by
/// up to 1.7× while a one-thread step does not move. The threaded tables
/// print it beside each measurement.
pub fn core_round_trip_ns(trips: usize) -> f64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    /// Spins before a wait yields (both threads on one CPU would otherwise
    /// spin out their time slices).
    const SPINS: u32 = 1 << 14;
    let word = AtomicU64::new(0);
    let wait_for = |want: u64| {
        let mut spins = 0u32;
        while word.load(Ordering::Acquire) != want {
            spins += 1;
            if spins >= SPINS {
                spins = 0;
                std::thread::yield_now();
            } else {
                std::hint::spin_loop();
            }
        }
    };
    let trips = trips.max(1) as u64;
    std::thread::scope(|s| {
        s.spawn(|| {
            for i in 0..trips {
                wait_for(2 * i + 1);
                word.store(2 * i + 2, Ordering::Release);
            }
        });
        // One trip first, so that the other thread is running before the
        // clock starts.
        word.store(1, Ordering::Release);
        wait_for(2);
        let start = Instant::now();
        for i in 1..trips {
            word.store(2 * i + 1, Ordering::Release);
            wait_for(2 * i + 2);
        }
        start.elapsed().as_secs_f64() * 1e9 / (trips - 1).max(1) as f64
    })
}

/// Which kernels ran our contact solver's normal rows, for the tables:
/// the exact wide lanes (with the batches they took and those their range
/// guard sent to the scalar rows, summed over a run), or the scalar rows
/// and why.
pub fn kernels(
    world: &lockstep_core::World,
    order: lockstep_core::ContactOrder,
    wide: u64,
    guarded: u64,
) -> String {
    if order == lockstep_core::ContactOrder::Pairs {
        "scalar (pair order has no batches)".to_owned()
    } else if world.wide() {
        let all = (wide + guarded).max(1) as f64;
        format!(
            "IFMA lanes: {wide} batches of 8 ({:.1}%), {guarded} sent to scalar by the guard",
            100.0 * wide as f64 / all
        )
    } else if lanes_here() {
        "scalar (the wide lanes are off; --wide turns them on)".to_owned()
    } else {
        "scalar (this CPU has no AVX-512 IFMA)".to_owned()
    }
}

/// What ran our contact rows over a run: the format, the share of the
/// constraints on the narrow rows, on the lanes and moved to the Q32.32
/// rows by the guard (sums over the run's steps of `StepReport`'s counts).
pub fn rows_line(
    world: &lockstep_core::World,
    constraints: u64,
    narrow: u64,
    fallbacks: u64,
    batches: u64,
) -> String {
    if world.config().contact_rows == lockstep_core::ContactRows::Exact {
        return "contact rows: Q32.32".to_owned();
    }
    let all = constraints.max(1) as f64;
    let lanes = match world.lanes() {
        Some(k) => format!("{k} lanes"),
        None => "lanes off".to_owned(),
    };
    format!(
        "contact rows: narrow, {:.1}% of constraints (Q32.32 rows from the start: {:.1}%; moved there by the guard: {:.3}%); {lanes}: {:.1}% in batches of 8",
        100.0 * narrow as f64 / all,
        100.0 * (constraints - narrow.min(constraints)) as f64 / all,
        100.0 * fallbacks as f64 / all,
        100.0 * (batches * 8) as f64 / all,
    )
}

/// Whether this CPU has the solver's wide lanes.
fn lanes_here() -> bool {
    let Ok(mut w) = lockstep_core::World::new(lockstep_core::WorldConfig::default()) else {
        return false;
    };
    w.set_wide(true);
    w.wide()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_and_csv_show_the_ratio_of_ours_to_the_reference() {
        let rows = [Row::new("sqrt", 8.0, "f64::sqrt", 2.0)];
        assert_eq!(rows[0].ratio(), 4.0);
        let t = table(&rows);
        assert!(t.lines().nth(1).unwrap().ends_with("4.00"), "{t}");
        assert_eq!(
            csv("math", &rows),
            "suite,op,ours_ns,reference,reference_ns,ratio\nmath,sqrt,8.000,f64::sqrt,2.000,4.0000\n"
        );
    }

    #[test]
    fn measurement_is_positive_and_finite() {
        let inputs: Vec<u64> = (0..64).collect();
        let ns = ns_per_op(Budget::QUICK, &inputs, |x| x.wrapping_mul(3));
        assert!(ns.is_finite() && ns >= 0.0);
    }

    #[test]
    fn the_round_trip_probe_measures_a_positive_time() {
        let ns = core_round_trip_ns(200);
        assert!(ns.is_finite() && ns > 0.0, "{ns}");
    }
}
