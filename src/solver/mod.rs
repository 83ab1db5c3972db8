//! Newton-Raphson with load increments, automatic cutback, and a hook for the sensitivity
//! engine after every converged increment.
//!
//! ## One increment
//! 1. Prescribed unknowns are set to their values at the target time; free unknowns start from
//!    the last converged state.
//! 2. Iterate: assemble `R(z)` and `K = dR/dz`; the increment has converged when
//!    `|R_free| <= force_tol * F_ref` (force criterion, `F_ref` = the larger of the external
//!    load and the reaction norms) or `|dz_{k-1} . R_{k-1}| <= energy_tol * |dz_0 . R_0|`
//!    (energy criterion), or when the last correction is at round-off,
//!    `|dz_{k-1}| <= 64 eps |z|`, or its positions part at the positions' round-off,
//!    `|dz_{k-1, nodal}| <= 64 eps |X + u|` with the other unknowns' part below
//!    `sqrt(eps)` of them (the residual left is the noise of its own evaluation, e.g. of a
//!    stiff penalty or of gaps computed from coordinates, which does not shrink with the
//!    load). Otherwise `K` (with identity rows and columns at the prescribed unknowns) is
//!    factored on the symbolic analysis done once per run, and `z -= K^-1 R`.
//! 3. On convergence the history is committed and the [`Observer`] is called with the
//!    converged state and the *last* factorization (that of the iterate before convergence —
//!    the tangent the paper's semi-analytical method reuses).
//!
//! In a model with contact, a Newton step whose end state cannot be evaluated (an inverted
//! element, a degenerate target segment) is first halved, down to about 1/32 of its length.
//! An increment whose Newton iterations diverge (residual growth, iteration limit, a non-finite
//! value) or in which an element inverts is halved and retried from the last converged state,
//! up to `max_cutbacks` times; then the analysis stops with [`AnalysisError::Diverged`], which
//! carries the results computed so far.

use crate::assembly::{Assembler, AssemblyFailure, Evaluation};
use crate::linalg::{LinalgError, LinearSolver, SparseMatrix};
use crate::material::Branch;
use crate::model::{Lifted, Model};

mod active_set;
mod attempt;
mod increment;
mod limits;
mod newton;
mod setup;

pub use crate::precheck::{PrecheckError, PrecheckWarning};
use active_set::*;
pub use increment::{Resume, Span};
use limits::*;
use newton::*;
pub use setup::Solver;

/// Newton record of one converged increment.
#[derive(Clone, Debug, serde::Serialize)]
pub struct IncrementRecord {
    /// Increment number (counting converged sub-increments after cutbacks).
    pub index: usize,
    /// Pseudo-time at the end of the increment.
    pub time: f64,
    /// Newton iterations (linear solves) used by the converged attempt, the solves that
    /// settled its first step's contact states ([`IncrementRecord::active_set_solves`])
    /// included.
    pub iterations: usize,
    /// `|R_free|` at each residual evaluation of the converged attempt (every Newton
    /// iteration, and the line search's re-evaluations; a step the penetration limiter
    /// shortens is evaluated once, shortened).
    pub residuals: Vec<f64>,
    /// `|dz . R|` at each iteration.
    pub energies: Vec<f64>,
    /// Each Newton correction's Euclidean norm over all unknowns, before any line search
    /// (of the last augmented-Lagrangian pass, if any): the last is about the step between
    /// the iterate of Newton's last factorization and the converged state, which a
    /// sensitivity solved with that factorization is off by.
    pub corrections: Vec<f64>,
    /// Reference force of the force criterion.
    pub reference_force: f64,
    /// Cutbacks taken before this increment converged.
    pub cutbacks: usize,
    /// Augmented-Lagrangian passes after the first (0 without such pairs).
    pub augmentations: usize,
    /// Solves that settled the contact states of the converged attempt's first step on the
    /// linearised problem ([`crate::model::SolverSettings::active_set_solves`]); part of
    /// [`IncrementRecord::iterations`].
    pub active_set_solves: usize,
}

