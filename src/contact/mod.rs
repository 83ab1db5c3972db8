//! Node-to-segment frictional contact.
//!
//! A contact pair joins a set of hitting (slave) nodes of a deformable body to a target (master)
//! surface: the faces of a deformable body (quad4, quad8, tri3, tri6; the quadratic ones curved),
//! or an analytic rigid surface moving with a prescribed translation `d(t)`.
//!
//! ## Normal contact
//! For each hitting node the closest-point projection onto the target gives the contact point
//! `xbar`, its convected coordinates `xi`, the outward normal `n` and the gap
//! `g = (x - xbar) . n` (positive = open; [`geometry`]). The normal force `p_n >= 0` is
//! * a Lagrange multiplier `lambda` (an unknown of the global system, eqs. 13-14 and 25-26 of
//!   the paper) with the primal-dual active set rule: the node is active when
//!   `lambda - c k g >= 0` (real parts, `c` = [`ContactPair::activation`]); active rows enforce `-k g = 0`,
//!   inactive ones `lambda = 0`, so the sparsity pattern never changes (`k` scales the rows to
//!   force units);
//! * or a penalty force `p_n = eps_N A <-g>` (`A` the node's tributary area, so a uniform
//!   penetration carries a uniform pressure; the multiplier stays zero);
//! * or an augmented Lagrangian (Uzawa): `p_n = <lambda_bar - eps_N A g>`, the estimate
//!   `lambda_bar` carried per node and moved towards `p_n` after each converged pass, the
//!   increment solved again until no node carrying a normal force is off the target, either
//!   way, by more than a tolerance.
//!
//! The trade (measured on the patch test, `tests/oracles/contact_laws.rs`): Lagrange multipliers are
//! exact (no penetration) in one pass, but add an unknown per hitting node and make the system
//! indefinite (LU with pivoting); the penalty needs no multiplier and is definite, but the
//! bodies interpenetrate by `p / eps_N` and a stiff `eps_N` ill-conditions the tangent; the
//! augmented Lagrangian keeps the penalty's system and reaches the tolerance's penetration at
//! the price of repeated passes (2 on the patch test). Its design sensitivities treat the
//! estimate as history and are exact only as the penetration tolerance goes to zero.
//!
//! ## Friction
//! A stick anchor per hitting node, a material point of the target (on a rigid body: a point in
//! the body's frame; on a deformable target: a face and its `xi`), is carried as history. The
//! elastic slip is `g_T = (I - n n)(x - x_anchor)`, the trial force `t_trial = -eps_T g_T`, and
//! the [`friction::FrictionLaw`] returns it to its slip surface. On slip the anchor moves to
//! `x + t / eps_T` (projected on the target), so the elastic slip keeps the returned force;
//! while a node is open the anchor follows the contact point. The anchor is carried across
//! segment boundaries by re-projection, so large sliding needs no special case.
//!
//! ## Residual and tangent
//! The contact force `f = p_n n + t` acts on the hitting node (`r_s -= f`) and is distributed
//! to the contact face nodes by the shape functions at `xi` (`r_a += N_a(xi) f`). The kernel
//! [`node_kernel`] is generic over the scalar: with `f64` it gives the residual (and SDM's
//! perturbed residual), with `Dual64` DDM's pseudo-load, and with `DualSVec64<N>` seeded on the
//! node's local unknowns its exact, unsymmetric consistent tangent (forward AD; eq. 43).
//! Which face is closest is a branch decision taken on real parts, like stick/slip.

pub(crate) mod assembly;
pub mod eval;
pub mod friction;
pub mod geometry;
pub mod setup;

use crate::element::face::MAX_FACE_NODES;
use crate::element::FaceFamily;
use crate::load::Amplitude;
use crate::mesh::FaceSet;
use crate::scalar::Scalar;
pub use assembly::ContactError;
pub use friction::Friction;
use friction::{FrictionBranch, FrictionLaw};
use geometry::{project_on_segment, project_smoothed, Projection, RigidSurface, Segment};
use nalgebra::Vector3;

