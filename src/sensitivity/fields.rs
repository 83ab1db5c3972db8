//! Derivatives of the state's fields ([`crate::fields`]) by every method (`Settings::fields`):
//! what `fricsens sensitivity --vtk` writes for ParaView.
//!
//! Each method differentiates the fields as it differentiates the responses:
//! * **DDM**: the fields of the converged state evaluated with dual numbers, the unknowns
//!   carrying `dz_n/db`, the incoming history `dh_{n-1}/db` and the design seeded: exact;
//! * **SDM** (forward, central): the fields at the perturbed design, the unknowns moved by
//!   `db dz_n/db` and the history by `db dh_{n-1}/db` (branches frozen as `freeze_branches`
//!   says), less those at the nominal design, over `db` (`2 db`): the same finite difference
//!   as SDM's update of the responses;
//! * **FDM** (forward, central): the differences of the reruns' converged fields at the
//!   nominal increment times, over `db` (`2 db`).
//!
//! The displacement field's derivative is the method's `dz_n/db` itself in every case.

use super::*;
use crate::assembly::{Assembler, Evaluation, Frozen};
use crate::fields::{state_fields, Field};
use crate::model::{Lifted, Model};
use crate::scalar::Scalar;
use crate::solver::{AnalysisError, Converged, Results};
use num_dual::Dual64;

/// The derivatives of the state's fields at one increment.
#[derive(Clone, Debug, Default)]
pub struct IncrementFields {
    /// Increment number of the nominal run, as [`IncrementSensitivity::increment`].
    pub increment: usize,
    /// Pseudo-time at the end of the increment.
    pub time: f64,
    /// `derivatives[p]`: every field's derivative with respect to parameter `p`, in the
    /// order and layout of [`state_fields`].
    pub derivatives: Vec<Vec<Field<f64>>>,
}

/// `(plus - minus) / step`, field by field.
pub(super) fn difference(plus: &[Field<f64>], minus: &[Field<f64>], step: f64) -> Vec<Field<f64>> {
    plus.iter()
        .zip(minus)
        .map(|(p, m)| Field {
            values: (p.values.iter().zip(&m.values))
                .map(|(a, b)| (a - b) / step)
                .collect(),
            ..p.clone()
        })
        .collect()
}

/// The dual parts of dual fields.
fn dual_parts(fields: Vec<Field<Dual64>>) -> Vec<Field<f64>> {
    fields
        .into_iter()
        .map(|f| Field {
            name: f.name,
            location: f.location,
            components: f.components,
            values: f.values.iter().map(|v| v.eps).collect(),
        })
        .collect()
}

/// The fields of a converged state `z` (history `hist_prev` before the increment) at design
/// `lifted` and `time`, on the branches `frozen`.
#[allow(clippy::too_many_arguments)]
pub(super) fn fields_at<S: Scalar>(
    model: &Model,
    asm: &Assembler,
    lifted: &Lifted<S>,
    z: &[S],
    hist_prev: &[S],
    time: f64,
    frozen: Option<&Frozen<'_>>,
) -> Result<Vec<Field<S>>, AnalysisError> {
    let mut ev = Evaluation::<S>::new(asm, model.mesh.n_elements());
    asm.evaluate(model, lifted, z, hist_prev, time, frozen, None, &mut ev)?;
    Ok(state_fields(model, asm, &ev, z))
}

/// The fields of stored increment `k` of a run of `model` (its converged state on its own
/// branches).
pub(super) fn results_fields(
    model: &Model,
    asm: &Assembler,
    res: &Results,
    k: usize,
) -> Result<Vec<Field<f64>>, AnalysisError> {
    let frozen = Frozen {
        gauss: res.branches.get(k).map(|b| b.as_slice()),
        contact: res.contact.get(k).map_or(&[], |c| c.choice.as_slice()),
        skip: None,
        ..Frozen::default()
    };
    let lifted = model.lifted::<f64>(&[]);
    fields_at(
        model,
        asm,
        &lifted,
        &res.states[k],
        &res.histories[k.saturating_sub(1)],
        res.times[k],
        Some(&frozen),
    )
}

impl Engine<'_> {
    /// The derivatives of the fields at the converged increment `c`, given the method's
    /// `dz_n/db` per parameter, `dh_{n-1}/db` (`self.dhist`, before it is moved on) and the
    /// steps `db` per parameter (SDM).
    pub(super) fn field_derivatives(
        &mut self,
        c: &Converged<'_>,
        dz: &[Vec<f64>],
        steps: &[f64],
    ) -> Result<IncrementFields, AnalysisError> {
        if self.field_assembler.is_none() {
            self.field_assembler = Some(Assembler::new(c.model, &[])?.reading_every_stress());
        }
        let asm = self.field_assembler.as_ref().expect("made above");
        let nh = c.hist_prev.len();
        let converged = converged_frozen(c);
        let frozen = (self.settings.method == Method::Ddm || self.settings.freeze_branches)
            .then_some(&converged);
        let mut derivatives = Vec::with_capacity(self.params.len());
        let nominal = match self.settings.method {
            Method::Sdm => Some(state_fields(c.model, c.assembler, c.eval, c.z)),
            _ => None,
        };
        for k in 0..self.params.len() {
            let dh = &self.dhist[k * nh..(k + 1) * nh];
            let fields = match self.settings.method {
                Method::Ddm => {
                    let p = &self.params[k];
                    let overrides: Vec<_> = (p.targets.iter())
                        .map(|t| (*t, Dual64::seeded(p.value, 0)))
                        .collect();
                    let lifted: Lifted<Dual64> = c.model.lifted(&overrides);
                    let z = ddm::duals(c.z, &dz[k]);
                    let hist = ddm::duals(c.hist_prev, dh);
                    dual_parts(fields_at(c.model, asm, &lifted, &z, &hist, c.time, frozen)?)
                }
                _ => {
                    let db = steps[k];
                    let at = |sign: f64| {
                        let lifted = self.lifted_at(c, k, sign * db);
                        let z: Vec<f64> = (c.z.iter().zip(&dz[k]))
                            .map(|(z, d)| z + sign * db * d)
                            .collect();
                        let hist: Vec<f64> = (c.hist_prev.iter().zip(dh))
                            .map(|(h, d)| h + sign * db * d)
                            .collect();
                        fields_at(c.model, asm, &lifted, &z, &hist, c.time, frozen)
                    };
                    match &nominal {
                        Some(base) => difference(&at(1.0)?, base, db),
                        None => difference(&at(1.0)?, &at(-1.0)?, 2.0 * db),
                    }
                }
            };
            derivatives.push(fields);
        }
        Ok(IncrementFields {
            increment: c.index,
            time: c.time,
            derivatives,
        })
    }
}