/// A converged increment: what the sensitivity engine and the output writers see.
pub struct Converged<'a> {
    /// The model being solved.
    pub model: &'a Model,
    /// Its unknown numbering and sparsity pattern.
    pub assembler: &'a Assembler,
    /// The nominal design lifted to `f64` (reference coordinates, parameters).
    pub lifted: &'a Lifted<f64>,
    /// Increment number (counting converged sub-increments after cutbacks).
    pub index: usize,
    /// Pseudo-time at the end of the increment.
    pub time: f64,
    /// Time at the start of the increment.
    pub time_prev: f64,
    /// Converged unknowns.
    pub z: &'a [f64],
    /// History committed at the end of the previous increment (`h_{n-1}`).
    pub hist_prev: &'a [f64],
    /// The evaluation at the converged state (residual = reactions at prescribed unknowns,
    /// `hist_new` = `h_n`, branches, stresses).
    pub eval: &'a Evaluation<f64>,
    /// Prescribed unknowns (identity rows in the factored tangent).
    pub constrained: &'a [bool],
    /// The last factorization of this increment, if Newton factored at all.
    pub last_factor: Option<&'a LinearSolver>,
    /// The tangent assembled at the converged state (before the identity rows of the
    /// prescribed unknowns are applied).
    pub tangent: &'a SparseMatrix,
    /// Whether `last_factor` was assembled with the converged state's contact choices and
    /// Gauss-point branches. Newton's last correction can still change a stick/slip or
    /// open/closed state; the last factorization is then the tangent of another branch, and a
    /// sensitivity solved with it can be off by the whole difference between the branches (the
    /// engine refactors then). Even on the same branches it is the tangent of the previous
    /// iterate, off by Newton's last correction: 3.5e-6 relative on the leaf spring's second
    /// increment, which is why the validation harness uses `TangentChoice::Exact`.
    pub factor_matches: bool,
    /// Newton's record of the increment.
    pub record: &'a IncrementRecord,
}

/// Called after every converged increment.
pub trait Observer {
    /// Look at the converged increment `c` (the solver goes on to the next one). An error
    /// stops the analysis.
    fn converged(&mut self, c: &Converged<'_>) -> Result<(), AnalysisError>;
}

/// An observer that does nothing.
pub struct NoObserver;
impl Observer for NoObserver {
    fn converged(&mut self, _c: &Converged<'_>) -> Result<(), AnalysisError> {
        Ok(())
    }
}

/// What a primal analysis returns.
#[derive(Clone, Default)]
pub struct Results {
    /// Time of each converged increment (index 0 is the initial state).
    pub times: Vec<f64>,
    /// Converged unknowns per increment (index 0: the initial state).
    pub states: Vec<Vec<f64>>,
    /// Residual per increment (reactions at prescribed unknowns).
    pub residuals: Vec<Vec<f64>>,
    /// Committed history per increment (empty vectors for models without history).
    pub histories: Vec<Vec<f64>>,
    /// Volume-averaged Cauchy stress per element, per increment.
    pub stresses: Vec<Vec<nalgebra::Matrix3<f64>>>,
    /// Gauss-point branches per increment.
    pub branches: Vec<Vec<Branch>>,
    /// Newton records of the converged increments.
    pub records: Vec<IncrementRecord>,
    /// Contact results per increment (index 0: empty).
    pub contact: Vec<crate::contact::eval::ContactEval<f64>>,
    /// First flat hitting-node index of each contact pair.
    pub contact_flat: Vec<usize>,
    /// Committed history after the last converged increment.
    pub history: Vec<f64>,
    /// Cost counters.
    pub cost: PrimalCost,
}

/// Work done by a primal run.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct PrimalCost {
    /// Wall time of the whole run (observers included), seconds.
    pub wall_seconds: f64,
    /// Residual and tangent assemblies.
    pub assemblies: usize,
    /// Numeric LU factorizations.
    pub factorizations: usize,
    /// Linear solves.
    pub solves: usize,
    /// Wall time spent assembling, seconds.
    pub assembly_seconds: f64,
    /// Wall time spent factoring, seconds.
    pub factor_seconds: f64,
    /// Wall time spent in triangular solves, seconds.
    pub solve_seconds: f64,
    /// Newton steps the penetration limiter shortened (failed attempts included): each
    /// stops just past where the first hitting node the step carries from a gap to a
    /// deeper penetration touches, and the next iteration goes on from there.
    #[serde(default)]
    pub limited_steps: usize,
}

