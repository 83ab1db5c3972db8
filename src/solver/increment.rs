//! The solver over a whole load path: increments, cutbacks and growth, the observer after each
//! converged increment.

use super::*;
use crate::assembly::{AssemblyFailure, Evaluation};
use crate::contact::eval::ContactEval;
use crate::contact::ContactChoice;
use crate::element::ElementFailure;
use crate::linalg::KeptFactor;
use crate::material::Branch;
use crate::model::SolverSettings;
use std::time::Instant;

impl Solver<'_> {
    /// Run the whole load history.
    pub fn run(
        &mut self,
        opts: &RunOptions,
        observer: &mut dyn Observer,
    ) -> Result<Results, AnalysisError> {
        let span = Span {
            from: None,
            to: self.model.times.len(),
            keep_every: 0,
            keep_factor: false,
        };
        self.run_span(&span, opts, observer, &mut Vec::new())
    }

    /// Run the user's increments of `span`: from its resume point (or the start) to the end
    /// of user increment `span.to`, pushing a [`Resume`] onto `resumes` at the end of every
    /// `span.keep_every`-th user increment (counted from the start of the load history). A
    /// run resumed from a point another run kept goes on exactly as that run did, bit for bit:
    /// the resume point holds everything the solver carries from one user increment into
    /// the next (Newton's last factorization too where `span.keep_factor`). The results of a
    /// resumed run start at its resume point.
    pub fn run_span(
        &mut self,
        span: &Span<'_>,
        opts: &RunOptions,
        observer: &mut dyn Observer,
        resumes: &mut Vec<Resume>,
    ) -> Result<Results, AnalysisError> {
        let model = self.model;
        let (mut run, first) = match span.from {
            None => (self.begin(opts)?, 0),
            Some(r) => (self.resume(r, opts)?, r.user),
        };
        let to = span.to.min(model.times.len());
        for (u, &t_end) in model.times.iter().enumerate().take(to).skip(first) {
            self.user_increment(&mut run, t_end, opts, observer)?;
            // the last resume point's factorization, where the increment after it factored
            // (or failed to) before it converged, is never read: a run resumed there does the
            // same
            if run.resume_factor_held == Some(false) {
                if let Some(f) = resumes.last_mut().and_then(|r| r.factored.as_mut()) {
                    f.factor = None;
                }
            }
            run.resume_factor_held = None;
            if span.keep_every > 0 && (u + 1) % span.keep_every == 0 && u + 1 < to {
                let resume = self.resume_point(&run, u + 1, span.keep_factor);
                if resume.factored.as_ref().is_some_and(|f| f.factor.is_some()) {
                    run.factors_at_resume = Some(self.linear.factor_count());
                }
                resumes.push(resume);
            }
        }
        Ok(run.finish(opts))
    }

    /// What the solver carries into user increment `user` (0-based) from `run`, with
    /// Newton's last factorization if `keep_factor`.
    fn resume_point(&self, run: &Run, user: usize, keep_factor: bool) -> Resume {
        Resume {
            user,
            z: run.z.clone(),
            hist: run.hist.clone(),
            t_prev: run.t_prev,
            previous: run.previous.clone(),
            index: run.index,
            suggested: run.suggested,
            converged_choice: self.converged_choice.clone(),
            force_history: self.force_history,
            factored: keep_factor.then(|| Factored {
                factor: self.linear.keep(),
                choice: self.factored_choice.clone(),
                branches: self.factored_branches.clone(),
            }),
        }
    }

    /// A run set up to go on from resume point `r`.
    fn resume(&mut self, r: &Resume, opts: &RunOptions) -> Result<Run, AnalysisError> {
        let start = Instant::now();
        self.deadline = opts.deadline(start);
        self.force_history = r.force_history;
        self.converged_choice.clone_from(&r.converged_choice);
        match &r.factored {
            Some(f) => {
                self.linear.restore(f.factor.as_ref())?;
                self.factored_choice.clone_from(&f.choice);
                self.factored_branches.clone_from(&f.branches);
            }
            // no factorization at hand, rather than one of another segment
            None => {
                self.linear.restore(None)?;
                self.factored_choice.clear();
                self.factored_branches.clear();
            }
        }
        let ne = self.model.mesh.n_elements();
        let mut res = Results::default();
        res.times.push(r.t_prev);
        res.contact_flat = self.assembler.contact.flat.clone();
        Ok(Run {
            start,
            res,
            z: r.z.clone(),
            hist: r.hist.clone(),
            eval: Evaluation::<f64>::new(&self.assembler, ne),
            t_prev: r.t_prev,
            previous: r.previous.clone(),
            index: r.index,
            suggested: r.suggested,
            factors_at_resume: None,
            resume_factor_held: None,
        })
    }

    /// Set up a run: the deadline, the initial state and history, the start state's contact
    /// states, and the results' entries of the initial state.
    fn begin(&mut self, opts: &RunOptions) -> Result<Run, AnalysisError> {
        let start = Instant::now();
        self.deadline = opts.deadline(start);
        self.force_history = (0.0, 0);
        self.relaxing_modes = false;
        let model = self.model;
        let n = self.assembler.dofs.n_total;
        let ne = model.mesh.n_elements();
        let mut res = Results::default();
        let z = vec![0.0; n];
        let hist = crate::contact::assembly::initial_history(
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
        Ok(Run {
            start,
            res,
            z,
            hist,
            eval,
            t_prev: 0.0,
            previous: None,
            index: 0,
            suggested: f64::INFINITY,
            factors_at_resume: None,
            resume_factor_held: None,
        })
    }

    /// One of the user's increments, to `t_end`: sub-increments until it is reached, the
    /// step cut back after a failed attempt and grown after an easy one.
    fn user_increment(
        &mut self,
        run: &mut Run,
        t_end: f64,
        opts: &RunOptions,
        observer: &mut dyn Observer,
    ) -> Result<(), AnalysisError> {
        let max_cutbacks = self.model.solver.max_cutbacks;
        let mut inc = UserIncrement::new(run, t_end, max_cutbacks);
        while run.t_prev < t_end - 1e-14 * t_end.abs().max(1.0) {
            let t = (run.t_prev + inc.step).min(t_end);
            inc.attempts += 1;
            // a budget of failed attempts per increment: halving after halving, and
            // sub-increments that converge only to fail again, end here rather than
            // creeping on at the smallest step (the curved punch spent 11 minutes
            // in 47-iteration attempts before the remedies)
            if inc.failed >= FAILED_ATTEMPTS_PER_STEP * max_cutbacks.max(1) {
                return Err(inc.over_budget(run, t));
            }
            self.relaxing_modes = inc.failed > 0;
            let (attempt, trial) = self.try_increment(run, t, inc.cutbacks)?;
            match attempt {
                Ok(factored) => {
                    let iterations = trial.record.iterations;
                    self.commit_increment(run, trial, factored, opts, observer)?;
                    inc.next_step(run, iterations, &self.model.solver);
                }
                Err(AttemptFailure::TimeLimit) => {
                    return Err(AnalysisError::TimeLimit {
                        increment: run.index + 1,
                        time: t,
                        seconds: opts.time_limit.unwrap_or(0.0),
                        partial: run.partial(),
                    });
                }
                Err(why) => self.cut_back(run, &mut inc, why, trial)?,
            }
        }
        Ok(())
    }

    /// An attempt at the sub-increment to `t` from the last converged state: the predictor,
    /// Newton's iterations, and the augmented-Lagrangian passes. Returns whether it
    /// converged (and then whether it factored), and what it computed.
    fn try_increment(
        &mut self,
        run: &mut Run,
        t: f64,
        cutbacks: usize,
    ) -> Result<(Result<bool, AttemptFailure>, Trial), AnalysisError> {
        let mut z_try = run.z.clone();
        self.set_prescribed(&mut z_try, t);
        let mut record = IncrementRecord {
            index: run.index + 1,
            time: t,
            iterations: 0,
            residuals: Vec::new(),
            energies: Vec::new(),
            corrections: Vec::new(),
            reference_force: 0.0,
            cutbacks,
            augmentations: 0,
            active_set_solves: 0,
        };
        let predicted = if self.extrapolate(run, &mut z_try, t) {
            Ok(false)
        } else {
            self.predict(
                &run.z,
                &mut z_try,
                &run.hist,
                t,
                &mut run.eval,
                &mut run.res.cost,
            )?
        };
        // the history the increment is solved with: h_{n-1}, with the multiplier
        // estimates of augmented-Lagrangian pairs updated between passes
        let hist_inc = run.hist.clone();
        let attempt = match predicted {
            Ok(factored) => self
                .attempt(
                    &mut z_try,
                    &hist_inc,
                    t,
                    &mut run.eval,
                    &mut record,
                    &mut run.res.cost,
                )
                .map(|f| {
                    if factored {
                        record.iterations += 1;
                    }
                    f || factored
                }),
            Err(why) => Err(why),
        };
        let mut trial = Trial {
            t,
            z: z_try,
            hist: hist_inc,
            record,
        };
        let attempt = self.augment(run, &mut trial, attempt);
        Ok((attempt, trial))
    }

    /// Predictor. Where the load path goes straight on from the last converged
    /// increment, extrapolate its solution linearly (free, and second-order
    /// accurate on a smooth path, like Abaqus' default within a step); otherwise
    /// (first increment, a reversal or a kink of any amplitude) linearise about
    /// the converged state ([`Solver::predict`]). Returns whether it extrapolated into
    /// `z_try`.
    fn extrapolate(&self, run: &Run, z_try: &mut [f64], t: f64) -> bool {
        let model = self.model;
        let t_prev = run.t_prev;
        match &run.previous {
            Some((z_old, t_old))
                if model.solver.extrapolate && model.load_path_straight(*t_old, t_prev, t) =>
            {
                let ratio = (t - t_prev) / (t_prev - t_old);
                for (d, zt) in z_try.iter_mut().enumerate() {
                    if !self.constrained[d] {
                        *zt = run.z[d] + ratio * (run.z[d] - z_old[d]);
                    }
                }
                true
            }
            _ => false,
        }
    }

    /// Augmented Lagrangian (Uzawa, Aitken-accelerated: [`crate::contact::assembly::augment`]):
    /// move lambda_bar towards p_n and solve again from the converged state until the
    /// constraint is met within tolerance; where the first pass and [`MAX_AUGMENTATIONS`] more
    /// do not get there, the attempt fails. A pass that fails after a converged one goes back
    /// to that pass and moves lambda_bar by a quarter of the step it took, and the later passes
    /// of the increment by a quarter of theirs ([`AUGMENTATION_BACKTRACKS`] times at most,
    /// each a quarter again): where the estimates change the friction bounds of nodes at the
    /// Coulomb limit, or release nodes of an unloading pair, a full update can leave Newton
    /// cycling between stick, slip and open. `attempt` is the first pass's outcome; returns the
    /// last one's.
    fn augment(
        &mut self,
        run: &mut Run,
        trial: &mut Trial,
        mut attempt: Result<bool, AttemptFailure>,
    ) -> Result<bool, AttemptFailure> {
        let mut augmentations = 0;
        let mut memory = crate::contact::assembly::Augmentation::default();
        // the last converged pass (its unknowns, the estimates it was solved with, its
        // contact forces and gaps), kept where a pair is augmented
        let augmented = self.model.contacts.iter().any(|p| p.augmented());
        let mut converged: Option<(Vec<f64>, Vec<f64>, ContactEval<f64>)> = None;
        let (mut damping, mut backtracks) = (1.0, 0);
        loop {
            let factored = match &attempt {
                Ok(f) => {
                    if augmented {
                        // into the last pass's buffers once there is one
                        match &mut converged {
                            Some((z, hist, contact)) => {
                                z.clone_from(&trial.z);
                                hist.clone_from(&trial.hist);
                                contact.clone_from(&run.eval.contact);
                            }
                            None => {
                                converged = Some((
                                    trial.z.clone(),
                                    trial.hist.clone(),
                                    run.eval.contact.clone(),
                                ))
                            }
                        }
                    }
                    *f
                }
                Err(AttemptFailure::TimeLimit) => break,
                Err(why) => match &converged {
                    Some((z, hist, contact)) if backtracks < AUGMENTATION_BACKTRACKS => {
                        if self.trace {
                            eprintln!(
                                "    augmentation: the pass failed ({why}): back to the last \
                                 converged pass, its update x {}",
                                damping * AUGMENTATION_BACKTRACK_STEP
                            );
                        }
                        trial.z.clone_from(z);
                        trial.hist.clone_from(hist);
                        run.eval.contact.clone_from(contact);
                        damping *= AUGMENTATION_BACKTRACK_STEP;
                        backtracks += 1;
                        // Aitken's factor restarts from the shortened step
                        memory = crate::contact::assembly::Augmentation::default();
                        false
                    }
                    _ => break,
                },
            };
            if !crate::contact::assembly::augment(
                self.model,
                &self.assembler.contact,
                &run.eval.contact,
                &mut trial.hist,
                &mut memory,
                self.trace,
                damping,
            ) {
                // no update: the last pass converged within the tolerance (a restored pass
                // violated it, so one is always made after a backtrack)
                attempt = attempt.or(Ok(factored));
                break;
            }
            if augmentations >= MAX_AUGMENTATIONS {
                attempt = Err(AttemptFailure::Diverged("augmentation limit"));
                break;
            }
            augmentations += 1;
            let mut again = trial.record.clone();
            again.residuals.clear();
            again.corrections.clear();
            attempt = self
                .attempt(
                    &mut trial.z,
                    &trial.hist,
                    trial.t,
                    &mut run.eval,
                    &mut again,
                    &mut run.res.cost,
                )
                .map(|f| {
                    trial.record.iterations += again.iterations;
                    trial.record.residuals.extend(&again.residuals);
                    f || factored
                });
        }
        trial.record.augmentations = augmentations;
        attempt
    }

    /// A converged sub-increment: the observer sees it, then it becomes the last converged
    /// state (history committed, contact states kept for the next predictor, results stored).
    fn commit_increment(
        &mut self,
        run: &mut Run,
        trial: Trial,
        factored: bool,
        opts: &RunOptions,
        observer: &mut dyn Observer,
    ) -> Result<(), AnalysisError> {
        let t = trial.t;
        run.index += 1;
        if let Some(n) = run.factors_at_resume.take() {
            run.resume_factor_held =
                Some(self.linear.factor_count() == n && self.linear.is_factored());
        }
        let conv = Converged {
            model: self.model,
            assembler: &self.assembler,
            lifted: &self.lifted,
            index: run.index,
            time: t,
            time_prev: run.t_prev,
            z: &trial.z,
            hist_prev: &trial.hist,
            eval: &run.eval,
            constrained: &self.constrained,
            // the last Newton factorization, of this increment or, when it
            // converged without iterating, of an earlier one
            last_factor: if factored || self.linear.is_factored() {
                Some(&self.linear)
            } else {
                None
            },
            tangent: &self.matrix,
            factor_matches: self.factored_choice == run.eval.contact.choice
                && self.factored_branches == run.eval.branches,
            record: &trial.record,
        };
        observer.converged(&conv)?;
        run.previous = Some((std::mem::replace(&mut run.z, trial.z), run.t_prev));
        run.hist.copy_from_slice(&run.eval.hist_new);
        self.keep_contact_states(&run.eval.contact.choice);
        let (res, eval) = (&mut run.res, &run.eval);
        res.times.push(t);
        if opts.keep_states {
            res.states.push(run.z.clone());
            res.residuals.push(eval.residual.clone());
            res.histories.push(run.hist.clone());
            res.contact.push(eval.contact.clone());
        }
        res.stresses.push(eval.cauchy.clone());
        res.branches.push(eval.branches.clone());
        self.force_history.0 += trial.record.reference_force;
        self.force_history.1 += 1;
        res.records.push(trial.record);
        run.t_prev = t;
        Ok(())
    }

    /// The body of element `e` if the element has incompatible modes (the advice of
    /// [`Solver::inversion_advice`] and of a cycle of material branches).
    pub(super) fn incompatible_modes_body(&self, e: usize) -> Option<usize> {
        (self.modes_elements.binary_search(&e).is_ok())
            .then(|| self.model.element_body(e))
            .flatten()
    }

    /// What to try when the attempt failed on an inverted incompatible-modes element: its
    /// enhanced modes can invert a Gauss point under large compressive (plastic) strain where
    /// F-bar may hold (the fuzzer's open corpus: three of its five element failures, seeds 451,
    /// 465 and 526, are J2 bodies with incompatible modes that complete their whole path with
    /// F-bar; seed 102 inverts with F-bar too, at its mesh's distortion limit). Empty
    /// otherwise.
    fn inversion_advice(&self, why: &AttemptFailure) -> String {
        let AttemptFailure::Element(AssemblyFailure::Element {
            element,
            failure: ElementFailure::Inverted { .. },
        }) = why
        else {
            return String::new();
        };
        let Some(body) = self.incompatible_modes_body(*element) else {
            return String::new();
        };
        let body = format!(" '{}'", self.model.bodies[body].name);
        format!(
            "; the element's body{body} has incompatible modes, whose enhanced modes can invert a Gauss point under large compressive strain: formulation = \"f-bar\" may hold there"
        )
    }

    /// A failed attempt: halve the step, or stop once the halvings in a row or the step
    /// reach their limit, or at once on a bad mesh.
    fn cut_back(
        &self,
        run: &mut Run,
        inc: &mut UserIncrement,
        why: AttemptFailure,
        mut trial: Trial,
    ) -> Result<(), AnalysisError> {
        let (t, t_end, step) = (trial.t, inc.t_end, inc.step);
        let max_cutbacks = self.model.solver.max_cutbacks;
        let at_minimum = step <= inc.min_step * (1.0 + 1e-9);
        if inc.cutbacks >= max_cutbacks || at_minimum {
            let mut reason = why.to_string();
            reason.push_str(&self.inversion_advice(&why));
            reason.push_str(&format!(
                " ({} halvings in a row{}; {} failed attempts within the increment ending at t = {t_end})",
                inc.cutbacks,
                if at_minimum {
                    format!(
                        ", down to the smallest step {:.3e}: the nominal one halved {} times",
                        inc.min_step, max_cutbacks
                    )
                } else {
                    String::new()
                },
                inc.failed + 1
            ));
            return Err(AnalysisError::Diverged {
                increment: run.index + 1,
                time: t,
                step,
                cutbacks: inc.failed + 1,
                residuals: trial.record.residuals,
                reason,
                partial: run.partial(),
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
                run.index + 1,
                trial.record.residuals
            );
        }
        let why = format!("{why}{}", self.inversion_advice(&why));
        inc.last_failure = Some((t, std::mem::take(&mut trial.record.residuals), why));
        inc.failed += 1;
        inc.cutbacks += 1;
        inc.step *= 0.5;
        Ok(())
    }
}

/// What a run carries from one increment to the next.
/// The user's increments a run covers ([`Solver::run_span`]).
#[derive(Clone, Copy, Debug)]
pub struct Span<'r> {
    /// The resume point it starts from (`None`: the start of the load history).
    pub from: Option<&'r Resume>,
    /// The user increments it ends after (the whole load history: `Model::times.len()`).
    pub to: usize,
    /// Keep a resume point after every `keep_every`-th user increment (0: none).
    pub keep_every: usize,
    /// The resume points keep Newton's last factorization: an increment of the resumed run
    /// that converges without factoring reports it as its last ([`Converged::last_factor`]),
    /// as the run that kept the point did. At most one factorization per resume point, for
    /// the adjoint's solves with Newton's factors (`--tangent last|refined`, GMRES). Without
    /// it a resumed run reports no factorization until it makes one.
    pub keep_factor: bool,
}

