//! The `engines` suite: the performance scenes (docs/engines.md) built from one
//! recipe ([`crate::scenes`]) in lockstep-core and in Rapier, stepped
//! alternately (ours, Rapier, ours, Rapier, ...) in one process.
//!
//! Per scene it reports ms/step for both (median and minimum over the runs,
//! the first step of each run excluded: it builds the trees and the first
//! contacts), their ratio, the bodies, the contact points after the last
//! step, the heap high-water mark per body, and whether the pyramids still
//! stand (the largest displacement of any body from its start, and how far
//! each pyramid's top box moved vertically: standing = every top within
//! 1 cm).

use std::fmt::Write as _;
use std::sync::Arc;
use std::time::Instant;

use lockstep_core::SleepConfig;
use lockstep_core::shape::{ConvexHull, Cuboid, Shape, Sphere};
use lockstep_core::{
    BodyDesc, BodyHandle, ColliderDesc, CollisionFilter, ContactOrder, ContactRows, JointDesc,
    Material, Scalar, Vec3, World, WorldConfig,
};
use rapier3d::prelude::{
    ColliderBuilder, IntegrationParameters, InteractionGroups, PhysicsWorld, RigidBodyBuilder,
    RigidBodyHandle, SharedShape, SphericalJointBuilder, Vector,
};

use crate::scenes::{self, BodyShape, Scene};
use crate::{Options, SuiteOutput};
use crate::{alloc, harness, scene_file, stages};

/// Steps per second in both engines.
const TICK_RATE: u32 = 60;
/// Our substeps per step.
pub(crate) const SUBSTEPS: u32 = 4;

/// Rapier's settings, chosen to match our 4 substeps: in Rapier 0.36 each
/// "solver iteration" is a substep of its TGS-soft solver (integrate, one
/// PGS pass with bias, one relax pass without), like Box2D v3's soft step.
fn rapier_parameters() -> IntegrationParameters {
    rapier_parameters_for(TICK_RATE, SUBSTEPS)
}

/// Rapier's settings for a tick rate and a substep count: one Rapier solver
/// iteration per substep (see [`rapier_parameters`]).
pub(crate) fn rapier_parameters_for(tick_rate: u32, substeps: u32) -> IntegrationParameters {
    IntegrationParameters {
        dt: 1.0 / tick_rate.max(1) as f32,
        num_solver_iterations: substeps.max(1) as usize,
        num_internal_pgs_iterations: 1,
        num_internal_stabilization_iterations: 1,
        ..IntegrationParameters::default()
    }
}

/// The settings line printed with the table.
fn settings_text() -> String {
    let p = rapier_parameters();
    format!(
        "ours: lockstep-core (Q32.32), tick_rate {TICK_RATE}, substeps {SUBSTEPS} (1 solve + 1 relax pass each), \
         friction at each manifold's patch centre (2 tangent rows + twist), sleep off, contact margin 2 cm\n\
         rapier3d 0.36.1 (dim3, f32, enhanced-determinism, `parallel` on a pool of one thread; `--threads N`: also on N): dt 1/{TICK_RATE}, \
         num_solver_iterations {} (= substeps), num_internal_pgs_iterations {}, \
         num_internal_stabilization_iterations {}, warmstart_coefficient {}, contact_clustering {}, \
         contact_recycling {}, prediction distance {} m, CCD off, can_sleep(false)\n\
         both: gravity (0, -10, 0), friction 0.6, restitution 0; bodies = dynamic bodies (plus one static ground)\n\
         ragdolls: the scene file's own world (gravity -9.81, 60 Hz, 4 substeps), shapes, statics and joints in both; \
         Rapier's cone limits are +/- the cone about the frame's y and z axes (docs/engines.md)",
        p.num_solver_iterations,
        p.num_internal_pgs_iterations,
        p.num_internal_stabilization_iterations,
        p.warmstart_coefficient,
        p.contact_clustering,
        p.contact_recycling,
        p.normalized_prediction_distance * p.length_unit,
    )
}

/// The two engines behind one small interface.
trait Sim {
    fn step(&mut self);
    /// Contact points after the last step.
    fn contact_points(&self) -> usize;
    /// Positions of the dynamic bodies, in scene order.
    fn positions(&self) -> Vec<[f64; 3]>;
}

