//! The performance scenes (docs/engines.md) as engine-neutral recipes: one list of
//! bodies that both engines build from, so the geometry, masses and
//! starting poses are the same.
//!
//! Every coordinate is a multiple of 1/2 (exact in Q32.32 and in `f32`),
//! except the hull points, which are rounded to Q32.32 first and handed to
//! Rapier as the `f32` nearest to that value.

use std::fmt::Write as _;

/// The one shape all dynamic bodies of a scene share.
#[derive(Clone, Debug)]
pub enum BodyShape {
    /// A box with these half-extents, m.
    Cube(f64),
    /// The convex hull of these points, m.
    Hull(Vec<[f64; 3]>),
    /// A sphere of this radius, m.
    Sphere(f64),
    /// Every body as this scene file describes it: its own shapes, the
    /// static bodies, the joints and the world settings (the `Scene`'s
    /// ground, density, friction, statics and joints are not used).
    File(std::sync::Arc<lockstep_core::scene::SceneDesc>),
}

/// A scene: a static ground box plus dynamic bodies of one shape.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The scene's name (docs/engines.md).
    pub name: &'static str,
    /// Half-extents of the ground box, m.
    pub ground_half: [f64; 3],
    /// Height of the ground box's centre, m.
    pub ground_y: f64,
    /// The dynamic bodies' shape.
    pub shape: BodyShape,
    /// Density of the dynamic bodies, kg/m³.
    pub density: f64,
    /// Friction of every collider (both engines, restitution 0).
    pub friction: f64,
    /// Starting positions of the dynamic bodies (no rotation).
    pub positions: Vec<[f64; 3]>,
    /// Indices (into `positions`) of the top box of each pyramid: the
    /// "still standing" check watches their height. Empty for a pile.
    pub tops: Vec<usize>,
    /// Steps per run.
    pub steps: usize,
    /// Indices (into `positions`) of bodies that are static instead of
    /// dynamic (sorted).
    pub statics: Vec<usize>,
    /// Spherical joints: two body indices and the anchor in world
    /// coordinates at the start.
    pub joints: Vec<(usize, usize, [f64; 3])>,
    /// Whether the bodies collide at all (false: every collider is filtered
    /// out of every pair, as joint_grid asks).
    pub collide: bool,
}

/// Friction used in every scene (Box2D/Box3D's default).
const FRICTION: f64 = 0.6;

/// Appends a pyramid in the x–y plane at `(cx, ·, cz)` with `base` cubes of
/// half-extent 0.5 on its bottom row (resting on y = 0); returns the index
/// of its top cube.
fn pyramid(positions: &mut Vec<[f64; 3]>, base: usize, cx: f64, cz: f64) -> usize {
    for row in 0..base {
        for i in 0..base - row {
            let x = cx + i as f64 + 0.5 * row as f64 - 0.5 * (base - 1) as f64;
            positions.push([x, 0.5 + row as f64, cz]);
        }
    }
    positions.len() - 1
}

/// large_pyramid: one pyramid with `base` cubes on the bottom row (100 →
/// 5,050 cubes), ground half-extents (400, 1, 400) at y = −1.
pub fn large_pyramid(base: usize, steps: usize) -> Scene {
    let mut positions = Vec::new();
    let top = pyramid(&mut positions, base, 0.0, 0.0);
    Scene {
        name: "large_pyramid",
        ground_half: [400.0, 1.0, 400.0],
        ground_y: -1.0,
        shape: BodyShape::Cube(0.5),
        density: 100.0,
        friction: FRICTION,
        positions,
        tops: vec![top],
        steps,
        statics: Vec::new(),
        joints: Vec::new(),
        collide: true,
    }
}

