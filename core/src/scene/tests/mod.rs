//! Tests of the scene parser: the example scenes, exact numbers, rotations
//! and defaults here; every error with its position in `errors`; robustness
//! against malformed input in `fuzz`.

mod errors;
mod fuzz;

use super::rotation::degrees_to_radians;
use super::*;
use crate::math::{Quat, Scalar, Vec3};
use crate::world::WorldConfig;

pub(super) const PYRAMID: &str = include_str!("../../../../scenes/pyramid.toml");
pub(super) const SHAPES: &str = include_str!("../../../../scenes/shapes.toml");
pub(super) const SPIN: &str = include_str!("../../../../scenes/spin.toml");
const FORMAT_DOC: &str = include_str!("../../../../docs/scene-format.md");

pub(super) fn parse(text: &str) -> SceneDesc {
    parse_scene(text, "test.toml").unwrap_or_else(|e| panic!("{e}"))
}

pub(super) fn error(text: &str) -> String {
    match parse_scene(text, "test.toml") {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => e.to_string(),
    }
}

pub(super) fn s(text: &str) -> Scalar {
    crate::math::decimal::parse_exact(text).unwrap_or_else(|e| panic!("{text}: {e}"))
}

pub(super) fn v(x: &str, y: &str, z: &str) -> Vec3 {
    Vec3::new(s(x), s(y), s(z))
}

/// A body with one sphere, to which tests append lines.
pub(super) const BALL: &str = "[[bodies]]\nname = \"ball\"\nkind = \"dynamic\"\n[[bodies.shapes]]\nkind = \"sphere\"\nradius = 1\n";

// ---- example scenes ----

#[test]
fn pyramid_scene_has_a_ground_and_ten_crates_in_rows_of_4_3_2_1() {
    let scene = parse(PYRAMID);
    assert_eq!(scene.bodies.len(), 11);
    let ground = scene.body("ground").expect("ground");
    assert_eq!(ground.kind, BodyKindDesc::Static);
    assert_eq!(ground.position, v("0", "-0.5", "0"));
    assert_eq!(
        ground.shapes[0].geometry,
        GeometryDesc::Box {
            half_extents: v("20", "0.5", "20")
        }
    );
    assert_eq!(ground.shapes[0].friction, s("0.8"));
    let crates: Vec<&BodyDesc> = scene.bodies[1..].iter().collect();
    let per_row: Vec<usize> = ["0.5", "1.5", "2.5", "3.5"]
        .iter()
        .map(|y| crates.iter().filter(|b| b.position.y == s(y)).count())
        .collect();
    assert_eq!(per_row, vec![4, 3, 2, 1]);
    for c in &crates {
        assert_eq!(c.kind, BodyKindDesc::Dynamic);
        assert_eq!(c.shapes[0].density_or_mass, MassSpec::Density(s("500")));
        assert_eq!(c.shapes[0].friction, s("0.6"));
        assert_eq!(c.shapes[0].restitution, Scalar::ZERO);
        assert_eq!(c.shapes[0].material.as_deref(), Some("crate"));
    }
    assert_eq!(
        scene.body("crate_10").map(|b| b.position),
        Some(v("0", "3.5", "0"))
    );
    assert_eq!(scene.world.dt(), Scalar::from_ratio(1, 60));
    assert_eq!(scene.world.substep_dt(), Scalar::from_ratio(1, 240));
}

