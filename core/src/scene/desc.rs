//! The scene description: plain data, fully validated, ready for a builder.
//!
//! Parsing and building are separate steps so that each can be tested alone:
//! [`parse_scene`](super::parse::parse_scene) turns text into these types and
//! checks everything that can be checked without building (ranges, names,
//! references, index bounds), and the world builder turns them into bodies
//! and shapes. Every number is already an exact [`Scalar`]; every rotation is
//! already a unit [`Quat`]; every shape already carries its resolved friction,
//! restitution and mass specification, so the builder never looks up a
//! material or applies a default.

use crate::math::{Quat, Scalar, Vec3};
use crate::world::WorldConfig;

/// A whole scene: world settings, the named materials, and the bodies.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneDesc {
    /// The `[world]` table: gravity, tick rate, substeps and every other
    /// world setting, as the file gives them; the keys it leaves out keep
    /// [`WorldConfig::default`]'s values (Earth gravity along −y, 60 ticks
    /// per second, 4 substeps, ...). A world built from the scene uses it
    /// as it is.
    pub world: WorldConfig,
    /// The `[materials.*]` tables in file order. Kept (although every shape
    /// already has its material resolved) so tools can list and re-export
    /// them.
    pub materials: Vec<(String, MaterialDesc)>,
    /// The bodies in file order. Determinism: the builder must create them in
    /// this order, since creation order is simulation order.
    pub bodies: Vec<BodyDesc>,
    /// The `[[joints]]` in file order (created after every body, in this
    /// order).
    pub joints: Vec<JointSceneDesc>,
}

/// One `[[joints]]` table, validated: its bodies exist and differ, its
/// parameters are in range, its angles are in radians.
#[derive(Clone, Debug, PartialEq)]
pub struct JointSceneDesc {
    /// The joint's name ("" when the file gives none).
    pub name: String,
    /// What it constrains, with its limits, motor or spring.
    pub kind: crate::joint::JointKind,
    /// The first body's name.
    pub body_a: String,
    /// The second body's name.
    pub body_b: String,
    /// The joint frame in A's body frame (`anchor_a`, `rotation_a`).
    pub frame_a: crate::math::Transform,
    /// The joint frame in B's body frame.
    pub frame_b: crate::math::Transform,
    /// Whether the two bodies collide with each other.
    pub collide_connected: bool,
    /// Whether the angle limits are rigid (`rigid_limits`).
    pub rigid_limits: bool,
    /// Joint friction, N·m (`friction_torque`; zero: none).
    pub friction: Scalar,
    /// Break thresholds, N and N·m.
    pub break_force: Option<Scalar>,
    /// See `break_force`.
    pub break_torque: Option<Scalar>,
    /// 1-based line of the table, for errors.
    pub line: u32,
}

impl SceneDesc {
    /// The body called `name`, if any (names are unique within a scene).
    pub fn body(&self, name: &str) -> Option<&BodyDesc> {
        self.bodies.iter().find(|b| b.name == name)
    }

    /// The material called `name`, if any.
    pub fn material(&self, name: &str) -> Option<&MaterialDesc> {
        self.materials
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, m)| m)
    }
}

/// A named surface material: the friction, restitution and (optionally)
/// density that shapes referring to it inherit.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialDesc {
    /// Coulomb friction coefficient, ≥ 0. Default [`DEFAULT_FRICTION`].
    pub friction: Scalar,
    /// Coefficient of restitution, in `[0, 1]`. Default
    /// [`DEFAULT_RESTITUTION`].
    pub restitution: Scalar,
    /// Density in kg/m³ (> 0) for shapes that give neither `density` nor
    /// `mass`; `None` leaves them at [`DEFAULT_DENSITY`].
    pub density: Option<Scalar>,
}

/// Friction of a shape that names no material and gives no `friction`: 0.5.
pub const DEFAULT_FRICTION: Scalar = Scalar::HALF;
/// Restitution of a shape that names no material and gives no
/// `restitution`: 0 (no bounce).
pub const DEFAULT_RESTITUTION: Scalar = Scalar::ZERO;
/// Density of a shape that gives no `density`, no `mass` and whose material
/// gives no density: 1000 kg/m³ (water).
pub const DEFAULT_DENSITY: Scalar = Scalar::from_int(1000);

/// How a body moves: the world's own type (the scene names it `kind =
/// "static" | "dynamic" | "kinematic"`).
pub use crate::body::BodyKind as BodyKindDesc;

/// One `[[bodies]]` entry.
#[derive(Clone, Debug, PartialEq)]
pub struct BodyDesc {
    /// Unique, non-empty name (how errors, tools and games refer to it).
    pub name: String,
    /// Static, dynamic or kinematic.
    pub kind: BodyKindDesc,
    /// Position of the body origin in the world, m.
    pub position: Vec3,
    /// Orientation, a unit quaternion (already converted from the file's
    /// axis/angle or normalised from its quaternion). Identity by default.
    pub rotation: Quat,
    /// Initial linear velocity of the body origin, m/s (zero for static
    /// bodies).
    pub linear_velocity: Vec3,
    /// Initial angular velocity in world axes, rad/s (zero for static
    /// bodies).
    pub angular_velocity: Vec3,
    /// Linear damping, 1/s, ≥ 0. Default 0.
    pub linear_damping: Scalar,
    /// Angular damping, 1/s, ≥ 0. Default 0.
    pub angular_damping: Scalar,
    /// Whether the body starts asleep. Default false.
    pub asleep: bool,
    /// Whether the body is a bullet (continuous collision every tick, also
    /// against dynamic bodies). Dynamic bodies only. Default false.
    pub bullet: bool,
    /// The body's shapes, at least one, in file order.
    pub shapes: Vec<ShapeDesc>,
    /// 1-based source line of the body's `[[bodies]]` header (or inline
    /// table), so that later errors (from the builder) can point at the file.
    pub line: u32,
}

