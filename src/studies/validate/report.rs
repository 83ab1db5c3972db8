//! The report: the Markdown of `validation/README.md` (tables, time ledger, findings) and the
//! CSV data behind it.

use super::*;
use crate::sensitivity::{Method, SensitivityCost};
use std::fmt::Write as _;
use std::path::Path;

/// The "where the time goes" part of the report's cost section: the primal run split into
/// assembly, factorization and solves; the in-line methods split into evaluations,
/// factorizations, solves and the rest, per parameter and increment, against the floor.
pub(super) fn write_time_ledger(s: &mut String, val: &Validation) {
    let _ = writeln!(s, "\n### Where the time goes\n");
    let _ = writeln!(s, "The primal analysis (the in-line methods' own time taken out), split by the solver's own timers. Assembly: residual, tangent and contact search, line-search re-evaluations included; the rest: the predictor, the convergence checks, the bookkeeping of increments and cutbacks, the hand-over of each converged state to the observers. Newton iterations count the linear solves of the converged attempts, those that settle the contact states of each attempt's first step included; factorizations include the failed attempts before cutbacks.\n");
    let _ = writeln!(
        s,
        "| scene | unknowns | increments | Newton it. / incr. | factorizations (with failed attempts) | primal s | assembly | factorization | solve | the rest |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for v in &val.scenes {
        let c = &v.primal_cost;
        let share = |x: f64| format!("{:.0} %", 100.0 * x / v.primal_seconds.max(1e-12));
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.2} | {} | {:.3} | {} | {} | {} | {} |",
            v.scene,
            v.unknowns,
            v.increments,
            v.newton_iterations as f64 / v.increments.max(1) as f64,
            c.factorizations,
            v.primal_seconds,
            share(c.assembly_seconds),
            share(c.factor_seconds),
            share(c.solve_seconds),
            share(c.rest_seconds(v.primal_seconds))
        );
    }
    let _ = writeln!(s, "\nThe in-line methods, in milliseconds per parameter and increment. The floor is measured in the same run: at every increment one f64 residual evaluation over all elements at the converged state and one single-column solve with Newton's last factorization, timed together (outside the methods' own time). \"x floor\" is the method's total over it. Evaluations: the pseudo-loads (over only the elements a parameter reaches; forward SDM only where they are fewer than half of all), the nominal state over the same elements (forward SDM), the update of the history and the responses after the solve, the forced tangents of one-sided derivatives (DDM at flagged increments). The rest: building the perturbed or seeded designs and the masks, copying vectors, kink detection, copying the tangent for forced branches, the first symbolic analysis of the sensitivity's own factorization (at an increment where Newton did not factor, the floor has no solve). Solves: with Newton's last factorization, and the GMRES steps (one solve and one product each) where a method solves with the converged tangent; \"own tangents\" counts those tangents and the forced ones of one-sided derivatives, solved by GMRES (with its steps) / factored (a forced tangent is always factored: it may be singular, which GMRES need not report).\n");
    let _ = writeln!(
        s,
        "| scene | method | % of primal / param. | own tangents: GMRES (steps) / factored | evaluations | factorizations | solves | the rest | total | floor | x floor |"
    );
    let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let row = |s: &mut String,
               scene: &str,
               method: &str,
               c: &SensitivityCost,
               np: usize,
               n_inc: usize,
               primal: f64,
               floor: f64| {
        let per = 1e3 / (np.max(1) * n_inc.max(1)) as f64;
        let rest = c.rest_seconds();
        let floor_ms = floor * 1e3 / n_inc.max(1) as f64;
        let total = c.wall_seconds * per;
        let _ = writeln!(
            s,
            "| {scene} | {method} | {:.2} | {} ({}) / {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} |",
            100.0 * c.wall_seconds / primal.max(1e-12) / np.max(1) as f64,
            c.krylov_solves,
            c.krylov_iterations,
            c.factorizations,
            c.evaluation_seconds * per,
            c.factor_seconds * per,
            c.solve_seconds * per,
            rest * per,
            total,
            floor_ms,
            total / floor_ms.max(1e-12)
        );
    };
    for v in &val.scenes {
        for (method, c) in &v.ledger {
            row(
                s,
                &v.scene,
                method,
                c,
                v.params.len(),
                v.increments,
                v.primal_seconds,
                v.floor_seconds,
            );
        }
    }
    for b in &val.batched {
        for (method, c) in &b.ledger {
            let name = format!("{method}, {} parameters batched", b.params.len());
            row(
                s,
                &b.scene,
                &name,
                c,
                b.params.len(),
                b.increments,
                b.primal_seconds,
                b.floor_seconds,
            );
        }
    }
}

