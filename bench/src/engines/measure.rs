//! The runs: one engine measured on one scene, and one scene's figures for
//! both engines (alternating runs).

use std::time::Instant;

use lockstep_core::{ContactOrder, ContactRows, WorldConfig};

use super::Sim;
use super::ours::Ours;
use super::rapier::Rapier;
use crate::scenes::Scene;
use crate::{alloc, harness};

/// What one run of one engine measured.
#[derive(Clone, Debug)]
pub(super) struct Run {
    pub(super) ms_per_step: f64,
    pub(super) contact_points: usize,
    pub(super) peak_bytes: usize,
    pub(super) max_displacement: f64,
    pub(super) max_horizontal: f64,
    pub(super) top_dy: f64,
    /// The pile's shape at each quarter of the run (see [`Settle`]).
    pub(super) settle: [Settle; 4],
}

/// How far a scene has settled at one moment: the median height of the
/// bodies and how many are still above the ground's top (y > −1 m; the
/// scenes' ground tops are at y ≤ 0 and a body that slid off falls on).
#[derive(Clone, Copy, Debug, Default)]
pub struct Settle {
    /// Median body height, m.
    pub median_y: f64,
    /// Bodies with y > −1 m.
    pub on_ground: usize,
}

pub(super) fn settle_of(positions: &[[f64; 3]]) -> Settle {
    let mut ys: Vec<f64> = positions.iter().map(|p| p[1]).collect();
    ys.sort_by(f64::total_cmp);
    Settle {
        median_y: ys.get(ys.len() / 2).copied().unwrap_or(f64::NAN),
        on_ground: ys.iter().filter(|&&y| y > -1.0).count(),
    }
}

pub(super) fn measure<S: Sim>(scene: &Scene, build: impl FnOnce(&Scene) -> S) -> (Run, S) {
    let _one_at_a_time = alloc::MEASUREMENT.lock().unwrap_or_else(|e| e.into_inner());
    let base = alloc::reset_peak();
    let mut sim = build(scene);
    let mut total = 0.0;
    let mut settle = [Settle::default(); 4];
    for i in 0..scene.steps {
        let t = Instant::now();
        sim.step();
        let dt = t.elapsed().as_secs_f64();
        if i > 0 {
            total += dt;
        }
        // After each quarter of the run (outside the timed step).
        for (k, slot) in settle.iter_mut().enumerate() {
            if i + 1 == ((k + 1) * scene.steps / 4).max(1) {
                *slot = settle_of(&sim.positions());
            }
        }
    }
    let peak_bytes = alloc::peak().saturating_sub(base);
    let end = sim.positions();
    let dist = |a: [f64; 3], b: [f64; 3]| {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    let max_displacement = scene
        .positions
        .iter()
        .zip(&end)
        .map(|(&a, &b)| dist(a, b))
        .fold(0.0, f64::max);
    let max_horizontal = scene
        .positions
        .iter()
        .zip(&end)
        .map(|(&a, &b)| dist([a[0], 0.0, a[2]], [b[0], 0.0, b[2]]))
        .fold(0.0, f64::max);
    let top_dy = scene
        .tops
        .iter()
        .map(|&i| (end[i][1] - scene.positions[i][1]).abs())
        .fold(0.0, f64::max);
    let run = Run {
        ms_per_step: total * 1e3 / (scene.steps.max(2) - 1) as f64,
        contact_points: sim.contact_points(),
        peak_bytes,
        max_displacement,
        max_horizontal,
        top_dy,
        settle,
    };
    (run, sim)
}

/// Median and minimum of the runs' ms/step.
pub(super) fn median_min(runs: &[Run]) -> (f64, f64) {
    let mut v: Vec<f64> = runs.iter().map(|r| r.ms_per_step).collect();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let median = if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    };
    (median, v[0])
}

