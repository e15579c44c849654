//! `engines --stages`: per scene, ms/step for each stage of our step beside
//! Rapier's own counters for its stages, grouped so the two compare (broad
//! phase, narrow phase, solver with integration, CCD, islands and sleep, the
//! rest), and callgrind's instruction counts per stage for ours.
//!
//! Our stages are timed through `World::step_observed`: the observer reads
//! the clock as each stage ends, so the core itself stays clock-free.
//! Rapier's figures are its `Counters` (the `profiler` feature, enabled only
//! for these runs). Both are extra runs after the headline ones, which stay
//! plain (no observer, counters off) and keep the headline ratio.

use std::fmt::Write as _;
use std::path::Path;
use std::time::{Duration, Instant};

use lockstep_core::world::{Stage, StepObserver};
use rapier3d::counters::Counters;

use crate::callgrind::{self, Counts, Skipped, Window};
use crate::engines::{Rapier, build_ours, sleep_off};
use crate::scenes::Scene;

/// Steps the callgrind window counts (full size; 2 with `--quick`).
pub const COUNT_STEPS: usize = 10;

/// The groups both engines' stages are summed into.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Group {
    /// Candidate pairs and keeping the proxies (boxes) up to date.
    BroadPhase,
    /// Contact manifolds for the candidates.
    NarrowPhase,
    /// Constraints, solve and relax, velocity and position integration.
    Solver,
    /// Continuous collision.
    Ccd,
    /// Islands, sleeping and waking.
    Islands,
    /// Everything else.
    Rest,
}

/// Every group, in table order.
pub const GROUPS: [Group; 6] = [
    Group::BroadPhase,
    Group::NarrowPhase,
    Group::Solver,
    Group::Ccd,
    Group::Islands,
    Group::Rest,
];

impl Group {
    fn label(self) -> &'static str {
        match self {
            Group::BroadPhase => "broad phase",
            Group::NarrowPhase => "narrow phase",
            Group::Solver => "solver (incl. integrate)",
            Group::Ccd => "CCD",
            Group::Islands => "islands & sleep",
            Group::Rest => "rest",
        }
    }

    fn key(self) -> &'static str {
        match self {
            Group::BroadPhase => "broad_phase",
            Group::NarrowPhase => "narrow_phase",
            Group::Solver => "solver",
            Group::Ccd => "ccd",
            Group::Islands => "islands_sleep",
            Group::Rest => "rest",
        }
    }

    fn index(self) -> usize {
        GROUPS
            .iter()
            .position(|&g| g == self)
            .unwrap_or(GROUPS.len() - 1)
    }
}

/// The group of one of our stages. A stage the core adds later lands in
/// `Rest` until it is placed here.
pub fn group_of(stage: Stage) -> Group {
    match stage {
        Stage::BroadPhase | Stage::SyncProxies => Group::BroadPhase,
        Stage::NarrowPhase => Group::NarrowPhase,
        Stage::PrepareContacts
        | Stage::IntegrateVelocities
        | Stage::WarmStart
        | Stage::Solve
        | Stage::IntegratePositions
        | Stage::Relax
        | Stage::Restitution
        | Stage::StoreImpulses
        | Stage::FinishVelocities => Group::Solver,
        Stage::CcdBegin | Stage::Ccd => Group::Ccd,
        Stage::WakeTouched | Stage::Sleep => Group::Islands,
        _ => Group::Rest,
    }
}

/// Reads the clock as each stage ends and adds the time since the previous
/// stage (or the step's start) to the stage that ended. Fixed arrays: it
/// does not allocate.
pub struct StageClock {
    last: Instant,
    spent: [Duration; Stage::ALL.len()],
}

impl StageClock {
    /// A clock with nothing spent yet.
    pub fn new() -> StageClock {
        StageClock {
            last: Instant::now(),
            spent: [Duration::ZERO; Stage::ALL.len()],
        }
    }

    /// Starts timing a step now.
    pub fn start_step(&mut self) {
        self.last = Instant::now();
    }

    /// Forgets what was spent so far (the first, cold step).
    pub fn reset(&mut self) {
        self.spent = [Duration::ZERO; Stage::ALL.len()];
    }

    /// Time spent per stage, [`Stage::ALL`] order.
    pub fn spent(&self) -> &[Duration; Stage::ALL.len()] {
        &self.spent
    }
}

