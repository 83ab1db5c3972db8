//! The in-line engine: an observer of the primal solver that, after each converged increment,
//! assembles the pseudo-loads of SDM or DDM and solves them with the tangent of its choice
//! ([`super::TangentChoice`]), carrying the derivative of the history to the next increment.

use super::*;
use crate::assembly::Frozen;
use crate::contact::ContactChoice;
use crate::linalg::LinearSolver;
use crate::material::Branch;
use crate::model::{node_dof, DesignParam, DofMap, Lifted, Model};
use crate::scalar::Scalar;
use crate::solver::{AnalysisError, Converged, Observer};
use num_dual::Dual64;
use std::time::Instant;

/// What one in-line method computes at an increment.
pub(super) struct Step {
    /// `[r][p]`: total derivative of each response.
    pub(super) dresp: Vec<Vec<f64>>,
    /// `dh_n/db`, parameter-major.
    pub(super) dhist: Vec<f64>,
    /// `dz_n/db` per parameter.
    pub(super) dz: Vec<Vec<f64>>,
    /// Round-off dominated, `[r][p]` (SDM; empty for DDM).
    pub(super) roundoff: Vec<Vec<bool>>,
    /// SDM, `[r][p]`: the round-off to expect in each derivative, machine precision times
    /// the forces that cancel in the unbalance (carried through the solve) and in the
    /// response's own difference, over the step (empty for DDM).
    pub(super) noise: Vec<Vec<f64>>,
    /// SDM, per parameter: the relative round-off of the unbalance, carried into `dz` and
    /// the history update through the solve (empty for DDM).
    pub(super) unbalance_noise: Vec<f64>,
}

/// DDM's pseudo-loads at one increment, with what the update after the solve reuses.
#[derive(Clone)]
pub(super) struct PseudoLoads {
    /// `-dR/db` at fixed state, column-major per parameter (0 at prescribed unknowns).
    pub(super) rhs: Vec<f64>,
    /// Derivative of the prescribed unknowns, per parameter.
    pub(super) dzc: Vec<Vec<f64>>,
    /// The design seeded along each parameter.
    pub(super) designs: Vec<Lifted<Dual64>>,
    /// The committed history carrying its derivative, per parameter.
    pub(super) hists: Vec<Vec<Dual64>>,
}

/// Adds the derivative of the prescribed unknowns at `time` with respect to `param` to `out`.
pub(super) fn prescribed_derivative(model: &Model, param: &Parameter, time: f64, out: &mut [f64]) {
    for (i, p) in model.prescribed.iter().enumerate() {
        if param
            .targets
            .contains(&DesignParam::Prescribed { index: i })
        {
            let a = p.amplitude.at(time);
            for &n in &p.nodes {
                out[node_dof(n, p.component)] += a;
            }
        }
    }
}

/// `dh_0/db` of parameter `param`: the history at t = 0 is not zero for frictional contact
/// (each hitting node's anchor is the projection of its reference position), and a shape
/// parameter moves it. Evaluated by dual numbers on the same routine the solver starts from;
/// `None` for a parameter that moves no node and no rigid target (the anchors stay).
pub(super) fn initial_history_derivative(
    model: &Model,
    asm: &crate::assembly::Assembler,
    param: &Parameter,
) -> Result<Option<Vec<f64>>, AnalysisError> {
    let seed = Dual64::new(param.value, 1.0);
    let overrides: Vec<(DesignParam, Dual64)> = param.targets.iter().map(|t| (*t, seed)).collect();
    let lifted: Lifted<Dual64> = model.lifted(&overrides);
    let carries = |x: &Dual64| x.eps != 0.0;
    if !(lifted.coords.iter()).any(|x| x.iter().any(carries))
        && !(lifted.rigid_motion.iter()).any(|m| m.iter().any(carries))
    {
        return Ok(None);
    }
    let h0 = crate::contact::assembly::initial_history(
        model,
        &asm.contact,
        asm.dofs.n_history,
        &lifted,
    )?;
    Ok(Some(h0.iter().map(|h| h.eps).collect()))
}

/// `k` with the prescribed unknowns' identity rows and columns, as in Newton's factored
/// tangent.
pub(super) fn with_prescribed_rows(
    mut k: crate::linalg::SparseMatrix,
    constrained: &[bool],
) -> crate::linalg::SparseMatrix {
    k.set_identity_rows_cols(constrained)
        .expect("a flag per unknown");
    k
}

