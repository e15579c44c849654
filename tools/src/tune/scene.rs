//! One scene at many settings: building it, running it, timing it, and the
//! trajectory error between two runs.

use std::path::Path;
use std::time::Instant;

use lockstep_core::scene::{SceneDesc, build_world_with_config, parse_scene};
use lockstep_core::{BodyHandle, BodyKind, Vec3, World, WorldConfig};

use super::{Deviation, Plan, Pose, RunFault, Settings, Trajectory, TuneError, step_work};

/// The scene, parsed once; each run builds its own world from it.
pub struct Scene {
    desc: SceneDesc,
    file: String,
    /// Each dynamic body's bounding radius about its origin, m, in creation
    /// order.
    radii: Vec<f64>,
    /// Each dynamic body's name, in the same order.
    names: Vec<String>,
}

impl Scene {
    /// Reads and parses a scene file.
    ///
    /// # Errors
    /// [`TuneError::Io`], or [`TuneError::Scene`] with the file, line and
    /// column of the problem.
    pub fn load(path: &Path) -> Result<Scene, TuneError> {
        let text = std::fs::read_to_string(path).map_err(|source| TuneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Scene::parse(&text, &path.display().to_string())
    }

    /// Parses a scene from its text.
    ///
    /// # Errors
    /// [`TuneError::Scene`].
    pub fn parse(text: &str, file: &str) -> Result<Scene, TuneError> {
        let desc = parse_scene(text, file)?;
        let mut scene = Scene {
            desc,
            file: file.to_owned(),
            radii: Vec::new(),
            names: Vec::new(),
        };
        let world = scene.build(scene.own())?;
        for h in dynamic_bodies(&world) {
            scene.radii.push(bounding_radius(&world, h));
            scene.names.push(
                world
                    .body(h)
                    .map_or_else(|_| String::new(), |b| b.name().to_owned()),
            );
        }
        Ok(scene)
    }

    /// The settings the scene file gives.
    pub fn own(&self) -> Settings {
        let d = self.desc.world;
        Settings {
            tick_rate: d.tick_rate,
            substeps: d.substeps,
            solver_iterations: d.solver_iterations,
            relax_iterations: d.relax_iterations,
        }
    }

    /// The scene's world at other settings.
    ///
    /// # Errors
    /// [`TuneError::Scene`] (geometry that does not build, settings out of
    /// range).
    pub fn build(&self, s: Settings) -> Result<World, TuneError> {
        // The scene's own settings (contact spring, margins, sleeping) with
        // the four that tune varies.
        let config = WorldConfig {
            tick_rate: s.tick_rate,
            substeps: s.substeps,
            solver_iterations: s.solver_iterations,
            relax_iterations: s.relax_iterations,
            ..self.desc.world
        };
        Ok(build_world_with_config(&self.desc, config, &self.file)?)
    }

    /// Dynamic bodies in the scene.
    pub fn dynamic_bodies(&self) -> usize {
        self.radii.len()
    }

    /// The names of the dynamic bodies, in file order.
    pub fn body_names(&self) -> &[String] {
        &self.names
    }

    /// Runs the scene at `s` for the plan, recording every dynamic body's
    /// pose at every sample time, and counting its work.
    ///
    /// # Errors
    /// [`TuneError::Scene`] if the world does not build; a fault is not an
    /// error but the second part of the result.
    pub fn run(&self, s: Settings, plan: Plan) -> Result<Run, TuneError> {
        let mut world = self.build(s)?;
        let handles: Vec<_> = dynamic_bodies(&world).collect();
        let every = u64::from(s.tick_rate / plan.sample_hz);
        let mut run = Run::default();
        for _ in 0..plan.steps(s.tick_rate) {
            let r = world.step();
            run.work += step_work(&r, s);
            run.steps += 1;
            if !r.faults.is_empty() {
                run.fault = Some(RunFault {
                    tick: r.tick,
                    faults: r.faults,
                });
                return Ok(run);
            }
            if r.tick.is_multiple_of(every) {
                let poses = handles
                    .iter()
                    .map(|&h| {
                        let b = world.body(h).expect("a handle of this world");
                        let (p, q) = (b.position(), b.rotation());
                        Pose {
                            p: [p.x.to_f64(), p.y.to_f64(), p.z.to_f64()],
                            q: [q.w.to_f64(), q.x.to_f64(), q.y.to_f64(), q.z.to_f64()],
                        }
                    })
                    .collect();
                run.trajectory.poses.push(poses);
            }
        }
        Ok(run)
    }

    /// Wall-clock seconds `steps` steps at `s` take (the world is built
    /// before the clock starts).
    ///
    /// # Errors
    /// [`TuneError::Scene`] if the world does not build.
    pub fn time(&self, s: Settings, steps: u64) -> Result<f64, TuneError> {
        let mut world = self.build(s)?;
        let start = Instant::now();
        for _ in 0..steps {
            std::hint::black_box(world.step());
        }
        Ok(start.elapsed().as_secs_f64())
    }

    /// How far `run` is from `reference` (see [`Deviation`]).
    pub fn deviation(&self, run: &Trajectory, reference: &Trajectory) -> Deviation {
        let mut d = Deviation::default();
        for (sample, (a, b)) in (1u64..).zip(run.poses.iter().zip(&reference.poses)) {
            for (body, ((pa, pb), r)) in a.iter().zip(b).zip(&self.radii).enumerate() {
                let dp = ((pa.p[0] - pb.p[0]).powi(2)
                    + (pa.p[1] - pb.p[1]).powi(2)
                    + (pa.p[2] - pb.p[2]).powi(2))
                .sqrt();
                let angle = rotation_between(pa.q, pb.q);
                let sin_half = (angle / 2.0).sin();
                d.position = d.position.max(dp);
                d.angle = d.angle.max(angle);
                let e = dp + 2.0 * sin_half * r;
                if e > d.error {
                    d.error = e;
                    d.worst = Some((body, sample));
                }
            }
        }
        d
    }
}

/// What one measuring run recorded.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Run {
    /// Dynamic-body poses at the sample times reached.
    pub trajectory: Trajectory,
    /// Total work (see [`step_work`]).
    pub work: u64,
    /// Steps taken (fewer than planned after a fault).
    pub steps: u64,
    /// The fault that stopped it, if any.
    pub fault: Option<RunFault>,
}

