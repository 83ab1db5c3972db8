//! What materials and friction laws share: named parameters, their own admissibility check, and
//! their scene format.
//!
//! A law's parameters are plain values (the scene's data) in a fixed order; the kernels get them
//! lifted to the scalar type in the same order (`p: &[S]`), so any of them can be a design
//! parameter. The order is given once, by [`Law::param_names`], and serves four uses:
//!
//! * the scene format: the law's table in a scene file is `law = NAME` followed by one key per
//!   parameter, named as in `param_names` ([`serialize_params`], [`deserialize_params`]);
//! * design parameters by name (`E`, `upper.sigma_y`, `ground.mu`: [`Law::param_index`]);
//! * reports (the parameter columns);
//! * [`Law::check`]'s errors, which name the parameter so a scene can name the field
//!   (`bodies[0].material.E`).
//!
//! A shipped law is registered with one line (`material_registry!` in `material/mod.rs`,
//! `friction_registry!` in `contact/friction.rs`); a law whose parameters are a fixed array
//! `params: [f64; N]` writes its [`Law`] implementation and its serde with one
//! [`law_params!`](crate::law_params).

use serde::de::{self, MapAccess, Visitor};
use serde::ser::SerializeStruct;
use serde::{Deserializer, Serializer};
use std::fmt;

/// Named parameters of a constitutive or friction law: one trait for both (the material and
/// friction traits extend it).
pub trait Law: Send + Sync + fmt::Debug {
    /// Short name, the `law = "..."` of scene files.
    fn name(&self) -> &'static str;
    /// Names of the parameters, in the order of [`Law::params`]; also the keys of the law's
    /// table in scene files.
    fn param_names(&self) -> &'static [&'static str];
    /// Parameter values, in the order of [`Law::param_names`].
    fn params(&self) -> &[f64];
    /// Parameter values, mutable (reruns with a perturbed design).
    fn params_mut(&mut self) -> &mut [f64];
    /// Whether the parameter values are admissible; the error names the parameter. The
    /// default accepts every value (a user's law that checks nothing).
    fn check(&self) -> Result<(), ParamError> {
        Ok(())
    }
    /// Position of the parameter called `name` (the one name-to-slot lookup).
    fn param_index(&self, name: &str) -> Option<usize> {
        self.param_names().iter().position(|n| *n == name)
    }
    /// Value of the parameter called `name`.
    fn param(&self, name: &str) -> Option<f64> {
        self.param_index(name).map(|i| self.params()[i])
    }
    /// The parameter called `name`, mutable.
    fn param_mut(&mut self, name: &str) -> Option<&mut f64> {
        let i = self.param_index(name)?;
        self.params_mut().get_mut(i)
    }
}

/// What is wrong with a parameter value.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum ParamProblem {
    /// NaN or infinite.
    NotFinite(f64),
    /// Must be positive.
    NotPositive(f64),
    /// Must not be negative.
    Negative(f64),
    /// A Poisson's ratio outside `(-1, 1/2)`.
    NotPoisson(f64),
    /// A negative hardening modulus (softening).
    Softening,
    /// One of the two parameters of saturation hardening without the other.
    SaturationIncomplete,
    /// Saturation hardening with `sigma_inf < sigma_y` or `delta < 0`.
    SaturationBelowYield,
}

impl fmt::Display for ParamProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamProblem::NotFinite(v) => write!(f, "{v} is not a finite number"),
            ParamProblem::NotPositive(v) => write!(f, "must be > 0, got {v}"),
            ParamProblem::Negative(v) => write!(f, "must be >= 0, got {v}"),
            ParamProblem::NotPoisson(v) => write!(f, "must lie in (-1, 0.5), got {v}"),
            ParamProblem::Softening => write!(f, "softening (H < 0) is not supported"),
            ParamProblem::SaturationIncomplete => {
                write!(f, "saturation hardening needs both sigma_inf and delta")
            }
            ParamProblem::SaturationBelowYield => {
                write!(f, "needs sigma_inf >= sigma_y and delta >= 0")
            }
        }
    }
}

/// An inadmissible parameter value: which parameter (its name in [`Law::param_names`], the
/// key in scene files) and what is wrong.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("parameter {param}: {problem}")]
pub struct ParamError {
    /// The parameter's name.
    pub param: &'static str,
    /// What is wrong with its value.
    pub problem: ParamProblem,
}

impl ParamError {
    /// `problem` with parameter `param`.
    pub fn new(param: &'static str, problem: ParamProblem) -> Self {
        ParamError { param, problem }
    }
}

/// `v` is finite.
pub fn finite(v: f64, param: &'static str) -> Result<(), ParamError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(ParamError::new(param, ParamProblem::NotFinite(v)))
    }
}

/// `v` is finite and positive.
pub fn positive(v: f64, param: &'static str) -> Result<(), ParamError> {
    finite(v, param)?;
    if v > 0.0 {
        Ok(())
    } else {
        Err(ParamError::new(param, ParamProblem::NotPositive(v)))
    }
}

