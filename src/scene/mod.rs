//! Scenes: complete analyses as data. A scene is written and read as TOML (serde), built-in
//! scenes have names, and [`Scene::build`] validates a scene and turns it into a [`Model`].
//!
//! A scene declares its physics — kinematics, material laws, element formulation, springs — and
//! the model pays only for what is declared (no history for elastic bodies, no internal
//! unknowns for plain hex8).

use crate::contact::friction::{Coulomb, PressureDependentCoulomb, RegularizedCoulomb};
use crate::contact::geometry::RigidSurface;
use crate::contact::{ContactPair, Friction, NormalLaw, RigidMotion, Target};
use crate::element::{Hex8Formulation, Kinematics, Spring};
use crate::material::{J2Plasticity, NeoHookean, StVenantKirchhoff};
use crate::mesh::{Axis, BlockSpec, Mesh, Zone};
use crate::model::{Amplitude, Body, Material, Model, NodalLoad, Prescribed, SolverSettings};
use crate::response::{Response, ResponseKind};
use serde::{Deserialize, Serialize};
use std::path::Path;

mod leaf;
pub use leaf::{leaf_spring, stacked_leaves, LeafSpringSpec, StackedLeavesSpec};

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

/// Material of a body, with named parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "law", rename_all = "kebab-case", deny_unknown_fields)]
pub enum MaterialSpec {
    /// St Venant-Kirchhoff.
    Svk {
        /// Young's modulus `E` (stress).
        #[serde(rename = "E")]
        young: f64,
        /// Poisson's ratio `nu`.
        nu: f64,
    },
    /// J2 plasticity; linear hardening `sigma_y + H alpha`, plus the saturation term
    /// `(sigma_inf - sigma_y)(1 - exp(-delta alpha))` when `sigma_inf` and `delta` are given.
    J2 {
        /// Young's modulus `E` (stress).
        #[serde(rename = "E")]
        young: f64,
        /// Poisson's ratio `nu`.
        nu: f64,
        /// Initial yield stress `sigma_y`.
        sigma_y: f64,
        /// Linear hardening modulus `H` (stress per unit equivalent plastic strain).
        #[serde(rename = "H")]
        hardening: f64,
        /// Saturation flow stress `sigma_inf` (with `delta`; `>= sigma_y`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        sigma_inf: Option<f64>,
        /// Saturation rate `delta` (per unit equivalent plastic strain; with `sigma_inf`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        delta: Option<f64>,
    },
    /// Compressible Neo-Hookean hyperelasticity (`E`, `nu` its small-strain constants).
    NeoHookean {
        /// Young's modulus `E` (stress).
        #[serde(rename = "E")]
        young: f64,
        /// Poisson's ratio `nu`.
        nu: f64,
    },
}

impl MaterialSpec {
    fn build(&self) -> Material {
        match self {
            MaterialSpec::Svk { young, nu } => Material::Svk(StVenantKirchhoff::new(*young, *nu)),
            MaterialSpec::NeoHookean { young, nu } => {
                Material::NeoHookean(NeoHookean::new(*young, *nu))
            }
            MaterialSpec::J2 {
                young,
                nu,
                sigma_y,
                hardening,
                sigma_inf,
                delta,
            } => Material::J2(match (sigma_inf, delta) {
                (Some(si), Some(d)) => {
                    J2Plasticity::saturation(*young, *nu, *sigma_y, *hardening, *si, *d)
                }
                _ => J2Plasticity::linear(*young, *nu, *sigma_y, *hardening),
            }),
        }
    }

    fn check(&self, at: &str) -> Result<(), SceneError> {
        match self {
            MaterialSpec::Svk { young, nu } | MaterialSpec::NeoHookean { young, nu } => {
                positive(*young, &format!("{at}.E"))?;
                poisson(*nu, &format!("{at}.nu"))
            }
            MaterialSpec::J2 {
                young,
                nu,
                sigma_y,
                hardening,
                sigma_inf,
                delta,
            } => {
                positive(*young, &format!("{at}.E"))?;
                poisson(*nu, &format!("{at}.nu"))?;
                positive(*sigma_y, &format!("{at}.sigma_y"))?;
                finite(*hardening, &format!("{at}.H"))?;
                if *hardening < 0.0 {
                    return Err(invalid(
                        &format!("{at}.H"),
                        "softening (H < 0) is not supported",
                    ));
                }
                if sigma_inf.is_some() != delta.is_some() {
                    return Err(invalid(
                        &format!("{at}.sigma_inf"),
                        "saturation hardening needs both sigma_inf and delta",
                    ));
                }
                if let (Some(si), Some(d)) = (sigma_inf, delta) {
                    finite(*si, &format!("{at}.sigma_inf"))?;
                    finite(*d, &format!("{at}.delta"))?;
                    if si < sigma_y || *d < 0.0 {
                        return Err(invalid(
                            &format!("{at}.sigma_inf"),
                            "needs sigma_inf >= sigma_y and delta >= 0",
                        ));
                    }
                }
                Ok(())
            }
        }
    }
}

/// A deformable body: one generated block.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "BodyToml", into = "BodyToml")]
pub struct BodySpec {
    /// The generated block of hex8 elements (its name is the body's name).
    pub block: BlockSpec,
    /// Constitutive law.
    pub material: MaterialSpec,
    /// Small or large deformation (scene default: large).
    pub kinematics: Kinematics,
    /// Hex8 element formulation (scene default: incompatible modes).
    pub formulation: Hex8Formulation,
}

/// The TOML table of a [`BodySpec`], with the block's fields inline. Spelled out rather than
/// `#[serde(flatten)]`, which buffers the table: errors inside it (`bodies[0].x.length`
/// missing) would point at `[[bodies]]` instead of the entry.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct BodyToml {
    name: String,
    origin: [f64; 3],
    x: Axis,
    y: Axis,
    z: Axis,
    material: MaterialSpec,
    #[serde(default = "large")]
    kinematics: Kinematics,
    #[serde(default = "incompatible")]
    formulation: Hex8Formulation,
}

impl From<BodyToml> for BodySpec {
    fn from(b: BodyToml) -> Self {
        BodySpec {
            block: BlockSpec {
                name: b.name,
                origin: b.origin,
                x: b.x,
                y: b.y,
                z: b.z,
            },
            material: b.material,
            kinematics: b.kinematics,
            formulation: b.formulation,
        }
    }
}

impl From<BodySpec> for BodyToml {
    fn from(b: BodySpec) -> Self {
        BodyToml {
            name: b.block.name,
            origin: b.block.origin,
            x: b.block.x,
            y: b.block.y,
            z: b.block.z,
            material: b.material,
            kinematics: b.kinematics,
            formulation: b.formulation,
        }
    }
}

fn large() -> Kinematics {
    Kinematics::Large
}
fn incompatible() -> Hex8Formulation {
    Hex8Formulation::IncompatibleModes
}

/// A node outside every block (for discrete models).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FreeNodeSpec {
    /// Name; the node forms the node set of that name.
    pub name: String,
    /// Reference position.
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
    #[serde(default = "ramp")]
    pub amplitude: Vec<(f64, f64)>,
}

/// A total force `value * amplitude(t)` shared equally by the nodes of a set.
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
    #[serde(default = "ramp")]
    pub amplitude: Vec<(f64, f64)>,
}

fn ramp() -> Vec<(f64, f64)> {
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
        point: [f64; 3],
        /// Normal, pointing out of the rigid body (any nonzero length; normalised on use).
        normal: [f64; 3],
    },
    /// Cylinder (contact on its outside).
    Cylinder {
        /// A point of the axis.
        axis_point: [f64; 3],
        /// Direction of the axis (any nonzero length).
        axis: [f64; 3],
        /// Radius (a length).
        radius: f64,
    },
    /// Box with rounded edges and corners.
    RoundedBox {
        /// Centre.
        center: [f64; 3],
        /// Half extents of the whole (rounded) box along x, y, z.
        half_extents: [f64; 3],
        /// Radius of the rounded edges and corners (`<= min(half_extents)`).
        radius: f64,
    },
}

/// One component of a rigid target's translation, `value * amplitude(t)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionSpec {
    /// Translated component.
    pub component: Component,
    /// Magnitude of the translation (a length).
    pub value: f64,
    /// Amplitude as `(time, value)` pairs (default the ramp 0 -> 1 over t = 0..1).
    #[serde(default = "ramp")]
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

