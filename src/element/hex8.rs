//! Eight-node hexahedron, total Lagrangian, generic over the scalar.
//!
//! ## Kinematics
//! Reference coordinates `X`, displacements `u`, deformation gradient
//! `F = I + sum_A d_A (x) g_A`, where the sum runs over the eight nodes (`d_A = u_a`,
//! `g_A = grad_X N_a`) and, for the enhanced variant, over three incompatible modes
//! (`d_A = alpha_k`, `g_A = Gtilde_k`).
//!
//! * `Large`: Green-Lagrange strain `E = (F^T F - I)/2`, second Piola-Kirchhoff `S = S(E)`,
//!   internal force `f_Ai = int B_Ai^T S dV0` with `B_Ai = dE/dd_Ai = sym(F^T e_i (x) g_A)`.
//! * `Small`: linear strain `eps = sym(F - I)`, `sigma = sigma(eps)`, `B_Ai = sym(e_i (x) g_A)`.
//!
//! Tangent (hand-coded, consistent): `K_AiBj = int B_Ai^T C B_Bj + delta_ij g_A^T S g_B dV0`
//! (the geometric term only under `Large`). It is checked against the dual-number derivative of
//! the internal force in the tests.
//!
//! ## Incompatible modes (the bending-capable variant)
//! Wilson's bubble modes `phi_k = 1 - xi_k^2` with Taylor's correction (Simo & Armero 1992):
//! `Gtilde_k(xi) = (j0 / j(xi)) J0^-T dphi_k/dxi`, `J0` the Jacobian at the element centre.
//! `int Gtilde_k dV0 = 0`, so the patch test is passed. Their nine amplitudes `alpha` are
//! element-internal unknowns of the global system (not condensed here): the sparse LU eliminates
//! them as it would any interior DOF, and the sensitivity engine treats them like any other
//! unknown. Plain full integration locks in bending; this variant does not.
//!
//! ## F-bar (the volumetric-locking remedy)
//! After de Souza Neto, Peric, Dutko & Owen (1996), on 2x2x2 full integration: at each Gauss
//! point the deformation gradient is replaced by
//! `Fbar = r F`, `r = (J0 / J)^(1/3)`, `J = det F`, `J0 = det F0`,
//! so that the volume change of every Gauss point is the element's single `J0`: one volumetric
//! constraint per element instead of eight, which is what removes volumetric locking (nearly
//! incompressible elasticity, isochoric plastic flow). `F0 = I + sum_A u_a (x) gbar_A` is the
//! *volume average* of `F` over the element, `gbar_A = (1/V0) int g_A dV0`. On a parallelepiped
//! this is exactly `F` at the element centre (the shape-function gradients are multilinear in
//! `xi`); on a distorted 3D hex the centre value differs from the average, and only the average
//! lets the variationally consistent element below pass the patch test (with the centre value:
//! nodal displacement errors of 3e-3 relative on a randomly distorted 3x3x3 patch).
//!
//! * `Large`: `Ebar = (Fbar^T Fbar - I)/2`, `S = S(Ebar)`, and the internal force is the
//!   variational derivative of the F-bar strain, `f_a = int B_a^T S dV0` with, for unknown
//!   `a = (A, i)`,
//!   `B_a = dEbar/dd_a = r sym(Fbar^T e_i (x) g_A) + v_a Cbar`,
//!   `v_a = d ln r / dd_a = ((q0_A)_i - (q_A)_i) / 3`, `q_A = F^-T g_A`, `q0_A = F0^-T gbar_A`,
//!   `Cbar = Fbar^T Fbar`. Equivalently `f_a = int p_a + s v_a dV0`, `p_a = r (Fbar S g_A)_i`,
//!   `s = S : Cbar`.
//! * `Small` (B-bar): `eps_bar = dev(eps) + (1/3) tr(eps0) I`, `eps0 = sym(F0 - I)` the element
//!   average; `B_a = sym(e_i (x) g_A) + ((gbar_A)_i - (g_A)_i)/3 I`.
//!
//! Tangent (hand-coded, consistent): `K_ab = int B_a^T C B_b + G_ab dV0` with the geometric term
//! (`Large` only) `G_ab = S : d2Ebar/dd_a dd_b`, for `b = (B, j)`:
//!
//! ```text
//! G_ab = r^2 delta_ij g_A . S g_B + 2 (v_a p_b + v_b p_a) + 2 s v_a v_b
//!        + (s/3) [ (q_A)_j (q_B)_i - (q0_A)_j (q0_B)_i ]
//! ```
//!
//! (from `dq_A/dd_Bj = -q_B (q_A)_j`, `dq0_A/dd_Bj = -q0_B (q0_A)_j`). Because the force is the
//! exact derivative of `int W(Ebar) dV0`-type work, this tangent is symmetric whenever `C` is
//! (hyperelasticity, associative J2 with its algorithmic tangent). The *non*-variational
//! original (spatial virtual work with the unmodified gradient of the test function) has an
//! unsymmetric tangent; it is not what is implemented here.
//!
//! | symbol | meaning |
//! |---|---|
//! | `xi` | natural coordinates in `[-1, 1]^3` |
//! | `N_a` | trilinear shape functions |
//! | `J = dX/dxi`, `j = det J` | reference Jacobian |
//! | `F`, `E`, `S` | deformation gradient, Green-Lagrange strain, PK2 stress |
//! | `g_A`, `B_A` | generalised shape gradient, strain-displacement row |
//! | `gbar_A`, `F0`, `J0` | element averages (F-bar): gradient, deformation gradient, its det |
//! | `r`, `Fbar`, `Cbar`, `Ebar` | F-bar factor `(J0/J)^(1/3)`, modified `F`, `C`, Green strain |
//! | `q_A`, `q0_A`, `v_a` | `F^-T g_A`, `F0^-T gbar_A`, `d ln r / dd_a` |