/// Errors of every (method, beta, parameter); sensitivity histories of DDM and of the other
/// methods at the figures' beta.
pub(super) fn write_scene_data(
    v: &SceneValidation,
    dir: &Path,
    beta: f64,
) -> Result<(), ValidateError> {
    let mut e = String::from("scene,method,beta,param,error,cost_ratio,roundoff_flagged,failure\n");
    for r in &v.errors {
        let _ = writeln!(
            e,
            "{},{},{:e},{},{:e},{:e},{},\"{}\"",
            r.scene,
            r.method,
            r.beta,
            r.param,
            r.error,
            r.cost_ratio,
            r.roundoff_flagged,
            r.failure.as_deref().unwrap_or("").replace('"', "'")
        );
    }
    write(&dir.join(format!("{}-errors.csv", v.scene)), &e)?;
    let mut s = String::from(
        "method,beta,increment,time,response,param,value,derivative,flagged,rerun_substeps\n",
    );
    let flagged = |n: usize| v.flagged.contains(&n);
    let at_beta = v
        .sweeps
        .iter()
        .filter(|s| (s.beta / beta - 1.0).abs() < 1e-9);
    for res in std::iter::once(&v.ddm).chain(at_beta) {
        let m = res.method.map(|m| m.name()).unwrap_or("?");
        for inc in &res.increments {
            for (r, name) in res.responses.iter().enumerate() {
                for (p, pn) in res.parameters.iter().enumerate() {
                    let _ = writeln!(
                        s,
                        "{m},{:e},{},{:e},{name},{pn},{:e},{:e},{},{}",
                        res.beta,
                        inc.increment,
                        inc.time,
                        inc.values[r],
                        inc.derivatives[r][p],
                        flagged(inc.increment),
                        inc.rerun_substeps.get(p).copied().unwrap_or(false)
                    );
                }
            }
        }
    }
    write(&dir.join(format!("{}-sensitivities.csv", v.scene)), &s)
}

