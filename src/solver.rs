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
//! An increment whose Newton iterations diverge (residual growth, iteration limit, a non-finite
//! value) or in which an element inverts is halved and retried from the last converged state,
//! up to `max_cutbacks` times; then the analysis stops with [`AnalysisError::Diverged`], which
//! carries the results computed so far.

use crate::assembly::{Assembler, AssemblyFailure, Evaluation, Frozen};
use crate::contact::{ContactChoice, ContactState};
use crate::element::hex8::ElementFailure;
use crate::linalg::{LinalgError, LinearSolver, SparseMatrix};
use crate::material::Branch;
use crate::model::{Lifted, Model};
use std::time::Instant;

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
    /// iteration, and the line search's and penetration limiter's re-evaluations).
    pub residuals: Vec<f64>,
    /// `|dz . R|` at each iteration.
    pub energies: Vec<f64>,
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
    pub contact: Vec<crate::contact::assembly::ContactEval<f64>>,
    /// First flat hitting-node index of each contact pair.
    pub contact_flat: Vec<usize>,
    /// Committed history after the last converged increment.
    pub history: Vec<f64>,
    /// Cost counters.
    pub cost: PrimalCost,
}

/// Work done by a primal run.
#[derive(Clone, Debug, Default, serde::Serialize)]
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
}

impl PrimalCost {
    /// Of `total` seconds of a run, those outside assembly, factorization and solves.
    pub fn rest_seconds(&self, total: f64) -> f64 {
        total - self.assembly_seconds - self.factor_seconds - self.solve_seconds
    }
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
    Model(String),
    /// A sensitivity computation failed (e.g. an unknown parameter name).
    #[error("sensitivity: {0}")]
    Sensitivity(String),
    /// A pre-check refused the model before the first increment ([`crate::precheck`]).
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

/// Augmented-Lagrangian passes allowed per increment.
const MAX_AUGMENTATIONS: usize = 50;

/// Residual growth over one Newton step that triggers backtracking (contact models).
const LINE_SEARCH_GROWTH: f64 = 4.0;

/// A Newton correction below this many ulps of what it corrects is round-off (the
/// round-off convergence criterion).
const CORRECTION_ROUND_OFF: f64 = 64.0;

/// The step limiter acts on penetrations deeper than this fraction of the model's size (the
/// diagonal of its reference bounding box): well above round-off, far below any clearance a
/// scene resolves (leaf spring: 1e-4 mm against a 0.02 mm clearance).
const PENETRATION_LIMIT_SCALE: f64 = 1e-6;

/// Diagonal of the bounding box of some points.
fn bounding_diagonal(points: &[nalgebra::Vector3<f64>]) -> f64 {
    let Some(first) = points.first() else {
        return 0.0;
    };
    let (lo, hi) = points
        .iter()
        .fold((*first, *first), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
    (hi - lo).norm()
}

/// Shortest fraction of a Newton step the yield-surface crossing limiter keeps. Without a
/// floor, points that cross near the start of the step cut it to 1e-7 and Newton stalls (the
/// leaf spring refined 4 times ran out of time).
const YIELD_CROSSING_FLOOR: f64 = 0.125;

/// A Newton iteration whose residual is above this fraction of the last one's stalls: the
/// slip-reversal remedy acts only then.
const STALL_RATIO: f64 = 0.5;

/// Failed attempts allowed within one of the user's increments, per `max_cutbacks`.
const FAILED_ATTEMPTS_PER_STEP: usize = 2;

/// Factor of the step after an increment harder than `SolverSettings::shrink_after` (CalculiX's
/// D_B), down to [`HARD_FLOOR`] of the user's increment.
const HARD_SHRINK: f64 = 0.75;
/// See [`HARD_SHRINK`].
const HARD_FLOOR: f64 = 0.25;

/// The energy and round-off convergence criteria accept a residual at most this many times
/// the force tolerance (the leaf spring's round-off floor, the reason for the round-off
/// criterion, is 11 times it on the finest mesh; the physics fuzzer found an increment
/// accepted with a tenth of its forces out of balance).
const NEAR_TOLERANCE: f64 = 1e4;

/// Free evaluations over which a cycle is looked for ([`Solver`]'s attempt): the same contact
/// decisions twice among them, after at least twice as many iterations, with no residual
/// below half the best before them, end the attempt.
const CYCLE_WINDOW: usize = 6;

/// Times a hitting node may be forced onto the stick branch per attempt when its slip
/// direction reverses between two Newton iterates ([`Solver`]'s attempt).
const SLIP_REVERSALS: usize = 3;

/// Of the nodes a step would close, the first active-set prediction takes those whose
/// predicted penetration is at least this fraction of their pair's deepest.
const ACTIVE_SET_ADD_FRACTION: f64 = 0.9;

/// The contact states the first step of an attempt leads to ([`Solver::settle_active_set`]).
struct ActiveSetPredictor {
    /// The trial state `z + dz`.
    z: Vec<f64>,
    /// Contact-only evaluation at the trial state.
    trial: Evaluation<f64>,
    /// The states to impose next: open or closed, friction left free.
    choice: Vec<ContactChoice>,
    /// First flat hitting-node index of each pair, and the end.
    pair_start: Vec<usize>,
}

/// A first step the active-set predictor solved with: how many states its prediction
/// changed, the step, the states it was solved with and the residual, and whether it is
/// Newton's own.
struct SettledStep {
    changes: usize,
    dz: Vec<f64>,
    choice: Vec<ContactChoice>,
    residual: Vec<f64>,
    newtons: bool,
}

impl ActiveSetPredictor {
    fn new(asm: &Assembler) -> Self {
        let mut pair_start = asm.contact.flat.clone();
        pair_start.push(asm.contact.n_hitting);
        ActiveSetPredictor {
            z: vec![0.0; asm.dofs.n_total],
            trial: Evaluation::new(asm, 0),
            choice: Vec::new(),
            pair_start,
        }
    }

    /// Decide the states at the trial state `self.z` against those `current.contact.choice`
    /// the step was solved with. `None` when they agree (or the trial state's contact
    /// geometry fails: Newton's own step then meets it). Otherwise the states to solve with
    /// next in `self.choice`, what changed (for the trace) and how many states the trial
    /// state changes (releases and closings predicted, taken or not).
    ///
    /// Releases come first: when any closed node's multiplier would turn negative, all such
    /// nodes open and no node closes. Otherwise, of the nodes the step would close, those
    /// whose penetration is at least [`ACTIVE_SET_ADD_FRACTION`] of their pair's deepest
    /// close. Taking every predicted change at once cycles on nearly conforming surfaces:
    /// the leaves' whole interface closes, the glued leaves' multipliers alternate in sign,
    /// the released nodes penetrate again (the leaf spring's first step did not settle in
    /// 8 solves; on the mesh refined 3 times, 50 factorizations for the first increment
    /// against 15 this way).
    fn next(
        &mut self,
        model: &Model,
        asm: &Assembler,
        lifted: &Lifted<f64>,
        (hist, t): (&[f64], f64),
        current: &Evaluation<f64>,
        keep_faces: &[ContactChoice],
    ) -> Option<(String, usize)> {
        let trial = &mut self.trial;
        trial.residual.iter_mut().for_each(|r| *r = 0.0);
        let mut tangents = Vec::new();
        crate::contact::assembly::evaluate(
            model,
            &asm.contact,
            lifted,
            &self.z,
            hist,
            t,
            None,
            Some(keep_faces),
            None,
            false,
            &mut trial.residual,
            &mut trial.hist_new,
            &mut trial.contact,
            &mut tangents,
        )
        .ok()?;
        let open = |c: &ContactChoice| c.state == ContactState::Open;
        let now = &current.contact.choice;
        let then = &trial.contact.choice;
        let releases = then
            .iter()
            .zip(now)
            .filter(|(a, b)| open(a) && !open(b))
            .count();
        let closing = then
            .iter()
            .zip(now)
            .filter(|(a, b)| !open(a) && open(b))
            .count();
        if releases + closing == 0 {
            return None;
        }
        self.choice.clear();
        self.choice.extend(now.iter().map(|c| ContactChoice {
            state: if open(c) {
                ContactState::Open
            } else {
                ContactState::Closed
            },
            ..*c
        }));
        let mut taken = 0;
        // the first few changes taken, for the trace
        let mut taken_list: Vec<String> = Vec::new();
        for w in self.pair_start.windows(2) {
            let range = w[0]..w[1];
            let deepest = range
                .clone()
                .filter(|&i| !open(&then[i]) && open(&now[i]))
                .map(|i| trial.contact.gap[i])
                .fold(0.0f64, f64::min);
            for i in range {
                let release = open(&then[i]) && !open(&now[i]);
                let close = releases == 0
                    && !open(&then[i])
                    && open(&now[i])
                    && trial.contact.gap[i] <= ACTIVE_SET_ADD_FRACTION * deepest;
                if release || close {
                    self.choice[i] = ContactChoice {
                        state: if release {
                            ContactState::Open
                        } else {
                            ContactState::Closed
                        },
                        ..then[i]
                    };
                    taken += 1;
                    if taken_list.len() < 12 {
                        taken_list.push(format!(
                            "{}{i} (g {:.1e})",
                            if release { '-' } else { '+' },
                            trial.contact.gap[i]
                        ));
                    }
                }
            }
        }
        let taken_list = taken_list.join(" ");
        Some((
            if releases > 0 {
                format!("{releases} releases predicted ({closing} closings), taken: {taken_list}")
            } else {
                format!("{closing} closings predicted, {taken} taken: {taken_list}")
            },
            releases + closing,
        ))
    }
}

/// Assemble the residual and the tangent (into `matrix`) at the state `(z, hist_old, t)`,
/// the time and the count going to `cost` when it succeeds. A free function: the callers
/// freeze states they borrow from the solver while its matrix is written.
#[allow(clippy::too_many_arguments)]
fn assemble(
    assembler: &Assembler,
    model: &Model,
    lifted: &Lifted<f64>,
    matrix: &mut SparseMatrix,
    (z, hist_old, t): (&[f64], &[f64], f64),
    frozen: Option<&Frozen>,
    eval: &mut Evaluation<f64>,
    cost: &mut PrimalCost,
) -> Result<(), AssemblyFailure> {
    let t0 = Instant::now();
    assembler.evaluate(model, lifted, z, hist_old, t, frozen, Some(matrix), eval)?;
    cost.assemblies += 1;
    cost.assembly_seconds += t0.elapsed().as_secs_f64();
    Ok(())
}

/// Why an attempt failed (recoverable by cutback, but for the time limit).
#[derive(Debug)]
enum AttemptFailure {
    Element(AssemblyFailure),
    Diverged(&'static str),
    /// Newton cycles: the same contact states come back without progress (the diagnosis).
    Cycle(String),
    /// [`RunOptions::time_limit`] passed: the run stops.
    TimeLimit,
}

impl std::fmt::Display for AttemptFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AttemptFailure::Element(e) => write!(f, "{e}"),
            AttemptFailure::Diverged(s) => write!(f, "{s}"),
            AttemptFailure::Cycle(s) => write!(f, "{s}"),
            AttemptFailure::TimeLimit => write!(f, "time limit"),
        }
    }
}

