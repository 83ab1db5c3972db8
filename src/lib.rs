#![warn(missing_docs)]

//! # fricsens
//!
//! Finite elements for large-deformation, elastoplastic, frictional contact problems, with design
//! sensitivity analysis by three methods that share one set of kernels:
//!
//! * **SDM** — the semi-analytical method of Chen, Hisada, Nakamura & Mori: after each converged
//!   increment, the unbalance force of a finitely perturbed design at the fixed converged state,
//!   solved with the already factored tangent;
//! * **DDM** — direct differentiation: the same kernels evaluated with forward-mode dual numbers;
//! * **FDM** — finite differences of complete reruns.
//!
//! Every kernel (element, material, contact, friction, mesh generator) is generic over
//! [`scalar::Scalar`], implemented by `f64`, `num_dual::Dual64` and `num_dual::DualSVec64<N>`.
//!
//! ```
//! use fricsens::scene::{cantilever, CantileverSpec};
//! use fricsens::sensitivity::{run_sensitivity, Method, Parameter, Settings};
//!
//! // a cantilever under a small tip load, and the derivative of its tip deflection in E
//! let spec = CantileverSpec::small_deflection();
//! let model = cantilever(&spec).build().unwrap();
//! let e = Parameter::by_name(&model, "E").unwrap();
//! let settings = Settings { method: Method::Ddm, ..Settings::default() };
//! let (_, sens) = run_sensitivity(&model, &[e], &settings).unwrap();
//! let last = sens.increments.last().unwrap();
//! let (w, dw_de) = (last.values[0], last.derivatives[0][0]);
//! // beam theory: w = -P L^3 / (3 E I), so dw/dE = -w / E
//! let exact = -spec.load() * spec.length.powi(3) / (3.0 * spec.young * spec.inertia());
//! assert!((w / exact - 1.0).abs() < 0.02);
//! assert!((dw_de / (-w / spec.young) - 1.0).abs() < 1e-6);
//! ```

pub mod assembly;
pub mod contact;
pub mod design;
pub mod element;
pub mod fields;
pub mod law;
pub mod linalg;
pub mod load;
pub mod material;
pub mod mesh;
pub mod model;
pub mod output;
pub(crate) mod precheck;
pub mod prelude;
pub mod response;
pub mod scalar;
pub mod scene;
pub mod sensitivity;
pub mod solver;
#[cfg(feature = "studies")]
pub mod studies;
pub mod terms;
