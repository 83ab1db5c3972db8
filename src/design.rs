//! Design parameters: a name resolved against a model into the quantities it moves.
//!
//! A [`Parameter`] names one value `b` and the model quantities ([`DesignParam`]) it sets; the
//! model lifts them into the scalar type of an evaluation ([`Model::lifted`]): `f64` at a
//! perturbed design for SDM and FDM, a dual number seeded with `db = 1` for DDM.

use crate::model::Model;
pub use crate::model::{DesignParam, Lifted};

/// Why a parameter name does not resolve on a model.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ParameterError {
    /// A shape parameter's axis is not x, y or z.
    #[error("parameter '{name}': axis '{axis}' is not x, y or z")]
    Axis {
        /// The parameter name.
        name: String,
        /// The axis given.
        axis: String,
    },
    /// A shape parameter of a body the block generator did not make (its nodes have fixed
    /// coordinates).
    #[error("parameter '{name}': body '{body}' was not made by the block generator: it has no shape parameters")]
    NotGenerated {
        /// The parameter name.
        name: String,
        /// The body.
        body: String,
    },
    /// No body of that name.
    #[error("parameter '{name}': no body '{body}'")]
    NoBody {
        /// The parameter name.
        name: String,
        /// The body named.
        body: String,
    },
    /// `PAIR.motionK` without a valid index.
    #[error("parameter '{name}': use PAIR.motion[K]")]
    MotionSyntax {
        /// The parameter name.
        name: String,
    },
    /// A rigid motion index beyond the pair's motions.
    #[error("parameter '{name}': pair '{pair}' has {count} rigid motions")]
    NoMotion {
        /// The parameter name.
        name: String,
        /// The pair.
        pair: String,
        /// Its number of rigid motions.
        count: usize,
    },
    /// A friction parameter of a pair without friction.
    #[error("parameter '{name}': pair '{pair}' is frictionless")]
    Frictionless {
        /// The parameter name.
        name: String,
        /// The pair.
        pair: String,
    },
    /// A law (friction or material) without a parameter of that name.
    #[error("parameter '{name}': {what} '{law}' has parameters {known:?}")]
    LawParameter {
        /// The parameter name.
        name: String,
        /// `friction law` or `material`.
        what: &'static str,
        /// The law's name.
        law: String,
        /// The law's parameter names.
        known: Vec<String>,
    },
    /// The name matches no quantity of the model.
    #[error("parameter '{name}': matches nothing in this model")]
    NoMatch {
        /// The parameter name.
        name: String,
    },
    /// A shared name whose targets have different values.
    #[error(
        "parameter '{name}': its targets have different values; name one of them (BODY.PARAM)"
    )]
    DifferentValues {
        /// The parameter name.
        name: String,
    },
    /// A target that does not exist in the model.
    #[error("design parameter {target:?} does not exist")]
    NoTarget {
        /// The target.
        target: DesignParam,
    },
}

/// A named design parameter: one value `b` shared by one or more model targets (e.g. the same
/// friction coefficient on two contact pairs).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Parameter {
    /// Name as given to [`Parameter::by_name`] (e.g. `mu`, `upper.length.x`).
    pub name: String,
    /// The model quantities that take the value `b` (all set together).
    pub targets: Vec<DesignParam>,
    /// Nominal value `b_0`.
    pub value: f64,
}

impl Parameter {
    /// A parameter with one target, named `name`.
    pub fn single(model: &Model, name: &str, target: DesignParam) -> Result<Self, ParameterError> {
        let value = model
            .param_value(target)
            .ok_or(ParameterError::NoTarget { target })?;
        Ok(Parameter {
            name: name.to_string(),
            targets: vec![target],
            value,
        })
    }