impl Default for StageClock {
    fn default() -> StageClock {
        StageClock::new()
    }
}

impl StepObserver for StageClock {
    fn finished(&mut self, stage: Stage) {
        let now = Instant::now();
        self.spent[stage.index()] += now - self.last;
        self.last = now;
    }
}

/// One observed run of ours: ms/step per stage (first step excluded).
#[derive(Clone, Debug, PartialEq)]
pub struct OursRun {
    /// Per stage, [`Stage::ALL`] order, summed over the substeps.
    pub stage_ms: Vec<f64>,
    /// The whole observed step.
    pub total_ms: f64,
}

impl OursRun {
    /// The step's time outside every stage (after the last one).
    fn between_ms(&self) -> f64 {
        self.total_ms - self.stage_ms.iter().sum::<f64>()
    }

    fn group_ms(&self, g: Group) -> f64 {
        let stages: f64 = Stage::ALL
            .iter()
            .zip(&self.stage_ms)
            .filter(|(s, _)| group_of(**s) == g)
            .map(|(_, ms)| ms)
            .sum();
        stages
            + if g == Group::Rest {
                self.between_ms()
            } else {
                0.0
            }
    }
}

/// One run of Rapier with its counters on: ms/step per group (first step
/// excluded).
#[derive(Clone, Debug, PartialEq)]
pub struct RapierRun {
    /// Per group, [`GROUPS`] order; `Rest` is the step's wall time minus
    /// the others.
    pub group_ms: Vec<f64>,
    /// The step's wall time.
    pub total_ms: f64,
}

fn ms_per_step(d: Duration, steps: usize) -> f64 {
    d.as_secs_f64() * 1e3 / (steps.max(2) - 1) as f64
}

/// Steps ours with the stage clock.
fn run_ours(scene: &Scene) -> OursRun {
    let (mut world, _) = build_ours(scene, sleep_off());
    let mut clock = StageClock::new();
    let mut total = Duration::ZERO;
    for i in 0..scene.steps {
        let start = Instant::now();
        clock.start_step();
        world.step_observed(&mut clock);
        let spent = start.elapsed();
        if i == 0 {
            clock.reset();
        } else {
            total += spent;
        }
    }
    OursRun {
        stage_ms: clock
            .spent
            .iter()
            .map(|&d| ms_per_step(d, scene.steps))
            .collect(),
        total_ms: ms_per_step(total, scene.steps),
    }
}

/// Rapier's counters for one step, grouped, in ms (`Rest` left at 0).
fn rapier_groups(c: &Counters) -> [f64; GROUPS.len()] {
    let mut g = [0.0; GROUPS.len()];
    g[Group::BroadPhase.index()] =
        c.cd.broad_phase_time.time_ms() + c.cd.final_broad_phase_time.time_ms();
    g[Group::NarrowPhase.index()] = c.cd.narrow_phase_time.time_ms();
    g[Group::Solver.index()] = c.stages.solver_time.time_ms()
        + c.stages.update_time.time_ms()
        + c.stages.island_constraints_collection_time.time_ms();
    g[Group::Ccd.index()] = c.ccd.toi_computation_time.time_ms() + c.stages.ccd_time.time_ms();
    g[Group::Islands.index()] = c.stages.island_construction_time.time_ms();
    g
}

/// Steps Rapier with its counters on.
fn run_rapier(scene: &Scene) -> RapierRun {
    let mut sim = Rapier::new(scene);
    sim.world.physics_pipeline.counters.enable();
    let mut sums = [0.0; GROUPS.len()];
    let mut total = Duration::ZERO;
    for i in 0..scene.steps {
        let start = Instant::now();
        sim.world.step();
        let spent = start.elapsed();
        if i > 0 {
            total += spent;
            let g = rapier_groups(&sim.world.physics_pipeline.counters);
            for (s, v) in sums.iter_mut().zip(g) {
                *s += v;
            }
        }
    }
    let steps = (scene.steps.max(2) - 1) as f64;
    let total_ms = ms_per_step(total, scene.steps);
    let mut group_ms: Vec<f64> = sums.iter().map(|s| s / steps).collect();
    let known: f64 = group_ms.iter().sum();
    group_ms[Group::Rest.index()] = total_ms - known;
    RapierRun { group_ms, total_ms }
}