/// many_pyramids: a `grid` × `grid` array of pyramids of base `base` (14 ×
/// 14 of base 10 → 10,780 cubes) in the x–z plane, `base + 1` m apart and
/// centred, on a ground of half-extent 77 (14 pyramids of width 10 spaced
/// 11 m span ±76.5 m).
pub fn many_pyramids(grid: usize, base: usize, ground: f64, steps: usize) -> Scene {
    let mut positions = Vec::new();
    let mut tops = Vec::new();
    let spacing = (base + 1) as f64;
    let mid = 0.5 * (grid as f64 - 1.0);
    for gx in 0..grid {
        for gz in 0..grid {
            let cx = (gx as f64 - mid) * spacing;
            let cz = (gz as f64 - mid) * spacing;
            tops.push(pyramid(&mut positions, base, cx, cz));
        }
    }
    Scene {
        name: "many_pyramids",
        ground_half: [ground, 1.0, ground],
        ground_y: -1.0,
        shape: BodyShape::Cube(0.5),
        density: 100.0,
        friction: FRICTION,
        positions,
        tops,
        steps,
        statics: Vec::new(),
        joints: Vec::new(),
        collide: true,
    }
}

/// A 64-bit linear congruential generator (Knuth's MMIX constants): the
/// fixed point source for the convex pile's hull.
#[derive(Clone, Debug)]
pub struct Lcg(u64);

impl Lcg {
    /// A generator from its seed.
    pub fn new(seed: u64) -> Lcg {
        Lcg(seed)
    }

