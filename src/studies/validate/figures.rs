//! The report's figures: V-curves of error against perturbation size, histories of values
//! and sensitivities, pressure profiles.

use super::*;
use crate::response::ResponseKind;
use crate::scene::Scene;
use crate::sensitivity::{Method, SensitivityResults};
use crate::studies::plot::{write_svg, Figure, Style};
use std::path::Path;

pub(super) fn sweep_of(v: &SceneValidation, m: Method, beta: f64) -> Option<&SensitivityResults> {
    v.sweeps
        .iter()
        .find(|s| s.method == Some(m) && (s.beta / beta - 1.0).abs() < 1e-9)
        .filter(|s| s.failure.is_none())
}

pub(super) const BETA_METHODS: [Method; 4] = [
    Method::Sdm,
    Method::SdmCentral,
    Method::Fdm,
    Method::FdmCentral,
];

/// Error-vs-beta figure of one scene and parameter.
pub(super) fn v_curve(v: &SceneValidation, param: &str) -> Figure {
    let mut f = Figure::new(
        format!("{}: d/d {} — error against DDM", v.scene, param),
        "perturbation beta",
        "largest relative error",
    )
    .log_x()
    .log_y();
    for m in BETA_METHODS {
        let pts: Vec<(f64, f64)> = v
            .errors
            .iter()
            .filter(|e| e.param == param && e.method == m.name() && e.error.is_finite())
            .map(|e| (e.beta, e.error))
            .collect();
        f = f.series(m.name(), pts, Style::LinePoints);
    }
    // vertical marks: the betas at which forward SDM flagged values round-off dominated
    let flagged: Vec<f64> = v
        .errors
        .iter()
        .filter(|e| e.param == param && e.method == Method::Sdm.name() && e.roundoff_flagged > 0)
        .map(|e| e.beta)
        .collect();
    f.marks(flagged)
}

/// The time history of a response's derivative by every method at one beta.
pub(super) fn history_figure(
    v: &SceneValidation,
    response: &str,
    param: &str,
    beta: f64,
    title: &str,
) -> Option<Figure> {
    let r = v.ddm.response_index(response)?;
    let p = v.ddm.parameter_index(param)?;
    let mut f = Figure::new(title, "pseudo-time t", format!("d {response} / d {param}"));
    let series = |s: &SensitivityResults| -> Vec<(f64, f64)> {
        s.increments
            .iter()
            .map(|i| (i.time, i.derivatives[r][p]))
            .collect()
    };
    f = f.series("ddm", series(&v.ddm), Style::Line);
    for m in BETA_METHODS {
        if let Some(s) = sweep_of(v, m, beta) {
            f = f.series(
                format!("{} (beta {beta:.0e})", m.name()),
                series(s),
                Style::Points,
            );
        }
    }
    let marks: Vec<f64> = v
        .flagged
        .iter()
        .map(|n| v.ddm.increments[n - 1].time)
        .collect();
    Some(f.marks(marks))
}

/// The contact pressure responses of a scene along the surface (x of the hitting node's
/// reference position), at the last increment.
pub(super) struct PressureProfile {
    /// `(response index, x)`, sorted by x.
    pub(super) nodes: Vec<(usize, f64)>,
    /// Index of the parameter "mu".
    pub(super) mu: Option<usize>,
}

impl PressureProfile {
    pub(super) fn new(v: &SceneValidation, scene: &Scene) -> Option<Self> {
        let model = scene.build().ok()?;
        let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
        let mut nodes: Vec<(usize, f64)> = model
            .responses
            .iter()
            .enumerate()
            .filter_map(|(r, resp)| match resp.kind {
                ResponseKind::ContactPressure {
                    pair, ref nodes, ..
                } => Some((r, x[model.contacts[pair].hitting[nodes[0]]][0])),
                _ => None,
            })
            .collect();
        nodes.sort_by(|a, b| a.1.total_cmp(&b.1));
        Some(PressureProfile {
            nodes,
            mu: v.ddm.parameter_index("mu"),
        })
    }

    /// `(x, p)` or `(x, dp/dmu)` near the block (|x| <= 40 mm), last increment.
    pub(super) fn curve(&self, s: &SensitivityResults, deriv: bool) -> Vec<(f64, f64)> {
        let Some(inc) = s.increments.last() else {
            return Vec::new();
        };
        self.nodes
            .iter()
            .filter(|(_, x)| x.abs() <= 40.0)
            .filter_map(|&(r, x)| {
                let y = if deriv {
                    inc.derivatives[r][self.mu?]
                } else {
                    inc.values[r]
                };
                Some((x, y))
            })
            .collect()
    }
}

