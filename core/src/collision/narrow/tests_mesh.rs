//! Tests of convex shapes against triangle meshes and height fields.

use super::tests_analytic::*;
use super::*;
use crate::math::Aabb;
use crate::math::Vec3;
use crate::shape::{ConvexHull, Cuboid, HeightField, TriMesh};

/// A flat square floor at `y = 0` over `[−half, half]²`, split into
/// `n × n` cells of two triangles each, facing +y.
fn floor_mesh(half: f64, n: usize) -> TriMesh {
    let mut verts = Vec::new();
    for r in 0..=n {
        for c in 0..=n {
            let x = -half + 2.0 * half * c as f64 / n as f64;
            let z = -half + 2.0 * half * r as f64 / n as f64;
            verts.push(v(x, 0.0, z));
        }
    }
    let mut idx = Vec::new();
    let w = n as u32 + 1;
    for r in 0..n as u32 {
        for c in 0..n as u32 {
            let (a, b, cc, d) = (
                r * w + c,
                r * w + c + 1,
                (r + 1) * w + c,
                (r + 1) * w + c + 1,
            );
            idx.push([a, d, b]);
            idx.push([a, cc, d]);
        }
    }
    TriMesh::new(verts, idx).unwrap()
}

/// A flat height field of `n × n` samples with spacing `step`.
fn flat_field(n: u32, step: f64) -> HeightField {
    HeightField::new(
        n,
        n,
        vec![Scalar::ZERO; (n * n) as usize],
        v(step, 1.0, step),
    )
    .unwrap()
}

fn sorted(m: &Manifold) -> Vec<(V, f64)> {
    let mut p: Vec<(V, f64)> = m
        .points()
        .iter()
        .map(|c| (vf(c.point), f(c.depth)))
        .collect();
    p.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap());
    p
}

fn assert_same_manifold(got: &Manifold, want: &Manifold, what: &str) {
    assert_eq!(got.count, 4, "{what}: count");
    assert_eq!(want.count, 4, "{what}: reference count");
    assert_vec_close(got.normal, vf(want.normal), 1e-6, what);
    for ((p, d), (q, e)) in sorted(got).iter().zip(sorted(want).iter()) {
        assert!(norm(sub(*p, *q)) <= 1e-6, "{what}: point {p:?} vs {q:?}");
        assert!((d - e).abs() <= 1e-6, "{what}: depth {d} vs {e}");
    }
}

#[test]
fn box_resting_on_mesh_and_height_field_matches_box_floor() {
    let body = cuboid(0.5, 0.25, 0.4);
    let ground: Shape = Cuboid::new(v(4.0, 1.0, 4.0)).unwrap().into();
    let ground_pose = at(0.0, -1.0, 0.0);
    let meshes: [(Shape, &str); 3] = [
        (floor_mesh(4.0, 1).into(), "two-triangle mesh"),
        (floor_mesh(4.0, 8).into(), "8x8 mesh"),
        (flat_field(9, 1.0).into(), "height field"),
    ];
    // Resting slightly sunk in, yawed and not: several placements.
    for (i, pose) in [
        at(0.3, 0.24, -0.2),
        posed(-1.1, 0.23, 0.7, rot(Vec3::Y, 30)),
        posed(0.0, 0.245, 0.0, rot(Vec3::Y, 45)),
        posed(1.7, 0.2, 1.3, rot(Vec3::Y, -71)),
    ]
    .iter()
    .enumerate()
    {
        let want = run(&body, pose, &ground, &ground_pose, 0.01);
        for (mesh, name) in &meshes {
            let got = run(&body, pose, mesh, &Transform::IDENTITY, 0.01);
            assert_same_manifold(&got, &want, &format!("{name}, placement {i}"));
            assert_eq!(got.normal, -Vec3::Y, "{name}: face normal is exact");
        }
    }
}

