//! Linear spring with a full 3x3 stiffness, between two nodes or from a node to the ground.
//!
//! Force on node `a`: `f_a = K (u_a - u_b)`, on node `b`: `f_b = -f_a` (`u_b = 0` for a
//! grounded spring). Linear in `u`, so its tangent is `K` itself.

use crate::scalar::Scalar;
use nalgebra::{Matrix3, Vector3};

/// A linear spring.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Spring {
    /// First node.
    pub a: usize,
    /// Second node; `None` ties `a` to the ground.
    pub b: Option<usize>,
    /// Stiffness matrix (row-major 3x3).
    pub stiffness: [[f64; 3]; 3],
}

impl Spring {
    /// The stiffness as a matrix lifted to `S`.
    pub fn k<S: Scalar>(&self, scale: S) -> Matrix3<S> {
        Matrix3::from_fn(|i, j| scale * self.stiffness[i][j])
    }

    /// Internal force on `a` (the force on `b` is its negative).
    pub fn force<S: Scalar>(&self, ua: &Vector3<S>, ub: &Vector3<S>, scale: S) -> Vector3<S> {
        self.k(scale) * (ua - ub)
    }
}