impl PrimalCost {
    /// Of `total` seconds of a run, those outside assembly, factorization and solves.
    pub fn rest_seconds(&self, total: f64) -> f64 {
        total - self.work_seconds()
    }

    /// The seconds in assembly, factorization and solves.
    pub fn work_seconds(&self) -> f64 {
        self.assembly_seconds + self.factor_seconds + self.solve_seconds
    }

    /// The price of one Newton iteration of this run: one assembly, one factorization and
    /// one solve, each at its mean over the run. The assembly's mean is the assembly time
    /// over the assemblies counted, and that time also holds what is not counted as one
    /// (the penetration limiter's contact-only gap evaluations, the incompatible modes'
    /// relaxation, evaluations that failed): an upper estimate.
    pub fn iteration_seconds(&self) -> f64 {
        let mean = |seconds: f64, n: usize| if n == 0 { 0.0 } else { seconds / n as f64 };
        mean(self.assembly_seconds, self.assemblies)
            + mean(self.factor_seconds, self.factorizations)
            + mean(self.solve_seconds, self.solves)
    }
}

/// A model that cannot be solved as given.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// A prescribed displacement on a node the model does not have.
    #[error("prescribed '{prescribed}': node {node} does not exist")]
    NoNode {
        /// The prescribed displacement's name.
        prescribed: String,
        /// The node.
        node: usize,
    },
    /// A component prescribed twice.
    #[error("prescribed '{prescribed}': node {node} component {component} is prescribed twice")]
    PrescribedTwice {
        /// The second prescribed displacement's name.
        prescribed: String,
        /// The node.
        node: usize,
        /// The component (0, 1, 2 for x, y, z).
        component: usize,
    },
    /// A nodal load on a node no element, spring or contact pair holds: its force would go
    /// straight to a reaction, the node never moving.
    #[error("load '{load}': node {node} is held by no element, spring or contact pair: its force would go to a reaction and the node would not move")]
    LoadOnNothing {
        /// The load's name.
        load: String,
        /// The node.
        node: usize,
    },
    /// A body whose element shape does not take its formulation (a model made in code; a
    /// scene file's is refused when it is built).
    #[error("body '{body}': {source}")]
    Formulation {
        /// The body's name.
        body: String,
        /// What is wrong.
        source: crate::element::FormulationError,
    },
}

