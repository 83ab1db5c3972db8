//! The solver over a whole load path: increments, cutbacks and growth, the observer after each
//! converged increment.

use super::*;
use crate::assembly::{Assembler, AssemblyFailure, Evaluation};
use crate::contact::{ContactChoice, ContactState};
use crate::element::ElementFailure;
use crate::linalg::{LinearSolver, SparseMatrix};
use crate::material::Branch;
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
}

impl<'m> Solver<'m> {
    /// Number the unknowns, build the pattern and its symbolic factorization.
    pub fn new(model: &'m Model) -> Result<Self, AnalysisError> {
        let assembler = Assembler::new(model, &[])?;
        let n = assembler.dofs.n_total;
        let mut constrained = vec![false; n];
        for p in &model.prescribed {
            for &node in &p.nodes {
                let d = node_dof(node, p.component);
                if d >= assembler.dofs.n_nodal {
                    return Err(ModelError::NoNode {
                        prescribed: p.name.clone(),
                        node,
                    }
                    .into());
                }
                if constrained[d] {
                    return Err(ModelError::PrescribedTwice {
                        prescribed: p.name.clone(),
                        node,
                        component: p.component,
                    }
                    .into());
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
            let mut eval = Evaluation::<f64>::new(&assembler, model.mesh.n_elements());
            let z = vec![0.0; n];
            let hist = crate::contact::assembly::initial_history(
                model,
                &assembler.contact,
                assembler.dofs.n_history,
                &lifted,
            )?;
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
            .map(|b| b.material.young())
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

    /// What the pre-checks found that does not stop the run ([`super::PrecheckWarning`]).
    pub fn warnings(&self) -> &[crate::precheck::PrecheckWarning] {
        &self.warnings
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
        let ne = model.mesh.n_elements();
        let mut res = Results::default();
        let mut z = vec![0.0; n];
        let mut hist = crate::contact::assembly::initial_history(
            model,
            &self.assembler.contact,
            self.assembler.dofs.n_history,
            &self.lifted,
        )?;
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
        res.branches
            .push(vec![Branch::Elastic; self.assembler.dofs.n_gauss()]);
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
                        .map_err(AnalysisError::Linalg)
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
}