/// A friction law with named parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "law", rename_all = "kebab-case", deny_unknown_fields)]
pub enum FrictionSpec {
    /// Coulomb with penalty stick.
    Coulomb {
        /// Friction coefficient.
        mu: f64,
    },
    /// Smooth (regularised) Coulomb: `t = t_trial / sqrt(1 + (|t_trial| / mu p_n)^2)`.
    RegularizedCoulomb {
        /// Friction coefficient.
        mu: f64,
    },
    /// Pressure-dependent coefficient `mu0 (p_n / p0)^(-n)`.
    PressureDependent {
        /// Coefficient at the reference normal force.
        mu0: f64,
        /// Reference normal force (per hitting node).
        p0: f64,
        /// Exponent.
        n: f64,
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
    pub friction: Option<FrictionSpec>,
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
}

fn lagrange() -> NormalLaw {
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
    /// Contact pressure (normal force / tributary area) at every hitting node of a pair: one
    /// response per node, named `NAME[i]`, ordered along `along`.
    PressureProfile {
        /// Response name prefix.
        name: String,
        /// Contact pair name.
        pair: String,
        /// Coordinate the nodes are ordered by (reference configuration).
        along: Component,
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
}

impl ResponseSpec {
    /// Name of the response.
    pub fn name(&self) -> &str {
        match self {
            ResponseSpec::Reaction { name, .. }
            | ResponseSpec::Displacement { name, .. }
            | ResponseSpec::TargetForce { name, .. }
            | ResponseSpec::PressureProfile { name, .. }
            | ResponseSpec::History { name, .. } => name,
        }
    }
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

fn invalid(field: &str, problem: impl Into<String>) -> SceneError {
    SceneError::Invalid {
        field: field.to_string(),
        problem: problem.into(),
    }
}

fn finite(v: f64, field: &str) -> Result<(), SceneError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(invalid(field, format!("{v} is not a finite number")))
    }
}

fn positive(v: f64, field: &str) -> Result<(), SceneError> {
    finite(v, field)?;
    if v > 0.0 {
        Ok(())
    } else {
        Err(invalid(field, format!("must be > 0, got {v}")))
    }
}

fn nonnegative(v: f64, field: &str) -> Result<(), SceneError> {
    finite(v, field)?;
    if v >= 0.0 {
        Ok(())
    } else {
        Err(invalid(field, format!("must be >= 0, got {v}")))
    }
}

fn poisson(v: f64, field: &str) -> Result<(), SceneError> {
    finite(v, field)?;
    if v > -1.0 && v < 0.5 {
        Ok(())
    } else {
        Err(invalid(field, format!("must lie in (-1, 0.5), got {v}")))
    }
}

/// The TOML path (`bodies[0].material.E`) of the entry a deserialization error points at, with
/// the name of a missing or unknown field appended; `None` for syntax errors (the message gives
/// the line), errors without a position, and positions no single entry owns.
fn toml_path(text: &str, err: &toml::de::Error) -> Option<String> {
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

    /// Read a scene file.
    pub fn from_file(path: &Path) -> Result<Scene, SceneError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            file: file.clone(),
            source,
        })?;
        Self::from_toml(&text, &file)
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
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a scene always serialises")
    }

    /// Node sets named `A & B` (e.g. `upper.xmax & upper.ymin`, an edge) are the intersection
    /// of the named node sets: add every one the scene refers to.
    fn add_intersections(&self, mesh: &mut Mesh) -> Result<(), SceneError> {
        let mut names: Vec<(String, String)> = Vec::new();
        for (i, p) in self.prescribed.iter().enumerate() {
            names.push((p.set.clone(), format!("prescribed[{i}].set")));
        }
        for (i, l) in self.loads.iter().enumerate() {
            names.push((l.set.clone(), format!("loads[{i}].set")));
        }
        for (i, c) in self.contacts.iter().enumerate() {
            names.push((c.hitting.clone(), format!("contacts[{i}].hitting")));
        }
        for (i, r) in self.responses.iter().enumerate() {
            if let ResponseSpec::Reaction { set, .. } | ResponseSpec::Displacement { set, .. } = r {
                names.push((set.clone(), format!("responses[{i}].set")));
            }
        }
        for (name, field) in names {
            if !name.contains('&') || mesh.node_sets.contains_key(&name) {
                continue;
            }
            let mut nodes: Option<Vec<usize>> = None;
            for part in name.split('&').map(str::trim) {
                let v = mesh.node_sets.get(part).ok_or_else(|| {
                    invalid(&field, format!("no node set named '{part}' (in '{name}')"))
                })?;
                nodes = Some(match nodes {
                    None => v.clone(),
                    Some(n) => n.into_iter().filter(|k| v.contains(k)).collect(),
                });
            }
            let nodes = nodes.unwrap_or_default();
            if nodes.is_empty() {
                return Err(invalid(
                    &field,
                    format!("the intersection '{name}' is empty"),
                ));
            }
            mesh.node_sets.insert(name, nodes);
        }
        Ok(())
    }

    /// Validate and build the analysis model.
    pub fn build(&self) -> Result<Model, SceneError> {
        // sizes first: an absurd element count is an error, not an allocation attempt
        let mut total_elements: usize = 0;
        for (i, b) in self.bodies.iter().enumerate() {
            let at = format!("bodies[{i}]");
            let mut n: usize = 1;
            let axes = [&b.block.x, &b.block.y, &b.block.z];
            for (c, (label, axis)) in ["x", "y", "z"].iter().zip(axes).enumerate() {
                let origin = b.block.origin[c];
                finite(origin, &format!("{at}.origin[{c}]"))?;
                n = n.saturating_mul(check_axis(axis, origin, &format!("{at}.{label}"))?);
            }
            total_elements = total_elements.saturating_add(n);
            if total_elements > MAX_ELEMENTS {
                return Err(invalid(
                    &at,
                    format!("the bodies have more than {MAX_ELEMENTS} elements in all"),
                ));
            }
        }
        let mut mesh = Mesh::default();
        let mut bodies = Vec::new();
        for (i, b) in self.bodies.iter().enumerate() {
            let at = format!("bodies[{i}]");
            b.material.check(&format!("{at}.material"))?;
            let block = mesh
                .add_block(b.block.clone())
                .map_err(|e| invalid(&at, e.to_string()))?;
            bodies.push(Body {
                name: b.block.name.clone(),
                block,
                material: b.material.build(),
                kinematics: b.kinematics,
                formulation: b.formulation,
            });
        }
        for (i, f) in self.free_nodes.iter().enumerate() {
            for (c, v) in f.x.iter().enumerate() {
                finite(*v, &format!("free_nodes[{i}].x[{c}]"))?;
            }
            if mesh.node_sets.contains_key(&f.name) {
                return Err(invalid(
                    &format!("free_nodes[{i}].name"),
                    format!("set '{}' already exists", f.name),
                ));
            }
            let n = mesh.add_free_node(f.x);
            mesh.node_sets.insert(f.name.clone(), vec![n]);
        }
        self.add_intersections(&mut mesh)?;
        let set = |name: &str, field: &str| -> Result<Vec<usize>, SceneError> {
            match mesh.node_sets.get(name) {
                Some(v) if !v.is_empty() => Ok(v.clone()),
                Some(_) => Err(invalid(field, format!("node set '{name}' is empty"))),
                None => Err(invalid(
                    field,
                    format!(
                        "no node set named '{name}' (sets: {})",
                        mesh.node_sets
                            .keys()
                            .cloned()
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                )),
            }
        };
        let one = |name: &str, field: &str| -> Result<usize, SceneError> {
            let v = set(name, field)?;
            if v.len() != 1 {
                return Err(invalid(
                    field,
                    format!("set '{name}' has {} nodes, a spring needs one", v.len()),
                ));
            }
            Ok(v[0])
        };
        let mut springs = Vec::new();
        for (i, s) in self.springs.iter().enumerate() {
            let at = format!("springs[{i}]");
            for r in s.stiffness.iter().flatten() {
                finite(*r, &format!("{at}.stiffness"))?;
            }
            springs.push(Spring {
                a: one(&s.a, &format!("{at}.a"))?,
                b: match &s.b {
                    Some(b) => Some(one(b, &format!("{at}.b"))?),
                    None => None,
                },
                stiffness: s.stiffness,
            });
        }
        let amplitude = |pts: &[(f64, f64)], field: &str| -> Result<Amplitude, SceneError> {
            if pts.is_empty() {
                return Err(invalid(field, "an amplitude needs at least one point"));
            }
            for (t, v) in pts {
                finite(*t, field)?;
                finite(*v, field)?;
            }
            if pts.windows(2).any(|w| w[1].0 < w[0].0) {
                return Err(invalid(field, "amplitude times must not decrease"));
            }
            Ok(Amplitude {
                points: pts.to_vec(),
            })
        };
        let mut prescribed = Vec::new();
        let mut seen = std::collections::HashMap::new();
        for (i, p) in self.prescribed.iter().enumerate() {
            let at = format!("prescribed[{i}]");
            finite(p.value, &format!("{at}.value"))?;
            let nodes = set(&p.set, &format!("{at}.set"))?;
            let amp = amplitude(&p.amplitude, &format!("{at}.amplitude"))?;
            if p.components.is_empty() {
                return Err(invalid(&format!("{at}.components"), "no component given"));
            }
            for c in &p.components {
                for &n in &nodes {
                    if let Some(j) = seen.insert((n, c.index()), i) {
                        return Err(invalid(
                            &at,
                            if j == i {
                                format!("component {c:?} is listed twice in '{}'", p.name)
                            } else {
                                format!(
                                    "node {n} component {c:?} is prescribed by both prescribed[{j}] ('{}') and prescribed[{i}] ('{}') (conflicting boundary conditions)",
                                    self.prescribed[j].name, p.name
                                )
                            },
                        ));
                    }
                }
                prescribed.push(Prescribed {
                    name: p.name.clone(),
                    nodes: nodes.clone(),
                    component: c.index(),
                    value: p.value,
                    amplitude: amp.clone(),
                });
            }
        }
        let mut loads = Vec::new();
        for (i, l) in self.loads.iter().enumerate() {
            let at = format!("loads[{i}]");
            finite(l.value, &format!("{at}.value"))?;
            let nodes = set(&l.set, &format!("{at}.set"))?;
            let weights = match mesh.face_sets.get(&l.set) {
                Some(faces) if !faces.is_empty() => {
                    let area = tributary_areas(&mesh, faces, &nodes);
                    let total: f64 = area.iter().sum();
                    if !(total.is_finite() && total > 0.0) {
                        return Err(invalid(
                            &format!("{at}.set"),
                            format!("the faces of '{}' have area {total}", l.set),
                        ));
                    }
                    area.iter().map(|a| a / total).collect()
                }
                _ => vec![1.0 / nodes.len() as f64; nodes.len()],
            };
            loads.push(NodalLoad {
                name: l.name.clone(),
                nodes,
                weights,
                component: l.component.index(),
                value: l.value,
                amplitude: amplitude(&l.amplitude, &format!("{at}.amplitude"))?,
            });
        }
        let mut times = Vec::new();
        let mut t0 = 0.0;
        if self.steps.is_empty() {
            return Err(invalid("steps", "no load step"));
        }
        for (i, s) in self.steps.iter().enumerate() {
            let at = format!("steps[{i}]");
            finite(s.end, &format!("{at}.end"))?;
            if s.end <= t0 {
                return Err(invalid(
                    &format!("{at}.end"),
                    format!(
                        "step ends at {} which is not after {t0} (zero or negative increment)",
                        s.end
                    ),
                ));
            }
            if s.increments == 0 {
                return Err(invalid(&format!("{at}.increments"), "must be at least 1"));
            }
            if s.increments > MAX_INCREMENTS - times.len() {
                return Err(invalid(
                    &format!("{at}.increments"),
                    format!("more than {MAX_INCREMENTS} increments in all steps"),
                ));
            }
            for k in 1..=s.increments {
                times.push(t0 + (s.end - t0) * k as f64 / s.increments as f64);
            }
            t0 = s.end;
        }
        let mut notes = Vec::new();
        let contacts = self.build_contacts(
            &mesh,
            &bodies,
            &springs,
            &prescribed,
            &amplitude,
            &mut notes,
        )?;
        let mut responses = Vec::new();
        let mut history_refs: Vec<(usize, usize, usize, usize, usize)> = Vec::new();
        for (i, r) in self.responses.iter().enumerate() {
            let field = format!("responses[{i}].set");
            let kind = match r {
                ResponseSpec::Reaction {
                    set: s, component, ..
                } => ResponseKind::Reaction {
                    nodes: set(s, &field)?,
                    component: component.index(),
                },
                ResponseSpec::Displacement {
                    set: s, component, ..
                } => ResponseKind::Displacement {
                    nodes: set(s, &field)?,
                    component: component.index(),
                },
                ResponseSpec::TargetForce {
                    pair, component, ..
                } => ResponseKind::TargetForce {
                    pair: contact_index(&contacts, pair, &format!("responses[{i}].pair"))?,
                    component: component.index(),
                },
                ResponseSpec::PressureProfile { name, pair, along } => {
                    let p = contact_index(&contacts, pair, &format!("responses[{i}].pair"))?;
                    let x = mesh.coordinates::<f64>(&mesh.block_geometry());
                    let c = &contacts[p];
                    let mut order: Vec<usize> = (0..c.hitting.len()).collect();
                    order.sort_by(|a, b| {
                        x[c.hitting[*a]][along.index()].total_cmp(&x[c.hitting[*b]][along.index()])
                    });
                    for (k, node) in order.iter().enumerate() {
                        responses.push(Response {
                            name: format!("{name}[{k}]"),
                            kind: ResponseKind::ContactPressure {
                                pair: p,
                                node: *node,
                                area: c.area[*node],
                            },
                        });
                    }
                    continue;
                }
                ResponseSpec::History {
                    body,
                    element,
                    point,
                    variable,
                    ..
                } => {
                    let at = format!("responses[{i}]");
                    let (bi, b) = bodies
                        .iter()
                        .enumerate()
                        .find(|(_, b)| &b.name == body)
                        .ok_or_else(|| {
                            invalid(&format!("{at}.body"), format!("no body '{body}'"))
                        })?;
                    let names = b.material.history_names();
                    let var = names.iter().position(|n| n == variable).ok_or_else(|| {
                        invalid(
                            &format!("{at}.variable"),
                            format!("material '{}' has history {names:?}", b.material.name()),
                        )
                    })?;
                    let elems = mesh.block_elements[b.block].clone();
                    if *element >= elems.len() {
                        return Err(invalid(
                            &format!("{at}.element"),
                            format!("body '{body}' has {} elements", elems.len()),
                        ));
                    }
                    if *point >= 8 {
                        return Err(invalid(&format!("{at}.point"), "Gauss points are 0-7"));
                    }
                    history_refs.push((responses.len(), bi, elems.start + element, *point, var));
                    ResponseKind::History { index: usize::MAX }
                }
            };
            responses.push(Response {
                name: r.name().to_string(),
                kind,
            });
        }
        let sv = &self.solver;
        positive(sv.force_tol, "solver.force_tol")?;
        positive(sv.energy_tol, "solver.energy_tol")?;
        if sv.max_iterations == 0 {
            return Err(invalid("solver.max_iterations", "must be at least 1"));
        }
        if sv.max_cutbacks > MAX_CUTBACKS {
            return Err(invalid(
                "solver.max_cutbacks",
                format!("at most {MAX_CUTBACKS} halvings of an increment"),
            ));
        }
        let mut model = Model {
            mesh,
            bodies,
            springs,
            prescribed,
            loads,
            times,
            contacts,
            responses,
            solver: self.solver.clone(),
            notes,
        };
        if !history_refs.is_empty() {
            let dofs = model.dof_map();
            for (r, b, e, point, var) in history_refs {
                let nh = model.bodies[b].material.history_len();
                model.responses[r].kind = ResponseKind::History {
                    index: dofs.history_offset[e] + point * nh + var,
                };
            }
        }
        if let Some(beta) = self.study.beta {
            finite(beta, "study.beta")?;
            if !(beta > 0.0 && beta < 1.0) {
                return Err(invalid(
                    "study.beta",
                    format!("must lie in (0, 1), got {beta}"),
                ));
            }
        }
        for (i, name) in self.study.params.iter().enumerate() {
            crate::sensitivity::Parameter::by_name(&model, name)
                .map_err(|e| invalid(&format!("study.params[{i}]"), e.to_string()))?;
        }
        Ok(model)
    }
}

