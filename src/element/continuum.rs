//! The continuum kernel: isoparametric solids of every shape (hex8, hex20, tet4, tet10,
//! wedge6, wedge15), total Lagrangian, generic over the scalar.
//!
//! One kernel integrates every solid family: a shape gives its `Interpolation` (node count
//! and shape-function derivatives in natural coordinates), a formulation its `Rule` (Gauss
//! points and weights) and whether it adds incompatible modes (hex8) or replaces `F` by F-bar.
//! Nothing below depends on the shape otherwise.
//!
//! ## Kinematics
//! Reference coordinates `X`, displacements `u`, deformation gradient
//! `F = I + sum_A d_A (x) g_A`, where the sum runs over the nodes (`d_A = u_a`,
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
//! ## Formulations
//! Each family takes the formulations its literature uses ([`Formulation`];
//! [`super::ElementFamily::new`] refuses the others): full integration, reduced integration
//! (hex20's 2x2x2), a higher-order rule (tet10's 14 points), incompatible modes (hex8) and
//! F-bar (every family with more than one Gauss point).
//!
//! ## Incompatible modes (hex8's bending-capable variant)
//! Wilson's bubble modes `phi_k = 1 - xi_k^2` with Taylor's correction (Simo & Armero 1992):
//! `Gtilde_k(xi) = (j0 / j(xi)) J0^-T dphi_k/dxi`, `J0` the Jacobian at the element centre.
//! `int Gtilde_k dV0 = 0`, so the patch test is passed. Their nine amplitudes `alpha` are
//! element-internal unknowns of the global system (not condensed here): the sparse LU eliminates
//! them as it would any interior DOF, and the sensitivity engine treats them like any other
//! unknown. Plain full integration locks in bending; this variant does not.
//!
//! ## F-bar (the volumetric-locking remedy)
//! After de Souza Neto, Peric, Dutko & Owen (1996), on the family's full rule: at each Gauss
//! point the deformation gradient is replaced by
//! `Fbar = r F`, `r = (J0 / J)^(1/3)`, `J = det F`, `J0 = det F0`,
//! so that the volume change of every Gauss point is the element's single `J0`: one volumetric
//! constraint per element instead of one per Gauss point, which is what removes volumetric locking (nearly
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
//! | `N_a` | shape functions of the element's `Interpolation` |
//! | `w_q` | Gauss weight of the `Rule` |
//! | `J = dX/dxi`, `j = det J` | reference Jacobian (the volume weight is `j w_q`) |
//! | `F`, `E`, `S` | deformation gradient, Green-Lagrange strain, PK2 stress |
//! | `g_A`, `B_A` | generalised shape gradient, strain-displacement row |
//! | `gbar_A`, `F0`, `J0` | element averages (F-bar): gradient, deformation gradient, its det |
//! | `r`, `Fbar`, `Cbar`, `Ebar` | F-bar factor `(J0/J)^(1/3)`, modified `F`, `C`, Green strain |
//! | `q_A`, `q0_A`, `v_a` | `F^-T g_A`, `F0^-T gbar_A`, `d ln r / dd_a` |
use crate::material::{strain_to_voigt, stress_to_voigt, Branch, MaterialLaw, Tangent, Voigt};
use crate::scalar::{det3, inv3, lift_vec, mat_mat, mat_vec, re, re_vec, tr_mat_mat, Scalar};
use nalgebra::{Matrix3, Vector3};

/// Most nodes of any registered family (hex20).
pub(crate) const MAX_NODES: usize = 20;
/// Most Gauss points of any registered family (hex20's 3x3x3).
pub(crate) const MAX_GAUSS: usize = 27;
/// Most generalised nodes (nodes plus groups of three internal unknowns) of any family.
pub(crate) const MAX_GEN: usize = 20;
/// Most element unknowns of any registered family.
pub(crate) const MAX_DOFS: usize = 3 * MAX_GEN;

/// Everything one element evaluation needs besides its unknowns.
pub struct ElementInput<'a, S: Scalar, M: MaterialLaw> {
    /// Reference coordinates of the nodes, in the shape's node order.
    pub x_ref: &'a [Vector3<S>],
    /// Unknowns: the nodal displacements, then the internal unknowns in groups of three.
    pub dofs: &'a [Vector3<S>],
    /// Strain measure.
    pub kinematics: Kinematics,
    /// The material law.
    pub material: &'a M,
    /// Material parameters lifted to `S`.
    pub params: &'a [S],
    /// Committed history, `n_gauss * material.history_len()` scalars.
    pub hist_old: &'a [S],
    /// Branch per Gauss point to impose (SDM's frozen evaluation), or `None`.
    pub frozen: Option<&'a [Branch]>,
}

/// What one element evaluation returns.
pub struct ElementOutput<'a, S: Scalar> {
    /// Internal force, `n_dofs` entries (node-major, component-minor).
    pub force: &'a mut [S],
    /// Tangent, row-major `n_dofs^2`, if wanted: every kernel writes each entry of it (the
    /// assembly hands it a slot holding another element's tangent).
    pub tangent: Option<&'a mut [S]>,
    /// Updated history, `n_gauss * history_len` scalars.
    pub hist_new: &'a mut [S],
    /// Branch taken at each Gauss point (`n_gauss` entries).
    pub branches: &'a mut [Branch],
    /// Trial yield ratio at each Gauss point (`n_gauss` entries).
    pub yield_ratio: &'a mut [f64],
    /// Volume-averaged Cauchy stress (set to zero where not [`ElementOutput::want_cauchy`]).
    pub cauchy: Matrix3<S>,
    /// Whether [`ElementOutput::cauchy`] is wanted: a differentiating evaluation (a recording
    /// or a dual one) of an element whose stress nothing reads skips its sums and
    /// differentiates no `det F` (under large kinematics 559 tape entries of a hex8's, with or
    /// without incompatible modes; 1,063 with F-bar).
    pub want_cauchy: bool,
    /// Smallest det F over the Gauss points (real part).
    pub min_det_f: f64,
}

impl<S: Scalar> ElementOutput<'_, S> {
    /// Zero the force and the tangent (if asked) of `ndof` unknowns.
    fn clear(&mut self, ndof: usize) {
        debug_assert!(self.force.len() >= ndof);
        for f in self.force[..ndof].iter_mut() {
            *f = S::zero();
        }
        if let Some(k) = self.tangent.as_deref_mut() {
            for v in k[..ndof * ndof].iter_mut() {
                *v = S::zero();
            }
        }
    }
}

