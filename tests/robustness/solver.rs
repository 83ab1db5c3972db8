//! Newton under prescribed displacements: the consistent predictor linearises about the last
//! converged state, so increments of a prescribed tip displacement on a plastic cantilever need
//! no cutbacks (starting from a state in which only the tip nodes have moved distorts the last
//! element layer, yields it spuriously and inverts elements).

use crate::common::solve;

use fricsens::material::{J2Plasticity, Material};
use fricsens::scene::{cantilever, CantileverSpec, Component, PrescribedSpec};

#[test]
fn displacement_controlled_plastic_cantilever_needs_no_cutback() {
    let spec = CantileverSpec {
        length: 10.0,
        height: 1.0,
        width: 1.0,
        nx: 20,
        ny: 2,
        young: 200e3,
        nu: 0.3,
        increments: 8,
        ..CantileverSpec::large_deflection()
    };
    let mut scene = cantilever(&spec);
    scene.bodies[0].material = Material::J2(J2Plasticity::linear(200e3, 0.3, 250.0, 200.0));
    scene.loads.clear();
    // tip deflection 3x the first-yield deflection of beam theory, w_y = 2 sigma_y L^2 / (3 E h)
    let w_yield = 2.0 * 250.0 * 10.0f64.powi(2) / (3.0 * 200e3 * 1.0);
    scene.prescribed.push(PrescribedSpec {
        name: "tip".into(),
        set: "beam.xmax".into(),
        components: vec![Component::Y],
        value: -3.0 * w_yield,
        amplitude: vec![(0.0, 0.0), (1.0, 1.0)],
    });
    let model = scene.build().unwrap();
    let res = solve(&model);
    let cutbacks: usize = res.records.iter().map(|r| r.cutbacks).sum();
    let iterations: Vec<usize> = res.records.iter().map(|r| r.iterations).collect();
    println!("iterations per increment {iterations:?}, cutbacks {cutbacks}");
    assert_eq!(res.records.len(), 8, "sub-increments were needed");
    assert_eq!(cutbacks, 0);
    // plasticity did develop (the test is about a plastic path)
    assert!(res.history.iter().skip(6).step_by(7).any(|a| *a > 0.0));
}

/// A force tolerance below the residual's round-off floor. The leaf spring's free residual does
/// not fall below about 1e-8 N at any refinement (gaps and slips are computed from coordinates
/// of 100 mm), so at `force_tol` 1e-15 the force criterion can never be met. Newton must stop
/// at the floor by the round-off criterion (the positions' correction below 64 eps |X + u|)
/// instead of cutting the increment back until the analysis fails, and stop at the state the
/// default tolerance reaches.
#[test]
fn a_force_tolerance_below_the_round_off_floor_converges_at_the_floor() {
    use fricsens::studies::scaling::ScalingScene;
    let model = ScalingScene::LeafSpring
        .scene(1.0)
        .unwrap()
        .build()
        .unwrap();
    let mut tight = model.clone();
    tight.solver.force_tol = 1e-15;
    tight.solver.energy_tol = 1e-40;
    let run = |m: &fricsens::model::Model| solve(m);
    let (nominal, floor) = (run(&model), run(&tight));
    assert_eq!(floor.times, nominal.times, "the tight run cut back");
    let n_nodal = 3 * model.mesh.n_nodes();
    for (inc, (a, b)) in nominal.states.iter().zip(&floor.states).enumerate().skip(1) {
        let scale = a[..n_nodal].iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let diff = a[..n_nodal]
            .iter()
            .zip(&b[..n_nodal])
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        println!("increment {inc}: max |u| {scale:.3e}, max difference {diff:.3e}");
        // the nominal run's force residual is 1e-9 of the reference force: its displacements
        // are that accurate relative to their scale, times the tangent's conditioning between
        // the force and displacement norms (1e3 allowed)
        assert!(
            diff <= 1e-6 * scale,
            "increment {inc}: {diff:e} against {scale:e}"
        );
    }
    for r in &floor.records {
        let last = *r.residuals.last().unwrap();
        // the floor, not the nominal tolerance, is where the tight run stopped
        assert!(last > 1e-15 * r.reference_force, "{last:e}");
    }
}
