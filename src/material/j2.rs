//! J2 (von Mises) elastoplasticity with isotropic hardening: radial return and its consistent
//! tangent, generic over the scalar so that one kernel gives values (`f64`), design
//! sensitivities (`Dual64`, `DualSVec64<N>`) and strain derivatives.
//!
//! ## Model
//! Total-Lagrangian additive split of the Green-Lagrange strain:
//!
//! ```text
//! E = E^e + E^p,       S = lambda tr(E - E^p) I + 2 mu (E - E^p)      (S = C : (E - E^p))
//! f(S, alpha) = |dev S| - sqrt(2/3) k(alpha)                            (von Mises on PK2)
//! dE^p/dt = gamma n,   n = dev S / |dev S|,   dalpha/dt = sqrt(2/3) gamma   (associated flow)
//! gamma >= 0,  f <= 0,  gamma f = 0
//! ```
//!
//! Hardening laws ([`Hardening`]):
//! * `Linear { h }`: `k(alpha) = sigma_y + H alpha`; parameters `[E, nu, sigma_y, H]`;
//! * `Saturation { h, sigma_inf, delta }` (Voce plus linear):
//!   `k(alpha) = sigma_y + H alpha + (sigma_inf - sigma_y)(1 - exp(-delta alpha))`;
//!   parameters `[E, nu, sigma_y, H, sigma_inf, delta]`.
//!
//! In uniaxial stress `alpha` equals the axial plastic strain and `k` is the uniaxial flow
//! stress, so `H` is the plastic modulus of a tensile test.
//!
//! Under small kinematics the element passes the linear strain `eps` in place of `E` and the
//! same code is classical small-strain J2 plasticity with `S` the Cauchy stress.
//!
//! | symbol | code | meaning |
//! |---|---|---|
//! | `E` | `strain` | Green-Lagrange strain (linear strain under small kinematics) |
//! | `E^p` | `ep_old`, `ep_new` | plastic strain (tensor components) |
//! | `alpha` | `alpha_old`, `alpha_new` | equivalent plastic strain |
//! | `S` | `stress` | second Piola-Kirchhoff stress (Cauchy under small kinematics) |
//! | `lambda`, `mu`, `kappa` | same | Lame constants, bulk modulus `lambda + 2 mu / 3` |
//! | `sigma_y`, `H` | `p[2]`, `p[3]` | initial yield stress, linear hardening modulus |
//! | `sigma_inf`, `delta` | `p[4]`, `p[5]` | saturation stress, saturation rate (Voce) |
//! | `k`, `k'` | `k`, `kp` | flow stress `k(alpha)` and its slope `dk/dalpha` |
//! | `xi_tr` | `xi_trial` | trial stress deviator `2 mu dev(E - E^p_n)` |
//! | `f_tr` | `f_trial` | trial yield function `|xi_tr| - sqrt(2/3) k(alpha_n)` |
//! | `Dgamma` | `dgamma` | plastic multiplier of the step |
//! | `theta`, `theta_bar` | `theta`, `theta_bar` | factors of the consistent tangent |
//!
//! ## Algorithm (Simo & Hughes 1998, Boxes 3.1 and 3.2)
//! 1. Trial state: `S_tr = C : (E - E^p_n)`, `xi_tr = dev S_tr`,
//!    `f_tr = |xi_tr| - sqrt(2/3) k(alpha_n)`.
//! 2. Branch: plastic if `re(f_tr) > 0`, unless `frozen` imposes one. Elastic: `S = S_tr`,
//!    history unchanged, tangent `C`.
//! 3. Plastic: solve
//!    `g(Dgamma) = |xi_tr| - 2 mu Dgamma - sqrt(2/3) k(alpha_n + sqrt(2/3) Dgamma) = 0`.
//!    Linear law: `Dgamma = f_tr / (2 mu + 2 H / 3)`, closed form in `S`. Saturation law: scalar
//!    Newton on real parts to 1e-13 relative (on `g` or on the step), then one Newton step in
//!    `S` from the converged value, whose derivative part is the implicit-function-theorem
//!    derivative `-(dg/db) / (dg/dDgamma)`, exact. (`g` is convex and decreasing for
//!    `k'' <= 0`, so Newton from `Dgamma = 0` converges monotonically.)
//! 4. `n = xi_tr / |xi_tr|`, `S = S_tr - 2 mu Dgamma n`, `E^p = E^p_n + Dgamma n`,
//!    `alpha = alpha_n + sqrt(2/3) Dgamma`.
//! 5. Consistent tangent, with `theta = 1 - 2 mu Dgamma / |xi_tr|` and
//!    `theta_bar = 1 / (1 + k'(alpha) / (3 mu)) - (1 - theta)`:
//!    `C_alg = kappa 1 (x) 1 + 2 mu theta (I - 1 (x) 1 / 3) - 2 mu theta_bar n (x) n`.
//!
//! Every quantity is computed in the scalar type `S`; only branch decisions and the Newton
//! iterations of step 3 use real parts. A zero trial deviator (hydrostatic or zero state) is
//! guarded: its norm goes through [`safe_norm_tensor`] and `n = 0`, so dual evaluations there
//! give finite derivatives. With `frozen = Some(Branch::Plastic)` at a state with `f_tr <= 0`
//! the return formulas are still evaluated (they stay defined, `Dgamma <= 0`): this is the
//! smooth continuation of the plastic branch that a perturbed (SDM) evaluation needs.
//!
//! `yield_ratio = re(f_tr) / (sqrt(2/3) re(k(alpha_n)))`.
//!
//! ## History (7 scalars per Gauss point)
//! `[Ep11, Ep22, Ep33, Ep12, Ep23, Ep13, alpha]`, tensor components (not engineering shears),
//! zero initially. In a sensitivity analysis the history is carried as dual numbers: the
//! derivative parts of step `n` enter step `n + 1` (design notes, section 3).
//!
//! ## Limits
//! * The additive split of the Green-Lagrange strain is objective (`E` is invariant under rigid
//!   rotations, so rotations of any size are handled exactly) but it is not the
//!   multiplicative `F = F^e F^p` of finite-strain plasticity: it is meant for small elastic
//!   strains and moderate plastic strains (a few percent), with large rotations allowed.
//! * Yield is measured on the deviator of PK2, not of the Kirchhoff/Cauchy stress; the two agree
//!   to first order in the strain. `tr E^p = 0` is plastic incompressibility only to first
//!   order (`det F^p = 1` is not enforced).
//! * Rate-independent, isothermal, isotropic hardening only (no kinematic hardening, so no
//!   Bauschinger effect); `k' >= 0` is assumed (no softening), which [`Law::check`]
//!   checks.