#[test]
fn shapes_scene_has_every_shape_kind_a_compound_a_kinematic_and_a_spinning_body() {
    let scene = parse(SHAPES);
    let mut kinds: Vec<&str> = scene
        .bodies
        .iter()
        .flat_map(|b| b.shapes.iter().map(|s| s.geometry.kind_name()))
        .collect();
    kinds.sort_unstable();
    kinds.dedup();
    assert_eq!(
        kinds,
        vec![
            "box",
            "capsule",
            "convex_hull",
            "heightfield",
            "sphere",
            "trimesh"
        ]
    );
    for b in &scene.bodies {
        for sh in &b.shapes {
            if sh.geometry.is_static_only() {
                assert_eq!(b.kind, BodyKindDesc::Static, "{}", b.name);
            }
        }
    }
    assert_eq!(scene.body("dumbbell").map(|b| b.shapes.len()), Some(3));
    assert_eq!(scene.body("top").map(|b| b.shapes.len()), Some(2));
    let platform = scene.body("platform").expect("platform");
    assert_eq!(platform.kind, BodyKindDesc::Kinematic);
    assert_eq!(platform.linear_velocity, Vec3::X);
    let top = scene.body("top").expect("top");
    assert_eq!(top.angular_velocity, Vec3::from_ints(0, 20, 0));
    assert_eq!(top.shapes[1].friction, s("0.3"));
    assert_eq!(top.shapes[1].restitution, s("0.1"));

    let hill = scene.body("hill").expect("hill");
    match &hill.shapes[0].geometry {
        GeometryDesc::HeightField {
            rows,
            cols,
            heights,
            scale,
        } => {
            assert_eq!((*rows, *cols, heights.len()), (4, 5, 20));
            assert_eq!(heights[7], s("0.8"));
            assert_eq!(*scale, v("1", "1.5", "1"));
        }
        other => panic!("hill is {other:?}"),
    }
    let floor = scene.body("floor").expect("floor");
    match &floor.shapes[0].geometry {
        GeometryDesc::TriMesh { vertices, indices } => {
            assert_eq!(vertices.len(), 4);
            assert_eq!(indices, &vec![[0, 1, 2], [0, 2, 3]]);
        }
        other => panic!("floor is {other:?}"),
    }
    let zone = scene.body("goal_zone").expect("goal_zone");
    assert!(zone.shapes[0].trigger);
    assert_eq!((zone.shapes[0].group, zone.shapes[0].mask), (4, 1));
    let dumbbell = scene.body("dumbbell").expect("dumbbell");
    assert!(dumbbell.asleep);
    assert_eq!(dumbbell.shapes[1].collision_group, -1);
    assert_eq!(dumbbell.shapes[1].offset, v("-0.5", "0", "0"));
    let pill = scene.body("pill").expect("pill");
    assert_eq!(pill.shapes[0].density_or_mass, MassSpec::Mass(s("2")));
    let ball = scene.body("ball").expect("ball");
    assert_eq!(ball.shapes[0].density_or_mass, MassSpec::Density(s("1100")));
    assert_eq!(ball.shapes[0].restitution, s("0.8"));
    // Lines point at the [[bodies]] and [[bodies.shapes]] headers.
    let line_of = |needle: &str| {
        SHAPES
            .lines()
            .position(|l| l.contains(needle))
            .map(|i| i as u32 + 1)
    };
    assert_eq!(Some(ball.line), line_of("name = \"ball\"").map(|l| l - 1));
    assert_eq!(
        Some(ball.shapes[0].line),
        line_of("radius = 0.5").map(|l| l - 2)
    );
    assert_eq!(
        scene
            .materials
            .iter()
            .map(|(n, _)| n.as_str())
            .collect::<Vec<_>>(),
        vec!["stone", "rubber", "ice"]
    );
}

#[test]
fn spin_scene_spins_a_box_about_its_intermediate_axis_without_gravity() {
    let scene = parse(SPIN);
    assert_eq!(scene.world.gravity, Vec3::ZERO);
    assert_eq!(scene.world.substeps, 8);
    let racket = &scene.bodies[0];
    let GeometryDesc::Box { half_extents: h } = racket.shapes[0].geometry else {
        panic!("racket is not a box");
    };
    // Principal moments ∝ (b² + c², a² + c², a² + b²): y must be the middle one.
    let sq = |a: Scalar, b: Scalar| a * a + b * b;
    let (ix, iy, iz) = (sq(h.y, h.z), sq(h.x, h.z), sq(h.x, h.y));
    assert!(iz < iy && iy < ix, "{ix} {iy} {iz}");
    let w = racket.angular_velocity;
    assert_eq!(w, v("0.005", "5", "0.005"));
    assert!(w.y > w.x.mul_int(100) && w.y > w.z.mul_int(100));
}

