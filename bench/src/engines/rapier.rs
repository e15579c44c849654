//! Rapier's side: a scene built in Rapier, its settings, and its one-thread pool.

use rapier3d::prelude::{
    ColliderBuilder, IntegrationParameters, InteractionGroups, PhysicsWorld, RigidBodyBuilder,
    RigidBodyHandle, SharedShape, SphericalJointBuilder, Vector,
};

use super::ours::s;
use super::{SUBSTEPS, Sim, TICK_RATE};
use crate::scene_file;
use crate::scenes::{BodyShape, Scene};

/// Rapier's settings, chosen to match our 4 substeps: in Rapier 0.36 each
/// "solver iteration" is a substep of its TGS-soft solver (integrate, one
/// PGS pass with bias, one relax pass without), like Box2D v3's soft step.
pub(super) fn rapier_parameters() -> IntegrationParameters {
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

/// A scene in Rapier.
pub(crate) struct Rapier {
    /// The whole Rapier world (its counters are `physics_pipeline.counters`).
    pub(crate) world: PhysicsWorld,
    pub(super) bodies: Vec<RigidBodyHandle>,
}

/// The `f32` Rapier gets for a scene value: the value rounded to Q32.32
/// first, so both engines start from the same numbers.
pub(super) fn r(v: f64) -> f32 {
    s(v).to_f64() as f32
}

pub(super) fn rv(p: [f64; 3]) -> Vector {
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
    pub(super) fn on_threads(scene: &Scene, threads: usize) -> Rapier {
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
