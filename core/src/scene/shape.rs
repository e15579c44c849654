//! `[[bodies.shapes]]`: one shape's geometry, pose, mass, surface and
//! collision filter.

use super::desc::{
    BodyDesc, BodyKindDesc, DEFAULT_DENSITY, DEFAULT_FRICTION, DEFAULT_RESTITUTION, GeometryDesc,
    MassSpec, MaterialDesc, ShapeDesc,
};
use super::error::SceneErrorKind;
use super::parse::{read_friction, read_positive, read_restitution};
use super::reader::{Field, Result, TableView};
use super::rotation::read_rotation;
use crate::math::{FaultScope, Quat, Scalar, Vec3};

/// Shape kinds, as written.
pub(super) const SHAPE_KINDS: &[&str] = &[
    "sphere",
    "capsule",
    "box",
    "convex_hull",
    "trimesh",
    "heightfield",
];

/// Keys every shape may have, whatever its kind.
const COMMON_KEYS: &[&str] = &[
    "kind",
    "offset",
    "rotation",
    "density",
    "mass",
    "material",
    "friction",
    "restitution",
    "group",
    "mask",
    "collision_group",
    "trigger",
];

/// Most points of a convex hull.
pub(super) const MAX_HULL_POINTS: usize = 1024;
/// Most vertices, and most triangles, of a triangle mesh.
pub(super) const MAX_MESH_ELEMENTS: usize = 1 << 20;
/// Most rows, and most columns, of a height field.
pub(super) const MAX_HEIGHTFIELD_SIDE: i64 = 4096;
/// Most samples of a height field.
pub(super) const MAX_HEIGHTFIELD_SAMPLES: usize = 1 << 20;

/// The keys specific to a shape kind.
fn kind_keys(kind: &str) -> &'static [&'static str] {
    match kind {
        "sphere" => &["radius"],
        "capsule" => &["half_height", "radius"],
        "box" => &["half_extents"],
        "convex_hull" => &["points"],
        "trimesh" => &["vertices", "indices"],
        "heightfield" => &["rows", "cols", "heights", "scale"],
        _ => &[],
    }
}

/// Reads one shape table of `body` (whose name, kind and line are already
/// known), resolving its material.
pub(super) fn read_shape(
    t: &TableView<'_>,
    body: &BodyDesc,
    materials: &[(String, MaterialDesc)],
) -> Result<ShapeDesc> {
    let kind_field = t.require("kind", &format!("one of: {}", SHAPE_KINDS.join(", ")))?;
    let kind = t.string(&kind_field)?;
    if !SHAPE_KINDS.contains(&kind) {
        return Err(t.error(
            kind_field.at,
            SceneErrorKind::WrongType,
            format!(
                "unknown shape kind \"{kind}\" (expected one of: {})",
                SHAPE_KINDS.join(", ")
            ),
        ));
    }
    let allowed: Vec<&str> = COMMON_KEYS.iter().chain(kind_keys(kind)).copied().collect();
    t.check_keys(&allowed, &format!("a {kind} shape"))?;

    if matches!(kind, "trimesh" | "heightfield") && body.kind != BodyKindDesc::Static {
        return Err(t.error(
            kind_field.at,
            SceneErrorKind::StaticOnly,
            format!(
                "{kind} shapes are static only: body \"{}\" is {} (expected kind = \"static\" on the body)",
                body.name,
                body.kind.name()
            ),
        ));
    }

    let geometry = read_geometry(t, kind)?;

    let mut shape = ShapeDesc {
        geometry,
        offset: Vec3::ZERO,
        rotation: Quat::IDENTITY,
        density_or_mass: MassSpec::Density(DEFAULT_DENSITY),
        material: None,
        friction: DEFAULT_FRICTION,
        restitution: DEFAULT_RESTITUTION,
        group: 1,
        mask: u32::MAX,
        collision_group: 0,
        trigger: false,
        line: t.src.line(t.at),
    };
    if let Some(f) = t.get("offset") {
        shape.offset = t.vec3(&f)?;
    }
    if let Some(f) = t.get("rotation") {
        shape.rotation = read_rotation(t, &f)?;
    }

    // The material first, so that the shape's own keys override it.
    if let Some(f) = t.get("material") {
        let name = t.string(&f)?;
        let Some((_, m)) = materials.iter().find(|(n, _)| n == name) else {
            let defined = if materials.is_empty() {
                "no materials are defined".to_owned()
            } else {
                let names: Vec<&str> = materials.iter().map(|(n, _)| n.as_str()).collect();
                format!("defined materials: {}", names.join(", "))
            };
            return Err(t.error(
                f.at,
                SceneErrorKind::UnknownMaterial,
                format!("material \"{name}\" is not defined ({defined})"),
            ));
        };
        shape.friction = m.friction;
        shape.restitution = m.restitution;
        if let Some(d) = m.density {
            shape.density_or_mass = MassSpec::Density(d);
        }
        shape.material = Some(name.to_owned());
    }
    if let Some(f) = t.get("friction") {
        shape.friction = read_friction(t, &f)?;
    }
    if let Some(f) = t.get("restitution") {
        shape.restitution = read_restitution(t, &f)?;
    }
    match (t.get("density"), t.get("mass")) {
        (Some(d), Some(m)) => {
            return Err(t.error(
                m.at,
                SceneErrorKind::Conflict,
                format!(
                    "{} cannot be combined with {} (give either a density in kg/m³ or a mass in kg)",
                    m.name, d.name
                ),
            ));
        }
        (Some(d), None) => {
            shape.density_or_mass = MassSpec::Density(read_positive(t, &d, "kg/m³")?)
        }
        (None, Some(m)) => shape.density_or_mass = MassSpec::Mass(read_positive(t, &m, "kg")?),
        (None, None) => {}
    }

    if let Some(f) = t.get("group") {
        shape.group =
            t.integer(&f, 0, i64::from(u32::MAX), "category bits, 0 to 0xFFFFFFFF")? as u32;
    }
    if let Some(f) = t.get("mask") {
        shape.mask =
            t.integer(&f, 0, i64::from(u32::MAX), "category bits, 0 to 0xFFFFFFFF")? as u32;
    }
    if let Some(f) = t.get("collision_group") {
        shape.collision_group = t.integer(
            &f,
            i64::from(i32::MIN),
            i64::from(i32::MAX),
            "a 32-bit signed group index",
        )? as i32;
    }
    if let Some(f) = t.get("trigger") {
        shape.trigger = t.boolean(&f)?;
    }
    Ok(shape)
}