#[test]
fn the_complete_example_in_the_format_doc_parses() {
    let start = FORMAT_DOC
        .find("## Complete example")
        .and_then(|i| FORMAT_DOC[i..].find("```toml\n").map(|j| i + j + 8))
        .expect("example block");
    let end = start + FORMAT_DOC[start..].find("```").expect("end of block");
    let scene = parse(&FORMAT_DOC[start..end]);
    assert_eq!(scene.bodies.len(), 4);
    let ball = scene.body("ball").expect("ball");
    let sh = &ball.shapes[0];
    assert_eq!((sh.friction, sh.restitution), (Scalar::ONE, s("0.8")));
    assert_eq!(sh.density_or_mass, MassSpec::Density(DEFAULT_DENSITY));
    let crate_ = scene.body("crate").expect("crate");
    assert_eq!(
        crate_.shapes[0].density_or_mass,
        MassSpec::Density(s("700"))
    );
    assert_eq!(crate_.shapes[0].mask, 0xFFFF_FFFD);
    assert_eq!(
        crate_.shapes[1].density_or_mass,
        MassSpec::Mass(Scalar::TWO)
    );
    assert_eq!(
        scene.body("ramp").map(|b| b.shapes[0].restitution),
        Some(Scalar::ZERO)
    );
}

// ---- numbers ----

#[test]
fn decimals_convert_exactly_from_their_digits() {
    let scene = parse(&format!(
        "{BALL}friction = 0.1\nrestitution = 1e-3\ndensity = 1_000.5\n"
    ));
    let shape = &scene.bodies[0].shapes[0];
    assert_eq!(shape.friction.to_bits(), 429_496_730);
    // 2^32 / 1000 = 4294967.296 -> 4294967.
    assert_eq!(shape.restitution.to_bits(), 4_294_967);
    assert_eq!(
        shape.density_or_mass,
        MassSpec::Density(Scalar::from_ratio(2001, 2))
    );
}

#[test]
fn integers_and_hex_integers_are_exact_scalars() {
    let scene = parse(&format!(
        "[world]\ngravity = [0, -10, 0x10]\n{BALL}offset = [2147483647, -2147483648, 0]\n"
    ));
    assert_eq!(scene.world.gravity, Vec3::from_ints(0, -10, 16));
    let offset = scene.bodies[0].shapes[0].offset;
    assert_eq!(offset.x, Scalar::from_int(i32::MAX));
    assert_eq!(offset.y, Scalar::MIN);
}

#[test]
fn an_empty_file_is_an_empty_world_with_default_settings() {
    let scene = parse("");
    assert!(scene.bodies.is_empty() && scene.materials.is_empty());
    assert_eq!(scene.world, WorldConfig::default());
    // 9.81 × 2^32 = 42133629173.76 -> 42133629174.
    assert_eq!(scene.world.gravity, v("0", "-9.81", "0"));
    assert_eq!(scene.world.gravity.y.to_bits(), -42_133_629_174);
    assert_eq!((scene.world.tick_rate, scene.world.substeps), (60, 4));
}

#[test]
fn defaults_fill_every_optional_body_and_shape_key() {
    let scene = parse(BALL);
    let b = &scene.bodies[0];
    assert_eq!(
        (
            b.position,
            b.rotation,
            b.linear_velocity,
            b.angular_velocity
        ),
        (Vec3::ZERO, Quat::IDENTITY, Vec3::ZERO, Vec3::ZERO)
    );
    assert_eq!(
        (b.linear_damping, b.angular_damping, b.asleep),
        (Scalar::ZERO, Scalar::ZERO, false)
    );
    assert_eq!(b.line, 1);
    let sh = &b.shapes[0];
    assert_eq!(
        sh.geometry,
        GeometryDesc::Sphere {
            radius: Scalar::ONE
        }
    );
    assert_eq!((sh.offset, sh.rotation), (Vec3::ZERO, Quat::IDENTITY));
    assert_eq!(
        sh.density_or_mass,
        MassSpec::Density(Scalar::from_int(1000))
    );
    assert_eq!((sh.friction, sh.restitution), (Scalar::HALF, Scalar::ZERO));
    assert_eq!(
        (sh.group, sh.mask, sh.collision_group, sh.trigger),
        (1, u32::MAX, 0, false)
    );
    assert_eq!(sh.material, None);
    assert_eq!(sh.line, 4);
}

