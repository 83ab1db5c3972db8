//! What one contact evaluation produces: states, forces and gaps per hitting node.

use super::{ContactChoice, ContactPair};
use crate::scalar::Scalar;
use nalgebra::Vector3;

/// Per-evaluation contact results.
#[derive(Clone, Debug)]
pub struct ContactEval<S: Scalar> {
    /// Branch decisions per hitting node (flat over pairs).
    pub choice: Vec<ContactChoice>,
    /// Normal force per hitting node.
    pub normal_force: Vec<S>,
    /// Pressure area per hitting node at the evaluation's design, in the reference
    /// configuration (nominal pressure = normal force over it;
    /// [`crate::element::FaceFamily::pressure_share`]: the tributary area on linear faces,
    /// zero at the corners of quadratic ones).
    pub area: Vec<S>,
    /// Pressure area per hitting node in the current (deformed) configuration (Cauchy, or
    /// true, pressure = normal force over it; what CalculiX and Abaqus report). One for a
    /// node-set pair, like `area`. An evaluation with a mask of hitting nodes
    /// ([`crate::assembly::Frozen::skip_contact`]) leaves it as it was.
    pub current_area: Vec<S>,
    /// Total contact force on each pair's target (minus the sum of the forces on its
    /// hitting nodes): the reaction of a rigid target.
    pub pair_force: Vec<Vector3<S>>,
    /// Translation of each pair's rigid target (zero for a deformable target): prescribed, or
    /// the unknowns of a target pushed by a force.
    pub translation: Vec<Vector3<S>>,
    /// Contact force per hitting node (real parts), for output.
    pub force: Vec<Vector3<f64>>,
    /// Tangential (friction) force per hitting node, in the evaluation's scalar (its
    /// direction is the slip direction).
    pub traction: Vec<Vector3<S>>,
    /// `(normal_distance, slip_ratio)` per hitting node.
    pub distance: Vec<(f64, f64)>,
    /// Gap per hitting node (real part; negative = penetration).
    pub gap: Vec<f64>,
    /// The size of the forces that cancel in each hitting node's friction force (the
    /// tangential penalty times the positions whose difference is its elastic slip; zero
    /// without friction, or open): machine precision times it is that force's round-off.
    pub cancelling: Vec<f64>,
}

impl<S: Scalar> ContactEval<S> {
    /// The nominal and current contact pressures of `pair`'s hitting nodes, whose results
    /// start at `first` ([`ContactPair::nodal_pressures`]); `None` when these results do not
    /// hold all of them.
    pub fn pressures(&self, pair: &ContactPair, first: usize) -> Option<(Vec<S>, Vec<S>)> {
        let range = first..first + pair.hitting.len();
        if range.end > self.normal_force.len() {
            return None;
        }
        let f = &self.normal_force[range.clone()];
        Some((
            pair.nodal_pressures(f, &self.area[range.clone()]),
            pair.nodal_pressures(f, &self.current_area[range]),
        ))
    }

    /// Empty results for `n_hitting` hitting nodes over `n_pairs` pairs: every node open,
    /// no force, distances and gaps infinite.
    pub fn new(n_hitting: usize, n_pairs: usize) -> Self {
        ContactEval {
            choice: vec![ContactChoice::default(); n_hitting],
            normal_force: vec![S::zero(); n_hitting],
            area: vec![S::one(); n_hitting],
            current_area: vec![S::one(); n_hitting],
            pair_force: vec![Vector3::zeros(); n_pairs],
            translation: vec![Vector3::zeros(); n_pairs],
            force: vec![Vector3::zeros(); n_hitting],
            traction: vec![Vector3::zeros(); n_hitting],
            distance: vec![(f64::INFINITY, f64::INFINITY); n_hitting],
            gap: vec![f64::INFINITY; n_hitting],
            cancelling: vec![0.0; n_hitting],
        }
    }
}