/// Per element: whether the Gauss-point branches of `a` and `b` agree on all its points
/// (`None` when either leaves them free: every element counts as changed).
pub(super) fn unchanged_elements(
    dofs: &DofMap,
    a: &Frozen<'_>,
    b: &Frozen<'_>,
) -> Option<Vec<bool>> {
    let (a, b) = (a.gauss?, b.gauss?);
    Some(
        (0..dofs.element_body.len())
            .map(|e| a[dofs.gauss(e)] == b[dofs.gauss(e)])
            .collect(),
    )
}

/// The branches of the converged state, frozen, over all elements.
pub(super) fn converged_frozen<'c>(c: &'c Converged<'_>) -> Frozen<'c> {
    Frozen {
        gauss: Some(&c.eval.branches),
        contact: &c.eval.contact.choice,
        skip: None,
        ..Frozen::default()
    }
}

/// The total derivative of the unknowns for parameter `k`: the solved column of `rhs` on the
/// free unknowns, the prescribed derivative `dzc` on the constrained ones.
pub(super) fn total_dz(c: &Converged<'_>, rhs: &[f64], dzc: &[f64], k: usize) -> Vec<f64> {
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
pub(super) const CORRECTION_TOL: f64 = 1e-3;

/// [`refine_extended`] stops when every column's correction is below this fraction of the
/// column: three orders of magnitude below the accuracy the default DDM is tested to (1e-10
/// of each sensitivity's scale against a fresh factorization).
pub(super) const REFINED_TO: f64 = 1e-13;

/// Steps of [`refine_extended`] at most (two reach working precision wherever the first
/// solve kept a few digits; a third only guards a slow correction).
pub(super) const EXTENDED_REFINEMENT_STEPS: usize = 3;

/// Solves `k d = r` in place for [`refine_extended`]'s corrections, adding its work to the
/// cost.
type CorrectionSolve<'a> =
    dyn FnMut(&mut [f64], &mut SensitivityCost) -> Result<(), crate::linalg::LinalgError> + 'a;

/// Iterative refinement of the solution `x` of `k x = b` (`k^T x = b` if `transpose`) (`ncols` column-major columns) with
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
pub(super) fn refine_extended(
    k: &crate::linalg::SparseMatrix,
    transpose: bool,
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
            let (xc, bc) = (&x[cols.clone()], &b[cols.clone()]);
            if transpose {
                k.residual_extended_transpose(xc, bc, &mut r[cols])?;
            } else {
                k.residual_extended(xc, bc, &mut r[cols])?;
            }
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

/// Solves `k x = b` (`k^T x = b` where `transpose`; `ncols` column-major columns) in place by
/// GMRES preconditioned with the factorization `m` (of `k` or of a tangent near it) to
/// [`KRYLOV_TOL`], refined with double-double residuals ([`refine_extended`], each correction
/// by GMRES to [`CORRECTION_TOL`]), the work added to `cost`. `Ok(false)`, `rhs` as it came,
/// where GMRES fails or does not converge: a factorization of `k` may work, and the caller
/// makes one ([`factored_refined`]). An error of the refinement leaves `rhs` part refined:
/// a caller that goes on to factor restores it. `what` names the tangent in
/// `FRICSENS_TRACE`'s output.
/// DDM's solve and the adjoint's transposed one.
pub(super) fn krylov_refined(
    m: &LinearSolver,
    k: &crate::linalg::SparseMatrix,
    transpose: bool,
    rhs: &mut [f64],
    ncols: usize,
    cost: &mut SensitivityCost,
    what: &str,
) -> Result<bool, crate::linalg::LinalgError> {
    let gmres = |r: &mut [f64], tol: f64| {
        if transpose {
            m.gmres_transpose_multi(k, r, ncols, tol, KRYLOV_MAX_ITER)
        } else {
            m.gmres_multi(k, r, ncols, tol, KRYLOV_MAX_ITER)
        }
    };
    let b = rhs.to_vec();
    let start = Instant::now();
    // an error of the solves counts as not converged: the factorization may work
    let report = gmres(rhs, KRYLOV_TOL).ok();
    if std::env::var_os("FRICSENS_TRACE").is_some() {
        match &report {
            Some(r) => eprintln!(
                "  sensitivity GMRES ({what}): {} steps, |K x - b| / |b| = {:.2e}, backward error {:.2} eps{}",
                r.iterations,
                r.relative_residual,
                r.backward_error / f64::EPSILON,
                if r.converged { "" } else { ": not converged, factoring" }
            ),
            None => eprintln!("  sensitivity GMRES ({what}): failed, factoring"),
        }
    }
    // its solves are work done, converged or not
    cost.solve_columns += report.map_or(0, |r| r.solve_columns);
    let Some(report) = report.filter(|r| r.converged) else {
        cost.solve_seconds += start.elapsed().as_secs_f64();
        rhs.copy_from_slice(&b);
        return Ok(false);
    };
    cost.krylov_iterations += report.iterations;
    let mut correct = |r: &mut [f64], cost: &mut SensitivityCost| {
        let rep = gmres(r, CORRECTION_TOL)?;
        cost.solve_columns += rep.solve_columns;
        cost.krylov_iterations += rep.iterations;
        Ok(())
    };
    let refined = refine_extended(k, transpose, &b, rhs, ncols, cost, &mut correct);
    cost.solve_seconds += start.elapsed().as_secs_f64();
    refined.map(|()| {
        cost.krylov_solves += 1;
        true
    })
}

/// Solves `k x = b` (`k^T x = b` where `transpose`) in place with `s`, a factorization of `k`,
/// refined with double-double residuals ([`refine_extended`]) to the solution rounded to
/// working precision, as [`krylov_refined`]'s are; the work added to `cost`.
pub(super) fn factored_refined(
    s: &LinearSolver,
    k: &crate::linalg::SparseMatrix,
    transpose: bool,
    rhs: &mut [f64],
    ncols: usize,
    cost: &mut SensitivityCost,
) -> Result<(), crate::linalg::LinalgError> {
    let solve = |r: &mut [f64]| {
        if transpose {
            s.solve_transpose_multi_in_place(r, ncols)
        } else {
            s.solve_multi_in_place(r, ncols)
        }
    };
    let b = rhs.to_vec();
    let start = Instant::now();
    solve(rhs)?;
    cost.solve_columns += ncols;
    let mut correct = |r: &mut [f64], cost: &mut SensitivityCost| {
        cost.solve_columns += ncols;
        solve(r)
    };
    let refined = refine_extended(k, transpose, &b, rhs, ncols, cost, &mut correct);
    cost.solve_seconds += start.elapsed().as_secs_f64();
    refined
}

/// Every response's value at the converged state.
pub(super) fn response_values(c: &Converged<'_>) -> Vec<f64> {
    c.model
        .responses
        .iter()
        .map(|r| r.value(&c.eval.response_input(c.z, c.assembler)))
        .collect()
}

/// Add the wall time of `f` to `slot`.
pub(super) fn timed<T>(slot: &mut f64, f: impl FnOnce() -> T) -> T {
    let t = Instant::now();
    let out = f();
    *slot += t.elapsed().as_secs_f64();
    out
}

/// The in-line engine (SDM and DDM) run as an observer of the primal solver.
pub struct Engine<'a> {
    pub(super) params: &'a [Parameter],
    pub(super) settings: Settings,
    pub(super) keep_state_derivative: bool,
    /// `dh/db`, parameter-major: `dhist[p * n_history + i]`.
    pub(super) dhist: Vec<f64>,
    /// DDM's own `dh/db` beside SDM's (`Settings::explain`: the error anatomy's reference).
    pub(super) exact_dhist: Vec<f64>,
    /// `--beta auto`: the history derivative of the shadow SDM run at a tenth of the chosen
    /// steps, whose difference from the chosen one gives the error bars.
    pub(super) shadow_dhist: Vec<f64>,
    pub(super) exact: Option<LinearSolver>,
    /// Increment whose converged tangent `exact` holds factored (`None`: a forced tangent,
    /// or nothing yet).
    pub(super) exact_holds: Option<usize>,
    /// Tangent to solve with instead of the Newton one (one-sided derivatives: the tangent of
    /// the forced branches).
    pub(super) forced_tangent: Option<crate::linalg::SparseMatrix>,
    /// `Settings::fields`: the assembler that keeps every element's stress in the scalar.
    pub(super) field_assembler: Option<crate::assembly::Assembler>,
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
            exact_dhist: vec![0.0; nh * params.len()],
            shadow_dhist: vec![0.0; nh * params.len()],
            exact: None,
            exact_holds: None,
            forced_tangent: None,
            field_assembler: None,
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

    /// Parameter `k`'s targets set to `value` (the others keep their values, the model's):
    /// the overrides of a design moved along one parameter.
    pub(super) fn overrides<S: Scalar>(&self, k: usize, value: S) -> Vec<(DesignParam, S)> {
        self.params[k].targets.iter().map(|t| (*t, value)).collect()
    }

    /// `dh_0/db` of every parameter ([`initial_history_derivative`]).
    pub(super) fn initial_history_derivative(
        &mut self,
        c: &Converged<'_>,
    ) -> Result<(), AnalysisError> {
        let nh = c.hist_prev.len();
        for k in 0..self.params.len() {
            if let Some(d) = initial_history_derivative(c.model, c.assembler, &self.params[k])? {
                self.dhist[k * nh..(k + 1) * nh].copy_from_slice(&d[..nh]);
            }
        }
        Ok(())
    }

    /// Derivative of the prescribed unknowns with respect to parameter `k`.
    pub(super) fn prescribed_derivative(&self, c: &Converged<'_>, k: usize, out: &mut [f64]) {
        prescribed_derivative(c.model, &self.params[k], c.time, out);
    }
    /// Solve `K X = RHS` (columns stored column-major) with the chosen tangent.
    pub(super) fn solve(
        &mut self,
        c: &Converged<'_>,
        rhs: &mut [f64],
        ncols: usize,
    ) -> Result<(), AnalysisError> {
        let prescribed = |k| with_prescribed_rows(k, c.constrained);
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
            // GMRES preconditioned with the factor closest to `k` at hand: the converged
            // tangent's where it was factored at this increment, else Newton's last. A
            // forced tangent (a one-sided derivative's side) is factored instead, as the
            // adjoint factors it: it may be singular (nothing resists the motion its side
            // frees, e.g. a node forced to slip or open), which the factorization reports
            // and GMRES need not (it may return one of the solutions); and the factor at
            // hand is of other branches, far from it (on the leaf spring, 25 GMRES steps
            // a side, slower than factoring it)
            let at_hand = if self.exact_holds == Some(c.index) {
                self.exact.as_ref()
            } else {
                c.last_factor
            };
            if let (true, false, Some(m)) = (self.settings.krylov, forced, at_hand) {
                if krylov_refined(m, &k, false, rhs, ncols, cost, "converged tangent")? {
                    return Ok(());
                }
            }
            if self.exact.is_none() {
                // on the primal's symbolic analysis where it has one at hand
                self.exact = Some(match c.last_factor {
                    Some(primal) => primal.sibling(),
                    None => LinearSolver::with_fixed(
                        c.assembler.pattern.clone(),
                        Default::default(),
                        c.constrained,
                    )?,
                });
            }
            let s = self.exact.as_mut().expect("just created");
            self.exact_holds = None;
            timed(&mut cost.factor_seconds, || s.factor(&k))?;
            cost.factorizations += 1;
            if !forced {
                self.exact_holds = Some(c.index);
            }
            factored_refined(s, &k, false, rhs, ncols, cost)?;
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
            cost.solve_columns += ncols;
        }
        Ok(())
    }
}