#[test]
fn box_sliding_across_seams_always_gets_normal_exactly_up() {
    let body = cuboid(0.3, 0.3, 0.3);
    let mesh: Shape = floor_mesh(4.0, 16).into();
    let field: Shape = flat_field(17, 0.5).into();
    let mut checked = 0;
    for k in 0..400 {
        let x = -2.0 + 4.0 * k as f64 / 400.0;
        // A small tilt makes an edge lead, as when sliding.
        let pose = posed(x, 0.29, 0.123 * (k % 7) as f64, rot(Vec3::Z, 2));
        for ground in [&mesh, &field] {
            let m = run(ground, &Transform::IDENTITY, &body, &pose, 0.02);
            assert!(!m.is_empty(), "x = {x}");
            assert_eq!(m.normal, Vec3::Y, "x = {x}: normal must not bump");
            assert!(
                m.count >= 2,
                "x = {x}: a tilted box keeps an edge on the floor"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 800);
}

/// A roof: two planes meeting at a ridge along z at `x = 0, y = 1`, sloping
/// down to `y = 0` at `x = ±1`, plus a pyramid apex at the origin of a
/// second mesh.
fn roof() -> TriMesh {
    let verts = vec![
        v(-1.0, 0.0, -2.0),
        v(0.0, 1.0, -2.0),
        v(1.0, 0.0, -2.0),
        v(-1.0, 0.0, 2.0),
        v(0.0, 1.0, 2.0),
        v(1.0, 0.0, 2.0),
    ];
    // Counter-clockwise seen from above the slopes.
    TriMesh::new(verts, vec![[0, 4, 1], [0, 3, 4], [1, 5, 2], [1, 4, 5]]).unwrap()
}

fn pyramid() -> TriMesh {
    let verts = vec![
        v(0.0, 1.0, 0.0),
        v(-1.0, 0.0, -1.0),
        v(1.0, 0.0, -1.0),
        v(1.0, 0.0, 1.0),
        v(-1.0, 0.0, 1.0),
    ];
    TriMesh::new(verts, vec![[0, 2, 1], [0, 3, 2], [0, 4, 3], [0, 1, 4]]).unwrap()
}

#[test]
fn ridge_and_apex_of_a_convex_mesh_are_active_and_give_their_own_normals() {
    let r = roof();
    // The ridge edge (corners 4→1 of triangle 0) is active on both sides.
    assert!(r.edge_active(0, 1) && r.edge_active(2, 0) || r.edge_active(2, 2));
    let ball = sphere(0.5);
    // Straight above the ridge: the edge normal is +y.
    let m = run(
        &ball,
        &at(0.0, 1.4, 0.3),
        &r.clone().into(),
        &Transform::IDENTITY,
        0.0,
    );
    assert_eq!(m.count, 1);
    assert_vec_close(m.normal, [0.0, -1.0, 0.0], 1e-9, "ridge normal");
    assert_close(m.points()[0].depth, 0.1, 1e-8, "ridge depth");
    // Off to one side but still closest to the ridge: normal through it.
    let m = run(
        &ball,
        &at(0.3, 1.4, 0.0),
        &r.into(),
        &Transform::IDENTITY,
        0.0,
    );
    let d = [0.3, 0.4, 0.0];
    let l = norm(d);
    assert_vec_close(m.normal, scale(d, -1.0 / l), 1e-8, "ridge side normal");
    assert_close(m.points()[0].depth, 0.5 - l, 1e-8, "ridge side depth");
    // Above the pyramid's apex, diagonal direction: the vertex normal.
    let p = pyramid();
    for t in 0..4 {
        assert!((0..3).all(|k| p.edge_active(t, k)));
    }
    let d = [0.1, 0.3, 0.15];
    let l = norm(d);
    let m = run(
        &ball,
        &at(d[0], 1.0 + d[1], d[2]),
        &p.into(),
        &Transform::IDENTITY,
        0.0,
    );
    assert_vec_close(m.normal, scale(d, -1.0 / l), 1e-8, "apex normal");
    assert_close(m.points()[0].depth, 0.5 - l, 1e-8, "apex depth");
}

#[test]
fn coplanar_and_concave_edges_are_inactive_and_height_field_agrees() {
    let m = floor_mesh(2.0, 2);
    // Interior diagonal of cell 0 and the seam between cells are inactive,
    // the border is active.
    assert!(!m.edge_active(0, 0));
    assert!(!m.edge_active(0, 1));
    assert!(m.edge_active(0, 2));
    let f = flat_field(3, 2.0);
    for t in 0..8u64 {
        for k in 0..3 {
            assert_eq!(
                f.edge_active(t, k),
                m.edge_active(t as usize, k),
                "triangle {t} edge {k}"
            );
        }
    }
    // A valley (concave) field: the middle column is low, its edges inactive.
    let h = [1, 0, 1, 1, 0, 1, 1, 0, 1].map(Scalar::from_int).to_vec();
    let valley = HeightField::new(3, 3, h, v(1.0, 1.0, 1.0)).unwrap();
    assert!(
        !valley.edge_active(0, 1),
        "concave edge along the valley floor"
    );
    // A ridge field: middle column high, its edges convex and active.
    let h = [0, 1, 0, 0, 1, 0, 0, 1, 0].map(Scalar::from_int).to_vec();
    let ridge = HeightField::new(3, 3, h, v(1.0, 1.0, 1.0)).unwrap();
    assert!(ridge.edge_active(0, 1), "convex ridge edge");
}

/// f64 closest point on triangle `t` to `p`.
fn closest_f64(p: V, t: [V; 3]) -> V {
    let (a, b, c) = (t[0], t[1], t[2]);
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return add(a, scale(ab, d1 / (d1 - d3)));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return add(a, scale(ac, d2 / (d2 - d6)));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return add(b, scale(sub(c, b), w));
    }
    let denom = 1.0 / (va + vb + vc);
    add(a, add(scale(ab, vb * denom), scale(ac, vc * denom)))
}

fn cross_f64(a: V, b: V) -> V {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// f64 distance from segment `p0`–`p1` to triangle `t` (zero if it crosses).
fn seg_tri_dist(p0: V, p1: V, t: [V; 3]) -> f64 {
    let n = cross_f64(sub(t[1], t[0]), sub(t[2], t[0]));
    let (h0, h1) = (dot(n, sub(p0, t[0])), dot(n, sub(p1, t[0])));
    if h0 * h1 < 0.0 {
        let x = add(p0, scale(sub(p1, p0), h0 / (h0 - h1)));
        if norm(sub(closest_f64(x, t), x)) < 1e-12 {
            return 0.0;
        }
    }
    let mut best = f64::MAX;
    // Sampled segment plus exact endpoints: fine enough for 1e-6 with
    // 4096 samples refined by ternary search.
    let d = |s: f64| {
        let x = add(p0, scale(sub(p1, p0), s));
        norm(sub(closest_f64(x, t), x))
    };
    let samples = 64;
    for i in 0..=samples {
        let s = i as f64 / samples as f64;
        let (mut lo, mut hi) = (
            (s - 1.0 / samples as f64).max(0.0),
            (s + 1.0 / samples as f64).min(1.0),
        );
        for _ in 0..60 {
            let m1 = lo + (hi - lo) / 3.0;
            let m2 = hi - (hi - lo) / 3.0;
            if d(m1) < d(m2) {
                hi = m2;
            } else {
                lo = m1;
            }
        }
        best = best.min(d(s)).min(d((lo + hi) / 2.0));
    }
    best
}

/// A bumpy mesh: a 6×6 grid over [−3, 3]² with seeded heights.
fn bumpy_mesh(rng: &mut Rng) -> (TriMesh, Vec<[V; 3]>) {
    let n = 6usize;
    let mut verts = Vec::new();
    for r in 0..=n {
        for c in 0..=n {
            verts.push(v(-3.0 + c as f64, rng.uniform(-0.3, 0.3), -3.0 + r as f64));
        }
    }
    let w = n as u32 + 1;
    let mut idx = Vec::new();
    for r in 0..n as u32 {
        for c in 0..n as u32 {
            let (a, b, cc, d) = (
                r * w + c,
                r * w + c + 1,
                (r + 1) * w + c,
                (r + 1) * w + c + 1,
            );
            idx.push([a, d, b]);
            idx.push([a, cc, d]);
        }
    }
    let mesh = TriMesh::new(verts, idx).unwrap();
    let tris = (0..mesh.indices().len())
        .map(|t| mesh.triangle(t).unwrap().map(vf))
        .collect();
    (mesh, tris)
}

#[test]
fn sphere_and_capsule_depths_match_f64_closest_points_over_seeded_poses() {
    let mut rng = Rng::new(7);
    let (mesh, tris) = bumpy_mesh(&mut rng);
    let shape_mesh: Shape = mesh.clone().into();
    let mesh_pose = posed(
        3.0,
        -1.0,
        2.0,
        rot(
            Vec3::new(Scalar::ONE, Scalar::ZERO, Scalar::ONE)
                .try_normalize()
                .unwrap(),
            10,
        ),
    );
    let (mut worst_s, mut worst_c, mut hits) = (0.0f64, 0.0f64, 0);
    for i in 0..1000 {
        let local = v(
            rng.uniform(-2.0, 2.0),
            rng.uniform(0.0, 0.8),
            rng.uniform(-2.0, 2.0),
        );
        let world = mesh_pose.transform_point(local);
        let q = rng.quat();
        let pose = Transform::new(world, q);
        let (shape, core): (Shape, [V; 2]) = if i % 2 == 0 {
            (sphere(0.45), [vf(local); 2])
        } else {
            let h = 0.4;
            let ax = vf(mesh_pose.rotation.inverse_rotate(q.rotate(Vec3::Y)));
            (
                capsule(h, 0.3),
                [add(vf(local), scale(ax, -h)), add(vf(local), scale(ax, h))],
            )
        };
        let r = if i % 2 == 0 { 0.45 } else { 0.3 };
        // Reference: deepest r − distance over triangles with the centre in
        // front (the one-sided rule); the core must stay clear of the mesh.
        let centre = vf(local);
        let mut want = f64::MIN;
        let mut min_dist = f64::MAX;
        for t in &tris {
            let n = cross_f64(sub(t[1], t[0]), sub(t[2], t[0]));
            let dist = seg_tri_dist(core[0], core[1], *t);
            min_dist = min_dist.min(dist);
            if dot(n, sub(centre, t[0])) >= 0.0 {
                want = want.max(r - dist);
            }
        }
        if min_dist < 0.02 {
            continue;
        }
        let m = run(&shape, &pose, &shape_mesh, &mesh_pose, 0.05);
        if want < -0.05 + 1e-6 {
            continue;
        }
        if want > -0.05 + 1e-3 {
            assert!(
                !m.is_empty(),
                "pose {i}: missing contact, want depth {want}"
            );
        }
        if m.is_empty() {
            continue;
        }
        hits += 1;
        let got = f(max_depth(&m));
        let err = (got - want).abs();
        if err > 1e-4 {
            eprintln!(
                "pose {i}: got {got} want {want} normal {:?} count {}",
                vf(m.normal),
                m.count
            );
        }
        if i % 2 == 0 {
            worst_s = worst_s.max(err);
        } else {
            worst_c = worst_c.max(err);
        }
    }
    eprintln!("sphere max depth error {worst_s:e}, capsule {worst_c:e}, {hits} contacts");
    assert!(hits >= 300, "{hits}");
    assert!(worst_s <= 1e-6, "sphere {worst_s}");
    assert!(worst_c <= 1e-6, "capsule {worst_c}");
}

#[test]
fn hull_on_a_flat_mesh_matches_its_lowest_vertex_over_seeded_poses() {
    let mut rng = Rng::new(11);
    let pts: Vec<Vec3> = (0..14)
        .map(|_| {
            v(
                rng.uniform(-0.5, 0.5),
                rng.uniform(-0.5, 0.5),
                rng.uniform(-0.5, 0.5),
            )
        })
        .collect();
    let hull = ConvexHull::from_points(&pts).unwrap();
    let shape: Shape = hull.clone().into();
    let mesh: Shape = floor_mesh(3.0, 6).into();
    let mut worst = 0.0f64;
    let mut hits = 0;
    for i in 0..600 {
        // The centre stays in front of the floor (one-sided triangles).
        let pose = Transform::new(
            v(
                rng.uniform(-1.5, 1.5),
                rng.uniform(0.0, 0.6),
                rng.uniform(-1.5, 1.5),
            ),
            rng.quat(),
        );
        let low = hull
            .vertices()
            .iter()
            .map(|&p| f(pose.transform_point(p).y))
            .fold(f64::MAX, f64::min);
        let want = -low;
        let m = run(&shape, &pose, &mesh, &Transform::IDENTITY, 0.05);
        if want < -0.05 + 1e-6 {
            assert!(m.is_empty() || f(max_depth(&m)) >= -0.05 - 1e-6, "pose {i}");
            continue;
        }
        assert!(!m.is_empty(), "pose {i}: want depth {want}");
        assert_eq!(m.normal, -Vec3::Y, "pose {i}");
        hits += 1;
        worst = worst.max((f(max_depth(&m)) - want).abs());
    }
    eprintln!("hull max depth error {worst:e}, {hits} contacts");
    assert!(hits >= 200, "{hits}");
    // The reduction to four points keeps, among the points within 2⁻¹² m
    // of the deepest, the one farthest across the normal (module docs,
    // step 4): the manifold's depth is the lowest vertex's to that slack.
    assert!(worst <= 2f64.powi(-12) + 1e-6, "{worst}");
}

#[test]
fn mesh_as_a_gives_the_flipped_manifold() {
    let mut rng = Rng::new(3);
    let mesh: Shape = floor_mesh(3.0, 6).into();
    let field: Shape = flat_field(7, 1.0).into();
    let shapes = [sphere(0.4), capsule(0.3, 0.2), cuboid(0.3, 0.2, 0.4)];
    let mut hits = 0;
    for i in 0..200 {
        let pose = Transform::new(
            v(
                rng.uniform(-2.0, 2.0),
                rng.uniform(0.0, 0.4),
                rng.uniform(-2.0, 2.0),
            ),
            rng.quat(),
        );
        for ground in [&mesh, &field] {
            let shape = &shapes[i % 3];
            let ab = run(shape, &pose, ground, &Transform::IDENTITY, 0.02);
            let ba = run(ground, &Transform::IDENTITY, shape, &pose, 0.02);
            if !ab.is_empty() {
                assert_eq!(ba.normal, -ab.normal);
            }
            assert_eq!(ba.points(), ab.points());
            hits += ab.count.min(1) as u32;
        }
    }
    assert!(hits > 100, "{hits}");
    // Static–static pairs have no contact.
    assert!(run(&mesh, &Transform::IDENTITY, &field, &at(0.0, 0.0, 0.0), 1.0).is_empty());
    assert!(
        run(
            &mesh,
            &Transform::IDENTITY,
            &mesh,
            &Transform::IDENTITY,
            1.0
        )
        .is_empty()
    );
}

#[test]
fn mesh_contacts_are_translation_invariant_bit_for_bit() {
    let mut rng = Rng::new(5);
    let (mesh, _) = bumpy_mesh(&mut rng);
    let grounds: [Shape; 2] = [mesh.into(), flat_field(7, 1.0).into()];
    let hull: Shape = ConvexHull::from_points(&[
        v(0.3, 0.0, 0.0),
        v(-0.3, 0.1, 0.2),
        v(0.0, 0.4, -0.2),
        v(0.1, -0.3, 0.3),
        v(-0.2, -0.2, -0.3),
    ])
    .unwrap()
    .into();
    let shapes = [sphere(0.4), capsule(0.3, 0.2), cuboid(0.3, 0.2, 0.4), hull];
    let offset = v(10_000.5, 0.0, -7_000.25);
    let mut hits = 0;
    for i in 0..200 {
        let pose = Transform::new(
            v(
                rng.uniform(-2.0, 2.0),
                rng.uniform(0.0, 0.5),
                rng.uniform(-2.0, 2.0),
            ),
            rng.quat(),
        );
        let gpose = Transform::new(v(0.5, -0.2, 0.25), rot(Vec3::Y, 17));
        let shape = &shapes[i % 4];
        for ground in &grounds {
            let m1 = run(shape, &pose, ground, &gpose, 0.05);
            let p2 = Transform::new(pose.translation + offset, pose.rotation);
            let g2 = Transform::new(gpose.translation + offset, gpose.rotation);
            let m2 = run(shape, &p2, ground, &g2, 0.05);
            assert_eq!(m1.count, m2.count);
            assert_eq!(m1.normal, m2.normal);
            for (a, b) in m1.points().iter().zip(m2.points()) {
                assert_eq!(a.depth, b.depth);
                assert_eq!(a.id, b.id);
                assert_eq!(a.point + offset, b.point);
            }
            hits += m1.count.min(1) as u32;
        }
    }
    assert!(hits > 50, "{hits}");
}

#[test]
fn bvh_query_equals_brute_force_over_random_boxes() {
    let mut rng = Rng::new(9);
    // A random triangle soup.
    let mut verts = Vec::new();
    let mut idx = Vec::new();
    for t in 0..3000u32 {
        let c = [
            rng.uniform(-50.0, 50.0),
            rng.uniform(-5.0, 5.0),
            rng.uniform(-50.0, 50.0),
        ];
        for _ in 0..3 {
            verts.push(v(
                c[0] + rng.uniform(-2.0, 2.0),
                c[1] + rng.uniform(-2.0, 2.0),
                c[2] + rng.uniform(-2.0, 2.0),
            ));
        }
        idx.push([3 * t, 3 * t + 1, 3 * t + 2]);
    }
    let mesh = TriMesh::new(verts, idx).unwrap();
    let mut buf = [0u32; 64];
    let mut truncations = 0;
    for _ in 0..500 {
        let c = v(
            rng.uniform(-60.0, 60.0),
            rng.uniform(-6.0, 6.0),
            rng.uniform(-60.0, 60.0),
        );
        let h = Vec3::splat(s(rng.uniform(0.1, 8.0)));
        let q = Aabb::from_center_half_extents(c, h);
        let brute: Vec<u32> = (0..mesh.indices().len() as u32)
            .filter(|&t| {
                let [a, b, cc] = mesh.triangle(t as usize).unwrap();
                Aabb::new(a.min(b).min(cc), a.max(b).max(cc)).overlaps(&q)
            })
            .collect();
        let r = mesh.query_triangles(&q, &mut buf);
        let expect = &brute[..brute.len().min(64)];
        assert_eq!(&buf[..r.count], expect);
        assert_eq!(r.truncated, brute.len() > 64);
        truncations += r.truncated as u32;
    }
    assert!(truncations > 0, "the cap was exercised");
}

#[test]
fn degenerate_meshes_are_rejected_and_huge_fields_clamp() {
    // Slivers with zero area are rejected at construction.
    let e = TriMesh::new(
        vec![v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(2.0, 0.0, 0.0)],
        vec![[0, 1, 2]],
    );
    assert!(e.is_err());
    // A one-ulp sliver is valid and does not break contacts.
    let d = Scalar::DELTA;
    let sliver = TriMesh::new(
        vec![
            Vec3::ZERO,
            Vec3::new(Scalar::ZERO, Scalar::ZERO, d),
            Vec3::new(Scalar::ONE, Scalar::ZERO, Scalar::ZERO),
        ],
        vec![[0, 1, 2]],
    )
    .unwrap();
    let m = run(
        &cuboid(0.5, 0.5, 0.5),
        &at(0.5, 0.45, 0.0),
        &sliver.into(),
        &Transform::IDENTITY,
        0.0,
    );
    assert!(m.count >= 1);
    assert_close(max_depth(&m), 0.05, 1e-6, "sliver depth");
    // A 4000 × 4000 field: a box far outside touches nothing, a huge box
    // keeps the first 64 triangles and reports the truncation.
    let n = 4000u32;
    let field =
        HeightField::new(n, n, vec![Scalar::ZERO; (n * n) as usize], v(1.0, 1.0, 1.0)).unwrap();
    let shape = Cuboid::new(v(0.5, 0.5, 0.5)).unwrap();
    let mut out = Manifold::EMPTY;
    let far = mesh_contact::contact_box_heightfield_info(
        &shape,
        &at(1.0e6, 0.4, 0.0),
        &field,
        &Transform::IDENTITY,
        Scalar::ZERO,
        &mut out,
    );
    assert!(!far.hit && far.triangles == 0);
    let big = Cuboid::new(v(3000.0, 1.0, 3000.0)).unwrap();
    let r = mesh_contact::contact_box_heightfield_info(
        &big,
        &at(0.0, 0.9, 0.0),
        &field,
        &Transform::IDENTITY,
        Scalar::ZERO,
        &mut out,
    );
    assert!(r.truncated && r.hit);
    assert_eq!(r.triangles, 64);
    assert_eq!(
        field.cell_range(&Aabb::new(v(-1e6, -1.0, -1e6), v(1e6, 1.0, 1e6))),
        Some(([0, n - 2], [0, n - 2]))
    );
    assert_eq!(
        field.cell_range(&Aabb::new(v(-1e6, 2.0, -1e6), v(1e6, 3.0, 1e6))),
        None
    );
}

#[test]
fn box_and_the_same_box_as_a_hull_agree_on_a_bumpy_mesh() {
    let mut rng = Rng::new(21);
    let (mesh, _) = bumpy_mesh(&mut rng);
    let mesh: Shape = mesh.into();
    let b = Cuboid::new(v(0.4, 0.25, 0.3)).unwrap();
    let as_box: Shape = b.into();
    let as_hull: Shape = ConvexHull::from_points(&b.corners()).unwrap().into();
    let (mut worst, mut hits, mut same_normal) = (0.0f64, 0, 0);
    for i in 0..500 {
        let pose = Transform::new(
            v(
                rng.uniform(-2.0, 2.0),
                rng.uniform(0.0, 0.6),
                rng.uniform(-2.0, 2.0),
            ),
            rng.quat(),
        );
        let mb = run(&as_box, &pose, &mesh, &Transform::IDENTITY, 0.05);
        let mh = run(&as_hull, &pose, &mesh, &Transform::IDENTITY, 0.05);
        assert_eq!(mb.is_empty(), mh.is_empty(), "pose {i}");
        if mb.is_empty() {
            continue;
        }
        // Deep overlaps (more than a third of the box) may pick different
        // but equally valid features through the face/edge tolerances.
        if f(max_depth(&mb)).max(f(max_depth(&mh))) > 0.15 {
            continue;
        }
        hits += 1;
        worst = worst.max((f(max_depth(&mb)) - f(max_depth(&mh))).abs());
        same_normal += (norm(sub(vf(mb.normal), vf(mh.normal))) < 1e-6) as u32;
    }
    eprintln!("box vs hull-box: max depth difference {worst:e}, {same_normal}/{hits} same normal");
    assert!(hits >= 150, "{hits}");
    assert!(worst <= 1e-6, "{worst}");
    assert!(same_normal * 100 >= hits * 95, "{same_normal}/{hits}");
}
