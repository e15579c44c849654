//! The scene parser: TOML text to a validated [`SceneDesc`].
//!
//! One pass over the document, table by table: `[world]`, `[materials.*]`,
//! then each `[[bodies]]` with its `[[bodies.shapes]]`. Every table first
//! rejects keys it does not know (typos otherwise silently fall back to
//! defaults), then reads its keys with their types and ranges. The first
//! problem found is returned, located at the offending text.

use toml_edit::Document;

use super::desc::{BodyDesc, BodyKindDesc, JointSceneDesc, MaterialDesc, SceneDesc};
use super::error::{SceneError, SceneErrorKind, Source, line_starts};
use super::reader::{Result, TableView};
use super::rotation::read_rotation;
use super::shape::read_shape;
use crate::math::{Quat, Scalar, Transform, Vec3};
use crate::world::{ContactOrder, ContactRows, MAX_SOLVER_ITERATIONS, WorldConfig};

/// Keys of the root table.
const ROOT_KEYS: &[&str] = &["world", "materials", "bodies", "joints"];
/// How many of [`JOINT_KEYS`] every joint kind reads (the rest belong to
/// some kinds only).
const COMMON_JOINT_KEYS: usize = 11;
/// Keys of a `[[joints]]` table: the common ones, then the kinds' own.
const JOINT_KEYS: &[&str] = &[
    "name",
    "kind",
    "body_a",
    "body_b",
    "anchor_a",
    "anchor_b",
    "rotation_a",
    "rotation_b",
    "collide_connected",
    "break_force",
    "break_torque",
    "rigid_limits",
    "friction_torque",
    "cone_deg",
    "twist_deg",
    "limits_deg",
    "limits",
    "motor_speed",
    "motor_target_deg",
    "motor_target",
    "max_force",
    "length",
    "min_length",
    "max_length",
    "spring_hertz",
    "spring_damping_ratio",
];
/// Joint kinds, as written.
const JOINT_KINDS: &[&str] = &["spherical", "revolute", "prismatic", "fixed", "distance"];
/// Keys of `[world]`.
const WORLD_KEYS: &[&str] = &[
    "gravity",
    "tick_rate",
    "substeps",
    "solver_iterations",
    "relax_iterations",
    "contact_hertz",
    "contact_damping_ratio",
    "contact_margin",
    "broad_phase_margin",
    "max_push_out",
    "restitution_threshold",
    "contact_order",
    "contact_rows",
    "sleep",
    "sleep_linear_threshold",
    "sleep_angular_threshold",
    "time_to_sleep",
];
/// Keys of a `[materials.NAME]` table.
const MATERIAL_KEYS: &[&str] = &["friction", "restitution", "density"];
/// Keys of a `[[bodies]]` table.
const BODY_KEYS: &[&str] = &[
    "name",
    "kind",
    "position",
    "rotation",
    "linear_velocity",
    "angular_velocity",
    "linear_damping",
    "angular_damping",
    "asleep",
    "bullet",
    "shapes",
];
/// Body kinds, as written.
const BODY_KINDS: &[&str] = &["static", "dynamic", "kinematic"];
/// Bounds of `world.tick_rate`.
pub(super) const MAX_TICK_RATE: i64 = 10_000;
/// Bounds of `world.substeps`.
pub(super) const MAX_SUBSTEPS: i64 = 64;
/// Most shapes one body may have.
pub(super) const MAX_SHAPES_PER_BODY: usize = 256;

