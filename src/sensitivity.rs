//! Design sensitivities along the whole load path: SDM, DDM and FDM behind one interface.
//!
//! ## Equations (shared/design.md section 3; the paper's eqs. 46-48, 53-56)
//! State after increment `n`: unknowns `z_n`, history `h_n`. At convergence
//! `R(z_n, h_{n-1}, b) = 0` and `h_n = H(z_n, h_{n-1}, b)`. Differentiating,
//!
//! ```text
//! K dz_n/db = -( dR/db + dR/dh_{n-1} dh_{n-1}/db )     =: -r      (the pseudo-load)
//! dh_n/db   =  dH/dz dz_n/db + dH/dh dh_{n-1}/db + dH/db
//! ```
//!
//! * **DDM**: `R` evaluated with `z_n` real, `h_{n-1}` carrying its derivative and `b` seeded
//!   (dual numbers): the derivative part is exactly `r`. After the solve, the same evaluation with
//!   `z_n` carrying `dz_n/db` gives `dh_n/db` and the total derivative of every response.
//!   Each parameter is seeded alone in a `Dual64`; the pseudo-loads of all of them go through
//!   one multi-column solve.
//! * **SDM**: `r ~ [R(z_n, h_{n-1} + db dh_{n-1}/db, b + db) - R(z_n, h_{n-1}, b)] / db` with the
//!   `f64` kernels, branches frozen at the converged state; central SDM uses `b +- db`.
//!   `db = beta b_0` (the paper's relative perturbation; `db = beta` where `b_0 = 0`).
//! * **FDM**: complete reruns of the load history at `b_0 (1 +- beta)`.
//!
//! Prescribed unknowns are not solved for: their derivative is known (non-zero only for the
//! magnitude of a prescribed displacement) and enters `r` through the coupling terms.
//!
//! ## Tangent of the sensitivity solve
//! * `exact` (the default): the converged tangent, to a relative residual of [`KRYLOV_TOL`] (or, where
//!   `|K||x|` is far above `|b|` and no solve reaches that, to the backward error of a
//!   backward-stable direct solve): by GMRES
//!   preconditioned with Newton's last factorization (a few solves: the two matrices differ by
//!   Newton's last correction and any branches it switched), factored afresh where GMRES
//!   does not converge in [`KRYLOV_MAX_ITER`] steps or `Settings::krylov` is off; then refined
//!   with residuals in double-double arithmetic until the correction is below 1e-13 of the
//!   solution (`refine_extended`), so that the result no longer depends on which solve
//!   produced it (two backward-stable solves differ by up to `cond(K) eps`: 2e-10 of the leaf
//!   spring's d(force)/d(length)). DDM is then the exact derivative of the discrete
//!   incremental solution to about 1e-13, and SDM's error is its own finite-difference error
//!   alone;
//! * `last`: the last Newton factorization, of the iterate before convergence (the paper's
//!   choice; no extra solve). It is the tangent of a state one Newton correction away from the
//!   converged one, so every in-line method inherits an error of the order of that correction
//!   (1.2e-2 relative on the leaf spring, 8.8e-5 on the indentation: the report's cost table);
//! * `refined`: the last factorization plus `Settings::refine_steps` steps of iterative
//!   refinement against the converged tangent (between the two in cost and accuracy).
//!
//! DDM's one-sided derivatives solve with forced tangents the same way (preconditioned with
//! the converged tangent's factorization where one was made at that increment).
//!
//! ## Non-differentiable points
//! A Gauss point whose trial yield ratio lies within `kink_tol` of zero sits on the
//! elastic/plastic transition: the increment is flagged, and for DDM the derivative is also
//! computed with that point forced onto each branch — the one-sided derivatives.

use crate::assembly::{Evaluation, Frozen};
use crate::contact::{ContactChoice, ContactState};
use crate::linalg::LinearSolver;
use crate::material::Branch;
use crate::model::{DesignParam, Lifted, Model};
use crate::scalar::Scalar;
use crate::solver::{AnalysisError, Converged, NoObserver, Observer, Results, RunOptions, Solver};
use num_dual::Dual64;
use std::time::Instant;

/// A sensitivity method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Semi-analytical, forward perturbation.
    Sdm,
    /// Semi-analytical, central perturbation.
    SdmCentral,
    /// Direct differentiation with dual numbers.
    Ddm,
    /// Forward finite differences of reruns.
    Fdm,
    /// Central finite differences of reruns.
    FdmCentral,
}

impl Method {
    /// All methods.
    pub const ALL: [Method; 5] = [
        Method::Sdm,
        Method::SdmCentral,
        Method::Ddm,
        Method::Fdm,
        Method::FdmCentral,
    ];

    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Sdm => "sdm",
            Method::SdmCentral => "sdm-central",
            Method::Ddm => "ddm",
            Method::Fdm => "fdm",
            Method::FdmCentral => "fdm-central",
        }
    }

    /// Whether the method needs a perturbation size.
    pub fn uses_beta(self) -> bool {
        !matches!(self, Method::Ddm)
    }

    /// Whether the method runs in line with the primal analysis (SDM, DDM), rather than as
    /// reruns of it (FDM).
    pub fn is_inline(self) -> bool {
        matches!(self, Method::Sdm | Method::SdmCentral | Method::Ddm)
    }
}

/// Which tangent the sensitivity solve uses (the module docs compare their accuracy and cost).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TangentChoice {
    /// Newton's last factorization, of the iterate before convergence (the paper's choice; no
    /// extra factorization). Like `Refined`, falls back to the exact tangent where Newton did
    /// not factor or its last factorization belongs to other branches than the converged
    /// state's.
    Last,
    /// The last factorization plus `Settings::refine_steps` steps of iterative refinement
    /// against the converged tangent.
    Refined,
    /// The tangent at the converged state, solved to a relative residual of [`KRYLOV_TOL`]:
    /// by GMRES preconditioned with Newton's last factorization, or factored afresh (see
    /// `Settings::krylov`), and refined with double-double residuals to 1e-13 of the
    /// solution. The default.
    Exact,
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

/// Significant digits a difference must keep above its noise for its finite-difference
/// derivative not to be flagged round-off dominated (`IncrementSensitivity::roundoff`):
/// three digits, i.e. a relative error of the difference below about 1e-3.
pub const ROUNDOFF_DIGITS: f64 = 3.0;

/// Whether a difference `delta` of quantities of size `size`, each known to `noise`
/// (relative), keeps fewer than [`ROUNDOFF_DIGITS`] digits.
fn roundoff_dominated(delta: f64, size: f64, noise: f64) -> bool {
    delta.abs() < 10f64.powf(ROUNDOFF_DIGITS) * noise * size.abs()
}

/// Settings of a sensitivity run.
#[derive(Clone, Debug)]
pub struct Settings {
    /// The method.
    pub method: Method,
    /// Relative perturbation (SDM, FDM).
    pub beta: f64,
    /// Tangent of the sensitivity solve (SDM, DDM); default [`TangentChoice::Exact`].
    pub tangent: TangentChoice,
    /// Refinement steps for `TangentChoice::Refined`.
    pub refine_steps: usize,
    /// Freeze branches at the converged state in SDM's perturbed evaluations.
    pub freeze_branches: bool,
    /// |trial yield ratio| below which a Gauss point is taken to sit on a transition.
    pub kink_tol: f64,
    /// Evaluate each pseudo-load (SDM's unbalance, DDM's derivative part) over only the
    /// elements the parameter reaches (forward SDM: only where they are fewer than half, as
    /// it then evaluates the nominal state over them too), and DDM's forced tangents and
    /// pseudo-loads at flagged increments as the converged ones changed over the elements
    /// whose branches are forced; off: everything over all elements.
    pub restrict: bool,
    /// Measure the floor (`SensitivityCost::floor_seconds`) at every increment, outside the
    /// method's own wall time.
    pub probe_floor: bool,
    /// Solve with the converged tangent (`TangentChoice::Exact`, or Newton's last factor on
    /// other branches) or a forced one (DDM's one-sided derivatives: the flagged points forced
    /// onto one branch) by GMRES preconditioned with a factorization at hand instead of
    /// factoring it: Newton's last factor differs from the converged tangent by Newton's last
    /// correction and a few switched branches, the forced tangent from the converged one by a
    /// few rows, so GMRES converges in a few solves. A factorization is the fallback when
    /// GMRES does not reach [`KRYLOV_TOL`] (or a direct solve's backward error) in
    /// [`KRYLOV_MAX_ITER`] steps, and the only way
    /// when this is off.
    pub krylov: bool,
}