/// The primal solver of one model.
pub struct Solver<'m> {
    /// The model it solves.
    pub model: &'m Model,
    /// Unknown numbering and the fixed sparsity pattern.
    pub assembler: Assembler,
    /// The nominal design lifted to `f64`.
    pub lifted: Lifted<f64>,
    linear: LinearSolver,
    matrix: SparseMatrix,
    constrained: Vec<bool>,
    /// Contact states of the last converged increment (the first iteration's active set).
    converged_choice: Vec<ContactChoice>,
    /// Print every iteration and failed attempt to stderr (`FRICSENS_TRACE` set).
    trace: bool,
    /// Smallest penetration the step limiter acts on: [`PENETRATION_LIMIT_SCALE`] times the
    /// diagonal of the reference bounding box.
    penetration_floor: f64,
    /// Contact choices and Gauss-point branches of the state the last factorization was
    /// assembled at (see [`Converged::factor_matches`]).
    factored_choice: Vec<ContactChoice>,
    factored_branches: Vec<crate::material::Branch>,
    /// When the run must stop ([`RunOptions::time_limit`]).
    deadline: Option<Instant>,
    /// What the pre-checks found that does not stop the run.
    warnings: Vec<crate::precheck::PrecheckWarning>,
    /// Sum and count of the reference forces of the converged increments.
    force_history: (f64, usize),
    /// The force of a strain of 1e-6 over the smallest element face of the stiffest body: the
    /// reference force of the energy and round-off criteria before any force has been seen.
    force_floor: f64,
}