impl Observer for Engine<'_> {
    fn converged(&mut self, c: &Converged<'_>) -> Result<(), AnalysisError> {
        if self.settings.probe_floor {
            self.probe_floor(c)?;
        }
        let t0 = Instant::now();
        let mut explain_seconds = 0.0;
        // --beta auto: the steps chosen and the error bars
        let mut auto = None;
        if self.results.increments.is_empty() && !c.model.contacts.is_empty() {
            self.initial_history_derivative(c)?;
            self.exact_dhist.clone_from(&self.dhist);
            self.shadow_dhist.clone_from(&self.dhist);
        }
        let kinks = self.kinks(c);
        // DDM's pseudo-loads on the converged branches, which the one-sided derivatives move
        let mut pseudo = None;
        let Step {
            dresp,
            dhist,
            dz,
            roundoff,
            ..
        } = match self.settings.method {
            Method::Ddm => {
                let frozen = converged_frozen(c);
                let p = self.pseudo_loads(c, &frozen)?;
                let step = self.ddm(c, &frozen, &p)?;
                pseudo = Some(p);
                step
            }
            Method::Sdm | Method::SdmCentral => {
                let central = self.settings.method == Method::SdmCentral;
                let step = if self.settings.beta_auto {
                    let (step, betas, bars) = self.sdm_auto(c, central)?;
                    auto = Some((betas, bars));
                    step
                } else {
                    let betas = vec![self.settings.beta; self.params.len()];
                    self.sdm(c, central, &betas)?
                };
                // the anatomy differences at one fixed beta on the converged branches
                if self.settings.explain
                    && !self.settings.beta_auto
                    && !self.settings.rigid_modes
                    && self.settings.freeze_branches
                {
                    // the anatomy's work is kept out of the method's cost
                    let t = Instant::now();
                    let cost = self.results.cost.clone();
                    let anatomy = self.anatomy(c, central, &step);
                    self.results.cost = cost;
                    let spent = t.elapsed().as_secs_f64();
                    self.results.cost.anatomy_seconds += spent;
                    explain_seconds += spent;
                    self.results.anatomy.push(anatomy?);
                }
                step
            }
            Method::Fdm | Method::FdmCentral | Method::Adjoint => {
                return Err(SensitivityError::NotInline {
                    method: self.settings.method.name(),
                }
                .into())
            }
        };
        // one-sided derivatives at flagged points (DDM): force the flagged points on each branch
        let one_sided = if !kinks.is_empty()
            && self.settings.method == Method::Ddm
            && self.settings.one_sided
        {
            // whether the derivative just computed solved with the converged tangent (the
            // forced tangent of the side the converged state is on)
            let exact_solve = self.settings.tangent == TangentChoice::Exact
                || c.last_factor.is_none()
                || !c.factor_matches;
            let mut sides = Vec::new();
            let mut failed = Vec::new();
            for upper in [false, true] {
                let mut gauss = c.eval.branches.clone();
                let mut contact: Vec<ContactChoice> = c.eval.contact.choice.clone();
                let at = (c.model, c.assembler);
                force_side(&kinks, upper, at, &mut gauss, &mut contact);
                if exact_solve && gauss == c.eval.branches && contact == c.eval.contact.choice {
                    // the converged state is on this side of every flagged point, and the
                    // derivative just computed solved with its tangent: that derivative is
                    // this side's
                    sides.push(Some(dresp.clone()));
                    continue;
                }
                let frozen = Frozen {
                    gauss: Some(&gauss),
                    contact: &contact,
                    skip: None,
                    ..Frozen::default()
                };
                let mut side = || -> Result<Vec<Vec<f64>>, AnalysisError> {
                    self.forced_tangent = Some(self.forced_tangent_at(c, &frozen)?);
                    let base = pseudo.as_ref().expect("DDM keeps its pseudo-loads");
                    let p = self.forced_pseudo_loads(c, base, &frozen)?;
                    Ok(self.ddm(c, &frozen, &p)?.dresp)
                };
                let side = side();
                self.forced_tangent = None;
                // a side whose forced tangent is singular (nothing resists the motion the
                // side frees, its derivative unbounded) leaves the run and the other side as
                // they are; any other error stops the run (`side_failure`)
                match side {
                    Ok(d) => sides.push(Some(d)),
                    Err(e) => {
                        failed.push(side_failure(upper, c.index, e)?);
                        sides.push(None);
                    }
                }
            }
            let upper = sides.pop().expect("two sides");
            let lower = sides.pop().expect("two sides");
            Some(OneSided {
                lower,
                upper,
                failed,
            })
        } else {
            None
        };
        if self.settings.fields {
            let t = Instant::now();
            let steps: Vec<f64> = (self.params.iter().enumerate())
                .map(|(k, p)| p.step(auto.as_ref().map_or(self.settings.beta, |a| a.0[k])))
                .collect();
            let fields = self.field_derivatives(c, &dz, &steps)?;
            self.results.fields.push(fields);
            let spent = t.elapsed().as_secs_f64();
            self.results.cost.fields_seconds += spent;
            explain_seconds += spent;
        }
        self.dhist = dhist;
        let values = response_values(c);
        self.results.increments.push(IncrementSensitivity {
            increment: c.index,
            time: c.time,
            values,
            derivatives: dresp,
            kinks,
            one_sided,
            rerun_substeps: Vec::new(),
            roundoff,
            betas: auto.as_ref().map(|a| a.0.clone()).unwrap_or_default(),
            error_bars: auto.map(|a| a.1).unwrap_or_default(),
            state_derivative: if self.keep_state_derivative {
                Some(dz)
            } else {
                None
            },
        });
        self.results.cost.wall_seconds += t0.elapsed().as_secs_f64() - explain_seconds;
        Ok(())
    }
}

