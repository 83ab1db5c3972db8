//! Element kernels: element shapes and face families ([`shape`]), element families evaluated
//! generically over the scalar ([`family`]), the hex8 continuum element and linear springs.

pub mod family;
pub mod hex8;
pub mod shape;
pub mod spring;

pub use family::{ElementFamily, ElementInput, ElementOutput};
pub use hex8::{ElementFailure, Hex8Formulation, Kinematics};
pub use shape::{FaceFamily, FaceTopology, Shape, ShapeError};
pub use spring::Spring;
