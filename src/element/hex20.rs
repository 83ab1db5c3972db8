//! Twenty-node serendipity hexahedron: node, face and edge tables, its interpolation and
//! Gauss rules, evaluated by the continuum kernel ([`super::continuum`]), with full (3x3x3)
//! or reduced (2x2x2, C3D20R) integration.
//!
//! Node order as Abaqus (C3D20) and VTK (`VTK_QUADRATIC_HEXAHEDRON`): the eight corners as a
//! hex8's ([`super::hex8::NODE_XI`]), then the mid-edge nodes of hex8's twelve edges in the
//! order of hex8's edge table (bottom ring, top ring, verticals). Gmsh orders them
//! otherwise; its reader permutes.
//!
//! Reduced integration is the literature's choice for hex20 in plasticity and near
//! incompressibility: its eight points leave one volumetric constraint per point, and its
//! spurious modes do not propagate in a mesh of more than one element.

use super::continuum::MAX_NODES;
use super::continuum::{Interpolation, Rule};
use super::hex8;
use super::{FaceFamily, FaceTopology};

/// Natural coordinates of the twenty nodes.
pub const NODE_XI: [[f64; 3]; 20] = [
    [-1.0, -1.0, -1.0],
    [1.0, -1.0, -1.0],
    [1.0, 1.0, -1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
    [1.0, -1.0, 1.0],
    [1.0, 1.0, 1.0],
    [-1.0, 1.0, 1.0],
    [0.0, -1.0, -1.0],
    [1.0, 0.0, -1.0],
    [0.0, 1.0, -1.0],
    [-1.0, 0.0, -1.0],
    [0.0, -1.0, 1.0],
    [1.0, 0.0, 1.0],
    [0.0, 1.0, 1.0],
    [-1.0, 0.0, 1.0],
    [-1.0, -1.0, 0.0],
    [1.0, -1.0, 0.0],
    [1.0, 1.0, 0.0],
    [-1.0, 1.0, 0.0],
];

/// The six faces (quad8: hex8's corners, then the mid-edge nodes of the face's edges in
/// order), counter-clockwise seen from outside.
pub(crate) const FACES: [FaceTopology; 6] = [
    quad8(&[0, 4, 7, 3, 16, 15, 19, 11]),
    quad8(&[1, 2, 6, 5, 9, 18, 13, 17]),
    quad8(&[0, 1, 5, 4, 8, 17, 12, 16]),
    quad8(&[3, 7, 6, 2, 19, 14, 18, 10]),
    quad8(&[0, 3, 2, 1, 11, 10, 9, 8]),
    quad8(&[4, 5, 6, 7, 12, 13, 14, 15]),
];

const fn quad8(nodes: &'static [usize]) -> FaceTopology {
    FaceTopology {
        family: FaceFamily::Quad8,
        nodes,
    }
}

/// The geometric edges: hex8's, corner to corner (the element's size; the mid-edge node is
/// interior to its edge).
pub(crate) const EDGES: [[usize; 2]; 12] = hex8::EDGES;

/// Serendipity shape functions at `xi`: `(1/8) prod(1 + x_k xi_k) (sum x_k xi_k - 2)` at a
/// corner, `(1/4) (1 - xi_m^2) prod_{k != m} (1 + x_k xi_k)` at the middle of an edge along
/// `m`.
pub(crate) fn values(xi: [f64; 3]) -> [f64; MAX_NODES] {
    let mut n = [0.0; MAX_NODES];
    for (na, x) in n.iter_mut().zip(&NODE_XI) {
        match x.iter().position(|c| *c == 0.0) {
            None => {
                let s = x[0] * xi[0] + x[1] * xi[1] + x[2] * xi[2];
                *na = 0.125
                    * (1.0 + x[0] * xi[0])
                    * (1.0 + x[1] * xi[1])
                    * (1.0 + x[2] * xi[2])
                    * (s - 2.0);
            }
            Some(m) => {
                let mut v = 0.25 * (1.0 - xi[m] * xi[m]);
                for k in (0..3).filter(|&k| k != m) {
                    v *= 1.0 + x[k] * xi[k];
                }
                *na = v;
            }
        }
    }
    n
}

/// Derivatives of [`values`] with respect to the natural coordinates.
pub(crate) fn derivatives(xi: [f64; 3]) -> [[f64; 3]; MAX_NODES] {
    let mut d = [[0.0; 3]; MAX_NODES];
    for (da, x) in d.iter_mut().zip(&NODE_XI) {
        let f = [1.0 + x[0] * xi[0], 1.0 + x[1] * xi[1], 1.0 + x[2] * xi[2]];
        match x.iter().position(|c| *c == 0.0) {
            None => {
                // (1/8) x_j prod_{k != j} f_k (2 x_j xi_j + sum_{k != j} x_k xi_k - 1)
                let s = x[0] * xi[0] + x[1] * xi[1] + x[2] * xi[2];
                for j in 0..3 {
                    let others: f64 = (0..3).filter(|&k| k != j).map(|k| f[k]).product();
                    da[j] = 0.125 * x[j] * others * (s + x[j] * xi[j] - 1.0);
                }
            }
            Some(m) => {
                for j in 0..3 {
                    da[j] = if j == m {
                        let others: f64 = (0..3).filter(|&k| k != m).map(|k| f[k]).product();
                        -0.5 * xi[m] * others
                    } else {
                        let other = (0..3).find(|&k| k != m && k != j).expect("three axes");
                        0.25 * (1.0 - xi[m] * xi[m]) * x[j] * f[other]
                    };
                }
            }
        }
    }
    d
}

/// The serendipity interpolation.
pub(crate) static INTERPOLATION: Interpolation = Interpolation {
    n_nodes: 20,
    values,
    derivatives,
};

const G3: f64 = 0.774_596_669_241_483_4; // sqrt(3/5)
const W5: f64 = 5.0 / 9.0;
const W8: f64 = 8.0 / 9.0;

/// The 3x3x3 Gauss rule (hex20's full rule), `xi` fastest.
pub(crate) static GAUSS_3X3X3: Rule = Rule {
    points: &product3(),
    weights: &product3_weights(),
};

const fn product3() -> [[f64; 3]; 27] {
    let g = [-G3, 0.0, G3];
    let mut p = [[0.0; 3]; 27];
    let mut k = 0;
    while k < 27 {
        p[k] = [g[k % 3], g[(k / 3) % 3], g[k / 9]];
        k += 1;
    }
    p
}

const fn product3_weights() -> [f64; 27] {
    let w = [W5, W8, W5];
    let mut p = [0.0; 27];
    let mut k = 0;
    while k < 27 {
        p[k] = w[k % 3] * w[(k / 3) % 3] * w[k / 9];
        k += 1;
    }
    p
}