use crate::material::{strain_to_voigt, stress_to_voigt, Branch, MaterialLaw, Voigt};
use crate::scalar::{det3, inv3, re, Scalar};
use nalgebra::{Matrix3, Vector3};

/// Strain measure used by an element.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Kinematics {
    /// Total Lagrangian, Green-Lagrange strain and PK2 stress.
    Large,
    /// Linear strain (geometrically linear).
    Small,
}

/// Hex8 formulation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Hex8Formulation {
    /// Plain 2x2x2 full integration (locks in bending).
    Full,
    /// Nine incompatible modes (Wilson-Taylor, Simo-Armero): accurate in bending.
    IncompatibleModes,
    /// F-bar (de Souza Neto et al. 1996) on 2x2x2 full integration, variationally consistent:
    /// free of volumetric locking (near incompressibility, isochoric plastic flow), but not of
    /// shear locking in bending. B-bar under small kinematics. See the module docs.
    #[serde(rename = "f-bar")]
    FBar,
}

impl Hex8Formulation {
    /// Number of element-internal unknowns.
    pub fn internal_dofs(self) -> usize {
        match self {
            Hex8Formulation::Full | Hex8Formulation::FBar => 0,
            Hex8Formulation::IncompatibleModes => 9,
        }
    }
}

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

/// The eight 2x2x2 Gauss points.
pub fn gauss_points() -> [[f64; 3]; 8] {
    let mut p = [[0.0; 3]; 8];
    for (g, x) in NODE_XI.iter().enumerate() {
        p[g] = [x[0] * GP, x[1] * GP, x[2] * GP];
    }
    p
}

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

/// Maximum number of generalised nodes (8 nodes + 3 incompatible modes).
pub(crate) const MAX_GEN: usize = 11;