/// `v` is finite and not negative.
pub fn nonnegative(v: f64, param: &'static str) -> Result<(), ParamError> {
    finite(v, param)?;
    if v >= 0.0 {
        Ok(())
    } else {
        Err(ParamError::new(param, ParamProblem::Negative(v)))
    }
}

/// `v` is a Poisson's ratio: finite, in `(-1, 1/2)`.
pub fn poisson(v: f64, param: &'static str) -> Result<(), ParamError> {
    finite(v, param)?;
    if v > -1.0 && v < 0.5 {
        Ok(())
    } else {
        Err(ParamError::new(param, ParamProblem::NotPoisson(v)))
    }
}

/// Write a law's table: `name = value` for each parameter given, in the order of `names`
/// (`values[i] = None` leaves parameter `i` out). The `law = "..."` key is written by the
/// enum that holds the law.
pub fn serialize_params<S: Serializer>(
    serializer: S,
    law: &'static str,
    names: &'static [&'static str],
    values: &[Option<f64>],
) -> Result<S::Ok, S::Error> {
    let given = values.iter().filter(|v| v.is_some()).count();
    let mut s = serializer.serialize_struct(law, given)?;
    for (name, v) in names.iter().zip(values) {
        match v {
            Some(v) => s.serialize_field(name, v)?,
            None => s.skip_field(name)?,
        }
    }
    s.end()
}

/// Read a law's table: keys among `names` (another key is an error naming it and the keys
/// expected, as serde's derive with `deny_unknown_fields` words it), the first `required` of
/// them present (`missing field`), values numbers. Returns the values in the order of `names`.
pub fn deserialize_params<'de, D: Deserializer<'de>>(
    deserializer: D,
    law: &'static str,
    names: &'static [&'static str],
    required: usize,
) -> Result<Vec<Option<f64>>, D::Error> {
    struct Params {
        law: &'static str,
        names: &'static [&'static str],
        required: usize,
    }
    impl<'de> Visitor<'de> for Params {
        type Value = Vec<Option<f64>>;
        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(f, "the parameters of law {}", self.law)
        }
        fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
            let mut values = vec![None; self.names.len()];
            while let Some(key) = map.next_key::<std::borrow::Cow<'de, str>>()? {
                let Some(i) = self.names.iter().position(|n| *n == key) else {
                    return Err(de::Error::unknown_field(&key, self.names));
                };
                if values[i].is_some() {
                    return Err(de::Error::duplicate_field(self.names[i]));
                }
                values[i] = Some(map.next_value::<f64>()?);
            }
            if let Some(i) = (0..self.required).find(|&i| values[i].is_none()) {
                return Err(de::Error::missing_field(self.names[i]));
            }
            Ok(values)
        }
    }
    deserializer.deserialize_struct(
        law,
        names,
        Params {
            law,
            names,
            required,
        },
    )
}

/// [`Law`] and the scene format (serde) of a law whose parameters are the field
/// `params: [f64; N]`: `law_params!(Type, "name", ["p0", "p1", ..], check = |p| ...)`, the
/// check a closure over the parameter array (omit it to accept every value). The format is
/// the law's name as tag and one key per parameter, every one required.
#[macro_export]
macro_rules! law_params {
    ($law:ty, $name:literal, [$($param:literal),+ $(,)?] $(, check = $check:expr)? $(,)?) => {
        impl $crate::law::Law for $law {
            fn name(&self) -> &'static str {
                $name
            }
            fn param_names(&self) -> &'static [&'static str] {
                &[$($param),+]
            }
            fn params(&self) -> &[f64] {
                &self.params
            }
            fn params_mut(&mut self) -> &mut [f64] {
                &mut self.params
            }
            $(
                fn check(&self) -> Result<(), $crate::law::ParamError> {
                    let check: fn(&[f64]) -> Result<(), $crate::law::ParamError> = $check;
                    check(&self.params)
                }
            )?
        }
        impl $crate::law::__serde::Serialize for $law {
            fn serialize<S: $crate::law::__serde::Serializer>(
                &self,
                serializer: S,
            ) -> Result<S::Ok, S::Error> {
                let values = self.params.map(Some);
                $crate::law::serialize_params(serializer, $name, &[$($param),+], &values)
            }
        }
        impl<'de> $crate::law::__serde::Deserialize<'de> for $law {
            fn deserialize<D: $crate::law::__serde::Deserializer<'de>>(
                deserializer: D,
            ) -> Result<Self, D::Error> {
                const NAMES: &[&str] = &[$($param),+];
                let v = $crate::law::deserialize_params(deserializer, $name, NAMES, NAMES.len())?;
                let mut params = [0.0; NAMES.len()];
                for (p, v) in params.iter_mut().zip(v) {
                    *p = v.unwrap_or_default();
                }
                Ok(Self { params })
            }
        }
    };
}

#[doc(hidden)]
pub use serde as __serde;