/// How the normal force is computed.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "law", rename_all = "kebab-case", from = "NormalLawToml")]
pub enum NormalLaw {
    /// Lagrange multiplier (exact impenetrability).
    Lagrange,
    /// Penalty `p_n = stiffness * A * <-g>`: `stiffness` is a pressure per unit penetration,
    /// `A` the hitting node's tributary area (so a uniform penetration carries a uniform
    /// pressure and the patch test is passed).
    Penalty {
        /// Penalty stiffness `eps_N` (pressure per unit penetration).
        stiffness: f64,
    },
    /// Augmented Lagrangian (Uzawa): `p_n = <lambda_bar - stiffness A g>` with the multiplier
    /// estimate `lambda_bar` carried per node; after each converged pass `lambda_bar` moves
    /// towards `p_n` (`contact::assembly::augment`) and the increment is solved again until no
    /// node carrying a normal force is off the target, pressed in or held off, by more than
    /// `tolerance` (a length).
    Augmented {
        /// Penalty stiffness `eps_N` (pressure per unit penetration).
        stiffness: f64,
        /// Largest `|g|` accepted at a node carrying a normal force (a length).
        tolerance: f64,
    },
}

/// What a scene file may write for a [`NormalLaw`]: serde lets an internally tagged unit
/// variant (`law = "lagrange"`) take any extra key, so every variant is a struct here and
/// unknown keys (`stiffnes = 5.0`) are errors.
#[derive(serde::Deserialize)]
#[serde(tag = "law", rename_all = "kebab-case", deny_unknown_fields)]
enum NormalLawToml {
    Lagrange {},
    Penalty { stiffness: f64 },
    Augmented { stiffness: f64, tolerance: f64 },
}

impl From<NormalLawToml> for NormalLaw {
    fn from(t: NormalLawToml) -> Self {
        match t {
            NormalLawToml::Lagrange {} => NormalLaw::Lagrange,
            NormalLawToml::Penalty { stiffness } => NormalLaw::Penalty { stiffness },
            NormalLawToml::Augmented {
                stiffness,
                tolerance,
            } => NormalLaw::Augmented {
                stiffness,
                tolerance,
            },
        }
    }
}

/// What a rigid target's motion component prescribes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MotionControl {
    /// The translation `d_c(t) = value * amplitude(t)` (a length).
    #[default]
    Displacement,
    /// The force `F_c(t) = value * amplitude(t)` applied to the target: its translation `d_c`
    /// becomes an unknown of the global system, with the target's equilibrium
    /// `sum_i f_i,c - F_c(t) = 0` (`f_i` the contact force on hitting node `i`) as its row.
    /// The target must touch the hitting nodes at t = 0 (else nothing holds it: the pre-check
    /// says so), and a component along which no contact resists (a frictionless slide) has
    /// no equilibrium.
    Force,
}

/// One component of a rigid target's prescribed motion: a translation or a force,
/// `value * amplitude(t)`.
#[derive(Clone, Debug, PartialEq)]
pub struct RigidMotion {
    /// Translated direction (0 = x, 1 = y, 2 = z).
    pub component: usize,
    /// Magnitude of the translation (a length) or of the force, scaled by `amplitude`.
    pub value: f64,
    /// Time history of the translation or force.
    pub amplitude: Amplitude,
    /// Whether `value` is a translation or a force.
    pub control: MotionControl,
}

/// What the hitting nodes touch.
#[derive(Clone, Debug, PartialEq)]
pub enum Target {
    /// Faces of a deformable body (outward oriented; any face family, projected onto by
    /// [`geometry::closest_on_segments`]).
    Faces {
        /// The target faces.
        faces: FaceSet,
    },
    /// An analytic rigid surface, translated or pushed.
    Rigid {
        /// The surface in its reference position.
        surface: RigidSurface,
        /// Prescribed translations and forces, one entry per moving component (at most one
        /// force per component, and no translation beside it).
        motion: Vec<RigidMotion>,
    },
}

