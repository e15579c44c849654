//! Tests of GJK, EPA and the hull contacts against independent f64
//! references (brute force over features, SAT over every candidate axis).

use super::super::epa::{Penetration, penetration};
use super::super::gjk::{DistanceResult, SupportShape, distance};
use super::*;
use crate::math::{Quat, Scalar, Transform, Vec3};
use crate::shape::{Capsule, ConvexHull, Cuboid, Sphere};
use crate::testing::{Rng, s, v as v3};

type V = [f64; 3];

fn f(v: Vec3) -> V {
    [v.x.to_f64(), v.y.to_f64(), v.z.to_f64()]
}
fn add(a: V, b: V) -> V {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn mul(a: V, k: f64) -> V {
    [a[0] * k, a[1] * k, a[2] * k]
}
fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V, b: V) -> V {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn len(a: V) -> f64 {
    dot(a, a).sqrt()
}
fn unit(a: V) -> V {
    mul(a, 1.0 / len(a))
}

/// Poses and rotations for the property tests, from the workspace's one
/// seeded test generator.
trait Draw {
    fn quat(&mut self) -> Quat;
    fn pose(&mut self, spread: f64) -> Transform;
}
impl Draw for Rng {
    fn quat(&mut self) -> Quat {
        loop {
            let q = [0; 4].map(|_| self.uniform(-1.0, 1.0));
            let n = q.iter().map(|c| c * c).sum::<f64>();
            if n > 0.05 && n <= 1.0 {
                return Quat::from_xyzw(s(q[0]), s(q[1]), s(q[2]), s(q[3])).normalize();
            }
        }
    }
    fn pose(&mut self, spread: f64) -> Transform {
        let t = v3(
            self.uniform(-spread, spread),
            self.uniform(-spread, spread),
            self.uniform(-spread, spread),
        );
        Transform::new(t, self.quat())
    }
}

/// A shape in world coordinates, f64: core features plus radius.
struct Ref {
    verts: Vec<V>,
    edges: Vec<[usize; 2]>,
    tris: Vec<[usize; 3]>,
    /// Outward planes (unit normal, offset) of a solid polytope core.
    planes: Vec<(V, f64)>,
    radius: f64,
}

fn rotate(q: Quat, p: V) -> V {
    let (x, y, z, w) = (q.x.to_f64(), q.y.to_f64(), q.z.to_f64(), q.w.to_f64());
    let n = (x * x + y * y + z * z + w * w).sqrt();
    let (x, y, z, w) = (x / n, y / n, z / n, w / n);
    let u = [x, y, z];
    let t = mul(cross(u, p), 2.0);
    add(add(p, mul(t, w)), cross(u, t))
}

fn world(pose: &Transform, p: V) -> V {
    add(rotate(pose.rotation, p), f(pose.translation))
}

#[derive(Clone)]
enum Sh {
    Sphere(Sphere),
    Capsule(Capsule),
    Box(Cuboid),
    Hull(Box<ConvexHull>),
}

impl Sh {
    fn name(&self) -> &'static str {
        match self {
            Sh::Sphere(_) => "sphere",
            Sh::Capsule(_) => "capsule",
            Sh::Box(_) => "box",
            Sh::Hull(_) => "hull",
        }
    }

    fn reference(&self, pose: &Transform) -> Ref {
        let mut r = Ref {
            verts: vec![],
            edges: vec![],
            tris: vec![],
            planes: vec![],
            radius: 0.0,
        };
        match self {
            Sh::Sphere(x) => {
                r.verts.push(world(pose, [0.0; 3]));
                r.radius = x.radius.to_f64();
            }
            Sh::Capsule(x) => {
                let [a, b] = x.segment();
                r.verts.push(world(pose, f(a)));
                r.verts.push(world(pose, f(b)));
                r.edges.push([0, 1]);
                r.radius = x.radius.to_f64();
            }
            Sh::Box(x) => {
                let h = ConvexHull::from_points(&x.corners()).unwrap();
                return Sh::Hull(Box::new(h)).reference(pose);
            }
            Sh::Hull(h) => {
                r.verts = h.vertices().iter().map(|v| world(pose, f(*v))).collect();
                r.edges = h
                    .edges()
                    .iter()
                    .map(|e| [e[0] as usize, e[1] as usize])
                    .collect();
                for fi in 0..h.faces().len() {
                    let fv = h.face_vertices(fi);
                    for k in 1..fv.len() - 1 {
                        r.tris
                            .push([fv[0] as usize, fv[k] as usize, fv[k + 1] as usize]);
                    }
                    let p = |i: usize| r.verts[fv[i] as usize];
                    let n = unit(cross(sub(p(1), p(0)), sub(p(2), p(0))));
                    r.planes.push((n, dot(n, p(0))));
                }
            }
        }
        r
    }
}

fn closest_on_segment(p: V, a: V, b: V) -> V {
    let ab = sub(b, a);
    let d = dot(ab, ab);
    if d == 0.0 {
        return a;
    }
    let t = (dot(sub(p, a), ab) / d).clamp(0.0, 1.0);
    add(a, mul(ab, t))
}

fn closest_on_triangle(p: V, a: V, b: V, c: V) -> V {
    let n = cross(sub(b, a), sub(c, a));
    let nn = dot(n, n);
    if nn > 0.0 {
        let q = sub(p, mul(n, dot(sub(p, a), n) / nn));
        let inside = [(a, b), (b, c), (c, a)]
            .iter()
            .all(|&(u, v)| dot(cross(sub(v, u), sub(q, u)), n) >= 0.0);
        if inside {
            return q;
        }
    }
    let mut best = closest_on_segment(p, a, b);
    for (u, v) in [(b, c), (c, a)] {
        let x = closest_on_segment(p, u, v);
        if len(sub(x, p)) < len(sub(best, p)) {
            best = x;
        }
    }
    best
}

