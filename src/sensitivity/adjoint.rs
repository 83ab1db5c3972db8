//! The adjoint method: a backward sweep over the stored converged increments.
//!
//! Each converged increment `n` solves `R_n(z_n, h_{n-1}, b) = 0` and commits the history
//! `h_n = H_n(z_n, h_{n-1}, b)` (the return maps of every Gauss point, and every frictional
//! node's stick anchor); `h_0 = H_0(b)`. A response `f = F_m(z_m, h_{m-1}, b)` read at
//! increment `m` has, with the multipliers `lambda_n` of the equilibrium and `mu_n` of the
//! history update, from `n = m` down to 1 (`mu_m = 0`):
//!
//! ```text
//! K_n^T lambda_n = d/dz_n [F_n + mu_n . H_n]                    (free unknowns; F_n = 0 for n != m)
//! mu_{n-1}       = d/dh_{n-1} [F_n + mu_n . H_n - lambda_n . R_n]
//! df/db          = sum_n d/db [F_n + mu_n . H_n - lambda_n . R_n] + mu_0 . dh_0/db
//! ```
//!
//! the `d/db` at the fixed state with the prescribed unknowns moving with the design. Every
//! response at every increment is one column of the sweep: the transposed solves are
//! multi-column, and the local Jacobians are computed once per increment for all columns.
//!
//! Nothing is differentiated by hand. What the sweep needs of the residual and the history
//! update are vector-Jacobian products: each column's cotangent on the outputs of an element
//! (its residual rows, history, stress) or a hitting node (its normal force, block rows,
//! history, force on the target), differentiated in the unknowns (before the transposed
//! solve, the residual's rows left out: their derivative is the tangent's) and in the
//! committed history (after it). They come from the same generic kernels, in one of two
//! ways ([`Settings::adjoint_reverse`]):
//!
//! * **reverse mode** ([`Rev`]): every solid element whose history moves or is read is
//!   recorded alone on the thread that evaluates it (in parallel), every colour of hitting
//!   nodes in one evaluation, once per increment for both phases; each column is then one
//!   backward sweep of each recording. A J2 hexahedron's recording is about 3,800 tape
//!   entries (4,200 with incompatible modes, 6,700 with F-bar; fewer where no response reads
//!   its stress: the Cauchy stress's sums and `det F` left out), its force summed from the
//!   stress without the tangent's B rows and a sum of products with a constant factor one
//!   entry a term ([`Scalar::add_mul`]); a recording and one sweep cost about ten times its
//!   `f64` residual, three times its residual and tangent (`cargo bench --bench kernels`);
//! * **forward duals**: `DualSVec64<W>` numbers seeded over each element's local unknowns (its
//!   degrees of freedom, then its history scalars) and each hitting node's (its block's
//!   unknowns, then its history); the elements are coloured so that no two of a colour
//!   share an unknown, and the hitting nodes so that no two of a colour share a block
//!   unknown, and one evaluation gives the local Jacobians of a whole colour, `W` inputs at a
//!   time, for every column at once.
//!
//! Reverse mode is the default while the columns alive at an increment are few
//! ([`REVERSE_COLUMNS`]); many columns (`--at all` on a long path) share the forward passes.
//! The residual's Jacobian in the unknowns is the tangent the forward run assembled at the
//! converged state, kept with each stored increment where the sweep reads it ([`Keep`]).
//! The derivatives in the design are one dual evaluation per parameter, as DDM's
//! pseudo-load, over the elements the parameter reaches (a field's members seeded a colour
//! at a time). A user material or friction law gets the adjoint with no code of its own.
//!
//! At a flagged (non-differentiable) increment the sweep follows the converged branches, as
//! DDM's main value does. The one-sided derivatives there ([`OneSided`]) are columns of their
//! own, two per response: at the flagged increment the stored state with every flagged point
//! forced onto one side ([`force_side`], DDM's forcing), its tangent assembled and factored
//! (GMRES preconditioned with the factorization at hand, DDM's way, took 26 and 27 steps on
//! the two sides of the leaf spring's last increment, three times a factorization's 5 ms)
//! and its local derivatives taken on those branches; before it, the converged branches, as
//! DDM carries the converged branches' history derivative into its forced solves. A side the
//! converged state is on, solved with its tangent, is the converged column itself (DDM's
//! rule, which saves its factorization). A side whose forced tangent is singular is left out
//! and says why ([`OneSided::failed`]); the other columns go on, as DDM's do.

use super::*;
use crate::assembly::{Assembler, Evaluation, Frozen};
use crate::contact::ContactChoice;
use crate::element::family::MAX_DOFS;
use crate::linalg::{KeptFactor, LinearSolver, SparseMatrix};
use crate::material::Branch;
use crate::model::{node_dof, DesignParam, Lifted};
use crate::response::{Response, ResponseKind};
use crate::scalar::{tape, Rev, Scalar};
use crate::solver::{AnalysisError, Converged, Observer, Resume, RunOptions, Solver, Span};
use crate::terms::Terms;
use nalgebra::{Matrix3, Vector3};
use num_dual::{Dual64, DualSVec64};
use num_traits::Zero;
use rayon::prelude::*;
use std::time::Instant;

/// The most columns for which the local derivatives are taken in reverse mode by default
/// ([`Settings::adjoint_reverse`]): its recording costs more than a forward pass, each of
/// its sweeps much less, and the forward passes serve every column at once. Measured on the
/// leaf spring's `--at all` (3 to 105 columns; local derivatives and the rest of the
/// sweep): forward alone 1.8 s, reverse alone 1.4 s, reverse up to 16 columns 1.5 s, up to
/// 64 columns 1.2 s. A J2 hexahedron takes 10 forward passes (24 unknowns and 56 history
/// scalars, 8 at a time); larger elements take more, which moves the crossover up.
const REVERSE_COLUMNS: usize = 64;

/// Directions per local-Jacobian evaluation.
const W: usize = 8;
type Ad = DualSVec64<W>;

/// Bytes of converged tangents the forward run keeps for the sweep (each segment's, with
/// checkpoints; [`Keep`] says which); beyond them an increment's tangent is assembled again
/// where the sweep reads it. On the leaf spring the 35 tangents take 44 MiB, one assembly
/// each saved (0.13 s of a 0.45 s sweep for one response, with the exact tangent).
const TANGENT_ROOM: usize = 1 << 30;

/// One converged increment, as the backward sweep needs it: on its converged branches, or on
/// a one-sided column's forced ones ([`Stored::forced`]).
struct Stored {
    index: usize,
    time: f64,
    z: Vec<f64>,
    hist_prev: Vec<f64>,
    branches: Vec<Branch>,
    choice: Vec<ContactChoice>,
    constrained: Vec<bool>,
    /// The values of the tangent assembled at the converged state (the assembler's pattern):
    /// the sweep's transposed solve needs no assembly of its own. Empty beyond
    /// [`TANGENT_ROOM`] (the sweep assembles it again), and where [`Keep::tangent`] keeps
    /// none (the sweep reads none there, but should the kept factorization fail).
    tangent: Vec<f64>,
    /// Newton's last factorization, where [`KeepFactors`] keeps it: for `--tangent
    /// last|refined` only where it was assembled on the converged branches (then it is the
    /// tangent), for GMRES any (a preconditioner).
    factor: Option<KeptFactor>,
}

/// Which of Newton's last factorizations the forward run keeps for the sweep.
#[derive(Debug, Clone, Copy, PartialEq)]
enum KeepFactors {
    /// None: the sweep factors every increment's converged tangent (`--tangent exact`, the
    /// default).
    None,
    /// Those assembled on the converged branches, the tangent of `--tangent last|refined`.
    Matching,
    /// Every one: GMRES's preconditioner on the converged tangent
    /// ([`Settings::adjoint_krylov`]).
    Any,
}

impl KeepFactors {
    fn of(settings: &Settings) -> Self {
        match (settings.tangent, settings.adjoint_krylov) {
            (TangentChoice::Exact, true) => KeepFactors::Any,
            (TangentChoice::Exact, false) => KeepFactors::None,
            _ => KeepFactors::Matching,
        }
    }
}

/// What the forward run (or a recomputed segment) keeps of a converged increment besides its
/// state: Newton's last factorization, and the converged tangent where the sweep reads it.
#[derive(Debug, Clone)]
struct Keep {
    factors: KeepFactors,
    /// Every increment keeps its tangent: the tangent options other than `--tangent last`
    /// factor it, refine or run GMRES against it.
    every: bool,
    /// With `--tangent last`, the sweep solves with the kept factorization and reads the
    /// tangent only for a reaction response's product, at the increments of the functionals:
    /// their times (empty: every increment), `None` where no response is a reaction. An
    /// increment with its factorization kept keeps no tangent elsewhere (on the leaf spring,
    /// whose block force is a target's, none of the 35, 1.3 MiB each).
    reactions_at: Option<Vec<f64>>,
}

impl Keep {
    fn of(settings: &Settings, model: &Model) -> Self {
        let reaction =
            (model.responses.iter()).any(|r| matches!(r.kind, ResponseKind::Reaction { .. }));
        Keep {
            factors: KeepFactors::of(settings),
            every: settings.tangent != TangentChoice::Last,
            reactions_at: reaction.then(|| settings.adjoint_at.clone()),
        }
    }

    /// Whether the increment converged at `time` keeps its tangent, its factorization kept
    /// or not.
    fn tangent(&self, time: f64, factor_kept: bool) -> bool {
        let read = |at: &Vec<f64>| at.is_empty() || at.iter().any(|t| (t - time).abs() < 1e-9);
        self.every || !factor_kept || self.reactions_at.as_ref().is_some_and(read)
    }
}

impl Stored {
    /// What the sweep needs of `c`, Newton's last factorization with it as `keep` says, its
    /// tangent where `keep` keeps it and `*tangent_room` bytes hold it (which it then takes
    /// from them).
    fn new(c: &Converged<'_>, keep: &Keep, tangent_room: &mut usize) -> Self {
        let kept = match keep.factors {
            KeepFactors::None => false,
            KeepFactors::Matching => c.factor_matches,
            KeepFactors::Any => true,
        };
        let factor = kept
            .then_some(c.last_factor)
            .flatten()
            .and_then(LinearSolver::keep);
        let values = c.tangent.values();
        let tangent = if keep.tangent(c.time, factor.is_some()) && 8 * values.len() <= *tangent_room
        {
            *tangent_room -= 8 * values.len();
            values.to_vec()
        } else {
            Vec::new()
        };
        Stored {
            factor,
            index: c.index,
            time: c.time,
            z: c.z.to_vec(),
            hist_prev: c.hist_prev.to_vec(),
            branches: c.eval.branches.clone(),
            choice: c.eval.contact.choice.clone(),
            constrained: c.constrained.to_vec(),
            tangent,
        }
    }

    /// The increment's branches and contact choices (converged, or forced).
    fn frozen(&self) -> Frozen<'_> {
        Frozen {
            gauss: Some(&self.branches),
            contact: &self.choice,
            ..Frozen::default()
        }
    }

    /// The increment on the branches `branches` and contact choices `choice` (a one-sided
    /// column's, [`force_side`]): no tangent and no factorization of the converged
    /// branches', so the sweep assembles and factors the tangent on those.
    fn forced(&self, branches: Vec<Branch>, choice: Vec<ContactChoice>) -> Self {
        Stored {
            index: self.index,
            time: self.time,
            z: self.z.clone(),
            hist_prev: self.hist_prev.clone(),
            branches,
            choice,
            constrained: self.constrained.clone(),
            tangent: Vec::new(),
            factor: None,
        }
    }

    fn bytes(&self) -> usize {
        8 * (self.z.len() + self.hist_prev.len() + self.tangent.len())
            + self.branches.len()
            + self.constrained.len()
            + std::mem::size_of::<ContactChoice>() * self.choice.len()
            + self.factor.as_ref().map_or(0, KeptFactor::bytes)
    }
}

