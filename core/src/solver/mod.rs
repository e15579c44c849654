//! The step's numerical stages: integration and sleeping (the contact
//! solver and islands join here).

pub mod integrate;
pub mod sleep;
