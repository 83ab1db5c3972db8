//! SDM's error anatomy (`Settings::explain`): where, at each increment, SDM's derivative
//! departs from DDM's, term by term of the residual.
//!
//! SDM replaces the pseudo-load `-dR/db` by a finite difference of the residual at the fixed
//! converged state. Its error in a response's derivative at increment `n` splits into (all
//! against DDM solved with the same tangent; the parts add up to the error up to the round-off
//! of the differences, `eps |R_t| / h`, since each term is differenced from its own partial
//! evaluation: where round-off dominates the error, the terms' shares are that round-off's):
//!
//! ```text
//! SDM - DDM = sum_t g . K^-1 (D_t - F_t)           the terms of the pseudo-load
//!           + [SDM - d/db resp(b, z + dz_SDM)]     the response's own difference
//!           + [DDM(dh_SDM) - DDM(dh_DDM)]          carried in through the history derivative
//! ```
//!
//! * `F_t`: the finite-difference unbalance of residual term `t` ([`Term`]: the solid
//!   elements on their elastic and on their plastic branch (the return map), the springs, the
//!   normal contact, the friction, the loads), with SDM's own step and SDM's own incoming
//!   history derivative `dh_SDM`; `D_t` the same term's exact (dual) pseudo-load at the same
//!   state; `g . v` the exact derivative of the response along `dz = v`. The residual is the
//!   sum of its terms, so the terms' errors add up to the pseudo-load's.
//! * The response's own difference: SDM evaluates each response at the perturbed design and
//!   state and differences it; this is that difference less the exact derivative along SDM's
//!   own `dz` (its curvature in the design and in the state).
//! * Carried in: DDM's derivative with SDM's incoming history derivative less DDM's own, the
//!   error of the earlier increments that reaches this one.
//!
//! Each term's error is split into truncation and round-off by the beta scaling: the same
//! term at [`TRUNCATION_SCALE`] times the step. Truncation grows as the step to the method's
//! order (1 forward, 2 central), round-off falls as its inverse; the term at the larger step is
//! taken as truncation alone and scaled back, the rest is round-off (and whatever the
//! truncation's higher orders add). Its local order `log10 |e(10 h)| / |e(h)|` says which
//! dominates (near the order: truncation; near -1: round-off), and for forward SDM the
//! truncation is `h/2` times the term's curvature in `b`.

use super::*;
use crate::assembly::{Evaluation, Frozen, Terms};
use crate::material::Branch;
use crate::model::Lifted;
use crate::solver::{AnalysisError, Converged};
use num_dual::Dual64;

/// The step multiple at which each term's truncation is measured.
pub const TRUNCATION_SCALE: f64 = 10.0;

/// A term of the residual, with a kernel of its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Term {
    /// Solid elements whose Gauss points are all elastic at the converged state.
    ElasticElements,
    /// Solid elements with a plastic Gauss point: the internal force through the return map.
    PlasticElements,
    /// Discrete springs.
    Springs,
    /// Normal contact forces and the multipliers' constraint rows.
    ContactNormal,
    /// Friction forces.
    Friction,
    /// Point loads, pressures, and the applied force on a pushed rigid target.
    Loads,
}

impl Term {
    /// Every term, in the order of [`ErrorParts::terms`].
    pub const ALL: [Term; 6] = [
        Term::ElasticElements,
        Term::PlasticElements,
        Term::Springs,
        Term::ContactNormal,
        Term::Friction,
        Term::Loads,
    ];

    /// How the report and `--explain` name it.
    pub fn name(self) -> &'static str {
        match self {
            Term::ElasticElements => "elastic elements",
            Term::PlasticElements => "plastic elements (return map)",
            Term::Springs => "springs",
            Term::ContactNormal => "contact normal",
            Term::Friction => "friction",
            Term::Loads => "loads",
        }
    }

    /// Its column name in `anatomy.csv`.
    pub fn key(self) -> &'static str {
        match self {
            Term::ElasticElements => "elastic_elements",
            Term::PlasticElements => "plastic_elements",
            Term::Springs => "springs",
            Term::ContactNormal => "contact_normal",
            Term::Friction => "friction",
            Term::Loads => "loads",
        }
    }

    fn terms(self) -> Terms {
        let mut t = Terms::NONE;
        match self {
            Term::ElasticElements | Term::PlasticElements => t.solids = true,
            Term::Springs => t.springs = true,
            Term::ContactNormal => t.contact_normal = true,
            Term::Friction => t.friction = true,
            Term::Loads => t.loads = true,
        }
        t
    }
}