/// What the forward pass keeps of every converged increment, checkpointed or not: its
/// number, time, response values and flagged points.
struct Light {
    index: usize,
    time: f64,
    values: Vec<f64>,
    kinks: Vec<Kink>,
}

/// The forward pass: every increment's [`Light`] record, the [`Stored`] states of the
/// increments from user increment `keep_from` on (all of them without checkpoints), the first
/// plastic increment of every element, the initial history's derivative and the flagged
/// points (by the in-line engine's rules).
struct Recorder<'a> {
    /// The in-line engine's rules for the flagged points (no parameters: it keeps nothing per
    /// parameter).
    engine: Engine<'a>,
    params: &'a [Parameter],
    /// `dh_0/db` per parameter (`None`: zero).
    dh0: Vec<Option<Vec<f64>>>,
    lights: Vec<Light>,
    stored: Vec<Stored>,
    /// The first user increment whose converged increments are stored.
    keep_from: usize,
    /// What the stored increments keep besides their states.
    keep: Keep,
    /// Per element: the first increment (position) at which a Gauss point of it is plastic
    /// (`usize::MAX`: not yet).
    first_plastic: Vec<usize>,
    /// Bytes left for the stored increments' tangents ([`TANGENT_ROOM`]).
    tangent_room: usize,
    watch: &'a mut dyn FnMut(&Converged<'_>),
    seconds: f64,
}

/// The user increment (0-based) converged increment `c` belongs to.
fn user_increment_of(c: &Converged<'_>) -> usize {
    let times = &c.model.times;
    let tol = 1e-12 * times.last().map_or(1.0, |t| t.abs().max(1.0));
    times.partition_point(|t| *t < c.time - tol)
}

impl Observer for Recorder<'_> {
    fn converged(&mut self, c: &Converged<'_>) -> Result<(), AnalysisError> {
        let t = Instant::now();
        if self.lights.is_empty() && !c.model.contacts.is_empty() {
            for p in self.params {
                let d = initial_history_derivative(c.model, c.assembler, p)?;
                self.dh0.push(d);
            }
        }
        let position = self.lights.len();
        let dofs = &c.assembler.dofs;
        for (e, first) in self.first_plastic.iter_mut().enumerate() {
            if *first == usize::MAX && c.eval.branches[dofs.gauss(e)].contains(&Branch::Plastic) {
                *first = position;
            }
        }
        self.lights.push(Light {
            index: c.index,
            time: c.time,
            values: response_values(c),
            kinks: self.engine.kinks(c),
        });
        if user_increment_of(c) >= self.keep_from {
            let s = Stored::new(c, &self.keep, &mut self.tangent_room);
            self.stored.push(s);
        }
        self.seconds += t.elapsed().as_secs_f64();
        (self.watch)(c);
        Ok(())
    }
}

/// A recomputed span's states, Newton's last factorizations and tangents with them as `.1`
/// says, the tangents while `.2` bytes hold them.
struct Keeper<'k>(Vec<Stored>, &'k Keep, usize);

impl Observer for Keeper<'_> {
    fn converged(&mut self, c: &Converged<'_>) -> Result<(), AnalysisError> {
        self.0.push(Stored::new(c, self.1, &mut self.2));
        Ok(())
    }
}

/// Where the backward sweep gets the stored increments from: segments between checkpoints,
/// the last one kept by the forward run, the others recomputed from their resume point when
/// the sweep reaches them ([`Solver::run_span`]: bit for bit the forward run's states).
struct Store<'m> {
    solver: Solver<'m>,
    /// Per segment: its resume point (`None`: the start; taken when the segment is
    /// fetched), the position of its first increment, and the user increment it ends after.
    segments: Vec<(Option<Resume>, usize, usize)>,
    /// The last segment's states, from the forward run.
    last: Vec<Stored>,
    /// Bytes of the resume points.
    resume_bytes: usize,
    /// What the recomputed increments keep besides their states.
    keep: Keep,
}

impl Store<'_> {
    /// The states of segment `k` (positions from `segments[k].1`): the forward run's for the
    /// last, recomputed from its resume point for the others.
    fn fetch(
        &mut self,
        k: usize,
        cost: &mut SensitivityCost,
    ) -> Result<Vec<Stored>, AnalysisError> {
        if k + 1 == self.segments.len() {
            return Ok(std::mem::take(&mut self.last));
        }
        // each segment is fetched once: its resume point (and factorization) freed after
        let (from, to) = (self.segments[k].0.take(), self.segments[k].2);
        let t = Instant::now();
        let span = Span {
            from: from.as_ref(),
            to,
            keep_every: 0,
            keep_factor: false,
        };
        let opts = RunOptions {
            keep_states: false,
            time_limit: None,
        };
        let mut keeper = Keeper(Vec::new(), &self.keep, TANGENT_ROOM);
        self.solver
            .run_span(&span, &opts, &mut keeper, &mut Vec::new())?;
        cost.recompute_seconds += t.elapsed().as_secs_f64();
        cost.recomputed_increments += keeper.0.len();
        Ok(keeper.0)
    }
}

