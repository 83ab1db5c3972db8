//! Solving a model with the default options, and the assembled tangent against the dual-number
//! derivative of the residual.

use fricsens::assembly::{Assembler, Evaluation};
use fricsens::linalg::SparseMatrix;
use fricsens::material::Branch;
use fricsens::model::Model;
use fricsens::scene::Scene;
use fricsens::solver::{AnalysisError, NoObserver, Results, RunOptions, Solver};
use num_dual::Dual64;

/// `model` solved along its whole path with the default run options.
pub fn try_solve(model: &Model) -> Result<Results, AnalysisError> {
    Solver::new(model)?.run(&RunOptions::default(), &mut NoObserver)
}

/// `model` solved along its whole path with the default run options; panics if it fails.
pub fn solve(model: &Model) -> Results {
    Solver::new(model)
        .expect("solver")
        .run(&RunOptions::default(), &mut NoObserver)
        .expect("converges")
}

/// `scene` built and solved with the default run options.
pub fn solve_scene(scene: Scene) -> (Model, Results) {
    let model = scene.build().expect("scene builds");
    let res = solve(&model);
    (model, res)
}

/// The assembled residual and tangent of `model` at `(z, hist, t)` in `f64`, and the residual
/// again in `Dual64` with `z` seeded along `v`.
pub struct Directional {
    /// The `f64` evaluation (residual, branches, contact choices).
    pub ev: Evaluation<f64>,
    /// The `Dual64` evaluation: its residual's `eps` parts are `dR(z + s v)/ds`.
    pub dual: Evaluation<Dual64>,
    /// `K v` with the assembled tangent `K`.
    pub kv: Vec<f64>,
}

/// Evaluate `model` at `(z, hist, t)` with the tangent and, in dual numbers, along `v`.
pub fn directional(model: &Model, z: &[f64], hist: &[f64], t: f64, v: &[f64]) -> Directional {
    let asm = Assembler::new(model, &[]).unwrap();
    let ne = model.mesh.n_elements();
    let mut k = SparseMatrix::new(asm.pattern.clone());
    let mut ev = Evaluation::<f64>::new(&asm, ne);
    let lifted = model.lifted::<f64>(&[]);
    asm.evaluate(model, &lifted, z, hist, t, None, Some(&mut k), &mut ev)
        .unwrap();
    let zd: Vec<Dual64> = z.iter().zip(v).map(|(a, b)| Dual64::new(*a, *b)).collect();
    let hd: Vec<Dual64> = hist.iter().map(|h| Dual64::from(*h)).collect();
    let mut dual = Evaluation::<Dual64>::new(&asm, ne);
    let lifted_d = model.lifted::<Dual64>(&[]);
    asm.evaluate(model, &lifted_d, &zd, &hd, t, None, None, &mut dual)
        .unwrap();
    let mut kv = vec![0.0; z.len()];
    k.mul_vec(v, &mut kv).unwrap();
    Directional { ev, dual, kv }
}

/// The consistent tangent of a whole model against the dual-number derivative of its residual,
/// at the last converged state of a run of `model` (its `times` as given).
pub struct TangentCheck {
    /// Largest `|dR(z + s v)/ds - K v|` over the unknowns, relative to the largest `|K v|`.
    pub mismatch: f64,
    /// Gauss points on the plastic branch at that state.
    pub plastic: usize,
}

/// Run `model`, then compare `K v` with the derivative of the residual along a fixed
/// direction `v` (size `amplitude`), evaluated with `Dual64` at the last converged state.
pub fn tangent_check(model: &Model, amplitude: f64) -> TangentCheck {
    let res = solve(model);
    let k_inc = res.states.len() - 1;
    let t = res.times[k_inc];
    let (z, hist) = (&res.states[k_inc], &res.histories[k_inc - 1]);
    let v: Vec<f64> = (0..z.len())
        .map(|i| amplitude * ((i as f64) * 0.61).cos())
        .collect();
    let d = directional(model, z, hist, t, &v);
    let plastic =
        d.ev.branches
            .iter()
            .filter(|b| **b == Branch::Plastic)
            .count();
    let scale = d.kv.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let mismatch = d
        .dual
        .residual
        .iter()
        .zip(&d.kv)
        .fold(0.0f64, |m, (r, kvi)| m.max((r.eps - kvi).abs()))
        / scale;
    TangentCheck { mismatch, plastic }
}
