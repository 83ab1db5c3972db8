//! Element kernels: the hex8 continuum element and linear springs.

pub mod hex8;
pub mod spring;

pub use hex8::{Hex8Formulation, Kinematics};
pub use spring::Spring;
