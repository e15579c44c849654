//! Tests of `ConvexHull`: construction on awkward inputs, canonical layout,
//! exact mass properties.

use super::wide::{orient3d, raw};
use super::*;
use crate::math::{Quat, SymMat3};
use crate::testing::{Rng, s, v};

const ULP: f64 = 1.0 / 4_294_967_296.0;

/// Shuffles `xs` (Fisher–Yates).
fn shuffle<T>(g: &mut Rng, xs: &mut [T]) {
    for i in (1..xs.len()).rev() {
        let j = g.below(i as u64 + 1) as usize;
        xs.swap(i, j);
    }
}

/// `n` points on the sphere of radius `r`, uniformly distributed.
fn sphere_points(n: usize, r: f64, seed: u64) -> Vec<Vec3> {
    let mut g = Rng::new(seed);
    (0..n)
        .map(|_| {
            let z = 2.0 * g.unit() - 1.0;
            let phi = std::f64::consts::TAU * g.unit();
            let rho = (1.0 - z * z).sqrt();
            v(r * rho * phi.cos(), r * rho * phi.sin(), r * z)
        })
        .collect()
}

fn cube_corners(h: Vec3) -> Vec<Vec3> {
    Cuboid::new(h).unwrap().corners().to_vec()
}

/// Exact structural checks every hull must pass: Euler's formula, each face
/// planar and counter-clockwise from outside, every vertex (and every extra
/// point given) on or below every face plane, offsets supporting, normals
/// unit, edges shared by exactly two faces.
fn check_valid(h: &ConvexHull, also_inside: &[Vec3]) {
    let (nv, nf, ne) = (h.vertices().len(), h.faces().len(), h.edges().len());
    assert_eq!(nv + nf, ne + 2, "Euler: V {nv} F {nf} E {ne}");
    let mut edge_uses = vec![0; ne];
    for (fi, face) in h.faces().iter().enumerate() {
        let idx = h.face_vertices(fi);
        assert_eq!(idx.len(), face.vertex_count());
        assert!(idx.len() >= 3);
        assert_eq!(
            idx[0],
            *idx.iter().min().unwrap(),
            "face starts at its smallest index"
        );
        let p = |i: usize| raw(h.vertices()[idx[i] as usize]);
        for (k, &vi) in idx.iter().enumerate() {
            // Strictly convex polygon: each consecutive triple turns the same
            // way as the face normal (left, seen from outside).
            let (a, b, c) = (p(k), p((k + 1) % idx.len()), p((k + 2) % idx.len()));
            let above = [
                a[0] + (face.normal().x.to_bits() >> 12),
                a[1] + (face.normal().y.to_bits() >> 12),
                a[2] + (face.normal().z.to_bits() >> 12),
            ];
            assert!(
                orient3d(a, b, c, above).is_positive(),
                "face {fi} is not counter-clockwise at {k}"
            );
            assert_eq!(
                orient3d(p(0), p(1), p(2), raw(h.vertices()[vi as usize])),
                super::wide::Wide192::ZERO
            );
        }
        for q in h.vertices().iter().chain(also_inside) {
            assert!(
                !orient3d(p(0), p(1), p(2), raw(*q)).is_positive(),
                "{q:?} above face {fi}"
            );
            assert!(face.normal().dot_wide(*q) <= (face.offset().to_bits() as i128) << 32);
        }
        let n2 = face.normal().length_squared_wide() as f64 / 2f64.powi(64);
        assert!((n2.sqrt() - 1.0).abs() < 4.0 * ULP);
        for k in 0..idx.len() {
            let (a, b) = (idx[k], idx[(k + 1) % idx.len()]);
            let e = [a.min(b), a.max(b)];
            let at = h.edges().binary_search(&e).expect("face edge listed");
            edge_uses[at] += 1;
        }
    }
    assert!(edge_uses.iter().all(|&u| u == 2), "{edge_uses:?}");
    assert!(h.edges().windows(2).all(|w| w[0] < w[1]));
}