/// What a design perturbation changes in the model an element sees: which nodes move and
/// which material parameters of each body, and of each element of a material field, change.
pub(super) struct Reach {
    pub(super) moved: Vec<bool>,
    material: Vec<Vec<bool>>,
    /// `(element, changed parameters)` of the elements with their own parameters, sorted.
    elements: Vec<(usize, Vec<bool>)>,
}

impl Reach {
    /// The changes from design `base` to design `other` (SDM's finite perturbation).
    pub(super) fn between(other: &Lifted<f64>, base: &Lifted<f64>) -> Self {
        let differ = |p: &[f64], q: &[f64]| p.iter().zip(q).map(|(a, b)| a != b).collect();
        let mut own: Vec<(usize, usize)> = (other.element_material.iter())
            .chain(&base.element_material)
            .map(|m| (m.0, m.1))
            .collect();
        own.sort_unstable();
        own.dedup();
        Reach {
            moved: (other.coords.iter().zip(&base.coords))
                .map(|(a, b)| a != b)
                .collect(),
            material: (other.material.iter().zip(&base.material))
                .map(|(p, q)| differ(p, q))
                .collect(),
            elements: (own.into_iter())
                .map(|(e, b)| (e, differ(other.material_of(b, e), base.material_of(b, e))))
                .collect(),
        }
    }

