//! Element families: a shape with a formulation, evaluated generically over the scalar.
//!
//! [`ElementFamily`] is what the assembly, the dof map and the history layout ask about an
//! element: its nodes, Gauss points and internal unknowns, and its evaluation (internal
//! force, tangent, history update, branches) for any scalar `S` and material law `M`.
//!
//! Two kinds of family: continuum ones (hex8), whose section is a body's material law at
//! Gauss points ([`ElementFamily::evaluate`]), and discrete ones (the springs `Spring1`,
//! `Spring2`), whose section is a constant stiffness and which have no Gauss point, history or
//! branch ([`ElementFamily::evaluate_discrete`]). Either is an element of the mesh, numbered,
//! assembled and differentiated in the same loop.
//!
//! ## Why an enum
//! The evaluation is generic over the scalar (`f64`, `Dual64`, `DualSVec64<N>`) and the
//! material; a trait with generic methods cannot be a trait object, and one vtable per scalar
//! (`dyn Element<f64>`, `dyn Element<Dual64>`, ...) would box every group once per scalar for
//! no gain. The enum is `Copy`, matched once per element evaluation (next to some 10^4 flops)
//! and monomorphised per `(S, M)`, as the materials are ([`crate::with_material!`]).
//!
//! ## Registering a family
//! One file in `element/` with the family's tables and kernels (as [`super::hex8`]), a
//! [`super::Shape`] variant if its shape is new, a variant of [`ElementFamily`] and one arm in
//! each of its `match`es here; raise the `MAX_*` bounds if it is the largest. The bounds size
//! the stack scratch of the assembly's element loop, which therefore allocates nothing.

use super::hex8::{self, ElementFailure, Hex8Formulation, Hex8Input, Hex8Output, Kinematics};
use super::{spring, Shape};
use crate::material::{Branch, MaterialLaw};
use crate::scalar::Scalar;
use nalgebra::{Matrix3, Vector3};

/// Most nodes of any registered family.
pub(crate) const MAX_NODES: usize = 8;
/// Most Gauss points of any registered family.
pub(crate) const MAX_GAUSS: usize = 8;
/// Most generalised nodes (nodes plus groups of three internal unknowns) of any family.
pub(crate) const MAX_GEN: usize = hex8::MAX_GEN;
/// Most element unknowns of any registered family.
pub(crate) const MAX_DOFS: usize = 3 * MAX_GEN;

/// An element family: a shape and how it is integrated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum ElementFamily {
    /// Eight-node hexahedron: plain, incompatible modes or F-bar ([`super::hex8`]).
    Hex8(Hex8Formulation),
    /// A linear spring from a `point1` element's node to the ground ([`super::spring`]).
    Spring1,
    /// A linear spring between the two nodes of a `line2` element ([`super::spring`]).
    Spring2,
}

/// Everything one element evaluation needs besides its unknowns (the slice form of
/// [`Hex8Input`], whatever the family).
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

/// What one element evaluation returns (the slice form of [`Hex8Output`]).
pub struct ElementOutput<'a, S: Scalar> {
    /// Internal force, `n_dofs` entries (node-major, component-minor).
    pub force: &'a mut [S],
    /// Tangent, row-major `n_dofs^2`, if wanted.
    pub tangent: Option<&'a mut [S]>,
    /// Updated history, `n_gauss * history_len` scalars.
    pub hist_new: &'a mut [S],
    /// Branch taken at each Gauss point (`n_gauss` entries).
    pub branches: &'a mut [Branch],
    /// Trial yield ratio at each Gauss point (`n_gauss` entries).
    pub yield_ratio: &'a mut [f64],
    /// Volume-averaged Cauchy stress.
    pub cauchy: Matrix3<S>,
    /// Smallest det F over the Gauss points (real part).
    pub min_det_f: f64,
}

impl ElementFamily {
    /// The family of an element of shape `shape` integrated with `formulation` (the hex8
    /// formulations; a shape with formulations of its own will take them here). The discrete
    /// shapes give the springs, which have no formulation.
    pub fn new(shape: Shape, formulation: Hex8Formulation) -> Self {
        match shape {
            Shape::Hex8 => ElementFamily::Hex8(formulation),
            Shape::Point1 => ElementFamily::Spring1,
            Shape::Line2 => ElementFamily::Spring2,
        }
    }

    /// The element's shape.
    pub fn shape(self) -> Shape {
        match self {
            ElementFamily::Hex8(_) => Shape::Hex8,
            ElementFamily::Spring1 => Shape::Point1,
            ElementFamily::Spring2 => Shape::Line2,
        }
    }

    /// Whether it is a discrete element, whose section is a stiffness
    /// ([`ElementFamily::evaluate_discrete`]) instead of a material law at Gauss points
    /// ([`ElementFamily::evaluate`]).
    pub fn is_discrete(self) -> bool {
        match self {
            ElementFamily::Hex8(_) => false,
            ElementFamily::Spring1 | ElementFamily::Spring2 => true,
        }
    }

    /// Number of nodes.
    pub fn n_nodes(self) -> usize {
        self.shape().n_nodes()
    }

    /// Number of Gauss points (each carries a material history and a branch).
    pub fn n_gauss(self) -> usize {
        match self {
            ElementFamily::Hex8(_) => 8,
            ElementFamily::Spring1 | ElementFamily::Spring2 => 0,
        }
    }

    /// Number of element-internal unknowns (a multiple of three).
    pub fn internal_dofs(self) -> usize {
        match self {
            ElementFamily::Hex8(f) => f.internal_dofs(),
            ElementFamily::Spring1 | ElementFamily::Spring2 => 0,
        }
    }

