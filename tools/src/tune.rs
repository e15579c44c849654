//! `lockstep tune`: the cheapest simulation settings for a scene file, within
//! a given error of a fine-step reference.
//!
//! The scene runs as it is (no game inputs, like `lockstep sim`) once at the
//! reference settings and once per candidate combination of tick rate,
//! substeps and solver/relax iterations. Each candidate's trajectory is
//! compared with the reference's at the times every tick rate hits; its cost
//! is the CPU time per simulated second (the minimum of a few timed runs
//! after the measuring run, which also warms the caches) and a deterministic
//! work count. The timing lives here, outside the core: the core has no clock.
//! docs/tune.md describes the method.

mod plot;
mod report;
mod scene;

pub use scene::{Run, Scene};

use std::io::Write;
use std::path::PathBuf;

use lockstep_core::StepReport;
use lockstep_core::math::Faults;
use lockstep_core::scene::SceneError;
use lockstep_core::world::{MAX_SOLVER_ITERATIONS, MAX_SUBSTEPS, MAX_TICK_RATE};
use thiserror::Error;

/// The tick rates tried unless told otherwise (the scene's own is added).
pub const DEFAULT_TICK_RATES: [u32; 4] = [30, 60, 120, 240];
/// The substep counts tried unless told otherwise (the scene's own is added).
pub const DEFAULT_SUBSTEPS: [u32; 4] = [1, 2, 4, 8];
/// The solver (push-out) iteration counts tried unless told otherwise.
pub const DEFAULT_SOLVER_ITERATIONS: [u32; 3] = [1, 2, 4];
/// The relax iteration counts tried unless told otherwise.
pub const DEFAULT_RELAX_ITERATIONS: [u32; 2] = [1, 2];
/// The reference runs at least this many times the scene's tick rate.
pub const REFERENCE_RATE_FACTOR: u32 = 4;
/// The reference's substeps, at least.
pub const REFERENCE_SUBSTEPS: u32 = 8;
/// The reference's solver iterations, at least.
pub const REFERENCE_SOLVER_ITERATIONS: u32 = 8;
/// The reference's relax iterations, at least.
pub const REFERENCE_RELAX_ITERATIONS: u32 = 4;
/// How long the scene runs when `--ticks` is not given, in seconds.
pub const DEFAULT_SECONDS: u64 = 2;

/// What the choice minimises.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CostBasis {
    /// Measured CPU time per simulated second (the default).
    Cpu,
    /// The deterministic work count per simulated second (the same choice on
    /// every run and machine).
    Work,
}

/// The settings of one run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Settings {
    /// Ticks per second.
    pub tick_rate: u32,
    /// Substeps per tick.
    pub substeps: u32,
    /// Contact solver passes with push-out per substep.
    pub solver_iterations: u32,
    /// Contact solver passes without push-out per substep.
    pub relax_iterations: u32,
}

impl std::fmt::Display for Settings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} Hz, {} substep{}, {} solve + {} relax iteration{}",
            self.tick_rate,
            self.substeps,
            if self.substeps == 1 { "" } else { "s" },
            self.solver_iterations,
            self.relax_iterations,
            if self.relax_iterations == 1 { "" } else { "s" },
        )
    }
}

/// The candidate lists; the scene's own tick rate and substeps are always
/// added.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Candidates {
    /// Tick rates, Hz.
    pub tick_rates: Vec<u32>,
    /// Substep counts.
    pub substeps: Vec<u32>,
    /// Solver iteration counts.
    pub solver_iterations: Vec<u32>,
    /// Relax iteration counts.
    pub relax_iterations: Vec<u32>,
}

impl Default for Candidates {
    fn default() -> Candidates {
        Candidates {
            tick_rates: DEFAULT_TICK_RATES.to_vec(),
            substeps: DEFAULT_SUBSTEPS.to_vec(),
            solver_iterations: DEFAULT_SOLVER_ITERATIONS.to_vec(),
            relax_iterations: DEFAULT_RELAX_ITERATIONS.to_vec(),
        }
    }
}