/// A contact pair.
#[derive(Clone, Debug)]
pub struct ContactPair {
    /// Name of the pair (from the scene; used in messages and parameter names).
    pub name: String,
    /// Hitting nodes.
    pub hitting: Vec<usize>,
    /// Tributary reference area of each hitting node, at the nominal design. With
    /// `hitting_faces` the evaluations use the areas recomputed at their design
    /// ([`Lifted::area`](crate::model::Lifted::area)), equal to these at the nominal one: this
    /// copy serves the pre-checks and exports. Without faces (a node set) these are the areas.
    pub area: Vec<f64>,
    /// The faces the hitting nodes and their areas came from (`None`: a node set, every area
    /// one). With them each evaluation recomputes the areas at its design's reference
    /// coordinates ([`Lifted::area`](crate::model::Lifted::area)), so that a shape parameter
    /// reaches the contact pressures and the penalty laws.
    pub hitting_faces: Option<FaceSet>,
    /// What the hitting nodes touch.
    pub target: Target,
    /// Normal contact law.
    pub normal: NormalLaw,
    /// Friction law (`None`: frictionless).
    pub friction: Option<Friction>,
    /// Tangential penalty stiffness `eps_T` (force per unit elastic slip), the scale of every
    /// hitting node's (`tangential_weight`); the design parameter `PAIR.eps_t`.
    pub tangential_stiffness: f64,
    /// Each hitting node's share of the tangential stiffness: node `i` sticks with
    /// `tangential_stiffness * tangential_weight[i]`. All ones when the scene gives
    /// `tangential_stiffness`; derived from the surface elements otherwise (see
    /// `fricsens::scene`'s default: `c_T E* A_i / h_i`, the stiffness of the element layer
    /// under node `i`, over its mean).
    pub tangential_weight: Vec<f64>,
    /// Row scale `k` of the multiplier constraints (force per unit gap).
    pub constraint_scale: f64,
    /// Weight `c` of the gap in the active-set rule of Lagrange multipliers: a node is active
    /// while `lambda - c k g >= 0`.
    ///
    /// Any `c > 0` gives the same solutions (complementarity); `c` decides how eagerly an
    /// active node is released when a Newton step leaves it a small positive gap. With `c = 1`
    /// a node carrying `lambda` opens at `g > lambda / k`: about 1e-4 mm on the leaf spring,
    /// where the curved block nose opens such a gap (`slide^2 / 2R`) whenever the leaf slides
    /// 0.03 mm under it; the node is released, the next step drives the leaf millimetres into
    /// the block, and the line search halves its way back, five iterations per episode. A small
    /// `c` keeps such a node until its multiplier turns tensile; an inactive node (`lambda =
    /// 0`) is activated when it penetrates, whatever `c`. Measured (`fricsens run`, increments
    /// / Newton iterations, `c` = 1 -> 1e-3 on every pair, measured before the extrapolating
    /// predictor and the penetration limiter, which since roughly halved the iterations):
    /// leaf spring 56 / 589 -> 38 / 369, frictionless 52 / 623 -> 38 / 344, coarse 20 / 281
    /// -> 17 / 222, sliding block 32 / 157 -> 32 / 142; indentation, Hertz, stacked leaves,
    /// Klarbring, Jenkins, contact patch unchanged. Not the default: on the 200-element strip pull-out the changed Newton path
    /// takes other cutbacks in unloading (58 against 31 increments), and the slip front, held
    /// at a node by the discrete derivative, then misses du0/dmu = -u0/mu by up to 7.7 %
    /// instead of 1.6 % (`tests/oracles/contact_oracles.rs`).
    pub activation: f64,
    /// Candidate target faces of each hitting node (indices into `Target::Faces::faces`).
    pub candidates: Vec<Vec<usize>>,
    /// A deformable target's normals smoothed: each hitting node is projected along the
    /// normal interpolated from the target's nodal normals (each the normalised sum of the
    /// node's candidate faces' `t_1 × t_2` there: a quad4's area over four, a tri3's twice its
    /// area), not onto the closest point of a facet, so that
    /// the gap and the normal are continuous from face to face
    /// (`geometry::project_smoothed`); faces meeting at a feature edge (more than 60 degrees
    /// in the reference geometry, `assembly::FEATURE_ANGLE_DEGREES`) are not averaged into
    /// each other. Linear faces (quad4, tri3) only: a quadratic face is
    /// curved already, and its smoothing would widen the local tangent beyond its duals.
    pub smoothing: bool,
}

impl ContactPair {
    /// History scalars of the stick anchor per hitting node (zero when frictionless).
    pub(crate) fn anchor_len(&self) -> usize {
        if self.friction.is_some() {
            3
        } else {
            0
        }
    }

    /// Number the unknowns of the pair's force-controlled motion entries (a rigid target pushed
    /// by a force, [`MotionControl::Force`]) from `*next` on: one per force entry, `None` for a
    /// prescribed translation (the layout of [`crate::model::DofMap::first_target`]).
    pub(crate) fn pushed_unknowns(&self, next: &mut usize) -> Vec<Option<usize>> {
        match &self.target {
            Target::Rigid { motion, .. } => (motion.iter())
                .map(|m| {
                    (m.control == MotionControl::Force).then(|| {
                        *next += 1;
                        *next - 1
                    })
                })
                .collect(),
            Target::Faces { .. } => Vec::new(),
        }
    }