impl<'m> Solver<'m> {
    /// Number the unknowns, build the pattern and its symbolic factorization.
    pub fn new(model: &'m Model) -> Result<Self, AnalysisError> {
        let assembler = Assembler::new(model, &[])?;
        let n = assembler.dofs.n_total;
        let mut constrained = vec![false; n];
        for p in &model.prescribed {
            for &node in &p.nodes {
                let d = 3 * node + p.component;
                if d >= assembler.dofs.n_nodal {
                    return Err(AnalysisError::Model(format!(
                        "prescribed '{}': node {node} does not exist",
                        p.name
                    )));
                }
                if constrained[d] {
                    return Err(AnalysisError::Model(format!(
                        "prescribed '{}': node {node} component {} is prescribed twice",
                        p.name, p.component
                    )));
                }
                constrained[d] = true;
            }
        }
        // unknowns no element or spring touches (e.g. nodes of unassembled blocks) are pinned
        let mut touched = vec![false; n];
        for e in 0..model.mesh.elements.len() {
            for &d in assembler.element_dofs(e) {
                touched[d] = true;
            }
        }
        for s in &model.springs {
            for i in 0..3 {
                touched[3 * s.a + i] = true;
                if let Some(b) = s.b {
                    touched[3 * b + i] = true;
                }
            }
        }
        for pair_blocks in &assembler.contact.blocks {
            for b in pair_blocks {
                for &d in &b.dofs {
                    touched[d] = true;
                }
            }
        }
        for (d, t) in touched.iter().enumerate() {
            if !t {
                constrained[d] = true;
            }
        }
        let lifted = model.lifted::<f64>(&[]);
        // pre-checks (crate::precheck): rigid-body modes, pairs that cannot touch, overlap
        let (mut warnings, free) = crate::precheck::rigid_body_modes(model, &lifted, &constrained);
        free?;
        warnings.extend(crate::precheck::never_touching(model, &lifted));
        if !model.contacts.is_empty() {
            let mut eval = Evaluation::<f64>::new(&assembler, model.mesh.elements.len());
            let z = vec![0.0; n];
            let hist = crate::contact::assembly::initial_history(model, &assembler, &lifted)
                .map_err(|e| AnalysisError::Model(e.to_string()))?;
            if assembler
                .evaluate(model, &lifted, &z, &hist, 0.0, None, None, &mut eval)
                .is_ok()
            {
                crate::precheck::overlap(model, &assembler, &eval)?;
            }
        }
        let e_max = model
            .bodies
            .iter()
            .map(|b| b.material.params()[0])
            .fold(0.0f64, f64::max);
        let h = model.mesh.smallest_edge(&lifted.coords);
        let force_floor = if h.is_finite() {
            1e-6 * e_max * h * h
        } else {
            0.0
        };
        let matrix = SparseMatrix::new(assembler.pattern.clone());
        let linear = LinearSolver::new(assembler.pattern.clone())?;
        let penetration_floor = PENETRATION_LIMIT_SCALE * bounding_diagonal(&lifted.coords);
        Ok(Solver {
            model,
            assembler,
            lifted,
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
        })
    }

    /// What the pre-checks found that does not stop the run ([`crate::precheck`]).
    pub fn warnings(&self) -> &[crate::precheck::PrecheckWarning] {
        &self.warnings
    }

    /// Prescribed unknowns.
    pub fn constrained(&self) -> &[bool] {
        &self.constrained
    }

    fn set_prescribed(&self, z: &mut [f64], t: f64) {
        for (i, p) in self.model.prescribed.iter().enumerate() {
            let v = self.lifted.prescribed[i] * p.amplitude.at(t);
            for &node in &p.nodes {
                z[3 * node + p.component] = v;
            }
        }
    }

    /// Keep the open/closed states (and contact faces) of a converged state for the next
    /// increment's first iteration; stick and slip stay free (a slip branch imposed across a
    /// load reversal sends Newton into a cycle).
    fn keep_contact_states(&mut self, choice: &[ContactChoice]) {
        self.converged_choice.clear();
        self.converged_choice.extend(choice.iter().map(|c| {
            let mut c = *c;
            if c.state != ContactState::Open {
                c.state = ContactState::Closed;
            }
            c
        }));
    }