/// Largest number of elements of a scene (all bodies).
const MAX_ELEMENTS: usize = 10_000_000;
/// Largest number of elements along one axis of a block.
const MAX_AXIS_ELEMENTS: usize = 100_000;
/// Largest number of load increments of a scene (all steps).
const MAX_INCREMENTS: usize = 1_000_000;
/// Largest number of halvings of an increment.
const MAX_CUTBACKS: usize = 64;

/// Checks one axis of a block (`at` is its TOML path, `origin` the block's origin along it)
/// and returns its number of elements.
fn check_axis(axis: &Axis, origin: f64, at: &str) -> Result<usize, SceneError> {
    positive(axis.length, &format!("{at}.length"))?;
    if !(origin + axis.length).is_finite() {
        return Err(invalid(
            &format!("{at}.length"),
            format!(
                "the block reaches {origin} + {} beyond the f64 range",
                axis.length
            ),
        ));
    }
    if axis.zones.is_empty() {
        return Err(invalid(
            &format!("{at}.zones"),
            "an axis needs at least one zone",
        ));
    }
    let mut n: usize = 0;
    for (k, z) in axis.zones.iter().enumerate() {
        let zf = format!("{at}.zones[{k}]");
        positive(z.fraction, &format!("{zf}.fraction"))?;
        positive(z.ratio, &format!("{zf}.ratio"))?;
        if z.elements == 0 {
            return Err(invalid(&format!("{zf}.elements"), "must be at least 1"));
        }
        n = n
            .checked_add(z.elements)
            .filter(|n| *n <= MAX_AXIS_ELEMENTS)
            .ok_or_else(|| {
                invalid(
                    &format!("{zf}.elements"),
                    format!("more than {MAX_AXIS_ELEMENTS} elements along one axis"),
                )
            })?;
    }
    // the grading must give elements of positive size in f64
    let t = axis.fractions();
    if t.iter().any(|v| !v.is_finite()) || t.windows(2).any(|w| w[1] <= w[0]) {
        return Err(invalid(
            &format!("{at}.zones"),
            "the fractions and ratios give elements of zero or non-finite size",
        ));
    }
    Ok(n)
}

/// Tributary area of each of `nodes` (sorted) over `faces`: a quarter of each face's area.
fn tributary_areas(mesh: &Mesh, faces: &[[usize; 4]], nodes: &[usize]) -> Vec<f64> {
    let x = mesh.coordinates::<f64>(&mesh.block_geometry());
    // position of each node in `nodes` (the first, as a linear search would find)
    let mut index = std::collections::HashMap::with_capacity(nodes.len());
    for (k, n) in nodes.iter().enumerate() {
        index.entry(*n).or_insert(k);
    }
    let mut area = vec![0.0; nodes.len()];
    for f in faces {
        let a = (x[f[1]] - x[f[0]]).cross(&(x[f[3]] - x[f[0]])).norm() * 0.5
            + (x[f[3]] - x[f[2]]).cross(&(x[f[1]] - x[f[2]])).norm() * 0.5;
        for n in f {
            if let Some(&k) = index.get(n) {
                area[k] += a / 4.0;
            }
        }
    }
    area
}

/// Factor `c_T` of the default tangential penalty `c_T E* A_i / h_i`: the stiffness of the
/// element layer under a hitting node times this. With it the elastic slip in stick,
/// `mu p_n / eps_T = (mu sigma_n / (c_T E*)) h_i`, is a strain-sized fraction of the element
/// (0.5 % of it at mu = 0.5 and a contact pressure of E* / 100), and Newton meets a stick
/// stiffness no larger than the structure's next to it.
pub const TANGENTIAL_STIFFNESS_FACTOR: f64 = 1.0;

/// Per node of `nodes` (sorted, with tributary areas `area`) on the boundary faces `faces`:
/// `A_i / h_i`, the node's area over the thickness of the element layer under it (the mean of
/// twice the distance from each adjacent face's centre to its element's centre). `None` when a
/// face belongs to no element.
fn layer_stiffness(
    mesh: &Mesh,
    x: &[nalgebra::Vector3<f64>],
    faces: &[[usize; 4]],
    nodes: &[usize],
    area: &[f64],
) -> Option<Vec<f64>> {
    use std::collections::{HashMap, HashSet};
    let key = |f: &[usize]| {
        let mut k = [f[0], f[1], f[2], f[3]];
        k.sort_unstable();
        k
    };
    let wanted: HashSet<[usize; 4]> = faces.iter().map(|f| key(f)).collect();
    let mut element_of: HashMap<[usize; 4], usize> = HashMap::new();
    for (e, conn) in mesh.elements.iter().enumerate() {
        for f in crate::element::hex8::FACE_NODES {
            let k = key(&f.map(|i| conn[i]));
            if wanted.contains(&k) {
                element_of.insert(k, e);
            }
        }
    }
    let index: HashMap<usize, usize> = nodes.iter().enumerate().map(|(k, n)| (*n, k)).collect();
    let mut h = vec![0.0; nodes.len()];
    let mut count = vec![0usize; nodes.len()];
    for f in faces {
        let e = *element_of.get(&key(f))?;
        let centre_f = f.iter().map(|n| x[*n]).sum::<nalgebra::Vector3<f64>>() / 4.0;
        let centre_e = mesh.elements[e]
            .iter()
            .map(|n| x[*n])
            .sum::<nalgebra::Vector3<f64>>()
            / 8.0;
        let hf = 2.0 * (centre_e - centre_f).norm();
        for n in f {
            if let Some(&k) = index.get(n) {
                h[k] += hf;
                count[k] += 1;
            }
        }
    }
    Some(
        area.iter()
            .zip(h.iter().zip(&count))
            .map(|(a, (h, c))| a / (h / (*c).max(1) as f64))
            .collect(),
    )
}

/// The generating block of node `n` (`None` for a free node).
fn block_of(mesh: &Mesh, n: usize) -> Option<usize> {
    match mesh.places[n] {
        crate::mesh::NodePlace::Block { block, .. } => Some(block),
        crate::mesh::NodePlace::Free(_) => None,
    }
}

