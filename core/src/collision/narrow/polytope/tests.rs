//! The ball and cone bounds skip work, never change a result: the pruned
//! SAT against the same test with nothing skipped, on seeded random pairs.

use std::sync::Arc;

use super::*;
use crate::collision::tests::rng::{Draw, Rng};
use crate::math::Quat;
use crate::shape::{ConvexHull, Cuboid};

/// `n` points on a sphere of radius `r` (seeded), as the pile scenes use.
fn round_hull(rng: &mut Rng, n: usize, r: i32) -> Arc<ConvexHull> {
    loop {
        let pts: Vec<Vec3> = (0..n)
            .filter_map(|_| (rng.vec(-4, 4)).try_normalize())
            .map(|u| u * Scalar::from_int(r))
            .collect();
        if let Ok(h) = ConvexHull::from_points(&pts) {
            return Arc::new(h);
        }
    }
}

/// A random rotation (a normalised random quaternion).
fn rotation(rng: &mut Rng) -> Quat {
    loop {
        let v = rng.vec(-1, 1);
        let w = rng.scalar(-1, 1);
        let q = Quat::from_xyzw(v.x, v.y, v.z, w);
        if q.norm_squared_wide() > (1u128 << 60) {
            return q.normalize();
        }
    }
}

/// B's pose: rotated at random, its origin at a random direction from A's
/// at `reach` × a distance between 0.6 and 1.15 (so pairs range from deep
/// through touching to apart by more than the margin).
fn pose_near(rng: &mut Rng, a: &Transform, reach: Scalar) -> Transform {
    let dir = loop {
        if let Some(u) = rng.vec(-1, 1).try_normalize() {
            break u;
        }
    };
    let k = Scalar::from_ratio(60 + rng.below(56) as i64, 100);
    Transform::new(a.translation + dir * (reach * k), rotation(rng))
}

#[derive(Default)]
struct Tally {
    touching: u32,
    apart: u32,
    edge: u32,
}

fn check<PA: Poly, PB: Poly>(a: &PA, b: &PB, reach: Scalar, rng: &mut Rng, tally: &mut Tally) {
    let margin = Scalar::from_ratio(2, 100);
    let far = Transform::new(
        Vec3::new(
            Scalar::from_int(700_000),
            Scalar::from_int(-3),
            Scalar::from_int(12),
        ),
        rotation(rng),
    );
    for _ in 0..40 {
        let pose_a = if rng.below(4) == 0 {
            far
        } else {
            Transform::new(rng.vec(-50, 50), rotation(rng))
        };
        let pose_b = pose_near(rng, &pose_a, reach);
        let (mut fast, mut full) = (Manifold::EMPTY, Manifold::EMPTY);
        let hit = sat_and_clip(a, &pose_a, b, &pose_b, margin, true, &mut fast);
        let hit_full = sat_and_clip(a, &pose_a, b, &pose_b, margin, false, &mut full);
        assert_eq!((hit, fast), (hit_full, full), "poses {pose_a:?} {pose_b:?}");
        if hit {
            tally.touching += 1;
            tally.edge += u32::from(fast.count == 1 && fast.points[0].id.0 & 0x4000_0000 != 0);
        } else {
            tally.apart += 1;
        }
    }
}

#[test]
fn pruned_sat_gives_the_same_manifolds_as_testing_every_feature() {
    let mut rng = Rng::new(0x5eed_0042);
    let mut tally = Tally::default();
    let cube = BoxPoly::new(&Cuboid::new(Vec3::from_ints(1, 1, 1)).unwrap());
    let slab = BoxPoly::new(
        &Cuboid::new(Vec3::new(
            Scalar::from_int(3),
            Scalar::from_ratio(1, 4),
            Scalar::ONE,
        ))
        .unwrap(),
    );
    for round in 0..12 {
        let n = [8, 12, 32, 64][round % 4];
        let ha = round_hull(&mut rng, n, 2);
        let hb = round_hull(&mut rng, 32, 1 + (round % 3) as i32);
        let reach = ha.sat().balls.outer + hb.sat().balls.outer;
        check(&*ha, &*hb, reach, &mut rng, &mut tally);
        check(
            &cube,
            &*hb,
            Scalar::from_ratio(173, 100) + hb.sat().balls.outer,
            &mut rng,
            &mut tally,
        );
        check(
            &slab,
            &*ha,
            Scalar::from_int(3) + ha.sat().balls.outer,
            &mut rng,
            &mut tally,
        );
    }
    // The pairs cover what the bounds decide between: touching and apart,
    // face and edge contacts.
    assert!(
        tally.touching > 300 && tally.apart > 300,
        "{} {}",
        tally.touching,
        tally.apart
    );
    assert!(tally.edge > 10, "{}", tally.edge);
}
