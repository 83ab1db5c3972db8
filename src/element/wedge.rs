//! Six- and fifteen-node wedges (triangular prisms) for swept meshes: node, face and edge
//! tables, interpolations and Gauss rules, evaluated by the continuum kernel
//! ([`super::continuum`]).
//!
//! Natural coordinates `(L1, L2, zeta)`: a triangle `L0 = 1 - L1 - L2` swept along
//! `zeta in [-1, 1]`. Node order as Abaqus (C3D6, C3D15) and Gmsh's corners: the bottom
//! triangle `0, 1, 2` (`zeta = -1`, counter-clockwise seen from the top, so the Jacobian is
//! positive), the top one `3, 4, 5`, then for wedge15 the mid-edge nodes of `01, 12, 20, 34,
//! 45, 53, 03, 14, 25`. VTK's wedge turns the triangles the other way: the VTK writer swaps.

use super::continuum::MAX_NODES;
use super::continuum::{Interpolation, Rule};
use super::{FaceFamily, FaceTopology};

/// Natural coordinates of the fifteen nodes (a wedge6 has the first six).
pub const NODE_XI: [[f64; 3]; 15] = [
    [0.0, 0.0, -1.0],
    [1.0, 0.0, -1.0],
    [0.0, 1.0, -1.0],
    [0.0, 0.0, 1.0],
    [1.0, 0.0, 1.0],
    [0.0, 1.0, 1.0],
    [0.5, 0.0, -1.0],
    [0.5, 0.5, -1.0],
    [0.0, 0.5, -1.0],
    [0.5, 0.0, 1.0],
    [0.5, 0.5, 1.0],
    [0.0, 0.5, 1.0],
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
];

/// The corners of each edge, in the order of wedge15's mid-edge nodes `6..15`.
pub(crate) const EDGES: [[usize; 2]; 9] = [
    [0, 1],
    [1, 2],
    [2, 0],
    [3, 4],
    [4, 5],
    [5, 3],
    [0, 3],
    [1, 4],
    [2, 5],
];

/// Wedge6's faces, counter-clockwise seen from outside: the two triangles, the three quads.
pub(crate) const FACES6: [FaceTopology; 5] = [
    face(FaceFamily::Tri3, &[0, 2, 1]),
    face(FaceFamily::Tri3, &[3, 4, 5]),
    face(FaceFamily::Quad4, &[0, 1, 4, 3]),
    face(FaceFamily::Quad4, &[1, 2, 5, 4]),
    face(FaceFamily::Quad4, &[2, 0, 3, 5]),
];

/// Wedge15's faces: wedge6's corners, then the mid-edge nodes of their edges in order.
pub(crate) const FACES15: [FaceTopology; 5] = [
    face(FaceFamily::Tri6, &[0, 2, 1, 8, 7, 6]),
    face(FaceFamily::Tri6, &[3, 4, 5, 9, 10, 11]),
    face(FaceFamily::Quad8, &[0, 1, 4, 3, 6, 13, 9, 12]),
    face(FaceFamily::Quad8, &[1, 2, 5, 4, 7, 14, 10, 13]),
    face(FaceFamily::Quad8, &[2, 0, 3, 5, 8, 12, 11, 14]),
];

const fn face(family: FaceFamily, nodes: &'static [usize]) -> FaceTopology {
    FaceTopology { family, nodes }
}

/// Triangle coordinates `(L0, L1, L2)` at `xi` and their gradients in `(L1, L2)`.
fn triangle(xi: [f64; 3]) -> ([f64; 3], [[f64; 2]; 3]) {
    (
        [1.0 - xi[0] - xi[1], xi[0], xi[1]],
        [[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]],
    )
}

/// Wedge6's shape functions: `L_a (1 -+ zeta) / 2`.
pub(crate) fn values6(xi: [f64; 3]) -> [f64; MAX_NODES] {
    let (l, _) = triangle(xi);
    let mut n = [0.0; MAX_NODES];
    for a in 0..3 {
        n[a] = 0.5 * l[a] * (1.0 - xi[2]);
        n[a + 3] = 0.5 * l[a] * (1.0 + xi[2]);
    }
    n
}

/// The linear interpolation.
pub(crate) static INTERPOLATION6: Interpolation = Interpolation {
    n_nodes: 6,
    values: values6,
    derivatives: |xi| {
        let (l, dl) = triangle(xi);
        let mut d = [[0.0; 3]; MAX_NODES];
        for a in 0..3 {
            for (k, s) in [(a, -1.0), (a + 3, 1.0)] {
                let z = 0.5 * (1.0 + s * xi[2]);
                d[k] = [dl[a][0] * z, dl[a][1] * z, 0.5 * s * l[a]];
            }
        }
        d
    },
};

