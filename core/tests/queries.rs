//! Scene queries: ray casts against every shape kind versus closed-form
//! answers, sweeps versus rays against inflated shapes, overlaps, filters,
//! independence from the broad phase's history, and read-only-ness.

use lockstep_core::query::{
    OverlapHit, QueryError, QueryFilter, Ray, RayHit, SWEEP_TOLERANCE, ShapeHit,
};
use lockstep_core::shape::{
    Capsule, ConvexHull, Cuboid, HeightField, Shape, ShapeKind, Sphere, TriMesh,
};
use lockstep_core::{
    Aabb, BodyDesc, BodyHandle, ColliderDesc, ColliderHandle, CollisionFilter, Quat, Scalar,
    Transform, Vec3, World, WorldConfig,
};
use lockstep_testsupport::{Rng, s, v};

fn world() -> World {
    World::new(WorldConfig {
        gravity: Vec3::ZERO,
        ..WorldConfig::default()
    })
    .unwrap()
}

fn fixed(w: &mut World, at: Vec3, rot: Quat, shape: Shape) -> (BodyHandle, ColliderHandle) {
    let b = w
        .create_body(&BodyDesc::fixed().position(at).rotation(rot))
        .unwrap();
    let c = w.add_collider(b, ColliderDesc::new(shape)).unwrap();
    (b, c)
}

fn one(at: Vec3, shape: Shape) -> (World, ColliderHandle) {
    let mut w = world();
    let (_, c) = fixed(&mut w, at, Quat::IDENTITY, shape);
    (w, c)
}

fn sphere(r: f64) -> Shape {
    Shape::Sphere(Sphere::new(s(r)).unwrap())
}

fn cuboid(x: f64, y: f64, z: f64) -> Shape {
    Shape::Cuboid(Cuboid::new(v(x, y, z)).unwrap())
}

fn closest(w: &World, o: Vec3, d: Vec3) -> Option<RayHit> {
    w.cast_ray_closest(&Ray::new(o, d), &QueryFilter::default())
}

fn near(a: Scalar, b: f64, tol: f64) -> bool {
    (a.to_f64() - b).abs() <= tol
}

fn near_v(a: Vec3, b: [f64; 3], tol: f64) -> bool {
    near(a.x, b[0], tol) && near(a.y, b[1], tol) && near(a.z, b[2], tol)
}

#[track_caller]
fn assert_hit(h: Option<RayHit>, t: f64, n: [f64; 3], tol: f64) -> RayHit {
    let h = h.expect("expected a hit");
    assert!(near(h.fraction, t, tol), "fraction {} vs {t}", h.fraction);
    assert!(near_v(h.normal, n, 1e-6), "normal {:?} vs {n:?}", h.normal);
    h
}

#[test]
fn ray_against_sphere_matches_closed_form_from_outside_inside_and_grazing() {
    let (w, c) = one(v(5.0, 0.0, 0.0), sphere(1.0));
    let d = v(10.0, 0.0, 0.0);
    let h = assert_hit(closest(&w, Vec3::ZERO, d), 0.4, [-1.0, 0.0, 0.0], 1e-9);
    assert_eq!(h.collider, c);
    assert!(near_v(h.point, [4.0, 0.0, 0.0], 1e-8));
    // Off axis: enters at x = 5 − √(1 − 0.36) = 4.2, normal (−0.8, 0.6, 0).
    assert_hit(
        closest(&w, v(0.0, 0.6, 0.0), d),
        0.42,
        [-0.8, 0.6, 0.0],
        1e-9,
    );
    // Grazing the top: touching counts, at x = 5.
    assert_hit(closest(&w, v(0.0, 1.0, 0.0), d), 0.5, [0.0, 1.0, 0.0], 1e-9);
    assert!(closest(&w, v(0.0, 1.000001, 0.0), d).is_none());
    // Too short, and pointing away.
    assert!(closest(&w, Vec3::ZERO, v(3.9, 0.0, 0.0)).is_none());
    assert!(closest(&w, Vec3::ZERO, v(-10.0, 0.0, 0.0)).is_none());
    // From inside: fraction 0, normal opposite the ray.
    assert_hit(
        closest(&w, v(5.0, 0.5, 0.0), v(0.0, 0.0, 3.0)),
        0.0,
        [0.0, 0.0, -1.0],
        0.0,
    );
    // A zero translation reports nothing.
    assert!(closest(&w, v(5.0, 0.0, 0.0), Vec3::ZERO).is_none());
}

#[test]
fn ray_against_box_is_the_slab_test_including_rotation_grazing_and_parallel() {
    let (w, _) = one(v(5.0, 0.0, 0.0), cuboid(1.0, 2.0, 3.0));
    let d = v(10.0, 0.0, 0.0);
    let h = assert_hit(
        closest(&w, v(0.0, 0.5, 0.5), d),
        0.4,
        [-1.0, 0.0, 0.0],
        1e-9,
    );
    assert!(near_v(h.point, [4.0, 0.5, 0.5], 1e-8));
    // Entering through the top face: from (5.5, 10, 1) straight down.
    assert_hit(
        closest(&w, v(5.5, 10.0, 1.0), v(0.0, -10.0, 0.0)),
        0.8,
        [0.0, 1.0, 0.0],
        1e-9,
    );
    // Parallel to the top face, in its plane: grazes it, enters at x = 4.
    assert_hit(
        closest(&w, v(0.0, 2.0, 0.0), d),
        0.4,
        [-1.0, 0.0, 0.0],
        1e-9,
    );
    // Parallel just outside: misses.
    assert!(closest(&w, v(0.0, 2.0001, 0.0), d).is_none());
    // Diagonal through the corner edge (x = 4, y = 2): ties go to the lowest
    // axis, so the normal is −x.
    assert_hit(
        closest(&w, v(0.0, 6.0, 0.0), v(8.0, -8.0, 0.0)),
        0.5,
        [-1.0, 0.0, 0.0],
        1e-9,
    );
    // From inside.
    assert_hit(
        closest(&w, v(5.0, 0.0, 0.0), d),
        0.0,
        [-1.0, 0.0, 0.0],
        1e-9,
    );
    // Rotated 45° about z: the ray at y = 0.3 enters the face with normal
    // (−1, 1, 0)/√2 at x = 5 + 0.3 − √2.
    let mut w = world();
    let q = Quat::from_axis_angle(Vec3::Z, Scalar::PI.div_int(4)).normalize();
    fixed(&mut w, v(5.0, 0.0, 0.0), q, cuboid(1.0, 1.0, 1.0));
    let r = 0.5f64.sqrt();
    let t = (5.3 - 2f64.sqrt()) / 10.0;
    assert_hit(closest(&w, v(0.0, 0.3, 0.0), d), t, [-r, r, 0.0], 1e-8);
}

