//! Our side: a scene built in lockstep-core, stepped and counted.

use std::sync::Arc;

use lockstep_core::SleepConfig;
use lockstep_core::shape::{ConvexHull, Cuboid, Shape, Sphere};
use lockstep_core::{
    BodyDesc, BodyHandle, ColliderDesc, CollisionFilter, ContactOrder, ContactRows, JointDesc,
    Material, Scalar, Vec3, World, WorldConfig,
};

use super::{SUBSTEPS, Sim, TICK_RATE};
use crate::scene_file;
use crate::scenes::{BodyShape, Scene};

pub(super) struct Ours {
    pub(super) world: World,
    pub(super) bodies: Vec<BodyHandle>,
    pub(super) contact_points: usize,
    /// Batches the wide lanes took and batches their guard refused, summed
    /// over the steps.
    pub(super) lanes: (u64, u64),
    /// Constraint-ticks, those on the narrow rows and those the guard
    /// moved to the Q32.32 rows, summed over the steps.
    pub(super) rows_count: (u64, u64, u64),
    pub(super) faulted: bool,
}

pub(super) fn s(v: f64) -> Scalar {
    Scalar::from_f64_lossy(v)
}

pub(super) fn v3(p: [f64; 3]) -> Vec3 {
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
    pub(super) fn new(scene: &Scene) -> Ours {
        Ours::in_order(scene, ContactOrder::Pairs, 1)
    }

    /// Ours in the given order with `workers` solver threads.
    pub(super) fn in_order(scene: &Scene, order: ContactOrder, workers: usize) -> Ours {
        Ours::with(scene, order, workers, false)
    }

    /// [`Ours::in_order`] with the solver's wide lanes on (`wide`) or off.
    pub(super) fn with(scene: &Scene, order: ContactOrder, workers: usize, wide: bool) -> Ours {
        Ours::with_rows(
            scene,
            order,
            workers,
            wide,
            WorldConfig::default().contact_rows,
        )
    }

    /// [`Ours::with`] with the contact rows' number format given.
    pub(super) fn with_rows(
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
