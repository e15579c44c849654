//! Deterministic Q32.32 math: the number type, vectors, rotations, matrices
//! and integer-only elementary functions. No floating point is used on any
//! path the simulation takes.

pub mod aabb;
pub mod decimal;
pub mod elem;
pub mod faults;
pub mod lanes;
pub mod mat3;
pub mod quat;
pub mod scalar;
pub mod transform;
pub mod vec3;

pub use aabb::Aabb;
pub use faults::{FaultScope, Faults};
pub use mat3::{Mat3, SymMat3};
pub use quat::Quat;
pub use scalar::Scalar;
pub use transform::Transform;
pub use vec3::Vec3;
