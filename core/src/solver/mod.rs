//! The step's numerical stages: integration, the contact solver and
//! sleeping (islands join here).

pub(crate) mod contact_solver;
pub mod integrate;
pub(crate) mod joint_solver;
pub mod sleep;