    /// Run the whole load history.
    pub fn run(
        &mut self,
        opts: &RunOptions,
        observer: &mut dyn Observer,
    ) -> Result<Results, AnalysisError> {
        let start = Instant::now();
        self.deadline = opts
            .time_limit
            .map(|s| start + std::time::Duration::from_secs_f64(s.max(0.0)));
        self.force_history = (0.0, 0);
        let model = self.model;
        let n = self.assembler.dofs.n_total;
        let ne = model.mesh.elements.len();
        let mut res = Results::default();
        let mut z = vec![0.0; n];
        let mut hist =
            crate::contact::assembly::initial_history(model, &self.assembler, &self.lifted)
                .map_err(|e| AnalysisError::Model(e.to_string()))?;
        let mut eval = Evaluation::<f64>::new(&self.assembler, ne);
        // the contact states of the start state: the first increment's active-set predictor
        self.converged_choice.clear();
        if !model.contacts.is_empty()
            && self
                .assembler
                .evaluate(model, &self.lifted, &z, &hist, 0.0, None, None, &mut eval)
                .is_ok()
        {
            self.keep_contact_states(&eval.contact.choice);
        }
        res.times.push(0.0);
        res.states.push(z.clone());
        res.residuals.push(vec![0.0; n]);
        res.histories.push(hist.clone());
        res.contact_flat = self.assembler.contact.flat.clone();
        res.contact.push(eval.contact.clone());
        res.stresses.push(vec![nalgebra::Matrix3::zeros(); ne]);
        res.branches.push(vec![Branch::Elastic; 8 * ne]);
        let mut t_prev = 0.0;
        // the converged state before `z` and its time: the extrapolating predictor's
        let mut previous: Option<(Vec<f64>, f64)> = None;
        let mut index = 0;
        // the step the last converged increment suggests for the next (halved after a hard
        // one, doubled after an easy one), carried into the next of the user's increments
        let mut suggested = f64::INFINITY;
        for &t_end in &model.times {
            let t_prev_nominal = t_prev;
            let nominal = t_end - t_prev;
            let mut step = nominal.min(suggested);
            // the smallest sub-increment: max_cutbacks halvings of the nominal one (the
            // cutback counter restarts after every converged sub-increment, so without it a
            // run creeping towards a limit point halves its step down to round-off)
            let min_step = nominal / 2f64.powi(model.solver.max_cutbacks as i32);
            let mut cutbacks = 0;
            // every attempt (converged or not) within this nominal increment; a budget keeps a
            // converge-grow-fail cycle from running forever
            let mut attempts = 0usize;
            // failed attempts within this nominal increment (`cutbacks` counts only those since
            // the last converged sub-increment), and the residuals and reason of the last one:
            // the attempt budget's error reports them
            let mut failed = 0usize;
            let mut last_failure: Option<(f64, Vec<f64>, String)> = None;
            while t_prev < t_end - 1e-14 * t_end.abs().max(1.0) {
                let t = (t_prev + step).min(t_end);
                attempts += 1;
                // a budget of failed attempts per increment: halving after halving, and
                // sub-increments that converge only to fail again, end here rather than
                // creeping on at the smallest step (the curved punch spent 11 minutes
                // in 47-iteration attempts before the remedies)
                if failed >= FAILED_ATTEMPTS_PER_STEP * model.solver.max_cutbacks.max(1) {
                    res.history = hist;
                    res.cost.wall_seconds = start.elapsed().as_secs_f64();
                    let (t_failed, residuals, why) = last_failure.take().unwrap_or_default();
                    return Err(AnalysisError::Diverged {
                        increment: index + 1,
                        time: t,
                        step,
                        cutbacks: failed,
                        residuals,
                        reason: format!(
                            "{failed} failed attempts within the increment ending at t = {t_end} ({} sub-increments of it converged); the last failed attempt, to t = {t_failed:.9}: {why}",
                            attempts - 1 - failed
                        ),
                        partial: Box::new(res),
                    });
                }
                let mut z_try = z.clone();
                self.set_prescribed(&mut z_try, t);
                let mut record = IncrementRecord {
                    index: index + 1,
                    time: t,
                    iterations: 0,
                    residuals: Vec::new(),
                    energies: Vec::new(),
                    reference_force: 0.0,
                    cutbacks,
                    augmentations: 0,
                    active_set_solves: 0,
                };
                // Predictor. Where the load path goes straight on from the last converged
                // increment, extrapolate its solution linearly (free, and second-order
                // accurate on a smooth path, like Abaqus' default within a step); otherwise
                // (first increment, a reversal or a kink of any amplitude) linearise about
                // the converged state.
                let extrapolate = match &previous {
                    Some((z_old, t_old))
                        if model.solver.extrapolate
                            && model.load_path_straight(*t_old, t_prev, t) =>
                    {
                        let ratio = (t - t_prev) / (t_prev - t_old);
                        for (d, zt) in z_try.iter_mut().enumerate() {
                            if !self.constrained[d] {
                                *zt = z[d] + ratio * (z[d] - z_old[d]);
                            }
                        }
                        true
                    }
                    _ => false,
                };
                let predicted = if extrapolate {
                    Ok(Some(false))
                } else {
                    self.predict(&z, &mut z_try, &hist, t, &mut eval, &mut res.cost)
                        .map_err(|e| AnalysisError::Model(e.to_string()))
                };
                // the history the increment is solved with: h_{n-1}, with the multiplier
                // estimates of augmented-Lagrangian pairs updated between passes
                let mut hist_inc = hist.clone();
                let mut attempt = match predicted {
                    Ok(Some(factored)) => self
                        .attempt(
                            &mut z_try,
                            &hist_inc,
                            t,
                            &mut eval,
                            &mut record,
                            &mut res.cost,
                        )
                        .map(|f| {
                            if factored {
                                record.iterations += 1;
                            }
                            f || factored
                        }),
                    Ok(None) => Err(AttemptFailure::Diverged("predictor failed")),
                    Err(e) => return Err(e),
                };
                // augmented Lagrangian (Uzawa): lambda_bar <- p_n and solve again from the
                // converged state until the penetration is within tolerance
                let mut augmentations = 0;
                while let Ok(factored) = attempt {
                    if augmentations >= MAX_AUGMENTATIONS
                        || !crate::contact::assembly::augment(
                            model,
                            &self.assembler.contact,
                            &eval.contact,
                            &mut hist_inc,
                        )
                    {
                        break;
                    }
                    augmentations += 1;
                    let mut again = record.clone();
                    again.residuals.clear();
                    attempt = self
                        .attempt(
                            &mut z_try,
                            &hist_inc,
                            t,
                            &mut eval,
                            &mut again,
                            &mut res.cost,
                        )
                        .map(|f| {
                            record.iterations += again.iterations;
                            record.residuals.extend(&again.residuals);
                            f || factored
                        });
                }
                record.augmentations = augmentations;
                match attempt {
                    Ok(factored) => {
                        index += 1;
                        let conv = Converged {
                            model,
                            assembler: &self.assembler,
                            lifted: &self.lifted,
                            index,
                            time: t,
                            time_prev: t_prev,
                            z: &z_try,
                            hist_prev: &hist_inc,
                            eval: &eval,
                            constrained: &self.constrained,
                            // the last Newton factorization, of this increment or, when it
                            // converged without iterating, of an earlier one
                            last_factor: if factored || self.linear.is_factored() {
                                Some(&self.linear)
                            } else {
                                None
                            },
                            tangent: &self.matrix,
                            factor_matches: self.factored_choice == eval.contact.choice
                                && self.factored_branches == eval.branches,
                            record: &record,
                        };
                        observer.converged(&conv)?;
                        previous = Some((std::mem::replace(&mut z, z_try), t_prev));
                        hist.copy_from_slice(&eval.hist_new);
                        self.keep_contact_states(&eval.contact.choice);
                        res.times.push(t);
                        if opts.keep_states {
                            res.states.push(z.clone());
                            res.residuals.push(eval.residual.clone());
                            res.histories.push(hist.clone());
                            res.contact.push(eval.contact.clone());
                        }
                        res.stresses.push(eval.cauchy.clone());
                        res.branches.push(eval.branches.clone());
                        let easy = record.iterations <= 4;
                        let hard = model.solver.shrink_after > 0
                            && record.iterations > model.solver.shrink_after;
                        self.force_history.0 += record.reference_force;
                        self.force_history.1 += 1;
                        res.records.push(record);
                        t_prev = t;
                        cutbacks = 0;
                        // automatic incrementation, the user's increment the largest step:
                        // grow a cut-back step again after an easy increment, shrink the next
                        // step after a hard one (as CalculiX and Abaqus do)
                        suggested = if easy {
                            2.0 * step
                        } else if hard {
                            // by a quarter, and to no less than a quarter of the user's
                            // increment: an increment that is hard at any size (an active set
                            // settling node by node) would otherwise halve the steps without
                            // end (fuzzer seed 240: 178 increments for 13)
                            (HARD_SHRINK * step).max(nominal * HARD_FLOOR).min(step)
                        } else {
                            step
                        };
                        step = suggested.min(t_end - t_prev_nominal);
                    }
                    Err(AttemptFailure::TimeLimit) => {
                        res.history = hist;
                        res.cost.wall_seconds = start.elapsed().as_secs_f64();
                        return Err(AnalysisError::TimeLimit {
                            increment: index + 1,
                            time: t,
                            seconds: opts.time_limit.unwrap_or(0.0),
                            partial: Box::new(res),
                        });
                    }
                    Err(why) => {
                        let at_minimum = step <= min_step * (1.0 + 1e-9);
                        if cutbacks >= model.solver.max_cutbacks || at_minimum {
                            let mut reason = why.to_string();
                            reason.push_str(&format!(
                                " ({} halvings in a row{}; {} failed attempts within the increment ending at t = {t_end})",
                                cutbacks,
                                if at_minimum {
                                    format!(
                                        ", down to the smallest step {min_step:.3e}: the nominal one halved {} times",
                                        model.solver.max_cutbacks
                                    )
                                } else {
                                    String::new()
                                },
                                failed + 1
                            ));
                            res.history = hist;
                            res.cost.wall_seconds = start.elapsed().as_secs_f64();
                            return Err(AnalysisError::Diverged {
                                increment: index + 1,
                                time: t,
                                step,
                                cutbacks: failed + 1,
                                residuals: record.residuals,
                                reason,
                                partial: Box::new(res),
                            });
                        }
                        // a bad mesh does not improve with a smaller step
                        if let AttemptFailure::Element(
                            f @ AssemblyFailure::Element {
                                failure: ElementFailure::BadReferenceGeometry { .. },
                                ..
                            },
                        ) = why
                        {
                            return Err(AnalysisError::Mesh(f));
                        }
                        if self.trace {
                            eprintln!(
                                "increment {} t = {t:.6e}: attempt failed ({why:?}); residuals {:?}",
                                index + 1,
                                record.residuals
                            );
                        }
                        let why = why.to_string();
                        last_failure = Some((t, std::mem::take(&mut record.residuals), why));
                        failed += 1;
                        cutbacks += 1;
                        step *= 0.5;
                    }
                }
            }
        }
        if !opts.keep_states {
            res.states.push(z);
        }
        res.history = hist;
        res.cost.wall_seconds = start.elapsed().as_secs_f64();
        Ok(res)
    }

