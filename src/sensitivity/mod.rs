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
//! DDM's one-sided derivatives factor each forced tangent, as the adjoint does, whatever the
//! option: a side may be singular (nothing resists the motion it frees), which a
//! factorization reports and GMRES need not.
//!
//! ## Non-differentiable points
//! A Gauss point whose trial yield ratio lies within `kink_tol` of zero sits on the
//! elastic/plastic transition: the increment is flagged, and for DDM and the adjoint the
//! derivative is also computed with that point forced onto each branch — the one-sided
//! derivatives. The forcing is at the flagged increment alone: the history carried into it
//! is the converged branches' (DDM forwards, the adjoint's one-sided columns backwards
//! through the earlier increments on their converged branches).

use crate::model::Model;
use crate::solver::{AnalysisError, Results};

mod adjoint;
pub mod anatomy;
mod auto;
mod ddm;
mod engine;
mod fdm;
pub mod fields;
mod kinks;
pub mod rigid;
mod sdm;

pub use crate::design::{Parameter, ParameterError};
pub use auto::{CENTRAL_LADDER, FORWARD_LADDER};
use engine::*;
pub use engine::{history_unchanged, Engine};
pub use fdm::*;
pub use kinks::*;

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
    /// The adjoint method: a backward sweep over the stored increments, one transposed
    /// solve per increment for every response at once, whatever the number of parameters.
    Adjoint,
}