    /// The pushed motion entries of the pair: `(entry index, its unknown, the entry)` for each
    /// entry of its rigid target's motion that is a force, its unknown from `target` (the
    /// pair's numbering by [`ContactPair::pushed_unknowns`]).
    pub(crate) fn pushed<'a>(
        &'a self,
        target: &'a [Option<usize>],
    ) -> impl Iterator<Item = (usize, usize, &'a RigidMotion)> + 'a {
        let motion: &[RigidMotion] = match &self.target {
            Target::Rigid { motion, .. } => motion,
            Target::Faces { .. } => &[],
        };
        (motion.iter().zip(target).enumerate())
            .filter_map(|(k, (m, dof))| dof.map(|dof| (k, dof, m)))
    }

    /// The area each hitting node reads its contact pressure over, with node `n` at `x(n)`
    /// (reference coordinates at a design, or deformed ones): its faces' pressure shares
    /// ([`FaceFamily::pressure_share`]; zero at the corners of quadratic faces), or `area`
    /// for a node set.
    pub fn pressure_areas_at<S: Scalar>(&self, x: impl Fn(usize) -> Vector3<S>) -> Vec<S> {
        match &self.hitting_faces {
            Some(faces) => faces.pressure_areas_at(x, &self.hitting),
            None => self.area.iter().map(|a| S::lift(*a)).collect(),
        }
    }

    /// The contact pressure of every hitting node: its normal force `force[i]` over its
    /// pressure area `area[i]`; a node without one (a corner of quadratic faces only, whose
    /// share of a face's load the mid-sides carry) takes the mean pressure of the nodes that
    /// share a hitting face with it and have one. Such a corner's own normal force (none
    /// under a uniform pressure; on the tet10 Hertz block 0.17 % of the pair's force, at most
    /// 1.6 % of the largest mid-side's) is in the pair's force and in station profiles, not in
    /// its nodal pressure. Generic, so that derivatives follow.
    pub fn nodal_pressures<S: Scalar>(&self, force: &[S], area: &[S]) -> Vec<S> {
        debug_assert!(force.len() == self.hitting.len() && area.len() == self.hitting.len());
        let mut p: Vec<S> = (force.iter().zip(area))
            .map(|(f, a)| if a.value() > 0.0 { *f / *a } else { S::zero() })
            .collect();
        let Some(faces) = &self.hitting_faces else {
            return p;
        };
        if area.iter().all(|a| a.value() > 0.0) {
            return p;
        }
        let local: std::collections::HashMap<usize, usize> = (self.hitting.iter().enumerate())
            .map(|(i, n)| (*n, i))
            .collect();
        let mut around: Vec<Vec<usize>> = vec![Vec::new(); self.hitting.len()];
        for k in 0..faces.len() {
            let ids: Vec<usize> = (faces.nodes(k).iter())
                .filter_map(|n| local.get(n).copied())
                .collect();
            for &i in ids.iter().filter(|i| area[**i].value() <= 0.0) {
                for &j in ids.iter().filter(|j| area[**j].value() > 0.0) {
                    if !around[i].contains(&j) {
                        around[i].push(j);
                    }
                }
            }
        }
        for (i, near) in around.iter().enumerate() {
            if !near.is_empty() {
                let sum = near.iter().fold(S::zero(), |s, j| s + force[*j] / area[*j]);
                p[i] = sum / near.len() as f64;
            }
        }
        p
    }

    /// Whether the normal law is the augmented Lagrangian (one multiplier estimate per node).
    pub fn augmented(&self) -> bool {
        matches!(self.normal, NormalLaw::Augmented { .. })
    }

    /// History scalars per hitting node: the stick anchor (with friction), then the multiplier
    /// estimate (augmented Lagrangian). Zero for a frictionless Lagrange or penalty pair.
    pub fn history_len(&self) -> usize {
        self.anchor_len() + usize::from(self.augmented())
    }

    /// The stick anchor stored in a hitting node's history `h` (its [`ContactPair::history_len`]
    /// scalars), `None` without friction.
    pub fn anchor<S: Scalar>(&self, h: &[S]) -> Option<StoredAnchor<S>> {
        (self.anchor_len() > 0).then(|| match self.target {
            Target::Faces { .. } => StoredAnchor::Face {
                face: h[0].value() as usize,
                xi: [h[1], h[2]],
            },
            Target::Rigid { .. } => StoredAnchor::Offset(Vector3::new(h[0], h[1], h[2])),
        })
    }

    /// Store a stick anchor in a hitting node's history `h` (a pair with friction).
    pub(crate) fn set_anchor<S: Scalar>(&self, h: &mut [S], anchor: StoredAnchor<S>) {
        debug_assert!(
            self.anchor_len() == 3,
            "a frictionless pair stores no anchor"
        );
        h[..3].copy_from_slice(&match anchor {
            StoredAnchor::Face { face, xi } => [S::lift(face as f64), xi[0], xi[1]],
            StoredAnchor::Offset(a) => [a[0], a[1], a[2]],
        });
    }

    /// Keep a hitting node's stick anchor: copy its scalars from the committed history `from`
    /// to the new one `to` unchanged (with their derivative parts).
    pub(crate) fn keep_anchor<S: Scalar>(&self, from: &[S], to: &mut [S]) {
        let n = self.anchor_len();
        to[..n].copy_from_slice(&from[..n]);
    }

    /// The augmented Lagrangian's multiplier estimate `lambda_bar` in a hitting node's history
    /// `h`, `None` for other normal laws.
    pub(crate) fn lambda_bar<S: Scalar>(&self, h: &[S]) -> Option<S> {
        self.augmented().then(|| h[self.anchor_len()])
    }

    /// Store the multiplier estimate `lambda_bar` in a hitting node's history `h` (an augmented
    /// pair).
    pub(crate) fn set_lambda_bar<S: Scalar>(&self, h: &mut [S], lambda_bar: S) {
        debug_assert!(
            self.augmented(),
            "only the augmented Lagrangian has an estimate"
        );
        h[self.anchor_len()] = lambda_bar;
    }
}

