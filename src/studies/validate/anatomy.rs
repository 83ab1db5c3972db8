//! The report's error anatomy ("Why SDM errs"): per scene, parameter and SDM variant at the
//! figure beta, the largest error as the report measures it and what it is made of
//! ([`crate::sensitivity::anatomy`]).

use crate::design::Parameter;
use crate::sensitivity::anatomy::explain;
use crate::sensitivity::{Method, SensitivityResults};
use std::fmt::Write;

/// One row of the anatomy table.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct AnatomyRow {
    /// Scene name.
    pub scene: String,
    /// `sdm` or `sdm-central`.
    pub method: String,
    /// The perturbation size.
    pub beta: f64,
    /// Design parameter.
    pub param: String,
    /// The response of the largest error.
    pub response: String,
    /// Its increment.
    pub increment: usize,
    /// The error there, relative as in the report (against DDM, floored).
    pub error: f64,
    /// DDM's derivative there over its largest magnitude over the run.
    pub derivative_share: f64,
    /// The parts, largest first: name and value over the error's denominator.
    pub parts: Vec<(String, f64)>,
    /// The largest part's truncation and round-off over the denominator, its local order
    /// and truncation coefficient (`None` for the carried-in error, which has no split).
    pub dominant: Option<DominantSplit>,
    /// `|sum of the parts - error| / |error|`.
    pub mismatch: f64,
    /// The anatomy's wall time (s).
    pub seconds: f64,
}

/// The dominant part's split by the beta scaling.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct DominantSplit {
    /// Truncation over the denominator.
    pub truncation: f64,
    /// Round-off over the denominator.
    pub roundoff: f64,
    /// Local order between beta and 10 beta.
    pub order: Option<f64>,
    /// Truncation over the denominator and over `beta^order`.
    pub coefficient: f64,
}

/// The anatomy rows of one scene from its explained SDM runs.
pub fn anatomy_rows(
    scene: &str,
    runs: &[&SensitivityResults],
    params: &[Parameter],
    floor: f64,
) -> Vec<AnatomyRow> {
    let values: Vec<f64> = params.iter().map(|p| p.value).collect();
    let mut rows = Vec::new();
    for s in runs {
        let central = s.method == Some(Method::SdmCentral);
        for x in explain(s, &values, floor) {
            let named = x.parts.named();
            let sum: f64 = named.iter().map(|p| p.1.abs()).sum();
            let (_, _, split) = x.dominant();
            rows.push(AnatomyRow {
                scene: scene.to_string(),
                method: s.method.map_or("?", Method::name).to_string(),
                beta: s.beta,
                param: x.parameter.clone(),
                response: x.response.clone(),
                increment: x.increment,
                error: x.relative_error,
                derivative_share: x.reference.abs() / x.largest,
                parts: named
                    .iter()
                    .filter(|p| p.1 != 0.0 && p.1.abs() >= 1e-2 * sum)
                    .map(|p| (p.0.name().to_string(), p.1 / x.scale))
                    .collect(),
                dominant: split.map(|sp| DominantSplit {
                    truncation: sp.truncation / x.scale,
                    roundoff: sp.roundoff() / x.scale,
                    order: sp.order(),
                    coefficient: x.truncation_coefficient(&sp, s.beta, central),
                }),
                mismatch: if x.parts.total == 0.0 {
                    0.0
                } else {
                    (x.parts.sum() - x.parts.total).abs() / x.parts.total.abs()
                },
                seconds: s.cost.anatomy_seconds,
            });
        }
    }
    rows
}