/// Strain measure used by an element.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Kinematics {
    /// Total Lagrangian, Green-Lagrange strain and PK2 stress.
    Large,
    /// Linear strain (geometrically linear).
    Small,
}

/// How a solid element is integrated. Which formulations a shape takes, and its standard one
/// (a body that names none), is [`super::ElementFamily::new`]'s table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
#[non_exhaustive]
pub enum Formulation {
    /// The family's full Gauss rule: 2x2x2 (hex8), 3x3x3 (hex20), 1 point (tet4), 4 points
    /// (tet10), 3x2 (wedge6), 3x3 (wedge15). Hex8 locks in bending.
    Full,
    /// Reduced integration: 2x2x2 on hex20 (C3D20R), free of volumetric and shear locking.
    Reduced,
    /// A higher-order rule: tet10 on Walkington's 14-point degree-5 rule (exact for a curved
    /// tet10's stiffness up to its Jacobian's variation).
    HighOrder,
    /// Nine incompatible modes (Wilson-Taylor, Simo-Armero) on hex8: accurate in bending.
    IncompatibleModes,
    /// F-bar (de Souza Neto et al. 1996) on the family's full rule, variationally consistent:
    /// free of volumetric locking (near incompressibility, isochoric plastic flow), but not of
    /// shear locking in bending. B-bar under small kinematics. See the module docs.
    #[serde(rename = "f-bar")]
    FBar,
}

impl Formulation {
    /// Every formulation.
    pub const ALL: [Formulation; 5] = [
        Formulation::Full,
        Formulation::Reduced,
        Formulation::HighOrder,
        Formulation::IncompatibleModes,
        Formulation::FBar,
    ];

    /// Name as in scene files (`full`, `reduced`, `high-order`, `incompatible-modes`,
    /// `f-bar`).
    pub fn name(self) -> &'static str {
        match self {
            Formulation::Full => "full",
            Formulation::Reduced => "reduced",
            Formulation::HighOrder => "high-order",
            Formulation::IncompatibleModes => "incompatible-modes",
            Formulation::FBar => "f-bar",
        }
    }

    /// Number of element-internal unknowns (the hex8 incompatible modes' nine amplitudes).
    pub fn internal_dofs(self) -> usize {
        match self {
            Formulation::IncompatibleModes => 9,
            _ => 0,
        }
    }
}

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
    #[error("reference Jacobian determinant {det:.3e} at {}: the element is degenerate or inverted in the mesh", point_words(*gauss_point, "the element centre"))]
    BadReferenceGeometry {
        /// Gauss point (`usize::MAX`: the element centre of the incompatible modes).
        gauss_point: usize,
        /// Determinant of the reference Jacobian `dX/dxi` there.
        det: f64,
    },
    /// det F <= 0 at a Gauss point: the element turned inside out (recoverable by cutback).
    /// `gauss_point == usize::MAX`: the element-average `det F0` of the F-bar variant.
    #[error("det F = {det_f:.3e} at {}: element inverted", point_words(*gauss_point, "the element average (F-bar)"))]
    Inverted {
        /// Gauss point, or `usize::MAX` for the F-bar average.
        gauss_point: usize,
        /// `det F` there.
        det_f: f64,
    },
    /// A non-finite number appeared in the stress.
    #[error("non-finite stress at Gauss point {gauss_point}")]
    NonFinite {
        /// Gauss point.
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

/// A shape's interpolation: its node count and the derivatives of its shape functions with
/// respect to the natural coordinates.
pub(crate) struct Interpolation {
    /// Number of nodes.
    pub(crate) n_nodes: usize,
    /// `N_a` at `xi`, entries `0..n_nodes` written.
    pub(crate) values: fn([f64; 3]) -> [f64; MAX_NODES],
    /// `dN_a/dxi_j` at `xi`, rows `0..n_nodes` written.
    pub(crate) derivatives: fn([f64; 3]) -> [[f64; 3]; MAX_NODES],
}

/// A Gauss rule on a shape's natural domain.
pub(crate) struct Rule {
    /// Natural coordinates of the points.
    pub(crate) points: &'static [[f64; 3]],
    /// Their weights (summing to the natural domain's volume).
    pub(crate) weights: &'static [f64],
}

impl Rule {
    /// Number of points.
    pub(crate) fn len(&self) -> usize {
        self.points.len()
    }
}

/// A solid element's tables: what the kernel integrates.
pub(crate) struct Solid<'t> {
    /// The shape's interpolation.
    pub(crate) interpolation: &'t Interpolation,
    /// The Gauss rule.
    pub(crate) rule: &'t Rule,
    /// Hex8's incompatible modes (three bubble gradients after the nodes).
    pub(crate) enhanced: bool,
    /// F-bar (see the module docs).
    pub(crate) fbar: bool,
}

/// The real parts of `v` (at most `N`), the rest zero.
fn values<S: Scalar, const N: usize>(v: &[Vector3<S>]) -> [Vector3<f64>; N] {
    let mut out = [Vector3::zeros(); N];
    for (p, q) in out.iter_mut().zip(v) {
        *p = re_vec(q);
    }
    out
}

/// [`values`] where every component of `v` is a constant ([`Scalar::is_constant`]): the
/// inputs a kernel may compute with in `f64`.
fn values_if_constant<S: Scalar, const N: usize>(v: &[Vector3<S>]) -> Option<[Vector3<f64>; N]> {
    (v.iter().all(|p| p.iter().all(S::is_constant))).then(|| values(v))
}

