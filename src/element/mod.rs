//! Element kernels: element shapes ([`shape`]) and face families ([`face`]), element families
//! evaluated generically over the scalar ([`family`]) by one continuum kernel ([`continuum`])
//! with each shape's tables ([`hex8`], [`hex20`], [`tet`], [`wedge`]), and linear springs
//! (discrete families).

pub mod continuum;
pub mod face;
pub mod family;
pub mod hex20;
pub mod hex8;
pub mod shape;
pub mod spring;
pub mod tet;
pub mod wedge;

pub use continuum::{ElementFailure, Formulation, Kinematics};
pub use face::FaceFamily;
pub use family::{ElementFamily, ElementInput, ElementOutput, FormulationError};
pub use shape::{FaceTopology, Shape, ShapeError};
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