/// Relative residual `|b - K x| / |b|` GMRES must reach (every column, recomputed from the
/// iterate): about what the direct solves reach on the paper's scenes (`FRICSENS_TRACE`
/// prints theirs).
pub const KRYLOV_TOL: f64 = 1e-13;

/// GMRES steps before the tangent is factored instead (each step is one solve with the
/// factor at hand and one product; a factorization of the leaf spring's tangent costs about
/// 50 solves).
pub const KRYLOV_MAX_ITER: usize = 30;

impl Default for Settings {
    fn default() -> Self {
        Settings {
            method: Method::Ddm,
            beta: 1e-6,
            tangent: TangentChoice::Exact,
            refine_steps: 2,
            freeze_branches: true,
            kink_tol: 1e-6,
            restrict: true,
            probe_floor: false,
            krylov: true,
        }
    }
}

/// A point where the converged state sits on a transition.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Kink {
    /// What kind of transition.
    pub kind: &'static str,
    /// Element (or node) number.
    pub at: usize,
    /// Gauss point (or 0).
    pub point: usize,
    /// Distance to the transition (trial yield ratio).
    pub distance: f64,
}

/// Derivatives `[r][p]` with every flagged point forced onto each side of its transition.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct OneSided {
    /// Elastic / stick / open side.
    pub lower: Vec<Vec<f64>>,
    /// Plastic / slip / closed side.
    pub upper: Vec<Vec<f64>>,
}

/// What one in-line method computes at an increment.
struct Step {
    /// `[r][p]`: total derivative of each response.
    dresp: Vec<Vec<f64>>,
    /// `dh_n/db`, parameter-major.
    dhist: Vec<f64>,
    /// `dz_n/db` per parameter.
    dz: Vec<Vec<f64>>,
    /// Round-off dominated, `[r][p]` (SDM; empty for DDM).
    roundoff: Vec<Vec<bool>>,
}

/// DDM's pseudo-loads at one increment, with what the update after the solve reuses.
#[derive(Clone)]
struct PseudoLoads {
    /// `-dR/db` at fixed state, column-major per parameter (0 at prescribed unknowns).
    rhs: Vec<f64>,
    /// Derivative of the prescribed unknowns, per parameter.
    dzc: Vec<Vec<f64>>,
    /// The design seeded along each parameter.
    designs: Vec<Lifted<Dual64>>,
    /// The committed history carrying its derivative, per parameter.
    hists: Vec<Vec<Dual64>>,
}

/// Per element: whether the Gauss-point branches of `a` and `b` agree on all its points
/// (`None` when either leaves them free: every element counts as changed).
fn unchanged_elements(a: &Frozen<'_>, b: &Frozen<'_>) -> Option<Vec<bool>> {
    let (a, b) = (a.gauss?, b.gauss?);
    Some(a.chunks(8).zip(b.chunks(8)).map(|(a, b)| a == b).collect())
}

/// Sensitivities at one converged increment.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct IncrementSensitivity {
    /// Increment number of the nominal run (1-based, counting cut-back sub-increments).
    pub increment: usize,
    /// Pseudo-time at the end of the increment.
    pub time: f64,
    /// `values[r]`: response `r`.
    pub values: Vec<f64>,
    /// `derivatives[r][p]`: d response r / d parameter p.
    pub derivatives: Vec<Vec<f64>>,
    /// Flagged non-differentiable points.
    pub kinks: Vec<Kink>,
    /// One-sided derivatives where kinks were flagged (DDM).
    pub one_sided: Option<OneSided>,
    /// Finite differences, per parameter: a rerun behind this value needed sub-increments
    /// (cutbacks) the nominal run did not take, at or before this increment. The incremental
    /// solution of a path-dependent problem depends on the step sequence, so the difference
    /// then carries that change (of the order of the discretisation error) divided by the
    /// perturbation. Empty for the in-line methods.
    pub rerun_substeps: Vec<bool>,
    /// SDM and FDM, `[r][p]` like `derivatives`: the difference behind this value kept fewer than
    /// [`ROUNDOFF_DIGITS`] significant digits above its noise (machine precision times the
    /// size of the cancelling terms for SDM, the Newton tolerance for FDM's reruns): the
    /// value is round-off dominated and a larger beta should be used.
    pub roundoff: Vec<Vec<bool>>,
    /// `dz/db` for every parameter (only when requested).
    #[serde(skip)]
    pub state_derivative: Option<Vec<Vec<f64>>>,
}

/// Work done by a sensitivity computation.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SensitivityCost {
    /// Wall time of the method's own work, seconds: the in-line engine's time after each
    /// increment (SDM, DDM), or the sum of the reruns' times (FDM; they may run in parallel).
    pub wall_seconds: f64,
    /// Residual evaluations beyond the primal run's: SDM's perturbed and nominal ones, DDM's
    /// dual ones (two per parameter and increment), the updates after the solve, and the
    /// assemblies of forced tangents (one-sided derivatives).
    pub residual_evaluations: usize,
    /// Of those, the pseudo-loads evaluated over only the elements a parameter reaches (SDM's
    /// unbalance and its nominal, DDM's derivative part: contact and the elements with a
    /// history derivative for a friction parameter, ...).
    pub partial_evaluations: usize,
    /// Factorizations beyond Newton's (the converged tangent, forced branches).
    pub factorizations: usize,
    /// Solves with the converged or a forced tangent done by GMRES instead of a
    /// factorization (`Settings::krylov`); their solve columns are in `solve_columns`.
    pub krylov_solves: usize,
    /// GMRES steps over all `krylov_solves`.
    pub krylov_iterations: usize,
    /// Right-hand-side columns solved (refinement steps included).
    pub solve_columns: usize,
    /// Complete primal reruns (FDM).
    pub primal_reruns: usize,
    /// Of the wall time: residual evaluations (perturbed, nominal, dual, the updates of the
    /// history and the responses after the solve, forced tangents).
    pub evaluation_seconds: f64,
    /// Of the wall time: numeric factorizations.
    pub factor_seconds: f64,
    /// Of the wall time: triangular solves (refinement steps included).
    pub solve_seconds: f64,
    /// The floor of one parameter (`Settings::probe_floor`), not part of the wall time: at
    /// every increment, one f64 residual evaluation over all elements at the converged state
    /// and one single-column solve with Newton's last factorization (none at an increment
    /// Newton did not factor), timed together. The in-line sweep takes it out of the primal
    /// run's time as well.
    pub floor_seconds: f64,
}

impl SensitivityCost {
    /// The wall time outside evaluations, factorizations and solves (building designs and
    /// masks, copies, kink detection, forced tangents' copies, the first symbolic analysis).
    pub fn rest_seconds(&self) -> f64 {
        self.wall_seconds - self.evaluation_seconds - self.factor_seconds - self.solve_seconds
    }
}

/// The branches of the converged state, frozen, over all elements.
fn converged_frozen<'c>(c: &'c Converged<'_>) -> Frozen<'c> {
    Frozen {
        gauss: Some(&c.eval.branches),
        contact: &c.eval.contact.choice,
        skip: None,
        ..Frozen::default()
    }
}

/// The total derivative of the unknowns for parameter `k`: the solved column of `rhs` on the
/// free unknowns, the prescribed derivative `dzc` on the constrained ones.
fn total_dz(c: &Converged<'_>, rhs: &[f64], dzc: &[f64], k: usize) -> Vec<f64> {
    let n = c.z.len();
    (0..n)
        .map(|i| {
            if c.constrained[i] {
                dzc[i]
            } else {
                rhs[k * n + i]
            }
        })
        .collect()
}

/// Relative residual the correction solves of [`refine_extended`] ask of GMRES: each step of
/// the refinement then shrinks the error by about this factor. Loose, so that the usual
/// correction is one solve with the factor at hand and one product (GMRES stops at its
/// start).
const CORRECTION_TOL: f64 = 1e-3;

/// [`refine_extended`] stops when every column's correction is below this fraction of the
/// column: three orders of magnitude below the accuracy the default DDM is tested to (1e-10
/// of each sensitivity's scale against a fresh factorization).
const REFINED_TO: f64 = 1e-13;

/// Steps of [`refine_extended`] at most (two reach working precision wherever the first
/// solve kept a few digits; a third only guards a slow correction).
const EXTENDED_REFINEMENT_STEPS: usize = 3;