/// One part of SDM's error that the beta scaling splits: its value at the step, at
/// [`TRUNCATION_SCALE`] times the step, and the truncation inferred from that.
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Split {
    /// The part's error at SDM's step.
    pub value: f64,
    /// The same at [`TRUNCATION_SCALE`] times the step.
    pub at_larger_step: f64,
    /// Of `value`, the truncation: `at_larger_step` scaled back by the method's order.
    pub truncation: f64,
}

impl Split {
    fn new(value: f64, at_larger_step: f64, order: i32) -> Self {
        Split {
            value,
            at_larger_step,
            truncation: at_larger_step / TRUNCATION_SCALE.powi(order),
        }
    }

    /// The round-off (and whatever the truncation's higher orders add).
    pub fn roundoff(&self) -> f64 {
        self.value - self.truncation
    }

    /// The local order between the step and [`TRUNCATION_SCALE`] times it: near the method's
    /// order where truncation dominates, near -1 where round-off does (`None`: no error).
    pub fn order(&self) -> Option<f64> {
        let (a, b) = (self.value.abs(), self.at_larger_step.abs());
        (a > 0.0 && b > 0.0).then(|| (b / a).log10() / TRUNCATION_SCALE.log10())
    }
}

/// A part of SDM's error, as [`ErrorParts::named`] lists them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    /// A term of the residual.
    Term(Term),
    /// The response's own difference.
    Response,
    /// Carried in through the history derivative.
    CarriedIn,
}

impl Part {
    /// How the report and `--explain` name it.
    pub fn name(self) -> &'static str {
        match self {
            Part::Term(t) => t.name(),
            Part::Response => "the response's own difference",
            Part::CarriedIn => "carried in through the history",
        }
    }
}

/// SDM's error in one derivative at one increment, split (module docs).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct ErrorParts {
    /// SDM less DDM.
    pub total: f64,
    /// Per [`Term::ALL`]: the error its finite-difference unbalance makes, through the solve.
    pub terms: [Split; 6],
    /// The response's own difference.
    pub response: Split,
    /// Carried in from earlier increments through the history derivative.
    pub propagated: f64,
}

impl ErrorParts {
    /// The parts added up: equal to [`ErrorParts::total`] to round-off.
    pub fn sum(&self) -> f64 {
        self.terms.iter().map(|t| t.value).sum::<f64>() + self.response.value + self.propagated
    }

    /// Every part with its value, largest first, and its split where it has one.
    pub fn named(&self) -> Vec<(Part, f64, Option<Split>)> {
        let mut v: Vec<(Part, f64, Option<Split>)> = Term::ALL
            .iter()
            .zip(&self.terms)
            .map(|(t, s)| (Part::Term(*t), s.value, Some(*s)))
            .collect();
        v.push((Part::Response, self.response.value, Some(self.response)));
        v.push((Part::CarriedIn, self.propagated, None));
        v.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
        v
    }
}

/// The anatomy of SDM's error at one increment.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct IncrementAnatomy {
    /// Increment number.
    pub increment: usize,
    /// Pseudo-time at its end.
    pub time: f64,
    /// `[r][p]`, like the derivatives.
    pub parts: Vec<Vec<ErrorParts>>,
    /// `[r][p]`: DDM's derivative (the reference).
    pub reference: Vec<Vec<f64>>,
}

