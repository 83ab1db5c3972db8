//! The scene schema: what a scene file says (serde types, read and written as TOML), its errors
//! naming the field, and reading and writing scenes.

use super::builtin;
use crate::contact::{Friction, NormalLaw};
use crate::element::{Formulation, Kinematics};
use crate::law::Law;
use crate::mesh::{Axis, BlockSpec};
use crate::model::{Material, SolverSettings};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A Cartesian component.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Component {
    /// x (index 0).
    X,
    /// y (index 1).
    Y,
    /// z (index 2).
    Z,
}

impl Component {
    /// Index 0, 1, 2.
    pub fn index(self) -> usize {
        match self {
            Component::X => 0,
            Component::Y => 1,
            Component::Z => 2,
        }
    }
}

/// A deformable body: a generated block, or the elements of a mesh file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "BodyToml", into = "BodyToml")]
pub struct BodySpec {
    /// Where its elements come from.
    pub geometry: BodyGeometry,
    /// Constitutive law.
    pub material: Material,
    /// Small or large deformation (scene default: large).
    pub kinematics: Kinematics,
    /// Element formulation; `None` (the scene default) is the standard one of the body's
    /// shape (incompatible modes for hex8, reduced integration for hex20, ...:
    /// [`crate::element::family`]'s table).
    pub formulation: Option<Formulation>,
}

/// Where a body's elements come from.
#[derive(Clone, Debug, PartialEq)]
pub enum BodyGeometry {
    /// A block of hex8 elements made by the generator (its name is the body's name).
    Block(BlockSpec),
    /// The solid elements of a mesh file, or of one of its element sets.
    Mesh(MeshSource),
}

/// A body's elements read from a mesh file: Gmsh MSH 4.1 (`.msh`, ASCII or binary) or
/// Abaqus/CalculiX input (`.inp`).
#[derive(Clone, Debug, PartialEq)]
pub struct MeshSource {
    /// The body's name: the prefix of its node and face sets (`NAME.SET`).
    pub name: String,
    /// The mesh file, relative to the scene file's folder (or absolute).
    pub file: std::path::PathBuf,
    /// The physical group (Gmsh) or element set (Abaqus) holding the body's elements; every
    /// solid element of the file when absent.
    pub set: Option<String>,
    /// Factor from the file's length unit to the scene's (default 1: the file is in the
    /// scene's consistent units).
    pub scale: f64,
    /// The folder a relative `file` starts from: the scene file's (set when the scene is read
    /// from a file), or the working folder when `None`.
    pub folder: Option<std::path::PathBuf>,
}

impl BodySpec {
    /// The body's name.
    pub fn name(&self) -> &str {
        match &self.geometry {
            BodyGeometry::Block(b) => &b.name,
            BodyGeometry::Mesh(m) => &m.name,
        }
    }

    /// The generated block, if the body is one.
    pub fn block(&self) -> Option<&BlockSpec> {
        match &self.geometry {
            BodyGeometry::Block(b) => Some(b),
            BodyGeometry::Mesh(_) => None,
        }
    }

    /// The generated block, mutably, if the body is one.
    pub fn block_mut(&mut self) -> Option<&mut BlockSpec> {
        match &mut self.geometry {
            BodyGeometry::Block(b) => Some(b),
            BodyGeometry::Mesh(_) => None,
        }
    }
}

/// The TOML table of a [`BodySpec`], with the block's or the mesh's fields inline. Spelled out
/// rather than `#[serde(flatten)]`, which buffers the table: errors inside it
/// (`bodies[0].x.length` missing) would point at `[[bodies]]` instead of the entry.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct BodyToml {
    name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    element: Option<crate::element::Shape>,
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "exact::opt_vec3"
    )]
    origin: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    x: Option<Axis>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    y: Option<Axis>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    z: Option<Axis>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    mesh: Option<std::path::PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    set: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    scale: Option<f64>,
    material: Material,
    #[serde(default = "large")]
    kinematics: Kinematics,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    formulation: Option<Formulation>,
}