fn segment_segment(a0: V, a1: V, b0: V, b1: V) -> f64 {
    // Dense enough: minimise over a fine parameter sweep refined by the
    // point–segment closed form (convex in the parameter).
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    let g = |t: f64| {
        let p = add(a0, mul(sub(a1, a0), t));
        len(sub(closest_on_segment(p, b0, b1), p))
    };
    for _ in 0..200 {
        let m1 = lo + (hi - lo) / 3.0;
        let m2 = hi - (hi - lo) / 3.0;
        if g(m1) <= g(m2) {
            hi = m2;
        } else {
            lo = m1;
        }
    }
    g(0.5 * (lo + hi)).min(g(0.0)).min(g(1.0))
}

/// Whether the cores intersect: solid–solid by SAT over every face normal
/// and edge cross product; a segment against a solid by clipping.
fn cores_intersect(a: &Ref, b: &Ref) -> bool {
    let solid = |r: &Ref| !r.planes.is_empty();
    match (solid(a), solid(b)) {
        (true, true) => {
            let mut axes: Vec<V> = a.planes.iter().chain(&b.planes).map(|p| p.0).collect();
            for ea in &a.edges {
                for eb in &b.edges {
                    let c = cross(
                        sub(a.verts[ea[1]], a.verts[ea[0]]),
                        sub(b.verts[eb[1]], b.verts[eb[0]]),
                    );
                    if len(c) > 1e-12 {
                        axes.push(unit(c));
                    }
                }
            }
            axes.iter().all(|&n| {
                let (amin, amax) = proj(a, n);
                let (bmin, bmax) = proj(b, n);
                amax >= bmin && bmax >= amin
            })
        }
        (false, true) => core_in_solid(a, b),
        (true, false) => core_in_solid(b, a),
        (false, false) => false,
    }
}

fn proj(r: &Ref, n: V) -> (f64, f64) {
    r.verts
        .iter()
        .map(|v| dot(*v, n))
        .fold((f64::MAX, f64::MIN), |(lo, hi), x| (lo.min(x), hi.max(x)))
}

fn core_in_solid(core: &Ref, solid: &Ref) -> bool {
    let p0 = core.verts[0];
    let p1 = *core.verts.last().unwrap();
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for &(n, d) in &solid.planes {
        let (d0, d1) = (dot(n, p0) - d, dot(n, p1) - d);
        if d0 > 0.0 && d1 > 0.0 {
            return false;
        }
        if d0 > 0.0 {
            t0 = t0.max(d0 / (d0 - d1));
        } else if d1 > 0.0 {
            t1 = t1.min(d0 / (d0 - d1));
        }
    }
    t0 <= t1
}

/// The exact core distance by brute force over feature pairs (0 when the
/// cores intersect).
fn core_distance(a: &Ref, b: &Ref) -> f64 {
    if cores_intersect(a, b) {
        return 0.0;
    }
    let mut best = f64::MAX;
    for &p in &a.verts {
        for &q in &b.verts {
            best = best.min(len(sub(p, q)));
        }
        for e in &b.edges {
            best = best.min(len(sub(
                closest_on_segment(p, b.verts[e[0]], b.verts[e[1]]),
                p,
            )));
        }
        for t in &b.tris {
            let c = closest_on_triangle(p, b.verts[t[0]], b.verts[t[1]], b.verts[t[2]]);
            best = best.min(len(sub(c, p)));
        }
    }
    for &q in &b.verts {
        for e in &a.edges {
            best = best.min(len(sub(
                closest_on_segment(q, a.verts[e[0]], a.verts[e[1]]),
                q,
            )));
        }
        for t in &a.tris {
            let c = closest_on_triangle(q, a.verts[t[0]], a.verts[t[1]], a.verts[t[2]]);
            best = best.min(len(sub(c, q)));
        }
    }
    for ea in &a.edges {
        for eb in &b.edges {
            best = best.min(segment_segment(
                a.verts[ea[0]],
                a.verts[ea[1]],
                b.verts[eb[0]],
                b.verts[eb[1]],
            ));
        }
    }
    best
}

/// Signed distance of `p` from a shape's surface (exact outside a sphere or
/// capsule; for polytopes the largest plane distance, which is exact inside
/// and on faces).
fn surface_distance(r: &Ref, p: V) -> f64 {
    if r.planes.is_empty() {
        let c = if r.edges.is_empty() {
            r.verts[0]
        } else {
            closest_on_segment(p, r.verts[0], r.verts[1])
        };
        return len(sub(p, c)) - r.radius;
    }
    r.planes
        .iter()
        .map(|&(n, d)| dot(n, p) - d)
        .fold(f64::MIN, f64::max)
}

fn random_hull(rng: &mut Rng, scale: f64) -> ConvexHull {
    loop {
        let pts: Vec<Vec3> = (0..12)
            .map(|_| {
                v3(
                    rng.uniform(-scale, scale),
                    rng.uniform(-scale, scale),
                    rng.uniform(-scale, scale),
                )
            })
            .collect();
        if let Ok(h) = ConvexHull::from_points(&pts) {
            return h;
        }
    }
}

fn random_shape(rng: &mut Rng, kind: usize) -> Sh {
    match kind {
        0 => Sh::Sphere(Sphere::new(s(rng.uniform(0.2, 1.5))).unwrap()),
        1 => Sh::Capsule(Capsule::new(s(rng.uniform(0.0, 1.5)), s(rng.uniform(0.1, 1.0))).unwrap()),
        2 => Sh::Box(
            Cuboid::new(v3(
                rng.uniform(0.1, 2.0),
                rng.uniform(0.1, 2.0),
                rng.uniform(0.1, 2.0),
            ))
            .unwrap(),
        ),
        _ => {
            let scale = rng.uniform(0.3, 2.0);
            Sh::Hull(Box::new(random_hull(rng, scale)))
        }
    }
}

fn dist_of(a: &Sh, pa: &Transform, b: &Sh, pb: &Transform) -> DistanceResult {
    fn inner<A: SupportShape>(a: &A, pa: &Transform, b: &Sh, pb: &Transform) -> DistanceResult {
        match b {
            Sh::Sphere(x) => distance(a, pa, x, pb),
            Sh::Capsule(x) => distance(a, pa, x, pb),
            Sh::Box(x) => distance(a, pa, x, pb),
            Sh::Hull(x) => distance(a, pa, &**x, pb),
        }
    }
    match a {
        Sh::Sphere(x) => inner(x, pa, b, pb),
        Sh::Capsule(x) => inner(x, pa, b, pb),
        Sh::Box(x) => inner(x, pa, b, pb),
        Sh::Hull(x) => inner(&**x, pa, b, pb),
    }
}

