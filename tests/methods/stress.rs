//! A response that reads element stresses (a component and the von Mises stress of one element's
//! volume-averaged Cauchy stress) is differentiated by every method: DDM equals central finite
//! differences of reruns within their own error estimate, and SDM (forward and central) equals
//! DDM within its perturbation error. One element yields, one stays elastic: the elastic one is
//! the element the sensitivity engine's element mask would leave out of the history update had
//! the response not declared that it reads it ([`fricsens::response::Reads`]): without the
//! declaration, the clamp element, elastic again after the unloading, is left out and its
//! d(von Mises)/d(sigma_y) comes out 0 against FDM's -0.85 at the last increment.

use crate::common::params;

use fricsens::response::StressMeasure;
use fricsens::scene::{ResponseSpec, Scene};
use fricsens::sensitivity::{run_sensitivity, Method, SensitivityResults, Settings};

/// The J2 beam of `methods` (10 x 4 x 4 plain hex8, clamped, tip pushed down 5 in 15
/// increments, then back to 3), with stress responses of a clamp element (plastic) and an
/// element near the tip and the neutral axis (elastic), beside its tip force.
fn beam_with_stress_responses() -> Scene {
    let mut scene = crate::methods::j2_beam();
    for (name, element, measure) in [
        ("clamp-mises", 0, StressMeasure::VonMises),
        ("clamp-sxx", 0, StressMeasure::Xx),
        ("tip-sxy", 59, StressMeasure::Xy),
    ] {
        scene.responses.push(ResponseSpec::Stress {
            name: name.into(),
            body: "beam".into(),
            element,
            measure,
        });
    }
    scene
}

const NAMES: [&str; 2] = ["sigma_y", "E"];

/// The largest |a - b| over the estimate `estimate(r, p, k)`, over every response, parameter
/// and increment; panics (naming them) where it is above one.
fn worst_over(
    what: &str,
    a: &SensitivityResults,
    b: &SensitivityResults,
    estimate: impl Fn(usize, usize, usize) -> f64,
) -> f64 {
    let mut worst: f64 = 0.0;
    for (r, name) in a.responses.iter().enumerate() {
        for (p, param) in NAMES.iter().enumerate() {
            for k in 0..a.increments.len() {
                let (x, y) = (
                    a.increments[k].derivatives[r][p],
                    b.increments[k].derivatives[r][p],
                );
                let e = estimate(r, p, k);
                let err = (x - y).abs();
                worst = worst.max(err / e);
                assert!(
                    err <= e,
                    "{what}: d({name})/d({param}) at increment {k}: {x:e} against {y:e}, |difference| {err:.2e} above the estimate {e:.2e}"
                );
            }
        }
    }
    worst
}

#[test]
fn stress_responses_are_differentiated_by_every_method() {
    let scene = beam_with_stress_responses();
    let model = scene.build().unwrap();
    // reruns converged to 1e-13, so that their round-off is below the truncation error the
    // comparison estimates
    let mut tight = scene.clone();
    tight.solver.force_tol = 1e-13;
    let tight = tight.build().unwrap();
    let params = params(&model, &NAMES);
    let (res, ddm) = run_sensitivity(&tight, &params, &Settings::default()).unwrap();
    // the clamp element yields, the element near the tip does not
    let at = |e: usize| &res.branches.last().unwrap()[8 * e..8 * e + 8];
    assert!(
        res.branches.iter().any(|b| b[..8]
            .iter()
            .any(|g| *g != fricsens::material::Branch::Elastic)),
        "the clamp element must yield"
    );
    assert!(
        res.branches.iter().all(|b| b[8 * 59..8 * 60]
            .iter()
            .all(|g| *g == fricsens::material::Branch::Elastic)),
        "element 59 must stay elastic ({:?})",
        at(59)
    );
    let run = |method: Method, beta: f64| {
        let s = Settings {
            method,
            beta,
            ..Settings::default()
        };
        let (r, d) = run_sensitivity(&tight, &params, &s).unwrap();
        assert_eq!(r.times, res.times, "the rerun takes DDM's increments");
        d
    };
    // DDM against central FDM of reruns at steps h and 2h: the truncation error is estimated by
    // their difference, the round-off by the rerun tolerance over the step
    let h = 1e-4;
    let (f1, f2) = (run(Method::FdmCentral, h), run(Method::FdmCentral, 2.0 * h));
    let force_tol = tight.solver.force_tol;
    let fdm_estimate = |r: usize, p: usize, k: usize| {
        let truncation =
            (f1.increments[k].derivatives[r][p] - f2.increments[k].derivatives[r][p]).abs();
        let size = f1.increments[k].values[r].abs();
        // the last term is DDM's own accuracy: its sensitivity solve is converged to 1e-13 of
        // the solution (the default exact tangent), so 1e-12 of the response's logarithmic
        // scale size / b bounds it; it matters only where truncation and round-off vanish (the
        // first, elastic increments, where FDM of a linear response is exact)
        truncation + force_tol * size / (h * params[p].value) + 1e-12 * size / params[p].value
    };
    // measured: the largest |DDM - FDM| is 0.64 of the estimate
    worst_over("DDM vs central FDM", &ddm, &f1, fdm_estimate);
    // SDM, forward and central, against DDM: estimated the same way from two steps
    for method in [Method::Sdm, Method::SdmCentral] {
        let (s1, s2) = (run(method, h), run(method, 2.0 * h));
        let estimate = |r: usize, p: usize, k: usize| {
            let truncation =
                (s1.increments[k].derivatives[r][p] - s2.increments[k].derivatives[r][p]).abs();
            let size = s1.increments[k].values[r].abs();
            // twice the truncation estimate: the forward difference's error at h is about
            // |s(h) - s(2h)|, the factor two covers the next order; SDM's round-off (the
            // unbalance evaluated to eps of its size, over the step, amplified by the solve) is
            // written as 1e3 eps: far below the truncation at h = 1e-4 (the measured worst ratio
            // is 0.5 with or without it)
            2.0 * truncation + 1e3 * f64::EPSILON * size / (h * params[p].value)
        };
        // measured: 0.50 (forward) and 0.30 (central) of the estimate
        worst_over(method.name(), &s1, &ddm, estimate);
    }
    // the derivatives are not trivially zero: sigma_y moves the clamp element's stress
    let d = ddm.derivative("clamp-mises", "sigma_y").unwrap();
    assert!(
        d.iter().any(|v| v.abs() > 1e-3),
        "d(mises)/d(sigma_y) = {d:?}"
    );
}