/// One scene's stage figures.
#[derive(Clone, Debug)]
pub struct StageResult {
    /// The scene's name.
    pub name: &'static str,
    /// Dynamic bodies.
    pub bodies: usize,
    /// Steps per run.
    pub steps: usize,
    /// Substeps per step (ours).
    pub substeps: u32,
    /// Our observed runs.
    pub ours: Vec<OursRun>,
    /// Rapier's runs with counters on.
    pub rapier: Vec<RapierRun>,
    /// The headline (plain, counters off) medians: ours, Rapier.
    pub headline_ms: (f64, f64),
    /// Our instruction counts, or why there are none.
    pub counts: Result<Counts, Skipped>,
}

/// Times the stages of both engines, `runs` runs each, alternating, then
/// counts ours under callgrind over `count_steps` steps (none if 0),
/// keeping the callgrind file in `keep` if given.
pub fn run_scene(
    scene: &Scene,
    runs: usize,
    headline_ms: (f64, f64),
    count_steps: usize,
    keep: Option<&Path>,
) -> StageResult {
    let mut ours = Vec::new();
    let mut rapier = Vec::new();
    for _ in 0..runs.max(1) {
        ours.push(run_ours(scene));
        rapier.push(run_rapier(scene));
    }
    let counts = if count_steps == 0 {
        Err(Skipped::Failed("not asked for".to_owned()))
    } else {
        callgrind::count(scene, Window::for_run(scene.steps, count_steps), keep)
    };
    StageResult {
        name: scene.name,
        bodies: scene.positions.len(),
        steps: scene.steps,
        substeps: crate::engines::SUBSTEPS,
        ours,
        rapier,
        headline_ms,
        counts,
    }
}

/// The median of some values (0 for none).
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => 0.0,
        _ if n % 2 == 1 => v[n / 2],
        _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// One line of a scene's stage table.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// The group (for a group line) or our stage's group.
    pub group: Group,
    /// Our stage's name, or `None` for a group line (or a total).
    pub stage: Option<&'static str>,
    /// Our ms/step (median over runs).
    pub ours_ms: f64,
    /// Rapier's ms/step (median over runs), on group lines and totals.
    pub rapier_ms: Option<f64>,
    /// Our instructions per step, if counted.
    pub ours_ir: Option<u64>,
}

/// The table's lines: each group, then its stages of ours; the step's time
/// outside the stages is the `Rest` group's `(between stages)` line.
pub fn rows(r: &StageResult) -> Vec<Row> {
    let counts = r.counts.as_ref().ok();
    let mut out = Vec::new();
    for g in GROUPS {
        let stage_ir = |st: &Stage| counts.map(|c| c.per_stage[st.index()]);
        let members: Vec<&Stage> = Stage::ALL.iter().filter(|s| group_of(**s) == g).collect();
        let between_ir = counts.map(|c| c.total.saturating_sub(c.per_stage.iter().sum()));
        let group_ir = counts.map(|_| {
            members.iter().filter_map(|s| stage_ir(s)).sum::<u64>()
                + if g == Group::Rest {
                    between_ir.unwrap_or(0)
                } else {
                    0
                }
        });
        out.push(Row {
            group: g,
            stage: None,
            ours_ms: median(r.ours.iter().map(|o| o.group_ms(g)).collect()),
            rapier_ms: Some(median(
                r.rapier.iter().map(|x| x.group_ms[g.index()]).collect(),
            )),
            ours_ir: group_ir,
        });
        for st in &members {
            out.push(Row {
                group: g,
                stage: Some(st.name()),
                ours_ms: median(r.ours.iter().map(|o| o.stage_ms[st.index()]).collect()),
                rapier_ms: None,
                ours_ir: stage_ir(st),
            });
        }
        if g == Group::Rest {
            out.push(Row {
                group: g,
                stage: Some("(between stages)"),
                ours_ms: median(r.ours.iter().map(OursRun::between_ms).collect()),
                rapier_ms: None,
                ours_ir: between_ir,
            });
        }
    }
    out
}

