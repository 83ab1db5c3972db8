//! The primal solver of one model: the unknowns it solves for (prescribed and untouched ones
//! pinned), the pre-checks, and what it carries from one increment to the next.

use super::*;
use crate::assembly::{Assembler, Evaluation};
use crate::contact::{ContactChoice, ContactState};
use crate::linalg::{LinearSolver, SparseMatrix};
use crate::model::{node_dof, Lifted, Model};
use std::time::Instant;

/// The primal solver of one model.
pub struct Solver<'m> {
    /// The model it solves.
    pub model: &'m Model,
    /// Unknown numbering and the fixed sparsity pattern.
    pub assembler: Assembler,
    /// The nominal design lifted to `f64`.
    pub lifted: Lifted<f64>,
    pub(super) linear: LinearSolver,
    pub(super) matrix: SparseMatrix,
    pub(super) constrained: Vec<bool>,
    /// Contact states of the last converged increment (the first iteration's active set).
    pub(super) converged_choice: Vec<ContactChoice>,
    /// Print every iteration and failed attempt to stderr (`FRICSENS_TRACE` set).
    pub(super) trace: bool,
    /// Smallest penetration the step limiter acts on: [`PENETRATION_LIMIT_SCALE`] times the
    /// diagonal of the reference bounding box.
    pub(super) penetration_floor: f64,
    /// Contact choices and Gauss-point branches of the state the last factorization was
    /// assembled at (see [`Converged::factor_matches`]).
    pub(super) factored_choice: Vec<ContactChoice>,
    pub(super) factored_branches: Vec<crate::material::Branch>,
    /// When the run must stop ([`RunOptions::time_limit`]).
    pub(super) deadline: Option<Instant>,
    /// What the pre-checks found that does not stop the run.
    pub(super) warnings: Vec<crate::precheck::PrecheckWarning>,
    /// Sum and count of the reference forces of the converged increments.
    pub(super) force_history: (f64, usize),
    /// The force of a strain of 1e-6 over the smallest element face of the stiffest body: the
    /// reference force of the energy and round-off criteria before any force has been seen.
    pub(super) force_floor: f64,
    /// Norm of each pressure load's nodal forces at unit pressure on the reference faces
    /// (the forces are linear in the pressure: the force criterion scales them).
    pub(super) unit_pressure_norms: Vec<f64>,
    /// The penetration limiter's evaluation of the gaps alone ([`Solver::gaps`]), made at
    /// its first use, and its mask leaving out every element.
    pub(super) gap_eval: Option<Box<Evaluation<f64>>>,
    pub(super) no_elements: Vec<bool>,
    /// The elements with incompatible modes.
    pub(super) modes_elements: Vec<usize>,
    /// Those of them with a history (a path-dependent material), whose modes are relaxed
    /// after a failed attempt ([`super::limits::MODE_RELAXATION_STEPS`]).
    pub(super) relaxed_elements: Vec<usize>,
    /// Whether the attempts of this nominal increment condense the incompatible modes by
    /// local Newton before each evaluation: once one of its attempts has failed
    /// ([`super::limits::MODE_RELAXATION_STEPS`]).
    pub(super) relaxing_modes: bool,
    /// Per flat hitting node, the elements at it that carry history: the active-set
    /// predictor's test for a yielded body ([`super::active_set::ActiveSetPredictor::next`]).
    pub(super) history_at_hitting: Vec<Vec<usize>>,
}

impl<'m> Solver<'m> {
    /// Number the unknowns, build the pattern and its symbolic factorization.
    pub fn new(model: &'m Model) -> Result<Self, AnalysisError> {
        model
            .check_families()
            .map_err(|(body, source)| ModelError::Formulation { body, source })?;
        let assembler = Assembler::new(model, &[])?;
        let constrained = constrained_unknowns(model, &assembler)?;
        let lifted = model.lifted::<f64>(&[]);
        let warnings = prechecks(model, &assembler, &lifted, &constrained)?;
        let e_max = model
            .bodies
            .iter()
            .map(|b| b.material.young())
            .fold(0.0f64, f64::max);
        let h = model.mesh.smallest_edge(&lifted.coords);
        let force_floor = if h.is_finite() {
            1e-6 * e_max * h * h
        } else {
            0.0
        };
        let matrix = SparseMatrix::new(assembler.pattern.clone());
        // the prescribed unknowns' rows and columns are the identity's in every tangent
        // Newton factors ([`Solver::factor_and_solve`]): left out of the factorizations
        let linear = LinearSolver::with_fixed(
            assembler.pattern.clone(),
            crate::linalg::SolverOptions::default(),
            &constrained,
        )?;
        let penetration_floor = PENETRATION_LIMIT_SCALE * bounding_diagonal(&lifted.coords);
        let unit_pressure_norms = (model.pressures.iter())
            .map(|p| p.force_norm(&lifted.coords, 1.0, assembler.dofs.n_total))
            .collect();
        let modes_elements: Vec<usize> = (0..model.mesh.n_elements())
            .filter(|&e| assembler.mode_dofs(e).is_some())
            .collect();
        let relaxed_elements = (modes_elements.iter().copied())
            .filter(|&e| !assembler.dofs.history(e).is_empty())
            .collect();
        let history_at_hitting =
            super::active_set::history_elements_at_hitting_nodes(model, &assembler);
        Ok(Solver {
            model,
            assembler,
            lifted,
            unit_pressure_norms,
            linear,
            matrix,
            constrained,
            converged_choice: Vec::new(),
            factored_choice: Vec::new(),
            factored_branches: Vec::new(),
            trace: std::env::var_os("FRICSENS_TRACE").is_some(),
            penetration_floor,
            deadline: None,
            warnings,
            force_history: (0.0, 0),
            force_floor,
            gap_eval: None,
            no_elements: Vec::new(),
            modes_elements,
            relaxed_elements,
            relaxing_modes: false,
            history_at_hitting,
        })
    }

