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

use crate::law::Law;
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

/// A tangential law: its parameters (design parameters too, named through [`Law`]) and its
/// return map.
pub trait FrictionLaw: Law {
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

/// The shipped friction laws, one line each: `Variant(Type) = "scene name", example VALUE;`
/// (the example: the parameters at which `fricsens compare-laws` compares the laws on the
/// strip pull-out, `mu = mu0 = 0.5`, the pressure-dependent law's reference force `p0 = 0.1`
/// about the strip's mean nodal normal force). A new law is its code (the law, [`Law`] with
/// its `check`, [`FrictionLaw`]) plus a line here: the [`Friction`] enum, its scene format,
/// [`crate::with_friction!`], [`Friction::NAMES`] and the law comparison's list are generated
/// from this list.
#[doc(hidden)]
#[macro_export]
macro_rules! friction_registry {
    ($callback:ident! $args:tt) => {
        $crate::$callback! { $args
            /// Coulomb friction (`law = "coulomb"`).
            Coulomb(Coulomb) = "coulomb", example Coulomb::new(0.5);
            /// Regularised Coulomb friction (`law = "regularized-coulomb"`).
            RegularizedCoulomb(RegularizedCoulomb) = "regularized-coulomb", example RegularizedCoulomb::new(0.5);
            /// Coulomb friction with a pressure-dependent coefficient (`law = "pressure-dependent"`).
            PressureDependent(PressureDependentCoulomb) = "pressure-dependent", example PressureDependentCoulomb::new(0.5, 0.1, 0.2);
        }
    };
}

/// Call `$body` with `$f` bound to the concrete law inside a [`Friction`] (one arm per
/// registered law, and one for [`Friction::User`]).
#[macro_export]
macro_rules! with_friction {
    ($fr:expr, $f:ident => $body:expr) => {
        $crate::friction_registry!(__friction_dispatch!($fr, $f, $body))
    };
}

#[doc(hidden)]
#[macro_export]
macro_rules! __friction_dispatch {
    (($fr:expr, $f:ident, $body:expr)
     $($(#[$doc:meta])* $variant:ident($law:ty) = $tag:literal, example $example:expr;)+) => {
        match $fr {
            $($crate::contact::Friction::$variant($f) => $body,)+
            $crate::contact::Friction::User($f) => $body,
        }
    };
}

#[doc(hidden)]
#[macro_export]
macro_rules! __friction_enum {
    (() $($(#[$doc:meta])* $variant:ident($law:ty) = $tag:literal, example $example:expr;)+) => {
        /// A friction law (enum dispatch over the registered laws, see [`FrictionLaw`], and a
        /// user's law), as written in scene files: `law = "NAME"` and the law's parameters by
        /// name.
        #[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
        // the enum's name in serde's messages ("expected internally tagged enum ..."), as
        // before the scene read the model's own type
        #[serde(tag = "law", rename = "FrictionSpec")]
        pub enum Friction {
            $($(#[$doc])* #[serde(rename = $tag)] $variant($law),)+
            /// A law defined outside the crate ([`UserFriction`]); a scene holding one builds
            /// and runs, but cannot be written to a scene file.
            #[serde(skip)]
            User(UserFriction),
        }

        impl Friction {
            /// Scene names of the registered laws, in registration order.
            pub const NAMES: &'static [&'static str] = &[$($tag),+];
            /// One instance of each registered law, in registration order, at the parameters
            /// the law comparison uses.
            pub fn examples() -> Vec<Friction> {
                vec![$(Friction::$variant($example)),+]
            }
        }
    };
}

friction_registry!(__friction_enum!());

impl Law for Friction {
    fn name(&self) -> &'static str {
        crate::with_friction!(self, f => f.name())
    }
    fn param_names(&self) -> &'static [&'static str] {
        crate::with_friction!(self, f => f.param_names())
    }
    fn params(&self) -> &[f64] {
        crate::with_friction!(self, f => f.params())
    }
    fn params_mut(&mut self) -> &mut [f64] {
        crate::with_friction!(self, f => f.params_mut())
    }
    fn check(&self) -> Result<(), crate::law::ParamError> {
        crate::with_friction!(self, f => f.check())
    }
}

impl Friction {
    /// A user's law (see [`UserFriction`]): any [`FrictionLaw`] written generic over the
    /// scalar.
    pub fn user<L: FrictionLaw + Clone + 'static>(law: L) -> Result<Self, UserFrictionError> {
        UserFriction::new(law).map(Friction::User)
    }
    /// Parameter values of the law, in the order of [`Friction::param_names`].
    pub fn params(&self) -> &[f64] {
        Law::params(self)
    }
    /// Names of the law's parameters (`mu`; `mu0`, `p0`, `n`; ...).
    pub fn param_names(&self) -> &'static [&'static str] {
        Law::param_names(self)
    }
    /// Set parameter `i` (in the order of [`Friction::params`]) to `v`.
    pub fn set_param(&mut self, i: usize, v: f64) {
        self.params_mut()[i] = v
    }
    /// Short name of the law, as in scene files.
    pub fn name(&self) -> &'static str {
        Law::name(self)
    }
    /// Whether the parameter values are admissible ([`Law::check`]).
    pub fn check(&self) -> Result<(), crate::law::ParamError> {
        Law::check(self)
    }
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
#[derive(Clone, Debug, PartialEq)]
pub struct Coulomb {
    params: [f64; 1],
}

impl Coulomb {
    /// Coulomb friction with coefficient `mu`.
    pub fn new(mu: f64) -> Self {
        Coulomb { params: [mu] }
    }
}

crate::law_params!(
    Coulomb,
    "coulomb",
    ["mu"],
    check = |p| crate::law::nonnegative(p[0], "mu")
);

impl FrictionLaw for Coulomb {
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
#[derive(Clone, Debug, PartialEq)]
pub struct RegularizedCoulomb {
    params: [f64; 1],
}

impl RegularizedCoulomb {
    /// Regularised Coulomb friction with coefficient `mu`.
    pub fn new(mu: f64) -> Self {
        RegularizedCoulomb { params: [mu] }
    }
}

crate::law_params!(
    RegularizedCoulomb,
    "regularized-coulomb",
    ["mu"],
    check = |p| crate::law::nonnegative(p[0], "mu")
);

impl FrictionLaw for RegularizedCoulomb {
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
#[derive(Clone, Debug, PartialEq)]
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

crate::law_params!(
    PressureDependentCoulomb,
    "pressure-dependent",
    ["mu0", "p0", "n"],
    check = |p| {
        crate::law::nonnegative(p[0], "mu0")?;
        crate::law::positive(p[1], "p0")?;
        crate::law::finite(p[2], "n")
    }
);

impl FrictionLaw for PressureDependentCoulomb {
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
trait ErasedFrictionLaw: Law {
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
/// [`UserFriction::new`] and put it in [`Friction::User`]. The wrapper erases
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

impl Law for UserFriction {
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
    fn check(&self) -> Result<(), crate::law::ParamError> {
        self.law.check()
    }
}

impl FrictionLaw for UserFriction {
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
        if !S::DIFFERENTIATES {
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

    /// The registry is consistent: each registered law's scene name is its own [`Law::name`],
    /// its example passes its own check, its scene table reads back equal, and the dispatch
    /// reaches it.
    #[test]
    fn every_registered_law_names_itself_and_reads_back_its_table() {
        #[derive(serde::Serialize, serde::Deserialize)]
        struct Table {
            friction: Friction,
        }
        let examples = Friction::examples();
        assert_eq!(examples.len(), Friction::NAMES.len());
        for (f, tag) in examples.into_iter().zip(Friction::NAMES) {
            assert_eq!(f.name(), *tag);
            assert_eq!(crate::with_friction!(&f, l => l.name()), *tag);
            assert_eq!(f.check(), Ok(()), "{tag}");
            let text = toml::to_string(&Table {
                friction: f.clone(),
            })
            .unwrap();
            assert!(text.contains(&format!("law = \"{tag}\"")), "{text}");
            assert_eq!(toml::from_str::<Table>(&text).unwrap().friction, f);
        }
    }

    #[test]
    fn a_parameter_is_found_by_its_name() {
        let mut f = PressureDependentCoulomb::new(0.5, 0.1, 0.2);
        assert_eq!(f.param_index("p0"), Some(1));
        assert_eq!(f.param("n"), Some(0.2));
        *f.param_mut("mu0").unwrap() = 0.7;
        assert_eq!(f.params(), [0.7, 0.1, 0.2]);
        assert_eq!(f.param("mu"), None);
        let err = PressureDependentCoulomb::new(0.5, 0.0, 0.2)
            .check()
            .unwrap_err();
        assert_eq!(
            (err.param, err.to_string().as_str()),
            ("p0", "parameter p0: must be > 0, got 0")
        );
    }
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
