//! One attempt at an increment: Newton iterations with the active-set predictor, line search,
//! step limiters and augmentation, and the convergence criteria of the module docs.

use super::*;
use crate::assembly::{Evaluation, Frozen};
use crate::contact::eval::ContactEval;
use crate::contact::{ContactChoice, ContactState};
use crate::material::Branch;
use std::collections::VecDeque;
use std::time::Instant;

/// The decisions of one free evaluation: contact states and faces, material branches (what a
/// cycle's diagnosis names), and its residual.
pub(super) type Decisions = (Vec<ContactChoice>, Vec<Branch>, f64);

/// What Newton's iterations carry from one to the next within an attempt.
pub(super) struct AttemptState {
    /// Backtracking line search and penetration limiter (contact models only: their
    /// residual is only piecewise smooth, and a full Newton step can flip many contact and
    /// stick/slip states at once).
    line_search: bool,
    /// Whether any contact pair has friction (the slip-reversal remedy).
    friction: bool,
    energy0: f64,
    last_energy: f64,
    last_correction: f64,
    /// The last correction of the positions relative to the positions `|X + u|`, and of
    /// the other unknowns (multipliers, incompatible modes) relative to themselves.
    last_position_correction: f64,
    last_other_correction: f64,
    alpha: f64,
    prev_r: f64,
    last_dz: Vec<f64>,
    /// Gaps and open states at the start of the last step, and whether the limiter has
    /// shortened it already.
    base_gap: Vec<f64>,
    base_open: Vec<bool>,
    limited: bool,
    first_residual: f64,
    /// Whether a factorization was made.
    factored: bool,
    /// Active-set predictor: the first iteration keeps the contact states (and faces) of
    /// the last converged increment instead of deciding them at the start state moved to
    /// the new load. A rigid target that moved by a whole increment otherwise closes every
    /// node it now overlaps, and the linearised constraints on nodes that will lift off
    /// load the first step with forces orders of magnitude too large (leaf spring: 40x,
    /// inverted elements and cutbacks).
    predict: bool,
    /// Built at the first settling (its trial evaluation holds a whole history vector).
    predictor: Option<ActiveSetPredictor>,
    /// Linear solves of the first step's active-set settling (counted as iterations).
    settle_solves: usize,
    /// Newton iterations (solves) made.
    k: usize,
    /// Slip reversal (see `SLIP_REVERSALS`): the states and friction forces of the last
    /// free evaluation, the nodes forced to stick in the current one, and how often each
    /// node has been forced in this attempt.
    last_free: Option<(Vec<ContactState>, Vec<nalgebra::Vector3<f64>>)>,
    forced: Vec<bool>,
    forced_count: Vec<usize>,
    /// Cycle detection: the contact decisions, material branches and residuals of the last
    /// free evaluations, and the smallest residual of those before them.
    window: VecDeque<Decisions>,
    best_before: f64,
    /// The target faces to keep (hysteresis, SEGMENT_KEEP): those the last Newton step was
    /// solved with, the converged ones at the first.
    keep_faces: Vec<ContactChoice>,
}

impl AttemptState {
    /// The state before the first iteration of an attempt of `model` from the contact states
    /// `converged` of the last converged increment.
    fn new(model: &Model, converged: &[ContactChoice]) -> Self {
        AttemptState {
            line_search: !model.contacts.is_empty(),
            friction: model.contacts.iter().any(|c| c.friction.is_some()),
            energy0: f64::NAN,
            last_energy: f64::INFINITY,
            last_correction: f64::INFINITY,
            last_position_correction: f64::INFINITY,
            last_other_correction: f64::INFINITY,
            alpha: 1.0,
            prev_r: f64::INFINITY,
            last_dz: Vec::new(),
            base_gap: Vec::new(),
            base_open: Vec::new(),
            limited: false,
            first_residual: f64::NAN,
            factored: false,
            predict: !converged.is_empty(),
            predictor: None,
            settle_solves: 0,
            k: 0,
            last_free: None,
            forced: Vec::new(),
            forced_count: Vec::new(),
            window: VecDeque::new(),
            best_before: f64::INFINITY,
            keep_faces: converged.to_vec(),
        }
    }