    /// A uniform value in `[0, 1)` from the top 53 bits of the next state.
    pub fn next_unit(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `n` points uniform on a sphere of radius `r` (z uniform in [−r, r], the
/// azimuth uniform), from an LCG seeded `seed`.
pub fn sphere_points(n: usize, r: f64, seed: u64) -> Vec<[f64; 3]> {
    let mut lcg = Lcg::new(seed);
    (0..n)
        .map(|_| {
            let z = 2.0 * lcg.next_unit() - 1.0;
            let phi = std::f64::consts::TAU * lcg.next_unit();
            let s = (1.0 - z * z).max(0.0).sqrt();
            [r * s * phi.cos(), r * z, r * s * phi.sin()]
        })
        .collect()
}

/// convex_pile: `nx` × `nz` × `ny` hulls (8 × 8 × 80 → 5,120) of 32 points
/// on a sphere of radius 2 (LCG seed 42), 4.5 m apart in a column grid
/// starting 2.5 m above the ground; ground half-extents (250, 1, 250).
pub fn convex_pile(nx: usize, nz: usize, ny: usize, steps: usize) -> Scene {
    let spacing = 4.5;
    let mut positions = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            for k in 0..nz {
                let x = (i as f64 - 0.5 * (nx as f64 - 1.0)) * spacing;
                let z = (k as f64 - 0.5 * (nz as f64 - 1.0)) * spacing;
                positions.push([x, 2.5 + j as f64 * spacing, z]);
            }
        }
    }
    Scene {
        name: "convex_pile",
        ground_half: [250.0, 1.0, 250.0],
        ground_y: -1.0,
        shape: BodyShape::Hull(sphere_points(32, 2.0, 42)),
        density: 100.0,
        friction: FRICTION,
        positions,
        tops: Vec::new(),
        steps,
        statics: Vec::new(),
        joints: Vec::new(),
        collide: true,
    }
}

/// jolt_pyramid: `layers` layers of 2 m boxes (15 → 1,240), layer `i` a
/// square of `layers − i` boxes per side, odd layers offset by 1 m so each
/// box rests on four; floor half-extents (50, 1, 50). Density 1000 (Jolt's
/// default).
pub fn jolt_pyramid(layers: usize, steps: usize) -> Scene {
    let mut positions = Vec::new();
    let n = layers as i64;
    for i in 0..n {
        let offset = if i % 2 == 1 { 1.0 } else { 0.0 };
        for j in i / 2..n - (i + 1) / 2 {
            for k in i / 2..n - (i + 1) / 2 {
                positions.push([
                    (-n + 2 * j) as f64 + offset,
                    1.0 + 2.0 * i as f64,
                    (-n + 2 * k) as f64 + offset,
                ]);
            }
        }
    }
    let top = positions.len() - 1;
    Scene {
        name: "jolt_pyramid",
        ground_half: [50.0, 1.0, 50.0],
        ground_y: -1.0,
        shape: BodyShape::Cube(1.0),
        density: 1000.0,
        friction: FRICTION,
        positions,
        tops: vec![top],
        steps,
        statics: Vec::new(),
        joints: Vec::new(),
        collide: true,
    }
}

/// joint_grid: `n` × `n` spheres of radius 0.4 at `(k, −i, 0)`, row `i = 0`
/// static, each sphere joined to its left and upper neighbours by a
/// spherical joint at the midpoint, no contacts at all. The published scene
/// counts `2n(n − 1)` joints; the `n − 1` between two static spheres of row 0
/// constrain nothing (and our `add_joint` refuses them), so neither engine
/// gets them: `2n(n − 1) − (n − 1)`.
/// There is no ground to stand on; the suite's ground box is put far below,
/// where nothing reaches it in the run.
pub fn joint_grid(n: usize, steps: usize) -> Scene {
    let mut positions = Vec::with_capacity(n * n);
    let mut joints = Vec::with_capacity(2 * n * n.saturating_sub(1));
    for i in 0..n {
        for k in 0..n {
            let index = i * n + k;
            let p = [k as f64, -(i as f64), 0.0];
            positions.push(p);
            if k > 0 && i > 0 {
                joints.push((index - 1, index, [k as f64 - 0.5, -(i as f64), 0.0]));
            }
            if i > 0 {
                joints.push((index - n, index, [k as f64, 0.5 - i as f64, 0.0]));
            }
        }
    }
    Scene {
        name: "joint_grid",
        ground_half: [1.0, 1.0, 1.0],
        ground_y: -10_000.0,
        shape: BodyShape::Sphere(0.4),
        density: 1000.0,
        friction: FRICTION,
        positions,
        tops: Vec::new(),
        steps,
        statics: (0..n).collect(),
        joints,
        collide: false,
    }
}

/// One ragdoll part: name, centre relative to the pelvis (m), capsule half
/// height and radius (m). Capsules lie along y: the ragdoll stands upright.
const RAGDOLL_PARTS: [(&str, [f64; 3], f64, f64); 11] = [
    ("pelvis", [0.0, 0.0, 0.0], 0.05, 0.14),
    ("torso", [0.0, 0.35, 0.0], 0.15, 0.15),
    ("head", [0.0, 0.85, 0.0], 0.02, 0.12),
    ("upper_arm_l", [-0.25, 0.45, 0.0], 0.1, 0.06),
    ("lower_arm_l", [-0.25, 0.05, 0.0], 0.1, 0.05),
    ("upper_arm_r", [0.25, 0.45, 0.0], 0.1, 0.06),
    ("lower_arm_r", [0.25, 0.05, 0.0], 0.1, 0.05),
    ("thigh_l", [-0.1, -0.35, 0.0], 0.15, 0.07),
    ("shin_l", [-0.1, -0.75, 0.0], 0.15, 0.06),
    ("thigh_r", [0.1, -0.35, 0.0], 0.15, 0.07),
    ("shin_r", [0.1, -0.75, 0.0], 0.15, 0.06),
];

/// How a ragdoll joint bends: a ball with a swing cone and twist limits
/// about the bone (degrees), or a hinge about x with angle limits.
enum Bend {
    Ball { cone: f64, twist: f64 },
    Hinge { lo: f64, hi: f64 },
}

/// One ragdoll joint: the two parts, the anchor in each part's frame, and
/// how it bends.
type RagdollJoint = (&'static str, &'static str, [f64; 3], [f64; 3], Bend);

/// Every ragdoll joint's friction, N·m: a limb hanging over a step's edge
/// (a head on its neck, a shin from a thigh lying on one contact point)
/// otherwise swings for minutes, damped by nothing but the bodies' angular
/// damping; with 1 N·m both ragdoll scenes sleep within 4 s.
const JOINT_FRICTION: &str = "1";

/// The joints of one ragdoll.
const RAGDOLL_JOINTS: [RagdollJoint; 10] = [
    (
        "pelvis",
        "torso",
        [0.0, 0.15, 0.0],
        [0.0, -0.2, 0.0],
        Bend::Ball {
            cone: 30.0,
            twist: 20.0,
        },
    ),
    (
        "torso",
        "head",
        [0.0, 0.35, 0.0],
        [0.0, -0.15, 0.0],
        Bend::Ball {
            cone: 40.0,
            twist: 45.0,
        },
    ),
    (
        "torso",
        "upper_arm_l",
        [-0.25, 0.25, 0.0],
        [0.0, 0.15, 0.0],
        Bend::Ball {
            cone: 80.0,
            twist: 45.0,
        },
    ),
    (
        "upper_arm_l",
        "lower_arm_l",
        [0.0, -0.2, 0.0],
        [0.0, 0.2, 0.0],
        Bend::Hinge {
            lo: -140.0,
            hi: 0.0,
        },
    ),
    (
        "torso",
        "upper_arm_r",
        [0.25, 0.25, 0.0],
        [0.0, 0.15, 0.0],
        Bend::Ball {
            cone: 80.0,
            twist: 45.0,
        },
    ),
    (
        "upper_arm_r",
        "lower_arm_r",
        [0.0, -0.2, 0.0],
        [0.0, 0.2, 0.0],
        Bend::Hinge {
            lo: -140.0,
            hi: 0.0,
        },
    ),
    (
        "pelvis",
        "thigh_l",
        [-0.1, -0.15, 0.0],
        [0.0, 0.2, 0.0],
        Bend::Ball {
            cone: 60.0,
            twist: 30.0,
        },
    ),
    (
        "thigh_l",
        "shin_l",
        [0.0, -0.2, 0.0],
        [0.0, 0.2, 0.0],
        Bend::Hinge { lo: 0.0, hi: 140.0 },
    ),
    (
        "pelvis",
        "thigh_r",
        [0.1, -0.15, 0.0],
        [0.0, 0.2, 0.0],
        Bend::Ball {
            cone: 60.0,
            twist: 30.0,
        },
    ),
    (
        "thigh_r",
        "shin_r",
        [0.0, -0.2, 0.0],
        [0.0, 0.2, 0.0],
        Bend::Hinge { lo: 0.0, hi: 140.0 },
    ),
];

/// A number as a scene file writes it: at most four decimals, no trailing
/// zeros (every value the generator writes is a multiple of 1/10,000).
fn num(v: f64) -> String {
    let text = format!("{:.4}", v + 0.0);
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".to_owned()
    } else {
        text.to_owned()
    }
}