/// f64 reference mass properties from the hull's own faces (fan
/// triangulation, tetrahedra from the origin).
fn reference(h: &ConvexHull, rho: f64) -> (f64, [f64; 3], [f64; 6]) {
    let f = |p: Vec3| [p.x.to_f64(), p.y.to_f64(), p.z.to_f64()];
    let (mut d, mut sm, mut q) = (0.0, [0.0; 3], [0.0; 6]);
    let pairs = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];
    for fi in 0..h.faces().len() {
        let idx = h.face_vertices(fi);
        let a = f(h.vertices()[idx[0] as usize]);
        for i in 1..idx.len() - 1 {
            let b = f(h.vertices()[idx[i] as usize]);
            let c = f(h.vertices()[idx[i + 1] as usize]);
            let det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]);
            let sum = [a[0] + b[0] + c[0], a[1] + b[1] + c[1], a[2] + b[2] + c[2]];
            d += det;
            for k in 0..3 {
                sm[k] += det * sum[k];
            }
            for (e, &(i, j)) in pairs.iter().enumerate() {
                q[e] += det * (a[i] * a[j] + b[i] * b[j] + c[i] * c[j] + sum[i] * sum[j]);
            }
        }
    }
    let vol = d / 6.0;
    let c = [sm[0] / (4.0 * d), sm[1] / (4.0 * d), sm[2] / (4.0 * d)];
    let cov: Vec<f64> = pairs
        .iter()
        .enumerate()
        .map(|(e, &(i, j))| q[e] / 120.0 - vol * c[i] * c[j])
        .collect();
    let inertia = [
        rho * (cov[1] + cov[2]),
        rho * (cov[0] + cov[2]),
        rho * (cov[0] + cov[1]),
        -rho * cov[3],
        -rho * cov[4],
        -rho * cov[5],
    ];
    (rho * vol, c, inertia)
}

fn entries(m: &SymMat3) -> [Scalar; 6] {
    [m.xx, m.yy, m.zz, m.xy, m.xz, m.yz]
}

#[test]
fn cube_corners_give_8_vertices_6_quads_12_edges() {
    let h = ConvexHull::from_points(&cube_corners(Vec3::from_ints(1, 1, 1))).unwrap();
    assert_eq!(
        (h.vertices().len(), h.faces().len(), h.edges().len()),
        (8, 6, 12)
    );
    assert!(h.faces().iter().all(|f| f.vertex_count() == 4));
    check_valid(&h, &[]);
    // Canonical layout: vertices sorted, faces by index list.
    assert_eq!(h.vertices()[0], Vec3::from_ints(-1, -1, -1));
    assert_eq!(h.vertices()[7], Vec3::from_ints(1, 1, 1));
    assert_eq!(h.face_vertices(0), &[0, 1, 3, 2]); // the x = −1 face
    assert_eq!(h.faces()[0].normal(), -Vec3::X);
    assert_eq!(h.faces()[0].offset(), Scalar::ONE);
}

#[test]
fn box_hull_mass_properties_equal_the_cuboid_bit_for_bit() {
    for (half, rho) in [
        ((0.3, 0.7, 1.1), 7.3),
        ((0.5, 0.5, 0.5), 1000.0),
        ((2.0, 0.05, 0.9), 450.0),
    ] {
        let he = v(half.0, half.1, half.2);
        let cuboid = Shape::from(Cuboid::new(he).unwrap())
            .mass_properties(s(rho))
            .unwrap();
        let hull = ConvexHull::from_points(&cube_corners(he)).unwrap();
        assert_eq!(hull.mass_properties(s(rho)).unwrap(), cuboid);
        assert_eq!(hull.volume(), Cuboid::new(he).unwrap().volume());
        // Shifted away from the origin: same inertia about the (exact) centre.
        let offset = v(3.25, -1.5, 0.125);
        let moved: Vec<Vec3> = cube_corners(he).iter().map(|&c| c + offset).collect();
        let mp = ConvexHull::from_points(&moved)
            .unwrap()
            .mass_properties(s(rho))
            .unwrap();
        assert_eq!(mp.mass, cuboid.mass);
        assert_eq!(mp.local_center, offset);
        assert_eq!(mp.inertia, cuboid.inertia);
    }
}

