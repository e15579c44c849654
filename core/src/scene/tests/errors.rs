//! Every kind of error, asserted with its exact `file:line:column: message`.

use super::{BALL, error};
use crate::scene::*;

// ---- errors: each with its position and message ----

/// Asserts `text` fails with exactly `expected` (file:line:col: message).
pub(super) fn assert_error(text: &str, expected: &str) {
    assert_eq!(error(text), expected, "input:\n{text}");
}

#[test]
fn syntax_errors_are_located() {
    assert_error(
        "[world]\ngravity = [0, -9.81, 0\n",
        "test.toml:2:23: TOML syntax error: unclosed array, expected `]`",
    );
    assert_error(
        "[world]\nsubsteps = 4\nsubsteps = 5\n",
        "test.toml:3:1: TOML syntax error: duplicate key",
    );
}

#[test]
fn unknown_shape_kind_names_the_valid_kinds() {
    assert_error(
        "[[bodies]]\nname = \"crate_3\"\nkind = \"dynamic\"\n[[bodies.shapes]]\nkind = \"cube\"\n",
        "test.toml:5:8: body \"crate_3\", shape 1: unknown shape kind \"cube\" (expected one of: sphere, capsule, box, convex_hull, trimesh, heightfield)",
    );
}

#[test]
fn unknown_keys_are_rejected_with_a_suggestion() {
    assert_error(
        &BALL.replace("radius = 1", "raduis = 1"),
        "test.toml:6:1: body \"ball\", shape 1: unknown key \"raduis\" in a sphere shape (did you mean \"radius\"? expected one of: kind, offset, rotation, density, mass, material, friction, restitution, group, mask, collision_group, trigger, radius)",
    );
    assert_error(
        "[world]\n  tickrate = 60\n",
        "test.toml:2:3: world: unknown key \"tickrate\" in [world] (did you mean \"tick_rate\"? expected one of: gravity, tick_rate, substeps, solver_iterations, relax_iterations, contact_hertz, contact_damping_ratio, contact_margin, broad_phase_margin, max_push_out, restitution_threshold, contact_order, contact_rows, sleep, sleep_linear_threshold, sleep_angular_threshold, time_to_sleep)",
    );
    assert_error(
        "[physics]\n",
        "test.toml:1:2: unknown key \"physics\" in the top level (expected one of: world, materials, bodies, joints)",
    );
    assert_error(
        &format!("{BALL}rotation = {{ axis = [0, 1, 0], angle = 3 }}\n"),
        "test.toml:7:32: body \"ball\", shape 1: unknown key \"rotation.angle\" in a rotation (expected one of: axis, angle_deg, quat_xyzw, quat_wxyz, quaternion, euler_deg, euler_order)",
    );
}

#[test]
fn missing_required_keys_point_at_their_table() {
    assert_error(
        "[[bodies]]\nname = \"a\"\n[[bodies.shapes]]\nkind = \"box\"\n",
        "test.toml:1:1: body \"a\": missing required key \"kind\" (one of: static, dynamic, kinematic)",
    );
    assert_error(
        "\n[[bodies]]\nkind = \"static\"\n",
        "test.toml:2:1: body #1: missing required key \"name\" (a unique string)",
    );
    assert_error(
        "[[bodies]]\nname = \"a\"\nkind = \"static\"\n[[bodies.shapes]]\nkind = \"box\"\n",
        "test.toml:4:1: body \"a\", shape 1: missing required key \"half_extents\" ([x, y, z] half-sizes in metres)",
    );
    assert_error(
        "[[bodies]]\nname = \"a\"\nkind = \"static\"\n",
        "test.toml:1:1: body \"a\": missing required key \"shapes\" (at least one [[bodies.shapes]] table)",
    );
}