impl Method {
    /// All methods.
    pub const ALL: [Method; 6] = [
        Method::Sdm,
        Method::SdmCentral,
        Method::Ddm,
        Method::Fdm,
        Method::FdmCentral,
        Method::Adjoint,
    ];

    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Sdm => "sdm",
            Method::SdmCentral => "sdm-central",
            Method::Ddm => "ddm",
            Method::Fdm => "fdm",
            Method::FdmCentral => "fdm-central",
            Method::Adjoint => "adjoint",
        }
    }

    /// Whether the method needs a perturbation size.
    pub fn uses_beta(self) -> bool {
        !matches!(self, Method::Ddm | Method::Adjoint)
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
    /// At a flagged increment, DDM and the adjoint also give each side's derivative, the
    /// flagged points forced onto it ([`IncrementSensitivity::one_sided`]): DDM two more
    /// solves per flagged increment, the adjoint two more columns per response read there.
    pub one_sided: bool,
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
    /// other branches) by GMRES preconditioned with a factorization at hand instead of
    /// factoring it: Newton's last factor differs from the converged tangent by Newton's last
    /// correction and a few switched branches, so GMRES converges in a few solves. A
    /// factorization is the fallback when GMRES does not reach [`KRYLOV_TOL`] (or a direct
    /// solve's backward error) in [`KRYLOV_MAX_ITER`] steps, and the only way when this is
    /// off. A forced tangent (DDM's one-sided derivatives: the flagged points forced onto one
    /// branch) is factored either way: it may be singular, which GMRES need not report.
    pub krylov: bool,
    /// SDM and SDM central: split the error against DDM at every increment into the terms
    /// of the residual, the response's own difference and what the history carries in
    /// ([`anatomy`]; `SensitivityResults::anatomy`). Its work is timed apart
    /// (`SensitivityCost::anatomy_seconds`) and kept out of the method's cost. Only at a fixed
    /// `beta` with `freeze_branches` (what the anatomy differences against) and plain SDM:
    /// ignored with `beta_auto`, free branches or `rigid_modes`.
    pub explain: bool,
    /// SDM and SDM central: choose each parameter's step at every increment from a ladder of
    /// probes at the fixed state instead of `beta`, and give every derivative an error bar
    /// (`auto` module docs; `IncrementSensitivity::betas`, `error_bars`). FDM and FDM
    /// central: the same rule on reruns at every step of a ladder ([`fdm_auto`]'s docs).
    pub beta_auto: bool,
    /// Keep the derivatives of the state's fields (displacement, contact forces and
    /// pressures, stress, equivalent plastic strain) at every increment
    /// (`SensitivityResults::fields`; the [`fields`] module says how each method takes them).
    /// Their work is timed apart (`SensitivityCost::fields_seconds`).
    pub fields: bool,
    /// The adjoint's functionals: every response at the increments ending at these times
    /// (an increment's time to 1e-9); empty: at every increment. Each (response, increment)
    /// is one column of the backward sweep, and the sweep starts from the latest one: the
    /// adjoint pays for the functionals asked for, not for the parameters.
    pub adjoint_at: Vec<f64>,
    /// The adjoint's checkpoints: keep the solver's state at the end of every
    /// `adjoint_checkpoint`-th user increment instead of every converged increment's, and
    /// recompute each segment between two of them from the first when the backward sweep
    /// reaches it (bit for bit the forward run's states); 0: keep every increment.
    pub adjoint_checkpoint: usize,
    /// The adjoint's local derivatives (of each element's and hitting node's outputs in its
    /// unknowns and history): `Some(true)` in reverse mode ([`crate::scalar::Rev`]: one
    /// recording, then one sweep per column of the backward sweep), `Some(false)` by
    /// forward duals (one evaluation per 8 inputs, every column at once); `None` (the
    /// default) whichever costs less for the columns alive at the increment.
    pub adjoint_reverse: Option<bool>,
    /// The adjoint with [`TangentChoice::Exact`]: the transposed solves by block GMRES
    /// preconditioned with Newton's last factorization of each increment, which the forward
    /// run then keeps (DDM's default solve, transposed), instead of a factorization per
    /// increment. Off by default: on the leaf spring it is slower than factoring (one
    /// response, the sweep 0.187 s against 0.144 s, median of 5 in turns; the factorizations
    /// run beside the recordings, GMRES cannot) and keeps 2.6 times the memory (123 MiB
    /// against 47); it pays where a factorization costs many solves.
    pub adjoint_krylov: bool,
    /// SDM and SDM central, shape parameters: the refined SDM, which differentiates the
    /// rigid-body part of every node's motion exactly and differences only the rest (the
    /// [`rigid`] module docs): its truncation no longer grows with mesh refinement under
    /// large element rotations. Costs one product with the converged tangent per moving
    /// parameter and increment.
    pub rigid_modes: bool,
    /// Seconds of wall time the primal analysis may take (the forward run of the in-line
    /// methods and of the adjoint, FDM's nominal run and each of its reruns), checked at
    /// every Newton iteration ([`RunOptions::time_limit`](crate::solver::RunOptions)): past
    /// it the run stops with [`AnalysisError::TimeLimit`] (an FDM rerun fails its own
    /// differences alone). The clock runs from the primal's start and counts the work done
    /// beside it: the in-line methods' after each converged increment, and the adjoint's
    /// recordings for its sweep; the adjoint's backward sweep (and its recomputation of
    /// checkpointed segments) comes after the forward run and is not limited. An in-line
    /// sweep of several settings runs one primal with the shortest of their limits.
    /// `None` (the default): no limit.
    pub time_limit: Option<f64>,
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
            one_sided: true,
            restrict: true,
            probe_floor: false,
            krylov: true,
            explain: false,
            beta_auto: false,
            fields: false,
            adjoint_at: Vec::new(),
            adjoint_checkpoint: 0,
            adjoint_reverse: None,
            adjoint_krylov: false,
            rigid_modes: false,
            time_limit: None,
        }
    }
}

/// Sensitivities at one converged increment.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
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
    /// One-sided derivatives where kinks were flagged (DDM, and the adjoint at the increments
    /// it reads).
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
    /// `--beta auto`: the relative step chosen per parameter for the responses (SDM's history
    /// derivative may come from a smaller one, not recorded here).
    pub betas: Vec<f64>,
    /// `--beta auto`, `[r][p]` like `derivatives`: the error bar of each derivative
    /// ([`IncrementSensitivity::bar_bounds`]).
    pub error_bars: Vec<Vec<f64>>,
    /// `dz/db` for every parameter (only when requested).
    #[serde(skip)]
    pub state_derivative: Option<Vec<Vec<f64>>>,
}

impl IncrementSensitivity {
    /// `--beta auto`: whether derivative `[r][p]`'s error bar bounds an `error`. An infinite
    /// bar (a probe or rerun that failed) bounds nothing worth saying, and no bar bounds
    /// nothing.
    pub fn bar_bounds(&self, r: usize, p: usize, error: f64) -> bool {
        (self.error_bars.get(r).and_then(|row| row.get(p)))
            .is_some_and(|b| b.is_finite() && *b >= error)
    }
}

