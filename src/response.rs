//! Responses: scalar functions of a converged state whose sensitivities are wanted.
//!
//! Each is evaluated generically from the unknowns `z` and the residual `R` (which holds the
//! reactions at prescribed unknowns), so that a dual evaluation at the converged state with
//! `z` carrying `dz/db` and the parameter seeded gives the total derivative `dr/db` directly —
//! responses are differentiated with the same machinery as the residual, never by differencing
//! printed numbers.

use crate::contact::eval::ContactEval;
use crate::scalar::Scalar;
use nalgebra::Matrix3;

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
    /// Volume-averaged Cauchy stresses, in the scalar of the evaluation.
    pub stress: &'a [Matrix3<S>],
    /// The element of each entry of `stress` (sorted); `None`: `stress` has every element.
    pub stress_elements: Option<&'a [usize]>,
}

impl<S: Scalar> ResponseInput<'_, S> {
    /// The volume-averaged Cauchy stress of element `e`, if this input has it.
    pub fn element_stress(&self, e: usize) -> Option<&Matrix3<S>> {
        match self.stress_elements {
            None => self.stress.get(e),
            Some(elements) => elements
                .binary_search(&e)
                .ok()
                .and_then(|i| self.stress.get(i)),
        }
    }
}

/// What a stress response measures of an element's volume-averaged Cauchy stress: a component
/// (`xx`, `yy`, `zz`, `xy`, `yz`, `xz`) or `von-mises`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StressMeasure {
    /// `sigma_xx`.
    Xx,
    /// `sigma_yy`.
    Yy,
    /// `sigma_zz`.
    Zz,
    /// `sigma_xy`.
    Xy,
    /// `sigma_yz`.
    Yz,
    /// `sigma_xz`.
    Xz,
    /// The von Mises stress `sqrt(3/2 s:s)`, `s` the deviator.
    VonMises,
}

impl StressMeasure {
    /// The measure of stress `sigma` (generic: differentiated with the evaluation).
    pub fn of<S: Scalar>(self, sigma: &Matrix3<S>) -> S {
        match self {
            StressMeasure::Xx => sigma[(0, 0)],
            StressMeasure::Yy => sigma[(1, 1)],
            StressMeasure::Zz => sigma[(2, 2)],
            StressMeasure::Xy => sigma[(0, 1)],
            StressMeasure::Yz => sigma[(1, 2)],
            StressMeasure::Xz => sigma[(0, 2)],
            StressMeasure::VonMises => {
                let p = sigma.trace() / 3.0;
                let mut ss = S::zero();
                for i in 0..3 {
                    for j in 0..3 {
                        let s = if i == j {
                            sigma[(i, j)] - p
                        } else {
                            sigma[(i, j)]
                        };
                        ss += s * s;
                    }
                }
                // zero-safe: the derivative of sqrt at a zero deviator is taken as zero
                if ss.re() == 0.0 {
                    S::zero()
                } else {
                    (ss * 1.5).sqrt()
                }
            }
        }
    }
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
    /// Translation of the rigid target of contact pair `pair` in `component`: prescribed, or
    /// the unknown of a target pushed by a force ([`crate::contact::MotionControl::Force`]),
    /// e.g. the indentation of a force-driven indenter.
    TargetDisplacement {
        /// Contact pair index in the model.
        pair: usize,
        /// 0, 1, 2 for x, y, z.
        component: usize,
    },
    /// Normal contact force over pressure area at hitting nodes `nodes` of pair `pair`: each
    /// node's share of the hitting faces in the reference configuration at the evaluated
    /// design (a shape parameter moves it:
    /// [`Lifted::pressure_area`](crate::model::Lifted::pressure_area)), or
    /// in the current configuration ([`PressureMeasure`]).
    ContactPressure {
        /// Contact pair index in the model.
        pair: usize,
        /// Hitting nodes, counted within the pair: one node, or the nodes of one station of a
        /// profile (e.g. the two node rows of a one-element-thick plane-strain slab), whose
        /// pressure is their total normal force over their total area.
        nodes: Vec<usize>,
        /// Over which area.
        measure: PressureMeasure,
    },
    /// One history scalar (e.g. the equivalent plastic strain of a Gauss point), by its index
    /// in the global history vector.
    History {
        /// Index in the global history vector.
        index: usize,
    },
    /// A measure of the volume-averaged Cauchy stress of one element.
    Stress {
        /// The element.
        element: usize,
        /// What of its stress.
        measure: StressMeasure,
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
    /// Elements whose evaluated stress it reads: every sensitivity evaluation evaluates them.
    pub stress_elements: &'a [usize],
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
            ResponseKind::TargetForce { .. }
            | ResponseKind::TargetDisplacement { .. }
            | ResponseKind::ContactPressure { .. } => Reads {
                contact: true,
                ..Reads::default()
            },
            ResponseKind::History { .. } => Reads {
                history: true,
                ..Reads::default()
            },
            ResponseKind::Stress { element, .. } => Reads {
                stress_elements: std::slice::from_ref(element),
                ..Reads::default()
            },
        }
    }
}

/// Which area a contact pressure divides the normal force by.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PressureMeasure {
    /// The nominal (first Piola-Kirchhoff-like) pressure: over the node's pressure area in the
    /// reference configuration. Equal to the current one under small strains; the default, as
    /// fricsens has always reported it.
    #[default]
    Nominal,
    /// The Cauchy (true) pressure: over the node's pressure area in the current configuration,
    /// as CalculiX, Abaqus and most papers report contact pressure. Its derivative includes how
    /// the area deforms.
    Current,
}

impl PressureMeasure {
    /// The name in scene files, CSV headers and VTK arrays: `nominal` or `current`.
    pub fn name(self) -> &'static str {
        match self {
            PressureMeasure::Nominal => "nominal",
            PressureMeasure::Current => "current",
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
                    acc + residual[crate::element::node_dof(*n, *component)]
                })
            }
            ResponseKind::Displacement { nodes, component } => {
                let sum = nodes.iter().fold(S::zero(), |acc, n| {
                    acc + z[crate::element::node_dof(*n, *component)]
                });
                sum / nodes.len() as f64
            }
            ResponseKind::History { index } => hist[*index],
            ResponseKind::Stress { element, measure } => at
                .element_stress(*element)
                .map_or(S::zero(), |sigma| measure.of(sigma)),
            ResponseKind::TargetForce { pair, component } => match at.contact {
                Some(c) => -c.pair_force[*pair][*component],
                None => S::zero(),
            },
            ResponseKind::TargetDisplacement { pair, component } => match at.contact {
                Some(c) => c.translation[*pair][*component],
                None => S::zero(),
            },
            ResponseKind::ContactPressure {
                pair,
                nodes,
                measure,
            } => match (at.contact, at.flat, nodes.split_first()) {
                (Some(c), Some(flat), Some((first, rest))) => {
                    let area = |k: usize| match measure {
                        PressureMeasure::Nominal => c.area[k],
                        PressureMeasure::Current => c.current_area[k],
                    };
                    // the sums start from the first node (one node: its force over its area,
                    // bit for bit)
                    let k0 = flat[*pair] + first;
                    let (force, total) =
                        rest.iter()
                            .fold((c.normal_force[k0], area(k0)), |(f, a), node| {
                                let k = flat[*pair] + node;
                                (f + c.normal_force[k], a + area(k))
                            });
                    force / total
                }
                _ => S::zero(),
            },
        }
    }
}