/// The section "Why SDM errs".
pub(super) fn write_anatomy(s: &mut String, rows: &[&AnatomyRow], beta: f64) {
    let _ = writeln!(s, "\n## Why SDM errs\n");
    let _ = writeln!(
        s,
        "SDM replaces the pseudo-load `-dR/db` by a difference of the residual at the fixed converged state. `fricsens sensitivity --method sdm --explain` (here at beta = {beta:.0e}) splits its error against DDM at every increment into (exactly but for the round-off of the differences, `eps |R| / h`: where round-off dominates, the last column shows the split's own round-off): each term of the residual (the solid elements whose Gauss points are all elastic, those with a plastic point, whose force goes through the return map, the springs, the normal contact, the friction, the loads), each its finite-difference unbalance less its exact (dual) pseudo-load at the same state, solved with the same tangent and read by the response's exact derivative along the state; the response's own difference (SDM differences the response at the perturbed design and state); and the error the history derivative carries in from earlier increments (DDM's derivative with SDM's incoming history derivative less DDM's own). Each split part is measured again at 10 times the step: truncation grows as the step to the method's order (1 forward, 2 central) and round-off falls as its inverse, so the part at the larger step, scaled back, is its truncation and the rest its round-off; the local order between the two steps says which dominates (near the method's order: truncation; near -1: round-off). Per scene, parameter and method, the row is the response and increment of the largest error, measured as in the sweep (relative to DDM with the floor); parts are over the same denominator, those above 1 % of the parts' magnitudes listed. The last column checks that the parts add up to the error (`|sum - error| / |error|`; the tests assert 1e-10 wherever the error is above 1e-2 of the derivative's scale, round-off elsewhere).\n"
    );
    let _ = writeln!(
        s,
        "| scene | parameter | method | response (increment) | error | parts, largest first | dominant part: truncation / round-off, local order | its truncation coefficient | parts vs error |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let parts: Vec<String> = r
            .parts
            .iter()
            .map(|(n, v)| format!("{n} {v:+.1e}"))
            .collect();
        let (split, coefficient) = match &r.dominant {
            Some(d) if d.truncation.abs() > d.roundoff.abs() => (
                format!(
                    "{:+.1e} / {:+.1e}, {}",
                    d.truncation,
                    d.roundoff,
                    d.order.map_or("-".to_string(), |o| format!("{o:.2}"))
                ),
                format!("{:.1e}", d.coefficient),
            ),
            Some(d) => (
                format!(
                    "{:+.1e} / {:+.1e}, {}",
                    d.truncation,
                    d.roundoff,
                    d.order.map_or("-".to_string(), |o| format!("{o:.2}"))
                ),
                "round-off".to_string(),
            ),
            None => ("carried in: no split".to_string(), "-".to_string()),
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} ({}) | {:.1e} | {} | {split} | {coefficient} | {:.0e} |",
            r.scene,
            r.param,
            r.method,
            r.response,
            r.increment,
            r.error,
            parts.join(", "),
            r.mismatch
        );
    }
    let _ = writeln!(
        s,
        "\nThe truncation coefficient `C` (shown where truncation dominates the part) makes the part's error `C beta` (forward) or `C beta^2` (central) relative to the derivative: for forward SDM `2 C` is the part's relative curvature `b (d2/db2) / (d/db)`, and the step at which its truncation reaches the derivative itself is `beta = 1 / C`."
    );
    // what the largest truncation-dominated errors come from
    for r in rows {
        let Some(d) = &r.dominant else { continue };
        let truncation = d.order.is_some_and(|o| o > 0.5) && d.truncation.abs() > d.roundoff.abs();
        if r.error < 1e-3 || !truncation {
            continue;
        }
        let (name, _) = &r.parts[0];
        let _ = writeln!(
            s,
            "\n**{} {}, {}.** The error of {:.1e} in d({})/d({}) at increment {} (where the derivative is {:.1e} of its largest magnitude over the run) is truncation of the {name} (local order {:.2}): {}",
            r.scene,
            r.param,
            r.method,
            r.error,
            r.response,
            r.param,
            r.increment,
            r.derivative_share,
            d.order.unwrap_or(f64::NAN),
            if r.method == "sdm" {
                format!(
                    "its relative curvature in b is {:.1e}, so the error falls only as beta and reaches the derivative at beta = {:.1e}.",
                    2.0 * d.coefficient,
                    1.0 / d.coefficient
                )
            } else {
                format!("b^2 d3/db3 over d/db is {:.1e}.", 6.0 * d.coefficient)
            }
        );
    }
    let _ = writeln!(s);
}
