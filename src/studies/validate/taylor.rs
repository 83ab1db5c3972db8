//! The Taylor test of the derivatives, as gradient checks are reported in the adjoint
//! literature: with `f'` the derivative under test, the remainder
//! `R(h) = |f(b + h) - f(b) - h f'|` falls as `h^2` when `f'` is the derivative of `f` at `b`
//! and only as `h` when it is not (shown with `f' = 0`, the zeroth-order remainder).
//!
//! `f(b + h)` comes from the sweep's forward FDM reruns (`h = beta b`, [`Parameter::step`]): their
//! derivative `D_h = (f(b + h) - f(b)) / h` gives `R(h) = h |D_h - f'|` without storing the
//! reruns' values. `f'` is DDM's. Per scene and parameter one response and increment is
//! tested: the one most sensitive to the parameter (largest `|b f'| / max|f|` over the
//! unflagged increments). A rerun that took extra sub-increments at that increment, or failed,
//! leaves its beta out.

use crate::design::Parameter;
use crate::sensitivity::{Method, SensitivityResults};

/// The betas whose remainders the slopes are fitted over: large enough that truncation
/// dominates the reruns' Newton noise (1e-9 of the response), small enough to stay in the
/// quadratic range of a smooth response.
pub const TAYLOR_BETAS: [f64; 4] = [1e-1, 1e-2, 1e-3, 1e-4];

/// The Taylor test of one parameter of one scene.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct TaylorRow {
    /// Scene name.
    pub scene: String,
    /// Design parameter.
    pub param: String,
    /// The response tested.
    pub response: String,
    /// Its increment (1-based).
    pub increment: usize,
    /// The steps `h` (absolute) of the reruns used, decreasing.
    pub h: Vec<f64>,
    /// `|f(b + h) - f(b) - h f'|` with DDM's `f'`, per step.
    pub exact: Vec<f64>,
    /// `|f(b + h) - f(b)|`, per step (the remainder with `f' = 0`).
    pub zeroth: Vec<f64>,
    /// Least-squares slope of `log R` against `log h` with DDM's `f'` (2 for a right
    /// derivative of a smooth response; NaN with fewer than two usable steps).
    pub slope_exact: f64,
    /// The same with `f' = 0` (1).
    pub slope_zeroth: f64,
    /// The response is linear in the parameter: its remainder is round-off at every step
    /// (below 1e-10 of the zeroth-order one), so its slope says nothing.
    pub linear: bool,
    /// The remainders with each other method's `f'` at the report's figure beta (SDM, SDM
    /// central, FDM central): they fall as `h^2` while the method's error `e` is below the
    /// remainder's `h f''/2`, and as `h` where `h e` takes over.
    pub methods: Vec<MethodTaylor>,
}

/// The Taylor remainders with one method's derivative.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct MethodTaylor {
    /// The method (`sdm`, `sdm-central`, `fdm-central`).
    pub method: String,
    /// `|f(b + h) - f(b) - h f'|` with its `f'`, per step of [`TaylorRow::h`].
    pub remainder: Vec<f64>,
    /// The least-squares slope of `log R` against `log h`.
    pub slope: f64,
}

/// Least-squares slope of `log y` against `log x` over the points with `y > 0`.
pub fn log_slope(x: &[f64], y: &[f64]) -> f64 {
    let pts: Vec<(f64, f64)> = (x.iter().zip(y))
        .filter(|(a, b)| **a > 0.0 && **b > 0.0 && b.is_finite())
        .map(|(a, b)| (a.ln(), b.ln()))
        .collect();
    if pts.len() < 2 {
        return f64::NAN;
    }
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    sxy / sxx
}

/// The Taylor rows of one scene: DDM's derivatives `ddm` against the forward FDM reruns among
/// `sweeps`, for each parameter of `params` (`flagged`: DDM's non-differentiable increments,
/// left out); the other methods' derivatives at `figure_beta` among `sweeps` are tested too.
pub fn taylor_rows(
    scene: &str,
    ddm: &SensitivityResults,
    sweeps: &[SensitivityResults],
    params: &[Parameter],
    flagged: &[bool],
    figure_beta: f64,
) -> Vec<TaylorRow> {
    let others: Vec<&SensitivityResults> = [Method::Sdm, Method::SdmCentral, Method::FdmCentral]
        .iter()
        .filter_map(|m| {
            (sweeps.iter())
                .find(|s| s.method == Some(*m) && (s.beta / figure_beta - 1.0).abs() < 1e-9)
        })
        .collect();
    let mut fdm: Vec<&SensitivityResults> = (sweeps.iter())
        .filter(|s| s.method == Some(Method::Fdm))
        .filter(|s| TAYLOR_BETAS.iter().any(|b| (s.beta / b - 1.0).abs() < 1e-9))
        .collect();
    fdm.sort_by(|a, b| b.beta.total_cmp(&a.beta));
    let mut rows = Vec::new();
    for (p, param) in params.iter().enumerate() {
        // the most sensitive response and increment
        let mut best: Option<(f64, usize, usize)> = None;
        for r in 0..ddm.responses.len() {
            let size = (ddm.increments.iter()).fold(0.0f64, |m, i| m.max(i.values[r].abs()));
            if size == 0.0 {
                continue;
            }
            for (n, inc) in ddm.increments.iter().enumerate() {
                if flagged.get(n).copied().unwrap_or(false) {
                    continue;
                }
                let relative = (param.step(1.0) * inc.derivatives[r][p]).abs() / size;
                if relative.is_finite() && best.is_none_or(|(m, _, _)| relative > m) {
                    best = Some((relative, r, n));
                }
            }
        }
        let Some((_, r, n)) = best else { continue };
        let exact_derivative = ddm.increments[n].derivatives[r][p];
        let derivative_of = |s: &SensitivityResults| {
            (s.increments.get(n)).map_or(f64::NAN, |inc| inc.derivatives[r][p])
        };
        let other_derivatives: Vec<f64> = others.iter().map(|s| derivative_of(s)).collect();
        let mut with_other: Vec<Vec<f64>> = vec![Vec::new(); others.len()];
        let (mut h, mut exact, mut zeroth) = (Vec::new(), Vec::new(), Vec::new());
        for s in &fdm {
            let Some(inc) = s.increments.get(n) else {
                continue;
            };
            let d = inc.derivatives[r][p];
            if !d.is_finite() || inc.rerun_substeps.get(p).copied().unwrap_or(false) {
                continue;
            }
            let step = param.step(s.beta).abs();
            h.push(step);
            exact.push(step * (d - exact_derivative).abs());
            zeroth.push(step * d.abs());
            for (w, o) in with_other.iter_mut().zip(&other_derivatives) {
                w.push(step * (d - o).abs());
            }
        }
        let largest = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(*x));
        let linear = largest(&exact) <= 1e-10 * largest(&zeroth);
        rows.push(TaylorRow {
            linear,
            scene: scene.to_string(),
            param: param.name.clone(),
            response: ddm.responses[r].clone(),
            increment: ddm.increments[n].increment,
            slope_exact: log_slope(&h, &exact),
            slope_zeroth: log_slope(&h, &zeroth),
            methods: (others.iter().zip(with_other))
                .map(|(s, remainder)| MethodTaylor {
                    method: s.method.map_or("?", |m| m.name()).to_string(),
                    slope: log_slope(&h, &remainder),
                    remainder,
                })
                .collect(),
            h,
            exact,
            zeroth,
        });
    }
    rows
}