pub(super) fn write_figures(
    val: &Validation,
    scenes: &[Scene],
    indentation: Option<&PressureProfile>,
    leaf_mu0: Option<&[(f64, f64)]>,
    opts: &ValidateOptions,
    dir: &Path,
) -> Result<(), ValidateError> {
    for v in &val.scenes {
        for p in &v.params {
            write_svg(
                &v_curve(v, p),
                &dir.join(format!("{}-{}-error.svg", v.scene, slug(p))),
            )?;
        }
        // cost against accuracy: every (method, beta) point, and DDM
        let mut f = Figure::new(
            format!("{}: cost against accuracy", v.scene),
            "sensitivity cost / primal analysis (all parameters)",
            "largest relative error",
        )
        .log_x()
        .log_y();
        for m in BETA_METHODS {
            let pts: Vec<(f64, f64)> = v
                .errors
                .iter()
                .filter(|e| e.method == m.name() && e.error.is_finite())
                .map(|e| (e.cost_ratio, e.error))
                .collect();
            f = f.series(m.name(), pts, Style::Points);
        }
        write_svg(&f, &dir.join(format!("{}-cost.svg", v.scene)))?;
    }
    if let Some(v) = val
        .scenes
        .iter()
        .find(|v| v.scene == super::report::TANGENT_SCENE)
    {
        write_svg(
            &super::tangent::tangent_figure(&v.scene, &v.tangent),
            &dir.join(super::report::TANGENT_FIGURE),
        )?;
    }
    let beta = opts.figure_beta;
    if let Some((v, prof)) = val
        .scenes
        .iter()
        .find(|v| v.scene == "indentation")
        .zip(indentation)
    {
        let fig4 = Figure::new(
            "Fig. 4: contact pressure after sliding 3.33 mm (indentation)",
            "x (mm, reference position of the surface node)",
            "contact pressure (MPa)",
        )
        .series("fricsens", prof.curve(&v.ddm, false), Style::LinePoints);
        write_svg(&fig4, &dir.join("fig4-indentation-pressure.svg"))?;
        let mut fig5 = Figure::new(
            "Fig. 5: d(contact pressure)/d mu after sliding (indentation)",
            "x (mm, reference position of the surface node)",
            "dp / d mu (MPa)",
        )
        .series("ddm", prof.curve(&v.ddm, true), Style::Line);
        for m in BETA_METHODS {
            if let Some(s) = sweep_of(v, m, beta) {
                fig5 = fig5.series(
                    format!("{} (beta {beta:.0e})", m.name()),
                    prof.curve(s, true),
                    Style::Points,
                );
            }
        }
        write_svg(&fig5, &dir.join("fig5-indentation-dpdmu.svg"))?;
    }
    if let Some(v) = val.scenes.iter().find(|v| v.scene == "leaf-spring") {
        let scene = scenes.iter().find(|s| s.name == "leaf-spring");
        let stroke = |t: f64| -> f64 {
            scene
                .and_then(|s| s.contacts.iter().find(|c| c.name == "block"))
                .and_then(|c| match &c.target {
                    crate::scene::TargetSpec::Rigid { motion, .. } => motion.first().map(|m| {
                        let a = crate::load::Amplitude {
                            points: m.amplitude.clone(),
                        };
                        -m.value.unwrap_or(0.0) * a.at(t)
                    }),
                    _ => None,
                })
                .unwrap_or(t)
        };
        if let Some(r) = v.ddm.response_index("block-force") {
            let mut fig7 = Figure::new(
                "Fig. 7: block force against block displacement (leaf spring)",
                "block displacement (mm)",
                "block force (N)",
            )
            .series(
                "mu = 0.5",
                v.ddm
                    .increments
                    .iter()
                    .map(|i| (stroke(i.time), i.values[r]))
                    .collect(),
                Style::LinePoints,
            );
            if let Some(m0) = leaf_mu0 {
                fig7 = fig7.series(
                    "mu = 0",
                    m0.iter().map(|(t, f)| (stroke(*t), *f)).collect(),
                    Style::LinePoints,
                );
            }
            write_svg(&fig7, &dir.join("fig7-leaf-force.svg"))?;
        }
        for (param, fig) in [
            ("upper.length.x", "fig8-leaf-dFdL"),
            ("mu", "fig9-leaf-dFdmu"),
        ] {
            let title = if param == "mu" {
                "Fig. 9: d(block force)/d mu (leaf spring)"
            } else {
                "Fig. 8: d(block force)/d L (leaf spring)"
            };
            if let Some(f) = history_figure(v, "block-force", param, beta, title) {
                write_svg(&f, &dir.join(format!("{fig}.svg")))?;
            }
        }
    }
    Ok(())
}

pub(super) fn slug(s: &str) -> String {
    s.chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect()
}
