//! DDM: the pseudo-load of direct differentiation, the same kernels evaluated with dual
//! numbers at the converged state.

use super::*;
use crate::assembly::{Evaluation, Frozen};
use crate::model::{DesignParam, Lifted};
use crate::scalar::Scalar;
use crate::solver::{AnalysisError, Converged};
use num_dual::Dual64;

impl Engine<'_> {
    /// DDM's pseudo-loads for all parameters. Each parameter is seeded alone in a `Dual64` (a
    /// vector dual of N parameters costs N times as much per element, or more, and would
    /// evaluate the union of the parameters' elements): its pseudo-load is evaluated over only
    /// the elements it reaches.
    pub(super) fn pseudo_loads(
        &mut self,
        c: &Converged<'_>,
        frozen: &Frozen<'_>,
    ) -> Result<PseudoLoads, AnalysisError> {
        let np = self.params.len();
        let n = c.z.len();
        let nh = c.hist_prev.len();
        let mut ev = Evaluation::<Dual64>::new(c.assembler, c.model.mesh.n_elements());
        let mut out = PseudoLoads {
            rhs: vec![0.0; n * np],
            dzc: vec![vec![0.0; n]; np],
            designs: Vec::with_capacity(np),
            hists: Vec::with_capacity(np),
        };
        for k in 0..np {
            self.prescribed_derivative(c, k, &mut out.dzc[k]);
            let p = &self.params[k];
            let overrides: Vec<(DesignParam, Dual64)> = p
                .targets
                .iter()
                .map(|t| (*t, Dual64::seeded(p.value, 0)))
                .collect();
            let lifted: Lifted<Dual64> = c.model.lifted(&overrides);
            let hist = duals(c.hist_prev, &self.dhist[k * nh..(k + 1) * nh]);
            let z = duals(c.z, &out.dzc[k]);
            // the pseudo-load is the derivative part alone: the elements the parameter does
            // not reach contribute none and are left out
            let mask = frozen
                .gauss
                .and_then(|g| self.unreached(c, k, &Reach::seeded(&lifted), &out.dzc[k], g, false));
            let pseudo = Frozen {
                skip: mask.as_deref(),
                ..*frozen
            };
            self.evaluate(c, &lifted, &z, &hist, Some(&pseudo), None, &mut ev)?;
            if mask.is_some() {
                self.results.cost.partial_evaluations += 1;
            }
            for i in 0..n {
                out.rhs[k * n + i] = if c.constrained[i] {
                    0.0
                } else {
                    -ev.residual[i].eps
                };
            }
            out.designs.push(lifted);
            out.hists.push(hist);
        }
        Ok(out)
    }

    /// The pseudo-loads `base` (on the converged branches) moved to the branches `forced`:
    /// the elements whose Gauss points `forced` changes, and the contact, evaluated on both
    /// and the difference added, as for the tangent ([`Engine::forced_tangent_at`]). Without
    /// `Settings::restrict`, evaluated anew over all elements.
    pub(super) fn forced_pseudo_loads(
        &mut self,
        c: &Converged<'_>,
        base: &PseudoLoads,
        forced: &Frozen<'_>,
    ) -> Result<PseudoLoads, AnalysisError> {
        let n = c.z.len();
        let converged = converged_frozen(c);
        let unchanged = match unchanged_elements(&c.assembler.dofs, forced, &converged) {
            Some(u) if self.settings.restrict => u,
            _ => return self.pseudo_loads(c, forced),
        };
        let mut ev = Evaluation::<Dual64>::new(c.assembler, c.model.mesh.n_elements());
        let mut out = base.clone();
        for k in 0..self.params.len() {
            let z = duals(c.z, &base.dzc[k]);
            for (branches, sign) in [(forced, 1.0), (&converged, -1.0)] {
                let frozen = Frozen {
                    skip: Some(&unchanged),
                    ..*branches
                };
                let (lifted, hist) = (&base.designs[k], &base.hists[k]);
                self.evaluate(c, lifted, &z, hist, Some(&frozen), None, &mut ev)?;
                for i in (0..n).filter(|&i| !c.constrained[i]) {
                    out.rhs[k * n + i] -= sign * ev.residual[i].eps;
                }
            }
            self.results.cost.partial_evaluations += 2;
        }
        Ok(out)
    }

    /// DDM's solve and update: the pseudo-loads `p` go through one multi-column solve, then
    /// one update per parameter carries `dz/db` into the history and the responses.
    pub(super) fn ddm(
        &mut self,
        c: &Converged<'_>,
        frozen: &Frozen<'_>,
        p: &PseudoLoads,
    ) -> Result<Step, AnalysisError> {
        let np = self.params.len();
        let nh = c.hist_prev.len();
        let nr = c.model.responses.len();
        let mut rhs = p.rhs.clone();
        self.solve(c, &mut rhs, np)?;
        // total derivatives: evaluate with z carrying dz/db. The update wants only the history
        // and the responses: elements frozen elastic keep their history and are skipped.
        let skip = frozen
            .gauss
            .map(|g| history_unchanged(c.model, &c.assembler.dofs, g));
        let update = Frozen {
            skip: skip.as_deref(),
            ..*frozen
        };
        let mut ev = Evaluation::<Dual64>::new(c.assembler, c.model.mesh.n_elements());
        let mut dresp = vec![vec![0.0; np]; nr];
        let mut dhist = vec![0.0; nh * np];
        let mut dz_all = Vec::with_capacity(np);
        for (k, (lifted, hist)) in p.designs.iter().zip(&p.hists).enumerate() {
            let dz = total_dz(c, &rhs, &p.dzc[k], k);
            let z = duals(c.z, &dz);
            self.evaluate(c, lifted, &z, hist, Some(&update), None, &mut ev)?;
            for (r, resp) in c.model.responses.iter().enumerate() {
                dresp[r][k] = resp.value(&ev.response_input(&z, c.assembler)).eps;
            }
            for (d, h) in dhist[k * nh..(k + 1) * nh].iter_mut().zip(&ev.hist_new) {
                *d = h.eps;
            }
            dz_all.push(dz);
        }
        Ok(Step {
            dresp,
            dhist,
            dz: dz_all,
            roundoff: Vec::new(),
            noise: Vec::new(),
            unbalance_noise: Vec::new(),
        })
    }
}

/// Dual numbers with real parts `re` and derivative parts `eps`.
pub(super) fn duals(re: &[f64], eps: &[f64]) -> Vec<Dual64> {
    re.iter()
        .zip(eps)
        .map(|(r, e)| Dual64::new(*r, *e))
        .collect()
}
