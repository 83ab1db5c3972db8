//! Scenes: complete analyses as data. A scene is written and read as TOML (serde), built-in
//! scenes have names, and [`Scene::build`] validates a scene and turns it into a [`Model`].
//!
//! A scene declares its physics — kinematics, material laws, element formulation, springs — and
//! the model pays only for what is declared (no history for elastic bodies, no internal
//! unknowns for plain hex8).

use crate::element::{Hex8Formulation, Kinematics, Spring};
use crate::material::{J2Plasticity, StVenantKirchhoff};
use crate::mesh::{Axis, BlockSpec, Mesh, Zone};
use crate::model::{Amplitude, Body, Material, Model, NodalLoad, Prescribed, SolverSettings};
use crate::response::{Response, ResponseKind};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A Cartesian component.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Component {
    X,
    Y,
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
        #[serde(rename = "E")]
        young: f64,
        nu: f64,
    },
    /// J2 plasticity; linear hardening `sigma_y + H alpha`, plus the saturation term
    /// `(sigma_inf - sigma_y)(1 - exp(-delta alpha))` when `sigma_inf` and `delta` are given.
    J2 {
        #[serde(rename = "E")]
        young: f64,
        nu: f64,
        sigma_y: f64,
        #[serde(rename = "H")]
        hardening: f64,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        sigma_inf: Option<f64>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        delta: Option<f64>,
    },
}

impl MaterialSpec {
    fn build(&self) -> Material {
        match self {
            MaterialSpec::Svk { young, nu } => Material::Svk(StVenantKirchhoff::new(*young, *nu)),
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
            MaterialSpec::Svk { young, nu } => {
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
                    return Err(invalid(&format!("{at}.H"), "softening (H < 0) is not supported"));
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
#[serde(deny_unknown_fields)]
pub struct BodySpec {
    #[serde(flatten)]
    pub block: BlockSpec,
    pub material: MaterialSpec,
    #[serde(default = "large")]
    pub kinematics: Kinematics,
    #[serde(default = "incompatible")]
    pub formulation: Hex8Formulation,
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
    pub x: [f64; 3],
}

/// A spring between two node sets of one node each (or to the ground).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringSpec {
    pub a: String,
    #[serde(default)]
    pub b: Option<String>,
    /// Row-major 3x3 stiffness.
    pub stiffness: [[f64; 3]; 3],
}

/// A prescribed displacement `value * amplitude(t)` on every node of a set.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PrescribedSpec {
    pub name: String,
    pub set: String,
    pub components: Vec<Component>,
    #[serde(default)]
    pub value: f64,
    #[serde(default = "ramp")]
    pub amplitude: Vec<(f64, f64)>,
}

/// A total force `value * amplitude(t)` shared equally by the nodes of a set.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoadSpec {
    pub name: String,
    pub set: String,
    pub component: Component,
    pub value: f64,
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
    pub increments: usize,
}

/// A scalar response of the converged state.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ResponseSpec {
    /// Sum of the reaction forces of a set in one component.
    Reaction {
        name: String,
        set: String,
        component: Component,
    },
    /// Mean displacement of a set in one component.
    Displacement {
        name: String,
        set: String,
        component: Component,
    },
    /// A history variable of one Gauss point: `element` counts within the body, `point` is
    /// the Gauss point (0-7), `variable` names a history entry of the body's material
    /// (for J2: `Ep11` ... `Ep13`, `alpha` = equivalent plastic strain).
    History {
        name: String,
        body: String,
        element: usize,
        point: usize,
        variable: String,
    },
}

impl ResponseSpec {
    /// Name of the response.
    pub fn name(&self) -> &str {
        match self {
            ResponseSpec::Reaction { name, .. }
            | ResponseSpec::Displacement { name, .. }
            | ResponseSpec::History { name, .. } => name,
        }
    }
}

/// A complete analysis.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    pub name: String,
    #[serde(default)]
    pub description: String,
    #[serde(default)]
    pub bodies: Vec<BodySpec>,
    #[serde(default)]
    pub free_nodes: Vec<FreeNodeSpec>,
    #[serde(default)]
    pub springs: Vec<SpringSpec>,
    #[serde(default)]
    pub prescribed: Vec<PrescribedSpec>,
    #[serde(default)]
    pub loads: Vec<LoadSpec>,
    pub steps: Vec<StepSpec>,
    #[serde(default)]
    pub responses: Vec<ResponseSpec>,
    #[serde(default)]
    pub solver: SolverSettings,
}

