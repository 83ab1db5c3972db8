//! Fixtures shared by the element test binaries.
#![allow(dead_code)]

use fricsens::element::hex8;
use fricsens::element::hex8::{Hex8Input, Hex8Output};
use fricsens::element::{Hex8Formulation, Kinematics};
use fricsens::material::{Branch, MaterialLaw};
use fricsens::mesh::{Axis, BlockSpec, Mesh, NodePlace};
use fricsens::model::{Body, Material, Model};
use nalgebra::{Matrix3, Vector3};

pub fn block(name: &str, n: [usize; 3], l: [f64; 3]) -> BlockSpec {
    BlockSpec {
        name: name.into(),
        origin: [0.0; 3],
        x: Axis::uniform(l[0], n[0]),
        y: Axis::uniform(l[1], n[1]),
        z: Axis::uniform(l[2], n[2]),
    }
}

pub fn one_body_model(
    mesh: Mesh,
    material: Material,
    kinematics: Kinematics,
    formulation: Hex8Formulation,
) -> Model {
    Model {
        mesh,
        bodies: vec![Body {
            name: "b".into(),
            block: 0,
            material,
            kinematics,
            formulation,
        }],
        times: vec![1.0],
        ..Model::default()
    }
}

/// A 2x2x2 block whose interior node and some surface nodes are moved off the grid.
pub fn distorted_mesh() -> Mesh {
    let mut mesh = Mesh::default();
    mesh.add_block(block("b", [2, 2, 2], [2.0, 2.0, 2.0]))
        .unwrap();
    let x = mesh.coordinates::<f64>(&mesh.block_geometry());
    for (n, p) in mesh.places.iter_mut().enumerate() {
        let c = x[n];
        // move every node that is not a corner of the cube by a smooth, non-affine offset
        let corner = (0..3).all(|i| c[i] == 0.0 || c[i] == 2.0);
        if !corner {
            let d = Vector3::new(
                0.13 * (c[1] * 1.7).sin() * (c[0] * (2.0 - c[0])).min(1.0),
                -0.11 * (c[2] * 1.3).cos() * (c[1] * (2.0 - c[1])).min(1.0),
                0.09 * (c[0] * 0.9).sin() * (c[2] * (2.0 - c[2])).min(1.0),
            );
            *p = NodePlace::Free([c[0] + d[0], c[1] + d[1], c[2] + d[2]]);
        }
    }
    mesh
}

pub fn boundary_nodes(mesh: &Mesh) -> Vec<usize> {
    let mut v: Vec<usize> = ["xmin", "xmax", "ymin", "ymax", "zmin", "zmax"]
        .iter()
        .flat_map(|s| mesh.node_sets[&format!("b.{s}")].clone())
        .collect();
    v.sort();
    v.dedup();
    v
}

pub fn unit_cube() -> [Vector3<f64>; 8] {
    std::array::from_fn(|a| {
        let xi = hex8::NODE_XI[a];
        Vector3::new(
            0.5 * (xi[0] + 1.0),
            0.5 * (xi[1] + 1.0),
            0.5 * (xi[2] + 1.0),
        )
    })
}

pub struct ElementResult<S> {
    pub force: Vec<S>,
    pub tangent: Vec<S>,
    pub hist_new: Vec<S>,
    pub cauchy: Matrix3<S>,
}