/// What `lockstep tune` was asked to do.
#[derive(Clone, Debug, PartialEq)]
pub struct TuneOptions {
    /// The scene file.
    pub scene: PathBuf,
    /// The largest trajectory error accepted, m.
    pub max_error: f64,
    /// How long to run, in the scene's own ticks (`None`: 2 s).
    pub ticks: Option<u64>,
    /// Timed runs per combination (the minimum is kept), ≥ 1.
    pub repeats: u32,
    /// What the choice minimises.
    pub cost: CostBasis,
    /// The combinations to try.
    pub candidates: Candidates,
    /// Where to write the plot (`<scene>.svg`) and the table
    /// (`<scene>.csv`); `None` writes neither.
    pub out: Option<PathBuf>,
}

impl TuneOptions {
    /// The defaults for a scene: 1 mm, 2 s, 5 timed runs, by CPU time, the
    /// default candidates, output to `out/tune`.
    pub fn new(scene: impl Into<PathBuf>) -> TuneOptions {
        TuneOptions {
            scene: scene.into(),
            max_error: 1e-3,
            ticks: None,
            repeats: 5,
            cost: CostBasis::Cpu,
            candidates: Candidates::default(),
            out: Some(PathBuf::from("out/tune")),
        }
    }
}

/// Why `lockstep tune` failed.
#[derive(Debug, Error)]
pub enum TuneError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// The scene file is invalid.
    #[error("{0}")]
    Scene(#[from] SceneError),
    /// The reference run raised an arithmetic fault: there is nothing to
    /// compare with.
    #[error(
        "the reference run ({settings}) raised an arithmetic fault at its tick {tick}: {faults} \
         (the scene is outside the fixed-point range)"
    )]
    ReferenceFault {
        /// The reference settings.
        settings: Settings,
        /// The reference's tick.
        tick: u64,
        /// Which faults.
        faults: Faults,
    },
    /// An argument is out of range.
    #[error("{0}")]
    InvalidArgument(String),
    /// Writing the output failed.
    #[error("writing output: {0}")]
    Output(std::io::Error),
    /// Drawing the plot failed.
    #[error("drawing the plot: {0}")]
    Plot(String),
}

/// When the trajectories are compared: every `1/sample_hz` s, `samples`
/// times (the first at `1/sample_hz` s, the last at the end of the run).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Plan {
    /// The comparison rate, Hz: the greatest common divisor of every tick
    /// rate run, so every run has a tick at every sample time.
    pub sample_hz: u32,
    /// Sample times.
    pub samples: u64,
}

impl Plan {
    /// Ticks a run at `tick_rate` steps.
    pub fn steps(&self, tick_rate: u32) -> u64 {
        self.samples * u64::from(tick_rate / self.sample_hz)
    }

    /// The simulated time, s.
    pub fn seconds(&self) -> f64 {
        self.samples as f64 / f64::from(self.sample_hz)
    }
}

/// One body's pose at one sample time, as f64 (the metric is computed in
/// f64; the simulation itself is fixed point).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Pose {
    p: [f64; 3],
    /// [w, x, y, z].
    q: [f64; 4],
}

/// A run's dynamic-body poses, `poses[sample][body]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trajectory {
    poses: Vec<Vec<Pose>>,
}

/// How far a run is from the reference.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Deviation {
    /// The largest distance of a point of a dynamic body's bounding sphere
    /// from where the reference has it, over bodies and sample times, m:
    /// `|Δp| + 2·sin(θ/2)·r` (Δp the origin's offset, θ the rotation
    /// between the two orientations, r the body's bounding radius about its
    /// origin). The bound `--max-error` applies to this.
    pub error: f64,
    /// The largest origin offset alone, m.
    pub position: f64,
    /// The largest orientation difference, radians.
    pub angle: f64,
    /// The dynamic body (its index among the scene's dynamic bodies, in
    /// file order) and the sample (1-based) where `error` is largest.
    pub worst: Option<(usize, u64)>,
}

/// An arithmetic fault during a candidate's run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RunFault {
    /// The run's tick whose step raised it.
    pub tick: u64,
    /// Which faults.
    pub faults: Faults,
}

/// One combination tried.
#[derive(Clone, Debug, PartialEq)]
pub struct Trial {
    /// Its settings.
    pub settings: Settings,
    /// Its deviation from the reference (`None` when the run faulted).
    pub deviation: Option<Deviation>,
    /// The fault that made it fail, if any.
    pub fault: Option<RunFault>,
    /// CPU ms per simulated second (minimum of the timed runs; for a faulted
    /// run, of the ticks before the fault).
    pub cpu_ms_per_s: f64,
    /// The deterministic work count per simulated second (see
    /// [`step_work`]).
    pub work_per_s: u64,
    /// Whether it is within the bound (and did not fault).
    pub pass: bool,
}