/// Solves `k d = r` in place for [`refine_extended`]'s corrections, adding its work to the
/// cost.
type CorrectionSolve<'a> =
    dyn FnMut(&mut [f64], &mut SensitivityCost) -> Result<(), crate::linalg::LinalgError> + 'a;

/// Iterative refinement of the solution `x` of `k x = b` (`ncols` column-major columns) with
/// residuals in double-double arithmetic ([`crate::linalg::SparseMatrix::residual_extended`]),
/// each correction solved by `correct` (with the factor or GMRES that solved `x`), until every
/// column's correction is below [`REFINED_TO`] of the column (or
/// [`EXTENDED_REFINEMENT_STEPS`]).
///
/// Why: a backward-stable solve (a factorization, or GMRES accepted at a direct solve's
/// backward error) leaves a forward error of up to `cond(k) eps`, and two such solves (DDM
/// by GMRES and by a fresh factorization) differ by that much. Where the pseudo-load is small
/// against `|k| |x|` (a slender beam's load in `E`: relative residual 2e-9 at a backward
/// error of 0.3 eps) that was 1.7e-10 of the derivative's scale on the elastica cantilever.
/// With the residual computed to twice the working precision, refinement converges to the
/// solution rounded to working precision, whichever solve started it (Moler 1967; Higham,
/// *Accuracy and Stability of Numerical Algorithms*, section 12.1).
fn refine_extended(
    k: &crate::linalg::SparseMatrix,
    b: &[f64],
    x: &mut [f64],
    ncols: usize,
    cost: &mut SensitivityCost,
    correct: &mut CorrectionSolve<'_>,
) -> Result<(), crate::linalg::LinalgError> {
    let n = k.n();
    let norm = |v: &[f64]| v.iter().map(|a| a * a).sum::<f64>().sqrt();
    let mut r = vec![0.0; n * ncols];
    for _ in 0..EXTENDED_REFINEMENT_STEPS {
        for c in 0..ncols {
            let cols = c * n..(c + 1) * n;
            k.residual_extended(&x[cols.clone()], &b[cols.clone()], &mut r[cols])?;
        }
        correct(&mut r, cost)?;
        let mut done = true;
        for c in 0..ncols {
            let cols = c * n..(c + 1) * n;
            let (d, xc) = (norm(&r[cols.clone()]), norm(&x[cols.clone()]));
            done &= d <= REFINED_TO * xc;
            for (xi, di) in x[cols.clone()].iter_mut().zip(&r[cols]) {
                *xi += di;
            }
        }
        if done {
            break;
        }
    }
    Ok(())
}

/// Add the wall time of `f` to `slot`.
fn timed<T>(slot: &mut f64, f: impl FnOnce() -> T) -> T {
    let t = Instant::now();
    let out = f();
    *slot += t.elapsed().as_secs_f64();
    out
}

/// Everything a sensitivity run produces.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SensitivityResults {
    /// The method that produced these results.
    pub method: Option<Method>,
    /// Relative perturbation (0 or unused for DDM).
    pub beta: f64,
    /// Parameter names, in the order of the derivative columns.
    pub parameters: Vec<String>,
    /// Response names, in the order of the rows.
    pub responses: Vec<String>,
    /// Per converged increment of the nominal run.
    pub increments: Vec<IncrementSensitivity>,
    /// The method's work.
    pub cost: SensitivityCost,
    /// Cost of the nominal primal run (with the inline sensitivity work excluded).
    pub primal_seconds: f64,
    /// Why this method stopped before the end of the run (a sweep keeps the other methods
    /// going): `increments` holds what it computed before.
    pub failure: Option<String>,
}

/// The in-line engine (SDM and DDM) run as an observer of the primal solver.
pub struct Engine<'a> {
    params: &'a [Parameter],
    settings: Settings,
    keep_state_derivative: bool,
    /// `dh/db`, parameter-major: `dhist[p * n_history + i]`.
    dhist: Vec<f64>,
    exact: Option<LinearSolver>,
    /// Increment whose converged tangent `exact` holds factored (`None`: a forced tangent,
    /// or nothing yet).
    exact_holds: Option<usize>,
    /// Tangent to solve with instead of the Newton one (one-sided derivatives: the tangent of
    /// the forced branches).
    forced_tangent: Option<crate::linalg::SparseMatrix>,
    /// What the engine has computed so far.
    pub results: SensitivityResults,
}

impl<'a> Engine<'a> {
    /// An engine for `params` with `settings`, before the first increment (`dh/db = 0`; the
    /// initial history's derivative is set at the first converged increment).
    pub fn new(model: &Model, params: &'a [Parameter], settings: Settings) -> Self {
        let nh = model.dof_map().n_history;
        Engine {
            params,
            keep_state_derivative: false,
            dhist: vec![0.0; nh * params.len()],
            exact: None,
            exact_holds: None,
            forced_tangent: None,
            results: SensitivityResults {
                method: Some(settings.method),
                beta: settings.beta,
                parameters: params.iter().map(|p| p.name.clone()).collect(),
                responses: model.responses.iter().map(|r| r.name.clone()).collect(),
                ..Default::default()
            },
            settings,
        }
    }

    /// Also keep `dz/db` of every increment.
    pub fn keep_state_derivative(mut self, yes: bool) -> Self {
        self.keep_state_derivative = yes;
        self
    }

    fn overrides<S: Scalar>(&self, value: impl Fn(usize, f64) -> S) -> Vec<(DesignParam, S)> {
        let mut v = Vec::new();
        for (k, p) in self.params.iter().enumerate() {
            let s = value(k, p.value);
            for t in &p.targets {
                v.push((*t, s));
            }
        }
        v
    }

    /// `dh_0/db`: the history at t = 0 is not zero for frictional contact (each hitting
    /// node's anchor is the projection of its reference position), and a shape parameter
    /// moves it. Evaluated by dual numbers on the same routine the solver starts from.
    fn initial_history_derivative(&mut self, c: &Converged<'_>) -> Result<(), AnalysisError> {
        let nh = c.hist_prev.len();
        for k in 0..self.params.len() {
            let lifted: Lifted<Dual64> = c
                .model
                .lifted(&self.overrides(|j, v| Dual64::new(v, if j == k { 1.0 } else { 0.0 })));
            let h0 = crate::contact::assembly::initial_history(c.model, c.assembler, &lifted)
                .map_err(|e| AnalysisError::Model(e.to_string()))?;
            for (i, h) in h0.iter().enumerate().take(nh) {
                self.dhist[k * nh + i] = h.eps;
            }
        }
        Ok(())
    }

    /// Derivative of the prescribed unknowns with respect to parameter `k`.
    fn prescribed_derivative(&self, c: &Converged<'_>, k: usize, out: &mut [f64]) {
        for (i, p) in c.model.prescribed.iter().enumerate() {
            let hit = self.params[k]
                .targets
                .contains(&DesignParam::Prescribed { index: i });
            if hit {
                let a = p.amplitude.at(c.time);
                for &n in &p.nodes {
                    out[3 * n + p.component] += a;
                }
            }
        }
    }

    /// Whether flat hitting node `k` belongs to a pair with friction.
    fn friction_at(&self, c: &Converged<'_>, k: usize) -> bool {
        let l = &c.assembler.contact;
        (0..l.flat.len())
            .rev()
            .find(|p| l.flat[*p] <= k)
            .map(|p| c.model.contacts[p].friction.is_some())
            .unwrap_or(false)
    }

    /// Points sitting on a transition: yield onset, contact opening/closing, stick/slip.
    fn kinks(&self, c: &Converged<'_>) -> Vec<Kink> {
        let mut v = Vec::new();
        let tol = self.settings.kink_tol;
        // contact: normal distance relative to the largest normal force (closed) or to the
        // pair's characteristic length (open); slip ratio for friction
        let fmax = c
            .eval
            .contact
            .normal_force
            .iter()
            .fold(0.0f64, |m, f| m.max(f.abs()));
        for (k, (nd, sr)) in c.eval.contact.distance.iter().enumerate() {
            let closed = c.eval.contact.choice[k].state != ContactState::Open;
            let rel = if closed {
                c.eval.contact.normal_force[k].abs() / fmax.max(f64::MIN_POSITIVE)
            } else {
                nd.abs() / c.model.characteristic_length()
            };
            if rel < tol {
                v.push(Kink {
                    kind: "contact",
                    at: k,
                    point: 0,
                    distance: rel,
                });
            } else if closed && sr.abs() < tol {
                v.push(Kink {
                    kind: "friction",
                    at: k,
                    point: 0,
                    distance: *sr,
                });
            }
        }
        for (i, r) in c.eval.yield_ratio.iter().enumerate() {
            if *r != -1.0 && r.abs() < self.settings.kink_tol {
                v.push(Kink {
                    kind: "yield",
                    at: i / 8,
                    point: i % 8,
                    distance: *r,
                });
            }
        }
        v
    }

