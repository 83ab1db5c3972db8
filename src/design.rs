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
    /// A field parameter's bracket is not `[N]`, `[*]` or `[A..B]`.
    #[error("parameter '{name}': use [N] (an element or node number), [*] or [A..B]")]
    FieldSyntax {
        /// The parameter name.
        name: String,
    },
    /// A field parameter's range (`[A..B]`) selects none of the field's members.
    #[error("parameter '{name}': the range selects none of the field's {count} members{numbered}")]
    EmptyRange {
        /// The parameter name.
        name: String,
        /// The field's members (elements of the body, hitting nodes of the pair, nodes of
        /// the set).
        count: usize,
        /// ` (numbered A to B)`, the smallest and largest member, or empty for none.
        numbered: String,
    },
    /// A field parameter's element or node is not on what it names.
    #[error("parameter '{name}': {what} {number} is not in '{on}'")]
    NotOn {
        /// The parameter name.
        name: String,
        /// `element`, `hitting node` or `node`.
        what: &'static str,
        /// The number given.
        number: usize,
        /// The body, pair or node set.
        on: String,
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
    ///   ([`crate::mesh::shape_map`]);
    /// * field parameters, one entity each (its number in brackets, as ParaView numbers cells
    ///   and points): `BODY.PARAM[E]`, material parameter `PARAM` of element `E` of the body
    ///   alone; `PAIR.PARAM[N]`, friction parameter `PARAM` at hitting node `N` alone;
    ///   `SET.x|y|z[N]`, the offset of node `N` of node set `SET` along an axis (a design
    ///   velocity per node and direction). [`Parameter::expand`] makes the whole field.
    pub fn by_name(model: &Model, name: &str) -> Result<Self, ParameterError> {
        if let Some((base, number)) = field_parts(name)? {
            let target = field_target(model, name, base, number)?;
            return Self::single(model, name, target);
        }
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

    /// The parameters a name stands for: [`Parameter::by_name`]'s one, or a field's every
    /// entity (`BODY.PARAM[*]`, `PAIR.PARAM[*]`, `SET.x[*]`) or those numbered `A` to `B - 1`
    /// (`[A..B]`), one parameter each, in entity order.
    pub fn expand(model: &Model, name: &str) -> Result<Vec<Self>, ParameterError> {
        let syntax = || ParameterError::FieldSyntax {
            name: name.to_string(),
        };
        let Some(open) = name.rfind('[').filter(|_| name.ends_with(']')) else {
            return Ok(vec![Self::by_name(model, name)?]);
        };
        let (base, inner) = (&name[..open], &name[open + 1..name.len() - 1]);
        let range = if inner == "*" {
            0..usize::MAX
        } else if let Some((a, b)) = inner.split_once("..") {
            let a = a.parse().map_err(|_| syntax())?;
            let b = b.parse().map_err(|_| syntax())?;
            a..b
        } else {
            return Ok(vec![Self::by_name(model, name)?]);
        };
        let members = field_members(model, name, base)?;
        let selected: Vec<usize> = members
            .iter()
            .copied()
            .filter(|m| range.contains(m))
            .collect();
        // an empty selection would ask the sensitivity solves for no column at all
        if selected.is_empty() {
            return Err(ParameterError::EmptyRange {
                name: name.to_string(),
                count: members.len(),
                numbered: match (members.iter().min(), members.iter().max()) {
                    (Some(a), Some(b)) => format!(" (numbered {a} to {b})"),
                    _ => String::new(),
                },
            });
        }
        (selected.into_iter())
            .map(|m| Self::by_name(model, &format!("{base}[{m}]")))
            .collect()
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

/// A field parameter's name split into what it names and the entity number in its bracket
/// (`None` for a name without a trailing `[N]`; `PAIR.motion[K]` is not a field).
fn field_parts(name: &str) -> Result<Option<(&str, usize)>, ParameterError> {
    let Some(open) = name.rfind('[').filter(|_| name.ends_with(']')) else {
        return Ok(None);
    };
    let base = &name[..open];
    if base.ends_with(".motion") {
        return Ok(None);
    }
    let number =
        name[open + 1..name.len() - 1]
            .parse()
            .map_err(|_| ParameterError::FieldSyntax {
                name: name.to_string(),
            })?;
    Ok(Some((base, number)))
}

/// What `OWNER.WHAT` names: a body's material parameter, a pair's friction parameter, or a
/// node set's axis.
enum FieldOwner<'a> {
    Body(usize, usize),
    Pair(usize, usize),
    Nodes(&'a [usize], usize),
}

fn field_owner<'a>(
    model: &'a Model,
    name: &str,
    base: &str,
) -> Result<(FieldOwner<'a>, String), ParameterError> {
    let no_match = || ParameterError::NoMatch {
        name: name.to_string(),
    };
    let (owner, what) = base.rsplit_once('.').ok_or_else(no_match)?;
    if let Some((b, body)) = (model.bodies.iter().enumerate()).find(|(_, b)| b.name == owner) {
        let names = body.material.param_names();
        let index =
            names
                .iter()
                .position(|n| *n == what)
                .ok_or_else(|| ParameterError::LawParameter {
                    name: name.to_string(),
                    what: "material",
                    law: body.material.name().to_string(),
                    known: names.iter().map(|n| n.to_string()).collect(),
                })?;
        return Ok((FieldOwner::Body(b, index), owner.to_string()));
    }
    if let Some((p, pair)) = (model.contacts.iter().enumerate()).find(|(_, c)| c.name == owner) {
        let f = pair
            .friction
            .as_ref()
            .ok_or_else(|| ParameterError::Frictionless {
                name: name.to_string(),
                pair: owner.to_string(),
            })?;
        let index = (f.param_names().iter().position(|n| *n == what)).ok_or_else(|| {
            ParameterError::LawParameter {
                name: name.to_string(),
                what: "friction law",
                law: f.name().to_string(),
                known: f.param_names().iter().map(|n| n.to_string()).collect(),
            }
        })?;
        return Ok((FieldOwner::Pair(p, index), owner.to_string()));
    }
    if let Some(nodes) = model.mesh.node_sets.get(owner) {
        let axis = ["x", "y", "z"]
            .iter()
            .position(|a| *a == what)
            .ok_or_else(|| ParameterError::Axis {
                name: name.to_string(),
                axis: what.to_string(),
            })?;
        return Ok((FieldOwner::Nodes(nodes, axis), owner.to_string()));
    }
    Err(no_match())
}

/// The target of field parameter `base[number]`.
fn field_target(
    model: &Model,
    name: &str,
    base: &str,
    number: usize,
) -> Result<DesignParam, ParameterError> {
    let (owner, on) = field_owner(model, name, base)?;
    let not_on = |what| ParameterError::NotOn {
        name: name.to_string(),
        what,
        number,
        on: on.clone(),
    };
    match owner {
        FieldOwner::Body(b, index) => {
            let elements = model.mesh.group_elements(model.bodies[b].group);
            elements
                .contains(&number)
                .then_some(DesignParam::ElementMaterial {
                    element: number,
                    index,
                })
                .ok_or_else(|| not_on("element"))
        }
        FieldOwner::Pair(pair, index) => {
            let node = (model.contacts[pair].hitting.iter())
                .position(|n| *n == number)
                .ok_or_else(|| not_on("hitting node"))?;
            Ok(DesignParam::NodeFriction { pair, node, index })
        }
        FieldOwner::Nodes(nodes, axis) => nodes
            .contains(&number)
            .then_some(DesignParam::NodeShape { node: number, axis })
            .ok_or_else(|| not_on("node")),
    }
}

/// The entity numbers of field `base` (`BODY.PARAM`, `PAIR.PARAM`, `SET.AXIS`), ascending.
fn field_members(model: &Model, name: &str, base: &str) -> Result<Vec<usize>, ParameterError> {
    Ok(match field_owner(model, name, base)?.0 {
        FieldOwner::Body(b, _) => model.mesh.group_elements(model.bodies[b].group).collect(),
        FieldOwner::Pair(p, _) => {
            let mut v = model.contacts[p].hitting.clone();
            v.sort_unstable();
            v
        }
        FieldOwner::Nodes(nodes, _) => {
            let mut v = nodes.to_vec();
            v.sort_unstable();
            v.dedup();
            v
        }
    })
}