impl Engine<'_> {
    /// The anatomy of SDM's step `sdm` at this increment (module docs). `self.dhist` holds
    /// SDM's incoming history derivative, `self.exact_dhist` DDM's, which this carries on.
    pub(super) fn anatomy(
        &mut self,
        c: &Converged<'_>,
        central: bool,
        sdm: &Step,
    ) -> Result<IncrementAnatomy, AnalysisError> {
        let np = self.params.len();
        let n = c.z.len();
        let nr = c.model.responses.len();
        let ne = c.model.mesh.n_elements();
        let converged = converged_frozen(c);
        // DDM on SDM's history derivative, then on its own
        let p_sdm = self.pseudo_loads(c, &converged)?;
        let on_sdm = self.ddm(c, &converged, &p_sdm)?;
        std::mem::swap(&mut self.dhist, &mut self.exact_dhist);
        let exact = self
            .pseudo_loads(c, &converged)
            .and_then(|p| self.ddm(c, &converged, &p));
        std::mem::swap(&mut self.dhist, &mut self.exact_dhist);
        let exact = exact?;
        self.exact_dhist.clone_from(&exact.dhist);

        // the terms present, each with its element mask
        let dofs = &c.assembler.dofs;
        let plastic: Vec<bool> = (0..ne)
            .map(|e| c.eval.branches[dofs.gauss(e)].contains(&Branch::Plastic))
            .collect();
        let solid = |e: usize| !dofs.gauss(e).is_empty();
        let model = c.model;
        let present = |t: Term| match t {
            Term::ElasticElements => (0..ne).any(|e| solid(e) && !plastic[e]),
            Term::PlasticElements => (0..ne).any(|e| solid(e) && plastic[e]),
            Term::Springs => !model.springs.is_empty(),
            Term::ContactNormal => !model.contacts.is_empty(),
            Term::Friction => model.contacts.iter().any(|p| p.friction.is_some()),
            Term::Loads => {
                !model.loads.is_empty()
                    || !model.pressures.is_empty()
                    || c.assembler
                        .contact
                        .target
                        .iter()
                        .flatten()
                        .any(Option::is_some)
            }
        };
        let skip_plastic = plastic.clone();
        let skip_elastic: Vec<bool> = plastic.iter().map(|p| !p).collect();
        let terms: Vec<(usize, Term)> = Term::ALL
            .iter()
            .copied()
            .enumerate()
            .filter(|(_, t)| present(*t))
            .collect();
        let scales = [1.0, TRUNCATION_SCALE];
        // columns: (term, scale, parameter), each D_t - F_t on the free rows
        let ncols = terms.len() * scales.len() * np;
        let mut rhs = vec![0.0; n * ncols];
        let col = |ti: usize, si: usize, k: usize| (ti * scales.len() + si) * np + k;
        let mut ev_p = Evaluation::<f64>::new(c.assembler, ne);
        let mut ev_m = Evaluation::<f64>::new(c.assembler, ne);
        let mut ev_0 = Evaluation::<f64>::new(c.assembler, ne);
        let mut ev_d = Evaluation::<Dual64>::new(c.assembler, ne);
        for (ti, &(_, t)) in terms.iter().enumerate() {
            let frozen = Frozen {
                terms: t.terms(),
                skip: match t {
                    Term::ElasticElements => Some(&skip_plastic[..]),
                    Term::PlasticElements => Some(&skip_elastic[..]),
                    _ => None,
                },
                ..converged
            };
            if !central {
                self.evaluate(
                    c,
                    c.lifted,
                    c.z,
                    c.hist_prev,
                    Some(&frozen),
                    None,
                    &mut ev_0,
                )?;
            }
            for (k, dzc) in p_sdm.dzc.iter().enumerate() {
                // the term's exact pseudo-load
                let z = super::ddm::duals(c.z, dzc);
                let (lifted, hist) = (&p_sdm.designs[k], &p_sdm.hists[k]);
                self.evaluate(c, lifted, &z, hist, Some(&frozen), None, &mut ev_d)?;
                for (si, scale) in scales.iter().enumerate() {
                    let db = self.params[k].step(self.settings.beta) * scale;
                    let lifted = self.lifted_at(c, k, db);
                    self.perturbed(c, k, db, &lifted, dzc, Some(&frozen), &mut ev_p)?;
                    if central {
                        let lifted = self.lifted_at(c, k, -db);
                        self.perturbed(c, k, -db, &lifted, dzc, Some(&frozen), &mut ev_m)?;
                    }
                    let j = col(ti, si, k);
                    for i in (0..n).filter(|&i| !c.constrained[i]) {
                        let fd = if central {
                            (ev_p.residual[i] - ev_m.residual[i]) / (2.0 * db)
                        } else {
                            (ev_p.residual[i] - ev_0.residual[i]) / db
                        };
                        rhs[j * n + i] = ev_d.residual[i].eps - fd;
                    }
                }
            }
        }
        self.solve(c, &mut rhs, ncols)?;
        // each column's exact derivative of every response along it (design and history
        // fixed: linear in the column)
        let constant: Lifted<Dual64> = c.model.lifted::<Dual64>(&[]);
        let hist0: Vec<Dual64> = c.hist_prev.iter().map(|h| Dual64::from(*h)).collect();
        let mut along = vec![vec![0.0; ncols]; nr];
        for j in 0..ncols {
            let v = &rhs[j * n..(j + 1) * n];
            if v.iter().all(|x| *x == 0.0) {
                continue;
            }
            let z = super::ddm::duals(c.z, v);
            self.evaluate(c, &constant, &z, &hist0, Some(&converged), None, &mut ev_d)?;
            for (r, resp) in c.model.responses.iter().enumerate() {
                along[r][j] = resp.value(&ev_d.response_input(&z, c.assembler)).eps;
            }
        }
        // the exact derivative along SDM's own dz, and SDM's difference of the responses
        // along it at the larger step
        let mut exact_along_sdm = vec![vec![0.0; np]; nr];
        let mut larger_step = vec![vec![0.0; np]; nr];
        let values = response_values(c);
        for (k, dz) in sdm.dz.iter().enumerate() {
            let z = super::ddm::duals(c.z, dz);
            let (lifted, hist) = (&p_sdm.designs[k], &p_sdm.hists[k]);
            self.evaluate(c, lifted, &z, hist, Some(&converged), None, &mut ev_d)?;
            for (r, resp) in c.model.responses.iter().enumerate() {
                exact_along_sdm[r][k] = resp.value(&ev_d.response_input(&z, c.assembler)).eps;
            }
            let db = self.params[k].step(self.settings.beta) * TRUNCATION_SCALE;
            let moved = |sign: f64| -> Vec<f64> {
                c.z.iter().zip(dz).map(|(z, d)| z + sign * db * d).collect()
            };
            let lifted = self.lifted_at(c, k, db);
            self.perturbed(c, k, db, &lifted, dz, Some(&converged), &mut ev_p)?;
            let zp = moved(1.0);
            if central {
                let lifted = self.lifted_at(c, k, -db);
                self.perturbed(c, k, -db, &lifted, dz, Some(&converged), &mut ev_m)?;
            }
            let zm = moved(-1.0);
            for (r, resp) in c.model.responses.iter().enumerate() {
                let vp = resp.value(&ev_p.response_input(&zp, c.assembler));
                let d = if central {
                    (vp - resp.value(&ev_m.response_input(&zm, c.assembler))) / (2.0 * db)
                } else {
                    (vp - values[r]) / db
                };
                larger_step[r][k] = d - exact_along_sdm[r][k];
            }
        }
        let order = if central { 2 } else { 1 };
        let parts = (0..nr)
            .map(|r| {
                (0..np)
                    .map(|k| {
                        let mut e = ErrorParts {
                            total: sdm.dresp[r][k] - exact.dresp[r][k],
                            response: Split::new(
                                sdm.dresp[r][k] - exact_along_sdm[r][k],
                                larger_step[r][k],
                                order,
                            ),
                            propagated: on_sdm.dresp[r][k] - exact.dresp[r][k],
                            ..ErrorParts::default()
                        };
                        for (ti, &(i, _)) in terms.iter().enumerate() {
                            let (a, b) = (along[r][col(ti, 0, k)], along[r][col(ti, 1, k)]);
                            e.terms[i] = Split::new(a, b, order);
                        }
                        e
                    })
                    .collect()
            })
            .collect();
        Ok(IncrementAnatomy {
            increment: c.index,
            time: c.time,
            parts,
            reference: exact.dresp,
        })
    }
}