#[test]
fn shape_keys_override_the_material_and_the_material_overrides_defaults() {
    let text = format!(
        "[materials.wood]\nfriction = 0.4\nrestitution = 0.25\ndensity = 700\n[materials.plain]\n{BALL}material = \"wood\"\nfriction = 0.7\n[[bodies.shapes]]\nkind = \"sphere\"\nradius = 1\nmaterial = \"plain\"\n"
    );
    let scene = parse(&text);
    let [a, b] = &scene.bodies[0].shapes[..] else {
        panic!("two shapes expected");
    };
    assert_eq!((a.friction, a.restitution), (s("0.7"), s("0.25")));
    assert_eq!(a.density_or_mass, MassSpec::Density(s("700")));
    assert_eq!((b.friction, b.restitution), (Scalar::HALF, Scalar::ZERO));
    assert_eq!(b.density_or_mass, MassSpec::Density(DEFAULT_DENSITY));
    assert_eq!(
        scene.material("wood"),
        Some(&MaterialDesc {
            friction: s("0.4"),
            restitution: s("0.25"),
            density: Some(s("700")),
        })
    );
}

// ---- rotations ----

#[test]
fn degrees_convert_to_the_nearest_radians() {
    assert_eq!(degrees_to_radians(Scalar::from_int(180)), Scalar::PI);
    assert_eq!(degrees_to_radians(Scalar::from_int(90)), Scalar::FRAC_PI_2);
    assert_eq!(
        degrees_to_radians(Scalar::from_int(-90)),
        -Scalar::FRAC_PI_2
    );
    // Whole turns are removed exactly before converting.
    assert_eq!(degrees_to_radians(Scalar::from_int(540)), Scalar::PI);
    assert_eq!(degrees_to_radians(Scalar::from_int(-720)), Scalar::ZERO);
    // 1° = 0.017453292519943295769... rad; × 2^32 = 74961320.576 -> 74961321.
    assert_eq!(degrees_to_radians(Scalar::ONE).to_bits(), 74_961_321);
}

#[test]
fn axis_angle_rotations_become_unit_quaternions() {
    let scene = parse(&format!(
        "{BALL}rotation = {{ axis = [0, 0, 2], angle_deg = 90 }}\n"
    ));
    let q = scene.bodies[0].shapes[0].rotation;
    // cos 45° = sin 45° = 0.7071067811865475244 -> bits 3037000499.97605 -> 3037000500.
    let half = 3_037_000_500i64;
    assert!((q.z.to_bits() - half).abs() <= 2, "{q:?}");
    assert!((q.w.to_bits() - half).abs() <= 2, "{q:?}");
    assert_eq!((q.x, q.y), (Scalar::ZERO, Scalar::ZERO));
    // Rotating x by 90° about z gives y, to a few ulps.
    let r = q.rotate(Vec3::X);
    assert!(
        r.x.abs().to_bits() <= 8 && (r.y - Scalar::ONE).abs().to_bits() <= 8,
        "{r:?}"
    );
}

#[test]
fn quaternions_name_their_order_and_near_unit_ones_are_normalised() {
    // The same rotation (90° about y) in every form.
    let half = Scalar::from_bits(3_037_000_500); // cos 45°, rounded
    let forms = [
        "quat_xyzw = [0, 0.7071068, 0, 0.7071068]",
        "quat_wxyz = [0.7071068, 0, 0.7071068, 0]",
        "quaternion = [0.7071068, 0, 0.7071068, 0]",
        "axis = [0, 1, 0], angle_deg = 90",
        "euler_deg = [0, 90, 0]",
    ];
    for form in forms {
        let scene = parse(&format!("{BALL}rotation = {{ {form} }}\n"));
        let q = scene.bodies[0].shapes[0].rotation;
        assert!(
            (q.w - half).abs().to_bits() <= 4 && (q.y - half).abs().to_bits() <= 4,
            "{form}: {q:?}"
        );
        assert_eq!((q.x, q.z), (Scalar::ZERO, Scalar::ZERO), "{form}");
    }
    // Exactly unit: kept as written, sign included.
    let scene = parse(&format!(
        "{BALL}rotation = {{ quat_xyzw = [0, 0, -1, 0] }}\n"
    ));
    assert_eq!(
        scene.bodies[0].shapes[0].rotation,
        Quat::from_xyzw(Scalar::ZERO, Scalar::ZERO, Scalar::NEG_ONE, Scalar::ZERO)
    );
}

