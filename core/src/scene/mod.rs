//! Scene files: a documented TOML format for a whole world (settings,
//! materials, bodies and their shapes), parsed into plain data.
//!
//! [`parse_scene`] reads the text with `toml_edit`, which keeps the source
//! span and raw text of every value, so numbers are converted exactly from
//! their digits (never through `f64`: the same file gives the same bits on
//! every machine) and every error points at a line and column. The result,
//! a [`SceneDesc`], is validated data; building a `World` from it is a
//! separate step. The format itself is documented in `docs/scene-format.md`.

mod build;
mod desc;
mod error;
mod parse;
mod reader;
mod rotation;
mod shape;

#[cfg(test)]
mod tests;

pub use build::{build_world, build_world_with_config, load_world};
pub use desc::{
    BodyDesc, BodyKindDesc, DEFAULT_DENSITY, DEFAULT_FRICTION, DEFAULT_RESTITUTION, GeometryDesc,
    JointSceneDesc, MassSpec, MaterialDesc, SceneDesc, ShapeDesc,
};
pub use error::{SceneError, SceneErrorKind};
pub use parse::parse_scene;
