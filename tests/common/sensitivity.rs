//! Design parameters by name and sensitivities by one method with the settings spelled out.

use fricsens::model::Model;
use fricsens::sensitivity::{
    run_sensitivity, Method, Parameter, SensitivityResults, Settings, TangentChoice,
};

/// The named design parameters of `model` (panics on an unknown name).
pub fn params(model: &Model, names: &[&str]) -> Vec<Parameter> {
    names
        .iter()
        .map(|n| Parameter::by_name(model, n).unwrap())
        .collect()
}

/// Default settings but for the method, the relative perturbation `beta` and the tangent.
pub fn settings(method: Method, beta: f64, tangent: TangentChoice) -> Settings {
    Settings {
        method,
        beta,
        tangent,
        ..Settings::default()
    }
}

/// Sensitivities of `model` for `params` by `method` (at relative perturbation `beta`),
/// solving with the tangent at the converged state.
pub fn sensitivities(
    model: &Model,
    params: &[Parameter],
    method: Method,
    beta: f64,
) -> SensitivityResults {
    let settings = settings(method, beta, TangentChoice::Exact);
    run_sensitivity(model, params, &settings).unwrap().1
}

/// Sensitivities of `model` for the named parameters by `method` (at relative perturbation
/// `beta`), solving with the tangent at the converged state.
pub fn sens(model: &Model, names: &[&str], method: Method, beta: f64) -> SensitivityResults {
    sensitivities(model, &params(model, names), method, beta)
}

/// Sensitivities of `model` for the named parameters by `method` (at relative perturbation
/// `beta`), solving with `tangent`.
pub fn sens_tangent(
    model: &Model,
    names: &[&str],
    method: Method,
    beta: f64,
    tangent: TangentChoice,
) -> SensitivityResults {
    let settings = settings(method, beta, tangent);
    run_sensitivity(model, &params(model, names), &settings)
        .unwrap()
        .1
}

/// DDM and central FDM (beta = 1e-6) of `model` for the named parameters, both solving with
/// the tangent at the converged state.
pub fn ddm_and_central_fdm(
    model: &Model,
    names: &[&str],
) -> (Vec<Parameter>, SensitivityResults, SensitivityResults) {
    let params = params(model, names);
    let ddm = sensitivities(model, &params, Method::Ddm, 0.0);
    let fdm = sensitivities(model, &params, Method::FdmCentral, 1e-6);
    (params, ddm, fdm)
}

/// The largest difference between `other`'s and `reference`'s derivatives in parameter `p`
/// over the responses `compared` and every increment, relative to the largest `|derivative|`
/// of `reference` over the responses `scaled_by`; and that scale.
pub fn worst_difference(
    reference: &SensitivityResults,
    other: &SensitivityResults,
    compared: &[usize],
    scaled_by: &[usize],
    p: usize,
) -> (f64, f64) {
    let scale = (reference.increments.iter())
        .flat_map(|i| scaled_by.iter().map(move |r| i.derivatives[*r][p].abs()))
        .fold(0.0f64, f64::max);
    let worst = (reference.increments.iter().zip(&other.increments))
        .flat_map(|(a, b)| {
            (compared.iter()).map(move |r| (a.derivatives[*r][p] - b.derivatives[*r][p]).abs())
        })
        .fold(0.0f64, f64::max);
    (worst / scale, scale)
}

/// Taylor remainders `|f(b + h d) - f(b) - h df.d|` of response `r` at the increment `at`
/// (its values and derivatives in `ps`) for each `h` of `hs`: `d` a fixed pseudo-random
/// direction relative to each parameter's value (no seed to remember), `f(b + h d)` a rerun
/// of the model with every target of every parameter set.
pub fn taylor_remainders(
    model: &Model,
    ps: &[Parameter],
    at: &fricsens::sensitivity::IncrementSensitivity,
    r: usize,
    hs: &[f64],
) -> Vec<f64> {
    let d: Vec<f64> = (0..ps.len())
        .map(|k| ((k as f64 + 1.0) * 0.754_877_666).fract() - 0.5)
        .collect();
    let slope: f64 = (0..ps.len())
        .map(|k| at.derivatives[r][k] * d[k] * ps[k].value)
        .sum();
    let rerun = |h: f64| -> f64 {
        let mut m = model.clone();
        for (k, p) in ps.iter().enumerate() {
            for t in &p.targets {
                m.set_param(*t, p.value * (1.0 + h * d[k]));
            }
        }
        let res = fricsens::solver::Solver::new(&m)
            .unwrap()
            .run(&Default::default(), &mut fricsens::solver::NoObserver)
            .unwrap();
        let n = res
            .increment_at(at.time)
            .expect("the rerun ends where the nominal does");
        res.response_value(&m, r, n)
    };
    let f0 = at.values[r];
    let rem: Vec<f64> = hs
        .iter()
        .map(|&h| (rerun(h) - f0 - h * slope).abs())
        .collect();
    eprintln!("Taylor remainders {rem:?} (slope {slope:e})");
    rem
}
