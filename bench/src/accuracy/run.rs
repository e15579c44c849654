//! Running one case in one engine at one setting: the timed stepping, the
//! generic instability checks, and what a run reports.

use std::time::{Duration, Instant};

use super::sim::{self, Engine, Settings, Sim, Spec};

/// Why a run is drawn as a marked point: it went unstable or got the
/// qualitative physics wrong.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Failure {
    /// Our step reported an arithmetic fault: its numbers are not trusted.
    Faulted,
    /// A position, orientation or velocity became NaN or infinite.
    NonFinite,
    /// A body went faster than the case allows.
    Exploded,
    /// A stack or pyramid fell over.
    Collapsed,
    /// A projectile passed through the wall.
    Tunnelled,
    /// The run finished but missed the case's qualitative outcome (named).
    Wrong(&'static str),
}

impl Failure {
    /// The name in the CSV's `status` column and the index.
    pub fn name(self) -> &'static str {
        match self {
            Failure::Faulted => "faulted",
            Failure::NonFinite => "nan",
            Failure::Exploded => "exploded",
            Failure::Collapsed => "collapsed",
            Failure::Tunnelled => "tunnelled",
            Failure::Wrong(what) => what,
        }
    }

    /// Whether the error still measures the run: a run that exploded,
    /// collapsed or tunnelled shows it in its error (a large drift, a
    /// fraction of shots through). A faulted or non-finite run's error is
    /// not trusted, and a run that missed the case's outcome may have a
    /// small error for the wrong reason (boxes that never separate move
    /// slowly): those stay off the frontier.
    pub fn error_is_meaningful(self) -> bool {
        matches!(
            self,
            Failure::Exploded | Failure::Collapsed | Failure::Tunnelled
        )
    }
}

/// What one run of a case measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// The case's error (see its metric); NaN if it could not be measured.
    pub error: f64,
    /// Set when the run is drawn as a marked point.
    pub failure: Option<Failure>,
    /// Secondary figures, for the CSV.
    pub detail: String,
}

impl Outcome {
    /// A run that measured `error` with nothing wrong.
    pub fn ok(error: f64, detail: String) -> Outcome {
        Outcome {
            error,
            failure: None,
            detail,
        }
    }

    /// With this failure if `failed`.
    pub fn failed_if(mut self, failed: bool, failure: Failure) -> Outcome {
        if failed && self.failure.is_none() {
            self.failure = Some(failure);
        }
        self
    }
}

/// Steps simulations of one engine at one setting for a case, timing only
/// the steps, and watches every dynamic body for faults, non-finite state
/// and explosions (the first such failure is kept).
pub struct Runner {
    /// The engine.
    pub engine: Engine,
    /// The setting.
    pub settings: Settings,
    /// Wall time inside `step()`, summed over the run.
    pub busy: Duration,
    /// Simulated time stepped, s.
    pub simulated: f64,
    failure: Option<Failure>,
    dynamic: Vec<usize>,
    explode_speed: f64,
}

impl Runner {
    /// A runner with nothing stepped yet.
    pub fn new(engine: Engine, settings: Settings) -> Runner {
        Runner {
            engine,
            settings,
            busy: Duration::ZERO,
            simulated: 0.0,
            failure: None,
            dynamic: Vec::new(),
            explode_speed: f64::INFINITY,
        }
    }

    /// Steps at `tick_rate` instead of the settings' rate: for a sweep
    /// over the step length. Call before [`build`](Self::build).
    pub fn set_tick_rate(&mut self, tick_rate: u32) {
        self.settings.tick_rate = tick_rate;
    }

    /// The step length, s.
    pub fn dt(&self) -> f64 {
        1.0 / self.settings.tick_rate as f64
    }

    /// Steps in `seconds` of simulated time (rounded).
    pub fn ticks(&self, seconds: f64) -> usize {
        (seconds * self.settings.tick_rate as f64).round() as usize
    }

    /// Builds `spec` in this runner's engine (not timed) and watches its
    /// dynamic bodies.
    pub fn build(&mut self, spec: &Spec) -> Box<dyn Sim> {
        self.dynamic = (0..spec.bodies.len())
            .filter(|&i| !spec.bodies[i].fixed)
            .collect();
        self.explode_speed = spec.explode_speed;
        sim::build(self.engine, spec, self.settings)
    }

    /// One timed step, then the checks.
    pub fn step(&mut self, sim: &mut dyn Sim) {
        let start = Instant::now();
        sim.step();
        self.busy += start.elapsed();
        self.simulated += self.dt();
        if self.failure.is_some() {
            return;
        }
        if sim.faulted() {
            self.failure = Some(Failure::Faulted);
            return;
        }
        for &i in &self.dynamic {
            let st = sim.state(i);
            if !st.is_finite() {
                self.failure = Some(Failure::NonFinite);
                return;
            }
            if super::closed::norm(st.vel) > self.explode_speed {
                self.failure = Some(Failure::Exploded);
                return;
            }
        }
    }

    /// `n` timed steps.
    pub fn steps(&mut self, sim: &mut dyn Sim, n: usize) {
        for _ in 0..n {
            self.step(sim);
        }
    }

    /// The failure the generic checks found, if any.
    pub fn failure(&self) -> Option<Failure> {
        self.failure
    }

    /// CPU milliseconds per simulated second.
    pub fn ms_per_simulated_second(&self) -> f64 {
        self.busy.as_secs_f64() * 1e3 / self.simulated.max(f64::MIN_POSITIVE)
    }
}