/// `H = grad_X u = sum_A d_A g_A^T` at a Gauss point over the pairs of generalised
/// displacements `dofs` and gradients `grads` (the enhanced part included where given; F-bar's
/// element average too). Each entry is its own sum in the pairs' order, so the order of the
/// entries changes no value, and a recording's adjoints neither: each input's contributions
/// come in the same order.
fn displacement_gradient<S: Scalar>(dofs: &[Vector3<S>], grads: &[Vector3<S>]) -> Matrix3<S> {
    let mut h = Matrix3::<S>::zeros();
    for (d, g) in dofs.iter().zip(grads) {
        for i in 0..3 {
            for j in 0..3 {
                h[(i, j)] = h[(i, j)].add_mul(d[i], g[j]);
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
        (tr_mat_mat(&f, &f) - Matrix3::identity()) * S::lift(0.5)
    } else {
        (h + h.transpose()) * S::lift(0.5)
    }
}

/// F-bar's element averages ([`fbar_average`]): `q0_A = F0^-T gbar_A` (large kinematics;
/// `gbar_A` under small) for the volume-averaged gradients `gbar_A`, `J0 = det F0` (1 under
/// small), and `tr H0`.
struct FbarAverage<T> {
    q0: [Vector3<T>; MAX_NODES],
    j0: T,
    tr_h0: T,
}

impl FbarAverage<f64> {
    fn lift<S: Scalar>(&self) -> FbarAverage<S> {
        FbarAverage {
            q0: self.q0.map(|v| lift_vec(&v)),
            j0: S::lift(self.j0),
            tr_h0: S::lift(self.tr_h0),
        }
    }
}

/// F-bar's element averages over the Gauss points' gradients `grads` and volume weights
/// `weights`, with the displacements `dofs` (`nn` nodes). Generic over the scalar: a
/// differentiating evaluation with constant inputs computes it in `f64`.
#[inline(always)]
fn fbar_average<T: Scalar>(
    dofs: &[Vector3<T>],
    grads: &[[Vector3<T>; MAX_NODES]],
    weights: &[T],
    nn: usize,
    large: bool,
) -> Result<FbarAverage<T>, ElementFailure> {
    let mut volume0 = T::zero();
    let mut gbar = [Vector3::<T>::zeros(); MAX_NODES];
    for (g_gp, w) in grads.iter().zip(weights) {
        volume0 += *w;
        for (gb, g) in gbar.iter_mut().zip(&g_gp[..nn]) {
            *gb += g * *w;
        }
    }
    let inv_v0 = volume0.recip();
    for gb in gbar[..nn].iter_mut() {
        *gb *= inv_v0;
    }
    let h0 = displacement_gradient(dofs, &gbar[..nn]);
    let f0 = h0 + Matrix3::identity();
    let (q0, j0) = if large {
        match inv3(&f0) {
            Some((f0inv, j0)) if re(j0) > 0.0 => {
                let t = f0inv.transpose();
                (gbar.map(|g| mat_vec(&t, &g)), j0)
            }
            other => {
                return Err(ElementFailure::Inverted {
                    gauss_point: usize::MAX,
                    det_f: other.map(|v| re(v.1)).unwrap_or(0.0),
                })
            }
        }
    } else {
        (gbar, T::one())
    };
    Ok(FbarAverage {
        q0,
        j0,
        tr_h0: h0.trace(),
    })
}

/// F-bar's kinematics at a Gauss point ([`fbar_point`]): under large kinematics
/// `Fbar = r F` with `r = (J0 / det F)^(1/3)`, `Cbar = Fbar^T Fbar` and the strain
/// `(Cbar - I) / 2`; under small, `Fbar = Cbar = I`, `r = 1` and the strain
/// `sym H + (tr H0 - tr H) I / 3` (B-bar's).
struct FbarPoint<T> {
    fbar: Matrix3<T>,
    cbar: Matrix3<T>,
    r: T,
    strain: Matrix3<T>,
}

impl FbarPoint<f64> {
    fn lift<S: Scalar>(&self) -> FbarPoint<S> {
        FbarPoint {
            fbar: self.fbar.map(S::lift),
            cbar: self.cbar.map(S::lift),
            r: S::lift(self.r),
            strain: self.strain.map(S::lift),
        }
    }
}

/// F-bar's kinematics at a Gauss point with gradients `g`, displacement gradient `h` and
/// `F = I + h` (`None` where `F` is inverted or singular under large kinematics); `q` takes
/// `q_A = F^-T g_A` (large), `g_A` (small). Generic over the scalar, as [`fbar_average`].
#[inline(always)]
fn fbar_point<T: Scalar>(
    h: &Matrix3<T>,
    f: &Matrix3<T>,
    g: &[Vector3<T>],
    average: &FbarAverage<T>,
    large: bool,
    q: &mut [Vector3<T>],
) -> Option<FbarPoint<T>> {
    if !large {
        q.copy_from_slice(g);
        let eps = (h + h.transpose()) * T::lift(0.5);
        let strain = eps + Matrix3::from_diagonal_element((average.tr_h0 - h.trace()) / 3.0);
        return Some(FbarPoint {
            fbar: Matrix3::identity(),
            cbar: Matrix3::identity(),
            r: T::one(),
            strain,
        });
    }
    let (finv, det) = match inv3(f) {
        Some(x) if re(x.1) > 0.0 => x,
        _ => return None,
    };
    let t = finv.transpose();
    for (qa, ga) in q.iter_mut().zip(g) {
        *qa = mat_vec(&t, ga);
    }
    // `* recip()`, not `/`: a dual quotient multiplies by the reciprocal, and the real part
    // of a dual evaluation must equal the f64 evaluation bit for bit
    let r = (average.j0 * det.recip()).cbrt();
    let fbar = f * r;
    let cbar = tr_mat_mat(&fbar, &fbar);
    let strain = (cbar - Matrix3::identity()) * T::lift(0.5);
    Some(FbarPoint {
        fbar,
        cbar,
        r,
        strain,
    })
}

impl Solid<'_> {
    /// Number of generalised nodes: the nodes and, with incompatible modes, three more.
    pub(crate) fn generalised_nodes(&self) -> usize {
        self.interpolation.n_nodes + if self.enhanced { 3 } else { 0 }
    }

    /// The element's reference nodes, checked against the interpolation's count, with their
    /// values in `f64` where none carries a derivative.
    fn nodes<'x, S: Scalar>(&self, x: &'x [Vector3<S>]) -> Result<RefNodes<'x, S>, ElementFailure> {
        if x.len() != self.interpolation.n_nodes {
            return Err(ElementFailure::Layout {
                what: "nodes",
                expected: self.interpolation.n_nodes,
                got: x.len(),
            });
        }
        let plain = if S::DIFFERENTIATES {
            values_if_constant(x)
        } else {
            None
        };
        Ok(RefNodes { x, plain })
    }

    /// The centre Jacobian's inverse transpose and determinant (incompatible modes only).
    fn centre<S: Scalar>(
        &self,
        x_ref: &RefNodes<'_, S>,
    ) -> Result<Option<(Matrix3<S>, S)>, ElementFailure> {
        if !self.enhanced {
            return Ok(None);
        }
        let jac = self.jacobian(x_ref.x, [0.0; 3]).0;
        match inv3(&jac) {
            Some((inv, det)) if re(det) > 0.0 => Ok(Some((inv.transpose(), det))),
            other => Err(ElementFailure::BadReferenceGeometry {
                gauss_point: usize::MAX,
                det: other.map(|v| re(v.1)).unwrap_or(0.0),
            }),
        }
    }

    /// `J_ij = dX_i / dxi_j` at `xi`, and the shape-function derivatives there.
    fn jacobian<S: Scalar>(
        &self,
        x_ref: &[Vector3<S>],
        xi: [f64; 3],
    ) -> (Matrix3<S>, [[f64; 3]; MAX_NODES]) {
        let dn = (self.interpolation.derivatives)(xi);
        let mut jac = Matrix3::<S>::zeros();
        for (xa, da) in x_ref.iter().zip(&dn).take(self.interpolation.n_nodes) {
            for i in 0..3 {
                for j in 0..3 {
                    jac[(i, j)] += xa[i] * da[j];
                }
            }
        }
        (jac, dn)
    }

    /// Reference geometry at Gauss point `gp`, written into `geo`: the nodes' gradients, the
    /// incompatible modes' after them where `centre` is given (the rest are left as they
    /// were), and the volume weight.
    ///
    /// Where the reference nodes carry no derivative (every use but a shape parameter's:
    /// [`RefNodes::plain`]), the nodal part is computed in `f64` and lifted
    /// ([`Solid::nodal_geometry`]): the same
    /// values to the bit, without the Jacobian, its inverse and the gradients costing dual
    /// or recorded arithmetic on constants (a fifth of a J2 hex8's recording in reverse
    /// mode). The incompatible modes' part stays in `S`: its ratio `j0 / det` is rounded as
    /// each scalar divides (a dual number by the reciprocal).
    fn reference_geometry<S: Scalar>(
        &self,
        x_ref: &RefNodes<'_, S>,
        gp: usize,
        centre: &Option<(Matrix3<S>, S)>,
        geo: &mut GaussGeometry<S>,
    ) -> Result<(), ElementFailure> {
        let n = self.interpolation.n_nodes;
        let det = match &x_ref.plain {
            Some(plain) => {
                let mut g = GaussGeometry::<f64>::default();
                let det = self.nodal_geometry(&plain[..n], gp, &mut g)?;
                for (o, v) in geo.grads.iter_mut().zip(&g.grads).take(n) {
                    *o = lift_vec(v);
                }
                geo.weight = S::lift(g.weight);
                S::lift(det)
            }
            None => self.nodal_geometry(x_ref.x, gp, geo)?,
        };
        if let Some((j0inv_t, j0)) = centre {
            let xi = self.rule.points[gp];
            let scale = *j0 / det;
            for k in 0..3 {
                let mut dphi = Vector3::<S>::zeros();
                dphi[k] = S::lift(-2.0 * xi[k]);
                geo.grads[n + k] = mat_vec(j0inv_t, &dphi) * scale;
            }
        }
        Ok(())
    }

    /// The nodal part of [`Solid::reference_geometry`]: the nodes' gradients and the volume
    /// weight written into `geo`, and the Jacobian's determinant returned.
    fn nodal_geometry<S: Scalar>(
        &self,
        x_ref: &[Vector3<S>],
        gp: usize,
        geo: &mut GaussGeometry<S>,
    ) -> Result<S, ElementFailure> {
        let xi = self.rule.points[gp];
        let (jac, dn) = self.jacobian(x_ref, xi);
        let (jinv, det) = match inv3(&jac) {
            Some(v) if re(v.1) > 0.0 => v,
            other => {
                return Err(ElementFailure::BadReferenceGeometry {
                    gauss_point: gp,
                    det: other.map(|v| re(v.1)).unwrap_or(0.0),
                })
            }
        };
        // grad_X N = J^-T dN/dxi
        let jinv_t = jinv.transpose();
        let n = self.interpolation.n_nodes;
        for (g, d) in geo.grads.iter_mut().zip(&dn).take(n) {
            let dxi = Vector3::new(S::lift(d[0]), S::lift(d[1]), S::lift(d[2]));
            *g = mat_vec(&jinv_t, &dxi);
        }
        geo.weight = det * self.rule.weights[gp];
        Ok(det)
    }

    /// The strain each Gauss point's material sees for the generalised displacements `dofs`
    /// (the evaluation's strain, without its stress update), written into `out[..n_gauss]`.
    /// `Ok(false)` for F-bar, whose points see a strain modified by the whole element.
    pub(crate) fn gauss_strains<S: Scalar>(
        &self,
        x_ref: &[Vector3<S>],
        dofs: &[Vector3<S>],
        kinematics: Kinematics,
        out: &mut [Matrix3<S>],
    ) -> Result<bool, ElementFailure> {
        if self.fbar {
            return Ok(false);
        }
        let x_ref = &self.nodes(x_ref)?;
        let centre = self.centre(x_ref)?;
        let n_gen = self.generalised_nodes();
        let mut geo = GaussGeometry::default();
        for (gp, e) in out.iter_mut().enumerate().take(self.rule.len()) {
            self.reference_geometry(x_ref, gp, &centre, &mut geo)?;
            let h = displacement_gradient(dofs, &geo.grads[..n_gen]);
            *e = strain_measure(&h, kinematics == Kinematics::Large);
        }
        Ok(true)
    }

    /// The shape functions at every Gauss point and the point's reference volume weight
    /// `j w_q` (for integrals over the element: errors, body forces).
    pub(crate) fn quadrature(
        &self,
        x_ref: &[Vector3<f64>],
    ) -> Result<Vec<([f64; MAX_NODES], f64)>, ElementFailure> {
        let x_ref = &self.nodes(x_ref)?;
        let mut geo = GaussGeometry::default();
        (0..self.rule.len())
            .map(|gp| {
                self.reference_geometry(x_ref, gp, &None, &mut geo)?;
                Ok((
                    (self.interpolation.values)(self.rule.points[gp]),
                    geo.weight,
                ))
            })
            .collect()
    }

    /// Element volume in the reference configuration.
    pub(crate) fn reference_volume<S: Scalar>(
        &self,
        x_ref: &[Vector3<S>],
    ) -> Result<S, ElementFailure> {
        let x_ref = &self.nodes(x_ref)?;
        let mut v = S::zero();
        let mut geo = GaussGeometry::default();
        for gp in 0..self.rule.len() {
            self.reference_geometry(x_ref, gp, &None, &mut geo)?;
            v += geo.weight;
        }
        Ok(v)
    }

    /// Evaluate internal force (and the tangent if asked), the updated history and the
    /// branch of every Gauss point.
    pub(crate) fn evaluate<S: Scalar, M: MaterialLaw>(
        &self,
        input: &ElementInput<'_, S, M>,
        out: &mut ElementOutput<'_, S>,
    ) -> Result<(), ElementFailure> {
        let x_ref = &self.nodes(input.x_ref)?;
        let ng = self.rule.len();
        if let Some(f) = input.frozen.filter(|f| f.len() != ng) {
            return Err(ElementFailure::Layout {
                what: "frozen branches",
                expected: ng,
                got: f.len(),
            });
        }
        let n_gen = self.generalised_nodes();
        if input.dofs.len() != n_gen {
            return Err(ElementFailure::Layout {
                what: "generalised nodes",
                expected: n_gen,
                got: input.dofs.len(),
            });
        }
        if self.fbar {
            self.evaluate_fbar(x_ref, input, out)
        } else {
            self.evaluate_standard(x_ref, input, out)
        }
    }

    /// The standard displacement formulation (with incompatible modes if enhanced).
    fn evaluate_standard<S: Scalar, M: MaterialLaw>(
        &self,
        x_ref: &RefNodes<'_, S>,
        input: &ElementInput<'_, S, M>,
        out: &mut ElementOutput<'_, S>,
    ) -> Result<(), ElementFailure> {
        let n_gen = self.generalised_nodes();
        let ndof = 3 * n_gen;
        out.clear(ndof);
        let centre = self.centre(x_ref)?;
        let large = input.kinematics == Kinematics::Large;
        let mut cauchy = Matrix3::<S>::zeros();
        let mut volume = S::zero();
        out.min_det_f = f64::INFINITY;
        let mut b = [[Voigt::<S>::zeros(); 3]; MAX_GEN];
        let mut geo = GaussGeometry::default();
        // with constant displacements and reference nodes (a recording's element whose
        // history alone is an input; a dual pseudo-load in a material or friction
        // parameter), the kinematics in `f64`, the same values to the bit
        let plain: Option<[Vector3<f64>; MAX_GEN]> = x_ref.constant_dofs(input.dofs);
        for gp in 0..self.rule.len() {
            self.reference_geometry(x_ref, gp, &centre, &mut geo)?;
            let (f, strain) = match &plain {
                Some(dofs) => {
                    let grads: [Vector3<f64>; MAX_GEN] = values(&geo.grads[..n_gen]);
                    let h = displacement_gradient(&dofs[..n_gen], &grads[..n_gen]);
                    let f = h + Matrix3::identity();
                    let strain = strain_measure(&h, large);
                    (f.map(S::lift), strain.map(S::lift))
                }
                None => {
                    let h = displacement_gradient(input.dofs, &geo.grads[..n_gen]);
                    (h + Matrix3::identity(), strain_measure(&h, large))
                }
            };
            let det_f = det_f_of(&f, large, out);
            out.min_det_f = out.min_det_f.min(re(det_f));
            if large && re(det_f) <= 0.0 {
                return Err(ElementFailure::Inverted {
                    gauss_point: gp,
                    det_f: re(det_f),
                });
            }
            let resp = material_point(input, out, gp, &strain)?;
            let w = geo.weight;
            let dv = out.want_cauchy.then(|| if large { w * det_f } else { w });
            if let Some(dv) = dv {
                volume += dv;
            }
            if without_b_rows(out) {
                // f_Ai += w B_Ai : S = w (F S g_A)_i ((S g_A)_i for small kinematics), and
                // sigma dv = (w F S) F^T
                let ps = if large {
                    mat_mat(&f, &resp.stress)
                } else {
                    resp.stress
                } * w;
                for (a, g) in geo.grads.iter().enumerate().take(n_gen) {
                    let fa = mat_vec(&ps, g);
                    for i in 0..3 {
                        out.force[3 * a + i] += fa[i];
                    }
                }
                if out.want_cauchy {
                    cauchy += if large { ps * f.transpose() } else { ps };
                }
                continue;
            }
            let sv = stress_to_voigt(&resp.stress);
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
                    *bai = sym_dyad_voigt(&fr, g);
                    out.force[3 * a + i] += bai.dot(&sv) * w;
                }
            }
            if let Some(k) = out.tangent.as_deref_mut() {
                add_material_tangent(k, &b[..n_gen], &resp.tangent, w);
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
            if let Some(dv) = dv {
                let sigma = if large {
                    mat_mat(&mat_mat(&f, &resp.stress), &f.transpose()) / det_f
                } else {
                    resp.stress
                };
                cauchy += sigma * dv;
            }
        }
        out.cauchy = if out.want_cauchy {
            cauchy / volume
        } else {
            Matrix3::zeros()
        };
        Ok(())
    }

    /// The F-bar variant of [`Solid::evaluate`] (see the module docs for the formulas).
    fn evaluate_fbar<S: Scalar, M: MaterialLaw>(
        &self,
        x_ref: &RefNodes<'_, S>,
        input: &ElementInput<'_, S, M>,
        out: &mut ElementOutput<'_, S>,
    ) -> Result<(), ElementFailure> {
        let nn = self.interpolation.n_nodes;
        let ng = self.rule.len();
        let ndof = 3 * nn;
        let large = input.kinematics == Kinematics::Large;
        out.clear(ndof);
        // reference geometry of every Gauss point, and the element averages
        let mut grads = [[Vector3::<S>::zeros(); MAX_NODES]; MAX_GAUSS];
        let mut weights = [S::zero(); MAX_GAUSS];
        let mut geo = GaussGeometry::default();
        for gp in 0..ng {
            self.reference_geometry(x_ref, gp, &None, &mut geo)?;
            grads[gp][..nn].copy_from_slice(&geo.grads[..nn]);
            weights[gp] = geo.weight;
        }
        let (grads, weights) = (&grads[..ng], &weights[..ng]);
        // with constant displacements and reference nodes, F-bar's kinematics in `f64` (as
        // the standard formulation's): the same values to the bit, lifted
        let plain = match x_ref.constant_dofs::<MAX_NODES>(input.dofs) {
            Some(dofs) => {
                let mut g64 = [[Vector3::<f64>::zeros(); MAX_NODES]; MAX_GAUSS];
                for (o, g) in g64.iter_mut().zip(grads) {
                    *o = values(&g[..nn]);
                }
                let mut w64 = [0.0; MAX_GAUSS];
                for (o, w) in w64.iter_mut().zip(weights) {
                    *o = re(*w);
                }
                let average = fbar_average(&dofs[..nn], &g64[..ng], &w64[..ng], nn, large)?;
                Some((dofs, g64, average))
            }
            None => None,
        };
        let average: FbarAverage<S> = match &plain {
            Some((.., average)) => average.lift(),
            None => fbar_average(input.dofs, grads, weights, nn, large)?,
        };
        let (q0, j0) = (&average.q0, average.j0);
        let mut cauchy = Matrix3::<S>::zeros();
        let mut volume = S::zero();
        out.min_det_f = f64::INFINITY;
        let mut b = [[Voigt::<S>::zeros(); 3]; MAX_NODES];
        let mut v = [[S::zero(); 3]; MAX_NODES];
        let mut p = [[S::zero(); 3]; MAX_NODES];
        let mut q = [Vector3::<S>::zeros(); MAX_NODES];
        // the geometric tangent's per-column factors (below), written anew at every Gauss
        // point up to `ndof`; gsg[i][3 B + i] = r^2 g_B . S g_A, zero off the block diagonals
        // (never written there): adding that zero to every entry leaves each entry's value as
        // a branch on i = j would (up to the sign of a zero), and the loop has no branch
        let mut v_c = [S::zero(); 3 * MAX_NODES];
        let mut p_c = [S::zero(); 3 * MAX_NODES];
        let mut q_cols = [[S::zero(); 3 * MAX_NODES]; 3];
        let mut q0_cols = [[S::zero(); 3 * MAX_NODES]; 3];
        let mut q_row = [S::zero(); 3 * MAX_NODES];
        let mut q0_row = [S::zero(); 3 * MAX_NODES];
        let mut gsg = [[S::zero(); 3 * MAX_NODES]; 3];
        // the shortcut's q_A in f64, before they are lifted into `q`
        let mut q64 = [Vector3::<f64>::zeros(); MAX_NODES];
        for (gp, (g_gp, &w)) in grads.iter().zip(weights).enumerate() {
            let g_gp = &g_gp[..nn];
            // F, then det F (a recording's tape as it always was: det F before the F-bar
            // kinematics), then those kinematics
            let (det_f, point) = match &plain {
                Some((dofs, g64, average)) => {
                    let h = displacement_gradient(&dofs[..nn], &g64[gp][..nn]);
                    let f = h + Matrix3::identity();
                    let det_f = det_f_of(&f.map(S::lift), large, out);
                    let point = fbar_point(&h, &f, &g64[gp][..nn], average, large, &mut q64[..nn]);
                    for (o, v) in q.iter_mut().zip(&q64[..nn]) {
                        *o = lift_vec(v);
                    }
                    (det_f, point.map(|p| p.lift()))
                }
                None => {
                    let h = displacement_gradient(input.dofs, g_gp);
                    let f = h + Matrix3::identity();
                    let det_f = det_f_of(&f, large, out);
                    (
                        det_f,
                        fbar_point(&h, &f, g_gp, &average, large, &mut q[..nn]),
                    )
                }
            };
            out.min_det_f = out.min_det_f.min(re(det_f));
            let Some(FbarPoint {
                fbar,
                cbar,
                r,
                strain,
            }) = point
            else {
                return Err(ElementFailure::Inverted {
                    gauss_point: gp,
                    det_f: re(det_f),
                });
            };
            let resp = material_point(input, out, gp, &strain)?;
            let sv = stress_to_voigt(&resp.stress);
            // Cbar in Voigt strain form (engineering shears): the dEbar of a unit d ln r (in
            // the B rows alone)
            let cbar_v = if without_b_rows(out) {
                Voigt::zeros()
            } else {
                strain_to_voigt(&cbar)
            };
            // r Fbar S (large); S (small): p_a = (this g_A)_i
            let rfs = if large {
                mat_mat(&fbar, &resp.stress) * r
            } else {
                resp.stress
            };
            // without B rows: f_Ai += w B_Ai : S = w (p_Ai + v_Ai S : Cbar)
            let s_cbar = without_b_rows(out).then(|| resp.stress.component_mul(&cbar).sum());
            for (a, g) in g_gp.iter().enumerate() {
                let pa = mat_vec(&rfs, g);
                for i in 0..3 {
                    v[a][i] = (q0[a][i] - q[a][i]) / 3.0;
                    p[a][i] = pa[i];
                    if let Some(s_c) = s_cbar {
                        out.force[3 * a + i] += (pa[i] + v[a][i] * s_c) * w;
                        continue;
                    }
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
                add_material_tangent(k, &b[..nn], &resp.tangent, w);
                if large {
                    let s_c = resp.stress.component_mul(&cbar).sum(); // S : Cbar
                    let r2 = r * r;
                    // G_ab for a = (A, i), b = (B, j), a row of K at a time over the flat
                    // column index c = 3 B + j: the factors indexed by b laid out by c
                    // (`q_cols[i][c] = (q_B)_i`), those indexed by (A, j) per row
                    // (`q_row[c] = (q_A)_j`), so that the inner loop reads contiguous slices
                    for bb in 0..nn {
                        for j in 0..3 {
                            let c = 3 * bb + j;
                            v_c[c] = v[bb][j];
                            p_c[c] = p[bb][j];
                            for i in 0..3 {
                                q_cols[i][c] = q[bb][i];
                                q0_cols[i][c] = q0[bb][i];
                            }
                        }
                    }
                    let (v_c, p_c) = (&v_c[..ndof], &p_c[..ndof]);
                    for a in 0..nn {
                        let sg = resp.stress * g_gp[a];
                        for bb in 0..nn {
                            // r^2 g_B . S g_A, on the diagonal i = j of the block
                            let gs = g_gp[bb].dot(&sg) * r2;
                            for j in 0..3 {
                                q_row[3 * bb + j] = q[a][j];
                                q0_row[3 * bb + j] = q0[a][j];
                                gsg[j][3 * bb + j] = gs;
                            }
                        }
                        let (q_row, q0_row) = (&q_row[..ndof], &q0_row[..ndof]);
                        for i in 0..3 {
                            let row = 3 * a + i;
                            let (va, pa) = (v[a][i], p[a][i]);
                            let s_va = s_c * va;
                            let (q_col, q0_col) = (&q_cols[i][..ndof], &q0_cols[i][..ndof]);
                            let gsg = &gsg[i][..ndof];
                            let k_row = &mut k[row * ndof..(row + 1) * ndof];
                            for c in 0..ndof {
                                let g_ab = (va * p_c[c] + v_c[c] * pa) * 2.0
                                    + s_va * v_c[c] * 2.0
                                    + s_c
                                        * (q_row[c] * q_col[c] - q0_row[c] * q0_col[c])
                                        * (1.0 / 3.0);
                                k_row[c] += (g_ab + gsg[c]) * w;
                            }
                        }
                    }
                }
            }
            if out.want_cauchy {
                let (sigma, dv) = if large {
                    (fbar * resp.stress * fbar.transpose() / j0, w * det_f)
                } else {
                    (resp.stress, w)
                };
                cauchy += sigma * dv;
                volume += dv;
            }
        }
        out.cauchy = if out.want_cauchy {
            cauchy / volume
        } else {
            Matrix3::zeros()
        };
        Ok(())
    }
}

