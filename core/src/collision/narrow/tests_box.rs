//! Tests of the box pairs (sphere–box, capsule–box, box–box): hand-built
//! configurations with exact numbers, agreement with f64 references over
//! seeded random poses, a box resting on a ground box, and the timing figure.

use super::super::manifold::FeatureId;
use super::box_box::{BoxAxis, box_sat};
use super::shared::relative_pose;
use super::shared::sat_tolerance;
use super::tests_analytic::*;
use super::*;
use crate::math::Vec3;
use crate::math::{Mat3, Quat};
use crate::shape::Cuboid;

fn ids(m: &Manifold) -> Vec<FeatureId> {
    m.points().iter().map(|p| p.id).collect()
}

fn sorted_points(m: &Manifold) -> Vec<V> {
    let mut p: Vec<V> = m.points().iter().map(|p| vf(p.point)).collect();
    p.sort_by(|a, b| a.partial_cmp(b).unwrap());
    p
}

#[test]
fn sphere_box_face_edge_corner_inside_and_rotated() {
    let (a, b) = (sphere(0.5), cuboid(1.0, 0.5, 2.0));
    let origin = Transform::IDENTITY;
    // Above the +y face, overlapping by 0.125: normal −y (sphere to box).
    let m = run(&a, &at(0.25, 0.875, 0.0), &b, &origin, 0.0);
    assert_eq!((m.normal, m.points()[0].depth), (-Vec3::Y, s(0.125)));
    assert_eq!(m.points()[0].point, v(0.25, 0.4375, 0.0));
    assert_eq!(m.points()[0].id, FeatureId::pair(0, 3));
    // Touching the +x face.
    let m = run(&a, &at(1.5, 0.0, 0.0), &b, &origin, 0.0);
    assert_eq!((m.normal, m.points()[0].depth), (-Vec3::X, Scalar::ZERO));
    // Beyond the margin, then within it.
    assert!(run(&a, &at(0.0, 1.25, 0.0), &b, &origin, 0.125).is_empty());
    let m = run(&a, &at(0.0, 1.25, 0.0), &b, &origin, 0.5);
    assert_eq!(m.points()[0].depth, s(-0.25));
    // Edge region (+x, +y): distance √2·0.25.
    let m = run(&a, &at(1.25, 0.75, 0.0), &b, &origin, 0.0);
    assert_vec_close(
        m.normal,
        [-(0.5f64.sqrt()), -(0.5f64.sqrt()), 0.0],
        1e-9,
        "edge normal",
    );
    assert_close(
        m.points()[0].depth,
        0.5 - 0.125f64.sqrt(),
        1e-9,
        "edge depth",
    );
    assert_eq!(m.points()[0].id, FeatureId::pair(0, 1 + 3));
    // Corner region (−x, +y, −z).
    let m = run(&a, &at(-1.25, 0.75, -2.25), &b, &origin, 0.0);
    assert_close(
        m.points()[0].depth,
        0.5 - 0.1875f64.sqrt(),
        1e-9,
        "corner depth",
    );
    assert_eq!(m.points()[0].id, FeatureId::pair(0, 2 + 3 + 18));
    // Centre inside, nearest face −y (0.125 away): depth r + 0.125.
    let m = run(&a, &at(0.0, -0.375, 0.5), &b, &origin, 0.0);
    assert_eq!((m.normal, m.points()[0].depth), (Vec3::Y, s(0.625)));
    assert_eq!(m.points()[0].id, FeatureId::pair(0, 27 + 3));
    // Box rotated 90° about z: its long x extent is now along y.
    let m = run(
        &a,
        &at(0.0, 1.375, 0.0),
        &b,
        &posed(0.0, 0.0, 0.0, rot(Vec3::Z, 90)),
        0.0,
    );
    assert_vec_close(m.normal, [0.0, -1.0, 0.0], 1e-9, "90° normal");
    assert_close(m.points()[0].depth, 0.125, 1e-9, "90° depth");
    // Box rotated 45° about z: its edge (+x, +y) points up at height √(1.25).
    let top = 1.25f64.sqrt() * (0.5f64.atan2(1.0) + std::f64::consts::FRAC_PI_4).sin();
    let ridge_x = 0.5 * 0.5f64.sqrt();
    let m = run(
        &a,
        &at(ridge_x, top + 0.375, 0.0),
        &b,
        &posed(0.0, 0.0, 0.0, rot(Vec3::Z, 45)),
        0.0,
    );
    assert_vec_close(m.normal, [0.0, -1.0, 0.0], 1e-8, "45° normal");
    assert_close(m.points()[0].depth, 0.125, 1e-8, "45° depth");
}