#[test]
fn wrong_types_say_what_was_expected() {
    assert_error(
        &BALL.replace("radius = 1", "radius = \"1\""),
        "test.toml:6:10: body \"ball\", shape 1: radius must be a number, found a string",
    );
    assert_error(
        "[world]\ngravity = [0, -9.81]\n",
        "test.toml:2:11: world: gravity must be an array of 3 numbers [x, y, z], found 2 elements",
    );
    assert_error(
        "[world]\ntick_rate = 60.0\n",
        "test.toml:2:13: world: tick_rate must be an integer (a positive number of ticks per second, 1 to 10000), found a float",
    );
    assert_error(
        &format!("{BALL}trigger = 1\n"),
        "test.toml:7:11: body \"ball\", shape 1: trigger must be true or false, found an integer",
    );
}

#[test]
fn non_finite_and_out_of_range_numbers_are_rejected() {
    assert_error(
        "[world]\ngravity = [0, -inf, 0]\n",
        "test.toml:2:15: world: gravity[1] must be a finite number, found -inf (inf and nan are not allowed)",
    );
    assert_error(
        &BALL.replace("radius = 1", "radius = nan"),
        "test.toml:6:10: body \"ball\", shape 1: radius must be a finite number, found nan (inf and nan are not allowed)",
    );
    assert_error(
        &BALL.replace("radius = 1", "radius = 3e9"),
        "test.toml:6:10: body \"ball\", shape 1: radius = 3e9 is outside the fixed-point range ±2147483648",
    );
    assert_error(
        &BALL.replace("radius = 1", "radius = 4294967296"),
        "test.toml:6:10: body \"ball\", shape 1: radius = 4294967296 is outside the fixed-point range ±2147483648",
    );
}

#[test]
fn values_outside_their_ranges_are_rejected() {
    let cases: [(&str, &str); 9] = [
        (
            "radius = -1",
            "6:10: body \"ball\", shape 1: radius must be positive (metres), found -1",
        ),
        (
            "radius = 1\ndensity = 0",
            "7:11: body \"ball\", shape 1: density must be positive (kg/m³), found 0",
        ),
        (
            "radius = 1\nmass = -2.5",
            "7:8: body \"ball\", shape 1: mass must be positive (kg), found -2.5",
        ),
        (
            "radius = 1\nfriction = -0.1",
            "7:12: body \"ball\", shape 1: friction must be ≥ 0 (a friction coefficient), found -0.1",
        ),
        (
            "radius = 1\nrestitution = 1.01",
            "7:15: body \"ball\", shape 1: restitution must be between 0 and 1 (0: no bounce, 1: fully elastic), found 1.01",
        ),
        (
            "radius = 1\nmask = -1",
            "7:8: body \"ball\", shape 1: mask must be category bits, 0 to 0xFFFFFFFF, found -1",
        ),
        (
            "radius = 1\ngroup = 0x1_0000_0000",
            "7:9: body \"ball\", shape 1: group must be category bits, 0 to 0xFFFFFFFF, found 0x1_0000_0000",
        ),
        (
            "radius = 1\ncollision_group = 2147483648",
            "7:19: body \"ball\", shape 1: collision_group must be a 32-bit signed group index, found 2147483648",
        ),
        (
            "radius = 1\noffset = [0, 0, 0]\nrestitution = -0.0001",
            "8:15: body \"ball\", shape 1: restitution must be between 0 and 1 (0: no bounce, 1: fully elastic), found -0.0001",
        ),
    ];
    for (replacement, expected) in cases {
        assert_error(
            &BALL.replace("radius = 1", replacement),
            &format!("test.toml:{expected}"),
        );
    }
    assert_error(
        "[world]\ntick_rate = 0\n",
        "test.toml:2:13: world: tick_rate must be a positive number of ticks per second, 1 to 10000, found 0",
    );
    assert_error(
        "[world]\ntick_rate = -60\n",
        "test.toml:2:13: world: tick_rate must be a positive number of ticks per second, 1 to 10000, found -60",
    );
    assert_error(
        "[world]\nsubsteps = 0\n",
        "test.toml:2:12: world: substeps must be 1 to 64, found 0",
    );
    assert_error(
        "[world]\nsubsteps = 65\n",
        "test.toml:2:12: world: substeps must be 1 to 64, found 65",
    );
    assert_error(
        &format!("{BALL}[materials.mud]\nrestitution = 2\n"),
        "test.toml:8:15: material \"mud\": restitution must be between 0 and 1 (0: no bounce, 1: fully elastic), found 2",
    );
    assert_error(
        &BALL.replace(
            "kind = \"dynamic\"",
            "kind = \"dynamic\"\nlinear_damping = -1",
        ),
        "test.toml:4:18: body \"ball\": linear_damping must be ≥ 0 (1/s), found -1",
    );
    assert_error(
        "[[bodies]]\nname = \"b\"\nkind = \"dynamic\"\n[[bodies.shapes]]\nkind = \"box\"\nhalf_extents = [1, 0, 1]\n",
        "test.toml:6:16: body \"b\", shape 1: half_extents[1] must be positive (metres), found 0",
    );
}