    /// Consistent predictor for an increment of prescribed displacements: linearise about the
    /// last converged state, `K dz_f = -(R_f(z_n, t) + K_fc dz_c)`, instead of starting Newton
    /// from a state in which only the prescribed nodes have moved (which distorts the elements
    /// next to them and provokes spurious yielding, inversion and cutbacks). Returns whether it
    /// factored (it counts as a Newton iteration), or `None` when the linearised step itself
    /// fails (the caller cuts back).
    fn predict(
        &mut self,
        z_old: &[f64],
        z_new: &mut [f64],
        hist: &[f64],
        t: f64,
        eval: &mut Evaluation<f64>,
        cost: &mut PrimalCost,
    ) -> Result<Option<bool>, LinalgError> {
        let n = z_old.len();
        let mut dzc = vec![0.0; n];
        let mut moved = false;
        for d in 0..n {
            if self.constrained[d] && z_new[d] != z_old[d] {
                dzc[d] = z_new[d] - z_old[d];
                moved = true;
            }
        }
        if !moved {
            return Ok(Some(false));
        }
        let assembled = assemble(
            &self.assembler,
            self.model,
            &self.lifted,
            &mut self.matrix,
            (z_old, hist, t),
            None,
            eval,
            cost,
        );
        if assembled.is_err() {
            return Ok(None);
        }
        let mut kdzc = vec![0.0; n];
        self.matrix.mul_vec(&dzc, &mut kdzc)?;
        let mut dz: Vec<f64> = (0..n)
            .map(|d| {
                if self.constrained[d] {
                    0.0
                } else {
                    -(eval.residual[d] + kdzc[d])
                }
            })
            .collect();
        if self.factor_and_solve(&mut dz, cost).is_err() {
            return Ok(None);
        }
        if dz.iter().any(|v| !v.is_finite()) {
            return Ok(None);
        }
        for d in 0..n {
            if !self.constrained[d] {
                z_new[d] = z_old[d] + dz[d];
            }
        }
        Ok(Some(true))
    }

    /// Apply the identity rows of the prescribed unknowns to the assembled tangent, factor it
    /// (numeric only, on the run's symbolic analysis) and solve `K dz = rhs` in place.
    fn factor_and_solve(
        &mut self,
        rhs: &mut [f64],
        cost: &mut PrimalCost,
    ) -> Result<(), AttemptFailure> {
        for (d, c) in self.constrained.iter().enumerate() {
            if *c {
                self.matrix
                    .set_identity_row_col(d)
                    .expect("constrained unknown in range");
            }
        }
        let t1 = Instant::now();
        if self.linear.factor(&self.matrix).is_err() {
            return Err(AttemptFailure::Diverged("singular tangent"));
        }
        cost.factorizations += 1;
        cost.factor_seconds += t1.elapsed().as_secs_f64();
        let b = self.trace.then(|| rhs.to_vec());
        let t2 = Instant::now();
        if self.linear.solve_in_place(rhs).is_err() {
            return Err(AttemptFailure::Diverged("solve failed"));
        }
        cost.solves += 1;
        cost.solve_seconds += t2.elapsed().as_secs_f64();
        if let Some(b) = b {
            // the linear solve's own accuracy: |K x - b| / |b|
            let mut kx = vec![0.0; b.len()];
            if self.matrix.mul_vec(rhs, &mut kx).is_ok() {
                let r = kx.iter().zip(&b).map(|(a, b)| (a - b).powi(2)).sum::<f64>();
                let bn = b.iter().map(|v| v * v).sum::<f64>();
                eprintln!(
                    "  solve: |K x - b| / |b| = {:.2e}",
                    (r / bn.max(f64::MIN_POSITIVE)).sqrt()
                );
            }
        }
        Ok(())
    }

    /// Newton's correction `dz = -K^-1 R` on the free unknowns for the evaluation `eval`
    /// (its tangent in `self.matrix`); remembers the states the factorization was assembled
    /// on.
    fn newton_step(
        &mut self,
        eval: &Evaluation<f64>,
        dz: &mut [f64],
        cost: &mut PrimalCost,
    ) -> Result<(), AttemptFailure> {
        for (d, (dzi, r)) in dz.iter_mut().zip(&eval.residual).enumerate() {
            *dzi = if self.constrained[d] { 0.0 } else { -r };
        }
        self.factored_choice.clone_from(&eval.contact.choice);
        self.factored_branches.clone_from(&eval.branches);
        self.factor_and_solve(dz, cost)
    }

    /// Settle the contact active set of the first Newton step of an attempt on the
    /// linearised problem, before the state moves; returns the extra solves made.
    ///
    /// The step `dz` was solved with the open/closed states decided at `z`. The contact
    /// kernel, evaluated alone at `z + dz`, predicts the states the step leads to (the
    /// multipliers' signs and the gaps, decided by the primal-dual rule). While they differ,
    /// the tangent at `z` is assembled again with the predicted states imposed and the step
    /// solved again ([`ActiveSetPredictor::next`] decides which changes to take).
    ///
    /// Why: at an increment's start the bodies overlap where a rigid target moved by a whole
    /// increment, and a deformable body the first step bends can overshoot a whole nearly
    /// conforming surface. Newton taking that step with the states decided at the start
    /// state loads the body with forces far from equilibrium: the leaf spring's first step
    /// held three nodes on the block's cylindrical nose 1.3 to 2 mm deep (bending plastic at
    /// 640 of its 1,104 Gauss points), then pressed the upper leaf up to 1.4 mm into the lower
    /// one along its whole length; 30 iterations later the attempt was cut back, twice. Settled
    /// on the linearised problem, the step holds the nose at one node row and the lower leaf
    /// at its tip, what the converged state has, and the increment converges without cutback.
    ///
    /// Only the first step of an attempt: on the strip pull-out, whose friction couples the
    /// normal and tangential directions, the linearised problem's states cycle (multipliers
    /// going negative where released nodes then penetrate) and settling every step multiplied
    /// the factorizations by 4.6; its first steps settle at once.
    #[allow(clippy::too_many_arguments)]
    fn settle_active_set(
        &mut self,
        z: &[f64],
        dz: &mut [f64],
        hist: &[f64],
        t: f64,
        eval: &mut Evaluation<f64>,
        predictor: &mut ActiveSetPredictor,
        cost: &mut PrimalCost,
    ) -> Result<usize, AttemptFailure> {
        let model = self.model;
        let mut solves = 0;
        let closed = |c: &[ContactChoice]| -> Vec<bool> {
            c.iter().map(|c| c.state != ContactState::Open).collect()
        };
        // the active sets solved with, and the step of the one whose prediction changed the
        // fewest states (Newton's own first step unless another changed strictly fewer, then
        // the latest of equals)
        let mut seen = vec![closed(&eval.contact.choice)];
        let mut best: Option<SettledStep> = None;
        while solves < model.solver.active_set_solves {
            for ((tz, zi), d) in predictor.z.iter_mut().zip(z).zip(dz.iter()) {
                *tz = zi + d;
            }
            let Some((trial, changes)) = predictor.next(
                model,
                &self.assembler,
                &self.lifted,
                (hist, t),
                eval,
                &self.converged_choice,
            ) else {
                break;
            };
            if self.trace {
                eprintln!("    active-set predictor: {trial}");
            }
            if best
                .as_ref()
                .is_none_or(|b| changes < b.changes || (changes == b.changes && !b.newtons))
            {
                best = Some(SettledStep {
                    changes,
                    dz: dz.to_vec(),
                    choice: eval.contact.choice.clone(),
                    residual: eval.residual.clone(),
                    newtons: best.is_none(),
                });
            }
            // A set solved with before: the prediction cycles (the block's nose between two
            // node rows, one tensile when closed and penetrating when open). Take the step of
            // the set whose prediction changed the fewest states and leave the rest to
            // Newton's iterations; Newton's own step wins a tie (the strip pull-out's
            // unloading cycles between it and the set releasing its end node at g = 0, and
            // the other step moves du0/dmu 2.26 % off -u0/mu, tests/contact_oracles.rs).
            // Newton's own first step is the worst on refined leaf springs: refined 7 times it
            // pressed the upper leaf 0.07 mm into the lower one along its whole length, the
            // active set then released the spurious contacts a row or two per iteration under
            // the yield-crossing limiter's short steps, and the increment never converged
            // (four cutbacks). With the fewest changes the first step holds the lower leaf at
            // its tip only, as the converged state does: refined 7 times 46 factorizations,
            // 8 times 40 (71 before), 10.4 times (230,567 unknowns) 73.
            let next = closed(&predictor.choice);
            if seen.contains(&next) {
                if let Some(b) = best.take() {
                    dz.copy_from_slice(&b.dz);
                    eval.contact.choice = b.choice;
                    eval.residual = b.residual;
                    if self.trace {
                        eprintln!(
                            "    active-set predictor: cycle, the step of the set with the fewest predicted changes ({}) taken",
                            b.changes
                        );
                    }
                }
                break;
            }
            seen.push(next);
            let frozen = Frozen {
                gauss: None,
                contact: &predictor.choice,
                skip: None,
                ..Frozen::default()
            };
            assemble(
                &self.assembler,
                model,
                &self.lifted,
                &mut self.matrix,
                (z, hist, t),
                Some(&frozen),
                eval,
                cost,
            )
            .map_err(AttemptFailure::Element)?;
            self.newton_step(eval, dz, cost)?;
            solves += 1;
        }
        Ok(solves)
    }

