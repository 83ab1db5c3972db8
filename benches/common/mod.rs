//! Set-ups shared by the benchmark binaries: one hex8 element at a fixed state, and the
//! ~10^4-unknown cantilever.
//!
//! Each binary uses a part of this module only.
#![allow(dead_code)]

use fricsens::element::hex8::{self, generalised_nodes, Hex8Input, Hex8Output, NODE_XI};
use fricsens::element::{ElementFailure, Formulation, Kinematics};
use fricsens::material::{Branch, J2Plasticity, MaterialLaw, StVenantKirchhoff};
use fricsens::mesh::Axis;
use fricsens::model::Model;
use fricsens::scalar::Scalar;
use fricsens::scene::{cantilever, CantileverSpec};
use nalgebra::{Matrix3, Vector3};
use std::time::{Duration, Instant};

/// The two materials of the kernel benchmarks.
pub fn svk() -> StVenantKirchhoff {
    StVenantKirchhoff::new(200e3, 0.3)
}

/// J2 with linear hardening (the uniaxial oracle material, MPa).
pub fn j2() -> J2Plasticity {
    J2Plasticity::linear(200e3, 0.3, 250.0, 10e3)
}

/// Displacement gradient of the element state: `plastic` gives a uniaxial-like stretch of
/// 0.5 % (four times the yield strain 250 / 200e3) with some shear, so every Gauss point of the
/// J2 element returns plastically from a virgin history; otherwise a 2 % general stretch.
fn displacement_gradient(plastic: bool) -> Matrix3<f64> {
    if plastic {
        Matrix3::new(
            5.0e-3, 1.0e-3, 0.0, 0.5e-3, -1.5e-3, 0.2e-3, 0.0, 0.3e-3, -1.5e-3,
        )
    } else {
        Matrix3::new(
            2.0e-2, 4.0e-3, -3.0e-3, 1.0e-3, -8.0e-3, 2.0e-3, 5.0e-3, -1.0e-3, 6.0e-3,
        )
    }
}

/// One hex8 element and its buffers, in scalar type `S`.
pub struct Element<S: Scalar> {
    pub formulation: Formulation,
    pub x_ref: [Vector3<S>; 8],
    /// `n_gen` generalised displacements (nodes, then incompatible modes).
    pub dofs: Vec<Vector3<S>>,
    pub params: Vec<S>,
    pub hist_old: Vec<S>,
    pub force: Vec<S>,
    pub tangent: Vec<S>,
    pub hist_new: Vec<S>,
    pub branches: [Branch; 8],
}

impl Element<f64> {
    /// A distorted brick of about unit size with a prescribed smooth displacement field (and
    /// small incompatible-mode amplitudes), `history_len` history scalars per Gauss point (zero:
    /// a virgin state).
    pub fn new(
        formulation: Formulation,
        params: &[f64],
        history_len: usize,
        plastic: bool,
    ) -> Self {
        let x_ref: [Vector3<f64>; 8] = std::array::from_fn(|a| {
            let x = NODE_XI[a];
            let skew = 0.05 * (a as f64 - 3.5);
            Vector3::new(
                0.5 * (1.0 + x[0]) + 0.03 * x[1] * x[2],
                0.5 * (1.0 + x[1]) + 0.02 * skew,
                0.5 * (1.0 + x[2]) - 0.04 * x[0] * x[1],
            )
        });
        let g = displacement_gradient(plastic);
        let n_gen = generalised_nodes(formulation);
        let mut dofs: Vec<Vector3<f64>> = x_ref.iter().map(|x| g * x).collect();
        for k in 8..n_gen {
            let s = 1e-4 * (k as f64 - 7.0);
            dofs.push(Vector3::new(s, -0.5 * s, 0.3 * s));
        }
        let ndof = 3 * n_gen;
        Element {
            formulation,
            x_ref,
            dofs,
            params: params.to_vec(),
            hist_old: vec![0.0; 8 * history_len],
            force: vec![0.0; ndof],
            tangent: vec![0.0; ndof * ndof],
            hist_new: vec![0.0; 8 * history_len],
            branches: [Branch::Elastic; 8],
        }
    }

    /// The same element in scalar type `S`: every input a constant, except design parameter
    /// `k` seeded in derivative slot `k` for `k < seed_params` (DDM's pseudo-load evaluation).
    pub fn lift<S: Scalar>(&self, seed_params: usize) -> Element<S> {
        let ndof = self.force.len();
        Element {
            formulation: self.formulation,
            x_ref: self.x_ref.map(|x| x.map(S::lift)),
            dofs: self.dofs.iter().map(|d| d.map(S::lift)).collect(),
            params: self
                .params
                .iter()
                .enumerate()
                .map(|(k, p)| {
                    if k < seed_params {
                        S::seeded(*p, k)
                    } else {
                        S::lift(*p)
                    }
                })
                .collect(),
            hist_old: self.hist_old.iter().map(|h| S::lift(*h)).collect(),
            force: vec![S::zero(); ndof],
            tangent: vec![S::zero(); ndof * ndof],
            hist_new: vec![S::zero(); self.hist_new.len()],
            branches: [Branch::Elastic; 8],
        }
    }
}

