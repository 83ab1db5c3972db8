//! Friction laws as return maps of the tangential traction, generic over the scalar.
//!
//! The elastoplastic analogy of the paper (section 2.1): the tangential force of a hitting node
//! is predicted elastically from its elastic slip `g_T` (stick, penalty stiffness `eps_T`),
//! `t_trial = -eps_T g_T`, and returned to the slip surface `|t| <= limit(p_n)` when it lies
//! outside:
//!
//! ```text
//! stick:  |t_trial| <= limit   =>  t = t_trial
//! slip:   |t_trial| >  limit   =>  t = limit t_trial / |t_trial|
//! ```
//!
//! A law supplies `limit` (and may shape the transition); the solver, the consistent tangent
//! (forward AD over the contact unknowns) and all three sensitivity methods work through
//! [`FrictionLaw::return_map`] alone, so a new law needs no hand-written derivative.
//!
//! | symbol | meaning |
//! |---|---|
//! | `p_n` | normal contact force of the hitting node (>= 0) |
//! | `mu` | friction coefficient |
//! | `t_trial`, `t` | trial and returned tangential force (vectors in the tangent plane) |
//! | `slip_ratio` | `|t_trial| / limit - 1`: zero on the stick/slip transition |

use crate::scalar::{safe_norm, Scalar};
use nalgebra::Vector3;
use num_dual::DualSVec64;

/// Stick or slip.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum FrictionBranch {
    /// The trial force lies within the slip surface: `t = t_trial`.
    Stick,
    /// The trial force lies outside: `t` is returned onto the slip surface.
    Slip,
}

/// Result of a friction return map.
#[derive(Clone, Debug)]
pub struct FrictionUpdate<S: Scalar> {
    /// Returned tangential force on the hitting node.
    pub traction: Vector3<S>,
    /// Branch taken (or imposed by `frozen`).
    pub branch: FrictionBranch,
    /// `|t_trial| / limit - 1` (real part); zero on the stick/slip transition.
    pub slip_ratio: f64,
}

/// A tangential law: its parameters (design parameters too) and its return map.
pub trait FrictionLaw: Send + Sync + std::fmt::Debug {
    /// Short name used in scene files.
    fn name(&self) -> &'static str;
    /// Names of the parameters, in the order of `params`.
    fn param_names(&self) -> &'static [&'static str];
    /// Parameter values, in the order of [`FrictionLaw::param_names`].
    fn params(&self) -> &[f64];
    /// Parameter values, mutable (to set a design parameter).
    fn params_mut(&mut self) -> &mut [f64];
    /// The return map. `p` are the parameters lifted to `S`, `p_n >= 0` the normal force,
    /// `margin` the round-off of `|t_trial|` (a trial within it of the slip surface sticks),
    /// `frozen` imposes a branch (SDM's perturbed evaluations).
    fn return_map<S: Scalar>(
        &self,
        p: &[S],
        t_trial: &Vector3<S>,
        p_n: S,
        margin: f64,
        frozen: Option<FrictionBranch>,
    ) -> FrictionUpdate<S>;
}

/// The radial return onto a circle of radius `limit` shared by the Coulomb-type laws.
pub fn radial_return<S: Scalar>(
    t_trial: &Vector3<S>,
    limit: S,
    margin: f64,
    frozen: Option<FrictionBranch>,
) -> FrictionUpdate<S> {
    let norm = safe_norm(t_trial);
    let ratio = if limit.value() > 0.0 {
        norm.value() / limit.value() - 1.0
    } else if norm.value() > 0.0 {
        f64::INFINITY
    } else {
        0.0
    };
    let excess = norm.value() - limit.value();
    let branch = frozen.unwrap_or(if excess > margin {
        FrictionBranch::Slip
    } else {
        FrictionBranch::Stick
    });
    let traction = match branch {
        FrictionBranch::Stick => *t_trial,
        FrictionBranch::Slip => {
            if norm.value() > 0.0 {
                t_trial * (limit / norm)
            } else {
                Vector3::zeros()
            }
        }
    };
    FrictionUpdate {
        traction,
        branch,
        slip_ratio: ratio,
    }
}