impl TryFrom<BodyToml> for BodySpec {
    type Error = String;
    fn try_from(b: BodyToml) -> Result<Self, String> {
        let geometry = match (b.mesh, b.origin, b.x, b.y, b.z) {
            (None, Some(origin), Some(x), Some(y), Some(z)) => {
                if b.set.is_some() || b.scale.is_some() {
                    return Err(format!(
                        "body '{}': `set` and `scale` belong to a body read from a mesh file",
                        b.name
                    ));
                }
                BodyGeometry::Block(BlockSpec {
                    name: b.name,
                    element: b.element.unwrap_or(crate::element::Shape::Hex8),
                    origin,
                    x,
                    y,
                    z,
                })
            }
            (Some(_), None, None, None, None) if b.element.is_some() => {
                return Err(format!(
                    "body '{}': `element` belongs to a generated block (a mesh file names its own)",
                    b.name
                ))
            }
            (Some(file), None, None, None, None) => BodyGeometry::Mesh(MeshSource {
                name: b.name,
                file,
                set: b.set,
                scale: b.scale.unwrap_or(1.0),
                folder: None,
            }),
            (Some(_), ..) => {
                return Err(format!(
                    "body '{}': a body read from a mesh file has no origin, x, y or z",
                    b.name
                ))
            }
            (None, ..) => {
                return Err(format!(
                    "body '{}': give origin, x, y and z (a generated block) or mesh (a mesh file)",
                    b.name
                ))
            }
        };
        Ok(BodySpec {
            geometry,
            material: b.material,
            kinematics: b.kinematics,
            formulation: b.formulation,
        })
    }
}

impl From<BodySpec> for BodyToml {
    fn from(b: BodySpec) -> Self {
        let mut t = BodyToml {
            name: b.name().to_string(),
            element: None,
            origin: None,
            x: None,
            y: None,
            z: None,
            mesh: None,
            set: None,
            scale: None,
            material: b.material,
            kinematics: b.kinematics,
            formulation: b.formulation,
        };
        match b.geometry {
            BodyGeometry::Block(block) => {
                // a block's shape is known here: its standard formulation is written out, so
                // a scene file that left it out is told which one it got
                // (`Scene::defaulted`); a mesh file's shapes are known once it is read
                t.formulation = t.formulation.or_else(|| {
                    crate::element::ElementFamily::standard(block.element).formulation()
                });
                t.element = (block.element != crate::element::Shape::Hex8).then_some(block.element);
                t.origin = Some(block.origin);
                t.x = Some(block.x);
                t.y = Some(block.y);
                t.z = Some(block.z);
            }
            BodyGeometry::Mesh(m) => {
                t.mesh = Some(m.file);
                t.set = m.set;
                t.scale = (m.scale != 1.0).then_some(m.scale);
            }
        }
        t
    }
}

pub(crate) fn large() -> Kinematics {
    Kinematics::Large
}
/// A node outside every block (for discrete models).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FreeNodeSpec {
    /// Name; the node forms the node set of that name.
    pub name: String,
    /// Reference position.
    #[serde(deserialize_with = "exact::vec3")]
    pub x: [f64; 3],
}

/// A spring between two node sets of one node each (or to the ground).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringSpec {
    /// Node set of the first node.
    pub a: String,
    /// Node set of the second node; none ties `a` to the ground.
    #[serde(default)]
    pub b: Option<String>,
    /// Row-major 3x3 stiffness.
    #[serde(deserialize_with = "exact::mat3")]
    pub stiffness: [[f64; 3]; 3],
}

/// A prescribed displacement `value * amplitude(t)` on every node of a set.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PrescribedSpec {
    /// Name (for design parameters and messages).
    pub name: String,
    /// Node set.
    pub set: String,
    /// Constrained components, each given `value * amplitude(t)`.
    pub components: Vec<Component>,
    /// Magnitude of the displacement (a length; default 0, a fixed support).
    #[serde(default)]
    pub value: f64,
    /// Amplitude as `(time, value)` pairs (default the ramp 0 -> 1 over t = 0..1).
    #[serde(default = "ramp", deserialize_with = "exact::pairs")]
    pub amplitude: Vec<(f64, f64)>,
}

/// A total force `value * amplitude(t)` in one component over a set. On a face set it is a
/// uniform traction over the set's reference faces: each node takes its tributary share of
/// the area (the consistent nodal forces of a uniform traction on parallelogram quad4 faces).
/// On a node set (no faces: an intersection such as `b.xmax & b.all`, a Gmsh point group, an
/// Abaqus `NSET`) the nodes share it equally. A pressure that follows a shape parameter's
/// faces is a `[[pressures]]` entry.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoadSpec {
    /// Name (for design parameters and messages).
    pub name: String,
    /// Node set.
    pub set: String,
    /// Force component.
    pub component: Component,
    /// Total force over the set.
    pub value: f64,
    /// Amplitude as `(time, value)` pairs (default the ramp 0 -> 1 over t = 0..1).
    #[serde(default = "ramp", deserialize_with = "exact::pairs")]
    pub amplitude: Vec<(f64, f64)>,
}

