//! The friction laws compared on one scene: the report's "Friction laws" section.
//!
//! The frictional strip pull-out (`shared/oracles.md` section 7) is run with each shipped
//! friction law at matching parameters — Coulomb (`mu`), regularised Coulomb (`mu`), and the
//! pressure-dependent coefficient (`mu0`, `p0`, `n`) — and the pulled end's displacement `u0`
//! and its sensitivities to every parameter of the law are computed by DDM, SDM central and
//! central FDM. What the section shows:
//!
//! * how much the law changes the response and its sensitivity to the friction coefficient,
//!   over the load (t = 0..1) and the release (t = 1..2);
//! * that the three methods agree for every law (none of them has a derivative written by
//!   hand), and what each costs;
//! * how smooth each law's sensitivity history is: the largest jump of `du0/dmu` between
//!   increments, relative to its largest value (the regularised law has no stick/slip switch).

use crate::contact::Friction;
use crate::scene::{strip_pullout, StripSpec};
use crate::sensitivity::{
    run_inline_sweep, run_sensitivity, Method, Parameter, SensitivityError, SensitivityResults,
    Settings, TangentChoice,
};
use crate::solver::AnalysisError;
use crate::studies::plot::{write_svg, Figure, PlotError, Style};
use std::fmt::Write as _;
use std::path::Path;

/// Perturbation of SDM central in the comparison. Not the sweep's best 1e-5: the regularised
/// law's force, `t_trial / sqrt(1 + (|t_trial| / mu p_n)^2)`, is strongly nonlinear in `mu`
/// where `p_n` is small (the released strip), and central SDM's truncation error there falls
/// as beta^2 from 18 % of the largest sensitivity at 1e-3 to 2.4e-5 at 1e-5 and 1e-10 at 1e-7.
const BETA_SDM: f64 = 1e-6;
/// See [`BETA_SDM`].
const BETA_FDM: f64 = 1e-6;

/// One law's results.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct LawResult {
    /// The law's name.
    pub law: String,
    /// Its design parameters (`ground.NAME`).
    pub parameters: Vec<String>,
    /// `(t, u0)` over the path.
    pub response: Vec<(f64, f64)>,
    /// `(t, du0/db)` by DDM, per parameter.
    pub ddm: Vec<Vec<(f64, f64)>>,
    /// Largest `|DDM - FDM central|` over the path relative to the largest `|DDM|`, per
    /// parameter.
    pub fdm_agreement: Vec<f64>,
    /// The same for SDM central.
    pub sdm_agreement: Vec<f64>,
    /// Seconds per parameter over the primal's seconds: DDM, SDM central, FDM central.
    pub cost: [f64; 3],
    /// Largest jump of the first parameter's DDM sensitivity between increments, relative to
    /// its largest magnitude.
    pub largest_jump: f64,
}

/// The comparison: one [`LawResult`] per shipped law.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct LawComparison {
    /// Strip elements.
    pub elements: usize,
    /// Results per law.
    pub laws: Vec<LawResult>,
}

/// Why the comparison failed.
#[derive(Debug, thiserror::Error)]
pub enum CompareLawsError {
    /// A run of one law failed.
    #[error("friction law '{law}': {source}")]
    Analysis {
        /// The law.
        law: String,
        /// What failed.
        #[source]
        source: AnalysisError,
    },
    /// Writing a figure failed.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// The strip scene did not build.
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
}

/// Largest `|a - b|` over the path relative to the largest `|a|`, for parameter `p` of
/// response 0.
fn agreement(a: &SensitivityResults, b: &SensitivityResults, p: usize) -> f64 {
    let scale = a
        .increments
        .iter()
        .fold(0.0f64, |m, i| m.max(i.derivatives[0][p].abs()));
    a.increments
        .iter()
        .zip(&b.increments)
        .map(|(x, y)| {
            (x.derivatives[0][p] - y.derivatives[0][p]).abs() / scale.max(f64::MIN_POSITIVE)
        })
        .fold(0.0, f64::max)
}