/// Wedge15's shape functions: at a corner `L_a ((2 L_a - 1)(1 + s zeta) - (1 - zeta^2)) / 2`
/// (`s = -1` bottom, `+1` top), `2 L_a L_b (1 + s zeta)` at the middle of a triangle edge,
/// `L_a (1 - zeta^2)` at the middle of a vertical edge.
pub(crate) fn values15(xi: [f64; 3]) -> [f64; MAX_NODES] {
    let (l, _) = triangle(xi);
    let z = xi[2];
    let mut n = [0.0; MAX_NODES];
    for (a, la) in l.iter().enumerate() {
        for (k, s) in [(a, -1.0), (a + 3, 1.0)] {
            n[k] = 0.5 * la * ((2.0 * la - 1.0) * (1.0 + s * z) - (1.0 - z * z));
        }
    }
    for (m, [a, b]) in EDGES.iter().enumerate() {
        let (a, b) = (a % 3, b % 3);
        n[6 + m] = if m < 3 {
            2.0 * l[a] * l[b] * (1.0 - z)
        } else if m < 6 {
            2.0 * l[a] * l[b] * (1.0 + z)
        } else {
            l[a] * (1.0 - z * z)
        };
    }
    n
}

/// Derivatives of [`values15`].
fn derivatives15(xi: [f64; 3]) -> [[f64; 3]; MAX_NODES] {
    let (l, dl) = triangle(xi);
    let z = xi[2];
    let mut d = [[0.0; 3]; MAX_NODES];
    for a in 0..3 {
        for (k, s) in [(a, -1.0), (a + 3, 1.0)] {
            // d/dL_a of 0.5 L ((2L - 1)(1 + s z) - (1 - z^2)) = 0.5 ((4L - 1)(1 + s z) - (1 - z^2))
            let dn_dl = 0.5 * ((4.0 * l[a] - 1.0) * (1.0 + s * z) - (1.0 - z * z));
            let dn_dz = 0.5 * l[a] * ((2.0 * l[a] - 1.0) * s + 2.0 * z);
            d[k] = [dn_dl * dl[a][0], dn_dl * dl[a][1], dn_dz];
        }
    }
    for (m, [a, b]) in EDGES.iter().enumerate() {
        let (a, b) = (a % 3, b % 3);
        d[6 + m] = if m < 6 {
            let s = if m < 3 { -1.0 } else { 1.0 };
            let zf = 1.0 + s * z;
            let g = |j: usize| 2.0 * (dl[a][j] * l[b] + l[a] * dl[b][j]) * zf;
            [g(0), g(1), 2.0 * l[a] * l[b] * s]
        } else {
            let zf = 1.0 - z * z;
            [dl[a][0] * zf, dl[a][1] * zf, -2.0 * z * l[a]]
        };
    }
    d
}

/// The quadratic (serendipity) interpolation.
pub(crate) static INTERPOLATION15: Interpolation = Interpolation {
    n_nodes: 15,
    values: values15,
    derivatives: derivatives15,
};

const T1: f64 = 1.0 / 6.0;
const T2: f64 = 2.0 / 3.0;
const G2: f64 = 0.577_350_269_189_625_8; // 1/sqrt(3)
const G3: f64 = 0.774_596_669_241_483_4; // sqrt(3/5)

/// Wedge6's rule: the 3-point triangle rule (degree 2) times 2 Gauss points.
pub(crate) static GAUSS_3X2: Rule = Rule {
    points: &[
        [T1, T1, -G2],
        [T2, T1, -G2],
        [T1, T2, -G2],
        [T1, T1, G2],
        [T2, T1, G2],
        [T1, T2, G2],
    ],
    weights: &[T1; 6],
};

/// Wedge15's rule (as CalculiX's C3D15): the 3-point triangle rule times 3 Gauss points.
pub(crate) static GAUSS_3X3: Rule = Rule {
    points: &[
        [T1, T1, -G3],
        [T2, T1, -G3],
        [T1, T2, -G3],
        [T1, T1, 0.0],
        [T2, T1, 0.0],
        [T1, T2, 0.0],
        [T1, T1, G3],
        [T2, T1, G3],
        [T1, T2, G3],
    ],
    weights: &[
        T1 * 5.0 / 9.0,
        T1 * 5.0 / 9.0,
        T1 * 5.0 / 9.0,
        T1 * 8.0 / 9.0,
        T1 * 8.0 / 9.0,
        T1 * 8.0 / 9.0,
        T1 * 5.0 / 9.0,
        T1 * 5.0 / 9.0,
        T1 * 5.0 / 9.0,
    ],
};