/// Parses a scene file.
///
/// `file_name` is used only in error messages. The result is fully
/// validated: ranges, references to materials, unique body names, index
/// bounds and static-only shapes are all checked here, so a builder can
/// trust every field.
///
/// # Errors
/// The first problem found, as a [`SceneError`] naming `file_name`, the
/// line and column, what is wrong and what was expected. Never panics,
/// whatever the input.
pub fn parse_scene(text: &str, file_name: &str) -> std::result::Result<SceneDesc, SceneError> {
    let lines = line_starts(text);
    let src = Source {
        text,
        file: file_name,
        line_starts: &lines,
    };
    let doc = Document::parse(text).map_err(|e| syntax_error(&src, &e))?;
    let root = TableView::root(src, doc.as_table());
    root.check_keys(ROOT_KEYS, "the top level")?;

    let world = match root.get("world") {
        Some(field) => {
            let mut t = root.sub_table(&field, "a table [world]")?;
            t.set_context("world".to_owned());
            read_world(&t)?
        }
        None => WorldConfig::default(),
    };

    let mut materials = Vec::new();
    if let Some(field) = root.get("materials") {
        let all = root.sub_table(&field, "a table of [materials.NAME] tables")?;
        for entry in all.fields() {
            let name = entry
                .name
                .strip_prefix("materials.")
                .unwrap_or(&entry.name)
                .to_owned();
            let mut t = all.sub_table(&entry, "a table with friction, restitution and density")?;
            t.set_context(format!("material \"{name}\""));
            materials.push((name, read_material(&t)?));
        }
    }

    let mut bodies: Vec<BodyDesc> = Vec::new();
    if let Some(field) = root.get("bodies") {
        let tables = root.table_array(&field, "[[bodies]] tables")?;
        for (index, mut t) in tables.into_iter().enumerate() {
            t.set_context(format!("body #{}", index + 1));
            let body = read_body(&mut t, &materials, &bodies)?;
            bodies.push(body);
        }
    }

    let mut joints = Vec::new();
    if let Some(field) = root.get("joints") {
        let tables = root.table_array(&field, "[[joints]] tables")?;
        for (index, mut t) in tables.into_iter().enumerate() {
            t.set_context(format!("joint #{}", index + 1));
            joints.push(read_joint(&mut t, &bodies)?);
        }
    }

    Ok(SceneDesc {
        world,
        materials,
        bodies,
        joints,
    })
}