/// Run the comparison on a strip of `elements` elements.
pub fn compare_laws(elements: usize) -> Result<LawComparison, CompareLawsError> {
    let spec = StripSpec {
        elements,
        ..StripSpec::default()
    };
    let mut out = Vec::new();
    // the registered laws at matching parameters (`Friction::examples`), every parameter a
    // design parameter
    for friction in Friction::examples() {
        let names = friction.param_names();
        let law = friction.name().to_string();
        let fail = |source| CompareLawsError::Analysis {
            law: law.clone(),
            source,
        };
        let mut model = strip_pullout(&spec).build()?;
        model.contacts[0].friction = Some(friction);
        let params = names
            .iter()
            .map(|n| Parameter::by_name(&model, &format!("ground.{n}")))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| fail(e.into()))?;
        let settings = |method, beta| Settings {
            method,
            beta,
            tangent: TangentChoice::Exact,
            ..Settings::default()
        };
        // DDM and SDM central observe one primal run; central FDM reruns it
        let (_, inline) = run_inline_sweep(
            &model,
            &params,
            &[
                settings(Method::Ddm, 0.0),
                settings(Method::SdmCentral, BETA_SDM),
            ],
        )
        .map_err(fail)?;
        let [ddm, sdm]: [SensitivityResults; 2] = inline.try_into().map_err(|_| {
            fail(
                SensitivityError::Failed {
                    method: "in-line sweep",
                    reason: "did not return two in-line methods".into(),
                }
                .into(),
            )
        })?;
        let fdm = run_sensitivity(&model, &params, &settings(Method::FdmCentral, BETA_FDM))
            .map_err(fail)?
            .1;
        let np = params.len() as f64;
        let primal = ddm.primal_seconds.max(f64::MIN_POSITIVE);
        let cost = [
            ddm.cost.wall_seconds / np / primal,
            sdm.cost.wall_seconds / np / primal,
            fdm.cost.wall_seconds / np / primal,
        ];
        let series = |p: usize| -> Vec<(f64, f64)> {
            ddm.increments
                .iter()
                .map(|i| (i.time, i.derivatives[0][p]))
                .collect()
        };
        let first = series(0);
        let largest = first.iter().fold(0.0f64, |m, (_, d)| m.max(d.abs()));
        let largest_jump = first
            .windows(2)
            .map(|w| (w[1].1 - w[0].1).abs())
            .fold(0.0, f64::max)
            / largest.max(f64::MIN_POSITIVE);
        out.push(LawResult {
            law,
            parameters: params.iter().map(|p| p.name.clone()).collect(),
            response: ddm
                .increments
                .iter()
                .map(|i| (i.time, i.values[0]))
                .collect(),
            ddm: (0..params.len()).map(series).collect(),
            fdm_agreement: (0..params.len())
                .map(|p| agreement(&ddm, &fdm, p))
                .collect(),
            sdm_agreement: (0..params.len())
                .map(|p| agreement(&ddm, &sdm, p))
                .collect(),
            cost,
            largest_jump,
        });
    }
    Ok(LawComparison {
        elements,
        laws: out,
    })
}

/// Value of a history at time `t` (the nearest increment).
fn at(history: &[(f64, f64)], t: f64) -> f64 {
    history
        .iter()
        .min_by(|a, b| (a.0 - t).abs().total_cmp(&(b.0 - t).abs()))
        .map_or(f64::NAN, |p| p.1)
}

impl LawComparison {
    /// Write the two figures (`laws-u0.svg`, `laws-du0dmu.svg`) into `figures`.
    pub(crate) fn write_figures(&self, figures: &Path) -> Result<(), PlotError> {
        let mut u = Figure::new(
            "Strip pull-out: pulled end's displacement, per friction law",
            "t (load to 1, release to 2)",
            "u0",
        );
        let mut d = Figure::new(
            "Strip pull-out: du0/dmu (mu0 for the pressure-dependent law) by DDM",
            "t (load to 1, release to 2)",
            "du0/dmu",
        );
        for l in &self.laws {
            u = u.series(l.law.clone(), l.response.clone(), Style::LinePoints);
            d = d.series(l.law.clone(), l.ddm[0].clone(), Style::LinePoints);
        }
        write_svg(&u, &figures.join("laws-u0.svg"))?;
        write_svg(&d, &figures.join("laws-du0dmu.svg"))
    }