/// Sensitivities of every response at every increment by the adjoint method.
pub(super) fn run_adjoint(
    model: &Model,
    params: &[Parameter],
    settings: &Settings,
    watch: &mut dyn FnMut(&Converged<'_>),
) -> Result<(Results, SensitivityResults), AnalysisError> {
    let users = model.times.len();
    let every = settings.adjoint_checkpoint;
    // segments start at user increments 0, every, 2 every, ...: the last one is kept
    let keep_from = if every == 0 || users == 0 {
        0
    } else {
        ((users - 1) / every) * every
    };
    let keep = Keep::of(settings, model);
    let mut rec = Recorder {
        keep: keep.clone(),
        engine: Engine::new(model, &[], settings.clone()),
        params,
        dh0: Vec::new(),
        lights: Vec::new(),
        stored: Vec::new(),
        keep_from,
        first_plastic: vec![usize::MAX; model.mesh.n_elements()],
        tangent_room: TANGENT_ROOM,
        watch,
        seconds: 0.0,
    };
    let mut solver = Solver::new(model)?;
    let span = Span {
        from: None,
        to: users,
        keep_every: every,
        // Newton's last factorization at a segment's first increment is the forward run's
        keep_factor: keep.factors != KeepFactors::None,
    };
    // checkpointed, the primal's results keep no state per increment either
    let opts = RunOptions {
        keep_states: every == 0,
        time_limit: settings.time_limit,
    };
    let mut resumes = Vec::new();
    let res = solver.run_span(&span, &opts, &mut rec, &mut resumes)?;
    let Recorder {
        engine,
        lights,
        stored,
        seconds,
        dh0,
        first_plastic,
        ..
    } = rec;
    let mut out = engine.results;
    out.parameters = params.iter().map(|p| p.name.clone()).collect();
    out.primal_seconds = res.cost.wall_seconds - seconds;
    let t = Instant::now();
    // the increments whose responses are the functionals
    let sel: Vec<usize> = if settings.adjoint_at.is_empty() {
        (0..lights.len()).collect()
    } else {
        let mut sel = Vec::new();
        for at in &settings.adjoint_at {
            let m = (lights.iter())
                .position(|s| (s.time - at).abs() < 1e-9)
                .ok_or(SensitivityError::NoIncrementAt { time: *at })?;
            sel.push(m);
        }
        sel.sort_unstable();
        sel.dedup();
        sel
    };
    let resume_bytes = resumes.iter().map(Resume::bytes).sum();
    let last_bytes: usize = stored.iter().map(Stored::bytes).sum();
    let mut segments: Vec<(Option<Resume>, usize, usize)> = vec![(None, 0, 0)];
    for r in resumes {
        let user = r.user;
        segments.last_mut().expect("one at least").2 = user;
        let first = r.increments();
        segments.push((Some(r), first, 0));
    }
    segments.last_mut().expect("one at least").2 = users;
    let mut store = Store {
        solver,
        segments,
        last: stored,
        resume_bytes,
        keep,
    };
    let tangent = SweepTangent {
        choice: settings.tangent,
        refine_steps: settings.refine_steps,
        krylov: settings.adjoint_krylov,
    };
    let sweep = Sweep::new(
        model,
        store.solver.assembler.clone(),
        params,
        first_plastic,
        tangent,
        settings.adjoint_reverse,
    );
    // every response at every selected increment, then at the flagged ones the one-sided
    // columns, the lower side's and the upper's
    let nr = model.responses.len();
    let columns: Vec<Column> = (sel.iter())
        .flat_map(|&at| (0..nr).map(move |response| (at, response, None)))
        .chain(
            (sel.iter()
                .filter(|&&m| settings.one_sided && !lights[m].kinks.is_empty()))
            .flat_map(|&at| {
                [false, true]
                    .into_iter()
                    .flat_map(move |upper| (0..nr).map(move |r| (at, r, Some(upper))))
            }),
        )
        .map(|(at, response, side)| Column { at, response, side })
        .collect();
    let mut cost = SensitivityCost::default();
    let kinks = |m: usize| lights[m].kinks.as_slice();
    let times = |m: usize| lights[m].time;
    let (dfdb, failed) = sweep.run(&columns, kinks, &dh0, &mut cost, &mut store, times)?;
    out.cost = cost;
    out.cost.wall_seconds = seconds + t.elapsed().as_secs_f64();
    out.cost.stored_bytes = out.cost.stored_bytes.max(last_bytes) + store.resume_bytes;
    out.cost.checkpoints = store.segments.len() - 1;
    let of = |at: usize, side: Option<bool>| -> Vec<Vec<f64>> {
        (columns.iter().zip(&dfdb))
            .filter(|(c, _)| c.at == at && c.side == side)
            .map(|(_, d)| d.clone())
            .collect()
    };
    for &m in &sel {
        let s = &lights[m];
        out.increments.push(IncrementSensitivity {
            increment: s.index,
            time: s.time,
            values: s.values.clone(),
            derivatives: of(m, None),
            kinks: s.kinks.clone(),
            one_sided: (settings.one_sided && !s.kinks.is_empty()).then(|| {
                // a failed side's columns all carry the same line
                let why = |side: bool| {
                    (columns.iter().zip(&failed))
                        .find(|(c, _)| c.at == m && c.side == Some(side))
                        .and_then(|(_, f)| f.clone())
                };
                let (lower, upper) = (why(false), why(true));
                OneSided {
                    lower: lower.is_none().then(|| of(m, Some(false))),
                    upper: upper.is_none().then(|| of(m, Some(true))),
                    failed: lower.into_iter().chain(upper).collect(),
                }
            }),
            ..Default::default()
        });
    }
    Ok((res, out))
}

/// Why each column has no derivatives, where it has none ([`Sweep::run`]).
type Failures = Vec<Option<String>>;

/// One output of an evaluation: a scalar a response reads, and a row of the local
/// Jacobians.
#[derive(Clone, Copy)]
enum Entry {
    /// An unknown itself (a displacement response).
    Z(usize),
    /// A residual row (reactions; `-lambda` on the free rows after the solve).
    Res(usize),
    /// An updated history scalar (`mu`, and history responses).
    Hist(usize),
    /// A hitting node's normal force.
    Nf(usize),
    /// A hitting node's nominal area (the design's alone).
    Area(usize),
    /// A hitting node's current area.
    CArea(usize),
    /// A pair's target force, by component.
    Pf(usize, usize),
    /// A pair's target translation, by component.
    Tr(usize, usize),
    /// A stress a response reads (`Assembler::stress_elements` slot), row-major component.
    Stress(usize, usize),
}

/// Where each [`Entry`] sits in a cotangent: one flat vector per column of the sweep, what
/// the column weighs each output with.
struct Outputs {
    n: usize,
    nh: usize,
    nk: usize,
    np: usize,
    ns: usize,
}

impl Outputs {
    fn new(asm: &Assembler, n_pairs: usize) -> Self {
        Outputs {
            n: asm.dofs.n_total,
            nh: asm.dofs.n_history,
            nk: asm.contact.n_hitting,
            np: n_pairs,
            ns: asm.stress_elements.len(),
        }
    }

    fn len(&self) -> usize {
        2 * self.n + self.nh + 3 * self.nk + 6 * self.np + 9 * self.ns
    }

    fn index(&self, e: Entry) -> usize {
        let (n, nh, nk, np) = (self.n, self.nh, self.nk, self.np);
        let contact = 2 * n + nh;
        match e {
            Entry::Z(i) => i,
            Entry::Res(i) => n + i,
            Entry::Hist(i) => 2 * n + i,
            Entry::Nf(k) => contact + k,
            Entry::Area(k) => contact + nk + k,
            Entry::CArea(k) => contact + 2 * nk + k,
            Entry::Pf(p, c) => contact + 3 * nk + 3 * p + c,
            Entry::Tr(p, c) => contact + 3 * nk + 3 * np + 3 * p + c,
            Entry::Stress(s, i) => contact + 3 * nk + 6 * np + 9 * s + i,
        }
    }

    fn z(&self) -> std::ops::Range<usize> {
        0..self.n
    }

    fn res(&self) -> std::ops::Range<usize> {
        self.n..2 * self.n
    }

    fn hist(&self) -> std::ops::Range<usize> {
        2 * self.n..2 * self.n + self.nh
    }

    fn carea(&self, range: std::ops::Range<usize>) -> std::ops::Range<usize> {
        let at = self.index(Entry::CArea(0));
        at + range.start..at + range.end
    }
}

/// The scalars response `r` reads (the support of its value).
fn support(r: &Response, asm: &Assembler) -> Vec<Entry> {
    match &r.kind {
        ResponseKind::Reaction { nodes, component } => nodes
            .iter()
            .map(|n| Entry::Res(node_dof(*n, *component)))
            .collect(),
        ResponseKind::Displacement { nodes, component } => nodes
            .iter()
            .map(|n| Entry::Z(node_dof(*n, *component)))
            .collect(),
        ResponseKind::History { index } => vec![Entry::Hist(*index)],
        ResponseKind::Stress { element, .. } => asm
            .stress_slot(*element)
            .map(|s| (0..9).map(|i| Entry::Stress(s, i)).collect())
            .unwrap_or_default(),
        ResponseKind::TargetForce { pair, component } => vec![Entry::Pf(*pair, *component)],
        ResponseKind::TargetDisplacement { pair, component } => {
            vec![Entry::Tr(*pair, *component)]
        }
        ResponseKind::ContactPressure { pair, nodes, .. } => nodes
            .iter()
            .flat_map(|i| {
                let k = asm.contact_flat(*pair) + i;
                [Entry::Nf(k), Entry::Area(k), Entry::CArea(k)]
            })
            .collect(),
    }
}

/// A response's input at a state in dual numbers, every derivative part zero.
struct DualInput {
    z: Vec<Dual64>,
    res: Vec<Dual64>,
    hist: Vec<Dual64>,
    contact: crate::contact::assembly::ContactEval<Dual64>,
    stress: Vec<Matrix3<Dual64>>,
}

impl DualInput {
    fn new(asm: &Assembler, z: &[f64], ev: &Evaluation<f64>) -> Self {
        let d = |v: &[f64]| -> Vec<Dual64> { v.iter().map(|x| Dual64::from_re(*x)).collect() };
        let d3 = |v: &[Vector3<f64>]| -> Vec<Vector3<Dual64>> {
            v.iter().map(|x| x.map(Dual64::from_re)).collect()
        };
        let c = &ev.contact;
        let mut contact = crate::contact::assembly::ContactEval::<Dual64>::new(
            asm.contact.n_hitting,
            asm.contact.lambda.len(),
        );
        contact.normal_force = d(&c.normal_force);
        contact.area = d(&c.area);
        contact.current_area = d(&c.current_area);
        contact.pair_force = d3(&c.pair_force);
        contact.translation = d3(&c.translation);
        DualInput {
            z: d(z),
            res: d(&ev.residual),
            hist: d(&ev.hist_new),
            contact,
            stress: ev.stress.iter().map(|s| s.map(Dual64::from_re)).collect(),
        }
    }

    fn slot(&mut self, e: Entry) -> &mut Dual64 {
        let c = &mut self.contact;
        match e {
            Entry::Z(i) => &mut self.z[i],
            Entry::Res(i) => &mut self.res[i],
            Entry::Hist(i) => &mut self.hist[i],
            Entry::Nf(k) => &mut c.normal_force[k],
            Entry::Area(k) => &mut c.area[k],
            Entry::CArea(k) => &mut c.current_area[k],
            Entry::Pf(p, i) => &mut c.pair_force[p][i],
            Entry::Tr(p, i) => &mut c.translation[p][i],
            Entry::Stress(s, i) => &mut self.stress[s][(i / 3, i % 3)],
        }
    }

    fn view<'a>(&'a self, asm: &'a Assembler) -> crate::response::ResponseInput<'a, Dual64> {
        crate::response::ResponseInput {
            z: &self.z,
            residual: &self.res,
            hist: &self.hist,
            contact: Some(&self.contact),
            flat: Some(&asm.contact.flat),
            stress: &self.stress,
            stress_elements: Some(&asm.stress_elements),
        }
    }
}

/// Adds response `r`'s cotangent on the evaluation's outputs at a state to `cot`: each scalar
/// it reads seeded alone in a dual number, through the response's own generic `value`.
fn response_cotangent(
    r: &Response,
    asm: &Assembler,
    outputs: &Outputs,
    input: &mut DualInput,
    cot: &mut [f64],
) {
    for e in support(r, asm) {
        input.slot(e).eps = 1.0;
        let g = r.value(&input.view(asm)).eps;
        input.slot(e).eps = 0.0;
        cot[outputs.index(e)] += g;
    }
}

/// The derivative parts of a `W`-wide dual.
#[inline]
fn parts(x: &Ad) -> [f64; W] {
    let mut p = [0.0; W];
    if let Some(v) = &x.eps.0 {
        for (a, b) in p.iter_mut().zip(v.iter()) {
            *a = *b;
        }
    }
    p
}

/// Greedy colouring of `items` (each a list of the unknowns it touches) so that no two items
/// of a colour share one: `colour[i]`, and the number of colours.
pub(super) fn colour(items: &[Vec<usize>], n: usize) -> (Vec<usize>, usize) {
    let mut taken: Vec<Vec<usize>> = vec![Vec::new(); n];
    let mut colours = vec![0; items.len()];
    let mut count = 0;
    for (i, touched) in items.iter().enumerate() {
        let mut c = 0;
        while touched.iter().any(|d| taken[*d].contains(&c)) {
            c += 1;
        }
        for d in touched {
            taken[*d].push(c);
        }
        colours[i] = c;
        count = count.max(c + 1);
    }
    (colours, count)
}

/// A mask of `len` entries, every one set but `members`' (the elements or hitting nodes a
/// pass leaves out).
fn all_but(members: &[usize], len: usize) -> Vec<bool> {
    let mut skip = vec![true; len];
    for &m in members {
        skip[m] = false;
    }
    skip
}

/// What a local pass seeds.
#[derive(Clone, Copy, PartialEq)]
enum Seeds {
    /// The unknowns.
    Z,
    /// The committed history.
    H,
}

/// One colour's local Jacobians ([`Sweep::local_passes`]).
struct Pass<'x> {
    seeds: Seeds,
    /// Per member: its local inputs, global indices into the unknowns or the history.
    inputs: Vec<Vec<usize>>,
    /// Elements left out of the evaluations.
    skip: &'x [bool],
    /// Hitting nodes left out of the evaluations.
    skip_contact: &'x [bool],
    terms: Terms,
}

/// The state in `W`-wide duals, the derivative parts zero but where a pass seeds them.
struct AdState {
    z: Vec<Ad>,
    h: Vec<Ad>,
}

impl AdState {
    fn new(s: &Stored) -> Self {
        let ad = |v: &[f64]| v.iter().map(|x| Ad::from_re(*x)).collect();
        AdState {
            z: ad(&s.z),
            h: ad(&s.hist_prev),
        }
    }

    /// Seed input `g` in direction `d` (`Some`), or clear it (`None`).
    fn seed(&mut self, s: &Stored, seeds: Seeds, g: usize, d: Option<usize>) {
        let (slot, re) = match seeds {
            Seeds::Z => (&mut self.z[g], s.z[g]),
            Seeds::H => (&mut self.h[g], s.hist_prev[g]),
        };
        *slot = match d {
            Some(d) => Ad::from_re(re).derivative(d),
            None => Ad::from_re(re),
        };
    }
}

/// Rows of one member's local Jacobian: the flat output index ([`Outputs`]) and the
/// derivative parts of that output.
type Rows = Vec<(usize, [f64; W])>;

/// Factors `k` into `ls`; returns the seconds it took.
fn factor_timed(
    ls: &mut LinearSolver,
    k: &SparseMatrix,
) -> Result<f64, crate::linalg::LinalgError> {
    let start = Instant::now();
    ls.factor(k)?;
    Ok(start.elapsed().as_secs_f64())
}

/// A parameter's partial derivatives at an increment, evaluated before its multipliers are
/// known: what every column reads of them but `-lambda . R_b` (its response's own part and
/// `mu . H_b`), and `R_b`.
struct DesignPartial {
    /// The parameter.
    p: usize,
    /// Per column.
    known: Vec<f64>,
    /// `R_b`'s nonzero entries, `(row, value)`: a nodal shape parameter reaches a few
    /// elements, and a field of them is as many parameters as the mesh has nodes.
    residual: Vec<(usize, f64)>,
}

/// One increment's transposed solve: the tangent at its converged state (the prescribed
/// unknowns' rows and columns made identity), Newton's last factorization if kept
/// ([`KeepFactors`]), and whether the sweep's solver holds the tangent's own factorization
/// already (made beside the increment's recordings).
struct Transposed<'x> {
    k: &'x mut SparseMatrix,
    /// Where `k` is not made (`--tangent last` with the factorization kept, which reads no
    /// tangent: `k` is stale, or the stored tangent without its identity rows where a
    /// reaction's product read it): the increment, to make it from (its stored tangent, or
    /// assembled where it kept none) should the kept factorization fail and the tangent be
    /// factored after all.
    unmade: Option<&'x Stored>,
    factor: Option<&'x mut KeptFactor>,
    factored: bool,
}

/// The transposed solves' options ([`Settings`]): the tangent, the refinement steps of
/// [`TangentChoice::Refined`], and GMRES preconditioned with Newton's last factor for
/// [`TangentChoice::Exact`] ([`Settings::adjoint_krylov`]).
#[derive(Debug, Clone, Copy)]
struct SweepTangent {
    choice: TangentChoice,
    refine_steps: usize,
    krylov: bool,
}

/// One recording of an increment's local derivatives in reverse mode ([`Sweep::record`]):
/// the tape of a solid element, of a colour of hitting nodes or of a pushed target, its
/// inputs (global unknowns, global history scalars) and its outputs (flat [`Outputs`]
/// indices).
struct Recorded {
    /// Its tape ([`Recordings::tapes`]) and its part of it.
    tape: usize,
    part: std::ops::Range<usize>,
    z: Vec<(usize, Rev)>,
    h: Vec<(usize, Rev)>,
    outputs: Vec<(usize, Rev)>,
}