#[test]
fn capsule_lying_on_a_box_face_gets_two_clipped_points() {
    let (a, b) = (capsule(1.0, 0.25), cuboid(0.5, 0.5, 2.0));
    let along_x = rot(Vec3::Z, 90);
    // Lying along x on the +y face, 0.0625 deep, overhanging both x sides.
    let m = run(
        &a,
        &posed(0.0, 0.6875, 0.5, along_x),
        &b,
        &Transform::IDENTITY,
        0.0,
    );
    assert_eq!(m.count, 2);
    assert_vec_close(m.normal, [0.0, -1.0, 0.0], 1e-9, "normal");
    for p in m.points() {
        assert_close(p.depth, 0.0625, 1e-8, "depth");
    }
    let pts = sorted_points(&m);
    assert_vec_close(
        v(pts[0][0], pts[0][1], pts[0][2]),
        [-0.5, 0.46875, 0.5],
        1e-8,
        "clipped at −x",
    );
    assert_vec_close(
        v(pts[1][0], pts[1][1], pts[1][2]),
        [0.5, 0.46875, 0.5],
        1e-8,
        "clipped at +x",
    );
    assert_eq!(
        ids(&m),
        [FeatureId::pair(0x10, 29), FeatureId::pair(0x11, 29)]
    );
    // Separated by 0.125 within the margin: still two points, depth −0.125.
    let m = run(
        &a,
        &posed(0.0, 0.875, 0.0, along_x),
        &b,
        &Transform::IDENTITY,
        0.25,
    );
    assert_eq!(m.count, 2);
    assert_close(max_depth(&m), -0.125, 1e-8, "speculative");
    assert!(
        run(
            &a,
            &posed(0.0, 0.875, 0.0, along_x),
            &b,
            &Transform::IDENTITY,
            0.0625
        )
        .is_empty()
    );
    // Standing on its end on the +y face: one point at the end, touching.
    let m = run(&a, &at(0.0, 1.75, 0.0), &b, &Transform::IDENTITY, 0.0);
    assert_eq!(
        (m.count, m.normal, m.points()[0].depth),
        (1, -Vec3::Y, Scalar::ZERO)
    );
    assert_eq!(m.points()[0].id, FeatureId::pair(1, 3));
    // Sunk deep with its core inside the box, standing: the SAT face, deepest end.
    let m = run(&a, &at(0.0, 1.25, 0.0), &b, &Transform::IDENTITY, 0.0);
    assert_eq!(m.count, 1);
    assert_eq!((m.normal, m.points()[0].depth), (-Vec3::Y, s(0.5)));
    // Lying along z inside the box's +y half (core 0.25 below the face): SAT face, two points.
    let along_z = rot(Vec3::X, 90);
    let m = run(
        &a,
        &posed(0.0, 0.25, 0.0, along_z),
        &b,
        &Transform::IDENTITY,
        0.0,
    );
    assert_eq!(m.count, 2);
    assert_vec_close(m.normal, [0.0, -1.0, 0.0], 1e-8, "SAT face normal");
    assert_close(max_depth(&m), 0.5, 1e-8, "SAT depth");
}