/// Everything the solver carries from the end of one user increment into the next: the
/// converged state and committed history, the predictor's previous state, the step the last
/// sub-increment suggests, the contact states the next first iteration starts from and the
/// mean reference force, and where asked ([`Span::keep_factor`]) Newton's last factorization.
/// A run resumed from it ([`Solver::run_span`]) is the run that kept it, bit for bit (the
/// adjoint's checkpoints): its states, and the factorization each increment reports where the
/// point kept it.
#[derive(Clone, Debug)]
pub struct Resume {
    /// User increments done (the next one's index, 0-based).
    pub user: usize,
    z: Vec<f64>,
    hist: Vec<f64>,
    t_prev: f64,
    previous: Option<(Vec<f64>, f64)>,
    index: usize,
    suggested: f64,
    converged_choice: Vec<ContactChoice>,
    force_history: (f64, usize),
    factored: Option<Factored>,
}

/// Newton's last factorization at a resume point and the contact choices and branches it
/// was assembled on. No factorization where none was made yet, or where the increment after
/// the point factored before it converged (no increment of a resumed run reads it then).
#[derive(Clone, Debug)]
struct Factored {
    factor: Option<KeptFactor>,
    choice: Vec<ContactChoice>,
    branches: Vec<Branch>,
}

impl Resume {
    /// Converged increments (sub-increments counted) done.
    pub fn increments(&self) -> usize {
        self.index
    }