/// Coulomb friction with a penalty stick law: `limit = mu p_n`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Coulomb {
    params: [f64; 1],
}

impl Coulomb {
    /// Coulomb friction with coefficient `mu`.
    pub fn new(mu: f64) -> Self {
        Coulomb { params: [mu] }
    }
}

impl FrictionLaw for Coulomb {
    fn name(&self) -> &'static str {
        "coulomb"
    }
    fn param_names(&self) -> &'static [&'static str] {
        &["mu"]
    }
    fn params(&self) -> &[f64] {
        &self.params
    }
    fn params_mut(&mut self) -> &mut [f64] {
        &mut self.params
    }
    fn return_map<S: Scalar>(
        &self,
        p: &[S],
        t_trial: &Vector3<S>,
        p_n: S,
        margin: f64,
        frozen: Option<FrictionBranch>,
    ) -> FrictionUpdate<S> {
        radial_return(t_trial, p[0] * p_n, margin, frozen)
    }
}

/// Regularised Coulomb friction: a smooth stick-slip transition,
/// `t = t_trial / sqrt(1 + (|t_trial| / (mu p_n))^2)`, which follows the penalty stick for
/// `|t_trial| << mu p_n` and tends to `mu p_n` for `|t_trial| >> mu p_n`. No branch: the law is
/// differentiable everywhere, so sensitivities have no kinks (at the price of a force that
/// only approaches the Coulomb limit). Parameters: `mu`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RegularizedCoulomb {
    params: [f64; 1],
}

impl RegularizedCoulomb {
    /// Regularised Coulomb friction with coefficient `mu`.
    pub fn new(mu: f64) -> Self {
        RegularizedCoulomb { params: [mu] }
    }
}

impl FrictionLaw for RegularizedCoulomb {
    fn name(&self) -> &'static str {
        "regularized-coulomb"
    }
    fn param_names(&self) -> &'static [&'static str] {
        &["mu"]
    }
    fn params(&self) -> &[f64] {
        &self.params
    }
    fn params_mut(&mut self) -> &mut [f64] {
        &mut self.params
    }
    fn return_map<S: Scalar>(
        &self,
        p: &[S],
        t_trial: &Vector3<S>,
        p_n: S,
        _margin: f64,
        frozen: Option<FrictionBranch>,
    ) -> FrictionUpdate<S> {
        let limit = p[0] * p_n;
        let norm = safe_norm(t_trial);
        if norm.value() == 0.0 {
            // the law's limit as the trial vanishes, for any positive limit: the penalty stick
            // (its tangent holds a node whose normal force is not yet known)
            return FrictionUpdate {
                traction: *t_trial,
                branch: FrictionBranch::Stick,
                slip_ratio: f64::INFINITY,
            };
        }
        if limit.value() <= 0.0 {
            return FrictionUpdate {
                traction: Vector3::zeros(),
                branch: FrictionBranch::Slip,
                slip_ratio: f64::INFINITY,
            };
        }
        let r = norm / limit;
        let scale = (r * r + 1.0).sqrt().recip();
        FrictionUpdate {
            traction: t_trial * scale,
            // the smooth law has no transition in its force; the trial's side of the cone
            // still decides whether the anchor follows the slip (as for Coulomb), a branch
            // decision that a frozen evaluation (SDM's perturbed unbalance) must keep
            branch: frozen.unwrap_or(if r.value() > 1.0 {
                FrictionBranch::Slip
            } else {
                FrictionBranch::Stick
            }),
            slip_ratio: f64::INFINITY,
        }
    }
}

/// Coulomb friction with a pressure-dependent coefficient `mu(p_n) = mu0 (p_n / p0)^(-n)`
/// (`p_n` the node's normal force, `p0` a reference force): the limit `mu(p_n) p_n` with the
/// radial return of [`Coulomb`]. Parameters: `mu0`, `p0`, `n`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PressureDependentCoulomb {
    params: [f64; 3],
}