#[test]
fn capsule_lying_out_past_a_box_edge_rests_on_the_edge_and_the_face() {
    // A thigh on a step: a capsule along z on the +y face of a box whose
    // face ends at z = 0.5, its +z end 5 cm out past that edge, tilted 1°
    // towards it. Its core is above the face everywhere (apart), its far
    // end 1 mm into the face, and the closest feature is the edge. It lies
    // along the face: two points, the face's normal, not the edge alone
    // (on which it rocked).
    let (hh, r) = (0.2, 0.07);
    let (a, b) = (capsule(hh, r), cuboid(1.0, 0.25, 0.5));
    let th = 91f64.to_radians();
    let d = [0.0, th.cos(), th.sin()];
    let yc = 0.25 - 0.001 + r + hh * d[1];
    let zc = 0.35;
    let pose = posed(0.0, yc, zc, rot(Vec3::X, 91));
    let m = run(&a, &pose, &b, &Transform::IDENTITY, 0.02);
    assert_eq!(m.count, 2, "{m:?}");
    assert_vec_close(m.normal, [0.0, -1.0, 0.0], 1e-8, "the face's normal");
    let depth_at = |z: f64| {
        m.points()
            .iter()
            .find(|p| (vf(p.point)[2] - z).abs() < 1e-6)
            .map(|p| p.depth)
    };
    // The far end, 1 mm deep; at the edge, r less the edge's distance
    // from the core (the closest features' separation, exactly).
    let far_z = zc - hh * d[2];
    assert_close(
        depth_at(far_z).expect("far end"),
        0.001,
        1e-6,
        "far end depth",
    );
    let edge_dist = ((0.25 - yc) * d[2] - (0.5 - zc) * d[1]).abs();
    assert_close(
        depth_at(0.5).expect("edge"),
        r - edge_dist,
        1e-6,
        "edge depth",
    );
    // Tilted the other way (the far end lower), the closest point is over
    // the face: the same two points' ids.
    let far = run(
        &a,
        &posed(0.0, yc, zc, rot(Vec3::X, 89)),
        &b,
        &Transform::IDENTITY,
        0.02,
    );
    assert_eq!(ids(&far), ids(&m));
}

#[test]
fn capsule_across_a_box_edge_uses_the_edge_axis() {
    // The box rotated 45° about z has a top edge along z at height √2·0.5.
    // A capsule along x crossing it: the edge × segment axis is y.
    let (a, b) = (capsule(1.0, 0.25), cuboid(0.5, 0.5, 0.5));
    let ridge = 0.5f64.sqrt();
    let m = run(
        &a,
        &posed(0.0, ridge + 0.125, 0.0, rot(Vec3::Z, 90)),
        &b,
        &posed(0.0, 0.0, 0.0, rot(Vec3::Z, 45)),
        0.0,
    );
    assert_eq!(m.count, 1);
    assert_vec_close(m.normal, [0.0, -1.0, 0.0], 1e-8, "edge normal");
    assert_close(m.points()[0].depth, 0.125, 1e-8, "edge depth");
    assert_vec_close(
        m.points()[0].point,
        [0.0, ridge - 0.0625, 0.0],
        1e-8,
        "edge point",
    );
    // Pushed down so the core dips into the box: the SAT chooses the edge cross axis.
    let m = run(
        &a,
        &posed(0.0, ridge - 0.125, 0.0, rot(Vec3::Z, 90)),
        &b,
        &posed(0.0, 0.0, 0.0, rot(Vec3::Z, 45)),
        0.0,
    );
    assert_eq!(m.count, 1);
    assert_vec_close(m.normal, [0.0, -1.0, 0.0], 1e-8, "SAT edge normal");
    assert_close(m.points()[0].depth, 0.375, 1e-8, "SAT edge depth");
}

#[test]
fn box_on_box_coplanar_faces_give_four_points_with_exact_depth() {
    let (a, b) = (cuboid(1.0, 1.0, 1.0), cuboid(0.5, 0.5, 0.5));
    // B sunk 0.125 into A's top face.
    let m = run(&a, &Transform::IDENTITY, &b, &at(0.25, 1.375, -0.25), 0.0);
    assert_eq!((m.count, m.normal), (4, Vec3::Y));
    for p in m.points() {
        assert_eq!(p.depth, s(0.125));
        assert_eq!(p.point.y, s(0.9375));
    }
    assert_eq!(
        sorted_points(&m),
        [
            [-0.25, 0.9375, -0.75],
            [-0.25, 0.9375, 0.25],
            [0.75, 0.9375, -0.75],
            [0.75, 0.9375, 0.25]
        ]
    );
    // Touching: depth exactly zero. Separated by 0.25: −0.25 within a 0.5 margin, none within 0.125.
    let m = run(&a, &Transform::IDENTITY, &b, &at(0.0, 1.5, 0.0), 0.0);
    assert_eq!(m.count, 4);
    assert!(m.points().iter().all(|p| p.depth == Scalar::ZERO));
    let m = run(&a, &Transform::IDENTITY, &b, &at(0.0, 1.75, 0.0), 0.5);
    assert!(m.count == 4 && m.points().iter().all(|p| p.depth == s(-0.25)));
    assert!(run(&a, &Transform::IDENTITY, &b, &at(0.0, 1.75, 0.0), 0.125).is_empty());
    // The smaller box underneath (B below A): normal −y, A's face is still the reference.
    let m = run(&a, &Transform::IDENTITY, &b, &at(0.0, -1.25, 0.0), 0.0);
    assert_eq!((m.count, m.normal), (4, -Vec3::Y));
    assert!(m.points().iter().all(|p| p.depth == s(0.25)));
    // A smaller A on a bigger B: B's face is the reference, normal still A to B.
    let m = run(&b, &at(0.0, 1.375, 0.0), &a, &Transform::IDENTITY, 0.0);
    assert_eq!((m.count, m.normal), (4, -Vec3::Y));
    assert!(m.points().iter().all(|p| p.depth == s(0.125)));
}