    /// What cycles in a stalled attempt, in words: the hitting nodes whose contact state or
    /// face changes over the window, with the states they take, and what to try.
    fn diagnose_cycle(
        &self,
        window: &std::collections::VecDeque<(Vec<ContactChoice>, f64)>,
        tolerance: f64,
    ) -> String {
        let model = self.model;
        let flat = &self.assembler.contact.flat;
        let mut flips = Vec::new();
        if let Some((first, _)) = window.front() {
            for i in 0..first.len() {
                let mut seen: Vec<String> = Vec::new();
                for (c, _) in window {
                    let what = match c[i].state {
                        ContactState::Open => "open".to_string(),
                        ContactState::Closed => format!("closed on face {}", c[i].face),
                        ContactState::Stick => format!("stick on face {}", c[i].face),
                        ContactState::Slip => format!("slip on face {}", c[i].face),
                    };
                    if !seen.contains(&what) {
                        seen.push(what);
                    }
                }
                if seen.len() > 1 {
                    let p = flat.iter().rposition(|&f| f <= i).unwrap_or(0);
                    let pair = &model.contacts[p];
                    let seen = if matches!(pair.target, crate::contact::Target::Rigid { .. }) {
                        seen.iter().map(|s| s.replace(" on face 0", "")).collect()
                    } else {
                        seen
                    };
                    flips.push(format!(
                        "pair '{}' node {} ({})",
                        pair.name,
                        pair.hitting[i - flat[p]],
                        seen.join(" / ")
                    ));
                }
            }
        }
        let best = window.iter().map(|(_, r)| *r).fold(f64::INFINITY, f64::min);
        let what = if flips.is_empty() {
            "with the contact states unchanged".to_string()
        } else {
            let n = flips.len();
            flips.truncate(6);
            format!(
                "with {n} hitting node(s) flipping: {}{}",
                flips.join(", "),
                if n > 6 { ", ..." } else { "" }
            )
        };
        format!(
            "Newton cycles {what}, the residual staying above {best:.3e} (tolerance {tolerance:.3e}); try more increments in this step, or a softer tangential_stiffness or normal penalty on those pairs"
        )
    }