use super::{
    isotropic_tangent, lame, stress_to_voigt, Branch, MaterialLaw, PointResponse, Tangent,
};
use crate::law::{
    deserialize_params, finite, poisson, positive, serialize_params, Law, ParamError, ParamProblem,
};
use crate::scalar::{safe_norm_tensor, Scalar};
use nalgebra::Matrix3;

/// `sqrt(2/3)`.
const SQRT_2_3: f64 = 0.816_496_580_927_726;
/// Relative tolerance of the local Newton iteration on `Dgamma` (saturation law).
const NEWTON_TOL: f64 = 1e-13;
/// Iteration cap of the local Newton iteration (monotone convergence: never reached in practice).
const NEWTON_MAX_ITER: usize = 60;

/// Isotropic hardening law: the flow stress `k(alpha)` as a function of the equivalent plastic
/// strain `alpha` (values here are the scene data; [`MaterialLaw::update`] reads the parameters
/// from its `p` slice so that any of them can be seeded).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Hardening {
    /// `k = sigma_y + H alpha`.
    Linear {
        /// Hardening modulus `H`.
        h: f64,
    },
    /// `k = sigma_y + H alpha + (sigma_inf - sigma_y)(1 - exp(-delta alpha))` (Voce plus linear).
    Saturation {
        /// Linear hardening modulus `H`.
        h: f64,
        /// Saturation stress `sigma_inf` (`>= sigma_y`).
        sigma_inf: f64,
        /// Saturation rate `delta` (`>= 0`).
        delta: f64,
    },
}