#[test]
fn box_on_box_rotated_90_and_45_degrees() {
    let (a, b) = (cuboid(1.0, 1.0, 1.0), cuboid(0.5, 0.25, 0.75));
    // B rotated 90° about y: its 0.75 extent along x; resting 0.125 deep.
    let m = run(
        &a,
        &Transform::IDENTITY,
        &b,
        &posed(0.0, 1.125, 0.0, rot(Vec3::Y, 90)),
        0.0,
    );
    assert_eq!(m.count, 4);
    assert_vec_close(m.normal, [0.0, 1.0, 0.0], 1e-9, "90° normal");
    for p in m.points() {
        assert_close(p.depth, 0.125, 1e-9, "90° depth");
        assert_close(p.point.x.abs(), 0.75, 1e-8, "90° x");
        assert_close(p.point.z.abs(), 0.5, 1e-8, "90° z");
    }
    // B rotated 45° about y: still face down, four points at its corners.
    let m = run(
        &a,
        &Transform::IDENTITY,
        &b,
        &posed(0.0, 1.125, 0.0, rot(Vec3::Y, 45)),
        0.0,
    );
    assert_eq!(m.count, 4);
    assert_vec_close(m.normal, [0.0, 1.0, 0.0], 1e-9, "45° y normal");
    assert!(m.points().iter().all(|p| (f(p.depth) - 0.125).abs() < 1e-9));
    // B rotated 45° about z: an edge down; two points where it meets A's face.
    let low = 0.5
        * (0.5 * 0.5 + 0.25 * 0.25f64).sqrt()
        * 2.0
        * ((0.25f64).atan2(0.5) + std::f64::consts::FRAC_PI_4).sin();
    let m = run(
        &a,
        &Transform::IDENTITY,
        &b,
        &posed(0.0, 1.0 + low - 0.0625, 0.0, rot(Vec3::Z, 45)),
        0.0,
    );
    assert_eq!(m.count, 2);
    assert_vec_close(m.normal, [0.0, 1.0, 0.0], 1e-9, "edge-down normal");
    for p in m.points() {
        assert_close(p.depth, 0.0625, 1e-8, "edge-down depth");
        assert_close(p.point.z.abs(), 0.75, 1e-8, "edge-down z");
    }
}

#[test]
fn box_box_edge_against_edge_gives_one_point_between_the_edges() {
    // A rotated 45° about z: top edge along z at height √2. B rotated 45°
    // about x: bottom edge along x at 2.8 − √2.
    let c = cuboid(1.0, 1.0, 1.0);
    let pa = posed(0.0, 0.0, 0.0, rot(Vec3::Z, 45));
    let pb = posed(0.0, 2.8, 0.0, rot(Vec3::X, 45));
    let m = run(&c, &pa, &c, &pb, 0.0);
    assert_eq!(m.count, 1);
    assert_vec_close(m.normal, [0.0, 1.0, 0.0], 1e-8, "edge normal");
    assert_close(
        m.points()[0].depth,
        2.0 * 2f64.sqrt() - 2.8,
        1e-8,
        "edge depth",
    );
    assert_vec_close(m.points()[0].point, [0.0, 1.4, 0.0], 1e-8, "edge point");
    let id = m.points()[0].id;
    assert_eq!(id.0 >> 16 & 0x100, 0x100);
    // Separated within the margin: same features, negative depth.
    let m = run(&c, &pa, &c, &posed(0.0, 2.9, 0.0, rot(Vec3::X, 45)), 0.1);
    assert_eq!((m.count, m.points()[0].id), (1, id));
    assert_close(
        m.points()[0].depth,
        2.0 * 2f64.sqrt() - 2.9,
        1e-8,
        "speculative edge depth",
    );
    assert!(run(&c, &pa, &c, &posed(0.0, 2.9, 0.0, rot(Vec3::X, 45)), 0.05).is_empty());
}

