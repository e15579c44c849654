//! Instruction counts per stage of our step, from callgrind: exact and the
//! same on every run of the same binary, unlike times on a shared machine.
//!
//! Valgrind cannot attach part-way through a run, and a whole scene under
//! callgrind takes far too long, so the bench steps the scene natively to
//! the middle of its run, writes a snapshot, and runs itself under
//! `valgrind --tool=callgrind` on that snapshot. The child restores it,
//! takes one step that is not counted (the first step after a restore
//! grows the scratch buffers and re-syncs every proxy), then steps the
//! counted window inside [`callgrind_counted_steps`], the only function for
//! which collection is on (`--collect-atstart=no --toggle-collect`). The
//! child prints its state hash after the window and the parent checks it
//! against its own native run of the same steps, so the counted steps are
//! the scene's own.
//!
//! Each stage runs in a core function named `stage_<name>` (see
//! `lockstep_core::world::Stage`); a stage's count is that function's
//! inclusive count over the window, divided by the window's steps.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use lockstep_core::World;
use lockstep_core::world::Stage;

use crate::engines::{build_ours, sleep_off};
use crate::scenes::Scene;

/// The window function's name, for `--toggle-collect`.
const WINDOW_FN: &str = "callgrind_counted_steps";

/// Steps the counted window. Callgrind collects only while this runs.
#[inline(never)]
pub fn callgrind_counted_steps(world: &mut World, steps: usize) {
    for _ in 0..steps {
        std::hint::black_box(world.step());
    }
}

/// Which steps were counted: `first..=last` of the scene's run (1-based, as
/// `StepReport::tick`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    /// The first counted step.
    pub first: u64,
    /// The last counted step.
    pub last: u64,
}

impl Window {
    /// The window for a run of `steps` steps: `count` steps starting two
    /// after the middle (the step after the restore is not counted).
    pub fn for_run(steps: usize, count: usize) -> Window {
        let restore_at = (steps / 2).max(1) as u64;
        Window {
            first: restore_at + 2,
            last: restore_at + 1 + count.max(1) as u64,
        }
    }

    /// The tick of the snapshot the child starts from.
    fn restore_at(self) -> u64 {
        self.first - 2
    }

    /// Steps counted.
    pub fn steps(self) -> u64 {
        self.last - self.first + 1
    }
}

/// Our instruction counts for one scene.
#[derive(Clone, Debug)]
pub struct Counts {
    /// The counted steps.
    pub window: Window,
    /// Instructions per step in each stage ([`Stage::ALL`] order), summed
    /// over the substeps.
    pub per_stage: Vec<u64>,
    /// Instructions per step in the whole window function (the steps and
    /// the step's bookkeeping between stages).
    pub total: u64,
}

/// Why there are no counts.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Skipped {
    /// `valgrind` could not be run.
    NoValgrind,
    /// It ran but something went wrong (the message says what).
    Failed(String),
}

impl std::fmt::Display for Skipped {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Skipped::NoValgrind => {
                write!(f, "instruction counts skipped: valgrind is not installed")
            }
            Skipped::Failed(why) => write!(f, "instruction counts failed: {why}"),
        }
    }
}

/// Whether `valgrind` runs here.
pub fn valgrind_available() -> bool {
    Command::new("valgrind")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Steps our engine natively to the window, then counts the window under
/// callgrind in a child process of this binary. The callgrind out file is
/// kept as `keep/SCENE.callgrind` if `keep` is given (for
/// `callgrind_annotate`), else removed.
pub fn count(scene: &Scene, window: Window, keep: Option<&Path>) -> Result<Counts, Skipped> {
    if !valgrind_available() {
        return Err(Skipped::NoValgrind);
    }
    let (mut world, _) = build_ours(scene, sleep_off());
    for _ in 0..window.restore_at() {
        world.step();
    }
    let dir = std::env::temp_dir();
    let tag = format!("lockstep-bench-{}-{}", std::process::id(), scene.name);
    let snapshot = dir.join(format!("{tag}.snapshot"));
    let out = match keep {
        Some(k) => {
            std::fs::create_dir_all(k)
                .map_err(|e| Skipped::Failed(format!("cannot create {}: {e}", k.display())))?;
            k.join(format!("{}.callgrind", scene.name))
        }
        None => dir.join(format!("{tag}.callgrind")),
    };
    let result = run_child(&mut world, window, &snapshot, &out);
    let _ = std::fs::remove_file(&snapshot);
    if keep.is_none() {
        let _ = std::fs::remove_file(&out);
    }
    result
}

fn run_child(
    world: &mut World,
    window: Window,
    snapshot: &Path,
    out: &Path,
) -> Result<Counts, Skipped> {
    let fail = |why: String| Skipped::Failed(why);
    std::fs::write(snapshot, world.snapshot())
        .map_err(|e| fail(format!("cannot write {}: {e}", snapshot.display())))?;
    let exe = std::env::current_exe().map_err(|e| fail(format!("own path: {e}")))?;
    let output = Command::new("valgrind")
        .arg("--tool=callgrind")
        .arg(format!("--callgrind-out-file={}", out.display()))
        .arg("--collect-atstart=no")
        .arg(format!("--toggle-collect=*{WINDOW_FN}"))
        .arg(&exe)
        .arg("engines")
        .arg("--count-snapshot")
        .arg(snapshot)
        .arg("--steps")
        .arg(window.steps().to_string())
        .output()
        .map_err(|e| fail(format!("cannot run valgrind: {e}")))?;
    let stdout = String::from_utf8_lossy(&output.stdout);
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr);
        let tail: Vec<&str> = stderr.lines().rev().take(5).collect();
        return Err(fail(format!(
            "valgrind exited with {}: {}",
            output.status,
            tail.into_iter().rev().collect::<Vec<_>>().join(" / ")
        )));
    }
    // The same steps natively: the child's hash must match.
    for _ in 0..window.steps() + 1 {
        world.step();
    }
    let want = hash_line(world);
    if !stdout.lines().any(|l| l == want) {
        return Err(fail(format!(
            "the counted run ended elsewhere than the native one (child said {:?}, expected {want:?})",
            stdout.trim()
        )));
    }
    let text =
        std::fs::read(out).map_err(|e| fail(format!("cannot read {}: {e}", out.display())))?;
    let inclusive = inclusive_counts(&String::from_utf8_lossy(&text)).map_err(fail)?;
    counts_from(&inclusive, window)
}