/// Reads one `[[joints]]` table; `bodies` are the scene's bodies.
fn read_joint(t: &mut TableView<'_>, bodies: &[BodyDesc]) -> Result<JointSceneDesc> {
    use crate::joint::{JointKind, Motor, Spring};
    t.check_keys(JOINT_KEYS, "a joint")?;
    let name = match t.get("name") {
        Some(f) => t.string(&f)?.to_owned(),
        None => String::new(),
    };
    if !name.is_empty() {
        t.set_context(format!("joint \"{name}\""));
    }
    let line = t.src.line(t.at);
    let body = |key: &str| -> Result<(String, BodyKindDesc)> {
        let f = t.require(key, "the name of a body in this scene")?;
        let n = t.string(&f)?;
        match bodies.iter().find(|b| b.name == n) {
            Some(b) => Ok((n.to_owned(), b.kind)),
            None => Err(t.error(
                f.at,
                SceneErrorKind::OutOfRange,
                format!("{key} = \"{n}\" names no body of this scene"),
            )),
        }
    };
    let (body_a, kind_a) = body("body_a")?;
    let (body_b, kind_b) = body("body_b")?;
    if body_a == body_b {
        return Err(t.error(
            t.at,
            SceneErrorKind::OutOfRange,
            format!("a joint needs two different bodies; both are \"{body_a}\""),
        ));
    }
    if kind_a != BodyKindDesc::Dynamic && kind_b != BodyKindDesc::Dynamic {
        return Err(t.error(
            t.at,
            SceneErrorKind::OutOfRange,
            format!("at least one of \"{body_a}\" and \"{body_b}\" must be dynamic"),
        ));
    }
    let frame = |a: &str, r: &str| -> Result<Transform> {
        let mut f = Transform::IDENTITY;
        if let Some(v) = t.get(a) {
            f.translation = t.vec3(&v)?;
        }
        if let Some(v) = t.get(r) {
            f.rotation = read_rotation(t, &v)?;
        }
        Ok(f)
    };
    let frame_a = frame("anchor_a", "rotation_a")?;
    let frame_b = frame("anchor_b", "rotation_b")?;

    let kind_field = t.require(
        "kind",
        "one of: spherical, revolute, prismatic, fixed, distance",
    )?;
    let kind_name = t.string(&kind_field)?;
    // The keys each kind reads (the others are errors, so a key meant for
    // another kind is not silently ignored).
    let allowed: &[&str] = match kind_name {
        "spherical" => &["rigid_limits", "friction_torque", "cone_deg", "twist_deg"],
        "revolute" => &[
            "rigid_limits",
            "friction_torque",
            "limits_deg",
            "motor_speed",
            "motor_target_deg",
            "max_force",
        ],
        "prismatic" => &["limits", "motor_speed", "motor_target", "max_force"],
        "fixed" => &[],
        "distance" => &[
            "length",
            "min_length",
            "max_length",
            "spring_hertz",
            "spring_damping_ratio",
        ],
        other => {
            return Err(t.error(
                kind_field.at,
                SceneErrorKind::WrongType,
                format!(
                    "unknown joint kind \"{other}\" (expected one of: {})",
                    JOINT_KINDS.join(", ")
                ),
            ));
        }
    };
    for key in &JOINT_KEYS[COMMON_JOINT_KEYS..] {
        if !allowed.contains(key)
            && let Some(f) = t.get(key)
        {
            return Err(t.error(
                f.at,
                SceneErrorKind::UnknownKey,
                format!("a {kind_name} joint has no {key}"),
            ));
        }
    }
    let angle = |f: &super::reader::Field<'_>| -> Result<Scalar> {
        let d = t.scalar_where(
            f,
            |v| v.abs() <= Scalar::from_int(180),
            "between -180 and 180 (degrees)",
        )?;
        Ok(super::rotation::degrees_to_radians(d))
    };
    let pair = |key: &str, degrees: bool| -> Result<Option<(Scalar, Scalar)>> {
        let Some(f) = t.get(key) else {
            return Ok(None);
        };
        let [lo, hi] = t.scalars::<2>(&f, "[lower, upper]")?;
        let (lo, hi) = if degrees {
            if lo.abs() > Scalar::from_int(180) || hi.abs() > Scalar::from_int(180) {
                return Err(t.out_of_range(
                    f.at,
                    key,
                    "two angles between -180 and 180 (degrees)",
                    &format!("[{lo}, {hi}]"),
                ));
            }
            (
                super::rotation::degrees_to_radians(lo),
                super::rotation::degrees_to_radians(hi),
            )
        } else {
            (lo, hi)
        };
        if lo > hi {
            return Err(t.out_of_range(
                f.at,
                key,
                "[lower, upper] with lower ≤ upper",
                &format!("[{lo}, {hi}]"),
            ));
        }
        Ok(Some((lo, hi)))
    };
    let motor = |target_key: &str, degrees: bool| -> Result<Option<Motor>> {
        let speed = t.get("motor_speed");
        let target = t.get(target_key);
        let max = t.get("max_force");
        let max_force = match &max {
            Some(f) => Some(t.scalar_where(f, |v| !v.is_negative(), "≥ 0 (N or N·m)")?),
            None => None,
        };
        let need_max = |at: usize| {
            t.error(
                at,
                SceneErrorKind::MissingKey,
                "a motor needs max_force (the largest force or torque it may apply)",
            )
        };
        match (speed, target) {
            (Some(a), Some(b)) => Err(t.error(
                a.at.max(b.at),
                SceneErrorKind::Conflict,
                format!("a motor has a speed or a target, not both (motor_speed and {target_key})"),
            )),
            (Some(f), None) => Ok(Some(Motor::Speed {
                speed: t.scalar(&f)?,
                max_force: max_force.ok_or_else(|| need_max(f.at))?,
            })),
            (None, Some(f)) => {
                let target = if degrees { angle(&f)? } else { t.scalar(&f)? };
                Ok(Some(Motor::Position {
                    target,
                    max_force: max_force.ok_or_else(|| need_max(f.at))?,
                }))
            }
            (None, None) => match max {
                Some(f) => Err(t.error(
                    f.at,
                    SceneErrorKind::MissingKey,
                    format!("max_force without a motor (give motor_speed or {target_key})"),
                )),
                None => Ok(None),
            },
        }
    };
    let kind = match kind_name {
        "spherical" => JointKind::Spherical {
            cone: match t.get("cone_deg") {
                Some(f) => {
                    let c = t.scalar_where(
                        &f,
                        |v| !v.is_negative() && v <= Scalar::from_int(180),
                        "between 0 and 180 (degrees)",
                    )?;
                    Some(super::rotation::degrees_to_radians(c))
                }
                None => None,
            },
            twist: pair("twist_deg", true)?,
        },
        "revolute" => JointKind::Revolute {
            limits: pair("limits_deg", true)?,
            motor: motor("motor_target_deg", true)?,
        },
        "prismatic" => JointKind::Prismatic {
            limits: pair("limits", false)?,
            motor: motor("motor_target", false)?,
        },
        "fixed" => JointKind::Fixed,
        _ => {
            let nonneg = |key: &str| -> Result<Option<Scalar>> {
                match t.get(key) {
                    Some(f) => Ok(Some(t.scalar_where(&f, |v| !v.is_negative(), "≥ 0 (m)")?)),
                    None => Ok(None),
                }
            };
            let length = nonneg("length")?;
            let min = nonneg("min_length")?;
            let max = nonneg("max_length")?;
            let hertz = match t.get("spring_hertz") {
                Some(f) => Some(t.scalar_where(&f, |v| !v.is_negative(), "≥ 0 (Hz)")?),
                None => None,
            };
            let damping = match t.get("spring_damping_ratio") {
                Some(f) => Some(t.scalar_where(&f, |v| !v.is_negative(), "≥ 0")?),
                None => None,
            };
            // Without a length: the distance the anchors start at is not
            // known here (the bodies' poses are), so the file must say.
            let Some(length) = length.or(max) else {
                return Err(t.error(
                    t.at,
                    SceneErrorKind::MissingKey,
                    "a distance joint needs length (or max_length, for a rope)",
                ));
            };
            let spring = match (hertz, damping) {
                (None, None) if min.is_none() && max.is_none() => None,
                (h, d) => Some(Spring {
                    hertz: h.unwrap_or(Scalar::ZERO),
                    damping_ratio: d.unwrap_or(Scalar::ZERO),
                }),
            };
            let min = min.unwrap_or(if spring.is_some() {
                Scalar::ZERO
            } else {
                length
            });
            let max = max.unwrap_or(if spring.is_some() {
                crate::joint::UNBOUNDED_LENGTH
            } else {
                length
            });
            if min > max || length < min || length > max {
                return Err(t.error(
                    t.at,
                    SceneErrorKind::OutOfRange,
                    format!("distance needs min_length ≤ length ≤ max_length (got {min}, {length}, {max})"),
                ));
            }
            if spring.is_none() && !length.is_positive() {
                return Err(t.error(
                    t.at,
                    SceneErrorKind::OutOfRange,
                    "a rigid distance joint needs a positive length",
                ));
            }
            JointKind::Distance {
                length,
                min,
                max,
                spring,
            }
        }
    };
    let threshold = |key: &str, unit: &str| -> Result<Option<Scalar>> {
        match t.get(key) {
            Some(f) => Ok(Some(read_positive(t, &f, unit)?)),
            None => Ok(None),
        }
    };
    let break_force = threshold("break_force", "N")?;
    let break_torque = threshold("break_torque", "N·m")?;
    let flag = |key: &str| -> Result<bool> {
        match t.get(key) {
            Some(f) => t.boolean(&f),
            None => Ok(false),
        }
    };
    let collide_connected = flag("collide_connected")?;
    let rigid_limits = flag("rigid_limits")?;
    let friction = match t.get("friction_torque") {
        Some(f) => t.scalar_where(&f, |v| !v.is_negative(), "≥ 0 (N·m)")?,
        None => Scalar::ZERO,
    };
    Ok(JointSceneDesc {
        name,
        kind,
        body_a,
        body_b,
        frame_a,
        frame_b,
        collide_connected,
        rigid_limits,
        friction,
        break_force,
        break_torque,
        line,
    })
}