#[test]
fn box_box_reduces_an_octagon_to_four_points_keeping_the_deepest() {
    // Equal boxes, B turned 22.5° about y and tilted very slightly: the clip
    // is an octagon.
    let c = cuboid(1.0, 1.0, 1.0);
    let q = (rot(Vec3::X, 1) * Quat::from_axis_angle(Vec3::Y, Scalar::PI.div_int(8))).normalize();
    let m = run(&c, &Transform::IDENTITY, &c, &posed(0.0, 1.9, 0.0, q), 0.0);
    assert_eq!(m.count, 4);
    // B's bottom face beats A's top face by more than the tolerance here, so
    // it is the reference: the normal is B's tilted axis.
    let one = 1f64.to_radians();
    assert_vec_close(m.normal, [0.0, one.cos(), one.sin()], 1e-9, "normal");
    // The deepest clipped vertex survives the reduction: the SAT depth.
    let (t, qr) = relative_pose(&Transform::IDENTITY, &posed(0.0, 1.9, 0.0, q));
    let sat = box_sat(v(1.0, 1.0, 1.0), v(1.0, 1.0, 1.0), &Mat3::from_quat(qr), t);
    assert_eq!(sat.chosen, BoxAxis::FaceB(1));
    let deepest = f(max_depth(&m));
    assert!(
        deepest > 0.1 && deepest <= -f(sat.separation) + 1e-9,
        "{deepest}"
    );
    // The four points span a large part of the octagon (area over 2).
    let p = sorted_points(&m);
    let area = |a: V, b: V, c: V| {
        ((b[0] - a[0]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[0] - a[0])).abs() / 2.0
    };
    let hull_area = area(p[0], p[1], p[2]).max(area(p[0], p[1], p[3]))
        + area(p[0], p[2], p[3]).min(area(p[1], p[2], p[3]));
    assert!(hull_area > 2.0, "{hull_area}");
}

#[test]
fn unit_box_resting_on_a_large_ground_box_keeps_four_points_and_ids() {
    let ground = cuboid(50.0, 0.5, 50.0);
    let cube = cuboid(0.5, 0.5, 0.5);
    let gp = at(0.0, -0.5, 0.0);
    let rest = run(&ground, &gp, &cube, &at(3.0, 0.5, -2.0), 0.01);
    assert_eq!((rest.count, rest.normal), (4, Vec3::Y));
    assert!(rest.points().iter().all(|p| p.depth == Scalar::ZERO));
    let want = ids(&rest);
    let mut rng = Rng::new(99);
    let mut worst: f64 = 0.0;
    for _ in 0..100 {
        let axis = v(
            rng.uniform(-1.0, 1.0),
            rng.uniform(-1.0, 1.0),
            rng.uniform(-1.0, 1.0),
        )
        .normalize_or_zero();
        let q = Quat::from_axis_angle(axis, s(rng.uniform(-1e-4, 1e-4))).normalize();
        let t = v(
            3.0 + rng.uniform(-1e-3, 1e-3),
            0.5 + rng.uniform(-1e-4, 1e-4),
            -2.0 + rng.uniform(-1e-3, 1e-3),
        );
        let m = run(&ground, &gp, &cube, &Transform::new(t, q), 0.01);
        assert_eq!(m.count, 4);
        assert_eq!(ids(&m), want);
        assert_vec_close(m.normal, [0.0, 1.0, 0.0], 1e-12, "ground normal");
        for p in m.points() {
            worst = worst.max(f(p.depth).abs());
        }
        // Swapped: the cube's bottom face is the reference, the same four points.
        let m = run(&cube, &Transform::new(t, q), &ground, &gp, 0.01);
        assert_eq!(m.count, 4);
    }
    assert!(worst < 3e-4, "{worst}");
}