#[test]
fn ray_against_capsule_hits_side_and_caps() {
    let cap = Shape::Capsule(Capsule::new(s(1.0), s(0.5)).unwrap());
    let (w, _) = one(v(5.0, 0.0, 0.0), cap);
    let d = v(10.0, 0.0, 0.0);
    assert_hit(closest(&w, Vec3::ZERO, d), 0.45, [-1.0, 0.0, 0.0], 1e-9);
    // Top cap centred at (5, 1, 0): at height 1.3 it enters at x = 4.6.
    assert_hit(
        closest(&w, v(0.0, 1.3, 0.0), d),
        0.46,
        [-0.8, 0.6, 0.0],
        1e-9,
    );
    // Down the axis: the top pole at y = 1.5.
    assert_hit(
        closest(&w, v(5.0, 10.0, 0.0), v(0.0, -10.0, 0.0)),
        0.85,
        [0.0, 1.0, 0.0],
        1e-9,
    );
    // Grazing the side (z = 0.5) and just missing it.
    assert_hit(closest(&w, v(0.0, 0.0, 0.5), d), 0.5, [0.0, 0.0, 1.0], 1e-9);
    assert!(closest(&w, v(0.0, 0.0, 0.5001), d).is_none());
    // From inside.
    assert_hit(
        closest(&w, v(5.0, 0.2, 0.2), d),
        0.0,
        [-1.0, 0.0, 0.0],
        1e-9,
    );
}

#[test]
fn ray_against_hull_clips_by_its_face_planes() {
    let tet = ConvexHull::from_points(&[
        Vec3::ZERO,
        Vec3::from_ints(2, 0, 0),
        Vec3::from_ints(0, 2, 0),
        Vec3::from_ints(0, 0, 2),
    ])
    .unwrap();
    let (w, _) = one(v(5.0, 0.0, 0.0), tet.into());
    // The face x = 0 (local), at world x = 5.
    assert_hit(
        closest(&w, v(0.0, 0.5, 0.5), v(10.0, 0.0, 0.0)),
        0.5,
        [-1.0, 0.0, 0.0],
        1e-9,
    );
    // The slanted face x + y + z = 2 from +x: enters at local x = 1.6.
    let k = 1.0 / 3f64.sqrt();
    assert_hit(
        closest(&w, v(20.0, 0.2, 0.2), v(-20.0, 0.0, 0.0)),
        0.67,
        [k, k, k],
        1e-8,
    );
    // Parallel to the slanted face, outside it: misses.
    assert!(closest(&w, v(5.0, 3.0, 0.5), v(3.0, -3.0, 0.0)).is_none());
    // From inside.
    assert_hit(
        closest(&w, v(5.2, 0.2, 0.2), v(0.0, 4.0, 0.0)),
        0.0,
        [0.0, -1.0, 0.0],
        0.0,
    );
}

fn quad_mesh() -> Shape {
    // Two triangles covering [0, 2]² at y = 0, wound to face +y.
    TriMesh::new(
        vec![
            Vec3::ZERO,
            Vec3::from_ints(2, 0, 0),
            Vec3::from_ints(2, 0, 2),
            Vec3::from_ints(0, 0, 2),
        ],
        vec![[0, 2, 1], [0, 3, 2]],
    )
    .unwrap()
    .into()
}

#[test]
fn ray_against_mesh_hits_triangles_from_both_sides_and_through_shared_edges() {
    let (w, _) = one(Vec3::ZERO, quad_mesh());
    let down = v(0.0, -10.0, 0.0);
    assert_hit(
        closest(&w, v(0.5, 5.0, 1.5), down),
        0.5,
        [0.0, 1.0, 0.0],
        1e-9,
    );
    assert_hit(
        closest(&w, v(1.5, 5.0, 0.5), down),
        0.5,
        [0.0, 1.0, 0.0],
        1e-9,
    );
    // From below: the normal faces the ray.
    assert_hit(
        closest(&w, v(1.5, -2.0, 0.5), v(0.0, 4.0, 0.0)),
        0.5,
        [0.0, -1.0, 0.0],
        1e-9,
    );
    // Exactly through the shared diagonal, and through a corner vertex.
    assert_hit(
        closest(&w, v(1.0, 5.0, 1.0), down),
        0.5,
        [0.0, 1.0, 0.0],
        1e-9,
    );
    assert_hit(
        closest(&w, v(2.0, 5.0, 2.0), down),
        0.5,
        [0.0, 1.0, 0.0],
        1e-9,
    );
    // Outside the quad, and in its plane: no hit.
    assert!(closest(&w, v(2.001, 5.0, 1.0), down).is_none());
    assert!(closest(&w, v(-1.0, 0.0, 1.0), v(4.0, 0.0, 0.0)).is_none());
    // Slanted.
    let h = assert_hit(
        closest(&w, v(-1.0, 1.0, 1.0), v(4.0, -2.0, 0.0)),
        0.5,
        [0.0, 1.0, 0.0],
        1e-9,
    );
    assert!(near_v(h.point, [1.0, 0.0, 1.0], 1e-8));
}