fn pen_of(a: &Sh, pa: &Transform, b: &Sh, pb: &Transform) -> Option<Penetration> {
    fn inner<A: SupportShape>(
        a: &A,
        pa: &Transform,
        b: &Sh,
        pb: &Transform,
    ) -> Option<Penetration> {
        match b {
            Sh::Sphere(x) => penetration(a, pa, x, pb),
            Sh::Capsule(x) => penetration(a, pa, x, pb),
            Sh::Box(x) => penetration(a, pa, x, pb),
            Sh::Hull(x) => penetration(a, pa, &**x, pb),
        }
    }
    match a {
        Sh::Sphere(x) => inner(x, pa, b, pb),
        Sh::Capsule(x) => inner(x, pa, b, pb),
        Sh::Box(x) => inner(x, pa, b, pb),
        Sh::Hull(x) => inner(&**x, pa, b, pb),
    }
}

/// Tolerance of GJK distances and witness points against the f64 brute
/// force, metres (measured worst: 4.4e-9).
const DIST_TOL: f64 = 2e-8;

#[test]
fn gjk_distance_matches_brute_force_over_1000_random_poses_per_pair_kind() {
    let mut rng = Rng::new(0x5eed_0001);
    let mut report = String::new();
    for ka in 0..4 {
        for kb in ka..4 {
            let (mut worst, mut separated, mut overlapping) = (0.0f64, 0, 0);
            for _ in 0..1000 {
                let a = random_shape(&mut rng, ka);
                let b = random_shape(&mut rng, kb);
                let pa = rng.pose(3.0);
                let pb = rng.pose(3.0);
                let (ra, rb) = (a.reference(&pa), b.reference(&pb));
                let want = core_distance(&ra, &rb) - ra.radius - rb.radius;
                match dist_of(&a, &pa, &b, &pb) {
                    DistanceResult::Separated {
                        distance,
                        point_a,
                        point_b,
                        normal,
                        converged,
                    } => {
                        separated += 1;
                        assert!(converged, "{} {}", a.name(), b.name());
                        let err = (distance.to_f64() - want).abs();
                        worst = worst.max(err);
                        assert!(
                            err <= DIST_TOL,
                            "{}-{}: {distance} vs {want}",
                            a.name(),
                            b.name()
                        );
                        // Witnesses: on the surfaces, the right way apart.
                        let (qa, qb) = (f(point_a), f(point_b));
                        assert!(surface_distance(&ra, qa).abs() <= DIST_TOL);
                        assert!(surface_distance(&rb, qb).abs() <= DIST_TOL);
                        assert!((len(sub(qb, qa)) - want).abs() <= DIST_TOL);
                        assert!((dot(sub(qb, qa), f(normal)) - want).abs() <= DIST_TOL);
                    }
                    DistanceResult::Overlapping => {
                        overlapping += 1;
                        assert!(
                            want <= DIST_TOL,
                            "{}-{}: overlap but {want}",
                            a.name(),
                            b.name()
                        );
                    }
                }
            }
            report += &format!(
                "{}-{}: {separated} separated, {overlapping} overlapping, worst {worst:.2e} m\n",
                ["sphere", "capsule", "box", "hull"][ka],
                ["sphere", "capsule", "box", "hull"][kb]
            );
            assert!(separated >= 100 && overlapping >= 50, "{report}");
        }
    }
    eprintln!("{report}");
}

/// Penetration depth over every candidate axis (faces of both, edge cross
/// products), f64: the minimum translation distance of two polytopes, and
/// its axis (A to B).
fn sat_depth(a: &Ref, b: &Ref) -> (f64, V) {
    let mut axes: Vec<V> = a.planes.iter().chain(&b.planes).map(|p| p.0).collect();
    for ea in &a.edges {
        for eb in &b.edges {
            let c = cross(
                sub(a.verts[ea[1]], a.verts[ea[0]]),
                sub(b.verts[eb[1]], b.verts[eb[0]]),
            );
            if len(c) > 1e-9 {
                axes.push(unit(c));
            }
        }
    }
    let mut best = (f64::MAX, [0.0; 3]);
    for n in axes {
        for n in [n, mul(n, -1.0)] {
            let (_, amax) = proj(a, n);
            let (bmin, _) = proj(b, n);
            let overlap = amax - bmin;
            if overlap < best.0 {
                best = (overlap, n);
            }
        }
    }
    best
}

#[test]
fn epa_depth_and_normal_match_f64_sat_for_deep_box_box_and_hull_hull() {
    let mut rng = Rng::new(0x5eed_0002);
    let (mut worst_depth, mut worst_angle, mut n) = (0.0f64, 0.0f64, 0);
    for i in 0..600 {
        let (a, b) = if i % 2 == 0 {
            (random_shape(&mut rng, 2), random_shape(&mut rng, 2))
        } else {
            (random_shape(&mut rng, 3), random_shape(&mut rng, 3))
        };
        let pa = rng.pose(0.4);
        let pb = rng.pose(0.4);
        let (ra, rb) = (a.reference(&pa), b.reference(&pb));
        let (want, axis) = sat_depth(&ra, &rb);
        if want < 0.05 {
            continue;
        }
        let p = pen_of(&a, &pa, &b, &pb).expect("deep overlap");
        assert!(p.complete);
        let err = (p.depth.to_f64() - want).abs();
        worst_depth = worst_depth.max(err);
        assert!(err <= 1e-5, "{} depth {} vs {want}", a.name(), p.depth);
        // The normal achieves the same overlap (it may differ from `axis`
        // only when two axes tie).
        let nn = f(p.normal);
        let (_, amax) = proj(&ra, nn);
        let (bmin, _) = proj(&rb, nn);
        assert!((amax - bmin - want).abs() <= 1e-5);
        worst_angle = worst_angle.max(1.0 - dot(nn, axis));
        // The witnesses are `depth` apart along the normal.
        let w = sub(f(p.point_a), f(p.point_b));
        assert!((dot(w, nn) - p.depth.to_f64()).abs() <= 1e-5);
        n += 1;
    }
    assert!(n >= 400, "{n} deep cases");
    eprintln!(
        "EPA: {n} deep cases, worst depth error {worst_depth:.2e} m, worst 1-cos {worst_angle:.2e}"
    );
}

