//! Loads in pseudo-time: the amplitudes that scale prescribed displacements, nodal loads,
//! pressures and rigid motions; and pressure loads on face sets.

use crate::element::face::MAX_FACE_NODES;
use crate::element::{node_dof, FaceFamily};
use crate::mesh::FaceSet;
use crate::scalar::Scalar;
use nalgebra::Vector3;

/// Piecewise-linear amplitude of pseudo-time, constant beyond its ends.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Amplitude {
    /// `(time, value)` pairs with increasing times.
    pub points: Vec<(f64, f64)>,
}

impl Amplitude {
    /// Linear ramp from 0 at t = 0 to 1 at t = 1.
    pub fn ramp() -> Self {
        Amplitude {
            points: vec![(0.0, 0.0), (1.0, 1.0)],
        }
    }

    /// Value at time `t`.
    pub fn at(&self, t: f64) -> f64 {
        let p = &self.points;
        if p.is_empty() {
            return 0.0;
        }
        if t <= p[0].0 {
            return p[0].1;
        }
        for w in p.windows(2) {
            let (t0, v0) = w[0];
            let (t1, v1) = w[1];
            if t <= t1 {
                if t1 == t0 {
                    return v1;
                }
                return v0 + (v1 - v0) * (t - t0) / (t1 - t0);
            }
        }
        p[p.len() - 1].1
    }
}

/// A pressure `p = value * amplitude(t)` on a face set: the traction `-p N` on the reference
/// faces (`N` their outward normal; a positive pressure pushes into the body), a dead load
/// whose nodal forces are the consistent ones, `f_a = -p * integral N_a N dA` over each face
/// (2x2 Gauss points, exact on a bilinear quad). The forces follow the reference coordinates,
/// so a shape parameter moves them (a larger bore carries a larger force) in every
/// sensitivity method. Under small strains it is the true pressure; under large strains the
/// nominal one (force per reference area, direction of the reference normal).
#[derive(Clone, Debug)]
pub struct PressureLoad {
    /// Name (for design parameters and messages).
    pub name: String,
    /// The loaded faces, outward oriented.
    pub faces: FaceSet,
    /// Pressure magnitude.
    pub value: f64,
    /// Amplitude in pseudo-time.
    pub amplitude: Amplitude,
}

impl PressureLoad {
    /// Add the external force of pressure `p` on reference coordinates `x` to `residual`
    /// (which holds internal minus external force): `+p * integral N_a N dA` per node.
    pub fn add_to_residual<S: Scalar>(&self, x: &[Vector3<S>], p: S, residual: &mut [S]) {
        for face in self.faces.iter() {
            let mut xf = [Vector3::<S>::zeros(); MAX_FACE_NODES];
            for (xa, &n) in xf.iter_mut().zip(face.nodes) {
                *xa = x[n];
            }
            // the quad4 keeps its own 2x2 loop (bit for bit as before the other families)
            let f = match face.family {
                FaceFamily::Quad4 => {
                    let q = quad4_normal_weights(&[xf[0], xf[1], xf[2], xf[3]]);
                    let mut f = [Vector3::<S>::zeros(); MAX_FACE_NODES];
                    f[..4].copy_from_slice(&q);
                    f
                }
                family => family.normal_weights(&xf[..face.nodes.len()]),
            };
            for (&n, fa) in face.nodes.iter().zip(&f) {
                for c in 0..3 {
                    residual[node_dof(n, c)] += p * fa[c];
                }
            }
        }
    }

    /// Euclidean norm of the nodal forces of pressure `p` (the force scale of the solver's
    /// convergence criterion).
    pub fn force_norm(&self, x: &[Vector3<f64>], p: f64, n_dofs: usize) -> f64 {
        let mut r = vec![0.0; n_dofs];
        self.add_to_residual(x, p, &mut r);
        r.iter().map(|v| v * v).sum::<f64>().sqrt()
    }
}