/// The line the child prints after the window and the parent expects.
fn hash_line(world: &World) -> String {
    format!("tick {} hash {:016x}", world.tick(), world.state_hash())
}

/// Per-stage figures from the inclusive counts of every function.
fn counts_from(inclusive: &BTreeMap<String, u64>, window: Window) -> Result<Counts, Skipped> {
    let n = window.steps();
    let find = |suffix: &str| -> Option<u64> {
        let hits: Vec<u64> = inclusive
            .iter()
            .filter(|(name, _)| name.starts_with("lockstep_") && name.ends_with(suffix))
            .map(|(_, &c)| c)
            .collect();
        (!hits.is_empty()).then(|| hits.iter().sum())
    };
    let total = find(&format!("::{WINDOW_FN}"))
        .ok_or_else(|| Skipped::Failed(format!("no {WINDOW_FN} in the profile")))?;
    let mut per_stage = Vec::with_capacity(Stage::ALL.len());
    let mut missing = Vec::new();
    for st in Stage::ALL {
        match find(&format!("::stage_{}", st.name())) {
            Some(c) => per_stage.push(c / n),
            None => {
                missing.push(st.name());
                per_stage.push(0);
            }
        }
    }
    if !missing.is_empty() {
        return Err(Skipped::Failed(format!(
            "no stage_ function in the profile for: {}",
            missing.join(", ")
        )));
    }
    Ok(Counts {
        window,
        per_stage,
        total: total / n,
    })
}

/// The child: restore, one uncounted step, the counted window, the hash.
pub fn child(snapshot: &PathBuf, steps: usize) -> Result<String, String> {
    let bytes =
        std::fs::read(snapshot).map_err(|e| format!("cannot read {}: {e}", snapshot.display()))?;
    let mut world = World::restore(&bytes).map_err(|e| e.to_string())?;
    world.step();
    callgrind_counted_steps(&mut world, steps);
    Ok(hash_line(&world))
}

/// The inclusive instruction count (`Ir`) of every function in a callgrind
/// out file: its own cost lines plus the cost of the calls it made.
///
/// The format: `fn=(id) name` starts a function's block (later `fn=(id)`
/// alone), `cfn=` names a callee, a `calls=` line says the next cost line
/// is the inclusive cost of a call made from the current function; other
/// cost lines are the function's own. A cost line is the positions (as
/// many as the `positions:` header names) then the events in the order of
/// the `events:` header. Names must be compressed (`(id)`), as callgrind
/// writes them by default.
pub fn inclusive_counts(text: &str) -> Result<BTreeMap<String, u64>, String> {
    let mut positions = 1;
    let mut ir_column = None;
    let mut names: BTreeMap<u64, String> = BTreeMap::new();
    let mut by_id: BTreeMap<u64, u64> = BTreeMap::new();
    let mut current: Option<u64> = None;
    for line in text.lines() {
        if let Some(p) = line.strip_prefix("positions:") {
            positions = p.split_whitespace().count();
            continue;
        }
        if let Some(e) = line.strip_prefix("events:") {
            ir_column = e.split_whitespace().position(|ev| ev == "Ir");
            continue;
        }
        if let Some(rest) = line.strip_prefix("fn=") {
            current = Some(name_id(rest, &mut names)?);
            continue;
        }
        if let Some(rest) = line.strip_prefix("cfn=") {
            name_id(rest, &mut names)?;
            continue;
        }
        let first = line.chars().next();
        let is_cost = first.is_some_and(|c| c.is_ascii_digit() || matches!(c, '+' | '-' | '*'));
        if !is_cost {
            continue;
        }
        let Some(col) = ir_column else {
            return Err("callgrind file has no Ir event".to_owned());
        };
        let ir: u64 = line
            .split_whitespace()
            .nth(positions + col)
            .map_or(Ok(0), str::parse)
            .map_err(|e| format!("bad cost line {line:?}: {e}"))?;
        // The function's own cost lines and the inclusive costs of the
        // calls it made (the line after a `calls=` line) both count.
        if let Some(f) = current {
            *by_id.entry(f).or_default() += ir;
        }
    }
    Ok(by_id
        .into_iter()
        .map(|(id, c)| (names.get(&id).cloned().unwrap_or_default(), c))
        .fold(BTreeMap::new(), |mut m, (name, c)| {
            *m.entry(name).or_default() += c;
            m
        }))
}