#[test]
fn capsule_lying_on_ground_box_keeps_two_points_and_ids_under_perturbation() {
    let ground = cuboid(50.0, 0.5, 50.0);
    let log = capsule(1.0, 0.25);
    let gp = at(0.0, -0.5, 0.0);
    let lying = rot(Vec3::Z, 90);
    let rest = run(&log, &posed(1.0, 0.25, 2.0, lying), &ground, &gp, 0.01);
    assert_eq!(rest.count, 2);
    assert!(rest.points().iter().all(|p| p.depth.abs() < s(1e-8)));
    let mut rng = Rng::new(3);
    for _ in 0..100 {
        let axis = v(
            rng.uniform(-1.0, 1.0),
            rng.uniform(-1.0, 1.0),
            rng.uniform(-1.0, 1.0),
        )
        .normalize_or_zero();
        let q = (Quat::from_axis_angle(axis, s(rng.uniform(-1e-3, 1e-3))) * lying).normalize();
        let t = v(
            1.0 + rng.uniform(-1e-3, 1e-3),
            0.25 + rng.uniform(-1e-4, 1e-4),
            2.0,
        );
        let m = run(&log, &Transform::new(t, q), &ground, &gp, 0.01);
        assert_eq!(ids(&m), ids(&rest));
        assert_vec_close(m.normal, [0.0, -1.0, 0.0], 1e-12, "log normal");
        assert!(m.points().iter().all(|p| p.depth.abs() < s(2e-3)));
    }
}

/// f64 SAT over all 15 axes: (index, separation) per axis, skipping edge
/// pairs within 1e-3 rad of parallel. Index 0–2 faces of A, 3–5 faces of B,
/// 6 + 3i + j edges.
#[allow(clippy::needless_range_loop)] // Axis indices are the point here.
fn sat_f64(ha: V, pa: &Transform, hb: V, pb: &Transform) -> Vec<(usize, f64)> {
    let (aa, ab) = (axes_f64(pa), axes_f64(pb));
    let d = sub(vf(pb.translation), vf(pa.translation));
    let sep = |l: V| {
        let ra: f64 = (0..3).map(|i| ha[i] * dot(l, aa[i]).abs()).sum();
        let rb: f64 = (0..3).map(|j| hb[j] * dot(l, ab[j]).abs()).sum();
        dot(d, l).abs() - ra - rb
    };
    let mut out = Vec::new();
    for i in 0..3 {
        out.push((i, sep(aa[i])));
    }
    for j in 0..3 {
        out.push((3 + j, sep(ab[j])));
    }
    for i in 0..3 {
        for j in 0..3 {
            let a = aa[i];
            let b = ab[j];
            let l = [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ];
            let n = norm(l);
            if n > 1e-3 {
                out.push((6 + 3 * i + j, sep(scale(l, 1.0 / n))));
            }
        }
    }
    out
}

/// A speculative edge–edge contact of two separated boxes, against its
/// documented construction in f64: one point midway between the closest
/// points of the two edges that support the axis (A's along the normal, B's
/// against it). The depth is minus the SAT separation, a lower bound of the
/// distance, so when those closest points are clamped to an edge's end the
/// point lies farther than `|depth| / 2` from the surfaces (up to half the
/// edges' distance), which the general surface check would not allow.
fn assert_separated_edge_point(ha: V, pa: &Transform, hb: V, pb: &Transform, m: &Manifold) {
    assert_eq!(m.points().len(), 1, "an edge contact has one point");
    let n = vf(m.normal);
    // The edge of a box along its axis `k` that is extreme along `dir`.
    let edge = |h: V, pose: &Transform, k: usize, dir: V| -> (V, V) {
        let local = to_local(pose, add(vf(pose.translation), dir));
        let mut c = [0.0; 3];
        for j in 0..3 {
            c[j] = if local[j] >= 0.0 { h[j] } else { -h[j] };
        }
        let (mut e0, mut e1) = (c, c);
        e0[k] = -h[k];
        e1[k] = h[k];
        (to_world(pose, e0), to_world(pose, e1))
    };
    let p = m.points()[0];
    let (fa, fb) = (
        (p.id.0 >> 16) as u16 - 0x100,
        (p.id.0 & 0xffff) as u16 - 0x100,
    );
    let (a0, a1) = edge(ha, pa, (fa / 4) as usize, n);
    let (b0, b1) = edge(hb, pb, (fb / 4) as usize, scale(n, -1.0));
    let (ca, cb) = seg_seg_points_f64(a0, a1, b0, b1);
    let mid = scale(add(ca, cb), 0.5);
    let off = norm(sub(vf(p.point), mid));
    assert!(off <= 1e-6, "edge point {off} from the f64 midpoint");
    // Never closer than the depth says: the separation is a lower bound.
    assert!(norm(sub(ca, cb)) >= -f(p.depth) - 1e-6);
}