fn hull_of(points: &[Vec3]) -> ConvexHull {
    ConvexHull::from_points(points).unwrap()
}

fn cube_hull(h: Vec3) -> ConvexHull {
    hull_of(&Cuboid::new(h).unwrap().corners())
}

fn slab_floor() -> ConvexHull {
    // Top face at y = 0, 10 m wide.
    hull_of(&[
        v3(-5.0, -1.0, -5.0),
        v3(5.0, -1.0, -5.0),
        v3(-5.0, -1.0, 5.0),
        v3(5.0, -1.0, 5.0),
        v3(-5.0, 0.0, -5.0),
        v3(5.0, 0.0, -5.0),
        v3(-5.0, 0.0, 5.0),
        v3(5.0, 0.0, 5.0),
    ])
}

#[test]
fn box_resting_on_a_hull_floor_gets_four_points_at_the_placed_depth() {
    let floor = slab_floor();
    let cube = Cuboid::new(Vec3::splat(Scalar::HALF)).unwrap();
    let y = Scalar::from_ratio(49, 100);
    let pose_box = Transform::from_translation(Vec3::new(Scalar::ZERO, y, Scalar::ZERO));
    let mut m = Manifold::EMPTY;
    assert!(contact_box_hull(
        &cube,
        &pose_box,
        &floor,
        &Transform::IDENTITY,
        Scalar::ZERO,
        &mut m
    ));
    assert_eq!(m.count, 4);
    assert_eq!(m.normal, -Vec3::Y);
    let depth = Scalar::HALF - y;
    for p in m.points() {
        assert_eq!(p.depth, depth);
        assert_eq!(p.point.y, -depth.half());
        assert_eq!(p.point.x.abs(), Scalar::HALF);
        assert_eq!(p.point.z.abs(), Scalar::HALF);
    }
    // The same cube as a hull on the floor: identical manifold.
    let hull_cube = cube_hull(Vec3::splat(Scalar::HALF));
    let mut mh = Manifold::EMPTY;
    assert!(contact_hull_hull(
        &hull_cube,
        &pose_box,
        &floor,
        &Transform::IDENTITY,
        Scalar::ZERO,
        &mut mh
    ));
    assert_eq!(mh.normal, m.normal);
    assert_eq!(mh.count, 4);
    for (p, q) in m.points().iter().zip(mh.points()) {
        assert_eq!(p.depth, q.depth);
    }
    // Exactly touching: four points of zero depth; lifted by 1 mm with a
    // 2 mm margin: four speculative points at −1 mm; beyond: none.
    let touch = Transform::from_translation(Vec3::new(Scalar::ZERO, Scalar::HALF, Scalar::ZERO));
    assert!(contact_box_hull(
        &cube,
        &touch,
        &floor,
        &Transform::IDENTITY,
        Scalar::ZERO,
        &mut m
    ));
    assert_eq!(m.count, 4);
    assert!(m.points().iter().all(|p| p.depth == Scalar::ZERO));
    let mm = Scalar::from_ratio(1, 1000);
    let lifted =
        Transform::from_translation(Vec3::new(Scalar::ZERO, Scalar::HALF + mm, Scalar::ZERO));
    assert!(contact_box_hull(
        &cube,
        &lifted,
        &floor,
        &Transform::IDENTITY,
        mm + mm,
        &mut m
    ));
    assert_eq!(m.count, 4);
    assert!(m.points().iter().all(|p| p.depth == -mm));
    assert!(!contact_box_hull(
        &cube,
        &lifted,
        &floor,
        &Transform::IDENTITY,
        mm.half(),
        &mut m
    ));
    assert!(m.is_empty());
}

#[test]
fn cube_hull_on_box_matches_the_analytic_box_case_rotated_45_degrees() {
    // A unit cube hull turned 45° about y, sunk 0.1 into a box whose top is
    // at y = 0: face contact, normal −y from the hull (A) to the box... the
    // hull ranks after the box, so A is the box: normal +y, depth 0.1.
    let floor = Cuboid::new(v3(3.0, 0.5, 3.0)).unwrap();
    let floor_pose = Transform::from_translation(v3(0.0, -0.5, 0.0));
    let cube = cube_hull(Vec3::splat(Scalar::HALF));
    let q = Quat::from_axis_angle(Vec3::Y, Scalar::FRAC_PI_2.half());
    let pose = Transform::new(v3(0.25, 0.4, -0.5), q);
    let mut m = Manifold::EMPTY;
    assert!(contact_box_hull(
        &floor,
        &floor_pose,
        &cube,
        &pose,
        Scalar::ZERO,
        &mut m
    ));
    assert_eq!(m.count, 4);
    assert!((f(m.normal)[1] - 1.0).abs() < 1e-9);
    let half_diag = 0.5f64.sqrt();
    for p in m.points() {
        assert!((p.depth.to_f64() - 0.1).abs() < 1e-8, "{}", p.depth);
        let c = f(p.point);
        let r = ((c[0] - 0.25).powi(2) + (c[2] + 0.5).powi(2)).sqrt();
        assert!((r - half_diag).abs() < 1e-6, "corner at {c:?}");
        assert!((c[1] + 0.05).abs() < 1e-8);
    }
    // Edge on edge: two cubes crossed at 90° about the contact normal,
    // each turned 45° so an edge points down/up.
    let qa = Quat::from_axis_angle(Vec3::Z, Scalar::FRAC_PI_2.half());
    let qb = Quat::from_axis_angle(Vec3::X, Scalar::FRAC_PI_2.half());
    let gap = 2.0 * 0.5f64.sqrt() - 0.02; // 2 cm overlap
    let pa = Transform::new(Vec3::ZERO, qa);
    let pb = Transform::new(v3(0.0, gap, 0.0), qb);
    let boxa = Cuboid::new(Vec3::splat(Scalar::HALF)).unwrap();
    assert!(contact_box_hull(
        &boxa,
        &pa,
        &cube,
        &pb,
        Scalar::ZERO,
        &mut m
    ));
    assert_eq!(m.count, 1);
    assert!((f(m.normal)[1] - 1.0).abs() < 1e-8, "{:?}", m.normal);
    assert!(
        (m.points[0].depth.to_f64() - 0.02).abs() < 1e-7,
        "{}",
        m.points[0].depth
    );
    let c = f(m.points[0].point);
    assert!(c[0].abs() < 1e-7 && c[2].abs() < 1e-7 && (c[1] - (0.5f64.sqrt() - 0.01)).abs() < 1e-7);
}