/// Reads the kind-specific keys.
fn read_geometry(t: &TableView<'_>, kind: &str) -> Result<GeometryDesc> {
    let positive = |key: &str| -> Result<Scalar> {
        let f = t.require(key, "a positive number, metres")?;
        read_positive(t, &f, "metres")
    };
    let positive_vec = |f: &Field<'_>, unit: &str| -> Result<Vec3> {
        let v = t.vec3(f)?;
        for (i, c) in v.to_array().into_iter().enumerate() {
            if !c.is_positive() {
                let rule = format!("positive ({unit})");
                return Err(t.out_of_range(
                    f.at,
                    &format!("{}[{i}]", f.name),
                    &rule,
                    &c.to_string(),
                ));
            }
        }
        Ok(v)
    };
    Ok(match kind {
        "sphere" => GeometryDesc::Sphere {
            radius: positive("radius")?,
        },
        "capsule" => GeometryDesc::Capsule {
            half_height: positive("half_height")?,
            radius: positive("radius")?,
        },
        "box" => {
            let f = t.require("half_extents", "[x, y, z] half-sizes in metres")?;
            GeometryDesc::Box {
                half_extents: positive_vec(&f, "metres")?,
            }
        }
        "convex_hull" => {
            let f = t.require("points", "an array of at least 4 [x, y, z] points")?;
            let points = t.vec3_list(&f, 4, MAX_HULL_POINTS)?;
            if all_coplanar(&points) {
                return Err(t.error(
                    f.at,
                    SceneErrorKind::BadGeometry,
                    format!(
                        "{} are all in one plane (expected at least 4 points that enclose a volume)",
                        f.name
                    ),
                ));
            }
            GeometryDesc::ConvexHull { points }
        }
        "trimesh" => read_trimesh(t)?,
        "heightfield" => read_heightfield(t, &positive_vec)?,
        // `kind` was checked against SHAPE_KINDS by the caller.
        other => {
            return Err(t.error(
                t.at,
                SceneErrorKind::WrongType,
                format!("unknown shape kind \"{other}\""),
            ));
        }
    })
}