/// Work done by a sensitivity computation.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
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
    /// history derivative for a friction parameter, ...). The adjoint counts here its local
    /// derivatives' evaluations: its forward passes and its reverse-mode recordings (one per
    /// element, colour of hitting nodes or pushed target), which are no residual evaluations.
    pub partial_evaluations: usize,
    /// Factorizations beyond Newton's (the converged tangent, forced branches).
    pub factorizations: usize,
    /// Solves with the converged tangent done by GMRES instead of a factorization
    /// (`Settings::krylov`; a forced tangent is always factored); their solve columns are in
    /// `solve_columns`.
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
    /// Of the wall time, counted twice above: work done at the same time as other work (the
    /// adjoint's factorizations beside its recordings, its design derivatives beside its
    /// solves: in `evaluation_seconds` and in `factor_seconds` or `solve_seconds`).
    pub overlap_seconds: f64,
    /// The floor of one parameter (`Settings::probe_floor`), not part of the wall time: at
    /// every increment, one f64 residual evaluation over all elements at the converged state
    /// and one single-column solve with Newton's last factorization (none at an increment
    /// Newton did not factor), timed together. The in-line sweep takes it out of the primal
    /// run's time as well.
    pub floor_seconds: f64,
    /// The error anatomy's work (`Settings::explain`), not part of the wall time or the
    /// counts above.
    pub anatomy_seconds: f64,
    /// The field derivatives' work (`Settings::fields`), not part of the wall time or the
    /// counts above (FDM: the reruns' field evaluations are in their rerun times).
    pub fields_seconds: f64,
    /// The adjoint's stored forward states, bytes (unknowns, committed history, branches and
    /// contact choices of every converged increment): what the backward sweep keeps. With
    /// checkpoints, the largest segment's states at any one time and every resume point.
    pub stored_bytes: usize,
    /// The adjoint's checkpoints (resume points kept by the forward run).
    pub checkpoints: usize,
    /// Converged increments the adjoint solved again from its checkpoints.
    pub recomputed_increments: usize,
    /// Wall time of those recomputations (part of the wall time).
    pub recompute_seconds: f64,
}

impl SensitivityCost {
    /// The wall time outside evaluations, factorizations and solves (building designs and
    /// masks, copies, kink detection, forced tangents' copies, the first symbolic analysis).
    pub fn rest_seconds(&self) -> f64 {
        self.wall_seconds - self.evaluation_seconds - self.factor_seconds - self.solve_seconds
            + self.overlap_seconds
    }
}

/// Everything a sensitivity run produces.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
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
    /// SDM's error anatomy per increment (`Settings::explain`; empty otherwise).
    pub anatomy: Vec<anatomy::IncrementAnatomy>,
    /// The derivatives of the state's fields per increment (`Settings::fields`; empty
    /// otherwise).
    #[serde(skip)]
    pub fields: Vec<fields::IncrementFields>,
}

impl SensitivityResults {
    /// The row of response `name`.
    pub fn response_index(&self, name: &str) -> Option<usize> {
        self.responses.iter().position(|r| r == name)
    }

    /// The column of parameter `name`.
    pub fn parameter_index(&self, name: &str) -> Option<usize> {
        self.parameters.iter().position(|p| p == name)
    }

    /// Response `name` at every increment (`None`: no such response).
    pub fn values(&self, response: &str) -> Option<Vec<f64>> {
        let r = self.response_index(response)?;
        Some(self.increments.iter().map(|i| i.values[r]).collect())
    }

    /// `d response / d parameter` at every increment (`None`: no such response or parameter).
    pub fn derivative(&self, response: &str, parameter: &str) -> Option<Vec<f64>> {
        let (r, p) = (
            self.response_index(response)?,
            self.parameter_index(parameter)?,
        );
        Some(
            self.increments
                .iter()
                .map(|i| i.derivatives[r][p])
                .collect(),
        )
    }

