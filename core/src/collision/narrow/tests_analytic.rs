//! Tests of the sphere and capsule pairs, the dispatcher, and the shared
//! properties of every analytic pair (translation invariance, symmetry under
//! swapping, agreement with f64 closed forms, points on both surfaces),
//! plus the helpers the box tests share.

use super::super::manifold::FeatureId;
use super::shared::sat_tolerance;
use super::*;
use crate::math::{Quat, Vec3};
use crate::shape::{Capsule, Cuboid, Sphere};

pub(super) use crate::testing::{s, v};

pub(super) fn f(x: Scalar) -> f64 {
    x.to_f64()
}

pub(super) type V = [f64; 3];

pub(super) fn vf(p: Vec3) -> V {
    [f(p.x), f(p.y), f(p.z)]
}

pub(super) fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(super) fn add(a: V, b: V) -> V {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub(super) fn scale(a: V, k: f64) -> V {
    [a[0] * k, a[1] * k, a[2] * k]
}

pub(super) fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(super) fn norm(a: V) -> f64 {
    dot(a, a).sqrt()
}

/// The rotation matrix columns of a pose, in f64 (independent of the
/// fixed-point rotate).
pub(super) fn axes_f64(pose: &Transform) -> [V; 3] {
    let q = pose.rotation;
    let (x, y, z, w) = (f(q.x), f(q.y), f(q.z), f(q.w));
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y + w * z),
            2.0 * (x * z - w * y),
        ],
        [
            2.0 * (x * y - w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z + w * x),
        ],
        [
            2.0 * (x * z + w * y),
            2.0 * (y * z - w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// A world point in the pose's local frame, f64.
pub(super) fn to_local(pose: &Transform, p: V) -> V {
    let d = sub(p, vf(pose.translation));
    let ax = axes_f64(pose);
    [dot(d, ax[0]), dot(d, ax[1]), dot(d, ax[2])]
}

pub(super) fn to_world(pose: &Transform, p: V) -> V {
    let ax = axes_f64(pose);
    add(
        vf(pose.translation),
        add(
            add(scale(ax[0], p[0]), scale(ax[1], p[1])),
            scale(ax[2], p[2]),
        ),
    )
}

/// The workspace's test generator, re-exported for the narrow-phase tests.
pub(super) use crate::testing::Rng;

/// Random rotations and poses drawn from the test generator.
pub(super) trait DrawPose {
    /// A rotation about a random axis by a random angle.
    fn quat(&mut self) -> Quat;
    /// A pose within `spread` of the origin, random rotation.
    fn pose(&mut self, spread: f64) -> Transform;
}

impl DrawPose for Rng {
    fn quat(&mut self) -> Quat {
        let axis = v(
            self.uniform(-1.0, 1.0),
            self.uniform(-1.0, 1.0),
            self.uniform(-1.0, 1.0),
        );
        let axis = axis.try_normalize().unwrap_or(Vec3::X);
        Quat::from_axis_angle(axis, s(self.uniform(-3.2, 3.2))).normalize()
    }
    fn pose(&mut self, spread: f64) -> Transform {
        let t = v(
            self.uniform(-spread, spread),
            self.uniform(-spread, spread),
            self.uniform(-spread, spread),
        );
        Transform::new(t, self.quat())
    }
}

pub(super) fn rot(axis: Vec3, degrees: i64) -> Quat {
    Quat::from_axis_angle(axis, Scalar::PI * Scalar::from_ratio(degrees, 180)).normalize()
}

pub(super) fn at(x: f64, y: f64, z: f64) -> Transform {
    Transform::from_translation(v(x, y, z))
}

pub(super) fn posed(x: f64, y: f64, z: f64, q: Quat) -> Transform {
    Transform::new(v(x, y, z), q)
}

pub(super) fn run(a: &Shape, pa: &Transform, b: &Shape, pb: &Transform, margin: f64) -> Manifold {
    let mut m = Manifold::EMPTY;
    m.normal = v(9.0, 9.0, 9.0);
    let (hit, faults) = crate::math::FaultScope::run(|| contact(a, pa, b, pb, s(margin), &mut m));
    assert!(faults.is_empty(), "contact raised {faults}");
    assert_eq!(hit, !m.is_empty());
    m
}

pub(super) fn max_depth(m: &Manifold) -> Scalar {
    m.points()
        .iter()
        .map(|p| p.depth)
        .max()
        .unwrap_or(Scalar::MIN)
}

pub(super) fn assert_close(x: Scalar, want: f64, tol: f64, what: &str) {
    assert!(
        (f(x) - want).abs() <= tol,
        "{what}: got {}, want {want}",
        f(x)
    );
}

pub(super) fn assert_vec_close(x: Vec3, want: V, tol: f64, what: &str) {
    let d = norm(sub(vf(x), want));
    assert!(d <= tol, "{what}: got {:?}, want {want:?}", vf(x));
}

pub(super) fn sphere(r: f64) -> Shape {
    Sphere::new(s(r)).unwrap().into()
}

pub(super) fn capsule(half_height: f64, r: f64) -> Shape {
    Capsule::new(s(half_height), s(r)).unwrap().into()
}

pub(super) fn cuboid(x: f64, y: f64, z: f64) -> Shape {
    Cuboid::new(v(x, y, z)).unwrap().into()
}

/// Signed distance from a world point to a shape's surface, f64.
pub(super) fn sdf(shape: &Shape, pose: &Transform, p: V) -> f64 {
    let l = to_local(pose, p);
    match shape {
        Shape::Sphere(b) => norm(l) - f(b.radius),
        Shape::Capsule(c) => {
            let h = f(c.half_height);
            let y = l[1].clamp(-h, h);
            norm(sub(l, [0.0, y, 0.0])) - f(c.radius)
        }
        Shape::Cuboid(b) => {
            let h = vf(b.half_extents);
            let q = [l[0].abs() - h[0], l[1].abs() - h[1], l[2].abs() - h[2]];
            let outside = norm([q[0].max(0.0), q[1].max(0.0), q[2].max(0.0)]);
            outside + q[0].max(q[1]).max(q[2]).min(0.0)
        }
        _ => unreachable!("analytic shapes only"),
    }
}

/// Every point lies within `|depth|/2` (plus `tol`) of both surfaces: the
/// midpoint convention.
pub(super) fn assert_points_on_surfaces(
    a: &Shape,
    pa: &Transform,
    b: &Shape,
    pb: &Transform,
    m: &Manifold,
    tol: f64,
) -> f64 {
    let mut worst: f64 = 0.0;
    for p in m.points() {
        let half = f(p.depth).abs() / 2.0;
        for (shape, pose) in [(a, pa), (b, pb)] {
            let d = sdf(shape, pose, vf(p.point)).abs();
            worst = worst.max(d - half);
            assert!(
                d <= half + tol,
                "point {:?} is {d} from a surface, depth {}",
                vf(p.point),
                f(p.depth)
            );
        }
    }
    worst
}

/// f64 closest distance between two segments (the textbook closed form, with
/// clamping), for the references.
pub(super) fn seg_seg_f64(p1: V, q1: V, p2: V, q2: V) -> f64 {
    let (a, b) = seg_seg_points_f64(p1, q1, p2, q2);
    norm(sub(a, b))
}

/// The closest points of two segments, f64 (as [`seg_seg_f64`]).
pub(super) fn seg_seg_points_f64(p1: V, q1: V, p2: V, q2: V) -> (V, V) {
    let (d1, d2, r) = (sub(q1, p1), sub(q2, p2), sub(p1, p2));
    let (a, e, ff) = (dot(d1, d1), dot(d2, d2), dot(d2, r));
    let (c, b) = (dot(d1, r), dot(d1, d2));
    if a == 0.0 && e == 0.0 {
        return (p1, p2);
    }
    if a == 0.0 {
        let t = (ff / e).clamp(0.0, 1.0);
        return (p1, add(p2, scale(d2, t)));
    }
    if e == 0.0 {
        let sv = (-c / a).clamp(0.0, 1.0);
        return (add(p1, scale(d1, sv)), p2);
    }
    let den = a * e - b * b;
    let mut sv = if den > 1e-14 {
        ((b * ff - c * e) / den).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = (b * sv + ff) / e;
    if t < 0.0 {
        t = 0.0;
        sv = (-c / a).clamp(0.0, 1.0);
    } else if t > 1.0 {
        t = 1.0;
        sv = ((b - c) / a).clamp(0.0, 1.0);
    }
    (add(p1, scale(d1, sv)), add(p2, scale(d2, t)))
}

/// A capsule's core segment in world coordinates, f64.
pub(super) fn core_f64(c: &Capsule, pose: &Transform) -> (V, V) {
    let h = f(c.half_height);
    (
        to_world(pose, [0.0, -h, 0.0]),
        to_world(pose, [0.0, h, 0.0]),
    )
}

#[test]
fn sphere_sphere_touching_separated_and_deep() {
    let (a, b) = (sphere(1.0), sphere(0.5));
    // Touching: depth exactly 0, point on the contact.
    let m = run(&a, &at(0.0, 0.0, 0.0), &b, &at(1.5, 0.0, 0.0), 0.0);
    assert_eq!(
        (m.normal, m.points()[0].depth, m.points()[0].point),
        (Vec3::X, Scalar::ZERO, v(1.0, 0.0, 0.0))
    );
    // Separated by 0.25 within a margin of 0.5: depth −0.25.
    let m = run(&a, &at(0.0, 0.0, 0.0), &b, &at(0.0, 1.75, 0.0), 0.5);
    assert_eq!((m.normal, m.points()[0].depth), (Vec3::Y, s(-0.25)));
    assert_eq!(m.points()[0].point, v(0.0, 1.125, 0.0));
    // Beyond the margin: nothing.
    assert!(run(&a, &at(0.0, 0.0, 0.0), &b, &at(0.0, 1.75, 0.0), 0.125).is_empty());
    // Deep overlap along −z.
    let m = run(&a, &at(0.0, 0.0, 0.0), &b, &at(0.0, 0.0, -0.5), 0.0);
    assert_eq!((m.normal, m.points()[0].depth), (-Vec3::Z, s(1.0)));
    // Coincident centres: A's +y, rotated with A (90° about z: world −x).
    let pa = posed(3.0, 0.0, 0.0, rot(Vec3::Z, 90));
    let m = run(&a, &pa, &b, &at(3.0, 0.0, 0.0), 0.0);
    assert_vec_close(m.normal, [-1.0, 0.0, 0.0], 1e-9, "fallback normal");
    assert_eq!(m.points()[0].depth, s(1.5));
}

#[test]
fn sphere_capsule_side_end_and_rotated() {
    let (a, b) = (sphere(0.5), capsule(1.0, 0.25));
    // Beside the capsule's side: normal −x (from the sphere toward the capsule axis).
    let m = run(&a, &at(0.625, 0.5, 0.0), &b, &at(0.0, 0.0, 0.0), 0.0);
    assert_eq!((m.normal, m.points()[0].depth), (-Vec3::X, s(0.125)));
    assert_eq!(m.points()[0].id, FeatureId::pair(0, 0));
    // Above the top end, exactly touching.
    let m = run(&a, &at(0.0, 1.75, 0.0), &b, &at(0.0, 0.0, 0.0), 0.0);
    assert_eq!(
        (m.normal, m.points()[0].depth, m.points()[0].id),
        (-Vec3::Y, Scalar::ZERO, FeatureId::pair(0, 2))
    );
    // Separated beyond the margin.
    assert!(run(&a, &at(0.0, 1.875, 0.0), &b, &at(0.0, 0.0, 0.0), 0.0625).is_empty());
    // Within the margin.
    let m = run(&a, &at(0.0, 1.875, 0.0), &b, &at(0.0, 0.0, 0.0), 0.25);
    assert_eq!(m.points()[0].depth, s(-0.125));
    // Capsule rotated 90° about z lies along x: the sphere above its middle.
    let m = run(
        &a,
        &at(0.5, 0.5, 0.0),
        &b,
        &posed(0.0, 0.0, 0.0, rot(Vec3::Z, 90)),
        0.0,
    );
    assert_vec_close(m.normal, [0.0, -1.0, 0.0], 1e-9, "normal");
    assert_close(m.points()[0].depth, 0.25, 1e-9, "depth");
    // Rotated 45° about z: the sphere sits on the capsule's axis line at distance 0.75.
    let m = run(
        &a,
        &at(-0.75 * 0.5f64.sqrt(), 0.75 * 0.5f64.sqrt(), 0.0),
        &b,
        &posed(0.0, 0.0, 0.0, rot(Vec3::Z, -45)),
        0.0,
    );
    assert_vec_close(
        m.normal,
        [0.5f64.sqrt(), -(0.5f64.sqrt()), 0.0],
        1e-8,
        "45° normal",
    );
    assert_close(m.points()[0].depth, 0.0, 1e-8, "45° depth");
    // Centre on the axis: perpendicular fallback (A's +y is along the axis, so +x... A's +y made perpendicular).
    let m = run(
        &a,
        &at(0.25, 0.0, 0.0),
        &b,
        &posed(0.0, 0.0, 0.0, rot(Vec3::Z, 90)),
        0.0,
    );
    assert_vec_close(m.normal, [0.0, 1.0, 0.0], 1e-8, "fallback");
    assert_close(m.points()[0].depth, 0.75, 1e-9, "fallback depth");
}

#[test]
fn capsule_capsule_crossed_touching_separated_deep() {
    let (a, b) = (capsule(1.0, 0.25), capsule(1.0, 0.25));
    let across = rot(Vec3::X, 90); // B along z.
    // Crossed at right angles, B 0.5 in front (z) ... and 0.375 in x: depth 0.125.
    let m = run(
        &a,
        &at(0.0, 0.0, 0.0),
        &b,
        &posed(0.375, 0.0, 0.0, across),
        0.0,
    );
    assert_eq!(m.count, 1);
    assert_vec_close(m.normal, [1.0, 0.0, 0.0], 1e-9, "normal");
    assert_close(m.points()[0].depth, 0.125, 1e-9, "depth");
    assert_vec_close(m.points()[0].point, [0.1875, 0.0, 0.0], 1e-9, "point");
    // Touching end to end along y.
    let m = run(&a, &at(0.0, 0.0, 0.0), &b, &at(0.0, 2.5, 0.0), 0.0);
    assert_eq!(
        (m.count, m.normal, m.points()[0].depth),
        (1, Vec3::Y, Scalar::ZERO)
    );
    assert_eq!(m.points()[0].id, FeatureId::pair(2, 1));
    // Separated beyond the margin, and within it.
    assert!(
        run(
            &a,
            &at(0.0, 0.0, 0.0),
            &b,
            &posed(1.0, 0.0, 0.0, across),
            0.25
        )
        .is_empty()
    );
    let m = run(
        &a,
        &at(0.0, 0.0, 0.0),
        &b,
        &posed(1.0, 0.0, 0.0, across),
        0.75,
    );
    assert_close(m.points()[0].depth, -0.5, 1e-9, "speculative depth");
    // Crossing cores: the common perpendicular, oriented toward B.
    let m = run(
        &a,
        &at(0.0, 0.0, 0.0),
        &b,
        &posed(0.0, 0.5, 0.0, rot(Vec3::Y, 30) * across),
        0.0,
    );
    assert_close(m.points()[0].depth, 0.5, 1e-9, "deep");
    assert_close(m.normal.y, 0.0, 1e-8, "perpendicular to A");
    // 45° about x in the yz plane, offset in x: normal x.
    let m = run(
        &a,
        &at(0.0, 0.0, 0.0),
        &b,
        &posed(0.25, 0.0, 0.0, rot(Vec3::X, 45)),
        0.0,
    );
    assert_vec_close(m.normal, [1.0, 0.0, 0.0], 1e-8, "45° normal");
    assert_close(m.points()[0].depth, 0.25, 1e-9, "45° depth");
}

#[test]
fn capsule_lying_on_a_parallel_capsule_gets_two_points() {
    let (a, b) = (capsule(1.0, 0.25), capsule(0.5, 0.25));
    // Both horizontal along x (90° about z), B on top, shifted by 0.75 along x.
    let q = rot(Vec3::Z, 90);
    let m = run(
        &a,
        &posed(0.0, 0.0, 0.0, q),
        &b,
        &posed(0.75, 0.5, 0.0, q),
        0.0,
    );
    assert_eq!(m.count, 2);
    assert_vec_close(m.normal, [0.0, 1.0, 0.0], 1e-9, "normal");
    for p in m.points() {
        assert_close(p.depth, 0.0, 1e-9, "resting depth");
    }
    // Overlap in x is [0.25, 1]; both points at height 0.25.
    let mut xs: Vec<f64> = m.points().iter().map(|p| f(p.point.x)).collect();
    xs.sort_by(f64::total_cmp);
    assert!(
        (xs[0] - 0.25).abs() < 1e-8 && (xs[1] - 1.0).abs() < 1e-8,
        "{xs:?}"
    );
    assert_vec_close(
        m.points()[0].point,
        [m.points()[0].point.x.to_f64(), 0.25, 0.0],
        1e-9,
        "height",
    );
    let ids: Vec<FeatureId> = m.points().iter().map(|p| p.id).collect();
    assert_eq!(ids, [FeatureId::pair(0x10, 0), FeatureId::pair(0x10, 1)]);
    // Tilted by 1°: still two points, depths differ by the tilt.
    let tilted = rot(Vec3::Z, 89);
    let m = run(
        &a,
        &posed(0.0, 0.0, 0.0, q),
        &b,
        &posed(0.75, 0.5, 0.0, tilted),
        0.05,
    );
    assert_eq!(m.count, 2);
    let spread = (f(m.points()[0].depth) - f(m.points()[1].depth)).abs();
    assert!(
        (spread - 0.75 * 1f64.to_radians().tan()).abs() < 1e-3,
        "{spread}"
    );
    // Coaxial and overlapping: the documented fallback (A's +x).
    let m = run(&a, &at(0.0, 0.0, 0.0), &b, &at(0.0, 0.5, 0.0), 0.0);
    assert_eq!(m.normal, Vec3::X);
    assert_eq!(m.count, 2);
    assert_eq!(max_depth(&m), s(0.5));
}

#[test]
fn dispatch_swaps_and_flips_mixed_pairs_exactly() {
    let mut rng = Rng::new(7);
    let shapes = [sphere(0.5), capsule(0.75, 0.3), cuboid(0.5, 0.75, 1.0)];
    let mut hits = 0;
    for _ in 0..300 {
        for i in 0..3 {
            for j in 0..3 {
                if i == j {
                    continue;
                }
                let (pa, pb) = (rng.pose(1.2), rng.pose(1.2));
                let ab = run(&shapes[i], &pa, &shapes[j], &pb, 0.1);
                let ba = run(&shapes[j], &pb, &shapes[i], &pa, 0.1);
                assert_eq!(ab.count, ba.count);
                if !ab.is_empty() {
                    hits += 1;
                    assert_eq!(ab.normal, -ba.normal);
                    assert_eq!(ab.points(), ba.points());
                }
            }
        }
    }
    assert!(hits > 500, "{hits}");
}

#[test]
fn static_only_pairs_report_no_contact_and_convex_mesh_pairs_do() {
    use crate::shape::{HeightField, TriMesh};
    let mesh: Shape = TriMesh::new(
        vec![
            Vec3::ZERO,
            Vec3::from_ints(4, 0, 0),
            Vec3::from_ints(0, 0, 4),
        ],
        vec![[0, 2, 1]],
    )
    .unwrap()
    .into();
    let field: Shape = HeightField::new(2, 2, vec![Scalar::ZERO; 4], Vec3::splat(Scalar::ONE))
        .unwrap()
        .into();
    // Mesh and height field are static-only: such pairs are never created.
    for (a, b) in [
        (&mesh, &mesh),
        (&mesh, &field),
        (&field, &mesh),
        (&field, &field),
    ] {
        assert!(run(a, &Transform::IDENTITY, b, &at(0.5, 0.0, 0.5), 0.1).is_empty());
    }
    // Convex shapes against them go to the mesh contacts (tests_mesh.rs).
    for other in [sphere(1.0), cuboid(1.0, 1.0, 1.0)] {
        let m = run(
            &other,
            &at(0.25, 0.5, 0.25),
            &mesh,
            &Transform::IDENTITY,
            0.1,
        );
        assert_eq!(m.normal, -Vec3::Y);
        assert_close(max_depth(&m), 0.5, 1e-9, "depth on the mesh");
        let m = run(
            &field,
            &Transform::IDENTITY,
            &other,
            &at(0.25, 0.5, 0.25),
            0.1,
        );
        assert_eq!(m.normal, Vec3::Y);
        assert_close(max_depth(&m), 0.5, 1e-9, "depth on the field");
    }
}

/// Every pair kind, for the property tests.
pub(super) fn pair_kinds() -> Vec<(&'static str, Shape, Shape)> {
    vec![
        ("sphere_sphere", sphere(0.5), sphere(0.75)),
        ("sphere_capsule", sphere(0.5), capsule(0.75, 0.3)),
        ("capsule_capsule", capsule(0.6, 0.25), capsule(0.75, 0.3)),
        ("sphere_box", sphere(0.5), cuboid(0.5, 0.75, 1.0)),
        ("capsule_box", capsule(0.75, 0.3), cuboid(0.5, 0.75, 1.0)),
        ("box_box", cuboid(0.5, 0.25, 0.75), cuboid(0.5, 0.75, 1.0)),
    ]
}

#[test]
fn moving_a_pair_by_a_large_offset_moves_points_exactly_and_keeps_normals_and_depths() {
    let offset = v(10000.5, 0.0, -7000.25);
    let mut rng = Rng::new(11);
    for (name, a, b) in pair_kinds() {
        let mut hits = 0;
        for _ in 0..1000 {
            let (pa, pb) = (rng.pose(1.0), rng.pose(1.0));
            let near = run(&a, &pa, &b, &pb, 0.05);
            let shift = |p: &Transform| Transform::new(p.translation + offset, p.rotation);
            let far = run(&a, &shift(&pa), &b, &shift(&pb), 0.05);
            assert_eq!((near.count, near.normal), (far.count, far.normal), "{name}");
            for (x, y) in near.points().iter().zip(far.points()) {
                assert_eq!((x.depth, x.id), (y.depth, y.id), "{name}");
                assert_eq!(x.point + offset, y.point, "{name}");
            }
            hits += !near.is_empty() as u32;
        }
        assert!(hits > 300, "{name}: {hits} contacts");
    }
}

#[test]
fn swapping_same_kind_shapes_flips_the_normal_and_keeps_the_depth() {
    let mut rng = Rng::new(23);
    for (name, a, b) in pair_kinds() {
        let (mut hits, mut feature_switch, mut worst) = (0, 0, 0.0f64);
        for _ in 0..1000 {
            let (pa, pb) = (rng.pose(1.0), rng.pose(1.0));
            let ab = run(&a, &pa, &b, &pb, 0.05);
            let ba = run(&b, &pb, &a, &pa, 0.05);
            if ab.is_empty() || ba.is_empty() {
                // Only a contact at the margin's edge may differ.
                let m = if ab.is_empty() { &ba } else { &ab };
                assert!(m.is_empty() || f(max_depth(m)) < -0.05 + 1e-6, "{name}");
                continue;
            }
            hits += 1;
            let dn = norm(add(vf(ab.normal), vf(ba.normal)));
            let dd = (f(max_depth(&ab)) - f(max_depth(&ba))).abs();
            if dn > 1e-6 || dd > 1e-6 {
                // Box–box prefers A's face over B's within the tolerance, so a
                // near-tie may pick the other box's face after swapping; the
                // depths then still agree within that tolerance.
                assert_eq!(name, "box_box", "normal off by {dn}, depth by {dd}");
                assert!(
                    dd <= f(sat_tolerance(max_depth(&ab))) + 1e-6,
                    "{name}: {dd}"
                );
                feature_switch += 1;
            } else {
                worst = worst.max(dn).max(dd);
            }
        }
        println!(
            "{name}: {hits} contacts, {feature_switch} near-ties chose the other face, worst {worst:e}"
        );
        assert!(hits > 300, "{name}: {hits}");
        assert!(
            feature_switch * 20 <= hits,
            "{name}: {feature_switch} of {hits}"
        );
    }
}

#[test]
fn sphere_and_capsule_pairs_agree_with_the_f64_closed_form() {
    let mut rng = Rng::new(31);
    for (name, a, b) in pair_kinds().into_iter().take(3) {
        let (mut hits, mut worst_depth, mut worst_normal, mut worst_surface) =
            (0, 0.0f64, 0.0f64, 0.0f64);
        for _ in 0..1000 {
            let (pa, pb) = (rng.pose(0.8), rng.pose(0.8));
            let m = run(&a, &pa, &b, &pb, 0.05);
            // Core features (points or segments) and radii.
            let core = |shape: &Shape, pose: &Transform| match shape {
                Shape::Sphere(x) => {
                    let c = vf(pose.translation);
                    (c, c, f(x.radius))
                }
                Shape::Capsule(c) => {
                    let (p, q) = core_f64(c, pose);
                    (p, q, f(c.radius))
                }
                _ => unreachable!(),
            };
            let (p1, q1, ra) = core(&a, &pa);
            let (p2, q2, rb) = core(&b, &pb);
            let dist = seg_seg_f64(p1, q1, p2, q2);
            let want = ra + rb - dist;
            if want < -0.05 - 1e-6 {
                assert!(m.is_empty(), "{name}: contact beyond the margin");
                continue;
            }
            if want < -0.05 + 1e-6 {
                continue;
            }
            assert!(!m.is_empty(), "{name}: missed contact of depth {want}");
            hits += 1;
            let got = f(max_depth(&m));
            if m.count == 1 {
                worst_depth = worst_depth.max((got - want).abs());
                // The normal is the direction between the closest core points.
                let n = vf(m.normal);
                if dist > 1e-3 {
                    let centre_gap = dot(sub(vf(pb.translation), vf(pa.translation)), n);
                    assert!(centre_gap > -1.0, "{name}");
                }
                worst_normal = worst_normal.max((norm(n) - 1.0).abs());
            } else {
                // Parallel capsules: every point's depth is at most the deepest.
                assert!(got <= want + 1e-6, "{name}: {got} > {want}");
                assert!(got >= want - 0.05, "{name}: {got} < {want}");
            }
            worst_surface =
                worst_surface.max(assert_points_on_surfaces(&a, &pa, &b, &pb, &m, 1e-6));
        }
        println!(
            "{name}: {hits} contacts, max |depth − f64| {worst_depth:e}, max |‖n‖−1| {worst_normal:e}, surface excess {worst_surface:e}"
        );
        assert!(worst_depth <= 1e-6, "{name}: {worst_depth}");
        assert!(hits > 300, "{name}: {hits}");
    }
}
