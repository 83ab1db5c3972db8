//! Cantilever beams against beam theory and the elastica (shared/oracles.md section 3).

// Index loops over responses, parameters and unknowns read like the formulas they check.
#![allow(clippy::needless_range_loop)]

use crate::common::solve_scene;

use fricsens::element::{Formulation, Kinematics};
use fricsens::scene::{cantilever, CantileverSpec};
use fricsens::solver::Results;

fn run(spec: &CantileverSpec) -> (fricsens::model::Model, Results) {
    solve_scene(cantilever(spec))
}

fn response(model: &fricsens::model::Model, res: &Results, name: &str, inc: usize) -> f64 {
    let r = model.responses.iter().position(|r| r.name == name).unwrap();
    res.response_value(model, r, inc)
}

#[test]
fn small_deflection_matches_beam_theory_with_incompatible_modes() {
    let spec = CantileverSpec::small_deflection();
    let (model, res) = run(&spec);
    let w = -response(&model, &res, "tip-deflection", 1);
    let p = spec.load();
    let exact = p * spec.length.powi(3) / (3.0 * spec.young * spec.inertia());
    let err = (w - exact).abs() / exact;
    println!("incompatible modes: w = {w:.6e}, PL^3/3EI = {exact:.6e}, error {err:.4}");
    // Shear deformation adds (h/L)^2-order flexibility (~0.75 % at L/h = 20 with nu = 0).
    assert!(err < 0.02, "error {err}");
}

#[test]
fn small_deflection_plain_full_integration_locks() {
    let tip = |formulation| {
        let spec = CantileverSpec {
            formulation,
            ..CantileverSpec::small_deflection()
        };
        let (model, res) = run(&spec);
        let w = -response(&model, &res, "tip-deflection", 1);
        let exact = spec.load() * spec.length.powi(3) / (3.0 * spec.young * spec.inertia());
        (w - exact).abs() / exact
    };
    let err_full = tip(Formulation::Full);
    let err_im = tip(Formulation::IncompatibleModes);
    println!("full integration error {err_full:.4}, incompatible modes error {err_im:.5}");
    // Shear locking: fully integrated hex8 with 2 elements through the thickness (aspect ratio
    // 2) is far too stiff; the same mesh with incompatible modes is accurate. This documents
    // why the variant exists.
    assert!(err_full > 0.25, "full integration error {err_full}");
    assert!(err_full > 100.0 * err_im, "{err_full} vs {err_im}");
}

#[test]
fn large_deflection_elastica() {
    // oracles.md section 3, alpha = 1, 2, 5: w/L and u/L
    let table = [
        (1.0, 0.30172, 0.05643),
        (2.0, 0.49346, 0.16064),
        (5.0, 0.71379, 0.38763),
    ];
    let spec = CantileverSpec {
        alpha: 5.0,
        increments: 10,
        ..CantileverSpec::large_deflection()
    };
    let (model, res) = run(&spec);
    for (alpha, w_l, u_l) in table {
        let inc = (alpha / spec.alpha * spec.increments as f64).round() as usize;
        let w = -response(&model, &res, "tip-deflection", inc) / spec.length;
        let u = -response(&model, &res, "tip-shortening", inc) / spec.length;
        println!("alpha {alpha}: w/L {w:.5} (elastica {w_l}), u/L {u:.5} (elastica {u_l})");
        assert!(
            (w - w_l).abs() / w_l < 0.03,
            "alpha {alpha}: w/L {w} vs {w_l}"
        );
        assert!(
            (u - u_l).abs() / u_l < 0.03,
            "alpha {alpha}: u/L {u} vs {u_l}"
        );
    }
    let _ = Kinematics::Large;
}