/// Why an element evaluation failed. The solver recovers from an inverted element or a
/// non-finite stress by cutting the increment back; a bad reference geometry is fatal.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ElementFailure {
    /// The element was handed the wrong number of nodes, branches or unknowns for its family
    /// (a model whose layout does not match its elements; not recoverable).
    #[error("{what}: the family has {expected}, the element was given {got}")]
    Layout {
        /// What was miscounted (`nodes`, `frozen branches`).
        what: &'static str,
        /// How many the family has.
        expected: usize,
        /// How many the element was given.
        got: usize,
    },
    /// The reference Jacobian is singular or negative: a bad mesh (not recoverable).
    #[error("reference Jacobian determinant {det:.3e} at Gauss point {gauss_point}: the element is degenerate or inverted in the mesh")]
    BadReferenceGeometry {
        /// Gauss point (0-7).
        gauss_point: usize,
        /// Determinant of the reference Jacobian `dX/dxi` there.
        det: f64,
    },
    /// det F <= 0 at a Gauss point: the element turned inside out (recoverable by cutback).
    /// `gauss_point == usize::MAX`: the element-average `det F0` of the F-bar variant.
    #[error("det F = {det_f:.3e} at Gauss point {gauss_point}: element inverted")]
    Inverted {
        /// Gauss point (0-7), or `usize::MAX` for the F-bar average.
        gauss_point: usize,
        /// `det F` there.
        det_f: f64,
    },
    /// A non-finite number appeared in the stress.
    #[error("non-finite stress at Gauss point {gauss_point}")]
    NonFinite {
        /// Gauss point (0-7).
        gauss_point: usize,
    },
    /// The element was evaluated with the wrong kind of section: a material for a spring, a
    /// stiffness for a continuum element (a model whose layout does not match its elements;
    /// not recoverable).
    #[error("a {family} element takes {expected}, it was given {got}")]
    Section {
        /// The family's name.
        family: &'static str,
        /// The section it takes.
        expected: &'static str,
        /// The section it was given.
        got: &'static str,
    },
}

/// Everything one element evaluation needs besides its unknowns.
pub struct Hex8Input<'a, S: Scalar, M: MaterialLaw> {
    /// Reference coordinates of the 8 nodes.
    pub x_ref: &'a [Vector3<S>; 8],
    /// Unknowns: 8 nodal displacements, then the incompatible-mode amplitudes if any.
    pub dofs: &'a [Vector3<S>],
    /// Strain measure: Green-Lagrange (large) or linear (small).
    pub kinematics: Kinematics,
    /// Element variant: plain, incompatible modes or F-bar.
    pub formulation: Hex8Formulation,
    /// The material law (its parameters come in `params`).
    pub material: &'a M,
    /// Material parameters lifted to `S`.
    pub params: &'a [S],
    /// Committed history, `8 * material.history_len()` scalars.
    pub hist_old: &'a [S],
    /// Branch per Gauss point to impose (SDM's frozen evaluation), or `None`.
    pub frozen: Option<&'a [Branch; 8]>,
}

/// What one element evaluation returns.
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

/// `H = grad_X u` at a Gauss point from the generalised displacements (the enhanced part
/// included).
fn displacement_gradient<S: Scalar>(
    dofs: &[Vector3<S>],
    grads: &[Vector3<S>; MAX_GEN],
    n_gen: usize,
) -> Matrix3<S> {
    let mut h = Matrix3::<S>::zeros();
    for (d, g) in dofs.iter().zip(grads).take(n_gen) {
        for i in 0..3 {
            for j in 0..3 {
                h[(i, j)] += d[i] * g[j];
            }
        }
    }
    h
}

/// The strain the material sees: Green-Lagrange `(F^T F - I) / 2` under large kinematics,
/// `sym H` under small.
fn strain_measure<S: Scalar>(h: &Matrix3<S>, large: bool) -> Matrix3<S> {
    if large {
        let f = h + Matrix3::identity();
        (f.transpose() * f - Matrix3::identity()) * S::lift(0.5)
    } else {
        (h + h.transpose()) * S::lift(0.5)
    }
}

/// The strain each Gauss point's material sees for the generalised displacements `dofs`
/// (the evaluation's strain, without its stress update). `None` for F-bar, whose points see
/// a strain modified by the element's centre.
pub(crate) fn gauss_strains<S: Scalar>(
    x_ref: &[Vector3<S>; 8],
    dofs: &[Vector3<S>],
    kinematics: Kinematics,
    formulation: Hex8Formulation,
) -> Result<Option<[Matrix3<S>; 8]>, ElementFailure> {
    if formulation == Hex8Formulation::FBar {
        return Ok(None);
    }
    let centre = if formulation == Hex8Formulation::IncompatibleModes {
        Some(centre_jacobian(x_ref)?)
    } else {
        None
    };
    let n_gen = generalised_nodes(formulation);
    let mut out = [Matrix3::<S>::zeros(); 8];
    for (gp, (xi, e)) in gauss_points().iter().zip(out.iter_mut()).enumerate() {
        let geo = reference_geometry(x_ref, *xi, gp, formulation, &centre)?;
        let h = displacement_gradient(dofs, &geo.grads, n_gen);
        *e = strain_measure(&h, kinematics == Kinematics::Large);
    }
    Ok(Some(out))
}