    /// Bytes it keeps (a factorization in full, however many others share it).
    pub fn bytes(&self) -> usize {
        let prev = self.previous.as_ref().map_or(0, |p| p.0.len());
        let factored = self.factored.as_ref().map_or(0, |f| {
            f.factor.as_ref().map_or(0, KeptFactor::bytes)
                + std::mem::size_of::<ContactChoice>() * f.choice.len()
                + std::mem::size_of::<Branch>() * f.branches.len()
        });
        8 * (self.z.len() + self.hist.len() + prev)
            + std::mem::size_of::<ContactChoice>() * self.converged_choice.len()
            + factored
    }
}

struct Run {
    /// When it started.
    start: Instant,
    /// The results so far.
    res: Results,
    /// The last converged state and its committed history.
    z: Vec<f64>,
    hist: Vec<f64>,
    /// The evaluation every attempt assembles into.
    eval: Evaluation<f64>,
    /// The time of the last converged state.
    t_prev: f64,
    /// The converged state before `z` and its time: the extrapolating predictor's.
    previous: Option<(Vec<f64>, f64)>,
    /// Converged increments (sub-increments counted).
    index: usize,
    /// The step the last converged increment suggests for the next (halved after a hard
    /// one, doubled after an easy one), carried into the next of the user's increments.
    suggested: f64,
    /// Newton's successful factorizations when the run kept a resume point with a
    /// factorization, until the increment after it converges.
    factors_at_resume: Option<usize>,
    /// Whether the solver still held the resume point's factorization (none made since,
    /// none failed) when that increment converged: else no later increment reads it.
    resume_factor_held: Option<bool>,
}

