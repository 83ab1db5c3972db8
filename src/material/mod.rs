//! Constitutive laws at a Gauss point, generic over the scalar.
//!
//! A material maps a strain tensor (Green-Lagrange `E` under large kinematics, the linear strain
//! `eps` under small kinematics) and the history of the point to the stress conjugate to it
//! (second Piola-Kirchhoff `S`, or Cauchy `sigma` under small kinematics) and the material tangent
//! `C = dS/dE`.
//!
//! ## Conventions
//! * Voigt order `(11, 22, 33, 12, 23, 13)`.
//! * Strain vectors carry engineering shears (`2 E12`); stress vectors carry tensor components.
//! * The tangent is the 6x6 matrix `C` with `dS_voigt = C dE_voigt` in those conventions.
//! * History is a flat slice of scalars per Gauss point, laid out by the material
//!   ([`MaterialLaw::history_len`]) and read through the law's typed view (J2:
//!   [`j2::J2History`]). It is generic: `f64` for values, a dual number for values with their
//!   design sensitivities.
//! * Branches (elastic/plastic) are decided on real parts; `frozen` forces the branch of a
//!   converged state (SDM's perturbed evaluation must not flip a branch).
//!
//! | symbol | meaning |
//! |---|---|
//! | `E`, `eps` | Green-Lagrange / linear strain |
//! | `S` | second Piola-Kirchhoff stress (Cauchy under small kinematics) |
//! | `C` | material tangent dS/dE (6x6 Voigt) |
//! | `lambda`, `mu` | Lame constants, `lambda = E nu / ((1+nu)(1-2nu))`, `mu = E / (2(1+nu))` |

pub mod j2;
pub mod neo_hookean;
pub mod svk;

pub use j2::J2Plasticity;
pub use neo_hookean::NeoHookean;
pub use svk::StVenantKirchhoff;

use crate::law::Law;
use crate::scalar::Scalar;
use nalgebra::{Matrix3, SMatrix, SVector};

/// The shipped materials, one line each: `Variant(Type) = "scene name", example VALUE;`
/// (the example: admissible parameters, used by the registry's tests). A new material is its
/// file (the law, [`Law`] with its `check`, [`MaterialLaw`]) plus a line here: the
/// [`Material`] enum, its scene format, [`crate::with_material!`] and [`Material::NAMES`] are
/// generated from this list.
#[doc(hidden)]
#[macro_export]
macro_rules! material_registry {
    ($callback:ident! $args:tt) => {
        $crate::$callback! { $args
            /// St Venant-Kirchhoff elasticity.
            Svk(StVenantKirchhoff) = "svk", example StVenantKirchhoff::new(1000.0, 0.3);
            /// J2 elastoplasticity with isotropic hardening.
            J2(J2Plasticity) = "j2", example J2Plasticity::saturation(200e3, 0.3, 250.0, 1e3, 400.0, 20.0);
            /// Compressible Neo-Hookean hyperelasticity.
            NeoHookean(NeoHookean) = "neo-hookean", example NeoHookean::new(1000.0, 0.3);
        }
    };
}

/// Call `$body` with `$m` bound to the concrete law inside a [`Material`] (one arm per
/// registered material).
#[macro_export]
macro_rules! with_material {
    ($mat:expr, $m:ident => $body:expr) => {
        $crate::material_registry!(__material_dispatch!($mat, $m, $body))
    };
}