/// One hex8 evaluated with its material's own parameters (no branch imposed).
pub fn element<S: fricsens::scalar::Scalar, M: MaterialLaw>(
    x_ref: &[Vector3<S>; 8],
    dofs: &[Vector3<S>],
    kinematics: Kinematics,
    formulation: Hex8Formulation,
    material: &M,
    hist_old: &[S],
    want_tangent: bool,
) -> ElementResult<S> {
    let nd = 3 * dofs.len();
    let params: Vec<S> = material.params().iter().map(|p| S::lift(*p)).collect();
    let mut force = vec![S::zero(); nd];
    let mut tangent = vec![S::zero(); if want_tangent { nd * nd } else { 0 }];
    let mut hist_new = vec![S::zero(); 8 * material.history_len()];
    let input = Hex8Input {
        x_ref,
        dofs,
        kinematics,
        formulation,
        material,
        params: &params,
        hist_old,
        frozen: None,
    };
    let mut out = Hex8Output {
        force: &mut force,
        tangent: if want_tangent {
            Some(&mut tangent[..])
        } else {
            None
        },
        hist_new: &mut hist_new,
        branches: [Branch::Elastic; 8],
        yield_ratio: [0.0; 8],
        cauchy: Matrix3::zeros(),
        min_det_f: 0.0,
    };
    hex8::evaluate(&input, &mut out).unwrap();
    let cauchy = out.cauchy;
    ElementResult {
        force,
        tangent,
        hist_new,
        cauchy,
    }
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
    use fricsens::assembly::{Assembler, Evaluation};
    use fricsens::linalg::SparseMatrix;
    use fricsens::solver::{NoObserver, RunOptions, Solver};
    use num_dual::Dual64;
    let res = Solver::new(model)
        .unwrap()
        .run(&RunOptions::default(), &mut NoObserver)
        .unwrap();
    let k_inc = res.states.len() - 1;
    let t = res.times[k_inc];
    let (z, hist) = (&res.states[k_inc], &res.histories[k_inc - 1]);
    let asm = Assembler::new(model, &[]).unwrap();
    let ne = model.mesh.elements.len();
    let mut k = SparseMatrix::new(asm.pattern.clone());
    let mut ev = Evaluation::<f64>::new(&asm, ne);
    let lifted = model.lifted::<f64>(&[]);
    asm.evaluate(model, &lifted, z, hist, t, None, Some(&mut k), &mut ev)
        .unwrap();
    let plastic = ev
        .branches
        .iter()
        .filter(|b| **b == Branch::Plastic)
        .count();
    let v: Vec<f64> = (0..z.len())
        .map(|i| amplitude * ((i as f64) * 0.61).cos())
        .collect();
    let zd: Vec<Dual64> = z.iter().zip(&v).map(|(a, b)| Dual64::new(*a, *b)).collect();
    let hd: Vec<Dual64> = hist.iter().map(|h| Dual64::from(*h)).collect();
    let mut evd = Evaluation::<Dual64>::new(&asm, ne);
    let lifted_d = model.lifted::<Dual64>(&[]);
    asm.evaluate(model, &lifted_d, &zd, &hd, t, None, None, &mut evd)
        .unwrap();
    let mut kv = vec![0.0; z.len()];
    k.mul_vec(&v, &mut kv).unwrap();
    let scale = kv.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let mismatch = evd
        .residual
        .iter()
        .zip(&kv)
        .fold(0.0f64, |m, (r, kvi)| m.max((r.eps - kvi).abs()))
        / scale;
    TangentCheck { mismatch, plastic }
}

/// Sensitivities of `model` for the named parameters by `method` (at relative perturbation
/// `beta`), solving with the tangent at the converged state.
pub fn sensitivities(
    model: &Model,
    params: &[fricsens::sensitivity::Parameter],
    method: fricsens::sensitivity::Method,
    beta: f64,
) -> fricsens::sensitivity::SensitivityResults {
    use fricsens::sensitivity::{run_sensitivity, Settings, TangentChoice};
    let settings = Settings {
        method,
        beta,
        tangent: TangentChoice::Exact,
        ..Settings::default()
    };
    run_sensitivity(model, params, &settings).unwrap().1
}

/// DDM and central FDM (beta = 1e-6) of `model` for the named parameters, both solving with
/// the tangent at the converged state.
pub fn ddm_and_central_fdm(
    model: &Model,
    names: &[&str],
) -> (
    Vec<fricsens::sensitivity::Parameter>,
    fricsens::sensitivity::SensitivityResults,
    fricsens::sensitivity::SensitivityResults,
) {
    use fricsens::sensitivity::{Method, Parameter};
    let params: Vec<Parameter> = names
        .iter()
        .map(|p| Parameter::by_name(model, p).unwrap())
        .collect();
    let ddm = sensitivities(model, &params, Method::Ddm, 0.0);
    let fdm = sensitivities(model, &params, Method::FdmCentral, 1e-6);
    (params, ddm, fdm)
}
