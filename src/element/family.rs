//! Element families: a shape with a formulation, evaluated generically over the scalar.
//!
//! [`ElementFamily`] is what the assembly, the dof map and the history layout ask about an
//! element: its nodes, Gauss points and internal unknowns, and its evaluation (internal
//! force, tangent, history update, branches) for any scalar `S` and material law `M`.
//!
//! Two kinds of family: solids (hex8, hex20, tet4, tet10, wedge6, wedge15, each with its
//! formulations), whose section is a body's material law at Gauss points
//! ([`ElementFamily::evaluate`], one continuum kernel for all: [`super::continuum`]), and
//! discrete ones (the springs `Spring1`,
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
//! A solid shape: one file in `element/` with its tables, interpolation and Gauss rules (as
//! [`super::tet`]), a [`super::Shape`] variant, and its rows in [`ElementFamily::new`]'s table
//! and `ElementFamily::solid`; raise the `MAX_*` bounds if it is the largest. The bounds size
//! the stack scratch of the assembly's element loop, which therefore allocates nothing.
//!
//! ## Formulations per shape
//! | shape | standard (a body that names none) | also |
//! |---|---|---|
//! | hex8 | incompatible modes | full, f-bar |
//! | hex20 | reduced (2x2x2) | full (3x3x3), f-bar |
//! | tet4 | full (1 point) | - |
//! | tet10 | full (4 points) | high-order (14 points), f-bar |
//! | wedge6 | full (3x2) | f-bar |
//! | wedge15 | full (3x3) | f-bar |

use super::continuum::{ElementFailure, Formulation, Kinematics, Solid};
pub use super::continuum::{ElementInput, ElementOutput};
use super::{hex20, hex8, spring, tet, wedge, Shape};
use crate::material::MaterialLaw;
use crate::scalar::Scalar;
use nalgebra::{Matrix3, Vector3};

pub(crate) use super::continuum::{MAX_DOFS, MAX_GAUSS, MAX_GEN, MAX_NODES};

/// An element family: a shape and how it is integrated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum ElementFamily {
    /// A solid of a shape, integrated as its formulation says ([`super::continuum`]).
    Solid(Shape, Formulation),
    /// A linear spring from a `point1` element's node to the ground ([`super::spring`]).
    Spring1,
    /// A linear spring between the two nodes of a `line2` element ([`super::spring`]).
    Spring2,
}

/// A formulation a shape does not take.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{shape} elements take {allowed}, not {formulation}")]
pub struct FormulationError {
    /// The shape's name.
    pub shape: &'static str,
    /// The formulation asked for.
    pub formulation: &'static str,
    /// The formulations the shape takes.
    pub allowed: String,
}

/// The formulations a solid shape takes, its standard one first (the table in the module
/// docs); none for a discrete shape.
fn formulations(shape: Shape) -> &'static [Formulation] {
    use Formulation::*;
    match shape {
        Shape::Hex8 => &[IncompatibleModes, Full, FBar],
        Shape::Hex20 => &[Reduced, Full, FBar],
        Shape::Tet4 => &[Full],
        Shape::Tet10 => &[Full, HighOrder, FBar],
        Shape::Wedge6 | Shape::Wedge15 => &[Full, FBar],
        Shape::Point1 | Shape::Line2 => &[],
    }
}

impl ElementFamily {
    /// The family of an element of shape `shape` integrated with `formulation`, or with the
    /// shape's standard formulation if `None` (the table in the module docs). A discrete
    /// shape gives its spring, which has no formulation. A formulation the shape does not
    /// take is a typed error.
    pub fn new(shape: Shape, formulation: Option<Formulation>) -> Result<Self, FormulationError> {
        match shape {
            Shape::Point1 => return Ok(ElementFamily::Spring1),
            Shape::Line2 => return Ok(ElementFamily::Spring2),
            _ => {}
        }
        let allowed = formulations(shape);
        let f = formulation.unwrap_or(allowed[0]);
        if !allowed.contains(&f) {
            return Err(FormulationError {
                shape: shape.name(),
                formulation: f.name(),
                allowed: allowed
                    .iter()
                    .map(|f| f.name())
                    .collect::<Vec<_>>()
                    .join(", "),
            });
        }
        Ok(ElementFamily::Solid(shape, f))
    }