/// One engine's summary for one scene.
#[derive(Clone, Debug)]
pub struct EngineResult {
    /// ms/step, median over the runs.
    pub median_ms: f64,
    /// ms/step, fastest run.
    pub min_ms: f64,
    /// Contact points after the last step (last run).
    pub contact_points: usize,
    /// Heap high-water mark while building and stepping, bytes (smallest
    /// over the runs).
    pub peak_bytes: usize,
    /// Largest distance of any body from its start at the end, m.
    pub max_displacement: f64,
    /// Largest horizontal (x–z) distance of any body from its start, m: a
    /// pyramid that sags under soft contacts keeps this small; one that
    /// topples or slides does not.
    pub max_horizontal: f64,
    /// Largest vertical movement of a pyramid's top box, m (NaN if the
    /// scene has no pyramid).
    pub top_dy: f64,
    /// Whether our engine raised a fault flag (always false for Rapier).
    pub faulted: bool,
    /// The scene's settling at each quarter of the run (last run).
    pub settle: [Settle; 4],
}

impl EngineResult {
    pub(super) fn from_runs(runs: &[Run], has_tops: bool, faulted: bool) -> EngineResult {
        let (median_ms, min_ms) = median_min(runs);
        let last = runs.last().expect("at least one run");
        EngineResult {
            median_ms,
            min_ms,
            contact_points: last.contact_points,
            peak_bytes: runs.iter().map(|r| r.peak_bytes).min().unwrap_or(0),
            max_displacement: last.max_displacement,
            max_horizontal: last.max_horizontal,
            top_dy: if has_tops { last.top_dy } else { f64::NAN },
            faulted,
            settle: last.settle,
        }
    }

    /// "yes"/"NO" for the 1 cm top-box check, "n/a" for a pile.
    pub fn standing(&self) -> &'static str {
        if self.top_dy.is_nan() {
            "n/a"
        } else if self.top_dy <= 0.01 {
            "yes"
        } else {
            "NO"
        }
    }
}

/// One scene's figures for both engines.
#[derive(Clone, Debug)]
pub struct SceneResult {
    /// The scene's name.
    pub name: &'static str,
    /// Dynamic bodies.
    pub bodies: usize,
    /// Steps per run.
    pub steps: usize,
    /// Runs per engine.
    pub runs: usize,
    /// lockstep-core.
    pub ours: EngineResult,
    /// With `--threads N`: ours in pair order on N workers, and in colour
    /// order on one and on N.
    pub threaded: Option<Threaded>,
    /// Rapier.
    pub rapier: EngineResult,
    /// Ours on each contact-row format (pair order, one worker), measured
    /// in the same runs: the A/B of the rows.
    pub rows: RowsAb,
}

/// Ours with the Q32.32 rows and with the narrow rows (pair order, one
/// worker), in the same runs: the headline runs on the world's default
/// rows, and one run of the other format beside each.
#[derive(Clone, Debug)]
pub struct RowsAb {
    /// On the Q32.32 rows.
    pub exact: EngineResult,
    /// On the narrow rows.
    pub narrow: EngineResult,
    /// The share of constraint-ticks the narrow rows solved, and the share
    /// moved to the Q32.32 rows by the guard (last run).
    pub narrow_share: f64,
    pub fallback_share: f64,
}

/// Ours on N workers in pair order, and in colour order on one worker and
/// on N (`engines --threads N`).
#[derive(Clone, Debug)]
pub struct Threaded {
    /// N.
    pub workers: usize,
    /// Pair order, N workers (the same bits as pair order on one: the
    /// narrow phase, integrators and solver set-up split, the passes not).
    pub pairs_many: EngineResult,
    /// Colour order, one worker.
    pub one: EngineResult,
    /// Colour order, N workers (the same bits as `one`).
    pub many: EngineResult,
    /// Rapier on a pool of N threads.
    pub rapier_many: EngineResult,
    /// Which kernels ran the colour-order runs' normal rows
    /// ([`harness::kernels`]).
    pub kernels: String,
    /// Whether Rapier on N threads ended every run with the same positions,
    /// to the bit, as on one thread.
    pub rapier_same: bool,
    /// The core-to-core round trip (ns, [`harness::core_round_trip_ns`])
    /// before and after each run's N-thread measurements: whether the host
    /// had the two CPUs near each other or far apart while they ran.
    pub round_trip_ns: Vec<f64>,
}