/// The largest SDM error of one parameter over a run, explained.
#[derive(Clone, Debug)]
pub struct Explanation {
    /// The parameter's name.
    pub parameter: String,
    /// The response whose derivative SDM gets most wrong, relative to its scale.
    pub response: String,
    /// Its increment number and time.
    pub increment: usize,
    /// Pseudo-time.
    pub time: f64,
    /// What the error is measured against: DDM's derivative there, or `floor` times its
    /// largest magnitude over the run where that is larger.
    pub scale: f64,
    /// SDM's error there over `scale`.
    pub relative_error: f64,
    /// The derivative's largest magnitude over the run (DDM's).
    pub largest: f64,
    /// DDM's derivative there.
    pub reference: f64,
    /// The split.
    pub parts: ErrorParts,
}

impl Explanation {
    /// The largest part, its value and its split (none for the carried-in error).
    pub fn dominant(&self) -> (Part, f64, Option<Split>) {
        self.parts.named()[0]
    }

    /// A split's truncation over `scale` and over `beta^order` (`order` 1 forward, 2
    /// central): its error is about this times `beta^order`. For forward SDM it is half the
    /// part's relative curvature `b d2/db2 / (d/db)`; for central a sixth of `b^2 d3/db3 /
    /// (d/db)`.
    pub fn truncation_coefficient(&self, split: &Split, beta: f64, central: bool) -> f64 {
        let order = if central { 2 } else { 1 };
        split.truncation.abs() / (self.scale * beta.powi(order))
    }
}