struct Ours {
    world: World,
    bodies: Vec<BodyHandle>,
    contact_points: usize,
    /// Batches the wide lanes took and batches their guard refused, summed
    /// over the steps.
    lanes: (u64, u64),
    /// Constraint-ticks, those on the narrow rows and those the guard
    /// moved to the Q32.32 rows, summed over the steps.
    rows_count: (u64, u64, u64),
    faulted: bool,
}

fn s(v: f64) -> Scalar {
    Scalar::from_f64_lossy(v)
}

fn v3(p: [f64; 3]) -> Vec3 {
    Vec3::new(s(p[0]), s(p[1]), s(p[2]))
}

/// Our world for a scene (sleep as given: off for `engines`), in pair
/// order.
pub fn build_ours(scene: &Scene, sleep: SleepConfig) -> (World, Vec<BodyHandle>) {
    build_ours_in(
        scene,
        sleep,
        ContactOrder::Pairs,
        WorldConfig::default().contact_rows,
    )
}

/// Our world for a scene with the contact solver's order given.
pub fn build_ours_in(
    scene: &Scene,
    sleep: SleepConfig,
    order: ContactOrder,
    rows: ContactRows,
) -> (World, Vec<BodyHandle>) {
    if let BodyShape::File(desc) = &scene.shape {
        return scene_file::build_ours(desc, sleep, order, rows);
    }
    let mut world = World::new(WorldConfig {
        gravity: Vec3::new(Scalar::ZERO, Scalar::from_int(-10), Scalar::ZERO),
        tick_rate: TICK_RATE,
        substeps: SUBSTEPS,
        sleep,
        contact_order: order,
        contact_rows: rows,
        ..WorldConfig::default()
    })
    .expect("valid world config");
    let material = Material::new(s(scene.friction), Scalar::ZERO);
    let ground = world
        .create_body(&BodyDesc::fixed().position(v3([0.0, scene.ground_y, 0.0])))
        .expect("ground body");
    world
        .add_collider(
            ground,
            ColliderDesc::new(Shape::Cuboid(Cuboid {
                half_extents: v3(scene.ground_half),
            }))
            .material(material),
        )
        .expect("ground collider");
    let shape = match &scene.shape {
        BodyShape::Cube(h) => Shape::Cuboid(Cuboid {
            half_extents: v3([*h; 3]),
        }),
        BodyShape::Hull(points) => {
            let pts: Vec<Vec3> = points.iter().map(|&p| v3(p)).collect();
            Shape::ConvexHull(Arc::new(
                ConvexHull::from_points(&pts).expect("hull of points on a sphere"),
            ))
        }
        BodyShape::Sphere(radius) => Shape::Sphere(Sphere::new(s(*radius)).expect("radius")),
        BodyShape::File(_) => unreachable!("built above"),
    };
    let filter = if scene.collide {
        CollisionFilter::default()
    } else {
        CollisionFilter {
            mask: 0,
            ..CollisionFilter::default()
        }
    };
    let bodies: Vec<BodyHandle> = scene
        .positions
        .iter()
        .enumerate()
        .map(|(i, &p)| {
            let desc = if scene.statics.binary_search(&i).is_ok() {
                BodyDesc::fixed()
            } else {
                BodyDesc::dynamic()
            };
            let b = world.create_body(&desc.position(v3(p))).expect("body");
            world
                .add_collider(
                    b,
                    ColliderDesc::new(shape.clone())
                        .density(s(scene.density))
                        .material(material)
                        .filter(filter),
                )
                .expect("collider");
            b
        })
        .collect();
    for &(a, b, at) in &scene.joints {
        let (pa, pb) = (v3(scene.positions[a]), v3(scene.positions[b]));
        world
            .add_joint(JointDesc::spherical(bodies[a], bodies[b]).anchors(v3(at) - pa, v3(at) - pb))
            .expect("joint");
    }
    (world, bodies)
}

/// Sleep off: the suite compares engines stepping every body (Rapier's
/// bodies are built with `can_sleep(false)`).
pub(crate) fn sleep_off() -> SleepConfig {
    SleepConfig {
        enabled: false,
        ..SleepConfig::default()
    }
}

impl Ours {
    fn new(scene: &Scene) -> Ours {
        Ours::in_order(scene, ContactOrder::Pairs, 1)
    }

    /// Ours in the given order with `workers` solver threads.
    fn in_order(scene: &Scene, order: ContactOrder, workers: usize) -> Ours {
        Ours::with(scene, order, workers, false)
    }

