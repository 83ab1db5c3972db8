//! What a researcher uses, in one import: `use fricsens::prelude::*;`.
//!
//! A scene (built-in or read from TOML) builds a model; the solver runs it and calls an observer
//! after every converged increment; a sensitivity run differentiates every response with respect
//! to the named design parameters by one of the methods. Kernels are generic over [`Scalar`];
//! a law of your own implements [`Law`] (its named parameters) and [`MaterialLaw`] or
//! [`FrictionLaw`].
//!
//! ```
//! use fricsens::prelude::*;
//!
//! let model = builtin("jenkins").unwrap().build().unwrap();
//! let mu = Parameter::by_name(&model, "mu").unwrap();
//! let settings = Settings { method: Method::Ddm, ..Settings::default() };
//! let (_, sens) = run_sensitivity(&model, &[mu], &settings).unwrap();
//! // oracles.md section 5: slipping at t = 1, T = mu N and dT/dmu = N = 1
//! let dt_dmu = sens.derivative("T", "mu").unwrap();
//! let at_1 = sens.increments.iter().position(|i| (i.time - 1.0).abs() < 1e-9).unwrap();
//! assert!((dt_dmu[at_1] - 1.0).abs() < 1e-10);
//! ```

pub use crate::contact::friction::FrictionLaw;
pub use crate::design::{Parameter, ParameterError};
pub use crate::law::Law;
pub use crate::material::MaterialLaw;
pub use crate::model::Model;
pub use crate::response::{Response, ResponseKind};
pub use crate::scalar::Scalar;
pub use crate::scene::{builtin, Scene, SceneError};
pub use crate::sensitivity::{
    run_sensitivity, Engine, Method, SensitivityError, SensitivityResults, Settings, TangentChoice,
};
pub use crate::solver::{AnalysisError, Converged, Observer, Results, RunOptions, Solver};