    /// Whether this evaluation imposes the last converged increment's contact states (the
    /// active-set predictor's first iteration).
    fn predicting(&self) -> bool {
        self.predict && self.k == 0
    }

    /// Whether this evaluation forces slip-reversing nodes onto the stick branch (it is not
    /// the true residual, never accepted as converged).
    fn forcing(&self) -> bool {
        !self.forced.is_empty()
    }

    /// Whether the penetration limiter may shorten the step that led to the state about to
    /// be evaluated: a Newton step (not the first), not shortened yet, with the decisions
    /// free.
    fn may_limit(&self) -> bool {
        self.line_search && self.k >= 1 && !self.limited && self.forced.is_empty()
    }

    /// Penetration limiter. A node the step found open at a positive gap and left
    /// deeper inside its target than it was outside overshot first contact (the
    /// linearised step knows nothing of the constraint it crosses). Shorten the step to
    /// just past the deepest such overshoot's first touch (linear in the step), so that
    /// node closes at the next solve with the bodies where they meet. Without it, the
    /// first contact of the leaf spring's leaves pressed the upper leaf 0.3 mm into the
    /// lower one along its whole length (0.02 mm clearance), and the primal-dual active
    /// set then released the spurious contacts one node per iteration (26 iterations;
    /// refined meshes ran out of iterations).
    ///
    /// Shortens the step in `z` where it overshoots (before `z` is evaluated); `gap` are the
    /// gaps at `z`, `floor` the solver's penetration floor. Returns whether it did.
    fn limit_penetration(&mut self, z: &mut [f64], gap: &[f64], floor: f64, trace: bool) -> bool {
        if !self.may_limit() {
            return false;
        }
        // the earliest touch, its node and the node's gaps before and after the step
        let (first_touch, node, g0, g1) = (self.base_gap.iter())
            .zip(&self.base_open)
            .zip(gap)
            .enumerate()
            .filter(|(_, ((g0, open), g1))| {
                **open && g0.is_finite() && **g0 > floor && **g1 < -floor && -**g1 > **g0
            })
            .map(|(i, ((g0, _), g1))| (g0 / (g0 - g1), i, *g0, *g1))
            .fold((1.0f64, 0, 0.0, 0.0), |a, b| if b.0 < a.0 { b } else { a });
        if first_touch < 0.5 {
            self.limited = true;
            // a tenth of the node's gap past first touch
            let keep = 1.1 * first_touch;
            if trace {
                eprintln!(
                    "    penetration limiter: step x {keep:.3e} (hitting node {node}: gap {g0:.3e} -> {g1:.3e})"
                );
            }
            for (zi, d) in z.iter_mut().zip(&self.last_dz) {
                *zi -= self.alpha * (1.0 - keep) * d;
            }
            self.alpha *= keep;
        }
        self.limited
    }

    /// Backtrack only from the second correction on, and only on a blow-up (residual
    /// up more than LINE_SEARCH_GROWTH times). The first correction and every
    /// primal-dual active-set step that settles contact or stick/slip states raise the
    /// residual moderately before quadratic steps follow; backtracking them stalls
    /// Newton (stacked leaves 0.8 -> 30 then converged in two; leaf spring a quarter
    /// step per iteration, no convergence in 30). Measured before the extrapolating
    /// predictor and the penetration limiter, growth 1 / 4 / 100:
    /// sliding block 5.75 / 4.91 / 4.81 iterations per increment, strip pull-out
    /// 21 / 39 / 83 increments (its slip front needs the damping), leaf spring
    /// diverged / 12 / 12.
    ///
    /// Returns whether it stepped `z` back (to be evaluated again).
    fn backtrack(&mut self, z: &mut [f64], r_free: f64) -> bool {
        if self.line_search
            && !self.forcing()
            && self.k > 1
            && r_free > LINE_SEARCH_GROWTH * self.prev_r
            && self.alpha > SHORTEST_STEP
        {
            self.halve(z);
            return true;
        }
        false
    }