impl Trial {
    /// The cost the choice minimises.
    pub fn cost(&self, basis: CostBasis) -> f64 {
        match basis {
            CostBasis::Cpu => self.cpu_ms_per_s,
            CostBasis::Work => self.work_per_s as f64,
        }
    }
}

/// What `lockstep tune` found.
#[derive(Clone, Debug, PartialEq)]
pub struct TuneReport {
    /// The scene file's name, as shown.
    pub scene: String,
    /// The scene's own settings.
    pub own: Settings,
    /// The reference settings.
    pub reference: Settings,
    /// The comparison times.
    pub plan: Plan,
    /// Dynamic bodies compared.
    pub dynamic_bodies: usize,
    /// Their names, in file order (see [`Deviation::worst`]).
    pub body_names: Vec<String>,
    /// The bound, m.
    pub max_error: f64,
    /// What the choice minimised.
    pub cost: CostBasis,
    /// Every combination tried, in the order run.
    pub trials: Vec<Trial>,
    /// The index in `trials` of the cheapest one within the bound.
    pub chosen: Option<usize>,
    /// The index in `trials` of the scene's own settings.
    pub own_index: usize,
    /// Where the plot went, if written.
    pub plot: Option<PathBuf>,
    /// Where the CSV went, if written.
    pub csv: Option<PathBuf>,
}

impl TuneReport {
    /// The chosen trial.
    pub fn chosen(&self) -> Option<&Trial> {
        self.chosen.map(|i| &self.trials[i])
    }

    /// The scene's own settings' trial.
    pub fn own_trial(&self) -> &Trial {
        &self.trials[self.own_index]
    }
}

/// Parses a length with a unit, `m`, `cm` or `mm` (`1mm`, `0.5 cm`,
/// `2e-3m`), into metres.
///
/// # Errors
/// A message saying what was expected.
pub fn parse_length(text: &str) -> Result<f64, String> {
    let t = text.trim();
    let (number, scale) = if let Some(n) = t.strip_suffix("mm") {
        (n, 1e-3)
    } else if let Some(n) = t.strip_suffix("cm") {
        (n, 1e-2)
    } else if let Some(n) = t.strip_suffix('m') {
        (n, 1.0)
    } else {
        return Err(format!(
            "{text:?} has no unit: write a length with m, cm or mm, e.g. 1mm"
        ));
    };
    let number = number.trim();
    let v: f64 = number
        .parse()
        .map_err(|_| format!("{text:?} is not a length: expected a number then m, cm or mm"))?;
    if !v.is_finite() || v < 0.0 {
        return Err(format!(
            "{text:?} must be a finite length of at least 0 (m, cm or mm)"
        ));
    }
    Ok(v * scale)
}