    /// What the pre-checks found that does not stop the run ([`super::PrecheckWarning`]).
    pub fn warnings(&self) -> &[crate::precheck::PrecheckWarning] {
        &self.warnings
    }

    /// A linear solver on this solver's pattern sharing its symbolic analysis
    /// ([`LinearSolver::sibling`]).
    pub fn linear_sibling(&self) -> LinearSolver {
        self.linear.sibling()
    }

    /// Prescribed unknowns.
    pub fn constrained(&self) -> &[bool] {
        &self.constrained
    }

    pub(super) fn set_prescribed(&self, z: &mut [f64], t: f64) {
        for (i, p) in self.model.prescribed.iter().enumerate() {
            let v = self.lifted.prescribed[i] * p.amplitude.at(t);
            for &node in &p.nodes {
                z[node_dof(node, p.component)] = v;
            }
        }
    }

    /// Keep the open/closed states (and contact faces) of a converged state for the next
    /// increment's first iteration; stick and slip stay free (a slip branch imposed across a
    /// load reversal sends Newton into a cycle).
    pub(super) fn keep_contact_states(&mut self, choice: &[ContactChoice]) {
        self.converged_choice.clear();
        self.converged_choice.extend(choice.iter().map(|c| {
            let mut c = *c;
            if c.state != ContactState::Open {
                c.state = ContactState::Closed;
            }
            c
        }));
    }
}

/// The unknowns Newton does not solve for: the prescribed ones, and those no element (springs
/// included) or contact pair touches.
fn constrained_unknowns(model: &Model, assembler: &Assembler) -> Result<Vec<bool>, ModelError> {
    let n = assembler.dofs.n_total;
    let mut constrained = vec![false; n];
    for p in &model.prescribed {
        for &node in &p.nodes {
            let d = node_dof(node, p.component);
            if d >= assembler.dofs.n_nodal {
                return Err(ModelError::NoNode {
                    prescribed: p.name.clone(),
                    node,
                });
            }
            if constrained[d] {
                return Err(ModelError::PrescribedTwice {
                    prescribed: p.name.clone(),
                    node,
                    component: p.component,
                });
            }
            constrained[d] = true;
        }
    }
    // unknowns no element (springs included) touches (e.g. nodes of unassembled blocks)
    // are pinned
    let mut touched = vec![false; n];
    for e in 0..model.mesh.n_elements() {
        for &d in assembler.element_dofs(e) {
            touched[d] = true;
        }
    }
    for pair_blocks in &assembler.contact.blocks {
        for b in pair_blocks {
            for &d in &b.dofs {
                touched[d] = true;
            }
        }
    }
    for load in &model.loads {
        for (&node, &w) in load.nodes.iter().zip(&load.weights) {
            let d = node_dof(node, load.component);
            if w != 0.0 && d < assembler.dofs.n_nodal && !touched[d] {
                return Err(ModelError::LoadOnNothing {
                    load: load.name.clone(),
                    node,
                });
            }
        }
    }
    for (d, t) in touched.iter().enumerate() {
        if !t {
            constrained[d] = true;
        }
    }
    Ok(constrained)
}

/// The pre-checks ([`crate::precheck`]): rigid-body modes, pairs that cannot touch, overlap.
/// Returns what does not stop the run.
fn prechecks(
    model: &Model,
    assembler: &Assembler,
    lifted: &Lifted<f64>,
    constrained: &[bool],
) -> Result<Vec<crate::precheck::PrecheckWarning>, AnalysisError> {
    let (mut warnings, free) = crate::precheck::rigid_body_modes(model, lifted, constrained);
    free?;
    warnings.extend(crate::precheck::never_touching(model, lifted));
    warnings.extend(crate::precheck::coarse_hitting(model, lifted));
    if !model.contacts.is_empty() {
        let mut eval = Evaluation::<f64>::new(assembler, model.mesh.n_elements());
        let z = vec![0.0; assembler.dofs.n_total];
        let hist = crate::contact::assembly::initial_history(
            model,
            &assembler.contact,
            assembler.dofs.n_history,
            lifted,
        )?;
        if assembler
            .evaluate(model, lifted, &z, &hist, 0.0, None, None, &mut eval)
            .is_ok()
        {
            crate::precheck::overlap(model, assembler, &eval)?;
        }
    }
    Ok(warnings)
}
