//! The seeded random scene of the `scene_hashes` and `plain_exports`
//! examples (included by both with `#[path]`; not an example itself).
//!
//! It is built through the core API from an integer SplitMix64 stream: every
//! number is an integer or an exact ratio of integers (no floats on the way
//! into the world), so every architecture builds the very same world and any
//! difference in the hashes is a difference in stepping.

use std::sync::Arc;

use lockstep_core::shape::{Capsule, ConvexHull, Cuboid, Shape, Sphere};
use lockstep_core::{
    BodyDesc, ColliderDesc, Material, Quat, Scalar, Transform, Vec3, World, WorldConfig,
};
use lockstep_testsupport::Rng;

/// The scene's draws, on the workspace's one seeded test generator
/// (SplitMix64; its integer draws are `Rng::int`).
trait Draw {
    fn milli(&mut self, lo: i64, hi: i64) -> Scalar;
    fn vec(&mut self, lo: i64, hi: i64) -> Vec3;
    fn rotation(&mut self) -> Quat;
    fn shape(&mut self) -> Result<Shape, Box<dyn std::error::Error>>;
    fn material(&mut self) -> Material;
}

impl Draw for Rng {
    /// A value in `[lo, hi]` thousandths, exactly `k/1000` for an integer k.
    fn milli(&mut self, lo: i64, hi: i64) -> Scalar {
        Scalar::from_ratio(self.int(lo, hi), 1000)
    }

    /// A vector whose components are in `[lo, hi]` thousandths.
    fn vec(&mut self, lo: i64, hi: i64) -> Vec3 {
        Vec3::new(self.milli(lo, hi), self.milli(lo, hi), self.milli(lo, hi))
    }

    /// A rotation: four integer components, normalised in fixed point.
    fn rotation(&mut self) -> Quat {
        let mut c = || Scalar::from_int(self.int(-1000, 1000) as i32);
        Quat::from_xyzw(c(), c(), c(), c()).normalize()
    }

    /// One of the convex shapes, about 0.2 m to 1.2 m across.
    fn shape(&mut self) -> Result<Shape, Box<dyn std::error::Error>> {
        Ok(match self.int(0, 3) {
            0 => Shape::Sphere(Sphere::new(self.milli(200, 600))?),
            1 => Shape::Cuboid(Cuboid::new(self.vec(150, 600))?),
            2 => Shape::Capsule(Capsule::new(self.milli(100, 500), self.milli(150, 400))?),
            _ => loop {
                let n = self.int(5, 10) as usize;
                let points: Vec<Vec3> = (0..n).map(|_| self.vec(-500, 500)).collect();
                // A rare draw of points spanning less than three dimensions
                // is drawn again (the same way on every machine).
                if let Ok(hull) = ConvexHull::from_points(&points) {
                    break Shape::ConvexHull(Arc::new(hull));
                }
            },
        })
    }

    fn material(&mut self) -> Material {
        Material::new(self.milli(100, 1000), self.milli(0, 500))
    }
}

/// A seeded random scene: a ground box, a few static obstacles and a dozen
/// or so dynamic bodies of every convex kind (some of two shapes), thrown
/// with random positions, rotations and velocities.
pub fn random_world(seed: u64) -> Result<World, Box<dyn std::error::Error>> {
    let mut rng = Rng::new(seed);
    let mut world = World::new(WorldConfig::default())?;
    let ground = world.create_body(
        &BodyDesc::fixed()
            .name("ground")
            .position(Vec3::from_ints(0, -1, 0)),
    )?;
    world.add_collider(
        ground,
        ColliderDesc::new(Shape::Cuboid(Cuboid::new(Vec3::from_ints(20, 1, 20))?))
            .material(rng.material()),
    )?;
    for i in 0..rng.int(1, 3) {
        let position = Vec3::new(
            rng.milli(-4000, 4000),
            rng.milli(0, 500),
            rng.milli(-4000, 4000),
        );
        let h = world.create_body(
            &BodyDesc::fixed()
                .name(format!("obstacle{i}"))
                .position(position)
                .rotation(rng.rotation()),
        )?;
        let shape = rng.shape()?;
        world.add_collider(h, ColliderDesc::new(shape).material(rng.material()))?;
    }
    for i in 0..rng.int(8, 16) {
        let position = Vec3::new(
            rng.milli(-3000, 3000),
            rng.milli(1000, 10000),
            rng.milli(-3000, 3000),
        );
        let h = world.create_body(
            &BodyDesc::dynamic()
                .name(format!("body{i}"))
                .position(position)
                .rotation(rng.rotation())
                .linear_velocity(rng.vec(-3000, 3000))
                .angular_velocity(rng.vec(-4000, 4000)),
        )?;
        let shape = rng.shape()?;
        let density = rng.milli(300_000, 3_000_000);
        world.add_collider(
            h,
            ColliderDesc::new(shape)
                .density(density)
                .material(rng.material()),
        )?;
        if rng.int(0, 5) == 0 {
            // A second shape beside the first: a compound body.
            let pose = Transform::new(rng.vec(-700, 700), rng.rotation());
            let shape = rng.shape()?;
            world.add_collider(
                h,
                ColliderDesc::new(shape)
                    .local_pose(pose)
                    .density(density)
                    .material(rng.material()),
            )?;
        }
    }
    Ok(world)
}
