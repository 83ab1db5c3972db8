//! Eight-node hexahedron: its node, face and edge tables, its trilinear interpolation and
//! 2x2x2 rule, evaluated by the continuum kernel ([`super::continuum`]) as plain full
//! integration, incompatible modes or F-bar.

use super::continuum::{ElementFailure, Formulation, Interpolation, Kinematics, Rule, Solid};
use super::continuum::{ElementInput, ElementOutput, MAX_NODES};
use crate::material::{Branch, MaterialLaw};
use crate::scalar::Scalar;
use nalgebra::{Matrix3, Vector3};

/// Natural coordinates of the nodes, in the usual order (bottom face counter-clockwise, then top).
pub const NODE_XI: [[f64; 3]; 8] = [
    [-1.0, -1.0, -1.0],
    [1.0, -1.0, -1.0],
    [1.0, 1.0, -1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
    [1.0, -1.0, 1.0],
    [1.0, 1.0, 1.0],
    [-1.0, 1.0, 1.0],
];

/// Local node numbers of the six faces, ordered counter-clockwise seen from outside
/// (so the face normal `t1 x t2` points out of the element). Order: -x, +x, -y, +y, -z, +z.
pub(crate) const FACE_NODES: [[usize; 4]; 6] = [
    [0, 4, 7, 3],
    [1, 2, 6, 5],
    [0, 1, 5, 4],
    [3, 7, 6, 2],
    [0, 3, 2, 1],
    [4, 5, 6, 7],
];

/// The six faces as quad4 faces (outward, [`FACE_NODES`]).
pub(crate) const FACES: [super::FaceTopology; 6] = [
    quad(&FACE_NODES[0]),
    quad(&FACE_NODES[1]),
    quad(&FACE_NODES[2]),
    quad(&FACE_NODES[3]),
    quad(&FACE_NODES[4]),
    quad(&FACE_NODES[5]),
];

const fn quad(nodes: &'static [usize]) -> super::FaceTopology {
    super::FaceTopology {
        family: super::FaceFamily::Quad4,
        nodes,
    }
}

/// The twelve edges (local node numbers).
pub(crate) const EDGES: [[usize; 2]; 12] = [
    [0, 1],
    [1, 2],
    [2, 3],
    [3, 0],
    [4, 5],
    [5, 6],
    [6, 7],
    [7, 4],
    [0, 4],
    [1, 5],
    [2, 6],
    [3, 7],
];

const GP: f64 = 0.577_350_269_189_625_8; // 1/sqrt(3)

/// The 2x2x2 Gauss points, in node order (each at `NODE_XI / sqrt(3)`), weights one: hex8's
/// rule, and hex20's reduced one.
pub(crate) static GAUSS_2X2X2: Rule = Rule {
    points: &[
        [-GP, -GP, -GP],
        [GP, -GP, -GP],
        [GP, GP, -GP],
        [-GP, GP, -GP],
        [-GP, -GP, GP],
        [GP, -GP, GP],
        [GP, GP, GP],
        [-GP, GP, GP],
    ],
    weights: &[1.0; 8],
};

/// The eight 2x2x2 Gauss points.
pub fn gauss_points() -> [[f64; 3]; 8] {
    let mut p = [[0.0; 3]; 8];
    p.copy_from_slice(GAUSS_2X2X2.points);
    p
}

/// The trilinear interpolation.
pub(crate) static INTERPOLATION: Interpolation = Interpolation {
    n_nodes: 8,
    values: |xi| {
        let mut n = [0.0; MAX_NODES];
        for (na, x) in n.iter_mut().zip(&NODE_XI) {
            *na = 0.125 * (1.0 + x[0] * xi[0]) * (1.0 + x[1] * xi[1]) * (1.0 + x[2] * xi[2]);
        }
        n
    },
    derivatives: |xi| {
        let mut d = [[0.0; 3]; MAX_NODES];
        d[..8].copy_from_slice(&shape_derivatives(xi));
        d
    },
};

/// Derivatives of the shape functions with respect to the natural coordinates at `xi`.
#[inline]
pub(crate) fn shape_derivatives(xi: [f64; 3]) -> [[f64; 3]; 8] {
    let mut d = [[0.0; 3]; 8];
    for (a, n) in NODE_XI.iter().enumerate() {
        let f0 = 1.0 + n[0] * xi[0];
        let f1 = 1.0 + n[1] * xi[1];
        let f2 = 1.0 + n[2] * xi[2];
        d[a] = [
            0.125 * n[0] * f1 * f2,
            0.125 * f0 * n[1] * f2,
            0.125 * f0 * f1 * n[2],
        ];
    }
    d
}

/// The hex8 of a formulation (full, incompatible modes, F-bar) as the kernel integrates it.
pub(crate) fn solid(formulation: Formulation) -> Solid<'static> {
    Solid {
        interpolation: &INTERPOLATION,
        rule: &GAUSS_2X2X2,
        enhanced: formulation == Formulation::IncompatibleModes,
        fbar: formulation == Formulation::FBar,
    }
}

