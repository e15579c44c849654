//! The scene parser: TOML text to a validated [`SceneDesc`].
//!
//! One pass over the document, table by table: `[world]`, `[materials.*]`,
//! then each `[[bodies]]` with its `[[bodies.shapes]]`. Every table first
//! rejects keys it does not know (typos otherwise silently fall back to
//! defaults), then reads its keys with their types and ranges. The first
//! problem found is returned, located at the offending text.

use toml_edit::Document;

use super::desc::{BodyDesc, BodyKindDesc, MaterialDesc, SceneDesc, WorldDesc};
use super::error::{SceneError, SceneErrorKind, Source, line_column};
use super::reader::{Result, TableView};
use super::rotation::read_rotation;
use super::shape::read_shape;
use crate::math::{Quat, Scalar, Vec3};
use crate::world::MAX_SOLVER_ITERATIONS;

/// Keys of the root table.
const ROOT_KEYS: &[&str] = &["world", "materials", "bodies"];
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
    let src = Source {
        text,
        file: file_name,
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
        None => WorldDesc::default(),
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

    Ok(SceneDesc {
        world,
        materials,
        bodies,
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
fn read_world(t: &TableView<'_>) -> Result<WorldDesc> {
    t.check_keys(WORLD_KEYS, "[world]")?;
    let mut world = WorldDesc::default();
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
    let settings = &mut world.settings;
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

    let line = line_column(t.src.text, t.at).0;
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
