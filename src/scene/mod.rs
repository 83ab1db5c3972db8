//! Scenes: complete analyses as data. A scene is written and read as TOML (serde), built-in
//! scenes have names, and [`Scene::build`] validates a scene and turns it into a [`Model`](crate::model::Model).
//!
//! A scene declares its physics — kinematics, material laws, element formulation, springs — and
//! the model pays only for what is declared (no history for elastic bodies, no internal
//! unknowns for plain hex8).

mod build;
pub mod builtin;
mod schema;

pub use build::TANGENTIAL_STIFFNESS_FACTOR;
pub use builtin::*;
pub use schema::*;