/// J2 elastoplasticity with isotropic hardening on the additive Green-strain split (see the
/// module documentation for the model and its limits).
///
/// In scene files: `law = "j2"`, `E`, `nu`, `sigma_y`, `H`, and for the saturation law both
/// `sigma_inf` and `delta`.
#[derive(Clone, Debug, PartialEq)]
pub struct J2Plasticity {
    /// Which law; its values live in `params` only, so `params_mut` cannot desynchronise them.
    saturation: bool,
    /// `[E, nu, sigma_y, H, sigma_inf, delta]`; the last two are unused (zero) for `Linear`.
    params: [f64; 6],
    /// A scene file gave one of the saturation parameters without the other (its value is in
    /// its slot, `saturation` is false): [`Law::check`] rejects the law, and it is written back
    /// as it was read.
    incomplete: Option<Incomplete>,
}

/// The one saturation parameter a scene gave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Incomplete {
    SigmaInf,
    Delta,
}

/// Names of the parameters of the saturation law (the linear law has the first four); the
/// keys of the law's table in scene files.
const PARAM_NAMES: [&str; 6] = ["E", "nu", "sigma_y", "H", "sigma_inf", "delta"];

impl serde::Serialize for J2Plasticity {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let p = &self.params;
        let sigma_inf = self.saturation || self.incomplete == Some(Incomplete::SigmaInf);
        let delta = self.saturation || self.incomplete == Some(Incomplete::Delta);
        let values = [
            Some(p[0]),
            Some(p[1]),
            Some(p[2]),
            Some(p[3]),
            sigma_inf.then_some(p[4]),
            delta.then_some(p[5]),
        ];
        serialize_params(serializer, "j2", &PARAM_NAMES, &values)
    }
}

impl<'de> serde::Deserialize<'de> for J2Plasticity {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let v = deserialize_params(deserializer, "j2", &PARAM_NAMES, 4)?;
        let p = |i: usize| v[i].unwrap_or_default();
        let mut law = match (v[4], v[5]) {
            (Some(sigma_inf), Some(delta)) => {
                Self::saturation(p(0), p(1), p(2), p(3), sigma_inf, delta)
            }
            _ => Self::linear(p(0), p(1), p(2), p(3)),
        };
        law.incomplete = match (v[4], v[5]) {
            (Some(sigma_inf), None) => {
                law.params[4] = sigma_inf;
                Some(Incomplete::SigmaInf)
            }
            (None, Some(delta)) => {
                law.params[5] = delta;
                Some(Incomplete::Delta)
            }
            _ => None,
        };
        Ok(law)
    }
}