impl PressureDependentCoulomb {
    /// `mu(p_n) = mu0 (p_n / p0)^(-n)`: coefficient `mu0` at the reference normal force `p0`,
    /// exponent `n`.
    pub fn new(mu0: f64, p0: f64, n: f64) -> Self {
        PressureDependentCoulomb {
            params: [mu0, p0, n],
        }
    }
}

impl FrictionLaw for PressureDependentCoulomb {
    fn name(&self) -> &'static str {
        "pressure-dependent"
    }
    fn param_names(&self) -> &'static [&'static str] {
        &["mu0", "p0", "n"]
    }
    fn params(&self) -> &[f64] {
        &self.params
    }
    fn params_mut(&mut self) -> &mut [f64] {
        &mut self.params
    }
    fn return_map<S: Scalar>(
        &self,
        p: &[S],
        t_trial: &Vector3<S>,
        p_n: S,
        margin: f64,
        frozen: Option<FrictionBranch>,
    ) -> FrictionUpdate<S> {
        // mu(p) p = mu0 p0^n p^(1-n), written with exp/ln so every parameter carries its
        // derivative (powf takes a plain exponent); p_n = 0 gives no friction
        let limit = if p_n.value() > 0.0 {
            p[0] * ((p_n / p[1]).ln() * (-p[2])).exp() * p_n
        } else {
            S::zero()
        };
        radial_return(t_trial, limit, margin, frozen)
    }
}

/// Most parameters a [`UserFriction`] law may have: its Jacobian is taken with one dual number
/// of width `4 + MAX_USER_PARAMS` (the trial force, the normal force and the parameters).
pub const MAX_USER_PARAMS: usize = 12;

/// Width of the dual number that differentiates a user law: `t_trial` (3), `p_n` (1) and up to
/// [`MAX_USER_PARAMS`] parameters.
const USER_INPUTS: usize = 4 + MAX_USER_PARAMS;

/// The dual number a user law is differentiated with.
type UserJet = DualSVec64<USER_INPUTS>;

/// The object-safe face of a [`FrictionLaw`] the [`crate::contact::Friction`] enum does not
/// name: the law evaluated on plain values, and on plain values with the Jacobian of its
/// traction with respect to its inputs. The blanket implementation below gives it to every
/// `FrictionLaw + Clone`; users never implement it.
trait ErasedFrictionLaw: Send + Sync + std::fmt::Debug {
    fn name(&self) -> &'static str;
    fn param_names(&self) -> &'static [&'static str];
    fn params(&self) -> &[f64];
    fn params_mut(&mut self) -> &mut [f64];
    fn return_map_f64(
        &self,
        p: &[f64],
        t_trial: &Vector3<f64>,
        p_n: f64,
        margin: f64,
        frozen: Option<FrictionBranch>,
    ) -> FrictionUpdate<f64>;
    /// The update and `J[i][j] = d traction_i / d input_j`, inputs ordered
    /// `(t_trial_x, t_trial_y, t_trial_z, p_n, p_0, p_1, ..)`.
    fn return_map_jacobian(
        &self,
        p: &[f64],
        t_trial: &Vector3<f64>,
        p_n: f64,
        margin: f64,
        frozen: Option<FrictionBranch>,
    ) -> (FrictionUpdate<f64>, [[f64; USER_INPUTS]; 3]);
    fn clone_box(&self) -> Box<dyn ErasedFrictionLaw>;
}

