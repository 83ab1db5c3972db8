//! Newton's linear algebra: assembly at a state, the consistent predictor, factorization and
//! solve, Newton's correction; and why an attempt fails.

use super::*;
use crate::assembly::{AssemblyFailure, Evaluation, Frozen};
use crate::linalg::LinalgError;
use std::time::Instant;

/// The state an assembly is evaluated at: the unknowns `z`, the history `hist_old` committed
/// at the end of the last converged increment, and the time `t`.
pub(super) type At<'a> = (&'a [f64], &'a [f64], f64);

/// Why an attempt failed (recoverable by cutback, but for the time limit).
#[derive(Debug)]
pub(super) enum AttemptFailure {
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

impl Solver<'_> {
    /// Assemble the residual and the tangent (into `self.matrix`) at the state
    /// `(z, hist_old, t)`, the time and the count going to `cost` when it succeeds. `frozen`
    /// borrows nothing of the solver (the attempt's first iteration freezes its own copy of
    /// the converged contact states).
    pub(super) fn assemble(
        &mut self,
        (z, hist_old, t): At<'_>,
        frozen: Option<&Frozen>,
        eval: &mut Evaluation<f64>,
        cost: &mut PrimalCost,
    ) -> Result<(), AssemblyFailure> {
        let t0 = Instant::now();
        let done = self.assembler.evaluate(
            self.model,
            &self.lifted,
            z,
            hist_old,
            t,
            frozen,
            Some(&mut self.matrix),
            eval,
        );
        // a failed evaluation's time counts too (the step it ends is halved or cut back)
        cost.assembly_seconds += t0.elapsed().as_secs_f64();
        done?;
        cost.assemblies += 1;
        Ok(())
    }

    /// The gaps of the hitting nodes at `(z, hist_old, t)`, their contact decided freely but
    /// for the faces `keep_faces` (as [`Solver::evaluate`]'s free evaluation decides it):
    /// contact evaluated alone, without the elements or a tangent, into the solver's own
    /// buffer. Its time counts as assembly; it is no residual evaluation.
    pub(super) fn gaps(
        &mut self,
        (z, hist_old, t): At<'_>,
        keep_faces: &[crate::contact::ContactChoice],
        cost: &mut PrimalCost,
    ) -> Result<&[f64], AssemblyFailure> {
        let t0 = Instant::now();
        let ne = self.model.mesh.n_elements();
        if self.no_elements.len() != ne {
            self.no_elements = vec![true; ne];
        }
        let buffer = self
            .gap_eval
            .get_or_insert_with(|| Box::new(Evaluation::new(&self.assembler, ne)));
        let frozen = Frozen {
            gauss: None,
            contact: &[],
            keep_faces: Some(keep_faces),
            skip: Some(&self.no_elements),
            // the elements' outputs are not read: no history carried over for them
            members_only: true,
            ..Frozen::default()
        };
        let done = self.assembler.evaluate(
            self.model,
            &self.lifted,
            z,
            hist_old,
            t,
            Some(&frozen),
            None,
            buffer,
        );
        cost.assembly_seconds += t0.elapsed().as_secs_f64();
        done?;
        Ok(&buffer.contact.gap)
    }

    /// Consistent predictor for an increment of prescribed displacements: linearise about the
    /// last converged state, `K dz_f = -(R_f(z_n, t) + K_fc dz_c)`, instead of starting Newton
    /// from a state in which only the prescribed nodes have moved (which distorts the elements
    /// next to them and provokes spurious yielding, inversion and cutbacks). Returns whether it
    /// factored (it counts as a Newton iteration), or `None` when the linearised step itself
    /// fails (the caller cuts back).
    pub(super) fn predict(
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
        let assembled = self.assemble((z_old, hist, t), None, eval, cost);
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
        // the states this factorization is assembled on ([`Converged::factor_matches`]): an
        // increment that converges without a Newton step reports it as its last
        self.factored_choice.clone_from(&eval.contact.choice);
        self.factored_branches.clone_from(&eval.branches);
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
    pub(super) fn factor_and_solve(
        &mut self,
        rhs: &mut [f64],
        cost: &mut PrimalCost,
    ) -> Result<(), AttemptFailure> {
        self.matrix
            .set_identity_rows_cols(&self.constrained)
            .expect("a flag per unknown");
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
    pub(super) fn newton_step(
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
}