    /// Solve `K X = RHS` (columns stored column-major) with the chosen tangent.
    fn solve(
        &mut self,
        c: &Converged<'_>,
        rhs: &mut [f64],
        ncols: usize,
    ) -> Result<(), AnalysisError> {
        // the prescribed unknowns' identity rows, as in Newton's factored tangent
        let prescribed = |mut k: crate::linalg::SparseMatrix| {
            for (d, fixed) in c.constrained.iter().enumerate() {
                if *fixed {
                    k.set_identity_row_col(d).expect("in range");
                }
            }
            k
        };
        let converged_k = || prescribed(c.tangent.clone());
        // the last Newton factorization is the converged tangent only if it was assembled on
        // the converged branches (see `Converged::factor_matches`)
        let use_exact = self.settings.tangent == TangentChoice::Exact
            || c.last_factor.is_none()
            || !c.factor_matches
            || self.forced_tangent.is_some();
        if use_exact {
            let forced = self.forced_tangent.is_some();
            let k = match self.forced_tangent.take() {
                Some(k) => prescribed(k),
                None => converged_k(),
            };
            let cost = &mut self.results.cost;
            // the factor closest to `k` at hand: the converged tangent's (a forced tangent
            // after the converged one was factored at this increment), else Newton's last.
            // (A forced tangent that is singular, e.g. a rigid mode left by a node forced
            // open, factors as singular; GMRES may instead return one of its solutions.)
            let at_hand = if self.exact_holds == Some(c.index) {
                self.exact.as_ref()
            } else {
                c.last_factor
            };
            if let (true, Some(m)) = (self.settings.krylov, at_hand) {
                let b = rhs.to_vec();
                // an error of the solves counts as not converged: the factorization may work
                let report = timed(&mut cost.solve_seconds, || {
                    m.gmres_multi(&k, rhs, ncols, KRYLOV_TOL, KRYLOV_MAX_ITER)
                })
                .unwrap_or(crate::linalg::KrylovReport {
                    iterations: 0,
                    solve_columns: 0,
                    relative_residual: f64::NAN,
                    backward_error: f64::NAN,
                    converged: false,
                });
                if std::env::var_os("FRICSENS_TRACE").is_some() {
                    eprintln!(
                        "  sensitivity GMRES ({}): {} steps, |K x - b| / |b| = {:.2e}, backward error {:.2} eps{}",
                        if forced {
                            "forced tangent"
                        } else {
                            "converged tangent"
                        },
                        report.iterations,
                        report.relative_residual,
                        report.backward_error / f64::EPSILON,
                        if report.converged {
                            ""
                        } else {
                            ": not converged, factoring"
                        }
                    );
                }
                cost.solve_columns += report.solve_columns;
                if report.converged {
                    cost.krylov_solves += 1;
                    cost.krylov_iterations += report.iterations;
                    let mut correct = |r: &mut [f64], cost: &mut SensitivityCost| {
                        let rep = m.gmres_multi(&k, r, ncols, CORRECTION_TOL, KRYLOV_MAX_ITER)?;
                        cost.solve_columns += rep.solve_columns;
                        cost.krylov_iterations += rep.iterations;
                        Ok(())
                    };
                    let t = Instant::now();
                    refine_extended(&k, &b, rhs, ncols, cost, &mut correct)?;
                    cost.solve_seconds += t.elapsed().as_secs_f64();
                    return Ok(());
                }
                rhs.copy_from_slice(&b);
            }
            if self.exact.is_none() {
                self.exact = Some(LinearSolver::new(c.assembler.pattern.clone())?);
            }
            let s = self.exact.as_mut().expect("just created");
            self.exact_holds = None;
            timed(&mut cost.factor_seconds, || s.factor(&k))?;
            cost.factorizations += 1;
            if !forced {
                self.exact_holds = Some(c.index);
            }
            let b = rhs.to_vec();
            let s = &*s;
            let t = Instant::now();
            s.solve_multi_in_place(rhs, ncols)?;
            let mut correct = |r: &mut [f64], cost: &mut SensitivityCost| {
                cost.solve_columns += ncols;
                s.solve_multi_in_place(r, ncols)
            };
            refine_extended(&k, &b, rhs, ncols, cost, &mut correct)?;
            cost.solve_seconds += t.elapsed().as_secs_f64();
        } else {
            let last = c.last_factor.expect("checked above");
            let b = rhs.to_vec();
            let cost = &mut self.results.cost;
            timed(&mut cost.solve_seconds, || {
                last.solve_multi_in_place(rhs, ncols)
            })?;
            if self.settings.tangent == TangentChoice::Refined {
                let k = converged_k();
                timed(&mut cost.solve_seconds, || {
                    last.refine_multi(&k, &b, rhs, ncols, self.settings.refine_steps)
                })?;
                cost.solve_columns += ncols * self.settings.refine_steps;
            }
        }
        self.results.cost.solve_columns += ncols;
        Ok(())
    }

    /// DDM's pseudo-loads for all parameters. Each parameter is seeded alone in a `Dual64` (a
    /// vector dual of N parameters costs N times as much per element, or more, and would
    /// evaluate the union of the parameters' elements): its pseudo-load is evaluated over only
    /// the elements it reaches.
    fn pseudo_loads(
        &mut self,
        c: &Converged<'_>,
        frozen: &Frozen<'_>,
    ) -> Result<PseudoLoads, AnalysisError> {
        let np = self.params.len();
        let n = c.z.len();
        let nh = c.hist_prev.len();
        let mut ev = Evaluation::<Dual64>::new(c.assembler, c.model.mesh.elements.len());
        let mut out = PseudoLoads {
            rhs: vec![0.0; n * np],
            dzc: vec![vec![0.0; n]; np],
            designs: Vec::with_capacity(np),
            hists: Vec::with_capacity(np),
        };
        for k in 0..np {
            self.prescribed_derivative(c, k, &mut out.dzc[k]);
            let p = &self.params[k];
            let overrides: Vec<(DesignParam, Dual64)> = p
                .targets
                .iter()
                .map(|t| (*t, Dual64::seeded(p.value, 0)))
                .collect();
            let lifted: Lifted<Dual64> = c.model.lifted(&overrides);
            let hist = duals(c.hist_prev, &self.dhist[k * nh..(k + 1) * nh]);
            let z = duals(c.z, &out.dzc[k]);
            // the pseudo-load is the derivative part alone: the elements the parameter does
            // not reach contribute none and are left out
            let mask = frozen
                .gauss
                .and_then(|g| self.unreached(c, k, &Reach::seeded(&lifted), &out.dzc[k], g, false));
            let pseudo = Frozen {
                skip: mask.as_deref(),
                ..*frozen
            };
            self.evaluate(c, &lifted, &z, &hist, Some(&pseudo), None, &mut ev)?;
            if mask.is_some() {
                self.results.cost.partial_evaluations += 1;
            }
            for i in 0..n {
                out.rhs[k * n + i] = if c.constrained[i] {
                    0.0
                } else {
                    -ev.residual[i].eps
                };
            }
            out.designs.push(lifted);
            out.hists.push(hist);
        }
        Ok(out)
    }

