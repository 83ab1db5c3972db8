//! SDM, the paper's semi-analytical method: the unbalance force of a finitely perturbed design
//! at the fixed converged state (forward or central), evaluated only where the perturbation
//! reaches.

use super::rigid;
use super::*;
use crate::assembly::{Evaluation, Frozen};
use crate::material::Branch;
use crate::model::Lifted;
use crate::scalar::Scalar;
use crate::solver::{AnalysisError, Converged};
use crate::terms::Terms;
use std::time::Instant;

impl Engine<'_> {
    /// The design perturbed by `db` along parameter `k`, lifted to f64.
    pub(super) fn lifted_at(&self, c: &Converged<'_>, k: usize, db: f64) -> Lifted<f64> {
        c.model
            .lifted(&self.overrides(k, self.params[k].value + db))
    }

    /// f64 evaluation at the design `lifted` (perturbed by `db` along parameter `k`), with the
    /// history perturbed consistently and the unknowns moved by `db * z_shift` (the prescribed
    /// derivative for the pseudo-load, the total derivative for the update).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn perturbed(
        &mut self,
        c: &Converged<'_>,
        k: usize,
        db: f64,
        lifted: &Lifted<f64>,
        z_shift: &[f64],
        frozen: Option<&Frozen<'_>>,
        ev: &mut Evaluation<f64>,
    ) -> Result<(), AnalysisError> {
        let nh = c.hist_prev.len();
        let hist: Vec<f64> = (0..nh)
            .map(|i| c.hist_prev[i] + db * self.dhist[k * nh + i])
            .collect();
        let z: Vec<f64> = c.z.iter().zip(z_shift).map(|(z, s)| z + db * s).collect();
        self.evaluate(c, lifted, &z, &hist, frozen, None, ev)
    }

    /// One residual evaluation of the engine's own, at the converged increment's time: timed
    /// and counted in the cost ledger.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn evaluate<S: Scalar>(
        &mut self,
        c: &Converged<'_>,
        lifted: &Lifted<S>,
        z: &[S],
        hist: &[S],
        frozen: Option<&Frozen<'_>>,
        tangent: Option<&mut crate::linalg::SparseMatrix>,
        ev: &mut Evaluation<S>,
    ) -> Result<(), AnalysisError> {
        let cost = &mut self.results.cost;
        timed(&mut cost.evaluation_seconds, || {
            c.assembler
                .evaluate(c.model, lifted, z, hist, c.time, frozen, tangent, ev)
        })?;
        cost.residual_evaluations += 1;
        Ok(())
    }

    /// The elements a perturbation of parameter `k` does not reach at the fixed state, or
    /// `None` when there are none, or when `nominal` (forward SDM, which then evaluates the
    /// nominal state over the same elements) and they are fewer than half (leaving them out
    /// would not pay for that second evaluation).
    ///
    /// An element is reached when a node moves (shape), when its body's material parameter
    /// changes (unless the law says the parameter acts only on the plastic branch and all its
    /// points are `gauss`-frozen elastic), when a prescribed unknown of it moves (`dzc`), or
    /// when its history carries a derivative. Contact and loads are always evaluated.
    pub(super) fn unreached(
        &self,
        c: &Converged<'_>,
        k: usize,
        reach: &Reach,
        dzc: &[f64],
        gauss: &[Branch],
        nominal: bool,
    ) -> Option<Vec<bool>> {
        if !self.settings.restrict {
            return None;
        }
        let model = c.model;
        let nh = c.hist_prev.len();
        let dofs = &c.assembler.dofs;
        let mask: Vec<bool> = (0..model.mesh.n_elements())
            .map(|e| {
                let b = dofs.element_body[e];
                let Some(body) = model.bodies.get(b) else {
                    return false;
                };
                let elastic = gauss[dofs.gauss(e)].iter().all(|g| *g == Branch::Elastic);
                let material_unchanged = (0..body.material.params().len()).all(|i| {
                    !reach.material_changed(b, e, i)
                        || (elastic && !body.material.enters_elastic_branch(i))
                });
                let hist = dofs.history(e);
                material_unchanged
                    && !model.mesh.element_nodes(e).iter().any(|&n| reach.moved[n])
                    && c.assembler.element_dofs(e).iter().all(|&i| dzc[i] == 0.0)
                    && self.dhist[k * nh + hist.start..k * nh + hist.end]
                        .iter()
                        .all(|v| *v == 0.0)
            })
            .collect();
        let unreached = mask.iter().filter(|m| **m).count();
        let pays = if nominal {
            2 * unreached > mask.len()
        } else {
            unreached > 0
        };
        pays.then_some(mask)
    }

    /// Time the floor of one parameter at this increment: one f64 residual evaluation over all
    /// elements at the converged state, with its branches frozen, and one single-column solve
    /// with Newton's last factorization (none where Newton did not factor).
    pub(super) fn probe_floor(&mut self, c: &Converged<'_>) -> Result<(), AnalysisError> {
        let t = Instant::now();
        let frozen = converged_frozen(c);
        let mut ev = Evaluation::<f64>::new(c.assembler, c.model.mesh.n_elements());
        c.assembler.evaluate(
            c.model,
            c.lifted,
            c.z,
            c.hist_prev,
            c.time,
            Some(&frozen),
            None,
            &mut ev,
        )?;
        if let Some(f) = c.last_factor {
            f.solve_in_place(&mut ev.residual)?;
        }
        self.results.cost.floor_seconds += t.elapsed().as_secs_f64();
        Ok(())
    }

    /// The tangent at the converged state on the branches `forced`: the converged tangent with
    /// the elements whose Gauss points `forced` puts on other branches evaluated again, their
    /// converged blocks taken out and their forced ones put in. Contact and the loads enter
    /// both of these evaluations, so forced contact states are taken in the same way. A
    /// flagged increment has a few such elements (5 and 13 of 138 on the two sides of the
    /// leaf spring's last one): two evaluations over them cost a fraction of an assembly.
    /// Without `Settings::restrict` (or with free branches), one assembly over all elements.
    pub(super) fn forced_tangent_at(
        &mut self,
        c: &Converged<'_>,
        forced: &Frozen<'_>,
    ) -> Result<crate::linalg::SparseMatrix, AnalysisError> {
        let ne = c.model.mesh.n_elements();
        let converged = converged_frozen(c);
        let mut k = c.tangent.clone();
        let mut ev = Evaluation::<f64>::new(c.assembler, ne);
        let unchanged = match unchanged_elements(&c.assembler.dofs, forced, &converged) {
            Some(u) if self.settings.restrict => u,
            // over all elements
            _ => {
                let (lifted, z, hist) = (c.lifted, c.z, c.hist_prev);
                self.evaluate(c, lifted, z, hist, Some(forced), Some(&mut k), &mut ev)?;
                return Ok(k);
            }
        };
        let mut part = crate::linalg::SparseMatrix::new(c.assembler.pattern.clone());
        for (branches, sign) in [(forced, 1.0), (&converged, -1.0)] {
            let frozen = Frozen {
                skip: Some(&unchanged),
                ..*branches
            };
            self.evaluate(
                c,
                c.lifted,
                c.z,
                c.hist_prev,
                Some(&frozen),
                Some(&mut part),
                &mut ev,
            )?;
            for (kv, pv) in k.values_mut().iter_mut().zip(part.values()) {
                *kv += sign * pv;
            }
        }
        Ok(k)
    }

    /// The relative noise of parameter `k`'s unbalance (machine precision times the forces
    /// that cancel in it over the unbalance), and the round-off flag where the perturbed
    /// parameter itself lost its digits (`b + db` keeps fewer than `ROUNDOFF_DIGITS` digits of
    /// `db`).
    ///
    /// The forces that cancel: the reference force of Newton's criterion (the internal and
    /// external forces), and at every node in contact with friction the tangential penalty
    /// times the positions its elastic slip is the difference of. A stiff stick penalty makes
    /// the second far the larger: the perturbed design's anchor, `a + db da`, is rounded to
    /// the ulp of the position `a`, and the stick force `k_t (x - a)` with it, so the
    /// unbalance is quantized in steps of `k_t ulp(a)` (on the Klarbring oscillator 5.55e-11,
    /// against 2e-16 of its reference force).
    #[allow(clippy::too_many_arguments)]
    fn unbalance_noise(
        &self,
        c: &Converged<'_>,
        k: usize,
        db: f64,
        central: bool,
        rhs: &[f64],
        noise: &mut [f64],
        roundoff: &mut [Vec<bool>],
    ) {
        let n = c.z.len();
        let db_eff = if central { 2.0 * db } else { db };
        let unbalance = (0..n)
            .map(|i| (rhs[k * n + i] * db_eff).powi(2))
            .sum::<f64>()
            .sqrt();
        if unbalance != 0.0 {
            let friction = (c.eval.contact.cancelling.iter())
                .map(|f| f * f)
                .sum::<f64>()
                .sqrt();
            noise[k] = f64::EPSILON * (c.record.reference_force + friction) / unbalance;
        }
        if roundoff_dominated(db, self.params[k].value, f64::EPSILON) {
            for row in roundoff.iter_mut() {
                row[k] = true;
            }
        }
    }

    /// SDM (forward or central) for all parameters, parameter `k` perturbed by `betas[k]`
    /// (relative, [`crate::design::Parameter::step`]).
    pub(super) fn sdm(
        &mut self,
        c: &Converged<'_>,
        central: bool,
        betas: &[f64],
    ) -> Result<Step, AnalysisError> {
        let np = self.params.len();
        let n = c.z.len();
        let nh = c.hist_prev.len();
        let ne = c.model.mesh.n_elements();
        let converged = converged_frozen(c);
        let frozen = if self.settings.freeze_branches {
            Some(&converged)
        } else {
            None
        };
        let mut ev_p = Evaluation::<f64>::new(c.assembler, ne);
        let mut ev_m = Evaluation::<f64>::new(c.assembler, ne);
        // the nominal state evaluated over the elements a parameter reaches (forward SDM,
        // where the others are left out)
        let mut ev_0 = Evaluation::<f64>::new(c.assembler, ne);
        // every response at the converged state
        let values = response_values(c);
        let mut rhs = vec![0.0; n * np];
        let mut dzc = vec![vec![0.0; n]; np];
        // round-off: the unbalance against the forces that cancel in it (`unbalance_noise`),
        // each response difference against the response
        let nr = c.model.responses.len();
        let mut roundoff = vec![vec![false; np]; nr];
        // relative noise of each unbalance (eps times the forces that cancel in it), and each
        // response's explicit derivative
        // (design perturbed, state fixed): the noise reaches a response only through dz
        let mut unbalance_noise = vec![0.0; np];
        let mut explicit = vec![vec![0.0; np]; nr];
        // the perturbed designs (+db, and -db for central), built once for both evaluations
        let mut designs: Vec<(Lifted<f64>, Option<Lifted<f64>>)> = Vec::with_capacity(np);
        for k in 0..np {
            self.prescribed_derivative(c, k, &mut dzc[k]);
            let db = self.params[k].step(betas[k]);
            designs.push((
                self.lifted_at(c, k, db),
                central.then(|| self.lifted_at(c, k, -db)),
            ));
        }
        // refined SDM: the solid elements' part of every moving parameter's difference with
        // the rigid rotations differentiated exactly (`rigid` module docs)
        let mut solid: Vec<Option<Vec<f64>>> = vec![None; np];
        if self.settings.rigid_modes {
            let moving: Vec<rigid::Moving<'_>> = (0..np)
                .filter_map(|k| {
                    let db = self.params[k].step(betas[k]);
                    let (plus, minus) = (&designs[k].0, designs[k].1.as_ref());
                    let velocity = match minus {
                        Some(m) => rigid::velocity(plus, m, 2.0 * db),
                        None => rigid::velocity(plus, c.lifted, db),
                    }?;
                    Some(rigid::Moving {
                        k,
                        db,
                        plus,
                        minus,
                        velocity,
                        dzc: &dzc[k],
                    })
                })
                .collect();
            let base = frozen.copied().unwrap_or_default();
            let parts = self.solid_differences(c, &base, &moving)?;
            for (m, part) in moving.iter().zip(parts) {
                solid[m.k] = Some(part);
            }
        }
        let rest = Frozen {
            terms: Terms {
                solids: false,
                ..Terms::ALL
            },
            ..frozen.copied().unwrap_or_default()
        };
        for k in 0..np {
            let db = self.params[k].step(betas[k]);
            let (lifted_p, lifted_m) = &designs[k];
            if let Some(part) = &solid[k] {
                // the springs, contact and loads differenced as plain SDM does
                self.perturbed(c, k, db, lifted_p, &dzc[k], Some(&rest), &mut ev_p)?;
                let base = match lifted_m {
                    Some(lifted_m) => {
                        self.perturbed(c, k, -db, lifted_m, &dzc[k], Some(&rest), &mut ev_m)?;
                        &ev_m
                    }
                    None => {
                        let (lifted, z, hist) = (c.lifted, c.z, c.hist_prev);
                        self.evaluate(c, lifted, z, hist, Some(&rest), None, &mut ev_0)?;
                        &ev_0
                    }
                };
                let span = if central { 2.0 * db } else { db };
                for i in (0..n).filter(|&i| !c.constrained[i]) {
                    rhs[k * n + i] = -((ev_p.residual[i] - base.residual[i]) / span + part[i]);
                }
                // (the explicit part of the responses is left at zero: the noise bound below
                // then takes the whole derivative as carried by dz, the larger bound)
                self.unbalance_noise(c, k, db, central, &rhs, &mut unbalance_noise, &mut roundoff);
                continue;
            }
            // Leave out the elements the perturbation does not reach: their residual is the
            // same in both evaluations of the difference, so it cancels exactly (and its
            // round-off with it). Friction and contact-stiffness parameters then evaluate the
            // contact and the elements with a history derivative; yield and hardening the
            // elements with plastic points.
            let mask = frozen.and_then(|f| f.gauss).and_then(|g| {
                let reach = Reach::between(lifted_p, c.lifted);
                self.unreached(c, k, &reach, &dzc[k], g, !central)
            });
            let restricted = frozen.zip(mask.as_deref()).map(|(f, m)| Frozen {
                skip: Some(m),
                ..*f
            });
            let pseudo = restricted.as_ref().or(frozen);
            self.perturbed(c, k, db, lifted_p, &dzc[k], pseudo, &mut ev_p)?;
            if let Some(lifted_m) = lifted_m {
                self.perturbed(c, k, -db, lifted_m, &dzc[k], pseudo, &mut ev_m)?;
            }
            // the residual at b: the converged one, or the nominal state over the same elements
            let nominal = match &restricted {
                Some(r) if !central => {
                    self.evaluate(c, c.lifted, c.z, c.hist_prev, Some(r), None, &mut ev_0)?;
                    &ev_0
                }
                _ => c.eval,
            };
            if restricted.is_some() {
                self.results.cost.partial_evaluations += 2;
            }
            for (r, resp) in c.model.responses.iter().enumerate() {
                let vp = resp.value(&ev_p.response_input(c.z, c.assembler));
                explicit[r][k] = if central {
                    (vp - resp.value(&ev_m.response_input(c.z, c.assembler))) / (2.0 * db)
                } else {
                    (vp - resp.value(&nominal.response_input(c.z, c.assembler))) / db
                };
            }
            for i in 0..n {
                if c.constrained[i] {
                    continue;
                }
                // forward: R(b) = c.eval.residual (the converged residual, no extra evaluation)
                let d = if central {
                    (ev_p.residual[i] - ev_m.residual[i]) / (2.0 * db)
                } else {
                    (ev_p.residual[i] - nominal.residual[i]) / db
                };
                rhs[k * n + i] = -d;
            }
            self.unbalance_noise(c, k, db, central, &rhs, &mut unbalance_noise, &mut roundoff);
        }
        self.solve(c, &mut rhs, np)?;
        let mut dresp = vec![vec![0.0; np]; nr];
        let mut dhist = vec![0.0; nh * np];
        let mut dz_all = Vec::with_capacity(np);
        // the updates below want only the history and the responses: elements frozen elastic
        // keep their history and are skipped (free branches: nothing is skipped)
        let skip = frozen
            .and_then(|f| f.gauss)
            .map(|g| history_unchanged(c.model, &c.assembler.dofs, g));
        let update = frozen.map(|f| Frozen {
            skip: skip.as_deref(),
            ..*f
        });
        let frozen = update.as_ref();
        for k in 0..np {
            let dz = total_dz(c, &rhs, &dzc[k], k);
            let db = self.params[k].step(betas[k]);
            let (lifted_p, lifted_m) = &designs[k];
            self.perturbed(c, k, db, lifted_p, &dz, frozen, &mut ev_p)?;
            let zp: Vec<f64> = (0..n).map(|i| c.z[i] + db * dz[i]).collect();
            if let Some(lifted_m) = lifted_m {
                self.perturbed(c, k, -db, lifted_m, &dz, frozen, &mut ev_m)?;
                let zm: Vec<f64> = (0..n).map(|i| c.z[i] - db * dz[i]).collect();
                for (r, resp) in c.model.responses.iter().enumerate() {
                    let vp = resp.value(&ev_p.response_input(&zp, c.assembler));
                    let vm = resp.value(&ev_m.response_input(&zm, c.assembler));
                    dresp[r][k] = (vp - vm) / (2.0 * db);
                    roundoff[r][k] |= vp != vm && roundoff_dominated(vp - vm, vp, f64::EPSILON);
                }
                for i in 0..nh {
                    dhist[k * nh + i] = (ev_p.hist_new[i] - ev_m.hist_new[i]) / (2.0 * db);
                }
            } else {
                for (r, resp) in c.model.responses.iter().enumerate() {
                    let vp = resp.value(&ev_p.response_input(&zp, c.assembler));
                    let v0 = values[r];
                    dresp[r][k] = (vp - v0) / db;
                    roundoff[r][k] |= vp != v0 && roundoff_dominated(vp - v0, v0, f64::EPSILON);
                }
                for i in 0..nh {
                    dhist[k * nh + i] = (ev_p.hist_new[i] - c.eval.hist_new[i]) / db;
                }
            }
            dz_all.push(dz);
        }
        // the unbalance's noise carried through dz into each response: flag where it exceeds
        // 10^-ROUNDOFF_DIGITS of the derivative
        let mut noise = vec![vec![0.0; np]; nr];
        for r in 0..nr {
            // the size of what cancels in the response's own difference: a force read from
            // the residual or the contact sums forces of the size of the reference force
            let reads = c.model.responses[r].kind.reads();
            let value = values[r];
            let cancelling = if !reads.residual_nodes.is_empty() || reads.contact {
                value.abs().max(c.record.reference_force)
            } else {
                value.abs()
            };
            for k in 0..np {
                let implicit = dresp[r][k] - explicit[r][k];
                roundoff[r][k] |= dresp[r][k] != 0.0
                    && implicit.abs() * unbalance_noise[k]
                        > 10f64.powf(-ROUNDOFF_DIGITS) * dresp[r][k].abs();
                // (a negative parameter has a negative step)
                let db = self.params[k].step(betas[k]).abs();
                noise[r][k] = implicit.abs() * unbalance_noise[k] + f64::EPSILON * cancelling / db;
            }
        }
        Ok(Step {
            dresp,
            dhist,
            dz: dz_all,
            roundoff,
            noise,
            unbalance_noise,
        })
    }
}