/// A pressure `value * amplitude(t)` on a face set: the traction `-p N` on the reference faces
/// (outward normal `N`; a positive pressure pushes into the body), by consistent nodal forces
/// ([`crate::load::PressureLoad`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PressureSpec {
    /// Name (design parameter `pressure.NAME`).
    pub name: String,
    /// Face set.
    pub faces: String,
    /// Pressure (force per reference area).
    pub value: f64,
    /// Amplitude as `(time, value)` pairs (default the ramp 0 -> 1 over t = 0..1).
    #[serde(default = "ramp", deserialize_with = "exact::pairs")]
    pub amplitude: Vec<(f64, f64)>,
}

/// A shape map: the nodes of a set moved with a design value `b` (its name is the design
/// parameter's name; [`crate::mesh::shape_map`]). `value` is the reference value at which the
/// mesh holds (default: 0 for a translation, rotation, morph or boundary field; 1 for a scale
/// — give the size itself, e.g. a radius, to differentiate per unit of it).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeSpec {
    /// Name: the design parameter.
    pub name: String,
    /// Node set moved (for `boundary`, the body whose nodes follow).
    pub nodes: String,
    /// Reference value `b_ref`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub value: Option<f64>,
    /// What the map does.
    pub map: MapSpec,
}

/// The kinds of shape map.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub enum MapSpec {
    /// `X = X0 + (b - b_ref) d`.
    Translate {
        /// `d`.
        #[serde(deserialize_with = "exact::vec3")]
        direction: [f64; 3],
    },
    /// Rotation by `b - b_ref` radians about the axis through `centre`.
    Rotate {
        /// A point of the axis.
        #[serde(deserialize_with = "exact::vec3")]
        centre: [f64; 3],
        /// Axis direction.
        #[serde(deserialize_with = "exact::vec3")]
        axis: [f64; 3],
    },
    /// Scale by `b / b_ref` about `centre`, or about the axis through it.
    Scale {
        /// Centre (a point of the axis).
        #[serde(deserialize_with = "exact::vec3")]
        centre: [f64; 3],
        /// Axis direction (a scale about the point without it).
        #[serde(
            default,
            skip_serializing_if = "Option::is_none",
            deserialize_with = "exact::opt_vec3"
        )]
        axis: Option<[f64; 3]>,
    },
    /// A morph to a second mesh of the same topology: `X = X_A + b (X_B - X_A)`, node `k` of
    /// the set moving towards node `k` of the same body in `mesh`.
    Morph {
        /// The second mesh file (relative to the scene file's folder).
        mesh: std::path::PathBuf,
        /// Its element set or physical group (the body's own when absent).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        set: Option<String>,
    },
    /// A boundary-driven field: the nodes of `surface` move with `motion` per unit of `b`,
    /// those of `fixed` stay, the components of `slide` stay zero on their sets, and the body's
    /// other nodes follow by a `smoothing` solve on the reference mesh.
    Boundary {
        /// Node or face set moved.
        surface: String,
        /// How it moves.
        motion: SurfaceMotion,
        /// Node sets held fixed.
        #[serde(default)]
        fixed: Vec<String>,
        /// `(set, component)` pairs held zero (a symmetry plane keeps its normal component).
        #[serde(default)]
        slide: Vec<(String, Component)>,
        /// Laplace (default) or linear elastic smoothing.
        #[serde(default)]
        smoothing: crate::mesh::Smoothing,
    },
}

/// How a boundary-driven shape map moves its surface, per unit of the design value.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub enum SurfaceMotion {
    /// Along the unit direction away from `centre` (from the axis through it along `axis`
    /// when given): a sphere's or a cylinder's radius grows by `b`.
    Radial {
        /// Centre (a point of the axis).
        #[serde(deserialize_with = "exact::vec3")]
        centre: [f64; 3],
        /// Axis direction.
        #[serde(
            default,
            skip_serializing_if = "Option::is_none",
            deserialize_with = "exact::opt_vec3"
        )]
        axis: Option<[f64; 3]>,
    },
    /// By a constant vector.
    Translate {
        /// The vector.
        #[serde(deserialize_with = "exact::vec3")]
        direction: [f64; 3],
    },
}

pub(crate) fn ramp() -> Vec<(f64, f64)> {
    vec![(0.0, 0.0), (1.0, 1.0)]
}

/// A stretch of the load history split into equal increments.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StepSpec {
    /// Pseudo-time at the end of the step.
    pub end: f64,
    /// Number of equal increments.
    pub increments: usize,
}