    /// The largest `|d response r / d parameter k|` over the increments, if the response is
    /// sensitive to the parameter, whose value is `b`: `|b| max|dR/db| >= 1e-9 max|R|` over
    /// the history (`|b|` at least 1). `None` for a response insensitive to it, e.g. a
    /// reaction fixed by equilibrium, whose derivative is round-off.
    pub fn sensitive_scale(&self, r: usize, k: usize, b: f64) -> Option<f64> {
        let max = |f: &dyn Fn(&IncrementSensitivity) -> f64| {
            self.increments.iter().map(f).fold(0.0f64, f64::max)
        };
        let scale = max(&|i| i.derivatives[r][k].abs());
        let size = max(&|i| i.values[r].abs());
        (scale != 0.0 && b.abs().max(1.0) * scale >= 1e-9 * size).then_some(scale)
    }

    /// The increment that ends at pseudo-time `t` (to 1e-9).
    pub fn increment_at(&self, t: f64) -> Option<&IncrementSensitivity> {
        self.increments.iter().find(|i| (i.time - t).abs() < 1e-9)
    }
}

/// Run the primal analysis with in-line SDM or DDM, or the reruns of FDM.
pub fn run_sensitivity(
    model: &Model,
    params: &[Parameter],
    settings: &Settings,
) -> Result<(Results, SensitivityResults), AnalysisError> {
    run_sensitivity_watched(model, params, settings, &mut |_| {})
}

/// [`run_sensitivity`], `watch` seeing each converged increment of the primal run (with the
/// in-line methods' work for it done; for FDM, of the nominal run before the reruns): a
/// progress display.
pub fn run_sensitivity_watched(
    model: &Model,
    params: &[Parameter],
    settings: &Settings,
    watch: &mut dyn FnMut(&crate::solver::Converged<'_>),
) -> Result<(Results, SensitivityResults), AnalysisError> {
    let (res, mut out) = if settings.method == Method::Adjoint {
        let (res, s) = adjoint::run_adjoint(model, params, settings, watch)?;
        (res, vec![s])
    } else if settings.method.is_inline() {
        let (res, out, mut errors) =
            inline_sweep(model, params, std::slice::from_ref(settings), watch)?;
        if let Some(e) = errors.pop().flatten() {
            return Err(e);
        }
        (res, out)
    } else if settings.beta_auto {
        let central = settings.method == Method::FdmCentral;
        let (res, s) = fdm_auto(model, params, central, settings.time_limit, watch)?;
        (res, vec![s])
    } else {
        let central = settings.method == Method::FdmCentral;
        fdm_sweep(
            model,
            params,
            &[settings.beta],
            central,
            settings.fields,
            settings.time_limit,
            watch,
        )?
    };
    // the sweep of one beta gives [forward] or [forward, central]: the requested one is last
    let s = out.pop().expect("one result per setting");
    if let Some(why) = &s.failure {
        return Err(SensitivityError::Failed {
            method: s.method.map_or("?", Method::name),
            reason: why.clone(),
        }
        .into());
    }
    Ok((res, s))
}

/// Why a sensitivity computation failed (carried by [`AnalysisError::Sensitivity`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SensitivityError {
    /// A finite-difference method asked of the in-line engine, or of an in-line sweep.
    #[error("{method} is not an in-line method (finite differences rerun the analysis, the adjoint sweeps back over it: use run_sensitivity)")]
    NotInline {
        /// The method's name.
        method: &'static str,
    },
    /// A rerun took other increments than the nominal run: it has none at this time.
    #[error("rerun has no increment at t = {time}")]
    NoIncrementAt {
        /// The nominal run's pseudo-time.
        time: f64,
    },
    /// A field parameter of a law with more parameters than the adjoint's field passes seed
    /// at once.
    #[error("the adjoint seeds field parameters of index below 8; got index {index}")]
    FieldIndex {
        /// The law parameter's index.
        index: usize,
    },
    /// The adjoint recomputed a segment from a checkpoint and did not retrace the forward
    /// run's increments (a solver that does not resume exactly).
    #[error("the adjoint's recomputation from the checkpoint before increment {increment} did not retrace the forward run's increments")]
    Recomputed {
        /// The first increment of the segment.
        increment: usize,
    },
    /// A method stopped; `reason` is the error that stopped it, as recorded in its results
    /// ([`SensitivityResults::failure`]).
    #[error("{method} failed: {reason}")]
    Failed {
        /// The method's name.
        method: &'static str,
        /// Why it stopped.
        reason: String,
    },
}

impl From<SensitivityError> for AnalysisError {
    fn from(e: SensitivityError) -> Self {
        AnalysisError::Sensitivity(Box::new(e))
    }
}