    /// The quantities of a seeded design with a nonzero derivative (DDM).
    pub(super) fn seeded(lifted: &Lifted<Dual64>) -> Self {
        let carries = |x: &Dual64| x.eps != 0.0;
        Reach {
            moved: (lifted.coords.iter())
                .map(|x| x.iter().any(carries))
                .collect(),
            material: (lifted.material.iter())
                .map(|p| p.iter().map(carries).collect())
                .collect(),
            elements: (lifted.element_material.iter())
                .map(|(e, _, p)| (*e, p.iter().map(carries).collect()))
                .collect(),
        }
    }

    /// Whether material parameter `i` of element `e` of body `b` changes.
    pub(super) fn material_changed(&self, b: usize, e: usize, i: usize) -> bool {
        self.material[b][i]
            || (self.elements.binary_search_by_key(&e, |m| m.0))
                .is_ok_and(|k| self.elements[k].1[i])
    }

    /// Whether any material parameter of element `e` of body `b` changes.
    pub(super) fn any_material(&self, b: usize, e: usize) -> bool {
        (0..self.material[b].len()).any(|i| self.material_changed(b, e, i))
    }
}

/// The elements whose history an evaluation with Gauss-point branches `gauss` leaves
/// unchanged and whose residual no response reads: all its points frozen elastic (no
/// history at all counts as elastic), none of its nodes among the residual rows a response
/// declares it reads, and not an element whose stress a response reads
/// ([`crate::response::ResponseKind::reads`]).
pub fn history_unchanged(model: &Model, dofs: &DofMap, gauss: &[Branch]) -> Vec<bool> {
    let mut reaction_node = vec![false; model.mesh.n_nodes()];
    let mut stress_read = vec![false; model.mesh.n_elements()];
    for r in &model.responses {
        let reads = r.kind.reads();
        for &n in reads.residual_nodes {
            if let Some(f) = reaction_node.get_mut(n) {
                *f = true;
            }
        }
        for &e in reads.stress_elements {
            if let Some(f) = stress_read.get_mut(e) {
                *f = true;
            }
        }
    }
    model
        .mesh
        .elements()
        .enumerate()
        .map(|(e, (_, conn))| {
            gauss[dofs.gauss(e)].iter().all(|b| *b == Branch::Elastic)
                && !conn.iter().any(|&n| reaction_node[n])
                && !stress_read[e]
        })
        .collect()
}