/// An analytic rigid surface (undisplaced position).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "shape", rename_all = "kebab-case", deny_unknown_fields)]
pub enum RigidSpec {
    /// Plane through `point`, `normal` pointing out of the rigid body (towards the deformable
    /// one).
    Plane {
        /// A point of the plane.
        #[serde(deserialize_with = "exact::vec3")]
        point: [f64; 3],
        /// Normal, pointing out of the rigid body (any nonzero length; normalised on use).
        #[serde(deserialize_with = "exact::vec3")]
        normal: [f64; 3],
    },
    /// Cylinder (contact on its outside).
    Cylinder {
        /// A point of the axis.
        #[serde(deserialize_with = "exact::vec3")]
        axis_point: [f64; 3],
        /// Direction of the axis (any nonzero length).
        #[serde(deserialize_with = "exact::vec3")]
        axis: [f64; 3],
        /// Radius (a length).
        radius: f64,
    },
    /// Box with rounded edges and corners.
    RoundedBox {
        /// Centre.
        #[serde(deserialize_with = "exact::vec3")]
        center: [f64; 3],
        /// Half extents of the whole (rounded) box along x, y, z.
        #[serde(deserialize_with = "exact::vec3")]
        half_extents: [f64; 3],
        /// Radius of the rounded edges and corners (`<= min(half_extents)`).
        radius: f64,
    },
}

/// One component of a rigid target's motion: a translation `value * amplitude(t)`, or a force
/// `force * amplitude(t)` pushing the target (its translation then follows from its
/// equilibrium with the contact forces). Exactly one of `value` and `force`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionSpec {
    /// Component.
    pub component: Component,
    /// Magnitude of the prescribed translation (a length).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub value: Option<f64>,
    /// Magnitude of the force applied to the target instead (its translation in `component`
    /// becomes an unknown; the target must touch the hitting nodes at t = 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force: Option<f64>,
    /// Amplitude as `(time, value)` pairs (default the ramp 0 -> 1 over t = 0..1).
    #[serde(default = "ramp", deserialize_with = "exact::pairs")]
    pub amplitude: Vec<(f64, f64)>,
}

/// The target of a contact pair.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum TargetSpec {
    /// A face set of a deformable body (e.g. `"upper.ymin"`).
    Faces(String),
    /// An analytic rigid surface and its prescribed translation.
    Rigid {
        /// The surface in its undisplaced position.
        surface: RigidSpec,
        /// Prescribed translation, one entry per moving component (default: fixed).
        #[serde(default)]
        motion: Vec<MotionSpec>,
    },
}

/// A contact pair.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSpec {
    /// Name (for design parameters, responses and messages).
    pub name: String,
    /// Hitting nodes: a face set (tributary areas from its faces) or a node set (unit areas).
    pub hitting: String,
    /// What the hitting nodes touch.
    pub target: TargetSpec,
    /// Normal law; default Lagrange multipliers.
    #[serde(default = "lagrange")]
    pub normal: NormalLaw,
    /// Friction law; none = frictionless.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<Friction>,
    /// Tangential penalty stiffness per hitting node (force per length); default
    /// 100 x the constraint scale.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tangential_stiffness: Option<f64>,
    /// Scale of the multiplier rows (force per length); default E_max x sqrt(mean area), or
    /// the largest spring stiffness for models without bodies.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub constraint_scale: Option<f64>,
    /// Weight `c` of the gap in the active-set rule of Lagrange multipliers (a node is active
    /// while `lambda - c k g >= 0`); default 1. Any `c > 0` gives the same solutions; a small
    /// `c` keeps a loaded node active until its multiplier turns tensile, instead of releasing
    /// it on the small positive gap a Newton step leaves on a curved target (see
    /// [`crate::contact::ContactPair::activation`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub activation: Option<f64>,
    /// Candidate target faces lie within this distance of a hitting node (reference
    /// configuration); default 3 x the largest face diagonal.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub search_radius: Option<f64>,
    /// A deformable target's surface as the hitting nodes see it: `"normals"`, projected
    /// along the normal interpolated from averaged nodal normals (gap and normal continuous
    /// from face to face), or `"none"`, the closest point on the faces. Default: see
    /// [`crate::contact::ContactPair::smoothing`]. Linear target faces only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub smoothing: Option<Smoothing>,
}

/// How a deformable target's surface is seen by the hitting nodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Smoothing {
    /// The faces as they are: closest-point projection, normals jump at the edges.
    None,
    /// Averaged nodal normals, interpolated over each face.
    Normals,
}