/// Maps a `toml_edit` syntax error to a located [`SceneError`].
fn syntax_error(src: &Source<'_>, e: &toml_edit::TomlError) -> SceneError {
    let at = e.span().map_or(0, |s| s.start);
    src.error(
        at,
        SceneErrorKind::Syntax,
        format!("TOML syntax error: {}", e.message()),
    )
}

/// Reads `[world]`.
fn read_world(t: &TableView<'_>) -> Result<WorldConfig> {
    t.check_keys(WORLD_KEYS, "[world]")?;
    let mut world = WorldConfig::default();
    if let Some(f) = t.get("gravity") {
        world.gravity = t.vec3(&f)?;
    }
    if let Some(f) = t.get("tick_rate") {
        let rule = format!("a positive number of ticks per second, 1 to {MAX_TICK_RATE}");
        world.tick_rate = t.integer(&f, 1, MAX_TICK_RATE, &rule)? as u32;
    }
    if let Some(f) = t.get("substeps") {
        let rule = format!("1 to {MAX_SUBSTEPS}");
        world.substeps = t.integer(&f, 1, MAX_SUBSTEPS, &rule)? as u32;
    }
    let settings = &mut world;
    for (key, slot) in [
        ("solver_iterations", &mut settings.solver_iterations),
        ("relax_iterations", &mut settings.relax_iterations),
    ] {
        if let Some(f) = t.get(key) {
            let rule = format!("1 to {MAX_SOLVER_ITERATIONS} passes per substep");
            *slot = t.integer(&f, 1, i64::from(MAX_SOLVER_ITERATIONS), &rule)? as u32;
        }
    }
    for (key, slot, unit) in [
        ("contact_hertz", &mut settings.contact_hertz, "Hz"),
        (
            "contact_damping_ratio",
            &mut settings.contact_damping_ratio,
            "a damping ratio",
        ),
        ("contact_margin", &mut settings.contact_margin, "m"),
        ("broad_phase_margin", &mut settings.broad_phase_margin, "m"),
        ("max_push_out", &mut settings.max_push_out, "m/s"),
        (
            "restitution_threshold",
            &mut settings.restitution_threshold,
            "m/s",
        ),
        (
            "sleep_linear_threshold",
            &mut settings.sleep.linear_threshold,
            "m/s",
        ),
        (
            "sleep_angular_threshold",
            &mut settings.sleep.angular_threshold,
            "rad/s",
        ),
        ("time_to_sleep", &mut settings.sleep.time_to_sleep, "s"),
    ] {
        if let Some(f) = t.get(key) {
            *slot = t.scalar_where(&f, |v| !v.is_negative(), &format!("≥ 0 ({unit})"))?;
        }
    }
    if let Some(f) = t.get("sleep") {
        settings.sleep.enabled = t.boolean(&f)?;
    }
    if let Some(f) = t.get("contact_order") {
        settings.contact_order = match t.string(&f)? {
            "pairs" => ContactOrder::Pairs,
            "colors" => ContactOrder::Colors,
            other => {
                return Err(t.error(
                    f.at,
                    SceneErrorKind::WrongType,
                    format!("unknown contact order \"{other}\" (expected \"pairs\" or \"colors\")"),
                ));
            }
        };
    }
    if let Some(f) = t.get("contact_rows") {
        settings.contact_rows = match t.string(&f)? {
            "exact" => ContactRows::Exact,
            "narrow" => ContactRows::Narrow,
            other => {
                return Err(t.error(
                    f.at,
                    SceneErrorKind::WrongType,
                    format!("unknown contact rows \"{other}\" (expected \"exact\" or \"narrow\")"),
                ));
            }
        };
    }
    Ok(world)
}