#[test]
fn a_lattice_of_points_has_the_hull_of_its_corners() {
    // 5×5×5 grid: points on edges, on faces and inside, all exactly so.
    let mut pts = Vec::new();
    for i in 0..5 {
        for j in 0..5 {
            for k in 0..5 {
                pts.push(Vec3::new(
                    s(0.25 * i as f64),
                    s(0.5 * j as f64),
                    s(0.75 * k as f64),
                ));
            }
        }
    }
    let h = ConvexHull::from_points(&pts).unwrap();
    let corners = ConvexHull::from_points(
        &cube_corners(v(0.5, 1.0, 1.5))
            .iter()
            .map(|&c| c + v(0.5, 1.0, 1.5))
            .collect::<Vec<_>>(),
    )
    .unwrap();
    assert_eq!(h, corners);
    assert_eq!(
        (h.vertices().len(), h.faces().len(), h.edges().len()),
        (8, 6, 12)
    );
    check_valid(&h, &pts);
}

#[test]
fn an_octagonal_prism_has_two_octagons_and_eight_quads() {
    let mut pts = Vec::new();
    for i in 0..8 {
        let a = std::f64::consts::TAU * i as f64 / 8.0;
        for z in [-1.0, 1.0] {
            pts.push(v(a.cos(), a.sin(), z));
        }
    }
    let h = ConvexHull::from_points(&pts).unwrap();
    assert_eq!(
        (h.vertices().len(), h.faces().len(), h.edges().len()),
        (16, 10, 24)
    );
    let mut sizes: Vec<usize> = h.faces().iter().map(HullFace::vertex_count).collect();
    sizes.sort_unstable();
    assert_eq!(sizes, [4, 4, 4, 4, 4, 4, 4, 4, 8, 8]);
    check_valid(&h, &pts);
}

#[test]
fn hull_of_points_on_a_sphere_matches_the_f64_integrals_of_its_own_faces() {
    let mut worst = (0.0f64, 0.0f64, 0.0f64);
    for (n, seed) in [(32usize, 1u64), (64, 2), (100, 3), (200, 4)] {
        let pts = sphere_points(n, 2.0, seed);
        let h = ConvexHull::from_points(&pts).unwrap();
        // Points on a sphere are all extreme (unless two coincide after rounding).
        assert_eq!(h.vertices().len(), n);
        check_valid(&h, &pts);
        let rho = 2.5;
        let mp = h.mass_properties(s(rho)).unwrap();
        let (m, c, i) = reference(&h, rho);
        let em = (mp.mass.to_f64() - m).abs() / ULP;
        let ec = (0..3)
            .map(|k| (mp.local_center.get(k).to_f64() - c[k]).abs() / ULP)
            .fold(0.0, f64::max);
        let ei = entries(&mp.inertia)
            .iter()
            .zip(i)
            .map(|(got, want)| (got.to_f64() - want).abs() / ULP)
            .fold(0.0, f64::max);
        worst = (worst.0.max(em), worst.1.max(ec), worst.2.max(ei));
        assert!(
            em <= 0.6 && ec <= 0.6 && ei <= 0.6,
            "n {n}: mass {em}, centre {ec}, inertia {ei} ulp"
        );
        // Volume tends to the sphere's from below.
        let ball = 4.0 / 3.0 * std::f64::consts::PI * 8.0;
        assert!(h.volume().to_f64() < ball);
        assert!((h.volume().to_f64() - m / rho).abs() <= 0.6 * ULP * 1.0001);
    }
    eprintln!(
        "sphere hulls vs f64: worst mass {:.3} ulp, centre {:.3} ulp, inertia {:.3} ulp",
        worst.0, worst.1, worst.2
    );
}

