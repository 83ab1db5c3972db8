//! Non-differentiable points: where a state sits on a transition (yield onset, contact
//! opening or closing, stick and slip) the derivative is one-sided, and these are flagged.

use super::*;
use crate::assembly::Assembler;
use crate::contact::{ContactChoice, ContactState};
use crate::material::Branch;
use crate::solver::Converged;

/// Significant digits a difference must keep above its noise for its finite-difference
/// derivative not to be flagged round-off dominated (`IncrementSensitivity::roundoff`):
/// three digits, i.e. a relative error of the difference below about 1e-3.
pub const ROUNDOFF_DIGITS: f64 = 3.0;

/// Whether a difference `delta` of quantities of size `size`, each known to `noise`
/// (relative), keeps fewer than [`ROUNDOFF_DIGITS`] digits.
pub(super) fn roundoff_dominated(delta: f64, size: f64, noise: f64) -> bool {
    delta.abs() < 10f64.powf(ROUNDOFF_DIGITS) * noise * size.abs()
}

/// The kind of transition a [`Kink`] sits on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum KinkKind {
    /// A hitting node between open and closed (`at`: its flat hitting-node index).
    Contact,
    /// A closed frictional node between stick and slip (`at`: its flat hitting-node index).
    Friction,
    /// A Gauss point at yield onset (`at`: the element, `point`: the Gauss point).
    Yield,
}

impl KinkKind {
    /// `contact`, `friction` or `yield`, as in the reports.
    pub fn name(self) -> &'static str {
        match self {
            KinkKind::Contact => "contact",
            KinkKind::Friction => "friction",
            KinkKind::Yield => "yield",
        }
    }
}

impl std::fmt::Display for KinkKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A point where the converged state sits on a transition.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Kink {
    /// What kind of transition.
    pub kind: KinkKind,
    /// Element (or node) number.
    pub at: usize,
    /// Gauss point (or 0).
    pub point: usize,
    /// Distance to the transition (trial yield ratio).
    pub distance: f64,
}

/// Derivatives `[r][p]` with every flagged point forced onto each side of its transition.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct OneSided {
    /// Elastic / stick / open side; `None` where its solve failed (`failed` says why).
    pub lower: Option<Vec<Vec<f64>>>,
    /// Plastic / slip / closed side; `None` where its solve failed.
    pub upper: Option<Vec<Vec<f64>>>,
    /// Why a side has no derivatives, one line a side that failed: a side fails alone where
    /// its forced tangent is singular (no pivot, or not positive definite): nothing resists
    /// the motion the side frees, as a frictional node forced to slip with no elastic support
    /// along the surface, and that side's derivative is unbounded.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub failed: Vec<String>,
}

/// Derivatives `[r][p]`: response `r`, parameter `p`.
pub type DerivativeTable = [Vec<f64>];

impl OneSided {
    /// Both sides (lower, upper), where neither failed.
    pub fn both(&self) -> Option<(&DerivativeTable, &DerivativeTable)> {
        Some((self.lower.as_deref()?, self.upper.as_deref()?))
    }
}

/// The line of [`OneSided::failed`] for side `upper` at increment `increment`, whose solve
/// failed with `e`, where that failure is the side's own: its forced tangent singular (no
/// pivot, or not positive definite), which nothing else in the run shares. Any other error
/// (an evaluation, a pattern, a model) is returned as it is, for the run to stop on: the
/// converged branches' solve at that increment would meet it too, or it is a bug.
pub(crate) fn side_failure(
    upper: bool,
    increment: usize,
    e: AnalysisError,
) -> Result<String, AnalysisError> {
    use crate::linalg::LinalgError;
    if !matches!(
        e,
        AnalysisError::Linalg(
            LinalgError::Singular { .. } | LinalgError::NotPositiveDefinite { .. }
        )
    ) {
        return Err(e);
    }
    let side = if upper {
        "upper (plastic / slip / closed)"
    } else {
        "lower (elastic / stick / open)"
    };
    Ok(format!(
        "increment {increment}: the {side} side's derivatives failed ({e}); the derivatives on \
         the converged branches are kept"
    ))
}

/// Whether hitting node `k` (flat) is in a frictional pair.
fn friction_at(model: &Model, asm: &Assembler, k: usize) -> bool {
    let flat = &asm.contact.flat;
    (0..flat.len())
        .rev()
        .find(|p| flat[*p] <= k)
        .is_some_and(|p| model.contacts[p].friction.is_some())
}