    /// The pseudo-loads `base` (on the converged branches) moved to the branches `forced`:
    /// the elements whose Gauss points `forced` changes, and the contact, evaluated on both
    /// and the difference added, as for the tangent ([`Engine::forced_tangent_at`]). Without
    /// `Settings::restrict`, evaluated anew over all elements.
    fn forced_pseudo_loads(
        &mut self,
        c: &Converged<'_>,
        base: &PseudoLoads,
        forced: &Frozen<'_>,
    ) -> Result<PseudoLoads, AnalysisError> {
        let n = c.z.len();
        let converged = converged_frozen(c);
        let unchanged = match unchanged_elements(forced, &converged) {
            Some(u) if self.settings.restrict => u,
            _ => return self.pseudo_loads(c, forced),
        };
        let mut ev = Evaluation::<Dual64>::new(c.assembler, c.model.mesh.elements.len());
        let mut out = base.clone();
        for k in 0..self.params.len() {
            let z = duals(c.z, &base.dzc[k]);
            for (branches, sign) in [(forced, 1.0), (&converged, -1.0)] {
                let frozen = Frozen {
                    skip: Some(&unchanged),
                    ..*branches
                };
                let (lifted, hist) = (&base.designs[k], &base.hists[k]);
                self.evaluate(c, lifted, &z, hist, Some(&frozen), None, &mut ev)?;
                for i in (0..n).filter(|&i| !c.constrained[i]) {
                    out.rhs[k * n + i] -= sign * ev.residual[i].eps;
                }
            }
            self.results.cost.partial_evaluations += 2;
        }
        Ok(out)
    }

    /// DDM's solve and update: the pseudo-loads `p` go through one multi-column solve, then
    /// one update per parameter carries `dz/db` into the history and the responses.
    fn ddm(
        &mut self,
        c: &Converged<'_>,
        frozen: &Frozen<'_>,
        p: &PseudoLoads,
    ) -> Result<Step, AnalysisError> {
        let np = self.params.len();
        let nh = c.hist_prev.len();
        let nr = c.model.responses.len();
        let mut rhs = p.rhs.clone();
        self.solve(c, &mut rhs, np)?;
        // total derivatives: evaluate with z carrying dz/db. The update wants only the history
        // and the responses: elements frozen elastic keep their history and are skipped.
        let skip = frozen.gauss.map(|g| Frozen::history_unchanged(c.model, g));
        let update = Frozen {
            skip: skip.as_deref(),
            ..*frozen
        };
        let mut ev = Evaluation::<Dual64>::new(c.assembler, c.model.mesh.elements.len());
        let mut dresp = vec![vec![0.0; np]; nr];
        let mut dhist = vec![0.0; nh * np];
        let mut dz_all = Vec::with_capacity(np);
        for (k, (lifted, hist)) in p.designs.iter().zip(&p.hists).enumerate() {
            let dz = total_dz(c, &rhs, &p.dzc[k], k);
            let z = duals(c.z, &dz);
            self.evaluate(c, lifted, &z, hist, Some(&update), None, &mut ev)?;
            for (r, resp) in c.model.responses.iter().enumerate() {
                dresp[r][k] = resp.value(&ev.response_input(&z, c.assembler)).eps;
            }
            for (d, h) in dhist[k * nh..(k + 1) * nh].iter_mut().zip(&ev.hist_new) {
                *d = h.eps;
            }
            dz_all.push(dz);
        }
        Ok(Step {
            dresp,
            dhist,
            dz: dz_all,
            roundoff: Vec::new(),
        })
    }

    /// The design perturbed by `db` along parameter `k`, lifted to f64.
    fn lifted_at(&self, c: &Converged<'_>, k: usize, db: f64) -> Lifted<f64> {
        c.model
            .lifted(&self.overrides(|j, v| if j == k { v + db } else { v }))
    }

    /// f64 evaluation at the design `lifted` (perturbed by `db` along parameter `k`), with the
    /// history perturbed consistently and the unknowns moved by `db * z_shift` (the prescribed
    /// derivative for the pseudo-load, the total derivative for the update).
    #[allow(clippy::too_many_arguments)]
    fn perturbed(
        &mut self,
        c: &Converged<'_>,
        k: usize,
        db: f64,
        lifted: &Lifted<f64>,
        z_shift: &[f64],
        frozen: Option<&Frozen<'_>>,
        ev: &mut Evaluation<f64>,
    ) -> Result<(), AnalysisError> {
        let nh = c.hist_prev.len();
        let hist: Vec<f64> = (0..nh)
            .map(|i| c.hist_prev[i] + db * self.dhist[k * nh + i])
            .collect();
        let z: Vec<f64> = c.z.iter().zip(z_shift).map(|(z, s)| z + db * s).collect();
        self.evaluate(c, lifted, &z, &hist, frozen, None, ev)
    }

    /// One residual evaluation of the engine's own, at the converged increment's time: timed
    /// and counted in the cost ledger.
    #[allow(clippy::too_many_arguments)]
    fn evaluate<S: Scalar>(
        &mut self,
        c: &Converged<'_>,
        lifted: &Lifted<S>,
        z: &[S],
        hist: &[S],
        frozen: Option<&Frozen<'_>>,
        tangent: Option<&mut crate::linalg::SparseMatrix>,
        ev: &mut Evaluation<S>,
    ) -> Result<(), AnalysisError> {
        let cost = &mut self.results.cost;
        timed(&mut cost.evaluation_seconds, || {
            c.assembler
                .evaluate(c.model, lifted, z, hist, c.time, frozen, tangent, ev)
        })?;
        cost.residual_evaluations += 1;
        Ok(())
    }

    /// The elements a perturbation of parameter `k` does not reach at the fixed state, or
    /// `None` when there are none, or when `nominal` (forward SDM, which then evaluates the
    /// nominal state over the same elements) and they are fewer than half (leaving them out
    /// would not pay for that second evaluation).
    ///
    /// An element is reached when a node moves (shape), when its body's material parameter
    /// changes (unless the law says the parameter acts only on the plastic branch and all its
    /// points are `gauss`-frozen elastic), when a prescribed unknown of it moves (`dzc`), or
    /// when its history carries a derivative. Contact and loads are always evaluated.
    fn unreached(
        &self,
        c: &Converged<'_>,
        k: usize,
        reach: &Reach,
        dzc: &[f64],
        gauss: &[Branch],
        nominal: bool,
    ) -> Option<Vec<bool>> {
        if !self.settings.restrict {
            return None;
        }
        let model = c.model;
        let nh = c.hist_prev.len();
        let dofs = &c.assembler.dofs;
        let mask: Vec<bool> = (0..model.mesh.elements.len())
            .map(|e| {
                let b = dofs.element_body[e];
                let Some(body) = model.bodies.get(b) else {
                    return false;
                };
                let elastic = gauss[8 * e..8 * e + 8]
                    .iter()
                    .all(|g| *g == Branch::Elastic);
                let material_unchanged =
                    reach.material[b].iter().enumerate().all(|(i, changed)| {
                        !changed || (elastic && !body.material.enters_elastic_branch(i))
                    });
                let h0 = dofs.history_offset[e];
                let nh8 = 8 * body.material.history_len();
                material_unchanged
                    && !model.mesh.elements[e].iter().any(|&n| reach.moved[n])
                    && c.assembler.element_dofs(e).iter().all(|&i| dzc[i] == 0.0)
                    && self.dhist[k * nh + h0..k * nh + h0 + nh8]
                        .iter()
                        .all(|v| *v == 0.0)
            })
            .collect();
        let unreached = mask.iter().filter(|m| **m).count();
        let pays = if nominal {
            2 * unreached > mask.len()
        } else {
            unreached > 0
        };
        pays.then_some(mask)
    }

    /// Time the floor of one parameter at this increment: one f64 residual evaluation over all
    /// elements at the converged state, with its branches frozen, and one single-column solve
    /// with Newton's last factorization (none where Newton did not factor).
    fn probe_floor(&mut self, c: &Converged<'_>) -> Result<(), AnalysisError> {
        let t = Instant::now();
        let frozen = converged_frozen(c);
        let mut ev = Evaluation::<f64>::new(c.assembler, c.model.mesh.elements.len());
        c.assembler.evaluate(
            c.model,
            c.lifted,
            c.z,
            c.hist_prev,
            c.time,
            Some(&frozen),
            None,
            &mut ev,
        )?;
        if let Some(f) = c.last_factor {
            f.solve_in_place(&mut ev.residual)?;
        }
        self.results.cost.floor_seconds += t.elapsed().as_secs_f64();
        Ok(())
    }