/// `integral N_a N dA` at the four nodes of a bilinear quad (2x2 Gauss points).
fn quad4_normal_weights<S: Scalar>(x: &[Vector3<S>; 4]) -> [Vector3<S>; 4] {
    const XI: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    let g = 1.0 / 3f64.sqrt();
    let mut out = [Vector3::<S>::zeros(); 4];
    for (s, t) in [(-g, -g), (g, -g), (g, g), (-g, g)] {
        let mut dxs = Vector3::<S>::zeros();
        let mut dxt = Vector3::<S>::zeros();
        let mut n = [0.0; 4];
        for (a, xa) in XI.iter().enumerate() {
            n[a] = 0.25 * (1.0 + xa[0] * s) * (1.0 + xa[1] * t);
            dxs += x[a] * S::lift(0.25 * xa[0] * (1.0 + xa[1] * t));
            dxt += x[a] * S::lift(0.25 * xa[1] * (1.0 + xa[0] * s));
        }
        let nda = dxs.cross(&dxt);
        for (o, na) in out.iter_mut().zip(n) {
            *o += nda * S::lift(na);
        }
    }
    out
}

#[cfg(test)]
mod pressure_tests {
    use super::*;
    use num_dual::Dual64;

    /// A pressure load of magnitude 1 on the quads `faces`.
    fn load(faces: &[[usize; 4]]) -> PressureLoad {
        PressureLoad {
            name: "p".into(),
            faces: FaceSet::quad4(faces),
            value: 1.0,
            amplitude: Amplitude::ramp(),
        }
    }

    #[test]
    fn pressure_on_a_flat_quad_is_p_times_area_shared_by_the_bilinear_weights() {
        // a 2 x 3 rectangle in z = 0, normal +z: each node a quarter of p * 6, against +z
        let x = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(2.0, 0.0, 0.0),
            Vector3::new(2.0, 3.0, 0.0),
            Vector3::new(0.0, 3.0, 0.0),
        ];
        let load = load(&[[0, 1, 2, 3]]);
        let mut r = vec![0.0; 12];
        load.add_to_residual(&x, 2.0, &mut r);
        for a in 0..4 {
            assert!((r[3 * a + 2] - 2.0 * 6.0 / 4.0).abs() < 1e-14);
            assert!(r[3 * a].abs() < 1e-15 && r[3 * a + 1].abs() < 1e-15);
        }
        // its derivative with respect to the width is p * 3 / 2 at the nodes of the moved edge
        // and p * 3 / 2 at the others too (the area 3 w is shared equally on a rectangle)
        let mut xd: Vec<Vector3<Dual64>> = x.iter().map(|p| p.map(Dual64::from)).collect();
        xd[1].x = Dual64::new(2.0, 1.0);
        xd[2].x = Dual64::new(2.0, 1.0);
        let mut rd = vec![Dual64::from(0.0); 12];
        load.add_to_residual(&xd, Dual64::from(2.0), &mut rd);
        let total: f64 = (0..4).map(|a| rd[3 * a + 2].eps).sum();
        assert!((total - 2.0 * 3.0).abs() < 1e-14);
    }

    #[test]
    fn a_closed_surface_under_pressure_has_no_resultant() {
        // the six outward faces of a skewed hexahedron: integral N dA over a closed surface = 0
        let x = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.2, 0.1, 0.0),
            Vector3::new(1.0, 1.1, 0.2),
            Vector3::new(-0.1, 0.9, 0.0),
            Vector3::new(0.1, 0.0, 1.0),
            Vector3::new(1.1, 0.2, 1.3),
            Vector3::new(1.0, 1.0, 1.0),
            Vector3::new(0.0, 1.2, 0.9),
        ];
        let faces: Vec<[usize; 4]> = crate::element::Shape::Hex8
            .faces()
            .iter()
            .map(|f| [f.nodes[0], f.nodes[1], f.nodes[2], f.nodes[3]])
            .collect();
        let load = load(&faces);
        let mut r = vec![0.0; 24];
        load.add_to_residual(&x, 3.0, &mut r);
        for c in 0..3 {
            let sum: f64 = (0..8).map(|a| r[3 * a + c]).sum();
            assert!(sum.abs() < 1e-14, "{sum}");
        }
    }
}