impl J2Plasticity {
    /// Names of the history scalars, in storage order ([`J2History`]).
    pub const HISTORY_NAMES: [&'static str; J2History::<f64>::LEN] =
        ["Ep11", "Ep22", "Ep33", "Ep12", "Ep23", "Ep13", "alpha"];

    /// Young's modulus, Poisson's ratio, initial yield stress and a hardening law (unchecked;
    /// see [`Law::check`]).
    pub fn new(young: f64, poisson: f64, sigma_y: f64, hardening: Hardening) -> Self {
        match hardening {
            Hardening::Linear { h } => Self {
                saturation: false,
                params: [young, poisson, sigma_y, h, 0.0, 0.0],
                incomplete: None,
            },
            Hardening::Saturation {
                h,
                sigma_inf,
                delta,
            } => Self {
                saturation: true,
                params: [young, poisson, sigma_y, h, sigma_inf, delta],
                incomplete: None,
            },
        }
    }

    /// Linear isotropic hardening `k = sigma_y + H alpha`; parameters `[E, nu, sigma_y, H]`.
    pub fn linear(young: f64, poisson: f64, sigma_y: f64, h: f64) -> Self {
        Self::new(young, poisson, sigma_y, Hardening::Linear { h })
    }

    /// Voce plus linear hardening; parameters `[E, nu, sigma_y, H, sigma_inf, delta]`.
    pub fn saturation(
        young: f64,
        poisson: f64,
        sigma_y: f64,
        h: f64,
        sigma_inf: f64,
        delta: f64,
    ) -> Self {
        Self::new(
            young,
            poisson,
            sigma_y,
            Hardening::Saturation {
                h,
                sigma_inf,
                delta,
            },
        )
    }

    /// The hardening law, with its current parameter values.
    pub fn hardening(&self) -> Hardening {
        let p = &self.params;
        if self.saturation {
            Hardening::Saturation {
                h: p[3],
                sigma_inf: p[4],
                delta: p[5],
            }
        } else {
            Hardening::Linear { h: p[3] }
        }
    }

    /// Number of parameters: 6 for the saturation law, 4 for the linear one.
    fn param_count(&self) -> usize {
        if self.saturation {
            6
        } else {
            4
        }
    }
}

impl Law for J2Plasticity {
    fn name(&self) -> &'static str {
        "j2"
    }
    fn param_names(&self) -> &'static [&'static str] {
        &PARAM_NAMES[..self.param_count()]
    }
    fn params(&self) -> &[f64] {
        &self.params[..self.param_count()]
    }
    fn params_mut(&mut self) -> &mut [f64] {
        let n = self.param_count();
        &mut self.params[..n]
    }
    /// `E > 0`, `-1 < nu < 1/2`, `sigma_y > 0`, `H >= 0`, and for the saturation law both of
    /// `sigma_inf >= sigma_y` and `delta >= 0` (so that `k' >= 0`), all finite.
    fn check(&self) -> Result<(), ParamError> {
        let p = &self.params;
        positive(p[0], "E")?;
        poisson(p[1], "nu")?;
        positive(p[2], "sigma_y")?;
        finite(p[3], "H")?;
        if p[3] < 0.0 {
            return Err(ParamError::new("H", ParamProblem::Softening));
        }
        if self.incomplete.is_some() {
            return Err(ParamError::new(
                "sigma_inf",
                ParamProblem::SaturationIncomplete,
            ));
        }
        if self.saturation {
            finite(p[4], "sigma_inf")?;
            finite(p[5], "delta")?;
            if p[4] < p[2] || p[5] < 0.0 {
                return Err(ParamError::new(
                    "sigma_inf",
                    ParamProblem::SaturationBelowYield,
                ));
            }
        }
        Ok(())
    }
}

/// The history of a J2 Gauss point, read from and written to its slice of the history
/// (`[Ep11, Ep22, Ep33, Ep12, Ep23, Ep13, alpha]`, tensor components, in that order).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct J2History<S: Scalar> {
    /// Plastic strain `E^p` (symmetric).
    pub plastic_strain: Matrix3<S>,
    /// Equivalent plastic strain `alpha`.
    pub alpha: S,
}

impl<S: Scalar> J2History<S> {
    /// Scalars per Gauss point.
    pub const LEN: usize = 7;

    /// The history stored in `h` (at least [`J2History::LEN`] scalars).
    pub fn read(h: &[S]) -> Self {
        J2History {
            plastic_strain: Matrix3::new(h[0], h[3], h[5], h[3], h[1], h[4], h[5], h[4], h[2]),
            alpha: h[6],
        }
    }

    /// Store the history in `h` (at least [`J2History::LEN`] scalars).
    pub fn write(&self, h: &mut [S]) {
        let ep = &self.plastic_strain;
        h[..Self::LEN].copy_from_slice(&[
            ep[(0, 0)],
            ep[(1, 1)],
            ep[(2, 2)],
            ep[(0, 1)],
            ep[(1, 2)],
            ep[(0, 2)],
            self.alpha,
        ]);
    }
}

/// The flow stress with parameters of scalar type `T`.
#[derive(Clone, Copy, Debug)]
struct FlowStress<T> {
    sigma_y: T,
    h: T,
    /// `(sigma_inf - sigma_y, delta)` for the saturation law.
    saturation: Option<(T, T)>,
}

impl<T: Scalar> FlowStress<T> {
    fn from_params(saturation: bool, p: &[T]) -> Self {
        Self {
            sigma_y: p[2],
            h: p[3],
            saturation: saturation.then(|| (p[4] - p[2], p[5])),
        }
    }

    fn re(&self) -> FlowStress<f64> {
        FlowStress {
            sigma_y: self.sigma_y.value(),
            h: self.h.value(),
            saturation: self.saturation.map(|(q, d)| (q.value(), d.value())),
        }
    }