/// Reads one `[materials.NAME]` table.
fn read_material(t: &TableView<'_>) -> Result<MaterialDesc> {
    t.check_keys(MATERIAL_KEYS, "a material")?;
    let mut m = MaterialDesc {
        friction: super::desc::DEFAULT_FRICTION,
        restitution: super::desc::DEFAULT_RESTITUTION,
        density: None,
    };
    if let Some(f) = t.get("friction") {
        m.friction = read_friction(t, &f)?;
    }
    if let Some(f) = t.get("restitution") {
        m.restitution = read_restitution(t, &f)?;
    }
    if let Some(f) = t.get("density") {
        m.density = Some(read_positive(t, &f, "kg/m³")?);
    }
    Ok(m)
}

/// A friction coefficient: any number ≥ 0.
pub(super) fn read_friction(t: &TableView<'_>, f: &super::reader::Field<'_>) -> Result<Scalar> {
    t.scalar_where(f, |v| !v.is_negative(), "≥ 0 (a friction coefficient)")
}

/// A restitution coefficient: a number in [0, 1].
pub(super) fn read_restitution(t: &TableView<'_>, f: &super::reader::Field<'_>) -> Result<Scalar> {
    t.scalar_where(
        f,
        |v| !v.is_negative() && v <= Scalar::ONE,
        "between 0 and 1 (0: no bounce, 1: fully elastic)",
    )
}

/// A number > 0 in `unit`.
pub(super) fn read_positive(
    t: &TableView<'_>,
    f: &super::reader::Field<'_>,
    unit: &str,
) -> Result<Scalar> {
    t.scalar_where(f, Scalar::is_positive, &format!("positive ({unit})"))
}