fn contact_of(a: &Sh, pa: &Transform, b: &Sh, pb: &Transform, margin: Scalar) -> Manifold {
    let mut m = Manifold::EMPTY;
    match (a, b) {
        (Sh::Sphere(x), Sh::Hull(y)) => contact_sphere_hull(x, pa, y, pb, margin, &mut m),
        (Sh::Capsule(x), Sh::Hull(y)) => contact_capsule_hull(x, pa, y, pb, margin, &mut m),
        (Sh::Box(x), Sh::Hull(y)) => contact_box_hull(x, pa, y, pb, margin, &mut m),
        (Sh::Hull(x), Sh::Hull(y)) => contact_hull_hull(x, pa, y, pb, margin, &mut m),
        _ => unreachable!("pair not handled here"),
    };
    m
}

#[test]
fn hull_contacts_agree_with_the_references_and_lie_on_both_surfaces() {
    let mut rng = Rng::new(0x5eed_0003);
    let margin = s(0.05);
    let mut report = String::new();
    for ka in 0..4 {
        let (mut worst_surface, mut worst_depth, mut hits, mut misses) = (0.0f64, 0.0f64, 0, 0);
        for _ in 0..1000 {
            let a = random_shape(&mut rng, ka);
            let b = random_shape(&mut rng, 3);
            let pa = rng.pose(1.5);
            let pb = rng.pose(1.5);
            let (ra, rb) = (a.reference(&pa), b.reference(&pb));
            let gap = core_distance(&ra, &rb) - ra.radius - rb.radius;
            let m = contact_of(&a, &pa, &b, &pb, margin);
            if m.is_empty() {
                misses += 1;
                assert!(
                    gap > margin.to_f64() - 1e-6,
                    "{}: missed contact at gap {gap}",
                    a.name()
                );
                continue;
            }
            hits += 1;
            let n = f(m.normal);
            assert!((len(n) - 1.0).abs() < 1e-8);
            // Speculative points only within the margin of a real gap.
            if gap > 1e-6 {
                assert!(gap <= margin.to_f64() + 1e-6);
            }
            // True penetration (f64 SAT for polytopes, distance for round
            // cores) bounds every depth from above.
            // (For a point or segment core inside the hull, the SAT axes
            // are the hull's faces and the crosses of the segment with the
            // hull's edges; the radius adds on.)
            let true_depth = if core_distance(&ra, &rb) > 0.0 {
                -gap
            } else {
                sat_depth(&ra, &rb).0 + ra.radius
            };
            for p in m.points() {
                let d = p.depth.to_f64();
                worst_depth = worst_depth.max(d - true_depth);
                // Face axes win over edge axes (and A's faces over B's)
                // unless beaten by 1/1024 m + |separation|/32.
                let pref = if ka == 0 {
                    0.0
                } else {
                    1.0 / 1024.0 + d.abs() / 32.0
                };
                assert!(
                    d <= true_depth + pref + 1e-6,
                    "{}: depth {d} > {true_depth}",
                    a.name()
                );
                let c = f(p.point);
                let on_a = add(c, mul(n, 0.5 * d));
                let on_b = sub(c, mul(n, 0.5 * d));
                let (ea, eb) = (surface_distance(&ra, on_a), surface_distance(&rb, on_b));
                // Round surfaces are exact; a polytope's largest plane
                // distance is exact on its faces and inside.
                // (A polytope's deep-overlap fallback point may lie off
                // A's face polygon: only its B side is pinned.)
                let ea_pinned = if ea > 0.0 && !ra.planes.is_empty() {
                    0.0
                } else {
                    ea.abs()
                };
                worst_surface = worst_surface.max(ea_pinned).max(eb.abs());
                // A capsule's clipped face points sit on its core's sphere
                // of radius r around the clip point: within r·(1 − cos 5.1°)
                // of the surface.
                let slack = if ka == 1 { 0.004 * ra.radius } else { 0.0 };
                assert!(
                    ea.abs() <= 1e-5 + slack || (ea > 0.0 && !ra.planes.is_empty()),
                    "{}: A {ea} depth {d} gap {gap}",
                    a.name()
                );
                assert!(eb.abs() <= 1e-5, "{}: B {eb} depth {d}", a.name());
            }
        }
        report += &format!(
            "{}-hull: {hits} contacts, {misses} apart, worst surface {worst_surface:.2e} m, depth over reference {worst_depth:.2e} m\n",
            ["sphere", "capsule", "box", "hull"][ka]
        );
        assert!(hits >= 200 && misses >= 100, "{report}");
    }
    eprintln!("{report}");
}