/// Forces every flagged point of `kinks` onto one side of its transition in the converged
/// Gauss points' branches `gauss` and hitting nodes' choices `contact`: the lower side
/// (elastic, stick, open; `upper` false) or the upper (plastic, slip, closed). A node forced
/// closed from open enters stick where its pair has friction. The branches the one-sided
/// derivatives ([`OneSided`]) are taken on, by DDM and the adjoint alike.
pub(super) fn force_side(
    kinks: &[Kink],
    upper: bool,
    (model, asm): (&Model, &Assembler),
    gauss: &mut [Branch],
    contact: &mut [ContactChoice],
) {
    let side = usize::from(upper);
    for k in kinks {
        match k.kind {
            KinkKind::Yield => {
                gauss[asm.dofs.gauss(k.at).start + k.point] =
                    [Branch::Elastic, Branch::Plastic][side];
            }
            KinkKind::Friction => {
                contact[k.at].state = [ContactState::Stick, ContactState::Slip][side];
            }
            KinkKind::Contact => {
                // a node is flagged once: its state here is the converged one
                let closed = match contact[k.at].state {
                    ContactState::Open if friction_at(model, asm, k.at) => ContactState::Stick,
                    ContactState::Open => ContactState::Closed,
                    converged => converged,
                };
                contact[k.at].state = [ContactState::Open, closed][side];
            }
        }
    }
}

impl Engine<'_> {
    /// Points sitting on a transition: yield onset, contact opening/closing, stick/slip.
    pub(super) fn kinks(&self, c: &Converged<'_>) -> Vec<Kink> {
        let mut v = Vec::new();
        let tol = self.settings.kink_tol;
        // contact: normal distance relative to the largest normal force (closed) or to the
        // model's size (open); slip ratio for friction
        let fmax = c
            .eval
            .contact
            .normal_force
            .iter()
            .fold(0.0f64, |m, f| m.max(f.abs()));
        // the model's size (the reference mesh's bounding box), measured once and only if a
        // node is open
        let mut length = None;
        for (k, (nd, sr)) in c.eval.contact.distance.iter().enumerate() {
            let closed = c.eval.contact.choice[k].state != ContactState::Open;
            let rel = if closed {
                c.eval.contact.normal_force[k].abs() / fmax.max(f64::MIN_POSITIVE)
            } else {
                nd.abs() / *length.get_or_insert_with(|| c.model.characteristic_length())
            };
            if rel < tol {
                v.push(Kink {
                    kind: KinkKind::Contact,
                    at: k,
                    point: 0,
                    distance: rel,
                });
            } else if closed && sr.abs() < tol {
                v.push(Kink {
                    kind: KinkKind::Friction,
                    at: k,
                    point: 0,
                    distance: *sr,
                });
            }
        }
        for (i, r) in c.eval.yield_ratio.iter().enumerate() {
            if *r != -1.0 && r.abs() < self.settings.kink_tol {
                let (at, point) = c.assembler.dofs.gauss_owner(i);
                v.push(Kink {
                    kind: KinkKind::Yield,
                    at,
                    point,
                    distance: *r,
                });
            }
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::LinalgError;

    /// A forced side leaves the run only on its own tangent's singularity; an error any
    /// solve of the increment would meet, or a bug, still stops the run.
    #[test]
    fn only_a_singular_forced_tangent_fails_a_side_alone() {
        let singular = AnalysisError::Linalg(LinalgError::Singular { index: Some(3) });
        let line = side_failure(true, 7, singular).expect("a side's own failure");
        assert!(line.starts_with("increment 7: the upper"), "{line}");
        assert!(line.contains("singular matrix"), "{line}");
        let spd = AnalysisError::Linalg(LinalgError::NotPositiveDefinite { index: 0 });
        let line = side_failure(false, 2, spd).expect("a side's own failure");
        assert!(line.starts_with("increment 2: the lower"), "{line}");
        for shared in [
            AnalysisError::Linalg(LinalgError::PatternMismatch),
            AnalysisError::Linalg(LinalgError::NotFactored),
            AnalysisError::Linalg(LinalgError::Faer("out of memory".into())),
        ] {
            let text = shared.to_string();
            let back = side_failure(false, 1, shared).expect_err("not a side's own");
            assert_eq!(back.to_string(), text);
        }
    }
}