/// Why an analysis stopped.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AnalysisError {
    /// Newton did not converge within the allowed cutbacks (or the attempt budget).
    #[error("increment {increment} (t = {time:.6}): Newton failed ({cutbacks} failed attempts in this increment, the last with step {step:.3e}): {reason}; residual history of the last attempt: {residuals:?}")]
    Diverged {
        /// The increment that failed (counting converged sub-increments).
        increment: usize,
        /// Pseudo-time the failed attempt aimed at.
        time: f64,
        /// Pseudo-time step of the last attempt.
        step: f64,
        /// Failed attempts within the user's increment, the last one included.
        cutbacks: usize,
        /// `|R_free|` at each iteration of the last attempt.
        residuals: Vec<f64>,
        /// Why the last attempt failed.
        reason: String,
        /// Everything computed up to the last converged increment.
        partial: Box<Results>,
    },
    /// Assembly failed where no cutback applies: a degenerate reference mesh, or an evaluation
    /// outside Newton's loop (e.g. a perturbed design in the sensitivity engine).
    #[error("mesh: {0}")]
    Mesh(#[from] AssemblyFailure),
    /// The sparse linear algebra failed (e.g. a singular tangent).
    #[error("linear algebra: {0}")]
    Linalg(#[from] LinalgError),
    /// The model is inconsistent (e.g. a prescribed unknown that does not exist).
    #[error("model: {0}")]
    Model(#[from] ModelError),
    /// The contact kernel failed outside Newton's loop (the initial history: a hitting node
    /// whose reference position does not project onto its target).
    #[error("{0}")]
    Contact(#[from] crate::contact::assembly::ContactError),
    /// A design parameter does not resolve on the model.
    #[error("sensitivity: {0}")]
    Parameter(#[from] crate::design::ParameterError),
    /// A sensitivity computation failed ([`crate::sensitivity::SensitivityError`], boxed so
    /// that the solver, below the sensitivity engine, need not know its type; `downcast_ref`
    /// recovers it).
    #[error("sensitivity: {0}")]
    Sensitivity(Box<dyn std::error::Error + Send + Sync>),
    /// A pre-check refused the model before the first increment ([`PrecheckError`]).
    #[error("{0}")]
    Precheck(#[from] crate::precheck::PrecheckError),
    /// The run took longer than [`RunOptions::time_limit`].
    #[error("increment {increment} (t = {time:.6}): stopped at the time limit of {seconds} s")]
    TimeLimit {
        /// The increment being solved (counting converged sub-increments).
        increment: usize,
        /// Pseudo-time the attempt aimed at.
        time: f64,
        /// The limit, seconds.
        seconds: f64,
        /// Everything computed up to the last converged increment.
        partial: Box<Results>,
    },
}

impl std::fmt::Debug for Results {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Results {{ {} increments, last t = {:?}, cost: {:?} }}",
            self.records.len(),
            self.times.last(),
            self.cost
        )
    }
}

impl Results {
    /// Value of response `r` at stored increment `k` (needs `keep_states`).
    pub fn response_value(&self, model: &Model, r: usize, k: usize) -> f64 {
        let input = crate::response::ResponseInput {
            z: &self.states[k],
            residual: &self.residuals[k],
            hist: &self.histories[k],
            contact: self.contact.get(k),
            flat: Some(&self.contact_flat),
            stress: self.stresses.get(k).map_or(&[], |s| s.as_slice()),
            stress_elements: None,
        };
        model.responses[r].value(&input)
    }

    /// Stored increment whose time is `t`, if any.
    pub fn increment_at(&self, t: f64) -> Option<usize> {
        self.times
            .iter()
            .position(|x| (x - t).abs() <= 1e-12 * t.abs().max(1.0))
    }
}

impl AnalysisError {
    /// Results computed before the failure, where the error keeps them.
    pub fn partial(&self) -> Option<&Results> {
        match self {
            AnalysisError::Diverged { partial, .. } | AnalysisError::TimeLimit { partial, .. } => {
                Some(partial)
            }
            _ => None,
        }
    }
}

/// Options of a run.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Keep the full state vector of every increment in the results.
    pub keep_states: bool,
    /// Stop with [`AnalysisError::TimeLimit`] (keeping the results so far) once the run has
    /// taken this many seconds of wall time, checked at every Newton iteration (none: no
    /// limit).
    pub time_limit: Option<f64>,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            keep_states: true,
            time_limit: None,
        }
    }
}

impl RunOptions {
    /// The default options with a time limit (`None`: none).
    pub fn limited(time_limit: Option<f64>) -> Self {
        RunOptions {
            time_limit,
            ..RunOptions::default()
        }
    }

    /// When a run started at `start` must stop: none without a limit or with one too large
    /// for a `Duration` (infinite), at once with a negative or NaN one.
    pub(crate) fn deadline(&self, start: std::time::Instant) -> Option<std::time::Instant> {
        start.checked_add(saturating_duration(self.time_limit?))
    }
}

/// `seconds` as a `Duration`: zero for a negative or NaN number, `Duration::MAX` for one no
/// `Duration` holds (infinite), where `Duration::from_secs_f64` would panic.
pub(crate) fn saturating_duration(seconds: f64) -> std::time::Duration {
    let s = if seconds.is_nan() {
        0.0
    } else {
        seconds.max(0.0)
    };
    std::time::Duration::try_from_secs_f64(s).unwrap_or(std::time::Duration::MAX)
}

#[cfg(test)]
mod tests {
    use super::RunOptions;
    use std::time::{Duration, Instant};

    /// A time limit gives a deadline that far from the start; one no `Duration` holds
    /// (infinite) gives none, and a negative or NaN one the start itself (the run stops at
    /// its first Newton iteration) rather than a panic.
    #[test]
    fn a_time_limit_of_any_value_gives_a_deadline_or_none() {
        let start = Instant::now();
        let at = |limit: Option<f64>| RunOptions::limited(limit).deadline(start);
        assert_eq!(at(None), None);
        assert_eq!(at(Some(1.5)), Some(start + Duration::from_millis(1500)));
        assert_eq!(at(Some(f64::INFINITY)), None);
        assert_eq!(at(Some(1e300)), None);
        assert_eq!(at(Some(-1.0)), Some(start));
        assert_eq!(at(Some(f64::NAN)), Some(start));
    }
}