    /// The tangent at the converged state on the branches `forced`: the converged tangent with
    /// the elements whose Gauss points `forced` puts on other branches evaluated again, their
    /// converged blocks taken out and their forced ones put in. Contact and the loads enter
    /// both of these evaluations, so forced contact states are taken in the same way. A
    /// flagged increment has a few such elements (5 and 13 of 138 on the two sides of the
    /// leaf spring's last one): two evaluations over them cost a fraction of an assembly.
    /// Without `Settings::restrict` (or with free branches), one assembly over all elements.
    fn forced_tangent_at(
        &mut self,
        c: &Converged<'_>,
        forced: &Frozen<'_>,
    ) -> Result<crate::linalg::SparseMatrix, AnalysisError> {
        let ne = c.model.mesh.elements.len();
        let converged = converged_frozen(c);
        let mut k = c.tangent.clone();
        let mut ev = Evaluation::<f64>::new(c.assembler, ne);
        let unchanged = match unchanged_elements(forced, &converged) {
            Some(u) if self.settings.restrict => u,
            // over all elements
            _ => {
                let (lifted, z, hist) = (c.lifted, c.z, c.hist_prev);
                self.evaluate(c, lifted, z, hist, Some(forced), Some(&mut k), &mut ev)?;
                return Ok(k);
            }
        };
        let mut part = crate::linalg::SparseMatrix::new(c.assembler.pattern.clone());
        for (branches, sign) in [(forced, 1.0), (&converged, -1.0)] {
            let frozen = Frozen {
                skip: Some(&unchanged),
                ..*branches
            };
            self.evaluate(
                c,
                c.lifted,
                c.z,
                c.hist_prev,
                Some(&frozen),
                Some(&mut part),
                &mut ev,
            )?;
            for (kv, pv) in k.values_mut().iter_mut().zip(part.values()) {
                *kv += sign * pv;
            }
        }
        Ok(k)
    }

    /// SDM (forward or central) for all parameters.
    fn sdm(&mut self, c: &Converged<'_>, central: bool) -> Result<Step, AnalysisError> {
        let np = self.params.len();
        let n = c.z.len();
        let nh = c.hist_prev.len();
        let ne = c.model.mesh.elements.len();
        let converged = converged_frozen(c);
        let frozen = if self.settings.freeze_branches {
            Some(&converged)
        } else {
            None
        };
        let mut ev_p = Evaluation::<f64>::new(c.assembler, ne);
        let mut ev_m = Evaluation::<f64>::new(c.assembler, ne);
        // the nominal state evaluated over the elements a parameter reaches (forward SDM,
        // where the others are left out)
        let mut ev_0 = Evaluation::<f64>::new(c.assembler, ne);
        let mut rhs = vec![0.0; n * np];
        let mut dzc = vec![vec![0.0; n]; np];
        // round-off: the unbalance against the forces that cancel in it (the reference force
        // of Newton's criterion), each response difference against the response
        let nr = c.model.responses.len();
        let mut roundoff = vec![vec![false; np]; nr];
        // relative noise of each unbalance (eps times the forces that cancel in it, the
        // reference force of Newton's criterion), and each response's explicit derivative
        // (design perturbed, state fixed): the noise reaches a response only through dz
        let mut unbalance_noise = vec![0.0; np];
        let mut explicit = vec![vec![0.0; np]; nr];
        // the perturbed designs (+db, and -db for central), built once for both evaluations
        let mut designs: Vec<(Lifted<f64>, Option<Lifted<f64>>)> = Vec::with_capacity(np);
        for k in 0..np {
            self.prescribed_derivative(c, k, &mut dzc[k]);
            let db = self.params[k].step(self.settings.beta);
            designs.push((
                self.lifted_at(c, k, db),
                central.then(|| self.lifted_at(c, k, -db)),
            ));
            let (lifted_p, lifted_m) = &designs[k];
            // Leave out the elements the perturbation does not reach: their residual is the
            // same in both evaluations of the difference, so it cancels exactly (and its
            // round-off with it). Friction and contact-stiffness parameters then evaluate the
            // contact and the elements with a history derivative; yield and hardening the
            // elements with plastic points.
            let mask = frozen.and_then(|f| f.gauss).and_then(|g| {
                let reach = Reach::between(lifted_p, c.lifted);
                self.unreached(c, k, &reach, &dzc[k], g, !central)
            });
            let restricted = frozen.zip(mask.as_deref()).map(|(f, m)| Frozen {
                skip: Some(m),
                ..*f
            });
            let pseudo = restricted.as_ref().or(frozen);
            self.perturbed(c, k, db, lifted_p, &dzc[k], pseudo, &mut ev_p)?;
            if let Some(lifted_m) = lifted_m {
                self.perturbed(c, k, -db, lifted_m, &dzc[k], pseudo, &mut ev_m)?;
            }
            // the residual at b: the converged one, or the nominal state over the same elements
            let nominal = match &restricted {
                Some(r) if !central => {
                    self.evaluate(c, c.lifted, c.z, c.hist_prev, Some(r), None, &mut ev_0)?;
                    &ev_0
                }
                _ => c.eval,
            };
            if restricted.is_some() {
                self.results.cost.partial_evaluations += 2;
            }
            for (r, resp) in c.model.responses.iter().enumerate() {
                let vp = resp.value(&ev_p.response_input(c.z, c.assembler));
                explicit[r][k] = if central {
                    (vp - resp.value(&ev_m.response_input(c.z, c.assembler))) / (2.0 * db)
                } else {
                    (vp - resp.value(&nominal.response_input(c.z, c.assembler))) / db
                };
            }
            for i in 0..n {
                if c.constrained[i] {
                    continue;
                }
                // forward: R(b) = c.eval.residual (the converged residual, no extra evaluation)
                let d = if central {
                    (ev_p.residual[i] - ev_m.residual[i]) / (2.0 * db)
                } else {
                    (ev_p.residual[i] - nominal.residual[i]) / db
                };
                rhs[k * n + i] = -d;
            }
            let db_eff = if central { 2.0 * db } else { db };
            let unbalance = (0..n)
                .map(|i| (rhs[k * n + i] * db_eff).powi(2))
                .sum::<f64>()
                .sqrt();
            if unbalance != 0.0 {
                unbalance_noise[k] = f64::EPSILON * c.record.reference_force / unbalance;
            }
            // the perturbed parameter itself lost its digits (b + db keeps fewer than
            // ROUNDOFF_DIGITS digits of db)
            if roundoff_dominated(db, self.params[k].value, f64::EPSILON) {
                for row in roundoff.iter_mut() {
                    row[k] = true;
                }
            }
        }
        self.solve(c, &mut rhs, np)?;
        let mut dresp = vec![vec![0.0; np]; nr];
        let mut dhist = vec![0.0; nh * np];
        let mut dz_all = Vec::with_capacity(np);
        // the updates below want only the history and the responses: elements frozen elastic
        // keep their history and are skipped (free branches: nothing is skipped)
        let skip = frozen
            .and_then(|f| f.gauss)
            .map(|g| Frozen::history_unchanged(c.model, g));
        let update = frozen.map(|f| Frozen {
            skip: skip.as_deref(),
            ..*f
        });
        let frozen = update.as_ref();
        for k in 0..np {
            let dz = total_dz(c, &rhs, &dzc[k], k);
            let db = self.params[k].step(self.settings.beta);
            let (lifted_p, lifted_m) = &designs[k];
            self.perturbed(c, k, db, lifted_p, &dz, frozen, &mut ev_p)?;
            let zp: Vec<f64> = (0..n).map(|i| c.z[i] + db * dz[i]).collect();
            if let Some(lifted_m) = lifted_m {
                self.perturbed(c, k, -db, lifted_m, &dz, frozen, &mut ev_m)?;
                let zm: Vec<f64> = (0..n).map(|i| c.z[i] - db * dz[i]).collect();
                for (r, resp) in c.model.responses.iter().enumerate() {
                    let vp = resp.value(&ev_p.response_input(&zp, c.assembler));
                    let vm = resp.value(&ev_m.response_input(&zm, c.assembler));
                    dresp[r][k] = (vp - vm) / (2.0 * db);
                    roundoff[r][k] |= vp != vm && roundoff_dominated(vp - vm, vp, f64::EPSILON);
                }
                for i in 0..nh {
                    dhist[k * nh + i] = (ev_p.hist_new[i] - ev_m.hist_new[i]) / (2.0 * db);
                }
            } else {
                for (r, resp) in c.model.responses.iter().enumerate() {
                    let vp = resp.value(&ev_p.response_input(&zp, c.assembler));
                    let v0 = resp.value(&c.eval.response_input(c.z, c.assembler));
                    dresp[r][k] = (vp - v0) / db;
                    roundoff[r][k] |= vp != v0 && roundoff_dominated(vp - v0, v0, f64::EPSILON);
                }
                for i in 0..nh {
                    dhist[k * nh + i] = (ev_p.hist_new[i] - c.eval.hist_new[i]) / db;
                }
            }
            dz_all.push(dz);
        }
        // the unbalance's noise carried through dz into each response: flag where it exceeds
        // 10^-ROUNDOFF_DIGITS of the derivative
        for r in 0..nr {
            for k in 0..np {
                let implicit = dresp[r][k] - explicit[r][k];
                roundoff[r][k] |= dresp[r][k] != 0.0
                    && implicit.abs() * unbalance_noise[k]
                        > 10f64.powf(-ROUNDOFF_DIGITS) * dresp[r][k].abs();
            }
        }
        Ok(Step {
            dresp,
            dhist,
            dz: dz_all,
            roundoff,
        })
    }
}

