//! Four- and ten-node tetrahedra: node, face and edge tables, interpolations and Gauss rules,
//! evaluated by the continuum kernel ([`super::continuum`]).
//!
//! Natural coordinates `xi = (L1, L2, L3)` with `L0 = 1 - L1 - L2 - L3` (volume coordinates):
//! corner `a` at `L_a = 1`. Node order as Abaqus (C3D4, C3D10) and VTK: corners `0..4` with
//! `(x1 - x0) x (x2 - x0)` pointing towards node 3 (positive Jacobian), then the mid-edge
//! nodes of `01, 12, 20, 03, 13, 23` (Gmsh numbers the last two the other way round: its
//! reader swaps them).
//!
//! ## Locking
//! Tet4 is a constant-strain element: one Gauss point and `3 n` unknowns against one
//! volumetric constraint per element, of which a tet mesh has some five per node. It locks
//! volumetrically (nearly incompressible elasticity, fully developed J2 flow) and in bending;
//! no remedy is cheap in this code (F-bar needs the element's neighbours, a patch the assembly
//! does not keep), so a researcher meshing tetrahedra for plasticity takes tet10: its F-bar
//! variant averages the volume change over the element (one constraint per element instead
//! of four), which is the stated choice for J2 here, on its full 4-point rule.

// the Gauss rules' digits as published (rounded to f64 on reading)
#![allow(clippy::excessive_precision)]

use super::continuum::MAX_NODES;
use super::continuum::{Interpolation, Rule};
use super::{FaceFamily, FaceTopology};

/// Natural coordinates `(L1, L2, L3)` of the ten nodes (a tet4 has the first four).
pub const NODE_XI: [[f64; 3]; 10] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.5, 0.0, 0.0],
    [0.5, 0.5, 0.0],
    [0.0, 0.5, 0.0],
    [0.0, 0.0, 0.5],
    [0.5, 0.0, 0.5],
    [0.0, 0.5, 0.5],
];

/// The corners of each edge, in the order of tet10's mid-edge nodes `4..10`.
pub(crate) const EDGES: [[usize; 2]; 6] = [[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]];

/// The four faces of a tet4 (tri3), counter-clockwise seen from outside.
pub(crate) const FACES4: [FaceTopology; 4] = [
    tri3(&[0, 2, 1]),
    tri3(&[0, 1, 3]),
    tri3(&[1, 2, 3]),
    tri3(&[0, 3, 2]),
];

/// The four faces of a tet10 (tri6: the corners of [`FACES4`], then the mid-edge nodes of
/// their edges in order).
pub(crate) const FACES10: [FaceTopology; 4] = [
    tri6(&[0, 2, 1, 6, 5, 4]),
    tri6(&[0, 1, 3, 4, 8, 7]),
    tri6(&[1, 2, 3, 5, 9, 8]),
    tri6(&[0, 3, 2, 7, 9, 6]),
];

const fn tri3(nodes: &'static [usize]) -> FaceTopology {
    FaceTopology {
        family: FaceFamily::Tri3,
        nodes,
    }
}

const fn tri6(nodes: &'static [usize]) -> FaceTopology {
    FaceTopology {
        family: FaceFamily::Tri6,
        nodes,
    }
}

/// The volume coordinates at `xi` and their (constant) gradients.
fn volume_coordinates(xi: [f64; 3]) -> ([f64; 4], [[f64; 3]; 4]) {
    (
        [1.0 - xi[0] - xi[1] - xi[2], xi[0], xi[1], xi[2]],
        [
            [-1.0, -1.0, -1.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ],
    )
}

/// Tet4's shape functions at `xi`: the volume coordinates.
pub(crate) fn values4(xi: [f64; 3]) -> [f64; MAX_NODES] {
    let mut n = [0.0; MAX_NODES];
    n[..4].copy_from_slice(&volume_coordinates(xi).0);
    n
}

/// The linear interpolation.
pub(crate) static INTERPOLATION4: Interpolation = Interpolation {
    n_nodes: 4,
    values: values4,
    derivatives: |xi| {
        let mut d = [[0.0; 3]; MAX_NODES];
        d[..4].copy_from_slice(&volume_coordinates(xi).1);
        d
    },
};

/// Tet10's shape functions at `xi`: `L_a (2 L_a - 1)` at the corners, `4 L_a L_b` at the
/// middle of edge `ab`.
pub(crate) fn values10(xi: [f64; 3]) -> [f64; MAX_NODES] {
    let (l, _) = volume_coordinates(xi);
    let mut n = [0.0; MAX_NODES];
    for a in 0..4 {
        n[a] = l[a] * (2.0 * l[a] - 1.0);
    }
    for (k, [a, b]) in EDGES.iter().enumerate() {
        n[4 + k] = 4.0 * l[*a] * l[*b];
    }
    n
}

/// The quadratic interpolation.
pub(crate) static INTERPOLATION10: Interpolation = Interpolation {
    n_nodes: 10,
    values: values10,
    derivatives: |xi| {
        let (l, dl) = volume_coordinates(xi);
        let mut d = [[0.0; 3]; MAX_NODES];
        for a in 0..4 {
            for j in 0..3 {
                d[a][j] = (4.0 * l[a] - 1.0) * dl[a][j];
            }
        }
        for (k, [a, b]) in EDGES.iter().enumerate() {
            for j in 0..3 {
                d[4 + k][j] = 4.0 * (l[*a] * dl[*b][j] + l[*b] * dl[*a][j]);
            }
        }
        d
    },
};

/// The centroid, weight 1/6: tet4's rule (exact for its constant strain).
pub(crate) static GAUSS_1: Rule = Rule {
    points: &[[0.25; 3]],
    weights: &[1.0 / 6.0],
};

const A4: f64 = 0.585_410_196_624_968_5; // (5 + 3 sqrt 5) / 20
const B4: f64 = 0.138_196_601_125_010_5; // (5 - sqrt 5) / 20

/// The 4-point rule of degree 2 (tet10's full rule: exact for a straight-sided tet10's
/// stiffness).
pub(crate) static GAUSS_4: Rule = Rule {
    points: &[[B4, B4, B4], [A4, B4, B4], [B4, A4, B4], [B4, B4, A4]],
    weights: &[1.0 / 24.0; 4],
};

const W1: f64 = 0.018_781_320_953_002_641_8;
const W2: f64 = 0.012_248_840_519_393_658_257;
const W3: f64 = 0.007_091_003_462_846_911_073;
const P1: f64 = 0.310_885_919_263_300_609_8;
const Q1: f64 = 1.0 - 3.0 * P1;
const P2: f64 = 0.092_735_250_310_891_226_402;
const Q2: f64 = 1.0 - 3.0 * P2;
const P3: f64 = 0.045_503_704_125_649_649_492;
const Q3: f64 = 0.5 - P3;

/// Walkington's 14-point rule of degree 5, all weights positive (tet10's high-order rule).
pub(crate) static GAUSS_14: Rule = Rule {
    points: &[
        [P1, P1, P1],
        [Q1, P1, P1],
        [P1, Q1, P1],
        [P1, P1, Q1],
        [P2, P2, P2],
        [Q2, P2, P2],
        [P2, Q2, P2],
        [P2, P2, Q2],
        [P3, P3, Q3],
        [P3, Q3, P3],
        [Q3, P3, P3],
        [P3, Q3, Q3],
        [Q3, P3, Q3],
        [Q3, Q3, P3],
    ],
    weights: &[W1, W1, W1, W1, W2, W2, W2, W2, W3, W3, W3, W3, W3, W3],
};