/// A `n × n` field with unit cells whose heights rise by 0.5 per column: the
/// plane `y = 0.5 (x + (n − 1)/2)`.
fn ramp(n: u32) -> Shape {
    let heights = (0..n * n).map(|i| s(0.5 * (i % n) as f64)).collect();
    HeightField::new(n, n, heights, v(1.0, 1.0, 1.0))
        .unwrap()
        .into()
}

#[test]
fn ray_against_height_field_hits_the_cells_it_crosses() {
    let (w, _) = one(Vec3::ZERO, ramp(9));
    let n = {
        let l = 1.25f64.sqrt();
        [-0.5 / l, 1.0 / l, 0.0]
    };
    // Straight down at (0.3, −0.4): y = 0.5 (0.3 + 4) = 2.15.
    assert_hit(
        closest(&w, v(0.3, 10.0, -0.4), v(0.0, -20.0, 0.0)),
        (10.0 - 2.15) / 20.0,
        n,
        1e-9,
    );
    // Down a grid vertex and down a cell diagonal.
    assert_hit(
        closest(&w, v(1.0, 10.0, 1.0), v(0.0, -20.0, 0.0)),
        (10.0 - 2.5) / 20.0,
        n,
        1e-9,
    );
    assert_hit(
        closest(&w, v(1.5, 10.0, 1.5), v(0.0, -20.0, 0.0)),
        (10.0 - 2.75) / 20.0,
        n,
        1e-9,
    );
    // A shallow ray across many cells: x = −4 + 8t, y = 5 − 4t meets
    // y = 0.5 x + 2 at t = 5/8.
    assert_hit(
        closest(&w, v(-4.0, 5.0, 0.25), v(8.0, -4.0, 0.0)),
        0.625,
        n,
        1e-9,
    );
    // Diagonal in z too.
    assert_hit(
        closest(&w, v(-4.0, 5.0, -3.0), v(8.0, -4.0, 6.0)),
        0.625,
        n,
        1e-9,
    );
    // From below the surface, going up: the normal faces the ray.
    let up = assert_hit(
        closest(&w, v(0.0, 0.0, 0.0), v(0.0, 4.0, 0.0)),
        0.5,
        [-n[0], -n[1], 0.0],
        1e-9,
    );
    assert!(near_v(up.point, [0.0, 2.0, 0.0], 1e-8));
    // Outside the grid's footprint, and parallel above it.
    assert!(closest(&w, v(4.5, 10.0, 0.0), v(0.0, -20.0, 0.0)).is_none());
    assert!(closest(&w, v(-4.0, 6.0, 0.0), v(8.0, 0.0, 0.0)).is_none());
}

#[test]
fn all_hits_are_sorted_and_filters_and_triggers_apply() {
    let mut w = world();
    let mut balls = Vec::new();
    // Spheres at x = 8, 2, 6, 4 (created in that order: handles 0..4).
    for (i, x) in [8.0, 2.0, 6.0, 4.0].into_iter().enumerate() {
        let b = w
            .create_body(&BodyDesc::fixed().position(v(x, 0.0, 0.0)))
            .unwrap();
        let mut desc = ColliderDesc::new(sphere(0.5));
        if i == 2 {
            desc = desc.trigger(true);
        }
        if i == 3 {
            desc = desc.filter(CollisionFilter {
                category: 2,
                ..CollisionFilter::default()
            });
        }
        let c = w.add_collider(b, desc).unwrap();
        balls.push((b, c));
    }
    let ray = Ray::new(Vec3::ZERO, v(10.0, 0.0, 0.0));
    let mut out = Vec::new();
    // Fractions to 1e-9 (0.15 is not a Q32.32 number).
    let fractions = |out: &[RayHit]| -> Vec<f64> {
        out.iter()
            .map(|h| (h.fraction.to_f64() * 1e9).round() / 1e9)
            .collect()
    };
    w.cast_ray_all(&ray, &QueryFilter::default(), &mut out);
    assert_eq!(fractions(&out), [0.15, 0.35, 0.75]);
    let order: Vec<ColliderHandle> = out.iter().map(|h| h.collider).collect();
    assert_eq!(order, [balls[1].1, balls[3].1, balls[0].1]);
    w.cast_ray_all(&ray, &QueryFilter::default().triggers(true), &mut out);
    assert_eq!(fractions(&out), [0.15, 0.35, 0.55, 0.75]);
    assert_eq!(out[2].collider, balls[2].1);
    // Mask without category 2, then exclusion and a predicate.
    w.cast_ray_all(&ray, &QueryFilter::default().bits(1, !2), &mut out);
    assert_eq!(fractions(&out), [0.15, 0.75]);
    // A query whose category the colliders' masks reject finds nothing.
    let masked = w
        .create_body(&BodyDesc::fixed().position(v(3.0, 0.0, 0.0)))
        .unwrap();
    let odd = w
        .add_collider(
            masked,
            ColliderDesc::new(sphere(0.25)).filter(CollisionFilter {
                category: 1,
                mask: 4,
                group: 0,
            }),
        )
        .unwrap();
    w.cast_ray_all(&ray, &QueryFilter::default(), &mut out);
    assert!(out.iter().all(|h| h.collider != odd));
    // With category 4 it is found (at x = 2.75), alongside the default ones.
    w.cast_ray_all(&ray, &QueryFilter::default().bits(4, u32::MAX), &mut out);
    assert_eq!(fractions(&out), [0.15, 0.275, 0.35, 0.75]);
    assert_eq!(out[1].collider, odd);
    let excluded = [balls[1].0];
    w.cast_ray_all(&ray, &QueryFilter::default().exclude(&excluded), &mut out);
    assert_eq!(fractions(&out), [0.35, 0.75]);
    let not_first = |h: ColliderHandle, _: &lockstep_core::collider::Collider| h != balls[3].1;
    let filter = QueryFilter::default().predicate(&not_first);
    w.cast_ray_all(&ray, &filter, &mut out);
    assert_eq!(fractions(&out), [0.15, 0.75]);
    // Closest honours the same filter; any-hit reports the lowest handle hit.
    assert_eq!(
        w.cast_ray_closest(&ray, &filter).unwrap().collider,
        balls[1].1
    );
    let any = w.cast_ray_any(&ray, &QueryFilter::default()).unwrap();
    assert_eq!(any.collider, balls[0].1);
    assert!(near(any.fraction, 0.75, 1e-9));
    assert!(
        w.cast_ray_any(
            &Ray::new(v(0.0, 5.0, 0.0), ray.translation),
            &QueryFilter::default()
        )
        .is_none()
    );
}

