//! The report's check of `--beta auto` (`crate::sensitivity` `auto` module): per scene,
//! parameter and method (SDM and FDM, forward and central), how often the error bar bounds the true error against DDM, and
//! the largest error against the sweep's best.

use super::{increment_errors, SensitivityResults};
use crate::design::Parameter;
use std::fmt::Write;

/// One row of the table.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct AutoRow {
    /// `sdm`, `sdm-central`, `fdm` or `fdm-central`.
    pub method: String,
    /// Design parameter.
    pub param: String,
    /// Derivatives (unflagged increments, sensitive responses) whose bar bounds the error.
    pub bounded: usize,
    /// Derivatives compared.
    pub compared: usize,
    /// The largest error as the sweep measures it.
    pub error: f64,
    /// The smallest and largest step chosen over the increments.
    pub steps: (f64, f64),
}

/// The rows of one scene from its `--beta auto` runs against DDM.
pub fn auto_rows(
    ddm: &SensitivityResults,
    runs: &[SensitivityResults],
    params: &[Parameter],
    floor: f64,
    flagged: &[bool],
) -> Vec<AutoRow> {
    let mut rows = Vec::new();
    for s in runs {
        for (k, p) in params.iter().enumerate() {
            let (mut bounded, mut compared) = (0, 0);
            for r in 0..ddm.responses.len() {
                if ddm.sensitive_scale(r, k, p.value).is_none() {
                    continue;
                }
                for (n, (a, d)) in s.increments.iter().zip(&ddm.increments).enumerate() {
                    if flagged.get(n).copied().unwrap_or(false) {
                        continue;
                    }
                    compared += 1;
                    let e = (a.derivatives[r][k] - d.derivatives[r][k]).abs();
                    if a.bar_bounds(r, k, e) {
                        bounded += 1;
                    }
                }
            }
            let error = increment_errors(ddm, s, k, p.value, floor, flagged)
                .map_or(0.0, |e| e.into_iter().flatten().fold(0.0, f64::max));
            let steps = s
                .increments
                .iter()
                .filter_map(|i| i.betas.get(k).copied())
                .fold((f64::INFINITY, 0.0f64), |(lo, hi), b| {
                    (lo.min(b), hi.max(b))
                });
            rows.push(AutoRow {
                method: s.method.map_or("?", |m| m.name()).to_string(),
                param: p.name.clone(),
                bounded,
                compared,
                error,
                steps,
            });
        }
    }
    rows
}

/// A row of the table with its scene and the sweep's best `(beta, error)` for its method and
/// parameter.
pub(super) type SceneRow<'a> = (&'a str, &'a AutoRow, Option<(f64, f64)>);

/// The subsection, from every scene's rows and each row's best error over the sweep.
pub(super) fn write_auto(s: &mut String, rows: &[SceneRow<'_>]) {
    let _ = writeln!(s, "\n### Choosing the step: `--beta auto`\n");
    let _ = writeln!(
        s,
        "`--beta auto` chooses each parameter's step at every increment from a ladder of SDM probes at the fixed state (1e-1 to 1e-10 forward, 1e-1 to 1e-7 central: the largest pair of neighbouring probes that agree to the round-off they expect, where their differences stop shrinking, else the better of the pair that agrees best: its smaller step where the differences shrink into it at the method's order; the round-off from the forces that cancel, the reference force and the friction penalty times the positions; a response whose probe is within its round-off of zero and that shows no plateau, a derivative that is zero, is left out of the choice; the history derivative the increment carries on has its own step by the same rule on its own differences, its round-off machine precision times the history over the step plus the unbalance's carried through the solve, taken where it is smaller than the responses': the responses do not show a truncation that only the history carries on) and gives every derivative an error bar: twice the sum of the difference from a shadow run at a tenth of each step and the round-off SDM expects in both runs (the chosen error is at most that difference plus the shadow's error). FDM and FDM central apply the same rule to reruns at every step of their ladders (1e-1 to 1e-8), keeping to the steps whose reruns are in the nominal run's contact states and Gauss point branches at the increment (where the nominal state lies within a step of a switch, reruns on either side cross it and their secants can agree), the bar from the next step down and the noise of the Newton residual both reruns reached (left out on the scenes whose FDM sweep is reduced; `validate --full` runs them). The target: a finite bar bounds the true error (against DDM) for at least 95 % of the derivatives (unflagged increments, responses sensitive to the parameter), and the largest error is within a factor 10 of the sweep's best fixed beta.\n"
    );
    let _ = writeln!(
        s,
        "| scene | parameter | method | bars that bound the error | largest error | sweep's best (beta) | steps chosen |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    let (mut met, mut within) = (0, 0);
    for (scene, r, best) in rows {
        let share = if r.compared == 0 {
            f64::NAN
        } else {
            r.bounded as f64 / r.compared as f64
        };
        met += usize::from(share >= 0.95);
        within += usize::from(best.is_some_and(|(_, e)| r.error <= 10.0 * e));
        let _ = writeln!(
            s,
            "| {scene} | {} | {} | {} of {} ({:.1} %) | {:.1e} | {} | {:.0e} .. {:.0e} |",
            r.param,
            r.method,
            r.bounded,
            r.compared,
            100.0 * share,
            r.error,
            best.map_or("-".to_string(), |(b, e)| format!("{e:.1e} ({b:.0e})")),
            r.steps.1,
            r.steps.0
        );
    }
    let _ = writeln!(
        s,
        "\nOf {} rows, {met} meet the 95 % target and {within} have their largest error within a factor 10 of the sweep's best.\n",
        rows.len()
    );
}
