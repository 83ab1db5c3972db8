//! Element kernels: element shapes and face families ([`shape`]), element families evaluated
//! generically over the scalar ([`family`]), the hex8 continuum element and linear springs (discrete families).

pub mod family;
pub mod hex8;
pub mod shape;
pub mod spring;

pub use family::{ElementFamily, ElementInput, ElementOutput};
pub use hex8::{ElementFailure, Hex8Formulation, Kinematics};
pub use shape::{FaceFamily, FaceTopology, Shape, ShapeError};
pub use spring::SpringSet;

/// Unknowns per node (three displacement components).
pub const NODE_DOFS: usize = 3;

/// The global unknown of component `c` of node `n` (nodal unknowns come first, node-major).
#[inline]
pub fn node_dof(n: usize, c: usize) -> usize {
    NODE_DOFS * n + c
}

/// The three global unknowns of node `n`.
#[inline]
pub fn node_dofs(n: usize) -> std::ops::Range<usize> {
    NODE_DOFS * n..NODE_DOFS * (n + 1)
}