#[test]
fn equal_fractions_go_to_the_lowest_collider_handle() {
    let mut w = world();
    // Two boxes side by side whose left faces share the plane x = 4; the ray
    // runs along their common face y = 0.
    let (_, upper) = fixed(
        &mut w,
        v(5.0, 1.0, 0.0),
        Quat::IDENTITY,
        cuboid(1.0, 1.0, 1.0),
    );
    let (_, lower) = fixed(
        &mut w,
        v(5.0, -1.0, 0.0),
        Quat::IDENTITY,
        cuboid(1.0, 1.0, 1.0),
    );
    let ray = Ray::new(Vec3::ZERO, v(10.0, 0.0, 0.0));
    let h = w.cast_ray_closest(&ray, &QueryFilter::default()).unwrap();
    assert_eq!(h.collider, upper);
    assert!(near(h.fraction, 0.4, 1e-9));
    let mut out = Vec::new();
    w.cast_ray_all(&ray, &QueryFilter::default(), &mut out);
    let got: Vec<ColliderHandle> = out.iter().map(|h| h.collider).collect();
    assert_eq!(got, [upper, lower]);
    assert!(upper < lower);
}

fn sweep(w: &World, shape: &Shape, at: Vec3, d: Vec3) -> Option<ShapeHit> {
    w.cast_shape(
        shape,
        &Transform::from_translation(at),
        d,
        &QueryFilter::default(),
    )
    .unwrap()
}

/// The next test number in `[0, 1)` from the workspace's test generator.
fn lcg(state: &mut Rng) -> f64 {
    state.unit()
}

/// The ray from `o` along `d` against a sphere of radius `r` at `c`, in f64.
fn ray_sphere_f64(o: [f64; 3], d: [f64; 3], c: [f64; 3], r: f64) -> Option<f64> {
    let m = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
    let a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let b = m[0] * d[0] + m[1] * d[1] + m[2] * d[2];
    let cc = m[0] * m[0] + m[1] * m[1] + m[2] * m[2] - r * r;
    let disc = b * b - a * cc;
    if disc < 0.0 {
        return None;
    }
    let t = (-b - disc.sqrt()) / a;
    (0.0..=1.0).contains(&t).then_some(t)
}

#[test]
fn sphere_sweep_equals_a_ray_against_the_inflated_sphere() {
    // Tolerance: the sweep stops within SWEEP_TOLERANCE (6.1e-5 m) of contact
    // along the normal, so its distance along the path is at most
    // TOL / cos θ short of the exact one, and never past it.
    let (w, c) = one(v(5.0, 0.0, 0.0), sphere(1.0));
    let ball = sphere(0.5);
    let tol = SWEEP_TOLERANCE.to_f64();
    let mut st = Rng::new(7);
    let (mut hits, mut misses, mut worst) = (0, 0, 0.0f64);
    for _ in 0..300 {
        let o = [0.0, lcg(&mut st) * 4.0 - 2.0, lcg(&mut st) * 4.0 - 2.0];
        let target = [5.0, lcg(&mut st) * 4.0 - 2.0, lcg(&mut st) * 4.0 - 2.0];
        let len = 6.0 + lcg(&mut st) * 4.0;
        let dir = {
            let d = [target[0] - o[0], target[1] - o[1], target[2] - o[2]];
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            [d[0] / l * len, d[1] / l * len, d[2] / l * len]
        };
        let (os, ds) = (v(o[0], o[1], o[2]), v(dir[0], dir[1], dir[2]));
        // The ray from the quantised inputs, so both see the same numbers.
        let (o, dir) = (
            [os.x.to_f64(), os.y.to_f64(), os.z.to_f64()],
            [ds.x.to_f64(), ds.y.to_f64(), ds.z.to_f64()],
        );
        let want = ray_sphere_f64(o, dir, [5.0, 0.0, 0.0], 1.5);
        let got = sweep(&w, &ball, os, ds);
        match (want, got) {
            (Some(t), Some(h)) => {
                hits += 1;
                assert_eq!(h.collider, c);
                assert!(!h.initially_overlapping);
                let p = [o[0] + dir[0] * t, o[1] + dir[1] * t, o[2] + dir[2] * t];
                let n = [(p[0] - 5.0) / 1.5, p[1] / 1.5, p[2] / 1.5];
                let cos = -(n[0] * dir[0] + n[1] * dir[1] + n[2] * dir[2]) / len;
                let short = (t - h.fraction.to_f64()) * len;
                assert!(short >= -1e-7, "sweep went past contact by {}", -short);
                assert!(short <= tol / cos + 1e-7, "short by {short}, cos {cos}");
                worst = worst.max(short * cos);
                assert!(near_v(h.normal, n, 1e-3), "{:?} vs {n:?}", h.normal);
                let q = [5.0 + n[0], n[1], n[2]];
                assert!(near_v(h.point, q, 1e-3), "{:?} vs {q:?}", h.point);
            }
            (None, None) => misses += 1,
            (w, g) => {
                // Only rays grazing the inflated sphere within the tolerance
                // may disagree.
                let m = [o[0] - 5.0, o[1], o[2]];
                let l2 = dir.iter().map(|x| x * x).sum::<f64>();
                let b = (m[0] * dir[0] + m[1] * dir[1] + m[2] * dir[2]) / l2;
                let closest = [m[0] - b * dir[0], m[1] - b * dir[1], m[2] - b * dir[2]];
                let gap = closest.iter().map(|x| x * x).sum::<f64>().sqrt() - 1.5;
                assert!(gap.abs() <= tol, "{w:?} vs {g:?}, gap {gap}");
            }
        }
    }
    assert!(hits > 100 && misses > 20, "{hits} hits, {misses} misses");
    // The stop is within the tolerance along the normal.
    println!("worst stop along the normal: {worst:e} m ({hits} hits, {misses} misses)");
    assert!(worst <= tol, "{worst}");
}