/// A hitting node's stick anchor as its history stores it ([`ContactPair::anchor`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StoredAnchor<S> {
    /// Material point of a deformable target: the face (index into the target's faces) and
    /// the anchor's convected coordinates on it.
    Face {
        /// Index into `Target::Faces::faces` (not clamped: a frozen or stale face number is
        /// the reader's to check).
        face: usize,
        /// Convected coordinates of the anchor on the face.
        xi: [S; 2],
    },
    /// Material point of a rigid target: the anchor minus the hitting node's reference
    /// position, in the body's frame.
    Offset(Vector3<S>),
}

/// The four nodes of a quad4 target face `f` (the CalculiX export's master faces; another
/// family gives its first node four times, a collapsed quad that the export refuses).
pub fn quad_nodes(faces: &FaceSet, f: usize) -> [usize; 4] {
    let face = faces.face(f);
    match face.family {
        // a quad4 face of a FaceSet has four nodes (FaceSet::push checks)
        FaceFamily::Quad4 => [face.nodes[0], face.nodes[1], face.nodes[2], face.nodes[3]],
        _ => [face.nodes[0]; 4],
    }
}

/// Contact state of a hitting node.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum ContactState {
    /// Not in contact (`p_n = 0`).
    Open,
    /// Closed, frictionless.
    Closed,
    /// Closed, sticking.
    Stick,
    /// Closed, slipping.
    Slip,
}

impl ContactState {
    /// Numeric code for VTK output: 0 open, 1 closed (frictionless), 2 stick, 3 slip.
    pub fn code(self) -> f64 {
        match self {
            ContactState::Open => 0.0,
            ContactState::Closed => 1.0,
            ContactState::Stick => 2.0,
            ContactState::Slip => 3.0,
        }
    }
}

/// The branch decisions of one hitting node: what SDM freezes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ContactChoice {
    /// Normal and friction branch.
    pub state: ContactState,
    /// Contact face (deformable target), index into the target's faces.
    pub face: usize,
    /// Face of the new anchor (deformable target).
    pub anchor_face: usize,
    /// Projected along smoothed normals ([`ContactPair::smoothing`]; false where the node
    /// lies beyond a free edge of the target, or no smoothed projection onto the faces
    /// around its closest one succeeds, and it is projected onto the face as without).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub smoothed: bool,
}

impl Default for ContactChoice {
    fn default() -> Self {
        ContactChoice {
            state: ContactState::Open,
            face: 0,
            anchor_face: 0,
            smoothed: false,
        }
    }
}