/// For each parameter: the response and increment of SDM's largest error, measured as the
/// verification report measures it: against `max(|DDM|, floor * scale)` at each increment,
/// `scale` the derivative's largest magnitude over the run, increments flagged
/// non-differentiable left out, and responses insensitive to the parameter (`|b| scale <
/// 1e-9` of the response's largest value) too.
pub fn explain(s: &SensitivityResults, values: &[f64], floor: f64) -> Vec<Explanation> {
    let nr = s.responses.len();
    let mut out = Vec::new();
    for (k, parameter) in s.parameters.iter().enumerate() {
        let mut best: Option<Explanation> = None;
        for r in 0..nr {
            let scale = s
                .anatomy
                .iter()
                .map(|a| a.reference[r][k].abs())
                .fold(0.0, f64::max);
            let size = s
                .increments
                .iter()
                .map(|i| i.values[r].abs())
                .fold(0.0, f64::max);
            if scale == 0.0 || values[k].abs().max(1.0) * scale < 1e-9 * size {
                continue;
            }
            for (at, a) in s.anatomy.iter().enumerate() {
                let flagged = s.increments.get(at).is_some_and(|i| !i.kinks.is_empty());
                if flagged {
                    continue;
                }
                let d = a.reference[r][k];
                let rel = a.parts[r][k].total.abs() / d.abs().max(floor * scale);
                if best.as_ref().is_none_or(|b| rel > b.relative_error) {
                    best = Some(Explanation {
                        parameter: parameter.clone(),
                        response: s.responses[r].clone(),
                        increment: a.increment,
                        time: a.time,
                        scale: d.abs().max(floor * scale),
                        relative_error: rel,
                        largest: scale,
                        reference: d,
                        parts: a.parts[r][k].clone(),
                    });
                }
            }
        }
        out.extend(best);
    }
    out
}

/// `anatomy.csv`: one row per increment, response and parameter, with SDM's and DDM's
/// derivatives, the error and its parts (each term's error and truncation).
pub fn anatomy_csv(s: &SensitivityResults) -> String {
    let mut csv = String::from("increment,time,response,parameter,ddm,sdm_minus_ddm,sum_of_parts");
    for t in Term::ALL {
        csv.push_str(&format!(",{0},{0}_truncation", t.key()));
    }
    csv.push_str(",response_own_difference,response_own_difference_truncation,carried_in\n");
    for a in &s.anatomy {
        for (r, name) in s.responses.iter().enumerate() {
            for (k, param) in s.parameters.iter().enumerate() {
                let p = &a.parts[r][k];
                csv.push_str(&format!(
                    "{},{:.10e},{name},{param},{:.12e},{:.6e},{:.6e}",
                    a.increment,
                    a.time,
                    a.reference[r][k],
                    p.total,
                    p.sum()
                ));
                for t in p.terms.iter().chain([&p.response]) {
                    csv.push_str(&format!(",{:.6e},{:.6e}", t.value, t.truncation));
                }
                csv.push_str(&format!(",{:.6e}\n", p.propagated));
            }
        }
    }
    csv
}