    /// Resolve a parameter name:
    /// * `PARAM` (e.g. `E`, `nu`, `sigma_y`): that material parameter of every body that has it
    ///   (one shared value);
    /// * `BODY.PARAM`: that material parameter of one body;
    /// * `BODY.length.x|y|z`, `BODY.origin.x|y|z`: a shape parameter of a body's block;
    /// * `PAIR.mu` (any friction-law parameter), `PAIR.eps_t`, `PAIR.motion[K]`: a contact
    ///   pair's friction parameter, tangential penalty, or rigid-target motion magnitude; a bare
    ///   friction parameter name (`mu`) is shared by every pair that has it;
    /// * `load.NAME`, `prescribed.NAME`, `pressure.NAME`: the magnitude of a nodal load, a
    ///   prescribed displacement or a pressure;
    /// * the name of a shape map (matched first, dots and all): its value
    ///   ([`crate::mesh::shape_map`]).
    pub fn by_name(model: &Model, name: &str) -> Result<Self, ParameterError> {
        let named = || name.to_string();
        let no_body = |body: &str| ParameterError::NoBody {
            name: named(),
            body: body.to_string(),
        };
        let axis = |a: &str| match a {
            "x" => Ok(0),
            "y" => Ok(1),
            "z" => Ok(2),
            _ => Err(ParameterError::Axis {
                name: named(),
                axis: a.to_string(),
            }),
        };
        let parts: Vec<&str> = name.split('.').collect();
        let mut targets = Vec::new();
        if let Some(map) = model.mesh.shape_maps.iter().position(|m| m.name == name) {
            targets.push(DesignParam::Shape { map });
        }
        match parts.as_slice() {
            _ if !targets.is_empty() => {}
            ["pressure", l] => {
                for (i, x) in model.pressures.iter().enumerate() {
                    if x.name == *l {
                        targets.push(DesignParam::Pressure { index: i });
                    }
                }
            }
            ["load", l] => {
                for (i, x) in model.loads.iter().enumerate() {
                    if x.name == *l {
                        targets.push(DesignParam::Load { index: i });
                    }
                }
            }
            ["prescribed", l] => {
                for (i, x) in model.prescribed.iter().enumerate() {
                    if x.name == *l {
                        targets.push(DesignParam::Prescribed { index: i });
                    }
                }
            }
            [body, kind @ ("length" | "origin"), a] => {
                let b = model
                    .bodies
                    .iter()
                    .find(|b| b.name == *body)
                    .ok_or_else(|| no_body(body))?;
                // a shape parameter moves the nodes of the block that generated the body
                let block = model.mesh.groups[b.group].block.ok_or_else(|| {
                    ParameterError::NotGenerated {
                        name: named(),
                        body: body.to_string(),
                    }
                })?;
                let axis = axis(a)?;
                targets.push(if *kind == "length" {
                    DesignParam::BlockLength { block, axis }
                } else {
                    DesignParam::BlockOrigin { block, axis }
                });
            }
            [pair, param] if model.contacts.iter().any(|c| c.name == *pair) => {
                let (pi, c) = model
                    .contacts
                    .iter()
                    .enumerate()
                    .find(|(_, c)| c.name == *pair)
                    .expect("checked");
                if *param == "eps_t" {
                    targets.push(DesignParam::TangentialStiffness { pair: pi });
                } else if let Some(k) = param.strip_prefix("motion") {
                    let index: usize = k
                        .trim_matches(|ch| ch == '[' || ch == ']')
                        .parse()
                        .map_err(|_| ParameterError::MotionSyntax { name: named() })?;
                    let n = match &c.target {
                        crate::contact::Target::Rigid { motion, .. } => motion.len(),
                        _ => 0,
                    };
                    if index >= n {
                        return Err(ParameterError::NoMotion {
                            name: named(),
                            pair: pair.to_string(),
                            count: n,
                        });
                    }
                    targets.push(DesignParam::RigidMotion { pair: pi, index });
                } else {
                    let f = c
                        .friction
                        .as_ref()
                        .ok_or_else(|| ParameterError::Frictionless {
                            name: named(),
                            pair: pair.to_string(),
                        })?;
                    let index =
                        f.param_names()
                            .iter()
                            .position(|n| n == param)
                            .ok_or_else(|| ParameterError::LawParameter {
                                name: named(),
                                what: "friction law",
                                law: f.name().to_string(),
                                known: f.param_names().iter().map(|n| n.to_string()).collect(),
                            })?;
                    targets.push(DesignParam::Friction { pair: pi, index });
                }
            }
            [body, param] => {
                let (bi, b) = model
                    .bodies
                    .iter()
                    .enumerate()
                    .find(|(_, b)| b.name == *body)
                    .ok_or_else(|| no_body(body))?;
                let index = b
                    .material
                    .param_names()
                    .iter()
                    .position(|n| n == param)
                    .ok_or_else(|| ParameterError::LawParameter {
                        name: named(),
                        what: "material",
                        law: b.material.name().to_string(),
                        known: b
                            .material
                            .param_names()
                            .iter()
                            .map(|n| n.to_string())
                            .collect(),
                    })?;
                targets.push(DesignParam::Material { body: bi, index });
            }
            [param] => {
                for (bi, b) in model.bodies.iter().enumerate() {
                    if let Some(index) = b.material.param_names().iter().position(|n| n == param) {
                        targets.push(DesignParam::Material { body: bi, index });
                    }
                }
                for (pi, c) in model.contacts.iter().enumerate() {
                    if let Some(f) = &c.friction {
                        if let Some(index) = f.param_names().iter().position(|n| n == param) {
                            targets.push(DesignParam::Friction { pair: pi, index });
                        }
                    }
                }
            }
            _ => {}
        }
        if targets.is_empty() {
            return Err(ParameterError::NoMatch { name: named() });
        }
        let value = model
            .param_value(targets[0])
            .expect("resolved target exists");
        if targets.iter().any(|t| model.param_value(*t) != Some(value)) {
            return Err(ParameterError::DifferentValues { name: named() });
        }
        Ok(Parameter {
            name: name.to_string(),
            targets,
            value,
        })
    }

    /// Perturbation step `db = beta b_0` (`beta` where `b_0 = 0`).
    pub fn step(&self, beta: f64) -> f64 {
        if self.value == 0.0 {
            beta
        } else {
            beta * self.value
        }
    }
}