/// `1234567` as `1,234,567`.
fn grouped(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

fn ir_text(ir: Option<u64>) -> String {
    ir.map_or_else(String::new, grouped)
}

/// One scene's stage table, with how it was measured.
pub fn table(r: &StageResult) -> String {
    let mut out = String::new();
    let runs = r.ours.len();
    let _ = writeln!(
        out,
        "stages of {}: {} bodies, {} steps, runs per engine: {runs} (ms/step: median over the runs, first step excluded)",
        r.name, r.bodies, r.steps
    );
    let _ = writeln!(
        out,
        "{:<32} {:>9} {:>10} {:>7} {:>15}",
        "group / our stage", "ours ms", "rapier ms", "ratio", "ours Ir/step"
    );
    for row in rows(r) {
        match row.stage {
            None => {
                let rap = row.rapier_ms.unwrap_or(f64::NAN);
                let _ = writeln!(
                    out,
                    "{:<32} {:>9.3} {:>10.3} {:>7} {:>15}",
                    row.group.label(),
                    row.ours_ms,
                    rap,
                    ratio_text(row.ours_ms, rap),
                    ir_text(row.ours_ir)
                );
            }
            Some(name) => {
                let _ = writeln!(
                    out,
                    "  {:<30} {:>9.3} {:>10} {:>7} {:>15}",
                    name,
                    row.ours_ms,
                    "",
                    "",
                    ir_text(row.ours_ir)
                );
            }
        }
    }
    let ours_total = median(r.ours.iter().map(|o| o.total_ms).collect());
    let rapier_total = median(r.rapier.iter().map(|x| x.total_ms).collect());
    let total_ir = r.counts.as_ref().ok().map(|c| c.total);
    let _ = writeln!(
        out,
        "{:<32} {:>9.3} {:>10.3} {:>7} {:>15}",
        "total (observed / counters on)",
        ours_total,
        rapier_total,
        ratio_text(ours_total, rapier_total),
        ir_text(total_ir)
    );
    let (ho, hr) = r.headline_ms;
    let _ = writeln!(
        out,
        "{:<32} {:>9.3} {:>10.3} {:>7}",
        "headline (plain / counters off)",
        ho,
        hr,
        ratio_text(ho, hr)
    );
    let _ = writeln!(
        out,
        "(ours: a clock read as each stage ends, through World::step_observed; the {} substep stages \
         summed over the {} substeps; (between stages) = the step's time outside them. \
         Each figure is a median over the runs, so a column adds up only approximately.)",
        Stage::ALL.iter().filter(|s| s.per_substep()).count(),
        r.substeps
    );
    match &r.counts {
        Ok(c) => {
            let _ = writeln!(
                out,
                "(ours Ir/step: callgrind instructions, ours alone, mean over steps {}–{} of the run ({} steps): \
                 stepped natively to step {}, snapshot, then under valgrind --tool=callgrind step {} not counted \
                 (the first after a restore) and steps {}–{} counted; each stage's inclusive count of its \
                 stage_<name> function)",
                c.window.first,
                c.window.last,
                c.window.steps(),
                c.window.first - 2,
                c.window.first - 1,
                c.window.first,
                c.window.last
            );
        }
        Err(why) => {
            let _ = writeln!(out, "({why})");
        }
    }
    out
}

fn ratio_text(ours: f64, rapier: f64) -> String {
    if rapier > 0.0 && ours.is_finite() {
        format!("{:.2}", ours / rapier)
    } else {
        "-".to_owned()
    }
}

/// How Rapier's counters are grouped, printed once with the tables.
pub const RAPIER_MAPPING: &str = "rapier: its own Counters (rapier3d `profiler` feature; counters enabled only in these runs): \
broad phase = cd.broad_phase_time + cd.final_broad_phase_time; narrow phase = cd.narrow_phase_time; \
solver = stages.solver_time + stages.update_time (forces, final positions, collider poses and AABBs) \
+ stages.island_constraints_collection_time (solver contact graph upkeep); CCD = ccd.toi_computation_time; \
islands & sleep = stages.island_construction_time; rest = the step's wall time minus those \
(user changes, kinematic velocities, gaps). ours: broad phase = broad_phase + sync_proxies, \
CCD = ccd_begin + ccd, islands & sleep = wake_touched + sleep";

/// The header of the stage section of the CSV (it follows the headline
/// section after a blank line).
pub const CSV_HEADER: &str =
    "section,scene,engine,group,stage,runs,ms_per_step_median,instructions_per_step,counted_steps";

/// The stage figures as CSV lines (no header).
pub fn csv_lines(r: &StageResult) -> String {
    let mut out = String::new();
    let runs = r.ours.len();
    let window = r.counts.as_ref().map_or_else(
        |_| String::new(),
        |c| format!("{}-{}", c.window.first, c.window.last),
    );
    let ir = |v: Option<u64>| v.map_or_else(String::new, |v| v.to_string());
    for row in rows(r) {
        let stage = row.stage.unwrap_or("");
        let _ = writeln!(
            out,
            "engines-stages,{},lockstep,{},{stage},{runs},{:.4},{},{window}",
            r.name,
            row.group.key(),
            row.ours_ms,
            ir(row.ours_ir)
        );
        if let Some(ms) = row.rapier_ms {
            let _ = writeln!(
                out,
                "engines-stages,{},rapier3d,{},,{runs},{ms:.4},,",
                r.name,
                row.group.key()
            );
        }
    }
    let ours_total = median(r.ours.iter().map(|o| o.total_ms).collect());
    let rapier_total = median(r.rapier.iter().map(|x| x.total_ms).collect());
    let _ = writeln!(
        out,
        "engines-stages,{},lockstep,total,,{runs},{ours_total:.4},{},{window}",
        r.name,
        ir(r.counts.as_ref().ok().map(|c| c.total))
    );
    let _ = writeln!(
        out,
        "engines-stages,{},rapier3d,total,,{runs},{rapier_total:.4},,",
        r.name
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenes;

    /// Our run with stage `i` taking `(i + 1) * unit` ms and `extra` ms
    /// outside the stages.
    fn ours(unit: f64, extra: f64) -> OursRun {
        let stage_ms: Vec<f64> = (0..Stage::ALL.len())
            .map(|i| (i + 1) as f64 * unit)
            .collect();
        let total_ms = stage_ms.iter().sum::<f64>() + extra;
        OursRun { stage_ms, total_ms }
    }

    fn rapier(ms: [f64; 6]) -> RapierRun {
        RapierRun {
            group_ms: ms.to_vec(),
            total_ms: ms.iter().sum(),
        }
    }

    fn result(counts: Result<Counts, Skipped>) -> StageResult {
        StageResult {
            name: "large_pyramid",
            bodies: 6,
            steps: 3,
            substeps: 4,
            // Medians: the middle run of three.
            ours: vec![ours(1.0, 0.5), ours(3.0, 1.5), ours(2.0, 1.0)],
            rapier: vec![
                rapier([1.0, 2.0, 3.0, 0.0, 1.0, 0.5]),
                rapier([3.0, 4.0, 5.0, 0.0, 3.0, 1.5]),
                rapier([2.0, 3.0, 4.0, 0.0, 2.0, 1.0]),
            ],
            headline_ms: (100.0, 50.0),
            counts,
        }
    }

    fn ms_of(rows: &[Row], stage: Option<&str>, g: Group) -> f64 {
        rows.iter()
            .find(|r| r.stage == stage && r.group == g)
            .map(|r| r.ours_ms)
            .unwrap()
    }

    #[test]
    fn every_stage_is_in_one_group_and_the_groups_add_up_to_the_step() {
        let window = Window::for_run(3, 1);
        let counts = Counts {
            window,
            per_stage: (1..=20).map(|i| 10 * i).collect(),
            total: 2200,
        };
        let r = result(Ok(counts));
        let rows = rows(&r);
        // Every stage once, and the between-stages line.
        let stage_rows: Vec<&Row> = rows.iter().filter(|r| r.stage.is_some()).collect();
        assert_eq!(stage_rows.len(), Stage::ALL.len() + 1);
        for st in Stage::ALL {
            assert_eq!(
                stage_rows
                    .iter()
                    .filter(|r| r.stage == Some(st.name()))
                    .count(),
                1
            );
        }
        // The median run is the one with unit 2: stage i takes 2(i+1) ms.
        assert_eq!(ms_of(&rows, Some("solve"), Group::Solver), 20.0);
        assert_eq!(ms_of(&rows, Some("(between stages)"), Group::Rest), 1.0);
        // broad phase = broad_phase (index 2) + sync_proxies (index 19).
        assert_eq!(ms_of(&rows, None, Group::BroadPhase), 2.0 * (3.0 + 20.0));
        // Groups add up to the median total: 2·(1+…+20) + 1.
        let groups: f64 = rows
            .iter()
            .filter(|r| r.stage.is_none())
            .map(|r| r.ours_ms)
            .sum();
        assert!((groups - 421.0).abs() < 1e-9, "{groups}");
        // Instructions: each group is its stages; all groups are the total.
        for g in GROUPS {
            let of_stages: u64 = rows
                .iter()
                .filter(|r| r.group == g && r.stage.is_some())
                .filter_map(|r| r.ours_ir)
                .sum();
            let group = rows
                .iter()
                .find(|r| r.group == g && r.stage.is_none())
                .unwrap();
            assert_eq!(group.ours_ir, Some(of_stages), "{g:?}");
        }
        let ir_groups: u64 = rows
            .iter()
            .filter(|r| r.stage.is_none())
            .filter_map(|r| r.ours_ir)
            .sum();
        assert_eq!(ir_groups, 2200);
        // Rapier: the median per group.
        let rap = |g: Group| {
            rows.iter()
                .find(|r| r.group == g && r.stage.is_none())
                .unwrap()
        };
        assert_eq!(rap(Group::NarrowPhase).rapier_ms, Some(3.0));
        assert_eq!(rap(Group::Rest).rapier_ms, Some(1.0));

        let t = table(&r);
        let line = |start: &str| {
            t.lines()
                .find(|l| l.starts_with(start))
                .unwrap_or_else(|| panic!("no {start:?} line in\n{t}"))
                .split_whitespace()
                .map(str::to_owned)
                .collect::<Vec<_>>()
        };
        // narrow phase: ours 2·4 = 8 ms, Rapier 3 ms, ratio 2.67, 40 Ir.
        assert_eq!(line("narrow phase")[2..], ["8.000", "3.000", "2.67", "40"]);
        assert_eq!(line("  solve")[1..], ["20.000", "100"]);
        assert_eq!(line("headline")[5..], ["100.000", "50.000", "2.00"]);
        assert_eq!(line("total")[5..], ["421.000", "12.000", "35.08", "2,200"]);
        assert!(
            t.contains("mean over steps 3–3 of the run (1 steps)"),
            "{t}"
        );

        let c = csv_lines(&r);
        // A line per group and engine, per stage of ours, between, totals.
        assert_eq!(
            c.lines().count(),
            2 * GROUPS.len() + Stage::ALL.len() + 1 + 2
        );
        assert!(
            c.lines()
                .all(|l| l.split(',').count() == CSV_HEADER.split(',').count())
        );
        assert!(
            c.contains("engines-stages,large_pyramid,lockstep,solver,solve,3,20.0000,100,3-3\n"),
            "{c}"
        );
        assert!(c.contains("engines-stages,large_pyramid,rapier3d,narrow_phase,,3,3.0000,,\n"));
    }

    #[test]
    fn without_counts_the_table_says_why() {
        let r = result(Err(Skipped::NoValgrind));
        let t = table(&r);
        assert!(
            t.contains("(instruction counts skipped: valgrind is not installed)"),
            "{t}"
        );
        assert!(rows(&r).iter().all(|r| r.ours_ir.is_none()));
    }

    #[test]
    fn both_engines_report_their_stages_on_a_small_scene() {
        let scene = scenes::large_pyramid(3, 4);
        let r = run_scene(&scene, 1, (1.0, 1.0), 0, None);
        let (o, x) = (&r.ours[0], &r.rapier[0]);
        assert!(o.stage_ms.iter().all(|&ms| ms >= 0.0));
        let staged: f64 = o.stage_ms.iter().sum();
        assert!(staged > 0.0 && staged <= o.total_ms, "{o:?}");
        // The six boxes touch: the solver and the narrow phase work.
        assert!(o.stage_ms[Stage::Solve.index()] > 0.0, "{o:?}");
        assert!(o.stage_ms[Stage::NarrowPhase.index()] > 0.0, "{o:?}");
        // Rapier's counters run (the `profiler` feature is on): its solver
        // and narrow phase take time, and its groups fit in the step.
        assert!(x.group_ms[Group::Solver.index()] > 0.0, "{x:?}");
        assert!(x.group_ms[Group::NarrowPhase.index()] > 0.0, "{x:?}");
        let known: f64 = x.group_ms[..5].iter().sum();
        assert!(known <= x.total_ms, "{x:?}");
    }
}