#[test]
fn sphere_sweep_against_a_box_face_equals_the_inflated_box_ray() {
    let (w, _) = one(v(5.0, 0.0, 0.0), cuboid(1.0, 1.0, 1.0));
    let ball = sphere(0.5);
    let tol = SWEEP_TOLERANCE.to_f64();
    // Inflated face at x = 3.5: t = 0.35 whatever the sideways motion while
    // the contact stays inside the face.
    for (o, d) in [
        (v(0.0, 0.0, 0.0), v(10.0, 0.0, 0.0)),
        (v(0.0, 0.2, -0.3), v(10.0, 0.5, 0.3)),
        (v(0.0, -0.9, 0.9), v(10.0, 0.0, -1.0)),
    ] {
        let h = sweep(&w, &ball, o, d).unwrap();
        let short = (0.35 - h.fraction.to_f64()) * 10.0;
        assert!((0.0..=tol).contains(&short), "{short}");
        assert!(near_v(h.normal, [-1.0, 0.0, 0.0], 1e-6), "{:?}", h.normal);
        assert!(near(h.point.x, 4.0, 1e-6));
    }
    // Passing above the inflated box: no hit.
    assert!(sweep(&w, &ball, v(0.0, 1.6, 0.0), v(10.0, 0.0, 0.0)).is_none());
    // Starting inside: fraction 0, flagged, pushed out through the near face.
    let h = sweep(&w, &ball, v(3.8, 0.0, 0.0), v(10.0, 0.0, 0.0)).unwrap();
    assert!(h.initially_overlapping);
    assert_eq!(h.fraction, Scalar::ZERO);
    assert!(near_v(h.normal, [-1.0, 0.0, 0.0], 1e-6), "{:?}", h.normal);
    // Touching within the tolerance at the start is a hit at 0, not an
    // overlap.
    let h = sweep(&w, &ball, v(3.49999, 0.0, 0.0), v(1.0, 0.0, 0.0)).unwrap();
    assert!(!h.initially_overlapping && h.fraction == Scalar::ZERO);
}

#[test]
fn box_capsule_and_hull_sweeps_land_on_the_ground_face() {
    let (w, ground) = one(v(0.0, -1.0, 0.0), cuboid(10.0, 1.0, 10.0));
    let tol = SWEEP_TOLERANCE.to_f64();
    let tet = ConvexHull::from_points(&[
        Vec3::ZERO,
        Vec3::from_ints(2, 0, 0),
        Vec3::from_ints(0, 2, 0),
        Vec3::from_ints(0, 0, 2),
    ])
    .unwrap();
    let tilted = Transform::new(
        v(1.0, 3.0, 0.0),
        Quat::from_axis_angle(Vec3::Z, Scalar::PI.div_int(4)).normalize(),
    );
    // (shape, pose, exact fraction for a translation of 10 m down)
    let cases: [(Shape, Transform, f64); 4] = [
        (
            cuboid(0.5, 0.5, 0.5),
            Transform::from_translation(v(0.0, 3.0, 0.0)),
            0.25,
        ),
        (
            Shape::Capsule(Capsule::new(s(1.0), s(0.5)).unwrap()),
            Transform::from_translation(v(2.0, 5.0, 0.0)),
            0.35,
        ),
        (
            tet.into(),
            Transform::from_translation(v(-1.0, 2.0, 3.0)),
            0.2,
        ),
        // A box on its edge: the lowest edge is √2/2 below the centre.
        (cuboid(0.5, 0.5, 0.5), tilted, (3.0 - 0.5f64.sqrt()) / 10.0),
    ];
    for (shape, pose, t) in cases {
        let h = w
            .cast_shape(&shape, &pose, v(0.0, -10.0, 0.0), &QueryFilter::default())
            .unwrap()
            .unwrap();
        assert_eq!(h.collider, ground);
        let short = (t - h.fraction.to_f64()) * 10.0;
        assert!(
            (-1e-8..=tol).contains(&short),
            "{:?}: {short}",
            shape.kind()
        );
        // The normal comes from GJK witness points about 3e-5 m apart
        // (the gap the sweep aims for), so it is good to ~1e-5.
        assert!(near_v(h.normal, [0.0, 1.0, 0.0], 2e-5), "{:?}", h.normal);
        assert!(near(h.point.y, 0.0, 1e-6));
    }
    // Moving away or sideways above it: nothing.
    let b = cuboid(0.5, 0.5, 0.5);
    assert!(sweep(&w, &b, v(0.0, 3.0, 0.0), v(0.0, 10.0, 0.0)).is_none());
    assert!(sweep(&w, &b, v(0.0, 3.0, 0.0), v(5.0, 0.0, 0.0)).is_none());
    // The ground excluded: nothing either.
    let body = [w.collider(ground).unwrap().body];
    let f = QueryFilter::default().exclude(&body);
    let pose = Transform::from_translation(v(0.0, 3.0, 0.0));
    assert!(
        w.cast_shape(&b, &pose, v(0.0, -10.0, 0.0), &f)
            .unwrap()
            .is_none()
    );
    // Meshes cannot be swept.
    assert_eq!(
        w.cast_shape(&quad_mesh(), &pose, v(0.0, -1.0, 0.0), &f),
        Err(QueryError::NonConvexQueryShape {
            kind: ShapeKind::TriMesh
        })
    );
}