/// One shape of a body: geometry, local pose, mass, surface and filtering.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeDesc {
    /// The kind and its dimensions.
    pub geometry: GeometryDesc,
    /// Position of the shape's origin in body coordinates, m. Default zero.
    pub offset: Vec3,
    /// Orientation of the shape in body coordinates, a unit quaternion.
    /// Identity by default.
    pub rotation: Quat,
    /// The shape's mass: a density or a total mass. Only dynamic bodies use
    /// it.
    pub density_or_mass: MassSpec,
    /// The material the shape named, if any (already applied to `friction`,
    /// `restitution` and `density_or_mass`; kept for tools).
    pub material: Option<String>,
    /// Friction coefficient, ≥ 0: the shape's own `friction`, else its
    /// material's, else [`DEFAULT_FRICTION`].
    pub friction: Scalar,
    /// Restitution, in `[0, 1]`: the shape's own, else its material's, else
    /// [`DEFAULT_RESTITUTION`].
    pub restitution: Scalar,
    /// Collision category bits this shape belongs to. Default 1.
    pub group: u32,
    /// Categories this shape collides with. Default `0xFFFF_FFFF` (all). Two
    /// shapes collide only if each one's `group` meets the other's `mask`.
    pub mask: u32,
    /// Group index: two shapes with the same negative index never collide;
    /// with the same positive index always collide (overriding the masks);
    /// 0 means no group. Default 0.
    pub collision_group: i32,
    /// A trigger reports overlaps but produces no contact forces. Default
    /// false.
    pub trigger: bool,
    /// 1-based source line of the shape's `[[bodies.shapes]]` header (or
    /// inline table).
    pub line: u32,
}

/// How a shape's mass is given: the collider type, shared with the world
/// API so the builder passes it through unchanged.
pub use crate::collider::MassSpec;

/// The geometry of a shape, in the shape's local frame (before `offset` and
/// `rotation`). All lengths in metres.
#[derive(Clone, Debug, PartialEq)]
pub enum GeometryDesc {
    /// A ball centred on the origin.
    Sphere {
        /// Radius, > 0.
        radius: Scalar,
    },
    /// A segment along local y from `-half_height` to `+half_height`,
    /// inflated by `radius`: total height `2·half_height + 2·radius`.
    Capsule {
        /// Half the length of the core segment, > 0.
        half_height: Scalar,
        /// Radius, > 0.
        radius: Scalar,
    },
    /// A box centred on the origin, aligned with the local axes.
    Box {
        /// Half the size along x, y and z; each > 0.
        half_extents: Vec3,
    },
    /// The convex hull of a point cloud (at least 4 points, not all in one
    /// plane). The builder computes the hull; points inside it are allowed.
    ConvexHull {
        /// The points, in file order.
        points: Vec<Vec3>,
    },
    /// A triangle soup, static bodies only. Each triangle's front face is
    /// the side from which its vertices appear counter-clockwise.
    TriMesh {
        /// Vertex positions.
        vertices: Vec<Vec3>,
        /// Triangles as three distinct indices into `vertices`.
        indices: Vec<[u32; 3]>,
    },
    /// A regular grid of heights, static bodies only. Sample `(r, c)` sits at
    /// local `((c − (cols−1)/2)·sx, heights[r·cols + c]·sy, (r − (rows−1)/2)·sz)`:
    /// columns run along x, rows along z, and the grid is centred on the
    /// origin in x and z.
    HeightField {
        /// Number of rows (samples along z), ≥ 2.
        rows: u32,
        /// Number of columns (samples along x), ≥ 2.
        cols: u32,
        /// `rows·cols` heights, row-major (row 0 first), before scaling.
        heights: Vec<Scalar>,
        /// `[sx, sy, sz]`: column spacing, height multiplier, row spacing;
        /// each > 0.
        scale: Vec3,
    },
}

impl GeometryDesc {
    /// The `kind` string this geometry is written with in a scene file.
    pub fn kind_name(&self) -> &'static str {
        match self {
            GeometryDesc::Sphere { .. } => "sphere",
            GeometryDesc::Capsule { .. } => "capsule",
            GeometryDesc::Box { .. } => "box",
            GeometryDesc::ConvexHull { .. } => "convex_hull",
            GeometryDesc::TriMesh { .. } => "trimesh",
            GeometryDesc::HeightField { .. } => "heightfield",
        }
    }

    /// Whether only static bodies may carry this geometry (triangle meshes
    /// and height fields have no volume, hence no mass or inertia).
    pub fn is_static_only(&self) -> bool {
        matches!(
            self,
            GeometryDesc::TriMesh { .. } | GeometryDesc::HeightField { .. }
        )
    }
}