#[test]
fn duplicate_interior_and_boundary_points_do_not_change_the_hull() {
    let base = sphere_points(60, 1.5, 7);
    let clean = ConvexHull::from_points(&base).unwrap();
    let mut extra = base.clone();
    extra.extend_from_slice(&base[..20]); // duplicates
    let mut g = Rng::new(99);
    for _ in 0..50 {
        // interior points
        extra.push(v(g.unit() - 0.5, g.unit() - 0.5, g.unit() - 0.5));
    }
    // Points exactly on faces and edges of the clean hull: the midpoint of
    // every edge whose sum is even (so the midpoint is exact), and the
    // centroid of triangle faces whose corners sum to a multiple of 3.
    for e in clean.edges() {
        let (a, b) = (
            clean.vertices()[e[0] as usize],
            clean.vertices()[e[1] as usize],
        );
        let sum = raw(a + b);
        if sum.iter().all(|c| c % 2 == 0) {
            extra.push((a + b).half());
        }
    }
    for fi in 0..clean.faces().len() {
        let idx = clean.face_vertices(fi);
        let sum = idx
            .iter()
            .fold(Vec3::ZERO, |acc, &i| acc + clean.vertices()[i as usize]);
        if raw(sum).iter().all(|c| c % idx.len() as i64 == 0) {
            extra.push(Vec3::new(
                sum.x.div_int(idx.len() as i64),
                sum.y.div_int(idx.len() as i64),
                sum.z.div_int(idx.len() as i64),
            ));
        }
    }
    shuffle(&mut g, &mut extra);
    let messy = ConvexHull::from_points(&extra).unwrap();
    assert_eq!(messy, clean);
    check_valid(&messy, &extra);

    // On a box, points on faces and edges are easy to make exact.
    let corners = cube_corners(Vec3::from_ints(2, 1, 3));
    let mut more = corners.clone();
    more.extend([
        Vec3::from_ints(0, 1, 0),  // face centre
        Vec3::from_ints(2, 1, 0),  // edge midpoint
        Vec3::from_ints(1, -1, 2), // on a face
        Vec3::from_ints(2, 0, -3), // edge midpoint
        Vec3::from_ints(0, 0, 0),  // centre
        Vec3::from_ints(2, 1, 3),  // duplicate corner
    ]);
    assert_eq!(
        ConvexHull::from_points(&more).unwrap(),
        ConvexHull::from_points(&corners).unwrap()
    );
}

#[test]
fn input_order_does_not_change_a_single_bit() {
    let pts = sphere_points(120, 3.0, 21);
    let reference = ConvexHull::from_points(&pts).unwrap();
    let mp = reference.mass_properties(s(1.25)).unwrap();
    let mut g = Rng::new(5);
    for _ in 0..5 {
        let mut shuffled = pts.clone();
        shuffle(&mut g, &mut shuffled);
        let h = ConvexHull::from_points(&shuffled).unwrap();
        assert_eq!(h, reference);
        assert_eq!(h.volume(), reference.volume());
        assert_eq!(h.mass_properties(s(1.25)).unwrap(), mp);
    }
    let mut reversed = pts;
    reversed.reverse();
    assert_eq!(ConvexHull::from_points(&reversed).unwrap(), reference);
}