pub(crate) fn lagrange() -> NormalLaw {
    NormalLaw::Lagrange
}

/// A scalar response of the converged state.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ResponseSpec {
    /// Sum of the reaction forces of a set in one component.
    Reaction {
        /// Response name.
        name: String,
        /// Node set.
        set: String,
        /// Force component.
        component: Component,
    },
    /// Mean displacement of a set in one component.
    Displacement {
        /// Response name.
        name: String,
        /// Node set.
        set: String,
        /// Displacement component.
        component: Component,
    },
    /// Force exerted on the target of a contact pair (the reaction of a rigid target).
    TargetForce {
        /// Response name.
        name: String,
        /// Contact pair name.
        pair: String,
        /// Force component.
        component: Component,
    },
    /// Translation of a contact pair's rigid target (e.g. the indentation of an indenter
    /// pushed by a force).
    TargetDisplacement {
        /// Response name.
        name: String,
        /// Contact pair name (a rigid target).
        pair: String,
        /// Translation component.
        component: Component,
    },
    /// Contact pressure (normal force / pressure area) along a pair's hitting surface,
    /// ordered along `along`. `area = "nominal"` (the default) divides by the reference
    /// pressure area ([`crate::element::FaceFamily::pressure_share`]: the tributary area on
    /// linear faces), `area = "current"` by the deformed one (the Cauchy pressure that
    /// CalculiX and Abaqus report). With `per = "station"` (the default) the hitting nodes at
    /// one reference coordinate along `along` make one station (the node rows of a plane-strain
    /// slab, or a row across a 3D surface), its pressure their total normal force over their
    /// total area, one response per station named `NAME_MEASURE[k]` (`p_current[3]`; the
    /// measure is not repeated when `NAME` already ends with it); `profile.csv` gives each
    /// station's coordinates. `per = "node"` gives one response per node, `NAME[i]`, as the
    /// built-in scenes (and their regression data) have it.
    PressureProfile {
        /// Response name prefix.
        name: String,
        /// Contact pair name.
        pair: String,
        /// Coordinate the nodes are ordered by (reference configuration).
        along: Component,
        /// Over which area: `nominal` (reference) or `current` (deformed).
        #[serde(default)]
        area: crate::response::PressureMeasure,
        /// One response per station (default) or per hitting node.
        #[serde(default)]
        per: ProfilePoints,
    },
    /// A history variable of one Gauss point: `element` counts within the body, `point` is
    /// the Gauss point (0-7), `variable` names a history entry of the body's material
    /// (for J2: `Ep11` ... `Ep13`, `alpha` = equivalent plastic strain).
    History {
        /// Response name.
        name: String,
        /// Body name.
        body: String,
        /// Element index within the body.
        element: usize,
        /// Gauss point (0-7).
        point: usize,
        /// History entry of the body's material.
        variable: String,
    },
    /// A measure of one element's volume-averaged Cauchy stress: `element` counts within the
    /// body; `measure` is a component (`xx`, `yy`, `zz`, `xy`, `yz`, `xz`) or `von-mises`.
    Stress {
        /// Response name.
        name: String,
        /// Body name.
        body: String,
        /// Element index within the body.
        element: usize,
        /// What of its stress.
        measure: crate::response::StressMeasure,
    },
}

impl ResponseSpec {
    /// Name of the response.
    pub fn name(&self) -> &str {
        match self {
            ResponseSpec::Reaction { name, .. }
            | ResponseSpec::Displacement { name, .. }
            | ResponseSpec::TargetForce { name, .. }
            | ResponseSpec::TargetDisplacement { name, .. }
            | ResponseSpec::PressureProfile { name, .. }
            | ResponseSpec::History { name, .. }
            | ResponseSpec::Stress { name, .. } => name,
        }
    }
}

/// What a pressure profile gives a value for ([`ResponseSpec::PressureProfile`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ProfilePoints {
    /// One value per station: the hitting nodes at one reference coordinate along the profile
    /// (to 1e-9 of the profile's extent), their total normal force over their total area.
    #[default]
    Station,
    /// One value per hitting node (but the corners of quadratic faces, which read no
    /// pressure of their own: [`crate::element::FaceFamily::pressure_share`]; the points are
    /// numbered along the profile without them).
    Node,
}

