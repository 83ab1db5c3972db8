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
    /// The tangent could not be factored; what [`Solver::zero_rows`] finds (may be empty).
    Singular(String),
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
            AttemptFailure::Singular(why) if why.is_empty() => write!(f, "singular tangent"),
            AttemptFailure::Singular(why) => write!(f, "singular tangent: {why}"),
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
    /// factored (it counts as a Newton iteration), or why the linearised step itself fails
    /// (the caller cuts back): a singular tangent with what [`Solver::zero_rows`] finds, else
    /// "predictor failed".
    pub(super) fn predict(
        &mut self,
        z_old: &[f64],
        z_new: &mut [f64],
        hist: &[f64],
        t: f64,
        eval: &mut Evaluation<f64>,
        cost: &mut PrimalCost,
    ) -> Result<Result<bool, AttemptFailure>, LinalgError> {
        const FAILED: AttemptFailure = AttemptFailure::Diverged("predictor failed");
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
            return Ok(Ok(false));
        }
        let assembled = self.assemble((z_old, hist, t), None, eval, cost);
        if assembled.is_err() {
            return Ok(Err(FAILED));
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
        match self.factor_and_solve(&mut dz, cost) {
            Err(singular @ AttemptFailure::Singular(_)) => return Ok(Err(singular)),
            Err(_) => return Ok(Err(FAILED)),
            Ok(()) => {}
        }
        if dz.iter().any(|v| !v.is_finite()) {
            return Ok(Err(FAILED));
        }
        for d in 0..n {
            if !self.constrained[d] {
                z_new[d] = z_old[d] + dz[d];
            }
        }
        Ok(Ok(true))
    }

    /// Why the tangent (identity rows of the prescribed unknowns applied) is singular, where
    /// it can be said: the unknowns Newton solves for whose row is zero, at most five, each
    /// named (a node nothing holds in some direction, such as one on a spring of zero
    /// stiffness; the multiplier of a closed Lagrange node prescribed in every component), or
    /// those whose row holds a non-finite entry; empty where neither (rows that depend on
    /// each other).
    pub(super) fn zero_rows(&self) -> String {
        let pattern = self.matrix.pattern();
        let (cp, ri, vals) = (pattern.col_ptr(), pattern.row_idx(), self.matrix.values());
        let n = self.matrix.n();
        // over the unknowns Newton solves for: the prescribed ones' identity rows and
        // columns left out
        let free = |d: usize| !self.constrained[d];
        let mut largest = vec![0.0f64; n];
        let mut non_finite = Vec::new();
        for j in (0..n).filter(|&j| free(j)) {
            for k in cp[j]..cp[j + 1] {
                let i = ri[k];
                if !vals[k].is_finite() && free(i) {
                    non_finite.push(i);
                }
                largest[i] = largest[i].max(vals[k].abs());
            }
        }
        if !non_finite.is_empty() {
            // not a row nothing holds: say where the tangent is not a number
            non_finite.sort_unstable();
            non_finite.dedup();
            let named: Vec<String> = (non_finite.iter().take(5))
                .map(|&d| self.describe_unknown(d))
                .collect();
            return format!(
                "non-finite entries in the rows of {} unknown(s): {}{}",
                non_finite.len(),
                named.join(", "),
                if non_finite.len() > 5 { ", ..." } else { "" }
            );
        }
        let scale = (0..n)
            .filter(|&d| free(d))
            .fold(0.0f64, |m, d| m.max(largest[d]));
        // zero to round-off against the tangent's largest entry
        let zero: Vec<usize> = (0..n)
            .filter(|&d| free(d) && largest[d] <= 1e-14 * scale)
            .collect();
        if zero.is_empty() {
            return String::new();
        }
        let named: Vec<String> = zero
            .iter()
            .take(5)
            .map(|&d| self.describe_unknown(d))
            .collect();
        format!(
            "{} unknown(s) with a zero row, nothing holding them: {}{}",
            zero.len(),
            named.join(", "),
            if zero.len() > 5 { ", ..." } else { "" }
        )
    }

    /// Unknown `d` in words: a node's component, an element's incompatible modes, a pair's
    /// multiplier at a hitting node, or a force-pushed rigid target's translation.
    pub(super) fn describe_unknown(&self, d: usize) -> String {
        let dofs = &self.assembler.dofs;
        let layout = &self.assembler.contact;
        if d < dofs.n_nodal {
            return format!("node {} {}", d / 3, ["x", "y", "z"][d % 3]);
        }
        // every pair has a multiplier per hitting node, in the flat order of the hitting nodes
        if d >= dofs.first_lambda && d < dofs.first_lambda + layout.n_hitting {
            let words = self.hitting_node_words(d - dofs.first_lambda);
            return format!("the contact multiplier of {words}");
        }
        for (p, targets) in layout.target.iter().enumerate() {
            if let Some(k) = targets.iter().position(|&t| t == Some(d)) {
                return format!(
                    "the translation of the force-pushed target of pair '{}' (its motion[{k}])",
                    self.model.contacts[p].name
                );
            }
        }
        if d < dofs.first_lambda {
            // the element whose internal unknowns start last at or before `d` (their order
            // follows the bodies, not the element numbers)
            let owner = (dofs.element_internal.iter().enumerate())
                .filter_map(|(e, f)| f.filter(|&f| f <= d).map(|f| (f, e)))
                .max();
            if let Some((_, e)) = owner {
                return format!("an incompatible mode of element {e}");
            }
        }
        format!("unknown {d}")
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
            return Err(AttemptFailure::Singular(self.zero_rows()));
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