#[test]
fn sphere_sweeps_land_on_mesh_and_height_field_triangles() {
    let tol = SWEEP_TOLERANCE.to_f64();
    let ball = sphere(0.5);
    let (w, _) = one(Vec3::ZERO, quad_mesh());
    for at in [v(1.0, 5.0, 1.0), v(0.3, 5.0, 1.7), v(1.9, 5.0, 0.1)] {
        let h = sweep(&w, &ball, at, v(0.0, -10.0, 0.0)).unwrap();
        let short = (0.45 - h.fraction.to_f64()) * 10.0;
        assert!((-1e-8..=tol).contains(&short), "{short}");
        assert!(near_v(h.normal, [0.0, 1.0, 0.0], 1e-6));
    }
    // Beyond the mesh's edge by more than the radius: no hit.
    assert!(sweep(&w, &ball, v(2.6, 5.0, 1.0), v(0.0, -10.0, 0.0)).is_none());
    // The ramp y = 0.5 x + 2: the centre stops r·√1.25 above the plane.
    let (w, _) = one(Vec3::ZERO, ramp(9));
    let y = 2.15 + 0.5 * 1.25f64.sqrt();
    let h = sweep(&w, &ball, v(0.3, 10.0, -0.4), v(0.0, -20.0, 0.0)).unwrap();
    let short = ((10.0 - y) / 20.0 - h.fraction.to_f64()) * 20.0;
    let cos = 1.0 / 1.25f64.sqrt();
    assert!((-1e-8..=tol / cos).contains(&short), "{short}");
    let l = 1.25f64.sqrt();
    assert!(
        near_v(h.normal, [-0.5 / l, 1.0 / l, 0.0], 1e-5),
        "{:?}",
        h.normal
    );
}

#[test]
fn overlap_queries_are_exact_and_sorted_by_handle() {
    let mut w = world();
    let mut cs = Vec::new();
    for x in [4.0, 0.0, 2.0] {
        cs.push(fixed(&mut w, v(x, 0.0, 0.0), Quat::IDENTITY, sphere(0.5)));
    }
    let (_, mesh) = fixed(&mut w, v(10.0, 0.0, 0.0), Quat::IDENTITY, quad_mesh());
    let mut out = Vec::new();
    let f = QueryFilter::default();
    let at = |x: f64, y: f64, z: f64| Transform::from_translation(v(x, y, z));
    let handles = |out: &[OverlapHit]| out.iter().map(|h| h.collider).collect::<Vec<_>>();
    w.overlap_shape(&sphere(0.6), &at(1.0, 0.0, 0.0), &f, &mut out)
        .unwrap();
    assert_eq!(handles(&out), [cs[1].1, cs[2].1]);
    assert_eq!(out[0].body, cs[1].0);
    // Touching counts; 0.1 mm apart does not.
    w.overlap_shape(&sphere(0.5), &at(1.0, 0.0, 0.0), &f, &mut out)
        .unwrap();
    assert_eq!(handles(&out), [cs[1].1, cs[2].1]);
    w.overlap_shape(&sphere(0.4999), &at(1.0, 0.0, 0.0), &f, &mut out)
        .unwrap();
    assert!(out.is_empty());
    // A box between the spheres reaching 0.55 each way: exact, not by boxes.
    w.overlap_shape(&cuboid(0.5, 0.1, 0.1), &at(3.0, 0.0, 0.0), &f, &mut out)
        .unwrap();
    assert_eq!(handles(&out), [cs[0].1, cs[2].1]);
    let rotated = Transform::new(
        v(3.0, 0.0, 0.0),
        Quat::from_axis_angle(Vec3::Z, Scalar::FRAC_PI_2).normalize(),
    );
    w.overlap_shape(&cuboid(0.5, 0.1, 0.1), &rotated, &f, &mut out)
        .unwrap();
    assert!(out.is_empty());
    // Against the mesh's triangles.
    w.overlap_shape(&sphere(0.5), &at(11.0, 0.4, 1.0), &f, &mut out)
        .unwrap();
    assert_eq!(handles(&out), [mesh]);
    w.overlap_shape(&sphere(0.5), &at(11.0, 0.6, 1.0), &f, &mut out)
        .unwrap();
    assert!(out.is_empty());
    // AABB query: fat boxes give candidates, tight boxes decide.
    let b = |lo: f64, hi: f64| Aabb::new(v(lo, -0.1, -0.1), v(hi, 0.1, 0.1));
    w.overlap_aabb(&b(0.55, 1.45), &f, &mut out);
    assert!(out.is_empty());
    w.overlap_aabb(&b(0.45, 1.5), &f, &mut out);
    assert_eq!(handles(&out), [cs[1].1, cs[2].1]);
    w.overlap_aabb(&b(-100.0, 100.0), &f, &mut out);
    assert_eq!(handles(&out), [cs[0].1, cs[1].1, cs[2].1, mesh]);
}

/// A mixed scene: static boxes, spheres, capsules and hulls on a grid, some
/// dynamic bodies, a mesh and a height field.
fn scene() -> World {
    let mut w = world();
    let mut st = Rng::new(99);
    fixed(&mut w, v(0.0, -5.0, 0.0), Quat::IDENTITY, ramp(9));
    fixed(&mut w, v(20.0, -5.0, 0.0), Quat::IDENTITY, quad_mesh());
    for i in 0..60 {
        let at = v(
            (i % 5) as f64 * 3.0 - 6.0,
            (i / 25) as f64 * 3.0,
            ((i / 5) % 5) as f64 * 3.0 - 6.0,
        );
        let axis = v(lcg(&mut st) - 0.5, lcg(&mut st) - 0.5, lcg(&mut st) - 0.5)
            .try_normalize()
            .unwrap_or(Vec3::X);
        let q = Quat::from_axis_angle(axis, s(lcg(&mut st) * 3.0)).normalize();
        let shape = match i % 4 {
            0 => sphere(0.5 + lcg(&mut st)),
            1 => cuboid(0.5, 0.8, 1.1),
            2 => Shape::Capsule(Capsule::new(s(0.7), s(0.4)).unwrap()),
            _ => ConvexHull::from_points(&[
                v(-1.0, 0.0, 0.0),
                v(1.0, 0.1, 0.0),
                v(0.0, 1.2, 0.3),
                v(0.2, 0.1, 1.0),
                v(0.0, -0.8, -0.5),
            ])
            .unwrap()
            .into(),
        };
        let desc = if i % 7 == 3 {
            BodyDesc::dynamic()
        } else {
            BodyDesc::fixed()
        };
        let b = w.create_body(&desc.position(at).rotation(q)).unwrap();
        w.add_collider(b, ColliderDesc::new(shape).trigger(i % 11 == 5))
            .unwrap();
    }
    w
}

