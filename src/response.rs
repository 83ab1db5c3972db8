//! Responses: scalar functions of a converged state whose sensitivities are wanted.
//!
//! Each is evaluated generically from the unknowns `z` and the residual `R` (which holds the
//! reactions at prescribed unknowns), so that a dual evaluation at the converged state with
//! `z` carrying `dz/db` and the parameter seeded gives the total derivative `dr/db` directly —
//! responses are differentiated with the same machinery as the residual, never by differencing
//! printed numbers.

use crate::scalar::Scalar;

/// What a response measures.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum ResponseKind {
    /// Sum of the reactions (residual) of `nodes` in `component`.
    Reaction { nodes: Vec<usize>, component: usize },
    /// Mean displacement of `nodes` in `component`.
    Displacement { nodes: Vec<usize>, component: usize },
    /// One history scalar (e.g. the equivalent plastic strain of a Gauss point), by its index
    /// in the global history vector.
    History { index: usize },
}

/// A named response.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Response {
    pub name: String,
    pub kind: ResponseKind,
}

impl Response {
    /// Value at unknowns `z` with residual `residual` and committed history `hist`.
    pub fn value<S: Scalar>(&self, z: &[S], residual: &[S], hist: &[S]) -> S {
        match &self.kind {
            ResponseKind::Reaction { nodes, component } => nodes
                .iter()
                .fold(S::zero(), |acc, n| acc + residual[3 * n + component]),
            ResponseKind::Displacement { nodes, component } => {
                let sum = nodes
                    .iter()
                    .fold(S::zero(), |acc, n| acc + z[3 * n + component]);
                sum / nodes.len() as f64
            }
            ResponseKind::History { index } => hist[*index],
        }
    }
}