#[test]
fn duplicate_body_names_are_rejected() {
    assert_error(
        &format!("{BALL}\n{BALL}"),
        "test.toml:9:8: body #2: duplicate body name \"ball\" (first used by the body on line 1; names must be unique)",
    );
}

#[test]
fn undefined_materials_are_rejected() {
    assert_error(
        &format!("[materials.wood]\n[materials.ice]\n{BALL}material = \"steel\"\n"),
        "test.toml:9:12: body \"ball\", shape 1: material \"steel\" is not defined (defined materials: wood, ice)",
    );
    assert_error(
        &format!("{BALL}material = \"steel\"\n"),
        "test.toml:7:12: body \"ball\", shape 1: material \"steel\" is not defined (no materials are defined)",
    );
}

#[test]
fn static_only_shapes_on_moving_bodies_are_rejected() {
    assert_error(
        "[[bodies]]\nname = \"X\"\nkind = \"dynamic\"\n[[bodies.shapes]]\nkind = \"trimesh\"\nvertices = [[0,0,0],[1,0,0],[0,0,1]]\nindices = [[0,1,2]]\n",
        "test.toml:5:8: body \"X\", shape 1: trimesh shapes are static only: body \"X\" is dynamic (expected kind = \"static\" on the body)",
    );
    assert_error(
        "[[bodies]]\nname = \"H\"\nkind = \"kinematic\"\n[[bodies.shapes]]\nkind = \"heightfield\"\nrows = 2\ncols = 2\nheights = [0, 0, 0, 0]\n",
        "test.toml:5:8: body \"H\", shape 1: heightfield shapes are static only: body \"H\" is kinematic (expected kind = \"static\" on the body)",
    );
    assert_error(
        &BALL.replace("\"dynamic\"", "\"static\"\nlinear_velocity = [0, 1, 0]"),
        "test.toml:4:19: body \"ball\": static bodies cannot move: linear_velocity must be zero (use kind = \"kinematic\" for a moving body that is not pushed)",
    );
}

#[test]
fn bad_trimesh_indices_are_rejected() {
    let mesh = |indices: &str| {
        format!(
            "[[bodies]]\nname = \"m\"\nkind = \"static\"\n[[bodies.shapes]]\nkind = \"trimesh\"\nvertices = [[0,0,0],[1,0,0],[0,0,1]]\nindices = {indices}\n"
        )
    };
    assert_error(
        &mesh("[[0, 1, 3]]"),
        "test.toml:7:19: body \"m\", shape 1: indices[0][2] must be a vertex index, 0 to 2 (vertices has 3 entries), found 3",
    );
    assert_error(
        &mesh("[[0, -1, 2]]"),
        "test.toml:7:16: body \"m\", shape 1: indices[0][1] must be a vertex index, 0 to 2 (vertices has 3 entries), found -1",
    );
    assert_error(
        &mesh("[[0, 1, 2], [2, 2, 1]]"),
        "test.toml:7:23: body \"m\", shape 1: indices[1] = [2, 2, 1] repeats a vertex (expected three distinct indices)",
    );
    assert_error(
        &mesh("[[0, 1]]"),
        "test.toml:7:12: body \"m\", shape 1: indices[0] must have 3 to 3 elements, found 2",
    );
    assert_error(
        &mesh("[]"),
        "test.toml:7:11: body \"m\", shape 1: indices must have 1 to 1048576 elements, found 0",
    );
}