impl Recorded {
    /// The recording from tape position `start` to the tape's end, on the thread's tape
    /// (numbered when the tapes are gathered).
    fn since(
        start: usize,
        z: Vec<(usize, Rev)>,
        h: Vec<(usize, Rev)>,
        outputs: Vec<(usize, Rev)>,
    ) -> Self {
        Recorded {
            tape: 0,
            part: start..tape::len(),
            z,
            h,
            outputs,
        }
    }
}

/// An increment's recordings: the tapes (a parallel task's elements one after the other on
/// one tape, the colours of hitting nodes on another) and each recording's part of them.
struct Recordings {
    tapes: Vec<tape::Recording>,
    items: Vec<Recorded>,
}

/// Puts `val[g]` for every `g` of `at` on the tape as an input, in `buf` and returned.
fn put(buf: &mut [Rev], val: &[f64], at: impl Iterator<Item = usize>) -> Vec<(usize, Rev)> {
    at.map(|g| {
        buf[g] = Rev::input(val[g]);
        (g, buf[g])
    })
    .collect()
}

/// Makes the inputs `put` made constants again.
fn restore(buf: &mut [Rev], val: &[f64], inputs: &[(usize, Rev)]) {
    for (g, _) in inputs {
        buf[*g] = Rev::constant(val[*g]);
    }
}

/// The terms the solid elements' passes evaluate.
const SOLIDS: Terms = Terms {
    solids: true,
    ..Terms::NONE
};

/// The terms the hitting nodes' passes evaluate.
const CONTACT: Terms = Terms {
    contact_normal: true,
    friction: true,
    ..Terms::NONE
};

/// A field parameter's element (flat hitting node), the index of the law's parameter, and
/// its own index among the parameters.
type FieldParam = (usize, usize, usize);

/// One column of the sweep: response `response` read at stored increment `at`, on the
/// converged branches there, or with the increment's flagged points forced onto one side
/// (`side`: `Some(upper)`, [`force_side`]) for its one-sided derivative. Before `at` every
/// column follows the converged branches.
#[derive(Clone, Copy, Debug)]
struct Column {
    at: usize,
    response: usize,
    side: Option<bool>,
}

/// The sweep's work space, kept from one increment to the next: the tangent, the
/// evaluations in each scalar, the solver of the transposed systems (on the forward run's
/// symbolic analysis), and the longest tape of a task recording solids and the hitting
/// nodes' tape at the last increment swept, the room made at once for the next
/// ([`Sweep::record`]).
struct Work {
    k: SparseMatrix,
    ev: Evaluation<f64>,
    ev_ad: Evaluation<Ad>,
    ev_d: Evaluation<Dual64>,
    ev_rev: Evaluation<Rev>,
    solver: LinearSolver,
    tape_room: (usize, usize),
}

/// What the sweep carries per column: the history multipliers, and `df/db` so far.
struct Multipliers<'v> {
    mu: &'v mut [Vec<f64>],
    dfdb: &'v mut [Vec<f64>],
}

/// The backward sweep's fixed data.
struct Sweep<'a> {
    model: &'a Model,
    params: &'a [Parameter],
    asm: Assembler,
    outputs: Outputs,
    lifted: Lifted<f64>,
    lifted_ad: Lifted<Ad>,
    lifted_rev: Lifted<Rev>,
    /// Solid elements with unknowns (springs are in the tangent alone: no history, no
    /// stress), their colours and the colour count.
    solids: Vec<usize>,
    solid_colour: Vec<usize>,
    solid_colours: usize,
    /// Per hitting node (flat): its pair, index in the pair, block unknowns without a
    /// pushed target's.
    nodes: Vec<(usize, usize, Vec<usize>)>,
    /// The hitting nodes (flat) of each colour.
    colour_nodes: Vec<Vec<usize>>,
    /// Every pushed target's unknown.
    pushed: Vec<usize>,
    /// Per parameter: a field parameter, its reach one element's material or one hitting
    /// node's friction law ([`Sweep::field_passes`]), instead of the general pass.
    field: Vec<bool>,
    /// The material field parameters by solid colour.
    element_fields: Vec<Vec<FieldParam>>,
    /// The friction field parameters by node colour.
    node_fields: Vec<Vec<FieldParam>>,
    /// Per element: the first stored increment at which a Gauss point of it is plastic
    /// (`usize::MAX`: never). An element elastic throughout keeps its history
    /// ([`history_unchanged`]'s rule): the history's derivative in the unknowns is zero there
    /// and the multiplier of its history is read by nothing before its first plastic
    /// increment, so the local Jacobians leave it out.
    first_plastic: Vec<usize>,
    /// The transposed solves' options.
    tangent: SweepTangent,
    /// [`Settings::adjoint_reverse`].
    reverse: Option<bool>,
}

impl<'a> Sweep<'a> {
    /// The sweep of `model` on the forward run's numbering and pattern `asm`.
    fn new(
        model: &'a Model,
        asm: Assembler,
        params: &'a [Parameter],
        first_plastic: Vec<usize>,
        tangent: SweepTangent,
        reverse: Option<bool>,
    ) -> Self {
        let dofs = &asm.dofs;
        let solids: Vec<usize> = (0..model.mesh.n_elements())
            .filter(|&e| !dofs.element_dofs(e).is_empty() && !dofs.gauss(e).is_empty())
            .collect();
        let touched: Vec<Vec<usize>> = solids
            .iter()
            .map(|&e| dofs.element_dofs(e).to_vec())
            .collect();
        let (solid_colour, solid_colours) = colour(&touched, dofs.n_total);
        let mut pushed = Vec::new();
        for t in &asm.contact.target {
            pushed.extend(t.iter().flatten());
        }
        let mut nodes = Vec::new();
        for (p, blocks) in asm.contact.blocks.iter().enumerate() {
            for (i, b) in blocks.iter().enumerate() {
                let own: Vec<usize> = b
                    .dofs
                    .iter()
                    .copied()
                    .filter(|d| !pushed.contains(d))
                    .collect();
                nodes.push((p, i, own));
            }
        }
        let touched: Vec<Vec<usize>> = nodes.iter().map(|n| n.2.clone()).collect();
        let (node_colour, node_colours) = colour(&touched, dofs.n_total);
        let mut colour_nodes = vec![Vec::new(); node_colours];
        for (f, &c) in node_colour.iter().enumerate() {
            colour_nodes[c].push(f);
        }
        // field parameters: one target, one element's material or one node's friction law
        let mut field = vec![false; params.len()];
        let mut element_fields = vec![Vec::new(); solid_colours];
        let mut node_fields = vec![Vec::new(); node_colours];
        let solid_at: std::collections::HashMap<usize, usize> =
            solids.iter().enumerate().map(|(i, e)| (*e, i)).collect();
        for (k, p) in params.iter().enumerate() {
            match p.targets.as_slice() {
                [DesignParam::ElementMaterial { element, index }] => {
                    if let Some(&i) = solid_at.get(element) {
                        element_fields[solid_colour[i]].push((*element, *index, k));
                        field[k] = true;
                    }
                }
                [DesignParam::NodeFriction { pair, node, index }] => {
                    let f = asm.contact_flat(*pair) + node;
                    node_fields[node_colour[f]].push((f, *index, k));
                    field[k] = true;
                }
                _ => {}
            }
        }
        Sweep {
            outputs: Outputs::new(&asm, model.contacts.len()),
            first_plastic,
            tangent,
            reverse,
            model,
            params,
            lifted: model.lifted(&[]),
            lifted_ad: model.lifted(&[]),
            lifted_rev: model.lifted(&[]),
            asm,
            solids,
            solid_colour,
            solid_colours,
            nodes,
            colour_nodes,
            pushed,
            field,
            element_fields,
            node_fields,
        }
    }