/// Every kind of query on a batch of seeded rays and poses, as plain data.
fn query_digest(w: &World, seed: u64, n: usize) -> Vec<String> {
    let mut st = Rng::new(seed);
    let mut out = Vec::new();
    let mut all = Vec::new();
    let mut over = Vec::new();
    let f = QueryFilter::default().triggers(seed.is_multiple_of(2));
    for _ in 0..n {
        let mut p = || {
            v(
                lcg(&mut st) * 24.0 - 12.0,
                lcg(&mut st) * 14.0 - 6.0,
                lcg(&mut st) * 24.0 - 12.0,
            )
        };
        let (o, e) = (p(), p());
        let ray = Ray::new(o, e - o);
        out.push(format!("{:?}", w.cast_ray_closest(&ray, &f)));
        out.push(format!("{:?}", w.cast_ray_any(&ray, &f)));
        w.cast_ray_all(&ray, &f, &mut all);
        out.push(format!("{all:?}"));
        let pose = Transform::from_translation(o);
        out.push(format!(
            "{:?}",
            w.cast_shape(&sphere(0.3), &pose, e - o, &f)
        ));
        w.overlap_shape(&cuboid(1.0, 0.5, 1.5), &pose, &f, &mut over)
            .unwrap();
        out.push(format!("{over:?}"));
        w.overlap_aabb(
            &Aabb::new(o - v(2.0, 2.0, 2.0), o + v(2.0, 2.0, 2.0)),
            &f,
            &mut over,
        );
        out.push(format!("{over:?}"));
    }
    out
}

#[test]
fn query_results_do_not_depend_on_the_broad_phase_history() {
    let a = scene();
    let mut b = scene();
    // Move every other body far away and back: its proxy is reinserted, so
    // the trees end up with another shape.
    let handles: Vec<BodyHandle> = b.body_handles().collect();
    for (i, &h) in handles.iter().enumerate().filter(|(i, _)| i % 2 == 0) {
        let pose = b.body(h).unwrap().pose();
        let far = Transform::new(
            pose.translation + v(500.0, (i % 7) as f64 * 40.0, -300.0),
            pose.rotation,
        );
        b.set_pose(h, far).unwrap();
    }
    for &h in handles.iter().step_by(2).rev() {
        let pose = a.body(h).unwrap().pose();
        b.set_pose(h, pose).unwrap();
    }
    assert_eq!(a.state_hash(), b.state_hash());
    assert!(a != b, "the broad phases should differ");
    let (da, db) = (query_digest(&a, 1, 150), query_digest(&b, 1, 150));
    assert_eq!(da, db);
    // The digest is not trivial: some of each query hit something.
    let hits = da.iter().filter(|x| x.contains("collider")).count();
    assert!(hits > 300, "{hits}");
    let (da, db) = (query_digest(&a, 2, 50), query_digest(&b, 2, 50));
    assert_eq!(da, db);
}

#[test]
fn a_thousand_queries_leave_the_state_hash_unchanged() {
    let mut a = scene();
    let mut b = scene();
    for step in 0..5 {
        let before = a.state_hash();
        let digest = query_digest(&a, 3 + step, 1000 / 6 + 1);
        assert!(digest.len() >= 1000);
        assert_eq!(a.state_hash(), before);
        assert_eq!(a.faults(), b.faults());
        a.step();
        b.step();
        assert_eq!(a.state_hash(), b.state_hash());
    }
    assert!(a == b);
}

#[test]
fn world_ray_queries_match_brute_force_over_every_collider() {
    use lockstep_core::query::cast_ray_shape;
    let w = scene();
    let f = QueryFilter::default().triggers(true);
    let mut st = Rng::new(23);
    let mut all = Vec::new();
    let mut hits = 0;
    for _ in 0..300 {
        let mut p = || {
            v(
                lcg(&mut st) * 24.0 - 12.0,
                lcg(&mut st) * 14.0 - 6.0,
                lcg(&mut st) * 24.0 - 12.0,
            )
        };
        let (o, e) = (p(), p());
        let ray = Ray::new(o, e - o);
        let mut brute: Vec<(Scalar, ColliderHandle)> = w
            .colliders()
            .filter_map(|(h, c)| {
                let pose = c.world_pose(&w.body(c.body).unwrap().pose());
                cast_ray_shape(&c.shape, &pose, &ray, Scalar::ONE).map(|x| (x.fraction, h))
            })
            .collect();
        brute.sort_unstable();
        w.cast_ray_all(&ray, &f, &mut all);
        let got: Vec<(Scalar, ColliderHandle)> =
            all.iter().map(|h| (h.fraction, h.collider)).collect();
        assert_eq!(got, brute);
        let closest = w
            .cast_ray_closest(&ray, &f)
            .map(|h| (h.fraction, h.collider));
        assert_eq!(closest, brute.first().copied());
        let any = w.cast_ray_any(&ray, &f).map(|h| h.collider);
        assert_eq!(any, brute.iter().map(|x| x.1).min());
        hits += brute.len();
    }
    assert!(hits > 150, "{hits}");
}