impl Run {
    /// The results so far, for an error that stops the run.
    fn partial(&mut self) -> Box<Results> {
        let mut res = std::mem::take(&mut self.res);
        res.history = std::mem::take(&mut self.hist);
        res.cost.wall_seconds = self.start.elapsed().as_secs_f64();
        Box::new(res)
    }

    /// The results of a run that reached the end of the load history.
    fn finish(self, opts: &RunOptions) -> Results {
        let mut res = self.res;
        if !opts.keep_states {
            res.states.push(self.z);
        }
        res.history = self.hist;
        res.cost.wall_seconds = self.start.elapsed().as_secs_f64();
        res
    }
}

/// One of the user's increments, solved in sub-increments.
struct UserIncrement {
    /// Where it ends.
    t_end: f64,
    /// Where it starts.
    t_start: f64,
    /// Its length.
    nominal: f64,
    /// The step of the next attempt.
    step: f64,
    /// The smallest sub-increment: max_cutbacks halvings of the nominal one (the
    /// cutback counter restarts after every converged sub-increment, so without it a
    /// run creeping towards a limit point halves its step down to round-off).
    min_step: f64,
    /// Failed attempts since the last converged sub-increment.
    cutbacks: usize,
    /// Every attempt (converged or not) within this nominal increment; a budget keeps a
    /// converge-grow-fail cycle from running forever.
    attempts: usize,
    /// Failed attempts within this nominal increment (`cutbacks` counts only those since
    /// the last converged sub-increment), and the residuals and reason of the last one:
    /// the attempt budget's error reports them.
    failed: usize,
    last_failure: Option<(f64, Vec<f64>, String)>,
}