impl Observer for Engine<'_> {
    fn converged(&mut self, c: &Converged<'_>) -> Result<(), AnalysisError> {
        if self.settings.probe_floor {
            self.probe_floor(c)?;
        }
        let t0 = Instant::now();
        if self.results.increments.is_empty() && !c.model.contacts.is_empty() {
            self.initial_history_derivative(c)?;
        }
        let kinks = self.kinks(c);
        // DDM's pseudo-loads on the converged branches, which the one-sided derivatives move
        let mut pseudo = None;
        let Step {
            dresp,
            dhist,
            dz,
            roundoff,
        } =
            match self.settings.method {
                Method::Ddm => {
                    let frozen = converged_frozen(c);
                    let p = self.pseudo_loads(c, &frozen)?;
                    let step = self.ddm(c, &frozen, &p)?;
                    pseudo = Some(p);
                    step
                }
                Method::Sdm => self.sdm(c, false)?,
                Method::SdmCentral => self.sdm(c, true)?,
                Method::Fdm | Method::FdmCentral => return Err(AnalysisError::Sensitivity(
                    "finite differences of reruns are not an in-line method (use run_sensitivity)"
                        .into(),
                )),
            };
        // one-sided derivatives at flagged points (DDM): force the flagged points on each branch
        let one_sided = if !kinks.is_empty() && self.settings.method == Method::Ddm {
            // whether the derivative just computed solved with the converged tangent (the
            // forced tangent of the side the converged state is on)
            let exact_solve = self.settings.tangent == TangentChoice::Exact
                || c.last_factor.is_none()
                || !c.factor_matches;
            let mut sides = Vec::new();
            for side in [0, 1] {
                let mut gauss = c.eval.branches.clone();
                let mut contact: Vec<ContactChoice> = c.eval.contact.choice.clone();
                for k in &kinks {
                    match k.kind {
                        "yield" => {
                            gauss[8 * k.at + k.point] = [Branch::Elastic, Branch::Plastic][side];
                        }
                        "friction" => {
                            contact[k.at].state = [ContactState::Stick, ContactState::Slip][side];
                        }
                        _ => {
                            let closed = if c.eval.contact.choice[k.at].state == ContactState::Open
                            {
                                // closing: stick is the state a node enters
                                if self.friction_at(c, k.at) {
                                    ContactState::Stick
                                } else {
                                    ContactState::Closed
                                }
                            } else {
                                c.eval.contact.choice[k.at].state
                            };
                            contact[k.at].state = [ContactState::Open, closed][side];
                        }
                    }
                }
                if exact_solve && gauss == c.eval.branches && contact == c.eval.contact.choice {
                    // the converged state is on this side of every flagged point, and the
                    // derivative just computed solved with its tangent: that derivative is
                    // this side's
                    sides.push(dresp.clone());
                    continue;
                }
                let frozen = Frozen {
                    gauss: Some(&gauss),
                    contact: &contact,
                    skip: None,
                    ..Frozen::default()
                };
                self.forced_tangent = Some(self.forced_tangent_at(c, &frozen)?);
                let base = pseudo.as_ref().expect("DDM keeps its pseudo-loads");
                let p = self.forced_pseudo_loads(c, base, &frozen)?;
                sides.push(self.ddm(c, &frozen, &p)?.dresp);
            }
            let upper = sides.pop().expect("two sides");
            let lower = sides.pop().expect("two sides");
            Some(OneSided { lower, upper })
        } else {
            None
        };
        self.dhist = dhist;
        let values = c
            .model
            .responses
            .iter()
            .map(|r| r.value(&c.eval.response_input(c.z, c.assembler)))
            .collect();
        self.results.increments.push(IncrementSensitivity {
            increment: c.index,
            time: c.time,
            values,
            derivatives: dresp,
            kinks,
            one_sided,
            rerun_substeps: Vec::new(),
            roundoff,
            state_derivative: if self.keep_state_derivative {
                Some(dz)
            } else {
                None
            },
        });
        self.results.cost.wall_seconds += t0.elapsed().as_secs_f64();
        Ok(())
    }
}

/// What a design perturbation changes in the model an element sees: which nodes move and
/// which material parameters of each body change.
struct Reach {
    moved: Vec<bool>,
    material: Vec<Vec<bool>>,
}

impl Reach {
    /// The changes from design `base` to design `other` (SDM's finite perturbation).
    fn between(other: &Lifted<f64>, base: &Lifted<f64>) -> Self {
        Reach {
            moved: other
                .coords
                .iter()
                .zip(&base.coords)
                .map(|(a, b)| a != b)
                .collect(),
            material: other
                .material
                .iter()
                .zip(&base.material)
                .map(|(p, q)| p.iter().zip(q).map(|(a, b)| a != b).collect())
                .collect(),
        }
    }

    /// The quantities of a seeded design with a nonzero derivative (DDM).
    fn seeded(lifted: &Lifted<Dual64>) -> Self {
        let carries = |x: &Dual64| x.eps != 0.0;
        Reach {
            moved: lifted
                .coords
                .iter()
                .map(|x| x.iter().any(carries))
                .collect(),
            material: lifted
                .material
                .iter()
                .map(|p| p.iter().map(carries).collect())
                .collect(),
        }
    }
}

/// Dual numbers with real parts `re` and derivative parts `eps`.
fn duals(re: &[f64], eps: &[f64]) -> Vec<Dual64> {
    re.iter()
        .zip(eps)
        .map(|(r, e)| Dual64::new(*r, *e))
        .collect()
}

/// Run the primal analysis with in-line SDM or DDM, or the reruns of FDM.
pub fn run_sensitivity(
    model: &Model,
    params: &[Parameter],
    settings: &Settings,
) -> Result<(Results, SensitivityResults), AnalysisError> {
    let (res, mut out) = if settings.method.is_inline() {
        let (res, out, mut errors) = inline_sweep(model, params, std::slice::from_ref(settings))?;
        if let Some(e) = errors.pop().flatten() {
            return Err(e);
        }
        (res, out)
    } else {
        let central = settings.method == Method::FdmCentral;
        run_fdm_sweep(model, params, &[settings.beta], central)?
    };
    // the sweep of one beta gives [forward] or [forward, central]: the requested one is last
    let s = out.pop().expect("one result per setting");
    if let Some(why) = &s.failure {
        return Err(AnalysisError::Sensitivity(why.clone()));
    }
    Ok((res, s))
}

/// Primal run of a model with parameter `k` set to `b_0 + db`.
fn rerun(model: &Model, p: &Parameter, db: f64) -> Result<Results, AnalysisError> {
    let mut m = model.clone();
    for t in &p.targets {
        m.set_param(*t, p.value + db);
    }
    let mut solver = Solver::new(&m)?;
    solver.run(&RunOptions::default(), &mut NoObserver)
}

/// Response values at the nominal increment times of a run (cutback sub-increments skipped).
fn responses_at(
    model: &Model,
    res: &Results,
    times: &[f64],
) -> Result<Vec<Vec<f64>>, AnalysisError> {
    let mut out = Vec::with_capacity(times.len());
    for t in times {
        let k = res.increment_at(*t).ok_or_else(|| {
            AnalysisError::Sensitivity(format!("rerun has no increment at t = {t}"))
        })?;
        out.push(
            (0..model.responses.len())
                .map(|r| res.response_value(model, r, k))
                .collect(),
        );
    }
    Ok(out)
}

/// Several in-line engines observing one primal run. An engine that fails (e.g. an SDM
/// perturbation so large that the perturbed geometry is degenerate) is stopped and its error
/// kept; the primal run and the other engines go on.
struct Engines<'a> {
    engines: Vec<Engine<'a>>,
    errors: Vec<Option<AnalysisError>>,
}