/// `det F` of `f`, differentiated only where the Cauchy stress's volume reads it (large
/// kinematics and [`ElementOutput::want_cauchy`]): elsewhere a differentiating scalar
/// ([`Scalar::DIFFERENTIATES`]) reads only its value (the smallest `det F`, the inversion
/// check), and a constant of that value (the same `f64` operations on the real parts) spares
/// a recording its tape entries (about fourteen a Gauss point) and a dual evaluation its
/// derivative parts. `f64` computes it as ever.
fn det_f_of<S: Scalar>(f: &Matrix3<S>, large: bool, out: &ElementOutput<'_, S>) -> S {
    if S::DIFFERENTIATES && !(large && out.want_cauchy) {
        S::lift(det3(&f.map(re)))
    } else {
        det3(f)
    }
}

/// Whether an evaluation sums its force without the B rows: a recording ([`Scalar::RECORDS`])
/// that wants no tangent. `f_Ai = w B_Ai : S` is then summed from the stress directly, the same
/// sums in fewer operations, each of which a tape stores and a sweep reads (a J2 hex8's tape
/// 8,419 -> 4,699 entries). Other scalars keep the B rows: a dual evaluation's real part is
/// the `f64` one to the bit, and the `f64` residual is the same with and without its tangent.
fn without_b_rows<S: Scalar>(out: &ElementOutput<'_, S>) -> bool {
    S::RECORDS && out.tangent.is_none()
}