#[test]
fn swapping_hulls_flips_the_normal_and_keeps_the_depth() {
    let mut rng = Rng::new(0x5eed_0004);
    let mut worst = 0.0f64;
    for _ in 0..500 {
        let a = random_hull(&mut rng, 1.0);
        let b = random_hull(&mut rng, 1.0);
        let pa = rng.pose(0.8);
        let pb = rng.pose(0.8);
        let mut m1 = Manifold::EMPTY;
        let mut m2 = Manifold::EMPTY;
        let h1 = contact_hull_hull(&a, &pa, &b, &pb, Scalar::ZERO, &mut m1);
        let h2 = contact_hull_hull(&b, &pb, &a, &pa, Scalar::ZERO, &mut m2);
        assert_eq!(h1, h2);
        // EPA: flipped normal, same depth.
        let p1 = penetration(&a, &pa, &b, &pb);
        let p2 = penetration(&b, &pb, &a, &pa);
        assert_eq!(p1.is_some(), p2.is_some());
        if let (Some(p1), Some(p2)) = (p1, p2) {
            let e = (p1.depth.to_f64() - p2.depth.to_f64()).abs();
            worst = worst.max(e);
            assert!(e <= 1e-6, "{} vs {}", p1.depth, p2.depth);
            if p1.depth.to_f64() > 1e-3 {
                assert!(dot(f(p1.normal), f(p2.normal)) < -1.0 + 1e-6 || e <= 1e-6);
            }
        }
        if h1 {
            let d1 = m1.points().iter().map(|p| p.depth).max().unwrap();
            let d2 = m2.points().iter().map(|p| p.depth).max().unwrap();
            // Same axis up to the face/edge preference tolerance.
            let tol = 1.0 / 1024.0 + d1.to_f64().abs() / 16.0 + 1e-6;
            assert!((d1.to_f64() - d2.to_f64()).abs() <= tol, "{d1} vs {d2}");
        }
        // GJK distance is symmetric.
        if let (
            DistanceResult::Separated {
                distance: x,
                point_a: xa,
                ..
            },
            DistanceResult::Separated {
                distance: y,
                point_b: yb,
                ..
            },
        ) = (distance(&a, &pa, &b, &pb), distance(&b, &pb, &a, &pa))
        {
            assert!((x.to_f64() - y.to_f64()).abs() <= 1e-7);
            assert!(len(sub(f(xa), f(yb))) <= 1e-3 || (x.to_f64() - y.to_f64()).abs() <= 1e-7);
        }
    }
    eprintln!("swap: worst EPA depth difference {worst:.2e} m");
}

#[test]
fn moving_both_shapes_by_a_large_offset_changes_nothing_but_the_points() {
    let off = Vec3::new(s(10000.5), Scalar::ZERO, s(-7000.25));
    let mut rng = Rng::new(0x5eed_0005);
    let mut checked = 0;
    for i in 0..400 {
        let a = random_shape(&mut rng, i % 4);
        let b = random_shape(&mut rng, 3);
        let pa = rng.pose(1.0);
        let pb = rng.pose(1.0);
        let qa = Transform::new(pa.translation + off, pa.rotation);
        let qb = Transform::new(pb.translation + off, pb.rotation);
        let m1 = contact_of(&a, &pa, &b, &pb, s(0.05));
        let m2 = contact_of(&a, &qa, &b, &qb, s(0.05));
        assert_eq!(m1.count, m2.count);
        assert_eq!(m1.normal, m2.normal);
        for (p, q) in m1.points().iter().zip(m2.points()) {
            assert_eq!(p.depth, q.depth);
            assert_eq!(p.id, q.id);
            assert_eq!(p.point + off, q.point);
        }
        checked += m1.count as usize;
        match (dist_of(&a, &pa, &b, &pb), dist_of(&a, &qa, &b, &qb)) {
            (
                DistanceResult::Separated {
                    distance: d1,
                    point_a: a1,
                    normal: n1,
                    ..
                },
                DistanceResult::Separated {
                    distance: d2,
                    point_a: a2,
                    normal: n2,
                    ..
                },
            ) => {
                assert_eq!((d1, n1, a1 + off), (d2, n2, a2));
            }
            (x, y) => assert_eq!(x, y),
        }
        let (p1, p2) = (pen_of(&a, &pa, &b, &pb), pen_of(&a, &qa, &b, &qb));
        assert_eq!(
            p1.map(|p| (p.depth, p.normal, p.point_a + off)),
            p2.map(|p| (p.depth, p.normal, p.point_a))
        );
    }
    assert!(checked > 200, "{checked}");
}

#[test]
fn touching_and_near_touching_shapes_give_zero_or_the_exact_gap() {
    let cube = Cuboid::new(Vec3::splat(Scalar::HALF)).unwrap();
    let hull = cube_hull(Vec3::splat(Scalar::HALF));
    let at = |x: Scalar| Transform::from_translation(Vec3::new(x, Scalar::ZERO, Scalar::ZERO));
    // Face to face, exactly touching: overlapping (touch counts).
    assert_eq!(
        distance(&cube, &Transform::IDENTITY, &hull, &at(Scalar::ONE)),
        DistanceResult::Overlapping
    );
    let p = penetration(&cube, &Transform::IDENTITY, &hull, &at(Scalar::ONE)).unwrap();
    assert_eq!(p.depth, Scalar::ZERO);
    // 1 µm and 1 ulp·1000 apart: the exact gap.
    for gap in [Scalar::from_ratio(1, 1_000_000), Scalar::from_bits(1000)] {
        match distance(&cube, &Transform::IDENTITY, &hull, &at(Scalar::ONE + gap)) {
            DistanceResult::Separated {
                distance, normal, ..
            } => {
                assert_eq!(distance, gap);
                assert_eq!(normal, Vec3::X);
            }
            r => panic!("{r:?}"),
        }
    }
    // Spheres: closed form.
    let ball = Sphere::new(Scalar::ONE).unwrap();
    match distance(&ball, &Transform::IDENTITY, &ball, &at(Scalar::from_int(3))) {
        DistanceResult::Separated {
            distance,
            point_a,
            point_b,
            ..
        } => {
            assert_eq!(distance, Scalar::ONE);
            assert_eq!(point_a, Vec3::X);
            assert_eq!(point_b, Vec3::X + Vec3::X);
        }
        r => panic!("{r:?}"),
    }
    // A sphere touching a hull face from above, 1 µm away within a 1 mm
    // margin: one point at −1 µm.
    let mut m = Manifold::EMPTY;
    let um = Scalar::from_ratio(1, 1_000_000);
    let pose = Transform::from_translation(Vec3::new(Scalar::ZERO, s(1.5) + um, Scalar::ZERO));
    assert!(contact_sphere_hull(
        &ball,
        &pose,
        &hull,
        &Transform::IDENTITY,
        s(0.001),
        &mut m
    ));
    assert_eq!(m.count, 1);
    assert!((m.points[0].depth.to_f64() + 1e-6).abs() < 1e-9);
    assert!((f(m.normal)[1] + 1.0).abs() < 1e-9);
}

