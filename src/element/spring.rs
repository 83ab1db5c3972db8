//! Linear springs with a full 3x3 stiffness: the discrete element families `Spring2` (between
//! the two nodes of a `line2` element) and `Spring1` (from the node of a `point1` element to
//! the ground), as Abaqus' SPRING2 and SPRING1.
//!
//! Force on node `a`: `f_a = K (u_a - u_b)`, on node `b`: `f_b = -f_a` (`u_b = 0` for a
//! grounded spring). Linear in `u`, so its tangent is `[[K, -K], [-K, K]]` (`K` grounded).
//! A spring has no Gauss point, history or branch, and its stiffness is its section: the
//! [`SpringSet`] of its element group, as a material is a body's.

use super::continuum::ElementFailure;
use crate::scalar::Scalar;
use nalgebra::{Matrix3, Vector3};

/// A set of linear springs: an element group of the mesh (`point1`: to the ground, `line2`:
/// between two nodes) sharing one stiffness.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SpringSet {
    /// Name (from the scene).
    pub name: String,
    /// The mesh's element group of the springs.
    pub group: usize,
    /// Stiffness matrix (row-major 3x3).
    pub stiffness: [[f64; 3]; 3],
}

impl SpringSet {
    /// The stiffness as a matrix lifted to `S`.
    pub fn k<S: Scalar>(&self) -> Matrix3<S> {
        Matrix3::from_fn(|i, j| S::one() * self.stiffness[i][j])
    }
}

/// Internal force of one spring (`dofs`: the displacements of its one or two nodes) into
/// `force` (three entries per node), and its tangent, row-major, into `tangent` if asked.
pub fn evaluate<S: Scalar>(
    k: &Matrix3<S>,
    dofs: &[Vector3<S>],
    force: &mut [S],
    tangent: Option<&mut [S]>,
) -> Result<(), ElementFailure> {
    let n = 3 * dofs.len();
    let (ua, ub) = match dofs {
        [a] => (a, Vector3::zeros()),
        [a, b] => (a, *b),
        _ => {
            return Err(ElementFailure::Layout {
                what: "spring nodes",
                expected: 2,
                got: dofs.len(),
            })
        }
    };
    let f = k * (ua - ub);
    for i in 0..3 {
        force[i] = f[i];
        if n == 6 {
            force[3 + i] = -f[i];
        }
    }
    if let Some(t) = tangent {
        for i in 0..3 {
            for j in 0..3 {
                t[i * n + j] = k[(i, j)];
                if n == 6 {
                    t[(i + 3) * n + j + 3] = k[(i, j)];
                    t[i * n + j + 3] = -k[(i, j)];
                    t[(i + 3) * n + j] = -k[(i, j)];
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spring_pulls_its_nodes_together_and_its_tangent_is_the_force_derivative() {
        let set = SpringSet {
            name: "s".into(),
            group: 0,
            stiffness: [[2.0, 0.5, 0.0], [0.5, 3.0, 0.0], [0.0, 0.0, 1.0]],
        };
        let k = set.k::<f64>();
        let d = [Vector3::new(0.1, -0.2, 0.3), Vector3::new(-0.05, 0.1, 0.0)];
        let mut f = [0.0; 6];
        let mut t = [0.0; 36];
        evaluate(&k, &d, &mut f, Some(&mut t)).unwrap();
        // equal and opposite forces
        for i in 0..3 {
            assert_eq!(f[i], -f[3 + i]);
        }
        // linear: f = T u exactly for the stacked displacements
        let u = [0.1, -0.2, 0.3, -0.05, 0.1, 0.0];
        for i in 0..6 {
            let tu: f64 = (0..6).map(|j| t[i * 6 + j] * u[j]).sum();
            assert!((tu - f[i]).abs() < 1e-15, "row {i}: {tu} vs {}", f[i]);
        }
        // grounded: the first node's half alone
        let mut g = [0.0; 3];
        evaluate(&k, &d[..1], &mut g, None).unwrap();
        let kd = k * d[0];
        assert_eq!(g, [kd[0], kd[1], kd[2]]);
        assert!(evaluate(&k, &[], &mut g, None).is_err());
    }
}