/// Number of generalised nodes of a formulation (the nodes and the incompatible modes).
#[inline]
pub fn generalised_nodes(formulation: Formulation) -> usize {
    8 + formulation.internal_dofs() / 3
}

/// Everything one hex8 evaluation needs besides its unknowns (the array form of
/// [`ElementInput`]).
pub struct Hex8Input<'a, S: Scalar, M: MaterialLaw> {
    /// Reference coordinates of the 8 nodes.
    pub x_ref: &'a [Vector3<S>; 8],
    /// Unknowns: 8 nodal displacements, then the incompatible-mode amplitudes if any.
    pub dofs: &'a [Vector3<S>],
    /// Strain measure: Green-Lagrange (large) or linear (small).
    pub kinematics: Kinematics,
    /// Element variant: plain, incompatible modes or F-bar.
    pub formulation: Formulation,
    /// The material law (its parameters come in `params`).
    pub material: &'a M,
    /// Material parameters lifted to `S`.
    pub params: &'a [S],
    /// Committed history, `8 * material.history_len()` scalars.
    pub hist_old: &'a [S],
    /// Branch per Gauss point to impose (SDM's frozen evaluation), or `None`.
    pub frozen: Option<&'a [Branch; 8]>,
}

/// What one hex8 evaluation returns (the array form of [`ElementOutput`]).
pub struct Hex8Output<'a, S: Scalar> {
    /// Internal force, `3 * n_gen` entries (node-major, component-minor).
    pub force: &'a mut [S],
    /// Tangent, row-major `(3 n_gen)^2`, if wanted.
    pub tangent: Option<&'a mut [S]>,
    /// Updated history, `8 * history_len` scalars.
    pub hist_new: &'a mut [S],
    /// Branch taken at each Gauss point.
    pub branches: [Branch; 8],
    /// Trial yield ratio at each Gauss point (see `PointResponse::yield_ratio`).
    pub yield_ratio: [f64; 8],
    /// Volume-averaged Cauchy stress (for output).
    pub cauchy: Matrix3<S>,
    /// Smallest det F over the Gauss points (real part).
    pub min_det_f: f64,
}

/// Evaluate internal force (and optionally the tangent), the updated history and the
/// per-Gauss-point branches of one hex8 (a formulation hex8 does not take is a typed
/// failure).
pub fn evaluate<S: Scalar, M: MaterialLaw>(
    input: &Hex8Input<'_, S, M>,
    out: &mut Hex8Output<'_, S>,
) -> Result<(), ElementFailure> {
    use Formulation::{FBar, Full, IncompatibleModes};
    if !matches!(input.formulation, Full | IncompatibleModes | FBar) {
        return Err(ElementFailure::Section {
            family: "hex8",
            expected: "full, incompatible-modes or f-bar",
            got: input.formulation.name(),
        });
    }
    let general = ElementInput {
        x_ref: input.x_ref,
        dofs: input.dofs,
        kinematics: input.kinematics,
        material: input.material,
        params: input.params,
        hist_old: input.hist_old,
        frozen: input.frozen.map(|f| &f[..]),
    };
    let mut o = ElementOutput {
        force: &mut *out.force,
        tangent: out.tangent.as_deref_mut(),
        hist_new: &mut *out.hist_new,
        branches: &mut out.branches,
        yield_ratio: &mut out.yield_ratio,
        cauchy: Matrix3::zeros(),
        want_cauchy: true,
        min_det_f: f64::INFINITY,
    };
    let r = solid(input.formulation).evaluate(&general, &mut o);
    out.cauchy = o.cauchy;
    out.min_det_f = o.min_det_f;
    r
}
