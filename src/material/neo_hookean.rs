//! Compressible Neo-Hookean hyperelasticity, the third implementation of [`MaterialLaw`]
//! (after St Venant-Kirchhoff and J2), written in the second Piola-Kirchhoff form:
//!
//! ```text
//! W(C) = mu/2 (tr C - 3) - mu ln J + lambda/2 (ln J)^2
//! S    = 2 dW/dC = mu (I - C^-1) + lambda ln J C^-1
//! C_ijkl = dS_ij/dE_kl = lambda C^-1_ij C^-1_kl + (mu - lambda ln J)(C^-1_ik C^-1_jl + C^-1_il C^-1_jk)
//! ```
//!
//! | symbol | meaning |
//! |---|---|
//! | `C = I + 2E` | right Cauchy-Green tensor (`E` Green-Lagrange) |
//! | `J = sqrt(det C)` | volume ratio |
//! | `lambda`, `mu` | Lame constants from `E`, `nu` ([`super::lame`]) |
//!
//! At `E = 0` the tangent is Hooke's (`lambda`, `mu`), so the law agrees with St
//! Venant-Kirchhoff for small strains; unlike it, the energy grows without bound as `J -> 0`,
//! so an element cannot be compressed through zero volume. Under small kinematics the law is
//! evaluated with the linear strain in place of `E`. Parameters: `[E, nu]`. No history.

use super::{lame, Branch, MaterialLaw, PointResponse, Tangent};
use crate::scalar::{inv3, Scalar};
use nalgebra::Matrix3;

/// Compressible Neo-Hookean hyperelastic material.
#[derive(Clone, Debug, PartialEq)]
pub struct NeoHookean {
    params: [f64; 2],
}

impl NeoHookean {
    /// Young's modulus `young` and Poisson's ratio `poisson` (small-strain values).
    pub fn new(young: f64, poisson: f64) -> Self {
        Self {
            params: [young, poisson],
        }
    }
}

/// Voigt index pairs `(11, 22, 33, 12, 23, 13)`.
const VOIGT: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2)];

crate::law_params!(
    NeoHookean,
    "neo-hookean",
    ["E", "nu"],
    check = |p| {
        crate::law::positive(p[0], "E")?;
        crate::law::poisson(p[1], "nu")
    }
);

impl MaterialLaw for NeoHookean {
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
        let c = Matrix3::identity() + strain * S::from(2.0);
        // det C <= 0 (an inverted point) has no Neo-Hookean energy: the NaN it gives makes the
        // solver cut the increment back, as any non-finite residual does
        let (ci, det) = inv3(&c).unwrap_or((Matrix3::from_element(S::from(f64::NAN)), S::zero()));
        let ln_j = det.ln() * 0.5;
        let stress = (Matrix3::identity() - ci) * mu + ci * (lambda * ln_j);
        let shear = mu - lambda * ln_j;
        let tangent = if tangent {
            Tangent::<S>::from_fn(|a, b| {
                let (i, j) = VOIGT[a];
                let (k, l) = VOIGT[b];
                ci[(i, j)] * ci[(k, l)] * lambda
                    + (ci[(i, k)] * ci[(j, l)] + ci[(i, l)] * ci[(j, k)]) * shear
            })
        } else {
            Tangent::zeros()
        };
        PointResponse {
            stress,
            tangent,
            branch: Branch::Elastic,
            yield_ratio: -1.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::{strain_to_voigt, stress_to_voigt, voigt_to_strain, StVenantKirchhoff};
    use approx::assert_relative_eq;
    use num_dual::{DualNum, DualSVec64};

    fn strain() -> Matrix3<f64> {
        Matrix3::new(0.08, 0.02, -0.03, 0.02, -0.05, 0.01, -0.03, 0.01, 0.06)
    }

    #[test]
    fn tangent_is_the_dual_derivative_of_the_stress() {
        let m = NeoHookean::new(1000.0, 0.3);
        let e = strain();
        let r = m.update(&[1000.0, 0.3], &e, &[], &mut [], None, true);
        // S(E) with the six Voigt strains seeded
        let ev = strain_to_voigt(&e);
        let ed = voigt_to_strain(
            &ev.map(DualSVec64::<6>::from_re)
                .zip_map(&nalgebra::SVector::<usize, 6>::from_fn(|i, _| i), |x, i| {
                    DualSVec64::<6>::seeded(x.re, i)
                }),
        );
        let p = [
            DualSVec64::<6>::from_re(1000.0),
            DualSVec64::<6>::from_re(0.3),
        ];
        let rd = m.update(&p, &ed, &[], &mut [], None, true);
        let s = stress_to_voigt(&rd.stress);
        for a in 0..6 {
            for b in 0..6 {
                assert_relative_eq!(
                    r.tangent[(a, b)],
                    s[a].part(b),
                    epsilon = 1e-8 * r.tangent.abs().max(),
                );
            }
        }
    }

    #[test]
    fn small_strains_follow_hooke_and_the_stress_is_the_energy_gradient() {
        let (young, nu) = (1000.0, 0.3);
        let nh = NeoHookean::new(young, nu);
        let svk = StVenantKirchhoff::new(young, nu);
        let e = strain() * 1e-6;
        let a = nh.update(&[young, nu], &e, &[], &mut [], None, true);
        let b = svk.update(&[young, nu], &e, &[], &mut [], None, true);
        // the two laws differ at second order in the strain
        assert_relative_eq!(a.stress, b.stress, max_relative = 1e-5);
        // zero strain: zero stress, Hooke's tangent
        let z = nh.update(&[young, nu], &Matrix3::zeros(), &[], &mut [], None, true);
        assert!(z.stress.norm() < 1e-12);
        assert_relative_eq!(z.tangent, b.tangent, max_relative = 1e-12);
    }

    #[test]
    fn uniaxial_stretch_matches_the_energy() {
        // S = 2 dW/dC checked by differentiating W(C) with duals on the strain
        let (young, nu) = (1000.0, 0.3);
        let (lambda, mu) = lame(young, nu);
        let m = NeoHookean::new(young, nu);
        let e = strain();
        let r = m.update(&[young, nu], &e, &[], &mut [], None, true);
        for (i, j) in VOIGT {
            let mut ed = e.map(num_dual::Dual64::from);
            ed[(i, j)].eps = 1.0;
            if i != j {
                ed[(j, i)].eps = 1.0;
            }
            let c = Matrix3::identity() + ed * num_dual::Dual64::from(2.0);
            let ln_j = crate::scalar::det3(&c).ln() * 0.5;
            let w = (c.trace() - 3.0) * (mu / 2.0) - ln_j * mu + ln_j * ln_j * (lambda / 2.0);
            // dW/dE_ij for a symmetric perturbation counts both S_ij and S_ji
            let expected = if i == j {
                r.stress[(i, j)]
            } else {
                2.0 * r.stress[(i, j)]
            };
            assert_relative_eq!(w.eps, expected, max_relative = 1e-12);
        }
    }
}
