//! Responses: scalar functions of a converged state whose sensitivities are wanted.
//!
//! Each is evaluated generically from the unknowns `z` and the residual `R` (which holds the
//! reactions at prescribed unknowns), so that a dual evaluation at the converged state with
//! `z` carrying `dz/db` and the parameter seeded gives the total derivative `dr/db` directly —
//! responses are differentiated with the same machinery as the residual, never by differencing
//! printed numbers.

use crate::contact::eval::ContactEval;
use crate::scalar::Scalar;

/// The converged state a response is evaluated at.
pub struct ResponseInput<'a, S: Scalar> {
    /// Unknowns `z`: nodal displacements (3 per node), element-internal unknowns, contact
    /// multipliers.
    pub z: &'a [S],
    /// Residual (reactions at prescribed unknowns).
    pub residual: &'a [S],
    /// Committed history.
    pub hist: &'a [S],
    /// Contact results, if the model has contact.
    pub contact: Option<&'a ContactEval<S>>,
    /// First flat hitting-node index of each pair.
    pub flat: Option<&'a [usize]>,
}

/// What a response measures.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum ResponseKind {
    /// Sum of the reactions (residual) of `nodes` in `component`.
    Reaction {
        /// Mesh node numbers.
        nodes: Vec<usize>,
        /// 0, 1, 2 for x, y, z.
        component: usize,
    },
    /// Mean displacement of `nodes` in `component`.
    Displacement {
        /// Mesh node numbers.
        nodes: Vec<usize>,
        /// 0, 1, 2 for x, y, z.
        component: usize,
    },
    /// Force exerted on the target of contact pair `pair` in `component`.
    TargetForce {
        /// Contact pair index in the model.
        pair: usize,
        /// 0, 1, 2 for x, y, z.
        component: usize,
    },
    /// Normal contact force over tributary area at hitting node `node` of pair `pair`.
    ContactPressure {
        /// Contact pair index in the model.
        pair: usize,
        /// Hitting node, counted within the pair.
        node: usize,
        /// Tributary area of the node in the reference configuration.
        area: f64,
    },
    /// One history scalar (e.g. the equivalent plastic strain of a Gauss point), by its index
    /// in the global history vector.
    History {
        /// Index in the global history vector.
        index: usize,
    },
}

/// What a response reads of a converged state. The sensitivity engine derives from it which
/// elements an evaluation may leave out (those whose residual and history nothing reads and
/// whose state the design does not change), so a response kind that reads something must say so
/// here, or its sensitivities would be silently wrong.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Reads<'a> {
    /// Nodes whose residual rows (reactions) it sums: every element around them is evaluated.
    pub residual_nodes: &'a [usize],
    /// It reads the unknowns `z` (always evaluated).
    pub state: bool,
    /// It reads the committed history.
    pub history: bool,
    /// It reads the contact results.
    pub contact: bool,
}

impl ResponseKind {
    /// What this response reads ([`Reads`]).
    pub fn reads(&self) -> Reads<'_> {
        match self {
            ResponseKind::Reaction { nodes, .. } => Reads {
                residual_nodes: nodes,
                ..Reads::default()
            },
            ResponseKind::Displacement { .. } => Reads {
                state: true,
                ..Reads::default()
            },
            ResponseKind::TargetForce { .. } | ResponseKind::ContactPressure { .. } => Reads {
                contact: true,
                ..Reads::default()
            },
            ResponseKind::History { .. } => Reads {
                history: true,
                ..Reads::default()
            },
        }
    }
}

/// A named response.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Response {
    /// Name, as in CSV headers and on the command line.
    pub name: String,
    /// What it measures.
    pub kind: ResponseKind,
}

impl Response {
    /// Value at a converged state.
    pub fn value<S: Scalar>(&self, at: &ResponseInput<'_, S>) -> S {
        let (z, residual, hist) = (at.z, at.residual, at.hist);
        match &self.kind {
            ResponseKind::Reaction { nodes, component } => {
                nodes.iter().fold(S::zero(), |acc, n| {
                    acc + residual[crate::model::node_dof(*n, *component)]
                })
            }
            ResponseKind::Displacement { nodes, component } => {
                let sum = nodes.iter().fold(S::zero(), |acc, n| {
                    acc + z[crate::model::node_dof(*n, *component)]
                });
                sum / nodes.len() as f64
            }
            ResponseKind::History { index } => hist[*index],
            ResponseKind::TargetForce { pair, component } => match at.contact {
                Some(c) => -c.pair_force[*pair][*component],
                None => S::zero(),
            },
            ResponseKind::ContactPressure { pair, node, area } => match (at.contact, at.flat) {
                (Some(c), Some(flat)) => c.normal_force[flat[*pair] + node] / *area,
                _ => S::zero(),
            },
        }
    }
}