/// `vertices` and `indices` of a triangle mesh.
fn read_trimesh(t: &TableView<'_>) -> Result<GeometryDesc> {
    let vf = t.require("vertices", "an array of [x, y, z] points")?;
    let vertices = t.vec3_list(&vf, 3, MAX_MESH_ELEMENTS)?;
    let inf = t.require("indices", "an array of [a, b, c] vertex indices")?;
    let triangles = t.array(
        &inf,
        "an array of [a, b, c] vertex indices",
        1,
        MAX_MESH_ELEMENTS,
    )?;
    let last = vertices.len() as i64 - 1;
    let rule = format!(
        "a vertex index, 0 to {last} (vertices has {} entries)",
        vertices.len()
    );
    let mut indices = Vec::with_capacity(triangles.len());
    for tri in &triangles {
        let corners = t.array(tri, "an array of 3 vertex indices [a, b, c]", 3, 3)?;
        let mut abc = [0u32; 3];
        for (slot, corner) in abc.iter_mut().zip(&corners) {
            *slot = t.integer(corner, 0, last, &rule)? as u32;
        }
        if abc[0] == abc[1] || abc[1] == abc[2] || abc[0] == abc[2] {
            return Err(t.error(
                tri.at,
                SceneErrorKind::BadGeometry,
                format!(
                    "{} = [{}, {}, {}] repeats a vertex (expected three distinct indices)",
                    tri.name, abc[0], abc[1], abc[2]
                ),
            ));
        }
        indices.push(abc);
    }
    Ok(GeometryDesc::TriMesh { vertices, indices })
}

/// `rows`, `cols`, `heights` and `scale` of a height field.
fn read_heightfield(
    t: &TableView<'_>,
    positive_vec: &dyn Fn(&Field<'_>, &str) -> Result<Vec3>,
) -> Result<GeometryDesc> {
    let side_rule = format!("an integer from 2 to {MAX_HEIGHTFIELD_SIDE}");
    let rf = t.require("rows", &format!("the number of rows, {side_rule}"))?;
    let rows = t.integer(&rf, 2, MAX_HEIGHTFIELD_SIDE, &side_rule)? as usize;
    let cf = t.require("cols", &format!("the number of columns, {side_rule}"))?;
    let cols = t.integer(&cf, 2, MAX_HEIGHTFIELD_SIDE, &side_rule)? as usize;
    let samples = rows * cols;
    if samples > MAX_HEIGHTFIELD_SAMPLES {
        return Err(t.error(
            cf.at,
            SceneErrorKind::BadGeometry,
            format!(
                "rows × cols = {samples} samples is too many (at most {MAX_HEIGHTFIELD_SAMPLES})"
            ),
        ));
    }
    let hf = t.require("heights", "an array of rows × cols numbers, row-major")?;
    let elements = t.array(
        &hf,
        "an array of numbers, row-major",
        0,
        MAX_HEIGHTFIELD_SAMPLES,
    )?;
    if elements.len() != samples {
        return Err(t.error(
            hf.at,
            SceneErrorKind::BadGeometry,
            format!(
                "{} has {} values but rows × cols = {rows} × {cols} = {samples} (expected one height per sample, row-major)",
                hf.name,
                elements.len()
            ),
        ));
    }
    let heights = elements
        .iter()
        .map(|e| t.scalar(e))
        .collect::<Result<Vec<Scalar>>>()?;
    let scale = match t.get("scale") {
        Some(f) => positive_vec(&f, "metres per column, height multiplier, metres per row")?,
        None => Vec3::new(Scalar::ONE, Scalar::ONE, Scalar::ONE),
    };
    Ok(GeometryDesc::HeightField {
        rows: rows as u32,
        cols: cols as u32,
        heights,
        scale,
    })
}

/// Whether every point lies in one plane (or on one line, or is the same
/// point), so that no hull with volume exists. Cross products round once;
/// the final triple product is exact, so only features far below a
/// millimetre could be misjudged as flat. Overflow (from points kilometres
/// apart) only makes the test lenient; the builder's hull code has the last
/// word.
fn all_coplanar(points: &[Vec3]) -> bool {
    let (flat, _faults) = FaultScope::run(|| {
        let Some(&p0) = points.first() else {
            return true;
        };
        let Some(e1) = points.iter().map(|&p| p - p0).find(|d| !d.is_zero()) else {
            return true;
        };
        let Some(normal) = points
            .iter()
            .map(|&p| e1.cross(p - p0))
            .find(|n| !n.is_zero())
        else {
            return true;
        };
        points.iter().all(|&p| normal.dot_wide(p - p0) == 0)
    });
    flat
}