/// Target geometry seen by the kernel.
pub enum TargetGeom<'a, S: Scalar> {
    /// The contact face of a deformable target.
    Face {
        /// The face, at the current positions of its nodes.
        segment: Segment<S>,
        /// Starting point of the closest-point Newton iteration.
        xi_start: [f64; 2],
        /// The target's nodal normals at the face's nodes, where the pair smooths them
        /// ([`ContactPair::smoothing`]): the projection is then along the interpolated normal
        /// (`geometry::project_smoothed`), else the closest point.
        normals: Option<[Vector3<S>; MAX_FACE_NODES]>,
    },
    /// A rigid target.
    Rigid {
        /// The surface in its reference position.
        surface: &'a RigidSurface,
        /// Its current translation.
        d: Vector3<S>,
    },
}

/// The stick anchor, stored so that the elastic slip `x - x_anchor` is formed from small
/// quantities (displacements and offsets) rather than as a difference of large coordinates:
/// `x - x_anchor = (X - Xbar) + (u - ubar)`.
pub enum AnchorGeom<S: Scalar> {
    /// Material point `xi` of a target face: reference coordinates and displacements of its
    /// nodes (the first `family.n_nodes()`).
    Face {
        /// The face's family.
        family: FaceFamily,
        /// Reference coordinates of the face's nodes.
        reference: [Vector3<S>; MAX_FACE_NODES],
        /// Displacements of the face's nodes.
        displacement: [Vector3<S>; MAX_FACE_NODES],
        /// Convected coordinates of the anchor on the face.
        xi: [S; 2],
    },
    /// Material point of a rigid target at `offset` from the hitting node's reference position
    /// (in the body's frame), the body translated by `d`.
    Rigid {
        /// Anchor minus the hitting node's reference position, in the body's frame.
        offset: Vector3<S>,
        /// Current translation of the rigid body.
        d: Vector3<S>,
    },
}

impl<S: Scalar> AnchorGeom<S> {
    /// `x - x_anchor` for a hitting node with reference position `x_ref` and displacement `u`,
    /// and a magnitude for its round-off.
    fn separation(&self, x_ref: &Vector3<S>, u: &Vector3<S>) -> (Vector3<S>, f64) {
        let norm = |v: &Vector3<S>| v.map(|c| c.value()).norm();
        match self {
            AnchorGeom::Face {
                family,
                reference,
                displacement,
                xi,
            } => {
                let (xb, ub) = if *family == FaceFamily::Quad4 {
                    let n = bilinear(xi);
                    (
                        reference[0] * n[0]
                            + reference[1] * n[1]
                            + reference[2] * n[2]
                            + reference[3] * n[3],
                        displacement[0] * n[0]
                            + displacement[1] * n[1]
                            + displacement[2] * n[2]
                            + displacement[3] * n[3],
                    )
                } else {
                    let n = family.interpolation(*xi).n;
                    let nn = family.n_nodes();
                    let at = |v: &[Vector3<S>]| {
                        (v.iter().zip(&n).take(nn)).fold(Vector3::zeros(), |s, (p, w)| s + p * *w)
                    };
                    (at(reference), at(displacement))
                };
                let dx = x_ref - xb;
                let du = u - ub;
                // the reference part carries the round-off of the anchor's projection
                let scale = norm(&dx) + norm(u) + norm(&ub) + norm(x_ref);
                (dx + du, scale)
            }
            AnchorGeom::Rigid { offset, d } => {
                let sep = u - d - offset;
                (sep, norm(u) + norm(d) + norm(offset))
            }
        }
    }
}

/// Bilinear shape functions of a quad at `xi`.
pub(crate) fn bilinear<S: Scalar>(xi: &[S; 2]) -> [S; 4] {
    let q = 0.25;
    let (a, b) = (xi[0], xi[1]);
    let one = S::one();
    [
        (one - a) * (one - b) * q,
        (one + a) * (one - b) * q,
        (one + a) * (one + b) * q,
        (one - a) * (one + b) * q,
    ]
}