/// What is wrong with a scene, and where.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SceneError {
    #[error("{file}: {message}")]
    Parse { file: String, message: String },
    #[error("{file}: {source}")]
    Io {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error("field `{field}`: {problem}")]
    Invalid { field: String, problem: String },
    #[error("unknown built-in scene '{0}' (see `fricsens scenes`)")]
    UnknownScene(String),
    #[error("{file}: {source}")]
    InFile {
        file: String,
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

fn poisson(v: f64, field: &str) -> Result<(), SceneError> {
    finite(v, field)?;
    if v > -1.0 && v < 0.5 {
        Ok(())
    } else {
        Err(invalid(field, format!("must lie in (-1, 0.5), got {v}")))
    }
}

impl Scene {
    /// Parse a scene from TOML text; `file` names the source in errors.
    pub fn from_toml(text: &str, file: &str) -> Result<Scene, SceneError> {
        toml::from_str(text).map_err(|e| SceneError::Parse {
            file: file.to_string(),
            message: e.to_string(),
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
        toml::to_string_pretty(self).expect("a scene always serialises")
    }

    /// Validate and build the analysis model.
    pub fn build(&self) -> Result<Model, SceneError> {
        let mut mesh = Mesh::default();
        let mut bodies = Vec::new();
        for (i, b) in self.bodies.iter().enumerate() {
            let at = format!("bodies[{i}]");
            b.material.check(&format!("{at}.material"))?;
            for (c, v) in b.block.origin.iter().enumerate() {
                finite(*v, &format!("{at}.origin[{c}]"))?;
            }
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
                    if let Some(other) = seen.insert((n, c.index()), p.name.clone()) {
                        return Err(invalid(
                            &at,
                            format!(
                                "node {n} component {c:?} is already prescribed by '{other}' (conflicting boundary conditions)"
                            ),
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
            let per_node = l.value / nodes.len() as f64;
            loads.push(NodalLoad {
                name: l.name.clone(),
                nodes,
                component: l.component.index(),
                value: per_node,
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
            if s.increments > 1_000_000 {
                return Err(invalid(
                    &format!("{at}.increments"),
                    "more than 10^6 increments",
                ));
            }
            for k in 1..=s.increments {
                times.push(t0 + (s.end - t0) * k as f64 / s.increments as f64);
            }
            t0 = s.end;
        }
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
                        .ok_or_else(|| invalid(&format!("{at}.body"), format!("no body '{body}'")))?;
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
        let mut model = Model {
            mesh,
            bodies,
            springs,
            prescribed,
            loads,
            times,
            contacts: Vec::new(),
            responses,
            solver: self.solver.clone(),
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
        Ok(model)
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
            "cantilever-small",
            "elastic cantilever, L/h = 20, small tip load: P L^3/(3 E I) (oracles 3)",
        ),
    ]
}

/// A built-in scene by name.
pub fn builtin(name: &str) -> Option<Scene> {
    match name {
        "cantilever" => Some(cantilever(&CantileverSpec::large_deflection())),
        "cantilever-small" => Some(cantilever(&CantileverSpec::small_deflection())),
        "uniaxial-j2" => Some(uniaxial_j2(Kinematics::Small, 10)),
        _ => None,
    }
}

/// Parameters of the cantilever scenes.
#[derive(Clone, Debug)]
pub struct CantileverSpec {
    pub length: f64,
    pub height: f64,
    pub width: f64,
    pub young: f64,
    pub nu: f64,
    pub nx: usize,
    pub ny: usize,
    /// Load parameter alpha = P L^2 / (E I) at the end of the history.
    pub alpha: f64,
    pub increments: usize,
    pub kinematics: Kinematics,
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
    }
}

/// One unit hex8 of J2 material (E = 200 GPa, nu = 0.3, sigma_y = 250 MPa, H = 10 GPa; units
/// MPa and mm) in uniaxial stress: symmetry planes x = 0, y = 0, z = 0, the face x = 1 driven
/// through the axial strain cycle 0 -> +0.01 (t = 1) -> -0.01 (t = 3), `increments_per_unit`
/// increments per unit of pseudo-time. Responses: the axial stress (the reaction on the unit
/// face), the strain, and the equivalent plastic strain of Gauss point 0.
pub fn uniaxial_j2(kinematics: Kinematics, increments_per_unit: usize) -> Scene {
    let fixed = |name: &str, set: &str, c: Component| PrescribedSpec {
        name: name.into(),
        set: set.into(),
        components: vec![c],
        value: 0.0,
        amplitude: ramp(),
    };
    Scene {
        name: "uniaxial-j2".into(),
        description: "Uniaxial stress cycle of one J2 hex8 (shared/oracles.md section 1).".into(),
        bodies: vec![BodySpec {
            block: BlockSpec {
                name: "cube".into(),
                origin: [0.0; 3],
                x: Axis::uniform(1.0, 1),
                y: Axis::uniform(1.0, 1),
                z: Axis::uniform(1.0, 1),
            },
            material: MaterialSpec::J2 {
                young: 200e3,
                nu: 0.3,
                sigma_y: 250.0,
                hardening: 10e3,
                sigma_inf: None,
                delta: None,
            },
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
                value: 0.01,
                amplitude: vec![(0.0, 0.0), (1.0, 1.0), (3.0, -1.0)],
            },
        ],
        loads: vec![],
        steps: vec![
            StepSpec {
                end: 1.0,
                increments: increments_per_unit,
            },
            StepSpec {
                end: 3.0,
                increments: 2 * increments_per_unit,
            },
        ],
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
            ResponseSpec::History {
                name: "alpha".into(),
                body: "cube".into(),
                element: 0,
                point: 0,
                variable: "alpha".into(),
            },
        ],
        solver: SolverSettings::default(),
    }
}