/// Reads one `[[bodies]]` table and its shapes. `earlier` are the bodies
/// already read (for the duplicate-name check).
fn read_body(
    t: &mut TableView<'_>,
    materials: &[(String, MaterialDesc)],
    earlier: &[BodyDesc],
) -> Result<BodyDesc> {
    t.check_keys(BODY_KEYS, "a body")?;
    let name_field = t.require("name", "a unique string")?;
    let name = t.string(&name_field)?;
    if name.is_empty() {
        return Err(t.error(
            name_field.at,
            SceneErrorKind::OutOfRange,
            "name must not be empty",
        ));
    }
    if let Some(first) = earlier.iter().find(|b| b.name == name) {
        return Err(t.error(
            name_field.at,
            SceneErrorKind::DuplicateName,
            format!(
                "duplicate body name \"{name}\" (first used by the body on line {}; names must be unique)",
                first.line
            ),
        ));
    }
    t.set_context(format!("body \"{name}\""));

    let kind_field = t.require("kind", "one of: static, dynamic, kinematic")?;
    let kind = match t.string(&kind_field)? {
        "static" => BodyKindDesc::Static,
        "dynamic" => BodyKindDesc::Dynamic,
        "kinematic" => BodyKindDesc::Kinematic,
        other => {
            return Err(t.error(
                kind_field.at,
                SceneErrorKind::WrongType,
                format!(
                    "unknown body kind \"{other}\" (expected one of: {})",
                    BODY_KINDS.join(", ")
                ),
            ));
        }
    };

    let line = t.src.line(t.at);
    let mut body = BodyDesc {
        name: name.to_owned(),
        kind,
        position: Vec3::ZERO,
        rotation: Quat::IDENTITY,
        linear_velocity: Vec3::ZERO,
        angular_velocity: Vec3::ZERO,
        linear_damping: Scalar::ZERO,
        angular_damping: Scalar::ZERO,
        asleep: false,
        bullet: false,
        shapes: Vec::new(),
        line,
    };
    if let Some(f) = t.get("position") {
        body.position = t.vec3(&f)?;
    }
    if let Some(f) = t.get("rotation") {
        body.rotation = read_rotation(t, &f)?;
    }
    for (key, slot) in [
        ("linear_velocity", &mut body.linear_velocity),
        ("angular_velocity", &mut body.angular_velocity),
    ] {
        if let Some(f) = t.get(key) {
            let v = t.vec3(&f)?;
            if kind == BodyKindDesc::Static && !v.is_zero() {
                return Err(t.error(
                    f.at,
                    SceneErrorKind::StaticOnly,
                    format!(
                        "static bodies cannot move: {key} must be zero (use kind = \"kinematic\" for a moving body that is not pushed)"
                    ),
                ));
            }
            *slot = v;
        }
    }
    for (key, slot) in [
        ("linear_damping", &mut body.linear_damping),
        ("angular_damping", &mut body.angular_damping),
    ] {
        if let Some(f) = t.get(key) {
            *slot = t.scalar_where(&f, |v| !v.is_negative(), "≥ 0 (1/s)")?;
        }
    }
    if let Some(f) = t.get("asleep") {
        body.asleep = t.boolean(&f)?;
    }
    if let Some(f) = t.get("bullet") {
        body.bullet = t.boolean(&f)?;
        if body.bullet && kind != BodyKindDesc::Dynamic {
            return Err(t.error(
                f.at,
                SceneErrorKind::OutOfRange,
                format!(
                    "only dynamic bodies can be bullets; this body is {}",
                    kind.name()
                ),
            ));
        }
    }

    let shapes_field = t.require("shapes", "at least one [[bodies.shapes]] table")?;
    let shape_tables = t.table_array(&shapes_field, "[[bodies.shapes]] tables")?;
    if shape_tables.is_empty() || shape_tables.len() > MAX_SHAPES_PER_BODY {
        return Err(t.error(
            shapes_field.at,
            SceneErrorKind::OutOfRange,
            format!(
                "a body must have 1 to {MAX_SHAPES_PER_BODY} shapes, found {}",
                shape_tables.len()
            ),
        ));
    }
    for (index, mut s) in shape_tables.into_iter().enumerate() {
        s.set_context(format!("{}, shape {}", t.context(), index + 1));
        body.shapes.push(read_shape(&s, &body, materials)?);
    }
    Ok(body)
}