#[test]
fn rotated_box_hull_matches_the_rotated_box_tensor() {
    let he = v(1.0, 0.5, 0.25);
    let rho = s(3.0);
    let boxed = Cuboid::new(he).unwrap().mass_properties(rho).unwrap();
    let quarter_pi = Scalar::PI.div_int(4);
    let axes = [
        Vec3::Z,
        v(1.0, 1.0, 0.0).try_normalize().unwrap(),
        v(0.3, -0.5, 0.8).try_normalize().unwrap(),
    ];
    for (k, axis) in axes.iter().enumerate() {
        let q = Quat::from_axis_angle(*axis, quarter_pi).normalize();
        let corners: Vec<Vec3> = cube_corners(he).iter().map(|&c| q.rotate(c)).collect();
        let h = ConvexHull::from_points(&corners).unwrap();
        assert_eq!(h.vertices().len(), 8);
        check_valid(&h, &corners);
        if k == 0 {
            // About z the rounded corners stay exactly coplanar per face.
            assert_eq!((h.faces().len(), h.edges().len()), (6, 12));
        }
        let mp = h.mass_properties(rho).unwrap();
        let rel_mass = (mp.mass.to_f64() / boxed.mass.to_f64() - 1.0).abs();
        assert!(rel_mass < 5e-9, "mass off by {rel_mass:e}");
        assert!(mp.local_center.abs().max_element().to_f64() < 1e-8);
        let want = boxed.inertia.rotate(&crate::math::Mat3::from_quat(q));
        let scale = boxed.inertia.diagonal().max_element().to_f64();
        let err = entries(&mp.inertia)
            .iter()
            .zip(entries(&want))
            .map(|(a, b)| (a.to_f64() - b.to_f64()).abs() / scale)
            .fold(0.0, f64::max);
        eprintln!("rotated box {k}: mass rel {rel_mass:e}, inertia rel {err:e}");
        assert!(
            err < 5e-9,
            "inertia off by {err:e}: {:?} vs {want:?}",
            mp.inertia
        );
    }
}

#[test]
fn flat_and_tiny_inputs_are_rejected_with_their_dimension() {
    let err = |pts: &[Vec3]| ConvexHull::from_points(pts).unwrap_err();
    assert_eq!(
        err(&[]),
        ShapeError::DegenerateHull {
            distinct_points: 0,
            dimension: 0
        }
    );
    assert_eq!(
        err(&[Vec3::X; 5]),
        ShapeError::DegenerateHull {
            distinct_points: 1,
            dimension: 0
        }
    );
    let line: Vec<Vec3> = (0..6).map(|i| Vec3::from_ints(i, 2 * i, -i)).collect();
    assert_eq!(
        err(&line),
        ShapeError::DegenerateHull {
            distinct_points: 6,
            dimension: 1
        }
    );
    let three = [Vec3::X, Vec3::Y, Vec3::Z];
    assert_eq!(
        err(&three),
        ShapeError::DegenerateHull {
            distinct_points: 3,
            dimension: 2
        }
    );
    // A grid on the tilted plane x + y + z = 1.
    let mut plane = Vec::new();
    for i in -3..4 {
        for j in -3..4 {
            plane.push(Vec3::from_ints(i, j, 1 - i - j));
        }
    }
    assert_eq!(
        err(&plane),
        ShapeError::DegenerateHull {
            distinct_points: 49,
            dimension: 2
        }
    );
    assert_eq!(
        err(&three).to_string(),
        "convex hull needs at least 4 points that are not coplanar; \
         got 3 distinct point(s) spanning 2 dimension(s)"
    );
    // One point off the plane is enough.
    plane.push(Vec3::from_ints(0, 0, 0));
    assert_eq!(ConvexHull::from_points(&plane).unwrap().vertices().len(), 5);
}

#[test]
fn coordinates_beyond_the_limit_are_rejected_by_index() {
    let lim = ConvexHull::COORDINATE_LIMIT;
    let mut pts = cube_corners(Vec3::splat(lim));
    assert!(
        ConvexHull::from_points(&pts).is_ok(),
        "the limit itself is accepted"
    );
    pts.push(Vec3::new(Scalar::ZERO, -lim - Scalar::DELTA, Scalar::ZERO));
    assert_eq!(
        ConvexHull::from_points(&pts),
        Err(ShapeError::HullCoordinateOutOfRange {
            index: 8,
            coordinate: -lim - Scalar::DELTA
        })
    );
    pts[8] = Vec3::new(Scalar::MIN, Scalar::ZERO, Scalar::ZERO);
    assert!(matches!(
        ConvexHull::from_points(&pts),
        Err(ShapeError::HullCoordinateOutOfRange { index: 8, .. })
    ));
}