/// Reference geometry at one Gauss point: generalised gradients and the volume weight.
struct GaussGeometry<S: Scalar> {
    grads: [Vector3<S>; MAX_GEN],
    weight: S,
}

fn reference_geometry<S: Scalar>(
    x_ref: &[Vector3<S>; 8],
    xi: [f64; 3],
    gp: usize,
    formulation: Hex8Formulation,
    centre: &Option<(Matrix3<S>, S)>,
) -> Result<GaussGeometry<S>, ElementFailure> {
    let dn = shape_derivatives(xi);
    // J_ij = dX_i / dxi_j
    let mut jac = Matrix3::<S>::zeros();
    for a in 0..8 {
        for i in 0..3 {
            for j in 0..3 {
                jac[(i, j)] += x_ref[a][i] * dn[a][j];
            }
        }
    }
    let (jinv, det) = match inv3(&jac) {
        Some(v) if re(v.1) > 0.0 => v,
        other => {
            return Err(ElementFailure::BadReferenceGeometry {
                gauss_point: gp,
                det: other.map(|v| re(v.1)).unwrap_or(0.0),
            })
        }
    };
    let mut grads = [Vector3::<S>::zeros(); MAX_GEN];
    // grad_X N = J^-T dN/dxi
    let jinv_t = jinv.transpose();
    for a in 0..8 {
        let dxi = Vector3::new(S::lift(dn[a][0]), S::lift(dn[a][1]), S::lift(dn[a][2]));
        grads[a] = jinv_t * dxi;
    }
    if formulation == Hex8Formulation::IncompatibleModes {
        let (j0inv_t, j0) = centre
            .as_ref()
            .expect("centre Jacobian computed for enhanced");
        let scale = *j0 / det;
        for k in 0..3 {
            let mut dphi = Vector3::<S>::zeros();
            dphi[k] = S::lift(-2.0 * xi[k]);
            grads[8 + k] = (j0inv_t * dphi) * scale;
        }
    }
    Ok(GaussGeometry { grads, weight: det })
}

fn centre_jacobian<S: Scalar>(x_ref: &[Vector3<S>; 8]) -> Result<(Matrix3<S>, S), ElementFailure> {
    let dn = shape_derivatives([0.0; 3]);
    let mut jac = Matrix3::<S>::zeros();
    for a in 0..8 {
        for i in 0..3 {
            for j in 0..3 {
                jac[(i, j)] += x_ref[a][i] * dn[a][j];
            }
        }
    }
    match inv3(&jac) {
        Some((inv, det)) if re(det) > 0.0 => Ok((inv.transpose(), det)),
        other => Err(ElementFailure::BadReferenceGeometry {
            gauss_point: usize::MAX,
            det: other.map(|v| re(v.1)).unwrap_or(0.0),
        }),
    }
}

/// The material update at Gauss point `gp` (branch frozen if asked), with its bookkeeping:
/// history slot, branch, yield ratio, finiteness.
fn material_point<S: Scalar, M: MaterialLaw>(
    input: &Hex8Input<'_, S, M>,
    out: &mut Hex8Output<'_, S>,
    gp: usize,
    strain: &Matrix3<S>,
) -> Result<crate::material::PointResponse<S>, ElementFailure> {
    let nh = input.material.history_len();
    let resp = input.material.update(
        input.params,
        strain,
        &input.hist_old[gp * nh..(gp + 1) * nh],
        &mut out.hist_new[gp * nh..(gp + 1) * nh],
        input.frozen.map(|fr| fr[gp]),
    );
    if !resp.stress.iter().all(|s| re(*s).is_finite()) {
        return Err(ElementFailure::NonFinite { gauss_point: gp });
    }
    out.branches[gp] = resp.branch;
    out.yield_ratio[gp] = resp.yield_ratio;
    Ok(resp)
}