/// The work one step did, a deterministic cost proxy: one for the step
/// itself, broad-phase candidate pairs and narrow-phase tests once per tick,
/// then per substep each awake body once (integration) and each contact
/// constraint once per warm start, solve and relax pass.
pub fn step_work(r: &StepReport, s: Settings) -> u64 {
    let per_substep = u64::from(r.awake_bodies)
        + u64::from(r.contact_constraints)
            * u64::from(1 + s.solver_iterations + s.relax_iterations);
    1 + u64::from(r.candidate_pairs)
        + u64::from(r.narrow_tests)
        + u64::from(s.substeps) * per_substep
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// The reference for a scene running at `own` with these candidates: the
/// smallest multiple of the scene's tick rate that is at least 4× it and at
/// least the fastest candidate (at most 10,000 Hz), at least 8 substeps and
/// 8 solve + 4 relax iterations, and never coarser than a candidate.
pub fn reference_settings(own: Settings, c: &Candidates) -> Settings {
    let max = |v: &[u32], own: u32| v.iter().copied().chain([own]).max().unwrap_or(own);
    let want = (own.tick_rate.saturating_mul(REFERENCE_RATE_FACTOR))
        .max(max(&c.tick_rates, own.tick_rate));
    let mut rate = want.div_ceil(own.tick_rate).saturating_mul(own.tick_rate);
    if rate > MAX_TICK_RATE {
        rate = (MAX_TICK_RATE / own.tick_rate).max(1) * own.tick_rate;
    }
    Settings {
        tick_rate: rate,
        substeps: REFERENCE_SUBSTEPS
            .max(max(&c.substeps, own.substeps))
            .min(MAX_SUBSTEPS),
        solver_iterations: REFERENCE_SOLVER_ITERATIONS
            .max(max(&c.solver_iterations, own.solver_iterations))
            .min(MAX_SOLVER_ITERATIONS),
        relax_iterations: REFERENCE_RELAX_ITERATIONS
            .max(max(&c.relax_iterations, own.relax_iterations))
            .min(MAX_SOLVER_ITERATIONS),
    }
}

/// Every candidate combination, the scene's own tick rate and substeps
/// added, in run order (tick rate, substeps, solver, relax; ascending).
fn combinations(own: Settings, c: &Candidates) -> Vec<Settings> {
    let sorted = |v: &[u32], extra: u32| {
        let mut v: Vec<u32> = v.iter().copied().chain([extra]).collect();
        v.sort_unstable();
        v.dedup();
        v
    };
    let rates = sorted(&c.tick_rates, own.tick_rate);
    let subs = sorted(&c.substeps, own.substeps);
    let solve = sorted(&c.solver_iterations, own.solver_iterations);
    let relax = sorted(&c.relax_iterations, own.relax_iterations);
    let mut out = Vec::new();
    for &tick_rate in &rates {
        for &substeps in &subs {
            for &solver_iterations in &solve {
                for &relax_iterations in &relax {
                    out.push(Settings {
                        tick_rate,
                        substeps,
                        solver_iterations,
                        relax_iterations,
                    });
                }
            }
        }
    }
    out
}

fn check_list(name: &str, v: &[u32], max: u32) -> Result<(), TuneError> {
    if v.is_empty() {
        return Err(TuneError::InvalidArgument(format!(
            "{name} needs at least one value"
        )));
    }
    if let Some(bad) = v.iter().find(|&&x| x == 0 || x > max) {
        return Err(TuneError::InvalidArgument(format!(
            "{name}: {bad} is out of range (1 to {max})"
        )));
    }
    Ok(())
}

/// The plan for a scene: compare at the greatest common divisor of every
/// tick rate run, over `ticks` of the scene's own ticks (rounded down to a
/// whole number of sample intervals).
fn plan(
    own: Settings,
    reference: Settings,
    all: &[Settings],
    ticks: u64,
) -> Result<Plan, TuneError> {
    let sample_hz = all
        .iter()
        .map(|s| s.tick_rate)
        .chain([own.tick_rate, reference.tick_rate])
        .fold(0, gcd);
    let samples = ticks * u64::from(sample_hz) / u64::from(own.tick_rate);
    if samples == 0 {
        return Err(TuneError::InvalidArgument(format!(
            "--ticks {ticks} is shorter than one comparison interval (1/{sample_hz} s = {} ticks \
             at the scene's {} Hz): give at least that many",
            own.tick_rate / sample_hz,
            own.tick_rate
        )));
    }
    Ok(Plan { sample_hz, samples })
}

/// Runs `lockstep tune`, printing the table as it goes and the choice at the
/// end to `out`, and writing the plot and CSV if asked.
///
/// # Errors
/// See [`TuneError`]. No combination within the bound is not an error: the
/// report's `chosen` is `None`.
pub fn run_tune(opts: &TuneOptions, out: &mut impl Write) -> Result<TuneReport, TuneError> {
    let c = &opts.candidates;
    check_list("--tick-rates", &c.tick_rates, MAX_TICK_RATE)?;
    check_list("--substeps", &c.substeps, MAX_SUBSTEPS)?;
    check_list("--iterations", &c.solver_iterations, MAX_SOLVER_ITERATIONS)?;
    check_list("--relax", &c.relax_iterations, MAX_SOLVER_ITERATIONS)?;
    if opts.repeats == 0 {
        return Err(TuneError::InvalidArgument(
            "--repeats must be at least 1".into(),
        ));
    }
    if !(opts.max_error.is_finite() && opts.max_error >= 0.0) {
        return Err(TuneError::InvalidArgument(
            "--max-error must be a finite length of at least 0".into(),
        ));
    }
    let scene = Scene::load(&opts.scene)?;
    let own = scene.own();
    let reference = reference_settings(own, c);
    let all = combinations(own, c);
    let ticks = opts
        .ticks
        .unwrap_or(DEFAULT_SECONDS * u64::from(own.tick_rate));
    if ticks == 0 {
        return Err(TuneError::InvalidArgument(
            "--ticks must be at least 1".into(),
        ));
    }
    let plan = plan(own, reference, &all, ticks)?;
    let o = |e| TuneError::Output(e);
    let name = opts.scene.display().to_string();

    writeln!(out, "lockstep tune: {name}").map_err(o)?;
    writeln!(out, "scene's own settings: {own}").map_err(o)?;
    writeln!(out, "reference:            {reference}").map_err(o)?;
    writeln!(
        out,
        "run: {} s ({} ticks at the scene's {} Hz), compared every 1/{} s ({} times), {} dynamic \
         bod{}",
        report::fmt_num(plan.seconds()),
        plan.steps(own.tick_rate),
        own.tick_rate,
        plan.sample_hz,
        plan.samples,
        scene.dynamic_bodies(),
        if scene.dynamic_bodies() == 1 {
            "y"
        } else {
            "ies"
        }
    )
    .map_err(o)?;
    writeln!(
        out,
        "error: the largest distance of a point of a dynamic body from where the reference has it \
         (|Δp| + 2·sin(θ/2)·radius), bound {}",
        report::fmt_len(opts.max_error)
    )
    .map_err(o)?;
    writeln!(
        out,
        "cost: CPU ms per simulated second, minimum of {} timed run{} after a warm-up; work: a \
         deterministic count per simulated second (pairs, tests, body and contact passes); the \
         choice minimises {}",
        opts.repeats,
        if opts.repeats == 1 { "" } else { "s" },
        match opts.cost {
            CostBasis::Cpu => "CPU time",
            CostBasis::Work => "work",
        }
    )
    .map_err(o)?;

    let ref_run = scene.run(reference, plan)?;
    if let Some(f) = ref_run.fault {
        return Err(TuneError::ReferenceFault {
            settings: reference,
            tick: f.tick,
            faults: f.faults,
        });
    }
    // Warm the caches and the clock before the first timed run.
    scene.time(own, plan.steps(own.tick_rate))?;
    writeln!(out).map_err(o)?;
    writeln!(
        out,
        "{:>6} {:>8} {:>6}  {:>12} {:>12} {:>10} {:>10} {:>12}  result",
        "Hz", "substeps", "iters", "error", "position", "angle", "CPU ms/s", "work/s"
    )
    .map_err(o)?;

    let mut trials = Vec::with_capacity(all.len());
    for &s in &all {
        let run = scene.run(s, plan)?;
        let seconds = run.steps as f64 / f64::from(s.tick_rate);
        let mut best = f64::INFINITY;
        for _ in 0..opts.repeats {
            best = best.min(scene.time(s, run.steps)?);
        }
        let cpu_ms_per_s = if seconds > 0.0 {
            best * 1e3 / seconds
        } else {
            0.0
        };
        let work_per_s = if seconds > 0.0 {
            (run.work as f64 / seconds).round() as u64
        } else {
            0
        };
        let deviation = match run.fault {
            None => Some(scene.deviation(&run.trajectory, &ref_run.trajectory)),
            Some(_) => None,
        };
        let pass = deviation.is_some_and(|d| d.error <= opts.max_error);
        let trial = Trial {
            settings: s,
            deviation,
            fault: run.fault,
            cpu_ms_per_s,
            work_per_s,
            pass,
        };
        writeln!(out, "{}", report::table_row(&trial, own)).map_err(o)?;
        trials.push(trial);
    }

    let own_index = trials
        .iter()
        .position(|t| t.settings == own)
        .expect("the scene's own settings are always tried");
    let chosen = choose(&trials, opts.cost);
    let mut report = TuneReport {
        scene: name,
        own,
        reference,
        plan,
        dynamic_bodies: scene.dynamic_bodies(),
        body_names: scene.body_names().to_vec(),
        max_error: opts.max_error,
        cost: opts.cost,
        trials,
        chosen,
        own_index,
        plot: None,
        csv: None,
    };
    if let Some(dir) = &opts.out {
        std::fs::create_dir_all(dir).map_err(|source| TuneError::Io {
            path: dir.clone(),
            source,
        })?;
        let stem = opts
            .scene
            .file_stem()
            .map_or_else(|| "scene".to_owned(), |s| s.to_string_lossy().into_owned());
        let svg_path = dir.join(format!("{stem}.svg"));
        let svg = plot::svg(&report).map_err(TuneError::Plot)?;
        std::fs::write(&svg_path, svg).map_err(|source| TuneError::Io {
            path: svg_path.clone(),
            source,
        })?;
        let csv_path = dir.join(format!("{stem}.csv"));
        std::fs::write(&csv_path, report::csv(&report)).map_err(|source| TuneError::Io {
            path: csv_path.clone(),
            source,
        })?;
        report.plot = Some(svg_path);
        report.csv = Some(csv_path);
    }
    writeln!(out).map_err(o)?;
    report::write_summary(&report, out).map_err(o)?;
    Ok(report)
}

/// CPU times within this fraction of the cheapest passing one count as a
/// tie (the minimum of a few runs still moves by a few per cent on a loaded
/// machine); the work count breaks it.
pub const CPU_TIE: f64 = 0.05;

/// Whether `a` asks for no more than `b` in every setting.
fn no_finer(a: Settings, b: Settings) -> bool {
    a.tick_rate <= b.tick_rate
        && a.substeps <= b.substeps
        && a.solver_iterations <= b.solver_iterations
        && a.relax_iterations <= b.relax_iterations
}

/// The cheapest passing trial. A passing trial is first set aside if
/// another passing one does no more work with settings no finer in any
/// respect (extra iterations with no contacts to solve cost nothing but
/// noise). By work: the least work, then run order (the coarser settings).
/// By CPU time: among the rest within [`CPU_TIE`] of the fastest, the same.
pub fn choose(trials: &[Trial], basis: CostBasis) -> Option<usize> {
    let dominated = |t: &Trial| {
        trials.iter().any(|u| {
            u.pass
                && u.settings != t.settings
                && u.work_per_s <= t.work_per_s
                && no_finer(u.settings, t.settings)
        })
    };
    let candidates: Vec<(usize, &Trial)> = trials
        .iter()
        .enumerate()
        .filter(|(_, t)| t.pass && !dominated(t))
        .collect();
    let limit = match basis {
        CostBasis::Work => f64::INFINITY,
        CostBasis::Cpu => {
            candidates
                .iter()
                .map(|(_, t)| t.cpu_ms_per_s)
                .fold(f64::INFINITY, f64::min)
                * (1.0 + CPU_TIE)
        }
    };
    candidates
        .into_iter()
        .filter(|(_, t)| t.cpu_ms_per_s <= limit)
        .min_by(|(i, a), (j, b)| a.work_per_s.cmp(&b.work_per_s).then(i.cmp(j)))
        .map(|(i, _)| i)
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::rotation_between;

    #[test]
    fn lengths_parse_with_their_unit() {
        assert_eq!(parse_length("1mm"), Ok(1e-3));
        assert_eq!(parse_length("2.5 cm"), Ok(0.025));
        assert_eq!(parse_length("0.004m"), Ok(0.004));
        assert_eq!(parse_length("1e-3 m"), Ok(1e-3));
        assert_eq!(parse_length("0mm"), Ok(0.0));
        for bad in ["1", "1km", "mm", "-1mm", "infmm", "NaN m", "1 inch"] {
            assert!(parse_length(bad).is_err(), "{bad} parsed");
        }
    }

    #[test]
    fn the_reference_is_at_least_four_times_the_scene_rate_and_never_coarser() {
        let own = Settings {
            tick_rate: 60,
            substeps: 4,
            solver_iterations: 1,
            relax_iterations: 1,
        };
        let c = Candidates::default();
        let r = reference_settings(own, &c);
        assert_eq!(
            r,
            Settings {
                tick_rate: 240,
                substeps: 8,
                solver_iterations: 8,
                relax_iterations: 4
            }
        );
        // A slow scene: the fastest candidate (240 Hz) wins, rounded up to
        // a multiple of the scene's 50 Hz.
        let r = reference_settings(
            Settings {
                tick_rate: 50,
                ..own
            },
            &c,
        );
        assert_eq!(r.tick_rate, 250);
        // A fast one: capped at 10,000 Hz, still a multiple of its rate.
        let r = reference_settings(
            Settings {
                tick_rate: 3000,
                ..own
            },
            &c,
        );
        assert_eq!(r.tick_rate, 9000);
        for s in combinations(own, &c) {
            assert!(s.tick_rate <= 240 && s.substeps <= r.substeps);
            assert!(s.solver_iterations < r.solver_iterations);
            assert!(s.relax_iterations < r.relax_iterations);
        }
    }

    #[test]
    fn every_run_has_a_tick_at_every_sample_time() {
        let own = Settings {
            tick_rate: 50,
            substeps: 3,
            solver_iterations: 1,
            relax_iterations: 1,
        };
        let c = Candidates::default();
        let reference = reference_settings(own, &c);
        let all = combinations(own, &c);
        // 30, 50, 60, 120, 240 Hz and the reference's 250: every 1/10 s.
        let p = plan(own, reference, &all, 100).unwrap();
        assert_eq!(
            p,
            Plan {
                sample_hz: 10,
                samples: 20
            }
        );
        assert_eq!(p.steps(30), 60);
        assert_eq!(p.steps(250), 500);
        assert!(plan(own, reference, &all, 4).is_err());
        // 5 rates × 5 substep counts (3 added) × 3 × 2 iterations.
        assert_eq!(all.len(), 5 * 5 * 3 * 2);
    }

    #[test]
    fn rotation_angles_are_exact_at_zero_and_right_elsewhere() {
        // A quaternion that is unit only to about 1e-9, as Q32.32 gives.
        let q = [0.6, 0.0, 0.8 + 1e-9, 0.0];
        assert_eq!(rotation_between(q, q), 0.0);
        assert_eq!(rotation_between(q, q.map(|v| -v)), 0.0);
        let half = 0.25f64; // a 0.5 rad turn about x
        let r = [half.cos(), half.sin(), 0.0, 0.0];
        assert!((rotation_between(r, [1.0, 0.0, 0.0, 0.0]) - 0.5).abs() < 1e-12);
        let flip = [0.0, 0.0, 0.0, 1.0]; // π about z
        assert!(
            (rotation_between(flip, [1.0, 0.0, 0.0, 0.0]) - std::f64::consts::PI).abs() < 1e-12
        );
    }

    fn trial(tick_rate: u32, solve: u32, error: Option<f64>, ms: f64, work: u64) -> Trial {
        let settings = Settings {
            tick_rate,
            substeps: 1,
            solver_iterations: solve,
            relax_iterations: 1,
        };
        let deviation = error.map(|error| Deviation {
            error,
            ..Deviation::default()
        });
        Trial {
            settings,
            deviation,
            fault: error.is_none().then_some(RunFault {
                tick: 7,
                faults: Faults::OVERFLOW,
            }),
            cpu_ms_per_s: ms,
            work_per_s: work,
            pass: error.is_some_and(|e| e <= 1e-3),
        }
    }

    #[test]
    fn the_choice_skips_faults_and_failures_and_breaks_ties_by_work() {
        let trials = [
            // Cheapest of all, but it faulted: a failure, shown as such.
            trial(30, 1, None, 0.1, 10),
            // Outside the bound.
            trial(30, 2, Some(2e-3), 0.2, 20),
            // Within: the fastest, and one within 5% of it with less work.
            trial(60, 1, Some(5e-4), 1.0, 50),
            trial(60, 2, Some(4e-4), 1.04, 40),
            trial(120, 1, Some(1e-4), 3.0, 90),
        ];
        assert_eq!(choose(&trials, CostBasis::Cpu), Some(3));
        assert_eq!(choose(&trials, CostBasis::Work), Some(3));
        let row = report::table_row(&trials[0], trials[4].settings);
        assert!(row.contains("FAIL: fault at tick 7 (overflow)"), "{row}");
        assert!(!trials[0].pass);
        // Equal work, one asks for more iterations: the coarser one, even
        // when the clock says the other was faster.
        let tie = [
            trial(60, 2, Some(1e-4), 1.0, 40),
            trial(60, 1, Some(1e-4), 1.2, 40),
        ];
        assert_eq!(choose(&tie, CostBasis::Cpu), Some(1));
        assert_eq!(
            choose(&[trials[0].clone(), trials[1].clone()], CostBasis::Cpu),
            None
        );
    }

    #[test]
    fn work_counts_every_pass() {
        let r = StepReport {
            candidate_pairs: 3,
            narrow_tests: 2,
            awake_bodies: 5,
            contact_constraints: 4,
            ..StepReport::default()
        };
        let s = Settings {
            tick_rate: 60,
            substeps: 2,
            solver_iterations: 2,
            relax_iterations: 1,
        };
        // 1 + 3 + 2 + 2 · (5 + 4 · (1 + 2 + 1)).
        assert_eq!(step_work(&r, s), 1 + 3 + 2 + 2 * (5 + 16));
    }
}