/// The angle of the rotation from `b` to `a`, radians in [0, π]: from the
/// relative quaternion `b⁻¹·a`, as `2·atan2(|vector part|, |real part|)`,
/// which is exact near zero (equal inputs give exactly 0) and needs no unit
/// length (a Q32.32 quaternion is unit only to its last bits; `acos` of
/// their dot product would turn that into an angle of 10⁻⁴ rad).
pub(super) fn rotation_between(a: [f64; 4], b: [f64; 4]) -> f64 {
    let [aw, ax, ay, az] = a;
    let [bw, bx, by, bz] = b;
    // conj(b) · a
    let w = bw * aw + bx * ax + by * ay + bz * az;
    let x = bw * ax - bx * aw - (by * az - bz * ay);
    let y = bw * ay - by * aw - (bz * ax - bx * az);
    let z = bw * az - bz * aw - (bx * ay - by * ax);
    2.0 * (x * x + y * y + z * z).sqrt().atan2(w.abs())
}

fn dynamic_bodies(world: &World) -> impl Iterator<Item = BodyHandle> + '_ {
    world
        .body_handles()
        .filter(|&h| world.body(h).is_ok_and(|b| b.kind() == BodyKind::Dynamic))
}

/// The largest distance from a body's origin of a corner of one of its
/// shapes' local bounding boxes, m: every point of the body is within it.
fn bounding_radius(world: &World, h: BodyHandle) -> f64 {
    let Ok(body) = world.body(h) else {
        return 0.0;
    };
    let mut r = 0.0f64;
    for &c in body.colliders() {
        let Ok(collider) = world.collider(c) else {
            continue;
        };
        let b = collider.shape.local_aabb();
        for i in 0..8 {
            let pick = |bit: usize, lo, hi| if i & bit == 0 { lo } else { hi };
            let corner = Vec3::new(
                pick(1, b.min.x, b.max.x),
                pick(2, b.min.y, b.max.y),
                pick(4, b.min.z, b.max.z),
            );
            let p = collider.local_pose.transform_point(corner);
            let d = (p.x.to_f64().powi(2) + p.y.to_f64().powi(2) + p.z.to_f64().powi(2)).sqrt();
            r = r.max(d);
        }
    }
    r
}