/// An attempt at a sub-increment: its end time, the unknowns, the history it is solved with
/// (h_{n-1}, with the multiplier estimates of augmented-Lagrangian pairs updated between
/// passes), and Newton's record.
struct Trial {
    t: f64,
    z: Vec<f64>,
    hist: Vec<f64>,
    record: IncrementRecord,
}

impl UserIncrement {
    /// The user's increment from the last converged state of `run` to `t_end`, its first
    /// step the one the last converged increment suggests (at most the whole increment).
    fn new(run: &Run, t_end: f64, max_cutbacks: usize) -> Self {
        let t_start = run.t_prev;
        let nominal = t_end - t_start;
        UserIncrement {
            t_end,
            t_start,
            nominal,
            step: nominal.min(run.suggested),
            min_step: nominal / 2f64.powi(max_cutbacks as i32),
            cutbacks: 0,
            attempts: 0,
            failed: 0,
            last_failure: None,
        }
    }

    /// The error that ends a user's increment whose failed attempts exceed the budget (the
    /// next attempt would have aimed at `t`).
    fn over_budget(&mut self, run: &mut Run, t: f64) -> AnalysisError {
        let partial = run.partial();
        let (t_failed, residuals, why) = self.last_failure.take().unwrap_or_default();
        let (failed, t_end) = (self.failed, self.t_end);
        AnalysisError::Diverged {
            increment: run.index + 1,
            time: t,
            step: self.step,
            cutbacks: failed,
            residuals,
            reason: format!(
                "{failed} failed attempts within the increment ending at t = {t_end} ({} sub-increments of it converged); the last failed attempt, to t = {t_failed:.9}: {why}",
                self.attempts - 1 - failed
            ),
            partial,
        }
    }

    /// The step after a sub-increment that converged in `iterations`: automatic
    /// incrementation, the user's increment the largest step: grow a cut-back step again
    /// after an easy increment, shrink the next step after a hard one (as CalculiX and
    /// Abaqus do). The suggestion is the run's, for the next user's increment too.
    fn next_step(&mut self, run: &mut Run, iterations: usize, s: &SolverSettings) {
        let easy = iterations <= 4;
        let hard = s.shrink_after > 0 && iterations > s.shrink_after;
        let step = self.step;
        self.cutbacks = 0;
        run.suggested = if easy {
            2.0 * step
        } else if hard {
            // by a quarter, and to no less than a quarter of the user's
            // increment: an increment that is hard at any size (an active set
            // settling node by node) would otherwise halve the steps without
            // end (fuzzer seed 240: 178 increments for 13)
            (HARD_SHRINK * step)
                .max(self.nominal * HARD_FLOOR)
                .min(step)
        } else {
            step
        };
        self.step = run.suggested.min(self.t_end - self.t_start);
    }
}