    /// Number of element unknowns: three per node and the internal ones.
    pub fn n_dofs(self) -> usize {
        3 * self.n_nodes() + self.internal_dofs()
    }

    /// Whether its Gauss points see the strain of the element's own displacements alone
    /// ([`ElementFamily::gauss_strains`] can give it).
    pub fn has_pointwise_strain(self) -> bool {
        match self {
            ElementFamily::Hex8(f) => f != Hex8Formulation::FBar,
            ElementFamily::Spring1 | ElementFamily::Spring2 => true,
        }
    }

    /// Evaluate internal force (and the tangent if asked), the updated history and the
    /// branch of every Gauss point of a continuum family (a discrete one is a typed failure:
    /// it has no material, see [`ElementFamily::evaluate_discrete`]).
    pub fn evaluate<S: Scalar, M: MaterialLaw>(
        self,
        input: &ElementInput<'_, S, M>,
        out: &mut ElementOutput<'_, S>,
    ) -> Result<(), ElementFailure> {
        match self {
            ElementFamily::Hex8(formulation) => {
                let x_ref = nodes8(input.x_ref)?;
                let frozen: Option<&[Branch; 8]> = match input.frozen {
                    Some(f) => Some(f.try_into().map_err(|_| ElementFailure::Layout {
                        what: "frozen branches",
                        expected: 8,
                        got: f.len(),
                    })?),
                    None => None,
                };
                let h8 = Hex8Input {
                    x_ref,
                    dofs: input.dofs,
                    kinematics: input.kinematics,
                    formulation,
                    material: input.material,
                    params: input.params,
                    hist_old: input.hist_old,
                    frozen,
                };
                let mut o = Hex8Output {
                    force: &mut *out.force,
                    tangent: out.tangent.as_deref_mut(),
                    hist_new: &mut *out.hist_new,
                    branches: [Branch::Elastic; 8],
                    yield_ratio: [-1.0; 8],
                    cauchy: Matrix3::zeros(),
                    min_det_f: f64::INFINITY,
                };
                let r = hex8::evaluate(&h8, &mut o);
                out.branches[..8].copy_from_slice(&o.branches);
                out.yield_ratio[..8].copy_from_slice(&o.yield_ratio);
                out.cauchy = o.cauchy;
                out.min_det_f = o.min_det_f;
                r
            }
            ElementFamily::Spring1 | ElementFamily::Spring2 => Err(ElementFailure::Section {
                family: self.name(),
                expected: "a stiffness",
                got: "a material",
            }),
        }
    }

    /// Evaluate a discrete family: internal force (and the tangent if asked) of a spring with
    /// stiffness `k` and nodal displacements `dofs`. A continuum family is a typed failure
    /// (its section is a material, see [`ElementFamily::evaluate`]).
    pub fn evaluate_discrete<S: Scalar>(
        self,
        k: &Matrix3<S>,
        dofs: &[Vector3<S>],
        out: &mut ElementOutput<'_, S>,
    ) -> Result<(), ElementFailure> {
        match self {
            ElementFamily::Spring1 | ElementFamily::Spring2 => {
                spring::evaluate(k, dofs, out.force, out.tangent.as_deref_mut())
            }
            ElementFamily::Hex8(_) => Err(ElementFailure::Section {
                family: self.name(),
                expected: "a material",
                got: "a stiffness",
            }),
        }
    }

    /// Short name (`hex8`, `hex8-incompatible-modes`, `hex8-f-bar`, `spring1`, `spring2`).
    pub fn name(self) -> &'static str {
        match self {
            ElementFamily::Hex8(Hex8Formulation::Full) => "hex8",
            ElementFamily::Hex8(Hex8Formulation::IncompatibleModes) => "hex8-incompatible-modes",
            ElementFamily::Hex8(Hex8Formulation::FBar) => "hex8-f-bar",
            ElementFamily::Spring1 => "spring1",
            ElementFamily::Spring2 => "spring2",
        }
    }

    /// The strain each Gauss point's material sees for the generalised displacements `dofs`
    /// (without the stress update), written into `out[..n_gauss]`. `Ok(false)` for families
    /// whose points see a strain modified by the whole element (F-bar).
    pub fn gauss_strains<S: Scalar>(
        self,
        x_ref: &[Vector3<S>],
        dofs: &[Vector3<S>],
        kinematics: Kinematics,
        out: &mut [Matrix3<S>],
    ) -> Result<bool, ElementFailure> {
        match self {
            ElementFamily::Hex8(formulation) => {
                match hex8::gauss_strains(nodes8(x_ref)?, dofs, kinematics, formulation)? {
                    Some(e) => {
                        out[..8].copy_from_slice(&e);
                        Ok(true)
                    }
                    None => Ok(false),
                }
            }
            // no Gauss point, nothing to write
            ElementFamily::Spring1 | ElementFamily::Spring2 => Ok(true),
        }
    }

    /// Element volume in the reference configuration.
    pub fn reference_volume<S: Scalar>(self, x_ref: &[Vector3<S>]) -> Result<S, ElementFailure> {
        match self {
            ElementFamily::Hex8(_) => hex8::reference_volume(nodes8(x_ref)?),
            ElementFamily::Spring1 | ElementFamily::Spring2 => Ok(S::zero()),
        }
    }
}

/// The eight reference nodes of a hex8 as an array (a typed failure for any other count).
fn nodes8<S: Scalar>(x: &[Vector3<S>]) -> Result<&[Vector3<S>; 8], ElementFailure> {
    x.try_into().map_err(|_| ElementFailure::Layout {
        what: "nodes",
        expected: 8,
        got: x.len(),
    })
}