    /// `df/db` of every column ([`Column`]), in their order, and why a one-sided column has
    /// none where its forced increment failed ([`OneSided::failed`]: that side is left out,
    /// the rest of the sweep goes on). `kinks(m)`: the flagged points of stored increment
    /// `m`, which a one-sided column forces. `dh0` is the initial history's
    /// derivative per parameter (`None` or absent: zero). The stored increments come from
    /// `store`, a segment at a time from the last.
    fn run<'k>(
        &self,
        columns: &[Column],
        kinks: impl Fn(usize) -> &'k [Kink],
        dh0: &[Option<Vec<f64>>],
        cost: &mut SensitivityCost,
        store: &mut Store<'_>,
        lights_time: impl Fn(usize) -> f64,
    ) -> Result<(Vec<Vec<f64>>, Failures), AnalysisError> {
        let model = self.model;
        let ns = columns.iter().map(|c| c.at + 1).max().unwrap_or(0);
        let np = self.params.len();
        let nh = self.asm.dofs.n_history;
        let ncol = columns.len();
        let mut dfdb = vec![vec![0.0; np]; ncol];
        // a one-sided column whose side is the converged state's, solved with its tangent:
        // the column on the converged branches, which it is a copy of
        let mut copy_of: Vec<Option<usize>> = vec![None; ncol];
        let mut failed: Failures = vec![None; ncol];
        // the recordings' memory, kept from one increment to the next, freed however the
        // sweep ends
        let _kept = tape::FreeKept;
        // mu per column (history multipliers carried back)
        let mut mu = vec![vec![0.0; nh]; ncol];
        let ne = model.mesh.n_elements();
        let mut work = Work {
            k: SparseMatrix::new(self.asm.pattern.clone()),
            ev: Evaluation::new(&self.asm, ne),
            ev_ad: Evaluation::new(&self.asm, ne),
            ev_d: Evaluation::new(&self.asm, ne),
            ev_rev: Evaluation::new(&self.asm, ne),
            // on the forward run's symbolic analysis
            solver: store.solver.linear_sibling(),
            tape_room: (0, 0),
        };
        let mut segment: Vec<Stored> = Vec::new();
        let mut seg_first = usize::MAX;
        let mut seg = store.segments.len();
        for m in (0..ns).rev() {
            while m < seg_first {
                seg -= 1;
                seg_first = store.segments[seg].1;
                if m >= seg_first {
                    segment = store.fetch(seg, cost)?;
                    // a recomputed segment is the forward run's, increment for increment
                    let same = |(i, s): (usize, &Stored)| {
                        s.index == seg_first + i + 1 && s.time == lights_time(seg_first + i)
                    };
                    if !segment.iter().enumerate().all(same) || segment.len() <= m - seg_first {
                        return Err(SensitivityError::Recomputed {
                            increment: seg_first + 1,
                        }
                        .into());
                    }
                    let bytes = segment.iter().map(Stored::bytes).sum();
                    cost.stored_bytes = cost.stored_bytes.max(bytes);
                }
            }
            let mut factor = segment[m - seg_first].factor.take();
            let s = &segment[m - seg_first];
            // the columns alive at this increment on its converged branches: responses read
            // here or later, but the one-sided columns of this increment
            let alive =
                |j: usize| copy_of[j].is_none() && failed[j].is_none() && columns[j].at >= m;
            let cols: Vec<usize> = (0..ncol)
                .filter(|&j| alive(j) && (columns[j].at > m || columns[j].side.is_none()))
                .collect();
            // whether the converged branches' column solved with their tangent (DDM's rule)
            let exact = self.tangent.choice == TangentChoice::Exact || factor.is_none();
            let mut vars = Multipliers {
                mu: &mut mu,
                dfdb: &mut dfdb,
            };
            self.increment(
                &mut work,
                s,
                factor.as_mut(),
                m,
                columns,
                &cols,
                &mut vars,
                cost,
            )?;
            // the one-sided columns, each side's flagged points forced, its tangent factored
            let sides = [false, true].map(|upper| -> Vec<usize> {
                (0..ncol)
                    .filter(|&j| alive(j) && columns[j].at == m && columns[j].side == Some(upper))
                    .collect()
            });
            for (upper, side) in [false, true].into_iter().zip(sides) {
                if side.is_empty() {
                    continue;
                }
                let (mut gauss, mut choice) = (s.branches.clone(), s.choice.clone());
                force_side(kinks(m), upper, (model, &self.asm), &mut gauss, &mut choice);
                if exact && gauss == s.branches && choice == s.choice {
                    for &j in &side {
                        let c = &columns[j];
                        copy_of[j] = (0..ncol).find(|&i| {
                            columns[i].side.is_none()
                                && (columns[i].at, columns[i].response) == (m, c.response)
                        });
                    }
                    continue;
                }
                let forced = s.forced(gauss, choice);
                // a side whose forced tangent is singular is left out, as DDM leaves it;
                // any other error stops the sweep (`side_failure`)
                if let Err(e) =
                    self.increment(&mut work, &forced, None, m, columns, &side, &mut vars, cost)
                {
                    let line = side_failure(upper, s.index, e)?;
                    for &j in &side {
                        failed[j] = Some(line.clone());
                    }
                }
            }
        }
        // mu_0 . dh_0/db
        for (j, row) in dfdb.iter_mut().enumerate() {
            for (d, dh) in row.iter_mut().zip(dh0) {
                if let Some(dh) = dh {
                    *d += (mu[j].iter().zip(dh)).map(|(a, b)| a * b).sum::<f64>();
                }
            }
        }
        for (j, of) in copy_of.iter().enumerate() {
            if let Some(i) = of {
                dfdb[j] = dfdb[*i].clone();
            }
        }
        // a failed side's columns stopped part-way: nothing of them is an answer
        for (row, why) in dfdb.iter_mut().zip(&failed) {
            if why.is_some() {
                row.fill(f64::NAN);
            }
        }
        Ok((dfdb, failed))
    }

    /// Stored increment `m` (`s`, Newton's last factorization `factor` if kept) for the
    /// columns `cols` of `columns`: their transposed solve, the history multipliers carried
    /// back to the increment before (`vars.mu`), and the increment's terms of `df/db` added to
    /// `vars.dfdb`.
    #[allow(clippy::too_many_arguments)]
    fn increment(
        &self,
        w: &mut Work,
        s: &Stored,
        factor: Option<&mut KeptFactor>,
        m: usize,
        columns: &[Column],
        cols: &[usize],
        vars: &mut Multipliers<'_>,
        cost: &mut SensitivityCost,
    ) -> Result<(), AnalysisError> {
        let model = self.model;
        let out = &self.outputs;
        let n = self.asm.dofs.n_total;
        let nh = self.asm.dofs.n_history;
        let reads_here = |j: usize| columns[j].at == m;
        let response = |j: usize| &model.responses[columns[j].response];
        let reads = cols.iter().any(|&j| reads_here(j));
        let reads_reaction = (cols.iter())
            .any(|&j| reads_here(j) && matches!(response(j).kind, ResponseKind::Reaction { .. }));
        // Newton's last factorization, kept, and no refinement: the transposed solve
        // reads no tangent, so it is made only for a product with a reaction's cotangent
        // (or should the kept factorization fail: `Transposed::unmade`), from the stored
        // one where the forward run kept it ([`Keep`])
        let lazy = self.tangent.choice == TangentChoice::Last
            && factor.is_some()
            && (!s.tangent.is_empty() || !reads_reaction);
        let frozen = s.frozen();
        let k = &mut w.k;
        // the converged state, where a response reads it or the tangent is read and the
        // forward run kept none, and that tangent
        let assemble = s.tangent.is_empty() && !lazy;
        if reads || assemble {
            self.assemble_at(s, assemble.then_some(&mut *k), &mut w.ev, cost)?;
        }
        let mut input = reads.then(|| DualInput::new(&self.asm, &s.z, &w.ev));
        let mut cots: Vec<Vec<f64>> = cols
            .iter()
            .map(|&j| {
                let mut c = vec![0.0; out.len()];
                if let (true, Some(input)) = (reads_here(j), input.as_mut()) {
                    response_cotangent(response(j), &self.asm, out, input, &mut c);
                }
                for (a, b) in c[out.hist()].iter_mut().zip(&vars.mu[j]) {
                    *a += b;
                }
                c
            })
            .collect();
        let product = (cots.iter()).any(|c| c[out.res()].iter().any(|v| *v != 0.0));
        debug_assert!(
            !product || reads_reaction,
            "only a reaction's cotangent is on the residual's rows before the solve"
        );
        if !s.tangent.is_empty() && (product || !lazy) {
            k.values_mut().copy_from_slice(&s.tangent);
        }
        // d/dz [F + mu . H]
        let mut rhs = vec![0.0; n * cols.len()];
        let mut scratch = vec![0.0; n];
        for (c, cot) in cots.iter().enumerate() {
            let g = &mut rhs[c * n..(c + 1) * n];
            // nothing on the residual's rows (no reaction read here): no product
            if cot[out.res()].iter().all(|v| *v == 0.0) {
                g.copy_from_slice(&cot[out.z()]);
                continue;
            }
            k.mul_vec_transpose(&cot[out.res()], &mut scratch)?;
            for ((gi, a), b) in g.iter_mut().zip(&scratch).zip(&cot[out.z()]) {
                *gi = a + b;
            }
        }
        // the prescribed unknowns' identity rows, in place (`k` is rewritten at the next
        // increment): the right-hand sides have read the tangent
        if !lazy {
            k.set_identity_rows_cols(&s.constrained)?;
        }
        let reverse = self.reverse(cols.len());
        let mut factored = false;
        let tape_room = &mut w.tape_room;
        let ev_rev = &mut w.ev_rev;
        // factored anew: the exact tangent's way, and any tangent's where no factorization
        // was kept (a forced side's; one Newton's last was not on the converged branches)
        let anew = self.factors_anew() || factor.is_none();
        let (recorded, mut state) = if reverse && anew {
            // the tangent factored beside the recordings: neither reads the other, and
            // the factorization is serial below `PAR_FACTOR_MIN_N` unknowns while the
            // recordings keep every thread busy
            let ls = &mut w.solver;
            let before = cost.evaluation_seconds;
            let t = Instant::now();
            let (rec, fac) = rayon::join(
                || self.record(cost, s, m, tape_room, ev_rev),
                || factor_timed(ls, k),
            );
            let wall = t.elapsed().as_secs_f64();
            let fac = fac?;
            cost.factor_seconds += fac;
            cost.factorizations += 1;
            cost.overlap_seconds += (cost.evaluation_seconds - before + fac - wall).max(0.0);
            factored = true;
            (Some(rec?), None)
        } else if reverse {
            (Some(self.record(cost, s, m, tape_room, ev_rev)?), None)
        } else {
            (None, Some(AdState::new(s)))
        };
        if let Some(recorded) = &recorded {
            self.sweep_recorded(cost, recorded, Seeds::Z, &cots, (&mut rhs, n));
            self.current_area_pass(s, &cots, &mut rhs);
        } else {
            let state = state.get_or_insert_with(|| AdState::new(s));
            self.z_passes(cost, s, state, &cots, &mut rhs, &mut w.ev_ad)?;
        }
        // K^T lambda = rhs on the free unknowns
        for c in 0..cols.len() {
            for (i, fixed) in s.constrained.iter().enumerate() {
                if *fixed {
                    rhs[c * n + i] = 0.0;
                }
            }
        }
        let transposed = Transposed {
            k,
            unmade: lazy.then_some(s),
            factor,
            factored,
        };
        // the design's partial derivatives need no multiplier of this increment: they are
        // evaluated beside the solve (and beside its factorization where it makes one).
        // What each column reads at this increment: its response, if it reads here, and
        // the history multipliers carried back to here
        let reading: Vec<(Option<&Response>, &[f64])> = (cols.iter())
            .map(|&j| (reads_here(j).then(|| response(j)), &vars.mu[j][..]))
            .collect();
        let ev_d = &mut w.ev_d;
        let design = || {
            let t = Instant::now();
            let partials = self.design_partials(s, &frozen, &reading, ev_d);
            partials.map(|p| (p, t.elapsed().as_secs_f64()))
        };
        let t = Instant::now();
        let solve_before = cost.solve_seconds + cost.factor_seconds;
        let solver = &mut w.solver;
        let (solved, partials) = rayon::join(
            || self.solve_transposed(cost, transposed, &mut rhs, cols.len(), solver),
            design,
        );
        let wall = t.elapsed().as_secs_f64();
        solved?;
        let (partials, design_seconds) = partials?;
        let solve_seconds = cost.solve_seconds + cost.factor_seconds - solve_before;
        cost.evaluation_seconds += design_seconds;
        cost.partial_evaluations += partials.len();
        cost.overlap_seconds += (solve_seconds + design_seconds - wall).max(0.0);
        for (c, cot) in cots.iter_mut().enumerate() {
            for (r, l) in cot[out.res()].iter_mut().zip(&rhs[c * n..(c + 1) * n]) {
                *r -= l;
            }
        }
        // mu_{n-1} = d/dh [F + mu . H - lambda . R]
        let mut mu_prev = vec![0.0; nh * cols.len()];
        if nh > 0 {
            if let Some(recorded) = &recorded {
                self.sweep_recorded(cost, recorded, Seeds::H, &cots, (&mut mu_prev, nh));
            } else {
                let state = state.get_or_insert_with(|| AdState::new(s));
                self.h_passes(cost, s, m, state, &cots, &mut mu_prev, &mut w.ev_ad)?;
            }
        }
        // d/db [F + mu . H - lambda . R], prescribed unknowns moving with the design
        self.field_passes(cost, s, cols, &cots, vars.dfdb, &mut w.ev_ad)?;
        for d in &partials {
            for (c, &j) in cols.iter().enumerate() {
                let mut v = d.known[c];
                // -lambda . R_b (F's own reaction part is in its value above)
                let lam = &rhs[c * n..(c + 1) * n];
                v -= (d.residual.iter()).map(|(i, b)| lam[*i] * b).sum::<f64>();
                vars.dfdb[j][d.p] += v;
            }
        }
        for (c, &j) in cols.iter().enumerate() {
            vars.mu[j].copy_from_slice(&mu_prev[c * nh..(c + 1) * nh]);
        }
        Ok(())
    }

    /// Every non-field parameter's partial derivatives at stored increment `s`, before the
    /// increment's multipliers are known ([`DesignPartial`]): one dual evaluation each, over
    /// what the parameter reaches, on the stored branches (`frozen`: converged, or forced). `reading[c]`:
    /// column `c`'s response where it reads this increment, and its history multipliers.
    fn design_partials(
        &self,
        s: &Stored,
        frozen: &Frozen<'_>,
        reading: &[(Option<&Response>, &[f64])],
        ev: &mut Evaluation<Dual64>,
    ) -> Result<Vec<DesignPartial>, AnalysisError> {
        let hd: Vec<Dual64> = s.hist_prev.iter().map(|v| Dual64::from_re(*v)).collect();
        let mut partials = Vec::new();
        for (p, par) in (self.params.iter().enumerate()).filter(|(p, _)| !self.field[*p]) {
            let (lifted, zd) = self.seeded(s, par);
            let skip = self.unreached(&Reach::seeded(&lifted), &zd);
            let fr = Frozen {
                skip: Some(&skip),
                ..*frozen
            };
            (self.asm).evaluate(self.model, &lifted, &zd, &hd, s.time, Some(&fr), None, ev)?;
            let known = (reading.iter())
                .map(|(response, mu)| {
                    let mut v = 0.0;
                    if let Some(r) = response {
                        v += r.value(&ev.response_input(&zd, &self.asm)).eps;
                    }
                    v += (mu.iter().zip(&ev.hist_new))
                        .map(|(a, b)| a * b.eps)
                        .sum::<f64>();
                    v
                })
                .collect();
            let residual = (ev.residual.iter().enumerate())
                .filter(|(_, r)| r.eps != 0.0)
                .map(|(i, r)| (i, r.eps))
                .collect();
            partials.push(DesignPartial { p, known, residual });
        }
        Ok(partials)
    }

    /// The design seeded along parameter `par`, and the state with the prescribed unknowns
    /// carrying their derivative.
    fn seeded(&self, s: &Stored, par: &Parameter) -> (Lifted<Dual64>, Vec<Dual64>) {
        let overrides: Vec<(DesignParam, Dual64)> = (par.targets.iter())
            .map(|t| (*t, Dual64::new(par.value, 1.0)))
            .collect();
        let lifted = self.model.lifted(&overrides);
        let mut dzc = vec![0.0; s.z.len()];
        prescribed_derivative(self.model, par, s.time, &mut dzc);
        let z = (s.z.iter().zip(&dzc))
            .map(|(r, e)| Dual64::new(*r, *e))
            .collect();
        (lifted, z)
    }

    /// The elements a parameter's seeds do not reach: no moved node, no changed material
    /// parameter of its body, no moving prescribed unknown (the state and history carry no
    /// derivative here). Elements whose stress a response reads are always evaluated.
    fn unreached(&self, reach: &Reach, z: &[Dual64]) -> Vec<bool> {
        let dofs = &self.asm.dofs;
        (0..self.model.mesh.n_elements())
            .map(|e| {
                let b = dofs.element_body[e];
                let material = b < self.model.bodies.len() && reach.any_material(b, e);
                let moved = (self.model.mesh.element_nodes(e).iter()).any(|&nd| reach.moved[nd]);
                let reached = material
                    || moved
                    || dofs.element_dofs(e).iter().any(|&i| z[i].eps != 0.0)
                    || self.asm.stress_slot(e).is_some();
                !reached && !dofs.gauss(e).is_empty()
            })
            .collect()
    }

    /// `K^T X = RHS` with the tangent `k` at the converged state, on the stored branches (a
    /// one-sided column's forced ones: no factorization kept, factored) (prescribed unknowns as
    /// identity rows; made first from [`Transposed::unmade`] where it is not) — the
    /// transposes of what DDM solves with each tangent option:
    /// [`TangentChoice::Exact`] factored anew (already, beside the recordings, where
    /// [`Transposed::factored`]), or by block GMRES preconditioned with
    /// Newton's last factor kept by the forward run ([`Settings::adjoint_krylov`]; factored
    /// where GMRES or its refinement fails: DDM stops at a failed refinement), and refined
    /// with double-double residuals either way; [`TangentChoice::Last`] with Newton's last
    /// factorization alone
    /// (the paper's choice: off by the order of Newton's last correction), or
    /// [`TangentChoice::Refined`] with refinement steps against the converged tangent, where
    /// that factorization was assembled on the converged branches. Where it was not (or a
    /// recomputed segment's first increment converged without one), the converged tangent
    /// is factored, as DDM does.
    fn solve_transposed(
        &self,
        cost: &mut SensitivityCost,
        t: Transposed<'_>,
        rhs: &mut [f64],
        ncols: usize,
        ls: &mut LinearSolver,
    ) -> Result<(), AnalysisError> {
        let SweepTangent {
            choice,
            refine_steps,
            krylov,
        } = self.tangent;
        if let Some(kept) = t.factor {
            let b = rhs.to_vec();
            let kd = &*t.k;
            let solved = match choice {
                // kept only where it is the converged branches' tangent (KeepFactors::Matching)
                TangentChoice::Last | TangentChoice::Refined => {
                    let steps = if choice == TangentChoice::Refined {
                        refine_steps
                    } else {
                        0
                    };
                    let start = Instant::now();
                    let kept_solve = ls.with_kept(kept, |last| {
                        last.solve_transpose_multi_in_place(rhs, ncols)?;
                        if steps > 0 {
                            last.refine_transpose_multi(kd, &b, rhs, ncols, steps)?;
                        }
                        Ok(())
                    });
                    cost.solve_seconds += start.elapsed().as_secs_f64();
                    kept_solve
                        .is_ok()
                        .then(|| cost.solve_columns += ncols * (1 + steps))
                }
                TangentChoice::Exact if krylov => {
                    // a refinement that fails counts as not solved, as GMRES that does not
                    // converge: the converged tangent is factored anew below
                    let krylov_solve = ls.with_kept(kept, |m| {
                        krylov_refined(m, kd, true, rhs, ncols, cost, "transposed, adjoint")
                    });
                    matches!(krylov_solve, Ok(true)).then_some(())
                }
                // the exact tangent without GMRES keeps no factor; were one kept, the
                // converged tangent is factored anew below as for any other miss
                TangentChoice::Exact => None,
            };
            if solved.is_some() {
                return Ok(());
            }
            // no solve with the kept factor: factor anew
            rhs.copy_from_slice(&b);
        }
        if let Some(s) = t.unmade {
            if s.tangent.is_empty() {
                let ne = self.model.mesh.n_elements();
                let mut ev = Evaluation::<f64>::new(&self.asm, ne);
                self.assemble_at(s, Some(&mut *t.k), &mut ev, cost)?;
            } else {
                t.k.values_mut().copy_from_slice(&s.tangent);
            }
            t.k.set_identity_rows_cols(&s.constrained)?;
        }
        let kd = &*t.k;
        if !t.factored {
            cost.factor_seconds += factor_timed(ls, kd)?;
            cost.factorizations += 1;
        }
        // refined to the solution rounded to working precision, as DDM's solves are
        factored_refined(ls, kd, true, rhs, ncols, cost)?;
        Ok(())
    }

    /// The stored increment `s` evaluated at its converged state on its stored branches
    /// into `ev`, with its tangent into `k` if given.
    fn assemble_at(
        &self,
        s: &Stored,
        k: Option<&mut SparseMatrix>,
        ev: &mut Evaluation<f64>,
        cost: &mut SensitivityCost,
    ) -> Result<(), AnalysisError> {
        let t = Instant::now();
        let frozen = s.frozen();
        (self.asm).evaluate(
            self.model,
            &self.lifted,
            &s.z,
            &s.hist_prev,
            s.time,
            Some(&frozen),
            k,
            ev,
        )?;
        cost.evaluation_seconds += t.elapsed().as_secs_f64();
        cost.residual_evaluations += 1;
        Ok(())
    }

    /// Whether the converged tangent is factored at every increment whatever Newton kept
    /// ([`TangentChoice::Exact`] without GMRES): then the factorization can be made before
    /// the right-hand sides are complete.
    fn factors_anew(&self) -> bool {
        self.tangent.choice == TangentChoice::Exact && !self.tangent.krylov
    }

    /// One colour's local Jacobians: every member's inputs seeded `W` at a time (input `l`
    /// in direction `l % W` of evaluation `l / W`); after each evaluation, the rows
    /// `rows(i, ev)` of member `i`, weighed by each column's cotangent, give the derivative
    /// added to `out[c * stride + input]`. The state's duals are clear again on return.
    #[allow(clippy::too_many_arguments)]
    fn local_passes(
        &self,
        cost: &mut SensitivityCost,
        s: &Stored,
        state: &mut AdState,
        pass: &Pass<'_>,
        ev: &mut Evaluation<Ad>,
        rows: impl Fn(usize, &Evaluation<Ad>) -> Rows,
        cots: &[Vec<f64>],
        (out, stride): (&mut [f64], usize),
    ) -> Result<(), AnalysisError> {
        let longest = pass.inputs.iter().map(Vec::len).max().unwrap_or(0);
        let chunk_of = |inputs: &[usize], chunk: usize| {
            let start = (chunk * W).min(inputs.len());
            start..((chunk + 1) * W).min(inputs.len())
        };
        for chunk in 0..longest.div_ceil(W) {
            for inputs in &pass.inputs {
                for l in chunk_of(inputs, chunk) {
                    state.seed(s, pass.seeds, inputs[l], Some(l % W));
                }
            }
            let frozen = Frozen {
                gauss: Some(&s.branches),
                contact: &s.choice,
                skip: Some(pass.skip),
                skip_contact: Some(pass.skip_contact),
                terms: pass.terms,
                members_only: true,
                ..Frozen::default()
            };
            let t = Instant::now();
            self.asm.evaluate(
                self.model,
                &self.lifted_ad,
                &state.z,
                &state.h,
                s.time,
                Some(&frozen),
                None,
                ev,
            )?;
            cost.evaluation_seconds += t.elapsed().as_secs_f64();
            cost.partial_evaluations += 1;
            for (i, inputs) in pass.inputs.iter().enumerate() {
                let ls = chunk_of(inputs, chunk);
                if ls.is_empty() {
                    continue;
                }
                let rows = rows(i, ev);
                for l in ls {
                    let d = l % W;
                    for (c, cot) in cots.iter().enumerate() {
                        let v: f64 = (rows.iter()).map(|(o, p)| cot[*o] * p[d]).sum();
                        out[c * stride + inputs[l]] += v;
                    }
                    state.seed(s, pass.seeds, inputs[l], None);
                }
            }
        }
        Ok(())
    }

    /// Whether the solids' local derivatives are taken in reverse mode for `ncols` columns.
    fn reverse(&self, ncols: usize) -> bool {
        self.reverse.unwrap_or(ncols <= REVERSE_COLUMNS)
    }

    /// Whether solid `e`'s outputs other than its residual move with the unknowns at the
    /// increment `s`: it is plastic there (an elastic one keeps its history), or a response
    /// reads its stress.
    fn moves_with_z(&self, s: &Stored, e: usize) -> bool {
        self.asm.stress_slot(e).is_some()
            || s.branches[self.asm.dofs.gauss(e)].contains(&Branch::Plastic)
    }

    /// Whether the multiplier of solid `e`'s history committed before stored position `m` is
    /// read: it has history and was plastic before (else nothing reads it).
    fn history_read(&self, m: usize, e: usize) -> bool {
        !self.asm.dofs.history(e).is_empty() && self.first_plastic[e] < m
    }

    /// The local derivatives of the increment stored at position `m` (`s`) in reverse mode
    /// ([`Rev`]), recorded once for both phases of the sweep: every solid whose outputs move
    /// with the unknowns or whose history is read, alone, on the thread that evaluates it (in
    /// parallel); every colour of hitting nodes in one evaluation on this thread (a colour's
    /// members share no input, so each input's adjoint is its own member's); and a pushed
    /// target's translations. Each recording's inputs are the unknowns and history scalars
    /// its phases differentiate in. `tape_room`: the longest solids' task tape and the
    /// hitting nodes' tape of the increment recorded before, the room each tape is given at
    /// once (updated to this increment's).
    fn record(
        &self,
        cost: &mut SensitivityCost,
        s: &Stored,
        m: usize,
        tape_room: &mut (usize, usize),
        ev: &mut Evaluation<Rev>,
    ) -> Result<Recordings, AnalysisError> {
        let t = Instant::now();
        let konst = |v: &[f64]| -> Vec<Rev> { v.iter().map(|x| Rev::constant(*x)).collect() };
        let (z0, h0) = (konst(&s.z), konst(&s.hist_prev));
        let o = &self.outputs;
        let members: Vec<(usize, bool, bool)> = (self.solids.iter())
            .map(|&e| (e, self.moves_with_z(s, e), self.history_read(m, e)))
            .filter(|(_, z, h)| *z || *h)
            .collect();
        let solid = |(e, in_z, in_h): (usize, bool, bool), z: &mut [Rev], h: &mut [Rev]| {
            let start = tape::len();
            let dofs = self.asm.element_dofs(e);
            let hist = self.asm.dofs.history(e);
            let zi = if in_z {
                put(z, &s.z, dofs.iter().copied())
            } else {
                Vec::new()
            };
            let hi = if in_h {
                put(h, &s.hist_prev, hist.clone())
            } else {
                Vec::new()
            };
            let mut force = [Rev::zero(); MAX_DOFS];
            let mut hist_new = vec![Rev::zero(); hist.len()];
            let slot = self.asm.stress_slot(e);
            let cauchy = self.asm.element_outputs(
                self.model,
                &self.lifted_rev,
                z,
                h,
                Some(&s.branches),
                e,
                &mut force,
                &mut hist_new,
                slot.is_some(),
            );
            restore(z, &s.z, &zi);
            restore(h, &s.hist_prev, &hi);
            let cauchy = cauchy?;
            let mut outputs: Vec<(usize, Rev)> = (dofs.iter().zip(force))
                .map(|(&g, f)| (o.index(Entry::Res(g)), f))
                .collect();
            outputs.extend(
                hist.zip(hist_new)
                    .map(|(i, x)| (o.index(Entry::Hist(i)), x)),
            );
            if let Some(sl) = slot {
                outputs.extend(
                    (0..9).map(|k| (o.index(Entry::Stress(sl, k)), cauchy[(k / 3, k % 3)])),
                );
            }
            Ok::<_, AnalysisError>(Recorded::since(start, zi, hi, outputs))
        };
        let room = *tape_room;
        // two tasks per thread, each copying the state once: the hitting nodes' recording
        // runs beside them
        let chunk = (members.len())
            .div_ceil(2 * rayon::current_num_threads())
            .max(1);
        // a task's elements one after the other on its thread's tape
        let record_solids = || -> Vec<Result<(tape::Recording, Vec<Recorded>), AnalysisError>> {
            members
                .par_chunks(chunk)
                .map(|ch| {
                    let (mut z, mut h) = (z0.clone(), h0.clone());
                    tape::clear();
                    // room for the task's tape as long as the last increment's longest
                    tape::reserve(room.0);
                    let items: Result<Vec<Recorded>, AnalysisError> =
                        ch.iter().map(|&x| solid(x, &mut z, &mut h)).collect();
                    let tape = tape::take();
                    Ok((tape, items?))
                })
                .collect()
        };
        // the hitting nodes, a colour at a time, on one tape
        let record_nodes = || -> Option<Result<(tape::Recording, Vec<Recorded>), AnalysisError>> {
            if self.model.contacts.is_empty() {
                return None;
            }
            let (mut z, mut h) = (z0.clone(), h0.clone());
            let ne = self.model.mesh.n_elements();
            let nk = self.nodes.len();
            let no_solid = vec![true; ne];
            // a colour of hitting nodes (`members`), or the pushed targets' translations
            let mut colour = |members: &[usize], pushed: bool| {
                let start = tape::len();
                let (zi, hi) = if pushed {
                    (put(&mut z, &s.z, self.pushed.iter().copied()), Vec::new())
                } else {
                    let own = members
                        .iter()
                        .flat_map(|&f| self.nodes[f].2.iter().copied());
                    let hist = members.iter().flat_map(|&f| {
                        let (p, i, _) = self.nodes[f];
                        let nhc = self.model.contacts[p].history_len();
                        let h0 = self.asm.contact_history(p) + nhc * i;
                        h0..h0 + nhc
                    });
                    (put(&mut z, &s.z, own), put(&mut h, &s.hist_prev, hist))
                };
                let skip = if pushed {
                    vec![false; nk]
                } else {
                    all_but(members, nk)
                };
                let frozen = Frozen {
                    gauss: Some(&s.branches),
                    contact: &s.choice,
                    skip: Some(&no_solid),
                    skip_contact: Some(&skip),
                    terms: CONTACT,
                    members_only: true,
                    ..Frozen::default()
                };
                let evaluated = self.asm.evaluate(
                    self.model,
                    &self.lifted_rev,
                    &z,
                    &h,
                    s.time,
                    Some(&frozen),
                    None,
                    ev,
                );
                restore(&mut z, &s.z, &zi);
                restore(&mut h, &s.hist_prev, &hi);
                evaluated?;
                let outputs = if pushed {
                    self.pushed_outputs(ev)
                } else {
                    (members.iter())
                        .flat_map(|&f| self.node_outputs(f, ev, true))
                        .collect()
                };
                Ok::<_, AnalysisError>(Recorded::since(start, zi, hi, outputs))
            };
            // the colours one after the other on this thread's tape
            tape::clear();
            tape::reserve(room.1);
            let mut items = Vec::new();
            let mut all = || -> Result<(), AnalysisError> {
                for members in &self.colour_nodes {
                    items.push(colour(members, false)?);
                }
                if !self.pushed.is_empty() {
                    items.push(colour(&[], true)?);
                }
                Ok(())
            };
            let done = all();
            let tape = tape::take();
            Some(done.map(|()| (tape, items)))
        };
        // every recording stays on one thread from its `clear` to its `take`: neither
        // closure runs parallel work of its own inside one (a recording evaluation is serial)
        let (solids, nodes) = rayon::join(record_solids, record_nodes);
        let mut recorded = Recordings {
            tapes: Vec::new(),
            items: Vec::new(),
        };
        let longest = solids.iter().flatten().map(|(t, _)| t.len()).max();
        tape_room.0 = longest.unwrap_or(0);
        if let Some(Ok((t, _))) = &nodes {
            tape_room.1 = t.len();
        }
        for r in solids.into_iter().chain(nodes) {
            let (tape, items) = r?;
            let k = recorded.tapes.len();
            recorded.tapes.push(tape);
            recorded
                .items
                .extend(items.into_iter().map(|r| Recorded { tape: k, ..r }));
        }
        cost.evaluation_seconds += t.elapsed().as_secs_f64();
        cost.partial_evaluations += recorded.items.len();
        Ok(recorded)
    }

    /// One phase of an increment's sweep over its recordings: per column, each recording
    /// swept with the column's cotangent on its outputs, the residual's rows left out in the
    /// unknowns' phase (there the residual's derivative is the tangent's), and its inputs'
    /// adjoints added to `out[c * stride + input]` (the unknowns' or the history's, by
    /// `phase`). The recordings are swept in parallel and their sums added in order
    /// (bit-identical whatever the thread count).
    fn sweep_recorded(
        &self,
        cost: &mut SensitivityCost,
        recorded: &Recordings,
        phase: Seeds,
        cots: &[Vec<f64>],
        (out, stride): (&mut [f64], usize),
    ) {
        let t = Instant::now();
        let res = self.outputs.res();
        fn inputs_of(r: &Recorded, phase: Seeds) -> &[(usize, Rev)] {
            match phase {
                Seeds::Z => &r.z,
                Seeds::H => &r.h,
            }
        }
        let grads = |adj: &mut Vec<f64>, r: &Recorded| -> Vec<f64> {
            let inputs = inputs_of(r, phase);
            let mut g = vec![0.0; cots.len() * inputs.len()];
            if inputs.is_empty() {
                return g;
            }
            for (c, cot) in cots.iter().enumerate() {
                let weights = (r.outputs.iter())
                    .filter(|(o, _)| phase == Seeds::H || !res.contains(o))
                    .map(|(o, x)| (*x, cot[*o]));
                if weights.clone().all(|(_, w)| w == 0.0) {
                    continue;
                }
                recorded.tapes[r.tape].sweep_part(r.part.clone(), weights, adj);
                for (l, (_, x)) in inputs.iter().enumerate() {
                    g[c * inputs.len() + l] = x.adjoint_in(adj, r.part.start);
                }
            }
            g
        };
        let all: Vec<Vec<f64>> = (recorded.items.par_iter())
            .map_init(Vec::new, grads)
            .collect();
        for (r, g) in recorded.items.iter().zip(all) {
            let inputs = inputs_of(r, phase);
            for c in 0..cots.len() {
                for (l, (i, _)) in inputs.iter().enumerate() {
                    out[c * stride + i] += g[c * inputs.len() + l];
                }
            }
        }
        cost.evaluation_seconds += t.elapsed().as_secs_f64();
    }

    /// The solids of colour `colour` that `keep` keeps.
    fn solids_of(&self, colour: usize, keep: impl Fn(usize) -> bool) -> Vec<usize> {
        (0..self.solids.len())
            .filter(|i| self.solid_colour[*i] == colour)
            .map(|i| self.solids[i])
            .filter(|&e| keep(e))
            .collect()
    }

    /// The rows of element `e`'s local Jacobian: its residual rows (`residual`), its
    /// history, its stress if a response reads it.
    fn element_rows(&self, e: usize, ev: &Evaluation<Ad>, residual: bool) -> Rows {
        let out = &self.outputs;
        let mut rows = Vec::new();
        if residual {
            for &g in self.asm.element_dofs(e) {
                rows.push((out.index(Entry::Res(g)), parts(&ev.residual[g])));
            }
        }
        for i in self.asm.dofs.history(e) {
            rows.push((out.index(Entry::Hist(i)), parts(&ev.hist_new[i])));
        }
        if let Some(sl) = self.asm.stress_slot(e) {
            for k in 0..9 {
                let p = parts(&ev.stress[sl][(k / 3, k % 3)]);
                rows.push((out.index(Entry::Stress(sl, k)), p));
            }
        }
        rows
    }

    /// The rows of hitting node `f`'s local Jacobian: its normal force, its block's residual
    /// rows (`residual`), its history, and its force on the target (minus its hitting node's
    /// rows), which is its part of the pair's target force and of a pushed target's rows.
    fn node_rows(&self, f: usize, ev: &Evaluation<Ad>, residual: bool) -> Rows {
        (self.node_outputs(f, ev, residual).into_iter())
            .map(|(o, x)| (o, parts(&x)))
            .collect()
    }

    /// [`Sweep::node_rows`]' outputs themselves, in any scalar.
    fn node_outputs<S: Scalar>(
        &self,
        f: usize,
        ev: &Evaluation<S>,
        residual: bool,
    ) -> Vec<(usize, S)> {
        let out = &self.outputs;
        let (p, i, ref own) = self.nodes[f];
        let pair = &self.model.contacts[p];
        let hitting = pair.hitting[i];
        let nhc = pair.history_len();
        let h0 = self.asm.contact_history(p) + nhc * i;
        let mut rows = vec![(out.index(Entry::Nf(f)), ev.contact.normal_force[f])];
        if residual {
            for &g in own {
                rows.push((out.index(Entry::Res(g)), ev.residual[g]));
            }
        }
        for a in h0..h0 + nhc {
            rows.push((out.index(Entry::Hist(a)), ev.hist_new[a]));
        }
        let force: Vec<S> = (0..3).map(|c| -ev.residual[node_dof(hitting, c)]).collect();
        for (c, fc) in force.iter().enumerate() {
            rows.push((out.index(Entry::Pf(p, c)), *fc));
        }
        if residual {
            for (_, dof, mo) in pair.pushed(&self.asm.contact.target[p]) {
                rows.push((out.index(Entry::Res(dof)), force[mo.component]));
            }
        }
        rows
    }

    /// The outputs a pushed target's translations reach: every hitting node's history and
    /// normal force, every pair's target force and translation.
    fn pushed_outputs<S: Scalar>(&self, ev: &Evaluation<S>) -> Vec<(usize, S)> {
        let out = &self.outputs;
        let first = self.asm.dofs.first_contact_history;
        let mut rows: Vec<(usize, S)> = (first..self.asm.dofs.n_history)
            .map(|a| (out.index(Entry::Hist(a)), ev.hist_new[a]))
            .collect();
        for (f, nf) in ev.contact.normal_force.iter().enumerate() {
            rows.push((out.index(Entry::Nf(f)), *nf));
        }
        for p in 0..self.model.contacts.len() {
            for c in 0..3 {
                rows.push((out.index(Entry::Pf(p, c)), ev.contact.pair_force[p][c]));
                rows.push((out.index(Entry::Tr(p, c)), ev.contact.translation[p][c]));
            }
        }
        rows
    }

    /// Adds to each column of `rhs` the derivative in the unknowns of the outputs other than
    /// the residual (history, stresses, contact forces, targets) weighed by the column's
    /// cotangent: local Jacobians by coloured dual evaluations.
    fn z_passes(
        &self,
        cost: &mut SensitivityCost,
        s: &Stored,
        state: &mut AdState,
        cots: &[Vec<f64>],
        rhs: &mut [f64],
        ev: &mut Evaluation<Ad>,
    ) -> Result<(), AnalysisError> {
        let model = self.model;
        let n = self.asm.dofs.n_total;
        let ne = model.mesh.n_elements();
        let nk = self.nodes.len();
        let every_node = vec![true; nk];
        // solids plastic at this increment (an elastic one keeps its history: it does not
        // move with the unknowns), and those whose stress a response reads
        let z_member = |e: usize| self.moves_with_z(s, e);
        for colour in 0..self.solid_colours {
            let members = self.solids_of(colour, z_member);
            if members.is_empty() {
                continue;
            }
            let skip = all_but(&members, ne);
            let pass = Pass {
                seeds: Seeds::Z,
                inputs: (members.iter())
                    .map(|&e| self.asm.element_dofs(e).to_vec())
                    .collect(),
                skip: &skip,
                skip_contact: &every_node,
                terms: SOLIDS,
            };
            let rows = |i: usize, ev: &Evaluation<Ad>| self.element_rows(members[i], ev, false);
            self.local_passes(cost, s, state, &pass, ev, rows, cots, (rhs, n))?;
        }
        if model.contacts.is_empty() {
            return Ok(());
        }
        // hitting nodes: their history, normal forces and target forces
        let no_solid = vec![true; ne];
        for members in &self.colour_nodes {
            let skip = all_but(members, nk);
            let pass = Pass {
                seeds: Seeds::Z,
                inputs: members.iter().map(|&f| self.nodes[f].2.clone()).collect(),
                skip: &no_solid,
                skip_contact: &skip,
                terms: CONTACT,
            };
            let rows = |i: usize, ev: &Evaluation<Ad>| self.node_rows(members[i], ev, false);
            self.local_passes(cost, s, state, &pass, ev, rows, cots, (rhs, n))?;
        }
        // a pushed target's translations: every node sees them
        if !self.pushed.is_empty() {
            let pass = Pass {
                seeds: Seeds::Z,
                inputs: vec![self.pushed.clone()],
                skip: &no_solid,
                skip_contact: &vec![false; nk],
                terms: CONTACT,
            };
            let rows = |_: usize, ev: &Evaluation<Ad>| -> Rows {
                (self.pushed_outputs(ev).into_iter())
                    .map(|(o, x)| (o, parts(&x)))
                    .collect()
            };
            self.local_passes(cost, s, state, &pass, ev, rows, cots, (rhs, n))?;
        }
        self.current_area_pass(s, cots, rhs);
        Ok(())
    }

    /// The current areas' part of the unknowns' derivative: each node of a pair's hitting
    /// faces seeded alone, through the same generic area routine the contact evaluation
    /// uses.
    fn current_area_pass(&self, s: &Stored, cots: &[Vec<f64>], rhs: &mut [f64]) {
        let n = self.asm.dofs.n_total;
        for (p, pair) in self.model.contacts.iter().enumerate() {
            let Some(faces) = &pair.hitting_faces else {
                continue;
            };
            let first = self.asm.contact_flat(p);
            let carea = self.outputs.carea(first..first + pair.hitting.len());
            if cots
                .iter()
                .all(|c| c[carea.clone()].iter().all(|v| *v == 0.0))
            {
                continue;
            }
            let pos = |nd: usize| -> Vector3<Dual64> {
                let u = Vector3::new(
                    s.z[node_dof(nd, 0)],
                    s.z[node_dof(nd, 1)],
                    s.z[node_dof(nd, 2)],
                );
                (self.lifted.coords[nd] + u).map(Dual64::from_re)
            };
            // each node once (the faces list their nodes face after face, with repetitions:
            // a node's term was added once per face around it)
            let mut nodes = faces.all_nodes().to_vec();
            nodes.sort_unstable();
            nodes.dedup();
            for &nd in &nodes {
                for comp in 0..3 {
                    let seeded = |m: usize| {
                        let mut x = pos(m);
                        if m == nd {
                            x[comp].eps = 1.0;
                        }
                        x
                    };
                    let areas = faces.pressure_areas_at(seeded, &pair.hitting);
                    let g = node_dof(nd, comp);
                    for (c, cot) in cots.iter().enumerate() {
                        let v: f64 = (areas.iter().zip(&cot[carea.clone()]))
                            .map(|(a, w)| a.eps * w)
                            .sum();
                        rhs[c * n + g] += v;
                    }
                }
            }
        }
    }

    /// Adds to `dfdb` (`[column][parameter]`, the columns `cols` alive at increment `m`) the
    /// derivatives in the field parameters, `d/db [F + mu . H - lambda . R]` as the general
    /// pass, which is the column's cotangent (`-lambda` on the residual, `mu` on the history)
    /// on the outputs' derivatives: a field parameter reaches one element (one hitting node)
    /// alone, so every parameter of a colour's members is seeded in one evaluation, each
    /// parameter index in a direction of its own, and each member's rows read apart. An
    /// element elastic at this increment is left out for a parameter that acts on the
    /// plastic branch alone (its residual, history and stress do not see it).
    fn field_passes(
        &self,
        cost: &mut SensitivityCost,
        s: &Stored,
        cols: &[usize],
        cots: &[Vec<f64>],
        dfdb: &mut [Vec<f64>],
        ev: &mut Evaluation<Ad>,
    ) -> Result<(), AnalysisError> {
        let model = self.model;
        if self
            .element_fields
            .iter()
            .chain(&self.node_fields)
            .all(Vec::is_empty)
        {
            return Ok(());
        }
        let state = AdState::new(s);
        let ne = model.mesh.n_elements();
        let nk = self.nodes.len();
        let seeded = |value: f64, index: usize| {
            (index < W)
                .then(|| Ad::from_re(value).derivative(index))
                .ok_or_else(|| AnalysisError::from(SensitivityError::FieldIndex { index }))
        };
        let mut passes: Vec<(Vec<FieldParam>, Terms)> = Vec::new();
        for fields in &self.element_fields {
            let live: Vec<FieldParam> = (fields.iter().copied())
                .filter(|&(e, i, _)| {
                    let b = self.asm.dofs.element_body[e];
                    model.bodies[b].material.enters_elastic_branch(i)
                        || s.branches[self.asm.dofs.gauss(e)].contains(&Branch::Plastic)
                })
                .collect();
            passes.push((live, SOLIDS));
        }
        for fields in &self.node_fields {
            passes.push((fields.clone(), CONTACT));
        }
        for (mut fields, terms) in passes {
            fields.sort_by_key(|f| f.0);
            if fields.is_empty() {
                continue;
            }
            let solids = terms.solids;
            let mut overrides = Vec::with_capacity(fields.len());
            for &(_, index, k) in &fields {
                let value = self.params[k].value;
                overrides.push((self.params[k].targets[0], seeded(value, index)?));
            }
            let members: Vec<usize> = fields.iter().map(|f| f.0).collect();
            let (skip, skip_contact) = if solids {
                (all_but(&members, ne), vec![true; nk])
            } else {
                (vec![true; ne], all_but(&members, nk))
            };
            let lifted: Lifted<Ad> = model.lifted(&overrides);
            let frozen = Frozen {
                gauss: Some(&s.branches),
                contact: &s.choice,
                skip: Some(&skip),
                skip_contact: Some(&skip_contact),
                terms,
                members_only: true,
                ..Frozen::default()
            };
            let t = Instant::now();
            (self.asm).evaluate(
                model,
                &lifted,
                &state.z,
                &state.h,
                s.time,
                Some(&frozen),
                None,
                ev,
            )?;
            cost.evaluation_seconds += t.elapsed().as_secs_f64();
            cost.partial_evaluations += 1;
            let mut rows_of: Vec<(usize, Rows)> = Vec::new();
            for &(x, index, k) in &fields {
                if rows_of.last().is_none_or(|r| r.0 != x) {
                    let rows = if solids {
                        self.element_rows(x, ev, true)
                    } else {
                        self.node_rows(x, ev, true)
                    };
                    rows_of.push((x, rows));
                }
                let rows = &rows_of.last().expect("pushed").1;
                for (c, &j) in cols.iter().enumerate() {
                    let v: f64 = (rows.iter()).map(|(o, p)| cots[c][*o] * p[index]).sum();
                    dfdb[j][k] += v;
                }
            }
        }
        Ok(())
    }

    /// Adds to each column's `mu_prev` (column-major) the derivative in the committed history
    /// of every output weighed by the column's cotangent (residual included: `-lambda`), at
    /// the increment stored at position `m` (`s`).
    #[allow(clippy::too_many_arguments)]
    fn h_passes(
        &self,
        cost: &mut SensitivityCost,
        s: &Stored,
        m: usize,
        state: &mut AdState,
        cots: &[Vec<f64>],
        mu_prev: &mut [f64],
        ev: &mut Evaluation<Ad>,
    ) -> Result<(), AnalysisError> {
        let model = self.model;
        let nh = self.asm.dofs.n_history;
        let ne = model.mesh.n_elements();
        let nk = self.nodes.len();
        let every_node = vec![true; nk];
        // solids plastic before this increment: the history multiplier of the others is
        // read by nothing
        let h_member = |e: usize| self.history_read(m, e);
        for colour in 0..self.solid_colours {
            let members = self.solids_of(colour, h_member);
            if members.is_empty() {
                continue;
            }
            let skip = all_but(&members, ne);
            let pass = Pass {
                seeds: Seeds::H,
                inputs: (members.iter())
                    .map(|&e| self.asm.dofs.history(e).collect())
                    .collect(),
                skip: &skip,
                skip_contact: &every_node,
                terms: SOLIDS,
            };
            let rows = |i: usize, ev: &Evaluation<Ad>| self.element_rows(members[i], ev, true);
            self.local_passes(cost, s, state, &pass, ev, rows, cots, (mu_prev, nh))?;
        }
        let no_solid = vec![true; ne];
        for members in &self.colour_nodes {
            let skip = all_but(members, nk);
            let pass = Pass {
                seeds: Seeds::H,
                inputs: (members.iter())
                    .map(|&f| {
                        let (p, i, _) = self.nodes[f];
                        let nhc = model.contacts[p].history_len();
                        let h0 = self.asm.contact_history(p) + nhc * i;
                        (h0..h0 + nhc).collect()
                    })
                    .collect(),
                skip: &no_solid,
                skip_contact: &skip,
                terms: CONTACT,
            };
            let rows = |i: usize, ev: &Evaluation<Ad>| self.node_rows(members[i], ev, true);
            self.local_passes(cost, s, state, &pass, ev, rows, cots, (mu_prev, nh))?;
        }
        Ok(())
    }
}
