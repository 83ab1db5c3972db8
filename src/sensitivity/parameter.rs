//! Design parameters: a name resolved against a model into the quantities it moves.

use crate::model::{DesignParam, Model};
use crate::solver::AnalysisError;

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
    pub fn single(model: &Model, name: &str, target: DesignParam) -> Result<Self, AnalysisError> {
        let value = model.param_value(target).ok_or_else(|| {
            AnalysisError::Sensitivity(format!("design parameter {target:?} does not exist"))
        })?;
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
    /// * `load.NAME`, `prescribed.NAME`: the magnitude of a nodal load or prescribed displacement.
    pub fn by_name(model: &Model, name: &str) -> Result<Self, AnalysisError> {
        let err = |why: String| AnalysisError::Sensitivity(format!("parameter '{name}': {why}"));
        let axis = |a: &str| match a {
            "x" => Ok(0),
            "y" => Ok(1),
            "z" => Ok(2),
            _ => Err(err(format!("axis '{a}' is not x, y or z"))),
        };
        let parts: Vec<&str> = name.split('.').collect();
        let mut targets = Vec::new();
        match parts.as_slice() {
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
                    .ok_or_else(|| err(format!("no body '{body}'")))?;
                let axis = axis(a)?;
                targets.push(if *kind == "length" {
                    DesignParam::BlockLength {
                        block: b.block,
                        axis,
                    }
                } else {
                    DesignParam::BlockOrigin {
                        block: b.block,
                        axis,
                    }
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
                        .map_err(|_| err("use PAIR.motion[K]".into()))?;
                    let n = match &c.target {
                        crate::contact::Target::Rigid { motion, .. } => motion.len(),
                        _ => 0,
                    };
                    if index >= n {
                        return Err(err(format!("pair '{pair}' has {n} rigid motions")));
                    }
                    targets.push(DesignParam::RigidMotion { pair: pi, index });
                } else {
                    let f = c
                        .friction
                        .as_ref()
                        .ok_or_else(|| err(format!("pair '{pair}' is frictionless")))?;
                    let index =
                        f.param_names()
                            .iter()
                            .position(|n| n == param)
                            .ok_or_else(|| {
                                err(format!(
                                    "friction law '{}' has parameters {:?}",
                                    f.name(),
                                    f.param_names()
                                ))
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
                    .ok_or_else(|| err(format!("no body '{body}'")))?;
                let index = b
                    .material
                    .param_names()
                    .iter()
                    .position(|n| n == param)
                    .ok_or_else(|| {
                        err(format!(
                            "material '{}' has parameters {:?}",
                            b.material.name(),
                            b.material.param_names()
                        ))
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
            return Err(err("matches nothing in this model".into()));
        }
        let value = model
            .param_value(targets[0])
            .expect("resolved target exists");
        if targets.iter().any(|t| model.param_value(*t) != Some(value)) {
            return Err(err(
                "its targets have different values; name one of them (BODY.PARAM)".into(),
            ));
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