#[test]
fn capsule_lying_on_a_hull_face_gets_two_points() {
    let floor = slab_floor();
    let cap = Capsule::new(Scalar::ONE, s(0.25)).unwrap();
    // Lying along x (turned 90° about z), 1 cm into the floor, then 1 cm
    // above it with a 2 cm margin.
    let q = Quat::from_axis_angle(Vec3::Z, Scalar::FRAC_PI_2);
    for (y, want) in [(0.24, 0.01), (0.26, -0.01)] {
        let pose = Transform::new(v3(0.5, y, 1.0), q);
        let mut m = Manifold::EMPTY;
        assert!(contact_capsule_hull(
            &cap,
            &pose,
            &floor,
            &Transform::IDENTITY,
            s(0.02),
            &mut m
        ));
        assert_eq!(m.count, 2, "at {y}");
        assert!((f(m.normal)[1] + 1.0).abs() < 1e-8);
        let xs: Vec<f64> = m.points().iter().map(|p| f(p.point)[0]).collect();
        assert!((xs[0] - xs[1]).abs() > 1.99, "{xs:?}");
        for p in m.points() {
            assert!((p.depth.to_f64() - want).abs() < 1e-7, "{}", p.depth);
        }
    }
    // Standing upright, 5 cm deep: one point under the bottom cap.
    let pose = Transform::from_translation(v3(0.0, 1.2, 0.0));
    let mut m = Manifold::EMPTY;
    assert!(contact_capsule_hull(
        &cap,
        &pose,
        &floor,
        &Transform::IDENTITY,
        Scalar::ZERO,
        &mut m
    ));
    assert_eq!(m.count, 1);
    assert!((m.points[0].depth.to_f64() - 0.05).abs() < 1e-8);
    // Core inside the floor (deep): SAT face, depth = radius + core depth.
    let pose = Transform::new(v3(0.0, -0.1, 0.0), q);
    assert!(contact_capsule_hull(
        &cap,
        &pose,
        &floor,
        &Transform::IDENTITY,
        Scalar::ZERO,
        &mut m
    ));
    assert_eq!(m.count, 2);
    for p in m.points() {
        assert!((p.depth.to_f64() - 0.35).abs() < 1e-8, "{}", p.depth);
    }
}

#[test]
fn degenerate_inputs_never_panic_and_give_documented_results() {
    let cube = Cuboid::new(Vec3::splat(Scalar::HALF)).unwrap();
    let hull = cube_hull(Vec3::splat(Scalar::HALF));
    let ball = Sphere::new(Scalar::HALF).unwrap();
    let cap = Capsule::new(Scalar::HALF, s(0.1)).unwrap();
    let id = Transform::IDENTITY;
    let mut m = Manifold::EMPTY;
    // Coincident centres.
    assert!(contact_box_hull(
        &cube,
        &id,
        &hull,
        &id,
        Scalar::ZERO,
        &mut m
    ));
    assert_eq!(m.points[0].depth, Scalar::ONE);
    assert_eq!(f(m.normal).iter().map(|c| c.abs()).sum::<f64>(), 1.0);
    assert!(contact_hull_hull(
        &hull,
        &id,
        &hull,
        &id,
        Scalar::ZERO,
        &mut m
    ));
    assert_eq!(m.points[0].depth, Scalar::ONE);
    assert!(contact_sphere_hull(
        &ball,
        &id,
        &hull,
        &id,
        Scalar::ZERO,
        &mut m
    ));
    assert_eq!(m.points[0].depth, Scalar::ONE);
    assert!(contact_capsule_hull(
        &cap,
        &id,
        &hull,
        &id,
        Scalar::ZERO,
        &mut m
    ));
    assert!(m.points().iter().all(|p| p.depth.to_f64() >= 0.6 - 1e-9));
    // Concentric spheres: EPA's documented +y, depth = both radii.
    let p = penetration(&ball, &id, &ball, &id).unwrap();
    assert_eq!((p.depth, p.normal), (Scalar::ONE, Vec3::Y));
    // Capsule cores crossing at a point: depth = both radii.
    let p = penetration(&cap, &id, &cap, &id).unwrap();
    assert_eq!(p.depth, s(0.1) + s(0.1));
    // A thin hull (0.001 ulp-scale slab) and a tiny one, against a box.
    let thin = hull_of(&[
        v3(-1.0, 0.0, -1.0),
        v3(1.0, 0.0, -1.0),
        v3(0.0, 0.0, 1.0),
        v3(0.0, 1e-6, 0.0),
    ]);
    let tiny = cube_hull(Vec3::splat(s(1e-4)));
    let huge = Cuboid::new(Vec3::splat(s(1000.0))).unwrap();
    let mut rng = Rng::new(0x5eed_0006);
    let mut contacts = 0;
    for _ in 0..300 {
        let pa = rng.pose(0.3);
        let pb = rng.pose(0.3);
        for h in [&thin, &tiny] {
            contacts += usize::from(contact_box_hull(&cube, &pa, h, &pb, s(0.01), &mut m));
            contacts += usize::from(contact_hull_hull(h, &pa, h, &pb, s(0.01), &mut m));
            contacts += usize::from(contact_hull_hull(&hull, &pa, h, &pb, s(0.01), &mut m));
            contacts += usize::from(contact_sphere_hull(&ball, &pa, h, &pb, s(0.01), &mut m));
            contacts += usize::from(contact_capsule_hull(&cap, &pa, h, &pb, s(0.01), &mut m));
            contacts += usize::from(contact_box_hull(&huge, &pa, h, &pb, s(0.01), &mut m));
            for p in m.points() {
                assert!(p.depth.to_f64().abs() < 2001.0);
            }
            let _ = distance(h, &pa, h, &pb);
            let _ = penetration(h, &pa, &huge, &pb);
        }
    }
    assert!(contacts > 1000, "{contacts}");
    // The huge box swallowing the tiny hull: depth ≈ 1000 m.
    assert!(contact_box_hull(
        &huge,
        &id,
        &tiny,
        &id,
        Scalar::ZERO,
        &mut m
    ));
    assert!((m.points[0].depth.to_f64() - 1000.0001).abs() < 1e-3);
}