    /// [`Ours::in_order`] with the solver's wide lanes on (`wide`) or off.
    fn with(scene: &Scene, order: ContactOrder, workers: usize, wide: bool) -> Ours {
        Ours::with_rows(
            scene,
            order,
            workers,
            wide,
            WorldConfig::default().contact_rows,
        )
    }

    /// [`Ours::with`] with the contact rows' number format given.
    fn with_rows(
        scene: &Scene,
        order: ContactOrder,
        workers: usize,
        wide: bool,
        rows: ContactRows,
    ) -> Ours {
        let (mut world, bodies) = build_ours_in(scene, sleep_off(), order, rows);
        world.set_workers(workers);
        world.set_wide(wide);
        Ours {
            world,
            bodies,
            contact_points: 0,
            lanes: (0, 0),
            rows_count: (0, 0, 0),
            faulted: false,
        }
    }
}

impl Sim for Ours {
    fn step(&mut self) {
        let r = self.world.step();
        self.contact_points = r.contact_points as usize;
        self.lanes.0 += u64::from(r.wide_batches);
        self.lanes.1 += u64::from(r.wide_batches_guarded);
        self.rows_count.0 += u64::from(r.contact_constraints);
        self.rows_count.1 += u64::from(r.narrow_constraints);
        self.rows_count.2 += u64::from(r.narrow_fallbacks);
        self.faulted |= !r.faults.is_empty();
    }

    fn contact_points(&self) -> usize {
        self.contact_points
    }

    fn positions(&self) -> Vec<[f64; 3]> {
        self.bodies
            .iter()
            .map(|&h| {
                let p = self.world.body(h).expect("live body").position();
                [p.x.to_f64(), p.y.to_f64(), p.z.to_f64()]
            })
            .collect()
    }
}

/// A scene in Rapier.
pub(crate) struct Rapier {
    /// The whole Rapier world (its counters are `physics_pipeline.counters`).
    pub(crate) world: PhysicsWorld,
    bodies: Vec<RigidBodyHandle>,
}

/// The `f32` Rapier gets for a scene value: the value rounded to Q32.32
/// first, so both engines start from the same numbers.
fn r(v: f64) -> f32 {
    s(v).to_f64() as f32
}

fn rv(p: [f64; 3]) -> Vector {
    Vector::new(r(p[0]), r(p[1]), r(p[2]))
}

/// Runs `f` on the one thread of a rayon pool of its own, so that Rapier
/// (built with `parallel`) steps on one thread: called from a pool's
/// thread, Rapier's parallel loops split over that pool, and from outside
/// any pool over rayon's global pool (one thread per core).
pub fn on_one_thread<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    match rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .thread_name(|_| "bench".to_string())
        // The main thread's size: scene building and the suites recurse as
        // they would there.
        .stack_size(8 << 20)
        .build()
    {
        Ok(pool) => pool.install(f),
        Err(e) => panic!("cannot start the bench's one-thread pool: {e}"),
    }
}

impl Rapier {
    /// The scene built in Rapier with the suite's settings, stepping on the
    /// calling thread's pool (see [`on_one_thread`]).
    pub(crate) fn new(scene: &Scene) -> Rapier {
        if let BodyShape::File(desc) = &scene.shape {
            let (world, bodies) = scene_file::build_rapier(desc);
            return Rapier { world, bodies };
        }
        let mut world = PhysicsWorld {
            gravity: Vector::new(0.0, -10.0, 0.0),
            integration_parameters: rapier_parameters(),
            ..PhysicsWorld::default()
        };
        let [gx, gy, gz] = scene.ground_half;
        world.insert(
            RigidBodyBuilder::fixed().translation(rv([0.0, scene.ground_y, 0.0])),
            ColliderBuilder::cuboid(r(gx), r(gy), r(gz))
                .friction(r(scene.friction))
                .restitution(0.0),
        );
        let shape = match &scene.shape {
            BodyShape::Cube(h) => SharedShape::cuboid(r(*h), r(*h), r(*h)),
            BodyShape::Hull(points) => {
                let pts: Vec<Vector> = points.iter().map(|&p| rv(p)).collect();
                SharedShape::convex_hull(&pts).expect("hull of points on a sphere")
            }
            BodyShape::Sphere(radius) => SharedShape::ball(r(*radius)),
            BodyShape::File(_) => unreachable!("built above"),
        };
        let groups = if scene.collide {
            InteractionGroups::all()
        } else {
            InteractionGroups::none()
        };
        let bodies: Vec<RigidBodyHandle> = scene
            .positions
            .iter()
            .enumerate()
            .map(|(i, &p)| {
                let builder = if scene.statics.binary_search(&i).is_ok() {
                    RigidBodyBuilder::fixed()
                } else {
                    RigidBodyBuilder::dynamic()
                };
                world
                    .insert(
                        builder.translation(rv(p)).can_sleep(false),
                        ColliderBuilder::new(shape.clone())
                            .density(r(scene.density))
                            .friction(r(scene.friction))
                            .restitution(0.0)
                            .collision_groups(groups),
                    )
                    .0
            })
            .collect();
        for &(a, b, at) in &scene.joints {
            let (pa, pb) = (scene.positions[a], scene.positions[b]);
            let rel = |p: [f64; 3]| rv([at[0] - p[0], at[1] - p[1], at[2] - p[2]]);
            world.insert_impulse_joint(
                bodies[a],
                bodies[b],
                SphericalJointBuilder::new()
                    .local_anchor1(rel(pa))
                    .local_anchor2(rel(pb)),
            );
        }
        Rapier { world, bodies }
    }

