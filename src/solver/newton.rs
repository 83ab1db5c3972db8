//! One attempt at an increment: Newton iterations with the active-set predictor, line search,
//! step limiters and augmentation, and the convergence criteria of the module docs.

use super::*;
use crate::assembly::{Assembler, AssemblyFailure, Evaluation, Frozen};
use crate::contact::{ContactChoice, ContactState};
use crate::linalg::{LinalgError, SparseMatrix};
use crate::model::{Lifted, Model};
use std::time::Instant;

/// Assemble the residual and the tangent (into `matrix`) at the state `(z, hist_old, t)`,
/// the time and the count going to `cost` when it succeeds. A free function: the callers
/// freeze states they borrow from the solver while its matrix is written.
#[allow(clippy::too_many_arguments)]
pub(super) fn assemble(
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
    pub(super) fn factor_and_solve(
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
    /// Newton iterations of one attempt. Returns whether a factorization was made.
    ///
    /// An iteration is one linear solve; the residual evaluations of the line search and of
    /// the penetration limiter between two solves are not iterations (they are counted in
    /// [`PrimalCost::assemblies`] and recorded in [`IncrementRecord::residuals`]).
    pub(super) fn attempt(
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