#[test]
fn euler_angles_apply_in_the_given_order_about_the_parent_axes() {
    let rot =
        |e: &str| parse(&format!("{BALL}rotation = {{ {e} }}\n")).bodies[0].shapes[0].rotation;
    let near = |a: Vec3, b: [f64; 3]| {
        (a.x.to_f64() - b[0]).abs() < 1e-8
            && (a.y.to_f64() - b[1]).abs() < 1e-8
            && (a.z.to_f64() - b[2]).abs() < 1e-8
    };
    // x by 90° first, then z by 90°: +y goes to +z, then stays (z axis).
    // +x stays under the first, then goes to +y.
    let q = rot("euler_deg = [90, 0, 90]");
    assert!(
        near(q.rotate(Vec3::Y), [0.0, 0.0, 1.0]),
        "{:?}",
        q.rotate(Vec3::Y)
    );
    assert!(
        near(q.rotate(Vec3::X), [0.0, 1.0, 0.0]),
        "{:?}",
        q.rotate(Vec3::X)
    );
    // z first, then x: +x goes to +y, then to +z.
    let q = rot("euler_deg = [90, 0, 90], euler_order = \"zxy\"");
    assert!(
        near(q.rotate(Vec3::X), [0.0, 0.0, 1.0]),
        "{:?}",
        q.rotate(Vec3::X)
    );
}

#[test]
fn world_settings_reach_the_world() {
    let scene = parse(
        "[world]\nsolver_iterations = 4\nrelax_iterations = 2\ncontact_hertz = 30\ncontact_damping_ratio = 1\ncontact_margin = 0.01\nbroad_phase_margin = 0.2\nmax_push_out = 1.5\nrestitution_threshold = 0.5\nsleep = false\nsleep_linear_threshold = 0.01\nsleep_angular_threshold = 0.02\ntime_to_sleep = 2\n",
    );
    let c = scene.world;
    assert_eq!((c.solver_iterations, c.relax_iterations), (4, 2));
    assert_eq!(c.contact_hertz, Scalar::from_int(30));
    assert_eq!(c.contact_damping_ratio, Scalar::ONE);
    assert_eq!(c.contact_margin, Scalar::from_ratio(1, 100));
    assert_eq!(c.broad_phase_margin, Scalar::from_ratio(1, 5));
    assert_eq!(c.max_push_out, Scalar::from_ratio(3, 2));
    assert_eq!(c.restitution_threshold, Scalar::HALF);
    assert!(!c.sleep.enabled);
    assert_eq!(c.sleep.linear_threshold, Scalar::from_ratio(1, 100));
    assert_eq!(c.sleep.angular_threshold, Scalar::from_ratio(1, 50));
    assert_eq!(c.sleep.time_to_sleep, Scalar::from_int(2));
    let world = build_world(&scene, "test.toml").unwrap();
    assert_eq!(world.config(), &c);
    // Left out: the defaults.
    assert_eq!(parse("").world, WorldConfig::default());
}

#[test]
fn bullet_marks_a_dynamic_body_for_continuous_collision_and_is_refused_elsewhere() {
    let scene = parse(&BALL.replace("\"dynamic\"", "\"dynamic\"\nbullet = true"));
    assert!(scene.bodies[0].bullet);
    assert!(!parse(BALL).bodies[0].bullet);
    let world = build_world(&scene, "test.toml").unwrap();
    let h = world.find_body("ball").unwrap();
    assert_eq!(world.is_bullet(h), Ok(true));
    let e = error(&BALL.replace("\"dynamic\"", "\"kinematic\"\nbullet = true"));
    assert_eq!(
        e,
        "test.toml:4:10: body \"ball\": only dynamic bodies can be bullets; this body is kinematic"
    );
    let e = error(&BALL.replace("\"dynamic\"", "\"dynamic\"\nbullet = 1"));
    assert!(e.starts_with("test.toml:4:10:"), "{e}");
}
