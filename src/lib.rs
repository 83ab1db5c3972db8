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
//! use fricsens::scene::builtin;
//! use fricsens::solver::{NoObserver, RunOptions, Solver};
//!
//! let model = builtin("cantilever-small").unwrap().build().unwrap();
//! let mut solver = Solver::new(&model).unwrap();
//! let results = solver.run(&RunOptions::default(), &mut NoObserver).unwrap();
//! let n = results.states.len() - 1;
//! let w = model.responses[0].value(&results.states[n], &results.residuals[n], &results.histories[n]);
//! // tip deflection of a cantilever under P: -P L^3 / (3 E I)
//! let (p, l, e, i) = (1e-4 * 1e5 * 0.1f64.powi(4) / 12.0 / 4.0, 2.0, 1e5, 0.1f64.powi(4) / 12.0);
//! assert!((w / (-p * l.powi(3) / (3.0 * e * i)) - 1.0).abs() < 0.02);
//! ```

pub mod assembly;
pub mod element;
pub mod linalg;
pub mod material;
pub mod mesh;
pub mod model;
pub mod output;
pub mod response;
pub mod scalar;
pub mod scene;
pub mod sensitivity;
pub mod solver;