/// An element's reference nodes ([`Solid::nodes`]).
struct RefNodes<'x, S: Scalar> {
    x: &'x [Vector3<S>],
    /// Their values, where none carries a derivative (never for `f64`, which needs no copy).
    plain: Option<[Vector3<f64>; MAX_NODES]>,
}

impl<S: Scalar> RefNodes<'_, S> {
    /// The values of the displacements `dofs` where they and the reference nodes carry no
    /// derivative: the element's kinematics may then be computed in `f64` and lifted.
    fn constant_dofs<const N: usize>(&self, dofs: &[Vector3<S>]) -> Option<[Vector3<f64>; N]> {
        self.plain.and_then(|_| values_if_constant(dofs))
    }
}

/// Reference geometry at one Gauss point: generalised gradients and the volume weight.
struct GaussGeometry<S: Scalar> {
    grads: [Vector3<S>; MAX_GEN],
    weight: S,
}

impl<S: Scalar> Default for GaussGeometry<S> {
    fn default() -> Self {
        GaussGeometry {
            grads: [Vector3::zeros(); MAX_GEN],
            weight: S::zero(),
        }
    }
}

/// The material update at Gauss point `gp` (branch frozen if asked), with its bookkeeping:
/// history slot, branch, yield ratio, finiteness.
fn material_point<S: Scalar, M: MaterialLaw>(
    input: &ElementInput<'_, S, M>,
    out: &mut ElementOutput<'_, S>,
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
        out.tangent.is_some(),
    );
    if !resp.stress.iter().all(|s| re(*s).is_finite()) {
        return Err(ElementFailure::NonFinite { gauss_point: gp });
    }
    out.branches[gp] = resp.branch;
    out.yield_ratio[gp] = resp.yield_ratio;
    Ok(resp)
}