/// A complete analysis.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Scene name.
    pub name: String,
    /// What the scene is (one paragraph).
    #[serde(default)]
    pub description: String,
    /// Deformable bodies.
    #[serde(default)]
    pub bodies: Vec<BodySpec>,
    /// Nodes outside every body.
    #[serde(default)]
    pub free_nodes: Vec<FreeNodeSpec>,
    /// Linear springs.
    #[serde(default)]
    pub springs: Vec<SpringSpec>,
    /// Prescribed displacements.
    #[serde(default)]
    pub prescribed: Vec<PrescribedSpec>,
    /// Loads.
    #[serde(default)]
    pub loads: Vec<LoadSpec>,
    /// Pressures on face sets.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pressures: Vec<PressureSpec>,
    /// Shape maps: design-dependent reference coordinates (shape parameters of any mesh).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub shapes: Vec<ShapeSpec>,
    /// Contact pairs.
    #[serde(default)]
    pub contacts: Vec<ContactSpec>,
    /// The load history: steps of equal increments.
    pub steps: Vec<StepSpec>,
    /// Responses recorded at every increment.
    #[serde(default)]
    pub responses: Vec<ResponseSpec>,
    /// Newton-Raphson settings.
    #[serde(default)]
    pub solver: SolverSettings,
    /// The design parameters the scene is studied with, and its default perturbation size.
    #[serde(default, skip_serializing_if = "StudySpec::is_empty")]
    pub study: StudySpec,
}

/// The design parameters a scene is studied with (`fricsens validate`, and `fricsens
/// sensitivity` without `--param`) and the default perturbation size of the finite-perturbation
/// methods.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudySpec {
    /// Parameter names as `fricsens sensitivity --param` takes them (`mu`, `E`,
    /// `upper.length.x`, ...).
    #[serde(default)]
    pub params: Vec<String>,
    /// Default relative perturbation size beta of SDM and FDM (default 1e-6).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beta: Option<f64>,
}

impl StudySpec {
    fn is_empty(&self) -> bool {
        self.params.is_empty() && self.beta.is_none()
    }

    /// The default perturbation size.
    pub fn beta(&self) -> f64 {
        self.beta.unwrap_or(1e-6)
    }
}

/// What is wrong with a scene, and where.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SceneError {
    /// The scene holds what a scene file cannot say (a user's friction law, defined in code).
    #[error("scene '{scene}' cannot be written as TOML: {why}")]
    NotWritable {
        /// The scene's name.
        scene: String,
        /// The serializer's message.
        why: String,
    },
    /// The TOML text does not parse as a scene.
    #[error("{file}: {message}")]
    Parse {
        /// The file (or source name).
        file: String,
        /// The parser's message, with the field's path when known.
        message: String,
    },
    /// A scene file could not be read.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: String,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A field has an invalid value.
    #[error("field `{field}`: {problem}")]
    Invalid {
        /// Path of the field (`contacts[0].friction.mu`).
        field: String,
        /// What is wrong with it.
        problem: String,
    },
    /// Neither a built-in scene nor a scene file.
    #[error("unknown built-in scene '{0}' (see `fricsens scenes`)")]
    UnknownScene(String),
    /// An error in a scene file, found when it was built.
    #[error("{file}: {source}")]
    InFile {
        /// The file.
        file: String,
        /// The error.
        #[source]
        source: Box<SceneError>,
    },
}

pub(crate) fn invalid(field: &str, problem: impl Into<String>) -> SceneError {
    SceneError::Invalid {
        field: field.to_string(),
        problem: problem.into(),
    }
}

/// `v` is finite (worded as for a law's parameters, [`crate::law::ParamProblem`]).
pub(crate) fn finite(v: f64, field: &str) -> Result<(), SceneError> {
    crate::law::finite(v, "").map_err(|e| invalid(field, e.problem.to_string()))
}

/// `v` is finite and positive.
pub(crate) fn positive(v: f64, field: &str) -> Result<(), SceneError> {
    crate::law::positive(v, "").map_err(|e| invalid(field, e.problem.to_string()))
}

/// A law's own check ([`Law::check`]), its error naming the field `{at}.{parameter}`.
pub(crate) fn check_law(law: &impl Law, at: &str) -> Result<(), SceneError> {
    law.check()
        .map_err(|e| invalid(&format!("{at}.{}", e.param), e.problem.to_string()))
}