#[test]
fn feature_ids_stay_the_same_under_small_motions() {
    let floor = slab_floor();
    let cube = cube_hull(Vec3::splat(Scalar::HALF));
    let mut rng = Rng::new(0x5eed_0008);
    let q0 = Quat::from_axis_angle(Vec3::Y, s(0.3));
    let base = Transform::new(v3(0.2, 0.49, -0.1), q0);
    let mut m0 = Manifold::EMPTY;
    assert!(contact_hull_hull(
        &cube,
        &base,
        &floor,
        &Transform::IDENTITY,
        s(0.01),
        &mut m0
    ));
    assert_eq!(m0.count, 4);
    let mut ids0: Vec<u32> = m0.points().iter().map(|p| p.id.0).collect();
    ids0.sort_unstable();
    ids0.dedup();
    assert_eq!(ids0.len(), 4, "distinct ids");
    for _ in 0..200 {
        // Up to 1 mm and 1e-4 rad of jitter (a tilt of 1e-4 moves the
        // 10 m floor's far corners by 0.5 mm: within the face preference).
        let d = v3(
            rng.uniform(-1e-3, 1e-3),
            rng.uniform(-1e-3, 1e-3),
            rng.uniform(-1e-3, 1e-3),
        );
        let axis = v3(rng.uniform(-1.0, 1.0), 1.0, rng.uniform(-1.0, 1.0)).normalize_or_zero();
        let q = (Quat::from_axis_angle(axis, s(rng.uniform(-1e-4, 1e-4))) * q0).normalize();
        let pose = Transform::new(base.translation + d, q);
        let mut m = Manifold::EMPTY;
        assert!(contact_hull_hull(
            &cube,
            &pose,
            &floor,
            &Transform::IDENTITY,
            s(0.01),
            &mut m
        ));
        let mut ids: Vec<u32> = m.points().iter().map(|p| p.id.0).collect();
        ids.sort_unstable();
        assert_eq!(ids, ids0);
    }
}

#[test]
fn hulls_beyond_the_sat_buffers_fall_back_to_one_gjk_epa_point() {
    // 200 points on a sphere of radius 1 (golden spiral): a hull well over
    // MAX_SAT_VERTICES.
    let n = 200;
    let pts: Vec<Vec3> = (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - y * y).sqrt();
            let phi = i as f64 * 2.399_963_229_728_653;
            v3(r * phi.cos(), y, r * phi.sin())
        })
        .collect();
    let ball = hull_of(&pts);
    assert!(ball.vertices().len() > MAX_SAT_VERTICES);
    let cube = Cuboid::new(Vec3::splat(Scalar::HALF)).unwrap();
    let pose = Transform::from_translation(v3(0.0, 1.4, 0.0));
    let mut m = Manifold::EMPTY;
    assert!(contact_box_hull(
        &cube,
        &Transform::IDENTITY,
        &ball,
        &pose,
        s(0.01),
        &mut m
    ));
    assert_eq!(m.count, 1);
    assert_eq!(m.points[0].id, FeatureId(u32::MAX));
    // The box top at 0.5, the ball's lowest vertex at 1.4 − 0.995: 0.095
    // deep.
    let want = penetration(&cube, &Transform::IDENTITY, &ball, &pose).unwrap();
    assert_eq!(m.points[0].depth, want.depth);
    assert!((want.depth.to_f64() - 0.095).abs() < 1e-6, "{}", want.depth);
    assert!(f(m.normal)[1] > 0.99);
    // Apart beyond the margin: nothing; within it: one speculative point.
    let far = Transform::from_translation(v3(0.0, 2.1, 0.0));
    assert!(!contact_hull_hull(
        &ball,
        &far,
        &ball,
        &Transform::IDENTITY,
        s(0.01),
        &mut m
    ));
    let near = Transform::from_translation(v3(0.0, 1.995, 0.0));
    assert!(contact_hull_hull(
        &ball,
        &Transform::IDENTITY,
        &ball,
        &near,
        s(0.01),
        &mut m
    ));
    assert_eq!(m.count, 1);
    let sh = Sh::Hull(Box::new(ball.clone()));
    let gap = core_distance(&sh.reference(&Transform::IDENTITY), &sh.reference(&near));
    assert!((0.005..0.006).contains(&gap), "{gap}");
    assert!(
        (m.points[0].depth.to_f64() + gap).abs() < 2e-8,
        "{} vs {gap}",
        m.points[0].depth
    );
}

#[test]
fn extreme_sizes_keep_distances_accurate() {
    let mut rng = Rng::new(0x5eed_0009);
    let mut worst = [0.0f64; 2];
    for (k, (size, spread)) in [(5000.0, 4000.0), (1e-3, 2e-3)].into_iter().enumerate() {
        for _ in 0..300 {
            let a = Sh::Box(Cuboid::new(Vec3::splat(s(size * rng.uniform(0.2, 1.0)))).unwrap());
            let pts: Vec<Vec3> = (0..10)
                .map(|_| {
                    v3(
                        rng.uniform(-size, size),
                        rng.uniform(-size, size),
                        rng.uniform(-size, size),
                    )
                })
                .collect();
            let Ok(h) = ConvexHull::from_points(&pts) else {
                continue;
            };
            let b = Sh::Hull(Box::new(h));
            let pa = rng.pose(spread);
            let pb = rng.pose(spread);
            let want = core_distance(&a.reference(&pa), &b.reference(&pb));
            match dist_of(&a, &pa, &b, &pb) {
                DistanceResult::Separated { distance, .. } => {
                    let err = (distance.to_f64() - want).abs();
                    worst[k] = worst[k].max(err);
                    // Relative to the size for kilometre shapes (the f64
                    // reference and the rotation's 2⁻³⁰ both scale).
                    assert!(
                        err <= 2e-8 + size * 1e-8,
                        "{distance} vs {want} at size {size}"
                    );
                }
                DistanceResult::Overlapping => assert!(want <= 2e-8 + size * 1e-8),
            }
        }
    }
    eprintln!(
        "km shapes: worst {:.2e} m; mm shapes: worst {:.2e} m",
        worst[0], worst[1]
    );
}