/// Number of generalised nodes of a formulation.
#[inline]
pub fn generalised_nodes(formulation: Hex8Formulation) -> usize {
    8 + formulation.internal_dofs() / 3
}

/// Evaluate internal force (and optionally the tangent), the updated history and the
/// per-Gauss-point branches of one hex8.
pub fn evaluate<S: Scalar, M: MaterialLaw>(
    input: &Hex8Input<'_, S, M>,
    out: &mut Hex8Output<'_, S>,
) -> Result<(), ElementFailure> {
    if input.formulation == Hex8Formulation::FBar {
        return evaluate_fbar(input, out);
    }
    let n_gen = generalised_nodes(input.formulation);
    let ndof = 3 * n_gen;
    debug_assert_eq!(input.dofs.len(), n_gen);
    debug_assert!(out.force.len() >= ndof);
    for f in out.force[..ndof].iter_mut() {
        *f = S::zero();
    }
    if let Some(k) = out.tangent.as_deref_mut() {
        for v in k[..ndof * ndof].iter_mut() {
            *v = S::zero();
        }
    }
    let centre = if input.formulation == Hex8Formulation::IncompatibleModes {
        Some(centre_jacobian(input.x_ref)?)
    } else {
        None
    };
    let large = input.kinematics == Kinematics::Large;
    let mut cauchy = Matrix3::<S>::zeros();
    let mut volume = S::zero();
    out.min_det_f = f64::INFINITY;
    let mut b = [[Voigt::<S>::zeros(); 3]; MAX_GEN];
    for (gp, xi) in gauss_points().iter().enumerate() {
        let geo = reference_geometry(input.x_ref, *xi, gp, input.formulation, &centre)?;
        let h = displacement_gradient(input.dofs, &geo.grads, n_gen);
        let f = h + Matrix3::identity();
        let det_f = det3(&f);
        out.min_det_f = out.min_det_f.min(re(det_f));
        if large && re(det_f) <= 0.0 {
            return Err(ElementFailure::Inverted {
                gauss_point: gp,
                det_f: re(det_f),
            });
        }
        let strain = strain_measure(&h, large);
        let resp = material_point(input, out, gp, &strain)?;
        let sv = stress_to_voigt(&resp.stress);
        let w = geo.weight;
        // B rows: dE_voigt / d(d_Ai)
        for (a, (ba, g)) in b.iter_mut().zip(&geo.grads).enumerate().take(n_gen) {
            for (i, bai) in ba.iter_mut().enumerate() {
                // F^T e_i = row i of F (or e_i for small kinematics)
                let fr: Vector3<S> = if large {
                    Vector3::new(f[(i, 0)], f[(i, 1)], f[(i, 2)])
                } else {
                    let mut e = Vector3::zeros();
                    e[i] = S::one();
                    e
                };
                *bai = Voigt::from([
                    fr[0] * g[0],
                    fr[1] * g[1],
                    fr[2] * g[2],
                    fr[0] * g[1] + fr[1] * g[0],
                    fr[1] * g[2] + fr[2] * g[1],
                    fr[0] * g[2] + fr[2] * g[0],
                ]);
                out.force[3 * a + i] += bai.dot(&sv) * w;
            }
        }
        if let Some(k) = out.tangent.as_deref_mut() {
            let c = &resp.tangent;
            for a in 0..n_gen {
                for i in 0..3 {
                    let cb = c * b[a][i] * w; // C B_Ai w
                    let row = 3 * a + i;
                    for bb in 0..n_gen {
                        for j in 0..3 {
                            k[row * ndof + 3 * bb + j] += b[bb][j].dot(&cb);
                        }
                    }
                }
            }
            if large {
                for a in 0..n_gen {
                    let sg = resp.stress * geo.grads[a] * w;
                    for bb in 0..n_gen {
                        let v = geo.grads[bb].dot(&sg);
                        for i in 0..3 {
                            k[(3 * a + i) * ndof + 3 * bb + i] += v;
                        }
                    }
                }
            }
        }
        let sigma = if large {
            f * resp.stress * f.transpose() / det_f
        } else {
            resp.stress
        };
        let dv = if large { w * det_f } else { w };
        cauchy += sigma * dv;
        volume += dv;
    }
    out.cauchy = cauchy / volume;
    Ok(())
}