#[test]
fn box_box_sat_agrees_with_f64_sat_over_15_axes() {
    let mut rng = Rng::new(5);
    let (mut overlapping, mut preferred, mut worst_max, mut worst_chosen) = (0, 0, 0.0f64, 0.0f64);
    let mut separated_edges = 0;
    for _ in 0..2000 {
        let ha = [
            rng.uniform(0.1, 1.5),
            rng.uniform(0.1, 1.5),
            rng.uniform(0.1, 1.5),
        ];
        let hb = [
            rng.uniform(0.1, 1.5),
            rng.uniform(0.1, 1.5),
            rng.uniform(0.1, 1.5),
        ];
        let (pa, pb) = (rng.pose(1.5), rng.pose(1.5));
        let reference = sat_f64(ha, &pa, hb, &pb);
        let best = reference
            .iter()
            .cloned()
            .fold((0, f64::MIN), |b, x| if x.1 > b.1 { x } else { b });
        let (t, q) = relative_pose(&pa, &pb);
        let sat = box_sat(
            v(ha[0], ha[1], ha[2]),
            v(hb[0], hb[1], hb[2]),
            &Mat3::from_quat(q),
            t,
        );
        worst_max = worst_max.max((f(sat.max_separation) - best.1).abs());
        let index = match sat.chosen {
            BoxAxis::FaceA(i) => i,
            BoxAxis::FaceB(j) => 3 + j,
            BoxAxis::Edge(i, j) => 6 + 3 * i + j,
        };
        let chosen = reference
            .iter()
            .find(|x| x.0 == index)
            .expect("chosen axis is tested by the reference")
            .1;
        worst_chosen = worst_chosen.max((f(sat.separation) - chosen).abs());
        // The chosen axis is the best one, or within the preference tolerance of it.
        assert!(
            chosen >= best.1 - f(sat_tolerance(sat.separation)) - 1e-6,
            "{index} {chosen} vs {best:?}"
        );
        if index != best.0 {
            preferred += 1;
            assert!(index < best.0, "only earlier groups are preferred");
        }
        overlapping += (best.1 < 0.0) as u32;
        // The manifold never reports a point deeper than the chosen axis allows.
        let a: Shape = Cuboid::new(v(ha[0], ha[1], ha[2])).unwrap().into();
        let b: Shape = Cuboid::new(v(hb[0], hb[1], hb[2])).unwrap().into();
        let m = run(&a, &pa, &b, &pb, 0.05);
        if best.1 > 0.05 + 1e-6 {
            assert!(m.is_empty());
        }
        if !m.is_empty() {
            assert!(
                f(max_depth(&m)) <= -chosen + 1e-6,
                "{} > {}",
                f(max_depth(&m)),
                -chosen
            );
            if matches!(sat.chosen, BoxAxis::Edge(..)) && chosen > 0.0 {
                separated_edges += 1;
                assert_separated_edge_point(ha, &pa, hb, &pb, &m);
            } else {
                assert_points_on_surfaces(&a, &pa, &b, &pb, &m, 1e-6);
            }
        }
    }
    println!(
        "box_box: {overlapping} overlapping of 2000, {preferred} took a preferred axis, {separated_edges} separated on an edge axis, max |max sep − f64| {worst_max:e}, max |chosen sep − f64| {worst_chosen:e}"
    );
    assert!(worst_max <= 1e-6 && worst_chosen <= 1e-6);
    assert!(overlapping > 300);
}