#[test]
fn hull_at_the_coordinate_limit_has_exact_mass_properties() {
    // A thin rod reaching the limit along x: the predicates and integrals
    // must not overflow, and the result is still the box's, bit for bit.
    let lim = ConvexHull::COORDINATE_LIMIT;
    let thin = Scalar::from_ratio(1, 1024);
    let he = Vec3::new(lim, thin, thin);
    let hull = ConvexHull::from_points(&cube_corners(he)).unwrap();
    let rho = Scalar::from_ratio(1, 4096);
    let want = Cuboid::new(he).unwrap().mass_properties(rho).unwrap();
    assert_eq!(hull.mass_properties(rho), Ok(want));
    // The full cube at the limit: its mass does not fit, which is an error,
    // not an overflow inside the exact arithmetic.
    let big = ConvexHull::from_points(&cube_corners(Vec3::splat(lim))).unwrap();
    assert_eq!((big.vertices().len(), big.faces().len()), (8, 6));
    let (r, faults) = crate::math::FaultScope::run(|| big.mass_properties(Scalar::ONE));
    assert!(matches!(
        r,
        Err(ShapeError::MassOutOfRange {
            kind: "convex_hull",
            ..
        })
    ));
    assert!(faults.is_empty(), "{faults}");
}

#[test]
fn support_takes_the_lowest_index_among_ties() {
    let h = ConvexHull::from_points(&cube_corners(Vec3::from_ints(1, 1, 1))).unwrap();
    // Four vertices have x = 1; the lowest index among them is (1, −1, −1).
    assert_eq!(h.support_index(Vec3::X), 4);
    assert_eq!(h.support(Vec3::X), Vec3::from_ints(1, -1, -1));
    assert_eq!(h.support_index(Vec3::ZERO), 0);
    assert_eq!(h.support(v(0.1, 0.2, -0.3)), Vec3::from_ints(1, 1, -1));
    // Against brute force on a sphere hull.
    let hull = ConvexHull::from_points(&sphere_points(80, 1.0, 13)).unwrap();
    let mut g = Rng::new(3);
    for _ in 0..200 {
        let d = v(g.unit() - 0.5, g.unit() - 0.5, g.unit() - 0.5);
        let best = hull.vertices().iter().map(|p| p.dot_wide(d)).max().unwrap();
        assert_eq!(hull.support(d).dot_wide(d), best);
    }
}

#[test]
fn a_hull_rebuilt_from_its_vertices_is_identical_and_serde_round_trips() {
    let h = ConvexHull::from_points(&sphere_points(50, 0.75, 17)).unwrap();
    assert_eq!(ConvexHull::from_points(h.vertices()).unwrap(), h);
    let cfg = bincode::config::standard();
    let bytes = bincode::serde::encode_to_vec(&h, cfg).unwrap();
    let (back, _): (ConvexHull, usize) = bincode::serde::decode_from_slice(&bytes, cfg).unwrap();
    assert_eq!(back, h);
}

#[test]
fn a_thousand_random_points_build_a_valid_hull() {
    let mut g = Rng::new(1234);
    // Points in a cube, many coplanar by construction (snapped to a coarse
    // grid), to stress the exact predicates.
    let pts: Vec<Vec3> = (0..1000)
        .map(|_| {
            let c = |g: &mut Rng| Scalar::from_int((g.unit() * 9.0) as i32 - 4);
            Vec3::new(c(&mut g), c(&mut g), c(&mut g))
        })
        .collect();
    let h = ConvexHull::from_points(&pts).unwrap();
    check_valid(&h, &pts);
    assert!(h.vertices().iter().all(|p| pts.contains(p)));
    let fine: Vec<Vec3> = (0..1000)
        .map(|_| v(g.unit() * 4.0 - 2.0, g.unit() * 4.0 - 2.0, g.unit() - 0.5))
        .collect();
    let h = ConvexHull::from_points(&fine).unwrap();
    check_valid(&h, &fine);
}