    /// The report section (markdown), every number computed from the runs.
    pub fn section(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "## Friction laws compared\n");
        let _ = writeln!(
            s,
            "The frictional strip pull-out ({} elements, pulled to its peak force at t = 1 and released by t = 2) with each shipped friction law at matching parameters (mu = mu0 = 0.5; the pressure-dependent law's p0 = 0.1, about the mean nodal normal force, and n = 0.2). Response: the pulled end's displacement u0. Every sensitivity by DDM, SDM central (beta = {BETA_SDM:.0e}) and central FDM (beta = {BETA_FDM:.0e}); no law has a derivative written by hand. `src/studies/compare_laws.rs`.\n",
            self.elements
        );
        let _ = writeln!(s, "| law | parameter | u0 at peak | du0/db at peak | du0/db released | FDM central vs DDM | SDM central vs DDM |");
        let _ = writeln!(s, "|---|---|---|---|---|---|---|");
        for l in &self.laws {
            for (p, name) in l.parameters.iter().enumerate() {
                let _ = writeln!(
                    s,
                    "| {} | {} | {:.4e} | {:+.4e} | {:+.4e} | {:.1e} | {:.1e} |",
                    l.law,
                    name,
                    at(&l.response, 1.0),
                    at(&l.ddm[p], 1.0),
                    at(&l.ddm[p], 2.0),
                    l.fdm_agreement[p],
                    l.sdm_agreement[p]
                );
            }
        }
        let _ = writeln!(
            s,
            "\nAgreement: the largest difference over the path relative to the largest DDM sensitivity.\n"
        );
        let _ = writeln!(s, "| law | DDM / primal per parameter | SDM central | FDM central | largest jump of du0/dmu between increments |");
        let _ = writeln!(s, "|---|---|---|---|---|");
        for l in &self.laws {
            let _ = writeln!(
                s,
                "| {} | {:.3} | {:.3} | {:.2} | {:.2} |",
                l.law, l.cost[0], l.cost[1], l.cost[2], l.largest_jump
            );
        }
        if let (Some(c), Some(r)) = (
            self.laws.iter().find(|l| l.law == "coulomb"),
            self.laws.iter().find(|l| l.law == "regularized-coulomb"),
        ) {
            let (uc, ur) = (at(&c.response, 1.0), at(&r.response, 1.0));
            let (dc, dr) = (at(&c.ddm[0], 1.0), at(&r.ddm[0], 1.0));
            let smoothness = if (r.largest_jump - c.largest_jump).abs() < 0.25 * c.largest_jump {
                "close to each other: at this increment size the load steps, more than Coulomb's stick/slip switch, set the jumps"
            } else if r.largest_jump < c.largest_jump {
                "smaller: the smooth law has no stick/slip switch to kink its sensitivity where the slip front passes a node"
            } else {
                "not smaller, though the smooth law has no stick/slip switch"
            };
            let _ = writeln!(
                s,
                "\nAt the peak the regularised law lets the strip slide {:+.2} % further than Coulomb (its force only approaches mu p_n), and its du0/dmu is {:.1} % of Coulomb's in magnitude. Its largest jump between increments is {:.2} of its largest value against Coulomb's {:.2}, {smoothness}.\n",
                100.0 * (ur / uc - 1.0),
                100.0 * dr.abs() / dc.abs().max(f64::MIN_POSITIVE),
                r.largest_jump,
                c.largest_jump
            );
        }
        let _ = writeln!(
            s,
            "![laws-u0.svg](figures/laws-u0.svg)\n\n![laws-du0dmu.svg](figures/laws-du0dmu.svg)\n"
        );
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_law_agrees_across_methods_and_the_section_names_them() {
        let c = compare_laws(20).unwrap();
        assert_eq!(c.laws.len(), 3);
        for l in &c.laws {
            for (p, name) in l.parameters.iter().enumerate() {
                // central differences at these betas: truncation ~beta^2, round-off of the
                // converged reruns ~1e-10 relative
                assert!(
                    l.fdm_agreement[p] < 1e-6,
                    "{} {name}: {}",
                    l.law,
                    l.fdm_agreement[p]
                );
                assert!(
                    l.sdm_agreement[p] < 1e-6,
                    "{} {name}: {}",
                    l.law,
                    l.sdm_agreement[p]
                );
            }
        }
        let s = c.section();
        if std::env::var_os("FRICSENS_PRINT").is_some() {
            println!("{s}");
        }
        for name in ["coulomb", "regularized-coulomb", "pressure-dependent"] {
            assert!(s.contains(&format!("| {name} |")), "{name} missing");
        }
    }
}