/// The TOML path (`bodies[0].material.E`) of the entry a deserialization error points at, with
/// the name of a missing or unknown field appended; `None` for syntax errors (the message gives
/// the line), errors without a position, and positions no single entry owns.
pub(crate) fn toml_path(text: &str, err: &toml::de::Error) -> Option<String> {
    use toml::de::{DeTable, DeValue};
    type Span = std::ops::Range<usize>;
    /// The entry with the smallest span containing the error's start, the deepest among equal
    /// spans; `ambiguous` when two different entries tie.
    struct Best {
        at: usize,
        found: Option<(usize, usize, String)>,
        ambiguous: bool,
    }
    impl Best {
        fn consider(&mut self, span: Span, depth: usize, path: &str) {
            if !span.contains(&self.at) {
                return;
            }
            let key = (span.len(), usize::MAX - depth);
            match &self.found {
                Some((len, d, p)) if key == (*len, usize::MAX - *d) => {
                    self.ambiguous |= p != path;
                }
                Some((len, d, _)) if key > (*len, usize::MAX - *d) => {}
                _ => {
                    self.found = Some((span.len(), depth, path.to_string()));
                    self.ambiguous = false;
                }
            }
        }
        fn value(&mut self, v: &DeValue, span: Span, depth: usize, path: &str) {
            self.consider(span, depth, path);
            match v {
                DeValue::Table(t) => self.table(t, depth, path),
                DeValue::Array(a) => {
                    for (i, e) in a.iter().enumerate() {
                        self.value(e.get_ref(), e.span(), depth + 1, &format!("{path}[{i}]"));
                    }
                }
                _ => {}
            }
        }
        fn table(&mut self, t: &DeTable, depth: usize, path: &str) {
            for (k, v) in t.iter() {
                let p = if path.is_empty() {
                    k.get_ref().to_string()
                } else {
                    format!("{path}.{}", k.get_ref())
                };
                self.consider(k.span(), depth + 1, &p);
                self.value(v.get_ref(), v.span(), depth + 1, &p);
            }
        }
    }
    let span = err.span()?;
    let mut path = if span.is_empty() {
        // the document itself (the toml crate's position for errors of the root table)
        if span.start != 0 {
            return None;
        }
        String::new()
    } else {
        let doc = DeTable::parse(text).ok()?;
        let mut best = Best {
            at: span.start,
            found: None,
            ambiguous: false,
        };
        best.table(doc.get_ref(), 0, "");
        match best.found {
            Some((_, _, p)) if !best.ambiguous => p,
            _ => return None,
        }
    };
    let msg = err.message();
    let field = ["missing field `", "unknown field `"]
        .iter()
        .find_map(|p| msg.strip_prefix(p))
        .and_then(|rest| rest.split('`').next());
    if let Some(f) = field {
        if path.rsplit('.').next() != Some(f) {
            path = if path.is_empty() {
                f.to_string()
            } else {
                format!("{path}.{f}")
            };
        }
    }
    (!path.is_empty()).then_some(path)
}

/// The keys of `full` missing from `given`, with their values (see [`Scene::defaulted`]).
fn defaulted_keys(
    full: &toml::Value,
    given: Option<&toml::Value>,
    path: &str,
    out: &mut Vec<String>,
) {
    let join = |k: &str| {
        if path.is_empty() {
            k.to_string()
        } else {
            format!("{path}.{k}")
        }
    };
    match (full, given) {
        (toml::Value::Table(t), Some(toml::Value::Table(g))) => {
            for (k, v) in t {
                defaulted_keys(v, g.get(k), &join(k), out);
            }
        }
        (toml::Value::Array(a), Some(toml::Value::Array(g)))
            if a.iter().all(toml::Value::is_table) && a.len() == g.len() =>
        {
            for (i, (v, w)) in a.iter().zip(g).enumerate() {
                defaulted_keys(v, Some(w), &format!("{path}[{i}]"), out);
            }
        }
        (_, Some(_)) => {}
        // nothing declared is nothing defaulted
        (toml::Value::Array(a), None) if a.is_empty() => {}
        (v, None) => {
            let shown = match v {
                toml::Value::Table(t) => {
                    // a whole table left out: its keys one by one
                    for (k, w) in t {
                        defaulted_keys(w, None, &join(k), out);
                    }
                    return;
                }
                other => other.to_string(),
            };
            out.push(format!("{path} = {shown}"));
        }
    }
}

impl Scene {
    /// Parse a scene from TOML text; `file` names the source in errors.
    pub fn from_toml(text: &str, file: &str) -> Result<Scene, SceneError> {
        toml::from_str(text).map_err(|e| {
            let message = e.to_string().trim_end().to_string();
            SceneError::Parse {
                file: file.to_string(),
                message: match toml_path(text, &e) {
                    Some(path) => format!("field `{path}`: {message}"),
                    None => message,
                },
            }
        })
    }