impl<L: FrictionLaw + Clone + 'static> ErasedFrictionLaw for L {
    fn name(&self) -> &'static str {
        FrictionLaw::name(self)
    }
    fn param_names(&self) -> &'static [&'static str] {
        FrictionLaw::param_names(self)
    }
    fn params(&self) -> &[f64] {
        FrictionLaw::params(self)
    }
    fn params_mut(&mut self) -> &mut [f64] {
        FrictionLaw::params_mut(self)
    }
    fn return_map_f64(
        &self,
        p: &[f64],
        t_trial: &Vector3<f64>,
        p_n: f64,
        margin: f64,
        frozen: Option<FrictionBranch>,
    ) -> FrictionUpdate<f64> {
        self.return_map(p, t_trial, p_n, margin, frozen)
    }
    fn return_map_jacobian(
        &self,
        p: &[f64],
        t_trial: &Vector3<f64>,
        p_n: f64,
        margin: f64,
        frozen: Option<FrictionBranch>,
    ) -> (FrictionUpdate<f64>, [[f64; USER_INPUTS]; 3]) {
        let t = Vector3::from_fn(|i, _| UserJet::seeded(t_trial[i], i));
        let pn = UserJet::seeded(p_n, 3);
        let mut pj = [UserJet::from_re(0.0); MAX_USER_PARAMS];
        for (k, (pk, v)) in pj.iter_mut().zip(p).enumerate() {
            *pk = UserJet::seeded(*v, 4 + k);
        }
        let u = self.return_map(&pj[..p.len()], &t, pn, margin, frozen);
        let mut jac = [[0.0; USER_INPUTS]; 3];
        for (i, row) in jac.iter_mut().enumerate() {
            u.traction[i].parts_into(row);
        }
        let value = FrictionUpdate {
            traction: u.traction.map(|x| x.value()),
            branch: u.branch,
            slip_ratio: u.slip_ratio,
        };
        (value, jac)
    }
    fn clone_box(&self) -> Box<dyn ErasedFrictionLaw> {
        Box::new(self.clone())
    }
}

/// A friction law defined outside this crate, plugged into the solver and all three
/// sensitivity methods through [`FrictionLaw`] alone.
///
/// Write the law once, generic over the scalar, as the shipped laws are; wrap it with
/// [`UserFriction::new`] and put it in [`crate::contact::Friction::User`]. The wrapper erases
/// its type (the `Friction` enum is closed) and keeps every derivative exact:
///
/// * on `f64` (residuals, SDM's perturbed unbalance, FDM's reruns) the law runs as written;
/// * on a dual scalar `S` (the consistent tangent, DDM) the law runs once on a dual number
///   seeded on its own inputs `x = (t_trial, p_n, p)`, which gives its Jacobian
///   `J = d traction / d x`, and the chain rule carries the derivatives of `S`:
///   `traction_S = traction(x_re) + J (x_S - x_re)`, exact to first order, which is all a
///   first-order dual number holds.
///
/// The parameters become design parameters by name (`PAIR.NAME`), like those of the shipped
/// laws. A user law cannot be written to a scene file.
pub struct UserFriction {
    law: Box<dyn ErasedFrictionLaw>,
}

/// Why a law cannot be wrapped as a [`UserFriction`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UserFrictionError {
    /// The law has more parameters than the Jacobian's dual number holds.
    #[error("friction law '{name}' has {count} parameters; at most {max} are supported")]
    TooManyParameters {
        /// The law's name.
        name: &'static str,
        /// Its number of parameters.
        count: usize,
        /// [`MAX_USER_PARAMS`].
        max: usize,
    },
    /// The law's parameter names and values differ in number.
    #[error("friction law '{name}' names {names} parameters but has {values} values")]
    ParameterCount {
        /// The law's name.
        name: &'static str,
        /// Length of `param_names()`.
        names: usize,
        /// Length of `params()`.
        values: usize,
    },
}

impl UserFriction {
    /// Wrap a law. Fails when it has more than [`MAX_USER_PARAMS`] parameters, or when its
    /// parameter names and values differ in number.
    pub fn new<L: FrictionLaw + Clone + 'static>(law: L) -> Result<Self, UserFrictionError> {
        let name = law.name();
        let (names, values) = (law.param_names().len(), law.params().len());
        if names != values {
            return Err(UserFrictionError::ParameterCount {
                name,
                names,
                values,
            });
        }
        if values > MAX_USER_PARAMS {
            return Err(UserFrictionError::TooManyParameters {
                name,
                count: values,
                max: MAX_USER_PARAMS,
            });
        }
        Ok(UserFriction { law: Box::new(law) })
    }
}

impl Clone for UserFriction {
    fn clone(&self) -> Self {
        UserFriction {
            law: self.law.clone_box(),
        }
    }
}

impl std::fmt::Debug for UserFriction {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_tuple("UserFriction").field(&self.law).finish()
    }
}

