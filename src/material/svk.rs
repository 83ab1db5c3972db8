//! St Venant-Kirchhoff: `S = lambda tr(E) I + 2 mu E`, the linear isotropic law applied to the
//! Green-Lagrange strain (and, under small kinematics, Hooke's law).
//!
//! Parameters: `[E, nu]` (Young's modulus, Poisson's ratio). No history.

use super::{isotropic_tangent, lame, Branch, MaterialLaw, PointResponse, Tangent};
use crate::scalar::Scalar;
use nalgebra::Matrix3;

/// St Venant-Kirchhoff hyperelastic material.
#[derive(Clone, Debug, PartialEq)]
pub struct StVenantKirchhoff {
    params: [f64; 2],
}

impl StVenantKirchhoff {
    /// Young's modulus `young`, Poisson's ratio `poisson`.
    pub fn new(young: f64, poisson: f64) -> Self {
        Self {
            params: [young, poisson],
        }
    }
}

crate::law_params!(
    StVenantKirchhoff,
    "svk",
    ["E", "nu"],
    check = |p| {
        crate::law::positive(p[0], "E")?;
        crate::law::poisson(p[1], "nu")
    }
);

impl MaterialLaw for StVenantKirchhoff {
    fn elastic_constants(&self) -> (f64, f64) {
        (self.params[0], self.params[1])
    }
    fn update<S: Scalar>(
        &self,
        p: &[S],
        strain: &Matrix3<S>,
        _hist_old: &[S],
        _hist_new: &mut [S],
        _frozen: Option<Branch>,
        tangent: bool,
    ) -> PointResponse<S> {
        let (lambda, mu) = lame(p[0], p[1]);
        let tr = strain.trace();
        let stress = strain * (mu * 2.0) + Matrix3::from_diagonal_element(lambda * tr);
        PointResponse {
            stress,
            tangent: if tangent {
                isotropic_tangent(lambda, mu)
            } else {
                Tangent::zeros()
            },
            branch: Branch::Elastic,
            yield_ratio: -1.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::{strain_to_voigt, stress_to_voigt};
    use approx::assert_relative_eq;

    #[test]
    fn tangent_maps_voigt_strain_to_voigt_stress() {
        let m = StVenantKirchhoff::new(210e9, 0.3);
        let e = Matrix3::new(1e-3, 2e-4, -3e-4, 2e-4, -5e-4, 1e-4, -3e-4, 1e-4, 7e-4);
        let r = m.update(&[210e9, 0.3], &e, &[], &mut [], None, true);
        let s_from_c = r.tangent * strain_to_voigt(&e);
        assert_relative_eq!(s_from_c, stress_to_voigt(&r.stress), max_relative = 1e-13);
    }
}