#[doc(hidden)]
#[macro_export]
macro_rules! __material_dispatch {
    (($mat:expr, $m:ident, $body:expr)
     $($(#[$doc:meta])* $variant:ident($law:ty) = $tag:literal, example $example:expr;)+) => {
        match $mat {
            $($crate::material::Material::$variant($m) => $body,)+
        }
    };
}

#[doc(hidden)]
#[macro_export]
macro_rules! __material_enum {
    (() $($(#[$doc:meta])* $variant:ident($law:ty) = $tag:literal, example $example:expr;)+) => {
        /// The constitutive law of a body (enum dispatch over the registered materials), as it
        /// is written in scene files: `law = "NAME"` and the law's parameters by name.
        #[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
        // the enum's name in serde's messages ("expected internally tagged enum ..."), as
        // before the scene read the model's own type
        #[serde(tag = "law", rename = "MaterialSpec")]
        pub enum Material {
            $($(#[$doc])* #[serde(rename = $tag)] $variant($law),)+
        }

        impl Material {
            /// Scene names of the registered materials, in registration order.
            pub const NAMES: &'static [&'static str] = &[$($tag),+];
            /// One admissible instance of each registered material, in registration order.
            pub fn examples() -> Vec<Material> {
                vec![$(Material::$variant($example)),+]
            }
        }
    };
}

material_registry!(__material_enum!());

impl Law for Material {
    fn name(&self) -> &'static str {
        with_material!(self, m => m.name())
    }
    fn param_names(&self) -> &'static [&'static str] {
        with_material!(self, m => m.param_names())
    }
    fn params(&self) -> &[f64] {
        with_material!(self, m => m.params())
    }
    fn params_mut(&mut self) -> &mut [f64] {
        with_material!(self, m => m.params_mut())
    }
    fn check(&self) -> Result<(), crate::law::ParamError> {
        with_material!(self, m => m.check())
    }
}

impl Material {
    /// Parameter values.
    pub fn params(&self) -> &[f64] {
        Law::params(self)
    }
    /// Parameter names.
    pub fn param_names(&self) -> &'static [&'static str] {
        Law::param_names(self)
    }
    /// Short name (the scene's `law`).
    pub fn name(&self) -> &'static str {
        Law::name(self)
    }
    /// Whether the parameter values are admissible ([`Law::check`]).
    pub fn check(&self) -> Result<(), crate::law::ParamError> {
        Law::check(self)
    }
    /// Change parameter `index`.
    pub fn set_param(&mut self, index: usize, v: f64) {
        self.params_mut()[index] = v
    }
    /// Whether parameter `index` enters the stress of a point frozen elastic
    /// ([`MaterialLaw::enters_elastic_branch`]).
    pub fn enters_elastic_branch(&self, index: usize) -> bool {
        with_material!(self, m => m.enters_elastic_branch(index))
    }
    /// Young's modulus and Poisson's ratio of the initial elastic response
    /// ([`MaterialLaw::elastic_constants`]).
    pub fn elastic_constants(&self) -> (f64, f64) {
        with_material!(self, m => m.elastic_constants())
    }
    /// Young's modulus of the initial elastic response.
    pub fn young(&self) -> f64 {
        self.elastic_constants().0
    }
    /// History scalars per Gauss point.
    pub fn history_len(&self) -> usize {
        with_material!(self, m => m.history_len())
    }
    /// Names of the history entries per Gauss point.
    pub fn history_names(&self) -> &'static [&'static str] {
        with_material!(self, m => m.history_names())
    }
}

/// 6-vector in Voigt order `(11, 22, 33, 12, 23, 13)`.
pub type Voigt<S> = SVector<S, 6>;
/// 6x6 material tangent in Voigt form.
pub type Tangent<S> = SMatrix<S, 6, 6>;

/// Which side of a transition a Gauss point (or a friction point) is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Branch {
    /// Inside the transition: the elastic (trial) state is kept and the history is unchanged
    /// (a contract of every law: sensitivity updates skip elements frozen elastic).
    Elastic,
    /// Beyond it: the state is returned (plastic flow).
    Plastic,
}

/// What a material update returns at one Gauss point.
#[derive(Clone, Debug)]
pub struct PointResponse<S: Scalar> {
    /// Stress conjugate to the strain that was given (PK2 or Cauchy).
    pub stress: Matrix3<S>,
    /// Material tangent dS/dE, Voigt form (consistent/algorithmic for inelastic laws); zero
    /// where the update was not asked for it.
    pub tangent: Tangent<S>,
    /// Branch taken (or imposed by `frozen`).
    pub branch: Branch,
    /// Trial yield function over the current flow stress, real part: `f_trial / k`. Zero means
    /// the point sits exactly on the elastic/plastic transition; elastic laws return `-1`.
    pub yield_ratio: f64,
}

/// A constitutive law: parameters as plain values (scene data, named through [`Law`]),
/// evaluated with parameters lifted to the scalar type so any of them can be a design parameter.
pub trait MaterialLaw: Law {
    /// Young's modulus and Poisson's ratio of the law's initial (small-strain) elastic
    /// response: the stiffness scale from which the scene derives default penalties and
    /// contact scales, and the solver its force floor.
    fn elastic_constants(&self) -> (f64, f64);
    /// Whether parameter `index` enters the stress of a point frozen on the elastic branch
    /// ([`Branch::Elastic`]). Elastic laws: every parameter (the default); a plastic law says
    /// which act only on its plastic branch, so a design derivative with respect to them
    /// need not evaluate elements frozen elastic.
    fn enters_elastic_branch(&self, index: usize) -> bool {
        let _ = index;
        true
    }
    /// Number of history scalars per Gauss point (0 for elastic laws: they pay for none).
    /// Every history scalar starts at zero, the virgin state: the solver sets no other
    /// initial value (a law measures its history from that state, as J2's plastic strain
    /// and equivalent plastic strain are), and a scalar moved from zero means the point's
    /// path has changed its state (the active-set predictor holds contact nodes against
    /// such a body).
    fn history_len(&self) -> usize {
        0
    }
    /// Names of the history scalars of a Gauss point (`history_len` of them).
    fn history_names(&self) -> &'static [&'static str] {
        &[]
    }
    /// Where a Newton step from `strain_start` to `strain_end` (the strain the point sees,
    /// history `hist_old` committed) crosses the law's elastic domain from one side of its
    /// yield surface to the other: the fraction of the step, in (0, 1), whose trial state is
    /// deepest inside, or `None` (the default: elastic laws have no yield surface).
    ///
    /// A plastic point's consistent tangent is soft along the flow direction (J2 with
    /// H = 2000 MPa on E = 206 GPa: 120 times softer than 2 mu), so Newton's step for a point
    /// the converged state has elastic can be wider than the elastic domain; the radial
    /// return then lands on the opposite side of the yield surface and the next step comes
    /// back: a two-cycle with constant branches (the leaf spring refined 4 times, 30
    /// iterations at a residual of 1e4 N). The solver shortens such steps
    /// ([`crate::assembly::Assembler::elastic_crossing`]).
    fn elastic_crossing(
        &self,
        p: &[f64],
        strain_start: &Matrix3<f64>,
        strain_end: &Matrix3<f64>,
        hist_old: &[f64],
    ) -> Option<f64> {
        let _ = (p, strain_start, strain_end, hist_old);
        None
    }
    /// Stress update. `p` are the parameters lifted to `S` (same order as `params`),
    /// `hist_old` the committed history, `hist_new` receives the updated history. `tangent`:
    /// whether the caller reads [`PointResponse::tangent`]; where it does not (a residual
    /// alone: the sensitivity passes, SDM's unbalance, the adjoint's recordings) the law
    /// may leave it zero and pay nothing for it.
    fn update<S: Scalar>(
        &self,
        p: &[S],
        strain: &Matrix3<S>,
        hist_old: &[S],
        hist_new: &mut [S],
        frozen: Option<Branch>,
        tangent: bool,
    ) -> PointResponse<S>;
}