#[test]
fn bad_heightfield_dimensions_are_rejected() {
    let field = |rest: &str| {
        format!(
            "[[bodies]]\nname = \"h\"\nkind = \"static\"\n[[bodies.shapes]]\nkind = \"heightfield\"\n{rest}\n"
        )
    };
    assert_error(
        &field("rows = 2\ncols = 3\nheights = [0, 1, 2, 3, 4]"),
        "test.toml:8:11: body \"h\", shape 1: heights has 5 values but rows × cols = 2 × 3 = 6 (expected one height per sample, row-major)",
    );
    assert_error(
        &field("rows = 1\ncols = 3\nheights = [0, 1, 2]"),
        "test.toml:6:8: body \"h\", shape 1: rows must be an integer from 2 to 4096, found 1",
    );
    assert_error(
        &field("rows = 2\ncols = 2\nheights = [0, 1, 2, 3]\nscale = [1, 1, -1]"),
        "test.toml:9:9: body \"h\", shape 1: scale[2] must be positive (metres per column, height multiplier, metres per row), found -1",
    );
}

#[test]
fn flat_convex_hulls_are_rejected() {
    assert_error(
        "[[bodies]]\nname = \"c\"\nkind = \"dynamic\"\n[[bodies.shapes]]\nkind = \"convex_hull\"\npoints = [[0,0,0],[1,0,0],[0,1,0],[1,1,0],[0.5,0.5,0]]\n",
        "test.toml:6:10: body \"c\", shape 1: points are all in one plane (expected at least 4 points that enclose a volume)",
    );
    assert_error(
        "[[bodies]]\nname = \"c\"\nkind = \"dynamic\"\n[[bodies.shapes]]\nkind = \"convex_hull\"\npoints = [[0,0,0],[1,0,0],[0,1,0]]\n",
        "test.toml:6:10: body \"c\", shape 1: points must have 4 to 1024 elements, found 3",
    );
}

#[test]
fn zero_rotations_are_rejected() {
    assert_error(
        &format!("{BALL}rotation = {{ quaternion = [0, 0, 0, 0] }}\n"),
        "test.toml:7:27: body \"ball\", shape 1: rotation.quaternion must not be zero (expected a unit quaternion)",
    );
    assert_error(
        &format!("{BALL}rotation = {{ axis = [0, 0.0, 0], angle_deg = 45 }}\n"),
        "test.toml:7:21: body \"ball\", shape 1: rotation.axis must not be the zero vector (expected a direction [x, y, z])",
    );
    assert_error(
        &format!("{BALL}rotation = {{ axis = [0, 1, 0] }}\n"),
        "test.toml:7:12: body \"ball\", shape 1: missing required key \"rotation.angle_deg\" (a number of degrees)",
    );
}

#[test]
fn rotations_that_are_not_unit_or_mix_forms_are_rejected() {
    assert_error(
        &format!("{BALL}rotation = {{ quat_xyzw = [0, 0, 1, 1] }}\n"),
        "test.toml:7:26: body \"ball\", shape 1: rotation.quat_xyzw is not a unit quaternion (its length is 1.4142136); write the normalised [0.0000000, 0.0000000, 0.7071068, 0.7071068]",
    );
    assert_error(
        &format!("{BALL}rotation = {{ quaternion = [2, 0, 0, 0] }}\n"),
        "test.toml:7:27: body \"ball\", shape 1: rotation.quaternion is not a unit quaternion (its length is 2.0000000); write the normalised [1.0000000, 0.0000000, 0.0000000, 0.0000000]",
    );
    assert_error(
        &format!("{BALL}rotation = {{ euler_deg = [0, 90, 0], quat_wxyz = [1, 0, 0, 0] }}\n"),
        "test.toml:7:50: body \"ball\", shape 1: rotation.quat_wxyz cannot be combined with rotation.euler_deg (give one rotation: axis and angle_deg, a quaternion, or euler_deg)",
    );
    assert_error(
        &format!("{BALL}rotation = {{ euler_deg = [0, 90, 0], euler_order = \"xxz\" }}\n"),
        "test.toml:7:52: body \"ball\", shape 1: rotation.euler_order \"xxz\" is not an order of the three axes (expected one of: xyz, xzy, yxz, yzx, zxy, zyx; the first is applied first)",
    );
    assert_error(
        &format!("{BALL}rotation = {{ quat_xyzw = [0, 0, 0, 1], euler_order = \"zxy\" }}\n"),
        "test.toml:7:54: body \"ball\", shape 1: rotation.euler_order goes with euler_deg only",
    );
}