    /// Step back from `z_prev + alpha dz` to `z_prev + (alpha / 2) dz`.
    fn halve(&mut self, z: &mut [f64]) {
        self.alpha *= 0.5;
        for (zi, d) in z.iter_mut().zip(&self.last_dz) {
            *zi -= self.alpha * d;
        }
    }

    /// A Newton step whose end state cannot be evaluated (an element inverted, a target
    /// segment degenerate or a smoothed normal turned away from its face) is halved while it
    /// is longer than [`SHORTEST_STEP`] of its length, instead of ending the attempt: the
    /// state the step started from was evaluated, so a short enough step can be (contact
    /// models only, as the line search). When halving runs out, the attempt ends with the
    /// failure at the shortest step. Returns whether it stepped `z` back (to be evaluated
    /// again).
    fn shorten_on_failure(&mut self, z: &mut [f64]) -> bool {
        if !(self.line_search && self.k >= 1 && !self.forcing() && self.alpha > SHORTEST_STEP) {
            return false;
        }
        self.halve(z);
        true
    }

    /// Slip reversal: a node that slipped at the last free evaluation and slips the
    /// other way now has its stick zone between the two iterates; Newton's slip tangent
    /// (no stiffness along the slip) steps over it each time and cycles. Evaluate again
    /// with such nodes on the stick branch, so that the step is solved with their
    /// stick stiffness and lands them in the zone (at most SLIP_REVERSALS times per
    /// node and attempt: the forcing ends, and the free decisions take over).
    ///
    /// Returns whether it forced nodes (the state is to be evaluated again).
    fn reverse_slips(&mut self, contact: &ContactEval<f64>, r_free: f64, trace: bool) -> bool {
        if !(self.friction && !self.forcing() && !self.predicting()) {
            return false;
        }
        let states: Vec<ContactState> = contact.choice.iter().map(|c| c.state).collect();
        let mut reversed = Vec::new();
        // only where Newton stalls: far from the solution a slip direction may turn
        // on the way (the leaf spring's nose nodes do at its second iteration, where
        // forcing them cost 27 more iterations over the run)
        let stalled = r_free > STALL_RATIO * self.prev_r;
        if let (true, Some((old_states, old_t))) = (stalled, &self.last_free) {
            self.forced_count.resize(states.len(), 0);
            for i in 0..states.len() {
                if states[i] == ContactState::Slip
                    && old_states[i] == ContactState::Slip
                    && contact.traction[i].dot(&old_t[i]) < 0.0
                    && self.forced_count[i] < SLIP_REVERSALS
                {
                    reversed.push(i);
                }
            }
        }
        self.last_free = Some((states, contact.traction.clone()));
        if reversed.is_empty() {
            return false;
        }
        self.forced = vec![false; contact.choice.len()];
        for &i in &reversed {
            self.forced[i] = true;
            self.forced_count[i] += 1;
        }
        if trace {
            eprintln!("    slip reversal: nodes {reversed:?} evaluated again on the stick branch");
        }
        true
    }

    /// Fail fast on a cycle: at a free evaluation, contact decisions seen earlier in
    /// the window again, and no residual in the window below half the best before it.
    /// Returns whether the attempt cycles (the window then holds what to diagnose).
    fn cycles(&mut self, choice: &[ContactChoice], branches: &[Branch], r_free: f64) -> bool {
        if !(self.line_search && !self.forcing() && !self.predicting()) {
            return false;
        }
        let repeated = self.window.iter().any(|(c, _, _)| *c == choice);
        // a full window's oldest entry leaves it, and its buffers take the newest (no
        // allocation per iteration once the window is full)
        let (mut c, mut b) = (Vec::new(), Vec::new());
        if self.window.len() == CYCLE_WINDOW {
            let (oc, ob, r) = self.window.pop_front().expect("not empty");
            self.best_before = self.best_before.min(r);
            (c, b) = (oc, ob);
        }
        c.clear();
        c.extend_from_slice(choice);
        b.clear();
        b.extend_from_slice(branches);
        self.window.push_back((c, b, r_free));
        let best_now = self
            .window
            .iter()
            .map(|(_, _, r)| *r)
            .fold(f64::INFINITY, f64::min);
        repeated && self.k >= 2 * CYCLE_WINDOW && best_now >= 0.5 * self.best_before
    }