/// Symmetric tensor to Voigt strain (engineering shears).
#[inline]
pub fn strain_to_voigt<S: Scalar>(e: &Matrix3<S>) -> Voigt<S> {
    Voigt::from([
        e[(0, 0)],
        e[(1, 1)],
        e[(2, 2)],
        e[(0, 1)] + e[(1, 0)],
        e[(1, 2)] + e[(2, 1)],
        e[(0, 2)] + e[(2, 0)],
    ])
}

/// Symmetric tensor to Voigt stress (tensor components).
#[inline]
pub fn stress_to_voigt<S: Scalar>(s: &Matrix3<S>) -> Voigt<S> {
    Voigt::from([
        s[(0, 0)],
        s[(1, 1)],
        s[(2, 2)],
        s[(0, 1)],
        s[(1, 2)],
        s[(0, 2)],
    ])
}

/// Voigt stress (tensor components) to a symmetric tensor.
#[inline]
pub fn voigt_to_stress<S: Scalar>(v: &Voigt<S>) -> Matrix3<S> {
    Matrix3::new(v[0], v[3], v[5], v[3], v[1], v[4], v[5], v[4], v[2])
}

/// Voigt strain (engineering shears) to a symmetric tensor.
#[inline]
pub fn voigt_to_strain<S: Scalar>(v: &Voigt<S>) -> Matrix3<S> {
    let h = 0.5;
    Matrix3::new(
        v[0],
        v[3] * h,
        v[5] * h,
        v[3] * h,
        v[1],
        v[4] * h,
        v[5] * h,
        v[4] * h,
        v[2],
    )
}

/// Isotropic elasticity tensor in Voigt form from Lame constants.
#[inline]
pub fn isotropic_tangent<S: Scalar>(lambda: S, mu: S) -> Tangent<S> {
    let mut c = Tangent::<S>::zeros();
    for i in 0..3 {
        for j in 0..3 {
            c[(i, j)] = lambda;
        }
        c[(i, i)] = lambda + mu * 2.0;
        c[(i + 3, i + 3)] = mu;
    }
    c
}

/// Lame constants `(lambda, mu)` from Young's modulus and Poisson's ratio.
#[inline]
pub fn lame<S: Scalar>(young: S, poisson: S) -> (S, S) {
    let mu = young / ((poisson + 1.0) * 2.0);
    let lambda = young * poisson / ((poisson + 1.0) * (-(poisson * 2.0) + 1.0));
    (lambda, mu)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The registry is consistent: each registered material's scene name is its own
    /// [`Law::name`], its example passes its own check, and its scene table reads back equal.
    #[test]
    fn every_registered_material_names_itself_and_reads_back_its_table() {
        #[derive(serde::Serialize, serde::Deserialize)]
        struct Table {
            material: Material,
        }
        let examples = Material::examples();
        assert_eq!(examples.len(), Material::NAMES.len());
        for (m, tag) in examples.into_iter().zip(Material::NAMES) {
            assert_eq!(m.name(), *tag);
            assert_eq!(m.check(), Ok(()), "{tag}");
            assert_eq!(m.param_names().len(), m.params().len(), "{tag}");
            let text = toml::to_string(&Table {
                material: m.clone(),
            })
            .unwrap();
            assert!(text.contains(&format!("law = \"{tag}\"")), "{text}");
            for name in m.param_names() {
                assert!(
                    text.contains(&format!("\n{name} = ")),
                    "{tag}: {name} in {text}"
                );
            }
            assert_eq!(toml::from_str::<Table>(&text).unwrap().material, m);
        }
    }
}