/// Best beta and smallest error of a method for one scene and parameter.
pub(super) fn best(v: &SceneValidation, m: Method, param: &str) -> Option<(f64, f64)> {
    v.errors
        .iter()
        .filter(|e| e.method == m.name() && e.param == param && e.error.is_finite())
        .map(|e| (e.beta, e.error))
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// The scene whose tangent study is drawn, and its figure's file.
pub(super) const TANGENT_SCENE: &str = "leaf-spring";
/// The tangent study's figure.
pub(super) const TANGENT_FIGURE: &str = "leaf-spring-tangent.svg";

pub(super) fn report(
    val: &Validation,
    indentation: Option<&PressureProfile>,
    leaf_mu0: Option<&[(f64, f64)]>,
    laws: Option<&crate::studies::compare_laws::LawComparison>,
    opts: &ValidateOptions,
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# fricsens verification report\n");
    let _ = writeln!(
        s,
        "Generated by `cargo run --release -- validate` ({:.0} s on this machine). Every number and figure below is written by that command from the committed code; the data behind each plot is in `data/` (CSV per scene, `validation.json`).\n",
        val.wall_seconds
    );
    let _ = writeln!(s, "## What was run\n");
    let _ = writeln!(s, "The data: `data/SCENE-errors.csv` (every method, beta and parameter), `data/SCENE-sensitivities.csv` (every response's value and derivatives at every increment, by DDM and by the other methods at beta = {:.0e}), `data/validation.json` (the tables).\n", opts.figure_beta);
    let _ = writeln!(
        s,
        "For every scene and design parameter: DDM (forward-mode dual numbers, the exact derivative of the discrete equations, the reference), and SDM, SDM central, FDM and FDM central at beta = {} (relative perturbation `db = beta b`, `beta` itself where `b = 0`). SDM and DDM run in line with one primal analysis (all betas on the same run); FDM reruns the analysis at `b +- db` (in parallel). Errors are relative to DDM with a floor of {} x the largest |sensitivity| of the response over the history; increments flagged as non-differentiable (yield, contact or stick/slip transition within tolerance at the converged state) are excluded and marked in the plots.\n",
        opts.betas.iter().map(|b| format!("{b:.0e}")).collect::<Vec<_>>().join(", "),
        val.floor
    );
    let thinned: Vec<&str> = val
        .scenes
        .iter()
        .filter(|v| opts.reduced_fdm.contains(&v.scene))
        .map(|v| v.scene.as_str())
        .collect();
    if !thinned.is_empty() {
        let _ = writeln!(
            s,
            "The FDM sweeps of {} (a full rerun per beta, parameter and sign) use beta = {} only; `validate --full` runs them at every beta.\n",
            thinned.join(", "),
            REDUCED_FDM_BETAS
                .iter()
                .map(|b| format!("{b:.0e}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let _ = writeln!(s, "| scene | unknowns | increments | primal (s) | parameters | flagged increments | DDM cost / primal |");
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for v in &val.scenes {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.2} | {} | {} | {:.3} |",
            v.scene,
            v.unknowns,
            v.increments,
            v.primal_seconds,
            v.params.join(", "),
            v.flagged.len(),
            v.ddm_cost_ratio
        );
    }
    s.push_str(&findings(val, indentation, leaf_mu0, opts));
    let _ = writeln!(s, "\n## Best perturbation size per method\n");
    let _ = writeln!(
        s,
        "Smallest error over the sweep and the beta that gives it (relative error against DDM).\n"
    );
    let _ = writeln!(
        s,
        "| scene | parameter | SDM | SDM central | FDM | FDM central |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    for v in &val.scenes {
        for p in &v.params {
            let cells: Vec<String> = BETA_METHODS
                .iter()
                .map(|m| match best(v, *m, p) {
                    Some((b, e)) => format!("{e:.1e} @ {b:.0e}"),
                    None => "-".into(),
                })
                .collect();
            let _ = writeln!(s, "| {} | {} | {} |", v.scene, p, cells.join(" | "));
        }
    }
    write_taylor(&mut s, val, opts);
    let rows: Vec<&super::anatomy::AnatomyRow> =
        val.scenes.iter().flat_map(|v| &v.anatomy).collect();
    super::anatomy::write_anatomy(&mut s, &rows, opts.figure_beta);
    if let Some(r) = &val.refinement {
        super::refinement::write_refinement(&mut s, r);
    }
    let tangents: Vec<(&str, &super::tangent::TangentStudy)> = val
        .scenes
        .iter()
        .map(|v| (v.scene.as_str(), &v.tangent))
        .collect();
    let autos: Vec<super::auto_step::SceneRow<'_>> = val
        .scenes
        .iter()
        .flat_map(|v| {
            v.auto.iter().map(move |r| {
                let m = (Method::ALL.into_iter())
                    .find(|m| m.name() == r.method)
                    .unwrap_or(Method::Sdm);
                (v.scene.as_str(), r, best(v, m, &r.param))
            })
        })
        .collect();
    super::auto_step::write_auto(&mut s, &autos);
    let drawn = tangents.iter().any(|(n, _)| *n == TANGENT_SCENE);
    super::tangent::write_tangent(&mut s, &tangents, drawn.then_some(TANGENT_FIGURE));
    let _ = writeln!(s, "\n## Cost\n");
    let _ = writeln!(s, "Sensitivity wall time for all of a scene's parameters over the primal analysis, at beta = {:.0e} (SDM and DDM share the primal run; FDM is reruns). DDM, SDM and SDM central solve with the tangent at the converged state (the default, `--tangent exact`), to a relative residual of {:.0e}: by GMRES preconditioned with Newton's last factorization (a few solves per increment), with a factorization of their own only where GMRES does not get there in {} steps, then refined with double-double residuals to 1e-13 of the solution, so that DDM is exact to about that and SDM's error is its own; \"last factor\" (`--tangent last`) solves with Newton's last factorization alone (the paper's choice: no solve beyond one triangular solve), and its error against the reference is the price in accuracy, its time against DDM's the price of exactness. SDM's errors include its own forward-difference error at this beta, shown beside SDM with the converged tangent; the largest error over a scene's parameters is shown. The floor is one residual evaluation and one triangular solve per parameter and increment; the updates of the history after the solve skip the elements whose Gauss points are all elastic.\n", opts.figure_beta, crate::sensitivity::KRYLOV_TOL, crate::sensitivity::KRYLOV_MAX_ITER);
    let _ = writeln!(
        s,
        "| scene | parameters | DDM | DDM, last factor (error) | SDM (error) | SDM, last factor (error) | SDM central | FDM | FDM central | adjoint (last increment, every response) (error) |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|");
    for v in &val.scenes {
        let cost = |m: Method| {
            v.errors
                .iter()
                .find(|e| e.method == m.name() && (e.beta / opts.figure_beta - 1.0).abs() < 1e-9)
                .map(|e| format!("{:.3}", e.cost_ratio))
                .unwrap_or_else(|| "-".into())
        };
        // SDM's own error at this beta (converged tangent): the last factor's error adds to it
        let sdm_errors: Vec<f64> = v
            .errors
            .iter()
            .filter(|e| {
                e.method == Method::Sdm.name() && (e.beta / opts.figure_beta - 1.0).abs() < 1e-9
            })
            .map(|e| e.error)
            .collect();
        // a failed parameter (NaN) shows as NaN, no row at this beta as "-"
        let sdm_error = if sdm_errors.is_empty() {
            "-".to_string()
        } else if sdm_errors.iter().any(|e| e.is_nan()) {
            "NaN".to_string()
        } else {
            format!("{:.1e}", sdm_errors.iter().copied().fold(0.0f64, f64::max))
        };
        let adjoint = match &v.adjoint.failure {
            Some(_) => "failed".to_string(),
            None => format!(
                "{:.3} ({:.1e})",
                v.adjoint.cost_ratio,
                v.adjoint.errors.iter().copied().fold(0.0f64, f64::max)
            ),
        };
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} | {:.3} ({:.1e}) | {} ({}) | {:.3} ({:.1e}) | {} | {} | {} | {} |",
            v.scene,
            v.params.len(),
            v.ddm_cost_ratio,
            v.ddm_last_cost_ratio,
            v.ddm_last_errors.iter().copied().fold(0.0f64, f64::max),
            cost(Method::Sdm),
            sdm_error,
            v.sdm_last_cost_ratio,
            v.sdm_last_errors.iter().copied().fold(0.0f64, f64::max),
            cost(Method::SdmCentral),
            cost(Method::Fdm),
            cost(Method::FdmCentral),
            adjoint
        );
    }
    let _ = writeln!(s, "\nThe adjoint column: `--method adjoint --at last`, every response at the last increment in one backward sweep for all the parameters (its forward run stores every converged increment; its time is the storing and the sweep), and its largest error against DDM there over the responses and parameters, relative as above (a flagged last increment included: both follow the converged branches). It gives no history, so it has no place in the beta sweeps.");
    for b in &val.batched {
        let _ = writeln!(
            s,
            "\n**Batched.** The {} parameters of `{}` ({}) through one primal run ({} unknowns, {:.1} s): {}. Per parameter: {}.",
            b.params.len(),
            b.scene,
            b.params.iter().map(|p| format!("`{p}`")).collect::<Vec<_>>().join(", "),
            b.unknowns,
            b.primal_seconds,
            b.ratios
                .iter()
                .map(|(m, r)| format!("{m} {:.2} % of the primal in total", 100.0 * r))
                .collect::<Vec<_>>()
                .join(", "),
            b.ratios
                .iter()
                .map(|(m, r)| format!("{m} {:.2} %", 100.0 * r / b.params.len() as f64))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    write_time_ledger(&mut s, val);
    let _ = writeln!(s, "\n## Closed forms\n");
    write_oracle_table(&mut s, &val.oracles);
    write_imported(&mut s, val);
    let _ = writeln!(s, "\n## The paper's figures, redrawn\n");
    for (f, what) in [
        ("fig4-indentation-pressure.svg", "Contact pressure under the block after sliding (paper fig. 4)."),
        ("fig5-indentation-dpdmu.svg", "Its sensitivity to mu by every method (paper fig. 5)."),
        ("fig7-leaf-force.svg", "Leaf spring: block force against block displacement, mu = 0.5 and mu = 0 (paper fig. 7)."),
        ("fig8-leaf-dFdL.svg", "Leaf spring: d(block force)/dL over the load path (paper fig. 8)."),
        ("fig9-leaf-dFdmu.svg", "Leaf spring: d(block force)/d mu over the load path (paper fig. 9)."),
    ] {
        if opts.out.join("figures").join(f).exists() {
            let _ = writeln!(s, "{what}\n\n![{f}](figures/{f})\n");
        }
    }
    if let Some(l) = laws {
        s.push_str(&l.section());
    }
    super::convergence::write_convergence(&mut s, &val.convergence);
    super::hertz_families::write_hertz_families(&mut s, &val.hertz_families);
    super::smoothness::write_smoothness(&mut s, &val.smoothness);
    // sections written by `fricsens scaling` and `fricsens ccx` (long, or needing CalculiX):
    // included as they were last generated
    let mut sections: Vec<(String, &str)> = [
        ("robustness/robustness.md", "fricsens fuzz"),
        ("scaling/scaling.md", "fricsens scaling"),
        ("adjoint/adjoint.md", "fricsens adjoint-study"),
    ]
    .iter()
    .map(|(f, w)| (f.to_string(), *w))
    .collect();
    sections.extend(
        CCX_DIRS
            .iter()
            .map(|d| (format!("{d}/ccx.md"), "fricsens ccx")),
    );
    for (k, (file, what)) in sections.iter().enumerate() {
        // the comparisons side by side before the first of them
        if k == sections.len() - CCX_DIRS.len() {
            ccx_side_by_side(&mut s, &opts.out);
        }
        if let Ok(text) = std::fs::read_to_string(opts.out.join(file)) {
            let dir = file.split('/').next().unwrap_or("");
            let _ = writeln!(
                s,
                "<!-- included from {file}, written by `{what}` -->\n{}\n",
                text.replace("](", &format!("]({dir}/"))
                    .replace(&format!("]({dir}/http"), "](http"),
            );
        }
    }
    let _ = writeln!(s, "## Error against perturbation size\n");
    let _ = writeln!(s, "One plot per scene and parameter: the largest error over responses and unflagged increments against beta, for each method. Vertical marks: the betas at which forward SDM flagged some of its values round-off dominated.\n");
    for v in &val.scenes {
        let _ = writeln!(s, "### {}\n\n{}\n", v.scene, v.description);
        for p in &v.params {
            let f = format!("{}-{}-error.svg", v.scene, slug(p));
            let _ = writeln!(s, "![{f}](figures/{f})\n");
        }
        let f = format!("{}-cost.svg", v.scene);
        let _ = writeln!(s, "![{f}](figures/{f})\n");
    }
    s
}

pub(super) fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The "what was found" and "what it means" sections, every number computed from the run.
pub(super) fn findings(
    val: &Validation,
    indentation: Option<&PressureProfile>,
    leaf_mu0: Option<&[(f64, f64)]>,
    opts: &ValidateOptions,
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "\n## What was found\n");
    let _ = writeln!(s, "**Accuracy against perturbation size.** For each method, over every scene and parameter: the best error and its beta, and the single beta whose worst error over all scenes is smallest (the beta to choose without a sweep).\n");
    let _ = writeln!(
        s,
        "| method | median best error | worst best error | median best beta | one beta for all: beta, worst error |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|");
    let mut one_beta = Vec::new();
    for m in BETA_METHODS {
        let mut errs = Vec::new();
        let mut betas = Vec::new();
        for v in &val.scenes {
            for p in &v.params {
                if let Some((b, e)) = best(v, m, p) {
                    errs.push(e);
                    betas.push(b.log10());
                }
            }
        }
        let worst_best = errs.iter().copied().fold(0.0f64, f64::max);
        // the beta minimising the worst error over every scene and parameter
        let all = val
            .betas
            .iter()
            .map(|&b| {
                let worst = val
                    .scenes
                    .iter()
                    .flat_map(|v| &v.errors)
                    .filter(|e| e.method == m.name() && (e.beta / b - 1.0).abs() < 1e-9)
                    .map(|e| {
                        if e.error.is_finite() {
                            e.error
                        } else {
                            f64::INFINITY
                        }
                    })
                    .fold(0.0f64, f64::max);
                (b, worst)
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some(a) = all {
            one_beta.push((m, a));
        }
        let _ = writeln!(
            s,
            "| {} | {:.1e} | {:.1e} | 1e{:.0} | {} |",
            m.name(),
            median(errs),
            worst_best,
            median(betas),
            all.map(|(b, e)| format!("{b:.0e}: {e:.1e}"))
                .unwrap_or_else(|| "-".into())
        );
    }
    // round-off flags: the largest beta at which each method flagged a result
    let mut flags = Vec::new();
    for m in BETA_METHODS {
        let rows: Vec<&ErrorRow> = val
            .scenes
            .iter()
            .flat_map(|v| &v.errors)
            .filter(|e| e.method == m.name() && e.roundoff_flagged > 0)
            .collect();
        let largest = rows.iter().map(|e| e.beta).fold(0.0f64, f64::max);
        if largest > 0.0 {
            flags.push(format!(
                "{} from beta = {largest:.0e} down ({} scene-parameter-beta cases)",
                m.name(),
                rows.len()
            ));
        }
    }
    if !flags.is_empty() {
        let _ = writeln!(
            s,
            "\n**Round-off flags.** A difference that keeps fewer than {} significant digits above its noise (machine precision times the cancelling forces for SDM, the Newton tolerance for FDM's reruns) flags its value round-off dominated: {}. The flags sit on the right-hand, rising side of the V-curves.\n",
            crate::sensitivity::ROUNDOFF_DIGITS,
            flags.join("; ")
        );
    }
    // cost per parameter
    let per_param = |m: Option<Method>| -> f64 {
        median(
            val.scenes
                .iter()
                .filter_map(|v| {
                    let np = v.params.len().max(1) as f64;
                    match m {
                        None => Some(v.ddm_cost_ratio / np),
                        Some(m) => v
                            .errors
                            .iter()
                            .find(|e| {
                                e.method == m.name()
                                    && (e.beta / opts.figure_beta - 1.0).abs() < 1e-9
                                    && e.failure.is_none()
                            })
                            .map(|e| e.cost_ratio / np),
                    }
                })
                .collect(),
        )
    };
    let _ = writeln!(
        s,
        "\n**Cost.** Median over the scenes of the sensitivity time per parameter over the primal analysis: DDM {:.3}, SDM {:.3}, SDM central {:.3}, FDM {:.3}, FDM central {:.3}. The in-line methods reuse the converged state and the factored tangent; finite differences rerun the analysis (FDM's ratio is below 1 where the reruns ran in parallel on the two cores, or took fewer Newton iterations than the nominal run).\n",
        per_param(None),
        per_param(Some(Method::Sdm)),
        per_param(Some(Method::SdmCentral)),
        per_param(Some(Method::Fdm)),
        per_param(Some(Method::FdmCentral)),
    );
    // the adjoint at the last increment
    let adjoint: Vec<&SceneValidation> = val
        .scenes
        .iter()
        .filter(|v| v.adjoint.failure.is_none() && !v.adjoint.errors.is_empty())
        .collect();
    if !adjoint.is_empty() {
        let worst = adjoint
            .iter()
            .map(|v| {
                (
                    v.adjoint.errors.iter().copied().fold(0.0f64, f64::max),
                    v.scene.as_str(),
                )
            })
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .expect("not empty");
        let failed: Vec<&str> = val
            .scenes
            .iter()
            .filter(|v| v.adjoint.failure.is_some())
            .map(|v| v.scene.as_str())
            .collect();
        let _ = writeln!(
            s,
            "**Adjoint.** Every response at the last increment, all of a scene's parameters in one backward sweep: its largest error against DDM over {} scenes is {:.1e} ({}); its cost over the primal analysis, for all the parameters, has a median of {:.3} (against DDM's {:.3}).{}\n",
            adjoint.len(),
            worst.0,
            worst.1,
            median(adjoint.iter().map(|v| v.adjoint.cost_ratio).collect()),
            median(adjoint.iter().map(|v| v.ddm_cost_ratio).collect()),
            if failed.is_empty() {
                String::new()
            } else {
                format!(" It failed on {}.", failed.join(", "))
            }
        );
    }
    let pass = val.oracles.iter().filter(|o| o.pass).count();
    let worst = val
        .oracles
        .iter()
        .map(|o| o.rel_error / o.tolerance)
        .fold(0.0f64, f64::max);
    let _ = writeln!(
        s,
        "**Closed forms.** {pass} of {} checks pass (table below); the closest to its tolerance uses {:.0} % of it.\n",
        val.oracles.len(),
        100.0 * worst
    );
    let failures: Vec<&ErrorRow> = val
        .scenes
        .iter()
        .flat_map(|v| &v.errors)
        .filter(|e| e.failure.is_some())
        .collect();
    if failures.is_empty() {
        let _ = writeln!(s, "**Failures.** None: every method ran at every beta.\n");
    } else {
        let _ = writeln!(s, "**Failures.** A perturbed analysis that cannot be evaluated is a result too (the other methods went on):\n");
        for e in failures {
            let why = e.failure.as_deref().unwrap_or("");
            // the residual histories are in data/SCENE-errors.csv
            let short: String = why.chars().take(160).collect();
            let _ = writeln!(
                s,
                "- {} {} d/d {} at beta {:.0e}: {}{}",
                e.scene,
                e.method,
                e.param,
                e.beta,
                short,
                if short.len() < why.len() { " ..." } else { "" }
            );
        }
        let _ = writeln!(s);
    }
    let substeps: Vec<&ErrorRow> = val
        .scenes
        .iter()
        .flat_map(|v| &v.errors)
        .filter(|e| e.substep_excluded > 0 && e.failure.is_none())
        .collect();
    if !substeps.is_empty() {
        let _ = writeln!(s, "**Finite differences across a different step sequence.** A rerun that needs a cutback the nominal run did not take solves the path-dependent incremental problem on other steps. From that increment on, its difference measures the change of the discrete path divided by the perturbation, not the derivative: those increments are left out of FDM's errors (and marked in the data). This happened to:\n");
        for e in substeps {
            let _ = writeln!(
                s,
                "- {} {} d/d {} at beta {:.0e}: {} increments",
                e.scene, e.method, e.param, e.beta, e.substep_excluded
            );
        }
        let _ = writeln!(s);
    }
    if let (Some(prof), Some(v)) = (
        indentation,
        val.scenes.iter().find(|v| v.scene == "indentation"),
    ) {
        let p = prof.curve(&v.ddm, false);
        let d = prof.curve(&v.ddm, true);
        // the contact zone after sliding: nodes with pressure; trailing edge = smallest x
        let zone: Vec<usize> = (0..p.len()).filter(|&i| p[i].1 > 0.0).collect();
        if let (Some(&i0), Some(&i1)) = (zone.first(), zone.last()) {
            let (nu, mu) = (0.3f64, 0.5f64);
            let gamma = (mu * (1.0 - 2.0 * nu) / (2.0 * (1.0 - nu))).atan() / std::f64::consts::PI;
            let _ = writeln!(s, "**Why the indentation pressure is asymmetric** (figure 4). The block slides towards +x. After sliding, the pressure at the trailing edge (x = {:.2} mm) is {:.1} MPa and at the leading edge (x = {:.2} mm) {:.1} MPa: the sharper gradient is at the trailing (left) edge, as in the paper. The friction traction mu p drags the slab's surface in the sliding direction. On an elastic half-space a tangential surface traction also moves the surface normally, by a term proportional to (1 - 2 nu) / (2 (1 - nu)): the surface ahead of it sinks and the surface behind it rises (Johnson, Contact Mechanics, section 2.2). So a rigid flat block bears harder behind and lighter ahead. For a flat punch, the edge singularities become (a + x)^(-1/2 - gamma) and (a - x)^(-1/2 + gamma), with tan(pi gamma) = mu (1 - 2 nu) / (2 (1 - nu)) = {:.3}, so gamma = {:.3} here. The paper gives the same effect as the rigid block's reaction resisting the friction moment. The asymmetry grows with mu (figure 5): dp/dmu = {:+.1} MPa at the trailing edge and {:+.1} MPa at the leading edge.\n",
                p[i0].0, p[i0].1, p[i1].0, p[i1].1,
                (std::f64::consts::PI * gamma).tan(), gamma,
                d[i0].1, d[i1].1);
        }
    }
    if let Some(v) = val.scenes.iter().find(|v| v.scene == "leaf-spring") {
        if let (Some(r), Some(pm)) = (
            v.ddm.response_index("block-force"),
            v.ddm.parameter_index("mu"),
        ) {
            let inc = &v.ddm.increments;
            let f: Vec<(f64, f64)> = inc.iter().map(|i| (i.time, i.values[r])).collect();
            let peak = |pts: &[(f64, f64)]| {
                pts.iter()
                    .filter(|(t, _)| *t <= 1.0 + 1e-9)
                    .map(|p| p.1)
                    .fold(f64::NEG_INFINITY, f64::max)
            };
            let at_end = |pts: &[(f64, f64)]| {
                pts.iter()
                    .filter(|(t, _)| (*t - 1.0).abs() < 1e-9)
                    .map(|p| p.1)
                    .next()
            };
            let first_unload = f.iter().find(|(t, _)| *t > 1.0 + 1e-9).map(|p| p.1);
            let _ = write!(s, "**Leaf spring** (figures 7-9). With mu = 0.5 the block force peaks at {:.0} N in loading", peak(&f));
            if let Some(m0) = leaf_mu0 {
                let _ = write!(s, "; without friction at {:.0} N, so friction raises the loading force by {:.0} %", peak(m0), 100.0 * (peak(&f) / peak(m0) - 1.0));
            }
            if let (Some(a), Some(b)) = (at_end(&f), first_unload) {
                let _ = write!(s, ". Right after unloading starts it drops from {a:.0} N to {b:.0} N in one increment: the friction forces reverse");
            }
            let dmu: Vec<f64> = inc.iter().map(|i| i.derivatives[r][pm]).collect();
            let changes = dmu.windows(2).filter(|w| w[0] * w[1] < 0.0).count();
            let (lo, hi) = dmu
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |a, &x| {
                    (a.0.min(x), a.1.max(x))
                });
            let phase = |a: f64, b: f64| {
                median(
                    inc.iter()
                        .filter(|i| i.time > a + 1e-9 && i.time <= b + 1e-9)
                        .map(|i| i.derivatives[r][pm])
                        .collect(),
                )
            };
            let _ = writeln!(s, ". dF/dmu ranges over [{lo:.0}, {hi:.0}] N along the path and changes sign {changes} times; its median is {:+.0} N in loading, {:+.0} N in unloading and {:+.0} N in reloading: the derivative depends on the path, not only on the block's position. {} of {} increments are flagged as non-differentiable (stick/slip, contact or yield transitions) and are marked in the plots.\n", phase(0.0, 1.0), phase(1.0, 2.0), phase(2.0, 3.0), v.flagged.len(), v.increments);
        }
    }
    let _ = writeln!(s, "## What it means for choosing beta and a method\n");
    for (m, (b, e)) in &one_beta {
        let _ = writeln!(
            s,
            "- **{}**: beta = {b:.0e} keeps the error below {e:.1e} on every scene here.",
            m.name()
        );
    }
    let _ = writeln!(s, "\nForward differences (SDM, FDM) trade truncation error, which is proportional to beta, against round-off, which is proportional to 1/beta. Central differences make truncation proportional to beta^2, so their best beta is larger and their best error smaller. SDM's round-off is that of one residual evaluation at a fixed state, so it goes down to about sqrt(machine epsilon). FDM's round-off is the Newton tolerance of two separate analyses divided by beta: it is worse by orders of magnitude, and its best beta is larger. DDM has no beta, is exact to the linear solve, and costs about as much as SDM. It is the method to use when the kernels are generic, as all of fricsens' are. SDM central is the check that needs no dual numbers, and FDM is the check that needs nothing but reruns. Away from the flagged increments all methods converge to DDM. At a flagged increment a finite perturbation crosses the kink, so a difference returns a mix of the one-sided derivatives.\n");
    s
}

/// The imported-geometry oracles ([`super::imported`]).
fn write_imported(s: &mut String, val: &Validation) {
    if val.imported.is_empty() {
        return;
    }
    let _ = writeln!(s, "\n## Imported geometry\n");
    let pass = val.imported.iter().filter(|o| o.pass).count();
    let _ = writeln!(
        s,
        "Scenes around Gmsh meshes (`meshes/`, made by `meshes/make_meshes.py`), DDM against \
         closed forms and independent methods: {pass} of {} pass. Two elastic cylinders of \
         different radii and moduli in plane strain (R1 = 8, R2 = 12, E1 = 2e5, E2 = 1e5, 18 \
         elements across the half-width), in both master/slave directions: two-body Hertz with \
         1/R = 1/R1 + 1/R2 and 1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2, the half-width measured \
         by the second moment of the nodal forces. The Lamé thick sphere under internal pressure \
         (an octant of 6912 hex8): the bore's displacement and its derivatives in E, nu and the \
         inner radius a, a shape parameter through a boundary-driven design velocity field, \
         against the closed form differentiated by dual numbers, and against central FDM of \
         reruns. A morph to the same mesh scaled by 1.05 against the scale map of the same \
         change. `cargo test --release --test oracles imported` asserts the same rows.\n",
        val.imported.len()
    );
    write_oracle_table(s, &val.imported);
}

/// A table of closed-form checks.
fn write_oracle_table(s: &mut String, rows: &[OracleRow]) {
    let _ = writeln!(
        s,
        "| scene | quantity | expected | fricsens (DDM) | relative error | tolerance | |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for o in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.6e} | {:.6e} | {:.2e} | {:.0e} | {} |",
            o.scene,
            o.quantity,
            o.expected,
            o.got,
            o.rel_error,
            o.tolerance,
            if o.pass { "pass" } else { "**FAIL**" }
        );
    }
}

/// The Taylor table ([`super::taylor`]).
fn write_taylor(s: &mut String, val: &Validation, opts: &ValidateOptions) {
    let _ = writeln!(s, "\n## Taylor test\n");
    let _ = writeln!(
        s,
        "The remainder `R(h) = |f(b + h) - f(b) - h f'|` falls as `h^2` when `f'` is the derivative of `f` at `b`, and only as `h` when it is not: the gradient check of the adjoint literature. `f(b + h)` is the forward FDM rerun at `h = beta b` for beta = {} (where the sweep ran it), `f'` DDM's; per scene and parameter the response and increment most sensitive to the parameter (unflagged). Slopes are least-squares fits of `log R` against `log h`; the zeroth-order column (`f' = 0`) shows what a wrong derivative gives, and the last column the slope with each other method's derivative at the figure beta (2 while the method's error `e` is below `h f''/2` at every step, falling towards 1 where `h e` takes over). A slope below 2 with DDM means the response is not smooth over the step: an active set, a stick/slip or a yield state changes between `b` and `b + h` (the scenes with contact and plasticity), or the rerun's Newton noise (1e-9 of the response) reaches the remainder at the smallest step.\n",
        super::taylor::TAYLOR_BETAS
            .iter()
            .map(|b| format!("{b:.0e}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let rows: Vec<&super::taylor::TaylorRow> = val.scenes.iter().flat_map(|v| &v.taylor).collect();
    let tested: Vec<_> = rows
        .iter()
        .filter(|t| !t.linear && t.h.len() >= 2)
        .collect();
    let quadratic = tested
        .iter()
        .filter(|t| (t.slope_exact - 2.0).abs() <= 0.05)
        .count();
    let last_steps = tested
        .iter()
        .filter(|t| {
            let n = t.h.len();
            (super::taylor::log_slope(&t.h[n - 2..], &t.exact[n - 2..]) - 2.0).abs() <= 0.1
        })
        .count();
    let first_order = tested
        .iter()
        .filter(|t| (t.slope_zeroth - 1.0).abs() <= 0.1)
        .count();
    let _ = writeln!(
        s,
        "Of {} tests with at least two steps and a response not linear in its parameter, {quadratic} have a fitted slope within 0.05 of 2, and {last_steps} fall as `h^2` (slope within 0.1 of 2) over their last, smallest step; with `f' = 0`, {first_order} have a fitted slope within 0.1 of 1.\n",
        tested.len()
    );
    let _ = writeln!(
        s,
        "| scene | parameter | response (increment) | R(h) with DDM's f', largest h first | slope per step, DDM | fitted slope, DDM | fitted slope, f' = 0 | fitted slope with f' by SDM, SDM central, FDM central at beta = {:.0e} |",
        opts.figure_beta
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
    for v in &val.scenes {
        for t in &v.taylor {
            let rs: Vec<String> = t.exact.iter().map(|r| format!("{r:.1e}")).collect();
            let fmt = |v: f64| {
                if v.is_finite() {
                    format!("{v:.2}")
                } else {
                    "-".to_string()
                }
            };
            let steps: Vec<String> = (t.h.windows(2).zip(t.exact.windows(2)))
                .map(|(h, r)| fmt(super::taylor::log_slope(h, r)))
                .collect();
            let (steps, slope) = if t.linear {
                ("-".to_string(), "linear in b: R is round-off".to_string())
            } else if t.h.len() < 2 {
                (
                    "-".to_string(),
                    format!(
                        "{} usable step (the others took extra sub-increments or failed)",
                        t.h.len()
                    ),
                )
            } else {
                (steps.join(", "), fmt(t.slope_exact))
            };
            let others: Vec<String> = t.methods.iter().map(|m| fmt(m.slope)).collect();
            let _ = writeln!(
                s,
                "| {} | {} | {} ({}) | {} | {steps} | {slope} | {} | {} |",
                t.scene,
                t.param,
                t.response,
                t.increment,
                rs.join(", "),
                fmt(t.slope_zeroth),
                others.join(", ")
            );
        }
    }
}

/// The folders of the CalculiX comparisons the report includes, in its order.
const CCX_DIRS: [&str; 3] = ["ccx", "ccx-hex20", "ccx-tet10"];

/// The CalculiX comparisons the report includes (`OUT/DIR/ccx.json` for each of
/// [`CCX_DIRS`], written by `fricsens ccx`), side by side: one row each.
fn ccx_side_by_side(s: &mut String, out: &std::path::Path) {
    use std::fmt::Write;
    let rows: Vec<crate::studies::ccx::CcxSummary> = CCX_DIRS
        .iter()
        .filter_map(|d| std::fs::read_to_string(out.join(d).join("ccx.json")).ok())
        .filter_map(|t| serde_json::from_str(&t).ok())
        .collect();
    if rows.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "## Against CalculiX, side by side\n\nThe comparisons below (written by `fricsens ccx SCENE --out validation/DIR`; the quadratic meshes are `scenes/indentation-hex20.toml` and `scenes/indentation-tet10.toml`, the indentation on hex20 and tet10 elements of twice the size), in a few numbers: primal wall times, their ratio, and the largest difference between the two codes' compared forces over the history, over the largest force.\n\n| scene | CalculiX elements | fricsens family | fricsens unknowns | CalculiX nodes | fricsens primal (s) | CalculiX primal (s) | ratio | largest force difference |\n|---|---|---|---|---|---|---|---|---|"
    );
    for r in &rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2e} |",
            r.scene,
            r.element_types.join(", "),
            r.families.join(", "),
            r.unknowns,
            r.ccx_nodes,
            r.fricsens_seconds,
            r.ccx_seconds,
            r.ccx_seconds / r.fricsens_seconds.max(1e-12),
            r.largest_difference
        );
    }
    let _ = writeln!(s);
}
