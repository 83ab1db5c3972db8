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
//! Nothing is differentiated by hand. The Jacobians of the residual and of the history
//! update with respect to the unknowns and the history come from the same generic kernels
//! evaluated on `DualSVec64<W>` numbers seeded over each element's local unknowns (its
//! degrees of freedom, then its history scalars) and each hitting node's (its block's
//! unknowns, then its history): the elements are coloured so that no two of a colour share an
//! unknown, and the hitting nodes so that no two of a colour share a block unknown, and one
//! evaluation then gives the local Jacobians of a whole colour. The residual's Jacobian in the
//! unknowns is the assembled tangent. The derivatives in the design are one dual evaluation
//! per parameter, as DDM's pseudo-load, over the elements the parameter reaches. A user
//! material or friction law gets the adjoint with no code of its own.
//!
//! At a flagged (non-differentiable) increment the sweep follows the converged branches, as
//! DDM's main value does; the one-sided variants are DDM's (`--method ddm`).

use super::*;
use crate::assembly::{Assembler, Evaluation, Frozen};
use crate::contact::ContactChoice;
use crate::linalg::{LinearSolver, SparseMatrix};
use crate::material::Branch;
use crate::model::{node_dof, DesignParam, Lifted};
use crate::response::{Response, ResponseKind};
use crate::solver::{AnalysisError, Converged, Observer, RunOptions, Solver};
use crate::terms::Terms;
use nalgebra::{Matrix3, Vector3};
use num_dual::{Dual64, DualSVec64};
use std::time::Instant;

/// Directions per local-Jacobian evaluation.
const W: usize = 8;
type Ad = DualSVec64<W>;

/// One converged increment, as the backward sweep needs it.
struct Stored {
    index: usize,
    time: f64,
    z: Vec<f64>,
    hist_prev: Vec<f64>,
    branches: Vec<Branch>,
    choice: Vec<ContactChoice>,
    constrained: Vec<bool>,
    values: Vec<f64>,
    kinks: Vec<Kink>,
}

impl Stored {
    fn bytes(&self) -> usize {
        8 * (self.z.len() + self.hist_prev.len() + self.values.len())
            + self.branches.len()
            + self.constrained.len()
            + std::mem::size_of::<ContactChoice>() * self.choice.len()
    }
}

/// The forward pass: stores every converged increment, the initial history's derivative and
/// the flagged points (by the in-line engine's rules).
struct Recorder<'a> {
    engine: Engine<'a>,
    stored: Vec<Stored>,
    watch: &'a mut dyn FnMut(&Converged<'_>),
    seconds: f64,
}

impl Observer for Recorder<'_> {
    fn converged(&mut self, c: &Converged<'_>) -> Result<(), AnalysisError> {
        let t = Instant::now();
        if self.stored.is_empty() && !c.model.contacts.is_empty() {
            self.engine.initial_history_derivative(c)?;
        }
        self.stored.push(Stored {
            index: c.index,
            time: c.time,
            z: c.z.to_vec(),
            hist_prev: c.hist_prev.to_vec(),
            branches: c.eval.branches.clone(),
            choice: c.eval.contact.choice.clone(),
            constrained: c.constrained.to_vec(),
            values: response_values(c),
            kinks: self.engine.kinks(c),
        });
        self.seconds += t.elapsed().as_secs_f64();
        (self.watch)(c);
        Ok(())
    }
}

