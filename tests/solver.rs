//! Newton under prescribed displacements: the consistent predictor linearises about the last
//! converged state, so increments of a prescribed tip displacement on a plastic cantilever need
//! no cutbacks (starting from a state in which only the tip nodes have moved distorts the last
//! element layer, yields it spuriously and inverts elements).

use fricsens::scene::{cantilever, CantileverSpec, Component, MaterialSpec, PrescribedSpec};
use fricsens::solver::{NoObserver, RunOptions, Solver};

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
    scene.bodies[0].material = MaterialSpec::J2 {
        young: 200e3,
        nu: 0.3,
        sigma_y: 250.0,
        hardening: 200.0,
        sigma_inf: None,
        delta: None,
    };
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
    let mut solver = Solver::new(&model).unwrap();
    let res = solver.run(&RunOptions::default(), &mut NoObserver).unwrap();
    let cutbacks: usize = res.records.iter().map(|r| r.cutbacks).sum();
    let iterations: Vec<usize> = res.records.iter().map(|r| r.iterations).collect();
    println!("iterations per increment {iterations:?}, cutbacks {cutbacks}");
    assert_eq!(res.records.len(), 8, "sub-increments were needed");
    assert_eq!(cutbacks, 0);
    // plasticity did develop (the test is about a plastic path)
    assert!(res.history.iter().skip(6).step_by(7).any(|a| *a > 0.0));
}