    /// The state `z` is to take a Newton step: the step starts at full length, and the
    /// residual is the one the next is measured against (unless this evaluation forced
    /// nodes to stick).
    fn start_step(&mut self, r_free: f64) {
        self.alpha = 1.0;
        self.limited = false;
        if !self.forcing() {
            self.prev_r = r_free;
        }
    }

    /// Take the step `dz` from `z` (`eval` the evaluation it was solved at, `energy` its
    /// `|dz . R|`, `corrections` its size relative to the state: [`Solver::corrections`]), and
    /// keep what the next iteration's criteria and limiters need.
    fn take_step(
        &mut self,
        z: &mut [f64],
        dz: Vec<f64>,
        eval: &Evaluation<f64>,
        energy: f64,
        (correction, position_correction, other_correction): (f64, f64, f64),
    ) -> Result<(), AttemptFailure> {
        if self.k == 1 {
            self.energy0 = energy;
        }
        self.last_energy = energy;
        self.last_correction = correction;
        self.last_position_correction = position_correction;
        self.last_other_correction = other_correction;
        if !energy.is_finite() {
            return Err(AttemptFailure::Diverged("non-finite correction"));
        }
        if self.line_search {
            self.base_gap.clone_from(&eval.contact.gap);
            self.base_open.clear();
            self.base_open.extend(
                eval.contact
                    .choice
                    .iter()
                    .map(|c| c.state == crate::contact::ContactState::Open),
            );
        }
        for (zi, d) in z.iter_mut().zip(&dz) {
            *zi += d;
        }
        self.last_dz = dz;
        Ok(())
    }
}