    /// Newton iterations of one attempt. Returns whether a factorization was made.
    ///
    /// An iteration is one linear solve; the residual evaluations of the line search and of
    /// the penetration limiter between two solves are not iterations (they are counted in
    /// [`PrimalCost::assemblies`] and recorded in [`IncrementRecord::residuals`]).
    fn attempt(
        &mut self,
        z: &mut [f64],
        hist: &[f64],
        t: f64,
        eval: &mut Evaluation<f64>,
        record: &mut IncrementRecord,
        cost: &mut PrimalCost,
    ) -> Result<bool, AttemptFailure> {
        let model = self.model;
        let s = &model.solver;
        let mut energy0 = f64::NAN;
        let mut last_energy = f64::INFINITY;
        let mut last_correction = f64::INFINITY;
        // the last correction of the positions relative to the positions `|X + u|`, and of
        // the other unknowns (multipliers, incompatible modes) relative to themselves
        let mut last_position_correction = f64::INFINITY;
        let mut last_other_correction = f64::INFINITY;
        // backtracking line search and penetration limiter (contact models only: their
        // residual is only piecewise smooth, and a full Newton step can flip many contact and
        // stick/slip states at once)
        let line_search = !model.contacts.is_empty();
        let mut alpha = 1.0;
        let mut prev_r = f64::INFINITY;
        let mut last_dz: Vec<f64> = Vec::new();
        // gaps and open states at the start of the last step, and whether the limiter has
        // shortened it already
        let mut base_gap: Vec<f64> = Vec::new();
        let mut base_open: Vec<bool> = Vec::new();
        let mut limited = false;
        let mut first_residual = f64::NAN;
        let mut factored = false;
        // Active-set predictor: the first iteration keeps the contact states (and faces) of
        // the last converged increment instead of deciding them at the start state moved to
        // the new load. A rigid target that moved by a whole increment otherwise closes every
        // node it now overlaps, and the linearised constraints on nodes that will lift off
        // load the first step with forces orders of magnitude too large (leaf spring: 40x,
        // inverted elements and cutbacks).
        let mut predict = !self.converged_choice.is_empty();
        // built at the first settling (its trial evaluation holds a whole history vector)
        let mut predictor: Option<ActiveSetPredictor> = None;
        // linear solves of the first step's active-set settling (counted as iterations)
        let mut settle_solves = 0;
        // Newton iterations (solves) made
        let mut k = 0;
        // Slip reversal (see `SLIP_REVERSALS`): the states and friction forces of the last
        // free evaluation, the nodes forced to stick in the current one, and how often each
        // node has been forced in this attempt
        let friction = model.contacts.iter().any(|c| c.friction.is_some());
        let mut last_free: Option<(Vec<ContactState>, Vec<nalgebra::Vector3<f64>>)> = None;
        let mut forced: Vec<bool> = Vec::new();
        let mut forced_count: Vec<usize> = Vec::new();
        // cycle detection: the contact decisions and residuals of the last free evaluations,
        // and the smallest residual of those before them
        let mut window: std::collections::VecDeque<(Vec<ContactChoice>, f64)> =
            std::collections::VecDeque::new();
        let mut best_before = f64::INFINITY;
        // the target faces to keep (hysteresis, SEGMENT_KEEP): those the last Newton step was
        // solved with, the converged ones at the first
        let mut keep_faces = self.converged_choice.clone();
        loop {
            if self.deadline.is_some_and(|d| Instant::now() > d) {
                return Err(AttemptFailure::TimeLimit);
            }
            let (r_free, f_ref) = loop {
                // the first iteration's contact states and faces those of the last converged
                // increment (the predictor below), the others' decided freely but for the
                // faces' hysteresis against the converged ones
                let frozen = Frozen {
                    gauss: None,
                    contact: &self.converged_choice,
                    skip: None,
                    ..Frozen::default()
                };
                let free = Frozen {
                    gauss: None,
                    contact: &[],
                    skip: None,
                    keep_faces: Some(&keep_faces),
                    stick: (!forced.is_empty()).then_some(&forced[..]),
                };
                assemble(
                    &self.assembler,
                    model,
                    &self.lifted,
                    &mut self.matrix,
                    (z, hist, t),
                    Some(if predict && k == 0 { &frozen } else { &free }),
                    eval,
                    cost,
                )
                .map_err(AttemptFailure::Element)?;
                let mut r_free = 0.0;
                let mut r_fixed = 0.0;
                for (d, r) in eval.residual.iter().enumerate() {
                    if self.constrained[d] {
                        r_fixed += r * r;
                    } else {
                        r_free += r * r;
                    }
                }
                let r_free = r_free.sqrt();
                let mut f_ext = 0.0;
                for (l, load) in model.loads.iter().enumerate() {
                    let f = self.lifted.loads[l] * load.amplitude.at(t);
                    f_ext += load.weights.iter().map(|w| (f * w).powi(2)).sum::<f64>();
                }
                let f_ref = r_fixed.sqrt().max(f_ext.sqrt());
                // a state that balances with the predicted contact states is accepted only
                // once they are decided freely
                if predict && k == 0 && (r_free <= s.force_tol * f_ref || r_free == 0.0) {
                    predict = false;
                    continue;
                }
                break (r_free, f_ref);
            };
            record.residuals.push(r_free);
            record.reference_force = f_ref;
            if self.trace {
                let active: Vec<String> = eval
                    .contact
                    .choice
                    .iter()
                    .zip(&eval.contact.normal_force)
                    .enumerate()
                    .filter(|(_, (c, _))| c.state != crate::contact::ContactState::Open)
                    .map(|(i, (c, f))| format!("{i}:{:?}:{f:.3e}:f{}", c.state, c.face))
                    .collect();
                eprintln!(
                    "  t = {t:.4e} k = {k} alpha = {alpha:.3} r = {r_free:.3e} closed {}",
                    active.join(" ")
                );
            }
            if !r_free.is_finite() {
                return Err(AttemptFailure::Diverged("non-finite residual"));
            }
            if k == 0 {
                first_residual = r_free;
            }
            // Penetration limiter. A node the step found open at a positive gap and left
            // deeper inside its target than it was outside overshot first contact (the
            // linearised step knows nothing of the constraint it crosses). Shorten the step to
            // just past the deepest such overshoot's first touch (linear in the step), so that
            // node closes at the next solve with the bodies where they meet. Without it, the
            // first contact of the leaf spring's leaves pressed the upper leaf 0.3 mm into the
            // lower one along its whole length (0.02 mm clearance), and the primal-dual active
            // set then released the spurious contacts one node per iteration (26 iterations;
            // refined meshes ran out of iterations).
            if line_search && k >= 1 && !limited && forced.is_empty() {
                let floor = self.penetration_floor;
                let first_touch = base_gap
                    .iter()
                    .zip(&base_open)
                    .zip(&eval.contact.gap)
                    .filter(|((g0, open), g1)| {
                        **open && g0.is_finite() && **g0 > floor && **g1 < -floor && -**g1 > **g0
                    })
                    .map(|((g0, _), g1)| g0 / (g0 - g1))
                    .fold(1.0f64, f64::min);
                if first_touch < 0.5 {
                    limited = true;
                    // a tenth of the node's gap past first touch
                    let keep = 1.1 * first_touch;
                    if self.trace {
                        eprintln!("    penetration limiter: step x {keep:.3e}");
                    }
                    for (zi, d) in z.iter_mut().zip(&last_dz) {
                        *zi -= alpha * (1.0 - keep) * d;
                    }
                    alpha *= keep;
                    continue;
                }
            }
            let forcing = !forced.is_empty();
            let force_ok = !forcing && (r_free <= s.force_tol * f_ref || r_free == 0.0);
            // (a first correction of zero energy gives no scale: the force criterion decides)
            let energy_ok =
                !forcing && k > 0 && energy0 > 0.0 && last_energy <= s.energy_tol * energy0;
            // the correction is at round-off: Newton cannot move the state any more, the
            // residual left is the noise of its own evaluation. Either the whole correction
            // is at round-off of the unknowns, or the positions moved by less than the
            // round-off of the positions themselves (the displacement unknowns are small at
            // low load, but the gaps and slips are computed from `X + u`) while the other
            // unknowns settled to sqrt(eps). The leaf spring's residual floor is 1.1e-8 N at
            // every refinement from 2,662 to 230,303 unknowns; the tolerance 1e-9 F_ref is
            // below it in the first increments of the finest mesh, where Newton stayed at the
            // floor for 29 iterations with position corrections of 0.0 to 0.6 eps |x| (the
            // quadratic step before reaching the floor: 450 eps |x| and more).
            let correction_ok = !forcing
                && k > 1
                && (last_correction <= CORRECTION_ROUND_OFF * f64::EPSILON
                    || (last_position_correction <= CORRECTION_ROUND_OFF * f64::EPSILON
                        && last_other_correction <= f64::EPSILON.sqrt()));
            // the energy and round-off criteria stand in for the force criterion where the
            // residual cannot reach it for round-off, not where it is far above it: a
            // correction at round-off with a large residual is a stiff or inconsistent tangent
            // (against the larger of the current reference force and the mean of the converged
            // increments': an unloaded state's is zero, and its residual only round-off)
            let mean_ref = self.force_history.0 / self.force_history.1.max(1) as f64;
            let near =
                r_free <= NEAR_TOLERANCE * s.force_tol * f_ref.max(mean_ref).max(self.force_floor);
            if force_ok || (near && (energy_ok || correction_ok)) {
                record.iterations = k + settle_solves;
                return Ok(factored);
            }
            // Backtrack only from the second correction on, and only on a blow-up (residual
            // up more than LINE_SEARCH_GROWTH times). The first correction and every
            // primal-dual active-set step that settles contact or stick/slip states raise the
            // residual moderately before quadratic steps follow; backtracking them stalls
            // Newton (stacked leaves 0.8 -> 30 then converged in two; leaf spring a quarter
            // step per iteration, no convergence in 30). Measured before the extrapolating
            // predictor and the penetration limiter, growth 1 / 4 / 100:
            // sliding block 5.75 / 4.91 / 4.81 iterations per increment, strip pull-out
            // 21 / 39 / 83 increments (its slip front needs the damping), leaf spring
            // diverged / 12 / 12.
            if line_search
                && !forcing
                && k > 1
                && r_free > LINE_SEARCH_GROWTH * prev_r
                && alpha > 1.0 / 32.0
            {
                // step back to z_prev + (alpha / 2) dz and evaluate again
                alpha *= 0.5;
                for (zi, d) in z.iter_mut().zip(&last_dz) {
                    *zi -= alpha * d;
                }
                continue;
            }
            // Slip reversal: a node that slipped at the last free evaluation and slips the
            // other way now has its stick zone between the two iterates; Newton's slip tangent
            // (no stiffness along the slip) steps over it each time and cycles. Evaluate again
            // with such nodes on the stick branch, so that the step is solved with their
            // stick stiffness and lands them in the zone (at most SLIP_REVERSALS times per
            // node and attempt: the forcing ends, and the free decisions take over).
            if friction && !forcing && !(predict && k == 0) {
                let states: Vec<ContactState> =
                    eval.contact.choice.iter().map(|c| c.state).collect();
                let mut reversed = Vec::new();
                // only where Newton stalls: far from the solution a slip direction may turn
                // on the way (the leaf spring's nose nodes do at its second iteration, where
                // forcing them cost 27 more iterations over the run)
                let stalled = r_free > STALL_RATIO * prev_r;
                if let (true, Some((old_states, old_t))) = (stalled, &last_free) {
                    forced_count.resize(states.len(), 0);
                    for i in 0..states.len() {
                        if states[i] == ContactState::Slip
                            && old_states[i] == ContactState::Slip
                            && eval.contact.traction[i].dot(&old_t[i]) < 0.0
                            && forced_count[i] < SLIP_REVERSALS
                        {
                            reversed.push(i);
                        }
                    }
                }
                last_free = Some((states, eval.contact.traction.clone()));
                if !reversed.is_empty() {
                    forced = vec![false; eval.contact.choice.len()];
                    for &i in &reversed {
                        forced[i] = true;
                        forced_count[i] += 1;
                    }
                    if self.trace {
                        eprintln!(
                            "    slip reversal: nodes {reversed:?} evaluated again on the stick branch"
                        );
                    }
                    continue;
                }
            }
            alpha = 1.0;
            limited = false;
            if !forcing {
                prev_r = r_free;
            }
            // Fail fast on a cycle: at a free evaluation, contact decisions seen earlier in
            // the window again, and no residual in the window below half the best before it.
            if line_search && !forcing && !(predict && k == 0) {
                let repeated = window.iter().any(|(c, _)| *c == eval.contact.choice);
                window.push_back((eval.contact.choice.clone(), r_free));
                if window.len() > CYCLE_WINDOW {
                    let (_, r) = window.pop_front().expect("not empty");
                    best_before = best_before.min(r);
                }
                let best_now = window.iter().map(|(_, r)| *r).fold(f64::INFINITY, f64::min);
                if repeated && k >= 2 * CYCLE_WINDOW && best_now >= 0.5 * best_before {
                    return Err(AttemptFailure::Cycle(
                        self.diagnose_cycle(&window, s.force_tol * f_ref),
                    ));
                }
            }
            if k == s.max_iterations {
                return Err(AttemptFailure::Diverged("iteration limit"));
            }
            if k >= 4 && r_free > 1e4 * first_residual.max(f_ref) {
                return Err(AttemptFailure::Diverged("residual growing"));
            }
            let mut dz = vec![0.0; eval.residual.len()];
            self.newton_step(eval, &mut dz, cost)?;
            factored = true;
            forced.clear();
            keep_faces.clone_from(&eval.contact.choice);
            if k == 0 && line_search {
                let predictor =
                    predictor.get_or_insert_with(|| ActiveSetPredictor::new(&self.assembler));
                settle_solves =
                    self.settle_active_set(z, &mut dz, hist, t, eval, predictor, cost)?;
                record.active_set_solves += settle_solves;
            }
            // Yield-surface crossing limiter: a step that carries a plastic point through its
            // elastic domain to the far side of the yield surface stops where the point is
            // deepest inside (at least YIELD_CROSSING_FLOOR of the step), so the next
            // iteration sees it elastic instead of returned the other way (a two-cycle of
            // constant branches otherwise: MaterialLaw::elastic_crossing).
            let (crossing, points) =
                self.assembler
                    .elastic_crossing(model, &self.lifted, z, &dz, hist, &eval.branches);
            if points > 0 {
                let scale = crossing.max(YIELD_CROSSING_FLOOR);
                if self.trace {
                    eprintln!(
                        "    yield crossing: {points} points cross their elastic domain, step x {scale:.3e}"
                    );
                }
                dz.iter_mut().for_each(|d| *d *= scale);
            }
            k += 1;
            let energy: f64 = dz
                .iter()
                .zip(&eval.residual)
                .map(|(a, b)| a * b)
                .sum::<f64>()
                .abs();
            record.energies.push(energy);
            if k == 1 {
                energy0 = energy;
            }
            last_energy = energy;
            let n_nodal = self.assembler.dofs.n_nodal;
            // the displacement-like unknowns (nodal, and the elements' incompatible modes)
            // against the positions' round-off; the multipliers against themselves (an
            // unloaded body's incompatible modes are zero, and their corrections were measured
            // against nothing: the fuzzer found Newton at the round-off floor of a lifted-off
            // body for 30 iterations)
            let first_lambda = self.assembler.dofs.first_lambda.min(dz.len());
            let norm = |v: &[f64]| v.iter().map(|v| v * v).sum::<f64>().sqrt();
            let (dz_nodal, dz_other) = (norm(&dz[..first_lambda]), norm(&dz[first_lambda..]));
            let (z_nodal, z_other) = (norm(&z[..first_lambda]), norm(&z[first_lambda..]));
            let x_norm = (0..n_nodal)
                .map(|d| (self.lifted.coords[d / 3][d % 3] + z[d]).powi(2))
                .sum::<f64>()
                .sqrt();
            last_correction =
                dz_nodal.hypot(dz_other) / z_nodal.hypot(z_other).max(f64::MIN_POSITIVE);
            last_position_correction = dz_nodal / x_norm.max(f64::MIN_POSITIVE);
            last_other_correction = if dz_other == 0.0 {
                0.0
            } else {
                dz_other / z_other.max(f64::MIN_POSITIVE)
            };
            if !energy.is_finite() {
                return Err(AttemptFailure::Diverged("non-finite correction"));
            }
            if line_search {
                base_gap.clone_from(&eval.contact.gap);
                base_open.clear();
                base_open.extend(
                    eval.contact
                        .choice
                        .iter()
                        .map(|c| c.state == crate::contact::ContactState::Open),
                );
            }
            for (zi, d) in z.iter_mut().zip(&dz) {
                *zi += d;
            }
            last_dz = dz;
        }
    }
}