impl Observer for Engines<'_> {
    fn converged(&mut self, c: &Converged<'_>) -> Result<(), AnalysisError> {
        for (e, err) in self.engines.iter_mut().zip(&mut self.errors) {
            if err.is_none() {
                if let Err(x) = e.converged(c) {
                    e.results.failure =
                        Some(format!("increment {} (t = {}): {x}", c.index, c.time));
                    *err = Some(x);
                }
            }
        }
        Ok(())
    }
}

/// In-line methods (SDM, SDM central, DDM) at several settings — a perturbation sweep — on
/// one primal run: each engine does its own work after every converged increment and keeps
/// its own cost; `primal_seconds` of every result is the primal run alone.
pub fn run_inline_sweep(
    model: &Model,
    params: &[Parameter],
    settings: &[Settings],
) -> Result<(Results, Vec<SensitivityResults>), AnalysisError> {
    if let Some(s) = settings.iter().find(|s| !s.method.is_inline()) {
        return Err(AnalysisError::Sensitivity(format!(
            "{} is not an in-line method",
            s.method.name()
        )));
    }
    let (res, out, _) = inline_sweep(model, params, settings)?;
    Ok((res, out))
}

/// [`run_inline_sweep`] with each engine's error, if it failed.
#[allow(clippy::type_complexity)]
fn inline_sweep(
    model: &Model,
    params: &[Parameter],
    settings: &[Settings],
) -> Result<(Results, Vec<SensitivityResults>, Vec<Option<AnalysisError>>), AnalysisError> {
    let mut engines = Engines {
        engines: settings
            .iter()
            .map(|s| Engine::new(model, params, s.clone()))
            .collect(),
        errors: settings.iter().map(|_| None).collect(),
    };
    let mut solver = Solver::new(model)?;
    let res = solver.run(&RunOptions::default(), &mut engines)?;
    // the engines' own work and their floor probes are not the primal run's
    let inline: f64 = engines
        .engines
        .iter()
        .map(|e| e.results.cost.wall_seconds + e.results.cost.floor_seconds)
        .sum();
    let out = engines
        .engines
        .into_iter()
        .map(|e| {
            let mut s = e.results;
            s.primal_seconds = res.cost.wall_seconds - inline;
            s
        })
        .collect();
    Ok((res, out, engines.errors))
}

/// Finite differences at several perturbation sizes from one nominal run: the reruns at
/// `b + db` serve forward and central differences, those at `b - db` central ones; they run
/// in parallel. Returns `[forward, central]` per beta when `central` is set, else forward only.
/// A rerun that fails fails only the differences that need it: their `failure` says why.
pub fn run_fdm_sweep(
    model: &Model,
    params: &[Parameter],
    betas: &[f64],
    central: bool,
) -> Result<(Results, Vec<SensitivityResults>), AnalysisError> {
    use rayon::prelude::*;
    let t0 = Instant::now();
    let mut solver = Solver::new(model)?;
    let nominal = solver.run(&RunOptions::default(), &mut NoObserver)?;
    let primal_seconds = t0.elapsed().as_secs_f64();
    let times: Vec<f64> = nominal.times[1..].to_vec();
    let base = responses_at(model, &nominal, &times)?;
    // the reruns follow the nominal run's increments, cut-back ones included, so that every
    // difference is taken between states of the same load level
    let mut model = model.clone();
    model.times = times.clone();
    let model = &model;
    let signs: &[f64] = if central { &[1.0, -1.0] } else { &[1.0] };
    let jobs: Vec<(usize, usize, f64)> = (0..betas.len())
        .flat_map(|b| (0..params.len()).flat_map(move |k| signs.iter().map(move |s| (b, k, *s))))
        .collect();
    let runs: Vec<Result<Rerun, AnalysisError>> = jobs
        .par_iter()
        .map(|&(b, k, sign)| {
            let t = Instant::now();
            let p = &params[k];
            let r = rerun(model, p, sign * p.step(betas[b]))?;
            // the first time the rerun needed a sub-increment the nominal run did not take
            let substep_from = r.times[1..]
                .iter()
                .find(|t| {
                    !times
                        .iter()
                        .any(|n| (*n - **t).abs() <= 1e-12 * n.abs().max(1.0))
                })
                .copied();
            Ok(Rerun {
                values: responses_at(model, &r, &times)?,
                seconds: t.elapsed().as_secs_f64(),
                substep_from,
            })
        })
        .collect();
    // reruns[b][k][0: plus, 1: minus]; a rerun that fails (a perturbed design that does not
    // converge, or whose geometry is degenerate) fails only the differences that need it
    let mut reruns: Vec<Vec<[RerunSlot; 2]>> = vec![vec![[None, None]; params.len()]; betas.len()];
    for (&(b, k, sign), r) in jobs.iter().zip(runs) {
        let side = usize::from(sign < 0.0);
        reruns[b][k][side] = Some(r.map_err(|e| {
            format!(
                "rerun with {} {} beta: {e}",
                params[k].name,
                ["+", "-"][side]
            )
        }));
    }
    let nr = model.responses.len();
    let np = params.len();
    let size: Vec<f64> = (0..nr)
        .map(|r| base.iter().map(|v| v[r].abs()).fold(0.0, f64::max))
        .collect();
    let mut out = Vec::new();
    for (b, &beta) in betas.iter().enumerate() {
        let variants: &[bool] = if central { &[false, true] } else { &[false] };
        for &is_central in variants {
            let mut derivs = vec![vec![vec![f64::NAN; np]; nr]; times.len()];
            let mut roundoff = vec![vec![vec![false; np]; nr]; times.len()];
            let mut substep_from = vec![f64::INFINITY; np];
            let mut failures = Vec::new();
            let mut seconds = 0.0;
            let mut count = 0;
            for (k, p) in params.iter().enumerate() {
                let db = p.step(beta);
                let sides: &[usize] = if is_central { &[0, 1] } else { &[0] };
                let mut used = Vec::new();
                for &side in sides {
                    match reruns[b][k][side].as_ref().expect("every rerun ran") {
                        Ok(r) => used.push(r),
                        Err(why) => failures.push(why.clone()),
                    }
                }
                if used.len() < sides.len() {
                    continue; // this parameter's derivatives stay NaN
                }
                for r in &used {
                    seconds += r.seconds;
                    count += 1;
                    substep_from[k] = substep_from[k].min(r.substep_from.unwrap_or(f64::INFINITY));
                }
                for i in 0..times.len() {
                    for r in 0..nr {
                        let delta = if is_central {
                            used[0].values[i][r] - used[1].values[i][r]
                        } else {
                            used[0].values[i][r] - base[i][r]
                        };
                        derivs[i][r][k] = delta / if is_central { 2.0 * db } else { db };
                        // each rerun's response is converged to the Newton tolerance relative
                        // to the response's size over the history (in practice much better:
                        // the last Newton steps are quadratic), so a difference below that
                        // tolerance itself is indistinguishable from convergence noise
                        roundoff[i][r][k] = (delta != 0.0
                            && delta.abs() < model.solver.force_tol * size[r])
                            || roundoff_dominated(db, p.value, f64::EPSILON);
                    }
                }
            }
            out.push(SensitivityResults {
                method: Some(if is_central {
                    Method::FdmCentral
                } else {
                    Method::Fdm
                }),
                beta,
                parameters: params.iter().map(|p| p.name.clone()).collect(),
                responses: model.responses.iter().map(|r| r.name.clone()).collect(),
                increments: times
                    .iter()
                    .enumerate()
                    .map(|(i, t)| IncrementSensitivity {
                        increment: i + 1,
                        time: *t,
                        values: base[i].clone(),
                        derivatives: derivs[i].clone(),
                        rerun_substeps: substep_from.iter().map(|f| *t >= *f).collect(),
                        roundoff: roundoff[i].clone(),
                        ..Default::default()
                    })
                    .collect(),
                cost: SensitivityCost {
                    wall_seconds: seconds,
                    primal_reruns: count,
                    ..Default::default()
                },
                primal_seconds,
                failure: (!failures.is_empty()).then(|| failures.join("; ")),
            });
        }
    }
    Ok((nominal, out))
}

/// A rerun of the FDM sweep once run: its responses, or why it failed.
type RerunSlot = Option<Result<Rerun, String>>;

/// One finite-difference rerun: responses at the nominal times.
#[derive(Clone)]
struct Rerun {
    values: Vec<Vec<f64>>,
    seconds: f64,
    substep_from: Option<f64>,
}