#[test]
fn overlaps_and_box_sweeps_against_a_height_field() {
    let (w, field) = one(Vec3::ZERO, ramp(9));
    let mut out = Vec::new();
    let f = QueryFilter::default();
    // Above (0.3, −0.4) the surface is at 2.15; a ball of radius 0.5 touches
    // it with its centre 0.5·√1.25 higher (the plane's slope is 0.5).
    let above = |y: f64| Transform::from_translation(v(0.3, y, -0.4));
    let reach = 0.5 * 1.25f64.sqrt();
    w.overlap_shape(&sphere(0.5), &above(2.15 + reach - 1e-4), &f, &mut out)
        .unwrap();
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].collider, field);
    w.overlap_shape(&sphere(0.5), &above(2.15 + reach + 1e-4), &f, &mut out)
        .unwrap();
    assert!(out.is_empty());
    // A unit cube dropped onto the ramp lands on its uphill bottom edge: its
    // centre stops where the corner (x + 0.5, y − 0.5) meets y = 0.5 x + 2.
    let h = w
        .cast_shape(&cuboid(0.5, 0.5, 0.5), &above(10.0), v(0.0, -20.0, 0.0), &f)
        .unwrap()
        .unwrap();
    let y = 0.5 * (0.3 + 0.5) + 2.0 + 0.5;
    let short = ((10.0 - y) / 20.0 - h.fraction.to_f64()) * 20.0;
    let cos = 1.0 / 1.25f64.sqrt();
    assert!(
        (-1e-8..=SWEEP_TOLERANCE.to_f64() / cos).contains(&short),
        "{short}"
    );
    assert!(!h.initially_overlapping);
}

/// A random convex shape of size 0.2–1.2 m: sphere, capsule, box or hull.
fn random_convex(rng: &mut Rng) -> Shape {
    let mut r = |lo: f64, hi: f64| lo + (hi - lo) * lcg(rng);
    match (r(0.0, 4.0)) as u32 {
        0 => sphere(r(0.2, 1.0)),
        1 => Shape::Capsule(Capsule::new(s(r(0.1, 0.8)), s(r(0.1, 0.5))).unwrap()),
        2 => cuboid(r(0.1, 0.8), r(0.1, 0.8), r(0.1, 0.8)),
        _ => {
            let points: Vec<Vec3> = (0..8)
                .map(|_| v(r(-0.8, 0.8), r(-0.8, 0.8), r(-0.8, 0.8)))
                .collect();
            ConvexHull::from_points(&points)
                .map(Shape::from)
                .unwrap_or_else(|_| cuboid(0.5, 0.5, 0.5))
        }
    }
}

fn random_rotation(rng: &mut Rng) -> Quat {
    let axis = v(lcg(rng) - 0.5, lcg(rng) - 0.5, lcg(rng) - 0.5)
        .try_normalize()
        .unwrap_or(Vec3::Y);
    Quat::from_axis_angle(axis, s(lcg(rng) * std::f64::consts::TAU)).normalize()
}

/// Seeded shapes and motions: a sweep's fraction is never one at which the
/// moving shape overlaps what it hit (nor anything else), and a shape that
/// starts clear of everything is never reported as starting in contact.
#[test]
fn a_sweep_never_returns_an_overlapping_fraction() {
    let mut rng = Rng::new(0x5eed);
    let (mut hits, mut cases) = (0, 0);
    for _ in 0..200 {
        let mut w = world();
        for _ in 0..6 {
            let at = v(
                lcg(&mut rng) * 8.0 - 4.0,
                lcg(&mut rng) * 8.0 - 4.0,
                lcg(&mut rng) * 8.0 - 4.0,
            );
            let rot = random_rotation(&mut rng);
            let shape = random_convex(&mut rng);
            fixed(&mut w, at, rot, shape);
        }
        let mut out = Vec::new();
        for _ in 0..40 {
            let shape = random_convex(&mut rng);
            let pose = Transform::new(
                v(
                    lcg(&mut rng) * 16.0 - 8.0,
                    lcg(&mut rng) * 16.0 - 8.0,
                    lcg(&mut rng) * 16.0 - 8.0,
                ),
                random_rotation(&mut rng),
            );
            w.overlap_shape(&shape, &pose, &QueryFilter::default(), &mut out)
                .unwrap();
            if !out.is_empty() {
                continue;
            }
            cases += 1;
            // Aim near the middle of the targets, with some spread.
            let aim = v(
                lcg(&mut rng) * 6.0 - 3.0,
                lcg(&mut rng) * 6.0 - 3.0,
                lcg(&mut rng) * 6.0 - 3.0,
            );
            let d = (aim - pose.translation) * s(1.0 + lcg(&mut rng));
            let Some(h) = w
                .cast_shape(&shape, &pose, d, &QueryFilter::default())
                .unwrap()
            else {
                continue;
            };
            hits += 1;
            assert!(!h.initially_overlapping, "started clear: {h:?}");
            let at = Transform::new(pose.translation + d * h.fraction, pose.rotation);
            w.overlap_shape(&shape, &at, &QueryFilter::default(), &mut out)
                .unwrap();
            assert!(
                out.is_empty(),
                "{:?} swept by {d:?} from {pose:?} overlaps {out:?} at fraction {}",
                shape.kind(),
                h.fraction
            );
        }
    }
    assert!(cases > 4000 && hits > 1000, "{cases} cases, {hits} hits");
}

/// A box resting within the sweep tolerance of the floor is stopped only
/// when it moves into the floor: sliding along it or lifting off is free
/// (what move-and-slide needs), and pressing down is a hit at fraction 0.
#[test]
fn a_shape_resting_on_the_floor_is_hit_only_when_it_presses_in() {
    let (w, ground) = one(v(0.0, -1.0, 0.0), cuboid(10.0, 1.0, 10.0));
    let box_ = cuboid(0.5, 0.5, 0.5);
    let rest = v(0.0, 0.5, 0.0) + Vec3::Y * SWEEP_TOLERANCE.half().half();
    assert!(sweep(&w, &box_, rest, v(3.0, 0.0, 0.0)).is_none());
    assert!(sweep(&w, &box_, rest, v(0.0, 2.0, 0.0)).is_none());
    assert!(sweep(&w, &box_, rest, v(2.0, 1.0, -1.0)).is_none());
    let h = sweep(&w, &box_, rest, v(1.0, -1.0, 0.0)).unwrap();
    assert_eq!(h.collider, ground);
    assert_eq!(h.fraction, Scalar::ZERO);
    assert!(!h.initially_overlapping);
    assert_eq!(h.normal, Vec3::Y);
}