#[test]
fn nonzero_numbers_that_round_to_zero_are_rejected() {
    assert_error(
        &BALL.replace("radius = 1\n", "radius = 1e-11\n"),
        "test.toml:6:10: body \"ball\", shape 1: radius = 1e-11 rounds to 0: numbers are fixed point with steps of 2^-32 (about 2.3e-10); write 0 or a larger value",
    );
}

#[test]
fn keys_that_exclude_each_other_are_rejected() {
    assert_error(
        &format!("{BALL}density = 10\nmass = 2\n"),
        "test.toml:8:8: body \"ball\", shape 1: mass cannot be combined with density (give either a density in kg/m³ or a mass in kg)",
    );
    assert_error(
        &format!("{BALL}rotation = {{ quaternion = [1, 0, 0, 0], axis = [0, 1, 0] }}\n"),
        "test.toml:7:48: body \"ball\", shape 1: rotation.axis cannot be combined with rotation.quaternion (give one rotation: axis and angle_deg, a quaternion, or euler_deg)",
    );
}

#[test]
fn bodies_need_at_least_one_shape_and_a_valid_kind() {
    assert_error(
        "[[bodies]]\nname = \"a\"\nkind = \"static\"\nshapes = []\n",
        "test.toml:4:10: body \"a\": a body must have 1 to 256 shapes, found 0",
    );
    assert_error(
        "[[bodies]]\nname = \"a\"\nkind = \"fixed\"\n",
        "test.toml:3:8: body \"a\": unknown body kind \"fixed\" (expected one of: static, dynamic, kinematic)",
    );
    assert_error(
        "[[bodies]]\nname = \"\"\n",
        "test.toml:2:8: body #1: name must not be empty",
    );
}

#[test]
fn columns_count_characters_not_bytes() {
    assert_error(
        &format!("# é\n[materials.\"bois\"]\nfriction = 0.5\n{BALL}material = \"bøis\"\n"),
        "test.toml:10:12: body \"ball\", shape 1: material \"bøis\" is not defined (defined materials: bois)",
    );
    assert_error(
        "[world] # ééé\ngravity = [0, \"é\", 0] ; x = 1\n",
        "test.toml:2:23: TOML syntax error: unexpected key or value, expected newline, `#`",
    );
}

#[test]
fn error_kinds_classify_the_problem() {
    let kind = |text: &str| parse_scene(text, "k.toml").err().map(|e| e.kind);
    assert_eq!(kind("x = ["), Some(SceneErrorKind::Syntax));
    assert_eq!(kind("[world]\ng = 1\n"), Some(SceneErrorKind::UnknownKey));
    assert_eq!(kind("[[bodies]]\n"), Some(SceneErrorKind::MissingKey));
    assert_eq!(
        kind(&format!("{BALL}{BALL}")),
        Some(SceneErrorKind::DuplicateName)
    );
    assert_eq!(
        kind(&BALL.replace("radius = 1", "radius = 1\nmaterial = \"m\"")),
        Some(SceneErrorKind::UnknownMaterial)
    );
    let e = parse_scene("[world]\nsubsteps = 100\n", "dir/k.toml").err();
    assert_eq!(
        e.map(|e| (e.file, e.line, e.column, e.kind)),
        Some(("dir/k.toml".to_owned(), 2, 12, SceneErrorKind::OutOfRange))
    );
}