/// Parameters of the kernel, lifted.
pub struct KernelParams<'a, S: Scalar> {
    /// Normal contact law of the pair.
    pub normal: NormalLaw,
    /// Friction law of the pair (`None`: frictionless).
    pub friction: Option<&'a Friction>,
    /// The friction law's parameters, lifted.
    pub friction_params: &'a [S],
    /// Tangential penalty stiffness `eps_T` (force per unit elastic slip), lifted.
    pub eps_t: S,
    /// Row scale `k` of the multiplier constraint (force per unit gap).
    pub k: f64,
    /// Gap weight of the active-set rule ([`ContactPair::activation`]).
    pub activation: f64,
    /// Tributary area of the hitting node (scales the penalty laws), at the evaluation's
    /// design.
    pub area: S,
    /// A gap up to this (a length) counts as touching in the active-set rule: zero, except
    /// on a pair whose rigid target is pushed by a force ([`MotionControl::Force`]), where it
    /// is the round-off of the gap (`ContactLayout::touch`) so that the node a target is
    /// placed on at t = 0 holds it from the first iteration (a gap of `+1e-16` would leave
    /// the target's equilibrium row empty).
    pub touch: f64,
    /// The stick branch imposed by `frozen` is the elastic predictor, the friction force the
    /// trial force `t_trial` whatever the law: the primal solver's forced stick (slip
    /// reversal). Coulomb-type laws stick so anyway; a smooth law (regularised Coulomb) keeps
    /// its force on either branch, so forcing its branch changed nothing but the anchor's
    /// update, and Newton went on overshooting the saturated force (fuzzer seeds 393, 868,
    /// 869: the same residual before and after every forcing, the friction forces of the
    /// nodes reversing at every iterate). Off for SDM's frozen evaluations, which keep the
    /// law.
    pub elastic_stick: bool,
}

/// What the kernel returns for one hitting node.
pub struct KernelOut<S: Scalar> {
    /// Contact force on the hitting node, `p_n n + t` (the residual gets `-force`).
    pub force: Vector3<S>,
    /// Shape functions of the contact point on the contact face (deformable target; the
    /// first `n_nodes` of its family).
    pub weights: [S; MAX_FACE_NODES],
    /// Residual of the multiplier row.
    pub r_lambda: S,
    /// Normal contact force `p_n >= 0`.
    pub p_n: S,
    /// Contact state reached (or imposed by `frozen`).
    pub state: ContactState,
    /// Where the stick anchor goes (spatial position), for the history update.
    pub new_anchor: Vector3<S>,
    /// `x - x_anchor` after the update, formed without cancellation: the old separation on
    /// stick, `-t / eps_T` on slip, the gap vector while open.
    pub new_separation: Vector3<S>,
    /// Closest-point projection of the hitting node onto the target.
    pub projection: Projection<S>,
    /// Distance to the open/closed transition (gap over length, or force over force scale).
    pub normal_distance: f64,
    /// `|t_trial| / limit - 1` when closed with friction.
    pub slip_ratio: f64,
    /// The size of the forces that cancel in the friction force: the tangential penalty times
    /// the positions whose difference is the elastic slip in stick, that times `|t| /
    /// |t_trial|` in slip (the trial force's round-off turns the slip force's direction by its
    /// size over `|t_trial|`); zero without friction, or open. Machine precision times it is the friction
    /// force's round-off.
    pub cancelling: f64,
}

/// Kernel failures (recoverable by cutback).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ContactFailure {
    /// The closest-point projection failed.
    #[error("projection: {0}")]
    Geometry(#[from] geometry::GeometryError),
    /// A contact or anchor face (from the history or a frozen choice) has a node outside the
    /// hitting node's candidate faces, so its tangent has no place in the node's block.
    #[error("target node {node} is not on any of the hitting node's candidate faces")]
    OutsideCandidates {
        /// The target node (global mesh node number).
        node: usize,
    },
    /// The local tangent of a node on smoothed normals would seed more unknowns than its
    /// widest dual numbers hold (the faces around the contact face of a high valence).
    #[error(
        "the smoothed normals around the contact face need {seeds} local unknowns in the tangent, more than the {most} it holds: set smoothing = \"none\" on this pair"
    )]
    TooManySeeds {
        /// The unknowns the tangent would seed.
        seeds: usize,
        /// The most it holds.
        most: usize,
    },
}