fn vec_text(v: [f64; 3]) -> String {
    format!("[{}, {}, {}]", num(v[0]), num(v[1]), num(v[2]))
}

/// The ragdoll scene as a scene file: `cols` × `rows` ragdolls (11 capsules
/// and 10 joints each: cone-twist balls at the spine, neck, shoulders and
/// hips, limited hinges at the elbows and knees) standing on a staircase of
/// `rows + 8` steps (1 m deep, 0.5 m high), row `j` on step `j`, columns 2 m
/// apart, each pushed off its step with 2.5 m/s forward and a tumble. The
/// stairs end on a wide floor. Joined parts do not collide with each other;
/// all other pairs do. `scenes/ragdolls_100.toml` is `ragdolls_toml(10, 10)`.
pub fn ragdolls_toml(cols: usize, rows: usize) -> String {
    let steps = rows + 8;
    let half_width = cols as f64 + 2.0;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# Generated by lockstep-bench (scenes::ragdolls_toml({cols}, {rows})); edit the generator,\n\
         # not this file: `LOCKSTEP_BLESS=1 cargo test -p lockstep-bench ragdoll` rewrites it.\n\
         #\n\
         # {n} ragdolls of eleven capsules each, joined by spherical joints with cone\n\
         # and twist limits (spine, neck, shoulders, hips) and hinges with limits\n\
         # (elbows, knees), stand in {rows} rows of {cols} on a staircase of {steps} steps\n\
         # and are pushed off. They tumble down onto each other and pile up on the\n\
         # stairs, come to rest and fall asleep. Joined parts do not collide with\n\
         # each other. The limbs are damped (linear 0.2/s, angular 2/s), as game\n\
         # ragdolls usually are: without it, limbs pressed between ragdolls and\n\
         # steps keep moving at a few cm/s and part of the pile stays awake.\n\
         # Every joint has {JOINT_FRICTION} N·m of friction: without it a limb hanging\n\
         # over a step's edge can swing on for minutes.\n\
         \n\
         [world]\n\
         gravity = [0, -9.81, 0]\n\
         tick_rate = 60\n\
         substeps = 4\n\
         \n\
         [materials.stone]\n\
         friction = 0.8\n\
         \n\
         [materials.cloth]\n\
         friction = 0.6\n\
         density = 985",
        n = cols * rows
    );
    for k in 0..steps {
        let _ = write!(
            out,
            "\n[[bodies]]\nname = \"step_{k}\"\nkind = \"static\"\nposition = {}\n\
             shapes = [{{ kind = \"box\", half_extents = [{}, 0.25, 0.5], material = \"stone\" }}]\n",
            vec_text([0.0, -0.25 - 0.5 * k as f64, 0.5 + k as f64]),
            num(half_width),
        );
    }
    let _ = write!(
        out,
        "\n[[bodies]]\nname = \"floor\"\nkind = \"static\"\nposition = {}\n\
         shapes = [{{ kind = \"box\", half_extents = [{}, 0.5, 15], material = \"stone\" }}]\n",
        vec_text([0.0, -0.5 * steps as f64 - 0.5, steps as f64 + 15.0]),
        num(half_width + 12.0),
    );
    for row in 0..rows {
        for col in 0..cols {
            let r = row * cols + col;
            let pelvis = [
                2.0 * col as f64 - (cols as f64 - 1.0),
                1.02 - 0.5 * row as f64,
                0.5 + row as f64,
            ];
            // A different tumble per ragdoll, from a fixed pattern.
            let spin = ((3 * col + 7 * row) % 9) as f64 * 0.1 - 0.4;
            for (part, at, half_height, radius) in RAGDOLL_PARTS {
                let p = [pelvis[0] + at[0], pelvis[1] + at[1], pelvis[2] + at[2]];
                let _ = write!(
                    out,
                    "\n[[bodies]]\nname = \"r{r}_{part}\"\nkind = \"dynamic\"\nposition = {}\n\
                     linear_velocity = [0, 0.5, 2.5]\nangular_velocity = [2, {}, 0]\n\
                     linear_damping = 0.2\nangular_damping = 2\n\
                     shapes = [{{ kind = \"capsule\", half_height = {}, radius = {}, material = \"cloth\" }}]\n",
                    vec_text(p),
                    num(spin),
                    num(half_height),
                    num(radius),
                );
            }
        }
    }
    for r in 0..rows * cols {
        for (a, b, anchor_a, anchor_b, bend) in &RAGDOLL_JOINTS {
            let _ = write!(
                out,
                "\n[[joints]]\nname = \"r{r}_{a}_{b}\"\nbody_a = \"r{r}_{a}\"\nbody_b = \"r{r}_{b}\"\n\
                 anchor_a = {}\nanchor_b = {}\n",
                vec_text(*anchor_a),
                vec_text(*anchor_b),
            );
            match bend {
                // The joint's x axis along the bone (body y): the cone is
                // around the bone and the twist is about it.
                Bend::Ball { cone, twist } => {
                    let _ = write!(
                        out,
                        "kind = \"spherical\"\n\
                         rotation_a = {{ axis = [0, 0, 1], angle_deg = 90 }}\n\
                         rotation_b = {{ axis = [0, 0, 1], angle_deg = 90 }}\n\
                         cone_deg = {}\ntwist_deg = [{}, {}]\nfriction_torque = {JOINT_FRICTION}\n",
                        num(*cone),
                        num(-twist),
                        num(*twist),
                    );
                }
                Bend::Hinge { lo, hi } => {
                    let _ = write!(
                        out,
                        "kind = \"revolute\"\nlimits_deg = [{}, {}]\nfriction_torque = {JOINT_FRICTION}\n",
                        num(*lo),
                        num(*hi)
                    );
                }
            }
        }
    }
    out
}