    /// The family of `shape` with its standard formulation (a discrete shape's spring).
    pub fn standard(shape: Shape) -> Self {
        match (shape, formulations(shape).first()) {
            (Shape::Point1, _) => ElementFamily::Spring1,
            (Shape::Line2, _) | (_, None) => ElementFamily::Spring2,
            (_, Some(f)) => ElementFamily::Solid(shape, *f),
        }
    }

    /// Every solid family (each shape with each formulation it takes).
    pub fn solids() -> impl Iterator<Item = ElementFamily> {
        Shape::SOLIDS.into_iter().flat_map(|s| {
            formulations(s)
                .iter()
                .map(move |f| ElementFamily::Solid(s, *f))
        })
    }

    /// The tables the continuum kernel integrates (`None` for a discrete family).
    pub(crate) fn solid(self) -> Option<Solid<'static>> {
        let ElementFamily::Solid(shape, f) = self else {
            return None;
        };
        let fbar = f == Formulation::FBar;
        let (interpolation, rule) = match (shape, f) {
            (Shape::Hex8, _) => return Some(hex8::solid(f)),
            (Shape::Hex20, Formulation::Reduced) => (&hex20::INTERPOLATION, &hex8::GAUSS_2X2X2),
            (Shape::Hex20, _) => (&hex20::INTERPOLATION, &hex20::GAUSS_3X3X3),
            (Shape::Tet4, _) => (&tet::INTERPOLATION4, &tet::GAUSS_1),
            (Shape::Tet10, Formulation::HighOrder) => (&tet::INTERPOLATION10, &tet::GAUSS_14),
            (Shape::Tet10, _) => (&tet::INTERPOLATION10, &tet::GAUSS_4),
            (Shape::Wedge6, _) => (&wedge::INTERPOLATION6, &wedge::GAUSS_3X2),
            (Shape::Wedge15, _) => (&wedge::INTERPOLATION15, &wedge::GAUSS_3X3),
            (Shape::Point1 | Shape::Line2, _) => return None,
        };
        Some(Solid {
            interpolation,
            rule,
            enhanced: false,
            fbar,
        })
    }

    /// The element's shape.
    pub fn shape(self) -> Shape {
        match self {
            ElementFamily::Solid(s, _) => s,
            ElementFamily::Spring1 => Shape::Point1,
            ElementFamily::Spring2 => Shape::Line2,
        }
    }

    /// The solid's formulation (`None` for a discrete family).
    pub fn formulation(self) -> Option<Formulation> {
        match self {
            ElementFamily::Solid(_, f) => Some(f),
            ElementFamily::Spring1 | ElementFamily::Spring2 => None,
        }
    }

    /// Whether it is a discrete element, whose section is a stiffness
    /// ([`ElementFamily::evaluate_discrete`]) instead of a material law at Gauss points
    /// ([`ElementFamily::evaluate`]).
    pub fn is_discrete(self) -> bool {
        !matches!(self, ElementFamily::Solid(..))
    }

    /// Number of nodes.
    pub fn n_nodes(self) -> usize {
        self.shape().n_nodes()
    }

    /// Number of Gauss points (each carries a material history and a branch).
    pub fn n_gauss(self) -> usize {
        self.solid().map_or(0, |s| s.rule.len())
    }

    /// Number of element-internal unknowns (a multiple of three).
    pub fn internal_dofs(self) -> usize {
        self.formulation().map_or(0, Formulation::internal_dofs)
    }

    /// Number of element unknowns: three per node and the internal ones.
    pub fn n_dofs(self) -> usize {
        3 * self.n_nodes() + self.internal_dofs()
    }

    /// Whether its Gauss points see the strain of the element's own displacements alone
    /// ([`ElementFamily::gauss_strains`] can give it).
    pub fn has_pointwise_strain(self) -> bool {
        self.formulation() != Some(Formulation::FBar)
    }

    /// Evaluate internal force (and the tangent if asked), the updated history and the
    /// branch of every Gauss point of a solid (a discrete family is a typed failure: it has
    /// no material, see [`ElementFamily::evaluate_discrete`]).
    pub fn evaluate<S: Scalar, M: MaterialLaw>(
        self,
        input: &ElementInput<'_, S, M>,
        out: &mut ElementOutput<'_, S>,
    ) -> Result<(), ElementFailure> {
        match self.solid() {
            Some(solid) => solid.evaluate(input, out),
            None => Err(ElementFailure::Section {
                family: self.name(),
                expected: "a stiffness",
                got: "a material",
            }),
        }
    }

    /// Evaluate a discrete family: internal force (and the tangent if asked) of a spring with
    /// stiffness `k` and nodal displacements `dofs`. A solid is a typed failure (its section
    /// is a material, see [`ElementFamily::evaluate`]).
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
            ElementFamily::Solid(..) => Err(ElementFailure::Section {
                family: self.name(),
                expected: "a material",
                got: "a stiffness",
            }),
        }
    }

    /// Short name: the shape's, followed by the formulation where the shape takes more than
    /// one and it is not the plain full rule (`hex8`, `hex8-incompatible-modes`,
    /// `hex20-reduced`, `tet10-f-bar`, `spring1`, ...).
    pub fn name(self) -> &'static str {
        use Formulation::*;
        match self {
            ElementFamily::Solid(shape, f) => match (shape, f) {
                (Shape::Hex8, IncompatibleModes) => "hex8-incompatible-modes",
                (Shape::Hex8, FBar) => "hex8-f-bar",
                (Shape::Hex20, Reduced) => "hex20-reduced",
                (Shape::Hex20, FBar) => "hex20-f-bar",
                (Shape::Tet10, HighOrder) => "tet10-high-order",
                (Shape::Tet10, FBar) => "tet10-f-bar",
                (Shape::Wedge6, FBar) => "wedge6-f-bar",
                (Shape::Wedge15, FBar) => "wedge15-f-bar",
                (s, _) => s.name(),
            },
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
        match self.solid() {
            Some(solid) => solid.gauss_strains(x_ref, dofs, kinematics, out),
            // no Gauss point, nothing to write
            None => Ok(true),
        }
    }

    /// The shape functions (the first `n_nodes` entries) at every Gauss point and its
    /// reference volume weight; none for a discrete family.
    pub fn quadrature(
        self,
        x_ref: &[Vector3<f64>],
    ) -> Result<Vec<([f64; MAX_NODES], f64)>, ElementFailure> {
        match self.solid() {
            Some(solid) => solid.quadrature(x_ref),
            None => Ok(Vec::new()),
        }
    }

    /// The shape functions at the points of the finest Gauss rule of the element's shape
    /// (3x3x3 on hexahedra, 14 points on tetrahedra, 3x3 on wedges) and each point's
    /// reference volume weight: for integrals whose integrand is richer than the element's
    /// own rule integrates (errors against an exact field); none for a discrete family.
    pub fn fine_quadrature(
        self,
        x_ref: &[Vector3<f64>],
    ) -> Result<Vec<([f64; MAX_NODES], f64)>, ElementFailure> {
        let Some(solid) = self.solid() else {
            return Ok(Vec::new());
        };
        let rule = match self.shape().corners() {
            Shape::Tet4 => &tet::GAUSS_14,
            Shape::Wedge6 => &wedge::GAUSS_3X3,
            _ => &hex20::GAUSS_3X3X3,
        };
        Solid {
            interpolation: solid.interpolation,
            rule,
            enhanced: false,
            fbar: false,
        }
        .quadrature(x_ref)
    }

    /// Element volume in the reference configuration.
    pub fn reference_volume<S: Scalar>(self, x_ref: &[Vector3<S>]) -> Result<S, ElementFailure> {
        match self.solid() {
            Some(solid) => solid.reference_volume(x_ref),
            None => Ok(S::zero()),
        }
    }
}