/// `Gauss point N`, or `centre` for the `usize::MAX` of an element failure that is at no
/// Gauss point.
fn point_words(gauss_point: usize, centre: &str) -> String {
    if gauss_point == usize::MAX {
        centre.to_string()
    } else {
        format!("Gauss point {gauss_point}")
    }
}

/// `K += B^T C B w`, `K` row-major over the unknowns of the rows `b` (three per generalised
/// node).
///
/// Each entry adds the dot product of a row of `B` with `C B_Ai w`, summed as
/// [`nalgebra::Matrix::dot`] sums six terms (from zero, one term after the other); the rows
/// of `B` are first laid out by strain component, contiguous over the unknowns, so that a
/// row of `K` is summed over its columns at once (for `f64`, in vector registers).
///
/// For `f64` on a processor with AVX2 the same code is compiled for it and chosen at run
/// time: each entry is summed in the same order, four columns to a register instead of two
/// (no fused multiply-add), so `K` is the same bit for bit.
fn add_material_tangent<S: Scalar>(k: &mut [S], b: &[[Voigt<S>; 3]], c: &Tangent<S>, w: S) {
    #[cfg(target_arch = "x86_64")]
    if std::any::TypeId::of::<S>() == std::any::TypeId::of::<f64>()
        && std::is_x86_feature_detected!("avx2")
    {
        // SAFETY: `S` is `f64` (the same type, so the same layout), and the processor has
        // AVX2, the one feature the callee is compiled for.
        unsafe {
            let k = &mut *(k as *mut [S] as *mut [f64]);
            let b = &*(b as *const [[Voigt<S>; 3]] as *const [[Voigt<f64>; 3]]);
            let c = &*(c as *const Tangent<S> as *const Tangent<f64>);
            let w = *(&w as *const S as *const f64);
            return add_material_tangent_avx2(k, b, c, w);
        }
    }
    material_tangent_sum(k, b, c, w);
}