/// `Voigt` row of `sym(a (x) g)` with engineering shears.
#[inline]
fn sym_dyad_voigt<S: Scalar>(a: &Vector3<S>, g: &Vector3<S>) -> Voigt<S> {
    Voigt::from([
        a[0] * g[0],
        a[1] * g[1],
        a[2] * g[2],
        a[0] * g[1] + a[1] * g[0],
        a[1] * g[2] + a[2] * g[1],
        a[0] * g[2] + a[2] * g[0],
    ])
}

/// The F-bar variant of [`evaluate`] (see the module docs for the formulas).
fn evaluate_fbar<S: Scalar, M: MaterialLaw>(
    input: &Hex8Input<'_, S, M>,
    out: &mut Hex8Output<'_, S>,
) -> Result<(), ElementFailure> {
    const NDOF: usize = 24;
    debug_assert_eq!(input.dofs.len(), 8);
    debug_assert!(out.force.len() >= NDOF);
    let large = input.kinematics == Kinematics::Large;
    for f in out.force[..NDOF].iter_mut() {
        *f = S::zero();
    }
    if let Some(k) = out.tangent.as_deref_mut() {
        for v in k[..NDOF * NDOF].iter_mut() {
            *v = S::zero();
        }
    }
    // reference geometry of every Gauss point, and the element averages
    let mut grads = [[Vector3::<S>::zeros(); 8]; 8];
    let mut weights = [S::zero(); 8];
    for (gp, xi) in gauss_points().iter().enumerate() {
        let geo = reference_geometry(input.x_ref, *xi, gp, Hex8Formulation::Full, &None)?;
        grads[gp].copy_from_slice(&geo.grads[..8]);
        weights[gp] = geo.weight;
    }
    let mut volume0 = S::zero();
    let mut gbar = [Vector3::<S>::zeros(); 8];
    for (g_gp, w) in grads.iter().zip(&weights) {
        volume0 += *w;
        for (gb, g) in gbar.iter_mut().zip(g_gp) {
            *gb += g * *w;
        }
    }
    let inv_v0 = volume0.recip();
    for gb in gbar.iter_mut() {
        *gb *= inv_v0;
    }
    let mut h0 = Matrix3::<S>::zeros();
    for (d, g) in input.dofs.iter().zip(&gbar) {
        h0 += d * g.transpose();
    }
    let f0 = h0 + Matrix3::identity();
    // q0_A = F0^-T gbar_A (large), gbar_A (small); J0
    let (q0, j0) = if large {
        match inv3(&f0) {
            Some((f0inv, j0)) if re(j0) > 0.0 => {
                let t = f0inv.transpose();
                (gbar.map(|g| t * g), j0)
            }
            other => {
                return Err(ElementFailure::Inverted {
                    gauss_point: usize::MAX,
                    det_f: other.map(|v| re(v.1)).unwrap_or(0.0),
                })
            }
        }
    } else {
        (gbar, S::one())
    };
    let tr_h0 = h0.trace();
    let mut cauchy = Matrix3::<S>::zeros();
    let mut volume = S::zero();
    out.min_det_f = f64::INFINITY;
    let mut b = [[Voigt::<S>::zeros(); 3]; 8];
    let mut v = [[S::zero(); 3]; 8];
    let mut p = [[S::zero(); 3]; 8];
    let mut q = [Vector3::<S>::zeros(); 8];
    for (gp, (g_gp, &w)) in grads.iter().zip(&weights).enumerate() {
        let mut h = Matrix3::<S>::zeros();
        for (d, g) in input.dofs.iter().zip(g_gp) {
            h += d * g.transpose();
        }
        let f = h + Matrix3::identity();
        let det_f = det3(&f);
        out.min_det_f = out.min_det_f.min(re(det_f));
        // F-bar kinematics
        let (fbar, cbar, r, strain) = if large {
            let (finv, det) = match inv3(&f) {
                Some(x) if re(x.1) > 0.0 => x,
                _ => {
                    return Err(ElementFailure::Inverted {
                        gauss_point: gp,
                        det_f: re(det_f),
                    })
                }
            };
            let t = finv.transpose();
            for (qa, g) in q.iter_mut().zip(g_gp) {
                *qa = t * g;
            }
            // `* recip()`, not `/`: a dual quotient multiplies by the reciprocal, and the real
            // part of a dual evaluation must equal the f64 evaluation bit for bit
            let r = (j0 * det.recip()).cbrt();
            let fbar = f * r;
            let cbar = fbar.transpose() * fbar;
            let strain = (cbar - Matrix3::identity()) * S::lift(0.5);
            (fbar, cbar, r, strain)
        } else {
            q.copy_from_slice(g_gp);
            let eps = (h + h.transpose()) * S::lift(0.5);
            let strain = eps + Matrix3::from_diagonal_element((tr_h0 - h.trace()) / 3.0);
            (Matrix3::identity(), Matrix3::identity(), S::one(), strain)
        };
        let resp = material_point(input, out, gp, &strain)?;
        let sv = stress_to_voigt(&resp.stress);
        // Cbar in Voigt strain form (engineering shears): the dEbar of a unit d ln r
        let cbar_v = strain_to_voigt(&cbar);
        // r Fbar S (large); S (small): p_a = (this g_A)_i
        let rfs = if large {
            fbar * resp.stress * r
        } else {
            resp.stress
        };
        for (a, g) in g_gp.iter().enumerate() {
            let pa = rfs * g;
            for i in 0..3 {
                v[a][i] = (q0[a][i] - q[a][i]) / 3.0;
                p[a][i] = pa[i];
                // r Fbar^T e_i = r (row i of Fbar), or e_i
                let row: Vector3<S> = if large {
                    Vector3::new(fbar[(i, 0)], fbar[(i, 1)], fbar[(i, 2)]) * r
                } else {
                    let mut e = Vector3::zeros();
                    e[i] = S::one();
                    e
                };
                b[a][i] = sym_dyad_voigt(&row, g) + cbar_v * v[a][i];
                out.force[3 * a + i] += b[a][i].dot(&sv) * w;
            }
        }
        if let Some(k) = out.tangent.as_deref_mut() {
            let c = &resp.tangent;
            for a in 0..8 {
                for i in 0..3 {
                    let cb = c * b[a][i] * w; // C B_a w
                    let row = 3 * a + i;
                    for bb in 0..8 {
                        for j in 0..3 {
                            k[row * NDOF + 3 * bb + j] += b[bb][j].dot(&cb);
                        }
                    }
                }
            }
            if large {
                let s_c = resp.stress.component_mul(&cbar).sum(); // S : Cbar
                let r2 = r * r;
                for a in 0..8 {
                    let sg = resp.stress * g_gp[a];
                    for bb in 0..8 {
                        let gsg = g_gp[bb].dot(&sg) * r2;
                        for i in 0..3 {
                            let row = 3 * a + i;
                            for j in 0..3 {
                                let mut g_ab = (v[a][i] * p[bb][j] + v[bb][j] * p[a][i]) * 2.0
                                    + s_c * v[a][i] * v[bb][j] * 2.0
                                    + s_c
                                        * (q[a][j] * q[bb][i] - q0[a][j] * q0[bb][i])
                                        * (1.0 / 3.0);
                                if i == j {
                                    g_ab += gsg;
                                }
                                k[row * NDOF + 3 * bb + j] += g_ab * w;
                            }
                        }
                    }
                }
            }
        }
        let (sigma, dv) = if large {
            (fbar * resp.stress * fbar.transpose() / j0, w * det_f)
        } else {
            (resp.stress, w)
        };
        cauchy += sigma * dv;
        volume += dv;
    }
    out.cauchy = cauchy / volume;
    Ok(())
}

/// Element volume in the reference configuration (for tributary areas, mass checks).
pub(crate) fn reference_volume<S: Scalar>(x_ref: &[Vector3<S>; 8]) -> Result<S, ElementFailure> {
    let mut v = S::zero();
    for (gp, xi) in gauss_points().iter().enumerate() {
        let g = reference_geometry(x_ref, *xi, gp, Hex8Formulation::Full, &None)?;
        v += g.weight;
    }
    Ok(v)
}