impl PartialEq for UserFriction {
    /// Two user laws are equal when they have the same name, parameter names and values.
    fn eq(&self, other: &Self) -> bool {
        self.law.name() == other.law.name()
            && self.law.param_names() == other.law.param_names()
            && self.law.params() == other.law.params()
    }
}

impl FrictionLaw for UserFriction {
    fn name(&self) -> &'static str {
        self.law.name()
    }
    fn param_names(&self) -> &'static [&'static str] {
        self.law.param_names()
    }
    fn params(&self) -> &[f64] {
        self.law.params()
    }
    fn params_mut(&mut self) -> &mut [f64] {
        self.law.params_mut()
    }
    fn return_map<S: Scalar>(
        &self,
        p: &[S],
        t_trial: &Vector3<S>,
        p_n: S,
        margin: f64,
        frozen: Option<FrictionBranch>,
    ) -> FrictionUpdate<S> {
        let np = p.len().min(MAX_USER_PARAMS);
        let mut pv = [0.0; MAX_USER_PARAMS];
        for (v, x) in pv.iter_mut().zip(p) {
            *v = x.value();
        }
        let tv = t_trial.map(|x| x.value());
        if S::NPARTS == 0 {
            let u = self
                .law
                .return_map_f64(&pv[..np], &tv, p_n.value(), margin, frozen);
            return FrictionUpdate {
                traction: u.traction.map(S::lift),
                branch: u.branch,
                slip_ratio: u.slip_ratio,
            };
        }
        let (u, jac) = self
            .law
            .return_map_jacobian(&pv[..np], &tv, p_n.value(), margin, frozen);
        // the inputs' derivative parts: x_S - x_re has a zero value and the parts of x_S
        let delta = |x: S| x - S::lift(x.value());
        let mut dx = [S::zero(); USER_INPUTS];
        for i in 0..3 {
            dx[i] = delta(t_trial[i]);
        }
        dx[3] = delta(p_n);
        for k in 0..np {
            dx[4 + k] = delta(p[k]);
        }
        let traction = Vector3::from_fn(|i, _| {
            let mut t = S::lift(u.traction[i]);
            for (j, d) in dx.iter().enumerate().take(4 + np) {
                if jac[i][j] != 0.0 {
                    t += *d * jac[i][j];
                }
            }
            t
        });
        FrictionUpdate {
            traction,
            branch: u.branch,
            slip_ratio: u.slip_ratio,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::{Dual64, DualSVec64};

    #[test]
    fn stick_returns_the_trial_and_slip_lies_on_the_cone() {
        let law = Coulomb::new(0.3);
        let t = Vector3::new(0.1, 0.2, 0.0);
        let u = law.return_map(&[0.3], &t, 10.0, 0.0, None);
        assert_eq!(u.branch, FrictionBranch::Stick);
        assert_eq!(u.traction, t);
        let u = law.return_map(&[0.3], &(t * 100.0), 10.0, 0.0, None);
        assert_eq!(u.branch, FrictionBranch::Slip);
        assert!((u.traction.norm() - 3.0).abs() < 1e-14);
    }

    #[test]
    fn return_map_derivative_by_duals_matches_closed_form() {
        // slip: t = mu p t_trial/|t_trial|; d t / d mu = p e
        let law = Coulomb::new(0.3);
        let t = Vector3::new(Dual64::from(3.0), Dual64::from(4.0), Dual64::from(0.0));
        let u = law.return_map(&[Dual64::new(0.3, 1.0)], &t, Dual64::from(2.0), 0.0, None);
        assert!((u.traction[0].eps - 2.0 * 0.6).abs() < 1e-15);
        assert!((u.traction[1].eps - 2.0 * 0.8).abs() < 1e-15);
        // zero trial traction: finite derivatives
        let z = Vector3::from_element(DualSVec64::<3>::from_re(0.0).derivative(0));
        let u = law.return_map(
            &[DualSVec64::from_re(0.3)],
            &z,
            DualSVec64::from_re(1.0),
            0.0,
            Some(FrictionBranch::Slip),
        );
        assert!(u.traction[0].re == 0.0);
    }
}