/// Runs one scene `runs` times per engine, alternating; with `threads`,
/// each run also steps ours in pair order on that many workers and in
/// colour order on one worker and on that many.
/// With `wide`, the colour-order runs turn the solver's wide lanes on.
pub fn run_scene(scene: &Scene, runs: usize, threads: Option<usize>, wide: bool) -> SceneResult {
    let mut ours = Vec::new();
    // The headline runs are on the world's default rows; the A/B measures
    // the other format beside them.
    let default_rows = WorldConfig::default().contact_rows;
    let other_rows = match default_rows {
        ContactRows::Exact => ContactRows::Narrow,
        ContactRows::Narrow => ContactRows::Exact,
    };
    let mut other = Vec::new();
    let mut shares = (0.0, 0.0);
    let share_of = |count: (u64, u64, u64)| {
        let all = count.0.max(1) as f64;
        (count.1 as f64 / all, count.2 as f64 / all)
    };
    let mut theirs = Vec::new();
    let (mut pairs_many, mut one, mut many) = (Vec::new(), Vec::new(), Vec::new());
    let mut rapier_many = Vec::new();
    let mut rapier_same = true;
    let mut round_trip_ns = Vec::new();
    let mut kernels = String::new();
    let mut faulted = false;
    for _ in 0..runs.max(1) {
        let (run, sim) = measure(scene, Ours::new);
        faulted |= sim.faulted;
        if default_rows == ContactRows::Narrow {
            shares = share_of(sim.rows_count);
        }
        drop(sim);
        ours.push(run);
        let (run, sim) = measure(scene, |s| {
            Ours::with_rows(s, ContactOrder::Pairs, 1, false, other_rows)
        });
        faulted |= sim.faulted;
        if other_rows == ContactRows::Narrow {
            shares = share_of(sim.rows_count);
        }
        drop(sim);
        other.push(run);
        let (run, sim) = measure(scene, Rapier::new);
        let rapier_end = sim.positions();
        drop(sim);
        theirs.push(run);
        if let Some(n) = threads {
            round_trip_ns.push(harness::core_round_trip_ns(harness::ROUND_TRIPS));
            let (run, sim) = measure(scene, |s| Rapier::on_threads(s, n));
            rapier_same &= same_bits(&rapier_end, &sim.positions());
            drop(sim);
            rapier_many.push(run);
            for (order, workers, out) in [
                (ContactOrder::Pairs, n, &mut pairs_many),
                (ContactOrder::Colors, 1, &mut one),
                (ContactOrder::Colors, n, &mut many),
            ] {
                let (run, sim) = measure(scene, |s| Ours::with(s, order, workers, wide));
                faulted |= sim.faulted;
                if order == ContactOrder::Colors {
                    kernels = harness::kernels(&sim.world, order, sim.lanes.0, sim.lanes.1);
                }
                drop(sim);
                out.push(run);
            }
            round_trip_ns.push(harness::core_round_trip_ns(harness::ROUND_TRIPS));
        }
    }
    let has_tops = !scene.tops.is_empty();
    let threaded = threads.map(|workers| Threaded {
        workers,
        pairs_many: EngineResult::from_runs(&pairs_many, has_tops, faulted),
        one: EngineResult::from_runs(&one, has_tops, faulted),
        many: EngineResult::from_runs(&many, has_tops, faulted),
        rapier_many: EngineResult::from_runs(&rapier_many, has_tops, false),
        rapier_same,
        round_trip_ns,
        kernels,
    });
    SceneResult {
        threaded,
        name: scene.name,
        bodies: scene.positions.len(),
        steps: scene.steps,
        runs: runs.max(1),
        ours: EngineResult::from_runs(&ours, has_tops, faulted),
        rapier: EngineResult::from_runs(&theirs, has_tops, false),
        rows: {
            let (default, other) = (
                EngineResult::from_runs(&ours, has_tops, faulted),
                EngineResult::from_runs(&other, has_tops, faulted),
            );
            let (exact, narrow) = match default_rows {
                ContactRows::Exact => (default, other),
                ContactRows::Narrow => (other, default),
            };
            RowsAb {
                exact,
                narrow,
                narrow_share: shares.0,
                fallback_share: shares.1,
            }
        },
    }
}

/// Whether two lists of positions are the same to the bit.
pub(super) fn same_bits(a: &[[f64; 3]], b: &[[f64; 3]]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(p, q)| (0..3).all(|i| p[i].to_bits() == q[i].to_bits()))
}