/// The contact kernel of one hitting node (see the module docs).
#[allow(clippy::too_many_arguments)]
pub fn node_kernel<S: Scalar>(
    x_ref: &Vector3<S>,
    u: &Vector3<S>,
    lambda: S,
    lambda_bar: S,
    target: &TargetGeom<'_, S>,
    anchor: Option<&AnchorGeom<S>>,
    par: &KernelParams<'_, S>,
    frozen: Option<ContactState>,
) -> Result<KernelOut<S>, ContactFailure> {
    let x = &(x_ref + u);
    let proj = match target {
        TargetGeom::Face {
            segment,
            xi_start,
            normals: None,
        } => project_on_segment(x, segment, *xi_start),
        TargetGeom::Face {
            segment,
            xi_start,
            normals: Some(normals),
        } => project_smoothed(x, segment, normals, *xi_start),
        TargetGeom::Rigid { surface, d } => surface.project(x, d),
    }
    .map_err(ContactFailure::Geometry)?;
    let g = proj.gap;
    let n = proj.normal;
    let mut weights = [S::zero(); MAX_FACE_NODES];
    match target {
        TargetGeom::Face { segment, .. } if segment.family == FaceFamily::Quad4 => {
            weights[..4].copy_from_slice(&bilinear(&proj.xi));
        }
        TargetGeom::Face { segment, .. } => weights = segment.family.interpolation(proj.xi).n,
        TargetGeom::Rigid { .. } => {}
    }
    let k = par.k;
    // normal branch, on real parts
    let active = match frozen {
        Some(s) => s != ContactState::Open,
        None => match par.normal {
            NormalLaw::Lagrange => {
                lambda.value() - par.activation * k * (g.value() - par.touch) >= 0.0
            }
            // touching (g = 0) counts as closed, so a body held only by contact is supported
            // from the first iteration
            NormalLaw::Penalty { .. } => g.value() <= par.touch,
            NormalLaw::Augmented { stiffness, .. } => {
                lambda_bar.value() - stiffness * par.area.value() * (g.value() - par.touch) >= 0.0
            }
        },
    };
    let (p_n, r_lambda) = match (par.normal, active) {
        (NormalLaw::Lagrange, true) => (lambda, -g * k),
        (NormalLaw::Lagrange, false) => (S::zero(), lambda),
        (NormalLaw::Penalty { stiffness }, true) => (-g * (par.area * stiffness), lambda),
        (NormalLaw::Penalty { .. }, false) => (S::zero(), lambda),
        (NormalLaw::Augmented { stiffness, .. }, true) => {
            (lambda_bar - g * (par.area * stiffness), lambda)
        }
        (NormalLaw::Augmented { .. }, false) => (S::zero(), lambda),
    };
    let normal_distance = if active {
        p_n.value() / k.max(f64::MIN_POSITIVE)
    } else {
        g.value()
    };
    let mut force = n * p_n;
    let mut state = if active {
        ContactState::Closed
    } else {
        ContactState::Open
    };
    let mut new_anchor = proj.point;
    let mut new_separation = n * g;
    let mut slip_ratio = f64::INFINITY;
    let mut cancelling = 0.0;
    if let (true, Some(law), Some(anchor)) = (active, par.friction, anchor) {
        let (dx, scale) = anchor.separation(x_ref, u);
        let g_t = dx - n * n.dot(&dx);
        let t_trial = g_t * (-par.eps_t);
        cancelling = scale * par.eps_t.value();
        // Round-off of the trial force: a trial within it of the slip surface is taken as stick
        // (the elastic predictor), so the branch does not flip on noise.
        let margin = 8.0 * f64::EPSILON * scale * par.eps_t.value();
        let fb = match frozen {
            Some(ContactState::Stick) => Some(FrictionBranch::Stick),
            Some(ContactState::Slip) => Some(FrictionBranch::Slip),
            _ => None,
        };
        let mut upd = crate::with_friction!(law, f => f.return_map(par.friction_params, &t_trial, p_n, margin, fb));
        if par.elastic_stick && fb == Some(FrictionBranch::Stick) {
            upd.traction = t_trial;
        }
        slip_ratio = upd.slip_ratio;
        force += upd.traction;
        match upd.branch {
            FrictionBranch::Stick => {
                state = ContactState::Stick;
                new_anchor = x - dx;
                new_separation = dx;
            }
            FrictionBranch::Slip => {
                state = ContactState::Slip;
                new_separation = -upd.traction / par.eps_t;
                new_anchor = x - new_separation;
                // the slip force is its size along the trial's direction, which the trial's
                // round-off turns by its size over |t_trial| (Coulomb: over 1 + slip ratio)
                let trial = t_trial.map(|c| c.value()).norm();
                cancelling *= if trial > 0.0 {
                    upd.traction.map(|c| c.value()).norm() / trial
                } else {
                    0.0
                };
            }
        }
    }
    Ok(KernelOut {
        force,
        weights,
        r_lambda,
        p_n,
        state,
        new_anchor,
        new_separation,
        projection: proj,
        normal_distance,
        slip_ratio,
        cancelling,
    })
}