impl<S: Scalar> Element<S> {
    /// Number of element unknowns.
    pub fn ndof(&self) -> usize {
        self.force.len()
    }

    /// One call of `hex8::evaluate` (large kinematics), with or without the hand-coded tangent.
    pub fn evaluate<M: MaterialLaw>(
        &mut self,
        material: &M,
        want_tangent: bool,
    ) -> Result<(), ElementFailure> {
        let input = Hex8Input {
            x_ref: &self.x_ref,
            dofs: &self.dofs,
            kinematics: Kinematics::Large,
            formulation: self.formulation,
            material,
            params: &self.params,
            hist_old: &self.hist_old,
            frozen: None,
        };
        let mut out = Hex8Output {
            force: &mut self.force,
            tangent: if want_tangent {
                Some(&mut self.tangent[..])
            } else {
                None
            },
            hist_new: &mut self.hist_new,
            branches: [Branch::Elastic; 8],
            yield_ratio: [-1.0; 8],
            cauchy: Matrix3::zeros(),
            min_det_f: f64::INFINITY,
        };
        hex8::evaluate(&input, &mut out)?;
        self.branches = out.branches;
        Ok(())
    }
}

/// Element tangent `K[i][k] = d f_i / d d_k` (row-major) by forward AD of the residual: the
/// element unknowns are seeded `S::NPARTS` at a time (one `Dual64` pass per unknown, one
/// `DualSVec64<24>` pass for a full hex8), the rest of the inputs are constants.
pub fn ad_tangent<S: Scalar, M: MaterialLaw>(
    base: &Element<f64>,
    work: &mut Element<S>,
    material: &M,
    k_out: &mut [f64],
) -> Result<(), ElementFailure> {
    let ndof = base.ndof();
    let width = S::NPARTS;
    let mut first = 0;
    while first < ndof {
        let last = (first + width).min(ndof);
        for (a, (w, d)) in work.dofs.iter_mut().zip(&base.dofs).enumerate() {
            for i in 0..3 {
                let k = 3 * a + i;
                w[i] = if (first..last).contains(&k) {
                    S::seeded(d[i], k - first)
                } else {
                    S::lift(d[i])
                };
            }
        }
        work.evaluate(material, false)?;
        for (i, f) in work.force.iter().enumerate() {
            for k in first..last {
                k_out[i * ndof + k] = f.part(k - first);
            }
        }
        first = last;
    }
    Ok(())
}

/// Largest entry difference between two row-major matrices over the largest entry of the first.
pub fn relative_difference(a: &[f64], b: &[f64]) -> f64 {
    let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let diff = a
        .iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    diff / scale
}

/// The cantilever of the assembly figures: the large-deflection beam (L = 10, h = b = 0.2,
/// incompatible modes) meshed `nx x 4 x 2`; `nx = 85` gives 9 990 unknowns (3 870 nodal and
/// 6 120 incompatible-mode amplitudes).
pub fn cantilever_model(nx: usize, alpha: f64, increments: usize) -> Model {
    let spec = CantileverSpec {
        nx,
        ny: 4,
        alpha,
        increments,
        ..CantileverSpec::large_deflection()
    };
    let mut scene = cantilever(&spec);
    scene.bodies[0].block_mut().unwrap().z = Axis::uniform(spec.width, 2);
    scene.build().expect("cantilever scene builds")
}

/// Number of elements along the ~10^4-unknown cantilever.
pub const NX_10K: usize = 85;

/// A bending-like displacement field of the cantilever (tip deflection about 5 % of the
/// length), for timing evaluations away from the zero state.
pub fn bending_state(model: &Model, n_total: usize) -> Vec<f64> {
    let coords = model.lifted::<f64>(&[]).coords;
    let mut z = vec![0.0; n_total];
    let c = 5e-4;
    for (n, x) in coords.iter().enumerate() {
        let (xx, yy) = (x[0], x[1] - 0.1);
        z[3 * n] = -2.0 * c * xx * yy;
        z[3 * n + 1] = c * xx * xx;
    }
    z
}

/// Fastest wall time of `reps` calls of `f` (after one warm-up call). On a shared machine the
/// fastest run is the one least disturbed by other processes.
pub fn fastest_time(reps: usize, mut f: impl FnMut()) -> Duration {
    f();
    (0..reps)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed()
        })
        .min()
        .expect("at least one repetition")
}