    /// The settings a scene text leaves to their defaults, each as `path = value` with the
    /// value in effect (`bodies[0].kinematics = "large"`): every key of the complete scene
    /// ([`Scene::to_toml`]) that the text does not give. `fricsens run` and `fricsens
    /// sensitivity` print them before a scene file's run.
    pub fn defaulted(text: &str, file: &str) -> Result<Vec<String>, SceneError> {
        let scene = Self::from_toml(text, file)?;
        let parse = |t: &str| {
            toml::from_str::<toml::Value>(t).map_err(|e| SceneError::Parse {
                file: file.to_string(),
                message: e.to_string(),
            })
        };
        let (given, full) = (parse(text)?, parse(&scene.to_toml()?)?);
        let mut out = Vec::new();
        defaulted_keys(&full, Some(&given), "", &mut out);
        // a body read from a mesh file takes the standard formulation of each of its shapes,
        // which only the file tells
        for (i, b) in scene.bodies.iter().enumerate() {
            if let (None, BodyGeometry::Mesh(_)) = (b.formulation, &b.geometry) {
                out.push(format!(
                    "bodies[{i}].formulation = each shape's standard (hex8 \"incompatible-modes\", hex20 \"reduced\", tet4, tet10, wedge6, wedge15 \"full\")"
                ));
            }
        }
        out.sort();
        Ok(out)
    }

    /// Read a scene file.
    pub fn from_file(path: &Path) -> Result<Scene, SceneError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            file: file.clone(),
            source,
        })?;
        let mut scene = Self::from_toml(&text, &file)?;
        let folder = path.parent().map(|p| p.to_path_buf());
        for b in &mut scene.bodies {
            if let BodyGeometry::Mesh(m) = &mut b.geometry {
                m.folder = folder.clone();
            }
        }
        Ok(scene)
    }

    /// A built-in scene by name, or a scene file by path.
    pub fn load(name_or_path: &str) -> Result<Scene, SceneError> {
        if let Some(s) = builtin(name_or_path) {
            return Ok(s);
        }
        let p = Path::new(name_or_path);
        if p.exists() || name_or_path.ends_with(".toml") {
            let s = Self::from_file(p)?;
            // validate now so errors name the file
            s.build().map_err(|e| SceneError::InFile {
                file: p.display().to_string(),
                source: Box::new(e),
            })?;
            return Ok(s);
        }
        Err(SceneError::UnknownScene(name_or_path.to_string()))
    }

    /// Serialise to TOML.
    pub fn to_toml(&self) -> Result<String, SceneError> {
        toml::to_string(self).map_err(|e| SceneError::NotWritable {
            scene: self.name.clone(),
            why: e.to_string(),
        })
    }
}

/// Fixed-size arrays read with their length checked. Read as `[f64; 3]` or `(f64, f64)`, a
/// longer TOML array gives its first values and the rest is dropped without a word
/// (`origin = [0, 0, 0, 7]` was taken as the origin, a spring's fourth stiffness row and an
/// amplitude point `[0, 0, 9]` were ignored); these read the whole array and refuse one of
/// another length, the parser's error naming the line.
mod exact {
    use serde::de::{Deserialize, Deserializer, Error};

    fn fixed<E: Error, const N: usize>(v: Vec<f64>) -> Result<[f64; N], E> {
        let n = v.len();
        v.try_into()
            .map_err(|_| E::invalid_length(n, &format!("an array of {N} numbers").as_str()))
    }

    /// `[x, y, z]`.
    pub fn vec3<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
        fixed(Vec::<f64>::deserialize(d)?)
    }

    /// An optional `[x, y, z]`.
    pub fn opt_vec3<'de, D: Deserializer<'de>>(d: D) -> Result<Option<[f64; 3]>, D::Error> {
        Option::<Vec<f64>>::deserialize(d)?.map(fixed).transpose()
    }

    /// Three rows of three.
    pub fn mat3<'de, D: Deserializer<'de>>(d: D) -> Result<[[f64; 3]; 3], D::Error> {
        let rows = Vec::<Vec<f64>>::deserialize(d)?;
        let n = rows.len();
        let rows: Vec<[f64; 3]> = rows.into_iter().map(fixed).collect::<Result<_, _>>()?;
        rows.try_into()
            .map_err(|_| D::Error::invalid_length(n, &"an array of 3 rows of 3 numbers"))
    }

    /// `(time, value)` points, `[[t, v], ...]`.
    pub fn pairs<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<(f64, f64)>, D::Error> {
        let points = Vec::<Vec<f64>>::deserialize(d)?;
        (points.into_iter())
            .map(|p| fixed::<D::Error, 2>(p).map(|[t, v]| (t, v)))
            .collect()
    }
}