impl Solver<'_> {
    /// Newton iterations of one attempt. Returns whether a factorization was made.
    ///
    /// An iteration is one linear solve; the residual evaluations of the line search between
    /// two solves are not iterations (they are counted in [`PrimalCost::assemblies`] and
    /// recorded in [`IncrementRecord::residuals`]). The penetration limiter reads the gaps of
    /// a contact-only evaluation ([`Solver::gaps`]: its time counts as assembly, it is no
    /// residual evaluation) before the residual is evaluated.
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
        let mut st = AttemptState::new(model, &self.converged_choice);
        loop {
            if self.deadline.is_some_and(|d| Instant::now() > d) {
                return Err(AttemptFailure::TimeLimit);
            }
            // the limiter reads the gaps alone: a step it shortens is shortened before the
            // residual is evaluated (no assembly at the full step, and no element inverted
            // by a step that is not taken)
            if st.may_limit() {
                let (floor, trace) = (self.penetration_floor, self.trace);
                match self.gaps((z, hist, t), &st.keep_faces, cost) {
                    Ok(gap) => {
                        if st.limit_penetration(z, gap, floor, trace) {
                            cost.limited_steps += 1;
                        }
                    }
                    Err(e) if st.shorten_on_failure(z) => {
                        if self.trace {
                            eprintln!("    {e}: step x {:.3e}", st.alpha);
                        }
                        continue;
                    }
                    Err(e) => return Err(AttemptFailure::Element(e)),
                }
            }
            if self.relaxing_modes && !self.relaxed_elements.is_empty() {
                let start = Instant::now();
                let moved = self.assembler.relax_modes(
                    model,
                    &self.lifted,
                    z,
                    hist,
                    &self.relaxed_elements,
                    MODE_RELAXATION_STEPS,
                );
                cost.assembly_seconds += start.elapsed().as_secs_f64();
                if self.trace {
                    eprintln!(
                        "    incompatible modes of {moved} elements moved to their equilibrium"
                    );
                }
            }
            let (r_free, f_ref) = match self.evaluate((z, hist, t), eval, &mut st, cost) {
                Ok(v) => v,
                Err(AttemptFailure::Element(e)) if st.shorten_on_failure(z) => {
                    if self.trace {
                        eprintln!("    {e}: step x {:.3e}", st.alpha);
                    }
                    continue;
                }
                Err(e) => return Err(e),
            };
            record.residuals.push(r_free);
            record.reference_force = f_ref;
            if self.trace {
                trace_iteration(t, &st, r_free, eval, &self.constrained);
            }
            if !r_free.is_finite() {
                return Err(AttemptFailure::Diverged("non-finite residual"));
            }
            if st.k == 0 {
                st.first_residual = r_free;
            }
            if self.converged(&st, r_free, f_ref) {
                record.iterations = st.k + st.settle_solves;
                return Ok(st.factored);
            }
            if st.backtrack(z, r_free) || st.reverse_slips(&eval.contact, r_free, self.trace) {
                continue;
            }
            st.start_step(r_free);
            if st.cycles(&eval.contact.choice, &eval.branches, r_free) {
                return Err(AttemptFailure::Cycle(
                    self.diagnose_cycle(&st.window, s.force_tol * f_ref),
                ));
            }
            if st.k == s.max_iterations {
                return Err(AttemptFailure::Diverged("iteration limit"));
            }
            if st.k >= 4 && r_free > 1e4 * st.first_residual.max(f_ref) {
                return Err(AttemptFailure::Diverged("residual growing"));
            }
            let dz = self.correction((z, hist, t), eval, &mut st, record, cost)?;
            st.k += 1;
            let energy: f64 = dz
                .iter()
                .zip(&eval.residual)
                .map(|(a, b)| a * b)
                .sum::<f64>()
                .abs();
            record.energies.push(energy);
            let corrections = self.corrections(z, &dz);
            record
                .corrections
                .push(dz.iter().map(|d| d * d).sum::<f64>().sqrt());
            st.take_step(z, dz, eval, energy, corrections)?;
        }
    }

    /// Assemble at `(z, hist, t)` with this iteration's contact states and return `|R_free|`
    /// and the reference force `F_ref`.
    fn evaluate(
        &mut self,
        (z, hist, t): At<'_>,
        eval: &mut Evaluation<f64>,
        st: &mut AttemptState,
        cost: &mut PrimalCost,
    ) -> Result<(f64, f64), AttemptFailure> {
        loop {
            // the first iteration's contact states and faces those of the last converged
            // increment (the predictor below; `keep_faces` holds them until the first step
            // is solved), the others' decided freely but for the faces' hysteresis against
            // the converged ones
            let frozen = Frozen {
                gauss: None,
                contact: &st.keep_faces,
                skip: None,
                ..Frozen::default()
            };
            let free = Frozen {
                gauss: None,
                contact: &[],
                skip: None,
                keep_faces: Some(&st.keep_faces),
                stick: (!st.forced.is_empty()).then_some(&st.forced[..]),
                ..Frozen::default()
            };
            self.assemble(
                (z, hist, t),
                Some(if st.predicting() { &frozen } else { &free }),
                eval,
                cost,
            )
            .map_err(AttemptFailure::Element)?;
            let (r_free, f_ref) = self.residual_norms(&eval.residual, t);
            // a state that balances with the predicted contact states is accepted only
            // once they are decided freely
            let s = &self.model.solver;
            if st.predicting() && (r_free <= s.force_tol * f_ref || r_free == 0.0) {
                st.predict = false;
                continue;
            }
            return Ok((r_free, f_ref));
        }
    }

    /// `|R_free|` of the residual `residual` at time `t`, and the reference force of the force
    /// criterion: the larger of the reactions' norm and the external load's.
    fn residual_norms(&self, residual: &[f64], t: f64) -> (f64, f64) {
        let mut r_free = 0.0;
        let mut r_fixed = 0.0;
        for (d, r) in residual.iter().enumerate() {
            if self.constrained[d] {
                r_fixed += r * r;
            } else {
                r_free += r * r;
            }
        }
        let r_free = r_free.sqrt();
        let mut f_ext = 0.0;
        for (l, load) in self.model.loads.iter().enumerate() {
            let f = self.lifted.loads[l] * load.amplitude.at(t);
            f_ext += load.weights.iter().map(|w| (f * w).powi(2)).sum::<f64>();
        }
        for (l, load) in self.model.pressures.iter().enumerate() {
            let p = self.lifted.pressures[l] * load.amplitude.at(t);
            f_ext += (p * self.unit_pressure_norms[l]).powi(2);
        }
        // the forces pushing rigid targets
        for (p, pair) in self.model.contacts.iter().enumerate() {
            for (k, _, m) in pair.pushed(&self.assembler.contact.target[p]) {
                f_ext += (self.lifted.rigid_motion[p][k] * m.amplitude.at(t)).powi(2);
            }
        }
        let f_ref = r_fixed.sqrt().max(f_ext.sqrt());
        (r_free, f_ref)
    }

    /// The convergence criteria of the module docs, at an evaluation of residual `r_free`
    /// and reference force `f_ref`.
    fn converged(&self, st: &AttemptState, r_free: f64, f_ref: f64) -> bool {
        let s = &self.model.solver;
        let forcing = st.forcing();
        let force_ok = !forcing && (r_free <= s.force_tol * f_ref || r_free == 0.0);
        // (a first correction of zero energy gives no scale: the force criterion decides)
        let energy_ok =
            !forcing && st.k > 0 && st.energy0 > 0.0 && st.last_energy <= s.energy_tol * st.energy0;
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
            && st.k > 1
            && (st.last_correction <= CORRECTION_ROUND_OFF * f64::EPSILON
                || (st.last_position_correction <= CORRECTION_ROUND_OFF * f64::EPSILON
                    && st.last_other_correction <= f64::EPSILON.sqrt()));
        // the energy and round-off criteria stand in for the force criterion where the
        // residual cannot reach it for round-off, not where it is far above it: a
        // correction at round-off with a large residual is a stiff or inconsistent tangent
        // (against the larger of the current reference force and the mean of the converged
        // increments': an unloaded state's is zero, and its residual only round-off)
        let mean_ref = self.force_history.0 / self.force_history.1.max(1) as f64;
        let near =
            r_free <= NEAR_TOLERANCE * s.force_tol * f_ref.max(mean_ref).max(self.force_floor);
        force_ok || (near && (energy_ok || correction_ok))
    }

    /// Newton's correction at the evaluation `eval` of `(z, hist, t)`: solved, its first
    /// step's contact states settled on the linearised problem, and shortened by the
    /// yield-surface crossing limiter.
    fn correction(
        &mut self,
        (z, hist, t): At<'_>,
        eval: &mut Evaluation<f64>,
        st: &mut AttemptState,
        record: &mut IncrementRecord,
        cost: &mut PrimalCost,
    ) -> Result<Vec<f64>, AttemptFailure> {
        let mut dz = vec![0.0; eval.residual.len()];
        self.newton_step(eval, &mut dz, cost)?;
        st.factored = true;
        st.forced.clear();
        st.keep_faces.clone_from(&eval.contact.choice);
        if st.k == 0 && st.line_search {
            let predictor = st
                .predictor
                .get_or_insert_with(|| ActiveSetPredictor::new(&self.assembler));
            st.settle_solves =
                self.settle_active_set((z, hist, t), &mut dz, eval, predictor, cost)?;
            record.active_set_solves += st.settle_solves;
        }
        // Yield-surface crossing limiter: a step that carries a plastic point through its
        // elastic domain to the far side of the yield surface stops where the point is
        // deepest inside (at least YIELD_CROSSING_FLOOR of the step), so the next
        // iteration sees it elastic instead of returned the other way (a two-cycle of
        // constant branches otherwise: MaterialLaw::elastic_crossing).
        let (crossing, points) =
            self.assembler
                .elastic_crossing(self.model, &self.lifted, z, &dz, hist, &eval.branches);
        if points > 0 {
            let scale = crossing.max(YIELD_CROSSING_FLOOR);
            if self.trace {
                eprintln!(
                    "    yield crossing: {points} points cross their elastic domain, step x {scale:.3e}"
                );
            }
            dz.iter_mut().for_each(|d| *d *= scale);
        }
        Ok(dz)
    }

    /// The size of the correction `dz` of `z`: relative to the whole state, its positions part
    /// relative to the positions `|X + u|`, and the other unknowns' relative to themselves.
    fn corrections(&self, z: &[f64], dz: &[f64]) -> (f64, f64, f64) {
        let n_nodal = self.assembler.dofs.n_nodal;
        // the displacement-like unknowns (nodal, and the elements' incompatible modes)
        // against the positions' round-off; the multipliers against themselves (an
        // unloaded body's incompatible modes are zero, and their corrections were measured
        // against nothing: the fuzzer found Newton at the round-off floor of a lifted-off
        // body for 30 iterations)
        // (a pushed rigid target's translations, after the multipliers, are displacements too)
        let first_lambda = self.assembler.dofs.first_lambda.min(dz.len());
        let first_target = self
            .assembler
            .dofs
            .first_target
            .clamp(first_lambda, dz.len());
        let norm = |v: &[f64]| v.iter().map(|v| v * v).sum::<f64>().sqrt();
        let both = |v: &[f64]| {
            let targets = norm(&v[first_target..]);
            let nodal = norm(&v[..first_lambda]);
            let nodal = if targets == 0.0 {
                nodal
            } else {
                nodal.hypot(targets)
            };
            (nodal, norm(&v[first_lambda..first_target]))
        };
        let (dz_nodal, dz_other) = both(dz);
        let (z_nodal, z_other) = both(z);
        let x_norm = (0..n_nodal)
            .map(|d| (self.lifted.coords[d / 3][d % 3] + z[d]).powi(2))
            .sum::<f64>()
            .sqrt();
        let correction = dz_nodal.hypot(dz_other) / z_nodal.hypot(z_other).max(f64::MIN_POSITIVE);
        let position_correction = dz_nodal / x_norm.max(f64::MIN_POSITIVE);
        let other_correction = if dz_other == 0.0 {
            0.0
        } else {
            dz_other / z_other.max(f64::MIN_POSITIVE)
        };
        (correction, position_correction, other_correction)
    }
}