/// [`add_material_tangent`] compiled for AVX2.
///
/// # Safety
/// The processor must have AVX2 (an `unsafe fn`, not a safe one with the feature, for the
/// crate's `rust-version`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn add_material_tangent_avx2(
    k: &mut [f64],
    b: &[[Voigt<f64>; 3]],
    c: &Tangent<f64>,
    w: f64,
) {
    material_tangent_sum(k, b, c, w);
}

/// The body of [`add_material_tangent`], inlined into each of its compilations.
#[inline(always)]
fn material_tangent_sum<S: Scalar>(k: &mut [S], b: &[[Voigt<S>; 3]], c: &Tangent<S>, w: S) {
    let ndof = 3 * b.len();
    // `bt[m][3 a + i]` = component `m` of row `B_Ai`
    let mut bt = [[S::zero(); MAX_DOFS]; 6];
    for (a, ba) in b.iter().enumerate() {
        for (i, bai) in ba.iter().enumerate() {
            for (m, v) in bai.iter().enumerate() {
                bt[m][3 * a + i] = *v;
            }
        }
    }
    let bt = bt.each_ref().map(|r| &r[..ndof]);
    for (a, ba) in b.iter().enumerate() {
        for (i, bai) in ba.iter().enumerate() {
            let cb = c * bai * w; // C B_Ai w
            let row = 3 * a + i;
            let k_row = &mut k[row * ndof..(row + 1) * ndof];
            for (col, kc) in k_row.iter_mut().enumerate() {
                let mut dot = S::zero();
                for m in 0..6 {
                    dot += bt[m][col] * cb[m];
                }
                *kc += dot;
            }
        }
    }
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

#[cfg(test)]
mod tests {
    use crate::element::{ElementFamily, Shape};

    /// Exact integral of `x^i y^j z^k` over a shape's natural domain.
    fn monomial(shape: Shape, [i, j, k]: [i32; 3]) -> f64 {
        let fact = |n: i32| (1..=n).map(f64::from).product::<f64>();
        let line = |p: i32| {
            if p % 2 == 1 {
                0.0
            } else {
                2.0 / f64::from(p + 1)
            }
        };
        match shape.corners() {
            Shape::Hex8 => line(i) * line(j) * line(k),
            Shape::Tet4 => fact(i) * fact(j) * fact(k) / fact(i + j + k + 3),
            _ => fact(i) * fact(j) / fact(i + j + 2) * line(k),
        }
    }

    #[test]
    fn a_failure_at_no_gauss_point_names_where_it_is() {
        use super::ElementFailure;
        let average = ElementFailure::Inverted {
            gauss_point: usize::MAX,
            det_f: -2.39,
        };
        assert_eq!(
            average.to_string(),
            "det F = -2.390e0 at the element average (F-bar): element inverted"
        );
        let point = ElementFailure::Inverted {
            gauss_point: 3,
            det_f: -2.39,
        };
        assert!(point.to_string().contains("at Gauss point 3:"));
        let centre = ElementFailure::BadReferenceGeometry {
            gauss_point: usize::MAX,
            det: 0.0,
        };
        assert!(centre.to_string().contains("at the element centre:"));
    }

    #[test]
    fn every_rule_integrates_its_degree_exactly() {
        // (family, total degree for simplices; per-axis degrees for the products)
        for family in ElementFamily::solids() {
            let solid = family.solid().unwrap();
            let shape = family.shape();
            let (tri_degree, axis_degree) = match family.name() {
                "tet4" => (1, 0),
                "tet10" | "tet10-f-bar" => (2, 0),
                "tet10-high-order" => (5, 0),
                "wedge6" | "wedge6-f-bar" => (2, 3),
                "wedge15" | "wedge15-f-bar" => (2, 5),
                "hex20" | "hex20-f-bar" => (0, 5),
                _ => (0, 3), // 2x2x2
            };
            let mut checked = 0;
            for i in 0..=6 {
                for j in 0..=6 {
                    for k in 0..=6 {
                        let exact_expected = match shape.corners() {
                            Shape::Hex8 => i <= axis_degree && j <= axis_degree && k <= axis_degree,
                            Shape::Tet4 => i + j + k <= tri_degree,
                            _ => i + j <= tri_degree && k <= axis_degree,
                        };
                        if !exact_expected {
                            continue;
                        }
                        let q: f64 = (solid.rule.points.iter().zip(solid.rule.weights))
                            .map(|(p, w)| w * p[0].powi(i) * p[1].powi(j) * p[2].powi(k))
                            .sum();
                        let exact = monomial(shape, [i, j, k]);
                        // round-off of summing up to 27 terms of the volume's size
                        let volume: f64 = solid.rule.weights.iter().sum();
                        assert!(
                            (q - exact).abs() < 1e-14 * volume,
                            "{}: x^{i} y^{j} z^{k}: {q} vs {exact}",
                            family.name()
                        );
                        checked += 1;
                    }
                }
            }
            assert!(checked > 0);
        }
    }

    #[test]
    fn interpolations_are_nodal_partitions_of_unity_with_their_slopes() {
        for shape in Shape::SOLIDS {
            let family = ElementFamily::standard(shape);
            let interp = family.solid().unwrap().interpolation;
            let nn = interp.n_nodes;
            for (a, xa) in shape.natural_nodes().iter().enumerate() {
                let n = (interp.values)(*xa);
                for (b, v) in n.iter().enumerate().take(nn) {
                    let expected = if a == b { 1.0 } else { 0.0 };
                    assert!((v - expected).abs() < 1e-14, "{shape:?} N_{b} at node {a}");
                }
            }
            let xi = [0.21, 0.17, 0.33];
            let n = (interp.values)(xi);
            assert!((n[..nn].iter().sum::<f64>() - 1.0).abs() < 1e-14);
            let d = (interp.derivatives)(xi);
            let h = 1e-6;
            for j in 0..3 {
                let (mut p, mut m) = (xi, xi);
                p[j] += h;
                m[j] -= h;
                let (np, nm) = ((interp.values)(p), (interp.values)(m));
                for a in 0..nn {
                    let fd = (np[a] - nm[a]) / (2.0 * h);
                    // central difference of a cubic at most: error h^2 ~ 1e-12, round-off 1e-10
                    assert!((fd - d[a][j]).abs() < 1e-9, "{shape:?} dN_{a}/dxi_{j}");
                }
                // the derivatives of a partition of unity sum to zero
                assert!(d[..nn].iter().map(|r| r[j]).sum::<f64>().abs() < 1e-13);
            }
        }
    }
}