    /// The scene in Rapier stepping on a pool of its own with `threads`
    /// threads (Rapier's `parallel` build: its narrow phase, body updates
    /// and coloured solver split over them).
    fn on_threads(scene: &Scene, threads: usize) -> Rapier {
        let mut rapier = Rapier::new(scene);
        if let Err(e) = rapier.world.physics_pipeline.configure_thread_pool(threads) {
            panic!("cannot start Rapier's pool of {threads} threads: {e}");
        }
        rapier
    }
}

impl Sim for Rapier {
    fn step(&mut self) {
        self.world.step();
    }

    /// The contact points its solver sees (after contact clustering).
    fn contact_points(&self) -> usize {
        self.world
            .narrow_phase
            .contact_pairs()
            .map(|pair| {
                pair.solver_manifolds()
                    .iter()
                    .map(|m| m.data.solver_contacts.len())
                    .sum::<usize>()
            })
            .sum()
    }

    fn positions(&self) -> Vec<[f64; 3]> {
        self.bodies
            .iter()
            .map(|&h| {
                let t = self.world.bodies[h].translation();
                [t.x as f64, t.y as f64, t.z as f64]
            })
            .collect()
    }
}

/// What one run of one engine measured.
#[derive(Clone, Debug)]
struct Run {
    ms_per_step: f64,
    contact_points: usize,
    peak_bytes: usize,
    max_displacement: f64,
    max_horizontal: f64,
    top_dy: f64,
    /// The pile's shape at each quarter of the run (see [`Settle`]).
    settle: [Settle; 4],
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

fn settle_of(positions: &[[f64; 3]]) -> Settle {
    let mut ys: Vec<f64> = positions.iter().map(|p| p[1]).collect();
    ys.sort_by(f64::total_cmp);
    Settle {
        median_y: ys.get(ys.len() / 2).copied().unwrap_or(f64::NAN),
        on_ground: ys.iter().filter(|&&y| y > -1.0).count(),
    }
}

fn measure<S: Sim>(scene: &Scene, build: impl FnOnce(&Scene) -> S) -> (Run, S) {
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
fn median_min(runs: &[Run]) -> (f64, f64) {
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
    fn from_runs(runs: &[Run], has_tops: bool, faulted: bool) -> EngineResult {
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

/// Whether two lists of positions are the same to the bit.
fn same_bits(a: &[[f64; 3]], b: &[[f64; 3]]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(p, q)| (0..3).all(|i| p[i].to_bits() == q[i].to_bits()))
}

/// The scenes by name, at full or quick size.
pub(crate) fn scene_list(quick: bool) -> Vec<(&'static str, Option<Scene>)> {
    if quick {
        vec![
            ("large_pyramid", Some(scenes::large_pyramid(10, 5))),
            ("many_pyramids", Some(scenes::many_pyramids(2, 4, 10.0, 5))),
            ("joint_grid", Some(scenes::joint_grid(4, 5))),
            ("convex_pile", Some(scenes::convex_pile(2, 2, 2, 5))),
            ("jolt_pyramid", Some(scenes::jolt_pyramid(4, 5))),
            (
                "ragdolls",
                Some(scenes::from_file(
                    "ragdolls",
                    &scenes::ragdolls_toml(2, 1),
                    5,
                )),
            ),
        ]
    } else {
        vec![
            ("large_pyramid", Some(scenes::large_pyramid(100, 200))),
            (
                "many_pyramids",
                Some(scenes::many_pyramids(14, 10, 77.0, 100)),
            ),
            ("joint_grid", Some(scenes::joint_grid(100, 100))),
            ("convex_pile", Some(scenes::convex_pile(8, 8, 80, 500))),
            ("jolt_pyramid", Some(scenes::jolt_pyramid(15, 500))),
            (
                "ragdolls",
                Some(scenes::from_file(
                    "ragdolls",
                    include_str!("../../scenes/ragdolls_100.toml"),
                    RAGDOLL_STEPS,
                )),
            ),
        ]
    }
}

/// The scene names the suite knows, for `--scenes` checking.
pub const SCENE_NAMES: &[&str] = &[
    "large_pyramid",
    "many_pyramids",
    "joint_grid",
    "convex_pile",
    "jolt_pyramid",
    "ragdolls",
];

/// Steps of the ragdoll scene: 10 s, time for the 100 ragdolls to tumble
/// down the stairs and come to rest.
const RAGDOLL_STEPS: usize = 600;

fn kib_per_body(bytes: usize, bodies: usize) -> f64 {
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
fn trip_range(ns: &[f64]) -> String {
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

/// Runs the suite (with `--stages`, the stage tables after the headline
/// ones; the headline runs are the same either way).
pub fn run(opts: &Options) -> SuiteOutput {
    let runs = opts.runs.unwrap_or(if opts.quick { 1 } else { 3 });
    let mut results = Vec::new();
    let mut staged = Vec::new();
    let mut skipped = Vec::new();
    for (name, scene) in scene_list(opts.quick) {
        if let Some(filter) = &opts.scenes
            && !filter.iter().any(|f| f == name)
        {
            continue;
        }
        match scene {
            None => skipped.push(name),
            Some(mut scene) => {
                if let Some(steps) = opts.steps {
                    scene.steps = steps.max(2);
                }
                eprintln!(
                    "engines: {name} ({} bodies, {} steps, {runs} runs per engine)...",
                    scene.positions.len(),
                    scene.steps
                );
                let result = run_scene(&scene, runs, opts.threads, opts.wide);
                if opts.stages {
                    eprintln!("engines --stages: {name}: stage runs, then instruction counts...");
                    let headline = (result.ours.median_ms, result.rapier.median_ms);
                    let count_steps = if opts.quick { 2 } else { stages::COUNT_STEPS };
                    staged.push(stages::run_scene(
                        &scene,
                        runs,
                        headline,
                        count_steps,
                        opts.callgrind_dir.as_deref(),
                    ));
                }
                results.push(result);
            }
        }
    }
    let mut text = format!("{}\n\n", settings_text());
    text.push_str(&table(&results, &skipped));
    text.push_str(&rows_table(&results));
    text.push_str(&threads_table(&results));
    let mut csv = csv(&results);
    if opts.stages {
        let _ = writeln!(text, "\n{}\n", stages::RAPIER_MAPPING);
        let _ = writeln!(csv, "\n{}", stages::CSV_HEADER);
        for r in &staged {
            let _ = writeln!(text, "{}", stages::table(r));
            csv.push_str(&stages::csv_lines(r));
        }
    }
    SuiteOutput { text, csv }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scene_file_builds_the_same_bodies_and_joints_in_both_engines() {
        let scene = scenes::from_file("ragdolls", &scenes::ragdolls_toml(2, 1), 1);
        let mut ours = Ours::new(&scene);
        let mut theirs = Rapier::new(&scene);
        assert_eq!(scene.positions.len(), 22);
        assert_eq!(ours.positions(), scene.positions);
        let apart = theirs
            .positions()
            .iter()
            .zip(&scene.positions)
            .map(|(a, b)| (0..3).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max))
            .fold(0.0, f64::max);
        assert!(apart < 1e-6, "Rapier's bodies are {apart} m off");
        assert_eq!(ours.world.joint_count(), 20);
        assert_eq!(theirs.world.impulse_joints.len(), 20);
        // 9 steps + floor + 22 capsules in each.
        assert_eq!(theirs.world.colliders.len(), 32);
        let mass = |i: usize| {
            let m = ours.world.body(ours.bodies[i]).unwrap().mass().to_f64();
            let rm = theirs.world.bodies[theirs.bodies[i]].mass() as f64;
            (m, rm)
        };
        for i in 0..22 {
            let (m, rm) = mass(i);
            assert!((m - rm).abs() < 1e-4 * m, "body {i}: {m} kg against {rm}");
        }
        // Both tumble down the stairs without flying apart.
        for _ in 0..120 {
            ours.step();
            theirs.step();
        }
        assert!(!ours.faulted);
        for p in ours.positions().iter().chain(&theirs.positions()) {
            assert!(p[1] < 2.5 && p[1] > -6.0 && p[0].abs() < 6.0, "{p:?}");
        }
    }

    #[test]
    fn both_engines_build_the_same_bodies_at_the_same_places() {
        let scene = scenes::jolt_pyramid(3, 1);
        let ours = Ours::new(&scene);
        let theirs = Rapier::new(&scene);
        assert_eq!(ours.positions(), scene.positions);
        assert_eq!(theirs.positions(), scene.positions);
        // Same mass: density 1000 × 8 m³.
        let m = ours.world.body(ours.bodies[0]).unwrap().mass().to_f64();
        let rm = theirs.world.bodies[theirs.bodies[0]].mass() as f64;
        assert!(
            (m - 8000.0).abs() < 1e-6 && (rm - 8000.0).abs() < 1e-2,
            "{m} {rm}"
        );
    }

    #[test]
    fn threads_runs_each_order_on_one_and_n_workers_to_the_same_positions() {
        let scene = scenes::large_pyramid(6, 20);
        let r = run_scene(&scene, 1, Some(3), false);
        let t = r.threaded.as_ref().expect("threaded runs");
        assert_eq!(t.workers, 3);
        for e in [&t.pairs_many, &t.one, &t.many, &t.rapier_many] {
            assert!(e.median_ms > 0.0 && !e.faulted);
        }
        // Rapier on 3 threads simulated the same scene: its pyramid stands
        // as on one thread.
        assert!(r.rapier.top_dy < 0.01 && t.rapier_many.top_dy < 0.01);
        // The same bits on 1 and 3 workers, so the same end positions.
        assert_eq!(
            t.one.max_displacement.to_bits(),
            t.many.max_displacement.to_bits()
        );
        assert_eq!(t.one.top_dy.to_bits(), t.many.top_dy.to_bits());
        assert_eq!(
            r.ours.max_displacement.to_bits(),
            t.pairs_many.max_displacement.to_bits()
        );
        assert_eq!(r.ours.top_dy.to_bits(), t.pairs_many.top_dy.to_bits());
        let table = threads_table(&[r]);
        assert!(table.contains("large_pyramid    3"), "{table}");
        assert!(table.contains("colours N"), "{table}");
        assert!(table.contains("rapier N"), "{table}");
    }

    #[test]
    fn a_quick_scene_runs_in_both_engines_and_reports_every_column() {
        let scene = scenes::large_pyramid(3, 3);
        let r = run_scene(&scene, 1, None, false);
        assert_eq!((r.bodies, r.steps, r.runs), (6, 3, 1));
        assert!(r.threaded.is_none() && threads_table(std::slice::from_ref(&r)).is_empty());
        for e in [&r.ours, &r.rapier] {
            assert!(e.median_ms > 0.0 && e.min_ms <= e.median_ms);
            assert!(e.peak_bytes > 0);
            assert!(e.max_displacement.is_finite() && e.top_dy.is_finite());
            assert!(e.max_horizontal <= e.max_displacement);
            // Six boxes, all still on the ground, the median one at least
            // one box above the lowest layer's centre.
            for q in &e.settle {
                assert_eq!(q.on_ground, 6);
                assert!(q.median_y > 0.5 && q.median_y < 10.0, "{q:?}");
            }
        }
        // Rapier resolves the resting contacts: the 6 boxes touch.
        assert!(r.rapier.contact_points >= 4, "{}", r.rapier.contact_points);
        let c = csv(&[r]);
        assert_eq!(c.lines().count(), 3);
        assert!(
            c.lines()
                .nth(1)
                .unwrap()
                .starts_with("engines,large_pyramid,lockstep,6,3,1,")
        );
    }

    #[test]
    fn median_of_even_and_odd_counts() {
        let run = |ms| Run {
            ms_per_step: ms,
            contact_points: 0,
            peak_bytes: 0,
            max_displacement: 0.0,
            max_horizontal: 0.0,
            top_dy: 0.0,
            settle: [Settle::default(); 4],
        };
        assert_eq!(median_min(&[run(3.0), run(1.0), run(2.0)]), (2.0, 1.0));
        assert_eq!(median_min(&[run(4.0), run(1.0)]), (2.5, 1.0));
    }
}