/// The trace line of an evaluation: time, iteration, step length, residual, the number of
/// plastic Gauss points, the closed hitting nodes with their states, normal forces and faces
/// (`s` projected along smoothed normals, `u` not), and the four largest free residual
/// entries (unknown: value; `constrained` marks the others), which name the unknowns a
/// cycling Newton leaves out of balance.
fn trace_iteration(
    t: f64,
    st: &AttemptState,
    r_free: f64,
    eval: &Evaluation<f64>,
    constrained: &[bool],
) {
    let (k, alpha) = (st.k, st.alpha);
    let active: Vec<String> = eval
        .contact
        .choice
        .iter()
        .zip(&eval.contact.normal_force)
        .enumerate()
        .filter(|(_, (c, _))| c.state != crate::contact::ContactState::Open)
        .map(|(i, (c, f))| {
            format!(
                "{i}:{:?}:{f:.3e}:f{}{}",
                c.state,
                c.face,
                if c.smoothed { "s" } else { "u" }
            )
        })
        .collect();
    let plastic = (eval.branches.iter())
        .filter(|b| **b == Branch::Plastic)
        .count();
    let r = &eval.residual;
    let mut free: Vec<usize> = (0..r.len()).filter(|&d| !constrained[d]).collect();
    free.sort_by(|&a, &b| r[b].abs().total_cmp(&r[a].abs()));
    let largest: Vec<String> = (free.iter().take(4))
        .map(|&d| format!("{d}:{:.3e}", r[d]))
        .collect();
    eprintln!(
        "  t = {t:.4e} k = {k} alpha = {alpha:.3} r = {r_free:.3e} plastic {plastic} closed {} \
         largest {}",
        active.join(" "),
        largest.join(" ")
    );
}