/// The id of `(id) name` or `(id)`, recording the name.
fn name_id(spec: &str, names: &mut BTreeMap<u64, String>) -> Result<u64, String> {
    let spec = spec.trim();
    let rest = spec
        .strip_prefix('(')
        .ok_or_else(|| format!("uncompressed name {spec:?}"))?;
    let (id, name) = rest
        .split_once(')')
        .ok_or_else(|| format!("bad name {spec:?}"))?;
    let id: u64 = id.parse().map_err(|e| format!("bad id in {spec:?}: {e}"))?;
    let name = name.trim();
    if !name.is_empty() {
        names.insert(id, name.to_owned());
    }
    Ok(id)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `main` calls `f` twice (inclusive 100 + 40), `f` costs 30 itself
    /// and calls `g` (70); `g` costs 70 + 40 itself (two blocks); the
    /// names are compressed, positions relative.
    const SAMPLE: &str = "# callgrind format
version: 1
positions: instr line
events: Ir Dr
summary: 180

fl=(1) main.rs
fn=(1) app::main
0x10 3 10 5
calls=1 0x20 7
+4 +1 100 9
calls=1 0x20 7
* * 40 1
fn=(2) lib::f
0x20 7 30 0
cfl=(1)
cfn=(3) lib::g
calls=1 0x30 9
+2 -1 70 2
fn=(3)
0x30 9 70 0
fn=(3)
-4 * 40 1
";

    #[test]
    fn inclusive_counts_add_own_costs_and_calls() {
        let inc = inclusive_counts(SAMPLE).unwrap();
        assert_eq!(inc["app::main"], 10 + 100 + 40);
        assert_eq!(inc["lib::f"], 30 + 70);
        assert_eq!(inc["lib::g"], 70 + 40);
        // `Ir` is found by the `events:` header, not assumed first.
        let swapped = SAMPLE.replace("events: Ir Dr", "events: Dr Ir");
        let inc = inclusive_counts(&swapped).unwrap();
        assert_eq!(inc["app::main"], 5 + 9 + 1);
        assert!(inclusive_counts("fn=lib::f\n1 2\n").is_err());
    }

    #[test]
    fn the_window_starts_two_steps_after_the_middle() {
        let w = Window::for_run(200, 10);
        assert_eq!(
            (w.restore_at(), w.first, w.last, w.steps()),
            (100, 102, 111, 10)
        );
        let w = Window::for_run(5, 2);
        assert_eq!((w.restore_at(), w.first, w.last), (2, 4, 5));
        // Even a two-step run has a window (past its end).
        assert_eq!(Window::for_run(2, 0).steps(), 1);
    }

    #[test]
    fn stage_counts_are_per_step_and_a_missing_stage_is_an_error() {
        let window = Window::for_run(20, 2);
        let mut inc = BTreeMap::new();
        inc.insert(format!("lockstep_bench::callgrind::{WINDOW_FN}"), 2 * 1000);
        for (i, st) in Stage::ALL.iter().enumerate() {
            let name = format!("lockstep_core::world::step::stage_{}", st.name());
            inc.insert(name.clone(), 2 * (i as u64 + 1));
            // A closure inside a stage is not the stage.
            inc.insert(format!("{name}::{{{{closure}}}}"), 999);
        }
        let c = counts_from(&inc, window).unwrap();
        assert_eq!(c.total, 1000);
        assert_eq!(c.per_stage, (1..=20).collect::<Vec<u64>>());
        inc.remove("lockstep_core::world::step::stage_relax");
        let err = counts_from(&inc, window).unwrap_err();
        assert_eq!(
            err,
            Skipped::Failed("no stage_ function in the profile for: relax".to_owned())
        );
    }
}