/// ragdolls: a scene file's bodies (the ragdoll file, or any other) as a
/// benchmark scene; `positions` are its dynamic bodies' starting positions
/// in file order.
pub fn from_file(name: &'static str, text: &str, steps: usize) -> Scene {
    let desc = lockstep_core::scene::parse_scene(text, name).unwrap_or_else(|e| panic!("{e}"));
    let positions = desc
        .bodies
        .iter()
        .filter(|b| b.kind == lockstep_core::BodyKind::Dynamic)
        .map(|b| {
            [
                b.position.x.to_f64(),
                b.position.y.to_f64(),
                b.position.z.to_f64(),
            ]
        })
        .collect();
    Scene {
        name,
        ground_half: [0.0; 3],
        ground_y: 0.0,
        shape: BodyShape::File(std::sync::Arc::new(desc)),
        density: 0.0,
        friction: 0.0,
        positions,
        tops: Vec::new(),
        steps,
        statics: Vec::new(),
        joints: Vec::new(),
        collide: true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_sizes_match_scenes_md() {
        let grid = joint_grid(100, 100);
        assert_eq!(grid.positions.len(), 10_000);
        assert_eq!(grid.joints.len(), 19_800 - 99);
        assert_eq!(grid.statics.len(), 100);
        assert_eq!(large_pyramid(100, 200).positions.len(), 5_050);
        let many = many_pyramids(14, 10, 77.0, 100);
        assert_eq!(many.positions.len(), 10_780);
        assert_eq!(many.tops.len(), 196);
        let max_x = many
            .positions
            .iter()
            .map(|p| p[0].abs())
            .fold(0.0, f64::max);
        assert_eq!(max_x + 0.5, 76.5, "every pyramid is on the ground");
        assert_eq!(convex_pile(8, 8, 80, 500).positions.len(), 5_120);
        assert_eq!(jolt_pyramid(15, 500).positions.len(), 1_240);
    }

    #[test]
    fn the_ragdoll_scene_file_is_the_generators_output() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/ragdolls_100.toml");
        let text = ragdolls_toml(10, 10);
        if std::env::var_os("LOCKSTEP_BLESS").is_some() {
            std::fs::write(path, &text).expect("write the scene file");
        }
        let on_disk = std::fs::read_to_string(path).expect("scenes/ragdolls_100.toml");
        assert!(
            on_disk == text,
            "scenes/ragdolls_100.toml differs from ragdolls_toml(10, 10): \
             run with LOCKSTEP_BLESS=1 to rewrite it"
        );
        let desc = lockstep_core::scene::parse_scene(&text, "ragdolls_100.toml").expect("parses");
        let dynamic = desc
            .bodies
            .iter()
            .filter(|b| b.kind == lockstep_core::BodyKind::Dynamic)
            .count();
        assert_eq!(dynamic, 1_100);
        assert_eq!(desc.bodies.len(), 1_100 + 18 + 1);
        assert_eq!(desc.joints.len(), 1_000);
    }

    #[test]
    fn pyramid_rows_rest_on_each_other() {
        let s = large_pyramid(3, 1);
        let ys: Vec<f64> = s.positions.iter().map(|p| p[1]).collect();
        assert_eq!(ys, [0.5, 0.5, 0.5, 1.5, 1.5, 2.5]);
        assert_eq!(s.positions[s.tops[0]], [0.0, 2.5, 0.0]);
    }

    #[test]
    fn hull_points_are_on_the_sphere_and_repeatable() {
        let p = sphere_points(32, 2.0, 42);
        assert_eq!(p.len(), 32);
        for q in &p {
            let r = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
            assert!((r - 2.0).abs() < 1e-12, "{r}");
        }
        assert_eq!(p, sphere_points(32, 2.0, 42));
        assert_ne!(p, sphere_points(32, 2.0, 43));
    }
}
