//! The Taylor test (`fricsens::studies::validate::taylor`): with DDM's derivative the
//! remainder `|f(b + h) - f(b) - h f'|` of reruns falls as `h^2`, with `f' = 0` as `h`.

use crate::common;
use fricsens::prelude::*;
use fricsens::sensitivity::Method;
use fricsens::studies::validate::taylor::{log_slope, taylor_rows, TAYLOR_BETAS};

/// DDM and forward FDM at the Taylor betas of `scene` for `names`, and its Taylor rows.
fn rows(scene: Scene, names: &[&str]) -> Vec<fricsens::studies::validate::taylor::TaylorRow> {
    let model = scene.build().unwrap();
    let params = common::params(&model, names);
    let ddm = common::sensitivities(&model, &params, Method::Ddm, 0.0);
    let sweeps: Vec<_> = TAYLOR_BETAS
        .iter()
        .map(|b| common::sensitivities(&model, &params, Method::Fdm, *b))
        .collect();
    let flagged: Vec<bool> = ddm.increments.iter().map(|i| !i.kinks.is_empty()).collect();
    taylor_rows(&scene.name, &ddm, &sweeps, &params, &flagged, 1e-6)
}

#[test]
fn the_remainder_falls_as_h_squared_with_ddm_and_as_h_without_a_derivative() {
    // smooth responses nonlinear in E: the elastica (large rotations) and the small-strain
    // beam (its tip deflection ~ 1/E)
    for (scene, names) in [
        (Scene::load("cantilever").unwrap(), vec!["E"]),
        (Scene::load("cantilever-small").unwrap(), vec!["E"]),
    ] {
        let name = scene.name.clone();
        for t in rows(scene, &names) {
            assert_eq!(t.h.len(), TAYLOR_BETAS.len(), "{name}: every rerun used");
            assert!(!t.linear, "{name}: {} is not linear in E", t.response);
            // three decades, each quadratic: R falls by 100 per decade of h (within 25 %:
            // the third-order term at beta = 1e-1)
            for w in t.exact.windows(2) {
                let ratio = w[0] / w[1];
                assert!(
                    (75.0..=125.0).contains(&ratio),
                    "{name} {}: R ratio {ratio} per decade, {:?}",
                    t.param,
                    t.exact
                );
            }
            assert!(
                (t.slope_exact - 2.0).abs() <= 0.05,
                "{name}: {}",
                t.slope_exact
            );
            assert!(
                (t.slope_zeroth - 1.0).abs() <= 0.05,
                "{name}: {}",
                t.slope_zeroth
            );
        }
    }
}

#[test]
fn log_slopes_are_fitted_by_least_squares() {
    let x = [1e-1, 1e-2, 1e-3];
    assert!((log_slope(&x, &x.map(|h| 3.0 * h * h)) - 2.0).abs() < 1e-12);
    assert!((log_slope(&x, &x.map(|h| 0.5 * h)) - 1.0).abs() < 1e-12);
    assert!(log_slope(&x[..1], &[1.0]).is_nan());
    // points with a zero remainder carry no slope
    assert!((log_slope(&x, &[1e-2, 0.0, 1e-6]) - 2.0).abs() < 1e-12);
}

#[test]
fn a_response_linear_in_the_parameter_is_told_apart() {
    // uniaxial St Venant-Kirchhoff under a prescribed stretch: the force is E times a
    // function of the stretch, so its remainder is round-off at every step
    for t in rows(Scene::load("uniaxial-svk").unwrap(), &["E"]) {
        assert!(t.linear, "{}: {:?}", t.response, t.exact);
        assert!((t.slope_zeroth - 1.0).abs() <= 1e-6);
    }
}

#[test]
fn a_derivative_with_a_finite_difference_error_falls_only_as_h() {
    // central FDM at beta = 0.3 on the small-strain beam in E (tip deflection ~ 1/E): its
    // derivative is off by beta^2 / (1 - beta^2) = 9.9 %, so once h is well below 0.1 b the
    // remainder with it falls as h (h e |f'|), not h^2
    let scene = Scene::load("cantilever-small").unwrap();
    let model = scene.build().unwrap();
    let params = common::params(&model, &["E"]);
    let ddm = common::sensitivities(&model, &params, Method::Ddm, 0.0);
    let mut sweeps: Vec<_> = TAYLOR_BETAS
        .iter()
        .map(|b| common::sensitivities(&model, &params, Method::Fdm, *b))
        .collect();
    sweeps.push(common::sensitivities(
        &model,
        &params,
        Method::FdmCentral,
        0.3,
    ));
    let flagged = vec![false; ddm.increments.len()];
    let rows = taylor_rows(&scene.name, &ddm, &sweeps, &params, &flagged, 0.3);
    let t = &rows[0];
    assert_eq!(t.methods.len(), 1);
    let m = &t.methods[0];
    assert_eq!(m.method, "fdm-central");
    let n = t.h.len();
    // the last step (beta 1e-3 -> 1e-4): R = h |f'| |beta_h - 0.099|, slope 1 - 0.004
    let last = log_slope(&t.h[n - 2..], &m.remainder[n - 2..]);
    assert!((last - 1.0).abs() <= 0.02, "last-step slope {last}");
    // and DDM's on the same steps stays 2
    let exact = log_slope(&t.h[n - 2..], &t.exact[n - 2..]);
    assert!((exact - 2.0).abs() <= 0.02, "DDM's last-step slope {exact}");
}