    /// `(k(alpha), k'(alpha))`.
    #[inline]
    fn eval(&self, alpha: T) -> (T, T) {
        let lin = self.sigma_y + self.h * alpha;
        match self.saturation {
            None => (lin, self.h),
            Some((q, delta)) => {
                let decay = (-(delta * alpha)).exp();
                (lin + q * (-decay + 1.0), self.h + q * delta * decay)
            }
        }
    }

    /// Consistency residual `g(Dgamma)` and its slope `g'(Dgamma)`.
    #[inline]
    fn consistency(&self, xi_norm: T, two_mu: T, alpha_old: T, dgamma: T) -> (T, T) {
        let (k, kp) = self.eval(alpha_old + dgamma * SQRT_2_3);
        (
            xi_norm - two_mu * dgamma - k * SQRT_2_3,
            -(two_mu + kp * (2.0 / 3.0)),
        )
    }
}

/// Plastic multiplier of the step: closed form (linear law) or real Newton iterations plus one
/// final Newton step in `S` (implicit-function-theorem derivative).
fn plastic_multiplier<S: Scalar>(
    law: &FlowStress<S>,
    xi_norm: S,
    two_mu: S,
    alpha_old: S,
    f_trial: S,
) -> S {
    if law.saturation.is_none() {
        return f_trial / (two_mu + law.h * (2.0 / 3.0));
    }
    let law_re = law.re();
    let (xi_re, two_mu_re, alpha_re) = (xi_norm.value(), two_mu.value(), alpha_old.value());
    let scale = xi_re.max(law_re.eval(alpha_re).0.abs() * SQRT_2_3);
    let mut x = 0.0;
    for _ in 0..NEWTON_MAX_ITER {
        let (g, dg) = law_re.consistency(xi_re, two_mu_re, alpha_re, x);
        let step = -g / dg;
        x += step;
        if g.abs() <= NEWTON_TOL * scale || step.abs() <= NEWTON_TOL * x.abs() {
            break;
        }
    }
    let x = S::lift(x);
    let (g, dg) = law.consistency(xi_norm, two_mu, alpha_old, x);
    x - g / dg
}

/// `C_alg = kappa 1(x)1 + 2 mu theta (I - 1(x)1/3) - 2 mu theta_bar n(x)n` in Voigt form
/// (`dS_voigt = C dE_voigt`, engineering shear strains).
fn algorithmic_tangent<S: Scalar>(
    lambda: S,
    mu: S,
    theta: S,
    theta_bar: S,
    n: &Matrix3<S>,
) -> Tangent<S> {
    let kappa = lambda + mu * (2.0 / 3.0);
    let a = mu * theta * 2.0;
    let b = mu * theta_bar * 2.0;
    let nv = stress_to_voigt(n);
    let mut c = Tangent::<S>::zeros();
    for i in 0..6 {
        for j in 0..6 {
            c[(i, j)] = -(b * nv[i] * nv[j]);
        }
    }
    let vol = kappa - a * (1.0 / 3.0);
    for i in 0..3 {
        for j in 0..3 {
            c[(i, j)] += vol;
        }
        c[(i, i)] += a;
        c[(i + 3, i + 3)] += a * 0.5;
    }
    c
}

impl MaterialLaw for J2Plasticity {
    fn elastic_constants(&self) -> (f64, f64) {
        (self.params[0], self.params[1])
    }
    /// The trial deviator `2 mu dev(E - E_p)` moves linearly along the step. The step
    /// crosses the elastic domain when the point of its path nearest the origin lies inside
    /// the yield surface (radius `sqrt(2/3) k(alpha)`) and the end lies on the other side of
    /// the origin from the start (the return map would reverse the flow direction).
    fn elastic_crossing(
        &self,
        p: &[f64],
        strain_start: &Matrix3<f64>,
        strain_end: &Matrix3<f64>,
        hist_old: &[f64],
    ) -> Option<f64> {
        let old = J2History::read(hist_old);
        let ep = old.plastic_strain;
        let (_, mu) = lame(p[0], p[1]);
        let radius = FlowStress::from_params(self.saturation, p)
            .eval(old.alpha)
            .0
            * SQRT_2_3;
        let dev = |m: Matrix3<f64>| {
            let m = (m + m.transpose()) * 0.5;
            m - Matrix3::from_diagonal_element(m.trace() / 3.0)
        };
        let a = dev(strain_start - ep) * (2.0 * mu);
        let b = dev(strain_end - strain_start) * (2.0 * mu);
        let bb = b.norm_squared();
        if bb == 0.0 {
            return None;
        }
        let s = -a.dot(&b) / bb;
        let crosses = s > 0.0 && s < 1.0 && (a + b * s).norm() < radius && a.dot(&(a + b)) < 0.0;
        crosses.then_some(s)
    }