/// f64 distance from a segment to a box (in the box frame) by golden-section
/// search of the convex distance along the segment.
fn seg_box_distance_f64(p0: V, p1: V, h: V) -> f64 {
    let dist = |t: f64| {
        let p = add(p0, scale(sub(p1, p0), t));
        let q = [
            (p[0].abs() - h[0]).max(0.0),
            (p[1].abs() - h[1]).max(0.0),
            (p[2].abs() - h[2]).max(0.0),
        ];
        norm(q)
    };
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    let g = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..200 {
        let (m1, m2) = (hi - g * (hi - lo), lo + g * (hi - lo));
        if dist(m1) <= dist(m2) {
            hi = m2;
        } else {
            lo = m1;
        }
    }
    dist(0.0).min(dist(1.0)).min(dist((lo + hi) / 2.0))
}

#[test]
fn sphere_box_and_capsule_box_agree_with_f64_references() {
    let mut rng = Rng::new(17);
    for (name, a, b) in pair_kinds().into_iter().skip(3).take(2) {
        let h = match &b {
            Shape::Cuboid(c) => vf(c.half_extents),
            _ => unreachable!(),
        };
        let (mut hits, mut worst, mut worst_surface, mut shallower, mut worst_two) =
            (0, 0.0f64, 0.0f64, 0, 0.0f64);
        for _ in 0..1500 {
            let (pa, pb) = (rng.pose(1.0), rng.pose(1.0));
            let m = run(&a, &pa, &b, &pb, 0.05);
            let (p0, p1, r) = match &a {
                Shape::Sphere(x) => {
                    let c = to_local(&pb, vf(pa.translation));
                    (c, c, f(x.radius))
                }
                Shape::Capsule(c) => {
                    let (p, q) = core_f64(c, &pa);
                    (to_local(&pb, p), to_local(&pb, q), f(c.radius))
                }
                _ => unreachable!(),
            };
            let dist = seg_box_distance_f64(p0, p1, h);
            let want = if dist > 1e-9 {
                r - dist
            } else {
                // Core inside: SAT over the box faces and the segment × edge axes.
                let u = sub(p1, p0);
                let c = scale(add(p0, p1), 0.5);
                let mut best = f64::MIN;
                for k in 0..3 {
                    best = best.max(c[k].abs() - h[k] - u[k].abs() / 2.0);
                    let mut e = [0.0; 3];
                    e[k] = 1.0;
                    let l = [
                        u[1] * e[2] - u[2] * e[1],
                        u[2] * e[0] - u[0] * e[2],
                        u[0] * e[1] - u[1] * e[0],
                    ];
                    let n = norm(l);
                    if n > 1e-3 * norm(u) {
                        let l = scale(l, 1.0 / n);
                        best = best
                            .max(dot(c, l).abs() - (0..3).map(|j| h[j] * l[j].abs()).sum::<f64>());
                    }
                }
                r - best
            };
            if want < -0.05 - 1e-6 {
                assert!(m.is_empty(), "{name}: contact beyond the margin");
                continue;
            }
            if want < -0.05 + 1e-6 {
                continue;
            }
            assert!(!m.is_empty(), "{name}: missed a contact of depth {want}");
            hits += 1;
            let got = f(max_depth(&m));
            // The face is preferred unless an edge axis beats it by the
            // tolerance of the face's own separation (`r − got`).
            let tol = f(sat_tolerance(s(r - got)));
            assert!(got <= want + tol + 1e-6, "{name}: {got} deeper than {want}");
            if dist > 1e-9 {
                worst = worst.max((got - want).abs());
            } else if got < want - 1e-6 {
                // A face point clipped to the face rectangle is shallower
                // than the SAT depth when the core exits through a side.
                shallower += 1;
            }
            // A capsule lying along a face within the parallel tolerance
            // (sine ≤ 1/32) measures both ends' depths along the face normal,
            // not perpendicular to its axis: off by at most r·(1/cos − 1).
            let tol = if m.count > 1 { 2e-4 } else { 1e-6 };
            let excess = assert_points_on_surfaces(&a, &pa, &b, &pb, &m, tol);
            if m.count > 1 {
                worst_two = worst_two.max(excess);
            } else {
                worst_surface = worst_surface.max(excess);
            }
        }
        println!(
            "{name}: {hits} contacts, max |depth − f64| apart {worst:e}, {shallower} clipped shallower, \
             surface excess {worst_surface:e} (two-point {worst_two:e})"
        );
        assert!(worst <= 1e-6, "{name}: {worst}");
        assert!(hits > 300);
    }
}