/// How far the prescribed displacements can move nodes of `blocks`: per component the sum of
/// `|value| max |amplitude|` over the prescribed entries acting on them, as a vector norm.
fn prescribed_travel(mesh: &Mesh, prescribed: &[Prescribed], blocks: &[Option<usize>]) -> f64 {
    let mut m = [0.0f64; 3];
    for p in prescribed {
        if p.nodes.iter().any(|&n| blocks.contains(&block_of(mesh, n))) {
            let amp = p
                .amplitude
                .points
                .iter()
                .map(|(_, v)| v.abs())
                .fold(0.0f64, f64::max);
            m[p.component] += p.value.abs() * amp;
        }
    }
    (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt()
}

/// Plane-strain modulus `E / (1 - nu^2)` of the body owning node `n` (0 for a free node).
fn plane_modulus(mesh: &Mesh, bodies: &[Body], n: usize) -> f64 {
    match mesh.places[n] {
        crate::mesh::NodePlace::Block { block, .. } => bodies
            .iter()
            .find(|b| b.block == block)
            .map(|b| {
                let p = b.material.params();
                p[0] / (1.0 - p[1] * p[1])
            })
            .unwrap_or(0.0),
        crate::mesh::NodePlace::Free(_) => 0.0,
    }
}

/// The contact modulus of a pair: the hitting body's plane-strain modulus against a rigid
/// target, `1 / (1 / E*_1 + 1 / E*_2)` against a deformable one.
fn contact_modulus(mesh: &Mesh, bodies: &[Body], hitting: &[usize], target: &Target) -> f64 {
    let e1 = plane_modulus(mesh, bodies, hitting[0]);
    match target {
        Target::Faces { faces } => {
            let e2 = plane_modulus(mesh, bodies, faces[0][0]);
            if e1 > 0.0 && e2 > 0.0 {
                1.0 / (1.0 / e1 + 1.0 / e2)
            } else {
                e1.max(e2)
            }
        }
        Target::Rigid { .. } => e1,
    }
}

/// Validates and builds an amplitude, naming the field in errors.
type AmplitudeBuilder<'a> = dyn Fn(&[(f64, f64)], &str) -> Result<Amplitude, SceneError> + 'a;

fn contact_index(contacts: &[ContactPair], name: &str, field: &str) -> Result<usize, SceneError> {
    contacts.iter().position(|c| c.name == name).ok_or_else(|| {
        invalid(
            field,
            format!(
                "no contact pair '{name}' (pairs: {})",
                contacts
                    .iter()
                    .map(|c| c.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )
    })
}

fn vec3(v: [f64; 3], field: &str) -> Result<nalgebra::Vector3<f64>, SceneError> {
    for x in v {
        finite(x, field)?;
    }
    Ok(nalgebra::Vector3::from(v))
}

/// A direction: finite, with a finite nonzero length.
fn direction(v: [f64; 3], field: &str) -> Result<nalgebra::Vector3<f64>, SceneError> {
    let d = vec3(v, field)?;
    let n = d.norm();
    if !(n.is_finite() && n > 0.0) {
        return Err(invalid(
            field,
            format!("a direction needs a finite nonzero length, got {v:?}"),
        ));
    }
    Ok(d)
}

impl Scene {
    fn build_contacts(
        &self,
        mesh: &Mesh,
        bodies: &[Body],
        springs: &[Spring],
        prescribed: &[Prescribed],
        amplitude: &AmplitudeBuilder<'_>,
        notes: &mut Vec<String>,
    ) -> Result<Vec<ContactPair>, SceneError> {
        let x = mesh.coordinates::<f64>(&mesh.block_geometry());
        let mut out = Vec::new();
        for (ci, c) in self.contacts.iter().enumerate() {
            let at = format!("contacts[{ci}]");
            if self.contacts[..ci].iter().any(|o| o.name == c.name) {
                return Err(invalid(
                    &format!("{at}.name"),
                    format!("pair '{}' defined twice", c.name),
                ));
            }
            // hitting nodes and their tributary areas
            // per hitting node: tributary area, and the stiffness A_i / h_i of the element
            // layer under it (none for a node set)
            let (hitting, area, layer) = if let Some(faces) = mesh.face_sets.get(&c.hitting) {
                let mut nodes: Vec<usize> = faces.iter().flatten().copied().collect();
                nodes.sort();
                nodes.dedup();
                let area = tributary_areas(mesh, faces, &nodes);
                let layer = layer_stiffness(mesh, &x, faces, &nodes, &area);
                (nodes, area, layer)
            } else if let Some(nodes) = mesh.node_sets.get(&c.hitting) {
                if nodes.is_empty() {
                    return Err(invalid(
                        &format!("{at}.hitting"),
                        format!("node set '{}' is empty", c.hitting),
                    ));
                }
                (nodes.clone(), vec![1.0; nodes.len()], None)
            } else {
                return Err(invalid(
                    &format!("{at}.hitting"),
                    format!("no face set or node set named '{}'", c.hitting),
                ));
            };
            if let Some(r) = c.search_radius {
                positive(r, &format!("{at}.search_radius"))?;
            }
            let (target, candidates, diag) = match &c.target {
                TargetSpec::Faces(name) => {
                    let faces = mesh.face_sets.get(name).ok_or_else(|| {
                        invalid(
                            &format!("{at}.target"),
                            format!("no face set named '{name}'"),
                        )
                    })?;
                    if faces.is_empty() {
                        return Err(invalid(
                            &format!("{at}.target"),
                            format!("face set '{name}' is empty"),
                        ));
                    }
                    let diag = faces
                        .iter()
                        .map(|f| (x[f[2]] - x[f[0]]).norm().max((x[f[3]] - x[f[1]]).norm()))
                        .fold(0.0f64, f64::max);
                    // default: three face diagonals, plus how far the prescribed
                    // displacements can move the two bodies against each other
                    let radius = match c.search_radius {
                        Some(r) => r,
                        None => {
                            let blocks = [block_of(mesh, hitting[0]), block_of(mesh, faces[0][0])];
                            let travel = prescribed_travel(mesh, prescribed, &blocks);
                            let r = 3.0 * diag + travel;
                            notes.push(format!(
                                "{at} '{}': search radius {r:.4e} (3 face diagonals {:.4e} + the bodies' largest prescribed travel {travel:.4e})",
                                c.name,
                                3.0 * diag
                            ));
                            r
                        }
                    };
                    positive(radius, &format!("{at}.search_radius"))?;
                    let mut candidates = Vec::new();
                    for &s in &hitting {
                        let cands: Vec<usize> = faces
                            .iter()
                            .enumerate()
                            .filter(|(_, f)| {
                                let centre = (x[f[0]] + x[f[1]] + x[f[2]] + x[f[3]]) / 4.0;
                                (x[s] - centre).norm() <= radius && !f.contains(&s)
                            })
                            .map(|(k, _)| k)
                            .collect();
                        candidates.push(cands);
                    }
                    (
                        Target::Faces {
                            faces: faces.clone(),
                        },
                        candidates,
                        diag,
                    )
                }
                TargetSpec::Rigid { surface, motion } => {
                    let sf = format!("{at}.target.surface");
                    let surface = match surface {
                        RigidSpec::Plane { point, normal } => RigidSurface::Plane {
                            point: vec3(*point, &format!("{sf}.point"))?,
                            normal: direction(*normal, &format!("{sf}.normal"))?,
                        },
                        RigidSpec::Cylinder {
                            axis_point,
                            axis,
                            radius,
                        } => {
                            positive(*radius, &format!("{sf}.radius"))?;
                            RigidSurface::Cylinder {
                                axis_point: vec3(*axis_point, &format!("{sf}.axis_point"))?,
                                axis: direction(*axis, &format!("{sf}.axis"))?,
                                radius: *radius,
                            }
                        }
                        RigidSpec::RoundedBox {
                            center,
                            half_extents,
                            radius,
                        } => {
                            for h in half_extents {
                                positive(*h, &format!("{sf}.half_extents"))?;
                            }
                            finite(*radius, &format!("{sf}.radius"))?;
                            if *radius < 0.0 || half_extents.iter().any(|h| *radius > *h) {
                                return Err(invalid(
                                    &format!("{sf}.radius"),
                                    "needs 0 <= radius <= every half extent",
                                ));
                            }
                            RigidSurface::RoundedBox {
                                center: vec3(*center, &format!("{sf}.center"))?,
                                half_extents: vec3(*half_extents, &sf)?,
                                radius: *radius,
                            }
                        }
                    };
                    let mut m = Vec::new();
                    for (k, ms) in motion.iter().enumerate() {
                        let f = format!("{at}.target.motion[{k}]");
                        finite(ms.value, &format!("{f}.value"))?;
                        m.push(RigidMotion {
                            component: ms.component.index(),
                            value: ms.value,
                            amplitude: amplitude(&ms.amplitude, &format!("{f}.amplitude"))?,
                        });
                    }
                    (
                        Target::Rigid { surface, motion: m },
                        vec![Vec::new(); hitting.len()],
                        0.0,
                    )
                }
            };
            // hitting nodes with no target face within the search radius can never touch it:
            // left out of the pair (all of them: an error)
            let (hitting, area, layer, candidates) = if let Target::Faces { .. } = target {
                let keep: Vec<bool> = candidates.iter().map(|c| !c.is_empty()).collect();
                let dropped: Vec<usize> = hitting
                    .iter()
                    .zip(&keep)
                    .filter(|(_, k)| !**k)
                    .map(|(n, _)| *n)
                    .collect();
                if dropped.len() == hitting.len() {
                    return Err(invalid(
                        &format!("{at}.search_radius"),
                        format!(
                            "no target face is within the search radius of any hitting node (largest face diagonal {diag:.3e}): the pair can never touch"
                        ),
                    ));
                }
                if !dropped.is_empty() {
                    let shown: Vec<String> =
                        dropped.iter().take(8).map(|n| n.to_string()).collect();
                    notes.push(format!(
                        "{at} '{}': {} of {} hitting nodes have no target face within the search radius and are left out (they can never touch it): nodes {}{}",
                        c.name,
                        dropped.len(),
                        hitting.len(),
                        shown.join(", "),
                        if dropped.len() > 8 { ", ..." } else { "" }
                    ));
                }
                let pick = |v: Vec<f64>| -> Vec<f64> {
                    v.into_iter()
                        .zip(&keep)
                        .filter(|(_, k)| **k)
                        .map(|(x, _)| x)
                        .collect()
                };
                (
                    hitting
                        .iter()
                        .zip(&keep)
                        .filter(|(_, k)| **k)
                        .map(|(n, _)| *n)
                        .collect::<Vec<usize>>(),
                    pick(area),
                    layer.map(pick),
                    candidates.into_iter().filter(|c| !c.is_empty()).collect(),
                )
            } else {
                (hitting, area, layer, candidates)
            };
            let friction = match &c.friction {
                None => None,
                Some(FrictionSpec::Coulomb { mu }) => {
                    nonnegative(*mu, &format!("{at}.friction.mu"))?;
                    Some(Friction::Coulomb(Coulomb::new(*mu)))
                }
                Some(FrictionSpec::RegularizedCoulomb { mu }) => {
                    nonnegative(*mu, &format!("{at}.friction.mu"))?;
                    Some(Friction::RegularizedCoulomb(RegularizedCoulomb::new(*mu)))
                }
                Some(FrictionSpec::PressureDependent { mu0, p0, n }) => {
                    nonnegative(*mu0, &format!("{at}.friction.mu0"))?;
                    positive(*p0, &format!("{at}.friction.p0"))?;
                    finite(*n, &format!("{at}.friction.n"))?;
                    Some(Friction::PressureDependent(PressureDependentCoulomb::new(
                        *mu0, *p0, *n,
                    )))
                }
            };
            match c.normal {
                NormalLaw::Penalty { stiffness } => {
                    positive(stiffness, &format!("{at}.normal.stiffness"))?;
                }
                NormalLaw::Augmented {
                    stiffness,
                    tolerance,
                } => {
                    positive(stiffness, &format!("{at}.normal.stiffness"))?;
                    positive(tolerance, &format!("{at}.normal.tolerance"))?;
                }
                NormalLaw::Lagrange => {}
            }
            let scale = match c.constraint_scale {
                Some(k) => {
                    positive(k, &format!("{at}.constraint_scale"))?;
                    k
                }
                None => {
                    let e = bodies
                        .iter()
                        .map(|b| b.material.params()[0])
                        .fold(0.0f64, f64::max);
                    let mean_area = area.iter().sum::<f64>() / area.len() as f64;
                    let ks = springs
                        .iter()
                        .flat_map(|s| s.stiffness.iter().flatten().map(|v| v.abs()))
                        .fold(0.0f64, f64::max);
                    let k = if e > 0.0 { e * mean_area.sqrt() } else { ks };
                    let k = if k > 0.0 { k } else { 1.0 };
                    if c.normal == NormalLaw::Lagrange {
                        notes.push(format!(
                            "{at} '{}': constraint scale {k:.4e} (force per unit gap of the multiplier rows: {})",
                            c.name,
                            if e > 0.0 {
                                "the largest E times the square root of the mean tributary area"
                            } else {
                                "the largest spring stiffness"
                            }
                        ));
                    }
                    k
                }
            };
            let activation = match c.activation {
                Some(a) => {
                    positive(a, &format!("{at}.activation"))?;
                    a
                }
                None => 1.0,
            };
            // the tangential penalty: given, or derived per node from the element layer
            // under it (TANGENTIAL_STIFFNESS_FACTOR E* A_i / h_i)
            let (eps_t, weight) = match (c.tangential_stiffness, &layer) {
                (Some(k), _) => {
                    positive(k, &format!("{at}.tangential_stiffness"))?;
                    (k, vec![1.0; hitting.len()])
                }
                (None, Some(layer)) => {
                    let e_star = contact_modulus(mesh, bodies, &hitting, &target);
                    let per_node: Vec<f64> = layer
                        .iter()
                        .map(|l| TANGENTIAL_STIFFNESS_FACTOR * e_star * l)
                        .collect();
                    let mean = per_node.iter().sum::<f64>() / per_node.len() as f64;
                    if !(mean.is_finite() && mean > 0.0) {
                        return Err(invalid(
                            &format!("{at}.tangential_stiffness"),
                            format!("no default from the surface elements (mean stiffness {mean}): give one"),
                        ));
                    }
                    let (lo, hi) = per_node
                        .iter()
                        .fold((f64::INFINITY, 0.0f64), |(a, b), k| (a.min(*k), b.max(*k)));
                    notes.push(format!(
                        "{at} '{}': tangential stiffness {mean:.4e} per hitting node on average ({lo:.4e} to {hi:.4e}): {} E* A_i / h_i, with E* = {e_star:.4e} and A_i / h_i the node's area over the thickness of the element layer under it",
                        c.name,
                        TANGENTIAL_STIFFNESS_FACTOR
                    ));
                    (mean, per_node.iter().map(|k| k / mean).collect())
                }
                (None, None) => (100.0 * scale, vec![1.0; hitting.len()]),
            };
            out.push(ContactPair {
                name: c.name.clone(),
                hitting,
                area,
                target,
                normal: c.normal,
                friction,
                tangential_stiffness: eps_t,
                tangential_weight: weight,
                constraint_scale: scale,
                activation,
                candidates,
            });
        }
        Ok(out)
    }
}

/// Names and one-line descriptions of the built-in scenes.
pub fn builtin_list() -> Vec<(&'static str, &'static str)> {
    vec![
        (
            "cantilever",
            "elastic cantilever, tip dead load to alpha = P L^2/(E I) = 5, large deflection (oracles 3)",
        ),
        (
            "uniaxial-j2",
            "one hex8, J2 with linear hardening, uniaxial stress, strain cycle 0 -> +0.01 -> -0.01 (oracles 1)",
        ),
        (
            "uniaxial-svk",
            "one hex8, St Venant-Kirchhoff, uniaxial stress, stretch to 1.5 (oracles 2)",
        ),
        ("klarbring-2dof", "node with coupled stiffness on a rigid plane, Coulomb friction, load cycle (oracles 6)"),
        ("jenkins", "spring and Coulomb slider under a cyclic base displacement (oracles 5)"),
        ("strip-pullout", "strip on a rigid plane pulled at one end, partial slip, unloading (oracles 7)"),
        ("hertz", "rigid cylinder on a plane-strain block, load control (oracles 4)"),
        ("contact-patch", "two blocks with matching meshes under uniform pressure, frictional"),
        ("sliding-block", "deformable block slid across three faces of a deformable base, mu = 0.3"),
        ("indentation", "paper 3.1: rigid block pressed into an elastic half-space, then slid 3.33 mm, mu = 0.5"),
        ("leaf-spring", "paper 3.2: elastoplastic two-leaf spring, block at the tip, load/unload/reload, mu = 0.5"),
        (
            "leaf-spring-coarse",
            "the leaf spring on 5 mm elements, 20 mm down, back to 10, down again (quick look, tests)",
        ),
        ("leaf-spring-mu0", "paper 3.2 without friction (mu = 0)"),
        ("stacked-leaves", "two elastic leaves clamped together, tip load, friction at the tip (oracles 8)"),
        (
            "cantilever-small",
            "elastic cantilever, L/h = 20, small tip load: P L^3/(3 E I) (oracles 3)",
        ),
    ]
}

/// A built-in scene by name, with the design parameters it is studied with.
pub fn builtin(name: &str) -> Option<Scene> {
    let mut scene = builtin_scene(name)?;
    scene.name = name.to_string();
    if scene.study.params.is_empty() {
        let params: &[&str] = match name {
            "cantilever" | "cantilever-small" => &["E"],
            "uniaxial-j2" => &["sigma_y", "H", "E"],
            // dP11/dnu = 0 exactly (oracles.md section 2): a relative error against a zero
            // derivative is undefined, so nu is not swept (tests check the zero)
            "uniaxial-svk" => &["E"],
            "klarbring-2dof" | "jenkins" | "indentation" | "sliding-block" | "contact-patch" => {
                &["mu"]
            }
            "strip-pullout" => &["mu", "E"],
            "hertz" => &["E"],
            _ => &[],
        };
        scene.study.params = params.iter().map(|p| p.to_string()).collect();
    }
    Some(scene)
}

fn builtin_scene(name: &str) -> Option<Scene> {
    match name {
        "cantilever" => Some(cantilever(&CantileverSpec::large_deflection())),
        "cantilever-small" => Some(cantilever(&CantileverSpec::small_deflection())),
        "uniaxial-j2" => Some(uniaxial_j2(Kinematics::Small, 10)),
        "uniaxial-svk" => Some(uniaxial_svk(1.5, 5)),
        "klarbring-2dof" => Some(klarbring_2dof(10)),
        "jenkins" => Some(jenkins(10)),
        "strip-pullout" => Some(strip_pullout(&StripSpec::default())),
        "hertz" => Some(hertz(&HertzSpec::default())),
        "contact-patch" => Some(contact_patch(Some(0.3))),
        "indentation" => Some(indentation(2, 10)),
        "sliding-block" => Some(sliding_block(Some(0.3))),
        "leaf-spring" => Some(leaf_spring(&LeafSpringSpec::default())),
        "leaf-spring-coarse" => Some(leaf_spring(&LeafSpringSpec::reduced())),
        "leaf-spring-mu0" => Some(leaf_spring(&LeafSpringSpec {
            mu: 0.0,
            ..LeafSpringSpec::default()
        })),
        "stacked-leaves" => Some(stacked_leaves(&StackedLeavesSpec::default())),
        _ => None,
    }
}

/// Parameters of the cantilever scenes.
#[derive(Clone, Debug)]
pub struct CantileverSpec {
    /// Length `L` along x.
    pub length: f64,
    /// Height `h` along y (the bending direction).
    pub height: f64,
    /// Width `b` along z.
    pub width: f64,
    /// Young's modulus `E`.
    pub young: f64,
    /// Poisson's ratio `nu`.
    pub nu: f64,
    /// Elements along the length.
    pub nx: usize,
    /// Elements through the height.
    pub ny: usize,
    /// Load parameter alpha = P L^2 / (E I) at the end of the history.
    pub alpha: f64,
    /// Number of equal load increments.
    pub increments: usize,
    /// Small or large deformation.
    pub kinematics: Kinematics,
    /// Hex8 element formulation.
    pub formulation: Hex8Formulation,
}

impl CantileverSpec {
    /// L/h = 50, nu = 0, alpha up to 5 (the elastica table).
    pub fn large_deflection() -> Self {
        CantileverSpec {
            length: 10.0,
            height: 0.2,
            width: 0.2,
            young: 1.0e5,
            nu: 0.0,
            nx: 50,
            ny: 2,
            alpha: 5.0,
            increments: 10,
            kinematics: Kinematics::Large,
            formulation: Hex8Formulation::IncompatibleModes,
        }
    }

    /// L/h = 20, 2 elements through the thickness, small load.
    pub fn small_deflection() -> Self {
        CantileverSpec {
            length: 2.0,
            height: 0.1,
            width: 0.1,
            young: 1.0e5,
            nu: 0.0,
            nx: 20,
            ny: 2,
            alpha: 1e-4,
            increments: 1,
            kinematics: Kinematics::Small,
            formulation: Hex8Formulation::IncompatibleModes,
        }
    }

    /// Second moment of area of the section.
    pub fn inertia(&self) -> f64 {
        self.width * self.height.powi(3) / 12.0
    }

    /// The tip load that gives `alpha`.
    pub fn load(&self) -> f64 {
        self.alpha * self.young * self.inertia() / self.length.powi(2)
    }
}

/// A cantilever along x, clamped at x = 0, dead load in -y on the tip face.
pub fn cantilever(c: &CantileverSpec) -> Scene {
    Scene {
        name: "cantilever".into(),
        description: format!(
            "Cantilever L = {}, h = {}, b = {}, E = {}, nu = {}; tip dead load P = alpha E I / L^2 with alpha = {} in -y, clamped at x = 0.",
            c.length, c.height, c.width, c.young, c.nu, c.alpha
        ),
        bodies: vec![BodySpec {
            block: BlockSpec {
                name: "beam".into(),
                origin: [0.0, 0.0, 0.0],
                x: Axis::uniform(c.length, c.nx),
                y: Axis::uniform(c.height, c.ny),
                z: Axis {
                    length: c.width,
                    zones: vec![Zone {
                        fraction: 1.0,
                        elements: 1,
                        ratio: 1.0,
                    }],
                },
            },
            material: MaterialSpec::Svk {
                young: c.young,
                nu: c.nu,
            },
            kinematics: c.kinematics,
            formulation: c.formulation,
        }],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![PrescribedSpec {
            name: "clamp".into(),
            set: "beam.xmin".into(),
            components: vec![Component::X, Component::Y, Component::Z],
            value: 0.0,
            amplitude: ramp(),
        }],
        contacts: vec![],
        loads: vec![LoadSpec {
            name: "tip".into(),
            set: "beam.xmax".into(),
            component: Component::Y,
            value: -c.load(),
            amplitude: ramp(),
        }],
        steps: vec![StepSpec {
            end: 1.0,
            increments: c.increments,
        }],
        responses: vec![
            ResponseSpec::Displacement {
                name: "tip-deflection".into(),
                set: "beam.xmax".into(),
                component: Component::Y,
            },
            ResponseSpec::Displacement {
                name: "tip-shortening".into(),
                set: "beam.xmax".into(),
                component: Component::X,
            },
            ResponseSpec::Reaction {
                name: "clamp-reaction-y".into(),
                set: "beam.xmin".into(),
                component: Component::Y,
            },
        ],
        solver: SolverSettings::default(),
        study: StudySpec::default(),
    }
}

/// One unit hex8 of J2 material (E = 200 GPa, nu = 0.3, sigma_y = 250 MPa, H = 10 GPa; units
/// MPa and mm) in uniaxial stress: symmetry planes x = 0, y = 0, z = 0, the face x = 1 driven
/// through the axial strain cycle 0 -> +0.01 (t = 1) -> -0.01 (t = 3), `increments_per_unit`
/// increments per unit of pseudo-time. Responses: the axial stress (the reaction on the unit
/// face), the strain, and the equivalent plastic strain of Gauss point 0.
pub fn uniaxial_j2(kinematics: Kinematics, increments_per_unit: usize) -> Scene {
    let mut scene = uniaxial_cube(
        MaterialSpec::J2 {
            young: 200e3,
            nu: 0.3,
            sigma_y: 250.0,
            hardening: 10e3,
            sigma_inf: None,
            delta: None,
        },
        kinematics,
        0.01,
        vec![(0.0, 0.0), (1.0, 1.0), (3.0, -1.0)],
        vec![
            StepSpec {
                end: 1.0,
                increments: increments_per_unit,
            },
            StepSpec {
                end: 3.0,
                increments: 2 * increments_per_unit,
            },
        ],
    );
    scene.name = "uniaxial-j2".into();
    scene.description =
        "Uniaxial stress cycle of one J2 hex8 (shared/oracles.md section 1).".into();
    scene.responses.push(ResponseSpec::History {
        name: "alpha".into(),
        body: "cube".into(),
        element: 0,
        point: 0,
        variable: "alpha".into(),
    });
    scene
}

/// shared/oracles.md section 2: one St Venant-Kirchhoff hex8 (unit cube, E = 1000, nu = 0.3,
/// large deformation) stretched to `lambda_max` in x with its lateral faces free; `stress` is
/// the nominal stress P11 (the reaction on the unit face).
pub fn uniaxial_svk(lambda_max: f64, increments: usize) -> Scene {
    let mut scene = uniaxial_cube(
        MaterialSpec::Svk {
            young: 1000.0,
            nu: 0.3,
        },
        Kinematics::Large,
        lambda_max - 1.0,
        ramp(),
        vec![StepSpec {
            end: 1.0,
            increments,
        }],
    );
    scene.name = "uniaxial-svk".into();
    scene.description = format!(
        "One St Venant-Kirchhoff hex8 stretched to lambda = {lambda_max} in uniaxial stress (shared/oracles.md section 2)."
    );
    scene
}

/// A unit cube with symmetry conditions on its three minimum faces and the x-displacement of
/// its `xmax` face prescribed (`value * amplitude(t)`); responses `stress` (reaction on
/// `xmax`, x) and `strain` (its displacement).
fn uniaxial_cube(
    material: MaterialSpec,
    kinematics: Kinematics,
    value: f64,
    amplitude: Vec<(f64, f64)>,
    steps: Vec<StepSpec>,
) -> Scene {
    let fixed = |name: &str, set: &str, c: Component| PrescribedSpec {
        name: name.into(),
        set: set.into(),
        components: vec![c],
        value: 0.0,
        amplitude: ramp(),
    };
    Scene {
        name: "uniaxial".into(),
        description: String::new(),
        bodies: vec![BodySpec {
            block: BlockSpec {
                name: "cube".into(),
                origin: [0.0; 3],
                x: Axis::uniform(1.0, 1),
                y: Axis::uniform(1.0, 1),
                z: Axis::uniform(1.0, 1),
            },
            material,
            kinematics,
            formulation: Hex8Formulation::Full,
        }],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![
            fixed("sym-x", "cube.xmin", Component::X),
            fixed("sym-y", "cube.ymin", Component::Y),
            fixed("sym-z", "cube.zmin", Component::Z),
            PrescribedSpec {
                name: "strain".into(),
                set: "cube.xmax".into(),
                components: vec![Component::X],
                value,
                amplitude,
            },
        ],
        loads: vec![],
        contacts: vec![],
        steps,
        responses: vec![
            ResponseSpec::Reaction {
                name: "stress".into(),
                set: "cube.xmax".into(),
                component: Component::X,
            },
            ResponseSpec::Displacement {
                name: "strain".into(),
                set: "cube.xmax".into(),
                component: Component::X,
            },
        ],
        solver: SolverSettings::default(),
        study: StudySpec::default(),
    }
}

fn fixed_set(name: &str, set: &str, components: &[Component]) -> PrescribedSpec {
    PrescribedSpec {
        name: name.into(),
        set: set.into(),
        components: components.to_vec(),
        value: 0.0,
        amplitude: ramp(),
    }
}

fn block_body(
    name: &str,
    origin: [f64; 3],
    axes: [Axis; 3],
    material: MaterialSpec,
    kinematics: Kinematics,
) -> BodySpec {
    let [x, y, z] = axes;
    BodySpec {
        block: BlockSpec {
            name: name.into(),
            origin,
            x,
            y,
            z,
        },
        material,
        kinematics,
        formulation: Hex8Formulation::IncompatibleModes,
    }
}

fn graded(length: f64, fine_fraction: f64, fine: usize, coarse: usize, ratio: f64) -> Axis {
    Axis {
        length,
        zones: vec![
            Zone {
                fraction: fine_fraction,
                elements: fine,
                ratio: 1.0,
            },
            Zone {
                fraction: 1.0 - fine_fraction,
                elements: coarse,
                ratio,
            },
        ],
    }
}

/// shared/oracles.md section 6: a node at the origin with stiffness
/// `K = [[k11, k12], [k12, k22]]` against the rigid plane y = 0, normal load `F_n = -1`, tangential
/// load `F_t` 0 -> 0.6 (t = 1) -> -0.6 (t = 3) -> 0.6 (t = 5), Coulomb `mu = 0.3`.
pub fn klarbring_2dof(increments_per_unit: usize) -> Scene {
    Scene {
        name: "klarbring-2dof".into(),
        description: "Two-degree-of-freedom frictional system (shared/oracles.md section 6)."
            .into(),
        bodies: vec![],
        free_nodes: vec![FreeNodeSpec {
            name: "node".into(),
            x: [0.0; 3],
        }],
        springs: vec![SpringSpec {
            a: "node".into(),
            b: None,
            stiffness: [[1.0, 0.5, 0.0], [0.5, 1.0, 0.0], [0.0, 0.0, 1.0]],
        }],
        prescribed: vec![],
        loads: vec![
            LoadSpec {
                name: "Fn".into(),
                set: "node".into(),
                component: Component::Y,
                value: -1.0,
                amplitude: vec![(0.0, 1.0), (5.0, 1.0)],
            },
            LoadSpec {
                name: "Ft".into(),
                set: "node".into(),
                component: Component::X,
                value: 0.6,
                amplitude: vec![(0.0, 0.0), (1.0, 1.0), (3.0, -1.0), (5.0, 1.0)],
            },
        ],
        contacts: vec![ContactSpec {
            name: "plane".into(),
            hitting: "node".into(),
            target: TargetSpec::Rigid {
                surface: RigidSpec::Plane {
                    point: [0.0; 3],
                    normal: [0.0, 1.0, 0.0],
                },
                motion: vec![],
            },
            normal: NormalLaw::Lagrange,
            friction: Some(FrictionSpec::Coulomb { mu: 0.3 }),
            // The oracle's stick is rigid; the penalty leaves an elastic slip |t| / eps_T in
            // stick phases (1e-7 here). Slipping states, where the worked values are, do not
            // depend on it. A stiffer penalty buys little: the stick force's round-off grows
            // as eps_T |u| 1e-16.
            tangential_stiffness: Some(1e6),
            constraint_scale: Some(1.0),
            activation: None,
            search_radius: None,
        }],
        steps: vec![StepSpec {
            end: 5.0,
            increments: 5 * increments_per_unit,
        }],
        responses: vec![
            ResponseSpec::Displacement {
                name: "u".into(),
                set: "node".into(),
                component: Component::X,
            },
            ResponseSpec::TargetForce {
                name: "plane-force-x".into(),
                pair: "plane".into(),
                component: Component::X,
            },
            ResponseSpec::TargetForce {
                name: "plane-force-y".into(),
                pair: "plane".into(),
                component: Component::Y,
            },
        ],
        // the oracle is exact: converge close to round-off (the stick force carries
        // eps_T |u| 1e-16 ~ 1e-11 of noise), not to the default 1e-9
        solver: SolverSettings {
            force_tol: 1e-11,
            ..SolverSettings::default()
        },
        study: StudySpec::default(),
    }
}

/// shared/oracles.md section 5: a slider (node on the rigid plane y = 0 under the normal force
/// `N = 1`) tied by a spring `k = 1` to a base whose displacement `U(t)` cycles 0 -> U_a (t = 1)
/// -> -U_a (t = 3) -> U_a (t = 5), `U_a = 1`, Coulomb `mu = 0.3`.
pub fn jenkins(increments_per_unit: usize) -> Scene {
    Scene {
        name: "jenkins".into(),
        description: "Jenkins element: spring and Coulomb slider (shared/oracles.md section 5)."
            .into(),
        bodies: vec![],
        free_nodes: vec![
            FreeNodeSpec {
                name: "slider".into(),
                x: [0.0; 3],
            },
            FreeNodeSpec {
                name: "base".into(),
                x: [-1.0, 0.0, 0.0],
            },
        ],
        springs: vec![
            SpringSpec {
                a: "slider".into(),
                b: Some("base".into()),
                stiffness: [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
            },
            // holds the slider in y before contact closes and in z (no effect in contact)
            SpringSpec {
                a: "slider".into(),
                b: None,
                stiffness: [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            },
        ],
        prescribed: vec![
            PrescribedSpec {
                name: "U".into(),
                set: "base".into(),
                components: vec![Component::X],
                value: 1.0,
                amplitude: vec![(0.0, 0.0), (1.0, 1.0), (3.0, -1.0), (5.0, 1.0)],
            },
            fixed_set("base-yz", "base", &[Component::Y, Component::Z]),
        ],
        loads: vec![LoadSpec {
            name: "N".into(),
            set: "slider".into(),
            component: Component::Y,
            value: -1.0,
            amplitude: vec![(0.0, 1.0), (5.0, 1.0)],
        }],
        contacts: vec![ContactSpec {
            name: "plane".into(),
            hitting: "slider".into(),
            target: TargetSpec::Rigid {
                surface: RigidSpec::Plane {
                    point: [0.0; 3],
                    normal: [0.0, 1.0, 0.0],
                },
                motion: vec![],
            },
            normal: NormalLaw::Lagrange,
            friction: Some(FrictionSpec::Coulomb { mu: 0.3 }),
            tangential_stiffness: Some(1e6),
            constraint_scale: Some(1.0),
            activation: None,
            search_radius: None,
        }],
        steps: vec![StepSpec {
            end: 5.0,
            increments: 5 * increments_per_unit,
        }],
        responses: vec![
            ResponseSpec::Reaction {
                name: "T".into(),
                set: "base".into(),
                component: Component::X,
            },
            ResponseSpec::Displacement {
                name: "slider-u".into(),
                set: "slider".into(),
                component: Component::X,
            },
        ],
        // the oracle is exact: converge close to round-off (the stick force carries
        // eps_T |u| 1e-16 ~ 1e-11 of noise), not to the default 1e-9
        solver: SolverSettings {
            force_tol: 1e-11,
            ..SolverSettings::default()
        },
        study: StudySpec::default(),
    }
}

/// Parameters of the strip pull-out scene (shared/oracles.md section 7).
#[derive(Clone, Debug)]
pub struct StripSpec {
    /// Length `L` along x.
    pub length: f64,
    /// Thickness `t` along y.
    pub thickness: f64,
    /// Width `b` along z.
    pub width: f64,
    /// Young's modulus `E`.
    pub young: f64,
    /// Coulomb friction coefficient `mu`.
    pub mu: f64,
    /// Normal load per unit length.
    pub n: f64,
    /// Largest pull force.
    pub force: f64,
    /// Elements along the length.
    pub elements: usize,
    /// Load increments per unit of pseudo-time (the history runs to t = 2).
    pub increments_per_unit: usize,
}

impl Default for StripSpec {
    fn default() -> Self {
        StripSpec {
            // thin: the 1D oracle holds where the slip zone exceeds 20 thicknesses
            length: 10.0,
            thickness: 0.02,
            width: 0.1,
            young: 1e5,
            mu: 0.5,
            n: 1.0,
            force: 1.5,
            elements: 100,
            increments_per_unit: 10,
        }
    }
}

/// A strip on the rigid plane y = 0 under a normal load `n` per unit length, pulled at
/// x = L by a force F: 0 -> F_1 (t = 1) -> 0 (t = 2). Small kinematics, nu = 0.
pub fn strip_pullout(s: &StripSpec) -> Scene {
    Scene {
        name: "strip-pullout".into(),
        description: format!(
            "Frictional strip pull-out (shared/oracles.md section 7): L = {}, t = {}, b = {}, E = {}, mu = {}, n = {}, F1 = {}.",
            s.length, s.thickness, s.width, s.young, s.mu, s.n, s.force
        ),
        bodies: vec![block_body(
            "strip",
            [0.0; 3],
            [
                Axis::uniform(s.length, s.elements),
                Axis::uniform(s.thickness, 1),
                Axis::uniform(s.width, 1),
            ],
            MaterialSpec::Svk {
                young: s.young,
                nu: 0.0,
            },
            Kinematics::Small,
        )],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![fixed_set("plane-z", "strip.all", &[Component::Z])],
        loads: vec![
            LoadSpec {
                name: "n".into(),
                set: "strip.ymax".into(),
                component: Component::Y,
                value: -s.n * s.length,
                amplitude: vec![(0.0, 1.0), (2.0, 1.0)],
            },
            LoadSpec {
                name: "F".into(),
                set: "strip.xmax".into(),
                component: Component::X,
                value: s.force,
                amplitude: vec![(0.0, 0.0), (1.0, 1.0), (2.0, 0.0)],
            },
        ],
        contacts: vec![ContactSpec {
            name: "ground".into(),
            hitting: "strip.ymin".into(),
            target: TargetSpec::Rigid {
                surface: RigidSpec::Plane {
                    point: [0.0; 3],
                    normal: [0.0, 1.0, 0.0],
                },
                motion: vec![],
            },
            normal: NormalLaw::Lagrange,
            friction: Some(FrictionSpec::Coulomb { mu: s.mu }),
            // 10 x the axial stiffness EA/h of one element: the elastic slip (mu n h / eps_T)
            // stays below 1e-4 of u0, and Newton is not crippled by a tangent dominated by
            // the penalty (1e4 x EA/h made the slip front advance one node per iteration)
            tangential_stiffness: Some(10.0 * s.young * s.thickness * s.width * s.elements as f64 / s.length),
            constraint_scale: None,
            activation: None,
            search_radius: None,
        }],
        steps: vec![StepSpec {
            end: 2.0,
            increments: 2 * s.increments_per_unit,
        }],
        responses: vec![ResponseSpec::Displacement {
            name: "u0".into(),
            set: "strip.xmax".into(),
            component: Component::X,
        }],
        // unloading leaves most of the strip stuck with friction forces locked in at the
        // forward slip limit; from an extrapolated start Newton spreads slip far beyond the
        // reverse-slip zone and lifts nodes off until cut back (observed; the locked-in forces
        // are the likely cause): 113 increments instead of 31 at 200 elements
        // (SolverSettings::extrapolate)
        solver: SolverSettings {
            extrapolate: false,
            ..SolverSettings::default()
        },
        study: StudySpec::default(),
    }
}

/// Parameters of the Hertz line-contact scene (shared/oracles.md section 4).
#[derive(Clone, Debug)]
pub struct HertzSpec {
    /// Radius `R` of the rigid cylinder.
    pub radius: f64,
    /// Young's modulus `E` of the block.
    pub young: f64,
    /// Poisson's ratio `nu` of the block.
    pub nu: f64,
    /// Target half-width; the load is `P = a^2 pi E* / (4 R)` per unit length.
    pub half_width: f64,
    /// Elements across the target half-width.
    pub elements_across: usize,
}

impl Default for HertzSpec {
    fn default() -> Self {
        HertzSpec {
            radius: 10.0,
            young: 1e5,
            nu: 0.3,
            half_width: 0.5,
            elements_across: 12,
        }
    }
}

impl HertzSpec {
    /// Plane-strain modulus `E* = E / (1 - nu^2)`.
    pub fn e_star(&self) -> f64 {
        self.young / (1.0 - self.nu * self.nu)
    }
    /// Load per unit length giving the target half-width.
    pub fn load(&self) -> f64 {
        self.half_width.powi(2) * std::f64::consts::PI * self.e_star() / (4.0 * self.radius)
    }
}

/// Half model (x >= 0) of a plane-strain block pushed by a bottom pressure against a rigid
/// cylinder of radius R whose lowest line touches the block's top at x = 0 (load control).
pub fn hertz(h: &HertzSpec) -> Scene {
    let a = h.half_width;
    let side = 10.0 * a; // half width of the block: 20a x 20a overall
    let depth = 20.0 * a;
    let fine = h.elements_across * 2; // fine zone 0..2a
    let thickness = a / h.elements_across as f64;
    Scene {
        name: "hertz".into(),
        description: format!(
            "Hertz line contact, plane strain: rigid cylinder R = {} on an elastic block E = {}, nu = {}, P = {:.6e} per unit length for a = {}.",
            h.radius, h.young, h.nu, h.load(), a
        ),
        bodies: vec![block_body(
            "block",
            [0.0, -depth, 0.0],
            [
                graded(side, 0.2, fine, 12, 8.0),
                Axis {
                    length: depth,
                    zones: vec![
                        Zone {
                            fraction: 0.9,
                            elements: 14,
                            ratio: 1.0 / 10.0,
                        },
                        Zone {
                            fraction: 0.1,
                            elements: fine,
                            ratio: 1.0,
                        },
                    ],
                },
                Axis::uniform(thickness, 1),
            ],
            MaterialSpec::Svk {
                young: h.young,
                nu: h.nu,
            },
            Kinematics::Small,
        )],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![
            fixed_set("symmetry", "block.xmin", &[Component::X]),
            fixed_set("plane-strain", "block.all", &[Component::Z]),
        ],
        loads: vec![LoadSpec {
            name: "P".into(),
            set: "block.ymin".into(),
            component: Component::Y,
            value: 0.5 * h.load() * thickness,
            amplitude: ramp(),
        }],
        contacts: vec![ContactSpec {
            name: "cylinder".into(),
            hitting: "block.ymax".into(),
            target: TargetSpec::Rigid {
                surface: RigidSpec::Cylinder {
                    axis_point: [0.0, h.radius, 0.0],
                    axis: [0.0, 0.0, 1.0],
                    radius: h.radius,
                },
                motion: vec![],
            },
            normal: NormalLaw::Lagrange,
            friction: None,
            tangential_stiffness: None,
            constraint_scale: None,
            activation: None,
            search_radius: None,
        }],
        steps: vec![StepSpec {
            end: 1.0,
            increments: 4,
        }],
        responses: vec![
            ResponseSpec::PressureProfile {
                name: "p".into(),
                pair: "cylinder".into(),
                along: Component::X,
            },
            ResponseSpec::TargetForce {
                name: "cylinder-force-y".into(),
                pair: "cylinder".into(),
                component: Component::Y,
            },
        ],
        solver: SolverSettings::default(),
        study: StudySpec::default(),
    }
}

/// Contact patch test: a block pressed by a uniform pressure onto another with a matching mesh;
/// symmetry planes x = 0 and z = 0, the lower block's bottom fixed in y.
pub fn contact_patch(friction: Option<f64>) -> Scene {
    let material = MaterialSpec::Svk {
        young: 1000.0,
        nu: 0.3,
    };
    let axes = || {
        [
            Axis::uniform(2.0, 4),
            Axis::uniform(1.0, 2),
            Axis::uniform(2.0, 4),
        ]
    };
    Scene {
        name: "contact-patch".into(),
        description:
            "Contact patch test: two blocks with matching meshes under a uniform pressure.".into(),
        bodies: vec![
            block_body(
                "lower",
                [0.0; 3],
                axes(),
                material.clone(),
                Kinematics::Small,
            ),
            block_body(
                "upper",
                [0.0, 1.0, 0.0],
                axes(),
                material,
                Kinematics::Small,
            ),
        ],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![
            fixed_set("lower-x", "lower.xmin", &[Component::X]),
            fixed_set("upper-x", "upper.xmin", &[Component::X]),
            fixed_set("lower-z", "lower.zmin", &[Component::Z]),
            fixed_set("upper-z", "upper.zmin", &[Component::Z]),
            fixed_set("lower-y", "lower.ymin", &[Component::Y]),
        ],
        loads: vec![LoadSpec {
            name: "p".into(),
            set: "upper.ymax".into(),
            component: Component::Y,
            value: -4.0 * 10.0,
            amplitude: ramp(),
        }],
        contacts: vec![ContactSpec {
            name: "interface".into(),
            hitting: "upper.ymin".into(),
            target: TargetSpec::Faces("lower.ymax".into()),
            normal: NormalLaw::Lagrange,
            friction: friction.map(|mu| FrictionSpec::Coulomb { mu }),
            tangential_stiffness: None,
            constraint_scale: None,
            activation: None,
            search_radius: None,
        }],
        steps: vec![StepSpec {
            end: 1.0,
            increments: 1,
        }],
        responses: vec![ResponseSpec::PressureProfile {
            name: "p".into(),
            pair: "interface".into(),
            along: Component::X,
        }],
        solver: SolverSettings::default(),
        study: StudySpec::default(),
    }
}

/// The paper's first example (section 3.1): a rigid block with rounded corners pressed into an
/// elastic half-space, then slid so that finite sliding occurs.
///
/// Plane strain through a one-element-thick slab (out-of-plane displacement fixed), 500 mm x
/// 250 mm, graded from 1.67 mm elements under and around the block to a coarse region; small
/// deformation, elasticity (E = 200 GPa, nu = 0.3, units N and mm). The block is 20 mm wide
/// with 1 mm corner radii; it is pressed down u_y = -0.01 mm (t = 0..1), then slid
/// u_x = 3.33 mm (t = 1..2, two fine elements); Coulomb friction mu = 0.5.
pub fn indentation(press_increments: usize, slide_increments: usize) -> Scene {
    indentation_mesh(press_increments, slide_increments, 1.0)
}

/// Largest refinement factor [`indentation_refined`] accepts (about 4 x 10^6 unknowns).
pub const MAX_INDENTATION_REFINEMENT: f64 = 16.0;

/// [`indentation`] on a mesh refined (or coarsened) in the plane by `refinement`: every
/// zone of the x and y axes gets `round(refinement * n)` elements (at least one) where the
/// paper's mesh has `n`, with the same zone extents and grading, so the fine elements are
/// `1.67 / refinement` mm wide. Geometry, material, contact, load path and the slab's
/// one-element thickness (plane strain) are unchanged; `refinement = 1` is [`indentation`].
/// Fails on a refinement that is not finite or lies outside `(0, MAX_INDENTATION_REFINEMENT]`.
pub fn indentation_refined(
    press_increments: usize,
    slide_increments: usize,
    refinement: f64,
) -> Result<Scene, SceneError> {
    if !(refinement.is_finite() && refinement > 0.0 && refinement <= MAX_INDENTATION_REFINEMENT) {
        return Err(invalid(
            "refinement",
            format!("must lie in (0, {MAX_INDENTATION_REFINEMENT}], got {refinement}"),
        ));
    }
    Ok(indentation_mesh(
        press_increments,
        slide_increments,
        refinement,
    ))
}

fn indentation_mesh(press_increments: usize, slide_increments: usize, refinement: f64) -> Scene {
    let refine = |n: usize| ((n as f64 * refinement).round() as usize).max(1);
    let h: f64 = 1.67;
    let fine_width: f64 = 60.0; // -30 .. +30 mm around the block's start and its slide
    let fine = (fine_width / h).round() as usize;
    let side = (500.0 - fine_width) / 2.0;
    let x = Axis {
        length: 500.0,
        zones: vec![
            Zone {
                fraction: side / 500.0,
                elements: refine(12),
                ratio: 1.0 / 12.0,
            },
            Zone {
                fraction: fine_width / 500.0,
                elements: refine(fine),
                ratio: 1.0,
            },
            Zone {
                fraction: side / 500.0,
                elements: refine(12),
                ratio: 12.0,
            },
        ],
    };
    let fine_depth = 10.0 * h;
    let y = Axis {
        length: 250.0,
        zones: vec![
            Zone {
                fraction: (250.0 - fine_depth) / 250.0,
                elements: refine(14),
                ratio: 1.0 / 14.0,
            },
            Zone {
                fraction: fine_depth / 250.0,
                elements: refine(10),
                ratio: 1.0,
            },
        ],
    };
    Scene {
        name: "indentation".into(),
        description: "Rigid block indenting and sliding on an elastic half-space (Chen, Hisada et al. section 3.1): plane strain, E = 200 GPa, nu = 0.3, block 20 mm wide with 1 mm corner radii, pressed 0.01 mm then slid 3.33 mm, mu = 0.5.".into(),
        bodies: vec![BodySpec {
            block: BlockSpec {
                name: "slab".into(),
                origin: [-250.0, -250.0, 0.0],
                x,
                y,
                z: Axis::uniform(h, 1),
            },
            material: MaterialSpec::Svk {
                young: 200e3,
                nu: 0.3,
            },
            kinematics: Kinematics::Small,
            formulation: Hex8Formulation::IncompatibleModes,
        }],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![
            fixed_set("base", "slab.ymin", &[Component::X, Component::Y]),
            fixed_set("plane-strain", "slab.all", &[Component::Z]),
        ],
        loads: vec![],
        contacts: vec![ContactSpec {
            name: "block".into(),
            hitting: "slab.ymax".into(),
            target: TargetSpec::Rigid {
                surface: RigidSpec::RoundedBox {
                    center: [-10.0 + 0.0, 10.0, 0.5 * h],
                    half_extents: [10.0, 10.0, 100.0],
                    radius: 1.0,
                },
                motion: vec![
                    MotionSpec {
                        component: Component::Y,
                        value: -0.01,
                        amplitude: vec![(0.0, 0.0), (1.0, 1.0), (2.0, 1.0)],
                    },
                    MotionSpec {
                        component: Component::X,
                        value: 3.33,
                        amplitude: vec![(0.0, 0.0), (1.0, 0.0), (2.0, 1.0)],
                    },
                ],
            },
            normal: NormalLaw::Lagrange,
            friction: Some(FrictionSpec::Coulomb { mu: 0.5 }),
            tangential_stiffness: None,
            constraint_scale: None,
            activation: None,
            search_radius: None,
        }],
        steps: vec![
            StepSpec {
                end: 1.0,
                increments: press_increments,
            },
            StepSpec {
                end: 2.0,
                increments: slide_increments,
            },
        ],
        responses: vec![
            ResponseSpec::TargetForce {
                name: "block-force-x".into(),
                pair: "block".into(),
                component: Component::X,
            },
            ResponseSpec::TargetForce {
                name: "block-force-y".into(),
                pair: "block".into(),
                component: Component::Y,
            },
            ResponseSpec::PressureProfile {
                name: "p".into(),
                pair: "block".into(),
                along: Component::X,
            },
        ],
        solver: SolverSettings::default(),
        study: StudySpec::default(),
    }
}

/// A deformable block (1.5 x 0.5, 3 elements) pressed by a total load of 1 onto a deformable
/// base (8 x 1, faces 1.0 long) and pulled 3 units along it: its hitting nodes cross several
/// target faces. Plane strain (z fixed), small kinematics, E = 1000, nu = 0.3.
pub fn sliding_block(friction: Option<f64>) -> Scene {
    let svk = || MaterialSpec::Svk {
        young: 1000.0,
        nu: 0.3,
    };
    let axes = |n: [usize; 2], l: [f64; 2]| {
        [
            Axis::uniform(l[0], n[0]),
            Axis::uniform(l[1], n[1]),
            Axis::uniform(0.5, 1),
        ]
    };
    Scene {
        name: "sliding-block".into(),
        description: "A block pressed onto a deformable base and slid across three of its faces."
            .into(),
        bodies: vec![
            block_body(
                "base",
                [0.0, -1.0, 0.0],
                axes([8, 2], [8.0, 1.0]),
                svk(),
                Kinematics::Small,
            ),
            block_body(
                "slider",
                [1.0, 0.0, 0.0],
                axes([3, 1], [1.5, 0.5]),
                svk(),
                Kinematics::Small,
            ),
        ],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![
            fixed_set("base", "base.ymin", &[Component::X, Component::Y]),
            fixed_set("plane-b", "base.all", &[Component::Z]),
            fixed_set("plane-s", "slider.all", &[Component::Z]),
            PrescribedSpec {
                name: "pull".into(),
                set: "slider.xmin".into(),
                components: vec![Component::X],
                value: 3.0,
                amplitude: vec![(0.0, 0.0), (1.0, 0.0), (2.0, 1.0)],
            },
        ],
        loads: vec![LoadSpec {
            name: "N".into(),
            set: "slider.ymax".into(),
            component: Component::Y,
            value: -1.0,
            amplitude: vec![(0.0, 0.0), (1.0, 1.0), (2.0, 1.0)],
        }],
        contacts: vec![ContactSpec {
            name: "interface".into(),
            hitting: "slider.ymin".into(),
            target: TargetSpec::Faces("base.ymax".into()),
            normal: NormalLaw::Lagrange,
            friction: friction.map(|mu| FrictionSpec::Coulomb { mu }),
            tangential_stiffness: None,
            constraint_scale: None,
            // the slider travels 3 units: every face it may reach is a candidate
            activation: None,
            search_radius: Some(6.0),
        }],
        steps: vec![
            StepSpec {
                end: 1.0,
                increments: 2,
            },
            StepSpec {
                end: 2.0,
                increments: 30,
            },
        ],
        responses: vec![ResponseSpec::Reaction {
            name: "pull".into(),
            set: "slider.xmin".into(),
            component: Component::X,
        }],
        solver: SolverSettings::default(),
        study: StudySpec::default(),
    }
}