    /// E and nu: the elastic branch is `C : (E - E_p)` with the history unchanged; the yield
    /// stress and the hardening parameters act only on the plastic branch.
    fn enters_elastic_branch(&self, index: usize) -> bool {
        index < 2
    }
    fn history_len(&self) -> usize {
        J2History::<f64>::LEN
    }
    fn history_names(&self) -> &'static [&'static str] {
        &Self::HISTORY_NAMES
    }

    fn update<S: Scalar>(
        &self,
        p: &[S],
        strain: &Matrix3<S>,
        hist_old: &[S],
        hist_new: &mut [S],
        frozen: Option<Branch>,
        tangent: bool,
    ) -> PointResponse<S> {
        debug_assert!(p.len() >= self.params().len());
        const LEN: usize = J2History::<f64>::LEN;
        debug_assert!(hist_old.len() >= LEN && hist_new.len() >= LEN);
        let (lambda, mu) = lame(p[0], p[1]);
        let two_mu = mu * 2.0;
        let law = FlowStress::from_params(self.saturation, p);
        let J2History {
            plastic_strain: ep_old,
            alpha: alpha_old,
        } = J2History::read(hist_old);

        // Trial state.
        let ee = (strain + strain.transpose()) * S::lift(0.5) - ep_old;
        let s_trial = ee * two_mu + Matrix3::from_diagonal_element(lambda * ee.trace());
        let xi_trial = s_trial - Matrix3::from_diagonal_element(s_trial.trace() * (1.0 / 3.0));
        let xi_norm = safe_norm_tensor(&xi_trial);
        let r_old = law.eval(alpha_old).0 * SQRT_2_3;
        let f_trial = xi_norm - r_old;
        let yield_ratio = f_trial.value() / r_old.value().max(f64::MIN_POSITIVE);

        let branch = frozen.unwrap_or(if f_trial.value() > 0.0 {
            Branch::Plastic
        } else {
            Branch::Elastic
        });
        if branch == Branch::Elastic {
            hist_new[..LEN].copy_from_slice(&hist_old[..LEN]);
            return PointResponse {
                stress: s_trial,
                tangent: if tangent {
                    isotropic_tangent(lambda, mu)
                } else {
                    Tangent::zeros()
                },
                branch,
                yield_ratio,
            };
        }

        // Radial return.
        let dgamma = plastic_multiplier(&law, xi_norm, two_mu, alpha_old, f_trial);
        let (n, one_minus_theta) = if xi_norm.value() > 0.0 {
            let inv = xi_norm.recip();
            (xi_trial * inv, two_mu * dgamma * inv)
        } else {
            (Matrix3::zeros(), S::zero())
        };
        let stress = s_trial - n * (two_mu * dgamma);
        let alpha_new = alpha_old + dgamma * SQRT_2_3;
        J2History {
            plastic_strain: ep_old + n * dgamma,
            alpha: alpha_new,
        }
        .write(hist_new);

        let kp = law.eval(alpha_new).1;
        let theta = -one_minus_theta + 1.0;
        let theta_bar = (kp / (mu * 3.0) + 1.0).recip() - one_minus_theta;
        PointResponse {
            stress,
            tangent: if tangent {
                algorithmic_tangent(lambda, mu, theta, theta_bar, &n)
            } else {
                Tangent::zeros()
            },
            branch,
            yield_ratio,
        }
    }
}

#[cfg(test)]
#[path = "j2_tests.rs"]
mod tests;