/// Sensitivities of every response at every increment by the adjoint method.
pub(super) fn run_adjoint(
    model: &Model,
    params: &[Parameter],
    settings: &Settings,
    watch: &mut dyn FnMut(&Converged<'_>),
) -> Result<(Results, SensitivityResults), AnalysisError> {
    let mut rec = Recorder {
        engine: Engine::new(model, params, settings.clone()),
        stored: Vec::new(),
        watch,
        seconds: 0.0,
    };
    let mut solver = Solver::new(model)?;
    let res = solver.run(&RunOptions::default(), &mut rec)?;
    let Recorder {
        engine,
        stored,
        seconds,
        ..
    } = rec;
    let mut out = engine.results;
    out.primal_seconds = res.cost.wall_seconds - seconds;
    let t = Instant::now();
    // the increments whose responses are the functionals
    let sel: Vec<usize> = if settings.adjoint_at.is_empty() {
        (0..stored.len()).collect()
    } else {
        let mut sel = Vec::new();
        for at in &settings.adjoint_at {
            let m = (stored.iter())
                .position(|s| (s.time - at).abs() < 1e-9)
                .ok_or(SensitivityError::NoIncrementAt { time: *at })?;
            sel.push(m);
        }
        sel.sort_unstable();
        sel.dedup();
        sel
    };
    let mut sweep = Sweep::new(model, params, &stored)?;
    let dfdb = sweep.run(&sel, &engine.dhist)?;
    out.cost = sweep.cost;
    out.cost.wall_seconds = seconds + t.elapsed().as_secs_f64();
    out.cost.stored_bytes = stored.iter().map(Stored::bytes).sum();
    let nr = model.responses.len();
    for (q, &m) in sel.iter().enumerate() {
        let s = &stored[m];
        out.increments.push(IncrementSensitivity {
            increment: s.index,
            time: s.time,
            values: s.values.clone(),
            derivatives: (0..nr).map(|r| dfdb[q * nr + r].clone()).collect(),
            kinks: s.kinks.clone(),
            ..Default::default()
        });
    }
    Ok((res, out))
}

/// A cotangent on an evaluation's outputs: what one column of the sweep weighs each output
/// with.
#[derive(Clone)]
struct Cot {
    /// On the unknowns themselves (a displacement response).
    z: Vec<f64>,
    /// On the residual (reactions; `-lambda` on the free rows after the solve).
    res: Vec<f64>,
    /// On the updated history (`mu`, and history responses).
    hist: Vec<f64>,
    /// On each hitting node's normal force.
    nf: Vec<f64>,
    /// On each hitting node's nominal area (design only).
    area: Vec<f64>,
    /// On each hitting node's current area.
    carea: Vec<f64>,
    /// On each pair's target force.
    pf: Vec<[f64; 3]>,
    /// On each pair's target translation.
    tr: Vec<[f64; 3]>,
    /// On the stresses responses read (`Assembler::stress_elements`), row-major.
    stress: Vec<[f64; 9]>,
}

impl Cot {
    fn zero(asm: &Assembler, n_pairs: usize) -> Self {
        let nk = asm.contact.n_hitting;
        Cot {
            z: vec![0.0; asm.dofs.n_total],
            res: vec![0.0; asm.dofs.n_total],
            hist: vec![0.0; asm.dofs.n_history],
            nf: vec![0.0; nk],
            area: vec![0.0; nk],
            carea: vec![0.0; nk],
            pf: vec![[0.0; 3]; n_pairs],
            tr: vec![[0.0; 3]; n_pairs],
            stress: vec![[0.0; 9]; asm.stress_elements.len()],
        }
    }
}

/// One scalar a response reads.
#[derive(Clone, Copy)]
enum Entry {
    Z(usize),
    Res(usize),
    Hist(usize),
    Nf(usize),
    Area(usize),
    CArea(usize),
    Pf(usize, usize),
    Tr(usize, usize),
    Stress(usize, usize),
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

/// The response's cotangent on the evaluation's outputs at a state: each scalar it reads
/// seeded alone in a dual number, through the response's own generic `value`.
fn response_cotangent(
    r: &Response,
    asm: &Assembler,
    z: &[f64],
    ev: &Evaluation<f64>,
    out: &mut Cot,
) {
    let d = |v: &[f64]| -> Vec<Dual64> { v.iter().map(|x| Dual64::from_re(*x)).collect() };
    let mut zd = d(z);
    let mut res = d(&ev.residual);
    let mut hist = d(&ev.hist_new);
    let mut contact = crate::contact::assembly::ContactEval::<Dual64>::new(
        asm.contact.n_hitting,
        asm.contact.lambda.len(),
    );
    let c = &ev.contact;
    contact.normal_force = d(&c.normal_force);
    contact.area = d(&c.area);
    contact.current_area = d(&c.current_area);
    contact.pair_force = c
        .pair_force
        .iter()
        .map(|v| v.map(Dual64::from_re))
        .collect();
    contact.translation = c
        .translation
        .iter()
        .map(|v| v.map(Dual64::from_re))
        .collect();
    let mut stress: Vec<Matrix3<Dual64>> =
        ev.stress.iter().map(|s| s.map(Dual64::from_re)).collect();
    for e in support(r, asm) {
        let slot: &mut Dual64 = match e {
            Entry::Z(i) => &mut zd[i],
            Entry::Res(i) => &mut res[i],
            Entry::Hist(i) => &mut hist[i],
            Entry::Nf(k) => &mut contact.normal_force[k],
            Entry::Area(k) => &mut contact.area[k],
            Entry::CArea(k) => &mut contact.current_area[k],
            Entry::Pf(p, c) => &mut contact.pair_force[p][c],
            Entry::Tr(p, c) => &mut contact.translation[p][c],
            Entry::Stress(s, i) => &mut stress[s][(i / 3, i % 3)],
        };
        slot.eps = 1.0;
        let input = crate::response::ResponseInput {
            z: &zd,
            residual: &res,
            hist: &hist,
            contact: Some(&contact),
            flat: Some(&asm.contact.flat),
            stress: &stress,
            stress_elements: Some(&asm.stress_elements),
        };
        let g = r.value(&input).eps;
        match e {
            Entry::Z(i) => out.z[i] += g,
            Entry::Res(i) => out.res[i] += g,
            Entry::Hist(i) => out.hist[i] += g,
            Entry::Nf(k) => out.nf[k] += g,
            Entry::Area(k) => out.area[k] += g,
            Entry::CArea(k) => out.carea[k] += g,
            Entry::Pf(p, c) => out.pf[p][c] += g,
            Entry::Tr(p, c) => out.tr[p][c] += g,
            Entry::Stress(s, i) => out.stress[s][i] += g,
        }
        let slot: &mut Dual64 = match e {
            Entry::Z(i) => &mut zd[i],
            Entry::Res(i) => &mut res[i],
            Entry::Hist(i) => &mut hist[i],
            Entry::Nf(k) => &mut contact.normal_force[k],
            Entry::Area(k) => &mut contact.area[k],
            Entry::CArea(k) => &mut contact.current_area[k],
            Entry::Pf(p, c) => &mut contact.pair_force[p][c],
            Entry::Tr(p, c) => &mut contact.translation[p][c],
            Entry::Stress(s, i) => &mut stress[s][(i / 3, i % 3)],
        };
        slot.eps = 0.0;
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
fn colour(items: &[Vec<usize>], n: usize) -> (Vec<usize>, usize) {
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

/// The backward sweep's fixed data and its work.
struct Sweep<'a> {
    model: &'a Model,
    params: &'a [Parameter],
    stored: &'a [Stored],
    asm: Assembler,
    lifted: Lifted<f64>,
    lifted_ad: Lifted<Ad>,
    /// Solid elements with unknowns (springs are in the tangent alone: no history, no
    /// stress), their colours and the colour count.
    solids: Vec<usize>,
    solid_colour: Vec<usize>,
    solid_colours: usize,
    /// Per hitting node (flat): its pair, index in the pair, block unknowns without a
    /// pushed target's, colour.
    nodes: Vec<(usize, usize, Vec<usize>)>,
    node_colour: Vec<usize>,
    node_colours: usize,
    /// Every pushed target's unknown.
    pushed: Vec<usize>,
    /// Per element: the first stored increment at which a Gauss point of it is plastic
    /// (`usize::MAX`: never). An element elastic throughout keeps its history
    /// ([`history_unchanged`]'s rule): the history's derivative in the unknowns is zero there
    /// and the multiplier of its history is read by nothing before its first plastic
    /// increment, so the local Jacobians leave it out.
    first_plastic: Vec<usize>,
    cost: SensitivityCost,
}

impl<'a> Sweep<'a> {
    fn new(
        model: &'a Model,
        params: &'a [Parameter],
        stored: &'a [Stored],
    ) -> Result<Self, AnalysisError> {
        let asm = Assembler::new(model, &[])?;
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
        let first_plastic = (0..model.mesh.n_elements())
            .map(|e| {
                (stored.iter())
                    .position(|s| s.branches[dofs.gauss(e)].contains(&Branch::Plastic))
                    .unwrap_or(usize::MAX)
            })
            .collect();
        Ok(Sweep {
            first_plastic,
            model,
            params,
            stored,
            lifted: model.lifted(&[]),
            lifted_ad: model.lifted(&[]),
            asm,
            solids,
            solid_colour,
            solid_colours,
            nodes,
            node_colour,
            node_colours,
            pushed,
            cost: SensitivityCost::default(),
        })
    }

    /// One evaluation in `W`-wide duals, counted and timed.
    #[allow(clippy::too_many_arguments)]
    fn evaluate_ad(
        &mut self,
        s: &Stored,
        z: &[Ad],
        h: &[Ad],
        skip: &[bool],
        skip_contact: &[bool],
        terms: Terms,
        ev: &mut Evaluation<Ad>,
    ) -> Result<(), AnalysisError> {
        let frozen = Frozen {
            gauss: Some(&s.branches),
            contact: &s.choice,
            skip: Some(skip),
            skip_contact: Some(skip_contact),
            terms,
            ..Frozen::default()
        };
        let t = Instant::now();
        self.asm.evaluate(
            self.model,
            &self.lifted_ad,
            z,
            h,
            s.time,
            Some(&frozen),
            None,
            ev,
        )?;
        self.cost.evaluation_seconds += t.elapsed().as_secs_f64();
        self.cost.partial_evaluations += 1;
        Ok(())
    }

    /// `df/db` of every response at the stored increments `sel` (sorted):
    /// `[q * n_responses + r][k]` for increment `sel[q]`. `dh0` is the initial history's
    /// derivative, parameter-major.
    fn run(&mut self, sel: &[usize], dh0: &[f64]) -> Result<Vec<Vec<f64>>, AnalysisError> {
        let model = self.model;
        let nr = model.responses.len();
        let ns = sel.last().map_or(0, |m| m + 1);
        let np = self.params.len();
        let n = self.asm.dofs.n_total;
        let nh = self.asm.dofs.n_history;
        let ncol = nr * sel.len();
        // the stored increment of column j
        let at = |j: usize| sel[j / nr];
        let n_pairs = model.contacts.len();
        let mut dfdb = vec![vec![0.0; np]; ncol];
        // mu per column (history multipliers carried back)
        let mut mu = vec![vec![0.0; nh]; ncol];
        let mut k = SparseMatrix::new(self.asm.pattern.clone());
        let mut ev = Evaluation::<f64>::new(&self.asm, model.mesh.n_elements());
        let mut ev_ad = Evaluation::<Ad>::new(&self.asm, model.mesh.n_elements());
        let mut ev_d = Evaluation::<Dual64>::new(&self.asm, model.mesh.n_elements());
        let mut solver: Option<LinearSolver> = None;
        let stored = self.stored;
        for m in (0..ns).rev() {
            let s = &stored[m];
            // the converged state, its tangent on the converged branches
            let frozen = Frozen {
                gauss: Some(&s.branches),
                contact: &s.choice,
                ..Frozen::default()
            };
            let t = Instant::now();
            self.asm.evaluate(
                model,
                &self.lifted,
                &s.z,
                &s.hist_prev,
                s.time,
                Some(&frozen),
                Some(&mut k),
                &mut ev,
            )?;
            self.cost.evaluation_seconds += t.elapsed().as_secs_f64();
            self.cost.residual_evaluations += 1;
            // the columns alive at this increment: responses read here or later
            let cols: Vec<usize> = (0..ncol).filter(|&j| at(j) >= m).collect();
            let mut cots: Vec<Cot> = cols
                .iter()
                .map(|&j| {
                    let mut c = Cot::zero(&self.asm, n_pairs);
                    if at(j) == m {
                        response_cotangent(&model.responses[j % nr], &self.asm, &s.z, &ev, &mut c);
                    }
                    for (a, b) in c.hist.iter_mut().zip(&mu[j]) {
                        *a += b;
                    }
                    c
                })
                .collect();
            // d/dz [F + mu . H]
            let mut rhs = vec![0.0; n * cols.len()];
            let mut scratch = vec![0.0; n];
            for (c, cot) in cots.iter().enumerate() {
                let g = &mut rhs[c * n..(c + 1) * n];
                k.mul_vec_transpose(&cot.res, &mut scratch)?;
                for ((gi, a), b) in g.iter_mut().zip(&scratch).zip(&cot.z) {
                    *gi = a + b;
                }
            }
            self.z_passes(m, &cots, &mut rhs, &mut ev_ad)?;
            // K^T lambda = rhs on the free unknowns
            for c in 0..cols.len() {
                for (i, fixed) in s.constrained.iter().enumerate() {
                    if *fixed {
                        rhs[c * n + i] = 0.0;
                    }
                }
            }
            self.solve_transposed(s, &k, &mut rhs, cols.len(), &mut solver)?;
            for (c, cot) in cots.iter_mut().enumerate() {
                for (r, l) in cot.res.iter_mut().zip(&rhs[c * n..(c + 1) * n]) {
                    *r -= l;
                }
            }
            // mu_{n-1} = d/dh [F + mu . H - lambda . R]
            let mut mu_prev = vec![vec![0.0; nh]; cols.len()];
            if nh > 0 {
                self.h_passes(m, &cots, &mut mu_prev, &mut ev_ad)?;
            }
            // d/db [F + mu . H - lambda . R], prescribed unknowns moving with the design
            let params = self.params;
            for (p, _) in params.iter().enumerate() {
                let t = Instant::now();
                let (lifted, zd) = self.seeded(s, p);
                let hd: Vec<Dual64> = s.hist_prev.iter().map(|v| Dual64::from_re(*v)).collect();
                let reach = Reach::seeded(&lifted);
                let skip = self.unreached(s, &reach, &zd);
                let fr = Frozen {
                    skip: Some(&skip),
                    ..frozen
                };
                self.asm
                    .evaluate(model, &lifted, &zd, &hd, s.time, Some(&fr), None, &mut ev_d)?;
                self.cost.evaluation_seconds += t.elapsed().as_secs_f64();
                self.cost.partial_evaluations += 1;
                for (c, &j) in cols.iter().enumerate() {
                    let mut v = 0.0;
                    if at(j) == m {
                        v += model.responses[j % nr]
                            .value(&ev_d.response_input(&zd, &self.asm))
                            .eps;
                    }
                    v += (mu[j].iter().zip(&ev_d.hist_new))
                        .map(|(a, b)| a * b.eps)
                        .sum::<f64>();
                    // -lambda . R_b: `cot.res` holds F's cotangent less lambda, and F's own
                    // reaction part is already in its value above
                    let lam = &rhs[c * n..(c + 1) * n];
                    v -= (lam.iter().zip(&ev_d.residual))
                        .map(|(a, b)| a * b.eps)
                        .sum::<f64>();
                    dfdb[j][p] += v;
                }
            }
            for (c, &j) in cols.iter().enumerate() {
                mu[j] = std::mem::take(&mut mu_prev[c]);
            }
        }
        // mu_0 . dh_0/db
        for (j, row) in dfdb.iter_mut().enumerate() {
            for (p, d) in row.iter_mut().enumerate() {
                *d += (mu[j].iter().zip(&dh0[p * nh..(p + 1) * nh]))
                    .map(|(a, b)| a * b)
                    .sum::<f64>();
            }
        }
        Ok(dfdb)
    }

    /// The design seeded along parameter `p`, and the state with the prescribed unknowns
    /// carrying their derivative.
    fn seeded(&self, s: &Stored, p: usize) -> (Lifted<Dual64>, Vec<Dual64>) {
        let par = &self.params[p];
        let overrides: Vec<(DesignParam, Dual64)> = par
            .targets
            .iter()
            .map(|t| (*t, Dual64::new(par.value, 1.0)))
            .collect();
        let lifted = self.model.lifted(&overrides);
        let mut dzc = vec![0.0; s.z.len()];
        for (i, pr) in self.model.prescribed.iter().enumerate() {
            if par.targets.contains(&DesignParam::Prescribed { index: i }) {
                let a = pr.amplitude.at(s.time);
                for &nd in &pr.nodes {
                    dzc[node_dof(nd, pr.component)] += a;
                }
            }
        }
        let z =
            s.z.iter()
                .zip(&dzc)
                .map(|(r, e)| Dual64::new(*r, *e))
                .collect();
        (lifted, z)
    }

    /// The elements a parameter's seeds do not reach: no moved node, no changed material
    /// parameter of its body, no moving prescribed unknown (the state and history carry no
    /// derivative here). Elements whose stress a response reads are always evaluated.
    fn unreached(&self, _s: &Stored, reach: &Reach, z: &[Dual64]) -> Vec<bool> {
        let dofs = &self.asm.dofs;
        (0..self.model.mesh.n_elements())
            .map(|e| {
                let b = dofs.element_body[e];
                let material = self
                    .model
                    .bodies
                    .get(b)
                    .is_some_and(|_| reach.material[b].iter().any(|c| *c));
                let reached = material
                    || self
                        .model
                        .mesh
                        .element_nodes(e)
                        .iter()
                        .any(|&nd| reach.moved[nd])
                    || dofs.element_dofs(e).iter().any(|&i| z[i].eps != 0.0)
                    || self.asm.stress_slot(e).is_some();
                !reached && !dofs.gauss(e).is_empty()
            })
            .collect()
    }

    /// `K^T X = RHS` with the tangent `k` at the converged state (prescribed unknowns as
    /// identity rows), factored anew: the backward sweep keeps no factor of the forward run.
    fn solve_transposed(
        &mut self,
        s: &Stored,
        k: &SparseMatrix,
        rhs: &mut [f64],
        ncols: usize,
        solver: &mut Option<LinearSolver>,
    ) -> Result<(), AnalysisError> {
        let mut kd = k.clone();
        for (d, fixed) in s.constrained.iter().enumerate() {
            if *fixed {
                kd.set_identity_row_col(d).expect("in range");
            }
        }
        if solver.is_none() {
            *solver = Some(LinearSolver::new(self.asm.pattern.clone())?);
        }
        let ls = solver.as_mut().expect("just made");
        let t = Instant::now();
        ls.factor(&kd)?;
        self.cost.factor_seconds += t.elapsed().as_secs_f64();
        self.cost.factorizations += 1;
        let t = Instant::now();
        let b = rhs.to_vec();
        ls.solve_transpose_multi_in_place(rhs, ncols)?;
        self.cost.solve_columns += ncols;
        // refined to the solution rounded to working precision, as DDM's solves are
        let ls = &*ls;
        let mut correct = |r: &mut [f64], cost: &mut SensitivityCost| {
            cost.solve_columns += ncols;
            ls.solve_transpose_multi_in_place(r, ncols)
        };
        refine_extended(&kd, true, &b, rhs, ncols, &mut self.cost, &mut correct)?;
        self.cost.solve_seconds += t.elapsed().as_secs_f64();
        Ok(())
    }

    /// Adds to each column of `rhs` the derivative in the unknowns of the outputs other than
    /// the residual (history, stresses, contact forces, targets) weighed by the column's
    /// cotangent: local Jacobians by coloured dual evaluations.
    fn z_passes(
        &mut self,
        m: usize,
        cots: &[Cot],
        rhs: &mut [f64],
        ev: &mut Evaluation<Ad>,
    ) -> Result<(), AnalysisError> {
        let model = self.model;
        let s = &self.stored[m];
        let n = self.asm.dofs.n_total;
        let ne = model.mesh.n_elements();
        let nk = self.nodes.len();
        let const_z: Vec<Ad> = s.z.iter().map(|v| Ad::from_re(*v)).collect();
        let const_h: Vec<Ad> = s.hist_prev.iter().map(|v| Ad::from_re(*v)).collect();
        let mut z = const_z.clone();
        // solids: the history and the stresses read, in each element's unknowns
        let want_solids = self.asm.dofs.n_history > 0 || !self.asm.stress_elements.is_empty();
        let max_nd = (self.solids.iter())
            .map(|&e| self.asm.dofs.element_dofs(e).len())
            .max()
            .unwrap_or(0);
        let solids_only = Terms {
            solids: true,
            ..Terms::NONE
        };
        let all_nodes = vec![true; nk];
        for colour in 0..self.solid_colours {
            if !want_solids {
                break;
            }
            // elastic at this increment: the history does not move with the unknowns
            let members: Vec<usize> = (0..self.solids.len())
                .filter(|i| self.solid_colour[*i] == colour)
                .map(|i| self.solids[i])
                .filter(|&e| {
                    self.asm.stress_slot(e).is_some()
                        || s.branches[self.asm.dofs.gauss(e)].contains(&Branch::Plastic)
                })
                .collect();
            if members.is_empty() {
                continue;
            }
            let mut skip = vec![true; ne];
            for &e in &members {
                skip[e] = false;
            }
            for chunk in 0..max_nd.div_ceil(W) {
                for &e in &members {
                    for (l, &g) in self.asm.dofs.element_dofs(e).iter().enumerate() {
                        if l / W == chunk {
                            z[g] = Ad::from_re(s.z[g]).derivative(l % W);
                        }
                    }
                }
                self.evaluate_ad(s, &z, &const_h, &skip, &all_nodes, solids_only, ev)?;
                for &e in &members {
                    let dofs = self.asm.element_dofs(e);
                    let hist = self.asm.dofs.history(e);
                    let hp: Vec<[f64; W]> = ev.hist_new[hist.clone()].iter().map(parts).collect();
                    let sp: Option<(usize, Vec<[f64; W]>)> = self.asm.stress_slot(e).map(|sl| {
                        (
                            sl,
                            (0..9)
                                .map(|i| parts(&ev.stress[sl][(i / 3, i % 3)]))
                                .collect(),
                        )
                    });
                    for (l, &g) in dofs.iter().enumerate() {
                        if l / W != chunk {
                            continue;
                        }
                        let d = l % W;
                        for (c, cot) in cots.iter().enumerate() {
                            let mut v = 0.0;
                            for (i, p) in hist.clone().zip(&hp) {
                                v += cot.hist[i] * p[d];
                            }
                            if let Some((sl, ps)) = &sp {
                                for (i, p) in ps.iter().enumerate() {
                                    v += cot.stress[*sl][i] * p[d];
                                }
                            }
                            rhs[c * n + g] += v;
                        }
                    }
                }
                for &e in &members {
                    for &g in self.asm.dofs.element_dofs(e) {
                        z[g] = const_z[g];
                    }
                }
            }
        }
        if model.contacts.is_empty() {
            return Ok(());
        }
        // contact: the nodes' history, normal forces and target forces
        let contact_only = Terms {
            contact_normal: true,
            friction: true,
            ..Terms::NONE
        };
        let no_solids = vec![true; ne];
        let max_nb = self.nodes.iter().map(|b| b.2.len()).max().unwrap_or(0);
        for colour in 0..self.node_colours {
            let members: Vec<usize> = (0..nk).filter(|f| self.node_colour[*f] == colour).collect();
            let mut skip = vec![true; nk];
            for &f in &members {
                skip[f] = false;
            }
            for chunk in 0..max_nb.div_ceil(W) {
                for &f in &members {
                    for (l, &g) in self.nodes[f].2.iter().enumerate() {
                        if l / W == chunk {
                            z[g] = Ad::from_re(s.z[g]).derivative(l % W);
                        }
                    }
                }
                self.evaluate_ad(s, &z, &const_h, &no_solids, &skip, contact_only, ev)?;
                for &f in &members {
                    let (p, i, ref own) = self.nodes[f];
                    let hitting = model.contacts[p].hitting[i];
                    let nhc = model.contacts[p].history_len();
                    let h0 = self.asm.contact_history(p) + nhc * i;
                    let hp: Vec<[f64; W]> = ev.hist_new[h0..h0 + nhc].iter().map(parts).collect();
                    let nfp = parts(&ev.contact.normal_force[f]);
                    // the node's force on the target is minus its hitting node's rows
                    let fp: Vec<[f64; W]> = (0..3)
                        .map(|c| parts(&ev.residual[node_dof(hitting, c)]))
                        .collect();
                    for (l, &g) in own.iter().enumerate() {
                        if l / W != chunk {
                            continue;
                        }
                        let d = l % W;
                        for (c, cot) in cots.iter().enumerate() {
                            let mut v = cot.nf[f] * nfp[d];
                            for (a, pa) in hp.iter().enumerate() {
                                v += cot.hist[h0 + a] * pa[d];
                            }
                            for (cc, pa) in fp.iter().enumerate() {
                                v -= cot.pf[p][cc] * pa[d];
                            }
                            rhs[c * n + g] += v;
                        }
                    }
                }
                for &f in &members {
                    for &g in &self.nodes[f].2 {
                        z[g] = const_z[g];
                    }
                }
            }
        }
        // a pushed target's translations: every node sees them
        let pushed = self.pushed.clone();
        let none = vec![false; nk];
        for chunk in pushed.chunks(W) {
            for (d, &g) in chunk.iter().enumerate() {
                z[g] = Ad::from_re(s.z[g]).derivative(d);
            }
            self.evaluate_ad(s, &z, &const_h, &no_solids, &none, contact_only, ev)?;
            let first = self.asm.dofs.first_contact_history;
            let hp: Vec<[f64; W]> = ev.hist_new[first..].iter().map(parts).collect();
            let nfp: Vec<[f64; W]> = ev.contact.normal_force.iter().map(parts).collect();
            for (d, &g) in chunk.iter().enumerate() {
                for (c, cot) in cots.iter().enumerate() {
                    let mut v = 0.0;
                    for (a, pa) in hp.iter().enumerate() {
                        v += cot.hist[first + a] * pa[d];
                    }
                    for (f, pa) in nfp.iter().enumerate() {
                        v += cot.nf[f] * pa[d];
                    }
                    for p in 0..model.contacts.len() {
                        for cc in 0..3 {
                            v += cot.pf[p][cc] * parts(&ev.contact.pair_force[p][cc])[d];
                            v += cot.tr[p][cc] * parts(&ev.contact.translation[p][cc])[d];
                        }
                    }
                    rhs[c * n + g] += v;
                }
            }
            for &g in chunk {
                z[g] = const_z[g];
            }
        }
        // the current tributary areas, from the hitting faces' nodes
        self.current_area_pass(s, cots, rhs);
        Ok(())
    }

    /// The current areas' part of the unknowns' derivative: each node of a pair's hitting
    /// faces seeded alone, through the same generic area routine the contact evaluation
    /// uses.
    fn current_area_pass(&self, s: &Stored, cots: &[Cot], rhs: &mut [f64]) {
        let n = self.asm.dofs.n_total;
        for (p, pair) in self.model.contacts.iter().enumerate() {
            let Some(faces) = &pair.hitting_faces else {
                continue;
            };
            let first = self.asm.contact_flat(p);
            let range = first..first + pair.hitting.len();
            if cots
                .iter()
                .all(|c| c.carea[range.clone()].iter().all(|v| *v == 0.0))
            {
                continue;
            }
            let pos = |nd: usize| -> Vector3<f64> {
                self.lifted.coords[nd]
                    + Vector3::new(
                        s.z[node_dof(nd, 0)],
                        s.z[node_dof(nd, 1)],
                        s.z[node_dof(nd, 2)],
                    )
            };
            for &nd in faces.all_nodes() {
                for comp in 0..3 {
                    let areas = faces.tributary_areas_at(
                        |m| {
                            let x = pos(m).map(Dual64::from_re);
                            if m == nd {
                                let mut x = x;
                                x[comp].eps = 1.0;
                                x
                            } else {
                                x
                            }
                        },
                        &pair.hitting,
                    );
                    let g = node_dof(nd, comp);
                    for (c, cot) in cots.iter().enumerate() {
                        let v: f64 = (areas.iter().zip(&cot.carea[range.clone()]))
                            .map(|(a, w)| a.eps * w)
                            .sum();
                        rhs[c * n + g] += v;
                    }
                }
            }
        }
    }

    /// Adds to each column's `mu_prev` the derivative in the committed history of every
    /// output weighed by the column's cotangent (residual included: `-lambda`).
    fn h_passes(
        &mut self,
        m: usize,
        cots: &[Cot],
        mu_prev: &mut [Vec<f64>],
        ev: &mut Evaluation<Ad>,
    ) -> Result<(), AnalysisError> {
        let model = self.model;
        let s = &self.stored[m];
        let ne = model.mesh.n_elements();
        let nk = self.nodes.len();
        let z: Vec<Ad> = s.z.iter().map(|v| Ad::from_re(*v)).collect();
        let const_h: Vec<Ad> = s.hist_prev.iter().map(|v| Ad::from_re(*v)).collect();
        let mut h = const_h.clone();
        let solids_only = Terms {
            solids: true,
            ..Terms::NONE
        };
        let all_nodes = vec![true; nk];
        let max_nh = (self.solids.iter())
            .map(|&e| self.asm.dofs.history(e).len())
            .max()
            .unwrap_or(0);
        for colour in 0..self.solid_colours {
            let members: Vec<usize> = (0..self.solids.len())
                .filter(|i| self.solid_colour[*i] == colour)
                .map(|i| self.solids[i])
                .filter(|&e| !self.asm.dofs.history(e).is_empty() && self.first_plastic[e] < m)
                .collect();
            if members.is_empty() {
                continue;
            }
            let mut skip = vec![true; ne];
            for &e in &members {
                skip[e] = false;
            }
            for chunk in 0..max_nh.div_ceil(W) {
                for &e in &members {
                    for (l, i) in self.asm.dofs.history(e).enumerate() {
                        if l / W == chunk {
                            h[i] = Ad::from_re(s.hist_prev[i]).derivative(l % W);
                        }
                    }
                }
                self.evaluate_ad(s, &z, &h, &skip, &all_nodes, solids_only, ev)?;
                for &e in &members {
                    let dofs = self.asm.element_dofs(e);
                    let hist = self.asm.dofs.history(e);
                    let rp: Vec<[f64; W]> = dofs.iter().map(|&g| parts(&ev.residual[g])).collect();
                    let hp: Vec<[f64; W]> = ev.hist_new[hist.clone()].iter().map(parts).collect();
                    let sp: Option<(usize, Vec<[f64; W]>)> = self.asm.stress_slot(e).map(|sl| {
                        (
                            sl,
                            (0..9)
                                .map(|i| parts(&ev.stress[sl][(i / 3, i % 3)]))
                                .collect(),
                        )
                    });
                    for (l, i0) in hist.clone().enumerate() {
                        if l / W != chunk {
                            continue;
                        }
                        let d = l % W;
                        for (c, cot) in cots.iter().enumerate() {
                            let mut v = 0.0;
                            for (&g, p) in dofs.iter().zip(&rp) {
                                v += cot.res[g] * p[d];
                            }
                            for (i, p) in hist.clone().zip(&hp) {
                                v += cot.hist[i] * p[d];
                            }
                            if let Some((sl, ps)) = &sp {
                                for (i, p) in ps.iter().enumerate() {
                                    v += cot.stress[*sl][i] * p[d];
                                }
                            }
                            mu_prev[c][i0] += v;
                        }
                    }
                }
                for &e in &members {
                    for i in self.asm.dofs.history(e) {
                        h[i] = const_h[i];
                    }
                }
            }
        }
        if model.contacts.is_empty() {
            return Ok(());
        }
        let contact_only = Terms {
            contact_normal: true,
            friction: true,
            ..Terms::NONE
        };
        let no_solids = vec![true; ne];
        let max_nhc = model
            .contacts
            .iter()
            .map(|p| p.history_len())
            .max()
            .unwrap_or(0);
        for colour in 0..self.node_colours {
            let members: Vec<usize> = (0..nk).filter(|f| self.node_colour[*f] == colour).collect();
            let mut skip = vec![true; nk];
            for &f in &members {
                skip[f] = false;
            }
            for chunk in 0..max_nhc.div_ceil(W) {
                let mut any = false;
                for &f in &members {
                    let (p, i, _) = self.nodes[f];
                    let nhc = model.contacts[p].history_len();
                    let h0 = self.asm.contact_history(p) + nhc * i;
                    for l in 0..nhc {
                        if l / W == chunk {
                            h[h0 + l] = Ad::from_re(s.hist_prev[h0 + l]).derivative(l % W);
                            any = true;
                        }
                    }
                }
                if !any {
                    continue;
                }
                self.evaluate_ad(s, &z, &h, &no_solids, &skip, contact_only, ev)?;
                for &f in &members {
                    let (p, i, ref own) = self.nodes[f];
                    let pair = &model.contacts[p];
                    let hitting = pair.hitting[i];
                    let nhc = pair.history_len();
                    let h0 = self.asm.contact_history(p) + nhc * i;
                    let rp: Vec<[f64; W]> = own.iter().map(|&g| parts(&ev.residual[g])).collect();
                    let hp: Vec<[f64; W]> = ev.hist_new[h0..h0 + nhc].iter().map(parts).collect();
                    let nfp = parts(&ev.contact.normal_force[f]);
                    let fp: Vec<[f64; W]> = (0..3)
                        .map(|c| parts(&ev.residual[node_dof(hitting, c)]))
                        .collect();
                    let targets: Vec<(usize, usize)> = pair
                        .pushed(&self.asm.contact.target[p])
                        .map(|(_, dof, mo)| (dof, mo.component))
                        .collect();
                    for l in 0..nhc {
                        if l / W != chunk {
                            continue;
                        }
                        let d = l % W;
                        for (c, cot) in cots.iter().enumerate() {
                            let mut v = cot.nf[f] * nfp[d];
                            for (&g, pa) in own.iter().zip(&rp) {
                                v += cot.res[g] * pa[d];
                            }
                            for (a, pa) in hp.iter().enumerate() {
                                v += cot.hist[h0 + a] * pa[d];
                            }
                            // the target force and a pushed target's rows: the node's force,
                            // minus its hitting node's rows
                            for (cc, pa) in fp.iter().enumerate() {
                                v -= cot.pf[p][cc] * pa[d];
                            }
                            for &(dof, cc) in &targets {
                                v -= cot.res[dof] * fp[cc][d];
                            }
                            mu_prev[c][h0 + l] += v;
                        }
                    }
                }
                for &f in &members {
                    let (p, i, _) = self.nodes[f];
                    let nhc = model.contacts[p].history_len();
                    let h0 = self.asm.contact_history(p) + nhc * i;
                    h[h0..h0 + nhc].copy_from_slice(&const_h[h0..h0 + nhc]);
                }
            }
        }
        Ok(())
    }
}
